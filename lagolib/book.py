"""The book's classroom conventions, the book an installation holds, and student copies.

Usage::

    lagolib book write OUTDIR [--book BOOKDIR] [--force]
    lagolib book student-copies OUTDIR [--book BOOKDIR] [--no-hints] [--force]
    lagolib book grade SUBMISSIONS... -o gradebook.csv [--assignment FILE]   (lagolib.grading)

(``python -m lagolib.book`` runs the first two.)  Every installation of lagolib holds the book:
a wheel carries the chapters, their table of contents and the site's configuration as
``lagolib/_book`` (the data they need is lagolib's own ``_data`` and its downloads), a clone has
them in ``book/`` (:func:`book_dir`).  ``write`` copies the full book, solutions included, into
``OUTDIR``; ``student-copies`` writes every chapter of ``BOOKDIR`` (default: the installed book)
into ``OUTDIR`` with each solution replaced by its stub and every output stripped.  A student copy
runs to the end; every check in it reports "not attempted yet" until the student fills the stubs
in.  With ``--no-hints`` the checks still say what is wrong and by how much, but give no hints.

Nothing a student wrote is lost: every chapter is read and checked before any copy is written (a
chapter that is not a notebook is named, and nothing is written); a notebook already in
``OUTDIR`` that differs from the copy that would replace it (a student's filled-in work, say) is
not overwritten unless ``--force`` is given — the message names the files; one identical to its
copy is left as it is.  Each copy is written to a temporary file and moved into place, so an
interrupted run leaves every notebook either as it was or whole.

An exercise in a chapter is a run of cells (the JSON is plain nbformat 4):

1. **the statement** — a markdown cell starting ``**Exercise 6.2 (implement).**``, with cell
   metadata ``{"lagolib": {"exercise": "6.2", "kind": "implement"}}``; ``kind`` is one of
   :data:`KINDS`: ``implement`` a step, ``predict`` then check, ``explore`` by changing something,
   ``derive`` a formula (entered as a sympy expression or a string sympy parses);
2. **the solution** — a code cell tagged ``solution`` (and ``hide-cell``, so the rendered book
   folds it), whose metadata ``{"lagolib": {"stub": "..."}}`` holds the stub the student starts
   from: the same names, ``# your code here``, and the placeholder ``...`` where the answer goes;
3. **the check** — a code cell calling ``chNN.check_…(answer)`` from :mod:`lagolib.exercises`;
4. **the assertion** — a code cell tagged ``remove-cell`` and ``solution-check``, its source
   :func:`solution_check_source` (``with bookkeeping("6.2"): assert passed("6.2")``), so a full
   chapter fails its test when a solution stops being correct (the book's tests set
   ``LAGOLIB_BOOK_STRICT``; a reader's "Run All" goes on); hidden from the rendered book,
   collapsed in JupyterLab, dropped from student copies;
5. **the discussion** — a markdown cell tagged ``solution`` that starts with
   ``<details><summary>Solution and discussion</summary>`` and ends with ``</details>`` (folded in
   JupyterLab and in the rendered book alike); in a student copy it becomes a place for the
   student's own answer.

Cells after an exercise never use names that only its solution defines, so that the student copy
runs to the end.
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
from pathlib import Path

from .checks import check_bool
from .errors import LagolibError, OptionError, ParseError
from .files import atomic_write

__all__ = [
    "KINDS",
    "BASIC_KINDS",
    "SOLUTION_TAG",
    "solution_check_source",
    "CHECK_TAG",
    "DISCUSSION_STUB",
    "book_dir",
    "exercises",
    "student_copy",
    "inject_solutions",
    "write_book",
    "write_student_copies",
    "main",
]

KINDS = ("implement", "predict", "explore", "derive")
BASIC_KINDS = KINDS[:3]  # every chapter with exercises has one of each; derive where the sources derive
SOLUTION_TAG = "solution"
CHECK_TAG = "solution-check"
HIDE_TAGS = ("hide-cell", "hide-input", "hide-output")
STUB_MARK = "# your code here"
DISCUSSION_STUB = (
    "**Your answer and discussion.** *Write here what you found, and why — then compare with a "
    "classmate's.*"
)


def book_dir() -> Path:
    """The folder of the book's chapters that this installation of lagolib holds.

    A wheel carries the chapters (and what they need) as ``lagolib/_book``; a clone with an
    editable install has them in ``book/`` beside the package.

    Raises
    ------
    OptionError
        If neither holds the preface (a broken installation): reinstall lagolib.
    """
    here = Path(__file__).resolve().parent
    for candidate in (here / "_book", here.parent / "book"):
        if (candidate / "00_preface.ipynb").is_file():
            return candidate
    raise OptionError(
        f"lagolib's book is missing from this installation (looked in {here / '_book'} and "
        f"{here.parent / 'book'}); reinstall lagolib (pip install --force-reinstall lagolib)"
    )


def solution_check_source(exercise: str) -> str:
    """The source of exercise ``exercise``'s hidden assertion cell (convention 4 above).

    >>> print(solution_check_source("6.2"))
    from lagolib.exercises import bookkeeping, passed  # noqa: F811
    <BLANKLINE>
    with bookkeeping("6.2"):  # the book's own check: strict in its tests, quiet for a reader
        assert passed("6.2")
    """
    return (
        "from lagolib.exercises import bookkeeping, passed  # noqa: F811\n\n"
        f'with bookkeeping("{exercise}"):  # the book\'s own check: strict in its tests, quiet '
        f'for a reader\n    assert passed("{exercise}")'
    )


def _tags(cell) -> list[str]:
    return list(cell.get("metadata", {}).get("tags", []))


def _source(cell) -> str:
    src = cell.get("source", "")
    return "".join(src) if isinstance(src, list) else src


def _where(path, index) -> str:
    return f"{path}: cell {index}" if path else f"cell {index}"


_CELL_TYPES = ("code", "markdown", "raw")


def _json_type(value) -> str:
    """The JSON name of a parsed value's type (for messages)."""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    for kind, name in ((dict, "object"), (list, "list"), (str, "string")):
        if isinstance(value, kind):
            return name
    return "number"


