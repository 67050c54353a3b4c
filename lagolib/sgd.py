"""A TORO-style iterative baseline: stochastic gradient descent on a tree parameterization.

Carlone et al. 2011 (§V, Table II, Fig. 3) compare LAGO with TORO, the *Tree-based netwORk
Optimizer* of Grisetti et al. [2]_, which refines Olson et al.'s stochastic gradient descent [1]_.
This module is a compact optimizer in that spirit, written here from the papers' description:

* **Tree parameterization** ([2]_).  A spanning tree is rooted at the anchor; each other
  vertex ``k`` is parameterized by its pose *difference* to its parent in the **global frame**,
  ``x_k = p_k − p_parent(k)`` (angles not wrapped).  A pose is the sum of the parameters on its
  path to the root, so changing ``x_k`` moves the whole subtree of ``k`` rigidly by a
  translation (or turns every orientation in it by the same angle, without moving positions:
  the first-order approximation of the incremental parameterization [1]_).
* **Per-constraint updates** ([1]_, [2]_).  The residual of constraint ``(a, b)`` in the global
  frame is ``r = (p_a ⊕ z_ab) − p_b``.  A fraction ``f`` of it is spread over the parameters of
  the tree path ``P_ab`` from ``a`` to ``b``: parameter ``k`` receives
  ``± f r M_k⁻¹ / Σ_{j∈P_ab} M_j⁻¹`` (``+`` on ``b``'s side of the path, ``−`` on ``a``'s), so
  the constraint's residual shrinks by ``f r`` while stiff parts of the tree move less.  ``M`` is
  Olson's diagonal preconditioner, ``M_k = Σ_{c ∋ k} diag(Ω_c)`` over the constraints whose path
  contains ``k``, with each information matrix rotated into the global frame.
* **Decreasing learning rate** ([1]_, [2]_).  At iteration ``t`` (one pass over all
  constraints) ``f = min(1, λ_t |P_ab| ω_ab)`` per coordinate, with ``λ_t = 1 / (γ t)``,
  ``ω_ab`` the diagonal of the constraint's information in the global frame, and ``γ`` the
  smallest information of any constraint in that coordinate — so no update overshoots its own
  constraint, and the steps shrink like ``1/t`` once ``t`` exceeds ``|P_ab| ω_ab / γ``.
* **Rotation first** ([2]_): orientations are corrected first; the translational residuals are
  then computed with the corrected orientations.

Sequential updates run at numpy speed: within a pass over one coordinate a constraint's
residual depends only on the parameters of its path, and its update changes only those, so
constraints whose paths share no parameter can be updated at once with the same result as one
after the other.  The order is cut into such *rounds* (first fit); a round is a handful of
vectorized operations.  :func:`sgd_reference` performs the same updates one constraint at a
time on the absolute poses (every update moving whole subtrees) and is tested equal.

What differs from TORO — this is written from the papers, not from TORO's code, and its
numbers are not TORO's:

* one iteration corrects every constraint's orientation, then every constraint's translation
  (TORO corrects both parts of one constraint before moving to the next);
* the processing order: deepest common ancestor first (the papers process constraints by the
  level of their path's top node), then the rounds above;
* the tree: lagolib's breadth-first tree (shallow, short paths) unless another is given;
* the learning rate and ``γ`` are the simple rule above; TORO's implementation has further
  refinements that are not reproduced.

What to expect.  SGD corrects each constraint in turn, not the information-weighted sum: it
brings the constraint-satisfaction metrics (:func:`lagolib.metrics.constraint_satisfaction`)
down fast, but its χ² levels off above the optimum — within 2–3x of Gauss–Newton's on INTEL,
M3500, MIT and FR079 after 300 iterations, 30–70x on CSAIL and ring — and started at an optimum
it moves away from it (``f`` stays 1 on constraints whose information is far above ``γ``).
With anisotropic information the result depends on the world frame: the preconditioner is the
diagonal of the information rotated into it.  It is the baseline of Carlone et al.'s Table II,
not a solver to finish with; :func:`lagolib.optimize` is.

References
----------
.. [1] E. Olson, J. Leonard, S. Teller, "Fast Iterative Optimization of Pose Graphs with Poor
   Initial Estimates", ICRA 2006.
.. [2] G. Grisetti, C. Stachniss, S. Grzonka, W. Burgard, "A Tree Parameterization for Efficiently
   Computing Maximum Likelihood Maps using Gradient Descent", Robotics: Science and Systems 2007.
.. [3] L. Carlone, R. Aragues, J. A. Castellanos, B. Bona, "A Linear Approximation for
   Graph-based Simultaneous Localization and Mapping", RSS 2011, §V.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import depth_first_order

from . import se2
from .checks import check_bool, check_callback, check_int
from .errors import GraphError, OptionError
from .graph import PoseGraph, as_graph_poses, check_graph, chi2
from .topology import SpanningTree, _anchor_row, spanning_tree

__all__ = ["SGDResult", "TreeParameterization", "sgd", "sgd_reference"]


# ----------------------------------------------------------------------------- the tree
@dataclass(frozen=True, eq=False)
class TreeParameterization:
    """A rooted spanning tree laid out for subtree and path sums in ``O(n)`` numpy operations.

    In depth-first preorder every subtree is a contiguous range ``[start[k], end[k])``; the sum
    over a subtree is then a difference of prefix sums, and adding a value to a whole subtree is
    a difference array — the two operations of the tree parameterization (Grisetti et al. 2007,
    §IV).

    Attributes
    ----------
    tree : SpanningTree
    preorder : ndarray of int, shape (n,)
        Vertex rows in depth-first preorder from the root.
    start, end : ndarray of int, shape (n,)
        Subtree of vertex row ``k`` = ``preorder[start[k]:end[k]]``.
    lca : ndarray of int, shape (m,)
        Lowest common ancestor (vertex row) of each edge's two ends.
    path_length : ndarray of int, shape (m,)
        ``|P_ab|``: tree edges on the path between each edge's ends (0 for a self-loop).
    """

    tree: SpanningTree
    preorder: np.ndarray
    start: np.ndarray
    end: np.ndarray
    lca: np.ndarray
    path_length: np.ndarray
    edges: np.ndarray  # (m, 2): the graph's edges (vertex rows) it was built for
    ends: sp.csr_matrix  # (n, m): +1 at each edge's two ends, −2 at their common ancestor
    _diff: sp.csr_matrix  # (n + 1, n): +1 at (start[k], k), −1 at (end[k], k)

    def subtree_sums(self, q):
        """``out[k] = Σ_{v in subtree(k)} q[v]``; ``q`` of shape (n,) or (n, d)."""
        prefix = np.zeros((q.shape[0] + 1,) + q.shape[1:])
        np.cumsum(q[self.preorder], 0, out=prefix[1:])
        return prefix[self.end] - prefix[self.start]

    def add_to_subtrees(self, dx):
        """``out[v] = Σ_{k ancestor of v, or v} dx[k]``: what adding ``dx[k]`` to the subtree of
        every ``k`` does.  Also the sum of ``dx`` along each vertex's path to the root."""
        diff = self._diff @ dx  # a difference array over the preorder
        out = np.empty_like(dx, dtype=float)
        out[self.preorder] = np.cumsum(diff[:-1], 0)
        return out


