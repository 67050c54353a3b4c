"""Issue 25's side-by-side: lagolib's robust back ends against GTSAM's, on spoiled benchmarks.

    LAGOLIB_DATA=/path/to/mirror python benchmarks/bench_robust.py \\
        [--datasets manhattan,ring,intel] [--counts 10,100,1000] \\
        [--policies random,local,random-grouped,local-grouped] [--seeds 0,1,2,3,4] \\
        [--methods gnc-tls,...,gtsam-gnc-tls,...] [--error log] [--time-limit MINUTES] \\
        [--out benchmarks/robust_results.jsonl]
    python benchmarks/bench_robust.py --report [--out results.jsonl ...] [--md benchmarks/ROBUST.md]
    LAGOLIB_DATA=... python benchmarks/bench_robust.py --profile   # cProfile of gnc-tls, M3500

Every run appends one JSON line per solve to ``--out`` as soon as the solve ends (a partial run
is usable; a re-run skips the solves already in the file), so the grid can be run in pieces.
``--report`` turns one or more result files into the Markdown tables of ``ROBUST.md``: medians
over seeds per dataset x count x policy x method, and a summary against issue 25's targets.

Datasets (:mod:`lagolib.datasets` names):

* ``manhattan``: ``m3500_olson`` (Olson's M3500 as the Vertigo suite ships it), ground truth
  ``m3500_olson_truth``;
* ``ring``: ``ring``, ground truth ``ring_truth``;
* ``intel``: ``intel`` (Carlone's INTEL), no ground truth: the reference trajectory is the
  outlier-free optimum, so its "ATE" is the distance to that optimum (the ratio column is empty).

Outliers: :func:`lagolib.simulate.add_outliers` (``group_size=10``, ``rng=seed``), appended after
the original edges.  Every method starts from ``graph.poses`` (the odometry in these files).

Methods: lagolib ``lagolib.robust.solve(graph, poses, method=m, error=--error)`` for
``m`` in :data:`lagolib.robust.METHODS` (PCM only when :mod:`lagolib.consistency` exists), and
GTSAM (``gtsam-<m>``): Levenberg–Marquardt with ``noiseModel.Robust`` on the loop closures
(``huber``, ``cauchy``, ``gm``, ``tls`` with ``k = c``; ``dcs`` with ``Φ = c²``: GTSAM's DCS
parameter is in χ² units, lagolib's in residual units), and ``GncLMOptimizer`` with TLS and GM
(``gnc-tls``, ``gnc-gm``), odometry and prior known inliers, inlier cost threshold ``c²/2``
(GTSAM's factor error is ``r²/2``).  ``c = lagolib.kernels.INLIER_THRESHOLD`` on both sides.
GTSAM's graph has a prior on the first pose (sigmas 1e-3, 1e-3, 1e-4 at the start pose; lagolib
fixes that pose); LM uses GTSAM's default parameters.

Measures per solve: precision and recall of the inlier set over the loop closures
(:func:`lagolib.robust.scores`; GTSAM's inliers by lagolib's rule ``r <= c`` at its final
estimate, GNC also by its own weights ``>= 0.5``), the ATE (translation RMSE after alignment) and
its ratio to the outlier-free optimum's, χ² (log error) of the true edges at the estimate and its
ratio to the outlier-free optimum's, and the wall time of the solve (GTSAM: optimizer construction
+ ``optimize()``; building GTSAM's factor graph from the arrays is timed apart, ``build_s``).
Not a test: nothing is asserted.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import statistics
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from _timing import package_version  # noqa: E402

DATASETS = {
    # name -> (graph, truth or None)
    "manhattan": ("m3500_olson", "m3500_olson_truth"),
    "ring": ("ring", "ring_truth"),
    "intel": ("intel", None),
}
POLICIES = ("random", "local", "random-grouped", "local-grouped")
COUNTS = (10, 100, 1000)
LAGOLIB_METHODS = ("gnc-tls", "gnc-gm", "huber", "cauchy", "gm", "tls", "dcs", "pcm",
                   "pcm+gnc-tls")
GTSAM_METHODS = ("gtsam-gnc-tls", "gtsam-gnc-gm", "gtsam-huber", "gtsam-cauchy", "gtsam-dcs",
                 "gtsam-gm", "gtsam-tls")
#: GTSAM's prior on the first pose: sigmas (x, y, θ), as in tests/test_gtsam_oracle.py
PRIOR_SIGMAS = (1e-3, 1e-3, 1e-4)
GROUP_SIZE = 10
DEFAULT_OUT = HERE / "robust_results.jsonl"


# ============================================================================ helpers
def _load_dataset(name):
    from lagolib import datasets

    gname, tname = DATASETS[name]
    graph = datasets.load(gname)
    truth = None
    if tname is not None:
        ids, poses = datasets.load(tname)
        row = {int(i): k for k, i in enumerate(ids)}
        truth = np.array([poses[row[int(i)]] for i in graph.ids])
    return graph, truth


def _ate(poses, reference):
    from lagolib.metrics import absolute_trajectory_error

    return float(absolute_trajectory_error(poses, reference).translation_rmse)


def _chi2_log(graph, poses):
    import lagolib

    return float(lagolib.chi2(graph, poses, error="log"))


def _load_avg():
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def _machine():
    try:
        from run_all import machine

        return machine()
    except Exception:  # noqa: BLE001 - informational only
        return {"platform": platform.platform(), "cores": os.cpu_count()}


def _versions():
    return {p: package_version(p) for p in ("numpy", "scipy", "qdldl", "gtsam", "lagolib",
                                             "networkx")}


def has_pcm():
    try:
        import lagolib.consistency  # noqa: F401
    except ImportError:
        return False
    return True


# ============================================================================ GTSAM side
class GtsamGraph:
    """GTSAM's factors for one spoiled graph, built once per (graph, method family)."""

    def __init__(self, gtsam, graph, base_noise=None):
        self.gtsam = gtsam
        self.graph = graph
        self.ids = [int(i) for i in graph.ids]
        self.loop = np.asarray(graph.loop_closure, bool)
        self.noise = base_noise if base_noise is not None else {}

    def gaussian(self, k):
        g = self.gtsam
        info = self.graph.information[k]
        key = info.tobytes()
        nm = self.noise.get(key)
        if nm is None:
            nm = g.noiseModel.Gaussian.Information(info)
            self.noise[key] = nm
        return nm

    def factor_graph(self, robust=None):
        """``(fg, prior_index)``; ``robust``: an mEstimator for the loop closures, or None."""
        g = self.gtsam
        fg = g.NonlinearFactorGraph()
        rob_cache = {}
        for k, (i, j) in enumerate(self.graph.edges):
            nm = self.gaussian(k)
            if robust is not None and self.loop[k]:
                key = id(nm)
                r = rob_cache.get(key)
                if r is None:
                    r = g.noiseModel.Robust.Create(robust, nm)
                    rob_cache[key] = r
                nm = r
            z = g.Pose2(*self.graph.measurements[k])
            fg.add(g.BetweenFactorPose2(self.ids[i], self.ids[j], z, nm))
        prior_noise = g.noiseModel.Diagonal.Sigmas(np.array(PRIOR_SIGMAS))
        fg.add(g.PriorFactorPose2(self.ids[0], g.Pose2(*self.graph.poses[0]), prior_noise))
        return fg, self.graph.m

    def values(self, poses):
        g = self.gtsam
        v = g.Values()
        for k, i in enumerate(self.ids):
            v.insert(i, g.Pose2(*poses[k]))
        return v

    def poses(self, values):
        out = np.empty((len(self.ids), 3))
        for k, i in enumerate(self.ids):
            p = values.atPose2(i)
            out[k] = (p.x(), p.y(), p.theta())
        return out


