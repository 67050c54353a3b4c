"""Robust back ends: IRLS inside optimize, GNC, the one-call solve, scores, certify_inliers."""

import numpy as np
import pytest

import lagolib
from lagolib import robust
from lagolib.errors import OptionError, OptionTypeError
from lagolib.gauss_newton import RobustSystem, robust_edge_mask
from lagolib.graph import PoseGraph
from lagolib.kernels import INLIER_THRESHOLD, Cauchy, kernel


def _rotated_information(m, rng):
    """Anisotropic information, rotated in the translation block and coupled to the angle."""
    out = np.empty((m, 3, 3))
    for k in range(m):
        a = rng.uniform(-np.pi, np.pi)
        R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        L = np.zeros((3, 3))
        L[:2, :2] = R @ np.diag(rng.uniform(20.0, 400.0, 2)) @ R.T
        L[2, 2] = rng.uniform(200.0, 2000.0)
        L[0, 2] = L[2, 0] = rng.uniform(-5.0, 5.0)
        out[k] = L
    return out


def _world(n=120, seed=0):
    sim = lagolib.simulate.manhattan_world(n_poses=n, rng=seed)
    return sim


def _with_random_outliers(graph, count, seed):
    """``count`` wrong loop closures between random poses (uniform 10 m box, any angle)."""
    rng = np.random.default_rng(seed)
    i, j = [], []
    while len(i) < count:
        a, b = rng.integers(0, graph.n, 2)
        if abs(int(a) - int(b)) > 1:
            i.append(a)
            j.append(b)
    z = np.c_[rng.uniform(-10, 10, (count, 2)), rng.uniform(-np.pi, np.pi, count)]
    info = np.broadcast_to(np.median(graph.information[graph.loop_closure], axis=0), (count, 3, 3))
    g = PoseGraph(
        graph.poses,
        np.r_[graph.edges, np.c_[i, j]],
        np.r_[graph.measurements, z],
        np.r_[graph.information, info],
    )
    return g, np.r_[np.zeros(graph.m, bool), np.ones(count, bool)]


def test_robust_gradient_is_twice_b_by_finite_differences():
    """RobustSystem's b is half the gradient of Σ 2 ρ(r) (IRLS), with rotated anisotropic
    information and residuals on both sides of the kernel's scale."""
    rng = np.random.default_rng(3)
    sim = _world(40, 1)
    g = sim.graph.with_information(_rotated_information(sim.graph.m, rng))
    x = sim.truth + rng.normal(0, 0.05, sim.truth.shape)
    for name in ("huber", "cauchy", "gm", "dcs"):
        system = RobustSystem(g, kernel(name, 2.0), robust_edge_mask(g, "all"), fixed=[0])
        H, b, cost = system.assemble(x)
        assert cost == pytest.approx(system.objective(x), rel=1e-13)
        r = np.sqrt(system.edge_chi2(x))
        assert (r < 2.0).any() and (r > 2.0).any()
        np.testing.assert_allclose(system.scale, kernel(name, 2.0).weight(r), rtol=1e-13)
        grad = np.empty(system.N)
        h = 1e-6
        for k in range(system.N):
            d = np.zeros(system.N)
            d[k] = h
            grad[k] = (system.objective(system.update(x, d)) - system.objective(
                system.update(x, -d))) / (2 * h)
        np.testing.assert_allclose(grad, 2 * b, rtol=2e-5, atol=1e-5 * np.abs(b).max())


#: kernels that are least squares inside their scale (Cauchy and Geman–McClure down-weight every
#: residual a little, so their optimum is near the plain one, not at it)
QUADRATIC_INSIDE = ("huber", "tls", "dcs", "gnc-tls", "pcm", "pcm+gnc-tls")


@pytest.mark.parametrize("name", ["huber", "tls", "dcs"])
def test_outlier_free_graph_gives_the_plain_optimum(name):
    sim = _world(150, 2)
    plain = lagolib.optimize(sim.graph)
    # TLS by IRLS keeps the classification of its start: from the odometry it drops closures
    start = plain.poses if name == "tls" else None
    res = lagolib.optimize(sim.graph, start, robust=name)
    r = np.sqrt(lagolib.chi2(sim.graph, plain.poses, per_edge=True))
    assert r.max() < INLIER_THRESHOLD  # every residual inside the scale: the kernel is r²/2
    np.testing.assert_allclose(res.poses, plain.poses, atol=1e-7)
    assert res.cost == pytest.approx(plain.chi2, rel=1e-10)
    assert res.chi2 == pytest.approx(plain.chi2, rel=1e-10)
    assert res.inlier.all() and np.all(res.weights == 1.0)


