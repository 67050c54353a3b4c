"""Generate ``book/equation_index.md``: every numbered item of the three sources → lagolib → chapter.

Run from the repository root (``python book/_scripts/equation_index.py``; ``--check`` exits 1 when the
committed page is stale).  The page is built from two readings:

* lagolib's docstrings — every public module, class, function and method — for citations such as
  ``Carlone et al. 2011, eq. 9–11``, ``Theorem 3``, ``Table I``, ``Lodi Rizzini eq. (44)`` or
  ``lecture notes, "Role of the Prior"``;
* the chapters' markdown, for the same citations, under the section heading they appear in.

A citation names its source by the nearest ``Carlone`` / ``Lodi Rizzini`` / ``lecture notes`` before
it in the same docstring or cell, or else by the module's or chapter's own source
(:data:`MODULE_SOURCE`, :data:`CHAPTER_SOURCE`).  Every item of :data:`ITEMS` must be implemented,
taught, or listed in :data:`NOT_IMPLEMENTED` with the reason (``tests/test_equation_index.py``).
"""

from __future__ import annotations

import importlib
import inspect
import json
import pkgutil
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BOOK = ROOT / "book"
PAGE = BOOK / "equation_index.md"

SOURCES = {
    "carlone": (
        "Carlone, Aragues, Castellanos, Bona — A Linear Approximation for Graph-based SLAM "
        "(LAGO), RSS 2011"
    ),
    "rizzini": (
        "Lodi Rizzini — A Closed-Form Constraint Networks Solver for Maximum Likelihood Mapping"
    ),
    "notes": "Lecture notes — Graph Based SLAM, a least-squares approach using a pose graph",
}

ROMAN = ["I", "II", "III"]
# the numbered items of each source, in the source's order (read off /work/shared/papers)
ITEMS = {
    "carlone": (
        [f"eq. {k}" for k in range(1, 24)]
        + ["Definition 1", "Lemma 1", "Proposition 1", "Proposition 2"]
        + [f"Theorem {k}" for k in (1, 2, 3)]
        + [f"Corollary {k}" for k in (1, 2, 3)]
        + ["Remark 1", "Remark 2", "Table I", "Table II", "Fig. 1", "Fig. 2", "Fig. 3"]
    ),
    "rizzini": [f"eq. {k}" for k in range(1, 50)] + ["Fig. 1", "Fig. 2"],
    # the notes number nothing: their slides' titles are the items
    "notes": [
        "Idea of Graph-Based SLAM",
        "Graph-based slam in a Nutshell",
        "The overall SLAM System",
        "The Graph",
        "Transformations",
        "The Edge Information matrices",
        "Pose Graph",
        "Least Square SLAM",
        "The Error Function",
        "Linearizing the error function",
        "Consequences of the Sparsity",
        "The Linear system",
        "Building the Linear system",
        "Algorithm",
        "Role of the Prior",
        "Fixing a Subset of Variables",
        "Uncertainty",
        "Relative Uncertainty",
    ],
}

# items lagolib does not implement as a function, and why
NOT_IMPLEMENTED: dict[tuple[str, str], str] = {
    (
        "carlone",
        "eq. 2",
    ): "the log-likelihood; lagolib minimizes the equivalent cost, eq. 3 (`chi2`)",
    ("carlone", "eq. 16"): (
        "phase 3's estimate written out with dense covariances; `lago.phase3_poses` solves eq. 15 "
        "sparse, which equals it (the dense reference in `tests/test_lago.py` checks eq. 9–15)"
    ),
    ("carlone", "eq. 17"): "the split θ* = θ̂ + θ̃ of eq. 16 — a step of the proof of Theorem 1",
    ("carlone", "eq. 18"): (
        "the expansion of the cost in the proof of Theorem 1; chapter 6 checks the theorem "
        "numerically instead"
    ),
    ("rizzini", "eq. 8"): (
        "the set of a pose's incoming constraints; `closed_form` assembles the gradient per "
        "constraint instead, with sparse matrices"
    ),
    ("rizzini", "eq. 9"): "the set of a pose's outgoing constraints (see eq. 8)",
    ("rizzini", "eq. 47"): (
        "the §IV-A example's Q for three poses; chapter 7 builds it with `closed_form`'s general "
        "matrices and prints it"
    ),
    ("rizzini", "eq. 48"): "the §IV-A example's M (see eq. 47)",
    ("rizzini", "eq. 49"): "the §IV-A example's L (see eq. 47)",
    ("rizzini", "Fig. 1"): "a drawing of an example network",
    ("notes", "Idea of Graph-Based SLAM"): "motivation, nothing to compute",
}

