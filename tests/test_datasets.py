"""Dataset registry: mirror lookup, checksums, and a real pooch download from a loopback server."""

import hashlib
import http.server
import os
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
        assert d.kind in ("graph", "poses", "laser")
        # a laser log has scans and beams, a graph file vertices and edges: never both
        assert (d.scans > 0 and d.beams > 0) == (d.kind == "laser") == (d.vertices == d.edges == 0)
    assert {"intel", "m3500", "csail", "fr079", "mit", "city10000"} <= set(datasets.names())
    assert {n for n in datasets.names() if datasets.info(n).kind == "laser"} == {
        "intel_laser",
        "fr079_laser",
        "csail_laser",
        "aces_laser",
    }


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
    thread = threading.Thread(target=httpd.serve_forever, args=(0.05,), daemon=True)
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
    with pytest.raises(
        DatasetError, match=r"not in the cache .*downloads are off \(download=False\)"
    ):
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


# ----------------------------------------------------------------------------- issue 22: the truth
def _cache(monkeypatch, folder):
    monkeypatch.delenv("LAGOLIB_DATA", raising=False)
    monkeypatch.delenv("LAGOLIB_OFFLINE", raising=False)
    monkeypatch.setenv("LAGOLIB_CACHE", str(folder))


def test_corrupt_cached_file_is_reported_as_corrupt(monkeypatch, tmp_path, capsys):
    _cache(monkeypatch, tmp_path)
    cached = tmp_path / datasets.info("intel").relpath.replace("/", "__")
    cached.write_text("VERTEX_SE2 0 0 0 0\n")  # a cut-off download: wrong bytes
    with pytest.raises(DatasetError, match=r"the cached file .* of dataset 'intel' is corrupt"):
        datasets.path("intel")
    loaded = datasets.load_or_example("intel", "manhattan200")
    assert not loaded.real and loaded.name == "manhattan200"
    assert f"the cached file {cached} is corrupt" in loaded.note
    assert "delete it and run lagolib.datasets.path('intel')" in loaded.note
    assert "no network" not in loaded.note
    assert capsys.readouterr().out == loaded.note + "\n"


def test_offline_is_named_as_the_reason(monkeypatch, tmp_path):
    _cache(monkeypatch, tmp_path)
    monkeypatch.setenv("LAGOLIB_OFFLINE", "1")
    with pytest.raises(DatasetError) as info:
        datasets.path("intel")
    text = str(info.value)
    assert "downloads are off (LAGOLIB_OFFLINE=1)" in text and "download=False" not in text
    note = datasets.load_or_example("intel", "grid100", quiet=True).note
    assert "downloads are off (LAGOLIB_OFFLINE=1)" in note and "unset LAGOLIB_OFFLINE" in note
    monkeypatch.setenv("LAGOLIB_OFFLINE", "0")
    note = datasets.load_or_example("intel", "grid100", download=False, quiet=True).note
    assert "downloads are off (download=False)" in note


@pytest.mark.parametrize("value", ["maybe", "2", "offline"])
def test_offline_values_that_mean_nothing_are_refused(monkeypatch, tmp_path, value):
    _cache(monkeypatch, tmp_path)
    monkeypatch.setenv("LAGOLIB_OFFLINE", value)
    with pytest.raises(lagolib.OptionError, match=rf"LAGOLIB_OFFLINE='{value}' means neither"):
        datasets.path("intel")
    with pytest.raises(lagolib.OptionError):  # a typo is not a reason to fall back silently
        datasets.load_or_example("intel", "grid100", quiet=True)


@pytest.mark.parametrize("value", ["abc", "0", "-3", "nan", "inf"])
def test_bad_timeout_is_refused(monkeypatch, tmp_path, value):
    _cache(monkeypatch, tmp_path)
    monkeypatch.setenv("LAGOLIB_TIMEOUT", value)
    with pytest.raises(lagolib.OptionError, match=r"LAGOLIB_TIMEOUT=.* positive number of seconds"):
        datasets.path("intel")


@pytest.mark.parametrize("variable", ["LAGOLIB_DATA", "LAGOLIB_CACHE"])
def test_folder_variables_naming_a_file_or_an_unknown_user(monkeypatch, tmp_path, variable):
    monkeypatch.delenv("LAGOLIB_DATA", raising=False)
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    monkeypatch.setenv(variable, str(a_file))
    for call in (lambda: datasets.path("intel"), lambda: datasets.available("intel")):
        with pytest.raises(DatasetError, match=rf"{variable}=.*a_file is a file, not a folder"):
            call()
    with pytest.raises(DatasetError, match=rf"{variable}=.*is a file"):  # never the stand-in
        datasets.load_or_example("intel", "grid100", quiet=True)
    monkeypatch.setenv(variable, "~nosuchuser_lagolib/x")
    with pytest.raises(DatasetError, match=rf"{variable}=~nosuchuser_lagolib/x: cannot expand"):
        datasets.path("intel")


