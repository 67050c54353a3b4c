"""Every benchmark of lagolib against its peers, in one run; writes ``benchmarks/RESULTS.md``.

    LAGOLIB_DATA=/path/to/mirror python benchmarks/run_all.py [--runs 5]
        [--datasets m3500 city10000] [--out benchmarks/RESULTS.md]

Tasks (each on every dataset): reading the g2o file; LAGO; one Gauss–Newton iteration; Gauss–Newton
to convergence; the marginal covariances of all poses; Lodi Rizzini's closed form.  Peers: GTSAM
(``gtsam``), g2o's Python bindings (``g2opy``) and python-graphslam (``graphslam``), each when
importable.  Every measurement (library, task, dataset) runs in a fresh subprocess (this script
with ``--child``), so its peak resident memory is its own: the child reports ``ru_maxrss`` after
importing its library and at the end.  The parent computes every χ² from the poses the children
return, with one function (``lagolib.chi2``), so the conventions agree.

Not a test: pytest's ``testpaths`` are ``lagolib`` and ``tests``, and no timing is asserted.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _timing import (  # benchmarks/ is on sys.path when run as a script
    importable,
    package_version,
    peak_rss_mib,
    vmhwm_mib,
)

HERE = Path(__file__).resolve().parent
PEERS = ("gtsam", "g2o", "graphslam")
MODULES = {"lagolib": "lagolib", "gtsam": "gtsam", "g2o": "g2opy", "graphslam": "graphslam"}
PACKAGES = ("numpy", "scipy", "qdldl", "gtsam", "g2opy", "graphslam", "lagolib")
#: σ of GTSAM's prior on the first pose (x, y in m, θ in rad): information 1e12, so the pose moves
#: by ~1e-12 of what the other factors pull — lagolib (and g2o, graphslam) hold it fixed instead.
PRIOR_SIGMA = 1e-6
#: A first run longer than this is timed (counted) instead of thrown away as a warm-up.
WARMUP_LIMIT = 2.0
#: Marginals on every k-th pose only (lagolib's cost is one factorization plus 3 solves per pose).
MARGINAL_STRIDE = {"m3500": 1, "city10000": 20}
#: python-graphslam: Gauss–Newton iterations at most (its tol is relative; it converges in 7-8
#: iterations on these graphs) and the time budget of one measurement (it is ~100x slower).
GRAPHSLAM_MAX_ITER = {"m3500": 30, "city10000": 30}
TOL = 1e-10

TASKS = {
    # key: (title, residual of the χ² column, peers compared)
    "io": ("read the g2o file", None, ("gtsam", "g2o", "graphslam")),
    "lago": ("LAGO, odometric tree", "t2v", ("gtsam",)),
    "lago_default": ("LAGO, default tree (min_uncertainty)", "t2v", ()),
    "gn1_log": ("1 GN iteration, log error (GTSAM's)", "log", ("gtsam",)),
    "gn1_t2v": ("1 GN iteration, t2v error (g2o's)", "t2v", ("g2o", "graphslam")),
    "gn_log": ("GN to convergence, log error", "log", ("gtsam",)),
    "gn_t2v": ("GN to convergence, t2v error", "t2v", ("g2o", "graphslam")),
    "marginals": ("marginal covariances", "log", ("gtsam",)),
    "closed_form": ("closed form (LAGO start + Newton)", "t2v", ()),
}
#: which peer task each (task, peer) runs
PEER_TASK = {
    "io": "io",
    "lago": "lago",
    "gn1_log": "gn1",
    "gn1_t2v": "gn1",
    "gn_log": "gn",
    "gn_t2v": "gn",
    "marginals": "marginals",
}


# ----------------------------------------------------------------------------------------------
# child: one (library, task, dataset) measurement
# ----------------------------------------------------------------------------------------------


def _measure(prepare, run, runs, budget):
    """Time ``run(prepare())`` ``runs`` times after one warm-up (counted when slower than
    ``WARMUP_LIMIT``); stop early once ``budget`` seconds of timed runs are spent."""
    wall, cpu, out = [], [], None
    first = True
    while len(wall) < runs:
        state = prepare()
        c0, t0 = time.process_time(), time.perf_counter()
        out = run(state)
        t, c = time.perf_counter() - t0, time.process_time() - c0
        if first and t <= WARMUP_LIMIT:
            first = False
            continue
        first = False
        wall.append(t)
        cpu.append(c)
        if sum(wall) + t > budget:
            break
    return wall, cpu, out


def _lagolib_task(task, path, spec):
    import numpy as np

    import lagolib
    from lagolib.closed_form import closed_form
    from lagolib.lago import lago
    from lagolib.uncertainty import marginal_covariances

    if task == "io":
        return (lambda: None), (lambda _: lagolib.read(path)), lambda r: {"counts": [r.n, r.m]}
    graph = lagolib.read(path)
    extra = {}
    if task in ("lago", "lago_default"):
        tree = "odometric" if task == "lago" else "min_uncertainty"
        return (lambda: None), (lambda _: lago(graph, tree)), lambda r: {"poses": r.poses}
    if task.startswith("gn"):
        error = task.rsplit("_", 1)[1]
        its = 1 if task.startswith("gn1") else 100

        def run(_):
            return lagolib.optimize(graph, error=error, max_iterations=its, tol=TOL)

        def result(r):
            return {"poses": r.poses, "native_chi2": r.chi2, "iterations": r.iterations}

        return (lambda: None), run, result
    if task == "marginals":
        opt = lagolib.optimize(graph, error="log", tol=TOL).poses
        rows = np.arange(0, graph.n, spec["stride"])
        vertices = graph.ids[rows]
        extra["vertices"] = vertices

        def run(_):
            return marginal_covariances(graph, vertices, poses=opt, error="log", frame="local")

        return (lambda: None), run, lambda cov: {"cov": cov, "poses": opt, **extra}
    if task == "closed_form":
        return (
            (lambda: None),
            (lambda _: closed_form(graph)),
            lambda r: {"poses": r.poses, "native_chi2": r.chi2, "iterations": r.iterations},
        )
    raise ValueError(task)


def _gtsam_poses(gtsam, values):
    import numpy as np

    keys = np.array(sorted(values.keys()))
    poses = gtsam.utilities.extractPose2(values)  # rows in key order
    return keys, np.asarray(poses)


def _gtsam_task(task, path, spec):
    import gtsam
    import numpy as np

    if task == "io":
        return (
            (lambda: None),
            (lambda _: gtsam.readG2o(path, False)),
            lambda r: {"counts": [r[1].size(), r[0].size()]},
        )
    fg, initial = gtsam.readG2o(path, False)
    edges_only = gtsam.NonlinearFactorGraph(fg)
    first = min(initial.keys())
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.full(3, PRIOR_SIGMA))
    fg.add(gtsam.PriorFactorPose2(first, initial.atPose2(first), noise))

    def params(iterations):
        p = gtsam.GaussNewtonParams()
        p.setRelativeErrorTol(TOL)
        p.setAbsoluteErrorTol(TOL)
        p.setMaxIterations(iterations)
        return p

    def result_of(values, iterations=None):
        keys, poses = _gtsam_poses(gtsam, values)
        out = {"ids": keys, "poses": poses, "native_chi2": 2.0 * edges_only.error(values)}
        if iterations is not None:
            out["iterations"] = iterations
        return out

    if task == "lago":
        return (lambda: None), (lambda _: gtsam.lago.initialize(fg, True)), result_of
    if task == "gn1":

        def run(_):
            opt = gtsam.GaussNewtonOptimizer(fg, initial, params(1))
            opt.iterate()
            return opt.values()

        return (lambda: None), run, lambda v: result_of(v, 1)
    if task == "gn":

        def run(_):
            opt = gtsam.GaussNewtonOptimizer(fg, initial, params(100))
            values = opt.optimize()
            return values, opt.iterations()

        return (lambda: None), run, lambda r: result_of(*r)
    if task == "marginals":
        optimum = gtsam.GaussNewtonOptimizer(fg, initial, params(100)).optimize()
        keys = np.array(sorted(initial.keys()))[:: spec["stride"]]

        def run(_):
            m = gtsam.Marginals(fg, optimum)
            return np.array([m.marginalCovariance(int(k)) for k in keys])

        return (lambda: None), run, lambda cov: {"cov": cov, **result_of(optimum)}
    raise ValueError(task)


def _g2o_task(task, path, spec):
    import g2opy as g2o
    import numpy as np

    def load():
        opt = g2o.SparseOptimizer()
        if not opt.load(path):
            raise RuntimeError(f"g2o could not read {path}")
        return opt

    if task == "io":
        return (
            (lambda: None),
            (lambda _: load()),
            lambda o: {"counts": [len(o.vertices()), len(o.edges())]},
        )
    iterations = 1 if task == "gn1" else 100

    def prepare():  # untimed: a fresh graph at the file's poses, first pose fixed
        opt = load()
        opt.set_algorithm(
            g2o.OptimizationAlgorithmGaussNewton(g2o.BlockSolverSE2(g2o.LinearSolverEigenSE2()))
        )
        opt.vertex(min(opt.vertices())).set_fixed(True)
        if iterations > 1:  # g2o's own stopping rule (g2o's command line: -gain)
            stop = g2o.SparseOptimizerTerminateAction()
            stop.set_gain_threshold(TOL)
            stop.set_max_iterations(iterations)
            opt.add_post_iteration_action(stop)
        return opt

    def run(opt):
        opt.initialize_optimization()
        return opt, opt.optimize(iterations)

    def result(r):
        opt, its = r
        ids = np.array(sorted(opt.vertices()))
        poses = np.array([opt.vertex(int(i)).estimate().to_vector() for i in ids])
        opt.compute_active_errors()
        return {"ids": ids, "poses": poses, "native_chi2": opt.active_chi2(), "iterations": its}

    if task in ("gn1", "gn"):
        return prepare, run, result
    raise ValueError(task)


def _graphslam_task(task, path, spec):
    import numpy as np
    from graphslam.graph import Graph

    if task == "io":
        return (
            (lambda: None),
            (lambda _: Graph.from_g2o(path)),
            lambda g: {"counts": [len(g._vertices), len(g._edges)]},
        )
    graph = Graph.from_g2o(path)
    start = [v.pose.copy() for v in graph._vertices]
    max_iter = 1 if task == "gn1" else spec["graphslam_max_iter"]

    def prepare():  # untimed: back to the file's poses
        for v, p in zip(graph._vertices, start):
            v.pose = p.copy()
        return graph

    def run(g):
        return g.optimize(tol=TOL, max_iter=max_iter, fix_first_pose=True, verbose=False)

    def result(r):
        ids = np.array([v.id for v in graph._vertices])
        poses = np.array([np.asarray(v.pose, dtype=float) for v in graph._vertices])
        return {
            "ids": ids,
            "poses": poses,
            "native_chi2": float(r.final_chi2),
            "iterations": int(r.num_iterations),
            "converged": bool(r.converged),
        }

    if task in ("gn1", "gn"):
        return prepare, run, result
    raise ValueError(task)


def child(spec):
    """Run one measurement; print a JSON line; save arrays to ``spec["npz"]``."""
    import numpy as np

    rss_start = peak_rss_mib()
    lib, task = spec["lib"], spec["task"]
    __import__(MODULES[lib])
    rss_import = peak_rss_mib()
    make = {
        "lagolib": _lagolib_task,
        "gtsam": _gtsam_task,
        "g2o": _g2o_task,
        "graphslam": _graphslam_task,
    }[lib]
    prepare, run, result = make(task, spec["path"], spec)
    wall, cpu, out = _measure(prepare, run, spec["runs"], spec["budget"])
    res = result(out)
    arrays = {k: np.asarray(v) for k, v in res.items() if k in ("poses", "ids", "cov", "vertices")}
    np.savez(spec["npz"], **arrays)
    scalars = {k: v for k, v in res.items() if k not in arrays}
    print(
        json.dumps(
            {
                "wall": wall,
                "cpu": cpu,
                "rss_start": rss_start,
                "rss_import": rss_import,
                "rss_peak": peak_rss_mib(),
                "hwm_peak": vmhwm_mib(),
                **scalars,
            }
        )
    )


# ----------------------------------------------------------------------------------------------
# parent
# ----------------------------------------------------------------------------------------------


def machine():
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    ram = "unknown"
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                ram = f"{int(line.split()[1]) / 2**20:.1f} GiB"
    except OSError:
        pass
    os_name = platform.platform()
    try:
        for line in Path("/etc/os-release").read_text().splitlines():
            if line.startswith("PRETTY_NAME="):
                os_name = f"{line.split('=', 1)[1].strip(chr(34))} ({platform.platform()})"
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "ram": ram, "os": os_name}


def run_child(spec, tmp):
    spec = dict(spec, npz=str(Path(tmp) / f"{spec['lib']}-{spec['task']}-{spec['dataset']}.npz"))
    # Through a small shell that forks the child and waits: on Linux ``ru_maxrss`` survives
    # ``execve``, so a child forked straight from this (large) process would start at our RSS.
    cmd = ["/bin/sh", "-c", '"$0" "$@"; exit $?', sys.executable, str(Path(__file__).resolve())]
    cmd += ["--child", json.dumps(spec)]
    t = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    elapsed = time.perf_counter() - t
    label = f"{spec['lib']:<9} {spec['task']:<12} {spec['dataset']:<9}"
    if proc.returncode != 0:
        err = proc.stderr.strip().splitlines()[-1:] or ["?"]
        print(f"  {label} FAILED: {err[0]}", flush=True)
        return {"error": err[0]}
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    import numpy as np

    with np.load(spec["npz"]) as z:
        out.update({k: z[k] for k in z.files})
    med = statistics.median(out["wall"])
    print(f"  {label} {len(out['wall'])} runs, median {1e3 * med:9.1f} ms ({elapsed:.0f} s)")
    return out


def poses_in_rows(graph, rec):
    """The child's poses in the rows of ``graph`` (children of peers return their own ids)."""
    import numpy as np

    if "ids" not in rec:
        return rec["poses"]
    row = {int(i): k for k, i in enumerate(rec["ids"])}
    order = np.array([row[int(i)] for i in graph.ids])
    return rec["poses"][order]


