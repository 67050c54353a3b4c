"""Checks for the exercises of chapter 7, *The closed form*.

===========  =========  ==========================================================================
exercise     kind       check
===========  =========  ==========================================================================
7.1          implement  :func:`check_sincos_error` — ``e_ij = f_ij − δ̂_ij`` of one edge in
                        ``(x, y, c, s)`` (Lodi Rizzini eq. 2–3)
7.2          implement  :func:`check_newton_step` — one Newton step on the orthogonality
                        condition ``R t = A t + b``, ``c_i² + s_i² = 1`` (eq. 44–45, 1)
7.3          predict    :func:`check_closed_form_gap` — the closed form's weighted χ² next to the
                        optimum's on grid100, where angles are 25× more informative
7.4          explore    :func:`check_noise_gap` — what decides how far the closed form is from
                        the optimum: the noise level or the ratio σ_θ / σ_xy
===========  =========  ==========================================================================

Each check prints one line starting ``Exercise 7.N`` (correct / not yet / not attempted yet, see
:mod:`lagolib.exercises`) and returns True or False; it never raises on a wrong answer.
Equation numbers are those of D. Lodi Rizzini, "A Closed-Form Constraint Networks Solver for
Maximum Likelihood Mapping".
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from lagolib import chi2, datasets, lago_solve, optimize, simulate
from lagolib import closed_form as cf
from lagolib.exercises._coerce import Choice, Function, Real, RealArray, Tuple
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
from lagolib.exercises._reference import independent_edges

__all__ = [
    "check_sincos_error",
    "check_newton_step",
    "check_closed_form_gap",
    "check_noise_gap",
    "orthogonality_residual",
    "newton_reference",
    "GAP_BANDS",
    "SIGMA_XY",
    "SIGMA_SWEEP",
    "DECIDES",
    "weighted_gap",
    "GRADIENT_SYMBOLS",
    "sincos_edge_error",
    "gradient_entry_reference",
    "check_gradient_entry",
]


def _close(got, expected, rtol=1e-7, atol=1e-9):
    return bool(
        np.shape(got) == np.shape(expected)
        and np.all(np.abs(np.asarray(got) - expected) <= atol + rtol * np.abs(expected))
    )


# --------------------------------------------------------------------------------------------
# Exercise 7.1 — the error of one edge with four-parameter poses


def _edge_cases(seed=7, k=16):
    """Seeded edges in ``(x, y, c, s)``: ``p_i, p_j, delta`` of shape (k, 4), and ``(x, y, θ)``.

    Headings and measured angles all around the circle, so that every rotation matters and a
    slip in a sine's sign cannot hide behind a small angle.
    """
    rng = np.random.default_rng(seed)
    q_i = rng.uniform([-5, -5, -np.pi], [5, 5, np.pi], size=(k, 3))
    q_j = rng.uniform([-5, -5, -np.pi], [5, 5, np.pi], size=(k, 3))
    z = rng.uniform([-3, -3, -np.pi], [3, 3, np.pi], size=(k, 3))
    return cf.sincos_poses(q_i), cf.sincos_poses(q_j), cf.sincos_poses(z), (q_i, q_j, z)


def _reference_sincos_errors(q_i, q_j, z):
    """lagolib's ``e_ij`` (:func:`lagolib.closed_form.sincos_residuals`), shape (k, 4)."""
    return cf.sincos_residuals(independent_edges(q_i, q_j, z))


