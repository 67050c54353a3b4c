"""When loop closures lie: robust back ends, outlier classification and what a certificate covers.

Every least-squares method in lagolib assumes each measurement is right.  A front end is not
always right: a wrong loop closure enters ``Σ e^T Ω e`` with a residual of tens of σ and bends
the whole map.  This module puts together what the rest of lagolib provides:

* :func:`gnc` — graduated non-convexity (Yang, Antonante, Tzoumas, Carlone 2020) with the
  truncated-least-squares or Geman–McClure kernel: start from the convex least-squares problem,
  make the kernel non-convex step by step (the control parameter μ), and re-solve a weighted
  least-squares problem (:class:`lagolib.gauss_newton.WeightedLeastSquares`) at every step.
  With globally solved weighted problems it needs no good start; here they are solved by
  Gauss–Newton, so it can still fail from a drifted start (``benchmarks/ROBUST.md``: intel with
  100 random wrong closures).  GTSAM's ``GncLMOptimizer`` is the same method.
* :func:`solve` — one call for every method: ``"gnc-tls"``, ``"gnc-gm"``, the IRLS kernels of
  :mod:`lagolib.kernels` inside :func:`lagolib.optimize` (``"huber"``, ``"cauchy"``, ``"gm"``,
  ``"tls"``, ``"dcs"``), and pairwise consistency maximization (``"pcm"``,
  :mod:`lagolib.consistency`) alone or followed by GNC (``"pcm+gnc-tls"``).  Every method
  returns a :class:`RobustResult` with the same fields: poses, a weight and an inlier flag per
  edge.
* :func:`scores` — precision and recall of the inlier set against the known outliers
  (:func:`lagolib.simulate.add_outliers`).
* :func:`certify_inliers` — chapter 9's certificate for the problem that remains once the
  outliers are removed; and, stated on the result, what it does not cover: the choice of which
  edges are inliers.

References
----------
.. [1] H. Yang, P. Antonante, V. Tzoumas, L. Carlone, "Graduated non-convexity for robust
   spatial perception: from non-minimal solvers to global outlier rejection", IEEE RA-L 5(2),
   2020.
.. [2] P. Agarwal, G. D. Tipaldi, L. Spinello, C. Stachniss, W. Burgard, "Robust map
   optimization using dynamic covariance scaling", ICRA 2013.
.. [3] N. Sünderhauf, P. Protzel, "Switchable constraints for robust pose graph SLAM", IROS
   2012.
.. [4] J. G. Mangelson, D. Dominic, R. M. Eustice, R. Vasudevan, "Pairwise consistency
   maximization for robust multi-robot map merging", ICRA 2018.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .certify import solve as certified_solve
from .checks import check_bool, check_choice, check_int, check_real
from .consistency import pcm
from .errors import GaugeError, GraphError, OptionError, OptionTypeError
from .gauss_newton import WeightedLeastSquares, optimize, robust_edge_mask
from .graph import PoseGraph, as_graph_poses, check_graph
from .graph import chi2 as graph_chi2
from .kernels import INLIER_THRESHOLD, KERNELS, gnc_initial_mu, gnc_weights
from .kernels import kernel as as_kernel

__all__ = [
    "METHODS",
    "RobustResult",
    "gnc",
    "solve",
    "Scores",
    "scores",
    "inlier_graph",
    "InlierCertificate",
    "certify_inliers",
]

#: :func:`solve`'s methods (the CLI's ``--robust``).
METHODS = ("gnc-tls", "gnc-gm", "huber", "cauchy", "gm", "tls", "dcs", "pcm", "pcm+gnc-tls")

#: GNC's factor on μ per outer iteration (Yang et al. 2020, §V; GTSAM's ``muStep``).
MU_STEP = 1.4


@dataclass
class RobustResult:
    """What :func:`gnc` and :func:`solve` return.

    Attributes
    ----------
    poses : ndarray, shape (n, 3)
    graph : PoseGraph
        The input graph with ``poses`` (all edges, outliers included).
    method : str
    inlier : ndarray of bool, shape (m,)
        The edges judged right; edges outside ``robust_edges`` (by default the odometry) are
        always True.
    weights : ndarray, shape (m,)
        The final weight on each edge's information (binary after GNC-TLS).
    chi2 : float
        χ² of all edges at ``poses`` (outliers included: large when outliers are rejected).
    chi2_inliers : float
        χ² of the inlier edges (plus priors) at ``poses``: the least-squares cost of the
        problem that remains.
    iterations : int
        Outer iterations (GNC's μ steps; 1 for the IRLS kernels, PCM).
    gauss_newton_iterations : int
        Gauss–Newton steps in all.
    converged : bool
    reason : str
    mu : list of float
        GNC's control parameter per outer iteration (empty for other methods).
    outliers_history : list of int
        Robust edges with weight below 1/2 after each outer iteration (GNC).
    timings : dict
        Seconds: ``"total"`` and per stage.
    """

    poses: np.ndarray
    graph: PoseGraph
    method: str
    inlier: np.ndarray
    weights: np.ndarray
    chi2: float
    chi2_inliers: float
    iterations: int
    gauss_newton_iterations: int
    converged: bool
    reason: str
    mu: list = field(default_factory=list)
    outliers_history: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)

    @property
    def outliers(self):
        """Indices of the edges judged wrong, shape (k,)."""
        return np.flatnonzero(~self.inlier)

    def __repr__(self):
        return (
            f"RobustResult(method={self.method!r}, outliers={int((~self.inlier).sum())}, "
            f"chi2_inliers={self.chi2_inliers:.10g}, iterations={self.iterations}, "
            f"converged={self.converged}, reason={self.reason!r})"
        )


def _check_c(c, where):
    return check_real(c, "c", where, minimum=0.0, strict=True)


#: :class:`_ActiveSet` rebuilds its system without the zero-weight edges once this fraction of
#: the edges has changed since the last build (a weight of 0 costs a factorization its fill).
REBUILD_FRACTION = 0.01


class _ActiveSet:
    """Weighted least squares over the edges whose weight is not zero.

    An edge with weight 0 adds nothing to ``H`` but keeps its place in the sparsity pattern —
    and a wrong loop closure between distant poses costs the factorization a great deal of
    fill (M3500 with 1000 random wrong closures: about 100 times the time per factorization).
    This solver rebuilds :class:`~lagolib.gauss_newton.WeightedLeastSquares` on the graph
    without them once enough weights have become zero, and at once when an excluded edge's
    weight becomes positive again, so the answer is the same as with every edge in place.
    Residuals are always evaluated on the whole graph.
    """

    def __init__(self, graph, opts, where):
        self.graph, self.opts, self.where = graph, opts, where
        self.full = WeightedLeastSquares(graph, where=where, **opts)
        self.wls, self.active = self.full, np.ones(graph.m, dtype=bool)
        self._done, self.rebuilds = 0, 0

    @property
    def iterations(self):
        """Gauss–Newton steps over every system built."""
        return self._done + self.wls.iterations

    def edge_chi2(self, x):
        return self.full.edge_chi2(x)

    def prior_chi2(self, x):
        return self.full.system._prior_chi2(x)

    def solve(self, x, w, **options):
        want = w != 0
        changed = int(np.count_nonzero(want != self.active))
        if np.any(want & ~self.active) or changed >= max(1.0, REBUILD_FRACTION * w.size):
            self._rebuild(want)
        return self.wls.solve(x, w[self.active], **options)

    def _rebuild(self, want):
        if want.all():
            wls = self.full
        else:
            try:
                wls = WeightedLeastSquares(inlier_graph(self.graph, want), where=self.where,
                                           **self.opts)
            except (GaugeError, GraphError):  # the edges left do not fix every pose: keep all
                want, wls = np.ones(want.size, dtype=bool), self.full
        self._done += self.wls.iterations
        wls.iterations = 0
        self.wls, self.active = wls, want
        self.rebuilds += 1


def _tls_polish(wls, x, robust, c, max_rounds=20):
    """TLS's own fixed point: weights ``[r <= c]``, re-solved until they stop changing.

    Each round minimizes ``Σ min(r², c²)`` with the classification fixed and then re-classifies,
    so the TLS cost never increases and the rounds end (at most ``max_rounds``).  Returns
    ``(poses, weights, rounds)``.
    """
    w = np.ones(robust.size)
    for rounds in range(1, max_rounds + 1):
        r2 = wls.edge_chi2(x)
        w_new = np.where(robust & (r2 > c * c), 0.0, 1.0)  # the TLS weight (Yang et al. 2020)
        if rounds > 1 and np.array_equal(w_new, w):
            return x, w, rounds - 1
        w = w_new
        x, _, _ = wls.solve(x, w)
    return x, w, max_rounds


def gnc(
    graph,
    initial=None,
    *,
    kernel="tls",
    c=INLIER_THRESHOLD,
    robust_edges="closures",
    mu_step=MU_STEP,
    max_iterations=100,
    inner_iterations=1,
    weights_tol=1e-4,
    fixed=None,
    prior=None,
    error="t2v",
    backend="auto",
    verbose=False,
    start="initial",
):
    """Graduated non-convexity (Yang et al. 2020, Algorithm 1) for pose graphs.

    Minimizes ``Σ ρ(r_ij)`` over the robust edges (TLS or Geman–McClure, scale ``c``) plus
    least squares over the others, by a sequence of surrogate kernels ``ρ_μ`` that starts
    convex and ends at ``ρ``:

    1. ``μ_0`` from the largest robust residual (:func:`lagolib.kernels.gnc_initial_mu`) at
       ``initial`` (``start="initial"``, the default) or, as Yang et al. and GTSAM do, at the
       least-squares solution from ``initial`` (``start="least_squares"``);
    2. repeat: weights ``w_ij = w_μ(r_ij)`` in closed form (:func:`lagolib.kernels.gnc_weights`),
       a weighted least-squares solve warm-started at the current poses (at most
       ``inner_iterations`` Gauss–Newton steps: GTSAM runs LM to convergence here), then
       ``μ <- μ / mu_step`` (GM, down to 1) or ``μ <- μ · mu_step`` (TLS);
    3. until GM reaches ``μ = 1`` or the TLS weights are binary (``Σ w (1 - w) < weights_tol``
       over the robust edges); then TLS's own fixed point (weights ``[r <= c]``, re-solved to
       convergence until they stop changing) and a Gauss–Newton polish.

    Yang et al. solve the weighted problems globally (pose graphs: by SE-Sync), and then GNC
    needs no initial guess.  Here each weighted solve is Gauss–Newton, a local method, and the
    start matters: least squares with outliers in it bends the map into a basin the
    continuation does not leave.  On 200-pose Manhattan worlds with 40–60 random wrong
    closures and heading noise 0.05–0.1 rad per step (``tests/test_robust.py``), starting at
    the least-squares solution kept 48–84 % of the right closures (ATE 24–33 times the
    outlier-free optimum's); starting at the odometry's own residuals kept all of them, at the
    outlier-free optimum, 4–5 times faster.  With small heading noise both starts agree.

    Parameters
    ----------
    graph : PoseGraph
    initial : array_like, shape (n, 3), optional
        Default ``graph.poses`` (e.g. the odometry).
    kernel : {"tls", "gm"}
    c : float
        The kernel's scale (whitened residual norm; default ``sqrt(χ²₃(0.999))``).
    robust_edges : {"closures", "all"} or array_like
        :func:`lagolib.gauss_newton.robust_edge_mask`; the others are known inliers.
    mu_step : float
        ``> 1``.
    max_iterations : int
        Outer (μ) iterations at most.
    inner_iterations : int
        Gauss–Newton steps per weighted solve at most (default 1: warm-started at the last
        μ's poses, one step; on a 1000-pose Manhattan world with 50 wrong closures 10 steps
        per μ gave the same classification and ATE to 1e-11 m in twice the time).
    weights_tol : float
        TLS's binary-weights test.
    fixed, prior, error, backend
        As :func:`lagolib.optimize`.
    verbose : bool
    start : {"initial", "least_squares"}
        Where the continuation starts: the residuals at ``initial``, or at the least-squares
        solution from it (Yang et al.'s Algorithm 1, GTSAM's ``GncOptimizer``).

    Returns
    -------
    RobustResult

    Examples
    --------
    >>> import lagolib
    >>> sim = lagolib.simulate.manhattan_world(n_poses=200, rng=0)
    >>> res = gnc(sim.graph)
    >>> res.converged, int((~res.inlier).sum())
    (True, 0)
    """
    t0 = time.perf_counter()
    where = "gnc"
    check_graph(graph, where)
    kind = check_choice(kernel, "kernel", where, ("tls", "gm"))
    c = _check_c(c, where)
    mu_step = check_real(mu_step, "mu_step", where, minimum=1.0, strict=True)
    if mu_step == 1.0:
        raise OptionError(f"{where}: mu_step must be > 1 (GNC would never reach its kernel)")
    max_iterations = check_int(max_iterations, "max_iterations", where, minimum=0)
    inner_iterations = check_int(inner_iterations, "inner_iterations", where, minimum=1)
    weights_tol = check_real(weights_tol, "weights_tol", where, minimum=0.0)
    verbose = check_bool(verbose, "verbose", where)
    start = check_choice(start, "start", where, ("initial", "least_squares"))
    robust = robust_edge_mask(graph, robust_edges, where)
    x = as_graph_poses(graph, initial, "initial", "initial guess")
    wls = _ActiveSet(graph, dict(fixed=fixed, prior=prior, error=error, backend=backend), where)
    w = np.ones(graph.m)
    if start == "least_squares":
        x, _, _ = wls.solve(x, w)  # step 1: least squares, w = 1
    r = np.sqrt(wls.edge_chi2(x))
    r_max = float(r[robust].max()) if robust.any() else 0.0
    mu = gnc_initial_mu(kind, r_max, c)
    mus, outliers, converged, reason = [], [], False, f"reached max_iterations={max_iterations}"
    for _ in range(max_iterations):
        if kind == "tls" and math.isinf(mu):
            converged, reason = True, "converged: every residual is within c (no outliers)"
            break
        w[robust] = gnc_weights(kind, r[robust], mu, c)  # closed-form weight update
        mus.append(mu)
        x, _, _ = wls.solve(x, w, max_iterations=inner_iterations, tol=1e-6)  # variable update
        r = np.sqrt(wls.edge_chi2(x))
        outliers.append(int(np.sum(w[robust] < 0.5)))
        if verbose:
            print(f"gnc {len(mus):3d}  mu {mu:.4g}  outliers {outliers[-1]}")
        if kind == "gm":
            if mu <= 1.0:
                converged, reason = True, "converged: mu reached 1 (the Geman–McClure kernel)"
                break
            mu = max(1.0, mu / mu_step)
        else:
            wr = w[robust]
            if float(np.sum(wr * (1.0 - wr))) < weights_tol:
                converged, reason = True, "converged: the TLS weights are binary"
                break
            mu *= mu_step
    if kind == "tls":
        x, w, _ = _tls_polish(wls, x, robust, c)
    else:
        w[robust] = gnc_weights("gm", r[robust], 1.0, c)
    x, _, _ = wls.solve(x, w)  # polish: the weighted problem to convergence
    return _result(
        graph, x, f"gnc-{kind}", robust, wls.edge_chi2(x), w, c, len(mus),
        wls.iterations, converged, reason, t0, mu=mus, outliers_history=outliers,
        prior_chi2=wls.prior_chi2(x),
    )


def _result(graph, x, method, robust, terms, weights, c, iterations, gn_iterations,
            converged, reason, t0, *, prior_chi2=0.0, inlier=None, **extra):
    """The RobustResult of poses ``x`` with edge terms ``terms`` (shape (m,)); ``inlier``
    defaults to the residual test ``r <= c`` on the ``robust`` edges (PCM passes its own)."""
    if inlier is None:
        inlier = ~robust | (terms <= c * c)
    return RobustResult(
        poses=x,
        graph=graph.with_poses(x),
        method=method,
        inlier=inlier,
        weights=np.asarray(weights, dtype=float),
        chi2=float(terms.sum()) + prior_chi2,
        chi2_inliers=float(terms[inlier].sum()) + prior_chi2,
        iterations=iterations,
        gauss_newton_iterations=gn_iterations,
        converged=converged,
        reason=reason,
        timings={"total": time.perf_counter() - t0},
        **extra,
    )


def solve(graph, initial=None, *, method="gnc-tls", c=INLIER_THRESHOLD,
          robust_edges="closures", fixed=None, prior=None, error="t2v", backend="auto",
          confidence=0.999):
    """Every robust method of lagolib behind one call, with one kind of result.

    Parameters
    ----------
    graph : PoseGraph
    initial : array_like, shape (n, 3), optional
        Default ``graph.poses``.
    method : str
        One of :data:`METHODS`:

        * ``"gnc-tls"``, ``"gnc-gm"`` — :func:`gnc`;
        * ``"huber"``, ``"cauchy"``, ``"gm"``, ``"tls"``, ``"dcs"`` — IRLS with that kernel
          (scale ``c``) inside :func:`lagolib.optimize`, from ``initial``;
        * ``"pcm"`` — pairwise consistency maximization (:func:`lagolib.consistency.pcm`,
          ``confidence``) keeps the largest mutually consistent set of loop closures, then
          Gauss–Newton on what it kept;
        * ``"pcm+gnc-tls"`` — PCM first, then GNC-TLS on the closures PCM kept.
    c : float
        Kernel scale (whitened residual norm), also the inlier test ``r <= c``.
    robust_edges, fixed, prior, error, backend
        As :func:`gnc` (PCM always judges the loop closures).
    confidence : float
        PCM's consistency test (χ²₃ quantile).

    Returns
    -------
    RobustResult

    Examples
    --------
    >>> import lagolib
    >>> sim = lagolib.simulate.manhattan_world(n_poses=200, rng=0)
    >>> bad = lagolib.simulate.add_outliers(sim.graph, 5, rng=0)
    >>> res = solve(bad.graph, method="gnc-tls")
    >>> bool(np.array_equal(~res.inlier, bad.outlier))
    True
    """
    t0 = time.perf_counter()
    where = "robust.solve"
    check_graph(graph, where)
    if not isinstance(method, str):
        raise OptionTypeError(f"{where}: method must be a string, one of {', '.join(METHODS)}")
    method = check_choice(method, "method", where, METHODS)
    c = _check_c(c, where)
    opts = dict(fixed=fixed, prior=prior, error=error, backend=backend)
    if method.startswith("gnc-"):
        return gnc(graph, initial, kernel=method[4:], c=c, robust_edges=robust_edges, **opts)
    if method in KERNELS:
        res = optimize(graph, initial, robust=as_kernel(method, c), robust_edges=robust_edges,
                       **opts)
        mask = robust_edge_mask(graph, robust_edges, where)
        terms = graph_chi2(graph, res.poses, per_edge=True, error=error)
        return _result(graph, res.poses, method, mask, terms, res.weights, c, 1, res.iterations,
                       res.converged, res.reason, t0, prior_chi2=res.chi2 - float(terms.sum()))
    # PCM: the largest set of mutually consistent loop closures (needs the odometry chain)
    t_pcm = time.perf_counter()
    kept = pcm(graph, confidence=confidence)
    seconds_pcm = time.perf_counter() - t_pcm
    keep = np.asarray(kept.inlier, dtype=bool)
    if method == "pcm":
        wls = WeightedLeastSquares(graph, where=where, **opts)
        x = as_graph_poses(graph, initial, "initial", "initial guess")
        x, _, reason = wls.solve(x, keep.astype(float))
        terms = wls.edge_chi2(x)
        res = _result(graph, x, method, graph.loop_closure, terms, keep.astype(float), c, 1,
                      wls.iterations, True, reason, t0, prior_chi2=wls.system._prior_chi2(x),
                      inlier=keep.copy())  # PCM's classification, not the residual test
    else:  # "pcm+gnc-tls": GNC on what PCM kept; PCM's rejections stay rejected
        sub = inlier_graph(graph, keep)
        g = gnc(sub, initial, kernel="tls", c=c, **opts)
        inlier = np.zeros(graph.m, dtype=bool)
        inlier[np.flatnonzero(keep)[g.inlier]] = True
        weights = np.zeros(graph.m)
        weights[np.flatnonzero(keep)] = g.weights
        terms = graph_chi2(graph, g.poses, per_edge=True, error=error)
        res = _result(graph, g.poses, method, graph.loop_closure, terms, weights, c,
                      g.iterations, g.gauss_newton_iterations, g.converged, g.reason, t0,
                      mu=g.mu, outliers_history=g.outliers_history, inlier=inlier,
                      prior_chi2=g.chi2 - float(terms[keep].sum()))  # sub's edges: terms[keep]
    res.timings["pcm"] = seconds_pcm
    return res


class Scores(NamedTuple):
    """Precision and recall of an inlier set over the judged edges (:func:`scores`)."""

    precision: float
    recall: float
    true_inliers: int
    false_inliers: int
    false_outliers: int
    true_outliers: int


def scores(inlier, outlier, judged=None):
    """Precision and recall of the predicted inlier set against the known outliers.

    ``precision = |kept ∩ right| / |kept|``, ``recall = |kept ∩ right| / |right|``, over the
    edges that were judged (default all; pass ``graph.loop_closure`` to leave out the trusted
    odometry, which would inflate both).  An empty kept set has precision 1; no right edges,
    recall 1.

    Parameters
    ----------
    inlier : array_like of bool, shape (m,)
        Predicted: True for an edge kept (e.g. :attr:`RobustResult.inlier`).
    outlier : array_like of bool, shape (m,)
        Truth: True for a wrong edge (e.g. ``Outliers.outlier``).
    judged : array_like of bool, shape (m,), optional

    Returns
    -------
    Scores

    Examples
    --------
    >>> scores([True, True, False, True], [False, True, True, False])
    Scores(precision=0.6666666666666666, recall=1.0, true_inliers=2, false_inliers=1, false_outliers=0, true_outliers=1)
    """  # noqa: E501
    where = "scores"
    pred, out = _mask(inlier, "inlier", where), _mask(outlier, "outlier", where)
    if pred.shape != out.shape:
        raise OptionError(
            f"{where}: inlier and outlier must have the same shape; got {pred.shape} and "
            f"{out.shape}"
        )
    sel = np.ones(pred.shape, bool) if judged is None else _mask(judged, "judged", where)
    if sel.shape != pred.shape:
        raise OptionError(f"{where}: judged must have shape {pred.shape}; got {sel.shape}")
    pred, right = pred[sel], ~out[sel]
    tp, fp = int(np.sum(pred & right)), int(np.sum(pred & ~right))
    fn, tn = int(np.sum(~pred & right)), int(np.sum(~pred & ~right))
    return Scores(tp / (tp + fp) if tp + fp else 1.0, tp / (tp + fn) if tp + fn else 1.0,
                  tp, fp, fn, tn)


def _mask(value, name, where):
    a = np.asarray(value)
    if a.dtype != bool or a.ndim != 1:
        raise OptionTypeError(
            f"{where}: {name} must be a one-dimensional boolean array (one entry per edge); got "
            f"dtype {a.dtype}, shape {a.shape}"
        )
    return a


def inlier_graph(graph, inlier):
    """The graph with only the edges where ``inlier`` (bool, shape (m,)) is True; same poses,
    ids and vertex order."""
    check_graph(graph, "inlier_graph")
    keep = _mask(inlier, "inlier", "inlier_graph")
    if keep.shape != (graph.m,):
        raise OptionError(f"inlier_graph: inlier must have shape ({graph.m},); got {keep.shape}")
    return PoseGraph(graph.poses, graph.edges[keep], graph.measurements[keep],
                     graph.information[keep], ids=graph.ids)


@dataclass
class InlierCertificate:
    """What :func:`certify_inliers` returns — and what it does not claim.

    Attributes
    ----------
    graph : PoseGraph
        The inlier problem (the kept edges) with the certified pipeline's poses.
    result : lagolib.certify.SolveResult
        :func:`lagolib.certify.solve` on it.
    certified : bool
        The chordal relaxation certifies that ``result``'s chordal point is the global
        optimum *of the inlier problem*.
    kept, removed : int
        Edges in the inlier problem, edges left out.
    statement : str
        The claim in words, including what is not covered: whether the removed edges were
        really wrong.  No certificate here speaks to that choice.
    """

    graph: PoseGraph
    result: object
    certified: bool
    kept: int
    removed: int
    statement: str


def certify_inliers(result, **options):
    """Chapter 9's certificate for the inlier problem a robust method leaves behind.

    Removes the edges ``result`` judged wrong and runs :func:`lagolib.certify.solve` (from
    ``result.poses``; ``options`` go to it) on the rest.  A certificate then proves that the
    answer is the global optimum of *that* problem — of the chosen inliers.  It proves nothing
    about the choice: a wrong closure that was kept is part of the certified problem, and a
    right one that was dropped is simply absent.  :attr:`InlierCertificate.statement` says so.

    Parameters
    ----------
    result : RobustResult
    **options
        Passed to :func:`lagolib.certify.solve` (``max_escapes``, ``eta``, ...).

    Returns
    -------
    InlierCertificate
    """
    if not isinstance(result, RobustResult):
        raise OptionTypeError(
            "certify_inliers: result must be a lagolib.robust.RobustResult (from "
            f"lagolib.robust.solve or gnc); got {type(result).__name__}"
        )
    g = inlier_graph(result.graph, result.inlier)
    cert = certified_solve(g, result.poses, **options)
    kept, removed = g.m, result.graph.m - g.m
    verdict = "certified globally optimal" if cert.certified else "NOT certified"
    statement = (
        f"{verdict} for the inlier problem: {kept} edges kept, {removed} removed by "
        f"{result.method} (relative gap {cert.relative_gap:.2g}).  The certificate covers the "
        "optimization over the kept edges only; it says nothing about whether the removed edges "
        "were wrong or the kept ones right."
    )
    return InlierCertificate(g.with_poses(cert.poses), cert, bool(cert.certified), kept, removed,
                             statement)
