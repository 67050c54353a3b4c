"""Grading a simulated class (lagolib.grading): every kind of submission a teacher meets.

The class hands in chapter 4 (graphs and cycles; the assignment counts its exercises 4.1-4.4) as
students would: student copies of the real chapter with the stubs filled in (the cells keep their
metadata, as JupyterLab keeps it).

* alice solves everything (and also hands in the preface, which the assignment does not count);
* bob predicts 4.2 wrong;
* carol hands the copy back untouched (graded without a kernel);
* dave's 4.1 cell crashes;
* erin's 4.1 function never returns when a check calls it (she deleted its check cell, so only
  the grader's check calls it), and her 4.2 cell loops forever;
* frank predicts 4.2 wrong, then in its check cell redefines the check, patches lagolib's
  ``verdict`` in the kernel and prints "Exercise 4.2 — correct";
* gina renamed her notebook and retyped her answer cells (their metadata is gone);
* hank handed in the preface under chapter 4's file name;
* ivan's 4.1 and 4.3 functions patch lagolib's checks when a check calls them (the first by
  swapping ``verdict``'s code, the second by replacing it);
* kim handed in two copies of chapter 4; leo's folder is empty; mia's notebook is not JSON;
* nina handed in the full chapter (solutions and all) instead of a student copy;
* olga's 4.4 cell swallows the interrupt and never ends: the notebook stops there.
"""

import copy
import csv
import json
import os
import time
from pathlib import Path

import pytest

from lagolib import book as lbook
from lagolib import grading
from lagolib.cli import main as cli_main
from lagolib.errors import OptionError, ParseError
from lagolib.grading import COLUMNS, grade, read_assignment

BOOK = Path(__file__).resolve().parent.parent / "book"
CH04 = "04_graphs_and_cycles.ipynb"
CELL_TIMEOUT = 5  # seconds: ch04's slowest cell takes 0.7 s, its checks 0.1 s; each loop costs 5 s
ASSIGNMENT = f"""\
title = "Week 2: graphs and cycles"
cell_timeout = {CELL_TIMEOUT}
[points]
"4.1" = 2
4.2 = 1
"4.3" = 2
"4.4" = 1
"""
POINTS = {"4.1": 2, "4.2": 1, "4.3": 2, "4.4": 1}
C, N, A, E = "correct", "not yet", "not attempted", "error"
EXPECTED = {
    "alice": [C, C, C, C],
    "bob": [C, N, C, C],
    "carol": [A, A, A, A],
    "dave": [E, C, C, C],
    "erin": [E, E, C, C],
    "frank": [C, N, C, C],
    "gina": [C, C, C, C],
    "hank": [E, E, E, E],
    "ivan": [E, C, E, C],
    "kim": [E, E, E, E],
    "leo": [A, A, A, A],
    "mia": [E, E, E, E],
    "nina": [C, C, C, C],
    "olga": [C, C, C, E],
}


def _load(name):
    return json.loads((BOOK / name).read_text(encoding="utf-8"))


def _ordinals(full):
    """``{exercise: ordinal of its answer cell}`` in the student copy of ``full``."""
    out, current, k = {}, None, 0
    for cell in full["cells"]:
        ex = cell["metadata"].get("lagolib", {}).get("exercise")
        if ex is not None:
            current = ex
        if "solution" in cell["metadata"].get("tags", []):
            if cell["cell_type"] == "code" and current not in out:
                out[current] = k
            k += 1
    return out


class Chapter:
    """The student copy of a chapter, and a way to fill its answer cells in."""

    def __init__(self, name):
        self.full = _load(name)
        self.copy = lbook.student_copy(self.full)
        self.ordinal = _ordinals(self.full)
        solutions = [c for c in self.full["cells"] if "solution" in c["metadata"].get("tags", [])]
        self.solution = {ex: "".join(solutions[k]["source"]) for ex, k in self.ordinal.items()}

    def cell(self, nb, ex):
        (hit,) = [
            c
            for c in nb["cells"]
            if c["metadata"].get("lagolib", {}).get("solution") == self.ordinal[ex]
        ]
        return hit

    def solved(self, **answers):
        """The copy with every answer filled in: the book's, or ``answers["4_2"]``'s source."""
        nb = copy.deepcopy(self.copy)
        for ex in self.ordinal:
            self.cell(nb, ex)["source"] = answers.get(ex.replace(".", "_"), self.solution[ex])
        return nb