@pytest.mark.parametrize("method", robust.METHODS)
def test_every_method_keeps_an_outlier_free_graph(method):
    sim = _world(150, 2)
    plain = lagolib.optimize(sim.graph)
    start = plain.poses if method == "tls" else None  # see above
    res = robust.solve(sim.graph, start, method=method)
    assert res.inlier.all(), method
    if method in QUADRATIC_INSIDE:
        np.testing.assert_allclose(res.poses, plain.poses, atol=1e-7)
        assert res.chi2_inliers == pytest.approx(plain.chi2, rel=1e-9)
    else:  # a smooth kernel: near the plain optimum (ATE within 5 %), χ² a little above it
        ate = lambda p: lagolib.metrics.absolute_trajectory_error(p, sim.truth).translation_rmse  # noqa: E731
        assert ate(res.poses) == pytest.approx(ate(plain.poses), rel=0.05)
        assert plain.chi2 < res.chi2_inliers < 1.05 * plain.chi2


def test_result_weights_equal_the_closed_form():
    sim = _world(150, 4)
    g, _ = _with_random_outliers(sim.graph, 8, 0)
    k = Cauchy(3.0)
    res = lagolib.optimize(g, robust=k)
    r = np.sqrt(lagolib.chi2(g, res.poses, per_edge=True))
    closures = g.loop_closure
    np.testing.assert_allclose(res.weights[closures], k.weight(r[closures]), rtol=1e-13)
    assert np.all(res.weights[~closures] == 1.0)  # odometry is trusted by default
    np.testing.assert_array_equal(res.inlier, ~closures | (r <= INLIER_THRESHOLD))
    assert res.cost == pytest.approx(
        float(np.sum(np.where(closures, k.cost(r**2), r**2))), rel=1e-12
    )


def test_gnc_reaches_the_inlier_optimum_where_least_squares_fails():
    """30 random wrong closures: Gauss–Newton's map breaks; IRLS with Geman–McClure from the
    odometry keeps wrong closures; GNC-TLS finds exactly the outliers and the optimum of the
    right edges."""
    sim = _world(200, 5)
    g, outlier = _with_random_outliers(sim.graph, 30, 1)
    clean = lagolib.optimize(sim.graph)
    ate = lambda p: lagolib.metrics.absolute_trajectory_error(p, sim.truth).translation_rmse  # noqa: E731
    ls = lagolib.optimize(g)
    assert ate(ls.poses) > 20 * ate(clean.poses)
    res = robust.gnc(g)
    assert res.converged
    np.testing.assert_array_equal(~res.inlier, outlier)
    np.testing.assert_allclose(res.poses, clean.poses, atol=1e-8)
    assert res.chi2_inliers == pytest.approx(clean.chi2, rel=1e-10)
    assert np.all(res.weights[outlier] == 0.0)
    # the continuation: μ grows by 1.4 per step, the outliers found never decrease at the end
    mu = np.array(res.mu)
    np.testing.assert_allclose(mu[1:] / mu[:-1], 1.4)
    assert res.outliers_history[-1] == 30
    s = robust.scores(res.inlier, outlier, g.loop_closure)
    assert (s.precision, s.recall) == (1.0, 1.0)
    tls = robust.solve(g, method="tls")  # the same kernel by IRLS from the odometry
    assert robust.scores(tls.inlier, outlier, g.loop_closure).recall < 0.9  # 58 right ones lost


@pytest.mark.parametrize("sigma_theta, closure_probability, count", [
    (0.05, 0.5, 60), (0.05, 0.2, 60), (0.1, 0.2, 40)])
def test_gnc_starts_at_the_initial_residuals(sigma_theta, closure_probability, count):
    """The numbers gnc's docstring quotes: from the least-squares solution (Yang et al., GTSAM)
    GNC keeps 48–84 % of the right closures at 24–33 times the outlier-free ATE; from the
    odometry's residuals all of them, at the outlier-free optimum."""
    sim = lagolib.simulate.manhattan_world(n_poses=200, rng=5, sigma_theta=sigma_theta,
                                           closure_probability=closure_probability)
    g, outlier = _with_random_outliers(sim.graph, count, 1)
    clean = lagolib.optimize(sim.graph)
    ate = lambda p: lagolib.metrics.absolute_trajectory_error(p, sim.truth).translation_rmse  # noqa: E731
    at_initial = robust.gnc(g)
    s = robust.scores(at_initial.inlier, outlier, g.loop_closure)
    assert (s.precision, s.recall) == (1.0, 1.0)
    np.testing.assert_allclose(at_initial.poses, clean.poses, atol=1e-7)
    at_ls = robust.gnc(g, start="least_squares")
    s = robust.scores(at_ls.inlier, outlier, g.loop_closure)
    assert 0.48 <= s.recall <= 0.85
    assert 23 < ate(at_ls.poses) / ate(clean.poses) < 33


