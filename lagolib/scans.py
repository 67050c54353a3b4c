"""Laser scans: the Carmen log reader, beam angles, and scans as points.

Lecture notes, "Graph-based SLAM": *every node in the graph corresponds to a robot position and a
laser measurement*.  A :class:`LaserLog` holds those measurements — one scan per row — with the
two pose sequences a log carries:

``reference`` (k, 3), world frame
    The pose of every scan as the log gives it.  In the Radish logs these are the *corrected*
    poses, GMapping's estimate — a reference to compare with, not ground truth.  In a simulated
    log (:mod:`lagolib.laser_world`) they are the truth.
``odometry`` (k, 3), frame of the previous scan
    The raw odometry increment ``u_k``: the pose of scan ``k`` in the frame of scan ``k - 1``
    (``u_0 = 0``).  The Radish logs keep raw odometry only as increments: the timed ``ODOM``
    lines after scan ``k - 1`` are its corrected pose plus the raw motion, so
    ``u_k = P[k-1]^-1 ⊕ O_k`` with ``O_k`` the last timed ``ODOM`` line before scan ``k``.

A Carmen ``FLASER`` line is ``FLASER n r_1 … r_n x y θ odom_x odom_y odom_θ timestamp host
logger_timestamp`` (Carmen's logger documentation; the two poses are equal in these logs).  The
beams span 180° from −90°: 180 beams step 1°, 360 and 361 beams step 0.5° (:func:`beam_angles`).
A beam at the log's maximum range (81.83 m for INTEL) is "no return", not a wall.

Examples
--------
>>> import numpy as np
>>> np.degrees(beam_angles(180)[[0, 1, -1]]).round(6).tolist()
[-90.0, -89.0, 89.0]
>>> np.degrees(beam_angles(361)[[0, -1]]).round(6).tolist()
[-90.0, 90.0]
"""

from __future__ import annotations

import gzip
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import se2
from .checks import check_int, check_real, check_rng
from .errors import OptionError, OptionTypeError, ParseError

__all__ = [
    "LaserLog",
    "beam_angles",
    "read_carmen",
    "scan_points",
    "chain_increments",
    "simulated_odometry",
]


def beam_angles(n, fov=math.pi):
    """Beam angles of an ``n``-beam scan in the sensor frame: ``-fov/2 + k * step``.

    The Radish logs' scanners cover 180°: with an even ``n`` the last beam stops one step short
    of +90° (180 beams: −90° … +89°), with an odd ``n`` it reaches +90° (361 beams: −90° … +90°).

    Parameters
    ----------
    n : int
        Number of beams (>= 2).
    fov : float
        Field of view in radians (default π).

    Returns
    -------
    ndarray, shape (n,)
        Angles in radians, counter-clockwise from the sensor's x axis.
    """
    n = check_int(n, "n", "beam_angles", minimum=2)
    fov = check_real(fov, "fov", "beam_angles", minimum=0.0, maximum=2 * math.pi, strict=True)
    step = fov / (n - n % 2)
    return -fov / 2 + step * np.arange(n)


def scan_points(ranges, angles, *, max_range=math.inf, min_range=0.0):
    """Points of one scan in its sensor frame, and which beams they are.

    Parameters
    ----------
    ranges : array_like, shape (n,)
        Ranges in metres.
    angles : array_like, shape (n,)
        Beam angles in the sensor frame.
    max_range, min_range : float
        A beam is a return when ``min_range < r < max_range`` and ``r`` is finite.

    Returns
    -------
    points : ndarray, shape (m, 2)
        ``r (cos a, sin a)`` of the returns, sensor frame.
    beams : ndarray of int, shape (m,)
        Their beam indices.
    """
    r = np.asarray(ranges, dtype=float)
    a = np.asarray(angles, dtype=float)
    if r.shape != a.shape or r.ndim != 1:
        raise OptionError(
            f"scan_points: ranges and angles must be 1-D of one length; got {r.shape}, {a.shape}"
        )
    ok = np.isfinite(r) & (r > min_range) & (r < max_range)
    (beams,) = np.nonzero(ok)
    return np.column_stack([r[beams] * np.cos(a[beams]), r[beams] * np.sin(a[beams])]), beams


