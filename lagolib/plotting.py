"""Pictures of pose graphs and trajectories (matplotlib).

Every function draws into an Axes (a new one when ``ax`` is None), returns it, and never calls
``plt.show()``: the notebook or script decides when to show.
"""

from __future__ import annotations

import numpy as np

from .checks import check_bool
from .errors import OptionError

__all__ = [
    "plot_graph",
    "plot_spanning_tree",
    "plot_trajectories",
    "plot_poses",
    "covariance_ellipse",
    "plot_covariance_ellipses",
]


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6, 6))
    return ax


def _segments(poses, edges):
    return np.stack([poses[edges[:, 0], :2], poses[edges[:, 1], :2]], axis=1)


_LEGEND_PLACES = ("best", "outside", "below")


def _check_legend(legend, where):
    """``legend`` is one of :data:`_LEGEND_PLACES`, None or False (else OptionError)."""
    if legend is None or legend is False:
        return legend
    if isinstance(legend, str) and legend in _LEGEND_PLACES:
        return legend
    raise OptionError(
        f"{where}: legend must be one of {', '.join(map(repr, _LEGEND_PLACES))}, None or False; "
        f"got {legend!r}"
    )


def _legend(ax, legend):
    """Place the legend: inside (``"best"``), right of the axes (``"outside"``), under the
    x label (``"below"``), or none (``None``/``False``)."""
    if legend is None or legend is False:
        return
    if legend == "outside":
        ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize="small")
    elif legend == "below":
        from matplotlib.transforms import ScaledTranslation

        # a fixed 0.5 inch under the axes clears the tick labels and the x label at any size
        below = ax.transAxes + ScaledTranslation(0.0, -0.5, ax.figure.dpi_scale_trans)
        ax.legend(
            loc="upper center",
            bbox_to_anchor=(0.5, 0.0),
            bbox_transform=below,
            ncol=2,
            fontsize="small",
        )
    else:
        ax.legend(loc="best", fontsize="small")


def _finish(ax, title, legend="best"):
    """Equal-aspect map axes in metres, with a legend and an optional title."""
    ax.autoscale_view()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    _legend(ax, legend)
    if title:
        ax.set_title(title)
    return ax


def _arrowheads(ax, poses, edges, color, *, at=0.7, zorder=3):
    """One arrowhead per edge, tip at fraction ``at`` of the way from tail to head.

    The heads have a fixed size on the page (0.15 inch), whatever the data scale, and point from
    the tail pose ``edges[:, 0]`` to the head pose ``edges[:, 1]``.  One
    :class:`matplotlib.quiver.Quiver` for all of them (``X, Y`` the tips, ``U, V`` the unit
    directions); edges of zero length get no head.

    Returns
    -------
    matplotlib.quiver.Quiver or None
    """
    tail, head = poses[edges[:, 0], :2], poses[edges[:, 1], :2]
    d = head - tail
    length = np.hypot(d[:, 0], d[:, 1])
    ok = length > 0
    if not ok.any():
        return None
    u = d[ok] / length[ok, None]
    tip = tail[ok] + at * d[ok]
    return ax.quiver(
        tip[:, 0],
        tip[:, 1],
        u[:, 0],
        u[:, 1],
        color=color,
        angles="xy",
        pivot="tip",
        units="inches",
        scale_units="inches",
        scale=1 / 0.15,
        width=0.02,
        headwidth=4.5,
        headlength=5,
        headaxislength=4.5,
        zorder=zorder,
        label="_nolegend_",
    )


def plot_graph(
    graph,
    poses=None,
    ax=None,
    *,
    odometry_kw=None,
    loop_kw=None,
    vertices=False,
    arrows=False,
    legend="best",
    title=None,
):
    """Draw a pose graph: odometric edges solid, loop closures dotted (as in Carlone et al. Fig. 1).

    Parameters
    ----------
    graph : PoseGraph
    poses : array_like, shape (n, 3), optional
        Where to draw the vertices; default ``graph.poses``.
    ax : matplotlib.axes.Axes, optional
    odometry_kw, loop_kw : dict, optional
        Extra LineCollection properties for the two kinds of edge.
    vertices : bool
        Also mark every vertex with a dot.
    arrows : bool
        Draw an arrowhead on every edge, pointing from its tail ``i`` to its head ``j`` (the
        direction of the measurement ``z_ij`` and of the incidence matrix's ``−1 → +1``).  For
        small graphs: one head per edge.
    legend : {"best", "outside", "below"} or None
        Legend inside the axes where matplotlib finds room, right of the axes, under the x label,
        or none.
    title : str, optional

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    OptionError, OptionTypeError
        ``legend`` is not one of the places above, or ``arrows`` is not a bool.
    """
    from matplotlib.collections import LineCollection

    _check_legend(legend, "plot_graph")
    arrows = check_bool(arrows, "arrows", "plot_graph")
    ax = _axes(ax)
    poses = graph.poses if poses is None else np.asarray(poses, dtype=float)
    odo = graph.odometric
    style = {"colors": "tab:blue", "linewidths": 1.0, "label": f"odometric ({int(odo.sum())})"}
    style.update(odometry_kw or {})
    ax.add_collection(LineCollection(_segments(poses, graph.edges[odo]), **style))
    style = {
        "colors": "tab:red",
        "linewidths": 0.6,
        "linestyles": ":",
        "alpha": 0.8,
        "label": f"loop closures ({int((~odo).sum())})",
    }
    style.update(loop_kw or {})
    ax.add_collection(LineCollection(_segments(poses, graph.edges[~odo]), **style))
    if arrows:
        _arrowheads(ax, poses, graph.edges[odo], (odometry_kw or {}).get("colors", "tab:blue"))
        _arrowheads(ax, poses, graph.edges[~odo], (loop_kw or {}).get("colors", "tab:red"))
    if vertices:
        ax.plot(poses[:, 0], poses[:, 1], ".", color="k", markersize=2)
    return _finish(ax, title, legend)


