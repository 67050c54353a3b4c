"""The *derive* exercises: an answer that is a formula, checked by symbolic equivalence.

A derive exercise asks for a formula — one entry of a Jacobian, a variance, an entry of a rotated
information matrix — and its check declares the answer's kind as :class:`Formula`::

    @check("6.5", W_xy=Formula([a, b, theta]))
    def check_world_information(W_xy): ...

A student writes the answer as a sympy expression or as a string that sympy reads, in the
exercise's symbols (``"(a - b)*sin(theta)*cos(theta)"``; ``θ`` may stand for ``theta``, ``^``
for ``**``, and a product may be written ``2 x_i`` or ``cos(θ)(a - b)``).  A string is read
safely: sympy turns it into Python code (:func:`sympy.parsing.sympy_parser.stringify_expr`), and
that code is evaluated only if every piece of it is a number, one of the exercise's symbols, one of
the usual functions (:data:`FUNCTIONS`) or arithmetic — nothing else (no attributes, no
indexing, no other names) is ever evaluated.  A string that does not parse is "not yet" with the
problem named; a name that is not one of the exercise's symbols is named.

:func:`compare_formula` compares the answer with the reference formula, in three steps:

1. **numbers first** — both formulas at eight seeded random points of the exercise's domain,
   each evaluated exactly (rational coordinates) to 40 significant digits.  A difference there
   *proves* that the formulas differ, and the answer is "not yet";
2. **symbolic proof** — otherwise ``got - reference`` is reduced to 0 by ``expand``, then by a
   trigonometric normal form (``expand_trig``, ``sin² = 1 - cos²``, over a common denominator),
   then by ``sympy.simplify``: "correct", exactly;
3. **numeric fallback** — when sympy cannot reduce the difference to 0 (``simplify`` does not
   know every identity), the agreement of step 1 decides.  Two different formulas built from
   polynomials, fractions and the elementary functions are analytic where they are defined, and
   their difference, if not identically zero, vanishes only on a set of measure zero; eight
   independent random points each hitting it is an event of probability zero, and agreement to
   40 digits rules out a difference hidden by rounding.  (What numbers cannot see is a difference
   outside the sampled domain — the domain is the exercise's: positive variances, any angle.)

A wrong formula gets a diagnosis that names the term that is wrong when it can: both formulas are
split into additive terms — as written, and in the trigonometric normal form over a common
denominator — and the split that explains the difference with the fewest changes is reported:
a missing term, an extra term, a term with the wrong sign or the wrong factor, a wrong
denominator; or the whole formula off by a constant factor or a constant.  A term is *described*
("the term in sin(θ_i + θ_z) has the wrong sign", "a term in a·c is missing"); only the
student's own terms are printed, never the reference formula, and never so many of its terms
that they spell it out.

>>> import sympy as sp
>>> a, b = sp.symbols("a b", positive=True)
>>> compare_formula("a*b/(a + b)", a * b / (a + b), symbols=[a, b]) is None
True
>>> print(compare_formula("1/(1/a + 1/b)", a * b / (a + b), symbols=[a, b]))
None
>>> print(compare_formula("a*b/(a - b)", a * b / (a + b), symbols=[a, b]))  # doctest: +NORMALIZE_WHITESPACE
your formula differs from the right one: the numerator is right; in the denominator,
your term −b has the wrong sign.
>>> print(compare_formula("a*b/(a + c)", a * b / (a + b), symbols=[a, b]))  # doctest: +ELLIPSIS
your formula should be one formula in a, b (...), got 'a*b/(a + c)' (a string): c is not one...
"""

from __future__ import annotations

import ast
import cmath
import math
import numbers
import re
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
import sympy as sp
from sympy.parsing.sympy_parser import (
    auto_number,
    auto_symbol,
    convert_xor,
    implicit_multiplication,
    stringify_expr,
)

from lagolib.exercises._coerce import (
    NOT_ATTEMPTED,
    Kind,
    WrongKind,
    _Bad,
    describe,
    is_placeholder,
    show,
)

__all__ = [
    "FUNCTIONS",
    "Formula",
    "FormulaComparison",
    "compare_formula",
    "formula_comparison",
    "show_formula",
]

#: the functions (and constants) a formula written as a string may use
FUNCTIONS = {
    "sin": sp.sin,
    "cos": sp.cos,
    "tan": sp.tan,
    "cot": sp.cot,
    "sec": sp.sec,
    "csc": sp.csc,
    "asin": sp.asin,
    "acos": sp.acos,
    "atan": sp.atan,
    "atan2": sp.atan2,
    "sinh": sp.sinh,
    "cosh": sp.cosh,
    "tanh": sp.tanh,
    "exp": sp.exp,
    "log": sp.log,
    "ln": sp.log,
    "sqrt": sp.sqrt,
    "Abs": sp.Abs,
    "abs": sp.Abs,
    "pi": sp.pi,
    "π": sp.pi,
    "E": sp.E,
}
_CONSTRUCTORS = {
    "Integer": sp.Integer,
    "Float": sp.Float,
    "Rational": sp.Rational,
    "Symbol": sp.Symbol,
    "Function": sp.Function,
}
_TRANSFORMATIONS = (auto_symbol, auto_number, convert_xor, implicit_multiplication)
_GREEK = (
    "alpha beta gamma delta epsilon zeta eta theta iota kappa lambda mu nu xi omicron pi rho "
    "sigma tau upsilon phi chi psi omega"
).split()
_GREEK_LETTERS = dict(zip(_GREEK, "αβγδεζηθικλμνξοπρστυφχψω"))
_MAX_CHARS = 2000  # a formula longer than this is not an answer
_MAX_NODES = 600  # nor one of more pieces
_MAX_EXPONENT = 8  # numeric exponents (2 is the usual; a tower of powers is refused)
_MAX_TERMS = 400  # expand / simplify only formulas whose expansion stays this small
_SIMPLIFY_OPS = 160  # sympy.simplify only below this many operations (it can take seconds)
_DIGITS = 40  # numeric comparison: significant digits of each evaluation
_RTOL = 1e-25  # numeric comparison: relative tolerance (far above 40-digit rounding)
_SHOWN = 3  # at most this many differences per message