def chi2_of(graph, rec, error):
    import lagolib

    if "poses" not in rec:
        return None
    return float(lagolib.chi2(graph, poses_in_rows(graph, rec), error=error))


def fmt_time(rec):
    if rec is None or "error" in rec:
        return "—"
    w = rec["wall"]
    med, lo = statistics.median(w), min(w)
    return f"{_ms(med)} ({_ms(lo)})"


def _ms(seconds):
    ms = 1e3 * seconds
    return f"{ms:,.0f}" if ms >= 100 else f"{ms:.1f}" if ms >= 10 else f"{ms:.2f}"


def fmt_rss(rec):
    if rec is None or "error" in rec:
        return "—"
    return f"{rec['rss_peak']:.0f} (+{rec['rss_peak'] - rec['rss_import']:.0f})"


def fmt_chi2(value):
    return "—" if value is None else f"{value:.10g}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5, help="timed runs per measurement (default 5)")
    ap.add_argument("--datasets", nargs="+", default=["m3500", "city10000"])
    ap.add_argument("--out", default=str(HERE / "RESULTS.md"), help="Markdown report to write")
    ap.add_argument(
        "--budget",
        type=float,
        default=75.0,
        help="seconds of timed runs per measurement before it stops repeating (default 75)",
    )
    ap.add_argument(
        "--slow-budget",
        type=float,
        default=30.0,
        help="the same for python-graphslam (~100x slower; default 30)",
    )
    ap.add_argument(
        "--full-marginals", action="store_true", help="marginals of every pose on every dataset"
    )
    ap.add_argument("--peers", nargs="*", default=list(PEERS), help="peers to run if importable")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(json.loads(args.child))
        return

    import numpy as np

    import lagolib
    from lagolib import datasets

    t_start = time.perf_counter()
    load_start = os.getloadavg()
    started = datetime.datetime.now(datetime.timezone.utc)
    peers = [p for p in args.peers if importable(MODULES[p])]
    missing = [p for p in args.peers if p not in peers]
    print(
        f"peers: {', '.join(peers) or 'none'}"
        + (f" (not importable: {missing})" if missing else "")
    )
    results = {}  # (dataset, lib, lagolib task or peer task key) -> record
    graphs = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.datasets:
            path = str(datasets.path(name))
            graphs[name] = lagolib.read(path)
            stride = 1 if args.full_marginals else MARGINAL_STRIDE.get(name, 1)
            base = {"dataset": name, "path": path, "runs": args.runs, "stride": stride}
            base["graphslam_max_iter"] = GRAPHSLAM_MAX_ITER.get(name, 30)
            print(f"{name}: {path}")
            for task in TASKS:
                spec = dict(base, lib="lagolib", task=task, budget=args.budget)
                results[name, "lagolib", task] = run_child(spec, tmp)
            for peer in peers:
                for task in dict.fromkeys(
                    PEER_TASK[t] for t, (_, _, ps) in TASKS.items() if peer in ps
                ):
                    budget = args.slow_budget if peer == "graphslam" else args.budget
                    spec = dict(base, lib=peer, task=task, budget=budget)
                    results[name, peer, task] = run_child(spec, tmp)
    load_end = os.getloadavg()
    elapsed = time.perf_counter() - t_start
    report = write_report(args, argv, results, graphs, peers, missing, started, elapsed)
    report = report.replace("@LOAD@", _load(load_start) + " at the start, " + _load(load_end))
    Path(args.out).write_text(report)
    print(f"wrote {args.out} ({elapsed:.0f} s)")
    del np