def tree_parameterization(graph, tree="bfs", anchor=None):
    """Lay out a spanning tree of ``graph`` for :func:`sgd` (preorder ranges, each edge's LCA).

    Parameters
    ----------
    graph : PoseGraph
        Connected.
    tree : {"bfs", "odometric", "min_uncertainty"} or SpanningTree
    anchor : int, optional
        Vertex id of the root (default: the smallest id).

    Returns
    -------
    TreeParameterization
    """
    _anchor_row(graph, anchor, "tree_parameterization")  # the graph, and one vertex id or None
    if isinstance(tree, SpanningTree):
        t = spanning_tree(graph, tree)  # checks a given tree against the graph
        _check_anchor(graph, t, anchor, "tree_parameterization")
    else:
        t = spanning_tree(graph, tree, anchor)
    n, root = graph.n, t.root
    child = np.flatnonzero(t.parent != np.arange(n))
    adj = sp.csr_matrix((np.ones(child.size), (t.parent[child], child)), shape=(n, n))
    preorder = depth_first_order(adj, root, directed=True, return_predecessors=False)
    start = np.empty(n, dtype=np.int64)
    start[preorder] = np.arange(n)
    size = [1] * n  # subtree sizes, children before parents (reverse breadth-first order)
    parent = t.parent.tolist()
    for v in t.order[:0:-1].tolist():
        size[parent[v]] += size[v]
    end = start + np.asarray(size, dtype=np.int64)
    lca = _lowest_common_ancestors(t, graph.edges[:, 0], graph.edges[:, 1])
    length = t.depth[graph.edges[:, 0]] + t.depth[graph.edges[:, 1]] - 2 * t.depth[lca]
    for a in (preorder, start, end, lca, length):
        a.setflags(write=False)
    m, k = graph.m, np.arange(n)
    ends = sp.csr_matrix(
        (
            np.repeat([1.0, 1.0, -2.0], m),
            (np.concatenate([graph.edges[:, 0], graph.edges[:, 1], lca]), np.tile(np.arange(m), 3)),
        ),
        shape=(n, m),
    )
    diff = sp.csr_matrix(
        (np.repeat([1.0, -1.0], n), (np.concatenate([start, end]), np.concatenate([k, k]))),
        shape=(n + 1, n),
    )
    edges = graph.edges.copy()
    edges.setflags(write=False)
    return TreeParameterization(t, preorder, start, end, lca, length, edges, ends, diff)


