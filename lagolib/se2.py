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
Every function checks its arguments before computing: complex numbers (which numpy would convert
by dropping their imaginary part), text, booleans, ``None`` and other non-numbers raise
:class:`~lagolib.errors.OptionTypeError` (a :class:`TypeError`); a wrong last dimension or
arguments that do not broadcast against each other raise :class:`~lagolib.errors.OptionError`
(a :class:`ValueError`) — each message names the function and the argument.  Values are not
checked: IEEE arithmetic carries a NaN or an infinity through to the result.

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

import numbers

import numpy as np

from .errors import OptionError, OptionTypeError

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


_KINDS = {"c": "complex", "U": "text", "S": "text", "b": "bool", "M": "date", "m": "time delta"}


def _real(a, name, where="se2"):
    """``a`` as a float ndarray; complex, text, bool, None and other non-numbers are refused.

    numpy would drop an imaginary part (with a warning), parse text and turn ``True`` into 1 and
    ``None`` into NaN: each is an :class:`~lagolib.errors.OptionTypeError` naming ``where`` and
    ``name`` instead.
    """
    try:
        arr = np.asarray(a)
    except (TypeError, ValueError) as exc:  # ragged nesting
        raise OptionError(f"{where}: {name} must be a numeric array: {exc}") from None
    kind = arr.dtype.kind
    if kind in "iuf":
        return arr.astype(float, copy=False)
    if kind == "O":
        for x in arr.ravel().tolist():
            if isinstance(x, complex | np.complexfloating):
                kind = "c"
                break
            if isinstance(x, bool | np.bool_) or not isinstance(x, numbers.Real):
                raise OptionTypeError(
                    f"{where}: {name} must hold real numbers; it holds {x!r} ({type(x).__name__})"
                )
        else:
            try:
                return arr.astype(float)
            except (TypeError, ValueError, OverflowError) as exc:
                raise OptionError(f"{where}: {name} must hold real numbers: {exc}") from None
    if kind == "c":
        raise OptionTypeError(
            f"{where}: {name} must be real; got a complex array (dtype {arr.dtype}): numpy would "
            "drop the imaginary part"
        )
    raise OptionTypeError(
        f"{where}: {name} must be an array of real numbers; got a "
        f"{_KINDS.get(kind, 'non-numeric')} array (dtype {arr.dtype})"
    )


def _broadcast(where, *named):
    """Raise OptionError unless the arrays ``named`` (``(name, array, trailing dims)``) broadcast
    against each other in their leading dimensions."""
    try:
        np.broadcast_shapes(*(a.shape[: a.ndim - k] for _, a, k in named))
    except ValueError:
        shapes = ", ".join(f"{name} {a.shape}" for name, a, _ in named)
        raise OptionError(
            f"{where}: the arguments do not broadcast against each other: {shapes} (stacks of "
            "poses must have equal leading shapes, or one of them 1)"
        ) from None


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
    theta = _real(theta, "theta", "se2.wrap_angle")
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
    theta = _real(theta, "theta", "se2.rotation")
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], axis=-1), np.stack([s, c], axis=-1)], axis=-2)


def _as_poses(p, name="pose", where="se2"):
    p = _real(p, name, where)
    if p.shape[-1:] != (3,):
        raise OptionError(
            f"{where}: {name} must have shape (..., 3) as (x, y, theta); got shape {p.shape}"
        )
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
    p = _as_poses(p, "p", "se2.v2t")
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
    T = _real(T, "T", "se2.t2v")
    if T.ndim < 2 or T.shape[-2:] != (3, 3):
        raise OptionError(f"se2.t2v: T must have shape (..., 3, 3); got shape {T.shape}")
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
    a, b = _as_poses(a, "a", "se2.compose"), _as_poses(b, "b", "se2.compose")
    _broadcast("se2.compose", ("a", a, 1), ("b", b, 1))
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
    p = _as_poses(p, "p", "se2.inverse")
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
    p_i, p_j = _as_poses(p_i, "p_i", "se2.between"), _as_poses(p_j, "p_j", "se2.between")
    _broadcast("se2.between", ("p_i", p_i, 1), ("p_j", p_j, 1))
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
    h = 0.5 * np.asarray(theta, dtype=float)  # callers checked it
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
    p = _as_poses(p, "p", "se2.log")
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
    v = _as_poses(v, "v", "se2.exp")
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
    p = _as_poses(p, "p", "se2.log_jacobian")
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
    theta_z = np.asarray(theta_z, dtype=float)  # checked by the callers
    G = np.zeros(theta_z.shape + (3, 3))
    G[..., :2, :2] = rotation(theta_z)
    G[..., 2, 2] = 1.0
    return G


def _information_args(information, theta_z, where):
    """Checked ``(information (..., 3, 3), theta_z (...))`` that broadcast against each other."""
    information = _real(information, "information", where)
    theta_z = _real(theta_z, "theta_z", where)
    if information.ndim < 2 or information.shape[-2:] != (3, 3):
        raise OptionError(
            f"{where}: information must have shape (m, 3, 3), one 3x3 matrix per measurement; got "
            f"shape {information.shape}"
        )
    _broadcast(where, ("information", information, 2), ("theta_z", theta_z, 0))
    return information, theta_z


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
    information, theta_z = _information_args(information, theta_z, "se2.information_to_frame_i")
    G = _frame_rotations(theta_z)
    return G @ information @ np.swapaxes(G, -1, -2)


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
    information, theta_z = _information_args(information, theta_z, "se2.information_from_frame_i")
    G = _frame_rotations(theta_z)
    return np.swapaxes(G, -1, -2) @ information @ G
