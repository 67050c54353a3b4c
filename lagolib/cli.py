"""The ``lagolib`` command: inspect, solve and plot planar pose-graph files from the shell, and
build them from laser logs.

::

    lagolib info FILE                  counts, connectivity, odometric chain, regularization per
                                       spanning tree, information isotropy, chi2 at the file's poses
    lagolib solve FILE --method M -o OUT.g2o [--plot OUT.png] [--progress] [--certify]
                  [--backend B]        M in lago, gn, lm, lago+gn, sgd; writes the solved graph
    lagolib certify FILE [--initial odometry|lago] [--max-escapes N] [-o OUT.g2o]
                                       is it the global optimum? LAGO -> Gauss-Newton -> chordal
                                       polish -> certificate (-> escape), :func:`lagolib.certify.solve`
    lagolib plot FILE [--poses P.txt] [--ellipses [--confidence P | --sigma K] [--every K]] -o OUT.png
                                       odometric edges solid, loop closures dotted (Carlone Fig. 1);
                                       --ellipses: 95 % position ellipses of a sample of the poses
    lagolib frontend LOG -o OUT.g2o [--progress] [--simulated-odometry FRACTION DEG]
                                       a pose graph from a laser log (:mod:`lagolib.frontend`):
                                       keyframes, ICP, gated and verified loop closures; on the
                                       log's REAL odometry increments by default
    lagolib map LOG|GRAPH [--log LOG] [--poses reference|odometry|FILE] -o OUT.png
                                       the occupancy grid map (:mod:`lagolib.occupancy`); a LOG
                                       alone: front end, certify.solve and map in one call
    lagolib datasets                   the registered benchmarks and where each one is
    lagolib book write OUTDIR          the full book, from this installation, into a folder
    lagolib book student-copies OUTDIR [--no-hints]
                                       every chapter with its solutions replaced by stubs
                                       (:mod:`lagolib.book`)
    lagolib book grade SUBMISSIONS... -o GRADEBOOK.csv [--assignment FILE.toml]
                                       run a class's notebooks and grade them with lagolib's
                                       own checks (:mod:`lagolib.grading`)

``FILE`` is a g2o or TORO file, or the name of a registered benchmark (``lagolib datasets``) or of
a shipped example (``square_loop``, ``manhattan200``, ``grid100``).  ``LOG`` is a Carmen laser
log (plain or gzip), the name of a registered laser log (``intel_laser``, ``fr079_laser``,
``csail_laser``, ``aces_laser``), or ``simulated`` (:func:`lagolib.laser_world.simulate_log`'s
office, offline).  The graphs of ``frontend`` have the scans' indices in the log as vertex ids
(0-based, in ``FLASER`` order): ``map`` reads them so, and anyone can compare a result with the
log's reference poses (GMapping's corrected poses for a real log: an estimate, not ground truth).

Errors print one line, ``lagolib: error: ...``, on stderr: the exit status is 2 for a usage error
(an unknown option, method or value) and 1 for anything else (a missing file, a parse error — the
message names ``file:line`` —, a graph lagolib cannot solve, a benchmark that cannot be
downloaded: the line names the shipped examples, which work offline, and ``LAGOLIB_DATA``).  A
suggestion the library words for Python callers (``backend='qdldl'``, ``ignore_unknown=True``)
is printed as the option to type (``--backend qdldl``, ``--ignore-unknown``).  ``--debug``
(anywhere on the command line) adds the traceback.  An interrupt (Ctrl-C) exits with 130,
without a traceback.
``lagolib certify`` and ``lagolib solve --certify`` exit with 3 (:data:`NOT_CERTIFIED`) when
everything ran but the poses could not be certified globally optimal, so that scripts can tell.
Warnings (e.g. :class:`lagolib.lago.RegularizationWarning`) print one line each,
``lagolib: warning: ...``.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import inspect
import io
import json
import os
import re
import sys
import time
import traceback
import warnings
from pathlib import Path

import numpy as np

from . import book, certify, datasets, frontend, metrics, robust, scans, se2, topology
from .errors import (
    DatasetError,
    GraphError,
    LagolibError,
    LagolibWarning,
    OptionError,
    OptionTypeError,
)
from .files import atomic_write
from .gauss_newton import optimize
from .graph import ERRORS, chi2, vertex_rows
from .io import detect_format, read, read_poses, write
from .lago import lago, regularize
from .laser_world import simulate_log
from .linalg import BACKENDS
from .occupancy import map_quality, occupancy_grid
from .scans import read_carmen
from .sgd import sgd

__all__ = ["main", "COMMANDS", "METHODS", "INITIALS", "NOT_CERTIFIED"]

#: Commands handed over whole to another module's ``main(argv)``.
def _book(argv):
    """``lagolib book``: ``grade`` is :mod:`lagolib.grading`'s, the rest :mod:`lagolib.book`'s."""
    if argv and argv[0] == "grade":
        from . import grading

        return grading.main(argv[1:])
    return book.main(argv)


COMMANDS = {"book": _book}
#: ``lagolib solve --method`` choices.
METHODS = ("lago", "gn", "lm", "lago+gn", "sgd")
#: ``lagolib certify --initial`` choices: the file's poses, or LAGO's.
INITIALS = ("odometry", "lago")
#: Exit status of ``lagolib certify`` and ``lagolib solve --certify`` when the run succeeded but
#: the poses are not certified globally optimal (a local minimum, or the escape budget ran out).
NOT_CERTIFIED = 3
#: ``lagolib certify --max-escapes`` default: :func:`lagolib.certify.solve`'s.
_MAX_ESCAPES = inspect.signature(certify.solve).parameters["max_escapes"].default
#: Chords whose cycle sum is closer than this many turns to ±½ are reported as unreliable.
MARGIN = 0.1
_GRAPH_SUFFIXES = {".g2o": "g2o", ".graph": "TORO"}
_VERTEX_LINE = re.compile(rb"(?m)^[ \t]*(?:VERTEX_SE2|VERTEX2)[ \t]")
_DPI = 150
_INCHES = 6.0


class _UsageError(Exception):
    """A command line argparse (or a check of ours) rejects: exit status 2."""


class _Parser(argparse.ArgumentParser):
    """argparse that raises :class:`_UsageError` instead of printing usage and exiting."""

    def error(self, message):
        command = self.prog.removeprefix("lagolib").strip()
        raise _UsageError(f"{command}: {message}" if command else message)


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Keep the descriptions' line breaks (for the examples); show the defaults that say something."""

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if "%(default)" in text or default in (None, False, argparse.SUPPRESS):
            return text
        if action.option_strings or action.nargs in ("?", "*"):
            text += " (default: %(default)s)"
        return text


# ----------------------------------------------------------------------------- argument types
def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer; got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer; got {value}")
    return value


#: --dpi bounds: below 10 dpi the labels' fonts cannot be rendered; above 2000 the 6-inch image
#: passes Agg's limit of 2^16 pixels a side and needs gigabytes.
_DPI_RANGE = (10, 2000)


