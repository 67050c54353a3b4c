"""Checks for the exercises of chapter 4, *Graphs and cycles*.

===========  =========  ==========================================================================
exercise     kind       check
===========  =========  ==========================================================================
4.1          implement  :func:`check_incidence` — the incidence matrix 𝒜 of a directed graph
4.2          predict    :func:`check_chords` — edges of a spanning tree and number of chords
4.3          implement  :func:`check_circuit_vector` — the fundamental circuit of a chord (a
                        row of 𝒞)
4.4          explore    :func:`check_tree_exploration` — odometric vs BFS tree: circuit noise
                        and the anchor
===========  =========  ==========================================================================

Each check prints one line starting ``Exercise 4.N`` (correct / not yet / not attempted yet, see
:mod:`lagolib.exercises`) and returns True or False; it never raises on a wrong answer.
Notation of Carlone et al., RSS 2011: ``n + 1`` nodes (``graph.n``), ``m`` edges.
"""

from __future__ import annotations

import numpy as np

from lagolib import PoseGraph, topology
from lagolib.exercises._coerce import Bool, Choice, Function, Int, RealArray
from lagolib.exercises._feedback import (
    NOT_ATTEMPTED,
    WRONG_CHOICE,
    call_student,
    check,
    compare_choice,
    compare_int,
    is_placeholder,
    verdict,
)

__all__ = [
    "check_incidence",
    "check_chords",
    "check_circuit_vector",
    "check_tree_exploration",
    "PREDICT_NODES",
    "PREDICT_EDGES",
    "incidence_cases",
    "circuit_graph",
    "circuit_trees",
    "worst_circuit_sigma",
]


def _graph(n_nodes, edges):
    """A PoseGraph with only a topology: zero poses and measurements, unit information."""
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    m = len(edges)
    return PoseGraph(np.zeros((n_nodes, 3)), edges, np.zeros((m, 3)), np.tile(np.eye(3), (m, 1, 1)))


def _edge_list(edges):
    return ", ".join(f"({int(i)}, {int(j)})" for i, j in edges)


# --------------------------------------------------------------------------------------------
# Exercise 4.1 — the incidence matrix


def incidence_cases(seed=4):
    """The graphs ``check_incidence`` uses: ``[(n_nodes, edges (m, 2) int array)]``.

    A square with a diagonal; five nodes with an edge stored backwards and a repeated measurement
    (two parallel edges); and a seeded random graph on 7 nodes with 11 edges of random direction.
    """
    rng = np.random.default_rng(seed)
    cases = [
        (4, np.array([(0, 1), (1, 2), (2, 3), (3, 0), (0, 2)])),
        (5, np.array([(0, 1), (2, 1), (2, 3), (3, 4), (4, 0), (2, 3), (1, 4)])),
    ]
    pairs = []
    while len(pairs) < 11:
        i, j = rng.choice(7, size=2, replace=False)
        pairs.append((int(i), int(j)))
    cases.append((7, np.array(pairs)))
    return cases


