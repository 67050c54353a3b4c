"""Make the small simulated graphs that lagolib ships in this folder.

Run from anywhere:  python data/make_data.py [output-folder]

Each world is written as ``NAME.g2o`` (the noisy graph; its vertices are the odometry guess) and
``NAME_truth.txt`` (ground-truth poses, ``id x y theta``).  Every world is seeded, so running this
script again reproduces the files byte for byte — ``tests/test_data.py`` checks that.
"""

from __future__ import annotations

import sys
from pathlib import Path

from lagolib import simulate, write_g2o, write_poses

# name -> (function, keyword arguments); the seeds make the files reproducible
WORLDS = {
    "square_loop": (
        simulate.loop_world,
        dict(
            laps=4,
            poses_per_lap=40,
            shape="square",
            step=1.0,
            closure_probability=1.0,
            sigma_xy=0.05,
            sigma_theta=0.01,
            rng=20110627,
        ),
    ),
    "manhattan200": (
        simulate.manhattan_world,
        dict(
            n_poses=200,
            extent=6,
            step=1.0,
            turn_probability=0.3,
            closure_probability=0.5,
            min_separation=10,
            sigma_xy=0.05,
            sigma_theta=0.01,
            rng=3500,
        ),
    ),
    "grid100": (
        simulate.grid_world,
        dict(
            rows=10,
            cols=10,
            step=1.0,
            closure_probability=0.5,
            sigma_xy=0.05,
            sigma_theta=0.01,
            rng=100,
        ),
    ),
}


def make(folder):
    """Write every world into ``folder``; returns the paths written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, (world, kwargs) in WORLDS.items():
        sim = world(**kwargs)
        write_g2o(sim.graph, folder / f"{name}.g2o")
        write_poses(folder / f"{name}_truth.txt", sim.truth, sim.graph.ids)
        written += [folder / f"{name}.g2o", folder / f"{name}_truth.txt"]
    return written


if __name__ == "__main__":
    out = sys.argv[1] if len(sys.argv) > 1 else Path(__file__).resolve().parent
    for p in make(out):
        print(p)
