"""The Carmen reader, beam angles, scans as points, odometry increments (lagolib.scans)."""

import gzip
import math

import numpy as np
import pytest

from lagolib import metrics, se2
from lagolib.errors import OptionError, OptionTypeError, ParseError
from lagolib.scans import (
    LaserLog,
    beam_angles,
    chain_increments,
    read_carmen,
    scan_points,
    simulated_odometry,
)


def _flaser(ranges, pose, stamp):
    r = " ".join(f"{v:g}" for v in ranges)
    x, y, t = pose
    return f"FLASER {len(ranges)} {r} {x} {y} {t} {x} {y} {t} {stamp} pippo {stamp}\n"


def _odom(pose, stamp):
    x, y, t = pose
    return f"ODOM {x} {y} {t} 0 0 0 {stamp} pippo {stamp}\n"


P = np.array([[0.5, -0.2, 0.3], [1.4, 0.1, 0.9], [1.9, 1.2, 2.0]])
RAW = [np.array([0.35, 0.05, 0.5]), None]  # the last timed ODOM before scans 1 and 2


def _log_text():
    n = 4
    lines = ["# message formats defined: PARAM SYNC ODOM FLASER\n", "PARAM robot_x 0 nohost 0\n"]
    lines += [_odom((0, 0, 0), 1.0), _odom((0.1, 0, 0.01), 1.1)]
    lines += [_flaser([1.0, 2.0, 81.83, 3.0], P[0], 2.0), _odom(P[0], 0), "NEFF 15\n"]
    # timed ODOMs after scan 0: the corrected pose of scan 0 plus the raw motion
    lines += [_odom(se2.compose(P[0], [0.1, 0.0, 0.1]), 2.5)]
    lines += [_odom(se2.compose(P[0], RAW[0]), 2.9)]
    lines += [_flaser([1.5, 81.83, 2.5, 0.5], P[1], 3.0), _odom(P[1], 0)]
    # no timed ODOM between scans 1 and 2: odometry saw no motion
    lines += [_flaser([2.0] * n, P[2], 2.8), _odom(P[2], 0)]
    return "".join(lines)


@pytest.fixture
def carmen(tmp_path):
    p = tmp_path / "tiny.log"
    p.write_text(_log_text())
    return p


def test_read_carmen_ranges_poses_and_increments(carmen):
    log = read_carmen(carmen)
    assert log.ranges.shape == (3, 4) and len(log) == 3
    assert log.max_range == 81.83  # the log's largest range: "no return"
    np.testing.assert_array_equal(log.reference, P)
    assert log.reference_kind == "gmapping"
    # u_1 = P[0]^-1 ⊕ O_1 with O_1 = P[0] ⊕ RAW: the raw increment itself
    np.testing.assert_allclose(log.odometry[1], RAW[0], atol=1e-12)
    np.testing.assert_array_equal(log.odometry[[0, 2]], 0.0)
    np.testing.assert_array_equal(log.timestamps, [2.0, 3.0, 2.8])  # backwards, kept as logged
    assert log.name == "tiny"
    np.testing.assert_array_equal(log.valid()[0], [True, True, False, True])
    pts = log.points(0)
    a = beam_angles(4)
    np.testing.assert_allclose(pts[1], [2 * math.cos(a[1]), 2 * math.sin(a[1])])
    assert len(pts) == 3


def test_gzip_reads_the_same(carmen, tmp_path):
    gz = tmp_path / "tiny.log.gz"
    with gzip.open(gz, "wt") as f:
        f.write(carmen.read_text())
    a, b = read_carmen(carmen), read_carmen(gz)
    np.testing.assert_array_equal(a.ranges, b.ranges)
    np.testing.assert_array_equal(a.odometry, b.odometry)
    assert b.name == "tiny"


def test_beam_angles_of_the_radish_scanners():
    np.testing.assert_allclose(np.degrees(beam_angles(180))[[0, 90, 179]], [-90, 0, 89])
    np.testing.assert_allclose(np.degrees(beam_angles(360))[[0, 180, 359]], [-90, 0, 89.5])
    np.testing.assert_allclose(np.degrees(beam_angles(361))[[0, 180, 360]], [-90, 0, 90])
    with pytest.raises(OptionError, match="beam_angles: n"):
        beam_angles(1)


def test_scan_points_drops_no_returns():
    a = np.array([0.0, np.pi / 2, np.pi])
    pts, beams = scan_points([1.0, np.inf, 5.0], a, max_range=5.0)
    np.testing.assert_allclose(pts, [[1.0, 0.0]])
    np.testing.assert_array_equal(beams, [0])


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("FLASER 3 1 2 0 0 0 0 0 0 1 pippo 1\n", r"tiny\.log:\d+: FLASER with 3 beams needs 14"),
        ("FLASER 2 1 x 0 0 0 0 0 0 1 pippo 1\n", r"tiny\.log:\d+: FLASER ranges has 'x'"),
        ("FLASER 2 1 -2 0 0 0 0 0 0 1 pippo 1\n", r"tiny\.log:\d+: FLASER range -2.0 is negative"),
        ("FLASER two 1 2\n", r"tiny\.log:\d+: FLASER beam count 'two'"),
        ("FLASER 2 1 nan 0 0 0 0 0 0 1 pippo 1\n", r"tiny\.log:\d+: FLASER ranges is not finite"),
        ("ODOM 1 2 3\n", r"tiny\.log:\d+: ODOM needs"),
    ],
)
def test_malformed_lines_name_file_and_line(tmp_path, line, message):
    p = tmp_path / "tiny.log"
    p.write_text(_flaser([1.0, 2.0], P[0], 1.0) + line)
    with pytest.raises(ParseError, match=message) as e:
        read_carmen(p)
    assert isinstance(e.value, ValueError)
    assert ":2:" in str(e.value)  # the second line