def gtsam_estimator(gtsam, kind, c):
    m = gtsam.noiseModel.mEstimator
    if kind == "huber":
        return m.Huber.Create(c)
    if kind == "cauchy":
        return m.Cauchy.Create(c)
    if kind == "gm":
        return m.GemanMcClure.Create(c)
    if kind == "tls":
        return m.TruncatedLeastSquares.Create(c)
    if kind == "dcs":
        return m.DCS.Create(c * c)  # GTSAM: weight (2Φ/(Φ + e²))² with e² = r², Φ in χ² units
    raise ValueError(kind)


def run_gtsam(gtsam, graph, initial, method, c, noise_cache):
    """One GTSAM solve; returns (poses, extra dict)."""
    kind = method[len("gtsam-"):]
    t = time.perf_counter()
    gg = GtsamGraph(gtsam, graph, noise_cache)
    if kind.startswith("gnc-"):
        fg, prior_index = gg.factor_graph(None)
    else:
        fg, prior_index = gg.factor_graph(gtsam_estimator(gtsam, kind, c))
    values = gg.values(initial)
    build = time.perf_counter() - t
    extra = {"build_s": build}
    lm = gtsam.LevenbergMarquardtParams()
    if kind.startswith("gnc-"):
        params = gtsam.GncLMParams(lm)
        params.setLossType(gtsam.GncLossType.TLS if kind == "gnc-tls" else gtsam.GncLossType.GM)
        known = [int(k) for k in np.flatnonzero(~gg.loop)] + [prior_index]
        params.setKnownInliers(known)
        t = time.perf_counter()
        opt = gtsam.GncLMOptimizer(fg, values, params)
        opt.setInlierCostThresholds(0.5 * c * c)  # GTSAM's factor error is r²/2
        result = opt.optimize()
        seconds = time.perf_counter() - t
        w = np.asarray(opt.getWeights(), float)[: graph.m]
        extra["gnc_weights_inlier"] = (w >= 0.5).tolist()
    else:
        t = time.perf_counter()
        opt = gtsam.LevenbergMarquardtOptimizer(fg, values, lm)
        result = opt.optimize()
        seconds = time.perf_counter() - t
        extra["iterations"] = int(opt.iterations())
    extra["seconds"] = seconds
    return gg.poses(result), extra


