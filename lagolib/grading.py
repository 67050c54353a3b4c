"""Grading a class: run the submitted notebooks, check every answer with lagolib's own checks.

Usage::

    lagolib book grade SUBMISSIONS... -o gradebook.csv [--assignment week3.toml]
                       [--feedback DIR] [--book DIR] [--cell-timeout S] [--notebook-timeout S]
                       [-j JOBS] [--force]

(exit status 0 when the class was graded — wrong answers included —, 2 for misuse, 1 for another
problem; each notebook's verdicts are reported on stderr as it is graded).

**A teacher's workflow.**

1. ``lagolib book student-copies class/ [--no-hints]`` writes every chapter as a student starts
   it: the solutions replaced by stubs, outputs stripped;
2. the students fill the stubs in (running the checks as often as they like) and hand the
   notebooks back, one folder per student — as a learning platform's "download all" gives them;
3. ``lagolib book grade submissions/ --assignment week3.toml -o gradebook.csv`` runs every
   notebook, checks every answer that counts and writes the gradebook and one short feedback file
   per student (``gradebook-feedback/alice.md``, …);
4. the gradebook goes into the spreadsheet or the platform, the feedback files to the students.

The folders::

    submissions/
        alice/06_lago.ipynb               <- alice's chapter 6
        alice/05_orientation_estimation.ipynb
        bob/lago (bob's copy).ipynb       <- renamed: still chapter 6, read from its content
        carol/                            <- nothing handed in: "not attempted" everywhere
    week3.toml                            <- the assignment (optional)
    gradebook.csv                         <- written by the grader
    gradebook-feedback/alice.md, bob.md, carol.md

**Submissions.**  Each argument is a notebook or a folder.  In a folder ``D`` every ``*.ipynb``
below it is a submission (hidden files and folders such as ``.ipynb_checkpoints``, and
``__MACOSX``, are skipped); its student is the first folder below ``D``, or ``D``'s own name for
a notebook directly in ``D``.  When ``D`` holds no notebook itself, each of its folders is a
student even if it is empty (the student handed nothing in).  A notebook given as a file belongs
to the student named by its parent folder.  A notebook's chapter is read from its content — the
exercise ids in its statement cells' metadata (``metadata.lagolib.exercise``), else its calls of
``chNN.check_…`` — never from its file name: a renamed notebook is graded like any other.  A
student copy or the full chapter may be handed in.

**The assignment file** (TOML) says which exercises count and their points::

    title = "Week 3: orientations and LAGO"
    cell_timeout = 60         # seconds per cell (optional; default 60)
    notebook_timeout = 600    # seconds per notebook (optional; default 600)

    [points]                  # the exercises that count, and their points
    "5.1" = 2
    "5.3" = 1
    "6.2" = 3

The ids may be written without quotes (``5.1 = 2``).  Without an assignment file every exercise
of every chapter that somebody handed in counts one point, for every student.  Time limits given
to :func:`grade` (or on the command line) override the file's.  A file that is not TOML is a
:class:`~lagolib.errors.ParseError` naming its line; an unknown key, an exercise the book does not
have (the message lists those it has), or a value that is not a number is an
:class:`~lagolib.errors.OptionError` naming the key.

**What runs where.**  Each notebook runs *as submitted* — cells a student added included — in a
fresh Jupyter kernel (nbclient, the ``python3`` kernel, in an empty temporary folder of its own),
cell by cell, going on after an error.  A cell that runs past the per-cell limit is interrupted
and the next cell runs; one that cannot be interrupted, a kernel that dies, or a notebook that
uses up its whole budget stops the notebook there.  Right before each counted exercise's check
cell would run (right after its answer cell, if the check cell is gone), the grader evaluates, in
the kernel, the arguments *its own copy* of the chapter passes to that check (for
``ch04.check_chords(n_tree_edges, n_chords)``: ``n_tree_edges`` and ``n_chords``) and carries
them out of the kernel with ``cloudpickle`` (a student's functions by value; what a
``functools.cached_property`` holds, such as a factorization, is left behind and recomputed).
The kernel's output, its printed "correct" and its ``passed()`` are never read.  The checks then
run in a separate, fresh Python process that imports the installed lagolib (hints off): it calls
the pristine ``lagolib.exercises.chNN.check_…`` with the answers and keeps the verdict line it
prints and the value it returns.  A student's function that a check calls runs there under the
per-cell time limit; before each check the process notes the identity of every function, class
and name of lagolib's modules (their code, defaults and closures included), of numpy's top level
and of Python's builtins, and if an answer changed any of them (a patched ``verdict``, say) the
exercise is an ``error`` and a new process grades the rest.  One process grades all of a
notebook's answers when nothing goes wrong.

**Verdicts** (the gradebook's ``verdict`` column):

* ``correct`` — the grader's check returned True: full points;
* ``not yet`` — the check found the answer wrong (the feedback file says how: the check's
  diagnosis, its first tier, without hints);
* ``not attempted`` — the check says the placeholder is still there, the notebook is the student
  copy as given, or no notebook of the exercise's chapter was handed in;
* ``error`` — the grader could not grade the answer: its cell raised before the answer existed or
  ran past its time limit, the notebook stopped (time budget, a cell that could not be
  interrupted, a dead kernel), the answer could not be carried to the check, the exercise's cells
  are missing from the notebook, the answer hung or crashed the check, or it changed lagolib's
  checks; also every exercise of a chapter for which the student handed in only other notebooks
  (another chapter, an unreadable file) or two notebooks (which one counts is the teacher's call:
  nothing is graded, the feedback names both).

Only ``correct`` earns points.

**The gradebook** (CSV) has exactly the columns ``student, chapter, exercise, verdict, points``:
one row per student and counted exercise, sorted by student, then chapter and exercise number.
A notebook of a chapter the assignment does not include is not run and earns nothing; the
student's feedback file says so, and if the student handed in no notebook of an assigned chapter,
that chapter's rows are ``error`` rows naming the notebook handed in instead.  Each student's
feedback file (Markdown, ``<gradebook's stem>-feedback/<student>.md`` by default) lists every
counted exercise with its verdict, points and the check's diagnosis, then the total.  Neither
file overwrites an existing one unless asked (``force=True``, ``--force``): without it the
message names them and nothing is written; each file is written whole or not at all
(:func:`lagolib.files.atomic_write`).

**Guarantees, and their limits.**  What decides a verdict is the installed lagolib's check,
called in a process the student's notebook never ran in: a redefined ``check_…``, a patched
``verdict`` in the kernel, a printed "Exercise 6.2 — correct" or a faked ``passed()`` change
nothing, and an answer that patches the checks while they run is caught.  But lagolib's checks
compare with lagolib's own implementation, so the solutions ship inside the package, and the
full chapters are one command away: a student can read them.  And a notebook runs with the
grader's rights (its code can read and write the grader's files, and a determined student can
defeat any check run on the same machine); run a class's notebooks in a container or an account
of their own.  A check that takes the chapter's own objects (the graph of exercise 4.4, …) takes
them from the student's run.  Grading here is for feedback and for honest classes, not an exam
proctor.

**Why nbclient, not otter-grader or nbgrader.**  lagolib's exercises already carry their checks,
stubs and ids in the chapters' metadata, so the grader only has to run notebooks and call the
checks: nbclient — the engine Jupyter's own ``nbconvert --execute`` and the book's tests run
notebooks with, already installed with Jupyter — does the first, and the teacher's cost is one
command (plus, optionally, a five-line TOML file).  otter-grader would have the teacher rewrite
each chapter in Otter Assign's notebook format (question, solution and test cells), build an
autograder configuration zip per assignment, and grade in the Docker image Otter builds from it
(a non-containerized mode exists; its documentation recommends the containers, for security).
nbgrader would have the teacher adopt its course directory layout
(``course/step/student/assignment/notebook.ipynb``), keep its gradebook database, give every
answer and test cell a grade id and points with its Create Assignment extension, and install its
extensions in the class's Jupyter for students to fetch and submit assignments.
"""

