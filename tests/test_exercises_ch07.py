"""The checks of chapter 7's exercises (lagolib.exercises.ch07): right, unfinished and wrong answers.

Every check must say "correct" to the reference answer, "not attempted yet" to the stub's
placeholder, name the slip in a realistic wrong answer, and never raise on a student's bug.
"""

import numpy as np
import pytest

from lagolib import closed_form as cf
from lagolib.exercises import ch07, hint, passed, reset


@pytest.fixture(autouse=True)
def _fresh():
    reset()
    yield
    reset()


def run(capsys, check, *args):
    """``(result, printed text)`` of one check."""
    ok = check(*args)
    return ok, capsys.readouterr().out


def hints(capsys, exercise):
    """Every hint level of ``exercise``'s last "not yet", as ``hint`` prints them."""
    for _ in range(4):
        hint(exercise)
    return capsys.readouterr().out


# ------------------------------------------------------------------------- 7.1 sincos error
def sincos_error(p_i, p_j, delta_ij):
    x_i, y_i, c_i, s_i = p_i
    x_j, y_j, c_j, s_j = p_j
    dx, dy = x_j - x_i, y_j - y_i
    f = np.array(
        [c_i * dx + s_i * dy, -s_i * dx + c_i * dy, c_j * c_i + s_j * s_i, s_j * c_i - c_j * s_i]
    )
    return f - np.asarray(delta_ij)


def rotated_by_R_i(p_i, p_j, delta_ij):  # R(θ_i) instead of its transpose
    x_i, y_i, c_i, s_i = p_i
    x_j, y_j, c_j, s_j = p_j
    dx, dy = x_j - x_i, y_j - y_i
    f = np.array(
        [c_i * dx - s_i * dy, s_i * dx + c_i * dy, c_j * c_i + s_j * s_i, s_j * c_i - c_j * s_i]
    )
    return f - delta_ij


def world_frame(p_i, p_j, delta_ij):
    e = sincos_error(p_i, p_j, delta_ij)
    e[:2] = p_j[:2] - p_i[:2] - delta_ij[:2]
    return e


def angle_backwards(p_i, p_j, delta_ij):  # sin(θ_i − θ_j)
    e = sincos_error(p_i, p_j, delta_ij)
    c_i, s_i, c_j, s_j = p_i[2], p_i[3], p_j[2], p_j[3]
    e[3] = c_j * s_i - s_j * c_i - delta_ij[3]
    return e


def test_sincos_error_reference_is_correct(capsys):
    ok, out = run(capsys, ch07.check_sincos_error, sincos_error)
    assert ok is True and passed("7.1")
    assert "Exercise 7.1 — correct" in out and "16 edges" in out


def test_sincos_error_agrees_with_lagolib_graph_residuals():
    rng = np.random.default_rng(0)
    q = rng.uniform([-3, -3, -np.pi], [3, 3, np.pi], size=(3, 3))
    z = np.array([1.0, -0.5, 2.5])
    p = cf.sincos_poses(q)
    got = sincos_error(p[0], p[1], cf.sincos_poses(z))
    expected = ch07._reference_sincos_errors(q[:1], q[1:2], z[None])[0]
    np.testing.assert_allclose(got, expected, atol=1e-14)


@pytest.mark.parametrize("stub", [..., lambda p_i, p_j, delta_ij: ..., None])
def test_sincos_error_stub_is_not_attempted(capsys, stub):
    ok, out = run(capsys, ch07.check_sincos_error, stub)
    assert ok is False and "not attempted yet" in out


@pytest.mark.parametrize(
    "wrong, message",
    [
        (rotated_by_R_i, "R(θ_i) instead of R(θ_i)ᵀ"),
        (world_frame, "in the world frame"),
        (angle_backwards, "θ_i − θ_j"),
        (lambda p_i, p_j, d: sincos_error(p_i, p_j, d) + d, "you returned f_ij itself"),
        (lambda p_i, p_j, d: -sincos_error(p_i, p_j, d), "you returned δ̂_ij − f_ij"),
        (lambda p_i, p_j, d: sincos_error(p_i, p_j, d)[[0, 1, 3, 2]], "last two rows are swapped"),
        (lambda p_i, p_j, d: sincos_error(p_i, p_j, d)[:3], "has shape (3,), expected (4,)"),
        (
            lambda p_i, p_j, d: sincos_error(p_i, p_j, d) + [0, 0, 0, 0.1],
            "angular rows (3 and 4) are not",
        ),
    ],
)
def test_sincos_error_wrong_answers_are_diagnosed(capsys, wrong, message):
    ok, out = run(capsys, ch07.check_sincos_error, wrong)
    assert ok is False and not passed("7.1")
    assert "Exercise 7.1 — not yet" in out and message in out


