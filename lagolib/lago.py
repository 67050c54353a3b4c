"""LAGO: the linear approximation for graph-based SLAM (Carlone et al. 2011).

A planar pose graph is solved without an initial guess, in closed form, by

0. **regularization** (§IV-E, Theorem 3): add ``2 k pi`` to each chord's relative orientation so
   that the orientations around every fundamental circuit sum to (nearly) zero;
1. **phase 1** (§IV-B, eq. 13): the BLUE of the orientations ``θ̂`` from ``A^T θ = δ̄``;
2. **phase 2** (§IV-C, eq. 9–11): the relative positions rotated into the global frame,
   ``z = [R̂ Δ^l; θ̂]``, with their uncertainty propagated to first order — kept in information
   form with the block inverse of §IV-D, so the dense ``P_θ̂`` is never formed;
3. **phase 3** (§IV-D, eq. 12, 15): the BLUE of all poses ``p* = [ρ*; θ*]`` from
   ``z = B^T p`` and its information ``I_p*``.

Theorem 1: phase 3 equals one Gauss–Newton step on cost (6) from ``p̂ = [ρ̂(θ̂); θ̂]``
(``ρ̂`` from eq. 14, :func:`positions_given_orientations`).

Notation: the paper's ``n + 1`` nodes are ``graph.n`` vertices; the anchor (``p_0 = 0``, by
default the smallest id) is deleted from every unknown vector, so ``θ`` has ``n = graph.n - 1``
entries, ``ρ = [x_1, y_1, x_2, y_2, …]`` has ``2n``, both in the graph's vertex-row order without
the anchor (:attr:`LagoResult.free`).  Relative measurements are stacked per edge the same way:
``Δ^l = [Δx_1, Δy_1, Δx_2, …]``.

Full information matrices
-------------------------
LAGO assumes ``P_ij = diag(P_Δ, P_δ)`` (§IV, Remark 2).  A general 3×3 information ``Ω_ij`` is
reduced to that form by taking the blocks of the *covariance* ``Ω_ij^-1``: ``P_Δ`` is its
top-left 2×2 block and ``P_δ`` its last diagonal entry (the marginals of position and orientation,
:func:`split_information`).  For diagonal ``Ω`` this changes nothing.  GTSAM's ``lago.initialize``
refuses non-diagonal noise and skips phase 2's covariance; lagolib does both.

References
----------
.. [1] L. Carlone, R. Aragues, J. A. Castellanos, B. Bona, "A Linear Approximation for
   Graph-based Simultaneous Localization and Mapping", Robotics: Science and Systems VII, 2011.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from . import se2
from .estimation import BLUE, blue, joint_information
from .graph import PoseGraph, vertex_rows
from .topology import (
    SpanningTree,
    _anchor_row,
    position_incidence_matrix,
    reduced_incidence_matrix,
    spanning_tree,
)

__all__ = [
    "split_information",
    "Regularization",
    "regularize",
    "phase1_orientations",
    "positions_given_orientations",
    "Phase2",
    "phase2_relative_positions",
    "phase3_poses",
    "LagoResult",
    "lago",
]

TWO_PI = 2.0 * np.pi


def split_information(information):
    """Position and orientation information of each edge under LAGO's independence assumption.

    ``P_ij = Ω_ij^-1``; LAGO uses ``P_Δ = P_ij[:2, :2]`` and ``P_δ = P_ij[2, 2]``
    (Carlone et al. 2011, §IV, eq. 4 and Remark 2), i.e. it drops the position–orientation
    correlation of the covariance.

    Parameters
    ----------
    information : ndarray, shape (m, 3, 3)
        Edge information matrices in (x, y, θ) order.

    Returns
    -------
    Omega_Delta : ndarray, shape (m, 2, 2)
        ``P_Δ^-1`` of each edge (local frame of the tail pose).
    omega_delta : ndarray, shape (m,)
        ``P_δ^-1`` of each edge.

    Examples
    --------
    >>> import numpy as np
    >>> O, w = split_information(np.diag([4.0, 9.0, 25.0])[None])
    >>> O[0], w
    (array([[4., 0.],
           [0., 9.]]), array([25.]))
    """
    P = np.linalg.inv(np.asarray(information, dtype=float))
    return np.linalg.inv(P[:, :2, :2]), 1.0 / P[:, 2, 2]


# --------------------------------------------------------------------------- regularization
@dataclass(frozen=True, eq=False)
class Regularization:
    """Outcome of :func:`regularize` (Carlone et al. 2011, Theorem 3).

    Attributes
    ----------
    delta : ndarray, shape (m,)
        Measured relative orientations wrapped to ``(-pi, pi]``.
    delta_bar : ndarray, shape (m,)
        Regularized relative orientations ``δ̄ = δ + ν``, ``ν = 2 pi k``.
    k : ndarray of int, shape (m,)
        Number of turns added to each edge: 0 on tree edges.
    cycle_sums : ndarray, shape (d,)
        ``𝒞 δ``: the orientations summed around the fundamental circuit of each chord, before
        regularization (eq. 22).
    tree : SpanningTree
    """

    delta: np.ndarray
    delta_bar: np.ndarray
    k: np.ndarray
    cycle_sums: np.ndarray
    tree: SpanningTree

    @property
    def chords(self):
        """Edge indices of the chords, in the order of :attr:`cycle_sums`."""
        return self.tree.chords

    @property
    def n_regularized(self):
        """Number of chords with ``k != 0`` (Table I, last column)."""
        return int(np.count_nonzero(self.k))

    @property
    def residual_sums(self):
        """``𝒞 δ̄`` per chord: what is left after regularization, the noise (eq. 21)."""
        return self.cycle_sums + TWO_PI * self.k[self.chords]


def regularize(graph, tree="odometric", anchor=None):
    """Regularized relative orientations ``δ̄ = δ + ν`` (Carlone et al. 2011, Theorem 3, eq. 20–23).

    ``ν = [-2 pi round(𝒞 δ / 2 pi); 0]``: only chords are corrected, tree edges keep their
    measured angle wrapped to ``(-pi, pi]``.  ``𝒞 δ`` for the chord ``(i, j)`` is
    ``δ_ij + φ_i - φ_j``, with ``φ`` the (unwrapped) sums of the tree's angles from the root
    (:meth:`SpanningTree.potentials`), so the cycle basis matrix is never formed.

    Parameters
    ----------
    graph : PoseGraph
    tree : {"odometric", "bfs"} or SpanningTree
        The odometric tree (Prop. 2) needs an edge between every pair of consecutive ids.
    anchor : int, optional
        Root vertex id (default: the smallest).

    Returns
    -------
    Regularization

    Examples
    --------
    A robot turning left four times around a square, then closing the loop: the odometric angles
    add up to 2π while the closure 0 → 4 measures 0; regularization adds one turn to it.

    >>> import numpy as np
    >>> from lagolib import PoseGraph
    >>> z = np.array([[1, 0, np.pi / 2]] * 4 + [[0, 0, 0.0]])
    >>> g = PoseGraph(np.zeros((5, 3)), [(0, 1), (1, 2), (2, 3), (3, 4), (0, 4)], z,
    ...               np.tile(np.eye(3), (5, 1, 1)))
    >>> reg = regularize(g)
    >>> reg.k, reg.n_regularized, float(reg.delta_bar[4] / np.pi)
    (array([0, 0, 0, 0, 1]), 1, 2.0)
    """
    tree = spanning_tree(graph, tree, anchor)
    delta = se2.wrap_angle(graph.measurements[:, 2])
    phi = tree.potentials(delta)
    chords = tree.chords
    i, j = graph.edges[chords, 0], graph.edges[chords, 1]
    cycle_sums = delta[chords] + phi[i] - phi[j]  # eq. (22): (𝒞 δ)_c
    k = np.zeros(graph.m, dtype=np.int64)
    k[chords] = -np.round(cycle_sums / TWO_PI).astype(np.int64)  # eq. (23), rounded
    delta_bar = delta + TWO_PI * k
    for a in (delta, delta_bar, k, cycle_sums):
        a.setflags(write=False)
    return Regularization(delta, delta_bar, k, cycle_sums, tree)


# --------------------------------------------------------------------------- phases
def _free_rows(graph, root):
    return np.delete(np.arange(graph.n), root)


def phase1_orientations(graph, delta_bar, *, anchor=None, omega_delta=None, backend="auto"):
    """Phase 1: the BLUE of the orientations (Carlone et al. 2011, §IV-B, eq. 13).

    ``θ̂ = (A P_δ^-1 A^T)^-1 A P_δ^-1 δ̄``, ``P_θ̂^-1 = A P_δ^-1 A^T``.

    Parameters
    ----------
    graph : PoseGraph
    delta_bar : array_like, shape (m,)
        Relative orientations, regularized (:func:`regularize`) — or not, to see why they must be.
    anchor : int, optional
        Vertex id with ``θ = 0`` (default: the smallest).
    omega_delta : ndarray, shape (m,), optional
        ``P_δ^-1`` per edge; default from :func:`split_information`.
    backend : {"auto", "qdldl", "scipy"}

    Returns
    -------
    BLUE
        ``estimate`` has shape (n,), ``information`` (n, n): the graph's vertex rows without the
        anchor.  Unique when the graph is connected (Prop. 1).
    """
    if omega_delta is None:
        omega_delta = split_information(graph.information)[1]
    A = reduced_incidence_matrix(graph, anchor)
    return blue(A, delta_bar, omega_delta, backend=backend)


def _position_blocks(graph, theta_full, Omega_Delta):
    """``R̂ Δ^l`` (m, 2) and the block-diagonal ``P_Δg^-1 = R̂ P_Δ^-1 R̂^T`` (2m, 2m)."""
    Ri = se2.rotation(theta_full[graph.edges[:, 0]])
    Delta_g = np.einsum("kab,kb->ka", Ri, graph.measurements[:, :2])
    Wk = Ri @ Omega_Delta @ np.swapaxes(Ri, 1, 2)
    m = graph.m
    rows = (2 * np.arange(m)[:, None, None] + np.arange(2)[None, :, None]).repeat(2, axis=2)
    cols = np.swapaxes(rows, 1, 2)
    W = sp.csr_matrix((Wk.ravel(), (rows.ravel(), cols.ravel())), shape=(2 * m, 2 * m))
    return Delta_g, W


def positions_given_orientations(graph, theta, *, anchor=None, Omega_Delta=None, backend="auto"):
    """``ρ̂``: the BLUE of the positions with the orientations held at ``θ`` (Carlone et al. 2011, eq. 14).

    ``ρ̂ = [A2 (R̂ P_Δ R̂^T)^-1 A2^T]^-1 A2 (R̂ P_Δ R̂^T)^-1 R̂ Δ^l``.  LAGO never needs it
    (Remark 1); it is the point Theorem 1 linearizes around.

    Parameters
    ----------
    graph : PoseGraph
    theta : array_like, shape (graph.n,)
        Orientation of every vertex (graph rows; the anchor's entry is ignored and taken as 0).
    anchor : int, optional
    Omega_Delta : ndarray, shape (m, 2, 2), optional
        ``P_Δ^-1`` per edge; default from :func:`split_information`.
    backend : {"auto", "qdldl", "scipy"}

    Returns
    -------
    BLUE
        ``estimate`` is ``ρ̂ = [x_1, y_1, x_2, y_2, …]``, shape (2n,).
    """
    if Omega_Delta is None:
        Omega_Delta = split_information(graph.information)[0]
    root = _anchor_row(graph, anchor)
    theta = np.array(theta, dtype=float)
    theta[root] = 0.0
    Delta_g, W = _position_blocks(graph, theta, Omega_Delta)
    A2 = position_incidence_matrix(reduced_incidence_matrix(graph, anchor))
    return blue(A2, Delta_g.ravel(), W, backend=backend)


@dataclass(eq=False)
class Phase2:
    """Phase 2 of LAGO: ``z = [R̂ Δ^l; θ̂]`` and its information (Carlone et al. 2011, eq. 9–11).

    Attributes
    ----------
    z : ndarray, shape (2m + n,)
        ``[Δ^g; θ̂]`` with ``Δ^g = R̂ Δ^l`` stacked per edge.
    information : scipy.sparse.csr_matrix, shape (2m + n, 2m + n)
        ``P_z^-1`` by the block inverse of §IV-D.
    Delta_g : ndarray, shape (m, 2)
        Relative positions in the global frame.
    J : scipy.sparse.csr_matrix, shape (2m, n)
        ``∂(R(θ) Δ^l) / ∂θ`` at ``θ̂`` (eq. 11).
    W : scipy.sparse.csr_matrix, shape (2m, 2m)
        ``P_Δg^-1 = R̂ P_Δ^-1 R̂^T``, block diagonal.
    """

    z: np.ndarray
    information: sp.csr_matrix
    Delta_g: np.ndarray
    J: sp.csr_matrix
    W: sp.csr_matrix


def phase2_relative_positions(graph, theta_hat, *, anchor=None, Omega_Delta=None):
    """Phase 2: relative positions in the global frame and their uncertainty (eq. 9–11).

    ``z = [R̂ Δ^l; θ̂]``, ``P_z = H diag(P_Δ, P_θ̂) H^T`` with ``H = [[R̂, J], [0, I]]`` (eq. 10,
    11).  Edge ``(i, j)`` contributes the block ``Δ^g_ij = R(θ̂_i) Δ^l_ij``, and ``J`` has one
    non-zero 2-vector per edge: ``∂Δ^g_ij / ∂θ_i = S Δ^g_ij`` with ``S = [[0, -1], [1, 0]]``
    (zero when ``i`` is the anchor).

    The result is kept as ``P_z^-1`` — ``[[W, -W J], [-J^T W, P_θ̂^-1 + J^T W J]]``, §IV-D — which
    is sparse, whereas ``P_z`` (and ``P_θ̂``) are dense.

    Parameters
    ----------
    graph : PoseGraph
    theta_hat : BLUE
        Phase 1's estimate (:func:`phase1_orientations`): ``θ̂`` and ``P_θ̂^-1``.
    anchor : int, optional
        The anchor phase 1 used.
    Omega_Delta : ndarray, shape (m, 2, 2), optional

    Returns
    -------
    Phase2
    """
    if Omega_Delta is None:
        Omega_Delta = split_information(graph.information)[0]
    root = _anchor_row(graph, anchor)
    free = _free_rows(graph, root)
    theta_full = np.zeros(graph.n)
    theta_full[free] = theta_hat.estimate
    Delta_g, W = _position_blocks(graph, theta_full, Omega_Delta)  # eq. (9), g1
    # column of each tail in θ (anchor: no column)
    col = np.full(graph.n, -1, dtype=np.int64)
    col[free] = np.arange(free.size)
    tail = col[graph.edges[:, 0]]
    k = np.flatnonzero(tail >= 0)
    SDg = np.column_stack([-Delta_g[:, 1], Delta_g[:, 0]])  # S R̂ Δ^l, eq. (11)
    J = sp.csr_matrix(
        (SDg[k].ravel(), ((2 * k[:, None] + np.arange(2)).ravel(), np.repeat(tail[k], 2))),
        shape=(2 * graph.m, free.size),
    )
    z = np.concatenate([Delta_g.ravel(), theta_hat.estimate])
    info = joint_information(W, J, theta_hat.information)  # P_z^-1, §IV-D
    return Phase2(z, info, Delta_g, J, W)


def phase3_poses(graph, phase2, *, anchor=None, backend="auto"):
    """Phase 3: the BLUE of ``p = [ρ; θ]`` from ``z = B^T p`` (Carlone et al. 2011, eq. 12, 15).

    ``p* = (B P_z^-1 B^T)^-1 B P_z^-1 z`` with ``B = [[A2, 0], [0, I_n]]``; ``I_p* = B P_z^-1 B^T``.

    Parameters
    ----------
    graph : PoseGraph
    phase2 : Phase2
    anchor : int, optional
    backend : {"auto", "qdldl", "scipy"}

    Returns
    -------
    BLUE
        ``estimate`` is ``p* = [x_1, y_1, …, x_n, y_n, θ_1, …, θ_n]``, shape (3n,); its
        ``information`` is ``I_p*``.
    """
    A2 = position_incidence_matrix(reduced_incidence_matrix(graph, anchor))
    n = A2.shape[0] // 2
    B = sp.block_diag([A2, sp.identity(n)], format="csr")  # eq. (12)
    return blue(B, phase2.z, phase2.information, backend=backend)  # eq. (15)


# --------------------------------------------------------------------------- LAGO
@dataclass(eq=False)
class LagoResult:
    """Outcome of :func:`lago`.

    Attributes
    ----------
    poses : ndarray, shape (graph.n, 3)
        ``p*`` per vertex row, angle wrapped to ``(-pi, pi]``; the anchor at the origin.
    theta : ndarray, shape (graph.n,)
        ``θ*`` unwrapped (the anchor 0): consistent with the regularized ``δ̄``.
    theta_hat : ndarray, shape (graph.n,)
        Phase 1's ``θ̂``, unwrapped.
    information : scipy.sparse.csc_matrix, shape (3n, 3n)
        ``I_p*`` in the paper's order ``[ρ; θ]`` over :attr:`free`.
    regularization : Regularization
    anchor : int
        Anchor vertex id.
    free : ndarray of int, shape (n,)
        Vertex rows of the unknowns (all but the anchor), in order.
    phase1, phase3 : BLUE
    phase2 : Phase2
    timings : dict
        Seconds: ``regularization``, ``phase1``, ``phase2``, ``phase3``, ``total``.
    graph : PoseGraph
    """

    poses: np.ndarray
    theta: np.ndarray
    theta_hat: np.ndarray
    information: sp.csc_matrix
    regularization: Regularization
    anchor: int
    free: np.ndarray
    phase1: BLUE
    phase2: Phase2
    phase3: BLUE
    graph: PoseGraph
    timings: dict = field(default_factory=dict)

    def covariance(self, vertices=None, *, batch=128):
        """Marginal covariance of ``p*`` at vertices, in (x, y, θ) order — blocks of ``I_p*^-1``.

        Three columns of ``I_p*^-1`` per vertex, ``batch`` vertices at a time, from phase 3's
        factorization (:meth:`lagolib.estimation.BLUE.covariance`); the anchor's covariance is zero.

        Parameters
        ----------
        vertices : int or array_like of int, optional
            Vertex ids (default: all, in row order).
        batch : int

        Returns
        -------
        ndarray, shape (k, 3, 3)
        """
        g = self.graph
        rows = np.arange(g.n) if vertices is None else vertex_rows(g, vertices, "covariance")
        n = self.free.size
        col = np.full(g.n, -1, dtype=np.int64)
        col[self.free] = np.arange(n)
        out = np.zeros((rows.size, 3, 3))
        sel = np.flatnonzero(col[rows] >= 0)
        for start in range(0, sel.size, batch):
            s = sel[start : start + batch]
            c = col[rows[s]]
            idx = np.column_stack([2 * c, 2 * c + 1, 2 * n + c])  # x, y, θ of each vertex
            P = self.phase3.covariance(idx.ravel()).reshape(s.size, 3, s.size, 3)
            out[s] = P[np.arange(s.size), :, np.arange(s.size), :]
        return out


def lago(graph, tree="odometric", anchor=None, *, backend="auto"):
    """The linear approximation of the pose-graph optimum (Carlone et al. 2011, §IV).

    Regularization (eq. 20–23), phase 1 (eq. 13), phase 2 (eq. 9–11) and phase 3 (eq. 12, 15).
    No initial guess is used: the poses stored in ``graph`` are ignored.

    Parameters
    ----------
    graph : PoseGraph
        Connected; full 3×3 information matrices are reduced to ``diag(P_Δ, P_δ)`` by taking the
        blocks of their covariance (Remark 2, :func:`split_information`).
    tree : {"odometric", "bfs"} or SpanningTree
        Spanning tree for the regularization: the odometric chain (Prop. 2) or a breadth-first
        tree from the anchor (for graphs whose odometric chain is broken).
    anchor : int, optional
        Vertex id fixed at the origin, ``p_0 = 0`` (default: the smallest id; 0 in the shipped
        datasets).
    backend : {"auto", "qdldl", "scipy"}
        Sparse Cholesky used by phases 1 and 3.

    Returns
    -------
    LagoResult

    Raises
    ------
    GraphError
        If the graph is not connected, the anchor is not a vertex, or ``tree="odometric"`` and
        the odometric chain is broken.

    Examples
    --------
    A noiseless robot driving three laps of a square is recovered exactly:

    >>> import numpy as np
    >>> from lagolib import simulate
    >>> sim = simulate.loop_world(laps=3, poses_per_lap=20, noiseless=True)
    >>> res = lago(sim.graph)
    >>> res.regularization.n_regularized
    40
    >>> bool(np.allclose(res.poses, sim.truth, atol=1e-9))
    True
    """
    t0 = time.perf_counter()
    if not isinstance(graph, PoseGraph):
        raise TypeError(f"lago needs a PoseGraph; got {type(graph).__name__}")
    root = _anchor_row(graph, anchor)
    anchor_id = int(graph.ids[root])
    Omega_Delta, omega_delta = split_information(graph.information)
    reg = regularize(graph, tree, anchor_id)
    t1 = time.perf_counter()
    p1 = phase1_orientations(
        graph, reg.delta_bar, anchor=anchor_id, omega_delta=omega_delta, backend=backend
    )
    t2 = time.perf_counter()
    p2 = phase2_relative_positions(graph, p1, anchor=anchor_id, Omega_Delta=Omega_Delta)
    t3 = time.perf_counter()
    p3 = phase3_poses(graph, p2, anchor=anchor_id, backend=backend)
    t4 = time.perf_counter()
    free = _free_rows(graph, root)
    n = free.size
    theta_hat = np.zeros(graph.n)
    theta_hat[free] = p1.estimate
    theta = np.zeros(graph.n)
    theta[free] = p3.estimate[2 * n :]
    poses = np.zeros((graph.n, 3))
    poses[free, :2] = p3.estimate[: 2 * n].reshape(n, 2)
    poses[:, 2] = se2.wrap_angle(theta)
    free.setflags(write=False)
    t5 = time.perf_counter()
    timings = {
        "regularization": t1 - t0,
        "phase1": t2 - t1,
        "phase2": t3 - t2,
        "phase3": t4 - t3,
        "total": t5 - t0,
    }
    return LagoResult(
        poses, theta, theta_hat, p3.information, reg, anchor_id, free, p1, p2, p3, graph, timings
    )
