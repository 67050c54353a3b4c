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


# ----------------------------------------------------------------------------- covariance ellipses
def _rotated_covariance(theta=0.6, sx=0.3, sy=0.1):
    """σ ``sx`` along the direction ``theta`` (rad), ``sy`` across it: (x, y) block of a 3x3."""
    c, s = np.cos(theta), np.sin(theta)
    R = np.array([[c, -s], [s, c]])
    cov = np.eye(3) * 1e-4
    cov[:2, :2] = R @ np.diag([sx**2, sy**2]) @ R.T
    return cov


def _ellipse_collection(ax):
    from matplotlib.collections import EllipseCollection

    (coll,) = [c for c in ax.collections if isinstance(c, EllipseCollection)]
    return coll


def _boundary(coll, k=0, n=64):
    """Points on the boundary of ellipse ``k`` of an EllipseCollection, centred at the origin."""
    from matplotlib.patches import Ellipse

    patch = Ellipse(
        (0.0, 0.0), coll.get_widths()[k], coll.get_heights()[k], angle=coll.get_angles()[k]
    )
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return patch.get_patch_transform().transform(np.column_stack([np.cos(t), np.sin(t)]))


@pytest.mark.parametrize("confidence", [0.95, 0.5, 0.999])
def test_ellipse_boundary_is_the_confidence_contour_of_an_anisotropic_rotated_covariance(
    confidence,
):
    """Every point of the drawn boundary has δᵀ Σ⁻¹ δ = χ²₂⁻¹(confidence); semi-axes sqrt of that
    times the σ's (0.3 m along 0.6 rad, 0.1 m across)."""
    from scipy.stats import chi2 as chi2_dist

    cov = _rotated_covariance()
    kw = {} if confidence == 0.95 else {"confidence": confidence}  # 0.95 is the default
    ax = lagolib.plot_covariance_ellipses([[1.0, 2.0, 0.0]], [cov], **kw)
    coll = _ellipse_collection(ax)
    q = chi2_dist.ppf(confidence, 2)
    assert lagolib.plotting.ellipse_scale(confidence) == pytest.approx(np.sqrt(q), rel=1e-12)
    np.testing.assert_allclose(coll.get_widths(), [2 * np.sqrt(q) * 0.3], rtol=1e-12)
    np.testing.assert_allclose(coll.get_heights(), [2 * np.sqrt(q) * 0.1], rtol=1e-12)
    np.testing.assert_allclose(coll.get_angles(), [np.degrees(0.6)], rtol=1e-12)
    np.testing.assert_allclose(coll.get_offsets(), [[1.0, 2.0]])
    d = _boundary(coll)
    d2 = np.einsum("ki,ij,kj->k", d, np.linalg.inv(cov[:2, :2]), d)
    np.testing.assert_allclose(d2, q, rtol=1e-9)
    # a Gaussian sample: the fraction inside is the confidence (20000 draws: ± 0.5 %)
    rng = np.random.default_rng(11)
    x = rng.multivariate_normal(np.zeros(2), cov[:2, :2], size=20000)
    inside = np.einsum("ki,ij,kj->k", x, np.linalg.inv(cov[:2, :2]), x) <= q
    assert abs(inside.mean() - confidence) < 0.01


def test_n_sigma_keeps_sigma_scales_and_states_their_confidence():
    ax = lagolib.plot_covariance_ellipses([[0.0, 0.0, 0.0]], [_rotated_covariance()], n_sigma=3)
    coll = _ellipse_collection(ax)
    np.testing.assert_allclose(coll.get_widths(), [2 * 3 * 0.3], rtol=1e-12)
    assert ax.get_legend_handles_labels()[1] == ["98.9 % confidence ellipses"]  # 1 − e^(−9/2)
    ax = lagolib.plot_covariance_ellipses([[0.0, 0.0, 0.0]], [_rotated_covariance()], n_sigma=1)
    assert ax.get_legend_handles_labels()[1] == ["39.3 % confidence ellipses"]
    ax = lagolib.plot_covariance_ellipses(
        [[0.0, 0.0, 0.0]], [_rotated_covariance()], confidence=0.9999
    )
    assert ax.get_legend_handles_labels()[1] == ["99.99 % confidence ellipses"]  # not "100"


def test_ellipses_are_not_the_loop_closures_colour_and_have_a_legend_entry():
    from matplotlib.colors import to_rgba

    g = lagolib.simulate.loop_world(laps=2, poses_per_lap=12, rng=np.random.default_rng(3)).graph
    fig, ax = plt.subplots()
    lagolib.plot_graph(g, ax=ax)
    covs = np.tile(_rotated_covariance(), (g.n, 1, 1))
    lagolib.plot_covariance_ellipses(g.poses, covs, ax=ax, every=1)
    closures = [
        c
        for c in ax.collections
        if isinstance(c, LineCollection) and str(c.get_label()).startswith("loop closures")
    ]
    assert len(closures) == 1
    ellipse_rgba = _ellipse_collection(ax).get_edgecolor()[0]
    np.testing.assert_allclose(ellipse_rgba, to_rgba(lagolib.plotting.ELLIPSE_COLOR))
    closure_rgb = np.asarray(closures[0].get_color()[0][:3])
    odometry_rgb = np.asarray(ax.collections[0].get_color()[0][:3])
    assert np.abs(ellipse_rgba[:3] - closure_rgb).max() > 0.3  # another hue, not a shade
    assert np.abs(ellipse_rgba[:3] - odometry_rgb).max() > 0.3
    handles, labels = ax.get_legend_handles_labels()
    assert labels[-1] == "95 % confidence ellipses"  # every pose: no "every"
    np.testing.assert_allclose(to_rgba(handles[-1].get_color()), ellipse_rgba)
    assert handles[-1].get_xydata().size == 0  # the entry draws nothing on the map
    ax.legend()
    assert "95 % confidence ellipses" in [t.get_text() for t in ax.get_legend().get_texts()]
    ax = lagolib.plot_covariance_ellipses(g.poses[:2], np.tile(np.eye(3), (2, 1, 1)), label=False)
    assert ax.get_legend_handles_labels()[1] == []
    ax = lagolib.plot_covariance_ellipses(g.poses[:2], np.tile(np.eye(3), (2, 1, 1)), label="σ")
    assert ax.get_legend_handles_labels()[1] == ["σ"]


