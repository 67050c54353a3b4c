"""Accuracy metrics: constraint satisfaction, SE-Sync's objective, trajectory errors.

Three ways to say how good an estimate of the poses is, each as published:

* **Constraint satisfaction** (:func:`constraint_satisfaction`): how well the poses agree with the
  measurements, without ground truth — the mean squared translation ``eta_c`` and the mean squared
  angle ``eta_a`` of the error ``Z_ij^-1 X_i^-1 X_j`` over all constraints.  These are the metrics
  of Kümmerle et al. 2009 [1]_ that Carlone et al. 2011, Table II reports for INTEL.
* **SE-Sync's objective** (:func:`sesync_objective`, :func:`sesync_weights`,
  :func:`sesync_parameters`): the maximum-likelihood cost of Rosen et al. [2]_, with an isotropic
  translational weight ``tau`` and a chordal (Frobenius) rotation term of weight ``kappa``, the
  cost their Table 1 reports for the 2D benchmarks.
* **Trajectory errors against ground truth** (:func:`align`, :func:`absolute_trajectory_error`,
  :func:`relative_pose_error`): the absolute trajectory error after the optimal rigid alignment
  (Horn [3]_, Umeyama [4]_, here in SE(2) without scale) and the relative pose error, as defined for
  the TUM RGB-D benchmark by Sturm et al. [5]_.

Everything is vectorized over edges and poses.  Bad input raises a lagolib error
(:class:`~lagolib.errors.GraphError` or :class:`~lagolib.errors.OptionError`, both
:class:`ValueError`) naming the argument and what to do.

Every metric accepts what the input checks accept — any finite coordinates — and computes in a
scaled way: positions are divided by a power of two near the largest coordinate (exact in binary
floating point) before any square or sum is formed, and errors are summarized relative to the
largest one.  So no intermediate value overflows or underflows: a result is ``inf`` only when it
is itself beyond float64's range (``eta_c`` of errors above 1.3e154, whose square is), never NaN,
and coordinates near 1e155 or 1e-155 give the same digits as coordinates near 1.

References
----------
.. [1] R. Kümmerle, B. Steder, C. Dornhege, M. Ruhnke, G. Grisetti, C. Stachniss, A. Kleiner,
   "On measuring the accuracy of SLAM algorithms", *Autonomous Robots* 27(4):387–407, 2009.
.. [2] D. M. Rosen, L. Carlone, A. S. Bandeira, J. J. Leonard, "SE-Sync: A certifiably correct
   algorithm for synchronization over the special Euclidean group", *Int. J. Robotics Research*
   38(2–3):95–125, 2019; code: github.com/david-m-rosen/SE-Sync (``read_g2o_file``).
.. [3] B. K. P. Horn, "Closed-form solution of absolute orientation using unit quaternions",
   *J. Opt. Soc. Am. A* 4(4):629–642, 1987.
.. [4] S. Umeyama, "Least-squares estimation of transformation parameters between two point
   patterns", *IEEE Trans. PAMI* 13(4):376–380, 1991.
.. [5] J. Sturm, N. Engelhard, F. Endres, W. Burgard, D. Cremers, "A benchmark for the evaluation
   of RGB-D SLAM systems", IROS 2012 (absolute trajectory error and relative pose error).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from . import se2
from .checks import check_bool
from .errors import GraphError, GraphTypeError, OptionError, OptionTypeError
from .graph import PoseGraph, _numeric, as_graph_poses, check_poses, chi2, edge_errors

__all__ = [
    "ConstraintSatisfaction",
    "constraint_satisfaction",
    "sesync_parameters",
    "sesync_weights",
    "sesync_objective",
    "Alignment",
    "TrajectoryError",
    "align",
    "absolute_trajectory_error",
    "relative_pose_error",
    "variance_factor",
]


def _check_graph(graph, where, *, need_edges=False):
    if not isinstance(graph, PoseGraph):
        raise OptionTypeError(
            f"{where}: graph must be a lagolib.PoseGraph; got {type(graph).__name__} (read a "
            "file with lagolib.read or build one with lagolib.PoseGraph)"
        )
    if need_edges and graph.m == 0:
        raise GraphError(f"{where}: the graph has no edges, so there is no constraint to measure")


# ---------------------------------------------------------------------- scaling
def _exponent(*positions):
    """``e`` with ``|x| < 2**e`` for every entry of the arrays ``positions`` (0 when all are 0).

    Dividing by ``2**e`` (:func:`numpy.ldexp`) is exact and brings every coordinate into
    ``(-1, 1)``, so squares, products and sums of a few of them neither overflow nor underflow.
    """
    m = max((float(np.max(np.abs(a), initial=0.0)) for a in positions), default=0.0)
    return math.frexp(m)[1] if m > 0 else 0


def _scaled_poses(poses, e):
    """``poses`` with the positions divided by ``2**e`` (the angles as they are)."""
    out = np.array(poses, dtype=float)
    out[..., :2] = np.ldexp(out[..., :2], -e)
    return out


def _unscale(x, e):
    """``x * 2**e``; ``inf`` (no warning) where the true value is beyond float64's range."""
    with np.errstate(over="ignore"):
        return np.ldexp(x, e)


