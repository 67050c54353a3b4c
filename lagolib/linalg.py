"""Sparse symmetric positive-definite solves: Cholesky with pluggable backends, selected inversion, PCG.

The lecture notes ("Consequences of the Sparsity") name the two ways to solve ``H dx = -b``:

1. **sparse Cholesky decomposition** — :class:`SparseCholesky` factors ``H = L D L^T`` after a
   fill-reducing ordering and then solves by two triangular substitutions.  Backends:

   ``"qdldl"``
       The QDLDL ``L D L^T`` factorization (OSQP's) with an AMD ordering: simplicial (one column
       at a time), small, always installed, and the one whose factor ``L`` is readable — the
       teaching default and the factor of :func:`selected_inverse`.
   ``"pardiso"``
       Intel MKL PARDISO (``pip install "lagolib[fast]"`` installs MKL from its wheel):
       supernodal, multithreaded, with a nested-dissection (METIS) ordering.  Its symbolic
       analysis — the ordering and the supernode structure — is computed once per sparsity
       pattern and reused by every :meth:`SparseCholesky.refactor`.
   ``"scipy"``
       SuperLU from :mod:`scipy.sparse.linalg` in symmetric mode (minimum degree on ``A + A^T``,
       diagonal pivots).  Always available.

   ``backend="auto"`` takes qdldl for systems below :data:`PARDISO_MIN_SIZE` rows and PARDISO
   above, when it is installed: on the 3 x 10^6-row system of a 10^6-pose graph PARDISO's
   factorization is about 10x faster than qdldl's (``benchmarks/bench_scale.py``).

2. **conjugate gradients** — :func:`pcg`, written out so that a chapter can count its
   iterations, with a Jacobi or 3x3 block-Jacobi preconditioner.

:func:`selected_inverse` computes the entries of ``H^-1`` on the sparsity pattern of ``L`` —
every diagonal block, every marginal covariance — by Takahashi's recurrences, in time comparable
to the factorization.

No function here forms a dense matrix of the system's size.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .checks import check_bool, check_choice, check_int, check_real, real_array
from .errors import BackendError, NotPositiveDefiniteError, OptionError, OptionTypeError

__all__ = [
    "SparseCholesky",
    "available_backends",
    "solve_spd",
    "selected_inverse",
    "SelectedInverse",
    "pcg",
    "PCGResult",
    "PARDISO_MIN_SIZE",
    "fill_reducing_ordering",
    "expand_ordering",
]

BACKENDS = ("qdldl", "pardiso", "scipy")

#: ``backend="auto"`` uses PARDISO (when installed) for systems of at least this many rows, qdldl
#: below.  Measured here (``benchmarks/bench_scale.py``, 2 cores): a refactorization of city10000's
#: 29 997 rows takes about 60 ms with qdldl and 45-140 ms with PARDISO (its two threads suffer
#: most when the machine is busy); at 9 x 10^4 rows qdldl takes 0.8 s and PARDISO 0.1 s.
PARDISO_MIN_SIZE = 50_000

_MKL = {}  # the loaded MKL runtime, found once: {"lib": CDLL or None, "why": str}


def _mkl_runtime():
    """Intel MKL's single dynamic library (``mkl_rt``), or None with the reason in ``_MKL["why"]``.

    Looked for in ``$LAGOLIB_MKL_RT`` (a path), then beside this Python (where the ``mkl`` wheel
    installs it: ``<prefix>/lib/libmkl_rt.so.*``), then on the system's library path.
    ``LAGOLIB_MKL_RT=off`` hides MKL, as on a machine without it (the tests run both ways).
    """
    if "lib" in _MKL:
        return _MKL["lib"]
    import os

    if os.environ.get("LAGOLIB_MKL_RT", "").lower() == "off":
        _MKL.update(lib=None, why="LAGOLIB_MKL_RT=off hides it")
        return None
    import ctypes
    import ctypes.util
    import glob
    import site
    import sys

    candidates = [os.environ.get("LAGOLIB_MKL_RT", "")]
    for root in (sys.prefix, site.USER_BASE or ""):
        for sub in ("lib", "Library/bin"):
            candidates += sorted(glob.glob(os.path.join(root, sub, "*mkl_rt*")), key=len)
    candidates += [ctypes.util.find_library("mkl_rt") or ""]
    lib, why = None, 'MKL is not installed (pip install "lagolib[fast]")'
    for path in filter(None, candidates):
        try:
            lib = ctypes.CDLL(path)
            lib.pardiso  # noqa: B018 - the symbol must be there
            break
        except (OSError, AttributeError) as exc:
            lib, why = None, f"MKL's runtime {path} could not be loaded: {exc}"
    _MKL.update(lib=lib, why=why)
    return lib


def available_backends():
    """The Cholesky backends importable here (``"qdldl"`` and ``"scipy"`` are always there)."""
    out = ["qdldl"] if _have_qdldl() else []
    if _mkl_runtime() is not None:
        out.append("pardiso")
    out.append("scipy")
    return tuple(out)


def _auto_backend(N):
    """``backend="auto"`` for a system of ``N`` rows (see :data:`PARDISO_MIN_SIZE`)."""
    if N >= PARDISO_MIN_SIZE and _mkl_runtime() is not None:  # MKL is loaded only then
        return "pardiso"
    return "qdldl" if _have_qdldl() else "scipy"


def _have_qdldl():
    """Whether qdldl imports (it is a dependency; SuperLU stands in if it is broken)."""
    try:
        import qdldl  # noqa: F401
    except ImportError:  # pragma: no cover - qdldl is a dependency
        return False
    return True


def _check_square(H, where="SparseCholesky", *, check=True):
    """``H`` must be a square scipy.sparse matrix; with ``check``, also finite and symmetric."""
    if not sp.issparse(H):
        raise OptionTypeError(f"{where}: H must be a scipy.sparse matrix; got {type(H).__name__}")
    if H.ndim != 2 or H.shape[0] != H.shape[1]:
        raise OptionError(f"{where}: H must be square; got shape {H.shape}")
    if H.dtype.kind not in "biuf":
        raise OptionTypeError(f"{where}: H must be real; got dtype {H.dtype}")
    if not check:
        return
    data = H.tocsr().data if H.format not in ("csr", "csc", "coo") else H.data
    if not np.all(np.isfinite(data)):
        raise OptionError(f"{where}: H has non-finite entries (nan or inf)")
    scale = float(np.max(np.abs(data))) if data.size else 0.0
    asym = abs(H - H.T)
    if asym.nnz and asym.max() > 1e-10 * scale:
        raise OptionError(
            f"{where}: H is not symmetric (max |H - H^T| = {asym.max():.3g} against max |H| = "
            f"{scale:.3g}); pass a symmetric matrix (both triangles stored)"
        )


def _check_rhs(b, N, where, *, columns=True, name="b"):
    """``b`` as a finite float array of shape (N,) (or (N, k) with ``columns``)."""
    b = real_array(b, name, where)
    ok = b.shape[:1] == (N,) and (b.ndim == 1 or (columns and b.ndim == 2))
    if not ok:
        shapes = f"({N},) or ({N}, k)" if columns else f"({N},)"
        raise OptionError(f"{where}: {name} must have shape {shapes}; got {b.shape}")
    if not np.all(np.isfinite(b)):
        raise OptionError(f"{where}: {name} has non-finite entries (nan or inf)")
    return b


_PARDISO_ERRORS = {
    -1: "input inconsistent",
    -2: "not enough memory",
    -3: "reordering problem",
    -4: "zero or negative pivot",
    -5: "unclassified (internal) error",
    -6: "reordering failed",
    -7: "diagonal matrix is singular",
    -8: "32-bit integer overflow problem",
    -9: "not enough memory for out-of-core",
    -10: "error opening out-of-core files",
    -11: "read/write error with out-of-core files",
    -12: "not enough memory (pardiso_64 required)",
}


def _pardiso_call(lib, pt, phase, n, data, indptr, indices, ordering, iparm, b, x):
    """One call of MKL's ``pardiso`` for a real SPD matrix (``mtype = 2``); its error code.

    ``data``, ``b`` and ``x`` are float64 arrays, ``indptr``, ``indices``, ``ordering`` and
    ``iparm`` int32 arrays; ``b`` holds ``nrhs = b.shape[1]`` (or 1) right-hand sides.
    """
    import ctypes

    i32, f64 = ctypes.c_int32, ctypes.c_double
    err = i32(0)
    one = ctypes.byref(i32(1))
    nrhs = 1 if b.ndim == 1 else b.shape[1]

    def ptr(a, kind):
        return a.ctypes.data_as(ctypes.POINTER(kind))

    lib.pardiso(
        pt.ctypes.data_as(ctypes.c_void_p), one, one, ctypes.byref(i32(2)),
        ctypes.byref(i32(phase)), ctypes.byref(i32(n)), ptr(data, f64), ptr(indptr, i32),
        ptr(indices, i32), ptr(ordering, i32), ctypes.byref(i32(nrhs)), ptr(iparm, i32),
        ctypes.byref(i32(0)), ptr(b, f64), ptr(x, f64), ctypes.byref(err),
    )  # fmt: skip
    return err.value


def _pardiso_release(lib, pt, n):
    """Free PARDISO's internal memory for one handle ``pt`` (phase -1)."""
    i, d = np.zeros(1, dtype=np.int32), np.zeros(1)
    _pardiso_call(lib, pt, -1, n, d, i, i, i, np.zeros(64, dtype=np.int32), d, d)


