"""The book's exercises follow the classroom conventions, and student copies run.

Structure (read as JSON): every chapter ``book/NN_*.ipynb`` with NN >= 01 has at least three
exercises, of all three kinds (implement, predict, explore); each exercise of any notebook (the
preface has one) is the run of cells
:mod:`lagolib.book` defines — statement, solution with its stub, a check from
``lagolib.exercises.chNN``, the hidden ``assert passed(id)``, and the folded "Solution and
discussion" — and the chapter links back to the preface.

Student copies (``lagolib.book.write_student_copies``): no solution is left in them; executed
offline in a kernel, each runs to the end and every check reports "not attempted yet".  With the
solutions injected back (:func:`lagolib.book.inject_solutions`), every check reports correct.
"""

import ast
import importlib
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from test_book import execute, kernel_env

from lagolib import book as lbook
from lagolib.exercises import NOT_ATTEMPTED

ROOT = Path(__file__).resolve().parent.parent
BOOK = ROOT / "book"
CHAPTERS = sorted(p for p in BOOK.glob("[0-9][0-9]_*.ipynb") if int(p.name[:2]) >= 1)
# every notebook with an exercise (the preface has one, to try the format)
WITH_EXERCISES = sorted(
    p
    for p in BOOK.glob("[0-9][0-9]_*.ipynb")
    if lbook.exercises(json.loads(p.read_text(encoding="utf-8")))
)


def _ids(paths):
    return [p.stem for p in paths]


def _load(path):
    return json.loads(path.read_text(encoding="utf-8"))


def _src(cell):
    s = cell.get("source", "")
    return "".join(s) if isinstance(s, list) else s


def _tags(cell):
    return cell.get("metadata", {}).get("tags", [])


def _outputs_text(nb):
    out = []
    for cell in nb.cells:
        for o in cell.get("outputs", []):
            if o.get("output_type") == "stream":
                out.append(o.get("text", ""))
            elif "data" in o and "text/plain" in o["data"]:
                out.append(o["data"]["text/plain"])
    return "".join(out)


@pytest.mark.parametrize("path", CHAPTERS, ids=_ids(CHAPTERS))
def test_every_chapter_has_exercises_of_each_kind(path):
    found = lbook.exercises(_load(path), path.name)
    assert len(found) >= 3, f"{path.name}: {len(found)} exercises; at least 3 are required"
    kinds = {e["kind"] for e in found}
    assert kinds >= set(lbook.BASIC_KINDS), (
        f"{path.name}: kinds {sorted(kinds)}; need at least {lbook.BASIC_KINDS}"
    )


@pytest.mark.parametrize("path", WITH_EXERCISES, ids=_ids(WITH_EXERCISES))
def test_exercises_follow_the_conventions(path):
    nb = _load(path)
    cells = nb["cells"]
    chapter = int(path.name[:2])
    module = importlib.import_module(f"lagolib.exercises.ch{chapter:02d}")
    found = lbook.exercises(nb, path.name)
    ids = [e["id"] for e in found]
    assert len(set(ids)) == len(ids), f"{path.name}: duplicate exercise ids {ids}"
    bounds = [e["cell"] for e in found] + [len(cells)]
    for e, end in zip(found, bounds[1:]):
        where = f"{path.name}, exercise {e['id']}"
        assert e["id"].startswith(f"{chapter}."), f"{where}: id should start with {chapter}."
        statement = _src(cells[e["cell"]])
        label = e["kind"]
        assert re.match(rf"\*\*Exercise {re.escape(e['id'])} \({label}", statement), (
            f"{where}: the statement should start with **Exercise {e['id']} ({label}…).**"
        )
        block = cells[e["cell"] + 1 : end]
        # given cells (data, a slider) may sit between the statement and the solution
        first = next((k for k, c in enumerate(block) if "solution" in _tags(c)), None)
        assert first is not None, f"{where}: no cell tagged solution"
        given, block = block[:first], block[first:]
        assert not any(re.search(r"\.check_\w+\(", _src(c)) for c in given), (
            f"{where}: a check runs before the solution"
        )
        solution = block[0]
        assert solution.get("cell_type") == "code", (
            f"{where}: the first cell tagged solution must be the code solution"
        )
        assert "hide-cell" in _tags(solution), f"{where}: the solution is not folded (hide-cell)"
        stub = solution.get("metadata", {}).get("lagolib", {}).get("stub", "")
        assert lbook.STUB_MARK in stub and "..." in stub, f"{where}: stub lacks the mark or ..."
        ast.parse(stub)
        assert stub.strip() != _src(solution).strip(), f"{where}: the stub is the solution"
        checks = [c for c in block if c["cell_type"] == "code" and "solution" not in _tags(c)]
        calls = re.findall(rf"ch{chapter:02d}\.(check_\w+)\(", "".join(map(_src, checks)))
        assert calls, f"{where}: no ch{chapter:02d}.check_…(…) call after the solution"
        for name in calls:
            assert callable(getattr(module, name, None)), f"{where}: {name} does not exist"
        asserts = [c for c in block if lbook.CHECK_TAG in _tags(c)]
        assert len(asserts) == 1 and "remove-cell" in _tags(asserts[0]), (
            f"{where}: one cell tagged solution-check and remove-cell is required"
        )
        assert _src(asserts[0]).strip() == lbook.solution_check_source(e["id"]), where
        assert asserts[0]["metadata"].get("jupyter", {}).get("source_hidden"), (
            f"{where}: the solution-check cell is not collapsed in JupyterLab (source_hidden)"
        )
        discussion = [c for c in block if c["cell_type"] == "markdown" and "solution" in _tags(c)]
        assert len(discussion) == 1, f"{where}: one 'Solution and discussion' cell is required"
        text = _src(discussion[0]).strip()
        assert text.startswith("<details>") and text.endswith("</details>"), where
        assert "<summary>Solution and discussion</summary>" in text, where
        words = len(re.sub(r"<[^>]+>", " ", text).split())
        assert words >= 40, f"{where}: the discussion has {words} words; explain the solution"


