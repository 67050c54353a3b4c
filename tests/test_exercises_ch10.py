"""Chapter 10's exercise checks (lagolib.exercises.ch10): right, unfinished, wrong and crashing
answers.

Every check must say "correct" to the reference answer, "not attempted yet" to the stub's
placeholder, name the mistake for the usual wrong answers, and never raise.  The checks draw their
test cases from fixed seeds, so the numbers asserted here are reproducible.
"""

import math

import numpy as np
import pytest

import lagolib
from lagolib import frontend, scan_matching, se2, simulate, uncertainty
from lagolib.exercises import NOT_ATTEMPTED, ch10, hint, passed, reset
from lagolib.gauss_newton import edge_jacobians


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


# --------------------------------------------------------------------------- 10.1
def step_ok(model, points, pose):
    """The chapter's solution: one Cauchy-weighted point-to-line Gauss–Newton step."""
    c, s = np.cos(pose[2]), np.sin(pose[2])
    Rp = points @ np.array([[c, -s], [s, c]]).T
    moved = Rp + pose[:2]
    dist, idx = model.tree.query(moved, distance_upper_bound=ch10.MAX_DISTANCE)
    ok = np.isfinite(dist)
    ok[ok] = model.usable[idx[ok]]
    n, q, Rp, moved = model.normals[idx[ok]], model.points[idx[ok]], Rp[ok], moved[ok]
    r = np.sum(n * (moved - q), axis=1)
    J = np.column_stack([n, n[:, 0] * -Rp[:, 1] + n[:, 1] * Rp[:, 0]])
    sigma = max(1.4826 * np.median(np.abs(r)), 1e-4)
    w = 1.0 / (1.0 + (r / (2.3849 * sigma)) ** 2)
    dx = -np.linalg.solve(J.T @ (w[:, None] * J), J.T @ (w * r))
    new = pose + dx
    new[2] = se2.wrap_angle(new[2])
    return new


def _slip(**kw):
    return lambda model, points, pose: ch10._icp_variant(model, points, pose, **kw)


def test_icp_step_reference_is_correct(capsys):
    ok, out = _run(capsys, ch10.check_icp_step, step_ok)
    assert ok is True and passed("10.1")
    assert "Exercise 10.1 — correct: your step equals scan_matching.icp_step on all 2" in out


def test_icp_cases_are_what_the_docstring_says():
    cases = ch10._icp_cases()
    assert len(cases) == 2
    world = lagolib.laser_world.office()
    for (model, points, guess), x_i, step in zip(
        cases, ([15.0, 14.6, 0.3], [12.0, 11.0, 0.05]), ([0.35, 0.05, 0.12], [0.45, 0.0, -0.05])
    ):
        assert len(points) == 180 and len(model) == 180  # every beam returns indoors
        # the scans are the office seen from x_i and x_i ⊕ step, to the range noise
        expected = lagolib.laser_world.ray_cast(world, np.array(x_i), model_angles(), 30.0)
        got = np.hypot(*model.points.T)
        assert np.abs(got - expected).max() < 0.05
        off = se2.between(np.array(step), guess)
        assert np.hypot(off[0], off[1]) > 0.09 and abs(off[2]) > math.radians(1.9)
        # the reference step and the check's own implementation agree to rounding
        ref = scan_matching.icp_step(model, points, guess, max_distance=ch10.MAX_DISTANCE)[0]
        assert np.abs(ref - ch10._icp_variant(model, points, guess)).max() < 1e-12
        # and one step moves towards the truth
        err0 = np.hypot(*se2.between(np.array(step), guess)[:2])
        err1 = np.hypot(*se2.between(np.array(step), ref)[:2])
        assert err1 < err0
    # the second guess is 30 cm off: some points have no partner within MAX_DISTANCE
    model, points, guess = cases[1]
    used = scan_matching.icp_step(model, points, guess, max_distance=ch10.MAX_DISTANCE)[3]
    assert len(used) < len(points)


def model_angles():
    return lagolib.scans.beam_angles(180)


@pytest.mark.parametrize(
    "stub", [..., lambda m, p, x: ..., lambda m, p, x: None, lambda m, p, x: (..., ...)[0]]
)
def test_icp_step_stub_is_not_attempted(capsys, stub):
    ok, out = _run(capsys, ch10.check_icp_step, stub)
    assert ok is False and not passed("10.1")
    assert NOT_ATTEMPTED in out


