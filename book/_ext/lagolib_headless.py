"""Running the chapters without a frontend: one client for the tests and for the site build.

Every headless run of a chapter — ``pytest --nbmake book/`` (``book/conftest.py``), the student
copies (``tests/test_exercises_book.py``) and ``jupyter-book build`` (``lagolib_site.py``) —
executes it with :class:`PassiveClient`, nbclient's ``NotebookClient`` with three changes:

* **It never writes to the kernel while a cell runs.**  nbclient mimics the Output widget of
  JupyterLab: each output an ``ipywidgets.interact`` callback prints is sent back to the kernel
  as a ``comm_msg`` on the shell channel, while the client waits on that same channel for the
  cell's reply.  Measured with nbclient 0.11, pyzmq 27.3 and ipykernel 7.4 over TCP (nbmake's
  and Jupyter Book's transport): 7 of 2100 interact cells had their reply, sent by the kernel
  within 0.05 s, noticed only when the wait timed out — the run idled for the whole cell timeout
  (300 s under nbmake's and Jupyter Book's defaults) and then went on as if nothing had happened
  (as in jupyter/nbclient#312); without the mimic, 0 of 2100.  The chapters' widget cells are
  tagged ``remove-output``, so the mimic adds nothing anyone reads: here it is removed, and what
  a callback prints is an ordinary output of its cell.
* **No wait on the kernel lasts longer than a second unchecked.**  The shell and IOPub waits are
  cut into slices of at most :data:`POLL_SLICE`; each slice ends with a real poll of the socket,
  so a wake-up the event loop missed costs at most one slice, never the cell timeout (with the
  mimic kept but the waits sliced, the 3 such cells of 1500 took 1.0 s each).
* **The kernel listens on IPC sockets, not TCP ports** (in a private folder, removed afterwards):
  jupyter_client picks a "free" port by binding and releasing it, and another process starting
  beside it can take the port first (seen as kernels that never answered under load).

A kernel that really hangs is stopped by the chapter's own per-cell timeout,
``metadata["execution"]["timeout"]``, which nbmake, Jupyter Book and :func:`run` all read.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
import time
from pathlib import Path
from queue import Empty

from nbclient import NotebookClient
from nbclient.util import run_sync

POLL_SLICE = 1.0  # seconds: the longest a wait on the kernel goes without a real poll
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def kernel_env(variant, cache, base=None):
    """The environment of a chapter's kernel.

    Parameters
    ----------
    variant : {"online", "offline"}
        ``online`` keeps the benchmark settings of ``base`` (in CI ``LAGOLIB_DATA`` names the
        mirror); ``offline`` removes ``LAGOLIB_DATA`` and sets ``LAGOLIB_OFFLINE=1``, so the
        chapters fall back to the shipped examples.
    cache : path-like
        ``LAGOLIB_CACHE`` of the kernel: offline always this (an empty folder), online only when
        ``base`` sets none (a test never touches the user's default cache).
    base : mapping, optional
        The environment to start from; ``os.environ`` by default.

    Returns
    -------
    dict
        ``base`` with the book's own asserts strict (``LAGOLIB_BOOK_STRICT=1``, see
        :class:`lagolib.exercises.bookkeeping`), matplotlib left to the kernel (``MPLBACKEND``
        removed: ipykernel then draws inline, where ``MPLBACKEND=Agg`` would silently render
        nothing), BLAS held to one thread (on a loaded machine threads fighting for the cores
        made a cell 50x slower), and the variant's data settings.
    """
    if variant not in ("online", "offline"):
        raise ValueError(f"kernel_env: variant must be 'online' or 'offline', not {variant!r}")
    env = dict(os.environ if base is None else base)
    env.pop("MPLBACKEND", None)
    env.update({k: "1" for k in THREAD_VARS})
    env["LAGOLIB_BOOK_STRICT"] = "1"  # the book's own asserts fail the run (bookkeeping())
    if variant == "offline":
        env.pop("LAGOLIB_DATA", None)
        env["LAGOLIB_OFFLINE"] = "1"
        env["LAGOLIB_CACHE"] = str(cache)
    else:
        env.pop("LAGOLIB_OFFLINE", None)
        env["LAGOLIB_CACHE"] = env.get("LAGOLIB_CACHE") or str(cache)
    return env


def _sliced(channel, step=POLL_SLICE):
    """Make ``channel.get_msg(timeout)`` poll the socket at least every ``step`` seconds."""
    wait = channel.get_msg

    async def get_msg(timeout=None):
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            left = step if deadline is None else min(step, max(0.0, deadline - time.monotonic()))
            try:
                return await wait(timeout=left)
            except Empty:
                if deadline is not None and time.monotonic() >= deadline:
                    raise

    channel.get_msg = get_msg


class PassiveClient(NotebookClient):
    """nbclient's ``NotebookClient`` for a chapter run without a frontend (see the module).

    Parameters
    ----------
    nb, km, **kw
        As for ``NotebookClient``.
    kernel_env : mapping, optional
        The kernel's environment (default: this process's).
    """

    def __init__(self, nb, km=None, *, kernel_env=None, **kw):
        # the kernel is stopped when the notebook is done (a run that owns it), at once: nothing
        # of it is kept, and a graceful shutdown waits on the kernel for about half a second
        kw.setdefault("shutdown_kernel", "immediate")
        super().__init__(nb, km=km, **kw)
        # no Output-widget mimic: nothing is sent to the kernel while a cell runs
        self.widget_registry = {}
        self._kernel_env = None if kernel_env is None else dict(kernel_env)
        self._sockets = None

    def create_kernel_manager(self):
        km = super().create_kernel_manager()
        self._sockets = tempfile.mkdtemp(prefix="lagolib-kernel-")
        km.transport = "ipc"
        km.ip = os.path.join(self._sockets, "k")
        return km

    async def async_start_new_kernel(self, **kwargs):
        if self._kernel_env is not None:
            kwargs.setdefault("env", self._kernel_env)
        return await super().async_start_new_kernel(**kwargs)

    async def async_start_new_kernel_client(self):
        kc = await super().async_start_new_kernel_client()
        _sliced(kc.shell_channel)
        _sliced(kc.iopub_channel)
        return kc

    async def async_execute(self, reset_kc=False, **kwargs):
        try:
            return await super().async_execute(reset_kc=reset_kc, **kwargs)
        finally:
            if self._sockets:
                shutil.rmtree(self._sockets, ignore_errors=True)
                self._sockets = None

    execute = run_sync(async_execute)


def run(path, env=None, *, timeout=300, verbose=False, kernel=None):
    """Execute the notebook at ``path`` with nbmake's runner and a :class:`PassiveClient`.

    Parameters
    ----------
    path : path-like
        The notebook; its kernel starts in the notebook's folder.
    env : mapping, optional
        The kernel's environment (see :func:`kernel_env`).
    timeout : int
        Per-cell timeout in seconds when the notebook's ``metadata["execution"]["timeout"]``
        sets none.
    verbose : bool
        nbmake's verbose flag.
    kernel : str, optional
        A kernel name overriding the notebook's (nbmake's ``--nbmake-kernel``).

    Returns
    -------
    nbmake.nb_result.NotebookResult
        The executed notebook (``.nb``) and the error, if a cell failed or timed out (``.error``).
    """
    from nbmake import nb_run  # a test tool: imported only when notebooks run as tests

    def client(nb, **kw):
        return PassiveClient(nb, kernel_env=env, **kw)

    runner = nb_run.NotebookRun(Path(path), timeout, verbose=verbose, kernel=kernel)
    original = nb_run.NotebookClient
    nb_run.NotebookClient = client  # nbmake builds its client by this name
    try:
        res = runner.execute()
    finally:
        nb_run.NotebookClient = original
    if res.error is not None:  # the last line of an IPython traceback, without its colors
        res.error.summary = _ANSI.sub("", res.error.summary)
    return res


def install():
    """Make nbclient's ``execute()`` (what Jupyter Book's executor calls) use a PassiveClient."""
    import nbclient.client

    if not issubclass(nbclient.client.NotebookClient, PassiveClient):
        nbclient.client.NotebookClient = PassiveClient