def _check_notebook(nb, path=None) -> None:
    """Raise ParseError (naming ``path`` and the cell) unless ``nb`` has the nbformat-4 structure
    the functions of this module rely on: an object whose ``cells`` is a list of objects, each
    with a ``cell_type`` (code, markdown or raw), a string or list-of-strings ``source``, and
    object ``metadata`` whose ``tags`` are strings and whose ``lagolib`` entry is an object."""
    where = path or "notebook"
    hint = "; is it a Jupyter notebook (nbformat 4)?"

    def fail(message):
        raise ParseError(where, None, message + hint)

    if not isinstance(nb, dict):
        fail(f"the file holds a JSON {_json_type(nb)}, not a notebook object")
    if not isinstance(nb.get("cells"), list):
        got = "none" if "cells" not in nb else f"a JSON {_json_type(nb['cells'])}"
        fail(f"the notebook has no list of cells ('cells' is {got})")
    if not isinstance(nb.get("metadata", {}), dict):
        fail(f"the notebook's metadata is a JSON {_json_type(nb['metadata'])}, not an object")
    for k, cell in enumerate(nb["cells"]):
        if not isinstance(cell, dict):
            fail(f"cell {k} is a JSON {_json_type(cell)}, not an object")
        if "cell_type" not in cell:
            fail(f"cell {k} has no cell_type")
        if cell["cell_type"] not in _CELL_TYPES:
            fail(f"cell {k} has cell_type {cell['cell_type']!r}, not one of {_CELL_TYPES}")
        source = cell.get("source", "")
        if not isinstance(source, str) and not (
            isinstance(source, list) and all(isinstance(line, str) for line in source)
        ):
            fail(f"cell {k}'s source is neither a string nor a list of strings")
        meta = cell.get("metadata", {})
        if not isinstance(meta, dict):
            fail(f"cell {k}'s metadata is a JSON {_json_type(meta)}, not an object")
        tags = meta.get("tags", [])
        if not isinstance(tags, list) or not all(isinstance(t, str) for t in tags):
            fail(f"cell {k}'s metadata.tags is not a list of strings")
        if not isinstance(meta.get("lagolib", {}), dict):
            fail(
                f"cell {k}'s metadata.lagolib is a JSON {_json_type(meta['lagolib'])}, not an object"
            )


