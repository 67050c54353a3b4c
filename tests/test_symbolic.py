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
