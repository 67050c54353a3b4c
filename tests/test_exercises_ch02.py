"""The checks of chapter 2's exercises: right answers pass, stubs are "not attempted yet", and the
usual mistakes get their own specific feedback — never an exception."""

import json
from pathlib import Path

import numpy as np
import pytest

from lagolib import book, gauss_newton
from lagolib.exercises import ch02, hint, passed, reset

CHAPTER = Path(__file__).resolve().parent.parent / "book" / "02_least_squares_slam.ipynb"


@pytest.fixture(autouse=True)
def _fresh_results():
    reset()
    yield
    reset()


def run(capsys, check, *args):
    """Call a check; return (result, printed text)."""
    ok = check(*args)
    out = capsys.readouterr().out
    assert out.count("Exercise 2.") == 1, out
    return ok, out


def hints(capsys, exercise):
    """Every hint level of ``exercise``'s last "not yet", as ``hint`` prints them."""
    for _ in range(6):
        hint(exercise)
    return capsys.readouterr().out


def _stub(*_):
    return ...


def _raises(*_):
    raise ValueError("not finished")


# ----------------------------------------------------------------------------- 2.1
def reference_blocks(p_i, p_j, z):
    _, A, B = gauss_newton.edge_jacobians(p_i, p_j, z)
    return A, B


def numpy_blocks(p_i, p_j, z):
    """A student's solution, written out with numpy (the notebook's solution)."""
    c, s = np.cos(p_i[2] + z[2]), np.sin(p_i[2] + z[2])
    dx, dy = p_j[0] - p_i[0], p_j[1] - p_i[1]
    B = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    A = -B
    A[0, 2] = -s * dx + c * dy
    A[1, 2] = -c * dx - s * dy
    return A, B


@pytest.mark.parametrize("fn", [reference_blocks, numpy_blocks])
def test_jacobians_correct(capsys, fn):
    ok, out = run(capsys, ch02.check_jacobians, fn)
    assert ok and passed("2.1")
    assert "Exercise 2.1 — correct" in out
    assert "on 5 random edges" in out and "finite differences" in out


@pytest.mark.parametrize("answer", [..., _stub, None])
def test_jacobians_not_attempted(capsys, answer):
    ok, out = run(capsys, ch02.check_jacobians, answer)
    assert not ok and not passed("2.1")
    assert "not attempted yet" in out


@pytest.mark.parametrize(
    "fn, message",
    [
        (lambda a, b, z: reference_blocks(a, b, z)[::-1], "A and B are swapped"),
        (
            lambda a, b, z: (reference_blocks(a, b, z)[0].T, reference_blocks(a, b, z)[1]),
            "A_ij is the transpose of the reference",
        ),
        (
            lambda a, b, z: (reference_blocks(a, b, z)[0], -reference_blocks(a, b, z)[1]),
            "B_ij has the opposite sign",
        ),
        (
            lambda a, b, z: reference_blocks(a, b, z * [1.0, 1.0, 0.0]),
            "uses the rotation R(theta_i)",
        ),
        (
            lambda a, b, z: (
                reference_blocks(a, b, z)[0] * [1.0, 1.0, 0.0] - [0, 0, 1],
                reference_blocks(a, b, z)[1],
            ),
            "its third column de/dtheta_i is not",
        ),
        (
            lambda a, b, z: (
                reference_blocks(a, b, z)[0] * [1.0, 1.0, 1.0] + np.diag([0, 0, 2.0]),
                reference_blocks(a, b, z)[1],
            ),
            "A_ij is right except its entry [2, 2], de_theta/dtheta_i (yours is 1): how does",
        ),
        (lambda a, b, z: np.zeros(3), "jacobian_blocks should return two 3x3 arrays, (A, B)"),
        (lambda a, b, z: (np.eye(3), np.eye(2)), "B_ij has shape (2, 2), expected (3, 3)"),
        (_raises, "jacobian_blocks raised ValueError: not finished"),
    ],
)
def test_jacobians_wrong(capsys, fn, message):
    ok, out = run(capsys, ch02.check_jacobians, fn)
    assert not ok and not passed("2.1")
    assert "Exercise 2.1 — not yet: on edge 1 of 5" in out
    assert message in out
    assert 'Stuck? hint("2.1") gives a hint' in out
    assert "[[c, s, 0]" not in out and "(c, s, 0)" not in out  # the blocks: hints only


