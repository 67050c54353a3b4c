"""Validation of the numeric and categorical options of lagolib's public functions.

Every public function checks its options with these helpers, so a misuse is reported the same way
everywhere: an :class:`~lagolib.errors.OptionError` (a :class:`ValueError`, or
:class:`~lagolib.errors.OptionTypeError`, a :class:`TypeError`, for the wrong type) whose message
names the function, the argument, what was given and what is allowed.

Examples
--------
>>> check_int(3, "max_iterations", "optimize", minimum=0)
3
>>> check_real(float("nan"), "tolerance", "optimize", minimum=0.0)
Traceback (most recent call last):
    ...
lagolib.errors.OptionError: optimize: tolerance must be a finite number >= 0.0; got nan
"""

from __future__ import annotations

import inspect
import math
import numbers

import numpy as np

from .errors import OptionError, OptionTypeError

__all__ = [
    "check_int",
    "check_real",
    "check_choice",
    "check_bool",
    "check_callback",
    "check_rng",
    "real_array",
]


def check_int(value, name, where, *, minimum=None, maximum=None):
    """``value`` as a Python int, checked to be an integer (not a bool, not a float) in range."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise OptionTypeError(
            f"{where}: {name} must be an integer; got {value!r} ({type(value).__name__})"
        )
    v = int(value)
    if (minimum is not None and v < minimum) or (maximum is not None and v > maximum):
        lo = "" if minimum is None else f" >= {minimum}"
        hi = "" if maximum is None else f" <= {maximum}"
        both = " and" if lo and hi else ""
        raise OptionError(f"{where}: {name} must be an integer{lo}{both}{hi}; got {v}")
    return v


def check_real(value, name, where, *, minimum=None, maximum=None, strict=False):
    """``value`` as a finite Python float in ``[minimum, maximum]`` (open ends with ``strict``)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise OptionTypeError(
            f"{where}: {name} must be a real number; got {value!r} ({type(value).__name__})"
        )
    v = float(value)
    lo_ok = minimum is None or (v > minimum if strict else v >= minimum)
    hi_ok = maximum is None or (v < maximum if strict else v <= maximum)
    if not (math.isfinite(v) and lo_ok and hi_ok):
        op_lo, op_hi = (">", "<") if strict else (">=", "<=")
        lo = "" if minimum is None else f" {op_lo} {minimum}"
        hi = "" if maximum is None else f" {op_hi} {maximum}"
        both = " and" if lo and hi else ""
        raise OptionError(f"{where}: {name} must be a finite number{lo}{both}{hi}; got {v!r}")
    return v


def check_choice(value, name, where, choices):
    """``value`` if it is one of ``choices`` (compared with ``==``, strings only)."""
    if not isinstance(value, str) or value not in choices:
        allowed = ", ".join(repr(c) for c in choices)
        raise OptionError(f"{where}: {name} must be one of {allowed}; got {value!r}")
    return value


def check_bool(value, name, where):
    """``value`` if it is a bool (or numpy bool)."""
    if not isinstance(value, (bool, np.bool_)):
        raise OptionTypeError(f"{where}: {name} must be True or False; got {value!r}")
    return bool(value)


def real_array(value, name, where):
    """``value`` as a float ndarray; complex or non-numeric input is an :class:`OptionTypeError`."""
    if np.iscomplexobj(value):
        raise OptionTypeError(f"{where}: {name} must be real; got a complex value")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise OptionTypeError(f"{where}: {name} must be a real number or array: {exc}") from None


def check_callback(value, name, where, arguments=("iteration", "poses")):
    """``value`` if it is None or a function that accepts ``len(arguments)`` positional
    arguments; else :class:`~lagolib.errors.OptionTypeError` naming ``name`` — before any work is
    done, not at the first call."""
    if value is None:
        return None
    signature = f"{name}({', '.join(arguments)})"
    if not callable(value):
        raise OptionTypeError(
            f"{where}: {name} must be a function {signature} or None; got {type(value).__name__}"
        )
    try:
        inspect.signature(value).bind(*([None] * len(arguments)))
    except TypeError:
        raise OptionTypeError(
            f"{where}: {name} must accept {len(arguments)} positional arguments, "
            f"{signature}; {getattr(value, '__name__', type(value).__name__)} does not"
        ) from None
    except ValueError:  # no signature to inspect (some builtins): accept it
        pass
    return value


def check_rng(rng, where):
    """A Generator from a non-negative int seed or a Generator; ``None`` (fresh OS entropy) is
    refused: every simulation lagolib makes is reproducible."""
    if isinstance(rng, np.random.Generator):
        return rng
    if isinstance(rng, (bool, np.bool_)) or not isinstance(rng, numbers.Integral):
        raise OptionTypeError(
            f"{where}: rng must be a non-negative integer seed or a numpy.random.Generator; "
            f"got {rng!r} ({type(rng).__name__})"
        )
    return np.random.default_rng(check_int(rng, "rng", where, minimum=0))
