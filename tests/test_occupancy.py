"""lagolib.occupancy: log-odds occupancy grids by ray casting (Thrun et al. 2005, ch. 9)."""

import math

import matplotlib
import numpy as np
import pytest

from lagolib.errors import OptionError, OptionTypeError
from lagolib.occupancy import (
    L_FREE,
    L_MAX,
    L_MIN,
    L_OCC,
    MapQuality,
    OccupancyGrid,
    map_quality,
    occupancy_grid,
)

matplotlib.use("Agg")

# A rectangular room.  Its walls lie inside cells at 0.1, 0.05 and 0.02 m (0.03 m is 0.3, 0.6 and
# 0.5 of a cell past a grid line: the grid's corner is a multiple of the resolution), so which
# cells a wall occupies is never a question of rounding.
ROOM = (0.03, 6.03, 0.03, 4.03)  # xmin, xmax, ymin, ymax
# sensor poses (x, y, θ), world frame: the centre and one near each corner (the corner cells hold
# only a few millimetres of wall; a close pose puts beams into them)
ROOM_POSES = np.array(
    [
        [3.0, 2.0, 0.3],
        [1.0, 0.9, 2.0],
        [5.1, 0.8, -1.0],
        [5.2, 3.3, 0.7],
        [0.9, 3.1, -2.5],
    ]
)
DENSE = np.linspace(-math.pi, math.pi, 7200, endpoint=False)  # 0.05°, all around


def room_ranges(poses, angles, room=ROOM):
    """Exact ranges from ``poses`` (inside the room) to its walls: the nearest of the lines
    ``x = xmin, xmax`` and ``y = ymin, ymax`` along each beam (ground-truth geometry)."""
    x0, x1, y0, y1 = room
    phi = poses[:, 2:3] + angles[None]
    c, s = np.cos(phi), np.sin(phi)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (x1 - poses[:, :1]) / c, (x0 - poses[:, :1]) / c)
        ty = np.where(s > 0, (y1 - poses[:, 1:2]) / s, (y0 - poses[:, 1:2]) / s)
    tx[c == 0] = np.inf
    ty[s == 0] = np.inf
    return np.minimum(tx, ty)


def wall_cells(grid, room=ROOM):
    """(rows, cols) bool: the cells a wall segment of the room passes through."""
    x0, x1, y0, y1 = room
    out = np.zeros(grid.shape, dtype=bool)
    (r0, r1), (c0, c1) = grid.cell_of([[x0, y0], [x1, y1]])
    out[r0 : r1 + 1, [c0, c1]] = True  # x = xmin and x = xmax, from ymin to ymax
    out[[r0, r1], c0 : c1 + 1] = True  # y = ymin and y = ymax
    return out


def interior_cells(grid, room=ROOM):
    """(rows, cols) bool: the cells strictly inside the room (touching no wall)."""
    x0, x1, y0, y1 = room
    (r0, r1), (c0, c1) = grid.cell_of([[x0, y0], [x1, y1]])
    out = np.zeros(grid.shape, dtype=bool)
    out[r0 + 1 : r1, c0 + 1 : c1] = True
    return out


def room_grid(resolution, poses=ROOM_POSES, **kw):
    return occupancy_grid(
        room_ranges(poses, DENSE), poses, angles=DENSE, max_range=30.0, resolution=resolution, **kw
    )


