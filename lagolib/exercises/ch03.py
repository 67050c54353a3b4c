"""Checks for the exercises of chapter 3, *Uncertainty* (``book/03_uncertainty.ipynb``).

* 3.1 (implement) :func:`check_marginal_covariance` — one pose's covariance, block of ``H^-1``;
* 3.2 (predict) :func:`check_closure_prediction` — how a loop closure changes the ellipses;
* 3.3 (implement) :func:`check_relative_covariance` — ``x_j`` relative to ``x_i`` from the joint
  covariance, with the cross terms;
* 3.4 (explore) :func:`check_gate` — what the χ² gate's confidence trades, and which false loop
  closures slip through it.

Every check compares with :mod:`lagolib.uncertainty`, prints one verdict line (see
:mod:`lagolib.exercises`) and returns True or False; it never raises on a wrong answer.
"""

from __future__ import annotations

import numpy as np

from lagolib import optimize, se2, simulate
from lagolib.exercises._coerce import Choice, Function, Int, Real, RealArray
from lagolib.exercises._feedback import (
    NOT_ATTEMPTED,
    call_student,
    check,
    compare_array,
    compare_choice,
    compare_int,
    compare_number,
    is_placeholder,
    matches,
    verdict,
)
from lagolib.graph import PoseGraph
from lagolib.uncertainty import (
    information_matrix,
    loop_closure_test,
    marginal_covariances,
    relative_covariances,
)

__all__ = [
    "SHRINK_CHOICES",
    "TREND_CHOICES",
    "GATE_CONFIDENCE",
    "check_marginal_covariance",
    "check_closure_prediction",
    "check_relative_covariance",
    "check_gate",
]

SHRINK_CHOICES = ("above 1", "0.5 to 1", "0.2 to 0.5", "below 0.2")
TREND_CHOICES = (
    "more true and more false accepted",
    "more true and fewer false accepted",
    "fewer true and more false accepted",
    "fewer true and fewer false accepted",
)
GATE_CONFIDENCE = 0.99
# confidences at which exercise 3.4's counts are compared (the trend) and wrong readings diagnosed
_CONFIDENCES = (0.5, 0.9, 0.99, 0.999, 0.9999, 0.99999)


def _graph(seed=31):
    """A seeded 24-pose, two-lap graph with anisotropic, rotated, x/y–θ-coupled information.

    Returns ``(graph, poses)``: poses at the Gauss–Newton optimum, rotated and shifted away from
    the origin so that lever arms and frames matter.
    """
    rng = np.random.default_rng(seed)
    sim = simulate.loop_world(laps=2, poses_per_lap=12, step=1.5, rng=rng)
    g = sim.graph
    m = g.m
    axis = se2.rotation(rng.uniform(-np.pi, np.pi, m))
    cov = np.zeros((m, 3, 3))
    cov[:, :2, :2] = axis @ np.diag([0.03**2, 0.25**2]) @ np.swapaxes(axis, 1, 2)
    cov[:, 2, 2] = 0.02**2
    cov[:, 0, 2] = cov[:, 2, 0] = 0.3 * 0.03 * 0.02  # x–θ correlation 0.3 (of the along-axis sigma)
    info = np.linalg.inv(cov)
    info = 0.5 * (info + np.swapaxes(info, 1, 2))
    moved = se2.compose(np.array([3.0, -2.0, 0.7]), g.poses)  # the map, somewhere else
    g = PoseGraph(moved, g.edges, g.measurements, info)
    return g, optimize(g).poses


def _block(a, r, c=None):
    c = r if c is None else c
    return a[3 * r : 3 * r + 3, 3 * c : 3 * c + 3]


# ---------------------------------------------------------------------------------------------
# 3.1


