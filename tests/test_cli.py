"""The ``lagolib`` command (lagolib/cli.py).

End to end: the installed console script runs in a subprocess once per command.  The many
option and error cases call :func:`lagolib.cli.main` in-process.  The graphs are small: a
simulated two-lap loop with anisotropic, rotated information (some edges isotropic, some with
rotation–translation coupling), written to a temporary folder.
"""

import json
import os
import re
import shutil
import struct
import subprocess
import sys

import numpy as np
import pytest

import lagolib
from lagolib import certify, cli, datasets, se2, simulate, topology
from lagolib.gauss_newton import optimize
from lagolib.lago import lago, regularize

LAGOLIB = shutil.which("lagolib")
script = pytest.mark.skipif(
    LAGOLIB is None,
    reason="the 'lagolib' console script is not on PATH (pip install -e . puts it there)",
)


# ----------------------------------------------------------------------------- helpers
def _png_size(path):
    data = path.read_bytes()[:24]
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    return struct.unpack(">II", data[16:24])


def _run(*args, env=None):
    full_env = {**os.environ, **(env or {})}
    return subprocess.run(
        [LAGOLIB, *map(str, args)], capture_output=True, text=True, env=full_env, timeout=300
    )


def _call(capsys, *args):
    """``(exit status, stdout, stderr)`` of ``lagolib.cli.main(args)``."""
    rc = cli.main([str(a) for a in args])
    out, err = capsys.readouterr()
    return rc, out, err


def _one_error_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("lagolib: error: "), err
    assert "Traceback" not in err
    return lines[0]


def _anisotropic_graph():
    """Two laps of a 10-pose square; information R(phi) diag(a, b) R(phi)^T with a != b, except
    every 5th edge isotropic; every 7th edge gets rotation–translation coupling."""
    sim = simulate.loop_world(laps=2, poses_per_lap=12, rng=13, sigma_xy=0.05, sigma_theta=0.02)
    g = sim.graph
    rng = np.random.default_rng(2011)
    m = g.m
    phi = rng.uniform(-np.pi, np.pi, m)
    a = rng.uniform(100.0, 400.0, m)
    b = a * rng.uniform(2.0, 20.0, m)
    iso = np.arange(m) % 5 == 0
    b[iso] = a[iso]
    R = se2.rotation(phi)
    info = np.zeros((m, 3, 3))
    info[:, :2, :2] = R @ (np.eye(2) * np.stack([a, b], -1)[:, None, :]) @ np.swapaxes(R, 1, 2)
    info[iso, 0, 1] = info[iso, 1, 0] = 0.0
    info[iso, 0, 0] = info[iso, 1, 1] = a[iso]
    info[:, 2, 2] = 2500.0
    coupled = (np.arange(m) % 7 == 3) & ~iso
    info[coupled, 0, 2] = info[coupled, 2, 0] = 0.3 * np.sqrt(a[coupled] * 2500.0)
    graph = lagolib.PoseGraph(g.poses, g.edges, g.measurements, info, ids=g.ids)
    return graph, sim.truth, int(iso.sum()), int(coupled.sum())


@pytest.fixture(scope="module")
def aniso(tmp_path_factory):
    """``(path, graph, truth path, isotropic count, coupled count)``."""
    folder = tmp_path_factory.mktemp("cli")
    graph, truth, n_iso, n_coupled = _anisotropic_graph()
    path = folder / "aniso.g2o"
    lagolib.write(graph, path)
    truth_path = folder / "truth.txt"
    lagolib.write_poses(truth_path, truth, graph.ids)
    return path, lagolib.read(path), truth_path, n_iso, n_coupled


def test_the_simulated_graph_has_what_the_tests_count_on(aniso):
    path, g, _, n_iso, n_coupled = aniso
    assert 0 < n_iso < g.m and 0 < n_coupled < g.m
    assert g.is_connected and g.loop_closure.any()
    # anisotropic and rotated: off-diagonal translation information on the other edges
    assert np.count_nonzero(g.information[:, 0, 1]) == g.m - n_iso