def test_jacobians_wrong_only_on_a_later_edge(capsys):
    """A function right on the first edges but wrong on a later one is caught there."""
    calls = []

    def fn(p_i, p_j, z):
        calls.append(1)
        A, B = reference_blocks(p_i, p_j, z)
        return (A, B + 1e-3) if len(calls) == 4 else (A, B)

    ok, out = run(capsys, ch02.check_jacobians, fn)
    assert not ok
    assert "on edge 4 of 5" in out
    assert "B_ij differs from the reference in 9 of its 9 entries: at index (0, 2) yours is " in out
    assert "larger, by 0.001." in out


def test_jacobians_hints_come_one_level_per_call(capsys):
    run(capsys, ch02.check_jacobians, lambda a, b, z: reference_blocks(a, b, z)[::-1])
    levels = hints(capsys, "2.1").splitlines()[:4]
    assert [line.split(":", 1)[0] for line in levels] == [
        "Exercise 2.1 — hint 1 of 3",
        "Exercise 2.1 — hint 2 of 3",
        "Exercise 2.1 — hint 3 of 3",
        "Exercise 2.1 — no more hints",
    ]
    assert "B_ij's rows are (c, s, 0), (-s, c, 0), (0, 0, 1)" in levels[2]


# ----------------------------------------------------------------------------- 2.2
def contribution(e, A, B, W):
    return A.T @ W @ A, A.T @ W @ B, B.T @ W @ B, A.T @ W @ e, B.T @ W @ e


def test_contribution_correct(capsys):
    ok, out = run(capsys, ch02.check_edge_contribution, contribution)
    assert ok and passed("2.2")
    assert "Exercise 2.2 — correct: on 3 edges with rotated, anisotropic Omega" in out


def test_contribution_information_is_anisotropic_and_rotated():
    """The check's Omega would catch Omega on the wrong side (it is not a multiple of I and not
    diagonal)."""
    for *_, omega in ch02._contribution_cases():
        eig = np.linalg.eigvalsh(omega)
        assert eig[-1] / eig[0] > 5
        assert np.abs(omega - np.diag(np.diag(omega))).max() > 1.0


@pytest.mark.parametrize("answer", [..., _stub])
def test_contribution_not_attempted(capsys, answer):
    ok, out = run(capsys, ch02.check_edge_contribution, answer)
    assert not ok and "not attempted yet" in out


def test_contribution_partly_placeholder_is_not_attempted(capsys):
    def fn(e, A, B, W):
        return A.T @ W @ A, A.T @ W @ B, B.T @ W @ B, A.T @ W @ e, ...

    ok, out = run(capsys, ch02.check_edge_contribution, fn)
    assert not ok and "not attempted yet" in out


