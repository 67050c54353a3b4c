"""Every chapter of the book runs as a test, renders its figures, and is stored without outputs.

Each ``book/*.ipynb`` (whatever chapters exist; a new chapter is picked up by its file name) is
executed with nbclient in its own Jupyter kernel, twice:

``online``
    the environment as it is: in CI ``LAGOLIB_DATA`` names the benchmark mirror, so the chapters
    show the real benchmarks;
``offline``
    ``LAGOLIB_DATA`` unset, ``LAGOLIB_OFFLINE=1`` and an empty ``LAGOLIB_CACHE``: the chapters fall
    back to the shipped examples, and their offline text is exercised.  Marked ``offline`` (it
    needs nothing and runs everywhere, CI included; ``-m "not offline"`` leaves it out).

A chapter fails on any cell error, and when it renders fewer figures (``image/png`` outputs) than
it promises in its metadata, ``nb.metadata["lagolib"]["figures"]``.  The kernels draw with
matplotlib's inline backend: ``MPLBACKEND`` is removed from the kernel's environment even when the
user's shell sets it (``MPLBACKEND=Agg`` would silently render nothing).  BLAS libraries are held to
one thread in the kernels: the chapters' vectors are small, and on a loaded machine threads fighting
for the cores made a cell 50x slower.  The per-cell timeout is a guard against hangs, not a time
limit on the chapters.
"""

import os
import shutil
import tempfile
from pathlib import Path

import nbformat
import pytest
from jupyter_client import KernelManager
from nbclient import NotebookClient
from nbclient.exceptions import CellExecutionError, CellTimeoutError

BOOK = Path(__file__).resolve().parent.parent / "book"
CHAPTERS = sorted(BOOK.glob("*.ipynb"))
CELL_TIMEOUT = 120  # seconds; a hang guard only
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
# the user's download cache as it was before conftest's per-test fixture replaced it
USER_CACHE = os.environ.get("LAGOLIB_CACHE", "")

pytestmark = pytest.mark.book


def _ids(paths):
    return [p.stem for p in paths]


def _read(path):
    return nbformat.read(path, as_version=4)


def promised_figures(nb, path):
    """``nb.metadata["lagolib"]["figures"]``, checked to be an int >= 1."""
    n = nb.metadata.get("lagolib", {}).get("figures")
    if n is None:
        pytest.fail(
            f"{path.name}: the chapter does not say how many figures it renders; add "
            'nb.metadata["lagolib"]["figures"] = N (with nbformat) for the N >= 1 figures it shows'
        )
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        pytest.fail(f'{path.name}: metadata["lagolib"]["figures"] must be an int >= 1; got {n!r}')
    return n


def count_figures(nb):
    """Number of ``image/png`` outputs of the executed notebook."""
    return sum(
        "image/png" in out.get("data", {})
        for cell in nb.cells
        if cell.cell_type == "code"
        for out in cell.get("outputs", [])
    )


def kernel_env(variant, cache):
    """The kernel's environment for ``variant`` ("online" or "offline")."""
    env = dict(os.environ)
    env.pop("MPLBACKEND", None)  # ipykernel then selects matplotlib_inline
    env.update({k: "1" for k in THREAD_VARS})
    if variant == "offline":
        env.pop("LAGOLIB_DATA", None)
        env["LAGOLIB_OFFLINE"] = "1"
        env["LAGOLIB_CACHE"] = str(cache)
    else:
        env.pop("LAGOLIB_OFFLINE", None)
        env["LAGOLIB_CACHE"] = USER_CACHE or str(cache)
    return env


def execute(path, env):
    """Run the notebook at ``path`` in a fresh kernel; return the executed notebook."""
    nb = _read(path)
    # IPC sockets, not TCP ports: jupyter_client picks a "free" TCP port by binding and releasing
    # it, and another kernel starting beside it can take the port first — the kernel then never
    # answers and nbclient waits out its start-up timeout (seen as ~120 s stalls under load)
    sockets = tempfile.mkdtemp(prefix="lagolib-kernel-")
    km = KernelManager(kernel_name="python3", transport="ipc", ip=os.path.join(sockets, "k"))
    client = NotebookClient(
        nb,
        km=km,
        timeout=CELL_TIMEOUT,
        kernel_name="python3",
        allow_errors=False,
        resources={"metadata": {"path": str(path.parent)}},
    )
    try:
        client.execute(env=env)
    except CellTimeoutError as exc:
        pytest.fail(f"{path.name}: a cell ran longer than {CELL_TIMEOUT} s (hang?)\n{exc}")
    except CellExecutionError as exc:
        pytest.fail(f"{path.name}: a cell raised\n{exc}", pytrace=False)
    finally:
        shutil.rmtree(sockets, ignore_errors=True)
    return nb


