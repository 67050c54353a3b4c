"""Checks for the exercises of chapter 9 (global optimality: the dual certificate), and a helper.

=========  =========  ==========================================================================
exercise   kind       check
=========  =========  ==========================================================================
9.1        implement  :func:`check_multipliers` — the Lagrange multipliers
                      ``lambda_i = Re(conj(z_i) (M x)_{n+i})`` from the data matrix and a point
9.2        predict    :func:`check_certificate_reading` — from printed multipliers and
                      eigenvalues: which of two points is certified, and the lower bound of the
                      other
9.3        explore    :func:`check_noise_sweep` — where on a noise sweep the certificate first
                      fails, and how often the relaxation is not tight
=========  =========  ==========================================================================

:func:`noise_sweep` computes exercise 9.3's sweep (the chapter's cell and the check share it).

Every check prints one line, ``Exercise 9.k — correct: …``, ``— not yet: …`` (what is wrong and by
how much, never the answer; ``hint(…)`` tells more, one level per call) or
``— not attempted yet: …``, and returns True or False; it never raises on
a wrong answer (see :mod:`lagolib.exercises._feedback`).
"""

from __future__ import annotations

import copy
import warnings
from functools import lru_cache

import numpy as np

from lagolib import LagolibWarning, certify, se2, simulate
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

__all__ = [
    "SWEEP_SIGMAS",
    "SWEEP_SEEDS",
    "POINT_CHOICES",
    "noise_sweep",
    "check_multipliers",
    "check_certificate_reading",
    "check_noise_sweep",
    "MULTIPLIER_SYMBOLS",
    "multiplier_reference",
    "check_multiplier_formula",
]

#: The rotation noises σ_θ (rad) of exercise 9.3's sweep.
SWEEP_SIGMAS = (0.2, 0.3, 0.4, 0.5)
#: The seeds of the Manhattan worlds of exercise 9.3 (one world per seed and σ_θ).
SWEEP_SEEDS = (0, 1, 2, 3)
#: The answers exercise 9.2 accepts for the certified point.
POINT_CHOICES = ("P", "Q", "both", "neither")


# --------------------------------------------------------------------------- exercise 9.1
@lru_cache(maxsize=1)
def _multiplier_cases():
    """Seeded test problems and points for exercise 9.1.

    Two laps of a square (16 poses) with anisotropic, rotated translational information, at a
    stationary point of the chordal cost (:func:`lagolib.certify.refine`) and at the odometry
    (not stationary: there the imaginary part of ``conj(z_i) (M x)_{n+i}`` is not zero, so an
    answer that takes it, or forgets the conjugate, is told apart).
    """
    rng = np.random.default_rng(901)
    sim = simulate.loop_world(laps=2, poses_per_lap=8, rng=rng, sigma_xy=0.05, sigma_theta=0.05)
    g = sim.graph
    axis = se2.rotation(rng.uniform(-np.pi, np.pi, g.m))
    cov = axis @ np.diag([0.02**2, 0.1**2]) @ np.swapaxes(axis, 1, 2)
    info = np.zeros((g.m, 3, 3))
    info[:, :2, :2] = np.linalg.inv(cov)
    info[:, 2, 2] = 1.0 / 0.05**2
    g = g.with_information(info)
    p = certify.chordal_problem(g)
    stationary = certify.refine(p, g.odometry_guess()).poses
    return (
        (p, certify.to_complex(stationary)),
        (p, certify.to_complex(g.odometry_guess())),
    )


