"""Checks for the exercises of chapter 11, *When loop closures lie* (``book/11_outliers.ipynb``),
and the chapter's shared computations.

=========  =========  ==========================================================================
exercise   kind       check
=========  =========  ==========================================================================
11.1       implement  :func:`check_dcs_weight` — the IRLS weight of dynamic covariance scaling,
                      ``w(r) = min(1, 2Φ/(Φ + r²))²``, compared with
                      :meth:`lagolib.kernels.DCS.weight` at many residuals and three Φ
11.2       derive     :func:`check_gm_influence` — the influence ψ(r) = dρ/dr of the
                      Geman–McClure kernel, a formula in r and c, by symbolic equivalence
11.3       predict    :func:`check_most_downweighted` — which of four labelled loop closures
                      (:func:`candidates`) a Cauchy kernel down-weights most
11.4       explore    :func:`check_breaking_ratio` — the smallest outlier ratio of
                      :data:`RATIOS` at which IRLS with the Cauchy kernel breaks the map
                      (:func:`ratio_sweep`)
=========  =========  ==========================================================================

:func:`world` is the chapter's synthetic world (a sparse Manhattan walk with ground truth);
:func:`candidates` builds exercise 11.3's four closures; :func:`ratio_sweep` runs exercise 11.4's
sweep (the chapter's cell and the check share it, cached).

Every check prints one line, ``Exercise 11.k — correct: …``, ``— not yet: …`` (what is wrong and by
how much, never the answer; ``hint(…)`` tells more, one level per call) or
``— not attempted yet: …``, and returns True or False; it never raises on a wrong answer (see
:mod:`lagolib.exercises._feedback`).
"""

from __future__ import annotations

import copy
import math
import time
from functools import lru_cache

import numpy as np

import lagolib
from lagolib import kernels, metrics, robust, se2, simulate
from lagolib.exercises._coerce import Choice, Function, Real, RealArray
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
    "WORLD",
    "LABELS",
    "CANDIDATES",
    "RATIOS",
    "BREAK_FACTOR",
    "SWEEP_METHOD",
    "PHIS",
    "world",
    "candidates",
    "ratio_sweep",
    "check_dcs_weight",
    "check_gm_influence",
    "gm_influence_reference",
    "GM_SYMBOLS",
    "check_most_downweighted",
    "check_breaking_ratio",
]

#: The chapter's world: :func:`lagolib.simulate.manhattan_world` with these options — 300 poses,
#: few loop closures (a sparse graph: each closure matters), heading noise 0.02 rad per edge.
WORLD = dict(n_poses=300, rng=1, closure_probability=0.05, sigma_theta=0.02)

#: Exercise 11.1: the values of Φ (χ² units) the check tries, the middle one the default
#: ``INLIER_THRESHOLD²``.
PHIS = (1.0, kernels.INLIER_THRESHOLD**2, 100.0)

#: Exercise 11.3's closures: label -> (i, j, offset along x of frame i in metres, σ_xy in metres).
#: The measurement is the true relative pose of ``j`` seen from ``i``, moved by the offset; the
#: information is ``diag(σ_xy⁻², σ_xy⁻², σ_θ⁻²)`` with the world's σ_θ.
CANDIDATES = {
    "A": (40, 120, 0.0, 0.05),
    "B": (60, 180, 1.0, 0.05),
    "C": (90, 250, 6.0, 1.0),
    "D": (150, 280, 0.4, 0.1),
}
#: The labels of exercise 11.3's answer.
LABELS = tuple(CANDIDATES)

#: Exercise 11.4: wrong closures per right closure.
RATIOS = (0.5, 1.0, 2.0, 4.0, 8.0)
#: A map "breaks" when its ATE exceeds this many times the outlier-free optimum's.
BREAK_FACTOR = 2.0
#: The method exercise 11.4 asks about (:func:`lagolib.robust.solve`'s name).
SWEEP_METHOD = "cauchy"
#: The seed of exercise 11.4's wrong closures (:func:`lagolib.simulate.add_outliers`).
SWEEP_SEED = 0


