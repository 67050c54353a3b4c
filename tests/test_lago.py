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


def _rot(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s], [s, c]])


@pytest.fixture(scope="module")
def aniso():
    """Random headings, loop closures, and anisotropic, rotated, correlated information.

    Per edge: position information ``Q diag(a, b) Qᵀ`` with ``a/b`` up to 400 and a random ``Q``,
    plus position–orientation coupling — the case where the g2o frame and frame ``i`` differ.
    """
    rng = np.random.default_rng(2011)
    n = 40
    steps = np.column_stack(
        [rng.uniform(0.5, 1.5, n - 1), rng.uniform(-0.3, 0.3, n - 1), rng.uniform(-1.2, 1.2, n - 1)]
    )
    truth = np.zeros((n, 3))
    for k in range(1, n):
        truth[k] = se2.compose(truth[k - 1], steps[k - 1])
    odo = [(k, k + 1) for k in range(n - 1)]
    closures = [
        (i, j)
        for i in range(n)
        for j in range(i + 2, n)
        if np.hypot(*(truth[i, :2] - truth[j, :2])) < 2.5
    ]
    edges = np.array(odo + closures)
    m = len(edges)
    info = np.zeros((m, 3, 3))
    for k in range(m):
        Q = _rot(rng.uniform(-np.pi, np.pi))
        pos = Q @ np.diag([rng.uniform(50, 400), rng.uniform(1, 20)]) @ Q.T
        info[k, :2, :2] = pos
        info[k, 2, 2] = w = rng.uniform(100, 900)
        u = rng.uniform(-0.6, 0.6, size=2)  # coupling with vᵀ pos⁻¹ v = w |u|² < w: still PD
        info[k, :2, 2] = info[k, 2, :2] = np.sqrt(w) * np.linalg.cholesky(pos) @ u
    z = se2.between(truth[edges[:, 0]], truth[edges[:, 1]])
    z += rng.normal(size=z.shape) * [0.03, 0.03, 0.02]
    assert np.all(np.linalg.eigvalsh(info) > 0)
    return PoseGraph(np.zeros((n, 3)), edges, z, info)


def _frame_i_blocks(g):
    """Independent reference of LAGO's weights: frame-i covariance blocks, one edge at a time.

    The g2o error rotates the frame-i position residual by ``R(θ_z)ᵀ``; so the frame-i covariance
    is ``G P Gᵀ`` with ``P = Ω⁻¹`` and ``G = blockdiag(R(θ_z), 1)`` (Carlone et al. eq. 4).
    """
    Om, om = [], []
    for Omega, z in zip(g.information, g.measurements, strict=True):
        G = np.eye(3)
        G[:2, :2] = _rot(z[2])
        P = G @ np.linalg.inv(Omega) @ G.T
        Om.append(np.linalg.inv(P[:2, :2]))
        om.append(1.0 / P[2, 2])
    return np.array(Om), np.array(om)


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
    reg = L.regularize(noisy, "odometric")
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
def test_information_is_rotated_into_frame_i(aniso):
    Om, om = L.split_information(aniso)
    Om_ref, om_ref = _frame_i_blocks(aniso)
    np.testing.assert_allclose(Om, Om_ref, rtol=1e-10)
    np.testing.assert_allclose(om, om_ref, rtol=1e-10)
    # the quadratic form is the same: e_g2o^T Ω e_g2o == r_i^T (G Ω G^T) r_i for any residual
    rng = np.random.default_rng(5)
    r = rng.normal(size=(aniso.m, 3))
    G = np.zeros((aniso.m, 3, 3))
    G[:, :2, :2] = se2.rotation(aniso.measurements[:, 2])
    G[:, 2, 2] = 1
    e = np.einsum("kba,kb->ka", G, r)  # e = Gᵀ r
    lhs = np.einsum("ka,kab,kb->k", e, aniso.information, e)
    rhs = np.einsum("ka,kab,kb->k", r, L.frame_i_information(aniso), r)
    np.testing.assert_allclose(lhs, rhs, rtol=1e-12)
    # and the g2o-frame blocks differ (else this graph could not catch a frame error)
    wrong = np.linalg.inv(np.linalg.inv(aniso.information)[:, :2, :2])
    assert np.abs(wrong - Om).max() > 10.0


def test_split_information_needs_the_graph():
    with pytest.raises(TypeError, match="PoseGraph"):
        L.split_information(np.eye(3)[None])