def _incidence_problem(got, expected, n_nodes, edges):
    """None if ``got`` (a float array: call_student read it, dense) is the incidence matrix
    ``expected``; otherwise what is wrong with it."""
    g = got
    m = len(edges)
    if g.shape != expected.shape:
        if g.shape == (n_nodes - 1, m):
            return (
                f"your matrix has shape {g.shape}, one row short of ({n_nodes}, {m}): that is the "
                "reduced matrix A of eq. (6), with the anchor's row deleted. 𝒜 keeps a row for "
                "every node, the anchor included."
            )
        if g.shape == (n_nodes + 1, m):
            return (
                f"your matrix has shape {g.shape}, one row more than the {n_nodes} nodes: rows "
                f"are the nodes 0 … {n_nodes - 1} (0-based), one row each."
            )
        if g.shape == (m, n_nodes):
            return (
                f"your matrix has shape {g.shape}: one row per edge, which is 𝒜ᵀ. 𝒜 has one row "
                f"per node and one column per edge, shape ({n_nodes}, {m})."
            )
        if g.shape == (n_nodes, n_nodes):
            return (
                f"your matrix has shape {g.shape}, node × node: an adjacency matrix. 𝒜 is "
                f"node × edge, shape ({n_nodes}, {m}), one column per edge."
            )
        return f"your matrix has shape {g.shape}, expected ({n_nodes}, {m}) = (nodes, edges)."
    if np.array_equal(g, expected):
        return None
    if g.shape[0] == g.shape[1] and np.array_equal(g, expected.T):
        return (
            "your matrix is 𝒜ᵀ, one row per edge: 𝒜 has one row per node and one column per edge."
        )
    if np.array_equal(g, -expected):
        return (
            "your matrix has +1 at the tail and −1 at the head: the opposite sign. Carlone's "
            "convention: the column of edge (i, j) has −1 in row i (the tail, where the edge "
            "leaves) and +1 in row j (the head), so that 𝒜ᵀθ gives θ_j − θ_i."
        )
    if np.array_equal(g, np.roll(expected, -1, axis=0)):
        return (
            "every ±1 of your matrix sits one row too high (and the first node's entries "
            "wrapped round to the last row): did you subtract 1 from the vertex numbers? The "
            "nodes are counted from 0, so edge (i, j) goes into rows i and j as they are."
        )
    if np.array_equal(g, np.abs(expected)):
        return (
            "your entries are all 0 or +1: the tail of every edge needs −1 (and the head +1), "
            "otherwise 𝒜ᵀθ is a sum θ_i + θ_j instead of a difference."
        )
    wrong = np.flatnonzero(np.any(g != expected, axis=0))
    k = int(wrong[0])
    i, j = (int(x) for x in edges[k])
    return (
        f"{wrong.size} of the {m} columns {'is' if wrong.size == 1 else 'are'} not right; the "
        f"first, column {k} for edge {k} = "
        f"({i}, {j}), is {(g[:, k] + 0.0).tolist()}: which rows should hold its −1 and its +1?"
    )


@check("4.1", incidence=Function(RealArray(("n_nodes", "m"), sparse=True)))
def check_incidence(incidence) -> bool:
    """Exercise 4.1: the incidence matrix 𝒜 of a directed graph (Carlone et al. 2011, §II).

    Calls ``incidence(edges, n_nodes)`` — ``edges`` an int array of shape (m, 2), row ``k`` =
    ``(i, j)`` the edge from tail ``i`` to head ``j`` — on the graphs of
    :func:`incidence_cases` (a square with a diagonal, a graph with a backward and a repeated edge, a seeded
    random graph) and compares the result, shape ``(n_nodes, m)``, exactly with
    :func:`lagolib.topology.incidence_matrix`.  Recognizes a flipped sign, unsigned entries, the
    transpose, rows shifted by one (vertices counted from 1), the reduced matrix (a row short), an
    extra row, an adjacency matrix, and names the first wrong column otherwise.

    Parameters
    ----------
    incidence : callable
        The student's function ``incidence(edges, n_nodes) -> ndarray of shape (n_nodes, m)``.

    Returns
    -------
    bool
    """
    ex = "4.1"
    cases = incidence_cases()
    for n_nodes, edges in cases:
        expected = topology.incidence_matrix(_graph(n_nodes, edges)).toarray()
        got, problem = call_student(incidence, edges.copy(), n_nodes, name="incidence")
        if problem is None:
            problem = _incidence_problem(got, expected, n_nodes, edges)
        if problem is not None:
            if problem != NOT_ATTEMPTED:
                problem += f"\n    (graph: {n_nodes} nodes, edges {_edge_list(edges)})"
            return verdict(
                ex,
                problem,
                hint=(
                    "𝒜 has one row per node and one column per edge; column k describes edge k "
                    "alone, whatever the other edges are.",
                    "Carlone's convention: the column of edge (i, j) has −1 at the tail i, where "
                    "the edge leaves, +1 at the head j, and 0 elsewhere, so that 𝒜ᵀθ gives "
                    "θ_j − θ_i; rows are vertex rows counted from 0.",
                    "start from np.zeros((n_nodes, m)); for edge k = (i, j) set the entries "
                    "(i, k) and (j, k) — a loop over k, or numpy's fancy indexing with "
                    "np.arange(m).",
                ),
            )
    total = sum(len(e) for _, e in cases)
    return verdict(
        ex,
        None,
        correct=f"your 𝒜 matches lagolib.topology.incidence_matrix on {len(cases)} graphs "
        f"({total} edges, including an edge stored backwards and a repeated measurement).",
    )


