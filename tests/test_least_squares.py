"""lagolib.gauss_newton and lagolib.linalg: Jacobians, H and b, solvers, gauge, optimize."""

import numpy as np
import pytest
import scipy.sparse as sp

import lagolib
from lagolib import gauss_newton as gn
from lagolib import linalg, se2, simulate
from lagolib.errors import GaugeError, GraphError, NotPositiveDefiniteError


def random_edges(rng, m):
    p_i = rng.normal(size=(m, 3)) * [5, 5, 2]
    p_j = rng.normal(size=(m, 3)) * [5, 5, 2]
    z = rng.normal(size=(m, 3)) * [2, 2, 1]
    return p_i, p_j, z


def central_difference(f, x, h=1e-6):
    """d f / d x for f: (m, 3) -> (m, 3), column by column."""
    J = np.zeros(x.shape + (3,))
    for a in range(3):
        d = np.zeros(3)
        d[a] = h
        J[..., a] = (f(x + d) - f(x - d)) / (2 * h)
    return J


def away_from_wrap(e, margin=1e-3):
    return np.abs(np.abs(e[:, 2]) - np.pi) > margin


@pytest.mark.parametrize("error", ["t2v", "log"])
def test_jacobians_equal_central_differences(error):
    rng = np.random.default_rng(1)
    p_i, p_j, z = random_edges(rng, 500)
    e, A, B = gn.edge_jacobians(p_i, p_j, z, error=error)
    FA = central_difference(lambda x: gn.edge_jacobians(x, p_j, z, error=error)[0], p_i)
    FB = central_difference(lambda x: gn.edge_jacobians(p_i, x, z, error=error)[0], p_j)
    ok = away_from_wrap(e)
    assert ok.sum() > 490
    np.testing.assert_allclose(A[ok], FA[ok], atol=1e-7, rtol=1e-7)
    np.testing.assert_allclose(B[ok], FB[ok], atol=1e-7, rtol=1e-7)


def test_edge_error_equals_residuals_and_definition():
    rng = np.random.default_rng(2)
    p_i, p_j, z = random_edges(rng, 200)
    e, _, _ = gn.edge_jacobians(p_i, p_j, z)
    T = np.linalg.inv(se2.v2t(z)) @ np.linalg.inv(se2.v2t(p_i)) @ se2.v2t(p_j)
    np.testing.assert_allclose(e, se2.t2v(T), atol=1e-12)
    e_log, _, _ = gn.edge_jacobians(p_i, p_j, z, error="log")
    np.testing.assert_allclose(e_log, se2.log(se2.t2v(T)), atol=1e-12)


def test_log_error_matches_gtsam_betweenfactor():
    gtsam = pytest.importorskip("gtsam")
    rng = np.random.default_rng(3)
    p_i, p_j, z = random_edges(rng, 50)
    e, _, _ = gn.edge_jacobians(p_i, p_j, z, error="log")
    noise = gtsam.noiseModel.Unit.Create(3)
    for k in range(50):
        f = gtsam.BetweenFactorPose2(0, 1, gtsam.Pose2(*z[k]), noise)
        v = gtsam.Values()
        v.insert(0, gtsam.Pose2(*p_i[k]))
        v.insert(1, gtsam.Pose2(*p_j[k]))
        np.testing.assert_allclose(e[k], f.unwhitenedError(v), atol=1e-10)


@pytest.mark.parametrize("error", ["t2v", "log"])
def test_prior_jacobian_equals_central_differences(error):
    rng = np.random.default_rng(4)
    p = rng.normal(size=(100, 3))
    mean = rng.normal(size=(100, 3))
    e, J = gn.prior_jacobian(p, mean, error=error)
    F = central_difference(lambda x: gn.prior_jacobian(x, mean, error=error)[0], p)
    ok = away_from_wrap(e)
    np.testing.assert_allclose(J[ok], F[ok], atol=1e-7)
    np.testing.assert_allclose(gn.prior_jacobian(mean, mean)[0], 0, atol=1e-15)


@pytest.fixture(scope="module")
def noisy():
    """A small noisy two-lap world, away from its optimum."""
    sim = simulate.loop_world(laps=2, poses_per_lap=24, rng=np.random.default_rng(5))
    return sim.graph