@pytest.mark.parametrize("resolution", [0.1, 0.05, 0.02])
def test_grid_of_a_simulated_room_is_the_room(resolution):
    """The occupied cells are exactly the cells the walls pass through; every cell inside the room
    is observed and free; every cell outside is unknown — at 0.1, 0.05 and 0.02 m."""
    grid = room_grid(resolution)
    walls, inside = wall_cells(grid), interior_cells(grid)
    outside = ~walls & ~inside
    labels = grid.classify()
    assert np.array_equal(labels == 1, walls)
    assert np.array_equal(grid.hits > 0, walls)  # every wall cell is hit, nothing else
    assert np.all(labels[inside] == 0)
    assert np.all(grid.log_odds[outside] == 0.0)
    # the walls span columns c0..c1 and rows r0..r1 of the grid: 6 m and 4 m plus a partial cell
    (r0, r1), (c0, c1) = grid.cell_of([[ROOM[0], ROOM[2]], [ROOM[1], ROOM[3]]])
    assert (c1 - c0, r1 - r0) == (round(6.0 / resolution), round(4.0 / resolution))
    assert walls.sum() == 2 * (c1 - c0 + 1) + 2 * (r1 - r0 + 1) - 4
    # the grid spans the poses and the walls with a margin of 5 cells, corner on a multiple of res
    x0, y0 = grid.origin
    assert x0 == pytest.approx(resolution * math.floor((0.03 - 5 * resolution) / resolution))
    assert grid.extent[1] >= 6.03 + 5 * resolution - 1e-9
    # every interior cell was crossed by beams of all five scans (one update per scan), clamped
    assert np.all(grid.log_odds[inside] == max(5 * L_FREE, L_MIN))


def test_room_wall_cells_counted():
    """At 0.1 m the walls 0.03..6.03 by 0.03..4.03 occupy columns 5 and 65, rows 5 and 45 (grid
    corner at -0.5 m): 2 * 61 + 2 * 39 cells."""
    grid = room_grid(0.1)
    assert grid.origin == pytest.approx((-0.5, -0.5))
    rows, cols = np.nonzero(grid.classify() == 1)
    assert set(cols.tolist()) == set(range(5, 66))
    assert set(rows.tolist()) == set(range(5, 46))
    assert len(rows) == 2 * 61 + 2 * 39
    assert map_quality(grid).occupied_cells == 200


def test_single_beam_exact_cells_and_log_odds():
    """A beam from (0.05, 0.05) to (0.37, 0.24) on 0.1 m cells, grid units (0.5, 0.5) → (3.7, 2.4):
    it crosses x = 1, 2, 3 at y = 0.80, 1.39, 1.98 and y = 1, 2 at x = 1.34, 3.03 (grid units),
    so it visits (row, col) (0,0) (0,1) (1,1) (1,2) (1,3) (2,3), the last the hit."""
    d = np.array([0.32, 0.19])
    grid = occupancy_grid(
        [[np.hypot(*d)]],
        [[0.05, 0.05, 0.0]],
        angles=[math.atan2(d[1], d[0])],
        max_range=10.0,
        resolution=0.1,
        extent=(0.0, 0.6, 0.0, 0.4),
    )
    expected = np.zeros((4, 6))
    for cell in [(0, 0), (0, 1), (1, 1), (1, 2), (1, 3)]:
        expected[cell] = L_FREE
    expected[2, 3] = L_OCC
    assert np.array_equal(grid.log_odds, expected)
    assert np.argwhere(grid.hits).tolist() == [[2, 3]] and grid.hits[2, 3] == 1
    assert (L_OCC, L_FREE) == (0.85, -0.4)


@pytest.mark.parametrize("forward", [True, False])
def test_a_beam_through_grid_corners_visits_only_the_diagonal(forward):
    """From (0.5, 0.5) to (3.5, 3.5) in grid units (exact), both ways: the segment passes
    through grid corners and enters only the diagonal cells, never the ones it touches at a
    corner; the hit cell is listed once more at the end."""
    from lagolib.occupancy import _beam_cells

    a, b = (0.5, 3.5) if forward else (3.5, 0.5)
    rows, cols, count = _beam_cells(
        np.array([a]), np.array([a]), np.array([b]), np.array([b]), np.array([True])
    )
    assert count.tolist() == [1 + 3 + 3 + 1]
    cells = list(zip(rows.tolist(), cols.tolist()))
    path = [(0, 0), (1, 1), (2, 2), (3, 3)]
    assert set(cells) == set(path)
    assert cells[0] == path[0 if forward else -1] and cells[-1] == path[-1 if forward else 0]


