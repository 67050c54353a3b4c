"""The closed form's Newton solve against Gauss–Newton on the same χ², in one process.

    python benchmarks/bench_closed_form.py      # needs LAGOLIB_DATA (or network)

Both minimize Lodi Rizzini's χ² (eq. 6, Ω = I_4) from LAGO's estimate and reach the same poses:
``closed_form.solve_orthogonality`` (Newton on positions, ``t`` and ``ρ``: 5n unknowns, sparse LU
of an unsymmetric Jacobian) and ``closed_form.optimize_sincos`` (Gauss–Newton on ``(x, y, θ)``:
3n unknowns, sparse Cholesky of ``J^T J``).  Printed per dataset: best-of-3 wall times (LAGO's
start excluded from both), the ratio closed form / Gauss–Newton, iterations, the largest pose
difference, and the closed form's peak traced memory (numpy and Python allocations; SuperLU's
factor is not traced) per edge.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
from _timing import best_of  # benchmarks/ is on sys.path when run as a script

from lagolib import closed_form as cf
from lagolib import datasets
from lagolib.lago import lago


def main():
    print(
        f"{'dataset':<10} {'n':>6} {'m':>6} {'GN ms':>8} {'closed ms':>9} {'ratio':>6} "
        f"{'GN it':>5} {'Newton it':>9} {'max |dp|':>9} {'B/edge':>7} {'fallback':>8}"
    )
    for name in ("intel", "m3500", "city10000"):
        graph = datasets.load(name)
        start = lago(graph).poses
        net = cf.network(graph)
        t0 = net.t_of(start[net.vertex, 2])
        t_gn = best_of(lambda g=graph, s=start: cf.optimize_sincos(g, s), repeat=3)
        t_cf = best_of(lambda n=net, t=t0: cf.solve_orthogonality(n, t), repeat=3)
        gn = cf.optimize_sincos(graph, start)
        tracemalloc.start()
        res = cf.solve_orthogonality(net, t0)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        diff = np.abs(res.poses - gn.poses).max()
        print(
            f"{name:<10} {graph.n:>6} {graph.m:>6} {1e3 * t_gn:>8.1f} {1e3 * t_cf:>9.1f} "
            f"{t_cf / t_gn:>6.2f} {gn.iterations:>5} {res.iterations:>9} {diff:>9.1e} "
            f"{peak / graph.m:>7.0f} {str(res.fallback):>8}"
        )


if __name__ == "__main__":
    main()
