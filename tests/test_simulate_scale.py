"""manhattan_world at scale: the spatial-hash version draws exactly the worlds of the reference loop.

``reference_manhattan_world`` below is the original O(n²) implementation of
:func:`lagolib.simulate.manhattan_world`, kept as the readable definition of the world: every
pose's distance to all earlier poses, one ``rng.random()`` per step and per candidate loop
closure.  The library's version (a table-driven walk, loop-closure candidates by spatial hashing,
vectorized draws) must give bit-identical graphs and truth for every seed and parameter.
"""

import itertools

import numpy as np
import pytest

from lagolib import simulate
from lagolib.checks import check_rng


def reference_manhattan_world(
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
    """The original manhattan_world (argument checks left out): the definition of the world."""
    rng = check_rng(rng, "reference")
    headings = np.array([0.0, np.pi / 2, np.pi, -np.pi / 2])
    cell = np.zeros(2, dtype=np.int64)
    h = 0  # index into headings
    unit = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]])
    cells, hs = [cell.copy()], [h]
    for _ in range(n_poses - 1):
        cell = cell + unit[h]
        r = rng.random()
        if r < turn_probability / 2:
            h = (h + 1) % 4
        elif r < turn_probability:
            h = (h - 1) % 4
        # turn back inside when the next move would leave the lattice
        options = [h, (h + 1) % 4, (h - 1) % 4, (h + 2) % 4]
        for cand in options:
            nxt = cell + unit[cand]
            if np.all((nxt >= 0) & (nxt < extent)):
                h = cand
                break
        cells.append(cell.copy())
        hs.append(h)
    cells = np.array(cells, dtype=float) * step
    truth = np.column_stack([cells, headings[hs]])
    pairs = []
    for k in range(min_separation, n_poses):
        d = np.hypot(*(cells[: k - min_separation + 1] - cells[k]).T)
        for j in np.flatnonzero(d <= closure_radius):
            if rng.random() < closure_probability:
                pairs.append((j, k))
    odo = np.column_stack([np.arange(n_poses - 1), np.arange(1, n_poses)])
    edges = np.vstack([odo, np.array(pairs, dtype=np.int64).reshape(-1, 2)])
    return simulate.measure(truth, edges, rng=rng, **noise)


