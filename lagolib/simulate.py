"""Synthetic worlds: a robot drives, measures its motion and recognises places it has seen.

Each world returns a :class:`Simulation`: the noisy :class:`~lagolib.graph.PoseGraph` (its poses
are the odometry guess — the noisy odometry composed from the true first pose) and the ground-truth
poses.  Everything random comes from one ``numpy.random.Generator`` (pass a seed or a Generator as
``rng``), so a world is reproducible from its seed.

Measurements follow Carlone et al. 2011, §III: ``xi_ij = (p_j ⊖ p_i) + eps_ij`` with
``eps_ij ~ N(0, P_ij)``, and two noise models (§V):

* ``noise="fixed"``: ``P_ij = diag(sigma_xy², sigma_xy², sigma_theta²)`` on every edge;
* ``noise="proportional"``: "uncertainties proportional to the respective measurements" —
  ``sigma = sigma_xy * max(|dρ|, floor)`` for the position and
  ``sigma_theta * max(|dθ|, floor)`` for the angle, so longer motions are less certain.

Translation noise is isotropic on every edge, so the information matrix is the same whether the
error is written in frame ``i`` or in the measurement's frame (TORO and g2o agree).

Wrong loop closures — outliers — are added to any graph by :func:`add_outliers`, which returns an
:class:`Outliers` (the spoiled graph and a mask of its wrong edges).  It reproduces the four
policies of the Vertigo benchmark suite (Sünderhauf & Protzel, "Switchable constraints for robust
pose graph SLAM", IROS 2012; the suite's ``datasets/generateDataset.py``): ``"random"``,
``"local"``, ``"random-grouped"`` and ``"local-grouped"`` — groups of wrong closures that agree
with each other, the hard case for robust back ends.

References
----------
.. [1] N. Sünderhauf, P. Protzel, "Switchable constraints for robust pose graph SLAM", IEEE/RSJ
   IROS 2012; Vertigo, https://github.com/OpenSLAM-org/openslam_vertigo (generateDataset.py).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from . import se2
from .checks import check_bool, check_choice, check_int, check_real, check_rng, real_array
from .errors import GraphError, OptionError
from .graph import PoseGraph, check_graph, describe_bad_information, first_bad_information

__all__ = [
    "Simulation",
    "measure",
    "loop_world",
    "manhattan_world",
    "grid_world",
    "Outliers",
    "add_outliers",
    "OUTLIER_POLICIES",
    "OUTLIER_SIGMA",
]


@dataclass(frozen=True)
class Simulation:
    """A simulated pose graph and the truth it was measured from.

    Attributes
    ----------
    graph : PoseGraph
        Noisy measurements; ``graph.poses`` is the odometry guess.
    truth : ndarray, shape (n, 3)
        Ground-truth poses, angles wrapped to ``(-pi, pi]``.
    """

    graph: PoseGraph
    truth: np.ndarray


def _sigmas(value, name, where, m):
    """Per-edge standard deviations: finite, > 0, one value or one per edge (shape (m,))."""
    a = real_array(value, name, where)
    if a.ndim > 1 or (a.ndim == 1 and a.shape != (m,)):
        raise OptionError(
            f"{where}: {name} must be one number or {m} (one per edge); got {a.shape}"
        )
    if not np.all(np.isfinite(a) & (a > 0)):
        flat = a.ravel()
        bad = float(flat[~(np.isfinite(flat) & (flat > 0))][0])
        raise OptionError(
            f"{where}: {name} must be positive and finite (use noiseless=True for exact data); "
            f"got {bad!r}"
        )
    return np.broadcast_to(a, (m,))


def measure(
    truth,
    edges,
    *,
    rng=0,
    sigma_xy=0.05,
    sigma_theta=0.01,
    noise="fixed",
    floor=0.1,
    noiseless=False,
):
    """Measure ``edges`` between ``truth`` poses with Gaussian noise; returns a :class:`Simulation`.

    Parameters
    ----------
    truth : array_like, shape (n, 3)
    edges : array_like of int, shape (m, 2)
        ``(i, j)``: measure pose ``j`` in the frame of ``i``.
    rng : int or numpy.random.Generator
    sigma_xy, sigma_theta : float or array_like of shape (m,)
        Standard deviations (``"fixed"``), or per metre / per radian (``"proportional"``); one
        value for all edges or one per edge.
    noise : {"fixed", "proportional"}
    floor : float
        Smallest motion used to scale the ``"proportional"`` noise (keeps straight motions from
        having infinite rotational information).
    noiseless : bool
        Keep the information matrices of the noise model but add no noise (for exact-recovery
        tests).

    Returns
    -------
    Simulation
    """
    where = "measure"
    rng = check_rng(rng, where)
    noise = check_choice(noise, "noise", where, ("fixed", "proportional"))
    floor = check_real(floor, "floor", where, minimum=0.0, strict=True)
    noiseless = check_bool(noiseless, "noiseless", where)
    if np.iscomplexobj(truth):
        raise GraphError(f"{where}: truth must be real; got a complex array")
    truth = np.asarray(truth, dtype=float)
    if truth.ndim != 2 or truth.shape[1] != 3:
        raise GraphError(f"{where}: truth must have shape (n, 3); got {truth.shape}")
    bad = np.flatnonzero(~np.all(np.isfinite(truth), axis=1))
    if bad.size:
        raise GraphError(f"{where}: truth pose {bad[0]} is not finite: {truth[bad[0]].tolist()}")
    edges = np.asarray(edges)
    if edges.size and edges.dtype.kind not in "iu":
        raise GraphError(f"{where}: edges must be integer vertex indices; got dtype {edges.dtype}")
    edges = edges.astype(np.int64).reshape(-1, 2)
    out = np.flatnonzero(np.any((edges < 0) | (edges >= len(truth)), axis=1))
    if out.size:
        raise GraphError(
            f"{where}: edge {out[0]} refers to pose {edges[out[0]].tolist()} but truth has "
            f"{len(truth)} poses",
            edge=int(out[0]),
        )
    z = se2.between(truth[edges[:, 0]], truth[edges[:, 1]])  # p_j ⊖ p_i, Carlone eq. (1)
    m = len(edges)
    sigma_xy = _sigmas(sigma_xy, "sigma_xy", where, m)
    sigma_theta = _sigmas(sigma_theta, "sigma_theta", where, m)
    if noise == "fixed":
        sxy, sth = sigma_xy.copy(), sigma_theta.copy()
    else:
        sxy = sigma_xy * np.maximum(np.hypot(z[:, 0], z[:, 1]), floor)
        sth = sigma_theta * np.maximum(np.abs(z[:, 2]), floor)
    sigma = np.column_stack([sxy, sxy, sth])
    eps = rng.standard_normal((m, 3)) * sigma
    if not noiseless:
        z = z + eps
        z[:, 2] = se2.wrap_angle(z[:, 2])
    information = np.zeros((m, 3, 3))
    information[:, [0, 1, 2], [0, 1, 2]] = 1.0 / sigma**2
    start = PoseGraph(np.tile(truth[0], (len(truth), 1)), edges, z, information)
    graph = start.with_poses(start.odometry_guess())
    truth = truth.copy()
    truth[:, 2] = se2.wrap_angle(truth[:, 2])
    return Simulation(graph, truth)


def _drive(controls, start=(0.0, 0.0, 0.0)):
    """Compose relative motions ``u_k`` from ``start``: ``x_{k+1} = x_k ⊕ u_k``; shape (K+1, 3)."""
    poses = [np.asarray(start, dtype=float)]
    for u in controls:
        poses.append(se2.compose(poses[-1], u))
    return np.array(poses)


def loop_world(
    *, laps=4, poses_per_lap=40, shape="square", step=1.0, closure_probability=1.0, rng=0, **noise
):
    """A robot driving the same closed loop several times.

    Pose ``k`` (``k >= poses_per_lap``) sees the place of pose ``k - poses_per_lap`` again; each
    such loop closure is kept with ``closure_probability``.  After several laps the robot's
    accumulated heading has grown by ``2 pi`` per lap while every loop closure measures a small
    angle — the wraparound that LAGO's regularization handles (Carlone et al. 2011, §IV-E).

    Parameters
    ----------
    laps : int
    poses_per_lap : int
        For ``shape="square"`` a multiple of 4.
    shape : {"square", "circle"}
        ``"square"``: straight sides, a left turn of ``pi/2`` at each corner; ``"circle"``: a regular
        polygon, turning ``2 pi / poses_per_lap`` at every pose.
    step : float
        Distance between consecutive poses.
    closure_probability : float
    rng : int or numpy.random.Generator
    **noise
        ``sigma_xy``, ``sigma_theta``, ``noise``, ``floor``, ``noiseless``: see :func:`measure`.

    Returns
    -------
    Simulation
        ``laps * poses_per_lap`` poses.
    """
    where = "loop_world"
    rng = check_rng(rng, where)
    laps = check_int(laps, "laps", where, minimum=1)
    poses_per_lap = check_int(poses_per_lap, "poses_per_lap", where, minimum=2)
    shape = check_choice(shape, "shape", where, ("square", "circle"))
    step = check_real(step, "step", where, minimum=0.0, strict=True)
    closure_probability = check_real(
        closure_probability, "closure_probability", where, minimum=0.0, maximum=1.0
    )
    n = laps * poses_per_lap
    if shape == "square":
        if poses_per_lap % 4:
            raise OptionError(
                f"{where}: a square loop needs poses_per_lap divisible by 4; got {poses_per_lap}"
            )
        side = poses_per_lap // 4
        turn = np.where((np.arange(n - 1) + 1) % side == 0, np.pi / 2, 0.0)
    else:
        turn = np.full(n - 1, 2 * np.pi / poses_per_lap)
    controls = np.column_stack([np.full(n - 1, step), np.zeros(n - 1), turn])
    truth = _drive(controls)
    odo = np.column_stack([np.arange(n - 1), np.arange(1, n)])
    later = np.arange(poses_per_lap, n)
    keep = rng.random(later.size) < closure_probability
    loops = np.column_stack([later[keep] - poses_per_lap, later[keep]])
    return measure(truth, np.vstack([odo, loops]), rng=rng, **noise)


# Lattice headings of manhattan_world: east, north, west, south (index h), and their unit moves.
_HEADINGS = np.array([0.0, np.pi / 2, np.pi, -np.pi / 2])
_UNIT = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]], dtype=np.int64)
# Candidate pairs (or offset-by-pose lookups) held in memory at once by _closure_pairs.
_CHUNK = 1 << 20


def _lattice_walk(n_poses, extent, turn_probability, rng):
    """Headings ``h_k`` (indices into ``_HEADINGS``) of :func:`manhattan_world`'s walk; shape (n,).

    Pose 0 stands at lattice point ``(0, 0)`` heading east; pose ``k`` is pose ``k - 1`` moved one
    lattice step along ``h_{k-1}``.  Its heading is ``h_{k-1}`` turned left (``r < p/2``), right
    (``p/2 <= r < p``) or kept, with ``r`` the step's uniform draw and ``p`` the
    ``turn_probability``; if the next move would then leave the ``extent × extent`` lattice the
    first of (that heading, a left turn, a right turn, a U-turn from it) that stays inside is
    taken.  The ``n - 1`` draws are one ``rng.random(n - 1)`` — bit-identical to one
    ``rng.random()`` per step for every numpy bit generator.  The turn back is sequential, so the
    walk is a loop, kept to a few Python integer operations and table look-ups per step.
    """
    r = rng.random(n_poses - 1)
    turns = np.where(r < turn_probability / 2, 1, np.where(r < turn_probability, 3, 0)).tolist()
    # A coordinate's place on the lattice — low edge, inside, high edge: 0, 1, 2 — is stored
    # pre-scaled (x by 12, y by 4) so that bx[x] + by[y] + h indexes a table of the heading taken
    # at such a place by a robot that wants to go along h.  Coordinates stay below
    # min(extent, n_poses), so the lists are never longer than the walk.
    size = min(extent, n_poses)
    bx, by = [12] * size, [4] * size
    bx[0] = by[0] = 0
    if extent <= size:
        bx[extent - 1], by[extent - 1] = 24, 8
    leaves = {0: -1, 1: None, 2: 1}  # the move that would leave the lattice from each place
    table = []
    for xplace, yplace, h in itertools.product(range(3), range(3), range(4)):
        for cand in (h, (h + 1) % 4, (h - 1) % 4, (h + 2) % 4):
            dx, dy = _UNIT[cand].tolist()
            if dx != leaves[xplace] and dy != leaves[yplace]:
                table.append(cand)
                break
    dxs, dys = _UNIT[:, 0].tolist(), _UNIT[:, 1].tolist()
    x = y = h = 0
    hs = [0] * n_poses
    for k, turn in enumerate(turns, 1):
        x += dxs[h]
        y += dys[h]
        h = table[bx[x] + by[y] + ((h + turn) & 3)]
        hs[k] = h
    return np.array(hs, dtype=np.intp)


def _closure_candidates(lattice, step, closure_radius, min_separation):
    """Pose pairs ``j <= k - min_separation`` whose lattice points may lie within the radius.

    A superset of the pairs :func:`manhattan_world` tests, found by spatial hashing instead of
    comparing every pair: lattice points are grouped in square blocks of ``s × s`` points (``s = 1``
    unless the radius spans many lattice steps), and pose ``k`` is paired with the earlier poses
    in the blocks whose nearest points are within ``closure_radius`` (plus a margin far above the
    rounding of ``cells``) of ``k``'s block.  Yields ``(k, j)``, two int64 arrays, in chunks of at
    most about ``_CHUNK`` pairs (one ``k`` may exceed it), ordered by ``k`` then ``j`` across all
    chunks.

    Parameters
    ----------
    lattice : ndarray of int64, shape (n, 2)
        Non-negative lattice coordinates of the poses.
    step, closure_radius : float
    min_separation : int
    """
    n = len(lattice)
    if n <= min_separation:
        return
    top = int(lattice.max())
    # |fl(a*step) - fl(b*step)| is a*step - b*step to within ~3e-16 * step * top (plus underflow)
    reach = closure_radius + 1e-9 * (closure_radius + step * (top + 1)) + 1e-300
    ratio = reach / step  # lattice steps; may be inf
    block = top + 1 if ratio >= 4 * (top + 1) else max(1, math.ceil(ratio / 4))
    blocks = lattice // block
    # offsets (ox, oy) between blocks whose closest lattice points are within reach
    span = int(blocks.max())
    side = span if ratio >= block * span else min(span, math.ceil(ratio / block) + 1)
    o = np.arange(-side, side + 1)
    ox, oy = (a.ravel() for a in np.meshgrid(o, o, indexing="ij"))
    near = np.maximum(np.abs(ox) * block - (block - 1), 0)
    far = np.maximum(np.abs(oy) * block - (block - 1), 0)
    keep = np.hypot(near, far) * step <= reach
    offsets = np.column_stack([ox[keep], oy[keep]])
    # blocks as dense ids; poses sorted by (block id, pose index) as one int64 key
    width = int(blocks[:, 1].max()) + 1
    block_key = blocks[:, 0] * width + blocks[:, 1]
    keys, block_id = np.unique(block_key, return_inverse=True)
    by_block = np.sort(block_id.ravel() * n + np.arange(n))
    pose_of = by_block % n
    per_chunk = max(1, _CHUNK // len(offsets))
    for k0 in range(min_separation, n, per_chunk):
        k = np.arange(k0, min(n, k0 + per_chunk))
        # target block of every (k, offset), k-major; blocks outside the walk's box hold no pose
        tx = blocks[k, 0][:, None] + offsets[:, 0]
        ty = blocks[k, 1][:, None] + offsets[:, 1]
        inside = (tx >= 0) & (tx <= span) & (ty >= 0) & (ty < width)
        target = np.where(inside, tx * width + ty, -1)
        at = np.minimum(np.searchsorted(keys, target), len(keys) - 1)
        found = inside & (keys[at] == target)
        start = np.searchsorted(by_block, at * n)
        stop = np.searchsorted(by_block, at * n + (k - min_separation)[:, None], side="right")
        count = np.where(found, stop - start, 0)
        # split this block of k into pieces of at most about _CHUNK candidates
        total = np.cumsum(count.sum(axis=1))
        cuts = np.searchsorted(total, np.arange(_CHUNK, total[-1], _CHUNK), side="right")
        edges = np.unique(np.concatenate([[0], cuts, [len(k)]]))
        for a, b in zip(edges[:-1].tolist(), edges[1:].tolist()):
            c = count[a:b].ravel()
            if not c.any():
                continue
            first = start[a:b].ravel()
            kk = np.repeat(np.repeat(k[a:b], len(offsets)), c)
            before = np.cumsum(c) - c
            pos = np.arange(int(c.sum())) - np.repeat(before - first, c)
            pair = np.sort(kk * n + pose_of[pos])
            yield pair // n, pair % n


def _closure_pairs(lattice, cells, step, closure_radius, closure_probability, min_separation, rng):
    """Loop closures ``(j, k)`` of :func:`manhattan_world`, shape (c, 2), ordered by ``k`` then ``j``.

    Every pair ``j <= k - min_separation`` with ``hypot(*(cells[j] - cells[k])) <=
    closure_radius`` draws one ``rng.random()``, in order of ``k`` then ``j``, and is kept when the
    draw is below ``closure_probability``.  The candidates come from
    :func:`_closure_candidates` (a superset) and are filtered with that same float test on the same
    ``cells``; each chunk's draws are one ``rng.random(size)`` call, bit-identical to successive
    scalar draws.  Time and memory grow with ``n`` plus the number of candidates, not ``n²``.
    """
    found = []
    for k, j in _closure_candidates(lattice, step, closure_radius, min_separation):
        d = cells[j] - cells[k]
        close = np.hypot(d[:, 0], d[:, 1]) <= closure_radius
        j, k = j[close], k[close]
        keep = rng.random(len(j)) < closure_probability
        found.append(np.column_stack([j[keep], k[keep]]))
    return np.vstack(found) if found else np.zeros((0, 2), dtype=np.int64)


def manhattan_world(
    *,
    n_poses=200,
    extent=6,
    step=1.0,
    turn_probability=0.3,
    closure_radius=0.5,
    closure_probability=0.5,
    min_separation=10,
    rng=0,
    **noise,
):
    """A random walk on a square lattice with loop closures at revisited places (after Olson's M3500).

    At every pose the robot moves ``step`` forward and then keeps its heading or turns by
    ``±pi/2`` (each turn with probability ``turn_probability / 2``), turning back when the next
    move would leave the ``extent × extent`` lattice.  When it stands within ``closure_radius``
    of an earlier pose at least ``min_separation`` poses back, a loop closure from that earlier
    pose is added with ``closure_probability``.

    Parameters
    ----------
    n_poses : int
    extent : int
        Lattice points per side.
    step : float
    turn_probability, closure_radius, closure_probability : float
    min_separation : int
    rng : int or numpy.random.Generator
    **noise
        See :func:`measure`.

    Returns
    -------
    Simulation

    Notes
    -----
    Time and memory grow with ``n_poses`` plus the number of pose pairs within
    ``closure_radius`` (each draws one random number), not with ``n_poses²``: the walk is a
    table-driven loop and earlier poses near pose ``k`` are found by spatial hashing.  With the
    default closure options, ``extent = int(sqrt(n_poses / 2.6))`` gives about 1.8 edges per pose
    (1.76–1.88 for ``rng=0`` from 1e3 to 1e6 poses).
    """
    where = "manhattan_world"
    rng = check_rng(rng, where)
    n_poses = check_int(n_poses, "n_poses", where, minimum=2)
    extent = check_int(extent, "extent", where, minimum=2)
    step = check_real(step, "step", where, minimum=0.0, strict=True)
    turn_probability = check_real(
        turn_probability, "turn_probability", where, minimum=0.0, maximum=1.0
    )
    closure_radius = check_real(closure_radius, "closure_radius", where, minimum=0.0)
    closure_probability = check_real(
        closure_probability, "closure_probability", where, minimum=0.0, maximum=1.0
    )
    min_separation = check_int(min_separation, "min_separation", where, minimum=1)
    hs = _lattice_walk(n_poses, extent, turn_probability, rng)
    lattice = np.zeros((n_poses, 2), dtype=np.int64)
    np.cumsum(_UNIT[hs[:-1]], axis=0, out=lattice[1:])
    cells = lattice.astype(float) * step
    truth = np.column_stack([cells, _HEADINGS[hs]])
    pairs = _closure_pairs(
        lattice, cells, step, closure_radius, closure_probability, min_separation, rng
    )
    odo = np.column_stack([np.arange(n_poses - 1), np.arange(1, n_poses)])
    edges = np.vstack([odo, pairs])
    return measure(truth, edges, rng=rng, **noise)


def grid_world(
    *,
    rows=10,
    cols=10,
    step=1.0,
    closure_probability=0.5,
    closure_noise=1.0,
    sigma_xy=0.05,
    sigma_theta=0.01,
    rng=0,
    **noise,
):
    """A robot sweeping a ``rows × cols`` grid row by row (100 poses by default).

    After Lodi Rizzini's test network (§IV-B, Fig. 2: "100 poses corresponding to a robot moving on
    a grid").  The robot visits every grid point once, boustrophedon: left to right on even rows,
    right to left on odd ones; its heading is the direction to the next point.  Each pair of
    vertically adjacent points that are not consecutive in time is a loop closure with
    ``closure_probability``.  Loop closures' standard deviations are ``closure_noise`` times the
    odometry's (place recognition is often less precise than odometry); other keywords go to
    :func:`measure`.

    Parameters
    ----------
    rows, cols : int
        Grid size, ``rows * cols >= 2``.
    step : float
        Grid spacing, ``> 0``.
    closure_probability : float
        In ``[0, 1]``.
    closure_noise : float
        ``> 0``.
    sigma_xy, sigma_theta : float
        Odometry standard deviations, ``> 0``.
    rng : int or numpy.random.Generator
    **noise
        ``noise``, ``floor``, ``noiseless``: see :func:`measure`.

    Returns
    -------
    Simulation
        ``rows * cols`` poses.
    """
    where = "grid_world"
    rng = check_rng(rng, where)
    rows = check_int(rows, "rows", where, minimum=1)
    cols = check_int(cols, "cols", where, minimum=1)
    if rows * cols < 2:
        raise OptionError(f"{where}: rows * cols must be at least 2; got {rows} x {cols}")
    step = check_real(step, "step", where, minimum=0.0, strict=True)
    closure_probability = check_real(
        closure_probability, "closure_probability", where, minimum=0.0, maximum=1.0
    )
    closure_noise = check_real(closure_noise, "closure_noise", where, minimum=0.0, strict=True)
    sigma_xy = check_real(sigma_xy, "sigma_xy", where, minimum=0.0, strict=True)
    sigma_theta = check_real(sigma_theta, "sigma_theta", where, minimum=0.0, strict=True)
    r = np.repeat(np.arange(rows), cols)
    c = np.tile(np.arange(cols), rows)
    c = np.where(r % 2 == 0, c, cols - 1 - c)
    xy = np.column_stack([c, r]).astype(float) * step
    d = np.diff(xy, axis=0)
    heading = np.arctan2(d[:, 1], d[:, 0])
    heading = np.append(heading, heading[-1])
    truth = np.column_stack([xy, heading])
    n = rows * cols
    index = np.empty((rows, cols), dtype=np.int64)
    index[r, c] = np.arange(n)
    below, above = index[:-1].ravel(), index[1:].ravel()
    non_consecutive = np.abs(above - below) > 1
    below, above = below[non_consecutive], above[non_consecutive]
    keep = rng.random(below.size) < closure_probability
    loops = np.sort(np.column_stack([below[keep], above[keep]]), axis=1)
    odo = np.column_stack([np.arange(n - 1), np.arange(1, n)])
    scale = np.concatenate([np.ones(n - 1), np.full(len(loops), float(closure_noise))])
    return measure(
        truth,
        np.vstack([odo, loops]),
        rng=rng,
        sigma_xy=sigma_xy * scale,
        sigma_theta=sigma_theta * scale,
        **noise,
    )


# ---------------------------------------------------------------------------- outliers

OUTLIER_POLICIES = ("random", "local", "random-grouped", "local-grouped")
"""The policies of :func:`add_outliers`, after the Vertigo suite (Sünderhauf & Protzel 2012)."""

#: Standard deviations ``(x, y, theta)`` of a wrong closure's measurement, Vertigo's 2D values:
#: 0.3 m, 0.3 m and 10 degrees around the identity (a "this is the same place" claim).
OUTLIER_SIGMA = (0.3, 0.3, math.radians(10.0))


@dataclass(frozen=True)
class Outliers:
    """A pose graph spoiled with wrong loop closures by :func:`add_outliers`.

    Attributes
    ----------
    graph : PoseGraph
        The original edges followed by the ``count`` wrong ones; the poses and ids are the
        original graph's.
    outlier : ndarray of bool, shape (m,)
        ``True`` for the appended wrong edges (the last ``count``), ``m = graph.m``.
    groups : ndarray of int64, shape (m,)
        Group of each wrong edge, ``0 .. n_groups - 1`` in the order they were appended; ``-1``
        for the original edges.  Without grouping every wrong edge is its own group.
    policy : str
        One of :data:`OUTLIER_POLICIES`.
    """

    graph: PoseGraph
    outlier: np.ndarray
    groups: np.ndarray
    policy: str

    @property
    def count(self):
        """int: the number of wrong edges."""
        return int(np.count_nonzero(self.outlier))


def _typical_information(graph, where):
    """The information matrix of the graph's loop closure with the median trace (odometry's if
    the graph has no loop closure); shape (3, 3)."""
    pick = graph.loop_closure if np.any(graph.loop_closure) else graph.odometric
    info = graph.information[pick]
    if len(info) == 0:
        raise OptionError(
            f"{where}: the graph has no edges to take a typical information matrix from; pass "
            "information= (one 3x3 matrix)"
        )
    trace = np.trace(info, axis1=1, axis2=2)
    return info[np.argsort(trace, kind="stable")[(len(trace) - 1) // 2]].copy()


def _outlier_information(information, graph, where):
    """``information`` checked to be one usable 3x3 matrix, or the graph's typical one."""
    if information is None:
        return _typical_information(graph, where)
    info = real_array(information, "information", where)
    if info.shape != (3, 3):
        raise OptionError(
            f"{where}: information must be one 3x3 matrix (used for every wrong edge); got "
            f"shape {info.shape}"
        )
    if first_bad_information(info[None]) is not None:
        raise OptionError(f"{where}: information: {describe_bad_information(info)}")
    return 0.5 * (info + info.T)


