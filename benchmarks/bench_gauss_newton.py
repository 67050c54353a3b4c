"""Gauss–Newton of lagolib against GTSAM's GaussNewtonOptimizer, in one process.

    python benchmarks/bench_gauss_newton.py      # needs LAGOLIB_DATA (or network) and gtsam

For M3500 and city10000, both optimizers start from the odometry with the same prior on the first
pose and lagolib uses GTSAM's residual (``error="log"``), so both solve the same problem.  Printed:
iterations, final χ², time per iteration (lagolib: assembly, solve and error evaluation apart;
GTSAM: its total divided by its iterations, and one linearize / one linear solve at the optimum),
the ratio lagolib / GTSAM per iteration, and lagolib's peak traced memory (numpy and Python
allocations; qdldl's C++ factor is not traced) per edge.  Then the two Cholesky backends on the
city10000 system.  Target of issue 3: ratio <= 1.0, memory O(m).
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np
from _timing import best_of  # benchmarks/ is on sys.path when run as a script

import lagolib
from lagolib import datasets, gauss_newton, linalg

SIGMAS = (1e-3, 1e-3, 1e-4)


def best_of3(fn):
    return best_of(fn, repeat=3)


def gtsam_problem(gtsam, graph, initial):
    fg = gtsam.NonlinearFactorGraph()
    for k, (i, j) in enumerate(graph.edges):
        noise = gtsam.noiseModel.Gaussian.Information(graph.information[k])
        fg.add(gtsam.BetweenFactorPose2(int(i), int(j), gtsam.Pose2(*graph.measurements[k]), noise))
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.array(SIGMAS))
    fg.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(*initial[0]), noise))
    values = gtsam.Values()
    for k in range(graph.n):
        values.insert(k, gtsam.Pose2(*initial[k]))
    return fg, values


def run_gtsam(gtsam, fg, values):
    params = gtsam.GaussNewtonParams()
    params.setRelativeErrorTol(1e-10)
    params.setAbsoluteErrorTol(1e-10)
    opt = gtsam.GaussNewtonOptimizer(fg, values, params)
    t = time.perf_counter()
    result = opt.optimize()
    return time.perf_counter() - t, opt.iterations(), 2 * fg.error(result), result


def main():
    import gtsam

    prior = lagolib.Prior.from_sigmas
    header = (
        f"{'dataset':<10} {'who':<14} {'iters':>5} {'chi2':>14} {'ms/iter':>8} "
        f"{'assembly':>9} {'solve':>7} {'eval':>6} {'ratio':>6} {'peak MiB':>9} {'B/edge':>7}"
    )
    print(header)
    for name in ["m3500", "city10000"]:
        graph = lagolib.read(datasets.path(name))
        initial = graph.odometry_guess()
        fg, values = gtsam_problem(gtsam, graph, initial)
        runs = []
        for _ in range(3):  # best of 3 by total time, one process
            runs.append(run_gtsam(gtsam, fg, values))
        t_gt, it_gt, chi_gt, result = min(runs, key=lambda r: r[0])
        per_gt = t_gt / it_gt
        lin = fg.linearize(result)
        t_lin = best_of3(lambda fg=fg, at=result: fg.linearize(at))
        t_sol = best_of3(lambda lin=lin: lin.optimize())
        print(
            f"{name:<10} {'gtsam GN':<14} {it_gt:>5} {chi_gt:>14.8f} {1e3 * per_gt:>8.1f} "
            f"{1e3 * t_lin:>9.1f} {1e3 * t_sol:>7.1f} {'':>6} {1.0:>6.2f}"
        )
        for error in ["log", "t2v"]:
            best = None
            for _ in range(3):
                res = lagolib.optimize(
                    graph, initial, error=error, prior=prior(0, initial[0], SIGMAS)
                )
                if best is None or res.timings["total"] < best.timings["total"]:
                    best = res
            tracemalloc.start()
            lagolib.optimize(graph, initial, error=error, prior=prior(0, initial[0], SIGMAS))
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            tm = best.timings
            per = (tm["total"] - tm["setup"]) / best.iterations
            print(
                f"{'':<10} {'lagolib GN ' + error:<14} {best.iterations:>5} {best.chi2:>14.8f} "
                f"{1e3 * per:>8.1f} {1e3 * np.mean(tm['assembly']):>9.1f} "
                f"{1e3 * np.mean(tm['solve']):>7.1f} {1e3 * np.mean(tm['evaluation']):>6.1f} "
                f"{per / per_gt:>6.2f} {peak / 2**20:>9.1f} {peak / graph.m:>7.0f}"
            )
        print(f"{'':<10} setup (pattern, once): {1e3 * best.timings['setup']:.1f} ms")

    graph = lagolib.read(datasets.path("city10000"))
    system = gauss_newton.LinearSystem(graph, fixed=[0])
    H, b, _ = system.assemble(graph.odometry_guess())
    print(f"\ncity10000 H: {H.shape[0]} x {H.shape[1]}, nnz {H.nnz}")
    for backend in linalg.available_backends():
        f = linalg.SparseCholesky(H, backend)
        t_first = best_of3(lambda backend=backend: linalg.SparseCholesky(H, backend).solve(b))
        t_re = best_of3(lambda f=f: f.refactor(H).solve(b))
        print(
            f"  {backend:<6} factor+solve {1e3 * t_first:7.1f} ms, refactor+solve {1e3 * t_re:7.1f} ms"
        )
    out = linalg.pcg(H, -b, rtol=1e-10)
    t_cg = best_of3(lambda: linalg.pcg(H, -b, rtol=1e-10))
    print(f"  pcg    block-Jacobi: {out.iterations} iterations, {1e3 * t_cg:.1f} ms")


if __name__ == "__main__":
    main()
