"""The checks of chapter 1's exercises (lagolib.exercises.ch01): right, placeholder, wrong, raising.

Every check must say "correct" for the reference answer, "not attempted yet" for the stub's
placeholder, name the specific mistake for realistic wrong answers, and never raise.
"""

import numpy as np
import pytest

from lagolib import PoseGraph, se2, simulate
from lagolib.exercises import ch01, hint, passed, reset

NOT_ATTEMPTED = "not attempted yet"


@pytest.fixture(autouse=True)
def _fresh_results():
    reset()
    yield
    reset()


def run(capsys, check, *answers):
    """Call ``check(*answers)``; return (result, printed text)."""
    result = check(*answers)
    out = capsys.readouterr().out
    return result, out


def hints(capsys, exercise):
    """Every hint level of ``exercise``'s last "not yet", as printed by ``hint`` (one per call)."""
    for _ in range(6):
        hint(exercise)
    return capsys.readouterr().out


# ---------------------------------------------------------------------------------------------
# Exercise 1.1: the error of one edge


def edge_error(p_i, p_j, z):
    return se2.t2v(np.linalg.inv(se2.v2t(z)) @ np.linalg.inv(se2.v2t(p_i)) @ se2.v2t(p_j))


def written_out(p_i, p_j, z):
    t = se2.rotation(z[2]).T @ (se2.rotation(p_i[2]).T @ (p_j[:2] - p_i[:2]) - z[:2])
    return np.r_[t, se2.wrap_angle(p_j[2] - p_i[2] - z[2])]


def unwrapped(p_i, p_j, z):
    e = written_out(p_i, p_j, z)
    e[2] = p_j[2] - p_i[2] - z[2]
    return e


def frame_i(p_i, p_j, z):
    return se2.between(p_i, p_j) - z


def swapped(p_i, p_j, z):
    return edge_error(p_j, p_i, z)


def z_not_inverted(p_i, p_j, z):
    return se2.t2v(se2.v2t(z) @ np.linalg.inv(se2.v2t(p_i)) @ se2.v2t(p_j))


def z_on_the_right(p_i, p_j, z):
    return se2.t2v(np.linalg.inv(se2.v2t(p_i)) @ se2.v2t(p_j) @ np.linalg.inv(se2.v2t(z)))


@pytest.mark.parametrize("answer", [edge_error, written_out], ids=["matrices", "written-out"])
def test_edge_error_reference_is_correct(capsys, answer):
    ok, out = run(capsys, ch01.check_edge_error, answer)
    assert ok is True and passed("1.1")
    assert out.startswith("Exercise 1.1 — correct: all 24 edges agree")


@pytest.mark.parametrize(
    "answer", [..., lambda p_i, p_j, z: ..., lambda p_i, p_j, z: None], ids=["...", "stub", "None"]
)
def test_edge_error_placeholder_is_not_attempted(capsys, answer):
    ok, out = run(capsys, ch01.check_edge_error, answer)
    assert ok is False and not passed("1.1")
    assert out.startswith(f"Exercise 1.1 — {NOT_ATTEMPTED}")


@pytest.mark.parametrize(
    "answer, message",
    [
        (unwrapped, "differs from lagolib's by a whole turn, 2π. The error's angle must be wrapped"),
        (frame_i, "the error in the frame of pose i"),
        (swapped, "you computed the pose of i seen from j"),
        (z_not_inverted, "you multiplied by Z_ij instead of its inverse"),
        (z_on_the_right, "Z_ij⁻¹ multiplies from the wrong side"),
        (lambda p_i, p_j, z: -edge_error(p_i, p_j, z), "has the opposite sign of the reference"),
        (
            lambda p_i, p_j, z: edge_error(p_i, p_j, z).reshape(3, 1),
            "has shape (3, 1), expected (3,)",
        ),
        (lambda p_i, p_j, z: edge_error(p_i, p_j, z)[:2], "has shape (2,), expected (3,)"),
        (lambda p_i, p_j, z: edge_error(p_i, p_j, z) + [1e-3, 0, 0], "angles are right but not"),
        (3.0, "edge_error should be a function (def ...), but it is a float"),
        (
            lambda p_i, p_j, z: edge_error(p_i, p_j, z) * [1.0, 1.0, 180 / np.pi],
            "your angles are in degrees",
        ),
    ],
    ids=[
        "unwrapped",
        "frame-i",
        "swapped",
        "z-not-inverted",
        "z-right",
        "sign",
        "shape31",
        "shape2",
        "offset",
        "not-callable",
        "degrees",
    ],
)
def test_edge_error_wrong_answers_are_named(capsys, answer, message):
    ok, out = run(capsys, ch01.check_edge_error, answer)
    assert ok is False and not passed("1.1")
    assert out.startswith("Exercise 1.1 — not yet:")
    assert message in out