from __future__ import annotations

import argparse
import ast
import csv
import io
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from .book import (
    SOLUTION_TAG,
    _read_notebook,
    _source,
    _tags,
    book_dir_or_default,
    exercises,
    student_copy,
)
from .checks import check_bool
from .errors import LagolibError, OptionError, ParseError
from .files import atomic_write

__all__ = [
    "VERDICTS",
    "COLUMNS",
    "CELL_TIMEOUT",
    "NOTEBOOK_TIMEOUT",
    "Assignment",
    "Gradebook",
    "read_assignment",
    "grade",
    "main",
]

VERDICTS = ("correct", "not yet", "not attempted", "error")
COLUMNS = ("student", "chapter", "exercise", "verdict", "points")
CELL_TIMEOUT = 60.0  # seconds per cell (and per check of one answer)
NOTEBOOK_TIMEOUT = 600.0  # seconds per notebook
INTERRUPT_GRACE = 10  # seconds an interrupted cell has to stop before the notebook is abandoned
STARTUP_TIMEOUT = 180.0  # seconds the evaluating process may take to import lagolib
KERNEL = "python3"
_NOT_ATTEMPTED = "not attempted yet"  # lagolib.exercises.NOT_ATTEMPTED, in every verdict line
_SKIPPED_DIRS = ("__MACOSX",)


# ----------------------------------------------------------------------------- the grader's book
@dataclass(frozen=True)
class _Exercise:
    id: str
    chapter: int
    check: str  # the check's name, e.g. "check_phase1"
    args: tuple  # the source of each positional argument of the book's check call
    kwargs: tuple  # ((name, source), ...)
    solutions: tuple  # ordinals (lagolib.book.student_copy's) of its answer code cells
    stubs: tuple  # their stubs


def _order(exercise: str):
    """Sort key of an exercise id: ``"10.2"`` after ``"9.4"``."""
    parts = exercise.split(".")
    return tuple(int(p) for p in parts) if all(p.isdigit() for p in parts) else (1 << 30, exercise)


def _check_call(source: str, chapter: int):
    """The ``chNN.check_…(…)`` call of a check cell: ``(name, args, kwargs)`` or None."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return None
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and isinstance(node.func.value, ast.Name)
            and node.func.value.id == f"ch{chapter:02d}"
            and node.func.attr.startswith("check_")
            and not any(isinstance(a, ast.Starred) for a in node.args)
            and all(k.arg is not None for k in node.keywords)
        ):
            args = tuple(ast.get_source_segment(source, a) for a in node.args)
            kwargs = tuple((k.arg, ast.get_source_segment(source, k.value)) for k in node.keywords)
            return node.func.attr, args, kwargs
    return None


def _chapter_number(exercise) -> int | None:
    head = str(exercise).split(".")[0]
    return int(head) if head.isdigit() else None


@dataclass
class _Book:
    exercises: dict  # {id: _Exercise}, the gradable ones
    copies: dict  # {chapter: the code cells of its student copy}


def _read_book(folder) -> _Book:
    """The grader's own chapters: every exercise with an answer cell and a check."""
    folder = Path(folder)
    paths = sorted(folder.glob("*.ipynb"))
    if not paths:
        raise OptionError(
            f"grade: book={str(folder)!r} holds no chapters (*.ipynb); pass the book's folder, "
            "or leave it out for the book this lagolib installed"
        )
    found, copies = {}, {}
    for path in paths:
        nb = _read_notebook(path)
        cells = nb["cells"]
        statements = exercises(nb, str(path))
        ordinals, k = {}, 0
        for i, cell in enumerate(cells):
            if SOLUTION_TAG in _tags(cell):
                ordinals[i] = k
                k += 1
        bounds = [e["cell"] for e in statements] + [len(cells)]
        for e, end in zip(statements, bounds[1:]):
            chapter = _chapter_number(e["id"])
            if chapter is None:
                continue
            answers = [
                i
                for i in range(e["cell"] + 1, end)
                if i in ordinals and cells[i]["cell_type"] == "code"
            ]
            call = None
            for i in range(answers[-1] + 1 if answers else end, end):
                if cells[i]["cell_type"] == "code" and i not in ordinals:
                    call = _check_call(_source(cells[i]), chapter)
                    if call:
                        break
            if not answers or call is None:
                continue  # nothing the grader can check (no answer cell, or no check call)
            stubs = tuple(
                str(cells[i].get("metadata", {}).get("lagolib", {}).get("stub", ""))
                for i in answers
            )
            found[e["id"]] = _Exercise(
                e["id"],
                chapter,
                call[0],
                call[1],
                call[2],
                tuple(ordinals[i] for i in answers),
                stubs,
            )
            if chapter not in copies:
                copies[chapter] = _code_sources(student_copy(nb, str(path)))
    if not found:
        raise OptionError(f"grade: the chapters in {folder} hold no exercise with a check")
    return _Book(found, copies)


def _code_sources(nb) -> list[str]:
    """The non-empty code cells of a notebook, stripped (the no-hints cell left out)."""
    out = []
    for cell in nb["cells"]:
        if cell["cell_type"] != "code":
            continue
        if cell.get("metadata", {}).get("lagolib", {}).get("no_hints"):
            continue
        text = _source(cell).strip()
        if text:
            out.append(text)
    return out


# ----------------------------------------------------------------------------- the assignment
@dataclass
class Assignment:
    """An assignment file, read (:func:`read_assignment`).

    Attributes
    ----------
    title : str
        Heads each feedback file ("" for none).
    points : dict or None
        ``{exercise id: points}`` of the exercises that count; None: every exercise of every
        chapter handed in, one point each.
    cell_timeout, notebook_timeout : float or None
        Seconds; None for the defaults (:data:`CELL_TIMEOUT`, :data:`NOTEBOOK_TIMEOUT`).
    """

    title: str = ""
    points: dict | None = None
    cell_timeout: float | None = None
    notebook_timeout: float | None = None


_KEYS = ("title", "cell_timeout", "notebook_timeout", "points")


def _line_of(text: str, key: str) -> int | None:
    """The line of ``text`` where ``key = …`` is set (for messages), or None."""
    pattern = re.compile(rf"""^\s*["']?{re.escape(key)}["']?\s*=""")
    for number, line in enumerate(text.splitlines(), 1):
        if pattern.match(line):
            return number
    return None


