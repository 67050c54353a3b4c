"""LAGO of lagolib against GTSAM's ``gtsam.lago.initialize``, in one process.

    python benchmarks/bench_lago.py      # needs LAGOLIB_DATA (or network) and gtsam

On M3500 and city10000 (diagonal, isotropic noise: the two compute the same estimate), both with
the odometric tree.  Printed per dataset: best-of-5 wall time of each, the ratio lagolib / GTSAM
(target of issue 4: <= 1.0), lagolib's time with its default tree (min_uncertainty: one Dijkstra
more), lagolib's time per phase, the χ² of both estimates, and lagolib's
peak traced memory (numpy and Python allocations; qdldl's C++ factor is not traced) per edge.
GTSAM's time includes building nothing: its factor graph is made before the clock starts, as
lagolib's PoseGraph is.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
from _timing import best_of  # benchmarks/ is on sys.path when run as a script

import lagolib
from lagolib import datasets
from lagolib.lago import lago


def gtsam_graph(gtsam, graph):
    fg = gtsam.NonlinearFactorGraph()
    for k, (i, j) in enumerate(graph.edges):
        noise = gtsam.noiseModel.Diagonal.Precisions(np.diag(graph.information[k]).copy())
        fg.add(gtsam.BetweenFactorPose2(int(i), int(j), gtsam.Pose2(*graph.measurements[k]), noise))
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.full(3, 1e-8))
    fg.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(0.0, 0.0, 0.0), noise))
    return fg


def main():
    import gtsam

    print(
        f"{'dataset':<10} {'n':>6} {'m':>6} {'GTSAM ms':>9} {'lagolib ms':>10} {'ratio':>6} "
        f"{'default ms':>10}  "
        f"{'phases (reg/1/2/3) ms':<24} {'chi2 GTSAM':>12} {'chi2 ours':>12} {'B/edge':>7}"
    )
    for name in ("m3500", "city10000"):
        graph = datasets.load(name)
        fg = gtsam_graph(gtsam, graph)
        t_gtsam = best_of(lambda fg=fg: gtsam.lago.initialize(fg, True))
        t_ours = best_of(lambda graph=graph: lago(graph, "odometric"))
        t_default = best_of(lambda graph=graph: lago(graph))
        values = gtsam.lago.initialize(fg, True)
        theirs = np.array(
            [
                [values.atPose2(i).x(), values.atPose2(i).y(), values.atPose2(i).theta()]
                for i in range(graph.n)
            ]
        )
        tracemalloc.start()
        res = lago(graph, "odometric")
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        t = res.timings
        phases = "/".join(
            f"{1e3 * t[k]:.1f}" for k in ("regularization", "phase1", "phase2", "phase3")
        )
        print(
            f"{name:<10} {graph.n:>6} {graph.m:>6} {1e3 * t_gtsam:>9.1f} {1e3 * t_ours:>10.1f} "
            f"{t_ours / t_gtsam:>6.2f} {1e3 * t_default:>10.1f}  {phases:<24} "
            f"{lagolib.chi2(graph, theirs):>12.6f} {lagolib.chi2(graph, res.poses):>12.6f} "
            f"{peak / graph.m:>7.0f}"
        )


if __name__ == "__main__":
    main()
