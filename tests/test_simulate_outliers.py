"""Wrong loop closures of the Vertigo policies (lagolib.simulate.add_outliers)."""

import numpy as np
import pytest

import lagolib
from lagolib import PoseGraph, simulate
from lagolib.errors import LagolibError, OptionError, OptionTypeError
from lagolib.simulate import OUTLIER_POLICIES, Outliers, add_outliers

CHI2_3_99 = 11.345  # 99 % quantile of chi-square with 3 degrees of freedom


@pytest.fixture(scope="module")
def world():
    """400 poses on a 12 x 12 lattice, 754 edges (355 loop closures), information 400 I / 1e4."""
    return simulate.manhattan_world(n_poses=400, extent=12, rng=0)


def _ranks(graph, edges):
    """The id ranks (odometric order) of the ends of ``edges``; shape (k, 2)."""
    return graph.order[edges]


@pytest.mark.parametrize("policy", OUTLIER_POLICIES)
def test_each_policy_appends_count_wrong_edges_after_the_original_ones(world, policy):
    g = world.graph
    out = add_outliers(g, 37, policy=policy, group_size=5, rng=2)
    assert isinstance(out, Outliers) and out.policy == policy
    assert out.graph.m == g.m + 37 and out.count == 37
    assert out.outlier.shape == (g.m + 37,) and out.outlier.dtype == bool
    assert not out.outlier[: g.m].any() and out.outlier[g.m :].all()
    np.testing.assert_array_equal(out.graph.edges[: g.m], g.edges)
    np.testing.assert_array_equal(out.graph.measurements[: g.m], g.measurements)
    np.testing.assert_array_equal(out.graph.information[: g.m], g.information)
    np.testing.assert_array_equal(out.graph.poses, g.poses)
    np.testing.assert_array_equal(out.graph.ids, g.ids)
    assert np.all(out.groups[: g.m] == -1) and np.all(out.groups[g.m :] >= 0)
    # never odometry-like, never a self-loop, always from the earlier pose to the later one
    r = _ranks(out.graph, out.graph.edges[out.outlier])
    assert np.all(r[:, 1] - r[:, 0] >= 2), r[r[:, 1] - r[:, 0] < 2]
    assert not out.graph.odometric[out.outlier].any()
    with pytest.raises(ValueError):
        out.outlier[0] = True  # the result's arrays are read-only


def test_same_seed_same_outliers_other_seed_other(world):
    for policy in OUTLIER_POLICIES:
        a = add_outliers(world.graph, 30, policy=policy, rng=5)
        b = add_outliers(world.graph, 30, policy=policy, rng=5)
        c = add_outliers(world.graph, 30, policy=policy, rng=6)
        np.testing.assert_array_equal(a.graph.edges, b.graph.edges)
        np.testing.assert_array_equal(a.graph.measurements, b.graph.measurements)
        np.testing.assert_array_equal(a.groups, b.groups)
        assert not np.array_equal(a.graph.edges, c.graph.edges)
        assert not np.array_equal(a.graph.measurements, c.graph.measurements)
    gen = np.random.default_rng(5)
    d = add_outliers(world.graph, 30, rng=gen)  # a Generator is accepted and advanced
    assert gen.bit_generator.state != np.random.default_rng(5).bit_generator.state
    np.testing.assert_array_equal(d.graph.edges, add_outliers(world.graph, 30, rng=5).graph.edges)


def test_random_ends_span_the_whole_trajectory(world):
    out = add_outliers(world.graph, 2000, policy="random", rng=1)
    r = _ranks(out.graph, out.graph.edges[out.outlier])
    gap = r[:, 1] - r[:, 0]
    assert gap.min() >= 2 and gap.max() > 350  # 400 poses: far-apart ends occur
    assert r.min() == 0 and r.max() == world.graph.n - 1
    np.testing.assert_array_equal(out.groups[out.outlier], np.arange(2000))
    # uniform over unordered pairs: the mean gap is about n / 3
    assert abs(gap.mean() - 400 / 3) < 8, gap.mean()


@pytest.mark.parametrize("radius", [2, 5, 20])
def test_local_outliers_stay_within_the_radius(world, radius):
    for policy in ("local", "local-grouped"):
        out = add_outliers(
            world.graph, 600, policy=policy, group_size=4, local_radius=radius, rng=3
        )
        r = _ranks(out.graph, out.graph.edges[out.outlier])
        gap = r[:, 1] - r[:, 0]
        assert gap.min() >= 2 and gap.max() <= radius
        # every allowed gap occurs (uniform in [2, radius] per group)
        assert set(gap.tolist()) == set(range(2, radius + 1))