def test_no_return_beams_mark_free_up_to_the_cap_and_no_hit():
    # beams along +x from (0.05, 0.05), +y from (0.05, 0.45): at max_range, at inf
    kw = dict(angles=[0.0], max_range=5.0, resolution=0.1, extent=(0.0, 1.0, 0.0, 1.0))
    poses = [[0.05, 0.05, 0.0], [0.05, 0.45, math.pi / 2]]
    grid = occupancy_grid([[5.0], [np.inf]], poses, max_beam=0.42, **kw)
    free = np.zeros((10, 10), dtype=bool)
    free[0, 0:5] = True  # x = 0.05 .. 0.47: columns 0..4
    free[4:9, 0] = True  # y = 0.45 .. 0.87: rows 4..8
    assert np.all(grid.log_odds[free] == L_FREE)
    assert np.all(grid.log_odds[~free] == 0.0)
    # the default cap is 10 m, never more than max_range; 0 ignores such beams
    grid = occupancy_grid([[5.0], [5.0]], poses, **kw)
    assert np.sum(grid.log_odds < 0) == 10 + 6  # cut at the grid's border
    grid = occupancy_grid([[5.0], [5.0]], poses, max_beam=0.0, **kw)
    assert np.all(grid.log_odds == 0.0)


def test_invalid_ranges_are_skipped():
    kw = dict(angles=[0.0, 0.5], max_range=5.0, resolution=0.1, extent=(0.0, 1.0, 0.0, 1.0))
    pose = [[0.05, 0.05, 0.0]]
    grid = occupancy_grid([[np.nan, 0.05]], pose, min_range=0.1, **kw)
    assert np.all(grid.log_odds == 0.0)
    grid = occupancy_grid([[0.0, 0.3]], pose, **kw)  # range 0 <= min_range 0: skipped
    only = occupancy_grid([[np.nan, 0.3]], pose, **kw)
    assert np.array_equal(grid.log_odds, only.log_odds)
    assert np.sum(grid.log_odds > 0) == 1


def test_one_update_per_scan():
    """Two beams of one scan crossing the same cells update them once; a cell one beam of a scan
    ends in is occupied even where another beam of that scan crosses it."""
    kw = dict(max_range=5.0, resolution=0.1, extent=(0.0, 1.0, 0.0, 1.0))
    pose = [[0.05, 0.05, 0.0]]
    grid = occupancy_grid([[0.52, 0.52]], pose, angles=[0.0, 0.0], **kw)
    assert grid.log_odds[0, :6].tolist() == [L_FREE] * 5 + [L_OCC]
    assert grid.hits[0, 5] == 1  # one scan
    grid = occupancy_grid([[0.52, 0.23]], pose, angles=[0.0, 0.0], **kw)
    assert grid.log_odds[0, :6].tolist() == [L_FREE] * 2 + [L_OCC] + [L_FREE] * 2 + [L_OCC]
    # as two scans they add up
    grid = occupancy_grid([[0.52], [0.52]], pose * 2, angles=[0.0], **kw)
    assert grid.log_odds[0, :6].tolist() == pytest.approx([2 * L_FREE] * 5 + [2 * L_OCC])


def test_clamped_after_every_scan():
    """10 scans that end in a cell, then 10 that see through it: clamped per scan the cell ends
    free, clip(3.5 - 4.0) = -0.5 (clamping only at the end would leave clip(8.5 - 4.0) = 3.5)."""
    ranges = [[0.32]] * 10 + [[0.72]] * 10
    poses = [[0.05, 0.05, 0.0]] * 20
    grid = occupancy_grid(
        ranges, poses, angles=[0.0], max_range=5.0, resolution=0.1, extent=(0, 1, 0, 1)
    )
    assert grid.log_odds[0, 3] == pytest.approx(L_MAX + 10 * L_FREE)
    assert grid.log_odds[0, 3] == pytest.approx(-0.5)
    assert grid.log_odds[0, 0] == L_MIN  # crossed 20 times
    assert grid.log_odds[0, 7] == L_MAX  # 10 hits, 8.5 clamped to 3.5
    assert (grid.hits[0, 3], grid.hits[0, 7], grid.hits.sum()) == (10, 10, 20)