# ============================================================================ one run
def classify(graph, poses, c):
    """lagolib's rule: a loop closure is an inlier when r = sqrt(eᵀΩe) <= c (log error)."""
    import lagolib

    r2 = lagolib.chi2(graph, poses, per_edge=True, error="log")
    return ~np.asarray(graph.loop_closure, bool) | (r2 <= c * c)


def robust_cost(graph, poses, kind, c):
    """The robust objective ``Σ_odometry r² + Σ_closures 2 ρ(r)`` (lagolib's kernel ``kind``,
    log error) at ``poses``: the same number for both libraries' estimates."""
    import lagolib
    from lagolib.kernels import kernel

    r2 = lagolib.chi2(graph, poses, per_edge=True, error="log")
    loop = np.asarray(graph.loop_closure, bool)
    return float(r2[~loop].sum() + 2.0 * kernel(kind, c).rho(np.sqrt(r2[loop])).sum())


def run_one(method, spoiled, base, truth, ref, c, error, gtsam, noise_cache):
    """One solve of ``spoiled.graph``: a dict of measures."""
    import lagolib
    from lagolib import robust

    graph = spoiled.graph
    initial = graph.poses
    rec = {"method": method}
    try:
        if method.startswith("gtsam-"):
            poses, extra = run_gtsam(gtsam, graph, initial, method, c, noise_cache)
            seconds = extra.pop("seconds")
            inlier = classify(graph, poses, c)
            gw = extra.pop("gnc_weights_inlier", None)
            if gw is not None:
                s = robust.scores(np.asarray(gw), spoiled.outlier, judged=graph.loop_closure)
                extra["precision_weights"], extra["recall_weights"] = s.precision, s.recall
            rec.update(extra)
        else:
            t = time.perf_counter()
            res = robust.solve(graph, initial, method=method, c=c, error=error)
            seconds = time.perf_counter() - t
            poses, inlier = res.poses, np.asarray(res.inlier, bool)
            rec.update(iterations=int(res.iterations), gn_iterations=int(
                res.gauss_newton_iterations), converged=bool(res.converged),
                reason=str(res.reason)[:120], chi2_kept=float(res.chi2_inliers))
    except Exception as exc:  # noqa: BLE001 - a failure is a result here
        rec.update(error=f"{type(exc).__name__}: {str(exc).strip()[:300]}")
        return rec
    s = robust.scores(inlier, spoiled.outlier, judged=graph.loop_closure)
    reference = truth if truth is not None else ref["poses"]
    ate = _ate(poses, reference)
    chi2_true = float(lagolib.chi2(base, poses, error="log"))
    rec.update(
        seconds=seconds,
        precision=s.precision,
        recall=s.recall,
        false_inliers=s.false_inliers,
        false_outliers=s.false_outliers,
        ate=ate,
        ate_ratio=(ate / ref["ate"]) if truth is not None else None,
        chi2_true=chi2_true,
        chi2_ratio=chi2_true / ref["chi2"],
    )
    kind = method.removeprefix("gtsam-").removeprefix("gnc-")
    if kind in ("huber", "cauchy", "gm", "tls", "dcs"):
        rec["robust_cost"] = robust_cost(graph, poses, kind, c)
    return rec


