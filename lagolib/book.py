"""The book's classroom conventions, and student copies of its chapters.

Usage::

    python -m lagolib.book student-copies OUTDIR [--book BOOKDIR] [--force]
    lagolib book student-copies OUTDIR [--book BOOKDIR] [--force]

writes every chapter of ``BOOKDIR`` (default ``book``) into ``OUTDIR`` with each solution replaced by
its stub and every output stripped.  A student copy runs to the end; every check in it reports
"not attempted yet" until the student fills the stubs in.

Nothing a student wrote is lost: every chapter is read and checked before any copy is written (a
chapter that is not a notebook is named, and nothing is written); a notebook already in
``OUTDIR`` that differs from the copy that would replace it (a student's filled-in work, say) is
not overwritten unless ``--force`` is given — the message names the files; one identical to its
copy is left as it is.  Each copy is written to a temporary file and moved into place, so an
interrupted run leaves every notebook either as it was or whole.

An exercise in a chapter is a run of cells (the JSON is plain nbformat 4):

1. **the statement** — a markdown cell starting ``**Exercise 6.2 (implement).**``, with cell
   metadata ``{"lagolib": {"exercise": "6.2", "kind": "implement"}}``; ``kind`` is one of
   :data:`KINDS`: ``implement`` a step, ``predict`` then check, ``explore`` by changing something;
2. **the solution** — a code cell tagged ``solution`` (and ``hide-cell``, so the rendered book
   folds it), whose metadata ``{"lagolib": {"stub": "..."}}`` holds the stub the student starts
   from: the same names, ``# your code here``, and the placeholder ``...`` where the answer goes;
3. **the check** — a code cell calling ``chNN.check_…(answer)`` from :mod:`lagolib.exercises`;
4. **the assertion** — a code cell tagged ``remove-cell`` and ``solution-check``:
   ``assert passed("6.2")``, so a full chapter fails its test when a solution stops being correct;
   hidden from the rendered book, dropped from student copies;
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
    "SOLUTION_TAG",
    "CHECK_TAG",
    "DISCUSSION_STUB",
    "exercises",
    "student_copy",
    "inject_solutions",
    "write_student_copies",
    "main",
]

KINDS = ("implement", "predict", "explore")
SOLUTION_TAG = "solution"
CHECK_TAG = "solution-check"
HIDE_TAGS = ("hide-cell", "hide-input", "hide-output")
STUB_MARK = "# your code here"
DISCUSSION_STUB = (
    "**Your answer and discussion.** *Write here what you found, and why — then compare with a "
    "classmate's.*"
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


def student_copy(nb: dict, path: str | None = None) -> dict:
    """A student's copy of a chapter (JSON dict in, new dict out; ``nb`` is not modified).

    Solution cells become their stubs, ``solution-check`` cells are dropped, every output and
    execution count is cleared, and ``metadata.lagolib.student_copy`` is set.

    Raises
    ------
    ParseError
        If ``nb`` is not a notebook (:func:`_check_notebook`), naming ``path``.
    OptionError
        For a solution code cell without its stub, naming the cell.
    """
    _check_notebook(nb, path)
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
    out["cells"] = cells
    out.setdefault("metadata", {}).setdefault("lagolib", {})["student_copy"] = True
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


def _plan_student_copies(book_dir, out_dir, force):
    """``[(target, bytes, unchanged)]`` for every chapter; reads and checks everything, writes
    nothing.  Raises before anything is written (see :func:`write_student_copies`)."""
    where = "write_student_copies"
    book_dir, out_dir = Path(book_dir), Path(out_dir)
    chapters = sorted(book_dir.glob("*.ipynb"))
    if not chapters:
        raise OptionError(
            f"{where}: book_dir={str(book_dir)!r} holds no chapters (*.ipynb); "
            "pass the book's folder (run from a clone of lagolib: book/)"
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
        text = json.dumps(student_copy(nb, str(path)), indent=1, ensure_ascii=False) + "\n"
        try:
            data = text.encode("utf-8")
        except UnicodeEncodeError as exc:  # a lone surrogate, from a \ud800 escape
            bad = exc.object[exc.start : exc.end]
            raise ParseError(
                path, None, f"holds text that is not valid Unicode ({exc.reason}: {bad!a})"
            ) from None
        plan.append((out_dir / path.name, data))
    out, differ = [], []
    for target, data in plan:
        if target.is_dir():
            raise OptionError(f"{where}: {target} is a folder; the student copy cannot go there")
        unchanged = target.is_file() and target.read_bytes() == data
        if target.exists() and not unchanged:
            differ.append(target.name)
        out.append((target, data, unchanged))
    if differ and not force:
        raise OptionError(
            f"{where}: {out_dir} already holds {len(differ)} notebook(s) that differ from the "
            f"student copies that would replace them (a student's work?): {', '.join(differ)}; "
            "nothing was written.  Pass force=True to overwrite them, or choose another folder"
        )
    return out


def write_student_copies(book_dir, out_dir, *, force=False) -> list[Path]:
    """Write the student copy of every ``*.ipynb`` in ``book_dir`` into ``out_dir``.

    Every chapter is read and checked, and every student copy made, before any file is written.

    Parameters
    ----------
    book_dir, out_dir : str or os.PathLike
        The book's folder, and the folder to write into (created if needed).
    force : bool
        Overwrite notebooks in ``out_dir`` that differ from their student copies.  Without it,
        such a notebook is an error and nothing is written; one identical to its copy is left
        as it is.

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
        No chapters in ``book_dir``; ``out_dir`` is the book or a file; an exercise without its
        stub or kind; or (without ``force``) notebooks in ``out_dir`` that differ from their
        copies — the message names them.  Nothing is written.
    """
    return [target for target, _ in _write_plan(book_dir, out_dir, force)]


def _write_plan(book_dir, out_dir, force):
    """Write what :func:`_plan_student_copies` planned; ``[(target, written)]``."""
    check_bool(force, "force", "write_student_copies")
    plan = _plan_student_copies(book_dir, out_dir, force)
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    done = []
    for target, data, unchanged in plan:
        if not unchanged:
            with atomic_write(target, "wb") as f:
                f.write(data)
        done.append((target, not unchanged))
    return done


def main(argv=None) -> int:
    """``lagolib book student-copies OUTDIR [--book BOOKDIR]``."""
    parser = argparse.ArgumentParser(
        prog="lagolib book", description="Tools for the lagolib book's chapters."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    sc = sub.add_parser(
        "student-copies",
        help="write every chapter with its solutions replaced by stubs, outputs stripped",
    )
    sc.add_argument("outdir", help="folder to write the student copies into (created if needed)")
    sc.add_argument("--book", default="book", help="the book's folder (default: book)")
    sc.add_argument(
        "--force",
        action="store_true",
        help="overwrite notebooks in OUTDIR that differ from their student copies (without it "
        "they are named and nothing is written)",
    )
    args = parser.parse_args(argv)
    try:
        done = _write_plan(args.book, args.outdir, args.force)
    except (LagolibError, OSError) as exc:
        text = str(exc).replace("Pass force=True", "Pass --force")
        print(f"lagolib book: {text}", file=sys.stderr)
        return 2 if isinstance(exc, OptionError) else 1
    n = sum(len(exercises(_read_notebook(p))) for p, _ in done)
    written = sum(w for _, w in done)
    if written == len(done):
        print(f"wrote {len(done)} chapters with {n} exercises to {args.outdir}")
    else:
        print(
            f"wrote {written} of {len(done)} chapters to {args.outdir} ({len(done) - written} "
            f"already up to date); {n} exercises"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
