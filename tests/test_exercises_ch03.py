"""The checks of chapter 3's exercises (lagolib.exercises.ch03): right, stub, wrong, raising."""

import json
from pathlib import Path

import numpy as np
import pytest

import lagolib
from lagolib import se2, simulate
from lagolib.book import exercises, solution_check_source
from lagolib.exercises import ch03, hint, passed, reset

CHAPTER = Path(__file__).resolve().parent.parent / "book" / "03_uncertainty.ipynb"


@pytest.fixture(autouse=True)
def _fresh():
    reset()
    yield
    reset()


def _out(capsys):
    return capsys.readouterr().out


def _hints(capsys, exercise):
    """Every hint level of ``exercise``'s last "not yet", as ``hint`` prints them."""
    for _ in range(4):
        hint(exercise)
    return _out(capsys)


def _block(a, r, c=None):
    c = r if c is None else c
    return np.asarray(a)[3 * r : 3 * r + 3, 3 * c : 3 * c + 3]


# ---------------------------------------------------------------------------------------------
# 3.1 marginal covariance


def marginal_ok(H, free, v):
    k = int(np.flatnonzero(free == v)[0])
    return _block(np.linalg.inv(H.toarray()), k)


def test_31_reference_is_correct(capsys):
    assert ch03.check_marginal_covariance(marginal_ok) is True
    out = _out(capsys)
    assert out.startswith("Exercise 3.1 — correct")
    assert "poses [12, 23, 1] of a 24-pose graph" in out
    assert passed("3.1")


@pytest.mark.parametrize("stub", [..., None, lambda H, free, v: ...])
def test_31_stub_not_attempted(stub, capsys):
    assert ch03.check_marginal_covariance(stub) is False
    assert "Exercise 3.1 — not attempted yet" in _out(capsys)
    assert not passed("3.1")


@pytest.mark.parametrize(
    "wrong, message",
    [
        (
            lambda H, free, v: _block(H.toarray(), v - 1),
            "you returned H's own diagonal block",
        ),
        (
            lambda H, free, v: np.linalg.inv(_block(H.toarray(), v - 1)),
            "you inverted H's 3x3 block alone",
        ),
        (
            lambda H, free, v: _block(np.linalg.inv(H.toarray()), v),
            "for pose 12 you returned block 12 of H^-1, which belongs to pose 13: off by one",
        ),
        (
            lambda H, free, v: -marginal_ok(H, free, v),
            "has the opposite sign of the reference",
        ),
        (
            lambda H, free, v: 2 * marginal_ok(H, free, v),
            "your covariance of pose 12 differs from the reference",
        ),
    ],
)
def test_31_wrong_answers(wrong, message, capsys):
    assert ch03.check_marginal_covariance(wrong) is False
    out = _out(capsys)
    assert out.startswith("Exercise 3.1 — not yet")
    assert message in out
    assert not passed("3.1")


def test_31_sparse_result_is_named(capsys):
    import scipy.sparse.linalg

    def sparse(H, free, v):
        k = int(np.flatnonzero(free == v)[0])
        return scipy.sparse.linalg.inv(H.tocsc())[3 * k : 3 * k + 3, 3 * k : 3 * k + 3]

    assert ch03.check_marginal_covariance(sparse) is False
    out = _out(capsys)
    assert "should return an array of real numbers of shape (3, 3)" in out
    assert "it returned a csc_matrix (a scipy.sparse matrix)" in out
    assert "(call .toarray() on a sparse result)" in _hints(capsys, "3.1")


def test_31_conditional_sigma_is_reported(capsys):
    ch03.check_marginal_covariance(lambda H, free, v: np.linalg.inv(_block(H.toarray(), v - 1)))
    out = _out(capsys)
    assert "you inverted H's 3x3 block alone" in out and "it is too small" in out
    # the student's own (conditional) sigma is printed, the marginal one is not
    a = float(out.split("your position sigma ")[1].split()[0])
    assert 0 < a < 0.1 and "instead of" not in out


def test_31_raising_function_is_feedback(capsys):
    def boom(H, free, v):
        return np.linalg.inv(H)  # a sparse matrix: numpy refuses it

    assert ch03.check_marginal_covariance(boom) is False
    out = _out(capsys)
    assert "raised LinAlgError" in out and "H.toarray()" not in out
    assert "hint 1 of 3: H is a scipy.sparse matrix: H.toarray()" in _hints(capsys, "3.1")


# ---------------------------------------------------------------------------------------------
# 3.2 prediction: a loop closure


@pytest.fixture(scope="module")
def loop():
    """The chapter's one-lap square, odometry only and with the closure 0-39 (same seeds)."""
    return loop_data()