def run_one_limited(timeout, *args):
    """:func:`run_one` in a forked child, killed after ``timeout`` seconds (None: in-process).

    The child inherits the warmed-up interpreter and the spoiled graph; the solve is timed
    inside it exactly as in-process, and the measures come back through a pipe.
    """
    if not timeout:
        return run_one(*args)
    import select
    import signal

    rfd, wfd = os.pipe()
    pid = os.fork()
    if pid == 0:  # child
        os.close(rfd)
        try:
            data = json.dumps(run_one(*args)).encode()
        except BaseException as exc:  # noqa: BLE001
            data = json.dumps({"method": args[0], "error": repr(exc)[:300]}).encode()
        with os.fdopen(wfd, "wb") as fh:
            fh.write(data)
        os._exit(0)
    os.close(wfd)
    chunks, deadline = [], time.monotonic() + timeout
    with os.fdopen(rfd, "rb") as fh:
        while True:
            left = deadline - time.monotonic()
            ready, _, _ = select.select([fh], [], [], max(left, 0.0))
            if not ready:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
                return {"method": args[0], "error": f"timeout: no result after {timeout:g} s",
                        "timeout": timeout}
            chunk = os.read(fh.fileno(), 1 << 20)
            if not chunk:
                break
            chunks.append(chunk)
    os.waitpid(pid, 0)
    return json.loads(b"".join(chunks).decode())


def _warm(gtsam, c, error):
    """Trigger lazy imports and caches on a small graph before anything is timed."""
    import warnings

    import lagolib
    from lagolib import robust, simulate

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = simulate.manhattan_world(n_poses=80, rng=0).graph
        sp = simulate.add_outliers(g, 5, rng=0)
        truth = g.poses
        ref = {"ate": 1.0, "chi2": 1.0, "poses": g.poses}
        for m in LAGOLIB_METHODS + GTSAM_METHODS:
            if m.startswith("pcm") and not has_pcm():
                continue
            if m.startswith("gtsam-") and gtsam is None:
                continue
            run_one(m, sp, g, truth, ref, c, error, gtsam, {})
        lagolib.optimize(g, g.poses)
        robust.scores(np.ones(g.m, bool), np.zeros(g.m, bool))


def reference(graph, truth, error):
    """The outlier-free optimum (lagolib GN from the odometry, ``error``)."""
    import lagolib

    t = time.perf_counter()
    res = lagolib.optimize(graph, graph.poses, error=error)
    seconds = time.perf_counter() - t
    ate = _ate(res.poses, truth) if truth is not None else 0.0
    return {"poses": res.poses, "ate": ate, "chi2": _chi2_log(graph, res.poses),
            "seconds": seconds, "converged": bool(res.converged)}


# ============================================================================ driver
def _key(r):
    return (r["dataset"], r["count"], r["policy"], r["seed"], r["method"])


def _done(path):
    done = set()
    if path.exists():
        for line in path.read_text().splitlines():
            try:
                r = json.loads(line)
            except json.JSONDecodeError:
                continue
            if r.get("kind") == "run":
                done.add(_key(r))
    return done


def _csv(value, cast=str):
    return [cast(v) for v in value.split(",") if v]


