"""The front end: from a laser log to a pose graph (lecture notes, "The overall SLAM System").

*"Interplay of front end and back end: graph construction, graph optimization"* (lecture notes,
"The overall SLAM System"); *"every node in the graph corresponds to a robot position and a
laser measurement"* ("Graph-based slam in a Nutshell").  The front end builds the graph the rest
of lagolib optimizes:

1. **keyframes** (:func:`keyframes`): a scan becomes a vertex once odometry says the robot moved
   ``min_translation`` metres or turned ``min_rotation`` radians since the last one;
2. **sequential edges**: each keyframe is matched to the previous one by point-to-line ICP
   (:func:`lagolib.scan_matching.match`) with the odometry increment as a prior
   (:func:`odometry_information`); the edge's information is the match's.  In a corridor
   (degeneracy above ``max_degeneracy``) the scans say nothing along it, and the translation
   along the match's weak direction is the odometry's;
3. **loop closures** (:func:`gate_candidates`, :func:`verify_closure`): old keyframes ``i`` near
   the new keyframe ``j`` *given the uncertainty* — the Mahalanobis distance under the relative
   covariance of chapter 3 (lecture notes, "Relative Uncertainty": *"useful to decide loop
   closure"*) — are matched without a prior, starting from the graph's prediction, and accepted
   only when the match passes explicit rules (:class:`ClosureRules`, :data:`VERDICTS`): it
   converged, enough inliers, a small residual, a well-conditioned match (the degeneracy test:
   corridors), an unambiguous window search, no walls where the old pass saw free space, and
   consistency with the prediction (:func:`lagolib.uncertainty.loop_closure_test`'s χ² test);
4. **re-optimization**: in the incremental front end, Gauss–Newton after each accepted closure,
   so that the next predictions use the corrected trajectory.  The batch variant gates every
   candidate against the chain of sequential edges, optimizes once at the end and prunes the
   closures that do not fit the optimum.

The graph's vertex ids are the scans' indices in the log (0-based, in ``FLASER`` order), so any
result can be compared with the log's reference poses (:attr:`lagolib.scans.LaserLog.reference`).

Examples
--------
>>> from lagolib import frontend, laser_world
>>> log = laser_world.simulate_log(rng=1)
>>> fe = frontend.build_graph(log)
>>> fe.graph.n == len(fe.keyframes), fe.n_accepted >= 5, fe.n_wrong
(True, True, 0)
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.special import gammaincinv

from . import se2
from .checks import check_bool, check_int, check_real
from .errors import OptionError, OptionTypeError
from .gauss_newton import edge_jacobians, optimize
from .graph import PoseGraph, as_graph_poses, chi2, vertex_rows
from .lago import lago
from .linalg import SparseCholesky
from .scan_matching import (
    INFORMATION_SCALE,
    ScanModel,
    correlative_search,
    free_space_conflicts,
    match,
)
from .scans import LaserLog, chain_increments
from .uncertainty import information_matrix, relative_covariances

__all__ = [
    "DEGREE",
    "VERDICTS",
    "keyframes",
    "odometry_information",
    "RelativeGate",
    "ClosureRules",
    "Candidate",
    "FrontEnd",
    "gate_candidates",
    "verify_closure",
    "build_graph",
    "wrong_closures",
]


#: The verdicts a candidate can get, in the order the rules are applied (:func:`verify_closure`;
#: "pruned" only in the batch front end).
VERDICTS = (
    "accepted",
    "not converged",
    "inliers",
    "residual",
    "degenerate",
    "ambiguous",
    "free space",
    "inconsistent",
    "pruned",
)

#: One degree in radians (the defaults below are written in degrees).
DEGREE = math.pi / 180


def _chi2_quantile(confidence, dof):
    """``t`` with ``P(χ²_dof ≤ t) = confidence``."""
    return float(2.0 * gammaincinv(dof / 2.0, confidence))


def keyframes(log, *, min_translation=0.5, min_rotation=20 * DEGREE):
    """Indices of the scans that become vertices: chosen by metres and radians of odometry.

    Scan 0 is a keyframe; scan ``k`` is the next one when the odometry since the last keyframe
    has moved ``>= min_translation`` metres or turned ``>= min_rotation`` radians.

    Parameters
    ----------
    log : LaserLog
    min_translation : float
        Metres (``> 0``).
    min_rotation : float
        Radians (``> 0``).

    Returns
    -------
    ndarray of int, shape (K,)
        Increasing scan indices.
    """
    where = "keyframes"
    _check_log(log, where)
    min_translation = check_real(min_translation, "min_translation", where, minimum=0, strict=True)
    min_rotation = check_real(min_rotation, "min_rotation", where, minimum=0, strict=True)
    odo = log.odometry_poses(start=np.zeros(3))
    chosen = [0]
    last = odo[0]
    for k in range(1, len(odo)):  # sequential by nature: each choice depends on the last
        d = se2.between(last, odo[k])
        if math.hypot(d[0], d[1]) >= min_translation or abs(d[2]) >= min_rotation:
            chosen.append(k)
            last = odo[k]
    return np.array(chosen)


def odometry_information(
    increment, *, translation_sigma=0.1, rotation_sigma=8 * DEGREE, min_translation_sigma=0.02
):
    """Information of an odometry increment ``u`` as a prior (g2o convention, frame of ``u``).

    ``σ_xy = max(translation_sigma · |t_u|, min_translation_sigma)`` on both position axes of the
    increment's own frame and ``σ_θ = rotation_sigma`` per increment: ``Ω = diag(σ_xy⁻², σ_xy⁻²,
    σ_θ⁻²)``.  Isotropic in position, so the frame does not change it.

    Parameters
    ----------
    increment : array_like, shape (3,) or (k, 3)
    translation_sigma : float
        Fraction of the distance travelled.
    rotation_sigma : float
        Radians per increment.
    min_translation_sigma : float
        Metres.

    Returns
    -------
    ndarray, shape (3, 3) or (k, 3, 3)
    """
    where = "odometry_information"
    translation_sigma = check_real(
        translation_sigma, "translation_sigma", where, minimum=0, strict=True
    )
    rotation_sigma = check_real(rotation_sigma, "rotation_sigma", where, minimum=0, strict=True)
    min_translation_sigma = check_real(
        min_translation_sigma, "min_translation_sigma", where, minimum=0, strict=True
    )
    u = np.asarray(increment, dtype=float)
    s = np.maximum(translation_sigma * np.hypot(u[..., 0], u[..., 1]), min_translation_sigma)
    out = np.zeros(u.shape[:-1] + (3, 3))
    out[..., 0, 0] = out[..., 1, 1] = 1.0 / s**2
    out[..., 2, 2] = 1.0 / rotation_sigma**2
    return out


@dataclass(frozen=True)
class ClosureRules:
    """When a loop closure candidate is matched, and when its match is accepted.

    Attributes
    ----------
    confidence : float
        Of both χ² tests: the candidate gate (1 dof, distance along the line of sight) and the
        consistency of the match with the prediction (3 dof).
    overlap : float
        Metres: scans whose poses are closer than this can overlap (the gate asks whether the
        predicted distance could be below it).
    min_travel : float
        Metres of odometry between ``i`` and ``j``: nearer pairs are neighbours, not closures.
    max_candidates : int
        Matched per new keyframe, the most plausible first, until one is accepted.
    spacing : float
        Metres of travel after a keyframe that got a closure before the next search (closures
        at every keyframe of a revisited corridor add little and cost matching).
    min_inliers : float
        Fraction of the new scan's points paired.
    max_rms : float
        Metres: root mean square point-to-line distance of the pairs.
    max_degeneracy : float
        ``λ_max/λ_min`` of the match's position information (a corridor slides).
    max_ambiguity : float
        When the prediction is uncertain, a correlative search (Olson 2009) finds ICP's start;
        the candidate is rejected when a placement ``0.5 m`` away scores this close to the best
        (:attr:`lagolib.scan_matching.Correlation.ambiguity`): repeated structure.
    max_conflicts : float
        Fraction of the new scan's returns that, placed by the match, lie in space an old scan
        saw through (:func:`lagolib.scan_matching.free_space_conflicts`), for the matched scan
        ``i`` and its ``pass_width`` neighbours each side on the old pass (placed by the
        graph): an alias fits one scan but puts walls where the old pass saw none.
    pass_width : int
    search_radius : float
        Metres: only old keyframes this close to the new one's estimate are gated (a cap on the
        cost of the covariances; raise it when the drift between closures can be larger).
    max_gated : int
        At most this many passes of the trajectory near the new keyframe are gated (the nearest
        keyframe of each pass), the nearest first.
    """

    confidence: float = 0.99
    overlap: float = 1.5
    min_travel: float = 5.0
    max_candidates: int = 3
    spacing: float = 1.0
    min_inliers: float = 0.4
    max_rms: float = 0.03
    max_degeneracy: float = 10.0
    max_ambiguity: float = 0.9
    max_conflicts: float = 0.05
    pass_width: int = 3
    search_radius: float = 8.0
    max_gated: int = 8

    def __post_init__(self):
        w = "ClosureRules"
        check_real(self.confidence, "confidence", w, minimum=0.0, maximum=1.0, strict=True)
        if self.confidence >= 1.0:
            raise OptionError(f"{w}: confidence must be below 1; got {self.confidence!r}")
        check_real(self.overlap, "overlap", w, minimum=0.0)
        check_real(self.min_travel, "min_travel", w, minimum=0.0)
        check_int(self.max_candidates, "max_candidates", w, minimum=1)
        check_real(self.spacing, "spacing", w, minimum=0.0)
        check_real(self.min_inliers, "min_inliers", w, minimum=0.0, maximum=1.0)
        check_real(self.max_rms, "max_rms", w, minimum=0.0, strict=True)
        check_real(self.max_degeneracy, "max_degeneracy", w, minimum=1.0)
        check_real(self.max_ambiguity, "max_ambiguity", w, minimum=0.0)
        check_real(self.max_conflicts, "max_conflicts", w, minimum=0.0, maximum=1.0)
        check_int(self.pass_width, "pass_width", w, minimum=0)
        check_real(self.search_radius, "search_radius", w, minimum=0.0)
        check_int(self.max_gated, "max_gated", w, minimum=1)


@dataclass(frozen=True, eq=False)
class Candidate:
    """A loop closure candidate ``i → j`` (scan indices) and what became of it.

    Attributes
    ----------
    i, j : int
        Scan indices (vertex ids); ``i < j``.
    prediction : ndarray, shape (3,)
        ``x_i^-1 x_j`` at the estimate when it was gated.
    gate_d2 : float
        Squared Mahalanobis distance of the predicted distance beyond ``overlap`` (1 dof).
    measurement : ndarray, shape (3,)
        The match's ``z_ij``.
    information : ndarray, shape (3, 3) or None
        Its information (g2o convention): the calibrated scan information; None when ICP did
        not converge.
    consistency_d2 : float
        ``e^T S^-1 e`` of the match against the prediction (3 dof; nan if not matched).
    inlier_fraction, rms, degeneracy : float
    accepted : bool
    reason : str
        ``"accepted"`` or the first rule it failed.
    """

    i: int
    j: int
    prediction: np.ndarray
    gate_d2: float
    measurement: np.ndarray | None = None
    information: np.ndarray | None = None
    consistency_d2: float = math.nan
    inlier_fraction: float = math.nan
    rms: float = math.nan
    degeneracy: float = math.nan
    accepted: bool = False
    reason: str = "not matched"


@dataclass(eq=False)
class FrontEnd:
    """What :func:`build_graph` returns.

    Attributes
    ----------
    graph : PoseGraph
        Vertex ids are scan indices; poses are the front end's estimate (incremental: optimized
        after every accepted closure; batch: the sequential chain).  Sequential edges first,
        then the accepted closures in the order found.
    keyframes : ndarray of int
    candidates : list of Candidate
        Every candidate matched (accepted or not).
    gated : int
        Candidates the gate admitted, before ``max_candidates`` cut them: more than were
        matched (``len(candidates)``).
    timings : dict
        Seconds: ``"read"`` excluded; ``"keyframes"``, ``"sequential"``, ``"closures"``,
        ``"optimization"``, ``"total"``.
    reference : ndarray, shape (K, 3)
        The log's reference poses of the keyframes.
    reference_kind : str
    settings : dict
        The options :func:`build_graph` ran with.
    """

    graph: PoseGraph
    keyframes: np.ndarray
    candidates: list
    gated: int
    timings: dict
    reference: np.ndarray
    reference_kind: str
    settings: dict = field(default_factory=dict)

    @property
    def closures(self):
        """The accepted candidates."""
        return [c for c in self.candidates if c.accepted]

    @property
    def n_accepted(self):
        return len(self.closures)

    @property
    def n_wrong(self):
        """Accepted closures off the reference by > 0.5 m or 5° (:func:`wrong_closures`)."""
        return int(wrong_closures(self).sum())


def wrong_closures(fe, *, translation=0.5, rotation=5 * DEGREE):
    """Which accepted closures disagree with the log's reference relative pose.

    Parameters
    ----------
    fe : FrontEnd
    translation, rotation : float
        Thresholds: metres and radians.

    Returns
    -------
    ndarray of bool, one per accepted closure.
    """
    closures = fe.closures
    if not closures:
        return np.zeros(0, bool)
    row = {int(v): k for k, v in enumerate(fe.keyframes)}
    ref = fe.reference
    i = np.array([row[c.i] for c in closures])
    j = np.array([row[c.j] for c in closures])
    z = np.array([c.measurement for c in closures])
    e = se2.between(se2.between(ref[i], ref[j]), z)
    return (np.hypot(e[:, 0], e[:, 1]) > translation) | (np.abs(e[:, 2]) > rotation)


def _check_log(log, where):
    if not isinstance(log, LaserLog):
        raise OptionTypeError(
            f"{where}: log must be a lagolib.scans.LaserLog; got {type(log).__name__}"
        )


def gate_candidates(graph, j, candidates, rules, *, poses=None, covariances=None):
    """The candidates ``i`` the relative uncertainty says may overlap the scan of ``j``.

    With ``x_j`` fixed, the relative covariance ``Σ_i|j`` (lecture notes, "Relative
    Uncertainty"; :func:`lagolib.uncertainty.relative_covariances`) gives the predicted relative
    pose ``x_i^-1 x_j`` the covariance ``A Σ_i|j A^T`` (``A = ∂e_ij/∂x_i``).  Its position part
    along the line of sight, ``σ²``, turns the predicted distance ``d`` into the gate's
    ``d2 = max(d − overlap, 0)² / σ²``, admitted when below ``χ²₁``'s ``confidence`` quantile.

    Parameters
    ----------
    graph : PoseGraph
        The graph so far (without candidate edges).
    j : int
        Vertex id of the new keyframe.
    candidates : sequence of int
        Vertex ids ``i``.
    rules : ClosureRules
    poses : ndarray, shape (n, 3), optional
    covariances : ndarray, shape (c, 3, 3), optional
        The covariance of each prediction, when the caller has it (:class:`RelativeGate`);
        default: :func:`lagolib.uncertainty.relative_covariances` of ``graph``.

    Returns
    -------
    d2 : ndarray, shape (c,)
    prediction : ndarray, shape (c, 3)
        ``x_i^-1 x_j``.
    cov : ndarray, shape (c, 3, 3)
        Covariance of the prediction (as the error ``e_ij`` of an edge ``i → j``).
    """
    where = "gate_candidates"
    if not isinstance(graph, PoseGraph):
        raise OptionTypeError(f"{where}: graph must be a PoseGraph; got {type(graph).__name__}")
    if not isinstance(rules, ClosureRules):
        raise OptionTypeError(f"{where}: rules must be a ClosureRules; got {type(rules).__name__}")
    x = as_graph_poses(graph, poses)
    (kj,) = vertex_rows(graph, [j], f"{where}: j (the new keyframe)")
    ki = vertex_rows(graph, candidates, f"{where}: candidates")
    if len(ki) == 0:
        z = np.zeros((0, 3))
        return np.zeros(0), z, np.zeros((0, 3, 3))
    if np.any(ki == kj):
        raise OptionError(f"{where}: the candidates include j itself (vertex {graph.ids[kj]})")
    pred = se2.between(x[ki], x[kj])
    if covariances is None:
        cov_i = relative_covariances(
            graph, graph.ids[kj], graph.ids[ki].tolist(), poses=x, method="solves"
        )
        _, A, _ = edge_jacobians(x[ki], np.broadcast_to(x[kj], x[ki].shape), pred)
        cov = A @ cov_i @ np.swapaxes(A, 1, 2)  # Σ_i|j carried into the error e_ij
    else:
        cov = covariances
    return _gate_d2(pred, cov, rules), pred, cov


def _gate_d2(pred, cov, rules):
    """``max(d − overlap, 0)² / σ²`` with ``σ²`` the variance along the line of sight."""
    d = np.hypot(pred[:, 0], pred[:, 1])
    los = pred[:, :2] / np.maximum(d, 1e-12)[:, None]
    var = np.einsum("ci,cij,cj->c", los, cov[:, :2, :2], los)
    return np.maximum(d - rules.overlap, 0.0) ** 2 / np.maximum(var, 1e-300)


class RelativeGate:
    """Covariances of predicted loop closures, one factorization per stretch between closures.

    Between two accepted closures the graph only grows by sequential edges: the keyframes after
    the last refresh ``s`` hang off ``x_s`` as a chain (a tree).  With ``x_s`` fixed, an old pose
    ``x_i`` has the relative covariance ``Σ_i|s`` of the factored graph, the new keyframe ``x_a``
    the chain's propagated covariance (lecture notes, "Uncertainty"; first order, exact on a
    tree)::

        Σ_{k+1|s} = (B⁻¹A) Σ_{k|s} (B⁻¹A)^T + B⁻¹ Ω⁻¹ B⁻ᵀ          (A, B of the edge k → k+1)

    and the two are independent, so the prediction ``e_ia`` has covariance
    ``A Σ_i|s A^T + B Σ_a|s B^T`` — what :func:`lagolib.uncertainty.relative_covariances` with
    ``x_a`` fixed gives (tested equal), at one triangular solve per candidate instead of one
    factorization per keyframe.
    """

    def __init__(self):
        self.s = None

    def reset(self):
        """The graph or the estimate changed (a closure was added): refactor on the next call."""
        self.s = None

    def _refresh(self, graph, x, a):
        graph = graph() if callable(graph) else graph
        H, free = information_matrix(graph, x, fixed=[int(graph.ids[a])])
        self.s, self.factor = a, SparseCholesky(H)
        self.block_of = np.full(graph.n, -1)
        self.block_of[free] = np.arange(free.size)
        self.k, self.sigma = a, np.zeros((3, 3))  # the chain's end and Σ_{k|s}

    def covariances(self, graph, x, a, rows, z_seq, info_seq):
        """Covariances of ``e_ia`` for the rows ``rows`` (keyframe indices < ``a``).

        ``graph`` (a PoseGraph, or a function returning it: it is read only when the gate
        refactors) holds keyframes ``0..a`` at ``x``; ``z_seq[k], info_seq[k]`` is the
        sequential edge ``k → k + 1``.
        """
        rows = np.asarray(rows)
        if self.s is None or rows.max() > self.s or a < self.k:
            self._refresh(graph, x, a)
        while self.k < a:  # carry Σ along the chain to the new keyframe
            k = self.k
            _, A, B = edge_jacobians(x[k], x[k + 1], z_seq[k])
            Bi = np.linalg.inv(B)
            T = -Bi @ A
            self.sigma = T @ self.sigma @ T.T + Bi @ np.linalg.inv(info_seq[k]) @ Bi.T
            self.k = k + 1
        cols = (3 * self.block_of[rows][:, None] + np.arange(3)).ravel()
        E = np.zeros((self.factor.shape[0], cols.size))
        E[cols, np.arange(cols.size)] = 1.0
        X = self.factor.solve(E)[cols]  # columns of H⁻¹ through the candidates' blocks
        q = len(rows)
        cov_i = X.reshape(q, 3, q, 3)[np.arange(q), :, np.arange(q), :]
        pred = se2.between(x[rows], x[a])
        _, A, B = edge_jacobians(x[rows], np.broadcast_to(x[a], x[rows].shape), pred)
        cov = A @ cov_i @ np.swapaxes(A, 1, 2) + B @ self.sigma @ np.swapaxes(B, 1, 2)
        return 0.5 * (cov + np.swapaxes(cov, 1, 2))


def verify_closure(
    model_i,
    points_j,
    prediction,
    cov,
    rules,
    *,
    old_scans=None,
    information_scale=INFORMATION_SCALE,
):
    """Match scan ``j`` to scan ``i`` from the prediction and apply the acceptance rules.

    ICP starts at the prediction, or — when the prediction is too uncertain for ICP's basin
    (σ > 0.1 m or > 2°) — at the best pose of a correlative search over the prediction's
    2.5σ window (:func:`lagolib.scan_matching.correlative_search`).  The match is then judged
    by ``rules``, in this order; the first rule it fails is the verdict:

    ``"not converged"``; ``"inliers"`` (fraction of ``j``'s points paired below
    ``min_inliers``); ``"residual"`` (rms above ``max_rms``); ``"degenerate"`` (a corridor:
    ``Match.degeneracy`` above ``max_degeneracy``); ``"ambiguous"`` (the window search found
    another placement ≥ 0.5 m away scoring within ``max_ambiguity`` of the best);
    ``"free space"`` (with ``old_scans``: the median over the old pass of the fraction of ``j``'s
    returns placed where an old scan saw through, above ``max_conflicts``); ``"inconsistent"``
    (the χ²₃ test of :func:`lagolib.uncertainty.loop_closure_test` against the prediction:
    ``e = t2v(z^-1 ẑ)``, ``S = Σ_pred + Ω_z^-1``); otherwise ``"accepted"``.

    Parameters
    ----------
    model_i : ScanModel
        The old scan ``i``.
    points_j : ndarray, shape (m, 2)
        The new scan ``j``, its own sensor frame.
    prediction : ndarray, shape (3,)
        ``ẑ = x_i^-1 x_j`` from the graph.
    cov : ndarray, shape (3, 3)
        Its covariance (:func:`gate_candidates`).
    rules : ClosureRules
    old_scans : (LaserLog, sequence of (int, ndarray)), optional
        The log and, for scan ``i`` and its neighbours ``n`` on the old pass, ``(scan index of n,
        T_ni)`` with ``T_ni`` the pose of ``i`` in the frame of ``n`` (from the graph; ``T_ii = 0``).
        Without it the free-space rule is not applied.
    information_scale : float
        The calibration of the match's information
        (:data:`lagolib.scan_matching.INFORMATION_SCALE`, measured on INTEL).

    Returns
    -------
    match : lagolib.scan_matching.Match
    d2 : float
        The consistency test's ``e^T S^-1 e``.
    reason : str
    """
    ambiguity = 0.0
    sd = _position_sd(cov)
    start = prediction
    if _outside_basin(cov):  # search a window
        window = (
            min(2.5 * sd + 0.2, 3.0),
            min(2.5 * math.sqrt(cov[2, 2]) + 0.05, math.radians(25)),
        )
        corr = correlative_search(
            model_i,
            points_j,
            prediction,
            window=window,
            resolution=0.2,
            angular_step=math.radians(2),
            max_points=60,
        )
        ambiguity, start = corr.ambiguity, corr.pose
    m = match(model_i, points_j, start, information_scale=information_scale)
    info = m.scan_information
    e = se2.between(m.pose, prediction)
    try:
        S = cov + np.linalg.inv(info)
        d2 = float(e @ np.linalg.solve(S, e))
    except np.linalg.LinAlgError:
        d2 = math.inf
    if not m.converged:
        reason = "not converged"
    elif m.inlier_fraction < rules.min_inliers:
        reason = "inliers"
    elif m.rms > rules.max_rms:
        reason = "residual"
    elif m.degeneracy > rules.max_degeneracy:
        reason = "degenerate"
    elif ambiguity > rules.max_ambiguity:
        reason = "ambiguous"
    elif old_scans is not None and _conflicts(old_scans, points_j, m.pose) > rules.max_conflicts:
        reason = "free space"
    elif d2 > _chi2_quantile(rules.confidence, 3):
        reason = "inconsistent"
    else:
        reason = "accepted"
    return m, d2, reason


def _conflicts(old_scans, points_j, z):
    """The median free-space conflict of scan ``j`` placed by ``z`` against old scans ``n``
    whose poses ``T_ni`` relative to ``i`` the graph knows (the old pass's own geometry); the
    median, because a person walking through one old scan is not an alias."""
    log, near = old_scans
    return np.median(
        [
            free_space_conflicts(
                log.ranges[k], log.angles, log.max_range, points_j, se2.compose(T_ni, z)
            )
            for k, T_ni in near
        ]
    )


def _old_pass(i, a, rules):
    """Keyframe ``i`` and its neighbours on the old pass (``rules.pass_width`` each side)."""
    lo, hi = max(i - rules.pass_width, 0), min(i + rules.pass_width, a - 1)
    return range(lo, hi + 1)


def _position_sd(cov):
    """The largest standard deviation of the position block of ``cov`` (metres)."""
    return math.sqrt(max(float(np.linalg.eigvalsh(cov[:2, :2]).max()), 0.0))


def _outside_basin(cov):
    """Is the prediction too uncertain for ICP alone (σ > 0.1 m or > 2°)?"""
    return _position_sd(cov) > 0.1 or cov[2, 2] > (2 * DEGREE) ** 2


def _nearest_per_pass(x, old, a, rules):
    """Keyframes to gate for keyframe ``a``: within ``search_radius`` of it, the nearest one of
    each pass (a run of consecutive keyframes), at most ``max_gated``, nearest first."""
    dist = np.hypot(x[old, 0] - x[a, 0], x[old, 1] - x[a, 1])
    inside = dist <= rules.search_radius
    old, dist = old[inside], dist[inside]
    if len(old) == 0:
        return old
    run = np.concatenate([[0], np.cumsum(np.diff(old) > 1)])  # pass number of each keyframe
    order = np.lexsort((dist, run))  # by pass, nearest first within a pass
    first = order[np.concatenate([[True], np.diff(run[order]) > 0])]
    return old[first[np.argsort(dist[first], kind="stable")]][: rules.max_gated]


def _scan_points(log, k, max_range):
    p = log.points(k)
    return p[np.hypot(p[:, 0], p[:, 1]) < max_range]


def build_graph(
    log,
    *,
    min_translation=0.5,
    min_rotation=20 * DEGREE,
    translation_sigma=0.1,
    rotation_sigma=8 * DEGREE,
    max_range=20.0,
    rules=None,
    incremental=True,
    information_scale=INFORMATION_SCALE,
    progress=None,
):
    """The front end: keyframes, sequential matches, gated and verified loop closures.

    Parameters
    ----------
    log : LaserLog
    min_translation, min_rotation : float
        Keyframe spacing (:func:`keyframes`).
    translation_sigma, rotation_sigma : float
        The odometry prior (:func:`odometry_information`).
    max_range : float
        Returns farther than this (metres) are not matched (sparse, noisy far walls).
    rules : ClosureRules, optional
    information_scale : float
        Divides the raw ICP information ``J^T J / σ̂²`` of every match
        (:data:`lagolib.scan_matching.INFORMATION_SCALE`: measured on INTEL's real scans; a
        calibration belongs to a sensor and its environment — a simulated scanner with
        independent Gaussian ranges needs far less).
    incremental : bool
        True: closures found while walking the keyframes, Gauss–Newton after each accepted one.
        False (batch): every candidate gated against the sequential chain (no re-optimization
        in between); at the end LAGO and Gauss–Newton, and closures whose ``e^T Ω e`` at the
        optimum exceeds χ²₃'s :data:`PRUNE_CONFIDENCE` quantile are pruned one at a time, the
        worst first (their verdict becomes ``"pruned"``).
    progress : callable, optional
        ``progress(stage, done, total)`` with ``stage`` in ``("sequential", "closures")``.

    Returns
    -------
    FrontEnd
    """
    where = "build_graph"
    _check_log(log, where)
    rules = ClosureRules() if rules is None else rules
    if not isinstance(rules, ClosureRules):
        raise OptionTypeError(f"{where}: rules must be a ClosureRules; got {type(rules).__name__}")
    incremental = check_bool(incremental, "incremental", where)
    information_scale = check_real(
        information_scale, "information_scale", where, minimum=0.0, strict=True
    )
    max_range = check_real(max_range, "max_range", where, minimum=0.0, strict=True)
    odometry_information(
        np.zeros(3), translation_sigma=translation_sigma, rotation_sigma=rotation_sigma
    )  # checks the two sigmas
    t0 = time.perf_counter()
    timings = {}
    kf = keyframes(log, min_translation=min_translation, min_rotation=min_rotation)
    timings["keyframes"] = time.perf_counter() - t0

    # 1. sequential edges: ICP with the odometry prior between consecutive keyframes
    t = time.perf_counter()
    odo = log.odometry_poses(start=np.zeros(3))
    pts = [_scan_points(log, k, max_range) for k in kf]
    for k, p in zip(kf, pts):
        if len(p) < 10:
            raise OptionError(
                f"{where}: scan {k} has {len(p)} returns within {max_range} m; scan matching "
                "needs at least 10 (raise max_range, or drop the scan from the log)"
            )
    models = [ScanModel(p) for p in pts]
    K = len(kf)
    z_seq = np.zeros((K - 1, 3))
    info_seq = np.zeros((K - 1, 3, 3))
    for a in range(1, K):
        u = se2.between(odo[kf[a - 1]], odo[kf[a]])
        omega_u = odometry_information(
            u, translation_sigma=translation_sigma, rotation_sigma=rotation_sigma
        )
        m = match(
            models[a - 1],
            pts[a],
            u,
            prior_information=omega_u,
            information_scale=information_scale,
        )
        z = m.pose
        if m.degeneracy > rules.max_degeneracy:
            # a corridor: along it the scans say nothing (their few far points would decide);
            # the odometry's translation along the weak direction replaces ICP's
            d = m.weak_direction
            z = z + np.append(((u[:2] - z[:2]) @ d) * d, 0.0)
        z_seq[a - 1], info_seq[a - 1] = z, m.information
        if progress is not None:
            progress("sequential", a, K - 1)
    x = chain_increments(log.reference[kf[0]], np.vstack([np.zeros((1, 3)), z_seq]))
    timings["sequential"] = time.perf_counter() - t

    # 2. loop closures
    t = time.perf_counter()
    travel = np.concatenate([[0.0], np.cumsum(np.hypot(z_seq[:, 0], z_seq[:, 1]))])
    seq = [(a - 1, a) for a in range(1, K)]
    closures = []  # (i, a, z, Ω) accepted so far
    chain_x = x.copy()
    candidates, gated = [], 0
    last_closure = -math.inf  # travel at the last keyframe that got a closure
    gate = RelativeGate()
    t_opt = 0.0
    for a in range(1, K):
        if progress is not None:
            progress("closures", a, K - 1)
        old = np.nonzero(travel[a] - travel[:a] >= rules.min_travel)[0]
        if len(old) == 0 or travel[a] - last_closure < rules.spacing:
            continue
        xs = x if incremental else chain_x
        near = _nearest_per_pass(xs, old, a, rules)
        if len(near) == 0:
            continue

        # the graph so far (keyframes 0..a, their sequential edges and, incremental, the
        # closures): built only when the gate refactors
        def graph_so_far(a=a, xs=xs):
            found = closures if incremental else []
            return _graph(xs[: a + 1], seq[:a], z_seq[:a], info_seq[:a], found, kf[: a + 1])

        cov = gate.covariances(graph_so_far, xs[: a + 1], a, near, z_seq, info_seq)
        pred = se2.between(xs[near], xs[a])
        d2 = _gate_d2(pred, cov, rules)  # gate_candidates' test, with the gate's covariances
        ok = d2 <= _chi2_quantile(rules.confidence, 1)
        gated += int(ok.sum())
        order = np.argsort(d2[ok], kind="stable")[: rules.max_candidates]
        for c in np.nonzero(ok)[0][order]:
            i = near[c]
            m, cd2, reason = verify_closure(
                models[i],
                pts[a],
                pred[c],
                cov[c],
                rules,
                old_scans=(log, [(kf[n], se2.between(x[n], x[i])) for n in _old_pass(i, a, rules)]),
                information_scale=information_scale,
            )
            cand = Candidate(
                int(kf[i]),
                int(kf[a]),
                pred[c],
                float(d2[c]),
                m.pose,
                m.scan_information if m.converged else None,
                cd2,
                m.inlier_fraction,
                m.rms,
                m.degeneracy,
                reason == "accepted",
                reason,
            )
            candidates.append(cand)
            if cand.accepted:
                closures.append((i, a, m.pose, m.scan_information, len(candidates) - 1))
                last_closure = travel[a]
                if incremental:  # re-optimize: the next predictions use the corrected poses
                    to = time.perf_counter()
                    res = optimize(_graph(x, seq, z_seq, info_seq, closures, kf), max_iterations=20)
                    x = np.array(res.poses)
                    gate.reset()
                    t_opt += time.perf_counter() - to
                break  # one closure per keyframe: the most plausible candidate that passed
    if not incremental and closures:  # batch: optimize once, then prune what does not fit
        to = time.perf_counter()
        x, closures = _prune(seq, z_seq, info_seq, closures, kf, chain_x, candidates)
        t_opt += time.perf_counter() - to
    timings["closures"] = time.perf_counter() - t - t_opt
    timings["optimization"] = t_opt
    timings["total"] = time.perf_counter() - t0
    graph = _graph(x if incremental or closures else chain_x, seq, z_seq, info_seq, closures, kf)
    settings = dict(
        min_translation=min_translation,
        min_rotation=min_rotation,
        translation_sigma=translation_sigma,
        rotation_sigma=rotation_sigma,
        max_range=max_range,
        rules=rules,
        incremental=incremental,
        information_scale=information_scale,
    )
    return FrontEnd(
        graph, kf, candidates, gated, timings, log.reference[kf], log.reference_kind, settings
    )


#: Batch front end: a closure whose χ² at the optimum exceeds this quantile of χ²₃ is pruned.
PRUNE_CONFIDENCE = 0.999


def _prune(seq, z_seq, info_seq, closures, kf, x0, candidates):
    """The batch front end's a-posteriori check: optimize (LAGO, then Gauss–Newton), and while
    the worst closure's ``e^T Ω e`` at the optimum exceeds χ²₃'s :data:`PRUNE_CONFIDENCE`
    quantile, drop it (its candidate becomes ``"pruned"``) and optimize again."""
    threshold = _chi2_quantile(PRUNE_CONFIDENCE, 3)
    closures = list(closures)
    x = x0
    while closures:
        g = _graph(x0, seq, z_seq, info_seq, closures, kf)
        x = np.array(optimize(g, lago(g).poses, max_iterations=50).poses)
        per_edge = chi2(g, x, per_edge=True)[len(seq) :]
        worst = int(np.argmax(per_edge))
        if per_edge[worst] <= threshold:
            break
        k = closures.pop(worst)[4]
        candidates[k] = replace(candidates[k], accepted=False, reason="pruned")
    return x, closures


def _graph(x, seq, z_seq, info_seq, closures, kf):
    """The PoseGraph of keyframes ``kf`` at ``x``: sequential edges, then the closures."""
    edges = np.array(list(seq) + [(c[0], c[1]) for c in closures]).reshape(-1, 2)
    z = np.concatenate([np.reshape(z_seq, (-1, 3)), np.reshape([c[2] for c in closures], (-1, 3))])
    info = np.concatenate(
        [np.reshape(info_seq, (-1, 3, 3)), np.reshape([c[3] for c in closures], (-1, 3, 3))]
    )
    return PoseGraph(x, edges, z, info, ids=kf)
