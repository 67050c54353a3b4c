"""The chapters are stored as the book needs them, and the harness that runs them is sound.

The chapters run as tests through nbmake (``pytest --nbmake book/``, and ``pytest``, whose
addopts carry ``--nbmake``): ``book/conftest.py`` makes each chapter an ``online`` and an
``offline`` run, executed once each by nbmake's runner with the book's headless client
(``book/_ext/lagolib_headless.py``), and fails a run on a cell error or timeout, on fewer figures
than the chapter promises, and on an offline run writing to the download cache.  This file checks,
without running a chapter:

* every chapter is stored stripped (no outputs, no execution counts), promises its figures
  (``metadata["lagolib"]["figures"]``) and declares its per-cell timeout
  (``metadata["execution"]["timeout"]``, read by nbmake and Jupyter Book);
* no chapter reaches into lagolib's private API, and every random generator is seeded;

and, on small notebooks of its own, that the harness keeps its promises: the headless client sends
the kernel nothing while a cell runs (a widget cell included), no wait on the kernel goes unchecked
for more than a second, a hanging cell fails after the notebook's timeout with the cell named, and
a chapter that breaks its figure or cache promise fails with a message saying so.

:func:`execute` and :func:`kernel_env` run other notebooks the same way (the student copies of
``tests/test_exercises_book.py``).
"""

import asyncio
import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path
from queue import Empty

import nbformat
import pytest

ROOT = Path(__file__).resolve().parent.parent
BOOK = ROOT / "book"
CHAPTERS = sorted(BOOK.glob("*.ipynb"))
MAX_CELL_TIMEOUT = 120  # seconds: a chapter's per-cell timeout is a hang guard, not a time limit


def _headless():
    """``book/_ext/lagolib_headless.py`` (the instance ``book/conftest.py`` uses, if loaded)."""
    if "lagolib_headless" not in sys.modules and str(BOOK / "_ext") not in sys.path:
        sys.path.insert(0, str(BOOK / "_ext"))
    return importlib.import_module("lagolib_headless")


def _ids(paths):
    return [p.stem for p in paths]


def _read(path):
    return nbformat.read(path, as_version=4)


def kernel_env(variant, cache):
    """The kernel's environment for ``variant`` ("online" or "offline"); see lagolib_headless."""
    return _headless().kernel_env(variant, cache)


def execute(path, env, timeout=MAX_CELL_TIMEOUT):
    """Run the notebook at ``path`` as the chapters run; return the executed notebook.

    Fails the test, naming the notebook and the cell, on a cell error or timeout (the notebook's
    ``metadata["execution"]["timeout"]``, else ``timeout``) and on a dead kernel.
    """
    from nbclient.exceptions import DeadKernelError

    try:
        res = _headless().run(path, env, timeout=timeout)
    except DeadKernelError as exc:
        pytest.fail(f"{Path(path).name}: the kernel died ({exc})", pytrace=False)
    if res.error is not None:
        pytest.fail(
            f"{Path(path).name}: cell {res.error.failing_cell_index}: {res.error.summary}\n"
            f"{res.error.trace}",
            pytrace=False,
        )
    return res.nb


def test_book_has_chapters():
    assert CHAPTERS, f"no chapters found in {BOOK}"


@pytest.mark.parametrize("path", CHAPTERS, ids=_ids(CHAPTERS))
def test_stored_without_outputs(path):
    """Stored stripped, with a figure promise and a per-cell timeout."""
    nb = _read(path)
    dirty = [
        i
        for i, cell in enumerate(nb.cells)
        if cell.cell_type == "code"
        and (cell.get("outputs") or cell.get("execution_count") is not None)
    ]
    assert not dirty, (
        f"{path.name}: cells {dirty} are stored with outputs or execution counts; clear them "
        "(Jupyter: Edit > Clear Outputs of All Cells; or nbformat) before saving"
    )
    n = nb.metadata.get("lagolib", {}).get("figures")
    assert isinstance(n, int) and not isinstance(n, bool) and n >= 1, (
        f'{path.name}: metadata["lagolib"]["figures"] must be an int >= 1, the figures the '
        f"chapter renders (book/conftest.py counts them); got {n!r}"
    )
    timeout = nb.metadata.get("execution", {}).get("timeout")
    assert (
        isinstance(timeout, int)
        and not isinstance(timeout, bool)
        and 1 <= timeout <= MAX_CELL_TIMEOUT
    ), (
        f'{path.name}: metadata["execution"]["timeout"] must be an int of 1 to '
        f"{MAX_CELL_TIMEOUT} seconds, the per-cell hang guard nbmake and Jupyter Book read "
        f"(without it a stalled cell idles for 300 s); got {timeout!r}"
    )


