"""Friendly feedback for the book's exercises: compare a student's answer with lagolib's reference.

Every ``check_…`` function in :mod:`lagolib.exercises` ends in :func:`verdict`, which prints one
line that starts with ``Exercise <id>`` and says one of three things, records the result (see
:func:`passed`) and returns ``True`` or ``False``:

* ``Exercise 6.2 — correct: …`` — the answer matches the reference (and how closely);
* ``Exercise 6.2 — not yet: …`` — what is wrong and by how much, never the answer (the first
  tier of feedback), and ``Stuck? hint("6.2") gives a hint (N levels …)``: :func:`hint` shows
  further tiers, one per call, each revealing more (a nudge, the equation or lagolib function to
  compare with, then close-to-solution detail; for a prediction, what the check computed) — the
  full solution stays in the chapter's folded cell;
* ``Exercise 6.2 — not attempted yet: …`` — the answer is still the stub's placeholder (``...`` or
  ``None``), or a function that still returns it.

A check never raises on a wrong answer: a student's function that raises is reported as "not yet"
with the exception's type and message.  Only misuse of the check itself (an exercise id that does
not exist) raises.

A check says "correct" only for an answer of the right *kind*: each check declares the kind of
every answer (:func:`check`, with the kinds of :mod:`lagolib.exercises._coerce`), and an answer
of another kind — a complex number, a numeric string, a dict where a shape is asked for, a bool
where a whole number is, a text or object array, None inside a list, a sparse matrix where a
dense array is asked for — is reported "not yet" with a sentence naming the kind asked for.

The comparisons here (:func:`compare_array`, :func:`compare_number`, :func:`compare_int`,
:func:`compare_choice`, :func:`call_student`) return ``None`` when the answer is right and
otherwise the sentence that says what is wrong, so a check reads as a short list of comparisons.
Their sentences are first-tier material: they say where and how much an answer differs (an
array's worst entry and the size of the difference, a number's direction and rough distance, an
integer's direction only — a predicted count would otherwise be given away), never the
reference's values.
"""

from __future__ import annotations

import functools
import inspect

import numpy as np

from lagolib.exercises._coerce import (
    NOT_ATTEMPTED,
    Bool,
    Choice,
    Int,
    Real,
    RealArray,
    StudentFunction,
    WrongKind,
    _Placeholder,
    is_placeholder,
    normalize_choice,
    show,
)

__all__ = [
    "NOT_ATTEMPTED",
    "STRICT_ENV",
    "bookkeeping",
    "check",
    "hint",
    "hints_enabled",
    "set_hints",
    "passed",
    "results",
    "reset",
    "is_placeholder",
    "matches",
    "show",
    "verdict",
    "not_attempted",
    "call_student",
    "compare_array",
    "compare_int",
    "compare_number",
    "compare_choice",
]

WRONG_CHOICE = "which is not the answer."  # the end of compare_choice's sentence for a wrong pick
_RESULTS: dict[str, bool] = {}
_HINTS: dict[str, tuple[str, ...]] = {}  # exercise -> the hint levels of its last "not yet"
_HINT_LEVEL: dict[str, int] = {}  # exercise -> how many of them hint() has shown
_SHOW_HINTS = [True]  # set_hints(False): a copy whose instructor turned hints off
STRICT_ENV = "LAGOLIB_BOOK_STRICT"  # set by the book's tests: bookkeeping() raises


def results() -> dict[str, bool]:
    """The last verdict of every exercise checked in this session, ``{id: True/False}``."""
    return dict(_RESULTS)


def passed(exercise: str) -> bool:
    """Whether the last check of ``exercise`` (e.g. ``"6.2"``) said correct (False if never run)."""
    return _RESULTS.get(str(exercise), False)


def reset() -> None:
    """Forget every recorded verdict and hint."""
    _RESULTS.clear()
    _HINTS.clear()
    _HINT_LEVEL.clear()


