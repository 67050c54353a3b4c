"""A simulated laser world: an office of rooms around a corridor ring, ray-cast exactly.

The offline stand-in for the Radish logs (:func:`lagolib.datasets.load_laser_or_simulated`) and the
test bench of scan matching and the front end: a :class:`World` is a set of wall segments (world
frame, metres), :func:`ray_cast` measures the exact range of every beam, :func:`trajectory` drives
a robot through the :func:`office` and :func:`simulate_log` turns it all into a
:class:`~lagolib.scans.LaserLog` whose ``reference`` poses are the ground truth.

The office (:func:`office`, 30 m x 18 m; ``][`` are doorways, ``#`` pilasters, furniture not
drawn)::

    y=18  +-------------+-------------+-------------+
          |   room A    |   room B    |   room C    |
          |             |             |             |
    y=12  +-----+----][-+---#--][--#--+-][----+-----+
          |     |     top corridor        |   |     |
    y=10  |     |  +----][-------#---#--+   |     |
          |  D  ][ |        hall        |   ][ E  |
          |     |  |                    |   |     |
    y=2   |     |  +--------------------+   +-----+
          |     |  bottom corridor: no features    exit, open
    y=0   +-----+-----------------------------------+
          x=0   5  7                    23  25    30

A corridor ring 2 m wide (centreline the rectangle ``[6, 24] x [1, 11]``) runs around a central
hall; six rooms open onto it through 1.2 m doorways.  Pilasters (0.4 m x 0.2 m boxes) stand out
of the corridor walls and desks, shelves and pillars furnish the rooms, so that scans constrain
all three degrees of freedom almost everywhere — except in **one** place: the **bottom corridor**
(``y`` in ``[0, 2]``, from ``x = 5`` to the building's open east exit at ``x = 30``) is 25 m of
two parallel walls without a doorway, a pilaster or anything else.  Driving along it (the route
does so twice, towards the exit), nothing ahead fixes the position along the corridor — the
beams that would leave through the exit — and scan matching is degenerate there: the corridor
case of :attr:`lagolib.scan_matching.Match.degeneracy` (measured on the default log: median
``λ_max / λ_min`` 52 between consecutive scans there, 2.6 elsewhere).

The world is **closed except for that exit** (``x = 30``, ``y`` in ``[0, 2]``), open to the
outside, where there is nothing.  A beam that leaves through it — and only such a beam, as long
as ``max_range`` exceeds every distance inside the building (26 m at most) — has no return and
reads ``max_range``, like the "no return" beams of a real log.  ``office(open_exit=False)``
closes it with a wall: then every beam returns.

Examples
--------
>>> import numpy as np
>>> from lagolib import laser_world
>>> world = laser_world.office()
>>> world.bounds()
(0.0, 0.0, 30.0, 18.0)
>>> # in the bottom corridor: 1 m to either wall, 5 m to its west end, nothing ahead (the exit)
>>> laser_world.ray_cast(world, [10.0, 1.0, 0.0], np.radians([90, -90, 180, 0])).tolist()
[1.0, 1.0, 5.0, 30.0]
>>> log = laser_world.simulate_log(rng=1)
>>> log
<LaserLog 'simulated office': 618 scans of 180 beams, max range 30 m>
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import se2
from .checks import check_bool, check_int, check_real, check_rng, real_array
from .errors import OptionError, OptionTypeError
from .scans import LaserLog, beam_angles

__all__ = ["World", "office", "ray_cast", "trajectory", "simulate_log"]

# rays x segments evaluated at once by ray_cast (bounds its memory to a few tens of MB)
_CHUNK = 1 << 20


@dataclass(frozen=True, eq=False)
class World:
    """A planar world of line-segment walls.

    Attributes
    ----------
    segments : ndarray, shape (s, 2, 2)
        Walls: ``segments[i] = [[x_a, y_a], [x_b, y_b]]``, world frame, metres.  Walls have no
        thickness; a ray is stopped by either side.
    name : str
    route : ndarray, shape (w, 2), or None
        Waypoints (world frame) of a path that keeps clear of every wall once its corners are
        rounded with a radius of 1.2 m (:func:`trajectory` drives it); None if the world has none.
    """

    segments: np.ndarray
    name: str = "world"
    route: np.ndarray | None = None

    def __post_init__(self):
        where = "World"
        seg = real_array(self.segments, "segments", where)
        if seg.ndim != 3 or seg.shape[1:] != (2, 2) or seg.shape[0] < 1:
            raise OptionError(
                f"{where}: segments must have shape (s, 2, 2), s >= 1 (two end points per "
                f"wall); got {seg.shape}"
            )
        if not np.all(np.isfinite(seg)):
            raise OptionError(
                f"{where}: segment {int(np.argwhere(~np.isfinite(seg))[0, 0])} is not finite"
            )
        length = np.hypot(*(seg[:, 1] - seg[:, 0]).T)
        if np.any(length == 0):
            raise OptionError(
                f"{where}: segment {int(np.argmin(length))} has zero length (both end points at "
                f"{seg[np.argmin(length), 0].tolist()})"
            )
        seg = seg.copy()
        seg.setflags(write=False)
        object.__setattr__(self, "segments", seg)
        if self.route is not None:
            route = real_array(self.route, "route", where)
            if route.ndim != 2 or route.shape[1] != 2 or route.shape[0] < 2:
                raise OptionError(
                    f"{where}: route must have shape (w, 2), w >= 2 waypoints; got {route.shape}"
                )
            if not np.all(np.isfinite(route)):
                raise OptionError(f"{where}: route is not finite")
            route = route.copy()
            route.setflags(write=False)
            object.__setattr__(self, "route", route)
        object.__setattr__(self, "name", str(self.name))

    def __repr__(self):
        x0, y0, x1, y1 = self.bounds()
        return (
            f"<World {self.name!r}: {len(self.segments)} walls in "
            f"[{x0:g}, {x1:g}] x [{y0:g}, {y1:g}] m>"
        )

    def bounds(self):
        """``(x_min, y_min, x_max, y_max)`` of the walls, world frame (metres)."""
        lo = self.segments.reshape(-1, 2).min(axis=0)
        hi = self.segments.reshape(-1, 2).max(axis=0)
        return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))


# ----------------------------------------------------------------------------- the office


def _box(x0, y0, x1, y1):
    """The four walls of the rectangle ``[x0, x1] x [y0, y1]``."""
    c = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    return [(c[i], c[(i + 1) % 4]) for i in range(4)]


def _wall(a, b, doors=()):
    """A straight wall from ``a`` to ``b`` (axis-parallel) with gaps ``(centre, width)``."""
    (xa, ya), (xb, yb) = a, b
    along = 0 if ya == yb else 1
    lo, hi = (xa, xb) if along == 0 else (ya, yb)
    cuts = [lo]
    for centre, width in sorted(doors):
        cuts += [centre - width / 2, centre + width / 2]
    cuts.append(hi)
    walls = []
    for s, e in zip(cuts[::2], cuts[1::2]):
        walls.append(((s, ya), (e, ya)) if along == 0 else ((xa, s), (xa, e)))
    return walls


def _pilaster(x, y, side):
    """A 0.4 m wide box standing 0.2 m out of a wall at ``(x, y)`` towards ``side`` (+x, -x, ...)."""
    h, d = 0.2, 0.2
    if side == "+x":
        return _box(x, y - h, x + d, y + h)
    if side == "-x":
        return _box(x - d, y - h, x, y + h)
    if side == "+y":
        return _box(x - h, y, x + h, y + d)
    return _box(x - h, y - d, x + h, y)


def _excursion(c, u, v, depth=4.0, back=1.5, width=2.5):
    """Waypoints of a visit to a room: from corridor point ``c`` (1 m before the door, the door
    on the line ``c + t u``) into the room, a loop ``width`` m to the side ``v``, and back to
    ``c``.  ``depth`` and ``back`` are the loop's far and near sides, metres past the door."""
    c, u, v = np.array(c, float), np.array(u, float), np.array(v, float)
    a, b = depth + 1.0, back + 1.0
    return [c, c + a * u, c + a * u + width * v, c + b * u + width * v, c + b * u, c]