def _flatten(table, prefix="") -> dict:
    """``{"5": {"1": 2}}`` (TOML's reading of ``5.1 = 2``) as ``{"5.1": 2}``."""
    out = {}
    for key, value in table.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            out.update(_flatten(value, name))
        else:
            out[name] = value
    return out


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def read_assignment(path, known=None) -> Assignment:
    """Read an assignment file (TOML; the format is in this module's docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    known : collection of str, optional
        The exercise ids that exist (default: every exercise of the installed book that has a
        check); a ``[points]`` entry outside it is an error.

    Returns
    -------
    Assignment

    Raises
    ------
    ParseError
        The file is not UTF-8 or not TOML (naming file:line).
    OptionError
        The file does not exist; an unknown key; a title that is not a string; a time limit that
        is not a positive number of seconds; a ``[points]`` that is not a table, or empty; points
        that are not a non-negative number; an exercise id the book does not have (naming the
        exercises of its chapter, or all of them).  The message names the file and the line.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> week = pathlib.Path(tempfile.mkdtemp()) / "week3.toml"
    >>> _ = week.write_text('title = "Week 3"\\n[points]\\n"6.2" = 3\\n5.1 = 2\\n')
    >>> read_assignment(week, known={"5.1", "6.2"})
    Assignment(title='Week 3', points={'6.2': 3.0, '5.1': 2.0}, cell_timeout=None, notebook_timeout=None)
    """
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    path = Path(path)
    if not path.is_file():
        raise OptionError(f"grade: assignment file {str(path)!r} does not exist (or is a folder)")
    data = path.read_bytes()
    try:
        text = data.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise ParseError(path, line, "not UTF-8 text; save the assignment file as UTF-8") from None
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        line = getattr(exc, "lineno", None)  # Python 3.14's tomllib; earlier ones say it in text
        found = re.search(r"\(at line (\d+), column \d+\)", str(exc))
        if line is None and found:
            line = int(found.group(1))
        detail = re.sub(r"\s*\(at line \d+, column \d+\)", "", str(exc))
        raise ParseError(path, line, f"not TOML: {detail}") from None

    def fail(key, message):
        line = _line_of(text, key)
        where = f"{path}:{line}" if line else str(path)
        raise OptionError(f"{where}: {message}")

    for key in table:
        if key not in _KEYS:
            fail(key, f"unknown key {key!r}; an assignment file has {', '.join(_KEYS)}")
    out = Assignment()
    if "title" in table:
        if not isinstance(table["title"], str):
            fail("title", f"title = {table['title']!r}; write the title as a string, in quotes")
        out.title = table["title"]
    for key in ("cell_timeout", "notebook_timeout"):
        if key in table:
            value = table[key]
            if not _is_number(value) or value <= 0:
                fail(key, f"{key} = {value!r}; give a positive number of seconds")
            setattr(out, key, float(value))
    if "points" in table:
        points = table["points"]
        if not isinstance(points, dict) or not points:
            fail("points", '[points] should be a table of the exercises that count: "6.2" = 3')
        points = _flatten(points)
        ids = sorted(known if known is not None else _installed_ids(), key=_order)
        for ex, value in points.items():
            if not _is_number(value) or value < 0:
                fail(ex, f'points "{ex}" = {value!r}; give a number of points, 0 or more')
            if ex not in ids:
                chapter = _chapter_number(ex)
                same = [i for i in ids if _chapter_number(i) == chapter]
                listed = (
                    f"chapter {chapter}'s are {', '.join(same)}"
                    if same
                    else f"the book's are {', '.join(ids)}"
                )
                fail(ex, f'[points] names exercise "{ex}", which the book does not have; {listed}')
        out.points = {ex: float(value) for ex, value in points.items()}
    return out


def _installed_ids():
    return set(_read_book(book_dir_or_default(None)).exercises)


# ----------------------------------------------------------------------------- submissions
def _hidden(name: str) -> bool:
    return name.startswith(".") or name in _SKIPPED_DIRS


def _collect(arguments, exclude=None) -> tuple[list[tuple[str, Path]], set[str]]:
    """``([(student, notebook)], students)``: every submitted notebook, and every student (also
    those whose folder is empty); nothing in the folder ``exclude`` (the feedback files')."""
    found, students = [], set()
    exclude = None if exclude is None else Path(exclude).resolve()
    for arg in arguments:
        path = Path(arg)
        if path.is_dir():
            own = path.resolve().name or "student"
            direct = False
            for nb in sorted(path.rglob("*.ipynb")):
                rel = nb.relative_to(path)
                if any(_hidden(part) for part in rel.parts) or not nb.is_file():
                    continue
                if exclude is not None and nb.resolve().is_relative_to(exclude):
                    continue
                direct = direct or len(rel.parts) == 1
                found.append((rel.parts[0] if len(rel.parts) > 1 else own, nb))
            if not direct:  # a class's folder: every student folder counts, empty or not
                students |= {
                    p.name
                    for p in path.iterdir()
                    if p.is_dir() and not _hidden(p.name) and p.resolve() != exclude
                }
        elif path.is_file():
            if path.suffix.lower() != ".ipynb":
                raise OptionError(
                    f"grade: submission {str(path)!r} is not a notebook (*.ipynb); give "
                    "notebooks, or folders of them"
                )
            found.append((path.resolve().parent.name or "student", path))
        else:
            raise OptionError(
                f"grade: submission {str(path)!r} does not exist; give notebooks, or folders of "
                "them (one folder per student)"
            )
    seen, unique = set(), []
    for student, nb in found:  # a notebook given twice (its folder, and itself) counts once
        if nb.resolve() not in seen:
            seen.add(nb.resolve())
            unique.append((student, nb))
    found = unique
    if not found and not students:
        raise OptionError(
            f"grade: no notebooks (*.ipynb) in {', '.join(map(str, arguments))}; give the "
            "class's folder (one folder per student) or the notebooks"
        )
    return found, students | {s for s, _ in found}


@dataclass
class _Submission:
    student: str
    path: Path
    chapter: int | None = None
    problem: str | None = None  # why it is not one of the book's chapters


_CHECK_CALL = re.compile(r"\bch(\d\d)\.check_\w+\s*\(")


def _identify(student, path) -> _Submission:
    """Read a submitted notebook and find its chapter from its content."""
    sub = _Submission(student, path)
    try:
        nb = _read_notebook(path)  # read again when graded: a class's notebooks, with their
        ids = [e["id"] for e in exercises(nb, str(path))]  # outputs, need not fit in memory
    except (LagolibError, OSError) as exc:
        sub.problem = f"could not be read ({exc})"
        return sub
    chapters = {c for c in map(_chapter_number, ids) if c is not None}
    if not chapters:  # the statements lost their metadata: the check calls say which chapter
        for cell in nb["cells"]:
            if cell["cell_type"] == "code":
                chapters |= {int(n) for n in _CHECK_CALL.findall(_source(cell))}
    if len(chapters) == 1:
        (sub.chapter,) = chapters
    elif not chapters:
        sub.problem = "holds none of the book's exercises"
    else:
        listed = " and ".join(str(c) for c in sorted(chapters))
        sub.problem = f"holds exercises of chapters {listed}; hand in one notebook per chapter"
    return sub


# ----------------------------------------------------------------------------- results
@dataclass
class _Result:
    verdict: str
    message: str = ""


@dataclass
class Gradebook:
    """What :func:`grade` found and wrote.

    Attributes
    ----------
    rows : list of dict
        The gradebook's rows, keys :data:`COLUMNS` (all strings, as in the CSV file).
    messages : dict
        ``{(student, exercise): why}``: the check's diagnosis, or why it is an error.
    feedback : dict
        ``{student: text}`` of the feedback files (Markdown).
    path : Path or None
        The gradebook written (None when ``output=None``).
    feedback_paths : list of Path
        The feedback files written.
    """

    rows: list
    messages: dict
    feedback: dict
    path: Path | None = None
    feedback_paths: list = field(default_factory=list)


# ----------------------------------------------------------------------------- locating answers
def _meta(cell) -> dict:
    meta = cell.get("metadata", {}).get("lagolib", {})
    return meta if isinstance(meta, dict) else {}