def _lowest_common_ancestors(tree, a, b):
    """LCA of vertex rows ``a[i]``, ``b[i]`` by binary lifting (``log2(depth)`` numpy rounds)."""
    up = [tree.parent.astype(np.int64)]
    for _ in range(max(int(tree.depth.max()), 1).bit_length()):
        up.append(up[-1][up[-1]])
    a, b = a.astype(np.int64).copy(), b.astype(np.int64).copy()
    swap = tree.depth[a] < tree.depth[b]
    a[swap], b[swap] = b[swap], a[swap].copy()
    gap = tree.depth[a] - tree.depth[b]  # lift a to b's depth
    for j, anc in enumerate(up):
        bit = (gap >> j) & 1 == 1
        a[bit] = anc[a[bit]]
    for anc in reversed(up):  # lift both while their ancestors differ
        differ = anc[a] != anc[b]
        a[differ], b[differ] = anc[a[differ]], anc[b[differ]]
    return np.where(a == b, a, tree.parent[a])


# ----------------------------------------------------------------------------- one iteration
def _global_information_diagonal(graph, theta):
    """``ω`` (m, 3): diagonal of each edge's information rotated into the global frame.

    lagolib stores ``Ω_ab`` in the g2o frame (the frame of ``p_a ⊕ z_ab``); the global-frame
    residual ``r = (p_a ⊕ z_ab) − p_b`` is that error rotated by ``φ = θ_a + δ_ab``, so
    ``Ω_global = G Ω Gᵀ`` with ``G = blockdiag(R(φ), 1)``; its diagonal is written out.
    """
    phi = theta[graph.edges[:, 0]] + graph.measurements[:, 2]
    c, s, info = np.cos(phi), np.sin(phi), graph.information
    cs2 = 2.0 * c * s * info[:, 0, 1]
    xx = c * c * info[:, 0, 0] - cs2 + s * s * info[:, 1, 1]  # (R Ω_tt Rᵀ)_xx
    yy = s * s * info[:, 0, 0] + cs2 + c * c * info[:, 1, 1]  # (R Ω_tt Rᵀ)_yy
    return np.column_stack([xx, yy, info[:, 2, 2]])