def run(args):
    import lagolib  # noqa: F401 - imported (and warmed) before anything is timed
    from lagolib.kernels import INLIER_THRESHOLD
    from lagolib.simulate import add_outliers

    try:
        import gtsam
    except ImportError:
        gtsam = None
    c = INLIER_THRESHOLD
    out = Path(args.out)
    methods = _csv(args.methods) if args.methods else list(LAGOLIB_METHODS + GTSAM_METHODS)
    skipped = []
    if not has_pcm():
        skipped += [m for m in methods if m.startswith("pcm")]
    if gtsam is None:
        skipped += [m for m in methods if m.startswith("gtsam-")]
    methods = [m for m in methods if m not in skipped]
    deadline = time.monotonic() + 60.0 * args.time_limit if args.time_limit else math.inf
    done = _done(out)
    t0 = time.perf_counter()
    _warm(gtsam, c, args.error)
    meta = {
        "kind": "meta",
        "command": " ".join([Path(sys.executable).name] + sys.argv),
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": _machine(),
        "python": platform.python_version(),
        "versions": _versions(),
        "load_start": _load_avg(),
        "methods": methods,
        "skipped_methods": skipped,
        "error": args.error,
        "c": c,
        "warmup_s": time.perf_counter() - t0,
        "solve_timeout": args.solve_timeout,
    }
    with out.open("a") as fh:
        fh.write(json.dumps(meta) + "\n")
    n_runs = 0
    stopped = None
    datasets = _csv(args.datasets)
    for dname in datasets:
        graph, truth = _load_dataset(dname)
        ref = reference(graph, truth, args.error)
        ref_line = {"kind": "ref", "dataset": dname, "graph": DATASETS[dname][0],
                    "truth": DATASETS[dname][1], "n": graph.n, "m": graph.m,
                    "loop_closures": int(graph.loop_closure.sum()), "ate": ref["ate"],
                    "chi2": ref["chi2"], "seconds": ref["seconds"],
                    "converged": ref["converged"],
                    "odometry_ate": _ate(graph.poses, truth) if truth is not None else None}
        if gtsam is not None:
            poses, extra = run_gtsam(gtsam, graph, graph.poses, "gtsam-huber", 1e9, {})
            ref_line["gtsam_ls_ate"] = _ate(poses, truth if truth is not None else ref["poses"])
            ref_line["gtsam_ls_chi2"] = _chi2_log(graph, poses)
        with out.open("a") as fh:
            fh.write(json.dumps(ref_line) + "\n")
        print(f"# {dname}: n={graph.n} m={graph.m} reference ATE {ref['ate']:.4g} "
              f"chi2 {ref['chi2']:.6g}", flush=True)
        noise_cache = {}
        for seed in _csv(args.seeds, int):
            for count in _csv(args.counts, int):
                for policy in _csv(args.policies):
                    spoiled = None
                    for method in methods:
                        key = (dname, count, policy, seed, method)
                        if key in done:
                            continue
                        if time.monotonic() > deadline:
                            stopped = f"time limit {args.time_limit} min reached"
                            break
                        if spoiled is None:
                            spoiled = add_outliers(graph, count, policy=policy,
                                                   group_size=GROUP_SIZE, rng=seed)
                        rec = run_one_limited(args.solve_timeout, method, spoiled, graph,
                                              truth, ref, c, args.error, gtsam, noise_cache)
                        rec.update(kind="run", dataset=dname, count=count, policy=policy,
                                   seed=seed, load=_load_avg()[0] if _load_avg() else None)
                        with out.open("a") as fh:
                            fh.write(json.dumps(rec) + "\n")
                        n_runs += 1
                        msg = rec.get("error") or (
                            f"P {rec['precision']:.3f} R {rec['recall']:.3f} "
                            f"ATE {rec['ate']:.4g} t {rec['seconds']:.3f}s")
                        print(f"{dname} {count} {policy} s{seed} {method}: {msg}", flush=True)
                    if stopped:
                        break
                if stopped:
                    break
            if stopped:
                break
        if stopped:
            break
    end = {"kind": "end", "command": meta["command"], "runs": n_runs,
           "load_end": _load_avg(), "wall_s": time.perf_counter() - t0,
           "stopped": stopped or "grid complete"}
    with out.open("a") as fh:
        fh.write(json.dumps(end) + "\n")
    print(json.dumps(end))


# ============================================================================ profile
def profile(args):
    import cProfile
    import io
    import pstats

    from lagolib import robust
    from lagolib.simulate import add_outliers

    _warm(None, robust.INLIER_THRESHOLD, args.error)
    graph, _ = _load_dataset("manhattan")
    sp = add_outliers(graph, 1000, policy=args.profile_policy, group_size=GROUP_SIZE, rng=0)
    pr = cProfile.Profile()
    t = time.perf_counter()
    pr.enable()
    res = robust.solve(sp.graph, sp.graph.poses, method="gnc-tls", error=args.error)
    pr.disable()
    wall = time.perf_counter() - t
    s = io.StringIO()
    st = pstats.Stats(pr, stream=s)
    st.sort_stats("tottime").print_stats(12)
    st.sort_stats("cumulative").print_stats(25)
    print(f"gnc-tls on manhattan + 1000 {args.profile_policy} outliers (seed 0, error="
          f"{args.error}): {wall:.2f} s under cProfile; {res!r}; "
          f"GN iterations {res.gauss_newton_iterations}, mu steps {len(res.mu)}")
    print(s.getvalue())


# ============================================================================ report
def _median(values):
    values = [v for v in values if v is not None and not (isinstance(v, float) and
                                                          math.isnan(v))]
    return statistics.median(values) if values else None


def _f(v, digits=3):
    if v is None:
        return "—"
    if isinstance(v, str):
        return v
    if abs(v) >= 1e4:
        return f"{v:.3g}"
    return f"{v:.{digits}f}"


def _ms(v):
    if v is None:
        return "—"
    return f"{1000 * v:,.0f}" if v >= 0.1 else f"{1000 * v:.1f}"


def load_results(paths):
    metas, refs, runs = [], {}, {}
    for p in paths:
        for line in Path(p).read_text().splitlines():
            try:
                r = json.loads(line)
            except json.JSONDecodeError:
                continue
            if r.get("kind") in ("meta", "end"):
                metas.append(r)
            elif r.get("kind") == "ref":
                refs[r["dataset"]] = r
            elif r.get("kind") == "run":
                runs[_key(r)] = r  # the last line of a key wins
    return metas, refs, list(runs.values())


def pair_of(method):
    """The GTSAM method a lagolib method is compared with (or None)."""
    g = "gtsam-" + method
    return g if g in GTSAM_METHODS else None


