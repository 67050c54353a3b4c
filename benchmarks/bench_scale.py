"""lagolib against GTSAM (and g2o) from 10^3 to 10^6 poses; writes ``benchmarks/SCALE.md``.

Usage
-----
::

    export LAGOLIB_DATA=/path/to/posegraphs        # for M3500 and city10000
    python benchmarks/bench_scale.py               # 1e3, 1e4, 1e5 poses, M3500, city10000
    python benchmarks/bench_scale.py --huge        # and 1e6 poses (minutes, ~6+ GB of RAM)
    python benchmarks/bench_scale.py --rows 1e3 1e4 m3500 --out /tmp/SCALE.md
    python benchmarks/bench_scale.py --child '{"task": ...}'   # one measurement (internal)

Rows are simulated Manhattan worlds (:func:`lagolib.simulate.manhattan_world`, ``rng=--seed``,
lattice side :func:`extent_for`, so that the edges grow like 1.8 N) and the M3500 and city10000
benchmarks (:func:`lagolib.datasets.load`).  Each row is written once to a ``.npz`` (lagolib's
arrays) and a ``.g2o`` file (GTSAM's ``readG2o``, g2o's ``load``) whose vertices are the start of
every optimizer (:func:`start_of`): the odometry guess on the datasets, lagolib's LAGO estimate on
the simulated worlds.

Every measurement — one (row, library, task) — runs in its own subprocess (this script with
``--child``), which prints one JSON line, so the peak resident memory (``ru_maxrss``, checked
against ``VmHWM``) is that process's alone; it is read at the end of the first timed run (the
peak of one call: later runs of a repeated measurement can only add what earlier ones left).
Tasks, lagolib vs GTSAM:

``lago``
    ``lagolib.lago.lago(graph, "odometric")`` vs ``gtsam.lago.initialize(graph, True)``: the
    same tree, the same estimate; ``lago_mu``: lagolib alone with its default tree.
``gn1``
    One warm Gauss–Newton iteration — the 2nd, pattern and ordering already analysed — split:
    lagolib ``LinearSystem.assemble``, ``SparseCholesky.refactor``, ``.solve`` and the update
    plus χ² of the new point; GTSAM ``linearize``, ``eliminateMultifrontal`` with the COLAMD
    ordering its optimizer computes once, ``BayesTree.optimize`` (back-substitution), and
    ``retract`` plus ``error``.
``gn``
    Gauss–Newton to convergence (relative decrease 1e-10), same start, same prior on the first
    pose (σ = 1e-3, 1e-3, 1e-4), lagolib with GTSAM's residual (``error="log"``).
``marg``
    Marginal covariances of all poses at lagolib's GN optimum (both libraries at the same
    point): ``uncertainty.marginal_covariances(..., frame="local")`` (selected inversion) vs
    ``gtsam.Marginals`` + ``marginalCovariance`` per pose; rows up to ``--marginals-max`` poses.
``order``
    lagolib only: nnz(L) and flops of the AMD ordering (qdldl) and of nested dissection (METIS,
    inside MKL PARDISO), with the time of a first factorization and of a refactorization.
``gn_t2v``
    On M3500 and city10000, when ``g2opy`` is importable: lagolib GN with g2o's residual and
    the first pose fixed vs g2o's Gauss–Newton (``BlockSolverSE2``, ``LinearSolverEigen``).

Timing: the best of 3 runs for runs under 2 s, a single run above (which then includes
one-time costs such as loading MKL, ~0.1 s); importing the libraries and loading the problem are
not timed.  BLAS, MKL and GTSAM's TBB threads are left at their defaults (all cores) for every
library.  Not a test: nothing is asserted.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _timing import (  # benchmarks/ is on sys.path when run as a script
    importable,
    install_label,
    package_version,
    peak_rss_mib,
    vmhwm_mib,
)

HERE = Path(__file__).resolve().parent
#: rows run by default, and the one behind ``--huge``
DEFAULT_ROWS = ("1e3", "1e4", "1e5", "m3500", "city10000")
HUGE_ROWS = ("1e6",)
DATASETS = ("m3500", "city10000")
#: σ of the prior on the first pose (x, y in m, θ in rad), lagolib's and GTSAM's GN and marginals
SIGMAS = (1e-3, 1e-3, 1e-4)
#: σ of GTSAM's prior on the first pose for LAGO, at the origin (benchmarks/bench_lago.py)
LAGO_PRIOR_SIGMA = 1e-8
TOL = 1e-10
MAX_ITERATIONS = 100
#: a run longer than this is not repeated (best of 3 below it)
SINGLE_RUN = 2.0
#: the two pipeline rows (lago_gn, certify) are compared with each other: best of 3 cold runs
#: up to this many seconds per run, so that both sides of their ratio get as many runs
PIPELINE_SINGLE_RUN = 15.0
PACKAGES = ("lagolib", "numpy", "scipy", "qdldl", "mkl", "cvxopt", "gtsam", "g2opy")
THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "TBB_NUM_THREADS")
WHO = {
    "lago": ("lagolib", "gtsam"),
    "lago_mu": ("lagolib",),
    "gn1": ("lagolib", "gtsam"),
    "gn": ("lagolib", "gtsam"),
    "marg": ("lagolib", "gtsam"),
    "order": ("lagolib",),
    "gn_t2v": ("lagolib", "g2o"),
    "lago_gn": ("lagolib",),
    "certify": ("lagolib",),
}
MODULES = {"lagolib": "lagolib", "gtsam": "gtsam", "g2o": "g2opy"}
#: targets of issue 15: ratio lagolib / peer at most ("own": GN iteration / its factorization;
#: "gn_t2v": strictly below)
TARGETS = {"lago": 0.5, "gn1": 0.5, "rss": 1.0, "own": 1.3, "marg": 1.0, "gn_t2v": 1.0}
#: targets of issue 26: certify.solve / (LAGO + GN) at most, and its peak RSS / GTSAM GN's (at
#: 1e5 poses and more)
CERTIFY_TARGETS = {"time": 1.5, "rss": 1.2, "rss_from": 100_000}
#: simulated poses per lattice point (:func:`extent_for`)
POSES_PER_POINT = 2.5


def extent_for(n_poses):
    """Side of the simulated lattice for ``n_poses``: grows like sqrt(n) so that m ≈ 1.8 n.

    The walk revisits a place (and closes a loop with probability 1/2) about as often at every
    size when the lattice has a fixed number of poses per point; 2.5 gives 1.74-1.80 edges per
    pose from 1e3 to 1e5 poses (measured; the report prints the edge count of every row).
    """
    return max(2, round(math.sqrt(n_poses / POSES_PER_POINT)))


def start_of(row, option):
    """The start of every optimizer on ``row``: ``"odometry"`` or ``"lago"``.

    ``option="auto"``: the odometry guess on the datasets (as ``benchmarks/run_all.py`` and
    ``bench_gauss_newton.py``), lagolib's LAGO (default tree) on the simulated worlds, whose
    odometry drifts by radians from 1e5 poses on: from it Gauss–Newton ends in a different
    local minimum in each library (measured: 1e5 poses, χ² 3.3e8 after 35 iterations vs
    5.4e8 after 6, where LAGO's start gives 2.4e5 in 3).
    """
    if option != "auto":
        return option
    return "odometry" if simulated_size(row) is None else "lago"


def simulated_size(row):
    """Poses of a simulated row (``"1e4"`` -> 10000), or None for a dataset."""
    try:
        return int(float(row))
    except ValueError:
        return None


# ----------------------------------------------------------------------------------------------
# child: one (row, library, task) measurement
# ----------------------------------------------------------------------------------------------


#: the child's ``ru_maxrss`` (MiB) once its library is imported, and once its problem is loaded
_IMPORTED, _LOADED = [], []
#: its ``(ru_maxrss, VmHWM)`` (MiB) at the end of the first timed run: the reported peak
_FIRST_RUN = []


def _phases(t0, t1, t2, t3, t4):
    """The four parts of one Gauss–Newton iteration from five clock readings, seconds."""
    return {"assembly": t1 - t0, "factorization": t2 - t1, "solve": t3 - t2, "evaluation": t4 - t3}


def timed(run, prepare=None, single_run=None):
    """Best of 3 runs of ``run(prepare())`` while a run takes under ``single_run`` s (default
    ``SINGLE_RUN``), else one.

    ``run`` returns ``(phases, out)``: ``phases`` a dict of seconds (or None).  Returns
    ``(best seconds, all seconds, phases of the best run, out of the last run, cpu / wall)``.
    """
    walls, cpus, best, out = [], [], None, None
    for _ in range(3):
        state = prepare() if prepare is not None else None
        c0, t0 = time.process_time(), time.perf_counter()
        phases, out = run(state)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        if not walls or wall < min(walls):
            best = phases
        if not walls:  # the peak of one call: later runs may add what earlier ones left behind
            _FIRST_RUN.append((peak_rss_mib(), vmhwm_mib()))
        walls.append(wall)
        cpus.append(cpu)
        if wall > (SINGLE_RUN if single_run is None else single_run):
            break
    return min(walls), walls, best, out, sum(cpus) / max(sum(walls), 1e-12)


def _load_lagolib_graph(files):
    import numpy as np

    import lagolib

    with np.load(files["npz"]) as z:
        graph = lagolib.PoseGraph(
            poses=z["start"],
            edges=z["edges"],
            measurements=z["measurements"],
            information=z["information"],
            ids=z["ids"],
        )
    return graph


def _fresh_graphs(graph, files):
    """``prepare`` of the cold pipeline runs: ``graph`` (already read) first, then a new read."""
    first = [graph]
    return lambda: first.pop() if first else _load_lagolib_graph(files)


def _lagolib_child(task, files, budget):
    import warnings

    import numpy as np

    import lagolib
    from lagolib import linalg
    from lagolib.gauss_newton import LinearSystem
    from lagolib.lago import lago
    from lagolib.uncertainty import marginal_covariances

    _IMPORTED.append(peak_rss_mib())
    graph = _load_lagolib_graph(files)
    _LOADED.append(peak_rss_mib())
    start = graph.poses
    prior = lagolib.Prior.from_sigmas(int(graph.ids[0]), start[0], SIGMAS)
    rec, arrays = {}, {}
    if task in ("lago", "lago_mu"):
        tree = "odometric" if task == "lago" else "min_uncertainty"

        def run(_):
            res = lago(graph, tree)
            return dict(res.timings), res

        best, walls, phases, res, par = timed(run)
        arrays["poses"] = res.poses
        rec["phases"] = {k: v for k, v in phases.items() if k != "total"}
    elif task == "gn1":
        system = LinearSystem(graph, prior=prior, error="log")
        H, b, _ = system.assemble(start)  # iteration 1, untimed: pattern, analysis, first step
        factor = linalg.SparseCholesky(H, "auto", check=False)
        x1 = system.update(start, factor.solve(-b))
        del H, b

        def run(_):  # iteration 2
            t0 = time.perf_counter()
            H, b, _ = system.assemble(x1)
            t1 = time.perf_counter()
            factor.refactor(H)
            t2 = time.perf_counter()
            dx = factor.solve(-b)
            t3 = time.perf_counter()
            x2 = system.update(x1, dx)
            chi = system.objective(x2)
            t4 = time.perf_counter()
            return _phases(t0, t1, t2, t3, t4), chi

        best, walls, phases, chi, par = timed(run)
        rec.update(phases=phases, native_chi2=chi, backend=factor.backend, N=system.N)
    elif task in ("gn", "gn_t2v"):
        kw = dict(error="log", prior=prior) if task == "gn" else dict(error="t2v")

        def run(_):
            res = lagolib.optimize(graph, start, tol=TOL, max_iterations=MAX_ITERATIONS, **kw)
            return None, res

        best, walls, _, res, par = timed(run)
        tm = res.timings
        rec["phases"] = {"setup": tm["setup"]}
        rec["phases"].update({k: float(np.sum(tm[k])) for k in ("assembly", "solve", "evaluation")})
        rec.update(iterations=res.iterations, native_chi2=res.chi2, converged=res.converged)
        arrays["poses"] = res.poses
        if task == "gn":
            np.save(files["optimum"], res.poses)
    elif task == "lago_gn":  # the plain pipeline: LAGO (default tree), then GN (t2v, pose 0 fixed)
        # both pipeline rows run cold: a freshly read graph per run, so that no run reuses the
        # elimination orderings an earlier run cached on the graph (a user's single call)

        def run(g):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", lagolib.RegularizationWarning)
                x = lago(g).poses
            return None, lagolib.optimize(g, x, method="gn")

        best, walls, _, res, par = timed(
            run, prepare=_fresh_graphs(graph, files), single_run=PIPELINE_SINGLE_RUN
        )
        rec.update(iterations=res.iterations, native_chi2=res.chi2, converged=res.converged)
        arrays["poses"] = res.poses
    elif task == "certify":  # the same, certified: lagolib.certify.solve (issue 26)
        from lagolib import certify

        def run(g):  # cold, as lago_gn
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", lagolib.RegularizationWarning)
                return None, certify.solve(g)

        best, walls, _, res, par = timed(
            run, prepare=_fresh_graphs(graph, files), single_run=PIPELINE_SINGLE_RUN
        )
        rec.update(
            native_chi2=res.chi2, f=res.f, certified=bool(res.certified), escapes=res.escapes,
            phases={k: v for k, v in res.timings.items() if k != "total"},
            engine=certify._certificate_engine(2 * graph.n - 1),
        )  # fmt: skip
        arrays["poses"] = res.poses
    elif task == "marg":
        x = np.load(files["optimum"])

        def run(_):
            cov = marginal_covariances(graph, poses=x, prior=prior, error="log", frame="local")
            return None, cov

        best, walls, _, cov, par = timed(run)
        arrays["cov"] = cov
    elif task == "order":
        best, walls, par = 0.0, [], 1.0
        system = LinearSystem(graph, prior=prior, error="log")
        H = system.assemble(start)[0]
        rec["N"], rec["nnz_H"] = int(H.shape[0]), int(H.nnz)
        t0 = time.perf_counter()
        f = linalg.SparseCholesky(H, "qdldl", check=False)
        t1 = time.perf_counter()
        f.refactor(H)
        t2 = time.perf_counter()
        L = f.factors()[0]
        counts = np.diff(L.indptr).astype(np.float64) + 1.0  # column j of L, diagonal included
        rec["amd"] = {
            "nnz_L": int(L.nnz) + H.shape[0],
            "mflop": float(np.sum(counts**2)) / 1e6,
            "first": t1 - t0,
            "refactor": t2 - t1,
        }
        del f, L, counts
        if "pardiso" in linalg.available_backends():
            t0 = time.perf_counter()
            f = linalg.SparseCholesky(H, "pardiso", check=False)
            t1 = time.perf_counter()
            f.refactor(H)
            t2 = time.perf_counter()
            rec["nd"] = {
                "nnz_L": int(f.nnz_L),
                "mflop": float(f._solver.mflops),
                "first": t1 - t0,
                "refactor": t2 - t1,
            }
    else:
        raise ValueError(task)
    return best, walls, par, rec, arrays


def _gtsam_child(task, files, budget):
    import gtsam
    import numpy as np

    _IMPORTED.append(peak_rss_mib())
    fg, initial = gtsam.readG2o(files["g2o"], False)
    _LOADED.append(peak_rss_mib())
    keys = np.array(sorted(initial.keys()))
    first = int(keys[0])
    rec, arrays = {}, {}

    def prior_graph(mean, sigmas):
        out = gtsam.NonlinearFactorGraph(fg)
        noise = gtsam.noiseModel.Diagonal.Sigmas(np.asarray(sigmas, dtype=float))
        out.add(gtsam.PriorFactorPose2(first, mean, noise))
        return out

    def poses(values):
        return np.asarray(gtsam.utilities.extractPose2(values))  # rows in key order

    if task == "lago":
        graph = prior_graph(gtsam.Pose2(0.0, 0.0, 0.0), [LAGO_PRIOR_SIGMA] * 3)
        del fg

        def run(_):
            return None, gtsam.lago.initialize(graph, True)

        best, walls, _, values, par = timed(run)
        arrays["poses"] = poses(values)
    elif task in ("gn1", "gn"):
        graph = prior_graph(initial.atPose2(first), SIGMAS)
        del fg
        if task == "gn1":
            # GaussNewtonOptimizer computes its COLAMD ordering once, from the nonlinear graph
            ordering = gtsam.Ordering.ColamdNonlinearFactorGraph(graph)
            x1 = initial.retract(graph.linearize(initial).optimize(ordering))  # iteration 1

            def run(_):  # iteration 2
                t0 = time.perf_counter()
                linear = graph.linearize(x1)
                t1 = time.perf_counter()
                tree = linear.eliminateMultifrontal(ordering)
                t2 = time.perf_counter()
                delta = tree.optimize()
                t3 = time.perf_counter()
                x2 = x1.retract(delta)
                error = graph.error(x2)
                t4 = time.perf_counter()
                return _phases(t0, t1, t2, t3, t4), 2.0 * error

            best, walls, phases, chi, par = timed(run)
            rec.update(phases=phases, native_chi2=chi)
        else:
            params = gtsam.GaussNewtonParams()
            params.setRelativeErrorTol(TOL)
            params.setAbsoluteErrorTol(TOL)
            params.setMaxIterations(MAX_ITERATIONS)

            def run(_):
                opt = gtsam.GaussNewtonOptimizer(graph, initial, params)
                values = opt.optimize()
                return None, (values, opt.iterations())

            best, walls, _, (values, its), par = timed(run)
            rec.update(iterations=int(its), native_chi2=2.0 * graph.error(values))
            arrays["poses"] = poses(values)
    elif task == "marg":
        graph = prior_graph(initial.atPose2(first), SIGMAS)
        del fg
        x = np.load(files["optimum"])  # lagolib's optimum, rows in id order = key order
        at = gtsam.Values()
        for k, p in zip(keys.tolist(), x.tolist()):
            at.insert(k, gtsam.Pose2(*p))

        def run(_):
            t0 = time.perf_counter()
            m = gtsam.Marginals(graph, at)
            t1 = time.perf_counter()
            cov = []
            for k in keys.tolist():
                cov.append(m.marginalCovariance(k))
                if budget and time.perf_counter() - t0 > budget:
                    break
            return {"factorization": t1 - t0, "blocks": time.perf_counter() - t1}, np.array(cov)

        best, walls, phases, cov, par = timed(run)
        rec["phases"] = phases
        if len(cov) < keys.size:  # over budget: the time so far is a lower bound
            rec["done"] = len(cov)
            keys = keys[: len(cov)]
        arrays["cov"] = cov
    else:
        raise ValueError(task)
    arrays["ids"] = keys
    return best, walls, par, rec, arrays


def _g2o_child(task, files, budget):
    import g2opy as g2o
    import numpy as np

    _IMPORTED.append(peak_rss_mib())
    if task != "gn_t2v":
        raise ValueError(task)

    def prepare():  # untimed: a fresh graph at the start, first pose fixed
        opt = g2o.SparseOptimizer()
        if not opt.load(files["g2o"]):
            raise RuntimeError(f"g2o could not read {files['g2o']}")
        opt.set_algorithm(
            g2o.OptimizationAlgorithmGaussNewton(g2o.BlockSolverSE2(g2o.LinearSolverEigenSE2()))
        )
        opt.vertex(min(opt.vertices())).set_fixed(True)
        stop = g2o.SparseOptimizerTerminateAction()  # g2o's own stopping rule (-gain)
        stop.set_gain_threshold(TOL)
        stop.set_max_iterations(MAX_ITERATIONS)
        opt.add_post_iteration_action(stop)
        if not _LOADED:
            _LOADED.append(peak_rss_mib())
        return opt

    def run(opt):
        opt.initialize_optimization()
        return None, (opt, opt.optimize(MAX_ITERATIONS))

    best, walls, _, (opt, its), par = timed(run, prepare)
    ids = np.array(sorted(opt.vertices()))
    opt.compute_active_errors()
    rec = {"iterations": int(its), "native_chi2": float(opt.active_chi2())}
    arrays = {
        "ids": ids,
        "poses": np.array([opt.vertex(int(i)).estimate().to_vector() for i in ids]),
    }
    return best, walls, par, rec, arrays


def _make_child(row, files, seed, start):
    """Write the row's problem: ``.npz`` for lagolib, ``.g2o`` (vertices = the start) for peers."""
    import numpy as np

    from lagolib import datasets, io, simulate
    from lagolib.lago import lago

    n = simulated_size(row)
    if n is not None:
        graph = simulate.manhattan_world(n_poses=n, extent=extent_for(n), rng=seed).graph
    else:
        graph = datasets.load(row)
    if start == "lago":
        graph = graph.with_poses(lago(graph).poses)  # the default tree (min_uncertainty)
    else:
        graph = graph.with_poses(graph.odometry_guess())
    start = graph.poses
    np.savez(
        files["npz"],
        ids=graph.ids,
        start=start,
        edges=graph.edges,
        measurements=graph.measurements,
        information=graph.information,
    )
    io.write_g2o(graph, files["g2o"])
    return {"n": int(graph.n), "m": int(graph.m)}


def child(spec):
    """Run one measurement; print one JSON line; save arrays to ``spec["files"]["out"]``."""
    who, task, files = spec["who"], spec["task"], spec["files"]
    if who == "make":
        print(json.dumps(_make_child(spec["row"], files, spec["seed"], spec["start"])))
        return
    import numpy as np

    run = {"lagolib": _lagolib_child, "gtsam": _gtsam_child, "g2o": _g2o_child}[who]
    best, walls, par, rec, arrays = run(task, files, spec.get("budget", 0.0))
    np.savez(files["out"], **arrays)
    rec.update(
        best=best,
        walls=walls,
        cpu_per_wall=par,
        rss_imported=_IMPORTED[0] if _IMPORTED else None,
        rss_loaded=_LOADED[0] if _LOADED else None,
        rss_peak=_FIRST_RUN[0][0] if _FIRST_RUN else peak_rss_mib(),
        hwm_peak=_FIRST_RUN[0][1] if _FIRST_RUN else vmhwm_mib(),
        rss_peak_all_runs=peak_rss_mib(),
    )
    print(json.dumps(rec))


# ----------------------------------------------------------------------------------------------
# parent
# ----------------------------------------------------------------------------------------------


def machine():
    """``nproc``, CPU model, RAM, OS, load average and the thread variables, as a dict."""
    cpu = ram = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                ram = f"{int(line.split()[1]) / 2**20:.1f} GiB"
    except OSError:
        pass
    return {
        "nproc": len(os.sched_getaffinity(0))
        if hasattr(os, "sched_getaffinity")
        else os.cpu_count(),
        "cpu": cpu,
        "ram": ram,
        "os": platform.platform(),
        "python": platform.python_version(),
        "threads": {v: os.environ.get(v, "unset") for v in THREAD_VARS},
    }


def run_child(spec, timeout):
    """Run ``spec`` in a fresh process; its JSON record (with its arrays), or ``{"error": ...}``."""
    # Through a small shell that forks the child: on Linux ``ru_maxrss`` survives ``execve``, so
    # a child forked straight from this process would start at our RSS (benchmarks/run_all.py).
    cmd = ["/bin/sh", "-c", '"$0" "$@"; exit $?', sys.executable, str(Path(__file__).resolve())]
    cmd += ["--child", json.dumps(spec)]
    label = f"{spec['row']:<10} {spec['who']:<8} {spec['task']:<7}"
    t = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        print(f"  {label} TIMEOUT after {timeout:.0f} s", flush=True)
        return {"error": f"timeout after {timeout:.0f} s"}
    elapsed = time.perf_counter() - t
    if proc.returncode != 0:
        err = (proc.stderr.strip().splitlines() or [f"exit status {proc.returncode}"])[-1]
        print(f"  {label} FAILED: {err}", flush=True)
        return {"error": err}
    rec = json.loads(proc.stdout.strip().splitlines()[-1])
    out = spec["files"].get("out")
    if out and Path(out).exists():
        import numpy as np

        with np.load(out) as z:
            rec.update({k: z[k] for k in z.files})
        Path(out).unlink()
    if rec.get("walls"):
        print(
            f"  {label} {fmt_s(rec['best'])} (best of {len(rec['walls'])}), peak RSS "
            f"{rec['rss_peak']:.0f} MiB, {elapsed:.0f} s in all",
            flush=True,
        )
    return rec


def fmt_s(seconds):
    """Seconds with 3 significant digits, in ms below 1 s."""
    if seconds is None or not math.isfinite(seconds):
        return "—"
    if seconds < 1.0:
        ms = 1e3 * seconds
        return f"{ms:.3g} ms" if ms >= 1 else f"{ms:.2f} ms"
    return f"{seconds:.3g} s"


def fmt_mib(peak, loaded):
    if peak is None:
        return "—"
    return f"{peak:,.0f}" + ("" if loaded is None else f" ({loaded:,.0f})")


def fmt_ratio(r, target=None, *, strict=False):
    """``r`` with ✓ when it meets ``target`` (``r <= target``, ``r < target`` when strict)."""
    if r is None or not math.isfinite(r):
        return "—"
    ok = target is not None and (r < target if strict else r <= target)
    mark = "" if target is None else (" ✓" if ok else " ✗")
    return f"{r:.2f}{mark}"


def _get(results, row, who, task, key="best"):
    rec = results.get((row, who, task))
    if not rec or "error" in rec:
        return None
    return rec.get(key)


def _ratio(a, b):
    return a / b if a is not None and b not in (None, 0) else None


def _ratio_free_diff(a, b):
    return a - b if a is not None and b is not None and a > b else None


def _gn1_total(rec):
    return sum(rec["phases"].values()) if rec and "phases" in rec else None


class Problem:
    """The row's graph, read back from its ``.npz`` for the parent's χ² checks (lazily)."""

    def __init__(self, files):
        self.files, self._graph = files, None

    @property
    def graph(self):
        if self._graph is None:
            self._graph = _load_lagolib_graph(self.files)
        return self._graph

    def rows_of(self, rec):
        """The record's poses in the rows of the graph (peers return them in key order)."""
        import numpy as np

        g = self.graph
        if "ids" not in rec:
            return rec["poses"]
        return rec["poses"][np.searchsorted(rec["ids"], g.ids)]

    def chi2(self, rec, error):
        import lagolib

        if not rec or "poses" not in rec:
            return None
        return float(lagolib.chi2(self.graph, self.rows_of(rec), error=error))


def certify_section(rows, sizes, results):
    """Issue 26's table: ``certify.solve`` against lagolib's LAGO + GN, and its peak RSS
    against GTSAM's GN (from the same LAGO start on the simulated rows)."""
    CT = CERTIFY_TARGETS
    L = [
        "",
        "## certify.solve against the plain pipeline (issue 26)",
        "",
        "`lagolib.certify.solve(graph)` (LAGO → GN → chordal polish → certificate [→ escape] → "
        "GN) against `optimize(graph, lago(graph).poses)` (LAGO with its default tree, then GN: "
        "t2v, first pose fixed) in the same run, each on a freshly read graph per run (cold: no "
        "ordering cached by an earlier run), best of 3 up to "
        f"{PIPELINE_SINGLE_RUN:g} s per run; peak RSS (`ru_maxrss`, MiB, through the first run) "
        "against GTSAM's GN (the `gn` task above). Targets: time ratio ≤ "
        f"{CT['time']}; RSS ratio ≤ {CT['rss']} from {CT['rss_from']:,} poses. The "
        "certificate's factorization (complex Hermitian, 2n − 1 rows): `pardiso` (MKL) or "
        "`cholmod` (cvxopt, without MKL) from 5 × 10^4 real rows, else `superlu` (SciPy).",
        "",
        "| row | poses | certify.solve | LAGO + GN | ratio | certified | f | certificate "
        "engine | LAGO / GN / polish / certificate / escape | RSS certify.solve | RSS LAGO + GN "
        "| RSS GTSAM GN | RSS ratio |",
        "|---|--:|--:|--:|--:|:-:|--:|:-:|--:|--:|--:|--:|--:|",
    ]
    for r in rows:
        rec = results.get((r, "lagolib", "certify"))
        if not rec or "error" in rec:
            continue
        n = sizes[r][0]
        a, b = rec.get("best"), _get(results, r, "lagolib", "lago_gn")
        ph = rec.get("phases", {})
        split = " / ".join(
            fmt_s(ph.get(k)) for k in ("lago", "gauss_newton", "refine", "certify", "escape")
        )
        ra = rec.get("rss_peak")
        rb = _get(results, r, "lagolib", "lago_gn", "rss_peak")
        rg = _get(results, r, "gtsam", "gn", "rss_peak")
        rss_target = CT["rss"] if n >= CT["rss_from"] else None
        L.append(
            "| " + " | ".join([
                r, f"{n:,}", fmt_s(a), fmt_s(b), fmt_ratio(_ratio(a, b), CT["time"]),
                "yes" if rec.get("certified") else "no", f"{rec.get('f', float('nan')):.10g}",
                rec.get("engine", "—"), split, fmt_mib(ra, None), fmt_mib(rb, None),
                fmt_mib(rg, None), fmt_ratio(_ratio(ra, rg), rss_target),
            ]) + " |"
        )  # fmt: skip
    return L


def growth(sizes, times):
    """Slope of log(time) against log(poses) by least squares, or None below 2 points."""
    import numpy as np

    pts = [(n, t) for n, t in zip(sizes, times) if t]
    if len(pts) < 2:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(x, y, 1)[0])


