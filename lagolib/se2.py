"""Planar poses: the group SE(2) as used by all three sources.

A pose is a vector ``p = (x, y, theta)``: the position ``rho = (x, y)`` of a robot and its heading
``theta``.  Every function here is vectorized over leading dimensions: an array of shape
``(..., 3)`` is a stack of poses, and arguments broadcast against each other like numpy arrays.

The operations are the ones of the lecture notes' "Transformations" slide and of Carlone et al.
2011, eq. (1):

* ``v2t`` / ``t2v`` convert between the vector ``(x, y, theta)`` and the homogeneous matrix
  ``[[R(theta), rho], [0, 0, 1]]``;
* ``compose(a, b)`` is ``a ⊕ b`` (``v2t(a) @ v2t(b)``): pose ``b``, given in the frame of ``a``,
  expressed in the world frame;
* ``inverse(p)`` is ``⊖p`` (``v2t(p)^-1``);
* ``between(p_i, p_j)`` is ``p_j ⊖ p_i`` (``v2t(p_i)^-1 v2t(p_j)``): where ``j`` is, seen from
  ``i``.  This is what a relative pose measurement ``z_ij`` measures.
* ``log`` / ``exp`` are the Lie-group logarithm and exponential of SE(2), the coordinates GTSAM
  measures its errors in (``Pose2.Logmap``); ``log_jacobian`` is the derivative of ``log``.

Angles returned by these functions are wrapped to ``(-pi, pi]``.

Angles given to lagolib (in files and in a :class:`~lagolib.PoseGraph`) must satisfy
``|theta| <= MAX_ANGLE = 1e9`` rad.  Beyond that float64 cannot reduce an angle consistently: the
spacing of float64 numbers at ``1e9`` is 1.2e-7 rad, and the two reductions lagolib relies on —
:func:`wrap_angle` (modulo the float64 value of ``2 pi``) and the exact reduction inside ``cos`` /
``sin`` — already disagree by up to 7e-8 rad there (4.8e-5 rad at 1e12, 0.06 rad at 1e15).
Arrays of complex numbers are rejected with a :class:`~lagolib.errors.GraphTypeError` (a
:class:`TypeError`) instead of losing their imaginary
part.

Examples
--------
>>> import numpy as np
>>> from lagolib import se2
>>> a = np.array([1.0, 2.0, np.pi / 2])
>>> b = np.array([1.0, 0.0, 0.0])
>>> se2.compose(a, b)             # one metre forward from a, which faces +y
array([1.        , 3.        , 1.57079633])
>>> se2.between(a, se2.compose(a, b)).round(12)
array([1., 0., 0.])
"""

from __future__ import annotations

import numpy as np

from .errors import GraphTypeError

__all__ = [
    "MAX_ANGLE",
    "wrap_angle",
    "rotation",
    "v2t",
    "t2v",
    "compose",
    "inverse",
    "between",
    "log",
    "exp",
    "log_jacobian",
    "information_to_frame_i",
    "information_from_frame_i",
]

_TWO_PI = 2.0 * np.pi

MAX_ANGLE = 1e9
"""Largest ``|theta|`` (rad) lagolib accepts in a file or a pose graph (module docstring)."""


def _real(a, name):
    """``np.asarray(a, dtype=float)``, refusing complex input instead of dropping its imaginary part."""
    arr = np.asarray(a)
    if arr.dtype.kind == "c":
        raise GraphTypeError(f"{name} must be real; got a complex array (dtype {arr.dtype})")
    return np.asarray(arr, dtype=float)


def wrap_angle(theta):
    """Wrap angles to the interval ``(-pi, pi]``.

    Angles already inside the interval are returned unchanged, bit for bit (so tiny angles keep
    all their digits); the others are shifted by the multiple of ``2 pi`` that brings them in.

    Parameters
    ----------
    theta : array_like, shape (...)
        Angles in radians.

    Returns
    -------
    ndarray, shape (...)
        The wrapped angles; ``-pi`` maps to ``+pi``.

    Examples
    --------
    >>> wrap_angle([np.pi, -np.pi, 3 * np.pi / 2]).tolist()
    [3.141592653589793, 3.141592653589793, -1.5707963267948966]
    >>> float(wrap_angle(1e-300)) == 1e-300   # inside the interval: untouched, every digit kept
    True
    """
    theta = _real(theta, "theta")
    outside = (theta > np.pi) | (theta <= -np.pi)
    if not np.any(outside):
        return theta.copy()
    wrapped = np.pi - np.mod(np.pi - theta, _TWO_PI)
    return np.where(outside, wrapped, theta)