class _Pardiso:
    """MKL PARDISO on one sparsity pattern of a real SPD matrix (``mtype = 2``).

    Phase 11 — the nested-dissection (METIS) ordering and the supernodal symbolic factorization —
    runs once, in the constructor; :meth:`factor` (phase 22) and :meth:`solve` (phase 33) reuse
    it.  ``U`` is the upper triangle in CSR with int32 indices (PARDISO's 32-bit interface).
    ``ordering`` (row ``k`` of the factor is row ``ordering[k]`` of ``U``) replaces METIS;
    otherwise METIS's ordering is returned in :attr:`ordering`.
    """

    def __init__(self, U, ordering=None):
        import ctypes
        import weakref

        self._lib = _mkl_runtime()
        self.n = U.shape[0]
        self.pt = np.zeros(64, dtype=np.int64)  # PARDISO's opaque handle
        self.iparm = np.zeros(64, dtype=np.int32)
        self._lib.pardisoinit(
            self.pt.ctypes.data_as(ctypes.c_void_p),
            ctypes.byref(ctypes.c_int32(2)),
            self.iparm.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)),
        )
        self.iparm[1] = 2  # nested dissection from METIS
        self.iparm[7] = 0  # no iterative refinement: a Cholesky solve is exact to rounding
        self.iparm[17] = -1  # report nnz(L) ...
        self.iparm[18] = -1  # ... and the factorization's Mflop
        self.iparm[26] = 0  # no matrix check (lagolib checks H itself)
        self.iparm[34] = 1  # zero-based indices
        if ordering is None:
            self.iparm[4] = 2  # return METIS's ordering in perm
            self.ordering = np.zeros(self.n, dtype=np.int32)
        else:
            self.iparm[4] = 1  # use the ordering given in perm
            self.ordering = np.ascontiguousarray(ordering, dtype=np.int32)
        self.indptr, self.indices = U.indptr, U.indices
        self._finalizer = weakref.finalize(self, _pardiso_release, self._lib, self.pt, self.n)
        self._call(11, U.data)

    def _call(self, phase, data, b=None):
        b = np.zeros(1) if b is None else b
        x = np.empty_like(b)
        code = _pardiso_call(
            self._lib, self.pt, phase, self.n, data, self.indptr, self.indices, self.ordering,
            self.iparm, b, x,
        )  # fmt: skip
        if code == -4 or code == -7:
            raise NotPositiveDefiniteError(
                f"sparse Cholesky (PARDISO): {_PARDISO_ERRORS[code]}; the matrix is singular or "
                "indefinite"
            )
        if code:
            what = _PARDISO_ERRORS.get(code, "unknown error")
            hint = "free memory or " if code in (-2, -9, -12) else ""
            raise BackendError(
                f"sparse Cholesky (PARDISO): error {code} ({what}) in phase {phase}; "
                f"{hint}use backend='qdldl'"
            )
        return x

    def factor(self, data):
        """Numerical factorization (phase 22) of the values ``data`` on the analysed pattern."""
        self._call(22, data)

    def solve(self, data, b):
        """Forward and back substitution (phase 33); ``b`` of shape (N,) or (N, k)."""
        B = np.asfortranarray(b, dtype=float)  # PARDISO reads k right-hand sides column by column
        return self._call(33, data, B)

    @property
    def nnz_L(self):
        """Entries of the factor ``L`` (diagonal included), from PARDISO's report."""
        return int(self.iparm[17])

    @property
    def mflops(self):
        """Mflop of one numerical factorization, from PARDISO's report."""
        return int(self.iparm[18])


