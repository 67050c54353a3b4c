"""Lodi Rizzini's closed form: the sparse matrices, the position equations, the orthogonality
condition solved and checked against Gauss–Newton on the same error, Fig. 2's experiment."""

import numpy as np
import pytest
import sympy

from lagolib import ConvergenceError, GraphError, PoseGraph, se2, simulate, symbolic
from lagolib import closed_form as cf
from lagolib import lago as L
from lagolib.gauss_newton import optimize


def _graph(edges, rng=0, n=None):
    """A noisy graph on random true poses with the given edges (isotropic information)."""
    rng = np.random.default_rng(rng)
    n = n or int(np.max(edges)) + 1
    truth = np.column_stack([np.cumsum(rng.normal(size=(n, 2)), axis=0), rng.uniform(-3, 3, n)])
    return simulate.measure(truth, edges, rng=rng, sigma_xy=0.1, sigma_theta=0.05).graph


EDGES = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (0, 3), (2, 5), (1, 2), (0, 5), (3, 5)]


@pytest.fixture(scope="module")
def grid():
    return simulate.grid_world(rows=6, cols=6, rng=11).graph


# ----------------------------------------------------------------------------- the matrices
def test_edges_follow_eq_20_and_parallel_spanning_edges_are_loops():
    g = _graph(EDGES)
    net = cf.network(g)
    assert net.n == 5 and net.e == 10 and net.n_L == 5
    pairs = list(zip(net.i.tolist(), net.j.tolist()))
    assert pairs[:5] == [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5)]
    # loops by i + (n + 1)(j - i): the second <1, 2> (length 1), then <3, 5>, <0, 3>, <2, 5>, <0, 5>
    assert pairs[5:] == [(1, 2), (3, 5), (0, 3), (2, 5), (0, 5)]
    assert net.edge[1] == 1 and net.edge[5] == 7  # the first stored <1, 2> is the spanning one
    assert net.U.toarray().tolist() == [
        [0, 1, 0, 0, 0],
        [0, 0, 0, 1, 1],
        [1, 1, 1, 0, 0],
        [0, 0, 1, 1, 1],
        [1, 1, 1, 1, 1],
    ]


def test_sparse_matrices_equal_the_symbolic_formulas():
    """closed_form assembles Q, M, L, … from blocks; symbolic computes eq. (21)-(45) literally."""
    g = _graph(EDGES, rng=3)
    net = cf.network(g)
    z = g.measurements
    deltas = [[z[k, 0], z[k, 1], sympy.cos(z[k, 2]), sympy.sin(z[k, 2])] for k in range(g.m)]
    sym = symbolic.sincos_network([tuple(e) for e in g.edges.tolist()], deltas)

    def num(M):
        return np.array(sympy.N(M), dtype=float)

    for name in ("N_out", "N_in", "N", "U", "U_bar", "D", "Q", "D_perp", "M"):
        np.testing.assert_allclose(
            getattr(net, name).toarray(), num(getattr(sym, name)), atol=1e-14
        )
    for name in ("C_in", "C_out", "L_in", "L_out", "L"):
        np.testing.assert_allclose(
            getattr(net, name).toarray(), num(getattr(sym, name)), atol=1e-14
        )
    np.testing.assert_allclose(net.P(), num(sym.P), atol=1e-12)
    A, b = net.A_b()
    np.testing.assert_allclose(A, num(sym.A), atol=1e-12)
    np.testing.assert_allclose(b, num(sym.b).ravel(), atol=1e-12)


def test_P_is_the_orthogonal_projector_the_laplacian_applies(grid):
    net = cf.network(grid)
    P = net.P()
    np.testing.assert_allclose(P, P.T, atol=1e-12)
    np.testing.assert_allclose(P @ P, P, atol=1e-12)
    assert round(np.trace(P)) == 2 * net.n  # rank 2n: the displacements a configuration can have
    rng = np.random.default_rng(2)
    t = net.t_of(rng.uniform(-np.pi, np.pi, net.n + 1))
    d = net.displacements(t)
    np.testing.assert_allclose(d.ravel(), P @ (net.Q @ net.t1(t)), atol=1e-12)
    # the loop equations (19): every loop displacement is the sum along the spanning path
    np.testing.assert_allclose(d[net.n :], net.U @ d[: net.n], atol=1e-12)
    A, b = net.A_b()
    np.testing.assert_allclose(A @ t + b, net.v(t), atol=1e-12)


