"""The kinds of answer the exercises ask for, and reading an answer as its kind.

Every check of :mod:`lagolib.exercises` declares the kind of each answer it takes::

    @check("2.3", n_blocks=Int(), null_dim=Int())
    def check_structure(n_blocks, null_dim): ...

    @check("1.1", edge_error=Function(RealArray((3,))))
    def check_edge_error(edge_error): ...

Before the check's body runs, :func:`lagolib.exercises.check` reads every answer that is not a
placeholder (``...``, ``None``) as its kind: the body gets a clean value (a Python ``int``,
``float``, ``bool`` or ``str``, a tuple of ints, a float ndarray), and an answer of another kind
is reported "not yet" with a sentence naming the kind asked for — never a traceback, never
"correct".  A student's function declared with :class:`Function` has its *result* read the same
way by :func:`lagolib.exercises.call_student`.  The comparisons (``compare_array``,
``compare_number``, ``compare_int``, ``compare_choice``, ``matches``) read their answer through the
same kinds.

A kind accepts every form of the right kind a student naturally writes, and refuses the rest:

===========  ===================================================  =====================================
kind         accepted                                             refused ("not yet", naming the kind)
===========  ===================================================  =====================================
Real         int, float, numpy integers and floats, numeric       bool; str (also ``"3.0"``); bytes;
             arrays holding one entry (0-d, (1,), (1, 1)),        complex (also ``3+0j``); lists,
             Fraction, Decimal, real sympy numbers                longer arrays, dicts; NaN and ±inf
Int          the same, when whole (``5.0`` is 5)                  as Real, and ``5.5``
Bool         ``True``/``False``, ``numpy.bool_``, a bool array    ``0``/``1``, ``"True"``, anything else
             holding one entry; ``"yes"``/``"no"`` (any case)
Choice       a str (``numpy.str_``, a 0-d text array)             bytes, numbers, lists, …
Shape        a tuple, list or 1-d integer array of n whole        dicts, sets, str, bools, negative or
             numbers                                              fractional sizes, another length
RealArray    arrays of integer or float dtype; nested lists and   bool, complex, text or object dtype;
             tuples of real numbers (as Real); sympy matrices;    None, text or bools inside a list;
             masked arrays with nothing masked; scipy.sparse      ragged nested lists; masked entries;
             only where the exercise allows it                    sparse matrices; NaN and ±inf
Tuple        a tuple, list or array of exactly n items, each      other containers, another length
             read as its own kind (n numbers: also a row or a
             column, shape (1, n) or (n, 1))
===========  ===================================================  =====================================

An answer of a wrong kind raises :class:`WrongKind` inside the checks, which :func:`check` turns
into the verdict; nothing here prints.
"""

from __future__ import annotations

import decimal
import math
import numbers

import numpy as np

__all__ = [
    "NOT_ATTEMPTED",
    "YES_NO",
    "WrongKind",
    "Kind",
    "Real",
    "Int",
    "Bool",
    "Choice",
    "Shape",
    "RealArray",
    "Tuple",
    "Function",
    "StudentFunction",
    "as_real",
    "as_int",
    "as_bool",
    "as_text",
    "as_shape",
    "as_real_array",
    "is_placeholder",
    "normalize_choice",
    "show",
    "describe",
]


NOT_ATTEMPTED = "not attempted yet"


class WrongKind(Exception):
    """An answer that is not of the kind asked for; ``str(exc)`` is the sentence for the student.

    ``hint`` says how to write an answer of the right kind.
    """

    def __init__(self, message: str, hint: str = ""):
        super().__init__(message)
        self.hint = hint


class _Placeholder(Exception):
    """An item of an answer (of a returned tuple) is still the placeholder."""


class _Bad(Exception):
    """Internal: ``got`` describes the value that is not of the kind (the end of the sentence)."""

    def __init__(self, got: str, hint: str = ""):
        super().__init__(got)
        self.got = got
        self.hint = hint


