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

Information frames
------------------
lagolib stores each edge's information ``Ω_ij`` in the **g2o frame** (it weights the position
error rotated into the frame of the measured pose ``Z_ij``).  LAGO's cost (eq. 3–4, 6) weights the
position error in the **frame of pose i**.  :func:`frame_i_information` converts,
``G Ω Gᵀ`` with ``G = blockdiag(R(θ_z), 1)``; phase 2 then rotates ``P_Δ`` into the **global
frame**, ``P_Δg = R̂ P_Δ R̂ᵀ`` (eq. 10).  For a general 3×3 information LAGO's assumption
``P_ij = diag(P_Δ, P_δ)`` (§IV; Remark 2, §V) is met by taking the blocks of the frame-``i``
*covariance* (:func:`split_information`): the marginals of position and orientation.  GTSAM's
``lago.initialize`` refuses non-diagonal noise and skips phase 2's covariance; lagolib does both.

Spanning trees
--------------
Regularization rounds the orientation sums around the fundamental circuits of a spanning tree.
The paper uses the odometric tree (Prop. 2); lagolib's default is the tree of least accumulated
orientation variance (:func:`lagolib.topology.min_uncertainty_tree`), chosen from the table in
chapter 5 (``benchmarks/tree_table.py``).  Each chord's distance from the rounding boundary is
reported (:attr:`Regularization.margin`) and a :class:`RegularizationWarning` flags chords near it.

References
----------
.. [1] L. Carlone, R. Aragues, J. A. Castellanos, B. Bona, "A Linear Approximation for
   Graph-based Simultaneous Localization and Mapping", Robotics: Science and Systems VII, 2011.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from . import se2
from .checks import check_choice, check_int, check_real
from .errors import LagolibWarning
from .estimation import BLUE, blue, joint_information
from .graph import PoseGraph, check_graph, vertex_rows
from .linalg import BACKENDS, _rows_key, core_size, elimination_ordering, expand_ordering
from .topology import (
    SpanningTree,
    _anchor_row,
    _disconnected,
    position_incidence_matrix,
    reduced_incidence_matrix,
    spanning_tree,
)

__all__ = [
    "RegularizationWarning",
    "frame_i_information",
    "split_information",
    "Regularization",
    "regularize",
    "pose_ordering",
    "phase1_orientations",
    "positions_given_orientations",
    "Phase2",
    "phase2_relative_positions",
    "phase3_poses",
    "LagoResult",
    "lago",
]

TWO_PI = 2.0 * np.pi


class RegularizationWarning(LagolibWarning):
    """Some chords' cycle sums were close to ±π: the 2kπ rounding (Theorem 3) may be wrong there."""


def frame_i_information(graph):
    """Edge information in the frame of the tail pose ``i`` (Carlone et al. 2011, eq. 3–4).

    lagolib stores ``Ω_ij`` in the **g2o frame**: it weights
    ``e = [R_zᵀ(R_iᵀ(t_j − t_i) − t_z); θ_j − θ_i − θ_z]``, the position error rotated into the
    frame of the *measured* pose ``Z_ij``.  LAGO's cost (eq. 3, 6) weights the position error in
    the **frame of pose i**, ``R_iᵀ(t_j − t_i) − Δ^l_ij`` (no ``R_zᵀ``).  Since
    ``e = Gᵀ [R_iᵀ(t_j − t_i) − Δ^l_ij; ·]`` with ``G = blockdiag(R(θ_z), 1)``, the same quadratic
    form in frame ``i`` has the information ``G Ω Gᵀ`` (:func:`lagolib.se2.information_to_frame_i`;
    TORO files store this frame-``i`` information, and :func:`lagolib.io.read_toro` applies the
    inverse, :func:`lagolib.se2.information_from_frame_i`).

    Parameters
    ----------
    graph : PoseGraph
        Information in the g2o frame (``graph.information``, shape (m, 3, 3)) and the measured
        angles ``θ_z = graph.measurements[:, 2]``.

    Returns
    -------
    ndarray, shape (m, 3, 3)
        ``G_k Ω_k G_kᵀ`` per edge, in (x, y, θ) order, frame ``i``.

    Examples
    --------
    A measurement turned by 90° with information 100 along its own x axis: in frame ``i`` that
    axis is ``y``.

    >>> import numpy as np
    >>> from lagolib import PoseGraph
    >>> g = PoseGraph(np.zeros((2, 3)), [(0, 1)], [[1.0, 0.0, np.pi / 2]],
    ...               [np.diag([100.0, 1.0, 10.0])])
    >>> np.round(frame_i_information(g)[0], 12) + 0.0
    array([[  1.,   0.,   0.],
           [  0., 100.,   0.],
           [  0.,   0.,  10.]])
    """
    check_graph(graph, "frame_i_information")
    return se2.information_to_frame_i(graph.information, graph.measurements[:, 2])  # G Ω Gᵀ


