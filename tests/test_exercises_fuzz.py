"""No check of any chapter raises on an answer, whatever the answer is; each returns a bool.

Every ``check_…`` of ``lagolib.exercises.ch01`` … ``ch07`` is called with adversarial answers in
every argument — placeholders, wrong types, ragged lists, NaN, strings, objects whose ``==`` and
``repr`` raise — and with functions that return them or raise.  A check must print a verdict and
return ``True`` or ``False``: a student's mistake is feedback, never a traceback.
"""

import importlib
import inspect

import numpy as np
import pytest

from lagolib.exercises import CHAPTERS


class Weird:
    def __eq__(self, other):
        raise RuntimeError("no comparing me")

    def __repr__(self):
        raise RuntimeError("no printing me")

    def __len__(self):
        raise RuntimeError("no length")

    __hash__ = None


def _raises(*args, **kwargs):
    raise RuntimeError("the student's function is broken")


VALUES = [
    None,
    ...,
    True,
    -1,
    2.5,
    float("nan"),
    "abc",
    [[1, 2], [3]],
    {"a": 1},
    np.zeros((2, 7)),
    np.array([np.inf]),
    Weird(),
]


def _returning(value):
    def student(*args, **kwargs):
        return value

    return student


ANSWERS = VALUES + [_returning(v) for v in VALUES] + [_raises]


def _checks():
    for name in CHAPTERS:
        module = importlib.import_module(f"lagolib.exercises.{name}")
        for fname, fn in sorted(vars(module).items()):
            if fname.startswith("check_") and inspect.isfunction(fn):
                if fn.__module__ == module.__name__:
                    yield pytest.param(fn, id=f"{name}.{fname}")


def _required(fn):
    sig = inspect.signature(fn)
    return [
        p
        for p in sig.parameters.values()
        if p.default is inspect.Parameter.empty
        and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
    ]


@pytest.mark.parametrize("check", list(_checks()))
def test_check_never_raises(check, capsys):
    chapter = int(check.__module__.rsplit("ch", 1)[1])
    exercise = getattr(check, "exercise", "")
    assert exercise.startswith(f"{chapter}."), (
        f'{check.__qualname__}: decorate it with @check("{chapter}.k") from lagolib.exercises'
    )
    n = len(_required(check))
    failures = []
    for k, answer in enumerate(ANSWERS):
        try:
            result = check(*([answer] * n))
        except Exception as exc:  # noqa: BLE001 - the point of the test
            failures.append(f"answer {k} ({type(answer).__name__}): {type(exc).__name__}: {exc}")
            continue
        if result is not True and result is not False:
            failures.append(f"answer {k}: returned {result!r}, not a bool")
        out = capsys.readouterr().out
        if f"Exercise {exercise} — " not in out:
            failures.append(f"answer {k}: printed no verdict")
    assert not failures, "\n".join(failures[:8])
