"""The *derive* exercises: formulas read safely, compared symbolically, wrong terms named.

1. :class:`~lagolib.exercises._derive.Formula` reads strings (ASCII and Unicode, ``^``, implicit
   products) and sympy expressions in the exercise's symbols, and refuses everything else with a
   sentence — junk strings included, without ever evaluating anything but arithmetic.
2. :func:`~lagolib.exercises._derive.formula_comparison` accepts equivalent forms (expanded,
   factored, rewritten with trigonometric identities), proves them symbolically, falls back to
   random points when sympy cannot, and names the wrong term of a wrong formula without printing
   the reference.
3. The chapters' derive exercises (2.5, 5.5, 6.5): their reference formulas, derived by sympy,
   agree with lagolib's numeric code at random points; their checks say correct, not yet (naming
   the slip) and not attempted yet.
"""

import itertools
import time

import numpy as np
import pytest
import sympy as sp

from lagolib import PoseGraph, gauss_newton
from lagolib import lago as L
from lagolib.exercises import NOT_ATTEMPTED, WrongKind, ch02, ch05, ch06, passed, reset
from lagolib.exercises._derive import (
    Formula,
    compare_formula,
    formula_comparison,
    show_formula,
)

a, b, c = sp.symbols("a b c", positive=True)
theta = sp.Symbol("theta", real=True)
x, y = sp.symbols("x y", real=True)
PARALLEL = c * (a + b) / (a + b + c)  # exercise 5.5's answer
W_XY = (a - b) * sp.sin(theta) * sp.cos(theta)  # exercise 6.5's answer
JAC = (x - y) * sp.sin(theta) + (y + 1) * sp.cos(theta)  # a two-term trigonometric formula


@pytest.fixture(autouse=True)
def _fresh_results():
    reset()
    yield
    reset()


# ------------------------------------------------------------------------------- reading
@pytest.mark.parametrize(
    "text, expected",
    [
        ("c*(a+b)/(a+b+c)", PARALLEL),
        ("c (a + b) / (a + b + c)", PARALLEL),  # implicit product
        ("(a - b)·sin(θ)·cos(θ)", W_XY),  # Unicode: θ, middle dot
        ("(a − b)*sin(theta)*cos(theta)", W_XY),  # a typographic minus sign
        ("a^2 + b²", a**2 + b**2),
        ("2a", 2 * a),
        ("0.5*a", a / 2),  # floats become the exact fractions they were written as
        ("sin(θ)^2", sp.sin(theta) ** 2),
        ("pi/2 + E", sp.pi / 2 + sp.E),
    ],
)
def test_strings_are_read_as_formulas(text, expected):
    got = Formula([a, b, c, theta]).coerce(text)
    assert sp.simplify(got - expected) == 0
    assert got.free_symbols <= {a, b, c, theta}


def test_a_students_own_symbols_are_the_exercises():
    mine = sp.Symbol("a") * sp.Symbol("θ")  # no assumptions, Greek name: still a and theta
    got = Formula([a, b, theta]).coerce(mine)
    assert got == a * theta and got.free_symbols == {a, theta}
    assert Formula([a]).coerce(3) == 3 and Formula([a]).coerce(np.float64(0.25)) == sp.Rational(1, 4)


@pytest.mark.parametrize(
    "answer, says",
    [
        ("a + q", "q is not one of the exercise's symbols (a, b, θ)"),
        ("foo(a)", "foo is not one of"),
        ("(a + b", "a parenthesis is not closed"),
        ("a + * b", "sympy cannot read"),
        ("sin θ", "sin needs its argument in parentheses"),
        ("sin^2(θ)", "sin needs its argument in parentheses"),
        ("W_xy = a - b", "an equation or comparison"),
        ("a == b", "an equation or comparison"),
        ("a.evalf()", "an attribute"),
        ("__import__('os').getcwd()", "an attribute"),
        ("(lambda: 1)()", "sympy cannot read"),
        ("[a, b]", "sympy cannot read"),
        ("a[0]", "indexing"),
        ("2**3**4", "a tower of powers"),
        ("a**100", "an exponent larger than 8"),
        ("'a'", "text in quotes"),
        ("", "an empty string"),
        ("a" * 3000, "too long"),
        (sp.Eq(a, b), "an equation"),
        (sp.Matrix([a, b]), "a sympy matrix of shape (2, 1)"),
        (sp.Function("f")(a), "f is not a known function"),
        (sp.gamma(a), "gamma is not a known function"),
        (sp.Derivative(sp.Function("g")(a), a), "unevaluated derivative"),
        (True, "True (a bool)"),
        ([a, b], "a list of length 2"),
        ({"W": a}, "a dict"),
        (np.array([1.0, 2.0]), "an array of dtype float64"),
        (float("nan"), "not a finite number"),
        (1 + 2j, "a complex number"),
        ("I*a", "I is not one of the exercise's symbols"),
    ],
)
def test_wrong_kinds_are_refused_with_the_reason(answer, says):
    with pytest.raises(WrongKind) as err:
        Formula([a, b, theta]).coerce(answer, "W_xy")
    message = str(err.value)
    assert message.startswith("W_xy should be one formula in a, b, θ"), message
    assert says in message, message