# --------------------------------------------------------------------------------------------
# Exercise 4.2 — predict the number of tree edges and chords

PREDICT_NODES = 8
#: poses 0…7 driven in order, three loop closures, and the steps 1→2 and 5→6 measured twice
PREDICT_EDGES = (
    (0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 6), (6, 7),
    (3, 0), (7, 4), (6, 1),
    (1, 2), (5, 6),
)  # fmt: skip


@check("4.2", n_tree_edges=Int(), n_chords=Int())
def check_chords(n_tree_edges, n_chords) -> bool:
    """Exercise 4.2: how many edges a spanning tree of the graph has, and how many chords remain.

    The graph: :data:`PREDICT_NODES` = 8 poses (``n + 1``), the :data:`PREDICT_EDGES` (``m`` =
    12: seven odometric edges, three loop closures, two repeated measurements).  Compares the
    predictions with lagolib's odometric and breadth-first spanning trees (their number of edges
    and chords) and :func:`lagolib.topology.cyclomatic_number`; the actual values are printed with
    a right answer, and are the last hint level after a wrong one.
    Recognizes the off-by-one (counting nodes instead of ``n``), forgetting the repeated
    measurements, and a prediction where tree edges and chords do not add up to ``m``.

    Parameters
    ----------
    n_tree_edges, n_chords : int
        The predictions.

    Returns
    -------
    bool
    """
    ex = "4.2"
    if is_placeholder(n_tree_edges) and is_placeholder(n_chords):
        return verdict(ex, NOT_ATTEMPTED)
    g = _graph(PREDICT_NODES, PREDICT_EDGES)
    odo, bfs = (topology.spanning_tree(g, kind) for kind in ("odometric", "bfs"))
    n_tree = int(odo.edges.size)
    d = topology.cyclomatic_number(g)
    pairs = len({(min(i, j), max(i, j)) for i, j in PREDICT_EDGES})
    actual = (
        f"the graph has {g.n} nodes (n + 1) and {g.m} edges (m); lagolib's odometric tree has "
        f"{odo.edges.size} edges and leaves {odo.d} chords, its BFS tree {bfs.edges.size} and "
        f"{bfs.d}, and cyclomatic_number = {d}"
    )
    hint = (
        "a spanning tree reaches every node; how many edges does it need to hang each node but "
        "the root from its parent?",
        "a tree on n + 1 nodes has n edges, and every edge that is not in the tree is a chord: "
        "d = m − n (Carlone et al., Cor. 1) — a repeated measurement is an edge like any other.",
        f"the graph has {g.n} nodes (n + 1) and m = {g.m} edges.",
    )
    for name, value in (("n_tree_edges", n_tree_edges), ("n_chords", n_chords)):
        if is_placeholder(value):
            return verdict(ex, f"{name} is still `...`: write both predictions.", hint=hint)
    problems = []
    wrong_tree = compare_int(n_tree_edges, n_tree, name="n_tree_edges")
    if wrong_tree is not None:
        if n_tree_edges == g.n:
            wrong_tree = (
                f"n_tree_edges = {n_tree_edges} is the number of nodes, n + 1, as if every node "
                "hung from an edge of its own — the root does not."
            )
        problems.append(wrong_tree)
    wrong_d = compare_int(n_chords, d, name="n_chords")
    if wrong_d is not None:
        if n_chords == g.m - g.n:
            wrong_d = (
                f"n_chords = {n_chords} = m − (n + 1): the classic off-by-one — the tree does "
                "not have one edge per node."
            )
        elif n_chords == pairs - n_tree:
            wrong_d = (
                f"n_chords = {n_chords} leaves out the repeated measurements: {g.m} edges join "
                f"only {pairs} distinct pairs, but a second edge between the same two poses is "
                "a chord too (it closes a cycle of two edges)."
            )
        elif n_chords == g.m - n_tree + 1:
            wrong_d = (
                f"n_chords = {n_chords} = m − n + 1 with the paper's n: the '+ 1' belongs to "
                "lagolib's count, d = graph.m − graph.n + 1, where graph.n is the paper's n + 1."
            )
        problems.append(wrong_d)
    if problems and n_tree_edges + n_chords != g.m:
        problems.append(
            f"Also, your two numbers add up to {n_tree_edges + n_chords}, but every "
            f"one of the m = {g.m} edges is either a tree edge or a chord."
        )
    if problems:
        return verdict(
            ex, " ".join(problems), hint=(*hint, f"lagolib's own count: {actual}.")
        )
    return verdict(ex, None, correct=f"{actual}: d = m − n = {g.m} − {n_tree} = {d}.")