def _display_name(name: str) -> str:
    """``theta_i`` as ``θ_i`` (a Greek letter's name spelled out becomes the letter)."""
    head, sep, tail = name.partition("_")
    return _GREEK_LETTERS.get(head, head) + sep + tail


def show_formula(expr, width: int = 80) -> str:
    """A formula as one readable line: ``θ`` for ``theta``, ``·`` for ``*``, ``^`` for ``**``.

    >>> x, theta = sp.symbols("x theta")
    >>> show_formula(-x * sp.sin(theta) ** 2)
    '−x·sin(θ)^2'
    """
    text = sp.sstr(expr)
    names = sorted({s.name for s in getattr(expr, "free_symbols", ())}, key=len, reverse=True)
    for name in names:
        shown = _display_name(name)
        if shown != name:
            text = re.sub(rf"(?<![\w]){re.escape(name)}(?![\w])", shown, text)
    text = text.replace("**", "^").replace("*", "·").replace("-", "−")
    return text if len(text) <= width else text[: width - 3] + "..."


# ------------------------------------------------------------------------------- the kind
class Formula(Kind):
    """One formula in the exercise's ``symbols``: a sympy expression, or a string sympy reads.

    The answer is read as a sympy expression in exactly those symbols (a student's own
    ``sp.Symbol("theta_i")``, whatever its assumptions, is the exercise's ``theta_i``; ``θ_i`` in
    a string is ``theta_i``); floats become exact fractions (``0.5`` is ``1/2``).  Refused, with
    the reason named: a string that sympy cannot read, a name that is not one of the symbols or
    of :data:`FUNCTIONS`, an equation, a matrix or a list, an undefined function, an imaginary
    unit, a bool, NaN or infinity.

    Parameters
    ----------
    symbols : sequence of sympy.Symbol
        The symbols the formula may use (their assumptions, e.g. ``positive=True``, say where the
        check samples them).
    example : str, optional
        A well-formed formula in these symbols for the hint (not the answer!).
    """

    def __init__(self, symbols, *, example: str | None = None):
        self.symbols = tuple(symbols)
        if not self.symbols or not all(isinstance(s, sp.Symbol) for s in self.symbols):
            raise TypeError("Formula(symbols): give a non-empty sequence of sympy Symbols")
        self.names = {}
        for s in self.symbols:
            self.names[s.name] = s
            self.names[_display_name(s.name)] = s
        listing = ", ".join(_display_name(s.name) for s in self.symbols)
        self.listing = listing
        self.what = f"one formula in {listing} (a sympy expression, or a string sympy reads)"
        greek = [s.name for s in self.symbols if _display_name(s.name) != s.name]
        spelled = (
            f" ({_display_name(greek[0])} may be written {greek[0]})" if greek else ""
        )
        example = example or f"2*{self.symbols[0].name}"
        self.hint = (
            f"write the formula as a string such as \"{example}\", in the symbols {listing}"
            f"{spelled}; * multiplies, ** or ^ raises to a power, and functions take their "
            "argument in parentheses, e.g. sin(...). A sympy expression works too."
        )

    # ---------------------------------------------------------------- reading an answer
    def parse(self, value):
        if isinstance(value, np.ndarray) and value.ndim == 0:
            value = value[()]
        if isinstance(value, np.str_):
            value = str(value)
        if isinstance(value, (bool, np.bool_)):
            raise _Bad(describe(value))
        if isinstance(value, str):
            expr = self._from_string(value)
        elif isinstance(value, (sp.Basic, sp.MatrixBase)):
            expr = self._from_sympy(value)
        elif isinstance(value, (numbers.Rational, Fraction)) and not isinstance(value, bool):
            expr = sp.Rational(value.numerator, value.denominator)
        elif isinstance(value, (numbers.Real, np.floating, np.integer)):
            x = float(value)
            if not math.isfinite(x):
                raise _Bad(f"{x}, which is not a finite number")
            expr = sp.nsimplify(sp.Float(repr(x)), rational=True)
        else:
            raise _Bad(describe(value))
        return _exact(expr)

    def _from_sympy(self, value):
        if isinstance(value, sp.MatrixBase):
            raise _Bad(
                f"a sympy matrix of shape {value.shape}",
                "give one entry of the matrix (M[0, 2]), not the matrix.",
            )
        if isinstance(value, sp.core.relational.Relational) or (
            isinstance(value, sp.logic.boolalg.Boolean) and not isinstance(value, sp.Expr)
        ):
            raise _Bad(
                f"{show(value, 60)}, an equation or a truth value",
                "give only the formula itself (the right-hand side), not an equation.",
            )
        if not isinstance(value, sp.Expr):
            raise _Bad(f"{show(value, 60)} (a sympy {type(value).__name__}, not a formula)")
        if value.has(sp.Derivative, sp.Integral):
            raise _Bad(
                f"{show(value, 60)}, which holds an unevaluated derivative or integral",
                "evaluate it first (.doit()), then simplify.",
            )
        known = {f for f in FUNCTIONS.values() if isinstance(f, type)}
        undefined = sorted(
            {f.func.__name__ for f in value.atoms(sp.Function) if f.func not in known}
        )
        if undefined:
            raise _Bad(
                f"{show(value, 60)}: {', '.join(undefined)} is not a known function",
                self.hint,
            )
        mapping, unknown = {}, []
        for s in value.free_symbols:
            mine = self.names.get(s.name)
            if mine is None:
                unknown.append(_display_name(s.name))
            elif mine is not s:
                mapping[s] = mine
        if unknown:
            raise _Bad(
                f"{show(value, 60)}: {self._unknown(unknown)}", self.hint
            )
        return value.xreplace(mapping) if mapping else value

    def _unknown(self, names) -> str:
        names = sorted(set(names))
        verb = "is not one of" if len(names) == 1 else "are not among"
        return f"{', '.join(names)} {verb} the exercise's symbols ({self.listing})"

    def _from_string(self, text: str):
        shown = show(text, 60)
        if len(text) > _MAX_CHARS:
            raise _Bad(f"a string of {len(text)} characters, too long for a formula")
        if not text.strip():
            raise _Bad("an empty string", self.hint)
        if re.search(r"(?<![=<>!])=(?!=)", text) or re.search(r"==|<|>|!=", text):
            raise _Bad(
                f"{shown} (a string): an equation or comparison",
                "give only the formula itself (the right-hand side), without = < >.",
            )
        funcs = "|".join(sorted((k for k in FUNCTIONS if k.isalpha() and k not in ("pi", "E")),
                                key=len, reverse=True))
        bare = re.search(rf"\b({funcs})\s*(\^|\*\*|[^\s(^*])", text)
        if bare:
            f = bare.group(1)
            raise _Bad(
                f"{shown} (a string), which sympy cannot read: {f} needs its argument in "
                f"parentheses, and a power goes after them: {f}(θ)^2, not {f}^2(θ) or {f} θ",
                self.hint,
            )
        clean = (
            text.replace("\u2212", "-").replace("·", "*").replace("×", "*").replace("⋅", "*")
        )
        clean = clean.replace("²", "**2").replace("³", "**3")
        local = dict(FUNCTIONS)
        local.update(self.names)
        try:
            code = stringify_expr(clean, dict(local), dict(_CONSTRUCTORS), _TRANSFORMATIONS)
            tree = ast.parse(code.strip(), mode="eval")
        except Exception as exc:  # a tokenizer or syntax error: name it
            raise _Bad(f"{shown} (a string), which sympy cannot read: {_syntax(exc)}",
                       self.hint) from None
        problem = _Checker(set(self.names), set(FUNCTIONS)).check(tree)
        if problem:
            unknown = problem[1] if problem[0] == "unknown" else None
            if unknown:
                raise _Bad(f"{shown} (a string): {self._unknown(unknown)}", self.hint)
            raise _Bad(f"{shown} (a string), which sympy cannot read: {problem[1]}", self.hint)
        namespace = {**_CONSTRUCTORS, **local}
        try:
            value = eval(compile(tree, "<formula>", "eval"), {"__builtins__": {}}, namespace)
        except Exception as exc:  # e.g. sin**2 (a function raised to a power)
            raise _Bad(
                f"{shown} (a string), which sympy cannot read: {type(exc).__name__}: "
                f"{show(str(exc), 80)}",
                self.hint,
            ) from None
        if not isinstance(value, sp.Basic):
            value = sp.sympify(value)
        if isinstance(value, sp.Expr) and (value.has(sp.I) or value.has(sp.zoo, sp.nan)):
            raise _Bad(f"{shown} (a string), which is not a real formula")
        return self._from_sympy(value)