def test_edge_error_hint_does_not_give_the_code_away(capsys):
    ok, out = run(capsys, ch01.check_edge_error, frame_i)
    assert ok is False and "build the three matrices" not in out  # a hint, not the diagnosis
    levels = hints(capsys, "1.1")
    assert "hint 3 of 3: build the three matrices" in levels
    assert "inv(v2t(z)) @ inv(v2t(p_i)) @ v2t(p_j)" not in out + levels


def test_edge_error_a_raising_function_is_feedback(capsys):
    def broken(p_i, p_j, z):
        return np.linalg.inv(np.zeros((3, 3)))

    ok, out = run(capsys, ch01.check_edge_error, broken)
    assert ok is False
    assert "edge_error raised LinAlgError: Singular matrix" in out
    assert "(edge 0: p_i = " in out  # names the input that broke it


def test_edge_cases_reach_beyond_pi():
    # the check's seeded edges include unwrapped angle errors beyond ±π, and the reference wraps
    p_i, p_j, z = ch01._edge_cases()
    raw = p_j[:, 2] - p_i[:, 2] - z[:, 2]
    assert len(p_i) == 24 and np.sum(np.abs(raw) > np.pi) >= 8
    ref = ch01._reference_errors(p_i, p_j, z)
    np.testing.assert_allclose(ref, [edge_error(*args) for args in zip(p_i, p_j, z)], atol=1e-12)
    assert np.all(np.abs(ref[:, 2]) <= np.pi)


# ---------------------------------------------------------------------------------------------
# Exercise 1.2: heading noise and the end distance


def test_heading_noise_reference_is_correct(capsys):
    ok, out = run(capsys, ch01.check_heading_noise, np.sqrt(10), "linear")
    assert ok is True and passed("1.2")
    assert out.startswith("Exercise 1.2 — correct: 4000 simulated runs each")
    assert "ratio 3.06" in out and "2.00 times" in out


def test_heading_noise_accepts_a_few_hundred_runs(capsys):
    # what the chapter's solution computes: 400 runs, seed 0
    rng = np.random.default_rng(0)
    d8 = ch01.end_distances(ch01.OCTAGON_STEP, 8, 0.05, 400, rng).mean()
    d80 = ch01.end_distances(ch01.OCTAGON_STEP / 10, 80, 0.05, 400, rng).mean()
    ok, _ = run(capsys, ch01.check_heading_noise, d80 / d8, "Linear ")
    assert ok is True


@pytest.mark.parametrize(
    "ratio, growth",
    [(..., "linear"), (3.16, ...), (None, None)],
    ids=["ratio", "growth", "both"],
)
def test_heading_noise_placeholder_is_not_attempted(capsys, ratio, growth):
    ok, out = run(capsys, ch01.check_heading_noise, ratio, growth)
    assert ok is False and out.startswith(f"Exercise 1.2 — {NOT_ATTEMPTED}")