class SparseCholesky:
    """Factorization of a sparse symmetric positive-definite matrix, for repeated solves.

    Parameters
    ----------
    H : scipy.sparse matrix, shape (N, N)
        Symmetric positive definite; both triangles stored (only the upper one is read).
    backend : {"auto", "qdldl", "pardiso", "scipy"}
        ``"auto"``: PARDISO from :data:`PARDISO_MIN_SIZE` rows up when MKL is installed
        (``pip install "lagolib[fast]"``), qdldl otherwise.
    check : bool
        Check that ``H`` (and every later one given to :meth:`refactor`) is finite and
        symmetric — ``O(nnz)``; lagolib's optimizer, which builds ``H`` symmetric, skips it.
    ordering : array_like of int, shape (N,), or callable, optional
        A fill-reducing ordering for PARDISO (row ``k`` of the factor is row ``ordering[k]`` of
        ``H``), e.g. a pose graph's nested dissection expanded to its unknowns
        (:func:`expand_ordering`), so that METIS runs once per graph, not once per matrix; a
        callable returning it (or None) is called only when the backend is PARDISO.  qdldl and
        SuperLU compute their own (AMD, MMD).

    Attributes
    ----------
    backend : str
        The backend in use (``"auto"`` resolved).
    ordering : ndarray of int or None
        PARDISO's ordering after the first factorization (the one given, or METIS's).
    nnz_L : int
        Entries of the factor ``L``, diagonal included: the fill its ordering leaves (0 for
        SuperLU, which stores ``L`` and ``U`` together).

    Raises
    ------
    OptionError, OptionTypeError
        ``H`` is not a square, finite, symmetric sparse matrix; unknown or unavailable ``backend``.
    NotPositiveDefiniteError
        If a pivot of the factorization is not positive: ``H`` is singular or indefinite
        (for a pose graph: a pose or component without a gauge, see
        :func:`lagolib.gauss_newton.check_gauge`).
    BackendError
        PARDISO failed for another reason (out of memory, an internal error).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> H = sp.csc_matrix(np.array([[4.0, 1.0], [1.0, 3.0]]))
    >>> SparseCholesky(H).solve(np.array([1.0, 2.0])).round(6)
    array([0.090909, 0.636364])
    """

    def __init__(self, H, backend="auto", *, check=True, ordering=None):
        backend = check_choice(backend, "backend", "SparseCholesky", ("auto",) + BACKENDS)
        self._check = check_bool(check, "check", "SparseCholesky")
        _check_square(H, "SparseCholesky", check=False)
        if backend == "auto":
            backend = _auto_backend(H.shape[0])
        elif backend == "pardiso" and _mkl_runtime() is None:
            raise OptionError(
                f"SparseCholesky: backend='pardiso' needs Intel MKL, but {_MKL['why']}; install it "
                "with pip install \"lagolib[fast]\" or use backend='qdldl'"
            )
        if callable(ordering):  # computed only when PARDISO will use it
            ordering = ordering() if backend == "pardiso" else None
        if ordering is not None:
            ordering = _check_ordering(ordering, H.shape[0])
        self.backend = backend
        self.shape = H.shape
        self.ordering = ordering
        self.nnz_L = 0
        self._solver = None
        self._pattern = None
        self.refactor(H)

    def refactor(self, H):
        """Factor a new matrix with the same shape (and, for speed, the same sparsity pattern)."""
        _check_square(H, "SparseCholesky", check=self._check)
        if H.shape != self.shape:
            raise OptionError(f"SparseCholesky.refactor needs shape {self.shape}; got {H.shape}")
        if self.shape[0] == 0:
            return self
        if self.backend == "scipy":
            self._factor_scipy(H)
            return self
        H = H if H.format == "csr" else sp.csr_matrix(H)
        if not H.has_sorted_indices:
            H = H.sorted_indices()
        same = self._pattern is not None and (
            (_same_memory(H.indptr, self._pattern[0]) and _same_memory(H.indices, self._pattern[1]))
            or (
                np.array_equal(H.indptr, self._pattern[0])
                and np.array_equal(H.indices, self._pattern[1])
            )
        )  # the symbolic analysis holds only for the same pattern
        if not same:
            self._solver = self._pattern = None  # frees the previous analysis before a new one
            self._upper = _upper_triangle(H, "csc" if self.backend == "qdldl" else "csr")
        perm, indptr, indices, (dpos, drows) = self._upper
        data = np.ascontiguousarray(H.data[perm], dtype=float)
        d = np.zeros(self.shape[0])  # a missing diagonal entry is a zero one
        d[drows] = data[dpos]
        _check_diagonal(d, self.backend)
        U = sp.csr_matrix if self.backend == "pardiso" else sp.csc_matrix
        U = U((data, indices, indptr), shape=self.shape)
        if self.backend == "qdldl":
            self._factor_qdldl(U, same)
        else:
            if not same:
                self._solver = _Pardiso(U, self.ordering)
                self.ordering = self._solver.ordering.astype(np.int64)
            self._data = data
            self._solver.factor(data)
            self.nnz_L = self._solver.nnz_L
        self._pattern = (H.indptr, H.indices)  # kept, not copied: O(nnz) memory at 10^6 poses
        return self

    def _factor_qdldl(self, U, same):
        import qdldl

        try:
            if same:
                self._solver.update(U, upper=True)
            else:
                self._solver = qdldl.Solver(U, upper=True)
        except (RuntimeError, ValueError):  # ValueError: qdldl's "Matrix A is empty" (H = 0)
            self._solver = self._pattern = None
            what = "the matrix is zero" if U.nnz == 0 else "the matrix is singular or indefinite"
            raise NotPositiveDefiniteError(f"sparse Cholesky (qdldl) failed: {what}") from None
        L, d, perm = self._solver.factors()
        self.nnz_L = int(L.nnz) + d.size
        bad = np.flatnonzero(~(d > 0))
        if bad.size:
            raise NotPositiveDefiniteError(
                f"sparse Cholesky (qdldl): pivot {d[bad[0]]:.3g} at row {perm[bad[0]]} is not "
                "positive; the matrix is singular or indefinite",
                pivot=int(perm[bad[0]]),
            )

    def factors(self):
        """``(L, d, perm)`` with ``H = P (I + L) diag(d) (I + L)^T P^T``, ``P[perm[k], k] = 1``.

        Only the qdldl backend exposes its factor (PARDISO and SuperLU keep theirs inside).

        Returns
        -------
        L : scipy.sparse.csc_matrix, shape (N, N)
            Strictly lower triangular, sorted indices.
        d : ndarray, shape (N,)
        perm : ndarray of int, shape (N,)
        """
        if self.backend != "qdldl":
            raise OptionError(
                f"SparseCholesky.factors: the {self.backend!r} backend does not expose its factor; "
                "factor with backend='qdldl'"
            )
        if self.shape[0] == 0:
            return sp.csc_matrix(self.shape), np.zeros(0), np.zeros(0, dtype=np.int64)
        L, d, perm = self._solver.factors()
        L = sp.csc_matrix(L)
        L.sort_indices()
        return L, np.asarray(d, dtype=float), np.asarray(perm, dtype=np.int64)

    def _factor_scipy(self, H):
        try:
            lu = spla.splu(
                sp.csc_matrix(H),
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=0.0,
                options={"SymmetricMode": True},
            )
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise NotPositiveDefiniteError(
                f"sparse Cholesky (SuperLU) failed: {exc}; the matrix is singular"
            ) from None
        d = lu.U.diagonal()
        bad = np.flatnonzero(~(d > 0))
        if bad.size:
            row = int(lu.perm_c[bad[0]])
            raise NotPositiveDefiniteError(
                f"sparse Cholesky (SuperLU): pivot {d[bad[0]]:.3g} at row {row} is not positive; "
                "the matrix is singular or indefinite",
                pivot=row,
            )
        self._solver = lu

    def solve(self, b):
        """Solve ``H x = b``.

        Parameters
        ----------
        b : array_like, shape (N,) or (N, k)

        Returns
        -------
        ndarray, same shape as ``b``
        """
        b = _check_rhs(b, self.shape[0], "SparseCholesky.solve")
        if self.shape[0] == 0:
            return np.zeros_like(b)
        if self.backend == "pardiso":
            x = self._solver.solve(self._data, b)
        elif self.backend == "qdldl" and b.ndim == 2:
            x = np.column_stack([self._solver.solve(col) for col in b.T]).reshape(b.shape)
        else:
            x = self._solver.solve(b)
        if not np.all(np.isfinite(x)):
            raise NotPositiveDefiniteError(
                f"sparse Cholesky ({self.backend}): the solution overflows float64; the matrix "
                "is numerically singular (pivots too small, e.g. information underflowing to zero)"
            )
        return x