def test_grouped_outliers_advance_together_with_one_measurement(world):
    for policy in ("random-grouped", "local-grouped"):
        out = add_outliers(world.graph, 23, policy=policy, group_size=10, rng=4)
        groups = out.groups[out.outlier]
        np.testing.assert_array_equal(groups, [0] * 10 + [1] * 10 + [2] * 3)  # last one short
        r = _ranks(out.graph, out.graph.edges[out.outlier])
        z = out.graph.measurements[out.outlier]
        for k in range(3):
            member = groups == k
            np.testing.assert_array_equal(np.diff(r[member], axis=0), 1)  # i + t -> j + t
            np.testing.assert_array_equal(z[member], np.tile(z[member][0], (member.sum(), 1)))
        assert len({tuple(z[groups == k][0]) for k in range(3)}) == 3  # each group its own lie


def test_a_group_tells_one_lie_where_the_trajectory_repeats_itself():
    # on a straight line every member (i + t, j + t) of a group joins poses the same distance
    # apart, so all members have the same error at the truth: they agree with each other and
    # nothing but the odometry's evidence can single one out
    truth = np.column_stack([np.arange(60.0), np.zeros(60), np.zeros(60)])
    sim = simulate.measure(truth, np.column_stack([np.arange(59), np.arange(1, 60)]), rng=0)
    for policy in ("random-grouped", "local-grouped"):
        out = add_outliers(sim.graph, 40, policy=policy, group_size=8, rng=7)
        error = lagolib.residuals(out.graph, truth)[out.outlier]
        groups = out.groups[out.outlier]
        for k in range(5):
            member = error[groups == k]
            np.testing.assert_allclose(member, np.tile(member[0], (8, 1)), atol=1e-12)
            assert np.hypot(*member[0, :2]) > 1.0  # ... and it is a lie: poses >= 2 m apart
        assert np.ptp(error[:, 0]) > 1.0  # groups differ from each other


def test_wrong_closures_are_far_from_the_truth(world):
    for policy in OUTLIER_POLICIES:
        out = add_outliers(world.graph, 100, policy=policy, rng=11)
        chi2 = lagolib.chi2(out.graph, world.truth, per_edge=True)
        inlier, wrong = chi2[~out.outlier], chi2[out.outlier]
        assert np.median(inlier) < 3.0  # chi-square with 3 dof: median 2.37
        assert np.median(wrong) > 100 * CHI2_3_99, (policy, np.median(wrong))
        assert np.mean(wrong > CHI2_3_99) > 0.95, (policy, np.mean(wrong > CHI2_3_99))


def test_measurements_follow_vertigos_distribution(world):
    out = add_outliers(world.graph, 20000, policy="random", rng=12)
    z = out.graph.measurements[out.outlier]
    np.testing.assert_allclose(z.std(axis=0), [0.3, 0.3, np.radians(10)], rtol=0.03)
    np.testing.assert_allclose(z.mean(axis=0), 0, atol=0.01)
    assert simulate.OUTLIER_SIGMA == (0.3, 0.3, np.radians(10.0))


