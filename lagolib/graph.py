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

import numbers
import reprlib
from decimal import Decimal

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from . import se2
from .checks import check_bool, check_choice, check_int, check_real
from .errors import GraphError, GraphTypeError, OptionError, OptionTypeError

__all__ = [
    "as_graph_poses",
    "check_graph",
    "PoseGraph",
    "residuals",
    "chi2",
    "vertex_rows",
    "vertex_row",
    "vertex_ids",
    "check_poses",
    "first_bad_information",
    "describe_bad_information",
    "MAX_INFORMATION",
    "MIN_INFORMATION",
    "MAX_INFORMATION_CONDITION",
]

# Limits on an information matrix Omega (eigenvalues lambda_min <= lambda_max), chosen so that
# chi² terms and the Hessian blocks built from it stay well inside float64.  An eigenvalue of
# 1e100 is a standard deviation of 1e-50 in the file's units, 1e-100 one of 1e50: no sensor is
# that precise or that vague, and beyond these bounds products such as the determinant or
# Omega * e * e overflow to inf or underflow to zero (float64 spans 2.2e-308 .. 1.8e308).
MAX_INFORMATION = 1e100
"""Largest eigenvalue an information matrix may have."""
MIN_INFORMATION = 1e-100
"""Smallest eigenvalue an information matrix may have."""
MAX_INFORMATION_CONDITION = 1e14
"""Largest condition number ``lambda_max / lambda_min`` of an information matrix.

eigvalsh computes ``lambda_min`` to about ``1e-15 * lambda_max``, so beyond ``1e14`` the sign and
size of the smallest eigenvalue are rounding noise: the matrix is numerically singular.  (The most
anisotropic matrix in the public benchmarks, in Carlone's INTEL, has 2.4e11.)
"""


_INT64 = np.iinfo(np.int64)
_ANGLE_BOUND = f"{se2.MAX_ANGLE:.0e}".replace("e+0", "e").replace("e+", "e")  # "1e9"


def _numeric(value, name, dtype):
    """``np.asarray(value, dtype)`` for arrays of real numbers, naming ``name`` when it fails.

    Complex, text, bool, date and other non-numeric arrays raise
    :class:`~lagolib.errors.GraphTypeError` (a TypeError) instead of being converted — numpy would
    drop an imaginary part with only a warning, or parse text; ragged nested lists raise
    :class:`~lagolib.errors.GraphError`.  With ``dtype=None`` an object array of Python integers
    (e.g. ids beyond 64 bits) is returned as is, for the caller to range-check.
    """
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise GraphError(f"{name} must be a numeric array: {exc}") from None
    kind = a.dtype.kind
    if kind == "O":
        flat = a.ravel().tolist()
        for x in flat:
            if isinstance(x, bool | np.bool_) or not isinstance(x, numbers.Real | Decimal):
                raise GraphTypeError(
                    f"{name} must be an array of real numbers; it holds {x!r} ({type(x).__name__})"
                )
        if dtype is None and all(isinstance(x, numbers.Integral) for x in flat):
            return a
        try:
            return a.astype(float if dtype is None else dtype)
        except (TypeError, ValueError, OverflowError) as exc:
            raise GraphTypeError(f"{name} must be an array of real numbers: {exc}") from None
    if kind not in "iuf":
        what = {"c": "complex", "U": "text", "S": "text", "b": "bool"}.get(kind, "non-numeric")
        raise GraphTypeError(
            f"{name} must be a numeric array of real numbers; got a {what} array (dtype {a.dtype})"
        )
    return a if dtype is None else a.astype(dtype, copy=False)


def _frozen(a, dtype):
    a = np.array(a, dtype=dtype, copy=True)
    a.setflags(write=False)
    return a


