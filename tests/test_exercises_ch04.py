"""The checks of chapter 4's exercises: right answers pass, stubs are "not attempted yet", and the
usual mistakes get their specific feedback — never an exception."""

import json
from pathlib import Path

import numpy as np
import pytest

from lagolib import datasets
from lagolib.exercises import ch04, hint, passed, reset

CHAPTER = Path(__file__).resolve().parent.parent / "book" / "04_graphs_and_cycles.ipynb"


@pytest.fixture(autouse=True)
def _fresh_results():
    reset()
    yield
    reset()


def _run(capsys, check, *args):
    ok = check(*args)
    return ok, capsys.readouterr().out


def _hints(capsys, exercise):
    """Every hint level of ``exercise``'s last "not yet", as ``hint`` prints them."""
    for _ in range(5):
        hint(exercise)
    return capsys.readouterr().out


def stub(*args):
    return ...


def boom(*args):
    raise IndexError("index 99 is out of bounds")


# ------------------------------------------------------------------------------ 4.1 incidence
def incidence(edges, n_nodes):
    edges = np.asarray(edges)
    m = len(edges)
    A = np.zeros((n_nodes, m))
    A[edges[:, 0], np.arange(m)] = -1.0
    A[edges[:, 1], np.arange(m)] = 1.0
    return A


def incidence_loop_sparse(edges, n_nodes):
    """Another right answer: a loop, returned as a scipy.sparse matrix."""
    import scipy.sparse as sp

    A = sp.lil_matrix((n_nodes, len(edges)))
    for k, (i, j) in enumerate(edges):
        A[i, k], A[j, k] = -1, 1
    return A.tocsr()


def _counted_from_one(edges, n_nodes):
    """A MATLAB habit: rows i - 1 and j - 1 (so node 0's entries land in the last row)."""
    A = np.zeros((n_nodes, len(edges)))
    for k, (i, j) in enumerate(edges):
        A[i - 1, k], A[j - 1, k] = -1.0, 1.0
    return A


def test_incidence_reference_is_correct(capsys):
    ok, out = _run(capsys, ch04.check_incidence, incidence)
    assert ok and passed("4.1")
    assert out.startswith("Exercise 4.1 — correct")
    assert "3 graphs (23 edges" in out
    ok, out = _run(capsys, ch04.check_incidence, incidence_loop_sparse)
    assert ok, out


@pytest.mark.parametrize("answer", [..., None, stub])
def test_incidence_stub_is_not_attempted(capsys, answer):
    ok, out = _run(capsys, ch04.check_incidence, answer)
    assert not ok and not passed("4.1")
    assert "not attempted yet" in out


@pytest.mark.parametrize(
    "wrong, message",
    [
        (lambda e, n: -incidence(e, n), "+1 at the tail and −1 at the head"),
        (lambda e, n: np.abs(incidence(e, n)), "all 0 or +1"),
        (lambda e, n: incidence(e, n).T, "one row per edge, which is 𝒜ᵀ"),
        (lambda e, n: incidence(e, n)[1:], "reduced matrix A of eq. (6)"),
        (lambda e, n: np.vstack([np.zeros(len(e)), incidence(e, n)]), "one row more"),
        (lambda e, n: np.zeros((n, n)), "an adjacency matrix"),
        (lambda e, n: _counted_from_one(e, n), "did you subtract 1 from the vertex numbers?"),
    ],
)
def test_incidence_mistakes(capsys, wrong, message):
    ok, out = _run(capsys, ch04.check_incidence, wrong)
    assert not ok and not passed("4.1")
    assert "Exercise 4.1 — not yet" in out and message in out
    assert "graph: 4 nodes, edges (0, 1), (1, 2), (2, 3), (3, 0), (0, 2)" in out


def test_incidence_square_transpose_is_recognized():
    edges = np.array([(0, 1), (1, 2), (0, 2)])  # 3 nodes, 3 edges: 𝒜 is square
    expected = incidence(edges, 3)
    problem = ch04._incidence_problem(expected.T, expected, 3, edges)
    assert problem.startswith("your matrix is 𝒜ᵀ")


def test_incidence_wrong_column_is_named(capsys):
    def last_edge_reversed(edges, n_nodes):
        A = incidence(edges, n_nodes)
        if len(edges) == 7:  # only on the second graph: its edge 1 is stored (2, 1)
            A[:, 1] *= -1
        return A

    ok, out = _run(capsys, ch04.check_incidence, last_edge_reversed)
    assert not ok
    assert "1 of the 7 columns is not right; the first, column 1 for edge 1 = (2, 1), is " in out
    assert "[0.0, -1.0, 1.0, 0.0, 0.0]: which rows should hold its −1 and its +1?" in out
    assert "expected" not in out and "[0, 1, -1, 0, 0]" not in out
    assert "−1 at the tail i, where the edge leaves, +1 at the head j" in _hints(capsys, "4.1")


def test_incidence_that_raises_is_feedback(capsys):
    ok, out = _run(capsys, ch04.check_incidence, boom)
    assert not ok
    assert "incidence raised IndexError: index 99 is out of bounds" in out