def _notebook(tmp_path, name, sources, **metadata):
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(s) for s in sources])
    nb.metadata.update(
        {"kernelspec": {"display_name": "Python 3", "language": "python", "name": "python3"}},
        **metadata,
    )
    path = tmp_path / name
    nbformat.write(nb, path)
    return path


WIDGET_CELL = (
    "from ipywidgets import FloatSlider, interact\n"
    "def show(sigma):\n"
    "    for k in range(3):\n"
    "        print(f'line {k}: sigma = {sigma:.2f}', flush=True)\n"
    "interact(show, sigma=FloatSlider(value=0.1, min=0.0, max=1.0));"
)


def test_headless_client_sends_nothing_while_a_cell_runs(tmp_path):
    """A widget cell run headless: the client writes only its requests to the kernel.

    nbclient's stock client echoes each output of an ``interact`` callback back to the kernel
    (a ``comm_msg`` on the shell channel, its Output-widget mimic) while it waits on that channel
    for the cell's reply; over TCP, 7 of 2100 such cells then had their reply noticed only when
    the wait timed out (300 s under nbmake's default).  The book's client sends nothing mid-cell.
    """
    hl = _headless()
    path = _notebook(tmp_path, "widget.ipynb", [WIDGET_CELL, "print('after')"])
    nb = _read(path)
    sent = []

    class Recording(hl.PassiveClient):
        async def async_start_new_kernel_client(self):
            kc = await super().async_start_new_kernel_client()
            send = kc.shell_channel.send

            def record(msg):
                sent.append(msg["header"]["msg_type"])
                return send(msg)

            kc.shell_channel.send = record
            return kc

    env = kernel_env("offline", tmp_path)
    Recording(
        nb, kernel_env=env, timeout=60, resources={"metadata": {"path": str(tmp_path)}}
    ).execute()
    assert sent.count("execute_request") == 2
    assert set(sent) <= {"kernel_info_request", "execute_request"}, sent
    text = "".join(o.get("text", "") for c in nb.cells for o in c.outputs)
    assert "line 2: sigma = 0.10" in text and "after" in text, text


def test_no_wait_on_the_kernel_goes_unchecked_for_more_than_a_slice():
    """A wait of ``timeout`` seconds (or forever) polls the socket at least every slice.

    pyzmq's poll re-checks the socket only when its timeout ends, so a wake-up the event loop
    missed used to cost the whole cell timeout; sliced, it costs at most one slice.
    """
    hl = _headless()

    class Channel:
        """Answers on the fourth poll; records the timeout of each."""

        def __init__(self):
            self.timeouts = []

        async def get_msg(self, timeout=None):
            self.timeouts.append(timeout)
            if len(self.timeouts) < 4:
                raise Empty
            return {"msg_type": "execute_reply"}

    for timeout in (None, 300.0):
        ch = Channel()
        hl._sliced(ch)
        assert asyncio.run(ch.get_msg(timeout=timeout)) == {"msg_type": "execute_reply"}
        assert len(ch.timeouts) == 4
        assert all(t is not None and 0 <= t <= hl.POLL_SLICE for t in ch.timeouts), ch.timeouts

    # a deadline still ends the wait with Empty (nbclient then reports the cell's timeout)
    class Silent:
        async def get_msg(self, timeout=None):
            await asyncio.sleep(timeout)
            raise Empty

    ch = Silent()
    hl._sliced(ch, step=0.05)
    with pytest.raises(Empty):
        asyncio.run(ch.get_msg(timeout=0.2))


