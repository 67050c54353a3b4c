"""The numbers of issue 14's closing note: is the answer the global optimum, and what does it cost?

    LAGOLIB_DATA=/path/to/mirror python benchmarks/bench_certify.py [--quick] [--runs 5]
        [--out benchmarks/CERTIFY.md]

Five parts, each measured in fresh subprocesses (this script with ``--child``; ``--parts``
picks some):

1. **Every graph of the mirror** that :mod:`lagolib.datasets` knows: the default pipeline
   ``lagolib.certify.solve(graph)`` (χ², chordal ``f``, the two smallest eigenvalues of the reduced
   certificate matrix, certified or relative gap, escapes, time and its split), the same pipeline
   from odometry, and GTSAM's ``lago.initialize`` + ``LevenbergMarquardtOptimizer`` on the same
   graph, its poses scored by ``lagolib.chi2``.  Every χ² is recomputed with one function, so the
   columns are the same cost.
2. **Cost of the certificate** on m3500 and city10000: ``certify(problem, poses)`` against one
   Gauss–Newton iteration (medians over ``--runs`` fresh processes), and the peak RSS of processes
   that only read the graph, or also run one GN iteration, certify, or run the whole pipeline.
3. **The noise sweep**: simulated Manhattan worlds over σ_θ, 10 seeds each: how often the pipeline
   certifies, how often LAGO + GN alone was already certified, escapes, gaps, and how often GTSAM
   ends above the pipeline.
4. **SE-Sync's published optima** (IJRR 2019, Table 1) from the SE-Sync-weighted graphs.
5. **Per-call fixed costs** (issue 26): ``certify.solve`` on a 200-pose world against GTSAM's
   ``lago.initialize`` + LM, warm, and the SciPy sparse matrices one call constructs.

Every child also checks the certificate against the other methods' points (a certified ``f``
must not be above another local minimum's chordal cost; every lower bound must be below every
chordal cost found) and the two smallest eigenvalues against an independent shift-and-invert
computation; violations are listed under "Anomalies" with a reproducer.

``--quick`` runs a small subset (< 1 min) and prints the report instead of writing it (unless
``--out`` is given).  Not a test: nothing here is asserted.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _timing import install_label  # benchmarks/ is on sys.path as a script
from _timing import package_version as _version
from run_all import machine

HERE = Path(__file__).resolve().parent
PACKAGES = ("numpy", "scipy", "qdldl", "mkl", "cvxopt", "gtsam", "lagolib")
#: GTSAM's prior on the first pose, as in its ``Pose2SLAMExample_lago``: variances (x, y, θ).
PRIOR_VARIANCES = (1e-6, 1e-6, 1e-8)
#: LM's stopping tolerances (relative and absolute decrease of the error): tight, so that the
#: comparison is of basins, not of where LM stopped (GTSAM's defaults are 1e-5).
LM_TOL = 1e-10
#: "Above" means more than this, relatively, plus ``ABS`` (noiseless graphs have χ²* = 0).
REL = 1e-6
ABS = 1e-9
SIGMAS = (0.01, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5)
SEEDS = 10
COST_DATASETS = ("m3500", "city10000")
#: dataset -> SE-Sync's published objective (Table 1, IJRR 2019), 4 digits
SESYNC = {"intel_sesync": 52.35, "csail": 31.70, "manhattan": 6432.0, "city10000": 638.6}


# ============================================================================ child side
def _maxrss_mib():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _load(name):
    from lagolib import datasets

    g = datasets.load(name)
    return getattr(g, "graph", g)


def _warm(with_gtsam=False):
    """Trigger every lazy import and cache on a small graph before anything is timed."""
    import warnings

    import lagolib
    from lagolib import certify, simulate

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = simulate.manhattan_world(n_poses=60, rng=0, sigma_theta=0.05).graph
        r = certify.solve(g)
        certify.certify(certify.chordal_problem(g), r.chordal_poses, eigenvalues=2)
        lagolib.optimize(g, g.poses, max_iterations=1, tol=0, step_tol=0)
        if with_gtsam:
            import gtsam

            fg, lago_fg, _ = gtsam_graphs(gtsam, g, None)
            gtsam_pipeline(gtsam, g, fg, lago_fg)


def gtsam_graphs(gtsam, graph, path):
    """``(fg, lago_fg, source)``: GTSAM's factor graph of the file, and a copy for ``lago``.

    ``fg`` is ``gtsam.readG2o(path, False)`` when GTSAM can read the file; else (TORO files, or
    no file: a simulation) it is built from lagolib's reading with the same information.
    ``gtsam.lago.initialize`` accepts only diagonal noise models ("current version assumes
    diagonal noise model"), so ``lago_fg`` has the diagonal of each information matrix where
    ``readG2o`` made a full Gaussian model; LM then runs on ``fg``.  Both carry the prior of
    ``Pose2SLAMExample_lago`` on the first key.
    """
    import numpy as np

    source = "readG2o"
    fg = None
    if path is not None:
        try:
            fg, _ = gtsam.readG2o(path, False)
        except RuntimeError as exc:
            source = f"built from lagolib's reading (readG2o: {str(exc).strip()[:60]})"
    else:
        source = "built from the PoseGraph"
    if fg is None:
        fg = gtsam.NonlinearFactorGraph()
        for k, (i, j) in enumerate(graph.edges):
            noise = gtsam.noiseModel.Gaussian.Information(graph.information[k])
            z = gtsam.Pose2(*graph.measurements[k])
            fg.add(gtsam.BetweenFactorPose2(int(graph.ids[i]), int(graph.ids[j]), z, noise))
    lago_fg = gtsam.NonlinearFactorGraph()
    rebuilt = 0
    for k in range(fg.size()):
        f = fg.at(k)
        nm = f.noiseModel()
        if isinstance(nm, gtsam.noiseModel.Diagonal):
            lago_fg.add(f)
        else:
            info = nm.R().T @ nm.R()
            diag = gtsam.noiseModel.Diagonal.Precisions(np.diag(info).copy())
            key1, key2 = f.keys()
            lago_fg.add(gtsam.BetweenFactorPose2(key1, key2, f.measured(), diag))
            rebuilt += 1
    if rebuilt:
        source += f"; LAGO on the diagonal information ({rebuilt} full models)"
    first = int(graph.ids[0])
    prior = gtsam.noiseModel.Diagonal.Variances(np.array(PRIOR_VARIANCES))
    for g_ in (fg, lago_fg):
        g_.add(gtsam.PriorFactorPose2(first, gtsam.Pose2(), prior))
    return fg, lago_fg, source


def gtsam_pipeline(gtsam, graph, fg, lago_fg):
    """GTSAM's ``lago.initialize`` + LM; returns (poses in lagolib's rows, seconds, iterations)."""
    import numpy as np

    t = time.perf_counter()
    init = gtsam.lago.initialize(lago_fg)
    params = gtsam.LevenbergMarquardtParams()
    params.setRelativeErrorTol(LM_TOL)
    params.setAbsoluteErrorTol(LM_TOL)
    params.setMaxIterations(100)
    opt = gtsam.LevenbergMarquardtOptimizer(fg, init, params)
    values = opt.optimize()
    seconds = time.perf_counter() - t
    poses = np.array([[values.atPose2(int(k)).x(), values.atPose2(int(k)).y(),
                       values.atPose2(int(k)).theta()] for k in graph.ids])  # fmt: skip
    return poses, seconds, opt.iterations()


def independent_eigenvalues(problem, poses, k=3, lambda_min=None):
    """The ``k`` smallest eigenvalues of ``S~``, independently of :func:`certify`'s machinery.

    ``K`` (:func:`reduced_certificate_matrix`) plus ``s I`` on the rotation rows, with a
    *moderate* shift ``s = 1e-3 mean |diag K_zz|`` (or ``2 |lambda_min|`` when larger), factored
    by SuperLU; shift-and-invert Lanczos on its rotation block, ``(S~ + s I)^-1``.  The real form
    repeats every eigenvalue, so every second one of the sorted list is kept.
    """
    import numpy as np
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from lagolib.certify import reduced_certificate_matrix

    K, zrows = reduced_certificate_matrix(problem, poses)
    flat = zrows.ravel()
    N = K.shape[0]
    s = 1e-3 * float(np.mean(np.abs(K.diagonal()[flat])))
    if lambda_min is not None and lambda_min < 0:
        s = max(s, 2.0 * abs(lambda_min))
    d = np.zeros(N)
    d[flat] = s
    lu = spla.splu((K + sp.diags(d)).tocsc())

    def op(v):
        rhs = np.zeros(N)
        rhs[flat] = np.ravel(v)
        return lu.solve(rhs)[flat]

    A = spla.LinearOperator((flat.size, flat.size), matvec=op, dtype=float)
    v0 = np.random.default_rng(1).standard_normal(flat.size)
    mu = spla.eigsh(A, k=min(2 * k, flat.size - 1), which="LA", v0=v0, tol=1e-12)[0]
    lam = np.sort(1.0 / mu - s)
    return lam[0::2][:k].tolist(), lam.tolist()


def _checks(name, res, others, eig_cert, eig_ind):
    """Anomalies: certified above another point's chordal minimum, bound above a chordal cost,
    eigenvalues disagreeing, negative cost."""
    out = []
    f = res.f
    scale = max(abs(f), 1.0)
    for label, f_other in others.items():
        if res.certified and f > f_other + 1e-8 * scale:
            out.append(
                f"{name}: certified f = {f!r} is above the chordal minimum {f_other!r} reached "
                f"from {label}"
            )
        if res.lower_bound > f_other + 1e-8 * scale:
            out.append(
                f"{name}: lower bound {res.lower_bound!r} is above the chordal cost {f_other!r} "
                f"of the point reached from {label}"
            )
    if f < 0:
        out.append(f"{name}: the certificate's f = {f!r} is negative (f = x^H M x >= 0)")
    if res.chi2 < ABS and not res.certified:
        out.append(
            f"{name}: the measurements are consistent (χ² = {res.chi2:.2g}: the optimum is "
            f"global, f* = 0) but the pipeline did not certify it: {res.reason!r} "
            f"(f = {f:.3g}, eta = {res.certificate.eta:.3g}, lambda_min = "
            f"{res.certificate.lambda_min!r})"
        )
    if eig_cert is not None and len(eig_cert) > 1 and len(eig_ind) > 1:
        tol = 1e-6 * max(abs(eig_ind[1]), 1e-8)
        if abs(eig_cert[1] - eig_ind[1]) > tol:
            out.append(
                f"{name}: certify(..., eigenvalues=2) gives lambda_2 = {eig_cert[1]:.6g}; an "
                f"independent shift-and-invert gives {eig_ind[1]:.6g} (lambda_1 = "
                f"{eig_cert[0]:.3g} / {eig_ind[0]:.3g})"
            )
    return out


def child_table(spec):
    """One pipeline run (timed) and one GTSAM run (timed); with ``extras`` the rest of a row."""
    import warnings

    import numpy as np

    import lagolib
    from lagolib import certify, datasets

    warnings.simplefilter("ignore")  # LAGO's RegularizationWarning on noisy graphs
    name = spec["dataset"]
    try:
        import gtsam
    except ImportError:
        gtsam = None
    _warm(with_gtsam=gtsam is not None)
    g = _load(name)
    path = str(datasets.path(name))
    out = {"n": g.n, "m": g.m}
    t = time.perf_counter()
    try:
        res = certify.solve(g)
    except Exception as exc:  # noqa: BLE001 - a failure is a result here
        out["error"] = f"{type(exc).__name__}: {exc}"
        out["anomalies"] = [f"{name}: lagolib.certify.solve(graph) raised {out['error']}"]
        return out
    out["wall"] = time.perf_counter() - t
    out["timings"] = dict(res.timings)
    gt = None
    if gtsam is not None:
        fg, lago_fg, source = gtsam_graphs(gtsam, g, path)
        try:
            gt, out["gtsam_wall"], out["gtsam_iterations"] = gtsam_pipeline(gtsam, g, fg, lago_fg)
        except RuntimeError as exc:
            out["gtsam_error"] = str(exc).strip().splitlines()[0][:100]
        out["gtsam_source"] = source
    if not spec.get("extras"):
        return out
    # ---- the rest of the row (untimed)
    p = certify.chordal_problem(g)
    cert2 = certify.certify(p, res.chordal_poses, eigenvalues=2)
    lm = res.certificate.lambda_min
    eig_ind, eig_all = independent_eigenvalues(p, res.chordal_poses, 3, lm)
    ours_log = lagolib.optimize(g, res.poses, error="log")
    out.update(
        chi2=res.chi2,
        f=res.f,
        f_direct=certify.chordal_cost(p, res.chordal_poses),
        certified=res.certified,
        escapes=res.escapes,
        reason=res.reason,
        lower_bound=res.lower_bound,
        relative_gap=res.relative_gap,
        eta=res.certificate.eta,
        eig_cert=cert2.eigenvalues.tolist(),
        cert2_certified=cert2.certified,
        eig_ind=eig_ind,
        eig_ind_all=eig_all,
        start_chi2=res.start_chi2,
        chi2_log=ours_log.chi2,
        stages=[
            {k: (v if isinstance(v, (int, float, str, bool)) else str(v)) for k, v in s.items()}
            for s in res.stages
        ],
    )
    others = {}
    try:
        odo = certify.solve(g, initial=g.poses)
        out["odo"] = {
            "chi2": odo.chi2,
            "f": odo.f,
            "certified": odo.certified,
            "escapes": odo.escapes,
            "lower_bound": odo.lower_bound,
            "reason": odo.reason,
            "start_chi2": odo.start_chi2,
        }
        others["odometry (solve(graph, initial=graph.poses))"] = odo.f
    except Exception as exc:  # noqa: BLE001
        out["odo"] = {"error": f"{type(exc).__name__}: {exc}"}
    if gt is not None:
        out["gtsam_chi2"] = lagolib.chi2(g, gt)
        out["gtsam_chi2_log"] = lagolib.chi2(g, gt, error="log")
        others["GTSAM lago+LM (chordal polish of its poses)"] = certify.refine(p, gt).chi2
        # the factor graph GTSAM optimized is the graph lagolib read: 2 x its error (prior
        # excluded) at our log optimum must be lagolib's log χ²
        values = gtsam.Values()
        for k, key in enumerate(g.ids):
            values.insert(int(key), gtsam.Pose2(*ours_log.poses[k]))
        fg, _, _ = gtsam_graphs(gtsam, g, path)
        prior = fg.at(fg.size() - 1).error(values)
        out["gtsam_consistency"] = abs(2 * (fg.error(values) - prior) - ours_log.chi2) / max(
            ours_log.chi2, 1e-300
        )
    out["others"] = others
    out["anomalies"] = _checks(name, res, others, out["eig_cert"], eig_ind)
    if "odo" in out and "error" not in out["odo"]:
        o = out["odo"]
        if o["certified"] and res.certified and abs(o["f"] - res.f) > 1e-7 * max(res.f, 1):
            out["anomalies"].append(
                f"{name}: two certified optima differ: f = {res.f!r} (LAGO start) and "
                f"{o['f']!r} (odometry start)"
            )
        if o["lower_bound"] > res.f + 1e-8 * max(res.f, 1):
            out["anomalies"].append(
                f"{name}: the odometry run's lower bound {o['lower_bound']!r} is above the LAGO "
                f"run's f = {res.f!r}"
            )
    if spec.get("poses_out"):
        np.save(spec["poses_out"], res.chordal_poses)
    return out


def child_cost(spec):
    """certify(problem, poses) against one GN iteration, in a warm process."""
    import numpy as np

    import lagolib
    from lagolib import certify

    _warm()
    g = _load(spec["dataset"])
    poses = np.load(spec["poses"])
    t = time.perf_counter()
    p = certify.chordal_problem(g)
    _ = p.M  # the data matrix, built and cached
    t_M = time.perf_counter() - t
    t = time.perf_counter()
    c = certify.certify(p, poses)
    t_first = time.perf_counter() - t
    cached = []
    for _ in range(3):
        t = time.perf_counter()
        certify.certify(p, poses)
        cached.append(time.perf_counter() - t)
    gn_core, gn_setup = [], []
    for _ in range(3):
        r = lagolib.optimize(g, g.poses, max_iterations=1, tol=0, step_tol=0)
        tm = r.timings
        gn_core.append(tm["assembly"][0] + tm["solve"][0] + tm["evaluation"][0])
        gn_setup.append(gn_core[-1] + tm["setup"])
    return {
        "M": t_M,
        "certify_first": t_first,
        "certify": statistics.median(cached),
        "gn_first": gn_core[0],
        "gn_setup_first": gn_setup[0],
        "gn": statistics.median(gn_core),
        "gn_setup": statistics.median(gn_setup),
        "certified": c.certified,
    }


def child_rss(spec):
    """Peak RSS of reading the graph and, by ``mode``, one GN iteration / certify / solve."""
    import numpy as np
    import qdldl  # noqa: F401 - every mode imports the same modules
    import scipy.sparse.linalg  # noqa: F401

    import lagolib
    from lagolib import certify

    rss_import = _maxrss_mib()
    g = _load(spec["dataset"])
    poses = np.load(spec["poses"])
    mode = spec["mode"]
    if mode == "gn1":
        lagolib.optimize(g, poses, max_iterations=1, tol=0, step_tol=0)
    elif mode == "certify":
        certify.certify(certify.chordal_problem(g), poses)
    elif mode == "solve":
        certify.solve(g)
    return {"rss_import": rss_import, "rss": _maxrss_mib()}


def child_sweep(spec):
    """One (N, σ_θ) cell of the noise sweep: every seed's pipeline, LAGO + GN, and GTSAM."""
    import warnings

    import lagolib
    from lagolib import certify, simulate

    warnings.simplefilter("ignore")
    try:
        import gtsam
    except ImportError:
        gtsam = None
    recs = []
    for seed in spec["seeds"]:
        kw = dict(n_poses=spec["N"], rng=seed, sigma_theta=spec["sigma"], sigma_xy=0.05)
        if spec.get("noiseless"):
            kw["noiseless"] = True
        g = simulate.manhattan_world(**kw).graph
        rec = {"seed": seed, "m": g.m}
        repro = (
            f"g = lagolib.simulate.manhattan_world({', '.join(f'{k}={v!r}' for k, v in kw.items())})"
            ".graph; r = lagolib.certify.solve(g)"
        )
        try:
            res = certify.solve(g)
        except Exception as exc:  # noqa: BLE001
            rec["error"] = f"{type(exc).__name__}: {exc}"
            rec["anomalies"] = [f"{repro} raised {rec['error']}"]
            recs.append(rec)
            continue
        gn_first = next(s for s in res.stages if s["stage"] == "Gauss-Newton")["chi2"]
        rec.update(
            chi2=res.chi2,
            f=res.f,
            certified=res.certified,
            escapes=res.escapes,
            reason=res.reason,
            lower_bound=res.lower_bound,
            relative_gap=res.relative_gap,
            lago_gn_chi2=gn_first,
            seconds=res.timings["total"],
        )
        others = {}
        p = certify.chordal_problem(g)
        if gtsam is not None:
            fg, lago_fg, _ = gtsam_graphs(gtsam, g, None)
            try:
                gt, _, _ = gtsam_pipeline(gtsam, g, fg, lago_fg)
                rec["gtsam_chi2"] = lagolib.chi2(g, gt)
                rec["gtsam_chi2_log"] = lagolib.chi2(g, gt, error="log")
                rec["chi2_log"] = lagolib.optimize(g, res.poses, error="log").chi2
                others["GTSAM lago+LM"] = certify.refine(p, gt).chi2
            except RuntimeError as exc:
                rec["gtsam_error"] = str(exc).strip().splitlines()[0][:100]
        rec["anomalies"] = [
            f"{repro}: {a.split(': ', 1)[1]}" for a in _checks("x", res, others, None, [])
        ]
        recs.append(rec)
    return {"records": recs}


