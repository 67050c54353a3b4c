"""Chapter 8's exercise checks (lagolib.exercises.ch08): right, unfinished, wrong and crashing answers.

Every check must say "correct" to the reference answer, "not attempted yet" to the stub's
placeholder, name the mistake for the usual wrong answers, and never raise.  The checks draw their
test cases from fixed seeds (and the shipped ``square_loop`` graph), so the numbers asserted here
are reproducible.
"""

import numpy as np
import pytest

import lagolib
from lagolib import se2
from lagolib.exercises import NOT_ATTEMPTED, ch08, hint, passed, reset
from lagolib.sgd import sgd


@pytest.fixture(autouse=True)
def _fresh_results():
    reset()
    yield
    reset()


def _run(capsys, check, *answer):
    ok = check(*answer)
    out = capsys.readouterr().out
    return ok, out


def _hints(capsys, exercise):
    """Every hint level of ``exercise``'s last "not yet", as ``hint`` prints them."""
    for _ in range(4):
        hint(exercise)
    return capsys.readouterr().out


# --------------------------------------------------------------------------- 8.1
def eta_ok(graph, poses):
    x = np.asarray(poses, dtype=float)
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    E = se2.between(graph.measurements, se2.between(x[i], x[j]))
    return float(np.mean(E[:, 0] ** 2 + E[:, 1] ** 2)), float(np.mean(E[:, 2] ** 2))


def eta_unwrapped(graph, poses):
    x = np.asarray(poses, dtype=float)
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    ec, _ = eta_ok(graph, poses)
    a = x[j, 2] - x[i, 2] - graph.measurements[:, 2]
    return ec, float(np.mean(a**2))


def eta_global_frame(graph, poses):
    x = np.asarray(poses, dtype=float)
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    t = x[j, :2] - x[i, :2] - graph.measurements[:, :2]
    return float(np.mean(np.sum(t**2, axis=1))), eta_ok(graph, poses)[1]


def eta_sum(graph, poses):
    return tuple(graph.m * v for v in eta_ok(graph, poses))


def eta_weighted(graph, poses):
    return lagolib.chi2(graph, poses) / graph.m, 0.0


def test_eta_reference_is_correct(capsys):
    ok, out = _run(capsys, ch08.check_eta, eta_ok)
    assert ok is True and passed("8.1")
    assert "Exercise 8.1 — correct" in out and "all 2 test cases" in out


def test_eta_frame_i_residual_is_also_correct(capsys):
    # R_i^T (t_j - t_i) - t_z has the same norm as the g2o error: property (a) of the chapter
    def frame_i(graph, poses):
        x = np.asarray(poses, dtype=float)
        i, j = graph.edges[:, 0], graph.edges[:, 1]
        d = se2.between(x[i], x[j])
        t = d[:, :2] - graph.measurements[:, :2]
        a = se2.wrap_angle(d[:, 2] - graph.measurements[:, 2])
        return float(np.mean(np.sum(t**2, axis=1))), float(np.mean(a**2))

    ok, _ = _run(capsys, ch08.check_eta, frame_i)
    assert ok is True


def test_eta_cases_are_what_the_statement_says():
    (g1, p1), (g2, p2) = ch08._eta_cases()
    assert (g1.n, g1.m) == (16, 23)
    ev = np.linalg.eigvalsh(g1.information[:, :2, :2])
    assert np.all(ev[:, 1] / ev[:, 0] > 100)  # anisotropic
    assert np.abs(p1[:, 2]).max() > 2 * np.pi  # headings stored whole turns apart
    eta = lagolib.metrics.constraint_satisfaction(g1, p1)
    assert eta.eta_c == pytest.approx(0.02061503045111443, rel=1e-9)
    assert eta.eta_a == pytest.approx(0.012974407330990461, rel=1e-9)


@pytest.mark.parametrize(
    "stub", [..., lambda g, p: ..., lambda g, p: None, lambda g, p: (..., ...)]
)
def test_eta_stub_is_not_attempted(capsys, stub):
    ok, out = _run(capsys, ch08.check_eta, stub)
    assert ok is False and not passed("8.1")
    assert NOT_ATTEMPTED in out


def eta_loop_closures_only(graph, poses):
    x = np.asarray(poses)
    i, j = graph.edges.T
    E = se2.between(graph.measurements, se2.between(x[i], x[j]))[graph.loop_closure]
    return float(np.mean(E[:, 0] ** 2 + E[:, 1] ** 2)), float(np.mean(se2.wrap_angle(E[:, 2]) ** 2))