def test_position_equations_are_lagos_eq_14_with_equal_weights(grid):
    """Given the angles, the position equations are Carlone et al.'s eq. (14) with Ω_Δ = I."""
    rng = np.random.default_rng(4)
    theta = rng.uniform(-np.pi, np.pi, grid.n)
    ours = cf.positions_from_orientations(grid, theta)
    lago_eq14 = L.positions_given_orientations(
        grid, theta - theta[0], Omega_Delta=np.broadcast_to(np.eye(2), (grid.m, 2, 2))
    ).estimate.reshape(-1, 2)
    # LAGO expresses them in the anchor's frame (θ_0 = 0); rotate into the world
    np.testing.assert_allclose(ours[1:], lago_eq14 @ se2.rotation(theta[0]).T, atol=1e-10)
    assert np.all(ours[0] == 0)


# --------------------------------------------------------------------------- the sin/cos χ²
def test_sincos_jacobians_and_gradient_equal_finite_differences(grid):
    rng = np.random.default_rng(8)
    poses = grid.poses + rng.normal(scale=0.2, size=grid.poses.shape)
    g = cf.sincos_gradient(grid, poses)
    fd = np.zeros_like(poses)
    h = 1e-6
    for r in range(grid.n):
        for c in range(3):
            p, q = poses.copy(), poses.copy()
            p[r, c] += h
            q[r, c] -= h
            fd[r, c] = (cf.sincos_chi2(grid, p) - cf.sincos_chi2(grid, q)) / (2 * h)
    np.testing.assert_allclose(g, fd, atol=1e-6)
    # eq. (12)-(13) are the Jacobians of eq. (3) in the 4 parameters (no constraint imposed)
    p4 = rng.normal(size=(5, 2, 4))
    Ji, Jj = cf.sincos_jacobians(p4[:, 0], p4[:, 1])
    for k in range(4):
        dp = np.zeros(4)
        dp[k] = h

        def f(a, b):
            ca, sa, cb, sb = a[2], a[3], b[2], b[3]
            dx, dy = b[0] - a[0], b[1] - a[1]
            return np.array(
                [dx * ca + dy * sa, -dx * sa + dy * ca, cb * ca + sb * sa, sb * ca - cb * sa]
            )

        for m in range(5):
            a, b = p4[m]
            np.testing.assert_allclose(
                Ji[m][:, k], (f(a + dp, b) - f(a - dp, b)) / (2 * h), atol=1e-8
            )
            np.testing.assert_allclose(
                Jj[m][:, k], (f(a, b + dp) - f(a, b - dp)) / (2 * h), atol=1e-8
            )


# ------------------------------------------------------------------ the orthogonality condition
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_closed_form_is_stationary_and_equals_gauss_newton_on_the_same_error(seed):
    sim = simulate.grid_world(rng=seed)
    g = sim.graph
    res = cf.closed_form(g, initial="lago")
    assert res.iterations <= 6
    assert res.residuals[-1] <= 1e-10
    assert np.abs(res.gradient).max() < 1e-8  # a stationary point of eq. (6), Ω = I
    np.testing.assert_allclose(res.t[0::2] ** 2 + res.t[1::2] ** 2, 1, atol=1e-12)
    gn = cf.optimize_sincos(g, L.lago(g).poses)
    assert gn.converged
    np.testing.assert_allclose(res.poses[:, :2], gn.poses[:, :2], atol=1e-6)
    assert np.abs(se2.wrap_angle(res.poses[:, 2] - gn.poses[:, 2])).max() < 1e-6
    assert res.chi2 == pytest.approx(gn.chi2, rel=1e-10)
    # eq. (44) with the dense A and b: R t = A t + b (the printed "- b" has the wrong sign)
    A, b = res.network.A_b()
    Rt = res.t * np.column_stack([res.rho, -res.rho]).ravel()
    np.testing.assert_allclose(Rt, A @ res.t + b, atol=1e-9)
    assert np.abs(Rt - (A @ res.t - b)).max() > 0.1


