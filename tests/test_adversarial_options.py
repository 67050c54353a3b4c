"""Adversarial inputs to the optimizer, linear algebra, estimation, uncertainty, closed form and
simulators (issue 11, §5 options/solver classes and §6).

Every misuse must raise a lagolib error that is also the builtin a user catches (``ValueError`` or
``TypeError``) and whose message names the argument, the vertex or the edge — never a numpy or
qdldl traceback, a hang, or a silently wrong answer.  Graphs are tiny and iteration counts small:
the whole file runs in a few seconds.
"""

import numpy as np
import pytest
import scipy.sparse as sp

import lagolib
from lagolib import closed_form as cf
from lagolib import estimation, linalg, simulate, uncertainty
from lagolib import gauss_newton as gn
from lagolib.errors import (
    GraphError,
    LagolibError,
    NotPositiveDefiniteError,
    OptionError,
    OptionTypeError,
)

SIM = simulate.loop_world(laps=1, poses_per_lap=8, rng=1)
G = SIM.graph  # vertex ids 0..7 and the chain of 7 odometry edges 0 -> 1 -> ... -> 7
LOOP = simulate.grid_world(rows=3, cols=3, rng=0).graph  # satisfies the closed form's rules
NAN = float("nan")
INF = float("inf")


def _raises(exc, builtin, words, fn):
    """``fn()`` raises ``exc`` (a lagolib error and a ``builtin``) whose message has ``words``."""
    with pytest.raises(exc) as info:
        fn()
    err = info.value
    assert isinstance(err, LagolibError) and isinstance(err, builtin), type(err).__mro__
    for word in words:
        assert word in str(err), f"{word!r} not in {str(err)!r}"
    return err


# ------------------------------------------------------------------- OPTIONS: optimize
OPTIMIZE_BAD = [
    # (keyword, value, exception, builtin)
    ("method", "newton", OptionError, ValueError),
    ("method", None, OptionError, ValueError),
    ("method", 1, OptionError, ValueError),
    ("error", "exp", OptionError, ValueError),
    ("linear_solver", "lu", OptionError, ValueError),
    ("backend", "mkl", OptionError, ValueError),
    ("max_iterations", -1, OptionError, ValueError),
    ("max_iterations", 1.5, OptionTypeError, TypeError),
    ("max_iterations", True, OptionTypeError, TypeError),
    ("max_iterations", "10", OptionTypeError, TypeError),
    ("max_iterations", INF, OptionTypeError, TypeError),
    ("tol", NAN, OptionError, ValueError),
    ("tol", INF, OptionError, ValueError),
    ("tol", -1e-3, OptionError, ValueError),
    ("tol", "1e-6", OptionTypeError, TypeError),
    ("tol", 1j, OptionTypeError, TypeError),
    ("step_tol", NAN, OptionError, ValueError),
    ("step_tol", -1.0, OptionError, ValueError),
    ("lambda_initial", 0.0, OptionError, ValueError),
    ("lambda_initial", -1e-5, OptionError, ValueError),
    ("lambda_initial", NAN, OptionError, ValueError),
    ("lambda_initial", INF, OptionError, ValueError),
    ("lambda_initial", -INF, OptionError, ValueError),
    ("max_backtracks", -1, OptionError, ValueError),
    ("max_backtracks", 2.0, OptionTypeError, TypeError),
    ("verbose", "yes", OptionTypeError, TypeError),
    ("verbose", 1, OptionTypeError, TypeError),
]


@pytest.mark.parametrize("method", ["gn", "lm"])
@pytest.mark.parametrize(("key", "value", "exc", "builtin"), OPTIMIZE_BAD)
def test_optimize_rejects_bad_options(key, value, exc, builtin, method):
    # also the no-hang tests: LM with lambda_initial <= 0, nan or inf used to loop forever
    # (lambda *= 10 never passes 1e10); now refused before the first iteration
    kwargs = {"method": method, "max_iterations": 3, key: value}
    _raises(exc, builtin, ["optimize", key], lambda: lagolib.optimize(G, **kwargs))


def test_optimize_rejects_a_non_graph():
    _raises(OptionTypeError, TypeError, ["graph", "PoseGraph"], lambda: lagolib.optimize("g.g2o"))