def _answer_ordinals(nb) -> dict[int, int]:
    """``{ordinal: cell index}`` of a submitted notebook's answer code cells: a student copy's
    stubs carry their ordinal (``metadata.lagolib.solution``); a full chapter's solution cells
    are counted in order, as :func:`lagolib.book.student_copy` counts them."""
    cells, out = nb["cells"], {}
    for i, cell in enumerate(cells):
        k = _meta(cell).get("solution")
        if cell["cell_type"] == "code" and isinstance(k, int) and not isinstance(k, bool):
            out.setdefault(k, i)
    if out or nb.get("metadata", {}).get("lagolib", {}).get("student_copy"):
        return out
    k = 0
    for i, cell in enumerate(cells):
        if SOLUTION_TAG in _tags(cell):
            if cell["cell_type"] == "code":
                out[k] = i
            k += 1
    return out


@dataclass
class _Located:
    exercise: _Exercise
    answers: list  # the answer cells' indices
    after: int  # the cell after which the answer is read
    stub: bool  # every answer cell is its stub as given (or empty)


def _locate(nb, ex: _Exercise, ordinals) -> _Located | None:
    """Where exercise ``ex``'s answer is in a submitted notebook (None: its cells are gone)."""
    cells = nb["cells"]
    statements = [i for i, c in enumerate(cells) if "exercise" in _meta(c)]
    answers = [ordinals.get(k) for k in ex.solutions]
    stubs = list(ex.stubs)
    if any(a is None for a in answers):  # metadata lost (a retyped cell): the cell before the check
        own = [i for i in statements if str(_meta(cells[i])["exercise"]) == ex.id]
        if not own:
            return None
        end = min([i for i in statements if i > own[0]] + [len(cells)])
        code = [i for i in range(own[0] + 1, end) if cells[i]["cell_type"] == "code"]
        check = [i for i in code if f".{ex.check}(" in _source(cells[i])]
        before = [i for i in code if check and i < check[0]]
        if not before:
            return None
        answers, stubs = [before[-1]], stubs[-1:]
    last = max(answers)
    end = min([i for i in statements if i > last] + [len(cells)])
    after = last
    for i in range(last + 1, end):  # read the answer right before the check cell runs
        if cells[i]["cell_type"] != "code":
            continue
        if f".{ex.check}(" in _source(cells[i]):
            break
        after = i
    else:
        after = last  # no check cell: right after the answer
    stub = all(_source(cells[i]).strip() in ("", stub.strip()) for i, stub in zip(answers, stubs))
    return _Located(ex, answers, after, stub)


# ----------------------------------------------------------------------------- the kernel
_CAPTURE = """\
def _lagolib_grader_capture(path, answers):
    import builtins, copyreg, functools, io
    try:
        import cloudpickle

        class Pickler(cloudpickle.Pickler):
            # a cached_property's value (a factorization, say) stays behind: recomputed on use
            def reducer_override(self, obj):
                cls = type(obj)
                try:
                    state = None if isinstance(obj, type) else getattr(obj, "__dict__", None)
                    cached = isinstance(state, dict) and {{
                        k for k in state
                        if isinstance(getattr(cls, k, None), functools.cached_property)
                    }}
                except Exception:
                    cached = None
                if cached:
                    kept = {{k: v for k, v in state.items() if k not in cached}}
                    return copyreg.__newobj__, (cls,), kept
                return super().reducer_override(obj)

        buffer = io.BytesIO()
        Pickler(buffer).dump(answers())
        data, status = buffer.getvalue(), "ok"
    except BaseException as exc:
        data, status = b"", f"{{type(exc).__name__}}: {{exc}}"
    with builtins.open(path, "wb") as f:
        f.write(data)
    with builtins.open(path + ".status", "w", encoding="utf-8") as f:
        f.write(status)
_lagolib_grader_capture({path!r}, lambda: (({args}), {{{kwargs}}}))
del _lagolib_grader_capture
"""


def _kernel_env(base=None) -> dict:
    """The environment of a submission's kernel and of the evaluating process: ``base`` (default
    this process's) with the book's own asserts lenient (``LAGOLIB_BOOK_STRICT`` removed: a full
    chapter handed in runs to the end), matplotlib left to the kernel (``MPLBACKEND`` removed)
    and BLAS on one thread (as the book's tests run the chapters)."""
    env = {str(k): str(v) for k, v in (os.environ if base is None else base).items()}
    env.pop("MPLBACKEND", None)
    env.pop("LAGOLIB_BOOK_STRICT", None)
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env[var] = "1"
    env["PYDEVD_DISABLE_FILE_VALIDATION"] = "1"  # no debugger warning on the kernel's stderr
    return env


def _sliced(channel, step=1.0):
    """Make ``channel.get_msg(timeout)`` poll the socket at least every ``step`` seconds (a
    wake-up the event loop missed costs a second, not the cell's time limit; see the book's
    ``_ext/lagolib_headless.py``)."""
    from queue import Empty

    wait = channel.get_msg

    async def get_msg(timeout=None):
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            left = step if deadline is None else min(step, max(0.0, deadline - time.monotonic()))
            try:
                return await wait(timeout=left)
            except Empty:
                if deadline is not None and time.monotonic() >= deadline:
                    raise

    channel.get_msg = get_msg


def _client(nb, sockets):
    """An nbclient client for one submission: no Output-widget mimic (nothing is sent to the
    kernel while a cell runs), waits sliced, IPC sockets on POSIX (no TCP port race)."""
    import logging

    from nbclient import NotebookClient

    class Client(NotebookClient):
        def create_kernel_manager(self):
            km = super().create_kernel_manager()
            if sockets is not None:
                km.transport = "ipc"
                km.ip = os.path.join(sockets, "k")
            return km

        async def async_start_new_kernel_client(self):
            kc = await super().async_start_new_kernel_client()
            _sliced(kc.shell_channel)
            _sliced(kc.iopub_channel)
            return kc

    quiet = logging.getLogger("lagolib.grading.kernel")
    quiet.propagate = False
    quiet.addHandler(logging.NullHandler())
    client = Client(
        nb,
        kernel_name=KERNEL,
        allow_errors=True,
        interrupt_on_timeout=False,  # the grader interrupts, and gives up on a stuck kernel
        shutdown_kernel="immediate",
        log=quiet,
    )
    client.widget_registry = {}
    return client


def _error_text(cell) -> str | None:
    for out in cell.get("outputs", []):
        if out.get("output_type") == "error":
            return f"{out.get('ename', 'Error')}: {out.get('evalue', '')}".strip().rstrip(":")
    return None


def _signal_kernel(km, what):
    """Interrupt (``"interrupt"``) or kill (``"kill"``) a kernel; from the watchdog's thread."""
    import asyncio

    from nbclient.util import ensure_async

    async def call(fn, **kw):
        return await ensure_async(fn(**kw))

    try:
        if what == "interrupt":
            asyncio.run(call(km.interrupt_kernel))
            return
        process = getattr(getattr(km, "provisioner", None), "process", None)
        if process is not None:
            process.kill()
        else:
            asyncio.run(call(km.shutdown_kernel, now=True))
    except Exception:  # noqa: BLE001 - the kernel is gone already
        pass