@pytest.mark.parametrize(
    "wrong, message",
    [
        (_slip(weights=False), "your step has no Cauchy weights"),
        (_slip(sign=-1.0), "your step goes the wrong way (uphill)"),
        (_slip(rotate=False), "the θ column of your Jacobian uses the scan point p itself"),
        (_slip(mad=False), "your weights use the standard deviation of the residuals"),
        (_slip(usable=False), "you paired points with reference points that have no normal"),
        (lambda m, p, x: np.array(x, dtype=float), "returned the guess unchanged"),
        (lambda m, p, x: np.array(x[:2]), "the new pose has shape (2,), expected (3,)"),
        (
            lambda m, p, x: scan_matching.match(m, p, x),
            "your function returned a Match; return the new pose itself",
        ),
        (
            lambda m, p, x: scan_matching.icp_step(m, p, x),
            "your function returned five things",
        ),
        (lambda m, p, x: step_ok(m, p, x) + 1j, "icp_step should return an array of real numbers"),
    ],
    ids=[
        "weights",
        "uphill",
        "rotation",
        "std",
        "usable",
        "unchanged",
        "shape",
        "match",
        "five",
        "complex",
    ],
)
def test_icp_step_wrong_answers_are_named(capsys, wrong, message):
    ok, out = _run(capsys, ch10.check_icp_step, wrong)
    assert ok is False and not passed("10.1")
    assert "Exercise 10.1 — not yet: on test pair 1 of 2" in out
    assert message in out


def test_icp_step_heading_off_by_a_turn_is_correct(capsys):
    def turned(m, p, x):
        out = step_ok(m, p, x)
        out[2] += 2 * np.pi
        return out

    ok, _ = _run(capsys, ch10.check_icp_step, turned)
    assert ok is True


def test_icp_step_student_exception_and_writes_are_feedback(capsys):
    def broken(m, p, x):
        return p[len(p) + 5]

    ok, out = _run(capsys, ch10.check_icp_step, broken)
    assert ok is False and "icp_step raised IndexError" in out

    def writes(m, p, x):
        new = step_ok(m, p, x)
        p[:] = 0.0  # a copy: allowed, and it changes nothing for the next test pair
        x[:] = 0.0
        m.normals[:] = 0.0  # the cached model is read-only
        return new

    ok, out = _run(capsys, ch10.check_icp_step, writes)
    assert ok is False and "icp_step raised ValueError" in out and "read-only" in out
    ok, _ = _run(capsys, ch10.check_icp_step, step_ok)
    assert ok is True


# --------------------------------------------------------------------------- 10.2
def gate_world_data():
    """A drifting chain: the odometric edges of two laps of a square (seed 3), at its odometry."""
    sim = simulate.loop_world(laps=2, poses_per_lap=40, rng=np.random.default_rng(3))
    g = sim.graph
    odo = g.odometric
    chain = lagolib.PoseGraph(g.poses, g.edges[odo], g.measurements[odo], g.information[odo])
    x = chain.odometry_guess()
    return chain.with_poses(x), x


@pytest.fixture(scope="module")
def gate_world():
    return gate_world_data()


def _gate_by_hand(chain, x, j, candidates, overlap):
    """d² of the gate from chapter 3's relative covariance, written out (not gate_candidates)."""
    cov_i = uncertainty.relative_covariances(chain, j, candidates, poses=x)
    pred = se2.between(x[candidates], x[j])
    _, A, _ = edge_jacobians(x[candidates], np.broadcast_to(x[j], (len(candidates), 3)), pred)
    cov = A @ cov_i @ np.swapaxes(A, 1, 2)
    d = np.hypot(pred[:, 0], pred[:, 1])
    los = pred[:, :2] / d[:, None]
    var = np.einsum("ci,cij,cj->c", los, cov[:, :2, :2], los)
    return np.maximum(d - overlap, 0.0) ** 2 / var


RULES = frontend.ClosureRules(overlap=1.6)
CANDIDATES = [2, 3, 4, 44]  # gated against pose 79, the end of the chain
RIGHT = (True, True, False, False)


def test_gate_numbers_match_chapter_3(gate_world):
    chain, x = gate_world
    d2, d, sigma, threshold = ch10._gate_numbers(chain, 79, CANDIDATES, RULES, x)
    assert np.allclose(d2, _gate_by_hand(chain, x, 79, CANDIDATES, 1.6), rtol=1e-8)
    assert threshold == pytest.approx(6.634896601, rel=1e-9)
    assert np.round(d2, 2).tolist() == [0.27, 3.72, 11.19, 13.8]
    assert tuple(d2 <= threshold) == RIGHT


def test_gate_prediction_reference_is_correct(capsys, gate_world):
    chain, x = gate_world
    ok, out = _run(capsys, ch10.check_gate_prediction, RIGHT, chain, 79, CANDIDATES, RULES, x)
    assert ok is True and passed("10.2")
    assert (
        "Exercise 10.2 — correct: A: d² = 0.27 → admitted; B: d² = 3.72 → admitted; C: d² = "
        "11.19 → rejected; D: d² = 13.80 → rejected (threshold 6.63)." in out
    )
    # the same answer as a list, numpy bools, an array
    for form in (list(RIGHT), tuple(np.bool_(v) for v in RIGHT), np.array(RIGHT)):
        ok, _ = _run(capsys, ch10.check_gate_prediction, form, chain, 79, CANDIDATES, RULES, x)
        assert ok is True


