"""LAGO (Carlone et al. 2011): regularization, the three phases, Theorem 1, real benchmarks."""

import numpy as np
import pytest
import scipy.sparse as sp

import lagolib
from lagolib import GraphError, PoseGraph, se2, simulate
from lagolib import lago as L
from lagolib import topology as T


def _relative_to(truth, row):
    """Truth expressed in the frame of pose ``row`` (LAGO puts its anchor at the origin)."""
    return se2.between(np.broadcast_to(truth[row], truth.shape), truth)


def _assert_poses_equal(a, b, atol):
    np.testing.assert_allclose(a[:, :2], b[:, :2], atol=atol)
    assert np.abs(se2.wrap_angle(a[:, 2] - b[:, 2])).max() < atol


@pytest.fixture(scope="module")
def noisy():
    """A small graph with three laps and noise (diagonal information)."""
    sim = simulate.loop_world(
        laps=3, poses_per_lap=12, closure_probability=0.8, sigma_xy=0.05, sigma_theta=0.02, rng=7
    )
    return sim.graph


# --------------------------------------------------------------------------- noiseless recovery
@pytest.mark.parametrize(
    "maker,tree,anchor",
    [
        ("square", "odometric", None),
        ("square", "bfs", None),
        ("circle", "odometric", 17),
        ("grid", "bfs", 5),
        ("manhattan", "odometric", None),
    ],
)
def test_noiseless_graphs_are_recovered_exactly(maker, tree, anchor):
    sim = {
        "square": lambda: simulate.loop_world(laps=5, poses_per_lap=24, noiseless=True),
        "circle": lambda: simulate.loop_world(
            laps=4, poses_per_lap=30, shape="circle", noiseless=True
        ),
        "grid": lambda: simulate.grid_world(rows=8, cols=9, noiseless=True, rng=1),
        "manhattan": lambda: simulate.manhattan_world(n_poses=300, noiseless=True, rng=2),
    }[maker]()
    res = L.lago(sim.graph, tree, anchor)
    row = 0 if anchor is None else anchor
    _assert_poses_equal(res.poses, _relative_to(sim.truth, row), 1e-9)
    if maker in ("square", "circle") and tree == "odometric":
        # each loop closure spans one lap: the odometric path turned 2π, the closure measures ~0
        reg = res.regularization
        assert reg.n_regularized == reg.tree.d > 0
        np.testing.assert_array_equal(np.abs(reg.k[reg.chords]), 1)
    np.testing.assert_allclose(res.regularization.residual_sums, 0.0, atol=1e-9)


def test_without_regularization_the_orientations_are_wrong():
    sim = simulate.loop_world(laps=3, poses_per_lap=20, noiseless=True)
    reg = L.regularize(sim.graph)
    good = L.phase1_orientations(sim.graph, reg.delta_bar).estimate
    bad = L.phase1_orientations(sim.graph, reg.delta).estimate
    assert np.abs(se2.wrap_angle(good - sim.truth[1:, 2])).max() < 1e-12
    assert np.abs(se2.wrap_angle(bad - sim.truth[1:, 2])).max() > 1.0  # radians: meaningless


def test_regularization_only_touches_chords_by_whole_turns(noisy):
    reg = L.regularize(noisy)
    np.testing.assert_array_equal(reg.k[reg.tree.in_tree], 0)
    turns = (reg.delta_bar - reg.delta) / (2 * np.pi)
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-12)
    assert np.all(np.abs(reg.delta) <= np.pi)
    # after regularization every circuit sums to noise, well inside (-pi, pi)
    assert np.abs(reg.residual_sums).max() < 0.3
    C = T.cycle_basis(noisy).C
    np.testing.assert_allclose(C @ reg.delta_bar, reg.residual_sums, atol=1e-12)


def test_unwrapped_angles_in_the_file_do_not_change_the_result(noisy):
    z = noisy.measurements.copy()
    z[::3, 2] += 2 * np.pi * np.arange(len(z[::3]))  # as some TORO files store them
    unwrapped = PoseGraph(noisy.poses, noisy.edges, z, noisy.information)
    a, b = L.lago(noisy), L.lago(unwrapped)
    np.testing.assert_allclose(a.poses, b.poses, atol=1e-12)