def _sincos_mistakes(p_i, p_j, delta):
    """What students compute instead of ``e_ij``: ``[(values (k, 4), diagnosis)]``."""
    x_i, y_i, c_i, s_i = p_i.T
    x_j, y_j, c_j, s_j = p_j.T
    dx, dy = x_j - x_i, y_j - y_i
    right_t = np.column_stack([c_i * dx + s_i * dy, -s_i * dx + c_i * dy])
    right_a = np.column_stack([c_j * c_i + s_j * s_i, s_j * c_i - c_j * s_i])
    f = np.column_stack([right_t, right_a])
    R_i = np.column_stack([c_i * dx - s_i * dy, s_i * dx + c_i * dy])
    world = np.column_stack([dx, dy])
    backwards = np.column_stack([c_j * c_i + s_j * s_i, c_j * s_i - s_j * c_i])
    with_theta = np.column_stack([right_t, right_a]) - delta
    return [
        (
            f,
            "you returned f_ij itself: the error is f_ij − δ̂_ij (eq. 3), the predicted "
            "observation minus the measured one.",
        ),
        (
            f + delta,
            "you added δ̂_ij: the error is f_ij − δ̂_ij (eq. 3).",
        ),
        (
            delta - f,
            "you returned δ̂_ij − f_ij: the error is f_ij − δ̂_ij (eq. 3), the predicted "
            "observation minus the measured one.",
        ),
        (
            np.column_stack([R_i, right_a]) - delta,
            "your translation rotates t_j − t_i by R(θ_i) instead of R(θ_i)ᵀ: f_ij's first two "
            "rows are the displacement seen from p_i's frame, [c_i dx + s_i dy, −s_i dx + c_i dy].",
        ),
        (
            np.column_stack([world, right_a]) - delta,
            "your translation is t_j − t_i in the world frame: f_ij's first two rows are that "
            "displacement rotated into p_i's frame, R(θ_i)ᵀ (t_j − t_i) (eq. 2).",
        ),
        (
            np.column_stack([right_t, backwards]) - delta,
            "your angular rows are cos and sin of θ_i − θ_j: the edge measures θ_j − θ_i, so "
            "the last row is sin(θ_j − θ_i) = s_j c_i − c_j s_i (eq. 2).",
        ),
        (
            np.column_stack([R_i, backwards]) - delta,
            "both rotations go the wrong way: f_ij is p_j seen from p_i, so the translation is "
            "R(θ_i)ᵀ (t_j − t_i) and the angle θ_j − θ_i (eq. 2).",
        ),
        (
            with_theta[:, [0, 1, 3, 2]],
            "your last two rows are swapped: f_ij ends with [cos(θ_j − θ_i), sin(θ_j − θ_i)] and "
            "δ̂_ij with [ĉ_ij, ŝ_ij], in that order.",
        ),
    ]


@check("7.1", sincos_error=Function(RealArray((4,))))
def check_sincos_error(sincos_error) -> bool:
    """Exercise 7.1: the error of one edge in ``(x, y, c, s)``, ``e_ij = f_ij − δ̂_ij``.

    Calls ``sincos_error(p_i, p_j, delta_ij)`` (three arrays of shape (4,): ``[x, y, c, s]`` of
    the two poses and ``[x̂, ŷ, ĉ, ŝ]`` of the measurement; it must return shape (4,)) on 16
    seeded edges with headings and measured angles all around the circle, and compares with
    :func:`lagolib.closed_form.sincos_residuals` (Lodi Rizzini eq. 2–3) to 1e-7 relative.
    Recognizes a missing ``− δ̂_ij``, a rotation by ``R(θ_i)`` instead of ``R(θ_i)ᵀ``, an
    unrotated (world-frame) displacement, the angle ``θ_i − θ_j`` instead of ``θ_j − θ_i``,
    swapped angular rows and a flipped sign (``δ̂_ij − f_ij``).

    Parameters
    ----------
    sincos_error : callable
        The student's ``sincos_error(p_i, p_j, delta_ij) -> ndarray of shape (4,)``.

    Returns
    -------
    bool
    """
    ex = "7.1"
    hint = (
        "f_ij is pose j seen from pose i: the displacement t_j − t_i rotated into i's frame, "
        "and the relative heading θ_j − θ_i as its cosine and sine; e_ij = f_ij − δ̂_ij (eq. 3).",
        "R(θ_i)ᵀ = [[c_i, s_i], [−s_i, c_i]]; cos(θ_j − θ_i) and sin(θ_j − θ_i) expand with the "
        "angle-difference formulas into products of c_i, s_i, c_j, s_j.",
        "with dx = x_j − x_i, dy = y_j − y_i: f_ij = [c_i dx + s_i dy, −s_i dx + c_i dy, "
        "c_j c_i + s_j s_i, s_j c_i − c_j s_i] (eq. 2).",
    )
    p_i, p_j, delta, (q_i, q_j, z) = _edge_cases()
    expected = _reference_sincos_errors(q_i, q_j, z)
    got = np.empty_like(expected)
    for k in range(len(p_i)):
        args = (p_i[k].copy(), p_j[k].copy(), delta[k].copy())
        # the result is read as an array of real numbers (complex, text, … are named as such)
        value, problem = call_student(sincos_error, *args, name="sincos_error")
        if problem is None and value.shape != (4,):
            problem = compare_array(value, expected[k], name=f"sincos_error(...) for edge {k}")
        if problem is not None:
            if problem != NOT_ATTEMPTED:
                problem += (
                    f"\n    (edge {k}: p_i = {np.round(args[0], 4)}, p_j = {np.round(args[1], 4)},"
                    f" delta_ij = {np.round(args[2], 4)})"
                )
            return verdict(
                ex,
                problem,
                hint=("return a numpy array of 4 real numbers for one edge.", *hint),
            )
        got[k] = value  # a wrong value is diagnosed below, on all edges together

    if _close(got, expected):
        return verdict(
            ex,
            None,
            correct=f"all {len(got)} edges agree with lagolib.closed_form.sincos_residuals "
            f"(largest difference {np.abs(got - expected).max():.1e}).",
        )
    for candidate, diagnosis in _sincos_mistakes(p_i, p_j, delta):
        if _close(got, candidate):
            return verdict(ex, diagnosis, hint=hint)
    problem = compare_array(got, expected, name="your errors (one row per edge)")
    t_ok = _close(got[:, :2], expected[:, :2])
    a_ok = _close(got[:, 2:], expected[:, 2:])
    if t_ok and not a_ok:
        problem = (
            "your translation rows are right, your angular rows (3 and 4) are not.\n    " + problem
        )
    elif a_ok and not t_ok:
        problem = (
            "your angular rows are right, your translation rows (1 and 2) are not.\n    " + problem
        )
    return verdict(ex, problem, hint=hint)


