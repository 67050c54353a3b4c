"""Adversarial guards for issue 13: lagolib.metrics, lagolib.sgd, the ``lagolib`` command and
``optimize(callback=...)``.

Every test here pins behaviour that was already correct when it was written (bad input gets a
lagolib error naming the argument, metrics agree with their definitions written out with 3×3
matrices, the CLI fails with one line and writes files that read back bit for bit).  Small
graphs only, seeded generators, no timing.
"""

import numpy as np
import pytest

import lagolib
from lagolib import PoseGraph, cli, se2
from lagolib import metrics as M
from lagolib.errors import (
    GraphError,
    GraphTypeError,
    LagolibError,
    OptionError,
    OptionTypeError,
)
from lagolib.sgd import sgd, sgd_reference

I3 = np.eye(3)


def _T(p):
    c, s = np.cos(p[2]), np.sin(p[2])
    return np.array([[c, -s, p[0]], [s, c, p[1]], [0.0, 0.0, 1.0]])


@pytest.fixture(scope="module")
def square():
    return lagolib.datasets.example("square_loop")


@pytest.fixture(scope="module")
def chain():
    """Three vertices, a chain 0-1-2 and a loop closure 0-2; root heading 0."""
    return PoseGraph(
        np.zeros((3, 3)),
        [[0, 1], [1, 2], [0, 2]],
        [[1.0, 0.0, 0.1], [1.0, 0.0, 0.1], [1.9, 0.2, 0.25]],
        [I3, I3, I3],
    )


# ----------------------------------------------------------------------------- metrics: values
def test_constraint_satisfaction_equals_matrix_definition(square):
    rng = np.random.default_rng(13)
    g = square.graph
    x = g.poses + rng.normal(0.0, 0.1, g.poses.shape)
    ec, ea = [], []
    for k, (i, j) in enumerate(g.edges):
        E = np.linalg.inv(_T(g.measurements[k])) @ np.linalg.inv(_T(x[i])) @ _T(x[j])
        ec.append(E[0, 2] ** 2 + E[1, 2] ** 2)
        ea.append(np.arctan2(E[1, 0], E[0, 0]) ** 2)
    eta = M.constraint_satisfaction(g, x)
    assert eta.eta_c == pytest.approx(np.mean(ec), rel=1e-12)
    assert eta.eta_a == pytest.approx(np.mean(ea), rel=1e-12)


def test_sesync_objective_equals_frobenius_definition(square):
    rng = np.random.default_rng(7)
    g = square.graph
    x = g.poses + rng.normal(0.0, 0.2, g.poses.shape)
    kappa, tau = M.sesync_parameters(g)
    total = 0.0
    for k, (i, j) in enumerate(g.edges):
        Ri, Rj, Rz = _T(x[i])[:2, :2], _T(x[j])[:2, :2], _T(g.measurements[k])[:2, :2]
        t = x[j, :2] - x[i, :2] - Ri @ g.measurements[k, :2]
        total += kappa[k] * np.sum((Rj - Ri @ Rz) ** 2) + tau[k] * t @ t
        assert tau[k] == pytest.approx(2.0 / np.trace(np.linalg.inv(g.information[k, :2, :2])))
    assert M.sesync_objective(g, x) == pytest.approx(total, rel=1e-12)
    # the surrogate of sesync_weights is an upper bound
    assert lagolib.chi2(M.sesync_weights(g), x) >= M.sesync_objective(g, x)


