"""Shared helpers of the benchmark scripts: timing, and the peak memory of the process."""

import os
import resource
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path


def best_of(fn, repeat=5):
    """Smallest wall time of ``repeat`` calls of ``fn()``, in seconds."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def peak_rss_mib():
    """This process's peak resident memory (``ru_maxrss``), MiB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB on Linux


def vmhwm_mib():
    """Peak RSS from ``/proc/self/status`` (Linux ``VmHWM``), the cross-check of ``ru_maxrss``."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


def importable(module):
    """Whether ``module`` imports in a fresh interpreter (a peer may crash on import)."""
    code = f"import {module}"
    return subprocess.run([sys.executable, "-c", code], capture_output=True).returncode == 0


def package_version(pkg):
    """The installed version of distribution ``pkg``, or "not installed"."""
    try:
        return metadata.version(pkg)
    except metadata.PackageNotFoundError:
        return "not installed"


def install_label():
    """Which of lagolib's installs a run measures: the backend of its large systems."""
    from lagolib import linalg

    if linalg._mkl_runtime() is not None:
        return 'MKL PARDISO available to lagolib (`pip install "lagolib[fast]"`)'
    hidden = os.environ.get("LAGOLIB_MKL_RT", "").lower() == "off"
    why = "MKL hidden (`LAGOLIB_MKL_RT=off`)" if hidden else "no MKL"
    if linalg._have_cholmod():
        return (
            f"{why}, CHOLMOD from cvxopt: what the book's install gives "
            '(`pip install -e ".[book]"`, or `lagolib[cholmod]`)'
        )
    return f"{why}, no CHOLMOD: what `pip install lagolib` gives (qdldl)"