def split_information(graph):
    """Position and orientation information of each edge under LAGO's independence assumption.

    LAGO assumes ``P_ij = diag(P_Δ, P_δ)`` in the frame of pose ``i`` (Carlone et al. 2011, §IV,
    eq. 4; the assumption is discussed in Remark 2, §V).  From the frame-``i`` information
    (:func:`frame_i_information`) lagolib takes the blocks of its *covariance*
    ``P_ij = (G Ω Gᵀ)⁻¹``: ``P_Δ = P_ij[:2, :2]`` (frame ``i``) and ``P_δ = P_ij[2, 2]`` — the
    marginals of position and orientation, dropping only their correlation.  For information
    that is diagonal with equal x and y weights nothing changes; otherwise the rotation matters.

    Parameters
    ----------
    graph : PoseGraph
        Information in the g2o frame, as lagolib stores it.

    Returns
    -------
    Omega_Delta : ndarray, shape (m, 2, 2)
        ``P_Δ⁻¹`` of each edge, in the frame of the tail pose ``i``.
    omega_delta : ndarray, shape (m,)
        ``P_δ⁻¹`` of each edge (frame-free).

    Examples
    --------
    >>> import numpy as np
    >>> from lagolib import PoseGraph
    >>> g = PoseGraph(np.zeros((2, 3)), [(0, 1)], [[1.0, 0.0, 0.0]], [np.diag([4.0, 9.0, 25.0])])
    >>> O, w = split_information(g)
    >>> O[0], w
    (array([[4., 0.],
           [0., 9.]]), array([25.]))
    """
    check_graph(graph, "split_information")
    P = np.linalg.inv(frame_i_information(graph))  # covariance in frame i
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
    margin : ndarray, shape (d,)
        Per chord, how far ``𝒞 δ / 2π`` was from the rounding boundary, in turns:
        ``½ − |𝒞 δ / 2π − round(𝒞 δ / 2π)|``.  ½ means the circuit summed to a whole number of
        turns exactly; near 0 the noise around the circuit was near ±π and the rounding may have
        picked the wrong ``k``.
    """

    delta: np.ndarray
    delta_bar: np.ndarray
    k: np.ndarray
    cycle_sums: np.ndarray
    tree: SpanningTree
    margin: np.ndarray

    @property
    def chords(self):
        """Edge indices of the chords, in the order of :attr:`cycle_sums`."""
        return self.tree.chords

    @property
    def n_regularized(self):
        """Number of chords with ``k != 0`` (Table I, last column)."""
        return int(np.count_nonzero(self.k))

    def unreliable(self, threshold=0.1):
        """Chords (edge indices) whose :attr:`margin` is below ``threshold`` turns."""
        threshold = check_real(
            threshold, "threshold", "Regularization.unreliable", minimum=0.0, maximum=0.5
        )
        return self.chords[self.margin < threshold]

    @property
    def residual_sums(self):
        """``𝒞 δ̄`` per chord: what is left after regularization, the noise (eq. 21)."""
        return self.cycle_sums + TWO_PI * self.k[self.chords]


def regularize(graph, tree="min_uncertainty", anchor=None, *, margin_warning=0.1):
    """Regularized relative orientations ``δ̄ = δ + ν`` (Carlone et al. 2011, Theorem 3, eq. 20–23).

    ``ν = [-2 pi round(𝒞 δ / 2 pi); 0]``: only chords are corrected, tree edges keep their
    measured angle wrapped to ``(-pi, pi]``.  ``𝒞 δ`` for the chord ``(i, j)`` is
    ``δ_ij + φ_i - φ_j``, with ``φ`` the (unwrapped) sums of the tree's angles from the root
    (:meth:`SpanningTree.potentials`), so the cycle basis matrix is never formed.

    Rounding is right only while the noise summed around each fundamental circuit stays inside
    ``(-π, π)``.  Each chord's distance from the rounding boundary is kept as
    :attr:`Regularization.margin`; when some chord is closer than ``margin_warning`` turns, a
    :class:`RegularizationWarning` says which — the ``k`` chosen there may be wrong.

    Parameters
    ----------
    graph : PoseGraph
    tree : {"min_uncertainty", "odometric", "bfs"} or SpanningTree
        :func:`lagolib.topology.min_uncertainty_tree` (default: each orientation from the path of
        least accumulated variance), the odometric chain (Prop. 2, the paper's choice; needs an
        edge between every pair of consecutive ids), or a breadth-first tree.
    anchor : int, optional
        Root vertex id (default: the smallest).
    margin_warning : float
        Warn when a chord's margin is below this many turns (0 turns it off; at most 0.5).

    Returns
    -------
    Regularization

    Warns
    -----
    RegularizationWarning
        When chords lie within ``margin_warning`` turns of the rounding boundary.

    Examples
    --------
    A robot turning left four times around a square, then closing the loop: the odometric angles
    add up to 2π while the closure 0 → 4 measures 0; regularization adds one turn to it.

    >>> import numpy as np
    >>> from lagolib import PoseGraph
    >>> z = np.array([[1, 0, np.pi / 2]] * 4 + [[0, 0, 0.0]])
    >>> g = PoseGraph(np.zeros((5, 3)), [(0, 1), (1, 2), (2, 3), (3, 4), (0, 4)], z,
    ...               np.tile(np.eye(3), (5, 1, 1)))
    >>> reg = regularize(g, "odometric")
    >>> reg.k, reg.n_regularized, float(reg.delta_bar[4] / np.pi), reg.margin
    (array([0, 0, 0, 0, 1]), 1, 2.0, array([0.5]))
    """
    _anchor_row(graph, anchor, "regularize")  # the graph, and one vertex id or None
    margin_warning = check_real(
        margin_warning, "margin_warning", "regularize", minimum=0.0, maximum=0.5
    )
    tree = spanning_tree(graph, tree, anchor)
    delta = se2.wrap_angle(graph.measurements[:, 2])
    phi = tree.potentials(delta)
    chords = tree.chords
    i, j = graph.edges[chords, 0], graph.edges[chords, 1]
    cycle_sums = delta[chords] + phi[i] - phi[j]  # eq. (22): (𝒞 δ)_c
    turns = cycle_sums / TWO_PI
    k = np.zeros(graph.m, dtype=np.int64)
    k[chords] = -np.round(turns).astype(np.int64)  # eq. (23), rounded
    margin = 0.5 - np.abs(turns + k[chords])  # distance of 𝒞δ/2π from the rounding boundary
    delta_bar = delta + TWO_PI * k
    for a in (delta, delta_bar, k, cycle_sums, margin):
        a.setflags(write=False)
    reg = Regularization(delta, delta_bar, k, cycle_sums, tree, margin)
    _warn_margins(graph, reg, margin_warning, stacklevel=3)
    return reg


def _warn_margins(graph, reg, threshold, stacklevel):
    """:class:`RegularizationWarning` when chords' margins are below ``threshold`` turns."""
    close = np.flatnonzero(reg.margin < threshold)
    if not close.size:
        return
    w = close[np.argmin(reg.margin[close])]
    e = int(reg.chords[w])
    a, b = (int(v) for v in graph.ids[graph.edges[e]])
    warnings.warn(
        f"regularization may be wrong: {close.size} of {reg.chords.size} chords summed to within "
        f"{threshold} turns of the rounding boundary ±½ (worst: edge {e}, {a} -> {b}, "
        f"{reg.cycle_sums[w]:+.3f} rad around its circuit, margin {reg.margin[w]:.3f} turns) with "
        f"the {reg.tree.kind!r} tree. The noise around those circuits approaches ±π: "
        + (
            "check those loop closures for outliers, or the orientation noise is too large "
            "for any tree"
            if reg.tree.kind == "min_uncertainty"
            else "use a tree with shorter, more precise paths (tree='min_uncertainty'), or "
            "check those loop closures for outliers"
        ),
        RegularizationWarning,
        stacklevel=stacklevel,
    )