def _root_mean_square(norms, e=0):
    """``(sqrt(mean(v²)), mean(v²))`` for ``v = norms * 2**e``, without intermediate overflow or
    underflow: the norms are summed relative to the largest one."""
    m = float(np.max(norms, initial=0.0))
    if m == 0.0:
        return 0.0, 0.0
    em = math.frexp(m)[1]
    s = float(np.mean(np.ldexp(norms, -em) ** 2))  # in (0, 1]
    return float(_unscale(math.sqrt(s), em + e)), float(_unscale(s, 2 * (em + e)))


def _scaled_residuals(graph, x):
    """``(e_s, e)``: the t2v errors of ``graph`` at ``x`` with their translations divided by
    ``2**e`` — computed from positions and measured translations divided by ``2**e`` (the error
    is linear in them), so that no intermediate value overflows."""
    z = graph.measurements
    e = _exponent(x[:, :2], z[:, :2])
    xs, zs = _scaled_poses(x, e), _scaled_poses(z, e)
    es = edge_errors(xs[graph.edges[:, 0]], xs[graph.edges[:, 1]], zs, error="t2v")
    return es, e


# ---------------------------------------------------------------------- constraint satisfaction
class ConstraintSatisfaction(NamedTuple):
    """The constraint-satisfaction metrics of :func:`constraint_satisfaction`.

    Attributes
    ----------
    eta_c : float
        Mean squared translational error, m² (the unit of the positions squared).
    eta_a : float
        Mean squared angular error, rad² (angles wrapped to ``(-pi, pi]`` first).
    """

    eta_c: float
    eta_a: float


def constraint_satisfaction(graph, poses=None):
    """How well ``poses`` satisfy the constraints: ``eta_c`` (m²) and ``eta_a`` (rad²).

    The benchmark metrics of Kümmerle et al. 2009 that Carlone et al. 2011, Table II reports for
    INTEL.  For every constraint ``(i, j)`` with measurement ``Z_ij`` take the error transform
    ``E_ij = Z_ij^-1 X_i^-1 X_j`` — the identity when the poses satisfy the constraint — and
    average over **all** ``m`` constraints (odometric edges and loop closures alike)::

        eta_c = (1/m) sum_ij || t(E_ij) ||²          t(E) = translation of E
        eta_a = (1/m) sum_ij wrap(theta(E_ij))²      wrap to (-pi, pi]

    ``t2v(E_ij)`` is the lecture notes' error :func:`lagolib.graph.residuals` with
    ``error="t2v"``, so ``t(E_ij) = R_z^T (R_i^T (t_j - t_i) - t_z)`` is expressed in the frame
    of the measurement.  Its norm is the same in frame ``i``: ``||t(E_ij)|| =
    ||R_i^T (t_j - t_i) - t_z||``, because the rotation ``R_z^T = R(delta_ij)^T`` preserves
    norms — so the metric does not depend on that choice.  Information matrices play no role:
    every constraint counts equally, whatever its uncertainty.

    Parameters
    ----------
    graph : PoseGraph
        At least one edge.
    poses : array_like, shape (n, 3), optional
        The estimate to assess; default ``graph.poses``.

    Returns
    -------
    ConstraintSatisfaction
        ``(eta_c, eta_a)``, a named tuple of floats.

    Raises
    ------
    OptionTypeError
        ``graph`` is not a :class:`~lagolib.PoseGraph`.
    GraphError
        The graph has no edges; ``poses`` has the wrong shape or a non-finite pose (the message
        names the vertex).

    Examples
    --------
    >>> import numpy as np
    >>> from lagolib import simulate
    >>> sim = simulate.loop_world(laps=2, poses_per_lap=8, noiseless=True)
    >>> eta = constraint_satisfaction(sim.graph, sim.truth)
    >>> bool(eta.eta_c < 1e-24 and eta.eta_a < 1e-24)
    True
    >>> moved = sim.truth.copy()
    >>> moved[-1, 2] += 0.1          # turn the last pose by 0.1 rad: 2 of the 23 edges see it
    >>> eta = constraint_satisfaction(sim.graph, moved)
    >>> sim.graph.m, round(eta.eta_a * 23 / 2, 12), bool(eta.eta_c < 1e-24)
    (23, 0.01, True)
    """
    where = "constraint_satisfaction"
    _check_graph(graph, where, need_edges=True)
    x = as_graph_poses(graph, poses, "poses")
    es, scale = _scaled_residuals(graph, x)  # t2v(Z_ij^-1 X_i^-1 X_j) / 2^scale, angle wrapped
    # Kümmerle et al. 2009: eta_c = mean ||t(E)||² (inf only when it is beyond float64's range,
    # errors above 1.3e154), eta_a = mean wrap(theta(E))²
    _, eta_c = _root_mean_square(np.hypot(es[:, 0], es[:, 1]), scale)
    _, eta_a = _root_mean_square(np.abs(es[:, 2]))
    return ConstraintSatisfaction(eta_c, eta_a)