def _check_ordering(ordering, N):
    """``ordering`` as an int64 permutation of ``range(N)``, or an OptionError saying what is wrong."""
    p = np.asarray(ordering)
    if p.dtype.kind not in "iu" or p.shape != (N,):
        raise OptionError(
            f"SparseCholesky: ordering must be a permutation of the {N} rows (integers, shape "
            f"({N},)); got dtype {p.dtype}, shape {p.shape}"
        )
    seen = np.zeros(N, dtype=bool)
    ok = p.size == 0 or (p.min() >= 0 and p.max() < N)
    if ok:
        seen[p] = True
    if not ok or not seen.all():
        raise OptionError(
            "SparseCholesky: ordering is not a permutation (a row is missing, repeated or out of "
            f"[0, {N}))"
        )
    return p.astype(np.int64)


def fill_reducing_ordering(pattern):
    """A nested-dissection ordering of a symmetric sparsity pattern, by METIS inside PARDISO.

    Computing it on the pose graph (``n x n``) and expanding it to the unknowns
    (:func:`expand_ordering`) is cheaper than METIS on the ``3n x 3n`` system and keeps a pose's
    rows together; lagolib's Gauss–Newton and LAGO do so once per graph.

    Parameters
    ----------
    pattern : scipy.sparse matrix, shape (n, n)
        Symmetric; its values are ignored.

    Returns
    -------
    ndarray of int, shape (n,), or None
        Row ``k`` of the reordered matrix is row ``perm[k]``; None without MKL.
    """
    if _mkl_runtime() is None or pattern.shape[0] == 0:
        return None
    P = sp.csr_matrix(pattern, dtype=float, copy=True)
    P.data[:] = 1.0
    P = sp.triu(P + sp.identity(P.shape[0], format="csr"), format="csr")  # SPD values: n I + A
    P.data[:] = 1.0
    P.setdiag(float(P.shape[0]) + 1.0)
    P.sort_indices()
    P.indptr, P.indices = P.indptr.astype(np.int32), P.indices.astype(np.int32)
    solver = _Pardiso(P)
    return solver.ordering.astype(np.int64)


