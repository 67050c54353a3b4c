"""lagolib.symbolic: the sympy derivation equals the numeric Jacobians."""

import numpy as np
import sympy as sp

from lagolib import gauss_newton as gn
from lagolib import symbolic


def test_derivation_has_the_expected_structure():
    d = symbolic.edge_jacobians()
    x_i, y_i, t_i = d.x_i
    x_j, y_j, t_j = d.x_j
    # B_ij is the rotation R(theta_i + theta_z)^T and d e_theta / d theta_i = -1
    a = t_i + d.z[2]
    expected_B = sp.Matrix([[sp.cos(a), sp.sin(a), 0], [-sp.sin(a), sp.cos(a), 0], [0, 0, 1]])
    assert sp.simplify(d.B - expected_B) == sp.zeros(3, 3)
    assert d.A[2, :] == sp.Matrix([[0, 0, -1]])
    assert sp.simplify(d.A[:2, :2] + d.B[:2, :2]) == sp.zeros(2, 2)
    # the error does not depend on where the pair is, only on the relative pose
    shifted = d.e.subs({x_i: x_i + 1, x_j: x_j + 1})
    assert sp.simplify(shifted[:2, :] - d.e[:2, :]) == sp.zeros(2, 1)
    assert not d.B.has(x_i, x_j, y_i, y_j, t_j)


def test_sympy_equals_numeric_at_random_points():
    rng = np.random.default_rng(20)
    for _ in range(25):
        p_i, p_j, z = rng.normal(size=(3, 3)) * [4, 4, 2]
        e_s, A_s, B_s = symbolic.numeric_edge_jacobians(p_i, p_j, z)
        e, A, B = gn.edge_jacobians(p_i, p_j, z)
        np.testing.assert_allclose(e_s, e, atol=1e-12)
        np.testing.assert_allclose(A_s, A, atol=1e-12)
        np.testing.assert_allclose(B_s, B, atol=1e-12)


def test_transform_helpers():
    x = symbolic.pose_symbols("a")
    T = symbolic.v2t(x)
    assert sp.simplify(symbolic.inverse_transform(T) * T) == sp.eye(3)
    v = symbolic.t2v(T)
    assert v[0] == x[0] and v[1] == x[1]


# ------------------------------------------------------------------ Lodi Rizzini (sin/cos poses)
def _printed_eq_12_13(d):
    """Lodi Rizzini eq. (12) and (13), typed in from the paper."""
    x_i, y_i, c_i, s_i = d.p_i
    x_j, y_j, c_j, s_j = d.p_j
    eq12 = sp.Matrix([[c_i, s_i, 0, 0], [-s_i, c_i, 0, 0], [0, 0, c_i, s_i], [0, 0, -s_i, c_i]])
    eq13 = sp.Matrix(
        [
            [-c_i, -s_i, x_j - x_i, y_j - y_i],
            [s_i, -c_i, y_j - y_i, -(x_j - x_i)],
            [0, 0, c_j, s_j],
            [0, 0, s_j, -c_j],
        ]
    )
    return eq12, eq13


def _printed_eq_14_15(d):
    """Lodi Rizzini eq. (14) and (15), typed in from the paper (x = x_ij, y = y_ij)."""
    _, _, c_i, s_i = d.p_i
    _, _, c_j, s_j = d.p_j
    xh, yh, ch, sh = d.delta
    x, y = d.x_ij, d.y_ij
    eq14 = sp.Matrix(
        [
            x - xh * c_i + yh * s_i,
            y - xh * s_i - yh * c_i,
            c_j - ch * c_i + sh * s_i,
            s_j - ch * s_i - sh * c_i,
        ]
    )
    eq15 = sp.Matrix(
        [
            -x + xh * c_i - yh * s_i,
            -y + xh * s_i + yh * c_i,
            x**2 * c_i + y**2 * c_i - xh * x - yh * y + c_i - ch * c_j - sh * s_j,
            x**2 * s_i + y**2 * s_i + yh * x - xh * y + s_i + sh * c_j - ch * s_j,
        ]
    )
    return eq14, eq15