_DOOR = 1.2  # doorway width, metres


def office(*, clutter=True, open_exit=True):
    """The simulated office: six rooms around a corridor ring, one featureless corridor.

    The layout is drawn in the module docstring: a 30 m x 18 m building, a 2 m wide corridor
    ring with centreline ``[6, 24] x [1, 11]`` around a central hall (16 m x 8 m), rooms A, B, C
    (10 m x 6 m) above it, D (5 m x 12 m) left of it and E (5 m x 10 m) right of it; every room
    has one 1.2 m doorway onto the corridor.  The bottom corridor (``y`` in ``[0, 2]``, 25 m
    from ``x = 5`` to the exit at ``x = 30``) is the one stretch without features.

    Parameters
    ----------
    clutter : bool
        Furnish the rooms (desks, shelves, pillars) and put pilasters on the corridor walls
        (except the bottom corridor's).  Without it the walls are plain.
    open_exit : bool
        Leave the bottom corridor's east end (``x = 30``, ``y`` in ``[0, 2]``) open to the
        outside: beams leaving through it have no return.  ``False`` closes it with a wall.

    Returns
    -------
    World
        Walls in the world frame (metres), named ``"office"``, with the route of
        :func:`trajectory` (two laps of the ring with an excursion into each room; every
        pose of it stays more than 0.5 m from every wall).

    Examples
    --------
    >>> w = office()
    >>> w
    <World 'office': 160 walls in [0, 30] x [0, 18] m>
    >>> len(office(clutter=False).segments)
    20
    """
    clutter = check_bool(clutter, "clutter", "office")
    open_exit = check_bool(open_exit, "open_exit", "office")
    d = _DOOR
    walls = []
    # the building's outline; the bottom corridor's east end (x = 30, y in [0, 2]) the exit
    walls += _wall((0, 0), (30, 0))
    walls += _wall((0, 18), (30, 18))
    walls += _wall((0, 0), (0, 18))
    walls += _wall((30, 2) if open_exit else (30, 0), (30, 18))
    # rooms A, B, C above the ring: their doorways onto the top corridor at x = 9, 15, 21
    walls += _wall((0, 12), (30, 12), [(9, d), (15, d), (21, d)])
    walls += _wall((10, 12), (10, 18))
    walls += _wall((20, 12), (20, 18))
    # room D left of the ring, room E right of it (above the bottom corridor): doorways at y = 6
    walls += _wall((5, 0), (5, 12), [(6, d)])
    walls += _wall((25, 2), (25, 12), [(6, d)])
    walls += _wall((25, 2), (30, 2))
    # the hall inside the ring, its doorway onto the top corridor at x = 12
    walls += _wall((7, 2), (23, 2))
    walls += _wall((7, 10), (23, 10), [(12, d)])
    walls += _wall((7, 2), (7, 10))
    walls += _wall((23, 2), (23, 10))
    if clutter:
        # pilasters on the corridor walls — none in the bottom corridor
        walls += _pilaster(13.5, 12, "-y") + _pilaster(18, 12, "-y")
        walls += _pilaster(17, 10, "+y") + _pilaster(20.5, 10, "+y")
        walls += _pilaster(5, 9, "+x") + _pilaster(5, 3, "+x")
        walls += _pilaster(7, 4.5, "-x") + _pilaster(7, 8, "-x")
        walls += _pilaster(25, 3, "-x") + _pilaster(25, 9, "-x")
        walls += _pilaster(23, 4, "+x") + _pilaster(23, 8, "+x")
        # furniture, clear of each room's visiting loop (see _excursion in office's route)
        furniture = [
            (1, 13, 3, 14),
            (1, 15.6, 3, 16.6),
            (4, 17.3, 8, 17.7),
            (4.5, 14.5, 4.9, 14.9),  # A
            (11, 14, 13, 15),
            (18.5, 13, 19.5, 14.5),
            (11, 17.3, 17, 17.7),  # B
            (12.8, 16.3, 13.2, 16.7),  # B's pillar
            (25, 13, 27, 14),
            (25, 15.5, 27, 16.5),
            (28.5, 12.5, 29.5, 17),  # C
            (22.5, 17, 22.9, 17.4),  # C's pillar
            (1, 9, 2.6, 9.8),
            (0.5, 0.3, 3, 0.9),
            (3.6, 1.6, 4, 2),  # D
            (26, 2.8, 27.6, 3.6),
            (28.5, 4, 29, 4.5),
            (26.5, 10, 28.5, 10.8),  # E
            (14.75, 5.75, 15.25, 6.25),
            (18.75, 5.75, 19.25, 6.25),  # the hall's columns
            (14, 3, 17, 4),
            (20, 7.5, 22, 9),
            (8, 3, 9.5, 4.5),  # the hall's tables
        ]
        for box in furniture:
            walls += _box(*box)
    # two laps of the ring, counter-clockwise from the left corridor, visiting every room
    route = [np.array([6.0, 9.5])]
    route += _excursion((6, 6), (-1, 0), (0, -1))  # D
    route += [np.array([6.0, 1.0]), np.array([24.0, 1.0])]
    route += _excursion((24, 6), (1, 0), (0, 1))  # E
    route += [np.array([24.0, 11.0])]
    route += _excursion((15, 11), (0, 1), (1, 0))  # B
    route += [np.array([6.0, 11.0]), np.array([6.0, 1.0]), np.array([24.0, 1.0])]
    route += [np.array([24.0, 11.0])]
    route += _excursion((21, 11), (0, 1), (1, 0))  # C
    route += _excursion((12, 11), (0, -1), (-1, 0))  # the hall
    route += _excursion((9, 11), (0, 1), (-1, 0))  # A
    route += [np.array([6.0, 11.0]), np.array([6.0, 3.5])]
    route = np.array([p for i, p in enumerate(route) if i == 0 or np.any(p != route[i - 1])])
    return World(np.array(walls, dtype=float), "office", route)