# ------------------------------------------------------------------- OPTIONS: the rest
def _pcg(**kw):
    H = sp.diags([4.0] * 6, format="csr")
    return lambda: linalg.pcg(H, np.ones(6), **kw)


OTHER_BAD = [
    # Prior
    ("Prior vertex", lambda: gn.Prior("a"), OptionTypeError, TypeError, ["vertex"]),
    ("Prior sigmas inf", lambda: gn.Prior.from_sigmas(0, sigmas=(1, INF, 1)), GraphError,
     ValueError, ["sigmas"]),
    ("Prior info overflow", lambda: gn.Prior(0, information=np.eye(3) * 1e200), GraphError,
     ValueError, ["Prior", "overflows"]),
    ("prior not a Prior", lambda: lagolib.optimize(G, prior=[(0, 0, 0)]), OptionTypeError,
     TypeError, ["prior"]),
    # uncertainty
    ("batch 0", lambda: uncertainty.marginal_covariances(G, batch=0), OptionError, ValueError,
     ["batch"]),
    ("batch -3", lambda: uncertainty.marginal_covariances(G, batch=-3), OptionError, ValueError,
     ["batch"]),
    ("batch 2.5", lambda: uncertainty.marginal_covariances(G, batch=2.5), OptionTypeError,
     TypeError, ["batch"]),
    ("frame", lambda: uncertainty.marginal_covariances(G, frame="world"), OptionError, ValueError,
     ["frame"]),
    ("mc backend", lambda: uncertainty.marginal_covariances(G, backend="mkl"), OptionError,
     ValueError, ["backend"]),
    ("rel frame", lambda: uncertainty.relative_covariances(G, 0, frame="x"), OptionError,
     ValueError, ["frame"]),
    ("im error", lambda: uncertainty.information_matrix(G, error="exp"), OptionError, ValueError,
     ["error"]),
    *[
        (f"confidence {c!r}",
         lambda c=c: uncertainty.loop_closure_test(G, 0, 3, [3, 0, 0], np.eye(3), confidence=c),
         OptionError, ValueError, ["confidence"])
        for c in (0.0, 1.0, 1.5, -0.1, NAN, INF)
    ],
    ("confidence str",
     lambda: uncertainty.loop_closure_test(G, 0, 3, [3, 0, 0], np.eye(3), confidence="high"),
     OptionTypeError, TypeError, ["confidence"]),
    # closed form
    ("cf tol nan", lambda: cf.closed_form(LOOP, tol=NAN), OptionError, ValueError, ["tol"]),
    ("cf tol -1", lambda: cf.closed_form(LOOP, tol=-1.0), OptionError, ValueError, ["tol"]),
    ("cf max_iterations -1", lambda: cf.closed_form(LOOP, max_iterations=-1), OptionError,
     ValueError, ["max_iterations"]),
    ("cf max_iterations 2.5", lambda: cf.closed_form(LOOP, max_iterations=2.5), OptionTypeError,
     TypeError, ["max_iterations"]),
    ("cf initial", lambda: cf.closed_form(LOOP, initial="truth"), OptionError, ValueError,
     ["initial"]),
    ("cf if_worse", lambda: cf.closed_form(LOOP, if_worse="ignore"), OptionError, ValueError,
     ["if_worse"]),
    ("sincos max_iterations", lambda: cf.optimize_sincos(LOOP, max_iterations=-2), OptionError,
     ValueError, ["max_iterations"]),
    ("sincos tol", lambda: cf.optimize_sincos(LOOP, tol=NAN), OptionError, ValueError, ["tol"]),
    ("origin", lambda: cf.positions_from_orientations(LOOP, LOOP.poses[:, 2], origin=(0, NAN)),
     OptionError, ValueError, ["origin"]),
    ("so net", lambda: cf.solve_orthogonality(LOOP, np.zeros(16)), OptionTypeError, TypeError,
     ["net"]),
    # linalg
    ("chol backend", lambda: linalg.SparseCholesky(sp.eye(3, format="csc"), "mkl"), OptionError,
     ValueError, ["backend"]),
    ("chol dense", lambda: linalg.SparseCholesky(np.eye(3)), OptionTypeError, TypeError, ["H"]),
    ("chol nan", lambda: linalg.SparseCholesky(sp.csc_matrix(np.diag([1.0, NAN]))), OptionError,
     ValueError, ["H", "non-finite"]),
    ("chol inf", lambda: linalg.SparseCholesky(sp.csc_matrix(np.diag([INF, 1.0]))), OptionError,
     ValueError, ["H", "non-finite"]),
    ("chol asym", lambda: linalg.SparseCholesky(sp.csc_matrix([[2.0, 0.0], [1.0, 2.0]])),
     OptionError, ValueError, ["H", "symmetric"]),
    ("chol complex", lambda: linalg.SparseCholesky(sp.csc_matrix(np.eye(2) * 1j)),
     OptionTypeError, TypeError, ["H", "real"]),
    ("chol b nan", lambda: linalg.SparseCholesky(sp.eye(2, format="csc")).solve([1, NAN]),
     OptionError, ValueError, ["b"]),
    ("chol b shape", lambda: linalg.SparseCholesky(sp.eye(2, format="csc")).solve([1, 2, 3]),
     OptionError, ValueError, ["b", "shape"]),
    ("pcg rtol nan", _pcg(rtol=NAN), OptionError, ValueError, ["rtol"]),
    ("pcg rtol -1", _pcg(rtol=-1.0), OptionError, ValueError, ["rtol"]),
    ("pcg maxiter -1", _pcg(maxiter=-1), OptionError, ValueError, ["maxiter"]),
    ("pcg maxiter 1.5", _pcg(maxiter=1.5), OptionTypeError, TypeError, ["maxiter"]),
    ("pcg block 0", _pcg(block=0), OptionError, ValueError, ["block"]),
    ("pcg block 4", _pcg(block=4), OptionError, ValueError, ["block"]),
    ("pcg preconditioner", _pcg(preconditioner="ilu"), OptionError, ValueError,
     ["preconditioner"]),
    ("pcg x0", _pcg(x0=np.zeros(5)), OptionError, ValueError, ["x0"]),
    ("pcg x0 nan", _pcg(x0=np.full(6, NAN)), OptionError, ValueError, ["x0"]),
    ("pcg b nan", lambda: linalg.pcg(sp.eye(3, format="csr"), [1, NAN, 1]), OptionError,
     ValueError, ["b"]),
    # estimation
    ("blue backend", lambda: estimation.blue(sp.csr_matrix([[1.0, 1.0]]), [1, 2], [1, 1],
                                              backend="x"), OptionError, ValueError, ["backend"]),
    ("blue z nan", lambda: estimation.blue(sp.csr_matrix([[1.0, 1.0]]), [1, NAN], [1, 1]),
     OptionError, ValueError, ["z"]),
    ("blue info inf", lambda: estimation.blue(sp.csr_matrix([[1.0, 1.0]]), [1, 2], [1, INF]),
     OptionError, ValueError, ["information"]),
    ("blue z complex", lambda: estimation.blue(sp.csr_matrix([[1.0, 1.0]]), [1j, 2], [1, 1]),
     OptionTypeError, TypeError, ["z"]),
    ("blue info shape", lambda: estimation.blue(sp.csr_matrix([[1.0, 1.0]]), [1, 2], [1, 1, 1]),
     OptionError, ValueError, ["information"]),
    ("BLUE rows", lambda: estimation.blue(sp.csr_matrix([[1.0, 1.0]]), [1, 2], [1, 1])
     .covariance([5]), OptionError, ValueError, ["rows"]),
    # simulate
    *[
        (f"rng {r!r}", lambda r=r: simulate.loop_world(rng=r), exc, builtin, ["rng"])
        for r, exc, builtin in [
            (None, OptionTypeError, TypeError),
            (-1, OptionError, ValueError),
            (1.5, OptionTypeError, TypeError),
            ("seed", OptionTypeError, TypeError),
        ]
    ],
    *[
        (f"loop_world {k}={v!r}", lambda k=k, v=v: simulate.loop_world(**{k: v}), exc, b, [k])
        for k, v, exc, b in [
            ("laps", 0, OptionError, ValueError),
            ("laps", 1.5, OptionTypeError, TypeError),
            ("poses_per_lap", 1, OptionError, ValueError),
            ("poses_per_lap", 10, OptionError, ValueError),  # square needs a multiple of 4
            ("shape", "hexagon", OptionError, ValueError),
            ("step", 0.0, OptionError, ValueError),
            ("step", NAN, OptionError, ValueError),
            ("closure_probability", 1.5, OptionError, ValueError),
            ("closure_probability", -0.1, OptionError, ValueError),
            ("sigma_xy", 0.0, OptionError, ValueError),
            ("sigma_theta", INF, OptionError, ValueError),
            ("sigma_theta", -0.1, OptionError, ValueError),
            ("floor", 0.0, OptionError, ValueError),
            ("noise", "huge", OptionError, ValueError),
            ("noiseless", "yes", OptionTypeError, TypeError),
        ]
    ],
    *[
        (f"manhattan {k}={v!r}", lambda k=k, v=v: simulate.manhattan_world(**{k: v}), exc, b, [k])
        for k, v, exc, b in [
            ("n_poses", 1, OptionError, ValueError),
            ("extent", 1, OptionError, ValueError),
            ("step", -1.0, OptionError, ValueError),
            ("turn_probability", 2.0, OptionError, ValueError),
            ("closure_radius", -1.0, OptionError, ValueError),
            ("closure_probability", NAN, OptionError, ValueError),
            ("min_separation", 0, OptionError, ValueError),
        ]
    ],
    *[
        (f"grid {k}={v!r}", lambda k=k, v=v: simulate.grid_world(**{k: v}), exc, b, [k])
        for k, v, exc, b in [
            ("rows", 0, OptionError, ValueError),
            ("cols", 2.5, OptionTypeError, TypeError),
            ("closure_noise", 0.0, OptionError, ValueError),
            ("sigma_xy", -1.0, OptionError, ValueError),
            ("step", INF, OptionError, ValueError),
        ]
    ],
    ("grid 1x1", lambda: simulate.grid_world(rows=1, cols=1), OptionError, ValueError, ["rows"]),
    ("measure sigma shape", lambda: simulate.measure(np.zeros((3, 3)), [[0, 1], [1, 2]],
                                                     sigma_xy=[1.0, 1.0, 1.0]), OptionError,
     ValueError, ["sigma_xy"]),
    ("measure truth nan", lambda: simulate.measure(np.full((2, 3), NAN), [[0, 1]]), GraphError,
     ValueError, ["truth"]),
    ("measure edge range", lambda: simulate.measure(np.zeros((2, 3)), [[0, 5]]), GraphError,
     ValueError, ["edge 0"]),
]  # fmt: skip