# --------------------------------------------------------------------------------------------
# Exercise 7.2 — one Newton step on the orthogonality condition


def orthogonality_residual(A, b, t, rho, *, sign=1.0):
    """``F(t, ρ) = [A t + b − R t; (c_i² + s_i² − 1)/2]`` (Lodi Rizzini eq. 44–45 and 1), (3n,).

    Parameters
    ----------
    A : ndarray, shape (2n, 2n)
    b, t : ndarray, shape (2n,)
    rho : ndarray, shape (n,)
    sign : float
        ``-1`` gives the printed ``A t − b`` (a mistake the check recognizes).
    """
    c, s = t[0::2], t[1::2]
    Rt = t * np.column_stack([rho, -rho]).ravel()  # eq. (45)
    return np.concatenate([A @ t + sign * b - Rt, 0.5 * (c**2 + s**2 - 1)])


def _jacobian(A, t, rho, *, rho_sign=1.0, R_signs=(1.0, -1.0), constraint_scale=1.0):
    """Dense ``∂F/∂[t; ρ]`` of :func:`orthogonality_residual`, shape (3n, 3n).

    The keywords build the Jacobians of the usual slips (the check recognizes them).
    """
    n = rho.size
    c, s = t[0::2], t[1::2]
    R = np.diag(np.column_stack([R_signs[0] * rho, R_signs[1] * rho]).ravel())
    J = np.zeros((3 * n, 3 * n))
    J[: 2 * n, : 2 * n] = A - R
    k = np.arange(n)
    J[2 * k, 2 * n + k] = -rho_sign * R_signs[0] * c  # ∂(α_i − ρ_i c_i)/∂ρ_i
    J[2 * k + 1, 2 * n + k] = -rho_sign * R_signs[1] * s  # ∂(β_i + ρ_i s_i)/∂ρ_i
    J[2 * n + k, 2 * k] = constraint_scale * c  # ∂((c_i² + s_i² − 1)/2)/∂c_i
    J[2 * n + k, 2 * k + 1] = constraint_scale * s
    return J


def newton_reference(A, b, t, rho):
    """lagolib's Newton step on eq. (44)–(45) with eq. (1), eliminated to ``(t, ρ)``.

    :func:`lagolib.closed_form.solve_orthogonality` takes this step (without its step halving)
    with the node positions kept as extra unknowns; the position equations are linear, so
    eliminating the positions gives exactly this ``3n × 3n`` system (``tests/`` compare the two
    iteration by iteration).

    Returns
    -------
    t_new : ndarray, shape (2n,)
    rho_new : ndarray, shape (n,)
    """
    n = rho.size
    d = np.linalg.solve(_jacobian(A, t, rho), -orthogonality_residual(A, b, t, rho))
    return t + d[: 2 * n], rho + d[2 * n :]


@lru_cache(maxsize=1)
def _newton_problem(seed=3):
    """A seeded 3×3 grid (n = 8): ``A, b`` of eq. (44), a start off the unit circles, and a start
    on them (the odometry's orientations) with its least-squares ρ, and lagolib's solution."""
    graph = simulate.grid_world(rows=3, cols=3, rng=seed).graph
    net = cf.network(graph)
    A, b = net.A_b()
    rng = np.random.default_rng(seed)
    theta = graph.odometry_guess()[net.vertex, 2]
    t_on = net.t_of(theta)
    v = net.v(t_on).reshape(net.n, 2)
    rho_on = v[:, 0] * t_on[0::2] - v[:, 1] * t_on[1::2]
    theta_off = theta[1:] - theta[0] + rng.normal(scale=0.3, size=net.n)
    scale = rng.uniform(0.8, 1.2, size=net.n)
    t_off = (scale[:, None] * np.column_stack([np.cos(theta_off), np.sin(theta_off)])).ravel()
    rho_off = rho_on + rng.normal(scale=0.5, size=net.n)
    solution = cf.solve_orthogonality(net, t_on, rho0=rho_on)
    return A, b, t_off, rho_off, t_on, rho_on, solution