@pytest.mark.parametrize("error", ["t2v", "log"])
def test_loop_and_vectorized_assembly_agree(noisy, error):
    rng = np.random.default_rng(6)
    poses = noisy.poses + rng.normal(size=noisy.poses.shape) * 0.05
    priors = [lagolib.Prior(0, (0.1, -0.2, 0.3)), lagolib.Prior(7)]
    H1, b1 = gn.build_linear_system_loop(noisy, poses, prior=priors, error=error)
    H2, b2, chi = gn.LinearSystem(noisy, fixed=(), prior=priors, error=error).assemble(poses)
    scale = abs(H1).max()
    assert abs(H1 - H2).max() <= 1e-12 * scale
    np.testing.assert_allclose(b2, b1, atol=1e-12 * np.abs(b1).max())
    expected = lagolib.chi2(noisy, poses, error=error)
    for p in priors:
        e, _ = gn.prior_jacobian(poses[p.vertex], p.mean, error=error)
        expected += e @ np.asarray(p.information) @ e
    assert chi == pytest.approx(expected, rel=1e-13)
    # fixing = deleting rows and columns of the full system
    fixed = [3, 10, 11]
    Hr, br = gn.reduce_system(noisy, H1, b1, fixed)
    system = gn.LinearSystem(noisy, fixed=fixed, prior=priors, error=error)
    H3, b3, _ = system.assemble(poses)
    assert H3.shape == (3 * (noisy.n - 3),) * 2
    assert abs(Hr - H3).max() <= 1e-12 * scale
    np.testing.assert_allclose(b3, br, atol=1e-12 * np.abs(b1).max())
    assert list(system.free) == [k for k in range(noisy.n) if k not in fixed]


def test_H_is_block_sparse_and_symmetric(noisy):
    H, _, _ = gn.LinearSystem(noisy, fixed=[0]).assemble(noisy.poses)
    assert (abs(H - H.T)).max() == 0.0
    # one 3x3 block per free pose and two per edge between free poses, fewer where repeated
    pairs = {tuple(sorted(e)) for e in noisy.edges.tolist() if 0 not in e}
    assert H.nnz == 9 * (noisy.n - 1 + 2 * len(pairs))


def test_solvers_agree():
    sim = simulate.manhattan_world(n_poses=150, rng=np.random.default_rng(7))
    H, b, _ = gn.LinearSystem(sim.graph, fixed=[0]).assemble(sim.graph.poses)
    ref = np.linalg.solve(H.toarray(), b)  # dense: test only, small graph
    for backend in linalg.available_backends():
        x = linalg.solve_spd(H, b, backend=backend)
        np.testing.assert_allclose(x, ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())
        X = linalg.SparseCholesky(H, backend).solve(np.column_stack([b, 2 * b]))
        np.testing.assert_allclose(X[:, 1], 2 * ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())
    out = linalg.pcg(H, b, rtol=1e-12)
    assert out.converged and out.iterations < H.shape[0]
    np.testing.assert_allclose(out.x, ref, rtol=1e-7, atol=1e-9 * np.abs(ref).max())
    assert out.residual_norms[0] == 1.0 and out.residual_norms[-1] <= 1e-12
    plain = linalg.pcg(H, b, preconditioner=None, rtol=1e-12)
    jac = linalg.pcg(H, b, preconditioner="jacobi", rtol=1e-12)
    assert out.iterations < plain.iterations and jac.converged


def test_refactor_reuses_pattern_and_matches_fresh_factor():
    sim = simulate.grid_world(rows=6, cols=6, rng=np.random.default_rng(8))
    system = gn.LinearSystem(sim.graph, fixed=[0])
    H1, b1, _ = system.assemble(sim.graph.poses)
    H2, b2, _ = system.assemble(sim.truth)
    for backend in linalg.available_backends():
        f = linalg.SparseCholesky(H1, backend)
        f.refactor(H2)
        np.testing.assert_allclose(f.solve(b2), linalg.solve_spd(H2, b2, backend), rtol=1e-12)


