"""The exercises' feedback never raises on an answer, whatever the answer is, and reads every
answer as the kind the exercise asks for.

Every comparison of :mod:`lagolib.exercises` is given the answers a student can produce — the
placeholder, numbers of the wrong kind, strings, arrays, nested lists, NaN, objects whose ``==`` or
``repr`` raises — and must return a sentence (or None when right), never raise.  The answer kinds
(``Real``, ``Int``, ``Bool``, ``Choice``, ``Shape``, ``RealArray``, ``Tuple``) accept every form of
the right kind and refuse the others with a sentence naming the kind asked for.
"""

import decimal
import fractions
import re

import numpy as np
import pytest
import scipy.sparse as sp
import sympy

from lagolib.exercises import (
    NOT_ATTEMPTED,
    Bool,
    Choice,
    Function,
    Int,
    Real,
    RealArray,
    Shape,
    Tuple,
    WrongKind,
    call_student,
    check,
    compare_array,
    compare_choice,
    compare_int,
    compare_number,
    passed,
    verdict,
)
from lagolib.exercises._feedback import matches


class Weird:
    def __eq__(self, other):
        raise RuntimeError("no comparing me")

    def __repr__(self):
        raise RuntimeError("no printing me")

    __hash__ = None


ANSWERS = [
    None,
    ...,
    True,
    3,
    3.0,
    np.float64(3.0),
    np.int64(3),
    1 + 2j,
    float("nan"),
    float("inf"),
    "3",
    "abc",
    b"3",
    [1, 2],
    [[1, 2], [3]],
    (1, "a"),
    {"a": 1},
    np.array([1.0, 2.0]),
    np.eye(3),
    np.array(["a"]),
    Weird(),
    object(),
]
IDS = [type(a).__name__ + str(k) for k, a in enumerate(ANSWERS)]


@pytest.mark.parametrize("answer", ANSWERS, ids=IDS)
def test_comparisons_never_raise(answer):
    for result in (
        compare_array(answer, np.eye(3)),
        compare_array(answer, [0.5, -1.0], angles=True),
        compare_number(answer, 3.0),
        compare_int(answer, 3),
        compare_choice(answer, "bfs", ["bfs", "odometric"]),
        compare_choice(answer, True, [True, False]),
    ):
        assert result is None or isinstance(result, str)


@pytest.mark.parametrize("answer", [None, ...], ids=["None", "Ellipsis"])
def test_placeholders_are_not_attempted(answer):
    assert compare_array(answer, np.eye(3)) == NOT_ATTEMPTED
    assert compare_number(answer, 1.0) == NOT_ATTEMPTED
    assert compare_int(answer, 1) == NOT_ATTEMPTED
    assert compare_choice(answer, "a", ["a", "b"]) == NOT_ATTEMPTED
    assert call_student(answer)[1] == NOT_ATTEMPTED
    assert call_student(lambda: answer)[1] == NOT_ATTEMPTED


def test_the_usual_slips_are_named():
    e = np.array([[1.0, 2.0], [3.0, 4.0]])
    assert "transpose" in compare_array(e.T, e)
    assert "opposite sign" in compare_array(-e, e)
    assert "shape (3,)" in compare_array([1, 2, 3], [1, 2])
    assert "multiples of 2π" in compare_array([0.1 + 2 * np.pi], [0.1], angles=True)
    assert compare_array([0.1 + 2 * np.pi], [0.1 + 1e-12], angles=False) is not None
    assert "non-finite" in compare_array([np.nan, 1.0], [0.0, 1.0])
    assert compare_int(4, 5) == "your answer = 4 is too small."
    assert compare_int(7, 5) == "your answer = 7 is too large."
    assert compare_int(5.0, 5) is None
    assert "whole number" in compare_int(5.5, 5)
    assert "a string" in compare_array("1.0", [1.0])
    assert "string" in compare_number("3", 3.0)
    assert compare_number(3.0 + 1e-12, 3.0) is None
    assert "one of" in compare_choice(np.array([1, 2]), "a", ["a", "b"])
    assert compare_choice(" BFS ", "bfs", ["bfs", "odometric"]) is None


