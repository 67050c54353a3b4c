"""Hints that teach instead of telling (issue 24, §2): the first tier of feedback never gives the
solution away.

A check's "not yet" line — its first tier — says what is wrong and by how much; ``hint("6.2")``
reveals more, one level per call; the full solution stays in the chapter's folded cell.  For
EVERY exercise of every chapter (the ``check_…`` functions of ``lagolib.exercises.chNN`` and the
exercises of the notebooks' metadata: a new exercise is covered automatically, and fails here
until :data:`WRONG` gives it plausible wrong answers), each wrong answer's first tier must contain

* none of the reference answer's values: every number of the reference answer (for a student's
  function, every value the reference function returns on the check's own inputs), formatted at
  the precisions a message uses (``%.3g``, ``%.4g``, ``%.6g``, ``repr``, and any rounding to 3
  or more significant digits), skipping trivial values (0, ±1, ±2) and numbers that also appear
  in the student's own answer, in the inputs the check hands the student's function, or in the
  exercise's statement; a choice's answer in quotes; a True/False answer; a formula's reference;
* no line of the solution cell's code (the full notebook's solution code cells: stripped lines,
  and right-hand sides of assignments, longer than 12 characters, that are not in the stub or
  the statement).

The test of the test (:func:`test_the_detector_catches_the_old_messages`) feeds it the messages
the checks printed before issue 24 — exercises 2.1, 2.3, 5.2 as the issue names them — and
requires it to flag each.
"""

from __future__ import annotations

import functools
import importlib
import inspect
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import sympy
from scipy.sparse.linalg import spsolve
from test_exercises_ch10 import step_ok
from test_exercises_fuzz import (
    REFERENCE,
    _circuit_vector,
    _edge_contribution,
    _edge_error,
    _eta,
    _gate_world,
    _incidence,
    _jacobian_blocks,
    _marginal_covariance,
    _multipliers,
    _phase1,
    _phase2_edge,
    _regularize_chord,
    _relative_covariance,
    _sincos_error,
    _to_frame_i,
)

import lagolib
from lagolib import book, se2
from lagolib.exercises import (
    CHAPTERS,
    ch01,
    ch02,
    ch03,
    ch06,
    ch07,
    ch08,
    ch09,
    ch10,
    hint,
    hints_enabled,
    reset,
    set_hints,
    verdict,
)
from lagolib.exercises._coerce import Function
from lagolib.exercises._derive import Formula, show_formula
from lagolib.exercises._feedback import compare_array, compare_int, compare_number

BOOK = Path(__file__).resolve().parent.parent / "book"


@pytest.fixture(autouse=True)
def _fresh():
    reset()
    set_hints(True)
    yield
    reset()
    set_hints(True)


# ============================================================================ the exercises
def _checks():
    """``{exercise id: (name "chNN.check_…", check)}`` of every chapter module."""
    out = {}
    for chapter in CHAPTERS:
        module = importlib.import_module(f"lagolib.exercises.{chapter}")
        for name, fn in sorted(vars(module).items()):
            if name.startswith("check_") and inspect.isfunction(fn) and hasattr(fn, "exercise"):
                out[fn.exercise] = (f"{chapter}.{name}", fn)
    return out


@functools.lru_cache(maxsize=None)
def _notebook_exercises():
    """``{exercise id: {"statement", "solution" (code), "stub"}}`` from the full notebooks."""
    out = {}
    for path in sorted(BOOK.glob("[0-9][0-9]_*.ipynb")):
        nb = json.loads(path.read_text(encoding="utf-8"))
        cells = nb["cells"]
        found = book.exercises(nb, str(path))
        starts = [e["cell"] for e in found] + [len(cells)]
        for e, end in zip(found, starts[1:]):
            solution, stub = [], []
            for cell in cells[e["cell"] + 1 : end]:
                tags = cell.get("metadata", {}).get("tags", [])
                if cell["cell_type"] == "code" and book.SOLUTION_TAG in tags:
                    solution.append("".join(cell["source"]))
                    stub.append(cell["metadata"].get("lagolib", {}).get("stub", ""))
            out[e["id"]] = {
                "statement": "".join(cells[e["cell"]]["source"]),
                "solution": "\n".join(solution),
                "stub": "\n".join(stub),
            }
    return out


CHECKS = _checks()
EXERCISES = sorted(
    set(CHECKS) | set(_notebook_exercises()), key=lambda x: tuple(map(int, x.split(".")))
)


# ============================================================================ wrong answers
# For every exercise: plausible wrong answers, each a (label, function returning the answers
# that replace the reference's) — the reference call is the fuzz file's REFERENCE.
def _scaled(fn, factor, which=None):
    """``fn``'s result with every array (or the item ``which`` of a tuple) times ``factor``."""

    def student(*args):
        out = fn(*args)
        if isinstance(out, tuple):
            return tuple(
                np.asarray(v) * factor if which is None or k == which else v
                for k, v in enumerate(out)
            )
        return np.asarray(out) * factor

    return student


def _raising(*args):
    raise ValueError("not finished yet")


def _wrapped_angle(p_i, p_j, z):
    e = _edge_error(p_i, p_j, z)
    e[2] = p_j[2] - p_i[2] - z[2]  # not wrapped
    return e


def _frame_i_error(p_i, p_j, z):
    return se2.between(p_i, p_j) - z


def _jacobian_r_theta_i(p_i, p_j, z):
    return _jacobian_blocks(p_i, p_j, np.asarray(z) * [1.0, 1.0, 0.0])


def _jacobian_third_column(p_i, p_j, z):
    A, B = _jacobian_blocks(p_i, p_j, z)
    A = A.copy()
    A[:2, 2] *= -1
    return A, B


def _ols(A, delta_bar, omega):
    return spsolve((A @ A.T).tocsc(), A @ delta_bar)


def _dense(A, delta_bar, omega):
    Ad = A.toarray()
    return np.linalg.lstsq(Ad @ np.diag(omega) @ Ad.T, Ad @ (omega * delta_bar), rcond=None)[0]


