"""The book's classroom conventions, and student copies of its chapters.

Usage::

    python -m lagolib.book student-copies OUTDIR [--book BOOKDIR]
    lagolib book student-copies OUTDIR [--book BOOKDIR]

writes every chapter of ``BOOKDIR`` (default ``book``) into ``OUTDIR`` with each solution replaced by
its stub and every output stripped.  A student copy runs to the end; every check in it reports
"not attempted yet" until the student fills the stubs in.

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

from .errors import OptionError

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


def exercises(nb: dict, path: str | None = None) -> list[dict]:
    """The exercises of a notebook (a JSON dict): ``[{"id", "kind", "cell"}, …]`` in order.

    Raises :class:`~lagolib.errors.OptionError` naming the cell when an exercise's metadata is
    malformed (no id, or a kind outside :data:`KINDS`).
    """
    out = []
    for k, cell in enumerate(nb.get("cells", [])):
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
    """
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


def write_student_copies(book_dir, out_dir) -> list[Path]:
    """Write the student copy of every ``*.ipynb`` in ``book_dir`` into ``out_dir``; return paths."""
    book_dir, out_dir = Path(book_dir), Path(out_dir)
    chapters = sorted(book_dir.glob("*.ipynb"))
    if not chapters:
        raise OptionError(
            f"write_student_copies: book_dir={str(book_dir)!r} holds no chapters (*.ipynb); "
            "pass the book's folder (run from a clone of lagolib: book/)"
        )
    if out_dir.resolve() == book_dir.resolve():
        raise OptionError(
            "write_student_copies: out_dir is the book itself; choose another folder so the "
            "solutions are not overwritten"
        )
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for path in chapters:
        with open(path, encoding="utf-8") as f:
            nb = json.load(f)
        target = out_dir / path.name
        with open(target, "w", encoding="utf-8") as f:
            json.dump(student_copy(nb, str(path)), f, indent=1, ensure_ascii=False)
            f.write("\n")
        written.append(target)
    return written


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
    args = parser.parse_args(argv)
    try:
        written = write_student_copies(args.book, args.outdir)
    except OptionError as exc:
        print(f"lagolib book: {exc}", file=sys.stderr)
        return 2
    n = sum(len(exercises(json.loads(p.read_text(encoding="utf-8")))) for p in written)
    print(f"wrote {len(written)} chapters with {n} exercises to {args.outdir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