def test_closed_form_from_odometry_and_from_given_poses():
    sim = simulate.loop_world(laps=2, poses_per_lap=16, closure_probability=0.7, rng=5)
    a = cf.closed_form(sim.graph, initial="odometry")
    b = cf.closed_form(sim.graph, initial=sim.truth)
    np.testing.assert_allclose(a.poses, b.poses, atol=1e-9)
    assert np.abs(a.gradient).max() < 1e-8


def test_noiseless_networks_are_recovered_exactly():
    sim = simulate.grid_world(rows=5, cols=7, rng=1, noiseless=True)
    rng = np.random.default_rng(0)
    start = sim.truth + np.column_stack(
        [np.zeros((sim.truth.shape[0], 2)), rng.normal(scale=0.1, size=35)]
    )
    res = cf.closed_form(sim.graph, initial=start)
    expected = se2.between(np.broadcast_to(sim.truth[0], sim.truth.shape), sim.truth)
    np.testing.assert_allclose(res.poses[:, :2], expected[:, :2], atol=1e-10)
    assert np.abs(se2.wrap_angle(res.poses[:, 2] - expected[:, 2])).max() < 1e-10
    assert res.chi2 < 1e-20


def test_no_convergence_is_reported_not_returned(grid):
    with pytest.raises(ConvergenceError, match="did not converge in 1 iterations") as info:
        cf.closed_form(grid, initial="odometry", max_iterations=1)
    assert info.value.iterations == 1 and len(info.value.residuals) == 2
    assert info.value.residuals[-1] < info.value.residuals[0]


def test_the_papers_assumptions_are_checked():
    g = _graph(EDGES)
    edges = g.edges.copy()
    edges[6] = edges[6][::-1]  # <2, 5> stored as 5 -> 2
    backward = PoseGraph(g.poses, edges, g.measurements, g.information)
    with pytest.raises(
        GraphError, match=r"edge 6 \(vertex ids 5 -> 2\) is stored from the larger id"
    ) as info:
        cf.network(backward)
    assert info.value.edge == 6
    keep = [k for k in range(g.m) if tuple(g.edges[k]) != (3, 4)]
    gap = PoseGraph(g.poses, g.edges[keep], g.measurements[keep], g.information[keep])
    with pytest.raises(GraphError, match="ids 3 and 4.*needs every spanning constraint"):
        cf.network(gap)
    with pytest.raises(GraphError, match="at least two poses"):
        cf.network(PoseGraph(np.zeros((1, 3)), np.zeros((0, 2), int), [], []))
    with pytest.raises(TypeError):
        cf.network("graph.g2o")
    with pytest.raises(ValueError, match="initial must be"):
        cf.closed_form(g, initial="truth")


def test_vertex_ids_need_not_start_at_zero():
    g = _graph(EDGES, rng=9)
    ids = np.array([10, 11, 12, 13, 14, 15])
    shifted = PoseGraph(g.poses, g.edges, g.measurements, g.information, ids=ids)
    a, b = cf.closed_form(g), cf.closed_form(shifted)
    np.testing.assert_allclose(a.poses, b.poses, atol=1e-12)