@pytest.mark.parametrize(
    "wrong, message",
    [
        (eta_unwrapped, "eta_a = 170.165 is too large: the angle errors were not wrapped"),
        (eta_global_frame, "eta_c = 1.32556 is not right: you compared t_j − t_i"),
        (eta_sum, "23 times too large — the sum over the 23 edges, not the mean"),
        (lambda g, p: eta_ok(g, p)[::-1], "your two numbers are swapped"),
        (
            lambda g, p: tuple(np.sqrt(eta_ok(g, p))),
            "a root mean square, not the mean squared error",
        ),
        (eta_weighted, "weighted by the information matrices (a χ²)"),
        (
            lambda g, p: eta_ok(g, p)[0],
            "eta should return two numbers, (eta_c, eta_a); it returned 0.020615 (a float)",
        ),
        (eta_loop_closures_only, "your numbers are means over the loop closures only"),
    ],
    ids=["unwrapped", "global-frame", "sum", "swapped", "rms", "weighted", "one-number", "lc"],
)
def test_eta_wrong_answers_are_named(capsys, wrong, message):
    ok, out = _run(capsys, ch08.check_eta, wrong)
    assert ok is False and not passed("8.1")
    assert "Exercise 8.1 — not yet: on test 1 of 2" in out or "(a float)" in out
    assert message in out
    assert "reference is" not in out and "0.0129744" not in out  # never the reference's numbers


@pytest.mark.parametrize(
    "form",
    [
        lambda ec, ea: np.array([ec, ea]),  # review of issue 24: an ndarray was refused
        lambda ec, ea: (np.array([ec]), np.array([ea])),  # np.mean(..., keepdims=True)
        lambda ec, ea: np.array([[ec], [ea]]),  # a column
        lambda ec, ea: np.array([[ec, ea]]),  # a row: np.mean(E, axis=0, keepdims=True)
        lambda ec, ea: [np.float32(ec), np.float64(ea)],
        lambda ec, ea: (np.array(ec), ea),
    ],
    ids=["array", "one-entry-arrays", "column", "row", "list-of-numpy-scalars", "0-d"],
)
def test_eta_right_answer_of_any_numeric_type_is_correct(capsys, form):
    def eta(graph, poses):
        return form(*eta_ok(graph, poses))

    ok, out = _run(capsys, ch08.check_eta, eta)
    assert ok is True and out.startswith("Exercise 8.1 — correct"), out


def test_eta_student_exception_is_feedback(capsys):
    def broken(graph, poses):
        return poses[graph.n + 5]

    ok, out = _run(capsys, ch08.check_eta, broken)
    assert ok is False and "eta raised IndexError" in out


def test_eta_in_place_modification_does_not_corrupt_the_reference(capsys):
    def in_place(graph, poses):
        out = eta_ok(graph, poses)
        poses[:] = 0.0
        return out

    ok, _ = _run(capsys, ch08.check_eta, in_place)
    assert ok is True
    ok, _ = _run(capsys, ch08.check_eta, eta_ok)
    assert ok is True


# --------------------------------------------------------------------------- 8.2
@pytest.fixture(scope="module")
def identity_scenario():
    g = lagolib.datasets.example("square_loop").graph
    gi = g.with_information(np.eye(3))
    run = sgd(gi, g.odometry_guess(), iterations=100)
    return gi, run.poses


def test_smallest_sum_reference_is_correct(capsys, identity_scenario):
    ok, out = _run(capsys, ch08.check_smallest_sum, "Gauss-Newton", *identity_scenario)
    assert ok is True and passed("8.2")
    assert (
        "Exercise 8.2 — correct: eta_c + eta_a: SGD 0.001967, LAGO 0.001736, Gauss-Newton 0.001735"
        in out
    )


@pytest.mark.parametrize("spelling", [" gauss-newton ", "Gauss–Newton", "Gauss Newton"])
def test_smallest_sum_accepts_the_printed_spellings(capsys, identity_scenario, spelling):
    # the chapter prints "Gauss–Newton" with an en dash; typing it as seen is the right answer
    ok, _ = _run(capsys, ch08.check_smallest_sum, spelling, *identity_scenario)
    assert ok is True


def test_smallest_sum_stub_is_not_attempted(capsys, identity_scenario):
    ok, out = _run(capsys, ch08.check_smallest_sum, ..., *identity_scenario)
    assert ok is False and NOT_ATTEMPTED in out