def assert_same_world(a, b):
    ga, gb = a.graph, b.graph
    for name in ("edges", "measurements", "information", "poses"):
        x, y = getattr(ga, name), getattr(gb, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert np.array_equal(x, y), name
    assert a.truth.dtype == b.truth.dtype and np.array_equal(a.truth, b.truth)


def _sweep():
    """Parameter sets: every extent/radius/step/separation combination at 50 poses, then more."""
    cases = []
    radii = (0.0, 0.5, 1.0, 1.5, 2.3)
    for i, (extent, radius, step, sep) in enumerate(
        itertools.product((2, 3, 5, 12, 40), radii, (0.7, 1.0, 2.0), (1, 10))
    ):
        turn, close = ((0.3, 0.5), (0.0, 1.0), (1.0, 0.0), (0.6, 0.8))[i % 4]
        cases.append(
            dict(
                n_poses=50,
                extent=extent,
                closure_radius=radius * step if i % 3 else radius,
                step=step,
                min_separation=sep,
                turn_probability=turn,
                closure_probability=close,
                rng=i,
            )
        )
    for n in (2, 3):
        for sep in (1, 2, 10):
            cases.append(dict(n_poses=n, extent=2, min_separation=sep, closure_radius=2.3, rng=n))
    for seed, (extent, radius, step) in enumerate(
        [
            (3, 0.0, 1.0),
            (10, 1.5, 0.7),
            (8, 0.5, 1.0),
            (12, 1.0, 2.0),
            (25, 2.3, 0.7),
            (40, 0.0, 1.0),
        ]
    ):
        cases.append(
            dict(n_poses=2000, extent=extent, closure_radius=radius * step, step=step, rng=seed)
        )
    return cases


SWEEP = _sweep()


@pytest.mark.parametrize("kw", SWEEP, ids=range(len(SWEEP)))
def test_same_world_as_the_reference_loop(kw):
    assert_same_world(simulate.manhattan_world(**kw), reference_manhattan_world(**kw))


@pytest.mark.parametrize("seed", [0, 5])
@pytest.mark.parametrize(
    "bit_generator", [np.random.PCG64, np.random.MT19937, np.random.Philox, np.random.SFC64]
)
def test_same_world_from_a_generator_and_proportional_noise(bit_generator, seed):
    kw = dict(n_poses=700, extent=7, closure_radius=1.0, noise="proportional", sigma_xy=0.1)
    a = np.random.Generator(bit_generator(seed))
    b = np.random.Generator(bit_generator(seed))
    assert_same_world(simulate.manhattan_world(rng=a, **kw), reference_manhattan_world(rng=b, **kw))
    # both consumed the same number of draws
    assert np.array_equal(a.random(4), b.random(4))


def test_worlds_used_by_tests_chapters_and_benchmarks():
    for kw in [
        dict(n_poses=800, rng=8, noise="proportional", sigma_xy=0.1, sigma_theta=0.05),
        dict(n_poses=700, extent=30, rng=2, sigma_theta=0.2, sigma_xy=0.1),
        dict(n_poses=600, extent=8, rng=3),
        dict(n_poses=300, noiseless=True, rng=2),
        dict(n_poses=150, rng=np.random.default_rng(7)),
    ]:
        ref = dict(kw)
        if isinstance(kw["rng"], np.random.Generator):
            ref["rng"] = np.random.default_rng(7)
        assert_same_world(simulate.manhattan_world(**kw), reference_manhattan_world(**ref))


def test_world_counts_are_the_reference_numbers():
    # numbers of the reference world (about 1.9 edges per pose at this extent)
    sim = simulate.manhattan_world(n_poses=3000, extent=31, rng=1)
    g = sim.graph
    assert (g.n, g.m) == (3000, 5739)
    assert int(g.loop_closure.sum()) == 2740
    assert np.array_equal(g.edges[-1], [885, 2999])


def test_closure_candidates_in_chunks_keep_the_order(monkeypatch):
    # many candidates per pose (small lattice, large radius) cut into chunks of a few pairs
    kw = dict(n_poses=400, extent=3, closure_radius=2.3, min_separation=1, rng=11)
    ref = reference_manhattan_world(**kw)
    for chunk in (1, 7, 1000):
        monkeypatch.setattr(simulate, "_CHUNK", chunk)
        assert_same_world(simulate.manhattan_world(**kw), ref)


@pytest.mark.parametrize(
    "extent, radius, step",
    [(50, 6.0, 1.0), (30, 40.0, 0.5), (200, 1e300, 1.0), (20, 3.0, 1e-300), (9, 2.0, 3e5)],
)
def test_large_radius_blocks_and_extreme_scales(extent, radius, step):
    # radius of many lattice steps (blocks of several lattice points), or of the whole walk
    kw = dict(n_poses=300, extent=extent, closure_radius=radius, step=step, rng=4)
    kw["closure_probability"] = 0.05
    assert_same_world(simulate.manhattan_world(**kw), reference_manhattan_world(**kw))


def test_walk_stays_on_the_lattice_at_scale():
    # a long walk (1e5 poses): lattice points of spacing step inside the extent, unit moves,
    # headings the direction of the next move, closures only between poses at the same point
    kw = dict(n_poses=100_000, extent=177, step=0.5, closure_radius=0.25, rng=3, noiseless=True)
    sim = simulate.manhattan_world(**kw)  # the reference loop takes minutes here
    xy = sim.truth[:, :2] / 0.5
    assert np.array_equal(xy, np.round(xy)) and xy.min() == 0 and xy.max() == 176
    move = np.diff(xy, axis=0)
    assert np.array_equal(np.abs(move).sum(axis=1), np.ones(len(move)))
    np.testing.assert_allclose(np.arctan2(move[:, 1], move[:, 0]), sim.truth[:-1, 2], atol=1e-15)
    g = sim.graph
    loops = g.edges[g.loop_closure]
    assert np.all(loops[:, 1] - loops[:, 0] >= 10)
    np.testing.assert_allclose(xy[loops[:, 0]], xy[loops[:, 1]])
    assert g.m == 201_888


@pytest.mark.parametrize("n, m", [(1000, 1880), (10_000, 17_557), (100_000, 184_919)])
def test_benchmark_extent_rule_gives_about_1_8_edges_per_pose(n, m):
    # the rule in manhattan_world's Notes (bench_scale's worlds); 1e6 poses give 1_830_018
    g = simulate.manhattan_world(n_poses=n, extent=int(np.sqrt(n / 2.6)), rng=0).graph
    assert g.m == m and 1.75 < g.m / n < 1.9