def _probability(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 < value < 1.0:
        raise argparse.ArgumentTypeError(f"{text} is not a probability in (0, 1)")
    return value


def _dpi(text):
    value = _positive_int(text)
    lo, hi = _DPI_RANGE
    if not lo <= value <= hi:
        raise argparse.ArgumentTypeError(
            f"expected a resolution from {lo} to {hi} dpi; got {value}"
        )
    return value


def _nonnegative_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer; got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer; got {value}")
    return value


def _number(strict):
    """An argparse type: a finite number, positive (``strict``) or non-negative."""
    what = "positive number" if strict else "finite non-negative number"

    def parse(text):
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a {what}; got {text!r}") from None
        if not (np.isfinite(value) and (value > 0 if strict else value >= 0)):
            raise argparse.ArgumentTypeError(f"expected a {what}; got {text!r}")
        return value

    return parse


_nonnegative_float, _positive_float = _number(False), _number(True)


# ----------------------------------------------------------------------------- input
def _resolve(name):
    """The path of ``FILE``: a file, a registered benchmark's name or a shipped example's name."""
    p = Path(name)
    if p.exists():
        if p.is_dir():
            raise LagolibError(f"{name}: is a folder, not a pose-graph file")
        return p
    if name in datasets.names():
        d = datasets.info(name)
        if d.kind == "laser":
            raise LagolibError(
                f"dataset {name!r} is a laser log (Carmen), not a pose graph; build a graph "
                f"from its scans first: 'lagolib frontend {name} -o graph.g2o'"
            )
        if d.kind != "graph":
            raise LagolibError(
                f"dataset {name!r} holds ground-truth poses, not a graph; give it to "
                "'lagolib plot GRAPH --poses' instead"
            )
        try:
            return datasets.path(name)
        except DatasetError as exc:
            reason = getattr(exc, "reason", None)
            if reason is None:  # a mirror without the file, a corrupt mirror: its own message
                raise
            raise LagolibError(
                f"cannot get the benchmark {name!r}: {reason}; work offline with a shipped "
                f"example ({', '.join(datasets.examples())}, e.g. 'lagolib info "
                f"{datasets.examples()[0]}'), or set LAGOLIB_DATA to a folder that mirrors the "
                "benchmarks"
            ) from exc
    if name in datasets.examples():
        return datasets.data_dir() / f"{name}.g2o"
    raise LagolibError(
        f"{name}: no such file (nor a dataset name: 'lagolib datasets' lists them, and the "
        f"shipped examples are {', '.join(datasets.examples())})"
    )


def _load(name, ignore_unknown):
    """``(path, graph, has_vertex_lines)`` of ``FILE``."""
    path = _resolve(name)
    graph = read(path, ignore_unknown=ignore_unknown)  # hints for Python callers: see _for_shell
    with open(path, "rb") as f:
        has_vertices = _VERTEX_LINE.search(f.read()) is not None
    return path, graph, has_vertices


def _output_path(text, kinds, flag, command):
    """``text`` as an output Path, its extension one of ``kinds`` and its folder existing."""
    p = Path(text)
    if p.suffix.lower() not in kinds:
        raise _UsageError(
            f"{command}: {flag} {text}: cannot tell the format from the extension {p.suffix or '(none)'!r}; "
            f"use one of {', '.join(sorted(kinds))}"
        )
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise LagolibError(f"{flag} {text}: the folder {folder} does not exist")
    if p.is_dir():
        raise LagolibError(f"{flag} {text}: is a folder")
    return p


def _image_kinds():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    return {f".{k}" for k in FigureCanvasAgg(Figure()).get_supported_filetypes()}


# ----------------------------------------------------------------------------- info
def _chain(graph):
    """Links between consecutive ids: ``(gaps, backward_only)`` as lists of ``(id, next id)``."""
    n = graph.n
    if n < 2:
        return [], []
    r = graph.order
    e = graph.edges
    ri, rj = r[e[:, 0]], r[e[:, 1]]
    forward = np.zeros(n - 1, dtype=bool)
    backward = np.zeros(n - 1, dtype=bool)
    forward[ri[rj == ri + 1]] = True
    backward[rj[ri == rj + 1]] = True
    ids = np.sort(graph.ids)

    def pairs(mask):
        k = np.flatnonzero(mask)
        return [(int(ids[a]), int(ids[a + 1])) for a in k]

    return pairs(~forward & ~backward), pairs(backward & ~forward)


def _regularization(graph):
    """Per spanning tree: chords, chords with ``k != 0``, chords near the rounding boundary."""
    out = {}
    for tree in topology.TREES:
        try:
            reg = regularize(graph, tree, margin_warning=0.0)
        except GraphError as exc:
            out[tree] = {"error": str(exc)}
            continue
        out[tree] = {
            "chords": int(reg.chords.size),
            "regularized": reg.n_regularized,
            "near_boundary": int(reg.unreliable(MARGIN).size),
        }
    return out


def _isotropy(graph):
    """Counts of edges with isotropic translational information and with coupling."""
    info = graph.information
    scale = np.max(np.abs(info), axis=(1, 2))
    tol = 1e-9 * scale
    iso = (np.abs(info[:, 0, 0] - info[:, 1, 1]) <= tol) & (np.abs(info[:, 0, 1]) <= tol)
    coupled = np.any(np.abs(info[:, :2, 2]) > tol[:, None], axis=1)
    return int(iso.sum()), int(coupled.sum())


def summarize(path, graph, has_vertices, error="t2v"):
    """Everything ``lagolib info`` reports, as a JSON-ready dict.

    Parameters
    ----------
    path : path-like
        The file the graph was read from.
    graph : PoseGraph
    has_vertices : bool
        Whether the file has vertex lines (else its poses are the odometry guess).
    error : {"t2v", "log"}
        Residual for the χ² (:func:`lagolib.graph.chi2`).

    Returns
    -------
    dict
    """
    count, labels = graph.components()
    sizes = np.sort(np.bincount(labels))[::-1] if graph.n else np.zeros(0, dtype=int)
    gaps, backward = _chain(graph)
    iso, coupled = _isotropy(graph)
    return {
        "file": str(path),
        "format": detect_format(path),
        "poses": graph.n,
        "edges": graph.m,
        "odometric": int(graph.odometric.sum()),
        "loop_closures": int(graph.loop_closure.sum()),
        "ids": [int(graph.ids.min()), int(graph.ids.max())],
        "vertex_lines": bool(has_vertices),
        "components": count,
        "component_sizes": sizes.tolist(),
        "chain_gaps": gaps,
        "chain_backward": backward,
        "cycles": graph.m - graph.n + count,
        "regularization": _regularization(graph),
        "isotropic": iso,
        "coupled": coupled,
        "chi2": chi2(graph, error=error),
        "chi2_error": error,
    }


def _show_pairs(pairs, limit=8):
    shown = ", ".join(f"{a} -> {b}" for a, b in pairs[:limit])
    return shown + (f", ... ({len(pairs) - limit} more)" if len(pairs) > limit else "")


def _render_info(s):
    m = s["edges"]
    lines = [
        f"file              {s['file']} ({s['format']})",
        f"poses             {s['poses']} (ids {s['ids'][0]}..{s['ids'][1]})",
        f"edges             {m}: {s['odometric']} odometric (id k -> next id), "
        f"{s['loop_closures']} loop closures",
    ]
    if s["components"] == 1:
        lines.append("connectivity      connected (1 component)")
    else:
        sizes = ", ".join(map(str, s["component_sizes"][:6]))
        more = ", ..." if s["components"] > 6 else ""
        lines.append(
            f"connectivity      NOT connected: {s['components']} components (sizes {sizes}{more})"
        )
    if s["chain_gaps"]:
        lines.append(
            f"odometric chain   broken: {len(s['chain_gaps'])} consecutive pair(s) without an edge: "
            f"{_show_pairs(s['chain_gaps'])}"
        )
    else:
        lines.append("odometric chain   complete: an edge between every pair of consecutive ids")
    if s["chain_backward"]:
        lines.append(
            f"                  {len(s['chain_backward'])} link(s) stored backward only "
            f"(k+1 -> k): {_show_pairs(s['chain_backward'])}"
        )
    lines.append(f"cycles            {s['cycles']} independent (m - n + components)")
    lines.append(
        "regularization    chords with k != 0 (Carlone et al. 2011, Thm. 3), per spanning tree:"
    )
    notes = {"min_uncertainty": "  [lago's default]", "odometric": "  [the paper's, Prop. 2]"}
    for tree, r in s["regularization"].items():
        if "error" in r:
            reason = (
                "the graph is not connected"
                if s["components"] > 1
                else "the odometric chain is broken"
                if tree == "odometric"
                else r["error"]
            )
            lines.append(f"  {tree:<16}n/a: {reason}")
            continue
        lines.append(
            f"  {tree:<16}{r['regularized']:>6} of {r['chords']} chords  ({r['near_boundary']} "
            f"within {MARGIN} turns of the rounding boundary){notes.get(tree, '')}"
        )
    lines.append(
        f"information       translation isotropic (I11 = I22, I12 = 0) on {s['isotropic']} of {m} "
        f"edges, anisotropic on {m - s['isotropic']}"
    )
    lines.append(
        f"                  rotation-translation coupling (I13 or I23 != 0) on {s['coupled']} of "
        f"{m} edges"
    )
    where = "the file's poses" if s["vertex_lines"] else "the odometry guess"
    lines.append(
        f"chi2              {s['chi2']:.10g} at {where} ({s['chi2_error']} error, g2o's chi2)"
    )
    if not s["vertex_lines"]:
        lines.append(
            "                  (the file has no vertex lines: its poses are the odometric "
            "measurements composed from the origin)"
        )
    return "\n".join(lines)


def _cmd_info(args):
    path, graph, has_vertices = _load(args.file, args.ignore_unknown)
    s = summarize(path, graph, has_vertices, args.error)
    print(json.dumps(s, indent=1) if args.json else _render_info(s))
    return 0


# ----------------------------------------------------------------------------- progress
class _Stamped(io.TextIOBase):
    """A text stream that writes each complete line to ``sink`` with a prefix and the time."""

    def __init__(self, sink, prefix, t0):
        self.sink, self.prefix, self.t0, self._buf = sink, prefix, t0, ""

    def writable(self):
        return True

    def write(self, text):
        self._buf += text
        *lines, self._buf = self._buf.split("\n")
        for line in lines:
            self.sink.write(f"{self.prefix}{line}  t {time.perf_counter() - self.t0:.3f} s\n")
        self.sink.flush()
        return len(text)


def _sgd_progress(graph, error, sink, t0, chi_start):
    """The ``callback(iteration, poses)`` that prints one line per SGD iteration."""
    state = {"chi": chi_start, "poses": graph.poses.copy()}

    def callback(iteration, poses):
        poses = np.array(poses, dtype=float)
        chi = chi2(graph, poses, error=error)
        d = poses - state["poses"]
        d[:, 2] = se2.wrap_angle(d[:, 2])
        step = float(np.max(np.abs(d))) if d.size else 0.0
        decrease = (state["chi"] - chi) / state["chi"] if state["chi"] else 0.0
        sink.write(
            f"[sgd] iter {iteration:4d}  chi2 {chi:.10g}  decrease {decrease:.2e}  "
            f"|dx| {step:.2e}  t {time.perf_counter() - t0:.3f} s\n"
        )
        sink.flush()
        state["chi"], state["poses"] = chi, poses

    return callback


# ----------------------------------------------------------------------------- solve
#: Why ``--method M`` can end above the chi2 of the file's poses, and what to do then.
_WORSE = {
    "lago": "LAGO is a linear approximation computed without the file's poses, and these are "
    "better (already optimized?); refine LAGO with --method lago+gn, or run --method gn from the "
    "file's poses",
    "lago+gn": "Gauss-Newton from LAGO's poses reached another local minimum than the file's "
    "poses are near; --method gn starts from the file's poses",
    "gn": "Gauss-Newton's steps increased the error; --method lm controls the step size",
    "lm": "Levenberg-Marquardt should never end above its start; please report it",
    "sgd": "SGD corrects constraints one at a time, not the weighted sum; from a good start use "
    "--method gn or lm",
}
#: ``solve`` warns when chi2 ends above ``before * (1 + _WORSE_RTOL) + _WORSE_ATOL`` (not for
#: rounding: Gauss-Newton started at an optimum ends there to about 1e-15 relative).
_WORSE_RTOL, _WORSE_ATOL = 1e-9, 1e-12


def _check_solve_options(args):
    m = args.method
    if args.robust is not None and m == "sgd":
        raise _UsageError(
            "solve: --robust starts from the file's poses (--method gn/lm) or LAGO's (--method "
            "lago/lago+gn); --method sgd has no robust variant"
        )
    if args.tree is not None and m not in ("lago", "lago+gn", "sgd"):
        raise _UsageError(
            f"solve: --tree is used by --method lago, lago+gn and sgd, not by --method {m}"
        )
    if args.backend is not None and m == "sgd":
        raise _UsageError(
            "solve: --backend chooses the sparse Cholesky of lago, gn, lm and lago+gn; --method "
            "sgd factors nothing"
        )
    if args.iterations is not None and m == "lago":
        raise _UsageError(
            "solve: --iterations does not apply to --method lago (a closed form, no iterations); "
            "use --method lago+gn to refine it"
        )


#: What ``solve --robust`` starts from, by ``--method``.
_ROBUST_START = {"lago": "LAGO", "lago+gn": "LAGO", "gn": "the file's poses", "lm": "the file's poses"}


def _run_robust(graph, args, sink, t0):
    """``solve --robust M``: :func:`lagolib.robust.solve` from LAGO's poses (``--method lago``,
    ``lago+gn``) or the file's (``gn``, ``lm``); returns poses, iterations, note, result."""
    start = _run_lago(graph, args, sink, t0) if args.method in ("lago", "lago+gn") else None
    res = robust.solve(graph, start, method=args.robust, error=args.error,
                       backend=args.backend or "auto")
    closures = int(np.sum(graph.loop_closure))
    note = (f"; {res.outliers.size} of {closures} loop closures judged outliers "
            f"(chi2 of the inliers {res.chi2_inliers:.10g})")
    if sink is not None:
        sink.write(f"[{args.robust}] {res.reason}; {time.perf_counter() - t0:.3f} s\n")
        sink.flush()
    return res.poses, res.gauss_newton_iterations, note, res


def _run_lago(graph, args, sink, t0):
    kw = {} if args.tree is None else {"tree": args.tree}
    if args.backend is not None:
        kw["backend"] = args.backend
    res = lago(graph, **kw)
    if sink is not None:
        t = res.timings
        sink.write(
            f"[lago] tree {res.regularization.tree.kind}: {res.regularization.n_regularized} "
            f"chords with k != 0  regularization {t['regularization'] * 1e3:.1f} ms  phase 1 "
            f"{t['phase1'] * 1e3:.1f} ms  phase 2 {t['phase2'] * 1e3:.1f} ms  phase 3 "
            f"{t['phase3'] * 1e3:.1f} ms  chi2 {chi2(graph, res.poses, error=args.error):.10g}  "
            f"t {time.perf_counter() - t0:.3f} s\n"
        )
        sink.flush()
    return res.poses


def _run_optimize(graph, initial, method, args, sink, t0):
    kw = {} if args.iterations is None else {"max_iterations": args.iterations}
    if args.backend is not None:
        kw["backend"] = args.backend
    stamped = _Stamped(sink, f"[{method}] ", t0) if sink is not None else None
    with contextlib.redirect_stdout(stamped) if stamped else contextlib.nullcontext():
        res = optimize(
            graph, initial, method=method, error=args.error, verbose=sink is not None, **kw
        )
    note = "" if res.converged else f" (not converged: {_for_shell(res.reason, 'solve')})"
    return res.poses, res.iterations, note


def _run_sgd(graph, args, sink, t0, chi_start):
    kw = {} if args.iterations is None else {"iterations": args.iterations}
    if args.tree is not None:
        kw["tree"] = args.tree
    if sink is not None:  # the progress line computes χ² with --error: sgd need not as well
        kw["callback"] = _sgd_progress(graph, args.error, sink, t0, chi_start)
        kw["history"] = False
    res = sgd(graph, **kw)
    return np.asarray(res.poses, dtype=float), int(res.iterations)


def _cmd_solve(args):
    if args.method is None:
        args.method = "gn" if args.robust is not None else "lago+gn"
    _check_solve_options(args)
    output = _output_path(args.output, _GRAPH_SUFFIXES, "-o", "solve")
    image = _output_path(args.plot, _image_kinds(), "--plot", "solve") if args.plot else None
    path, graph, has_vertices = _load(args.file, args.ignore_unknown)
    if args.certify:
        _check_certifiable(graph, path)
    sink = sys.stderr if args.progress else None
    before = chi2(graph, error=args.error)
    t0 = time.perf_counter()
    if sink is not None:
        start = "the file's poses" if has_vertices else "the odometry guess (no vertex lines)"
        sink.write(f"[{args.method}] start: chi2 {before:.10g} at {start}\n")
        sink.flush()
    note = ""
    judged = None
    if args.robust is not None:
        poses, iterations, note, judged = _run_robust(graph, args, sink, t0)
    elif args.method == "lago":
        poses, iterations = _run_lago(graph, args, sink, t0), 0
    elif args.method in ("gn", "lm"):
        poses, iterations, note = _run_optimize(graph, None, args.method, args, sink, t0)
    elif args.method == "lago+gn":
        start = _run_lago(graph, args, sink, t0)
        poses, iterations, note = _run_optimize(graph, start, "gn", args, sink, t0)
    else:
        poses, iterations = _run_sgd(graph, args, sink, t0, before)
    seconds = time.perf_counter() - t0
    if not np.all(np.isfinite(poses)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(poses), axis=1))[0])
        raise LagolibError(
            f"--method {args.method} diverged: the pose of vertex id {graph.ids[bad]} is not "
            f"finite after {iterations} iterations; nothing was written (try another method, "
            "e.g. lago+gn)"
        )
    solved = graph.with_poses(poses)
    after = chi2(solved, error=args.error)
    if judged is None and after > before * (1.0 + _WORSE_RTOL) + _WORSE_ATOL:
        start = "the file's poses" if has_vertices else "the odometry guess"
        warnings.warn(
            f"--method {args.method} ended at chi2 {after:.10g}, above the {before:.10g} of "
            f"{start}: {_WORSE[args.method]}",
            LagolibWarning,
            stacklevel=1,
        )
    # the certificate is computed before anything is written: a failure leaves no OUT behind
    if args.certify and judged is not None:
        checked = robust.certify_inliers(judged)
    else:
        checked = _certify_poses(graph, poses, sink, t0) if args.certify else None
    if image is not None:  # drawn first: a failing --plot leaves no OUT behind either
        title = f"{Path(path).name}: {args.method}, chi2 {after:.6g}"
        try:
            _save_figure(lambda ax: _draw_graph(ax, solved, title), image, args.dpi)
        except OSError as exc:
            raise LagolibError(
                f"--plot {image}: cannot write it ({exc.strerror or exc}); nothing was written"
            ) from exc
    _write_solved(solved, output)
    wrote = f"wrote {output}" + (f" and {image}" if image else "")
    name = args.method if judged is None else f"{args.robust} from {_ROBUST_START[args.method]}"
    print(
        f"{name}: chi2 {before:.10g} -> {after:.10g} ({args.error}), {iterations} "
        f"iterations, {seconds:.3f} s{note}; {wrote}"
    )
    if checked is None:
        return 0
    if judged is not None:
        print(checked.statement)
        return 0 if checked.certified else NOT_CERTIFIED
    ref, cert = checked
    lines = _certificate_lines(cert, cert)
    lines[0] += f" (the chordal minimum next to the solved poses: {ref.iterations} Newton steps)"
    print("\n".join(lines))
    return 0 if cert.certified else NOT_CERTIFIED