def chain_increments(start, increments):
    """Poses from chained increments: ``x_k = x_{k-1} ⊕ u_k`` (lecture notes' ⊕), ``x_0 = start``.

    Parameters
    ----------
    start : array_like, shape (3,)
        World-frame pose of the first scan.
    increments : array_like, shape (k, 3)
        ``u_k`` in the frame of pose ``k - 1`` (``u_0`` is ignored).

    Returns
    -------
    ndarray, shape (k, 3)
        World-frame poses.
    """
    u = np.asarray(increments, dtype=float)
    x = np.empty_like(u)
    x[0] = start
    # the headings first (a cumulative sum), then every translation rotated at once
    x[:, 2] = x[0, 2] + np.concatenate([[0.0], np.cumsum(u[1:, 2])])
    c, s = np.cos(x[:-1, 2]), np.sin(x[:-1, 2])
    dx = c * u[1:, 0] - s * u[1:, 1]
    dy = s * u[1:, 0] + c * u[1:, 1]
    x[1:, 0] = x[0, 0] + np.cumsum(dx)
    x[1:, 1] = x[0, 1] + np.cumsum(dy)
    x[:, 2] = se2.wrap_angle(x[:, 2])
    return x


@dataclass(frozen=True, eq=False)
class LaserLog:
    """A sequence of planar laser scans with their poses and odometry.

    Attributes
    ----------
    ranges : ndarray, shape (k, n)
        Ranges in metres, one row per scan in log order.
    angles : ndarray, shape (n,)
        Beam angles in the sensor frame (radians).
    max_range : float
        A range ``>= max_range`` is "no return".
    min_range : float
        A range ``<= min_range`` is invalid.
    reference : ndarray, shape (k, 3)
        World-frame poses of the scans as the log gives them (``reference_kind``).
    reference_kind : str
        ``"gmapping"`` (a Radish log's corrected poses: an estimate) or ``"truth"`` (simulated).
    odometry : ndarray, shape (k, 3)
        ``u_k``: pose of scan ``k`` in the frame of scan ``k - 1`` as odometry measured it;
        ``u_0 = 0``.
    timestamps : ndarray, shape (k,)
        Seconds, as logged (they may go backwards; lagolib never relies on them).
    name : str
    """

    ranges: np.ndarray
    angles: np.ndarray
    max_range: float
    min_range: float
    reference: np.ndarray
    reference_kind: str
    odometry: np.ndarray
    timestamps: np.ndarray
    name: str = "laser log"

    def __post_init__(self):
        where = "LaserLog"
        arrays = {}
        for field in ("ranges", "angles", "reference", "odometry", "timestamps"):
            value = getattr(self, field)
            try:
                a = np.array(value, dtype=float)
            except (TypeError, ValueError):
                raise OptionTypeError(
                    f"{where}: {field} must be an array of numbers; got {type(value).__name__}"
                ) from None
            a.setflags(write=False)
            arrays[field] = a
        r = arrays["ranges"]
        if r.ndim != 2 or r.shape[0] < 1 or r.shape[1] < 2:
            raise OptionError(f"{where}: ranges must have shape (k, n), n >= 2; got {r.shape}")
        k, n = r.shape
        want = {"angles": (n,), "reference": (k, 3), "odometry": (k, 3), "timestamps": (k,)}
        for field, shape in want.items():
            if arrays[field].shape != shape:
                raise OptionError(
                    f"{where}: {field} must have shape {shape} for {k} scans of {n} beams; got "
                    f"{arrays[field].shape}"
                )
        for field in ("angles", "reference", "odometry"):
            if not np.all(np.isfinite(arrays[field])):
                bad = np.argwhere(~np.isfinite(arrays[field]))[0].tolist()
                raise OptionError(f"{where}: {field} is not finite at index {bad}")
        if np.any(r < 0):
            (s, b) = np.argwhere(r < 0)[0]
            raise OptionError(f"{where}: scan {s} beam {b} has a negative range {r[s, b]!r}")
        max_range = check_real(self.max_range, "max_range", where, minimum=0.0, strict=True)
        min_range = check_real(self.min_range, "min_range", where, minimum=0.0)
        if self.reference_kind not in ("gmapping", "truth"):
            raise OptionError(
                f"{where}: reference_kind must be 'gmapping' or 'truth'; got {self.reference_kind!r}"
            )
        for field, a in arrays.items():
            object.__setattr__(self, field, a)
        object.__setattr__(self, "max_range", max_range)
        object.__setattr__(self, "min_range", min_range)
        object.__setattr__(self, "name", str(self.name))

    def __len__(self):
        return self.ranges.shape[0]

    def __repr__(self):
        k, n = self.ranges.shape
        return f"<LaserLog {self.name!r}: {k} scans of {n} beams, max range {self.max_range:g} m>"

    def valid(self):
        """(k, n) bool: the beams that returned (``min_range < r < max_range``, finite)."""
        r = self.ranges
        return np.isfinite(r) & (r > self.min_range) & (r < self.max_range)

    def points(self, k):
        """(m, 2) points of scan ``k``'s returns in the sensor frame of scan ``k``."""
        k = check_int(k, "k", "LaserLog.points", minimum=-len(self), maximum=len(self) - 1)
        pts, _ = scan_points(
            self.ranges[k], self.angles, max_range=self.max_range, min_range=self.min_range
        )
        return pts

    def odometry_poses(self, start=None):
        """(k, 3) world-frame poses of the chained odometry increments, from ``reference[0]``."""
        start = self.reference[0] if start is None else np.asarray(start, dtype=float)
        return chain_increments(start, self.odometry)

    def with_odometry(self, increments):
        """The same scans and reference with other odometry increments ``(k, 3)``."""
        return LaserLog(
            self.ranges,
            self.angles,
            self.max_range,
            self.min_range,
            self.reference,
            self.reference_kind,
            increments,
            self.timestamps,
            self.name,
        )

    def subset(self, scans):
        """The log restricted to ``scans`` (indices, increasing): increments are re-chained."""
        idx = np.asarray(scans)
        if (
            idx.dtype == bool
            or idx.ndim != 1
            or idx.size == 0
            or not np.issubdtype(idx.dtype, np.integer)
        ):
            raise OptionError("LaserLog.subset: scans must be a non-empty 1-D array of indices")
        if np.any(np.diff(idx) <= 0) or idx[0] < 0 or idx[-1] >= len(self):
            raise OptionError(
                f"LaserLog.subset: scans must increase within 0..{len(self) - 1}; got {idx[:8]}…"
            )
        odo = self.odometry_poses(start=np.zeros(3))[idx]
        u = np.zeros_like(odo)
        u[1:] = se2.between(odo[:-1], odo[1:])
        return LaserLog(
            self.ranges[idx],
            self.angles,
            self.max_range,
            self.min_range,
            self.reference[idx],
            self.reference_kind,
            u,
            self.timestamps[idx],
            self.name,
        )