# --------------------------------------------------------------------------- phases
def _free_rows(graph, root):
    return np.delete(np.arange(graph.n), root)


def phase1_orientations(
    graph,
    delta_bar,
    *,
    anchor=None,
    omega_delta=None,
    backend="auto",
    tree=None,
    ordering=None,
    core=None,
):
    """Phase 1: the BLUE of the orientations from ``A^T θ = δ̄`` (Carlone et al. 2011, eq. 8, 13).

    ``θ̂ = (A P_δ^-1 A^T)^-1 A P_δ^-1 δ̄``, ``P_θ̂^-1 = A P_δ^-1 A^T``.

    Parameters
    ----------
    graph : PoseGraph
    delta_bar : array_like, shape (m,)
        Relative orientations, regularized (:func:`regularize`) — or not, to see why they must be.
    anchor : int, optional
        Vertex id with ``θ = 0`` (default: the smallest).
    omega_delta : ndarray, shape (m,), optional
        ``P_δ^-1`` per edge (frame-free); default from :func:`split_information`.
    backend : {"auto", "qdldl", "pardiso", "cholmod", "scipy"}
    tree : SpanningTree, optional
        When given, the normal equations are solved for the correction to the orientations the
        tree alone assigns (``tree.potentials(δ̄)``), which is small: the same estimate, accurate
        also when ``A P_δ^-1 A^T`` is ill-conditioned (:func:`lagolib.estimation.blue`).
    ordering : ndarray of int, shape (n,), or callable, optional
        Elimination order of the free poses (:func:`pose_ordering`), for the factorization.
    core : int or callable, optional
        Free poses in the pose graph's 2-core (:func:`lagolib.linalg.core_size`), which decide
        ``backend="auto"``; computed from the graph when needed otherwise.

    Returns
    -------
    BLUE
        ``estimate`` has shape (n,), ``information`` (n, n): the graph's vertex rows without the
        anchor.  Unique when the graph is connected (Prop. 1).
    """
    _anchor_row(graph, anchor, "phase1_orientations")  # the graph, and one vertex id or None
    if (
        not graph.is_connected
    ):  # Prop. 1: A P_δ⁻¹ Aᵀ is singular; say why, not "not positive definite"
        raise _disconnected(graph)
    if omega_delta is None:
        omega_delta = split_information(graph)[1]
    A = reduced_incidence_matrix(graph, anchor)
    start = None
    if tree is not None:
        root = _anchor_row(graph, anchor)
        theta_tree = tree.potentials(delta_bar)
        start = (theta_tree - theta_tree[root])[_free_rows(graph, root)]
    if core is None:
        core = _FreePoses(graph, anchor, "phase1_orientations").core
    return blue(
        A, delta_bar, omega_delta, backend=backend, start=start, ordering=ordering, auto_rows=core
    )


