"""Chapter 9's exercise checks (lagolib.exercises.ch09): right, unfinished, wrong and crashing answers.

Every check must say "correct" to the reference answer, "not attempted yet" to the stub's
placeholder, name the mistake for the usual wrong answers, and never raise.  The checks draw their
test cases from fixed seeds, so the numbers asserted here are reproducible.
"""

import warnings

import numpy as np
import pytest

import lagolib
from lagolib import certify, simulate
from lagolib.exercises import NOT_ATTEMPTED, ch09, hint, passed, reset


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


# --------------------------------------------------------------------------- 9.1
def lam_ok(M, x):
    n = x.size // 2
    return (np.conj(x[n:]) * (M @ x)[n:]).real


def lam_imag(M, x):
    n = x.size // 2
    return (np.conj(x[n:]) * (M @ x)[n:]).imag


def lam_no_conj(M, x):
    n = x.size // 2
    return (x[n:] * (M @ x)[n:]).real


def lam_translations(M, x):
    n = x.size // 2
    return (np.conj(x[:n]) * (M @ x)[:n]).real


def lam_modulus(M, x):
    return np.abs((M @ x)[x.size // 2 :])


def lam_complex(M, x):
    n = x.size // 2
    return np.conj(x[n:]) * (M @ x)[n:]


def test_multipliers_reference_is_correct(capsys):
    ok, out = _run(capsys, ch09.check_multipliers, lam_ok)
    assert ok is True and passed("9.1")
    assert "Exercise 9.1 — correct" in out and "all 2 test points" in out


def test_multiplier_cases_are_what_the_statement_says():
    (p1, x1), (p2, x2) = ch09._multiplier_cases()
    assert p1.n == 16 and x1.shape == (32,) and np.iscomplexobj(x1)
    ev = np.linalg.eigvalsh(p1.graph.information[:, :2, :2])
    assert np.all(ev[:, 1] / ev[:, 0] > 10)  # anisotropic
    c1, c2 = certify.certify(p1, x1), certify.certify(p2, x2)
    assert c1.gradient < 1e-6 < 1.0 < c2.gradient  # stationary, then not
    lam = certify.multipliers(p1, x1)
    assert lam.sum() == pytest.approx(c1.f, rel=1e-7)


@pytest.mark.parametrize(
    "stub", [..., lambda M, x: ..., lambda M, x: None, lambda M, x: (..., ...)[0]]
)
def test_multipliers_stub_is_not_attempted(capsys, stub):
    ok, out = _run(capsys, ch09.check_multipliers, stub)
    assert ok is False and not passed("9.1")
    assert NOT_ATTEMPTED in out


@pytest.mark.parametrize(
    "wrong, message",
    [
        (lam_imag, "you took the imaginary part of conj(z_i) (M x)_{n+i}"),
        (lam_no_conj, "z_i is not conjugated"),
        (lam_translations, "you used the first n entries of x and M x"),
        (lam_modulus, "you took |(M x)_{n+i}|"),
        (lam_complex, "your multipliers are complex: conj(z_i) (M x)_{n+i} itself"),
        (lambda M, x: 2 * lam_ok(M, x), "your multipliers are twice the reference"),
        (lambda M, x: -lam_ok(M, x), "lambda has the opposite sign of the reference"),
        (lambda M, x: (M @ x).real, "lambda has shape (32,), expected (16,)"),
    ],
    ids=["imag", "no-conj", "translations", "modulus", "complex", "twice", "sign", "shape"],
)
def test_multipliers_wrong_answers_are_named(capsys, wrong, message):
    ok, out = _run(capsys, ch09.check_multipliers, wrong)
    assert ok is False and not passed("9.1")
    assert "Exercise 9.1 — not yet: on test" in out
    assert message in out


@pytest.mark.parametrize("imag", [0j, 1e-3j, 1000j], ids=["zero", "small", "large"])
def test_multipliers_complex_answers_are_not_yet(capsys, imag):
    # λ is real: a complex array is an answer of the wrong kind, even with imaginary part 0
    ok, out = _run(capsys, ch09.check_multipliers, lambda M, x: lam_ok(M, x) + imag)
    assert ok is False and "Exercise 9.1 — not yet: on test 1 of 2" in out
    assert "your multipliers are complex" in out
    assert "should return an array of real numbers of shape (n,)" in out


def test_multipliers_imaginary_part_fails_at_the_stationary_point_first(capsys):
    ok, out = _run(capsys, ch09.check_multipliers, lam_imag)
    assert "on test 1 of 2 (a stationary point)" in out


def test_multipliers_student_exception_is_feedback(capsys):
    def broken(M, x):
        return x[M.shape[0] + 5]

    ok, out = _run(capsys, ch09.check_multipliers, broken)
    assert ok is False and "multipliers raised IndexError" in out


def test_multipliers_in_place_modification_does_not_corrupt_the_reference(capsys):
    def in_place(M, x):
        out = lam_ok(M, x)
        x[:] = 0.0
        M.data[:] = 0.0
        return out

    ok, _ = _run(capsys, ch09.check_multipliers, in_place)
    assert ok is True
    ok, _ = _run(capsys, ch09.check_multipliers, lam_ok)
    assert ok is True


# --------------------------------------------------------------------------- 9.2
@pytest.fixture(scope="module")
def manhattan_points():
    """The chapter's two points on the 500-pose Manhattan world (sigma_theta = 0.2, seed 7)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lagolib.LagolibWarning)
        g = simulate.manhattan_world(
            n_poses=500, extent=20, rng=7, sigma_theta=0.2, sigma_xy=0.05
        ).graph
        p = certify.chordal_problem(g)
        gn = lagolib.optimize(g, lagolib.lago_solve(g, margin_warning=0).poses)
        P = certify.refine(p, gn.poses).poses
        Q = certify.solve(g).chordal_poses
    return p, P, Q


def _bound_P(p, P):
    c = certify.certify(p, P)
    return c, float(c.multipliers.sum()), c.lambda_min


def test_certificate_reading_reference_is_correct(capsys, manhattan_points):
    p, P, Q = manhattan_points
    c, s, lm = _bound_P(p, P)
    assert lm == pytest.approx(-7.72195, rel=1e-4) and c.lower_bound == pytest.approx(
        -3192.36, rel=1e-5
    )
    ok, out = _run(capsys, ch09.check_certificate_reading, "Q", s + p.n * lm, p, P, Q)
    assert ok is True and passed("9.2")
    assert "Exercise 9.2 — correct: P: certified False, λ_min -7.72195, lower bound -3192.36" in out
    assert "Q: certified True" in out


def test_certificate_reading_accepts_numbers_read_off_the_print(capsys, manhattan_points):
    p, P, Q = manhattan_points
    ok, _ = _run(
        capsys, ch09.check_certificate_reading, " q ", 668.613588 + 500 * -7.721953, p, P, Q
    )
    assert ok is True


def test_certificate_reading_states_the_gap_rule(capsys, manhattan_points):
    # the verdicts come with each point's gap and tolerance (certified: gap <= tolerance), and the
    # hint for a wrong pick states that rule — not "lambda_min >= -eta" — without naming the answer
    p, P, Q = manhattan_points
    cQ = certify.certify(p, Q)
    ok, out = _run(capsys, ch09.check_certificate_reading, "P", -3192.36, p, P, Q)
    assert ok is False
    assert "certified_point = 'P' is not what the two certificates say." in out
    assert "certified True" not in out and "-3192" not in out  # the verdicts: the last hint
    levels = _hints(capsys, "9.2").splitlines()
    first = levels[0]
    assert "gap" in first and "Σλ + n·min(λ_min, 0)" in first and "2nη₀" in first
    assert "Q" not in first.split(":", 1)[1] and "−7" not in first
    assert (
        "P: certified False, λ_min -7.72195, lower bound -3192.36, gap 669 (tolerance 0.000549)"
        in levels[2]
    )
    assert f"Q: certified True, λ_min > −η (not computed), lower bound {cQ.lower_bound:.6g}" in (
        levels[2]
    )


@pytest.mark.parametrize("answer", [(..., -3192.36), ("Q", ...), (None, None)])
def test_certificate_reading_stub_is_not_attempted(capsys, manhattan_points, answer):
    ok, out = _run(capsys, ch09.check_certificate_reading, *answer, *manhattan_points)
    assert ok is False and NOT_ATTEMPTED in out


@pytest.mark.parametrize(
    "choice, bound, message",
    [
        ("P", -3192.36, "certified_point = 'P' is not what the two certificates say."),
        ("both", -3192.36, "certified_point = 'both' is not what"),
        ("Q", 668.613587, "that is Σλ = f(P) itself"),
        ("Q", 668.613587 - 7.721953, "Σλ + λ_min — the eigenvalue counts once per pose"),
        ("Q", 668.613587 + 500 * 7.721953, "the sign of n·λ_min is flipped"),
        ("Q", 668.613587 - 1000 * 7.721953, "you multiplied by 2n; n = 500 poses"),
        ("Q", -3000.0, "lower_bound_P = -3000 is too large, by less than 10 %."),
        ("R", -3192.36, "certified_point should be one of ['P', 'Q', 'both', 'neither'], got 'R'"),
    ],
    ids=["P", "both", "f", "no-n", "sign", "2n", "misread", "unknown"],
)
def test_certificate_reading_wrong_answers_are_named(
    capsys, manhattan_points, choice, bound, message
):
    ok, out = _run(capsys, ch09.check_certificate_reading, choice, bound, *manhattan_points)
    assert ok is False and not passed("9.2")
    assert "Exercise 9.2 — not yet" in out and message in out
    assert "3192.36" not in out or bound == -3192.36  # P's bound is never told


def test_certificate_reading_odd_answer_does_not_raise(capsys, manhattan_points):
    ok, out = _run(capsys, ch09.check_certificate_reading, "Q", [1, 2], *manhattan_points)
    assert ok is False and "lower_bound_P should be one real number, got a list" in out
    ok, out = _run(capsys, ch09.check_certificate_reading, "Q", -3192.36, "not a problem", 1, 2)
    assert ok is False and "could not read your answer" in out


# --------------------------------------------------------------------------- 9.3
def test_noise_sweep_numbers_and_cache():
    sw = ch09.noise_sweep()
    assert sw["certified"].shape == (len(ch09.SWEEP_SIGMAS), len(ch09.SWEEP_SEEDS))
    assert sw["certified"][:3].all() and sw["certified"][3].tolist() == [False, True, True, True]
    assert sw["not_tight"].sum() == 1 and sw["not_tight"][3, 0]
    assert sw["escapes"][3, 0] == 1
    assert 1e-5 < sw["relative_gap"][3, 0] < 1e-3 and np.all(sw["relative_gap"] < 1e-3)
    assert "not tight" in sw["reason"][3, 0] and sw["reason"][0, 0] == "certified"
    names = [s["stage"] for s in sw["stages"][3, 0]]
    assert names[-3:] == ["rank-2 polish (tight)", "rank-2 certificate", "Gauss-Newton"]
    sw["certified"][:] = False  # a copy: the cache is not corrupted
    sw["stages"][3, 0].clear()
    again = ch09.noise_sweep()
    assert again["certified"][0].all() and len(again["stages"][3, 0]) == len(names)


def test_noise_sweep_reference_is_correct(capsys):
    ok, out = _run(capsys, ch09.check_noise_sweep, 0.5, 1)
    assert ok is True and passed("9.3")
    assert "σθ 0.4: 1.00, σθ 0.5: 0.75; 1 world(s) with a relaxation that is not tight" in out


@pytest.mark.parametrize("answer", [(..., ...), (0.5, ...), (..., 1)])
def test_noise_sweep_stub_is_not_attempted(capsys, answer):
    ok, out = _run(capsys, ch09.check_noise_sweep, *answer)
    assert ok is False and NOT_ATTEMPTED in out


@pytest.mark.parametrize(
    "answer, message",
    [
        ((0.4, 1), "first_uncertified = 0.4: at that σθ every world is certified."),
        ((0.45, 1), "first_uncertified = 0.45 is not one of the swept σθ (0.2, 0.3, 0.4, 0.5)."),
        ((0.5, 0), "not_tight = 0 is too small."),
        ((0.5, 2), "not_tight = 2 is too large."),
        ((0.5, "one"), "not_tight should be a whole number (how many worlds), got 'one'"),
        # review of issue 24: True for not_tight — the question is a count, and says so
        ((0.5, True), "got True (a bool): the question is how many worlds, not whether"),
    ],
    ids=["sigma-before", "sigma-off-grid", "count-low", "count-high", "count-word", "count-bool"],
)
def test_noise_sweep_wrong_answers_are_named(capsys, answer, message):
    ok, out = _run(capsys, ch09.check_noise_sweep, *answer)
    assert ok is False and not passed("9.3")
    assert "Exercise 9.3 — not yet" in out and message in out
    assert "0.75" not in out  # the certified fractions are the last hint


def test_noise_sweep_odd_answer_does_not_raise(capsys):
    ok, out = _run(capsys, ch09.check_noise_sweep, [0.5], 1)
    assert ok is False and "first_uncertified should be one real number, got a list" in out
