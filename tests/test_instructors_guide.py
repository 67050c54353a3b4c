"""The instructor's guide (book/instructors_guide.ipynb) covers every chapter and every exercise.

The guide's code cells are executed here (without a kernel); their tables are compared with the
chapters read independently, every exercise's difficulty is checked in its metadata and title, the
guide's prerequisites are checked against the preface's reading map and the chapters' own
statements, and a missing difficulty is shown to fail the book's strict run.
"""

import ast
import json
import re
import shutil
from pathlib import Path

import pytest

import lagolib.book

BOOK = Path(__file__).resolve().parent.parent / "book"
GUIDE = BOOK / "instructors_guide.ipynb"
STARS = {1: "★☆☆", 2: "★★☆", 3: "★★★"}


def _chapter_files(book=BOOK):
    """The chapters and appendices: 00_preface … 10_…, A_…; not the guide, not the index."""
    return [p for p in sorted(book.glob("*.ipynb")) if re.match(r"(\d\d|[A-Z])_", p.name)]


def _statements(book=BOOK):
    out = []
    for p in _chapter_files(book):
        nb = json.loads(p.read_text(encoding="utf-8"))
        for c in nb["cells"]:
            meta = c.get("metadata", {}).get("lagolib", {})
            if "exercise" in meta:
                out.append((p.name, meta, "".join(c["source"])))
    return out


def _run_guide(monkeypatch, book=BOOK):
    """Execute the guide's code cells in one namespace, reading the chapters of ``book``."""
    monkeypatch.setattr(lagolib.book, "book_dir", lambda: book)
    nb = json.loads(GUIDE.read_text(encoding="utf-8"))
    ns = {}
    for cell in nb["cells"]:
        if cell["cell_type"] == "code":
            assert not cell["outputs"], "the guide is stored without outputs"
            exec(compile("".join(cell["source"]), str(GUIDE), "exec"), ns)
    return ns


@pytest.fixture(scope="module")
def guide():
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("LAGOLIB_BOOK_STRICT", "1")
        yield _run_guide(mp)


def _preface_map():
    nb = json.loads((BOOK / "00_preface.ipynb").read_text(encoding="utf-8"))
    src = next("".join(c["source"]) for c in nb["cells"] if "NEEDS = {" in "".join(c["source"]))
    out = {}
    for node in ast.parse(src).body:
        if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name):
            name = node.targets[0].id
            if name in ("CHAPTERS", "NEEDS", "IN_ONE_SECTION", "APPENDICES", "APPENDIX_FOR"):
                out[name] = ast.literal_eval(node.value)
    return out


def test_every_chapter_in_the_tables(guide):
    files = [p.name for p in _chapter_files()]
    assert len(files) >= 12 and "A_math_for_global_optimality.ipynb" in files
    assert [c["file"] for c in guide["chapters"]] == files
    keys = [name.split("_")[0] for name in files]
    assert [r[0] for r in guide["time_rows"]] == keys
    assert [r[0] for r in guide["prereq_rows"]] == keys
    for r in guide["time_rows"]:
        assert r[2] > 0 and r[3] > 0  # words and reading hours
    rows = {r[0]: r for r in guide["prereq_rows"]}
    # chapter 9 needs appendix A, and the appendix's mathematics is named
    assert "appendix A" in rows["09"][2]
    for topic in ("Wirtinger", "duality", "Schur"):
        assert topic in rows["09"][3]


def test_prerequisites_are_the_preface_reading_map(guide):
    m = _preface_map()
    numbered = sorted(int(p.name[:2]) for p in _chapter_files() if p.name[:2].isdigit())
    # every chapter (a new one too) is on the preface's map, and every appendix
    assert sorted(m["CHAPTERS"]) == [n for n in numbered if n > 0]
    appendices = sorted(p.name.split("_")[0] for p in _chapter_files() if not p.name[:2].isdigit())
    assert sorted(m["APPENDICES"]) == appendices
    assert (guide["NEEDS"], guide["IN_ONE_SECTION"], guide["APPENDIX_FOR"]) == (
        m["NEEDS"], m["IN_ONE_SECTION"], m["APPENDIX_FOR"])
    rows = {r[0]: r[2] for r in guide["prereq_rows"]}
    for n in m["CHAPTERS"]:
        for a in m["NEEDS"].get(n, []) + m["IN_ONE_SECTION"].get(n, []):
            assert str(a) in rows[f"{n:02d}"], (n, a)


def test_chapters_stated_prerequisites_are_on_the_map():
    """A chapter that states "**Prerequisites:** chapters 5, 6 and 8" builds on them in the map."""
    m = _preface_map()

    def closure(n):
        direct = m["NEEDS"].get(n, []) + m["IN_ONE_SECTION"].get(n, [])
        return set(direct).union(*(closure(a) for a in direct))

    stated = 0
    for p in _chapter_files():
        if not p.name[:2].isdigit():
            continue
        text = "".join("".join(c["source"]) for c in json.loads(p.read_text())["cells"][:1])
        hit = re.search(r"\*\*Prerequisites:\*\*([^.]*)", text)
        if hit:
            stated += 1
            named = {int(x) for x in re.findall(r"\d+", hit.group(1).split("—")[0])}
            assert named <= closure(int(p.name[:2])), (p.name, named)
            if "Appendix A" in text[: hit.end() + 200]:
                assert int(p.name[:2]) in m["APPENDIX_FOR"]["A"]
    assert stated >= 1  # chapter 9 states its own