@lru_cache(maxsize=1)
def world():
    """The chapter's world, :func:`lagolib.simulate.manhattan_world` with :data:`WORLD`."""
    return simulate.manhattan_world(**WORLD)


# --------------------------------------------------------------------------- exercise 11.1
def _dcs_slips(r, phi):
    """The usual wrong DCS weights: (name, values, sentence, hint)."""
    s = 2.0 * phi / (phi + r * r)
    return (
        (
            "s",
            np.minimum(1.0, s),
            "your weight is the switch s itself; DCS scales the information by s² (the switch "
            "multiplies the whitened residual, so its square multiplies e^T Ω e).",
            "square the scaling: w = s².",
        ),
        (
            "no min",
            s**2,
            "your weight exceeds 1 for small residuals: the scaling s is clipped at 1 (a close "
            "edge keeps its full information, no more).",
            "s = min(1, 2Φ/(Φ + r²)).",
        ),
        (
            "r not squared",
            np.minimum(1.0, 2.0 * phi / (phi + r)) ** 2,
            "your weight falls too slowly: Φ is in χ² units, so it is compared with r², not r.",
            "the denominator is Φ + r².",
        ),
        (
            "sqrt phi",
            np.minimum(1.0, 2.0 * math.sqrt(phi) / (math.sqrt(phi) + r * r)) ** 2,
            "your weight uses √Φ where the formula has Φ (Φ is already in χ² units).",
            "s = min(1, 2Φ/(Φ + r²)) with Φ itself.",
        ),
    )


@check("11.1", dcs_weight=Function(RealArray()))
def check_dcs_weight(dcs_weight):
    """Check exercise 11.1: ``dcs_weight(r, phi)``, the IRLS weight of DCS for an array ``r``.

    Calls the student's function on 201 residual norms ``r`` from 0 to 40 (shape (201,)) for
    each Φ of :data:`PHIS` and compares with ``lagolib.kernels.DCS(sqrt(Φ)).weight(r)`` to 1e-9
    relative.  Names the usual slips: the switch ``s`` instead of ``s²``, no clipping at 1, ``r``
    instead of ``r²``, ``√Φ`` instead of ``Φ``.

    Parameters
    ----------
    dcs_weight : callable
        ``(r ndarray (k,), phi float) -> ndarray (k,)``.

    Returns
    -------
    bool
    """
    ex = "11.1"
    r = np.linspace(0.0, 40.0, 201)
    for phi in PHIS:
        got, problem = call_student(dcs_weight, r.copy(), phi, name="dcs_weight")
        if problem == NOT_ATTEMPTED:
            return verdict(ex, problem)
        where = f"with Φ = {phi:.4g}"
        hint = (
            "Agarwal et al. (2013) scale each closure's information by s², with the switch "
            "s = min(1, 2Φ/(Φ + χ²)) and χ² = r².",
            "w = np.minimum(1.0, 2 * phi / (phi + r**2)) ** 2, elementwise over r.",
        )
        if problem is not None:
            return verdict(ex, f"{where}: {problem}", hint=hint)
        expected = kernels.DCS(math.sqrt(phi)).weight(r)
        got = np.asarray(got, dtype=float)
        problem = compare_array(got, expected, name="the weights", rtol=1e-9, atol=1e-12)
        if problem is None:
            continue
        if got.shape == expected.shape:
            for _, wrong, sentence, slip_hint in _dcs_slips(r, phi):
                if np.allclose(got, wrong, rtol=1e-9, atol=1e-12):
                    return verdict(ex, f"{where}: {sentence}", hint=(slip_hint, hint[1]))
        return verdict(ex, f"{where}: {problem}", hint=hint)
    return verdict(
        ex,
        None,
        correct=f"your weights equal kernels.DCS's at {r.size} residuals for each of "
        f"{len(PHIS)} values of Φ.",
    )


