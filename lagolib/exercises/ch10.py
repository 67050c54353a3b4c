"""Checks for the exercises of chapter 10, *From laser scans to maps*
(``book/10_from_scans_to_maps.ipynb``), and a helper.

=========  =========  ==========================================================================
exercise   kind       check
=========  =========  ==========================================================================
10.1       implement  :func:`check_icp_step` — one point-to-line ICP step (pairs, Cauchy
                      weights, one Gauss–Newton step), compared with
                      :func:`lagolib.scan_matching.icp_step` on fixed pairs of simulated scans
10.2       predict    :func:`check_gate_prediction` — which of four printed loop-closure
                      candidates the front end's gate admits
10.3       explore    :func:`check_heading_sweep` — the smallest heading σ of the odometry prior
                      whose map stays within :data:`ATE_BOUND` of the truth, and how many loop
                      closures the front end found where the map broke
=========  =========  ==========================================================================

:func:`heading_sweep` computes exercise 10.3's sweep (the chapter's cell and the check share it).

Every check prints one line, ``Exercise 10.k — correct: …``, ``— not yet: …`` (what is wrong and by
how much, never the answer; ``hint(…)`` tells more, one level per call) or
``— not attempted yet: …``, and returns True or False; it never raises on
a wrong answer (see :mod:`lagolib.exercises._feedback`).
"""

from __future__ import annotations

import copy
import math
import time
import warnings
from functools import lru_cache

import numpy as np

from lagolib import LagolibWarning, certify, frontend, laser_world, metrics, scan_matching, se2
from lagolib.exercises._coerce import Bool, Function, Int, Real, RealArray, Tuple
from lagolib.exercises._feedback import (
    NOT_ATTEMPTED,
    call_student,
    check,
    compare_array,
    compare_int,
    compare_number,
    is_placeholder,
    matches,
    verdict,
)
from lagolib.scans import beam_angles, scan_points

__all__ = [
    "MAX_DISTANCE",
    "LABELS",
    "HEADING_BIAS",
    "SWEEP_SCANS",
    "SWEEP_SIGMAS",
    "ATE_BOUND",
    "heading_sweep",
    "check_icp_step",
    "check_gate_prediction",
    "check_heading_sweep",
]

#: Metres: exercise 10.1's pairing distance (:func:`lagolib.scan_matching.icp_step`'s default).
MAX_DISTANCE = 0.5
#: The names of exercise 10.2's four candidates, in the order of its answer.
LABELS = ("A", "B", "C", "D")
#: Radians per metre driven: the simulated odometry's heading bias in exercise 10.3 — the "about
#: −3.9°/m" that the laser data's notes (``SOURCES.md``) quote for INTEL's real odometry.  Chapter
#: 10's own estimators give −3.3 (summed heading error / distance driven) and −3.6 (least-squares
#: slope per increment) on INTEL; the exercise keeps the quoted, slightly stronger value.
HEADING_BIAS = math.radians(-3.9)
#: Exercise 10.3 runs the front end on the first this many scans of the simulated office.
SWEEP_SCANS = 320
#: Degrees: the heading σ of the odometry prior per keyframe step, exercise 10.3's sweep.
SWEEP_SIGMAS = (0.3, 1.0, 3.0)
#: Metres: a map "holds" when the ATE of its poses against the truth is at most this.
ATE_BOUND = 0.15