def _chord_floor(delta, edges, signs):
    s = float(np.sum(signs * delta[edges]))
    return s, -int(np.floor(s / (2 * np.pi)))


def _chord_unsigned(delta, edges, signs):
    s = float(np.sum(delta[edges]))
    return s, -int(np.round(s / (2 * np.pi)))


def _chord_off(delta, edges, signs):
    s = 1.01 * float(np.sum(signs * delta[edges]))
    return s, -int(np.round(s / (2 * np.pi)))


def _no_cross(S_ii, S_ij, S_jj, p_i, p_j):
    d = p_j[:2] - p_i[:2]
    M = np.array([[1.0, 0.0, -d[1]], [0.0, 1.0, d[0]], [0.0, 0.0, 1.0]])
    return S_jj + M @ S_ii @ M.T


def _info_frame_back(Omega, theta_z):
    G = np.eye(3)
    G[:2, :2] = se2.rotation(theta_z)
    return G.T @ Omega @ G


def _phase2_covariance(theta_i, Delta_l, Omega_Delta):
    Dg, J, W = _phase2_edge(theta_i, Delta_l, Omega_Delta)
    return Dg, J, np.linalg.inv(W)


def _phase2_unrotated(theta_i, Delta_l, Omega_Delta):
    Dg, J, W = _phase2_edge(theta_i, Delta_l, Omega_Delta)
    return Delta_l, J, W


def _sincos_f_only(p_i, p_j, delta_ij):
    return _sincos_error(p_i, p_j, delta_ij) + np.asarray(delta_ij)


def _newton_increment(A, b, t, rho):
    t1, r1 = ch07.newton_reference(A, b, t, rho)
    return t1 - t, r1 - rho


def _newton_off(A, b, t, rho):
    t1, r1 = ch07.newton_reference(A, b, t, rho)
    return 1.01 * t1, r1


def _eta_unwrapped(graph, poses):
    x = np.asarray(poses)
    i, j = graph.edges.T
    E = se2.between(graph.measurements, se2.between(x[i], x[j]))
    a = x[j, 2] - x[i, 2] - graph.measurements[:, 2]
    return float(np.mean(E[:, 0] ** 2 + E[:, 1] ** 2)), float(np.mean(a**2))


def _icp_no_weights(model, points, pose):
    return ch10._icp_variant(model, points, pose, weights=False)


def _icp_uphill(model, points, pose):
    return ch10._icp_variant(model, points, pose, sign=-1.0)


def _exact_gate_error():
    g, est, truth, cands, info = _gate_world()
    d2, error, false = ch03._gate_table(g, est, truth, cands, info)
    ok = (d2 <= ch03._chi2_3(ch03.GATE_CONFIDENCE)) & false
    return float(error[ok].max())


def _other_point(k):
    right = REFERENCE["ch09.check_certificate_reading"]()["certified_point"]
    return [c for c in ch09.POINT_CHOICES if c != right][k]


def _f(expr):
    """A formula answer given as a sympy expression built lazily."""
    return expr


