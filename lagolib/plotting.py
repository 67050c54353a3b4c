"""Pictures of pose graphs and trajectories (matplotlib).

Every function draws into an Axes (a new one when ``ax`` is None), returns it, and never calls
``plt.show()``: the notebook or script decides when to show.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .checks import check_bool, check_int, check_real
from .errors import GraphError, OptionError, OptionTypeError
from .graph import PoseGraph, _numeric, _shown, as_graph_poses, check_graph, check_poses
from .occupancy import OccupancyGrid
from .topology import spanning_tree

__all__ = [
    "plot_graph",
    "plot_spanning_tree",
    "plot_trajectories",
    "plot_poses",
    "covariance_ellipse",
    "ellipse_scale",
    "ELLIPSE_COLOR",
    "MAX_ELLIPSES",
    "MAX_ELLIPSE_AREA",
    "MIN_ELLIPSES",
    "plot_covariance_ellipses",
    "plot_occupancy",
]


def _axes(ax, where):
    """``ax``, or a new Axes when it is None; anything else is an OptionTypeError."""
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6, 6))
        return ax
    from matplotlib.axes import Axes

    if not isinstance(ax, Axes):
        raise OptionTypeError(
            f"{where}: ax must be a matplotlib Axes or None; got {_shown(ax)} (e.g. "
            "fig, ax = plt.subplots())"
        )
    return ax


def _check_title(title, where):
    if title is not None and not isinstance(title, str):
        raise OptionTypeError(f"{where}: title must be text or None; got {_shown(title)}")
    return title


def _check_color(color, name, where):
    from matplotlib.colors import is_color_like

    if isinstance(color, bool | np.bool_) or not is_color_like(color):
        raise OptionError(
            f"{where}: {name} must be a matplotlib colour (a name such as 'C3' or 'tab:red', "
            f"'#rrggbb', or an RGB(A) tuple of numbers in [0, 1]); got {_shown(color)}"
        )
    return color


def _check_kw(kw, name, where):
    """``kw`` if it is None or a mapping with text keys (matplotlib properties)."""
    if kw is None:
        return {}
    if not isinstance(kw, Mapping) or not all(isinstance(k, str) for k in kw):
        raise OptionTypeError(
            f"{where}: {name} must be a dict of matplotlib properties (e.g. "
            f"{{'linewidths': 2}}) or None; got {_shown(kw)}"
        )
    return dict(kw)


def _drawn(where, what, draw, *args, **kw):
    """``draw(*args, **kw)``; matplotlib's complaint about a property (an unknown name, a value
    of the wrong kind) becomes an OptionError naming ``where`` and ``what``."""
    try:
        return draw(*args, **kw)
    except (AttributeError, TypeError, ValueError) as exc:
        raise OptionError(f"{where}: {what}: matplotlib refused it: {exc}") from None


def _points(poses, where, name="poses", columns=(3,)):
    """``poses`` as a finite float array of shape (k, c) with ``c`` in ``columns``; a single
    pose of shape (c,) is one row.  GraphTypeError for what is not real numbers, GraphError for
    a wrong shape or a non-finite row (named)."""
    p = _numeric(poses, f"{where}: {name}", float)
    if p.ndim == 1 and p.shape[0] in columns:
        p = p[None]
    if p.ndim != 2 or p.shape[1] not in columns:
        want = " or ".join(f"(k, {c})" for c in columns)
        raise GraphError(f"{where}: {name} must have shape {want}; got {p.shape}")
    full = np.zeros((p.shape[0], 3))
    full[:, : p.shape[1]] = p
    check_poses(full, None, f"{where}: {name}: pose")
    return p


def _check_highlight(highlight, m, where):
    """Edge indices (integers in ``0..m-1``) as an int64 array."""
    if highlight is None:
        return np.zeros(0, dtype=np.int64)
    h = _numeric(highlight, f"{where}: highlight", None)
    if h.size == 0:
        return np.zeros(0, dtype=np.int64)
    if (
        h.ndim > 1
        or h.dtype.kind not in "iuO"
        or not all(isinstance(v, int) for v in h.ravel().tolist())
    ):
        raise OptionTypeError(
            f"{where}: highlight must be edge indices (integers); got {_shown(highlight)}"
        )
    h = np.atleast_1d(h)
    out = [v for v in h.tolist() if not 0 <= v < m]
    if out:
        raise OptionError(
            f"{where}: highlight: edge index {out[0]} is out of range (the graph has {m} edges, "
            f"indices 0..{m - 1})"
        )
    return h.astype(np.int64)


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
        An option of the wrong kind or value (the message names it): ``legend`` not one of the
        places above, ``arrows`` or ``vertices`` not a bool, ``odometry_kw``/``loop_kw`` not a
        dict of properties matplotlib accepts, ``ax`` not an Axes.
    GraphError
        ``poses`` of the wrong shape or not finite (the message names the vertex).
    """
    from matplotlib.collections import LineCollection

    where = "plot_graph"
    check_graph(graph, where)
    _check_legend(legend, where)
    arrows = check_bool(arrows, "arrows", where)
    vertices = check_bool(vertices, "vertices", where)
    odometry_kw = _check_kw(odometry_kw, "odometry_kw", where)
    loop_kw = _check_kw(loop_kw, "loop_kw", where)
    title = _check_title(title, where)
    poses = as_graph_poses(graph, poses, f"{where}: poses")
    ax = _axes(ax, where)
    odo = graph.odometric
    style = {"colors": "tab:blue", "linewidths": 1.0, "label": f"odometric ({int(odo.sum())})"}
    style.update(odometry_kw)
    lines = _drawn(
        where, "odometry_kw", LineCollection, _segments(poses, graph.edges[odo]), **style
    )
    style = {
        "colors": "tab:red",
        "linewidths": 0.6,
        "linestyles": ":",
        "alpha": 0.8,
        "label": f"loop closures ({int((~odo).sum())})",
    }
    style.update(loop_kw)
    loops = _drawn(where, "loop_kw", LineCollection, _segments(poses, graph.edges[~odo]), **style)
    ax.add_collection(lines)
    ax.add_collection(loops)
    if arrows:
        _arrowheads(ax, poses, graph.edges[odo], odometry_kw.get("colors", "tab:blue"))
        _arrowheads(ax, poses, graph.edges[~odo], loop_kw.get("colors", "tab:red"))
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
    tree : lagolib.topology.SpanningTree or {"min_uncertainty", "odometric", "bfs"}
        The tree to draw (checked against the graph), or the name of one to build
        (:func:`lagolib.topology.spanning_tree`).
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
        An option of the wrong kind or value (the message names it): ``legend`` not one of the
        places above, ``arrows`` or ``labels`` not a bool, ``highlight`` not edge indices of the
        graph, ``ax`` not an Axes.
    GraphError
        ``poses`` of the wrong shape or not finite, or a tree of another graph.
    """
    from matplotlib.collections import LineCollection

    where = "plot_spanning_tree"
    check_graph(graph, where)
    tree = spanning_tree(graph, tree)  # a name builds one; a given tree is checked against graph
    _check_legend(legend, where)
    arrows = check_bool(arrows, "arrows", where)
    labels = check_bool(labels, "labels", where)
    title = _check_title(title, where)
    h = _check_highlight(highlight, graph.m, where)
    poses = as_graph_poses(graph, poses, f"{where}: poses")
    ax = _axes(ax, where)
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
    if h.size:
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
    where = "plot_trajectories"
    _check_legend(legend, where)
    title = _check_title(title, where)
    if not isinstance(trajectories, Mapping):
        raise OptionTypeError(
            f"{where}: trajectories must be a dict of label -> poses (or PoseGraph); got "
            f"{_shown(trajectories)}, e.g. {{'odometry': graph, 'truth': truth}}"
        )
    lines = []
    for label, value in trajectories.items():
        if isinstance(value, PoseGraph):
            poses = value.poses[np.argsort(value.ids, kind="stable")]
        else:
            poses = _points(value, where, f"trajectories[{label!r}]", columns=(2, 3))
        lines.append((label, poses))
    ax = _axes(ax, where)
    for label, poses in lines:
        _drawn(where, "**kw", ax.plot, poses[:, 0], poses[:, 1], label=str(label), **kw)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    _legend(ax, legend if lines else None)  # nothing drawn: no (empty) legend
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
    where = "plot_poses"
    p = _points(poses, where)
    if length is None:
        with np.errstate(over="ignore"):
            extent = np.ptp(p[:, :2], axis=0).max() if len(p) > 1 else 1.0
        if not np.isfinite(extent):  # positions near ±1.8e308: the spread itself overflows
            extent = np.max(np.abs(p[:, :2]))
        length = max(0.1 * extent, 0.2)
    else:
        length = check_real(length, "length", where, minimum=0.0, strict=True)
    if labels is not None:
        try:
            texts = None if isinstance(labels, str | bytes) else list(labels)
        except TypeError:
            texts = None
        if texts is None or not all(isinstance(t, str) for t in texts):
            raise OptionTypeError(
                f"{where}: labels must be a list of text, one per pose; got {_shown(labels)}"
            )
        labels = texts
        if len(labels) != len(p):
            raise OptionError(f"{where}: {len(p)} poses but {len(labels)} labels")
    color = _check_color(color, "color", where)
    ax = _axes(ax, where)
    with np.errstate(over="ignore"):  # an arrow beyond float64 is refused below
        u, v = length * np.cos(p[:, 2]), length * np.sin(p[:, 2])
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(v))):
        raise OptionError(f"{where}: length {length!r} overflows float64 in the arrows")
    _drawn(
        where,
        "**kw",
        ax.quiver,
        p[:, 0],
        p[:, 1],
        u,
        v,
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
        Positive.

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
    where = "covariance_ellipse"
    n_sigma = check_real(n_sigma, "n_sigma", where, minimum=0.0, strict=True)
    return _ellipses(_position_blocks(cov, where, "cov"), n_sigma, where)


def _position_blocks(cov, where, name):
    """The symmetric ``(x, y)`` blocks of covariances, shape (..., 2, 2), checked.

    ``cov`` must be real and finite, of shape (..., 2, 2) or (..., 3, 3), with a symmetric
    positive semi-definite ``(x, y)`` block — up to rounding: an asymmetry or a negative
    eigenvalue below ``1e-8`` of the matrix's largest entry (or of a millionth of the largest
    entry of all of them, for matrices that are zero up to rounding, such as a fixed pose's).
    """
    c = _numeric(cov, f"{where}: {name}", float)
    if c.ndim < 2 or c.shape[-2:] not in ((2, 2), (3, 3)):
        raise OptionError(
            f"{where}: {name} must be covariance matrices, shape (..., 2, 2) or (..., 3, 3); got "
            f"shape {c.shape}"
        )
    c = c[..., :2, :2].reshape(-1, 2, 2)
    bad = np.flatnonzero(~np.all(np.isfinite(c), axis=(1, 2)))
    if bad.size:
        raise OptionError(
            f"{where}: {name}: matrix {int(bad[0])} is not finite: {c[bad[0]].tolist()}"
        )
    own = np.max(np.abs(c), axis=(1, 2), initial=0.0)
    tol = 1e-8 * np.maximum(own, 1e-6 * np.max(own, initial=0.0))
    asym = np.abs(c[:, 0, 1] - c[:, 1, 0])
    unit = np.where(own > 0, own, 1.0)[:, None, None]
    sym = 0.5 * (c / unit + np.swapaxes(c / unit, 1, 2))  # entries in [-1, 1]: no overflow
    lo = np.linalg.eigvalsh(sym)[:, 0] * unit[:, 0, 0]
    bad = np.flatnonzero((asym > tol) | (lo < -tol))
    if bad.size:
        k = int(bad[0])
        what = (
            "not symmetric"
            if asym[k] > tol[k]
            else f"not positive semi-definite (eigenvalue {lo[k]:.3g})"
        )
        raise OptionError(
            f"{where}: {name}: the (x, y) block of matrix {k} is {what}: {c[k].tolist()}; a "
            "covariance is symmetric positive semi-definite"
        )
    sym = 0.5 * c + 0.5 * np.swapaxes(c, 1, 2)  # halves first: no overflow near 1.8e308
    return sym.reshape(np.shape(cov)[:-2] + (2, 2))


def _ellipses(blocks, n_sigma, where):
    """Full axes and major-axis angle of checked ``(x, y)`` blocks (computed without overflow:
    the eigenvalues of each block divided by its largest entry)."""
    scale = np.max(np.abs(blocks), axis=(-2, -1))
    unit = np.where(scale > 0, scale, 1.0)
    vals, vecs = np.linalg.eigh(blocks / unit[..., None, None])
    vals = np.clip(vals, 0.0, None)
    major = vecs[..., :, 1]
    angle = np.degrees(np.arctan2(major[..., 1], major[..., 0]))
    angle = np.where(angle > 90, angle - 180, np.where(angle <= -90, angle + 180, angle))
    with np.errstate(over="ignore"):
        root = 2 * n_sigma * np.sqrt(unit)
        width, height = root * np.sqrt(vals[..., 1]), root * np.sqrt(vals[..., 0])
    if not np.all(np.isfinite(width)):
        raise OptionError(
            f"{where}: the {n_sigma!r}-sigma ellipse is beyond float64 (n_sigma times a standard "
            "deviation exceeds 1.8e308); choose a smaller n_sigma"
        )
    return width, height, angle + 0.0


#: The ellipses' default colour: not the odometry's blue or the loop closures' red of
#: :func:`plot_graph`, nor the orange and green of a second and third trajectory.
ELLIPSE_COLOR = "tab:purple"
#: :func:`plot_covariance_ellipses` draws at most this many ellipses by default ...
MAX_ELLIPSES = 100
#: ... whose areas add up to at most this fraction of the map's area (its ``every=None`` rule) ...
MAX_ELLIPSE_AREA = 0.25
#: ... but never fewer than this many (when there are that many poses).
MIN_ELLIPSES = 10


def ellipse_scale(confidence: float) -> float:
    """The number of standard deviations whose ellipse holds ``confidence`` of a 2D Gaussian.

    ``sqrt(χ²₂⁻¹(confidence)) = sqrt(−2 ln(1 − confidence))``, the square root of the quantile of
    the χ² distribution with 2 degrees of freedom: a position error ``δ`` with covariance ``Σ``
    has ``δᵀ Σ⁻¹ δ ~ χ²₂``, and the ellipse ``δᵀ Σ⁻¹ δ = k²`` has semi-axes ``k`` times the
    standard deviations along the principal axes of ``Σ``.  0.95 gives 2.448; 3 σ holds 98.9 %.

    Parameters
    ----------
    confidence : float
        A probability in (0, 1).

    Returns
    -------
    float

    Raises
    ------
    OptionError, OptionTypeError
        ``confidence`` not a number in (0, 1).

    >>> round(ellipse_scale(0.95), 4)
    2.4477
    """
    confidence = _check_confidence(confidence, "ellipse_scale")
    return float(np.sqrt(-2.0 * np.log1p(-confidence)))


def _check_confidence(confidence, where):
    confidence = check_real(confidence, "confidence", where)
    if not 0.0 < confidence < 1.0:
        raise OptionError(
            f"{where}: confidence must be a probability in (0, 1), e.g. 0.95 for 95 % ellipses; "
            f"got {confidence!r}"
        )
    return confidence


def _ellipse_step(centres, blocks, n_sigma) -> int:
    """The step of :func:`plot_covariance_ellipses`'s ``every=None`` (its docstring states the
    rule): ``centres`` (k, 2), checked ``(x, y)`` blocks (k, 2, 2), scale in sigmas."""
    k = len(centres)
    if k <= MIN_ELLIPSES:
        return 1
    fits = MAX_ELLIPSES
    span = np.ptp(centres, axis=0)
    if span.max() > 0:
        # the map's area: the centres' bounding box, each side at least a tenth of the longer one
        # (a straight corridor still has an area)
        area = float(np.prod(np.maximum(span, 0.1 * span.max())))
        det = np.clip(blocks[:, 0, 0] * blocks[:, 1, 1] - blocks[:, 0, 1] ** 2, 0.0, None)
        mean = float(np.mean(np.pi * n_sigma**2 * np.sqrt(det)))  # ellipse area π k² sqrt(det Σ)
        if mean > 0 and np.isfinite(mean):
            fits = min(fits, max(MIN_ELLIPSES, int(MAX_ELLIPSE_AREA * area / mean)))
    return max(1, -(-k // fits))


def _ordinal(n: int) -> str:
    """``1st``, ``2nd``, ``3rd``, ``4th``, ``11th``, ``123rd``."""
    teen = 10 <= n % 100 <= 20
    return f"{n}{'th' if teen else {1: 'st', 2: 'nd', 3: 'rd'}.get(n % 10, 'th')}"


def _percent(confidence: float) -> str:
    """``95``, ``98.9``, ``99.99``: the shortest of 3 to 6 significant digits that is not 100."""
    for digits in range(3, 7):
        text = f"{100 * confidence:.{digits}g}"
        if float(text) < 100:
            break
    return text


def plot_covariance_ellipses(
    poses,
    covariances,
    ax=None,
    *,
    confidence=None,
    n_sigma=None,
    every=None,
    color=ELLIPSE_COLOR,
    label=True,
    **kw,
):
    """Draw each pose's position-uncertainty ellipse at a stated confidence level.

    The ellipse of a pose with position covariance ``Σ`` (the ``(x, y)`` block) is
    ``δᵀ Σ⁻¹ δ = k²`` around it, ``k =`` :func:`ellipse_scale` ``(confidence)``: its semi-axes
    are ``k`` times the standard deviations along the eigenvectors of ``Σ``, and a Gaussian
    position error falls inside it with probability ``confidence``.

    Parameters
    ----------
    poses : array_like, shape (k, 3) or (k, 2)
        Centres (only ``x, y`` are used).
    covariances : array_like, shape (k, 3, 3) or (k, 2, 2)
        World-frame covariances, e.g. from :func:`lagolib.uncertainty.marginal_covariances`;
        the ``(x, y)`` block is drawn.
    ax : matplotlib.axes.Axes, optional
    confidence : float, optional
        The probability mass of a 2D Gaussian inside each ellipse, in (0, 1); default 0.95.
    n_sigma : float, optional
        Instead of ``confidence``, the scale ``k`` in standard deviations (1 holds 39.3 %, 3 holds
        98.9 %); the legend states the confidence it stands for, ``1 − exp(−k²/2)``.
    every : int, optional
        Draw the ellipse of every ``every``-th pose of ``poses`` (``>= 1``), starting with the
        first.  By default (None) the smallest step that draws at most :data:`MAX_ELLIPSES`
        (100) ellipses whose areas add up to at most :data:`MAX_ELLIPSE_AREA` (a quarter) of
        the map's area — the bounding box of the centres, each side at least a tenth of the
        longer — estimated from the mean ellipse area; but at least :data:`MIN_ELLIPSES` (10)
        ellipses when there are that many poses.  Measured on the LAGO + Gauss–Newton optimum of
        the benchmarks (``lagolib plot --ellipses``): INTEL's mean 95 % ellipse is 35.7 m², 5.1 %
        of its 705 m² box, and M3500's 204 m², 3.9 % of 5227 m², so a quarter of the map holds
        about 5 and 6 of them and the rule draws the minimum of 10 (every 123rd and every 350th
        pose); these cover 42 % and 18 % of the box, and 16 % and 28 % of the area they cover
        lies inside two or more of them.  The old default, about 100 3-sigma ellipses, covered
        95 % and 73 % of the box, 91 % and 78 % of that area inside two or more: a blob that hid
        the map.  Small ellipses (the shipped examples, city10000) keep up to 100.  Pass
        ``every=1`` to draw every ellipse (a ``label`` of your own does not turn the rule off).
    color : color
        Default :data:`ELLIPSE_COLOR`, not the colour of :func:`plot_graph`'s loop closures.
    label : bool or str
        The legend entry: True for "95 % confidence ellipses (every 123rd pose)", a string for
        your own, False for none.  The entry is added to the Axes' handles; call
        ``ax.legend()`` (or a lagolib plot with ``legend=...`` drawn after this) to show it.
    **kw
        Passed to :class:`matplotlib.collections.EllipseCollection` (e.g. ``linewidths``).

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    OptionError, OptionTypeError
        ``confidence`` not in (0, 1), both ``confidence`` and ``n_sigma`` given, ``n_sigma``
        not a positive number, ``every`` not a positive integer, ``label`` neither a bool nor
        text, a colour matplotlib does not know, ``ax`` not an Axes, covariances that are not
        finite symmetric positive semi-definite (the message names the matrix), or not one per
        pose.
    GraphError
        ``poses`` of the wrong shape or not finite (the message names the row).

    Examples
    --------
    >>> import numpy as np
    >>> ax = plot_covariance_ellipses(np.zeros((1, 3)), [np.diag([0.04, 0.01])])
    >>> ax.collections[0].get_widths().round(4)  # 2 × 2.4477 × 0.2 m: the full major axis
    array([0.9791])
    >>> ax.get_legend_handles_labels()[1]
    ['95 % confidence ellipses']
    """
    from matplotlib.collections import EllipseCollection

    where = "plot_covariance_ellipses"
    if confidence is not None and n_sigma is not None:
        raise OptionError(
            f"{where}: give confidence (e.g. 0.95) or n_sigma (e.g. 3), not both; got the "
            f"confidence {confidence!r} and the n_sigma {n_sigma!r}"
        )
    if n_sigma is None:
        confidence = _check_confidence(0.95 if confidence is None else confidence, where)
        n_sigma = ellipse_scale(confidence)
    else:
        n_sigma = check_real(n_sigma, "n_sigma", where, minimum=0.0, strict=True)
        confidence = float(-np.expm1(-(n_sigma**2) / 2))
    if every is not None:
        every = check_int(every, "every", where, minimum=1)
    if not isinstance(label, (bool, np.bool_, str)):
        raise OptionTypeError(
            f"{where}: label must be True (the default text), False (none) or text; got "
            f"{_shown(label)}"
        )
    color = _check_color(color, "color", where)
    p = _points(poses, where, columns=(2, 3))
    cov = _position_blocks(covariances, where, "covariances")
    if cov.ndim == 2:
        cov = cov[None]
    if cov.ndim != 3 or len(p) != len(cov):
        raise OptionError(
            f"{where}: {len(p)} poses but {len(cov) if cov.ndim == 3 else cov.shape} "
            "covariances; give one covariance per pose"
        )
    if every is None:
        every = _ellipse_step(p[:, :2], cov, n_sigma)
    p, cov = p[::every], cov[::every]
    w, h, a = _ellipses(cov, n_sigma, where)
    ax = _axes(ax, where)
    kw.setdefault("facecolors", "none")
    kw.setdefault("linewidths", 0.8)
    coll = _drawn(
        where,
        "**kw",
        EllipseCollection,
        w,
        h,
        a,
        units="xy",
        offsets=p[:, :2],
        offset_transform=ax.transData,
        edgecolors=color,
        **kw,
    )
    ax.add_collection(coll)
    if label is True or label is np.True_:
        nth = "" if every == 1 else f" (every {_ordinal(every)} pose)"
        label = f"{_percent(confidence)} % confidence ellipses{nth}"
    if label:
        # the legend's entry: a hollow circle of the ellipses' colour that draws nothing and
        # leaves the data limits alone
        ax.plot([], [], "o", markersize=9, markerfacecolor="none", color=color, label=label)
    ax.update_datalim(np.concatenate([p[:, :2] + w[:, None] / 2, p[:, :2] - w[:, None] / 2]))
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    return ax


def plot_occupancy(grid, ax=None, *, title=None, threshold=None, **kw):
    """Draw an occupancy grid as a grey image in world coordinates (metres).

    Occupied cells black, free white, unknown mid grey (:meth:`OccupancyGrid.image`), placed at
    the grid's world-frame ``extent`` so that poses and trajectories can be drawn on top.

    Parameters
    ----------
    grid : OccupancyGrid
        From :func:`lagolib.occupancy.occupancy_grid`.
    ax : matplotlib.axes.Axes, optional
    title : str, optional
    threshold : float, optional
        None: shades of grey ``255 (1 - p)``; a number: three levels (``OccupancyGrid.classify``).
    **kw
        Passed to ``ax.imshow`` (e.g. ``alpha``, ``zorder``).

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import numpy as np
    >>> from lagolib.occupancy import OccupancyGrid
    >>> grid = OccupancyGrid(np.array([[3.5, -2.0], [0.0, 0.0]]), 0.5, (1.0, 2.0))
    >>> ax = plot_occupancy(grid)
    >>> ax.images[0].get_extent()
    [1.0, 2.0, 2.0, 3.0]
    """
    where = "plot_occupancy"
    if not isinstance(grid, OccupancyGrid):
        raise OptionTypeError(
            f"{where}: grid must be an OccupancyGrid (from lagolib.occupancy.occupancy_grid); "
            f"got {_shown(grid)}"
        )
    title = _check_title(title, where)
    image = grid.image(threshold)
    ax = _axes(ax, where)
    kw.setdefault("cmap", "gray")
    kw.setdefault("interpolation", "nearest")
    _drawn(where, "**kw", ax.imshow, image, extent=grid.extent, vmin=0, vmax=255, **kw)
    return _finish(ax, title, legend=None)