def _newton_mistakes(A, b, t, rho):
    """Steps students take instead of Newton's: ``[((t_new, rho_new), diagnosis)]``."""
    n = rho.size
    F = orthogonality_residual(A, b, t, rho)
    J = _jacobian(A, t, rho)
    d = np.linalg.solve(J, -F)
    t1, r1 = t + d[: 2 * n], rho + d[2 * n :]
    out = []

    def add(J_, F_, diagnosis):
        try:
            dd = np.linalg.solve(J_, -F_)
        except np.linalg.LinAlgError:
            return
        out.append(((t + dd[: 2 * n], rho + dd[2 * n :]), diagnosis))

    add(
        J,
        orthogonality_residual(A, b, t, rho, sign=-1.0),
        "your step solves R t = A t − b, the sign printed in eq. (44); with b the first column "
        "of L + MPQ, eq. (36) gives v = A t + b (section 5 checks it numerically).",
    )
    out.append(
        (
            (t - d[: 2 * n], rho - d[2 * n :]),
            "your step goes the wrong way: Newton solves J Δ = −F (you solved J Δ = F).",
        )
    )
    out.append(
        (
            (d[: 2 * n], d[2 * n :]),
            "you returned the increment Δ; return the new point (t + Δt, ρ + Δρ).",
        )
    )
    add(
        _jacobian(A, t, rho, R_signs=(1.0, 1.0)),
        np.concatenate([A @ t + b - t * np.repeat(rho, 2), F[2 * n :]]),
        "your R is diag(ρ_1, ρ_1, …): eq. (45) alternates the sign, R = diag(ρ_1, −ρ_1, …, "
        "ρ_n, −ρ_n), because (α_i, β_i) = ρ_i (c_i, −s_i).",
    )
    no_R = _jacobian(A, t, rho)
    no_R[: 2 * n, : 2 * n] = A
    add(
        no_R,
        F,
        "your ∂F/∂t block is A alone: R t depends on t too, so the first 2n rows differentiate "
        "to A − R (R held at the current ρ).",
    )
    add(
        _jacobian(A, t, rho, rho_sign=-1.0),
        F,
        "your ∂F/∂ρ has the wrong sign: differentiate row 2i−1 of F, α_i − ρ_i c_i, and row "
        "2i, β_i + ρ_i s_i, by ρ_i once more.",
    )
    add(
        _jacobian(A, t, rho, constraint_scale=2.0),
        F,
        mismatch := "your constraint rows and their Jacobian do not match: one of them has the "
        "factor ½ of F_i = (c_i² + s_i² − 1)/2 and the other does not.",
    )
    add(J, np.concatenate([F[: 2 * n], 2 * F[2 * n :]]), mismatch)
    norm = np.linalg.norm(t1.reshape(n, 2), axis=1, keepdims=True)
    out.append(
        (
            ((t1.reshape(n, 2) / norm).ravel(), r1),
            "you renormalized (c_i, s_i) after the step. Newton's step is the plain t + Δt: its "
            "constraint rows already bring t back to the unit circles (to first order), and "
            "normalizing changes the next step's residual.",
        )
    )
    M = A - np.diag(np.column_stack([rho, -rho]).ravel())
    try:
        out.append(
            (
                (t + np.linalg.solve(M, -F[: 2 * n]), rho),
                "ρ did not change, and your t ignores the constraint rows: ρ (one per pose) is "
                "an unknown too, and the n rows (c_i² + s_i² − 1)/2 = 0 make the system square, "
                "3n equations in 3n unknowns.",
            )
        )
    except np.linalg.LinAlgError:
        pass
    return out


def _unpack(value, n):
    """``(t_new, rho_new)`` (two float arrays, as call_student read them) if their shapes are
    ``(2n,)`` and ``(n,)``, or ``(None, problem)``."""
    for name, a, m in (("t_new", value[0], 2 * n), ("rho_new", value[1], n)):
        if a.shape != (m,):
            return None, f"{name} has shape {a.shape}, expected ({m},)."
    return value, None


_STEP = Tuple(
    RealArray(("2n",)),
    RealArray(("n",)),
    names=("t_new", "rho_new"),
    what="a pair (t_new, rho_new) of arrays of shapes (2n,) and (n,)",
    hint="end the function with `return t_new, rho_new`.",
)