@pytest.mark.parametrize(
    "ratio, growth, message",
    [
        (10.0, "linear", "10 is the ratio of the numbers of steps"),
        (1.0, "linear", "ten times as many independent heading errors"),
        (1 / np.sqrt(10), "linear", "You inverted it"),
        (2.0, "linear", "distance_ratio = 2 is too small: less than two thirds of the reference."),
        (3.16, "quadratic", "doubling σ would multiply the mean end distance by 4"),
        (3.16, "square root", "growth_with_sigma = 'square root' is not what the simulation"),
        (3.16, "lin", "growth_with_sigma should be one of"),
        ("three", "linear", "distance_ratio should be one real number, got 'three' (a string)"),
        ("3.1", "linear", "distance_ratio should be one real number, got '3.1' (a string"),
        (np.array([3.1, 3.2]), "linear", "distance_ratio should be one real number, got an array"),
    ],
    ids=[
        "steps",
        "same",
        "inverted",
        "off",
        "quadratic",
        "sqrt",
        "bad-choice",
        "text",
        "numeric-text",
        "array",
    ],
)
def test_heading_noise_wrong_answers_are_named(capsys, ratio, growth, message):
    ok, out = run(capsys, ch01.check_heading_noise, ratio, growth)
    assert ok is False and not passed("1.2")
    assert out.startswith("Exercise 1.2 — not yet:")
    assert message in out
    assert "3.06" not in out  # the simulation's numbers are the last hint
    assert "'linear'" not in out or "should be one of" in out


def test_heading_noise_reports_both_mistakes(capsys):
    ok, out = run(capsys, ch01.check_heading_noise, 10.0, "square root")
    assert ok is False
    assert "growth_with_sigma = 'square root' is not what the simulation shows" in out
    assert "distance_ratio = 10 is too large: more than 1.5 times the reference." in out
    levels = hints(capsys, "1.2")
    assert "hint 3 of 3: the check's own simulation" in levels and "(ratio 3.06" in levels


def test_end_distances_close_without_noise_and_scale_with_sigma():
    rng = np.random.default_rng(1)
    assert ch01.end_distances(ch01.OCTAGON_STEP, 8, 0.0, 10, rng).max() < 1e-12
    d1 = ch01.end_distances(ch01.OCTAGON_STEP, 8, 0.01, 2000, np.random.default_rng(2)).mean()
    d2 = ch01.end_distances(ch01.OCTAGON_STEP, 8, 0.02, 2000, np.random.default_rng(2)).mean()
    assert d2 / d1 == pytest.approx(2.0, rel=0.01)  # same draws: linear to first order


# ---------------------------------------------------------------------------------------------
# Exercise 1.3: χ² at the odometry guess and the number of laps


def test_chi2_laps_reference_is_correct(capsys):
    ok, out = run(capsys, ch01.check_chi2_laps, 0.0, "linear")
    assert ok is True and passed("1.3")
    assert out.startswith("Exercise 1.3 — correct: mean χ² at the odometry guess over 12 worlds")
    assert "2 laps: 9636" in out and "6 laps: 4.706e+04" in out


def test_chi2_by_laps_numbers():
    mean, odometric = ch01.chi2_by_laps()
    assert mean[0] < 1e-20 and odometric < 1e-20
    per_lap = mean[1:] / np.arange(1, 6)
    assert per_lap.max() < 1.05 * per_lap.min()
    assert mean[1] == pytest.approx(9636, rel=1e-3)


@pytest.mark.parametrize("answers", [(..., "linear"), (0.0, ...)], ids=["value", "growth"])
def test_chi2_laps_placeholder_is_not_attempted(capsys, answers):
    ok, out = run(capsys, ch01.check_chi2_laps, *answers)
    assert ok is False and out.startswith(f"Exercise 1.3 — {NOT_ATTEMPTED}")