def child_sesync(spec):
    """``solve`` on the SE-Sync-weighted graph: its ``f`` is SE-Sync's objective."""
    import warnings

    from lagolib import certify, metrics

    warnings.simplefilter("ignore")
    g = _load(spec["dataset"])
    g2 = g.with_information(metrics.sesync_weights(g).information)
    t = time.perf_counter()
    r = certify.solve(g2)
    return {
        "f": r.f,
        "certified": r.certified,
        "escapes": r.escapes,
        "lower_bound": r.lower_bound,
        "seconds": time.perf_counter() - t,
        "sesync_objective": metrics.sesync_objective(g, r.chordal_poses)
        if hasattr(metrics, "sesync_objective")
        else None,
    }


def child_fixed(spec):
    """Per-call fixed costs: ``certify.solve`` on a small world against GTSAM's
    ``lago.initialize`` + LM on the same graph, warm, median of ``spec["calls"]`` calls; and how
    many SciPy compressed sparse matrices one ``certify.solve`` constructs."""
    import warnings

    import gtsam
    import scipy.sparse._compressed as compressed

    from lagolib import certify, simulate

    warnings.simplefilter("ignore")
    g = simulate.manhattan_world(n_poses=spec["n"], extent=spec["extent"], rng=0).graph
    fg, lago_fg, _ = gtsam_graphs(gtsam, g, None)
    for _ in range(3):  # warm: imports, caches
        certify.solve(g)
        gtsam_pipeline(gtsam, g, fg, lago_fg)
    ours, peer = [], []
    for _ in range(spec["calls"]):  # interleaved: both see the same load
        t = time.perf_counter()
        res = certify.solve(g)
        ours.append(time.perf_counter() - t)
        peer.append(gtsam_pipeline(gtsam, g, fg, lago_fg)[1])
    count, init = [0], compressed._cs_matrix.__init__

    def counted(self, *args, **kwargs):
        count[0] += 1
        return init(self, *args, **kwargs)

    compressed._cs_matrix.__init__ = counted
    try:
        certify.solve(g)
    finally:
        compressed._cs_matrix.__init__ = init
    return {
        "n": g.n, "m": g.m, "certified": bool(res.certified),
        "stages": {k: v for k, v in res.timings.items()},
        "ours": statistics.median(ours), "ours_best": min(ours),
        "peer": statistics.median(peer), "peer_best": min(peer), "sparse": count[0],
    }  # fmt: skip