def is_placeholder(answer) -> bool:
    """True for the stubs' placeholders: ``...`` (Ellipsis) and ``None``."""
    return answer is ... or answer is None


def show(value, width: int = 80) -> str:
    """``repr(value)`` cut to ``width`` characters, whatever ``value`` is (a repr may raise)."""
    try:
        text = repr(value)
    except Exception:  # a student's object whose repr raises
        text = f"<{type(value).__name__}>"
    return text if len(text) <= width else text[: width - 3] + "..."


def _a(word: str) -> str:
    return f"{'an' if word[:1].lower() in 'aeiou' else 'a'} {word}"


def _is_sparse(value) -> bool:
    try:
        import scipy.sparse as sp
    except ImportError:  # pragma: no cover - scipy is a dependency of lagolib
        return False
    return bool(sp.issparse(value))


def _is_sympy(value) -> bool:
    return type(value).__module__.split(".")[0] == "sympy"


def _describe_array(a: np.ndarray) -> str:
    """What an ndarray holds, for a sentence: ``an array of complex numbers (dtype …, shape …)``."""
    shape = f"shape {a.shape}"
    kind = a.dtype.kind
    if kind == "b":
        return f"an array of True/False values (dtype bool, {shape})"
    if kind == "c":
        zero = a.size and not np.any(np.imag(a))
        return f"an array of complex numbers (dtype {a.dtype}, {shape})" + (
            ", all with imaginary part 0: keep the real part (.real)" if zero else ""
        )
    if kind in "US":
        return f"an array of text (dtype {a.dtype}, {shape})"
    if kind == "O":
        return f"an array of dtype object ({shape})"
    return f"an array of dtype {a.dtype} ({shape})"


def describe(value) -> str:
    """``value`` as the end of "…, got <description>": its kind and, when short, what it is."""
    if value is None:
        return "None"
    if value is ...:
        return "... (the placeholder)"
    if isinstance(value, (bool, np.bool_)):
        return f"{bool(value)} (a bool)"
    if isinstance(value, str):
        return f"{show(str(value), 60)} (a string)"
    if isinstance(value, (bytes, bytearray)):
        return f"{show(value, 60)} (bytes, not a str)"
    if isinstance(value, (complex, np.complexfloating)):
        return f"{show(complex(value), 60)} (a complex number)"
    if _is_sparse(value):
        return f"{_a(type(value).__name__)} (a scipy.sparse matrix) of shape {value.shape}"
    if np.ma.isMaskedArray(value):
        k = int(np.ma.getmaskarray(value).sum())
        return (
            f"a masked array with {k} masked entr{'y' if k == 1 else 'ies'} (shape {value.shape})"
        )
    if isinstance(value, np.ndarray):
        return _describe_array(value)
    if isinstance(value, (list, tuple)):
        return f"{_a(type(value).__name__)} of length {len(value)}"
    if isinstance(value, dict):
        return f"a dict ({show(value, 50)})"
    if isinstance(value, (set, frozenset)):
        return f"a set ({show(value, 50)}), which has no order"
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.6g} ({_a(type(value).__name__)})"
    if isinstance(value, (numbers.Number, decimal.Decimal)) or _is_sympy(value):
        return f"{show(value, 60)} ({_a(type(value).__name__)})"
    return _a(type(value).__name__)


# ------------------------------------------------------------------------------ scalars
def _one(value):
    """A numpy array (or np.matrix) holding exactly one entry, as a 0-d array; else ``value``.

    ``np.mean(x, keepdims=True)``, ``A @ b`` of shapes (1, k) and (k, 1), a (1,) slice: numpy
    hands out one number in an array often, and it is the number all the same.
    """
    if (
        isinstance(value, np.ndarray)
        and value.ndim > 0
        and value.size == 1
        and not (np.ma.isMaskedArray(value) and np.ma.getmaskarray(value).any())
    ):
        return np.asarray(value).reshape(())
    return value