def expand_ordering(perm, rows):
    """Expand an ordering of poses to their unknowns.

    Parameters
    ----------
    perm : ndarray of int, shape (n,)
        Pose order (row ``k`` of the reordered pose graph is pose ``perm[k]``).
    rows : ndarray of int, shape (n, q)
        The rows of each pose's unknowns in the system; ``-1`` where a pose has none (fixed).

    Returns
    -------
    ndarray of int, shape (number of rows >= 0,)
    """
    out = np.asarray(rows)[perm].ravel()
    return out[out >= 0]


def _upper_triangle(H, fmt):
    """Where the upper triangle of ``H`` (CSR, sorted) sits, for a backend's format.

    Returns ``(perm, indptr, indices, diag)``: ``U.data = H.data[perm]`` with ``U``'s
    ``indptr`` and ``indices`` in ``fmt`` (``"csr"``: PARDISO's rows; ``"csc"``: qdldl's
    columns), and ``diag = (positions, rows)`` of the stored diagonal entries in ``U.data``.
    Computed once per sparsity pattern; every refactorization is then one gather.
    """
    N = H.shape[0]
    if H.nnz >= 2**31 - 1:
        raise BackendError(
            f"sparse Cholesky: {H.nnz} stored entries exceed the 32-bit indices lagolib's "
            "backends use; split the problem or use backend='scipy'"
        )
    rows = np.repeat(np.arange(N, dtype=np.int64), np.diff(H.indptr))
    cols = H.indices
    perm = np.flatnonzero(cols >= rows)  # the upper triangle, in row order
    major, minor = (rows[perm], cols[perm]) if fmt == "csr" else (cols[perm], rows[perm])
    del rows
    if fmt == "csc":
        order = np.lexsort((minor, major))  # by column, then row
        perm, major, minor = perm[order], major[order], minor[order]
    indptr = np.zeros(N + 1, dtype=np.int32)
    np.cumsum(np.bincount(major, minlength=N), out=indptr[1:])
    diag = np.flatnonzero(major == minor)
    return perm, indptr, minor.astype(np.int32), (diag, major[diag])