@pytest.mark.parametrize(
    "fn, message",
    [
        (
            lambda e, A, B, W: (A @ W @ A,) + contribution(e, A, B, W)[1:],
            "your H_ii is A Omega A: the transpose of A is missing",
        ),
        (
            lambda e, A, B, W: (A.T @ A @ W,) + contribution(e, A, B, W)[1:],
            "your H_ii is A^T A Omega: Omega is on the wrong side",
        ),
        (
            lambda e, A, B, W: (A.T @ W @ A, B.T @ W @ A) + contribution(e, A, B, W)[2:],
            "your H_ij is B^T Omega A: that is H_ji, the transpose of H_ij",
        ),
        (
            lambda e, A, B, W: (
                contribution(e, A, B, W)[:2] + (A.T @ W @ B,) + contribution(e, A, B, W)[3:]
            ),
            "your H_jj is A^T Omega B: the notes' slide, step 4, labels this product H^jj",
        ),
        (
            lambda e, A, B, W: contribution(e, A, B, W)[:3] + (-A.T @ W @ e, B.T @ W @ e),
            "your b_i is -A^T Omega e: b has a plus sign",
        ),
        (
            lambda e, A, B, W: contribution(e, A, B, W)[:4] + (B.T @ e,),
            "your b_j is B^T e: Omega is missing",
        ),
        (
            lambda e, A, B, W: contribution(e, A, B, W)[:4] + (A.T @ W @ e,),
            "your b_j is A^T Omega e: that uses the other block",
        ),
        (
            lambda e, A, B, W: contribution(e, A, B, W)[:4],
            "edge_contribution should return five arrays, (H_ii, H_ij, H_jj, b_i, b_j); it "
            "returned a tuple of length 4",
        ),
        (
            lambda e, A, B, W: contribution(e, A, B, W)[:3] + ((A.T @ W @ e)[:, None], B.T @ W @ e),
            "b_i has shape (3, 1), expected (3,)",
        ),
        (_raises, "edge_contribution raised ValueError: not finished"),
    ],
)
def test_contribution_wrong(capsys, fn, message):
    ok, out = run(capsys, ch02.check_edge_contribution, fn)
    assert not ok and not passed("2.2")
    assert "Exercise 2.2 — not yet: on edge 1 of 3: " in out
    assert message in out
    assert 'Stuck? hint("2.2")' in out
    # the diagnosis names the slip; the right products are the last hint level
    assert "A^T Omega B, B^T Omega A" not in out and "H_ij = A^T Omega B" not in out
    assert "J^T Omega J has the blocks A^T Omega A, A^T Omega B" in hints(capsys, "2.2")


def test_contribution_generic_difference(capsys):
    """An answer that is no known slip gets the size of the difference."""

    def fn(e, A, B, W):
        H_ii, *rest = contribution(e, A, B, W)
        return (H_ii * 1.01, *rest)

    ok, out = run(capsys, ch02.check_edge_contribution, fn)
    assert not ok and "H_ii differs from the reference in 9 of its 9 entries: at index" in out


# ----------------------------------------------------------------------------- 2.3
def test_structure_graph_is_as_described():
    g = ch02.structure_graph()
    assert (g.n, g.m) == (7, 10)
    assert g.components()[0] == 2
    assert ch02._structure(g) == (23, 6)


@pytest.mark.parametrize("answer", [(23, 6), (23.0, 6.0), (np.int64(23), np.int64(6))])
def test_structure_correct(capsys, answer):
    ok, out = run(capsys, ch02.check_structure, *answer)
    assert ok and passed("2.3")
    assert (
        "Exercise 2.3 — correct: lagolib's H has 23 non-zero blocks (7 diagonal + 2 x 8 pairs of "
        "joined poses) and a null space of dimension 6 (2 components x 3)." in out
    )


@pytest.mark.parametrize("answer", [(..., ...), (23, ...), (..., 6), (None, None)])
def test_structure_not_attempted(capsys, answer):
    ok, out = run(capsys, ch02.check_structure, *answer)
    assert not ok and "not attempted yet" in out


@pytest.mark.parametrize(
    "answer, messages",
    [
        ((27, 6), ["n_blocks = 27 is too large: you counted edges"]),
        ((15, 6), ["n_blocks = 15 is too small: each pair", "two off-diagonal blocks, H_ij and H_ji"]),
        ((16, 6), ["n_blocks = 16 is too small", "every pose also has its diagonal block"]),
        ((23, 3), ["null_dim = 3 is too small", "is this graph connected?"]),
        ((23, 0), ["null_dim = 0 is too small", "H is singular"]),
        ((49, 3), ["n_blocks = 49 is too large", "H is sparse", "null_dim = 3 is too small"]),
        ((23, 4), ["null_dim = 4 is too small."]),
        (("23", 6), ["n_blocks should be a whole number, got '23' (a string"]),
        ((23, True), ["null_dim should be a whole number, got True (a bool)"]),
        ((23.5, 6.0), ["n_blocks should be a whole number, got 23.5"]),
    ],
)
def test_structure_wrong(capsys, answer, messages):
    ok, out = run(capsys, ch02.check_structure, *answer)
    assert not ok and not passed("2.3")
    assert "Exercise 2.3 — not yet:" in out
    # neither the actual values nor the graph's counts are part of the diagnosis
    assert "lagolib's H has" not in out and "distinct pairs" not in out
    for m in messages:
        assert m in out
    kind = any("should be" in m for m in messages)
    assert ("8 distinct pairs of poses, in 2 connected components" in hints(capsys, "2.3")) is not (
        kind
    )