@check("7.2", newton_step=Function(_STEP))
def check_newton_step(newton_step) -> bool:
    """Exercise 7.2: one Newton step on the orthogonality condition (Lodi Rizzini eq. 44–45, 1).

    Calls ``newton_step(A, b, t, rho)`` — ``A`` (2n, 2n) and ``b`` (2n,) of eq. (44), the current
    ``t = [c_1, s_1, …, c_n, s_n]`` (2n,) and ``rho`` (n,) — which must return
    ``(t_new, rho_new)``, the full Newton step on ``F = [A t + b − R t; (c_i² + s_i² − 1)/2] = 0``.
    The problem is a seeded 3×3 grid (n = 8) with a start *off* the unit circles, so that the
    constraint rows matter; the answer is compared with :func:`newton_reference` (lagolib's step)
    to 1e-7 relative.  Recognizes the printed sign ``A t − b``, ``J Δ = +F``, returning Δ, the
    sign pattern of ``R`` or of ``∂F/∂ρ``, ``A`` for ``A − R`` in ``∂F/∂t``, mismatched constraint
    rows, renormalizing ``t``, and
    leaving out ``ρ`` and the constraint rows.  A right step is then iterated from the
    odometry's orientations and compared with :func:`lagolib.closed_form.solve_orthogonality`.

    Parameters
    ----------
    newton_step : callable
        The student's ``newton_step(A, b, t, rho) -> (t_new, rho_new)``.

    Returns
    -------
    bool
    """
    ex = "7.2"
    hint = (
        "Newton's step: evaluate F and its Jacobian J = ∂F/∂[t; ρ] at the current point, solve "
        "J Δ = −F (3n equations, 3n unknowns) and return the new point, not Δ.",
        "row 2i−1 of the first 2n rows of F is α_i − ρ_i c_i and row 2i is β_i + ρ_i s_i "
        "(R alternates the sign); constraint row i is (c_i² + s_i² − 1)/2 and does not depend "
        "on ρ.",
        "stack F = [A t + b − R t; (c_i² + s_i² − 1)/2] and J = [[A − R, ∂F/∂ρ], [S, 0]] "
        "(3n × 3n; S has (c_i, s_i) in row i; ∂F/∂ρ has −c_i and +s_i in the rows of pose i), "
        "solve J Δ = −F, return (t + Δt, ρ + Δρ).",
    )
    A, b, t, rho, t_on, rho_on, solution = _newton_problem()
    n = rho.size
    value, problem = call_student(
        newton_step, A.copy(), b.copy(), t.copy(), rho.copy(), name="newton_step"
    )
    if problem is None:
        value, problem = _unpack(value, n)
    if problem is not None:
        return verdict(ex, problem, hint=hint)
    t_new, rho_new = value
    t_ref, rho_ref = newton_reference(A, b, t, rho)
    if not (_close(t_new, t_ref) and _close(rho_new, rho_ref)):
        for (t_c, rho_c), diagnosis in _newton_mistakes(A, b, t, rho):
            if _close(t_new, t_c, rtol=1e-6, atol=1e-8) and _close(rho_new, rho_c, 1e-6, 1e-8):
                return verdict(ex, diagnosis, hint=hint)
        dt = t_new - t
        c, s = t[0::2], t[1::2]
        linear = c * dt[0::2] + s * dt[1::2] + 0.5 * (c**2 + s**2 - 1)  # 0 for a Newton step
        if np.abs(linear).max() > 1e-6:
            return verdict(
                ex,
                "your step ignores the constraint rows: a Newton step satisfies their "
                "linearization c_i Δc_i + s_i Δs_i = −(c_i² + s_i² − 1)/2, and yours misses it "
                f"by up to {np.abs(linear).max():.3g} (pose {int(np.argmax(np.abs(linear))) + 1}"
                ").",
                hint=hint,
            )
        problem = compare_array(t_new, t_ref, name="t_new") or compare_array(
            rho_new, rho_ref, name="rho_new"
        )
        return verdict(ex, problem, hint=hint)

    # iterate the student's step from the odometry's orientations, as solve_orthogonality does
    tk, rk = t_on.copy(), rho_on.copy()
    norms = [np.abs(orthogonality_residual(A, b, tk, rk)).max()]
    while norms[-1] > 1e-10 and len(norms) <= 20:
        value, problem = call_student(newton_step, A.copy(), b.copy(), tk, rk)
        if problem is None:
            value, problem = _unpack(value, n)
        if problem is not None:
            return verdict(ex, f"one step was right, but iterating it failed: {problem}", hint=hint)
        tk, rk = value
        norms.append(np.abs(orthogonality_residual(A, b, tk, rk)).max())
    diff = max(np.abs(tk - solution.t).max(), np.abs(rk - solution.rho).max())
    if norms[-1] > 1e-10 or diff > 1e-7:
        return verdict(
            ex,
            f"one step matches lagolib's, but iterating it from the odometry's orientations "
            f"ends at max |F| = {norms[-1]:.2g}, {diff:.2g} away from lagolib's solution.",
            hint="return new arrays; do not modify A, b, t or rho in place.",
        )
    step_diff = max(np.abs(t_new - t_ref).max(), np.abs(rho_new - rho_ref).max())
    return verdict(
        ex,
        None,
        correct=f"your step matches lagolib's to {step_diff:.1e} "
        f"(n = {n}, a start off the unit circles). Iterated from the odometry's orientations it "
        f"reaches lagolib's solution in {len(norms) - 1} steps (difference {diff:.1e}); max |F|: "
        + " → ".join(f"{x:.1e}" for x in norms)
        + ".",
    )


