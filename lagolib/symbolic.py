"""Symbolic derivations with sympy, so that the chapters can show where the formulas come from.

Two derivations live here; nothing in them is typed in — every matrix is what sympy's
``jacobian``, polynomial reduction or the paper's Kronecker-product formulas return, and the tests
compare the results with the printed equations and with lagolib's numeric code.

Lecture notes, "Building the Linear System", step 2 — "Compute the blocks of the Jacobian":
:func:`edge_error` builds ``e_ij = t2v(Z_ij^-1 X_i^-1 X_j)`` from homogeneous matrices and
:func:`edge_jacobians` differentiates it, ``A_ij = de/dx_i`` and ``B_ij = de/dx_j``.

Lodi Rizzini, "A Closed-Form Constraint Networks Solver for Maximum Likelihood Mapping":
poses with four parameters ``p_i = [x_i, y_i, c_i, s_i]`` (:func:`sincos_pose`, eq. 1), the
observation, error and χ² (:func:`sincos_observation`, :func:`sincos_error`, eq. 2–6), the
Jacobians and gradient terms (:func:`sincos_derivation`, eq. 12–15), and the matrices of the
position and angular equations of a small network (:func:`sincos_network`, eq. 16–45).

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
    "ORIGIN",
    "sincos_pose",
    "sincos_measurement",
    "unit_circle",
    "on_unit_circle",
    "sincos_observation",
    "sincos_error",
    "sincos_chi2_term",
    "SincosDerivation",
    "sincos_derivation",
    "edge_order_key",
    "SincosNetwork",
    "sincos_network",
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


def _trig_simplify(M):
    """Simplify each entry: expand, then Fu et al.'s trigonometric rules (``trigsimp(method="fu")``).

    For these products of rotations it returns the same expressions as ``sympy.simplify`` in about
    a third of the time (``simplify`` tries many strategies; only the trigonometric one matters).
    """
    return sp.Matrix(M).applyfunc(lambda q: sp.trigsimp(sp.expand(q), method="fu"))


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
    return sp.ImmutableMatrix(t2v(_trig_simplify(T))), (x_i, x_j, z)


@lru_cache(maxsize=None)
def edge_jacobians():
    """``A_ij = de_ij/dx_i`` and ``B_ij = de_ij/dx_j`` by symbolic differentiation.

    Lecture notes, "Building the Linear System", step 2.

    Returns
    -------
    EdgeDerivation
    """
    e, (x_i, x_j, z) = edge_error()
    A = _trig_simplify(sp.Matrix(e).jacobian(sp.Matrix(x_i)))
    B = _trig_simplify(sp.Matrix(e).jacobian(sp.Matrix(x_j)))
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


# --------------------------------------------------------------------------------------------
# Lodi Rizzini: poses with sine and cosine, the gradient, the position and angular equations
# --------------------------------------------------------------------------------------------

#: The origin pose ``p_0 = [0, 0, cos 0, sin 0]`` (Lodi Rizzini §II: "p_0 = [0, 0, 0]^T").
ORIGIN = sp.ImmutableMatrix([0, 0, 1, 0])


def sincos_pose(name):
    """The 4-parameter pose ``p_i = [x_i, y_i, c_i, s_i]`` (Lodi Rizzini eq. 1), shape (4, 1).

    ``c_i = cos θ_i`` and ``s_i = sin θ_i`` are independent symbols tied by ``g = 0``
    (:func:`unit_circle`).

    >>> sincos_pose(1).T
    Matrix([[x_1, y_1, c_1, s_1]])
    """
    return sp.Matrix(sp.symbols(f"x_{name} y_{name} c_{name} s_{name}", real=True))


def sincos_measurement(name):
    """The measurement ``δ̂_ij = [x̂_ij, ŷ_ij, ĉ_ij, ŝ_ij]`` as symbols, shape (4, 1).

    The symbol names (``xhat_01``) print as ``\\hat{x}_{01}`` in LaTeX.

    >>> sincos_measurement("01").T
    Matrix([[xhat_01, yhat_01, chat_01, shat_01]])
    """
    return sp.Matrix(sp.symbols(f"xhat_{name} yhat_{name} chat_{name} shat_{name}", real=True))


def unit_circle(p):
    """``g(c_i, s_i) = c_i² + s_i² − 1`` (Lodi Rizzini eq. 1) of a pose of shape (4, 1)."""
    return p[2] ** 2 + p[3] ** 2 - 1


def _cs_symbols(expr):
    """``(c_k, s_k)`` for every pose ``k`` with a ``c_k`` or an ``s_k`` in ``expr``."""
    names = {sym.name: sym for sym in expr.free_symbols}
    poses = sorted({name[2:] for name in names if name[:2] in ("c_", "s_")})

    def symbol(name):  # a missing partner gets the assumptions of :func:`sincos_pose`
        return names.get(name, sp.Symbol(name, real=True))

    return [(symbol("c_" + k), symbol("s_" + k)) for k in poses]


def on_unit_circle(expr):
    """The normal form of a polynomial modulo ``c_k² + s_k² − 1`` for every pose ``k`` in it.

    Every ``c_k²`` is replaced by ``1 − s_k²`` until each ``c_k`` appears at most linearly — the
    remainder of the division by the Gröbner basis ``{c_k² + s_k² − 1}`` in lex order with the
    ``c``'s first.  Two polynomials are equal on the unit circles exactly when their normal forms
    are equal, which is how the tests compare sympy's gradient with the printed eq. (14)–(15).
    Works elementwise on matrices.

    >>> c, s = sp.symbols("c_1 s_1", real=True)
    >>> on_unit_circle(c**3 + c * s**2 + 2)
    c_1 + 2
    """
    if isinstance(expr, sp.MatrixBase):
        return expr.applyfunc(on_unit_circle)
    expr = sp.expand(expr)
    pairs = _cs_symbols(expr)
    if not pairs or expr == 0:
        return expr
    cs = [c for c, _ in pairs] + [s for _, s in pairs]
    others = sorted(expr.free_symbols - set(cs), key=lambda x: x.name)
    basis = [c**2 + s**2 - 1 for c, s in pairs]
    _, remainder = sp.reduced(expr, basis, *cs, *others, order="lex")
    return sp.expand(remainder)


def sincos_observation(p_i, p_j):
    """``f_ij(p)``: pose ``j`` seen from pose ``i`` (Lodi Rizzini eq. 2), shape (4, 1).

    ``[R_i^T (t_j − t_i); cos(θ_j − θ_i); sin(θ_j − θ_i)]`` written with the cosines and sines.
    """
    x_i, y_i, c_i, s_i = p_i
    x_j, y_j, c_j, s_j = p_j
    return sp.Matrix(
        [
            (x_j - x_i) * c_i + (y_j - y_i) * s_i,
            -(x_j - x_i) * s_i + (y_j - y_i) * c_i,
            c_j * c_i + s_j * s_i,  # cos(θ_j − θ_i)
            s_j * c_i - c_j * s_i,  # sin(θ_j − θ_i)
        ]
    )


def sincos_error(p_i, p_j, delta):
    """``e_ij = f_ij(p) − δ̂_ij`` (Lodi Rizzini eq. 3), shape (4, 1)."""
    return sincos_observation(p_i, p_j) - sp.Matrix(delta)


def sincos_chi2_term(p_i, p_j, delta, Omega=None):
    """``χ²_ij = e_ij^T Ω_ij e_ij`` (Lodi Rizzini eq. 4); ``Ω_ij = I_4`` by default (§II-B)."""
    e = sincos_error(p_i, p_j, delta)
    W = sp.eye(4) if Omega is None else sp.Matrix(Omega)
    return sp.expand((e.T * W * e)[0, 0])


@dataclass(frozen=True)
class SincosDerivation:
    """The Jacobians and gradient terms of one constraint ``<i, j>``, derived by sympy.

    Attributes
    ----------
    e : sympy.ImmutableMatrix, shape (4, 1)
        ``e_ij`` (eq. 3).
    J_i, J_j : sympy.ImmutableMatrix, shape (4, 4)
        ``∂e_ij/∂p_i`` (eq. 13) and ``∂e_ij/∂p_j`` (eq. 12), exactly as differentiated.
    grad_i, grad_j : sympy.ImmutableMatrix, shape (4, 1)
        ``∇_i χ²_ij`` (eq. 15) and ``∇_j χ²_ij`` (eq. 14) for ``Ω_ij = I_4``, without the factor 2
        (the paper omits it, §II-A), in ``x_ij = x_j − x_i`` and ``y_ij = y_j − y_i``, reduced on
        the unit circles (:func:`on_unit_circle`).
    p_i, p_j, delta : sympy.ImmutableMatrix, shape (4, 1)
        The symbols of the two poses and of the measurement.
    x_ij, y_ij : sympy.Symbol
    """

    e: sp.ImmutableMatrix
    J_i: sp.ImmutableMatrix
    J_j: sp.ImmutableMatrix
    grad_i: sp.ImmutableMatrix
    grad_j: sp.ImmutableMatrix
    p_i: sp.ImmutableMatrix
    p_j: sp.ImmutableMatrix
    delta: sp.ImmutableMatrix
    x_ij: sp.Symbol
    y_ij: sp.Symbol


@lru_cache(maxsize=None)
def sincos_derivation():
    """Differentiate ``e_ij`` and ``χ²_ij`` of the 4-parameter poses (Lodi Rizzini eq. 12–15).

    ``J_j = ∂e_ij/∂p_j`` (eq. 12) and ``J_i = ∂e_ij/∂p_i`` (eq. 13) are sympy's ``jacobian``.
    The gradient terms are ``½ ∇χ²_ij = J^T e_ij`` (eq. 11 with ``Ω_ij = I_4``), rewritten with
    ``x_j = x_i + x_ij`` and reduced with ``c² + s² = 1``: that is all it takes to reach the
    printed eq. (14) and (15).

    Returns
    -------
    SincosDerivation

    Examples
    --------
    >>> d = sincos_derivation()
    >>> d.grad_j[0]  # first row of eq. (14): x_ij − x̂_ij c_i + ŷ_ij s_i
    -c_i*xhat_ij + s_i*yhat_ij + x_ij
    """
    p_i, p_j, delta = sincos_pose("i"), sincos_pose("j"), sincos_measurement("ij")
    e = sincos_error(p_i, p_j, delta)
    J_i, J_j = e.jacobian(p_i), e.jacobian(p_j)
    x_ij, y_ij = sp.symbols("x_ij y_ij", real=True)
    relative = {p_j[0]: p_i[0] + x_ij, p_j[1]: p_i[1] + y_ij}
    grad_i = on_unit_circle((J_i.T * e).subs(relative))
    grad_j = on_unit_circle((J_j.T * e).subs(relative))
    return SincosDerivation(
        *(sp.ImmutableMatrix(M) for M in (e, J_i, J_j, grad_i, grad_j, p_i, p_j, delta)),
        x_ij,
        y_ij,
    )


def edge_order_key(i, j, n):
    """Rank of constraint ``<i, j>`` in Lodi Rizzini's order (eq. 20): ``i + (n + 1)(j − i)``.

    Spanning constraints ``<i, i+1>`` come first (in order of ``i``), then the loop constraints by
    length ``j − i`` and start ``i``.  ``n`` is the number of poses besides ``p_0``.
    """
    return i + (n + 1) * (j - i)


def _kron(A, B):
    return sp.kronecker_product(sp.Matrix(A), sp.Matrix(B))


def _hat_rows(deltas, rows):
    """A ``2 × 2e`` matrix whose column pair ``h`` is ``rows`` evaluated on ``δ̂_h``."""
    return sp.Matrix.hstack(*(sp.Matrix(rows(*d)) for d in deltas))


@dataclass(frozen=True)
class SincosNetwork:
    """A small constraint network of 4-parameter poses and its closed-form matrices.

    All matrices are computed literally from Lodi Rizzini's formulas (Kronecker products ``⊗``,
    elementwise products ``.*``); :mod:`lagolib.closed_form` assembles the same matrices sparse for
    large networks.  Edges are ``(i, j)`` pairs with ``i < j`` in the order of eq. (20); pose
    ``p_0`` is the origin.

    Attributes
    ----------
    n : int
        Poses besides ``p_0``.
    edges : tuple of (int, int)
        The ``e`` constraints in the order of eq. (20): ``n`` spanning, then ``n_L`` loop ones.
    poses : tuple of sympy.ImmutableMatrix, shape (4, 1)
        ``p_0`` (:data:`ORIGIN`), ``p_1``, … ``p_n``.
    deltas : tuple of sympy.ImmutableMatrix, shape (4, 1)
        ``δ̂_h`` per edge (symbols unless numbers were given).
    lambdas : tuple of sympy.Symbol
        Lagrange multipliers ``λ_1 … λ_n``.
    chi2, E : sympy.Expr
        ``χ²`` (eq. 5–6, ``Ω = I_4``) and the Lagrangian ``E = χ² + Σ λ_i g_i`` (eq. 7).
    t : sympy.ImmutableMatrix, shape (2n, 1)
        ``[c_1, s_1, …, c_n, s_n]``.
    N_out, N_in, N : (n+1) × e
        Output and input incidence matrices, ``N = N_in − N_out`` (§III).
    U, U_bar : n_L × n and 2n_L × 2n
        Loop-edge matrix (eq. 21) and ``Ū = U ⊗ I_2``.
    G, P : 2n_L × 2n_L and 2e × 2e
        eq. (24) and ``P = [[P_SS, P_SL], [P_LS, P_LL]]`` (eq. 23–28).
    D, Q : 2e × 2 and 2e × 2(n+1)
        eq. (30) and (29): ``l = Q [1 0 t^T]^T`` stacks ``l_ij`` (eq. 18).
    D_perp, M : 2 × 2e and 2n × 2e
        eq. (38) and (37).
    C_in, C_out, L_in, L_out, L : 2 × 2e, 2 × 2e, 2n × 2e, 2n × 2e, 2n × 2(n+1)
        eq. (42), (43), (40), (41), (39).
    b, A : 2n × 1 and 2n × 2n
        The first column and the columns 3 to 2n + 2 of ``L + M P Q`` (§III-B, eq. 44).
    """

    n: int
    edges: tuple
    poses: tuple
    deltas: tuple
    lambdas: tuple
    chi2: sp.Expr
    E: sp.Expr
    t: sp.ImmutableMatrix
    N_out: sp.ImmutableMatrix
    N_in: sp.ImmutableMatrix
    N: sp.ImmutableMatrix
    U: sp.ImmutableMatrix
    U_bar: sp.ImmutableMatrix
    G: sp.ImmutableMatrix
    P: sp.ImmutableMatrix
    D: sp.ImmutableMatrix
    Q: sp.ImmutableMatrix
    D_perp: sp.ImmutableMatrix
    M: sp.ImmutableMatrix
    C_in: sp.ImmutableMatrix
    C_out: sp.ImmutableMatrix
    L_in: sp.ImmutableMatrix
    L_out: sp.ImmutableMatrix
    L: sp.ImmutableMatrix
    b: sp.ImmutableMatrix
    A: sp.ImmutableMatrix

    @property
    def t1(self):
        """``[1, 0, t^T]^T``: the angular parameters with ``c_0 = 1``, ``s_0 = 0``, shape (2n+2, 1)."""
        return sp.Matrix([1, 0, *self.t])

    def gradient(self, k):
        """``½ ∇_k E`` (eq. 10–11, factor 2 omitted), reduced on the unit circles, shape (4, 1).

        Rows 1–2 are the position equations of pose ``k`` (eq. 16), rows 3–4 its angular
        equations (eq. 31–32, with the sign convention of eq. 7: ``+λ_k``).
        """
        if not 1 <= k <= self.n:
            raise ValueError(f"pose index must be in 1..{self.n}; got {k}")
        g = sp.Matrix([sp.diff(self.E, v) / 2 for v in self.poses[k]])
        return on_unit_circle(g)

    def l_terms(self):
        """``l = [l_ij]`` (eq. 18) stacked in edge order, from the definition, shape (2e, 1)."""
        rows = []
        for (i, _), d in zip(self.edges, self.deltas):
            c, s = self.poses[i][2], self.poses[i][3]
            rows.append(sp.Matrix([[c, -s], [s, c]]) * d[:2, :])
        return sp.Matrix.vstack(*rows)

    def displacements(self):
        """``d = P Q [1 0 t^T]^T`` (eq. 23, 29): every ``d_ij`` as a linear function of ``t``."""
        return sp.expand(self.P * self.Q * self.t1)

    def alpha_beta(self):
        """``v = [α_1, β_1, …]`` from eq. (34)–(35) with ``x_ij = x_j − x_i``, shape (2n, 1)."""
        v = sp.zeros(2 * self.n, 1)
        for (i, j), (xh, yh, ch, sh) in zip(self.edges, self.deltas):
            (x_i, y_i, c_i, s_i), (x_j, y_j, c_j, s_j) = self.poses[i], self.poses[j]
            x, y = x_j - x_i, y_j - y_i
            # edge <i, j> is incoming at j ...
            v[2 * j - 2] += ch * c_i - sh * s_i
            v[2 * j - 1] += -(sh * c_i + ch * s_i)
            if i >= 1:  # ... and outgoing at i (p_0 has no equations)
                v[2 * i - 2] += ch * c_j + sh * s_j + xh * x + yh * y
                v[2 * i - 1] += sh * c_j - ch * s_j + yh * x - xh * y
        return v


def sincos_network(edges, deltas=None):
    """Build the closed-form matrices of a small network symbolically (Lodi Rizzini §III).

    Parameters
    ----------
    edges : sequence of (int, int)
        Constraints ``<i, j>`` with ``0 <= i < j``; every ``<k-1, k>`` must be present (§III's
        assumptions).  Any order: they are sorted by eq. (20).
    deltas : sequence of length-4 sequences, optional
        ``[x̂, ŷ, ĉ, ŝ]`` per edge (in the order given); default symbols ``xhat_ij`` etc.

    Returns
    -------
    SincosNetwork

    Examples
    --------
    The 3-pose network of §IV-A (eq. 46):

    >>> net = sincos_network([(0, 1), (1, 2), (0, 2)])
    >>> 3 * net.P[::2, ::2]
    Matrix([
    [ 2, -1, 1],
    [-1,  2, 1],
    [ 1,  1, 2]])
    """
    edges = [(int(i), int(j)) for i, j in edges]
    if any(not 0 <= i < j for i, j in edges):
        bad = next((i, j) for i, j in edges if not 0 <= i < j)
        raise ValueError(f"constraint <{bad[0]}, {bad[1]}> must be stored from the smaller index")
    n = max(j for _, j in edges)
    if deltas is None:
        sep = "" if n < 10 else ","
        deltas = [sincos_measurement(f"{i}{sep}{j}") for i, j in edges]
    deltas = [sp.Matrix(d).reshape(4, 1) for d in deltas]
    first = {}  # the first stored <k-1, k> is the spanning constraint; copies are loop ones
    for h, (i, j) in enumerate(edges):
        if j == i + 1:
            first.setdefault(i, h)
    missing = sorted(set(range(n)) - set(first))
    if missing:
        raise ValueError(f"the spanning constraint <{missing[0]}, {missing[0] + 1}> is missing")
    loop_idx = sorted(set(range(len(edges))) - set(first.values()))
    order = [first[k] for k in range(n)]
    order += sorted(loop_idx, key=lambda h: (edge_order_key(*edges[h], n), h))  # eq. (20)
    edges = [edges[h] for h in order]
    deltas = [deltas[h] for h in order]
    loops = edges[n:]
    n_L = len(loops)

    poses = [ORIGIN] + [sincos_pose(k) for k in range(1, n + 1)]
    lambdas = sp.symbols(f"lambda_1:{n + 1}", real=True)
    chi2 = sum(
        (sincos_chi2_term(poses[i], poses[j], d) for (i, j), d in zip(edges, deltas)), sp.S.Zero
    )
    E = chi2 + sum(lam * unit_circle(poses[k + 1]) for k, lam in enumerate(lambdas))  # eq. (7)
    t = sp.Matrix([v for k in range(1, n + 1) for v in poses[k][2:, 0]])

    N_out = sp.Matrix([[int(i == g) for i, _ in edges] for g in range(n + 1)])
    N_in = sp.Matrix([[int(j == g) for _, j in edges] for g in range(n + 1)])
    N = N_in - N_out
    U = sp.Matrix(n_L, n, [int(g < k <= h) for g, h in loops for k in range(1, n + 1)])  # (21)
    I2 = sp.eye(2)
    U_bar = _kron(U, I2)
    G = (sp.eye(2 * n_L) + U_bar * U_bar.T).inv()  # eq. (24)
    P_SS = sp.eye(2 * n) - U_bar.T * G * U_bar  # eq. (25)
    P_SL = U_bar.T - U_bar.T * G * U_bar * U_bar.T  # eq. (26)
    P_LS = G * U_bar  # eq. (27)
    P_LL = G * U_bar * U_bar.T  # eq. (28)
    P = sp.Matrix(sp.BlockMatrix([[P_SS, P_SL], [P_LS, P_LL]]))

    ones = sp.ones
    D = _hat_rows(deltas, lambda xh, yh, ch, sh: [[xh, yh], [-yh, xh]]).T  # eq. (30)
    Q = _kron(N_out.T, ones(2, 2)).multiply_elementwise(_kron(ones(1, n + 1), D))  # eq. (29)
    D_perp = _hat_rows(deltas, lambda xh, yh, ch, sh: [[xh, yh], [yh, -xh]])  # eq. (38)
    N0_out, N0_in = N_out[1:, :], N_in[1:, :]
    M = _kron(N0_out, ones(2, 2)).multiply_elementwise(_kron(ones(n, 1), D_perp))  # eq. (37)
    C_in = _hat_rows(deltas, lambda xh, yh, ch, sh: [[ch, -sh], [-sh, -ch]])  # eq. (42)
    C_out = _hat_rows(deltas, lambda xh, yh, ch, sh: [[ch, sh], [sh, -ch]])  # eq. (43)
    L_in = _kron(N0_in, ones(2, 2)).multiply_elementwise(_kron(ones(n, 1), C_in))  # eq. (40)
    L_out = _kron(N0_out, ones(2, 2)).multiply_elementwise(_kron(ones(n, 1), C_out))  # eq. (41)
    L = L_in * _kron(N_out.T, I2) + L_out * _kron(N_in.T, I2)  # eq. (39)
    V = sp.expand(L + M * P * Q)  # eq. (36): v = V [1 0 t^T]^T
    b, A = V[:, 0], V[:, 2:]

    def imm(X):
        return sp.ImmutableMatrix(X)

    return SincosNetwork(
        n,
        tuple(edges),
        tuple(imm(p) for p in poses),
        tuple(imm(d) for d in deltas),
        tuple(lambdas),
        chi2,
        E,
        imm(t),
        *(imm(X) for X in (N_out, N_in, N, U, U_bar, G, P, D, Q, D_perp, M, C_in, C_out)),
        *(imm(X) for X in (L_in, L_out, L, b, A)),
    )