# ----------------------------------------------------------------------------- 2.4
def test_damping_sweep_numbers():
    sweep = ch02.damping_sweep()
    its = [s[1] for s in sweep]
    assert its == [5, 5, 5, 6, 8, 10]
    chis = np.array([s[2] for s in sweep])
    assert np.ptp(chis) / chis.min() < 1e-9
    assert chis[0] == pytest.approx(321.6928171775, rel=1e-9)


@pytest.mark.parametrize("answer", [("more", True), ("More ", np.bool_(True))])
def test_damping_correct(capsys, answer):
    ok, out = run(capsys, ch02.check_damping, *answer)
    assert ok and passed("2.4")
    assert "Exercise 2.4 — correct: iterations per lambda_initial 1e-05: 5" in out
    assert "1e+05: 10" in out


@pytest.mark.parametrize("answer", [(..., ...), ("more", ...), (..., True)])
def test_damping_not_attempted(capsys, answer):
    ok, out = run(capsys, ch02.check_damping, *answer)
    assert not ok and "not attempted yet" in out


@pytest.mark.parametrize(
    "answer, messages",
    [
        (("fewer", True), ["trend is 'fewer', which is not the answer"]),
        (("same", True), ["trend is 'same', which is not the answer"]),
        (("more", False), ["same_optimum is False, which is not the answer"]),
        (("faster", True), ["trend should be one of ['more', 'fewer', 'same']"]),
        (("more", "maybe"), ["same_optimum should be True or False, got 'maybe' (a string)"]),
        (("more", 1), ["same_optimum should be True or False, got 1 (an int)"]),
        ((b"more", True), ["trend should be one of ['more', 'fewer', 'same'] (a string)"]),
    ],
)
def test_damping_wrong(capsys, answer, messages):
    ok, out = run(capsys, ch02.check_damping, *answer)
    assert not ok and not passed("2.4")
    assert "Exercise 2.4 — not yet:" in out
    # the sweep is the last hint of a prediction, never part of the diagnosis
    assert "1e+05: 10" not in out
    for m in messages:
        assert m in out
    kind = any("True or False," in m or "(a string)" in m for m in messages)
    levels = hints(capsys, "2.4")
    assert ("hint 3 of 3: the check's sweep: iterations per lambda_initial" in levels) is not kind
    if answer == ("fewer", True):
        assert "a large lambda I swamps H" in levels
    if answer == ("more", False):
        assert "changes the path to the minimum" in levels


def test_damping_accepts_yes_for_a_yes_no_question(capsys):
    ok, out = run(capsys, ch02.check_damping, "more", "yes")
    assert ok and out.startswith("Exercise 2.4 — correct:")


# ----------------------------------------------------------------------------- the chapter
def test_chapter_has_the_exercises():
    nb = json.loads(CHAPTER.read_text(encoding="utf-8"))
    found = [x for x in book.exercises(nb, str(CHAPTER)) if x["kind"] != "derive"]
    assert [(x["id"], x["kind"]) for x in found] == [
        ("2.1", "implement"),
        ("2.2", "implement"),
        ("2.3", "predict"),
        ("2.4", "explore"),
    ]
    student = book.student_copy(nb, str(CHAPTER))

    def sources(notebook):
        return "\n".join("".join(c["source"]) for c in notebook["cells"])

    for solved in ("A.T @ Omega @ B", 'trend = "more"', "n_blocks = 23", "A[0, 2] = -s"):
        assert solved in sources(nb) and solved not in sources(student)
    checks = [c for c in student["cells"] if "solution-check" in c["metadata"].get("tags", [])]
    assert not checks
