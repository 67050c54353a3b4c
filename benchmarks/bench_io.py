"""Reading speed of lagolib.io against GTSAM's reader, in one process.

    python benchmarks/bench_io.py            # needs LAGOLIB_DATA (or network for the download)

Prints, for each file, the best of several reads for lagolib and for GTSAM's ``readG2o``/``load2D``
(the peer), and their ratio.  Target for issue 2: city10000 (20,687 edges) in < 0.5 s.
"""

from __future__ import annotations

import tracemalloc

from _timing import best_of  # benchmarks/ is on sys.path when run as a script

import lagolib
from lagolib import datasets


def main():
    try:
        import gtsam
    except ImportError:  # pragma: no cover
        gtsam = None
    print(
        f"{'file':<12} {'edges':>6} {'lagolib [ms]':>13} {'gtsam [ms]':>11} {'ratio':>6} {'peak MiB':>9}"
    )
    for name in ["intel", "m3500", "csail_toro", "city10000"]:
        path = str(datasets.path(name))
        g = lagolib.read(path)
        t_ours = best_of(lambda path=path: lagolib.read(path))
        tracemalloc.start()
        lagolib.read(path)
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
        if gtsam is None:
            t_peer = float("nan")
        elif path.endswith(".graph"):
            fmt = gtsam.NoiseFormat.NoiseFormatTORO
            t_peer = best_of(lambda p=path, f=fmt: gtsam.load2D(p, None, 10**9, False, False, f))
        else:
            t_peer = best_of(lambda p=path: gtsam.readG2o(p, False))
        print(
            f"{name:<12} {g.m:>6} {1e3 * t_ours:>13.1f} {1e3 * t_peer:>11.1f} "
            f"{t_ours / t_peer:>6.2f} {peak:>9.1f}"
        )


if __name__ == "__main__":
    main()