def test_a_raising_function_is_feedback():
    def broken(x):
        return x / 0

    value, problem = call_student(broken, 1.0)
    assert value is None and problem.startswith("your function raised ZeroDivisionError")
    assert "should be a function" in call_student(42)[1]


def test_verdict_prints_records_and_returns(capsys):
    assert verdict("99.1", None, correct="matches to 1e-12") is True
    assert capsys.readouterr().out == "Exercise 99.1 — correct: matches to 1e-12\n"
    assert passed("99.1")
    assert verdict("99.1", "it is 3: too small.", hint="count again") is False
    assert capsys.readouterr().out == (
        "Exercise 99.1 — not yet: it is 3: too small.\n"
        '    Stuck? hint("99.1") gives a hint (1 level, one more per call).\n'
    )
    assert not passed("99.1")
    assert not passed("never.checked")


# --------------------------------------------------------------------------- the answer kinds
ACCEPTED = [
    (Real(), 0.25, 0.25),
    (Real(), np.float32(0.5), 0.5),
    (Real(), np.int64(3), 3.0),
    (Real(), np.array(2.5), 2.5),
    (Real(), np.array([2.5]), 2.5),  # one number in an array: np.mean(x, keepdims=True), …
    (Real(), np.array([[2.5]]), 2.5),
    (Real(), fractions.Fraction(1, 4), 0.25),
    (Real(), decimal.Decimal("0.25"), 0.25),
    (Real(), sympy.Rational(1, 4), 0.25),
    (Real(), sympy.sqrt(2), float(np.sqrt(2))),
    (Int(), 7, 7),
    (Int(), 7.0, 7),
    (Int(), np.uint8(7), 7),
    (Int(), np.array(7), 7),
    (Int(), np.array([7]), 7),
    (Int(), sympy.Integer(7), 7),
    (Int(), 10**30, 10**30),
    (Bool(), True, True),
    (Bool(), np.False_, False),
    (Bool(), np.array(True), True),
    (Bool(), np.array([True]), True),
    (Bool(), "yes", True),  # a yes/no question
    (Bool(), " No ", False),
    (Choice(["yes", "no"]), True, "yes"),
    (Choice(["yes", "no"]), np.False_, "no"),
    (Choice(["bfs", "odometric"]), np.str_("bfs"), "bfs"),
    (Choice(["bfs", "odometric"]), np.array("bfs"), "bfs"),
    (Choice(["Gauss-Newton", "LAGO"]), " gauss–newton ", "Gauss-Newton"),  # the choice itself
    (Choice(["bfs", "odometric"]), "shortest", "shortest"),  # a string: compare_choice says no
    (Shape(2), [11, 19], (11, 19)),
    (Shape(2), np.array([11, 19]), (11, 19)),
    (Shape(2), (np.int64(11), 19.0), (11, 19)),
]


@pytest.mark.parametrize(
    "kind, answer, clean", ACCEPTED, ids=[repr(a)[:30] for _, a, _ in ACCEPTED]
)
def test_kinds_accept_every_form_of_the_right_kind(kind, answer, clean):
    got = kind.coerce(answer, "x")
    assert got == clean and type(got) is type(clean)