def test_sincos_error_that_raises_is_feedback(capsys):
    def broken(p_i, p_j, delta_ij):
        return p_i @ np.ones(3)

    ok, out = run(capsys, ch07.check_sincos_error, broken)
    assert ok is False and "sincos_error raised ValueError" in out and "edge 0" in out


# ---------------------------------------------------------------------- 7.2 one Newton step
def newton_step(A, b, t, rho):
    n = rho.size
    c, s = t[0::2], t[1::2]
    R = np.diag(np.column_stack([rho, -rho]).ravel())
    F = np.concatenate([A @ t + b - R @ t, 0.5 * (c**2 + s**2 - 1)])
    J = np.zeros((3 * n, 3 * n))
    J[: 2 * n, : 2 * n] = A - R
    k = np.arange(n)
    J[2 * k, 2 * n + k] = -c
    J[2 * k + 1, 2 * n + k] = s
    J[2 * n + k, 2 * k] = c
    J[2 * n + k, 2 * k + 1] = s
    step = np.linalg.solve(J, -F)
    return t + step[: 2 * n], rho + step[2 * n :]


def _variant(
    *, b_sign=1.0, uphill=False, increment=False, rho_fixed=False, lstsq=False, no_R=False
):
    def step(A, b, t, rho):
        n = rho.size
        c, s = t[0::2], t[1::2]
        R = np.diag(np.column_stack([rho, -rho]).ravel())
        F = np.concatenate([A @ t + b_sign * b - R @ t, 0.5 * (c**2 + s**2 - 1)])
        if rho_fixed:
            return t + np.linalg.solve(A - R, -F[: 2 * n]), rho
        J = np.zeros((3 * n, 3 * n))
        J[: 2 * n, : 2 * n] = A if no_R else A - R
        k = np.arange(n)
        J[2 * k, 2 * n + k] = -c
        J[2 * k + 1, 2 * n + k] = s
        J[2 * n + k, 2 * k] = c
        J[2 * n + k, 2 * k + 1] = s
        if lstsq:  # only the 2n rows of eq. (44): minimum-norm step
            d = np.linalg.lstsq(J[: 2 * n], -F[: 2 * n], rcond=None)[0]
        else:
            d = np.linalg.solve(J, F if uphill else -F)
        if increment:
            return d[: 2 * n], d[2 * n :]
        return t + d[: 2 * n], rho + d[2 * n :]

    return step


def renormalized(A, b, t, rho):
    """Newton's step, then every (c_i, s_i) scaled back onto the unit circle."""
    t1, rho1 = newton_step(A, b, t, rho)
    cs = t1.reshape(-1, 2)
    return (cs / np.linalg.norm(cs, axis=1, keepdims=True)).ravel(), rho1


def test_newton_reference_is_lagolibs_step():
    """Iterating newton_reference from solve_orthogonality's start gives its residuals and end."""
    A, b, _, _, t, rho, solution = ch07._newton_problem()
    norms = [np.abs(ch07.orthogonality_residual(A, b, t, rho)).max()]
    for _ in range(len(solution.residuals) - 1):
        t, rho = ch07.newton_reference(A, b, t, rho)
        norms.append(np.abs(ch07.orthogonality_residual(A, b, t, rho)).max())
    np.testing.assert_allclose(norms[:-1], solution.residuals[:-1], rtol=1e-6)
    assert norms[-1] < 1e-12 and solution.residuals[-1] < 1e-12
    np.testing.assert_allclose(t, solution.t, atol=1e-12)
    np.testing.assert_allclose(rho, solution.rho, atol=1e-10)
    assert len(solution.residuals) == 4  # three quadratic steps from the odometry


def test_newton_step_reference_is_correct(capsys):
    ok, out = run(capsys, ch07.check_newton_step, newton_step)
    assert ok is True and passed("7.2")
    assert "Exercise 7.2 — correct" in out and "n = 8" in out and "in 3 steps" in out