def pose_ordering(graph, anchor=None):
    """An elimination order of the free poses (every vertex but the anchor) for LAGO's systems.

    :func:`lagolib.linalg.elimination_ordering` of the pose graph without the anchor, rooted at
    the anchor's neighbours: nested dissection on the cycles, and the tree-like parts (a long
    odometry chain) eliminated away from the anchor — the direction in which nothing cancels.

    Parameters
    ----------
    graph : PoseGraph
    anchor : int, optional
        Vertex id (default: the smallest).

    Returns
    -------
    ndarray of int, shape (graph.n - 1,)
        Positions in the free poses' order (graph rows without the anchor).
    """
    return _FreePoses(graph, anchor, "pose_ordering").ordering()


class _FreePoses:
    """The pose graph of the free poses (every vertex but the anchor), computed once, and what
    LAGO's two factorizations read from it: its 2-core's size and its elimination order."""

    def __init__(self, graph, anchor, where):
        root = _anchor_row(graph, anchor, where)
        self._graph, self._root = graph, root
        red = np.full(graph.n, -1, dtype=np.int64)
        red[_free_rows(graph, root)] = np.arange(graph.n - 1)
        self._e = red[graph.edges]
        self._k = graph.n - 1
        self._cached = {}

    def _once(self, key, compute):
        if key not in self._cached:
            self._cached[key] = compute()
        return self._cached[key]

    def pattern(self):
        """``(pattern, near)``: the (n-1, n-1) pose graph and the anchor's neighbours in it."""

        def compute():
            e, k = self._e, self._k
            inner = (e >= 0).all(axis=1)
            pattern = sp.csr_matrix(
                (np.ones(inner.sum()), (e[inner, 0], e[inner, 1])), shape=(k, k)
            )
            near = np.concatenate([e[e[:, 0] < 0, 1], e[e[:, 1] < 0, 0]])
            return pattern, near[near >= 0]

        return self._once("pattern", compute)

    def core(self):
        """Free poses in the 2-core (:func:`lagolib.linalg.core_size`)."""
        return self._once("core", lambda: core_size(self.pattern()[0]))

    def ordering(self):
        """:func:`lagolib.linalg.elimination_ordering` of the free poses (once per graph: the
        same as Gauss–Newton's with the anchor fixed, :meth:`LinearSystem.pose_ordering`)."""
        key = ("elimination_ordering", _rows_key([self._root]), _rows_key([]))
        return self._graph._structural(key, lambda: elimination_ordering(*self.pattern()))


