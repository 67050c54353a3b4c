"""Simulated worlds: reproducible, geometrically what they claim, and noise of the stated size."""

import numpy as np
import pytest

import lagolib
from lagolib import se2, simulate

WORLDS = [
    (simulate.loop_world, dict(laps=3, poses_per_lap=24)),
    (simulate.loop_world, dict(laps=2, poses_per_lap=30, shape="circle")),
    (simulate.manhattan_world, dict(n_poses=150)),
    (simulate.grid_world, dict()),
]


@pytest.mark.parametrize("world, kw", WORLDS)
def test_same_seed_same_world_other_seed_other_noise(world, kw):
    a, b, c = world(rng=1, **kw), world(rng=1, **kw), world(rng=2, **kw)
    np.testing.assert_array_equal(a.graph.measurements, b.graph.measurements)
    np.testing.assert_array_equal(a.graph.edges, b.graph.edges)
    np.testing.assert_array_equal(a.truth, b.truth)
    assert not np.array_equal(a.graph.measurements[:10], c.graph.measurements[:10])
    gen = np.random.default_rng(1)
    d = world(rng=gen, **kw)  # a Generator is accepted and advanced
    assert gen.bit_generator.state != np.random.default_rng(1).bit_generator.state
    np.testing.assert_array_equal(d.graph.measurements, a.graph.measurements)


@pytest.mark.parametrize("world, kw", WORLDS)
def test_noiseless_worlds_are_consistent(world, kw):
    sim = world(rng=4, noiseless=True, **kw)
    assert sim.graph.is_connected
    assert lagolib.chi2(sim.graph, sim.truth) < 1e-18
    # the odometry guess of noiseless odometry is the truth
    np.testing.assert_allclose(sim.graph.poses[:, :2], sim.truth[:, :2], atol=1e-9)
    np.testing.assert_allclose(
        se2.wrap_angle(sim.graph.poses[:, 2] - sim.truth[:, 2]), 0, atol=1e-12
    )
    assert np.all((sim.truth[:, 2] > -np.pi) & (sim.truth[:, 2] <= np.pi))


@pytest.mark.parametrize("noise", ["fixed", "proportional"])
def test_chi2_at_truth_has_the_chi_square_distribution_mean(noise):
    # with correct information matrices, chi2(truth) ~ chi-square with 3m degrees of freedom
    sim = simulate.manhattan_world(n_poses=800, rng=8, noise=noise, sigma_xy=0.1, sigma_theta=0.05)
    m = sim.graph.m
    value = lagolib.chi2(sim.graph, sim.truth)
    assert abs(value - 3 * m) < 4 * np.sqrt(6 * m), (value, 3 * m)


def test_proportional_noise_scales_with_the_motion():
    sim = simulate.loop_world(
        laps=2,
        poses_per_lap=16,
        step=2.0,
        noise="proportional",
        sigma_xy=0.1,
        sigma_theta=0.2,
        floor=0.1,
        noiseless=True,
    )
    info = sim.graph.information
    dist = np.hypot(*sim.graph.measurements[:, :2].T)
    np.testing.assert_allclose(info[:, 0, 0], 1 / (0.1 * np.maximum(dist, 0.1)) ** 2)
    np.testing.assert_allclose(
        info[:, 2, 2], 1 / (0.2 * np.maximum(np.abs(sim.graph.measurements[:, 2]), 0.1)) ** 2
    )
    assert np.all(info[:, 0, 0] == info[:, 1, 1])


def test_loop_world_geometry():
    sim = simulate.loop_world(laps=4, poses_per_lap=40, closure_probability=1.0, noiseless=True)
    g = sim.graph
    assert (g.n, int(g.odometric.sum()), int(g.loop_closure.sum())) == (160, 159, 120)
    loops = g.edges[g.loop_closure]
    assert np.all(loops[:, 1] - loops[:, 0] == 40)
    np.testing.assert_allclose(
        g.measurements[g.loop_closure], 0, atol=1e-9
    )  # same place, same heading
    # the heading accumulated along the odometry grows by 2 pi per lap (the wraparound)
    assert np.sum(g.measurements[g.odometric, 2]) == pytest.approx(2 * np.pi * 4 - np.pi / 2)
    with pytest.raises(ValueError, match="divisible by 4"):
        simulate.loop_world(poses_per_lap=10)
    with pytest.raises(ValueError, match="shape must be"):
        simulate.loop_world(shape="triangle")


def test_manhattan_world_geometry():
    sim = simulate.manhattan_world(
        n_poses=300, extent=5, closure_radius=0.5, min_separation=10, rng=9
    )
    t = sim.truth
    np.testing.assert_array_equal(t[:, :2], np.round(t[:, :2]))  # on the lattice
    assert t[:, :2].min() >= 0 and t[:, :2].max() <= 4
    np.testing.assert_allclose(np.mod(t[:, 2], np.pi / 2), 0, atol=1e-12)
    loops = sim.graph.edges[sim.graph.loop_closure]
    assert len(loops) > 50
    assert np.all(loops[:, 1] - loops[:, 0] >= 10)
    np.testing.assert_allclose(np.hypot(*(t[loops[:, 0], :2] - t[loops[:, 1], :2]).T), 0)


def test_grid_world_geometry():
    sim = simulate.grid_world(rows=10, cols=10, closure_probability=1.0, rng=0)
    g, t = sim.graph, sim.truth
    assert g.n == 100
    assert sorted(map(tuple, t[:, :2].tolist())) == [
        (float(x), float(y)) for x in range(10) for y in range(10)
    ]
    loops = g.edges[g.loop_closure]
    assert (
        len(loops) == 9 * 10 - 9
    )  # vertical neighbours, less the 9 row-end steps that are odometry
    np.testing.assert_allclose(np.hypot(*(t[loops[:, 0], :2] - t[loops[:, 1], :2]).T), 1.0)


def test_measure_rejects_bad_noise():
    t = np.zeros((2, 3))
    with pytest.raises(ValueError, match="noise must be"):
        simulate.measure(t, [[0, 1]], noise="huge")
    with pytest.raises(ValueError, match="must be positive"):
        simulate.measure(t, [[0, 1]], sigma_xy=0.0)