def _dense_lago(g, delta_bar):
    """Carlone et al. eq. 9–15 with dense matrices and the independent frame-i weights."""
    Om, om = _frame_i_blocks(g)
    m, n = g.m, g.n - 1
    A = T.reduced_incidence_matrix(g).toarray()
    I_theta = A @ np.diag(om) @ A.T  # eq. (13)
    theta = np.linalg.solve(I_theta, A @ np.diag(om) @ delta_bar)
    th = np.concatenate([[0.0], theta])
    R = np.zeros((2 * m, 2 * m))
    J = np.zeros((2 * m, n))
    for k, (i, _) in enumerate(g.edges):
        R[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = _rot(th[i])
        if i > 0:  # d(R(θ_i) Δ^l)/dθ_i = R(θ_i + π/2) Δ^l, eq. (11)
            J[2 * k : 2 * k + 2, i - 1] = _rot(th[i] + np.pi / 2) @ g.measurements[k, :2]
    Dl = g.measurements[:, :2].ravel()
    P_Dl = np.zeros((2 * m, 2 * m))
    for k in range(m):
        P_Dl[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = np.linalg.inv(Om[k])
    Hz = np.block([[R, J], [np.zeros((n, 2 * m)), np.eye(n)]])  # eq. (10)
    Pz = (
        Hz
        @ np.block([[P_Dl, np.zeros((2 * m, n))], [np.zeros((n, 2 * m)), np.linalg.inv(I_theta)]])
        @ Hz.T
    )
    z = np.concatenate([R @ Dl, theta])  # eq. (9)
    B = np.block(
        [[np.kron(A, np.eye(2)), np.zeros((2 * n, n))], [np.zeros((n, 2 * m)), np.eye(n)]]
    )  # eq. (12)
    I_p = B @ np.linalg.solve(Pz, B.T)
    p = np.linalg.solve(I_p, B @ np.linalg.solve(Pz, z))  # eq. (15)
    return theta, z, np.linalg.inv(Pz), J, p, I_p


def test_phases_1_2_3_equal_a_dense_implementation_of_eq_9_to_15(aniso):
    g = aniso
    reg = L.regularize(g, "odometric")
    theta, z, info_z, J, p, I_p = _dense_lago(g, reg.delta_bar)
    p1 = L.phase1_orientations(g, reg.delta_bar)
    np.testing.assert_allclose(p1.estimate, theta, atol=1e-12)
    p2 = L.phase2_relative_positions(g, p1)
    np.testing.assert_allclose(p2.z, z, atol=1e-12)
    np.testing.assert_allclose(p2.J.toarray(), J, atol=1e-12)
    scale = np.abs(info_z).max()
    np.testing.assert_allclose(p2.information.toarray(), info_z, atol=1e-9 * scale)
    p3 = L.phase3_poses(g, p2)
    np.testing.assert_allclose(p3.estimate, p, atol=1e-9)
    np.testing.assert_allclose(p3.information.toarray(), I_p, atol=1e-9 * np.abs(I_p).max())
    res = L.lago(g, "odometric")
    n = g.n - 1
    np.testing.assert_allclose(res.poses[1:, :2].ravel(), p[: 2 * n], atol=1e-9)


def test_theorem_1_phase_3_is_one_gauss_newton_step_on_cost_6(aniso):
    """p* = p̂ + argmin of the linearized cost (18) around p̂ = [ρ̂(θ̂); θ̂] (eq. 14, 17).

    Cost (6) is built here from the g2o-convention information alone (:func:`_frame_i_blocks`),
    with anisotropic, rotated, correlated information: a frame error in lagolib shows up here.
    """
    g = aniso
    Om, om = _frame_i_blocks(g)
    res = L.lago(g, "odometric")
    reg = res.regularization
    n = g.n - 1
    theta_hat = res.theta_hat
    A = T.reduced_incidence_matrix(g).toarray()
    A2 = np.kron(A, np.eye(2))
    Ri = se2.rotation(theta_hat[g.edges[:, 0]])
    W = sp.block_diag(list(Ri @ Om @ np.swapaxes(Ri, 1, 2))).toarray()  # frozen at θ̂
    Dl = g.measurements[:, :2]
    # eq. (14) densely: the linearization point's positions
    rho_hat = np.linalg.solve(A2 @ W @ A2.T, A2 @ W @ np.einsum("kab,kb->ka", Ri, Dl).ravel())
    np.testing.assert_allclose(
        L.positions_given_orientations(g, theta_hat).estimate, rho_hat, atol=1e-10
    )

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


def test_toro_files_hold_the_frame_i_information(mirror):
    """TORO stores information in frame i: the reader's g2o Ω rotated back gives the file's numbers."""
    path = mirror / "carlone-nano-pgo" / "CSAIL_P_toro.graph"
    g = lagolib.read(path)
    rows = [ln.split() for ln in path.read_text().splitlines() if ln.startswith("EDGE2")]
    # TORO order: I11 I12 I22 I33 I13 I23
    f = np.array([[float(x) for x in r[6:12]] for r in rows])
    file_info = np.zeros((len(f), 3, 3))
    file_info[:, 0, 0], file_info[:, 0, 1], file_info[:, 1, 1] = f[:, 0], f[:, 1], f[:, 2]
    file_info[:, 2, 2], file_info[:, 0, 2], file_info[:, 1, 2] = f[:, 3], f[:, 4], f[:, 5]
    file_info = np.triu(file_info) + np.swapaxes(np.triu(file_info, 1), 1, 2)
    scale = np.abs(file_info).max(axis=(1, 2))[:, None, None]
    np.testing.assert_allclose(L.frame_i_information(g) / scale, file_info / scale, atol=1e-12)


def test_full_information_uses_the_covariance_blocks(noisy):
    rng = np.random.default_rng(11)
    C = rng.normal(scale=0.3, size=(noisy.m, 3, 3))
    full = noisy.information + C @ np.swapaxes(C, 1, 2) * 50.0  # correlated x, y, θ
    g_full = PoseGraph(noisy.poses, noisy.edges, noisy.measurements, full)
    Om, om = L.split_information(g_full)
    P = np.linalg.inv(L.frame_i_information(g_full))
    np.testing.assert_allclose(np.linalg.inv(Om), P[:, :2, :2], rtol=1e-12)
    np.testing.assert_allclose(1.0 / om, P[:, 2, 2], rtol=1e-12)
    # the same blocks written back into the g2o frame: LAGO's answer does not change
    blocks = np.zeros_like(full)
    blocks[:, :2, :2] = Om
    blocks[:, 2, 2] = om
    G = np.zeros_like(full)
    G[:, :2, :2] = se2.rotation(noisy.measurements[:, 2])
    G[:, 2, 2] = 1.0
    g_blocks = PoseGraph(
        noisy.poses, noisy.edges, noisy.measurements, np.swapaxes(G, 1, 2) @ blocks @ G
    )
    np.testing.assert_allclose(L.lago(g_full).poses, L.lago(g_blocks).poses, atol=1e-12)
    diag = np.zeros_like(full)
    diag[:, [0, 1, 2], [0, 1, 2]] = [1.0, 1.0, 3.0]  # isotropic position: no rotation effect
    Od, od = L.split_information(PoseGraph(noisy.poses, noisy.edges, noisy.measurements, diag))
    np.testing.assert_allclose(Od, diag[:, :2, :2], atol=1e-12)
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
        L.lago(broken, "odometric")
    assert L.lago(broken).regularization.tree.kind == "min_uncertainty"
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


@pytest.mark.parametrize(
    "name,optimum", [("csail_toro", 40.5551289), ("fr079", 38.8448876), ("csail", 40.5551289)]
)
def test_lago_with_anisotropic_information_is_within_2_percent_of_the_optimum(
    benchmark, name, optimum
):
    """CSAIL and FR079 carry anisotropic, rotated information (TORO files, frame i)."""
    g = lagolib.read(benchmark(name))
    gn = lagolib.optimize(g, L.lago(g).poses)
    assert gn.chi2 == pytest.approx(optimum, rel=1e-3)  # independent of the start
    for tree in topology_trees():
        cost = lagolib.chi2(g, L.lago(g, tree).poses)
        assert gn.chi2 <= cost < gn.chi2 * 1.02, tree


def topology_trees():
    return T.TREES


# --------------------------------------------------------------------------- spanning trees
def test_min_uncertainty_tree_is_the_shortest_path_tree_of_orientation_variances(aniso):
    nx = pytest.importorskip("networkx")
    g = aniso
    var = np.linalg.inv(g.information)[:, 2, 2]
    G = nx.Graph()
    for (i, j), v in zip(g.edges, var, strict=True):
        if not G.has_edge(i, j) or G[i][j]["weight"] > v:
            G.add_edge(int(i), int(j), weight=float(v))
    dist = nx.single_source_dijkstra_path_length(G, 0)
    tree = T.min_uncertainty_tree(g)
    # the variance accumulated along each tree path equals the shortest-path distance
    acc = tree.potentials(var)  # sum of the tree's edge weights from the root, signless here
    acc_abs = np.zeros(g.n)
    for v in tree.order[1:]:
        acc_abs[v] = acc_abs[tree.parent[v]] + var[tree.parent_edge[v]]
    np.testing.assert_allclose(acc_abs, [dist[v] for v in range(g.n)], rtol=1e-12)
    assert acc.shape == (g.n,)
    assert tree.kind == "min_uncertainty" and tree.edges.size == g.n - 1


def test_min_uncertainty_tree_prefers_the_precise_parallel_edge():
    info = np.tile(np.eye(3), (3, 1, 1))
    info[1, 2, 2] = 50.0
    g = PoseGraph(np.zeros((2, 3)), [(0, 1), (0, 1), (1, 0)], np.zeros((3, 3)), info)
    assert T.min_uncertainty_tree(g).edges.tolist() == [1]
    apart = PoseGraph(np.zeros((3, 3)), [(0, 1)], np.zeros((1, 3)), info[:1])
    with pytest.raises(GraphError, match="not connected"):
        T.min_uncertainty_tree(apart)


@pytest.fixture(scope="module")
def noisy_manhattan():
    """Olson's hard setting, small: a Manhattan world with σ_θ = 0.1 rad on every edge."""
    return simulate.manhattan_world(
        n_poses=800, extent=10, closure_probability=0.3, sigma_xy=0.05, sigma_theta=0.1, rng=3
    )


def test_margins_are_the_distance_of_the_cycle_sums_from_the_rounding_boundary(noisy_manhattan):
    g = noisy_manhattan.graph
    reg = L.regularize(g, "odometric", margin_warning=0.0)
    C = T.cycle_basis(g, reg.tree).C
    turns = (C @ reg.delta) / (2 * np.pi)
    np.testing.assert_allclose(reg.margin, 0.5 - np.abs(turns - np.round(turns)), atol=1e-9)
    assert set(reg.unreliable(0.1)) == set(reg.chords[reg.margin < 0.1])


def test_the_odometric_tree_warns_and_fails_where_the_min_uncertainty_tree_does_not(
    noisy_manhattan,
):
    g, truth = noisy_manhattan.graph, noisy_manhattan.truth
    with pytest.warns(L.RegularizationWarning, match=r"edge \d+, \d+ -> \d+") as rec:
        odo = L.lago(g, "odometric")
    assert "'odometric' tree" in str(rec[0].message)
    best = L.lago(g)  # min_uncertainty: no warning (the suite turns warnings into errors)
    assert best.regularization.tree.kind == "min_uncertainty"
    assert best.regularization.margin.min() > 0.1
    # the right k: every circuit sums to noise, well inside ±π
    assert np.abs(best.regularization.residual_sums).max() < 0.8 * np.pi
    gn_best = lagolib.optimize(g, best.poses)
    gn_truth = lagolib.optimize(g, _relative_to(truth, 0))
    assert gn_best.chi2 == pytest.approx(gn_truth.chi2, rel=1e-9)
    assert lagolib.chi2(g, odo.poses) > 3 * lagolib.chi2(g, best.poses)


def test_margin_warning_can_be_turned_off_and_is_validated(noisy_manhattan):
    g = noisy_manhattan.graph
    L.lago(g, "odometric", margin_warning=0.0)  # silent
    for bad in (-0.1, 0.6, float("nan"), "0.1"):
        with pytest.raises((ValueError, TypeError), match="margin_warning"):
            L.lago(g, margin_warning=bad)
    with pytest.raises(ValueError, match="tree"):
        L.lago(g, "kruskal")


@pytest.mark.parametrize("seed", [1, 4])
def test_with_equal_variances_the_min_uncertainty_tree_is_the_bfs_tree(seed):
    """Every shortest-hop tree is then a minimum-uncertainty tree; ties go as in BFS."""
    for sim in (
        simulate.loop_world(laps=4, poses_per_lap=40, sigma_theta=0.3, rng=seed),
        simulate.manhattan_world(n_poses=600, extent=8, rng=seed),
    ):
        a, b = T.min_uncertainty_tree(sim.graph), T.bfs_tree(sim.graph)
        np.testing.assert_array_equal(a.edges, b.edges)
        np.testing.assert_array_equal(a.parent, b.parent)


def test_phase1_on_a_disconnected_graph_names_the_cause():
    z = np.zeros((2, 3))
    apart = PoseGraph(np.zeros((4, 3)), [(0, 1), (2, 3)], z, np.tile(np.eye(3), (2, 1, 1)))
    with pytest.raises(GraphError, match="not connected"):
        L.phase1_orientations(apart, np.zeros(2))
