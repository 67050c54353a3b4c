"""The checks of chapter 5's exercises (lagolib.exercises.ch05): right, unattempted and wrong answers."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from lagolib.exercises import ch05, hint, passed, reset


@pytest.fixture(autouse=True)
def _fresh_results():
    reset()
    yield
    reset()


def run(capsys, check, *answer):
    ok = check(*answer)
    return ok, capsys.readouterr().out


def hints(capsys, exercise):
    """Every hint level of ``exercise``'s last "not yet", as ``hint`` prints them."""
    for _ in range(5):
        hint(exercise)
    return capsys.readouterr().out


# --------------------------------------------------------------------------------- 5.1 phase 1
def phase1(A, delta_bar, omega):
    info = (A @ sp.diags(omega) @ A.T).tocsc()
    return spsolve(info, A @ (omega * delta_bar))


def test_phase1_reference(capsys):
    ok, out = run(capsys, ch05.check_phase1, phase1)
    assert ok and passed("5.1")
    assert out.startswith("Exercise 5.1 — correct")
    assert "both graphs (a 24-pose loop with 35 edges, a 60-pose Manhattan world" in out


def test_phase1_stub(capsys):
    def stub(A, delta_bar, omega):
        return ...

    ok, out = run(capsys, ch05.check_phase1, stub)
    assert not ok and "not attempted yet" in out
    ok, out = run(capsys, ch05.check_phase1, ...)
    assert not ok and "not attempted yet" in out


def test_phase1_unweighted(capsys):
    def ols(A, delta_bar, omega):
        return spsolve((A @ A.T).tocsc(), A @ delta_bar)

    ok, out = run(capsys, ch05.check_phase1, ols)
    assert not ok and "ordinary least squares" in out and "not yet" in out


def test_phase1_variances_as_weights(capsys):
    def inverted(A, delta_bar, omega):
        return phase1(A, delta_bar, 1.0 / omega)

    ok, out = run(capsys, ch05.check_phase1, inverted)
    assert not ok and "1/omega" in out


def test_phase1_anchor_included(capsys):
    def with_anchor(A, delta_bar, omega):
        return np.concatenate([[0.0], phase1(A, delta_bar, omega)])

    ok, out = run(capsys, ch05.check_phase1, with_anchor)
    assert not ok and "one per vertex" in out


def test_phase1_column(capsys):
    def column(A, delta_bar, omega):
        return phase1(A, delta_bar, omega)[:, None]

    ok, out = run(capsys, ch05.check_phase1, column)
    assert not ok and "a column" in out


def test_phase1_wrapped(capsys):
    def wrapped(A, delta_bar, omega):
        theta = phase1(A, delta_bar, omega)
        return (theta + np.pi) % (2 * np.pi) - np.pi

    ok, out = run(capsys, ch05.check_phase1, wrapped)
    assert not ok and "modulo 2π" in out and "wrapped?" in out


def test_phase1_raises(capsys):
    def transposed(A, delta_bar, omega):
        return spsolve((A.T @ sp.diags(omega) @ A).tocsc(), A @ (omega * delta_bar))

    ok, out = run(capsys, ch05.check_phase1, transposed)
    assert not ok and "raised" in out and 'Stuck? hint("5.1")' in out
    assert "A is a scipy.sparse matrix of shape (n, m)" in hints(capsys, "5.1")


# a right answer that makes the information matrix dense: exercise 5.1 asks for nothing dense
def _dense_lstsq(A, delta_bar, omega):
    Ad = A.toarray()
    return np.linalg.lstsq(Ad @ np.diag(omega) @ Ad.T, Ad @ (omega * delta_bar), rcond=None)[0]


def _dense_solve(A, delta_bar, omega):
    info = (A @ sp.diags(omega) @ A.T).todense()
    return np.asarray(np.linalg.solve(info, A @ (omega * delta_bar))).ravel()


def _dense_but_caught(A, delta_bar, omega):
    try:
        (A @ sp.diags(omega) @ A.T).toarray()
    except Exception:  # noqa: BLE001 - the student swallows the refusal: still refused
        pass
    return phase1(A, delta_bar, omega)


@pytest.mark.parametrize(
    "dense, method",
    [(_dense_lstsq, ".toarray() on a 23×35"), (_dense_solve, ".todense() on a 23×23"),
     (_dense_but_caught, ".toarray() on a 23×23")],
    ids=["lstsq", "todense-solve", "caught"],
)
def test_phase1_refuses_a_dense_solution(capsys, dense, method):
    """A right θ̂ computed densely is "not yet" (it was "correct" before issue 24)."""
    ok, out = run(capsys, ch05.check_phase1, dense)
    assert not ok and not passed("5.1")
    assert f"your phase1 made a sparse matrix dense ({method} matrix)" in out
    assert "exercise 5.1 keeps every matrix sparse" in out