# --------------------------------------------------------------------------------------------
# Exercise 4.3 — the fundamental circuit of a chord


def circuit_graph(seed=2011):
    """The graph ``check_circuit_vector`` uses: 12 poses on an odometric chain.

    Two odometric edges are stored backwards (``k+1 → k``, as GTSAM files do), the step 5 → 6 is
    measured twice (the second edge is a chord with a two-edge circuit), and six seeded loop
    closures join poses at least two steps apart, in random directions.
    """
    rng = np.random.default_rng(seed)
    n = 12
    edges = [(k + 1, k) if k in (3, 7) else (k, k + 1) for k in range(n - 1)]
    edges.append((5, 6))
    closures = set()
    while len(closures) < 6:
        i, j = (int(x) for x in rng.choice(n, size=2, replace=False))
        if abs(i - j) >= 2 and (i, j) not in closures and (j, i) not in closures:
            closures.add((i, j))
    edges += sorted(closures)
    return _graph(n, edges)


def circuit_trees(graph):
    """The spanning trees ``check_circuit_vector`` uses: ``[(description, SpanningTree)]``.

    The odometric tree rooted at pose 0 and at pose 6 (then a circuit's path climbs from both
    ends of its chord), and the breadth-first tree rooted at pose 7.
    """
    return [
        ("the odometric tree rooted at pose 0", topology.spanning_tree(graph, "odometric")),
        ("the odometric tree rooted at pose 6", topology.spanning_tree(graph, "odometric", 6)),
        ("the BFS tree rooted at pose 7", topology.spanning_tree(graph, "bfs", 7)),
    ]


def _pair_of_edges_and_signs(got, *args):
    """The sentence for a result that is a pair, like topology.fundamental_circuit's, or None."""
    if isinstance(got, tuple) and len(got) == 2:
        graph = args[0] if args else None
        m = f"({graph.m},)" if isinstance(graph, PoseGraph) else "(m,)"
        return (
            "your function returned a pair, like topology.fundamental_circuit's (edges, signs). "
            f"The exercise asks for the circuit vector c itself: an array of real numbers of "
            f"shape {m}, one entry per edge of the graph (a row of 𝒞)."
        )
    return None


def _circuit_array(g, expected):
    """``(g, None)`` if the float array ``g`` is shaped like ``expected`` and holds only −1, 0,
    +1, else ``(None, problem)``."""
    m = expected.size
    if g.shape != expected.shape:
        return None, (
            f"your vector has shape {g.shape}; it should have one entry per edge of the graph, "
            f"shape ({m},)."
        )
    bad = np.flatnonzero(~np.isin(g, (-1.0, 0.0, 1.0)))
    if bad.size:
        k = int(bad[0])
        return None, (
            f"entry {k} of your vector is {g[k]:.6g}; a circuit vector holds only −1, 0 and +1."
        )
    return g, None


def _others(g, chord):
    return np.delete(g, chord)


