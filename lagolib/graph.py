"""The pose graph: vertices (robot poses) and edges (relative pose measurements).

A :class:`PoseGraph` holds ``n`` poses and ``m`` edges.  Edge ``k = (i, j)`` says: *the pose of
vertex j, measured in the frame of vertex i, is* ``measurements[k]``, with information matrix
``information[k]``.  ``i`` and ``j`` are row indices into ``poses``; the original vertex ids of
the file the graph came from are kept in ``ids``.

Measurement model (lecture notes, "The Error Function"), used everywhere in lagolib::

    e_ij = t2v(Z_ij^-1 (X_i^-1 X_j))
         = [ R_z^T (R_i^T (t_j - t_i) - t_z) ;  wrap(theta_j - theta_i - theta_z) ]

    chi2 = sum_ij e_ij^T Omega_ij e_ij

This is g2o's error and g2o's chi²: no factor ½ (GTSAM's ``error`` is ½ of it), and the
information matrix ``Omega_ij`` weighs the error *in the frame of the measurement* — the g2o
convention.  TORO files weigh the error written in frame ``i``; :mod:`lagolib.io` converts them on
reading, so inside lagolib every information matrix follows the one convention above.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from . import se2
from .errors import GraphError

__all__ = ["PoseGraph", "residuals", "chi2", "vertex_rows"]


def _numeric(value, name, dtype):
    """``np.asarray`` that reports non-numeric or ragged input as a GraphError naming ``name``."""
    try:
        a = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise GraphError(f"{name} must be a numeric array: {exc}") from None
    if a.dtype.kind not in "biuf":
        raise GraphError(f"{name} must be a numeric array; got dtype {a.dtype}")
    return a


def _frozen(a, dtype):
    a = np.array(a, dtype=dtype, copy=True)
    a.setflags(write=False)
    return a


class PoseGraph:
    """An immutable planar pose graph.

    Parameters
    ----------
    poses : array_like, shape (n, 3)
        Current estimate (or initial guess) of each vertex, ``(x, y, theta)``.
    edges : array_like of int, shape (m, 2)
        Index pairs ``(i, j)``: ``measurements[k]`` is the pose of ``j`` in the frame of ``i``.
        Edges stored with ``i > j`` are kept as stored, and so are duplicate edges (each is a
        measurement).
    measurements : array_like, shape (m, 3)
        Relative poses ``z_ij = (dx, dy, dtheta)``.
    information : array_like, shape (m, 3, 3)
        Symmetric positive-definite information matrices, g2o convention (see module docstring).
        An asymmetry up to 1e-9 of the largest entry is tolerated (rounding), and the symmetric
        part ``(Omega + Omega^T) / 2`` is stored.
    ids : array_like of int, shape (n,), optional
        Original vertex ids (default ``0 .. n-1``).  Must be unique; they need not equal the row
        index, and they define the *odometric order* of the vertices.

    Raises
    ------
    GraphError
        For wrong shapes, non-finite numbers, indices out of range, self-loops, duplicate ids,
        or an information matrix that is not symmetric positive definite.  The message names the
        offending edge (index and vertex ids) or vertex.

    Notes
    -----
    The arrays are stored read-only; use :meth:`with_poses` to get a graph with other poses.

    Examples
    --------
    >>> import numpy as np
    >>> g = PoseGraph(poses=np.zeros((3, 3)), edges=[[0, 1], [1, 2], [0, 2]],
    ...               measurements=[[1, 0, 0], [1, 0, 0], [2, 0, 0]],
    ...               information=np.tile(np.eye(3), (3, 1, 1)))
    >>> g.n, g.m, g.odometric.tolist(), g.loop_closure.tolist()
    (3, 3, [True, True, False], [False, False, True])
    >>> g.odometry_guess()[:, 0].tolist()
    [0.0, 1.0, 2.0]
    """

    __slots__ = ("_poses", "_ids", "_edges", "_measurements", "_information", "_cache")

    def __init__(self, poses, edges, measurements, information, ids=None):
        poses = _numeric(poses, "poses", float)
        if poses.ndim != 2 or poses.shape[1] != 3:
            raise GraphError(f"poses must have shape (n, 3); got {poses.shape}")
        n = poses.shape[0]
        edges = _numeric(edges, "edges", None)
        if edges.size == 0:
            edges = edges.reshape(0, 2)
        if edges.ndim != 2 or edges.shape[1] != 2:
            raise GraphError(f"edges must have shape (m, 2); got {edges.shape}")
        if edges.dtype.kind not in "iu":
            integral = (
                edges.dtype.kind == "f"
                and np.all(np.isfinite(edges))
                and np.all(edges == np.round(edges))
            )
            if not integral:
                raise GraphError(f"edges must hold integer vertex indices; got dtype {edges.dtype}")
            edges = edges.astype(np.int64)
        m = edges.shape[0]
        measurements = _numeric(measurements, "measurements", float)
        information = _numeric(information, "information", float)
        if m == 0 and measurements.size == 0 and information.size == 0:
            measurements, information = np.zeros((0, 3)), np.zeros((0, 3, 3))
        if measurements.shape != (m, 3):
            raise GraphError(f"measurements must have shape ({m}, 3); got {measurements.shape}")
        if information.shape != (m, 3, 3):
            raise GraphError(f"information must have shape ({m}, 3, 3); got {information.shape}")
        ids = np.arange(n) if ids is None else _numeric(ids, "ids", None)
        if ids.shape != (n,) or ids.dtype.kind not in "iu":
            raise GraphError(f"ids must be {n} integers; got shape {ids.shape}, dtype {ids.dtype}")

        self._poses = _frozen(poses, float)
        self._ids = _frozen(ids, np.int64)
        self._edges = _frozen(edges, np.int64)
        self._measurements = _frozen(measurements, float)
        # only the symmetric part of an information matrix counts in e^T Omega e; storing it
        # exactly symmetric (bit-identical for symmetric input) lets writers store one triangle
        self._information = _frozen(0.5 * (information + np.swapaxes(information, 1, 2)), float)
        self._cache = {}
        self._validate(information)

    # ------------------------------------------------------------------ validation
    def _edge_name(self, k):
        i, j = self._edges[k]
        if 0 <= i < self.n and 0 <= j < self.n:
            return f"edge {k} (vertex ids {self._ids[i]} -> {self._ids[j]})"
        return f"edge {k} (indices {i} -> {j})"

    def _check_poses_finite(self):
        bad = np.flatnonzero(~np.all(np.isfinite(self._poses), axis=1))
        if bad.size:
            raise GraphError(
                f"pose of vertex id {self._ids[bad[0]]} (index {bad[0]}) is not finite: "
                f"{self._poses[bad[0]].tolist()}; give every vertex finite (x, y, theta)"
            )

    def _validate(self, information):
        n, m = self.n, self.m
        self._check_poses_finite()
        uniq, counts = np.unique(self._ids, return_counts=True)
        if np.any(counts > 1):
            raise GraphError(
                f"vertex id {uniq[counts > 1][0]} appears more than once; ids must be unique"
            )
        out = np.flatnonzero(np.any((self._edges < 0) | (self._edges >= n), axis=1))
        if out.size:
            k = out[0]
            raise GraphError(
                f"edge {k} refers to vertex index {self._edges[k].tolist()} but the graph has "
                f"{n} vertices (valid indices 0..{n - 1})",
                edge=int(k),
            )
        loops = np.flatnonzero(self._edges[:, 0] == self._edges[:, 1])
        if loops.size:
            k = loops[0]
            raise GraphError(
                f"{self._edge_name(k)} is a self-loop; a relative measurement needs two distinct "
                "vertices — remove it",
                edge=int(k),
            )
        bad = np.flatnonzero(~np.all(np.isfinite(self._measurements), axis=1))
        if bad.size:
            k = bad[0]
            raise GraphError(
                f"{self._edge_name(k)} has a non-finite measurement {self._measurements[k].tolist()}",
                edge=int(k),
            )
        if m:
            k = first_bad_information(information)
            if k is not None:
                raise GraphError(
                    f"{self._edge_name(k)}: {describe_bad_information(information[k])}",
                    edge=int(k),
                )

    # ------------------------------------------------------------------ arrays
    @property
    def poses(self):
        """ndarray, shape (n, 3): the vertex poses ``(x, y, theta)`` (read-only)."""
        return self._poses

    @property
    def ids(self):
        """ndarray of int64, shape (n,): original vertex ids (read-only)."""
        return self._ids

    @property
    def edges(self):
        """ndarray of int64, shape (m, 2): index pairs ``(i, j)`` (read-only)."""
        return self._edges

    @property
    def measurements(self):
        """ndarray, shape (m, 3): relative pose of ``j`` in the frame of ``i`` (read-only)."""
        return self._measurements

    @property
    def information(self):
        """ndarray, shape (m, 3, 3): information matrices, g2o convention (read-only)."""
        return self._information

    @property
    def n(self):
        """Number of vertices."""
        return self._poses.shape[0]

    @property
    def m(self):
        """Number of edges (measurements)."""
        return self._edges.shape[0]

    def __repr__(self):
        return (
            f"PoseGraph(n={self.n}, m={self.m}, odometric={int(self.odometric.sum())}, "
            f"loop_closures={int(self.loop_closure.sum())})"
        )

    # ------------------------------------------------------------------ structure
    @property
    def order(self):
        """ndarray, shape (n,): the rank of each vertex when vertices are sorted by id."""
        if "order" not in self._cache:
            rank = np.empty(self.n, dtype=np.int64)
            rank[np.argsort(self._ids, kind="stable")] = np.arange(self.n)
            rank.setflags(write=False)
            self._cache["order"] = rank
        return self._cache["order"]

    @property
    def odometric(self):
        """ndarray of bool, shape (m,): edges ``(i, j)`` where ``j`` directly follows ``i`` in id order.

        These are the odometric constraints of Carlone et al. 2011, §III (measurements between
        poses at subsequent instants of time).
        """
        if "odometric" not in self._cache:
            r = self.order
            mask = r[self._edges[:, 1]] == r[self._edges[:, 0]] + 1
            mask.setflags(write=False)
            self._cache["odometric"] = mask
        return self._cache["odometric"]

    @property
    def loop_closure(self):
        """ndarray of bool, shape (m,): every edge that is not odometric."""
        return ~self.odometric

    def components(self):
        """Weakly connected components.

        Returns
        -------
        count : int
            Number of components.
        labels : ndarray of int, shape (n,)
            Component label of each vertex (0 for the component holding vertex index 0).
        """
        if "components" not in self._cache:
            n = self.n
            A = coo_matrix(
                (np.ones(self.m), (self._edges[:, 0], self._edges[:, 1])), shape=(n, n)
            ).tocsr()
            count, labels = connected_components(A, directed=True, connection="weak")
            labels.setflags(write=False)
            self._cache["components"] = (int(count), labels)
        return self._cache["components"]

    @property
    def is_connected(self):
        """True when every vertex is reachable from every other along edges (in any direction)."""
        return self.components()[0] <= 1

    # ------------------------------------------------------------------ poses
    def with_poses(self, poses):
        """A new graph with the same edges and other poses (shape (n, 3))."""
        poses = _numeric(poses, "poses", float)
        if poses.shape != (self.n, 3):
            raise GraphError(f"poses must have shape ({self.n}, 3); got {poses.shape}")
        new = object.__new__(PoseGraph)
        new._poses = _frozen(poses, float)
        new._ids, new._edges = self._ids, self._edges
        new._measurements, new._information = self._measurements, self._information
        new._cache = self._cache  # structure only: nothing cached depends on the poses
        new._check_poses_finite()
        return new

    def odometric_chain(self):
        """For each consecutive pair of vertices in id order, the edge that measures it.

        Returns
        -------
        edge : ndarray of int, shape (n - 1,)
            ``edge[k]`` is the index of an edge between the ``k``-th and ``(k+1)``-th vertex in id
            order: the first edge stored forward (``i -> i+1``), else the first stored backward
            (``i+1 -> i``, as in GTSAM's ``.graph`` files).
        forward : ndarray of bool, shape (n - 1,)
            Whether that edge is stored forward.

        Raises
        ------
        GraphError
            If some consecutive pair has no edge; the message names the first gap.
        """
        n, r, e = self.n, self.order, self._edges
        edge = np.full(max(n - 1, 0), -1, dtype=np.int64)
        forward = np.zeros(max(n - 1, 0), dtype=bool)
        # backward-stored first, so that forward edges overwrite them; np.unique's return_index
        # picks the first stored edge of each pair
        backward = np.flatnonzero(r[e[:, 0]] == r[e[:, 1]] + 1)
        slot, first = np.unique(r[e[backward, 1]], return_index=True)
        edge[slot] = backward[first]
        fwd = np.flatnonzero(self.odometric)
        slot, first = np.unique(r[e[fwd, 0]], return_index=True)
        edge[slot] = fwd[first]
        forward[slot] = True
        gaps = np.flatnonzero(edge < 0)
        if gaps.size:
            by_rank = np.argsort(self._ids, kind="stable")
            a, b = self._ids[by_rank[gaps[0]]], self._ids[by_rank[gaps[0] + 1]]
            raise GraphError(
                f"the odometric chain is broken: no edge between vertex ids {a} and {b} "
                f"({gaps.size} gap(s) in all); the odometry guess needs an edge between every "
                "pair of consecutive ids"
            )
        return edge, forward

    def odometry_guess(self, start=None):
        """Poses obtained by composing the odometric measurements along the chain of ids.

        ``x_0 = start`` and ``x_{k+1} = x_k ⊕ z_{k,k+1}`` (a backward-stored edge contributes
        ``⊖z``).  The composition is written as cumulative sums — ``theta_k`` is the running sum of
        the odometric angles, and ``rho_{k+1} = rho_k + R(theta_k) dt_k`` — so it is vectorized.

        Parameters
        ----------
        start : array_like, shape (3,), optional
            Pose of the first vertex in id order; default: its current pose in the graph.

        Returns
        -------
        ndarray, shape (n, 3)
            Poses in row order of the graph, angles wrapped to ``(-pi, pi]``.

        Raises
        ------
        GraphError
            If the odometric chain has a gap (the message names it).
        """
        edge, forward = self.odometric_chain()
        by_rank = np.argsort(self._ids, kind="stable")
        x0 = self._poses[by_rank[0]] if start is None else np.asarray(start, dtype=float)
        z = self._measurements[edge]
        z = np.where(forward[:, None], z, se2.inverse(z))
        theta = x0[2] + np.concatenate([[0.0], np.cumsum(z[:, 2])])
        dt = np.einsum("kab,kb->ka", se2.rotation(theta[:-1]), z[:, :2])
        rho = x0[:2] + np.concatenate([np.zeros((1, 2)), np.cumsum(dt, axis=0)])
        out = np.empty((self.n, 3))
        out[by_rank, :2] = rho
        out[by_rank, 2] = se2.wrap_angle(theta)
        return out


def first_bad_information(information, rtol=1e-9):
    """Index of the first information matrix that is not symmetric positive definite, or None.

    Parameters
    ----------
    information : ndarray, shape (m, 3, 3)
    rtol : float
        Asymmetry tolerance relative to the largest entry of each matrix.
    """
    info = np.asarray(information, dtype=float)
    scale = np.max(np.abs(info), axis=(1, 2))
    asym = np.max(np.abs(info - np.swapaxes(info, 1, 2)), axis=(1, 2))
    bad = asym > rtol * scale
    with np.errstate(invalid="ignore"):
        eig_min = np.linalg.eigvalsh(0.5 * (info + np.swapaxes(info, 1, 2)))[:, 0]
    bad |= ~(eig_min > 0)
    idx = np.flatnonzero(bad)
    return int(idx[0]) if idx.size else None


def describe_bad_information(info):
    """One sentence saying why a 3x3 information matrix is rejected, and what to do."""
    info = np.asarray(info, dtype=float)
    if not np.all(np.isfinite(info)):
        return f"information matrix has non-finite entries {info.tolist()}"
    if not np.allclose(info, info.T, rtol=1e-9, atol=0):
        return f"information matrix is not symmetric: {info.tolist()}"
    eig = np.linalg.eigvalsh(info)
    return (
        f"information matrix is not positive definite (eigenvalues {eig.tolist()}): "
        f"{info.tolist()}; every measurement needs a positive-definite information matrix "
        "(check the file's field order: TORO and g2o differ)"
    )


def _edge_arrays(graph, poses):
    if poses is None:
        poses = graph.poses
    else:
        poses = _numeric(poses, "poses", float)
        if poses.shape != (graph.n, 3):
            raise GraphError(f"poses must have shape ({graph.n}, 3); got {poses.shape}")
    return poses[graph.edges[:, 0]], poses[graph.edges[:, 1]]


ERRORS = ("t2v", "log")


def _check_error(error):
    if error not in ERRORS:
        raise GraphError(f"error must be one of {ERRORS}; got {error!r}")


def residuals(graph, poses=None, *, error="t2v"):
    """Residual of every edge, ``e_ij = t2v(Z_ij^-1 (X_i^-1 X_j))`` (lecture notes, "The Error Function").

    Written out (rotations R_i = R(theta_i), R_z = R(theta_z))::

        e_ij = [ R_z^T (R_i^T (t_j - t_i) - t_z) ;  wrap(theta_j - theta_i - theta_z) ]

    Parameters
    ----------
    graph : PoseGraph
    poses : array_like, shape (n, 3), optional
        Where to evaluate; default ``graph.poses``.
    error : {"t2v", "log"}
        ``"t2v"`` (default) is the lecture notes' and g2o's error above.  ``"log"`` is GTSAM's:
        ``log(Z_ij^-1 X_i^-1 X_j)`` with the SE(2) logarithm :func:`lagolib.se2.log` in place of
        ``t2v`` (same angle, translation rotated into the twist's coordinates).

    Returns
    -------
    ndarray, shape (m, 3)
    """
    p_i, p_j = _edge_arrays(graph, poses)
    return edge_errors(p_i, p_j, graph.measurements, error=error)


def edge_errors(p_i, p_j, z, *, error="t2v"):
    """``e_ij`` of measurements ``z`` between poses ``p_i`` and ``p_j`` — see :func:`residuals`.

    The one place lagolib evaluates the error; :func:`residuals` applies it to a graph's edges,
    :func:`lagolib.gauss_newton.edge_jacobians` differentiates it.

    Parameters
    ----------
    p_i, p_j, z : array_like, shape (..., 3)
        Broadcast against each other.
    error : {"t2v", "log"}

    Returns
    -------
    ndarray, shape (..., 3)
    """
    _check_error(error)
    z = se2._as_poses(z, "z")
    rel = se2.between(p_i, p_j)  # X_i^-1 X_j, Carlone et al. 2011 eq. (1)
    d = rel[..., :2] - z[..., :2]
    c, s = np.cos(z[..., 2]), np.sin(z[..., 2])
    e = np.stack(
        [
            c * d[..., 0] + s * d[..., 1],
            -s * d[..., 0] + c * d[..., 1],
            se2.wrap_angle(rel[..., 2] - z[..., 2]),
        ],
        axis=-1,
    )
    return se2.log(e) if error == "log" else e


def chi2(graph, poses=None, *, per_edge=False, error="t2v"):
    """g2o's chi²: ``sum_ij e_ij^T Omega_ij e_ij`` (lecture notes' objective; no factor ½).

    GTSAM's ``NonlinearFactorGraph.error`` is half of this number computed with
    ``error="log"``: GTSAM measures residuals with the SE(2) logarithm instead of ``t2v``.  The
    two definitions give different numbers and different optima (on M3500: 137.91295 and
    137.91488, 1.4e-5 apart relatively).

    Parameters
    ----------
    graph : PoseGraph
    poses : array_like, shape (n, 3), optional
        Where to evaluate; default ``graph.poses``.
    per_edge : bool
        Return the ``(m,)`` vector of edge terms instead of their sum.
    error : {"t2v", "log"}
        Residual definition, see :func:`residuals`.

    Returns
    -------
    float, or ndarray of shape (m,) when ``per_edge``
    """
    e = residuals(graph, poses, error=error)
    terms = np.einsum("ka,kab,kb->k", e, graph.information, e)
    return terms if per_edge else float(terms.sum())


def vertex_rows(graph, vertices, what="vertex"):
    """Row indices (into ``graph.poses``) of vertex ids.

    Parameters
    ----------
    graph : PoseGraph
    vertices : int or sequence of int
        Vertex ids, as in the file the graph came from.
    what : str
        Who is asking; it starts the error message.

    Returns
    -------
    ndarray of int, shape (k,)

    Raises
    ------
    GraphError
        For an id that is not an integer or not in the graph (the message names it).
    """
    ids = np.asarray(graph.ids)
    vertices = np.atleast_1d(np.asarray(vertices, dtype=object))
    out = []
    if vertices.size == 0:
        return np.zeros(0, dtype=np.int64)
    sorter = np.argsort(ids, kind="stable")
    for v in vertices:
        if isinstance(v, bool | np.bool_) or not isinstance(v, int | np.integer):
            raise GraphError(f"{what}: vertex ids are integers; got {v!r}")
        k = np.searchsorted(ids, v, sorter=sorter)
        if k >= len(ids) or ids[sorter[k]] != v:
            raise GraphError(
                f"{what}: vertex id {v} is not in the graph (ids run from {ids.min()} to "
                f"{ids.max()})"
            )
        out.append(sorter[k])
    return np.asarray(out, dtype=np.int64)