def _learning_rate_scale(graph):
    """``γ`` (3,): the smallest information of any constraint per coordinate (Olson's ``γ``),
    rotation-invariant: the smaller eigenvalue of the translational block, and ``Ω_θθ``."""
    if graph.m == 0:
        return np.ones(3)  # nothing to scale: no constraint, no update
    lam_min = np.linalg.eigvalsh(graph.information[:, :2, :2])[:, 0]
    return np.array([lam_min.min(), lam_min.min(), graph.information[:, 2, 2].min()])


def _step_sizes(graph, par, theta, t, gamma):
    """What stays fixed during iteration ``t``: ``M⁻¹`` (n, 3) and ``f_c / S_c`` (m, 3).

    Olson's preconditioner ``M_k = Σ_{c: k ∈ P_c} ω_c`` (Olson et al. 2006) is a subtree
    sum of ``+ω`` at both ends of every constraint and ``−2ω`` at their common ancestor; the
    path sums ``S_c = Σ_{j∈P_c} M_j⁻¹`` are root-path sums; the fraction of its residual each
    constraint corrects is ``f_c = min(1, λ_t |P_c| ω_c)``, ``λ_t = 1/(γ t)`` (Grisetti et al.
    2007).
    """
    e, n = graph.edges, graph.n
    omega = _global_information_diagonal(graph, theta)
    M = par.subtree_sums(par.ends @ omega)
    inv_M = np.zeros_like(M)
    free = par.tree.parent != np.arange(n)
    inv_M[free] = 1.0 / M[free]
    R = par.add_to_subtrees(inv_M)  # Σ of M⁻¹ from the root down to each vertex
    S = R[e[:, 0]] + R[e[:, 1]] - 2.0 * R[par.lca]
    f = np.minimum(1.0, par.path_length[:, None] * omega / (gamma * t))
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.where(par.path_length[:, None] > 0, f / S, 0.0)
    return inv_M, g


@dataclass(frozen=True, eq=False)
class _Rounds:
    """The sequential order of per-constraint updates, cut into rounds of constraints whose tree
    paths share no parameter.  Within a pass over one coordinate a constraint's residual
    depends only on the parameters of its path, and its update changes only those, so the
    constraints of a round can be updated at once and the result equals the one-at-a-time order.

    ``constraints`` (K,) are all constraints, round after round, and ``nodes``/``signs`` (E,) the
    parameters on their paths (−1 on the tail's side); per round: the slices of both and, for its
    entries, the position of their constraint in the round and where each constraint starts.
    """

    constraints: np.ndarray
    nodes: np.ndarray
    signs: np.ndarray
    rounds: list  # per round: (constraint slice, entry slice, nodes, signs (e,), segment, starts)


def _rounds(paths, order):
    """Cut the processing order into rounds (first fit: each constraint joins the earliest round
    in which none of its parameters is used yet).  The sequential order the rounds implement is
    round by round, and within a round in ``order``."""
    used = {}  # parameter -> set of rounds using it
    groups = []
    for c in order:
        taken = set().union(*(used.get(k, ()) for k, _ in paths[c]))
        r = next(i for i in range(len(groups) + 1) if i not in taken)
        if r == len(groups):
            groups.append([])
        groups[r].append(c)
        for k, _ in paths[c]:
            used.setdefault(k, set()).add(r)
    cons = [c for cs in groups for c in cs]
    nodes = np.array([k for c in cons for k, _ in paths[c]], dtype=np.int64)
    signs = np.array([s for c in cons for _, s in paths[c]])
    rounds, c0, e0 = [], 0, 0
    for cs in groups:
        lengths = np.array([len(paths[c]) for c in cs], dtype=np.int64)
        c1, e1 = c0 + len(cs), e0 + int(lengths.sum())
        starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
        segment = np.repeat(np.arange(len(cs)), lengths)
        rounds.append((slice(c0, c1), slice(e0, e1), nodes[e0:e1], signs[e0:e1], segment, starts))
        c0, e0 = c1, e1
    return _Rounds(np.array(cons, dtype=np.int64), nodes, signs, rounds)