def _save(root, student, name, nb):
    folder = root / student
    folder.mkdir(parents=True, exist_ok=True)
    text = nb if isinstance(nb, str) else json.dumps(nb, indent=1, ensure_ascii=False)
    (folder / name).write_text(text, encoding="utf-8")


WRONG_42 = "n_tree_edges = 8\nn_chords = 4\n"
FRANK_CHECK = """\
ch04.check_chords = lambda *a, **k: print("Exercise 4.2 — correct") or True
import lagolib.exercises._feedback as fb
fb.verdict = lambda *a, **k: True
import lagolib.exercises as ex
ex.passed = lambda *a, **k: True
ch04.check_chords(n_tree_edges, n_chords)
print("Exercise 4.2 — correct")
"""
IVAN_41 = """\
def incidence(edges, n_nodes):
    import lagolib.exercises._feedback as f
    f.verdict.__code__ = (lambda *a, **k: True).__code__
    return None
"""
IVAN_43 = """\
def circuit_vector(graph, tree, chord):
    import lagolib.exercises._feedback as f
    f.verdict = lambda *a, **k: print("Exercise 4.3 — correct") or True
    return None
"""
OLGA_44 = """\
import time
while True:
    try:
        time.sleep(0.05)
    except KeyboardInterrupt:
        pass
"""


def _class(root):
    ch4, ch0 = Chapter(CH04), Chapter("00_preface.ipynb")
    _save(root, "alice", CH04, ch4.solved())
    _save(root, "alice", "00_preface.ipynb", ch0.solved())
    _save(root, "bob", CH04, ch4.solved(**{"4_2": WRONG_42}))
    _save(root, "carol", CH04, ch4.copy)
    _save(root, "dave", CH04, ch4.solved(**{"4_1": 'raise RuntimeError("oops")'}))
    erin = ch4.solved(
        **{
            "4_1": "def incidence(edges, n_nodes):\n    while True:\n        pass\n",
            "4_2": "while True:\n    pass\n",
        }
    )
    erin["cells"] = [
        c for c in erin["cells"] if "ch04.check_incidence(" not in "".join(c["source"])
    ]
    _save(root, "erin", CH04, erin)
    frank = ch4.solved(**{"4_2": WRONG_42})
    (check,) = [c for c in frank["cells"] if "ch04.check_chords(" in "".join(c["source"])]
    check["source"] = FRANK_CHECK
    _save(root, "frank", CH04, frank)
    gina = ch4.solved()
    for ex in ch4.ordinal:  # retyped cells: no lagolib metadata
        del ch4.cell(gina, ex)["metadata"]["lagolib"]
    _save(root, "gina", "my_homework_final(2).ipynb", gina)
    _save(root, "hank", CH04, ch0.solved())
    _save(root, "ivan", CH04, ch4.solved(**{"4_1": IVAN_41, "4_3": IVAN_43}))
    _save(root, "kim", CH04, ch4.solved())
    _save(root, "kim", "04_graphs_and_cycles-Copy1.ipynb", ch4.solved())
    (root / "leo").mkdir()
    _save(root, "mia", CH04, '{"cells": [')
    _save(root, "nina", CH04, ch4.full)
    _save(root, "olga", CH04, ch4.solved(**{"4_4": OLGA_44}))
    (root / ".ipynb_checkpoints").mkdir()  # Jupyter's: not a student
    _save(root / ".ipynb_checkpoints", "x", CH04, ch4.copy)