# ------------------------------------------------------------------------------ 4.2 chords
def test_chords_reference_is_correct(capsys):
    ok, out = _run(capsys, ch04.check_chords, 7, 5)
    assert ok and passed("4.2")
    assert out.startswith("Exercise 4.2 — correct")
    assert "8 nodes (n + 1) and 12 edges (m)" in out and "d = m − n = 12 − 7 = 5" in out


def test_chords_accepts_whole_floats(capsys):
    ok, _ = _run(capsys, ch04.check_chords, 7.0, np.int64(5))
    assert ok


def test_chords_stub_is_not_attempted(capsys):
    ok, out = _run(capsys, ch04.check_chords, ..., ...)
    assert not ok and "not attempted yet" in out


def test_chords_half_answered(capsys):
    ok, out = _run(capsys, ch04.check_chords, 7, ...)
    assert not ok and "n_chords is still `...`" in out
    assert "cyclomatic_number" not in out and "5" not in out  # no answer for a half answer


@pytest.mark.parametrize(
    "answer, messages",
    [
        ((8, 4), ["n_tree_edges = 8 is the number of nodes", "classic off-by-one"]),
        ((7, 4), ["classic off-by-one", "add up to 11"]),
        ((7, 3), ["leaves out the repeated measurements", "only 10 distinct pairs"]),
        ((7, 6), ["m − n + 1 with the paper's n: the '+ 1' belongs to lagolib's count"]),
        ((6, 5), ["n_tree_edges = 6 is too small."]),
        (("7", 5), ["n_tree_edges should be a whole number, got '7' (a string"]),
        ((7, True), ["n_chords should be a whole number, got True (a bool)"]),
        ((7, 5 + 0j), ["n_chords should be a whole number, got (5+0j) (a complex number)"]),
    ],
)
def test_chords_mistakes(capsys, answer, messages):
    ok, out = _run(capsys, ch04.check_chords, *answer)
    assert not ok and not passed("4.2")
    assert "Exercise 4.2 — not yet" in out
    for message in messages:
        assert message in out
    # the actual values are the last hint, never part of the diagnosis
    assert "lagolib's odometric tree" not in out and "= 5" not in out
    kind = any("should be" in m for m in messages)
    levels = _hints(capsys, "4.2")
    assert ("lagolib's odometric tree has 7 edges and leaves 5 chords" in levels) is not kind


def test_predict_statement_lists_the_checked_graph():
    nb = json.loads(CHAPTER.read_text(encoding="utf-8"))
    (statement,) = [
        "".join(c["source"])
        for c in nb["cells"]
        if c.get("metadata", {}).get("lagolib", {}).get("exercise") == "4.2"
    ]
    text = statement.replace(" ", "")
    for i, j in ch04.PREDICT_EDGES:
        assert f"({i},{j})" in text
    assert ch04.PREDICT_NODES == 8 and "0,1,\\dots,7" in text


# ------------------------------------------------------------------------------ 4.3 circuits
def circuit_vector(graph, tree, chord):
    c = np.zeros(graph.m)
    c[chord] = 1.0
    a, b = (int(v) for v in graph.edges[chord])
    while a != b:
        if tree.depth[a] >= tree.depth[b]:
            e = tree.parent_edge[a]
            c[e] = 1.0 if graph.edges[e, 1] == a else -1.0
            a = int(tree.parent[a])
        else:
            e = tree.parent_edge[b]
            c[e] = 1.0 if graph.edges[e, 0] == b else -1.0
            b = int(tree.parent[b])
    return c


def _root_walks(graph, tree, chord, accumulate):
    """The chord, plus j's path to the root minus i's path to the root."""
    c = np.zeros(graph.m)
    c[chord] = 1.0
    i, j = graph.edges[chord]
    for start, sign in ((j, 1.0), (i, -1.0)):
        a = int(start)
        while a != tree.root:
            e = tree.parent_edge[a]
            value = sign * (1.0 if graph.edges[e, 0] == a else -1.0)
            c[e] = c[e] + value if accumulate else value
            a = int(tree.parent[a])
    return c


def test_circuit_reference_is_correct(capsys):
    ok, out = _run(capsys, ch04.check_circuit_vector, circuit_vector)
    assert ok and passed("4.3")
    assert out.startswith("Exercise 4.3 — correct: all 21 circuit vectors")


def test_circuit_root_paths_that_cancel_are_correct(capsys):
    ok, out = _run(capsys, ch04.check_circuit_vector, lambda g, t, c: _root_walks(g, t, c, True))
    assert ok, out


@pytest.mark.parametrize("answer", [..., stub])
def test_circuit_stub_is_not_attempted(capsys, answer):
    ok, out = _run(capsys, ch04.check_circuit_vector, answer)
    assert not ok and "not attempted yet" in out


def _without_chord(g, t, c):
    v = circuit_vector(g, t, c)
    v[c] = 0.0
    return v


def _path_reversed(g, t, c):
    v = -circuit_vector(g, t, c)
    v[c] = 1.0
    return v


