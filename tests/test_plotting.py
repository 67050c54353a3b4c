"""Plots return Axes, draw what they claim, and never call plt.show()."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.quiver import Quiver  # noqa: E402

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


def _six_node_loop():
    """Chapter 4's small graph: six poses on a loop, three loop closures, one of them backwards."""
    xy = np.array([[0, 0], [2, 0], [4, 0], [4, 2], [2, 2], [0, 2]], dtype=float)
    edges = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 0), (4, 1), (0, 4)]
    m = len(edges)
    poses = np.column_stack([xy, np.zeros(6)])
    return lagolib.PoseGraph(poses, edges, np.zeros((m, 3)), np.tile(np.eye(3), (m, 1, 1)))


def _quivers(ax):
    return [c for c in ax.collections if isinstance(c, Quiver)]


def _check_heads(q, poses, edges):
    tail, head = poses[edges[:, 0], :2], poses[edges[:, 1], :2]
    d = head - tail
    u = d / np.linalg.norm(d, axis=1, keepdims=True)
    np.testing.assert_allclose(np.column_stack([q.X, q.Y]), tail + 0.7 * d)
    np.testing.assert_allclose(np.column_stack([np.asarray(q.U), np.asarray(q.V)]), u)


def test_arrows_point_from_tail_to_head_on_every_edge_of_a_spanning_tree():
    g = _six_node_loop()
    tree = lagolib.topology.spanning_tree(g, "odometric")
    assert _quivers(lagolib.plot_spanning_tree(g, tree)) == []  # no arrows unless asked
    ax = lagolib.plot_spanning_tree(g, tree, arrows=True, labels=True)
    tree_heads, chord_heads = _quivers(ax)
    assert tree_heads.N == 5 and chord_heads.N == 3
    _check_heads(tree_heads, g.poses, g.edges[:5])
    _check_heads(chord_heads, g.poses, g.edges[5:])
    # chord e5 = (5, 0) runs from (0, 2) down to (0, 0); e6 = (4, 1) also points down
    np.testing.assert_allclose([chord_heads.U[0], chord_heads.V[0]], [0.0, -1.0])
    np.testing.assert_allclose([chord_heads.U[1], chord_heads.V[1]], [0.0, -1.0])
    assert tree_heads.get_facecolor()[0][2] > 0.5  # tree heads blue, chord heads orange
    assert chord_heads.get_facecolor()[0][0] > 0.9
    # the arrows are extra artists: the tree, chord and vertex artists are unchanged
    assert len([c for c in ax.collections if isinstance(c, LineCollection)]) == 2


def test_plot_graph_arrows_on_odometry_and_loop_closures():
    g = _six_node_loop()
    assert _quivers(lagolib.plot_graph(g)) == []
    odo, loops = _quivers(lagolib.plot_graph(g, arrows=True))
    _check_heads(odo, g.poses, g.edges[g.odometric])
    _check_heads(loops, g.poses, g.edges[g.loop_closure])


def test_legend_inside_outside_below_or_none():
    g = _six_node_loop()
    tree = lagolib.topology.spanning_tree(g, "odometric")

    def legend_box(ax):
        ax.figure.canvas.draw()
        box = ax.get_legend().get_window_extent()
        return box.transformed(ax.transAxes.inverted())

    inside = legend_box(lagolib.plot_graph(g))
    assert 0 <= inside.x0 and inside.x1 <= 1 and 0 <= inside.y0 and inside.y1 <= 1
    outside = legend_box(lagolib.plot_spanning_tree(g, tree, legend="outside"))
    assert outside.x0 > 1.0  # right of the axes, off the data
    below = legend_box(lagolib.plot_graph(g, legend="below"))
    assert below.y1 < 0.0  # under the axes (and under the x label)
    fig, ax = plt.subplots()
    ax.figure.canvas.draw()
    label_box = ax.xaxis.label.get_window_extent().transformed(ax.transAxes.inverted())
    ax = lagolib.plot_trajectories({"truth": g.poses}, ax=ax, legend="below")
    assert legend_box(ax).y1 < label_box.y0
    assert lagolib.plot_graph(g, legend=None).get_legend() is None


def test_bad_legend_and_arrows_options_are_named():
    g = _six_node_loop()
    with pytest.raises(lagolib.errors.OptionError, match="plot_graph: legend") as info:
        lagolib.plot_graph(g, legend="left")
    assert isinstance(info.value, ValueError)
    with pytest.raises(TypeError, match="plot_spanning_tree: arrows"):
        lagolib.plot_spanning_tree(g, lagolib.topology.bfs_tree(g), arrows="yes")
    with pytest.raises(ValueError, match="plot_trajectories: legend"):
        lagolib.plot_trajectories({"a": g.poses}, legend=3)