@pytest.mark.parametrize("backend", ["qdldl", "scipy"])
def test_singular_or_indefinite_matrix_raises_lagolib_error(backend):
    singular = sp.csr_matrix(np.array([[1.0, 1.0], [1.0, 1.0]]))
    indefinite = sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 1.0]]))
    for H in (singular, indefinite):
        with pytest.raises(NotPositiveDefiniteError, match="singular or indefinite|singular"):
            linalg.SparseCholesky(H, backend)


def test_noiseless_graph_is_recovered_exactly():
    sim = simulate.loop_world(
        laps=3, poses_per_lap=32, noiseless=True, rng=np.random.default_rng(9)
    )
    start = sim.graph.odometry_guess(start=sim.truth[0])
    # the odometry of a noiseless graph is the truth; start from a perturbed guess instead
    rng = np.random.default_rng(10)
    guess = start + rng.normal(size=start.shape) * [0.3, 0.3, 0.1]
    guess[0] = sim.truth[0]
    for method in ("gn", "lm"):
        res = lagolib.optimize(sim.graph, guess, method=method)
        assert res.converged, res.reason
        np.testing.assert_allclose(res.poses[:, :2], sim.truth[:, :2], atol=1e-9)
        np.testing.assert_allclose(se2.wrap_angle(res.poses[:, 2] - sim.truth[:, 2]), 0, atol=1e-9)
        assert res.chi2 < 1e-15


def test_strong_prior_and_fixing_give_the_same_optimum(noisy):
    fixed = lagolib.optimize(noisy, fixed=[0])
    prior = lagolib.optimize(
        noisy, prior=lagolib.Prior.from_sigmas(0, noisy.poses[0], sigmas=(1e-6, 1e-6, 1e-7))
    )
    np.testing.assert_allclose(prior.poses, fixed.poses, atol=1e-8)
    assert prior.chi2 == pytest.approx(fixed.chi2, rel=1e-10)
    # fixing a pose keeps it exactly; the prior keeps it within its sigma
    np.testing.assert_array_equal(fixed.poses[0], noisy.poses[0])
    # any other pose fixed gives the same optimum up to a rigid motion: same chi2
    other = lagolib.optimize(noisy, fixed=[17])
    assert other.chi2 == pytest.approx(fixed.chi2, rel=1e-10)


def test_optimize_result_fields_and_monotone_history(noisy):
    res = lagolib.optimize(noisy, method="lm", max_iterations=50)
    assert res.converged and res.iterations == len(res.step_norms) == len(res.lambdas)
    assert len(res.chi2_history) == res.iterations + 1
    assert all(b < a for a, b in zip(res.chi2_history, res.chi2_history[1:]))
    assert res.chi2 == res.chi2_history[-1] == pytest.approx(lagolib.chi2(res.graph), rel=1e-12)
    for key in ("assembly", "solve", "evaluation"):
        assert len(res.timings[key]) == res.iterations
    assert res.timings["total"] > 0
    assert "chi2=" in repr(res)


def test_pcg_linear_solver_reaches_the_same_optimum(noisy):
    chol = lagolib.optimize(noisy)
    cg = lagolib.optimize(noisy, linear_solver="pcg")
    assert cg.chi2 == pytest.approx(chol.chi2, rel=1e-9)
    assert len(cg.linear_iterations) >= cg.iterations and min(cg.linear_iterations) > 0


def test_gauss_newton_halves_a_step_that_would_increase_the_error():
    # large rotation noise: at the 3rd iteration the full Gauss-Newton step overshoots
    sim = simulate.loop_world(
        laps=2, poses_per_lap=20, sigma_theta=0.3, rng=np.random.default_rng(3)
    )
    guess = sim.graph.odometry_guess()
    two = lagolib.optimize(sim.graph, guess, max_iterations=2)
    system = gn.LinearSystem(sim.graph, fixed=[0])
    H, b, chi = system.assemble(two.poses)
    full_step = system.update(two.poses, linalg.solve_spd(H, -b))
    assert lagolib.chi2(sim.graph, full_step) > chi  # plain GN (and GTSAM's) gets worse here
    res = lagolib.optimize(sim.graph, guess)
    assert res.step_fractions[:3] == [1.0, 1.0, 0.5]
    assert res.chi2_history[3] < res.chi2_history[2]
    assert res.converged and res.chi2 == min(res.chi2_history)
    # a step budget that stops mid-way still returns the best iterate, evaluated honestly
    short = lagolib.optimize(sim.graph, guess, max_iterations=3)
    assert (
        short.chi2
        == min(short.chi2_history)
        == pytest.approx(lagolib.chi2(sim.graph, short.poses), rel=1e-12)
    )
    assert short.reason == "reached max_iterations=3" and not short.converged
    # without halving Gauss-Newton stops at the overshoot and keeps the iterate before it
    plain = lagolib.optimize(sim.graph, guess, max_backtracks=0)
    assert plain.iterations == 2 and not plain.converged
    assert "increases the error" in plain.reason and "method='lm'" in plain.reason
    np.testing.assert_array_equal(plain.poses, two.poses)