# ---------------------------------------------------------------------- SE-Sync
def sesync_parameters(graph):
    """SE-Sync's per-edge weights ``(kappa, tau)`` from the g2o information matrices.

    As SE-Sync's ``read_g2o_file`` computes them (Rosen et al., IJRR 2019; the same in its
    MATLAB ``load_g2o_data``): for an EDGE_SE2 information matrix ``I`` with translational block
    ``I_tt`` (2×2)::

        tau   = 2 / tr(I_tt^-1)      (the harmonic mean of the eigenvalues of I_tt)
        kappa = I_33

    The cross terms ``I_13``, ``I_23`` are discarded.

    Parameters
    ----------
    graph : PoseGraph

    Returns
    -------
    kappa : ndarray, shape (m,)
    tau : ndarray, shape (m,)

    Examples
    --------
    >>> import numpy as np
    >>> g = PoseGraph(np.zeros((2, 3)), [[0, 1]], [[1.0, 0.0, 0.0]],
    ...               [[[4.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 9.0]]])
    >>> kappa, tau = sesync_parameters(g)
    >>> kappa.tolist(), tau.tolist()                # 2 / (1/4 + 1/1) = 1.6
    ([9.0], [1.6])
    """
    _check_graph(graph, "sesync_parameters")
    info = graph.information
    a, b, d = info[:, 0, 0], info[:, 0, 1], info[:, 1, 1]
    # tr(I_tt^-1) = (a + d) / det(I_tt) for the symmetric 2x2 block [[a, b], [b, d]]
    tau = 2.0 * (a * d - b * b) / (a + d)  # Rosen et al. 2019, tau = 2 / tr(I_tt^-1)
    kappa = info[:, 2, 2].copy()  # Rosen et al. 2019, kappa = I_33
    return kappa, tau


