"""Scan matching: point-to-line ICP with an odometry prior, and a calibrated information matrix.

The front end's measurement ``z_ij`` is the pose of scan ``j`` in the frame of scan ``i`` that
best aligns the two scans.  Point-to-line ICP (Chen & Medioni 1992; Censi 2008, "An ICP variant
using a point-to-line metric") alternates

1. *correspondences*: every point ``p_k`` of scan ``j``, moved by the current guess
   ``x = (t, θ)``, is paired with its nearest point ``q_k`` of scan ``i``, whose *normal* ``n_k``
   comes from a line fitted to ``q_k``'s neighbours (:class:`ScanModel`);
2. *a Gauss–Newton step* on the point-to-line distances (Censi 2008, the metric of his Section II)::

       r_k(x) = n_k^T (R(θ) p_k + t − q_k),     J_k = [n_k^T, n_k^T R'(θ) p_k]      (1 x 3)

   plus, when given, an odometry prior ``u`` with information ``Ω_u``: the error
   ``e_u = t2v(u^-1 x) = (R_u^T (t − t_u), θ − θ_u)`` is linear in ``x`` (Jacobian
   ``diag(R_u^T, 1)``), the lecture notes' error of one edge.

The Gauss–Newton steps weight each distance by ``1/σ̂²`` (``σ̂`` the residuals' standard
deviation, with Cauchy weights for outliers): against these raw weights the odometry prior only
matters where the scans say nothing (a corridor's axis).  The result's information matrix is
that ``H = J^T J / σ̂²`` divided by :data:`INFORMATION_SCALE` — the calibration.  The raw ``H``
treats the ~180 distances as independent, which they are not (a wall's points share one
modelling error, the scanner's bias and the ambiguity of the correspondences): on INTEL its NEES
``e^T H e`` against the reference poses has median 351 over 752 consecutive keyframe pairs,
where χ²₃'s median is 2.37 — about 150 times overconfident.  Chapter 10 shows the measurement.

*Degeneracy.*  In a straight corridor the walls constrain the position across the corridor but not
along it: ICP slides.  :attr:`Match.degeneracy` is the ratio ``λ_max / λ_min`` of the position
block of the scan information (θ marginalized), and :attr:`Match.weak_direction` the unit vector
along which the scans constrain the position least; a front end rejects loop closures with a large
ratio (:mod:`lagolib.frontend`).

Examples
--------
>>> import numpy as np
>>> from lagolib import scan_matching
>>> room = np.array([[x, y] for x in np.linspace(-2, 2, 41) for y in (-1.5, 1.5)]
...                 + [[x, y] for y in np.linspace(-1.5, 1.5, 31) for x in (-2.0, 2.0)])
>>> truth = np.array([0.10, -0.05, 0.03])          # pose of scan j in the frame of scan i
>>> R = np.array([[np.cos(0.03), -np.sin(0.03)], [np.sin(0.03), np.cos(0.03)]])
>>> scan_j = (room - truth[:2]) @ R                  # the same walls seen from pose j
>>> m = scan_matching.match(scan_matching.ScanModel(room), scan_j, np.zeros(3))
>>> bool(np.abs(m.pose - truth).max() < 1e-9), m.converged
(True, True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .checks import check_int, check_real
from .errors import OptionError

__all__ = [
    "INFORMATION_SCALE",
    "ScanModel",
    "Match",
    "match",
    "icp_step",
    "point_to_line_residuals",
    "Correlation",
    "correlative_search",
    "free_space_conflicts",
    "CAUCHY_C",
    "MIN_PAIR_DISTANCE",
    "MAX_SEARCH_POSES",
]

#: The raw ICP information ``J^T J / σ̂²`` is divided by this factor: the median NEES of the raw
#: information on INTEL's consecutive keyframes (scan term alone, no prior; the corridor matches
#: left out) is 351 against GMapping's poses, and 351 / 2.37 (χ²₃'s median) = 148.  The median,
#: because a few pairs where GMapping itself is off pull the mean up (mean 749, which would give
#: 250).  With it the accepted loop closures' NEES has median 2.5 and mean 4.5
#: (``tests/test_frontend.py``).
INFORMATION_SCALE = 150.0


@dataclass(frozen=True, eq=False)
class ScanModel:
    """A reference scan ready for point-to-line matching: its points, their normals, a k-d tree.

    Each normal is the direction of least spread of the point's ``neighbours`` nearest points (a
    line fit by principal components); a point whose neighbourhood is not a line (spread ratio
    above ``max_planarity``) or is wider than ``max_spread`` metres gets no normal and is never
    paired.

    Parameters
    ----------
    points : array_like, shape (m, 2)
        Sensor-frame points of the reference scan.
    neighbours : int
    max_spread : float
    max_planarity : float

    Attributes
    ----------
    points : ndarray, shape (m, 2)
    normals : ndarray, shape (m, 2)
        Unit normals (sensor frame); zero where ``usable`` is False.
    usable : ndarray of bool, shape (m,)
    tree : scipy.spatial.cKDTree
    """

    points: np.ndarray
    neighbours: int = 5
    max_spread: float = 0.5
    max_planarity: float = 0.1

    def __post_init__(self):
        q = _points(self.points, "ScanModel: points")
        k = check_int(self.neighbours, "neighbours", "ScanModel", minimum=2)
        tree = cKDTree(q)
        kk = min(k, len(q))
        dist, idx = tree.query(q, k=kk)
        dist, idx = dist.reshape(len(q), kk), idx.reshape(len(q), kk)
        nb = q[idx]  # (m, k, 2)
        centred = nb - nb.mean(axis=1, keepdims=True)
        cov = np.einsum("mki,mkj->mij", centred, centred) / kk
        w, v = np.linalg.eigh(cov)  # ascending: v[..., 0] is the normal direction
        normals = v[:, :, 0]
        usable = (
            (kk >= 2)
            & (w[:, 1] > 0)  # coincident points have no line
            & (dist[:, -1] <= self.max_spread)
            & (w[:, 0] <= self.max_planarity * np.maximum(w[:, 1], 1e-300))
        )
        normals = np.where(usable[:, None], normals, 0.0)
        object.__setattr__(self, "points", q)
        object.__setattr__(self, "normals", normals)
        object.__setattr__(self, "usable", usable)
        object.__setattr__(self, "tree", tree)

    def __len__(self):
        return len(self.points)


def _pose(value, what):
    """A finite pose ``(x, y, theta)`` as a float array of shape (3,)."""
    try:
        p = np.array(value, dtype=float)
    except (TypeError, ValueError):
        p = np.zeros(0)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise OptionError(f"{what} must be a finite pose (x, y, theta); got {value!r}")
    return p


def _points(value, what):
    try:
        p = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise OptionError(f"{what} must be an (m, 2) array of numbers") from None
    if p.ndim != 2 or p.shape[1] != 2:
        raise OptionError(f"{what} must have shape (m, 2); got {p.shape}")
    if len(p) < 3:
        raise OptionError(f"{what}: {len(p)} points; scan matching needs at least 3")
    if not np.all(np.isfinite(p)):
        raise OptionError(f"{what} holds non-finite values; drop the no-return beams first")
    return p


@dataclass(frozen=True, eq=False)
class Match:
    """Result of :func:`match`.

    Attributes
    ----------
    pose : ndarray, shape (3,)
        ``z_ij``: the pose of the current scan in the frame of the reference scan.
    information : ndarray, shape (3, 3)
        Of ``pose``, in the g2o convention (the error ``t2v(z^-1 x)``, frame of the reference
        scan's pose ``i`` rotated by ``z``): the calibrated scan information plus the prior's.
    scan_information : ndarray, shape (3, 3)
        The scan term alone, calibrated (``J^T J / (σ̂² INFORMATION_SCALE)``).
    sigma : float
        Residual standard deviation ``σ̂`` of the point-to-line distances (metres).
    rms : float
        Root mean square of the paired distances.
    pairs : int
        Correspondences used in the last step.
    inlier_fraction : float
        ``pairs`` over the current scan's points.
    degeneracy : float
        ``λ_max / λ_min`` of the scan information's position block with θ marginalized (1 for a
        scan constraining every direction alike; large in a corridor; inf when singular).
    weak_direction : ndarray, shape (2,)
        Unit vector (reference frame) of the least-constrained position direction.
    iterations : int
    converged : bool
        The step fell below ``tolerance``, or the iterates cycled (nearest-neighbour pairings can
        alternate between fixed points a fraction of a millimetre apart), with the pairing
        distance at its floor (``max(4 σ̂, MIN_PAIR_DISTANCE)``).
    """

    pose: np.ndarray
    information: np.ndarray
    scan_information: np.ndarray
    sigma: float
    rms: float
    pairs: int
    inlier_fraction: float
    degeneracy: float
    weak_direction: np.ndarray
    iterations: int
    converged: bool


def point_to_line_residuals(model, points, pose, pairs):
    """Point-to-line distances and their Jacobian (Censi 2008, Section II).

    Parameters
    ----------
    model : ScanModel
        Reference scan ``i``.
    points : ndarray, shape (m, 2)
        Current scan's points in its own sensor frame.
    pose : array_like, shape (3,)
        ``x``: current scan's pose in the reference frame.
    pairs : ndarray, shape (m,)
        Index into ``model.points`` of each point's partner.

    Returns
    -------
    r : ndarray, shape (m,)
        ``n^T (R(θ) p + t − q)``.
    J : ndarray, shape (m, 3)
        ``d r / d (t_x, t_y, θ)``.
    """
    c, s = math.cos(pose[2]), math.sin(pose[2])
    Rp = points @ np.array([[c, s], [-s, c]])  # R(θ) p for every row p
    n = model.normals[pairs]
    r = np.einsum(
        "mi,mi->m", n, Rp + pose[:2] - model.points[pairs]
    )  # Censi (2008): n^T (R p + t - q)
    dRp = np.column_stack([-Rp[:, 1], Rp[:, 0]])  # R'(θ) p = J R(θ) p
    J = np.column_stack([n, np.einsum("mi,mi->m", n, dRp)])
    return r, J


def _correspond(model, points, pose, max_distance):
    """Nearest usable reference point of every moved current point within ``max_distance``."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    moved = points @ np.array([[c, s], [-s, c]]) + pose[:2]
    dist, idx = model.tree.query(moved, distance_upper_bound=max_distance)
    ok = np.isfinite(dist)
    ok[ok] = model.usable[idx[ok]]
    return np.nonzero(ok)[0], idx[ok]