# ----------------------------------------------------------------------------- the script
@script
def test_script_info_prints_the_librarys_numbers(aniso):
    path, g, _, n_iso, n_coupled = aniso
    proc = _run("info", path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    out = proc.stdout
    n_odo = int(g.odometric.sum())
    assert re.search(rf"^poses\s+{g.n} \(ids 0\.\.{g.n - 1}\)$", out, re.M), out
    assert re.search(
        rf"^edges\s+{g.m}: {n_odo} odometric .*, {g.m - n_odo} loop closures$", out, re.M
    )
    assert "connected (1 component)" in out
    assert "odometric chain   complete" in out
    for tree in topology.TREES:
        reg = regularize(g, tree, margin_warning=0.0)
        assert re.search(
            rf"^  {tree}\s+{reg.n_regularized} of {reg.chords.size} chords", out, re.M
        ), (tree, out)
    assert f"isotropic (I11 = I22, I12 = 0) on {n_iso} of {g.m} edges" in out
    assert f"anisotropic on {g.m - n_iso}" in out
    assert f"coupling (I13 or I23 != 0) on {n_coupled} of {g.m} edges" in out
    chi = float(re.search(r"^chi2\s+(\S+) at the file's poses", out, re.M).group(1))
    assert chi == pytest.approx(lagolib.chi2(g), rel=1e-9)


@script
def test_script_solve_writes_what_lagolib_and_gtsam_read_back(aniso, tmp_path):
    gtsam = pytest.importorskip("gtsam")
    path, g, _, _, _ = aniso
    out, png = tmp_path / "solved.g2o", tmp_path / "solved.png"
    proc = _run(
        "solve", path, "--method", "lago+gn", "--progress", "-o", out, "--plot", png, "--dpi", 40
    )
    assert proc.returncode == 0, proc.stderr
    # the library's answer, computed here
    res = optimize(g, lago(g).poses, method="gn")
    # stdout: one summary line; stderr: the progress
    (summary,) = proc.stdout.strip().splitlines()
    m = re.fullmatch(
        r"lago\+gn: chi2 (\S+) -> (\S+) \(t2v\), (\d+) iterations, \S+ s; wrote (.+) and (.+)",
        summary,
    )
    assert m, summary
    assert float(m.group(1)) == pytest.approx(lagolib.chi2(g), rel=1e-9)
    assert float(m.group(2)) == pytest.approx(res.chi2, rel=1e-9)
    assert int(m.group(3)) == res.iterations
    lines = proc.stderr.strip().splitlines()
    assert lines[0].startswith("[lago+gn] start: chi2")
    assert lines[1].startswith("[lago] tree min_uncertainty:")
    iters = [ln for ln in lines if ln.startswith("[gn] iter")]
    assert len(iters) == res.iterations + 1  # iteration 0 and every accepted step
    for ln in iters[1:]:
        assert re.search(r"chi2 \S+  decrease \S+  \|dx\| \S+ .* t \d+\.\d{3} s$", ln), ln
    assert "Traceback" not in proc.stderr
    # the file: lagolib reads back the solved poses and the same edges; chi2 as the solver's
    back = lagolib.read(out)
    np.testing.assert_array_equal(back.ids, g.ids)
    np.testing.assert_array_equal(back.edges, g.edges)
    np.testing.assert_array_equal(back.information, g.information)
    np.testing.assert_allclose(back.poses, res.poses, rtol=0, atol=1e-9)
    assert lagolib.chi2(back) == pytest.approx(res.chi2, rel=1e-9)
    # ... and so does GTSAM (the oracle), to the printed precision
    factors, values = gtsam.readG2o(str(out), False)
    assert factors.size() == g.m and values.size() == g.n
    for vid, p in zip(back.ids.tolist(), back.poses):
        q = values.atPose2(vid)
        assert q.x() == pytest.approx(p[0], abs=1e-12)
        assert q.y() == pytest.approx(p[1], abs=1e-12)
        assert abs(se2.wrap_angle(q.theta() - p[2])) < 1e-12
    assert _png_size(png) == (240, 240)  # 6 inches at 40 dpi


def test_solve_writes_what_g2o_reads_back(aniso, capsys, tmp_path):
    """g2o itself (its Python bindings, g2opy) loads the solved file: the same vertices, edges,
    measurements, information, and the same χ² — g2o's χ² is the notes' t2v error."""
    g2o = pytest.importorskip("g2opy", reason="g2o's Python bindings (g2opy) are not installed")
    path, g, _, _, _ = aniso
    out = tmp_path / "solved.g2o"
    assert _call(capsys, "solve", path, "-m", "lago+gn", "-o", out)[0] == 0
    back = lagolib.read(out)
    opt = g2o.SparseOptimizer()
    assert opt.load(str(out))
    assert len(opt.vertices()) == g.n and len(opt.edges()) == g.m
    for vid, p in zip(back.ids.tolist(), back.poses):
        np.testing.assert_allclose(opt.vertex(vid).estimate().to_vector(), p, rtol=0, atol=1e-12)
    by_pair = {(int(e.vertices()[0].id()), int(e.vertices()[1].id())): e for e in opt.edges()}
    for (i, j), z, info in zip(back.ids[back.edges].tolist(), back.measurements, back.information):
        e = by_pair[(i, j)]
        np.testing.assert_allclose(e.measurement().to_vector(), z, rtol=0, atol=1e-12)
        np.testing.assert_allclose(e.information(), info, rtol=1e-12)
    opt.set_algorithm(
        g2o.OptimizationAlgorithmGaussNewton(g2o.BlockSolverSE2(g2o.LinearSolverEigenSE2()))
    )
    opt.initialize_optimization()
    opt.compute_active_errors()
    assert opt.chi2() == pytest.approx(lagolib.chi2(back), rel=1e-9)


@script
def test_script_plot_draws_a_png_of_the_expected_size(aniso, tmp_path):
    path, g, truth, _, _ = aniso
    png = tmp_path / "plot.png"
    proc = _run("plot", path, "--poses", truth, "--ellipses", "--every", 3, "-o", png, "--dpi", 30)
    assert proc.returncode == 0, proc.stderr
    n_ell = len(range(0, g.n, 3))
    assert proc.stdout.strip() == (
        f"wrote {png} ({g.n} poses, {g.m} edges with {n_ell} 95 % confidence ellipses)"
    )
    assert _png_size(png) == (180, 180)


@script
def test_script_datasets_lists_every_benchmark_and_its_url_offline(tmp_path):
    env = {"LAGOLIB_DATA": "", "LAGOLIB_CACHE": str(tmp_path), "LAGOLIB_OFFLINE": "1"}
    proc = _run("datasets", env=env)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert f"into the cache {tmp_path}" in out
    for name in datasets.names():
        d = datasets.info(name)
        vertices = d.vertices if d.vertices or d.kind != "graph" else "-"
        a, b = (d.scans, d.beams) if d.kind == "laser" else (vertices, d.edges)  # laser: own table
        pattern = (
            rf"^  {re.escape(name)}\s+{d.kind}\s+{a}\s+{b}  "
            rf"would be fetched from {re.escape(d.url)}$"
        )
        assert re.search(pattern, out, re.M), (name, out)
    for name in datasets.examples():
        ex = datasets.example(name)
        assert re.search(rf"^  {name}\s+graph\s+{ex.graph.n}\s+{ex.graph.m}  ", out, re.M)


@script
def test_script_errors_are_one_line_and_a_traceback_only_with_debug(tmp_path):
    bad = tmp_path / "bad.g2o"
    bad.write_text("VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 x 1 0 0 1 0 1\n")
    proc = _run("info", bad)
    assert proc.returncode == 1
    line = _one_error_line(proc.stderr)
    assert line.startswith(f"lagolib: error: {bad}:3: dtheta is not a number: 'x'")
    assert proc.stdout == ""
    proc = _run("--debug", "info", bad)
    assert proc.returncode == 1
    assert "Traceback (most recent call last)" in proc.stderr
    assert "lagolib.errors.ParseError" in proc.stderr
    assert proc.stderr.strip().splitlines()[-1] == line
    proc = _run("solve", bad, "--method", "newton", "-o", tmp_path / "x.g2o")
    assert proc.returncode == 2
    assert "invalid choice: 'newton'" in _one_error_line(proc.stderr)


# ----------------------------------------------------------------------------- info
def test_info_json_equals_the_library(aniso, capsys):
    path, g, _, n_iso, n_coupled = aniso
    rc, out, err = _call(capsys, "info", path, "--json")
    assert rc == 0 and err == ""
    s = json.loads(out)
    assert s["format"] == "g2o" and s["vertex_lines"] is True
    assert (s["poses"], s["edges"]) == (g.n, g.m)
    assert s["odometric"] == int(g.odometric.sum())
    assert s["loop_closures"] == int(g.loop_closure.sum())
    assert s["components"] == 1 and s["chain_gaps"] == [] and s["chain_backward"] == []
    assert s["cycles"] == topology.cyclomatic_number(g)
    for tree in topology.TREES:
        reg = regularize(g, tree, margin_warning=0.0)
        assert s["regularization"][tree] == {
            "chords": int(reg.chords.size),
            "regularized": reg.n_regularized,
            "near_boundary": int(reg.unreliable(0.1).size),
        }
    assert (s["isotropic"], s["coupled"]) == (n_iso, n_coupled)
    assert s["chi2"] == lagolib.chi2(g)
    rc, out, _ = _call(capsys, "info", path, "--json", "--error", "log")
    assert json.loads(out)["chi2"] == lagolib.chi2(g, error="log") != s["chi2"]


def test_info_names_the_gaps_of_a_broken_chain_and_the_components(capsys, tmp_path):
    # ids 0..3 chained, 4 missing between 3 and 5, 5 -> 6, a loop closure 0 -> 3, and vertex 9
    # only linked backwards (9 -> 6 is stored as 6 <- 9)
    lines = [f"VERTEX_SE2 {i} {i} 0 0" for i in (0, 1, 2, 3, 5, 6, 9)]
    info = "1 0 0 1 0 1"
    for i, j in [(0, 1), (1, 2), (2, 3), (0, 3), (5, 6), (9, 6)]:
        lines.append(f"EDGE_SE2 {i} {j} 1 0 0 {info}")
    p = tmp_path / "broken.g2o"
    p.write_text("\n".join(lines) + "\n")
    rc, out, err = _call(capsys, "info", p)
    assert rc == 0, err
    assert "NOT connected: 2 components (sizes 4, 3)" in out
    assert "odometric chain   broken: 1 consecutive pair(s) without an edge: 3 -> 5" in out
    assert "1 link(s) stored backward only (k+1 -> k): 6 -> 9" in out
    assert out.count("n/a: the graph is not connected") == 3
    rc, out, _ = _call(capsys, "info", p, "--json")
    s = json.loads(out)
    assert s["chain_gaps"] == [[3, 5]] and s["chain_backward"] == [[6, 9]]
    assert s["cycles"] == 6 - 7 + 2


def test_info_says_when_the_poses_are_the_odometry_guess(capsys, tmp_path):
    p = tmp_path / "edges_only.g2o"
    lines = (datasets.data_dir() / "grid100.g2o").read_text().splitlines()
    p.write_text("".join(ln + "\n" for ln in lines if ln.startswith("EDGE_SE2")))
    g = lagolib.read(p)
    rc, out, err = _call(capsys, "info", p)
    assert rc == 0, err
    chi = float(re.search(r"^chi2\s+(\S+) at the odometry guess", out, re.M).group(1))
    assert chi == pytest.approx(lagolib.chi2(g), rel=1e-9)
    assert "the file has no vertex lines" in out


def test_info_reads_toro_files_and_dataset_names(aniso, capsys, tmp_path):
    _, g, _, _, _ = aniso
    p = tmp_path / "aniso.graph"
    lagolib.write(g, p)
    rc, out, _ = _call(capsys, "info", p, "--json")
    assert rc == 0 and json.loads(out)["format"] == "toro"
    rc, out, _ = _call(capsys, "info", "square_loop", "--json")
    s = json.loads(out)
    assert rc == 0 and (s["poses"], s["edges"]) == (160, 279)
    assert s["file"] == str(datasets.data_dir() / "square_loop.g2o")


def test_info_on_intel_matches_carlone_table_1(benchmark, capsys):
    g = lagolib.read(benchmark("intel"))
    rc, out, _ = _call(capsys, "info", benchmark("intel"), "--json")
    s = json.loads(out)
    assert rc == 0
    assert (s["poses"], s["edges"], s["odometric"], s["loop_closures"]) == (1228, 1483, 1227, 256)
    reg = regularize(g, "odometric", margin_warning=0.0)
    assert s["regularization"]["odometric"]["regularized"] == reg.n_regularized
    assert s["isotropic"] == 0 and s["coupled"] == 0
    assert s["chi2"] == lagolib.chi2(g)


# ----------------------------------------------------------------------------- solve
def _solved(capsys, path, tmp_path, *options, name="out.g2o"):
    out = tmp_path / name
    rc, stdout, err = _call(capsys, "solve", path, "-o", out, *options)
    assert rc == 0, err
    return lagolib.read(out), stdout, err


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        (("--method", "lago"), lambda g: lago(g).poses),
        (("--method", "lago", "--tree", "odometric"), lambda g: lago(g, "odometric").poses),
        (("--method", "gn"), lambda g: optimize(g).poses),
        (("--method", "lm", "-n", "3"), lambda g: optimize(g, method="lm", max_iterations=3).poses),
        (
            ("--method", "gn", "--error", "log"),
            lambda g: optimize(g, error="log").poses,
        ),
        (
            ("--method", "lago+gn", "--tree", "bfs", "--iterations", "1"),
            lambda g: optimize(g, lago(g, "bfs").poses, max_iterations=1).poses,
        ),
    ],
    ids=["lago", "lago-odometric", "gn", "lm-3", "gn-log", "lago+gn-bfs-1"],
)
def test_solve_writes_the_solvers_poses(aniso, capsys, tmp_path, options, expected):
    path, g, _, _, _ = aniso
    back, out, err = _solved(capsys, path, tmp_path, *options)
    want = expected(g)
    np.testing.assert_allclose(back.poses, want, rtol=0, atol=1e-12)
    error = "log" if "log" in options else "t2v"
    chi = float(re.search(r"-> (\S+) ", out).group(1))
    assert chi == pytest.approx(lagolib.chi2(g, want, error=error), rel=1e-9)
    assert err == ""  # no --progress: nothing on stderr