def _execute(client, cell, index, timeout, *, history=True):
    """Run one cell: ``("ok" | "error" | "timeout" | "stuck" | "dead", error text)``.

    A watchdog thread interrupts the kernel when the cell runs past ``timeout`` seconds (the cell
    then ends with a KeyboardInterrupt, and nbclient's bookkeeping stays in step: its own
    timeout leaves a task behind that steals later cells' messages), and kills the kernel when
    the cell has not stopped :data:`INTERRUPT_GRACE` seconds later (``"stuck"``).
    """
    import threading

    from nbclient.exceptions import CellTimeoutError, DeadKernelError

    finished, lock, state = threading.Event(), threading.Lock(), {"done": False, "fired": None}

    def watchdog():
        for wait, action, name in (
            (timeout, "interrupt", "timeout"),
            (INTERRUPT_GRACE, "kill", "stuck"),
        ):
            if finished.wait(wait):
                return
            with lock:
                if state["done"]:
                    return
                state["fired"] = name
                _signal_kernel(client.km, action)

    thread = threading.Thread(target=watchdog, name="lagolib-grade-watchdog", daemon=True)
    client.timeout = math.ceil(timeout + INTERRUPT_GRACE + 60)  # a last resort only
    outcome = None
    thread.start()
    try:
        client.execute_cell(cell, index, store_history=history)
    except DeadKernelError:
        outcome = "dead"
    except CellTimeoutError:
        outcome = "stuck"
    finally:
        with lock:
            state["done"] = True
        finished.set()
        thread.join()
    if outcome == "stuck" or state["fired"] == "stuck":
        _signal_kernel(client.km, "kill")
        return "stuck", None
    if outcome == "dead":
        return "dead", None
    if state["fired"] == "timeout":
        return "timeout", None
    why = _error_text(cell)
    return ("error", why) if why else ("ok", None)


def _as_notebook(raw):
    """A submitted notebook (JSON dict) as an nbformat node nbclient runs: sources as strings,
    every code cell with its outputs list."""
    import nbformat

    nb = json.loads(json.dumps(raw))
    for cell in nb["cells"]:
        cell["source"] = _source(cell)
        cell.setdefault("metadata", {})
        if cell["cell_type"] == "code":
            cell["outputs"] = []
            cell.setdefault("execution_count", None)
    nb.setdefault("metadata", {})
    nb.setdefault("nbformat", 4)
    nb.setdefault("nbformat_minor", 5)
    return nbformat.from_dict(nb)


def _run_notebook(raw, plan, workdir, cell_timeout, notebook_timeout, env):
    """Run a submission cell by cell; after the cells in ``plan`` (``{cell index: [_Located]}``)
    write each exercise's answers into ``workdir``.  Returns ``{exercise: Path or _Result}``."""
    nb = _as_notebook(raw)
    kernel_dir = Path(workdir) / "kernel"
    answers_dir = Path(workdir) / "answers"
    kernel_dir.mkdir()
    answers_dir.mkdir()
    sockets = tempfile.mkdtemp(prefix="lagolib-kernel-") if os.name == "posix" else None
    client = _client(nb, sockets)
    out, outcomes = {}, {}  # outcomes: cell index -> (outcome, error text)
    stop = None
    try:
        with client.setup_kernel(
            env=env, cwd=str(kernel_dir), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        ):
            deadline = time.monotonic() + notebook_timeout
            budget = f"the notebook ran past its time limit of {notebook_timeout:g} s"
            for index, cell in enumerate(nb.cells):
                if cell.cell_type != "code":
                    continue
                left = deadline - time.monotonic()
                if left <= 0:
                    stop = f"{budget} before cell {index + 1}"
                    break
                outcome, why = _execute(client, cell, index, min(cell_timeout, left))
                outcomes[index] = (outcome, why)
                if outcome in ("stuck", "dead") or (
                    outcome == "timeout" and time.monotonic() >= deadline
                ):
                    stop = _stopped(outcome, index, cell_timeout, budget)
                    break
                for loc in plan.get(index, []):
                    out[loc.exercise.id], stop = _capture(
                        client, loc, index, outcomes, answers_dir, cell_timeout, deadline, budget
                    )
                    if stop:
                        break
                if stop:
                    break
    except Exception as exc:  # noqa: BLE001 - the kernel could not start (or the client broke)
        if type(exc).__name__ == "NoSuchKernel":
            raise LagolibError(
                f"grade: Jupyter has no {KERNEL!r} kernel to run the notebooks in; install "
                "ipykernel (pip install 'lagolib[book]')"
            ) from None
        stop = f"the grader's Jupyter kernel failed ({type(exc).__name__}: {exc})"
    finally:
        if sockets:
            shutil.rmtree(sockets, ignore_errors=True)
    for group in plan.values():
        for loc in group:
            if loc.exercise.id not in out:
                out[loc.exercise.id] = _Result(
                    "error", stop or "the notebook stopped before this exercise's answer"
                )
    return out


def _stopped(outcome, index, cell_timeout, budget) -> str:
    if outcome == "stuck":
        return (
            f"cell {index + 1} ran past its time limit of {cell_timeout:g} s and could not be "
            "interrupted, so the rest of the notebook was not run"
        )
    if outcome == "dead":
        return (
            f"the kernel died in cell {index + 1} (the notebook crashed Python or ran out of "
            "memory), so the rest of the notebook was not run"
        )
    return f"{budget} (in cell {index + 1})"


def _capture(client, loc, index, outcomes, answers_dir, cell_timeout, deadline, budget):
    """Read ``loc``'s answers in the kernel: ``(Path or _Result, stop)``."""
    from nbformat import v4

    ex = loc.exercise
    timed_out = [i for i in loc.answers if outcomes.get(i, ("",))[0] == "timeout"]
    if timed_out:
        return _Result(
            "error",
            f"the answer cell ran past its time limit of {cell_timeout:g} s and was interrupted "
            "(an endless loop?)",
        ), None
    target = answers_dir / f"answer-{ex.id}.pkl"
    args = "".join(f"{a}, " for a in ex.args)
    kwargs = ", ".join(f"{k!r}: {v}" for k, v in ex.kwargs)
    cell = v4.new_code_cell(_CAPTURE.format(args=args, kwargs=kwargs, path=str(target)))
    left = deadline - time.monotonic()
    if left <= 0:
        return _Result("error", budget), budget
    outcome, why = _execute(client, cell, index, min(cell_timeout, left), history=False)
    if outcome in ("stuck", "dead"):
        stop = _stopped(outcome, index, cell_timeout, budget)
        return _Result("error", stop), stop
    if outcome == "timeout":
        return _Result(
            "error", f"reading the answer ran past its time limit of {cell_timeout:g} s"
        ), None
    status_file = Path(f"{target}.status")
    status = status_file.read_text(encoding="utf-8") if status_file.is_file() else why
    if status == "ok":
        return target, None
    raised = [outcomes[i][1] for i in loc.answers if outcomes.get(i, ("",))[0] == "error"]
    if raised:
        return _Result("error", f"the answer cell raised {raised[0]}"), None
    names = ", ".join([*ex.args, *(v for _, v in ex.kwargs)])
    earlier = [
        (i, w) for i, (o, w) in sorted(outcomes.items()) if o == "error" and i < min(loc.answers)
    ]
    note = f" (cell {earlier[0][0] + 1} raised {earlier[0][1]})" if earlier else ""
    return _Result(
        "error",
        f"the check's answer ({names}) could not be taken from the notebook: "
        f"{status or 'nothing was written'}{note}",
    ), None


# ----------------------------------------------------------------------------- evaluating answers
class _CheckTimeout(BaseException):
    """Raised in the evaluating process when a check runs past its time limit (a BaseException:
    the checks turn every Exception a student's function raises into a "not yet")."""


def _identity(value, depth=0):
    """What must not change about ``value``: its identity, and a function's code, defaults and
    closure (a class's attributes, one level down)."""
    import types

    if isinstance(value, types.FunctionType):
        closure = []
        for cell in value.__closure__ or ():
            try:
                closure.append(id(cell.cell_contents))
            except ValueError:  # an empty cell
                closure.append(None)
        return (
            id(value),
            id(value.__code__),
            id(value.__defaults__),
            id(value.__kwdefaults__),
            id(getattr(value, "__wrapped__", None)),
            tuple(closure),
        )
    if isinstance(value, type) and depth == 0 and str(value.__module__).startswith("lagolib"):
        return (id(value), tuple((k, _identity(v, 1)) for k, v in sorted(vars(value).items())))
    wrapped = getattr(value, "__wrapped__", None) if callable(value) else None
    return (id(value), id(wrapped)) if wrapped is not None else id(value)