def _cmd_outliers(args):
    path, graph, _ = _load(args.file, args.ignore_unknown)
    t0 = time.perf_counter()
    res = robust.solve(graph, method=args.method, error=args.error)
    seconds = time.perf_counter() - t0
    terms = chi2(graph, res.poses, per_edge=True, error=args.error)
    bad = res.outliers
    closures = int(np.sum(graph.loop_closure))
    rows = [
        {"edge": int(k), "from": int(graph.ids[graph.edges[k, 0]]),
         "to": int(graph.ids[graph.edges[k, 1]]), "chi2": float(terms[k])}
        for k in bad
    ]
    if args.json:
        print(json.dumps({
            "file": str(path), "method": args.method, "edges": graph.m,
            "loop_closures": closures, "outliers": rows, "chi2_inliers": res.chi2_inliers,
            "converged": bool(res.converged), "reason": res.reason, "seconds": seconds,
        }, indent=1))
        return 0
    print(
        f"{Path(path).name}: {args.method} judged {bad.size} of {closures} loop closures wrong "
        f"({graph.m} edges; chi2 of the inliers {res.chi2_inliers:.10g}; {seconds:.3f} s; "
        f"{res.reason})"
    )
    if rows:
        print(f"{'edge':>8s} {'from':>8s} {'to':>8s} {'chi2':>14s}")
        for r in rows:
            print(f"{r['edge']:8d} {r['from']:8d} {r['to']:8d} {r['chi2']:14.6g}")
    return 0


# ----------------------------------------------------------------------------- certify
def _check_certifiable(graph, path):
    """A certificate needs 2 or more poses in one connected graph: say so before any work."""
    try:
        certify.chordal_problem(graph)
    except GraphError as exc:
        raise GraphError(f"{path}: {str(exc).removeprefix('chordal_problem: ')}") from None


def _value(v):
    """A stage's or a certificate's value as printed: yes/no, 10 significant digits, or as is."""
    if isinstance(v, bool | np.bool_):
        return "yes" if v else "no"
    if isinstance(v, float | np.floating):
        return f"{float(v):.10g}"
    return str(v)


def _stage_line(stage):
    """One line of :attr:`lagolib.certify.SolveResult.stages`: name, milliseconds, numbers."""
    info = "  ".join(f"{k} {_value(v)}" for k, v in stage.items() if k not in ("stage", "seconds"))
    return f"  {stage['stage']:<26s}{stage['seconds'] * 1e3:9.1f} ms  {info}"


def _certificate_lines(res, cert, lambda_min=None):
    """The lines both ``certify`` and ``solve --certify`` print: chordal f, certified, λ_min,
    the lower bound and the gap.  ``res``: what gives the verdict, f, bound and gap (the
    SolveResult, or the Certificate); ``cert``: the point's Certificate (λ_min, eta, tolerance);
    ``lambda_min``: a computed value to print instead of the certificate's (None: the
    certificate's, or "> -eta" when it computed none).  A sum of squares is printed as one:
    ``f`` and the bound never below 0, and the relative gap against ``max(f, f_scale)``."""
    f = max(float(res.f), 0.0)
    bound = min(max(float(res.lower_bound), 0.0), f)
    gap = f - bound
    scale = max(f, cert.f_scale, np.finfo(float).tiny)
    if res.certified:
        verdict = (
            f"yes: f is at most {gap:.3g} above the global minimum of the chordal cost (the "
            f"certificate's tolerance is {cert.tolerance:.3g})"
        )
    elif cert.saddle or res is not cert:
        verdict = (
            "no: the global minimum of the chordal cost may be lower than f, by at most the gap"
            + (" (lambda_min(S~) < 0: a direction of negative curvature)" if cert.saddle else "")
        )
    else:
        verdict = (
            "no: the point is not stationary enough to be certified (f - sum(lambda) = "
            f"{cert.stationarity:.3g}, the tolerance {cert.tolerance:.3g}); the global minimum "
            "may be lower than f, by at most the gap"
        )
    lam = cert.lambda_min if lambda_min is None else lambda_min
    if lam is None:
        lam_text = f"> -{cert.eta:.3g} (not computed: one factorization at eta {cert.eta:.3g})"
    else:
        lam_text = format(lam, ".10g")
    bound_text = f"{bound:.10g} (on f at any poses: the global minimum is in [bound, f])"
    if res.lower_bound < 0:
        bound_text += (
            f"; the dual bound sum(lambda) + n min(lambda_min, 0) is {res.lower_bound:.6g}, "
            "below the 0 of any sum of squares"
        )
    relative = f"relative {gap / scale:.3g}"
    if scale > f:
        relative += f" to the cost's rounding scale {cert.f_scale:.3g}, as f is below it"
    return [
        f"chordal f         {f:.10g}",
        f"certified         {verdict}",
        f"lambda_min        {lam_text}",
        f"lower bound       {bound_text}",
        f"gap               {gap:.6g} ({relative})",
    ]


def _write_solved(solved, output):
    """Write the solved graph (its poses, the file's edges): ``solve -o`` and ``certify -o``."""
    write(solved, output)


def _certify_poses(graph, poses, sink, t0):
    """``solve --certify``: polish the chordal cost from ``poses`` and certify the minimum there.

    Returns ``(refine result, Certificate)``; ``poses`` (what ``-o`` writes) are not changed.
    """
    problem = certify.chordal_problem(graph)
    with _internal("solve --certify"):
        ref = certify.refine(problem, poses)
        cert = certify.certify(problem, ref.poses)
    if sink is not None:
        sink.write(
            f"[certify] chordal polish: f {ref.chi2:.10g}, {ref.iterations} iterations, "
            f"{ref.timings['total'] * 1e3:.1f} ms  t {time.perf_counter() - t0:.3f} s\n"
            f"[certify] certificate: certified {_value(cert.certified)}, lambda_min "
            f"{'> -eta' if cert.lambda_min is None else _value(cert.lambda_min)}, "
            f"{cert.seconds * 1e3:.1f} ms  t {time.perf_counter() - t0:.3f} s\n"
        )
        sink.flush()
    return ref, cert


@contextlib.contextmanager
def _internal(command):
    """The options were checked when parsed: an option error raised by the library under
    ``command`` is not the user's (exit status 2 would blame them) but an internal error."""
    try:
        yield
    except (OptionError, OptionTypeError) as exc:
        raise LagolibError(
            f"{command}: internal error: {_one_line(exc)} (not a problem with the command line; "
            "please report it)"
        ) from exc


def _start_line(args, graph, has_vertices, res):
    if args.initial == "odometry":
        where = "the file's poses" if has_vertices else "the odometry guess (no vertex lines)"
    else:
        where = f"LAGO, spanning tree {args.tree or 'min_uncertainty'}"
    return f"start             {where}: chi2 {res.start_chi2:.10g}"