def _real(value) -> float:
    """``value`` as a float if it is one real number of any numeric type, else raise _Bad."""
    if isinstance(value, (bool, np.bool_)):
        raise _Bad(describe(value))
    value = _one(value)
    if np.ma.isMaskedArray(value) and value.ndim == 0 and not np.ma.getmaskarray(value).any():
        value = np.asarray(value.data)  # one number, not masked
    if isinstance(value, (numbers.Real, decimal.Decimal)) and not _is_sympy(value):
        try:
            return float(value)
        except (OverflowError, ValueError, TypeError):
            raise _Bad(f"{show(value, 40)}, which is not a float") from None
    if isinstance(value, np.ndarray) and value.ndim == 0 and not np.ma.isMaskedArray(value):
        if value.dtype.kind in "iuf":
            return float(value)
        raise _Bad(_describe_array(value))
    if _is_sympy(value):
        if getattr(value, "is_number", False) and getattr(value, "is_real", None):
            try:
                return float(value)
            except (TypeError, ValueError):
                pass
        if getattr(value, "is_number", False) and getattr(value, "is_real", None) is False:
            raise _Bad(f"{show(value, 40)} (a complex sympy number)")
        raise _Bad(f"the sympy expression {show(value, 40)}, not a number")
    if isinstance(value, str) and _parses_as_number(value):
        raise _Bad(f"{show(str(value), 40)} (a string: write the number without quotes)")
    raise _Bad(describe(value))


def _parses_as_number(text: str) -> bool:
    try:
        complex(text.strip())
    except ValueError:
        return False
    return True


def _int(value) -> int:
    """``value`` as an int if it is a whole number (``5`` or ``5.0``), else raise _Bad."""
    if isinstance(value, (bool, np.bool_)):
        raise _Bad(describe(value))
    value = _one(value)
    if isinstance(value, numbers.Integral) and not _is_sympy(value):
        return int(value)
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iu":
        return int(value)
    x = _real(value)
    if not (math.isfinite(x) and x.is_integer()):
        raise _Bad(show(value, 40))
    return int(x)


# ------------------------------------------------------------------------------ the kinds
class Kind:
    """The kind of one answer: :meth:`coerce` reads it or raises :class:`WrongKind`."""

    #: the kind, as the end of "… should be <what>"
    what = "an answer"
    #: how to write an answer of this kind
    hint = "the exercise's statement says what to give: which names, types and shapes."

    def parse(self, value):  # pragma: no cover - every kind overrides it
        """The clean value, or raise ``_Bad`` (internal)."""
        raise NotImplementedError

    def coerce(self, value, name: str = "your answer"):
        """``value`` read as this kind; raises :class:`WrongKind` naming the kind otherwise."""
        return self._read(value, f"{name} should be {self.what}, got {{}}.")

    def returned(self, value, name: str = "your function"):
        """Like :meth:`coerce` for the result of the student's function ``name``."""
        return self._read(value, f"{name} should return {self.what}; it returned {{}}.")

    def _read(self, value, message):
        """``parse(value)``, or WrongKind with ``message`` filled with what was got."""
        try:
            return self.parse(value)
        except _Bad as bad:
            raise WrongKind(message.format(bad.got), bad.hint or self.hint) from None

    def prepare(self, value, name: str):
        """What :func:`lagolib.exercises.check` hands the check's body (here: the read value)."""
        return self.coerce(value, name)

    def __repr__(self):
        return f"{type(self).__name__}({self.what!r})"


class Real(Kind):
    """One real number (see the module's table); read as a Python float."""

    what = "one real number"
    hint = (
        "write the number itself, e.g. 0.25: not in quotes, not in a list, not True/False, "
        "no imaginary part."
    )

    def __init__(self, *, finite: bool = True):
        self.finite = finite

    def parse(self, value):
        x = _real(value)
        if self.finite and not math.isfinite(x):
            raise _Bad(f"{x}, which is not finite")
        return x