@pytest.fixture(scope="session")
def online_cache(tmp_path_factory):
    """One download cache for all online chapters when the user has none."""
    return tmp_path_factory.mktemp("book-cache")


def test_book_has_chapters():
    assert CHAPTERS, f"no chapters found in {BOOK}"


@pytest.mark.parametrize("path", CHAPTERS, ids=_ids(CHAPTERS))
def test_stored_without_outputs(path):
    """Chapters are stored stripped: no outputs, no execution counts, and a figure promise."""
    nb = _read(path)
    dirty = [
        i
        for i, cell in enumerate(nb.cells)
        if cell.cell_type == "code"
        and (cell.get("outputs") or cell.get("execution_count") is not None)
    ]
    assert not dirty, (
        f"{path.name}: cells {dirty} are stored with outputs or execution counts; clear them "
        "(Jupyter: Edit > Clear Outputs of All Cells; or nbformat) before saving"
    )
    promised_figures(nb, path)


@pytest.mark.parametrize("path", CHAPTERS, ids=_ids(CHAPTERS))
def test_chapter_online(path, online_cache):
    """The chapter runs as the user's environment has it (CI: the benchmark mirror)."""
    nb = execute(path, kernel_env("online", online_cache))
    n = promised_figures(nb, path)
    assert count_figures(nb) >= n, (
        f"{path.name}: rendered {count_figures(nb)} figures, promises {n}"
    )


@pytest.mark.offline
@pytest.mark.parametrize("path", CHAPTERS, ids=_ids(CHAPTERS))
def test_chapter_offline(path, tmp_path):
    """The chapter runs without benchmarks or network: the shipped examples stand in."""
    cache = tmp_path / "empty-cache"
    cache.mkdir()
    nb = execute(path, kernel_env("offline", cache))
    n = promised_figures(nb, path)
    assert count_figures(nb) >= n, (
        f"{path.name}: rendered {count_figures(nb)} figures, promises {n}"
    )
    assert not any(cache.iterdir()), (
        f"{path.name}: wrote {list(cache.iterdir())} to the cache offline"
    )


def _code(nb):
    """The chapter's code cells, IPython magics and shell escapes blanked."""
    for k, cell in enumerate(nb.cells):
        if cell.cell_type == "code":
            lines = [
                "" if line.lstrip().startswith(("%", "!")) else line
                for line in cell.source.splitlines()
            ]
            yield k, "\n".join(lines)


@pytest.mark.parametrize("path", CHAPTERS, ids=_ids(CHAPTERS))
def test_chapter_uses_only_the_public_api(path):
    """No private module, function or attribute of lagolib (a leading underscore) in a chapter."""
    import ast

    bad = []
    for k, code in _code(_read(path)):
        tree = ast.parse(code)
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("lagolib"):
                parts = node.module.split(".") + [a.name for a in node.names]
                bad += [f"cell {k}: from {node.module} import {p}" for p in parts if p[:1] == "_"]
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.startswith("lagolib") and any(
                        p[:1] == "_" for p in a.name.split(".")
                    ):
                        bad.append(f"cell {k}: import {a.name}")
            elif isinstance(node, ast.Attribute):
                private = node.attr.startswith("_") and not node.attr.startswith("__")
                if private:
                    bad.append(f"cell {k}: .{node.attr}")
    assert not bad, f"{path.name} reaches into lagolib's private API: {bad}"


@pytest.mark.parametrize("path", CHAPTERS, ids=_ids(CHAPTERS))
def test_random_generators_are_seeded(path):
    """Every generator is seeded: no default_rng() without a seed, no legacy global np.random."""
    import re

    bad = []
    for k, code in _code(_read(path)):
        if re.search(r"default_rng\(\s*\)", code):
            bad.append(f"cell {k}: default_rng() without a seed")
        legacy = re.findall(
            r"np\.random\.(rand|randn|normal|uniform|random|randint|choice|shuffle|permutation)\(",
            code,
        )
        bad += [f"cell {k}: np.random.{f}() uses the unseeded global generator" for f in legacy]
        if re.search(r"^\s*import random\b|^\s*from random import", code, re.M):
            bad.append(f"cell {k}: Python's random module")
    assert not bad, f"{path.name}: {bad}"