@check("3.1", marginal_covariance=Function(RealArray((3, 3))))
def check_marginal_covariance(marginal_covariance) -> bool:
    """Exercise 3.1: ``marginal_covariance(H, free, v)`` → the 3x3 covariance of pose ``v``.

    ``H, free = lagolib.uncertainty.information_matrix(graph, poses)`` of a seeded 24-pose graph
    with anisotropic, rotated information (pose 0 fixed, so block ``k`` of ``H`` is pose
    ``free[k]``).  The student's function is called for a middle, the last and the first free
    pose, and compared with :func:`lagolib.uncertainty.marginal_covariances` (rtol 1e-7).
    Diagnosed: ``H``'s own block (information, not covariance), the inverse of ``H``'s block
    alone (conditional, too small), block ``v`` instead of the block of pose ``v`` (off by one),
    a scipy.sparse result instead of a numpy array.
    """
    ex = "3.1"
    graph, poses = _graph()
    H, free = information_matrix(graph, poses)
    ref_all = marginal_covariances(graph, poses=poses)
    Hd = H.toarray()
    Hinv = np.linalg.inv(Hd)
    K = free.size
    vertices = [int(free[K // 2]), int(free[-1]), int(free[0])]
    worst = 0.0
    levels = (
        "the covariance of pose v is a 3×3 block of the inverse of H — not of H, and not the "
        "inverse of H's block alone.",
        "pose 0 is fixed, so it has no rows in H: block k of H (and of its inverse) belongs to "
        "pose free[k].",
        "invert the whole H (np.linalg.inv(H.toarray()) on this small graph), find k with "
        "free[k] == v (np.flatnonzero), and take the rows and columns 3k, 3k+1, 3k+2.",
    )
    for v in vertices:
        got, problem = call_student(
            marginal_covariance, H.copy(), free.copy(), v, name="marginal_covariance(H, free, v)"
        )
        if problem:
            return verdict(
                ex,
                (f"for pose {v}: " if problem != NOT_ATTEMPTED else "") + problem,
                hint=(
                    "H is a scipy.sparse matrix: H.toarray() makes it a dense numpy array (fine "
                    "on this small graph); return a numpy array of shape (3, 3) (call "
                    ".toarray() on a sparse result).",
                    *levels[1:],
                ),
            )
        k = int(np.flatnonzero(free == v)[0])
        ref = ref_all[v]
        if matches(got, _block(Hd, k)):
            return verdict(
                ex,
                f"for pose {v} you returned H's own diagonal block: that is the information of "
                "pose v (how tightly the measurements hold it), not its covariance.",
                hint=levels,
            )
        if matches(got, np.linalg.inv(_block(Hd, k))):
            a = np.sqrt(np.trace(got[:2, :2]))
            return verdict(
                ex,
                f"for pose {v} you inverted H's 3x3 block alone: that is the covariance of pose "
                "v if every other pose were known exactly, and it is too small (your position "
                f"sigma {a:.3g} m leaves out the uncertainty of the path to the anchor).",
                hint=(
                    "(H^-1)_vv is not (H_vv)^-1: the off-diagonal blocks of H (the edges to the "
                    "neighbours) matter.",
                    *levels[1:],
                ),
            )
        if v < K and k != v and matches(got, _block(Hinv, v)):
            return verdict(
                ex,
                f"for pose {v} you returned block {v} of H^-1, which belongs to pose "
                f"{int(free[v])}: off by one.",
                hint=levels[1:],
            )
        problem = compare_array(
            got, ref, name=f"your covariance of pose {v}", rtol=1e-7, atol=1e-12
        )
        if problem:
            return verdict(ex, problem, hint=levels)
        worst = max(worst, float(np.abs(got - ref).max()))
    return verdict(
        ex,
        None,
        correct=f"poses {vertices} of a {graph.n}-pose graph match "
        f"lagolib.uncertainty.marginal_covariances within rtol 1e-7 (largest difference "
        f"{worst:.1e}).",
    )


# ---------------------------------------------------------------------------------------------
# 3.2


def _position_sigma(cov):
    return np.sqrt(np.trace(cov[:, :2, :2], axis1=1, axis2=2))


def _bucket(ratio):
    if ratio > 1:
        return SHRINK_CHOICES[0]
    if ratio > 0.5:
        return SHRINK_CHOICES[1]
    if ratio > 0.2:
        return SHRINK_CHOICES[2]
    return SHRINK_CHOICES[3]


@check("3.2", shrink=Choice(SHRINK_CHOICES), most_uncertain=Int())
def check_closure_prediction(shrink, most_uncertain, chain, closed) -> bool:
    """Exercise 3.2: predictions of what the loop closure does to the covariances.

    ``shrink`` is one of :data:`SHRINK_CHOICES`: the ratio of the last pose's position sigma
    (``sqrt(trace)`` of its 2x2 position covariance) with the loop closure to without it;
    ``most_uncertain`` is the pose with the largest position sigma after closing.  The reference:
    :func:`lagolib.uncertainty.marginal_covariances` of ``chain`` at its own poses (odometry only:
    they are its optimum) and of ``closed`` at its Gauss–Newton optimum.  The actual values are
    printed with a right answer, and are the last hint level after a wrong one.
    """
    ex = "3.2"
    if is_placeholder(shrink) or is_placeholder(most_uncertain):
        return verdict(ex, NOT_ATTEMPTED)
    last = closed.n - 1
    before = _position_sigma(marginal_covariances(chain))
    after = _position_sigma(marginal_covariances(closed, poses=optimize(closed).poses))
    ratio = after[last] / before[last]
    top = int(np.argmax(after))
    actual = (
        f"pose {last}'s position sigma goes from {before[last]:.3f} m to {after[last]:.3f} m "
        f"(ratio {ratio:.3f}: '{_bucket(ratio)}'); the most uncertain pose after closing is "
        f"{top} ({after[top]:.3f} m; before closing it was {int(np.argmax(before))})."
    )
    problems = []
    p = compare_choice(shrink, _bucket(ratio), SHRINK_CHOICES, name="shrink")
    if p and shrink == SHRINK_CHOICES[0]:  # @check read it as the choice written
        p = (
            "shrink: a measurement never makes an estimate less certain — at a given "
            "linearization point, adding an edge adds a positive semidefinite term to H, so "
            "every covariance can only shrink."
        )
    elif p and "one of" not in p:
        smaller = SHRINK_CHOICES.index(shrink) < SHRINK_CHOICES.index(_bucket(ratio))
        p = (
            f"shrink: {shrink!r} is not the band the ratio falls in: pose {last}'s "
            f"position sigma shrinks {'more' if smaller else 'less'} than that."
        )
    if p:
        problems.append(p)
    p = compare_int(most_uncertain, top, name="most_uncertain")
    if p:
        k = most_uncertain  # read by @check as an int
        if k == int(np.argmax(before)):
            p = (
                f"most_uncertain: pose {k} was the most uncertain before the closure; after it, "
                f"pose {k} is tied to the anchor by a single edge."
            )
        elif k == 0:
            p = "most_uncertain: pose 0 is the fixed anchor; its covariance is exactly zero."
        elif 0 <= k < closed.n:
            p = (
                f"most_uncertain: pose {k} is not the most uncertain pose after the closure "
                f"(its position sigma is {after[k]:.3f} m)."
            )
        else:
            p = f"most_uncertain should be a pose index from 0 to {closed.n - 1}; got {k}."
    if p:
        problems.append(p)
    if problems:
        return verdict(
            ex,
            " ".join(problems),
            hint=(
                "what matters is the chain of measurements between a pose and the fixed one, "
                "not the distance in the plane.",
                f"after the closure pose {last} is one measurement away from the fixed pose 0, "
                f"not {last} odometry steps; for any pose, count the edges from pose 0 to it "
                "both ways round the loop: the shorter way decides.",
                f"the check's numbers: {actual}",
            ),
        )
    return verdict(ex, None, correct=f"both predictions hold. {actual}")


# ---------------------------------------------------------------------------------------------
# 3.3


def _lever(p_i, p_j):
    d = np.asarray(p_j, float)[:2] - np.asarray(p_i, float)[:2]
    return np.array([[1.0, 0.0, -d[1]], [0.0, 1.0, d[0]], [0.0, 0.0, 1.0]])


@check("3.3", relative_covariance=Function(RealArray((3, 3))))
def check_relative_covariance(relative_covariance) -> bool:
    """Exercise 3.3: ``relative_covariance(S_ii, S_ij, S_jj, p_i, p_j)`` → ``Sigma_j|i``, (3, 3).

    On a seeded 24-pose graph with anisotropic, rotated information the joint covariance ``S``
    (pose 0 fixed; ``S_ij = E[dx_i dx_j^T]``) is computed densely and the student's function is
    called for three ordered pairs of free poses; each result is compared with
    :func:`lagolib.uncertainty.relative_covariances` (the inverse of ``H`` with pose ``i`` fixed,
    rtol 1e-7).  Diagnosed: the cross terms left out, their sign flipped, ``S_ij`` used where
    ``S_ji = S_ij^T`` belongs, the lever arm ``M`` left out, transposed or pointing the wrong
    way, the plain difference or sum of the two marginals, and the answer rotated into the frame
    of pose ``i`` or ``j`` instead of world coordinates.
    """
    ex = "3.3"
    graph, poses = _graph()
    H, free = information_matrix(graph, poses)
    S = np.zeros((3 * graph.n, 3 * graph.n))
    rows = (3 * free[:, None] + np.arange(3)).ravel()
    S[np.ix_(rows, rows)] = np.linalg.inv(H.toarray())
    pairs = [(3, 17), (17, 3), (8, 9)]
    worst = 0.0
    for i, j in pairs:
        Sii, Sij, Sjj = _block(S, i), _block(S, i, j), _block(S, j)
        p_i, p_j = poses[i].copy(), poses[j].copy()
        got, problem = call_student(
            relative_covariance,
            Sii.copy(),
            Sij.copy(),
            Sjj.copy(),
            p_i,
            p_j,
            name="relative_covariance(S_ii, S_ij, S_jj, p_i, p_j)",
        )
        if problem:
            return verdict(
                ex,
                problem,
                hint=(
                    "return a numpy array of shape (3, 3), computed from the five arguments "
                    "(S_ii, S_ij, S_jj are 3×3 numpy arrays, p_i and p_j have shape (3,)).",
                ),
            )
        ref = relative_covariances(graph, i, [j], poses=poses)[0]
        M, Mr = _lever(p_i, p_j), _lever(p_j, p_i)
        mistakes = [
            (
                Sjj + M @ Sii @ M.T,
                "you left out the cross terms (those with S_ij): x_i and x_j are strongly "
                "correlated (both carry the errors of the path to the anchor), and the "
                "correlation is what makes the relative uncertainty small.",
            ),
            (
                Sjj + M @ Sij + Sij.T @ M.T + M @ Sii @ M.T,
                "the cross terms have the wrong sign: dx_j|i = dx_j - M dx_i is a difference.",
            ),
            (
                Sjj - M @ Sij - Sij @ M.T + M @ Sii @ M.T,
                "you used S_ij where S_ji belongs: E[dx_j dx_i^T] = S_ij^T (your result is not "
                "even symmetric).",
            ),
            (
                Sjj - M @ Sij.T - Sij @ M.T + M @ Sii @ M.T,
                "the cross terms are transposed: which of them is E[dx_i dx_j^T] = S_ij, and "
                "which its transpose?",
            ),
            (
                Sjj - Sij - Sij.T + Sii,
                "you left out the lever arm M (used the identity): a heading error of x_i swings "
                "x_j around x_i by (x_j - x_i) times that angle.",
            ),
            (
                Sjj - Mr @ Sij - Sij.T @ Mr.T + Mr @ Sii @ Mr.T,
                "the lever arm points the wrong way: M of the statement uses p_j - p_i, the "
                "vector from x_i to x_j.",
            ),
            (
                Sjj - M.T @ Sij - Sij.T @ M + M.T @ Sii @ M,
                "your lever arm is transposed: M moves x_j by the heading error of x_i through "
                "its third column, (-(y_j - y_i), x_j - x_i, 1), not through its third row.",
            ),
            (
                Sjj - Sii,
                "the relative covariance is not the difference of the marginals; write "
                "dx_j|i = dx_j - M dx_i and take the covariance of that.",
            ),
            (
                Sjj + Sii,
                "Sigma_jj + Sigma_ii would be right only if x_i and x_j were independent (and "
                "without lever arm); they are not.",
            ),
        ]
        for theta, frame in [(p_i[2], "i"), (p_j[2], "j")]:
            G = np.eye(3)
            G[:2, :2] = se2.rotation(theta)
            mistakes.append(
                (
                    G.T @ ref @ G,
                    f"your result is the relative covariance rotated into the frame of pose "
                    f"{frame}. The check wants it in world coordinates, like S_ii, S_ij and S_jj "
                    "(and like lagolib.uncertainty.relative_covariances): no rotation is needed.",
                )
            )
        levels = (
            "Sigma_j|i is the covariance of dx_j|i = dx_j - M dx_i: expand "
            "E[(dx_j - M dx_i)(dx_j - M dx_i)^T] term by term.",
            "four terms, with E[dx_i dx_j^T] = S_ij, E[dx_j dx_i^T] = S_ij^T and the lever arm M "
            "of the statement built from p_j - p_i; nothing is rotated into a pose's frame.",
            "the four terms: S_jj, M S_ii M^T, and the two cross terms — -M S_ij and its "
            "transpose.",
        )
        for wrong, message in mistakes:
            if matches(got, wrong):
                return verdict(ex, f"for the pair (i, j) = ({i}, {j}) {message}", hint=levels)
        problem = compare_array(
            got, ref, name=f"your Sigma_j|i for (i, j) = ({i}, {j})", rtol=1e-7, atol=1e-12
        )
        if problem:
            return verdict(ex, problem, hint=levels)
        worst = max(worst, float(np.abs(got - ref).max()))
    return verdict(
        ex,
        None,
        correct=f"the pairs {pairs} of a {graph.n}-pose graph match "
        f"lagolib.uncertainty.relative_covariances (pose i fixed, H re-inverted) within rtol "
        f"1e-7 (largest difference {worst:.1e}).",
    )


# ---------------------------------------------------------------------------------------------
# 3.4


def _gate_table(graph, poses, truth, candidates, information):
    """``(d2, error, false)`` of every candidate: squared Mahalanobis distance, true error (m)."""
    pairs = np.asarray(candidates["pairs"], dtype=int)
    z = np.asarray(candidates["z"], dtype=float)
    false = np.asarray(candidates["false"], dtype=bool)
    d2 = np.array(
        [
            loop_closure_test(graph, i, j, zk, information, poses=poses).d2
            for (i, j), zk in zip(pairs, z)
        ]
    )
    zt = se2.between(np.asarray(truth)[pairs[:, 0]], np.asarray(truth)[pairs[:, 1]])
    error = np.linalg.norm(z[:, :2] - zt[:, :2], axis=1)
    return d2, error, false


def _chi2_3(confidence):
    from scipy.special import gammaincinv

    return float(2.0 * gammaincinv(1.5, confidence))


@check("3.4", trend=Choice(TREND_CHOICES), max_false_error=Real())
def check_gate(trend, max_false_error, graph, poses, truth, candidates, information) -> bool:
    """Exercise 3.4: what raising the gate's confidence does, and which false closures pass.

    ``trend`` is one of :data:`TREND_CHOICES` (as the confidence rises from 0.5 to 0.99999);
    ``max_false_error`` the largest true position error (m) of a false candidate that the gate at
    :data:`GATE_CONFIDENCE` accepts (read to 0.01 m: compared within 0.006 m).  The reference
    recomputes every candidate's ``d^2`` with :func:`lagolib.uncertainty.loop_closure_test` on
    ``graph`` at ``poses``; the true error is the candidate's position minus that of
    ``se2.between(truth[i], truth[j])``.  ``candidates`` is a dict with ``"pairs"`` (k, 2),
    ``"z"`` (k, 3) and ``"false"`` (k,) bool.
    """
    ex = "3.4"
    if is_placeholder(trend) or is_placeholder(max_false_error):
        return verdict(ex, NOT_ATTEMPTED)
    d2, error, false = _gate_table(graph, poses, truth, candidates, information)

    def counts(c):
        ok = d2 <= _chi2_3(c)
        return int(np.sum(ok & ~false)), int(np.sum(ok & false))

    def max_accepted(c):
        ok = (d2 <= _chi2_3(c)) & false
        return float(error[ok].max()) if ok.any() else 0.0

    (t0, f0), (t1, f1) = counts(_CONFIDENCES[0]), counts(_CONFIDENCES[-1])
    expected_trend = TREND_CHOICES[(0 if t1 >= t0 else 2) + (0 if f1 >= f0 else 1)]
    expected = max_accepted(GATE_CONFIDENCE)
    true_acc, false_acc = counts(GATE_CONFIDENCE)
    problems = []
    p = compare_choice(trend, expected_trend, TREND_CHOICES, name="trend")
    if p and "one of" not in p:
        p = (
            f"trend: {trend!r} is not what the gate does as its confidence rises from "
            f"{_CONFIDENCES[0]} to {_CONFIDENCES[-1]}."
        )
    if p:
        problems.append(p)
    p = compare_number(max_false_error, expected, name="max_false_error", rtol=0.0, atol=0.006)
    if p:
        g = max_false_error  # read by @check as one finite real number
        near = [
            c for c in _CONFIDENCES if c != GATE_CONFIDENCE and abs(max_accepted(c) - g) <= 0.006
        ]
        if near:
            p = (
                f"max_false_error: {g:.3f} m is the reading for the gate at confidence {near[0]}, "
                f"not {GATE_CONFIDENCE} (threshold {_chi2_3(GATE_CONFIDENCE):.2f})."
            )
        elif abs(g / 100.0 - expected) <= 0.006:
            p = f"max_false_error: {g:.3g} looks like centimetres; the answer is in metres."
        elif false.any() and abs(float(error[false].max()) - g) <= 0.006:
            p = (
                f"max_false_error: {g:.3f} m is the largest error of all false candidates; "
                "the gate rejects that one. Take the largest among those it accepts."
            )
        elif (~false).any() and abs(float(error[~false].max()) - g) <= 0.006:
            p = (
                f"max_false_error: {g:.3f} m is the largest error among the *true* candidates "
                "(their measurement noise); the question is about the false ones."
            )
        else:
            p += f" Read it off the row for confidence {GATE_CONFIDENCE}."
    if p:
        problems.append(p)
    summary = (
        f"at confidence {GATE_CONFIDENCE} (d^2 <= {_chi2_3(GATE_CONFIDENCE):.2f}) the gate "
        f"accepts {true_acc} of {int(np.sum(~false))} true and {false_acc} of "
        f"{int(np.sum(false))} false candidates; the largest error of an accepted false one is "
        f"{expected:.3f} m."
    )
    if problems:
        return verdict(
            ex,
            " ".join(problems),
            hint=(
                "move the slider (or read the printed table): count the accepted candidates of "
                "each kind, and look at the errors of the false ones it lets through.",
                "a higher confidence is a higher threshold on d^2; max_false_error is the largest "
                f"true error among the false candidates with d^2 <= {_chi2_3(GATE_CONFIDENCE):.2f} "
                f"(confidence {GATE_CONFIDENCE}), in metres.",
                f"from confidence {_CONFIDENCES[0]} to {_CONFIDENCES[-1]} the gate accepts "
                f"{t0} -> {t1} true and {f0} -> {f1} false candidates; {summary}",
            ),
        )
    return verdict(ex, None, correct=f"{expected_trend}; {summary}")