def set_hints(on: bool = True) -> None:
    """Turn the hints of every check on or off (a copy written with ``--no-hints`` turns them off).

    With hints off a "not yet" still says what is wrong and by how much (the diagnosis), but it
    offers no hint and :func:`hint` says hints are off.
    """
    if not isinstance(on, (bool, np.bool_)):
        raise TypeError(f"set_hints(on): on must be True or False, got {on!r}")
    _SHOW_HINTS[0] = bool(on)


def hints_enabled() -> bool:
    """Whether the checks offer hints (see :func:`set_hints`)."""
    return _SHOW_HINTS[0]


def _levels(hint) -> tuple[str, ...]:
    levels = (hint,) if isinstance(hint, str) else tuple(hint)
    return tuple(str(h) for h in levels if h)


def verdict(
    exercise: str, problem: str | None, *, correct: str = "", hint: str | tuple = ""
) -> bool:
    """Print the verdict line for ``exercise``, record it, and return whether it is correct.

    ``problem`` is None for a correct answer (then ``correct`` says what matched), otherwise the
    sentence saying what is wrong — the *diagnosis*, the first tier of feedback: what is wrong and
    by how much, never the reference answer's value or the solution's code.  ``hint`` is a string
    or a sequence of strings, the further tiers, each revealing more than the one before; a "not
    yet" line only says that they exist, and :func:`hint` shows them one per call (the full
    solution stays in the chapter's folded solution cell).
    """
    exercise = str(exercise)
    ok = problem is None
    if ok:
        line = f"Exercise {exercise} — correct" + (f": {correct}" if correct else ".")
        _HINTS.pop(exercise, None)
        _HINT_LEVEL.pop(exercise, None)
    elif problem == NOT_ATTEMPTED:
        line = (
            f"Exercise {exercise} — {NOT_ATTEMPTED}: replace the placeholder (`...`) in the cell "
            "above with your answer, run it, then run this check again."
        )
    else:
        line = f"Exercise {exercise} — not yet: {problem}"
        levels = _levels(hint)
        if levels and _SHOW_HINTS[0]:
            if _HINTS.get(exercise) != levels:  # a new diagnosis starts its hints afresh
                _HINTS[exercise] = levels
                _HINT_LEVEL[exercise] = 0
            n = len(levels)
            line += (
                f'\n    Stuck? hint("{exercise}") gives a hint ({n} level{"s" if n > 1 else ""}, '
                "one more per call)."
            )
    print(line)
    _RESULTS[exercise] = ok
    return ok


def hint(exercise: str) -> None:
    """Print the next hint of ``exercise``'s last "not yet", one level more per call.

    The hints follow what the last check found wrong, so run the check first.  After the last
    level it says where the full solution is.

    >>> from lagolib.exercises import hint, reset, verdict
    >>> reset()
    >>> verdict("0.9", "your count is too small.", hint=("count chords", "n - m + 1"))
    Exercise 0.9 — not yet: your count is too small.
        Stuck? hint("0.9") gives a hint (2 levels, one more per call).
    False
    >>> hint("0.9")
    Exercise 0.9 — hint 1 of 2: count chords
    >>> hint("0.9")
    Exercise 0.9 — hint 2 of 2: n - m + 1
    >>> hint("0.9")  # doctest: +ELLIPSIS
    Exercise 0.9 — no more hints: ...
    >>> reset()
    """
    exercise = str(exercise)
    if not _SHOW_HINTS[0]:
        print(f"Exercise {exercise} — hints are off in this copy (your instructor's choice).")
        return
    levels = _HINTS.get(exercise)
    if not levels:
        if _RESULTS.get(exercise):
            print(f"Exercise {exercise} — your last answer was correct: no hint needed.")
        else:
            print(
                f"Exercise {exercise} — no hint yet: run the exercise's check first; the hints "
                "follow what it finds wrong."
            )
        return
    k = _HINT_LEVEL.get(exercise, 0)
    if k >= len(levels):
        print(
            f"Exercise {exercise} — no more hints: the full solution is in the book's folded "
            "cell under the exercise (\"Solution and discussion\" in the full chapter)."
        )
        return
    _HINT_LEVEL[exercise] = k + 1
    print(f"Exercise {exercise} — hint {k + 1} of {len(levels)}: {levels[k]}")