# --------------------------------------------------------------------------- exercise 10.1
def _icp_variant(
    model,
    points,
    pose,
    *,
    weights=True,
    mad=True,
    usable=True,
    rotate=True,
    sign=1.0,
    max_distance=MAX_DISTANCE,
):
    """One point-to-line ICP step as :func:`lagolib.scan_matching.icp_step` takes it — or with
    one of the usual slips (the keywords), to recognize a wrong answer.

    ``weights=False``: no Cauchy weights; ``mad=False``: σ from the standard deviation instead of
    ``1.4826 median |r|``; ``usable=False``: reference points without a normal are paired too;
    ``rotate=False``: the θ column of the Jacobian uses ``p`` instead of ``R(θ) p``;
    ``sign=-1``: the step taken uphill.  Returns the new pose, shape (3,).
    """
    pose = np.asarray(pose, dtype=float)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    Rp = points @ np.array([[c, s], [-s, c]])  # R(θ) p for every row p
    moved = Rp + pose[:2]
    dist, idx = model.tree.query(moved, distance_upper_bound=max_distance)
    ok = np.isfinite(dist)
    if usable:
        ok[ok] = model.usable[idx[ok]]
    cur, ref = np.nonzero(ok)[0], idx[ok]
    if len(cur) < 3:
        return pose.copy()
    n = model.normals[ref]
    r = np.einsum("mi,mi->m", n, moved[cur] - model.points[ref])  # n^T (R p + t - q)
    lever = Rp[cur] if rotate else points[cur]
    J = np.column_stack([n, n[:, 0] * -lever[:, 1] + n[:, 1] * lever[:, 0]])
    if mad:
        sigma = max(1.4826 * float(np.median(np.abs(r))), 1e-4)
    else:
        sigma = max(float(np.std(r)), 1e-4)
    w = 1.0 / (1.0 + (r / (scan_matching.CAUCHY_C * sigma)) ** 2) if weights else np.ones_like(r)
    H = J.T @ (w[:, None] * J)
    g = J.T @ (w * r)
    dx = -np.linalg.solve(H, g)
    new = pose + sign * dx
    new[2] = math.remainder(new[2], 2 * math.pi)
    return new


@lru_cache(maxsize=1)
def _icp_cases():
    """Exercise 10.1's test pairs: two scans of the simulated office each, and a guess.

    Case 1: a scan in room B (furnished: every direction constrained) and one taken 0.35 m
    ahead and 0.12 rad to the left, the guess 10 cm and 2° off the truth.  Case 2: the top
    corridor, the guess 30 cm and 5° off (some points then have no partner within
    :data:`MAX_DISTANCE`).  Ranges with 1 cm Gaussian noise (seeded); 180 beams over 180°.
    Returns ``((model, points_j, guess), …)``; the points are in each scan's sensor frame.
    """
    world = laser_world.office()
    angles = beam_angles(180)
    rng = np.random.default_rng(1001)
    cases = []
    for x_i, step, off in (
        ((15.0, 14.6, 0.3), (0.35, 0.05, 0.12), (0.08, -0.06, math.radians(2))),
        ((12.0, 11.0, 0.05), (0.45, 0.0, -0.05), (-0.25, 0.15, math.radians(-5))),
    ):
        x_i = np.array(x_i)
        x_j = se2.compose(x_i, np.array(step))
        ranges = laser_world.ray_cast(world, np.array([x_i, x_j]), angles, 30.0)
        ranges = ranges + 0.01 * rng.standard_normal(ranges.shape)
        p_i, _ = scan_points(ranges[0], angles, max_range=30.0)
        p_j, _ = scan_points(ranges[1], angles, max_range=30.0)
        guess = se2.compose(np.array(step), np.array(off))
        model = scan_matching.ScanModel(p_i)
        # read-only: a student's function that writes into its arguments cannot change the
        # cached cases (the check hands over copies of the points and the guess)
        for a in (model.points, model.normals, model.usable, p_j, guess):
            a.setflags(write=False)
        cases.append((model, p_j, guess))
    return tuple(cases)


_ICP_SLIPS = (
    (
        dict(weights=False),
        "your step has no Cauchy weights: every pair counts fully, so the pairs that landed on "
        "the wrong wall pull as hard as the good ones.",
        "weight each pair by w_k = 1 / (1 + (r_k / (c s))²), c = 2.3849, with the robust scale "
        "s = 1.4826 · median |r|, and solve (Jᵀ W J) Δx = −Jᵀ W r.",
    ),
    (
        dict(sign=-1.0),
        "your step goes the wrong way (uphill): the Gauss–Newton step solves H Δx = −b, "
        "b = Jᵀ W r.",
        "check the sign of Δx — and that r is n·(R p + t − q), not n·(q − R p − t).",
    ),
    (
        dict(rotate=False),
        "the θ column of your Jacobian uses the scan point p itself; the derivative of R(θ) p "
        "is R'(θ) p = (−(R p)_y, (R p)_x), at the current θ.",
        "rotate the points by the guess first, then J_θ = n · (−(R p)_y, (R p)_x).",
    ),
    (
        dict(mad=False),
        "your weights use the standard deviation of the residuals as their scale; a few bad "
        "pairs inflate it. The weights take the robust scale s = 1.4826 · median |r|.",
        "s = 1.4826 * np.median(np.abs(r)).",
    ),
    (
        dict(usable=False),
        "you paired points with reference points that have no normal (model.usable is False "
        "there: their neighbourhood is not a line).",
        "keep only the pairs within max_distance whose reference point has model.usable[idx] True.",
    ),
)