def test_phase1_sparse_solutions_of_every_form_pass(capsys):
    from scipy.sparse.linalg import factorized

    def sparse_rhs(A, delta_bar, omega):  # spsolve with a sparse right-hand side: a vector
        x = spsolve((A.multiply(omega) @ A.T).tocsc(), sp.csc_matrix(A @ (omega * delta_bar)).T)
        return x.toarray().ravel() if sp.issparse(x) else x

    def factor(A, delta_bar, omega):
        return factorized((A @ sp.diags_array(omega) @ A.T).tocsc())(A @ (omega * delta_bar))

    for fn in (sparse_rhs, factor):
        ok, out = run(capsys, ch05.check_phase1, fn)
        assert ok, out


def test_nothing_dense_restores_scipy():
    m = sp.csr_matrix(np.eye(3))
    with pytest.raises(ch05.DenseMatrixRefused):
        with ch05.nothing_dense([]) as refused:
            try:
                m.toarray()
            finally:
                assert refused == [("toarray", (3, 3))]
    assert m.toarray().shape == (3, 3) and sp.csc_array(np.eye(2)).todense().shape == (2, 2)
    with ch05.nothing_dense([]) as refused:
        assert sp.csr_matrix(np.ones((1, 4))).toarray().shape == (1, 4)  # a row may be dense
    assert refused == []


# ------------------------------------------------------------------------ 5.2 one chord
def regularize_chord(delta, edges, signs):
    s = float(np.sum(signs * delta[edges]))
    return s, -int(np.round(s / (2 * np.pi)))


def test_chord_reference(capsys):
    ok, out = run(capsys, ch05.check_regularize_chord, regularize_chord)
    assert ok and passed("5.2")
    assert "correct" in out and "all 28 chords" in out and "k from -1 to 2" in out


def test_chord_stub(capsys):
    def stub(delta, edges, signs):
        return ...

    ok, out = run(capsys, ch05.check_regularize_chord, stub)
    assert not ok and "not attempted yet" in out

    def half(delta, edges, signs):
        return 0.0, ...

    ok, out = run(capsys, ch05.check_regularize_chord, half)
    assert not ok and "not attempted yet" in out


def test_chord_sign_of_k(capsys):
    def flipped(delta, edges, signs):
        s, k = regularize_chord(delta, edges, signs)
        return s, -k

    ok, out = run(capsys, ch05.check_regularize_chord, flipped)
    assert not ok and "the opposite sign" in out and "C ν = −C δ" in out
    assert "round(C δ / 2π)" not in out and "np.round" not in out  # the formula is a hint


def test_chord_floor(capsys):
    def floored(delta, edges, signs):
        s = float(np.sum(signs * delta[edges]))
        return s, -int(np.floor(s / (2 * np.pi)))

    ok, out = run(capsys, ch05.check_regularize_chord, floored)
    assert not ok and "np.floor where eq. (23) rounds" in out


def test_chord_truncation(capsys):
    def truncated(delta, edges, signs):
        s = float(np.sum(signs * delta[edges]))
        return s, -int(s / (2 * np.pi))

    ok, out = run(capsys, ch05.check_regularize_chord, truncated)
    assert not ok and "truncation" not in out and "cuts towards zero" in out


def test_chord_tree_path_forgotten(capsys):
    def chord_only(delta, edges, signs):
        s = float(delta[edges[0]])
        return s, -int(np.round(s / (2 * np.pi)))

    ok, out = run(capsys, ch05.check_regularize_chord, chord_only)
    assert not ok and "the tree path is missing" in out


def test_chord_left_out(capsys):
    def tree_path_only(delta, edges, signs):
        s = float(np.sum(signs[1:] * delta[edges[1:]]))
        return s, -int(np.round(s / (2 * np.pi)))

    ok, out = run(capsys, ch05.check_regularize_chord, tree_path_only)
    assert not ok and "the tree path alone: the chord itself is missing" in out


def test_chord_pair_swapped(capsys):
    def swapped(delta, edges, signs):
        s, k = regularize_chord(delta, edges, signs)
        return k, s

    ok, out = run(capsys, ch05.check_regularize_chord, swapped)
    assert not ok and "k first, then the sum" in out and "(cycle_sum, k)" in out


def test_chord_signs_ignored(capsys):
    def unsigned(delta, edges, signs):
        s = float(np.sum(delta[edges]))
        return s, -int(np.round(s / (2 * np.pi)))

    ok, out = run(capsys, ch05.check_regularize_chord, unsigned)
    assert not ok and "without their signs" in out


def test_chord_sum_wrapped(capsys):
    def wrapped(delta, edges, signs):
        s = float(np.sum(signs * delta[edges]))
        s = (s + np.pi) % (2 * np.pi) - np.pi
        return s, 0

    ok, out = run(capsys, ch05.check_regularize_chord, wrapped)
    assert not ok and "wrapped into (−π, π]" in out