def test_misaligned_pose_gives_a_worse_map():
    """Turning one of the five poses by 5° smears its scan off the walls: more cells hit, more
    occupied cells, higher entropy, fewer confident cells."""
    good = map_quality(room_grid(0.05))
    poses = ROOM_POSES.copy()
    poses[0, 2] += math.radians(5.0)
    ranges = room_ranges(ROOM_POSES, DENSE)  # measured from the true poses
    bad = map_quality(occupancy_grid(ranges, poses, angles=DENSE, max_range=30.0, resolution=0.05))
    assert isinstance(good, MapQuality)
    assert good.occupied_cells == good.hit_cells == 400  # 2 * 121 + 2 * 81 - 4 corners
    assert bad.hit_cells > good.hit_cells + 300
    assert bad.occupied_cells > good.occupied_cells + 100
    assert bad.entropy > good.entropy
    assert bad.fraction_confident < good.fraction_confident
    assert good.occupied_area == pytest.approx(400 * 0.05**2)


def test_map_quality_numbers():
    l_free4 = math.log(0.2 / 0.8)  # exactly at the "confident" bound
    g = OccupancyGrid(np.array([[L_MAX, L_OCC, 0.0], [l_free4, L_FREE, 0.0]]), 0.5, (0.0, 0.0))
    q = map_quality(g)
    assert (q.observed_cells, q.occupied_cells, q.free_cells) == (4, 2, 2)
    assert q.occupied_area == 0.5
    assert q.fraction_confident == 0.5  # 3.5 and log(1/4); not 0.85, -0.4
    p = g.probability[g.log_odds != 0]
    h = -(p * np.log2(p) + (1 - p) * np.log2(1 - p))
    assert q.entropy == pytest.approx(h.mean(), rel=1e-12)
    assert q.hit_cells is None
    assert map_quality(OccupancyGrid(np.zeros((2, 2)), 1.0, (0, 0))) == MapQuality(
        0, 0, 0, 0.0, None, 0.0, 0.0
    )
    hits = np.array([[3, 0, 0], [0, 0, 1]])
    assert map_quality(OccupancyGrid(g.log_odds, 0.5, (0, 0), hits)).hit_cells == 2
    # entropy stays finite for any log odds
    big = map_quality(OccupancyGrid(np.array([[1e4, -1e4]]), 1.0, (0, 0)))
    assert big.entropy == 0.0 and big.fraction_confident == 1.0


def test_image_orientation_and_levels():
    """A hit at large y is in the top rows of the image (row 0 = largest y), as a PNG stores it."""
    grid = occupancy_grid(
        [[1.72]],
        [[0.25, 0.05, math.pi / 2]],
        angles=[0.0],
        max_range=5.0,
        resolution=0.1,
        extent=(0.0, 1.0, 0.0, 2.0),
    )
    assert grid.shape == (20, 10)
    assert grid.log_odds[17, 2] == L_OCC  # y = 1.77
    image = grid.image()
    assert image.dtype == np.uint8 and image.shape == (20, 10)
    assert image[2, 2] == round(255 / (1 + math.exp(L_OCC)))  # grid row 17 is image row 2
    assert image[19, 2] == round(255 / (1 + math.exp(L_FREE)))  # the sensor's cell at the bottom
    assert image[0, 0] == 128  # unknown
    levels = grid.image(threshold=0.5)
    assert (levels[2, 2], levels[19, 2], levels[0, 0]) == (0, 255, 128)
    assert np.array_equal(grid.classify()[::-1] == 1, levels == 0)