def _reject_constant(name):
    raise ValueError(f"{name} is not JSON")


def _read_notebook(path) -> dict:
    """Read and check a chapter: a UTF-8 JSON notebook (nbformat 4), as a dict.

    Raises
    ------
    ParseError
        Naming the file (and the line, where there is one): not UTF-8 text, not JSON (``NaN``
        included), not valid Unicode, or not a notebook (:func:`_check_notebook`: no list of
        cells, a cell without ``cell_type``, ...).
    """
    data = Path(path).read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise ParseError(
            path,
            line,
            f"not UTF-8 text (byte 0x{data[exc.start]:02x}); a notebook is UTF-8 JSON — save it "
            "as UTF-8 (Jupyter does)",
        ) from None
    try:
        nb = json.loads(text.removeprefix("\ufeff"), parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise ParseError(path, exc.lineno, f"not JSON: {exc.msg} (column {exc.colno})") from None
    except (ValueError, RecursionError) as exc:
        raise ParseError(path, None, f"not JSON: {exc}") from None
    _check_notebook(nb, str(path))
    return nb


def exercises(nb: dict, path: str | None = None) -> list[dict]:
    """The exercises of a notebook (a JSON dict): ``[{"id", "kind", "cell"}, …]`` in order.

    Raises :class:`~lagolib.errors.OptionError` naming the cell when an exercise's metadata is
    malformed (no id, or a kind outside :data:`KINDS`).
    """
    _check_notebook(nb, path)
    out = []
    for k, cell in enumerate(nb["cells"]):
        meta = cell.get("metadata", {}).get("lagolib", {})
        if "exercise" not in meta:
            continue
        kind = meta.get("kind")
        if kind not in KINDS:
            raise OptionError(
                f"{_where(path, k)}: exercise {meta['exercise']!r} has kind {kind!r}; "
                f"set metadata lagolib.kind to one of {KINDS}"
            )
        out.append({"id": str(meta["exercise"]), "kind": kind, "cell": k})
    return out


def _stub_cell(cell: dict, ordinal: int, path, index) -> dict:
    stub = copy.deepcopy(cell)
    meta = stub.setdefault("metadata", {})
    lag = meta.setdefault("lagolib", {})
    meta["tags"] = [t for t in _tags(cell) if t != SOLUTION_TAG and t not in HIDE_TAGS]
    if not meta["tags"]:
        del meta["tags"]
    meta.pop("jupyter", None)  # source_hidden / outputs_hidden
    if cell["cell_type"] == "code":
        text = lag.pop("stub", None)
        if not isinstance(text, str) or STUB_MARK not in text:
            raise OptionError(
                f"{_where(path, index)}: a solution code cell needs metadata lagolib.stub, the "
                f"code the student starts from, containing {STUB_MARK!r} and the placeholder ..."
            )
        stub["source"] = text
        stub["outputs"] = []
        stub["execution_count"] = None
    else:
        stub["source"] = lag.pop("stub", DISCUSSION_STUB)
    lag["solution"] = ordinal  # which solution this stub stands for (inject_solutions)
    return stub


NO_HINTS_SOURCE = (
    "from lagolib.exercises import set_hints\n\n"
    "set_hints(False)  # this copy's checks say what is wrong, without hints (your instructor's choice)"
)


def student_copy(nb: dict, path: str | None = None, *, hints: bool = True) -> dict:
    """A student's copy of a chapter (JSON dict in, new dict out; ``nb`` is not modified).

    Solution cells become their stubs, ``solution-check`` cells are dropped, every output and
    execution count is cleared, and ``metadata.lagolib.student_copy`` is set.  With
    ``hints=False`` a code cell calling ``set_hints(False)`` goes before the chapter's first code
    cell (and ``metadata.lagolib.hints`` is False): the checks still diagnose a wrong answer, but
    ``hint("6.2")`` offers nothing.

    Raises
    ------
    ParseError
        If ``nb`` is not a notebook (:func:`_check_notebook`), naming ``path``.
    OptionError
        For a solution code cell without its stub, naming the cell.
    """
    _check_notebook(nb, path)
    check_bool(hints, "hints", "student_copy")
    out = copy.deepcopy(nb)
    cells, ordinal = [], 0
    for k, cell in enumerate(nb.get("cells", [])):
        tags = _tags(cell)
        if CHECK_TAG in tags:
            continue
        if SOLUTION_TAG in tags:
            cells.append(_stub_cell(cell, ordinal, path, k))
            ordinal += 1
            continue
        cell = copy.deepcopy(cell)
        if cell["cell_type"] == "code":
            cell["outputs"] = []
            cell["execution_count"] = None
        cells.append(cell)
    meta = out.setdefault("metadata", {}).setdefault("lagolib", {})
    meta["student_copy"] = True
    if not hints:
        first = next((k for k, c in enumerate(cells) if c["cell_type"] == "code"), len(cells))
        cells.insert(
            first,
            {
                "cell_type": "code",
                "execution_count": None,
                "id": "lagolib-no-hints",
                "metadata": {"lagolib": {"no_hints": True}},
                "outputs": [],
                "source": NO_HINTS_SOURCE,
            },
        )
        meta["hints"] = False
    out["cells"] = cells
    return out


def inject_solutions(student: dict, full: dict) -> dict:
    """Put ``full``'s solutions back into a student copy (the ``solution-check`` cells stay out).

    The result, executed, is the student copy of someone who solved everything; every check in it
    reports correct.
    """
    solutions = [copy.deepcopy(c) for c in full.get("cells", []) if SOLUTION_TAG in _tags(c)]
    out = copy.deepcopy(student)
    cells = []
    for cell in out.get("cells", []):
        k = cell.get("metadata", {}).get("lagolib", {}).get("solution")
        if k is None:
            cells.append(cell)
        elif not 0 <= k < len(solutions):
            raise OptionError(
                f"the student copy's stub {k} has no solution in the full notebook "
                f"({len(solutions)} solution cells): was the copy made from another chapter?"
            )
        else:
            cells.append(solutions[k])
    out["cells"] = cells
    out["metadata"].get("lagolib", {}).pop("student_copy", None)
    return out


#: What the book's folder holds that is not the book: builds, maintainers' scripts, the test
#: harness, editor state.
NOT_THE_BOOK = ("_build", "_scripts", "conftest.py", ".ipynb_checkpoints", "__pycache__", ".pytest_cache")


def _book_files(book_dir: Path) -> list[Path]:
    """Every file of the book (chapters, table of contents, configuration, static files, the
    site's extension), relative to ``book_dir``, without :data:`NOT_THE_BOOK`."""
    out = []
    for path in sorted(book_dir.rglob("*")):
        rel = path.relative_to(book_dir)
        if path.is_file() and not any(part in NOT_THE_BOOK for part in rel.parts):
            out.append(rel)
    return out


def _encode(nb: dict, path) -> bytes:
    text = json.dumps(nb, indent=1, ensure_ascii=False) + "\n"
    try:
        return text.encode("utf-8")
    except UnicodeEncodeError as exc:  # a lone surrogate, from a \ud800 escape
        bad = exc.object[exc.start : exc.end]
        raise ParseError(
            path, None, f"holds text that is not valid Unicode ({exc.reason}: {bad!a})"
        ) from None


def _plan(book_dir, out_dir, force, where, *, student, hints=True):
    """``[(target, bytes, unchanged)]``: every chapter's student copy (``student=True``) or every
    file of the book; reads and checks everything, writes nothing.  Raises before anything is
    written (see :func:`write_student_copies`, :func:`write_book`)."""
    book_dir = book_dir_or_default(book_dir)
    out_dir = Path(out_dir)
    chapters = sorted(book_dir.glob("*.ipynb"))
    if not chapters:
        raise OptionError(
            f"{where}: book_dir={str(book_dir)!r} holds no chapters (*.ipynb); "
            "pass the book's folder, or leave it out for the book this lagolib installed"
        )
    if out_dir.exists() and not out_dir.is_dir():
        raise OptionError(f"{where}: out_dir={str(out_dir)!r} is a file, not a folder")
    if out_dir.resolve() == book_dir.resolve():
        raise OptionError(
            f"{where}: out_dir is the book itself; choose another folder so the "
            "solutions are not overwritten"
        )
    plan = []
    for path in chapters:  # every chapter is read and checked before anything is written
        nb = _read_notebook(path)
        exercises(nb, str(path))
        if student:
            plan.append((out_dir / path.name, _encode(student_copy(nb, str(path), hints=hints), path)))
    if not student:
        plan = [(out_dir / rel, (book_dir / rel).read_bytes()) for rel in _book_files(book_dir)]
    out, differ = [], []
    for target, data in plan:
        if target.is_dir():
            raise OptionError(f"{where}: {target} is a folder; the file cannot go there")
        unchanged = target.is_file() and target.read_bytes() == data
        if target.exists() and not unchanged:
            differ.append(str(target.relative_to(out_dir)))
        out.append((target, data, unchanged))
    if differ and not force:
        what = "student copies" if student else "book's files"
        files = "notebook(s)" if student else "file(s)"
        raise OptionError(
            f"{where}: {out_dir} already holds {len(differ)} {files} that differ from the "
            f"{what} that would replace them (a student's work?): {', '.join(differ)}; "
            "nothing was written.  Pass force=True to overwrite them, or choose another folder"
        )
    return out


def book_dir_or_default(folder=None) -> Path:
    """``folder`` as a Path, or the installed book (:func:`book_dir`) when it is None."""
    return book_dir() if folder is None else Path(folder)


def write_student_copies(book_dir=None, out_dir=None, *, force=False, hints=True) -> list[Path]:
    """Write the student copy of every chapter (``*.ipynb``) of ``book_dir`` into ``out_dir``.

    Every chapter is read and checked, and every student copy made, before any file is written.

    Parameters
    ----------
    book_dir : str or os.PathLike, optional
        The book's folder; by default the book this installation of lagolib holds
        (:func:`book_dir`: a wheel's ``lagolib/_book``, or a clone's ``book/``).
    out_dir : str or os.PathLike
        The folder to write into (created if needed).
    force : bool
        Overwrite notebooks in ``out_dir`` that differ from their student copies.  Without it,
        such a notebook is an error and nothing is written; one identical to its copy is left
        as it is.
    hints : bool
        False writes copies whose checks give no hints (:func:`student_copy`).

    Returns
    -------
    list of Path
        The student copies, one per chapter, in the book's order.

    Raises
    ------
    ParseError
        A chapter is not a notebook (not UTF-8, not JSON, no list of cells, a cell without
        ``cell_type``, ...): the message names the file; nothing is written.
    OptionError
        No chapters in ``book_dir``; ``out_dir`` missing, the book, or a file; an exercise without
        its stub or kind; or (without ``force``) notebooks in ``out_dir`` that differ from their
        copies — the message names them.  Nothing is written.
    """
    done = _write(book_dir, out_dir, force, "write_student_copies", student=True, hints=hints)
    return [target for target, _ in done]


def write_book(out_dir, *, book_dir=None, force=False) -> list[Path]:
    """Write the full book — chapters with their solutions, the table of contents, the site's
    configuration and static files — into ``out_dir``, from this installation of lagolib.

    The same promises as :func:`write_student_copies`: everything is read before anything is
    written, a file in ``out_dir`` that differs from the book's is kept unless ``force``, each
    file is written to a temporary file and moved into place.

    Returns
    -------
    list of Path
        Every file of the book in ``out_dir``.
    """
    return [t for t, _ in _write(book_dir, out_dir, force, "write_book", student=False)]


def _write(book_dir, out_dir, force, where, *, student, hints=True):
    """Write what :func:`_plan` planned; ``[(target, written)]``."""
    check_bool(force, "force", where)
    check_bool(hints, "hints", where)
    if out_dir is None:
        raise OptionError(f"{where}: out_dir is required: the folder to write into")
    plan = _plan(book_dir, out_dir, force, where, student=student, hints=hints)
    done = []
    for target, data, unchanged in plan:
        if not unchanged:
            target.parent.mkdir(parents=True, exist_ok=True)
            with atomic_write(target, "wb") as f:
                f.write(data)
        done.append((target, not unchanged))
    return done


def _report(done, outdir, student):
    notebooks = [p for p, _ in done if p.suffix == ".ipynb"]
    n = sum(len(exercises(_read_notebook(p))) for p in notebooks)
    written = sum(w for _, w in done)
    what = "student copies of" if student else "the book:"
    if written == len(done):
        print(f"wrote {what} {len(notebooks)} chapters with {n} exercises to {outdir}")
    else:
        unit = "chapters" if student else "files of the book"
        print(
            f"wrote {written} of {len(done)} {unit} to {outdir} ({len(done) - written} already "
            f"up to date); {n} exercises"
        )
    print(
        f"next: jupyter lab {Path(outdir) / '00_preface.ipynb'}   (JupyterLab and the "
        "chapters' needs: pip install 'lagolib[book]')"
    )


def main(argv=None) -> int:
    """``lagolib book student-copies OUTDIR`` and ``lagolib book write OUTDIR``."""
    parser = argparse.ArgumentParser(
        prog="lagolib book", description="Tools for the lagolib book's chapters."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    sc = sub.add_parser(
        "student-copies",
        help="write every chapter with its solutions replaced by stubs, outputs stripped",
    )
    wr = sub.add_parser(
        "write",
        help="write the full book (chapters with solutions, table of contents, site "
        "configuration) from this installation into a folder",
    )
    for p, what in ((sc, "the student copies"), (wr, "the book")):
        p.add_argument("outdir", help=f"folder to write {what} into (created if needed)")
        p.add_argument(
            "--book",
            default=None,
            help="the book's folder (default: the book this lagolib installed: "
            f"{_default_book_text()})",
        )
        p.add_argument(
            "--force",
            action="store_true",
            help=f"overwrite files in OUTDIR that differ from {what} (without it they are "
            "named and nothing is written)",
        )
    sub.add_parser(
        "grade",
        add_help=False,
        help="run a class's submitted notebooks and grade them with lagolib's own checks "
        "(lagolib book grade --help; lagolib.grading)",
    )
    sc.add_argument(
        "--no-hints",
        dest="hints",
        action="store_false",
        help="copies whose checks say what is wrong but give no hints",
    )
    args, extra = parser.parse_known_args(argv)
    if args.command == "grade":  # the lagolib command hands grade to lagolib.grading
        print("lagolib book: grade runs as 'lagolib book grade ...' (lagolib.grading)", file=sys.stderr)
        return 2
    if extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    student = args.command == "student-copies"
    try:
        where = "write_student_copies" if student else "write_book"
        hints = getattr(args, "hints", True)
        done = _write(args.book, args.outdir, args.force, where, student=student, hints=hints)
    except (LagolibError, OSError) as exc:
        text = str(exc).replace("Pass force=True", "Pass --force")
        print(f"lagolib book: {text}", file=sys.stderr)
        return 2 if isinstance(exc, OptionError) else 1
    _report(done, args.outdir, student)
    return 0


def _default_book_text() -> str:
    try:
        return str(book_dir())
    except OptionError:
        return "missing from this installation"


if __name__ == "__main__":
    sys.exit(main())