# --------------------------------------------------------------------------- phases
def test_phase2_information_is_the_inverse_of_eq_10(noisy):
    """Build P_z = H diag(P_Δ, P_θ̂) H^T densely (eq. 10, 11) and invert it: must equal phase 2."""
    g = noisy
    Om, om = L.split_information(g.information)
    p1 = L.phase1_orientations(g, L.regularize(g).delta_bar)
    p2 = L.phase2_relative_positions(g, p1)
    m, n = g.m, g.n - 1
    theta = np.concatenate([[0.0], p1.estimate])
    R = sp.block_diag(list(se2.rotation(theta[g.edges[:, 0]]))).toarray()
    Dl = g.measurements[:, :2].ravel()
    # J by central differences of g1(θ) = R(θ) Δ^l
    J = np.zeros((2 * m, n))
    h = 1e-6
    for c in range(n):
        tp, tm = theta.copy(), theta.copy()
        tp[c + 1] += h
        tm[c + 1] -= h
        Rp = sp.block_diag(list(se2.rotation(tp[g.edges[:, 0]]))).toarray()
        Rm = sp.block_diag(list(se2.rotation(tm[g.edges[:, 0]]))).toarray()
        J[:, c] = (Rp @ Dl - Rm @ Dl) / (2 * h)
    np.testing.assert_allclose(p2.J.toarray(), J, atol=1e-8)
    H = np.block([[R, J], [np.zeros((n, 2 * m)), np.eye(n)]])
    P_Delta = sp.block_diag(list(np.linalg.inv(Om))).toarray()
    P_theta = np.linalg.inv(p1.information.toarray())
    Pz = H @ sp.block_diag([P_Delta, P_theta]).toarray() @ H.T
    info = p2.information.toarray()
    np.testing.assert_allclose(info @ Pz, np.eye(2 * m + n), atol=1e-7)
    np.testing.assert_allclose(p2.z, np.concatenate([R @ Dl, p1.estimate]), atol=1e-14)


def test_theorem_1_phase_3_is_one_gauss_newton_step_on_cost_6(noisy):
    """p* = p̂ + argmin of the linearized cost (18) around p̂ = [ρ̂(θ̂); θ̂] (eq. 14, 17)."""
    g = noisy
    Om, om = L.split_information(g.information)
    reg = L.regularize(g)
    res = L.lago(g)
    n = g.n - 1
    theta_hat = res.theta_hat
    rho_hat = L.positions_given_orientations(g, theta_hat).estimate
    A = T.reduced_incidence_matrix(g).toarray()
    A2 = np.kron(A, np.eye(2))
    Ri = se2.rotation(theta_hat[g.edges[:, 0]])
    W = sp.block_diag(list(Ri @ Om @ np.swapaxes(Ri, 1, 2))).toarray()  # frozen at θ̂
    Dl = g.measurements[:, :2]

    def residual(p):  # the residuals of cost (6), weights frozen
        rho, th = p[: 2 * n], np.concatenate([[0.0], p[2 * n :]])
        Rth = se2.rotation(th[g.edges[:, 0]])
        pos = A2.T @ rho - np.einsum("kab,kb->ka", Rth, Dl).ravel()
        return np.concatenate([pos, A.T @ th[1:] - reg.delta_bar])

    p_hat = np.concatenate([rho_hat, theta_hat[1:]])
    r0 = residual(p_hat)
    Jac = np.zeros((r0.size, 3 * n))
    h = 1e-6
    for c in range(3 * n):
        e = np.zeros(3 * n)
        e[c] = h
        Jac[:, c] = (residual(p_hat + e) - residual(p_hat - e)) / (2 * h)
    Omega = sp.block_diag([W, np.diag(om)]).toarray()
    step = np.linalg.solve(Jac.T @ Omega @ Jac, -Jac.T @ Omega @ r0)
    p_star = np.concatenate([res.poses[1:, :2].ravel(), res.theta[1:]])
    np.testing.assert_allclose(p_hat + step, p_star, atol=1e-8)
    assert np.abs(step).max() > 1e-4  # the correction is not trivially zero


def test_full_information_uses_the_covariance_blocks(noisy):
    rng = np.random.default_rng(11)
    C = rng.normal(scale=0.3, size=(noisy.m, 3, 3))
    full = noisy.information + C @ np.swapaxes(C, 1, 2) * 50.0  # correlated x, y, θ
    g_full = PoseGraph(noisy.poses, noisy.edges, noisy.measurements, full)
    Om, om = L.split_information(full)
    P = np.linalg.inv(full)
    np.testing.assert_allclose(np.linalg.inv(Om), P[:, :2, :2], rtol=1e-12)
    np.testing.assert_allclose(1.0 / om, P[:, 2, 2], rtol=1e-12)
    blocks = np.zeros_like(full)
    blocks[:, :2, :2] = Om
    blocks[:, 2, 2] = om
    g_blocks = PoseGraph(noisy.poses, noisy.edges, noisy.measurements, blocks)
    np.testing.assert_allclose(L.lago(g_full).poses, L.lago(g_blocks).poses, atol=1e-12)
    diag = np.zeros_like(full)
    diag[:, [0, 1, 2], [0, 1, 2]] = [1.0, 2.0, 3.0]
    Od, od = L.split_information(diag)
    np.testing.assert_allclose(Od, diag[:, :2, :2])
    np.testing.assert_allclose(od, 3.0)