# ---------------------------------------------------------------------------- Fig. 2 (§IV-B)
def _fig2(closure_noise, seed):
    """Gauss–Newton (Toro's stand-in) on a 100-pose grid, then positions from the position
    equations with its orientations; max and RMS distance between the two position sets."""
    sim = simulate.grid_world(rng=seed, closure_noise=closure_noise)
    g = sim.graph
    opt = optimize(g, L.lago(g).poses, tol=1e-14)
    assert opt.converged
    pos = cf.positions_from_orientations(g, opt.poses[:, 2], origin=opt.poses[0, :2])
    d = np.linalg.norm(pos - opt.poses[:, :2], axis=1)
    return g.n, d.max(), np.sqrt(np.mean(d**2))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fig_2_position_equations_overlap_the_optimizer(seed):
    n, worst, rms = _fig2(1.0, seed)
    print(f"Fig. 2, seed {seed}: {n} poses, max {worst:.2e} m, RMS {rms:.2e} m")
    assert n == 100
    # every edge of the grid has the same isotropic position information, so given the angles
    # the weighted and the unweighted position equations coincide
    assert worst < 1e-8 and rms < 1e-8


def test_fig_2_with_unequal_weights_the_solutions_only_almost_overlap():
    n, worst, rms = _fig2(4.0, 0)
    print(f"Fig. 2, loop closures 4x noisier: max {worst:.3f} m, RMS {rms:.3f} m")
    assert 0.05 < worst < 0.6 and 0.02 < rms < 0.3


# ----------------------------------------------------------------------------- real benchmarks
@pytest.mark.parametrize("name", ["m3500", "intel"])
def test_closed_form_on_benchmarks_equals_gauss_newton_on_the_same_error(benchmark, name):
    from lagolib import io

    g = io.read(benchmark(name))
    res = cf.closed_form(g)
    assert np.abs(res.gradient).max() < 1e-8
    gn = cf.optimize_sincos(g, L.lago(g).poses)
    np.testing.assert_allclose(res.poses[:, :2], gn.poses[:, :2], atol=1e-6)
    assert res.chi2 == pytest.approx(gn.chi2, rel=1e-10)


# ------------------------------------------------------- never worse than the start (issue 11)
def _two_poses():
    """One constraint p_0 -> p_1: on the circle c² + s² = 1 the stationary points are
    t = ±(cos θ̂, sin θ̂); the minus one is the maximum of χ² along the circle (χ² = 4)."""
    z = np.array([[1.0, 0.5, 0.3]])
    graph = PoseGraph(np.zeros((2, 3)), [[0, 1]], z, [np.eye(3)])
    start = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.3 + np.pi - 0.2]])  # 0.2 rad from the max
    return graph, start


def test_a_stationary_point_worse_than_the_start_falls_back_to_gauss_newton():
    graph, start = _two_poses()
    res = cf.closed_form(graph, initial=start)
    # the start (angle 0.2 rad off the maximum, positions optimal) has χ² = 2 + 2 cos 0.2
    assert res.start_chi2 == pytest.approx(2 + 2 * np.cos(0.2), rel=1e-12)
    assert res.newton_chi2 == pytest.approx(4.0, rel=1e-12)  # Newton climbed to the maximum
    assert res.fallback and "worse than its start" in res.reason and "Gauss-Newton" in res.reason
    assert res.chi2 < 1e-20 < res.start_chi2  # the minimum, found by Gauss-Newton
    np.testing.assert_allclose(res.poses[1], [1.0, 0.5, 0.3], atol=1e-12)
    np.testing.assert_allclose(res.t, [np.cos(0.3), np.sin(0.3)], atol=1e-12)
    with pytest.raises(ConvergenceError, match=r"chi2 4, worse than its start's 3\.96"):
        cf.closed_form(graph, initial=start, if_worse="raise")


def test_a_saddle_point_in_a_grid_is_never_returned_silently():
    sim = simulate.grid_world(rows=3, cols=3, rng=0)
    start = sim.truth.copy()
    start[0, 2] += np.pi - 0.3  # the first pose turned almost around
    res = cf.closed_form(sim.graph, initial=start)
    assert res.newton_chi2 > res.start_chi2 > res.chi2  # Newton: worse; returned: better
    assert res.fallback and res.chi2 == pytest.approx(cf.closed_form(sim.graph).chi2, rel=1e-9)
    good = cf.closed_form(sim.graph)
    assert not good.fallback and good.chi2 <= good.start_chi2
    assert good.reason.startswith("stationary point")