def _load(load):
    return "/".join(f"{x:.2f}" for x in load)


def write_report(args, argv, results, graphs, peers, missing, started, elapsed):
    import numpy as np

    m = machine()
    cmd = "python benchmarks/run_all.py " + " ".join(sys.argv[1:] if argv is None else argv)
    lines = [
        "# lagolib benchmarks",
        "",
        "Written by `benchmarks/run_all.py` — do not edit by hand; run it again.",
        "",
        f"- Date: {started:%Y-%m-%d %H:%M} UTC; run time {elapsed / 60:.1f} min",
        f"- Command: `{cmd.strip()}`",
        f"- Machine: {m['cpu']}, {m['cores']} cores, {m['ram']} RAM; {m['os']}",
        f"- Python {platform.python_version()}; "
        + ", ".join(f"{p} {package_version(p)}" for p in PACKAGES),
        "- Load average (1/5/15 min): @LOAD@ at the end (other jobs may share the 2 cores: "
        "compare ratios measured in the same run, not absolute times across runs)",
        f"- Peers run: {', '.join(peers) or 'none'}"
        + (f"; not importable: {', '.join(missing)}" if missing else ""),
        "",
        "Times: median (min) wall time in ms over the runs of one fresh subprocess per "
        "(library, task, dataset); ratio = lagolib median / peer median (< 1: lagolib faster). "
        "Peak RSS: the child's `ru_maxrss` in MiB, absolute, with (+ the increase over "
        "`ru_maxrss` right after importing the library and numpy, before reading data). "
        "χ²: recomputed by `lagolib.chi2` from each solver's final poses with the residual "
        "of the row (t2v = g2o's, log = GTSAM's; Σ eᵀΩe over the edges, the g2o convention "
        "= 2 × GTSAM's error, priors excluded).",
        "",
    ]
    notes_runs = []
    for name, graph in graphs.items():
        lines += [f"## {name} ({graph.n} poses, {graph.m} edges)", ""]
        lines += [
            "| task | peer | lagolib ms | peer ms | ratio | runs | lagolib peak RSS MiB | "
            "peer peak RSS MiB | χ² lagolib | χ² peer |",
            "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|",
        ]
        for task, (title, error, task_peers) in TASKS.items():
            ours = results.get((name, "lagolib", task))
            chi_ours = None if error is None or "error" in ours else chi2_of(graph, ours, error)
            label = title
            if task == "marginals":
                label += _marginal_label(ours, graph)
            if error is not None:
                label += f" [χ²: {error}]"
            rows = [p for p in task_peers if p in peers] or [None]
            for peer in rows:
                rec = None if peer is None else results.get((name, peer, PEER_TASK[task]))
                ratio = "—"
                if rec is not None and "error" not in rec and "error" not in ours:
                    ratio = (
                        f"{statistics.median(ours['wall']) / statistics.median(rec['wall']):.2f}"
                    )
                chi_peer = None
                if rec is not None and "error" not in rec and error is not None:
                    chi_peer = chi2_of(graph, rec, error)
                n_ours = len(ours.get("wall", []))
                n_peer = "" if rec is None else f"/{len(rec.get('wall', []))}"
                lines.append(
                    f"| {label} | {peer or '—'} | {fmt_time(ours)} | "
                    f"{fmt_time(rec) if peer else '—'} | {ratio} | {n_ours}{n_peer} | "
                    f"{fmt_rss(ours)} | {fmt_rss(rec) if peer else '—'} | "
                    f"{fmt_chi2(chi_ours)} | {fmt_chi2(chi_peer)} |"
                )
                for who, r in (("lagolib", ours), (peer, rec)):
                    if r is not None and "error" not in r and len(r["wall"]) < args.runs:
                        notes_runs.append(f"{who} {task} on {name}: {len(r['wall'])} runs")
                    if r is not None and "error" in r:
                        notes_runs.append(f"{who} {task} on {name} failed: {r['error']}")
        lines += ["", *_checks(name, graph, results, peers), ""]
    lines += _notes(args, notes_runs, results, graphs)
    del np
    return "\n".join(lines) + "\n"


