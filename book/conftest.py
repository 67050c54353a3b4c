"""The chapters run as tests through nbmake: ``pytest --nbmake book/``.

``pytest`` alone runs them too: pyproject.toml's ``addopts`` carry ``--nbmake`` and its
``testpaths`` end with ``book``.  nbmake collects every ``book/*.ipynb`` (a new chapter is picked up
by its file name); this file makes each chapter two tests, both executed by nbmake's runner with the
book's headless client (``_ext/lagolib_headless.py``: IPC sockets, nothing sent to the kernel while
a cell runs, no wait on the kernel longer than a second unchecked):

``book/NN_name.ipynb::online``
    the environment as it is: in CI ``LAGOLIB_DATA`` names the benchmark mirror, so the chapters
    show the real benchmarks.  Left out when ``LAGOLIB_OFFLINE`` is already on (it would repeat the
    offline run).
``book/NN_name.ipynb::offline``
    ``LAGOLIB_DATA`` unset, ``LAGOLIB_OFFLINE=1`` and an empty ``LAGOLIB_CACHE``: the chapters fall
    back to the shipped examples.  Marked ``offline`` (``-m "not offline"`` leaves it out).

Each run executes the chapter once.  It fails, naming the chapter and the cell, on a cell error, on
a cell running longer than the chapter's per-cell timeout (``metadata["execution"]["timeout"]``,
read by nbmake and Jupyter Book alike; a hang guard, not a time limit), on a dead kernel, when the
chapter renders fewer figures (``image/png`` outputs) than it promises
(``metadata["lagolib"]["figures"]``), and, offline, when it writes to the download cache.  The
kernels draw inline and hold BLAS to one thread (``lagolib_headless.kernel_env``).  nbmake's
``--overwrite`` is not honored here: the chapters are stored without outputs
(``tests/test_book.py`` checks that, and the figure promise, without running them).
"""

import importlib.util
import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest
from nbclient.exceptions import DeadKernelError
from nbmake.pytest_items import NotebookFailedException, NotebookFile, NotebookItem

BOOK = Path(__file__).resolve().parent
# the site's build output, its Sphinx extension and the scripts are not tests
# (and this file: --doctest-modules would import it as a test module named "conftest", the name
# tests/conftest.py's module has too)
collect_ignore_glob = ["_build/*", "_ext/*", "_scripts/*", "conftest.py"]
_ON = {"1", "true", "yes", "on"}  # what LAGOLIB_OFFLINE counts as on (lagolib.datasets)


def headless():
    """The ``lagolib_headless`` module of ``_ext`` (one instance for the whole session)."""
    name = "lagolib_headless"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, BOOK / "_ext" / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def pytest_configure(config):
    # also declared in pyproject.toml; here too, so that this folder runs as tests on its own
    config.addinivalue_line("markers", "book: executes a chapter of book/ in a Jupyter kernel")
    config.addinivalue_line("markers", "offline: runs a chapter with LAGOLIB_OFFLINE=1")


def _offline_already():
    return os.environ.get("LAGOLIB_OFFLINE", "").strip().lower() in _ON


def count_figures(nb):
    """Number of ``image/png`` outputs of an executed notebook."""
    return sum(
        "image/png" in out.get("data", {})
        for cell in nb.cells
        if cell.cell_type == "code"
        for out in cell.get("outputs", [])
    )


class ChapterFailed(Exception):
    """A chapter ran, but broke a promise (figures, cache) or its kernel died."""


class ChapterItem(NotebookItem):
    """One run of a chapter, ``online`` or ``offline`` (see the module)."""

    def __init__(self, *, parent, filename, variant, **kw):
        pytest.Item.__init__(self, name=variant, parent=parent, **kw)
        self.filename = filename
        self.variant = variant
        self.add_marker(pytest.mark.book)
        if variant == "offline":
            self.add_marker(pytest.mark.offline)

    def _online_cache(self):
        """The user's download cache, or one temporary cache for every online run."""
        key = _ONLINE_CACHE
        if key not in self.config.stash:
            folder = tempfile.mkdtemp(prefix="lagolib-book-cache-")
            self.config.stash[key] = folder
            self.config.add_cleanup(lambda: shutil.rmtree(folder, ignore_errors=True))
        return Path(self.config.stash[key])

    def runtest(self):
        hl = headless()
        option = self.config.option
        where = f"{self.path.name} [{self.variant}]"
        empty = Path(tempfile.mkdtemp(prefix="lagolib-book-offline-"))
        try:
            cache = empty if self.variant == "offline" else self._online_cache()
            env = hl.kernel_env(self.variant, cache)
            try:
                res = hl.run(
                    self.path,
                    env,
                    timeout=option.nbmake_timeout,
                    verbose=bool(option.verbose),
                    kernel=option.nbmake_kernel,
                )
            except DeadKernelError as exc:
                raise ChapterFailed(f"{where}: the kernel died ({exc})") from None
            if res.error is not None:
                cell = res.error.failing_cell_index
                res.error.summary = f"{where}: cell {cell}: {res.error.summary}"
                raise NotebookFailedException(res)
            problems = []
            promised = res.nb.metadata.get("lagolib", {}).get("figures")
            if not isinstance(promised, int) or isinstance(promised, bool) or promised < 1:
                problems.append(
                    f'metadata["lagolib"]["figures"] must be an int >= 1 (the figures the '
                    f"chapter renders); got {promised!r}"
                )
            elif count_figures(res.nb) < promised:
                problems.append(
                    f"rendered {count_figures(res.nb)} figures, promises {promised} "
                    '(metadata["lagolib"]["figures"])'
                )
            if self.variant == "offline":
                written = sorted(p.name for p in empty.iterdir())
                if written:
                    problems.append(f"wrote {written} to the download cache offline")
            if problems:
                raise ChapterFailed(f"{where}: " + "; ".join(problems))
        finally:
            shutil.rmtree(empty, ignore_errors=True)

    def repr_failure(self, excinfo, style=None):
        if isinstance(excinfo.value, ChapterFailed):
            return str(excinfo.value)
        return super().repr_failure(excinfo, style)

    def reportinfo(self):
        return self.path, 0, f"{self.path.name} [{self.variant}]"


class ChapterFile(NotebookFile):
    """A chapter collected by nbmake, as its ``online`` and ``offline`` runs."""

    def collect(self):
        variants = ("offline",) if _offline_already() else ("online", "offline")
        for variant in variants:
            yield ChapterItem.from_parent(self, filename=str(self.path), variant=variant)


_ONLINE_CACHE = pytest.StashKey[str]()


@pytest.hookimpl(wrapper=True)
def pytest_collect_file(file_path, parent):
    """Turn nbmake's collector of a chapter into a :class:`ChapterFile`."""
    collected = yield
    if file_path.parent != BOOK or file_path.suffix != ".ipynb":
        return collected
    return [
        ChapterFile.from_parent(parent, path=file_path)
        if isinstance(c, NotebookFile) and not isinstance(c, ChapterFile)
        else c
        for c in collected
    ]
