"""lagolib.uncertainty: marginal and relative covariances, gating, ellipses."""

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest

import lagolib
from lagolib import gauss_newton as gn
from lagolib import simulate
from lagolib.uncertainty import (
    covariance_ellipse,
    information_matrix,
    loop_closure_test,
    marginal_covariances,
    relative_covariances,
)


@pytest.fixture(scope="module")
def solved():
    sim = simulate.loop_world(laps=2, poses_per_lap=16, rng=np.random.default_rng(30))
    res = lagolib.optimize(sim.graph)
    return res.graph


def dense_inverse_blocks(H, free_rows):
    cov = np.linalg.inv(H.toarray())  # dense: tests on small graphs only
    return np.array([cov[3 * r : 3 * r + 3, 3 * r : 3 * r + 3] for r in free_rows])


@pytest.mark.parametrize("backend", ["qdldl", "scipy"])
def test_marginals_equal_the_dense_inverse(solved, backend):
    H, free = information_matrix(solved)
    ref = dense_inverse_blocks(H, range(free.size))
    cov = marginal_covariances(solved, backend=backend, batch=7)
    assert np.all(cov[0] == 0)  # vertex 0 is fixed by default
    np.testing.assert_allclose(cov[free], ref, rtol=1e-9, atol=1e-14)
    some = marginal_covariances(solved, [5, 2, 5], backend=backend)
    np.testing.assert_allclose(some, cov[[5, 2, 5]], rtol=1e-12)


def test_uncertainty_grows_along_odometry_and_shrinks_at_loop_closure():
    sim = simulate.loop_world(laps=1, poses_per_lap=40, rng=np.random.default_rng(31))
    chain_only = lagolib.PoseGraph(
        sim.graph.poses,
        sim.graph.edges[sim.graph.odometric],
        sim.graph.measurements[sim.graph.odometric],
        sim.graph.information[sim.graph.odometric],
    )
    # close the loop: the last pose sees the first
    closed = lagolib.PoseGraph(
        sim.graph.poses,
        np.vstack([chain_only.edges, [[0, 39]]]),
        np.vstack([chain_only.measurements, lagolib.se2.between(sim.truth[0], sim.truth[39])]),
        np.concatenate([chain_only.information, chain_only.information[:1]]),
    )
    open_cov, closed_cov = marginal_covariances(chain_only), marginal_covariances(closed)
    # heading variance adds up along the chain (position variance need not: on the way back the
    # lever arm of the early heading errors shrinks)
    assert np.all(np.diff(open_cov[:, 2, 2]) > 0)
    open_trace = np.trace(open_cov[:, :2, :2], axis1=1, axis2=2)
    closed_trace = np.trace(closed_cov[:, :2, :2], axis1=1, axis2=2)
    assert closed_trace[39] < 0.1 * open_trace[39]
    assert np.all(closed_trace <= open_trace + 1e-15)
    assert closed_trace.argmax() in range(15, 25)  # most uncertain: opposite the anchor


def test_relative_covariance_is_fixing_the_reference(solved):
    rel = relative_covariances(solved, 0)
    np.testing.assert_allclose(rel, marginal_covariances(solved), rtol=1e-12)
    # fix x_7: block j,j of the inverse of H without the rows and columns of x_7
    H, b = gn.build_linear_system_loop(solved)
    H7, _ = gn.reduce_system(solved, H, b, [7])
    ref = dense_inverse_blocks(H7, [9 - 1])  # pose 9 is block 8 once 7 is gone
    np.testing.assert_allclose(relative_covariances(solved, 7, [9])[0], ref[0], rtol=1e-9)
    # close poses are more certain relative to each other than far ones
    near, far = relative_covariances(solved, 7, [8, 15])
    assert np.trace(near) < np.trace(far)


def test_marginals_equal_gtsam_marginals():
    gtsam = pytest.importorskip("gtsam")
    sim = simulate.manhattan_world(n_poses=60, rng=np.random.default_rng(32))
    g = sim.graph
    prior = lagolib.Prior.from_sigmas(0, sim.graph.poses[0], sigmas=(0.1, 0.1, 0.01))
    res = lagolib.optimize(g, prior=prior, error="log")
    # linearize away from the optimum: GTSAM's Pose2 log-map Jacobian switches to a first-order
    # approximation when a residual angle is below 1e-5, which moves its H by 1e-7 relative
    poses = res.poses + np.random.default_rng(35).normal(size=res.poses.shape) * 0.05
    assert np.abs(lagolib.residuals(g, poses, error="log")[:, 2]).min() > 1e-4
    fg = gtsam.NonlinearFactorGraph()
    for k, (i, j) in enumerate(g.edges):
        noise = gtsam.noiseModel.Gaussian.Information(g.information[k])
        fg.add(gtsam.BetweenFactorPose2(int(i), int(j), gtsam.Pose2(*g.measurements[k]), noise))
    prior_noise = gtsam.noiseModel.Gaussian.Information(np.array(prior.information))
    fg.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(*prior.mean), prior_noise))
    values = gtsam.Values()
    for k in range(g.n):
        values.insert(k, gtsam.Pose2(*poses[k]))
    marginals = gtsam.Marginals(fg, values)
    ours = marginal_covariances(g, poses=poses, prior=prior, error="log", frame="local")
    for k in range(g.n):
        ref = marginals.marginalCovariance(k)
        np.testing.assert_allclose(ours[k], ref, rtol=1e-8, atol=1e-8 * np.abs(ref).max())


def test_loop_closure_gate_accepts_true_and_rejects_wrong_candidates():
    sim = simulate.loop_world(laps=2, poses_per_lap=24, rng=np.random.default_rng(33))
    g = sim.graph
    keep = g.odometric | (np.arange(g.m) % 2 == 0)
    g = lagolib.PoseGraph(g.poses, g.edges[keep], g.measurements[keep], g.information[keep])
    est = lagolib.optimize(g).poses
    info = np.diag([400.0, 400.0, 1e4])
    i, j = 3, 27  # the same place on the two laps
    z_true = lagolib.se2.between(sim.truth[i], sim.truth[j])
    good = loop_closure_test(g, i, j, z_true, info, poses=est)
    bad = loop_closure_test(g, i, j, z_true + [2.0, 0.0, 0.3], info, poses=est)
    assert good.accept and good.d2 < good.threshold
    assert not bad.accept and bad.d2 > 10 * bad.threshold
    assert good.threshold == pytest.approx(11.3449, abs=1e-4)  # chi2(3) 99 % quantile
    with pytest.raises(lagolib.GraphError, match="candidate loop closure 3 -> 27: .*positive"):
        loop_closure_test(g, i, j, z_true, np.diag([1.0, 1.0, 0.0]), poses=est)
    with pytest.raises(lagolib.GraphError, match="not in the graph"):
        loop_closure_test(g, i, 999, z_true, info, poses=est)


def test_covariance_ellipse_and_plot():
    w, h, a = covariance_ellipse(np.array([[2.0, 1.0], [1.0, 2.0]]), n_sigma=1)
    assert (float(w), float(h), float(a)) == pytest.approx((2 * np.sqrt(3), 2.0, 45.0))
    sim = simulate.loop_world(laps=1, poses_per_lap=20, rng=np.random.default_rng(34))
    cov = marginal_covariances(sim.graph)
    ax = lagolib.plot_covariance_ellipses(sim.graph.poses, cov, every=2)
    assert len(ax.collections) == 1 and len(ax.collections[0].get_offsets()) == 10
    with pytest.raises(ValueError, match="covariances"):
        lagolib.plot_covariance_ellipses(sim.graph.poses, cov[:5])