def _cmd_certify(args):
    if args.tree is not None and args.initial == "odometry":
        raise _UsageError(
            "certify: --tree chooses LAGO's spanning tree; it does not apply to --initial odometry"
        )
    output = _output_path(args.output, _GRAPH_SUFFIXES, "-o", "certify") if args.output else None
    path, graph, has_vertices = _load(args.file, args.ignore_unknown)
    _check_certifiable(graph, path)
    if args.eigenvalues is not None and args.eigenvalues > graph.n:
        raise _UsageError(
            f"certify: --eigenvalues {args.eigenvalues}: S~ has {graph.n} eigenvalues (one per "
            f"pose of {path}); ask for at most {graph.n}"
        )
    sink = sys.stderr if args.progress else None
    t0 = time.perf_counter()
    if sink is not None:
        start = "the file's poses" if args.initial == "odometry" else "LAGO"
        sink.write(f"[certify] start: {start}, at most {args.max_escapes} escape(s)\n")
        sink.flush()
    stamped = _Stamped(sink, "[certify] ", t0) if sink is not None else None
    with (
        contextlib.redirect_stdout(stamped) if stamped else contextlib.nullcontext(),
        _internal("certify"),
    ):
        res = certify.solve(
            graph,
            graph.poses if args.initial == "odometry" else None,
            tree=args.tree,
            max_escapes=args.max_escapes,
            eta=args.eta,
            verbose=sink is not None,
        )
    eigenvalues, seconds = None, 0.0
    if args.eigenvalues:
        problem = certify.chordal_problem(graph)
        with _internal("certify"):
            extra = certify.certify(
                problem, res.chordal_poses, eta=args.eta, eigenvalues=args.eigenvalues
            )
        eigenvalues, seconds = extra.eigenvalues, extra.seconds
        if sink is not None:
            sink.write(
                f"[certify] {eigenvalues.size} smallest eigenvalue(s) of S~  {seconds * 1e3:.1f} "
                f"ms  t {time.perf_counter() - t0:.3f} s\n"
            )
            sink.flush()
    odometric = int(graph.odometric.sum())
    lines = [
        f"file              {path} ({detect_format(path)})",
        f"graph             {graph.n} poses, {graph.m} edges ({odometric} odometric, "
        f"{graph.m - odometric} loop closures)",
        _start_line(args, graph, has_vertices, res),
        "stages            (chi2: g2o's t2v chi2; f: the chordal cost)",
        *map(_stage_line, res.stages),
        f"chi2              {res.chi2:.10g} (t2v, g2o's chi2, at the poses -o writes)",
        *_certificate_lines(
            res,
            res.certificate,
            None if eigenvalues is None or not eigenvalues.size else float(eigenvalues[0]),
        ),
        f"escapes           {res.escapes} (at most {args.max_escapes})",
        f"reason            {_for_shell(res.reason, 'certify')}",
        f"time              {res.timings['total']:.3f} s"
        + (f" (+ {seconds:.3f} s for the eigenvalues)" if eigenvalues is not None else ""),
    ]
    if eigenvalues is not None:
        lines.append(
            f"eigenvalues       the {eigenvalues.size} smallest of S~ (the reduced certificate "
            "matrix; lambda_1 ~ 0: S~ z = 0 at a stationary point)"
        )
        lines += [f"  lambda_{k:<8d}{lam:.10g}" for k, lam in enumerate(eigenvalues, start=1)]
    if output is not None:
        _write_solved(res.graph, output)
        lines.append(f"wrote             {output}")
    print("\n".join(lines))
    return 0 if res.certified else NOT_CERTIFIED


# ----------------------------------------------------------------------------- plot
def _save_figure(draw, output, dpi):
    """Draw on a new Agg figure (``_INCHES`` square, ``dpi``) and save it; pyplot is not used."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(_INCHES, _INCHES), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    draw(ax)
    # drawn in full first, then written beside OUT and moved into place: a failed or killed
    # write leaves the previous OUT as it was
    with atomic_write(output, "wb") as f:
        fig.savefig(f, dpi=dpi, format=Path(output).suffix.lower().lstrip("."))


def _draw_graph(ax, graph, title):
    from .plotting import plot_graph

    plot_graph(graph, ax=ax, title=title)


def _poses_for(graph, name):
    """Poses for every vertex of ``graph`` from ``--poses`` (a pose list or a graph file)."""
    p = Path(name)
    if p.is_dir():
        raise LagolibError(f"--poses {name}: is a folder, not a poses file")
    if not p.is_file():
        raise LagolibError(f"--poses {name}: no such file")
    if p.suffix.lower() in _GRAPH_SUFFIXES:
        other = read(p)
        ids, poses = other.ids, other.poses
    else:
        ids, poses = read_poses(p)
    try:
        rows = vertex_rows(graph, ids, f"--poses {name}")
    except GraphError as exc:  # its message names the id and the graph's id range
        raise LagolibError(str(exc)) from exc
    if rows.size != graph.n:
        missing = np.setdiff1d(graph.ids, ids)
        raise LagolibError(
            f"--poses {name}: gives poses for {rows.size} of the graph's {graph.n} vertices; "
            f"missing ids {', '.join(map(str, missing[:8]))}{', ...' if missing.size > 8 else ''}"
        )
    out = np.empty((graph.n, 3))
    out[rows] = poses
    return out


def _cmd_plot(args):
    output = _output_path(args.output, _image_kinds(), "-o", "plot")
    path, graph, _ = _load(args.file, args.ignore_unknown)
    if args.poses is not None:
        graph = graph.with_poses(_poses_for(graph, args.poses))
    covariances = None
    if args.ellipses:
        from .uncertainty import marginal_covariances

        # every pose's block (selected inversion computes them all at the cost of a few); the
        # plot picks every K-th, or by its own rule (plot_covariance_ellipses' every=None)
        covariances = marginal_covariances(graph)
    title = args.title if args.title is not None else Path(path).name
    drawn = []  # the ellipses' legend text, once drawn

    def draw(ax):
        _draw_graph(ax, graph, title)
        if covariances is not None:
            from .plotting import plot_covariance_ellipses

            level = (
                {"confidence": args.confidence} if args.sigma is None else {"n_sigma": args.sigma}
            )
            plot_covariance_ellipses(graph.poses, covariances, ax, every=args.every, **level)
            drawn.append(ax.collections[-1].get_offsets().shape[0])
            # "95 % confidence ellipses (every 123rd pose)": the count is printed instead
            drawn.append(ax.get_legend_handles_labels()[1][-1].partition(" (every")[0])
            ax.legend(loc="best", fontsize=8)

    _save_figure(draw, output, args.dpi)
    what = f" with {drawn[0]} {drawn[1]}" if covariances is not None else ""
    print(f"wrote {output} ({graph.n} poses, {graph.m} edges{what})")
    return 0


# ----------------------------------------------------------------------------- laser logs
#: ``LOG`` that names the simulated office of :mod:`lagolib.laser_world` (offline; its reference
#: poses are the ground truth): :func:`lagolib.laser_world.simulate_log`'s default log, the one
#: :func:`lagolib.datasets.load_laser_or_simulated` falls back to.
SIMULATED = "simulated"
#: The front end's defaults (:func:`lagolib.frontend.build_graph`), for the help and the summary.
_FE = {
    name: p.default
    for name, p in inspect.signature(frontend.build_graph).parameters.items()
    if p.default is not inspect.Parameter.empty
}
#: ``--simulated-odometry`` of the issue's simulated experiment: ``simulate_log``'s default
#: ``(fraction of the translation, radians per step)``.
_SIM_SIGMA = inspect.signature(simulate_log).parameters["odometry_sigma"].default
#: Why a matched loop-closure candidate was rejected (:func:`lagolib.frontend.verify_closure`),
#: in the order its rules are tested.
_REJECTIONS = frontend.VERDICTS[1:]  # every rejection, in the order the rules apply
#: ``(option, dest)`` of the options that set the front end (``map`` checks they apply).
_FRONTEND_OPTIONS = (
    ("--min-translation", "min_translation"),
    ("--min-rotation", "min_rotation"),
    ("--translation-sigma", "translation_sigma"),
    ("--rotation-sigma", "rotation_sigma"),
    ("--match-range", "match_range"),
    ("--batch", "batch"),
)
_FLASER_LINE = re.compile(rb"(?m)^[ \t]*FLASER[ \t]")
_GRAPH_LINE = re.compile(rb"(?m)^[ \t]*(?:VERTEX_SE2|VERTEX2|EDGE_SE2|EDGE2)[ \t]")


def _laser_names():
    return [n for n in datasets.names() if datasets.info(n).kind == "laser"]


def _log_names():
    """The names a ``LOG`` may be, for messages."""
    return f"{', '.join(_laser_names())}, or '{SIMULATED}' (the simulated office, offline)"


def _input_kind(name):
    """``"log"`` or ``"graph"``: what ``name`` (a file, a dataset or example name) holds.

    A file by its extension (``.g2o``, ``.graph``: a graph), else by its first 64 kB: gzip or a
    ``FLASER`` line is a log, vertex or edge lines without one a graph; anything else is given
    to the log reader, whose error names the file.  A name that is nothing: "log" (its reader
    says there is no such file).
    """
    p = Path(name)
    if p.is_file():
        if p.suffix.lower() in _GRAPH_SUFFIXES:
            return "graph"
        with open(p, "rb") as f:
            head = f.read(1 << 16)
        if head[:2] == b"\x1f\x8b" or _FLASER_LINE.search(head):
            return "log"
        return "graph" if _GRAPH_LINE.search(head) else "log"
    if p.exists() or name == SIMULATED:
        return "log"
    if name in datasets.names():
        return "log" if datasets.info(name).kind == "laser" else "graph"
    return "graph" if name in datasets.examples() else "log"


def _read_log(name, flag=""):
    """``(label, LaserLog)`` of ``LOG``: a Carmen log (plain or gzip), a laser log's name, or
    ``simulated``.  ``flag``: the option that gave it (``"--log"``), for the messages."""
    what = f"{flag} {name}" if flag else name
    p = Path(name)
    if p.exists():
        if p.is_dir():
            raise LagolibError(f"{what}: is a folder, not a Carmen laser log")
        if _input_kind(name) == "graph":
            raise LagolibError(
                f"{what}: is a pose-graph file, not a Carmen laser log (FLASER lines): give a "
                f"log file or one of {_log_names()}"
            )
        return str(p), read_carmen(p)
    if name == SIMULATED:
        return f"{SIMULATED} (the office of lagolib.laser_world.simulate_log)", simulate_log()
    if name in datasets.names():
        d = datasets.info(name)
        if d.kind != "laser":
            held = "a pose graph" if d.kind == "graph" else "ground-truth poses"
            raise LagolibError(
                f"{what}: dataset {name!r} is {held}, not a laser log; the laser logs: "
                f"{_log_names()}"
            )
        try:
            path = datasets.path(name)
        except DatasetError as exc:
            reason = getattr(exc, "reason", None)
            if reason is None:  # a mirror without the file, a corrupt mirror: its own message
                raise
            raise LagolibError(
                f"cannot get the laser log {name!r}: {reason}; work offline with the simulated "
                f"office ('lagolib frontend {SIMULATED} -o graph.g2o'), or set LAGOLIB_DATA to a "
                "folder that mirrors the laser logs"
            ) from exc
        return f"{name} ({path})", read_carmen(path, name=name)
    if name in datasets.examples():
        raise LagolibError(
            f"{what}: {name!r} is a shipped pose-graph example, not a laser log; the laser logs: "
            f"{_log_names()}"
        )
    raise LagolibError(f"{what}: no such file, nor the name of a laser log: {_log_names()}")


def _odometry_text(args, log):
    """Which odometry the front end (or ``--poses odometry``) uses."""
    if args.simulated_odometry is not None:
        fraction, degrees = args.simulated_odometry
        return (
            f"SIMULATED, not the log's: its reference increments + Gaussian noise, "
            f"{fraction * 100:g} % of the translation and {degrees:g} deg per step (seed "
            f"{args.seed or 0})"
        )
    if log.reference_kind == "truth":
        return "the log's increments (simulated with the log)"
    return "the log's REAL increments (raw odometry between scans)"


def _load_laser(name, args, flag=""):
    """``(label, LaserLog)`` of ``name`` with ``--simulated-odometry`` applied."""
    label, log = _read_log(name, flag)
    if args.simulated_odometry is not None:
        fraction, degrees = args.simulated_odometry
        log = scans.simulated_odometry(
            log, translation_sigma=fraction, rotation_sigma=np.radians(degrees), rng=args.seed or 0
        )
    return label, log


def _frontend_kwargs(args):
    """:func:`lagolib.frontend.build_graph`'s options from the command line (degrees to radians)."""

    def given(dest, default):
        value = getattr(args, dest)
        return default if value is None else value

    return dict(
        min_translation=given("min_translation", _FE["min_translation"]),
        min_rotation=np.radians(given("min_rotation", np.degrees(_FE["min_rotation"]))),
        translation_sigma=given("translation_sigma", _FE["translation_sigma"]),
        rotation_sigma=np.radians(given("rotation_sigma", np.degrees(_FE["rotation_sigma"]))),
        max_range=given("match_range", _FE["max_range"]),
        incremental=not args.batch,
    )


