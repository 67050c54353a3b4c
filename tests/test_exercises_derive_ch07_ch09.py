"""Exercises 7.5 and 9.4 (derive): their reference formulas against lagolib's numbers."""

import numpy as np
import sympy as sp

from lagolib import PoseGraph, closed_form
from lagolib.exercises import ch07, ch09, reset


def test_the_sympy_edge_error_is_lagolibs():
    rng = np.random.default_rng(75)
    e = ch07.sincos_edge_error()
    f = sp.lambdify(ch07.GRADIENT_SYMBOLS, list(e), "numpy")
    for _ in range(5):
        pi, pj, z = rng.uniform(-3, 3, (3, 3))
        g = PoseGraph(np.array([pi, pj]), [[0, 1]], [z], [np.diag([3.0, 1.0, 7.0])])
        want = closed_form.sincos_residuals(g)[0]
        got = f(pi[0], pi[1], np.cos(pi[2]), np.sin(pi[2]), pj[0], pj[1], np.cos(pj[2]),
                np.sin(pj[2]), z[0], z[1], np.cos(z[2]), np.sin(z[2]))
        assert np.allclose(got, want, atol=1e-12)


def test_the_gradient_entry_is_the_finite_difference():
    rng = np.random.default_rng(7)
    e = ch07.sincos_edge_error()
    F = sp.lambdify(ch07.GRADIENT_SYMBOLS, (e.T * e)[0, 0], "numpy")
    dF = sp.lambdify(ch07.GRADIENT_SYMBOLS, ch07.gradient_entry_reference(), "numpy")
    for _ in range(5):
        v = rng.uniform(-2, 2, 12)
        h = 1e-6
        up, down = v.copy(), v.copy()
        up[2] += h
        down[2] -= h
        assert abs((F(*up) - F(*down)) / (2 * h) - dF(*v)) < 1e-6 * max(1.0, abs(dF(*v)))


def test_the_multiplier_formula_is_section_4s_rule():
    rng = np.random.default_rng(94)
    lam = sp.lambdify(ch09.MULTIPLIER_SYMBOLS, ch09.multiplier_reference(), "numpy")
    for _ in range(5):
        w, tz, p0, p1 = rng.uniform(0.1, 3), *rng.uniform(-3, 3, 3)
        r = np.exp(1j * tz)
        M = w * np.array([[1, -np.conj(r)], [-r, 1]])
        z = np.exp(1j * np.array([p0, p1]))
        assert abs(np.real(np.conj(z[1]) * (M @ z)[1]) - lam(w, tz, p0, p1)) < 1e-12
        assert abs(np.real(np.vdot(z, M @ z)) - w * abs(z[1] - r * z[0]) ** 2) < 1e-12


def test_the_checks_accept_forms_and_name_slips(capsys):
    reset()
    assert ch09.check_multiplier_formula("w - w*cos(phi_1 - phi_0 - theta_z)")
    assert ch09.check_multiplier_formula(
        sp.sympify("w*(1 - cos(theta_z)*cos(phi_0 - phi_1) + sin(theta_z)*sin(phi_0 - phi_1))")
    )
    assert not ch09.check_multiplier_formula("w*sin(phi_1 - phi_0 - theta_z)")
    out = capsys.readouterr().out
    assert "imaginary part" in out and "Exercise 9.4 — not yet" in out
    assert not ch09.check_multiplier_formula("w*(1 - cos(phi_1 - phi_0 - theta_zz))")
    assert "theta_zz" in capsys.readouterr().out
    e1 = "(c_i*(x_j - x_i) + s_i*(y_j - y_i) - x_z)"
    e2 = "(-s_i*(x_j - x_i) + c_i*(y_j - y_i) - y_z)"
    e3 = "(c_j*c_i + s_j*s_i - c_z)"
    e4 = "(s_j*c_i - c_j*s_i - s_z)"
    right = f"2*({e1}*(x_j - x_i) + {e2}*(y_j - y_i) + {e3}*c_j + {e4}*s_j)"
    assert ch07.check_gradient_entry(right)
    assert ch07.check_gradient_entry(str(sp.expand(sp.sympify(right))))
    assert not ch07.check_gradient_entry(f"({e1}*(x_j - x_i) + {e2}*(y_j - y_i) + {e3}*c_j + {e4}*s_j)")
    assert "half of it" in capsys.readouterr().out
    assert not ch07.check_gradient_entry(f"2*({e1}*(x_j - x_i) + {e2}*(y_j - y_i))")
    out = capsys.readouterr().out
    assert "only the position rows" in out
    assert "c_j*c_i" not in out.replace(" ", "")  # the first tier never spells the reference


def test_the_multiplier_formula_is_lagolibs_certify_multipliers():
    # a two-pose graph, one edge with information diag(tau, tau, w): lambda_1 is the rotation term's
    # (pose 1's rotation enters no translation residual), whatever the translations are
    from lagolib import certify

    rng = np.random.default_rng(941)
    lam = sp.lambdify(ch09.MULTIPLIER_SYMBOLS, ch09.multiplier_reference(), "numpy")
    for _ in range(5):
        w, tau = rng.uniform(0.1, 5, 2)
        tz, p0, p1 = rng.uniform(-3, 3, 3)
        poses = np.array([[*rng.uniform(-2, 2, 2), p0], [*rng.uniform(-2, 2, 2), p1]])
        g = PoseGraph(poses, [[0, 1]], [[*rng.uniform(-1, 1, 2), tz]], [np.diag([tau, tau, w])])
        got = certify.multipliers(certify.chordal_problem(g), poses)[1]
        assert abs(got - lam(w, tz, p0, p1)) < 1e-10 * max(1.0, w)