# --------------------------------------------------------------------------- exercise 11.2
# Exercise 11.2 (derive) — :func:`check_gm_influence`: the influence ψ(r) = dρ/dr of the
# Geman–McClure kernel ρ(r) = c² r² / (2 (c² + r²)).

import sympy as _sp  # noqa: E402

from lagolib.exercises._derive import Formula, formula_comparison  # noqa: E402

#: exercise 11.2's symbols: the whitened residual norm r >= 0 and the kernel's scale c > 0
GM_SYMBOLS = (_sp.Symbol("r", positive=True), _sp.Symbol("c", positive=True))


def gm_influence_reference():
    """ψ(r) = dρ/dr for ρ(r) = c² r² / (2 (c² + r²)), differentiated by sympy."""
    r, c = GM_SYMBOLS
    return _sp.simplify(_sp.diff(c**2 * r**2 / (2 * (c**2 + r**2)), r))


def _gm_slips():
    r, c = GM_SYMBOLS
    return [
        (c**4 / (c**2 + r**2) ** 2, "that is the weight w(r) = ψ(r)/r, not the influence ψ(r) "
         "itself: multiply by r."),
        (c**2 * r / (c**2 + r**2), "the derivative of the denominator is missing: ρ is a "
         "quotient in r, and r appears below the fraction bar too."),
        (2 * c**4 * r / (c**2 + r**2) ** 2, "a factor 2 too many: ρ has the 1/2 of r²/2 in it."),
    ]


_GM_HINTS = (
    "the quotient rule on ρ = u/v with u = c² r²/2 and v = c² + r²: ψ = (u' v − u v')/v².",
    "u' = c² r and v' = 2 r; the terms in r³ cancel in the numerator.",
)


@check("11.2", psi=Formula(GM_SYMBOLS, example="c**2*r/(c + r)"))
def check_gm_influence(psi) -> bool:
    """Exercise 11.2: the influence ψ(r) of Geman–McClure's ``ρ(r) = c² r² / (2 (c² + r²))``.

    The answer is a formula in :data:`GM_SYMBOLS` (``r``, ``c``), compared with
    :func:`gm_influence_reference` by symbolic equivalence (:mod:`lagolib.exercises._derive`).
    Names the weight given for ψ, the quotient rule's missing term and a factor 2.
    """
    result = formula_comparison(
        psi, gm_influence_reference(), symbols=GM_SYMBOLS, name="your ψ(r)", slips=_gm_slips()
    )
    if result.problem is not None:
        return verdict("11.2", result.problem, hint=_GM_HINTS)
    return verdict(
        "11.2", None,
        correct=f"your ψ(r) is dρ/dr of Geman–McClure ({result.detail}); it equals "
        "kernels.GemanMcClure(c).psi(r).",
    )


# --------------------------------------------------------------------------- exercise 11.3
@lru_cache(maxsize=1)
def _candidates():
    sim = world()
    g, truth = sim.graph, sim.truth
    sigma_theta = WORLD["sigma_theta"]
    edges, z, info = [], [], []
    for i, j, offset, sigma in CANDIDATES.values():
        zz = se2.between(truth[i], truth[j]).copy()
        zz[0] += offset
        edges.append((i, j))
        z.append(zz)
        info.append(np.diag([sigma**-2, sigma**-2, sigma_theta**-2]))
    graph = lagolib.PoseGraph(
        g.poses,
        np.vstack([g.edges, edges]),
        np.vstack([g.measurements, z]),
        np.concatenate([g.information, info]),
        ids=g.ids,
    )
    res = lagolib.optimize(graph, graph.odometry_guess(), robust="cauchy")
    weights = np.asarray(res.weights[-len(CANDIDATES):], dtype=float)
    return graph, weights


def candidates():
    """Exercise 11.3's graph: :func:`world`'s graph with the four closures of
    :data:`CANDIDATES` appended (in label order, the last four edges).

    Returns
    -------
    PoseGraph
    """
    return _candidates()[0]