def test_newton_step_fixed_point_at_the_solution():
    A, b, _, _, _, _, solution = ch07._newton_problem()
    t, rho = newton_step(A, b, solution.t, solution.rho)
    np.testing.assert_allclose(t, solution.t, atol=1e-12)
    np.testing.assert_allclose(rho, solution.rho, atol=1e-10)


@pytest.mark.parametrize("stub", [..., lambda A, b, t, rho: ..., lambda A, b, t, rho: (..., ...)])
def test_newton_step_stub_is_not_attempted(capsys, stub):
    ok, out = run(capsys, ch07.check_newton_step, stub)
    assert ok is False and "not attempted yet" in out


@pytest.mark.parametrize(
    "wrong, message",
    [
        (_variant(b_sign=-1.0), "the sign printed in eq. (44)"),
        (_variant(uphill=True), "goes the wrong way"),
        (_variant(increment=True), "returned the increment"),
        (_variant(rho_fixed=True), "ρ did not change"),
        (_variant(lstsq=True), "ignores the constraint rows"),
        (_variant(no_R=True), "your ∂F/∂t block is A alone"),
        (lambda A, b, t, rho: newton_step(A, b, t, rho)[0], "should return a pair"),
        (renormalized, "renormalized"),
        (lambda A, b, t, rho: (newton_step(A, b, t, rho)[0][:-1], rho), "t_new has shape (15,)"),
    ],
)
def test_newton_step_wrong_answers_are_diagnosed(capsys, wrong, message):
    ok, out = run(capsys, ch07.check_newton_step, wrong)
    assert ok is False and not passed("7.2")
    assert "Exercise 7.2 — not yet" in out and message in out


@pytest.mark.parametrize("f_scale, j_scale", [(2.0, 1.0), (1.0, 2.0)])
def test_newton_step_mismatched_constraint_rows_are_diagnosed(capsys, f_scale, j_scale):
    def mismatched(A, b, t, rho):
        n = rho.size
        c, s = t[0::2], t[1::2]
        R = np.diag(np.column_stack([rho, -rho]).ravel())
        F = np.concatenate([A @ t + b - R @ t, f_scale * 0.5 * (c**2 + s**2 - 1)])
        J = np.zeros((3 * n, 3 * n))
        J[: 2 * n, : 2 * n] = A - R
        k = np.arange(n)
        J[2 * k, 2 * n + k] = -c
        J[2 * k + 1, 2 * n + k] = s
        J[2 * n + k, 2 * k] = j_scale * c
        J[2 * n + k, 2 * k + 1] = j_scale * s
        d = np.linalg.solve(J, -F)
        return t + d[: 2 * n], rho + d[2 * n :]

    ok, out = run(capsys, ch07.check_newton_step, mismatched)
    assert ok is False and "constraint rows and their Jacobian do not match" in out


def test_newton_step_sign_of_R_is_diagnosed(capsys):
    def same_sign_R(A, b, t, rho):
        n = rho.size
        c, s = t[0::2], t[1::2]
        R = np.diag(np.repeat(rho, 2))
        F = np.concatenate([A @ t + b - R @ t, 0.5 * (c**2 + s**2 - 1)])
        J = np.zeros((3 * n, 3 * n))
        J[: 2 * n, : 2 * n] = A - R
        k = np.arange(n)
        J[2 * k, 2 * n + k] = -c
        J[2 * k + 1, 2 * n + k] = -s
        J[2 * n + k, 2 * k] = c
        J[2 * n + k, 2 * k + 1] = s
        d = np.linalg.solve(J, -F)
        return t + d[: 2 * n], rho + d[2 * n :]

    ok, out = run(capsys, ch07.check_newton_step, same_sign_R)
    assert ok is False and "eq. (45) alternates the sign" in out


def test_newton_step_that_raises_is_feedback(capsys):
    def broken(A, b, t, rho):
        return np.linalg.solve(A[:, :-1], b)

    ok, out = run(capsys, ch07.check_newton_step, broken)
    assert ok is False and "newton_step raised LinAlgError" in out


# ---------------------------------------------------------------- 7.3 predict the χ² gap
def test_closed_form_gap_reference_is_correct(capsys):
    ok, out = run(capsys, ch07.check_closed_form_gap, "above 2")
    assert ok is True and passed("7.3")
    assert "closed form / optimum = 3.075 (above 2)" in out
    assert "closed form 369.5990" in out and "Gauss–Newton 120.1995" in out