@pytest.mark.parametrize("wrong", ["LAGO", "SGD"])
def test_smallest_sum_wrong_choice_is_explained(capsys, identity_scenario, wrong):
    ok, out = _run(capsys, ch08.check_smallest_sum, wrong, *identity_scenario)
    assert ok is False
    assert f"smallest = {wrong!r} is not the estimate with the smallest eta_c + eta_a." in out
    assert "SGD 0" not in out  # the three sums are the last hint
    levels = _hints(capsys, "8.2")
    assert "with identity information, what is χ² divided by the number of edges?" in levels
    assert "hint 3 of 3: the check's numbers: eta_c + eta_a: SGD" in levels


def test_smallest_sum_unknown_choice_lists_the_choices(capsys, identity_scenario):
    ok, out = _run(capsys, ch08.check_smallest_sum, "GN", *identity_scenario)
    assert ok is False
    assert "smallest should be one of ['SGD', 'LAGO', 'Gauss-Newton'], got 'GN'" in out


def test_smallest_sum_with_the_wrong_graph_does_not_raise(capsys, identity_scenario):
    g = lagolib.datasets.example("square_loop").graph  # not the identity scenario
    ok, out = _run(capsys, ch08.check_smallest_sum, "Gauss-Newton", g, identity_scenario[1])
    assert ok is False and "could not read your answer" in out and "P = I_3 graph" in out


# --------------------------------------------------------------------------- 8.3
@pytest.fixture(scope="module")
def sweep_graph():
    return lagolib.datasets.example("square_loop").graph


def test_angle_weight_sweep_numbers_and_cache(sweep_graph):
    table = ch08.angle_weight_sweep(sweep_graph)
    assert table.shape == (len(ch08.WEIGHTS), 2)
    assert np.all(np.diff(table[:, 0]) > 0) and np.all(np.diff(table[:, 1]) < 0)
    assert table[0, 1] / table[-1, 1] == pytest.approx(197.47, rel=1e-3)
    table[:] = 0.0  # a copy: the cache is not corrupted
    assert ch08.angle_weight_sweep(sweep_graph)[0, 1] > 0


def test_weight_sweep_reference_is_correct(capsys, sweep_graph):
    ratio = ch08.angle_weight_sweep(sweep_graph)[0, 1] / ch08.angle_weight_sweep(sweep_graph)[-1, 1]
    ok, out = _run(capsys, ch08.check_weight_sweep, "increases", "decreases", ratio, sweep_graph)
    assert ok is True and passed("8.3")
    assert "eta_c increases and eta_a decreases (by a factor 197)" in out


def test_weight_sweep_read_off_ratio_within_5_percent(capsys, sweep_graph):
    ok, _ = _run(capsys, ch08.check_weight_sweep, "increases", "decreases", 190, sweep_graph)
    assert ok is True


@pytest.mark.parametrize(
    "answer",
    [(..., ..., ...), ("increases", "decreases", ...), (..., "decreases", 197.0)],
)
def test_weight_sweep_stub_is_not_attempted(capsys, sweep_graph, answer):
    ok, out = _run(capsys, ch08.check_weight_sweep, *answer, sweep_graph)
    assert ok is False and NOT_ATTEMPTED in out


@pytest.mark.parametrize(
    "answer, message",
    [
        (("decreases", "increases", 197.0), "eta_c_trend is 'decreases', which is not the answer."),
        (("increases", "neither", 197.0), "eta_a_trend is 'neither', which is not the answer."),
        (("increases", "decreases", 1 / 197.47), "the inverse of the ratio asked for"),
        (("increases", "decreases", 150.0), "eta_a_ratio = 150 is too small, by 10 to 50 %."),
        (
            ("up", "decreases", 197.0),
            "eta_c_trend should be one of ['increases', 'decreases', 'neither']",
        ),
    ],
    ids=["trends-swapped", "a-neither", "inverse-ratio", "misread-ratio", "unknown-word"],
)
def test_weight_sweep_wrong_answers_are_named(capsys, sweep_graph, answer, message):
    ok, out = _run(capsys, ch08.check_weight_sweep, *answer, sweep_graph)
    assert ok is False and not passed("8.3")
    assert "Exercise 8.3 — not yet" in out and message in out
    assert "column" not in out and "197.4" not in out  # the table's numbers are the last hint
    levels = _hints(capsys, "8.3")
    if answer[0] == "decreases":
        assert "the check's eta_c column, w = 0.01 … 100: 0.000949" in levels
    if answer[1] == "neither":
        assert "the check's eta_a column, w = 0.01 … 100: 0.0084" in levels


def test_weight_sweep_odd_answer_does_not_raise(capsys, sweep_graph):
    ok, out = _run(capsys, ch08.check_weight_sweep, "increases", "decreases", [1, 2], sweep_graph)
    assert ok is False and "eta_a_ratio should be one real number, got a list" in out
