"""Shared fixtures.

Tests that read the public benchmarks use :func:`benchmark`: it skips the test when
``LAGOLIB_DATA`` is unset (a user's machine without the mirror), and *fails* when the variable is
set but a file is missing or corrupt, so CI — which sets it — can never skip them silently.
"""

import os
from pathlib import Path

import pytest
from hypothesis import settings

from lagolib import datasets

# no doctests here: --doctest-modules would import this file as a test module named "conftest",
# the name book/conftest.py's module has too (import file mismatch)
collect_ignore = ["conftest.py"]

# property tests are deterministic: the same examples on every run, no example database
settings.register_profile("lagolib", derandomize=True, database=None, deadline=None)
settings.load_profile("lagolib")


def _mirror_or_skip():
    root = datasets.mirror()
    if root is None:
        pytest.skip("LAGOLIB_DATA is not set: benchmark files not available")
    return root


@pytest.fixture
def mirror():
    """The LAGOLIB_DATA folder (skips when unset)."""
    root = _mirror_or_skip()
    assert root.is_dir(), f"LAGOLIB_DATA={root} is not a folder"
    return root


@pytest.fixture
def benchmark():
    """``benchmark(name)`` -> checksum-verified path of a registered benchmark file."""
    _mirror_or_skip()

    def get(name):
        return datasets.path(name, download=False)

    return get


@pytest.fixture
def tmp(tmp_path):
    """Write a small text file: ``tmp("name.g2o", "lines...")`` -> Path."""

    def write(name, text):
        p = Path(tmp_path) / name
        p.write_text(text)
        return p

    return write


@pytest.fixture(autouse=True)
def _no_user_cache(tmp_path_factory, monkeypatch):
    """Never touch the user's download cache from a test."""
    if not os.environ.get("LAGOLIB_CACHE"):
        monkeypatch.setenv("LAGOLIB_CACHE", str(tmp_path_factory.mktemp("lagolib-cache")))