def test_covariance_blocks_match_the_dense_inverse(noisy):
    res = L.lago(noisy)
    P = np.linalg.inv(res.information.toarray())
    n = noisy.n - 1
    covs = res.covariance([0, 3, 20])
    np.testing.assert_array_equal(covs[0], 0.0)  # the anchor
    for out, v in zip(covs[1:], (3, 20), strict=True):
        c = v - 1
        idx = [2 * c, 2 * c + 1, 2 * n + c]
        np.testing.assert_allclose(out, P[np.ix_(idx, idx)], rtol=1e-9, atol=1e-15)
    assert res.covariance().shape == (noisy.n, 3, 3)


def test_bad_input_is_reported():
    z = np.zeros((2, 3))
    apart = PoseGraph(np.zeros((4, 3)), [(0, 1), (2, 3)], z, np.tile(np.eye(3), (2, 1, 1)))
    with pytest.raises(GraphError, match="not connected"):
        L.lago(apart)
    broken = PoseGraph(
        np.zeros((3, 3)), [(0, 2), (2, 1)], z, np.tile(np.eye(3), (2, 1, 1)), ids=[0, 1, 2]
    )
    with pytest.raises(GraphError, match="tree='bfs'"):
        L.lago(broken)
    assert L.lago(broken, "bfs").poses.shape == (3, 3)
    with pytest.raises(GraphError, match="anchor: vertex id 7"):
        L.lago(broken, "bfs", anchor=7)
    with pytest.raises(TypeError, match="PoseGraph"):
        L.lago(np.zeros((3, 3)))


# --------------------------------------------------------------------------- benchmarks
def test_table_1_on_intel(benchmark):
    g = lagolib.read(benchmark("intel"))
    reg = L.regularize(g, "odometric")
    assert g.n == 1228
    assert int(g.odometric.sum()) == 1227
    assert int(g.loop_closure.sum()) == 256  # the paper's version of the data has 278
    assert reg.tree.d == 256
    assert reg.n_regularized == 198
    assert L.regularize(g, "bfs").n_regularized == 52  # a shallow tree has short circuits


@pytest.mark.parametrize("name,optimum", [("m3500", 137.9129509), ("city10000", 511.9851636)])
def test_lago_is_near_the_optimum_and_gauss_newton_finishes_in_3_steps(benchmark, name, optimum):
    g = lagolib.read(benchmark(name))
    res = L.lago(g)
    cost = lagolib.chi2(g, res.poses)
    assert optimum < cost < optimum * 1.002  # within 0.2 %
    gn = lagolib.optimize(g, res.poses, tol=1e-5)  # GTSAM's default relative tolerance
    assert gn.converged and gn.iterations <= 3
    assert gn.chi2 == pytest.approx(optimum, rel=1e-8)
    three = lagolib.optimize(g, res.poses, max_iterations=3)
    assert three.chi2 == pytest.approx(optimum, rel=1e-9)


def test_small_graphs_single_vertex_parallel_and_backward_edges():
    eye = np.tile(np.eye(3), (2, 1, 1))
    single = PoseGraph(np.zeros((1, 3)), np.zeros((0, 2), int), np.zeros((0, 3)), eye[:0])
    res = L.lago(single)
    np.testing.assert_array_equal(res.poses, 0.0)
    assert res.covariance().shape == (1, 3, 3)
    # two equally precise readings of the same edge: their average
    twice = PoseGraph(np.zeros((2, 3)), [(0, 1), (0, 1)], [[1, 0, 0.1], [1.1, 0, 0.1]], eye)
    np.testing.assert_allclose(L.lago(twice).poses[1], [1.05, 0.0, 0.1], atol=1e-12)
    # an odometric edge stored backward (1 -> 0) is inverted
    back = PoseGraph(np.zeros((2, 3)), [(1, 0)], [[1, 0, 0.1]], eye[:1])
    np.testing.assert_allclose(L.lago(back).poses[1], se2.inverse([1.0, 0.0, 0.1]), atol=1e-12)