# --------------------------------------------------------------------------------------------
# Exercise 7.3 — predict: the closed form's weighted χ² on grid100

#: The answers of exercise 7.3: where ``χ²(closed form) / χ²(Gauss–Newton)`` lies, weighted χ².
GAP_BANDS = ("below 1", "1 to 1.05", "1.05 to 2", "above 2")


def _band(ratio):
    if ratio < 1 - 1e-9:
        return GAP_BANDS[0]
    if ratio <= 1.05:
        return GAP_BANDS[1]
    if ratio <= 2:
        return GAP_BANDS[2]
    return GAP_BANDS[3]


def weighted_gap(graph):
    """``(χ²_closed, χ²_LAGO, χ²_GN)``: the lecture notes' weighted χ² of the closed form (from
    LAGO), of LAGO, and of Gauss–Newton from LAGO (the optimum)."""
    lag = lago_solve(graph)
    closed = cf.closed_form(graph, initial=lag.poses)  # the same as initial="lago"
    best = optimize(graph, lag.poses)
    return chi2(graph, closed.poses), chi2(graph, lag.poses), best.chi2


@check("7.3", prediction=Choice(GAP_BANDS))
def check_closed_form_gap(prediction) -> bool:
    """Exercise 7.3: predict ``χ²(closed form) / χ²(optimum)`` of the weighted χ² on grid100.

    Computes, on the shipped ``grid100`` example (σ_xy = 0.05 m, σ_θ = 0.01 rad: an angle 25×
    more informative than a coordinate), the lecture notes' weighted χ² of the closed form (from
    LAGO) and of Gauss–Newton's optimum, and compares the band their ratio falls in with
    ``prediction``, one of :data:`GAP_BANDS`.  Both χ² and the ratio are printed with a right
    answer; after a wrong one they are the last hint level.

    Parameters
    ----------
    prediction : str
        ``"below 1"``, ``"1 to 1.05"``, ``"1.05 to 2"`` or ``"above 2"``.

    Returns
    -------
    bool
    """
    ex = "7.3"
    if is_placeholder(prediction):
        return verdict(ex, NOT_ATTEMPTED)
    problem = compare_choice(prediction, GAP_BANDS[0], GAP_BANDS, name="prediction")
    if problem is not None and problem.startswith("prediction should be one of"):
        return verdict(ex, problem, hint="write your prediction as one of the four strings.")
    g = datasets.example("grid100").graph
    closed, lag, best = weighted_gap(g)
    ratio = closed / best
    actual = _band(ratio)
    numbers = (
        f"weighted χ² on grid100: closed form {closed:.4f}, LAGO {lag:.4f}, Gauss–Newton "
        f"{best:.4f}; closed form / optimum = {ratio:.3f} ({actual})"
    )
    problem = compare_choice(prediction, actual, GAP_BANDS, name="your prediction")
    if problem is None:
        return verdict(ex, None, correct=numbers + ".")
    why = {
        GAP_BANDS[0]: "Gauss–Newton minimizes exactly this weighted χ²: nothing is below it.",
        GAP_BANDS[1]: "'1 to 1.05' is what happens when Ω is a multiple of I; here an angle "
        "weighs 25× a coordinate, and the closed form weighs them alike.",
        GAP_BANDS[2]: "the gap is larger than that: the closed form trades the heavily weighted "
        "angular errors for position errors.",
        GAP_BANDS[3]: "the gap is smaller than that.",
    }[prediction]  # one of GAP_BANDS, as @check read it
    problem = f"prediction = {prediction!r} is not the band the ratio falls in."
    if prediction == GAP_BANDS[0]:
        problem += " " + why  # a ratio below 1 is impossible: that is the diagnosis itself
    return verdict(
        ex,
        problem,
        hint=(
            "which cost does each method minimize, and how different are the two costs here?",
            why[:1].upper() + why[1:],
            f"the check's numbers: {numbers}.",
        ),
    )


