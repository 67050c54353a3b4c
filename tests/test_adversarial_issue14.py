"""Adversarial tests for issue 14: lagolib.certify and the ``lagolib certify`` / ``solve --certify``
command lines.

Two kinds of test live here.  *Guards* pin behaviour that was correct when they were written:
the certified chordal optimum equals a brute-force minimum over a grid of angles on 3-pose graphs
(translations solved exactly for each grid point), the lower bound holds against every point
reached, the sparse eigenvalues equal dense ones of the Schur complement, and the verdict does not
change under rigid motions, row permutations, unsorted ids or wrapped angles.  *Regressions*
reproduce defects found by this pass (a certificate for a point that is not a minimum, a point off
the unit circles "certified", a bisection that never ends with ``eta=0``, Newton's damping that
stops working when the information is scaled by 1e9, numpy errors escaping from public functions).

Small graphs only, seeded generators, no timing.
"""

import numpy as np
import pytest

import lagolib
from lagolib import PoseGraph, cli, se2, simulate
from lagolib import certify as C
from lagolib.errors import (
    GraphError,
    LagolibError,
    OptionError,
    OptionTypeError,
)

I3 = np.eye(3)


# ----------------------------------------------------------------------------- helpers
def _rotated_anisotropic(m, rng, low=(1, 20, 100), high=(5, 60, 400)):
    info = np.empty((m, 3, 3))
    for k in range(m):
        Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        info[k] = Q @ np.diag(rng.uniform(low, high)) @ Q.T
    return info


def _loop(seed=0, laps=2, per_lap=8, sigma_theta=0.05):
    sim = simulate.loop_world(laps=laps, poses_per_lap=per_lap, rng=seed, sigma_theta=sigma_theta)
    return sim.graph.with_information(
        _rotated_anisotropic(sim.graph.m, np.random.default_rng(seed))
    )


@pytest.fixture(scope="module")
def multilap():
    """A 4-lap loop with sigma_theta 0.5 and the spurious local minimum LM reaches from odometry
    (the certificate rejects it; one escape reaches the certified optimum f = 510.8674)."""
    g = _loop(1, laps=4, per_lap=8, sigma_theta=0.5)
    lm = lagolib.optimize(g, g.poses, method="lm")
    return g, lm.poses


@pytest.fixture(scope="module")
def multilap_solved(multilap):
    g, start = multilap
    return C.solve(g, initial=start)


@pytest.fixture(scope="module")
def small():
    """A certified point on a small loop: (graph, problem, refined poses)."""
    g = _loop(0, laps=2, per_lap=4)
    p = C.chordal_problem(g)
    return g, p, C.refine(p, g.poses).poses


@pytest.fixture(scope="module")
def rejected(multilap):
    """The multilap local minimum, polished, and its (not certified) certificate."""
    g, start = multilap
    p = C.chordal_problem(g)
    x = C.refine(p, start).poses
    return p, x, C.certify(p, x)


def _reduced_dense(S, n):
    """Schur complement of the dense S on the rotations, first translation removed."""
    keep_t = np.arange(1, n)
    A = S[np.ix_(keep_t, keep_t)]
    B = S[np.ix_(keep_t, n + np.arange(n))]
    return S[n:, n:] - B.conj().T @ np.linalg.solve(A, B)


def _random_graph(rng, n, extra, scale=1.0, ids=None):
    """A connected graph on n poses: an odometric chain plus ``extra`` random directed edges,
    random measurements (angles anywhere in (-pi, pi]) and rotated anisotropic information."""
    pairs = [(a, b) for a in range(n) for b in range(n) if a != b]
    pick = rng.choice(len(pairs), size=extra, replace=False)
    edges = [(k, k + 1) for k in range(n - 1)] + [pairs[k] for k in pick]
    m = len(edges)
    meas = np.column_stack([rng.normal(0, 2, (m, 2)), rng.uniform(-np.pi, np.pi, m)])
    info = scale * _rotated_anisotropic(m, rng, (0.1, 1, 10), (1, 10, 100))
    return PoseGraph(rng.normal(0, 1, (n, 3)), edges, meas, info, ids=ids)