def _snapshot() -> dict:
    """``{name: identity}`` of every attribute of lagolib's modules, of numpy's top level and of
    Python's builtins."""
    import builtins

    snap = {}
    modules = [("builtins", builtins)]
    modules += [
        (n, m)
        for n, m in list(sys.modules.items())
        if n == "numpy" or n == "lagolib" or n.startswith("lagolib.")
    ]
    for name, module in modules:
        if module is None:
            continue
        for attr, value in list(vars(module).items()):
            snap[f"{name}.{attr}"] = _identity(value)
    return snap


def _changed(before, after) -> list[str]:
    """The names of ``before`` that ``after`` lacks or holds something else under (names added
    since — a module a check imported on first use — do not count)."""
    return [name for name, ident in before.items() if after.get(name) != ident]


def _evaluate_worker(tasks_path, results_path):
    """The evaluating process: run each task's pristine check, one JSON line per event."""
    import contextlib
    import importlib
    import signal

    import cloudpickle

    import lagolib.exercises

    lagolib.exercises.set_hints(False)
    tasks = json.loads(Path(tasks_path).read_text(encoding="utf-8"))
    for chapter in sorted({t["chapter"] for t in tasks}):
        importlib.import_module(f"lagolib.exercises.ch{chapter:02d}")
    snapshot, changed, dumps = _snapshot, _changed, json.dumps  # held before any answer is loaded
    results = open(results_path, "a", encoding="utf-8")  # noqa: SIM115 - kept to the end

    def record(**entry):
        results.write(dumps(entry) + "\n")
        results.flush()

    def alarm(signum, frame):
        raise _CheckTimeout

    timer = hasattr(signal, "setitimer")  # POSIX; elsewhere the grader's watchdog stops a hang
    if timer:
        signal.signal(signal.SIGALRM, alarm)
    initial = snapshot()
    for task in tasks:
        module = sys.modules[f"lagolib.exercises.ch{task['chapter']:02d}"]
        check = getattr(module, task["check"])
        before = snapshot()
        if changed(initial, before):  # changed after an earlier check ended (a thread of its
            results.close()  # answer's?): the grader runs the rest in a new process
            os._exit(4)
        record(id=task["id"], event="start")
        buffer = io.StringIO()
        try:
            if timer:  # again every second, should an answer swallow the first
                signal.setitimer(signal.ITIMER_REAL, task["timeout"], 1.0)
            try:
                with contextlib.redirect_stdout(buffer):
                    try:
                        args, kwargs = cloudpickle.loads(Path(task["answers"]).read_bytes())
                    except Exception as exc:  # noqa: BLE001
                        result = {
                            "error": f"the answer could not be carried to the check "
                            f"({type(exc).__name__}: {exc})"
                        }
                    else:
                        ok = check(*args, **kwargs)
                        result = {"ok": ok is True, "text": buffer.getvalue()[-20000:]}
            finally:
                if timer:
                    signal.setitimer(signal.ITIMER_REAL, 0)
        except _CheckTimeout:
            result = {
                "error": f"the check ran past its time limit of {task['timeout']:g} s with "
                "your answer (an endless loop in your function?)"
            }
        except BaseException as exc:  # noqa: BLE001 - SystemExit, KeyboardInterrupt from an answer
            result = {"error": f"your answer stopped the check ({type(exc).__name__}: {exc})"}
        names = changed(before, snapshot())
        if names:
            result = {
                "error": f"your answer changed lagolib's checks while they ran ({names[0]})",
                "tampered": True,
            }
        record(id=task["id"], event="done", **result)
        if names:  # this process can no longer be trusted: the grader starts another
            results.close()
            os._exit(3)
    results.close()


_WORKER = (
    "import sys; from lagolib.grading import _evaluate_worker; "
    "_evaluate_worker(sys.argv[1], sys.argv[2])"
)


def _events(path) -> list[dict]:
    if not path.is_file():
        return []
    text = path.read_text(encoding="utf-8", errors="replace")
    lines = text.split("\n")[:-1]  # a line is complete once its newline is written
    out = []
    for line in lines:
        try:
            out.append(json.loads(line))
        except ValueError:
            continue
    return out


def _evaluate(tasks, env) -> dict:
    """Run ``tasks`` (one notebook's answers) in fresh processes; ``{exercise: _Result}``."""
    out, pending, round_ = {}, list(tasks), 0
    timeouts = {t["id"]: t["timeout"] for t in tasks}
    with tempfile.TemporaryDirectory(prefix="lagolib-check-", ignore_cleanup_errors=True) as d:
        work = Path(d)
        while pending:
            round_ += 1
            tasks_path = work / f"tasks-{round_}.json"
            results_path = work / f"results-{round_}.jsonl"
            log_path = work / f"log-{round_}.txt"
            tasks_path.write_text(json.dumps(pending), encoding="utf-8")
            killed = None
            with open(log_path, "wb") as log:
                proc = subprocess.Popen(
                    [sys.executable, "-c", _WORKER, str(tasks_path), str(results_path)],
                    cwd=work,
                    env={**env, "PYTHONSAFEPATH": "1"},
                    stdin=subprocess.DEVNULL,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                )
                try:
                    startup = time.monotonic() + STARTUP_TIMEOUT
                    seen = {}  # id -> when its start was seen
                    while proc.poll() is None:
                        events = _events(results_path)
                        for e in events:
                            if e.get("event") == "start":
                                seen.setdefault(e["id"], time.monotonic())
                        finished = {e["id"] for e in events if e.get("event") == "done"}
                        running = [i for i in seen if i not in finished]
                        now = time.monotonic()
                        if running and now - seen[running[-1]] > timeouts[running[-1]] + 5:
                            killed = running[-1]
                        elif not seen and now > startup:
                            killed = ""
                        if killed is not None:
                            proc.kill()
                            break
                        time.sleep(0.05)
                finally:
                    if proc.poll() is None:
                        proc.kill()
                    proc.wait()
            events = _events(results_path)
            started = [e["id"] for e in events if e.get("event") == "start"]
            for e in events:
                if e.get("event") == "done":
                    out[e["id"]] = _verdict(e)
            for ex in started:
                if ex not in out:
                    out[ex] = _Result(
                        "error",
                        f"the check ran past its time limit of {timeouts[ex]:g} s with your "
                        "answer (an endless loop in your function?)"
                        if ex == killed
                        else "your answer ended the grader's process while the check ran "
                        f"(exit status {proc.returncode})",
                    )
            if not started:
                log = log_path.read_text(encoding="utf-8", errors="replace").strip()
                raise LagolibError(
                    "grade: the process that runs lagolib's checks failed before checking "
                    f"anything (exit status {proc.returncode}): {log[-2000:] or 'no output'}"
                )
            pending = [t for t in pending if t["id"] not in out]
    return out


def _verdict(event) -> _Result:
    if "error" in event:
        return _Result("error", event["error"])
    head = f"Exercise {event['id']} — "
    lines = [line for line in event["text"].splitlines() if line.startswith(head)]
    line = lines[-1][len(head) :] if lines else ""
    if event["ok"]:
        return _Result("correct", line.removeprefix("correct").lstrip(":. "))
    if line.startswith(_NOT_ATTEMPTED):
        return _Result("not attempted", "the answer is still the stub's placeholder (...)")
    if line.startswith("not yet:"):
        line = line[len("not yet:") :].strip()
    return _Result("not yet", line or "the check found the answer wrong")


