"""Which spanning tree should LAGO regularize on?  LAGO χ² and GN-from-LAGO χ² for each tree.

Rows: every graph benchmark reachable through ``lagolib.datasets`` (the ``LAGOLIB_DATA`` mirror
or the download cache) and simulated Manhattan worlds (3500 poses, as Olson's M3500) with
rotation noise σ_θ ∈ {0.01, 0.05, 0.1, 0.2} rad on every edge, two seeds each; and the same
worlds with *heterogeneous* noise, σ_θ · max(|δ|, 0.1) per edge (``noise="proportional"``:
turns are up to 16× noisier than straight moves), σ_θ ∈ {0.1, 0.2, 0.3}.  For each of the trees
``lagolib.topology.TREES``: LAGO's χ² (the lecture notes' t2v error, g2o information), the number
of chords regularized, and the χ² Gauss–Newton reaches from LAGO (at most 100 iterations).

Run: ``LAGOLIB_DATA=... python benchmarks/tree_table.py [--csv data/tree_table.csv]``.
The chapter ``book/05_orientation_estimation.ipynb`` prints the stored CSV, and
``tests/test_tree_table.py`` recomputes rows of it.
"""

from __future__ import annotations

import argparse
import csv
import sys
import warnings

import lagolib
from lagolib import datasets, simulate, topology

SIGMAS = (0.01, 0.05, 0.1, 0.2)
PROPORTIONAL = (0.1, 0.2, 0.3)
SEEDS = (0, 1)
FIELDS = [
    "graph",
    "poses",
    "edges",
    "tree",
    "regularized",
    "min_margin",
    "lago_chi2",
    "gn_chi2",
    "gn_iterations",
]


def benchmark_names():
    """Graph benchmarks that can be had without the network."""
    return [
        n for n in datasets.names() if datasets.info(n).kind == "graph" and datasets.available(n)
    ]


def simulated(sigma_theta, seed, noise="fixed"):
    """A 3500-pose Manhattan world (≈ Olson's M3500: ≈ 5.5k edges) with rotation noise σ_θ."""
    return simulate.manhattan_world(
        n_poses=3500,
        extent=20,
        closure_probability=0.12,
        sigma_xy=0.05,
        sigma_theta=sigma_theta,
        noise=noise,
        rng=seed,
    ).graph


def graphs():
    """(label, PoseGraph) for every row group of the table."""
    for name in benchmark_names():
        yield name, datasets.load(name, download=False)
    for s in SIGMAS:
        for seed in SEEDS:
            yield f"manhattan σθ={s} seed {seed}", simulated(s, seed)
    for s in PROPORTIONAL:
        for seed in SEEDS:
            yield f"manhattan ∝ σθ={s} seed {seed}", simulated(s, seed, "proportional")


def row(label, graph, tree):
    """One table row: LAGO with ``tree``, then Gauss–Newton from LAGO."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lagolib.LagolibWarning)
        try:
            res = lagolib.lago_solve(graph, tree)
        except lagolib.GraphError:  # e.g. no odometric chain
            return None
    gn = lagolib.optimize(graph, res.poses, max_iterations=100)
    reg = res.regularization
    return {
        "graph": label,
        "poses": graph.n,
        "edges": graph.m,
        "tree": tree,
        "regularized": reg.n_regularized,
        "min_margin": round(float(reg.margin.min()), 4) if reg.margin.size else 0.5,
        "lago_chi2": float(f"{lagolib.chi2(graph, res.poses):.10g}"),
        "gn_chi2": float(f"{gn.chi2:.10g}"),
        "gn_iterations": gn.iterations,
    }


def rows():
    for label, g in graphs():
        for tree in topology.TREES:
            r = row(label, g, tree)
            if r is not None:
                yield r


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--csv", help="write the table here as CSV")
    args = ap.parse_args(argv)
    out = list(rows())
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            w = csv.DictWriter(f, FIELDS)
            w.writeheader()
            w.writerows(out)
    w = csv.DictWriter(sys.stdout, FIELDS, delimiter="\t")
    w.writeheader()
    w.writerows(out)


if __name__ == "__main__":
    main()