# the notes number nothing, and the chapters teach their slides without quoting the titles: the
# chapter section (a heading's text, matched as a substring) that teaches each slide
NOTES_TAUGHT: dict[str, list[tuple[str, str]]] = {
    "Idea of Graph-Based SLAM": [("01", "Chapter 1")],
    "Graph-based slam in a Nutshell": [("01", "Chapter 1"), ("10", "The map")],
    "The overall SLAM System": [
        ("01", "Chapter 1"),
        ("10", "the front end run once"),
        ("10", "The back end"),
    ],
    "The Graph": [("01", "Odometric edges and loop closures")],
    "Transformations": [("01", "A pose and its homogeneous matrix"), ("01", "Compounding")],
    "The Edge Information matrices": [("01", "A relative measurement and its error")],
    "Pose Graph": [("01", "Odometric edges and loop closures")],
    "Least Square SLAM": [("02", "Chapter 2")],
    "The Error Function": [
        ("01", "A relative measurement and its error"),
        ("02", "The error function and its Jacobian blocks"),
    ],
    "Linearizing the error function": [("02", "The error function and its Jacobian blocks")],
    "Consequences of the Sparsity": [("02", "The structure of H"), ("02", "Solving H")],
    "The Linear system": [("02", "Building the linear system")],
    "Building the Linear system": [("02", "Building the linear system")],
    "Algorithm": [("02", "Gauss–Newton, one iteration at a time")],
    "Role of the Prior": [("02", "A prior on x₀ versus fixing x₀")],
    "Fixing a Subset of Variables": [("02", "A prior on x₀ versus fixing x₀")],
    "Uncertainty": [("03", "Marginal covariances from the sparse H")],
    "Relative Uncertainty": [("03", "relative uncertainty does not")],
}

# the source of an object's citations when its docstring names none (longest matching prefix)
MODULE_SOURCE = {
    "lagolib.estimation": "carlone",
    "lagolib.symbolic.Sincos": "rizzini",
    "lagolib.symbolic.on_unit_circle": "rizzini",
    "lagolib.lago": "carlone",
    "lagolib.sgd": "carlone",
    "lagolib.metrics": "carlone",
    "lagolib.topology": "carlone",
    "lagolib.closed_form": "rizzini",
    "lagolib.gauss_newton": "notes",
    "lagolib.uncertainty": "notes",
    "lagolib.linalg": "notes",
}
CHAPTER_SOURCE = {
    "01": "notes",
    "02": "notes",
    "03": "notes",
    "04": "carlone",
    "05": "carlone",
    "06": "carlone",
    "07": "rizzini",
    "08": "carlone",
}

_SOURCE_RX = re.compile(r"Carlone|LAGO paper|Lodi Rizzini|Rizzini|lecture notes|the notes'", re.I)
_NUM = r"\(?(\d{1,2})\)?"
_EQ_RX = re.compile(
    r"\b[Ee]qs?\.?\s*" + _NUM + r"((?:\s*(?:–|-|,|and|&)\s*" + _NUM.replace("(", "(?:", 1) + r")*)"
)
_EQ_WORD_RX = re.compile(r"\b[Ee]quations?\s*" + _NUM)
_NAMED_RX = re.compile(
    r"\b(Theorem|Thm\.|Definition|Def\.|Corollary|Cor\.|Lemma|Proposition|Prop\.|Remark)\s*(\d)"
)
_TABLE_RX = re.compile(r"\bTables?\s+(III|II|I)\b((?:\s*(?:–|-|,|and)\s*(?:III|II|I)\b)*)")
_FIG_RX = re.compile(r"\bFig(?:ure|\.)\s*(\d)")
_NOTES_RX = re.compile(r"[\"“]([^\"”]{3,60})[\"”]")
_ABBREV = {
    "Thm.": "Theorem",
    "Def.": "Definition",
    "Cor.": "Corollary",
    "Prop.": "Proposition",
}


def _source_of(name: str) -> str:
    name = name.lower()
    if "carlone" in name or "lago" in name:
        return "carlone"
    if "rizzini" in name:
        return "rizzini"
    return "notes"


def _numbers(first: str, rest: str) -> list[int]:
    """``13`` + ``–15, 17`` → [13, 14, 15, 17]."""
    out = [int(first)]
    for sep, num in re.findall(r"(–|-|,|and|&)\s*\(?(\d{1,2})\)?", rest):
        k = int(num)
        if sep in "–-" and k > out[-1]:
            out.extend(range(out[-1] + 1, k + 1))
        else:
            out.append(k)
    return out