def rotation(theta):
    """Planar rotation matrices ``R(theta) = [[cos, -sin], [sin, cos]]``.

    Parameters
    ----------
    theta : array_like, shape (...)

    Returns
    -------
    ndarray, shape (..., 2, 2)
    """
    theta = _real(theta, "theta")
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], axis=-1), np.stack([s, c], axis=-1)], axis=-2)


def _as_poses(p, name="pose"):
    p = _real(p, name)
    if p.shape[-1:] != (3,):
        raise ValueError(f"{name} must have shape (..., 3) as (x, y, theta); got shape {p.shape}")
    return p


def v2t(p):
    """Pose vector to homogeneous transform (lecture notes, "Transformations").

    Parameters
    ----------
    p : array_like, shape (..., 3)
        Poses ``(x, y, theta)``.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``[[cos, -sin, x], [sin, cos, y], [0, 0, 1]]``.
    """
    p = _as_poses(p)
    T = np.zeros(p.shape[:-1] + (3, 3))
    T[..., :2, :2] = rotation(p[..., 2])
    T[..., :2, 2] = p[..., :2]
    T[..., 2, 2] = 1.0
    return T


def t2v(T):
    """Homogeneous transform to pose vector, the inverse of :func:`v2t`.

    Parameters
    ----------
    T : array_like, shape (..., 3, 3)
        Homogeneous planar transforms (the rotation block must be a rotation).

    Returns
    -------
    ndarray, shape (..., 3)
        ``(T[0, 2], T[1, 2], atan2(T[1, 0], T[0, 0]))``; the angle is in ``(-pi, pi]``.
    """
    T = _real(T, "T")
    if T.shape[-2:] != (3, 3):
        raise ValueError(f"T must have shape (..., 3, 3); got shape {T.shape}")
    theta = wrap_angle(np.arctan2(T[..., 1, 0], T[..., 0, 0]))
    return np.stack([T[..., 0, 2], T[..., 1, 2], theta], axis=-1)


def compose(a, b):
    """Pose compounding ``a ⊕ b``: ``b`` (given in the frame of ``a``) in the world frame.

    ``compose(a, b) == t2v(v2t(a) @ v2t(b))`` = ``[rho_a + R(theta_a) rho_b; theta_a + theta_b]``.

    Parameters
    ----------
    a, b : array_like, shape (..., 3)
        Broadcast against each other.

    Returns
    -------
    ndarray, shape (..., 3)
    """
    a, b = _as_poses(a, "a"), _as_poses(b, "b")
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return np.stack([x, y, wrap_angle(a[..., 2] + b[..., 2])], axis=-1)


def inverse(p):
    """Inverse pose ``⊖p`` = ``t2v(v2t(p)^-1)`` = ``[-R(theta)^T rho; -theta]``.

    Parameters
    ----------
    p : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3)
    """
    p = _as_poses(p)
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    x = -(c * p[..., 0] + s * p[..., 1])
    y = -(-s * p[..., 0] + c * p[..., 1])
    return np.stack([x, y, wrap_angle(-p[..., 2])], axis=-1)


