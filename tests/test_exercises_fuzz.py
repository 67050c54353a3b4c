"""No check of any chapter raises on an answer, and none says "correct" to an answer of the
wrong kind.

1. Every ``check_…`` of ``lagolib.exercises.ch00`` … ``ch09`` is called with adversarial answers
   in every argument — placeholders, wrong types, ragged lists, NaN, strings, objects whose ``==``
   and ``repr`` raise — and with functions that return them or raise.  A check must print a
   verdict and return ``True`` or ``False``: a student's mistake is feedback, never a traceback.
2. Every check declares the kind of each answer (``check.answers``, see
   ``lagolib.exercises._coerce``).  Its reference answer (:data:`REFERENCE`, built from lagolib)
   is turned into every answer of a wrong kind that applies — plus 1000j, a complex dtype, a
   numeric string or text array, a dict, a set, a bool or a bool array, an object array, None,
   text or a bool inside a list, a ragged list, a masked entry, a sparse matrix where a dense
   array is asked for, NaN, ±inf, an int where True/False is asked for, a wrong-length tuple, … —
   one answer (or one item of a returned tuple) at a time; each must be "not yet" with a
   sentence naming the kind asked for.  The reference answer itself, and as a list, a tuple, a
   numpy scalar, a 0-d array, a sympy number, … must still be "correct".
"""

import decimal
import fractions
import functools
import importlib
import inspect
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
import sympy
from scipy.sparse.linalg import spsolve
from test_exercises_ch03 import gate_world_data, loop_data
from test_exercises_ch10 import gate_world_data as ch10_gate_world
from test_exercises_ch10 import step_ok

import lagolib
from lagolib import certify, se2, topology
from lagolib.exercises import CHAPTERS, ch03, ch07, ch08, ch09, ch10
from lagolib.exercises._coerce import (
    Bool,
    Choice,
    Function,
    Int,
    Real,
    RealArray,
    Shape,
    Tuple,
)
from lagolib.exercises._derive import Formula
from lagolib.gauss_newton import edge_jacobians
from lagolib.metrics import constraint_satisfaction
from lagolib.sgd import sgd


class Weird:
    def __eq__(self, other):
        raise RuntimeError("no comparing me")

    def __repr__(self):
        raise RuntimeError("no printing me")

    def __len__(self):
        raise RuntimeError("no length")

    __hash__ = None


def _raises(*args, **kwargs):
    raise RuntimeError("the student's function is broken")


VALUES = [
    None,
    ...,
    True,
    -1,
    2.5,
    float("nan"),
    "abc",
    [[1, 2], [3]],
    {"a": 1},
    np.zeros((2, 7)),
    np.array([np.inf]),
    Weird(),
]


def _returning(value):
    def student(*args, **kwargs):
        return value

    return student


ANSWERS = VALUES + [_returning(v) for v in VALUES] + [_raises]


def _checks():
    for name in CHAPTERS:
        module = importlib.import_module(f"lagolib.exercises.{name}")
        for fname, fn in sorted(vars(module).items()):
            if fname.startswith("check_") and inspect.isfunction(fn):
                if fn.__module__ == module.__name__:
                    yield pytest.param(fn, id=f"{name}.{fname}")


def _required(fn):
    sig = inspect.signature(fn)
    return [
        p
        for p in sig.parameters.values()
        if p.default is inspect.Parameter.empty
        and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
    ]


@pytest.mark.parametrize("check", list(_checks()))
def test_check_never_raises(check, capsys):
    chapter = int(check.__module__.rsplit("ch", 1)[1])
    exercise = getattr(check, "exercise", "")
    assert exercise.startswith(f"{chapter}."), (
        f'{check.__qualname__}: decorate it with @check("{chapter}.k") from lagolib.exercises'
    )
    n = len(_required(check))
    failures = []
    for k, answer in enumerate(ANSWERS):
        try:
            result = check(*([answer] * n))
        except Exception as exc:  # noqa: BLE001 - the point of the test
            failures.append(f"answer {k} ({type(answer).__name__}): {type(exc).__name__}: {exc}")
            continue
        if result is not True and result is not False:
            failures.append(f"answer {k}: returned {result!r}, not a bool")
        out = capsys.readouterr().out
        if f"Exercise {exercise} — " not in out:
            failures.append(f"answer {k}: printed no verdict")
    assert not failures, "\n".join(failures[:8])