# the usual mistakes: (test(got, expected, chord), what is wrong); a mistake made on every chord
# is reported as that mistake, otherwise the first wrong chord is described
_CIRCUIT_MISTAKES = (
    (
        lambda g, e, c: np.array_equal(g, -e),
        "your vector has the opposite sign: the circuit is walked in the chord's own direction, "
        "so the chord's entry is +1 (and the tree path leads back from j to i).",
    ),
    (
        lambda g, e, c: np.array_equal(g, np.abs(e)),
        "your entries are only 0 and +1: the signs are missing. Going around the circuit, an "
        "edge walked against its direction (from its head to its tail) counts −1.",
    ),
    (
        lambda g, e, c: g[c] == 0 and np.array_equal(_others(g, c), _others(e, c)),
        "your vector has the tree path right but 0 for the chord itself. The fundamental "
        "circuit is the chord plus the tree path (Def. 1): c has +1 at the chord.",
    ),
    (
        lambda g, e, c: g[c] == 1 and np.array_equal(_others(g, c), -_others(e, c)),
        "the chord's +1 is right, but the tree edges have the opposite sign: you walked the "
        "tree path from i to j, the same way as the chord. Going around the circuit, the path "
        "leads back from the chord's head j to its tail i.",
    ),
    (
        lambda g, e, c: g[c] == -1 and np.array_equal(_others(g, c), _others(e, c)),
        "your vector has −1 at the chord: the circuit is walked in the chord's direction, so "
        "the chord counts +1.",
    ),
)


def _circuit_difference(g, e, chord, in_tree):
    """What is wrong with the circuit vector ``g`` of ``chord`` (the reference is ``e``)."""
    for test, message in _CIRCUIT_MISTAKES:
        if test(g, e, chord):
            return message
    extra = np.flatnonzero((g != 0) & (e == 0))
    missing = np.flatnonzero((g == 0) & (e != 0))
    if extra.size or missing.size:
        parts = []
        if extra.size:
            above = bool(np.all(in_tree[extra]))
            parts.append(
                f"edges {extra.tolist()} are in your circuit but not in the fundamental circuit"
                + (
                    " — tree edges off the path between i and j (above the point where the "
                    "climbs from i and from j meet?): stop at the common ancestor, do not go on "
                    "to the root"
                    if above
                    else ""
                )
            )
        if missing.size:
            parts.append(f"edges {missing.tolist()} of the fundamental circuit are missing")
        return "; ".join(parts) + "."
    wrong = np.flatnonzero(g != e)
    return (
        f"the right edges, but the sign of edges {wrong.tolist()} is wrong: going around the "
        "circuit (the chord i → j, then the tree path from j back to i), an edge walked from its "
        "tail to its head counts +1, one walked from head to tail −1."
    )


