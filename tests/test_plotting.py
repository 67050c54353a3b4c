"""Plots return Axes, draw what they claim, and never call plt.show()."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402

import lagolib  # noqa: E402


@pytest.fixture(autouse=True)
def _no_show(monkeypatch):
    def show(*a, **k):
        raise AssertionError("lagolib must not call plt.show()")

    monkeypatch.setattr(plt, "show", show)
    yield
    plt.close("all")


def test_plot_graph_draws_odometry_solid_and_loop_closures_dotted():
    ex = lagolib.datasets.example("grid100")
    ax = lagolib.plot_graph(ex.graph, vertices=True, title="grid")
    odo, loops = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert len(odo.get_segments()) == int(ex.graph.odometric.sum())
    assert len(loops.get_segments()) == int(ex.graph.loop_closure.sum())
    assert odo.get_linestyle()[0][1] is None  # solid
    assert loops.get_linestyle()[0][1] is not None  # dashed pattern (dotted)
    np.testing.assert_allclose(odo.get_segments()[0], ex.graph.poses[ex.graph.edges[0], :2])
    assert ax.get_title() == "grid"


def test_plot_graph_at_other_poses_into_given_axes():
    ex = lagolib.datasets.example("square_loop")
    fig, ax = plt.subplots()
    out = lagolib.plot_graph(ex.graph, ex.truth, ax=ax)
    assert out is ax
    seg = ax.collections[0].get_segments()[0]
    np.testing.assert_allclose(seg, ex.truth[ex.graph.edges[0], :2])


def test_plot_trajectories_and_poses():
    ex = lagolib.datasets.example("manhattan200")
    ax = lagolib.plot_trajectories({"odometry": ex.graph, "truth": ex.truth})
    assert [ln.get_label() for ln in ax.lines] == ["odometry", "truth"]
    np.testing.assert_allclose(ax.lines[1].get_xydata(), ex.truth[:, :2])
    ax = lagolib.plot_poses(ex.truth[:3], labels=["a", "b", "c"])
    assert [t.get_text() for t in ax.texts] == ["a", "b", "c"]


def test_plot_spanning_tree_draws_tree_chords_and_a_circuit():
    ex = lagolib.datasets.example("grid100")
    tree = lagolib.topology.bfs_tree(ex.graph)
    circuit, _ = lagolib.topology.fundamental_circuit(ex.graph, tree, tree.chords[0])
    ax = lagolib.plot_spanning_tree(ex.graph, tree, highlight=circuit, labels=True, title="t")
    tr, ch, hi = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert len(tr.get_segments()) == ex.graph.n - 1
    assert len(ch.get_segments()) == tree.d
    assert len(hi.get_segments()) == circuit.size
    assert ch.get_linestyle()[0][1] is not None  # chords dashed
    np.testing.assert_allclose(ax.lines[1].get_xydata()[0], ex.graph.poses[tree.root, :2])
    assert len(ax.texts) == ex.graph.n + ex.graph.m