# ============================================================================= answer kinds
# Reference answers: for every check, the keyword arguments of a call that is correct.  Student
# functions are written from lagolib (the chapters' solutions, in a few lines each); chapter
# contexts (graphs a chapter builds and passes to its check) are small and built once.


def _edge_error(p_i, p_j, z):
    return se2.t2v(np.linalg.inv(se2.v2t(z)) @ np.linalg.inv(se2.v2t(p_i)) @ se2.v2t(p_j))


def _jacobian_blocks(p_i, p_j, z):
    _, A, B = edge_jacobians(p_i, p_j, z)
    return A, B


def _edge_contribution(e, A, B, W):
    return A.T @ W @ A, A.T @ W @ B, B.T @ W @ B, A.T @ W @ e, B.T @ W @ e


def _marginal_covariance(H, free, v):
    k = int(np.flatnonzero(free == v)[0])
    return np.linalg.inv(H.toarray())[3 * k : 3 * k + 3, 3 * k : 3 * k + 3]


def _relative_covariance(S_ii, S_ij, S_jj, p_i, p_j):
    d = p_j[:2] - p_i[:2]
    M = np.array([[1.0, 0.0, -d[1]], [0.0, 1.0, d[0]], [0.0, 0.0, 1.0]])
    return S_jj - M @ S_ij - S_ij.T @ M.T + M @ S_ii @ M.T


def _incidence(edges, n_nodes):
    A = np.zeros((n_nodes, len(edges)))
    A[edges[:, 0], np.arange(len(edges))] = -1.0
    A[edges[:, 1], np.arange(len(edges))] = 1.0
    return A


def _circuit_vector(graph, tree, chord):
    basis = topology.cycle_basis(graph, tree)
    return basis.C.toarray()[list(basis.chords).index(chord)]


def _phase1(A, delta_bar, omega):
    return spsolve((A @ sp.diags(omega) @ A.T).tocsc(), A @ (omega * delta_bar))


def _regularize_chord(delta, edges, signs):
    s = float(np.sum(signs * delta[edges]))
    return s, -int(np.round(s / (2 * np.pi)))


def _to_frame_i(Omega, theta_z):
    G = np.eye(3)
    G[:2, :2] = se2.rotation(theta_z)
    return G @ Omega @ G.T


def _phase2_edge(theta_i, Delta_l, Omega_Delta):
    R = se2.rotation(theta_i)
    S = np.array([[0.0, -1.0], [1.0, 0.0]])
    return R @ Delta_l, S @ R @ Delta_l, R @ Omega_Delta @ R.T


def _sincos_error(p_i, p_j, delta_ij):
    x_i, y_i, c_i, s_i = p_i
    x_j, y_j, c_j, s_j = p_j
    dx, dy = x_j - x_i, y_j - y_i
    f = np.array(
        [c_i * dx + s_i * dy, -s_i * dx + c_i * dy, c_j * c_i + s_j * s_i, s_j * c_i - c_j * s_i]
    )
    return f - delta_ij


def _eta(graph, poses):
    return tuple(float(v) for v in constraint_satisfaction(graph, poses))


def _multipliers(M, x):
    n = x.size // 2
    return (np.conj(x[n:]) * (M @ x)[n:]).real


@functools.lru_cache(maxsize=None)
def _loop_chain_and_closure():
    """Chapter 3's one-lap square: the odometry chain, and the chain with the closure 0-39."""
    return loop_data()


@functools.lru_cache(maxsize=None)
def _gate_world():
    """Chapter 3's two-lap square and candidate loop closures (exercise 3.4)."""
    return gate_world_data()


@functools.lru_cache(maxsize=None)
def _square_loop():
    return lagolib.datasets.example("square_loop").graph


@functools.lru_cache(maxsize=None)
def _identity_scenario():
    g = _square_loop()
    gi = g.with_information(np.eye(3))
    return gi, sgd(gi, g.odometry_guess(), iterations=100).poses