class bookkeeping:  # noqa: N801 - used as ``with bookkeeping():``, like a function
    """The book's own assertions: strict in its tests, quiet for a reader.

    The full chapters assert, in cells hidden from the site and collapsed in JupyterLab, that
    each exercise's solution passes its check and a few facts the text relies on::

        with bookkeeping("6.2"):
            assert passed("6.2")

    Inside ``with bookkeeping(…):`` a failing ``assert`` raises only when the environment
    variable ``LAGOLIB_BOOK_STRICT`` is on (the book's tests set it, so CI still fails on it); for
    a reader who changed a solution it prints one line and JupyterLab's "Run All" goes on.  Other
    exceptions are never swallowed.

    Parameters
    ----------
    exercise : str, optional
        The exercise whose solution the block asserts (named in the reader's line).

    >>> import os
    >>> strict = os.environ.pop("LAGOLIB_BOOK_STRICT", None)
    >>> with bookkeeping("0.8"):
    ...     assert passed("0.8")
    (the book's own check: exercise 0.8 is not solved as in the full book yet; nothing below depends on it.)
    >>> os.environ["LAGOLIB_BOOK_STRICT"] = "1"
    >>> with bookkeeping("0.8"):
    ...     assert passed("0.8")
    Traceback (most recent call last):
    AssertionError
    >>> _ = os.environ.pop("LAGOLIB_BOOK_STRICT") if strict is None else os.environ.update(
    ...     LAGOLIB_BOOK_STRICT=strict)
    """

    def __init__(self, exercise: str | None = None):
        self.exercise = None if exercise is None else str(exercise)

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        import os

        if kind is None or not issubclass(kind, AssertionError):
            return False
        if os.environ.get(STRICT_ENV, "").strip().lower() in ("1", "true", "yes", "on"):
            return False
        if self.exercise is not None:
            what = (
                f"exercise {self.exercise} is not solved as in the full book yet; nothing below "
                "depends on it."
            )
        else:
            text = str(exc) or "a fact the text relies on"
            what = (
                f"{text} does not hold in your run: the text around it describes the book's own "
                "run (did you change a cell above?)."
            )
        print(f"(the book's own check: {what})")
        return True


def check(exercise: str, **answers):
    """Decorator for a chapter's ``check_…`` function of ``exercise`` (e.g. ``"6.2"``).

    ``answers`` declares the kind of each answer the check takes (see
    :mod:`lagolib.exercises._coerce`), e.g. ``@check("2.3", n_blocks=Int(), null_dim=Int())``;
    the other arguments (a graph the chapter built, …) are passed on as they are.  Before the
    body runs, every declared answer that is not a placeholder is read as its kind, so the body
    gets a clean value (a student's function becomes a
    :class:`~lagolib.exercises._coerce.StudentFunction`, whose result :func:`call_student`
    reads); an answer of another kind is reported "not yet" with a sentence naming the kind asked
    for — every such answer at once, before the body computes anything (so a prediction's check
    prints the computed values only for an answer of the right kind).  Placeholders are left to
    the body, which reports them "not attempted yet".

    Whatever the answer is, the check prints a verdict and returns a bool: an exception the
    check's own code meets while reading an odd answer becomes a "not yet" naming what it could
    not read.  The exercise id is kept as the wrapper's ``exercise`` attribute and the declared
    kinds as its ``answers`` attribute.
    """

    def decorate(fn):
        sig = inspect.signature(fn)
        unknown = sorted(set(answers) - set(sig.parameters))
        if unknown:
            raise TypeError(f"check({exercise!r}): {fn.__name__} has no argument {unknown}")

        @functools.wraps(fn)
        def wrapper(*args, **kwargs):
            try:
                try:
                    bound = sig.bind(*args, **kwargs)
                except TypeError:
                    bound = None  # called with the wrong arguments: fn says how, below
                if bound is not None:
                    problems, hint = [], ""
                    for name, kind in answers.items():
                        value = bound.arguments.get(name, ...)
                        if is_placeholder(value):
                            continue
                        try:
                            bound.arguments[name] = kind.prepare(value, name)
                        except WrongKind as exc:
                            problems.append(str(exc))
                            hint = hint or exc.hint
                    if problems:
                        return verdict(exercise, " ".join(problems), hint=hint)
                    args, kwargs = bound.args, bound.kwargs
                result = fn(*args, **kwargs)
            except _Placeholder:
                return verdict(exercise, NOT_ATTEMPTED)
            except WrongKind as exc:
                return verdict(exercise, str(exc), hint=exc.hint)
            except Exception as exc:  # a student's odd answer is feedback, never a traceback
                detail = str(exc)
                detail = detail if len(detail) <= 120 else detail[:117] + "..."
                return verdict(
                    exercise,
                    f"this check could not read your answer ({type(exc).__name__}"
                    + (f": {detail})." if detail else ")."),
                    hint="the exercise's statement says what to give: which names, types and "
                    "shapes.",
                )
            return bool(result)

        wrapper.exercise = str(exercise)
        wrapper.answers = dict(answers)
        return wrapper

    return decorate


