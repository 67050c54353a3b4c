"""Dataset registry: mirror lookup, checksums, and a real pooch download from a loopback server."""

import hashlib
import http.server
import shutil
import threading
from functools import partial

import numpy as np
import pytest

import lagolib
from lagolib import DatasetError, datasets


def test_unknown_name_lists_the_known_ones():
    with pytest.raises(DatasetError, match=r"unknown dataset 'intell'; known: .*intel.*m3500"):
        datasets.info("intell")
    with pytest.raises(DatasetError, match=r"unknown example 'square'; shipped: square_loop"):
        datasets.example("square")


def test_registry_entries_are_complete():
    for name in datasets.names():
        d = datasets.info(name)
        assert len(d.sha256) == 64 and int(d.sha256, 16) >= 0
        assert d.url.startswith("https://") and d.url.endswith(d.relpath.split("/")[-1])
        assert d.kind in ("graph", "poses")
    assert {"intel", "m3500", "csail", "fr079", "mit", "city10000"} <= set(datasets.names())


def test_mirror_without_the_file_is_an_error_not_a_skip(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGOLIB_DATA", str(tmp_path))
    assert not datasets.available("intel")
    with pytest.raises(
        DatasetError, match=r"LAGOLIB_DATA=.* has no file carlone-nano-pgo/input_INTEL_g2o.g2o"
    ):
        datasets.path("intel")


def test_corrupt_mirror_file_fails_its_checksum(tmp_path, monkeypatch):
    monkeypatch.setenv("LAGOLIB_DATA", str(tmp_path))
    target = tmp_path / datasets.info("ring").relpath
    target.parent.mkdir(parents=True)
    shutil.copy(datasets.data_dir() / "grid100.g2o", target)
    assert datasets.available("ring")
    with pytest.raises(
        DatasetError, match=r"SHA-256 .* does not match the registry's .* for dataset 'ring'"
    ):
        datasets.load("ring")


@pytest.fixture
def server(tmp_path):
    """An HTTP server on 127.0.0.1 serving tmp_path/www; yields (folder, base_url); stops by itself."""
    www = tmp_path / "www"
    www.mkdir()
    handler = partial(http.server.SimpleHTTPRequestHandler, directory=str(www))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        yield www, f"http://127.0.0.1:{httpd.server_address[1]}/"
    finally:
        httpd.shutdown()
        httpd.server_close()


def _register(monkeypatch, name, source, url):
    digest = hashlib.sha256(source.read_bytes()).hexdigest()
    d = datasets.Dataset(name, f"test/{source.name}", digest, url, "graph", 100, 131, "test")
    monkeypatch.setitem(datasets._REGISTRY, name, d)
    return d


def test_download_into_the_cache_then_offline(server, monkeypatch, tmp_path):
    www, base = server
    monkeypatch.delenv("LAGOLIB_DATA", raising=False)
    monkeypatch.setenv("LAGOLIB_CACHE", str(tmp_path / "cache"))
    shutil.copy(datasets.data_dir() / "grid100.g2o", www / "grid100.g2o")
    _register(monkeypatch, "served", datasets.data_dir() / "grid100.g2o", base + "grid100.g2o")
    assert not datasets.available("served")
    with pytest.raises(DatasetError, match=r"not in the cache .* download=False"):
        datasets.path("served", download=False)
    g = datasets.load("served")
    assert (g.n, g.m) == (100, 131)
    assert datasets.available("served")
    (www / "grid100.g2o").unlink()  # the server no longer has it: the cache must be used
    np.testing.assert_array_equal(datasets.load("served", download=False).poses, g.poses)


def test_download_with_wrong_checksum_is_refused(server, monkeypatch, tmp_path):
    www, base = server
    monkeypatch.delenv("LAGOLIB_DATA", raising=False)
    monkeypatch.setenv("LAGOLIB_CACHE", str(tmp_path / "cache"))
    _register(monkeypatch, "served", datasets.data_dir() / "grid100.g2o", base + "grid100.g2o")
    shutil.copy(datasets.data_dir() / "square_loop.g2o", www / "grid100.g2o")  # wrong bytes
    with pytest.raises(DatasetError, match=r"failed its checksum"):
        datasets.path("served")
    assert not datasets.available("served")


def test_download_failure_names_the_fix(server, monkeypatch, tmp_path):
    _, base = server
    monkeypatch.delenv("LAGOLIB_DATA", raising=False)
    monkeypatch.setenv("LAGOLIB_CACHE", str(tmp_path / "cache"))
    _register(monkeypatch, "served", datasets.data_dir() / "grid100.g2o", base + "missing.g2o")
    with pytest.raises(DatasetError, match=r"could not download dataset 'served'.*LAGOLIB_DATA"):
        datasets.path("served")


@pytest.mark.parametrize("name", datasets.examples())
def test_examples_load_with_aligned_truth(name):
    ex = datasets.example(name)
    assert ex.truth.shape == (ex.graph.n, 3)
    assert ex.graph.is_connected
    # the truth explains the measurements: chi2(truth) is about 3m, the odometry guess far worse
    assert lagolib.chi2(ex.graph, ex.truth) < 4 * ex.graph.m
    assert lagolib.chi2(ex.graph) > 3 * lagolib.chi2(ex.graph, ex.truth)