@functools.lru_cache(maxsize=None)
def _certificates():
    """A small problem and two points, and exercise 9.2's answer for them (from lagolib)."""
    g = _square_loop()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lagolib.LagolibWarning)
        p = certify.chordal_problem(g)
        P = certify.refine(p, g.odometry_guess()).poses
        Q = certify.solve(g).chordal_poses
    cP, cQ = certify.certify(p, P), certify.certify(p, Q)
    point = {(True, True): "both", (True, False): "P", (False, True): "Q"}.get(
        (cP.certified, cQ.certified), "neither"
    )
    return point, float(cP.lower_bound), p, P, Q


def _weight_sweep():
    g = _square_loop()
    table = ch08.angle_weight_sweep(g)
    return dict(
        eta_c_trend="increases",
        eta_a_trend="decreases",
        eta_a_ratio=float(table[0, 1] / table[-1, 1]),
        graph=g,
    )


def _noise_sweep():
    sw = ch09.noise_sweep()
    first = float(np.array(sw["sigmas"])[~sw["certified"].all(axis=1)][0])
    return dict(first_uncertified=first, not_tight=int(sw["not_tight"].sum()))


def _gate():
    g, est, truth, candidates, info = _gate_world()
    return dict(
        trend=ch03.TREND_CHOICES[0],
        max_false_error=0.32,
        graph=g,
        poses=est,
        truth=truth,
        candidates=candidates,
        information=info,
    )


def _gate_prediction():
    chain, x = ch10_gate_world()
    return dict(
        admitted=(True, True, False, False),
        graph=chain,
        j=79,
        candidates=[2, 3, 4, 44],
        rules=lagolib.frontend.ClosureRules(overlap=1.6),
        poses=x,
    )


def _heading_sweep():
    sweep = ch10.heading_sweep()
    return dict(smallest_sigma=1.0, closures_when_broken=int(sweep["accepted"][0]))


def _certificate_reading():
    point, bound, p, P, Q = _certificates()
    return dict(certified_point=point, lower_bound_P=bound, problem=p, P=P, Q=Q)