def test_verbose_prints_one_line_per_iteration(noisy, capsys):
    res = lagolib.optimize(noisy, verbose=True)
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == res.iterations + 1
    assert lines[1].startswith("iter   1  chi2 ")


def test_callback_sees_every_accepted_iterate(noisy):
    seen = []
    res = lagolib.optimize(noisy, callback=lambda k, x: seen.append((k, x)))
    assert [k for k, _ in seen] == list(range(1, res.iterations + 1))
    assert np.array_equal(seen[-1][1], res.poses)
    # restarting one iteration at a time gives the same iterates (GN keeps no state between them)
    x = noisy.poses
    for _k, xk in seen[:3]:
        x = lagolib.optimize(noisy, x, max_iterations=1).poses
        np.testing.assert_allclose(x, xk, atol=1e-12)
    chis = [lagolib.chi2(noisy, xk) for _, xk in seen]
    np.testing.assert_allclose(chis, res.chi2_history[1:], rtol=1e-12)
    with pytest.raises(lagolib.OptionTypeError, match="callback"):
        lagolib.optimize(noisy, callback="print")


def test_gauge_errors_name_the_component_and_the_fix(noisy):
    with pytest.raises(GaugeError, match=r"no gauge.*fixed=\[0\].*Prior\(0\)"):
        lagolib.optimize(noisy, fixed=[])
    # two components: a second loop with its own ids, only the first anchored
    n = noisy.n
    two = lagolib.PoseGraph(
        np.vstack([noisy.poses, noisy.poses]),
        np.vstack([noisy.edges, noisy.edges + n]),
        np.vstack([noisy.measurements] * 2),
        np.concatenate([noisy.information] * 2),
    )
    with pytest.raises(GaugeError, match=rf"2 connected components.*\[{n}, {n + 1}, ") as info:
        lagolib.optimize(two)
    assert info.value.vertices[0] == n and len(info.value.vertices) == n
    res = lagolib.optimize(two, fixed=[0, n])
    assert res.chi2 == pytest.approx(2 * lagolib.optimize(noisy).chi2, rel=1e-9)
    with pytest.raises(GaugeError):
        gn.check_gauge(two, prior=lagolib.Prior(3))


def test_bad_input_is_rejected_clearly(noisy):
    bad = noisy.poses.copy()
    bad[5, 1] = np.nan
    with pytest.raises(GraphError, match=r"initial guess of vertex id 5 \(index 5\) is not finite"):
        lagolib.optimize(noisy, bad)
    with pytest.raises(GraphError, match="shape"):
        lagolib.optimize(noisy, bad[:-1])
    with pytest.raises(GraphError, match="vertex id 999 is not in the graph"):
        lagolib.optimize(noisy, fixed=[999])
    with pytest.raises(ValueError, match="method"):
        lagolib.optimize(noisy, method="newton")
    with pytest.raises(lagolib.OptionError, match="error must be one of"):
        lagolib.chi2(noisy, error="exp")
    with pytest.raises(GraphError, match="positive definite"):
        lagolib.Prior(0, information=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(GraphError, match="sigmas"):
        lagolib.Prior.from_sigmas(0, sigmas=(1.0, 0.0, 1.0))
    with pytest.raises(TypeError, match="Prior"):
        lagolib.optimize(noisy, prior=[(0, 0, 0)])