WRONG = {
    "0.1": [
        ("counts the anchor", lambda: dict(n_unknown=12, A_shape=(12, 19), state_length=36)),
        ("transposed, x_0 left out", lambda: dict(n_unknown=11, A_shape=(19, 11), state_length=33)),
        ("all off", lambda: dict(n_unknown=10, A_shape=(11, 18), state_length=48)),
    ],
    "1.1": [
        ("angle not wrapped", lambda: dict(edge_error=_wrapped_angle)),
        ("frame-i error", lambda: dict(edge_error=_frame_i_error)),
        ("translation 10 % off", lambda: dict(edge_error=_scaled(_edge_error, [1.1, 1.0, 1.0]))),
        ("degrees", lambda: dict(edge_error=_scaled(_edge_error, [1.0, 1.0, 180 / np.pi]))),
        ("raises", lambda: dict(edge_error=_raising)),
    ],
    "1.2": [
        (
            "steps ratio, quadratic",
            lambda: dict(distance_ratio=10.0, growth_with_sigma="quadratic"),
        ),
        ("too small", lambda: dict(distance_ratio=2.0, growth_with_sigma="square root")),
        ("same", lambda: dict(distance_ratio=1.0, growth_with_sigma="linear")),
    ],
    "1.3": [
        ("large, quadratic", lambda: dict(chi2_one_lap=117.0, growth="quadratic")),
        ("negative, constant", lambda: dict(chi2_one_lap=-1.0, growth="constant")),
    ],
    "1.4": [
        ("both wrong", lambda: dict(same_isotropic=False, same_anisotropic=True)),
        ("isotropic wrong", lambda: dict(same_isotropic=False, same_anisotropic=False)),
        ("anisotropic wrong", lambda: dict(same_isotropic=True, same_anisotropic=True)),
    ],
    "2.1": [
        ("swapped", lambda: dict(jacobian_blocks=lambda *a: _jacobian_blocks(*a)[::-1])),
        ("R(theta_i)", lambda: dict(jacobian_blocks=_jacobian_r_theta_i)),
        ("third column", lambda: dict(jacobian_blocks=_jacobian_third_column)),
        ("B off by 10 %", lambda: dict(jacobian_blocks=_scaled(_jacobian_blocks, 1.1, which=1))),
        (
            "A zero",
            lambda: dict(jacobian_blocks=lambda *a: (np.zeros((3, 3)), _jacobian_blocks(*a)[1])),
        ),
        ("raises", lambda: dict(jacobian_blocks=_raising)),
    ],
    "2.2": [
        (
            "transpose missing",
            lambda: dict(
                edge_contribution=lambda e, A, B, W: (
                    (A @ W @ A,) + _edge_contribution(e, A, B, W)[1:]
                )
            ),
        ),
        ("b negated", lambda: dict(edge_contribution=_scaled(_edge_contribution, -1.0, which=3))),
        (
            "H_ij 1 % off",
            lambda: dict(edge_contribution=_scaled(_edge_contribution, 1.01, which=1)),
        ),
        ("raises", lambda: dict(edge_contribution=_raising)),
    ],
    "2.3": [
        ("edges counted", lambda: dict(n_blocks=27, null_dim=3)),
        ("no diagonal, H regular", lambda: dict(n_blocks=16, null_dim=0)),
        ("dense", lambda: dict(n_blocks=49, null_dim=3)),
        ("close", lambda: dict(n_blocks=24, null_dim=7)),
        ("one off", lambda: dict(n_blocks=22, null_dim=5)),
    ],
    "2.4": [
        ("fewer", lambda: dict(trend="fewer", same_optimum=True)),
        ("same, not the same optimum", lambda: dict(trend="same", same_optimum=False)),
    ],
    "2.5": [
        (
            "theta_z left out",
            lambda: dict(de_x_dtheta_i="-sin(theta_i)*(x_j - x_i) + cos(theta_i)*(y_j - y_i)"),
        ),
        (
            "sign",
            lambda: dict(
                de_x_dtheta_i="sin(theta_i + theta_z)*(x_j - x_i) + cos(theta_i + theta_z)*(y_j - y_i)"
            ),
        ),
        ("one term", lambda: dict(de_x_dtheta_i="-sin(theta_i + theta_z)*(x_j - x_i)")),
    ],
    "3.1": [
        (
            "the first block",
            lambda: dict(marginal_covariance=lambda H, free, v: np.linalg.inv(H.toarray())[:3, :3]),
        ),
        ("10 % off", lambda: dict(marginal_covariance=_scaled(_marginal_covariance, 1.1))),
        ("raises", lambda: dict(marginal_covariance=_raising)),
    ],
    "3.2": [
        ("above 1", lambda: dict(shrink="above 1", most_uncertain=20)),
        ("0.2 to 0.5, before closing", lambda: dict(shrink="0.2 to 0.5", most_uncertain=39)),
        ("neighbour", lambda: dict(shrink="below 0.2", most_uncertain=21)),
        ("far off", lambda: dict(shrink="0.5 to 1", most_uncertain=10)),
    ],
    "3.3": [
        ("no cross terms", lambda: dict(relative_covariance=_no_cross)),
        ("doubled", lambda: dict(relative_covariance=_scaled(_relative_covariance, 2.0))),
        ("1 % off", lambda: dict(relative_covariance=_scaled(_relative_covariance, 1.01))),
    ],
    "3.4": [
        ("trend", lambda: dict(trend="fewer true and fewer false accepted", max_false_error=0.32)),
        ("too small", lambda: dict(max_false_error=0.25)),
        ("centimetres", lambda: dict(max_false_error=32.0)),
        ("other confidence", lambda: dict(max_false_error=0.187)),
    ],
    "4.1": [
        ("sign", lambda: dict(incidence=lambda e, n: -_incidence(e, n))),
        ("unsigned", lambda: dict(incidence=lambda e, n: np.abs(_incidence(e, n)))),
        ("transposed", lambda: dict(incidence=lambda e, n: _incidence(e, n).T)),
        (
            "one column",
            lambda: dict(
                incidence=lambda e, n: _incidence(e, n) * np.r_[1, -1, np.ones(len(e) - 2)]
            ),
        ),
    ],
    "4.2": [
        ("nodes", lambda: dict(n_tree_edges=8, n_chords=4)),
        ("repeated left out", lambda: dict(n_tree_edges=7, n_chords=3)),
        ("lagolib's +1", lambda: dict(n_tree_edges=7, n_chords=6)),
        ("too few", lambda: dict(n_tree_edges=6, n_chords=5)),
    ],
    "4.3": [
        ("sign", lambda: dict(circuit_vector=lambda g, t, c: -_circuit_vector(g, t, c))),
        ("unsigned", lambda: dict(circuit_vector=lambda g, t, c: np.abs(_circuit_vector(g, t, c)))),
        ("chord only", lambda: dict(circuit_vector=lambda g, t, c: np.eye(g.m)[c])),
    ],
    "4.4": [
        ("odometric", lambda: dict(safer_tree="odometric")),
        ("anchor matters", lambda: dict(odometric_anchor_matters=True)),
        ("both", lambda: dict(safer_tree="odometric", odometric_anchor_matters=True)),
    ],
    "5.1": [
        ("unweighted", lambda: dict(phase1=_ols)),
        ("variances", lambda: dict(phase1=lambda A, d, w: _phase1(A, d, 1.0 / w))),
        ("1 % off", lambda: dict(phase1=_scaled(_phase1, 1.01))),
        ("dense", lambda: dict(phase1=_dense)),
        ("wrapped", lambda: dict(phase1=lambda A, d, w: se2.wrap_angle(_phase1(A, d, w)))),
        ("raises", lambda: dict(phase1=_raising)),
    ],
    "5.2": [
        ("floor", lambda: dict(regularize_chord=_chord_floor)),
        ("unsigned", lambda: dict(regularize_chord=_chord_unsigned)),
        ("1 % off", lambda: dict(regularize_chord=_chord_off)),
        (
            "sign of k",
            lambda: dict(
                regularize_chord=lambda *a: (_regularize_chord(*a)[0], -_regularize_chord(*a)[1])
            ),
        ),
        ("raises", lambda: dict(regularize_chord=_raising)),
    ],
    "5.3": [
        ("every chord", lambda: dict(n_predicted=9)),
        ("whole laps", lambda: dict(n_predicted=4)),
        ("too few", lambda: dict(n_predicted=2)),
        ("one too many", lambda: dict(n_predicted=6)),
    ],
    "5.4": [
        ("warning level", lambda: dict(first_wrong_odometric=0.14)),
        ("swapped", lambda: dict(first_wrong_odometric=0.48, first_wrong_min_uncertainty=0.16)),
        ("one is the other's", lambda: dict(first_wrong_min_uncertainty=0.16)),
        ("too low", lambda: dict(first_wrong_odometric=0.1)),
        ("too high", lambda: dict(first_wrong_min_uncertainty=0.54)),
    ],
    "5.5": [
        ("theta_1's variance", lambda: dict(var_theta2="a*(b + c)/(a + b + c)")),
        ("odometry only", lambda: dict(var_theta2="a + b")),
        ("denominator", lambda: dict(var_theta2="c*(a + b)/(a + b + 2*c)")),
    ],
    "6.1": [
        ("the other way", lambda: dict(to_frame_i=_info_frame_back)),
        ("covariance", lambda: dict(to_frame_i=lambda om, t: _to_frame_i(np.linalg.inv(om), t))),
        ("twice the angle", lambda: dict(to_frame_i=lambda om, t: _to_frame_i(om, 2 * t))),
        ("1 % off", lambda: dict(to_frame_i=_scaled(_to_frame_i, 1.01))),
    ],
    "6.2": [
        ("Delta_g not rotated", lambda: dict(phase2_edge=_phase2_unrotated)),
        ("J sign", lambda: dict(phase2_edge=_scaled(_phase2_edge, -1.0, which=1))),
        ("W covariance", lambda: dict(phase2_edge=_phase2_covariance)),
        ("W 1 % off", lambda: dict(phase2_edge=_scaled(_phase2_edge, 1.01, which=2))),
    ],
    "6.3": [
        ("anisotropic", lambda: dict(closer="anisotropic")),
        ("same", lambda: dict(closer="same")),
    ],
    "6.4": [
        ("gap does not grow", lambda: dict(gap_grows=False)),
        ("distance grows", lambda: dict(distance_grows=True)),
        ("inverse", lambda: dict(gap_ratio=1 / 4451.4)),
        ("20 % off", lambda: dict(gap_ratio=4451.4 * 1.2)),
        ("another row", lambda: dict(gap_ratio=44.1)),
    ],
    "6.5": [
        ("sign", lambda: dict(W_xy="(b - a)*sin(theta)*cos(theta)")),
        ("a square", lambda: dict(W_xy="(a - b)*sin(theta)**2")),
        ("the diagonal entry", lambda: dict(W_xy="a*cos(theta)**2 + b*sin(theta)**2")),
    ],
    "7.1": [
        ("f only", lambda: dict(sincos_error=_sincos_f_only)),
        ("sign", lambda: dict(sincos_error=_scaled(_sincos_error, -1.0))),
        ("1 % off", lambda: dict(sincos_error=_scaled(_sincos_error, 1.01))),
    ],
    "7.2": [
        ("increment", lambda: dict(newton_step=_newton_increment)),
        ("1 % off", lambda: dict(newton_step=_newton_off)),
        ("raises", lambda: dict(newton_step=_raising)),
    ],
    "7.3": [
        ("below 1", lambda: dict(prediction="below 1")),
        ("1 to 1.05", lambda: dict(prediction="1 to 1.05")),
        ("1.05 to 2", lambda: dict(prediction="1.05 to 2")),
    ],
    "7.4": [
        ("another sigma", lambda: dict(closest_sigma_theta=0.1)),
        ("level", lambda: dict(what_decides="level")),
        ("off the sweep", lambda: dict(closest_sigma_theta=0.07)),
    ],
    "7.5": [
        ("half", lambda: dict(dF_dc_i=_f(ch07.gradient_entry_reference() / 2))),
        (
            "an extra term",
            lambda: dict(
                dF_dc_i=_f(ch07.gradient_entry_reference() + 2 * sympy.Symbol("c_i", real=True))
            ),
        ),
    ],
    "8.1": [
        ("unwrapped", lambda: dict(eta=_eta_unwrapped)),
        ("swapped", lambda: dict(eta=lambda g, p: _eta(g, p)[::-1])),
        ("10 % off", lambda: dict(eta=lambda g, p: tuple(1.1 * v for v in _eta(g, p)))),
        ("raises", lambda: dict(eta=_raising)),
    ],
    "8.2": [
        ("LAGO", lambda: dict(smallest="LAGO")),
        ("SGD", lambda: dict(smallest="SGD")),
    ],
    "8.3": [
        ("trends swapped", lambda: dict(eta_c_trend="decreases", eta_a_trend="increases")),
        ("neither", lambda: dict(eta_a_trend="neither")),
        (
            "30 % off",
            lambda: dict(eta_a_ratio=REFERENCE["ch08.check_weight_sweep"]()["eta_a_ratio"] * 1.3),
        ),
        (
            "inverse",
            lambda: dict(eta_a_ratio=1 / REFERENCE["ch08.check_weight_sweep"]()["eta_a_ratio"]),
        ),
    ],
    "9.1": [
        ("twice", lambda: dict(multipliers=_scaled(_multipliers, 2.0))),
        (
            "imaginary part",
            lambda: dict(
                multipliers=lambda M, x: (np.conj(x[x.size // 2 :]) * (M @ x)[x.size // 2 :]).imag
            ),
        ),
        ("1 % off", lambda: dict(multipliers=_scaled(_multipliers, 1.01))),
    ],
    "9.2": [
        ("another point", lambda: dict(certified_point=_other_point(0))),
        ("yet another", lambda: dict(certified_point=_other_point(1))),
        (
            "10 % off",
            lambda: dict(
                lower_bound_P=REFERENCE["ch09.check_certificate_reading"]()["lower_bound_P"] * 1.1
            ),
        ),
    ],
    "9.3": [
        ("a sigma too small", lambda: dict(first_uncertified=0.4)),
        ("off the sweep", lambda: dict(first_uncertified=0.45)),
        ("count too high", lambda: dict(not_tight=3)),
        ("count too low", lambda: dict(not_tight=0)),
        ("yes/no for a count", lambda: dict(not_tight=True)),
    ],
    "9.4": [
        ("sign", lambda: dict(lambda_1="w*(1 + cos(theta_z + phi_0 - phi_1))")),
        ("imaginary part", lambda: dict(lambda_1="w*sin(phi_1 - phi_0 - theta_z)")),
        ("half", lambda: dict(lambda_1="w*(1 - cos(theta_z + phi_0 - phi_1))/2")),
    ],
    "10.1": [
        ("no weights", lambda: dict(icp_step=_icp_no_weights)),
        ("uphill", lambda: dict(icp_step=_icp_uphill)),
        (
            "x off by 1 cm",
            lambda: dict(icp_step=lambda m, p, q: np.asarray(step_ok(m, p, q)) + [0.01, 0, 0]),
        ),
    ],
    "10.2": [
        ("all admitted", lambda: dict(admitted=(True, True, True, True))),
        ("one wrong", lambda: dict(admitted=(True, False, False, False))),
        ("three wrong", lambda: dict(admitted=(False, True, True, True))),
    ],
    "10.3": [
        ("breaks", lambda: dict(smallest_sigma=0.3)),
        ("a larger sigma", lambda: dict(smallest_sigma=3.0)),
        (
            "count too high",
            lambda: dict(
                closures_when_broken=REFERENCE["ch10.check_heading_sweep"]()["closures_when_broken"]
                + 3
            ),
        ),
    ],
    "11.1": [
        ("the switch, not squared", lambda: dict(dcs_weight=lambda r, phi: np.minimum(
            1.0, 2.0 * phi / (phi + r**2)))),
        ("Cauchy's weight", lambda: dict(dcs_weight=lambda r, phi: 1.0 / (1.0 + r**2 / phi))),
        ("1 % off", lambda: dict(dcs_weight=lambda r, phi: 1.01 * np.minimum(
            1.0, 2.0 * phi / (phi + r**2)) ** 2)),
    ],
    "11.2": [
        ("the weight", lambda: dict(psi="c**4/(c**2 + r**2)**2")),
        ("no quotient rule", lambda: dict(psi="c**2*r/(c**2 + r**2)")),
        ("twice", lambda: dict(psi="2*c**4*r/(c**2 + r**2)**2")),
    ],
    "11.3": [
        ("largest in metres", lambda: dict(most_downweighted="C")),
        ("the right closure", lambda: dict(most_downweighted="A")),
        ("another", lambda: dict(most_downweighted="D")),
    ],
    "11.4": [
        ("one ratio early", lambda: dict(breaking_ratio=4.0)),
        ("the first ratio", lambda: dict(breaking_ratio=0.5)),
        ("a count", lambda: dict(breaking_ratio=440)),
    ],
}

#: exact values of reference answers that REFERENCE gives rounded (as read off a table)
EXACT = {
    "1.2": lambda: dict(distance_ratio=float(np.divide(*ch01._heading_noise_reference()[1::-1]))),
    "3.4": lambda: dict(max_false_error=_exact_gate_error()),
    "6.4": lambda: dict(gap_ratio=float(ch06._sweep()[0][-1] / ch06._sweep()[0][0])),
}


# ============================================================================ the detector
_NUMBER = re.compile(r"(?<![\w.])\d+(?:\.\d+)?(?:[eE][-+]?\d+)?(?![\w])")
_TRIVIAL = (0.0, 1.0, 2.0)


def _sig_digits(token: str) -> int:
    mantissa = re.split("[eE]", token)[0].replace(".", "").lstrip("0")
    return len(mantissa) or 1


def _rounds_to(token: str, value: float) -> bool:
    """Whether the number ``token`` is ``|value|`` as printed: exactly (a whole number) or
    rounded to the token's significant digits, when it has 3 or more."""
    t = float(token)
    v = abs(float(value))
    if not math.isfinite(v):
        return False
    if "." not in token and "e" not in token.lower() and v.is_integer():
        return int(t) == int(v)
    k = _sig_digits(token)
    if k < 3 or t == 0:
        return False
    step = 10.0 ** (math.floor(math.log10(abs(t))) - k + 1)
    return abs(t - v) <= 0.5 * step * (1 + 1e-9)


def _numbers(obj, depth=0):
    """Every real number in an answer or an input (arrays, tuples, sparse matrices, graphs)."""
    if depth > 6 or obj is None or isinstance(obj, (str, bytes, bool, np.bool_)):
        return
    if isinstance(obj, (int, float, np.integer, np.floating)):
        yield float(obj)
    elif isinstance(obj, (complex, np.complexfloating)):
        yield float(obj.real)
        yield float(obj.imag)
    elif sp.issparse(obj):
        yield from _numbers(np.asarray(obj.data), depth + 1)
    elif isinstance(obj, np.ndarray):
        if obj.dtype.kind in "iuf":
            yield from (float(v) for v in obj.ravel())
        elif obj.dtype.kind == "c":
            yield from (float(v) for v in obj.real.ravel())
            yield from (float(v) for v in obj.imag.ravel())
    elif isinstance(obj, (list, tuple)):
        for item in obj:
            yield from _numbers(item, depth + 1)
    elif isinstance(obj, dict):
        for item in obj.values():
            yield from _numbers(item, depth + 1)
    elif isinstance(obj, lagolib.PoseGraph):
        for a in (obj.poses, obj.measurements, obj.information):
            yield from _numbers(a, depth + 1)
    elif isinstance(obj, lagolib.scan_matching.ScanModel):
        yield from _numbers(obj.points, depth + 1)
        yield from _numbers(obj.normals, depth + 1)
    elif hasattr(obj, "M") and hasattr(obj, "n"):  # certify.ChordalProblem
        yield from _numbers(obj.M, depth + 1)


def _recording(fn, log):
    """``fn`` that appends each call's inputs and result to ``log``."""

    def student(*args, **kwargs):
        log.append(("in", args))
        out = fn(*args, **kwargs)
        log.append(("out", out))
        return out

    return student


def _first_tier(out: str, exercise: str) -> str:
    """The "not yet" diagnosis: the verdict line(s) without the prefix and the hint pointer."""
    head = f"Exercise {exercise} — not yet: "
    assert out.startswith(head), f"{exercise}: the wrong answer is not 'not yet': {out[:300]}"
    text = out[len(head) :]
    return text.split("\n    Stuck? hint(", 1)[0]


_CALL = re.compile(r"[A-Za-z_][\w.]*\(")


def _calls(code: str):
    """Every call ``name(…)`` in a line of code, with its balanced parentheses."""
    for match in _CALL.finditer(code):
        depth, start = 0, match.start()
        for end in range(match.end() - 1, len(code)):
            depth += {"(": 1, ")": -1}.get(code[end], 0)
            if depth == 0:
                yield code[start : end + 1]
                break


def _code_lines(solution: str, stub: str, statement: str):
    """The pieces of the solution's code a message must not show: each stripped line, the
    right-hand side of each assignment and each call in it (``np.sum(signs * delta[edges])``),
    longer than 12 characters and not given in the stub or the statement."""
    given_text = " ".join((stub + "\n" + statement).split())
    out = set()
    for line in solution.splitlines():
        code = line.split("  #", 1)[0].split(" # ", 1)[0].strip()
        if not code or code.startswith(("#", "print(", "def ", "import ", "from ")):
            continue
        pieces = [code, *_calls(code)]
        if " = " in code:
            pieces.append(code.split(" = ", 1)[1])
        for piece in pieces:
            piece = " ".join(piece.split())
            if len(piece) > 12 and piece not in given_text:
                out.add(piece)
    return out


def _leaks(tier: str, *, reference_values, own_values, choices, bools, formulas, code) -> list:
    """What in ``tier`` gives the reference answer or the solution away (empty: nothing)."""
    found = []
    tokens = _NUMBER.findall(tier)
    for value in reference_values:
        if abs(value) in _TRIVIAL or not math.isfinite(value):
            continue
        if any(_rounds_to(t, value) for t in tokens) and not any(
            _close_as_printed(value, own) for own in own_values
        ):
            hit = next(t for t in tokens if _rounds_to(t, value))
            found.append(f"the reference value {value!r} (printed {hit})")
    for choice in choices:
        for quoted in (f"'{choice}'", f'"{choice}"'):
            if quoted.lower() in tier.lower():
                found.append(f"the reference choice {quoted}")
    for b in bools:
        if re.search(rf"\b{b}\b", tier):
            found.append(f"the reference answer {b}")
    flat = "".join(tier.split())
    for formula in formulas:
        if len(formula) > 5 and formula in flat:
            found.append(f"the reference formula {formula}")
    text = " ".join(tier.split())
    for line in code:
        if line in text:
            found.append(f"the solution's code {line!r}")
    return found


def _close_as_printed(value: float, other: float) -> bool:
    """Whether ``value`` is also one of the student's own (or the inputs', or the statement's)
    numbers: equal to 1e-9, or the same when printed with 3 significant digits."""
    if not math.isfinite(other):
        return False
    a, b = abs(value), abs(other)
    return abs(a - b) <= 1e-9 * max(1.0, a) or f"{a:.3g}" == f"{b:.3g}"


# ============================================================================ running a check
@functools.lru_cache(maxsize=None)
def _reference_run(exercise):
    """``(check, reference kwargs, reference values, choices, bools, formulas)``."""
    name, check = CHECKS[exercise]
    kwargs = REFERENCE[name]()
    values, choices, bools, formulas = [], [], [], []
    call = dict(kwargs)
    log = []
    exact = EXACT.get(exercise, dict)()
    for answer, kind in check.answers.items():
        if isinstance(kind, Function):
            call[answer] = _recording(kwargs[answer], log)
            continue
        value = exact.get(answer, kwargs[answer])
        if isinstance(kind, Formula):
            expr = kind.coerce(value)
            formulas += [
                "".join(str(value).split()),
                "".join(sympy.sstr(expr).split()),
                "".join(show_formula(expr, width=10_000).split()),
            ]
        elif isinstance(value, str):
            choices.append(value)
        elif isinstance(value, (bool, np.bool_)) or (
            isinstance(value, tuple) and all(isinstance(v, bool) for v in value)
        ):
            bools += [str(v) for v in (value if isinstance(value, tuple) else (value,))]
        else:
            values += list(_numbers(value))
    reset()
    assert check(**call) is True, f"{exercise}: the reference answer is not correct"
    values += [v for kind, item in log if kind == "out" for v in _numbers(item)]
    inputs = [v for kind, item in log if kind == "in" for v in _numbers(item)]
    return check, kwargs, values, inputs, choices, bools, formulas


def _statement_numbers(exercise):
    text = _notebook_exercises().get(exercise, {}).get("statement", "")
    return [float(t) for t in _NUMBER.findall(text)]


def _run_wrong(exercise, overrides, capsys):
    """``(printed text, first tier, the student's own numbers, the inputs' numbers)``."""
    check, kwargs, *_ = _reference_run(exercise)
    call, log = dict(kwargs), []
    own = []
    for answer, value in overrides.items():
        kind = check.answers.get(answer)
        if isinstance(kind, Function) and callable(value):
            value = _recording(value, log)
        else:
            own += list(_numbers(value))
        call[answer] = value
    for answer, kind in check.answers.items():  # the right answers the student kept
        if answer not in overrides and not isinstance(kind, Function):
            own += list(_numbers(kwargs[answer]))
    reset()
    capsys.readouterr()
    ok = check(**call)
    out = capsys.readouterr().out
    assert ok is False, f"{exercise}: a wrong answer ({overrides}) was accepted: {out}"
    own += [v for kind, item in log if kind == "out" for v in _numbers(item)]
    inputs = [v for kind, item in log if kind == "in" for v in _numbers(item)]
    return out, _first_tier(out, exercise), own, inputs


# ============================================================================ the tests
def test_every_exercise_has_a_check_and_wrong_answers():
    notebook = set(_notebook_exercises())
    missing_check = sorted(notebook - set(CHECKS))
    assert not missing_check, f"exercises without a check_… function: {missing_check}"
    missing = [ex for ex in EXERCISES if not WRONG.get(ex)]
    assert not missing, (
        f"exercise(s) {missing} have no wrong-answer case: add plausible wrong answers to WRONG "
        "in tests/test_exercises_hints.py (and the correct call to REFERENCE in "
        "tests/test_exercises_fuzz.py)"
    )


@pytest.mark.parametrize("exercise", EXERCISES)
def test_first_tier_never_gives_the_answer_away(exercise, capsys):
    assert WRONG.get(exercise), f"exercise {exercise} has no wrong-answer case in WRONG"
    _, _, values, ref_inputs, choices, bools, formulas = _reference_run(exercise)
    nb = _notebook_exercises().get(exercise, {})
    code = _code_lines(nb.get("solution", ""), nb.get("stub", ""), nb.get("statement", ""))
    statement = _statement_numbers(exercise)
    failures = []
    for label, make in WRONG[exercise]:
        overrides = make()
        out, tier, own, inputs = _run_wrong(exercise, overrides, capsys)
        excluded = own + inputs + ref_inputs + statement
        reference = [v for v in values if not any(_close_as_printed(v, x) for x in excluded)]
        own_choices = {str(v) for v in overrides.values() if isinstance(v, str)}
        own_bools = {str(v) for v in _flat_bools(overrides.values())}
        own_formulas = {"".join(str(v).split()) for v in overrides.values()}
        leaks = _leaks(
            tier,
            reference_values=reference,
            own_values=own,
            choices=[c for c in choices if c not in own_choices],
            bools=[b for b in bools if b not in own_bools],
            formulas=[f for f in formulas if not any(f in o for o in own_formulas)],
            code=code,
        )
        if leaks:
            failures.append(f"{label}: {'; '.join(leaks)}\n      first tier: {tier[:400]}")
    assert not failures, f"exercise {exercise}: the first tier gives away\n  " + "\n  ".join(
        failures
    )


def _flat_bools(values):
    for v in values:
        if isinstance(v, (bool, np.bool_)):
            yield bool(v)
        elif isinstance(v, tuple):
            yield from _flat_bools(v)


@pytest.mark.parametrize("exercise", EXERCISES)
def test_every_wrong_answer_offers_hints_one_level_per_call(exercise, capsys):
    """A diagnosis of a wrong value (not of a placeholder) offers at least one hint, and hint()
    shows the levels in order, one per call, then says where the solution is."""
    for label, make in WRONG[exercise]:
        out, tier, _, _ = _run_wrong(exercise, make(), capsys)
        pointer = re.search(
            rf'Stuck\? hint\("{re.escape(exercise)}"\) gives a hint \((\d+) levels?', out
        )
        assert pointer, f"{exercise} ({label}): no hint offered: {out}"
        n = int(pointer.group(1))
        for k in range(1, n + 1):
            hint(exercise)
            line = capsys.readouterr().out
            assert line.startswith(f"Exercise {exercise} — hint {k} of {n}: "), (label, line)
        hint(exercise)
        assert capsys.readouterr().out.startswith(f"Exercise {exercise} — no more hints:")


# --------------------------------------------------------------------- the hint mechanism
def test_hints_reveal_one_level_per_call_and_restart_with_a_new_diagnosis(capsys):
    assert verdict("99.3", "too small.", hint=("nudge", "method", "detail")) is False
    first = capsys.readouterr().out
    assert first == (
        "Exercise 99.3 — not yet: too small.\n"
        '    Stuck? hint("99.3") gives a hint (3 levels, one more per call).\n'
    )
    for k, text in enumerate(("nudge", "method", "detail"), 1):
        hint("99.3")
        assert capsys.readouterr().out == f"Exercise 99.3 — hint {k} of 3: {text}\n"
    hint("99.3")
    assert "no more hints" in capsys.readouterr().out
    # the same diagnosis again keeps the place; another one starts its own hints afresh
    verdict("99.3", "too small.", hint=("nudge", "method", "detail"))
    hint("99.3")
    assert "no more hints" in capsys.readouterr().out
    verdict("99.3", "too large.", hint=("other",))
    capsys.readouterr()
    hint("99.3")
    assert capsys.readouterr().out == "Exercise 99.3 — hint 1 of 1: other\n"
    verdict("99.3", None, correct="fine")
    capsys.readouterr()
    hint("99.3")
    assert "your last answer was correct: no hint needed" in capsys.readouterr().out
    hint("99.4")
    assert "no hint yet: run the exercise's check first" in capsys.readouterr().out


def test_hints_off_removes_the_pointer_and_hint_says_so(capsys):
    set_hints(False)
    assert not hints_enabled()
    verdict("99.5", "too small.", hint=("nudge",))
    assert capsys.readouterr().out == "Exercise 99.5 — not yet: too small.\n"
    hint("99.5")
    assert "hints are off in this copy" in capsys.readouterr().out
    # a real check too: the diagnosis stays, the pointer goes
    assert ch08.check_smallest_sum("LAGO", *_identity()) is False
    out = capsys.readouterr().out
    assert out.startswith("Exercise 8.2 — not yet: smallest = 'LAGO'") and "Stuck?" not in out
    set_hints(True)
    assert hints_enabled()
    with pytest.raises(TypeError):
        set_hints("no")


def _identity():
    kwargs = REFERENCE["ch08.check_smallest_sum"]()
    return kwargs["graph"], kwargs["sgd_poses"]


# ------------------------------------------------------------ the comparisons' first tier
def test_comparisons_never_print_the_reference():
    expected = np.array([[0.8347, 0.5507, 0.0], [-0.5507, 0.8347, 0.0], [0.0, 0.0, 1.0]])
    got = expected.copy()
    got[0, 0] = 0.9
    msg = compare_array(got, expected, name="B_ij")
    assert (
        msg
        == "B_ij differs from the reference in 1 of its 9 entries: at index (0, 0) yours is larger, by 0.065."
    )
    got[0, 0] = 0.0
    assert "yours is 0 and the reference's is not" in compare_array(got, expected, name="B_ij")
    got[0, 0] = -0.8347 * 1.5
    assert "yours has the opposite sign" in compare_array(got, expected, name="B_ij")
    assert (
        compare_number(5.0, 3.06)
        == "your answer = 5 is too large: more than 1.5 times the reference."
    )
    assert (
        compare_number(3.2, 3.06, rtol=0.01) == "your answer = 3.2 is too large, by less than 10 %."
    )
    assert compare_number(3.6, 3.06, rtol=0.01) == "your answer = 3.6 is too large, by 10 to 50 %."
    assert (
        compare_number(0.1, 3.06)
        == "your answer = 0.1 is too small: less than a tenth of the reference (units? a factor?)."
    )
    assert compare_number(-3.06, 3.06) == "your answer = -3.06 is of the wrong sign."
    assert compare_number(3.1, 3.06, rtol=0.01) == (
        "your answer = 3.1 is too large, though close: just outside the check's tolerance."
    )
    assert compare_int(22, 23, name="n_blocks") == "n_blocks = 22 is too small."
    for msg in (compare_number(5.0, 3.06), compare_int(22, 23)):
        assert "3.06" not in msg and "23" not in msg and "reference is" not in msg


# ------------------------------------------------------------- the test of the test
def _old_compare_array(got, expected, name):
    """compare_array's message before issue 24 (its last lines), for the detector's test."""
    g, e = np.asarray(got, float), np.asarray(expected, float)
    diff = g - e
    k = np.unravel_index(int(np.argmax(np.abs(diff))), diff.shape)
    fmt = functools.partial(np.array2string, precision=6, suppress_small=True, max_line_width=90)
    return (
        f"{name} differs from the reference by up to {np.abs(diff).max():.4g} at index "
        f"{tuple(int(i) for i in k)} (yours {g[k]:.6g}, expected {e[k]:.6g})."
        f"\n    yours:    {fmt(g)}\n    expected: {fmt(e)}"
    )


def _leaks_of(exercise, tier, capsys, overrides):
    _, _, values, ref_inputs, choices, bools, formulas = _reference_run(exercise)
    _, _, own, inputs = _run_wrong(exercise, overrides, capsys)
    nb = _notebook_exercises()[exercise]
    excluded = own + inputs + ref_inputs + _statement_numbers(exercise)
    return _leaks(
        tier,
        reference_values=[v for v in values if not any(_close_as_printed(v, x) for x in excluded)],
        own_values=own,
        choices=choices,
        bools=bools,
        formulas=formulas,
        code=_code_lines(nb["solution"], nb["stub"], nb["statement"]),
    )


def test_the_detector_catches_the_old_messages(capsys):
    """The messages the issue names (2.1, 2.3, 5.2), as the checks printed them before issue 24,
    are flagged; today's messages for the same answers are not."""

    # 2.1: a wrong block printed most of the reference block ("expected: [...]")
    def third_column_zero(p_i, p_j, z):
        A, B = _jacobian_blocks(p_i, p_j, z)
        A = A.copy()
        A[:2, 2] = 0.0
        return A, B

    wrong = {"jacobian_blocks": third_column_zero}
    p_i, p_j, z = ch02._jacobian_cases()[0]
    A, _ = _jacobian_blocks(p_i, p_j, z)
    where = (
        f"on edge 1 of 5 (p_i = {np.round(p_i, 3).tolist()}, p_j = {np.round(p_j, 3).tolist()}, "
        f"z = {np.round(z, 3).tolist()}): "
    )
    old = where + (  # exactly as printed before issue 24
        f"A_ij's first two columns are right, its third column de/dtheta_i is not: yours "
        f"{[0.0, 0.0, -1.0]}, expected {np.round(A[:, 2], 6).tolist()} (how turning x_i moves "
        "x_j as seen from x_i, rotated into the measurement's frame)."
    )
    assert _leaks_of("2.1", old, capsys, wrong), old
    _, tier, _, _ = _run_wrong("2.1", wrong, capsys)
    assert not _leaks_of("2.1", tier, capsys, wrong), tier
    # ... and compare_array's old dump of the expected array, for a block the student got wrong
    old = where + _old_compare_array(np.zeros((3, 3)), A, "A_ij")
    assert _leaks_of(
        "2.1",
        old,
        capsys,
        {"jacobian_blocks": lambda *a: (np.zeros((3, 3)), _jacobian_blocks(*a)[1])},
    )
    # 2.3: a wrong prediction printed the actual values (the answer)
    answer = {"n_blocks": 27, "null_dim": 3}
    old = (
        "n_blocks is 27: that is 4 more than the reference. null_dim is 3: that is 3 fewer than "
        "the reference. lagolib's H has 23 non-zero blocks (7 diagonal + 2 x 8 pairs of joined "
        "poses) and a null space of dimension 6 (2 components x 3)."
    )
    assert _leaks_of("2.3", old, capsys, answer)
    _, tier, _, _ = _run_wrong("2.3", answer, capsys)
    assert not _leaks_of("2.3", tier, capsys, answer), tier
    # 5.2: a crash printed the whole solution line (as the hint, then part of the verdict)
    crash = {"regularize_chord": _raising}
    old = (  # exactly as printed before issue 24
        "regularize_chord(delta, edges, signs) raised ValueError: not finished yet\n    Hint: end "
        "with `return cycle_sum, k`: cycle_sum = np.sum(signs * delta[edges]) and k = "
        "-round(cycle_sum / 2π) as an int."
    )
    assert any("solution's code" in leak for leak in _leaks_of("5.2", old, capsys, crash))
    out, tier, _, _ = _run_wrong("5.2", crash, capsys)
    assert not _leaks_of("5.2", tier, capsys, crash) and "np.sum" not in out


def test_a_yes_no_question_accepts_true_false_and_yes_no(capsys):
    """Review of issue 24: every yes/no answer accepts True/False of any type and "yes"/"no"."""
    for iso, aniso in ((True, False), ("yes", "no"), (np.True_, np.array([False])), (" Yes", "NO")):
        reset()
        assert ch01.check_toro_frames(iso, aniso) is True, capsys.readouterr().out
    capsys.readouterr()
    reset()
    assert ch01.check_toro_frames("True", False) is False
    assert "True and False are written without quotes" in capsys.readouterr().out