def sesync_weights(graph):
    """A graph whose χ² is SE-Sync's objective to second order: information ``diag(tau, tau, 2 kappa)``.

    With these weights the χ² of :func:`lagolib.graph.chi2` (``error="t2v"``) is::

        chi2 = sum_ij tau ||r_t||² + 2 kappa r_theta²

    where ``r = (r_t, r_theta)`` is the lecture notes' error ``t2v(Z_ij^-1 X_i^-1 X_j)``.  Its
    translation term *equals* SE-Sync's ``tau ||t_j - t_i - R_i t_ij||²`` exactly: ``tau`` is
    isotropic and ``r_t`` is that vector rotated by ``R_i R_z``, a norm-preserving rotation.  Its
    rotation term is the small-residual expansion of the chordal term
    ``kappa ||R_j - R_i R_ij||_F² = 4 kappa (1 - cos r_theta)``, and since
    ``2 r² >= 4 (1 - cos r)`` the χ² is an upper bound of :func:`sesync_objective`, equal to it
    up to ``O(r_theta^4)``.  So ``lagolib.optimize(sesync_weights(g), ...)`` minimizes SE-Sync's
    cost up to that surrogate; the factor 2 on ``kappa`` is the one of SE-Sync's cost (twice the
    negative log-likelihood, no ½; ``shared/reference/published_values.md`` in the project notes).

    Parameters
    ----------
    graph : PoseGraph

    Returns
    -------
    PoseGraph
        Same poses, ids, edges and measurements; information ``diag(tau, tau, 2 kappa)``
        (:func:`sesync_parameters`).

    Raises
    ------
    OptionTypeError
        ``graph`` is not a :class:`~lagolib.PoseGraph`.
    GraphError
        When the new information matrix is unusable (condition number above 1e14: ``tau`` and
        ``2 kappa`` more than 14 orders of magnitude apart).

    Examples
    --------
    >>> import numpy as np
    >>> g = PoseGraph(np.zeros((2, 3)), [[0, 1]], [[1.0, 0.0, 0.0]],
    ...               [[[4.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 9.0]]])
    >>> np.diag(sesync_weights(g).information[0]).tolist()
    [1.6, 1.6, 18.0]
    """
    kappa, tau = sesync_parameters(graph)
    info = np.zeros((graph.m, 3, 3))
    info[:, 0, 0] = info[:, 1, 1] = tau
    info[:, 2, 2] = 2.0 * kappa  # the surrogate's rotation weight: 4 kappa (1 - cos r) ~ 2 kappa r²
    return graph.with_information(info)


def sesync_objective(graph, poses=None, *, per_edge=False):
    """SE-Sync's maximum-likelihood objective, exactly (Rosen et al., IJRR 2019, Problem 1).

    For 2D poses ``(R_i, t_i)`` and measurements ``(R_ij, t_ij)``::

        F = sum_ij kappa_ij ||R_j - R_i R_ij||_F²  +  tau_ij ||t_j - t_i - R_i t_ij||²

    with ``kappa``, ``tau`` from :func:`sesync_parameters`.  There is no factor ½: it is twice the
    negative log-likelihood.  In 2D ``||R_j - R_i R_ij||_F² = ||R(r) - I||_F² = 4 (1 - cos r)``
    with ``r = theta_j - theta_i - theta_ij``; it is evaluated as ``8 sin²(r/2)``, which keeps its
    digits for tiny ``r``.  The translation term uses the t2v error of
    :func:`lagolib.graph.residuals`, whose norm equals ``||t_j - t_i - R_i t_ij||`` (rotations
    preserve norms).

    This is the cost SE-Sync's Table 1 reports.  The χ² of :func:`sesync_weights` is its
    small-residual surrogate ``sum tau ||r_t||² + 2 kappa r²`` and never smaller:
    ``chi2(sesync_weights(g), x) >= sesync_objective(g, x)``, with equality up to ``O(r^4)``.
    At the surrogate's optimum both round to Table 1's printed digits on intel (52.35), csail
    (31.70) and city10000 (638.6); on manhattan the surrogate gives 6432.05 and this function
    6431.39, 0.0102 % lower: the published 6432 agrees with the surrogate (Rosen et al. do not
    say which of the two their table prints).

    Parameters
    ----------
    graph : PoseGraph
    poses : array_like, shape (n, 3), optional
        Where to evaluate; default ``graph.poses``.
    per_edge : bool
        Return the ``(m,)`` vector of edge terms instead of their sum.

    Returns
    -------
    float, or ndarray of shape (m,) when ``per_edge``

    Raises
    ------
    OptionTypeError
        ``graph`` is not a PoseGraph, or ``per_edge`` is not a bool.
    GraphError
        ``poses`` has the wrong shape or a non-finite pose (the message names the vertex).

    Examples
    --------
    >>> import numpy as np
    >>> g = PoseGraph(np.zeros((2, 3)), [[0, 1]], [[1.0, 0.0, 0.0]],
    ...               [[[4.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 9.0]]])
    >>> x = [[0.0, 0.0, 0.0], [1.0, 0.5, np.pi / 2]]   # 0.5 m off, a quarter turn off
    >>> round(sesync_objective(g, x), 12)              # 1.6 * 0.25 + 9 * 4 * (1 - cos(pi/2))
    36.4
    """
    where = "sesync_objective"
    _check_graph(graph, where)
    per_edge = check_bool(per_edge, "per_edge", where)
    x = as_graph_poses(graph, poses, "poses")
    kappa, tau = sesync_parameters(graph)
    rs, scale = _scaled_residuals(graph, x)  # translations divided by 2^scale
    chordal = 8.0 * np.sin(0.5 * rs[:, 2]) ** 2  # ||R_j - R_i R_ij||_F² = 4 (1 - cos r)
    # Rosen et al. 2019, Problem 1: kappa ||R_j - R_i R_ij||_F² + tau ||t_j - t_i - R_i t_ij||²,
    # the translation term as (sqrt(tau) ||t||)² scaled back: inf only when it is beyond range
    translation = _unscale((np.sqrt(tau) * np.hypot(rs[:, 0], rs[:, 1])) ** 2, 2 * scale)
    terms = kappa * chordal + translation
    if per_edge:
        return terms
    with np.errstate(over="ignore"):
        return float(terms.sum())