def test_scans_of_different_widths_and_files_without_scans(tmp_path):
    p = tmp_path / "tiny.log"
    p.write_text(_flaser([1.0, 2.0], P[0], 1.0) + _flaser([1.0, 2.0, 3.0], P[1], 2.0))
    with pytest.raises(ParseError, match=r"tiny\.log:2: this scan has 3 beams, the earlier ones 2"):
        read_carmen(p)
    p.write_text("VERTEX_SE2 0 0 0 0\n")
    with pytest.raises(ParseError, match="no FLASER line"):
        read_carmen(p)
    with pytest.raises(ParseError, match="no such file"):
        read_carmen(tmp_path / "missing.log")


def test_chain_increments_is_the_notes_compounding():
    rng = np.random.default_rng(3)
    u = rng.normal(0, [0.5, 0.2, 0.3], (50, 3))
    x = chain_increments([1.0, 2.0, 0.5], u)
    ref = [np.array([1.0, 2.0, 0.5])]
    for k in range(1, 50):
        ref.append(se2.compose(ref[-1], u[k]))
    np.testing.assert_allclose(x, np.array(ref), atol=1e-12)


def _random_log(k=30, seed=0):
    rng = np.random.default_rng(seed)
    ref = chain_increments([0, 0, 0], rng.normal(0, [0.5, 0.1, 0.2], (k, 3)))
    odo = np.zeros((k, 3))
    odo[1:] = se2.between(ref[:-1], ref[1:]) + rng.normal(0, 0.01, (k - 1, 3))
    return LaserLog(
        rng.uniform(0.5, 10, (k, 8)), beam_angles(8), 30.0, 0.0, ref, "truth", odo, np.arange(k)
    )


def test_subset_rechains_the_odometry():
    log = _random_log()
    idx = np.array([0, 3, 4, 10, 29])
    sub = log.subset(idx)
    odo = log.odometry_poses()[idx]
    np.testing.assert_allclose(sub.odometry_poses(), odo, atol=1e-12)
    np.testing.assert_array_equal(sub.ranges, log.ranges[idx])
    for bad in ([3, 1], [], [0, 30], np.array([True, False])):
        with pytest.raises(OptionError, match="LaserLog.subset"):
            log.subset(bad)


def test_simulated_odometry_is_seeded_and_exact_without_noise():
    log = _random_log()
    exact = simulated_odometry(log, translation_sigma=0.0, rotation_sigma=0.0)
    np.testing.assert_allclose(exact.odometry_poses(), log.reference, atol=1e-12)
    a, b = simulated_odometry(log, rng=4), simulated_odometry(log, rng=4)
    np.testing.assert_array_equal(a.odometry, b.odometry)
    assert not np.array_equal(a.odometry, simulated_odometry(log, rng=5).odometry)
    with pytest.raises(OptionTypeError, match="simulated_odometry: rng"):
        simulated_odometry(log, rng=None)


def test_laserlog_checks_its_arrays():
    log = _random_log()
    with pytest.raises(OptionError, match="reference must have shape"):
        LaserLog(
            log.ranges,
            log.angles,
            30.0,
            0.0,
            log.reference[:3],
            "truth",
            log.odometry,
            log.timestamps,
        )
    with pytest.raises(OptionError, match="negative range"):
        LaserLog(
            -log.ranges, log.angles, 30.0, 0.0, log.reference, "truth", log.odometry, log.timestamps
        )
    with pytest.raises(OptionError, match="reference_kind"):
        LaserLog(
            log.ranges, log.angles, 30.0, 0.0, log.reference, "gps", log.odometry, log.timestamps
        )
    with pytest.raises(OptionTypeError, match="ranges must be an array of numbers"):
        LaserLog("abc", log.angles, 30.0, 0.0, log.reference, "truth", log.odometry, log.timestamps)
    assert not log.ranges.flags.writeable


def test_intel_log_facts(benchmark):
    """SOURCES.md: 910 scans of 180 beams; the chained increments drift to ATE 24.0 m."""
    log = read_carmen(benchmark("intel_laser"))
    assert log.ranges.shape == (910, 180)
    assert log.max_range == pytest.approx(81.83)
    ate = metrics.absolute_trajectory_error(log.odometry_poses(), log.reference)
    assert ate.translation_rmse == pytest.approx(24.0, abs=0.05)
    # 95 % of the heading increments are whole multiples of the encoder step 0.0061455 rad
    steps = log.odometry[1:, 2] / 0.0061455
    assert np.mean(np.abs(steps - np.round(steps)) < 0.01) > 0.9
