"""Shared timing helper of the benchmark scripts (each runs lagolib and its peer in one process)."""

import time


def best_of(fn, repeat=5):
    """Smallest wall time of ``repeat`` calls of ``fn()``, in seconds."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)