def _marginal_label(rec, graph):
    if rec is None or "error" in rec or "vertices" not in rec:
        return ""
    k = len(rec["vertices"])
    return (
        f", all {k} poses" if k == graph.n else f", {k} of {graph.n} poses (every {graph.n // k}th)"
    )


def _checks(name, graph, results, peers):
    """χ² each library reports itself, iterations, and the marginals' agreement."""
    import numpy as np

    out = ["Checks:", ""]
    counts = []
    for lib in ("lagolib", *peers):
        rec = results.get((name, lib, "io"))
        if rec and "counts" in rec:
            counts.append(f"{lib} {rec['counts'][0]}/{rec['counts'][1]}")
    out.append(f"- poses/edges read: {', '.join(counts)}")
    rss = [
        f"{lib} {results[name, lib, 'io']['rss_import']:.0f}"
        for lib in ("lagolib", *peers)
        if "rss_import" in results.get((name, lib, "io"), {})
    ]
    out.append(f"- RSS right after importing the library (MiB): {', '.join(rss)}")
    gaps = [
        abs(r["rss_peak"] - r["hwm_peak"])
        for (ds, _, _), r in results.items()
        if ds == name and r and "hwm_peak" in r
    ]
    if gaps:
        out.append(f"- ru_maxrss and VmHWM of the children agree within {max(gaps):.1f} MiB")
    for task, peer_task, peer_list in (
        ("gn1_log", "gn1", ("gtsam",)),
        ("gn1_t2v", "gn1", ("g2o", "graphslam")),
        ("gn_log", "gn", ("gtsam",)),
        ("gn_t2v", "gn", ("g2o", "graphslam")),
    ):
        items = []
        for lib, rec in [("lagolib", results.get((name, "lagolib", task)))] + [
            (p, results.get((name, p, peer_task))) for p in peer_list if p in peers
        ]:
            if rec is None or "error" in rec:
                continue
            s = f"{lib} {fmt_chi2(rec.get('native_chi2'))}"
            its = rec.get("iterations")
            if its:
                per = _ms(statistics.median(rec["wall"]) / its)
                s += f" ({its} it, {per} ms/it"
                s += ", not converged)" if rec.get("converged") is False and its > 1 else ")"
            items.append(s)
        out.append(
            f"- {task}: χ² as each library reports it (iterations, median time / iterations): "
            + "; ".join(items)
        )
    ours, theirs = (
        results.get((name, "lagolib", "marginals")),
        results.get((name, "gtsam", "marginals")),
    )
    if (
        ours
        and theirs
        and "cov" in ours
        and "cov" in theirs
        and ours["cov"].shape == theirs["cov"].shape
    ):
        a, b = ours["cov"], theirs["cov"]
        rel = np.abs(a - b).max() / np.abs(b).max()
        diag = np.einsum("kii->ki", b)
        rel_diag = (np.abs(np.einsum("kii->ki", a) - diag) / np.maximum(diag, 1e-300))[1:].max()
        out.append(
            f"- marginals, lagolib vs GTSAM (local frame, each at its own optimum): "
            f"max |ΔΣ| / max |Σ| = {rel:.1e}; largest relative difference of a variance "
            f"(first pose excluded: fixed vs prior) {rel_diag:.1e}"
        )
    cf = results.get((name, "lagolib", "closed_form"))
    if cf and "error" not in cf:
        out.append(
            f"- closed form: its own objective (Lodi Rizzini's χ², Ω = I₄) "
            f"{fmt_chi2(cf.get('native_chi2'))} after {cf.get('iterations')} Newton steps"
        )
    threads = []
    for (ds, lib, task), rec in results.items():
        if ds == name and rec and "wall" in rec and sum(rec["wall"]) > 0.05:
            ratio = sum(rec["cpu"]) / sum(rec["wall"])
            if ratio > 1.2:
                threads.append(f"{lib} {task} {ratio:.1f}")
    if threads:
        out.append(f"- CPU time / wall time above 1.2 (more than one thread): {', '.join(threads)}")
    del np
    return out