@pytest.mark.parametrize(
    ("fn", "exc", "builtin", "words"),
    [case[1:] for case in OTHER_BAD],
    ids=[case[0] for case in OTHER_BAD],
)
def test_other_functions_reject_bad_options(fn, exc, builtin, words):
    _raises(exc, builtin, words, fn)


# ------------------------------------------------------------------- vertex ids name their argument
ID_BAD = [
    ("relative i", lambda: uncertainty.relative_covariances(G, 999), ["i (the reference", "999"]),
    ("relative vertices", lambda: uncertainty.relative_covariances(G, 0, [1, 999]),
     ["vertices", "999"]),
    ("marginal vertices", lambda: uncertainty.marginal_covariances(G, [999]), ["vertices", "999"]),
    ("gate i", lambda: uncertainty.loop_closure_test(G, 999, 3, [1, 0, 0], np.eye(3)),
     ["loop_closure_test: i", "999"]),
    ("gate j", lambda: uncertainty.loop_closure_test(G, 0, 999, [1, 0, 0], np.eye(3)),
     ["loop_closure_test: j", "999"]),
    ("sincos fixed", lambda: cf.optimize_sincos(LOOP, fixed=999), ["fixed", "999"]),
]  # fmt: skip


@pytest.mark.parametrize(("fn", "words"), [c[1:] for c in ID_BAD], ids=[c[0] for c in ID_BAD])
def test_vertex_id_errors_name_the_argument(fn, words):
    err = _raises(GraphError, ValueError, words, fn)
    if "i (the reference" in words[0]:
        assert "fixed" not in str(err)  # it used to blame `fixed`