def _brute_force_minimum(p, N=90):
    """min f over a grid of N^(n-1) rotations (the first fixed at 0), translations optimal for
    each (a linear solve), the 8 best polished by refine: the global chordal minimum of a 3-pose
    graph to the polish's precision."""
    n = p.n
    th = np.linspace(-np.pi, np.pi, N, endpoint=False)
    grids = np.meshgrid(*([th] * (n - 1)), indexing="ij")
    Z = np.stack([np.ones(grids[0].size)] + [np.exp(1j * g.ravel()) for g in grids])
    T = C.optimal_translations(p, Z, np.zeros(Z.shape[1]))
    X = np.vstack([T, Z])
    f = np.real(np.sum(X.conj() * (p.M @ X), axis=0))
    best = float(f.min())
    for k in np.argsort(f)[:8]:
        best = min(best, C.refine(p, C.from_complex(X[:, k])).chi2)
    return best


def _rigid(poses, phi, shift):
    out = poses.copy()
    out[:, :2] = poses[:, :2] @ se2.rotation(phi).T + shift
    out[:, 2] = se2.wrap_angle(poses[:, 2] + phi)
    return out


# ----------------------------------------------------------------------------- wrong answers
@pytest.mark.parametrize("seed", range(4))
def test_certified_optimum_is_the_brute_force_minimum_on_three_poses(seed):
    rng = np.random.default_rng(100 + seed)
    g = _random_graph(rng, 3, extra=int(rng.integers(1, 4)))
    p = C.chordal_problem(g)
    best = _brute_force_minimum(p)
    res = C.solve(g)
    assert res.lower_bound <= best * (1 + 1e-9) + 1e-12  # the bound holds for every point
    if res.certified:
        assert res.f == pytest.approx(best, rel=1e-7, abs=1e-12)
    assert res.f >= best * (1 - 1e-9)


def test_certify_does_not_certify_a_point_that_is_not_stationary():
    """Scaling a certified optimum's translations by 2 makes every multiplier negative, so
    S~ = M~ - diag(lambda) is positive definite: certify says certified=True at f = 494.9 where
    the optimum is 2.196 (and the certificate's own lower bound is -490.5).  The dual bound is
    valid, but "certified" must mean f(x) is (close to) the bound."""
    g = _loop(0)
    p = C.chordal_problem(g)
    opt = C.refine(p, g.poses).poses
    f_opt = C.chordal_cost(p, opt)
    assert C.certify(p, opt).certified
    far = opt.copy()
    far[:, :2] *= 2.0
    cert = C.certify(p, far)
    assert cert.f > 100 * f_opt
    assert cert.lower_bound <= f_opt  # the bound itself is fine
    assert cert.certified is False, cert


@pytest.mark.parametrize("modulus", [0.0, 0.5])
def test_certify_does_not_certify_a_point_off_the_unit_circles(small, modulus):
    """certify accepts a complex x = [t; z] without checking |z_i| = 1: with z = 0 (translations
    of the optimum kept) it returned certified=True at f = 264.2 (the optimum is 1.3195), with
    z / 2 certified=True at f = 66.39."""
    g, p, opt = small
    x = C.to_complex(opt)
    x[g.n :] *= modulus
    try:
        cert = C.certify(p, x)
    except OptionError as exc:  # rejecting the point is fine: |z_i| must be 1
        assert "z" in str(exc)
        return
    assert cert.certified is False, cert