# ----------------------------------------------------------------------------- one notebook
def _grade_notebook(sub, counted, book, cell_timeout, notebook_timeout, env) -> dict:
    """``{exercise: _Result}`` for the counted exercises of one submitted notebook."""
    results, located = {}, []
    try:
        nb = _read_notebook(sub.path)
    except (LagolibError, OSError) as exc:  # changed since it was first read
        return {
            ex.id: _Result("error", f"the notebook could not be read ({exc})") for ex in counted
        }
    ordinals = _answer_ordinals(nb)
    for ex in counted:
        loc = _locate(nb, ex, ordinals)
        if loc is None:
            results[ex.id] = _Result(
                "error",
                f"Exercise {ex.id}'s answer cell is missing from the notebook (deleted, or its "
                "statement cell lost)",
            )
        else:
            located.append(loc)
    if not located:
        return results
    if _code_sources(nb) == book.copies.get(sub.chapter):  # the copy as given: nothing to run
        for loc in located:
            results[loc.exercise.id] = _Result("not attempted", "the answer cell is the stub")
        return results
    plan = {}
    for loc in located:
        plan.setdefault(loc.after, []).append(loc)
    with tempfile.TemporaryDirectory(prefix="lagolib-grade-", ignore_cleanup_errors=True) as work:
        captured = _run_notebook(nb, plan, work, cell_timeout, notebook_timeout, env)
        tasks = []
        for loc in located:
            got = captured[loc.exercise.id]
            if isinstance(got, _Result):
                results[loc.exercise.id] = got
            else:
                ex = loc.exercise
                tasks.append(
                    {
                        "id": ex.id,
                        "chapter": ex.chapter,
                        "check": ex.check,
                        "answers": str(got),
                        "timeout": cell_timeout,
                    }
                )
        if tasks:
            results.update(_evaluate(tasks, env))
    for loc in located:  # an untouched stub whose answer could not be read: not attempted
        if loc.stub and results[loc.exercise.id].verdict == "error":
            results[loc.exercise.id] = _Result("not attempted", "the answer cell is the stub")
    return results


# ----------------------------------------------------------------------------- grading a class
def _seconds(value, from_file, default, name) -> float:
    if value is None:
        return from_file if from_file is not None else default
    if not _is_number(value) or value <= 0:
        raise OptionError(f"grade: {name}={value!r}; give a positive number of seconds")
    return float(value)


def _require_tools():
    missing = []
    for module in ("nbclient", "nbformat", "cloudpickle"):
        try:
            __import__(module)
        except ModuleNotFoundError:
            missing.append(module)
    if missing:
        raise LagolibError(
            f"grade: grading needs {', '.join(missing)}, which this Python lacks; "
            "pip install 'lagolib[book]'"
        )


def _num(x) -> str:
    return f"{x:g}"


def _one_line(text: str, limit=400) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _timed(sub, exercises_, book, cell_timeout, notebook_timeout, env):
    started = time.monotonic()
    got = _grade_notebook(sub, exercises_, book, cell_timeout, notebook_timeout, env)
    return got, time.monotonic() - started


def _run_all(work, book, cell_timeout, notebook_timeout, env, jobs):
    """Grade the notebooks of ``work``, ``jobs`` at a time; yield ``(item, results, seconds)``
    in ``work``'s order."""
    args = [
        (sub, [book.exercises[e] for e in mine], book, cell_timeout, notebook_timeout, env)
        for _, _, sub, mine in work
    ]
    if jobs == 1 or len(work) < 2:
        for item, a in zip(work, args):
            yield (item, *_timed(*a))
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    context = multiprocessing.get_context("spawn")  # no fork of a process with threads
    with ProcessPoolExecutor(max_workers=min(jobs, len(work)), mp_context=context) as pool:
        futures = [pool.submit(_timed, *a) for a in args]
        for item, future in zip(work, futures):
            yield (item, *future.result())


