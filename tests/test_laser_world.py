"""The simulated laser world: exact ray casting, a collision-free trajectory, a noisy log."""

import math

import numpy as np
import pytest

from lagolib import laser_world, se2
from lagolib.errors import LagolibError, OptionError, OptionTypeError
from lagolib.laser_world import World, _ray_cast_loop, office, ray_cast, simulate_log, trajectory


def _square(h=2.0):
    """The walls of the square room [-h, h] x [-h, h]."""
    c = [(-h, -h), (h, -h), (h, h), (-h, h)]
    return World(np.array([(c[i], c[(i + 1) % 4]) for i in range(4)], float), "square")


@pytest.fixture(scope="module")
def log():
    return simulate_log()  # the default: the office, its route, seed 0


# --------------------------------------------------------------------------- ray casting


def test_ray_cast_square_room_hand_computed():
    room = _square(2.0)
    deg = np.radians([0, 90, 45, 180, -90, -45])
    r = ray_cast(room, [0.0, 0.0, 0.0], deg)
    np.testing.assert_allclose(r, [2, 2, 2 * math.sqrt(2), 2, 2, 2 * math.sqrt(2)], rtol=1e-15)
    # off centre and turned by 30°: beam -30° looks along +x (1 m to the wall), beam 60° along +y
    r = ray_cast(room, [1.0, 0.5, math.radians(30)], np.radians([-30, 60, 150, 240]))
    np.testing.assert_allclose(r, [1.0, 1.5, 3.0, 2.5], rtol=1e-14)
    # beam at atan(1/2) from (0, 0): hits x = 2 at y = 1, range sqrt(5)
    r = ray_cast(room, [0.0, 0.0, 0.0], [math.atan2(1, 2)])
    np.testing.assert_allclose(r, [math.sqrt(5)], rtol=1e-15)
    # a shorter sensor: the walls beyond max_range read max_range
    r = ray_cast(room, [[0.0, 0.0, 0.0], [1.5, 0.0, 0.0]], np.radians([0, 180]), max_range=1.5)
    np.testing.assert_array_equal(r, [[1.5, 1.5], [0.5, 1.5]])


def test_open_world_beams_that_hit_nothing_read_max_range():
    wall = World(np.array([[[1.0, -1.0], [1.0, 1.0]]]))  # one wall, x = 1, |y| <= 1
    deg = np.radians([0, 44, 46, 90, 180])
    r = ray_cast(wall, [0.0, 0.0, 0.0], deg, max_range=7.0)
    np.testing.assert_allclose(r, [1.0, 1 / math.cos(math.radians(44)), 7.0, 7.0, 7.0], rtol=1e-15)
    # a beam along the wall's own line is parallel to it: no hit
    assert ray_cast(wall, [1.0, -3.0, math.pi / 2], [0.0], max_range=7.0).tolist() == [7.0]


def test_vectorized_ray_cast_equals_the_loop(monkeypatch):
    world = office()
    rng = np.random.default_rng(5)
    poses = np.column_stack(
        [rng.uniform(0.2, 29.8, 30), rng.uniform(0.2, 17.8, 30), rng.uniform(-np.pi, np.pi, 30)]
    )
    angles = np.sort(rng.uniform(-np.pi, np.pi, 25))
    expected = _ray_cast_loop(world, poses, angles, 30.0)
    np.testing.assert_allclose(ray_cast(world, poses, angles, 30.0), expected, rtol=1e-12)
    monkeypatch.setattr(laser_world, "_CHUNK", 1)  # one pose per chunk: the same numbers
    np.testing.assert_allclose(ray_cast(world, poses, angles, 30.0), expected, rtol=1e-12)
    assert ray_cast(world, poses[3], angles).shape == (25,)
    assert 0.0 < expected.min() and expected.max() <= 30.0


# --------------------------------------------------------------------------- the trajectory


def _crossings(p, q, walls):
    """(k, s) bool: segment p_i q_i properly crosses wall s (orientation tests)."""

    def orient(a, b, c):
        return np.sign(
            (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
            - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])
        )

    p, q = p[:, None], q[:, None]
    a, b = walls[None, :, 0], walls[None, :, 1]
    return (orient(p, q, a) * orient(p, q, b) <= 0) & (orient(a, b, p) * orient(a, b, q) <= 0)