def _syntax(exc) -> str:
    """The problem a tokenizer or parser found, as a short phrase."""
    if isinstance(exc, SyntaxError):
        return "unbalanced parentheses or a misplaced operator" + (
            f" ({exc.msg})" if exc.msg else ""
        )
    text = str(exc)
    if "EOF" in text or "multi-line" in text:
        return "a parenthesis is not closed"
    return f"{type(exc).__name__}: {show(text, 60)}"


class _Checker:
    """Walks the code sympy made of a string; only numbers, symbols, functions and arithmetic
    pass.  ``check`` returns None, ``("unknown", names)`` or ``("syntax", what)``."""

    _OPS = (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow)

    def __init__(self, symbols, functions):
        self.symbols = symbols
        self.functions = functions
        self.unknown = []
        self.nodes = 0

    def check(self, tree):
        try:
            self._visit(tree.body)
        except _Refused as exc:
            return ("syntax", str(exc))
        if self.unknown:
            return ("unknown", self.unknown)
        return None

    def _visit(self, node, exponent=False):
        self.nodes += 1
        if self.nodes > _MAX_NODES:
            raise _Refused("the formula has too many pieces")
        if isinstance(node, ast.BinOp) and isinstance(node.op, self._OPS):
            if isinstance(node.op, ast.Pow):
                if exponent:
                    raise _Refused("a power inside an exponent (a tower of powers)")
                self._visit(node.left, exponent)
                self._visit(node.right, exponent=True)
                return
            self._visit(node.left, exponent)
            self._visit(node.right, exponent)
            return
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            self._visit(node.operand, exponent)
            return
        if isinstance(node, ast.Name):
            if node.id in self.symbols or node.id in self.functions:
                return
            raise _Refused(f"the name {node.id!r}")
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and not node.keywords:
            name = node.func.id
            if name in ("Integer", "Float", "Rational"):
                for arg in node.args:
                    if not (isinstance(arg, ast.Constant) and isinstance(arg.value, (int, str))):
                        raise _Refused("a malformed number")
                    if exponent and abs(float(arg.value)) > _MAX_EXPONENT:
                        raise _Refused(f"an exponent larger than {_MAX_EXPONENT}")
                return
            if name in ("Symbol", "Function"):
                if len(node.args) == 1 and isinstance(node.args[0], ast.Constant):
                    self.unknown.append(_display_name(str(node.args[0].value)))
                    return
                raise _Refused("a malformed name")
            if name in self.functions:
                for arg in node.args:
                    self._visit(arg, exponent)
                return
            raise _Refused(f"a call of {name!r}")
        if isinstance(node, ast.Call) and not isinstance(node.func, ast.Name):
            # Function('f')(x), an unknown function applied to arguments; or x.evalf()
            self._visit(node.func, exponent)
            for arg in node.args:
                self._visit(arg, exponent)
            return
        what = {
            ast.Attribute: "an attribute (a dot after a name)",
            ast.Subscript: "indexing with [ ]",
            ast.Lambda: "a lambda",
            ast.Compare: "a comparison",
            ast.Tuple: "several values separated by commas",
            ast.List: "a list",
            ast.Constant: "text in quotes",
        }.get(type(node), f"{type(node).__name__.lower()} syntax")
        raise _Refused(what)