class Int(Kind):
    """A whole number; read as a Python int (``5.0`` is 5; ``True`` and ``5.5`` are refused).

    Parameters
    ----------
    count_of : str, optional
        What the number counts (``"worlds"``), when it is a count: an answer True or False is
        then told that the question is how many, not whether.
    """

    what = "a whole number"
    hint = "write a whole number, e.g. 3: not True/False, not in quotes, not in a list."

    def __init__(self, *, count_of: str | None = None):
        self.count_of = count_of
        if count_of:
            self.what = f"a whole number (how many {count_of})"

    def parse(self, value):
        if self.count_of and isinstance(_one(value), (bool, np.bool_)):
            raise _Bad(
                f"{describe(_one(value))}: the question is how many {self.count_of}, not "
                "whether there are any",
                f"count the {self.count_of} and write the count, e.g. 3.",
            )
        return _int(value)


#: the words a yes/no question also accepts (any case, spaces around them ignored)
YES_NO = {"yes": True, "no": False}


class Bool(Kind):
    """``True`` or ``False`` (also numpy's, and a one-entry bool array), or the words ``"yes"`` /
    ``"no"`` (any case) — a yes/no question; read as a Python bool.  ``0``/``1`` and the string
    ``"True"`` are refused (a quoted ``"False"`` is true in an ``if``)."""

    what = "True or False"
    hint = 'write True or False without quotes (or the word "yes" or "no").'

    def parse(self, value):
        value = _one(value)
        if isinstance(value, (bool, np.bool_)):
            return bool(value)
        if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind == "b":
            return bool(value)
        if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind == "U":
            value = str(value[()])
        if isinstance(value, str) and value.strip().lower() in YES_NO:
            return YES_NO[value.strip().lower()]
        if isinstance(value, str) and value.strip().lower() in ("true", "false"):
            raise _Bad(
                f"{describe(value)}: True and False are written without quotes",
                "write True or False without quotes (or the word \"yes\" or \"no\").",
            )
        raise _Bad(describe(value))


_DASHES = str.maketrans({c: "-" for c in "\u2010\u2011\u2012\u2013\u2014\u2212"})


def normalize_choice(text: str) -> str:
    """A written choice as compared: case, repeated spaces, and the difference between a hyphen,
    the dashes a rendered page shows (‐ ‑ ‒ – — −) and a space do not matter.

    >>> normalize_choice(" Gauss–Newton ") == normalize_choice("gauss-newton")
    True
    """
    text = text.translate(_DASHES).replace("-", " ")
    return " ".join(text.lower().split())


class Choice(Kind):
    """One of ``choices``, written as a string; read as a str: the choice itself when the answer
    is one of them as :func:`normalize_choice` compares (``" Gauss–Newton"`` is
    ``"Gauss-Newton"``), otherwise the string as written (which choice it is, the check's
    :func:`~lagolib.exercises.compare_choice` says).  When the choices are ``"yes"`` and ``"no"``,
    ``True`` and ``False`` are those answers too."""

    hint = "write one of the listed answers as a string, in quotes."

    def __init__(self, choices):
        self.choices = tuple(choices)
        self.what = f"one of {list(self.choices)} (a string)"

    def parse(self, value):
        if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind == "U":
            value = str(value[()])
        if isinstance(value, (bool, np.bool_)):
            # a yes/no question answered True/False: the same answer
            words = {normalize_choice(c): c for c in self.choices if isinstance(c, str)}
            if set(words) == set(YES_NO):
                return words["yes" if value else "no"]
        if not isinstance(value, str):
            raise _Bad(describe(value))
        text = normalize_choice(value)
        for choice in self.choices:
            if isinstance(choice, str) and normalize_choice(choice) == text:
                return choice
        return str(value)