def test_grid_geometry():
    g = OccupancyGrid(np.zeros((3, 4)), 0.25, (-1.0, 2.0))
    assert g.shape == (3, 4)
    assert g.extent == (-1.0, 0.0, 2.0, 2.75)
    rows, cols = g.cell_of([[-1.0, 2.0], [-0.01, 2.74], [0.5, 1.0]])
    assert rows.tolist() == [0, 2, -4] and cols.tolist() == [0, 3, 6]
    assert g.probability.tolist() == [[0.5] * 4] * 3
    assert np.all(g.classify() == -1)
    assert g.log_odds.flags.writeable is False
    with pytest.raises(ValueError):
        g.log_odds[0, 0] = 1.0
    lo = np.array([[0.3, -0.3, 0.9]])
    assert OccupancyGrid(lo, 1.0, (0, 0)).classify(0.6).tolist() == [[-1, -1, 1]]
    assert OccupancyGrid(lo, 1.0, (0, 0)).probability[0, 2] == pytest.approx(
        1 - 1 / (1 + math.exp(0.9))
    )


def _cells_loop(u0, v0, u1, v1):
    """Amanatides & Woo 1987, one step at a time: the cells from (u0, v0) to (u1, v1), grid units."""
    du, dv = u1 - u0, v1 - v0
    col = math.floor(u0) if du >= 0 else math.ceil(u0) - 1
    row = math.floor(v0) if dv >= 0 else math.ceil(v0) - 1
    col_end = math.ceil(u1) - 1 if du > 0 else math.floor(u1)
    row_end = math.ceil(v1) - 1 if dv > 0 else math.floor(v1)
    step_c, step_r = (1 if du > 0 else -1), (1 if dv > 0 else -1)
    next_c = (col + (step_c > 0) - u0) / du if du else math.inf  # t of the next line x = const
    next_r = (row + (step_r > 0) - v0) / dv if dv else math.inf
    cells = [(row, col)]
    for _ in range(abs(col_end - col) + abs(row_end - row)):
        if next_c < next_r:
            col += step_c
            next_c += 1 / abs(du)
        else:
            row += step_r
            next_r += 1 / abs(dv)
        cells.append((row, col))
    assert cells[-1] == (row_end, col_end)
    return cells


def _occupancy_grid_loop(ranges, poses, angles, max_range, min_range, max_beam, res, extent):
    """Thrun et al. 2005, Table 9.1 and 9.2 read literally: one scan, one beam, one cell at a time."""
    ox, oy = extent[0], extent[2]
    rows = math.ceil((extent[3] - extent[2]) / res - 1e-9)
    cols = math.ceil((extent[1] - extent[0]) / res - 1e-9)
    log_odds = np.zeros((rows, cols))
    hits = np.zeros((rows, cols), dtype=int)
    for scan, (x, y, theta) in enumerate(poses):
        hit, crossed = set(), set()
        for beam, a in enumerate(angles):
            r = ranges[scan, beam]
            if math.isnan(r) or r <= min_range:
                continue
            is_hit = r < max_range
            length = r if is_hit else min(max_beam, max_range)
            if length <= 0:
                continue
            phi = np.float64(theta) + np.float64(a)  # as the vectorized code rounds it
            x1 = x + length * np.cos(phi)
            y1 = y + length * np.sin(phi)
            cells = _cells_loop((x - ox) / res, (y - oy) / res, (x1 - ox) / res, (y1 - oy) / res)
            crossed.update(cells)
            if is_hit:
                hit.add(cells[-1])
        for row, col in hit | crossed:
            if 0 <= row < rows and 0 <= col < cols:
                delta = L_OCC if (row, col) in hit else L_FREE
                log_odds[row, col] = min(max(log_odds[row, col] + delta, L_MIN), L_MAX)
                hits[row, col] += (row, col) in hit
    return log_odds, hits


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_vectorized_equals_the_loop(seed):
    """Random scans in a 4 m box, with no-return beams, NaN and too-short ranges, and a grid that
    cuts some beams: the vectorized grid equals the one-beam-at-a-time loop exactly."""
    rng = np.random.default_rng(seed)
    k, n = 12, 40
    poses = np.column_stack(
        [rng.uniform(-1, 3, k), rng.uniform(-1, 3, k), rng.uniform(-math.pi, math.pi, k)]
    )
    angles = np.sort(rng.uniform(-math.pi, math.pi, n))
    ranges = rng.uniform(0.0, 4.0, (k, n))
    ranges[rng.random((k, n)) < 0.1] = 4.0  # no return (max_range)
    ranges[rng.random((k, n)) < 0.05] = np.inf
    ranges[rng.random((k, n)) < 0.05] = np.nan
    ranges[rng.random((k, n)) < 0.05] = 0.01  # <= min_range
    extent = (-0.5, 2.7, -0.3, 2.9)
    kw = dict(max_range=4.0, min_range=0.02, max_beam=1.5)
    grid = occupancy_grid(ranges, poses, angles=angles, resolution=0.07, extent=extent, **kw)
    loop, hits = _occupancy_grid_loop(ranges, poses, angles, res=0.07, extent=extent, **kw)
    assert grid.origin == (-0.5, -0.3)
    assert np.array_equal(grid.log_odds, loop)
    assert np.array_equal(grid.hits, hits)
    assert np.sum(grid.log_odds > 0) > 50 and np.sum(grid.log_odds < 0) > 300