def test_ate_alignment_is_optimal_and_rpe_is_frame_free(square):
    rng = np.random.default_rng(3)
    truth = square.truth
    est = se2.compose([3.0, -2.0, 1.0], truth) + rng.normal(0.0, 0.05, truth.shape)
    ate = M.absolute_trajectory_error(est, truth)

    def cost(v):
        q = se2.compose(v, est)
        return np.sum((q[:, :2] - truth[:, :2]) ** 2)

    best = cost(ate.alignment.transform)
    assert best == pytest.approx(ate.translation_rmse**2 * len(truth), rel=1e-12)
    for d in ([1e-4, 0, 0], [0, 1e-4, 0], [0, 0, 1e-4], [0, 0, -1e-4]):
        assert cost(ate.alignment.transform + d) > best
    edges = square.graph.edges
    a = M.relative_pose_error(est, truth, pairs=edges)
    b = M.relative_pose_error(se2.compose([10.0, 1.0, 2.5], est), truth, pairs=edges)
    np.testing.assert_allclose(a.translation, b.translation, atol=1e-12)
    np.testing.assert_allclose(a.rotation, b.rotation, atol=1e-12)
    with pytest.raises(ValueError):
        ate.translation[0] = 1.0  # read-only results


# ----------------------------------------------------------------------------- metrics: misuse
@pytest.mark.parametrize(
    "call",
    [
        lambda g: M.constraint_satisfaction([1, 2]),
        lambda g: M.constraint_satisfaction(None),
        lambda g: M.sesync_parameters("graph"),
        lambda g: M.sesync_objective(g, per_edge="yes"),
        lambda g: M.sesync_objective(g, per_edge=1),
        lambda g: M.absolute_trajectory_error(g.poses, g.poses, align=None),
    ],
)
def test_metrics_wrong_types_are_type_errors(square, call):
    with pytest.raises(OptionTypeError) as info:
        call(square.graph)
    assert isinstance(info.value, TypeError)


@pytest.mark.parametrize(
    "poses, fragment",
    [
        (np.zeros((2, 3), complex), "complex"),
        (np.zeros((2, 3), bool), "bool"),
        ("abc", "text"),
        (np.array([[0, 0, 0], [1, 0, None]], dtype=object), "None"),
    ],
)
def test_constraint_satisfaction_rejects_non_real_poses(chain, poses, fragment):
    g = PoseGraph(np.zeros((2, 3)), [[0, 1]], [[1.0, 0.0, 0.0]], [I3])
    with pytest.raises(GraphTypeError, match=fragment):
        M.constraint_satisfaction(g, poses)


def test_constraint_satisfaction_needs_edges_and_right_shape():
    g1 = PoseGraph(np.zeros((1, 3)), np.zeros((0, 2), int), np.zeros((0, 3)), np.zeros((0, 3, 3)))
    with pytest.raises(GraphError, match="no edges"):
        M.constraint_satisfaction(g1)
    g = PoseGraph(np.zeros((2, 3)), [[0, 1]], [[1.0, 0.0, 0.0]], [I3])
    with pytest.raises(GraphError, match=r"shape \(2, 3\)"):
        M.constraint_satisfaction(g, np.zeros((3, 3)))
    with pytest.raises(GraphError, match="vertex id 1"):
        M.constraint_satisfaction(g, [[0, 0, 0], [np.nan, 0, 0]])


@pytest.mark.parametrize(
    "poses, truth, fragment",
    [
        (np.zeros((2, 3)), np.zeros((5, 3)), "poses has 2 rows but truth has 5"),
        (np.zeros((0, 3)), np.zeros((0, 3)), "n >= 1"),
        ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0], r"shape \(3,\)"),
        ([[np.inf, 0, 0]], [[0, 0, 0]], "row 0 is not finite"),
        ([[0, 0, 1e10]], [[0, 0, 0]], "row 0 has the angle"),
    ],
)
def test_ate_bad_trajectories(poses, truth, fragment):
    with pytest.raises(GraphError, match=fragment) as info:
        M.absolute_trajectory_error(poses, truth)
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize(
    "pairs, fragment",
    [
        ([[-1, 0]], r"pairs row 0 is \[-1, 0\]"),
        ([[0, 3]], r"valid row indices 0\.\.2"),
        ([[0.5, 1]], "integer row indices"),
        ([[True, False]], "dtype bool"),
        (np.zeros((0, 2), int), "m >= 1"),
        ([0, 1], r"shape \(2,\)"),
        ([[np.nan, 1]], "integer row indices"),
    ],
)
def test_rpe_bad_pairs(pairs, fragment):
    z = np.zeros((3, 3))
    with pytest.raises(OptionError, match=fragment):
        M.relative_pose_error(z, z, pairs=pairs)