JUNK = [
    "", " ", "(((", ")", "**", "a^^2", "1/0", "zoo", "nan", "oo", "sin()", "sin(1, 2)",
    "atan2(a)", "é", "\\", "'\"", "#", "a # comment", "a; import os", "lambda: 1", "{a}",
    "a if 1 else 0", "not a", "a and b", "f'{a}'", "b'x'", "a @ b", "a // 2", "a % 2", "a << 2",
    "~a", "...", "a.real", "Symbol('a')", "Integer(2)", "factorial(5)", "exec('1')",
    "globals()", "().__class__", "a**(b**2)", "10**10**10", "a" * 10000, "\x00", "\n\n",
    "2**(a*0 + 10**8)", "log(0)", "sqrt(-1)", "1/(a - a)", "a^(1/2)", "a" + "*a" * 400,
    "exp(exp(exp(exp(a))))", "exp(-exp(exp(exp(a))))", "sqrt(a - 100)", "(a + b)^8^8",
]


@pytest.mark.parametrize("junk", JUNK, ids=[repr(j)[:20] for j in JUNK])
def test_junk_strings_are_feedback_not_a_traceback(junk):
    start = time.perf_counter()
    result = formula_comparison(junk, W_XY, symbols=[a, b, theta])
    assert time.perf_counter() - start < 2.0
    assert result.problem is not None and result.problem != NOT_ATTEMPTED, junk


def test_formulas_too_large_to_evaluate_are_named_not_evaluated():
    start = time.perf_counter()
    for huge in ("exp(exp(exp(exp(a))))", sp.exp(-sp.exp(sp.exp(sp.exp(a))))):
        problem = compare_formula(huge, W_XY, symbols=[a, b, theta])
        assert "takes values too large to evaluate" in problem
    assert time.perf_counter() - start < 1.0
    assert "is not real at" in compare_formula("sqrt(a - 100)", W_XY, symbols=[a, b, theta])


def test_a_string_is_never_evaluated_beyond_arithmetic(tmp_path):
    marker = tmp_path / "ran"
    attempt = f"__import__('pathlib').Path({str(marker)!r}).touch()"
    for text in (attempt, f"a + ({attempt})", f"sin({attempt})"):
        assert formula_comparison(text, W_XY, symbols=[a, b, theta]).problem is not None
    assert not marker.exists()


@pytest.mark.parametrize("placeholder", [..., None])
def test_placeholders_are_not_attempted(placeholder):
    assert compare_formula(placeholder, W_XY, symbols=[a, b, theta]) == NOT_ATTEMPTED