def test_sincos_jacobians_are_eq_12_and_13():
    d = symbolic.sincos_derivation()
    eq12, eq13 = _printed_eq_12_13(d)
    assert sp.expand(d.J_j - eq12) == sp.zeros(4, 4)
    assert sp.expand(d.J_i - eq13) == sp.zeros(4, 4)


def test_sincos_gradient_simplifies_to_eq_14_and_15():
    d = symbolic.sincos_derivation()
    eq14, eq15 = _printed_eq_14_15(d)
    # the derivation, reduced with c² + s² = 1, is the printed polynomial term by term
    assert sp.expand(d.grad_j - eq14) == sp.zeros(4, 1)
    assert sp.expand(d.grad_i - eq15) == sp.zeros(4, 1)
    # ... and the unreduced J^T e differs from it only on the unit circles: independent check by
    # substituting c = cos(phi), s = sin(phi) and simplifying
    x_i, y_i, c_i, s_i = d.p_i
    x_j, y_j, c_j, s_j = d.p_j
    raw = (d.J_i.T * d.e).subs({x_j: x_i + d.x_ij, y_j: y_i + d.y_ij})
    assert sp.expand(raw - eq15) != sp.zeros(4, 1)
    phi_i, phi_j = sp.symbols("phi_i phi_j", real=True)
    angles = {c_i: sp.cos(phi_i), s_i: sp.sin(phi_i), c_j: sp.cos(phi_j), s_j: sp.sin(phi_j)}
    assert sp.simplify((raw - eq15).subs(angles)) == sp.zeros(4, 1)


def _chi2_numeric(p_i, p_j, delta):
    """χ²_ij with Ω = I_4 from eq. (2)-(4), in plain numpy (independent of lagolib)."""
    x_i, y_i, c_i, s_i = p_i
    x_j, y_j, c_j, s_j = p_j
    f = np.array(
        [
            (x_j - x_i) * c_i + (y_j - y_i) * s_i,
            -(x_j - x_i) * s_i + (y_j - y_i) * c_i,
            c_j * c_i + s_j * s_i,
            s_j * c_i - c_j * s_i,
        ]
    )
    e = f - delta
    return e @ e


def test_sincos_gradient_equals_finite_differences():
    d = symbolic.sincos_derivation()
    eq14, eq15 = _printed_eq_14_15(d)
    args = (*d.p_i, *d.p_j, *d.delta)
    relative = {d.x_ij: d.p_j[0] - d.p_i[0], d.y_ij: d.p_j[1] - d.p_i[1]}
    grad = sp.lambdify(args, sp.Matrix.vstack(eq15, eq14).subs(relative), "numpy")
    rng = np.random.default_rng(5)
    h = 1e-6
    for _ in range(20):
        a = rng.uniform(-np.pi, np.pi, 3)
        p_i = np.array([*rng.normal(size=2) * 3, np.cos(a[0]), np.sin(a[0])])
        p_j = np.array([*rng.normal(size=2) * 3, np.cos(a[1]), np.sin(a[1])])
        delta = np.array([*rng.normal(size=2) * 2, np.cos(a[2]), np.sin(a[2])])
        p = np.concatenate([p_i, p_j])
        fd = np.empty(8)
        for k in range(8):
            dp = np.zeros(8)
            dp[k] = h
            hi, lo = p + dp, p - dp
            fd[k] = (
                _chi2_numeric(hi[:4], hi[4:], delta) - _chi2_numeric(lo[:4], lo[4:], delta)
            ) / (2 * h)
        # the paper drops the factor 2 of the gradient (§II-A)
        analytic = 2 * np.asarray(grad(*p_i, *p_j, *delta), dtype=float).ravel()
        np.testing.assert_allclose(analytic, fd, atol=1e-6)


def _example():
    """The 3-pose, 3-constraint network of Lodi Rizzini §IV-A."""
    return symbolic.sincos_network([(0, 1), (1, 2), (0, 2)])