def test_chunks_do_not_change_the_grid(monkeypatch):
    """The cells are generated in chunks of scans; any chunk size gives the same grid."""
    import lagolib.occupancy as occupancy

    ranges = room_ranges(ROOM_POSES, DENSE)
    ref = occupancy_grid(ranges, ROOM_POSES, angles=DENSE, max_range=30.0, resolution=0.05)
    monkeypatch.setattr(occupancy, "_CHUNK", 1000)  # smaller than a scan: one scan per chunk
    small = occupancy_grid(ranges, ROOM_POSES, angles=DENSE, max_range=30.0, resolution=0.05)
    assert np.array_equal(ref.log_odds, small.log_odds)
    assert ref.origin == small.origin


def test_laser_log_input_equals_arrays():
    from lagolib.scans import LaserLog

    ranges = room_ranges(ROOM_POSES, DENSE)
    k = len(ROOM_POSES)
    log = LaserLog(ranges, DENSE, 30.0, 0.0, ROOM_POSES, "truth", np.zeros((k, 3)), np.arange(k))
    a = occupancy_grid(log, log.reference, resolution=0.1)
    b = occupancy_grid(ranges, ROOM_POSES, angles=DENSE, max_range=30.0, resolution=0.1)
    assert np.array_equal(a.log_odds, b.log_odds) and a.origin == b.origin
    with pytest.raises(OptionError, match="occupancy_grid: angles comes from the laser log"):
        occupancy_grid(log, log.reference, angles=DENSE)


def test_plot_occupancy():
    import matplotlib.pyplot as plt

    from lagolib.plotting import plot_occupancy

    grid = room_grid(0.1)
    fig, ax = plt.subplots()
    assert plot_occupancy(grid, ax, title="room") is ax
    (im,) = ax.images
    assert np.array_equal(im.get_array(), grid.image())
    assert tuple(im.get_extent()) == pytest.approx(grid.extent)
    assert ax.get_title() == "room"
    with pytest.raises(OptionTypeError, match="plot_occupancy: grid must be an OccupancyGrid"):
        plot_occupancy(grid.log_odds, ax)
    with pytest.raises(OptionError, match="plot_occupancy"):
        plot_occupancy(grid, ax, no_such_property=1)
    plt.close(fig)


GOOD = dict(angles=[0.0, 1.0], max_range=5.0)