# ---------------------------------------------------------------------- trajectories
@dataclass(frozen=True)
class Alignment:
    """The rigid SE(2) transform of :func:`align`: ``q ≈ R(angle) p + translation``.

    Attributes
    ----------
    angle : float
        Rotation, rad, in ``(-pi, pi]``.
    translation : ndarray, shape (2,)
    poses : ndarray, shape (n, 3)
        The aligned poses: positions ``R(angle) p + translation``, headings ``wrap(theta + angle)``.
    """

    angle: float
    translation: np.ndarray
    poses: np.ndarray

    @property
    def transform(self):
        """ndarray, shape (3,): the transform as a pose ``(tx, ty, angle)``; ``aligned = T ⊕ p``."""
        return np.array([self.translation[0], self.translation[1], self.angle])


@dataclass(frozen=True)
class TrajectoryError:
    """Translation and rotation errors of a trajectory against ground truth.

    Returned by :func:`absolute_trajectory_error` (one error per pose) and
    :func:`relative_pose_error` (one error per pair of poses).

    Attributes
    ----------
    translation_rmse, translation_mean, translation_max : float
        Root mean square, mean and maximum of ``translation`` (units of the positions).
    rotation_rmse, rotation_mean, rotation_max : float
        Root mean square, mean and maximum of ``|rotation|`` (rad).
    translation : ndarray, shape (k,)
        Per pose (or pair): the length of the translational error.
    rotation : ndarray, shape (k,)
        Per pose (or pair): the signed angular error, wrapped to ``(-pi, pi]``.
    pairs : ndarray of int, shape (k, 2), or None
        The row pairs ``(i, j)`` of a relative pose error; None for the absolute error.
    alignment : Alignment or None
        The alignment applied before an absolute error (None without it, and for the relative
        error, which needs none).
    """

    translation_rmse: float
    translation_mean: float
    translation_max: float
    rotation_rmse: float
    rotation_mean: float
    rotation_max: float
    translation: np.ndarray
    rotation: np.ndarray
    pairs: np.ndarray | None = None
    alignment: Alignment | None = None


def _readonly(a):
    a = np.array(a, dtype=a.dtype, copy=True)
    a.setflags(write=False)
    return a


def _summary(dt, dtheta, pairs=None, alignment=None, scale=0):
    """:class:`TrajectoryError` of translation vectors ``dt * 2**scale`` (k, 2) and wrapped
    angles (k,); no intermediate value overflows (:func:`_root_mean_square`)."""
    trans_s = np.hypot(dt[:, 0], dt[:, 1])
    trans = _unscale(trans_s, scale)
    rot = np.abs(dtheta)
    return TrajectoryError(
        translation_rmse=_root_mean_square(trans_s, scale)[0],
        translation_mean=float(_unscale(np.mean(trans_s), scale)),
        translation_max=float(np.max(trans)),
        rotation_rmse=_root_mean_square(rot)[0],
        rotation_mean=float(np.mean(rot)),
        rotation_max=float(np.max(rot)),
        translation=_readonly(trans),
        rotation=_readonly(dtheta),
        pairs=None if pairs is None else _readonly(pairs),
        alignment=alignment,
    )