def test_rpe_integral_float_pairs_and_single_pose():
    z = np.zeros((3, 3))
    res = M.relative_pose_error(z, z, pairs=[[0.0, 2.0]])
    assert res.pairs.tolist() == [[0, 2]]
    with pytest.raises(GraphError, match="at least 2 poses"):
        M.relative_pose_error([[1.0, 2.0, 3.0]], [[0.0, 0.0, 0.0]])


# ----------------------------------------------------------------------------- sgd
@pytest.mark.parametrize(
    "kwargs, exc, fragment",
    [
        ({"iterations": -1}, OptionError, "iterations must be an integer >= 0"),
        ({"iterations": 1.5}, OptionTypeError, "iterations must be an integer"),
        ({"iterations": True}, OptionTypeError, "bool"),
        ({"iterations": "5"}, OptionTypeError, "str"),
        ({"tree": "dfs"}, OptionError, "'dfs'"),
        ({"tree": None}, OptionTypeError, "NoneType"),
        ({"anchor": 99999}, GraphError, "vertex id 99999 is not in the graph"),
        ({"anchor": 1.5}, GraphError, "integers"),
        ({"callback": 3}, OptionTypeError, "callback"),
        ({"history": "no"}, OptionTypeError, "history"),
        ({"verbose": 1}, OptionTypeError, "verbose"),
    ],
)
def test_sgd_bad_options(chain, kwargs, exc, fragment):
    with pytest.raises(exc, match=fragment):
        sgd(chain, **kwargs)


def test_sgd_bad_graph_and_initial(chain):
    with pytest.raises(OptionTypeError, match="PoseGraph"):
        sgd([1, 2])
    with pytest.raises(GraphError, match=r"shape \(3, 3\)"):
        sgd(chain, np.zeros((4, 3)))
    with pytest.raises(GraphTypeError):
        sgd(chain, np.zeros((3, 3), complex))
    disconnected = PoseGraph(np.zeros((3, 3)), [[0, 1]], [[1.0, 0.0, 0.0]], [I3])
    with pytest.raises(GraphError, match="not connected"):
        sgd(disconnected)


def test_sgd_zero_iterations_returns_the_wrapped_initial_guess(chain):
    x0 = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 7.0], [2.0, 0.0, -7.0]])
    res = sgd(chain, x0, iterations=0)
    assert res.iterations == 0
    np.testing.assert_array_equal(res.poses[:, :2], x0[:, :2])
    np.testing.assert_allclose(res.poses[:, 2], se2.wrap_angle(x0[:, 2]))
    assert res.chi2 == pytest.approx(lagolib.chi2(chain, x0), rel=1e-12)