def _frontend_progress(stamped):
    """The ``progress(stage, done, total)`` of :func:`~lagolib.frontend.build_graph`: a line at
    every tenth of each stage (and the keyframes' count when the first stage starts)."""

    def progress(stage, done, total):
        if stage == "sequential" and done == 1:
            stamped.write(f"keyframes: {total + 1}\n")
        step = max(1, -(-total // 10))
        if done % step == 0 or done == total:
            what = "keyframe pairs matched" if stage == "sequential" else "keyframes searched"
            stamped.write(f"{stage}: {done} of {total} {what}\n")

    return progress


def _run_frontend(args, log, label, sink, t0):
    stamped = _Stamped(sink, "[frontend] ", t0) if sink is not None else None
    progress = _frontend_progress(stamped) if stamped is not None else None
    try:
        fe = frontend.build_graph(log, **_frontend_kwargs(args), progress=progress)
    except (OptionError, OptionTypeError) as exc:  # the options were checked: it is the log's
        raise LagolibError(f"{label}: {_one_line(exc)}") from exc
    if stamped is not None:
        stamped.write(f"done: {fe.n_accepted} loop closures accepted\n")
    return fe


def _against(log):
    """What a log's reference poses are, for the lines that compare with them."""
    if log.reference_kind == "truth":
        return "the ground truth"
    return "GMapping's corrected poses (the log's estimate, not ground truth)"


def _ate_text(poses, reference):
    ate = metrics.absolute_trajectory_error(poses, reference)
    return (
        f"{ate.translation_rmse:.3f} m RMSE (max {ate.translation_max:.3f} m), rotation "
        f"{np.degrees(ate.rotation_rmse):.2f} deg RMSE"
    )


def _log_lines(label, log):
    k, n = log.ranges.shape
    return [
        f"log               {label}: {k} scans of {n} beams, max range {log.max_range:g} m",
        f"reference poses   {_against(log)}",
    ]


def _frontend_lines(fe, log, args):
    """The summary of a front-end run (``frontend``, and ``map`` of a log)."""
    kw = _frontend_kwargs(args)
    g = fe.graph
    accepted, matched = fe.n_accepted, len(fe.candidates)
    reasons = {}
    for c in fe.candidates:
        reasons[c.reason] = reasons.get(c.reason, 0) + 1
    order = [*_REJECTIONS, *sorted(set(reasons) - set(_REJECTIONS) - {"accepted"})]
    rejected = ", ".join(f"{reasons.get(r, 0)} {r}" for r in order)
    wrong = frontend.wrong_closures(fe)
    pairs = [(c.i, c.j) for c, w in zip(fe.closures, wrong) if w]
    wrong_text = f"{int(wrong.sum())} of {accepted}" + (f": {_show_pairs(pairs)}" if pairs else "")
    reference = (
        "the ground truth" if log.reference_kind == "truth" else "GMapping's corrected poses"
    )
    rules = fe.settings.get("rules") or frontend.ClosureRules()
    if kw["incremental"]:
        mode, estimate = "incremental", "optimized after every accepted closure"
    else:
        mode, estimate = "batch", "the chain of sequential matches (batch)"
    return [
        f"odometry          {_odometry_text(args, log)}",
        f"keyframes         {len(fe.keyframes)} of {len(log)} scans (every "
        f"{kw['min_translation']:g} m or {np.degrees(kw['min_rotation']):g} deg of odometry); "
        "vertex ids: scan indices",
        f"sequential edges  {g.m - accepted}: ICP between consecutive keyframes, odometry prior "
        f"{kw['translation_sigma'] * 100:g} % of the distance and "
        f"{np.degrees(kw['rotation_sigma']):g} deg",
        f"loop closures     {mode}: {fe.gated} gated (relative uncertainty), {matched} matched, "
        f"{accepted} accepted",
        f"  rejected        {matched - accepted}: {rejected}",
        f"  not matched     {fe.gated - matched} gated (at most {rules.max_candidates} matched per "
        "keyframe, the most plausible first)",
        f"wrong closures    {wrong_text} (off by > 0.5 m or 5 deg against {reference})",
        f"front-end poses   {estimate}: ATE {_ate_text(g.poses, fe.reference)}",
        f"graph             {g.n} poses, {g.m} edges",
    ]


def _stage_times(fe):
    t = fe.timings
    return ", ".join(
        f"{stage} {t[stage]:.3f} s"
        for stage in ("keyframes", "sequential", "closures", "optimization")
        if stage in t
    )


def _check_seed(args, command, applies):
    if args.seed is not None and args.simulated_odometry is None:
        raise _UsageError(f"{command}: --seed draws the noise of --simulated-odometry; give both")
    if args.simulated_odometry is not None and not applies:
        raise _UsageError(
            f"{command}: --simulated-odometry replaces the odometry the front end (or --poses "
            "odometry) uses; it does not apply here"
        )


def _cmd_frontend(args):
    output = _output_path(args.output, _GRAPH_SUFFIXES, "-o", "frontend")
    _check_seed(args, "frontend", True)
    sink = sys.stderr if args.progress else None
    t0 = time.perf_counter()
    label, log = _load_laser(args.log, args)
    t_read = time.perf_counter() - t0
    if sink is not None:
        k, n = log.ranges.shape
        sink.write(f"[frontend] read {label}: {k} scans of {n} beams  t {t_read:.3f} s\n")
        sink.flush()
    fe = _run_frontend(args, log, label, sink, t0)
    t = time.perf_counter()
    write(fe.graph, output)
    t_write = time.perf_counter() - t
    lines = [*_log_lines(label, log), *_frontend_lines(fe, log, args)]
    lines += [
        f"time              read {t_read:.3f} s, {_stage_times(fe)}, write {t_write:.3f} s; "
        f"total {time.perf_counter() - t0:.3f} s",
        f"wrote             {output}",
    ]
    print("\n".join(lines))
    return 0


def _scan_ids(ids, log, label, what):
    """``ids`` checked as scan indices of ``log``: ``(order, sorted ids)``."""
    ids = np.asarray(ids, dtype=np.int64)
    bad = ids[(ids < 0) | (ids >= len(log))]
    if bad.size:
        raise LagolibError(
            f"{what}: vertex id {int(bad[0])} is not a scan of {label} ({len(log)} scans: ids 0.."
            f"{len(log) - 1}); the vertex ids of a graph for 'lagolib map' are the scans' indices "
            "in the log, as 'lagolib frontend' writes them"
        )
    order = np.argsort(ids, kind="stable")
    return order, ids[order]


def _poses_file(name, ignore_unknown):
    """``(ids, poses)`` of ``--poses FILE``: a g2o/TORO file or an ``id x y theta`` list."""
    p = Path(name)
    if p.is_dir():
        raise LagolibError(f"--poses {name}: is a folder, not a poses file")
    if not p.is_file():
        raise LagolibError(
            f"--poses {name}: no such file (nor 'reference' or 'odometry', the log's own poses)"
        )
    if p.suffix.lower() in _GRAPH_SUFFIXES:
        g = read(p, ignore_unknown=ignore_unknown)
        return g.ids, g.poses
    return read_poses(p)


def _map_checks(args, kind):
    """The usage errors of ``map``: which options apply to which INPUT."""
    runs_frontend = kind == "log" and args.poses is None
    if kind == "graph":
        if args.log is None:
            raise _UsageError(
                f"map: INPUT {args.input} is a pose graph: give the laser log whose scans its "
                "vertex ids index with --log LOG (a Carmen log file, or a laser log's name)"
            )
        if args.poses not in (None, "reference", "odometry"):
            raise _UsageError(
                "map: --poses FILE with a GRAPH input: give FILE as INPUT instead (its vertex ids "
                "are the scans drawn), with --log LOG"
            )
    elif args.log is not None:
        raise _UsageError(
            f"map: --log gives the scans of a GRAPH input; INPUT {args.input} is a laser log "
            "already"
        )
    given = [flag for flag, dest in _FRONTEND_OPTIONS if getattr(args, dest) not in (None, False)]
    if given and not runs_frontend:
        raise _UsageError(
            f"map: {', '.join(given)} set(s) the front end, which map runs only for a LOG "
            "without --poses"
        )
    _check_seed(args, "map", runs_frontend or args.poses == "odometry")
    return runs_frontend


def _cmd_map(args):
    output = _output_path(args.output, _image_kinds(), "-o", "map")
    kind = _input_kind(args.input)
    runs_frontend = _map_checks(args, kind)
    sink = sys.stderr if args.progress else None
    t0 = time.perf_counter()
    graph = path = None
    if kind == "graph":
        path = _resolve(args.input)
        graph = read(path, ignore_unknown=args.ignore_unknown)
        label, log = _load_laser(args.log, args, "--log")
    else:
        label, log = _load_laser(args.input, args)
    times = [f"read {time.perf_counter() - t0:.3f} s"]
    if sink is not None:
        k, n = log.ranges.shape
        sink.write(
            f"[map] read {label}: {k} scans of {n} beams  t {time.perf_counter() - t0:.3f} s\n"
        )
        sink.flush()
    lines, estimated = _log_lines(label, log), True
    if args.poses == "odometry":
        lines.append(f"odometry          {_odometry_text(args, log)}")
    if graph is not None:
        order, ids = _scan_ids(graph.ids, log, label, str(path))
        if args.poses == "reference":
            poses, what, estimated = log.reference[ids], "the log's reference poses", False
        elif args.poses == "odometry":
            poses, what = log.odometry_poses()[ids], "the chained odometry"
        else:
            poses, what = graph.poses[order], f"the poses of {path}"
        what += f" of the graph's {ids.size} scans"
    elif runs_frontend:
        fe = _run_frontend(args, log, label, sink, t0)
        lines += _frontend_lines(fe, log, args)
        times.append(_stage_times(fe))
        stamped = _Stamped(sink, "[certify] ", t0) if sink is not None else None
        with (
            contextlib.redirect_stdout(stamped) if stamped else contextlib.nullcontext(),
            _internal("map"),
        ):
            res = certify.solve(fe.graph, verbose=sink is not None)
        if not res.certified:
            warnings.warn(
                f"the optimized poses are not certified globally optimal ({res.reason}); the map "
                "is drawn at them",
                LagolibWarning,
                stacklevel=1,
            )
        lines.append(
            f"optimization      certify.solve (LAGO -> Gauss-Newton -> certificate): chi2 "
            f"{res.chi2:.10g}, certified globally optimal: {_value(res.certified)}"
        )
        times.append(f"certify.solve {res.timings['total']:.3f} s")
        order, ids = _scan_ids(fe.graph.ids, log, label, label)
        # in the front end's frame (the first keyframe at its reference pose), not LAGO's
        anchor = se2.compose(fe.graph.poses[0], se2.between(res.poses[0], np.zeros(3)))  # g0 r0^-1
        poses = se2.compose(anchor, res.poses)[order]
        what = f"the optimized poses of the {ids.size} keyframes"
    elif args.poses == "reference":
        ids, poses, estimated = np.arange(len(log)), log.reference, False
        what = f"the log's reference poses of all {len(log)} scans"
    elif args.poses == "odometry":
        ids, poses = np.arange(len(log)), log.odometry_poses()
        what = f"the chained odometry of all {len(log)} scans"
    else:
        file_ids, file_poses = _poses_file(args.poses, args.ignore_unknown)
        order, ids = _scan_ids(file_ids, log, label, f"--poses {args.poses}")
        poses = np.asarray(file_poses)[order]
        what = f"the poses of {args.poses} ({ids.size} scans)"
    lines.append(f"poses             {what}")
    if estimated and ids.size >= 2:
        lines.append(
            f"ATE               {_ate_text(poses, log.reference[ids])} against {_against(log)}"
        )
    t = time.perf_counter()
    grid = occupancy_grid(log.subset(ids), poses, resolution=args.resolution)
    times.append(f"occupancy grid {time.perf_counter() - t:.3f} s")
    q = map_quality(grid)
    if sink is not None:
        sink.write(
            f"[map] occupancy grid: {grid.shape[1]} x {grid.shape[0]} cells  t "
            f"{time.perf_counter() - t0:.3f} s\n"
        )
        sink.flush()
    title = args.title if args.title is not None else f"{log.name}: {what}"

    def draw(ax):
        from .plotting import plot_occupancy

        plot_occupancy(grid, ax=ax, title=title)

    t = time.perf_counter()
    _save_figure(draw, output, args.dpi)
    times.append(f"image {time.perf_counter() - t:.3f} s")
    x0, x1, y0, y1 = grid.extent
    hit = "n/a" if q.hit_cells is None else str(q.hit_cells)
    lines += [
        f"map               {grid.shape[1]} x {grid.shape[0]} cells of {grid.resolution:g} m "
        f"(x {x0:.2f}..{x1:.2f} m, y {y0:.2f}..{y1:.2f} m) from {ids.size} scans",
        f"map quality       hit_cells {hit}, entropy {q.entropy:.4f} bits, fraction_confident "
        f"{q.fraction_confident:.4f} (fewer hit cells, lower entropy: sharper walls; compare the "
        "same scans at one resolution)",
        f"time              {', '.join(times)}; total {time.perf_counter() - t0:.3f} s",
        f"wrote             {output}",
    ]
    print("\n".join(lines))
    return 0


# ----------------------------------------------------------------------------- datasets
def _where(name):
    d = datasets.info(name)
    roots = datasets.mirrors()
    for root in roots:  # the first folder that has the file is the one datasets.path reads
        p = root / d.relpath
        if p.is_file():
            return "mirror", str(p)
    if len(roots) == 1:
        return "missing", f"not in the mirror LAGOLIB_DATA={roots[0]}: get it from {d.url}"
    if roots:
        return "missing", f"in none of the LAGOLIB_DATA folders: get it from {d.url}"
    try:
        cache = datasets.cache_dir()
    except ImportError:  # pooch is needed for the default cache folder and for downloads
        return "url", f"would be fetched from {d.url} (needs pooch)"
    p = cache / d.relpath.replace("/", "__")
    if p.is_file():
        return "cache", str(p)
    return "url", f"would be fetched from {d.url}"


def _cmd_datasets(args):
    rows = []
    for name in datasets.names():
        d = datasets.info(name)
        status, where = _where(name)
        rows.append(
            {
                "name": name,
                "kind": d.kind,
                "vertices": d.vertices,
                "edges": d.edges,
                "scans": d.scans,
                "beams": d.beams,
                "status": status,
                "where": where,
                "url": d.url,
                "description": d.description,
            }
        )
    examples = []
    for name in datasets.examples():
        p = datasets.data_dir() / f"{name}.g2o"
        g = read(p)
        examples.append({"name": name, "vertices": g.n, "edges": g.m, "where": str(p)})
    if args.json:
        print(json.dumps({"datasets": rows, "examples": examples}, indent=1))
        return 0
    roots = datasets.mirrors()
    if len(roots) == 1:
        print(f"benchmarks (from the mirror LAGOLIB_DATA={roots[0]}):")
    elif roots:
        print(f"benchmarks (from the mirrors LAGOLIB_DATA={os.pathsep.join(map(str, roots))}):")
    else:
        try:
            cache = f" {datasets.cache_dir()}"
        except ImportError:
            cache = ""
        print(f"benchmarks (LAGOLIB_DATA is unset: downloaded on first use into the cache{cache}):")
    print(f"  {'name':<18}{'kind':<7}{'vertices':>9}{'edges':>8}  where")
    for r in rows:
        if r["kind"] == "laser":
            continue
        v = r["vertices"] if r["vertices"] or r["kind"] != "graph" else "-"
        print(f"  {r['name']:<18}{r['kind']:<7}{v:>9}{r['edges']:>8}  {r['where']}")
    print("  (vertices '-': the file has edge lines only; poses come from the odometry guess)")
    print("laser logs (Carmen; their reference poses are GMapping's estimate, not ground truth):")
    print(f"  {'name':<18}{'kind':<7}{'scans':>9}{'beams':>8}  where")
    for r in rows:
        if r["kind"] == "laser":
            print(f"  {r['name']:<18}{'laser':<7}{r['scans']:>9}{r['beams']:>8}  {r['where']}")
    print("shipped examples (offline, simulated with ground truth):")
    for e in examples:
        print(f"  {e['name']:<18}{'graph':<7}{e['vertices']:>9}{e['edges']:>8}  {e['where']}")
    return 0


# ----------------------------------------------------------------------------- parser
def _add_frontend_options(p):
    """The options of the front end (``frontend``, and ``map`` of a LOG); None: the default."""
    g = p.add_argument_group("front end (lagolib.frontend.build_graph)")
    g.add_argument(
        "--min-translation",
        type=_positive_float,
        metavar="M",
        help=f"a new keyframe after M metres of odometry (default: {_FE['min_translation']:g})",
    )
    g.add_argument(
        "--min-rotation",
        type=_positive_float,
        metavar="DEG",
        help=f"... or after DEG degrees of turning (default: {np.degrees(_FE['min_rotation']):g})",
    )
    g.add_argument(
        "--translation-sigma",
        type=_positive_float,
        metavar="FRACTION",
        help="the odometry prior of the sequential matches: standard deviation of the position, "
        f"a fraction of the distance travelled (default: {_FE['translation_sigma']:g})",
    )
    g.add_argument(
        "--rotation-sigma",
        type=_positive_float,
        metavar="DEG",
        help="... and of the heading, degrees per keyframe increment (default: "
        f"{np.degrees(_FE['rotation_sigma']):g}; real odometry's heading drifts: INTEL's by "
        "about -3.9 deg per metre)",
    )
    g.add_argument(
        "--match-range",
        type=_positive_float,
        metavar="M",
        help=f"returns farther than M metres are not scan-matched (default: {_FE['max_range']:g})",
    )
    g.add_argument(
        "--batch",
        action="store_true",
        help="gate every candidate against the chain of sequential matches, optimize nothing "
        "(default: incremental, Gauss-Newton after every accepted closure)",
    )
    g.add_argument(
        "--simulated-odometry",
        nargs=2,
        type=_nonnegative_float,
        metavar=("FRACTION", "DEG"),
        help="replace the log's REAL odometry increments by its reference increments plus "
        "Gaussian noise: FRACTION of the translation and DEG degrees per step (the issue's "
        f"experiment: {_SIM_SIGMA[0]:g} {np.degrees(_SIM_SIGMA[1]):g}); default: the real "
        "increments",
    )
    g.add_argument(
        "--seed",
        type=_nonnegative_int,
        metavar="N",
        help="seed of --simulated-odometry's noise (default: 0)",
    )


def _parser():
    debug = _Parser(add_help=False)
    debug.add_argument(
        "--debug", action="store_true", default=argparse.SUPPRESS, help="show tracebacks"
    )
    reading = _Parser(add_help=False)
    reading.add_argument(
        "--ignore-unknown",
        action="store_true",
        help="skip lines with tags lagolib does not read (FIX, VERTEX_XY, ...) instead of failing",
    )
    file_help = (
        "g2o (VERTEX_SE2/EDGE_SE2) or TORO (VERTEX2/EDGE2) file, or a name from 'lagolib datasets'"
    )

    top = _Parser(
        prog="lagolib",
        formatter_class=_Formatter,
        description=(
            "Planar pose-graph SLAM from the shell: inspect, solve (LAGO, Gauss-Newton, "
            "Levenberg-Marquardt, SGD), certify global optimality and plot g2o/TORO files; "
            "build a pose graph from a laser log and draw its map.\n\n"
            "examples:\n"
            "  lagolib info intel\n"
            "  lagolib solve graph.g2o --method lago+gn --progress -o solved.g2o --plot solved.png\n"
            "  lagolib certify mit --initial odometry\n"
            "  lagolib plot solved.g2o --ellipses -o solved.png\n"
            "  lagolib frontend intel_laser --progress -o intel_fe.g2o\n"
            "  lagolib map intel_laser -o intel_map.png\n"
            "  lagolib datasets\n\n"
            f"exit status: 0 ok, 1 error, 2 usage error, {NOT_CERTIFIED} not certified (certify, "
            "solve --certify), 130 interrupted"
        ),
    )
    top.add_argument("--debug", action="store_true", help="show the traceback of an error")
    sub = top.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    p = sub.add_parser(
        "info",
        parents=[debug, reading],
        formatter_class=_Formatter,
        help="what is in a pose-graph file",
        description=(
            "Counts (poses, edges, odometric edges, loop closures), connectivity, the odometric\n"
            "chain (the consecutive-id pairs without an edge are named), the chords LAGO must\n"
            "regularize (k != 0, Carlone et al. 2011 Thm. 3) for each spanning tree lagolib has,\n"
            "how many edges have isotropic translational information or rotation-translation\n"
            "coupling, and chi2 at the file's poses.\n\n"
            "example:\n  lagolib info data/square_loop.g2o\n  lagolib info intel --json"
        ),
    )
    p.add_argument("file", metavar="FILE", help=file_help)
    p.add_argument("--error", choices=ERRORS, default="t2v", help="residual for chi2")
    p.add_argument("--json", action="store_true", help="print the numbers as JSON")
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser(
        "solve",
        parents=[debug, reading],
        formatter_class=_Formatter,
        help="optimize a pose graph and write the result",
        description=(
            "Solve a pose graph and write it (g2o, or TORO for .graph) with the optimized poses.\n"
            "  lago     Carlone et al.'s linear approximation (closed form, no initial guess)\n"
            "  gn, lm   Gauss-Newton / Levenberg-Marquardt from the file's poses\n"
            "  lago+gn  Gauss-Newton from LAGO's poses\n"
            "  sgd      stochastic gradient descent on a tree parameterization (TORO-style)\n"
            "--progress prints one line per iteration on stderr (chi2, relative decrease, max\n"
            "|dx|, elapsed time); one summary line goes to stdout.\n"
            "--certify then polishes the chordal cost from the solved poses and tests the\n"
            "certificate of global optimality (as 'lagolib certify' does, without escaping):\n"
            f"the certificate's lines follow the summary; exit status {NOT_CERTIFIED} when not "
            "certified.\n\n"
            "examples:\n"
            "  lagolib solve intel --method lago+gn --progress -o intel_solved.g2o\n"
            "  lagolib solve mit --method gn --certify -o mit_gn.g2o"
        ),
    )
    p.add_argument("file", metavar="FILE", help=file_help)
    p.add_argument(
        "--method",
        "-m",
        choices=METHODS,
        default=None,
        help="the solver (default lago+gn; with --robust, the start: lago or lago+gn start it "
        "from LAGO's poses, by default it starts from the file's)",
    )
    p.add_argument(
        "--tree",
        choices=topology.TREES,
        default=None,
        help="spanning tree for lago and lago+gn (default: min_uncertainty) and for sgd "
        "(default: sgd's own)",
    )
    p.add_argument(
        "--backend",
        choices=("auto",) + BACKENDS,
        default=None,
        help="sparse Cholesky of lago, gn, lm and lago+gn (default: auto, PARDISO for large "
        "systems when MKL is installed, else qdldl)",
    )
    p.add_argument(
        "--error",
        choices=ERRORS,
        default="t2v",
        help="residual: g2o's t2v or GTSAM's log; minimized by gn/lm, reported for all",
    )
    p.add_argument(
        "--iterations",
        "-n",
        type=_positive_int,
        default=None,
        metavar="N",
        help="at most N iterations for gn, lm and the gn of lago+gn (default: 100); N for sgd "
        "(default: sgd's own)",
    )
    p.add_argument(
        "-o", "--output", required=True, metavar="OUT", help="where to write (.g2o or .graph)"
    )
    p.add_argument("--plot", metavar="PNG", help="also draw the solved graph into this image")
    p.add_argument("--dpi", type=_dpi, default=_DPI, help="resolution of --plot (10 to 2000)")
    p.add_argument("--progress", action="store_true", help="per-iteration lines on stderr")
    p.add_argument(
        "--robust",
        choices=robust.METHODS,
        default=None,
        metavar="R",
        help="robust back end against wrong loop closures: " + ", ".join(robust.METHODS)
        + " (lagolib.robust.solve), from LAGO's poses (--method lago, lago+gn) or the file's "
        "(gn, lm); OUT keeps every edge, the summary counts the outliers",
    )
    p.add_argument(
        "--certify",
        action="store_true",
        help="also certify: polish the chordal cost from the solved poses and test the "
        f"certificate; exit status {NOT_CERTIFIED} when not certified (OUT is the same); with "
        "--robust, the certified pipeline on the inliers only (the choice of inliers is not "
        "certified)",
    )
    p.set_defaults(func=_cmd_solve)

    p = sub.add_parser(
        "outliers",
        parents=[debug, reading],
        formatter_class=_Formatter,
        help="which loop closures are wrong: a robust back end's classification",
        description=(
            "Classify the loop closures of a pose graph as inliers or outliers with a robust\n"
            "back end (lagolib.robust.solve; default gnc-tls: graduated non-convexity with\n"
            "truncated least squares, from the file's poses) and list the outliers: edge\n"
            "index, vertex ids and chi2 at the robust estimate.  --json prints the numbers.\n\n"
            "examples:\n"
            "  lagolib outliers intel\n"
            "  lagolib outliers my_frontend.g2o --method pcm+gnc-tls --json"
        ),
    )
    p.add_argument("file", metavar="FILE", help=file_help)
    p.add_argument("--method", "-m", choices=robust.METHODS, default="gnc-tls", metavar="R",
                   help="the robust back end: " + ", ".join(robust.METHODS))
    p.add_argument("--error", choices=ERRORS, default="t2v", help="residual for chi2")
    p.add_argument("--json", action="store_true", help="print the numbers as JSON")
    p.set_defaults(func=_cmd_outliers)

    p = sub.add_parser(
        "certify",
        parents=[debug, reading],
        formatter_class=_Formatter,
        help="is it the global optimum? solve, certify, escape local minima",
        description=(
            "Solve a pose graph and certify that the answer is the global optimum\n"
            "(lagolib.certify.solve; Carlone et al., TRO 2016; SE-Sync, Rosen et al. 2019):\n"
            "  LAGO (or the file's poses, --initial odometry) -> Gauss-Newton on chi2\n"
            "  -> Newton polish of the chordal cost f -> the dual certificate: a lower bound\n"
            "     on the global minimum of f (a sparse factorization of S~ + eta I, and\n"
            "     lambda_min(S~) when needed); certified when f - bound is within its\n"
            "     tolerance (about 2e-7 of the sum of |Lagrange multipliers|)\n"
            "  -> if not: escape along the eigenvector of lambda_min (one rank up the\n"
            "     Riemannian staircase), polish, round, certify again, at most --max-escapes\n"
            "     times (and a budget of Newton iterations; when the staircase cannot go on it\n"
            "     stops with the best bound) -> Gauss-Newton on chi2 from the best chordal\n"
            "     minimum.\n"
            "Prints the stages, chi2, f, the certificate, a lower bound on the global minimum\n"
            "of f, the gap f - bound, the escapes and why it stopped.  --progress prints\n"
            "the stages on stderr as they end; the summary goes to stdout.  -o writes the\n"
            "chi2 poses (as 'lagolib solve -o' does), certified or not.\n\n"
            f"exit status: 0 certified globally optimal; {NOT_CERTIFIED} ran, but NOT certified\n"
            "(a local minimum the escape budget did not leave, a relaxation that is not\n"
            "tight, or a staircase that could not go on: the gap says how far from optimal\n"
            "f can be); 1 error; 2 usage error.\n\n"
            "examples:\n"
            "  lagolib certify mit --initial odometry\n"
            "  lagolib certify intel --eigenvalues 3 --progress -o intel_optimal.g2o"
        ),
    )
    p.add_argument("file", metavar="FILE", help=file_help)
    p.add_argument(
        "--initial",
        choices=INITIALS,
        default="lago",
        help="start from the file's poses (odometry) or from LAGO's",
    )
    p.add_argument(
        "--tree",
        choices=topology.TREES,
        default=None,
        help="LAGO's spanning tree (default: min_uncertainty)",
    )
    p.add_argument(
        "--max-escapes",
        type=_nonnegative_int,
        default=_MAX_ESCAPES,
        metavar="N",
        help="at most N escapes from a point the certificate rejects (0: certify only)",
    )
    p.add_argument(
        "--eta",
        type=_nonnegative_float,
        default=None,
        metavar="X",
        help="the shift of the certificate's first test: one factorization of S~ + X I proves "
        "lambda_min(S~) > -X and f* >= sum(lambda) - n X; when that bound does not certify (or "
        "the test fails) lambda_min is computed instead.  X sets the work, not what 'certified' "
        f"means (default: {certify.ETA:g} x the mean |Lagrange multiplier|, the largest shift "
        "whose bound can certify)",
    )
    p.add_argument(
        "--eigenvalues",
        type=_positive_int,
        default=None,
        metavar="K",
        help="also compute and print the K smallest eigenvalues of S~",
    )
    p.add_argument("-o", "--output", metavar="OUT", help="write the solved graph (.g2o or .graph)")
    p.add_argument("--progress", action="store_true", help="one line per stage on stderr")
    p.set_defaults(func=_cmd_certify)

    p = sub.add_parser(
        "plot",
        parents=[debug, reading],
        formatter_class=_Formatter,
        help="draw a pose graph",
        description=(
            "Draw a pose graph: odometric edges solid, loop closures dotted (Carlone et al. 2011,\n"
            f"Fig. 1), into a {_INCHES:g} x {_INCHES:g} inch image ({_INCHES * _DPI:.0f} pixels "
            f"square at the default {_DPI} dpi).\n"
            "--ellipses adds each pose's position uncertainty (the marginal covariance of the\n"
            "least-squares problem linearized at the drawn poses, first pose fixed): meaningful\n"
            "at an optimum, e.g. the output of 'lagolib solve'.  Each ellipse holds 95 % of a\n"
            "Gaussian's mass (--confidence, or --sigma for a scale in standard deviations), and\n"
            "only a sample is drawn where they would bury the map: at most 100 whose areas add\n"
            "up to at most a quarter of the map's bounding box, but at least 10 (--every K picks\n"
            "every K-th pose instead).\n\n"
            "example:\n"
            "  lagolib plot intel_solved.g2o --ellipses -o intel.png\n"
            "  lagolib plot ring --poses ring_truth.txt -o ring_truth.png"
        ),
    )
    p.add_argument("file", metavar="FILE", help=file_help)
    p.add_argument(
        "--poses",
        metavar="P",
        help="draw at these poses: 'id x y theta' (or 'x y theta') lines, or a .g2o/.graph file",
    )
    p.add_argument("--ellipses", action="store_true", help="draw covariance ellipses")
    p.add_argument(
        "--every",
        type=_positive_int,
        default=None,
        metavar="K",
        help="an ellipse on every K-th pose (default: at most 100 whose areas add up to at most "
        "a quarter of the map, at least 10)",
    )
    level = p.add_mutually_exclusive_group()
    level.add_argument(
        "--confidence",
        type=_probability,
        default=0.95,
        metavar="P",
        help="the probability mass inside each ellipse, in (0, 1)",
    )
    level.add_argument(
        "--sigma",
        type=_positive_float,
        default=None,
        metavar="K",
        help="instead of --confidence, the ellipses' size in standard deviations",
    )
    p.add_argument("--title", default=None, help="title (default: the file name)")
    p.add_argument("--dpi", type=_dpi, default=_DPI, help="resolution (10 to 2000)")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="image (.png, .pdf, .svg)")
    p.set_defaults(func=_cmd_plot)

    log_help = (
        "a Carmen log file (plain or .gz), a laser log's name from 'lagolib datasets' "
        f"(intel_laser, ...), or '{SIMULATED}' (the simulated office, offline)"
    )
    p = sub.add_parser(
        "frontend",
        parents=[debug],
        formatter_class=_Formatter,
        help="build a pose graph from a laser log (scan matching, loop closures)",
        description=(
            "Build a pose graph from a Carmen laser log (lagolib.frontend.build_graph): a keyframe\n"
            "every M metres or DEG degrees of odometry; a sequential edge between consecutive\n"
            "keyframes by point-to-line ICP with the odometry increment as a prior; loop-closure\n"
            "candidates gated by the Mahalanobis distance under the relative covariance\n"
            "(chapter 3), then verified by scan matching with explicit rules (inliers, residual,\n"
            "degeneracy: corridors, ambiguity, consistency with the prediction).  Incremental by\n"
            "default (Gauss-Newton after every accepted closure); --batch gates every candidate\n"
            "against the chain of sequential matches.\n"
            "The odometry is the log's REAL increments, unless --simulated-odometry replaces\n"
            "them (the reference increments plus seeded Gaussian noise).\n"
            "Vertex ids are the scans' indices in the log (0-based, in FLASER order), so a result\n"
            "compares with the log's reference poses.  OUT holds the front end's estimate: solve\n"
            "it with 'lagolib certify OUT', draw its map with 'lagolib map OUT --log LOG'.\n"
            "The summary (stdout) counts the candidates gated, matched, accepted and rejected (by\n"
            "rule), the wrong closures (off the log's reference by > 0.5 m or 5 deg: for a real\n"
            "log GMapping's corrected poses, an estimate; the ground truth for a simulated one)\n"
            "and the time per stage; --progress prints the stages on stderr as they go.\n\n"
            "examples:\n"
            "  lagolib frontend intel_laser --progress -o intel_fe.g2o\n"
            "  lagolib frontend intel_laser --simulated-odometry 0.05 2 --seed 1 -o intel_sim.g2o\n"
            f"  lagolib frontend {SIMULATED} --batch -o office.g2o"
        ),
    )
    p.add_argument("log", metavar="LOG", help=log_help)
    p.add_argument(
        "-o", "--output", required=True, metavar="OUT", help="where to write (.g2o or .graph)"
    )
    p.add_argument("--progress", action="store_true", help="the stages on stderr as they go")
    _add_frontend_options(p)
    p.set_defaults(func=_cmd_frontend)

    p = sub.add_parser(
        "map",
        parents=[debug, reading],
        formatter_class=_Formatter,
        help="the occupancy grid map of a laser log (front end, optimization, map)",
        description=(
            "Draw the occupancy grid map (log odds by ray casting, Thrun et al. 2005, Table 9.1;\n"
            "lagolib.occupancy) of a laser log's scans at a set of poses:\n"
            "  LOG                    the front end (as 'lagolib frontend', same options), then\n"
            "                         certify.solve (LAGO -> Gauss-Newton -> certificate), then\n"
            "                         the keyframes' scans at the optimized poses: one call\n"
            "  LOG --poses reference  every scan at the log's reference poses (for a real log\n"
            "                         GMapping's corrected poses)\n"
            "  LOG --poses odometry   every scan at its chained odometry\n"
            "  LOG --poses FILE       the scans FILE's ids name, at its poses (a .g2o/.graph\n"
            "                         file, or 'id x y theta' lines)\n"
            "  GRAPH --log LOG        the scans the graph's vertex ids name, at its poses (e.g.\n"
            "                         'lagolib frontend' then 'lagolib certify -o'); with --poses\n"
            "                         reference or odometry: the same scans at those poses\n"
            "Vertex ids are the scans' indices in the log (0-based, in FLASER order).  Prints the\n"
            "ATE against the log's reference when the poses are an estimate, and the map's\n"
            "quality (lagolib.occupancy.map_quality: hit_cells and entropy, lower is sharper;\n"
            "fraction_confident, higher is).\n\n"
            "examples:\n"
            "  lagolib map intel_laser -o intel_map.png\n"
            "  lagolib map intel_laser --poses reference -o intel_gmapping.png\n"
            "  lagolib map intel_fe.g2o --log intel_laser --resolution 0.1 -o intel_fe.png"
        ),
    )
    p.add_argument(
        "input",
        metavar="INPUT",
        help=f"a laser LOG ({log_help}), or a pose GRAPH (g2o or TORO file, or a name from "
        "'lagolib datasets') with --log",
    )
    p.add_argument("--log", metavar="LOG", help="the laser log of a GRAPH input: its scans")
    p.add_argument(
        "--poses",
        metavar="P",
        help="'reference', 'odometry', or a FILE of poses whose ids are scan indices (.g2o, "
        ".graph, or 'id x y theta' lines); default: optimize (LOG) or the graph's (GRAPH)",
    )
    p.add_argument(
        "--resolution", type=_positive_float, default=0.05, metavar="M", help="cell side, metres"
    )
    p.add_argument("--title", default=None, help="title (default: the log's name and the poses)")
    p.add_argument("--dpi", type=_dpi, default=_DPI, help="resolution (10 to 2000)")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="image (.png, .pdf, .svg)")
    p.add_argument("--progress", action="store_true", help="the stages on stderr as they go")
    _add_frontend_options(p)
    p.set_defaults(func=_cmd_map)

    p = sub.add_parser(
        "datasets",
        parents=[debug],
        formatter_class=_Formatter,
        help="the registered benchmarks and where they are",
        description=(
            "List the registered benchmarks (name, kind, vertex and edge counts; the laser logs\n"
            "with their scan and beam counts) and where each one is: in a LAGOLIB_DATA mirror\n"
            "(several folders separated by ':', as in PATH: the first that has the file), in the\n"
            "download cache, or the URL it would be fetched from on first use; then the examples\n"
            "shipped with lagolib.\n\n"
            "example:\n  LAGOLIB_DATA=/data/posegraphs:/data/laser lagolib datasets"
        ),
    )
    p.add_argument("--json", action="store_true", help="print the list as JSON")
    p.set_defaults(func=_cmd_datasets)

    sub.add_parser("book", add_help=False, help="the book's tools (lagolib book --help)")
    return top