def not_attempted(exercise: str) -> bool:
    """Report ``exercise`` as not attempted yet; returns False."""
    return verdict(exercise, NOT_ATTEMPTED)


def call_student(fn, *args, name: str = "your function", **kwargs):
    """Call a student's function; return ``(value, problem)``.

    ``problem`` is None when the call returned something other than a placeholder; otherwise it is
    :data:`NOT_ATTEMPTED` (the function still returns ``...``/``None``, or is itself ``...``) or a
    sentence naming the exception the function raised or why it cannot be called.  For a
    function that :func:`check` handed over (declared ``Function(returns=…)``) the result is
    read as that kind: ``value`` is the clean value, and a result of another kind is a
    ``problem`` naming the kind asked for.
    """
    spec = None
    if isinstance(fn, StudentFunction):
        spec, fn = fn.spec, fn.fn
    if is_placeholder(fn):
        return None, NOT_ATTEMPTED
    if not callable(fn):
        return None, f"{name} should be a function (def ...), but it is a {type(fn).__name__}."
    try:
        value = fn(*args, **kwargs)
    except Exception as exc:  # a student's bug is feedback, never a traceback
        return None, f"{name} raised {type(exc).__name__}: {exc}"
    if is_placeholder(value):
        return None, NOT_ATTEMPTED
    if spec is not None:
        return spec.read(value, name, args, kwargs)
    return value, None


def _never_raises(compare):
    """A comparison that returns a sentence instead of raising, whatever the answer is."""

    @functools.wraps(compare)
    def wrapper(got, *args, **kwargs):
        try:
            return compare(got, *args, **kwargs)
        except Exception as exc:  # an answer numpy cannot read: feedback, not a traceback
            name = kwargs.get("name", "your answer")
            return (
                f"{name} cannot be compared with the reference: it is a {type(got).__name__} "
                f"({type(exc).__name__}: {exc})."
            )

    return wrapper


def _entry(k) -> str:
    return "(" + ", ".join(str(int(i)) for i in k) + ")" if len(k) != 1 else f"{int(k[0])}"


