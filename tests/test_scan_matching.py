"""Point-to-line ICP, its information and degeneracy, correlative search (lagolib.scan_matching)."""

import math

import numpy as np
import pytest

from lagolib import frontend, laser_world, se2
from lagolib.errors import OptionError
from lagolib.scan_matching import (
    INFORMATION_SCALE,
    ScanModel,
    correlative_search,
    free_space_conflicts,
    icp_step,
    match,
    point_to_line_residuals,
)


def _room(nx=41, ny=31, w=4.0, h=3.0):
    xs, ys = np.linspace(-w / 2, w / 2, nx), np.linspace(-h / 2, h / 2, ny)
    return np.array(
        [[x, y] for x in xs for y in (-h / 2, h / 2)]
        + [[x, y] for y in ys for x in (-w / 2, w / 2)]
    )


def _seen_from(points_world, pose):
    """World points in the frame of ``pose``: ``R^T (q - t)``."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return (points_world - pose[:2]) @ np.array([[c, -s], [s, c]])


@pytest.fixture(scope="module")
def noiseless():
    return laser_world.simulate_log(range_sigma=0.0, rng=2)


def test_icp_recovers_simulated_transforms_exactly(noiseless):
    """Noise-free ray-cast scans of the office: the true relative pose to 1e-6."""
    log = noiseless
    errors, checked = [], 0
    for k in range(1, 200, 7):
        truth = se2.between(log.reference[k - 1], log.reference[k])
        guess = truth + np.array([0.05, -0.04, 0.03])  # a few cm and 1.7° off
        # straight walls: normals from neighbourhoods that are lines to rounding (corners excluded)
        model = ScanModel(log.points(k - 1), max_planarity=1e-6)
        m = match(model, log.points(k), guess, tolerance=1e-12)
        if m.degeneracy > 10:  # the featureless corridor: nothing to recover along it
            continue
        checked += 1
        assert m.converged
        errors.append(np.abs(se2.between(truth, m.pose)).max())
    assert checked >= 20
    assert max(errors) < 1e-6


def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(0)
    model = ScanModel(_room())
    pts = rng.uniform(-1.5, 1.5, (20, 2))
    pairs = rng.integers(0, len(model), 20)
    pairs = pairs[model.usable[pairs]]
    pts = pts[: len(pairs)]
    x = np.array([0.2, -0.1, 0.4])
    r, J = point_to_line_residuals(model, pts, x, pairs)
    h = 1e-7
    for k in range(3):
        dx = np.zeros(3)
        dx[k] = h
        rp, _ = point_to_line_residuals(model, pts, x + dx, pairs)
        rm, _ = point_to_line_residuals(model, pts, x - dx, pairs)
        np.testing.assert_allclose(J[:, k], (rp - rm) / (2 * h), atol=1e-7)


def test_one_step_reduces_the_distances():
    room = _room()
    truth = np.array([0.1, 0.05, 0.05])
    cur = _seen_from(room, truth)
    model = ScanModel(room)
    x0 = np.zeros(3)
    x1, H, sigma, used, r = icp_step(model, cur, x0)
    assert np.abs(x1 - truth).max() < np.abs(x0 - truth).max() / 3
    assert H.shape == (3, 3) and np.all(np.linalg.eigvalsh(H) > 0)
    assert len(used) > 0.8 * len(cur)


def test_information_is_in_the_g2o_frame():
    """A corridor along x of frame i; scan j turned by 90°: the weak axis of the information of
    the error t2v(z^-1 x) — the frame of pose j — is its y axis, not x."""
    xs = np.linspace(-6, 6, 121)
    corridor = np.array([[x, y] for x in xs for y in (-1.0, 1.0)])
    truth = np.array([0.0, 0.3, math.pi / 2])
    m = match(ScanModel(corridor), _seen_from(corridor, truth), truth + [0, 0.02, 0.01])
    w, v = np.linalg.eigh(m.scan_information[:2, :2])
    assert abs(v[1, 0]) > 0.99  # weakest direction: y of pose j's frame (= x of frame i)
    assert abs(m.weak_direction[0]) > 0.99  # and x in frame i (parameter coordinates)
    assert m.degeneracy > 1e3
    # a room constrains every direction
    room = _room()
    m2 = match(ScanModel(room), _seen_from(room, truth), truth + [0.02, 0.0, 0.01])
    assert m2.degeneracy < 10


def test_information_scale_divides_the_raw_hessian():
    room = _room()
    rng = np.random.default_rng(1)
    cur = _seen_from(room, np.array([0.1, 0.0, 0.02])) + rng.normal(0, 0.01, (len(room), 2))
    model = ScanModel(room + rng.normal(0, 0.01, room.shape))
    raw = match(model, cur, np.zeros(3), information_scale=1.0)
    cal = match(model, cur, np.zeros(3))
    np.testing.assert_allclose(raw.pose, cal.pose)  # the weights of the estimate do not change
    np.testing.assert_allclose(raw.scan_information, INFORMATION_SCALE * cal.scan_information)


def test_prior_only_where_the_scans_say_nothing():
    """A corridor with an odometry prior: along the corridor the estimate is the prior's."""
    xs = np.linspace(-6, 6, 121)
    corridor = np.array([[x, y] for x in xs for y in (-1.0, 1.0)])
    truth = np.array([0.5, 0.0, 0.0])
    prior = np.array([0.8, 0.05, 0.02])
    omega = frontend.odometry_information(prior)
    m = match(ScanModel(corridor), _seen_from(corridor, truth), prior, prior_information=omega)
    assert m.pose[0] == pytest.approx(0.8, abs=1e-3)
    assert abs(m.pose[1]) < 1e-3 and abs(m.pose[2]) < 1e-4  # across it, the walls decide