class _Refused(Exception):
    pass


def _exact(expr):
    """``expr`` with every float replaced by the exact fraction it was written as."""
    floats = expr.atoms(sp.Float)
    if not floats:
        return expr
    return expr.xreplace({f: sp.nsimplify(f, rational=True) for f in floats})


# ------------------------------------------------------------------------- comparing
@dataclass(frozen=True)
class FormulaComparison:
    """What :func:`formula_comparison` found.

    Attributes
    ----------
    problem : str or None
        None when the answer is right; otherwise the sentence for the student (the first tier:
        what is wrong, never the reference formula), or :data:`NOT_ATTEMPTED`.
    how : str
        For a right answer, how it was established: ``"symbolic"`` (sympy reduced the
        difference to 0) or ``"numeric"`` (sympy could not; the random points agreed).
    detail : str
        A sentence saying so, for the "correct" line.
    """

    problem: str | None
    how: str = ""
    detail: str = ""


def compare_formula(got, reference, *, symbols, name="your formula", domain=None, points=8,
                    seed=0, slips=()):
    """None if the formula ``got`` equals ``reference``, else the sentence saying what differs.

    See :func:`formula_comparison` for the parameters and the module docstring for the method.
    Never raises on an answer.
    """
    return formula_comparison(
        got, reference, symbols=symbols, name=name, domain=domain, points=points, seed=seed,
        slips=slips,
    ).problem


def formula_comparison(got, reference, *, symbols, name="your formula", domain=None, points=8,
                       seed=0, slips=()) -> FormulaComparison:
    """Compare a student's formula with the reference (see the module docstring).

    Parameters
    ----------
    got : str, sympy expression, number, or a placeholder
        The answer; read as :class:`Formula` of ``symbols``.
    reference : sympy expression
        The right formula, in ``symbols`` (ideally derived by sympy, not typed in).
    symbols : sequence of sympy.Symbol
        The exercise's symbols.
    name : str
        How the sentence calls the answer.
    domain : dict, optional
        ``{symbol: (low, high)}``: where to sample each symbol; default ``(0.1, 3)`` for a
        positive symbol, ``(-3, 3)`` otherwise (angles: any angle, in radians).
    points : int
        How many random points the numeric comparison uses (at least 3).
    seed : int
        Seed of the random points.
    slips : sequence of (formula, str)
        Known wrong answers and the sentence that names each (e.g. ``R(θ_i)`` where
        ``R(θ_i + θ_z)`` belongs): a formula equal to one of them gets that sentence.  The
        sentence must not give the right formula away.

    Returns
    -------
    FormulaComparison
    """
    if is_placeholder(got):
        return FormulaComparison(NOT_ATTEMPTED)
    kind = Formula(symbols)
    try:
        g = kind.coerce(got, name)
    except WrongKind as exc:
        return FormulaComparison(str(exc))
    try:
        return _compare(
            g, sp.sympify(reference), kind, name, domain, max(3, int(points)), seed, slips
        )
    except Exception as exc:  # noqa: BLE001 - an odd formula is feedback, never a traceback
        return FormulaComparison(
            f"{name} could not be compared with the right formula ({type(exc).__name__}: "
            f"{show(str(exc), 80)}); write it with the exercise's symbols and the usual "
            "functions only."
        )