def _sweep(rounds, x, target, g, inv_M, wrap):
    """One pass of per-constraint updates over one coordinate ``x`` (n,) (Grisetti et al. 2007,
    the update rule), in place.

    For each constraint ``c``: its residual is ``r = target_c − Σ_{k∈P_c} s_k x_k`` (``p_b − p_a``
    is the signed sum of the parameters on its path), and parameter ``k`` on the path moves by
    ``s_k f_c r M_k⁻¹ / S_c`` — so the path's sum moves by exactly ``f_c r``.  A round at a time
    (:class:`_Rounds`); :func:`sgd_reference` does the same one constraint at a time.
    """
    target, g = target[rounds.constraints], g[rounds.constraints]  # in round order
    coef = rounds.signs * inv_M[rounds.nodes]  # s_k M_k⁻¹ of every path entry
    for cs, es, k, s, seg, starts in rounds.rounds:
        xk = x[k]
        r = target[cs] - np.add.reduceat(s * xk, starts)  # residual, global frame
        if wrap:
            r = _wrap(r)
        x[k] = xk + coef[es] * (g[cs] * r)[seg]  # the update; no parameter twice in a round


def _sweep_xy(rounds, xy, target, g, inv_M):
    """:func:`_sweep` over both position coordinates at once: ``xy`` (n,) complex ``x + iy``,
    ``target`` (m,) complex, ``g`` and ``inv_M`` (·, 2) real (one factor per coordinate)."""
    target, g = target[rounds.constraints], g[rounds.constraints]  # in round order
    coef = rounds.signs[:, None] * inv_M[rounds.nodes]  # (E, 2)
    for cs, es, k, s, seg, starts in rounds.rounds:
        xk = xy[k]
        r = target[cs] - np.add.reduceat(s * xk, starts)  # residual, global frame
        w = g[cs] * r.view(np.float64).reshape(-1, 2)  # f_c r / S_c per coordinate
        xy[k] = xk + (coef[es] * w[seg]).view(np.complex128).ravel()


def _iterate(graph, par, rounds, x, t, gamma, theta_root):
    """One SGD iteration on the tree parameters ``x`` (n, 3), in place: every constraint's
    orientation residual first, then — with the new orientations — its translational one.
    ``theta_root``: the anchor's orientation (fixed), which every absolute orientation adds."""
    theta = theta_root + par.add_to_subtrees(x[:, 2])  # absolute orientations, unwrapped
    inv_M, g = _step_sizes(graph, par, theta, t, gamma)
    xd = x[:, 2].copy()
    _sweep(rounds, xd, graph.measurements[:, 2], g[:, 2], inv_M[:, 2], True)
    x[:, 2] = xd
    theta = theta_root + par.add_to_subtrees(x[:, 2])
    a = graph.edges[:, 0]
    u = np.einsum("kij,kj->ki", se2.rotation(theta[a]), graph.measurements[:, :2])  # R(θ_a) Δ_ab
    xy = x[:, 0] + 1j * x[:, 1]  # x and y are independent once the orientations are fixed
    _sweep_xy(rounds, xy, u[:, 0] + 1j * u[:, 1], np.ascontiguousarray(g[:, :2]), inv_M[:, :2])
    x[:, 0], x[:, 1] = xy.real, xy.imag


def _tree_paths(graph, par):
    """Per edge, the list of ``(k, s)``: parameters on its tree path, ``s = −1`` on the tail's side."""
    parent, depth = par.tree.parent.tolist(), par.tree.depth.tolist()
    paths = []
    for a, b in graph.edges.tolist():
        path = []
        while a != b:
            if depth[a] >= depth[b]:
                path.append((a, -1.0))
                a = parent[a]
            else:
                path.append((b, 1.0))
                b = parent[b]
        paths.append(path)
    return paths