def citations(text: str, default: str | None) -> list[tuple[str, str]]:
    """``[(source, item), …]`` cited in ``text``; ``default`` names the source when none is named.

    A numbered item whose source cannot be told (no paper named before it and a notes default)
    comes back with source ``None``: the test lists those so that the text names its source.
    """
    marks = [(m.start(), _source_of(m.group(0))) for m in _SOURCE_RX.finditer(text)]

    def source_at(pos):
        # the notes number nothing: a numbered item belongs to the nearest paper named before it
        before = [s for p, s in marks if p <= pos and s != "notes"]
        if before:
            return before[-1]
        return default if default != "notes" else None

    found = []
    for m in _EQ_RX.finditer(text):
        for k in _numbers(m.group(1), m.group(2) or ""):
            found.append((m.start(), f"eq. {k}"))
    for m in _EQ_WORD_RX.finditer(text):
        found.append((m.start(), f"eq. {int(m.group(1))}"))
    for m in _NAMED_RX.finditer(text):
        found.append((m.start(), f"{_ABBREV.get(m.group(1), m.group(1))} {m.group(2)}"))
    for m in _TABLE_RX.finditer(text):
        for t in [m.group(1), *re.findall(r"(III|II|I)\b", m.group(2) or "")]:
            found.append((m.start(), f"Table {t}"))
    for m in _FIG_RX.finditer(text):
        found.append((m.start(), f"Fig. {int(m.group(1))}"))
    notes_titles = {t.lower(): t for t in ITEMS["notes"]}
    for m in _NOTES_RX.finditer(text):
        title = notes_titles.get(" ".join(m.group(1).split()).rstrip(".").lower())
        if title:
            found.append((m.start(), title))
    out = []
    for pos, item in found:
        src = "notes" if item in notes_titles.values() else source_at(pos)
        key = (src, item)
        if key not in out:
            out.append(key)
    return out


def _public_objects():
    """``(qualified name, docstring, module name)`` of lagolib's public modules and objects."""
    import lagolib

    names = ["lagolib"] + [
        f"lagolib.{m.name}"
        for m in pkgutil.iter_modules(lagolib.__path__)
        if not m.name.startswith("_") and m.name not in ("exercises", "book", "cli")
    ]
    for modname in names:
        mod = importlib.import_module(modname)
        yield modname, inspect.getdoc(mod) or "", modname
        for name, obj in vars(mod).items():
            if name.startswith("_") or getattr(obj, "__module__", None) != modname:
                continue
            if inspect.isfunction(obj) or inspect.isclass(obj):
                yield f"{modname}.{name}", inspect.getdoc(obj) or "", modname
            if inspect.isclass(obj):
                for mname, member in vars(obj).items():
                    if mname.startswith("_"):
                        continue
                    if isinstance(member, property):
                        member = member.fget
                    if inspect.isfunction(member):
                        doc = inspect.getdoc(member) or ""
                        yield f"{modname}.{name}.{mname}", doc, modname


def default_source(qualname: str) -> str | None:
    """The source an object's docstring cites by default (:data:`MODULE_SOURCE`)."""
    hits = [p for p in MODULE_SOURCE if qualname.startswith(p)]
    return MODULE_SOURCE[max(hits, key=len)] if hits else None


def implementations() -> dict[tuple[str, str], list[str]]:
    """``{(source, item): [qualified names citing it]}`` from lagolib's docstrings."""
    out: dict[tuple[str, str], list[str]] = {}
    for qualname, doc, _module in _public_objects():
        for key in citations(doc, default_source(qualname)):
            out.setdefault(key, [])
            if qualname not in out[key]:
                out[key].append(qualname)
    return out


def slugify(title: str) -> str:
    """The anchor MyST gives a heading (``myst_heading_anchors``), as its default slug function."""
    return re.sub(r"[^\w\u4e00-\u9fff\- ]", "", title.strip().lower().replace(" ", "-"))


def _title(text: str) -> str:
    """Heading text as it reads: markdown links, code ticks and emphasis removed."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)
    return text.replace("`", "").replace("*", "").strip()


def _cells(path: Path):
    """``(markdown text, tags, chapter title, section title, anchor)`` of a chapter's cells."""
    nb = json.loads(path.read_text(encoding="utf-8"))
    chapter_title, section, anchor = path.stem, "", ""
    for cell in nb["cells"]:
        if cell["cell_type"] != "markdown":
            continue
        text = "".join(cell["source"]) if isinstance(cell["source"], list) else cell["source"]
        for line in text.splitlines():
            m = re.match(r"^(#{1,3})\s+(.*)$", line)
            if not m:
                continue
            title = _title(m.group(2))
            if len(m.group(1)) == 1:
                chapter_title, section, anchor = title, "", ""
            else:
                section, anchor = title, slugify(title)
        tags = cell.get("metadata", {}).get("tags", [])
        yield text, tags, chapter_title, section, anchor