def _open_text(path):
    p = Path(path)
    with open(p, "rb") as f:
        gz = f.read(2) == b"\x1f\x8b"
    if gz:
        return gzip.open(p, "rt", encoding="utf-8", errors="replace")
    return open(p, encoding="utf-8", errors="replace")


def _numbers(tokens, where, what):
    try:
        values = [float(t) for t in tokens]
    except ValueError:
        bad = next(t for t in tokens if not _is_float(t))
        raise ParseError(*where, f"{what} has {bad!r} where a number belongs") from None
    if not all(math.isfinite(v) for v in values):
        raise ParseError(*where, f"{what} is not finite ({' '.join(tokens)[:80]})")
    return values


def _is_float(t):
    try:
        float(t)
    except ValueError:
        return False
    return True


def read_carmen(path, *, max_range=None, name=None):
    """Read a Carmen log's ``FLASER`` scans, corrected poses and odometry increments.

    Parameters
    ----------
    path : str or Path
        A Carmen log, plain or gzip-compressed.
    max_range : float, optional
        Ranges at or above it are "no return".  Default: the largest range in the log (the
        scanner's "no return" value: 81.83 m in INTEL, 50 m in ACES).
    name : str, optional
        Default: the file name without ``.log``/``.gz``.

    Returns
    -------
    LaserLog
        ``reference`` holds the logged (corrected) poses, ``reference_kind="gmapping"``;
        ``odometry`` the raw increments ``u_k = P[k-1]^-1 ⊕ O_k`` (module docstring).

    Raises
    ------
    ParseError
        ``file:line`` of a malformed ``FLASER``/``ODOM`` line (too few fields, a count that does
        not match, text where a number belongs, a negative range, scans with different numbers
        of beams), or a file without ``FLASER`` lines.
    """
    p = Path(path)
    if p.is_dir():
        raise ParseError(p, None, "is a folder; read_carmen needs a Carmen laser log file")
    if not p.is_file():
        raise ParseError(p, None, "no such file (read_carmen needs a Carmen laser log)")
    try:
        return _read_carmen(p, max_range, name)
    except (OSError, EOFError, UnicodeError) as e:  # a corrupt .gz, an unreadable file
        raise ParseError(p, None, f"cannot be read as a Carmen log ({e})") from None