def _explain_pose(result, *args, **kwargs):
    """The sentence for a result that is a Match or a tuple (icp_step's whole return value)."""
    if isinstance(result, scan_matching.Match):
        return "your function returned a Match; return the new pose itself (its .pose), shape (3,)."
    if isinstance(result, tuple) and len(result) == 5:
        return (
            "your function returned five things (as scan_matching.icp_step does); return only "
            "the new pose, an array of shape (3,)."
        )
    return None


@check("10.1", icp_step=Function(RealArray((3,)), explain=_explain_pose))
def check_icp_step(icp_step):
    """Check exercise 10.1: ``icp_step(model, points, pose)``, one point-to-line ICP iteration.

    Calls the student's function on the pairs of :func:`_icp_cases` (a
    :class:`~lagolib.scan_matching.ScanModel` of scan ``i``, the points of scan ``j`` (m, 2) in
    its sensor frame, and a guess (3,) of the pose of ``j`` in the frame of ``i``) and compares the
    returned pose with :func:`lagolib.scan_matching.icp_step` (pairing distance
    :data:`MAX_DISTANCE`, no prior) to ``1e-7`` relative and ``1e-9`` absolute, the heading
    compared modulo 2π.  Diagnoses a step without weights, uphill, a Jacobian without the
    rotation, the weights' scale from the standard deviation, and pairs with points that have no normal.

    Parameters
    ----------
    icp_step : callable
        ``(model ScanModel, points ndarray (m, 2), pose ndarray (3,)) -> ndarray (3,)``.

    Returns
    -------
    bool
    """
    ex = "10.1"
    cases = _icp_cases()
    for k, (model, points, guess) in enumerate(cases):
        got, problem = call_student(icp_step, model, points.copy(), guess.copy(), name="icp_step")
        where = f"on test pair {k + 1} of {len(cases)}"
        if problem == NOT_ATTEMPTED:
            return verdict(ex, problem)
        if problem is not None:
            return verdict(
                ex,
                f"{where}: " + problem,
                hint=(
                    "the check calls icp_step(model, points, pose) with a "
                    "scan_matching.ScanModel, an (m, 2) array and a pose (x, y, θ), and expects "
                    "the new pose back, shape (3,). A point with no partner within "
                    "MAX_DISTANCE gets dist = inf and idx = len(model.points): mask with "
                    "np.isfinite(dist) before indexing with idx.",
                ),
            )
        expected = scan_matching.icp_step(model, points, guess, max_distance=MAX_DISTANCE)[0]
        got = np.array(got, dtype=float)
        if got.shape == (3,):
            got[2] = expected[2] + math.remainder(got[2] - expected[2], 2 * math.pi)
        problem = compare_array(got, expected, name="the new pose", rtol=1e-7, atol=1e-9)
        if problem is None:
            continue
        hint = (
            "go through the statement's five steps one at a time on the chapter's pair, and "
            "check each intermediate result: how many pairs, the residuals r (compare with "
            "scan_matching.point_to_line_residuals), the scale s, the weights.",
            "pairs: each moved point R(θ) p + t and its nearest usable model point q within "
            f"{MAX_DISTANCE} m; r = n·(R p + t − q), J = [n_x, n_y, n·R'(θ)p]; s = 1.4826 median|r|; "
            "Cauchy weights; Δx = −(JᵀWJ)⁻¹JᵀWr; new pose = pose + Δx, θ wrapped.",
        )
        if got.shape != expected.shape:
            return verdict(ex, f"{where}: {problem}", hint=hint)
        for slip, sentence, slip_hint in _ICP_SLIPS:
            wrong = _icp_variant(model, points, guess, **slip)
            if not np.allclose(wrong, expected, rtol=1e-7, atol=1e-9) and matches(got, wrong, 1e-7):
                problem, hint = sentence, (slip_hint, hint[1])
                break
        else:
            if np.allclose(got, guess, rtol=0, atol=1e-12):
                problem = "your function returned the guess unchanged: it did not take a step."
        return verdict(ex, f"{where}: {problem}", hint=hint)
    return verdict(
        ex,
        None,
        correct=f"your step equals scan_matching.icp_step on all {len(cases)} test pairs.",
    )