# ------------------------------------------------------------------- non-finite initial guesses
# (optimize and the uncertainty functions already named the vertex: tests/test_least_squares.py)
def _poisoned(graph, row, value):
    x = graph.poses.copy()
    x[row, 1] = value
    return x


CF_NONFINITE = [
    ("closed_form", lambda x: cf.closed_form(LOOP, initial=x)),
    ("optimize_sincos", lambda x: cf.optimize_sincos(LOOP, x)),
    ("sincos_chi2", lambda x: cf.sincos_chi2(LOOP, x)),
    ("sincos_gradient", lambda x: cf.sincos_gradient(LOOP, x)),
]


@pytest.mark.parametrize("value", [NAN, INF])
@pytest.mark.parametrize(("fn",), [c[1:] for c in CF_NONFINITE], ids=[c[0] for c in CF_NONFINITE])
def test_closed_form_non_finite_poses_name_the_vertex(fn, value):
    _raises(
        GraphError, ValueError, ["vertex id 4", "not finite"], lambda: fn(_poisoned(LOOP, 4, value))
    )


def test_closed_form_angles_and_t0_name_the_vertex():
    theta = LOOP.poses[:, 2].copy()
    theta[6] = NAN
    _raises(GraphError, ValueError, ["theta", "vertex id 6"],
            lambda: cf.positions_from_orientations(LOOP, theta))  # fmt: skip
    net = cf.network(LOOP)
    t0 = net.t_of(LOOP.poses[net.vertex, 2])
    t0[4:6] = 0.0  # node 3: (c, s) = (0, 0) cannot be normalized
    _raises(GraphError, ValueError, ["t0", "vertex id 3"], lambda: cf.solve_orthogonality(net, t0))