def test_a_hanging_cell_fails_after_the_notebooks_timeout(tmp_path):
    """The notebook's own per-cell timeout, not a 300 s default; the cell is named."""
    path = _notebook(
        tmp_path,
        "hang.ipynb",
        ["x = 1", "import time\ntime.sleep(600)", "y = 2"],
        execution={"timeout": 3},
    )
    res = _headless().run(path, kernel_env("offline", tmp_path), timeout=600)
    assert res.error is not None
    assert res.error.failing_cell_index == 1
    assert "timed out" in res.error.summary and "3 seconds" in res.error.summary, res.error.summary
    assert "time.sleep(600)" in res.error.trace


def test_a_broken_promise_fails_the_chapter(tmp_path):
    """Through ``pytest --nbmake``: fewer figures than promised, and a cache write offline."""
    book = tmp_path / "book"
    (book / "_ext").mkdir(parents=True)
    shutil.copy(BOOK / "conftest.py", book / "conftest.py")
    shutil.copy(BOOK / "_ext" / "lagolib_headless.py", book / "_ext" / "lagolib_headless.py")
    _notebook(
        book,
        "01_broken.ipynb",
        [
            "import os, pathlib\n"
            "pathlib.Path(os.environ['LAGOLIB_CACHE'], 'stray.txt').write_text('x')",
            "from IPython.display import Image, display\n"
            "import base64\n"
            "display(Image(data=base64.b64decode("
            "'iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg=='"
            ")))",
        ],
        lagolib={"figures": 2},
        execution={"timeout": 60},
    )
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST_", "LAGOLIB_OFFLINE"))}
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", *"--nbmake book -p no:cacheprovider -q -rf".split()]
        + ["-m", "offline"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode == 1, out
    assert "1 failed, 1 deselected" in out, out
    assert "01_broken.ipynb [offline]: rendered 1 figures, promises 2" in out, out
    assert "wrote ['stray.txt'] to the download cache offline" in out, out


def _code(nb):
    """The chapter's code cells, IPython magics and shell escapes blanked."""
    for k, cell in enumerate(nb.cells):
        if cell.cell_type == "code":
            lines = [
                "" if line.lstrip().startswith(("%", "!")) else line
                for line in cell.source.splitlines()
            ]
            yield k, "\n".join(lines)


@pytest.mark.parametrize("path", CHAPTERS, ids=_ids(CHAPTERS))
def test_chapter_uses_only_the_public_api(path):
    """No private module, function or attribute of lagolib (a leading underscore) in a chapter."""
    import ast

    bad = []
    for k, code in _code(_read(path)):
        tree = ast.parse(code)
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("lagolib"):
                parts = node.module.split(".") + [a.name for a in node.names]
                bad += [f"cell {k}: from {node.module} import {p}" for p in parts if p[:1] == "_"]
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.name.startswith("lagolib") and any(
                        p[:1] == "_" for p in a.name.split(".")
                    ):
                        bad.append(f"cell {k}: import {a.name}")
            elif isinstance(node, ast.Attribute):
                private = node.attr.startswith("_") and not node.attr.startswith("__")
                if private:
                    bad.append(f"cell {k}: .{node.attr}")
    assert not bad, f"{path.name} reaches into lagolib's private API: {bad}"


@pytest.mark.parametrize("path", CHAPTERS, ids=_ids(CHAPTERS))
def test_random_generators_are_seeded(path):
    """Every generator is seeded: no default_rng() without a seed, no legacy global np.random."""
    import re

    bad = []
    for k, code in _code(_read(path)):
        if re.search(r"default_rng\(\s*\)", code):
            bad.append(f"cell {k}: default_rng() without a seed")
        legacy = re.findall(
            r"np\.random\.(rand|randn|normal|uniform|random|randint|choice|shuffle|permutation)\(",
            code,
        )
        bad += [f"cell {k}: np.random.{f}() uses the unseeded global generator" for f in legacy]
        if re.search(r"^\s*import random\b|^\s*from random import", code, re.M):
            bad.append(f"cell {k}: Python's random module")
    assert not bad, f"{path.name}: {bad}"