# --------------------------------------------------------------------------------------------
# Exercise 7.4 — explore: noise level or noise ratio?

#: The position noise held fixed in the first sweep of exercise 7.4 (metres).
SIGMA_XY = 0.05
#: The σ values of exercise 7.4's sweeps.
SIGMA_SWEEP = (0.0125, 0.025, 0.05, 0.1, 0.2)
#: The answers of exercise 7.4's ``what_decides``.
DECIDES = ("level", "ratio")


@lru_cache(maxsize=None)
def _gap(sigma_xy, sigma_theta):
    g = simulate.grid_world(rng=0, sigma_xy=sigma_xy, sigma_theta=sigma_theta).graph
    closed, _, best = weighted_gap(g)
    return closed / best


@check("7.4", closest_sigma_theta=Real(), what_decides=Choice(DECIDES))
def check_noise_gap(closest_sigma_theta, what_decides) -> bool:
    """Exercise 7.4: what decides how far the closed form is from the optimum.

    Recomputes the first sweep of the exercise (10×10 grid, ``rng=0``, σ_xy = :data:`SIGMA_XY`,
    σ_θ over :data:`SIGMA_SWEEP`; weighted χ² of the closed form over Gauss–Newton's), compares
    ``closest_sigma_theta`` with the σ_θ of the smallest ratio (to 1e-9) and ``what_decides``
    with ``"ratio"`` (:data:`DECIDES`); to a wrong ``what_decides`` it shows the ends of the
    second sweep (σ_xy = σ_θ).

    Parameters
    ----------
    closest_sigma_theta : float
        The σ_θ of the first sweep at which the closed form is closest to the optimum.
    what_decides : str
        ``"level"`` (the amount of noise) or ``"ratio"`` (σ_θ / σ_xy).

    Returns
    -------
    bool
    """
    ex = "7.4"
    if is_placeholder(closest_sigma_theta) or is_placeholder(what_decides):
        return verdict(ex, NOT_ATTEMPTED)
    problem = compare_choice(what_decides, "ratio", DECIDES, name="what_decides")
    if problem is not None and problem.startswith("what_decides should be one of"):
        return verdict(ex, problem, hint='write "level" or "ratio".')
    gaps = np.array([_gap(SIGMA_XY, s) for s in SIGMA_SWEEP])
    best = SIGMA_SWEEP[int(np.argmin(gaps))]
    problem = compare_number(closest_sigma_theta, best, name="closest_sigma_theta", rtol=1e-9)
    if problem is not None:
        # closest_sigma_theta is one finite real number: @check read it
        hits = [k for k, s in enumerate(SIGMA_SWEEP) if np.isclose(s, closest_sigma_theta)]
        if hits:
            problem = (
                f"at σ_θ = {closest_sigma_theta} the closed form's χ² is {gaps[hits[0]]:.3f} "
                "times the optimum's, not the smallest ratio in the sweep."
            )
        else:
            problem = (
                f"closest_sigma_theta should be one of the swept σ_θ {list(SIGMA_SWEEP)}, "
                f"got {closest_sigma_theta!r:.40}."
            )
        table = ", ".join(f"σ_θ = {s}: {r:.4f}" for s, r in zip(SIGMA_SWEEP, gaps))
        return verdict(
            ex,
            problem,
            hint=(
                "read the σ_θ of the smallest ratio off the first table.",
                f"the check's first sweep (σ_xy = {SIGMA_XY}), closed form / optimum: {table}.",
            ),
        )
    level_gap = max(abs(_gap(s, s) - 1.0) for s in SIGMA_SWEEP)  # the σ_θ = σ_xy sweep
    if what_decides != "ratio":  # one of DECIDES, as @check read it
        level = [_gap(s, s) for s in (SIGMA_SWEEP[0], SIGMA_SWEEP[-1])]
        return verdict(
            ex,
            f"what_decides = {what_decides!r} is not what the two sweeps show.",
            hint=(
                "compare the two columns of the table: which one changes?",
                f"with σ_θ = σ_xy the ratio stays {level[0]:.6f} at σ = {SIGMA_SWEEP[0]} and "
                f"{level[1]:.6f} at σ = {SIGMA_SWEEP[-1]}, 16 times more noise; with σ_xy "
                f"fixed it ranges from {gaps.min():.4f} to {gaps.max():.3f}.",
            ),
        )
    return verdict(
        ex,
        None,
        correct=f"the closed form is closest at σ_θ = σ_xy = {best} (ratio {gaps.min():.6f}) and "
        f"up to {gaps.max():.3f} times the optimum elsewhere in the sweep, while σ_θ = σ_xy keeps "
        f"the ratio within {level_gap:.0e} of 1 over the whole sweep, 16 times more noise: the "
        "ratio of the noises decides, not their level.",
    )