class PoseGraph:
    """An immutable planar pose graph (lecture notes, "The Graph", "Pose Graph" and "The Edge
    Information matrices").

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
        part ``(Omega + Omega^T) / 2`` is stored.  Eigenvalues must lie in
        [:data:`MIN_INFORMATION`, :data:`MAX_INFORMATION`] = [1e-100, 1e100] and the condition
        number must be at most :data:`MAX_INFORMATION_CONDITION` = 1e14, so that nothing computed
        from them overflows, underflows or is rounding noise.
    ids : array_like of int, shape (n,), optional
        Original vertex ids (default ``0 .. n-1``), in the int64 range.  Must be unique; they
        need not equal the row index, and they define the *odometric order* of the vertices.

    Raises
    ------
    GraphError
        For wrong shapes, non-finite numbers, angles beyond ``|theta| <= 1e9``
        (:data:`lagolib.se2.MAX_ANGLE`), indices out of range, self-loops, duplicate ids, ids
        outside int64, or an information matrix lagolib cannot use
        (:func:`first_bad_information`).  The message names the offending edge (index and
        vertex ids) or vertex (id and index); ``GraphError.edge`` / ``GraphError.vertex`` hold
        the index.
    GraphTypeError
        For complex, text, bool or other non-numeric arrays (a TypeError and a GraphError).

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
        edges = _edge_indices(edges, n)
        m = edges.shape[0]
        measurements = _numeric(measurements, "measurements", float)
        information = _numeric(information, "information", float)
        if m == 0 and measurements.size == 0 and information.size == 0:
            measurements, information = np.zeros((0, 3)), np.zeros((0, 3, 3))
        if measurements.shape != (m, 3):
            raise GraphError(f"measurements must have shape ({m}, 3); got {measurements.shape}")
        if information.shape != (m, 3, 3):
            raise GraphError(f"information must have shape ({m}, 3, 3); got {information.shape}")
        ids = np.arange(n) if ids is None else vertex_ids(ids, n)

        self._poses = _frozen(poses, float)
        self._ids = _frozen(ids, np.int64)
        self._edges = _frozen(edges, np.int64)
        self._measurements = _frozen(measurements, float)
        self._cache = {}
        self._validate(information)
        # only the symmetric part of an information matrix counts in e^T Omega e; storing it
        # exactly symmetric (bit-identical for symmetric input) lets writers store one triangle.
        # The full check runs on this matrix: it is what a reader of a written file will check.
        with np.errstate(over="ignore", invalid="ignore"):
            sym = 0.5 * (information + np.swapaxes(information, 1, 2))
        self._check_information(sym, shown=information)
        self._information = _frozen(sym, float)

    # ------------------------------------------------------------------ validation
    def _edge_name(self, k):
        i, j = self._edges[k]
        if 0 <= i < self.n and 0 <= j < self.n:
            return f"edge {k} (vertex ids {self._ids[i]} -> {self._ids[j]})"
        return f"edge {k} (indices {i} -> {j})"

    def _check_poses(self):
        check_poses(self._poses, self._ids)

    def _validate(self, information):
        n = self.n
        self._check_poses()
        twice = first_duplicate(self._ids)
        if twice is not None:
            a, b = twice
            raise GraphError(
                f"vertex id {self._ids[a]} appears more than once (indices {a} and {b}); ids "
                "must be unique",
                vertex=b,
            )
        _check_edge_range(self._edges, n)
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
        big = np.flatnonzero(np.abs(self._measurements[:, 2]) > se2.MAX_ANGLE)
        if big.size:
            k = big[0]
            raise GraphError(
                f"{self._edge_name(k)} has the measured angle {float(self._measurements[k, 2])!r} "
                f"rad; |dtheta| must be <= {_ANGLE_BOUND} (float64 cannot reduce larger angles "
                "consistently, see lagolib.se2): wrap it to (-pi, pi]",
                edge=int(k),
            )
        self._check_symmetric(information)

    def _check_symmetric(self, information, rtol=1e-9):
        """GraphError for the first matrix whose asymmetry exceeds ``rtol`` times its largest entry.

        Elementwise only (no eigenvalues); non-finite matrices are left to
        :meth:`_check_information`.
        """
        with np.errstate(over="ignore", invalid="ignore"):
            scale = np.max(np.abs(information), axis=(1, 2), initial=0.0)
            asym = np.max(
                np.abs(information - np.swapaxes(information, 1, 2)), axis=(1, 2), initial=0.0
            )
            bad = np.flatnonzero(asym > rtol * scale)
        if bad.size:
            k = int(bad[0])
            raise GraphError(
                f"{self._edge_name(k)}: {describe_bad_information(information[k])}", edge=k
            )

    def _check_information(self, information, shown=None):
        """GraphError for the first matrix lagolib cannot use (:func:`first_bad_information`);
        the message describes ``shown[k]`` (the matrix as given) when that is passed."""
        k = first_bad_information(information) if self.m else None
        if k is not None:
            bad = information[k]
            if shown is not None and first_bad_information(shown[k : k + 1]) is not None:
                bad = shown[k]  # the matrix as given is itself unusable: describe that one
            raise GraphError(f"{self._edge_name(k)}: {describe_bad_information(bad)}", edge=int(k))

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
    def _structural(self, key, compute):
        """``compute()``, once per graph structure: kept in the cache this graph shares with
        every ``with_poses`` copy, so only what depends on the edges alone (not the poses,
        measurements or information) may be kept here — e.g. an elimination ordering, which
        LAGO, Gauss–Newton and the certificate of one graph then compute once."""
        if key not in self._cache:
            self._cache[key] = compute()
        return self._cache[key]

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
        """A new graph with the same edges and other poses (shape (n, 3)).

        The poses are checked as in the constructor: finite, ``|theta| <= 1e9``, real (a
        GraphError or GraphTypeError names the vertex).
        """
        poses = _numeric(poses, "with_poses: poses", float)
        if poses.shape != (self.n, 3):
            raise GraphError(f"with_poses: poses must have shape ({self.n}, 3); got {poses.shape}")
        new = object.__new__(PoseGraph)
        new._poses = _frozen(poses, float)
        new._ids, new._edges = self._ids, self._edges
        new._measurements, new._information = self._measurements, self._information
        new._cache = self._cache  # structure only: nothing cached depends on the poses
        new._check_poses()
        return new

    def _scaled_translations(self, k):
        """This graph with every position and measured translation times ``2**-k`` (exact: a
        power of two), for algorithms whose translation updates are linear in the translations
        (:func:`lagolib.sgd.sgd`) to run far from float64's limits.  Nothing is re-checked."""
        new = object.__new__(PoseGraph)
        poses, z = self._poses.copy(), self._measurements.copy()
        poses[:, :2] = np.ldexp(poses[:, :2], -k)
        z[:, :2] = np.ldexp(z[:, :2], -k)
        new._poses, new._measurements = _frozen(poses, float), _frozen(z, float)
        new._ids, new._edges, new._information = self._ids, self._edges, self._information
        new._cache = self._cache  # structure only
        return new

    def with_information(self, information):
        """A new graph with the same poses, edges and measurements and other information.

        Parameters
        ----------
        information : array_like, shape (3, 3) or (m, 3, 3)
            One matrix for every edge, or one per edge; g2o frame, checked as in the
            constructor (symmetric positive definite: a GraphError names the edge).

        Returns
        -------
        PoseGraph

        Examples
        --------
        >>> import numpy as np
        >>> g = PoseGraph(np.zeros((2, 3)), [[0, 1]], [[1.0, 0.0, 0.0]], [np.eye(3)])
        >>> np.diag(g.with_information(np.diag([1.0, 2.0, 3.0])).information[0]).tolist()
        [1.0, 2.0, 3.0]
        """
        info = _numeric(information, "with_information: information", float)
        if info.shape == (3, 3):
            info = np.broadcast_to(info, (self.m, 3, 3))
        return PoseGraph(self.poses, self.edges, self.measurements, info, ids=self.ids)

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
            If the odometric chain has a gap (the message names it), ``start`` is not one finite
            pose, or composing the measurements overflows float64 (the message names the vertex).
        """
        if start is not None:
            start = _numeric(start, "odometry_guess: start", float)
            if start.shape != (3,):
                raise GraphError(
                    f"odometry_guess: start must be one pose (x, y, theta); got shape {start.shape}"
                )
            check_poses(start[None], None, "odometry_guess: start pose")
        if self.n == 0:
            return np.zeros((0, 3))
        edge, forward = self.odometric_chain()
        by_rank = np.argsort(self._ids, kind="stable")
        x0 = self._poses[by_rank[0]] if start is None else start
        z = self._measurements[edge]
        z = np.where(forward[:, None], z, se2.inverse(z))
        with np.errstate(over="ignore", invalid="ignore"):  # overflow is reported below
            theta = x0[2] + np.concatenate([[0.0], np.cumsum(z[:, 2])])
            ok = np.abs(theta[:-1]) <= se2.MAX_ANGLE  # larger angles are refused below
            dt = np.einsum("kab,kb->ka", se2.rotation(np.where(ok, theta[:-1], 0.0)), z[:, :2])
            rho = x0[:2] + np.concatenate([np.zeros((1, 2)), np.cumsum(dt, axis=0)])
        out = np.empty((self.n, 3))
        out[by_rank, :2] = rho
        out[by_rank, 2] = se2.wrap_angle(np.where(np.abs(theta) <= se2.MAX_ANGLE, theta, 0.0))
        bad = np.flatnonzero(~(np.all(np.isfinite(rho), axis=1) & (np.abs(theta) <= se2.MAX_ANGLE)))
        if bad.size:  # measurements too large to compose (O(n), vectorized)
            k = int(by_rank[bad[0]])
            raise GraphError(
                f"odometry_guess: composing the odometry overflows at vertex id {self._ids[k]} "
                f"(index {k}): position {rho[bad[0]].tolist()}, summed angle {theta[bad[0]]!r} "
                f"rad (float64 holds positions up to 1.8e308, lagolib angles up to {_ANGLE_BOUND}); "
                "the odometric measurements are too large to compose",
                vertex=k,
            )
        return out


def _shown(value, limit=60):
    """``value`` for a message: a short repr and its type."""
    r = reprlib.Repr()
    r.maxstring = r.maxother = limit
    return f"{r.repr(value)} ({type(value).__name__})"


def check_graph(graph, where):
    """``graph`` if it is a :class:`PoseGraph`; else :class:`~lagolib.errors.OptionTypeError`.

    The one check every public function taking a ``graph`` runs first, so that anything else —
    a file name, an array of poses, a simulation or a result that *holds* a graph — is reported
    by the function that was called, with what to pass instead, not as an AttributeError from
    deep inside it.

    Parameters
    ----------
    graph : object
    where : str
        The function's name, which starts the message.

    Returns
    -------
    PoseGraph

    Raises
    ------
    OptionTypeError
        ``{where}: graph must be a lagolib.PoseGraph; got ...`` (a TypeError).

    Examples
    --------
    >>> try:
    ...     check_graph("intel.g2o", "chi2")
    ... except TypeError as exc:
    ...     print(exc)
    chi2: graph must be a lagolib.PoseGraph; got 'intel.g2o' (str): read it first with lagolib.read
    """
    if isinstance(graph, PoseGraph):
        return graph
    try:
        path = isinstance(graph, str | bytes) or hasattr(graph, "__fspath__")
        held = isinstance(getattr(graph, "graph", None), PoseGraph)
    except Exception:  # an object whose attributes raise: no hint from it
        path = held = False
    if path:
        hint = "read it first with lagolib.read"
    elif held:
        hint = f"pass its .graph (a {type(graph).__name__} holds the PoseGraph in .graph)"
    else:
        hint = "read a file with lagolib.read or build one with lagolib.PoseGraph"
    raise OptionTypeError(
        f"{where}: graph must be a lagolib.PoseGraph; got {_shown(graph)}: {hint}"
    )


_INFO_OK, _NON_FINITE, _ASYMMETRIC, _NOT_PD, _OVERFLOW, _UNDERFLOW, _SINGULAR = range(7)


#: Matrices per chunk in :func:`_information_check` (its temporaries stay a few MB at 10^6 edges).
_CHECK_CHUNK = 2**16


def _information_check(information, rtol=1e-9):
    """Classify each 3x3 information matrix; the eigenvalues are computed without overflow.

    Chunks of :data:`_CHECK_CHUNK` matrices at a time (:func:`_information_check_chunk`).
    """
    info = np.asarray(information, dtype=float)
    if len(info) <= _CHECK_CHUNK:
        return _information_check_chunk(info, rtol)
    parts = [
        _information_check_chunk(info[k : k + _CHECK_CHUNK], rtol)
        for k in range(0, len(info), _CHECK_CHUNK)
    ]
    return tuple(np.concatenate(p) for p in zip(*parts))


def _information_check_chunk(information, rtol=1e-9):
    """Classify each 3x3 information matrix; the eigenvalues are computed without overflow.

    Returns
    -------
    code : ndarray of int, shape (m,)
        ``_INFO_OK`` or the first defect: non-finite entries, asymmetry above ``rtol`` times the
        largest entry, not positive definite, largest eigenvalue above :data:`MAX_INFORMATION`,
        smallest below :data:`MIN_INFORMATION`, condition number above
        :data:`MAX_INFORMATION_CONDITION`.
    eig : ndarray, shape (m, 3)
        Eigenvalues of the symmetric part divided by ``scale`` (ascending).
    scale : ndarray, shape (m,)
        Largest absolute entry of each matrix (0 for non-finite ones).
    """
    info = np.asarray(information, dtype=float)
    finite = np.all(np.isfinite(info), axis=(1, 2))
    safe = np.where(finite[:, None, None], info, 0.0)
    scale = np.max(np.abs(safe), axis=(1, 2), initial=0.0)
    unit = np.where(scale > 0, scale, 1.0)[:, None, None]
    with np.errstate(all="ignore"):
        scaled = safe / unit  # entries in [-1, 1]: nothing below can overflow
        asym = np.max(np.abs(scaled - np.swapaxes(scaled, 1, 2)), axis=(1, 2), initial=0.0)
        eig = np.linalg.eigvalsh(0.5 * (scaled + np.swapaxes(scaled, 1, 2)))
        lo, hi = eig[:, 0], eig[:, -1]
        code = np.full(len(info), _INFO_OK)
        # assigned from the least to the most basic defect, so the most basic one wins
        code[lo < hi / MAX_INFORMATION_CONDITION] = _SINGULAR
        code[lo < MIN_INFORMATION / unit[:, 0, 0]] = _UNDERFLOW
        code[hi > MAX_INFORMATION / unit[:, 0, 0]] = _OVERFLOW
        code[~(lo > 0)] = _NOT_PD
        code[asym > rtol] = _ASYMMETRIC
        code[~finite] = _NON_FINITE
    return code, eig, scale


def first_bad_information(information, rtol=1e-9):
    """Index of the first information matrix lagolib cannot use, or None.

    A usable matrix is finite, symmetric (up to ``rtol`` times its largest entry), positive
    definite, has eigenvalues in [:data:`MIN_INFORMATION`, :data:`MAX_INFORMATION`] and a
    condition number of at most :data:`MAX_INFORMATION_CONDITION`;
    :func:`describe_bad_information` says which condition fails.

    Parameters
    ----------
    information : array_like, shape (m, 3, 3)
        A stack of matrices (one matrix: ``information[None]``).
    rtol : float
        Asymmetry tolerance relative to the largest entry of each matrix.

    Raises
    ------
    OptionError
        ``information`` is not of shape (m, 3, 3), or ``rtol`` is not a finite number >= 0.
    GraphTypeError
        ``information`` is complex, text, bool or not numbers.
    """
    where = "first_bad_information"
    information = _information_stack(information, where)
    rtol = check_real(rtol, "rtol", where, minimum=0.0)
    if len(information) == 0:
        return None
    code, _, _ = _information_check(information, rtol)
    idx = np.flatnonzero(code != _INFO_OK)
    return int(idx[0]) if idx.size else None


def _information_stack(information, where):
    """``information`` as a float array of shape (m, 3, 3), or an error naming ``where``."""
    info = _numeric(information, f"{where}: information", float)
    if info.ndim != 3 or info.shape[1:] != (3, 3):
        one = " (for one matrix pass information[None])" if info.shape == (3, 3) else ""
        raise OptionError(
            f"{where}: information must be a stack of 3x3 matrices, shape (m, 3, 3); got shape "
            f"{info.shape}{one}"
        )
    return info


def _times(a, scale):
    """``a * scale`` printed without overflowing (``a`` of order 1)."""
    value = a * scale
    if np.isfinite(value) or a == 0:
        return f"{value:.3g}"
    exp10 = np.log10(abs(a)) + np.log10(scale)
    whole = int(np.floor(exp10))
    return f"{'-' if a < 0 else ''}{10 ** (exp10 - whole):.3g}e+{whole}"


def describe_bad_information(info):
    """One sentence saying why a 3x3 information matrix is rejected, and what to do."""
    info = _numeric(info, "describe_bad_information: info", float)
    if info.shape != (3, 3):
        raise OptionError(
            f"describe_bad_information: info must be one 3x3 matrix; got shape {info.shape}"
        )
    code, eig, scale = _information_check(info[None])
    code, eig, scale = int(code[0]), eig[0], float(scale[0])
    eigs = "[" + ", ".join(_times(e, scale) for e in eig) + "]"
    if code == _NON_FINITE:
        return (
            f"information matrix has non-finite entries {info.tolist()}; every entry must be a "
            "finite number"
        )
    if code == _ASYMMETRIC:
        return (
            f"information matrix is not symmetric: {info.tolist()}; store a symmetric matrix "
            "(an asymmetry below 1e-9 of the largest entry is tolerated as rounding)"
        )
    if code == _NOT_PD:
        return (
            f"information matrix is not positive definite (eigenvalues {eigs}): "
            f"{info.tolist()}; every measurement needs a positive-definite information matrix "
            "(check the file's field order: TORO and g2o differ)"
        )
    if code == _OVERFLOW:
        return (
            f"information matrix overflows float64 arithmetic: its largest eigenvalue "
            f"{_times(eig[-1], scale)} exceeds {MAX_INFORMATION:g} (a standard deviation below "
            f"1e-50), so chi2 terms and the Hessian would overflow; rescale it (are the units "
            f"right?): {info.tolist()}"
        )
    if code == _UNDERFLOW:
        return (
            f"information matrix underflows: its smallest eigenvalue {_times(eig[0], scale)} is "
            f"below {MIN_INFORMATION:g} (a standard deviation above 1e50), so the Hessian would "
            f"underflow to zero; rescale it, or drop the edge if it carries no information: "
            f"{info.tolist()}"
        )
    if code == _SINGULAR:
        return (
            f"information matrix is numerically singular: condition number "
            f"{eig[-1] / eig[0]:.3g} exceeds {MAX_INFORMATION_CONDITION:g} (eigenvalues {eigs}), "
            "so float64 cannot hold its weakest direction next to its strongest; raise the "
            f"smallest eigenvalue to at least 1e-14 of the largest: {info.tolist()}"
        )
    return f"information matrix is valid: {info.tolist()}"


def vertex_ids(ids, n, where="ids"):
    """Vertex ids as an int64 array of shape (n,), refusing what does not fit exactly.

    Parameters
    ----------
    ids : array_like of int, shape (n,)
    n : int
        Number of vertices.
    where : str
        How the message names the argument.

    Raises
    ------
    GraphError
        For a wrong shape, non-integers, or an id outside the int64 range (never wrapped).
    GraphTypeError
        For complex, text or bool ids.
    """
    n = check_int(n, "n", "vertex_ids", minimum=0)
    a = _numeric(ids, where, None)
    if a.dtype.kind == "f" and not isinstance(ids, np.ndarray):
        # numpy turns a list holding an int beyond int64 (e.g. 2**63) into floats: look again
        obj = np.empty(len(ids), dtype=object) if np.ndim(ids) == 1 else None
        if obj is not None:
            obj[:] = list(ids)
            if all(isinstance(v, int) and not isinstance(v, bool) for v in obj):
                a = obj
    if a.shape != (n,) or a.dtype.kind not in "iuO":
        raise GraphError(f"{where} must be {n} integers; got shape {a.shape}, dtype {a.dtype}")
    if a.dtype.kind in "uO" and n:
        out = [k for k, v in enumerate(a.tolist()) if not _INT64.min <= v <= _INT64.max]
        if out:
            raise GraphError(
                f"{where}: vertex id {a.tolist()[out[0]]} (index {out[0]}) is outside the int64 "
                f"range [{_INT64.min}, {_INT64.max}] lagolib stores ids in",
                vertex=out[0],
            )
    return a.astype(np.int64)


def _edge_indices(edges, n):
    """Edge index pairs as int64, checked to be integers in ``0..n-1`` before any cast."""
    kind = edges.dtype.kind
    if kind == "f":
        if not (np.all(np.isfinite(edges)) and np.all(edges == np.round(edges))):
            raise GraphError(f"edges must hold integer vertex indices; got dtype {edges.dtype}")
    elif kind not in "iuO":
        raise GraphError(f"edges must hold integer vertex indices; got dtype {edges.dtype}")
    if kind in "fuO":  # values beyond int64 would wrap in the cast: check the range first
        _check_edge_range(edges, n)
    return edges.astype(np.int64)


def _check_edge_range(edges, n):
    """GraphError naming the first edge whose vertex index is outside ``0..n-1``."""
    out = np.flatnonzero(np.any((edges < 0) | (edges >= n), axis=1))
    if out.size:
        k = out[0]
        raise GraphError(
            f"edge {k} refers to vertex index {edges[k].tolist()} but the graph has "
            f"{n} vertices (valid indices 0..{n - 1})",
            edge=int(k),
        )


def check_poses(poses, ids, what="pose"):
    """Raise a GraphError naming the vertex when a pose is not finite or its angle is absurd.

    Parameters
    ----------
    poses : array_like, shape (n, 3)
    ids : ndarray of int, shape (n,), or None
        Vertex ids, for the message; None for a trajectory without ids (the message names the
        row).
    what : str
        How the message names the poses (e.g. ``"initial pose"``).

    Raises
    ------
    GraphError
        ``{what} of vertex id ... (index ...)`` (or ``{what} row ...``) is not finite, or has
        ``|theta| >`` :data:`lagolib.se2.MAX_ANGLE`; ``GraphError.vertex`` is the row index.
    """

    def name(k):
        return f"{what} row {k}" if ids is None else f"{what} of vertex id {ids[k]} (index {k})"

    if not (isinstance(poses, np.ndarray) and poses.dtype.kind == "f"):
        poses = _numeric(poses, f"{what}s", float)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise GraphError(f"{what}s must have shape (k, 3); got {poses.shape}")
    bad = np.flatnonzero(~np.all(np.isfinite(poses), axis=1))
    if bad.size:
        k = int(bad[0])
        raise GraphError(
            f"{name(k)} is not finite: {poses[k].tolist()}; give every vertex finite (x, y, theta)",
            vertex=k,
        )
    big = np.flatnonzero(np.abs(poses[:, 2]) > se2.MAX_ANGLE)
    if big.size:
        k = int(big[0])
        raise GraphError(
            f"{name(k)} has the angle {float(poses[k, 2])!r} rad; "
            f"|theta| must be <= {_ANGLE_BOUND} (float64 cannot reduce larger angles "
            "consistently, see lagolib.se2): wrap it to (-pi, pi]",
            vertex=k,
        )


def first_duplicate(ids):
    """Rows ``(a, b)``, ``a < b``, of the first id that appears twice (by id order), or None."""
    ids = np.asarray(ids)
    order = np.argsort(ids, kind="stable")
    same = np.flatnonzero(ids[order[1:]] == ids[order[:-1]])
    if not same.size:
        return None
    a, b = sorted(order[[same[0], same[0] + 1]].tolist())
    return a, b


def as_graph_poses(graph, poses, name="poses", what="pose"):
    """``poses`` for ``graph`` as a finite (n, 3) float array (a copy), checked vertex by vertex.

    Parameters
    ----------
    graph : PoseGraph
    poses : array_like, shape (graph.n, 3), or None
        None stands for ``graph.poses`` (already checked; returned as a copy).
    name : str
        The argument's name, for the messages (e.g. ``"initial"``).
    what : str
        How a message names one pose (e.g. ``"initial guess"``).

    Raises
    ------
    GraphTypeError
        Complex or non-numeric input.
    GraphError
        Wrong shape; a non-finite pose or an absurd angle, naming the vertex id (:func:`check_poses`).
    """
    check_graph(graph, "as_graph_poses")
    if poses is None:
        return graph.poses.copy()
    x = _numeric(poses, name, float)
    if x.shape != (graph.n, 3):
        raise GraphError(f"{name} must have shape ({graph.n}, 3); got {x.shape}")
    check_poses(x, graph.ids, f"{name}: {what}")
    return x.copy()


def _edge_arrays(graph, poses, where):
    """The poses at both ends of every edge, ``(p_i, p_j)``, with ``poses`` checked (finite,
    ``|theta| <= 1e9``, shape (n, 3)) once — O(n), vectorized."""
    check_graph(graph, where)
    if poses is None:
        poses = graph.poses
    else:
        poses = _numeric(poses, f"{where}: poses", float)
        if poses.shape != (graph.n, 3):
            raise GraphError(f"{where}: poses must have shape ({graph.n}, 3); got {poses.shape}")
        check_poses(poses, graph.ids, f"{where}: pose")
    return poses[graph.edges[:, 0]], poses[graph.edges[:, 1]]


ERRORS = ("t2v", "log")


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
        Never NaN: a translation error beyond float64 (poses near ±1e308 on opposite sides) is
        ``±inf`` (see :func:`edge_errors`).
    """
    check_choice(error, "error", "residuals", ERRORS)
    p_i, p_j = _edge_arrays(graph, poses, "residuals")
    return edge_errors(p_i, p_j, graph.measurements, error=error)


