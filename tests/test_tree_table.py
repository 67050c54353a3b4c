"""The spanning-tree table (data/tree_table.csv, printed in chapter 5) is true and supports the default.

``benchmarks/tree_table.py`` wrote the table; these tests recompute rows of it and check that
``lago()``'s default tree (``"min_uncertainty"``) never loses to the paper's odometric tree by more
than 0.1 % after Gauss–Newton and wins clearly on the noisy simulations.
"""

import csv
import importlib.util
from pathlib import Path

import pytest

import lagolib
from lagolib import datasets

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("tree_table", ROOT / "benchmarks" / "tree_table.py")
tree_table = importlib.util.module_from_spec(spec)
spec.loader.exec_module(tree_table)


def _table():
    with open(datasets.data_dir() / "tree_table.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return {(r["graph"], r["tree"]): r for r in rows}


def _check(stored, fresh):
    assert int(stored["regularized"]) == fresh["regularized"]
    assert float(stored["min_margin"]) == pytest.approx(fresh["min_margin"], abs=2e-4)
    # LAGO's χ² where a tree's rounding went wrong is large (INTEL: 1.7e6) and inherits the
    # conditioning of the solves: with numpy 2.4 / scipy 1.17 three runs on one machine gave
    # 1714815.7, 1714825.3 and 1714833.7 (stored 1714831.1) — not bit-reproducible, a known
    # open defect (threaded reductions?), so the row is compared to 1e-4 relative
    assert float(stored["lago_chi2"]) == pytest.approx(fresh["lago_chi2"], rel=1e-4, abs=1e-9)
    assert float(stored["gn_chi2"]) == pytest.approx(fresh["gn_chi2"], rel=1e-6, abs=1e-9)


def test_the_default_tree_is_min_uncertainty():
    import inspect

    assert inspect.signature(lagolib.lago_solve).parameters["tree"].default == "min_uncertainty"
    assert lagolib.topology.TREES[0] == "min_uncertainty"


def test_the_stored_table_supports_the_default():
    table = _table()
    graphs = sorted({g for g, _ in table})
    assert len(graphs) >= 20
    for g in graphs:
        best, odo = table[(g, "min_uncertainty")], table.get((g, "odometric"))
        if odo is None:
            continue
        # never loses to the odometric tree by more than 0.1 % after Gauss–Newton
        assert float(best["gn_chi2"]) <= float(odo["gn_chi2"]) * 1.001 + 1e-9, g
    for s in (0.05, 0.1, 0.2):
        for seed in tree_table.SEEDS:
            g = f"manhattan σθ={s} seed {seed}"
            # wins clearly on noisy simulations: at least 2x lower χ² after GN
            assert 2 * float(table[(g, "min_uncertainty")]["gn_chi2"]) < float(
                table[(g, "odometric")]["gn_chi2"]
            ), g
    # heterogeneous noise: the weights matter, the breadth-first tree fails where this one holds
    prop = [g for g in graphs if g.startswith("manhattan ∝")]
    assert len(prop) == len(tree_table.PROPORTIONAL) * len(tree_table.SEEDS)
    for g in prop:
        assert float(table[(g, "min_uncertainty")]["gn_chi2"]) <= 1.001 * float(
            table[(g, "bfs")]["gn_chi2"]
        ), g
    assert (
        max(
            float(table[(g, "bfs")]["gn_chi2"]) / float(table[(g, "min_uncertainty")]["gn_chi2"])
            for g in prop
        )
        > 2
    )
    # MIT: the odometric tree's LAGO sends GN into a local minimum, min_uncertainty does not
    assert float(table[("mit", "odometric")]["gn_chi2"]) > 700
    assert float(table[("mit", "min_uncertainty")]["gn_chi2"]) < 42


@pytest.mark.parametrize("name", ["mit", "csail_toro", "fr079", "intel", "m3500"])
def test_benchmark_rows_are_reproduced(benchmark, name):
    g = lagolib.read(benchmark(name))
    table = _table()
    for tree in lagolib.topology.TREES:
        _check(table[(name, tree)], tree_table.row(name, g, tree))


def test_a_simulated_row_group_is_reproduced():
    label = "manhattan σθ=0.05 seed 0"
    g = tree_table.simulated(0.05, 0)
    table = _table()
    for tree in lagolib.topology.TREES:
        _check(table[(label, tree)], tree_table.row(label, g, tree))