@check(
    "4.3",
    circuit_vector=Function(RealArray(("graph.m",), sparse=True), explain=_pair_of_edges_and_signs),
)
def check_circuit_vector(circuit_vector) -> bool:
    """Exercise 4.3: the fundamental circuit of a chord as a signed edge vector (a row of 𝒞).

    Calls ``circuit_vector(graph, tree, chord)`` for every chord of the three spanning trees of
    :func:`circuit_trees` on the graph of :func:`circuit_graph` (backward odometric edges, a
    repeated measurement) and compares the result, shape ``(graph.m,)``, exactly with the chord's
    row of :func:`lagolib.topology.cycle_basis` (Carlone et al. 2011, Def. 1 and eq. (19)).
    Recognizes a pair (edges, signs) instead of the vector, a flipped sign, missing signs, a
    missing chord entry (the tree path only), a tree path walked the wrong way, a chord with −1,
    edges above the common ancestor, missing edges and wrong signs.

    Parameters
    ----------
    circuit_vector : callable
        The student's function ``circuit_vector(graph, tree, chord) -> ndarray of shape (m,)``.

    Returns
    -------
    bool
    """
    ex = "4.3"
    hint = (
        "self-test: a circuit enters every node as often as it leaves it, so "
        "topology.incidence_matrix(graph) @ c must be 0 for your vector c.",
        "Def. 1: the fundamental circuit is the chord plus the tree path between its two ends — "
        "up from each end to their common ancestor, not to the root — walked from i to j along "
        "the chord and back from j to i along the tree.",
        "put +1 at the chord; climb from i and from j towards the root (the deeper end first, "
        "tree.depth) until they meet; at each step the edge tree.parent_edge of the vertex you "
        "leave counts +1 when walked tail → head, −1 when walked head → tail.",
    )
    graph = circuit_graph()

    def where(description, chord, expected, got=None):
        i, j = (int(x) for x in graph.edges[chord])
        text = f"\n    (chord e{chord} = ({i}, {j}) of {description}"
        if got is not None:
            text += f"; yours: {got.astype(int).tolist()}"
        return text + ")"

    cases = []
    for description, tree in circuit_trees(graph):
        basis = topology.cycle_basis(graph, tree)
        rows = basis.C.toarray()
        for row, chord in enumerate(basis.chords):
            chord, expected = int(chord), rows[row]
            got, problem = call_student(circuit_vector, graph, tree, chord, name="circuit_vector")
            if problem is None:
                got, problem = _circuit_array(got, expected)
            if problem is not None:
                if problem != NOT_ATTEMPTED:
                    problem += where(description, chord, expected)
                return verdict(ex, problem, hint=hint)
            cases.append((description, tree, chord, expected, got))
    wrong = [c for c in cases if not np.array_equal(c[4], c[3])]
    if not wrong:
        return verdict(
            ex,
            None,
            correct=f"all {len(cases)} circuit vectors (every chord of three spanning trees of a "
            f"{graph.n}-pose graph with backward and repeated edges) equal the rows of lagolib's "
            "𝒞.",
        )
    description, tree, chord, expected, got = wrong[0]
    problem = None
    for test, message in _CIRCUIT_MISTAKES:
        if all(test(g, e, c) for _, _, c, e, g in cases):
            problem = message + f" (on all {len(cases)} chords; the longest circuit:)"
            description, tree, chord, expected, got = max(
                wrong, key=lambda case: np.count_nonzero(case[3])
            )
            break
    if problem is None:
        problem = _circuit_difference(got, expected, chord, tree.in_tree)
        problem += f" ({len(wrong)} of the {len(cases)} circuits are wrong; the first:)"
    return verdict(ex, problem + where(description, chord, expected, got), hint=hint)


# --------------------------------------------------------------------------------------------
# Exercise 4.4 — odometric vs BFS tree; does the anchor matter?


def worst_circuit_sigma(graph, kind, anchor=None, C=None):
    """The largest standard deviation of a fundamental circuit's summed orientations, in rad.

    For circuit ``c``, ``c^T δ`` sums the relative orientations around it; with independent
    edge noise its variance is ``Σ_k |c_k| P_δk`` (:func:`lagolib.topology.orientation_variances`).

    Parameters
    ----------
    graph : PoseGraph
    kind : {"odometric", "bfs", "min_uncertainty"}
        The spanning tree.
    anchor : int, optional
        Its root (vertex id; default the smallest).
    C : scipy.sparse matrix, shape (d, m), optional
        The tree's cycle basis matrix, if already computed.

    Returns
    -------
    float
    """
    if C is None:
        C = topology.cycle_basis(graph, kind, anchor).C
    sigma = np.sqrt(abs(C) @ topology.orientation_variances(graph))
    return float(sigma.max()) if sigma.size else 0.0