# ----------------------------------------------------------------------------- messages
#: Suggestions in library messages spelled for Python callers, and the option to type in the
#: shell instead: ``(pattern, option, text for a command without that option)``; ``{v}`` is the
#: value the pattern captured.  A command without the option names one that has it, unless the
#: third entry says what to print instead.
_SHELL_OPTIONS = (
    (r"\bignore_unknown=True\b", "--ignore-unknown", None),
    (r"\bbackend='(\w+)'", "--backend {v}", None),
    (r"\bmethod='([\w+]+)'", "--method {v}", None),
    (r"\btree='(\w+)'", "--tree {v}", None),
    (r"\bmax_iterations=(\d+)", "--iterations {v}", "its cap of {v} iterations"),
    (r"\bmax_escapes=(\d+)", "--max-escapes {v}", "its cap of {v} escapes"),
    (r"\bforce=True\b", "--force", None),
    (r"\bbook_dir='([^']*)'", "--book {v}", None),
    (r"\bbook='([^']*)'", "--book {v}", None),
    (r"\bjobs=('[^']*'|[-\w.]+)", "--jobs {v}", None),
    (r"\bcell_timeout=('[^']*'|[-\w.]+)", "--cell-timeout {v}", None),
    (r"\bnotebook_timeout=('[^']*'|[-\w.]+)", "--notebook-timeout {v}", None),
)
#: Python advice in library messages that no option expresses, and what to say in the shell.
_SHELL_PHRASES = (
    (
        r"fix one of its poses \(fixed=\[[^\]]*\]\) or add a prior "
        r"\(prior=lagolib\.Prior\([^)]*\)\)",
        "connect it to the rest of the graph with an edge, or give each component a file of its "
        "own (the lagolib command fixes one pose: the one with the smallest id)",
    ),
    (
        r"certify each component \(PoseGraph\.components gives the labels\)",
        "certify each component from a file of its own",
    ),
    (r"lagolib\.datasets\.path\('([^']*)'\)", r"'lagolib info \1'"),
    (r"\bout_dir='([^']*)'", r"OUTDIR \1"),
    (
        r"\(raise max_range, or drop the scan from the log\)",
        "(raise --match-range, or drop the scan)",
    ),
    (
        r"coarsen the resolution, or pass extent=\(xmin, xmax, ymin, ymax\) around the region "
        r"you need",
        "use a coarser --resolution",
    ),
)
#: Options of the commands handed to another module's ``main`` (not in :func:`_parser`).
_DELEGATED_OPTIONS = {
    "book": {"-h", "--help", "--book", "--force", "--no-hints", "-o", "--output", "--assignment",
             "--feedback", "--cell-timeout", "--notebook-timeout", "-j", "--jobs"}
}