def test_every_exercise_in_the_table(guide):
    ids = [m["exercise"] for _, m, _ in _statements()]
    assert len(ids) >= 43 and len(set(ids)) == len(ids)
    rows = guide["exercise_rows"]
    assert [r[0] for r in rows] == ids
    for (_, meta, _), row in zip(_statements(), rows):
        assert row[1] == meta["kind"]
        assert row[2] == STARS[meta["difficulty"]]
        assert row[5] == meta["assesses"]
        assert row[4] > 0


def test_every_exercise_has_difficulty_and_stars():
    for name, meta, src in _statements():
        ex = meta["exercise"]
        assert meta.get("difficulty") in (1, 2, 3), f"{name}: {ex} has no difficulty 1–3"
        assert meta.get("assesses", "").strip() and "\n" not in meta["assesses"], ex
        m = re.match(r"\*\*Exercise " + re.escape(ex) + r" \(([^)]*)\)\.\*\*", src)
        assert m, f"{name}: {ex}: title not recognized"
        assert m.group(1).endswith(", " + STARS[meta["difficulty"]]), (ex, m.group(1))
        assert sum(s in m.group(1) for s in STARS.values()) == 1, (ex, m.group(1))


def test_plans_cover_every_chapter_once(guide):
    keys = sorted(c["key"] for c in guide["chapters"])
    plans = guide["plans"]
    assert set(plans) == {"4-week back-end module", "12-week course"}
    assert len(plans["4-week back-end module"]) == 4
    assert len(plans["12-week course"]) == min(10, len(keys))
    for name, weeks in plans.items():
        covered = [c["key"] for week in weeks for c in week]
        assert sorted(covered) == keys, name  # every chapter exactly once
        assert all(week for week in weeks), name
        numbered = [k for k in covered if k.isdigit()]
        assert numbered == sorted(numbered), name  # in the book's order
        assert covered.index("A") < covered.index("09"), name  # the appendix before its chapter
    # the tables show 4 and 12 weeks (the 12-week course: two project weeks)
    assert len(guide["plan_table"]("4-week back-end module", plans["4-week back-end module"]).rows) == 4
    t12 = guide["plan_table"]("12-week course", plans["12-week course"], extra=["p", "q"])
    assert len(t12.rows) == 12
    # every exercise is assigned once in the 12-week course; the module leaves out the ★★★ ones
    assigned = ", ".join(r[2] for r in t12.rows[:10]).split(", ")
    assert sorted(assigned) == sorted(m["exercise"] for _, m, _ in _statements())


def test_split_weeks_is_balanced(guide):
    # the busiest week of the split is no heavier than that of the naive equal-count split
    order = guide["order"]
    hours = [guide["week_hours"]([c]) for c in order]
    blocks = guide["split_weeks"](order, 4)
    busiest = max(guide["week_hours"](b) for b in blocks)
    size = -(-len(order) // 4)
    naive = max(sum(hours[k:k + size]) for k in range(0, len(order), size))
    assert busiest <= naive + 1e-9
    assert busiest < sum(hours)


def test_a_missing_difficulty_fails_the_strict_run(monkeypatch, tmp_path):
    book = tmp_path / "book"
    book.mkdir()
    for p in BOOK.glob("*.ipynb"):
        shutil.copy(p, book / p.name)
    path = book / "06_lago.ipynb"
    nb = json.loads(path.read_text(encoding="utf-8"))
    cell = next(c for c in nb["cells"] if c["metadata"].get("lagolib", {}).get("exercise") == "6.2")
    del cell["metadata"]["lagolib"]["difficulty"]
    path.write_text(json.dumps(nb), encoding="utf-8")
    monkeypatch.setenv("LAGOLIB_BOOK_STRICT", "1")
    with pytest.raises(AssertionError, match=r"difficulty 1-3: \['6\.2'\]"):
        _run_guide(monkeypatch, book)
    # a reader's run goes on, and the tables show "?" for it
    monkeypatch.delenv("LAGOLIB_BOOK_STRICT")
    ns = _run_guide(monkeypatch, book)
    assert dict((r[0], r[2]) for r in ns["exercise_rows"])["6.2"] == "?"


def test_guide_uses_only_the_public_api():
    src = "\n".join("".join(c["source"]) for c in json.loads(GUIDE.read_text())["cells"]
                  if c["cell_type"] == "code")
    imports = re.findall(r"^\s*(?:from\s+(\S+)\s+import|import\s+(\S+))", src, re.M)
    modules = {a or b for a, b in imports}
    allowed = {"ast", "inspect", "json", "pathlib", "re", "tempfile", "lagolib", "lagolib.book",
               "lagolib.exercises"}
    assert modules <= allowed, modules
    private = [node.attr for node in ast.walk(ast.parse(src)) if isinstance(node, ast.Attribute)
               and node.attr.startswith("_") and not node.attr.startswith("__")]
    assert not private, private
