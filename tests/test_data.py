"""The shipped data folder is exactly what data/make_data.py produces (nothing edited by hand)."""

import runpy
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent.parent / "data"


def test_make_data_reproduces_the_shipped_files(tmp_path):
    if not (DATA / "make_data.py").is_file():
        pytest.skip("not running from a source checkout")
    make = runpy.run_path(str(DATA / "make_data.py"))["make"]
    written = make(tmp_path)
    assert len(written) == 6
    for p in written:
        shipped = DATA / p.name
        assert shipped.read_bytes() == p.read_bytes(), (
            f"{shipped} differs from what make_data.py writes"
        )
    documented = (DATA / "README.md").read_text()
    for p in written:
        assert p.name in documented