def _processing_order(par):
    """Constraints with a path (not self-loops), deepest common ancestor first, as TORO sorts
    them by the level of their path's top node (stable: edge order within a level)."""
    active = np.flatnonzero(par.path_length > 0)
    depth = par.tree.depth[par.lca[active]]
    return active[np.argsort(-depth, kind="stable")].tolist()


def _to_parameters(par, p):
    """``x_k = p_k − p_parent(k)`` (global frame), 0 at the root."""
    x = p - p[par.tree.parent]
    x[par.tree.root] = 0.0
    return x


def _to_poses(par, x, root_pose):
    return root_pose + par.add_to_subtrees(x)


# ----------------------------------------------------------------------------- sgd
@dataclass(eq=False)
class SGDResult:
    """What :func:`sgd` returns.

    Attributes
    ----------
    poses : ndarray, shape (n, 3)
        The last iterate, angles wrapped to ``(-pi, pi]`` (SGD does not keep the best iterate:
        its objective need not decrease monotonically).
    chi2 : float
        Its ``Σ e_ijᵀ Ω_ij e_ij`` (the notes' t2v error).
    chi2_history : list of float
        χ² at the start and after every iteration (``history=True``), else at the start and the
        end.
    iterations : int
    tree : TreeParameterization
    timings : dict
        Seconds: ``setup``, ``iterations`` (list, one per iteration) and ``total``.
    graph : PoseGraph
    """

    poses: np.ndarray
    chi2: float
    chi2_history: list
    iterations: int
    tree: TreeParameterization
    graph: PoseGraph
    timings: dict = field(default_factory=dict)

    def __repr__(self):
        return f"SGDResult(chi2={self.chi2:.10g}, iterations={self.iterations})"


def _setup(graph, initial, iterations, tree, anchor, callback, verbose, where):
    check_graph(graph, where)
    _anchor_row(graph, anchor, where)  # one vertex id of the graph, or None
    iterations = check_int(iterations, "iterations", where, minimum=0)
    check_callback(callback, "callback", where)
    verbose = check_bool(verbose, "verbose", where)
    p = as_graph_poses(graph, initial, "initial", "initial guess").copy()
    if isinstance(tree, TreeParameterization):
        if not np.array_equal(tree.edges, graph.edges):
            raise GraphError(
                f"{where}: the TreeParameterization was built for another graph (its edges "
                "differ from this graph's); build it with tree_parameterization(graph, ...)"
            )
        _check_anchor(graph, tree.tree, anchor, where)
        par = tree
    else:  # checks a given SpanningTree and its anchor
        par = tree_parameterization(graph, tree, anchor)
    return iterations, verbose, p, par


#: Positions and measured translations beyond ``2**_SCALE_ABOVE`` (about 1e77) are scaled down.
_SCALE_ABOVE = 256


def _scaled(graph, p):
    """``(graph, p, k)`` with translations divided by ``2**k`` when they are huge, else ``k = 0``.

    SGD's translational updates are linear in the translations (the step fractions depend on the
    information and the orientations only), so running on ``2**-k`` times the positions and
    measured translations and multiplying back is exact — while near ±1e308 the differences
    ``p_k − p_parent(k)``, the residuals and their products with the step sizes would overflow
    to ``inf`` and NaN.  :mod:`lagolib.metrics` scales the same way.  One O(n + m) pass.
    """
    big = max(
        np.max(np.abs(p[:, :2]), initial=0.0),
        np.max(np.abs(graph.measurements[:, :2]), initial=0.0),
    )
    if big < 2.0**_SCALE_ABOVE:
        return graph, p, 0
    k = int(np.frexp(big)[1])
    p = p.copy()
    p[:, :2] = np.ldexp(p[:, :2], -k)
    return graph._scaled_translations(k), p, k