# ---------------------------------------------------------------------------- comparing
@pytest.mark.parametrize(
    "answer, reference, symbols",
    [
        ("(a*c + b*c)/(a + b + c)", PARALLEL, [a, b, c]),  # expanded numerator
        ("1/(1/(a + b) + 1/c)", PARALLEL, [a, b, c]),  # the parallel rule
        ("c - c**2/(a + b + c)", PARALLEL, [a, b, c]),  # another form
        ("(a - b)*sin(2*theta)/2", W_XY, [a, b, theta]),  # double angle
        ("(a - b)*tan(θ)*cos(θ)^2", W_XY, [a, b, theta]),  # tangent
        ("a*sin(θ)*cos(θ) - b*cos(θ)*sin(θ)", W_XY, [a, b, theta]),  # expanded
        ("(a-b)*sin(θ)*cos(θ)*(sin(θ)^2 + cos(θ)^2)", W_XY, [a, b, theta]),  # times 1
        (sp.expand(W_XY), W_XY, [a, b, theta]),  # a sympy expression
        ("(x - y)*sin(θ) + (y + 1)*cos(θ)", JAC, [x, y, theta]),
        ("x*sin(θ) - y*sin(θ) + y*cos(θ) + cos(θ)", JAC, [x, y, theta]),
    ],
)
def test_equivalent_forms_are_proved_equal(answer, reference, symbols):
    result = formula_comparison(answer, reference, symbols=symbols)
    assert result.problem is None and result.how == "symbolic", result


def test_the_numeric_fallback_decides_when_sympy_cannot():
    # sympy does not reduce sqrt(a^2 + 2ab + b^2) - (a + b) to 0, even for positive a, b
    got, ref = sp.sqrt(a**2 + 2 * a * b + b**2), a + b
    assert sp.simplify(got - ref) != 0
    result = formula_comparison(got, ref, symbols=[a, b])
    assert result.problem is None and result.how == "numeric"
    assert "agree to 40 digits at 8 random points" in result.detail
    result = formula_comparison(sp.atan(a) + sp.atan(1 / a), sp.pi / 2, symbols=[a])
    assert result.problem is None and result.how == "numeric"
    # ... and it is not lenient: |a - b| is not a - b once b > a, which the points sample
    assert compare_formula(sp.sqrt((a - b) ** 2), a - b, symbols=[a, b]) is not None
    # nor is atan(a) + atan(b) the angle of the sum formula beyond ab = 1
    got = sp.atan((a + b) / (1 - a * b))
    assert compare_formula(got, sp.atan(a) + sp.atan(b), symbols=[a, b]) is not None


@pytest.mark.parametrize(
    "answer, reference, symbols, named",
    [
        # a term's sign, a missing term, an extra term, a wrong factor (the student's form)
        ("(y - x)*sin(θ) + (y + 1)*cos(θ)", JAC, [x, y, theta],
         "the term in sin(θ) has the wrong sign"),
        ("(x - y)*sin(θ)", JAC, [x, y, theta], "a term in cos(θ) is missing"),
        ("(x - y)*sin(θ) + (y + 1)*cos(θ) + x", JAC, [x, y, theta],
         "your term x should not be there"),
        ("(x - y)*sin(θ) + 2*(y + 1)*cos(θ)", JAC, [x, y, theta],
         "the term in cos(θ) has the wrong factor: yours is 2·(y + 1)·cos(θ), 2 times"),
        ("(x - y)*sin(θ) + (y - 1)*cos(θ)", JAC, [x, y, theta],
         "in the term in cos(θ), your term −1 has the wrong sign"),
        ("(x - y)*sin(θ) + y*cos(θ)", JAC, [x, y, theta],
         "in the term in cos(θ), a constant term is missing"),
        ("(x + y)*sin(θ) + (y + 1)*cos(θ)", JAC, [x, y, theta],
         "in the term in sin(θ), your term y has the wrong sign"),
        # the same, found in the trigonometric normal form when the student expanded sin(2θ)
        ("(a + b)*sin(θ)*cos(θ)", sp.factor(sp.trigsimp(W_XY)), [a, b, theta],
         "in the term in sin(θ)·cos(θ), your term b has the wrong sign"),
        ("a*sin(θ)*cos(θ)", W_XY, [a, b, theta],
         "it does not depend on b, and the right formula does"),
        ("(a - b)*sin(θ)^2", W_XY, [a, b, theta],
         "your term (a − b)·sin(θ)^2 should not be there"),
        # fractions: the denominator, the numerator, upside down
        ("c*(a + b)/(a + b - c)", PARALLEL, [a, b, c],
         "the numerator is right; in the denominator, your term −c has the wrong sign"),
        ("a*b*c/(a + b + c)", PARALLEL, [a, b, c],
         "over the right denominator, your numerator a·b·c is wrong"),
        ("c*(a + b)", PARALLEL, [a, b, c], "the numerator is right, but yours has no denominator"),
        ("(a + b + c)/(c*(a + b))", PARALLEL, [a, b, c], "it is the reciprocal of the right one"),
        ("a + b + c", PARALLEL, [a, b, c],
         "the right formula is a fraction, and yours has no denominator"),
        # the whole formula: a sign, a factor, a constant, zero
        ("-(a - b)*sin(θ)*cos(θ)", W_XY, [a, b, theta], "it has the opposite sign"),
        ("(a - b)*sin(2*θ)", W_XY, [a, b, theta], "it is 2 times the right one"),
        ("c*(a + b)/(a + b + c) + 1", PARALLEL, [a, b, c], "it is 1 larger everywhere"),
        ("0", W_XY, [a, b, theta], "is 0 everywhere"),
    ],
)
def test_wrong_formulas_name_the_wrong_term(answer, reference, symbols, named):
    problem = compare_formula(answer, reference, symbols=symbols)
    assert problem is not None and named in problem, problem