@pytest.mark.parametrize("path", CHAPTERS, ids=_ids(CHAPTERS))
def test_chapter_links_to_the_preface(path):
    first = next(c for c in _load(path)["cells"] if c["cell_type"] == "markdown")
    assert "(00_preface.ipynb)" in _src(first), f"{path.name}: link the preface in the first cell"


def test_student_copy_removes_every_solution(tmp_path):
    written = lbook.write_student_copies(BOOK, tmp_path)
    assert [p.name for p in written] == sorted(p.name for p in BOOK.glob("*.ipynb"))
    for path in written:
        full, student = _load(BOOK / path.name), _load(path)
        for cell in student["cells"]:
            assert "solution" not in _tags(cell) and lbook.CHECK_TAG not in _tags(cell)
            assert not cell.get("outputs") and cell.get("execution_count") is None
        solutions = [c for c in full["cells"] if "solution" in _tags(c)]
        stubs = [c for c in student["cells"] if "solution" in c["metadata"].get("lagolib", {})]
        assert len(stubs) == len(solutions), path.name
        for stub, sol in zip(stubs, solutions):
            if sol["cell_type"] == "code":
                assert _src(stub) == sol["metadata"]["lagolib"]["stub"]
            assert _src(stub) != _src(sol)
        # injecting the solutions back gives the chapter without its hidden assertions
        back = lbook.inject_solutions(student, full)
        kept = [c for c in full["cells"] if lbook.CHECK_TAG not in _tags(c)]
        assert [(c["cell_type"], _src(c), _tags(c)) for c in back["cells"]] == [
            (c["cell_type"], _src(c), _tags(c)) for c in kept
        ], path.name


@pytest.fixture(scope="module")
def copies(tmp_path_factory):
    folder = tmp_path_factory.mktemp("student-copies")
    lbook.write_student_copies(BOOK, folder)
    return folder