def _hats(net, name):
    return dict(zip(["x", "y", "c", "s"], net.deltas[[(0, 1), (1, 2), (0, 2)].index(name)]))


def test_example_P_is_eq_46():
    net = _example()
    assert net.edges == ((0, 1), (1, 2), (0, 2))
    eq46 = sp.Rational(1, 3) * sp.Matrix([[2, -1, 1], [-1, 2, 1], [1, 1, 2]])
    assert net.P == sp.kronecker_product(eq46, sp.eye(2))
    assert net.U == sp.Matrix([[1, 1]])


def test_example_L_is_eq_49_entry_by_entry():
    net = _example()
    a, b, c = _hats(net, (0, 1)), _hats(net, (1, 2)), _hats(net, (0, 2))
    eq49 = sp.Matrix(
        [
            [a["c"], -a["s"], 0, 0, b["c"], b["s"]],
            [-a["s"], -a["c"], 0, 0, b["s"], -b["c"]],
            [c["c"], -c["s"], b["c"], -b["s"], 0, 0],
            [-c["s"], -c["c"], -b["s"], -b["c"], 0, 0],
        ]
    )
    assert net.L == eq49


def test_example_Q_and_M_against_eq_47_48_and_the_derivation():
    """Eq. (29)-(30) and (37)-(38) give Q and M; the printed (47)-(48) have slips.

    Printed eq. (47) holds every 2x2 block of Q transposed, and printed eq. (48) has the block of
    <1, 2> as [[x̂, -ŷ], [ŷ, x̂]] instead of D⊥'s [[x̂, ŷ], [ŷ, -x̂]].  Both contradict eq. (18)
    and (34)-(35); Q and M built by the formulas satisfy them (checked here symbolically).
    """
    net = _example()
    a, b, c = _hats(net, (0, 1)), _hats(net, (1, 2)), _hats(net, (0, 2))
    eq47 = sp.Matrix(
        [
            [a["x"], a["y"], 0, 0, 0, 0],
            [-a["y"], a["x"], 0, 0, 0, 0],
            [0, 0, b["x"], b["y"], 0, 0],
            [0, 0, -b["y"], b["x"], 0, 0],
            [c["x"], c["y"], 0, 0, 0, 0],
            [-c["y"], c["x"], 0, 0, 0, 0],
        ]
    )
    eq48 = sp.Matrix(
        [
            [0, 0, b["x"], -b["y"], 0, 0],
            [0, 0, b["y"], b["x"], 0, 0],
            [0, 0, 0, 0, 0, 0],
            [0, 0, 0, 0, 0, 0],
        ]
    )
    blockwise_T = sp.Matrix(6, 6, lambda r, k: net.Q[2 * (r // 2) + k % 2, 2 * (k // 2) + r % 2])
    assert blockwise_T == eq47
    assert net.M == sp.Matrix(
        [[0, 0, b["x"], b["y"], 0, 0], [0, 0, b["y"], -b["x"], 0, 0], [0, 0, 0, 0, 0, 0], [0] * 6]
    )
    assert net.M != eq48
    # Q [1 0 t] is l of eq. (18); the printed Q is not
    assert sp.expand(net.Q * net.t1 - net.l_terms()) == sp.zeros(6, 1)
    assert sp.expand(eq47 * net.t1 - net.l_terms()) != sp.zeros(6, 1)
    # eq. (36): (L + M P Q)[1 0 t] is eq. (34)-(35) once the displacements solve the position
    # equations -- which sympy solves here from the gradient itself
    rows = [net.gradient(k)[r] for k in (1, 2) for r in (0, 1)]
    unknowns = [v for k in (1, 2) for v in net.poses[k][:2]]
    sol = sp.solve(rows, unknowns, dict=True)[0]
    d_from_gradient = sp.Matrix(
        [(net.poses[j][r] - net.poses[i][r]).subs(sol) for i, j in net.edges for r in (0, 1)]
    )
    assert sp.expand(d_from_gradient - net.displacements()) == sp.zeros(6, 1)
    v = sp.expand(net.alpha_beta().subs(sol))
    assert sp.expand(v - (net.L + net.M * net.P * net.Q) * net.t1) == sp.zeros(4, 1)
    assert sp.expand(v - (net.L + eq48 * net.P * net.Q) * net.t1) != sp.zeros(4, 1)
    # b and A are the first and the last 2n columns of L + M P Q
    V = sp.expand((net.L + net.M * net.P * net.Q))
    assert net.b == V[:, 0] and net.A == V[:, 2:]


def test_example_gradient_equations_for_p1_and_p2():
    """The equations listed in §IV-A, typed in (rows 1-2 printed negated; λ with eq. 31's sign)."""
    net = _example()
    a, b, c = _hats(net, (0, 1)), _hats(net, (1, 2)), _hats(net, (0, 2))
    x1, y1, c1, s1 = net.poses[1]
    x2, y2, c2, s2 = net.poses[2]
    lam1, lam2 = net.lambdas
    x01, y01, x02, y02, x12, y12 = x1, y1, x2, y2, x2 - x1, y2 - y1
    p1 = [
        (-x01 + a["x"]) + (x12 - b["x"] * c1 + b["y"] * s1),
        (-y01 + a["y"]) + (y12 - b["x"] * s1 - b["y"] * c1),
        (x12**2 * c1 + y12**2 * c1 - b["x"] * x12 - b["y"] * y12 + c1 - b["c"] * c2 - b["s"] * s2)
        + (c1 - a["c"])
        - lam1 * c1,
        (x12**2 * s1 + y12**2 * s1 + b["y"] * x12 - b["x"] * y12 + s1 + b["s"] * c2 - b["c"] * s2)
        + (s1 - a["s"])
        - lam1 * s1,
    ]
    p2 = [
        (-x02 + c["x"]) + (-x12 + b["x"] * c1 - b["y"] * s1),
        (-y02 + c["y"]) + (-y12 + b["x"] * s1 + b["y"] * c1),
        (c2 - c["c"]) + (c2 - b["c"] * c1 + b["s"] * s1) - lam2 * c2,
        (s2 - c["s"]) + (s2 - b["s"] * c1 - b["c"] * s1) - lam2 * s2,
    ]
    flip = {lam1: -lam1, lam2: -lam2}  # eq. (7) adds +λ g; eq. (31) and §IV-A subtract it
    for k, printed in ((1, p1), (2, p2)):
        g = net.gradient(k).subs(flip)
        assert sp.expand(g[0] + printed[0]) == 0 and sp.expand(g[1] + printed[1]) == 0
        assert symbolic.on_unit_circle(g[2] - printed[2]) == 0
        assert symbolic.on_unit_circle(g[3] - printed[3]) == 0


def test_orthogonality_combination_is_eq_33():
    """-s_i (31) + c_i (32) = s_i α_i + c_i β_i (eq. 33-35): λ_i drops out."""
    net = symbolic.sincos_network([(0, 1), (1, 2), (2, 3), (0, 2), (1, 3)])
    v = net.alpha_beta()
    for k in range(1, net.n + 1):
        c, s = net.poses[k][2], net.poses[k][3]
        g = net.gradient(k)
        combo = -s * g[2] + c * g[3]
        assert symbolic.on_unit_circle(combo - (s * v[2 * k - 2] + c * v[2 * k - 1])) == 0


def test_sincos_network_rejects_the_papers_excluded_cases():
    import pytest

    with pytest.raises(ValueError, match="smaller index"):
        symbolic.sincos_network([(0, 1), (2, 1)])
    with pytest.raises(ValueError, match="<1, 2> is missing"):
        symbolic.sincos_network([(0, 1), (0, 2)])


def test_on_unit_circle_normal_form():
    c, s, x = sp.symbols("c_3 s_3 x", real=True)
    assert symbolic.on_unit_circle(x * (c**2 + s**2)) == x
    assert symbolic.on_unit_circle(c**4) == sp.expand((1 - s**2) ** 2)
    assert symbolic.on_unit_circle(sp.Matrix([c**2, 1])) == sp.Matrix([1 - s**2, 1])