def _sample_points(symbols, domain, n, seed):
    """``n`` points, each a dict symbol -> exact rational inside the symbol's interval."""
    rng = np.random.default_rng(seed)
    domain = dict(domain or {})
    out = []
    for _ in range(n):
        point = {}
        for s in symbols:
            low, high = domain.get(s, (0.1, 3.0) if s.is_positive else (-3.0, 3.0))
            u = float(rng.uniform(low, high))
            point[s] = sp.Rational(round(u * 10**6), 10**6)
        out.append(point)
    return out


def _value(expr, point):
    """``(real part, imaginary part)`` of ``expr`` at ``point``, to :data:`_DIGITS` digits, or
    None where it is undefined."""
    v = expr.xreplace(point)
    if v.has(sp.zoo, sp.nan, sp.oo, -sp.oo):
        return None
    try:
        re_, im_ = sp.N(v, _DIGITS).as_real_imag()
        re_, im_ = sp.Float(re_, _DIGITS), sp.Float(im_, _DIGITS)
    except (TypeError, ValueError, ArithmeticError):
        return None
    if not (re_.is_finite and im_.is_finite):
        return None
    return re_, im_


_CMATH = {
    sp.sin: cmath.sin, sp.cos: cmath.cos, sp.tan: cmath.tan, sp.sinh: cmath.sinh,
    sp.cosh: cmath.cosh, sp.tanh: cmath.tanh, sp.exp: cmath.exp, sp.log: cmath.log,
    sp.asin: cmath.asin, sp.acos: cmath.acos, sp.atan: cmath.atan, sp.Abs: abs,
    sp.cot: lambda z: 1 / cmath.tan(z), sp.sec: lambda z: 1 / cmath.cos(z),
    sp.csc: lambda z: 1 / cmath.sin(z),
}
_HUGE = 1e250


def _overflows(expr, point) -> bool:
    """Whether ``expr`` or one of its parts exceeds :data:`_HUGE` at ``point`` in floating point.

    Exact evaluation of such a formula (``exp(exp(exp(exp(a))))``) would not finish; a quick
    float pass over every sub-expression finds it first.  Parts it cannot evaluate (a division
    by zero, a function it does not know) are left to the exact evaluation.
    """

    def value(e):
        if e.is_Symbol:
            return complex(point[e])
        if e.is_Number or e.is_NumberSymbol:
            return complex(e)
        args = [value(a) for a in e.args]
        if e.is_Add:
            out = sum(args)
        elif e.is_Mul:
            out = 1
            for a in args:
                out *= a
        elif e.is_Pow:
            out = args[0] ** args[1]
        elif isinstance(e, sp.atan2):
            out = complex(math.atan2(args[0].real, args[1].real))
        elif e.func in _CMATH:
            out = _CMATH[e.func](args[0])
        else:
            raise ArithmeticError(type(e).__name__)
        if not (abs(out) <= _HUGE):  # also NaN
            raise OverflowError
        return out

    try:
        value(expr)
    except OverflowError:
        return True
    except (ArithmeticError, ValueError, TypeError):
        return False
    return False