def test_solve_lm_says_when_it_stopped_before_converging(aniso, capsys, tmp_path):
    path, g, _, _, _ = aniso
    res = optimize(g, method="lm", max_iterations=2)
    assert not res.converged
    _, out, _ = _solved(capsys, path, tmp_path, "--method", "lm", "-n", "2")
    assert ", 2 iterations, " in out
    assert "(not converged: reached --iterations 2)" in out


def test_solve_progress_for_gn_is_one_line_per_iteration_on_stderr(aniso, capsys, tmp_path):
    path, g, _, _, _ = aniso
    res = optimize(g)
    _, out, err = _solved(capsys, path, tmp_path, "--method", "gn", "--progress")
    assert len(out.strip().splitlines()) == 1 and out.startswith("gn: chi2 ")
    lines = err.strip().splitlines()
    assert lines[0] == f"[gn] start: chi2 {lagolib.chi2(g):.10g} at the file's poses"
    assert len(lines) == 1 + res.iterations + 1
    for k, (line, chi) in enumerate(zip(lines[1:], res.chi2_history)):
        assert line.startswith(f"[gn] iter {k:3d}  chi2 {chi:.10g}")
        assert re.search(r"  t \d+\.\d{3} s$", line)


def test_solve_sgd(aniso, capsys, tmp_path):
    sgd = pytest.importorskip("lagolib.sgd")
    path, g, _, _, _ = aniso
    res = sgd.sgd(g, iterations=4)
    back, out, err = _solved(capsys, path, tmp_path, "--method", "sgd", "-n", "4", "--progress")
    np.testing.assert_allclose(back.poses, res.poses, rtol=0, atol=1e-12)
    assert f"-> {res.chi2:.10g} (t2v), 4 iterations" in out
    iters = [ln for ln in err.splitlines() if ln.startswith("[sgd] iter")]
    assert len(iters) == 4
    for k, (line, chi) in enumerate(zip(iters, res.chi2_history[1:]), start=1):
        assert line.startswith(f"[sgd] iter {k:4d}  chi2 {chi:.10g}  decrease ")


