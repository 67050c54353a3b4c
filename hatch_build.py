"""Hatch build hook: put the book into lagolib's wheel as ``lagolib/_book``.

Every file of ``book/`` goes in except what is not the book (``lagolib.book.NOT_THE_BOOK``:
builds, maintainers' scripts, the test harness, editor state), so a chapter added later ships
without touching this file.  Editable installs read the clone's ``book/`` and skip this.
"""

from pathlib import Path

from hatchling.builders.hooks.plugin.interface import BuildHookInterface

# the same list as lagolib.book.NOT_THE_BOOK (the package is not importable while it is built;
# tests/test_wheel.py checks that the wheel holds the book and nothing of these)
NOT_THE_BOOK = ("_build", "_scripts", "conftest.py", ".ipynb_checkpoints", "__pycache__",
                ".pytest_cache")


class CustomBuildHook(BuildHookInterface):
    def initialize(self, version, build_data):
        if self.target_name != "wheel" or version == "editable":
            return
        book = Path(self.root) / "book"
        for path in sorted(book.rglob("*")):
            rel = path.relative_to(book)
            if path.is_file() and not any(part in NOT_THE_BOOK for part in rel.parts):
                build_data["force_include"][str(path)] = f"lagolib/_book/{rel.as_posix()}"