def _same_memory(a, b):
    """``a`` and ``b`` view the same memory (``b`` is kept alive, so its address is not reused).

    LinearSystem hands every iteration's ``H`` the same index arrays (scipy wraps them in new
    views); recognizing them spares an ``O(nnz)`` comparison per factorization.
    """
    return (
        a.shape == b.shape
        and a.dtype == b.dtype
        and a.strides == b.strides
        and a.ctypes.data == b.ctypes.data
    )


def _check_diagonal(d, backend):
    """A positive-definite matrix has a positive diagonal ``d``: say which row fails, up front."""
    bad = np.flatnonzero(~(d > 0))
    if bad.size:
        raise NotPositiveDefiniteError(
            f"sparse Cholesky ({backend}): diagonal entry {d[bad[0]]:.3g} at row {bad[0]} is not "
            "positive; the matrix is singular or indefinite",
            pivot=int(bad[0]),
        )


def solve_spd(H, b, backend="auto"):
    """Solve ``H x = b`` for sparse symmetric positive-definite ``H`` by sparse Cholesky.

    Parameters
    ----------
    H : scipy.sparse matrix, shape (N, N)
    b : array_like, shape (N,) or (N, k)
    backend : {"auto", "qdldl", "pardiso", "scipy"}

    Returns
    -------
    ndarray, same shape as ``b``
    """
    return SparseCholesky(H, backend).solve(b)


def _supernodes(L):
    """First column of every supernode of the strictly lower factor ``L`` (CSC), and ``N``.

    Column ``j + 1`` joins column ``j``'s supernode when ``L[:, j]`` is ``L[:, j + 1]`` plus the
    one row ``j + 1`` — their rows below the supernode are the same, so the supernode's columns
    are one dense block.  Shape (K + 1,).
    """
    N = L.shape[0]
    counts = np.diff(L.indptr)
    first = np.full(N, -1, dtype=np.int64)
    has = counts > 0
    first[has] = L.indices[L.indptr[:-1][has]]
    joins = (counts[:-1] == counts[1:] + 1) & (first[:-1] == np.arange(1, N))
    return np.concatenate([[0], np.flatnonzero(~joins) + 1, [N]])


@dataclass(eq=False)
class SelectedInverse:
    """The entries of ``H^-1`` on the sparsity pattern of ``H``'s Cholesky factor.

    Made by :func:`selected_inverse`.  The pattern of ``L + L^T`` contains the pattern of ``H``,
    so every diagonal entry, every 3x3 block of a pose, and every entry that couples two
    variables sharing a constraint is there.

    Attributes
    ----------
    N : int
    perm : ndarray of int, shape (N,)
        The factor's ordering: row ``k`` of the factor is row ``perm[k]`` of ``H``.
    """

    N: int
    perm: np.ndarray
    _iperm: np.ndarray
    _keys: np.ndarray  # column * N + row of every entry of L (CSC order, so sorted)
    _lower: np.ndarray  # Sigma at those entries (in the factor's ordering)
    _diag: np.ndarray  # Sigma's diagonal (in the factor's ordering)

    def entries(self, i, j):
        """``(H^-1)[i, j]`` for arrays of rows ``i`` and columns ``j`` (of ``H``, broadcast).

        Raises
        ------
        OptionError
            A requested entry lies outside the factor's pattern (it was not computed): such an
            entry needs a solve, e.g. ``SparseCholesky(H).solve(e_j)[i]``.
        """
        i, j = np.broadcast_arrays(np.asarray(i), np.asarray(j))
        for name, v in (("i", i), ("j", j)):
            if v.dtype.kind not in "iu" or (v.size and (v.min() < 0 or v.max() >= self.N)):
                raise OptionError(f"SelectedInverse.entries: {name} must be rows in [0, {self.N})")
        a, b = self._iperm[i], self._iperm[j]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        out = self._diag[lo]
        off = lo != hi
        key = lo[off] * self.N + hi[off]
        pos = np.minimum(np.searchsorted(self._keys, key), max(self._keys.size - 1, 0))
        found = self._keys[pos] == key if self._keys.size else np.zeros(key.shape, bool)
        if not np.all(found):
            k = np.flatnonzero(off)[np.flatnonzero(~found)[0]]
            raise OptionError(
                f"SelectedInverse.entries: entry ({i.flat[k]}, {j.flat[k]}) of H^-1 is not on the "
                "pattern of the factor, so it was not computed; solve for that column instead"
            )
        out = out.copy()
        out[off] = self._lower[pos]
        return out

    def blocks(self, rows):
        """Diagonal blocks ``(H^-1)[r, r]`` for each row group ``r`` of ``rows``.

        Parameters
        ----------
        rows : array_like of int, shape (k, q)
            E.g. ``3 * pose + [0, 1, 2]`` for the marginal covariance of each pose.

        Returns
        -------
        ndarray, shape (k, q, q)
        """
        rows = np.asarray(rows)
        if rows.ndim != 2:
            raise OptionError(
                f"SelectedInverse.blocks: rows must have shape (k, q); got {rows.shape}"
            )
        return self.entries(rows[:, :, None], rows[:, None, :])