@_never_raises
def compare_array(
    got,
    expected,
    *,
    name: str = "your answer",
    rtol: float = 1e-7,
    atol: float = 1e-9,
    angles: bool = False,
) -> str | None:
    """None if ``got`` equals ``expected`` within ``atol + rtol·|expected|``, else what differs.

    ``got`` is read as an array of real numbers (:class:`~lagolib.exercises._coerce.RealArray`:
    complex, text, bool, object, sparse or masked answers, None inside a list, a ragged list, NaN
    are each named as such).  Diagnoses the usual slips: a placeholder, a wrong shape (or a
    transpose), a flipped sign, a transpose of a square matrix, and — with ``angles=True`` —
    angles that differ by a multiple of 2π (compared wrapped, and reported as a missing wrap).

    Otherwise it says how many entries differ, where the worst one is and by how much (two
    significant digits) — never the reference's values: this is the first tier of feedback
    (see :func:`verdict`).

    >>> print(compare_array([[1.0, 2.0], [3.0, 0.0]], [[1.0, 2.0], [3.0, 4.25]], name="H"))
    H differs from the reference in 1 of its 4 entries: at index (1, 1) yours is 0 and the reference's is not.
    >>> print(compare_array([1.0, 2.5, 3.0], [1.0, 2.0, 3.0], name="v"))
    v differs from the reference in 1 of its 3 entries: at index 1 yours is larger, by 0.5.
    """
    if is_placeholder(got):
        return NOT_ATTEMPTED
    e = np.asarray(expected, dtype=float)
    try:
        g = RealArray(e.shape).coerce(got, name)
    except WrongKind as exc:
        return str(exc)
    if g.shape != e.shape:
        if g.size == e.size and g.T.shape == e.shape:
            return f"{name} has shape {g.shape}, expected {e.shape}: transposed?"
        return f"{name} has shape {g.shape}, expected {e.shape}."
    diff = g - e
    if angles:
        wrapped = (diff + np.pi) % (2 * np.pi) - np.pi
        if np.all(np.abs(wrapped) <= atol + rtol * np.abs(e)) and np.any(np.abs(diff) > np.pi):
            turns = int(np.round(np.abs(diff).max() / (2 * np.pi)))
            return (
                f"{name} differs from the reference by multiples of 2π (up to {turns} "
                f"turn{'s' if turns > 1 else ''}): wrap the angles into (-π, π] "
                "(lagolib.se2.wrap_angle)."
            )
        diff = wrapped
    tol = atol + rtol * np.abs(e)
    if np.all(np.abs(diff) <= tol):
        return None
    if e.size > 1 and np.any(e != 0) and np.all(np.abs(g + e) <= tol):
        return f"{name} has the opposite sign of the reference."
    if g.ndim == 2 and g.shape[0] == g.shape[1] and np.all(np.abs(g.T - e) <= tol):
        return f"{name} is the transpose of the reference."
    bad = np.abs(diff) > tol
    if diff.ndim == 0:
        k, where, count = (), "", ""
    else:
        k = np.unravel_index(int(np.argmax(np.abs(diff) - tol)), diff.shape)
        where = f"at index {_entry(k)} "
        count = f" in {int(bad.sum())} of its {e.size} entries"
    if g[k] == 0 and e[k] != 0:
        detail = "yours is 0 and the reference's is not"
    elif g[k] * e[k] < 0:
        detail = "yours has the opposite sign"
    else:
        bigger = "larger" if abs(g[k]) > abs(e[k]) else "smaller"
        detail = f"yours is {bigger}, by {abs(diff[k]):.2g}"
        if e[k] != 0 and abs(diff[k]) < 1e-3 * abs(e[k]):
            detail += " (less than 0.1 % of the entry: rounding, or a constant slightly off?)"
    return f"{name} differs from the reference{count}: {where}{detail}."


def _how_far(got: float, expected: float, tol: float) -> str:
    """How far ``got`` is from ``expected``, in words that do not give ``expected`` away."""
    d = got - expected
    side = "too large" if d > 0 else "too small"
    if abs(d) <= 1.5 * tol:
        return f"{side}, though close: just outside the check's tolerance"
    if expected == 0:
        return f"{side} (the check allows ± {tol:.2g})"
    if got * expected < 0:
        return "of the wrong sign"
    if got == 0:
        return "0, and the reference is not"
    ratio = got / expected
    if ratio >= 10:
        return f"{side}: more than 10 times the reference (units? a factor?)"
    if ratio <= 0.1:
        return f"{side}: less than a tenth of the reference (units? a factor?)"
    if ratio >= 1.5:
        return f"{side}: more than 1.5 times the reference"
    if ratio <= 2 / 3:
        return f"{side}: less than two thirds of the reference"
    if abs(ratio - 1) > 0.1:
        return f"{side}, by 10 to 50 %"
    return f"{side}, by less than 10 %"