#: every check's correct call, as keyword arguments (built lazily: some need a small world)
REFERENCE = {
    "ch00.check_notation": lambda: dict(n_unknown=11, A_shape=(11, 19), state_length=36),
    "ch01.check_edge_error": lambda: dict(edge_error=_edge_error),
    "ch01.check_heading_noise": lambda: dict(distance_ratio=3.06, growth_with_sigma="linear"),
    "ch01.check_chi2_laps": lambda: dict(chi2_one_lap=0.0, growth="linear"),
    "ch01.check_toro_frames": lambda: dict(same_isotropic=True, same_anisotropic=False),
    "ch02.check_jacobians": lambda: dict(jacobian_blocks=_jacobian_blocks),
    "ch02.check_edge_contribution": lambda: dict(edge_contribution=_edge_contribution),
    "ch02.check_structure": lambda: dict(n_blocks=23, null_dim=6),
    "ch02.check_damping": lambda: dict(trend="more", same_optimum=True),
    "ch03.check_marginal_covariance": lambda: dict(marginal_covariance=_marginal_covariance),
    "ch03.check_closure_prediction": lambda: dict(
        shrink="below 0.2",
        most_uncertain=20,
        chain=_loop_chain_and_closure()[0],
        closed=_loop_chain_and_closure()[1],
    ),
    "ch03.check_relative_covariance": lambda: dict(relative_covariance=_relative_covariance),
    "ch03.check_gate": _gate,
    "ch04.check_incidence": lambda: dict(incidence=_incidence),
    "ch04.check_chords": lambda: dict(n_tree_edges=7, n_chords=5),
    "ch04.check_circuit_vector": lambda: dict(circuit_vector=_circuit_vector),
    "ch04.check_tree_exploration": lambda: dict(
        safer_tree="bfs",
        odometric_anchor_matters=False,
        graph=lagolib.datasets.example("manhattan200").graph,
    ),
    "ch05.check_phase1": lambda: dict(phase1=_phase1),
    "ch05.check_regularize_chord": lambda: dict(regularize_chord=_regularize_chord),
    "ch05.check_n_regularized": lambda: dict(n_predicted=5),
    "ch05.check_noise_tolerance": lambda: dict(
        first_wrong_odometric=0.16, first_wrong_min_uncertainty=0.48
    ),
    "ch06.check_frame_i": lambda: dict(to_frame_i=_to_frame_i),
    "ch06.check_phase2_edge": lambda: dict(phase2_edge=_phase2_edge),
    "ch06.check_closer": lambda: dict(closer="isotropic"),
    "ch06.check_anisotropy_sweep": lambda: dict(
        gap_grows=True, distance_grows=False, gap_ratio=4451.4
    ),
    "ch07.check_sincos_error": lambda: dict(sincos_error=_sincos_error),
    "ch07.check_newton_step": lambda: dict(newton_step=ch07.newton_reference),
    "ch07.check_closed_form_gap": lambda: dict(prediction="above 2"),
    "ch07.check_noise_gap": lambda: dict(closest_sigma_theta=0.05, what_decides="ratio"),
    "ch08.check_eta": lambda: dict(eta=_eta),
    "ch08.check_smallest_sum": lambda: dict(
        smallest="Gauss-Newton",
        graph=_identity_scenario()[0],
        sgd_poses=_identity_scenario()[1],
    ),
    "ch08.check_weight_sweep": _weight_sweep,
    "ch09.check_multipliers": lambda: dict(multipliers=_multipliers),
    "ch09.check_certificate_reading": _certificate_reading,
    "ch09.check_noise_sweep": _noise_sweep,
    "ch10.check_icp_step": lambda: dict(icp_step=step_ok),
    "ch10.check_gate_prediction": _gate_prediction,
    "ch10.check_heading_sweep": _heading_sweep,
    "ch11.check_dcs_weight": lambda: dict(
        dcs_weight=lambda r, phi: np.minimum(1.0, 2.0 * phi / (phi + np.asarray(r) ** 2)) ** 2
    ),
    "ch11.check_gm_influence": lambda: dict(psi="c**4*r/(c**2 + r**2)**2"),
    "ch11.check_most_downweighted": lambda: dict(most_downweighted="B"),
    "ch11.check_breaking_ratio": lambda: dict(breaking_ratio=8.0),
    "ch02.check_jacobian_entry": lambda: dict(
        de_x_dtheta_i="-sin(theta_i + theta_z)*(x_j - x_i) + cos(theta_i + theta_z)*(y_j - y_i)"
    ),
    "ch05.check_blue_variance": lambda: dict(var_theta2="c*(a + b)/(a + b + c)"),
    "ch06.check_world_information": lambda: dict(W_xy="(a - b)*sin(theta)*cos(theta)"),
    "ch07.check_gradient_entry": lambda: dict(
        dF_dc_i="2*((c_i*(x_j - x_i) + s_i*(y_j - y_i) - x_z)*(x_j - x_i)"
        " + (-s_i*(x_j - x_i) + c_i*(y_j - y_i) - y_z)*(y_j - y_i)"
        " + (c_j*c_i + s_j*s_i - c_z)*c_j + (s_j*c_i - c_j*s_i - s_z)*s_j)"
    ),
    "ch09.check_multiplier_formula": lambda: dict(lambda_1="w*(1 - cos(theta_z + phi_0 - phi_1))"),
}


# ----------------------------------------------------------------------- wrong kinds, by kind
def _first_leaf(nested, new):
    """``nested`` (a nested list) with its first number replaced by ``new``."""
    out = list(nested)
    if out and isinstance(out[0], list):
        out[0] = _first_leaf(out[0], new)
    else:
        out[0] = new
    return out


def _ragged(a):
    rows = a.tolist()
    if a.ndim == 1:
        return [rows[:1], *rows[1:]]
    return [rows[0], rows[1][:-1], *rows[2:]]


def _masked(a):
    mask = np.zeros(a.shape, bool)
    mask.flat[0] = True
    return np.ma.masked_array(a, mask=mask)


def _with(a, value):
    out = a.copy()
    out.flat[0] = value
    return out


def _object_vector(items):
    out = np.empty(len(items), dtype=object)
    for k, item in enumerate(items):
        out[k] = item
    return out


