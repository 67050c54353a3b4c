"""Checks for the exercises of chapter 8 (Carlone et al. 2011, §V reproduced), and a helper.

=========  =========  ==========================================================================
exercise   kind       check
=========  =========  ==========================================================================
8.1        implement  :func:`check_eta` — the constraint-satisfaction metrics ``eta_c``,
                      ``eta_a`` of Kümmerle et al. 2009 for a graph and poses
8.2        predict    :func:`check_smallest_sum` — with ``P_ij = I_3``, which estimate has the
                      smallest ``eta_c + eta_a``: SGD, LAGO or Gauss–Newton?
8.3        explore    :func:`check_weight_sweep` — how ``eta_c`` and ``eta_a`` of the optimum move
                      when the angles' weight grows
=========  =========  ==========================================================================

:func:`angle_weight_sweep` computes exercise 8.3's sweep (the chapter's cell and the check use the
same numbers).

Every check prints one line, ``Exercise 8.k — correct: …``, ``— not yet: …`` (what is wrong and by
how much, never the answer; ``hint(…)`` tells more, one level per call) or
``— not attempted yet: …``, and returns True or False; it never raises on
a wrong answer (see :mod:`lagolib.exercises._feedback`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from lagolib import lago_solve, optimize, se2, simulate
from lagolib.exercises._coerce import Choice, Function, Real, Tuple
from lagolib.exercises._feedback import (
    NOT_ATTEMPTED,
    call_student,
    check,
    compare_choice,
    compare_number,
    is_placeholder,
    verdict,
)
from lagolib.metrics import constraint_satisfaction

__all__ = [
    "WEIGHTS",
    "SMALLEST_CHOICES",
    "TREND_CHOICES",
    "angle_weight_sweep",
    "check_eta",
    "check_smallest_sum",
    "check_weight_sweep",
]

#: The angles' weights ``w`` of exercise 8.3: information ``diag(1, 1, w)`` on every edge.
WEIGHTS = (0.01, 0.1, 1.0, 10.0, 100.0)
#: The answers exercise 8.2 accepts.
SMALLEST_CHOICES = ("SGD", "LAGO", "Gauss-Newton")
#: The answers exercise 8.3 accepts for a trend.
TREND_CHOICES = ("increases", "decreases", "neither")


# --------------------------------------------------------------------------- exercise 8.1
@lru_cache(maxsize=1)
def _eta_cases():
    """Seeded test graphs and poses for exercise 8.1.

    Two laps of a square (16 poses, 23 edges) with anisotropic, rotated information (so an answer
    that weights the errors by it is wrong), evaluated at poses that are off the truth by
    centimetres and a few degrees, with some headings stored 2π or 4π away (so an unwrapped angle
    is wrong), and at the odometry guess.
    """
    rng = np.random.default_rng(801)
    sim = simulate.loop_world(laps=2, poses_per_lap=8, rng=rng, sigma_xy=0.05, sigma_theta=0.03)
    g = sim.graph
    axis = se2.rotation(rng.uniform(-np.pi, np.pi, g.m))
    cov = axis @ np.diag([0.01**2, 0.2**2]) @ np.swapaxes(axis, 1, 2)
    info = np.zeros((g.m, 3, 3))
    info[:, :2, :2] = np.linalg.inv(cov)
    info[:, 2, 2] = 1.0 / 0.03**2
    g = g.with_information(info)
    moved = sim.truth + np.column_stack(
        [0.05 * rng.standard_normal((g.n, 2)), 0.08 * rng.standard_normal(g.n)]
    )
    moved[1:, 2] += 2 * np.pi * rng.integers(-2, 3, g.n - 1)  # unwrapped headings
    return ((g, moved), (g, g.odometry_guess()))


def _errors(graph, poses, *, frame="measurement", wrap=True):
    """Per-edge translation error vectors (m, 2) and angle errors (m,), for the diagnoses."""
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    p = np.asarray(poses, dtype=float)
    z = graph.measurements
    d = p[j, :2] - p[i, :2]
    if frame == "global":  # t_j - t_i - t_z: no rotation at all
        t = d - z[:, :2]
    else:
        Ri = se2.rotation(p[i, 2])
        t = np.einsum("kba,kb->ka", Ri, d) - z[:, :2]  # R_i^T (t_j - t_i) - t_z
    a = p[j, 2] - p[i, 2] - z[:, 2]
    return t, (se2.wrap_angle(a) if wrap else a)


def _diagnose_eta(got, graph, poses, expected):
    """(problem, hint) for a wrong ``(eta_c, eta_a)`` (two floats, as call_student read them);
    (None, "") when right."""
    ec, ea = expected
    pc = compare_number(got[0], ec, name="eta_c", rtol=1e-6, atol=1e-15)
    pa = compare_number(got[1], ea, name="eta_a", rtol=1e-6, atol=1e-15)
    if pc is None and pa is None:
        return None, ""
    gc, ga = got

    def near(x, y):
        return bool(np.isclose(x, y, rtol=1e-6, atol=1e-15))

    m = graph.m
    method = (
        "for every edge (i, j): E = Z⁻¹ X_i⁻¹ X_j (chapter 1's error, se2.between twice); "
        "eta_c is the mean over all edges of ||t(E)||², eta_a the mean of θ(E)² with θ(E) "
        "wrapped into (−π, π].",
        "with x = poses and i, j = graph.edges.T: se2.between(x[i], x[j]) is X_i⁻¹ X_j for every "
        "edge at once, and se2.between(graph.measurements, that) is Z⁻¹ X_i⁻¹ X_j; square, "
        "sum the translation's two entries, average over the edges.",
    )
    if near(gc, ea) and near(ga, ec):
        return (
            "your two numbers are swapped: the first should be eta_c (translation, m²), the "
            "second eta_a (angle, rad²).",
            ("return eta_c, eta_a — in that order.",),
        )
    if near(gc, m * ec) or near(ga, m * ea):
        return (
            f"your numbers are {m} times too large — the sum over the {m} edges, not the mean.",
            ("eta is a mean over all constraints: divide by the number of edges (np.mean).",),
        )
    if near(gc, np.sqrt(ec)) or near(ga, np.sqrt(ea)):
        return (
            "your numbers are the square roots of the reference: a root mean square, not the "
            "mean squared error.",
            ("eta_c is the mean of ||t||², in m² — no square root.",),
        )
    t, a = _errors(graph, poses, wrap=False)
    if pc is None and near(ga, np.mean(a**2)):
        return (
            f"eta_a = {ga:.6g} is too large: the angle errors were not wrapped. Some headings "
            "here are stored 2π or 4π away from each other, so θ_j − θ_i − δ_ij is off by whole "
            "turns.",
            ("wrap each angle error into (-π, π] with lagolib.se2.wrap_angle before squaring it.",),
        )
    tg, _ = _errors(graph, poses, frame="global")
    if pa is None and near(gc, np.mean(np.sum(tg**2, axis=1))):
        return (
            f"eta_c = {gc:.6g} is not right: you compared t_j − t_i, a difference in the world "
            "frame, with t_z, which is measured in the frame of pose i.",
            (
                "rotate first: pose j seen from pose i (lagolib.se2.between(x_i, x_j) gives "
                "R_iᵀ (t_j − t_i)), then compare it with the measurement.",
                *method,
            ),
        )
    e = np.column_stack([*_errors(graph, poses)[0].T, _errors(graph, poses)[1]])
    # the error in the measurement's frame: rotate the frame-i translation by R_z^T
    e[:, :2] = np.einsum("kba,kb->ka", se2.rotation(graph.measurements[:, 2]), e[:, :2])
    chi = np.einsum("ka,kab,kb->k", e, graph.information, e)
    if near(gc, np.mean(chi)) or near(gc + ga, np.mean(chi)) or near(gc, chi.sum()):
        return (
            "your number is weighted by the information matrices (a χ²). The constraint-"
            "satisfaction metrics count every constraint equally, whatever its uncertainty.",
            ("square the plain translation and angle errors; leave graph.information out.",),
        )
    tr, ar = _errors(graph, poses)
    for mask, which in (
        (graph.loop_closure, "loop closures"),
        (graph.odometric, "odometric edges"),
    ):
        if mask.any() and (
            near(gc, np.mean(np.sum(tr[mask] ** 2, axis=1))) or near(ga, np.mean(ar[mask] ** 2))
        ):
            return (
                f"your numbers are means over the {which} only.",
                (f"eta averages over all {m} constraints, odometric edges and loop closures "
                 "alike.",),
            )
    return " ".join(x for x in (pc, pa) if x), (
        "print your (eta_c, eta_a) next to lagolib.metrics.constraint_satisfaction on the "
        "chapter's graph (the cell under the exercise does) and find which one differs.",
        *method,
    )


_ETA = Tuple(
    Real(),
    Real(),
    names=("eta_c", "eta_a"),
    what="two numbers, (eta_c, eta_a)",
    hint="end the function with `return eta_c, eta_a`.",
)


@check("8.1", eta=Function(_ETA))
def check_eta(eta):
    """Check exercise 8.1: ``eta(graph, poses)``, the constraint-satisfaction metrics.

    Calls the student's function on two seeded graphs-and-poses (:func:`_eta_cases`: anisotropic,
    rotated information; headings stored whole turns apart; the odometry guess) and compares
    ``(eta_c, eta_a)`` with :func:`lagolib.metrics.constraint_satisfaction` to ``1e-6``
    relative.  Diagnoses swapped outputs, a sum instead of a mean, a root mean square, unwrapped
    angles, the world-frame difference ``t_j − t_i − t_z`` and an information-weighted error.

    Parameters
    ----------
    eta : callable
        ``(graph PoseGraph, poses (n, 3)) -> (eta_c, eta_a)``.

    Returns
    -------
    bool
    """
    ex = "8.1"
    cases = _eta_cases()
    for k, (g, poses) in enumerate(cases):
        got, problem = call_student(eta, g, poses.copy(), name="eta")
        if problem == NOT_ATTEMPTED:
            return verdict(ex, problem)
        if problem is not None:
            return verdict(
                ex,
                problem,
                hint=(
                    "the check calls eta(graph, poses) with a lagolib.PoseGraph and an (n, 3) "
                    "array, and expects `return eta_c, eta_a` (two real numbers, or a numpy "
                    "array of two); try your function on such inputs.",
                ),
            )
        expected = tuple(constraint_satisfaction(g, poses))
        problem, hint = _diagnose_eta(got, g, poses, expected)
        if problem is not None:
            return verdict(ex, f"on test {k + 1} of {len(cases)}: " + problem, hint=hint)
    return verdict(
        ex,
        None,
        correct=f"(eta_c, eta_a) equal lagolib.metrics.constraint_satisfaction on all "
        f"{len(cases)} test cases (anisotropic information, headings whole turns apart).",
    )


# --------------------------------------------------------------------------- exercise 8.2
@check("8.2", smallest=Choice(SMALLEST_CHOICES))
def check_smallest_sum(smallest, graph, sgd_poses):
    """Check exercise 8.2: with ``P_ij = I_3``, which estimate has the smallest ``eta_c + eta_a``?

    Computes LAGO and Gauss–Newton from LAGO on ``graph`` (which must have identity information
    on every edge) with lagolib, and ``eta_c + eta_a`` of the three estimates (``sgd_poses`` is
    the chapter's SGD run); the answer is the one with the smallest sum.  Prints the three sums
    with a right answer; after a wrong one they are the last hint level.

    Parameters
    ----------
    smallest : {"SGD", "LAGO", "Gauss-Newton"}
    graph : PoseGraph
        The ``P_ij = I_3`` scenario.
    sgd_poses : array_like, shape (n, 3)

    Returns
    -------
    bool
    """
    ex = "8.2"
    if is_placeholder(smallest):
        return verdict(ex, NOT_ATTEMPTED)
    if not np.allclose(graph.information, np.eye(3)):
        raise ValueError("check_smallest_sum needs the P = I_3 graph (identity information)")
    lg = lago_solve(graph, margin_warning=0)
    gn = optimize(graph, lg.poses)
    sums = {
        "SGD": sum(constraint_satisfaction(graph, sgd_poses)),
        "LAGO": sum(constraint_satisfaction(graph, lg.poses)),
        "Gauss-Newton": sum(constraint_satisfaction(graph, gn.poses)),
    }
    expected = min(sums, key=sums.get)
    facts = "eta_c + eta_a: " + ", ".join(f"{k} {v:.4g}" for k, v in sums.items())
    problem = compare_choice(smallest, expected, SMALLEST_CHOICES, name="smallest")
    if problem is None:
        return verdict(ex, None, correct=facts + ".")
    if problem.startswith("smallest should be"):
        return verdict(ex, problem, hint='write smallest = "SGD", "LAGO" or "Gauss-Newton".')
    return verdict(
        ex,
        f"smallest = {smallest!r} is not the estimate with the smallest eta_c + eta_a.",
        hint=(
            "with identity information, what is χ² divided by the number of edges?",
            "with P_ij = I_3, χ² = m (eta_c + eta_a) (section 1): which of the three methods "
            "minimizes χ²?",
            f"the check's numbers: {facts}.",
        ),
    )


# --------------------------------------------------------------------------- exercise 8.3
_SWEEP_CACHE: dict = {}


def angle_weight_sweep(graph, weights=WEIGHTS):
    """``eta_c`` and ``eta_a`` at the Gauss–Newton optimum for information ``diag(1, 1, w)``.

    For each ``w`` in ``weights`` every edge of ``graph`` gets the information ``diag(1, 1, w)``
    (:meth:`lagolib.PoseGraph.with_information`); LAGO initializes :func:`lagolib.optimize`, and the optimum's
    :func:`~lagolib.metrics.constraint_satisfaction` is returned.  With this information
    ``χ² = m (eta_c + w eta_a)``: the optimum minimizes a weighted sum of the two metrics.  The
    last result is cached (the chapter's cell and :func:`check_weight_sweep` share it).

    Parameters
    ----------
    graph : PoseGraph
    weights : sequence of float
        Positive.

    Returns
    -------
    ndarray, shape (len(weights), 2)
        ``[eta_c, eta_a]`` per weight.
    """
    key = (id(graph), tuple(float(w) for w in weights))
    hit = _SWEEP_CACHE.get("last")
    if hit is not None and hit[0] == key and hit[1] is graph:
        return hit[2].copy()
    rows = []
    for w in key[1]:
        g = graph.with_information(np.diag([1.0, 1.0, w]))
        gn = optimize(g, lago_solve(g, margin_warning=0).poses)
        rows.append(tuple(constraint_satisfaction(g, gn.poses)))
    out = np.array(rows)
    _SWEEP_CACHE["last"] = (key, graph, out)
    return out.copy()


def _trend(values):
    d = np.diff(values)
    if np.all(d > 0):
        return "increases"
    if np.all(d < 0):
        return "decreases"
    return "neither"


@check(
    "8.3",
    eta_c_trend=Choice(TREND_CHOICES),
    eta_a_trend=Choice(TREND_CHOICES),
    eta_a_ratio=Real(),
)
def check_weight_sweep(eta_c_trend, eta_a_trend, eta_a_ratio, graph):
    """Check exercise 8.3: the trends of ``eta_c``, ``eta_a`` as the angles' weight grows.

    Recomputes :func:`angle_weight_sweep` on ``graph`` for :data:`WEIGHTS` and compares: each
    trend (``"increases"``, ``"decreases"`` or ``"neither"`` — strictly at every step), and
    ``eta_a_ratio``, ``eta_a`` at the smallest weight divided by ``eta_a`` at the largest, to 5 %
    (enough for a number read off the printed table).

    Parameters
    ----------
    eta_c_trend, eta_a_trend : {"increases", "decreases", "neither"}
    eta_a_ratio : float
    graph : PoseGraph

    Returns
    -------
    bool
    """
    ex = "8.3"
    if any(is_placeholder(a) for a in (eta_c_trend, eta_a_trend, eta_a_ratio)):
        return verdict(ex, NOT_ATTEMPTED)
    table = angle_weight_sweep(graph)
    want_c, want_a = _trend(table[:, 0]), _trend(table[:, 1])
    ratio = float(table[0, 1] / table[-1, 1])
    hint = (
        "read the printed table from the top (w = 0.01) to the bottom (w = 100): does each "
        "column go up at every row, down at every row, or neither?",
        "with information diag(1, 1, w) the optimum minimizes m (eta_c + w eta_a): the larger "
        "w, the more an angle error costs compared with a translation error.",
    )
    for got, want, name in (
        (eta_c_trend, want_c, "eta_c_trend"),
        (eta_a_trend, want_a, "eta_a_trend"),
    ):
        problem = compare_choice(got, want, TREND_CHOICES, name=name)
        if problem is not None:
            if problem.startswith(f"{name} should be"):
                return verdict(ex, problem, hint=hint[:1])
            col = table[:, 0] if name == "eta_c_trend" else table[:, 1]
            column = (
                f"the check's {name[:5]} column, w = {WEIGHTS[0]:g} … {WEIGHTS[-1]:g}: "
                + ", ".join(f"{v:.3g}" for v in col)
                + "."
            )
            return verdict(ex, problem, hint=(*hint, column))
    problem = compare_number(eta_a_ratio, ratio, name="eta_a_ratio", rtol=0.05)
    if problem is not None:
        if np.isclose(eta_a_ratio, 1.0 / ratio, rtol=0.05):  # a float: @check read it
            problem = (
                f"eta_a_ratio is {float(eta_a_ratio):.3g}, the inverse of the ratio asked for: "
                f"eta_a at w = {WEIGHTS[0]} divided by eta_a at w = {WEIGHTS[-1]}."
            )
        return verdict(
            ex,
            problem,
            hint=(
                f"divide the first row's eta_a (w = {WEIGHTS[0]:g}) by the last row's "
                f"(w = {WEIGHTS[-1]:g}).",
                "the check's eta_a column: " + ", ".join(f"{v:.4g}" for v in table[:, 1]) + ".",
            ),
        )
    return verdict(
        ex,
        None,
        correct=f"as the angles' weight grows from {WEIGHTS[0]} to {WEIGHTS[-1]}, eta_c {want_c} "
        f"and eta_a {want_a} (by a factor {ratio:.3g}).",
    )