WRONG = {
    PARALLEL: ["a*b*c/(a + b + c)", "c*(a+b)/(a+b-c)", "a + b", "c", "0", "a*(b + c)/(a+b+c)",
               "(a+b)*c**2/(a+b+c)", "1/(a + b + c)", "c*(a+b)", "c/(a+b+c)", "a*b/(a+b+c)"],
    W_XY: ["0", "a*sin(θ)*cos(θ)", "b*sin(θ)*cos(θ)", "(a+b)*sin(θ)*cos(θ)", "sin(θ)*cos(θ)",
           "(a-b)*sin(θ)", "(a-b)*cos(θ)", "a - b", "(a-b)*sin(θ)^2", "a*cos(θ)^2 + b*sin(θ)^2"],
    JAC: ["0", "(x - y)*sin(θ)", "(y + 1)*cos(θ)", "sin(θ) + cos(θ)", "x*sin(θ) + y*cos(θ)",
          "(y - x)*sin(θ) - (y + 1)*cos(θ) + 1", "x - y + y + 1", "(x-y)*cos(θ) + (y+1)*sin(θ)"],
}


def _terms(expr):
    return [sp.sstr(t) for t in sp.Add.make_args(sp.expand(expr))]


@pytest.mark.parametrize("reference", list(WRONG), ids=["5.5", "6.5", "two terms"])
def test_the_first_tier_never_shows_the_reference(reference):
    symbols = sorted(reference.free_symbols, key=lambda s: s.name)
    forms = {sp.sstr(reference), show_formula(reference), sp.sstr(sp.expand(reference)),
             show_formula(sp.expand(reference)), show_formula(sp.factor(reference)),
             sp.sstr(sp.factor(reference)), show_formula(sp.together(sp.expand(reference)))}
    for answer in WRONG[reference]:
        problem = compare_formula(answer, reference, symbols=symbols)
        assert problem is not None, answer
        for form in forms:
            assert form not in problem, (answer, form, problem)
        # never every term of the reference named as missing
        missing = [t for t in _terms(reference)
                   if f"a term in {show_formula(sp.sympify(t).as_coeff_Mul()[1])} is missing"
                   in problem]
        assert len(missing) < len(_terms(reference)) or len(_terms(reference)) == 0, problem


def test_comparisons_are_fast():
    start = time.perf_counter()
    for answer, ref in itertools.product(WRONG[W_XY][:5], [W_XY]):
        compare_formula(answer, ref, symbols=[a, b, theta])
    assert time.perf_counter() - start < 5.0


def test_show_formula_reads_like_the_book():
    assert show_formula((a - b) * sp.sin(theta) ** 2) == "(a − b)·sin(θ)^2"
    assert show_formula(sp.Symbol("theta_i") + sp.Symbol("x_j")) == "θ_i + x_j"


def test_formula_needs_symbols():
    with pytest.raises(TypeError):
        Formula([])
    with pytest.raises(TypeError):
        Formula(["a"])


# ------------------------------------------------------------------ the chapters' exercises
def _points(n, seed):
    return np.random.default_rng(seed).uniform(-3, 3, size=(n, 9))