def selected_inverse(H, *, factor=None):
    """``H^-1`` on the pattern of ``L`` by Takahashi's recurrences, supernode by supernode.

    With ``H = L D L^T`` (unit lower ``L``, rows permuted) the inverse ``Σ`` satisfies
    ``Σ L = L^-T D^-1``, upper triangular; column ``j`` of it below the diagonal reads
    (Takahashi, Fagan and Chen 1973; Erisman and Tinney 1975)::

        Σ[s, j] = -Σ[s, s] L[s, j]            s = struct(L[:, j]), the rows below j
        Σ[j, j] = 1 / d_j - L[s, j]^T Σ[s, j]

    and ``Σ[s, s]`` involves only entries on the pattern of ``L`` (``s`` is a clique of the
    filled graph), already computed because the columns run from the last to the first.  The
    columns of a supernode share their rows below it, so ``Σ`` on those rows is gathered once
    per supernode into a small dense matrix.  The work is that of one more factorization; no
    column of ``H^-1`` is solved for.

    Parameters
    ----------
    H : scipy.sparse matrix, shape (N, N)
        Symmetric positive definite.
    factor : SparseCholesky, optional
        A qdldl factorization of ``H`` to reuse (checked by one solve).

    Returns
    -------
    SelectedInverse

    References
    ----------
    K. Takahashi, J. Fagan, M.-S. Chen, "Formation of a sparse bus impedance matrix and its
    application to short circuit study", PICA 1973.  A. M. Erisman, W. F. Tinney, "On computing
    certain elements of the inverse of a sparse matrix", Comm. ACM 18(3), 1975.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> H = sp.csc_matrix(np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]]))
    >>> S = selected_inverse(H)
    >>> bool(np.allclose(S.entries([0, 1, 2], [0, 1, 2]), np.diag(np.linalg.inv(H.toarray()))))
    True
    """
    if factor is None:
        factor = SparseCholesky(H, "qdldl")
    elif not isinstance(factor, SparseCholesky) or factor.shape != H.shape:
        raise OptionTypeError("selected_inverse: factor must be a SparseCholesky of H")
    else:  # a factor of another matrix would give a wrong inverse: one probe solve says
        r = np.cos(np.arange(H.shape[0]))
        if H.shape[0] and not np.allclose(factor.solve(H @ r), r, rtol=1e-6, atol=1e-6):
            raise OptionError(
                "selected_inverse: factor is not a factorization of H (a solve with it does not "
                "invert H); pass the SparseCholesky of this H, or none"
            )
    L, d, perm = factor.factors()
    N = L.shape[0]
    indptr, indices, data = L.indptr, L.indices, L.data
    lower = np.zeros(data.size)
    diag = np.zeros(N)
    keys = np.repeat(np.arange(N, dtype=np.int64), np.diff(indptr)) * N + indices
    starts = _supernodes(L)
    for J in range(starts.size - 2, -1, -1):
        c0, c1 = int(starts[J]), int(starts[J + 1])
        s = c1 - c0
        R = indices[indptr[c1 - 1] : indptr[c1]].astype(np.int64)  # rows below the supernode
        r = R.size
        S = np.empty((s + r, s + r))  # Σ on [J, R]: local rows 0..s-1 are J, then R
        S[s:, s:] = np.diag(diag[R])
        ia, ib = np.tril_indices(r, -1)
        if ia.size:  # Σ_RR: on the pattern of L, already computed
            S[s + ia, s + ib] = S[s + ib, s + ia] = lower[np.searchsorted(keys, R[ib] * N + R[ia])]
        for k in range(s - 1, -1, -1):  # column j = c0 + k: rows c0+k+1 .. c1-1, then R
            o = indptr[c0 + k]
            lj = data[o : indptr[c0 + k + 1]]  # L[struct(j), j], shape (s - 1 - k + r,)
            col = -(S[k + 1 :, k + 1 :] @ lj)  # Σ[struct(j), j] = -Σ[struct, struct] L[struct, j]
            S[k + 1 :, k] = S[k, k + 1 :] = col
            S[k, k] = 1.0 / d[c0 + k] - lj @ col  # Σ_jj = 1/d_j - L[struct, j]^T Σ[struct, j]
            lower[o : indptr[c0 + k + 1]] = col
        diag[c0:c1] = np.diagonal(S)[:s]
    iperm = np.empty(N, dtype=np.int64)
    iperm[perm] = np.arange(N)
    return SelectedInverse(N, perm, iperm, keys, lower, diag)


@dataclass
class PCGResult:
    """Outcome of :func:`pcg`.

    Attributes
    ----------
    x : ndarray, shape (N,)
        The approximate solution.
    iterations : int
        Matrix-vector products with ``H`` taken.
    residual_norms : list of float
        ``||b - H x_k|| / ||b||`` after each iteration (index 0: the start).
    converged : bool
        Whether the relative residual reached ``rtol``.
    """

    x: np.ndarray
    iterations: int
    residual_norms: list = field(default_factory=list)
    converged: bool = False