def _raw_edge_errors(p_i, p_j, z, error):
    """The formula of :func:`edge_errors`, with nothing guarded."""
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


def _scaled_edge_errors(p_i, p_j, z, error):
    """``(e', k)`` with ``e = diag(2^k, 2^k, 1) e'`` per row, computed without overflow.

    The translation part of the error (``t2v`` and ``log`` alike) is linear and homogeneous in
    the translations ``t_i, t_j, t_z``, and the angle part does not depend on them; dividing the
    three translations of a row by ``2^k > max |t|`` (exact: a power of two) therefore divides
    its translation error by ``2^k`` and leaves the angle error alone, while every intermediate —
    ``t_j - t_i`` above all — stays below 4 in magnitude.  The same scaling as
    :mod:`lagolib.metrics` uses.  Rows of shape (r, 3).
    """
    big = np.max(np.abs(np.concatenate([p_i[:, :2], p_j[:, :2], z[:, :2]], axis=1)), axis=1)
    k = np.frexp(big)[1].astype(np.int64)  # |t| < 2**k (k = 0 for zeros)

    def scaled(p):
        return np.column_stack([np.ldexp(p[:, :2], -k[:, None]), p[:, 2]])

    return _raw_edge_errors(scaled(p_i), scaled(p_j), scaled(z), error), k