_DEGREE = math.pi / 180

#: Metres: the pairing distance is never tightened below this.
MIN_PAIR_DISTANCE = 0.1

#: :func:`correlative_search` refuses windows of more poses than this (memory and time).
MAX_SEARCH_POSES = 20_000_000

#: Cauchy's constant: 95 % efficiency at the normal distribution.
CAUCHY_C = 2.3849


def _robust_sigma(r):
    """``1.4826 · median |r|``, the normal-consistent median absolute deviation, floored."""
    return max(1.4826 * float(np.median(np.abs(r))), 1e-4)


def icp_step(
    model,
    points,
    pose,
    *,
    max_distance=0.5,
    prior=None,
    prior_information=None,
    weight_scale=1.0,
):
    """One point-to-line ICP iteration: correspondences, then one Gauss–Newton step.

    The readable core of :func:`match` (chapter 10 runs it step by step).

    Parameters
    ----------
    model : ScanModel
    points : ndarray, shape (m, 2)
        Current scan, its own sensor frame.
    pose : ndarray, shape (3,)
        Current guess of its pose in the reference frame.
    max_distance : float
        Pairs farther apart are not used (metres).
    prior, prior_information : ndarray, shape (3,) and (3, 3), optional
        Odometry prior ``u`` and its information (g2o convention).
    weight_scale : float
        The distances are weighted ``1 / (σ̂² weight_scale)`` against the prior (1: raw).

    Returns
    -------
    pose : ndarray, shape (3,)
        The updated guess.
    H : ndarray, shape (3, 3)
        The scan term's ``J^T J / σ̂²`` (uncalibrated) at the old guess.
    sigma : float
    used : ndarray of int
        Indices of the current points paired (inliers).
    r : ndarray
        Their residuals, times the square roots of their Cauchy weights.
    """
    cur, ref = _correspond(model, points, pose, max_distance)
    if len(cur) < 3:
        return pose, np.zeros((3, 3)), math.inf, cur, np.zeros(0)
    r, J = point_to_line_residuals(model, points[cur], pose, ref)
    sigma = _robust_sigma(r)
    # Cauchy weights (an M-estimator, Huber 1981): a pair far off counts little, and smoothly —
    # a hard cut would let the set of pairs flip back and forth between iterations
    w_r = 1.0 / (1.0 + (r / (CAUCHY_C * sigma)) ** 2)
    J = J * np.sqrt(w_r)[:, None]
    r = r * np.sqrt(w_r)
    sigma = max(math.sqrt(float(r @ r) / max(float(w_r.sum()) - 3, 1)), 1e-4)
    H_scan = J.T @ J / sigma**2  # the lecture notes' H = Σ J^T Ω J with Ω = 1/σ̂²
    w = 1.0 / (sigma**2 * weight_scale)  # weight of one distance against the prior
    H = J.T @ J * w
    g = J.T @ r * w
    if prior is not None:
        cu, su = math.cos(prior[2]), math.sin(prior[2])
        A = np.array([[cu, su, 0.0], [-su, cu, 0.0], [0.0, 0.0, 1.0]])  # d t2v(u^-1 x) / d x
        e = _between(prior, pose)  # e_u = t2v(u^-1 x)
        H = H + A.T @ prior_information @ A
        g = g + A.T @ prior_information @ e
    try:
        dx = -np.linalg.solve(H, g)  # the notes' Gauss–Newton step H Δx = −b
    except np.linalg.LinAlgError:
        dx = -np.linalg.lstsq(H, g, rcond=None)[0]
    new = pose + dx
    new[2] = math.remainder(new[2], 2 * math.pi)
    return new, H_scan, sigma, cur, r