REFUSED = [
    (Real(), "0.5", "x should be one real number, got '0.5' (a string: write the number"),
    (Real(), np.str_("0.5"), "got '0.5' (a string"),
    (Real(), 0.5 + 1000j, "got (0.5+1000j) (a complex number)"),
    (Real(), 0.5 + 0j, "got (0.5+0j) (a complex number)"),
    (Real(), np.complex64(1), "(a complex number)"),
    (Real(), sympy.I, "(a complex sympy number)"),
    (Real(), sympy.Symbol("t"), "the sympy expression t, not a number"),
    (Real(), True, "got True (a bool)"),
    (Real(), np.True_, "got True (a bool)"),
    (Real(), [0.5], "got a list of length 1"),
    (Real(), np.array([0.5, 1.0]), "got an array of dtype float64 (shape (2,))"),
    (Real(), np.array(0.5, dtype=object), "an array of dtype object"),
    (Real(), {"x": 0.5}, "got a dict"),
    (Real(), float("nan"), "got nan, which is not finite"),
    (Real(), -np.inf, "got -inf, which is not finite"),
    (Int(), True, "x should be a whole number, got True (a bool)"),
    (Int(), 5.5, "x should be a whole number, got 5.5"),
    (Int(), "5", "got '5' (a string"),
    (Int(), 5 + 0j, "got (5+0j) (a complex number)"),
    (Int(), float("inf"), "x should be a whole number, got inf"),
    (Bool(), 1, "x should be True or False, got 1 (an int)"),
    (Bool(), 0.0, "x should be True or False, got 0 (a float)"),
    (Bool(), "True", "got 'True' (a string): True and False are written without quotes"),
    (Bool(), "maybe", "got 'maybe' (a string)"),
    (Bool(), np.array([True, False]), "got an array of True/False values"),
    (Int(count_of="worlds"), True, "the question is how many worlds, not whether"),
    (Choice(["bfs"]), b"bfs", "x should be one of ['bfs'] (a string), got b'bfs' (bytes"),
    (Choice(["bfs"]), ["bfs"], "got a list of length 1"),
    (Choice(["bfs"]), 1, "got 1 (an int)"),
    (Shape(2), {11: 0, 19: 1}, "x should be a shape, a tuple of 2 whole numbers, got a dict"),
    (Shape(2), {11, 19}, "which has no order"),
    (Shape(2), "(11, 19)", "got '(11, 19)' (a string)"),
    (Shape(2), (True, 19), "whose item 0 is True (a bool)"),
    (Shape(2), (11.5, 19), "whose item 0 is 11.5"),
    (Shape(2), (11, 19, 1), "got a tuple of length 3"),
    (Shape(2), (-11, 19), "with the negative size -11"),
    (Shape(2), np.array([11, 19], dtype=complex), "an array of complex numbers"),
]


@pytest.mark.parametrize("kind, answer, message", REFUSED, ids=[m[:30] for *_, m in REFUSED])
def test_kinds_refuse_other_kinds_naming_the_kind(kind, answer, message):
    with pytest.raises(WrongKind) as info:
        kind.coerce(answer, "x")
    text = str(info.value)
    assert text.startswith(f"x should be {kind.what}, got ") and message in text
    assert info.value.hint


ARRAYS_REFUSED = [
    (np.eye(2) + 1000j, "an array of complex numbers (dtype complex128, shape (2, 2))"),
    (np.eye(2).astype(complex), "all with imaginary part 0: keep the real part (.real)"),
    (np.eye(2).astype(str), "an array of text (dtype <U32, shape (2, 2))"),
    (np.eye(2).astype(bool), "an array of True/False values (dtype bool, shape (2, 2))"),
    (np.eye(2).astype(object), "an array of dtype object (shape (2, 2))"),
    ([[1.0, None], [0.0, 1.0]], "a list holding None at index [0][1]"),
    ([[1.0, "0"], [0.0, 1.0]], "a list holding '0' (a string"),
    ([(1.0, 0.0), (0.0, True)], "a list holding True (a bool) at index [1][1]"),
    ([[1.0, 0.0], [0.0]], "a ragged nested list (its rows have different lengths)"),
    ([np.zeros(2), np.zeros(2, dtype=complex)], "a list holding an array of complex numbers"),
    (np.ma.masked_array(np.eye(2), mask=np.eye(2)), "a masked array with 2 masked entries"),
    (sp.csr_matrix(np.eye(2)), "a csr_matrix (a scipy.sparse matrix) of shape (2, 2)"),
    (sympy.Matrix([[1, sympy.I], [0, 1]]), "a sympy matrix holding I (a complex sympy number)"),
    (np.array([[1.0, np.nan], [0.0, 1.0]]), "a non-finite value (nan) at index (0, 1)"),
    ({0: 1.0, 1: 0.0}, "a dict"),
    ("[[1, 0], [0, 1]]", "(a string)"),
    (None, "None"),
]


@pytest.mark.parametrize("answer, message", ARRAYS_REFUSED, ids=[m[:30] for _, m in ARRAYS_REFUSED])
def test_real_arrays_refuse_other_kinds_naming_the_kind(answer, message):
    with pytest.raises(WrongKind) as info:
        RealArray((2, 2)).coerce(answer, "x")
    assert str(info.value).startswith("x should be an array of real numbers of shape (2, 2), got ")
    assert message in str(info.value)