def grade(
    submissions,
    *,
    assignment=None,
    output="gradebook.csv",
    feedback_dir=None,
    book=None,
    cell_timeout=None,
    notebook_timeout=None,
    force=False,
    env=None,
    jobs=1,
    progress=None,
) -> Gradebook:
    """Grade a class's notebooks; write the gradebook (CSV) and one feedback file per student.

    See the module's docstring for the folders, the assignment file, what runs where and what
    the verdicts mean.

    Parameters
    ----------
    submissions : path or sequence of paths
        Notebooks, or folders of them (a class's folder: one folder per student).
    assignment : path, optional
        The assignment file (TOML): which exercises count, their points, time limits.  Without
        one, every exercise of every chapter handed in counts one point.
    output : path or None
        The gradebook to write; None writes nothing (the rows are returned).
    feedback_dir : path, optional
        The folder of the feedback files; default ``<output's stem>-feedback`` beside the
        gradebook.
    book : path, optional
        The grader's copy of the chapters (which check and which answers each exercise has);
        default the book this lagolib installed (:func:`lagolib.book.book_dir`).
    cell_timeout, notebook_timeout : float, optional
        Seconds a cell (and a check of one answer) and a whole notebook may run; default the
        assignment's, else :data:`CELL_TIMEOUT` (60) and :data:`NOTEBOOK_TIMEOUT` (600).
    force : bool
        Overwrite an existing gradebook or feedback file.
    env : mapping, optional
        The environment of the notebooks' kernels and of the checks (default this process's),
        e.g. with ``LAGOLIB_DATA`` or ``LAGOLIB_OFFLINE=1``.
    jobs : int
        How many notebooks run at once (each in a process of its own, with its kernel); default
        1.  More than the machine's cores makes the time limits harder to meet.
    progress : callable, optional
        Called with one line of text per notebook as it is graded (the command line prints them).

    Returns
    -------
    Gradebook

    Raises
    ------
    OptionError
        A submission that does not exist or is not a notebook, no notebooks at all, a bad
        assignment file (or :class:`~lagolib.errors.ParseError`), a time limit that is not a
        positive number, nothing to grade, or (without ``force``) output files that exist —
        named; nothing is written.
    LagolibError
        Grading's tools are missing (nbclient, cloudpickle: ``pip install 'lagolib[book]'``),
        Jupyter has no ``python3`` kernel, or the process running the checks cannot start.
    """
    check_bool(force, "force", "grade")
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise OptionError(f"grade: jobs={jobs!r}; give a whole number of notebooks, 1 or more")
    if isinstance(submissions, (str, os.PathLike)):
        submissions = [submissions]
    submissions = list(submissions)
    if not submissions:
        raise OptionError("grade: submissions is empty; give notebooks, or folders of them")
    if output is not None:
        output = Path(output)
        feedback = (
            Path(feedback_dir)
            if feedback_dir is not None
            else output.with_name(f"{output.stem}-feedback")
        )
    found, students = _collect(submissions, exclude=feedback if output is not None else None)
    book_ = _read_book(book_dir_or_default(book))
    spec = read_assignment(assignment, book_.exercises) if assignment is not None else Assignment()
    cell_timeout = _seconds(cell_timeout, spec.cell_timeout, CELL_TIMEOUT, "cell_timeout")
    notebook_timeout = _seconds(
        notebook_timeout, spec.notebook_timeout, NOTEBOOK_TIMEOUT, "notebook_timeout"
    )
    _require_tools()
    subs = [_identify(student, path) for student, path in found]
    if spec.points is not None:
        points = dict(spec.points)
    else:
        chapters = {s.chapter for s in subs if s.chapter is not None}
        points = {e: 1.0 for e, x in book_.exercises.items() if x.chapter in chapters}
        if not points:
            why = "; ".join(f"{s.path}: {s.problem}" for s in subs if s.problem)
            raise OptionError(
                f"grade: none of the notebooks is a chapter of the book with exercises ({why}); "
                "nothing to grade"
            )
    counted = sorted(points, key=_order)
    chapters = sorted({book_.exercises[e].chapter for e in counted})

    targets = []
    if output is not None:
        targets = [output] + [feedback / f"{s}.md" for s in sorted(students)]
        existing = [str(t) for t in targets if t.exists()]
        if existing and not force:
            raise OptionError(
                f"grade: {len(existing)} output file(s) already exist: {', '.join(existing)}; "
                "nothing was written.  Pass force=True to overwrite them, or choose another output"
            )
        for t in targets:
            if t.is_dir():
                raise OptionError(f"grade: {t} is a folder; the file cannot go there")

    env = _kernel_env(env)
    results, notes = {}, {s: [] for s in students}  # (student, exercise) -> _Result
    by_chapter = {}
    for sub in subs:
        if sub.problem:
            notes[sub.student].append(f"`{sub.path.name}` was not graded: it {sub.problem}.")
        elif sub.chapter not in chapters:
            notes[sub.student].append(
                f"`{sub.path.name}` is chapter {sub.chapter}, which this assignment does not "
                "include: it was not graded."
            )
        else:
            by_chapter.setdefault((sub.student, sub.chapter), []).append(sub)
    work = []  # (student, chapter, submission, exercises): the notebooks to run
    for student in sorted(students):
        for chapter in chapters:
            mine = [e for e in counted if book_.exercises[e].chapter == chapter]
            handed = by_chapter.get((student, chapter), [])
            if len(handed) == 1:
                work.append((student, chapter, handed[0], mine))
                continue
            if handed:
                names = ", ".join(f"`{s.path.name}`" for s in handed)
                why, verdict = (
                    f"{len(handed)} notebooks of chapter {chapter} were handed in ({names}); "
                    "hand in one (none was graded)",
                    "error",
                )
            else:
                others = [
                    s.path.name
                    for s in subs
                    if s.student == student and (s.problem or s.chapter not in chapters)
                ]
                why, verdict = f"no notebook of chapter {chapter} was handed in", "not attempted"
                if others:
                    why += "; handed in instead: " + ", ".join(f"`{n}`" for n in others)
                    verdict = "error"
            for e in mine:
                results[(student, e)] = _Result(verdict, why)
    for (student, chapter, sub, mine), got, seconds in _run_all(
        work, book_, cell_timeout, notebook_timeout, env, jobs
    ):
        for e in mine:
            results[(student, e)] = got[e]
        if progress is not None:
            tally = ", ".join(
                f"{sum(r.verdict == v for r in got.values())} {v}"
                for v in VERDICTS
                if any(r.verdict == v for r in got.values())
            )
            progress(f"{student}: {sub.path.name} (chapter {chapter}): {tally} ({seconds:.1f} s)")

    rows, messages, texts = [], {}, {}
    possible = sum(points[e] for e in counted)
    for student in sorted(students):
        lines, total = [], 0.0
        for e in counted:
            r = results[(student, e)]
            earned = points[e] if r.verdict == "correct" else 0.0
            total += earned
            rows.append(
                {
                    "student": student,
                    "chapter": str(book_.exercises[e].chapter),
                    "exercise": e,
                    "verdict": r.verdict,
                    "points": _num(earned),
                }
            )
            messages[(student, e)] = r.message
            why = "" if r.verdict == "correct" or not r.message else f": {_one_line(r.message)}"
            lines.append(
                f"- **Exercise {e}** — {r.verdict} ({_num(earned)} of {_num(points[e])} "
                f"point{'' if points[e] == 1 else 's'}){why}"
            )
        title = f"{spec.title} — " if spec.title else ""
        text = f"# {title}feedback for {student}\n\n" + "\n".join(lines) + "\n"
        if notes[student]:
            text += "\n" + "\n".join(f"- {n}" for n in notes[student]) + "\n"
        text += f"\n**Total: {_num(total)} of {_num(possible)} points.**\n"
        texts[student] = text
    out = Gradebook(rows=rows, messages=messages, feedback=texts)
    if output is None:
        return out
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    output.parent.mkdir(parents=True, exist_ok=True)
    feedback.mkdir(parents=True, exist_ok=True)
    with atomic_write(output, "w", encoding="utf-8", newline="") as f:
        f.write(buffer.getvalue())
    out.path = output
    for student, text in texts.items():
        path = feedback / f"{student}.md"
        with atomic_write(path, "w", encoding="utf-8") as f:
            f.write(text)
        out.feedback_paths.append(path)
    return out


# ----------------------------------------------------------------------------- command line
def main(argv=None) -> int:
    """``lagolib book grade SUBMISSIONS... -o GRADEBOOK.csv [options]``: exit status 0 when the
    class was graded (wrong answers included), 2 for misuse, 1 for another problem."""
    parser = argparse.ArgumentParser(
        prog="lagolib book grade",
        description="Run a class's notebooks and grade every exercise with lagolib's own checks "
        "(see python -c 'import lagolib.grading; help(lagolib.grading)').",
    )
    parser.add_argument(
        "submissions",
        nargs="+",
        metavar="SUBMISSION",
        help="notebooks, or folders of them (one folder per student)",
    )
    parser.add_argument(
        "-o", "--output", required=True, metavar="GRADEBOOK.csv", help="the gradebook to write"
    )
    parser.add_argument(
        "--assignment",
        metavar="FILE.toml",
        help="the assignment file (TOML): which exercises count, their points",
    )
    parser.add_argument(
        "--feedback",
        metavar="DIR",
        help="folder of the feedback files (default: <gradebook>-feedback)",
    )
    parser.add_argument(
        "--book", metavar="DIR", help="the grader's chapters (default: the installed book)"
    )
    parser.add_argument(
        "--cell-timeout",
        type=float,
        metavar="S",
        help=f"seconds per cell (default {CELL_TIMEOUT:g})",
    )
    parser.add_argument(
        "--notebook-timeout",
        type=float,
        metavar="S",
        help=f"seconds per notebook (default {NOTEBOOK_TIMEOUT:g})",
    )
    parser.add_argument(
        "-j",
        "--jobs",
        type=int,
        default=1,
        metavar="N",
        help="notebooks graded at once (default 1)",
    )
    parser.add_argument("--force", action="store_true", help="overwrite existing output files")
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2, already printed)
        return int(exc.code or 0)

    def say(line):
        print(line, file=sys.stderr, flush=True)

    try:
        result = grade(
            args.submissions,
            assignment=args.assignment,
            output=args.output,
            feedback_dir=args.feedback,
            book=args.book,
            cell_timeout=args.cell_timeout,
            notebook_timeout=args.notebook_timeout,
            force=args.force,
            jobs=args.jobs,
            progress=say,
        )
    except (LagolibError, OSError) as exc:
        text = str(exc).replace("Pass force=True", "Pass --force")
        if not text.startswith("grade: "):
            text = f"grade: {text}"
        print(f"lagolib book {text}", file=sys.stderr)
        return 2 if isinstance(exc, OptionError) else 1
    counts = ", ".join(f"{sum(r['verdict'] == v for r in result.rows)} {v}" for v in VERDICTS)
    students = len({r["student"] for r in result.rows})
    print(
        f"graded {students} students: {counts}; wrote {result.path} and "
        f"{len(result.feedback_paths)} feedback files in {result.feedback_paths[0].parent}"
        if result.feedback_paths
        else f"graded {students} students: {counts}; wrote {result.path}"
    )
    return 0