def test_crossing_test_detects_a_crossing():
    walls = np.array([[[0.0, -1.0], [0.0, 1.0]]])
    p, q = np.array([[-0.5, 0.0], [0.5, 0.0]]), np.array([[0.5, 0.0], [1.5, 0.0]])
    assert _crossings(p, q, walls)[:, 0].tolist() == [True, False]


def test_trajectory_drives_the_corridors_and_rooms_without_touching_a_wall():
    world = office()
    x = trajectory(world)
    assert x.shape == (618, 3)
    steps = np.diff(x[:, :2], axis=0)
    length = np.hypot(steps[:, 0], steps[:, 1])
    assert 0.299 < length.min() and length.max() < 0.3 + 1e-12  # chords of 0.3 m of path
    turn = se2.wrap_angle(np.diff(x[:, 2]))
    assert np.abs(turn).max() <= 0.3 / 1.2 + 1e-12  # 14.3° per step at most
    # the heading is the direction of travel (to within half a step's turn)
    travel = np.arctan2(steps[:, 1], steps[:, 0])
    assert np.abs(se2.wrap_angle(travel - x[:-1, 2])).max() <= 0.5 * 0.3 / 1.2 + 1e-9
    # no step crosses a wall, and no pose comes within 0.5 m of one
    assert not _crossings(x[:-1, :2], x[1:, :2], world.segments).any()
    A, E = world.segments[:, 0], world.segments[:, 1] - world.segments[:, 0]
    P = x[:, None, :2]
    t = np.clip(((P - A) * E).sum(-1) / (E * E).sum(-1), 0, 1)
    clearance = np.linalg.norm(A + t[..., None] * E - P, axis=-1)
    assert clearance.min() > 0.5
    # loops: it passes its start again, and many pose pairs > 50 steps apart are within 1 m
    assert np.linalg.norm(x[300:, :2] - x[0, :2], axis=1).min() < 0.3
    i, j = np.triu_indices(len(x), 51)
    near = np.hypot(*(x[i, :2] - x[j, :2]).T) < 1.0
    assert near.sum() > 500
    # it enters every room (A, B, C, D, E and the hall) at least 2 m past the door
    rooms = {"A": (0, 12, 10, 18), "B": (10, 12, 20, 18), "C": (20, 12, 30, 18),
             "D": (0, 0, 5, 12), "E": (25, 2, 30, 12), "hall": (7, 2, 23, 10)}  # fmt: skip
    for name, (x0, y0, x1, y1) in rooms.items():
        inside = (x[:, 0] > x0 + 2) & (x[:, 0] < x1 - 2) & (x[:, 1] > y0 + 2) & (x[:, 1] < y1 - 2)
        assert inside.any(), name
    # two laps: it drives the bottom corridor twice, towards the exit
    bottom = (np.abs(x[:, 1] - 1.0) < 1e-9) & (x[:, 0] > 8) & (x[:, 0] < 22)
    runs = np.flatnonzero(np.diff(bottom.astype(int)) == 1)
    assert len(runs) == 2 and np.all(np.abs(x[bottom, 2]) < 1e-12)


def test_trajectory_is_deterministic_and_follows_the_route_spacing():
    np.testing.assert_array_equal(trajectory(), trajectory(office()))
    coarse = trajectory(step=0.5)
    assert len(coarse) == 371
    assert np.abs(se2.wrap_angle(np.diff(coarse[:, 2]))).max() <= 0.5 / 1.2 + 1e-12
    # the path's length: the route's legs, less (2 tan(Δ/2) - Δ) r at each corner turning by Δ
    route = office().route
    legs = np.diff(route, axis=0)
    turns = np.abs(se2.wrap_angle(np.diff(np.arctan2(legs[:, 1], legs[:, 0]))))
    for r in (1.2, 0.6):
        length = np.hypot(*legs.T).sum() - r * (2 * np.tan(turns / 2) - turns).sum()
        assert len(trajectory(turn_radius=r)) == math.floor(length / 0.3 + 1e-9) + 1


# --------------------------------------------------------------------------- the log