def test_solve_writes_toro_for_dot_graph(aniso, capsys, tmp_path):
    path, g, _, _, _ = aniso
    back, _, _ = _solved(capsys, path, tmp_path, "--method", "gn", name="out.graph")
    assert lagolib.io.detect_format(tmp_path / "out.graph") == "toro"
    np.testing.assert_allclose(back.poses, optimize(g).poses, rtol=0, atol=1e-12)
    # TORO's convention is a rotation away: a few units in the last place of the largest entry
    np.testing.assert_allclose(back.information, g.information, rtol=0, atol=1e-12 * 1e4)


# ----------------------------------------------------------------------------- certify
def _field(out, label):
    """The first word after ``label`` at the start of a summary line of ``certify``."""
    m = re.search(rf"^{re.escape(label)}\s+(\S+)", out, re.M)
    assert m, (label, out)
    return m.group(1)


def _number(out, label):
    return float(_field(out, label))


def _stage_names(out):
    """The stage names of the ``stages`` block of ``certify`` (lines ``  NAME  12.3 ms  ...``)."""
    return re.findall(r"^  (\S.*?)\s+\d+\.\d ms  ", out, re.M)


@script
def test_script_certify_an_example_prints_the_librarys_numbers(tmp_path):
    g = datasets.example("square_loop").graph
    res = certify.solve(g)
    extra = certify.certify(certify.chordal_problem(g), res.chordal_poses, eigenvalues=3)
    assert res.certified and res.escapes == 0  # the library's verdict the CLI must report
    out_path = tmp_path / "optimal.g2o"
    proc = _run("certify", "square_loop", "--eigenvalues", 3, "-o", out_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""  # no --progress: nothing on stderr
    out = proc.stdout
    assert re.search(rf"^graph\s+{g.n} poses, {g.m} edges \(", out, re.M), out
    start = re.search(r"^start\s+LAGO, spanning tree min_uncertainty: chi2 (\S+)$", out, re.M)
    assert start and float(start.group(1)) == pytest.approx(res.start_chi2, rel=1e-9)
    assert _stage_names(out) == [s["stage"] for s in res.stages]
    assert _number(out, "chi2") == pytest.approx(res.chi2, rel=1e-9)
    assert _number(out, "chordal f") == pytest.approx(res.f, rel=1e-9)
    assert _field(out, "certified") == "yes:"
    assert _number(out, "lambda_min") == pytest.approx(extra.eigenvalues[0], rel=1e-6, abs=1e-9)
    assert _number(out, "lower bound") == pytest.approx(res.lower_bound, rel=1e-9)
    assert _number(out, "gap") == pytest.approx(res.gap, rel=1e-5)
    assert res.lower_bound <= res.f
    assert _field(out, "escapes") == "0" and _field(out, "reason") == "certified"
    for k, lam in enumerate(extra.eigenvalues, start=1):
        assert float(_field(out, f"  lambda_{k}")) == pytest.approx(lam, rel=1e-6, abs=1e-9)
    assert extra.eigenvalues.size == 3 and extra.eigenvalues[-1] > 1.0  # a gap above 0
    assert _field(out, "wrote") == str(out_path)
    back = lagolib.read(out_path)
    np.testing.assert_allclose(back.poses, res.poses, rtol=0, atol=1e-9)
    assert lagolib.chi2(back) == pytest.approx(res.chi2, rel=1e-9)


@script
def test_script_certify_mit_from_odometry_escapes_to_the_certified_optimum(benchmark):
    """GN from the file's poses stops at χ² 770.66 (a local minimum the certificate rejects); one
    escape reaches the certified optimum χ² 41.163, chordal f 40.2407 (SE-Sync's Table 1)."""
    proc = _run("certify", benchmark("mit"), "--initial", "odometry", "--progress")
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert _number(out, "chi2") == pytest.approx(41.163, abs=1e-3)
    assert _number(out, "chordal f") == pytest.approx(40.2407, abs=5e-5)
    assert _field(out, "certified") == "yes:"
    assert _field(out, "escapes") == "1"
    assert re.search(r"^reason\s+certified after 1 escape\(s\), through rank 2$", out, re.M)
    assert _number(out, "lower bound") <= _number(out, "chordal f")
    names = _stage_names(out)
    assert names[:3] == ["Gauss-Newton", "chordal polish", "certificate"]
    assert "escape to rank 2" in names
    first = re.search(r"^  certificate\s+\S+ ms  certified no  lambda_min (\S+)$", out, re.M)
    assert first and float(first.group(1)) < 0  # the GN local minimum: rejected
    gn = re.search(r"^  Gauss-Newton\s+\S+ ms  chi2 (\S+)", out, re.M)
    assert float(gn.group(1)) == pytest.approx(770.66, abs=0.01)
    # --progress: the same stages on stderr as they end, stamped; stdout holds only the summary
    err = proc.stderr.strip().splitlines()
    assert err[0] == "[certify] start: the file's poses, at most 10 escape(s)"
    stamped = [ln for ln in err[1:] if re.search(r"  t \d+\.\d{3} s$", ln)]
    assert len(stamped) == len(err) - 1 == len(names)
    for line, name in zip(stamped, names):
        assert line.startswith(f"[certify] {name} ")
    assert "[certify]" not in out and "Traceback" not in proc.stderr


def test_certify_mit_without_escapes_is_not_certified(benchmark, capsys, tmp_path):
    out_path = tmp_path / "local.g2o"
    rc, out, err = _call(
        capsys,
        "certify",
        benchmark("mit"),
        "--initial",
        "odometry",
        "--max-escapes",
        0,
        "-o",
        out_path,
    )
    assert rc == cli.NOT_CERTIFIED == 3, err
    assert err == ""
    assert _field(out, "certified") == "no:"
    f, bound = _number(out, "chordal f"), _number(out, "lower bound")
    assert f == pytest.approx(749.371, abs=1e-3)  # the chordal minimum next to GN's 770.66
    assert _number(out, "chi2") == pytest.approx(770.66, abs=0.01)
    assert bound < f
    assert _number(out, "lambda_min") < 0
    assert _number(out, "gap") == pytest.approx(f - bound, rel=1e-5)
    assert _field(out, "escapes") == "0"
    assert "not certified: the budget of --max-escapes 0 ran out" in out
    assert "escape to rank" not in out
    # -o writes the chi2 poses, certified or not
    assert lagolib.chi2(lagolib.read(out_path)) == pytest.approx(_number(out, "chi2"), rel=1e-9)


def test_solve_certify_prints_the_certificate_and_writes_the_same_file(capsys, tmp_path):
    g = datasets.example("grid100").graph
    plain, checked = tmp_path / "plain.g2o", tmp_path / "checked.g2o"
    rc, out_plain, _ = _call(capsys, "solve", "grid100", "-m", "lago+gn", "-o", plain)
    assert rc == 0
    rc, out, err = _call(capsys, "solve", "grid100", "-m", "lago+gn", "--certify", "-o", checked)
    assert rc == 0, err
    assert checked.read_bytes() == plain.read_bytes()  # --certify does not change the output
    # the library's numbers: polish the chordal cost from the solved poses, then certify
    solved = lagolib.read(checked)
    problem = certify.chordal_problem(g)
    ref = certify.refine(problem, solved.poses)
    cert = certify.certify(problem, ref.poses)
    assert cert.certified
    lines = out.strip().splitlines()
    timeless = [re.sub(r"\d+\.\d{3} s", "T s", text) for text in (lines[0], out_plain.strip())]
    assert timeless[0] == timeless[1].replace(str(plain), str(checked))  # the same summary line
    assert _number(out, "chordal f") == pytest.approx(cert.f, rel=1e-9)
    assert f"{ref.iterations} Newton steps" in out
    assert _field(out, "certified") == "yes:"
    assert _field(out, "lambda_min") == ">"  # "> -eta": certified by the factorization alone
    assert _number(out, "lower bound") == pytest.approx(cert.lower_bound, rel=1e-9)
    assert cert.lower_bound <= cert.f
    assert _number(out, "gap") == pytest.approx(cert.gap, rel=1e-5)
    assert err == ""


def test_solve_certify_a_local_minimum_exits_3(benchmark, capsys, tmp_path):
    """Gauss–Newton from MIT's file poses: a local minimum; the file is written all the same."""
    plain, checked = tmp_path / "plain.g2o", tmp_path / "checked.g2o"
    assert _call(capsys, "solve", benchmark("mit"), "-m", "gn", "-o", plain)[0] == 0
    rc, out, err = _call(
        capsys, "solve", benchmark("mit"), "-m", "gn", "--certify", "--progress", "-o", checked
    )
    assert rc == cli.NOT_CERTIFIED, err
    assert checked.read_bytes() == plain.read_bytes()
    assert _field(out, "certified") == "no:"
    assert _number(out, "lambda_min") < 0
    assert _number(out, "lower bound") < _number(out, "chordal f")
    assert re.search(r"^\[certify\] certificate: certified no, lambda_min -\S+, ", err, re.M)


@pytest.mark.parametrize(
    ("args", "status", "message"),
    [
        (("--max-escapes", "-1"), 2, "argument --max-escapes: expected a non-negative integer"),
        (("--max-escapes", "1.5"), 2, "argument --max-escapes: expected a non-negative integer"),
        (("--eta", "nan"), 2, "argument --eta: expected a finite non-negative number; got 'nan'"),
        (("--eta", "-0.001"), 2, "argument --eta: expected a finite non-negative number"),
        (("--eigenvalues", "x"), 2, "argument --eigenvalues: expected a positive integer; got 'x'"),
        (("--eigenvalues", "0"), 2, "argument --eigenvalues: expected a positive integer; got 0"),
        (("--eigenvalues", "101"), 2, "--eigenvalues 101: S~ has 100 eigenvalues"),
        (("--initial", "gn"), 2, "argument --initial: invalid choice: 'gn'"),
        (("--initial", "odometry", "--tree", "bfs"), 2, "--tree chooses LAGO's spanning tree"),
        (("-o", "{tmp}/o.txt"), 2, "-o {tmp}/o.txt: cannot tell the format"),
        (("--method", "gn"), 2, "unrecognized arguments: --method gn"),
    ],
)
def test_certify_bad_options_name_the_option(capsys, tmp_path, args, status, message):
    rc, out, err = _call(capsys, "certify", "grid100", *(a.format(tmp=tmp_path) for a in args))
    assert rc == status, err
    assert out == ""
    line = _one_error_line(err)
    assert message.format(tmp=tmp_path) in line
    assert line.endswith("(see 'lagolib certify --help')")


@pytest.mark.parametrize(
    ("command", "graph", "message"),
    [
        (("certify",), "one", "has 1 pose(s); a certificate of global optimality needs at least 2"),
        (("solve", "--certify", "-o", "{tmp}/o.g2o"), "one", "needs at least 2 poses"),
        (("certify",), "split", "the graph is not connected: 2 components (sizes 2, 2)"),
        (("certify", "--initial", "odometry"), "split", "the graph is not connected"),
        (("solve", "-m", "lm", "--certify", "-o", "{tmp}/o.g2o"), "split", "is not connected"),
    ],
    ids=["certify-1-pose", "solve-1-pose", "certify-split", "certify-split-odo", "solve-split"],
)
def test_certify_graphs_it_cannot_certify_get_a_lagolib_error(
    capsys, tmp_path, command, graph, message
):
    files = {
        "one": "VERTEX_SE2 0 0 0 0\n",
        "split": "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nVERTEX_SE2 2 2 0 0\n"
        "VERTEX_SE2 3 3 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\nEDGE_SE2 2 3 1 0 0 1 0 0 1 0 1\n",
    }
    path = tmp_path / f"{graph}.g2o"
    path.write_text(files[graph])
    argv = [command[0], path, *(a.format(tmp=tmp_path) for a in command[1:])]
    rc, out, err = _call(capsys, *argv)
    assert rc == 1, err
    assert out == ""
    line = _one_error_line(err)
    assert line.startswith(f"lagolib: error: {path}: ") and message in line
    assert not (tmp_path / "o.g2o").exists()


def test_certify_help_documents_the_exit_status(capsys):
    rc, out, _ = _call(capsys, "certify", "--help")
    assert rc == 0
    text = " ".join(out.split())
    assert "exit status: 0 certified globally optimal; 3 ran, but NOT certified" in text
    assert "--max-escapes N" in out and "(default: 10)" in out
    rc, out, _ = _call(capsys, "solve", "--help")
    assert "--certify" in out and "exit status 3 when not certified" in " ".join(out.split())
    rc, out, _ = _call(capsys, "--help")
    assert "3 not certified" in out


# ----------------------------------------------------------------------------- plot, datasets
def test_plot_the_graph_at_its_own_poses(aniso, capsys, tmp_path):
    path, g, _, _, _ = aniso
    png = tmp_path / "g.png"
    rc, out, err = _call(capsys, "plot", path, "-o", png, "--dpi", 20, "--title", "a title")
    assert rc == 0, err
    assert out.strip() == f"wrote {png} ({g.n} poses, {g.m} edges)"
    assert _png_size(png) == (120, 120)


def test_plot_poses_from_a_graph_file_and_an_svg(aniso, capsys, tmp_path):
    path, g, _, _, _ = aniso
    solved = tmp_path / "solved.g2o"
    assert _call(capsys, "solve", path, "-m", "gn", "-o", solved)[0] == 0
    svg = tmp_path / "g.svg"
    rc, _, err = _call(capsys, "plot", path, "--poses", solved, "-o", svg)
    assert rc == 0, err
    assert svg.read_text().lstrip().startswith("<?xml")


def test_datasets_with_the_mirror(mirror, capsys):
    rc, out, err = _call(capsys, "datasets", "--json")
    assert rc == 0, err
    rows = {r["name"]: r for r in json.loads(out)["datasets"]}
    assert sorted(rows) == datasets.names()
    for name, r in rows.items():
        assert r["status"] == "mirror", r
        assert r["where"] == str(datasets.path(name, download=False))  # the first folder with it
        assert (r["vertices"], r["edges"], r["scans"], r["beams"]) == (
            datasets.info(name).vertices,
            datasets.info(name).edges,
            datasets.info(name).scans,
            datasets.info(name).beams,
        )


def test_datasets_from_the_cache(capsys, monkeypatch, tmp_path):
    monkeypatch.setenv("LAGOLIB_DATA", "")
    monkeypatch.setenv("LAGOLIB_CACHE", str(tmp_path))
    d = datasets.info("intel")
    (tmp_path / d.relpath.replace("/", "__")).write_text("cached\n")
    rc, out, _ = _call(capsys, "datasets", "--json")
    rows = {r["name"]: r for r in json.loads(out)["datasets"]}
    assert rows["intel"]["status"] == "cache"
    assert rows["intel"]["where"] == str(tmp_path / d.relpath.replace("/", "__"))
    assert rows["m3500"]["status"] == "url"
    assert rows["m3500"]["where"] == f"would be fetched from {datasets.info('m3500').url}"


# ----------------------------------------------------------------------------- errors
@pytest.mark.parametrize(
    ("args", "status", "message"),
    [
        (("info", "{tmp}/missing.g2o"), 1, "lagolib: error: {tmp}/missing.g2o: no such file"),
        (("info", "{tmp}"), 1, "lagolib: error: {tmp}: is a folder"),
        (("info", "ring_truth"), 1, "dataset 'ring_truth' holds ground-truth poses, not a graph"),
        (("info", "{bad}"), 1, "lagolib: error: {bad}:2: unknown tag 'FIX' in a g2o file"),
        (("solve", "{good}", "-m", "foo", "-o", "{tmp}/o.g2o"), 2, "invalid choice: 'foo'"),
        (("solve", "{good}", "-o", "{tmp}/o.g2o", "--bogus"), 2, "unrecognized arguments: --bogus"),
        (("solve", "{good}"), 2, "the following arguments are required: -o/--output"),
        (("solve", "{good}", "-m", "gn", "--tree", "bfs", "-o", "{tmp}/o.g2o"), 2, "--tree is"),
        (("solve", "{good}", "-m", "lago", "-n", "5", "-o", "{tmp}/o.g2o"), 2, "--iterations does"),
        (("solve", "{good}", "-n", "0", "-o", "{tmp}/o.g2o"), 2, "positive integer; got 0"),
        (("solve", "{good}", "-n", "x", "-o", "{tmp}/o.g2o"), 2, "positive integer; got 'x'"),
        (("solve", "{good}", "--tree", "dfs", "-o", "{tmp}/o.g2o"), 2, "invalid choice: 'dfs'"),
        (("solve", "{good}", "-o", "{tmp}/o.txt"), 2, "-o {tmp}/o.txt: cannot tell the format"),
        (("solve", "{good}", "-o", "{tmp}/no/o.g2o"), 1, "the folder {tmp}/no does not exist"),
        (("solve", "{good}", "-o", "{tmp}/o.g2o", "--plot", "{tmp}/p.xyz"), 2, "'.xyz'"),
        (("solve", "{split}", "-o", "{tmp}/o.g2o"), 1, "the graph is not connected: 2 components"),
        (("solve", "{split}", "-m", "gn", "-o", "{tmp}/o.g2o"), 1, "H is singular"),
        (("plot", "{good}", "--poses", "{tmp}/none.txt", "-o", "{tmp}/p.png"), 1, "no such file"),
        (("plot", "{good}", "--poses", "{few}", "-o", "{tmp}/p.png"), 1, "missing ids 3, 4"),
        (("plot", "{good}", "--sigma", "-1", "-o", "{tmp}/p.png"), 2, "positive number"),
        (("plot", "{good}", "--dpi", "100000", "-o", "{tmp}/p.png"), 2, "from 10 to 2000 dpi"),
        (("plot", "{good}", "--dpi", "1", "-o", "{tmp}/p.png"), 2, "from 10 to 2000 dpi"),
        (("plot", "{good}", "--poses", "{tmp}", "-o", "{tmp}/p.png"), 1, "is a folder"),
        (
            ("solve", "{good}", "-m", "gn", "-o", "{tmp}/o.g2o", "--plot", "{tmp}/no/p.png"),
            1,
            "the folder {tmp}/no does not exist",
        ),
        (("bogus",), 2, "invalid choice: 'bogus'"),
        ((), 2, "a command is required"),
    ],
)
def test_errors_print_one_line_and_set_the_exit_status(
    aniso, capsys, tmp_path, args, status, message
):
    path, g, _, _, _ = aniso
    bad = tmp_path / "bad.g2o"
    bad.write_text("VERTEX_SE2 0 0 0 0\nFIX 0\n")
    split = tmp_path / "split.g2o"
    split.write_text(
        "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nVERTEX_SE2 2 2 0 0\n"
        "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n"
    )
    few = tmp_path / "few.txt"
    lagolib.write_poses(few, g.poses[:3], g.ids[:3])
    names = {"tmp": tmp_path, "bad": bad, "good": path, "split": split, "few": few}
    rc, out, err = _call(capsys, *(a.format(**names) for a in args))
    assert rc == status, err
    assert out == ""
    assert message.format(**names) in _one_error_line(err)
    assert not (tmp_path / "o.g2o").exists()


def test_a_plot_that_cannot_be_written_leaves_no_output(aniso, capsys, tmp_path, monkeypatch):
    path = aniso[0]

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr("matplotlib.figure.Figure.savefig", refuse)
    rc, out, err = _call(
        capsys, "solve", path, "-m", "gn", "-o", tmp_path / "o.g2o", "--plot", tmp_path / "p.png"
    )
    assert rc == 1 and out == ""
    assert "--plot" in _one_error_line(err) and "nothing was written" in err
    assert not (tmp_path / "o.g2o").exists()


def test_sgd_from_an_optimum_warns_that_it_went_up(aniso, capsys, tmp_path):
    path = aniso[0]
    assert _call(capsys, "solve", path, "-m", "lago+gn", "-o", tmp_path / "opt.g2o")[0] == 0
    rc, out, err = _call(
        capsys, "solve", tmp_path / "opt.g2o", "-m", "sgd", "-n", "3", "-o", tmp_path / "s.g2o"
    )
    assert rc == 0
    assert "lagolib: warning: --method sgd ended at chi2" in err and "above" in err


def test_debug_shows_the_traceback(capsys, tmp_path):
    rc, _, err = _call(capsys, "info", tmp_path / "missing.g2o", "--debug")
    assert rc == 1
    assert "Traceback (most recent call last)" in err
    assert err.strip().splitlines()[-1].startswith("lagolib: error: ")


def test_interrupt_exits_130_without_a_traceback(capsys, monkeypatch, aniso):
    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_cmd_info", interrupted)
    rc, out, err = _call(capsys, "info", aniso[0])
    assert rc == 130
    assert err == "lagolib: interrupted\n"


def test_an_internal_error_is_one_line_that_asks_for_debug(capsys, monkeypatch, aniso):
    def broken(args):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(cli, "_cmd_info", broken)
    rc, _, err = _call(capsys, "info", aniso[0])
    assert rc == 1
    line = _one_error_line(err)
    assert "internal error: ZeroDivisionError: division by zero" in line
    assert "--debug" in line


def test_warnings_are_one_line_each(capsys, tmp_path):
    p = tmp_path / "fix.g2o"
    p.write_text("VERTEX_SE2 0 0 0 0\nFIX 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n")
    rc, out, err = _call(capsys, "info", p, "--ignore-unknown")
    assert rc == 0
    assert (
        err == f"lagolib: warning: {p}: skipped 1 line(s) with tags lagolib does not read: 1 FIX\n"
    )
    assert "poses             2 (ids 0..1)" in out


@pytest.mark.parametrize("command", ["info", "solve", "certify", "plot", "datasets"])
def test_help_on_every_command_has_a_description_and_an_example(capsys, command):
    rc, out, err = _call(capsys, command, "--help")
    assert rc == 0 and err == ""
    assert out.startswith(f"usage: lagolib {command}")
    assert re.search(rf"^examples?:\n  (\S+=\S+ )?lagolib {command}", out, re.M), out


def test_top_level_help_lists_the_commands(capsys):
    rc, out, _ = _call(capsys, "--help")
    assert rc == 0
    for command in ("info", "solve", "certify", "plot", "datasets", "book"):
        assert re.search(rf"^    {command}\s", out, re.M)


def test_book_is_still_dispatched(capsys):
    rc, out, _ = _call(capsys, "book", "--help")
    assert rc == 0 and "student-copies" in out
    rc, _, err = _call(capsys, "--debug", "book", "nonsense")
    assert rc == 2 and "invalid choice: 'nonsense'" in err


def test_module_runs_as_a_script():
    proc = subprocess.run(
        [sys.executable, "-m", "lagolib.cli", "solve", "--help"], capture_output=True, text=True
    )
    assert proc.returncode == 0 and "lago+gn" in proc.stdout


# ----------------------------------------------------------------------------- plot --ellipses
def _weak_square(tmp_path, n=240):
    """One lap of a 20 m square, ``n`` poses, weak odometry and one loop closure: ellipses metres
    across, written as a g2o file."""
    side = n // 4
    steps = np.tile([20.0 / side, 0.0, 0.0], (n - 1, 1))
    steps[side - 1 :: side, 2] = np.pi / 2  # turn left at each corner
    poses = np.zeros((n, 3))
    for k in range(1, n):
        poses[k] = se2.compose(poses[k - 1], steps[k - 1])
    edges = [[k, k + 1] for k in range(n - 1)] + [[0, n - 1]]
    z = np.vstack([steps, se2.between(poses[0], poses[n - 1])])
    info = np.tile(np.diag([4.0, 4.0, 100.0]), (n, 1, 1))
    path = tmp_path / "weak.g2o"
    lagolib.write_g2o(lagolib.PoseGraph(poses, edges, z, info), path)
    return path


def test_plot_ellipses_state_their_confidence_and_are_subsampled(capsys, tmp_path):
    import matplotlib.image

    path = _weak_square(tmp_path)
    png = tmp_path / "e.png"
    rc, out, err = _call(capsys, "plot", path, "--ellipses", "-o", png, "--dpi", 40)
    assert rc == 0, err
    # 240 poses with 95 % ellipses metres across on a 20 m square: the minimum, 10, drawn
    assert out.strip() == f"wrote {png} (240 poses, 240 edges with 10 95 % confidence ellipses)"
    rgb = (matplotlib.image.imread(png)[..., :3] * 255).round().astype(int)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    # tab:purple (148, 103, 189), even blended with the white: red and blue above green; the
    # odometry's blue has red below green, the closures' red has blue at green's level
    assert np.sum((r > g + 20) & (b > g + 20)) > 100
    rc, out, err = _call(capsys, "plot", path, "--ellipses", "--sigma", 3, "-o", png, "--dpi", 40)
    assert rc == 0, err
    assert out.strip().endswith("with 10 98.9 % confidence ellipses)")
    rc, out, err = _call(
        capsys, "plot", path, "--ellipses", "--every", 60, "--confidence", 0.5, "-o", png
    )
    assert rc == 0, err
    assert out.strip().endswith("with 4 50 % confidence ellipses)")
    rc, _, err = _call(
        capsys, "plot", path, "--ellipses", "--sigma", 3, "--confidence", 0.9, "-o", png
    )
    assert rc == 2 and "not allowed with argument" in _one_error_line(err)
    rc, _, err = _call(capsys, "plot", path, "--ellipses", "--confidence", 1.5, "-o", png)
    assert rc == 2 and "not a probability in (0, 1)" in _one_error_line(err)