def report(paths):
    metas, refs, runs = load_results(paths)
    lines = []
    w = lines.append
    groups = defaultdict(list)
    for r in runs:
        groups[(r["dataset"], r["count"], r["policy"], r["method"])].append(r)
    order = {m: i for i, m in enumerate(LAGOLIB_METHODS + GTSAM_METHODS)}
    dsets = [d for d in DATASETS if any(k[0] == d for k in groups)]

    # datasets where GTSAM's LM does not reach the outlier-free optimum from the odometry even
    # without outliers: its robust solves there say nothing about robustness, so they are left
    # out of every lagolib-vs-GTSAM comparison (their rows stay in the per-instance tables)
    gtsam_broken = sorted(d for d, ref in refs.items() if "gtsam_ls_chi2" in ref
                          and ref["gtsam_ls_chi2"] > 1.01 * ref["chi2"] + 1e-9)
    def med(rs, field):
        return _median([r.get(field) for r in rs if "error" not in r])

    # ---- time ratios: per (dataset, count, policy, seed) the same spoiled graph
    by_instance = defaultdict(dict)
    for r in runs:
        if "error" not in r:
            by_instance[(r["dataset"], r["count"], r["policy"], r["seed"])][r["method"]] = r

    def ratios(method, select=lambda k: True):
        g = pair_of(method)
        out = []
        for k, ms in by_instance.items():
            if k[0] in gtsam_broken:
                continue
            if select(k) and method in ms and g in ms:
                out.append(ms[method]["seconds"] / ms[g]["seconds"])
        return out

    # ---------------------------------------------------------------- summary vs targets
    w("## Summary against issue 25's targets\n")
    if gtsam_broken:
        w(f"Left out of every lagolib-vs-GTSAM comparison below: {', '.join(gtsam_broken)} — "
          "GTSAM's Levenberg–Marquardt from the odometry does not reach the outlier-free "
          "optimum there even without outliers (see the dataset's line in the tables), so its "
          "robust solves there measure that failure, not robustness.\n")
    w("Medians over the seeds run (n = number of seeds). ATE ratio = ATE / ATE of the "
      "outlier-free optimum (same ground truth).\n")
    w("### 1. manhattan, 1000 random outliers: recall ≥ 0.99 and ATE ratio ≤ 1.05\n")
    w("| method | n | precision | recall | ATE ratio | meets target | time s |")
    w("|---|--:|--:|--:|--:|---|--:|")
    best = None
    for m in sorted({k[3] for k in groups if k[:3] == ("manhattan", 1000, "random")},
                    key=order.get):
        rs = groups[("manhattan", 1000, "random", m)]
        ok = [r for r in rs if "error" not in r]
        rec, ratio = med(rs, "recall"), med(rs, "ate_ratio")
        meets = rec is not None and ratio is not None and rec >= 0.99 and ratio <= 1.05
        if not m.startswith("gtsam-") and meets and (best is None or ratio < best[1]):
            best = (m, ratio)
        w(f"| {m} | {len(ok)}{'' if len(ok) == len(rs) else f' ({len(rs) - len(ok)} failed)'}"
          f" | {_f(med(rs, 'precision'))} | {_f(rec)} | {_f(ratio)} | "
          f"{'yes' if meets else 'no'} | {_f(med(rs, 'seconds'), 2)} |")
    w("")
    w(f"Best lagolib method meeting the target: **{best[0] if best else 'none'}**"
      + (f" (ATE ratio {best[1]:.3f})" if best else "") + ".\n")

    w("### 2. Grouped outliers: best lagolib precision vs GTSAM's GNC\n")
    w("Per dataset × count × grouped policy: the lagolib method with the highest median "
      "precision (ties: higher recall), against GTSAM GNC-TLS and GNC-GM (inliers by r ≤ c "
      "at the estimate; in brackets by GTSAM's own weights ≥ 0.5).\n")
    w("| dataset | count | policy | best lagolib (P / R) | lagolib gnc-tls P / R | "
      "GTSAM GNC-TLS P / R | GTSAM GNC-GM P / R | best lagolib better in precision |")
    w("|---|--:|---|---|---|---|---|---|")
    for d in dsets:
        if d in gtsam_broken:
            continue
        for cnt in COUNTS:
            for pol in ("random-grouped", "local-grouped"):
                cand = [(m, med(groups[(d, cnt, pol, m)], "precision"),
                         med(groups[(d, cnt, pol, m)], "recall"))
                        for m in LAGOLIB_METHODS if (d, cnt, pol, m) in groups]
                cand = [x for x in cand if x[1] is not None]
                if not cand:
                    continue
                bm = max(cand, key=lambda x: (x[1], x[2] or 0))
                cells = []
                gp_best = None
                for g in ("gtsam-gnc-tls", "gtsam-gnc-gm"):
                    rs = groups.get((d, cnt, pol, g), [])
                    p, rc = med(rs, "precision"), med(rs, "recall")
                    pw = med(rs, "precision_weights")
                    cells.append(f"{_f(p)} ({_f(pw)}) / {_f(rc)}" if p is not None else "—")
                    if p is not None:
                        gp_best = max(gp_best or 0.0, p)
                better = "—" if gp_best is None else (
                    "yes" if bm[1] > gp_best else ("tie" if bm[1] == gp_best else "no"))
                gt = groups.get((d, cnt, pol, "gnc-tls"), [])
                w(f"| {d} | {cnt} | {pol} | {bm[0]} ({_f(bm[1])} / {_f(bm[2])}) | "
                  f"{_f(med(gt, 'precision'))} / {_f(med(gt, 'recall'))} | "
                  f"{cells[0]} | {cells[1]} | {better} |")
    w("")

    w("### 3. Time: lagolib / GTSAM, same spoiled graph, same process\n")
    w("Ratio of wall times per solve (lagolib `robust.solve` / GTSAM optimizer construction + "
      "`optimize()`), median and max over every instance run; target ≤ 1.5.\n")
    w("| lagolib | GTSAM | instances | median ratio | max ratio | median ratio, manhattan | "
      "within 1.5× (median) |")
    w("|---|---|--:|--:|--:|--:|---|")
    for m in LAGOLIB_METHODS:
        g = pair_of(m)
        if g is None:
            continue
        rr = ratios(m)
        if not rr:
            continue
        rm = ratios(m, lambda k: k[0] == "manhattan")
        w(f"| {m} | {g} | {len(rr)} | {_f(statistics.median(rr), 2)} | {_f(max(rr), 2)} | "
          f"{_f(statistics.median(rm), 2) if rm else '—'} | "
          f"{'yes' if statistics.median(rr) <= 1.5 else 'no'} |")
    w("")

    w("### 4. Same objective, two minimizers\n")
    w("For each M-estimator and GNC pair: the robust objective ``Σ_odometry r² + "
      "Σ_closures 2ρ(r)`` (lagolib's kernel, log error, scale c; TLS for GNC-TLS, GM for "
      "GNC-GM) evaluated at both libraries' estimates of the same spoiled graph: how often "
      "each ends lower (ties: within 1e-6 relative) — a lower value is the better local "
      "minimum of the same cost, whatever the ATE.\n")
    w("| lagolib | GTSAM | instances | lagolib lower | tie | GTSAM lower | "
      "median cost ratio lagolib / GTSAM |")
    w("|---|---|--:|--:|--:|--:|--:|")
    for m in LAGOLIB_METHODS:
        g = pair_of(m)
        if g is None:
            continue
        lo = tie = hi = 0
        cr = []
        for key, ms in by_instance.items():
            if key[0] in gtsam_broken:
                continue
            a, b = ms.get(m, {}).get("robust_cost"), ms.get(g, {}).get("robust_cost")
            if a is None or b is None:
                continue
            cr.append(a / b if b > 0 else math.nan)
            if abs(a - b) <= 1e-6 * max(abs(a), abs(b)):
                tie += 1
            elif a < b:
                lo += 1
            else:
                hi += 1
        if lo + tie + hi:
            w(f"| {m} | {g} | {lo + tie + hi} | {lo} | {tie} | {hi} | "
              f"{_f(_median(cr), 3)} |")
    w("")

    # ---------------------------------------------------------------- per-instance tables
    w("## Tables per dataset × outlier count × policy\n")
    w("Medians over seeds. P, R: precision and recall of the inlier set over the loop "
      "closures. ATE in m (intel: distance to the outlier-free optimum, after alignment); "
      "ATE ratio = ATE / outlier-free optimum's ATE. χ² ratio: χ² (log error) of the true "
      "edges at the estimate / at the outlier-free optimum. Time: wall ms of the solve; "
      "ratio: lagolib / its GTSAM counterpart on the same instances (median). "
      "`fail` = solves that raised.\n")
    for d in dsets:
        ref = refs.get(d, {})
        w(f"### {d}\n")
        if ref:
            w(f"`{ref.get('graph')}`: {ref.get('n')} poses, {ref.get('m')} edges, "
              f"{ref.get('loop_closures')} loop closures. Outlier-free optimum (lagolib GN "
              f"from odometry): ATE {_f(ref.get('ate'), 4)} m, χ² {_f(ref.get('chi2'), 2)}"
              + (f"; odometry ATE {_f(ref.get('odometry_ate'), 3)} m"
                 if ref.get("odometry_ate") is not None else "")
              + (f"; GTSAM LM outlier-free: ATE {_f(ref.get('gtsam_ls_ate'), 4)} m, χ² "
                 f"{_f(ref.get('gtsam_ls_chi2'), 2)}" if "gtsam_ls_ate" in ref else "")
              + ".\n")
        for cnt in COUNTS:
            for pol in POLICIES:
                ms = sorted({k[3] for k in groups if k[:3] == (d, cnt, pol)}, key=order.get)
                if not ms:
                    continue
                seeds = sorted({r["seed"] for m in ms for r in groups[(d, cnt, pol, m)]})
                w(f"#### {d}, {cnt} outliers, {pol} (seeds {', '.join(map(str, seeds))})\n")
                w("| method | n | fail | P | R | ATE m | ATE ratio | χ² ratio | time ms | "
                  "time ratio | P / R by GNC weights |")
                w("|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|")
                for m in ms:
                    rs = groups[(d, cnt, pol, m)]
                    ok = [r for r in rs if "error" not in r]
                    rr = ratios(m, lambda k, d=d, cnt=cnt, pol=pol: k[:3] == (d, cnt, pol)) \
                        if pair_of(m) else []
                    w(f"| {m} | {len(ok)} | {len(rs) - len(ok)} | {_f(med(rs, 'precision'))} | "
                      f"{_f(med(rs, 'recall'))} | {_f(med(rs, 'ate'), 3)} | "
                      f"{_f(med(rs, 'ate_ratio'), 2)} | {_f(med(rs, 'chi2_ratio'), 2)} | "
                      f"{_ms(med(rs, 'seconds'))} | "
                      f"{_f(statistics.median(rr), 2) if rr else '—'} | "
                      + (f"{_f(med(rs, 'precision_weights'))} / "
                         f"{_f(med(rs, 'recall_weights'))}"
                         if med(rs, "precision_weights") is not None else "")
                      + " |")
                w("")
    # failures
    fails = [r for r in runs if "error" in r]
    if fails:
        w("## Failed solves\n")
        w("| dataset | count | policy | seed | method | error |")
        w("|---|--:|---|--:|---|---|")
        for r in sorted(fails, key=lambda r: (_key(r)[:4], order.get(r["method"], 99))):
            w(f"| {r['dataset']} | {r['count']} | {r['policy']} | {r['seed']} | {r['method']} | "
              f"{r['error'][:160].replace('|', '/')} |")
        w("")
    # runs
    w("## Runs recorded in the result files\n")
    for mt in metas:
        if mt["kind"] == "meta":
            skipped = ", ".join(mt.get("skipped_methods") or []) or "none"
            w(f"- `{mt['command']}` — started {mt['date']}, load {mt.get('load_start')}, "
              f"error={mt.get('error')}, skipped: {skipped}")
        else:
            w(f"  - ended: {mt['runs']} solves in {mt['wall_s'] / 60:.1f} min, load "
              f"{mt.get('load_end')}, {mt['stopped']}")
    w("")
    return "\n".join(lines), metas, runs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--datasets", default="manhattan,ring,intel")
    ap.add_argument("--counts", default="10,100,1000")
    ap.add_argument("--policies", default=",".join(POLICIES))
    ap.add_argument("--seeds", default="0,1,2,3,4")
    ap.add_argument("--methods", default=None, help="comma-separated; default every method")
    ap.add_argument("--error", default="log", choices=("log", "t2v"),
                    help="lagolib's residual (GTSAM's is log; default log: the same cost)")
    ap.add_argument("--out", default=str(DEFAULT_OUT),
                    help="JSON-lines result file (--report: comma-separated files to merge)")
    ap.add_argument("--time-limit", type=float, default=None,
                    help="minutes; no new solve starts after it")
    ap.add_argument("--solve-timeout", type=float, default=None,
                    help="seconds; each solve runs in a forked child killed after this "
                         "(recorded as a failed solve)")
    ap.add_argument("--report", action="store_true", help="print/write the Markdown tables")
    ap.add_argument("--md", default=None, help="--report: write the tables to this file")
    ap.add_argument("--profile", action="store_true",
                    help="cProfile of gnc-tls on manhattan with 1000 outliers")
    ap.add_argument("--profile-policy", default="random")
    args = ap.parse_args(argv)
    if args.report:
        text, _, _ = report(_csv(args.out))
        if args.md:
            Path(args.md).write_text(text + "\n")
        else:
            print(text)
        return
    if args.profile:
        profile(args)
        return
    run(args)


if __name__ == "__main__":
    main()