def loop_data():
    """``(chain, closed)`` of exercise 3.2 (also used by tests/test_exercises_fuzz.py)."""
    sim = simulate.loop_world(laps=1, poses_per_lap=40, rng=np.random.default_rng(7))
    full = sim.graph
    odo = full.odometric
    chain = lagolib.PoseGraph(
        full.poses, full.edges[odo], full.measurements[odo], full.information[odo]
    )
    noise = np.random.default_rng(8).normal(size=3) * [0.05, 0.05, 0.01]
    z = se2.between(sim.truth[0], sim.truth[39]) + noise
    closed = lagolib.PoseGraph(
        chain.poses,
        np.vstack([chain.edges, [[0, 39]]]),
        np.vstack([chain.measurements, z]),
        np.concatenate([chain.information, chain.information[:1]]),
    )
    return chain, closed


def test_32_reference_is_correct(loop, capsys):
    assert ch03.check_closure_prediction("below 0.2", 20, *loop) is True
    out = _out(capsys)
    assert out.startswith("Exercise 3.2 — correct")
    assert "from 0.710 m to 0.070 m (ratio 0.099" in out
    assert "most uncertain pose after closing is 20 (0.320 m; before closing it was 39)" in out
    # case and spaces do not matter; a float that is a whole number is a pose index
    assert ch03.check_closure_prediction("  Below 0.2", 20.0, *loop) is True


@pytest.mark.parametrize("shrink, top", [(..., 20), ("below 0.2", ...), (None, None)])
def test_32_stub_not_attempted(loop, shrink, top, capsys):
    assert ch03.check_closure_prediction(shrink, top, *loop) is False
    assert "Exercise 3.2 — not attempted yet" in _out(capsys)


@pytest.mark.parametrize(
    "shrink, top, messages",
    [
        ("above 1", 20, ["a measurement never makes an estimate less certain"]),
        ("0.2 to 0.5", 20, ["shrink: '0.2 to 0.5' is not the band", "shrinks more than that"]),
        ("below 0.2", 39, ["pose 39 was the most uncertain before the closure"]),
        ("below 0.2", 21, ["pose 21 is not the most uncertain pose after the closure"]),
        ("below 0.2", 0, ["pose 0 is the fixed anchor"]),
        ("below 0.2", 10, ["pose 10 is not the most uncertain", "(its position sigma is 0.2"]),
        ("below 0.2", 40, ["should be a pose index from 0 to 39; got 40"]),
        ("smaller", 20, ["shrink should be one of"]),
        ("0.5 to 1", 39, ["shrinks more than that", "pose 39 was the most uncertain"]),
    ],
)
def test_32_wrong_predictions(loop, shrink, top, messages, capsys):
    assert ch03.check_closure_prediction(shrink, top, *loop) is False
    out = _out(capsys)
    assert out.startswith("Exercise 3.2 — not yet")
    for m in messages:
        assert m in out
    # the actual values are the last hint, never part of the diagnosis
    assert "0.099" not in out and "Actual" not in out
    levels = _hints(capsys, "3.2")
    assert "hint 3 of 3: the check's numbers: pose 39's position sigma goes from 0.710 m to " in (
        levels
    )


# ---------------------------------------------------------------------------------------------
# 3.3 relative covariance


def lever(p_i, p_j):
    d = np.asarray(p_j)[:2] - np.asarray(p_i)[:2]
    return np.array([[1.0, 0.0, -d[1]], [0.0, 1.0, d[0]], [0.0, 0.0, 1.0]])


def relative_ok(S_ii, S_ij, S_jj, p_i, p_j):
    M = lever(p_i, p_j)
    return S_jj - M @ S_ij - S_ij.T @ M.T + M @ S_ii @ M.T


def test_33_reference_is_correct(capsys):
    assert ch03.check_relative_covariance(relative_ok) is True
    out = _out(capsys)
    assert out.startswith("Exercise 3.3 — correct")
    assert "[(3, 17), (17, 3), (8, 9)] of a 24-pose graph" in out
    assert passed("3.3")


@pytest.mark.parametrize("stub", [..., lambda *a: ..., lambda *a: None])
def test_33_stub_not_attempted(stub, capsys):
    assert ch03.check_relative_covariance(stub) is False
    assert "Exercise 3.3 — not attempted yet" in _out(capsys)


def _no_cross(S_ii, S_ij, S_jj, p_i, p_j):
    M = lever(p_i, p_j)
    return S_jj + M @ S_ii @ M.T


def _plus_cross(S_ii, S_ij, S_jj, p_i, p_j):
    M = lever(p_i, p_j)
    return S_jj + M @ S_ij + S_ij.T @ M.T + M @ S_ii @ M.T


def _untransposed(S_ii, S_ij, S_jj, p_i, p_j):
    M = lever(p_i, p_j)
    return S_jj - M @ S_ij - S_ij @ M.T + M @ S_ii @ M.T