# --------------------------------------------------------------------------- exercise 10.2
_ADMITTED = Tuple(
    *(Bool() for _ in LABELS),
    names=tuple(f"candidate {c}" for c in LABELS),
    what="four True/False values, one per candidate A, B, C, D",
)


def _gate_numbers(graph, j, candidates, rules, poses):
    """``(d2, d, sigma, threshold)``: the gate's d² and its ingredients for each candidate."""
    from scipy.stats import chi2

    d2, pred, cov = frontend.gate_candidates(graph, j, candidates, rules, poses=poses)
    d = np.hypot(pred[:, 0], pred[:, 1])
    los = pred[:, :2] / np.maximum(d, 1e-12)[:, None]
    sigma = np.sqrt(np.einsum("ci,cij,cj->c", los, cov[:, :2, :2], los))
    return d2, d, sigma, float(chi2.ppf(rules.confidence, 1))


@check("10.2", admitted=_ADMITTED)
def check_gate_prediction(admitted, graph, j, candidates, rules, poses):
    """Check exercise 10.2: which of four candidates the front end's gate admits.

    Recomputes the gate with :func:`lagolib.frontend.gate_candidates` — ``d² = max(d − overlap,
    0)² / σ²`` with ``d`` the predicted distance between the scans' poses and ``σ²`` the variance
    of the prediction along the line of sight (the relative covariance of chapter 3) — and
    admits a candidate when ``d²`` is at most the ``rules.confidence`` quantile of χ² with one
    degree of freedom.  Names the usual slips: the overlap left out, χ²'s quantile for 3 degrees
    of freedom, σ instead of σ², a gate on the distance alone.

    Parameters
    ----------
    admitted : tuple of 4 bool
        One per candidate, in the order of ``candidates`` (A, B, C, D).
    graph : PoseGraph
        The graph the candidates are gated against (the chapter: the drifting chain).
    j : int
        Vertex id of the new keyframe.
    candidates : sequence of 4 int
        Vertex ids of the old keyframes.
    rules : lagolib.frontend.ClosureRules
    poses : ndarray, shape (n, 3)

    Returns
    -------
    bool
    """
    from scipy.stats import chi2

    ex = "10.2"
    if is_placeholder(admitted):
        return verdict(ex, NOT_ATTEMPTED)
    if len(candidates) != len(LABELS):
        raise ValueError(f"exercise 10.2 has {len(LABELS)} candidates; got {len(candidates)}")
    d2, d, sigma, threshold = _gate_numbers(graph, j, candidates, rules, poses)
    want = tuple(bool(v) for v in d2 <= threshold)
    got = tuple(admitted)
    facts = "; ".join(
        f"{c}: d² = {v:.2f} → {'admitted' if ok else 'rejected'}"
        for c, v, ok in zip(LABELS, d2, want)
    )
    if got == want:
        return verdict(ex, None, correct=f"{facts} (threshold {threshold:.2f}).")
    excess = np.maximum(d - rules.overlap, 0.0)
    slips = (
        (
            tuple(bool(v) for v in (d / sigma) ** 2 <= threshold),
            "you left out the overlap: two scans overlap when their poses are less than "
            f"overlap = {rules.overlap:g} m apart, so the gate asks how many σ the distance is "
            "beyond that, max(d − overlap, 0) / σ.",
        ),
        (
            tuple(bool(v) for v in d2 <= chi2.ppf(rules.confidence, 3)),
            f"you took χ²'s quantile for 3 degrees of freedom ({chi2.ppf(rules.confidence, 3):.2f}); "
            "the gate tests one number, the distance along the line of sight: 1 degree of "
            f"freedom, {threshold:.2f}.",
        ),
        (
            tuple(bool(v) for v in excess**2 / sigma <= threshold),
            "you divided by σ instead of σ²: d² = (d − overlap)² / σ² is the square of a number "
            "of standard deviations.",
        ),
        (
            tuple(bool(v) for v in d <= rules.overlap),
            f"you admitted exactly the candidates closer than overlap = {rules.overlap:g} m: the "
            "gate is not a distance threshold — a far candidate whose relative pose is uncertain "
            "can overlap too.",
        ),
    )
    problem = None
    for answer, sentence in slips:
        if answer != want and got == answer:
            problem = sentence
            break
    wrong = [c for c, a, b in zip(LABELS, got, want) if a != b]
    if problem is None:
        verb = "is" if len(wrong) == 1 else "are"
        problem = f"{len(wrong)} of your {len(LABELS)} answers {verb} not right."
    else:
        verb = "is" if len(wrong) == 1 else "are"
        problem += f" ({len(wrong)} of your {len(LABELS)} answers {verb} not right.)"
    return verdict(
        ex,
        problem,
        hint=(
            "the gate asks how many standard deviations the predicted distance is beyond the "
            "overlap, along the line of sight, and compares the square with a χ² quantile.",
            "d² = max(d − overlap, 0)² / σ² from the printed d and σ; admitted when d² is at "
            f"most χ²₁'s quantile at the rules' confidence ({threshold:.2f}).",
            f"the check's gate: {facts} (threshold {threshold:.2f}).",
        ),
    )