def _unscaled(graph, p, k, where):
    """Poses ``p`` of the scaled problem back in the graph's units; a GraphError names the first
    vertex whose position is beyond float64."""
    if k == 0:
        return p
    out = p.copy()
    with np.errstate(over="ignore"):
        out[:, :2] = np.ldexp(p[:, :2], k)
    bad = np.flatnonzero(~np.all(np.isfinite(out), axis=1))
    if bad.size:
        v = int(bad[0])
        raise GraphError(
            f"{where}: the iterate left float64's range: vertex id {graph.ids[v]} reached "
            f"position {out[v, :2].tolist()}; the poses are too close to ±1.8e308 — move the "
            "map towards the origin",
            vertex=v,
        )
    return out


def _check_anchor(graph, tree, anchor, where):
    """A given tree is rooted at its own anchor: an ``anchor`` that differs is a misuse."""
    if anchor is not None and tree.root != _anchor_row(graph, anchor, where):
        raise OptionError(
            f"{where}: anchor={anchor!r} differs from the root of the given tree (vertex id "
            f"{graph.ids[tree.root]}); leave anchor out, or build the tree from that anchor"
        )


def sgd(
    graph,
    initial=None,
    *,
    iterations=100,
    tree="bfs",
    anchor=None,
    callback=None,
    history=True,
    verbose=False,
):
    """TORO-style stochastic gradient descent on a tree parameterization (module docstring).

    One iteration is one pass over all constraints, deepest common ancestor first::

        for t in 1 .. iterations:
            M, S = preconditioner(θ)                  # Olson et al. 2006
            f = min(1, |P_ab| ω_ab / (γ t))            # Grisetti et al. 2007
            for each constraint (a, b):                # orientations first ...
                spread f r_θ over the path P_ab        # Grisetti et al. 2007
            for each constraint (a, b):                # ... then positions, with the new θ
                spread f r_xy over the path P_ab

    Parameters
    ----------
    graph : PoseGraph
        Connected; information in the g2o frame (rotated into the global frame per constraint).
    initial : array_like, shape (n, 3), optional
        Initial guess, default ``graph.poses``.  The anchor stays where it is.
    iterations : int
        Passes over all constraints (``>= 0``).
    tree : {"bfs", "odometric", "min_uncertainty"} or SpanningTree or TreeParameterization
        The parameterization's tree; breadth-first by default (shallow, like TORO's).  The cost
        of an iteration is proportional to the total length of the constraints' tree paths:
        short for a breadth-first tree, long for the odometric chain.
    anchor : int, optional
        Vertex id of the root, held fixed (default: the smallest id).
    callback : callable, optional
        ``callback(iteration, poses)`` after every iteration (``poses`` wrapped, a copy).
    history : bool
        Record χ² after every iteration (it costs about a fifth of an iteration); ``False``
        records it at the start and the end only.
    verbose : bool
        Print χ² after every iteration (implies ``history``).

    Returns
    -------
    SGDResult

    Raises
    ------
    GraphError
        Disconnected graph, unknown anchor, a broken odometric chain for ``tree="odometric"``,
        or a bad ``initial``.
    OptionError, OptionTypeError
        A bad option (the message names it).

    Examples
    --------
    >>> import lagolib
    >>> from lagolib.sgd import sgd
    >>> ex = lagolib.datasets.example("square_loop")
    >>> res = sgd(ex.graph, iterations=50)
    >>> gn = lagolib.optimize(ex.graph)
    >>> round(res.chi2_history[0]), round(res.chi2, 1), round(gn.chi2, 1)
    (20730, 341.8, 321.7)
    """
    t0 = time.perf_counter()
    iterations, verbose, p, par = _setup(
        graph, initial, iterations, tree, anchor, callback, verbose, "sgd"
    )
    history = check_bool(history, "history", "sgd")
    work, p, k = _scaled(graph, p)  # far from float64's limits (k = 0: nothing to do)
    root_pose = p[par.tree.root].copy()
    x = _to_parameters(par, p)
    rounds = _rounds(_tree_paths(graph, par), _processing_order(par))
    gamma = _learning_rate_scale(graph)
    chis, per_iteration = [chi2(graph, _unscaled(graph, p, k, "sgd"))], []
    t_setup = time.perf_counter() - t0
    for t in range(1, iterations + 1):
        ti = time.perf_counter()
        _iterate(work, par, rounds, x, t, gamma, root_pose[2])
        p = _to_poses(par, x, root_pose)
        if history or verbose or t == iterations:
            chis.append(chi2(graph, _unscaled(graph, p, k, "sgd")))
        per_iteration.append(time.perf_counter() - ti)
        if verbose:
            print(f"iter {t:4d}  chi2 {chis[-1]:.10g}")
        if callback is not None:
            callback(t, _wrapped(_unscaled(graph, p, k, "sgd")))
    timings = {"setup": t_setup, "iterations": per_iteration, "total": time.perf_counter() - t0}
    poses = _wrapped(_unscaled(graph, p, k, "sgd"))
    return SGDResult(poses, chis[-1], chis, iterations, par, graph, timings)