def test_chord_not_a_pair_and_raises(capsys):
    def only_k(delta, edges, signs):
        return regularize_chord(delta, edges, signs)[1]

    ok, out = run(capsys, ch05.check_regularize_chord, only_k)
    assert not ok and "should return two numbers, (cycle_sum, k); it returned" in out

    def broken(delta, edges, signs):
        return delta[edges + 10_000], 0

    ok, out = run(capsys, ch05.check_regularize_chord, broken)
    assert not ok and "raised IndexError" in out


def test_chord_fractional_k(capsys):
    def turns(delta, edges, signs):
        s = float(np.sum(signs * delta[edges]))
        return s, -s / (2 * np.pi)

    ok, out = run(capsys, ch05.check_regularize_chord, turns)
    assert not ok and "whole number of turns" in out


# -------------------------------------------------------------------- 5.3 predict the count
def test_n_regularized_reference(capsys):
    ok, out = run(capsys, ch05.check_n_regularized, 5)
    assert ok and passed("5.3")
    assert "5 of the 9 chords" in out and "4->46: k=+2" in out and "40->59: k=+1" in out


def test_n_regularized_stub(capsys):
    ok, out = run(capsys, ch05.check_n_regularized, ...)
    assert not ok and "not attempted yet" in out


def test_n_regularized_all_closures(capsys):
    ok, out = run(capsys, ch05.check_n_regularized, 9)
    assert not ok and "your prediction = 9 is too large" in out
    assert "not every loop closure" in out and "k=" not in out
    assert "hint 3 of 3: lagolib's regularize, chord by chord: 2->22: k=+1" in hints(capsys, "5.3")


def test_n_regularized_whole_laps_only(capsys):
    ok, out = run(capsys, ch05.check_n_regularized, 4)
    assert not ok and "whole lap (360°)" in out and "half a turn (180°)" not in out
    assert "more than half a turn (180°) either way" in hints(capsys, "5.3")


def test_n_regularized_start_line(capsys):
    ok, out = run(capsys, ch05.check_n_regularized, 6)
    assert not ok and "start line" in out


def test_n_regularized_not_a_number(capsys):
    ok, out = run(capsys, ch05.check_n_regularized, "five")
    assert not ok and "whole number" in out


# ------------------------------------------------------------------ 5.4 explore the noise
def test_noise_tolerance_reference(capsys):
    ok, out = run(capsys, ch05.check_noise_tolerance, 0.16, 0.48)
    assert ok and passed("5.4")
    assert "σθ = 0.16 rad (warning from 0.14)" in out and "3.0 times the noise" in out


def test_noise_tolerance_stub(capsys):
    ok, out = run(capsys, ch05.check_noise_tolerance, ..., ...)
    assert not ok and "not attempted yet" in out
    ok, out = run(capsys, ch05.check_noise_tolerance, 0.16, ...)
    assert not ok and "not attempted yet" in out


def test_noise_tolerance_warning_level(capsys):
    ok, out = run(capsys, ch05.check_noise_tolerance, 0.14, 0.48)
    assert not ok and "starts to warn" in out


def test_noise_tolerance_swapped(capsys):
    ok, out = run(capsys, ch05.check_noise_tolerance, 0.48, 0.16)
    assert not ok and "your two thresholds are swapped" in out
    # one value that is the other tree's threshold is not called a swap: that would tell it
    ok, out = run(capsys, ch05.check_noise_tolerance, 0.48, 0.3)
    assert not ok and "swapped" not in out and "already picks a wrong k at a smaller σθ" in out


def test_noise_tolerance_too_low_and_off_grid(capsys):
    ok, out = run(capsys, ch05.check_noise_tolerance, 0.16, 0.3)
    assert not ok and "still right" in out
    ok, out = run(capsys, ch05.check_noise_tolerance, 0.155, 0.48)
    assert not ok and "not one of the slider's values" in out
    ok, out = run(capsys, ch05.check_noise_tolerance, 0.2, 0.48)
    assert not ok and "already picks a wrong k" in out


def test_wrong_k_matches_explore_world():
    """The helper the chapter's explore cell uses: no wrong k without noise, some at σθ = 0.6."""
    from lagolib.lago import regularize

    sim = ch05.explore_world(0.6)
    assert ch05.wrong_k(sim, regularize(sim.graph, "odometric", margin_warning=0)).sum() > 10
    sim = ch05.explore_world(0.02)
    assert not ch05.wrong_k(sim, regularize(sim.graph, margin_warning=0)).any()


def test_explore_world_is_shared_and_read_only():
    import lagolib

    a, b = ch05.explore_world(0.3), ch05.explore_world(np.float64(0.3))
    assert a is b and not a.truth.flags.writeable and a.graph.n == 160
    with pytest.raises(lagolib.OptionError, match="explore_world: sigma_theta"):
        ch05.explore_world(-0.1)
    with pytest.raises(TypeError, match="sigma_theta must be a real number"):
        ch05.explore_world("0.3")