def _read_carmen(p, max_range, name):
    ranges, poses, stamps, odom = [], [], [], []
    last_odom = None  # the last timed ODOM pose since the previous FLASER
    n_beams = None
    with _open_text(p) as f:
        for lineno, line in enumerate(f, 1):
            tokens = line.split()
            if not tokens or tokens[0].startswith("#"):
                continue
            where = (p, lineno)
            kind = tokens[0]
            if kind == "ODOM":
                if len(tokens) < 10:
                    raise ParseError(
                        *where,
                        f"ODOM needs x y theta tv rv accel timestamp host "
                        f"logger_timestamp; got {len(tokens) - 1} fields",
                    )
                x, y, th, *_, stamp = _numbers(tokens[1:8], where, "ODOM")
                if stamp != 0.0:  # the untimed copy after each FLASER repeats its pose
                    last_odom = (x, y, th)
            elif kind == "FLASER":
                if len(tokens) < 2:
                    raise ParseError(*where, "FLASER without a beam count")
                try:
                    n = int(tokens[1])
                except ValueError:
                    raise ParseError(
                        *where, f"FLASER beam count {tokens[1]!r} is not an integer"
                    ) from None
                if n < 2 or len(tokens) != n + 11:
                    raise ParseError(
                        *where,
                        f"FLASER with {tokens[1]} beams needs {n + 11} fields (beams, "
                        f"x y theta odom_x odom_y odom_theta timestamp host logger_timestamp); "
                        f"got {len(tokens)}",
                    )
                if n_beams is not None and n != n_beams:
                    raise ParseError(
                        *where,
                        f"this scan has {n} beams, the earlier ones {n_beams}; lagolib "
                        "reads logs of one scanner",
                    )
                n_beams = n
                r = _numbers(tokens[2 : 2 + n], where, "FLASER ranges")
                if min(r) < 0:
                    raise ParseError(*where, f"FLASER range {min(r)!r} is negative")
                x, y, th = _numbers(tokens[2 + n : 5 + n], where, "FLASER pose")
                (stamp,) = _numbers(tokens[8 + n : 9 + n], where, "FLASER timestamp")
                ranges.append(r)
                poses.append((x, y, th))
                stamps.append(stamp)
                odom.append(last_odom)
                last_odom = None
    if not ranges:
        raise ParseError(p, None, "no FLASER line: is it a Carmen laser log?")
    P = np.array(poses)
    P[:, 2] = se2.wrap_angle(P[:, 2])
    u = np.zeros_like(P)
    for k in range(1, len(P)):
        # no timed ODOM between two scans: odometry saw no motion
        u[k] = se2.between(P[k - 1], odom[k]) if odom[k] is not None else 0.0
    R = np.array(ranges)
    if max_range is None:
        max_range = float(R.max())
    if name is None:
        name = p.name.removesuffix(".gz").removesuffix(".log")
    return LaserLog(
        R, beam_angles(n_beams), max_range, 0.0, P, "gmapping", u, np.array(stamps), name
    )


def simulated_odometry(log, *, translation_sigma=0.05, rotation_sigma=2 * math.pi / 180, rng=0):
    """The log with its odometry replaced by the reference's increments plus Gaussian noise.

    ``u_k = t2v(P[k-1]^-1 P[k]) + n_k`` with ``n_k ~ N(0, diag(s², s², rotation_sigma²))``,
    ``s = translation_sigma · |t_k|`` (a fraction of the distance between the reference poses).
    The experiment of issue 23: INTEL's scans with odometry as good as the model says, to
    separate the front end's errors from the real odometry's heading bias.

    Parameters
    ----------
    log : LaserLog
    translation_sigma : float
        Fraction of each step's translation.
    rotation_sigma : float
        Radians per step.
    rng : int or numpy.random.Generator
        Seed (every draw is seeded).

    Returns
    -------
    LaserLog
    """
    where = "simulated_odometry"
    if not isinstance(log, LaserLog):
        raise OptionTypeError(f"{where}: log must be a LaserLog; got {type(log).__name__}")
    translation_sigma = check_real(translation_sigma, "translation_sigma", where, minimum=0.0)
    rotation_sigma = check_real(rotation_sigma, "rotation_sigma", where, minimum=0.0)
    gen = check_rng(rng, where)
    u = np.zeros_like(log.reference)
    u[1:] = se2.between(log.reference[:-1], log.reference[1:])  # frame of scan k - 1
    n = gen.standard_normal((len(u) - 1, 3))  # the draws of lagolib.laser_world.simulate_log
    u[1:, :2] += n[:, :2] * (translation_sigma * np.hypot(u[1:, 0], u[1:, 1]))[:, None]
    u[1:, 2] = se2.wrap_angle(u[1:, 2] + rotation_sigma * n[:, 2])
    return log.with_odometry(u)