_SCALAR_WRONG = {
    "plus 1000j": lambda r: r + 1000j,
    "complex with imaginary part 0": complex,
    "numpy complex": np.complex128,
    "sympy complex": lambda r: sympy.Float(r) + sympy.I,
    "sympy symbol": lambda r: sympy.Symbol("x"),
    "numeric string": str,
    "numpy string": lambda r: np.str_(r),
    "bytes": lambda r: str(r).encode(),
    "0-d text array": lambda r: np.array(str(r)),
    "bool": bool,
    "numpy bool": np.bool_,
    "list of one": lambda r: [r],
    "tuple of one": lambda r: (r,),
    "array of two": lambda r: np.array([r, r]),
    "0-d object array": lambda r: np.array(r, dtype=object),
    "dict": lambda r: {"value": r},
    "set": lambda r: {r},
}
WRONG_KINDS = {
    Real: {
        **_SCALAR_WRONG,
        "nan": lambda r: float("nan"),
        "inf": lambda r: float("inf"),
        "-inf": lambda r: -np.inf,
    },
    Int: {
        **_SCALAR_WRONG,
        "a half more": lambda k: k + 0.5,
        "numpy float, a half more": lambda k: np.float64(k) + 0.5,
        "nan": lambda k: float("nan"),
    },
    Bool: {
        "int": int,
        "float": float,
        "numpy int": np.int64,
        "string": str,
        "numpy string": lambda b: np.str_(b),
        "bytes": lambda b: str(b).encode(),
        "complex": complex,
        "list of one": lambda b: [b],
        "array of two": lambda b: np.array([b, b]),
        "0-d object array": lambda b: np.array(b, dtype=object),
        "dict": lambda b: {"value": b},
    },
    Choice: {
        "bytes": str.encode,
        "numpy bytes": lambda s: np.bytes_(s.encode()),
        "list of one": lambda s: [s],
        "tuple of one": lambda s: (s,),
        "array of one": lambda s: np.array([s]),
        "0-d object array": lambda s: np.array(s, dtype=object),
        "dict": lambda s: {s: 1},
        "set": lambda s: {s},
        "int": lambda s: 1,
        "bool": lambda s: True,
    },
    Shape: {
        "dict": lambda t: {n: k for k, n in enumerate(t)},
        "string": str,
        "set": set,
        "one more size": lambda t: (*t, 1),
        "one size fewer": lambda t: t[:-1],
        "nested": lambda t: (t,),
        "complex size": lambda t: (t[0] + 0j, *t[1:]),
        "bool size": lambda t: (True, *t[1:]),
        "fractional size": lambda t: (t[0] + 0.5, *t[1:]),
        "text size": lambda t: (str(t[0]), *t[1:]),
        "None size": lambda t: (None, *t[1:]),
        "negative size": lambda t: (-t[0], *t[1:]),
        "text array": lambda t: np.array(t).astype(str),
        "complex array": lambda t: np.array(t, dtype=complex),
        "object array": lambda t: np.array(t, dtype=object),
        "bool array": lambda t: np.array(t, dtype=bool),
    },
    RealArray: {
        "plus 1000j": lambda a: a + 1000j,
        "complex dtype": lambda a: a.astype(complex),
        "text array": lambda a: a.astype(str),
        "list of numeric strings": lambda a: a.astype(str).tolist(),
        "string": lambda a: str(a.tolist()),
        "dict": lambda a: dict(enumerate(a.ravel().tolist())),
        "bool array": lambda a: a.astype(bool),
        "object array": lambda a: a.astype(object),
        "None in a list": lambda a: _first_leaf(a.tolist(), None),
        "text in a list": lambda a: _first_leaf(a.tolist(), "1.0"),
        "bool in a list": lambda a: _first_leaf(a.tolist(), True),
        "complex in a list": lambda a: _first_leaf(a.tolist(), 1 + 0j),
        "ragged list": _ragged,
        "masked entry": _masked,
        "nan": lambda a: _with(a, np.nan),
        "inf": lambda a: _with(a, np.inf),
        "sparse": lambda a: sp.csr_matrix(np.atleast_2d(a)),  # only where dense is asked for
        "generator": lambda a: (x for x in a),
    },
    Formula: {
        "bytes": lambda f: f.encode(),
        "list of one": lambda f: [f],
        "tuple of one": lambda f: (f,),
        "dict": lambda f: {"answer": f},
        "set": lambda f: {f},
        "bool": lambda f: True,
        "array of one": lambda f: np.array([1.0]),
        "complex": lambda f: 1 + 2j,
        "nan": lambda f: float("nan"),
        "sympy matrix": lambda f: sympy.Matrix([sympy.sympify(1)]),
        "equation string": lambda f: f"W = {f}",
        "unknown symbol": lambda f: f"({f}) + q",
        "unclosed parenthesis": lambda f: f"({f}",
        "attribute": lambda f: f"({f}).evalf()",
    },
    Tuple: {
        "dict": lambda t: dict(enumerate(t)),
        "string": lambda t: str(t),
        "one item fewer": lambda t: t[:-1],
        "one item more": lambda t: (*t, t[0]),
        "nested": lambda t: (t,),
        "object array": _object_vector,
        "generator": lambda t: (x for x in t),
    },
}