def _trajectory(value, name, where):
    """``value`` as a finite float array of shape (n, 3), n >= 1, or a GraphError naming it."""
    try:
        a = _numeric(value, f"{where}: {name}", float)
    except GraphTypeError:
        raise
    except GraphError as exc:
        raise GraphError(f"{exc}; pass an (n, 3) array of poses (x, y, theta)") from None
    if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] == 0:
        raise GraphError(
            f"{where}: {name} must have shape (n, 3) with n >= 1, one row (x, y, theta) per "
            f"pose; got shape {a.shape}"
        )
    check_poses(a, None, f"{where}: {name}")
    return a


def _same_length(poses, other, name, where):
    if poses.shape[0] != other.shape[0]:
        raise GraphError(
            f"{where}: poses has {poses.shape[0]} rows but {name} has {other.shape[0]}; pass "
            "the estimate and the ground truth of the same vertices in the same row order "
            "(match them by vertex id first)"
        )


def _align(p, q):
    """Horn/Umeyama in SE(2): ``angle, translation`` minimizing ``sum ||R p_k + t - q_k||²``."""
    pc, qc = p.mean(axis=0), q.mean(axis=0)
    a, b = p - pc, q - qc
    # the optimal rotation maximizes sum b_k . R a_k = cos(phi) S_cos + sin(phi) S_sin
    s_cos = np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1])
    s_sin = np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    angle = float(np.arctan2(s_sin, s_cos))  # Horn 1987 / Umeyama 1991 in 2D, no scale
    c, s = np.cos(angle), np.sin(angle)
    translation = qc - np.array([c * pc[0] - s * pc[1], s * pc[0] + c * pc[1]])  # t = q̄ - R p̄
    return angle, translation


def align(poses, reference):
    """The rigid motion that best maps the positions of ``poses`` onto ``reference``.

    Minimizes ``sum_k ||R(phi) p_k + t - q_k||²`` over the rotation ``phi`` and translation ``t``
    (no scale), with ``p_k`` the positions of ``poses`` and ``q_k`` those of ``reference``:
    the closed form of Horn 1987 and Umeyama 1991, in the plane.  With centred points
    ``a_k = p_k - p̄`` and ``b_k = q_k - q̄``::

        phi = atan2( sum a_k × b_k , sum a_k · b_k )      t = q̄ - R(phi) p̄

    Only positions determine the motion (as for the TUM benchmark's ATE); the headings of the
    aligned poses are turned by ``phi`` too.  When all positions coincide the rotation is
    undetermined and ``phi = 0``.

    Parameters
    ----------
    poses : array_like, shape (n, 3)
        The trajectory to move (e.g. an estimate).
    reference : array_like, shape (n, 3)
        Where it should be (e.g. the ground truth), row ``k`` the same pose as in ``poses``.

    Returns
    -------
    Alignment
        ``angle``, ``translation`` and the aligned ``poses``.

    Raises
    ------
    GraphError
        Wrong shapes, non-finite values or different lengths (the message names the argument).

    Examples
    --------
    >>> import numpy as np
    >>> q = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 1.5]])
    >>> p = se2.compose([2.0, -1.0, 0.3], q)          # the same poses, moved rigidly
    >>> al = align(p, q)
    >>> round(al.angle, 12), bool(np.allclose(al.poses, q, atol=1e-12))
    (-0.3, True)
    """
    where = "align"
    p = _trajectory(poses, "poses", where)
    q = _trajectory(reference, "reference", where)
    _same_length(p, q, "reference", where)
    alignment, _, _ = _aligned(p, q)
    return alignment


def _aligned(p, q):
    """``(Alignment, aligned poses scaled, e)``: :func:`align` of ``p`` onto ``q``, computed on
    positions divided by ``2**e`` so that no sum of products overflows."""
    e = _exponent(p[:, :2], q[:, :2])
    ps, qs = _scaled_poses(p, e), _scaled_poses(q, e)
    angle, ts = _align(ps[:, :2], qs[:, :2])
    out_s = se2.compose([ts[0], ts[1], angle], ps)  # R p + t, wrap(theta + phi)
    out = out_s.copy()
    out[:, :2] = _unscale(out_s[:, :2], e)
    return Alignment(angle, _readonly(_unscale(ts, e)), _readonly(out)), out_s, e