CHILDREN = {
    "table": child_table,
    "cost": child_cost,
    "rss": child_rss,
    "sweep": child_sweep,
    "sesync": child_sesync,
    "fixed": child_fixed,
}


def child(spec):
    out = CHILDREN[spec["task"]](spec)
    print(json.dumps(out))


# ============================================================================ parent side
def _cmd(spec):
    # Through a small shell that forks the child (as run_all.py): ru_maxrss survives execve, so
    # a child forked straight from this process would start at our RSS.
    cmd = ["/bin/sh", "-c", '"$0" "$@"; exit $?', sys.executable, str(Path(__file__).resolve())]
    return cmd + ["--child", json.dumps(spec)]


def run_child(spec):
    proc = subprocess.run(_cmd(spec), capture_output=True, text=True)
    if proc.returncode != 0:
        err = (proc.stderr.strip().splitlines() or ["?"])[-1]
        print(f"  {spec['task']} {spec.get('dataset', '')} FAILED: {err}", flush=True)
        return {"error": err, "anomalies": [f"child {spec} failed: {err}"]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run_parallel(specs, workers=2):
    """Run children ``workers`` at a time (the sweep: nothing in it is timed)."""
    results, running, queue = [None] * len(specs), [], list(enumerate(specs))
    while queue or running:
        while queue and len(running) < workers:
            k, spec = queue.pop(0)
            running.append((k, spec, subprocess.Popen(_cmd(spec), stdout=subprocess.PIPE,
                                                      stderr=subprocess.PIPE, text=True)))  # fmt: skip
        k, spec, proc = running.pop(0)
        out, err = proc.communicate()
        if proc.returncode != 0:
            msg = (err.strip().splitlines() or ["?"])[-1]
            print(f"  sweep {spec['N']} {spec['sigma']} FAILED: {msg}", flush=True)
            results[k] = {"records": [], "error": msg}
        else:
            results[k] = json.loads(out.strip().splitlines()[-1])
    return results


def _above(x, ref):
    """``x`` above ``ref`` by more than ``REL`` relative (and ``ABS`` absolute)."""
    return x > (1 + REL) * ref + ABS


def _four(x):
    """``x`` to 4 significant digits, as SE-Sync's Table 1 prints it."""
    return f"{float(f'{x:.4g}'):g}"


def _med(xs):
    xs = [x for x in xs if x is not None]
    return statistics.median(xs) if xs else None


def _ms(seconds):
    if seconds is None:
        return "—"
    ms = 1e3 * seconds
    return f"{ms:,.0f}" if ms >= 100 else f"{ms:.1f}" if ms >= 1 else f"{ms:.2f}"


def _g(x, digits=10):
    return "—" if x is None else f"{x:.{digits}g}"


def part_table(names, runs, tmp):
    rows = {}
    for name in names:
        recs = []
        for r in range(runs):
            spec = {"task": "table", "dataset": name, "extras": r == 0}
            if r == 0 and name in COST_DATASETS:
                spec["poses_out"] = str(Path(tmp) / f"{name}.npy")
            recs.append(run_child(spec))
        first = recs[0]
        ok = [x for x in recs if "wall" in x]
        first["wall_runs"] = [x["wall"] for x in ok]
        first["gtsam_runs"] = [x["gtsam_wall"] for x in ok if "gtsam_wall" in x]
        # the split of the run with the median total
        if ok:
            mid = sorted(ok, key=lambda x: x["wall"])[len(ok) // 2]
            first["split"] = mid["timings"]
        rows[name] = first
        print(
            f"  {name:<17} χ² {_g(first.get('chi2'))}  f {_g(first.get('f'))}  certified "
            f"{first.get('certified')}  pipeline {_ms(_med(first['wall_runs']))} ms  GTSAM "
            f"{_ms(_med(first['gtsam_runs']))} ms",
            flush=True,
        )
    return rows


def part_cost(names, runs, tmp):
    out = {}
    for name in names:
        poses = Path(tmp) / f"{name}.npy"
        if not poses.exists():  # the table did not run on it (--quick): make the poses here
            run_child({"task": "table", "dataset": name, "extras": True, "poses_out": str(poses)})
        recs = [
            run_child({"task": "cost", "dataset": name, "poses": str(poses)}) for _ in range(runs)
        ]
        recs = [r for r in recs if "error" not in r]
        rss = {
            mode: run_child({"task": "rss", "dataset": name, "poses": str(poses), "mode": mode})
            for mode in ("read", "gn1", "certify", "solve")
        }
        out[name] = {"runs": recs, "rss": rss}
        c = _med([r["certify"] for r in recs])
        gn = _med([r["gn"] for r in recs])
        print(f"  {name}: certify {_ms(c)} ms, one GN iteration {_ms(gn)} ms", flush=True)
    return out


def part_sweep(Ns, sigmas, seeds):
    specs = []
    for N in Ns:
        specs.append({"task": "sweep", "N": N, "sigma": 0.05, "noiseless": True, "seeds": seeds})
        specs += [{"task": "sweep", "N": N, "sigma": s, "seeds": seeds} for s in sigmas]
    results = run_parallel(specs)
    return list(zip(specs, results))


def part_sesync(names):
    out = {}
    for name in names:
        out[name] = run_child({"task": "sesync", "dataset": name})
        print(f"  SE-Sync {name}: f = {_g(out[name].get('f'), 12)}", flush=True)
    return out


# ---------------------------------------------------------------------------- report
def report_table(rows, runs):
    lines = [
        "## 1. The default pipeline on every graph of the mirror",
        "",
        "`lagolib.certify.solve(graph)` (LAGO, default tree → GN → chordal polish → certificate "
        "→ escape). χ²: `lagolib.chi2` (t2v error, g2o convention Σ eᵀΩe); f: the chordal cost "
        "of the certified (or best) chordal point; λ₁, λ₂: the two smallest eigenvalues of the "
        "reduced certificate matrix S̃ from `certify(problem, result.chordal_poses, "
        "eigenvalues=2)` (λ₁ ≈ 0 is the null vector z itself; λ₂ > 0 is the margin), and λ₂ "
        "again from an independent shift-and-invert (SuperLU, moderate shift); η: the "
        "certificate's tolerance; gap: (f − lower bound) / f, an upper bound on the relative "
        f"suboptimality. Time: median over {runs} fresh processes of the whole call; the split "
        "is that of the median run.",
        "",
        "| dataset | n | m | χ² | f | λ₁ | λ₂ | λ₂ (independent) | η | certified | rel. gap | "
        "escapes | pipeline ms | LAGO / GN / polish / certify / escape ms |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|:-:|--:|--:|--:|--:|",
    ]
    for name, r in rows.items():
        if "chi2" not in r:
            lines.append(f"| {name} | — | — | failed: {r.get('error', '?')} |" + " |" * 11)
            continue
        ec, ei = r["eig_cert"], r["eig_ind"]
        sp = r.get("split", r["timings"])
        split = " / ".join(
            _ms(sp[k]) for k in ("lago", "gauss_newton", "refine", "certify", "escape")
        )
        lines.append(
            f"| {name} | {r['n']} | {r['m']} | {r['chi2']:.7f} | {r['f']:.7f} | "
            f"{ec[0]:.2e} | {ec[1] if len(ec) > 1 else float('nan'):.4g} | {ei[1]:.4g} | "
            f"{r['eta']:.1e} | {'yes' if r['certified'] else 'no'} | {r['relative_gap']:.1e} | "
            f"{r['escapes']} | {_ms(_med(r['wall_runs']))} | {split} |"
        )
    lines += [
        "",
        "### From odometry, and GTSAM's LAGO + Levenberg–Marquardt on the same graphs",
        "",
        "From odometry: `solve(graph, initial=graph.poses)`. GTSAM: `gtsam.readG2o(path, False)`, "
        "a `PriorFactorPose2` on the first key with variances "
        f"{PRIOR_VARIANCES} (as `Pose2SLAMExample_lago`), `gtsam.lago.initialize`, then "
        f"`LevenbergMarquardtOptimizer` (relative and absolute error tolerance {LM_TOL:g}, at most "
        "100 iterations); its poses are mapped to lagolib's rows by vertex id and scored by "
        "`lagolib.chi2` — with the t2v error (the pipeline's cost, column χ² GTSAM) and with the "
        "log error (GTSAM's own cost, ×2). Since GTSAM minimizes the log error, its t2v χ² sits "
        "slightly above the t2v optimum even in the same basin (10⁻⁵ relative on M3500); the "
        "fair basin test is the log column against lagolib's pipeline poses polished with "
        "`optimize(graph, result.poses, error='log')`. Flags: **t2v** when χ² GTSAM > (1 + "
        f"{REL:g}) χ² pipeline, **log** when the same holds for the log costs. GTSAM time: "
        f"`lago.initialize` + LM, median over the same fresh processes.",
        "",
        "| dataset | χ² pipeline | χ² from odometry | odometry certified | odometry escapes | "
        "χ² GTSAM (t2v) | log χ² pipeline | log χ² GTSAM | GTSAM LM its | flag | "
        "GTSAM ms | pipeline ms | pipeline / GTSAM |",
        "|---|--:|--:|:-:|--:|--:|--:|--:|--:|:-:|--:|--:|--:|",
    ]
    notes = []
    for name, r in rows.items():
        if "chi2" not in r:
            continue
        o = r.get("odo", {})
        odo = (
            (f"{o['chi2']:.7f}", "yes" if o["certified"] else "no", str(o["escapes"]))
            if "chi2" in o
            else (f"failed: {o.get('error')}", "—", "—")
        )
        if "gtsam_chi2" in r:
            flags = []
            if _above(r["gtsam_chi2"], r["chi2"]):
                flags.append("t2v")
            if _above(r["gtsam_chi2_log"], r["chi2_log"]):
                flags.append("**log**")
            gt = (f"{r['gtsam_chi2']:.7f}", f"{r['chi2_log']:.7f}", f"{r['gtsam_chi2_log']:.7f}",
                  str(r.get("gtsam_iterations", "—")), ", ".join(flags) or "—")  # fmt: skip
            g_ms = _med(r["gtsam_runs"])
            ratio = f"{_med(r['wall_runs']) / g_ms:.2f}" if g_ms else "—"
        else:
            gt = (f"failed: {r.get('gtsam_error', 'gtsam not importable')}", "—", "—", "—", "—")
            g_ms, ratio = None, "—"
        lines.append(
            f"| {name} | {r['chi2']:.7f} | {' | '.join(odo)} | {' | '.join(gt)} | {_ms(g_ms)} | "
            f"{_ms(_med(r['wall_runs']))} | {ratio} |"
        )
        src = r.get("gtsam_source", "")
        if src and src != "readG2o":
            notes.append(f"{name}: GTSAM's factor graph {src}")
        if "gtsam_consistency" in r and r["gtsam_consistency"] > 1e-8:
            notes.append(
                f"{name}: 2 × GTSAM's error (prior excluded) at lagolib's log optimum differs from "
                f"lagolib's log χ² by {r['gtsam_consistency']:.1e} relative — the graphs differ"
            )
    cons = [r["gtsam_consistency"] for r in rows.values() if "gtsam_consistency" in r]
    if cons:
        notes.append(
            "every graph GTSAM optimized is the graph lagolib read: 2 × GTSAM's error (prior "
            f"excluded) at lagolib's log optimum = lagolib's log χ² within {max(cons):.1e} "
            "relative"
        )
    uncert = [
        f"{n}: {r['reason']}" for n, r in rows.items() if "chi2" in r and not r["certified"]
    ] + [
        f"{n} from odometry: {r['odo']['reason']}"
        for n, r in rows.items()
        if "chi2" in r.get("odo", {}) and not r["odo"]["certified"]
    ]
    if uncert:
        notes.append("not certified — " + "; ".join(uncert))
    lines += ["", *[f"- {x}" for x in notes]]
    return lines


def report_cost(cost, runs):
    lines = [
        "## 2. What the certificate costs",
        "",
        "Per fresh process (after a warm-up on a small graph that triggers every lazy import): "
        "`p = chordal_problem(g); p.M` (column *build M*), then `certify(p, poses)` at the "
        "pipeline's certified chordal poses — the first call (*first*, which also builds the "
        "cached real form of M) and the median of 3 more (*cached*); then one Gauss–Newton "
        "iteration `optimize(g, g.poses, max_iterations=1, tol=0, step_tol=0)`: assembly + "
        "solve + evaluation of iteration 0 (*GN it.*), and the same plus `setup` (sparsity "
        "pattern, symbolic analysis; *GN it. + setup*), first call and median of 3. Table: "
        f"medians over {runs} fresh processes.",
        "",
        "| dataset | n | m | build M ms | certify, cached ms | certify, first call ms | "
        "GN it. ms | GN it. + setup ms | GN it. + setup, first call ms | "
        "certify / GN it. | certify first / (GN it. + setup, first) | processes |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for name, c in cost.items():
        rs = c["runs"]
        if not rs:
            lines.append(f"| {name} | failed |" + " |" * 10)
            continue
        med = {k: _med([r[k] for r in rs]) for k in rs[0] if k != "certified"}
        nm = c.get("nm", ("", ""))
        lines.append(
            f"| {name} | {nm[0]} | {nm[1]} | {_ms(med['M'])} | {_ms(med['certify'])} | "
            f"{_ms(med['certify_first'])} | {_ms(med['gn'])} | {_ms(med['gn_setup'])} | "
            f"{_ms(med['gn_setup_first'])} | {med['certify'] / med['gn']:.2f} | "
            f"{med['certify_first'] / med['gn_setup_first']:.2f} | {len(rs)} |"
        )
    lines += [
        "",
        "Peak RSS (`ru_maxrss`, MiB) of a fresh process that imports lagolib, numpy, scipy and "
        "qdldl, reads the graph and the poses, and then does nothing more (*read*) or one GN "
        "iteration, `certify(chordal_problem(g), poses)`, or the whole `solve(g)`; "
        "(+ increase over *read*), and that increase per edge.",
        "",
        "| dataset | m | after import | read | + 1 GN iteration | + certify | + solve | "
        "certify KiB / edge | solve KiB / edge |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for name, c in cost.items():
        r = c["rss"]
        if any("rss" not in r[k] for k in r):
            continue
        base = r["read"]["rss"]
        m = c.get("nm", (0, 0))[1] or 1
        cell = {
            k: f"{r[k]['rss']:.0f} (+{r[k]['rss'] - base:.0f})" for k in ("gn1", "certify", "solve")
        }
        lines.append(
            f"| {name} | {m} | {r['read']['rss_import']:.0f} | {base:.0f} | {cell['gn1']} | "
            f"{cell['certify']} | {cell['solve']} | "
            f"{1024 * (r['certify']['rss'] - base) / m:.1f} | "
            f"{1024 * (r['solve']['rss'] - base) / m:.1f} |"
        )
    return lines


def report_sweep(sweep, seeds):
    lines = [
        "## 3. The noise sweep",
        "",
        "`lagolib.simulate.manhattan_world(n_poses=N, rng=seed, sigma_theta=σ_θ, sigma_xy=0.05)` "
        f"(information = the noise model's), seeds 0–{len(seeds) - 1}; the *noiseless* row is "
        "`noiseless=True` with σ_θ = 0.05 (information of that noise, no noise added: χ²* = 0). "
        "Pipeline: `certify.solve(g)`. *LAGO+GN certified*: certified without an escape "
        "(`escapes == 0`), i.e. LAGO → GN → chordal polish was already at the certified optimum. "
        "*gap*: (f − lower bound) / f of the uncertified runs. *χ² LAGO+GN / pipeline*: the "
        "first Gauss–Newton stage's χ² over the final χ² (1 when no escape was needed). GTSAM: "
        "`lago.initialize` + LM as in part 1 on the same graph (built from the PoseGraph); "
        f"*above*: χ² > (1 + {REL:g}) χ² pipeline, with the t2v cost, and with GTSAM's own log "
        "cost against the pipeline's poses polished on the log cost.",
        "",
        "| N | σ_θ | graphs | certified | LAGO+GN certified | median escapes (max) | "
        "median gap, uncertified | median (max) χ² LAGO+GN / pipeline | GTSAM above (t2v) | "
        "GTSAM above (log) | median (max) χ² GTSAM / pipeline | anomalies |",
        "|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    reasons = {}
    for spec, res in sweep:
        recs = [r for r in res.get("records", []) if "chi2" in r]
        k = len(recs)
        label = "noiseless" if spec.get("noiseless") else f"{spec['sigma']:g}"
        if not k:
            lines.append(f"| {spec['N']} | {label} | 0 | failed |" + " |" * 8)
            continue
        cert = sum(r["certified"] for r in recs)
        lago_cert = sum(r["certified"] and r["escapes"] == 0 for r in recs)
        esc = [r["escapes"] for r in recs]
        gaps = [r["relative_gap"] for r in recs if not r["certified"]]
        ratio = [r["lago_gn_chi2"] / r["chi2"] for r in recs if r["chi2"] > ABS]
        gt = [r for r in recs if "gtsam_chi2" in r]
        above_t2v = sum(_above(r["gtsam_chi2"], r["chi2"]) for r in gt)
        above_log = sum(_above(r["gtsam_chi2_log"], r["chi2_log"]) for r in gt)
        gratio = [r["gtsam_chi2"] / r["chi2"] for r in gt if r["chi2"] > ABS]
        n_anom = sum(len(r.get("anomalies", [])) for r in res.get("records", []))
        for r in recs:
            if not r["certified"]:
                key = r["reason"].split(":")[1].strip() if ":" in r["reason"] else r["reason"]
                reasons.setdefault(key, []).append(f"N={spec['N']} σ_θ={label} seed {r['seed']}")
        lines.append(
            f"| {spec['N']} | {label} | {k} | {cert}/{k} | {lago_cert}/{k} | "
            f"{statistics.median(esc):g} ({max(esc)}) | "
            f"{f'{statistics.median(gaps):.1e}' if gaps else '—'} | "
            f"{f'{statistics.median(ratio):.4f} ({max(ratio):.4f})' if ratio else '—'} | "
            f"{above_t2v}/{len(gt)} | "
            f"{above_log}/{len(gt)} | "
            f"{f'{statistics.median(gratio):.4f} ({max(gratio):.4f})' if gratio else '—'} | "
            f"{n_anom} |"
        )
    if reasons:
        lines += ["", "Why the uncertified runs stopped:", ""]
        lines += [f"- {key}: {', '.join(v)}" for key, v in reasons.items()]
    return lines


def report_fixed(fixed):
    """Part 5: per-call fixed costs (issue 26: within 2x GTSAM's LAGO + LM at 200 poses)."""
    lines = [
        "## 5. Per-call fixed costs: a 200-pose world",
        "",
        "`certify.solve(graph)` against GTSAM's `lago.initialize` + `LevenbergMarquardtOptimizer` "
        "(as in part 1) on `simulate.manhattan_world(n_poses=200, extent=9, rng=0)`, warm, "
        "interleaved calls in one process (median and best of each); target: ratio ≤ 2. "
        '"sparse" counts the SciPy compressed sparse matrices one call constructs.',
        "",
        "| poses | edges | certify.solve median (best) | GTSAM LAGO + LM median (best) | ratio "
        "| certified | LAGO / GN / polish / certificate ms | sparse |",
        "|--:|--:|--:|--:|--:|:-:|--:|--:|",
    ]
    for r in fixed:
        if "error" in r:
            lines.append(f"| — | — | failed: {r['error']} | | | | | |")
            continue
        st = r["stages"]
        split = " / ".join(
            _ms(st.get(k, 0.0)) for k in ("lago", "gauss_newton", "refine", "certify")
        )
        lines.append(
            f"| {r['n']} | {r['m']} | {_ms(r['ours'])} ms ({_ms(r['ours_best'])}) | "
            f"{_ms(r['peer'])} ms ({_ms(r['peer_best'])}) | {r['ours'] / r['peer']:.2f} | "
            f"{'yes' if r['certified'] else 'no'} | {split} | {r['sparse']} |"
        )
    return lines


def report_sesync(sesync):
    lines = [
        "## 4. SE-Sync's published optima",
        "",
        "`g2 = g.with_information(lagolib.metrics.sesync_weights(g).information)`; "
        "`solve(g2).f` is SE-Sync's objective (IJRR 2019, eq. 12; Table 1 gives 4 digits).",
        "",
        "| dataset | published (Table 1) | solve(g2).f | to 4 digits | certified | escapes | "
        "lower bound | SE-Sync objective (`metrics.sesync_objective`) at the chordal poses |",
        "|---|--:|--:|--:|:-:|--:|--:|--:|",
    ]
    for name, r in sesync.items():
        if "f" not in r:
            lines.append(f"| {name} | {SESYNC[name]:g} | failed: {r.get('error')} |" + " |" * 4)
            continue
        lines.append(
            f"| {name} | {SESYNC[name]:g} | {r['f']:.10g} | {_four(r['f'])} | "
            f"{'yes' if r['certified'] else 'no'} | {r['escapes']} | {r['lower_bound']:.10g} | "
            f"{_g(r.get('sesync_objective'))} |"
        )
    return lines


def write_report(args, parts, started, elapsed, loads):
    m = machine()
    cmd = "python benchmarks/bench_certify.py " + " ".join(sys.argv[1:])
    lines = [
        "# Global optimality: the certificate on the benchmarks (issue 14)",
        "",
        "Written by `benchmarks/bench_certify.py` — do not edit by hand; run it again.",
        "",
        f"- Date: {started:%Y-%m-%d %H:%M} UTC; run time {elapsed / 60:.1f} min",
        f"- Command: `{cmd.strip()}`" + (" (quick subset)" if args.quick else ""),
        f"- Machine: {m['cpu']}, {m['cores']} cores, {m['ram']} RAM; {m['os']}",
        f"- Python {platform.python_version()}; "
        + ", ".join(f"{p} {_version(p)}" for p in PACKAGES),
        f"- Install: {install_label()}",
        f"- Load average (1/5/15 min): {loads[0]} at the start, {loads[1]} at the end (other jobs "
        "may share the cores: compare ratios measured in the same run, not absolute times "
        "across runs)",
        "",
    ]
    table, cost, sweep, sesync, fixed = parts
    if table:
        lines += report_table(table, args.runs_table) + [""]
    if cost:
        lines += report_cost(cost, args.runs) + [""]
    if sweep:
        lines += report_sweep(sweep, args.seeds) + [""]
    if sesync:
        lines += report_sesync(sesync) + [""]
    if fixed:
        lines += report_fixed(fixed) + [""]
    anomalies = []
    for r in (table or {}).values():
        anomalies += r.get("anomalies", [])
    for _, res in sweep or []:
        for r in res.get("records", []):
            anomalies += r.get("anomalies", [])
    lines += ["## Anomalies", ""]
    if anomalies:
        lines += [
            "Checks that failed (each line names the graph; the table rows reproduce with "
            "`g = lagolib.datasets.load(name); r = lagolib.certify.solve(g)`):",
            "",
        ]
        lines += [f"- {a}" for a in anomalies]
    else:
        lines.append("None: every check passed.")
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--quick", action="store_true", help="a small subset (< 1 min)")
    ap.add_argument("--runs", type=int, default=None, help="fresh processes for part 2 (5)")
    ap.add_argument("--out", default=None, help="report file (default benchmarks/CERTIFY.md; "
                    "--quick: print it)")  # fmt: skip
    ap.add_argument("--sizes", type=int, nargs="*", default=None, help="N of the sweep (200 500)")
    ap.add_argument("--parts", type=int, nargs="*", default=[1, 2, 3, 4, 5],
                    help="the parts to run (default all: 1 2 3 4 5)")  # fmt: skip
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(json.loads(args.child))
        return

    from lagolib import datasets

    started = datetime.datetime.now(datetime.timezone.utc)
    t_start = time.perf_counter()
    load_start = os.getloadavg()
    graphs = [n for n in datasets.names() if datasets.info(n).kind == "graph"]
    if args.quick:
        graphs = [n for n in ("ring", "mit", "intel_g2o", "csail_toro") if n in graphs]
        cost_names, sesync_names = ("m3500",), ("csail",)
        args.runs = args.runs or 2
        args.runs_table = 1
        args.seeds = list(range(3))
        sizes = args.sizes or [200]
        sigmas = (0.05, 0.2, 0.5)
    else:
        cost_names, sesync_names = COST_DATASETS, tuple(SESYNC)
        args.runs = args.runs or 5
        args.runs_table = 3
        args.seeds = list(range(SEEDS))
        sizes = args.sizes or [200, 500]
        sigmas = SIGMAS
    parts = set(args.parts)
    table = cost = sweep = sesync = fixed = None
    with tempfile.TemporaryDirectory() as tmp:
        if 1 in parts:
            print(f"1. pipeline on {len(graphs)} graphs ({args.runs_table} processes each)",
                  flush=True)  # fmt: skip
            table = part_table(graphs, args.runs_table, tmp)
        if 2 in parts:
            print(f"2. certificate cost on {', '.join(cost_names)} ({args.runs} processes)",
                  flush=True)  # fmt: skip
            cost = part_cost(cost_names, args.runs, tmp)
    for name in cost or {}:
        info = datasets.info(name)
        r = (table or {}).get(name, {})
        cost[name]["nm"] = (r.get("n", info.vertices), r.get("m", info.edges))
    if 3 in parts:
        print(f"3. noise sweep, N = {sizes}, {len(sigmas)} σ_θ × {len(args.seeds)} seeds",
              flush=True)  # fmt: skip
        t = time.perf_counter()
        sweep = part_sweep(sizes, sigmas, args.seeds)
        print(f"   ({time.perf_counter() - t:.0f} s)", flush=True)
    if 4 in parts:
        print("4. SE-Sync's optima", flush=True)
        sesync = part_sesync(sesync_names)
    if 5 in parts:
        print("5. per-call fixed costs, 200 poses", flush=True)
        fixed = [run_child({"task": "fixed", "n": 200, "extent": 9, "calls": 30})]
    elapsed = time.perf_counter() - t_start
    loads = ["/".join(f"{x:.2f}" for x in load) for load in (load_start, os.getloadavg())]
    report = write_report(args, (table, cost, sweep, sesync, fixed), started, elapsed, loads)
    out = args.out or (None if args.quick else str(HERE / "CERTIFY.md"))
    if out:
        Path(out).write_text(report)
        print(f"wrote {out} ({elapsed:.0f} s)")
    else:
        print(report)
        print(f"({elapsed:.0f} s)")


if __name__ == "__main__":
    main()