def test_2_5_reference_is_lagolibs_numeric_jacobian():
    ref = ch02.jacobian_entry_reference()
    f = sp.lambdify(ch02.EDGE_SYMBOLS, ref, "numpy")
    for p in _points(20, 5):
        _, A, _ = gauss_newton.edge_jacobians(p[0:3], p[3:6], p[6:9])
        assert abs(f(*p) - A[0, 2]) <= 1e-12 * (1 + abs(A[0, 2]))
    theta_i = ch02.EDGE_SYMBOLS[2]
    assert ref.has(sp.sin) and ref.has(sp.cos) and theta_i in ref.free_symbols


def test_5_5_reference_is_lagolibs_phase1_covariance():
    ref = ch05.blue_variance_reference()
    assert sp.simplify(ref - PARALLEL) == 0  # c(a + b)/(a + b + c), as derived from eq. (13)
    f = sp.lambdify(ch05.VARIANCE_SYMBOLS, ref)
    rng = np.random.default_rng(3)
    for variances in rng.uniform(0.01, 4.0, size=(20, 3)):
        g = ch05.triangle_graph(variances)
        est = L.phase1_orientations(g, g.measurements[:, 2])
        assert est.covariance()[1, 1] == pytest.approx(f(*variances), rel=1e-10)


def test_6_5_reference_is_lagolibs_phase2_information():
    ref = ch06.world_information_reference()
    assert sp.simplify(ref - W_XY) == 0  # (a − b) sin θ cos θ
    f = sp.lambdify(ch06.INFORMATION_SYMBOLS, ref)
    rng = np.random.default_rng(4)
    for a_, b_, th in zip(rng.uniform(0.1, 50, 20), rng.uniform(0.1, 50, 20),
                          rng.uniform(-np.pi, np.pi, 20)):
        # 0 -> 1 turns by th (so theta_hat_1 = th); edge 1 -> 2 has frame-i information
        # diag(a, b) (its measured turn is 0: the g2o frame is frame i)
        info = np.tile(np.diag([1.0, 1.0, 100.0]), (2, 1, 1))
        info[1, :2, :2] = np.diag([a_, b_])
        z = np.array([[1.0, 0.0, th], [1.0, 0.0, 0.0]])
        g = PoseGraph(np.zeros((3, 3)), np.array([(0, 1), (1, 2)]), z, info)
        p1 = L.phase1_orientations(g, L.regularize(g).delta_bar)
        W = L.phase2_relative_positions(g, p1).W.toarray()
        assert W[2, 3] == pytest.approx(f(a_, b_, th), rel=1e-9, abs=1e-9)


CHECKS = [
    (ch02.check_jacobian_entry, "2.5",
     "(x_i - x_j)*sin(theta_i + theta_z) + (y_j - y_i)*cos(theta_i + theta_z)",
     "(x_i - x_j)*sin(θ_i) + (y_j - y_i)*cos(θ_i)", "it rotates by θ_i alone"),
    (ch05.check_blue_variance, "5.5", "1/(1/(a + b) + 1/c)", "a*(b + c)/(a + b + c)",
     "that is the variance of θ̂_1"),
    (ch06.check_world_information, "6.5", "(a - b)*sin(2θ)/2",
     "(b - a)*sin(θ)*cos(θ)", "the rotation the other way round"),
]


@pytest.mark.parametrize("check, ex, right, slip, named", CHECKS, ids=[c[1] for c in CHECKS])
def test_the_chapters_derive_checks(check, ex, right, slip, named, capsys):
    assert check(...) is False
    assert f"Exercise {ex} — {NOT_ATTEMPTED}" in capsys.readouterr().out
    assert check(right) is True and passed(ex)
    out = capsys.readouterr().out
    assert out.startswith(f"Exercise {ex} — correct: your ") and "reduces the difference" in out
    assert check(slip) is False and not passed(ex)
    out = capsys.readouterr().out
    assert out.startswith(f"Exercise {ex} — not yet: ") and named in out, out
    assert 'hint("' + ex + '") gives a hint (3 levels' in out
    assert check("nonsense + 1") is False
    assert "nonsense is not one of the exercise's symbols" in capsys.readouterr().out
    for junk in JUNK[:20] + [[1, 2], {"a": 1}, np.zeros(3), object()]:
        assert check(junk) is False
        assert f"Exercise {ex} — not yet: " in capsys.readouterr().out