def test_log_is_deterministic_for_a_seed(log):
    again = simulate_log(rng=0)
    np.testing.assert_array_equal(again.ranges, log.ranges)
    np.testing.assert_array_equal(again.odometry, log.odometry)
    other = simulate_log(rng=np.random.default_rng(1))
    assert not np.array_equal(other.ranges, log.ranges)
    np.testing.assert_array_equal(other.reference, log.reference)
    assert (log.name, log.reference_kind, log.max_range, log.min_range) == (
        "simulated office",
        "truth",
        30.0,
        0.0,
    )
    np.testing.assert_array_equal(log.reference, trajectory())
    np.testing.assert_allclose(np.degrees(log.angles[[0, 1, -1]]), [-90, -89, 89], atol=1e-12)
    np.testing.assert_array_equal(log.timestamps[:3], [0.0, 0.5, 1.0])
    assert log.odometry[0].tolist() == [0.0, 0.0, 0.0]


def test_noiseless_log_is_exact():
    exact = simulate_log(range_sigma=0.0, odometry_sigma=(0.0, 0.0))
    chained = exact.odometry_poses()
    assert np.abs(se2.between(exact.reference, chained)).max() < 1e-12
    np.testing.assert_array_equal(exact.ranges, ray_cast(office(), exact.reference, exact.angles))


def test_noise_statistics_match_the_sigmas(log):
    true = np.zeros_like(log.odometry)
    true[1:] = se2.between(log.reference[:-1], log.reference[1:])
    dist = np.hypot(true[1:, 0], true[1:, 1])
    err = log.odometry[1:] - true[1:]
    err[:, 2] = se2.wrap_angle(err[:, 2])
    xy = err[:, :2] / (0.05 * dist)[:, None]  # in units of σ_xy = 5 % of the step
    assert abs(xy.std() - 1) < 0.15 and abs(xy.mean()) < 0.1
    assert abs(err[:, 2].std() / math.radians(2) - 1) < 0.15 and abs(err[:, 2].mean()) < 0.003
    exact = ray_cast(office(), log.reference, log.angles)
    hit = exact < 30.0
    noise = (log.ranges - exact)[hit]
    assert abs(noise.std() / 0.01 - 1) < 0.15 and abs(noise.mean()) < 0.001
    np.testing.assert_array_equal(log.valid(), hit)  # every wall hit returns, nothing else


def test_heading_bias_is_radians_per_metre():
    bias = math.radians(-3.9)
    biased = simulate_log(odometry_sigma=(0.05, 0.0), heading_bias=bias, range_sigma=0.0)
    true = se2.between(biased.reference[:-1], biased.reference[1:])
    dist = np.hypot(true[:, 0], true[:, 1])
    dtheta = se2.wrap_angle(biased.odometry[1:, 2] - true[:, 2])
    np.testing.assert_allclose(dtheta, bias * dist, atol=1e-12)
    # over the 184 m driven, the chained heading drifts by -3.9°/m x 184 m (wrapped)
    drift = se2.wrap_angle(biased.odometry_poses()[-1, 2] - biased.reference[-1, 2])
    assert float(drift) == pytest.approx(float(se2.wrap_angle(bias * dist.sum())), abs=1e-9)


def test_no_return_beams_are_the_ones_leaving_through_the_exit(log):
    """The office is closed but for its exit (x = 30, 0 <= y <= 2): with the exit walled up,
    every beam returns; with it open, exactly the beams whose first wall would be the exit's
    read max_range."""
    closed = ray_cast(office(open_exit=False), log.reference, log.angles)
    assert closed.max() < 26.0  # nothing inside is farther
    exit_only = ray_cast(World(np.array([[[30.0, 0.0], [30.0, 2.0]]])), log.reference, log.angles)
    through_exit = np.isclose(exit_only, closed, rtol=1e-12, atol=0)  # the exit is hit first
    no_return = ~log.valid()
    assert no_return.sum() > 500  # the bottom corridor's scans look out of the exit
    np.testing.assert_array_equal(no_return, through_exit)
    np.testing.assert_array_equal(log.ranges[no_return], 30.0)
    assert np.all(log.reference[no_return.any(axis=1), 1] < 2.1)  # seen from the corridor