def between(p_i, p_j):
    """Relative pose ``p_j ⊖ p_i``: pose ``j`` expressed in the frame of pose ``i``.

    Carlone et al. 2011, eq. (1)::

        p_j ⊖ p_i = [ R_i^T (rho_j - rho_i) ;  theta_j - theta_i ]

    which equals ``t2v(v2t(p_i)^-1 v2t(p_j))`` (the lecture notes' ``X_i^-1 X_j``).  The angle is
    wrapped to ``(-pi, pi]``.

    Parameters
    ----------
    p_i, p_j : array_like, shape (..., 3)
        Broadcast against each other.

    Returns
    -------
    ndarray, shape (..., 3)
    """
    p_i, p_j = _as_poses(p_i, "p_i"), _as_poses(p_j, "p_j")
    c, s = np.cos(p_i[..., 2]), np.sin(p_i[..., 2])
    dx = p_j[..., 0] - p_i[..., 0]
    dy = p_j[..., 1] - p_i[..., 1]
    # eq. (1): R_i^T (rho_j - rho_i)
    x = c * dx + s * dy
    y = -s * dx + c * dy
    return np.stack([x, y, wrap_angle(p_j[..., 2] - p_i[..., 2])], axis=-1)


# h cot h = sum_n (-1)^n 2^(2n) B_2n h^(2n) / (2n)!: its Taylor coefficients in h^2 (for |h| small,
# where the closed forms cancel catastrophically)
_HCOT = (1.0, -1.0 / 3.0, -1.0 / 45.0, -2.0 / 945.0, -1.0 / 4725.0)
_SMALL = 1e-2


def _half_cot(theta):
    """``c = h cot h`` with ``h = theta/2``, and ``dc/dtheta``; both smooth through 0."""
    h = 0.5 * _real(theta, "theta")
    small = np.abs(h) < _SMALL
    hs = np.where(small, 1.0, h)  # keeps the closed forms finite where the series is used
    with np.errstate(divide="ignore", invalid="ignore"):
        c_exact = hs * np.cos(hs) / np.sin(hs)
        dc_exact = 0.5 * (np.cos(hs) / np.sin(hs) - hs / np.sin(hs) ** 2)
    h2 = h * h
    c_series = _HCOT[0] + h2 * (_HCOT[1] + h2 * (_HCOT[2] + h2 * (_HCOT[3] + h2 * _HCOT[4])))
    # d/dtheta = 1/2 d/dh
    dc_series = h * (_HCOT[1] + h2 * (2 * _HCOT[2] + h2 * (3 * _HCOT[3] + h2 * 4 * _HCOT[4])))
    return np.where(small, c_series, c_exact), np.where(small, dc_series, dc_exact)


def log(p):
    """Logarithm of SE(2): the twist ``v = (v_x, v_y, theta)`` with ``exp(v) = p``.

    With ``h = theta / 2`` (``theta`` wrapped to ``(-pi, pi]``)::

        (v_x, v_y) = V(theta)^-1 (x, y),   V(theta)^-1 = [[h cot h, h], [-h, h cot h]]

    This is GTSAM's ``Pose2.Logmap``: GTSAM measures the error of a ``BetweenFactorPose2`` as
    ``log(Z_ij^-1 X_i^-1 X_j)`` where the lecture notes (and g2o) take ``t2v`` of the same
    transform.  The two agree in the angle and to first order in the translation.

    Parameters
    ----------
    p : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3)

    Examples
    --------
    >>> import numpy as np
    >>> from lagolib import se2
    >>> v = np.array([1.0, -2.0, 0.5])
    >>> np.allclose(se2.log(se2.exp(v)), v)
    True
    """
    p = _as_poses(p)
    theta = wrap_angle(p[..., 2])
    c, _ = _half_cot(theta)
    h = 0.5 * theta
    vx = c * p[..., 0] + h * p[..., 1]
    vy = -h * p[..., 0] + c * p[..., 1]
    return np.stack([vx, vy, theta], axis=-1)


def exp(v):
    """Exponential of SE(2): the pose reached by the twist ``v = (v_x, v_y, theta)``.

    ``(x, y) = V(theta) (v_x, v_y)`` with ``V = [[sin t / t, -(1 - cos t) / t],
    [(1 - cos t) / t, sin t / t]]`` (``V = I`` at ``theta = 0``); the angle is wrapped.

    Parameters
    ----------
    v : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3)
    """
    v = _as_poses(v, "v")
    t = v[..., 2]
    small = np.abs(t) < _SMALL
    ts = np.where(small, 1.0, t)
    t2 = t * t
    a = np.where(small, 1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0)), np.sin(ts) / ts)
    b = np.where(small, t / 2.0 * (1.0 - t2 / 12.0 * (1.0 - t2 / 30.0)), (1.0 - np.cos(ts)) / ts)
    x = a * v[..., 0] - b * v[..., 1]
    y = b * v[..., 0] + a * v[..., 1]
    return np.stack([x, y, wrap_angle(t)], axis=-1)