def _chord_negative(g, t, c):
    v = circuit_vector(g, t, c)
    v[c] = -1.0
    return v


def _one_sign_rule(g, t, c):
    """Uses the 'leaving j' rule on both sides: wrong signs on i's side."""
    v = np.zeros(g.m)
    v[c] = 1.0
    a, b = (int(x) for x in g.edges[c])
    while a != b:
        if t.depth[a] >= t.depth[b]:
            e = t.parent_edge[a]
            v[e] = 1.0 if g.edges[e, 0] == a else -1.0
            a = int(t.parent[a])
        else:
            e = t.parent_edge[b]
            v[e] = 1.0 if g.edges[e, 0] == b else -1.0
            b = int(t.parent[b])
    return v


@pytest.mark.parametrize(
    "wrong, message",
    [
        (lambda g, t, c: -circuit_vector(g, t, c), "opposite sign (…)|on all 21 chords"),
        (lambda g, t, c: np.abs(circuit_vector(g, t, c)), "the signs are missing"),
        (_without_chord, "0 for the chord itself"),
        (_path_reversed, "you walked the tree path from i to j"),
        (_chord_negative, "−1 at the chord"),
        (lambda g, t, c: _root_walks(g, t, c, False), "stop at the common ancestor"),
        (_one_sign_rule, "of the 21 circuits are wrong"),
        (lambda g, t, c: np.delete(circuit_vector(g, t, c), 0), "shape (17,)"),
        (lambda g, t, c: 2 * circuit_vector(g, t, c), "holds only −1, 0 and +1"),
    ],
)
def test_circuit_mistakes(capsys, wrong, message):
    ok, out = _run(capsys, ch04.check_circuit_vector, wrong)
    assert not ok and not passed("4.3")
    assert "Exercise 4.3 — not yet" in out
    for part in message.split("|"):
        assert part.replace(" (…)", "") in out
    assert "chord e" in out and "expected" not in out  # the right vector is not shown


def test_circuit_pair_instead_of_vector(capsys):
    from lagolib import topology

    ok, out = _run(capsys, ch04.check_circuit_vector, topology.fundamental_circuit)
    assert not ok and "returned a pair, like topology.fundamental_circuit's" in out


def test_circuit_that_raises_is_feedback(capsys):
    ok, out = _run(capsys, ch04.check_circuit_vector, boom)
    assert not ok and "circuit_vector raised IndexError" in out


# ------------------------------------------------------------------------------ 4.4 explore
@pytest.fixture(scope="module")
def city():
    return datasets.example("manhattan200").graph


def test_exploration_reference_is_correct(capsys, city):
    ok, out = _run(capsys, ch04.check_tree_exploration, "bfs", False, city)
    assert ok and passed("4.4")
    assert "8.0° with the odometric tree, 2.7° with the BFS tree" in out
    assert "the same for the anchors [0, 100, 199] (depths [199, 100, 199])" in out
    ok, _ = _run(capsys, ch04.check_tree_exploration, " BFS", np.False_, city)
    assert ok


def test_exploration_stub_is_not_attempted(capsys, city):
    ok, out = _run(capsys, ch04.check_tree_exploration, ..., ..., city)
    assert not ok and "not attempted yet" in out
    ok, out = _run(capsys, ch04.check_tree_exploration, "bfs", ..., city)
    assert not ok and "odometric_anchor_matters is still `...`" in out


@pytest.mark.parametrize(
    "answer, messages",
    [
        (("odometric", False), ["safer_tree = 'odometric' is not the tree"]),
        (("bfs", True), ["odometric_anchor_matters = True is not what the odometric tree's"]),
        (("shortest", False), ["safer_tree should be one of ['odometric', 'bfs']"]),
        (("bfs", "perhaps"), ["odometric_anchor_matters should be True or False, got 'perhaps'"]),
        (("bfs", 0), ["odometric_anchor_matters should be True or False, got 0 (an int)"]),
    ],
)
def test_exploration_mistakes(capsys, city, answer, messages):
    ok, out = _run(capsys, ch04.check_tree_exploration, *answer, city)
    assert not ok and not passed("4.4")
    assert "Exercise 4.4 — not yet" in out
    for message in messages:
        assert message in out
    assert "°" not in out and "depth" not in out  # the numbers are the last hint
    levels = _hints(capsys, "4.4")
    if answer == ("odometric", False):
        assert "8.0° with the odometric tree, 2.7° with the BFS tree" in levels
        assert "the bfs tree's circuits are shorter" in levels
    if answer == ("bfs", True):
        assert "odometric tree's 𝒞 is identical" in levels and "only its depth changes" in levels


def test_exploration_accepts_no_for_false(capsys, city):
    ok, out = _run(capsys, ch04.check_tree_exploration, "bfs", "no", city)
    assert ok and out.startswith("Exercise 4.4 — correct")


def test_exploration_without_a_graph_is_feedback(capsys):
    ok, out = _run(capsys, ch04.check_tree_exploration, "bfs", False, "intel")
    assert not ok and "the graph you explored (G)" in out