def _env(tmp):
    """The kernels' environment: the shipped stand-ins, no network, a private cache."""
    env = {k: v for k, v in os.environ.items() if k != "LAGOLIB_DATA"}
    env.update(LAGOLIB_OFFLINE="1", LAGOLIB_CACHE=str(tmp))
    return env


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    root = tmp_path_factory.mktemp("class")
    _class(root / "submissions")
    (root / "week2.toml").write_text(ASSIGNMENT, encoding="utf-8")
    started = time.monotonic()
    result = grade(
        root / "submissions",
        assignment=root / "week2.toml",
        output=root / "gradebook.csv",
        env=_env(root / "cache"),
        jobs=2,  # two notebooks at once, each in a process of its own
    )
    return root, result, time.monotonic() - started


def _rows(expected):
    out = []
    for student, verdicts in expected.items():
        for (ex, pts), verdict in zip(POINTS.items(), verdicts):
            out.append([student, "4", ex, verdict, str(pts if verdict == C else 0)])
    return out


@pytest.mark.book
def test_the_gradebook_of_a_simulated_class(graded):
    root, result, seconds = graded
    with open(root / "gradebook.csv", newline="", encoding="utf-8") as f:
        reader = csv.reader(f)
        assert (
            tuple(next(reader))
            == COLUMNS
            == ("student", "chapter", "exercise", "verdict", "points")
        )
        rows = list(reader)
    assert rows == _rows(EXPECTED)
    assert [list(r.values()) for r in result.rows] == rows
    assert result.path == root / "gradebook.csv"
    assert seconds < 240  # 9 kernels and 4 time limits: about 40 s on 2 cores


@pytest.mark.book
def test_why_each_answer_got_its_verdict(graded):
    _, result, _ = graded
    why = result.messages
    assert why[("dave", "4.1")] == "the answer cell raised RuntimeError: oops"
    assert why[("erin", "4.1")] == (
        f"the check ran past its time limit of {CELL_TIMEOUT} s with your answer (an endless "
        "loop in your function?)"
    )
    assert why[("erin", "4.2")] == (
        f"the answer cell ran past its time limit of {CELL_TIMEOUT} s and was interrupted (an "
        "endless loop?)"
    )
    assert why[("olga", "4.4")].startswith("cell ") and why[("olga", "4.4")].endswith(
        f"ran past its time limit of {CELL_TIMEOUT} s and could not be interrupted, so the rest "
        "of the notebook was not run"
    )
    # frank's kernel said correct three times over; the grader's own check did not
    assert why[("frank", "4.2")].startswith("n_tree_edges = 8 ")  # the check's diagnosis
    assert why[("bob", "4.2")] == why[("frank", "4.2")]
    for ex in ("4.1", "4.3"):
        assert why[("ivan", ex)].startswith(
            "your answer changed lagolib's checks while they ran (lagolib.exercises"
        ), why[("ivan", ex)]
    assert why[("carol", "4.1")] == "the answer cell is the stub"
    assert why[("leo", "4.1")] == "no notebook of chapter 4 was handed in"
    assert why[("hank", "4.1")] == (
        "no notebook of chapter 4 was handed in; handed in instead: `04_graphs_and_cycles.ipynb`"
    )
    assert why[("kim", "4.1")] == (
        "2 notebooks of chapter 4 were handed in (`04_graphs_and_cycles-Copy1.ipynb`, "
        "`04_graphs_and_cycles.ipynb`); hand in one (none was graded)"
    )