class Shape(Kind):
    """The shape of an array: a tuple (or list, or 1-d integer array) of ``ndim`` whole numbers,
    none negative; read as a tuple of ints."""

    hint = "write the shape as a tuple of whole numbers, e.g. (3, 4), as A.shape gives it."

    def __init__(self, ndim: int, what: str | None = None):
        self.ndim = int(ndim)
        self.what = what or f"a shape, a tuple of {self.ndim} whole numbers"

    def parse(self, value):
        if isinstance(value, np.ndarray) and value.ndim == 1 and value.dtype.kind in "iuf":
            items = value.tolist()
        elif isinstance(value, (tuple, list)):
            items = list(value)
        else:
            raise _Bad(describe(value))
        if len(items) != self.ndim:
            raise _Bad(f"{describe(value)}: {show(value, 40)}")
        out = []
        for k, item in enumerate(items):
            try:
                size = _int(item)
            except _Bad as bad:
                raise _Bad(f"{show(value, 40)}, whose item {k} is {bad.got}") from None
            if size < 0:
                raise _Bad(f"{show(value, 40)}, with the negative size {size}")
            out.append(size)
        return tuple(out)


class RealArray(Kind):
    """An array of finite real numbers; read as a float ndarray (its shape is left to the check).

    Parameters
    ----------
    shape : tuple, optional
        The shape asked for, for the sentence only; entries may be names (``("n",)``).  The check
        compares the shape itself, so that it can name a transpose or a missing row.
    sparse : bool
        Whether a scipy.sparse matrix is an answer of this kind (read as dense; a sparse row is
        read as a vector when ``shape`` has one entry).
    finite : bool
        Whether NaN and ±inf are refused.
    """

    hint = (
        "give a numpy array of real numbers (float or int dtype), e.g. np.array([0.5, -1.0]): "
        "no complex parts, no text, no None, no True/False."
    )

    def __init__(self, shape=None, *, sparse: bool = False, finite: bool = True):
        self.shape = tuple(shape) if shape is not None else None
        self.sparse = bool(sparse)
        self.finite = bool(finite)
        if self.shape is None:
            where = ""
        else:
            dims = ", ".join(str(s) for s in self.shape)
            where = f" of shape ({dims}{',' if len(self.shape) == 1 else ''})"
        self.what = (
            "a dense or sparse " if self.sparse else "an "
        ) + f"array of real numbers{where}"

    def parse(self, value):
        if _is_sparse(value):
            if not self.sparse:
                raise _Bad(
                    describe(value),
                    "give a dense numpy array: call .toarray() on a sparse matrix (np.asarray "
                    "does not convert it).",
                )
            dense = np.asarray(value.toarray())
            if self.shape is not None and len(self.shape) == 1 and dense.ndim == 2:
                if dense.shape[0] == 1:
                    dense = dense[0]
            return self._finite(self._from_ndarray(dense))
        if np.ma.isMaskedArray(value):
            if np.ma.getmaskarray(value).any():
                raise _Bad(describe(value), "fill in the masked entries (or give a plain array).")
            value = np.asarray(value.data)
        if isinstance(value, np.ndarray):
            return self._finite(self._from_ndarray(value))
        if isinstance(value, (list, tuple)) or (_is_sympy(value) and hasattr(value, "tolist")):
            seq = value.tolist() if _is_sympy(value) else value
            container = "sympy matrix" if _is_sympy(value) else type(value).__name__
            self._check_items(seq, container, ())
            try:
                arr = np.array(seq, dtype=float)
            except (ValueError, TypeError):
                raise _Bad(
                    f"a ragged nested {container} (its rows have different lengths)"
                ) from None
            return self._finite(arr)
        if isinstance(value, (str, bytes, dict, set, frozenset, bool, np.bool_, complex)):
            raise _Bad(describe(value))
        if isinstance(value, (numbers.Number, decimal.Decimal, np.generic)) or _is_sympy(value):
            return self._finite(np.array(_real(value)))  # one number: the check names the shape
        try:  # anything numpy reads as an array (pandas, array-likes, …)
            arr = np.asarray(value)
        except Exception:  # an odd object: it is not an array of numbers
            raise _Bad(describe(value)) from None
        if arr.dtype.kind == "O" and arr.ndim == 0:
            raise _Bad(describe(value))
        return self._finite(self._from_ndarray(arr))

    @staticmethod
    def _from_ndarray(a: np.ndarray) -> np.ndarray:
        if a.dtype.kind in "iuf":
            return np.array(a, dtype=float)  # a copy: the check may keep it
        raise _Bad(_describe_array(a))

    def _check_items(self, seq, container: str, path: tuple):
        """Every item of the nested list ``seq`` is a real number or a numeric array."""
        if len(path) > 32:  # deeper than any array (or a list that holds itself)
            raise _Bad(f"{_a(container)} nested more than 32 levels deep")
        for k, item in enumerate(seq):
            where = path + (k,)
            if isinstance(item, (list, tuple)):
                self._check_items(item, container, where)
                continue
            if isinstance(item, np.ndarray) and not np.ma.isMaskedArray(item):
                if item.dtype.kind in "iuf":
                    continue
                got = _describe_array(item)
            elif _is_sympy(item) and hasattr(item, "tolist"):
                self._check_items(item.tolist(), container, where)
                continue
            else:
                try:
                    _real(item)
                    continue
                except _Bad as bad:
                    got = bad.got
            index = "".join(f"[{i}]" for i in where)
            raise _Bad(f"{_a(container)} holding {got} at index {index}")

    def _finite(self, arr: np.ndarray) -> np.ndarray:
        if self.finite and not np.all(np.isfinite(arr)):
            bad = tuple(int(i) for i in np.argwhere(~np.isfinite(arr))[0])
            raise _Bad(f"an array with a non-finite value ({arr[bad]}) at index {bad}")
        return arr