@pytest.mark.parametrize("answer", [..., None, (True, ..., False, False)])
def test_gate_prediction_stub_is_not_attempted(capsys, gate_world, answer):
    chain, x = gate_world
    ok, out = _run(capsys, ch10.check_gate_prediction, answer, chain, 79, CANDIDATES, RULES, x)
    assert ok is False and NOT_ATTEMPTED in out


@pytest.mark.parametrize(
    "candidates, answer, message",
    [
        (CANDIDATES, (False, False, False, False), "you left out the overlap"),
        (CANDIDATES, (True, True, True, False), "you took χ²'s quantile for 3 degrees of freedom"),
        (CANDIDATES, (True, True, False, True), "you divided by σ instead of σ²"),
        ([42, 2, 3, 44], (True, False, False, False), "you admitted exactly the candidates closer"),
        (CANDIDATES, (True, False, False, False), "1 of your 4 answers is not right."),
        (CANDIDATES, (False, True, True, True), "3 of your 4 answers are not right."),
    ],
    ids=["no-overlap", "chi2-3", "sigma", "distance", "one", "three"],
)
def test_gate_prediction_wrong_answers_are_named(capsys, gate_world, candidates, answer, message):
    chain, x = gate_world
    ok, out = _run(capsys, ch10.check_gate_prediction, answer, chain, 79, candidates, RULES, x)
    assert ok is False and not passed("10.2")
    assert "Exercise 10.2 — not yet: " in out and message in out
    # which candidate is wrong, and the gate's verdicts, are the hints' business
    assert "A: d² =" not in out and "→ admitted" not in out and "candidate B" not in out
    assert "hint 3 of 3: the check's gate: A: d² = " in _hints(capsys, "10.2")


@pytest.mark.parametrize(
    "answer, message",
    [
        ((1, 1, 0, 0), "candidate A should be True or False, got 1 (an int)"),
        ((True, True, False), "admitted should be four True/False values"),
        ("TTFF", "admitted should be four True/False values"),
    ],
    ids=["ints", "three", "string"],
)
def test_gate_prediction_wrong_kinds(capsys, gate_world, answer, message):
    chain, x = gate_world
    ok, out = _run(capsys, ch10.check_gate_prediction, answer, chain, 79, CANDIDATES, RULES, x)
    assert ok is False and message in out


# --------------------------------------------------------------------------- 10.3
def test_heading_sweep_numbers_and_cache():
    sw = ch10.heading_sweep()
    assert sw["sigmas"] == ch10.SWEEP_SIGMAS == (0.3, 1.0, 3.0)
    assert sw["keyframes"] == 160
    holds = sw["ate"] <= ch10.ATE_BOUND
    assert holds.tolist() == [False, True, True]
    assert sw["ate"][0] > 1.0  # broken by metres, not centimetres
    assert sw["chain_ate"][0] > 1.0 and np.all(sw["chain_ate"][1:] < 0.5)
    assert sw["accepted"][0] < sw["accepted"][1] and np.all(sw["wrong"] == 0)
    assert sw["certified"].all()
    sw["ate"][:] = 0.0  # a copy: the cache is not corrupted
    again = ch10.heading_sweep()
    assert again["ate"][0] > 1.0


def _answer():
    sw = ch10.heading_sweep()
    return 1.0, int(sw["accepted"][0]), sw


def test_heading_sweep_reference_is_correct(capsys):
    sigma, closures, _ = _answer()
    ok, out = _run(capsys, ch10.check_heading_sweep, sigma, closures)
    assert ok is True and passed("10.3")
    assert "the map holds from σ 1°" in out
    assert f"at the largest σ that breaks it the front end found {closures} loop closures" in out


@pytest.mark.parametrize("answer", [(..., ...), (1.0, ...), (..., 2), (None, None)])
def test_heading_sweep_stub_is_not_attempted(capsys, answer):
    ok, out = _run(capsys, ch10.check_heading_sweep, *answer)
    assert ok is False and NOT_ATTEMPTED in out


def test_heading_sweep_wrong_answers_are_named(capsys):
    _, closures, sw = _answer()
    cases = [
        ((0.3, closures), "smallest_sigma is 0.3°, where the map breaks"),
        ((3.0, closures), "where the map holds (ATE"),
        ((math.radians(1.0), closures), "that is a σ in radians"),
        ((0.5, closures), "smallest_sigma = 0.5 is not one of the swept σ (0.3, 1, 3 degrees)."),
        ((1.0, int(sw["accepted"][1])), "That is the count where the map holds"),
        ((1.0, closures + 3), f"closures_when_broken = {closures + 3} is too large."),
        ((1.0, True), "the question is how many loop closures, not whether"),
        ((1.0, "two"), "closures_when_broken should be a whole number"),
        (([1.0], closures), "smallest_sigma should be one real number, got a list"),
    ]
    for answer, message in cases:
        ok, out = _run(capsys, ch10.check_heading_sweep, *answer)
        assert ok is False and not passed("10.3"), answer
        assert "Exercise 10.3 — not yet" in out and message in out, (answer, out)


# never raising on any answer: tests/test_exercises_fuzz.py (every chapter's checks)