def _outlier_starts(n_groups, last, local_radius, rng):
    """Rank pairs ``(a, b)``, ``a + 2 <= b <= last``, of ``n_groups`` groups; shape (g, 2).

    Without ``local_radius``: ``a``, ``b`` uniform over the unordered pairs (two independent
    uniform draws in ``[0, last]``, redrawn when less than two apart, then sorted).  With it:
    ``a`` uniform in ``[0, last]`` and ``b = a + d``, ``d`` uniform in ``[2, local_radius]``,
    redrawn when ``b > last``.  Redrawing happens in batches, so the result depends only on the
    generator's state.
    """
    found = []
    need = n_groups
    while need > 0:
        size = 2 * need + 16
        if local_radius is None:
            u = rng.integers(0, last + 1, size=(size, 2))
            u = u[np.abs(u[:, 0] - u[:, 1]) >= 2]
            u.sort(axis=1)
        else:
            a = rng.integers(0, last + 1, size=size)
            b = a + rng.integers(2, local_radius + 1, size=size)
            keep = b <= last
            u = np.column_stack([a[keep], b[keep]])
        found.append(u[:need])
        need -= len(found[-1])
    return np.vstack(found) if found else np.zeros((0, 2), dtype=np.int64)


def add_outliers(
    graph,
    count,
    *,
    policy="random",
    group_size=10,
    rng=0,
    local_radius=20,
    information=None,
):
    """Append ``count`` wrong loop closures to ``graph``, as the Vertigo benchmark suite does.

    Sünderhauf & Protzel (IROS 2012) spoil pose graphs with false-positive loop closures of four
    kinds; their suite's ``generateDataset.py`` draws them as follows, and so does this function:

    * ``"random"``: both ends uniform over the poses;
    * ``"local"``: the second end a few poses after the first, ``2 <= j - i <= local_radius``
      (Vertigo: 20) — a wrong closure near the true trajectory, hard to tell from odometry drift;
    * ``"random-grouped"`` / ``"local-grouped"``: groups of ``group_size`` wrong closures
      ``(i + t, j + t)``, ``t = 0 .. group_size - 1``, all with the *same* wrong measurement, so
      that the members of a group agree with each other (and a consistency test passes them) —
      the hard case.

    Each group's measurement ``z = (x, y, theta)`` is drawn once, Gaussian around the identity with
    the standard deviations :data:`OUTLIER_SIGMA` = (0.3 m, 0.3 m, 10°), Vertigo's 2D values: the
    wrong closure claims "pose ``j`` is where pose ``i`` was".  Ends are vertex ranks in id order
    (the odometric order), ``i < j``, the edge measures ``j`` in the frame of ``i``, never between
    consecutive ids and never a self-loop.

    Parameters
    ----------
    graph : PoseGraph
    count : int
        Number of wrong edges to append, ``>= 0`` (edges, not groups: Vertigo's ``--outliers``
        counts groups when ``--groupsize > 1``).  With grouping, ``ceil(count / group_size)``
        groups; the last one is shorter when ``group_size`` does not divide ``count``.
    policy : {"random", "local", "random-grouped", "local-grouped"}
    group_size : int
        Wrong edges per group for the grouped policies, ``>= 1`` (ignored by the others).
    rng : int or numpy.random.Generator
        Seed or generator; the same seed gives the same wrong edges.
    local_radius : int
        Largest ``j - i`` of the local policies, ``>= 2``.
    information : array_like, shape (3, 3), optional
        Information matrix of every wrong edge.  Default: the graph's typical loop closure's —
        the loop closure with the median trace (the lower median), or the odometry's if the graph
        has no loop closure — so that the wrong edges claim the confidence of the right ones.

    Returns
    -------
    Outliers
        ``graph`` with the original edges first, then the wrong ones; ``outlier`` marks the wrong
        ones and ``groups`` numbers their groups.  ``count = 0`` returns ``graph`` itself.

    Raises
    ------
    OptionError
        ``count < 0``, ``group_size < 1``, ``local_radius < 2``, an unknown ``policy``, an
        information matrix that is not one usable 3x3 matrix, or a graph with too few poses:
        ``group_size + 2`` are needed for the grouped policies, 3 for the others.
    OptionTypeError
        ``graph`` is not a :class:`~lagolib.graph.PoseGraph`, or an option has the wrong type.

    Notes
    -----
    Differences from Vertigo's script, all in how the ends are drawn: Vertigo draws ``j`` in
    ``[i, i + 20]`` for "local" and moves ``j = i + 1`` to ``i + 2`` (so a gap of 2 is twice as
    likely); here the gap is uniform in ``[2, local_radius]`` and pairs closer than 2 are redrawn,
    and in both cases the ends range over every pose the group fits in.  A wrong closure between
    two poses that really are at nearly the same place (a revisit) is close to right; with random
    ends on a large map this is rare, but it is not excluded.

    Examples
    --------
    >>> from lagolib.simulate import add_outliers, manhattan_world
    >>> sim = manhattan_world(n_poses=100, rng=0)
    >>> spoiled = add_outliers(sim.graph, 12, policy="local-grouped", group_size=5, rng=1)
    >>> spoiled.graph.m - sim.graph.m, spoiled.count, bool(spoiled.outlier[: sim.graph.m].any())
    (12, 12, False)
    >>> spoiled.groups[spoiled.outlier].tolist()
    [0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 2, 2]
    >>> wrong = spoiled.graph.edges[spoiled.outlier]
    >>> bool(np.all(np.diff(wrong[:5], axis=0) == 1))  # a group's ends advance together
    True
    >>> bool(np.all(spoiled.graph.measurements[spoiled.outlier][:5] == spoiled.graph.measurements[
    ...     spoiled.outlier][0]))  # with one wrong measurement
    True
    """
    where = "add_outliers"
    graph = check_graph(graph, where)
    count = check_int(count, "count", where, minimum=0)
    policy = check_choice(policy, "policy", where, OUTLIER_POLICIES)
    group_size = check_int(group_size, "group_size", where, minimum=1)
    rng = check_rng(rng, where)
    local_radius = check_int(local_radius, "local_radius", where, minimum=2)
    information = _outlier_information(information, graph, where)
    grouped = policy.endswith("-grouped")
    length = group_size if grouped else 1
    n = graph.n
    if n < length + 2:
        need = f"group_size + 2 = {length + 2}" if grouped else "3"
        fix = "; use a smaller group_size" if grouped else ""
        raise OptionError(
            f"{where}: policy {policy!r} needs a graph of at least {need} poses for a wrong edge "
            f"between non-consecutive poses; the graph has {n}{fix}"
        )
    m = graph.m
    if count == 0:
        return Outliers(graph, _read_only(np.zeros(m, bool)), _read_only(np.full(m, -1)), policy)
    n_groups = -(-count // length)
    radius = local_radius if policy.startswith("local") else None
    starts = _outlier_starts(n_groups, n - length, radius, rng)
    z = rng.standard_normal((n_groups, 3)) * np.asarray(OUTLIER_SIGMA)
    z[:, 2] = se2.wrap_angle(z[:, 2])
    group = np.repeat(np.arange(n_groups), length)[:count]
    step = np.tile(np.arange(length), n_groups)[:count]
    ranks = starts[group] + step[:, None]
    row_of_rank = np.argsort(graph.order, kind="stable")
    spoiled = PoseGraph(
        graph.poses,
        np.vstack([graph.edges, row_of_rank[ranks]]),
        np.vstack([graph.measurements, z[group]]),
        np.concatenate([graph.information, np.broadcast_to(information, (count, 3, 3))]),
        ids=graph.ids,
    )
    outlier = np.concatenate([np.zeros(m, bool), np.ones(count, bool)])
    groups = np.concatenate([np.full(m, -1), group]).astype(np.int64)
    return Outliers(spoiled, _read_only(outlier), _read_only(groups), policy)


def _read_only(a):
    """``a`` with its write flag cleared (the arrays of a frozen result)."""
    a.setflags(write=False)
    return a
