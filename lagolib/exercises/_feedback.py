"""Friendly feedback for the book's exercises: compare a student's answer with lagolib's reference.

Every ``check_…`` function in :mod:`lagolib.exercises` ends in :func:`verdict`, which prints one
line that starts with ``Exercise <id>`` and says one of three things, records the result (see
:func:`passed`) and returns ``True`` or ``False``:

* ``Exercise 6.2 — correct: …`` — the answer matches the reference (and how closely);
* ``Exercise 6.2 — not yet: …`` — what is wrong, by how much, and a hint;
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

The comparisons here (:func:`compare_array`, :func:`compare_int`, :func:`compare_choice`,
:func:`call_student`) return ``None`` when the answer is right and otherwise the sentence that says
what is wrong, so a check reads as a short list of comparisons.
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
    "check",
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


def results() -> dict[str, bool]:
    """The last verdict of every exercise checked in this session, ``{id: True/False}``."""
    return dict(_RESULTS)


def passed(exercise: str) -> bool:
    """Whether the last check of ``exercise`` (e.g. ``"6.2"``) said correct (False if never run)."""
    return _RESULTS.get(str(exercise), False)


def reset() -> None:
    """Forget every recorded verdict."""
    _RESULTS.clear()


def verdict(exercise: str, problem: str | None, *, correct: str = "", hint: str = "") -> bool:
    """Print the verdict line for ``exercise``, record it, and return whether it is correct.

    ``problem`` is None for a correct answer (then ``correct`` says what matched), otherwise the
    sentence saying what is wrong; ``hint`` is appended to a wrong answer's line.
    """
    exercise = str(exercise)
    ok = problem is None
    if ok:
        line = f"Exercise {exercise} — correct" + (f": {correct}" if correct else ".")
    elif problem == NOT_ATTEMPTED:
        line = (
            f"Exercise {exercise} — {NOT_ATTEMPTED}: replace the placeholder (`...`) in the cell "
            "above with your answer, run it, then run this check again."
        )
    else:
        line = f"Exercise {exercise} — not yet: {problem}"
        if hint:
            line += f"\n    Hint: {hint}"
    print(line)
    _RESULTS[exercise] = ok
    return ok


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


def _fmt(x) -> str:
    return np.array2string(np.asarray(x), precision=6, suppress_small=True, max_line_width=90)


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
            return (
                f"{name} differs from the reference by multiples of 2π (up to "
                f"{np.abs(diff).max():.4g} rad): wrap the angles into (-π, π] (lagolib.se2.wrap_angle)."
            )
        diff = wrapped
    tol = atol + rtol * np.abs(e)
    if np.all(np.abs(diff) <= tol):
        return None
    if e.size > 1 and np.any(e != 0) and np.all(np.abs(g + e) <= tol):
        return f"{name} has the opposite sign of the reference."
    if g.ndim == 2 and g.shape[0] == g.shape[1] and np.all(np.abs(g.T - e) <= tol):
        return f"{name} is the transpose of the reference."
    k = np.unravel_index(int(np.argmax(np.abs(diff) - tol)), diff.shape) if diff.ndim else ()
    where = f" at index {tuple(int(i) for i in k)}" if diff.ndim else ""
    rel = np.abs(diff[k]) / max(np.abs(e[k]), 1e-300)
    msg = (
        f"{name} differs from the reference by up to {np.abs(diff).max():.4g}{where} "
        f"(yours {g[k]:.6g}, expected {e[k]:.6g}"
        + (f", {rel:.2g} relative" if e[k] != 0 else "")
        + ")."
    )
    if e.size <= 12:
        msg += f"\n    yours:    {_fmt(g)}\n    expected: {_fmt(e)}"
    return msg


@_never_raises
def compare_number(
    got, expected: float, *, name: str = "your answer", rtol: float = 1e-7, atol: float = 1e-9
) -> str | None:
    """None if the number ``got`` equals ``expected`` within the tolerance, else what differs.

    ``got`` is read as one real number (:class:`~lagolib.exercises._coerce.Real`): a bool, a
    string (also ``"3.0"``), a complex number, a list or an array is named as such; NaN and ±inf
    are reported as such.
    """
    if is_placeholder(got):
        return NOT_ATTEMPTED
    try:
        g = Real(finite=False).coerce(got, name)
    except WrongKind as exc:
        return str(exc)
    if not np.isfinite(g):
        return f"{name} is {g}: it should be one real number, a finite one."
    if abs(g - expected) <= atol + rtol * abs(expected):
        return None
    rel = f" ({abs(g - expected) / abs(expected):.2g} relative)" if expected else ""
    return f"{name} is {g:.6g}; the reference is {expected:.6g}{rel}."


@_never_raises
def compare_int(got, expected: int, *, name: str = "your answer") -> str | None:
    """None if ``got`` is the integer ``expected``, else what differs (too many / too few).

    ``got`` is read as a whole number (:class:`~lagolib.exercises._coerce.Int`): ``5.0`` is 5;
    a bool, a string, a complex number or ``5.5`` is named as such.
    """
    if is_placeholder(got):
        return NOT_ATTEMPTED
    try:
        got = Int().coerce(got, name)
    except WrongKind as exc:
        return str(exc)
    if got == int(expected):
        return None
    more = "more" if got > expected else "fewer"
    return f"{name} is {got}: that is {abs(got - int(expected))} {more} than the reference."


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
