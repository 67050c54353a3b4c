"""The Radish laser logs in the registry, and LAGOLIB_DATA's several folders.

Tests of the real logs use conftest's ``benchmark`` fixture: skipped when ``LAGOLIB_DATA`` is
unset, failing when it is set but none of its folders holds a log (CI lists the pose-graph and
the laser mirrors, ``.ci/run``).  The others build their mirrors in ``tmp_path`` from a small
Carmen log written here, so they run everywhere.
"""

import gzip
import hashlib
import os
import re
import shutil

import numpy as np
import pytest
from test_datasets import server  # noqa: F401 (the loopback HTTP server fixture)

import lagolib
from lagolib import DatasetError, cli, datasets

LASER = ("aces_laser", "csail_laser", "fr079_laser", "intel_laser")

# two scans of four beams: the corrected poses (0, 0, 0) and (0.5, 0.25, 0.1); the timed ODOM
# line between them is the first pose plus odometry's increment (0.4, 0.2, 0.05)
_LOG = """\
# a Carmen log
FLASER 4 1.0 2.0 3.0 81.83 0 0 0 0 0 0 1.0 host 1.0
ODOM 0 0 0 0 0 0 1.0 pippo 0
ODOM 0.4 0.2 0.05 0 0 0 1.5 host 1.5
FLASER 4 1.5 2.5 3.5 4.5 0.5 0.25 0.1 0.5 0.25 0.1 2.0 host 2.0
ODOM 0.5 0.25 0.1 0 0 0 2.0 pippo 0
"""


def _write_log(folder, name="carmen/tiny.log.gz"):
    p = folder / name
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_bytes(gzip.compress(_LOG.encode(), mtime=0))
    return p


def _register(monkeypatch, name, source, url="https://example.invalid/tiny.log.gz"):
    """Register ``source`` (a Carmen log) as the laser dataset ``name``."""
    digest = hashlib.sha256(source.read_bytes()).hexdigest()
    rel = source.relative_to(source.parents[1]).as_posix()
    d = datasets.Dataset(name, rel, digest, url, "laser", 0, 0, "test", 2, 4)
    monkeypatch.setitem(datasets._REGISTRY, name, d)
    return d


def _env(monkeypatch, *folders):
    monkeypatch.setenv("LAGOLIB_DATA", os.pathsep.join(str(f) for f in folders))
    monkeypatch.delenv("LAGOLIB_OFFLINE", raising=False)


# ----------------------------------------------------------------------------- the real logs
def _sources_table(laser_root):
    """file -> (sha256, scans, beams) from the laser mirror's SOURCES.md."""
    rows = {}
    for line in (laser_root / "SOURCES.md").read_text(encoding="utf-8").splitlines():
        m = re.match(
            r"\| `(carmen/[^`]+)` \| \w+ \| \d+ \| ([0-9a-f]{64}) \| (\d+) \| (\d+) \|", line
        )
        if m:
            rows[m[1]] = (m[2], int(m[3]), int(m[4]))
    return rows


def test_the_laser_logs_through_two_folders(benchmark, monkeypatch, tmp_path):
    found = {name: benchmark(name) for name in [*LASER, "intel"]}  # from the environment's
    laser_root = found["intel_laser"].parents[1]
    graphs_root = found["intel"].parents[1]
    assert laser_root != graphs_root  # two mirrors, as CI has them
    empty = tmp_path / "empty"
    empty.mkdir()
    # an empty folder first, a trailing separator: the first folder that has a file wins
    _env(monkeypatch, empty, graphs_root, laser_root, "")
    monkeypatch.setattr(datasets, "_verified", {})  # hash every file again
    assert datasets.mirrors() == [empty, graphs_root, laser_root]
    assert datasets.path("intel") == graphs_root / "carlone-nano-pgo/input_INTEL_g2o.g2o"
    table = _sources_table(laser_root)
    assert len(table) == 4
    for name in LASER:
        d = datasets.info(name)
        p = datasets.path(name, download=False)  # checksum verified
        assert p == laser_root / d.relpath
        assert table[d.relpath] == (d.sha256, d.scans, d.beams)
        assert hashlib.sha256(p.read_bytes()).hexdigest() == d.sha256
        assert d.url.endswith(
            f"/acschaefer/ple/8af88b28759f8a48b1bf33083a85f2013907c41d/data/{d.relpath}"
        )
    assert {n: (datasets.info(n).scans, datasets.info(n).beams) for n in LASER} == {
        "aces_laser": (440, 180),
        "csail_laser": (406, 361),
        "fr079_laser": (4791, 360),
        "intel_laser": (910, 180),
    }