class Tuple(Kind):
    """A fixed number of answers returned together, e.g. ``(A, B)``: a tuple, a list or a numeric
    array of exactly ``len(items)`` items, each read as its own kind and named by ``names``.

    An item that is still a placeholder makes the whole answer "not attempted yet".
    """

    def __init__(self, *items: Kind, names, what: str, hint: str = ""):
        if len(names) != len(items):
            raise ValueError("Tuple: one name per item")
        self.items, self.names, self.what = tuple(items), tuple(names), what
        self.hint = hint or f"return {len(items)} values separated by commas: {', '.join(names)}."

    def _items(self, value):
        if isinstance(value, (tuple, list)):
            items = list(value)
        elif (
            isinstance(value, np.ndarray)
            and value.ndim == 2
            and 1 in value.shape
            and value.size == len(self.items)
            and value.dtype.kind != "O"
            and all(isinstance(k, (Real, Int, Bool)) for k in self.items)
        ):
            items = list(np.asarray(value).ravel())  # a row or a column of numbers: the numbers
        elif isinstance(value, np.ndarray) and value.ndim >= 1 and value.dtype.kind != "O":
            items = list(value)
        else:
            raise _Bad(describe(value))
        if len(items) != len(self.items):
            raise _Bad(describe(value))
        if any(is_placeholder(item) for item in items):
            raise _Placeholder()
        return items

    def coerce(self, value, name: str = "your answer"):
        try:
            items = self._items(value)
        except _Bad as bad:
            raise WrongKind(f"{name} should be {self.what}, got {bad.got}.", self.hint) from None
        return tuple(k.coerce(i, n) for k, i, n in zip(self.items, items, self.names))

    def returned(self, value, name: str = "your function"):
        try:
            items = self._items(value)
        except _Bad as bad:
            raise WrongKind(
                f"{name} should return {self.what}; it returned {bad.got}.", self.hint
            ) from None
        return tuple(k.coerce(i, n) for k, i, n in zip(self.items, items, self.names))