def test_real_arrays_accept_every_form_of_the_right_kind():
    e = np.eye(2)
    for answer in (
        e,
        e.tolist(),
        ((1, 0), (0, 1)),
        e.astype(np.float32),
        e.astype(int),
        [np.array([1, 0]), [0.0, np.float64(1)]],
        np.ma.masked_array(e),
        sympy.Matrix([[1, 0], [0, 1]]),
        [[fractions.Fraction(1), 0], [0, decimal.Decimal(1)]],
    ):
        got = RealArray((2, 2)).coerce(answer, "x")
        assert got.dtype == np.float64 and np.array_equal(got, e), repr(answer)
    # a sparse matrix where the exercise allows it; a sparse row where a vector is asked for
    assert np.array_equal(RealArray((2, 2), sparse=True).coerce(sp.csr_matrix(e)), e)
    row = RealArray(("m",), sparse=True).coerce(sp.csr_matrix([[1.0, 0.0, -1.0]]))
    assert row.tolist() == [1.0, 0.0, -1.0]


def test_a_returned_tuple_is_read_item_by_item():
    pair = Tuple(RealArray((2,)), Real(), names=("t", "s"), what="a pair (t, s)")
    t, s = pair.returned([np.zeros(2), np.float64(1.5)], "f")
    assert t.tolist() == [0.0, 0.0] and s == 1.5
    assert pair.returned(np.array([[1.0, 2.0], [3.0, 4.0]])[[0]].tolist() + [2], "f")[1] == 2.0
    for answer, message in [
        ((np.zeros(2),), "f should return a pair (t, s); it returned a tuple of length 1."),
        ({"t": 0, "s": 1}, "f should return a pair (t, s); it returned a dict"),
        ((np.zeros(2), 1 + 2j), "s should be one real number, got (1+2j) (a complex number)."),
        ((["0", 0], 1.0), "t should be an array of real numbers of shape (2,), got a list"),
    ]:
        with pytest.raises(WrongKind, match=re.escape(message)):
            pair.returned(answer, "f")


def test_check_reads_the_declared_answers_and_names_every_wrong_one(capsys):
    seen = []

    @check("99.7", n=Int(), ok=Bool(), f=Function(RealArray((2,))))
    def check_demo(n, ok, f, context="given"):
        seen.append((n, ok, context))
        value, problem = call_student(f, name="f")
        return verdict("99.7", problem, correct="fine")

    assert check_demo.answers.keys() == {"n", "ok", "f"}
    assert check_demo(np.int64(3), np.True_, lambda: [1, 2]) is True
    assert seen == [(3, True, "given")] and type(seen[0][0]) is int
    assert check_demo(3, True, lambda: [1, 2 + 0j]) is False
    assert "f should return an array of real numbers of shape (2,); it returned a list " in (
        capsys.readouterr().out
    )
    assert check_demo("3", 1, lambda: [1, 2]) is False
    out = capsys.readouterr().out
    assert out.startswith("Exercise 99.7 — not yet: n should be a whole number, got '3'")
    assert "ok should be True or False, got 1 (an int)." in out and len(seen) == 2
    assert check_demo(..., None, lambda: ...) is False  # placeholders are left to the body
    assert NOT_ATTEMPTED in capsys.readouterr().out and seen[-1] == (..., None, "given")
    with pytest.raises(TypeError, match="has no argument"):
        check("99.8", missing=Int())(lambda n: n)


def test_comparisons_name_the_kind_they_read():
    assert "an array of complex numbers" in compare_array(np.eye(3) + 1000j, np.eye(3))
    assert "an array of text" in compare_array(np.array(["1.0"]), [1.0])
    assert "got True (a bool)" in compare_number(True, 1.0)
    assert "got (3+0j) (a complex number)" in compare_int(3 + 0j, 3)
    assert "should be True or False, got 1 (an int)" in compare_choice(1, True, [True, False])
    assert "(a string), got b'bfs'" in compare_choice(b"bfs", "bfs", ["bfs", "odometric"])
    assert not matches(np.array(["1.0"]), [1.0]) and not matches([1.0 + 1j], [1.0])