@functools.cache
def _command_options():
    """``{command: set of its option strings}``, read from the parser."""
    top = _parser()
    sub = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    options = {name: set(p._option_string_actions) for name, p in sub.choices.items()}
    return options | _DELEGATED_OPTIONS


def _for_shell(text, command):
    """``text`` (a library message) with its suggestions for Python callers written as what to
    type in the shell for ``command``: ``backend='qdldl'`` becomes ``--backend qdldl``."""
    options = _command_options()
    for pattern, option, absent in _SHELL_OPTIONS:
        flag = option.split()[0]

        def say(m, option=option, flag=flag, absent=absent):
            v = m.group(1) if m.groups() else ""
            if flag in options.get(command, ()):
                return option.format(v=v)
            if absent is not None:
                return absent.format(v=v)
            other = next(c for c, flags in options.items() if flag in flags)
            return f"'lagolib {other} {option.format(v=v)}'"

        text = re.sub(pattern, say, text)
    for pattern, replacement in _SHELL_PHRASES:
        text = re.sub(pattern, replacement, text)
    return text


# ----------------------------------------------------------------------------- main
def _warning_printer(command):
    def show(message, category, filename, lineno, file=None, line=None):
        print(f"lagolib: warning: {_for_shell(str(message), command)}", file=sys.stderr)

    return show