def _right_forms(kind, value):
    """The reference ``value`` in the forms of the right kind a student may write."""
    if isinstance(kind, Real):
        forms = [np.float64(value), np.array(value), sympy.Float(value)]
        forms += [fractions.Fraction(value), decimal.Decimal(value)]
        # one number in an array (np.mean(x, keepdims=True), a (1, 1) product): the number
        forms += [np.array([value]), np.array([[value]], dtype=np.float32).astype(float)]
        return forms + ([int(value)] if float(value).is_integer() else [])
    if isinstance(kind, Int):
        return [np.int64(value), float(value), np.float64(value), np.array(value)] + [
            sympy.Integer(value),
            np.int32(value),
            np.array([value]),
        ]
    if isinstance(kind, Bool):
        # a yes/no question: True/False of any type, or the words yes and no
        return [np.bool_(value), np.array(value), np.array([value]), "yes" if value else "No"]
    if isinstance(kind, Choice):
        return [np.str_(value), f"  {value.upper()}  ", np.array(value)]
    if isinstance(kind, Shape):
        return [list(value), np.array(value), tuple(np.int64(v) for v in value)] + [
            tuple(float(v) for v in value)
        ]
    if isinstance(kind, RealArray):
        a = np.asarray(value)
        forms = [
            a.tolist(),
            np.ma.masked_array(a),
            [tuple(r) for r in a] if a.ndim == 2 else tuple(a),
        ]
        if np.array_equal(a, np.round(a)):
            forms.append(a.astype(int))
        if a.ndim == 2:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", PendingDeprecationWarning)  # np.matrix is legacy
                forms += [np.asmatrix(a), sympy.Matrix(a)]
        if kind.sparse:
            forms.append(sp.csr_matrix(np.atleast_2d(a)))
        return forms
    if isinstance(kind, Formula):
        expr = kind.coerce(value)
        return [expr, sympy.expand(expr), sympy.factor(expr), np.str_(value), np.array(value),
                f"  {value}  ", value.replace("theta", "θ")]
    if isinstance(kind, Tuple):
        items = list(value)
        forms = [items] + [
            tuple(_in_form(item_kind, j, v) for item_kind, v in zip(kind.items, items))
            for j in range(3)
        ]
        if len({np.shape(v) for v in items}) == 1:
            forms.append(np.array(items))
        if all(isinstance(k, (Real, Int)) for k in kind.items):  # n numbers as a row, a column
            forms += [np.array([items], dtype=float), np.array(items, dtype=float)[:, None]]
        return forms
    raise AssertionError(f"no right forms for {kind!r}")


def _wrong_forms(kind, value):
    """``[(label, wrong value, the kind the message must name)]`` for the reference ``value``."""
    return [
        (label, make(value), kind)
        for label, make in WRONG_KINDS[type(kind)].items()
        if not (label == "sparse" and getattr(kind, "sparse", False))
    ]


def _checks_by_name():
    out = {}
    for chapter in CHAPTERS:
        module = importlib.import_module(f"lagolib.exercises.{chapter}")
        for fname, fn in sorted(vars(module).items()):
            if fname.startswith("check_") and inspect.isfunction(fn):
                if fn.__module__ == module.__name__:
                    out[f"{chapter}.{fname}"] = fn
    return out


CHECKS = _checks_by_name()


