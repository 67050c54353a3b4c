"""Exceptions and warnings raised by lagolib.

Every problem lagolib detects in its input is reported with one of these classes, and the message
says *where* (``file:line``, or the edge index and the vertex ids) and *what to do*.  They all
derive from :class:`LagolibError`, so ``except lagolib.LagolibError`` catches any of them.  Each
also derives from the builtin a Python user would catch for that kind of problem:

=========================  ===============================================================
lagolib class              builtin base
=========================  ===============================================================
GraphError, ParseError     :class:`ValueError` (bad values in a graph or a file)
GraphTypeError             :class:`TypeError` (and :class:`ValueError`, via GraphError)
OptionError, GaugeError    :class:`ValueError`
OptionTypeError            :class:`TypeError`
DatasetError               :class:`LookupError` (a named dataset that cannot be provided)
NotPositiveDefiniteError   :class:`ArithmeticError`
ConvergenceError           :class:`RuntimeError`
BackendError               :class:`RuntimeError` (a sparse solver failed for another reason)
=========================  ===============================================================
"""

from __future__ import annotations

__all__ = [
    "LagolibError",
    "GraphError",
    "GraphTypeError",
    "ParseError",
    "DatasetError",
    "GaugeError",
    "NotPositiveDefiniteError",
    "BackendWarning",
    "ConditioningWarning",
    "ConvergenceError",
    "BackendError",
    "OptionError",
    "OptionTypeError",
    "LagolibWarning",
    "SkippedLinesWarning",
]


class LagolibError(Exception):
    """Base class of every error lagolib raises on purpose."""


class GraphError(LagolibError, ValueError):
    """A pose graph (or poses given for it) is invalid.

    Attributes
    ----------
    edge : int or None
        Index of the offending edge in the graph's edge arrays, when one edge is to blame.
    vertex : int or None
        Row index of the offending vertex in the graph's pose array, when one vertex is to blame
        (the message names its id).
    """

    def __init__(self, message: str, *, edge: int | None = None, vertex: int | None = None):
        super().__init__(message)
        self.edge = edge
        self.vertex = vertex


class GraphTypeError(GraphError, TypeError):
    """An array given for a pose graph has the wrong type: complex, text, bool or objects.

    Raised instead of converting silently (``np.asarray(z, dtype=float)`` would drop the imaginary
    part of a complex array with only a warning).  It is a :class:`TypeError`, and also a
    :class:`GraphError` so that ``except GraphError`` still catches every problem with a graph.
    """


class ParseError(LagolibError, ValueError):
    """A file could not be read; the message starts with ``path:line:``.

    Attributes
    ----------
    path : str
        The file that was being read.
    line : int or None
        1-based line number of the offending line (None for whole-file problems).
    """

    def __init__(self, path, line: int | None, message: str):
        self.path = str(path)
        self.line = line
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {message}")


class DatasetError(LagolibError, LookupError):
    """A named dataset is unknown, missing from the local mirror, or fails its checksum.

    A :class:`LookupError` (like ``KeyError``): the dataset that was asked for by name cannot be
    provided.
    """


class GaugeError(LagolibError, ValueError):
    """The least-squares system has no unique solution: some poses have no gauge.

    The error of a pose graph depends only on relative poses, so moving a whole connected
    component rigidly changes nothing and ``H`` is singular.  Each component needs one fixed pose
    or a prior (lecture notes, "Role of the Prior" and "Fixing a Subset of Variables").

    Attributes
    ----------
    vertices : list of int
        Vertex ids of the first component without a gauge.
    """

    def __init__(self, message: str, *, vertices=()):
        super().__init__(message)
        self.vertices = list(vertices)


class NotPositiveDefiniteError(LagolibError, ArithmeticError):
    """A matrix that had to be symmetric positive definite is not, numerically.

    Attributes
    ----------
    pivot : int or None
        Row (in the matrix's own ordering) of the first non-positive pivot, when known.
    """

    def __init__(self, message: str, *, pivot: int | None = None):
        super().__init__(message)
        self.pivot = pivot


class ConvergenceError(LagolibError, RuntimeError):
    """An iterative solver stopped before its equations were satisfied; nothing is returned.

    Attributes
    ----------
    iterations : int
        Iterations done.
    residuals : list of float
        The residual norm after each iteration (the first entry is the initial one).
    """

    def __init__(self, message: str, *, iterations: int = 0, residuals=()):
        super().__init__(message)
        self.iterations = iterations
        self.residuals = list(residuals)


class BackendError(LagolibError, RuntimeError):
    """A sparse-solver backend (e.g. MKL PARDISO) failed for a reason other than the matrix.

    Out of memory inside the solver, or an internal error it reports by number; the message
    names the backend, its error code and what to try (usually ``backend="qdldl"``).
    """


class OptionError(LagolibError, ValueError):
    """A function's option (keyword argument) has a value outside its allowed range or set.

    The message names the function, the argument, the value given and what is allowed
    (:mod:`lagolib.checks`).
    """


class OptionTypeError(LagolibError, TypeError):
    """A function's option has the wrong type (e.g. a float where an integer count is needed)."""


class LagolibWarning(UserWarning):
    """Base class of lagolib's warnings."""


class BackendWarning(LagolibWarning):
    """A fast sparse-solver backend's answer failed lagolib's check and was recomputed.

    :class:`lagolib.linalg.SparseCholesky` checks every solve (its backward error); when MKL
    PARDISO's factorization breaks down on a matrix that is positive definite, or its solution stays
    inaccurate after iterative refinement, the system is solved again with qdldl and this warning
    says so (once per factorization object).
    """


class ConditioningWarning(LagolibWarning):
    """A result is limited by float64, not by the method: the matrix it comes from is so
    ill-conditioned that only the leading digits can be trusted; the message says how many."""


class SkippedLinesWarning(LagolibWarning):
    """A reader skipped lines on request (``ignore_unknown=True``); the message says how many."""