@check("4.4", safer_tree=Choice(("odometric", "bfs")), odometric_anchor_matters=Bool())
def check_tree_exploration(safer_tree, odometric_anchor_matters, graph) -> bool:
    """Exercise 4.4: which tree's circuits carry less orientation noise; does the anchor matter?

    Recomputes, on the ``graph`` explored in the chapter, the worst circuit's standard deviation
    (:func:`worst_circuit_sigma`) for the odometric and the breadth-first tree (default anchor),
    and compares the odometric tree's cycle basis 𝒞 for the first, middle and last vertex as
    anchor.

    Parameters
    ----------
    safer_tree : {"odometric", "bfs"}
        The tree whose worst fundamental circuit has the smaller noise.
    odometric_anchor_matters : bool
        Whether moving the anchor changes any fundamental circuit of the odometric tree.
    graph : PoseGraph
        The graph explored (``G`` in the chapter).

    Returns
    -------
    bool
    """
    ex = "4.4"
    if is_placeholder(safer_tree) and is_placeholder(odometric_anchor_matters):
        return verdict(ex, NOT_ATTEMPTED)
    for name, value in (
        ("safer_tree", safer_tree),
        ("odometric_anchor_matters", odometric_anchor_matters),
    ):
        if is_placeholder(value):
            return verdict(ex, f"{name} is still `...`: answer both questions.")
    if not isinstance(graph, PoseGraph):
        return verdict(
            ex,
            f"the third argument should be the graph you explored (G), got {type(graph).__name__}.",
        )
    anchors = [int(graph.ids[0]), int(graph.ids[graph.n // 2]), int(graph.ids[-1])]
    bases = [topology.cycle_basis(graph, "odometric", a).C for a in anchors]
    bfs_bases = [topology.cycle_basis(graph, "bfs", a).C for a in anchors]
    sigma = {
        "odometric": worst_circuit_sigma(graph, "odometric", C=bases[0]),
        "bfs": worst_circuit_sigma(graph, "bfs", C=bfs_bases[0]),
    }
    safer = min(sigma, key=sigma.get)
    read = (
        f"worst circuit σ: {np.degrees(sigma['odometric']):.1f}° with the odometric tree, "
        f"{np.degrees(sigma['bfs']):.1f}° with the BFS tree"
    )
    matters = any(b.shape != bases[0].shape or (b != bases[0]).nnz for b in bases[1:])
    depths = [int(topology.spanning_tree(graph, "odometric", a).depth.max()) for a in anchors]
    bfs_changes = any(
        b.shape != bfs_bases[0].shape or (b != bfs_bases[0]).nnz for b in bfs_bases[1:]
    )
    problems, facts = [], []
    wrong = compare_choice(safer_tree, safer, ("odometric", "bfs"), name="safer_tree")
    if wrong is not None:
        if not wrong.endswith(WRONG_CHOICE):
            problems.append(wrong)  # not one of the choices
        else:
            problems.append(
                f"safer_tree = {safer_tree!r} is not the tree whose worst circuit carries less "
                "noise."
            )
            facts.append(
                f"{read}: the {safer} tree's circuits are shorter, so less noise adds up around "
                "them"
            )
    wrong = compare_choice(
        odometric_anchor_matters, matters, (True, False), name="odometric_anchor_matters"
    )
    if wrong is not None:
        if not wrong.endswith(WRONG_CHOICE):
            problems.append(wrong)  # not one of the choices
        else:
            problems.append(
                f"odometric_anchor_matters = {odometric_anchor_matters!r} is not what the "
                "odometric tree's cycle bases show."
            )
            facts.append(
                f"the odometric tree's 𝒞 is identical with the anchor at vertex {anchors[0]}, "
                f"{anchors[1]} or {anchors[2]}; only its depth changes "
                f"({', '.join(map(str, depths))})"
                if not matters
                else "on this graph the odometric tree's circuits change with the anchor"
            )
    if problems:
        return verdict(
            ex,
            " ".join(problems),
            hint=(
                "compare nnz(C), the longest circuit and the worst σ printed for each tree and "
                "anchor — not the depth.",
                "a fundamental circuit is the chord plus the tree path between its two ends: "
                "does that path depend on where the root is? And the noise of a circuit adds "
                "up over its edges: which tree has the shorter circuits?",
                "the check's numbers: " + "; ".join(facts) + ".",
            ),
        )
    return verdict(
        ex,
        None,
        correct=f"{read}; the odometric tree's 𝒞 is the same for the anchors {anchors} "
        f"(depths {depths})"
        + (", while the BFS tree's 𝒞 changes with the anchor." if bfs_changes else "."),
    )