def test_the_bottom_corridor_is_featureless(log):
    """From the straight part of the bottom corridor, heading for the exit, a scan's returns lie
    on its two parallel walls (y = 0, y = 2) except a few on the far wall x = 25."""
    k = np.flatnonzero((np.abs(log.reference[:, 1] - 1) < 1e-9) & (log.reference[:, 0] < 18))
    k = k[log.reference[k, 0] > 8]
    assert len(k) >= 50
    exact = ray_cast(office(), log.reference[k], log.angles)
    phi = log.reference[k, 2:3] + log.angles
    y = log.reference[k, 1:2] + exact * np.sin(phi)
    x_end = log.reference[k, 0:1] + exact * np.cos(phi)
    side = (np.abs(y) < 1e-9) | (np.abs(y - 2) < 1e-9)
    other = ~side & (exact < 30)
    assert np.all(np.abs(x_end[other] - 25) < 1e-9)  # the only walls across the corridor
    assert other.sum(axis=1).max() <= 4


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "call, error, match",
    [
        (
            lambda: World(np.zeros((2, 2))),
            OptionError,
            r"World: segments must have shape \(s, 2, 2\)",
        ),
        (lambda: World([[[0, 0], [0, 0]]]), OptionError, "segment 0 has zero length"),
        (lambda: World([[[0, 0], [np.nan, 1]]]), OptionError, "segment 0 is not finite"),
        (lambda: World("walls"), OptionTypeError, "World: segments must be a real number"),
        (lambda: World([[[0, 0], [1, 0]]], route=[[0, 0]]), OptionError, "route must have shape"),
        (
            lambda: ray_cast(np.zeros((1, 2, 2)), [0, 0, 0], [0]),
            OptionTypeError,
            "must be a lagolib",
        ),
        (lambda: ray_cast(office(), [0, 0], [0]), OptionError, r"ray_cast: poses must have shape"),
        (lambda: ray_cast(office(), [0, np.inf, 0], [0]), OptionError, "pose 0 is not finite"),
        (lambda: ray_cast(office(), [1, 1, 0], []), OptionError, "angles must be a non-empty"),
        (lambda: ray_cast(office(), [1, 1, 0], [0], 0.0), OptionError, "max_range must be"),
        (lambda: ray_cast(office(), [1, 1, 0], [0j]), OptionTypeError, "angles must be real"),
        (lambda: office(clutter=1), OptionTypeError, "office: clutter must be True or False"),
        (lambda: trajectory(_square()), OptionError, "world 'square' has no route"),
        (lambda: trajectory(step=0), OptionError, "trajectory: step must be"),
        (lambda: trajectory(turn_radius=2.0), OptionError, "too short for corners of radius 2"),
        (lambda: simulate_log(rng=None), OptionTypeError, "simulate_log: rng must be"),
        (lambda: simulate_log(rng=-1), OptionError, "rng must be an integer >= 0"),
        (lambda: simulate_log(n_beams=1), OptionError, "n_beams must be an integer >= 2"),
        (lambda: simulate_log(fov=0.0), OptionError, "fov must be a finite number > 0.0"),
        (lambda: simulate_log(odometry_sigma=0.05), OptionError, "odometry_sigma must be a pair"),
        (lambda: simulate_log(odometry_sigma=(0.05, -1)), OptionError, r"odometry_sigma\[1\]"),
        (lambda: simulate_log(range_sigma=-0.01), OptionError, "range_sigma must be"),
        (
            lambda: simulate_log(heading_bias=np.nan),
            OptionError,
            "heading_bias must be a finite number",
        ),
        (
            lambda: simulate_log(poses=np.zeros((3, 2))),
            OptionError,
            r"poses must have shape \(k, 3\)",
        ),
        (lambda: simulate_log(_square(), poses=[[np.nan, 0, 0]]), OptionError, "not finite"),
        (lambda: simulate_log(world="office"), OptionTypeError, "simulate_log: world must be"),
    ],
)
def test_bad_input_is_a_lagolib_error(call, error, match):
    with pytest.raises(error, match=match) as info:
        call()
    assert isinstance(info.value, LagolibError)


def test_a_world_without_route_needs_poses():
    log = simulate_log(_square(), poses=[[0.0, 0.0, 0.0], [1.0, 0.0, math.pi / 2]], n_beams=4,
                       range_sigma=0.0, odometry_sigma=(0.0, 0.0))  # fmt: skip
    # 4 beams over 180°: -90°, -45°, 0°, 45°
    np.testing.assert_allclose(
        log.ranges,
        [[2, 2 * math.sqrt(2), 2, 2 * math.sqrt(2)], [1, math.sqrt(2), 2, 2 * math.sqrt(2)]],
        rtol=1e-14,
    )
    np.testing.assert_allclose(log.odometry[1], [1.0, 0.0, math.pi / 2], atol=1e-15)