def _diagnose_multipliers(got, M, x, expected):
    """(problem, hint) for a wrong ``lambda``; (None, "") when right."""
    n = x.size // 2
    Mx = M @ x
    w = np.conj(x[n:]) * Mx[n:]
    problem = compare_array(got, expected, name="lambda", rtol=1e-7, atol=1e-9)
    if problem is None:
        return None, ""
    levels = (
        "λ_i = Re(conj(z_i) (M x)_{n+i}) (the statement); x = [t; z], so z_i is x[n + i] and "
        "its row of M x is (M x)[n + i].",
        "compute M x once (M @ x, a complex vector), take the last n entries of it and of x, "
        "multiply them elementwise with x's conjugated, and keep the real part.",
    )
    tiny = 1e-6 * max(1.0, float(np.abs(expected).max(initial=0.0)))

    def named(candidate):  # a pattern that is zero here cannot be told from another zero one
        return float(np.abs(candidate).max(initial=0.0)) > tiny and matches(got, candidate)

    if named(w.imag):
        return (
            "you took the imaginary part of conj(z_i) (M x)_{n+i}: that is the gradient of f "
            "along the circle |z_i| = 1, not the multiplier.",
            ("λ_i is the real part.", *levels[1:]),
        )
    if named((x[n:] * Mx[n:]).real):
        return (
            "z_i is not conjugated: Re(z_i (M x)_{n+i}) is not the multiplier (it changes when "
            "the whole graph is rotated).",
            ("multiply by conj(z_i) (np.conj), the complex inner product of z_i with "
             "(M x)_{n+i}.", *levels[1:]),
        )
    if named((np.conj(x[:n]) * Mx[:n]).real):
        return (
            "you used the first n entries of x and M x: those are the translations t_i, which "
            "are not constrained.",
            ("the rotations z_i are x[n:], and their rows of M x are (M x)[n:].", *levels[1:]),
        )
    if named(np.abs(Mx[n:])):
        return (
            "you took |(M x)_{n+i}|. At a stationary point that is |λ_i|, but elsewhere (M x)_{n+i} "
            "also has a component along the circle, and the sign of λ_i is lost.",
            ("project (M x)_{n+i} on z_i: Re(conj(z_i) (M x)_{n+i}).", *levels[1:]),
        )
    if named(2 * expected):
        return (
            "your multipliers are twice the reference: the gradient of x^H M x is 2 M x, but "
            "the Lagrangian's condition (M − Λ) x = 0 has no factor 2 on either side.",
            ("λ_i = Re(conj(z_i) (M x)_{n+i}), no factor 2.",),
        )
    return problem, (
        _GENERIC_MULTIPLIER_HINT,
        *levels,
    )


_GENERIC_MULTIPLIER_HINT = (
    "print your multipliers next to certify.multipliers on the chapter's small problem (the "
    "cell under the exercise does) and see where they differ."
)


def _complex_multipliers(got, M, x):
    """The sentence for complex multipliers (which are real numbers), or None."""
    if not (isinstance(got, np.ndarray) and np.iscomplexobj(got)):
        return None
    n = np.size(x) // 2
    try:
        w = np.conj(x[n:]) * (M @ x)[n:]
        itself = got.shape == w.shape and np.allclose(got, w, rtol=1e-7, atol=1e-9)
    except (TypeError, ValueError):
        itself = False
    return (
        "your multipliers are complex"
        + (": conj(z_i) (M x)_{n+i} itself. λ_i is its real part" if itself else "")
        + " — multipliers should return an array of real numbers of shape (n,), one λ_i per "
        "pose, even where the imaginary part is 0 (take .real: the imaginary part is the "
        "gradient along the circle, zero only at a stationary point)."
    )