@pytest.mark.book
@pytest.mark.parametrize("path", WITH_EXERCISES, ids=_ids(WITH_EXERCISES))
def test_student_copy_runs_and_nothing_is_attempted(path, copies, tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    target = copies / path.name
    nb = execute(target, kernel_env("offline", cache))
    text = _outputs_text(nb)
    for e in lbook.exercises(_load(path), path.name):
        assert f"Exercise {e['id']} — {NOT_ATTEMPTED}" in text, (
            f"{path.name}: the student copy's check of exercise {e['id']} did not report "
            f"'{NOT_ATTEMPTED}'"
        )
        assert f"Exercise {e['id']} — correct" not in text, (
            f"{path.name}: the student copy's check of exercise {e['id']} said correct"
        )


@pytest.mark.book
@pytest.mark.parametrize("path", WITH_EXERCISES, ids=_ids(WITH_EXERCISES))
def test_solutions_injected_back_pass_every_check(path, copies, tmp_path):
    student = _load(copies / path.name)
    injected = lbook.inject_solutions(student, _load(path))
    # beside the other chapters, as in the book (the preface looks at them)
    for other in copies.glob("*.ipynb"):
        shutil.copy(other, tmp_path / other.name)
    target = tmp_path / path.name
    target.write_text(json.dumps(injected), encoding="utf-8")
    cache = tmp_path / "cache"
    cache.mkdir()
    text = _outputs_text(execute(target, kernel_env("offline", cache)))
    for e in lbook.exercises(injected, path.name):
        assert f"Exercise {e['id']} — correct" in text, (
            f"{path.name}: with the solutions injected, exercise {e['id']} is not correct"
        )
        for other in ("not yet", NOT_ATTEMPTED):
            assert f"Exercise {e['id']} — {other}" not in text, (path.name, e["id"], other)


def test_command_line(tmp_path):
    out = tmp_path / "copies"
    proc = subprocess.run(
        [sys.executable, "-m", "lagolib.book", "student-copies", str(out), "--book", str(BOOK)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    n = sum(len(lbook.exercises(_load(p))) for p in WITH_EXERCISES)
    first, following = proc.stdout.strip().splitlines()
    assert first == (
        f"wrote student copies of {len(list(BOOK.glob('*.ipynb')))} chapters with {n} "
        f"exercises to {out}"
    )
    assert following.startswith(f"next: jupyter lab {out / '00_preface.ipynb'}")
    proc = subprocess.run(
        [sys.executable, "-m", "lagolib.book", "student-copies", str(out), "--book", str(tmp_path)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2 and "holds no chapters" in proc.stderr
    proc = subprocess.run(
        [sys.executable, "-m", "lagolib.book", "student-copies", str(BOOK), "--book", str(BOOK)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2 and "out_dir is the book itself" in proc.stderr


def test_malformed_exercises_are_named():
    nb = {"cells": [{"cell_type": "markdown", "metadata": {"lagolib": {"exercise": "9.1"}}}]}
    with pytest.raises(ValueError, match=r"ch09.ipynb: cell 0: exercise '9.1' has kind None"):
        lbook.exercises(nb, "ch09.ipynb")
    nb = {
        "cells": [
            {"cell_type": "code", "metadata": {"tags": ["solution"]}, "source": "x = 1"},
        ]
    }
    with pytest.raises(ValueError, match=r"ch09.ipynb: cell 0: a solution code cell needs"):
        lbook.student_copy(nb, "ch09.ipynb")


def test_no_hints_copies_turn_hints_off_before_any_check(tmp_path):
    written = lbook.write_student_copies(BOOK, tmp_path, hints=False)
    for path in written:
        nb = _load(path)
        assert nb["metadata"]["lagolib"]["hints"] is False
        code = [c for c in nb["cells"] if c["cell_type"] == "code"]
        assert _src(code[0]) == lbook.NO_HINTS_SOURCE, path.name
        assert sum(lbook.NO_HINTS_SOURCE in _src(c) for c in code) == 1
    with_hints = _load(lbook.write_student_copies(BOOK, tmp_path / "h")[0])
    assert not any(lbook.NO_HINTS_SOURCE in _src(c) for c in with_hints["cells"])
    assert "hints" not in with_hints["metadata"]["lagolib"]


@pytest.mark.book
def test_a_no_hints_copy_diagnoses_without_hints(tmp_path):
    """The preface's exercise answered wrong in a --no-hints copy: a diagnosis, no hint."""
    subprocess.run(
        [sys.executable, "-m", "lagolib.book", "student-copies", str(tmp_path), "--no-hints"],
        check=True,
        capture_output=True,
    )
    path = tmp_path / "00_preface.ipynb"
    nb = _load(path)
    stub = next(c for c in nb["cells"] if "solution" in c["metadata"].get("lagolib", {}))
    wrong = "n_unknown = 1\nA_shape = (1, 1)\nstate_length = 1\n"  # three wrong predictions
    assert [line.split(" = ")[0] for line in wrong.splitlines()] == [
        line.split(" = ")[0] for line in _src(stub).splitlines()
    ]
    stub["source"] = wrong
    # with hints on, the same answers get a hint (so the copy below really turned them off)
    import contextlib
    import io

    from lagolib.exercises import ch00, reset, set_hints

    reset()
    set_hints(True)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        ch00.check_notation(1, (1, 1), 1)
    assert "Stuck?" in out.getvalue()
    probe = {"cell_type": "code", "metadata": {}, "outputs": [], "execution_count": None,
             "source": 'from lagolib.exercises import hint\nhint("0.1")'}
    nb["cells"].append(probe)
    path.write_text(json.dumps(nb), encoding="utf-8")
    cache = tmp_path / "cache"
    cache.mkdir()
    text = _outputs_text(execute(path, kernel_env("offline", cache)))
    assert "Exercise 0.1 — not yet:" in text
    assert "Stuck?" not in text and "Exercise 0.1 — hints are off in this copy" in text


def test_write_book_copies_the_book_and_keeps_a_changed_file(tmp_path):
    out = tmp_path / "mybook"
    written = lbook.write_book(out)
    names = {p.relative_to(out).as_posix() for p in written}
    assert {p.name for p in BOOK.glob("*.ipynb")} <= names
    assert {"_toc.yml", "_config.yml", "equation_index.md", "_static/lagolib.css"} <= names
    assert not any(part in lbook.NOT_THE_BOOK for n in names for part in n.split("/"))
    for p in written:
        assert p.read_bytes() == (BOOK / p.relative_to(out)).read_bytes()
    mine = out / "06_lago.ipynb"
    mine.write_text("my notes", encoding="utf-8")
    with pytest.raises(ValueError, match=r"1 file\(s\) that differ.*06_lago.ipynb; nothing"):
        lbook.write_book(out)
    assert mine.read_text(encoding="utf-8") == "my notes"
    lbook.write_book(out, force=True)
    assert mine.read_bytes() == (BOOK / "06_lago.ipynb").read_bytes()


def test_the_installed_book_is_the_default(tmp_path):
    assert lbook.book_dir() == BOOK  # an editable install: the clone's book/
    assert [p.name for p in lbook.write_student_copies(out_dir=tmp_path)] == sorted(
        p.name for p in BOOK.glob("*.ipynb")
    )
    with pytest.raises(ValueError, match="out_dir is required"):
        lbook.write_student_copies()