# ----------------------------------------------------------------------------- ray casting


def _check_world(world, where):
    if not isinstance(world, World):
        raise OptionTypeError(
            f"{where}: world must be a lagolib.laser_world.World (e.g. laser_world.office()); "
            f"got {type(world).__name__}"
        )
    return world


def _ray_args(world, poses, angles, max_range, where):
    _check_world(world, where)
    p = real_array(poses, "poses", where)
    single = p.ndim == 1
    p = np.atleast_2d(p)
    if p.ndim != 2 or p.shape[1] != 3:
        raise OptionError(
            f"{where}: poses must have shape (k, 3) or (3,) as (x, y, theta); got {np.shape(poses)}"
        )
    if not np.all(np.isfinite(p)):
        raise OptionError(f"{where}: pose {int(np.argwhere(~np.isfinite(p))[0, 0])} is not finite")
    a = real_array(angles, "angles", where)
    if a.ndim != 1 or a.size < 1 or not np.all(np.isfinite(a)):
        raise OptionError(
            f"{where}: angles must be a non-empty 1-D array of finite beam angles (radians); "
            f"got shape {a.shape}"
        )
    max_range = check_real(max_range, "max_range", where, minimum=0.0, strict=True)
    return p, a, max_range, single


def ray_cast(world, poses, angles, max_range=30.0):
    """Exact ranges of the beams ``angles`` from the sensor poses ``poses`` to the walls.

    A beam from ``p`` with world-frame direction ``d = (cos(θ + α), sin(θ + α))`` hits the wall
    from ``a`` to ``b`` (``e = b - a``, ``w = a - p``) where ``p + t d = a + s e``; by Cramer's
    rule (the ray–segment intersection of computational geometry, e.g. O'Rourke 1998, §7.2)::

        t = (w × e) / (d × e),    s = (w × d) / (d × e),    hit iff t > 0 and 0 <= s <= 1

    with ``×`` the planar cross product.  The range is the smallest ``t`` over the walls, or
    ``max_range`` when no wall is hit before ``max_range`` (a beam parallel to a wall does not
    hit it).  Vectorized over scans x beams x walls, in chunks of about a million rays x walls.

    Parameters
    ----------
    world : World
    poses : array_like, shape (k, 3) or (3,)
        Sensor poses ``(x, y, θ)`` in the world frame.
    angles : array_like, shape (n,)
        Beam angles in the sensor frame (radians).
    max_range : float
        The sensor's range, > 0.

    Returns
    -------
    ndarray, shape (k, n) (or (n,) for one pose)
        Ranges in metres, in ``(0, max_range]``.

    Examples
    --------
    >>> room = World(np.array([[[-2, -1], [2, -1]], [[2, -1], [2, 1]],
    ...                        [[2, 1], [-2, 1]], [[-2, 1], [-2, -1]]], float))
    >>> ray_cast(room, [0.0, 0.0, 0.0], np.radians([0, 90, 180, 45])).round(12).tolist()
    [2.0, 1.0, 2.0, 1.414213562373]
    """
    p, a, max_range, single = _ray_args(world, poses, angles, max_range, "ray_cast")
    seg = world.segments
    A, E = seg[:, 0], seg[:, 1] - seg[:, 0]  # (s, 2): a and e = b - a, world frame
    k, n, s = len(p), len(a), len(seg)
    out = np.empty((k, n))
    step = max(1, _CHUNK // (n * s))
    with np.errstate(divide="ignore", invalid="ignore"):
        for lo in range(0, k, step):
            P = p[lo : lo + step]
            W = A[None] - P[:, None, :2]  # (c, s, 2): w = a - p
            t_num = W[..., 0] * E[:, 1] - W[..., 1] * E[:, 0]  # (c, s): w × e
            phi = P[:, 2:3] + a  # (c, n): beam directions in the world frame
            dx, dy = np.cos(phi)[..., None], np.sin(phi)[..., None]  # (c, n, 1)
            den = dx * E[:, 1] - dy * E[:, 0]  # (c, n, s): d × e
            s_par = (W[:, None, :, 0] * dy - W[:, None, :, 1] * dx) / den  # (w × d) / (d × e)
            t = t_num[:, None, :] / den  # (w × e) / (d × e)
            hit = (s_par >= 0) & (s_par <= 1) & (t > 0)
            r = np.where(hit, t, np.inf).min(axis=-1)
            out[lo : lo + step] = np.minimum(r, max_range)
    return out[0] if single else out


def _ray_cast_loop(world, poses, angles, max_range=30.0):
    """:func:`ray_cast` one beam and one wall at a time: the readable reference it is tested
    against.  Same arguments and result."""
    p, a, max_range, single = _ray_args(world, poses, angles, max_range, "_ray_cast_loop")
    out = np.full((len(p), len(a)), max_range)
    for i, (x, y, theta) in enumerate(p):
        for j, alpha in enumerate(a):
            dx, dy = math.cos(theta + alpha), math.sin(theta + alpha)
            for (ax, ay), (bx, by) in world.segments:
                ex, ey, wx, wy = bx - ax, by - ay, ax - x, ay - y
                den = dx * ey - dy * ex  # d × e
                if den == 0:
                    continue  # parallel: no hit
                t = (wx * ey - wy * ex) / den  # (w × e) / (d × e)
                s = (wx * dy - wy * dx) / den  # (w × d) / (d × e)
                if t > 0 and 0 <= s <= 1 and t < out[i, j]:
                    out[i, j] = t
    return out[0] if single else out


# ----------------------------------------------------------------------------- the trajectory


def _fillet_path(route, radius):
    """Pieces of the route with its corners rounded: lines ``(start, direction, length)`` and
    arcs ``(centre, start_angle, sign, radius, length, heading0)``."""
    P = np.asarray(route, float)
    D = np.diff(P, axis=0)
    L = np.hypot(D[:, 0], D[:, 1])
    if np.any(L == 0):
        raise OptionError("trajectory: the route repeats a waypoint")
    U = D / L[:, None]
    heading = np.arctan2(U[:, 1], U[:, 0])
    turn = se2.wrap_angle(np.diff(heading))  # (w - 2,) turn at each interior waypoint
    if np.any(np.abs(turn) > math.radians(179)):
        raise OptionError("trajectory: the route turns back on itself; add a waypoint")
    cut = radius * np.tan(np.abs(turn) / 2)  # tangent length of each corner's arc
    used = np.concatenate([[0.0], cut]) + np.concatenate([cut, [0.0]])
    if np.any(used > L + 1e-9):
        i = int(np.argmax(used - L))
        raise OptionError(
            f"trajectory: the route's leg {i} ({L[i]:.3g} m) is too short for corners of radius "
            f"{radius:g} m at both ends; use a smaller turn_radius or longer legs"
        )
    pieces = []
    start = P[0]
    for i in range(len(L)):
        end_cut = cut[i] if i < len(cut) else 0.0
        end = P[i + 1] - end_cut * U[i]
        length = float(np.dot(end - start, U[i]))
        if length > 1e-12:
            pieces.append(("line", start, U[i], length, heading[i]))
        if i < len(cut) and turn[i] != 0:
            sign = math.copysign(1.0, turn[i])
            normal = np.array([-U[i, 1], U[i, 0]]) * sign  # towards the corner's centre
            centre = end + radius * normal
            phi0 = math.atan2(end[1] - centre[1], end[0] - centre[0])
            pieces.append(("arc", centre, (phi0, sign), radius * abs(turn[i]), heading[i]))
            start = P[i + 1] + cut[i] * U[i + 1]
        else:
            start = end
    return pieces


def trajectory(world=None, *, step=0.3, turn_radius=1.2):
    """Ground-truth poses of a robot driving the world's route (deterministic).

    The route's corners are rounded with circular arcs of radius ``turn_radius`` and the path
    is sampled every ``step`` metres of arc length; the heading is the path's tangent.  So
    consecutive poses are exactly ``step`` apart along the path, and the heading changes by at
    most ``step / turn_radius`` radians per step (14.3° with the defaults).  The office's route
    (:func:`office`) drives two laps of the corridor ring — loop closures — with an excursion
    through the doorway of each of its six rooms, never through a wall: 618 poses.

    Parameters
    ----------
    world : World, optional
        Default :func:`office`.  It must have a ``route``.
    step : float
        Metres between consecutive poses along the path, > 0.
    turn_radius : float
        Radius of the rounded corners, > 0.  The office's route is checked with 1.2 m.

    Returns
    -------
    ndarray, shape (k, 3)
        World-frame poses ``(x, y, θ)``, ``θ`` in ``(-π, π]``.

    Examples
    --------
    >>> x = trajectory()
    >>> x.shape, x[0].tolist()
    ((618, 3), [6.0, 9.5, -1.5707963267948966])
    >>> float(np.hypot(*np.diff(x[:, :2], axis=0).T).max().round(6))
    0.3
    """
    where = "trajectory"
    world = office() if world is None else _check_world(world, where)
    step = check_real(step, "step", where, minimum=0.0, strict=True)
    turn_radius = check_real(turn_radius, "turn_radius", where, minimum=0.0, strict=True)
    if world.route is None:
        raise OptionError(
            f"trajectory: world {world.name!r} has no route; give World(..., route=waypoints) "
            "or pass your own poses to simulate_log"
        )
    pieces = _fillet_path(world.route, turn_radius)
    lengths = np.array([pc[3] for pc in pieces])
    starts = np.concatenate([[0.0], np.cumsum(lengths)])
    s = np.arange(0.0, starts[-1] + 1e-9, step)
    which = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(pieces) - 1)
    poses = np.empty((len(s), 3))
    for i, piece in enumerate(pieces):  # a Python loop over the ~100 pieces, not over poses
        m = which == i
        local = s[m] - starts[i]
        if piece[0] == "line":
            _, p0, u, _, h = piece
            poses[m, 0] = p0[0] + local * u[0]
            poses[m, 1] = p0[1] + local * u[1]
            poses[m, 2] = h
        else:
            _, centre, (phi0, sign), _, h = piece
            phi = phi0 + sign * local / turn_radius
            poses[m, 0] = centre[0] + turn_radius * np.cos(phi)
            poses[m, 1] = centre[1] + turn_radius * np.sin(phi)
            poses[m, 2] = h + sign * local / turn_radius
    poses[:, 2] = se2.wrap_angle(poses[:, 2])
    return poses