# --- derive exercises ---
# Exercise 7.5 (derive) — :func:`check_gradient_entry`: one entry of the gradient of Lodi
# Rizzini's χ² (eq. 14–15), ∂F/∂c_i of one edge's F = e_ijᵀ e_ij with e_ij of eq. (2)–(3), the
# four parameters (x, y, c, s) of each pose treated as independent, as the Lagrangian does.

import sympy as _sp  # noqa: E402

from lagolib.exercises._derive import Formula, formula_comparison  # noqa: E402

#: exercise 7.5's symbols: pose i, pose j (x, y, c, s) and the measurement (x_z, y_z, c_z, s_z)
GRADIENT_SYMBOLS = _sp.symbols("x_i y_i c_i s_i x_j y_j c_j s_j x_z y_z c_z s_z", real=True)


def sincos_edge_error():
    """``e_ij`` of Lodi Rizzini eq. (2)–(3) in :data:`GRADIENT_SYMBOLS`, a sympy 4-vector."""
    xi, yi, ci, si, xj, yj, cj, sj, xz, yz, cz, sz = GRADIENT_SYMBOLS
    dx, dy = xj - xi, yj - yi
    f = _sp.Matrix([ci * dx + si * dy, -si * dx + ci * dy, cj * ci + sj * si, sj * ci - cj * si])
    return f - _sp.Matrix([xz, yz, cz, sz])  # eq. (2) minus the measurement, eq. (3)


def gradient_entry_reference():
    """``∂F/∂c_i`` of ``F = e_ijᵀ e_ij`` (Lodi Rizzini eq. 14–15 for one edge), by sympy."""
    e = sincos_edge_error()
    return _sp.diff((e.T * e)[0, 0], GRADIENT_SYMBOLS[2])


def _gradient_slips():
    e = sincos_edge_error()
    ci = GRADIENT_SYMBOLS[2]
    half = _sp.diff((e.T * e)[0, 0], ci) / 2
    position_only = _sp.diff((e[:2, 0].T * e[:2, 0])[0, 0], ci)
    angle_only = _sp.diff((e[2:, 0].T * e[2:, 0])[0, 0], ci)
    return [
        (half, "that is half of it: the derivative of e² is 2e·∂e, and F sums the squares."),
        (position_only, "only the position rows of e_ij are there: c_i also appears in the two "
         "angular rows, c_j c_i + s_j s_i and s_j c_i − c_j s_i."),
        (angle_only, "only the angular rows of e_ij are there: c_i also rotates t_j − t_i in "
         "the two position rows."),
    ]


_GRADIENT_HINTS = (
    "F = Σ_k e_k², so ∂F/∂c_i = 2 Σ_k e_k ∂e_k/∂c_i: find which of the four rows of e_ij "
    "contain c_i, and differentiate each.",
    "∂e/∂c_i = (x_j − x_i, y_j − y_i, c_j, s_j): each row of e_ij is linear in c_i.",
    "so ∂F/∂c_i = 2 [e_1 (x_j − x_i) + e_2 (y_j − y_i) + e_3 c_j + e_4 s_j], each e_k written "
    "out with eq. (2)–(3).",
)


@check("7.5", dF_dc_i=Formula(GRADIENT_SYMBOLS, example="2*(x_j - x_i)*c_i"))
def check_gradient_entry(dF_dc_i) -> bool:
    """Exercise 7.5: ``∂F/∂c_i`` of one edge's ``F = e_ijᵀ e_ij`` (Lodi Rizzini eq. 14–15).

    The answer is a formula (a string sympy reads, or a sympy expression) in
    :data:`GRADIENT_SYMBOLS`; it is compared with :func:`gradient_entry_reference` by symbolic
    equivalence (:func:`lagolib.exercises._derive.formula_comparison`).
    """
    result = formula_comparison(
        dF_dc_i,
        gradient_entry_reference(),
        symbols=GRADIENT_SYMBOLS,
        name="your ∂F/∂c_i",
        slips=_gradient_slips(),
    )
    if result.problem is not None:
        return verdict("7.5", result.problem, hint=_GRADIENT_HINTS)
    return verdict("7.5", None, correct=f"your ∂F/∂c_i is the gradient's entry: {result.detail}.")
