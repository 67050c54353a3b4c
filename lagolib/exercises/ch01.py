"""Checks for the exercises of chapter 1, *Poses and pose graphs*.

===========  =========  ==========================================================================
exercise     kind       check
===========  =========  ==========================================================================
1.1          implement  :func:`check_edge_error` — ``e_ij = t2v(Z_ij⁻¹ X_i⁻¹ X_j)`` of one edge
1.2          explore    :func:`check_heading_noise` — heading noise and the end of a closed loop
1.3          predict    :func:`check_chi2_laps` — χ² at the odometry guess and the number of laps
1.4          predict    :func:`check_toro_frames` — does a TORO file hold the g2o information?
===========  =========  ==========================================================================

Each check prints one line starting ``Exercise 1.N`` (correct / not yet / not attempted yet, see
:mod:`lagolib.exercises`) and returns True or False; it never raises on a wrong answer.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from lagolib import PoseGraph, chi2, residuals, se2, simulate, write_toro
from lagolib.exercises._coerce import Bool, Choice, Function, Real, RealArray
from lagolib.exercises._feedback import (
    NOT_ATTEMPTED,
    WRONG_CHOICE,
    call_student,
    check,
    compare_array,
    compare_choice,
    compare_number,
    is_placeholder,
    verdict,
)
from lagolib.exercises._reference import independent_edges

__all__ = [
    "check_edge_error",
    "check_heading_noise",
    "check_chi2_laps",
    "check_toro_frames",
    "end_distances",
    "chi2_by_laps",
    "toro_file_information",
]

# --------------------------------------------------------------------------------------------
# Exercise 1.1 — the error of one edge


def _edge_cases(seed=11):
    """Seeded test edges ``(p_i, p_j, z)``, each of shape (k, 3).

    Random poses and measurements with headings all around the circle, plus edges whose
    unwrapped angle error ``θ_j − θ_i − θ_z`` lies beyond ±π (headings near ±π), so that an
    error that forgets to wrap its angle is caught.
    """
    rng = np.random.default_rng(seed)
    k = 24
    p_i = rng.uniform([-10, -10, -np.pi], [10, 10, np.pi], size=(k, 3))
    p_j = rng.uniform([-10, -10, -np.pi], [10, 10, np.pi], size=(k, 3))
    z = rng.uniform([-3, -3, -np.pi], [3, 3, np.pi], size=(k, 3))
    # near the seam: theta_i ≈ -π, theta_j ≈ +π (and the reverse), small measured turns
    near = 8
    eps = rng.uniform(0.01, 0.4, size=(near, 3))
    sign = np.where(np.arange(near) % 2 == 0, 1.0, -1.0)
    p_i[:near, 2] = -sign * (np.pi - eps[:, 0])
    p_j[:near, 2] = sign * (np.pi - eps[:, 1])
    z[:near, 2] = -sign * eps[:, 2]
    return p_i, p_j, z


def _reference_errors(p_i, p_j, z):
    """lagolib's ``e_ij`` (:func:`lagolib.residuals`) of the edges ``(p_i, p_j, z)``, shape (k, 3)."""
    return residuals(independent_edges(p_i, p_j, z))