def _dot(a, b):
    """``a . b`` without BLAS: a single-threaded, deterministic sum.

    OpenBLAS runs ``ddot`` on all cores for vectors longer than 10 000 entries; for one dot
    product that is mostly thread start-up and, on a machine whose cores are busy, threads waiting
    for each other — PCG on M3500's 10 497 unknowns ran 20x slower than single-threaded, and its
    iteration count changed from run to run with the summation order.
    """
    return float(np.einsum("i,i->", a, b))


def _preconditioner(H, kind, block):
    """``M^-1`` as a function ``r -> z``."""
    if kind is None:
        return lambda r: r
    if kind == "jacobi":
        d = H.diagonal()
        if np.any(d <= 0):
            raise NotPositiveDefiniteError(
                "Jacobi preconditioner: a diagonal entry is not positive"
            )
        inv = 1.0 / d
        return lambda r: inv * r
    if kind == "block_jacobi":
        N = H.shape[0]
        if N % block:
            raise OptionError(
                f"pcg: block={block} does not divide the size of H ({N}); the block-Jacobi "
                "preconditioner needs N divisible by block"
            )
        nb = N // block
        Hc = H.tocsr()
        idx = np.arange(N).reshape(nb, block)
        rows = np.repeat(idx, block, axis=1).ravel()
        cols = np.tile(idx, (1, block)).ravel()
        blocks = np.asarray(Hc[rows, cols]).reshape(nb, block, block)
        try:
            inv = np.linalg.inv(blocks)
        except np.linalg.LinAlgError:
            raise NotPositiveDefiniteError(
                "block-Jacobi preconditioner: a diagonal block is singular"
            ) from None
        return lambda r: np.einsum("kab,kb->ka", inv, r.reshape(nb, block)).ravel()
    raise AssertionError(kind)  # pragma: no cover - pcg checks the choice


def pcg(
    H, b, *, preconditioner="block_jacobi", block=3, rtol=1e-10, maxiter=None, x0=None, check=True
):
    """Preconditioned conjugate gradients for ``H x = b`` (lecture notes: "Conjugate gradients").

    The textbook iteration (Shewchuk, "An Introduction to the Conjugate Gradient Method Without
    the Agonizing Pain", 1994, §B3)::

        r = b - H x;  z = M^-1 r;  d = z
        repeat:  alpha = r.z / d.H d;  x += alpha d;  r_new = r - alpha H d
                 z_new = M^-1 r_new;  beta = r_new.z_new / r.z;  d = z_new + beta d

    Parameters
    ----------
    H : scipy.sparse matrix, shape (N, N)
        Symmetric positive definite.
    b : array_like, shape (N,)
    preconditioner : {"block_jacobi", "jacobi", None}
        ``M`` = the 3x3 diagonal blocks of ``H`` (one per pose), its diagonal, or the identity.
    block : int
        Block size of ``"block_jacobi"``.
    rtol : float
        Stop when ``||b - H x|| <= rtol ||b||``.
    maxiter : int, optional
        Default ``10 N``.
    x0 : array_like, shape (N,), optional
        Start; default zeros.
    check : bool
        Check that ``H`` is finite and symmetric (``O(nnz)``).

    Returns
    -------
    PCGResult

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> H = sp.diags([-1.0, 2.5, -1.0], [-1, 0, 1], shape=(6, 6), format="csr")
    >>> out = pcg(H, np.ones(6), preconditioner=None)
    >>> out.iterations <= 6, bool(np.allclose(H @ out.x, 1.0))
    (True, True)
    """
    where = "pcg"
    _check_square(H, where, check=check_bool(check, "check", where))
    N = H.shape[0]
    b = _check_rhs(b, N, where, columns=False)
    if preconditioner is not None:
        check_choice(preconditioner, "preconditioner", where, ("block_jacobi", "jacobi"))
    block = check_int(block, "block", where, minimum=1)
    rtol = check_real(rtol, "rtol", where, minimum=0.0)
    maxiter = 10 * N if maxiter is None else check_int(maxiter, "maxiter", where, minimum=0)
    if x0 is None:
        x = np.zeros(N)
    else:
        x = np.array(_check_rhs(x0, N, where, columns=False, name="x0"), dtype=float)
    apply_Minv = _preconditioner(H, preconditioner, block)
    bnorm = np.sqrt(_dot(b, b))
    if bnorm == 0.0:
        return PCGResult(np.zeros(N), 0, [0.0], True)
    r = b - H @ x
    z = apply_Minv(r)
    d = z.copy()
    rz = _dot(r, z)
    history = [np.sqrt(_dot(r, r)) / bnorm]
    k = 0
    while history[-1] > rtol and k < maxiter:
        Hd = H @ d
        dHd = _dot(d, Hd)
        if not dHd > 0:
            raise NotPositiveDefiniteError(f"PCG: d^T H d = {dHd:.3g} at iteration {k}")
        alpha = rz / dHd
        x += alpha * d
        r -= alpha * Hd
        z = apply_Minv(r)
        rz_new = _dot(r, z)
        d = z + (rz_new / rz) * d
        rz = rz_new
        k += 1
        history.append(np.sqrt(_dot(r, r)) / bnorm)
    return PCGResult(x, k, history, history[-1] <= rtol)