def _cauchy_weights():
    """The final IRLS weights of the four candidates under ``optimize(..., robust="cauchy")``
    from the odometry, shape (4,)."""
    return _candidates()[1].copy()


@check("11.3", most_downweighted=Choice(LABELS))
def check_most_downweighted(most_downweighted):
    """Check exercise 11.3: which candidate closure ends with the smallest Cauchy weight.

    Runs :func:`lagolib.optimize` with ``robust="cauchy"`` (scale ``INLIER_THRESHOLD``) from the
    odometry on :func:`candidates` and compares the answer with the label of the smallest final
    weight among the four candidates.  Names the slip of ranking by metres instead of by
    whitened residual.

    Parameters
    ----------
    most_downweighted : str
        One of :data:`LABELS`.

    Returns
    -------
    bool
    """
    ex = "11.3"
    if is_placeholder(most_downweighted):
        return verdict(ex, NOT_ATTEMPTED)
    w = _cauchy_weights()
    want = LABELS[int(np.argmin(w))]
    problem = compare_choice(most_downweighted, want, LABELS, name="most_downweighted")
    facts = ", ".join(f"{c}: w = {v:.3g}" for c, v in zip(LABELS, w))
    if problem is None:
        return verdict(ex, None, correct=f"the final Cauchy weights are {facts}.")
    metres = LABELS[int(np.argmax([abs(c[2]) for c in CANDIDATES.values()]))]
    got = str(most_downweighted).strip().upper()
    if got not in LABELS:
        pass  # compare_choice's sentence: not one of the labels
    elif got == metres and metres != want:
        problem = (
            f"{most_downweighted!r} is the claim furthest off in metres, but a kernel sees the "
            "whitened residual r = sqrt(e^T Ω e): metres divided by the claim's σ."
        )
    elif got == LABELS[0]:
        problem = (
            f"{most_downweighted!r} is the right closure: its residual stays within the "
            "kernel's scale, where the Cauchy weight is close to 1."
        )
    else:
        problem = f"{most_downweighted!r} is not the closure with the smallest final weight."
    return verdict(
        ex,
        problem,
        hint=(
            "divide how far each claim is off by its σ: the Cauchy weight 1/(1 + r²/c²) falls "
            "with the whitened residual r, not with the error in metres.",
            f"the check's final weights: {facts}.",
        ),
    )


# --------------------------------------------------------------------------- exercise 11.4
_SWEEP: dict = {}


def ratio_sweep(method=SWEEP_METHOD, ratios=RATIOS):
    """ATE of :func:`lagolib.robust.solve` from the odometry as the outlier ratio grows.

    For each ratio, ``round(ratio · L)`` random wrong closures (``L`` the world's loop closures;
    :func:`lagolib.simulate.add_outliers`, policy ``"random"``, seed :data:`SWEEP_SEED`) are
    appended to :func:`world`'s graph and ``robust.solve(graph, odometry, method=method)`` is
    run; the ATE against the truth (:func:`lagolib.metrics.absolute_trajectory_error`) is
    recorded, with precision and recall over the loop closures.  Cached per ``(method, ratios)``.

    Returns
    -------
    dict
        ``"method"``, ``"ratios"`` (tuple), ``"counts"`` (ndarray of int), ``"ate"``,
        ``"precision"``, ``"recall"`` (ndarrays over the ratios), ``"base_ate"`` (the
        outlier-free least-squares optimum's ATE), ``"broken"`` (bool ndarray: ATE above
        :data:`BREAK_FACTOR` times ``base_ate``) and ``"seconds"``.
    """
    if not isinstance(method, str) or method not in robust.METHODS:
        raise ValueError(f"method must be one of {', '.join(robust.METHODS)}; got {method!r}")
    key = (method, tuple(float(r) for r in ratios))
    if key in _SWEEP:
        return copy.deepcopy(_SWEEP[key])
    t0 = time.perf_counter()
    sim = world()
    g = sim.graph
    n_closures = int(np.count_nonzero(g.loop_closure))
    base = lagolib.optimize(g, g.odometry_guess()).poses
    base_ate = metrics.absolute_trajectory_error(base, sim.truth).translation_rmse
    out = {name: np.zeros(len(key[1])) for name in ("ate", "precision", "recall")}
    out["counts"] = np.zeros(len(key[1]), int)
    for k, ratio in enumerate(key[1]):
        count = int(round(ratio * n_closures))
        bad = simulate.add_outliers(g, count, rng=SWEEP_SEED)
        res = robust.solve(bad.graph, bad.graph.odometry_guess(), method=method)
        sc = robust.scores(res.inlier, bad.outlier, bad.graph.loop_closure)
        out["counts"][k] = count
        out["ate"][k] = metrics.absolute_trajectory_error(res.poses, sim.truth).translation_rmse
        out["precision"][k], out["recall"][k] = sc.precision, sc.recall
    out.update(method=method, ratios=key[1], base_ate=base_ate,
               broken=out["ate"] > BREAK_FACTOR * base_ate,
               seconds=time.perf_counter() - t0)
    _SWEEP[key] = out
    return ratio_sweep(method, ratios)