class Function:
    """A student's function whose result is of the kind ``returns``.

    :func:`lagolib.exercises.check` hands the body a :class:`StudentFunction`;
    :func:`lagolib.exercises.call_student` calls it and reads its result as ``returns``.
    ``explain(result, *args)``, if given, may first return a sentence for a recognized wrong
    form of the result (a pair where a vector is asked for, …), or None.
    """

    def __init__(self, returns: Kind, explain=None):
        self.returns = returns
        self.explain = explain
        self.what = f"a function returning {returns.what}"

    def prepare(self, value, name: str):
        if callable(value) and not isinstance(value, StudentFunction):
            return StudentFunction(value, self)
        return value  # a placeholder or not a function: call_student says so

    def read(self, value, name: str, args=(), kwargs=None):
        """``(value read as returns, None)`` or ``(None, the problem)`` for a result."""
        if self.explain is not None:
            problem = self.explain(value, *args, **(kwargs or {}))
            if problem:
                return None, problem
        try:
            return self.returns.returned(value, name), None
        except _Placeholder:
            return None, NOT_ATTEMPTED
        except WrongKind as exc:
            return None, str(exc)

    def __repr__(self):
        return f"Function({self.returns!r})"


class StudentFunction:
    """A student's function as a check's body receives it: calling it calls the student's
    function; :func:`lagolib.exercises.call_student` also reads the result (``spec.returns``)."""

    def __init__(self, fn, spec: Function):
        self.fn = fn
        self.spec = spec

    def __call__(self, *args, **kwargs):
        return self.fn(*args, **kwargs)

    def __repr__(self):
        return show(self.fn)


# ------------------------------------------------------------------------------ functions
def as_real(value, name: str = "your answer", *, finite: bool = True) -> float:
    """``value`` as a float if it is one real number, else raise :class:`WrongKind`.

    >>> as_real(np.float64(0.5)), as_real(2)
    (0.5, 2.0)
    >>> try:
    ...     as_real("0.5", "ratio")
    ... except WrongKind as exc:
    ...     print(exc)  # doctest: +NORMALIZE_WHITESPACE
    ratio should be one real number, got '0.5'
    (a string: write the number without quotes).
    """
    return Real(finite=finite).coerce(value, name)


def as_int(value, name: str = "your answer") -> int:
    """``value`` as an int if it is a whole number (not a bool), else raise :class:`WrongKind`.

    >>> as_int(7.0), as_int(np.int64(7))
    (7, 7)
    """
    return Int().coerce(value, name)


def as_bool(value, name: str = "your answer") -> bool:
    """``value`` as a bool if it is True or False (also numpy's), else raise :class:`WrongKind`."""
    return Bool().coerce(value, name)


def as_text(value, choices, name: str = "your answer") -> str:
    """``value`` as a str if it is one (to be compared with ``choices``), else raise."""
    return Choice(choices).coerce(value, name)


def as_shape(value, ndim: int, name: str = "your answer") -> tuple:
    """``value`` as a tuple of ``ndim`` non-negative ints, else raise :class:`WrongKind`.

    >>> as_shape([11, np.int64(19)], 2)
    (11, 19)
    >>> try:
    ...     as_shape({11: 0, 19: 1}, 2, "A_shape")
    ... except WrongKind as exc:
    ...     print(exc)  # doctest: +NORMALIZE_WHITESPACE
    A_shape should be a shape, a tuple of 2 whole numbers,
    got a dict ({11: 0, 19: 1}).
    """
    return Shape(ndim).coerce(value, name)


def as_real_array(value, name: str = "your answer", *, shape=None, sparse=False, finite=True):
    """``value`` as a float ndarray if it is an array of real numbers, else raise.

    >>> as_real_array([[1, 2], [3, 4]]).dtype
    dtype('float64')
    >>> try:
    ...     as_real_array(np.array([1.0, 2.0]) + 1000j, "e", shape=(2,))
    ... except WrongKind as exc:
    ...     print(exc)  # doctest: +NORMALIZE_WHITESPACE
    e should be an array of real numbers of shape (2,),
    got an array of complex numbers (dtype complex128, shape (2,)).
    """
    return RealArray(shape, sparse=sparse, finite=finite).coerce(value, name)
