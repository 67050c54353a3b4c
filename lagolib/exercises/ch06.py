"""Checks for the exercises of chapter 6 (LAGO, Carlone et al. 2011), and the world they use.

=========  =========  ==========================================================================
exercise   kind       check
=========  =========  ==========================================================================
6.1        implement  :func:`check_frame_i` — one edge's information, g2o frame → frame ``i``
6.2        implement  :func:`check_phase2_edge` — phase 2 for one edge (eq. 9–11)
6.3        predict    :func:`check_closer` — isotropic or anisotropic: where is LAGO closer to
                      the Gauss–Newton optimum?
6.4        explore    :func:`check_anisotropy_sweep` — LAGO's χ² gap and map error against the
                      anisotropy ratio of the position information
=========  =========  ==========================================================================

:func:`anisotropic_loop` builds the chapter's test world (section 1 of the chapter is
``anisotropic_loop(8.0)``) with any anisotropy ratio, so that exercises 6.3 and 6.4 and their
checks look at the same graphs.

Every check prints one line, ``Exercise 6.k — correct: …``, ``— not yet: …`` (what is wrong and by
how much, never the answer; ``hint(…)`` tells more, one level per call) or
``— not attempted yet: …``, and returns True or False; it never raises on
a wrong answer (see :mod:`lagolib.exercises._feedback`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from lagolib import PoseGraph, chi2, lago_solve, optimize, se2, simulate
from lagolib import lago as L
from lagolib.checks import check_int, check_real
from lagolib.exercises._coerce import Bool, Choice, Function, Real, RealArray, Tuple
from lagolib.exercises._feedback import (
    NOT_ATTEMPTED,
    call_student,
    check,
    compare_array,
    compare_choice,
    compare_number,
    is_placeholder,
    verdict,
)

__all__ = [
    "anisotropic_loop",
    "check_frame_i",
    "check_phase2_edge",
    "check_closer",
    "check_anisotropy_sweep",
    "SWEEP_RATIOS",
    "INFORMATION_SYMBOLS",
    "world_information_reference",
    "check_world_information",
]

#: The anisotropy ratios of exercise 6.4's sweep (σ_across / σ_along).
SWEEP_RATIOS = (1, 2, 4, 8, 16, 32, 64)
_AREA_SIGMA = float(np.sqrt(0.02 * 0.16))  # m: σ_along σ_across = 0.02 · 0.16 m², as in section 1
_S = np.array([[0.0, -1.0], [1.0, 0.0]])  # dR/dθ = S R


# --------------------------------------------------------------------------- the chapter's world
def anisotropic_loop(ratio=8.0, *, sigma_theta=0.02, seed=7):
    """Chapter 6's world: three laps of a square with anisotropic, rotated position information.

    48 poses, 16 per lap, 47 odometry edges and 32 loop closures
    (:func:`lagolib.simulate.loop_world`).  Each edge's position covariance is an ellipse with
    standard deviations ``a / sqrt(ratio)`` along and ``a * sqrt(ratio)`` across a direction drawn
    uniformly at random, ``a = sqrt(0.02 · 0.16)`` m, so every ellipse has the same area whatever
    the ratio; the heading has standard deviation ``sigma_theta``.  The noise is drawn from exactly
    that covariance, from the same standard normal draws for every ratio.  ``ratio=8`` with the
    defaults is the graph of the chapter's section 1 (0.02 m along, 0.16 m across); ``ratio=1``
    is its isotropic twin.

    Parameters
    ----------
    ratio : float
        ``σ_across / σ_along`` of the position ellipse, ``>= 1``.
    sigma_theta : float
        Heading standard deviation in rad, ``> 0``.
    seed : int
        Seed of the random directions and of the noise.

    Returns
    -------
    lagolib.simulate.Simulation
        ``graph`` (information in the g2o frame, poses = the odometry guess) and ``truth``.

    Examples
    --------
    >>> sim = anisotropic_loop(8.0)
    >>> sim.graph.n, sim.graph.m
    (48, 79)
    >>> import numpy as np
    >>> lam = np.linalg.eigvalsh(np.linalg.inv(sim.graph.information[0])[:2, :2])
    >>> np.round(np.sqrt(lam), 6)
    array([0.02, 0.16])
    """
    where = "anisotropic_loop"
    ratio = check_real(ratio, "ratio", where, minimum=1.0)
    sigma_theta = check_real(sigma_theta, "sigma_theta", where, minimum=0.0, strict=True)
    seed = check_int(seed, "seed", where, minimum=0)
    world = simulate.loop_world(laps=3, poses_per_lap=16, noiseless=True)
    truth, edges = world.truth, world.graph.edges
    m = len(edges)
    rng = np.random.default_rng(seed)
    axis = se2.rotation(rng.uniform(-np.pi, np.pi, m))  # each sensor's precise direction
    sigmas = _AREA_SIGMA * np.array([1.0 / np.sqrt(ratio), np.sqrt(ratio)])
    cov_pos = axis @ np.diag(sigmas**2) @ np.swapaxes(axis, 1, 2)
    info = np.zeros((m, 3, 3))
    info[:, :2, :2] = np.linalg.inv(cov_pos)
    info[:, 2, 2] = 1.0 / sigma_theta**2
    white = rng.standard_normal((m, 2))
    e = np.column_stack(
        [
            np.einsum("kab,kb->ka", np.linalg.cholesky(cov_pos), white),
            sigma_theta * rng.standard_normal(m),
        ]
    )
    # e = t2v(Z^-1 X_i^-1 X_j), so Z = (X_i^-1 X_j) ⊕ e^-1
    z = se2.compose(se2.between(truth[edges[:, 0]], truth[edges[:, 1]]), se2.inverse(e))
    g = PoseGraph(np.zeros_like(truth), edges, z, info)
    return simulate.Simulation(g.with_poses(g.odometry_guess()), truth)


def _lago_gap(graph):
    """How far LAGO lands from the Gauss–Newton optimum it initializes.

    Parameters
    ----------
    graph : PoseGraph

    Returns
    -------
    gap : float
        ``χ²(LAGO) − χ²(optimum)``, the optimum by :func:`lagolib.optimize` started from LAGO.
    distance : float
        The largest distance between a LAGO position and the optimum's, in the graph's units.
    """
    lg = lago_solve(graph, margin_warning=0)
    gn = optimize(graph, lg.poses)
    gap = chi2(graph, lg.poses) - gn.chi2
    distance = np.linalg.norm(lg.poses[:, :2] - gn.poses[:, :2], axis=1).max()
    return float(gap), float(distance)


@lru_cache(maxsize=64)
def _gap(ratio, sigma_theta=0.02, seed=7):
    return _lago_gap(anisotropic_loop(ratio, sigma_theta=sigma_theta, seed=seed).graph)


def _rotation_block(theta):
    G = np.eye(3)
    G[:2, :2] = se2.rotation(theta)
    return G


def _close(a, b, rtol=1e-7, atol=1e-9):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= atol + rtol * np.abs(b)))


# --------------------------------------------------------------------------- exercise 6.1
def _frame_cases():
    """Seeded g2o-frame informations: full 3×3, rotated, anisotropic, position–heading correlated."""
    rng = np.random.default_rng(601)
    thetas = np.array([np.pi / 2 + 0.045, -2.4, 0.35, 3.0, -0.9])
    cases = []
    for theta_z in thetas:
        Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        P = Q @ np.diag([0.02**2, 0.2**2, 0.05**2]) @ Q.T  # covariance, every entry non-zero
        Omega = np.linalg.inv(P)
        cases.append((0.5 * (Omega + Omega.T), float(theta_z)))
    return cases


def _diagnose_frame(got, Omega, theta_z, expected):
    """The sentence saying what is wrong with ``got`` (not equal to ``expected``), and the hint
    levels (a tuple)."""
    problem = compare_array(got, expected, name="your matrix")
    if problem is None:
        return None, ""
    hint = (
        "try your function on θ_z = π/2 and Ω = diag(100, 1, 10): rotating the frame by a "
        "quarter turn, the 100 must move to the y entry.",
        "G = blockdiag(R(θ_z), 1) is 3×3: the rotation by θ_z acts on x and y, the heading is "
        "left alone; and an information matrix rotates on both sides, G Ω Gᵀ.",
        "build G from np.eye(3) with se2.rotation(θ_z) in its top-left 2×2 block, then "
        "multiply G, Ω and Gᵀ in that order.",
    )
    if got.shape == (2, 2):
        return problem, (
            "return the whole 3×3 information: the heading row and column too.",
            *hint[1:],
        )
    if got.shape != (3, 3):
        return problem, hint
    g = got  # a float array: call_student read it
    G = _rotation_block(theta_z)
    if _close(g, np.linalg.inv(expected), rtol=1e-6):
        return (
            "your matrix is G Ω⁻¹ Gᵀ — the covariance in frame i, not the information. The "
            "exercise asks for the information, which rotates the same way: G Ω Gᵀ.",
            ("no inverse is needed: rotating a covariance or an information is the same "
             "product.", *hint[1:]),
        )
    if (
        np.allclose(g[:2, 2], 0.0, atol=1e-9)
        and np.allclose(g[2, :2], 0.0, atol=1e-9)
        and not np.allclose(expected[:2, 2], 0.0, atol=1e-9)
    ):
        return (
            "your matrix has zeros in its position–heading entries [:2, 2] and [2, :2], but "
            "this Ω correlates position and heading and G Ω Gᵀ keeps that correlation. (Dropping "
            "it is the next step, split_information — not this one.)",
            ("convert the whole 3×3 matrix; nothing is dropped in a change of frame.",
             *hint[1:]),
        )
    if _close(g, G.T @ Omega @ G):
        return (
            "your matrix is Gᵀ Ω G — the conversion the other way, frame i → g2o "
            "(se2.information_from_frame_i); you rotated by −θ_z.",
            ("the g2o error is e = Gᵀ r (r the frame-i residual), so eᵀ Ω e = rᵀ (G Ω Gᵀ) r.",
             *hint[1:]),
        )
    if _close(g, G @ Omega) or _close(g, Omega @ G.T) or _close(g, G.T @ Omega):
        return (
            "your matrix is not symmetric: G was applied on one side only. An information "
            "matrix rotates on both sides.",
            hint,
        )
    if _close(g, Omega):
        return (
            "your matrix is Ω unchanged — still the g2o frame; nothing was rotated.",
            hint,
        )
    if not np.isclose(g[2, 2], Omega[2, 2], rtol=1e-7, atol=1e-9):
        return (
            f"the heading entry [2, 2] changed from Ω's {Omega[2, 2]:.6g} to {g[2, 2]:.6g}. A "
            "change of frame in the plane rotates x and y only; the θ row and column are "
            "not rotated into anything.",
            ("G's bottom-right entry is 1 and the rest of its last row and column is 0.",
             *hint[1:]),
        )
    # rotated by some other angle phi?  The cross terms rotate by it: g[:2, 2] = R(phi) Omega[:2, 2]
    a, b = Omega[:2, 2], g[:2, 2]
    if np.linalg.norm(a) > 0:
        phi = float(np.arctan2(a[0] * b[1] - a[1] * b[0], a @ b))
        Gp = _rotation_block(phi)
        if _close(g, Gp @ Omega @ Gp.T):
            if np.isclose(se2.wrap_angle(phi - np.deg2rad(theta_z)), 0.0, atol=1e-9):
                why = " — θ_z is already in radians (it was converted as if in degrees)"
            elif np.isclose(se2.wrap_angle(phi - 2 * theta_z), 0.0, atol=1e-9):
                why = " — twice θ_z: rotated twice?"
            else:
                why = ""
            return (
                f"your matrix is Ω rotated by {phi:+.4f} rad, but the measured angle is "
                f"θ_z = {theta_z:+.4f} rad{why}" + ("" if why.endswith("?") else "."),
                ("rotate by θ_z itself, the measurement's angle (not the pose's), in radians.",
                 *hint[1:]),
            )
    ref_xy = expected[:2, :2]
    if _close(g[:2, :2], ref_xy) and _close(g[:2, 2], Omega[:2, 2]):
        return (
            "the position block is right, but the position–heading entries [:2, 2] and [2, :2] "
            "were left as in Ω. G rotates them too: (G Ω Gᵀ)[:2, 2] = R(θ_z) Ω[:2, 2].",
            ("build the whole 3×3 G and rotate the whole Ω with it, instead of rotating the "
             "2×2 block alone.", *hint[2:]),
        )
    return problem, hint


@check("6.1", to_frame_i=Function(RealArray((3, 3))))
def check_frame_i(to_frame_i):
    """Check exercise 6.1: ``to_frame_i(Omega, theta_z)``, one edge's information in frame ``i``.

    Calls the student's function on five seeded 3×3 informations in the g2o frame — full,
    anisotropic, rotated, with position–heading correlation — and measured angles in all four
    quadrants, and compares each result with :func:`lagolib.se2.information_to_frame_i`
    (``G Ω Gᵀ``, ``G = blockdiag(R(θ_z), 1)``).  Diagnoses ``Gᵀ Ω G``, the frame-``i``
    covariance ``G Ω⁻¹ Gᵀ``, dropped position–heading entries, a one-sided product, an unrotated
    ``Ω``, a changed heading entry, a wrong angle (also degrees, twice the angle) and unrotated
    cross terms.

    Parameters
    ----------
    to_frame_i : callable
        ``(Omega (3, 3), theta_z float) -> (3, 3)``.

    Returns
    -------
    bool
    """
    ex = "6.1"
    cases = _frame_cases()
    for k, (Omega, theta_z) in enumerate(cases):
        got, problem = call_student(to_frame_i, Omega.copy(), theta_z, name="to_frame_i")
        if problem == NOT_ATTEMPTED:
            return verdict(ex, problem)
        if problem is not None:
            return verdict(
                ex,
                problem,
                hint="the check calls to_frame_i(Omega, theta_z) with Omega a (3, 3) array and "
                "theta_z a float, and expects a (3, 3) array of real numbers back; try your "
                "function on such inputs.",
            )
        expected = se2.information_to_frame_i(Omega[None], [theta_z])[0]
        problem, hint = _diagnose_frame(got, Omega, theta_z, expected)
        if problem is not None:
            where = f"for θ_z = {theta_z:+.4f} rad (test {k + 1} of {len(cases)}): "
            return verdict(ex, where + problem, hint=hint)
    return verdict(
        ex,
        None,
        correct=f"G Ω Gᵀ on all {len(cases)} anisotropic, rotated test informations, "
        "θ_z in all four quadrants, equal to lagolib.se2.information_to_frame_i.",
    )


# --------------------------------------------------------------------------- exercise 6.2
@lru_cache(maxsize=1)
def _phase2_reference():
    """Seeded anisotropic world (not the chapter's draw) and lagolib's phase 2 on it."""
    g = anisotropic_loop(8.0, seed=2011).graph
    Omega_Delta, omega_delta = L.split_information(g)
    reg = L.regularize(g, margin_warning=0)
    p1 = L.phase1_orientations(g, reg.delta_bar, omega_delta=omega_delta)
    p2 = L.phase2_relative_positions(g, p1, Omega_Delta=Omega_Delta)
    theta = np.zeros(g.n)
    theta[1:] = p1.estimate  # the anchor is vertex row 0
    J = p2.J.toarray()
    W = p2.W.toarray()
    rows = []
    for k, (i, j) in enumerate(g.edges):
        if i == 0:  # edges leaving the anchor have no θ column
            continue
        s = slice(2 * k, 2 * k + 2)
        rows.append(
            (
                k,
                int(i),
                int(j),
                float(theta[i]),
                g.measurements[k, :2].copy(),
                Omega_Delta[k].copy(),
                p2.Delta_g[k].copy(),
                J[s, i - 1].copy(),
                W[s, s].copy(),
            )
        )
    # edges whose θ̂_i is near ±π/2 first: there R(θ̂_i) and its transpose differ most
    rows.sort(key=lambda r: -abs(np.sin(r[3])))
    return tuple(rows)


def _diagnose_phase2(out, theta_i, Delta_l, Omega_Delta, Dg, Jr, Wr):
    """What is wrong with ``out = (Delta_g, J, W)``: (problem, hint), or (None, "")."""
    R = se2.rotation(theta_i)
    got_Dg, got_J, got_W = out  # three float arrays: call_student read them
    # Δ^g, eq. (9)
    problem = compare_array(got_Dg, Dg, name="Delta_g")
    if problem is not None:
        if _close(got_Dg, Delta_l):
            problem = "Delta_g equals Δ^l: it is still in frame i."
        elif _close(got_Dg, R.T @ Delta_l):
            problem = "Delta_g is R(θ̂_i)ᵀ Δ^l: rotated the wrong way (by −θ̂_i)."
        return problem, (
            "Δ^l is measured in the frame of pose i; Δ^g is the same vector in the world frame.",
            "Δ^g = R(θ̂_i) Δ^l (eq. 9), with se2.rotation(theta_i) — θ̂_i may be several turns, "
            "which the rotation does not mind.",
        )
    # J = ∂Δ^g/∂θ_i, eq. (11)
    problem = compare_array(got_J, Jr, name="J")
    if problem is not None:
        hint = (
            "J is the derivative of Δ^g = R(θ) Δ^l by θ at θ̂_i: only R(θ) depends on θ.",
            "differentiate R(θ) entry by entry and compare with S R(θ), S = [[0, -1], [1, 0]] "
            "(eq. 11); then ask which vector the derivative of R(θ) Δ^l multiplies — a 2-vector.",
            "dR/dθ = S R(θ), so J = S R(θ̂_i) Δ^l: S applied to a vector you already have.",
        )
        if _close(got_J, -Jr):
            problem = "J has the opposite sign of the reference: check the sign of S (or of sin)."
        elif _close(got_J, _S @ Delta_l):
            problem = "J is S Δ^l — the derivative of a frame-i vector; Δ^g is in the world frame."
        elif _close(got_J, Dg):
            problem = "J equals Δ^g itself: the derivative of a rotation is missing its S."
        return problem, hint
    # W = P_Δg^-1 = R P_Δ^-1 Rᵀ, eq. (10)
    problem = compare_array(got_W, Wr, name="W")
    if problem is not None:
        hint = (
            "W is an information matrix in the world frame: the inverse of the covariance "
            "P_Δg = R(θ̂_i) P_Δ R(θ̂_i)ᵀ (section 3).",
            "with R⁻¹ = Rᵀ the inverse of R P_Δ Rᵀ is again a rotated matrix, and no matrix "
            "needs inverting: Ω_Δ = P_Δ⁻¹ is given.",
            "W = (R P_Δ Rᵀ)⁻¹ = R P_Δ⁻¹ Rᵀ: rotate Ω_Δ on both sides, R on the left, Rᵀ on the "
            "right.",
        )
        if _close(got_W, Omega_Delta):
            problem = "W equals Ω_Δ: it is still the frame-i information."
        elif _close(got_W, R.T @ Omega_Delta @ R):
            problem = "W is Rᵀ Ω_Δ R: rotated the wrong way (by −θ̂_i)."
        elif _close(got_W, np.linalg.inv(Wr), rtol=1e-6):
            problem = "W is the covariance P_Δg; phase 2 keeps the information W = P_Δg⁻¹."
        return problem, hint
    return None, ""


_PHASE2 = Tuple(
    RealArray((2,)),
    RealArray((2,)),
    RealArray((2, 2)),
    names=("Delta_g", "J", "W"),
    what="three arrays, (Delta_g, J, W)",
    hint="end the function with `return Delta_g, J, W`.",
)


@check("6.2", phase2_edge=Function(_PHASE2))
def check_phase2_edge(phase2_edge):
    """Check exercise 6.2: ``phase2_edge(theta_i, Delta_l, Omega_Delta)``, phase 2 for one edge.

    On a seeded anisotropic three-lap world (``anisotropic_loop(8.0, seed=2011)``, not the
    chapter's draw) lagolib runs phases 1 and 2 (:func:`lagolib.lago.phase2_relative_positions`);
    for every edge not leaving the anchor the student's function gets ``θ̂_i`` (unwrapped, up to
    three turns), ``Δ^l_ij`` (2,) and ``Ω_Δ`` (2, 2, frame ``i``, from
    :func:`lagolib.lago.split_information`), and its ``(Delta_g, J, W)`` is compared with that
    edge's ``Δ^g`` (eq. 9), its 2-vector of ``J`` (eq. 11) and its 2×2 block of ``W = P_Δg⁻¹``
    (eq. 10).  Diagnoses an unrotated or inversely rotated vector or matrix, a sign flip or a
    frame-``i`` derivative in ``J``, and a covariance in place of ``W``.

    Parameters
    ----------
    phase2_edge : callable
        ``(theta_i float, Delta_l (2,), Omega_Delta (2, 2)) -> (Delta_g (2,), J (2,), W (2, 2))``.

    Returns
    -------
    bool
    """
    ex = "6.2"
    rows = _phase2_reference()
    for k, i, j, theta_i, Delta_l, Omega_Delta, Dg, Jr, Wr in rows:
        out, problem = call_student(
            phase2_edge, theta_i, Delta_l.copy(), Omega_Delta.copy(), name="phase2_edge"
        )
        if problem == NOT_ATTEMPTED:
            return verdict(ex, problem)
        if problem is not None:
            return verdict(
                ex,
                f"edge {k} ({i} -> {j}), θ̂_i = {theta_i:+.4f} rad: {problem}",
                hint="the check calls phase2_edge(theta_i, Delta_l, Omega_Delta) with a float, "
                "a (2,) and a (2, 2) array, and expects `return Delta_g, J, W` (arrays of real "
                "numbers of shapes (2,), (2,), (2, 2)); try your function on such inputs.",
            )
        problem, hint = _diagnose_phase2(out, theta_i, Delta_l, Omega_Delta, Dg, Jr, Wr)
        if problem is not None:
            where = f"edge {k} ({i} -> {j}), θ̂_i = {theta_i:+.4f} rad: "
            return verdict(ex, where + problem, hint=hint)
    return verdict(
        ex,
        None,
        correct=f"Δ^g, J and W agree with lagolib's phase 2 on all {len(rows)} edges "
        "(θ̂_i up to three turns, anisotropic information).",
    )


# --------------------------------------------------------------------------- exercise 6.3
CLOSER_CHOICES = ("isotropic", "anisotropic", "same")


@check("6.3", closer=Choice(CLOSER_CHOICES))
def check_closer(closer):
    """Check exercise 6.3: on which graph does LAGO land closer to the Gauss–Newton optimum?

    Computes LAGO and Gauss–Newton from it (``_lago_gap``) on ``anisotropic_loop(1.0)`` (the
    isotropic twin) and ``anisotropic_loop(8.0)`` (section 1's graph): same robot, same noise
    draws, same ellipse areas.  The gap is ``χ²(LAGO) − χ²(optimum)``; the answer is the graph
    with the smaller gap (``"same"`` if they are within 1 %).  Prints both gaps with a right
    answer; after a wrong one they are the last hint level.

    Parameters
    ----------
    closer : {"isotropic", "anisotropic", "same"}

    Returns
    -------
    bool
    """
    ex = "6.3"
    if is_placeholder(closer):
        return verdict(ex, NOT_ATTEMPTED)
    iso, _ = _gap(1.0)
    aniso, _ = _gap(8.0)
    if abs(iso - aniso) <= 0.01 * max(iso, aniso):
        expected = "same"
    else:
        expected = "isotropic" if iso < aniso else "anisotropic"
    facts = (
        f"LAGO's χ² lies {iso:.3g} above the Gauss–Newton optimum on the isotropic graph and "
        f"{aniso:.3g} above it on the anisotropic one ({max(iso, aniso) / min(iso, aniso):.3g} "
        "times more" + (" on the anisotropic one)." if aniso > iso else " on the isotropic one).")
    )
    problem = compare_choice(closer, expected, CLOSER_CHOICES, name="closer")
    if problem is None:
        return verdict(ex, None, correct=facts)
    if problem.startswith("closer should be"):
        return verdict(ex, problem, hint='write closer = "isotropic", "anisotropic" or "same".')
    return verdict(
        ex,
        f"closer = {closer!r} is not where LAGO lands closer to the Gauss–Newton optimum.",
        hint=(
            "think of Theorem 1: LAGO is exact when the weights it holds fixed do not depend on "
            "the orientations.",
            "eq. (18) holds the weights (R̂ P_Δ R̂ᵀ)⁻¹ at θ̂, while the true cost rotates "
            "them with θ. For which P_Δ does rotating it change nothing?",
            "the check's numbers: " + facts,
        ),
    )


# --------------------------------------------------------------------------- exercise 6.4
def _sweep():
    gaps, dists = zip(*(_gap(float(r)) for r in SWEEP_RATIOS))
    return np.array(gaps), np.array(dists)


@check("6.4", gap_grows=Bool(), distance_grows=Bool(), gap_ratio=Real())
def check_anisotropy_sweep(gap_grows, distance_grows, gap_ratio):
    """Check exercise 6.4: what the anisotropy sweep shows.

    Recomputes the sweep as the chapter gives it — ``anisotropic_loop(ratio)`` for the ratios in
    :data:`SWEEP_RATIOS`, seed 7, heading noise 0.02 rad — with ``_lago_gap``, and compares:

    * ``gap_grows`` — does the χ² gap (LAGO − optimum) grow at every step of the sweep?
    * ``distance_grows`` — does LAGO's largest distance from the optimum grow at every step?
    * ``gap_ratio`` — the gap at ratio 64 divided by the gap at ratio 1 (5 % tolerance, as read
      from the printed table).

    Parameters
    ----------
    gap_grows, distance_grows : bool
    gap_ratio : float

    Returns
    -------
    bool
    """
    ex = "6.4"
    answers = (gap_grows, distance_grows, gap_ratio)
    if any(is_placeholder(a) for a in answers):
        return verdict(ex, NOT_ATTEMPTED)
    gaps, dists = _sweep()
    exp_gap = bool(np.all(np.diff(gaps) > 0))
    exp_dist = bool(np.all(np.diff(dists) > 0))
    ratio = float(gaps[-1] / gaps[0])
    gap_txt = " → ".join(f"{v:.3g}" for v in gaps)
    dist_txt = " → ".join(f"{1e3 * v:.1f}" for v in dists)
    if bool(gap_grows) != exp_gap:
        return verdict(
            ex,
            f"gap_grows = {bool(gap_grows)} is not what the sweep shows: 'grows' means larger "
            "at every step, from each ratio to the next.",
            hint=(
                "compare each gap printed by the sweep cell with the one before it.",
                f"the check's χ² gaps over the ratios {list(SWEEP_RATIOS)}: {gap_txt}.",
            ),
        )
    if bool(distance_grows) != exp_dist:
        steps = np.flatnonzero(np.diff(dists) <= 0)
        return verdict(
            ex,
            f"distance_grows = {bool(distance_grows)} is not what the sweep shows: 'grows' "
            "means larger at every step, from each ratio to the next.",
            hint=(
                "read the right panel (or the distance column) from left to right.",
                f"the check's largest distances [mm] over the ratios {list(SWEEP_RATIOS)}: "
                f"{dist_txt}"
                + (
                    f" — it falls from ratio {SWEEP_RATIOS[steps[0]]} to "
                    f"{SWEEP_RATIOS[steps[0] + 1]}."
                    if steps.size
                    else "."
                ),
            ),
        )
    problem = compare_number(gap_ratio, ratio, name="gap_ratio", rtol=0.05)
    if problem is not None:
        hint = (
            "gap_ratio is the gap at ratio 64 divided by the gap at ratio 1 — the last row of "
            "the table over the first.",
            f"the check's χ² gaps over the ratios {list(SWEEP_RATIOS)}: {gap_txt}.",
        )
        got = gap_ratio  # read by @check as one finite real number
        if abs(got * ratio - 1) <= 0.05:
            problem += " It is the inverse of the reference."
        else:
            # which two gaps of the table did the student divide?
            pairs = [
                (a, b)
                for a in range(len(gaps))
                for b in range(len(gaps))
                if a != b and abs(got / (gaps[a] / gaps[b]) - 1) <= 0.05
            ]
            if pairs:
                a, b = pairs[0]
                problem += (
                    f" That is the gap at ratio {SWEEP_RATIOS[a]} divided by the gap at ratio "
                    f"{SWEEP_RATIOS[b]}."
                )
        return verdict(ex, problem, hint=hint)
    return verdict(
        ex,
        None,
        correct=f"the χ² gap grows at every step ({gap_txt}), {ratio:.3g} times from ratio 1 to "
        f"64, while the largest distance from the optimum [mm] goes {dist_txt}.",
    )


# --- derive exercises ---
# Exercise 6.5 (derive) — :func:`check_world_information`: the off-diagonal entry W_xy of an edge's
# position information carried into the world frame by phase 2, W = R(θ) diag(a, b) R(θ)^T
# (Carlone et al. 2011, §IV-C: P_Δg = R̂ P_Δl R̂^T, whose inverse rotates the same way), as a
# formula in a, b and θ.

import sympy as _sp  # noqa: E402

from lagolib import symbolic as _symbolic  # noqa: E402
from lagolib.exercises._derive import Formula, formula_comparison  # noqa: E402

#: exercise 6.5's symbols: the information along x_i and y_i (a, b > 0), and θ = θ̂_i
INFORMATION_SYMBOLS = (*_sp.symbols("a b", positive=True), _sp.Symbol("theta", real=True))


def world_information_reference():
    """``W_xy``: entry (1, 2) of ``W = R(θ) diag(a, b) R(θ)^T`` (phase 2's ``P_Δg^-1``).

    ``R(θ)`` is the rotation block of :func:`lagolib.symbolic.v2t`; sympy multiplies the three
    matrices.
    """
    a, b, theta = INFORMATION_SYMBOLS
    R = _symbolic.v2t((0, 0, theta))[:2, :2]
    return _sp.factor(_sp.expand((R * _sp.diag(a, b) * R.T)[0, 1]))


def _world_information_slips():
    """Known wrong answers of exercise 6.5 and the sentence that names each."""
    a, b, theta = INFORMATION_SYMBOLS
    R = _symbolic.v2t((0, 0, theta))[:2, :2]
    backwards = (R.T * _sp.diag(a, b) * R)[0, 1]
    covariance = (R * _sp.diag(1 / a, 1 / b) * R.T)[0, 1]
    return [
        (
            backwards,
            "that is the entry of R(θ)^T diag(a, b) R(θ): the rotation the other way round, "
            "world → frame i. Phase 2 carries frame i into the world.",
        ),
        (
            covariance,
            "that is the entry of the rotated covariance R diag(1/a, 1/b) R^T; the exercise asks "
            "for the information, which rotates the same way without any inverse.",
        ),
        (
            (R * _sp.diag(a, b) * R.T)[0, 0],
            "that is W_xx, the diagonal entry in row 1; the exercise asks for the off-diagonal "
            "entry W_xy (row 1, column 2).",
        ),
    ]


_WORLD_INFORMATION_HINTS = (
    "W = R(θ) diag(a, b) R(θ)^T, as in exercise 6.2 (information rotates like covariance). "
    "Multiply the three 2×2 matrices and take row 1, column 2 — or let sympy do it with "
    "sp.Matrix and sp.diag.",
    "R(θ) diag(a, b) = [[a cos θ, −b sin θ], [a sin θ, b cos θ]]; W_xy is its first row times "
    "the second column of R(θ)^T, which is (sin θ, cos θ).",
    "test your formula on special cases: W_xy = 0 for a circle (a = b, the same in every frame) "
    "and for θ = 0 or θ = π/2 (the axes line up); it is largest in size at θ = π/4.",
)


@check("6.5", W_xy=Formula(INFORMATION_SYMBOLS, example="a*cos(theta)**2 - 2*b"))
def check_world_information(W_xy) -> bool:
    """Exercise 6.5: the off-diagonal entry of ``R(θ) diag(a, b) R(θ)^T`` as a formula.

    The answer is a string sympy reads or a sympy expression in :data:`INFORMATION_SYMBOLS`
    (``a``, ``b`` positive; ``θ`` may be written ``theta``).  It is compared with
    :func:`world_information_reference` by
    :func:`lagolib.exercises._derive.formula_comparison` (``sin(2θ)/2`` is ``sin θ cos θ``); a
    wrong formula gets the term that is wrong, never the reference.
    """
    result = formula_comparison(
        W_xy,
        world_information_reference(),
        symbols=INFORMATION_SYMBOLS,
        name="your W_xy",
        slips=_world_information_slips(),
    )
    if result.problem is not None:
        return verdict("6.5", result.problem, hint=_WORLD_INFORMATION_HINTS)
    return verdict(
        "6.5", None, correct=f"your W_xy is the entry of R diag(a, b) R^T: {result.detail}."
    )