def _position_blocks(graph, theta_full, Omega_Delta):
    """``Δ^g = R̂ Δ^l`` (m, 2) and the block-diagonal ``P_Δg^-1 = R̂ P_Δ^-1 R̂^T`` (2m, 2m).

    ``Omega_Delta`` is in the frame of each edge's tail pose ``i``; both outputs are in the global
    frame (Carlone et al. 2011, eq. 9–10).
    """
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
        ``P_Δ^-1`` per edge in the frame of its tail pose ``i``; default from
        :func:`split_information`.
    backend : {"auto", "qdldl", "pardiso", "cholmod", "scipy"}

    Returns
    -------
    BLUE
        ``estimate`` is ``ρ̂ = [x_1, y_1, x_2, y_2, …]`` (global frame), shape (2n,).
    """
    root = _anchor_row(graph, anchor, "positions_given_orientations")
    if Omega_Delta is None:
        Omega_Delta = split_information(graph)[0]
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
        ``∂(R(θ) Δ^l) / ∂θ`` at ``θ̂`` (eq. 11), global frame.
    W : scipy.sparse.csr_matrix, shape (2m, 2m)
        ``P_Δg^-1 = R̂ P_Δ^-1 R̂^T``, block diagonal, global frame (``P_Δ`` is in frame ``i``).
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
        ``P_Δ^-1`` per edge in the frame of its tail pose ``i``; default from
        :func:`split_information` (which converts lagolib's g2o-frame information).

    Returns
    -------
    Phase2
    """
    root = _anchor_row(graph, anchor, "phase2_relative_positions")
    if Omega_Delta is None:
        Omega_Delta = split_information(graph)[0]
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