def report(args, rows, sizes, results, checks, info, started, elapsed, load):
    """The Markdown report (also printed)."""
    T = TARGETS
    sim = [r for r in rows if simulated_size(r)]
    L = [
        "# lagolib at scale: lagolib / GTSAM from 1e3 to 1e6 poses",
        "",
        "Written by `benchmarks/bench_scale.py` — do not edit by hand; run it again.",
        "",
        f"- Date: {started:%Y-%m-%d %H:%M} UTC; run time {elapsed / 60:.1f} min",
        f"- Command: `{' '.join(['python benchmarks/bench_scale.py', *args.argv])}`",
        f"- Machine: {info['cpu']}, nproc {info['nproc']}, {info['ram']} RAM; {info['os']}; "
        f"Python {info['python']}",
        "- Versions: " + ", ".join(f"{p} {package_version(p)}" for p in PACKAGES),
        "- Install: " + install_label(),
        f"- Load average (1/5/15 min): {'/'.join(f'{x:.2f}' for x in load[0])} at the start, "
        f"{'/'.join(f'{x:.2f}' for x in load[1])} at the end (other jobs on the same cores change "
        "absolute times; compare the ratios of one run)",
        "- Threads: BLAS, MKL (PARDISO) and GTSAM (TBB) at their defaults, i.e. all "
        f"{info['nproc']} cores for both libraries ("
        + ", ".join(f"{k}={v}" for k, v in info["threads"].items())
        + ")",
        f"- Simulated rows: `lagolib.simulate.manhattan_world(n_poses=N, extent=extent_for(N), "
        f"rng={args.seed})` with `extent_for(N) = round(sqrt(N / {POSES_PER_POINT:g}))`",
        f"- Start of GN (`--start {args.start}`): "
        + ", ".join(f"{r} {sizes[r][2]}" for r in rows)
        + " (odometry: the odometry guess; lago: lagolib's LAGO with its default tree)",
        "",
        "Times: best of 3 runs (a single run when it takes over 2 s) in one fresh process per "
        "(row, library, task); ratio = lagolib / peer (< 1: lagolib faster); ✓/✗ against the "
        "target of issue 15.",
        "",
        "## lagolib / GTSAM",
        "",
        f"| row | poses | edges | LAGO lagolib | LAGO GTSAM | ratio (≤ {T['lago']}) | "
        f"GN iteration lagolib | GN iteration GTSAM | ratio (≤ {T['gn1']}) | "
        "GN to convergence lagolib | GTSAM | ratio | "
        f"all marginals lagolib | GTSAM | ratio (≤ {T['marg']} on M3500, city10000) |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for r in rows:
        n, m, _ = sizes[r]
        cells = [r, f"{n:,}", f"{m:,}"]
        for task, target in (
            ("lago", T["lago"]),
            ("gn1", T["gn1"]),
            ("gn", None),
            ("marg", T["marg"]),
        ):
            if task == "gn1":
                a = _gn1_total(results.get((r, "lagolib", task)))
                b = _gn1_total(results.get((r, "gtsam", task)))
            else:
                a, b = _get(results, r, "lagolib", task), _get(results, r, "gtsam", task)
            if task == "marg" and r not in DATASETS:
                target = None
            if task == "marg" and _get(results, r, "gtsam", task, "done"):  # lower bound
                q = _ratio(a, b)
                cells += [fmt_s(a), f"> {fmt_s(b)}*", "—" if q is None else f"< {q:.2f}"]
                continue
            cells += [fmt_s(a), fmt_s(b), fmt_ratio(_ratio(a, b), target)]
        L.append("| " + " | ".join(cells) + " |")

    partial = [
        f"{r} ({_get(results, r, 'gtsam', 'marg', 'done'):,} of {sizes[r][0]:,} poses)"
        for r in rows
        if _get(results, r, "gtsam", "marg", "done")
    ]
    if partial:
        L += [
            "",
            "\\* `gtsam.Marginals` stopped at its time budget (`--marginals-budget` "
            f"{args.marginals_budget:g} s), so its time is a lower bound and the ratio an upper "
            "bound (its first poses cost more than the later ones, whose shortcuts in the "
            "Bayes tree are cached, so no extrapolation is given): " + ", ".join(partial) + ".",
        ]
    if any(results.get((r, "lagolib", "certify")) for r in rows):
        L += certify_section(rows, sizes, results)
    L += [
        "",
        "## One warm Gauss–Newton iteration (the 2nd), split",
        "",
        "lagolib: `LinearSystem.assemble` (H, b, χ²) / `SparseCholesky.refactor` (numeric "
        "factorization, analysis reused) / `.solve` / `update` + χ² of the new point. GTSAM: "
        "`linearize` / `eliminateMultifrontal(ordering)` (COLAMD, computed once, as its "
        "optimizer does) / `BayesTree.optimize` / `retract` + `error`. Target: lagolib's "
        f"iteration ≤ {T['own']} × its own factorization.",
        "",
        "| row | backend | lagolib assembly | factorization | solve | evaluation | total | "
        f"total / factorization (≤ {T['own']}) | GTSAM linearize | eliminate | back-substitute | "
        "retract + error | total |",
        "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    keys = ("assembly", "factorization", "solve", "evaluation")
    for r in rows:
        a, b = results.get((r, "lagolib", "gn1")), results.get((r, "gtsam", "gn1"))
        cells = [r, a.get("backend", "—") if a and "error" not in a else "—"]
        if a and "phases" in a:
            p = a["phases"]
            own = _gn1_total(a) / p["factorization"]
            cells += [fmt_s(p[k]) for k in keys] + [fmt_s(_gn1_total(a)), fmt_ratio(own, T["own"])]
        else:
            cells += ["—"] * 6
        if b and "phases" in b:
            cells += [fmt_s(b["phases"][k]) for k in keys] + [fmt_s(_gn1_total(b))]
        else:
            cells += ["—"] * 5
        L.append("| " + " | ".join(cells) + " |")

    L += [
        "",
        "## Peak resident memory (MiB) per process",
        "",
        "`ru_maxrss` of the child at the end of the task's first run (the library, the problem "
        "and one call), "
        "in parentheses right after importing the library and loading the problem (lagolib: "
        "the `.npz` into a `PoseGraph`; GTSAM: `readG2o`); target ≤ 1.0 × GTSAM.",
        "",
        "| row | LAGO lagolib | GTSAM | ratio | GN iteration lagolib | GTSAM | ratio | "
        "GN to convergence lagolib | GTSAM | ratio | marginals lagolib | GTSAM | ratio |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for r in rows:
        cells = [r]
        for task in ("lago", "gn1", "gn", "marg"):
            a = _get(results, r, "lagolib", task, "rss_peak")
            b = _get(results, r, "gtsam", task, "rss_peak")
            a0 = _get(results, r, "lagolib", task, "rss_loaded")
            b0 = _get(results, r, "gtsam", task, "rss_loaded")
            cells += [fmt_mib(a, a0), fmt_mib(b, b0), fmt_ratio(_ratio(a, b), T["rss"])]
        L.append("| " + " | ".join(cells) + " |")

    if sim:
        L += [
            "",
            "## Growth exponents",
            "",
            "Slope of log(time) against log(poses) over the simulated rows "
            f"({', '.join(sim)}): 1 is linear.",
            "",
            "| | LAGO | GN iteration | GN to convergence | all marginals | "
            "peak RSS of GN above the RSS after import |",
            "|---|--:|--:|--:|--:|--:|",
        ]
        ns = [sizes[r][0] for r in sim]
        for who in ("lagolib", "gtsam"):
            cells = [who]
            for task in ("lago", "gn1", "gn", "marg", "rss"):
                if task == "gn1":
                    ts = [_gn1_total(results.get((r, who, task))) for r in sim]
                elif task == "rss":
                    ts = [
                        _ratio_free_diff(
                            _get(results, r, who, "gn", "rss_peak"),
                            _get(results, r, who, "gn", "rss_imported"),
                        )
                        for r in sim
                    ]
                else:
                    ts = [
                        None if _get(results, r, who, task, "done") else _get(results, r, who, task)
                        for r in sim
                    ]
                k = growth(ns, ts)
                cells.append("—" if k is None else f"{k:.2f}")
            L.append("| " + " | ".join(cells) + " |")

    L += [
        "",
        "## Orderings: AMD (qdldl) vs nested dissection (METIS in MKL PARDISO)",
        "",
        "H of the GN problem at the start (prior on the first pose). nnz(L) includes the "
        "diagonal. AMD flops are Σ_j c_j² with c_j the entries of column j of L (diagonal "
        "included), computed from qdldl's factor; ND flops are PARDISO's own report "
        "(`iparm[18]`). First = ordering + symbolic + numeric factorization; refactor = numeric "
        "only, the analysis reused.",
        "",
        "| row | N | nnz(H), both triangles | AMD nnz(L) | AMD Mflop | qdldl first | qdldl refactor | "
        "ND nnz(L) | ND Mflop | PARDISO first | PARDISO refactor | nnz ratio ND/AMD |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for r in rows:
        o = results.get((r, "lagolib", "order"))
        if not o or "error" in o:
            continue
        a, d = o["amd"], o.get("nd")
        cells = [r, f"{o['N']:,}", f"{o['nnz_H']:,}", f"{a['nnz_L']:,}", f"{a['mflop']:,.0f}"]
        cells += [fmt_s(a["first"]), fmt_s(a["refactor"])]
        if d:
            cells += [f"{d['nnz_L']:,}", f"{d['mflop']:,.0f}", fmt_s(d["first"])]
            cells += [fmt_s(d["refactor"]), f"{d['nnz_L'] / a['nnz_L']:.2f}"]
        else:
            cells += ["—"] * 5
        L.append("| " + " | ".join(cells) + " |")

    g2o_rows = [r for r in rows if (r, "g2o", "gn_t2v") in results]
    if g2o_rows:
        L += [
            "",
            "## Gauss–Newton to convergence: lagolib vs g2o (g2opy)",
            "",
            "Both with g2o's residual (t2v), the first pose fixed, the same start; g2o: "
            "`OptimizationAlgorithmGaussNewton(BlockSolverSE2(LinearSolverEigenSE2))`, its "
            "gain threshold 1e-10. Target: lagolib faster.",
            "",
            "| row | lagolib | iterations | χ² | g2o | iterations | χ² | ratio (< 1) |",
            "|---|--:|--:|--:|--:|--:|--:|--:|",
        ]
        for r in g2o_rows:
            a, b = results.get((r, "lagolib", "gn_t2v")), results.get((r, "g2o", "gn_t2v"))
            ta, tb = _get(results, r, "lagolib", "gn_t2v"), _get(results, r, "g2o", "gn_t2v")
            ca, cb = checks.get((r, "lagolib", "gn_t2v")), checks.get((r, "g2o", "gn_t2v"))
            L.append(
                f"| {r} | {fmt_s(ta)} | {(a or {}).get('iterations', '—')} | {fmt_chi(ca)} | "
                f"{fmt_s(tb)} | {(b or {}).get('iterations', '—')} | {fmt_chi(cb)} | "
                f"{fmt_ratio(_ratio(ta, tb), T['gn_t2v'], strict=True)} |"
            )

    L += [
        "",
        "## Checks: both libraries solve the same problem",
        "",
        "χ² recomputed by `lagolib.chi2` from each library's poses (edges only, priors "
        "excluded): LAGO with t2v, GN with the log residual. Marginals: both at lagolib's GN "
        "optimum, local frame; the first pose has the prior. LAGO with the odometric tree "
        "(both libraries) and lagolib's default tree (min_uncertainty, lagolib only): on long "
        "odometric paths the tree's noise approaches ±π, the regularization of some chords "
        "flips (lagolib warns) and the two libraries' estimates differ.",
        "",
        "| row | LAGO χ² lagolib | GTSAM | LAGO default tree: time, χ² | "
        "GN iterations lagolib / GTSAM | GN χ² lagolib | GTSAM | "
        "relative difference | marginals max abs(ΔΣ) / max abs(Σ) |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for r in rows:
        la, lb = checks.get((r, "lagolib", "lago")), checks.get((r, "gtsam", "lago"))
        mu = f"{fmt_s(_get(results, r, 'lagolib', 'lago_mu'))}, "
        mu += fmt_chi(checks.get((r, "lagolib", "lago_mu")))
        ga, gb = checks.get((r, "lagolib", "gn")), checks.get((r, "gtsam", "gn"))
        ia = (results.get((r, "lagolib", "gn")) or {}).get("iterations", "—")
        ib = (results.get((r, "gtsam", "gn")) or {}).get("iterations", "—")
        rel = abs(ga - gb) / gb if ga is not None and gb else None
        L.append(
            f"| {r} | {fmt_chi(la)} | {fmt_chi(lb)} | {mu} | {ia} / {ib} | {fmt_chi(ga)} | "
            f"{fmt_chi(gb)} | {'—' if rel is None else f'{rel:.1e}'} | "
            f"{checks.get((r, 'marg'), '—')} |"
        )

    L += [
        "",
        "## Where lagolib's time goes",
        "",
        "GN to convergence: its setup (gauge, pattern) and its iterations' assembly, solve "
        "(factorization + substitution) and evaluation (update + χ²), summed; LAGO: its phases.",
        "",
        "| row | GN total | setup | assembly | solve | evaluation | LAGO total | "
        "regularization | phase 1 | phase 2 | phase 3 |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for r in rows:
        g, lg = results.get((r, "lagolib", "gn")), results.get((r, "lagolib", "lago"))
        cells = [r]
        if g and "phases" in g:
            cells += [fmt_s(g["best"])] + [
                fmt_s(g["phases"][k]) for k in ("setup", "assembly", "solve", "evaluation")
            ]
        else:
            cells += ["—"] * 5
        if lg and "phases" in lg:
            ph = lg["phases"]
            cells += [fmt_s(lg["best"])] + [
                fmt_s(ph.get(k)) for k in ("regularization", "phase1", "phase2", "phase3")
            ]
        else:
            cells += ["—"] * 5
        L.append("| " + " | ".join(cells) + " |")

    L += ["", "## Targets of issue 15", ""] + targets(rows, results)
    failed = [
        f"{r} {who} {task}: {rec['error']}"
        for (r, who, task), rec in results.items()
        if rec and "error" in rec
    ]
    skipped = [f"{r} {who} {task}" for (r, who, task), rec in results.items() if rec is None]
    if failed or skipped:
        L += [""]
        if failed:
            L += ["Failed: " + "; ".join(failed) + "."]
        if skipped:
            L += ["Not run: " + "; ".join(skipped) + "."]
    par = [
        f"{r} {who} {task} {rec['cpu_per_wall']:.1f}"
        for (r, who, task), rec in results.items()
        if rec and "cpu_per_wall" in rec and rec["cpu_per_wall"] > 1.2 and rec["best"] > 0.05
    ]
    if par:
        L += ["", "CPU time / wall time above 1.2 (more than one thread busy): " + ", ".join(par)]
    gaps = [
        abs(rec["rss_peak"] - rec["hwm_peak"])
        for rec in results.values()
        if rec and "rss_peak" in rec and math.isfinite(rec.get("hwm_peak", math.nan))
    ]
    if gaps:
        L += ["", f"`ru_maxrss` and `VmHWM` of the children agree within {max(gaps):.1f} MiB."]
    return "\n".join(L) + "\n"


def targets(rows, results):
    """The issue's targets, one line each, with the measured ratios and ✓/✗."""

    def line(title, items, limit, strict=False):
        cells = []
        for r, v in items:
            ok = v is not None and (v < limit if strict else v <= limit)
            cells.append(f"{r} {'—' if v is None else f'{v:.2f}'} {'✓' if ok else '✗'}")
        return f"- {title}: " + ("; ".join(cells) if cells else "not measured")

    sim = [r for r in rows if simulated_size(r)]
    out = []
    T = TARGETS
    for task, title in (("lago", "LAGO"), ("gn1", "GN iteration")):
        items = []
        for r in sim:
            if task == "gn1":
                a = _gn1_total(results.get((r, "lagolib", task)))
                b = _gn1_total(results.get((r, "gtsam", task)))
            else:
                a, b = _get(results, r, "lagolib", task), _get(results, r, "gtsam", task)
            items.append((r, _ratio(a, b)))
        out.append(line(f"{title} ≤ {T[task]} × GTSAM (simulated rows)", items, T[task]))
    items = []
    for r in sim:
        ratios = [
            _ratio(
                _get(results, r, "lagolib", t, "rss_peak"), _get(results, r, "gtsam", t, "rss_peak")
            )
            for t in ("lago", "gn1", "gn", "marg")
        ]
        ratios = [x for x in ratios if x is not None]
        items.append((r, max(ratios) if ratios else None))
    title = f"peak RSS ≤ {T['rss']} × GTSAM (largest ratio over LAGO, GN, marginals)"
    out.append(line(title, items, T["rss"]))
    items = []
    for r in rows:
        a = results.get((r, "lagolib", "gn1"))
        if a and "phases" in a:
            items.append((r, _gn1_total(a) / a["phases"]["factorization"]))
    out.append(line(f"GN iteration ≤ {T['own']} × its own factorization", items, T["own"]))
    items = [
        (r, _ratio(_get(results, r, "lagolib", "marg"), _get(results, r, "gtsam", "marg")))
        for r in rows
        if r in DATASETS
    ]
    out.append(line(f"all marginals ≤ {T['marg']} × gtsam.Marginals", items, T["marg"]))
    items = [
        (r, _ratio(_get(results, r, "lagolib", "gn_t2v"), _get(results, r, "g2o", "gn_t2v")))
        for r in rows
        if (r, "g2o", "gn_t2v") in results
    ]
    title = f"GN to convergence faster than g2o (ratio < {T['gn_t2v']})"
    out.append(line(title, items, T["gn_t2v"], strict=True))
    return out


def fmt_chi(value):
    return "—" if value is None else f"{value:.10g}"


def compute_checks(problem, row, results):
    """χ² of every result from its poses (one function for all), and the marginals' agreement."""
    import numpy as np

    checks = {}
    for who, task, error in (
        ("lagolib", "lago", "t2v"),
        ("gtsam", "lago", "t2v"),
        ("lagolib", "lago_mu", "t2v"),
        ("lagolib", "gn", "log"),
        ("gtsam", "gn", "log"),
        ("lagolib", "gn_t2v", "t2v"),
        ("g2o", "gn_t2v", "t2v"),
    ):
        rec = results.get((row, who, task))
        if rec and "poses" in rec:
            checks[row, who, task] = problem.chi2(rec, error)
            del rec["poses"]  # free the parent's memory
    a, b = results.get((row, "lagolib", "marg")), results.get((row, "gtsam", "marg"))
    if a and b and "cov" in a and "cov" in b:
        ids = problem.graph.ids
        order = np.argsort(ids)
        rows = order[np.searchsorted(ids[order], b["ids"])]  # GTSAM's poses (maybe a prefix)
        ca, cb = a["cov"][rows], b["cov"]
        rel = float(np.abs(ca - cb).max() / np.abs(cb).max())
        checks[row, "marg"] = f"{rel:.1e}"
    for rec in (a, b):
        if rec:
            rec.pop("cov", None)
    return checks


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--rows",
        nargs="+",
        default=None,
        help=f"rows to run: simulated sizes (1e3 ...) or datasets (default {' '.join(DEFAULT_ROWS)})",
    )
    ap.add_argument("--huge", action="store_true", help="add the 1e6-pose row (minutes, 6+ GB)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the simulated worlds (default 0)")
    ap.add_argument(
        "--start",
        choices=("auto", "odometry", "lago"),
        default="auto",
        help="start of GN (default auto: odometry on the datasets, LAGO on simulated worlds)",
    )
    ap.add_argument("--out", default=str(HERE / "SCALE.md"), help="Markdown report ('-': none)")
    ap.add_argument(
        "--marginals-max",
        type=float,
        default=1e5,
        help="all marginals on rows up to this many poses (default 1e5)",
    )
    ap.add_argument(
        "--tasks",
        nargs="+",
        default=list(WHO),
        choices=list(WHO),
        help="tasks to run (default all)",
    )
    ap.add_argument(
        "--marginals-budget",
        type=float,
        default=900.0,
        help="seconds after which gtsam.Marginals stops and its time for all poses is "
        "extrapolated from its time per pose so far (default 900; 0: no limit)",
    )
    ap.add_argument(
        "--timeout", type=float, default=3600.0, help="seconds per child (default 3600)"
    )
    ap.add_argument(
        "--workdir", help="keep the problem files here (default: a temporary directory)"
    )
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(json.loads(args.child))
        return
    args.argv = list(sys.argv[1:] if argv is None else argv)
    rows = list(args.rows or DEFAULT_ROWS) + (list(HUGE_ROWS) if args.huge else [])
    if any(r in DATASETS for r in rows) and not os.environ.get("LAGOLIB_DATA"):
        print("note: LAGOLIB_DATA is unset; M3500 and city10000 may be downloaded or fail")
    t_start, load_start = time.perf_counter(), os.getloadavg()
    started = datetime.datetime.now(datetime.timezone.utc)
    info = machine()
    have = {who: importable(mod) for who, mod in MODULES.items()}
    print(f"libraries importable: {have}; machine: {info['cpu']}, nproc {info['nproc']}")
    results, checks, sizes = {}, {}, {}
    tmp = None
    if args.workdir:
        work = Path(args.workdir)
        work.mkdir(parents=True, exist_ok=True)
    else:
        tmp = tempfile.TemporaryDirectory(prefix="bench_scale_")
        work = Path(tmp.name)
    try:
        for row in rows:
            start = start_of(row, args.start)
            base = work / (f"{row}-seed{args.seed}" if simulated_size(row) else row)
            base = Path(f"{base}-{start}")
            files = {
                "npz": f"{base}.npz",
                "g2o": f"{base}.g2o",
                "optimum": f"{base}.optimum.npy",
            }
            spec = {
                "row": row,
                "who": "make",
                "task": "make",
                "files": files,
                "seed": args.seed,
                "start": start,
            }
            if Path(files["npz"]).exists() and Path(files["g2o"]).exists():
                import numpy as np

                with np.load(files["npz"]) as z:
                    made = {"n": int(z["ids"].size), "m": int(z["edges"].shape[0])}
            else:
                made = run_child(spec, args.timeout)
            if "error" in made:
                print(f"{row}: could not make the problem: {made['error']}")
                continue
            sizes[row] = (made["n"], made["m"], start)
            print(f"{row}: {made['n']:,} poses, {made['m']:,} edges, start {start}", flush=True)
            for task in args.tasks:
                if task == "gn_t2v" and row not in DATASETS:
                    continue
                for who in WHO[task]:
                    key = (row, who, task)
                    if not have[who]:
                        continue
                    if task == "marg" and made["n"] > args.marginals_max:
                        results[key] = None
                        continue
                    if task == "marg" and not Path(files["optimum"]).exists():
                        results[key] = {"error": "no lagolib GN optimum (run the gn task)"}
                        continue
                    out = str(work / f"{row}-{who}-{task}.npz")
                    results[key] = run_child(
                        {
                            "row": row,
                            "who": who,
                            "task": task,
                            "files": {**files, "out": out},
                            "budget": args.marginals_budget,
                        },
                        args.timeout,
                    )
            problem = Problem(files)
            checks.update(compute_checks(problem, row, results))
            del problem
    finally:
        if tmp is not None:
            tmp.cleanup()
    elapsed = time.perf_counter() - t_start
    text = report(
        args,
        [r for r in rows if r in sizes],
        sizes,
        results,
        checks,
        info,
        started,
        elapsed,
        (load_start, os.getloadavg()),
    )
    print()
    print(text)
    if args.out != "-":
        Path(args.out).write_text(text, encoding="utf-8")
        print(f"written to {args.out}")


if __name__ == "__main__":
    main()