def test_correlative_search_finds_a_far_start_and_measures_ambiguity():
    rng = np.random.default_rng(2)
    room = np.vstack([_room(), rng.uniform([-2, -1.5], [0, 0], (30, 2))])  # clutter: unique
    truth = np.array([1.2, -0.7, 0.15])
    cur = _seen_from(room, truth)
    c = correlative_search(ScanModel(room), cur, np.zeros(3), window=(1.5, 0.3))
    assert np.abs(c.pose[:2] - truth[:2]).max() <= 0.1 and abs(c.pose[2] - truth[2]) <= 0.03
    assert c.ambiguity < 0.9
    m = match(ScanModel(room), cur, c.pose)
    np.testing.assert_allclose(m.pose, truth, atol=1e-6)
    # a long corridor: every placement along it fits as well
    xs = np.linspace(-15, 15, 301)
    corridor = np.array([[x, y] for x in xs for y in (-1.0, 1.0)])
    c2 = correlative_search(
        ScanModel(corridor),
        corridor[(corridor[:, 0] > -5) & (corridor[:, 0] < 5)],
        np.zeros(3),
        window=(1.0, 0.1),
    )
    assert c2.ambiguity > 0.95


def test_bad_input():
    model = ScanModel(_room())
    with pytest.raises(OptionError, match=r"ScanModel: points must have shape \(m, 2\)"):
        ScanModel(np.zeros((5, 3)))
    with pytest.raises(OptionError, match="at least 3"):
        ScanModel(np.zeros((2, 2)))
    with pytest.raises(OptionError, match="non-finite"):
        match(model, np.full((5, 2), np.nan), np.zeros(3))
    with pytest.raises(OptionError, match="match: guess"):
        match(model, _room(), [0, 0])
    with pytest.raises(OptionError, match="prior_information must be positive semidefinite"):
        match(model, _room(), np.zeros(3), prior_information=-np.eye(3))
    with pytest.raises(OptionError, match="correlative_search: the window holds"):
        correlative_search(model, _room(), np.zeros(3), window=(50.0, 3.0), resolution=0.01)
    with pytest.raises(OptionError, match="correlative_search: resolution"):
        correlative_search(model, _room(), np.zeros(3), resolution=0)
    with pytest.raises(OptionError, match="free_space_conflicts: ranges_i and angles"):
        free_space_conflicts([1.0, 2.0], [0.0, 1.0, 2.0], 30.0, _room(), np.zeros(3))
    with pytest.raises(OptionError, match="max_distance"):
        match(model, _room(), np.zeros(3), max_distance=0)