def log_jacobian(p):
    """Derivative of :func:`log` with respect to ``p = (x, y, theta)``.

    With ``c = h cot h``, ``h = theta / 2`` and ``c' = dc/dtheta``::

        d log / d p = [[ c,  h, c' x + y / 2],
                       [-h,  c, c' y - x / 2],
                       [ 0,  0, 1          ]]

    Parameters
    ----------
    p : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    p = _as_poses(p)
    theta = wrap_angle(p[..., 2])
    c, dc = _half_cot(theta)
    h = 0.5 * theta
    x, y = p[..., 0], p[..., 1]
    D = np.zeros(p.shape[:-1] + (3, 3))
    D[..., 0, 0], D[..., 0, 1], D[..., 0, 2] = c, h, dc * x + 0.5 * y
    D[..., 1, 0], D[..., 1, 1], D[..., 1, 2] = -h, c, dc * y - 0.5 * x
    D[..., 2, 2] = 1.0
    return D


# --------------------------------------------------------------------------- information frames
def _frame_rotations(theta_z):
    """``G = blockdiag(R(θ_z), 1)`` per measurement, shape (m, 3, 3)."""
    theta_z = _real(theta_z, "theta_z")
    G = np.zeros(theta_z.shape + (3, 3))
    G[..., :2, :2] = rotation(theta_z)
    G[..., 2, 2] = 1.0
    return G


def information_to_frame_i(information, theta_z):
    """Edge information from the **g2o frame** to the **frame of pose i**: ``G Ω Gᵀ``.

    lagolib (and g2o, and the lecture notes' error ``t2v(Z⁻¹ X_i⁻¹ X_j)``) weights the position
    error rotated into the frame of the measured pose, ``R_zᵀ(R_iᵀ(t_j − t_i) − t_z)``.  LAGO's
    cost (Carlone et al. 2011, eq. 3–4) and TORO files weight it in the frame of pose ``i``,
    ``R_iᵀ(t_j − t_i) − t_z``.  With ``G = blockdiag(R(θ_z), 1)`` the g2o error is ``Gᵀ`` times the
    frame-``i`` error, so the same quadratic form has the information ``G Ω Gᵀ`` in frame ``i``.

    Parameters
    ----------
    information : array_like, shape (m, 3, 3)
        Information in the g2o frame, (x, y, θ) order.
    theta_z : array_like, shape (m,)
        Measured relative angles ``θ_z``.

    Returns
    -------
    ndarray, shape (m, 3, 3)
        Information in the frame of each edge's tail pose ``i``.

    Examples
    --------
    >>> import numpy as np
    >>> O = information_to_frame_i([np.diag([100.0, 1.0, 10.0])], [np.pi / 2])
    >>> np.round(O[0], 12) + 0.0
    array([[  1.,   0.,   0.],
           [  0., 100.,   0.],
           [  0.,   0.,  10.]])
    """
    G = _frame_rotations(theta_z)
    return G @ _real(information, "information") @ np.swapaxes(G, -1, -2)


def information_from_frame_i(information, theta_z):
    """Edge information from the **frame of pose i** (TORO, LAGO) to the **g2o frame**: ``Gᵀ Ω G``.

    The inverse of :func:`information_to_frame_i`.

    Parameters
    ----------
    information : array_like, shape (m, 3, 3)
        Information in the frame of each edge's tail pose ``i``.
    theta_z : array_like, shape (m,)
        Measured relative angles ``θ_z``.

    Returns
    -------
    ndarray, shape (m, 3, 3)
        Information in the g2o frame.
    """
    G = _frame_rotations(theta_z)
    return np.swapaxes(G, -1, -2) @ _real(information, "information") @ G