def _no_lever(S_ii, S_ij, S_jj, p_i, p_j):
    return S_jj - S_ij - S_ij.T + S_ii


def _reversed_lever(S_ii, S_ij, S_jj, p_i, p_j):
    return relative_ok(S_ii, S_ij, S_jj, p_j, p_i)


def _degrees(S_ii, S_ij, S_jj, p_i, p_j):
    out = relative_ok(S_ii, S_ij, S_jj, p_i, p_j)
    return out * np.array([1.0, 1.0, (180 / np.pi) ** 2])[:, None]


def _transposed_lever(S_ii, S_ij, S_jj, p_i, p_j):
    M = lever(p_i, p_j).T
    return S_jj - M @ S_ij - S_ij.T @ M.T + M @ S_ii @ M.T


def _in_frame_i(S_ii, S_ij, S_jj, p_i, p_j):
    G = np.eye(3)
    G[:2, :2] = se2.rotation(p_i[2])
    return G.T @ relative_ok(S_ii, S_ij, S_jj, p_i, p_j) @ G


def test_33_generic_hint_does_not_give_the_formula_away(capsys):
    def doubled(*args):
        return 2 * relative_ok(*args)

    assert ch03.check_relative_covariance(doubled) is False
    out = _out(capsys)
    levels = _hints(capsys, "3.3")
    assert "hint 1 of 3: Sigma_j|i is the covariance of dx_j|i = dx_j - M dx_i: expand" in levels
    assert "S_jj - M S_ij" not in out + levels


@pytest.mark.parametrize(
    "wrong, message",
    [
        (_no_cross, "you left out the cross terms"),
        (_plus_cross, "the cross terms have the wrong sign"),
        (_untransposed, "you used S_ij where S_ji belongs"),
        (_no_lever, "you left out the lever arm M"),
        (_reversed_lever, "the lever arm points the wrong way"),
        (lambda a, b, c, p, q: c - a, "not the difference of the marginals"),
        (lambda a, b, c, p, q: c + a, "only if x_i and x_j were independent"),
        (lambda a, b, c, p, q: relative_ok(a, b, c, p, q).T[:2], "has shape (2, 3)"),
        (_degrees, "differs from the reference"),
        (_transposed_lever, "your lever arm is transposed"),
        (_in_frame_i, "rotated into the frame of pose i"),
    ],
)
def test_33_wrong_answers(wrong, message, capsys):
    assert ch03.check_relative_covariance(wrong) is False
    out = _out(capsys)
    assert out.startswith("Exercise 3.3 — not yet")
    assert message in out
    assert "(i, j) = (3, 17)" in out


def test_33_raising_function_is_feedback(capsys):
    def boom(S_ii, S_ij, S_jj, p_i, p_j):
        return S_jj @ p_i[:2]  # (3, 3) @ (2,)

    assert ch03.check_relative_covariance(boom) is False
    out = _out(capsys)
    assert "not yet: relative_covariance(S_ii, S_ij, S_jj, p_i, p_j) raised ValueError" in out


# ---------------------------------------------------------------------------------------------
# 3.4 exploring the gate


@pytest.fixture(scope="module")
def gate_world():
    """The chapter's two-lap square and candidate loop closures (same seeds and construction)."""
    return gate_world_data()


def gate_world_data():
    """``(graph, estimate, truth, candidates, information)`` of exercise 3.4 (also used by
    tests/test_exercises_fuzz.py)."""
    sim2 = simulate.loop_world(laps=2, poses_per_lap=40, rng=np.random.default_rng(9))
    g = sim2.graph
    keep = g.odometric | (np.arange(g.m) % 2 == 0)
    g = lagolib.PoseGraph(g.poses, g.edges[keep], g.measurements[keep], g.information[keep])
    est = lagolib.optimize(g).poses
    info = np.diag([400.0, 400.0, 1e4])
    rng = np.random.default_rng(10)
    pairs = np.column_stack([np.arange(0, 40, 2), np.arange(40, 80, 2)])
    k = len(pairs)
    z_pair = se2.between(sim2.truth[pairs[:, 0]], sim2.truth[pairs[:, 1]])
    noise = rng.multivariate_normal(np.zeros(3), np.linalg.inv(info), size=k)
    angle, offset = rng.uniform(-np.pi, np.pi, k), rng.uniform(0.05, 0.60, k)
    wrong = np.column_stack(
        [offset * np.cos(angle), offset * np.sin(angle), rng.normal(0, 0.01, k)]
    )
    candidates = {
        "pairs": np.vstack([pairs, pairs]),
        "z": np.vstack([z_pair + noise, z_pair + wrong]),
        "false": np.repeat([False, True], k),
    }
    return g, est, sim2.truth, candidates, info


TREND = "more true and more false accepted"