def test_mirror_folder_that_does_not_exist(monkeypatch, tmp_path):
    monkeypatch.setenv("LAGOLIB_DATA", str(tmp_path / "nowhere"))
    for call in (lambda: datasets.path("intel"), lambda: datasets.available("intel")):
        with pytest.raises(DatasetError, match=r"LAGOLIB_DATA=.*nowhere: no such folder"):
            call()


def test_cache_folder_that_does_not_exist_is_named(monkeypatch, tmp_path):
    _cache(monkeypatch, tmp_path / "not" / "yet")
    with pytest.raises(DatasetError, match=r"the folder .*not/yet does not exist yet"):
        datasets.path("intel", download=False)
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    _cache(monkeypatch, a_file / "below")
    with pytest.raises(DatasetError, match=r"LAGOLIB_CACHE=.*below: cannot create the folder"):
        datasets.path("intel")


@pytest.mark.parametrize("value", ["no", 1, 0, None, "False"])
def test_download_and_quiet_must_be_bools(monkeypatch, tmp_path, value):
    _cache(monkeypatch, tmp_path)
    monkeypatch.setenv("LAGOLIB_OFFLINE", "1")
    calls = [
        lambda: datasets.path("intel", download=value),
        lambda: datasets.load("intel", download=value),
        lambda: datasets.load_or_example("intel", "grid100", download=value),
        lambda: datasets.load_or_example("intel", "grid100", quiet=value),
    ]
    for call in calls:
        with pytest.raises(lagolib.OptionTypeError, match=r"must be True or False"):
            call()


@pytest.mark.parametrize("bad", [["intel"], ("intel",), {"intel"}, None, 3, b"intel"])
def test_names_must_be_strings(bad):
    calls = [
        datasets.info,
        datasets.path,
        datasets.available,
        datasets.load,
        datasets.example,
        lambda n: datasets.load_or_example(n, "grid100"),
        lambda n: datasets.load_or_example("intel", n),
    ]
    for call in calls:
        with pytest.raises(lagolib.OptionTypeError, match=r"must be a str"):
            call(bad)


def test_download_prints_nothing_and_the_note_says_where_it_came_from(
    server, monkeypatch, tmp_path, capfd
):
    www, base = server
    _cache(monkeypatch, tmp_path / "cache")
    shutil.copy(datasets.data_dir() / "grid100.g2o", www / "grid100.g2o")
    _register(monkeypatch, "served", datasets.data_dir() / "grid100.g2o", base + "grid100.g2o")
    capfd.readouterr()
    datasets.path("served")
    out, err = capfd.readouterr()
    assert "Downloading" not in err and out == ""
    (tmp_path / "cache" / "test__grid100.g2o").unlink()
    loaded = datasets.load_or_example("served", "square_loop")
    out, err = capfd.readouterr()
    assert "Downloading" not in err
    assert out == (
        f"Using the public benchmark 'served' (100 poses, 131 edges; downloaded from "
        f"{base}grid100.g2o into {tmp_path / 'cache'}).\n"
    )
    assert loaded.real
    loaded = datasets.load_or_example("served", "square_loop", quiet=True)
    assert loaded.note == "Using the public benchmark 'served' (100 poses, 131 edges)."


def test_download_failures_are_one_short_sentence(server, monkeypatch, tmp_path):
    import socket

    _, base = server
    _cache(monkeypatch, tmp_path / "cache")
    _register(monkeypatch, "served", datasets.data_dir() / "grid100.g2o", base + "missing.g2o")
    with pytest.raises(DatasetError) as info:
        datasets.path("served")
    assert info.value.reason == "the download failed: 127.0.0.1 answered HTTP 404 File not found"
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    url = f"http://127.0.0.1:{port}/grid100.g2o"
    _register(monkeypatch, "served", datasets.data_dir() / "grid100.g2o", url)
    with pytest.raises(DatasetError) as info:
        datasets.path("served")
    assert info.value.reason == "the download failed: 127.0.0.1 refused the connection"
    assert len(str(info.value)) < 250 and "Max retries" not in str(info.value)
    assert list((tmp_path / "cache").iterdir()) == []