def test_gnc_gm_and_pipeline_options():
    sim = _world(200, 5)
    g, outlier = _with_random_outliers(sim.graph, 30, 1)
    res = robust.gnc(g, kernel="gm")
    assert res.mu[-1] == 1.0 and res.converged
    np.testing.assert_array_equal(~res.inlier, outlier)
    # robust_edges as indices: only the outliers may be down-weighted
    only = robust.gnc(g, robust_edges=np.flatnonzero(outlier))
    np.testing.assert_array_equal(~only.inlier, outlier)


def test_scores():
    s = robust.scores(np.array([True, True, False, True]), np.array([False, True, True, False]))
    assert s == (2 / 3, 1.0, 2, 1, 0, 1)
    judged = np.array([False, True, True, True])
    assert robust.scores(np.ones(4, bool), np.zeros(4, bool), judged).precision == 1.0
    with pytest.raises(OptionTypeError, match="inlier must be a one-dimensional boolean"):
        robust.scores([1, 0], np.zeros(2, bool))
    with pytest.raises(OptionError, match="same shape"):
        robust.scores(np.ones(3, bool), np.zeros(2, bool))


def test_certify_inliers_states_what_it_covers():
    sim = _world(120, 6)
    g, outlier = _with_random_outliers(sim.graph, 10, 2)
    res = robust.gnc(g)
    cert = robust.certify_inliers(res)
    assert cert.certified
    assert (cert.kept, cert.removed) == (g.m - 10, 10)
    assert cert.graph.m == g.m - 10
    assert "says nothing about whether the removed edges were wrong" in cert.statement
    clean = lagolib.optimize(sim.graph)
    assert cert.result.chi2 == pytest.approx(clean.chi2, rel=1e-8)
    with pytest.raises(OptionTypeError, match="RobustResult"):
        robust.certify_inliers(clean)


def test_misuse_names_the_argument():
    g = _world(30, 0).graph
    with pytest.raises(OptionError, match="unknown robust kernel"):
        lagolib.optimize(g, robust="welsch")
    with pytest.raises(OptionError, match="robust_edges names edge index"):
        lagolib.optimize(g, robust="huber", robust_edges=[g.m])
    with pytest.raises(OptionError, match=r"shape \(\d+,\)"):
        lagolib.optimize(g, robust="huber", robust_edges=np.ones(3, bool))
    with pytest.raises(OptionError, match="method"):
        robust.solve(g, method="ransac")
    with pytest.raises(OptionError, match="kernel"):
        robust.gnc(g, kernel="huber")
    with pytest.raises(OptionError, match="mu_step"):
        robust.gnc(g, mu_step=1.0)
    with pytest.raises(ValueError, match="c"):
        robust.gnc(g, c=0.0)


def test_cli_outliers_and_solve_robust(tmp_path, capsys):
    from lagolib.cli import main
    from lagolib.io import write

    sim = _world(120, 6)
    g, outlier = _with_random_outliers(sim.graph, 4, 3)
    path = tmp_path / "bad.g2o"
    write(g, path)
    assert main(["outliers", str(path)]) == 0
    out = capsys.readouterr().out
    assert "gnc-tls judged 4 of" in out
    for k in np.flatnonzero(outlier):
        assert f"{k:8d}" in out
    assert main(["outliers", str(path), "--json"]) == 0
    import json

    data = json.loads(capsys.readouterr().out)
    assert sorted(r["edge"] for r in data["outliers"]) == np.flatnonzero(outlier).tolist()
    out_path = tmp_path / "solved.g2o"
    assert main(["solve", str(path), "--robust", "gnc-tls", "-o", str(out_path), "--certify"]) == 0
    text = capsys.readouterr().out
    assert "gnc-tls from the file's poses" in text and "4 of" in text and "certified" in text
    solved = lagolib.read(out_path)
    assert solved.m == g.m  # every edge kept in OUT
    ref = robust.gnc(g)
    np.testing.assert_allclose(solved.poses, ref.poses, atol=1e-6)
    assert main(["solve", str(path), "--robust", "huber", "--method", "sgd", "-o",
                 str(tmp_path / "s.g2o")]) == 2


def test_gnc_without_its_zero_weight_edges_gives_the_same_answer(monkeypatch):
    """Rebuilding the system without the edges whose weight reached 0 changes the cost, not
    the answer: the same classification and poses as keeping every edge in the pattern."""
    sim = _world(200, 5)
    g, outlier = _with_random_outliers(sim.graph, 60, 4)
    pruned = robust.gnc(g)
    monkeypatch.setattr(robust, "REBUILD_FRACTION", np.inf)
    kept = robust.gnc(g)
    np.testing.assert_array_equal(pruned.inlier, kept.inlier)
    np.testing.assert_array_equal(~pruned.inlier, outlier)
    np.testing.assert_allclose(pruned.poses, kept.poses, atol=1e-7)  # both converged to 1e-10
    assert pruned.iterations == kept.iterations  # the same continuation (μ steps)