@pytest.mark.parametrize(
    "answers, message",
    [
        ((117, "linear"), "chi2_one_lap = 117 is too large (the check allows 1e-6"),
        ((-3, "linear"), "χ² is a sum of squares, it cannot be negative"),
        ((0.0, "quadratic"), "(every lap would add more than the one before)"),
        ((0.0, "constant"), "(every lap after the first would add nothing)"),
        ((0.0, "exponential"), "growth should be one of ['constant', 'linear', 'quadratic']"),
        ((True, "linear"), "chi2_one_lap should be one real number, got True (a bool)"),
        (("zero", "linear"), "chi2_one_lap should be one real number, got 'zero' (a string)"),
    ],
    ids=["3m", "negative", "quadratic", "constant", "bad-choice", "bool", "text"],
)
def test_chi2_laps_wrong_answers_are_named(capsys, answers, message):
    ok, out = run(capsys, ch01.check_chi2_laps, *answers)
    assert ok is False and not passed("1.3")
    assert out.startswith("Exercise 1.3 — not yet:")
    assert message in out
    # the computed table is the last hint of a prediction, never part of the diagnosis
    assert "per lap after the first" not in out
    levels = hints(capsys, "1.3")
    assert ("per lap after the first" in levels) == ("real number" not in message)


# ---------------------------------------------------------------------------------------------
# Exercise 1.4: the information in a TORO file


def test_toro_frames_reference_is_correct(capsys):
    ok, out = run(capsys, ch01.check_toro_frames, True, False)
    assert ok is True and passed("1.4")
    assert out.startswith("Exercise 1.4 — correct:") and "anisotropic 0.92" in out


@pytest.mark.parametrize("answers", [(..., False), (True, None)], ids=["iso", "aniso"])
def test_toro_frames_placeholder_is_not_attempted(capsys, answers):
    ok, out = run(capsys, ch01.check_toro_frames, *answers)
    assert ok is False and out.startswith(f"Exercise 1.4 — {NOT_ATTEMPTED}")


@pytest.mark.parametrize(
    "answers, message",
    [
        ((False, False), "same_isotropic = False is not what the TORO file holds."),
        ((True, True), "same_anisotropic = True is not what the TORO file holds."),
        ((False, True), "same_isotropic = False is not what"),
        (("maybe", False), "same_isotropic should be True or False, got 'maybe' (a string)"),
        (("True", False), "True and False are written without quotes"),
    ],
    ids=["iso", "aniso", "both", "text", "quoted"],
)
def test_toro_frames_wrong_answers_are_named(capsys, answers, message):
    ok, out = run(capsys, ch01.check_toro_frames, *answers)
    assert ok is False and not passed("1.4")
    assert out.startswith("Exercise 1.4 — not yet:")
    assert message in out
    assert "isotropic 1.4e-16" not in out  # what the file holds is the last hint


def test_toro_frames_explains_in_the_hints(capsys):
    run(capsys, ch01.check_toro_frames, False, True)
    levels = hints(capsys, "1.4")
    assert "hint 2 of 3: a rotation leaves an isotropic block unchanged" in levels
    assert "turns an anisotropic block's principal axes" in levels
    assert "hint 3 of 3: what the check read in the files" in levels and "anisotropic 0.92" in levels


def test_toro_frames_accepts_yes_and_no(capsys):
    ok, out = run(capsys, ch01.check_toro_frames, "yes", "No")
    assert ok is True and out.startswith("Exercise 1.4 — correct:")


def test_toro_file_information_is_the_frame_i_information():
    g = simulate.loop_world(laps=1, poses_per_lap=8, sigma_xy=0.05, sigma_theta=0.01, rng=4).graph
    rng = np.random.default_rng(4)
    Q = se2.rotation(rng.uniform(-np.pi, np.pi, g.m))
    info = np.zeros((g.m, 3, 3))
    info[:, :2, :2] = Q @ np.diag([400.0, 25.0]) @ np.swapaxes(Q, 1, 2)
    info[:, 2, 2] = 1e4
    info[:, 0, 2] = info[:, 2, 0] = 5.0  # x–θ coupling: the TORO order I11 I12 I22 I33 I13 I23
    h = PoseGraph(g.poses, g.edges, g.measurements, info)
    in_file = ch01.toro_file_information(h)
    expected = se2.information_to_frame_i(info, g.measurements[:, 2])
    np.testing.assert_allclose(in_file, expected, rtol=1e-12, atol=1e-9)
    assert np.abs(in_file - info).max() > 1.0