def test_sgd_backward_and_parallel_edges():
    back = PoseGraph(
        np.zeros((3, 3)),
        [[1, 0], [2, 1], [0, 2]],
        [[-1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        [I3, I3, I3],
    )
    np.testing.assert_allclose(sgd(back, iterations=50).poses[:, 0], [0.0, 1.0, 2.0], atol=1e-9)
    np.testing.assert_allclose(sgd_reference(back, iterations=50)[:, 0], [0.0, 1.0, 2.0], atol=1e-9)
    par = PoseGraph(np.zeros((2, 3)), [[0, 1], [0, 1]], [[1.0, 0, 0], [2.0, 0, 0]], [I3, I3])
    assert sgd(par, iterations=200).poses[1, 0] == pytest.approx(1.5, abs=0.01)


def test_sgd_callback_errors_propagate_and_copies_are_passed(square):
    g = square.graph

    def boom(i, p):
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError, match="boom"):
        sgd(g, iterations=3, callback=boom)

    def interrupt(i, p):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        sgd(g, iterations=3, callback=interrupt)
    seen = []

    def spoil(i, p):
        seen.append(i)
        p[:] = 1e9

    res = sgd(g, iterations=3, callback=spoil)
    assert seen == [1, 2, 3]
    assert res.chi2 == pytest.approx(lagolib.chi2(g, res.poses), rel=1e-9)
    assert res.chi2 < res.chi2_history[0]


# ----------------------------------------------------------------------------- optimize callback
@pytest.mark.parametrize("method", ["gn", "lm"])
def test_optimize_callback_sees_every_accepted_iterate(square, method):
    g = square.graph
    seen = []
    res = lagolib.optimize(g, method=method, callback=lambda i, p: seen.append((i, p.copy())))
    assert [i for i, _ in seen] == list(range(1, res.iterations + 1))
    np.testing.assert_array_equal(seen[-1][1], res.poses)
    chis = [lagolib.chi2(g, p) for _, p in seen]
    np.testing.assert_allclose(chis, res.chi2_history[1:], rtol=1e-9)


def test_optimize_callback_misuse(square):
    g = square.graph
    with pytest.raises(OptionTypeError, match="callback"):
        lagolib.optimize(g, callback="print")

    def spoil(i, p):
        p[:] = np.nan

    clean = lagolib.optimize(g)
    assert lagolib.optimize(g, callback=spoil).chi2 == clean.chi2

    def interrupt(i, p):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        lagolib.optimize(g, callback=interrupt)
    assert lagolib.optimize(g, max_iterations=0, callback=interrupt).iterations == 0


# ----------------------------------------------------------------------------- CLI
def _call(capsys, *args):
    rc = cli.main([str(a) for a in args])
    out, err = capsys.readouterr()
    return rc, out, err


def _one_error_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("lagolib: error: "), err
    assert "Traceback" not in err
    return lines[0]


@pytest.fixture
def files(tmp_path):
    src = lagolib.datasets.data_dir() / "square_loop.g2o"
    (tmp_path / "sq.g2o").write_bytes(src.read_bytes())
    (tmp_path / "empty.g2o").write_text("")
    (tmp_path / "bin.g2o").write_bytes(bytes(range(256)) * 2)
    (tmp_path / "nul.g2o").write_bytes(b"VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\x00\n")
    (tmp_path / "folder").mkdir()
    (tmp_path / "two.g2o").write_text(
        "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nEDGE_SE2 1 0 -1 0 0 1 0 0 1 0 1\n"
    )
    (tmp_path / "p1.txt").write_text("0 0 0 0\n")
    (tmp_path / "p3.txt").write_text("0 0 0 0\n1 1 0 0\n7 1 0 0\n")
    (tmp_path / "pdup.txt").write_text("0 0 0 0\n0 1 0 0\n")
    return tmp_path


@pytest.mark.parametrize(
    "args, status, fragment",
    [
        (["info", "{d}/nosuch.g2o"], 1, "no such file"),
        (["info", "{d}/empty.g2o"], 1, "not a pose-graph file"),
        (["info", "{d}/bin.g2o"], 1, "bin.g2o:1:"),
        (["info", "{d}/nul.g2o"], 1, "nul.g2o:2: NUL byte"),
        (["info", "{d}/folder"], 1, "is a folder"),
        (["solve", "{d}/sq.g2o", "-o", "{d}/nodir/out.g2o"], 1, "does not exist"),
        (["solve", "{d}/sq.g2o", "-o", "{d}/out.txt"], 2, "'.txt'"),
        (["solve", "{d}/sq.g2o", "-o", "{d}/folder"], 2, "'(none)'"),
        (["solve", "{d}/sq.g2o", "-o", "{d}/o.g2o", "--iterations", "0"], 2, "got 0"),
        (["solve", "{d}/sq.g2o", "-o", "{d}/o.g2o", "--iterations", "-1"], 2, "got -1"),
        (["solve", "{d}/sq.g2o", "-o", "{d}/o.g2o", "--iterations", "abc"], 2, "'abc'"),
        (["solve", "{d}/sq.g2o", "-o", "{d}/o.g2o", "--method", "foo"], 2, "'foo'"),
        (["solve", "{d}/sq.g2o", "-o", "{d}/o.g2o", "-m", "lago", "-n", "3"], 2, "lago"),
        (["solve", "{d}/sq.g2o", "-o", "{d}/o.g2o", "-m", "gn", "--tree", "bfs"], 2, "--tree"),
        (["solve", "{d}/sq.g2o", "-o", "{d}/o.g2o", "--plot", "{d}/p.xyz"], 2, "'.xyz'"),
        (["plot", "{d}/two.g2o", "-o", "{d}/p.png", "--poses", "{d}/p1.txt"], 1, "missing ids 1"),
        (["plot", "{d}/two.g2o", "-o", "{d}/p.png", "--poses", "{d}/p3.txt"], 1, "vertex id 7"),
        (["plot", "{d}/two.g2o", "-o", "{d}/p.png", "--poses", "{d}/pdup.txt"], 1, "pdup.txt:2"),
        (["plot", "{d}/two.g2o", "-o", "{d}/p.png", "--poses", "{d}/none.txt"], 1, "no such"),
        (["plot", "{d}/two.g2o", "-o", "{d}/p.png", "--sigma", "inf"], 2, "'inf'"),
        (["plot", "{d}/two.g2o", "-o", "{d}/p.png", "--every", "0"], 2, "got 0"),
        ([], 2, "a command is required"),
    ],
)
def test_cli_errors_are_one_line(capsys, files, args, status, fragment):
    rc, _, err = _call(capsys, *[a.format(d=files) for a in args])
    assert rc == status
    assert fragment in _one_error_line(err)


def test_cli_disconnected_graph_is_an_error_not_a_traceback(capsys, files):
    (files / "disc.g2o").write_text(
        "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\nVERTEX_SE2 2 2 0 0\n"
        "EDGE_SE2 0 1 1 0 0 1 0 0 1 0 1\n"
    )
    for method in ("lago", "gn", "sgd"):
        rc, _, err = _call(capsys, "solve", files / "disc.g2o", "-m", method, "-o", files / "o.g2o")
        assert rc == 1
        line = _one_error_line(err)
        assert "not connected" in line or "no gauge" in line
    assert not (files / "o.g2o").exists()


@pytest.mark.parametrize("method", ["gn", "lago+gn", "sgd", "lago"])
@pytest.mark.parametrize("ext", ["g2o", "graph"])
def test_cli_solve_round_trip_is_bit_for_bit(capsys, files, method, ext):
    g = lagolib.read(files / "sq.g2o")
    out = files / f"solved.{ext}"
    rc, stdout, _ = _call(capsys, "solve", files / "sq.g2o", "-m", method, "-o", out)
    assert rc == 0 and f"wrote {out}" in stdout
    if method == "gn":
        ref = lagolib.optimize(g).poses
    elif method == "sgd":
        ref = sgd(g).poses
    elif method == "lago":
        ref = lagolib.lago.lago(g).poses
    else:
        ref = lagolib.optimize(g, lagolib.lago.lago(g).poses).poses
    back = lagolib.read(out)
    np.testing.assert_array_equal(back.poses, ref)
    np.testing.assert_array_equal(back.ids, g.ids)
    np.testing.assert_array_equal(back.edges, g.edges)
    np.testing.assert_array_equal(back.measurements, g.measurements)
    if ext == "g2o":
        np.testing.assert_array_equal(back.information, g.information)


def test_cli_errors_are_lagolib_or_os_errors_in_debug(capsys, files):
    rc, _, err = _call(capsys, "--debug", "info", files / "nosuch.g2o")
    assert rc == 1 and "Traceback" in err
    assert issubclass(GraphError, LagolibError)
