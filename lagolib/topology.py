"""Graph theory of the pose graph: incidence matrices, spanning trees, chords, cycle bases.

Notation of Carlone, Aragues, Castellanos, Bona, "A Linear Approximation for Graph-based SLAM",
RSS 2011, §II–IV.  The paper has ``n + 1`` nodes ``v_0 … v_n`` and ``m`` edges; a
:class:`~lagolib.graph.PoseGraph` has ``graph.n`` vertices, so **the paper's n is ``graph.n - 1``**.

- the incidence matrix 𝒜, shape (n+1, m): the column of edge ``(i, j)`` has −1 in row ``i``
  (tail) and +1 in row ``j`` (head);
- the reduced incidence matrix ``A`` (eq. 6): 𝒜 without the row of the anchor node;
- ``A2 = A ⊗ I2`` for positions stacked as ``rho = [x_1, y_1, x_2, y_2, …]`` (eq. 5);
- a spanning tree ``T`` (``n`` edges), its chords (the other ``m - n`` edges), the fundamental
  circuit of each chord (Def. 1) and the cycle basis matrix 𝒞 = [I_d ℬ] (eq. 19), ``d = m - n``
  (Cor. 1).

Rows are the graph's vertex rows (``graph.poses`` order) and columns the graph's edge order, except
where a docstring says otherwise.

References
----------
.. [1] L. Carlone, R. Aragues, J. A. Castellanos, B. Bona, "A Linear Approximation for
   Graph-based Simultaneous Localization and Mapping", Robotics: Science and Systems, 2011.
.. [2] W. Chen, *Graph Theory and Its Engineering Applications*, 1997 (fundamental circuits).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, dijkstra

from .checks import check_int
from .errors import GraphError, OptionError, OptionTypeError
from .graph import _numeric, check_graph, vertex_row

__all__ = [
    "incidence_matrix",
    "reduced_incidence_matrix",
    "position_incidence_matrix",
    "SpanningTree",
    "spanning_tree",
    "odometric_tree",
    "bfs_tree",
    "min_uncertainty_tree",
    "orientation_variances",
    "fundamental_circuit",
    "CycleBasis",
    "cycle_basis",
    "cyclomatic_number",
]

TREES = ("min_uncertainty", "odometric", "bfs")


def incidence_matrix(graph):
    """The incidence matrix 𝒜 of the directed pose graph (Carlone et al. 2011, §II).

    Parameters
    ----------
    graph : PoseGraph

    Returns
    -------
    scipy.sparse.csr_matrix, shape (graph.n, graph.m)
        Column ``k`` of edge ``(i, j)``: −1 in row ``i`` (tail), +1 in row ``j`` (head).

    Examples
    --------
    A triangle 0 → 1 → 2 and the chord 0 → 2:

    >>> import numpy as np
    >>> from lagolib import PoseGraph
    >>> g = PoseGraph(np.zeros((3, 3)), [(0, 1), (1, 2), (0, 2)], np.zeros((3, 3)),
    ...               np.tile(np.eye(3), (3, 1, 1)))
    >>> incidence_matrix(g).toarray().astype(int)
    array([[-1,  0, -1],
           [ 1, -1,  0],
           [ 0,  1,  1]])
    """
    check_graph(graph, "incidence_matrix")
    e, m = graph.edges, graph.m
    rows = np.concatenate([e[:, 0], e[:, 1]])
    cols = np.concatenate([np.arange(m), np.arange(m)])
    vals = np.concatenate([-np.ones(m), np.ones(m)])
    # a self-loop (i, i) would sum to a zero column, which is what the definition gives
    return sp.csr_matrix((vals, (rows, cols)), shape=(graph.n, m))


def _anchor_row(graph, anchor, where=None):
    """Row of the vertex id ``anchor`` (default: the smallest id), checked to be one id
    (:func:`lagolib.graph.vertex_row`); ``where`` names the caller in the messages."""
    if where is not None:
        check_graph(graph, where)
    head = f"{where}: " if where else ""
    if anchor is None:
        if graph.n == 0:
            raise GraphError(f"{head}the graph has no vertices, so there is no anchor")
        return int(np.argmin(graph.ids))
    return vertex_row(graph, anchor, f"{head}anchor")


def reduced_incidence_matrix(graph, anchor=None):
    """The reduced incidence matrix ``A``: 𝒜 without the anchor's row (Carlone et al. 2011, eq. 6).

    Parameters
    ----------
    graph : PoseGraph
    anchor : int, optional
        Vertex id whose pose is known (the reference frame, ``p_0 = 0``); default: the smallest id.

    Returns
    -------
    A : scipy.sparse.csr_matrix, shape (graph.n - 1, graph.m)
        Rows are the graph's vertex rows with the anchor's row deleted, in order.

    Notes
    -----
    For a connected graph 𝒜 has rank ``graph.n - 1`` and ``A`` has full row rank (Prop. 1), so
    ``A P_delta^-1 A^T`` is positive definite.
    """
    row = _anchor_row(graph, anchor, "reduced_incidence_matrix")
    keep = np.delete(np.arange(graph.n), row)
    return incidence_matrix(graph)[keep]


def position_incidence_matrix(A):
    """``A2 = A ⊗ I2``, the incidence matrix acting on stacked positions (Carlone et al. 2011, eq. 5).

    Parameters
    ----------
    A : scipy.sparse matrix, shape (r, m)
        An incidence matrix, full (𝒜) or reduced (``A``).

    Returns
    -------
    scipy.sparse.csr_matrix, shape (2 r, 2 m)
        With ``rho = [x_1, y_1, x_2, y_2, …]`` (rows of ``A`` in order) and relative positions
        stacked the same way, ``A2.T @ rho`` is ``[x_j - x_i, y_j - y_i]`` for each edge ``(i, j)``.

    Examples
    --------
    >>> import scipy.sparse as sp
    >>> A = sp.csr_matrix([[-1.0], [1.0]])   # one edge 0 -> 1
    >>> position_incidence_matrix(A).toarray().astype(int)
    array([[-1,  0],
           [ 0, -1],
           [ 1,  0],
           [ 0,  1]])
    """
    where = "position_incidence_matrix"
    if not sp.issparse(A):
        A = _numeric(A, f"{where}: A", float)
    elif A.dtype.kind not in "iuf":
        raise OptionTypeError(f"{where}: A must hold real numbers; got dtype {A.dtype}")
    if A.ndim != 2:
        raise OptionError(f"{where}: A must be a matrix (2-D), shape (r, m); got shape {A.shape}")
    return sp.kron(sp.csr_matrix(A, dtype=float), sp.identity(2), format="csr")


# --------------------------------------------------------------------------- spanning trees
@dataclass(frozen=True, eq=False)
class SpanningTree:
    """A spanning tree of a connected pose graph, rooted at the anchor.

    Attributes
    ----------
    kind : str
        ``"min_uncertainty"``, ``"odometric"`` or ``"bfs"`` (``"given"`` for trees built by hand).
    root : int
        Row of the root vertex (the anchor).
    edges : ndarray of int, shape (n,)
        Tree edges (edge indices), ``n = graph.n - 1`` of them.
    parent : ndarray of int, shape (graph.n,)
        Parent row of each vertex; the root is its own parent.
    parent_edge : ndarray of int, shape (graph.n,)
        Edge joining each vertex to its parent (−1 at the root).
    down : ndarray of bool, shape (graph.n,)
        Whether that edge is stored parent → child (tail at the parent).
    order : ndarray of int, shape (graph.n,)
        Vertices in breadth-first order from the root: parents before children.
    depth : ndarray of int, shape (graph.n,)
        Number of tree edges between each vertex and the root.
    in_tree : ndarray of bool, shape (m,)
        Edge mask of the tree.
    """

    kind: str
    root: int
    edges: np.ndarray
    parent: np.ndarray
    parent_edge: np.ndarray
    down: np.ndarray
    order: np.ndarray
    depth: np.ndarray
    in_tree: np.ndarray

    @property
    def chords(self):
        """ndarray of int, shape (m - n,): edges not in the tree (Cor. 3), in edge order."""
        return np.flatnonzero(~self.in_tree)

    @property
    def d(self):
        """The cyclomatic number ``m - n`` = number of chords (Cor. 1)."""
        return int((~self.in_tree).sum())

    def potentials(self, values):
        """Sums of signed edge values along the tree path from the root to every vertex.

        ``phi[root] = 0`` and ``phi[v] = phi[parent(v)] ± values[parent_edge(v)]`` (+ when the
        edge is stored parent → child).  With ``values`` = the relative orientations δ this is
        the orientation that the tree alone assigns to each node, **not wrapped** (§IV-E).

        Computed by pointer jumping: ``log2(max depth)`` vectorized rounds, no Python loop over
        vertices.

        Parameters
        ----------
        values : array_like, shape (m,)

        Returns
        -------
        ndarray, shape (graph.n,)
        """
        values = _numeric(values, "SpanningTree.potentials: values", float)
        if values.shape != self.in_tree.shape:
            raise OptionError(
                f"SpanningTree.potentials: values must have one entry per edge, shape "
                f"{self.in_tree.shape}; got {values.shape}"
            )
        local = np.zeros(self.parent.size)
        child = np.flatnonzero(self.parent_edge >= 0)
        local[child] = np.where(self.down[child], 1.0, -1.0) * values[self.parent_edge[child]]
        return _sum_to_root(self.parent, self.root, local)

    def path(self, u, v):
        """The tree path from vertex row ``u`` to vertex row ``v``.

        Returns
        -------
        edges : ndarray of int
            Edge indices in the order they are walked.
        signs : ndarray of float
            +1 where an edge is walked from its tail to its head, −1 otherwise.
        """
        last = self.parent.size - 1
        a = check_int(u, "u", "SpanningTree.path", minimum=0, maximum=last)
        b = check_int(v, "v", "SpanningTree.path", minimum=0, maximum=last)
        up_u, up_v = [], []
        while self.depth[a] > self.depth[b]:
            up_u.append(a)
            a = int(self.parent[a])
        while self.depth[b] > self.depth[a]:
            up_v.append(b)
            b = int(self.parent[b])
        while a != b:
            up_u.append(a)
            up_v.append(b)
            a, b = int(self.parent[a]), int(self.parent[b])
        # u climbs to the common ancestor (against 'down'), then v's branch is walked downward
        up_u, up_v = np.array(up_u, dtype=np.int64), np.array(up_v[::-1], dtype=np.int64)
        edges = np.concatenate([self.parent_edge[up_u], self.parent_edge[up_v]]).astype(np.int64)
        signs = np.concatenate(
            [np.where(self.down[up_u], -1.0, 1.0), np.where(self.down[up_v], 1.0, -1.0)]
        )
        return edges, signs


def _sum_to_root(parent, root, local):
    """``out[v]`` = sum of ``local`` over ``v`` and its ancestors, by pointer jumping.

    ``parent[root] == root`` and ``local[root] == 0``; after round ``r``, ``out[v]`` holds the sum
    over the ``2^r`` vertices from ``v`` upward (or up to the root), so ``log2(depth)`` vectorized
    rounds suffice.
    """
    up = parent.copy()
    while np.any(up != root):
        local = local + local[up]
        up = up[up]
    return local


def _disconnected(graph):
    count, labels = graph.components()
    sizes = np.bincount(labels)
    return GraphError(
        f"the graph is not connected: {count} components (sizes "
        f"{', '.join(map(str, sizes[:6]))}{', ...' if count > 6 else ''}); a spanning tree, and "
        "LAGO, need a connected graph (Carlone et al. 2011, Lemma 1) — keep the largest component "
        "or add the missing odometric edges"
    )


def _rooted(graph, kind, tree_edges, root):
    """Orient a set of n tree edges away from ``root``: parents, depths and breadth-first order."""
    n, e = graph.n, graph.edges
    t = np.asarray(tree_edges, dtype=np.int64)
    adj = sp.csr_matrix(
        (
            np.concatenate([t, t]) + 1.0,
            (np.concatenate([e[t, 0], e[t, 1]]), np.concatenate([e[t, 1], e[t, 0]])),
        ),
        shape=(n, n),
    )
    order, pred = breadth_first_order(adj, root, directed=False, return_predecessors=True)
    if order.size != n:
        raise _disconnected(graph)
    parent = np.where(pred < 0, root, pred).astype(np.int64)
    parent[root] = root
    child = np.flatnonzero(np.arange(n) != root)
    parent_edge = np.full(n, -1, dtype=np.int64)
    if child.size:  # a single vertex has no tree edges
        parent_edge[child] = np.asarray(adj[parent[child], child]).ravel().astype(np.int64) - 1
    down = np.zeros(n, dtype=bool)
    down[child] = e[parent_edge[child], 0] == parent[child]
    depth = _sum_to_root(parent, root, (np.arange(n) != root).astype(np.int64))
    in_tree = np.zeros(graph.m, dtype=bool)
    in_tree[t] = True
    for a in (t, parent, parent_edge, down, order, depth, in_tree):
        a.setflags(write=False)
    return SpanningTree(kind, int(root), t, parent, parent_edge, down, order, depth, in_tree)


def odometric_tree(graph, anchor=None):
    """The spanning tree of odometric edges (Carlone et al. 2011, Prop. 2).

    The edges between consecutive ids ``k → k+1`` form a spanning path; the chords are then the
    loop closures (Cor. 3).  Where two edges join the same consecutive pair, the first stored
    forward is the tree edge and the other is a chord; an edge stored ``k+1 → k`` (GTSAM's
    ``.graph`` files) serves when no forward one exists.

    Parameters
    ----------
    graph : PoseGraph
    anchor : int, optional
        Vertex id of the root; default: the smallest id.

    Returns
    -------
    SpanningTree

    Raises
    ------
    GraphError
        If a consecutive pair has no edge (the odometric chain is broken): use :func:`bfs_tree`.
    """
    root = _anchor_row(graph, anchor, "odometric_tree")
    if not graph.is_connected:
        raise _disconnected(graph)
    try:
        edge, _ = graph.odometric_chain()
    except GraphError as exc:
        raise GraphError(f"{exc}. Without it there is no odometric tree: use tree='bfs'") from None
    return _rooted(graph, "odometric", edge, root)


def bfs_tree(graph, anchor=None):
    """A breadth-first spanning tree from the anchor.

    For graphs whose odometric chain is broken.  Among parallel edges the first stored one is
    used.  The tree is shallow (depth = graph distance from the anchor), so its fundamental
    circuits are short.

    Parameters
    ----------
    graph : PoseGraph
    anchor : int, optional
        Vertex id of the root; default: the smallest id.

    Returns
    -------
    SpanningTree

    Raises
    ------
    GraphError
        If the graph is not connected.
    """
    root = _anchor_row(graph, anchor, "bfs_tree")
    n, e = graph.n, graph.edges
    a, b = np.minimum(e[:, 0], e[:, 1]), np.maximum(e[:, 0], e[:, 1])
    key = a * n + b
    ok = a != b
    uniq, first = np.unique(key[ok], return_index=True)
    first = np.flatnonzero(ok)[first]
    adj = sp.csr_matrix(
        (
            np.ones(2 * first.size),
            (np.concatenate([a[first], b[first]]), np.concatenate([b[first], a[first]])),
        ),
        shape=(n, n),
    )
    order, pred = breadth_first_order(adj, root, directed=False, return_predecessors=True)
    if order.size != n:
        raise _disconnected(graph)
    child = order[1:]
    p = pred[child]
    k = np.minimum(p, child) * n + np.maximum(p, child)
    tree = first[np.searchsorted(uniq, k)]
    return _rooted(graph, "bfs", np.sort(tree), root)


def spanning_tree(graph, tree="odometric", anchor=None):
    """A spanning tree by name, or a given :class:`SpanningTree` checked against the graph.

    A spanning tree exists because the pose graph is connected (Carlone et al. 2011, Lemma 1); a
    disconnected graph raises :class:`~lagolib.errors.GraphError` naming its components.

    Parameters
    ----------
    graph : PoseGraph
    tree : {"min_uncertainty", "odometric", "bfs"} or SpanningTree
        :func:`min_uncertainty_tree`, :func:`odometric_tree` or :func:`bfs_tree`.
    anchor : int, optional
        Vertex id of the root; default: the smallest id.

    Returns
    -------
    SpanningTree

    Notes
    -----
    A given :class:`SpanningTree` keeps its own root; ``anchor`` is still checked to be a vertex
    id of the graph.
    """
    _anchor_row(graph, anchor, "spanning_tree")  # the graph, and one vertex id (or None)
    if isinstance(tree, SpanningTree):
        if tree.in_tree.size != graph.m or tree.parent.size != graph.n:
            raise GraphError(
                f"the spanning tree was built for a graph with {tree.parent.size} vertices and "
                f"{tree.in_tree.size} edges; this one has {graph.n} and {graph.m}"
            )
        child = np.flatnonzero(tree.parent_edge >= 0)
        e = graph.edges[tree.parent_edge[child]]
        tail = np.where(tree.down[child], tree.parent[child], child)
        head = np.where(tree.down[child], child, tree.parent[child])
        if not (np.all(e[:, 0] == tail) and np.all(e[:, 1] == head)):
            raise GraphError(
                "the spanning tree was built for another graph with as many vertices and edges: "
                "its edges do not join the vertices they join here; build it from this graph"
            )
        return tree
    if not isinstance(tree, str):
        raise OptionTypeError(
            f"spanning_tree: tree must be a name ({', '.join(map(repr, TREES))}) or a "
            f"SpanningTree; got {type(tree).__name__}"
        )
    if tree == "odometric":
        return odometric_tree(graph, anchor)
    if tree == "bfs":
        return bfs_tree(graph, anchor)
    if tree == "min_uncertainty":
        return min_uncertainty_tree(graph, anchor)
    raise OptionError(
        f"spanning_tree: tree must be one of {', '.join(map(repr, TREES))} or a SpanningTree; "
        f"got {tree!r}"
    )


def orientation_variances(graph):
    """``P_δ`` of each edge: the variance of its relative orientation, in rad².

    The last diagonal entry of the covariance ``Ω_ij⁻¹`` (the same in the g2o frame and in frame
    ``i``: the rotation between them leaves θ alone).

    Returns
    -------
    ndarray, shape (m,)
    """
    check_graph(graph, "orientation_variances")
    return np.linalg.inv(graph.information)[:, 2, 2]


def min_uncertainty_tree(graph, anchor=None):
    """The spanning tree through which every orientation is least uncertain.

    The shortest-path tree from the anchor (Dijkstra) where an edge's length is the variance of
    its relative orientation, ``P_δ`` (:func:`orientation_variances`): each vertex hangs from the
    path whose summed variance is smallest.  Regularization (Carlone et al. 2011, Theorem 3)
    rounds ``𝒞 δ / 2π`` around each chord's fundamental circuit; the noise in that sum is the
    noise accumulated along the circuit, so trees with short, precise paths round correctly on
    graphs where the odometric tree's long paths pass ±π.  With equal variances it is a
    breadth-first tree (fewest edges to the anchor).  Ties — several parents on equally precise
    paths — go to the parent that comes first in breadth-first order, so with equal variances
    this *is* :func:`bfs_tree`.  Among parallel edges the most precise one is used.

    Parameters
    ----------
    graph : PoseGraph
    anchor : int, optional
        Vertex id of the root; default: the smallest id.

    Returns
    -------
    SpanningTree

    Raises
    ------
    GraphError
        If the graph is not connected.

    Examples
    --------
    A square with a precise diagonal: vertex 2 hangs from the diagonal, not from the
    imprecise two-edge path.

    >>> import numpy as np
    >>> from lagolib import PoseGraph
    >>> info = np.tile(np.eye(3), (5, 1, 1)); info[4, 2, 2] = 100.0
    >>> g = PoseGraph(np.zeros((4, 3)), [(0, 1), (1, 2), (2, 3), (3, 0), (0, 2)],
    ...               np.zeros((5, 3)), info)
    >>> t = min_uncertainty_tree(g)
    >>> t.edges.tolist(), t.chords.tolist()
    ([0, 3, 4], [1, 2])
    """
    root = _anchor_row(graph, anchor, "min_uncertainty_tree")
    n, e = graph.n, graph.edges
    var = orientation_variances(graph)
    tiny = np.finfo(float).tiny
    ok = (e[:, 0] != e[:, 1]) & np.isfinite(var) & (var > 0)
    a, b = np.minimum(e[:, 0], e[:, 1]), np.maximum(e[:, 0], e[:, 1])
    k = np.flatnonzero(ok)
    # the most precise of parallel edges: sort by (pair, variance, index) and keep the first
    order = np.lexsort((k, var[k], a[k] * n + b[k]))
    k = k[order]
    key = a[k] * n + b[k]
    uniq = np.ones(k.size, dtype=bool)
    uniq[1:] = key[1:] != key[:-1]
    best, best_key = k[uniq], key[uniq]
    w = np.maximum(var[best], tiny)  # csgraph drops explicit zeros
    adj = sp.csr_matrix(
        (
            np.concatenate([w, w]),
            (np.concatenate([a[best], b[best]]), np.concatenate([b[best], a[best]])),
        ),
        shape=(n, n),
    )
    dist, pred = dijkstra(adj, directed=True, indices=root, return_predecessors=True)
    if not np.all(np.isfinite(dist)):
        raise _disconnected(graph)
    # Ties: many parents can lie on a shortest path (equal variances make every shortest-hop
    # tree a minimum-uncertainty tree).  Take the parent that comes first in breadth-first order,
    # as bfs_tree does; with equal variances the two trees coincide.
    bfs = breadth_first_order(adj, root, directed=False, return_predecessors=False)
    pos = np.empty(n, dtype=np.int64)
    pos[bfs] = np.arange(n)
    src = np.concatenate([a[best], b[best]])
    dst = np.concatenate([b[best], a[best]])
    via = np.concatenate([best, best])
    length = np.concatenate([w, w])
    reach = dist[src] + length
    tight = (dst != root) & (dist[src] < dist[dst]) & (reach <= dist[dst] * (1 + 1e-12))
    src, dst, via = src[tight], dst[tight], via[tight]
    first = np.lexsort((pos[src], dst))
    src, dst, via = src[first], dst[first], via[first]
    keep = np.ones(dst.size, dtype=bool)
    keep[1:] = dst[1:] != dst[:-1]
    parent_edge = np.full(n, -1, dtype=np.int64)
    parent_edge[dst[keep]] = via[keep]
    # a vertex whose variance step underflowed against its distance keeps Dijkstra's parent
    child = np.flatnonzero((np.arange(n) != root) & (parent_edge < 0))
    if child.size:
        p = pred[child]
        pair = np.minimum(p, child) * n + np.maximum(p, child)
        parent_edge[child] = best[np.searchsorted(best_key, pair)]
    tree = parent_edge[np.arange(n) != root]
    return _rooted(graph, "min_uncertainty", np.sort(tree), root)


# --------------------------------------------------------------------------- cycles
def cyclomatic_number(graph):
    """``d = m - n`` for a connected graph: the dimension of its cycle space (Cor. 1).

    In lagolib's count of vertices, ``d = graph.m - graph.n + (number of components)``.
    """
    check_graph(graph, "cyclomatic_number")
    return graph.m - graph.n + graph.components()[0]


def fundamental_circuit(graph, tree, chord):
    """The fundamental circuit of a chord (Carlone et al. 2011, Def. 1).

    The chord ``(i, j)`` walked forward, then the unique tree path from ``j`` back to ``i``.

    Parameters
    ----------
    graph : PoseGraph
    tree : SpanningTree
    chord : int
        Edge index of a chord.

    Returns
    -------
    edges : ndarray of int
        The chord first, then the tree edges in walking order.
    signs : ndarray of float
        +1 for an edge walked tail → head, −1 for one walked backwards: the non-zero entries of
        the circuit vector ``c`` (§IV-E).
    """
    where = "fundamental_circuit"
    check_graph(graph, where)
    if not isinstance(tree, SpanningTree | str):
        raise OptionTypeError(
            f"{where}: tree must be a SpanningTree (or a tree name, {', '.join(map(repr, TREES))}); "
            f"got {type(tree).__name__}"
        )
    tree = spanning_tree(graph, tree)  # a given tree is checked against the graph
    chord = check_int(chord, "chord", where)
    if not 0 <= chord < graph.m or tree.in_tree[chord]:
        raise GraphError(
            f"{where}: edge {chord} is not a chord of this spanning tree (chords: "
            f"{_few(tree.chords)})"
        )
    return _fundamental_circuit(graph, tree, chord)


def _few(values, k=8):
    shown = ", ".join(map(str, values[:k].tolist()))
    return f"[{shown}{', ...' if values.size > k else ''}]"


def _fundamental_circuit(graph, tree, chord):
    """:func:`fundamental_circuit` of a checked tree and chord."""
    i, j = graph.edges[chord]
    edges, signs = tree.path(j, i)
    return np.concatenate([[chord], edges]), np.concatenate([[1.0], signs])


@dataclass(frozen=True, eq=False)
class CycleBasis:
    """The fundamental cycle basis of a spanning tree (Carlone et al. 2011, Thm. 2, eq. 19).

    Attributes
    ----------
    C : scipy.sparse.csr_matrix, shape (d, m)
        Row ``c`` is the circuit vector of the ``c``-th chord, columns in the graph's edge order.
    chords : ndarray of int, shape (d,)
    tree_edges : ndarray of int, shape (n,)
    """

    C: sp.csr_matrix
    chords: np.ndarray
    tree_edges: np.ndarray

    @property
    def d(self):
        """Cyclomatic number (Cor. 1)."""
        return int(self.chords.size)

    @property
    def edge_order(self):
        """ndarray of int, shape (m,): chords first, then tree edges — the column order of eq. 19."""
        return np.concatenate([self.chords, self.tree_edges])

    @property
    def ordered(self):
        """𝒞 with columns in :attr:`edge_order`: the form ``[I_d ℬ]`` of eq. 19 (Cor. 2)."""
        return self.C[:, self.edge_order]

    @property
    def B(self):
        """ℬ of eq. 19, shape (d, n): entries in {−1, 0, 1}, columns in tree-edge order."""
        return self.C[:, self.tree_edges]


def cycle_basis(graph, tree="odometric", anchor=None):
    """Cycle basis matrix 𝒞 of the fundamental circuits (Carlone et al. 2011, eq. 19).

    Parameters
    ----------
    graph : PoseGraph
    tree : {"odometric", "bfs"} or SpanningTree
    anchor : int, optional
        Root of the tree (default: the smallest id).

    Returns
    -------
    CycleBasis
        ``𝒞 𝒜^T = 0``: every circuit enters each node as often as it leaves it.

    Notes
    -----
    ``nnz(𝒞)`` is the total length of the fundamental circuits — up to ``d × n`` for the
    odometric tree of a long trajectory — so this is for teaching and small graphs.  LAGO's
    regularization only needs ``𝒞 δ``, which :meth:`SpanningTree.potentials` gives in
    ``O(m log n)`` without forming 𝒞.

    Examples
    --------
    A square 0 → 1 → 2 → 3 with the loop closure 3 → 0 and a diagonal 0 → 2:

    >>> import numpy as np
    >>> from lagolib import PoseGraph
    >>> g = PoseGraph(np.zeros((4, 3)), [(0, 1), (1, 2), (2, 3), (3, 0), (0, 2)],
    ...               np.zeros((5, 3)), np.tile(np.eye(3), (5, 1, 1)))
    >>> basis = cycle_basis(g)
    >>> basis.chords, basis.d
    (array([3, 4]), 2)
    >>> basis.ordered.toarray().astype(int)
    array([[ 1,  0,  1,  1,  1],
           [ 0,  1, -1, -1,  0]])

    References
    ----------
    Chen, *Graph Theory and Its Engineering Applications*, 1997; Carlone et al. 2011, §IV-E.
    """
    _anchor_row(graph, anchor, "cycle_basis")
    tree = spanning_tree(graph, tree, anchor)
    rows, cols, vals = [], [], []
    for c, chord in enumerate(tree.chords):
        edges, signs = _fundamental_circuit(graph, tree, chord)
        rows.append(np.full(edges.size, c))
        cols.append(edges)
        vals.append(signs)
    d = tree.d
    if d:
        rows, cols, vals = map(np.concatenate, (rows, cols, vals))
    C = sp.csr_matrix((vals, (rows, cols)), shape=(d, graph.m))
    return CycleBasis(C, tree.chords, tree.edges)