def _delegate(command, argv):
    """Run another module's ``main(argv)`` (``lagolib book``): an argparse usage error of it
    becomes one line, as lagolib's own are (no usage block, no second line)."""
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            return COMMANDS[command](argv)
    except SystemExit as exc:
        text = err.getvalue()
        if exc.code != 2 or ": error: " not in text:
            raise
        err = io.StringIO()  # the usage block is not replayed: one line says it all
        message = text.strip().splitlines()[-1].split(": error: ", 1)[1]
        choices = re.search(r"\{([\w,-]+)\}", text)
        if choices and not [a for a in argv if not a.startswith("-")]:
            message = f"a subcommand is required: {', '.join(choices[1].split(','))}"
        raise _UsageError(f"{command}: {message}") from None
    finally:
        sys.stderr.write(_for_shell(err.getvalue(), command))  # what it wrote, for the shell


def _one_line(exc):
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        return f"{exc.filename}: {exc.strerror}"
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def _dispatch(argv):
    rest = list(argv)
    while rest and rest[0] == "--debug":
        rest.pop(0)
    if rest and rest[0] in COMMANDS:
        return _delegate(rest[0], rest[1:])
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command is None:
        raise _UsageError(
            "a command is required (info, solve, outliers, certify, plot, frontend, map, "
            "datasets, book)"
        )
    return args.func(args)


def main(argv=None) -> int:
    """Run ``lagolib`` with ``argv`` (default ``sys.argv[1:]``); returns the exit status."""
    argv = sys.argv[1:] if argv is None else [os.fspath(a) for a in argv]
    debug = "--debug" in argv
    command = next((a for a in argv if not a.startswith("-")), None)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            # numpy's overflow/invalid-value warnings: a failure they announce is reported as an
            # error (non-finite poses, lagolib's own checks), one line instead of several
            warnings.simplefilter("ignore", RuntimeWarning)
            warnings.showwarning = _warning_printer(command)
            return _dispatch(argv)
    except SystemExit as exc:  # --help, and the book's argparse
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except KeyboardInterrupt:
        print("lagolib: interrupted", file=sys.stderr)
        return 130
    except _UsageError as exc:
        if debug:
            traceback.print_exc()
        known = ("info", "solve", "outliers", "certify", "plot", "frontend", "map", "datasets",
                 *COMMANDS)
        hint = f"lagolib {command} --help" if command in known else "lagolib --help"
        print(
            f"lagolib: error: {_for_shell(_one_line(exc), command)} (see '{hint}')",
            file=sys.stderr,
        )
        return 2
    except BrokenPipeError:  # e.g. 'lagolib datasets | head -1'
        with contextlib.suppress(OSError, ValueError, AttributeError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except Exception as exc:
        if debug:
            traceback.print_exc()
        usage = isinstance(exc, OptionError | OptionTypeError)
        known = isinstance(exc, LagolibError | OSError)
        text = _for_shell(_one_line(exc), command)
        if not known:
            text = (
                f"internal error: {type(exc).__name__}: {text} (rerun with --debug for the "
                "traceback, and please report it)"
            )
        print(f"lagolib: error: {text}", file=sys.stderr)
        return 2 if usage else 1


if __name__ == "__main__":
    sys.exit(main())
