"""Symbolic derivations with sympy, so that the chapters can show where the formulas come from.

Lecture notes, "Building the Linear System", step 2 — "Compute the blocks of the Jacobian":
:func:`edge_error` builds ``e_ij = t2v(Z_ij^-1 X_i^-1 X_j)`` from homogeneous matrices and
:func:`edge_jacobians` differentiates it, ``A_ij = de/dx_i`` and ``B_ij = de/dx_j``.  Nothing is
typed in: the blocks are what sympy's ``jacobian`` and ``simplify`` return, and the tests compare
them with :func:`lagolib.gauss_newton.edge_jacobians` at random points.

Results are cached (a derivation takes about a second) and returned as immutable sympy matrices.

Examples
--------
>>> from lagolib import symbolic
>>> d = symbolic.edge_jacobians()
>>> d.B
Matrix([
[ cos(theta_i + theta_z), sin(theta_i + theta_z), 0],
[-sin(theta_i + theta_z), cos(theta_i + theta_z), 0],
[                      0,                      0, 1]])
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import sympy as sp

__all__ = [
    "pose_symbols",
    "v2t",
    "t2v",
    "inverse_transform",
    "edge_error",
    "edge_jacobians",
    "EdgeDerivation",
    "numeric_edge_jacobians",
]


def pose_symbols(name):
    """Real symbols ``(x_name, y_name, theta_name)`` of a pose."""
    return sp.symbols(f"x_{name} y_{name} theta_{name}", real=True)


def v2t(pose):
    """Homogeneous transform ``[[cos, -sin, x], [sin, cos, y], [0, 0, 1]]`` of a symbolic pose."""
    x, y, theta = pose
    return sp.Matrix(
        [[sp.cos(theta), -sp.sin(theta), x], [sp.sin(theta), sp.cos(theta), y], [0, 0, 1]]
    )


def inverse_transform(T):
    """``T^-1 = [[R^T, -R^T t], [0, 1]]`` (no general matrix inverse, so it stays readable)."""
    R, t = T[:2, :2], T[:2, 2]
    Rt = R.T
    out = sp.eye(3)
    out[:2, :2] = Rt
    out[:2, 2] = -Rt * t
    return out


def t2v(T):
    """``(T[0, 2], T[1, 2], atan2(T[1, 0], T[0, 0]))`` as a 3x1 matrix."""
    return sp.Matrix([T[0, 2], T[1, 2], sp.atan2(T[1, 0], T[0, 0])])


@dataclass(frozen=True)
class EdgeDerivation:
    """The lecture notes' error and Jacobian blocks, derived symbolically.

    Attributes
    ----------
    e : sympy.ImmutableMatrix, shape (3, 1)
        ``t2v(Z^-1 X_i^-1 X_j)``, simplified.
    A, B : sympy.ImmutableMatrix, shape (3, 3)
        ``de/dx_i`` and ``de/dx_j``, simplified.
    x_i, x_j, z : tuple of sympy.Symbol
        The symbols ``(x, y, theta)`` of the two poses and of the measurement.
    """

    e: sp.ImmutableMatrix
    A: sp.ImmutableMatrix
    B: sp.ImmutableMatrix
    x_i: tuple
    x_j: tuple
    z: tuple


@lru_cache(maxsize=None)
def edge_error():
    """``e_ij = t2v(Z_ij^-1 (X_i^-1 X_j))`` (lecture notes, "The Error Function"), simplified.

    Returns
    -------
    e : sympy.ImmutableMatrix, shape (3, 1)
    symbols : tuple
        ``(x_i, x_j, z)``, each a tuple of three symbols.
    """
    x_i, x_j, z = pose_symbols("i"), pose_symbols("j"), pose_symbols("z")
    T = inverse_transform(v2t(z)) * inverse_transform(v2t(x_i)) * v2t(x_j)
    e = t2v(sp.simplify(T))
    return sp.ImmutableMatrix(sp.simplify(e)), (x_i, x_j, z)


@lru_cache(maxsize=None)
def edge_jacobians():
    """``A_ij = de_ij/dx_i`` and ``B_ij = de_ij/dx_j`` by symbolic differentiation.

    Lecture notes, "Building the Linear System", step 2.

    Returns
    -------
    EdgeDerivation
    """
    e, (x_i, x_j, z) = edge_error()
    A = sp.simplify(sp.Matrix(e).jacobian(sp.Matrix(x_i)))
    B = sp.simplify(sp.Matrix(e).jacobian(sp.Matrix(x_j)))
    return EdgeDerivation(e, sp.ImmutableMatrix(A), sp.ImmutableMatrix(B), x_i, x_j, z)


@lru_cache(maxsize=None)
def _lambdified():
    d = edge_jacobians()
    args = (*d.x_i, *d.x_j, *d.z)
    return tuple(sp.lambdify(args, M, "numpy") for M in (d.e, d.A, d.B))


def numeric_edge_jacobians(p_i, p_j, z):
    """Evaluate the sympy-derived ``e``, ``A``, ``B`` at one edge (via ``sympy.lambdify``).

    Parameters
    ----------
    p_i, p_j, z : array_like, shape (3,)

    Returns
    -------
    e : ndarray, shape (3,)
        The angle is ``atan2(sin, cos)`` of the difference, i.e. wrapped to ``(-pi, pi]``.
    A, B : ndarray, shape (3, 3)
    """
    f_e, f_A, f_B = _lambdified()
    args = (*np.asarray(p_i, float), *np.asarray(p_j, float), *np.asarray(z, float))
    return (
        np.asarray(f_e(*args), dtype=float).reshape(3),
        np.asarray(f_A(*args), dtype=float),
        np.asarray(f_B(*args), dtype=float),
    )