@check("9.1", multipliers=Function(RealArray(("n",)), explain=_complex_multipliers))
def check_multipliers(multipliers):
    """Check exercise 9.1: ``multipliers(M, x)``, the Lagrange multipliers of ``|z_i|^2 = 1``.

    Calls the student's function with the sparse Hermitian data matrix ``M`` (2 n, 2 n) and a
    complex ``x = [t; z]`` (2 n,) of a seeded graph (:func:`_multiplier_cases`: a stationary
    point and the odometry, which is not stationary) and compares with
    :func:`lagolib.certify.multipliers` to ``1e-7`` relative.  Diagnoses a complex answer, the
    imaginary part, a missing conjugate, the translation block, the modulus, and a factor 2.

    Parameters
    ----------
    multipliers : callable
        ``(M scipy.sparse (2n, 2n) complex, x ndarray (2n,) complex) -> ndarray (n,)``.

    Returns
    -------
    bool
    """
    ex = "9.1"
    cases = _multiplier_cases()
    first = None  # the first failing test's (message, hint) when it names no pattern
    for k, (p, x) in enumerate(cases):
        got, problem = call_student(multipliers, p.M.copy(), x.copy(), name="multipliers")
        if problem == NOT_ATTEMPTED:
            return verdict(ex, problem)
        where = "a stationary point" if k == 0 else "the odometry (not stationary)"
        if problem is not None:
            return verdict(
                ex,
                f"on test {k + 1} of {len(cases)} ({where}): " + problem,
                hint="the check calls multipliers(M, x) with a scipy.sparse complex matrix and a "
                "complex numpy vector, and expects a real array of shape (n,) back "
                "(λ_i = Re(conj(z_i) (M x)_{n+i})); try your function on certify.data_matrix(g) "
                "and certify.to_complex(poses).",
            )
        expected = certify.multipliers(p, x)
        problem, hint = _diagnose_multipliers(got, p.M, x, expected)
        if problem is None:
            continue
        message = f"on test {k + 1} of {len(cases)} ({where}): " + problem
        if hint[0] != _GENERIC_MULTIPLIER_HINT:  # a wrong answer recognized by name
            if first is not None:  # it failed earlier too, where it could not be named
                message = f"{first[0].rstrip('.')}; {message}"
            return verdict(ex, message, hint=hint)
        # at the stationary point several wrong answers are all zero: a later test may tell
        # which one this is
        first = first or (message, hint)
    if first is not None:
        return verdict(ex, first[0], hint=first[1])
    return verdict(
        ex,
        None,
        correct=f"λ equals lagolib.certify.multipliers on all {len(cases)} test points (a "
        "stationary point and one that is not).",
    )


# --------------------------------------------------------------------------- exercise 9.2
@check("9.2", certified_point=Choice(POINT_CHOICES), lower_bound_P=Real())
def check_certificate_reading(certified_point, lower_bound_P, problem, P, Q):
    """Check exercise 9.2: read two certificates' numbers before certifying.

    Certifies ``P`` and ``Q`` (poses of ``problem``'s graph) with :func:`lagolib.certify.certify`
    and compares: ``certified_point`` (``"P"``, ``"Q"``, ``"both"`` or ``"neither"``) with the
    certificates' verdicts (certified: the gap ``f - lower bound`` is at most the tolerance
    ``2 n eta0``), and ``lower_bound_P`` with ``P``'s lower bound
    ``sum(lambda) + n min(lambda_min, 0)`` to ``1e-4`` relative (numbers read off a print).
    Prints both certificates with a right answer; after a wrong ``certified_point`` they are the
    last hint level.

    Parameters
    ----------
    certified_point : {"P", "Q", "both", "neither"}
    lower_bound_P : float
    problem : lagolib.certify.ChordalProblem
    P, Q : ndarray, shape (n, 3)

    Returns
    -------
    bool
    """
    ex = "9.2"
    if is_placeholder(certified_point) or is_placeholder(lower_bound_P):
        return verdict(ex, NOT_ATTEMPTED)
    cP, cQ = certify.certify(problem, P), certify.certify(problem, Q)
    want = {(True, True): "both", (True, False): "P", (False, True): "Q"}.get(
        (cP.certified, cQ.certified), "neither"
    )

    def said(name, c):
        lm = "> −η (not computed)" if c.lambda_min is None else f"{c.lambda_min:.6g}"
        return (
            f"{name}: certified {c.certified}, λ_min {lm}, lower bound {c.lower_bound:.6g}, "
            f"gap {c.gap:.3g} (tolerance {c.tolerance:.3g})"
        )

    facts = f"{said('P', cP)}; {said('Q', cQ)}"
    wrong = compare_choice(certified_point, want, POINT_CHOICES, name="certified_point")
    if wrong is not None:
        if wrong.startswith("certified_point should be"):
            return verdict(ex, wrong, hint='write certified_point = "P", "Q", "both" or "neither".')
        return verdict(
            ex,
            f"certified_point = {certified_point!r} is not what the two certificates say.",
            hint=(
                "a point is certified when its gap — f minus its lower bound "
                "Σλ + n·min(λ_min, 0) — is at most the tolerance 2nη₀, tiny next to f "
                "(section 4).",
                "work out each point's bound from the printed numbers: a negative λ_min lowers "
                "it by n·|λ_min|; then compare the bound with the point's f.",
                f"the check's certificates: {facts}.",
            ),
        )
    n = problem.n
    lam_sum = float(cP.multipliers.sum())
    lam_min = cP.lambda_min if cP.lambda_min is not None else 0.0
    wrong = compare_number(lower_bound_P, cP.lower_bound, name="lower_bound_P", rtol=1e-4)
    if wrong is not None:
        got = lower_bound_P  # read by @check as one finite real number

        def near(a, b):
            return bool(np.isclose(a, b, rtol=1e-4))

        hint = (
            "the bound is Σλ + n·min(λ_min, 0), with n the number of poses: read Σλ, n and the "
            "smallest eigenvalue off P's printed line.",
            f"P's numbers as the check reads them: Σλ = {lam_sum:.6f}, n = {n}, λ_min = "
            f"{lam_min:.6g}.",
        )
        if near(got, lam_sum) or near(got, cP.f):
            wrong = (
                f"lower_bound_P is {got:.6g}: that is Σλ = f(P) itself, the bound of a certified "
                "point. P's λ_min is negative, so the bound is lower."
            )
        elif near(got, lam_sum + lam_min):
            wrong = (
                f"lower_bound_P is {got:.6g}: Σλ + λ_min — the eigenvalue counts once per pose: "
                f"n·λ_min, with n = {n}."
            )
        elif near(got, lam_sum - n * lam_min):
            wrong = f"lower_bound_P is {got:.6g}: the sign of n·λ_min is flipped (λ_min < 0)."
        elif near(got, lam_sum + 2 * n * lam_min):
            wrong = (
                f"lower_bound_P is {got:.6g}: you multiplied by 2n; n = {n} poses (the rotation "
                "block of S has n rows)."
            )
        return verdict(ex, wrong, hint=hint)
    return verdict(ex, None, correct=facts + ".")