def test_lower_bound_at_rejected_points_is_below_every_reached_cost(multilap, multilap_solved):
    g, start = multilap
    p = C.chordal_problem(g)
    rng = np.random.default_rng(3)
    reached = [multilap_solved.f]
    for _ in range(4):  # random restarts of the local solver
        z = np.exp(1j * rng.uniform(-np.pi, np.pi, g.n))
        x = np.concatenate([C.optimal_translations(p, z), z])
        reached.append(C.refine(p, C.from_complex(x)).chi2)
    assert multilap_solved.f == pytest.approx(min(reached), rel=1e-9)
    points = [start, g.poses, g.poses + rng.normal(0, 0.5, g.poses.shape)]
    for poses in points:
        cert = C.certify(p, poses)
        assert cert.gap >= 0 and cert.relative_gap >= 0
        assert cert.lower_bound <= min(reached) * (1 + 1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_sparse_eigenvalues_match_dense_on_random_graphs_and_points(seed):
    """Unsorted ids, scales 1e-6 .. 1e8, stationary and non-stationary points, k up to n."""
    rng = np.random.default_rng(200 + seed)
    n = int(rng.integers(3, 8))
    scale = [1e-6, 1.0, 1e4, 1e8][seed]
    g = _random_graph(rng, n, int(rng.integers(1, 2 * n)), scale, ids=rng.permutation(100)[:n])
    p = C.chordal_problem(g)
    points = [g.poses, C.refine(p, g.poses, method="gn", max_iterations=100).poses]
    for poses in points:
        k = int(rng.integers(1, n + 1))
        cert = C.certify(p, poses, eigenvalues=k)
        S = C.certificate_matrix(p, C.to_complex(poses)).toarray()
        ev = np.linalg.eigvalsh(_reduced_dense(S, n))
        sc = np.abs(ev).max()
        assert cert.eigenvalues.shape == (k,)
        np.testing.assert_allclose(cert.eigenvalues, ev[:k], atol=1e-8 * sc)
        assert cert.certified == (ev[0] >= -cert.eta)
        if not cert.certified:
            assert cert.lower_bound == pytest.approx(
                cert.multipliers.sum() + n * ev[0], abs=1e-8 * sc * n
            )


# ----------------------------------------------------------------------------- invariances
@pytest.mark.parametrize(
    "phi,shift", [(np.pi - 1e-9, (100.0, -50.0)), (2.0, (1e3, 1e3)), (-np.pi / 2, (0.0, 0.0))]
)
def test_rigid_motion_of_the_whole_graph_changes_nothing(multilap, multilap_solved, phi, shift):
    g, start = multilap
    moved = g.with_poses(_rigid(g.poses, phi, np.array(shift)))
    res = C.solve(moved, initial=_rigid(start, phi, np.array(shift)))
    assert res.certified == multilap_solved.certified is True
    assert res.f == pytest.approx(multilap_solved.f, rel=1e-9)
    assert res.chi2 == pytest.approx(multilap_solved.chi2, rel=1e-9)


def test_row_order_and_unsorted_ids_change_nothing(multilap, multilap_solved):
    g, start = multilap
    perm = np.random.default_rng(4).permutation(g.n)
    inv = np.argsort(perm)
    gp = PoseGraph(g.poses[perm], inv[g.edges], g.measurements, g.information, ids=g.ids[perm])
    res = C.solve(gp, initial=start[perm])
    assert res.certified and res.f == pytest.approx(multilap_solved.f, rel=1e-9)
    # the same poses, row for row
    back = res.chordal_poses[inv]
    rel = se2.between(np.repeat(back[:1], g.n, 0), back)
    ref = multilap_solved.chordal_poses
    rel0 = se2.between(np.repeat(ref[:1], g.n, 0), ref)
    np.testing.assert_allclose(rel[:, :2], rel0[:, :2], atol=1e-6)


def test_wrapped_measurement_and_pose_angles_change_nothing(multilap, multilap_solved):
    g, start = multilap
    rng = np.random.default_rng(5)
    meas = g.measurements.copy()
    meas[:, 2] += 2 * np.pi * rng.integers(-3, 4, g.m)
    gw = PoseGraph(g.poses, g.edges, meas, g.information, ids=g.ids)
    wrapped = start.copy()
    wrapped[:, 2] += 2 * np.pi * rng.integers(-3, 4, g.n)
    for graph, initial in ((gw, start), (g, wrapped)):
        res = C.solve(graph, initial=initial)
        assert res.certified and res.f == pytest.approx(multilap_solved.f, rel=1e-9)


@pytest.mark.parametrize("scale", [1e-6, 1e9])
def test_scaling_all_information_scales_f_and_keeps_the_verdict(multilap, multilap_solved, scale):
    """Information 1e9 I is a valid graph (PoseGraph allows 1e-100 .. 1e100), but Newton's
    Levenberg damping is capped at an absolute 1e10 (gauss_newton.LAMBDA_MAX): refine and solve
    raised NotPositiveDefiniteError at scale 1e9 instead of returning 1e9 x the same f."""
    g, start = multilap
    gs = g.with_information(g.information * scale)
    res = C.solve(gs, initial=start)
    assert res.certified
    assert res.f / scale == pytest.approx(multilap_solved.f, rel=1e-8)


def test_refine_from_a_far_start_does_not_depend_on_the_information_scale():
    g = _loop(0, laps=2, per_lap=4)
    start = g.poses + np.random.default_rng(1).normal(0, 1.0, g.poses.shape)
    base = C.refine(g, start)
    assert base.converged
    big = C.refine(g.with_information(g.information * 1e9), start)
    assert big.converged
    assert big.chi2 / 1e9 == pytest.approx(base.chi2, rel=1e-8)


# ----------------------------------------------------------------------------- special graphs
def test_noiseless_graphs_near_pi_trees_two_poses_and_parallel_edges_are_certified():
    n = 6
    meas = np.array([[1.0, 0.0, np.pi]] * n)
    meas[::2, 2] = -np.pi  # every measured angle at +-pi
    ring = PoseGraph(np.zeros((n, 3)), [[k, (k + 1) % n] for k in range(n)], meas, [I3] * n)
    tree = PoseGraph(
        np.zeros((5, 3)),
        [[0, 1], [1, 2], [1, 3], [3, 4]],
        np.tile([1.0, 0.5, 3.1], (4, 1)),
        [I3] * 4,
    )
    two = PoseGraph(np.zeros((2, 3)), [[0, 1]], [[1.0, 2.0, 3.1]], [I3])
    for g in (ring, tree, two):
        res = C.solve(g)
        assert res.certified and res.escapes == 0, g
        assert res.f < 1e-20 and res.chi2 < 1e-20
        assert res.lower_bound <= res.f
    parallel = PoseGraph(
        np.zeros((2, 3)),
        [[0, 1], [0, 1], [1, 0]],
        [[1.0, 0, 3.0], [1.0, 0, -3.0], [0, 0, 0.5]],
        [I3, 2 * I3, I3],
    )
    p = C.chordal_problem(parallel)
    res = C.solve(parallel)
    assert res.certified
    assert res.f == pytest.approx(_brute_force_minimum(p, N=720), rel=1e-9)


def test_noiseless_graph_with_reversed_edges_is_certified_at_zero():
    """Reverse half the edges of a noiseless Manhattan world (inverse measurement, information
    moved into the other frame, Omega' = Ad^-T Omega Ad^-1): still f = 0, certified."""
    sim = simulate.manhattan_world(n_poses=80, rng=6, noiseless=True)
    g = sim.graph
    edges, meas, info = g.edges.copy(), g.measurements.copy(), g.information.copy()
    for k in range(0, g.m, 2):
        dx, dy, dth = meas[k]
        R = se2.rotation(dth)
        inv_t = -R.T @ np.array([dx, dy])
        A = np.eye(3)  # e_ji = -Ad(z_ij) e_ij to first order: Ad = [[R, [dy, -dx]], [0, 1]]
        A[:2, :2], A[:2, 2] = R, [dy, -dx]
        Ainv = np.linalg.inv(A)
        edges[k] = edges[k][::-1]
        meas[k] = [inv_t[0], inv_t[1], -dth]
        info[k] = Ainv.T @ info[k] @ Ainv
    gr = PoseGraph(g.poses, edges, meas, 0.5 * (info + info.transpose(0, 2, 1)), ids=g.ids)
    res = C.solve(gr)
    assert res.certified and res.f < 1e-16 * g.m


def test_huge_rotation_noise_terminates_within_the_budget_and_says_why():
    sim = simulate.loop_world(laps=4, poses_per_lap=8, rng=0, sigma_theta=1.0)
    g = sim.graph
    for budget in (0, 3):
        res = C.solve(g, max_escapes=budget)
        assert res.escapes <= budget
        assert res.lower_bound <= res.f
        if not res.certified:
            assert res.reason.startswith("not certified:")
        else:
            assert res.reason.startswith("certified")
    assert not res.certified  # the rank-2 relaxation is not tight here
    assert "not tight" in res.reason or "max_escapes=3" in res.reason


# ----------------------------------------------------------------------------- eta = 0
def _count_factorizations(monkeypatch, limit=500):
    """Make a bisection that never ends fail fast: at most ``limit`` factorizations per call."""
    cls = getattr(C, "_ShiftedFactor", None)
    if cls is None:  # the implementation changed: nothing to count
        return
    original = cls.factor
    calls = {"n": 0}

    def counted(self, shift):
        calls["n"] += 1
        if calls["n"] > limit:
            raise AssertionError(f"certify: more than {limit} factorizations (shift {shift!r})")
        return original(self, shift)

    monkeypatch.setattr(cls, "factor", counted)


def test_certify_with_eta_zero_terminates_at_a_rejected_point(rejected, monkeypatch):
    """eta=0 passes check_real(minimum=0), and the log-bisection of certify's bracket then runs
    forever: lo = 0, mid = sqrt(0 * hi) = 0, factor(0) fails, lo = 0, ..."""
    p, x, cert = rejected
    _count_factorizations(monkeypatch)
    zero = C.certify(p, x, eta=0.0)
    assert zero.certified is False
    assert zero.lambda_min == pytest.approx(cert.lambda_min, rel=1e-6)


def test_certify_with_eta_zero_at_an_exact_optimum_does_not_raise(monkeypatch):
    """A noiseless graph at its truth (all multipliers 0, S~ singular): eta=0 raised
    NotPositiveDefiniteError('lost positive definiteness at a tested shift')."""
    g = PoseGraph(np.zeros((2, 3)), [[0, 1]], [[1.0, 0.0, 0.0]], [I3])
    _count_factorizations(monkeypatch)
    cert = C.certify(g, np.array([[0.0, 0, 0], [1.0, 0, 0]]), eta=0.0)
    assert cert.f == 0.0
    assert cert.lower_bound <= 0.0


# ----------------------------------------------------------------------------- misuse
def test_misuse_of_certify_gets_lagolib_errors(small):
    g, p, x = small
    n = g.n
    bad = x.copy()
    bad[2, 0] = np.nan
    cases = [
        (lambda: C.certify(p, bad), GraphError, "vertex id 2"),
        (lambda: C.certify(p, x[:, :2]), GraphError, "shape"),
        (lambda: C.certify(p, x.T), GraphError, "shape"),
        (lambda: C.certify(p, x + 0j), OptionError, "shape"),
        (lambda: C.certify(p, np.zeros((2 * n, 2, 2), complex)), OptionError, "shape"),
        (lambda: C.certify(p, [["a", "b", "c"]] * n), TypeError, "text"),
        (lambda: C.certify(p, x, eta=float("nan")), OptionError, "eta"),
        (lambda: C.certify(p, x, eta=float("inf")), OptionError, "eta"),
        (lambda: C.certify(p, x, eta=-1e-9), OptionError, "eta"),
        (lambda: C.certify(p, x, eta=True), OptionTypeError, "eta"),
        (lambda: C.certify(p, x, eta="1e-7"), OptionTypeError, "eta"),
        (lambda: C.certify(p, x, eigenvalues=True), OptionTypeError, "eigenvalues"),
        (lambda: C.certify(p, x, eigenvalues=2.5), OptionTypeError, "eigenvalues"),
        (lambda: C.certify(p, x, eigenvalues=n + 1), OptionError, "eigenvalues"),
        (lambda: C.certify("graph.g2o", x), OptionTypeError, "PoseGraph"),
    ]
    for call, kind, word in cases:
        with pytest.raises(kind, match=word) as exc:
            call()
        assert isinstance(exc.value, LagolibError)
        assert isinstance(exc.value, ValueError | TypeError)


def test_certify_eigenvalues_n_returns_all_of_them(small):
    g, p, x = small
    cert = C.certify(p, x, eigenvalues=g.n)
    S = C.certificate_matrix(p, C.to_complex(x)).toarray()
    ev = np.linalg.eigvalsh(_reduced_dense(S, g.n))
    np.testing.assert_allclose(cert.eigenvalues, ev, atol=1e-8 * np.abs(ev).max())


def test_certify_a_lifted_point_with_no_columns_is_an_option_error(small):
    """X of shape (2 n, 0) went through to numpy: 'zero-size array to reduction operation'."""
    g, p, _ = small
    with pytest.raises(OptionError, match="shape"):
        C.certify(p, np.zeros((2 * g.n, 0), complex))


def test_escape_with_the_certificate_of_another_graph_is_an_option_error(small, rejected):
    """The eigenvector has the other graph's length: numpy's 'all the input array dimensions
    ... must match exactly' came out."""
    g, p, x = small
    _, _, cert = rejected
    assert not cert.certified and cert.eigenvector.size != g.n
    with pytest.raises(OptionError, match="certificate"):
        C.escape(p, x, cert)


def test_escape_misuse_is_reported(rejected, small):
    p, x, cert = rejected
    _, p_small, x_small = small
    ok = C.certify(p_small, x_small)
    assert ok.certified
    with pytest.raises(OptionError, match="not certified"):
        C.escape(p_small, x_small, ok)
    with pytest.raises(OptionError, match="max_halvings"):
        C.escape(p, x, cert, max_halvings=-1)
    with pytest.raises(OptionTypeError, match="max_halvings"):
        C.escape(p, x, cert, max_halvings=True)
    X, alpha = C.escape(p, x, cert)
    assert alpha > 0 and C.lifted_cost(p, X) < cert.f


def test_misuse_of_solve_and_refine_gets_lagolib_errors(small):
    g, p, x = small
    bad = x.copy()
    bad[1, 2] = np.inf
    one = PoseGraph(np.zeros((1, 3)), np.zeros((0, 2)), np.zeros((0, 3)), np.zeros((0, 3, 3)))
    apart = PoseGraph(np.zeros((3, 3)), [[0, 1]], [[1.0, 0, 0]], [I3])
    cases = [
        (lambda: C.solve(g, max_escapes=True), OptionTypeError, "max_escapes"),
        (lambda: C.solve(g, max_escapes=2.0), OptionTypeError, "max_escapes"),
        (lambda: C.solve(g, initial=np.zeros((2, 3))), GraphError, "initial"),
        (lambda: C.solve(g, initial=bad), GraphError, "vertex id 1"),
        (lambda: C.solve(g, tree="nope"), OptionError, "tree"),
        (lambda: C.solve(g, tree=3), OptionTypeError, "tree"),
        (lambda: C.solve(g, eta=float("nan")), OptionError, "eta"),
        (lambda: C.solve(g, verbose=1), OptionTypeError, "verbose"),
        (lambda: C.solve(None), OptionTypeError, "PoseGraph"),
        (lambda: C.solve(one), GraphError, "1 pose"),
        (lambda: C.solve(apart), GraphError, "connected"),
        (lambda: C.refine(p, max_iterations=-1), OptionError, "max_iterations"),
        (lambda: C.refine(p, np.zeros((3, 3))), GraphError, "initial"),
        (lambda: C.refine(p, tol=float("nan")), OptionError, "tol"),
        (lambda: C.refine(p, method="bfgs"), OptionError, "method"),
    ]
    for call, kind, word in cases:
        with pytest.raises(kind, match=word) as exc:
            call()
        assert isinstance(exc.value, LagolibError)


def test_refine_with_zero_iterations_returns_the_start(small):
    g, p, _ = small
    res = C.refine(p, g.poses, max_iterations=0)
    np.testing.assert_array_equal(res.poses, g.poses)
    assert not res.converged and "max_iterations=0" in res.reason
    assert res.chi2 == pytest.approx(C.chordal_cost(p, g.poses), rel=1e-12)


def test_solve_with_a_huge_escape_budget_stops_when_certified(multilap):
    g, start = multilap
    res = C.solve(g, initial=start, max_escapes=10**12)
    assert res.certified and res.escapes == 1


def test_refine_lifted_checks_its_options_and_its_point(rejected):
    """refine_lifted accepted max_iterations=-1 and tol=nan silently, and a point with zero rows
    of Y (off the spheres) returned f = 0 — below the optimum — without a word."""
    p, x, _ = rejected
    X = C.to_complex(x)[:, None]
    with pytest.raises(OptionError, match="max_iterations"):
        C.refine_lifted(p, X, max_iterations=-1)
    with pytest.raises(OptionError, match="tol"):
        C.refine_lifted(p, X, tol=float("nan"))
    with pytest.raises(OptionError):
        C.refine_lifted(p, np.zeros((2 * p.n, 2), complex))


def test_round_solution_of_zero_rows_is_an_error_not_nan_poses(rejected):
    p, _, _ = rejected
    try:
        poses = C.round_solution(p, np.zeros((2 * p.n, 2), complex))
    except OptionError:
        return
    assert np.all(np.isfinite(poses)), "round_solution returned NaN poses"


def test_optimal_translations_bad_input_names_the_argument(small):
    """A z of the wrong length, text, a t_anchor of the wrong length: numpy's errors came out;
    a NaN z was blamed on 'SparseCholesky.solve: b'."""
    g, p, _ = small
    n = g.n
    cases = [
        (lambda: C.optimal_translations(p, np.ones(3)), "z"),
        (lambda: C.optimal_translations(p, "abc"), "z"),
        (lambda: C.optimal_translations(p, np.full(n, np.nan)), "z"),
        (lambda: C.optimal_translations(p, np.ones((n, 2)), [0, 0, 0]), "t_anchor"),
    ]
    for call, word in cases:
        with pytest.raises(LagolibError, match=word) as exc:
            call()
        assert isinstance(exc.value, ValueError | TypeError)


def test_to_complex_and_from_complex_bad_shapes_are_lagolib_errors():
    for call in (
        lambda: C.to_complex(np.zeros((3, 2))),
        lambda: C.to_complex("abc"),
        lambda: C.from_complex(np.zeros(5, complex)),
    ):
        with pytest.raises(LagolibError) as exc:
            call()
        assert isinstance(exc.value, ValueError | TypeError)


def test_chordal_cost_per_edge_must_be_a_bool(small):
    g, p, x = small
    with pytest.raises(OptionTypeError, match="per_edge"):
        C.chordal_cost(p, x, per_edge="no")


# ----------------------------------------------------------------------------- command line
def _call(capsys, *args):
    rc = cli.main([str(a) for a in args])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture
def files(tmp_path):
    two = tmp_path / "two.g2o"
    two.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n")
    one = tmp_path / "one.g2o"
    one.write_text("VERTEX_SE2 0 0 0 0\n")
    apart = tmp_path / "apart.g2o"
    apart.write_text(
        "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nVERTEX_SE2 2 2 0 0\n"
        "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n"
    )
    short = tmp_path / "short.g2o"
    short.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0\n")
    garbage = tmp_path / "garbage.g2o"
    garbage.write_text("hello world\n")
    return {"two": two, "one": one, "apart": apart, "short": short, "garbage": garbage}


@pytest.fixture(scope="module")
def local_minimum_file(tmp_path_factory, multilap):
    """The multilap graph with its LM local minimum as the file's poses."""
    g, start = multilap
    path = tmp_path_factory.mktemp("certify") / "local.g2o"
    lagolib.write(g.with_poses(start), path)
    return path


@pytest.mark.parametrize(
    "name,line", [("one", "1 pose"), ("apart", "not connected"), ("short", ":3:"), ("garbage", "")]
)
def test_cli_certify_bad_files_exit_1_with_one_line(capsys, files, tmp_path, name, line):
    out_path = tmp_path / "out.g2o"
    for argv in (["certify", files[name]], ["solve", files[name], "--method", "gn", "--certify"]):
        rc, out, err = _call(capsys, *argv, "-o", out_path)
        assert rc == 1, err
        assert err.startswith("lagolib: error: ") and len(err.strip().splitlines()) == 1
        assert line in err and "internal error" not in err and "Traceback" not in err
        assert not out_path.exists()


def test_cli_certify_unwritable_output_exits_1_and_writes_nothing(capsys, files, tmp_path):
    folder = tmp_path / "folder.g2o"
    folder.mkdir()
    for target in (folder, tmp_path / "missing" / "out.g2o", files["two"] / "out.g2o"):
        rc, out, err = _call(capsys, "certify", files["two"], "-o", target)
        assert rc == 1, err
        assert err.startswith("lagolib: error: -o ") and "internal error" not in err
    assert sorted(p.name for p in folder.iterdir()) == []


def test_cli_certify_usage_errors_exit_2(capsys, files):
    for extra in (
        ["--eigenvalues", "3"],  # two poses: at most 2
        ["--eigenvalues", "0"],
        ["--eta", "nan"],
        ["--eta", "-1"],
        ["--max-escapes", "-1"],
        ["--initial", "odometry", "--tree", "bfs"],
        ["-o", "out.txt"],
    ):
        rc, out, err = _call(capsys, "certify", files["two"], *extra)
        assert rc == 2, (extra, err)
        assert err.startswith("lagolib: error: ") and "certify --help" in err


def test_cli_exit_codes_certified_and_not(capsys, files, local_minimum_file, tmp_path):
    rc, out, err = _call(capsys, "certify", files["two"], "--eigenvalues", "2")
    assert rc == 0, err
    rc, out, err = _call(capsys, "certify", "square_loop")
    assert rc == 0, err
    out_path = tmp_path / "lm.g2o"
    rc, out, err = _call(
        capsys, "certify", local_minimum_file, "--initial", "odometry", "--max-escapes", "0",
        "-o", out_path,
    )  # fmt: skip
    assert rc == cli.NOT_CERTIFIED == 3, err
    assert "not certified: the budget of --max-escapes 0 ran out" in out  # said for the shell
    assert out_path.exists()
    rc, out, err = _call(capsys, "certify", local_minimum_file, "--initial", "odometry")
    assert rc == 0, err
    rc, out, err = _call(
        capsys, "solve", local_minimum_file, "--method", "gn", "--certify", "-o", out_path
    )
    assert rc == 3, err


def test_cli_certify_eta_zero_terminates(capsys, local_minimum_file, monkeypatch):
    """--eta 0 is accepted (non-negative) and hung in certify's bisection (see the API test)."""
    _count_factorizations(monkeypatch)
    rc, out, err = _call(
        capsys, "certify", local_minimum_file, "--initial", "odometry", "--max-escapes", "0",
        "--eta", "0",
    )  # fmt: skip
    assert rc == 3, err
    assert "internal error" not in err