def _notes(args, notes_runs, results, graphs):
    out = [
        "## What each row measures",
        "",
        "Every child loads its library and the data untimed, does one untimed warm-up run "
        f"(counted as a timed run instead when it takes over {WARMUP_LIMIT:.0f} s), then times "
        f"`--runs` runs ({args.runs}), stopping early once {args.budget:.0f} s "
        f"({args.slow_budget:.0f} s for python-graphslam) of timed runs are spent — the `runs` "
        "column gives lagolib/peer counts.",
        "",
        "- **read the g2o file**: `lagolib.read` (a `PoseGraph`, information checked) vs "
        "`gtsam.readG2o(path, is3D=False)` (factor graph and values), g2o "
        "`SparseOptimizer().load` (vertices and edges), python-graphslam `Graph.from_g2o`.",
        "- **LAGO, odometric tree**: `lagolib.lago.lago(graph, 'odometric')` vs "
        "`gtsam.lago.initialize(graph, useOdometricPath=True)`, both on the same tree (GTSAM's "
        f"factor graph carries the prior on the first pose, σ = {PRIOR_SIGMA:g}); the "
        "default-tree row is lagolib alone (one Dijkstra more, the tree the book recommends).",
        "- **1 GN iteration**: one Gauss–Newton step from the file's poses, from scratch: "
        "lagolib `optimize(graph, max_iterations=1)` (sparsity pattern, assembly, Cholesky, "
        "update, error); GTSAM `GaussNewtonOptimizer(...)` + one `iterate()` (error, "
        "linearize, COLAMD ordering, elimination, update, error); g2o "
        "`initialize_optimization()` + `optimize(1)` (Gauss–Newton, `BlockSolverSE2` with "
        "`LinearSolverEigen`, i.e. Eigen's simplicial LDLᵀ — the bindings have no CHOLMOD); "
        "python-graphslam `optimize(max_iter=1)` (dense Python loops, `lil_matrix`, "
        "`scipy.sparse.linalg.spsolve`). lagolib is run with GTSAM's residual (log map) for "
        "the GTSAM row and with g2o's (t2v) for the others. Each timed run repeats the setup (pattern, "
        "ordering) in an already warm process. The χ² after one step agree between lagolib and "
        "g2o (both update (x, y, θ) additively with the same Jacobians) but not with GTSAM "
        "(retraction on SE(2), the log map's Jacobians) nor python-graphslam (pose ⊕ dx, "
        "its own error and Jacobians) — different first steps, the same optimum.",
        "- **GN to convergence**: the same, iterated until the relative decrease of χ² is "
        f"below {TOL:g} (lagolib `tol`, GTSAM relative and absolute error tolerance, g2o's "
        "`SparseOptimizerTerminateAction` gain threshold, graphslam's `tol`), at most 100 "
        "iterations (python-graphslam: "
        + ", ".join(f"{k} {v}" for k, v in GRAPHSLAM_MAX_ITER.items())
        + "). Gauge: lagolib, g2o and python-graphslam hold the first pose fixed; GTSAM has "
        f"no fixed poses, so it gets a prior factor at the first pose's file value with σ = "
        f"{PRIOR_SIGMA:g} (information 1e12) on x, y and θ — the same optimum to ~1e-12.",
        "- **marginal covariances**: at each library's own GN optimum (untimed): lagolib "
        "`uncertainty.marginal_covariances(graph, vertices, error='log', frame='local')` (one "
        "sparse Cholesky of H, then 3 columns of H⁻¹ per pose) vs `gtsam.Marginals(graph, "
        "optimum)` + `marginalCovariance(key)` per pose (multifrontal Cholesky, Bayes tree). "
        "On city10000 only every "
        f"{MARGINAL_STRIDE.get('city10000', 1)}th pose by default (`--full-marginals` for all): "
        "lagolib's cost is linear in the number of poses (a full run on city10000 takes minutes). "
        "g2opy's `compute_marginals` cannot return its result to Python (a binding error), so "
        "g2o is not compared.",
        "- **closed form**: `lagolib.closed_form.closed_form(graph)` (LAGO's estimate as the "
        "start, then Newton's method on the orthogonality condition); no peer implements it. Its "
        "χ² (file information, t2v) is not GN's: it minimizes Lodi Rizzini's χ² with Ω = I₄.",
    ]
    if notes_runs:
        out += [
            "",
            "Fewer runs than asked (time budget) or failures: " + "; ".join(notes_runs) + ".",
        ]
    return out


if __name__ == "__main__":
    main()