def _spread(n, width, height):
    """``n`` poses on a grid filling a ``width`` × ``height`` box (corners included)."""
    cols = int(np.ceil(np.sqrt(n * width / height)))
    k = np.arange(n)
    x, y = (k % cols) / (cols - 1) * width, (k // cols) / ((n - 1) // cols) * height
    return np.column_stack([x, y, np.zeros(n)])


def _isotropic(n, area, confidence=0.95):
    """Covariances whose ``confidence`` ellipses have the given area (m²): π k² σ² = area."""
    k = lagolib.plotting.ellipse_scale(confidence)
    return np.tile(np.eye(3) * area / (np.pi * k**2), (n, 1, 1))


@pytest.mark.parametrize(
    "area, drawn, step",
    [
        (0.01, 100, 35),  # small: the cap of 100 (every 35th of 3500)
        (50.0, 25, 140),  # a quarter of the 5000 m² box holds 25 of 50 m²: every 140th
        (500.0, 10, 350),  # a quarter holds 2.5 of them: the minimum, 10
    ],
)
def test_default_subsampling_keeps_the_ellipses_from_burying_the_map(area, drawn, step):
    n = 3500  # as many poses as M3500, in a 100 m x 50 m box
    poses = _spread(n, 100.0, 50.0)
    assert np.ptp(poses[:, :2], axis=0).tolist() == [100.0, 50.0]
    ax = lagolib.plot_covariance_ellipses(poses, _isotropic(n, area))
    coll = _ellipse_collection(ax)
    assert len(coll.get_widths()) == drawn
    np.testing.assert_allclose(coll.get_offsets(), poses[::step, :2])
    assert ax.get_legend_handles_labels()[1] == [f"95 % confidence ellipses (every {step}th pose)"]
    # the drawn ellipses' areas add up to at most a quarter of the box, unless the minimum rules
    if drawn > 10:
        assert drawn * area <= 0.25 * 100 * 50
    # an explicit step wins
    ax = lagolib.plot_covariance_ellipses(poses, _isotropic(n, area), every=1000)
    assert len(_ellipse_collection(ax).get_widths()) == 4
    assert ax.get_legend_handles_labels()[1] == ["95 % confidence ellipses (every 1000th pose)"]


def test_subsampling_of_a_straight_corridor_and_of_few_poses():
    # all on a line: the map's area is its length times a tenth of it (100 m x 10 m)
    poses = np.column_stack([np.linspace(0, 100, 1000), np.zeros(1000), np.zeros(1000)])
    ax = lagolib.plot_covariance_ellipses(poses, _isotropic(1000, 12.5))  # 20 fit a quarter
    assert len(_ellipse_collection(ax).get_widths()) == 20
    assert ax.get_legend_handles_labels()[1] == ["95 % confidence ellipses (every 50th pose)"]
    # ten poses or fewer: all of them, however large
    ax = lagolib.plot_covariance_ellipses(poses[:10], _isotropic(10, 1e6))
    assert len(_ellipse_collection(ax).get_widths()) == 10
    ax = lagolib.plot_covariance_ellipses(poses[:500:21], _isotropic(24, 1e6))
    assert ax.get_legend_handles_labels()[1] == ["95 % confidence ellipses (every 3rd pose)"]


@pytest.mark.parametrize(
    "kw, error, fragment",
    [
        ({"confidence": 1.0}, lagolib.errors.OptionError, r"confidence must be a probability"),
        ({"confidence": 0.0}, lagolib.errors.OptionError, r"confidence must be a probability"),
        ({"confidence": 95}, lagolib.errors.OptionError, r"e\.g\. 0\.95 .*got 95"),
        ({"confidence": "0.95"}, lagolib.errors.OptionTypeError, r"confidence must be a real"),
        ({"confidence": 0.9, "n_sigma": 3}, lagolib.errors.OptionError, r"not both"),
        ({"label": 3}, lagolib.errors.OptionTypeError, r"label must be True"),
    ],
)
def test_bad_ellipse_options_are_named(kw, error, fragment):
    with pytest.raises(error, match=rf"^plot_covariance_ellipses: .*{fragment}"):
        lagolib.plot_covariance_ellipses([[0.0, 0.0, 0.0]], [np.eye(3)], **kw)
    with pytest.raises(lagolib.errors.OptionError, match=r"^ellipse_scale: confidence must be"):
        lagolib.plotting.ellipse_scale(1.5)