def absolute_trajectory_error(poses, truth, *, align=True):
    """Absolute trajectory error (ATE) of ``poses`` against ``truth``, after the best alignment.

    Sturm et al. 2012: align the estimate to the ground truth by the rigid motion of least
    squares (:func:`align`; Horn 1987, Umeyama 1991), then take per pose the translation error
    ``||p'_k - q_k||`` and — an addition to the TUM metric, which is translational only — the
    rotation error ``wrap(theta'_k - theta_k)``.  The ATE is usually quoted as
    ``translation_rmse``.

    Parameters
    ----------
    poses : array_like, shape (n, 3)
        The estimate.
    truth : array_like, shape (n, 3)
        Ground truth, row ``k`` the same vertex as in ``poses``.
    align : bool
        Align first (default).  Without it, the errors are in the frame the poses are given in
        (e.g. both anchored at the same first pose).

    Returns
    -------
    TrajectoryError
        Per-pose ``translation`` and ``rotation``, their RMSE, mean and maximum, and the
        ``alignment`` used.

    Raises
    ------
    GraphError
        Wrong shapes, non-finite values or different lengths (the message names the argument).
    OptionTypeError
        ``align`` is not a bool.

    Examples
    --------
    >>> import numpy as np
    >>> truth = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    >>> est = truth + [[0.0, 0.1, 0.0], [0.0, -0.2, 0.0], [0.0, 0.1, 0.0]]
    >>> ate = absolute_trajectory_error(est, truth)
    >>> round(ate.translation_rmse, 12), ate.translation.round(12).tolist()
    (0.141421356237, [0.1, 0.2, 0.1])
    """
    where = "absolute_trajectory_error"
    do_align = check_bool(align, "align", where)
    p = _trajectory(poses, "poses", where)
    q = _trajectory(truth, "truth", where)
    _same_length(p, q, "truth", where)
    alignment = None
    if do_align:
        alignment, ps, e = _aligned(p, q)
    else:
        e = _exponent(p[:, :2], q[:, :2])
        ps = _scaled_poses(p, e)
    qs = _scaled_poses(q, e)
    # Sturm et al. 2012, ATE: per pose, the error of the aligned estimate against the truth
    dtheta = se2.wrap_angle(ps[:, 2] - qs[:, 2])
    return _summary(ps[:, :2] - qs[:, :2], dtheta, None, alignment, e)


def _pairs(pairs, n, where):
    if pairs is None:
        if n < 2:
            raise GraphError(
                f"{where}: the default pairs (k, k+1) need at least 2 poses; got {n}; pass "
                "longer trajectories"
            )
        return np.column_stack([np.arange(n - 1), np.arange(1, n)])
    try:
        a = np.asarray(pairs)
    except ValueError:  # ragged rows
        a = np.asarray(pairs, dtype=object)
    if a.dtype.kind == "f" and a.size and np.all(np.isfinite(a)) and np.all(a == np.round(a)):
        if np.any(np.abs(a) > 2.0**62):  # outside int64: out of range whatever n is
            raise OptionError(
                f"{where}: pairs holds {a.flat[np.argmax(np.abs(a))]:g}, not a row index of "
                f"trajectories with {n} poses (valid 0..{n - 1})"
            )
        a = a.astype(np.int64)
    if a.dtype.kind not in "iu" or a.ndim != 2 or a.shape[1] != 2 or a.shape[0] == 0:
        raise OptionError(
            f"{where}: pairs must be an (m, 2) array of integer row indices with m >= 1 (e.g. "
            f"graph.edges); got shape {a.shape}, dtype {a.dtype}"
        )
    out = np.flatnonzero(np.any((a < 0) | (a >= n), axis=1))
    if out.size:
        k = int(out[0])
        raise OptionError(
            f"{where}: pairs row {k} is {a[k].tolist()} but the trajectories have {n} poses "
            f"(valid row indices 0..{n - 1})"
        )
    return a.astype(np.int64)