# --------------------------------------------------------------------------- exercise 9.3
_SWEEP: dict = {}


def noise_sweep(sigmas=SWEEP_SIGMAS, seeds=SWEEP_SEEDS):
    """:func:`lagolib.certify.solve` on small simulated Manhattan worlds as σ_θ grows.

    One world per ``(sigma, seed)``: :func:`lagolib.simulate.manhattan_world` with 60 poses on
    an 8 × 8 lattice, ``sigma_xy = 0.05`` and ``sigma_theta = sigma``; the pipeline runs with
    ``max_escapes=2``.  The result is cached (the chapter's cell and :func:`check_noise_sweep`
    share it).

    Parameters
    ----------
    sigmas : sequence of float
    seeds : sequence of int

    Returns
    -------
    dict
        ``"sigmas"``, ``"seeds"`` (tuples) and, each an ndarray of shape
        ``(len(sigmas), len(seeds))``: ``"certified"`` (bool), ``"not_tight"`` (bool: the
        rank-2 relaxation is certified but not rank one), ``"escapes"`` (int), ``"chi2"``,
        ``"f"``, ``"relative_gap"`` (``SolveResult.relative_gap``: the gap over ``f``),
        ``"reason"`` (str) and ``"stages"`` (object: each world's ``SolveResult.stages``), and
        ``"seconds"`` (float, the whole sweep).
    """
    import time

    key = (tuple(float(s) for s in sigmas), tuple(int(s) for s in seeds))
    if key in _SWEEP:  # a deep copy: the caller may change it without corrupting the cache
        return copy.deepcopy(_SWEEP[key])
    shape = (len(key[0]), len(key[1]))
    out = {
        "certified": np.zeros(shape, bool),
        "not_tight": np.zeros(shape, bool),
        "escapes": np.zeros(shape, int),
        "chi2": np.zeros(shape),
        "f": np.zeros(shape),
        "relative_gap": np.zeros(shape),
        "reason": np.empty(shape, object),
        "stages": np.empty(shape, object),
    }
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LagolibWarning)  # LAGO's margin warnings at high noise
        for a, s in enumerate(key[0]):
            for b, seed in enumerate(key[1]):
                g = simulate.manhattan_world(
                    n_poses=60, extent=8, rng=seed, sigma_theta=s, sigma_xy=0.05
                ).graph
                r = certify.solve(g, max_escapes=2)
                out["certified"][a, b] = r.certified
                out["not_tight"][a, b] = "not tight" in r.reason
                out["escapes"][a, b] = r.escapes
                out["chi2"][a, b] = r.chi2
                out["f"][a, b] = r.f
                out["relative_gap"][a, b] = r.relative_gap
                out["reason"][a, b] = r.reason
                out["stages"][a, b] = r.stages
    out["seconds"] = time.perf_counter() - t0
    out["sigmas"], out["seeds"] = key
    _SWEEP[key] = out
    return noise_sweep(sigmas, seeds)