# ------------------------------------------------------------------- SOLVER: overflow, singular
def _with_information(graph, k, scale):
    info = graph.information.copy()
    info[k] *= scale
    return lagolib.PoseGraph(graph.poses, graph.edges, graph.measurements, info)


@pytest.mark.parametrize("method", ["gn", "lm"])
def test_overflowing_chi2_names_the_edge_not_ill_conditioning(method):
    far = G.poses.copy()
    far[4] = [1e200, -1e200, 0.0]  # edges 3 (3 -> 4) and 4 (4 -> 5) overflow
    err = _raises(GraphError, ValueError, ["edge 3 (vertex ids 3 -> 4)", "overflows float64"],
                  lambda: lagolib.optimize(G, far, method=method))  # fmt: skip
    assert err.edge == 3 and "ill-conditioned" not in str(err)
    err = _raises(GraphError, ValueError, ["prior on vertex id 0", "overflows"],
                  lambda: lagolib.optimize(G, prior=lagolib.Prior(0, mean=(1e200, 0, 0))))  # fmt: skip


@pytest.mark.parametrize("method", ["gn", "lm"])
@pytest.mark.parametrize("scale", [1e40, 1e90])
def test_information_spanning_many_orders_names_both_edges(method, scale):
    bad = _with_information(G, 3, scale)
    err = _raises(GraphError, ValueError, ["H is not positive definite", "orders of magnitude",
                                           "edge 3 (vertex ids 3 -> 4)", "edge 0"],
                  lambda: lagolib.optimize(bad, method=method, max_iterations=3))  # fmt: skip
    assert err.edge == 3 and "Matrix A is empty" not in str(err)


@pytest.mark.parametrize("backend", ["qdldl", "scipy"])
def test_zero_or_underflowing_matrices_are_lagolib_errors(backend):
    with pytest.raises(NotPositiveDefiniteError) as info:
        linalg.SparseCholesky(sp.csc_matrix((3, 3)), backend)
    assert "Matrix A is empty" not in str(info.value)
    tiny = linalg.SparseCholesky(sp.csc_matrix(np.eye(2) * 1e-320), backend)
    with pytest.raises(NotPositiveDefiniteError, match="numerically singular"):
        tiny.solve(np.ones(2))  # used to return [inf, inf]


def test_gate_information_overflow_is_a_graph_error_not_linalg_error():
    _raises(GraphError, ValueError, ["loop_closure_test", "information"],
            lambda: uncertainty.loop_closure_test(G, 0, 3, [3, 0, 0], np.diag([INF, 1, 1])))  # fmt: skip
