"""The instructor's guide (book/instructors_guide.ipynb) covers every chapter and every exercise.

The guide's code cells are executed here (without a kernel); their tables are compared with the
chapters read independently, and every exercise's difficulty is checked in its metadata and title.
"""

import json
import re
from pathlib import Path

import pytest

BOOK = Path(__file__).resolve().parent.parent / "book"
GUIDE = BOOK / "instructors_guide.ipynb"
STARS = {1: "★☆☆", 2: "★★☆", 3: "★★★"}


def _chapter_files():
    return [p for p in sorted(BOOK.glob("*.ipynb")) if p.name != GUIDE.name]


def _statements():
    out = []
    for p in _chapter_files():
        nb = json.loads(p.read_text(encoding="utf-8"))
        for c in nb["cells"]:
            meta = c.get("metadata", {}).get("lagolib", {})
            if "exercise" in meta:
                out.append((p.name, meta, "".join(c["source"])))
    return out


@pytest.fixture(scope="module")
def guide():
    nb = json.loads(GUIDE.read_text(encoding="utf-8"))
    ns = {}
    for cell in nb["cells"]:
        if cell["cell_type"] == "code":
            assert not cell["outputs"], "the guide is stored without outputs"
            exec(compile("".join(cell["source"]), str(GUIDE), "exec"), ns)
    return ns


def test_every_chapter_in_the_tables(guide):
    files = [p.name for p in _chapter_files()]
    assert len(files) >= 11
    assert [c["file"] for c in guide["chapters"]] == files
    keys = [p.name.split("_")[0] for p in _chapter_files()]
    assert [r[0] for r in guide["time_rows"]] == keys
    assert [r[0] for r in guide["prereq_rows"]] == keys
    for r in guide["time_rows"]:
        assert r[2] > 0 and r[3] > 0          # words and reading hours
    # chapter 9 lists its mathematics, and the appendix when (and only when) it exists
    row9 = dict((r[0], r[2]) for r in guide["prereq_rows"])["09"]
    for topic in ("Wirtinger", "duality", "Schur"):
        assert topic in row9
    assert ("A_math_for_global_optimality.ipynb" in row9) == (
        BOOK / "A_math_for_global_optimality.ipynb").is_file()


def test_every_exercise_in_the_table(guide):
    ids = [m["exercise"] for _, m, _ in _statements()]
    assert len(ids) >= 40
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


def test_plans_cover_every_chapter_once(guide):
    keys = sorted(c["key"] for c in guide["chapters"])
    plans = guide["plans"]
    assert set(plans) == {"4-week back-end module", "12-week course"}
    assert len(plans["4-week back-end module"]) == 4
    assert len(plans["12-week course"]) == min(10, len(keys))
    for name, weeks in plans.items():
        covered = [c["key"] for week in weeks for c in week]
        assert sorted(covered) == keys, name
        assert all(week for week in weeks), name
        # the appendix comes no later than the chapter that needs it
        if "A" in covered:
            assert covered.index("A") < covered.index("09")


def test_split_weeks_is_balanced(guide):
    # the busiest week of the split is no heavier than that of the naive equal-count split
    order = guide["order"]
    hours = [(c["read_min"] + c["ex_min"]) / 60 for c in order]
    blocks = guide["split_weeks"](order, 4)
    busiest = max(sum((c["read_min"] + c["ex_min"]) / 60 for c in b) for b in blocks)
    size = -(-len(order) // 4)
    naive = max(sum(hours[k:k + size]) for k in range(0, len(order), size))
    assert busiest <= naive + 1e-9
    assert busiest < sum(hours)


def test_guide_uses_only_the_public_api():
    src = "".join("".join(c["source"]) for c in json.loads(GUIDE.read_text())["cells"]
                  if c["cell_type"] == "code")
    imports = re.findall(r"^\s*(?:from\s+(\S+)\s+import|import\s+(\S+))", src, re.M)
    modules = {a or b for a, b in imports}
    assert modules <= {"json", "pathlib", "lagolib", "lagolib.book"}, modules
    assert "._" not in src
