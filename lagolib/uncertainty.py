"""Uncertainty of the estimate: marginal and relative covariances from the sparse ``H``.

Lecture notes, "Uncertainty": ``H`` is the information matrix of the poses given the
linearization point, and inverting it gives their (dense) covariance matrix, whose diagonal
blocks are the uncertainties of the individual poses.  Here the inverse is never formed: ``H`` is
factored once and the entries of ``H^-1`` on the pattern of the factor — every pose's 3x3 block
among them — follow by selected inversion (:func:`lagolib.linalg.selected_inverse`, Takahashi's
recurrences), in about the time of the factorization.  ``method="solves"`` keeps the direct
reading of the notes: solve for the columns of ``H^-1`` through the wanted blocks.

"Relative Uncertainty": the covariance of ``x_j`` relative to ``x_i`` is block ``(j, j)`` of the
inverse of ``H`` with the rows and columns of ``x_i`` deleted — ``x_i`` fixed.  It is what a
front end needs to decide whether a candidate loop closure is plausible
(:func:`loop_closure_test`).

Covariances are of the additive parametrization ``(x, y, theta)`` in the world frame — the one
:func:`lagolib.optimize` updates.  ``frame="local"`` rotates them into each pose's own frame,
``G^-1 Sigma G^-T`` with ``G = diag(R(theta), 1)``: the tangent-space convention of GTSAM's
``Marginals``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.special import gammaincinv

from . import se2
from .checks import check_choice, check_int, check_real
from .errors import ConditioningWarning, GraphError, GraphTypeError, OptionTypeError
from .gauss_newton import (
    LinearSystem,
    _check_finite_system,
    edge_jacobians,
    resolve_gauge,
)
from .graph import (
    ERRORS,
    PoseGraph,
    _numeric,
    as_graph_poses,
    describe_bad_information,
    first_bad_information,
    vertex_rows,
)
from .linalg import BACKENDS, SparseCholesky, selected_inverse
from .plotting import covariance_ellipse, plot_covariance_ellipses

__all__ = [
    "information_matrix",
    "marginal_covariances",
    "relative_covariances",
    "loop_closure_test",
    "GateResult",
    "covariance_ellipse",
    "plot_covariance_ellipses",
]


FRAMES = ("global", "local")
METHODS = ("takahashi", "solves")


def _check_graph(graph, where):
    if not isinstance(graph, PoseGraph):
        raise OptionTypeError(f"{where}: graph must be a PoseGraph; got {type(graph).__name__}")


def _one_vertex(graph, v, what):
    """Row index of the single vertex id ``v``; a list or an array of ids is a GraphError."""
    if isinstance(v, np.ndarray) and v.ndim == 0:
        v = v.item()
    if np.ndim(v) != 0:
        raise GraphError(f"{what}: one vertex id (an integer) is needed; got {v!r}")
    (k,) = vertex_rows(graph, [v], what)
    return k


def information_matrix(graph, poses=None, *, fixed=None, prior=None, error="t2v"):
    """``H`` of the free poses at ``poses`` (lecture notes, "Uncertainty").

    Parameters
    ----------
    graph : PoseGraph
    poses : array_like, shape (n, 3), optional
        Linearization point, default ``graph.poses``.
    fixed, prior
        The gauge, as in :func:`lagolib.optimize` (default: the smallest vertex id fixed).
    error : {"t2v", "log"}

    Returns
    -------
    H : scipy.sparse.csr_matrix, shape (3k, 3k)
    free : ndarray of int, shape (k,)
        Row index (into ``graph.poses``) of the pose of each 3x3 block of ``H``.
    """
    _check_graph(graph, "information_matrix")
    error = check_choice(error, "error", "information_matrix", ERRORS)
    x = as_graph_poses(graph, poses)
    fixed, priors = resolve_gauge(graph, fixed, prior)
    system = LinearSystem(graph, fixed=fixed, prior=priors, error=error)
    H, _, _ = system.assemble(x)
    if not np.all(np.isfinite(H.data)):
        _check_finite_system(system, x, H, np.zeros(0), 0.0)
    return H, system.free


def _to_local(cov, theta):
    c, s = np.cos(theta), np.sin(theta)
    Ginv = np.zeros(theta.shape + (3, 3))
    Ginv[..., 0, 0], Ginv[..., 0, 1], Ginv[..., 1, 0], Ginv[..., 1, 1] = c, s, -s, c
    Ginv[..., 2, 2] = 1.0
    return Ginv @ cov @ np.swapaxes(Ginv, -1, -2)


def marginal_covariances(
    graph,
    vertices=None,
    *,
    poses=None,
    fixed=None,
    prior=None,
    error="t2v",
    frame="global",
    method="takahashi",
    backend="auto",
    batch=64,
):
    """Marginal covariance ``(H^-1)_{kk}`` of selected poses, without a dense inverse.

    ``method="takahashi"`` (default): one ``L D L^T`` factorization and the selected inverse on
    its pattern (:func:`lagolib.linalg.selected_inverse`) — all poses' blocks in about the time
    of a second factorization, memory ``O(nnz(L))``.  ``method="solves"``: for ``batch`` poses
    at a time the ``3 batch`` columns of ``H^-1`` through their blocks are solved for and the
    3x3 diagonal blocks kept — ``O(N)`` per pose, the readable reference (tested equal).

    Parameters
    ----------
    graph : PoseGraph
    vertices : sequence of int, optional
        Vertex ids; default all.
    poses : array_like, shape (n, 3), optional
        Linearization point (usually the optimum), default ``graph.poses``.
    fixed, prior
        The gauge, as in :func:`lagolib.optimize`.  Fixed poses get zero covariance.
    error : {"t2v", "log"}
    frame : {"global", "local"}
        World-frame ``(x, y, theta)`` covariance, or rotated into each pose's frame (GTSAM's
        ``Marginals`` convention).
    method : {"takahashi", "solves"}
    backend : {"auto", "qdldl", "pardiso", "cholmod", "scipy"}
        The factorization of ``method="solves"`` (selected inversion reads qdldl's factor).
    batch : int
        Poses per block of right-hand sides (``method="solves"``).

    Returns
    -------
    ndarray, shape (k, 3, 3)

    Examples
    --------
    >>> import lagolib
    >>> from lagolib.uncertainty import marginal_covariances
    >>> g = lagolib.datasets.example("square_loop").graph
    >>> cov = marginal_covariances(g, [0, 40, 80])
    >>> float(cov[0].max()), bool(cov[2, 0, 0] > cov[1, 0, 0] > 0)
    (0.0, True)
    """
    where = "marginal_covariances"
    _check_graph(graph, where)
    frame = check_choice(frame, "frame", where, FRAMES)
    method = check_choice(method, "method", where, METHODS)
    backend = check_choice(backend, "backend", where, ("auto",) + BACKENDS)
    batch = check_int(batch, "batch", where, minimum=1)
    x = as_graph_poses(graph, poses)
    idx = (
        np.arange(graph.n)
        if vertices is None
        else vertex_rows(graph, vertices, "marginal_covariances: vertices")
    )
    H, free = information_matrix(graph, x, fixed=fixed, prior=prior, error=error)
    block_of = np.full(graph.n, -1, dtype=np.int64)
    block_of[free] = np.arange(free.size)
    out = np.zeros((idx.size, 3, 3))
    wanted = np.flatnonzero(block_of[idx] >= 0)
    if wanted.size and method == "takahashi":
        rows = 3 * block_of[idx[wanted]][:, None] + np.arange(3)  # (q, 3)
        blocks = selected_inverse(H).blocks(rows)
        out[wanted] = 0.5 * (blocks + np.swapaxes(blocks, 1, 2))
    elif wanted.size:
        factor = SparseCholesky(H, backend)
        comp = np.arange(3)
        for start in range(0, wanted.size, int(batch)):
            sel = wanted[start : start + int(batch)]
            rows = (3 * block_of[idx[sel]][:, None] + comp).ravel()  # (3q,)
            E = np.zeros((H.shape[0], rows.size))
            E[rows, np.arange(rows.size)] = 1.0
            X = factor.solve(E)  # columns of H^-1
            q = sel.size
            blocks = X[rows].reshape(q, 3, q, 3)[np.arange(q), :, np.arange(q), :]
            out[sel] = 0.5 * (blocks + np.swapaxes(blocks, 1, 2))
    if wanted.size:
        rows = 3 * block_of[idx[wanted]][:, None] + np.arange(3)
        _warn_conditioning(out[wanted][:, [0, 1, 2], [0, 1, 2]], H.diagonal()[rows], where)
    if frame == "local":
        out = _to_local(out, x[idx, 2])
    return out


#: :func:`marginal_covariances` warns when float64 leaves them fewer than this many digits.
COVARIANCE_DIGITS = 6


def _warn_conditioning(var, h, where):
    """ConditioningWarning when ``eps max(Σ_kk H_kk)`` — ``eps`` times a lower bound on the
    condition number of ``H`` — exceeds ``10^-COVARIANCE_DIGITS``: the covariances computed from
    ``H`` are then accurate to about that, relative (an odometry chain of 2 x 10^4 poses: 2e-3,
    measured against exact compounding; every backend and method alike)."""
    kappa = float(np.max(var * h, initial=0.0))
    accuracy = np.finfo(float).eps * kappa
    if accuracy > 10.0**-COVARIANCE_DIGITS:
        warnings.warn(
            f"{where}: H's condition number is at least {kappa:.2g}, so the covariances are "
            f"accurate to about {accuracy:.1g} relative in float64 (a long chain without loop "
            "closures does this: its far poses' covariances grow as n^3)",
            ConditioningWarning,
            stacklevel=3,
        )


def relative_covariances(
    graph, i, vertices=None, *, poses=None, error="t2v", frame="global", method="takahashi"
):
    """Covariance of poses relative to pose ``i`` (lecture notes, "Relative Uncertainty").

    Construct the full ``H``, delete the rows and columns of ``x_i``, and take block ``(j, j)`` of
    the inverse: the covariance of ``x_j`` when ``x_i`` is known exactly.

    Parameters
    ----------
    graph : PoseGraph
    i : int
        Vertex id of the reference pose.
    vertices : sequence of int, optional
        Vertex ids ``j``; default all (``i`` itself gets zeros).
    poses, error, frame, method
        As in :func:`marginal_covariances`.

    Returns
    -------
    ndarray, shape (k, 3, 3)
    """
    _check_graph(graph, "relative_covariances")
    i = int(graph.ids[_one_vertex(graph, i, "relative_covariances: i (the reference pose)")])
    if vertices is not None:
        vertex_rows(graph, vertices, "relative_covariances: vertices")
    return marginal_covariances(
        graph,
        vertices,
        poses=poses,
        fixed=[i],
        prior=None,
        error=error,
        frame=frame,
        method=method,
    )


@dataclass(frozen=True)
class GateResult:
    """Outcome of :func:`loop_closure_test`.

    Attributes
    ----------
    d2 : float
        Squared Mahalanobis distance ``e^T S^-1 e`` of the candidate.
    threshold : float
        ``chi2.ppf(confidence, 3)``.
    accept : bool
        ``d2 <= threshold``.
    innovation : ndarray, shape (3,)
        ``e_ij`` of the candidate at the current estimate.
    S : ndarray, shape (3, 3)
        Its covariance ``B Sigma_rel B^T + Omega^-1``.
    """

    d2: float
    threshold: float
    accept: bool
    innovation: np.ndarray
    S: np.ndarray


def loop_closure_test(
    graph, i, j, measurement, information, *, poses=None, confidence=0.99, error="t2v"
):
    """Gate a candidate loop closure ``z_ij`` with the relative uncertainty of ``x_j`` given ``x_i``.

    The candidate's error ``e = t2v(z^-1 X_i^-1 X_j)`` has, to first order, covariance
    ``S = B_ij Sigma_j|i B_ij^T + Omega^-1`` where ``Sigma_j|i`` is the relative covariance
    (lecture notes, "Relative Uncertainty": "useful to decide loop closures").  The candidate is
    plausible when ``e^T S^-1 e`` is below the ``confidence`` quantile of a χ² with 3 degrees of
    freedom.

    Parameters
    ----------
    graph : PoseGraph
        The graph without the candidate.
    i, j : int
        Vertex ids.
    measurement : array_like, shape (3,)
        Candidate ``z_ij``.
    information : array_like, shape (3, 3)
        Its information matrix.
    poses : array_like, shape (n, 3), optional
        Current estimate, default ``graph.poses``.
    confidence : float
    error : {"t2v", "log"}

    Returns
    -------
    GateResult
    """
    where = "loop_closure_test"
    _check_graph(graph, where)
    confidence = check_real(confidence, "confidence", where, minimum=0.0, maximum=1.0, strict=True)
    error = check_choice(error, "error", where, ERRORS)
    ki = _one_vertex(graph, i, f"{where}: i")
    kj = _one_vertex(graph, j, f"{where}: j")
    i, j = int(graph.ids[ki]), int(graph.ids[kj])
    if ki == kj:
        raise GraphError(
            f"{where}: i and j are the same vertex (id {i}); a loop closure relates two "
            "different poses"
        )
    x = as_graph_poses(graph, poses)
    for name, value in (("measurement", measurement), ("information", information)):
        if np.iscomplexobj(value):
            raise GraphTypeError(f"{where}: {name} must be real; got a complex array")
    z = _numeric(measurement, f"{where}: measurement", float)
    omega = _numeric(information, f"{where}: information", float)
    if z.shape != (3,):
        raise GraphError(f"{where}: measurement must have shape (3,); got {z.shape}")
    if omega.shape != (3, 3):
        raise GraphError(f"{where}: information must have shape (3, 3); got {omega.shape}")
    if not np.all(np.isfinite(z)):
        raise GraphError(f"{where}: candidate measurement is not finite: {z.tolist()}")
    if abs(z[2]) > se2.MAX_ANGLE:  # as PoseGraph checks every measured angle
        raise GraphError(
            f"{where}: the candidate's measured angle {float(z[2])!r} rad is too large: |dtheta| "
            f"must be <= {se2.MAX_ANGLE:g} (float64 cannot reduce larger angles consistently, see "
            "lagolib.se2); wrap it to (-pi, pi]"
        )
    if not np.all(np.isfinite(omega)) or first_bad_information(omega[None]) is not None:
        raise GraphError(
            f"{where}: information of the candidate loop closure {i} -> {j}: "
            f"{describe_bad_information(omega)}"
        )
    (cov,) = relative_covariances(graph, i, [j], poses=x, error=error)
    e, _, B = edge_jacobians(x[ki], x[kj], z, error=error)
    S = B @ cov @ B.T + np.linalg.inv(omega)
    d2 = float(e @ np.linalg.solve(S, e))
    threshold = float(2.0 * gammaincinv(1.5, confidence))  # χ²₃ quantile: P(χ²₃ ≤ t) = confidence
    return GateResult(d2, threshold, d2 <= threshold, e, S)