def test_closed_form_gap_is_case_insensitive(capsys):
    ok, _ = run(capsys, ch07.check_closed_form_gap, " Above 2")
    assert ok is True


@pytest.mark.parametrize("stub", [..., None])
def test_closed_form_gap_stub_is_not_attempted(capsys, stub):
    ok, out = run(capsys, ch07.check_closed_form_gap, stub)
    assert ok is False and "not attempted yet" in out


@pytest.mark.parametrize(
    "wrong, message",
    [
        ("below 1", "nothing is below it"),
        ("1 to 1.05", "prediction = '1 to 1.05' is not the band the ratio falls in."),
        ("1.05 to 2", "prediction = '1.05 to 2' is not the band the ratio falls in."),
        ("maybe", "prediction should be one of"),
        (3.0, "prediction should be one of"),
        (np.array([1.0, 2.0]), "(a string)"),
    ],
)
def test_closed_form_gap_wrong_answers_are_diagnosed(capsys, wrong, message):
    ok, out = run(capsys, ch07.check_closed_form_gap, wrong)
    assert ok is False and not passed("7.3")
    assert "Exercise 7.3 — not yet" in out and message in out
    assert "3.075" not in out and "369" not in out  # the computed χ² are the last hint
    levels = hints(capsys, "7.3")
    if isinstance(wrong, str) and wrong == "1 to 1.05":
        assert "hint 2 of 3: '1 to 1.05' is what happens when Ω is a multiple of I" in levels
    if isinstance(wrong, str) and wrong == "1.05 to 2":
        assert "hint 2 of 3: The gap is larger than that" in levels
        assert "closed form / optimum = 3.075 (above 2)" in levels


def test_closed_form_gap_bands():
    assert [ch07._band(r) for r in (0.5, 1.0, 1.05, 1.5, 2.0, 3.0)] == [
        "below 1", "1 to 1.05", "1 to 1.05", "1.05 to 2", "1.05 to 2", "above 2"
    ]  # fmt: skip


# --------------------------------------------------------------- 7.4 explore the noise gap
def test_noise_gap_reference_is_correct(capsys):
    ok, out = run(capsys, ch07.check_noise_gap, 0.05, "ratio")
    assert ok is True and passed("7.4")
    assert "closest at σ_θ = σ_xy = 0.05" in out and "2.292 times the optimum" in out
    assert "keeps the ratio within 1e-05 of 1 over the whole sweep" in out


def test_noise_gap_sweep_values():
    gaps = [ch07._gap(ch07.SIGMA_XY, s) for s in ch07.SIGMA_SWEEP]
    np.testing.assert_allclose(gaps, [2.292050, 1.204422, 1.0, 1.188626, 2.133823], atol=2e-6)
    assert abs(ch07._gap(0.2, 0.2) - 1) < 1e-4


@pytest.mark.parametrize("stub", [(..., ...), (0.05, ...), (..., "ratio")])
def test_noise_gap_stub_is_not_attempted(capsys, stub):
    ok, out = run(capsys, ch07.check_noise_gap, *stub)
    assert ok is False and "not attempted yet" in out


@pytest.mark.parametrize(
    "wrong, message",
    [
        ((0.2, "ratio"), "at σ_θ = 0.2 the closed form's χ² is 2.134 times"),
        ((0.0125, "ratio"), "2.292 times the optimum's, not the smallest ratio in the sweep."),
        ((0.05, "level"), "what_decides = 'level' is not what the two sweeps show."),
        ((0.07, "ratio"), "should be one of the swept σ_θ"),
        ((0.05, "noise"), "what_decides should be one of"),
        ((0.05, np.array([1, 2])), "(a string)"),
        (("abc", "ratio"), "closest_sigma_theta should be one real number, got 'abc'"),
    ],
)
def test_noise_gap_wrong_answers_are_diagnosed(capsys, wrong, message):
    ok, out = run(capsys, ch07.check_noise_gap, *wrong)
    assert ok is False and not passed("7.4")
    assert "Exercise 7.4 — not yet" in out and message in out
    assert "1.0000" not in out  # the smallest ratio (at the answer) is the last hint
    if isinstance(wrong[1], str) and wrong[1] == "level":
        levels = hints(capsys, "7.4")
        assert "with σ_θ = σ_xy the ratio stays 1.000000 at σ = 0.0125" in levels
