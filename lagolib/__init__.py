"""lagolib: planar pose-graph SLAM, taught from three sources.

Layers (each imports only from the ones before it)::

    errors -> files (atomic writes) -> se2 -> checks -> graph
    -> io, simulate, metrics, occupancy, scans, scan_matching -> laser_world -> datasets
    -> topology -> linalg -> estimation -> gauss_newton, lago, sgd -> closed_form -> certify
    -> robust -> plotting -> uncertainty -> frontend -> book -> cli;   symbolic (sympy only);
    kernels and consistency sit in the layer of io

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
topology
    Incidence matrices, spanning trees, chords, fundamental circuits, cycle basis matrix.
linalg
    Sparse Cholesky with pluggable backends, preconditioned conjugate gradients.
gauss_newton, optimize, Prior
    The lecture notes' least squares: Jacobians, ``H`` and ``b`` (loop and vectorized),
    Gauss–Newton and Levenberg–Marquardt, gauge by prior or fixed poses; ``robust=`` a kernel
    (IRLS, a weight per edge).
kernels
    Robust kernels (M-estimators): Huber, Cauchy, Geman–McClure, truncated least squares,
    DCS — each with ρ, ψ and the IRLS weight; GNC's surrogate weights.
consistency
    Pairwise consistency maximization (Mangelson et al. 2018): the consistency graph of the loop
    closures under the odometry's first-order uncertainty, its maximum clique, ``pcm``.
robust
    When loop closures lie: graduated non-convexity (``gnc``), every robust method behind
    ``robust.solve``, precision/recall ``scores``, ``certify_inliers`` (and what it does not
    cover).
estimation
    The BLUE in information form, first-order covariance propagation.
lago_solve, LagoResult, lago
    Carlone et al.'s linear approximation (``lago_solve(graph)``, the same function as
    ``lagolib.lago.lago``): regularization and the three phases.
closed_form
    Lodi Rizzini's closed form: poses as (x, y, cos, sin), position and angular equations, the
    orthogonality condition solved by Newton's method.
certify
    Is it the global optimum?  The chordal problem in complex form (data matrix ``M``), a local
    Newton solver, the dual certificate ``lambda_min(S)`` with a lower bound when it fails,
    escape up the Riemannian staircase, and ``certify.solve(graph)``: LAGO → Gauss–Newton →
    chordal polish → certificate (→ escape).
metrics
    Carlone's Table II metrics ``constraint_satisfaction`` (η_c, η_a); SE-Sync's objective and
    weights (``sesync_objective``, ``sesync_weights``); ``align``, ``absolute_trajectory_error``
    and ``relative_pose_error`` against ground truth.
sgd
    A TORO-style baseline: stochastic gradient descent on a tree parameterization
    (``lagolib.sgd.sgd``).
scans
    Laser logs: the Carmen reader (``read_carmen``), ``LaserLog`` (ranges, beam angles, the
    log's reference poses and raw odometry increments), scans as points.
scan_matching
    Point-to-line ICP with an odometry prior and a calibrated information matrix, its
    degeneracy measure, and correlative search (``match``, ``ScanModel``,
    ``correlative_search``).
laser_world
    A simulated office ray-cast by lagolib: the offline laser log of chapter 10.
frontend
    From a laser log to a pose graph: keyframes, sequential matches, loop closures gated by
    the relative covariance and verified by scan matching (``build_graph``).
occupancy
    Log-odds occupancy grids (Thrun et al. 2005, ch. 9) and their map quality.
cli
    The ``lagolib`` command: ``info``, ``solve``, ``certify``, ``plot``, ``frontend``, ``map``,
    ``datasets``, ``book``.
uncertainty
    Marginal and relative covariances from the sparse ``H``, loop-closure gating.
symbolic
    sympy derivations: the lecture notes' error and Jacobians; Lodi Rizzini's sin/cos error,
    gradient and closed-form matrices.
plotting
    ``plot_graph``, ``plot_spanning_tree``, ``plot_trajectories``, ``plot_poses``,
    ``plot_covariance_ellipses``.
"""

from . import (
    certify,
    closed_form,
    consistency,
    datasets,
    estimation,
    frontend,
    gauss_newton,
    kernels,
    lago,
    laser_world,
    linalg,
    metrics,
    occupancy,
    plotting,
    robust,
    scan_matching,
    scans,
    se2,
    sgd,
    simulate,
    tables,
    topology,
    uncertainty,
)
from .errors import (
    BackendError,
    BackendWarning,
    ConditioningWarning,
    ConvergenceError,
    DatasetError,
    GaugeError,
    GraphError,
    GraphTypeError,
    LagolibError,
    LagolibWarning,
    NotPositiveDefiniteError,
    OptionError,
    OptionTypeError,
    ParseError,
    SkippedLinesWarning,
)
from .gauss_newton import OptimizeResult, Prior, optimize
from .graph import PoseGraph, chi2, residuals
from .io import read, read_g2o, read_poses, read_toro, write, write_g2o, write_poses, write_toro
from .lago import LagoResult, RegularizationWarning
from .lago import lago as lago_solve
from .plotting import (
    plot_covariance_ellipses,
    plot_graph,
    plot_occupancy,
    plot_poses,
    plot_spanning_tree,
    plot_trajectories,
)
from .tables import Table

__version__ = "0.1.0"


def __getattr__(name):
    """``lagolib.symbolic`` is imported on first use: it needs sympy, which takes a second to load."""
    if name == "symbolic":
        import importlib

        module = importlib.import_module(".symbolic", __name__)
        globals()["symbolic"] = module
        return module
    raise AttributeError(f"module 'lagolib' has no attribute {name!r}")


__all__ = [
    "Table",
    "tables",
    "se2",
    "simulate",
    "datasets",
    "plotting",
    "linalg",
    "gauss_newton",
    "kernels",
    "consistency",
    "robust",
    "topology",
    "estimation",
    "lago",
    "metrics",
    "sgd",
    "LagoResult",
    "lago_solve",
    "certify",
    "closed_form",
    "uncertainty",
    "symbolic",
    "scans",
    "scan_matching",
    "laser_world",
    "frontend",
    "occupancy",
    "plot_occupancy",
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
    "plot_spanning_tree",
    "plot_trajectories",
    "plot_poses",
    "plot_covariance_ellipses",
    "optimize",
    "OptimizeResult",
    "Prior",
    "LagolibError",
    "GraphError",
    "GraphTypeError",
    "ParseError",
    "DatasetError",
    "GaugeError",
    "NotPositiveDefiniteError",
    "BackendError",
    "ConvergenceError",
    "OptionError",
    "OptionTypeError",
    "LagolibWarning",
    "SkippedLinesWarning",
    "BackendWarning",
    "ConditioningWarning",
    "RegularizationWarning",
]