def _wrap(angle):
    """Angles to ``[-pi, pi)`` without :func:`lagolib.se2.wrap_angle`'s checks (inner loop)."""
    return np.remainder(angle + np.pi, 2.0 * np.pi) - np.pi


def _wrapped(p):
    out = p.copy()
    out[:, 2] = se2.wrap_angle(out[:, 2])
    return out


def sgd_reference(graph, initial=None, *, iterations=100, tree="bfs", anchor=None):
    """:func:`sgd` written on the absolute poses: every update moves whole subtrees.

    The same iteration as :func:`sgd`, without the parameters ``x``: changing ``x_k`` adds to
    the pose of every vertex in the subtree of ``k`` (Grisetti et al. 2007, §IV), so each update
    is written as that — ``O(m · path · subtree)`` per iteration, for small graphs and for
    testing :func:`sgd` against.

    Returns
    -------
    ndarray, shape (n, 3)
        The poses after ``iterations`` passes, angles wrapped.
    """
    iterations, _, p, par = _setup(
        graph, initial, iterations, tree, anchor, None, False, "sgd_reference"
    )
    work, p, scale = _scaled(graph, p)  # far from float64's limits (0: nothing to do)
    n, e, z = graph.n, graph.edges, work.measurements
    subtree = [par.preorder[par.start[k] : par.end[k]] for k in range(n)]
    gamma = _learning_rate_scale(graph)
    paths = _tree_paths(graph, par)
    order = _rounds(paths, _processing_order(par)).constraints  # round by round
    for t in range(1, iterations + 1):
        omega = _global_information_diagonal(graph, p[:, 2])
        M = np.zeros((n, 3))
        for c, P in enumerate(paths):
            for k, _ in P:
                M[k] += omega[c]  # Olson's preconditioner
        f = [np.minimum(1.0, len(P) * omega[c] / (gamma * t)) for c, P in enumerate(paths)]
        S = [sum((1.0 / M[k] for k, _ in P), np.zeros(3)) for P in paths]
        for c in order:  # orientations: move b's side by +f r, a's side by −f r
            a, b = e[c]
            r = _wrap(p[a, 2] + z[c, 2] - p[b, 2])
            for k, s in paths[c]:
                p[subtree[k], 2] += s * f[c][2] * r / M[k, 2] / S[c][2]
        theta_a = p[e[:, 0], 2].copy()  # the orientations the translational pass uses
        for c in order:
            a, b = e[c]
            r = p[a, :2] + se2.rotation(theta_a[c]) @ z[c, :2] - p[b, :2]
            for k, s in paths[c]:
                p[subtree[k], :2] += s * f[c][:2] * r / M[k, :2] / S[c][:2]
    return _wrapped(_unscaled(graph, p, scale, "sgd_reference"))