def chapters() -> list[Path]:
    return sorted(BOOK.glob("[0-9][0-9]_*.ipynb"))


def headings() -> dict[str, list[tuple[str, str]]]:
    """``{chapter prefix "06": [(heading title, anchor), …]}``, the chapter title with anchor ""."""
    out: dict[str, list[tuple[str, str]]] = {}
    for path in chapters():
        seen = out.setdefault(path.name[:2], [])
        for _, _, chapter_title, section, anchor in _cells(path):
            for h in [(chapter_title, ""), (section, anchor)]:
                if h[0] and h not in seen:
                    seen.append(h)
    return out


def notes_section(prefix: str, needle: str) -> tuple[str, str, str] | None:
    """``(chapter file, section title, anchor)`` of the heading containing ``needle``, or None."""
    files = {p.name[:2]: p.name for p in chapters()}
    for title, anchor in headings().get(prefix, []):
        if needle in title:
            return files[prefix], title, anchor
    return None


def teachings() -> dict[tuple[str, str], list[tuple[str, str, str]]]:
    """``{(source, item): [(chapter file, section title, anchor)]}`` from the chapters' markdown."""
    out: dict[tuple[str, str], list[tuple[str, str, str]]] = {}
    for item, places in NOTES_TAUGHT.items():
        for prefix, needle in places:
            where = notes_section(prefix, needle)
            if where is not None:
                out.setdefault(("notes", item), []).append(where)
    for path in chapters():
        if path.name.startswith("00_"):
            continue  # the preface maps the sources to the chapters; it teaches nothing itself
        default = CHAPTER_SOURCE.get(path.name[:2])
        for text, tags, chapter_title, section, anchor in _cells(path):
            if "solution" in tags:
                continue  # exercises' discussions do not teach an item first
            for key in citations(text, default):
                where = (path.name, section or chapter_title, anchor)
                out.setdefault(key, [])
                if where not in out[key]:
                    out[key].append(where)
    return out


def _label(path_name: str) -> str:
    return f"ch. {int(path_name[:2])}"


def _specific(names: list[str]) -> list[str]:
    """Drop a module (or class) when something inside it is listed too."""
    return [q for q in names if not any(o.startswith(q + ".") for o in names)]


def render() -> str:
    impl, teach = implementations(), teachings()
    lines = [
        "# Equation index",
        "",
        "Every numbered equation, definition, theorem, table and figure of the three sources, the "
        "lagolib function that implements it, and the chapter section that teaches it. The lecture "
        "notes number nothing, so their slides are listed by title. Generated from lagolib's "
        "docstrings and the chapters by `book/_scripts/equation_index.py`; "
        "`tests/test_equation_index.py` keeps it complete and current.",
        "",
    ]
    for src, title in SOURCES.items():
        lines += [f"## {title}", "", "| item | lagolib | taught in |", "|---|---|---|"]
        for item in ITEMS[src]:
            key = (src, item)
            funcs = ", ".join(
                f"`{q.removeprefix('lagolib.')}`" for q in _specific(impl.get(key, []))
            )
            places = teach.get(key, [])
            with_section = {f for f, _, a in places if a}
            taught = ", ".join(
                f"[{_label(f)} — {sec}]({f}{'#' + a if a else ''})"
                for f, sec, a in places
                if a or f not in with_section
            )
            reason = NOT_IMPLEMENTED.get(key)
            if not funcs:
                funcs = f"not implemented: {reason}" if reason else "—"
            lines.append(f"| {item} | {funcs} | {taught or '—'} |")
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    import argparse

    parser = argparse.ArgumentParser(description="Write book/equation_index.md (see the module).")
    parser.add_argument(
        "--check", action="store_true", help="exit 1 if the page is stale; write nothing"
    )
    args = parser.parse_args(argv)
    text = render()
    if args.check:
        current = PAGE.read_text(encoding="utf-8") if PAGE.exists() else ""
        if current != text:
            print(f"{PAGE} is stale: run python book/_scripts/equation_index.py", file=sys.stderr)
            return 1
        return 0
    PAGE.write_text(text, encoding="utf-8")
    print(f"wrote {PAGE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