def test_every_check_declares_its_answers_and_has_a_reference():
    assert set(REFERENCE) == set(CHECKS), "add the new check's correct call to REFERENCE"
    for name, check in CHECKS.items():
        answers = getattr(check, "answers", None)
        assert answers, f"{name}: declare its answers' kinds in @check(...)"
        params = set(inspect.signature(check).parameters)
        assert set(answers) <= params, name


def _verdict(capsys, check, kwargs):
    ok = check(**kwargs)
    out = capsys.readouterr().out
    assert ok is True or ok is False
    return ok, out


def _answers(name):
    """``(check, reference kwargs, [(answer name, kind, reference value)])``."""
    check = CHECKS[name]
    kwargs = REFERENCE[name]()
    assert set(kwargs) == set(inspect.signature(check).parameters), name
    return check, kwargs, [(a, kind, kwargs[a]) for a, kind in check.answers.items()]


def _returning(fn, transform):
    def student(*args, **kwargs):
        return transform(fn(*args, **kwargs))

    return student


@pytest.mark.parametrize("name", sorted(REFERENCE))
def test_wrong_kinds_are_not_yet_and_name_the_kind(name, capsys):
    check, kwargs, answers = _answers(name)
    ex = check.exercise
    failures = []
    for answer, kind, reference in answers:
        if isinstance(kind, Function):
            # the student's function returns the reference result in a wrong form
            probe = kind.returns
            cases = [
                (label, _returning(reference, functools.partial(_mutate, probe, label)), named)
                for label, named in _labels(probe)
            ]
        else:
            cases = _wrong_forms(kind, reference)
        for label, wrong, named in cases:
            ok, out = _verdict(capsys, check, {**kwargs, answer: wrong})
            where = f"{answer} ({label})"
            if ok or not out.startswith(f"Exercise {ex} — not yet: "):
                failures.append(f"{where}: {out.strip()[:200]}")
            elif named.what not in out:
                failures.append(f"{where}: does not name {named.what!r}: {out.strip()[:200]}")
            elif "could not read your answer" in out:
                failures.append(f"{where}: a generic message: {out.strip()[:200]}")
    assert not failures, f"{len(failures)} wrong kinds:\n" + "\n".join(failures[:12])


def _labels(kind):
    """``[(label, kind the message must name)]`` of the wrong forms of a result of ``kind``."""
    labels = [
        (label, kind)
        for label in WRONG_KINDS[type(kind)]
        if not (label == "sparse" and getattr(kind, "sparse", False))
    ]
    if isinstance(kind, Tuple):  # one item of the returned tuple at a time
        for k, item_kind in enumerate(kind.items):
            labels += [(f"{k}:{label}", named) for label, named in _labels(item_kind)]
    return labels


def _mutate(kind, label, value):
    """The result ``value`` of ``kind`` in the wrong form ``label`` (see :func:`_labels`)."""
    if isinstance(kind, Tuple) and ":" in label and label.split(":", 1)[0].isdigit():
        k, rest = label.split(":", 1)
        items = list(value)
        items[int(k)] = _mutate(kind.items[int(k)], rest, items[int(k)])
        return tuple(items)
    if isinstance(kind, RealArray):
        value = np.asarray(value, dtype=float)
    return WRONG_KINDS[type(kind)][label](value)


def _in_form(kind, k, value):
    """A result ``value`` of ``kind`` in its ``k``-th right form (the forms repeat cyclically)."""
    forms = _right_forms(kind, value)
    return forms[k % len(forms)]


@pytest.mark.parametrize("name", sorted(REFERENCE))
def test_right_answers_in_every_form_are_correct(name, capsys):
    check, kwargs, answers = _answers(name)
    ok, out = _verdict(capsys, check, kwargs)
    assert ok, f"{name}: the reference answer is not correct: {out}"
    n_forms = max(
        6 if isinstance(kind, Function) else len(_right_forms(kind, reference))
        for _, kind, reference in answers
    )
    # one call per form k: every answer (every result of a function) in its k-th form at once
    for k in range(n_forms):
        call = dict(kwargs)
        for answer, kind, reference in answers:
            if isinstance(kind, Function):
                call[answer] = _returning(reference, functools.partial(_in_form, kind.returns, k))
            else:
                call[answer] = _in_form(kind, k, reference)
        ok, out = _verdict(capsys, check, call)
        assert ok, f"{name}, form {k}: {out}"
