"""qdldl against MKL PARDISO with every solve checked: where ``backend="auto"`` should switch.

For Manhattan worlds and odometry chains of growing size, one Gauss–Newton system ``H dx = -b``
(near the optimum) is factored and solved the way :func:`lagolib.optimize` does it:
the pose graph's elimination order computed once (:func:`lagolib.linalg.elimination_ordering`),
the first factorization (analysis included), then a refactorization and a checked solve — the
cost of every later iteration.  Each backend's answer is compared with qdldl's and its backward
error, residual and refinement steps are reported.  Medians of ``--repeat`` runs, the backends
alternating so that a busy machine slows both alike.

    python benchmarks/bench_backends.py            # writes benchmarks/BACKENDS.md
    python benchmarks/bench_backends.py --quick    # smaller sizes, one repeat, no file
"""

from __future__ import annotations

import argparse
import os
import platform
import time
import warnings
from pathlib import Path

import numpy as np

import lagolib
from lagolib import linalg, simulate
from lagolib.gauss_newton import LinearSystem

HERE = Path(__file__).resolve().parent


def _world(kind, n, seed=0):
    if kind == "chain":
        return simulate.loop_world(laps=1, poses_per_lap=n, rng=seed).graph
    sim = simulate.manhattan_world(n_poses=n, rng=seed, extent=max(4, int(np.sqrt(n / 3))))
    return sim.graph.with_poses(sim.truth)


def _measure(kind, n, repeat):
    g = _world(kind, n)
    system = LinearSystem(g, fixed=[g.ids[0]])
    nudge = 1e-3 * np.cos(np.arange(3 * g.n)).reshape(-1, 3)
    nudge[0] = 0.0  # the fixed pose stays: a Gauss–Newton step back to the optimum
    H, b, _ = system.assemble(g.poses + nudge)
    t = time.perf_counter()
    order = system.ordering()
    t_order = time.perf_counter() - t
    rows = {}
    times = {be: {"first": [], "iteration": []} for be in ("qdldl", "pardiso")}
    for _ in range(repeat):
        for be in ("qdldl", "pardiso"):
            if be not in linalg.available_backends():
                continue
            with warnings.catch_warnings(record=True) as seen:
                warnings.simplefilter("always")
                t0 = time.perf_counter()
                F = linalg.SparseCholesky(H, be, check=False, ordering=order)
                x = F.solve(-b)
                t1 = time.perf_counter()
                F.refactor(H)
                x = F.solve(-b)
                t2 = time.perf_counter()
            times[be]["first"].append(t1 - t0)
            times[be]["iteration"].append(t2 - t1)
            rows[be] = (x, F.last_check, F.nnz_L, F.backend, len(seen))
    x = rows["qdldl"][0]
    check = []
    upper = linalg._Upper(H)  # what SparseCholesky keeps for its check
    for _ in range(repeat):
        t = time.perf_counter()
        linalg._backward_error(upper, x, -b)  # the check's cost: H x and |H| |x|
        check.append(time.perf_counter() - t)
    out = {
        "kind": kind,
        "n": n,
        "N": H.shape[0],
        "order": t_order,
        "check": float(np.median(check)),
    }
    ref = rows["qdldl"][0]
    for be, (x, chk, nnz, used, warned) in rows.items():
        out[be] = {
            "first": float(np.median(times[be]["first"])),
            "iteration": float(np.median(times[be]["iteration"])),
            "omega": chk.backward_error,
            "residual": chk.relative_residual,
            "steps": chk.refinement_steps,
            "nnz_L": nnz,
            "used": used,
            "warned": warned,
            "vs_qdldl": float(np.linalg.norm(x - ref) / np.linalg.norm(ref)),
        }
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--repeat", type=int, default=3)
    args = p.parse_args()
    if args.quick:
        cases = [("manhattan", 3_000), ("manhattan", 20_000), ("chain", 20_000)]
        repeat = 1
    else:
        cases = [("manhattan", k) for k in (3_000, 10_000, 17_000, 30_000, 60_000, 100_000)]
        cases += [("chain", k) for k in (20_000, 60_000, 100_000)]
        repeat = args.repeat
    results = []
    for kind, n in cases:
        r = _measure(kind, n, repeat)
        results.append(r)
        q, pa = r["qdldl"], r.get("pardiso")
        line = f"{kind:9s} n={n:7d} N={r['N']:7d} qdldl it {q['iteration']:.3f}s"
        if pa:
            line += (
                f"  pardiso it {pa['iteration']:.3f}s ({pa['used']}) ratio "
                f"{q['iteration'] / pa['iteration']:.2f}  omega {pa['omega']:.1e} steps "
                f"{pa['steps']} vs qdldl {pa['vs_qdldl']:.1e}"
            )
        print(line, flush=True)
    if args.quick:
        return
    lines = [
        "# qdldl against MKL PARDISO, every solve checked (`benchmarks/bench_backends.py`)",
        "",
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"lagolib {lagolib.__version__}, median of {repeat} runs (backends alternating), load "
        f"average at the end {os.getloadavg()[0]:.1f}.",
        "",
        "One Gauss–Newton system near the optimum (every pose but the fixed one nudged by 1e-3), "
        "the pose graph's elimination order computed once. *first*: analysis, factorization "
        "and a checked solve; *iteration*: a refactorization and a checked solve (every later Gauss–Newton "
        "iteration). The check is the backward error `max|b - Hx| / (|H||x| + |b|)` and "
        "iterative refinement while it halves; *check*: one evaluation of it (the products "
        "`Hx` and `|H||x|`), included in every solve's time. *vs qdldl*: "
        "`||x - x_qdldl|| / ||x_qdldl||` (on chains the system's condition number, about "
        "1e17, allows 1e-5 to 1e-3: both backward errors are at rounding, and Gauss–Newton "
        "reaches the same poses to 1e-8, `tests/test_trust_backends.py`).",
        "",
        '`backend="auto"` takes PARDISO from `PARDISO_MIN_SIZE` = 50 000 rows of the pose '
        "graph's 2-core. On an idle machine PARDISO wins on every Manhattan row here; on a busy "
        "one (an earlier run, load 3-5, before the two-level factorization) it lost below 5e4 "
        "rows (0.10 at 9e3, 0.85 at 3e4, 1.13 at 5.1e4, 6.2 at 3e5), and the book's graphs (at "
        "most 3e4 rows) stay on the readable, deterministic qdldl. The chains (2-core empty) "
        "stay on qdldl at every size.",
        "",
        "| world | poses | rows | order (s) | check (s) | qdldl first | qdldl iteration | PARDISO first | "
        "PARDISO iteration | qdldl / PARDISO per iteration | PARDISO omega | refinement steps "
        "| vs qdldl | solved by |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        q, pa = r["qdldl"], r.get("pardiso")
        if pa is None:
            continue
        lines.append(
            f"| {r['kind']} | {r['n']} | {r['N']} | {r['order']:.3f} | {r['check']:.4f} | "
            f"{q['first']:.3f} | "
            f"{q['iteration']:.3f} | {pa['first']:.3f} | {pa['iteration']:.3f} | "
            f"{q['iteration'] / pa['iteration']:.2f} | {pa['omega']:.1e} | {pa['steps']} | "
            f"{pa['vs_qdldl']:.1e} | {pa['used']} |"
        )
    (HERE / "BACKENDS.md").write_text("\n".join(lines) + "\n")
    print("wrote", HERE / "BACKENDS.md")


if __name__ == "__main__":
    main()