def phase3_poses(
    graph, phase2, *, anchor=None, backend="auto", pose_ordering=None, tree=None, core=None
):
    """Phase 3: the BLUE of ``p = [ρ; θ]`` from ``z = B^T p`` (Carlone et al. 2011, eq. 12, 15).

    ``p* = (B P_z^-1 B^T)^-1 B P_z^-1 z`` with ``B = [[A2, 0], [0, I_n]]``; ``I_p* = B P_z^-1 B^T``.
    ``z = B^T p`` is eq. 7 (``A2^T ρ = R(θ) Δ^l``, ``A^T θ = δ``) with ``R(θ)`` taken at ``θ̂``.

    Parameters
    ----------
    graph : PoseGraph
    phase2 : Phase2
    anchor : int, optional
    backend : {"auto", "qdldl", "pardiso", "cholmod", "scipy"}
    pose_ordering : ndarray of int, shape (n,), or callable, optional
        An elimination order of the free poses (:func:`pose_ordering`) — phase 1's, whose matrix
        is the pose graph's weighted Laplacian — expanded to each pose's three rows, so that it
        is computed once for LAGO's two factorizations.
    tree : SpanningTree, optional
        When given, the normal equations are solved for the correction to the positions the tree
        alone assigns (``Δ^g`` summed along it) and to ``θ̂``: the same estimate, and accurate
        where the direct solve is not — on a 4 x 10^4-pose chain ``B P_z^-1 B^T`` has a condition
        number of about 5e17 and the direct solve's poses were off by 1e-3 to 1e-1 relative,
        depending on the backend's rounding (:func:`lagolib.estimation.blue`).
    core : int or callable, optional
        Free poses in the pose graph's 2-core (three rows each decide ``backend="auto"``);
        computed from the graph when needed otherwise.

    Returns
    -------
    BLUE
        ``estimate`` is ``p* = [x_1, y_1, …, x_n, y_n, θ_1, …, θ_n]``, shape (3n,); its
        ``information`` is ``I_p*``.
    """
    _anchor_row(graph, anchor, "phase3_poses")  # the graph, and one vertex id or None
    A2 = position_incidence_matrix(reduced_incidence_matrix(graph, anchor))
    n = A2.shape[0] // 2
    B = sp.block_diag([A2, sp.identity(n)], format="csr")  # eq. (12)
    order = None
    if pose_ordering is not None:
        r = np.arange(n)
        rows = np.column_stack([2 * r, 2 * r + 1, 2 * n + r])
        if callable(pose_ordering):  # computed only if the factorization needs it
            order = lambda: expand_ordering(pose_ordering(), rows)  # noqa: E731
        else:
            order = expand_ordering(pose_ordering, rows)
    start = None
    if tree is not None:
        root = _anchor_row(graph, anchor)
        free = _free_rows(graph, root)
        rho = np.column_stack([tree.potentials(phase2.Delta_g[:, k]) for k in (0, 1)])
        start = np.concatenate([(rho - rho[root])[free].ravel(), phase2.z[2 * graph.m :]])
    if core is None:
        core = _FreePoses(graph, anchor, "phase3_poses").core
    core_rows = lambda: 3 * (core() if callable(core) else core)  # noqa: E731
    return blue(  # eq. (15)
        B,
        phase2.z,
        phase2.information,
        backend=backend,
        ordering=order,
        start=start,
        auto_rows=core_rows,
    )


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
            Vertices per block of right-hand sides, ``>= 1``.

        Returns
        -------
        ndarray, shape (k, 3, 3)
        """
        g = self.graph
        batch = check_int(batch, "batch", "LagoResult.covariance", minimum=1)
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


def lago(graph, tree="min_uncertainty", anchor=None, *, margin_warning=0.1, backend="auto"):
    """The linear approximation of the pose-graph optimum (Carlone et al. 2011, §IV).

    Regularization (eq. 20–23), phase 1 (eq. 13), phase 2 (eq. 9–11) and phase 3 (eq. 12, 15).
    No initial guess is used: the poses stored in ``graph`` are ignored.

    Parameters
    ----------
    graph : PoseGraph
        Connected; information in the g2o frame, as lagolib stores it.  It is rotated into the
        frame of each edge's tail pose (:func:`frame_i_information`) and reduced to
        ``diag(P_Δ, P_δ)`` by taking the blocks of its covariance (§IV, Remark 2;
        :func:`split_information`).
    tree : {"min_uncertainty", "odometric", "bfs"} or SpanningTree
        Spanning tree for the regularization (:func:`regularize`): by default the tree of least
        accumulated orientation variance (:func:`lagolib.topology.min_uncertainty_tree`); the
        paper's odometric chain (Prop. 2, Table I); or a breadth-first tree from the anchor.
        The default was chosen on the benchmarks and on noisy simulated Manhattan worlds
        (chapter 5 prints the table): it never did worse than the odometric tree after
        Gauss–Newton, and on noisy graphs the odometric tree's long circuits round wrongly.
    anchor : int, optional
        Vertex id fixed at the origin, ``p_0 = 0`` (default: the smallest id; 0 in the shipped
        datasets).
    margin_warning : float
        Warn (:class:`RegularizationWarning`) when chords' cycle sums lie within this many turns
        of the rounding boundary (:attr:`Regularization.margin`); 0 turns the warning off.
    backend : {"auto", "qdldl", "pardiso", "cholmod", "scipy"}
        Sparse Cholesky used by phases 1 and 3.

    Returns
    -------
    LagoResult

    Warns
    -----
    RegularizationWarning
        When the 2kπ regularization may have picked a wrong ``k`` for some chords.

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
    >>> res = lago(sim.graph, "odometric")
    >>> res.regularization.n_regularized
    40
    >>> bool(np.allclose(res.poses, sim.truth, atol=1e-9))
    True
    """
    t0 = time.perf_counter()
    check_graph(graph, "lago")
    margin_warning = check_real(margin_warning, "margin_warning", "lago", minimum=0.0, maximum=0.5)
    check_choice(backend, "backend", "lago", ("auto",) + BACKENDS)
    root = _anchor_row(graph, anchor, "lago")
    anchor_id = int(graph.ids[root])
    Omega_Delta, omega_delta = split_information(graph)  # frame i, eq. (4)
    reg = regularize(graph, tree, anchor_id, margin_warning=0.0)
    _warn_margins(graph, reg, margin_warning, stacklevel=2)
    t1 = time.perf_counter()
    free_poses = _FreePoses(graph, anchor_id, "lago")  # computed once, if a factorization asks
    p1 = phase1_orientations(  # solved as a correction to the tree's orientations
        graph,
        reg.delta_bar,
        anchor=anchor_id,
        omega_delta=omega_delta,
        backend=backend,
        tree=reg.tree,
        ordering=free_poses.ordering,
        core=free_poses.core,
    )
    t2 = time.perf_counter()
    p2 = phase2_relative_positions(graph, p1, anchor=anchor_id, Omega_Delta=Omega_Delta)
    t3 = time.perf_counter()
    p3 = phase3_poses(  # phase 1's order and core serve phase 3 too
        graph,
        p2,
        anchor=anchor_id,
        backend=backend,
        pose_ordering=free_poses.ordering,
        tree=reg.tree,
        core=free_poses.core,
    )
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
