"""Chapter 6's exercise checks (lagolib.exercises.ch06): right, unfinished, wrong and crashing answers.

Every check must say "correct" to the reference answer, "not attempted yet" to the stub's
placeholder, name the mistake for the usual wrong answers, and never raise.  The checks draw their
test cases from fixed seeds, so the numbers asserted here are reproducible.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from lagolib import se2
from lagolib.book import exercises, solution_check_source
from lagolib.errors import OptionError
from lagolib.exercises import NOT_ATTEMPTED, ch06, hint, passed, reset

S = np.array([[0.0, -1.0], [1.0, 0.0]])
CHAPTER = Path(__file__).resolve().parent.parent / "book" / "06_lago.ipynb"


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


# --------------------------------------------------------------------------- the world
def test_anisotropic_loop_is_section_1s_world():
    sim = ch06.anisotropic_loop(8.0)
    g = sim.graph
    assert (g.n, g.m) == (48, 79)
    P = np.linalg.inv(g.information)
    sd = np.sqrt(np.linalg.eigvalsh(P[:, :2, :2]))
    np.testing.assert_allclose(sd, np.tile([0.02, 0.16], (79, 1)), rtol=1e-12)
    np.testing.assert_allclose(P[:, 2, 2], 0.02**2, rtol=1e-12)
    # same draws for every ratio: the isotropic twin has circles of the same area
    iso = ch06.anisotropic_loop(1.0).graph
    sd_iso = np.sqrt(np.linalg.eigvalsh(np.linalg.inv(iso.information)[:, :2, :2]))
    np.testing.assert_allclose(sd_iso, np.sqrt(0.02 * 0.16), rtol=1e-12)
    np.testing.assert_array_equal(iso.edges, g.edges)


@pytest.mark.parametrize(
    "kwargs, exc",
    [
        ({"ratio": 0.5}, OptionError),
        ({"ratio": "8"}, TypeError),
        ({"sigma_theta": 0.0}, ValueError),
        ({"seed": -1}, ValueError),
    ],
)
def test_anisotropic_loop_rejects_bad_arguments(kwargs, exc):
    with pytest.raises(exc, match="anisotropic_loop"):
        ch06.anisotropic_loop(**kwargs)


# --------------------------------------------------------------------------- 6.1
def _G(theta):
    G = np.eye(3)
    G[:2, :2] = se2.rotation(theta)
    return G


def frame_ok(Omega, theta_z):
    return _G(theta_z) @ Omega @ _G(theta_z).T


def test_frame_i_reference_is_correct(capsys):
    ok, out = _run(capsys, ch06.check_frame_i, frame_ok)
    assert ok is True and passed("6.1")
    assert "Exercise 6.1 — correct" in out and "all 5" in out


@pytest.mark.parametrize("stub", [..., lambda Omega, theta_z: ..., lambda Omega, theta_z: None])
def test_frame_i_stub_is_not_attempted(capsys, stub):
    ok, out = _run(capsys, ch06.check_frame_i, stub)
    assert ok is False and not passed("6.1")
    assert NOT_ATTEMPTED in out


@pytest.mark.parametrize(
    "wrong, message",
    [
        (lambda om, t: _G(t).T @ om @ _G(t), "Gᵀ Ω G — the conversion the other way"),
        (lambda om, t: om, "Ω unchanged"),
        (lambda om, t: _G(t) @ om, "not symmetric"),
        (lambda om, t: frame_ok(om, np.deg2rad(t)), "already in radians"),
        (lambda om, t: frame_ok(om, 2 * t), "twice θ_z"),
        (lambda om, t: frame_ok(om, t + 0.3), "rotated by +1.9158 rad"),
        (lambda om, t: frame_ok(om, t)[:2, :2], "shape (2, 2), expected (3, 3)"),
    ],
    ids=["transpose", "unrotated", "one-sided", "degrees", "twice", "wrong-angle", "2x2"],
)
def test_frame_i_wrong_answers_are_named(capsys, wrong, message):
    ok, out = _run(capsys, ch06.check_frame_i, wrong)
    assert ok is False
    assert "Exercise 6.1 — not yet: for θ_z = +1.6158 rad (test 1 of 5)" in out
    assert message in out


def test_frame_i_unrotated_cross_terms_are_named(capsys):
    def position_block_only(Omega, theta_z):
        R = se2.rotation(theta_z)
        out = Omega.copy()
        out[:2, :2] = R @ Omega[:2, :2] @ R.T
        return out

    ok, out = _run(capsys, ch06.check_frame_i, position_block_only)
    assert ok is False and "position–heading entries [:2, 2] and [2, :2]" in out


def test_frame_i_rotating_the_heading_row_is_named(capsys):
    def rotates_theta(Omega, theta_z):  # R placed on rows/columns (y, θ)
        G = np.eye(3)
        G[1:, 1:] = se2.rotation(theta_z)
        return G @ Omega @ G.T

    ok, out = _run(capsys, ch06.check_frame_i, rotates_theta)
    assert ok is False and "the heading entry [2, 2] changed from Ω's 1601.05" in out


def test_frame_i_covariance_instead_of_information_is_named(capsys):
    def covariance(Omega, theta_z):  # G Ω⁻¹ Gᵀ: rotated the right way, but not the information
        return frame_ok(np.linalg.inv(Omega), theta_z)

    ok, out = _run(capsys, ch06.check_frame_i, covariance)
    assert ok is False and "the covariance in frame i, not the information" in out
    assert "heading entry" not in out  # not misreported as a rotated heading row


@pytest.mark.parametrize("marginals", [False, True], ids=["zeroed", "split-information"])
def test_frame_i_dropped_correlation_is_named(capsys, marginals):
    def block_diagonal(Omega, theta_z):
        full = frame_ok(Omega, theta_z)
        out = np.zeros((3, 3))
        if marginals:  # what split_information does: the covariance's blocks, inverted
            P = np.linalg.inv(full)
            out[:2, :2], out[2, 2] = np.linalg.inv(P[:2, :2]), 1.0 / P[2, 2]
        else:
            out[:2, :2], out[2, 2] = full[:2, :2], full[2, 2]
        return out

    ok, out = _run(capsys, ch06.check_frame_i, block_diagonal)
    assert ok is False and "zeros in its position–heading entries" in out
    assert "split_information" in out and "heading entry" not in out


def test_frame_i_a_later_case_is_reported(capsys):
    # right for positive angles only: the check reports the first case it gets wrong
    def positive_only(Omega, theta_z):
        return frame_ok(Omega, abs(theta_z))

    ok, out = _run(capsys, ch06.check_frame_i, positive_only)
    assert ok is False and "θ_z = -2.4000 rad (test 2 of 5)" in out


def test_frame_i_student_exception_is_feedback(capsys):
    def broken(Omega, theta_z):
        return Omega[3, 3]

    ok, out = _run(capsys, ch06.check_frame_i, broken)
    assert ok is False and "to_frame_i raised IndexError" in out


def test_frame_i_in_place_modification_does_not_corrupt_the_reference(capsys):
    def in_place(Omega, theta_z):
        out = frame_ok(Omega, theta_z)
        Omega[:] = 0.0
        return out

    ok, out = _run(capsys, ch06.check_frame_i, in_place)
    assert ok is True
    ok, out = _run(capsys, ch06.check_frame_i, frame_ok)
    assert ok is True


# --------------------------------------------------------------------------- 6.2
def phase2_ok(theta_i, Delta_l, Omega_Delta):
    R = se2.rotation(theta_i)
    Delta_g = R @ Delta_l
    return Delta_g, S @ Delta_g, R @ Omega_Delta @ R.T


def test_phase2_edge_reference_is_correct(capsys):
    ok, out = _run(capsys, ch06.check_phase2_edge, phase2_ok)
    assert ok is True and passed("6.2")
    assert "Exercise 6.2 — correct" in out and "all 77 edges" in out


def test_phase2_edge_wrapped_angle_is_also_correct(capsys):
    ok, _ = _run(capsys, ch06.check_phase2_edge, lambda t, d, o: phase2_ok(se2.wrap_angle(t), d, o))
    assert ok is True


@pytest.mark.parametrize(
    "stub",
    [..., lambda t, d, o: ..., lambda t, d, o: (..., ..., ...), lambda t, d, o: None],
)
def test_phase2_edge_stub_is_not_attempted(capsys, stub):
    ok, out = _run(capsys, ch06.check_phase2_edge, stub)
    assert ok is False and NOT_ATTEMPTED in out


def _replace(k, value):
    def wrong(t, d, o):
        out = list(phase2_ok(t, d, o))
        out[k] = value(t, d, o)
        return tuple(out)

    return wrong


@pytest.mark.parametrize(
    "wrong, message",
    [
        (_replace(0, lambda t, d, o: d), "Delta_g equals Δ^l: it is still in frame i"),
        (_replace(0, lambda t, d, o: se2.rotation(t).T @ d), "Delta_g is R(θ̂_i)ᵀ Δ^l"),
        (_replace(1, lambda t, d, o: -S @ se2.rotation(t) @ d), "J has the opposite sign"),
        (_replace(1, lambda t, d, o: S @ d), "J is S Δ^l"),
        (_replace(1, lambda t, d, o: se2.rotation(t) @ d), "missing its S"),
        (_replace(2, lambda t, d, o: o), "W equals Ω_Δ"),
        (
            _replace(2, lambda t, d, o: se2.rotation(t).T @ o @ se2.rotation(t)),
            "W is Rᵀ Ω_Δ R: rotated the wrong way",
        ),
        (
            _replace(2, lambda t, d, o: np.linalg.inv(se2.rotation(t) @ o @ se2.rotation(t).T)),
            "W is the covariance P_Δg",
        ),
        (lambda t, d, o: phase2_ok(t, d, o)[:2], "returned a tuple of length 2"),
        (
            lambda t, d, o: np.zeros(2),
            "should return three arrays, (Delta_g, J, W); it returned an array of dtype float64",
        ),
    ],
    ids=[
        "Dg-frame-i",
        "Dg-transpose",
        "J-sign",
        "J-frame-i",
        "J-no-S",
        "W-frame-i",
        "W-transpose",
        "W-covariance",
        "two-outputs",
        "one-array",
    ],
)
def test_phase2_edge_wrong_answers_are_named(capsys, wrong, message):
    ok, out = _run(capsys, ch06.check_phase2_edge, wrong)
    assert ok is False and "Exercise 6.2 — not yet: edge " in out
    assert message in out


def test_phase2_edge_reports_an_edge_with_a_large_turn(capsys):
    # the first edge tried has θ̂_i near ±π/2 (mod 2π), where R and Rᵀ differ most
    ok, out = _run(capsys, ch06.check_phase2_edge, _replace(0, lambda t, d, o: d))
    theta = float(out.split("θ̂_i = ")[1].split(" rad")[0])
    assert abs(np.sin(theta)) > 0.99


def test_phase2_edge_student_exception_is_feedback(capsys):
    ok, out = _run(capsys, ch06.check_phase2_edge, lambda t, d, o: d @ np.ones(3))
    assert ok is False and "phase2_edge raised ValueError" in out


# --------------------------------------------------------------------------- 6.3
def test_closer_reference_is_correct(capsys):
    ok, out = _run(capsys, ch06.check_closer, "isotropic")
    assert ok is True and passed("6.3")
    assert "Exercise 6.3 — correct" in out
    assert "0.000157 above the Gauss–Newton optimum on the isotropic graph" in out
    assert "0.208 above it on the anisotropic one (1.32e+03 times more" in out


def test_closer_ignores_case_and_spaces(capsys):
    ok, _ = _run(capsys, ch06.check_closer, "  Isotropic ")
    assert ok is True


@pytest.mark.parametrize("stub", [..., None])
def test_closer_stub_is_not_attempted(capsys, stub):
    ok, out = _run(capsys, ch06.check_closer, stub)
    assert ok is False and NOT_ATTEMPTED in out


@pytest.mark.parametrize("wrong", ["anisotropic", "same"])
def test_closer_wrong_prediction_prints_the_values(capsys, wrong):
    ok, out = _run(capsys, ch06.check_closer, wrong)
    assert ok is False
    assert f"closer = {wrong!r} is not where LAGO lands closer" in out
    assert "0.000157" not in out and "eq. (18)" not in out  # both are hints
    levels = _hints(capsys, "6.3")
    assert "hint 2 of 3: eq. (18) holds the weights" in levels
    assert "hint 3 of 3: the check's numbers: LAGO's χ² lies 0.000157" in levels


@pytest.mark.parametrize("bad", ["iso", 1, True, ["isotropic"]])
def test_closer_not_a_choice(capsys, bad):
    ok, out = _run(capsys, ch06.check_closer, bad)
    assert ok is False and "closer should be one of" in out


# --------------------------------------------------------------------------- 6.4
GAP_RATIO = 4451.4  # 0.70097 / 0.00015747, printed by the chapter's sweep


def test_sweep_reference_is_correct(capsys):
    ok, out = _run(capsys, ch06.check_anisotropy_sweep, True, False, GAP_RATIO)
    assert ok is True and passed("6.4")
    assert "Exercise 6.4 — correct" in out and "4.45e+03 times" in out
    assert "0.5 → 2.5 → 5.2 → 6.8 → 8.3 → 6.4 → 6.3" in out


def test_sweep_ratio_read_from_the_rounded_table_is_correct(capsys):
    ok, _ = _run(capsys, ch06.check_anisotropy_sweep, True, False, 0.701 / 0.000157)
    assert ok is True


@pytest.mark.parametrize(
    "answer", [(..., False, GAP_RATIO), (True, ..., GAP_RATIO), (True, False, ...)]
)
def test_sweep_stub_is_not_attempted(capsys, answer):
    ok, out = _run(capsys, ch06.check_anisotropy_sweep, *answer)
    assert ok is False and NOT_ATTEMPTED in out


@pytest.mark.parametrize(
    "answer, message",
    [
        ((False, False, GAP_RATIO), "gap_grows = False is not what the sweep shows"),
        ((True, True, GAP_RATIO), "distance_grows = True is not what the sweep shows"),
        ((True, False, 1 / GAP_RATIO), "It is the inverse of the reference"),
        ((True, False, 4451.4 * 1.2), "gap_ratio = 5341.68 is too large, by 10 to 50 %."),
        ((True, False, 0.701 / 0.0159), "the gap at ratio 64 divided by the gap at ratio 2"),
        (("maybe", False, GAP_RATIO), "gap_grows should be True or False"),
        ((True, False, "many"), "gap_ratio should be one real number, got 'many'"),
    ],
    ids=[
        "gap-trend",
        "distance-trend",
        "inverse",
        "off-by-20%",
        "wrong-row",
        "not-bool",
        "not-number",
    ],
)
def test_sweep_wrong_answers_are_named(capsys, answer, message):
    ok, out = _run(capsys, ch06.check_anisotropy_sweep, *answer)
    assert ok is False and "Exercise 6.4 — not yet" in out
    assert message in out
    assert "→" not in out and "4451" not in out  # the sweep's numbers are the last hint
    if answer[:2] == (True, True):
        assert "it falls from ratio 16 to 32" in _hints(capsys, "6.4")


# --------------------------------------------------------------------------- the chapter
def test_chapter_has_the_exercises_the_checks_belong_to():
    nb = json.loads(CHAPTER.read_text(encoding="utf-8"))
    found = exercises(nb, str(CHAPTER))
    assert [(e["id"], e["kind"]) for e in found if e["kind"] != "derive"] == [
        ("6.1", "implement"),
        ("6.2", "implement"),
        ("6.3", "predict"),
        ("6.4", "explore"),
    ]
    sources = ["".join(c["source"]) for c in nb["cells"]]
    for name in ("check_frame_i", "check_phase2_edge", "check_closer", "check_anisotropy_sweep"):
        assert sum(f"ch06.{name}(" in s for s in sources) == 1
    for e in found:
        assert solution_check_source(e["id"]) in sources