class _HalfHandler(http.server.BaseHTTPRequestHandler):
    """Sends half of ``body`` and then either hangs (until ``release``) or closes the connection."""

    body = b""
    sent = None  # threading.Event, set once half the body is out
    release = None  # threading.Event that ends a hang
    hang = True

    def do_GET(self):  # noqa: N802 (http.server's name)
        self.send_response(200)
        self.send_header("Content-Length", str(len(self.body)))
        self.end_headers()
        self.wfile.write(self.body[: len(self.body) // 2])
        self.wfile.flush()
        self.sent.set()
        if self.hang:
            self.release.wait(60)

    def log_message(self, *args):
        pass


@pytest.fixture
def half_server():
    handler = type(
        "H",
        (_HalfHandler,),
        {
            "body": (datasets.data_dir() / "grid100.g2o").read_bytes(),
            "sent": threading.Event(),
            "release": threading.Event(),
        },
    )
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    httpd.daemon_threads = True
    thread = threading.Thread(target=httpd.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    try:
        yield handler, f"http://127.0.0.1:{httpd.server_address[1]}/grid100.g2o"
    finally:
        handler.release.set()
        httpd.shutdown()
        httpd.server_close()


_CHILD = """
import os, sys
if sys.argv[3] == "named":
    del os.O_TMPFILE  # as on a system without anonymous files: the named .part file
from lagolib import datasets
d = datasets.Dataset("served", "test/grid100.g2o", sys.argv[2], sys.argv[1], "graph", 100, 131, "")
datasets._REGISTRY["served"] = d
datasets.path("served")
"""


@pytest.mark.skipif(os.name != "posix", reason="kills the downloading process with SIGKILL")
@pytest.mark.parametrize("kind", ["anonymous", "named"])
def test_download_killed_half_way_leaves_no_stray_file(half_server, monkeypatch, tmp_path, kind):
    import signal
    import subprocess
    import sys

    handler, url = half_server
    cache = tmp_path / "cache"
    cache.mkdir()
    digest = hashlib.sha256(handler.body).hexdigest()
    env = dict(os.environ, LAGOLIB_CACHE=str(cache), LAGOLIB_OFFLINE="0", LAGOLIB_DATA="")
    child = subprocess.Popen([sys.executable, "-c", _CHILD, url, digest, kind], env=env)
    try:
        assert handler.sent.wait(120), "the child never asked for the file"
        # the child has the first half, and is waiting for the rest: kill it outright
        child.send_signal(signal.SIGKILL)
        child.wait(60)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    left = sorted(p.name for p in cache.iterdir())
    if kind == "anonymous":
        assert left == []  # the kernel freed the anonymous file with the process
    else:
        assert len(left) <= 1 and all(n.startswith(".test__grid100.g2o.") for n in left)
    # the next download, from a server that sends the whole file, sweeps what a dead process left
    handler.hang = False
    www = tmp_path / "www"
    www.mkdir()
    (www / "grid100.g2o").write_bytes(handler.body)
    handler_full = partial(http.server.SimpleHTTPRequestHandler, directory=str(www))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler_full)
    thread = threading.Thread(target=httpd.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    try:
        full = f"http://127.0.0.1:{httpd.server_address[1]}/grid100.g2o"
        d = datasets.Dataset("served", "test/grid100.g2o", digest, full, "graph", 100, 131, "")
        monkeypatch.setitem(datasets._REGISTRY, "served", d)
        _cache(monkeypatch, cache)
        got = datasets.path("served")
    finally:
        httpd.shutdown()
        httpd.server_close()
    assert sorted(p.name for p in cache.iterdir()) == ["test__grid100.g2o"]
    assert got.read_bytes() == handler.body


@pytest.mark.parametrize("kind", ["anonymous", "named"])
def test_download_broken_off_leaves_nothing(half_server, monkeypatch, tmp_path, kind):
    handler, url = half_server
    handler.hang = False  # send half, then close the connection
    _cache(monkeypatch, tmp_path / "cache")
    if kind == "named":
        monkeypatch.delattr(os, "O_TMPFILE", raising=False)
    _register(monkeypatch, "served", datasets.data_dir() / "grid100.g2o", url)
    with pytest.raises(DatasetError) as info:
        datasets.path("served")
    assert "broke off before the whole file arrived" in info.value.reason
    assert list((tmp_path / "cache").iterdir()) == []