@check("11.4", breaking_ratio=Real())
def check_breaking_ratio(breaking_ratio):
    """Check exercise 11.4: the smallest ratio of :data:`RATIOS` at which :data:`SWEEP_METHOD`
    (IRLS with the Cauchy kernel, from the odometry) breaks the map — its ATE above
    :data:`BREAK_FACTOR` times the outlier-free optimum's.

    Recomputes (or reuses) ``ratio_sweep(SWEEP_METHOD)`` and compares to 1e-9 relative.

    Parameters
    ----------
    breaking_ratio : float
        Wrong closures per right closure, one of :data:`RATIOS`.

    Returns
    -------
    bool
    """
    ex = "11.4"
    if is_placeholder(breaking_ratio):
        return verdict(ex, NOT_ATTEMPTED)
    sw = ratio_sweep(SWEEP_METHOD)
    ratios = np.array(sw["ratios"])
    if not sw["broken"].any():
        return verdict(ex, f"in this sweep {SWEEP_METHOD} never breaks; nothing to find.")
    want = float(ratios[sw["broken"]][0])
    table = ", ".join(
        f"ratio {r:g}: ATE {a / sw['base_ate']:.2f}× the optimum's"
        for r, a in zip(ratios, sw["ate"])
    )
    problem = compare_number(breaking_ratio, want, name="breaking_ratio", rtol=1e-9)
    if problem is None:
        return verdict(
            ex, None, correct=f"{table}; {SWEEP_METHOD} breaks first at ratio {want:g}."
        )
    got = float(breaking_ratio)
    if not np.any(np.isclose(ratios, got)):
        counts = sw["counts"]
        if np.any(np.isclose(counts, got)):
            problem = (
                f"breaking_ratio = {got:g} is a number of wrong closures; the answer is the "
                "ratio: wrong closures per right closure (ch11.RATIOS)."
            )
        else:
            problem = (
                f"breaking_ratio = {got:g} is not one of the swept ratios "
                f"({', '.join(f'{r:g}' for r in ratios)})."
            )
    else:
        k = int(np.argmin(np.abs(ratios - got)))
        if sw["broken"][k]:
            problem = (
                f"at ratio {got:g} the map is broken, but it is not the first ratio that "
                "breaks it: look at the smaller ratios."
            )
        else:
            problem = (
                f"at ratio {got:g} the map holds (ATE at most {BREAK_FACTOR:g} times the "
                "outlier-free optimum's): the method breaks at a larger ratio."
            )
    return verdict(
        ex,
        problem,
        hint=(
            f"run ch11.ratio_sweep({SWEEP_METHOD!r}) and read its 'broken' entries from the "
            "smallest ratio up.",
            f"the check's sweep: {table}.",
        ),
    )
