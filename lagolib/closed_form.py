"""Lodi Rizzini's closed-form analysis of a constraint network, numerically and at scale.

Source: D. Lodi Rizzini, "A Closed-Form Constraint Networks Solver for Maximum Likelihood
Mapping"; equation numbers below are that paper's.

Poses have four parameters ``p_i = [x_i, y_i, c_i, s_i]`` with ``c_i² + s_i² = 1`` (eq. 1), every
constraint weighs its error with ``Ω_ij = I_4`` (§II-B), and the stationary points of

    χ²(p) = Σ_<i,j> |f_ij(p) − δ̂_ij|²                                          (eq. 2–6)

split into two sets of equations:

* **position equations** (§III-A, eq. 16–30): linear in the positions once the angles are known,
  ``d = P Q [1 0 t^T]^T`` — the displacements ``d_ij`` are the orthogonal projection of the
  rotated measurements ``l_ij`` (eq. 18) onto the displacements a configuration can have;
* **angular equations** (§III-B, eq. 31–43): with ``v = [α_1, β_1, …] = (L + M P Q)[1 0 t^T]^T``
  (eq. 36), stationarity is ``v = R t`` with ``R = diag(ρ_1, −ρ_1, …)`` (eq. 44–45) and
  ``ρ_i`` such that ``c_i² + s_i² = 1``.

The paper leaves the last step numeric.  :func:`solve_orthogonality` solves it by Newton's method
on ``(t, ρ)`` together — with the positions kept as unknowns so that every matrix stays sparse —
and raises :class:`~lagolib.errors.ConvergenceError` rather than return a point that does not
satisfy the equations.  :func:`optimize_sincos` (Gauss–Newton on the same χ² in ``(x, y, θ)``) is
the independent check.

What the paper requires of the network (§III) is checked by :func:`network`: the vertices,
sorted by id, are ``p_0, p_1, …, p_n``; every spanning constraint ``<k−1, k>`` is present; every
constraint is stored from the smaller index.  ``p_0`` is the origin.

The symbolic counterpart for small networks (the §IV-A example) is
:func:`lagolib.symbolic.sincos_network`; the tests check that both build the same matrices.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from . import se2
from .checks import check_bool, check_choice, check_int, check_real
from .errors import ConvergenceError, GraphError, OptionError, OptionTypeError
from .graph import PoseGraph, _numeric, as_graph_poses, check_graph, vertex_row
from .lago import lago
from .linalg import SparseCholesky, solve_spd

__all__ = [
    "ClosedFormNetwork",
    "network",
    "sincos_poses",
    "sincos_residuals",
    "sincos_chi2",
    "sincos_jacobians",
    "sincos_gradient",
    "SincosOptimum",
    "optimize_sincos",
    "positions_from_orientations",
    "ClosedFormResult",
    "solve_orthogonality",
    "closed_form",
]

#: Above this many edges, :meth:`ClosedFormNetwork.P` and :meth:`ClosedFormNetwork.A_b` refuse to
#: form their dense matrices.
DENSE_LIMIT = 3000


def _blocks(row_block, col_block, blocks, shape):
    """Sparse matrix with the 2×2 ``blocks[k]`` at block position ``(row_block[k], col_block[k])``."""
    r = 2 * np.asarray(row_block)[:, None, None] + np.arange(2)[None, :, None]
    c = 2 * np.asarray(col_block)[:, None, None] + np.arange(2)[None, None, :]
    r, c = np.broadcast_arrays(r, c)
    return sp.csr_matrix((np.asarray(blocks, float).ravel(), (r.ravel(), c.ravel())), shape=shape)


def _block_array(a, b, c, d):
    """``[[a, b], [c, d]]`` per edge, shape (e, 2, 2)."""
    return np.stack([np.stack([a, b], -1), np.stack([c, d], -1)], -2)


@dataclass(eq=False)
class ClosedFormNetwork:
    """The matrices of Lodi Rizzini §III for one graph, sparse.

    Nodes are numbered ``0 … n`` by vertex id (``p_0`` is the origin), edges are sorted by eq.
    (20): the ``n`` spanning constraints ``<k−1, k>`` first, then the ``n_L = e − n`` loop ones.

    Attributes
    ----------
    graph : PoseGraph
    n, e, n_L : int
        Poses besides ``p_0``; constraints; loop constraints.
    vertex : ndarray of int, shape (n + 1,)
        Graph row of node ``k``.
    edge : ndarray of int, shape (e,)
        Graph edge index of the ``h``-th constraint in eq. (20)'s order.
    i, j : ndarray of int, shape (e,)
        Node indices of the constraints (``i < j``).
    delta : ndarray, shape (e, 4)
        ``δ̂_ij = [x̂, ŷ, ĉ, ŝ]`` with ``ĉ = cos θ̂``, ``ŝ = sin θ̂``.
    N_out, N_in, N : scipy.sparse, shape (n + 1, e)
        Output and input incidence matrices and ``N = N_in − N_out`` (§III).
    D, Q : scipy.sparse, shapes (2e, 2) and (2e, 2(n + 1))
        eq. (30) and (29): ``Q [1 0 t^T]^T`` stacks the ``l_ij`` of eq. (18).
    D_perp, M : scipy.sparse, shapes (2, 2e) and (2n, 2e)
        eq. (38) and (37).
    C_in, C_out : scipy.sparse, shape (2, 2e)
        eq. (42) and (43).
    L_in, L_out, L : scipy.sparse, shapes (2n, 2e), (2n, 2e), (2n, 2(n + 1))
        eq. (40), (41) and (39).
    """

    graph: PoseGraph
    n: int
    e: int
    vertex: np.ndarray
    edge: np.ndarray
    i: np.ndarray
    j: np.ndarray
    delta: np.ndarray
    N_out: sp.csr_matrix = field(repr=False)
    N_in: sp.csr_matrix = field(repr=False)
    N: sp.csr_matrix = field(repr=False)
    D: sp.csr_matrix = field(repr=False)
    Q: sp.csr_matrix = field(repr=False)
    D_perp: sp.csr_matrix = field(repr=False)
    M: sp.csr_matrix = field(repr=False)
    C_in: sp.csr_matrix = field(repr=False)
    C_out: sp.csr_matrix = field(repr=False)
    L_in: sp.csr_matrix = field(repr=False)
    L_out: sp.csr_matrix = field(repr=False)
    L: sp.csr_matrix = field(repr=False)

    @property
    def n_L(self):
        return self.e - self.n

    # ----------------------------------------------------------------- position equations
    @cached_property
    def U(self):
        """The loop-edge matrix (eq. 21), shape (n_L, n): ``u_rk = 1`` when ``g_r < k <= h_r``.

        Row ``r`` marks the spanning constraints on the path of loop constraint ``<g_r, h_r>``
        (eq. 19); it holds ``h_r − g_r`` ones, so ``U`` is only sparse when the loops are short.
        """
        g, h = self.i[self.n :], self.j[self.n :]
        lengths = h - g
        rows = np.repeat(np.arange(self.n_L), lengths)
        cols = np.repeat(g, lengths) + _ranges(lengths)  # spanning k = g+1 … h is column k − 1
        return sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(self.n_L, self.n))

    @property
    def U_bar(self):
        """``Ū = U ⊗ I_2`` (§III-A), shape (2 n_L, 2n)."""
        return sp.kron(self.U, sp.identity(2), format="csr")

    def P(self):
        """``P = [[P_SS, P_SL], [P_LS, P_LL]]`` from ``G`` (eq. 23–28), dense, shape (2e, 2e).

        ``G = (I + Ū Ū^T)^-1`` (eq. 24) is inverted densely, as in the paper; for teaching and
        for the tests.  :meth:`displacements` applies ``P`` without forming it.

        Raises
        ------
        ValueError
            If the network has more than ``DENSE_LIMIT`` edges.
        """
        self._check_dense("P")
        Ub = self.U_bar.toarray()
        G = np.linalg.inv(np.eye(2 * self.n_L) + Ub @ Ub.T)  # eq. (24)
        P_SS = np.eye(2 * self.n) - Ub.T @ G @ Ub  # eq. (25)
        P_SL = Ub.T - Ub.T @ G @ Ub @ Ub.T  # eq. (26)
        P_LS = G @ Ub  # eq. (27)
        P_LL = G @ Ub @ Ub.T  # eq. (28)
        return np.block([[P_SS, P_SL], [P_LS, P_LL]])

    def _check_dense(self, what):
        if self.e > DENSE_LIMIT:
            raise ValueError(
                f"{what} is dense ({2 * self.e} x {2 * self.e} here); it is formed only for networks "
                f"of at most {DENSE_LIMIT} edges — use displacements() / v() instead"
            )

    @cached_property
    def _N0(self):
        return self.N[1:, :].tocsr()

    @cached_property
    def _laplacian(self):
        """Factor of ``K = N_0 N_0^T`` (n × n): the position equations in node positions."""
        return SparseCholesky((self._N0 @ self._N0.T).tocsc())

    def t1(self, t):
        """``[1, 0, t^T]^T``: ``t`` with ``c_0 = 1``, ``s_0 = 0`` prepended, shape (2n + 2,)."""
        t = np.asarray(t, dtype=float)
        if t.shape != (2 * self.n,):
            raise ValueError(f"t must have shape ({2 * self.n},); got {t.shape}")
        return np.concatenate([[1.0, 0.0], t])

    def l_terms(self, t):
        """``l_ij = R(θ_i) [x̂_ij, ŷ_ij]^T`` (eq. 18) for every constraint, shape (e, 2)."""
        return (self.Q @ self.t1(t)).reshape(self.e, 2)

    def positions(self, t):
        """Node positions solving the position equations (eq. 16), shape (n + 1, 2); ``d_0 = 0``.

        With ``d = N_0^T X`` the equations ``N_0 (d − l) = 0`` become ``N_0 N_0^T X = N_0 l``: the
        Laplacian system the paper mentions (§III-A), solved by sparse Cholesky.
        """
        X = self._laplacian.solve(self._N0 @ self.l_terms(t))
        return np.vstack([np.zeros((1, 2)), X])

    def displacements(self, t):
        """``d = P Q [1 0 t^T]^T`` (eq. 23, 29), shape (e, 2), without forming ``P``."""
        X = self.positions(t)
        return X[self.j] - X[self.i]

    def v(self, t):
        """``v = [α_1, β_1, …, α_n, β_n] = (L + M P Q)[1 0 t^T]^T`` (eq. 34–36), shape (2n,)."""
        return self.L @ self.t1(t) + self.M @ self.displacements(t).ravel()

    def A_b(self):
        """``b`` (first column) and ``A`` (columns 3 to 2n + 2) of ``L + M P Q`` (eq. 36, 44).

        Dense: ``P`` couples every constraint of a loop.  For networks of at most
        ``DENSE_LIMIT`` edges; :func:`solve_orthogonality` does not need them.

        Returns
        -------
        A : ndarray, shape (2n, 2n)
        b : ndarray, shape (2n,)
        """
        self._check_dense("A")
        V = self.L.toarray() + self.M @ (self.P() @ self.Q.toarray())  # eq. (36)
        return V[:, 2:], V[:, 0]

    def t_of(self, theta):
        """``t = [c_1, s_1, …, c_n, s_n]`` of the node orientations ``theta`` (shape (n + 1,)),
        measured from ``θ_0`` so that ``p_0`` is the origin."""
        theta = np.asarray(theta, dtype=float)
        rel = theta[1:] - theta[0]
        return np.column_stack([np.cos(rel), np.sin(rel)]).ravel()


def _ranges(lengths):
    """``concatenate([arange(k) for k in lengths])`` without a Python loop."""
    lengths = np.asarray(lengths, dtype=np.int64)
    total = int(lengths.sum())
    starts = np.repeat(np.cumsum(lengths) - lengths, lengths)
    return np.arange(total) - starts


def network(graph):
    """Check Lodi Rizzini's assumptions and build the matrices of §III (:class:`ClosedFormNetwork`).

    Parameters
    ----------
    graph : PoseGraph
        Vertices sorted by id are ``p_0 … p_n``; the information matrices are not used
        (``Ω_ij = I_4``, §II-B).

    Returns
    -------
    ClosedFormNetwork

    Raises
    ------
    GraphError
        If the graph has fewer than two vertices, a constraint is stored from the larger id
        (or is a self-loop), or a spanning constraint ``<k−1, k>`` is missing; the message names
        the edge or the vertex ids.

    Examples
    --------
    >>> from lagolib import datasets
    >>> net = network(datasets.example("square_loop").graph)
    >>> net.n, net.e, net.n_L
    (159, 279, 120)
    """
    check_graph(graph, "network")
    if graph.n < 2:
        raise GraphError("the closed form needs at least two poses (p_0 and one more)")
    rank = graph.order  # node index of every graph row
    vertex = np.argsort(graph.ids, kind="stable")  # graph row of every node
    i, j = rank[graph.edges[:, 0]], rank[graph.edges[:, 1]]
    backward = np.flatnonzero(i >= j)
    if backward.size:
        k = int(backward[0])
        a, b = graph.ids[graph.edges[k]]
        raise GraphError(
            f"{graph._edge_name(k)} is stored from the larger id ({backward.size} such edge(s)); "
            "the closed form (Lodi Rizzini §III) needs every constraint <i, j> with i < j: store "
            f"it as {b} -> {a} with the inverse measurement (lagolib.se2.inverse) — with "
            "Omega = I this changes the cost, as §III notes",
            edge=k,
        )
    n = graph.n - 1
    key = i + (n + 1) * (j - i)  # eq. (20)
    try:  # the first stored <k-1, k> of each pair is the spanning constraint; copies are loops
        spanning, _ = graph.odometric_chain()
    except GraphError as exc:
        raise GraphError(
            f"{exc}; the closed form (Lodi Rizzini §III) needs every spanning constraint <k-1, k>, "
            "as a robot's odometry gives"
        ) from None
    is_loop = np.ones(graph.m, dtype=bool)
    is_loop[spanning] = False
    loops = np.flatnonzero(is_loop)
    loops = loops[np.lexsort((loops, key[loops]))]
    edge = np.concatenate([spanning, loops])
    i, j = i[edge], j[edge]
    e = edge.size
    z = graph.measurements[edge]
    xh, yh, ch, sh = z[:, 0], z[:, 1], np.cos(z[:, 2]), np.sin(z[:, 2])
    delta = np.column_stack([xh, yh, ch, sh])

    h = np.arange(e)
    N_out = sp.csr_matrix((np.ones(e), (i, h)), shape=(n + 1, e))
    N_in = sp.csr_matrix((np.ones(e), (j, h)), shape=(n + 1, e))
    D_blocks = _block_array(xh, -yh, yh, xh)  # l_ij = D_h [c_i, s_i]^T (eq. 18, 30)
    D = _blocks(h, np.zeros(e, int), D_blocks, (2 * e, 2))  # eq. (30)
    Q = _blocks(h, i, D_blocks, (2 * e, 2 * (n + 1)))  # eq. (29)
    Dp_blocks = _block_array(xh, yh, yh, -xh)
    D_perp = _blocks(np.zeros(e, int), h, Dp_blocks, (2, 2 * e))  # eq. (38)
    out = i >= 1  # N_0: the rows of p_0 are dropped
    M = _blocks(i[out] - 1, h[out], Dp_blocks[out], (2 * n, 2 * e))  # eq. (37)
    Cin_blocks = _block_array(ch, -sh, -sh, -ch)
    Cout_blocks = _block_array(ch, sh, sh, -ch)
    C_in = _blocks(np.zeros(e, int), h, Cin_blocks, (2, 2 * e))  # eq. (42)
    C_out = _blocks(np.zeros(e, int), h, Cout_blocks, (2, 2 * e))  # eq. (43)
    L_in = _blocks(j - 1, h, Cin_blocks, (2 * n, 2 * e))  # eq. (40)
    L_out = _blocks(i[out] - 1, h[out], Cout_blocks[out], (2 * n, 2 * e))  # eq. (41)
    I2 = sp.identity(2)
    L = (L_in @ sp.kron(N_out.T, I2) + L_out @ sp.kron(N_in.T, I2)).tocsr()  # eq. (39)
    return ClosedFormNetwork(
        graph, n, e, vertex, edge, i, j, delta,
        N_out, N_in, (N_in - N_out).tocsr(), D, Q, D_perp, M, C_in, C_out, L_in, L_out, L,
    )  # fmt: skip


# ------------------------------------------------------------------------------ the sin/cos χ²
def sincos_poses(poses):
    """``[x, y, θ]`` → ``[x, y, cos θ, sin θ]`` (Lodi Rizzini eq. 1), shape (..., 4)."""
    p = _numeric(poses, "sincos_poses: poses", float)
    if p.ndim == 0 or p.shape[-1] != 3:
        raise OptionError(f"sincos_poses: poses must have shape (..., 3); got {p.shape}")
    return np.concatenate([p[..., :2], np.cos(p[..., 2:3]), np.sin(p[..., 2:3])], axis=-1)


def sincos_residuals(graph, poses=None):
    """``e_ij = f_ij(p) − δ̂_ij`` for every edge (Lodi Rizzini eq. 2–3), shape (m, 4).

    ``f_ij = [R_i^T (t_j − t_i); c_j c_i + s_j s_i; s_j c_i − c_j s_i]`` and
    ``δ̂_ij = [x̂, ŷ, cos θ̂, sin θ̂]`` of the edge's measurement.

    Never NaN: where ``t_j − t_i`` overflows float64 (positions near ±1e308 on opposite sides)
    the row is computed again with its translations scaled by a power of two, as
    :func:`lagolib.graph.edge_errors` does, and a component beyond float64 is ``±inf``.
    """
    return _sincos_residuals(graph, poses, "sincos_residuals")


def _sincos_residuals(graph, poses, where):
    check_graph(graph, where)
    p = as_graph_poses(graph, poses)
    a, b, z = p[graph.edges[:, 0]], p[graph.edges[:, 1]], graph.measurements
    with np.errstate(over="ignore", invalid="ignore"):  # overflow is redone below
        e = _sincos_errors(a, b, z)
    if not np.isfinite(e).all():  # rare: scale the translations of those rows (exact)
        bad = ~np.all(np.isfinite(e), axis=1)
        a, b, z = a[bad], b[bad], z[bad]
        big = np.max(np.abs(np.concatenate([a[:, :2], b[:, :2], z[:, :2]], axis=1)), axis=1)
        k = np.frexp(big)[1][:, None]
        scaled = [np.column_stack([np.ldexp(q[:, :2], -k), q[:, 2]]) for q in (a, b, z)]
        es = _sincos_errors(*scaled)
        with np.errstate(over="ignore"):
            es[:, :2] = np.ldexp(es[:, :2], k)  # ±inf beyond float64, never NaN
        e[bad] = es
    return e


def _sincos_errors(a, b, z):
    """Eq. (2)–(3) for poses ``a``, ``b`` (``(x, y, θ)``, shape (m, 3)) and measurements ``z``."""
    pi, pj = sincos_poses(a), sincos_poses(b)
    ci, si, cj, sj = pi[:, 2], pi[:, 3], pj[:, 2], pj[:, 3]
    dx, dy = pj[:, 0] - pi[:, 0], pj[:, 1] - pi[:, 1]
    f = np.column_stack(
        [dx * ci + dy * si, -dx * si + dy * ci, cj * ci + sj * si, sj * ci - cj * si]
    )  # eq. (2)
    return f - np.column_stack([z[:, :2], np.cos(z[:, 2]), np.sin(z[:, 2])])  # eq. (3)


def sincos_chi2(graph, poses=None, *, per_edge=False):
    """``χ² = Σ e_ij^T e_ij`` (Lodi Rizzini eq. 6 with ``Ω_ij = I_4``).

    Returns
    -------
    float, or ndarray of shape (m,) with ``per_edge=True``
    """
    per_edge = check_bool(per_edge, "per_edge", "sincos_chi2")
    e = _sincos_residuals(graph, poses, "sincos_chi2")
    with np.errstate(over="ignore"):  # a term beyond float64 is inf (a sum of squares: never NaN)
        per = np.einsum("ka,ka->k", e, e)
        return per if per_edge else float(per.sum())


def sincos_jacobians(p_i, p_j):
    """``∂e_ij/∂p_i`` (Lodi Rizzini eq. 13) and ``∂e_ij/∂p_j`` (eq. 12) for 4-parameter poses.

    Parameters
    ----------
    p_i, p_j : array_like, shape (m, 4)
        ``[x, y, c, s]`` of the two ends of each constraint.

    Returns
    -------
    J_i, J_j : ndarray, shape (m, 4, 4)
    """
    p_i = np.atleast_2d(_numeric(p_i, "sincos_jacobians: p_i", float))
    p_j = np.atleast_2d(_numeric(p_j, "sincos_jacobians: p_j", float))
    if p_i.ndim != 2 or p_i.shape[1] != 4 or p_j.shape != p_i.shape:
        raise OptionError(
            "sincos_jacobians: p_i and p_j must be 4-parameter poses [x, y, c, s] of the same "
            f"shape (m, 4); got {p_i.shape} and {p_j.shape}"
        )
    x_i, y_i, c_i, s_i = p_i.T
    x_j, y_j, c_j, s_j = p_j.T
    dx, dy = x_j - x_i, y_j - y_i
    zero = np.zeros_like(dx)
    J_i = np.stack(
        [
            np.stack([-c_i, -s_i, dx, dy], -1),
            np.stack([s_i, -c_i, dy, -dx], -1),
            np.stack([zero, zero, c_j, s_j], -1),
            np.stack([zero, zero, s_j, -c_j], -1),
        ],
        axis=-2,
    )  # eq. (13)
    J_j = np.stack(
        [
            np.stack([c_i, s_i, zero, zero], -1),
            np.stack([-s_i, c_i, zero, zero], -1),
            np.stack([zero, zero, c_i, s_i], -1),
            np.stack([zero, zero, -s_i, c_i], -1),
        ],
        axis=-2,
    )  # eq. (12)
    return J_i, J_j


def _theta_jacobians(graph, poses, where):
    """``e`` and its Jacobians in ``(x, y, θ)``: eq. (12)–(13) times ``∂p/∂(x, y, θ)``."""
    p = sincos_poses(poses)
    pi, pj = p[graph.edges[:, 0]], p[graph.edges[:, 1]]
    with np.errstate(over="ignore", invalid="ignore"):  # overflow is refused below
        J_i, J_j = sincos_jacobians(pi, pj)

    def chain(J, q):  # ∂[x, y, c, s]/∂[x, y, θ] = [[1, 0, 0], [0, 1, 0], [0, 0, −s], [0, 0, c]]
        d_theta = -q[:, 3, None] * J[..., 2] + q[:, 2, None] * J[..., 3]
        return np.concatenate([J[..., :2], d_theta[..., None]], axis=-1)

    e = _sincos_residuals(graph, poses, where)
    with np.errstate(over="ignore", invalid="ignore"):
        J_i, J_j = chain(J_i, pi), chain(J_j, pj)
    if not (np.isfinite(e).all() and np.isfinite(J_i).all()):  # J_j holds only sines and cosines
        _refuse_overflow(graph, poses, e, J_i, where)
    return e, J_i, J_j


def _refuse_overflow(graph, poses, e, J_i, where):
    """GraphError naming the first edge whose residual or Jacobian is beyond float64."""
    bad = ~(np.all(np.isfinite(e), axis=1) & np.all(np.isfinite(J_i), axis=(1, 2)))
    k = int(np.flatnonzero(bad)[0])
    i, j = graph.edges[k]
    raise GraphError(
        f"{where}: at these poses {graph._edge_name(k)} has a residual or a Jacobian beyond "
        f"float64 (poses {poses[i].tolist()} and {poses[j].tolist()}): positions ±1.8e308 "
        "apart; give poses closer together (sincos_chi2 evaluates such poses: inf)",
        edge=k,
    )


def sincos_gradient(graph, poses=None):
    """``∂χ²/∂(x, y, θ)`` of every pose (Lodi Rizzini eq. 10–11 with ``Ω = I_4``), shape (n, 3).

    The factor 2 is kept (this is the gradient of :func:`sincos_chi2`).  In ``(x, y, θ)`` the
    constraint ``c² + s² = 1`` holds by construction, so a stationary point of eq. (7) is a zero
    of this gradient.
    """
    where = "sincos_gradient"
    check_graph(graph, where)
    poses = as_graph_poses(graph, poses)
    e, Ji, Jj = _theta_jacobians(graph, poses, where)
    g = np.zeros((graph.n, 3))
    with np.errstate(over="ignore", invalid="ignore"):  # overflow is refused below
        np.add.at(g, graph.edges[:, 0], 2 * np.einsum("kab,ka->kb", Ji, e))
        np.add.at(g, graph.edges[:, 1], 2 * np.einsum("kab,ka->kb", Jj, e))
    bad = np.flatnonzero(~np.all(np.isfinite(g), axis=1))
    if bad.size:
        v = int(bad[0])
        raise GraphError(
            f"{where}: the gradient of vertex id {graph.ids[v]} overflows float64 (residuals times "
            "distances beyond 1.8e308); at these poses only sincos_chi2 is defined (inf)",
            vertex=v,
        )
    return g


@dataclass(frozen=True)
class SincosOptimum:
    """Result of :func:`optimize_sincos`.

    Attributes
    ----------
    poses : ndarray, shape (n, 3)
    chi2 : float
        :func:`sincos_chi2` at ``poses``.
    iterations : int
    converged : bool
    history : list of float
        χ² after each accepted step (first entry: the initial χ²).
    """

    poses: np.ndarray
    chi2: float
    iterations: int
    converged: bool
    history: list


def optimize_sincos(graph, initial=None, *, fixed=None, max_iterations=100, tol=1e-14):
    """Gauss–Newton on Lodi Rizzini's χ² (eq. 6, ``Ω_ij = I_4``) in ``(x, y, θ)``.

    The independent check of :func:`solve_orthogonality`: same cost, other unknowns (angles
    instead of ``(c, s, ρ)``), other algorithm (lecture notes' Gauss–Newton with the Jacobians
    of eq. 12–13, a step halved when it does not decrease χ²).

    Parameters
    ----------
    graph : PoseGraph
    initial : array_like, shape (n, 3), optional
        Default ``graph.poses``.
    fixed : int, optional
        Vertex id held at its initial pose (default: the smallest id).
    max_iterations : int
    tol : float
        Converged when a step decreases χ² by less than ``tol`` times its value.

    Returns
    -------
    SincosOptimum
    """
    where = "optimize_sincos"
    check_graph(graph, where)
    max_iterations = check_int(max_iterations, "max_iterations", where, minimum=0)
    tol = check_real(tol, "tol", where, minimum=0.0)
    x = as_graph_poses(graph, initial, "initial")
    n = graph.n
    if n == 0:
        raise GraphError(f"{where}: the graph has no vertices")
    if fixed is None:
        fixed_row = int(np.argmin(graph.ids))
    else:
        fixed_row = vertex_row(graph, fixed, f"{where}: fixed")
    free = np.delete(np.arange(n), fixed_row)
    col_of = np.full(n, -1)
    col_of[free] = np.arange(free.size)
    m = graph.m
    rows = np.repeat(np.arange(4 * m).reshape(m, 4, 1), 3, axis=2)
    chi = sincos_chi2(graph, x)
    history, converged, iterations = [chi], False, 0
    while iterations < max_iterations:
        iterations += 1
        e, Ji, Jj = _theta_jacobians(graph, x, where)
        data, r, c = [], [], []
        for J, end in ((Ji, graph.edges[:, 0]), (Jj, graph.edges[:, 1])):
            keep = col_of[end] >= 0
            cols = 3 * col_of[end][keep, None, None] + np.arange(3)[None, None, :]
            cols = np.broadcast_to(cols, (keep.sum(), 4, 3))
            data.append(J[keep].ravel())
            r.append(rows[keep].ravel())
            c.append(cols.ravel())
        J = sp.csr_matrix(
            (np.concatenate(data), (np.concatenate(r), np.concatenate(c))),
            shape=(4 * m, 3 * free.size),
        )
        with np.errstate(over="ignore", invalid="ignore"):
            H, b = (J.T @ J).tocsc(), J.T @ e.ravel()
        if not (np.isfinite(H.data).all() and np.isfinite(b).all()):
            raise GraphError(
                f"{where}: the normal equations overflow float64 at iteration {iterations} (the "
                "poses are too far apart: squared distances beyond 1.8e308); give poses closer "
                "together"
            )
        dx = solve_spd(H, -b).reshape(-1, 3)
        step = 1.0
        for _ in range(30):
            trial = x.copy()
            trial[free] += step * dx
            new = sincos_chi2(graph, trial)
            if new <= chi:
                break
            step /= 2
        else:
            converged = True  # no step decreases χ² any more: at the optimum to round-off
            break
        decrease = chi - new
        x, chi = trial, new
        history.append(chi)
        if decrease <= tol * max(chi, 1e-300) or np.max(np.abs(step * dx)) < 1e-13:
            converged = True
            break
    x[:, 2] = se2.wrap_angle(x[:, 2])
    return SincosOptimum(x, chi, iterations, converged, history)


# ------------------------------------------------------------------ the closed-form solution
def positions_from_orientations(graph, theta, origin=(0.0, 0.0)):
    """Positions from the position equations with the orientations held at ``theta``.

    Lodi Rizzini §III-A (eq. 16–30), the computation of Fig. 2: ``d = P Q [1 0 t^T]^T`` with
    ``t`` from ``theta`` — the positions minimizing ``Σ |d_ij − R(θ_i) t̂_ij|²``.  This is
    Carlone et al.'s eq. (14) with the same weight on every edge.

    Parameters
    ----------
    graph : PoseGraph or ClosedFormNetwork
        A graph satisfying :func:`network`'s assumptions, or its network (built once).
    theta : array_like, shape (graph.n,)
        Orientation of every vertex (graph rows), e.g. an optimizer's.
    origin : array_like, shape (2,)
        Position of ``p_0`` (the vertex with the smallest id).

    Returns
    -------
    ndarray, shape (graph.n, 2)
    """
    where = "positions_from_orientations"
    if not isinstance(graph, ClosedFormNetwork):
        check_graph(graph, where)
    net = graph if isinstance(graph, ClosedFormNetwork) else network(graph)
    theta = _numeric(theta, f"{where}: theta", float)
    if theta.shape != (net.graph.n,):
        raise GraphError(f"{where}: theta must have shape ({net.graph.n},); got {theta.shape}")
    bad = np.flatnonzero(~np.isfinite(theta))
    if bad.size:
        raise GraphError(
            f"{where}: theta of vertex id {net.graph.ids[bad[0]]} is not finite ({theta[bad[0]]})"
        )
    origin = _numeric(origin, f"{where}: origin", float)
    if origin.shape != (2,) or not np.all(np.isfinite(origin)):
        raise OptionError(f"{where}: origin must be 2 finite numbers; got {origin.tolist()}")
    theta_nodes = theta[net.vertex]
    local = net.positions(net.t_of(theta_nodes))  # in p_0's frame
    world = local @ se2.rotation(theta_nodes[0]).T + origin
    out = np.empty((net.graph.n, 2))
    out[net.vertex] = world
    return out


@dataclass(eq=False)
class ClosedFormResult:
    """A solution of the orthogonality condition (Lodi Rizzini eq. 44–45).

    Attributes
    ----------
    poses : ndarray, shape (graph.n, 3)
        In graph rows; ``p_0`` (smallest id) is the origin.
    t : ndarray, shape (2n,)
        ``[c_1, s_1, …, c_n, s_n]``.
    rho : ndarray, shape (n,)
        ``ρ_i`` of ``R = diag(ρ_1, −ρ_1, …)``.
    positions : ndarray, shape (n + 1, 2)
        Node positions (node order), from the position equations at ``t``.
    iterations : int
        Newton steps.
    residuals : list of float
        ``max |F|`` of the stacked equations before each step and at the end.
    network : ClosedFormNetwork
    start_chi2 : float
        :func:`sincos_chi2` of the start: the orientations ``t0`` with the positions of the
        position equations.
    newton_chi2 : float
        :func:`sincos_chi2` of the stationary point Newton's method reached.
    fallback : bool
        True when Newton's stationary point was worse than the start (a saddle point or a
        worse minimum) and the result is Gauss–Newton's (:func:`optimize_sincos`) from the start
        instead; ``t`` and ``rho`` are then those of the Gauss–Newton optimum.
    reason : str
        What was returned and why.
    """

    poses: np.ndarray
    t: np.ndarray
    rho: np.ndarray
    positions: np.ndarray
    iterations: int
    residuals: list
    network: ClosedFormNetwork = field(repr=False)
    start_chi2: float = float("nan")
    newton_chi2: float = float("nan")
    fallback: bool = False
    reason: str = ""

    @property
    def chi2(self):
        """:func:`sincos_chi2` at the solution."""
        return sincos_chi2(self.network.graph, self.poses)

    @property
    def gradient(self):
        """:func:`sincos_gradient` at the solution, shape (graph.n, 3); ~0 at a stationary point."""
        return sincos_gradient(self.network.graph, self.poses)

    def orthogonality_residual(self):
        """``v − R t`` (eq. 36, 44–45) at the solution, shape (2n,)."""
        return self.network.v(self.t) - _R_times(self.rho, self.t)


def _R_times(rho, t):
    """``R t`` with ``R = diag(ρ_1, −ρ_1, …, ρ_n, −ρ_n)`` (eq. 45)."""
    return t * np.column_stack([rho, -rho]).ravel()


IF_WORSE = ("fallback", "raise")


def _start_poses(net, t, positions):
    """Poses (graph rows) of node positions (n + 1, 2) and ``t`` (2n,), ``p_0`` at the origin."""
    theta = np.concatenate([[0.0], np.arctan2(t[1::2], t[0::2])])
    poses = np.empty((net.graph.n, 3))
    poses[net.vertex] = np.column_stack([positions, theta])
    return poses


def _rho_of(net, t):
    """Least-squares ``ρ`` of ``v(t) = R t``: ``ρ_i = α_i c_i − β_i s_i`` (eq. 36, 44–45)."""
    v = net.v(t).reshape(net.n, 2)
    return v[:, 0] * t[0::2] - v[:, 1] * t[1::2]


def solve_orthogonality(net, t0, *, rho0=None, tol=1e-10, max_iterations=50, if_worse="fallback"):
    """Solve ``R t = A t + b`` with ``c_i² + s_i² = 1`` (Lodi Rizzini eq. 44–45) by Newton's method.

    Unknowns: ``t`` (2n), ``ρ`` (n) and — to keep every matrix sparse — the node positions ``X``
    (2n), which the position equations tie to ``t``.  Newton's method on

    * ``(N_0 N_0^T ⊗ I_2) X − (N_0 ⊗ I_2) Q [1 0 t^T]^T = 0``   (position equations, eq. 16)
    * ``L [1 0 t^T]^T + M (N_0^T ⊗ I_2) X − R t = 0``          (``v = R t``, eq. 36, 44)
    * ``(c_i² + s_i² − 1) / 2 = 0``                             (eq. 1)

    Eliminating ``X`` gives exactly eq. (44) with ``A`` and ``b`` of :meth:`ClosedFormNetwork.A_b`
    — the paper prints ``R t = A t − b``; with ``b`` the first column of ``L + M P Q`` as the text
    defines it, eq. (36) gives ``+ b``.  Each step solves the sparse Jacobian by LU; a step that
    does not decrease ``max |F|`` is halved.

    Parameters
    ----------
    net : ClosedFormNetwork
    t0 : array_like, shape (2n,)
        Initial angular parameters (from LAGO or odometry: :meth:`ClosedFormNetwork.t_of`).
    rho0 : array_like, shape (n,), optional
        Default: the least-squares ``ρ`` of ``v(t0) = R t0``, ``ρ_i = α_i c_i − β_i s_i``.
    tol : float
        Converged when every equation holds to ``tol`` (metres, and squared unit lengths).
        Finite, ``>= 0``.
    max_iterations : int
        ``>= 0``.
    if_worse : {"fallback", "raise"}
        Newton's method finds a *stationary* point of χ², which may be a saddle point or a
        minimum worse than the start.  Its χ² is compared with the start's: when it is larger,
        ``"fallback"`` returns Gauss–Newton's optimum from the start (:func:`optimize_sincos`,
        which never increases χ²) with ``fallback=True`` and the reason on the result;
        ``"raise"`` raises :class:`~lagolib.errors.ConvergenceError`.

    Returns
    -------
    ClosedFormResult

    Raises
    ------
    ConvergenceError
        When ``max_iterations`` steps do not reach ``tol`` or no step fraction decreases the
        residual, or (``if_worse="raise"``) the stationary point is worse than the start; no
        result is returned then.
    """
    where = "solve_orthogonality"
    if not isinstance(net, ClosedFormNetwork):
        raise OptionTypeError(f"{where}: net must be a ClosedFormNetwork; got {type(net).__name__}")
    tol = check_real(tol, "tol", where, minimum=0.0)
    max_iterations = check_int(max_iterations, "max_iterations", where, minimum=0)
    if_worse = check_choice(if_worse, "if_worse", where, IF_WORSE)
    n = net.n
    t = _numeric(t0, f"{where}: t0", float).copy()
    if t.shape != (2 * n,):
        raise OptionError(f"{where}: t0 must have shape ({2 * n},); got {t.shape}")
    cs = t.reshape(n, 2)
    norm = np.linalg.norm(cs, axis=1, keepdims=True)
    bad = np.flatnonzero(~(np.isfinite(norm[:, 0]) & (norm[:, 0] > 0)))
    if bad.size:
        k = int(bad[0]) + 1  # node k: t0 holds nodes 1..n
        raise GraphError(
            f"{where}: t0 of vertex id {net.graph.ids[net.vertex[k]]} (node {k}) is "
            f"{cs[k - 1].tolist()}; every (c, s) pair must be finite and non-zero"
        )
    t = (cs / norm).ravel()
    positions = net.positions(t)  # one solve of the position equations serves X and v(t0)
    X = positions[1:].ravel()
    start_poses = _start_poses(net, t, positions)
    start_chi2 = sincos_chi2(net.graph, start_poses)
    if rho0 is None:
        d = positions[net.j] - positions[net.i]
        v = (net.L @ net.t1(t) + net.M @ d.ravel()).reshape(n, 2)  # eq. (36)
        rho = v[:, 0] * t[0::2] - v[:, 1] * t[1::2]
    else:
        rho = _numeric(rho0, f"{where}: rho0", float).copy()
        if rho.shape != (n,) or not np.all(np.isfinite(rho)):
            raise OptionError(f"{where}: rho0 must be {n} finite numbers; got shape {rho.shape}")

    I2 = sp.identity(2)
    N0 = net._N0
    K2 = sp.kron(N0 @ N0.T, I2, format="csr")
    N02 = sp.kron(N0, I2, format="csr")
    q0, Qt = net.Q[:, 0].toarray().ravel(), net.Q[:, 2:]
    l0, Lt = net.L[:, 0].toarray().ravel(), net.L[:, 2:]
    MB = (net.M @ N02.T).tocsr()
    A_Xt = -(N02 @ Qt)
    idx = np.arange(n)

    def F(X, t, rho):
        c, s = t[0::2], t[1::2]
        return np.concatenate(
            [
                K2 @ X - N02 @ (q0 + Qt @ t),
                l0 + Lt @ t + MB @ X - _R_times(rho, t),
                0.5 * (c**2 + s**2 - 1),
            ]
        )

    def jacobian(t, rho):
        c, s = t[0::2], t[1::2]
        R = sp.diags(np.column_stack([rho, -rho]).ravel())
        pair, node = np.arange(2 * n), np.repeat(idx, 2)
        T = sp.csr_matrix((np.column_stack([-c, s]).ravel(), (pair, node)), shape=(2 * n, n))
        S = sp.csr_matrix((np.column_stack([c, s]).ravel(), (node, pair)), shape=(n, 2 * n))
        return sp.bmat([[K2, A_Xt, None], [MB, Lt - R, T], [None, S, None]], format="csc")

    r = F(X, t, rho)
    norms = [float(np.max(np.abs(r)))]
    it = 0
    while norms[-1] > tol:
        if it == max_iterations:
            raise ConvergenceError(
                f"Newton on the orthogonality condition did not converge in {max_iterations} "
                f"iterations: max |F| = {norms[-1]:.3g} > tol = {tol:.3g} (start from a better "
                "initial guess, e.g. initial='lago')",
                iterations=it,
                residuals=norms,
            )
        try:
            step = spla.splu(jacobian(t, rho)).solve(-r)
        except RuntimeError as exc:  # exactly singular Jacobian
            raise ConvergenceError(
                f"Newton on the orthogonality condition: singular Jacobian at iteration {it} "
                f"({exc})",
                iterations=it,
                residuals=norms,
            ) from None
        dX, dt, drho = step[: 2 * n], step[2 * n : 4 * n], step[4 * n :]
        fraction = 1.0
        for _ in range(40):
            X1, t1, rho1 = X + fraction * dX, t + fraction * dt, rho + fraction * drho
            r1 = F(X1, t1, rho1)
            if np.max(np.abs(r1)) < norms[-1]:
                break
            fraction /= 2
        else:
            raise ConvergenceError(
                f"Newton on the orthogonality condition stalled at iteration {it}: no step "
                f"fraction decreases max |F| = {norms[-1]:.3g}",
                iterations=it,
                residuals=norms,
            )
        X, t, rho, r = X1, t1, rho1, r1
        it += 1
        norms.append(float(np.max(np.abs(r))))

    positions = np.vstack([np.zeros((1, 2)), X.reshape(n, 2)])
    poses = _start_poses(net, t, positions)
    newton_chi2 = sincos_chi2(net.graph, poses)
    if not newton_chi2 > start_chi2 * (1 + 1e-12) + 1e-300:
        reason = (
            f"stationary point of the orthogonality condition: chi2 {newton_chi2:.10g} "
            f"(start {start_chi2:.10g})"
        )
        return ClosedFormResult(
            poses, t, rho, positions, it, norms, net, start_chi2, newton_chi2, False, reason
        )
    why = (
        f"Newton on the orthogonality condition converged in {it} iterations to a stationary "
        f"point with chi2 {newton_chi2:.10g}, worse than its start's {start_chi2:.10g}: a saddle "
        "point or a worse minimum of eq. (6)"
    )
    if if_worse == "raise":
        raise ConvergenceError(
            f"{why}; start from a better initial guess (e.g. initial='lago') or use "
            "if_worse='fallback'",
            iterations=it,
            residuals=norms,
        )
    gn = optimize_sincos(net.graph, start_poses, fixed=int(net.graph.ids[net.vertex[0]]))
    poses = gn.poses.copy()
    t = net.t_of(poses[net.vertex, 2])
    return ClosedFormResult(
        poses,
        t,
        _rho_of(net, t),
        poses[net.vertex, :2] - poses[net.vertex[0], :2],
        it,
        norms,
        net,
        start_chi2,
        newton_chi2,
        True,
        f"{why}; returned Gauss-Newton's optimum from the start instead (chi2 {gn.chi2:.10g})",
    )


def closed_form(graph, initial="lago", *, tol=1e-10, max_iterations=50, if_worse="fallback"):
    """The stationary point of Lodi Rizzini's χ² (``Ω = I_4``) near ``initial``, via eq. (44).

    Builds the network (:func:`network`), takes the orientations of ``initial`` as ``t0`` and
    solves the orthogonality condition (:func:`solve_orthogonality`).

    Parameters
    ----------
    graph : PoseGraph
    initial : {"lago", "odometry"} or array_like of shape (graph.n, 3)
        Where the orientations start: LAGO's estimate (:func:`lagolib.lago.lago`), the odometry
        guess, or given poses.
    tol, max_iterations, if_worse
        See :func:`solve_orthogonality`: the result is never worse than its start unless it
        says so (``fallback``, ``reason``).

    Returns
    -------
    ClosedFormResult

    Examples
    --------
    >>> import numpy as np
    >>> from lagolib import simulate
    >>> sim = simulate.grid_world(rows=4, cols=4, rng=3)
    >>> res = closed_form(sim.graph)
    >>> res.iterations <= 6, bool(np.abs(res.gradient).max() < 1e-8)
    (True, True)
    """
    where = "closed_form"
    check_graph(graph, where)
    net = network(graph)
    tol = check_real(tol, "tol", where, minimum=0.0)
    max_iterations = check_int(max_iterations, "max_iterations", where, minimum=0)
    if_worse = check_choice(if_worse, "if_worse", where, IF_WORSE)
    if isinstance(initial, str):
        initial = check_choice(initial, "initial", where, ("lago", "odometry"))
        guess = lago(graph).poses if initial == "lago" else graph.odometry_guess()
    else:
        guess = as_graph_poses(graph, initial, "initial")
    return solve_orthogonality(
        net,
        net.t_of(guess[net.vertex, 2]),
        tol=tol,
        max_iterations=max_iterations,
        if_worse=if_worse,
    )