@check("9.3", first_uncertified=Real(), not_tight=Int(count_of="worlds"))
def check_noise_sweep(first_uncertified, not_tight):
    """Check exercise 9.3: where the certificate first fails on the sweep, and how often the
    relaxation is not tight.

    Recomputes (or reuses) :func:`noise_sweep` and compares ``first_uncertified`` — the smallest
    σ_θ of :data:`SWEEP_SIGMAS` at which some world ends not certified (``None`` is not an
    answer; every σ is) — exactly (to 1e-9), and ``not_tight``, the number of worlds whose
    :attr:`~lagolib.certify.SolveResult.reason` says the relaxation is not tight.

    Parameters
    ----------
    first_uncertified : float
    not_tight : int

    Returns
    -------
    bool
    """
    ex = "9.3"
    if is_placeholder(first_uncertified) or is_placeholder(not_tight):
        return verdict(ex, NOT_ATTEMPTED)
    sw = noise_sweep()
    sigmas = np.array(sw["sigmas"])
    failing = ~sw["certified"].all(axis=1)
    want_sigma = float(sigmas[failing][0]) if failing.any() else float("nan")
    want_nt = int(sw["not_tight"].sum())
    fractions = ", ".join(
        f"σθ {s:g}: {c:.2f}" for s, c in zip(sigmas, sw["certified"].mean(axis=1))
    )
    wrong = compare_number(first_uncertified, want_sigma, name="first_uncertified", rtol=1e-9)
    if wrong is not None:
        got = first_uncertified  # read by @check as one finite real number
        if np.any(np.isclose(sigmas, got)):
            k = int(np.argmin(np.abs(sigmas - got)))
            wrong = (
                f"first_uncertified = {got:g}: "
                + (
                    "at that σθ every world is certified."
                    if sw["certified"][k].all()
                    else "some world already ends not certified at a smaller σθ."
                )
            )
        elif not np.any(np.isclose(sigmas, got, rtol=1e-6)):
            wrong = (
                f"first_uncertified = {got:g} is not one of the swept σθ "
                f"({', '.join(f'{s:g}' for s in sigmas)})."
            )
        return verdict(
            ex,
            wrong,
            hint=(
                "read the printed certified fraction per σθ from the top: the first row "
                "below 1.00.",
                f"the check's certified fractions: {fractions}.",
            ),
        )
    wrong = compare_int(not_tight, want_nt, name="not_tight")
    if wrong is not None:
        n_unc = int((~sw["certified"]).sum())
        if not_tight == n_unc and n_unc != want_nt:  # an int: @check read it
            wrong += (
                " You counted every world that is not certified; some of those stopped for "
                "another reason (a budget ran out, or the staircase could not go on: the printed "
                "reason says which)."
            )
        return verdict(
            ex,
            wrong,
            hint=(
                "count the worlds whose printed reason says 'not tight' (the column 'tight?'), "
                "over the whole sweep: every σθ, every seed.",
                f"the sweep has {sigmas.size * len(sw['seeds'])} worlds, {n_unc} of them not "
                "certified; the 'tight?' column marks the ones whose relaxation is not tight.",
            ),
        )
    return verdict(
        ex,
        None,
        correct=f"certified fractions {fractions}; {want_nt} world(s) with a relaxation that "
        "is not tight.",
    )