@_never_raises
def compare_number(
    got, expected: float, *, name: str = "your answer", rtol: float = 1e-7, atol: float = 1e-9
) -> str | None:
    """None if the number ``got`` equals ``expected`` within the tolerance, else what differs.

    ``got`` is read as one real number (:class:`~lagolib.exercises._coerce.Real`): a bool, a
    string (also ``"3.0"``), a complex number, a list or an array is named as such; NaN and ±inf
    are reported as such.  A wrong number is told whether it is too large or too small, and
    roughly by how much (a few per cent, a factor, an order of magnitude) — never the
    reference's value.

    >>> print(compare_number(7.0, 3.0, name="ratio"))
    ratio = 7 is too large: more than 1.5 times the reference.
    """
    if is_placeholder(got):
        return NOT_ATTEMPTED
    try:
        g = Real(finite=False).coerce(got, name)
    except WrongKind as exc:
        return str(exc)
    if not np.isfinite(g):
        return f"{name} is {g}: it should be one real number, a finite one."
    tol = atol + rtol * abs(expected)
    if abs(g - expected) <= tol:
        return None
    return f"{name} = {g:.6g} is {_how_far(g, float(expected), tol)}."


@_never_raises
def compare_int(got, expected: int, *, name: str = "your answer") -> str | None:
    """None if ``got`` is the integer ``expected``, else whether it is too large or too small.

    ``got`` is read as a whole number (:class:`~lagolib.exercises._coerce.Int`): ``5.0`` is 5;
    a bool, a string, a complex number or ``5.5`` is named as such.  How far it is off is not
    said: for a predicted count that would give the count away.

    >>> print(compare_int(4, 5, name="n_chords"))
    n_chords = 4 is too small.
    """
    if is_placeholder(got):
        return NOT_ATTEMPTED
    try:
        got = Int().coerce(got, name)
    except WrongKind as exc:
        return str(exc)
    if got == int(expected):
        return None
    return f"{name} = {got} is too {'large' if got > expected else 'small'}."


@_never_raises
def compare_choice(got, expected, choices, *, name: str = "your answer") -> str | None:
    """None if ``got`` is the choice ``expected``.

    Choices that are all True/False read ``got`` as :class:`~lagolib.exercises._coerce.Bool`
    (``1`` is not ``True`` here), choices that are all strings as
    :class:`~lagolib.exercises._coerce.Choice` (bytes, a list, a number are named as such).
    Strings are compared ignoring case, repeated spaces, and the difference between a hyphen,
    the dashes a rendered page shows (‐ ‑ ‒ – — −) and a space: ``"Gauss–Newton"`` as printed in a
    chapter is the choice ``"Gauss-Newton"``.
    """
    if is_placeholder(got):
        return NOT_ATTEMPTED
    if all(isinstance(c, (bool, np.bool_)) for c in choices):
        kind = Bool()
    elif all(isinstance(c, str) for c in choices):
        kind = Choice(choices)
    else:
        kind = None
    if kind is not None:
        try:
            got = kind.coerce(got, name)
        except WrongKind as exc:
            return str(exc)

    def norm(x):
        # "Gauss–Newton" (en dash, as the chapters print it), "gauss-newton", " Gauss  Newton":
        # the same choice; only hyphens, dashes, spaces and case are normalized
        return normalize_choice(x) if isinstance(x, str) else x

    def same(a, b):
        # a numpy array or an odd object compares elementwise or raises: it is not a choice
        try:
            return bool(norm(a) == norm(b))
        except (TypeError, ValueError):
            return False

    if not any(same(got, c) for c in choices):
        return f"{name} should be one of {list(choices)}, got {show(got)}."
    if same(got, expected):
        return None
    return f"{name} is {show(got)}, {WRONG_CHOICE}"


def matches(got, expected, tol: float = 1e-9) -> bool:
    """Whether ``got`` is the array ``expected`` to ``tol`` (relative to its largest entry).

    For recognizing a particular wrong answer (a transpose, a missing term); False for anything
    that is not an array of real numbers of the same shape.
    """
    try:
        g = RealArray().coerce(got)
        e = np.asarray(expected, dtype=float)
        return g.shape == e.shape and bool(
            np.all(np.abs(g - e) <= tol * max(1.0, float(np.abs(e).max(initial=0.0))))
        )
    except (WrongKind, TypeError, ValueError):
        return False