def _matches(got, candidate, angles=True):
    """Whether ``got`` (k, 3) equals ``candidate`` (k, 3); angles compared wrapped."""
    d = got - candidate
    if angles:
        d[:, 2] = (d[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return bool(np.all(np.abs(d) <= 1e-7 * (1 + np.abs(candidate))))


def _t2v_batch(T):
    return np.column_stack([T[:, 0, 2], T[:, 1, 2], np.arctan2(T[:, 1, 0], T[:, 0, 0])])


def _edge_mistakes(p_i, p_j, z):
    """Errors a student commonly computes instead of ``e_ij``: ``[(values (k, 3), diagnosis)]``."""
    Xi, Xj, Z = se2.v2t(p_i), se2.v2t(p_j), se2.v2t(z)
    inv = np.linalg.inv
    frame_i = se2.between(p_i, p_j) - z  # t2v(X_i⁻¹X_j) − z: TORO's frame-i error
    return [
        (
            frame_i,
            "your translation error is R_iᵀ(t_j − t_i) − t_z, the error in the frame of pose i "
            "(what t2v(X_i⁻¹ X_j) − z gives). The edge's error is measured in the frame of the "
            "measurement: compose with Z_ij⁻¹ instead of subtracting z, which rotates it by R_zᵀ.",
        ),
        (
            _t2v_batch(inv(Z) @ inv(Xj) @ Xi),
            "you computed the pose of i seen from j (X_j⁻¹ X_i): the measurement z_ij is the pose "
            "of j in the frame of i, so the product is Z_ij⁻¹ X_i⁻¹ X_j.",
        ),
        (
            _t2v_batch(inv(Xi) @ Xj @ inv(Z)),
            "Z_ij⁻¹ multiplies from the wrong side: X_i⁻¹ X_j Z_ij⁻¹ rotates the translation "
            "differently. The error is t2v(Z_ij⁻¹ (X_i⁻¹ X_j)), Z_ij⁻¹ on the left.",
        ),
        (
            _t2v_batch(inv(Z) @ Xi @ inv(Xj)),
            "you used X_i X_j⁻¹ instead of X_i⁻¹ X_j: the pose of j in the frame of i is "
            "X_i⁻¹ X_j.",
        ),
        (
            _t2v_batch(Z @ inv(Xi) @ Xj),
            "you multiplied by Z_ij instead of its inverse Z_ij⁻¹.",
        ),
    ]


_EDGE_HINT = (
    "print your edge_error and lagolib.residuals for one edge side by side (the chapter's cell "
    "does) and look at which of x, y, θ differ.",
    "e_ij = t2v(Z_ij⁻¹ (X_i⁻¹ X_j)): X_i⁻¹ X_j is pose j seen from pose i; Z_ij⁻¹ on the left "
    "then compares it with the measurement, in the measurement's frame.",
    "build the three matrices X_i, X_j, Z_ij with se2.v2t, multiply them in the order of the "
    "equation (Z_ij's inverse on the left), and turn the product back into (x, y, θ) with se2.t2v.",
)


@check("1.1", edge_error=Function(RealArray((3,))))
def check_edge_error(edge_error) -> bool:
    """Exercise 1.1: the error of one edge, ``e_ij = t2v(Z_ij⁻¹ (X_i⁻¹ X_j))``.

    Calls ``edge_error(p_i, p_j, z)`` (three arrays of shape (3,); it must return shape (3,)) on
    24 seeded edges with headings all around the circle — a third of them with headings near ±π,
    where the unwrapped angle error lies beyond ±π — and compares with :func:`lagolib.residuals`
    (the lecture notes' error, angle wrapped into (−π, π]) to 1e-7 relative.  Recognizes a
    missing wrap, an angle in degrees, the frame-i error ``t2v(X_i⁻¹X_j) − z``, swapped poses,
    ``Z_ij`` on the wrong side or not inverted, and a flipped sign.

    Parameters
    ----------
    edge_error : callable
        The student's function ``edge_error(p_i, p_j, z) -> ndarray of shape (3,)``.

    Returns
    -------
    bool
        Whether every edge's error matched.
    """
    ex = "1.1"
    p_i, p_j, z = _edge_cases()
    expected = _reference_errors(p_i, p_j, z)
    got = np.empty_like(expected)
    for k in range(len(p_i)):
        args = (p_i[k].copy(), p_j[k].copy(), z[k].copy())
        # the result is read as an array of real numbers (complex, text, … are named as such)
        value, problem = call_student(edge_error, *args, name="edge_error")
        if problem is None and value.shape != (3,):
            problem = compare_array(
                value, expected[k], name=f"edge_error(p_i, p_j, z) for edge {k}", angles=True
            )
        if problem is not None:
            if problem != NOT_ATTEMPTED:
                problem += f"\n    (edge {k}: p_i = {args[0]}, p_j = {args[1]}, z = {args[2]})"
            return verdict(
                ex,
                problem,
                hint=("return a numpy array of 3 real numbers (x, y, θ) for one edge.", *_EDGE_HINT),
            )
        got[k] = value  # a wrong value is diagnosed below, on all edges together

    problem = compare_array(got, expected, name="edge_error's output", angles=True)
    if problem is None:
        return verdict(
            ex,
            None,
            correct=f"all {len(got)} edges agree with lagolib.residuals (largest difference "
            f"{np.abs(got - expected).max():.1e}), including the edges with headings near ±π.",
        )
    translation_ok = np.allclose(got[:, :2], expected[:, :2], rtol=1e-7, atol=1e-9)
    if translation_ok and "by multiples of 2π" in problem:
        worst = int(np.argmax(np.abs(got[:, 2] - expected[:, 2])))
        return verdict(
            ex,
            f"your translations are right, but your angle of edge {worst} ({got[worst, 2]:.4f} "
            "rad) differs from lagolib's by a whole turn, 2π. The error's angle must be wrapped "
            "into (−π, π].",
            hint=(
                "which of your edges have headings near ±π? There θ_j − θ_i − θ_z leaves (−π, π].",
                "wrap θ_j − θ_i − θ_z with se2.wrap_angle, or take it from t2v of the matrix "
                "product (t2v uses atan2, which wraps).",
            ),
        )
    if translation_ok and np.allclose(got[:, 2], np.degrees(expected[:, 2]), rtol=1e-7, atol=1e-7):
        return verdict(
            ex,
            "your translations are right, but your angles are in degrees: lagolib (and t2v, "
            "arctan2, se2.wrap_angle) works in radians.",
            hint=("leave the angle in radians, as t2v returns it (no np.degrees).",),
        )
    for candidate, diagnosis in _edge_mistakes(p_i, p_j, z):
        if _matches(got, candidate):
            return verdict(ex, diagnosis, hint=_EDGE_HINT)
    if not translation_ok and np.allclose(got[:, 2], expected[:, 2], rtol=1e-7, atol=1e-9):
        problem = "your angles are right but not your translations.\n    " + problem
    return verdict(ex, problem, hint=_EDGE_HINT)


# --------------------------------------------------------------------------------------------
# Exercise 1.2 — heading noise and the end of a closed loop

OCTAGON_STEP = np.array([1.0, 0.0, np.pi / 4])


def end_distances(step, n, sigma, trials, rng):
    """Distance from the start after composing ``step`` ``n`` times with heading noise ``sigma``.

    Each of the ``n`` steps gets an independent Gaussian heading error of standard deviation
    ``sigma`` (rad) added to its turn; ``trials`` runs at once, vectorized over runs.

    Parameters
    ----------
    step : array_like, shape (3,)
    n : int
    sigma : float
    trials : int
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (trials,)
        The final position's distance from the start of each run.
    """
    p = np.zeros((trials, 3))
    noisy = np.tile(np.asarray(step, dtype=float), (trials, 1))
    for _ in range(n):
        noisy[:, 2] = step[2] + rng.normal(scale=sigma, size=trials)
        p = se2.compose(p, noisy)
    return np.hypot(p[:, 0], p[:, 1])


GROWTH_WITH_SIGMA = ("linear", "quadratic", "square root")


def _nearest_growth(ratio, factor, choices):
    """The choice whose power law (1, 2, ½ / 0, 1, 2) best explains ``ratio`` for ``factor``."""
    powers = {"linear": 1.0, "quadratic": 2.0, "square root": 0.5, "constant": 0.0}
    return min(choices, key=lambda c: abs(np.log(ratio) - powers[c] * np.log(factor)))


def _heading_noise_reference(trials=4000, seed=5):
    rng = np.random.default_rng(seed)
    d8 = end_distances(OCTAGON_STEP, 8, 0.05, trials, rng).mean()
    d80 = end_distances(OCTAGON_STEP / 10, 80, 0.05, trials, rng).mean()
    d8_double = end_distances(OCTAGON_STEP, 8, 0.10, trials, rng).mean()
    return d8, d80, d8_double


@check("1.2", distance_ratio=Real(), growth_with_sigma=Choice(GROWTH_WITH_SIGMA))
def check_heading_noise(distance_ratio, growth_with_sigma) -> bool:
    """Exercise 1.2: heading noise and how far from its start a closed loop ends.

    Compares ``distance_ratio`` — the mean end distance of 80 steps ``step / 10`` divided by that
    of 8 steps ``step`` (``step = (1 m, 0, π/4)``, heading noise σ = 0.05 rad per step) — with
    lagolib's own seeded simulation of 4000 runs each, to 15 % (the student reads it off a few
    hundred runs; the expected value is close to √10), and ``growth_with_sigma`` — how the mean
    end distance grows with σ for small σ, one of :data:`GROWTH_WITH_SIGMA` — with the law that
    the simulation at σ = 0.05 and 0.10 shows.  Prints the simulated numbers with a right
    answer; after a wrong one they are the last hint level (:func:`lagolib.exercises.hint`).

    Parameters
    ----------
    distance_ratio : float
    growth_with_sigma : str

    Returns
    -------
    bool
    """
    ex = "1.2"
    if is_placeholder(distance_ratio) or is_placeholder(growth_with_sigma):
        return verdict(ex, NOT_ATTEMPTED)
    d8, d80, d8_double = _heading_noise_reference()
    ratio = d80 / d8
    expected_growth = _nearest_growth(d8_double / d8, 2.0, GROWTH_WITH_SIGMA)
    facts = (
        f"4000 simulated runs each: σ = 0.05 rad, 8 steps → {d8:.3f} m, 80 steps → {d80:.3f} m "
        f"(ratio {ratio:.2f}, √10 = {np.sqrt(10):.2f}); σ = 0.10 rad, 8 steps → {d8_double:.3f} m "
        f"({d8_double / d8:.2f} times σ = 0.05)."
    )
    problems = []
    problem = compare_choice(
        growth_with_sigma, expected_growth, GROWTH_WITH_SIGMA, name="growth_with_sigma"
    )
    if problem is not None and not problem.startswith("growth_with_sigma should be one of"):
        factor = {"linear": "2", "quadratic": "4", "square root": "√2 ≈ 1.41"}[growth_with_sigma]
        problem = (
            f"growth_with_sigma = {growth_with_sigma!r} is not what the simulation shows: with "
            f"it, doubling σ would multiply the mean end distance by {factor}. Is that what "
            "your table shows?"
        )
    if problem is not None:
        problems.append(problem)
    r = distance_ratio  # read by @check as one finite real number
    if abs(r - ratio) > 0.15 * ratio:
        problem = compare_number(r, ratio, name="distance_ratio", rtol=0.15)
        if abs(r - 10.0) <= 1.5:
            problem += (
                " 10 is the ratio of the numbers of steps, as if the end distance grew in "
                "proportion to them — but the heading errors are independent, and independent "
                "errors partly cancel."
            )
        elif abs(r - 1.0) <= 0.15:
            problem += (
                " The same octagon, but ten times as many independent heading errors: the "
                "robot ends farther away."
            )
        elif abs(r * ratio - 1.0) <= 0.15:
            problem += " You inverted it: divide the 80-step distance by the 8-step one."
        problems.append(problem)
    if problems:
        return verdict(
            ex,
            " ".join(problems),
            hint=(
                "compare the printed means of end_distance for 8 and for 80 steps at σ = 0.05, "
                "and how they change from row to row as σ doubles.",
                "independent heading errors add in variance, not in size: after N steps their "
                "sum has the standard deviation σ√N; and while σ is small, the end position is "
                "to first order a linear function of the heading errors.",
                "the check's own simulation: " + facts,
            ),
        )
    return verdict(ex, None, correct=facts)


# --------------------------------------------------------------------------------------------
# Exercise 1.3 — χ² at the odometry guess and the number of laps

GROWTH_WITH_LAPS = ("constant", "linear", "quadratic")


def chi2_by_laps(max_laps=6, worlds=12, poses_per_lap=40):
    """Mean χ² at the odometry guess of the first ``L`` laps, ``L = 1 … max_laps``.

    ``worlds`` seeded ``simulate.loop_world`` graphs of ``max_laps`` laps (σ_xy = 0.05 m,
    σ_θ = 0.01 rad); the first ``L`` laps of each are its poses ``0 … L·poses_per_lap − 1`` and
    the edges between them, whose odometry guess is the same first poses.

    Returns
    -------
    mean : ndarray, shape (max_laps,)
        Mean χ² over the worlds for ``L = 1 … max_laps`` laps.
    odometric : float
        Largest χ² of the odometric edges alone, over the worlds (≈ 0: rounding).
    """
    table = np.zeros((worlds, max_laps))
    odometric = 0.0
    for seed in range(worlds):
        g = simulate.loop_world(
            laps=max_laps, poses_per_lap=poses_per_lap, sigma_xy=0.05, sigma_theta=0.01, rng=seed
        ).graph
        terms = chi2(g, per_edge=True)
        odometric = max(odometric, float(terms[g.odometric].sum()))
        last = g.edges.max(axis=1)
        for k in range(max_laps):
            table[seed, k] = terms[last < (k + 1) * poses_per_lap].sum()
    return table.mean(axis=0), odometric


@check("1.3", chi2_one_lap=Real(), growth=Choice(GROWTH_WITH_LAPS))
def check_chi2_laps(chi2_one_lap, growth) -> bool:
    """Exercise 1.3: how χ² at the odometry guess grows with the number of laps.

    Computes :func:`chi2_by_laps` (12 seeded 6-lap square worlds) — the mean χ² for 1 … 6 laps,
    printed with a right answer and the last hint level after a wrong one — and compares
    ``chi2_one_lap`` — the predicted χ² of a one-lap world at its odometry guess — with the
    computed value (to 1e-6 absolute: it is zero up to rounding), and ``growth`` — one of
    :data:`GROWTH_WITH_LAPS` — with the power law that the mean χ² of 2 and 6
    laps shows (χ² per lap after the first: constant → linear).

    Parameters
    ----------
    chi2_one_lap : float
    growth : str

    Returns
    -------
    bool
    """
    ex = "1.3"
    if is_placeholder(chi2_one_lap) or is_placeholder(growth):
        return verdict(ex, NOT_ATTEMPTED)
    mean, odometric = chi2_by_laps()
    # with L laps there are L − 1 laps of loop closures: compare 5 (6 laps) with 1 (2 laps)
    expected_growth = _nearest_growth(mean[5] / mean[1], 5.0, GROWTH_WITH_LAPS)
    table = "; ".join(f"{k + 1} lap{'s' if k else ''}: {c:.4g}" for k, c in enumerate(mean))
    facts = (
        f"mean χ² at the odometry guess over 12 worlds — {table}; per lap after the first: "
        + ", ".join(f"{mean[k] / k:.0f}" for k in range(1, len(mean)))
        + f"; odometric edges alone ≤ {odometric:.1e}."
    )
    problems = []
    value = chi2_one_lap  # read by @check as one finite real number
    if abs(value - mean[0]) > 1e-6:
        problems.append(
            f"chi2_one_lap = {value:.4g}: χ² is a sum of squares, it cannot be negative."
            if value < 0
            else f"chi2_one_lap = {value:.4g} is too large (the check allows 1e-6 for rounding)."
        )
    problem = compare_choice(growth, expected_growth, GROWTH_WITH_LAPS, name="growth")
    if problem is not None and not problem.startswith("growth should be one of"):
        meaning = {
            "constant": "every lap after the first would add nothing",
            "linear": "every lap after the first would add about the same",
            "quadratic": "every lap would add more than the one before",
        }[growth]
        problem = (
            f"growth = {growth!r} is not what the 12 simulated worlds show ({meaning})."
        )
    if problem is not None:
        problems.append(problem)
    if problems:
        return verdict(
            ex,
            " ".join(problems),
            hint=(
                "which edges does the odometry guess satisfy, and what does a loop closure "
                "compare?",
                "the odometry guess composes the odometric measurements, so every odometric "
                "error is zero there; a loop closure joins a pose to the same place one lap "
                "earlier, so its error is the drift of one lap, not of the whole trajectory.",
                "the check's own numbers: " + facts,
            ),
        )
    return verdict(ex, None, correct=facts)


# --------------------------------------------------------------------------------------------
# Exercise 1.4 — the information in a TORO file


def toro_file_information(graph):
    """The information matrices as written in ``graph``'s TORO file, shape (m, 3, 3).

    Writes the graph with :func:`lagolib.write_toro` into a temporary folder and parses the
    ``EDGE2 i j dx dy dθ I11 I12 I22 I33 I13 I23`` lines (the frame-i convention).
    """
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "graph.graph"
        write_toro(graph, path)
        rows = [
            line.split()[6:12]
            for line in path.read_text().splitlines()
            if line.startswith("EDGE2 ")
        ]
    i11, i12, i22, i33, i13, i23 = np.array(rows, dtype=float).T
    return np.stack(
        [
            np.stack([i11, i12, i13], axis=-1),
            np.stack([i12, i22, i23], axis=-1),
            np.stack([i13, i23, i33], axis=-1),
        ],
        axis=1,
    )


def _toro_graphs(seed=3):
    """The chapter's square world (isotropic information) and the same graph with each edge's
    translational information anisotropic (400 and 25 along a random direction)."""
    g = simulate.loop_world(
        laps=2, poses_per_lap=16, sigma_xy=0.05, sigma_theta=0.01, rng=seed
    ).graph
    rng = np.random.default_rng(seed)
    Q = se2.rotation(rng.uniform(-np.pi, np.pi, g.m))
    aniso = np.zeros((g.m, 3, 3))
    aniso[:, :2, :2] = Q @ np.diag([400.0, 25.0]) @ np.swapaxes(Q, 1, 2)
    aniso[:, 2, 2] = 1e4
    h = PoseGraph(g.poses, g.edges, g.measurements, aniso)
    return g, h


def _relative_change(a, b):
    """Largest ``|a − b|`` relative to the largest translational entry of ``b`` (m, 3, 3)."""
    return float(np.abs(a - b).max() / np.abs(b[:, :2, :2]).max())


@check("1.4", same_isotropic=Bool(), same_anisotropic=Bool())
def check_toro_frames(same_isotropic, same_anisotropic) -> bool:
    """Exercise 1.4: does a TORO file hold the same information matrices as the g2o file?

    Writes two seeded 2-lap square worlds with :func:`lagolib.write_toro` — one with isotropic
    translational information (``diag(400, 400, 1e4)``, as in the chapter), one with
    anisotropic, rotated information (400 and 25 along a random direction per edge) — reads the
    matrices in the files, and compares the predictions ``same_isotropic`` / ``same_anisotropic``
    (True if the TORO file holds the same matrices as lagolib's g2o-convention ones, up to
    rounding, 1e-9 relative) with what the files hold.  The largest relative changes are printed
    with a right answer, and are the last hint level after a wrong one.

    Parameters
    ----------
    same_isotropic, same_anisotropic : bool

    Returns
    -------
    bool
    """
    ex = "1.4"
    if is_placeholder(same_isotropic) or is_placeholder(same_anisotropic):
        return verdict(ex, NOT_ATTEMPTED)
    iso, aniso = _toro_graphs()
    change_iso = _relative_change(toro_file_information(iso), iso.information)
    change_aniso = _relative_change(toro_file_information(aniso), aniso.information)
    facts = (
        f"largest difference between the TORO file's and the g2o information matrices, "
        f"relative to their largest translational entry: "
        f"isotropic {change_iso:.1e}, anisotropic {change_aniso:.2f}."
    )
    problems, whys = [], []
    for name, got, change, why_same, why_not in [
        (
            "same_isotropic",
            same_isotropic,
            change_iso,
            "a rotation leaves an isotropic block unchanged: R(θ_z) (a I₂) R(θ_z)ᵀ = a I₂.",
            "",
        ),
        (
            "same_anisotropic",
            same_anisotropic,
            change_aniso,
            "",
            "the conversion G Ω Gᵀ, G = blockdiag(R(θ_z), 1), turns an anisotropic block's "
            "principal axes by the measured angle θ_z, so its numbers change.",
        ),
    ]:
        expected = change <= 1e-9
        problem = compare_choice(got, expected, (True, False), name=name)
        if problem is not None and problem.endswith(WRONG_CHOICE):
            problem = f"{name} = {got!r} is not what the TORO file holds."
            whys.append(why_same if expected else why_not)
        if problem is not None:
            problems.append(problem)
    if problems:
        return verdict(
            ex,
            " ".join(problems),
            hint=(
                "what does the rotation G = blockdiag(R(θ_z), 1) do to a I₂, and to "
                "diag(400, 25)?",
                " ".join(w for w in whys if w)
                or "G Ω Gᵀ rotates the translational block by θ_z: work it out for a I₂ and for "
                "diag(400, 25).",
                "what the check read in the files: " + facts,
            ),
        )
    return verdict(ex, None, correct=facts)
