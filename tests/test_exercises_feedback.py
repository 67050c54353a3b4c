"""The exercises' feedback never raises on an answer, whatever the answer is.

Every comparison of :mod:`lagolib.exercises` is given the answers a student can produce — the
placeholder, numbers of the wrong kind, strings, arrays, nested lists, NaN, objects whose ``==`` or
``repr`` raises — and must return a sentence (or None when right), never raise.
"""

import numpy as np
import pytest

from lagolib.exercises import (
    NOT_ATTEMPTED,
    call_student,
    compare_array,
    compare_choice,
    compare_int,
    compare_number,
    passed,
    verdict,
)


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
    assert "1 fewer" in compare_int(4, 5)
    assert "2 more" in compare_int(7, 5)
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
    assert verdict("99.1", "it is 3; the reference is 4.", hint="count again") is False
    assert capsys.readouterr().out == (
        "Exercise 99.1 — not yet: it is 3; the reference is 4.\n    Hint: count again\n"
    )
    assert not passed("99.1")
    assert not passed("never.checked")