# --------------------------------------------------------------------------- exercise 10.3
_SWEEP: dict = {}


def heading_sweep(sigmas=SWEEP_SIGMAS):
    """The front end and :func:`lagolib.certify.solve` on a biased simulated log, per heading σ.

    The log: :func:`lagolib.laser_world.simulate_log` with ``heading_bias`` = :data:`HEADING_BIAS`
    (its other defaults: seed 0), its first :data:`SWEEP_SCANS` scans.  For each σ (degrees) of
    ``sigmas``, :func:`lagolib.frontend.build_graph` runs with ``rotation_sigma`` = σ (its other
    defaults), :func:`lagolib.certify.solve` optimizes the graph, and the ATE of the result
    against the truth is recorded (aligned, :func:`lagolib.metrics.absolute_trajectory_error`).
    The result is cached (the chapter's cell and :func:`check_heading_sweep` share it).

    Parameters
    ----------
    sigmas : sequence of float
        Degrees.

    Returns
    -------
    dict
        ``"sigmas"`` (tuple, degrees) and, each an ndarray over ``sigmas``: ``"ate"`` (m, after
        optimization), ``"chain_ate"`` (m, the sequential chain alone), ``"accepted"`` and
        ``"wrong"`` (int, loop closures), ``"certified"`` (bool); ``"keyframes"`` (int) and
        ``"seconds"`` (float, the whole sweep).
    """
    key = tuple(float(s) for s in sigmas)
    if key in _SWEEP:  # a deep copy: the caller may change it without corrupting the cache
        return copy.deepcopy(_SWEEP[key])
    t0 = time.perf_counter()
    log = laser_world.simulate_log(heading_bias=HEADING_BIAS)
    log = log.subset(np.arange(min(SWEEP_SCANS, len(log))))
    out = {name: np.zeros(len(key)) for name in ("ate", "chain_ate")}
    out.update({name: np.zeros(len(key), int) for name in ("accepted", "wrong")})
    out["certified"] = np.zeros(len(key), bool)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LagolibWarning)
        for k, s in enumerate(key):
            fe = frontend.build_graph(log, rotation_sigma=math.radians(s))
            sol = certify.solve(fe.graph)
            g = fe.graph
            chain = g.odometry_guess()
            out["ate"][k] = metrics.absolute_trajectory_error(
                sol.poses, fe.reference
            ).translation_rmse
            out["chain_ate"][k] = metrics.absolute_trajectory_error(
                chain, fe.reference
            ).translation_rmse
            out["accepted"][k] = fe.n_accepted
            out["wrong"][k] = fe.n_wrong
            out["certified"][k] = sol.certified
            out["keyframes"] = g.n
    out["sigmas"] = key
    out["seconds"] = time.perf_counter() - t0
    _SWEEP[key] = out
    return heading_sweep(sigmas)