def test_load_intel_laser(benchmark, capsys):
    p = benchmark("intel_laser")
    log = datasets.load("intel_laser")
    assert isinstance(log, lagolib.scans.LaserLog)
    assert log.name == "intel_laser" and log.reference_kind == "gmapping"
    assert log.ranges.shape == (910, 180)
    np.testing.assert_allclose(np.degrees(log.angles[[0, 1, -1]]), [-90, -89, 89], atol=1e-12)
    with gzip.open(p, "rt") as f:
        first = next(line.split() for line in f if line.startswith("FLASER"))
    assert first[1] == "180"
    np.testing.assert_array_equal(log.reference[0], [float(t) for t in first[182:185]])
    np.testing.assert_array_equal(log.ranges[0], [float(t) for t in first[2:182]])
    loaded = datasets.load_laser_or_simulated("intel_laser")
    assert (loaded.source, loaded.offline) == ("intel_laser", False)
    np.testing.assert_array_equal(loaded.log.ranges, log.ranges)
    assert capsys.readouterr().out == (
        "Using the Radish laser log 'intel_laser' (910 scans of 180 beams; its reference poses "
        "are GMapping's estimate, not ground truth).\n"
    )


# ----------------------------------------------------------------------------- several folders
def test_the_first_folder_that_has_the_file_wins(monkeypatch, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    log_a, log_b = _write_log(a), _write_log(b)
    only_b = _write_log(b, "carmen/other.log.gz")
    _register(monkeypatch, "tiny", log_a)
    _register(monkeypatch, "other", only_b)
    _env(monkeypatch, a, b)
    assert datasets.path("tiny") == log_a and datasets.path("other") == only_b
    assert datasets.mirror() == a and datasets.available("other")
    _env(monkeypatch, b, a)
    assert datasets.path("tiny") == log_b and datasets.mirror() == b
    # the first copy must pass its checksum: a corrupt one is an error, not a reason to go on
    log_b.write_bytes(log_b.read_bytes()[:-1])  # cut short (a new size: not the verified file)
    with pytest.raises(
        DatasetError, match=rf"{re.escape(str(log_b))}: SHA-256 \w+ does not match the registry's"
    ):
        datasets.load("tiny")
    _env(monkeypatch, a, b)
    log = datasets.load("tiny")  # the good copy in a, read as a LaserLog named by the registry
    assert (log.name, log.ranges.shape, log.max_range) == ("tiny", (2, 4), 81.83)
    np.testing.assert_array_equal(log.reference, [[0, 0, 0], [0.5, 0.25, 0.1]])
    np.testing.assert_allclose(log.odometry[1], [0.4, 0.2, 0.05], atol=1e-15)


def test_a_file_in_none_of_the_folders_names_them_all(monkeypatch, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    _register(monkeypatch, "tiny", _write_log(tmp_path / "elsewhere"))
    b.mkdir()
    _env(monkeypatch, a, b)
    assert not datasets.available("tiny")
    with pytest.raises(DatasetError) as info:
        datasets.path("tiny")
    assert str(info.value).startswith(
        f"none of the LAGOLIB_DATA folders {a}, {b} has the file carmen/tiny.log.gz (dataset "
        "'tiny'); put the file from https://example.invalid/tiny.log.gz into one of them"
    )
    with pytest.raises(DatasetError, match="none of the LAGOLIB_DATA folders"):  # no stand-in
        datasets.load_laser_or_simulated("tiny", quiet=True)
    # one folder and empty entries: the one-folder message, as before
    _env(monkeypatch, "", a, "")
    assert datasets.mirrors() == [a]
    with pytest.raises(DatasetError, match=rf"^LAGOLIB_DATA={re.escape(str(a))} has no file"):
        datasets.path("tiny")


def test_every_folder_is_checked(monkeypatch, tmp_path):
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    value = f"{tmp_path}{os.pathsep}{a_file}"
    monkeypatch.setenv("LAGOLIB_DATA", value)
    for call in (datasets.mirrors, datasets.mirror, lambda: datasets.available("intel")):
        with pytest.raises(DatasetError) as info:
            call()
        assert str(info.value).startswith(
            f"LAGOLIB_DATA={value}: its folder {a_file} is a file, not a folder; name folders only"
        )
    value = f"{tmp_path}{os.pathsep}{tmp_path / 'nowhere'}"
    monkeypatch.setenv("LAGOLIB_DATA", value)
    with pytest.raises(
        DatasetError, match=r"its folder .*nowhere does not exist; list only existing"
    ):
        datasets.path("intel")
    monkeypatch.setenv("LAGOLIB_DATA", f"{tmp_path}{os.pathsep}~nosuchuser_lagolib/x")
    with pytest.raises(DatasetError, match=r"its folder ~nosuchuser_lagolib/x: cannot expand"):
        datasets.path("intel")
    monkeypatch.setenv("LAGOLIB_DATA", os.pathsep * 2)  # nothing but separators: unset
    assert datasets.mirrors() == [] and datasets.mirror() is None


def test_the_cli_lists_laser_logs_with_scans_and_beams(monkeypatch, tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    log = _write_log(b)
    _register(monkeypatch, "tiny", log)
    _env(monkeypatch, a, b)
    assert cli.main(["datasets"]) == 0
    out = capsys.readouterr().out
    assert f"benchmarks (from the mirrors LAGOLIB_DATA={a}{os.pathsep}{b}):" in out
    laser = out.split("laser logs (Carmen; their reference poses are GMapping's estimate")[1]
    assert f"\n  tiny              laser          2       4  {log}\n" in laser
    assert (
        "  intel_laser       laser        910     180  in none of the LAGOLIB_DATA folders" in laser
    )
    assert "intel_laser" not in out.split("laser logs")[0]  # not among the pose graphs
    assert cli.main(["info", "tiny"]) == 1
    assert "dataset 'tiny' is a laser log (Carmen), not a pose graph" in capsys.readouterr().err


# ----------------------------------------------------------------------------- download, fallback
def test_a_laser_log_downloaded_into_the_cache(server, monkeypatch, tmp_path, capsys):  # noqa: F811
    www, base = server
    source = _write_log(tmp_path / "src")
    shutil.copy(source, www / "tiny.log.gz")
    _register(monkeypatch, "tiny", source, base + "tiny.log.gz")
    monkeypatch.delenv("LAGOLIB_DATA", raising=False)
    monkeypatch.delenv("LAGOLIB_OFFLINE", raising=False)
    monkeypatch.setenv("LAGOLIB_CACHE", str(tmp_path / "cache"))
    loaded = datasets.load_laser_or_simulated("tiny")
    assert (loaded.source, loaded.offline, loaded.log.name) == ("tiny", False, "tiny")
    assert capsys.readouterr().out == (
        "Using the Radish laser log 'tiny' (2 scans of 4 beams; its reference poses are GMapping's "
        f"estimate, not ground truth; downloaded from {base}tiny.log.gz into {tmp_path / 'cache'}).\n"
    )
    assert (tmp_path / "cache" / "carmen__tiny.log.gz").read_bytes() == source.read_bytes()


def test_offline_the_simulated_log_stands_in(monkeypatch, tmp_path, capsys):
    monkeypatch.delenv("LAGOLIB_DATA", raising=False)
    monkeypatch.setenv("LAGOLIB_OFFLINE", "1")
    monkeypatch.setenv("LAGOLIB_CACHE", str(tmp_path / "cache"))
    loaded = datasets.load_laser_or_simulated("intel_laser")
    assert (loaded.source, loaded.offline) == ("simulated", True)
    assert loaded.log.reference_kind == "truth"
    k, n = loaded.log.ranges.shape
    assert capsys.readouterr().out == loaded.note + "\n"
    assert loaded.note == (
        f"Using a simulated laser log ({k} scans of {n} beams, its reference poses the ground "
        "truth) instead of 'intel_laser': it is not in the cache, and downloads are off "
        "(LAGOLIB_OFFLINE=1). For the real log, unset LAGOLIB_OFFLINE and run "
        "lagolib.datasets.path('intel_laser') once online, or set LAGOLIB_DATA to a mirror."
    )
    again = datasets.load_laser_or_simulated("intel_laser", quiet=True)  # seeded: the same log
    np.testing.assert_array_equal(again.log.ranges, loaded.log.ranges)
    assert capsys.readouterr().out == ""
    assert not (tmp_path / "cache").exists()


def test_laser_and_graph_loaders_refuse_each_others_names(monkeypatch, tmp_path):
    monkeypatch.setenv("LAGOLIB_OFFLINE", "1")
    with pytest.raises(
        DatasetError, match=r"'intel' is a graph file, not a laser log; laser logs: aces"
    ):
        datasets.load_laser_or_simulated("intel")
    with pytest.raises(
        DatasetError, match=r"'intel_laser' is a laser log, not a graph; use load_laser"
    ):
        datasets.load_or_example("intel_laser", "grid100")
    for bad in (["intel_laser"], None):
        with pytest.raises(lagolib.OptionTypeError, match=r"name must be a str.*'intel_laser'"):
            datasets.load_laser_or_simulated(bad)
    with pytest.raises(lagolib.OptionTypeError, match=r"quiet must be True or False"):
        datasets.load_laser_or_simulated("intel_laser", quiet=1)