def plot_spanning_tree(
    graph,
    tree,
    poses=None,
    ax=None,
    *,
    highlight=None,
    labels=False,
    arrows=False,
    legend="best",
    title=None,
):
    """Draw a spanning tree and its chords (Carlone et al. 2011, §IV-E).

    Tree edges solid, chords dashed; ``highlight`` edges (e.g. a fundamental circuit) drawn thick.

    Parameters
    ----------
    graph : PoseGraph
    tree : lagolib.topology.SpanningTree
    poses : array_like, shape (n, 3), optional
        Where to draw the vertices; default ``graph.poses``.
    ax : matplotlib.axes.Axes, optional
    highlight : array_like of int, optional
        Edge indices to emphasize.
    labels : bool
        Write vertex rows at the vertices and edge indices at the edge midpoints (small graphs).
    arrows : bool
        Draw an arrowhead on every edge, from its tail ``i`` to its head ``j``: the direction in
        which a fundamental circuit's sign is counted (+1 along the edge, −1 against it).  For
        small graphs.
    legend : {"best", "outside", "below"} or None
        Legend inside the axes, right of them, under the x label, or none.
    title : str, optional

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    OptionError, OptionTypeError
        ``legend`` is not one of the places above, or ``arrows`` is not a bool.
    """
    from matplotlib.collections import LineCollection

    _check_legend(legend, "plot_spanning_tree")
    arrows = check_bool(arrows, "arrows", "plot_spanning_tree")
    ax = _axes(ax)
    poses = graph.poses if poses is None else np.asarray(poses, dtype=float)
    t = np.asarray(tree.in_tree, dtype=bool)
    ax.add_collection(
        LineCollection(
            _segments(poses, graph.edges[t]),
            colors="tab:blue",
            linewidths=1.2,
            label=f"{tree.kind} tree ({int(t.sum())} edges)",
        )
    )
    ax.add_collection(
        LineCollection(
            _segments(poses, graph.edges[~t]),
            colors="tab:orange",
            linewidths=1.0,
            linestyles="--",
            label=f"chords ({int((~t).sum())})",
        )
    )
    if highlight is not None and len(highlight):
        h = np.asarray(highlight, dtype=np.int64)
        ax.add_collection(
            LineCollection(
                _segments(poses, graph.edges[h]),
                colors="tab:red",
                linewidths=3.0,
                alpha=0.6,
                label=f"highlighted ({h.size})",
            )
        )
    if arrows:
        _arrowheads(ax, poses, graph.edges[t], "tab:blue")
        _arrowheads(ax, poses, graph.edges[~t], "tab:orange")
    ax.plot(poses[:, 0], poses[:, 1], "o", color="k", markersize=3 if labels else 1.5)
    ax.plot(*poses[tree.root, :2], "s", color="tab:green", markersize=8, label="root (anchor)")
    if labels:
        for v, (x, y) in enumerate(poses[:, :2]):
            ax.annotate(str(v), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
        mid = 0.5 * (poses[graph.edges[:, 0], :2] + poses[graph.edges[:, 1], :2])
        for k, (x, y) in enumerate(mid):
            ax.annotate(f"e{k}", (x, y), fontsize=7, color="tab:gray", ha="center")
    return _finish(ax, title, legend)


def plot_trajectories(trajectories, ax=None, *, title=None, legend="best", **kw):
    """Draw several trajectories for comparison.

    Parameters
    ----------
    trajectories : dict of str -> array_like (n, 3) or PoseGraph
        Label to poses (a PoseGraph contributes its ``poses``), drawn as lines in id order.
    ax : matplotlib.axes.Axes, optional
    title : str, optional
    legend : {"best", "outside", "below"} or None
        Legend inside the axes, right of them, under the x label, or none.
    **kw
        Passed to every ``ax.plot`` call.

    Returns
    -------
    matplotlib.axes.Axes
    """
    _check_legend(legend, "plot_trajectories")
    ax = _axes(ax)
    for label, value in trajectories.items():
        if hasattr(value, "poses") and hasattr(value, "order"):
            poses = value.poses[np.argsort(value.ids, kind="stable")]
        else:
            poses = np.asarray(value, dtype=float)
        ax.plot(poses[:, 0], poses[:, 1], label=label, **kw)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    _legend(ax, legend)
    if title:
        ax.set_title(title)
    return ax


def plot_poses(poses, ax=None, *, length=None, labels=None, color="k", **kw):
    """Draw poses as arrows (position and heading), e.g. to illustrate compounding.

    Parameters
    ----------
    poses : array_like, shape (k, 3)
    ax : matplotlib.axes.Axes, optional
    length : float, optional
        Arrow length; default a tenth of the extent of the positions (at least 0.2).
    labels : sequence of str, optional
        Text written next to each pose.
    color : color
    **kw
        Passed to ``ax.quiver``.

    Returns
    -------
    matplotlib.axes.Axes
    """
    ax = _axes(ax)
    p = np.atleast_2d(np.asarray(poses, dtype=float))
    if length is None:
        extent = np.ptp(p[:, :2], axis=0).max() if len(p) > 1 else 1.0
        length = max(0.1 * extent, 0.2)
    ax.quiver(
        p[:, 0],
        p[:, 1],
        length * np.cos(p[:, 2]),
        length * np.sin(p[:, 2]),
        angles="xy",
        scale_units="xy",
        scale=1,
        color=color,
        **kw,
    )
    ax.plot(p[:, 0], p[:, 1], "o", color=color, markersize=3)
    for text, q in zip(labels or [], p):
        ax.annotate(text, (q[0], q[1]), textcoords="offset points", xytext=(5, -12))
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    return ax


def covariance_ellipse(cov, n_sigma=3.0):
    """Axes and orientation of the ``n_sigma`` ellipse of the ``(x, y)`` block of a covariance.

    Parameters
    ----------
    cov : array_like, shape (..., 2, 2) or (..., 3, 3)
        Only the top-left 2x2 block is used.
    n_sigma : float

    Returns
    -------
    width, height : ndarray, shape (...)
        Full axis lengths, ``2 n_sigma sqrt(eigenvalue)``, major first.
    angle : ndarray, shape (...)
        Angle of the major axis from the x axis, in degrees.

    Examples
    --------
    >>> import numpy as np
    >>> from lagolib.plotting import covariance_ellipse
    >>> w, h, a = covariance_ellipse(np.diag([4.0, 1.0]), n_sigma=1)
    >>> float(w), float(h), float(a)
    (4.0, 2.0, 0.0)
    """
    cov = np.asarray(cov, dtype=float)[..., :2, :2]
    vals, vecs = np.linalg.eigh(cov)
    vals = np.clip(vals, 0.0, None)
    major = vecs[..., :, 1]
    angle = np.degrees(np.arctan2(major[..., 1], major[..., 0]))
    angle = np.where(angle > 90, angle - 180, np.where(angle <= -90, angle + 180, angle))
    return 2 * n_sigma * np.sqrt(vals[..., 1]), 2 * n_sigma * np.sqrt(vals[..., 0]), angle + 0.0


def plot_covariance_ellipses(
    poses, covariances, ax=None, *, n_sigma=3.0, every=1, color="C3", **kw
):
    """Draw the ``n_sigma`` position-uncertainty ellipse of each pose.

    Parameters
    ----------
    poses : array_like, shape (k, 3)
        Centres (only ``x, y`` are used).
    covariances : array_like, shape (k, 3, 3) or (k, 2, 2)
        World-frame covariances, e.g. from :func:`lagolib.uncertainty.marginal_covariances`;
        the ``(x, y)`` block is drawn.
    ax : matplotlib.axes.Axes, optional
    n_sigma : float
        Scale of the ellipses (3: 98.9 % of a 2D Gaussian's mass inside).
    every : int
        Draw every ``every``-th ellipse.
    color : color
    **kw
        Passed to :class:`matplotlib.collections.EllipseCollection`.

    Returns
    -------
    matplotlib.axes.Axes
    """
    from matplotlib.collections import EllipseCollection

    ax = _axes(ax)
    p = np.atleast_2d(np.asarray(poses, dtype=float))[::every]
    cov = np.asarray(covariances, dtype=float)[::every]
    if len(p) != len(cov):
        raise ValueError(f"{len(p)} poses but {len(cov)} covariances")
    w, h, a = covariance_ellipse(cov, n_sigma)
    kw.setdefault("facecolors", "none")
    kw.setdefault("linewidths", 0.8)
    coll = EllipseCollection(
        w, h, a, units="xy", offsets=p[:, :2], offset_transform=ax.transData, edgecolors=color, **kw
    )
    ax.add_collection(coll)
    ax.update_datalim(np.concatenate([p[:, :2] + w[:, None] / 2, p[:, :2] - w[:, None] / 2]))
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    return ax