def _between(a, b):
    """``t2v(v2t(a)^-1 v2t(b))`` of two single poses (:func:`lagolib.se2.between`, unchecked)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, math.remainder(b[2] - a[2], 2 * math.pi)])


def _degeneracy(info):
    """``λ_max/λ_min`` and the weak direction of the position block, θ marginalized."""
    if info[2, 2] > 0:
        P = info[:2, :2] - np.outer(info[:2, 2], info[2, :2]) / info[2, 2]  # Schur complement
    else:
        P = info[:2, :2]
    w, v = np.linalg.eigh(0.5 * (P + P.T))
    ratio = math.inf if w[0] <= 1e-12 * max(w[1], 1e-300) else float(w[1] / w[0])
    return ratio, v[:, 0]


def match(
    model,
    points,
    guess,
    *,
    prior_information=None,
    max_distance=0.5,
    max_iterations=60,
    tolerance=1e-4,
    information_scale=INFORMATION_SCALE,
    weight_scale=1.0,
):
    """Point-to-line ICP: the pose of ``points`` in the frame of ``model``.

    Parameters
    ----------
    model : ScanModel or array_like, shape (m, 2)
        Reference scan ``i`` (sensor frame).
    points : array_like, shape (m', 2)
        Current scan ``j`` in its own sensor frame.
    guess : array_like, shape (3,)
        Initial guess of ``z_ij`` — odometry's, or the graph's prediction.
    prior_information : array_like, shape (3, 3), optional
        When given, ``guess`` is also a prior with this information (g2o convention): the
        odometry prior.  ``None``: the guess only starts the iterations.
    max_distance : float
        Correspondences farther apart are ignored (metres); halved once the step is small, down
        to 4 σ̂, so that the last steps see only inliers.
    max_iterations : int
    tolerance : float
        Converged when the step is below it (metres and radians).
    information_scale : float
        The reported information is ``J^T J / (σ̂² information_scale)``
        (:data:`INFORMATION_SCALE`; 1 for the raw Hessian).
    weight_scale : float
        The weight of the scan against the prior in the iterations (see :func:`icp_step`).

    Returns
    -------
    Match
    """
    where = "match"
    if not isinstance(model, ScanModel):
        model = ScanModel(model)
    p = _points(points, f"{where}: points")
    x0 = _pose(guess, f"{where}: guess")
    max_distance = check_real(max_distance, "max_distance", where, minimum=0.0, strict=True)
    max_iterations = check_int(max_iterations, "max_iterations", where, minimum=1)
    tolerance = check_real(tolerance, "tolerance", where, minimum=0.0, strict=True)
    omega_u = None
    if prior_information is not None:
        omega_u = np.array(prior_information, dtype=float)
        if omega_u.shape != (3, 3) or not np.all(np.isfinite(omega_u)):
            raise OptionError(f"{where}: prior_information must be a finite 3x3 matrix")
        if np.any(np.linalg.eigvalsh(0.5 * (omega_u + omega_u.T)) < 0):
            raise OptionError(f"{where}: prior_information must be positive semidefinite")
    x = x0.copy()
    d = max_distance
    converged = False
    H_scan, sigma, used = np.zeros((3, 3)), math.inf, np.zeros(0, int)
    r = np.zeros(0)
    recent = []  # the last iterates at this pairing distance: the nearest-neighbour pairing
    it = 0
    while it < max_iterations:  # can cycle through a few mm-apart fixed points
        it += 1
        new, H_scan, sigma, used, r = icp_step(
            model,
            p,
            x,
            max_distance=d,
            prior=x0 if omega_u is not None else None,
            prior_information=omega_u,
            weight_scale=weight_scale,
        )
        step = float(np.abs(_between(x, new)).max())
        cycle = any(float(np.abs(_between(old, new)).max()) < tolerance for old in recent)
        recent = (recent + [new])[-8:]
        x = new
        if len(used) < 3:
            break
        floor = max(4 * sigma, MIN_PAIR_DISTANCE)
        settled = step < tolerance or cycle
        if settled and d <= floor:
            converged = True
            break
        if (settled or step < 1e-3) and d > floor:  # near a fixed point: tighten the pairing
            d = max(d / 2, floor)
            recent = []
    scan_info = H_scan / information_scale
    info = scan_info.copy()
    if omega_u is not None:
        cu, su = math.cos(x0[2]), math.sin(x0[2])
        A = np.array([[cu, su, 0.0], [-su, cu, 0.0], [0.0, 0.0, 1.0]])
        info = info + A.T @ omega_u @ A
    info = _to_g2o(info, x)
    ratio, weak = _degeneracy(scan_info)
    rms = float(np.sqrt(np.mean(r**2))) if len(r) else math.inf
    return Match(
        pose=x,
        information=info,
        scan_information=_to_g2o(scan_info, x),
        sigma=float(sigma),
        rms=rms,
        pairs=int(len(used)),
        inlier_fraction=len(used) / len(p),
        degeneracy=ratio,
        weak_direction=weak,
        iterations=it,
        converged=converged,
    )


def _to_g2o(info_x, z):
    """Information of the parameters ``x = (t, θ)`` → of the error ``t2v(z^-1 x)`` (g2o).

    Near ``x = z`` the error is ``diag(R_z^T, 1) (x − z)``, so ``Ω_e = G^T Ω_x G`` with
    ``G = diag(R_z, 1)``.
    """
    c, s = math.cos(z[2]), math.sin(z[2])
    G = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    out = G.T @ info_x @ G
    return 0.5 * (out + out.T)


@dataclass(frozen=True, eq=False)
class Correlation:
    """Result of :func:`correlative_search`.

    Attributes
    ----------
    pose : ndarray, shape (3,)
        Best pose of the current scan in the reference frame on the search grid.
    score : float
        Its mean likelihood per point, in (0, 1].
    evaluated : int
        Poses scored.
    ambiguity : float
        The best score among poses at least ``separation`` metres from ``pose``, over ``score``:
        near 1 when another placement fits as well (a corridor's repeated doors), low for a
        unique fit.
    """

    pose: np.ndarray
    score: float
    evaluated: int
    ambiguity: float


def _likelihood_field(model, resolution, sigma, margin):
    """``exp(-d²/2σ²)`` of the distance ``d`` to the nearest reference point on a grid."""
    from scipy.ndimage import distance_transform_edt

    lo = model.points.min(axis=0) - margin
    shape = np.ceil((model.points.max(axis=0) + margin - lo) / resolution).astype(int) + 1
    hit = np.ones(shape, dtype=bool)
    cells = np.floor((model.points - lo) / resolution).astype(int)
    hit[cells[:, 0], cells[:, 1]] = False
    d = distance_transform_edt(hit) * resolution
    return lo, np.exp(-0.5 * (d / sigma) ** 2)  # Olson (2009): the lookup table


def correlative_search(
    model,
    points,
    prediction,
    *,
    window=(1.0, 10 * _DEGREE),
    resolution=0.1,
    angular_step=1.5 * _DEGREE,
    sigma=None,
    max_points=90,
    separation=0.5,
):
    """Brute-force search of a window around ``prediction`` on a likelihood grid (Olson 2009).

    Where ICP needs a guess inside its basin (a few decimetres, a few degrees), correlative
    scan matching scores every pose of a grid — ``dx, dy`` ``resolution`` apart within
    ``±window[0]`` metres of the prediction, ``θ`` ``angular_step`` apart within ``±window[1]`` —
    by the mean of the reference scan's likelihood field at the moved points (Olson, "Real-time
    correlative scan matching", ICRA 2009, Section III).  The best pose starts ICP.

    Parameters
    ----------
    model : ScanModel
        Reference scan ``i``.
    points : ndarray, shape (m, 2)
        Current scan ``j`` in its sensor frame (subsampled to ``max_points``).
    prediction : array_like, shape (3,)
        Centre of the window: the predicted pose of ``j`` in the frame of ``i``.
    window : (float, float)
        Half widths in metres and radians.
    resolution : float
        Grid step in metres (also the field's cell size).
    angular_step : float
    sigma : float, optional
        Width of the likelihood (metres), default ``resolution``.
    max_points : int
    separation : float
        Metres: :attr:`Correlation.ambiguity` compares with poses at least this far away.

    Returns
    -------
    Correlation
    """
    where = "correlative_search"
    if not isinstance(model, ScanModel):
        model = ScanModel(model)
    p = _points(points, f"{where}: points")
    z = _pose(prediction, f"{where}: prediction")
    try:
        half, ang = (float(w) for w in window)
    except (TypeError, ValueError):
        raise OptionError(f"{where}: window must be (metres, radians); got {window!r}") from None
    check_real(half, "window[0]", where, minimum=0.0, maximum=100.0)
    check_real(ang, "window[1]", where, minimum=0.0, maximum=math.pi)
    resolution = check_real(resolution, "resolution", where, minimum=1e-3, strict=True)
    angular_step = check_real(angular_step, "angular_step", where, minimum=1e-4, strict=True)
    max_points = check_int(max_points, "max_points", where, minimum=3)
    separation = check_real(separation, "separation", where, minimum=0.0)
    sigma = (
        resolution if sigma is None else check_real(sigma, "sigma", where, minimum=0, strict=True)
    )
    if len(p) > max_points:
        p = p[np.linspace(0, len(p) - 1, max_points).astype(int)]
    n_poses = (2 * int(round(half / resolution)) + 1) ** 2 * (2 * int(ang / angular_step) + 1)
    if n_poses > MAX_SEARCH_POSES:
        raise OptionError(
            f"{where}: the window holds {n_poses:.3g} poses (more than {MAX_SEARCH_POSES:.0e}); "
            "narrow the window or coarsen resolution / angular_step"
        )
    key = (resolution, sigma, half)
    cache = model.__dict__.setdefault("_fields", {})
    if key not in cache:
        cache[key] = _likelihood_field(model, resolution, sigma, half + 1.0)
    lo, field = cache[key]
    k = int(round(half / resolution))
    offsets = np.arange(-k, k + 1)
    thetas = z[2] + np.arange(-int(ang / angular_step), int(ang / angular_step) + 1) * angular_step
    scores = np.empty((len(thetas), len(offsets), len(offsets)))
    for t, th in enumerate(thetas):  # one rotation at a time; every translation of the grid at once
        c, s = math.cos(th), math.sin(th)
        moved = p @ np.array([[c, s], [-s, c]]) + z[:2]
        base = np.floor((moved - lo) / resolution).astype(int)  # (m, 2) cells at zero offset
        ix = np.clip(base[:, 0][None, :] + offsets[:, None], 0, field.shape[0] - 1)  # (o, m)
        iy = np.clip(base[:, 1][None, :] + offsets[:, None], 0, field.shape[1] - 1)
        scores[t] = field[ix[:, None, :], iy[None, :, :]].mean(axis=2)  # (o, o): dx by dy
    t, a, b = np.unravel_index(np.argmax(scores), scores.shape)
    best = float(scores[t, a, b])
    far = np.hypot(*np.meshgrid(offsets - offsets[a], offsets - offsets[b], indexing="ij"))
    far = far * resolution >= separation
    runner_up = float(scores[:, far].max()) if far.any() else 0.0
    pose = np.array([z[0] + offsets[a] * resolution, z[1] + offsets[b] * resolution, thetas[t]])
    return Correlation(pose, best, scores.size, runner_up / best if best > 0 else 1.0)


def free_space_conflicts(ranges_i, angles, max_range, points_j, pose, *, margin=0.3):
    """Fraction of scan ``j``'s returns that the match puts where scan ``i`` saw through.

    Each point of ``j``, moved into the frame of ``i`` by ``pose``, falls on some beam of ``i``
    (the nearest in angle).  If it lies more than ``margin`` metres *in front of* that beam's
    return, scan ``i`` saw free space there: a wall of ``j`` cannot be where ``i`` saw through
    (the ray-consistency test of map matching, e.g. Hähnel et al. 2003).  An alias — a
    corridor's next door — typically puts some walls into seen-through space.

    Parameters
    ----------
    ranges_i : ndarray, shape (n,)
        Scan ``i``'s ranges; ``>= max_range`` is "no return" (free as far as ``max_range``).
    angles : ndarray, shape (n,)
        Its beam angles (increasing, evenly spaced), sensor frame.
    max_range : float
    points_j : ndarray, shape (m, 2)
        Scan ``j``'s returns in its own frame.
    pose : array_like, shape (3,)
        Pose of ``j`` in the frame of ``i``.
    margin : float

    Returns
    -------
    float
    """
    where = "free_space_conflicts"
    r_i = np.asarray(ranges_i, dtype=float)
    a = np.asarray(angles, dtype=float)
    if r_i.ndim != 1 or a.shape != r_i.shape or len(a) < 2:
        raise OptionError(f"{where}: ranges_i and angles must be 1-D of one length (>= 2)")
    pts = _points(points_j, f"{where}: points_j")
    pose = _pose(pose, f"{where}: pose")
    c, s = math.cos(pose[2]), math.sin(pose[2])
    q = pts @ np.array([[c, s], [-s, c]]) + pose[:2]
    rho = np.hypot(q[:, 0], q[:, 1])
    phi = np.arctan2(q[:, 1], q[:, 0])
    step = (a[-1] - a[0]) / (len(a) - 1)
    beam = np.rint((phi - a[0]) / step).astype(int)
    inside = (beam >= 0) & (beam < len(a))
    if not inside.any():
        return 0.0
    r = r_i[beam[inside]]
    seen = np.where(np.isfinite(r) & (r > 0), np.minimum(r, max_range), 0.0)
    return float(np.mean(rho[inside] < seen - margin))
