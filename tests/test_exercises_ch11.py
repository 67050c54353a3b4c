"""Chapter 11's exercise checks (lagolib.exercises.ch11): right, unfinished, wrong and crashing
answers, and the shared computations the chapter relies on.

Every check must say "correct" to the reference answer, "not attempted yet" to the stub's
placeholder, name the mistake for the usual wrong answers, and never raise.  The world, the
candidates and the sweep come from fixed seeds, so the numbers asserted here are reproducible.
"""

import math

import numpy as np
import pytest

import lagolib
from lagolib import kernels, metrics, robust, se2, simulate
from lagolib.exercises import NOT_ATTEMPTED, ch11, hint, passed, reset


@pytest.fixture(autouse=True)
def _fresh_results():
    reset()
    yield
    reset()


def _run(capsys, check, *answer):
    ok = check(*answer)
    return ok, capsys.readouterr().out


def dcs_ok(r, phi):
    """The chapter's solution of exercise 11.1."""
    return np.minimum(1.0, 2.0 * phi / (phi + np.asarray(r, dtype=float) ** 2)) ** 2


# --------------------------------------------------------------------------- the world
def test_world_is_the_documented_sparse_manhattan_walk():
    sim = ch11.world()
    g = sim.graph
    assert (g.n, g.m, int(g.loop_closure.sum())) == (300, 354, 55)
    again = simulate.manhattan_world(**ch11.WORLD)
    assert np.array_equal(again.graph.measurements, g.measurements)
    # the outlier-free least-squares optimum is close to the truth; the odometry is not
    x = lagolib.optimize(g, g.odometry_guess()).poses
    ate = metrics.absolute_trajectory_error(x, sim.truth).translation_rmse
    ate_odo = metrics.absolute_trajectory_error(g.odometry_guess(), sim.truth).translation_rmse
    assert 0.05 < ate < 0.15 and ate_odo > 5 * ate


# --------------------------------------------------------------------------- 11.1
def test_dcs_weight_reference_is_correct(capsys):
    ok, out = _run(capsys, ch11.check_dcs_weight, dcs_ok)
    assert ok is True and passed("11.1")
    assert "Exercise 11.1 — correct: your weights equal kernels.DCS's at 201 residuals" in out


def test_dcs_weight_closed_form_at_known_points():
    # s = min(1, 2Φ/(Φ + r²)): r² = Φ gives s = 1; r² = 3Φ gives s = 1/2, w = 1/4
    phi = 4.0
    r = np.array([0.0, 2.0, 2.0 * math.sqrt(3.0), 1e3])
    w = kernels.DCS(math.sqrt(phi)).weight(r)
    assert np.allclose(w[:3], [1.0, 1.0, 0.25], rtol=0, atol=1e-15)
    assert w[3] == pytest.approx((2 * phi / (phi + 1e6)) ** 2, rel=1e-12)
    assert np.allclose(dcs_ok(r, phi), w, rtol=1e-15)


@pytest.mark.parametrize("stub", [..., lambda r, phi: ..., lambda r, phi: None])
def test_dcs_weight_stub_is_not_attempted(capsys, stub):
    ok, out = _run(capsys, ch11.check_dcs_weight, stub)
    assert ok is False and not passed("11.1")
    assert NOT_ATTEMPTED in out