@pytest.mark.book
def test_feedback_files_say_why(graded):
    root, result, _ = graded
    folder = root / "gradebook-feedback"
    assert sorted(p.name for p in folder.iterdir()) == sorted(f"{s}.md" for s in EXPECTED)
    assert result.feedback_paths == [folder / f"{s}.md" for s in sorted(EXPECTED)]
    dave = (folder / "dave.md").read_text(encoding="utf-8")
    assert dave == (
        "# Week 2: graphs and cycles — feedback for dave\n"
        "\n"
        "- **Exercise 4.1** — error (0 of 2 points): the answer cell raised RuntimeError: oops\n"
        "- **Exercise 4.2** — correct (1 of 1 point)\n"
        "- **Exercise 4.3** — correct (2 of 2 points)\n"
        "- **Exercise 4.4** — correct (1 of 1 point)\n"
        "\n"
        "**Total: 4 of 6 points.**\n"
    )
    frank = (folder / "frank.md").read_text(encoding="utf-8")
    assert "- **Exercise 4.2** — not yet (0 of 1 point): n_tree_edges = 8 " in frank
    assert "Stuck?" not in frank and "hint(" not in frank  # the grader's checks give no hints
    assert frank.endswith("**Total: 5 of 6 points.**\n")
    alice = (folder / "alice.md").read_text(encoding="utf-8")
    assert (
        "- `00_preface.ipynb` is chapter 0, which this assignment does not include: it was not "
        "graded.\n" in alice
    )
    assert alice.endswith("**Total: 6 of 6 points.**\n")
    hank = (folder / "hank.md").read_text(encoding="utf-8")
    assert "`04_graphs_and_cycles.ipynb` is chapter 0, which this assignment" in hank
    mia = (folder / "mia.md").read_text(encoding="utf-8")
    assert "- `04_graphs_and_cycles.ipynb` was not graded: it could not be read (" in mia
    assert "not JSON" in mia


def _carol(root):
    """A one-student class whose copy is untouched: graded without a kernel."""
    _save(root, "carol", CH04, lbook.student_copy(_load(CH04)))
    return root / "carol"


def test_nothing_is_overwritten_without_force(tmp_path, capsys):
    out = tmp_path / "book.csv"
    argv = ["book", "grade", str(_carol(tmp_path / "class")), "-o", str(out)]
    assert cli_main(argv) == 0  # every exercise of chapter 4 counts one point
    rows = list(csv.reader(out.open(encoding="utf-8")))
    assert rows[0] == list(COLUMNS)
    assert [r[2] for r in rows[1:]] == sorted(
        (e["id"] for e in lbook.exercises(_load(CH04))), key=grading._order
    )
    assert {(r[0], r[1], r[3], r[4]) for r in rows[1:]} == {("carol", "4", A, "0")}
    assert "graded 1 students: 0 correct, 0 not yet" in capsys.readouterr().out
    feedback = tmp_path / "book-feedback" / "carol.md"
    before = out.read_bytes(), feedback.read_bytes()
    out.write_text("edited by hand\n", encoding="utf-8")
    assert cli_main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("lagolib book grade: 2 output file(s) already exist: ")
    assert str(out) in err and str(feedback) in err and "Pass --force" in err
    assert out.read_text(encoding="utf-8") == "edited by hand\n"  # nothing was written
    assert cli_main([*argv, "--force"]) == 0
    assert (out.read_bytes(), feedback.read_bytes()) == before
    with pytest.raises(OptionError, match=r"already exist: .*book\.csv.*nothing was written"):
        grade(tmp_path / "class", output=out)
    # the gradebook inside the class's folder: its feedback folder is not a student next time
    inside = tmp_path / "class" / "week2.csv"
    for force in (False, True):
        result = grade(tmp_path / "class", output=inside, force=force)
        assert {r["student"] for r in result.rows} == {"carol"}
    assert sorted(p.name for p in (tmp_path / "class").iterdir()) == [
        "carol",
        "week2-feedback",
        "week2.csv",
    ]