def test_34_reference_is_correct(gate_world, capsys):
    assert ch03.check_gate(TREND, 0.32, *gate_world) is True
    out = _out(capsys)
    assert out.startswith("Exercise 3.4 — correct: more true and more false accepted")
    assert "accepts 20 of 20 true and 10 of 20 false candidates" in out
    assert "accepted false one is 0.319 m" in out
    assert ch03.check_gate(TREND.upper(), 0.319, *gate_world) is True


@pytest.mark.parametrize("trend, err", [(..., 0.32), (TREND, ...), (None, None)])
def test_34_stub_not_attempted(gate_world, trend, err, capsys):
    assert ch03.check_gate(trend, err, *gate_world) is False
    assert "Exercise 3.4 — not attempted yet" in _out(capsys)


@pytest.mark.parametrize(
    "trend, err, message",
    [
        (
            "fewer true and fewer false accepted",
            0.32,
            "trend: 'fewer true and fewer false accepted' is not what the gate does",
        ),
        (TREND, 0.187, "0.187 m is the reading for the gate at confidence 0.9, not 0.99"),
        (TREND, 0.342, "0.342 m is the reading for the gate at confidence 0.999"),
        (TREND, 0.54, "is the largest error of all false candidates"),
        (TREND, 0.25, "max_false_error = 0.25 is too small, by 10 to 50 %. Read it off the row"),
        (TREND, "0.32 m", "max_false_error should be one real number, got '0.32 m'"),
        (TREND, 32, "looks like centimetres; the answer is in metres"),
        ("rises", 0.32, "trend should be one of"),
    ],
)
def test_34_wrong_answers(gate_world, trend, err, message, capsys):
    assert ch03.check_gate(trend, err, *gate_world) is False
    out = _out(capsys)
    assert out.startswith("Exercise 3.4 — not yet")
    assert message in out
    # the counts and the answer are the last hint, never part of the diagnosis
    assert "0.319" not in out and "9 -> 20" not in out
    kind = "real number" in message
    levels = _hints(capsys, "3.4")
    assert ("the gate accepts 9 -> 20 true and 4 -> 16 false candidates" in levels) is not kind


def test_34_largest_true_error_is_diagnosed(gate_world, capsys):
    g, est, truth, cands, info = gate_world
    zt = se2.between(truth[cands["pairs"][:, 0]], truth[cands["pairs"][:, 1]])
    err = np.linalg.norm(cands["z"][:, :2] - zt[:, :2], axis=1)
    largest_true = float(err[~cands["false"]].max())
    assert ch03.check_gate(TREND, largest_true, *gate_world) is False
    assert "largest error among the *true* candidates" in _out(capsys)


# ---------------------------------------------------------------------------------------------
# the chapter follows the conventions of lagolib.book


def test_chapter_3_exercises_follow_the_conventions():
    nb = json.loads(CHAPTER.read_text(encoding="utf-8"))
    found = exercises(nb, str(CHAPTER))
    assert [(e["id"], e["kind"]) for e in found] == [
        ("3.1", "implement"),
        ("3.2", "predict"),
        ("3.3", "implement"),
        ("3.4", "explore"),
    ]
    cells = nb["cells"]

    def src(c):
        return "".join(c["source"])

    heads = {"implement": "(implement", "predict": "(predict, then check"}
    for e in found:
        ex, start = e["id"], e["cell"]
        stars = {1: "★☆☆", 2: "★★☆", 3: "★★★"}[cells[start]["metadata"]["lagolib"]["difficulty"]]
        assert src(cells[start]).startswith(
            f"**Exercise {ex} " + heads.get(e["kind"], "(explore") + f", {stars}).**"
        )
        rest = cells[start + 1 :]
        k = next(i for i, c in enumerate(rest) if "solution" in c["metadata"].get("tags", []))
        sol, check, assertion, discussion = rest[k : k + 4]
        assert sol["metadata"]["tags"] == ["solution", "hide-cell"]
        assert "# your code here" in sol["metadata"]["lagolib"]["stub"]
        assert "ch03.check_" in src(check)
        assert src(assertion) == solution_check_source(ex)
        assert assertion["metadata"]["tags"] == ["remove-cell", "solution-check"]
        assert discussion["metadata"]["tags"] == ["solution"]
        assert src(discussion).startswith("<details>\n<summary>Solution and discussion</summary>")
        assert src(discussion).endswith("</details>")
        # the stub runs
        exec(compile(sol["metadata"]["lagolib"]["stub"], f"stub {ex}", "exec"), {})
    assert "[preface](00_preface.ipynb)" in src(cells[0])
    captions = [c["metadata"]["mystnb"]["figure"] for c in cells if "mystnb" in c["metadata"]]
    assert len(captions) == nb["metadata"]["lagolib"]["figures"] == 5
    assert all(f["name"].startswith("fig-ch03-") and f["caption"] for f in captions)