@pytest.mark.parametrize(
    "wrong, message",
    [
        (lambda r, phi: np.minimum(1.0, 2 * phi / (phi + r**2)), "your weight is the switch s itself"),
        (lambda r, phi: (2 * phi / (phi + r**2)) ** 2, "your weight exceeds 1 for small residuals"),
        (lambda r, phi: np.minimum(1.0, 2 * phi / (phi + r)) ** 2, "compared with r², not r"),
        (
            lambda r, phi: np.minimum(1.0, 2 * np.sqrt(phi) / (np.sqrt(phi) + r**2)) ** 2,
            "your weight uses √Φ",
        ),
        (lambda r, phi: 1.0 / (1.0 + r**2 / phi), "the weights differs from the reference"),
        (lambda r, phi: dcs_ok(r, phi)[:-1], "the weights has shape (200,), expected (201,)"),
        (lambda r, phi: 1 / 0, "dcs_weight raised ZeroDivisionError"),
        (lambda r, phi: dcs_ok(r, phi) + 0j, "should return an array of real numbers"),
    ],
    ids=["switch", "no-min", "r", "sqrt-phi", "cauchy", "shape", "raises", "complex"],
)
def test_dcs_weight_wrong_answers_are_named(capsys, wrong, message):
    ok, out = _run(capsys, ch11.check_dcs_weight, wrong)
    assert ok is False and not passed("11.1")
    assert out.startswith("Exercise 11.1 — not yet: ")
    assert message in out, out


def test_dcs_weight_hints_reveal_the_formula_last(capsys):
    ch11.check_dcs_weight(lambda r, phi: 1.0 / (1.0 + r**2 / phi))
    capsys.readouterr()
    hint("11.1")
    first = capsys.readouterr().out
    hint("11.1")
    second = capsys.readouterr().out
    assert "hint 1 of 2" in first and "np.minimum" not in first
    assert "hint 2 of 2" in second and "np.minimum(1.0, 2 * phi / (phi + r**2)) ** 2" in second

# --------------------------------------------------------------------------- 11.2
def test_gm_influence_reference_is_psi_of_the_kernel():
    import sympy

    r, c = ch11.GM_SYMBOLS
    ref = ch11.gm_influence_reference()
    assert sympy.simplify(ref - c**4 * r / (c**2 + r**2) ** 2) == 0
    f = sympy.lambdify((r, c), ref)
    rs = np.linspace(0.0, 20.0, 41)
    for scale in (1.0, kernels.INLIER_THRESHOLD):
        assert np.allclose(f(rs, scale), kernels.GemanMcClure(scale).psi(rs), rtol=1e-12)


@pytest.mark.parametrize(
    "answer", ["c**4*r/(c**2 + r**2)**2", "r*c^4/(r^2+c^2)^2", "c**4*r/(c**4 + 2*c**2*r**2 + r**4)"]
)
def test_gm_influence_right_forms_are_correct(capsys, answer):
    ok, out = _run(capsys, ch11.check_gm_influence, answer)
    assert ok is True and passed("11.2"), out


@pytest.mark.parametrize(
    "answer, message",
    [
        ("c**4/(c**2 + r**2)**2", "that is the weight w(r) = ψ(r)/r"),
        ("c**2*r/(c**2 + r**2)", "the derivative of the denominator is missing"),
        ("2*c**4*r/(c**2 + r**2)**2", "a factor 2 too many"),
        ("c**4*r/(c**2 + r**2)", "your ψ(r) differs from the right one"),
        ("c**4*r/(c**2 + x**2)**2", "x is not one"),
    ],
)
def test_gm_influence_wrong_answers_are_named(capsys, answer, message):
    ok, out = _run(capsys, ch11.check_gm_influence, answer)
    assert ok is False and not passed("11.2")
    assert message in out, out
    assert "c**4*r/(c**2 + r**2)**2" not in out


def test_gm_influence_placeholder(capsys):
    ok, out = _run(capsys, ch11.check_gm_influence, ...)
    assert ok is False and NOT_ATTEMPTED in out


# --------------------------------------------------------------------------- 11.3
def test_candidates_are_the_documented_closures():
    g4 = ch11.candidates()
    sim = ch11.world()
    assert g4.m == sim.graph.m + 4 and int(g4.loop_closure.sum()) == 59
    for k, (i, j, offset, sigma) in enumerate(ch11.CANDIDATES.values()):
        e = sim.graph.m + k
        assert tuple(g4.edges[e]) == (i, j)
        true = se2.between(sim.truth[i], sim.truth[j])
        assert np.allclose(g4.measurements[e], true + [offset, 0.0, 0.0], atol=1e-12)
        assert np.allclose(np.diag(g4.information[e]), [sigma**-2, sigma**-2, 0.02**-2])