@pytest.mark.parametrize(
    "args, kw, error, match",
    [
        (([1.0, 2.0], [[0, 0, 0]]), GOOD, OptionError, "ranges must have shape"),
        (([[1.0, 2.0]], [[0, 0]]), GOOD, OptionError, r"poses must have shape \(k, 3\)"),
        (([[1.0, 2.0]], [[0, 0, 0]] * 2), GOOD, OptionError, "1 scans of ranges but 2 poses"),
        (([[1.0, 2.0]], [[0, np.nan, 0]]), GOOD, OptionError, r"poses\[0\] is not finite"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(GOOD, resolution=0.0), OptionError, "resolution"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(GOOD, resolution=-1), OptionError, "resolution"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(GOOD, resolution=1e-4), OptionError, "coarsen"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(GOOD, angles=[0.0]), OptionError, r"angles must have"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(angles=[0.0, 1.0]), OptionError, "max_range="),
        (([[1.0, -2.0]], [[0, 0, 0]]), GOOD, OptionError, "scan 0 beam 1 is negative"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(GOOD, l_occ=-1.0), OptionError, "l_occ"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(GOOD, l_free=0.4), OptionError, "l_free"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(GOOD, extent=(1, 0, 0, 1)), OptionError, "extent"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(GOOD, extent=(0, 1e9, 0, 1)), OptionError, "smaller"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(GOOD, max_range=np.nan), OptionError, "inf: every"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(GOOD, min_range=6.0), OptionError, "min_range"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(GOOD, max_beam=-1.0), OptionError, "max_beam"),
        ((["a", "b"], [[0, 0, 0]]), GOOD, OptionTypeError, "ranges"),
        (([[1.0, 2.0]], "pose"), GOOD, OptionTypeError, "poses"),
        (([[1.0, 2.0]], [[0, 0, 0]]), dict(GOOD, resolution="5cm"), OptionTypeError, "resolution"),
    ],
)
def test_bad_input(args, kw, error, match):
    with pytest.raises(error, match=match) as info:
        occupancy_grid(*args, **kw)
    assert str(info.value).startswith("occupancy_grid: ")


def test_huge_grid_is_refused_before_any_work():
    """A 81 m beam at 1 mm would need 10^10 cells: an OptionError saying what to do, at once."""
    with pytest.raises(OptionError, match="coarsen the resolution, or pass extent="):
        occupancy_grid([[81.0]], [[0, 0, 0]], angles=[0.7], max_range=82.0, resolution=0.001)


def test_bad_grid_and_options():
    with pytest.raises(OptionError, match="OccupancyGrid: resolution"):
        OccupancyGrid(np.zeros((2, 2)), 0.0, (0, 0))
    with pytest.raises(OptionError, match=r"OccupancyGrid: log_odds must have shape"):
        OccupancyGrid(np.zeros(4), 1.0, (0, 0))
    with pytest.raises(OptionError, match="not finite"):
        OccupancyGrid(np.array([[np.nan]]), 1.0, (0, 0))
    with pytest.raises(OptionError, match="origin"):
        OccupancyGrid(np.zeros((2, 2)), 1.0, (0, 0, 0))
    with pytest.raises(OptionError, match="OccupancyGrid: hits must be"):
        OccupancyGrid(np.zeros((2, 2)), 1.0, (0, 0), np.zeros((2, 3), dtype=int))
    with pytest.raises(OptionError, match="OccupancyGrid: hits must be"):
        OccupancyGrid(np.zeros((2, 2)), 1.0, (0, 0), np.full((2, 2), 0.5))
    with pytest.raises(OptionTypeError, match="OccupancyGrid: log_odds"):
        OccupancyGrid(np.zeros((2, 2), dtype=bool), 1.0, (0, 0))
    g = OccupancyGrid(np.zeros((2, 2)), 1.0, (0, 0))
    with pytest.raises(OptionError, match="OccupancyGrid.classify: threshold"):
        g.classify(0.3)
    with pytest.raises(OptionError, match="OccupancyGrid.classify: threshold"):
        g.classify(1.0)
    with pytest.raises(OptionError, match=r"OccupancyGrid.cell_of: xy must have shape"):
        g.cell_of([1.0, 2.0, 3.0])
    with pytest.raises(OptionTypeError, match="map_quality: grid must be an OccupancyGrid"):
        map_quality(np.zeros((2, 2)))