# --- derive exercises ---
# Exercise 9.4 (derive) — :func:`check_multiplier_formula`: the multiplier λ_1 of section 4 for
# the smallest rotation problem, f = w |z_1 − r z_0|² with r = e^{iθ_z}, z_k = e^{iφ_k}.

import sympy as _sp  # noqa: E402

from lagolib.exercises._derive import Formula, formula_comparison  # noqa: E402

#: exercise 9.4's symbols: the weight w > 0, the measured angle θ_z and the two angles φ_0, φ_1
MULTIPLIER_SYMBOLS = (
    _sp.Symbol("w", positive=True),
    *_sp.symbols("theta_z phi_0 phi_1", real=True),
)


def multiplier_reference():
    """λ_1 = Re(conj(z_1) (M z)_1) for ``M = w [[1, −conj(r)], [−r, 1]]`` (section 4's rule).

    ``f(z) = zᴴ M z = w |z_1 − r z_0|²`` with ``r = e^{iθ_z}``, ``z = (e^{iφ_0}, e^{iφ_1})``;
    sympy forms ``M z`` and takes the real part.
    """
    w, tz, p0, p1 = MULTIPLIER_SYMBOLS
    r = _sp.exp(_sp.I * tz)
    z = _sp.Matrix([_sp.exp(_sp.I * p0), _sp.exp(_sp.I * p1)])
    M = w * _sp.Matrix([[1, -_sp.conjugate(r)], [-r, 1]])
    value = _sp.conjugate(z[1]) * (M * z)[1]
    return _sp.simplify(_sp.re(_sp.expand_complex(value)))


def _multiplier_slips():
    w, tz, p0, p1 = MULTIPLIER_SYMBOLS
    return [
        (w * (1 + _sp.cos(p1 - p0 - tz)), "the cosine's sign: (M z)_1 = w (z_1 − r z_0), a "
         "difference."),
        (w * _sp.sin(p1 - p0 - tz), "that is the imaginary part of conj(z_1)(M z)_1 — the "
         "gradient along the circle, zero at a stationary point — not the multiplier."),
        (2 * w * (1 - _sp.cos(p1 - p0 - tz)), "a factor 2 too many: differentiate with respect "
         "to conj(z), as section 4 does, and the 2's of f and of the constraint cancel."),
    ]


_MULTIPLIER_HINTS = (
    "section 4: λ_i = Re(conj(z_i) (M x)_i). Here x = z = (z_0, z_1), so write out the second "
    "row of M z first.",
    "(M z)_1 = w (z_1 − r z_0), and conj(z_1) z_1 = 1 on the circle.",
    "conj(z_1) r z_0 = e^{i(θ_z + φ_0 − φ_1)}; its real part is a cosine.",
)


@check("9.4", lambda_1=Formula(MULTIPLIER_SYMBOLS, example="w*cos(phi_0)"))
def check_multiplier_formula(lambda_1) -> bool:
    """Exercise 9.4: λ_1 of ``f = w |z_1 − e^{iθ_z} z_0|²`` at ``z = (e^{iφ_0}, e^{iφ_1})``.

    The answer is a formula in :data:`MULTIPLIER_SYMBOLS` (``w``, ``theta_z``, ``phi_0``,
    ``phi_1``), compared with :func:`multiplier_reference` by symbolic equivalence.
    """
    result = formula_comparison(
        lambda_1,
        multiplier_reference(),
        symbols=MULTIPLIER_SYMBOLS,
        name="your λ_1",
        slips=_multiplier_slips(),
    )
    if result.problem is not None:
        return verdict("9.4", result.problem, hint=_MULTIPLIER_HINTS)
    return verdict("9.4", None, correct=f"your λ_1 is section 4's multiplier: {result.detail}.")