def relative_pose_error(poses, truth, *, pairs=None):
    """Relative pose error (RPE) of ``poses`` against ``truth`` over pairs of poses.

    Sturm et al. 2012: for each pair ``(i, j)`` compare the estimated motion from ``i`` to ``j``
    with the true one::

        E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)

    and report ``||t(E_ij)||`` (which equals ``||t(P_i^-1 P_j) - t(Q_i^-1 Q_j)||``) and
    ``wrap(theta(E_ij))``.  It needs no alignment: it is unchanged when either trajectory is
    moved rigidly as a whole.

    Parameters
    ----------
    poses : array_like, shape (n, 3)
        The estimate.
    truth : array_like, shape (n, 3)
        Ground truth, row ``k`` the same vertex as in ``poses``.
    pairs : array_like of int, shape (m, 2), optional
        Row index pairs ``(i, j)``; default consecutive rows ``(k, k+1)`` (the TUM benchmark's
        per-frame drift).  ``graph.edges`` gives the error of every measured relative pose.

    Returns
    -------
    TrajectoryError
        Per-pair ``translation`` and ``rotation``, their RMSE, mean and maximum, and ``pairs``.

    Raises
    ------
    GraphError
        Wrong shapes, non-finite values or different lengths (the message names the argument).
    OptionError
        ``pairs`` is not an (m, 2) array of row indices in range.

    Examples
    --------
    >>> import numpy as np
    >>> truth = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    >>> est = np.array([[0.0, 0.0, 0.0], [1.1, 0.0, 0.0], [2.1, 0.0, 0.0]])
    >>> relative_pose_error(est, truth).translation.round(12).tolist()
    [0.1, 0.0]
    """
    where = "relative_pose_error"
    p = _trajectory(poses, "poses", where)
    q = _trajectory(truth, "truth", where)
    _same_length(p, q, "truth", where)
    ij = _pairs(pairs, p.shape[0], where)
    scale = _exponent(p[:, :2], q[:, :2])  # positions / 2^scale: no difference overflows
    p, q = _scaled_poses(p, scale), _scaled_poses(q, scale)
    rel_p = se2.between(p[ij[:, 0]], p[ij[:, 1]])  # P_i^-1 P_j
    rel_q = se2.between(q[ij[:, 0]], q[ij[:, 1]])  # Q_i^-1 Q_j
    e = se2.between(rel_q, rel_p)  # Sturm et al. 2012, RPE: (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)
    return _summary(e[:, :2], e[:, 2], ij, None, scale)


def variance_factor(graph, poses=None, *, error="t2v"):
    """The a-posteriori variance factor ``σ̂₀² = χ² / r``: how well the information matrices
    describe the residuals at a least-squares optimum.

    ``r = 3 m - 3 (n - 1)`` is the redundancy (equations minus unknowns, the gauge removed).
    When every information matrix is right, ``χ²`` at the optimum is χ²-distributed with ``r``
    degrees of freedom and ``σ̂₀² ≈ 1``; ``σ̂₀² = 0.02`` says the matrices claim 7 times too
    large a standard deviation.  ``graph.with_information(graph.information / σ̂₀²)`` is then
    calibrated — what a threshold in σ units (a robust kernel's scale, a χ² gate) assumes.

    Parameters
    ----------
    graph : PoseGraph
    poses : array_like, shape (n, 3), optional
        A least-squares optimum of ``graph`` (default ``graph.poses``).
    error : {"t2v", "log"}

    Returns
    -------
    float

    Raises
    ------
    GraphError
        When the graph has no redundancy (``3 m <= 3 (n - 1)``: a tree or less).

    Examples
    --------
    >>> import lagolib
    >>> sim = lagolib.simulate.manhattan_world(n_poses=200, rng=0)
    >>> round(variance_factor(sim.graph, lagolib.optimize(sim.graph).poses), 2)
    1.08
    """
    where = "variance_factor"
    _check_graph(graph, where, need_edges=True)
    redundancy = 3 * graph.m - 3 * (graph.n - 1)
    if redundancy <= 0:
        raise GraphError(
            f"{where}: the graph has no redundancy ({graph.m} edges for {graph.n} poses: 3m - "
            "3(n-1) <= 0), so its residuals say nothing about its information matrices"
        )
    return float(chi2(graph, poses, error=error)) / redundancy  # sigma0^2 = chi2 / r