def test_most_downweighted_is_the_largest_offset_in_sigma(capsys):
    w = ch11._cauchy_weights()
    # recomputed independently: Cauchy IRLS from the odometry, the last four weights
    g4 = ch11.candidates()
    res = lagolib.optimize(g4, g4.odometry_guess(), robust=kernels.Cauchy())
    assert np.allclose(res.weights[-4:], w, rtol=1e-9)
    assert ch11.LABELS[int(np.argmin(w))] == "B"  # 20 sigma; C is 6 m but only 6 sigma
    assert w[0] > 0.9 and w[1] < 0.2 < w[2] < w[3]
    ok, out = _run(capsys, ch11.check_most_downweighted, "B")
    assert ok is True and passed("11.3") and "A: w = 0.946, B: w = 0.126" in out


@pytest.mark.parametrize(
    "answer, message",
    [
        ("C", "the claim furthest off in metres"),
        ("A", "is the right closure"),
        ("D", "is not the closure with the smallest final weight"),
        ("E", "should be one of"),
        (2, "should be one of"),
    ],
)
def test_most_downweighted_wrong_answers_are_named(capsys, answer, message):
    ok, out = _run(capsys, ch11.check_most_downweighted, answer)
    assert ok is False and not passed("11.3")
    assert message in out, out
    assert "0.126" not in out.split("Stuck?")[0]


def test_most_downweighted_accepts_lower_case_and_rejects_the_placeholder(capsys):
    assert _run(capsys, ch11.check_most_downweighted, "b")[0] is True
    ok, out = _run(capsys, ch11.check_most_downweighted, ...)
    assert ok is False and NOT_ATTEMPTED in out


# --------------------------------------------------------------------------- 11.4
def test_ratio_sweep_numbers_and_cache():
    sw = ch11.ratio_sweep("cauchy")
    assert sw["ratios"] == ch11.RATIOS
    assert sw["counts"].tolist() == [28, 55, 110, 220, 440]
    assert sw["broken"].tolist() == [False, False, False, False, True]
    assert sw["ate"][-1] > 4 * sw["base_ate"] and sw["ate"][0] < 1.1 * sw["base_ate"]
    gm = ch11.ratio_sweep("gm")
    assert gm["broken"].tolist() == [False, False, False, True, True]
    # a copy: changing the returned dict does not change the cache
    sw["ate"][:] = 0.0
    assert ch11.ratio_sweep("cauchy")["ate"][-1] > 0
    # one entry recomputed by hand
    sim = ch11.world()
    bad = simulate.add_outliers(sim.graph, 220, rng=ch11.SWEEP_SEED)
    res = robust.solve(bad.graph, bad.graph.odometry_guess(), method="cauchy")
    ate = metrics.absolute_trajectory_error(res.poses, sim.truth).translation_rmse
    assert ate == pytest.approx(ch11.ratio_sweep("cauchy")["ate"][3], rel=1e-9)
    with pytest.raises(ValueError, match="method must be one of"):
        ch11.ratio_sweep("median")


def test_breaking_ratio_reference_is_correct(capsys):
    ok, out = _run(capsys, ch11.check_breaking_ratio, 8.0)
    assert ok is True and passed("11.4") and "cauchy breaks first at ratio 8" in out


@pytest.mark.parametrize(
    "answer, message",
    [
        (4.0, "at ratio 4 the map holds"),
        (0.5, "at ratio 0.5 the map holds"),
        (440, "is a number of wrong closures"),
        (3.0, "is not one of the swept ratios"),
        ("8", "should be one real number"),
    ],
)
def test_breaking_ratio_wrong_answers_are_named(capsys, answer, message):
    ok, out = _run(capsys, ch11.check_breaking_ratio, answer)
    assert ok is False and not passed("11.4")
    assert message in out, out


def test_breaking_ratio_placeholder(capsys):
    ok, out = _run(capsys, ch11.check_breaking_ratio, ...)
    assert ok is False and NOT_ATTEMPTED in out
