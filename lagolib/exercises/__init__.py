"""Checks for the book's exercises, one module per chapter (``lagolib.exercises.ch06``, …).

A chapter imports its module, e.g. ``from lagolib.exercises import ch06``, and each exercise cell is
followed by a check such as ``ch06.check_phase1(phase1)``.  A check compares the answer with
lagolib's own implementation, prints one line that starts with ``Exercise <id>`` — *correct*, *not
yet* (what is wrong and by how much, never the answer; ``hint(id)`` gives hints, one level per
call) or *not attempted yet* (the stub is still as given) —
and returns ``True`` or ``False``; it never raises on a wrong answer.  A check says correct only for
an answer of the right kind: each declares the kind of its answers (``Int()``, ``Real()``,
``Bool()``, ``Choice(...)``, ``Shape(2)``, ``RealArray(...)``, ``Function(returns=...)``, see
:mod:`lagolib.exercises._coerce`), and an answer of another kind (a complex number, a numeric
string, a bool where a whole number is asked for, …) is "not yet" with a sentence naming the kind
asked for.  :func:`passed` tells whether an exercise's last check said correct (the full notebooks
assert it in a cell hidden from the rendered book and dropped from the student copies).

The conventions that tie a chapter's exercise, solution, check and student stub together are in
:mod:`lagolib.book`, which also writes the student copies.

>>> from lagolib.exercises import compare_int, verdict
>>> verdict("0.1", compare_int(4, 5, name="the number of chords"), hint="count the chords")
Exercise 0.1 — not yet: the number of chords = 4 is too small.
    Stuck? hint("0.1") gives a hint (1 level, one more per call).
False
>>> hint("0.1")
Exercise 0.1 — hint 1 of 1: count the chords
>>> verdict("0.1", compare_int(..., 5))  # doctest: +ELLIPSIS
Exercise 0.1 — not attempted yet: replace the placeholder (`...`) in the cell above with ...
False
>>> passed("0.1")
False
"""

import importlib

from lagolib.exercises._coerce import (
    Bool,
    Choice,
    Function,
    Int,
    Real,
    RealArray,
    Shape,
    Tuple,
    WrongKind,
    as_bool,
    as_int,
    as_real,
    as_real_array,
    as_shape,
    as_text,
)
from lagolib.exercises._feedback import (
    NOT_ATTEMPTED,
    STRICT_ENV,
    bookkeeping,
    call_student,
    check,
    compare_array,
    compare_choice,
    compare_int,
    compare_number,
    hint,
    hints_enabled,
    is_placeholder,
    not_attempted,
    passed,
    reset,
    results,
    set_hints,
    verdict,
)

CHAPTERS = ("ch00", "ch01", "ch02", "ch03", "ch04", "ch05", "ch06", "ch07", "ch08", "ch09", "ch10", "ch11")

__all__ = [
    "CHAPTERS",
    "NOT_ATTEMPTED",
    "STRICT_ENV",
    "Bool",
    "Choice",
    "Function",
    "Int",
    "Real",
    "RealArray",
    "Shape",
    "Tuple",
    "WrongKind",
    "as_bool",
    "as_int",
    "as_real",
    "as_real_array",
    "as_shape",
    "as_text",
    "bookkeeping",
    "call_student",
    "check",
    "compare_array",
    "compare_choice",
    "compare_int",
    "compare_number",
    "hint",
    "hints_enabled",
    "is_placeholder",
    "not_attempted",
    "passed",
    "reset",
    "results",
    "set_hints",
    "verdict",
    *CHAPTERS,
]


def __getattr__(name):
    # chapter modules load on first use (importing lagolib.exercises stays light)
    if name in CHAPTERS:
        module = importlib.import_module(f"{__name__}.{name}")
        globals()[name] = module
        return module
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