def _compare(g, r, kind, name, domain, n_points, seed, slips):
    symbols = kind.symbols
    # 1. numbers first: a difference at one point proves the formulas differ
    pts, vals_g, vals_r = [], [], []
    for point in _sample_points(symbols, domain, 4 * n_points, seed):
        vr = _value(r, point)
        if vr is None or abs(vr[1]) > 10.0 ** (-_DIGITS // 2) * max(1.0, abs(vr[0])):
            continue  # the reference is undefined (or not real) here: another point
        pts.append(point)
        vals_r.append(vr[0])
        if _overflows(g, {k: float(v) for k, v in point.items()}):
            where = ", ".join(f"{_display_name(s.name)} = {float(v):.3g}" for s, v in point.items())
            return FormulaComparison(
                f"{name} takes values too large to evaluate at {where} (beyond 1e250: an "
                "exponential of an exponential?), where the right formula is a moderate number."
            )
        vals_g.append(_value(g, point))
        if len(pts) == n_points:
            break
    if len(pts) < 3:
        raise ValueError("the reference formula is undefined almost everywhere in the domain")
    for point, vg in zip(pts, vals_g):
        if vg is None:
            where = ", ".join(f"{_display_name(s.name)} = {float(v):.3g}" for s, v in point.items())
            return FormulaComparison(
                f"{name} is undefined at {where} (a division by zero?), where the right "
                "formula has a value."
            )
        if abs(vg[1]) > 10.0 ** (-_DIGITS // 2) * max(1.0, abs(vg[0])):
            where = ", ".join(f"{_display_name(s.name)} = {float(v):.3g}" for s, v in point.items())
            return FormulaComparison(
                f"{name} is not real at {where}: it has an imaginary part (the square root or "
                "logarithm of a negative number?)."
            )
    vals_g = [vg[0] for vg in vals_g]
    diffs = [abs(vg - vr) for vg, vr in zip(vals_g, vals_r)]
    scales = [max(abs(vg), abs(vr), 1) for vg, vr in zip(vals_g, vals_r)]
    differ = [d > _RTOL * s for d, s in zip(diffs, scales)]
    if any(differ):
        slips = [(sp.sympify(e), str(t)) for e, t in slips]
        return FormulaComparison(_diagnose(g, r, name, pts, vals_g, vals_r, differ, slips))
    # 2. symbolic proof
    if _is_zero(g - r):
        return FormulaComparison(None, "symbolic", "sympy reduces the difference from the "
                                 "right formula to 0")
    # 3. numeric fallback (sound enough: see the module docstring)
    return FormulaComparison(
        None,
        "numeric",
        f"sympy could not reduce the difference to 0, but the two agree to {_DIGITS} digits at "
        f"{len(pts)} random points",
    )


# ---------------------------------------------------------------- normal forms and proofs
def _term_bound(expr) -> int:
    """An upper bound on the number of terms of ``expand(expr)`` (to refuse a blow-up)."""
    if expr.is_Add:
        return sum(_term_bound(a) for a in expr.args)
    if expr.is_Mul:
        out = 1
        for a in expr.args:
            out *= _term_bound(a)
            if out > 10**9:
                return out
        return out
    if expr.is_Pow and expr.exp.is_Integer and expr.exp > 0:
        k, n = _term_bound(expr.base), int(expr.exp)
        return math.comb(k + n - 1, n) if k > 1 else 1
    if isinstance(expr, sp.Function) and expr.args:
        return max(1, max(_term_bound(a) for a in expr.args) // 2)  # expand_trig may split it
    return 1


def _small(*exprs) -> bool:
    return all(_term_bound(e) <= _MAX_TERMS for e in exprs)


def _sin_cos(expr):
    """``tan``, ``cot``, ``sec``, ``csc`` written with ``sin`` and ``cos``; trig of sums and
    multiples expanded (``sin(a + b)``, ``sin(2a)``)."""
    expr = expr.replace(sp.tan, lambda u: sp.sin(u) / sp.cos(u))
    expr = expr.replace(sp.cot, lambda u: sp.cos(u) / sp.sin(u))
    expr = expr.replace(sp.sec, lambda u: 1 / sp.cos(u))
    expr = expr.replace(sp.csc, lambda u: 1 / sp.sin(u))
    return sp.expand_trig(expr)


def _unit_circle(poly):
    """An expanded polynomial in sines and cosines with every ``sin(u)^k``, ``k >= 2``, replaced
    by ``sin(u)^(k-2) (1 - cos(u)^2)``: a normal form (two such polynomials are equal as
    functions exactly when their normal forms are equal)."""

    def high_sine(x):
        return x.is_Pow and isinstance(x.base, sp.sin) and x.exp.is_Integer and x.exp >= 2

    def lower(x):
        u = x.base.args[0]
        return sp.sin(u) ** (x.exp - 2) * (1 - sp.cos(u) ** 2)

    poly = sp.expand(poly)
    for _ in range(2 * _MAX_EXPONENT + 2):
        if not poly.has(sp.sin):
            return poly
        reduced = sp.expand(poly.replace(high_sine, lower))
        if reduced == poly:
            return poly
        poly = reduced
    return poly


def _fraction(expr):
    """``(numerator, denominator)`` of the normal form of ``expr``, both expanded and reduced on
    the unit circle, the denominator's leading coefficient 1 (so that equal fractions have equal
    parts)."""
    expr = sp.cancel(sp.together(_sin_cos(expr)))
    num, den = sp.fraction(expr)
    num, den = _unit_circle(num), _unit_circle(den)
    if den.free_symbols:
        gens = sorted(den.atoms(sp.Symbol, sp.Function), key=sp.default_sort_key)
        try:
            lc = sp.Poly(den, *gens).LC()
        except sp.PolynomialError:
            lc = 1
    else:
        lc = den
    if lc not in (0, 1):
        num, den = sp.expand(num / lc), sp.expand(den / lc)
    return num, den


def _is_zero(d) -> bool:
    """Whether sympy reduces ``d`` to 0: expand, the trigonometric normal form, simplify."""
    if d == 0:
        return True
    if not _small(d):
        return False
    if sp.expand(d) == 0:
        return True
    try:
        if _fraction(d)[0] == 0:
            return True
    except (sp.PolynomialError, TypeError, ValueError):
        pass
    if sp.count_ops(d) <= _SIMPLIFY_OPS:
        try:
            return sp.simplify(d) == 0
        except Exception:  # noqa: BLE001 - simplify can fail on odd input; then: inconclusive
            return False
    return False


# -------------------------------------------------------------------------- diagnosis
def _split(expr, deep=True):
    """``{function part: polynomial cofactor}`` of an expression, expanded: each additive term
    is split into its factors whose base is a symbol (the cofactor) and the rest (sines,
    cosines, fractions, …: the function part, 1 when there is none).  ``deep=False`` leaves the
    arguments of the functions as written."""
    out = {}
    for term in sp.Add.make_args(sp.expand(expr) if deep else _expand_outside(expr)):
        coeff, factors = term.as_coeff_mul()
        fpart, ppart = [], []
        for f in factors:
            (ppart if f.as_base_exp()[0].is_Symbol else fpart).append(f)
        key = sp.Mul(*fpart)
        out[key] = out.get(key, 0) + coeff * sp.Mul(*ppart)
    out = {k: sp.expand(v) for k, v in out.items()}
    return {k: v for k, v in out.items() if v != 0}


def _expand_outside(expr):
    """``expand(expr)`` with the arguments of its functions left as they are."""
    funcs = expr.atoms(sp.Function)
    outer = [f for f in funcs if not any(h is not f and f in h.args for h in funcs)]
    outer = [f for f in outer if not any(h is not f and h.has(f) for h in funcs)]
    dummies = {f: sp.Dummy() for f in outer}
    expanded = sp.expand(expr.xreplace(dummies))
    return expanded.xreplace({d: f for f, d in dummies.items()})


def _is_fraction(key) -> bool:
    return any(
        f.is_Pow and f.exp.is_negative and f.base.free_symbols for f in sp.Mul.make_args(key)
    )


@dataclass
class _Issue:
    text: str
    missing: int = 0  # how many of the reference's terms this sentence names as missing


@dataclass
class _Report:
    """The differences one way of splitting finds; ``units`` counts the reference's terms."""

    issues: list
    units: int = 0
    prefix: str = ""

    def sentences(self) -> list:
        """The issues as sentences, never naming every term of the reference as missing."""
        named = sum(i.missing for i in self.issues)
        issues = [i.text for i in self.issues]
        if self.units and named >= self.units:  # that would spell the reference out
            issues = [i.text for i in self.issues if not i.missing]
            issues.append(
                "the right formula's term is missing from it" if named == 1
                else f"{named} terms of the right formula are missing from it"
            )
        if self.prefix and issues:
            issues[0] = self.prefix + issues[0]
        return issues


def _units(split) -> int:
    """Terms of a split as the sentences count them: one per function part, one per monomial of
    the part without functions."""
    return sum(len(sp.Add.make_args(v)) if k == 1 else 1 for k, v in split.items())


def _compare_terms(got, ref) -> _Report:
    """The differences between two splits ``{key: cofactor}`` (see :func:`_split`)."""
    issues = []
    for key in sorted(set(got) | set(ref), key=sp.default_sort_key):
        pg, pr = got.get(key, 0), ref.get(key, 0)
        if sp.expand(pg - pr) == 0:
            continue
        if key == 1:  # the part without functions: compare its monomials one by one
            issues += _compare_monomials(pg, pr)
            continue
        fraction = _is_fraction(key)
        if pr == 0:
            issues.append(_Issue(f"your term {_show_term(key, pg)} should not be there"))
            continue
        if pg == 0:
            what = "a term with a denominator" if fraction else f"a term in {show_formula(key)}"
            issues.append(_Issue(f"{what} is missing", 1))
            continue
        pure = fraction and all(_is_fraction(f) for f in sp.Mul.make_args(key))
        label = "the term over the right denominator" if fraction else (
            f"the term in {show_formula(key)}"
        )
        ratio = sp.cancel(pg / pr)
        inner = _compare_monomials(pg, pr)
        shared = set(sp.expand(pg).as_coefficients_dict()) & set(
            sp.expand(pr).as_coefficients_dict()
        )
        if pure:  # a single fraction: speak of its numerator
            if ratio == -1:
                text = "over the right denominator, the numerator has the wrong sign"
            elif ratio.is_number:
                text = (f"over the right denominator, your numerator {_show_term(1, pg)} is "
                        f"{show_formula(ratio)} times the right one")
            elif not shared:
                text = f"over the right denominator, your numerator {_show_term(1, pg)} is wrong"
            else:
                text = "over the right denominator, in the numerator, " + ", and ".join(
                    i.text for i in inner
                )
            issues.append(_Issue(text))
        elif ratio == -1:
            issues.append(_Issue(f"{label} has the wrong sign"))
        elif ratio.is_number:
            issues.append(_Issue(
                f"{label} has the wrong factor: yours is {_show_term(key, pg)}, "
                f"{show_formula(ratio)} times the right one"
            ))
        elif not shared:
            issues.append(_Issue(f"{label} has the wrong factor: yours is {_show_term(key, pg)}"))
        else:
            issues.append(_Issue(f"in {label}, " + ", and ".join(i.text for i in inner)))
    return _Report(issues, _units(ref))


def _show_term(key, cofactor) -> str:
    """A term ``cofactor · key`` as the sentences show it: ``(x_i − x_j)·sin(θ_i)``."""
    factored = sp.factor(cofactor)
    coeff, rest = factored.as_coeff_Mul()
    sums = [f for f in sp.Mul.make_args(rest) if f.is_Add]
    if coeff < 0 and len(sums) == 1:  # −2·(y_i − y_j) reads better as 2·(y_j − y_i)
        factored = sp.Mul(-coeff, rest.xreplace({sums[0]: -sums[0]}), evaluate=False)
    text = show_formula(factored)
    if key == 1:
        return text
    if _is_fraction(key):
        return show_formula(factored * key)
    if factored == 1:
        return show_formula(key)
    if factored == -1:
        return "−" + show_formula(key)
    if factored.is_Add:
        text = f"({text})"
    return f"{text}·{show_formula(key)}"


def _compare_monomials(pg, pr) -> list:
    """Differences between two polynomials, monomial by monomial (``-b`` vs ``+b``, …)."""
    dg, dr = sp.expand(pg).as_coefficients_dict(), sp.expand(pr).as_coefficients_dict()
    issues = []
    for mono in sorted(set(dg) | set(dr), key=sp.default_sort_key):
        cg, cr = dg.get(mono, 0), dr.get(mono, 0)
        if cg == cr:
            continue
        what = "a constant term" if mono == 1 else f"a term in {show_formula(mono)}"
        if cr == 0:
            issues.append(_Issue(f"your term {show_formula(cg * mono)} should not be there"))
        elif cg == 0:
            issues.append(_Issue(f"{what} is missing", 1))
        elif cg == -cr:
            issues.append(_Issue(f"your term {show_formula(cg * mono)} has the wrong sign"))
        else:
            issues.append(_Issue(
                f"your term {show_formula(cg * mono)} has the wrong factor ("
                f"{show_formula(sp.nsimplify(cg / cr))} times the right one)"
            ))
    return issues


def _by_structure(g, r) -> list:
    """The reports of the splits that apply: as written, and in the normal form over a common
    denominator (see :func:`_fraction`)."""
    if not _small(g, r):
        return []
    reports = [_compare_terms(_split(g, deep=False), _split(r, deep=False))]
    try:
        ng, dg = _fraction(g)
        nr, dr = _fraction(r)
    except (sp.PolynomialError, TypeError, ValueError):
        return [rep for rep in reports if rep.issues]
    if dr == 1 and dg == 1:
        reports.append(_compare_terms(_split(ng), _split(nr)))
    elif sp.expand(dg - dr) == 0:
        rep = _compare_terms(_split(ng), _split(nr))
        rep.prefix = "over the right denominator, "
        reports.append(rep)
    elif dg == 1:
        same = sp.expand(ng - nr) == 0
        reports.append(_Report([_Issue(
            ("the numerator is right, but " if same else "the right formula is a fraction, and ")
            + "yours has no denominator"
        )]))
    elif dr == 1:
        reports.append(_Report([_Issue("yours is a fraction, and the right formula has no "
                                       "denominator")]))
    elif sp.expand(ng - nr) == 0:
        rep = _compare_terms(_split(dg), _split(dr))
        rep.prefix = "the numerator is right; in the denominator, "
        reports.append(rep)
    return [rep for rep in reports if rep.issues]


def _constant_relation(vals_g, vals_r):
    """How ``got`` relates to the reference at every point, if simply: ``("factor", k)`` for
    got = k·reference, ``("offset", c)`` for got = reference + c, ``("reciprocal", 1)`` for
    got = 1/reference; else None."""
    ratios, offsets, products = [], [], []
    for g, r in zip(vals_g, vals_r):
        if abs(r) > 1e-30:
            ratios.append(g / r)
        offsets.append(g - r)
        products.append(g * r)

    def constant(xs):
        if len(xs) < 3:
            return None
        x0 = xs[0]
        if all(abs(x - x0) <= 1e-20 * max(1, abs(x0)) for x in xs):
            return sp.nsimplify(sp.Float(x0, 15), rational=False, tolerance=1e-12)
        return None

    k = constant(ratios)
    if k is not None and k != 1:
        return ("factor", k)
    c = constant(offsets)
    if c is not None and c != 0:
        return ("offset", c)
    if constant(products) == 1:
        return ("reciprocal", 1)
    return None


def _diagnose(g, r, name, points, vals_g, vals_r, differ, slips):
    """The sentence for a formula that differs from the reference (never the reference)."""
    head = f"{name} differs from the right one"
    for slip, sentence in slips:
        if _same_values(slip, points, vals_g):
            return f"{head}: {sentence}"
    relation = _constant_relation(vals_g, vals_r)
    if relation is not None:
        what, k = relation
        if what == "factor" and k == -1:
            return f"{head}: it has the opposite sign (every term's sign is flipped)."
        if what == "factor" and k == 0:
            return f"{name} is 0 everywhere, and the right formula is not."
        if what == "factor":
            return (f"{head} by a constant factor: it is {show_formula(k)} times the right one "
                    "(a factor 2 or ½, a sign, or a missing constant?).")
        if what == "reciprocal":
            return f"{head}: it is the reciprocal of the right one (upside down)."
        sign = "larger" if k > 0 else "smaller"
        return (f"{head} by a constant: it is {show_formula(abs(k))} {sign} everywhere (a "
                "constant term that should not be there, or one that is missing).")
    parts = []
    extra = sorted(g.free_symbols - r.free_symbols, key=lambda s: s.name)
    missing = sorted(r.free_symbols - g.free_symbols, key=lambda s: s.name)
    if extra:
        names = ", ".join(_display_name(s.name) for s in extra)
        parts.append(f"it depends on {names}, and the right formula does not")
    if missing:
        names = ", ".join(_display_name(s.name) for s in missing)
        parts.append(f"it does not depend on {names}, and the right formula does")
    reports = [rep.sentences() for rep in _by_structure(g, r)]
    if reports:
        issues = min(reports, key=len)  # the explanation with the fewest changes
        shown = issues[:_SHOWN]
        if len(issues) > _SHOWN:
            more = len(issues) - _SHOWN
            shown.append(f"and {more} more difference{'s' if more > 1 else ''}")
        parts += shown
    if not parts:
        n = sum(bool(d) for d in differ)
        parts.append(f"the two disagree at {n} of the {len(differ)} random points checked")
    return f"{head}: " + "; ".join(parts) + "."


def _same_values(slip, points, vals_g) -> bool:
    """Whether the values ``vals_g`` at ``points`` are those of ``slip`` (a known wrong answer)."""
    return all(
        (v := _value(slip, p)) is not None and abs(v[0] - x) <= _RTOL * max(1, abs(x))
        for p, x in zip(points, vals_g)
    )