def _overflowed_rows(p_i, p_j, z, bad):
    """The rows ``bad`` (a mask over the broadcast leading shape) of the three pose arrays."""
    p_i, p_j, z = np.broadcast_arrays(np.asarray(p_i, float), np.asarray(p_j, float), z)
    return p_i[bad], p_j[bad], z[bad]


def edge_errors(p_i, p_j, z, *, error="t2v"):
    """``e_ij`` of measurements ``z`` between poses ``p_i`` and ``p_j`` — see :func:`residuals`.

    The one place lagolib evaluates the error; :func:`residuals` applies it to a graph's edges,
    :func:`lagolib.gauss_newton.edge_jacobians` differentiates it.

    Poses far apart near the ends of float64 (``t_j - t_i`` beyond 1.8e308) do not give NaN:
    those rows are computed again with their translations scaled by a power of two
    (:func:`_scaled_edge_errors`), so an error component is exact where float64 can hold it and
    ``±inf`` where it cannot.  The check costs one ``isfinite`` over the result.

    Parameters
    ----------
    p_i, p_j, z : array_like, shape (..., 3)
        Broadcast against each other.
    error : {"t2v", "log"}

    Returns
    -------
    ndarray, shape (..., 3)
    """
    check_choice(error, "error", "edge_errors", ERRORS)
    z = se2._as_poses(z, "z")
    with np.errstate(over="ignore", invalid="ignore"):  # overflow is caught and redone below
        e = _raw_edge_errors(p_i, p_j, z, error)
    if not np.isfinite(e).all():  # rare: an intermediate overflowed; redo those rows scaled
        bad = ~np.all(np.isfinite(e), axis=-1)
        es, k = _scaled_edge_errors(*_overflowed_rows(p_i, p_j, z, bad), error)
        with np.errstate(over="ignore"):
            es[:, :2] = np.ldexp(es[:, :2], k[:, None])  # ±inf beyond float64, never NaN
        e[bad] = es
    return e


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
        ``inf`` (never NaN) for a term beyond float64, e.g. poses near ±1e308 joined by an edge.
    """
    per_edge = check_bool(per_edge, "per_edge", "chi2")
    check_choice(error, "error", "chi2", ERRORS)
    terms = _edge_chi2(graph, *_edge_arrays(graph, poses, "chi2"), error)
    return terms if per_edge else float(terms.sum())


def _edge_chi2(graph, p_i, p_j, error):
    """``e_ij^T Omega_ij e_ij`` per edge at endpoint poses ``p_i``, ``p_j`` (unchecked), (m,).

    One ``isfinite`` over the ``m`` terms; a term that is not finite (an overflow: the poses are
    finite) is computed again scaled, ``4^k (v^T Omega v)`` with ``v = (e'_t, 2^-k e_theta)``
    from :func:`_scaled_edge_errors` — ``inf`` when the term is beyond float64, never NaN.
    """
    z = graph.measurements
    with np.errstate(over="ignore", invalid="ignore"):  # overflow is caught and redone below
        e = _raw_edge_errors(p_i, p_j, z, error)
        terms = np.einsum("ka,kab,kb->k", e, graph.information, e)
    if not np.isfinite(terms).all():
        bad = ~np.isfinite(terms)
        terms[bad] = _scaled_edge_chi2(p_i[bad], p_j[bad], z[bad], graph.information[bad], error)
    return terms


def _scaled_edge_chi2(p_i, p_j, z, information, error):
    """``e^T Omega e`` per row computed as ``4^k (v^T Omega v)``, ``v = (e'_t, 2^-k e_theta)``
    (:func:`_scaled_edge_errors`): no intermediate overflows, ``inf`` when the term itself is
    beyond float64.  Rows of shape (r, 3), (r, 3, 3)."""
    es, k = _scaled_edge_errors(p_i, p_j, z, error)
    es[:, 2] = np.ldexp(es[:, 2], -k)
    q = np.maximum(np.einsum("ka,kab,kb->k", es, information, es), 0.0)
    with np.errstate(over="ignore"):
        return np.ldexp(q, 2 * k)


def _by_id(graph):
    """Rows of ``graph`` sorted by vertex id (stable), cached with the graph's structure."""
    if "by_id" not in graph._cache:
        rows = np.argsort(graph.ids, kind="stable")
        rows.setflags(write=False)
        graph._cache["by_id"] = rows
    return graph._cache["by_id"]


def _id_array(vertices, what):
    """Vertex ids as a 1-D object or int64 array, every one an integer (not a bool)."""
    if isinstance(vertices, np.ndarray) and vertices.dtype.kind in "iu":
        a = np.atleast_1d(vertices)
    else:
        if isinstance(vertices, np.ndarray) and vertices.dtype.kind != "O":
            raise GraphTypeError(
                f"{what}: vertex ids are integers; got an array of dtype {vertices.dtype}"
            )
        try:
            a = np.atleast_1d(np.asarray(vertices, dtype=object))
        except (TypeError, ValueError) as exc:
            raise GraphTypeError(
                f"{what}: vertex ids are integers; got {_shown(vertices)}: {exc}"
            ) from None
        if a.ndim == 1:
            for v in a.tolist():
                if isinstance(v, bool | np.bool_) or not isinstance(v, numbers.Integral):
                    raise GraphTypeError(f"{what}: vertex ids are integers; got {_shown(v)}")
    if a.ndim != 1:
        raise GraphTypeError(
            f"{what}: vertex ids must be one id or a flat sequence of ids; got an array of shape "
            f"{a.shape}"
        )
    return a


def vertex_rows(graph, vertices, what="vertex"):
    """Row indices (into ``graph.poses``) of vertex ids.

    Vectorized (one ``searchsorted`` over the ids, sorted once per graph).

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
    GraphTypeError
        For an id that is not an integer (a float, a bool, text, a nested list); a TypeError
        and a GraphError.
    GraphError
        For an id not in the graph (the message names it).
    """
    check_graph(graph, "vertex_rows")
    a = _id_array(vertices, what)
    if a.size == 0:
        return np.zeros(0, dtype=np.int64)
    ids = graph.ids
    if graph.n == 0:
        raise GraphError(
            f"{what}: vertex id {a[0]} is not in the graph (the graph has no vertices)"
        )
    if a.dtype.kind != "i":  # Python ints of any size, or uint64: beyond int64 is never an id
        outside = [v for v in a.tolist() if not _INT64.min <= int(v) <= _INT64.max]
        if outside:
            raise GraphError(
                f"{what}: vertex id {outside[0]} is not in the graph (ids run from {ids.min()} "
                f"to {ids.max()})"
            )
        a = a.astype(np.int64)
    sorter = _by_id(graph)
    k = np.minimum(np.searchsorted(ids, a, sorter=sorter), graph.n - 1)
    rows = sorter[k]
    missing = np.flatnonzero(ids[rows] != a)
    if missing.size:
        raise GraphError(
            f"{what}: vertex id {a[missing[0]]} is not in the graph (ids run from {ids.min()} to "
            f"{ids.max()})"
        )
    return rows.astype(np.int64)


def vertex_row(graph, vertex, what="vertex"):
    """Row index (into ``graph.poses``) of **one** vertex id — an anchor, a fixed pose, an end.

    The one check for arguments that name a single vertex: an integer (a Python or numpy integer,
    or a 0-d integer array), not a bool, a float, text or a sequence.

    Parameters
    ----------
    graph : PoseGraph
    vertex : int
    what : str
        Who is asking and the argument's name, e.g. ``"bfs_tree: anchor"``; it starts the message.

    Returns
    -------
    int

    Raises
    ------
    GraphTypeError
        ``{what}: one vertex id (an integer) is needed; got ...`` (a TypeError and a GraphError).
    GraphError
        For an id not in the graph.

    Examples
    --------
    >>> import numpy as np
    >>> g = PoseGraph(np.zeros((2, 3)), [[0, 1]], [[1.0, 0.0, 0.0]], [np.eye(3)], ids=[7, 3])
    >>> vertex_row(g, 3), vertex_row(g, np.int64(7))
    (1, 0)
    """
    check_graph(graph, "vertex_row")
    v = vertex.item() if isinstance(vertex, np.ndarray) and vertex.ndim == 0 else vertex
    if isinstance(v, bool | np.bool_) or not isinstance(v, numbers.Integral):
        raise GraphTypeError(
            f"{what}: one vertex id (an integer) is needed; got {_shown(vertex)}: a vertex id is "
            "one of the integers in graph.ids"
        )
    return int(vertex_rows(graph, [int(v)], what)[0])