@check("10.3", smallest_sigma=Real(), closures_when_broken=Int(count_of="loop closures"))
def check_heading_sweep(smallest_sigma, closures_when_broken):
    """Check exercise 10.3: where the biased odometry prior stops breaking the map.

    Recomputes (or reuses) :func:`heading_sweep` and compares ``smallest_sigma`` — the smallest
    σ (degrees) of :data:`SWEEP_SIGMAS` whose ATE is at most :data:`ATE_BOUND` — to 1e-9, and
    ``closures_when_broken``, the loop closures the front end accepted at the largest σ whose
    ATE is above the bound.

    Parameters
    ----------
    smallest_sigma : float
        Degrees, one of :data:`SWEEP_SIGMAS`.
    closures_when_broken : int

    Returns
    -------
    bool
    """
    ex = "10.3"
    if is_placeholder(smallest_sigma) or is_placeholder(closures_when_broken):
        return verdict(ex, NOT_ATTEMPTED)
    sw = heading_sweep()
    sigmas = np.array(sw["sigmas"])
    ok = sw["ate"] <= ATE_BOUND
    table = ", ".join(
        f"σ {s:g}°: {a:.2f} m ({c} closures)" for s, a, c in zip(sigmas, sw["ate"], sw["accepted"])
    )
    if not ok.any() or ok.all():
        return verdict(ex, f"this sweep has no σ at which the map breaks and holds: {table}.")
    want_sigma = float(sigmas[ok][0])
    broken = np.nonzero(~ok & (sigmas < want_sigma))[0]
    if len(broken) == 0:
        return verdict(ex, f"this sweep has no broken map below σ {want_sigma:g}°: {table}.")
    want_closures = int(sw["accepted"][broken[-1]])
    got = smallest_sigma  # read by @check as one finite real number
    wrong = compare_number(got, want_sigma, name="smallest_sigma", rtol=1e-9)
    if wrong is not None:
        if np.any(np.isclose(np.radians(sigmas), got, rtol=1e-6)):
            wrong = (
                f"smallest_sigma is {got:.6g}: that is a σ in radians; the sweep lists degrees "
                "(ch10.SWEEP_SIGMAS)."
            )
        elif not np.any(np.isclose(sigmas, got)):
            wrong = (
                f"smallest_sigma = {got:g} is not one of the swept σ "
                f"({', '.join(f'{s:g}' for s in sigmas)} degrees)."
            )
        else:
            k = int(np.argmin(np.abs(sigmas - got)))
            state = "holds" if ok[k] else "breaks"
            wrong = (
                f"smallest_sigma is {got:g}°, where the map {state} (ATE {sw['ate'][k]:.2f} m, "
                f"bound {ATE_BOUND:g} m); "
                + ("a smaller σ holds too." if ok[k] else "the smallest σ that holds is larger.")
            )
        return verdict(
            ex,
            wrong,
            hint=(
                "read the ATE column from the smallest σ up: the first row at or below "
                f"{ATE_BOUND:g} m.",
                f"the check's sweep: {table}.",
            ),
        )
    wrong = compare_int(closures_when_broken, want_closures, name="closures_when_broken")
    if wrong is not None:
        at_ok = int(sw["accepted"][ok][0])
        if closures_when_broken == at_ok:  # an int: @check read it
            wrong += (
                " That is the count where the map holds; the question is about the row below it."
            )
        return verdict(
            ex,
            wrong,
            hint=(
                "the 'closures' column of the largest σ whose ATE is above the bound.",
                f"the check's sweep: {table}.",
            ),
        )
    return verdict(
        ex,
        None,
        correct=f"{table}; the map holds from σ {want_sigma:g}°, and at the largest σ that "
        f"breaks it the front end found {want_closures} loop closures.",
    )