def test_default_information_is_the_median_loop_closure():
    truth = simulate.manhattan_world(n_poses=120, extent=5, rng=1).truth
    base = simulate.manhattan_world(n_poses=120, extent=5, rng=1).graph
    m = base.m
    sigma = np.linspace(0.01, 0.2, m)  # every edge its own information
    g = simulate.measure(truth, base.edges, sigma_xy=sigma, sigma_theta=sigma, rng=2).graph
    lc = g.information[g.loop_closure]
    traces = np.trace(lc, axis1=1, axis2=2)
    median = lc[np.argsort(traces)[(len(lc) - 1) // 2]]
    out = add_outliers(g, 9, rng=0)
    np.testing.assert_array_equal(out.graph.information[out.outlier], np.tile(median, (9, 1, 1)))
    assert np.trace(median) == np.sort(traces)[(len(lc) - 1) // 2]
    # loop closures less certain than odometry (grid_world's closure_noise): theirs is taken
    grid = simulate.grid_world(closure_noise=3.0, rng=0).graph
    out = add_outliers(grid, 4, rng=0)
    np.testing.assert_allclose(out.graph.information[out.outlier][0], np.diag([400, 400, 1e4]) / 9)
    # no loop closures at all: the odometry's
    chain = simulate.loop_world(laps=1, poses_per_lap=12, rng=0).graph
    assert not chain.loop_closure.any()
    out = add_outliers(chain, 3, rng=0)
    np.testing.assert_allclose(out.graph.information[out.outlier][0], np.diag([400, 400, 1e4]))
    # or the one given
    info = [[50.0, 1.0, 0.0], [1.0, 40.0, 0.0], [0.0, 0.0, 30.0]]
    out = add_outliers(chain, 3, rng=0, information=info)
    np.testing.assert_array_equal(out.graph.information[out.outlier], np.tile(info, (3, 1, 1)))


def test_consecutive_means_consecutive_ids_not_rows(world):
    # the same graph with its rows shuffled and ids 7, 10, 13, ...: the ends are chosen in id
    # order, so no wrong edge joins two poses that follow each other in time
    g = world.graph
    perm = np.random.default_rng(0).permutation(g.n)  # row r holds old pose perm[r]
    row = np.argsort(perm)
    shuffled = PoseGraph(
        g.poses[perm], row[g.edges], g.measurements, g.information, ids=7 + 3 * perm
    )
    assert shuffled.odometric.sum() == g.odometric.sum()
    for policy in OUTLIER_POLICIES:
        out = add_outliers(shuffled, 200, policy=policy, group_size=5, local_radius=3, rng=1)
        ids = out.graph.ids[out.graph.edges[out.outlier]]
        step = (ids[:, 1] - ids[:, 0]) // 3
        assert step.min() >= 2 and not out.graph.odometric[out.outlier].any()
        if policy.startswith("local"):
            assert step.max() <= 3
        if policy.endswith("grouped"):
            first = out.groups[out.outlier] == 0
            np.testing.assert_array_equal(np.diff(ids[first], axis=0), 3)


def test_zero_outliers_return_the_graph_unchanged(world):
    out = add_outliers(world.graph, 0, policy="local-grouped")
    assert out.graph is world.graph and out.count == 0
    assert out.outlier.shape == (world.graph.m,) and not out.outlier.any()
    np.testing.assert_array_equal(out.groups, -1)


def test_smallest_graphs_that_fit():
    three = simulate.measure(
        np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]), [[0, 1], [1, 2]], rng=0
    ).graph
    out = add_outliers(three, 5, policy="local", rng=0)
    np.testing.assert_array_equal(out.graph.edges[out.outlier], np.tile([0, 2], (5, 1)))
    twelve = simulate.loop_world(laps=1, poses_per_lap=12, rng=0).graph
    out = add_outliers(twelve, 20, policy="random-grouped", group_size=10, rng=0)
    np.testing.assert_array_equal(
        out.graph.edges[out.outlier][:10], [[k, k + 2] for k in range(10)]
    )


BAD = [
    (dict(count=-1), OptionError, "count"),
    (dict(count=2.5), OptionTypeError, "count"),
    (dict(count=3, group_size=0), OptionError, "group_size"),
    (dict(count=3, local_radius=1, policy="local"), OptionError, "local_radius"),
    (dict(count=3, policy="grouped"), OptionError, "policy"),
    (dict(count=3, rng=None), OptionTypeError, "rng"),
    (dict(count=3, rng=-2), OptionError, "rng"),
    (dict(count=3, information=np.eye(2)), OptionError, "information"),
    (dict(count=3, information=-np.eye(3)), OptionError, "positive definite"),
    (dict(count=3, information=np.full((3, 3), np.nan)), OptionError, "non-finite"),
    (dict(count=3, policy="random-grouped", group_size=11), OptionError, "group_size"),
]


@pytest.mark.parametrize("kw, exc, words", BAD, ids=[str(k) for k, _, _ in BAD])
def test_bad_arguments_are_lagolib_errors_naming_the_argument(kw, exc, words):
    g = simulate.loop_world(laps=1, poses_per_lap=12, rng=0).graph
    with pytest.raises(exc, match=r"^add_outliers: ") as info:
        add_outliers(g, **kw)
    assert isinstance(info.value, LagolibError)
    assert isinstance(info.value, TypeError if exc is OptionTypeError else ValueError)
    assert words in str(info.value), str(info.value)


def test_graphs_too_small_or_without_edges_are_refused():
    two = PoseGraph(np.zeros((2, 3)), [[0, 1]], [[1.0, 0, 0]], np.eye(3)[None])
    with pytest.raises(OptionError, match=r"at least 3 poses .* has 2$"):
        add_outliers(two, 1)
    bare = PoseGraph(np.zeros((5, 3)), np.zeros((0, 2), int), np.zeros((0, 3)), np.zeros((0, 3, 3)))
    with pytest.raises(OptionError, match=r"no edges .* pass information="):
        add_outliers(bare, 1)
    out = add_outliers(bare, 2, information=np.eye(3), rng=0)
    assert out.graph.m == 2 and out.outlier.all()
    with pytest.raises(OptionTypeError, match=r"^add_outliers: graph must be a"):
        add_outliers(simulate.loop_world(laps=1, poses_per_lap=12), 1)  # the Simulation