# ----------------------------------------------------------------------------- the log

# the simulated odometry: 5 % of the translation, 2° per step
_ODOMETRY_SIGMA = (0.05, math.radians(2.0))


def simulate_log(
    world=None,
    *,
    poses=None,
    n_beams=180,
    fov=math.pi,
    max_range=30.0,
    range_sigma=0.01,
    odometry_sigma=_ODOMETRY_SIGMA,
    heading_bias=0.0,
    rng=0,
    name="simulated office",
):
    """A simulated laser log: exact scans plus noise, true poses, noisy odometry increments.

    For true poses ``x_k`` (world frame) the log holds

    * ``reference = x_k`` and ``reference_kind = "truth"``;
    * ``ranges = ray_cast(world, x_k, angles, max_range) + N(0, range_sigma²)`` for the beams
      that hit a wall, clipped to ``(0, max_range]``; beams that hit nothing within
      ``max_range`` (out through the office's exit) read exactly ``max_range``: no return;
    * odometry increments ``u_k = (x_k ⊖ x_{k-1}) + ε_k`` (``u_0 = 0``; frame of scan ``k - 1``)
      with ``ε_k = (N(0, σ_xy²), N(0, σ_xy²), b |t_k| + N(0, σ_θ²))`` where ``|t_k|`` is the
      length of the true step's translation, ``σ_xy = odometry_sigma[0] * |t_k|`` (5 % of the
      translation by default), ``σ_θ = odometry_sigma[1]`` per step (2° by default) and
      ``b = heading_bias`` radians per metre driven (INTEL's real odometry turns about
      ``math.radians(-3.9)`` per metre);
    * beam angles ``scans.beam_angles(n_beams, fov)`` (from ``-fov/2``), timestamps 0.5 s apart.

    The odometry noise is drawn first (``(k - 1, 3)`` standard normals), then the range noise
    (``(k, n_beams)``), from one generator: a seed gives the same log every time.  The default
    log (the office, its 618-pose trajectory, 180 beams) takes about 0.2 s.

    Parameters
    ----------
    world : World, optional
        Default :func:`office`.
    poses : array_like, shape (k, 3), optional
        True sensor poses in the world frame; default ``trajectory(world)``.
    n_beams : int
        Beams per scan, >= 2.
    fov : float
        Field of view in radians, in ``(0, 2π)``.
    max_range : float
        The sensor's range (metres), > 0.
    range_sigma : float
        Standard deviation of the range noise (metres), >= 0.
    odometry_sigma : (float, float)
        ``(fraction of the translation, radians per step)``, each >= 0.
    heading_bias : float
        Systematic heading error of the odometry, radians per metre.
    rng : int or numpy.random.Generator
        Seed (default 0) or generator.
    name : str

    Returns
    -------
    LaserLog
        ``min_range = 0``; ``timestamps = 0.5 k`` seconds.

    Examples
    --------
    >>> log = simulate_log(rng=3)
    >>> log.reference_kind, log.ranges.shape
    ('truth', (618, 180))
    >>> exact = simulate_log(range_sigma=0.0, odometry_sigma=(0.0, 0.0))
    >>> err = se2.between(exact.reference, exact.odometry_poses())  # chained = the truth
    >>> bool(np.abs(err).max() < 1e-12)
    True
    """
    where = "simulate_log"
    world = office() if world is None else _check_world(world, where)
    if poses is None:
        poses = trajectory(world)
    x = real_array(poses, "poses", where)
    if x.ndim != 2 or x.shape[1] != 3 or x.shape[0] < 1:
        raise OptionError(f"{where}: poses must have shape (k, 3), k >= 1; got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise OptionError(f"{where}: pose {int(np.argwhere(~np.isfinite(x))[0, 0])} is not finite")
    n_beams = check_int(n_beams, "n_beams", where, minimum=2)
    fov = check_real(fov, "fov", where, minimum=0.0, maximum=2 * math.pi, strict=True)
    max_range = check_real(max_range, "max_range", where, minimum=0.0, strict=True)
    range_sigma = check_real(range_sigma, "range_sigma", where, minimum=0.0)
    sig = real_array(odometry_sigma, "odometry_sigma", where)
    if sig.shape != (2,):
        raise OptionError(
            f"{where}: odometry_sigma must be a pair (fraction of the translation, radians per "
            f"step); got {odometry_sigma!r}"
        )
    frac = check_real(float(sig[0]), "odometry_sigma[0]", where, minimum=0.0)
    sigma_theta = check_real(float(sig[1]), "odometry_sigma[1]", where, minimum=0.0)
    heading_bias = check_real(heading_bias, "heading_bias", where)
    gen = check_rng(rng, where)

    k = len(x)
    angles = beam_angles(n_beams, fov)
    u = np.zeros((k, 3))
    u[1:] = se2.between(x[:-1], x[1:])  # the true increments, frame of scan k - 1
    dist = np.hypot(u[1:, 0], u[1:, 1])  # |t_k|
    z = gen.standard_normal((k - 1, 3))
    u[1:, :2] += z[:, :2] * (frac * dist)[:, None]  # σ_xy = 5 % of the translation
    u[1:, 2] += heading_bias * dist + sigma_theta * z[:, 2]  # b |t_k| + N(0, σ_θ²)
    u[:, 2] = se2.wrap_angle(u[:, 2])

    exact = ray_cast(world, x, angles, max_range)
    hit = exact < max_range
    ranges = exact + range_sigma * gen.standard_normal(exact.shape)
    ranges = np.where(hit, np.clip(ranges, 1e-6, max_range), max_range)
    return LaserLog(ranges, angles, max_range, 0.0, x, "truth", u, 0.5 * np.arange(k), str(name))
