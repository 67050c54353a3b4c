"""lagolib: planar pose-graph SLAM, taught from three sources.

Layers (each imports only from the ones before it)::

    errors, se2 -> graph -> io, simulate, datasets -> plotting

Public API
----------
se2
    Planar poses: ``wrap_angle``, ``rotation``, ``v2t``, ``t2v``, ``compose``, ``inverse``,
    ``between``.
PoseGraph, residuals, chi2
    The pose graph and the lecture notes' error ``e_ij = t2v(Z_ij^-1 X_i^-1 X_j)``.
read, write, read_g2o, write_g2o, read_toro, write_toro, read_poses, write_poses
    g2o and TORO files (TORO information converted to the g2o convention).
simulate
    Seeded synthetic worlds with ground truth.
datasets
    Public benchmarks by name (``LAGOLIB_DATA`` mirror or checksummed download) and the shipped
    examples.
plotting
    ``plot_graph``, ``plot_trajectories``, ``plot_poses``.
"""

from . import datasets, plotting, se2, simulate
from .errors import (
    DatasetError,
    GraphError,
    LagolibError,
    LagolibWarning,
    ParseError,
    SkippedLinesWarning,
)
from .graph import PoseGraph, chi2, residuals
from .io import read, read_g2o, read_poses, read_toro, write, write_g2o, write_poses, write_toro
from .plotting import plot_graph, plot_poses, plot_trajectories

__version__ = "0.1.0"

__all__ = [
    "se2",
    "simulate",
    "datasets",
    "plotting",
    "PoseGraph",
    "residuals",
    "chi2",
    "read",
    "write",
    "read_g2o",
    "write_g2o",
    "read_toro",
    "write_toro",
    "read_poses",
    "write_poses",
    "plot_graph",
    "plot_trajectories",
    "plot_poses",
    "LagolibError",
    "GraphError",
    "ParseError",
    "DatasetError",
    "LagolibWarning",
    "SkippedLinesWarning",
]