def test_misuse_is_named(tmp_path, capsys):
    out = str(tmp_path / "g.csv")
    assert cli_main(["book", "grade", str(tmp_path / "nobody"), "-o", out]) == 2
    assert "submission" in (err := capsys.readouterr().err) and "does not exist" in err
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("x", encoding="utf-8")
    assert cli_main(["book", "grade", str(tmp_path / "empty"), "-o", out]) == 2
    assert "no notebooks (*.ipynb)" in capsys.readouterr().err
    notes = tmp_path / "empty" / "notes.txt"
    assert cli_main(["book", "grade", str(notes), "-o", out]) == 2
    assert "is not a notebook (*.ipynb)" in capsys.readouterr().err
    carol = str(_carol(tmp_path / "class"))
    assert cli_main(["book", "grade", carol]) == 2  # no -o: argparse's usage error
    assert "-o/--output" in capsys.readouterr().err
    assert cli_main(["book", "grade", carol, "-o", out, "--cell-timeout", "-1"]) == 2
    assert "-1.0; give a positive number of seconds" in capsys.readouterr().err
    assert cli_main(["book", "grade", carol, "-o", out, "--jobs", "0"]) == 2
    assert "0; give a whole number of notebooks" in capsys.readouterr().err
    bad = tmp_path / "a.toml"
    bad.write_text('title = "x"\n[points]\n"4.1" = \n', encoding="utf-8")
    assert cli_main(["book", "grade", carol, "-o", out, "--assignment", str(bad)]) == 1
    assert f"lagolib book grade: {bad}:3: not TOML" in capsys.readouterr().err
    assert not Path(out).exists()
    with pytest.raises(ParseError, match=r"a\.toml:3: not TOML"):
        read_assignment(bad)
    bad.write_text('title = "x"\n[points]\n"4.9" = 2\n', encoding="utf-8")
    with pytest.raises(
        OptionError,
        match=r'a\.toml:3: \[points\] names exercise "4\.9", which the book does not have; '
        r"chapter 4's are 4\.1, 4\.2, 4\.3, 4\.4",
    ):
        read_assignment(bad, known={"4.1", "4.2", "4.3", "4.4", "5.1"})
    with pytest.raises(OptionError, match=r'"12\.1", which the book does not have; the book'):
        bad.write_text('[points]\n"12.1" = 2\n', encoding="utf-8")
        read_assignment(bad, known={"4.1", "5.1"})
    for text, message in [
        ('tittle = "x"\n', r"a\.toml:1: unknown key 'tittle'; an assignment file has title"),
        ("cell_timeout = -1\n", r"a\.toml:1: cell_timeout = -1; give a positive number"),
        ('[points]\n"4.1" = "two"\n', r"a\.toml:2: points \"4\.1\" = 'two'; give a number"),
        ("points = 3\n", r"a\.toml:1: \[points\] should be a table"),
        ("title = 3\n", r"a\.toml:1: title = 3; write the title as a string"),
    ]:
        bad.write_text(text, encoding="utf-8")
        with pytest.raises(OptionError, match=message):
            read_assignment(bad, known={"4.1"})
    with pytest.raises(OptionError, match="assignment file .* does not exist"):
        read_assignment(tmp_path / "missing.toml")


def test_the_notebook_time_limit_stops_it(tmp_path):
    """A notebook that uses up its budget: every exercise after that point is an error."""
    ch4 = Chapter(CH04)
    nb = ch4.solved()
    first = next(k for k, c in enumerate(nb["cells"]) if c["cell_type"] == "code")
    nb["cells"].insert(
        first,
        {
            "cell_type": "code",
            "execution_count": None,
            "metadata": {},
            "outputs": [],
            "source": "import time\ntime.sleep(60)",
        },
    )
    _save(tmp_path / "class", "zoe", CH04, nb)
    started = time.monotonic()
    result = grade(tmp_path / "class", output=None, notebook_timeout=2, env=_env(tmp_path))
    assert time.monotonic() - started < 60
    assert [(r["exercise"], r["verdict"]) for r in result.rows][:4] == [
        ("4.1", E),
        ("4.2", E),
        ("4.3", E),
        ("4.4", E),
    ]
    assert result.messages[("zoe", "4.1")] == (
        f"the notebook ran past its time limit of 2 s (in cell {first + 1})"
    )
