"""The modules form the acyclic layers the README and ``lagolib/__init__.py`` describe."""

import ast
from pathlib import Path

import pytest

import lagolib

# each module may import only from modules in earlier layers (or its own layer's helpers below it)
LAYERS = [
    ["errors"],
    ["files", "tables"],
    ["se2"],
    ["checks"],
    ["graph"],
    ["io", "simulate", "metrics", "occupancy", "scans", "scan_matching", "kernels", "consistency"],
    ["laser_world"],
    ["datasets"],
    ["topology"],
    ["linalg"],
    ["estimation"],
    ["gauss_newton", "lago", "sgd"],
    ["closed_form"],
    ["certify"],
    ["robust"],
    ["plotting"],
    ["uncertainty"],
    ["frontend"],
    ["book"],
    ["grading"],
    ["cli"],
]
RANK = {name: k for k, layer in enumerate(LAYERS) for name in layer}
ROOT = Path(lagolib.__file__).parent


def _imports(path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            if node.module:
                yield node.module.split(".")[0]
            else:
                yield from (alias.name for alias in node.names)


@pytest.mark.parametrize("module", sorted(RANK))
def test_module_imports_only_earlier_layers(module):
    for dep in _imports(ROOT / f"{module}.py"):
        assert dep in RANK, f"{module} imports {dep}, which is not in a layer"
        assert RANK[dep] < RANK[module], f"{module} (layer {RANK[module]}) imports {dep}"


def test_exercises_are_on_top():
    """lagolib.exercises (the book's checks) may use all of lagolib; nothing in lagolib uses it."""
    for path in ROOT.glob("*.py"):
        if path.name == "grading.py":  # grading runs the checks (by name, in a process of its own)
            continue
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.ImportFrom):
                names = [f"{'.' * node.level}{node.module or ''}"]
                names += [f"{names[0]}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            assert not any("exercises" in n for n in names), f"{path.name} imports {names}"
    for path in (ROOT / "exercises").glob("*.py"):
        tree = ast.parse(path.read_text())
        relative = [n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.level > 1]
        assert not relative, f"exercises/{path.name}: import lagolib's API absolutely"


def test_every_module_has_a_layer():
    modules = {p.stem for p in ROOT.glob("*.py")} - {"__init__", "symbolic"}
    assert modules == set(RANK)


def test_symbolic_needs_only_sympy():
    assert list(_imports(ROOT / "symbolic.py")) == []
