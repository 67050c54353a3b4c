"""Least-squares graph SLAM as in the lecture notes: Jacobians, ``H`` and ``b``, Gauss–Newton, LM.

The lecture notes ("Least Square SLAM") minimize

.. math:: F(x) = \\sum_{ij} e_{ij}^T \\Omega_{ij} e_{ij}, \\qquad
          e_{ij} = t2v(Z_{ij}^{-1} X_i^{-1} X_j)

by linearizing every error around the current guess, ``e_ij(x + dx) ≈ e_ij + A_ij dx_i +
B_ij dx_j``, building the normal equations ``H dx = -b`` one constraint at a time, solving them
with a sparse factorization and updating ``x <- x + dx`` until convergence ("Algorithm").  This
module has each piece:

* :func:`edge_jacobians` — ``e_ij``, ``A_ij = de/dx_i`` and ``B_ij = de/dx_j`` for all edges at
  once, shape ``(m, 3, 3)`` (:mod:`lagolib.symbolic` derives the same blocks with sympy);
* :func:`build_linear_system_loop` — "Building the Linear System" literally, one constraint at a
  time: the readable reference;
* :class:`LinearSystem` — the same ``H`` and ``b`` assembled for all edges at once into a sparse
  matrix whose pattern is computed once per graph and reused at every iteration;
* :class:`Prior` and ``fixed=`` — the two ways to fix the gauge ("Role of the Prior",
  "Fixing a Subset of Variables"); :func:`check_gauge` says what is missing;
* :func:`optimize` — Gauss–Newton (with step control) or Levenberg–Marquardt.

Poses are updated additively, ``(x, y, theta) <- (x, y, theta) + dx`` with the angle wrapped, as
in the notes.  Two error definitions are offered: ``error="t2v"`` (the notes' and g2o's) and
``error="log"`` (GTSAM's: the SE(2) logarithm :func:`lagolib.se2.log` in place of ``t2v``).  They
have different optima; choose ``"log"`` to reproduce GTSAM's numbers.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from . import se2
from .checks import check_bool, check_callback, check_choice, check_int, check_real
from .errors import (
    ConvergenceError,
    GaugeError,
    GraphError,
    NotPositiveDefiniteError,
    OptionError,
    OptionTypeError,
)
from .graph import (
    ERRORS,
    PoseGraph,
    _edge_chi2,
    _numeric,
    as_graph_poses,
    check_graph,
    describe_bad_information,
    edge_errors,
    first_bad_information,
    vertex_rows,
)
from .kernels import INLIER_THRESHOLD, Kernel
from .kernels import kernel as as_kernel
from .linalg import (
    BACKENDS,
    SparseCholesky,
    _norm2,
    _rows_key,
    core_size,
    elimination_ordering,
    expand_ordering,
    pcg,
)

__all__ = [
    "Prior",
    "edge_jacobians",
    "prior_jacobian",
    "build_linear_system_loop",
    "reduce_system",
    "LinearSystem",
    "RobustSystem",
    "WeightedLeastSquares",
    "robust_edge_mask",
    "check_gauge",
    "resolve_gauge",
    "optimize",
    "OptimizeResult",
]


# ----------------------------------------------------------------------------- Jacobians
def edge_jacobians(p_i, p_j, z, *, error="t2v"):
    """Error ``e_ij`` and its Jacobian blocks ``A_ij``, ``B_ij`` (lecture notes, "Linearizing the
    error function" and "Building the Linear system": "Compute the blocks of the Jacobian").

    For ``error="t2v"``, with ``R_iz = R(theta_i + theta_z)`` and ``dt = t_j - t_i``::

        e_ij = [ R_iz^T dt - R_z^T t_z ;  wrap(theta_j - theta_i - theta_z) ]

        A_ij = de/dx_i = [[ -R_iz^T , dR_iz^T/dtheta dt ],      B_ij = de/dx_j = [[ R_iz^T, 0 ],
                          [  0  0   ,        -1         ]]                        [ 0  0 , 1 ]]

    For ``error="log"`` the error is ``log(u)`` of the ``t2v`` error ``u`` and the blocks are
    ``D(u) A_ij``, ``D(u) B_ij`` with ``D = d log / du`` (:func:`lagolib.se2.log_jacobian`).

    Parameters
    ----------
    p_i, p_j : array_like, shape (..., 3)
        Poses ``x_i`` and ``x_j``.
    z : array_like, shape (..., 3)
        Measurements ``z_ij``.
    error : {"t2v", "log"}

    Returns
    -------
    e : ndarray, shape (..., 3)
    A, B : ndarray, shape (..., 3, 3)

    Examples
    --------
    >>> import numpy as np
    >>> e, A, B = edge_jacobians(np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([1.0, 0, 0]))
    >>> e.round(12) + 0.0
    array([0., 0., 0.])
    >>> A + 0.0  # x_j is 1 m ahead of x_i: turning x_i moves it sideways
    array([[-1.,  0.,  0.],
           [ 0., -1., -1.],
           [ 0.,  0., -1.]])
    """
    check_choice(error, "error", "edge_jacobians", ERRORS)
    e, J = _edge_jacobian(p_i, p_j, z, error)
    return e, J[..., :3], J[..., 3:]


def _edge_jacobian(p_i, p_j, z, error):
    """:func:`edge_jacobians` with ``[A_ij  B_ij]`` written into one array ``J``, shape (..., 3, 6)."""
    p_i, p_j, z = np.broadcast_arrays(
        se2._as_poses(p_i, "p_i"), se2._as_poses(p_j, "p_j"), se2._as_poses(z, "z")
    )
    e = edge_errors(p_i, p_j, z)  # the t2v error, also for "log" (its argument)
    c, s, u0, u1 = _jacobian_parts(p_i, p_j, z)
    J = np.zeros(p_i.shape + (6,))
    J[..., 0, 3], J[..., 0, 4] = c, s  # B_ij = [[R_iz^T, 0], [0, 1]]
    J[..., 1, 3], J[..., 1, 4] = -s, c
    J[..., 2, 5] = 1.0
    J[..., 0, 0], J[..., 0, 1] = -c, -s  # A_ij = -B_ij, but for its last column
    J[..., 1, 0], J[..., 1, 1] = s, -c
    J[..., 2, 2] = -1.0
    J[..., 0, 2], J[..., 1, 2] = u0, u1  # d(R_iz^T)/dtheta_i dt
    if error == "log":
        return se2.log(e), se2.log_jacobian(e) @ J
    return e, J


def _jacobian_parts(p_i, p_j, z):
    """``cos``, ``sin`` of ``theta_i + theta_z`` and ``u = d(R_iz^T)/dtheta_i (t_j - t_i)``.

    The entries of the ``t2v`` Jacobians: ``B_ij = diag(R_iz^T, 1)`` and ``A_ij = -B_ij`` with
    ``(u0, u1, 0)`` added to its last column (:func:`edge_jacobians`).  Arrays of shape (...).
    """
    a = p_i[..., 2] + z[..., 2]
    c, s = np.cos(a), np.sin(a)
    dx = p_j[..., 0] - p_i[..., 0]
    dy = p_j[..., 1] - p_i[..., 1]
    return c, s, -s * dx + c * dy, -c * dx - s * dy


def _normal_blocks(p_i, p_j, z, information, Oe):
    """``J^T Omega J`` and ``J^T Omega e`` of every edge in closed form.

    Lecture notes, "Building the Linear system": an edge adds ``A^T Ω A``, ``A^T Ω B``,
    ``B^T Ω A``, ``B^T Ω B`` to ``H`` and ``A^T Ω e``, ``B^T Ω e`` to ``b``.  With the ``t2v``
    Jacobians of :func:`edge_jacobians`, ``B = G = diag(R_iz^T, 1)`` and ``A = -G + u e3^T`` where
    ``u = (dR_iz^T/dθ (t_j - t_i), 0)``, so with ``P = G^T Ω G`` (Ω rotated), ``q = G^T Ω u``,
    ``r = u^T Ω u``, ``g = G^T Ω e`` and ``h = u^T Ω e``::

        B^T Ω B = P,     A^T Ω B = -P + e3 q^T,     A^T Ω A = P - e3 q^T - q e3^T + r e3 e3^T
        B^T Ω e = g,     A^T Ω e = -g + h e3

    — a few products per edge instead of two 3x6 matrix products; equal to them to rounding
    (tested), and exactly symmetric.  GTSAM's ``log`` error has Jacobians ``D [A B]``
    (``D = d log/du``), which is the same with Ω replaced by ``D^T Ω D`` and ``Ω e`` by
    ``D^T Ω e``.  Entry-major layout: every entry is one contiguous vector over the edges.

    Parameters
    ----------
    p_i, p_j, z : ndarray, shape (c, 3)
    information : ndarray, shape (c, 3, 3)
        Ω (``t2v``) or ``D^T Ω D`` (``log``); symmetric.
    Oe : ndarray, shape (c, 3)
        ``Ω e`` (``t2v``) or ``D^T Ω e`` (``log``).

    Returns
    -------
    M : ndarray, shape (6, 6, c)
        ``J^T Ω J`` with ``J = [A B]``, entry ``(a, b)`` of every edge in ``M[a, b]``.
    Jte : ndarray, shape (6, c)
        ``J^T Ω e``.
    """
    c, s, u0, u1 = _jacobian_parts(p_i, p_j, z)
    Om = information
    a, bxy, d = Om[:, 0, 0], Om[:, 0, 1], Om[:, 1, 1]
    p, q, t = Om[:, 0, 2], Om[:, 1, 2], Om[:, 2, 2]
    cs, cc, ss = c * s, c * c, s * s
    P = np.empty((3, 3, len(c)))  # P = G^T Ω G: the xy block rotated by R_iz
    P[0, 0] = cc * a - 2.0 * cs * bxy + ss * d
    P[0, 1] = P[1, 0] = cs * (a - d) + (cc - ss) * bxy
    P[1, 1] = ss * a + 2.0 * cs * bxy + cc * d
    P[0, 2] = P[2, 0] = c * p - s * q
    P[1, 2] = P[2, 1] = s * p + c * q
    P[2, 2] = t
    w0, w1 = a * u0 + bxy * u1, bxy * u0 + d * u1  # Ω u (its first two entries) ...
    qv = np.stack([c * w0 - s * w1, s * w0 + c * w1, p * u0 + q * u1])  # ... G^T Ω u, (3, c)
    M = np.empty((6, 6, len(c)))
    M[3:, 3:] = P  # B^T Ω B
    Hij = M[:3, 3:]
    np.negative(P, out=Hij)
    Hij[2] += qv  # A^T Ω B = -P + e3 q^T
    M[3:, :3] = np.swapaxes(Hij, 0, 1)
    Hii = M[:3, :3]
    Hii[...] = P  # A^T Ω A = P - e3 q^T - q e3^T + r e3 e3^T
    Hii[2] -= qv
    Hii[:, 2] -= qv
    Hii[2, 2] += u0 * w0 + u1 * w1  # r = u^T Ω u
    f0, f1 = Oe[:, 0], Oe[:, 1]  # Ω e
    Jte = np.empty((6, len(c)))
    Jte[3], Jte[4] = c * f0 - s * f1, s * f0 + c * f1  # g = G^T Ω e
    Jte[5] = Oe[:, 2]
    np.negative(Jte[3:], out=Jte[:3])
    Jte[2] += u0 * f0 + u1 * f1  # A^T Ω e = -g + h e3
    return M, Jte


def prior_jacobian(p, mean, *, error="t2v"):
    """Error of a pose prior and its Jacobian (lecture notes, "Role of the Prior").

    ``e = t2v(M^-1 X)`` — the notes' ``e(x_0) = t2v(x_0)`` for a prior at the origin — so
    ``J = de/dx = [[R_m^T, 0], [0, 1]]``.  With ``error="log"``, ``e = log(M^-1 X)`` (GTSAM's
    ``PriorFactorPose2``) and ``J = D(u) [[R_m^T, 0], [0, 1]]``.

    Parameters
    ----------
    p, mean : array_like, shape (..., 3)
    error : {"t2v", "log"}

    Returns
    -------
    e : ndarray, shape (..., 3)
    J : ndarray, shape (..., 3, 3)
    """
    check_choice(error, "error", "prior_jacobian", ERRORS)
    p, mean = np.broadcast_arrays(se2._as_poses(p), se2._as_poses(mean, "mean"))
    e = se2.between(mean, p)
    c, s = np.cos(mean[..., 2]), np.sin(mean[..., 2])
    J = np.zeros(p.shape + (3,))
    J[..., 0, 0], J[..., 0, 1] = c, s
    J[..., 1, 0], J[..., 1, 1] = -s, c
    J[..., 2, 2] = 1.0
    if error == "log":
        D = se2.log_jacobian(e)
        return se2.log(e), D @ J
    return e, J


# ----------------------------------------------------------------------------- gauge
@dataclass(frozen=True)
class Prior:
    """A Gaussian prior on one pose: an extra unary constraint ``e = t2v(M^-1 X)``.

    Lecture notes, "Role of the Prior": a Gaussian estimate of ``x_0`` fixes the global reference
    frame.

    Parameters
    ----------
    vertex : int
        Vertex id (as in the file) of the pose.
    mean : array_like, shape (3,)
        ``M``, default the origin.
    information : array_like, shape (3, 3)
        Default ``diag(1e6, 1e6, 1e8)``: standard deviations 1 mm and 0.1 mrad (GTSAM examples'
        ``(1e-3, 1e-3, 1e-4)``).
    """

    vertex: int
    mean: tuple = (0.0, 0.0, 0.0)
    information: tuple = ((1e6, 0.0, 0.0), (0.0, 1e6, 0.0), (0.0, 0.0, 1e8))

    def __post_init__(self):
        object.__setattr__(self, "vertex", check_int(self.vertex, "vertex", "Prior"))
        mean = _numeric(self.mean, "Prior mean", float)
        info = _numeric(self.information, "Prior information", float)
        if mean.shape != (3,) or not np.all(np.isfinite(mean)):
            raise GraphError(f"Prior mean must be 3 finite numbers; got {self.mean!r}")
        if info.shape != (3, 3) or not np.all(np.isfinite(info)):
            raise GraphError(f"Prior information must be a finite 3x3 matrix; got {info.tolist()}")
        if first_bad_information(info[None], rtol=1e-12) is not None:  # the edges' rules
            raise GraphError(
                f"Prior on vertex id {self.vertex}: information must be symmetric positive "
                f"definite and usable in float64: {describe_bad_information(info)}"
            )
        object.__setattr__(self, "mean", tuple(mean.tolist()))
        object.__setattr__(self, "information", tuple(map(tuple, info.tolist())))

    @classmethod
    def from_sigmas(cls, vertex, mean=(0.0, 0.0, 0.0), sigmas=(1e-3, 1e-3, 1e-4)):
        """A prior with diagonal covariance ``diag(sigmas)^2``."""
        sig = _numeric(sigmas, "Prior sigmas", float)
        if sig.shape != (3,) or not np.all((sig > 0) & np.isfinite(sig)):
            raise GraphError(f"Prior sigmas must be 3 finite positive numbers; got {sigmas!r}")
        return cls(vertex, mean, np.diag(1.0 / sig**2))


def _as_priors(prior, where):
    """``prior`` as a tuple of :class:`Prior`: None, one Prior, or an iterable of them (not a
    number, a bool, text or a dict); else an OptionTypeError naming ``where``."""
    if prior is None:
        return ()
    if isinstance(prior, Prior):
        return (prior,)
    if isinstance(prior, str | bytes | dict) or not isinstance(prior, Iterable):
        raise OptionTypeError(
            f"{where}: prior must be a lagolib.Prior, a list of them, or None; got {prior!r} "
            f"({type(prior).__name__}); a lagolib.Prior holds one vertex id"
        )
    priors = tuple(prior)
    for p in priors:
        if not isinstance(p, Prior):
            raise OptionTypeError(
                f"{where}: prior must be a lagolib.Prior or a list of them; it holds {p!r} "
                f"({type(p).__name__})"
            )
    return priors


def resolve_gauge(graph, fixed=None, prior=None, *, where="resolve_gauge"):
    """The gauge :func:`optimize` uses: ``(fixed ids, priors)``, checked by :func:`check_gauge`.

    ``fixed=None`` means: the vertex with the smallest id when no prior is given, else none.
    ``where`` (the caller's name) starts the error messages.
    """
    check_graph(graph, where)
    priors = _as_priors(prior, where)
    if fixed is None:
        fixed = () if priors or graph.n == 0 else (int(np.min(graph.ids)),)
    fixed = tuple(np.atleast_1d(np.asarray(fixed, dtype=object)).tolist())
    check_gauge(graph, fixed, priors, where=where)
    return fixed, priors


def check_gauge(graph, fixed=(), prior=None, *, where="check_gauge"):
    """Raise :class:`~lagolib.GaugeError` unless every connected component is anchored.

    The χ² of a pose graph depends only on relative poses, so ``H`` is singular unless each
    connected component has a fixed pose or a prior.

    Parameters
    ----------
    graph : PoseGraph
    fixed : sequence of int
        Vertex ids held fixed.
    prior : Prior or sequence of Prior, optional

    Raises
    ------
    GaugeError
        Naming the first component without a gauge and what to pass.
    """
    check_graph(graph, where)
    fixed_idx = vertex_rows(graph, fixed, f"{where}: fixed")
    prior_idx = vertex_rows(graph, [p.vertex for p in _as_priors(prior, where)], f"{where}: prior")
    count, labels = graph.components()
    anchored = np.zeros(count, dtype=bool)
    anchored[labels[np.concatenate([fixed_idx, prior_idx])]] = True
    missing = np.flatnonzero(~anchored)
    if missing.size == 0:
        return
    comp = np.flatnonzero(labels == missing[0])
    ids = np.sort(np.asarray(graph.ids)[comp])
    shown = ", ".join(map(str, ids[:8])) + (", ..." if ids.size > 8 else "")
    where = (
        f"the graph has {count} connected components and {missing.size} of them "
        f"{'has' if missing.size == 1 else 'have'} no gauge; the first is vertex ids [{shown}] "
        f"({ids.size} vertices)"
        if count > 1
        else "the graph has no gauge"
    )
    raise GaugeError(
        f"H is singular: {where}. Nothing fixes where this part of the map is: fix one of its "
        f"poses (fixed=[{ids[0]}]) or add a prior (prior=lagolib.Prior({ids[0]}))",
        vertices=ids.tolist(),
    )


# ----------------------------------------------------------------------------- H and b
def build_linear_system_loop(graph, poses=None, *, prior=None, error="t2v"):
    """``H`` and ``b`` built one constraint at a time — the lecture notes' algorithm, literally.

    Lecture notes, "Building the Linear System": for each constraint

    1. compute the error ``e_ij``;
    2. compute the blocks of the Jacobian ``A_ij``, ``B_ij``;
    3. update the coefficient vector: ``b_i += A_ij^T Omega_ij e_ij``, ``b_j += B_ij^T Omega_ij e_ij``;
    4. update the normal-equation matrix: ``H_ii += A^T Omega A``, ``H_ij += A^T Omega B``,
       ``H_ji += B^T Omega A``, ``H_jj += B^T Omega B``.

    (The slide's last two lines swap the ``ij``/``jj`` labels; the blocks above are the ones
    ``J_ij^T Omega J_ij`` gives.)  This is the readable reference; :class:`LinearSystem` computes
    the same numbers vectorized.  Nothing is fixed here: pass the result to :func:`reduce_system`.

    Parameters
    ----------
    graph : PoseGraph
    poses : array_like, shape (n, 3), optional
        Linearization point, default ``graph.poses``.
    prior : Prior or sequence of Prior, optional
        Unary constraints, added like edges with only an ``A`` block.
    error : {"t2v", "log"}

    Returns
    -------
    H : scipy.sparse.csr_matrix, shape (3n, 3n)
    b : ndarray, shape (3n,)
    """
    check_graph(graph, "build_linear_system_loop")
    priors = _as_priors(prior, "build_linear_system_loop")
    x = as_graph_poses(graph, poses)
    blocks = {}
    b = np.zeros((graph.n, 3))

    def add(r, c, block):
        blocks[r, c] = blocks.get((r, c), 0.0) + block

    for k in range(graph.m):
        i, j = graph.edges[k]
        omega = graph.information[k]
        e, A, B = edge_jacobians(x[i], x[j], graph.measurements[k], error=error)  # steps 1 and 2
        b[i] += A.T @ omega @ e  # step 3
        b[j] += B.T @ omega @ e
        add(i, i, A.T @ omega @ A)  # step 4
        add(i, j, A.T @ omega @ B)
        add(j, i, B.T @ omega @ A)
        add(j, j, B.T @ omega @ B)
    for p in priors:
        (k,) = vertex_rows(graph, [p.vertex], "build_linear_system_loop: prior")
        omega = np.asarray(p.information)
        e, J = prior_jacobian(x[k], p.mean, error=error)
        b[k] += J.T @ omega @ e
        add(k, k, J.T @ omega @ J)
    rows, cols, vals = [], [], []
    for (r, c), block in blocks.items():
        rr, cc = np.meshgrid(3 * r + np.arange(3), 3 * c + np.arange(3), indexing="ij")
        rows.append(rr.ravel())
        cols.append(cc.ravel())
        vals.append(np.ravel(block))
    N = 3 * graph.n
    if not rows:
        return sp.csr_matrix((N, N)), b.ravel()
    H = sp.coo_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(N, N)
    )
    return H.tocsr(), b.ravel()


def reduce_system(graph, H, b, fixed):
    """Delete the rows and columns of fixed poses (lecture notes, "Fixing a Subset of Variables").

    Parameters
    ----------
    graph : PoseGraph
    H : sparse matrix, shape (3n, 3n)
    b : ndarray, shape (3n,)
    fixed : sequence of int
        Vertex ids to hold fixed.

    Returns
    -------
    H_free : scipy.sparse.csr_matrix, shape (3k, 3k)
    b_free : ndarray, shape (3k,)
        ``k = n - len(fixed)``, free poses in row order of the graph.
    """
    check_graph(graph, "reduce_system")
    keep = np.ones(graph.n, dtype=bool)
    keep[vertex_rows(graph, fixed, "reduce_system: fixed")] = False
    rows = (3 * np.flatnonzero(keep)[:, None] + np.arange(3)).ravel()
    H = sp.csr_matrix(H)
    return H[rows][:, rows], np.asarray(b)[rows]


#: Edges per chunk in :meth:`LinearSystem.assemble`: the 6x6 products of 2^15 edges (9 MB) stay
#: small, so a 10^6-pose graph is assembled without gigabyte temporaries.
_CHUNK = 2**15


#: What :class:`LinearSystem` computes from the structure alone (shared with ``like``).
_STRUCTURE = (
    "_blocks", "nnz", "_indptr", "_indices", "_slot_e", "_slot_p", "_diag_slot", "_rows_b_e",
    "_rows_b_p",
)  # fmt: skip


class LinearSystem:
    """``H`` and ``b`` for all constraints at once, in a sparsity pattern computed once.

    Lecture notes, "The Linear system": ``H = Σ J_ij^T Ω_ij J_ij``, ``b = Σ J_ij^T Ω_ij e_ij``,
    block-sparse as "Consequences of the Sparsity" shows.

    The pattern — which 3x3 blocks of ``H`` are non-zero — depends only on the edges, the fixed
    poses and the priors, so it is computed in the constructor (a ``np.unique`` over the block
    entries of all edges).  :meth:`assemble` then evaluates the blocks ``J^T Omega J`` of every
    edge at once and adds them into the CSR data array with one ``np.bincount``.

    Parameters
    ----------
    graph : PoseGraph
    fixed : sequence of int
        Vertex ids held fixed: their rows and columns are left out ("Fixing a Subset of
        Variables").
    prior : Prior or sequence of Prior, optional
    error : {"t2v", "log"}
    like : LinearSystem, optional
        A system of the same graph (or a ``with_poses`` copy of it) with the same fixed poses
        and priors: its pattern and scatter indices are reused instead of built again, and its
        ``H`` shares their arrays — so a factorization's symbolic analysis recognizes the pattern
        at once.  Ignored when it does not match.

    Attributes
    ----------
    free : ndarray of int, shape (k,)
        Row indices (into ``graph.poses``) of the free poses; block ``r`` of ``H`` is pose
        ``free[r]``.
    N : int
        ``3 k``, the size of ``H``.
    nnz : int
        Stored entries of ``H`` (both triangles).
    """

    def __init__(self, graph, *, fixed=(), prior=None, error="t2v", like=None):
        check_graph(graph, "LinearSystem")
        check_choice(error, "error", "LinearSystem", ERRORS)
        self.graph, self.error = graph, error
        self.scale = None  # a weight per edge on its information (IRLS, GNC), or None (all 1)
        self.priors = _as_priors(prior, "LinearSystem")
        n = graph.n
        fixed_idx = vertex_rows(graph, fixed, "fixed")
        is_free = np.ones(n, dtype=bool)
        is_free[fixed_idx] = False
        self.fixed = np.flatnonzero(~is_free)
        self.free = np.flatnonzero(is_free)
        red = np.full(n, -1, dtype=np.int64)
        red[self.free] = np.arange(self.free.size)
        self._red = red
        self.N = 3 * self.free.size
        comp = np.arange(3)
        self._prior_idx = vertex_rows(graph, [p.vertex for p in self.priors], "prior")
        self._prior_mean = np.array([p.mean for p in self.priors], dtype=float).reshape(-1, 3)
        self._prior_info = np.array([p.information for p in self.priors], float).reshape(-1, 3, 3)
        if self._same_structure(like):
            for name in _STRUCTURE:
                setattr(self, name, getattr(like, name))
            return
        e = red[graph.edges]  # block of each edge's poses, -1 where fixed; (m, 2)
        pblk = red[self._prior_idx]
        self._build_pattern(e, pblk)
        # where each edge's / prior's J^T Omega e goes in b: N (a trash row) where the pose is fixed
        N = self.N
        rows_b = np.where(e[:, :, None] >= 0, 3 * e[:, :, None] + comp, N)  # (m, 2, 3)
        self._rows_b_e = np.ascontiguousarray(rows_b.reshape(-1, 6).T)  # entry-major, (6, m)
        self._rows_b_p = np.where(pblk[:, None] >= 0, 3 * pblk[:, None] + comp, N)  # (p, 3)

    def _same_structure(self, other):
        """Whether ``other`` (a LinearSystem or None) has this system's pattern: the same
        edges (the same arrays: one graph or its ``with_poses`` copies), fixed poses and
        priors' poses."""
        return (
            isinstance(other, LinearSystem)
            and other.graph._edges is self.graph._edges
            and np.array_equal(other.fixed, self.fixed)
            and np.array_equal(other._prior_idx, self._prior_idx)
        )

    def _build_pattern(self, e, pblk):
        """The CSR pattern of ``H`` from its 3x3 blocks, and where every Jacobian product goes.

        The non-zero blocks are ``(i, i), (i, j), (j, i), (j, j)`` of every edge, ``(k, k)`` of
        every prior and of every free pose: one ``np.unique`` over ``4 m + p + k`` block keys.
        Each block ``u`` of block-row ``r`` (the ``t``-th of the ``c_r`` blocks in that row)
        holds the scalar entries ``(3 r + a, 3 col_u + c)`` at CSR position
        ``9 ptr_r + 3 a c_r + 3 t + c``, so the scalar pattern is written out, never sorted.
        Blocks of fixed poses go to one extra "trash" slot past the end, so assembly needs no
        masks.
        """
        k = self.free.size
        q = np.array([[0, 0], [0, 1], [1, 0], [1, 1]])  # the four blocks of an edge
        R, C = e[:, q[:, 0]], e[:, q[:, 1]]  # (m, 4)
        keep_e = (R >= 0) & (C >= 0)
        keep_p = pblk >= 0
        keys = np.concatenate(
            [(R * k + C)[keep_e], pblk[keep_p] * (k + 1), np.arange(k, dtype=np.int64) * (k + 1)]
        )
        del R, C
        blocks, inverse = np.unique(keys, return_inverse=True)
        del keys
        brow, bcol = np.divmod(blocks, k) if k else (blocks, blocks)
        self._blocks = (brow, bcol)  # the pose-level pattern, for the fill-reducing ordering
        bptr = np.zeros(k + 1, dtype=np.int64)
        np.cumsum(np.bincount(brow, minlength=k), out=bptr[1:])
        cnt = np.diff(bptr)
        self.nnz = nnz = 9 * blocks.size
        itype = np.int32 if nnz + 1 < 2**31 else np.int64
        a3 = np.arange(3)
        self._indptr = np.append((9 * bptr[:-1, None] + 3 * a3 * cnt[:, None]).ravel(), nnz)
        self._indptr = self._indptr.astype(itype)
        base = 9 * bptr[brow] + 3 * (np.arange(blocks.size) - bptr[brow])  # entry (0, 0) of u
        stride = 3 * cnt[brow]  # from row a of a block to row a + 1
        self._indices = np.empty(nnz, dtype=itype)
        for a in range(3):
            for c in range(3):
                self._indices[base + a * stride + c] = 3 * bcol + c
        # frozen: every H shares them, and SparseCholesky knows its pattern by their address
        self._indptr.setflags(write=False)
        self._indices.setflags(write=False)
        # entry (a, c) of each edge's four blocks and each prior's block: its CSR slot or `nnz`
        ue = np.zeros(keep_e.shape, dtype=np.int64)  # block 0 where dropped: masked below
        ue[keep_e] = inverse[: int(keep_e.sum())]
        base, stride = np.append(base, nnz), np.append(stride, 0)  # a block past the end for k = 0
        up = inverse[int(keep_e.sum()) : int(keep_e.sum()) + int(keep_p.sum())]
        slot = np.empty(keep_e.shape + (3, 3), dtype=itype)  # (m, 4, 3, 3)
        self._slot_p = np.full(pblk.shape + (3, 3), nnz, dtype=itype)  # (p, 3, 3)
        be, se = np.where(keep_e, base[ue], nnz), np.where(keep_e, stride[ue], 0)
        for a in range(3):
            for c in range(3):
                slot[:, :, a, c] = np.where(keep_e, be + a * se + c, nnz)
                self._slot_p[keep_p, a, c] = base[up] + a * stride[up] + c
        # in the layout of an edge's 6x6 J^T Omega J: rows 3 qr + a, columns 3 qc + c
        self._slot_e = np.ascontiguousarray(  # entry-major, (6, 6, m): a chunk's slots are runs
            slot.reshape(-1, 2, 2, 3, 3).transpose(1, 3, 2, 4, 0).reshape(6, 6, -1)
        )
        del slot
        first = np.searchsorted(blocks, np.arange(k) * (k + 1)) - bptr[:-1]  # rank of (r, r)
        self._diag_slot = (
            9 * bptr[:-1, None] + 3 * a3 * cnt[:, None] + 3 * first[:, None] + a3
        ).ravel()

    @property
    def _closed_form(self):
        """Whether :meth:`assemble` may use :func:`_normal_blocks`: the graph's own edges,
        information and Jacobians, not a subclass's residual (e.g. lagolib.certify's)."""
        cls = type(self)
        return cls._terms is LinearSystem._terms and cls._edge_weights is LinearSystem._edge_weights

    def ordering(self):
        """An elimination order of ``H``'s rows, from the pose graph, stable on long chains.

        :func:`lagolib.linalg.elimination_ordering` on the ``k x k`` pattern of the free poses'
        blocks — nested dissection on the cycles, away from the gauge (the fixed poses' neighbours
        and the poses with a prior) on the tree-like parts — and each pose's three rows follow it.
        """
        k = self.free.size
        return expand_ordering(self.pose_ordering(), 3 * np.arange(k)[:, None] + np.arange(3))

    def pose_ordering(self):
        """The order of the free poses behind :meth:`ordering` (positions in :attr:`free`),
        computed once per graph structure, fixed poses and priors (LAGO's, with its anchor
        fixed, is the same one)."""

        def compute():
            e = self._red[self.graph.edges]  # -1 where a pose is fixed
            near = np.concatenate(
                [e[e[:, 0] < 0, 1], e[e[:, 1] < 0, 0], self._red[self._prior_idx]]
            )
            return elimination_ordering(self._pose_pattern(), near[near >= 0])

        key = ("elimination_ordering", _rows_key(self.fixed), _rows_key(self._prior_idx))
        return self.graph._structural(key, compute)

    def core_rows(self):
        """Rows of ``H`` in the pose graph's 2-core (:func:`lagolib.linalg.core_size`): where
        the factorization's work is, which decides ``backend="auto"``."""
        return 3 * core_size(self._pose_pattern())

    def _pose_pattern(self):
        """The ``k x k`` pattern of the free poses' blocks of ``H``."""
        k = self.free.size
        brow, bcol = self._blocks
        return sp.csr_matrix((np.ones(brow.size), (brow, bcol)), shape=(k, k))

    def _edge_weights(self):
        """The weight of every edge's residual: its information matrix, times :attr:`scale`
        where set, shape (m, 3, 3)."""
        if self.scale is None:
            return self.graph.information
        return self.graph.information * self.scale[:, None, None]

    def edge_chi2(self, poses):
        """Every edge's ``e^T Omega e`` at ``poses`` (shape (n, 3)), unscaled; shape (m,)."""
        edges = self.graph.edges
        return _edge_chi2(self.graph, poses[edges[:, 0]], poses[edges[:, 1]], self.error)

    def _prior_chi2(self, poses):
        ep = se2.between(self._prior_mean, poses[self._prior_idx])
        if self.error == "log":
            ep = se2.log(ep)
        return float(np.einsum("ka,kab,kb->", ep, self._prior_info, ep))

    def _terms(self, poses):
        g = self.graph
        e, J = _edge_jacobian(
            poses[g.edges[:, 0]], poses[g.edges[:, 1]], g.measurements, self.error
        )
        ep, Jp = prior_jacobian(poses[self._prior_idx], self._prior_mean, error=self.error)
        return e, J, ep, Jp

    def objective(self, poses):
        """χ² of the edges (each times :attr:`scale` where set) plus the priors' terms at
        ``poses`` (shape (n, 3)); no Jacobians."""
        terms = self.edge_chi2(poses)
        chi = float(terms.sum() if self.scale is None else terms @ self.scale)
        return chi + self._prior_chi2(poses)

    def assemble(self, poses):
        """``H``, ``b`` and the objective at ``poses``.

        Parameters
        ----------
        poses : ndarray, shape (n, 3)
            Linearization point (fixed poses included).

        Returns
        -------
        H : scipy.sparse.csr_matrix, shape (N, N)
            ``sum_ij J_ij^T Omega_ij J_ij`` over edges and priors (lecture notes, "Consequences of
            the Sparsity"), free poses only.  Symmetric; both triangles stored.
        b : ndarray, shape (N,)
            ``sum_ij J_ij^T Omega_ij e_ij``.
        chi2 : float
            ``sum_ij e_ij^T Omega_ij e_ij`` (each term times :attr:`scale` where set) plus the
            priors' terms.
        """
        fast = self._closed_form  # lagolib's own edges and Jacobians: the blocks in closed form
        if fast:
            g = self.graph
            p_i, p_j = poses[g.edges[:, 0]], poses[g.edges[:, 1]]
            ep, Jp = prior_jacobian(poses[self._prior_idx], self._prior_mean, error=self.error)
            m = g.m
        else:
            e, J, ep, Jp = self._terms(poses)
            W = self._edge_weights()  # Omega_ij, (m, k, k)
            m = J.shape[0]
        data = np.zeros(self.nnz + 1)  # the last slot takes the blocks of fixed poses
        b = np.zeros(self.N + 1)
        objective = 0.0
        for lo in range(0, m, _CHUNK):  # chunks keep the temporaries small
            c = slice(lo, lo + _CHUNK)
            if fast:
                u = edge_errors(p_i[c], p_j[c], g.measurements[c])  # the t2v error
                Wc = g.information[c]
                if self.scale is not None:  # IRLS: w_ij Omega_ij
                    Wc = Wc * self.scale[c, None, None]
                if self.error == "log":  # e = log(u): Jacobians D [A B]
                    ec, D = se2.log(u), se2.log_jacobian(u)
                    Dt = np.swapaxes(D, 1, 2)
                    Om, Oe = Dt @ Wc @ D, np.einsum("kab,kb->ka", Dt @ Wc, ec)
                    Om = 0.5 * (Om + np.swapaxes(Om, 1, 2))
                else:
                    ec, Om, Oe = u, Wc, np.einsum("kab,kb->ka", Wc, u)
                M, Jte = _normal_blocks(p_i[c], p_j[c], g.measurements[c], Om, Oe)
            else:
                ec, Wc = e[c], W[c]
                OJ = Wc @ J[c]  # Omega J, (c, k, 6)
                M = np.swapaxes(J[c], 1, 2) @ OJ  # J^T Omega J, (c, 6, 6)
                M += np.swapaxes(M, 1, 2)  # exactly symmetric, as H is
                M *= 0.5
                M = np.moveaxis(M, 0, -1)  # entry-major, (6, 6, c), as the slots
                Jte = np.einsum("kab,ka->bk", OJ, ec)  # J^T Omega e, (6, c)
            np.add.at(data, self._slot_e[:, :, c].ravel(), M.ravel())
            np.add.at(b, self._rows_b_e[:, c].ravel(), Jte.ravel())
            objective += float(np.einsum("ka,kab,kb->", ec, Wc, ec))
        OJp = self._prior_info @ Jp
        Mp = np.swapaxes(Jp, 1, 2) @ OJp
        Mp = 0.5 * (Mp + np.swapaxes(Mp, 1, 2))
        np.add.at(data, self._slot_p.ravel(), Mp.ravel())
        np.add.at(b, self._rows_b_p.ravel(), np.einsum("kab,ka->kb", OJp, ep).ravel())
        objective += float(np.einsum("ka,kab,kb->", ep, self._prior_info, ep))
        H = self._on_pattern(data[: self.nnz])
        b = b[: self.N]
        return H, b, objective

    def damped(self, H, lam):
        """``H + lam I`` (Levenberg's damping), same pattern."""
        data = H.data.copy()
        data[self._diag_slot] += lam
        return self._on_pattern(data)

    def _on_pattern(self, data):
        """The (N, N) CSR matrix with ``data`` on this system's frozen pattern."""
        H = sp.csr_matrix((data, self._indices, self._indptr), shape=(self.N, self.N))
        H.has_canonical_format = True  # sorted, no duplicates by construction: spares the
        return H  # backends an O(nnz) check

    def rounding_floor(self, poses):
        """How far the objective at ``poses`` can move from floating-point rounding alone.

        Each edge's residual ``e`` (this system's own: :meth:`_terms`, weighted by
        :meth:`_edge_weights`) is computed from coordinates of size ``|t_i| + |t_j|``, so it
        carries a rounding error of about ``4 eps (|t_i| + |t_j| + |z_ij| + pi)``; its term
        ``e^T W e`` moves by up to ``2 sqrt(e^T W e) sqrt(tr W)`` times that.  Below this sum no
        step can be told to decrease the objective (:func:`optimize` then stops as converged).
        """
        g = self.graph
        edges = g.edges
        e = self._terms(poses)[0]
        W = self._edge_weights()
        with np.errstate(over="ignore", invalid="ignore"):
            terms = np.einsum("ka,kab,kb->k", e, W, e)
        size = np.abs(poses[:, :2]).sum(axis=1)
        de = 4 * np.finfo(float).eps * (
            size[edges[:, 0]] + size[edges[:, 1]] + np.abs(g.measurements).sum(axis=1) + np.pi
        )
        trace = np.einsum("kaa->k", W)
        return float(np.sum(2 * np.sqrt(np.abs(terms) * trace) * de + trace * de**2))

    def update(self, poses, dx):
        """``x <- x + dx`` on the free poses (lecture notes, "Algorithm" line 5), angles wrapped.

        Parameters
        ----------
        poses : ndarray, shape (n, 3)
        dx : ndarray, shape (N,)

        Returns
        -------
        ndarray, shape (n, 3)
        """
        out = poses.copy()
        out[self.free] += dx.reshape(-1, 3)
        out[self.free, 2] = se2.wrap_angle(out[self.free, 2])
        return out


class RobustSystem(LinearSystem):
    """``H``, ``b`` and the objective of a robust cost ``Σ 2 ρ(r_ij)``, by IRLS.

    The notes' loop unchanged, with a weight per edge: at every linearization point each
    robust edge's information is scaled by its kernel weight ``w(r_ij)``,
    ``r_ij = sqrt(e_ij^T Omega_ij e_ij)`` (:mod:`lagolib.kernels`), so ``b = Σ w_ij J^T Omega e``
    is half the gradient of ``Σ 2 ρ(r_ij)`` and ``H = Σ w_ij J^T Omega J`` its Gauss–Newton
    approximation (Zhang 1997, §4; GTSAM's robust noise models do the same).  Edges outside
    ``robust`` keep ``ρ(r) = r²/2`` (weight 1).  :attr:`scale` holds the weights of the last
    :meth:`assemble`.

    Parameters
    ----------
    graph : PoseGraph
    kernel : lagolib.kernels.Kernel
    robust : ndarray of bool, shape (m,)
        The edges the kernel applies to.
    fixed, prior, error
        As :class:`LinearSystem`.
    """

    def __init__(self, graph, kernel, robust, *, fixed=(), prior=None, error="t2v"):
        check_graph(graph, "RobustSystem")
        super().__init__(graph, fixed=fixed, prior=prior, error=error)
        self.kernel = as_kernel(kernel, where="RobustSystem: kernel")
        self.robust = robust_edge_mask(graph, robust, "RobustSystem")

    def weights(self, terms):
        """``w(r_ij)`` on the robust edges, 1 elsewhere, from ``terms = e^T Omega e``, (m,)."""
        w = np.ones(terms.shape)
        w[self.robust] = self.kernel.weight(np.sqrt(terms[self.robust]))  # IRLS weight w(r)
        return w

    def _cost(self, terms):
        cost = terms.copy()
        cost[self.robust] = self.kernel.cost(terms[self.robust])  # 2 rho(r) on robust edges
        return float(cost.sum())

    def objective(self, poses):
        """``Σ 2 ρ(r_ij)`` over robust edges, ``Σ r_ij²`` over the others, plus the priors."""
        return self._cost(self.edge_chi2(poses)) + self._prior_chi2(poses)

    def assemble(self, poses):
        """:meth:`LinearSystem.assemble` with the weights ``w(r_ij)`` at ``poses``; returns
        ``(H, b, objective)`` with the robust objective."""
        terms = self.edge_chi2(poses)
        with np.errstate(invalid="ignore"):
            self.scale = self.weights(terms)
        H, b, _ = super().assemble(poses)
        return H, b, self._cost(terms) + self._prior_chi2(poses)


#: ``robust_edges=`` choices: the loop closures (odometry trusted, as Vertigo and most robust
#: back ends assume) or every edge.
ROBUST_EDGES = ("closures", "all")


def robust_edge_mask(graph, robust_edges, where="robust_edge_mask"):
    """The edges a robust kernel applies to, ndarray of bool, shape (m,).

    ``"closures"``: every edge that is not odometric (:attr:`PoseGraph.loop_closure`);
    ``"all"``; or a boolean mask / a sequence of edge indices.
    """
    check_graph(graph, where)
    if isinstance(robust_edges, str):
        robust_edges = check_choice(robust_edges, "robust_edges", where, ROBUST_EDGES)
        if robust_edges == "all":
            return np.ones(graph.m, dtype=bool)
        return np.array(graph.loop_closure, dtype=bool)
    a = np.asarray(robust_edges)
    if a.dtype == bool:
        if a.shape != (graph.m,):
            raise OptionError(
                f"{where}: robust_edges as a mask must have shape ({graph.m},) (one per edge); "
                f"got {a.shape}"
            )
        return a.copy()
    if a.ndim != 1 or (a.size and not np.issubdtype(a.dtype, np.integer)):
        raise OptionTypeError(
            f"{where}: robust_edges must be 'closures', 'all', a boolean mask of shape "
            f"({graph.m},) or edge indices; got {type(robust_edges).__name__} of dtype {a.dtype}"
        )
    bad = a[(a < 0) | (a >= graph.m)]
    if bad.size:
        raise OptionError(
            f"{where}: robust_edges names edge index {int(bad[0])}, but the graph has edges "
            f"0..{graph.m - 1}"
        )
    mask = np.zeros(graph.m, dtype=bool)
    mask[a.astype(np.int64)] = True
    return mask


# ----------------------------------------------------------------------------- optimize
@dataclass
class OptimizeResult:
    """What :func:`optimize` returns.

    Attributes
    ----------
    poses : ndarray, shape (n, 3)
        The best iterate (lowest objective) — never worse than any other iterate.
    chi2 : float
        Its χ²: ``sum e^T Omega e`` over all edges, plus the priors' terms — the objective
        minimized, unless a robust kernel was (then see ``cost``).
    chi2_history : list of float
        The objective minimized (``cost``) at the start and after every accepted step.
    step_norms : list of float
        ``max |dx|`` of every accepted step.
    iterations : int
        Accepted steps.
    converged : bool
    reason : str
        Why the iteration stopped.
    method, error : str
    lambdas : list of float
        LM: the damping used for each accepted step.
    step_fractions : list of float
        GN: the fraction of the Gauss–Newton step taken (1, or 1/2, 1/4, ... after halving).
    linear_iterations : list of int
        PCG iterations per solve (``linear_solver="pcg"``).
    timings : dict
        ``"assembly"``, ``"solve"`` and ``"evaluation"``: seconds per accepted step (a rejected
        LM/backtracking trial is charged to the step that follows it); ``"setup"`` (pattern
        and checks) and ``"total"``: seconds.
    graph : PoseGraph
        The input graph with ``poses``.
    cost : float
        The objective minimized at ``poses``: ``chi2`` without a robust kernel; with one,
        ``Σ 2 ρ(r_ij)`` over the robust edges plus ``Σ r_ij²`` over the others and the priors.
    kernel : lagolib.kernels.Kernel or None
        The robust kernel (``robust=``), or None.
    weights : ndarray, shape (m,)
        Each edge's weight on its information at ``poses``: ``w(r_ij)`` on the robust edges,
        1 elsewhere (all 1 without a kernel).
    inlier : ndarray of bool, shape (m,)
        Edges judged right at ``poses``: ``e^T Omega e <= INLIER_THRESHOLD²`` (χ²₃ at 0.999) on
        the robust edges; every other edge is assumed right.  Without a kernel, all True.
    """

    poses: np.ndarray
    chi2: float
    chi2_history: list
    step_norms: list
    iterations: int
    converged: bool
    reason: str
    method: str
    error: str
    graph: PoseGraph
    lambdas: list = field(default_factory=list)
    step_fractions: list = field(default_factory=list)
    linear_iterations: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    cost: float = float("nan")
    kernel: Kernel | None = None
    weights: np.ndarray | None = None
    inlier: np.ndarray | None = None

    def __repr__(self):
        robust = "" if self.kernel is None else f", kernel={self.kernel!r}, cost={self.cost:.10g}"
        return (
            f"OptimizeResult(method={self.method!r}, error={self.error!r}, chi2={self.chi2:.10g}"
            f"{robust}, iterations={self.iterations}, converged={self.converged}, "
            f"reason={self.reason!r})"
        )


METHODS = ("gn", "lm")
LINEAR_SOLVERS = ("cholesky", "pcg")

#: LM gives up when its damping exceeds this (GTSAM's ``lambdaUpperBound`` is 1e5 x larger).
LAMBDA_MAX = 1e10
#: LM's damping never drops below this after a successful step.
LAMBDA_MIN = 1e-12
#: Trials (step halvings, damping increases) per iteration at most.  Neither rule can reach it
#: (halving a float reaches 0 after 1075 steps, ``lambda *= 10`` passes ``LAMBDA_MAX`` from the
#: smallest positive float in 334); it turns any future bug into an error instead of a hang.
_MAX_TRIALS = 4096


class _GaussNewtonSteps:
    """Gauss–Newton step control: the step ``dx`` of ``H dx = -b``, halved while it fails.

    ``H dx = -b`` is solved once per iteration; each halving only rescales ``dx``.  When no
    fraction down to ``2^-max_backtracks`` decreases the objective the iteration stops (and
    :func:`optimize` keeps the best iterate).
    """

    method = "gn"

    def __init__(self, max_backtracks):
        self.max_backtracks = max_backtracks
        self.alpha, self._dx = 1.0, None

    def begin(self):
        """A new iteration: a new ``H`` and ``b``, the full step again."""
        self.alpha, self._dx = 1.0, None

    def step(self, H, b, solve, system):
        """``alpha dx`` with ``H dx = -b`` (lecture notes, "Algorithm" line 4)."""
        if self._dx is None:
            self._dx = solve(H, -b)
        return self.alpha * self._dx

    def reject(self):
        """The trial did not decrease the objective: halve; returns why to give up, or None."""
        self.alpha *= 0.5
        if self.alpha < 0.5**self.max_backtracks:
            return (
                f"the Gauss-Newton step increases the error even when halved "
                f"{self.max_backtracks} times; returned the best iterate (try method='lm')"
            )
        return None

    def accept(self):
        """The trial decreased the objective; returns ``(lambda, fraction)`` to record."""
        return 0.0, self.alpha


class _LevenbergMarquardtDamping:
    """Levenberg–Marquardt step control: solve ``(H + lambda I) dx = -b``.

    ``lambda`` is divided by 10 after a step that decreases the objective (not below
    ``LAMBDA_MIN``) and multiplied by 10 after one that does not or when ``H + lambda I`` cannot
    be factored; above ``LAMBDA_MAX`` LM gives up.  ``lambda`` starts finite and positive
    (:func:`optimize` checks it), so it passes ``LAMBDA_MAX`` after finitely many increases.
    """

    method = "lm"

    def __init__(self, lambda_initial):
        self.lam = float(lambda_initial)  # finite and > 0: optimize checks it

    def begin(self):
        """A new iteration: the damping carries over."""

    def step(self, H, b, solve, system):
        """``dx`` with ``(H + lambda I) dx = -b``, raising ``lambda`` until it can be factored."""
        while True:  # at most log10(LAMBDA_MAX / lambda) + 1 passes
            try:
                return solve(system.damped(H, self.lam), -b)
            except NotPositiveDefiniteError:
                if not self.lam < LAMBDA_MAX:
                    raise
                self.lam *= 10.0

    def reject(self):
        """The trial did not decrease the objective: ``lambda *= 10``; why to give up, or None."""
        self.lam *= 10.0
        if self.lam > LAMBDA_MAX:
            return f"LM damping exceeded {LAMBDA_MAX:.0e} without decreasing the error"
        return None

    def accept(self):
        """The trial decreased the objective: ``lambda /= 10``; returns ``(lambda, fraction)``."""
        used = self.lam
        self.lam = max(self.lam / 10.0, LAMBDA_MIN)
        return used, 1.0


class _LinearSolver:
    """``solve(H, rhs)``: sparse Cholesky (one symbolic analysis, refactored) or PCG.

    ``ordering``, when given, is called once, by the first factorization that needs it:
    :meth:`LinearSystem.ordering`, the pose graph's elimination order; ``auto_rows`` (called only
    for large systems) decides ``backend="auto"``: :meth:`LinearSystem.core_rows`.
    """

    def __init__(self, kind, backend, ordering=None, auto_rows=None):
        self.kind, self.backend = kind, backend
        self._ordering, self._auto_rows = ordering, auto_rows
        self.factor = None
        self.system = None  # the last system bound: later ones may share its pattern
        self.iterations = []  # PCG iterations per solve

    def bind(self, system):
        """Solve ``system``'s matrices: a solver reused for a system with the same unknowns (the
        same size and fixed poses) keeps its factor, whose ordering and symbolic analysis serve
        every matrix of the same pattern (another pattern is analysed anew by
        :meth:`SparseCholesky.refactor`); for other unknowns it starts afresh."""
        key = (system.N, system.fixed.tobytes())
        if self.factor is None or getattr(self, "_key", None) != key:
            self.factor, self._key = None, key
            self._ordering, self._auto_rows = system.ordering, system.core_rows
        self.system = system
        self.iterations = []
        return self

    def __call__(self, H, rhs):
        if self.kind == "pcg":
            out = pcg(H, rhs, preconditioner="block_jacobi", rtol=1e-10, check=False)
            self.iterations.append(out.iterations)
            return out.x
        if self.factor is None:
            self.factor = SparseCholesky(
                H, self.backend, check=False, ordering=self._ordering, auto_rows=self._auto_rows
            )
        else:
            self.factor.refactor(H)
        return self.factor.solve(rhs)


class _Trace:
    """What :func:`optimize` records — χ² history, steps, damping, timings — and prints."""

    def __init__(self, method, verbose):
        self.method, self.verbose = method, verbose
        self.history, self.steps, self.lambdas, self.fractions = [], [], [], []
        self.timings = {"assembly": [], "solve": [], "evaluation": []}
        self._pending = dict.fromkeys(self.timings, 0.0)  # charged to the next accepted step

    @property
    def iterations(self):
        return len(self.steps)

    def timed(self, key, fn, *args):
        """``fn(*args)``, its seconds charged to ``key`` of the next accepted step."""
        t = time.perf_counter()
        out = fn(*args)
        self._pending[key] += time.perf_counter() - t
        return out

    def start(self, chi):
        self.history.append(chi)
        if self.verbose:
            print(f"iter {0:3d}  chi2 {chi:.10g}")

    def accept(self, chi_old, chi, step, lam, alpha, linear_iterations):
        """Record an accepted step; returns its relative decrease of the objective."""
        decrease = (chi_old - chi) / chi_old
        self.history.append(chi)
        self.steps.append(float(np.max(np.abs(step))) if step.size else 0.0)
        self.lambdas.append(lam)
        self.fractions.append(alpha)
        if self.verbose:
            extra = f"  lambda {lam:.1e}" if self.method == "lm" else ""
            extra += f"  alpha {alpha:g}" if alpha != 1.0 else ""
            extra += f"  cg {linear_iterations[-1]}" if linear_iterations else ""
            print(
                f"iter {self.iterations:3d}  chi2 {chi:.10g}  decrease {decrease:.2e}  "
                f"|dx| {self.steps[-1]:.2e}{extra}  assembly {self._pending['assembly'] * 1e3:.1f} "
                f"ms  solve {self._pending['solve'] * 1e3:.1f} ms"
            )
        for key, seconds in self._pending.items():
            self.timings[key].append(seconds)
            self._pending[key] = 0.0
        return decrease


def _stop_after_step(decrease, step_norm, tol, step_tol):
    """``(True, reason)`` when an accepted step meets a convergence test, else None."""
    if decrease < tol:
        return True, f"converged: relative decrease {decrease:.2e} < tol"
    if step_norm < step_tol:
        return True, f"converged: max |dx| {step_norm:.2e} < step_tol"
    return None


def optimize(
    graph,
    initial=None,
    *,
    method="gn",
    error="t2v",
    fixed=None,
    prior=None,
    max_iterations=100,
    tol=1e-10,
    step_tol=1e-10,
    linear_solver="cholesky",
    backend="auto",
    lambda_initial=1e-5,
    max_backtracks=10,
    verbose=False,
    callback=None,
    robust=None,
    robust_edges="closures",
):
    """Minimize ``sum e_ij^T Omega_ij e_ij`` by Gauss–Newton or Levenberg–Marquardt.

    Lecture notes, "Algorithm" — and the skeleton of this function::

        while not converged:
            H, b = build_linear_system(x)
            dx = solve_sparse(H dx = -b)
            x = x + dx

    with two safeguards the notes leave out, each a small step-control object
    (``begin``/``step``/``reject``/``accept``):

    * **Gauss–Newton** (``method="gn"``): when a full step increases the objective, the step is
      halved (up to ``max_backtracks`` times); when no fraction decreases it, the iteration stops
      and returns the best iterate.  Where plain Gauss–Newton converges no step is ever halved,
      so the iterates are the notes' (GTSAM's ``GaussNewtonOptimizer`` instead returns the worse
      estimate).
    * **Levenberg–Marquardt** (``method="lm"``): solves ``(H + lambda I) dx = -b``; ``lambda``
      (first ``lambda_initial``) is divided by 10 after a step that decreases the objective and
      multiplied by 10 after one that does not (the step is then retried without relinearizing)
      — GTSAM's default rule; LM gives up above ``lambda = 1e10``.  Marquardt's
      ``lambda diag(H)`` scaling, tried here, stalled on the ill-conditioned INTEL graph and
      needed 2-3x the iterations on CSAIL, where ``lambda I`` does not.

    Parameters
    ----------
    graph : PoseGraph
    initial : array_like, shape (n, 3), optional
        Initial guess, default ``graph.poses``.
    method : {"gn", "lm"}
    error : {"t2v", "log"}
        Residual definition (:func:`lagolib.graph.residuals`): ``"t2v"`` is the notes' and g2o's,
        ``"log"`` GTSAM's.
    fixed : sequence of int, optional
        Vertex ids held at their initial value.  Default: the vertex with the smallest id, unless
        ``prior`` is given (then none).
    prior : Prior or sequence of Prior, optional
    max_iterations : int
        Accepted steps at most (``>= 0``).
    tol : float
        Converged when an accepted step decreases the objective by less than ``tol`` times its
        value (or a rejected one would change it by less).  Finite, ``>= 0``.
    step_tol : float
        Converged when ``max |dx|`` of an accepted step is below this.  Finite, ``>= 0``.
    linear_solver : {"cholesky", "pcg"}
        Sparse Cholesky (:class:`lagolib.linalg.SparseCholesky`) or block-Jacobi
        preconditioned conjugate gradients (:func:`lagolib.linalg.pcg`, relative residual 1e-10).
    backend : {"auto", "qdldl", "pardiso", "cholmod", "scipy"}
        Cholesky backend.
    lambda_initial : float
        LM's first damping; finite and ``> 0``.
    max_backtracks : int
        GN's step halvings before giving up (``>= 0``).
    verbose : bool
        Print one progress line per iteration.
    callback : callable, optional
        ``callback(iteration, poses)`` after every accepted step (``poses``: the new iterate, a
        copy) — e.g. to record a metric per iteration.
    robust : str or lagolib.kernels.Kernel, optional
        Minimize ``Σ 2 ρ(r_ij)`` instead (:class:`RobustSystem`, IRLS): ``"huber"``,
        ``"cauchy"``, ``"gm"``, ``"tls"``, ``"dcs"`` with the scale
        :data:`lagolib.kernels.INLIER_THRESHOLD`, or a Kernel with its own.  A robust cost has
        local minima a bad start falls into: :func:`lagolib.robust.gnc` does not need a good
        start.
    robust_edges : {"closures", "all"} or array_like
        The edges the kernel applies to (:func:`robust_edge_mask`); default the loop closures.

    Returns
    -------
    OptimizeResult
        With a kernel, ``weights`` and ``inlier`` say what it made of every edge.

    Raises
    ------
    OptionError, OptionTypeError
        An option is out of range or of the wrong type (the message names it).
    GaugeError
        A connected component has no fixed pose and no prior (``H`` would be singular).
    GraphError
        ``initial`` has the wrong shape or a non-finite pose; unknown vertex ids; an edge's (or
        prior's) χ² term or block of ``H`` overflows float64 at the initial guess (the message
        names the edge); ``H`` cannot be factored although the gauge is fixed and the
        information matrices span more than 12 orders of magnitude (the message names the
        weakest and the strongest edge).
    NotPositiveDefiniteError
        ``H`` is numerically not positive definite although the gauge is fixed and the
        information matrices are comparable (a poor linearization point; try ``method="lm"``).

    Examples
    --------
    >>> import lagolib
    >>> ex = lagolib.datasets.example("square_loop")
    >>> res = lagolib.optimize(ex.graph)
    >>> res.converged, res.iterations <= 10, res.chi2 < lagolib.chi2(ex.graph)
    (True, True, True)
    """
    return _optimize(**locals(), solver=None)


def _optimize(
    graph,
    initial,
    *,
    method,
    error,
    fixed,
    prior,
    max_iterations,
    tol,
    step_tol,
    linear_solver,
    backend,
    lambda_initial,
    max_backtracks,
    verbose,
    callback,
    robust,
    robust_edges,
    solver,
):
    """:func:`optimize`, with ``solver`` a :class:`_LinearSolver` to reuse (or None): a caller
    that optimizes the same graph again (:func:`lagolib.certify.solve`) keeps its ordering and
    symbolic analysis."""
    t_start = time.perf_counter()
    where = "optimize"
    check_graph(graph, where)
    method = check_choice(method, "method", where, METHODS)
    error = check_choice(error, "error", where, ERRORS)
    linear_solver = check_choice(linear_solver, "linear_solver", where, LINEAR_SOLVERS)
    backend = check_choice(backend, "backend", where, ("auto",) + BACKENDS)
    max_iterations = check_int(max_iterations, "max_iterations", where, minimum=0)
    tol = check_real(tol, "tol", where, minimum=0.0)
    step_tol = check_real(step_tol, "step_tol", where, minimum=0.0)
    lambda_initial = check_real(lambda_initial, "lambda_initial", where, minimum=0.0, strict=True)
    max_backtracks = check_int(max_backtracks, "max_backtracks", where, minimum=0)
    verbose = check_bool(verbose, "verbose", where)
    callback = check_callback(callback, "callback", where)
    fixed, priors = resolve_gauge(graph, fixed, prior, where=where)
    x = as_graph_poses(graph, initial, "initial", "initial guess")
    like = None if solver is None else solver.system  # a system to share the pattern with
    if robust is None:
        system = LinearSystem(graph, fixed=fixed, prior=priors, error=error, like=like)
    else:
        kern = as_kernel(robust, where=f"{where}: robust")
        mask = robust_edge_mask(graph, robust_edges, where)
        system = RobustSystem(graph, kern, mask, fixed=fixed, prior=priors, error=error)
    if solver is None or solver.kind != linear_solver or solver.backend != backend:
        solver = _LinearSolver(linear_solver, backend)
    solve = solver.bind(system)
    if method == "gn":
        control = _GaussNewtonSteps(max_backtracks)
    else:
        control = _LevenbergMarquardtDamping(lambda_initial)
    trace = _Trace(method, verbose)
    t_setup = time.perf_counter() - t_start

    x, chi, stop = _minimize(
        system, x, control, solve, trace, max_iterations, tol, step_tol, callback
    )
    converged, reason = stop or (False, f"reached max_iterations={max_iterations}")
    cost, weights, inlier = chi, np.ones(graph.m), np.ones(graph.m, dtype=bool)
    if robust is not None:
        terms = system.edge_chi2(x)
        weights = system.weights(terms)
        inlier = ~system.robust | (terms <= INLIER_THRESHOLD**2)
        chi = float(terms.sum()) + system._prior_chi2(x)
    trace.timings["setup"] = t_setup
    trace.timings["total"] = time.perf_counter() - t_start
    return OptimizeResult(
        poses=x,
        chi2=chi,
        cost=cost,
        kernel=None if robust is None else system.kernel,
        weights=weights,
        inlier=inlier,
        chi2_history=trace.history,
        step_norms=trace.steps,
        iterations=trace.iterations,
        converged=converged,
        reason=reason,
        method=method,
        error=error,
        graph=graph.with_poses(x),
        lambdas=trace.lambdas,
        step_fractions=trace.fractions,
        linear_iterations=solve.iterations,
        timings=trace.timings,
    )


def _minimize(
    system, x, control, solve, trace, max_iterations, tol, step_tol, callback, flat_steps=False
):
    """The notes' loop (lecture notes, "Algorithm") for any system with ``assemble``,
    ``objective`` and ``update`` — :func:`optimize`'s χ² and :mod:`lagolib.certify`'s chordal
    cost.  Returns ``(x, objective, stop)``, ``stop`` = ``(converged, reason)`` or None when
    ``max_iterations`` ran out.

    ``flat_steps``: a last step that leaves the objective flat (within ``tol``, where rounding
    decides the sign of the change) is still taken when it shrinks the gradient ``b`` — for
    :func:`lagolib.certify.refine`, whose certificate reads the multipliers off the gradient."""
    with np.errstate(over="ignore", invalid="ignore"):  # reported by _check_finite_system
        H, b, chi = trace.timed("assembly", system.assemble, x)  # build H and b
    _check_finite_system(system, x, H, b, chi)
    trace.start(chi)
    stop = None  # (converged, reason)
    while stop is None and trace.iterations < max_iterations:
        if system.N == 0 or chi == 0.0:
            stop = True, "nothing to optimize" if system.N == 0 else "zero error"
            break
        control.begin()
        for _ in range(_MAX_TRIALS):
            # solve H dx = -b (GN: a fraction of dx; LM: (H + lambda I) dx = -b)
            dx = trace.timed("solve", _solve_step, control, H, b, solve, system, trace)
            x_new = trace.timed("evaluation", system.update, x, dx)  # x <- x + dx
            chi_new = trace.timed("evaluation", system.objective, x_new)
            if chi_new < chi:
                break
            if chi_new - chi <= tol * chi:  # no decrease, but no increase worth a retry
                stop = True, "converged: no step decreases the error by more than tol"
                if flat_steps:
                    b_new = trace.timed("assembly", system.assemble, x_new)[1]
                    if _norm2(b_new) < _norm2(b):  # more stationary: keep it
                        x, chi = x_new, chi_new
                break
            floor = getattr(system, "rounding_floor", None)
            if floor is not None and chi_new - chi <= floor(x):
                stop = True, (
                    "converged: the error is at the rounding level of its evaluation (no step can "
                    "decrease it measurably)"
                )
                break
            give_up = control.reject()  # halve the step / raise the damping
            if give_up is not None:
                stop = False, give_up
                break
        else:  # pragma: no cover - unreachable, see _MAX_TRIALS
            raise ConvergenceError(f"optimize: {_MAX_TRIALS} rejected trials in one iteration")
        if stop is not None:
            break
        lam, alpha = control.accept()
        decrease = trace.accept(chi, chi_new, dx, lam, alpha, solve.iterations)
        x, chi = x_new, chi_new
        if callback is not None:
            callback(trace.iterations, x.copy())
        stop = _stop_after_step(decrease, trace.steps[-1], tol, step_tol)  # converged?
        if stop is None and trace.iterations < max_iterations:
            H, b, _ = trace.timed("assembly", system.assemble, x)  # build H and b
    return x, chi, stop


def _check_finite_system(system, poses, H, b, chi):
    """GraphError naming the edge (or prior) whose χ² term or block of ``H`` overflows float64."""
    if math.isfinite(chi) and np.all(np.isfinite(H.data)) and np.all(np.isfinite(b)):
        return
    g = system.graph
    e, J, ep, Jp = system._terms(poses)
    with np.errstate(all="ignore"):
        parts = [
            (e, J, system._edge_weights(), [g._edge_name(k) for k in range(g.m)]),
            (
                ep,
                Jp,
                system._prior_info,
                [f"the prior on vertex id {p.vertex}" for p in system.priors],
            ),
        ]
        for err, jac, info, names in parts:
            terms = np.einsum("ka,kab,kb->k", err, info, err)
            blocks = np.swapaxes(jac, 1, 2) @ info @ jac
            bad = np.flatnonzero(~np.isfinite(terms) | ~np.all(np.isfinite(blocks), axis=(1, 2)))
            if bad.size:
                k = int(bad[0])
                raise GraphError(
                    f"{names[k]}: at the initial guess its χ² term e^T Omega e = {terms[k]:.3g} or "
                    f"its block J^T Omega J of H overflows float64 (error e = {err[k].tolist()}, "
                    f"largest information entry {np.max(np.abs(info[k])):.3g}; {bad.size} such "
                    "term(s)); give an initial guess closer to the measurements or rescale the "
                    "information",
                    edge=k if info is not system._prior_info else None,
                )
    raise GraphError(
        f"the χ² sum ({chi!r}) or H overflows float64 although every edge's term is finite; "
        "rescale the information matrices"
    )


#: When the information matrices of a graph span more orders of magnitude than this, a failed
#: factorization of ``H`` is blamed on them (GraphError) rather than on the linearization point.
_SPREAD_ORDERS = 12


def _information_spread(system):
    """Why ``H`` may be numerically singular: ``(orders, sentence, edge)`` from the range of the
    information matrices' eigenvalues (``edge``: the strongest edge, or None for a prior)."""
    g = system.graph
    info = np.concatenate([g.information, system._prior_info])
    names = [g._edge_name(k) for k in range(g.m)] + [
        f"the prior on vertex id {p.vertex}" for p in system.priors
    ]
    if info.shape[0] == 0:
        return 0.0, "the graph has no measurements", None
    eig = np.linalg.eigvalsh(info)
    weak, strong = int(np.argmin(eig[:, 0])), int(np.argmax(eig[:, -1]))
    lo, hi = eig[weak, 0], eig[strong, -1]
    orders = math.log10(hi / lo)
    if orders < _SPREAD_ORDERS:
        return (
            orders,
            (
                f"the information matrices span only {orders:.0f} orders of magnitude, so the "
                "linearization point is the likely cause: give a better initial guess"
            ),
            None,
        )
    return (
        orders,
        (
            f"the information matrices span {orders:.0f} orders of magnitude (smallest eigenvalue "
            f"{lo:.3g} on {names[weak]}, largest {hi:.3g} on {names[strong]}) and float64 resolves "
            "about 16: rescale the information or remove the outlier"
        ),
        (strong if strong < g.m else None),
    )


def _solve_step(control, H, b, solve, system, trace):
    """``control.step``, with a factorization failure explained in the user's terms."""
    try:
        return control.step(H, b, solve, system)
    except NotPositiveDefiniteError as exc:
        orders, why, edge = _information_spread(system)
        message = (
            f"iteration {trace.iterations + 1}: H is not positive definite although every "
            f"component has a gauge ({exc}); {why}"
        )
        if orders >= _SPREAD_ORDERS:  # the input is to blame
            raise GraphError(message, edge=edge) from None
        raise NotPositiveDefiniteError(
            message + ("; try method='lm'" if control.method == "gn" else ""), pivot=exc.pivot
        ) from None


class WeightedLeastSquares:
    """Gauss–Newton on ``Σ w_ij e_ij^T Omega_ij e_ij`` with weights that change between solves.

    Graduated non-convexity's variable update (:func:`lagolib.robust.gnc`): one
    :class:`LinearSystem`, one elimination ordering and one symbolic factorization serve every
    set of weights (a weight of 0 removes an edge's term but not its place in the pattern).

    Parameters
    ----------
    graph : PoseGraph
    fixed, prior, error, backend
        As :func:`optimize` (the gauge: the first vertex fixed unless ``prior`` is given).
    where : str
        The caller's name, for messages.
    """

    def __init__(self, graph, *, fixed=None, prior=None, error="t2v", backend="auto",
                 where="WeightedLeastSquares"):
        check_graph(graph, where)
        error = check_choice(error, "error", where, ERRORS)
        backend = check_choice(backend, "backend", where, ("auto",) + BACKENDS)
        fixed, priors = resolve_gauge(graph, fixed, prior, where=where)
        self.graph = graph
        self.system = LinearSystem(graph, fixed=fixed, prior=priors, error=error)
        self._solver = _LinearSolver("cholesky", backend, self.system.ordering,
                                     self.system.core_rows)
        self.iterations = 0  # Gauss–Newton steps over all solves

    def edge_chi2(self, poses):
        """Every edge's ``e^T Omega e`` at ``poses`` (unweighted), shape (m,)."""
        return self.system.edge_chi2(poses)

    def solve(self, poses, weights, *, max_iterations=100, tol=1e-10, step_tol=1e-10):
        """Minimize the weighted χ² from ``poses`` (shape (n, 3)) with ``weights`` (shape (m,),
        ``>= 0``); returns ``(poses, weighted objective, stop reason)``."""
        self.system.scale = np.asarray(weights, dtype=float)
        trace = _Trace("gn", False)
        x, chi, stop = _minimize(self.system, poses, _GaussNewtonSteps(10), self._solver, trace,
                                 max_iterations, tol, step_tol, None)
        self.iterations += trace.iterations
        return x, chi, (stop or (False, f"reached max_iterations={max_iterations}"))[1]
