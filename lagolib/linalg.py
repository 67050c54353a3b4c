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

import threading
import warnings
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .checks import check_bool, check_choice, check_int, check_real, real_array
from .errors import (
    BackendError,
    BackendWarning,
    NotPositiveDefiniteError,
    OptionError,
    OptionTypeError,
)

__all__ = [
    "SparseCholesky",
    "SolveCheck",
    "available_backends",
    "solve_spd",
    "selected_inverse",
    "SelectedInverse",
    "pcg",
    "PCGResult",
    "PARDISO_MIN_SIZE",
    "PARDISO_MIN_MFLOP",
    "PIVOT_TOL",
    "fill_reducing_ordering",
    "elimination_ordering",
    "core_size",
    "expand_ordering",
]

BACKENDS = ("qdldl", "pardiso", "cholmod", "scipy")

#: What each backend is, for messages.
_NAMES = {
    "qdldl": "qdldl", "pardiso": "MKL PARDISO", "cholmod": "CHOLMOD (cvxopt)", "scipy": "SuperLU",
}

#: ``backend="auto"`` uses PARDISO (when installed) for systems of at least this many rows, qdldl
#: below — rows of a pose graph's *2-core* when the caller knows it (``auto_rows``): the tree-like
#: parts (an odometry chain) cost O(n) with no fill on qdldl.  Measured with every solve's check
#: included (``benchmarks/BACKENDS.md``: one Gauss–Newton refactorization and checked solve, 2
#: cores).  Above 5 x 10^4 rows PARDISO won on an idle machine (qdldl / PARDISO 1.7 at 5.1 x 10^4
#: rows, 2.5 at 9 x 10^4, 7.3 at 3 x 10^5) and on a busy one (1.13, 1.9, 6.2); below, it won idle
#: (1.6-2.4) but lost busy (0.10-0.85: its threads wait for each other), and the book's graphs
#: (at most 3 x 10^4 rows) stay on the readable, deterministic qdldl.  On chains qdldl was
#: 3-4x faster at every size.
PARDISO_MIN_SIZE = 50_000

#: ``backend="auto"`` also moves a smaller system to PARDISO (when installed) from its second
#: factorization on, when qdldl's first one took at least this many Mflop (``sum_j c_j^2`` over
#: the columns of ``L``): the row count misses the fill of long random closures.  Measured (one
#: refactorization, qdldl / PARDISO, 2 cores): a 1.7 x 10^4-pose Manhattan world, 351 Mflop,
#: 0.14 / 0.13 s; 3 x 10^4 poses, 1178 Mflop, 0.43 / 0.19 s; M3500 with 300 random wrong
#: closures, 230 Mflop, 0.13 / 0.10 s; with 1000, 1973 Mflop, 1.15 / 0.20 s — where IRLS ran
#: 62.6 s on qdldl and 6.8 s on PARDISO (benchmarks/ROBUST.md).
PARDISO_MIN_MFLOP = 500.0

#: Every solve is checked by its componentwise (Oettli–Prager) backward error
#: ``omega = max_i |b - H x|_i / (|H| |x| + |b|)_i`` — one product with ``H`` and one with ``|H|``
#: — and refined (``x += F^-1 (b - H x)``, one more solve each) while ``omega`` exceeds this and
#: keeps halving, as LAPACK's ``xPORFS`` does.
REFINE_TARGET = 2.0 * np.finfo(float).eps

#: At most this many refinement steps per solve.
MAX_REFINEMENT_STEPS = 10

#: A solve whose backward error is still above this after refinement is not accepted: a fast backend
#: is replaced by qdldl (:class:`lagolib.BackendWarning`), qdldl's own failure raises.
BACKWARD_ERROR_TOL = 1e-12

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


def single_threaded_blas():
    """A context in which OpenBLAS (NumPy's and SciPy's) runs on one thread.

    SciPy's SuperLU calls the BLAS on small supernodes; with a multi-threaded OpenBLAS beside
    another job on the same 2 cores, one factorization of the certificate matrix of a
    10^4-pose world took 0.3-2.2 s instead of 0.06 s (measured).  Uses ``threadpoolctl``
    (its controller found once).  MKL is left alone: changing its thread count between
    PARDISO's phases of one factorization crashed it (a segmentation fault, measured).
    """
    ctl = _BLAS.get("controller")
    if ctl is None:
        from threadpoolctl import ThreadpoolController

        ctl = _BLAS["controller"] = ThreadpoolController().select(internal_api="openblas")
    return ctl.limit(limits=1)


_BLAS = {}


def available_backends():
    """The Cholesky backends importable here (``"qdldl"`` and ``"scipy"`` are always there)."""
    out = ["qdldl"] if _have_qdldl() else []
    if _mkl_runtime() is not None:
        out.append("pardiso")
    if _have_cholmod():
        out.append("cholmod")
    out.append("scipy")
    return tuple(out)


def _fast_backend():
    """The supernodal backend ``"auto"`` uses for large systems: PARDISO when MKL is installed,
    else CHOLMOD when cvxopt is, else None."""
    if _mkl_runtime() is not None:
        return "pardiso"
    return "cholmod" if _have_cholmod() else None


def _have_cholmod():
    """Whether CHOLMOD imports (``pip install "lagolib[cholmod]"``: cvxopt's wheel carries it);
    ``LAGOLIB_CHOLMOD=off`` hides it, as on a machine without it (the tests run both ways)."""
    import os

    if os.environ.get("LAGOLIB_CHOLMOD", "").lower() == "off":
        return False
    try:
        from cvxopt import cholmod  # noqa: F401
    except ImportError:
        return False
    return True


def _auto_backend(N, auto_rows=None):
    """``backend="auto"`` for a system of ``N`` rows (see :data:`PARDISO_MIN_SIZE`).

    ``auto_rows`` (a number, or a callable computing it only for large systems) replaces ``N``
    in the comparison: the rows where the factorization's work is.
    """
    if N >= PARDISO_MIN_SIZE:  # MKL (or cvxopt) is loaded only then
        fast = _fast_backend()
        if fast is not None:
            rows = N if auto_rows is None else (auto_rows() if callable(auto_rows) else auto_rows)
            rows = check_int(rows, "auto_rows", "SparseCholesky", minimum=0)
            if rows >= PARDISO_MIN_SIZE:
                return fast
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
    if H.dtype.kind not in "iuf":
        raise OptionTypeError(
            f"{where}: H must be a real (integer or floating-point) matrix; got dtype {H.dtype}"
        )
    if not check:
        return
    H = H.tocsr()  # any format (dia, lil, ...) is read the same way
    data = H.data
    if not np.all(np.isfinite(data)):
        raise OptionError(f"{where}: H has non-finite entries (nan or inf)")
    scale = float(np.max(np.abs(data))) if data.size else 0.0
    asym = abs(H - H.T).tocsr()
    if asym.nnz and asym.max() > 1e-10 * scale:
        raise OptionError(
            f"{where}: H is not symmetric (max |H - H^T| = {asym.max():.3g} against max |H| = "
            f"{scale:.3g}); pass a symmetric matrix (both triangles stored)"
        )


def _check_rhs(b, N, where, *, columns=True, name="b"):
    """``b`` as a finite float array of shape (N,) (or (N, k) with ``columns``)."""
    if np.asarray(b).dtype.kind == "b":
        raise OptionTypeError(f"{where}: {name} must be real numbers; got booleans (dtype bool)")
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


def _pardiso_call(lib, pt, phase, n, data, indptr, indices, ordering, iparm, b, x, mtype=-2):
    """One call of MKL's ``pardiso``; its error code.

    ``mtype`` is PARDISO's matrix type: ``-2`` real symmetric indefinite (``data``, ``b``, ``x``
    float64) or ``-4`` complex Hermitian indefinite (complex128); ``indptr``, ``indices``,
    ``ordering`` and ``iparm`` are int32 arrays; ``b`` holds ``nrhs = b.shape[1]`` (or 1)
    right-hand sides.
    """
    import ctypes

    i32, void = ctypes.c_int32, ctypes.c_void_p
    err = i32(0)
    one = ctypes.byref(i32(1))
    nrhs = 1 if b.ndim == 1 else b.shape[1]

    def ptr(a, kind):
        return a.ctypes.data_as(ctypes.POINTER(kind))

    lib.pardiso(
        pt.ctypes.data_as(void), one, one, ctypes.byref(i32(mtype)),
        ctypes.byref(i32(phase)), ctypes.byref(i32(n)), data.ctypes.data_as(void),
        ptr(indptr, i32), ptr(indices, i32), ptr(ordering, i32), ctypes.byref(i32(nrhs)),
        ptr(iparm, i32), ctypes.byref(i32(0)), b.ctypes.data_as(void), x.ctypes.data_as(void),
        ctypes.byref(err),
    )  # fmt: skip
    return err.value


def _pardiso_release(lib, pt, n, mtype=-2):
    """Free PARDISO's internal memory for one handle ``pt`` (phase -1)."""
    i, d = np.zeros(1, dtype=np.int32), np.zeros(1)
    _pardiso_call(lib, pt, -1, n, d, i, i, i, np.zeros(64, dtype=np.int32), d, d, mtype)


# PARDISO's matrix type: real symmetric *indefinite*, factored as L D L^T with 1 x 1 diagonal
# pivots in the given order, and positive definiteness read from the inertia.  Its Cholesky
# (mtype = 2) broke down ("zero or negative pivot") on the Gauss-Newton matrix of a 6 x 10^4-pose
# odometry chain in the elimination order in which SuperLU's L D L^T had no pivot below 50 — and
# succeeded in the order in which SuperLU's pivots fell to 2.6e-10; the L D L^T factors both, in
# the same time (1.2-1.5 s against 0.8-1.5 s on a 10^5-pose Manhattan world, same fill).
_MTYPE = -2


class _Pardiso:
    """MKL PARDISO on one sparsity pattern of a real symmetric matrix (``mtype = -2``), or of a
    complex Hermitian one (``mtype = -4``, :mod:`lagolib.certify`'s certificate matrix).

    Phase 11 — the nested-dissection (METIS) ordering and the supernodal symbolic factorization —
    runs once, in the constructor; :meth:`factor` (phase 22) and :meth:`solve` (phase 33) reuse
    it.  ``U`` is the upper triangle in CSR with int32 indices (PARDISO's 32-bit interface).
    ``ordering`` (row ``k`` of the factor is row ``ordering[k]`` of ``U``) replaces METIS;
    otherwise METIS's ordering is returned in :attr:`ordering`.  The factorization is
    ``L D L^T`` with 1 x 1 pivots; a matrix whose inertia is not ``(n, 0, 0)``, or one that needed
    a perturbed pivot, is reported as not positive definite; :meth:`inertia` reports it instead.
    """

    def __init__(self, U, ordering=None, mtype=_MTYPE):
        import ctypes
        import weakref

        self._lib = _mkl_runtime()
        self.n = U.shape[0]
        self.mtype = mtype
        self.pt = np.zeros(64, dtype=np.int64)  # PARDISO's opaque handle
        self.iparm = np.zeros(64, dtype=np.int32)
        self._lib.pardisoinit(
            self.pt.ctypes.data_as(ctypes.c_void_p),
            ctypes.byref(ctypes.c_int32(mtype)),
            self.iparm.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)),
        )
        self.iparm[1] = 2  # nested dissection from METIS
        self.iparm[7] = 0  # no refinement inside PARDISO: SparseCholesky.solve checks and refines
        self.iparm[9] = 13  # a pivot below 1e-13 |H| is perturbed (and then refused, see factor)
        self.iparm[10] = 0  # no scaling ...
        self.iparm[12] = 0  # ... and no matching: the order is the one given or METIS's
        self.iparm[20] = 0  # 1 x 1 diagonal pivots only (no Bunch-Kaufman 2 x 2)
        # the two-level parallel factorization: the default (classic) one took 6-37 s on the
        # path-shaped elimination tree of a 10^5-pose chain with 2 threads (0.2 s with one);
        # two-level takes 0.27 s there, and 0.50-0.56 s against 0.64-0.67 s on a 10^5-pose
        # Manhattan world
        self.iparm[23] = 1
        self.iparm[55] = 1  # keep the factor's diagonal readable (pardiso_getdiag)
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
        self._finalizer = weakref.finalize(
            self, _pardiso_release, self._lib, self.pt, self.n, mtype
        )
        self._call(11, U.data)

    def _call(self, phase, data, b=None):
        b = np.zeros(1, dtype=data.dtype) if b is None else b
        x = np.empty_like(b)
        code = _pardiso_call(
            self._lib, self.pt, phase, self.n, data, self.indptr, self.indices, self.ordering,
            self.iparm, b, x, self.mtype,
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

    def inertia(self, data):
        """Numerical factorization (phase 22) of ``data``: ``(positive, negative, perturbed)``
        pivots of ``L D L^T`` — by Sylvester's law of inertia the numbers of positive and
        negative eigenvalues when no pivot was perturbed.  A factorization with a perturbed
        pivot is not to be solved with."""
        try:
            self._call(22, data)
        except NotPositiveDefiniteError:  # an exactly singular diagonal block
            return 0, 0, self.n
        return tuple(int(v) for v in self.iparm[[21, 22, 13]])

    def factor(self, data):
        """Numerical factorization (phase 22) of the values ``data`` on the analysed pattern.

        Raises NotPositiveDefiniteError unless every pivot is positive and none was perturbed.
        """
        import ctypes

        self._call(22, data)
        positive, negative, perturbed = (int(v) for v in self.iparm[[21, 22, 13]])
        if positive != self.n or perturbed:
            raise NotPositiveDefiniteError(
                f"sparse Cholesky (PARDISO): {negative} negative and {self.n - positive - negative} "
                f"zero pivots, {perturbed} perturbed; the matrix is singular or indefinite"
            )
        df, da, err = np.zeros(self.n), np.zeros(self.n), ctypes.c_int32(0)
        f64 = ctypes.POINTER(ctypes.c_double)
        self._lib.pardiso_getdiag(
            self.pt.ctypes.data_as(ctypes.c_void_p), df.ctypes.data_as(f64),
            da.ctypes.data_as(f64), ctypes.byref(ctypes.c_int32(1)), ctypes.byref(err),
        )  # fmt: skip
        if err.value == 0:  # the pivots D of L D L^T and H's diagonal, rows of H
            _check_pivots(df, da, np.arange(self.n), "PARDISO")

    def solve(self, data, b):
        """Forward and back substitution (phase 33); ``b`` of shape (N,) or (N, k)."""
        B = np.asfortranarray(b, dtype=data.dtype)  # PARDISO reads k right-hand sides column by column
        return self._call(33, data, B)

    def release(self):
        """Free the numerical factor (phase 0); the ordering and symbolic analysis stay."""
        i = np.zeros(1, dtype=np.int32)
        d = np.zeros(1, dtype=np.complex128 if self.mtype == -4 else np.float64)
        _pardiso_call(self._lib, self.pt, 0, self.n, d, i, i, i, self.iparm, d, d, self.mtype)

    @property
    def nnz_L(self):
        """Entries of the factor ``L`` (diagonal included), from PARDISO's report."""
        return int(self.iparm[17])

    @property
    def mflops(self):
        """Mflop of one numerical factorization, from PARDISO's report."""
        return int(self.iparm[18])


#: cvxopt's ``cholmod.options`` are one module-wide dict: one scope at a time sets them
_CHOLMOD_LOCK = threading.RLock()


class _Cholmod:
    """CHOLMOD (SuiteSparse; supernodal ``L L^T``) through cvxopt, on one sparsity pattern.

    The symbolic analysis runs once, in the constructor, in the given ``ordering`` (row ``k`` of
    the factor is row ``ordering[k]``; CHOLMOD's own AMD without one); :meth:`factor` puts new
    values into the same pattern and factors them numerically.  ``U`` is the upper triangle in
    CSR, read as the lower triangle in CSC (column ``j`` of ``L``'s input is row ``j`` of ``U``).
    Measured on the Gauss–Newton systems of Manhattan worlds (2 cores): 0.33-0.42 s per
    numerical factorization at 10^5 poses, where qdldl takes 2.3 s and PARDISO 0.30-1.25 s.
    """

    _OPTIONS = {"supernodal": 2, "postorder": True}

    def __init__(self, U, ordering=None, dtype=float):
        import cvxopt
        from cvxopt import cholmod

        self._cholmod, self._matrix = cholmod, cvxopt.matrix
        # real symmetric, or complex Hermitian (L L^H; U's values then enter conjugated: row j
        # of the upper triangle, read as column j of the lower one)
        self.dtype = np.dtype(dtype)
        N = self.n = U.shape[0]
        cols = np.repeat(np.arange(N, dtype=np.int64), np.diff(U.indptr))
        one = 1.0 + 0.0j if self.dtype.kind == "c" else 1.0
        self._A = cvxopt.spmatrix(one, U.indices.astype(np.int64), cols, (N, N))
        if len(self._A.V) != U.nnz:  # pragma: no cover - cvxopt keeps the triplets' pattern
            raise BackendError("sparse Cholesky (CHOLMOD): cvxopt changed the pattern")
        options, given = dict(self._OPTIONS), {}
        if ordering is not None:
            options["nmethods"] = 1  # the given ordering only
            given["p"] = cvxopt.matrix(np.ascontiguousarray(ordering, dtype=np.int64), tc="i")
        with self._options(options):
            self._F = cholmod.symbolic(self._A, uplo="L", **given)
        self.perm = None  # CHOLMOD's final order (after its postordering), once factored

    def _options(self, options):
        """cvxopt's module-wide ``cholmod.options``, set for one call and restored; one thread at
        a time (a lock), or two overlapping scopes would leave lagolib's options behind."""
        from contextlib import contextmanager

        @contextmanager
        def scope():
            with _CHOLMOD_LOCK:
                saved = dict(self._cholmod.options)
                self._cholmod.options.clear()
                self._cholmod.options.update(options)
                try:
                    yield
                finally:
                    self._cholmod.options.clear()
                    self._cholmod.options.update(saved)

        return scope()

    def factor(self, data, hdiag, pivot_tol=None):
        """Numerical factorization of ``data`` (``U``'s values; conjugated for a complex
        Hermitian matrix) with ``hdiag`` its diagonal; NotPositiveDefiniteError when a pivot is
        not positive (CHOLMOD's ``ArithmeticError``) or below ``pivot_tol`` (default
        :data:`PIVOT_TOL`) of its diagonal entry."""
        self._A.V = self._matrix(np.ascontiguousarray(data, dtype=self.dtype))
        with self._options(self._OPTIONS):
            try:
                self._cholmod.numeric(self._A, self._F)
            except ArithmeticError as exc:
                raise self._breakdown(exc.args[0] if exc.args else None) from None
            if self.perm is None:
                B = self._matrix(np.arange(self.n, dtype=self.dtype))
                self._cholmod.solve(self._F, B, sys=7)  # P applied to 0..N-1: the final order
                self.perm = np.array(B).ravel().real.astype(np.int64)
            d = np.array(self._cholmod.diag(self._F)).ravel().real ** 2  # diag(L)^2: pivots D
        _check_pivots(d, hdiag[self.perm], self.perm, "CHOLMOD", pivot_tol)

    def _breakdown(self, k):
        """NotPositiveDefiniteError for CHOLMOD's failure at step ``k`` of its elimination order:
        the row of ``H`` when the order is known (from an earlier factorization of the pattern)."""
        if isinstance(k, int) and self.perm is not None and 0 <= k < self.n:
            row = int(self.perm[k])
            return NotPositiveDefiniteError(
                f"sparse Cholesky (CHOLMOD): the pivot at row {row} is not positive; the matrix "
                "is singular or indefinite",
                pivot=row,
            )
        return NotPositiveDefiniteError(
            f"sparse Cholesky (CHOLMOD): the pivot at step {k} of its elimination order is not "
            "positive; the matrix is singular or indefinite"
        )

    def solve(self, b):
        """``H^-1 b`` for ``b`` of shape (N,) or (N, k)."""
        B = self._matrix(np.asfortranarray(b, dtype=self.dtype))
        with self._options(self._OPTIONS):
            self._cholmod.solve(self._F, B)
        return np.array(B).reshape(b.shape)

    nnz_L = 0  # not exposed (reading it would turn the factor simplicial)


class SparseCholesky:
    """Factorization of a sparse symmetric positive-definite matrix, for repeated solves.

    Parameters
    ----------
    H : scipy.sparse matrix, shape (N, N)
        Symmetric positive definite; both triangles stored (only the upper one is read).
    backend : {"auto", "qdldl", "pardiso", "cholmod", "scipy"}
        ``"auto"``: from :data:`PARDISO_MIN_SIZE` rows (``auto_rows``) up, a supernodal
        factorization — PARDISO when MKL is installed (``pip install "lagolib[fast]"``), else
        CHOLMOD when cvxopt is (``pip install "lagolib[cholmod]"``) — and qdldl otherwise; the
        same supernodal backend from the second factorization on when qdldl's first one cost
        :data:`PARDISO_MIN_MFLOP` or more (fill from long loop closures).
    check : bool
        Check that ``H`` (and every later one given to :meth:`refactor`) is finite and
        symmetric — ``O(nnz)``; lagolib's optimizer, which builds ``H`` symmetric, skips it.
    ordering : array_like of int, shape (N,), or callable, optional
        An elimination order (row ``k`` of the factor is row ``ordering[k]`` of ``H``), e.g. a
        pose graph's :func:`elimination_ordering` expanded to its unknowns
        (:func:`expand_ordering`): computed once per graph, not once per matrix, and stable on
        long chains.  PARDISO, CHOLMOD and SuperLU factor in it; qdldl computes its own (AMD) and, if that
        breaks down, hands the matrix to SuperLU in this order (:class:`lagolib.BackendWarning`).
        A callable returning it (or None) is called only when it is needed.
    auto_rows : int or callable, optional
        For ``backend="auto"``: the rows that decide (default ``N``) — a pose graph's 2-core's
        (:func:`core_size`), since its tree-like parts cost no fill on any backend.  A callable
        is called only for systems of at least :data:`PARDISO_MIN_SIZE` rows.

    Attributes
    ----------
    backend : str
        The backend in use (``"auto"`` resolved).
    ordering : ndarray of int or None
        The ordering PARDISO, CHOLMOD or SuperLU factors in (PARDISO: the one given, or METIS's
        after the first factorization); None on qdldl, which orders by AMD inside.
    nnz_L : int
        Entries of the factor ``L``, diagonal included: the fill its ordering leaves (0 for
        SuperLU, which stores ``L`` and ``U`` together, and for CHOLMOD, whose supernodal factor
        cvxopt does not report).
    mflops : float or None
        qdldl's cost of one factorization in Mflop (``sum_j c_j^2``, ``c_j`` the entries of
        column ``j`` of ``L``), from its first factorization of a pattern; None on the other
        backends.
    fallback : str or None
        Why the supernodal backend (PARDISO or CHOLMOD) was replaced by qdldl (its factorization
        broke down, or its solution failed the check after refinement), or why qdldl was replaced
        by SuperLU in the given ordering; None while the first backend serves.
    last_check : SolveCheck or None
        How the last :meth:`solve` was checked: backward error, residual, refinement steps.

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

    Warns
    -----
    BackendWarning
        PARDISO's factorization broke down, or its solution stayed inaccurate after refinement,
        on a matrix qdldl factors: this object solves with qdldl from then on.

    Notes
    -----
    A fast backend is never trusted blindly: every :meth:`solve` is checked by its backward error
    and refined (see there).  A factorization that fails leaves nothing usable: :meth:`solve`
    raises until :meth:`refactor` succeeds.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> H = sp.csc_matrix(np.array([[4.0, 1.0], [1.0, 3.0]]))
    >>> SparseCholesky(H).solve(np.array([1.0, 2.0])).round(6)
    array([0.090909, 0.636364])
    """

    def __init__(self, H, backend="auto", *, check=True, ordering=None, auto_rows=None):
        backend = check_choice(backend, "backend", "SparseCholesky", ("auto",) + BACKENDS)
        self._check = check_bool(check, "check", "SparseCholesky")
        _check_square(H, "SparseCholesky", check=False)
        if auto_rows is not None and not callable(auto_rows):
            check_int(auto_rows, "auto_rows", "SparseCholesky", minimum=0)
        self._auto = backend == "auto"  # may move to PARDISO after a costly first factor
        self._next_backend = None
        self.mflops = None
        if backend == "auto":
            backend = _auto_backend(H.shape[0], auto_rows)
        elif backend == "pardiso" and _mkl_runtime() is None:
            raise OptionError(
                f"SparseCholesky: backend='pardiso' needs Intel MKL, but {_MKL['why']}; install it "
                "with pip install \"lagolib[fast]\" or use backend='qdldl'"
            )
        elif backend == "cholmod" and not _have_cholmod():
            raise OptionError(
                "SparseCholesky: backend='cholmod' needs CHOLMOD from cvxopt, which is not "
                "installed (or hidden by LAGOLIB_CHOLMOD=off); install it with pip install "
                "\"lagolib[cholmod]\" or use backend='qdldl'"
            )
        self.backend = backend
        self.shape = H.shape
        if ordering is not None and not callable(ordering):
            ordering = _check_ordering(ordering, H.shape[0])  # checked now, whoever uses it
        self._ordering_source = ordering  # an array, or a callable computing it on first use
        self.ordering = None
        if backend in ("pardiso", "cholmod", "scipy"):
            self.ordering = self._given_ordering()
        self.nnz_L = 0
        self.fallback = None
        self.last_check = None
        self._solver = None
        self._pattern = None
        self._residual = self._triangle = None
        self._failed = "it was never factored"
        self.refactor(H)

    def refactor(self, H):
        """Factor a new matrix with the same shape (and, for speed, the same sparsity pattern).

        If the factorization fails (an exception), the object holds no usable factor: every
        :meth:`solve` raises until a later ``refactor`` succeeds.
        """
        self._failed = "its last factorization failed"  # until this one has succeeded
        self._residual = self._triangle = None
        _check_square(H, "SparseCholesky", check=self._check)
        if H.shape != self.shape:
            raise OptionError(f"SparseCholesky.refactor needs shape {self.shape}; got {H.shape}")
        if self.shape[0] == 0:
            self._failed = None
            return self
        H = H if H.format == "csr" and H.dtype == np.float64 else sp.csr_matrix(H, dtype=float)
        if not H.has_canonical_format:  # sorted, and duplicate entries summed (scipy's meaning
            H = H.copy()  # of them): every backend reads one value per stored position
            H.sum_duplicates()
        if self._next_backend is not None:  # qdldl's first factorization was costly
            self.backend, self._next_backend = self._next_backend, None
            self._solver = self._pattern = None
            self.ordering = self._given_ordering()
        if self.backend == "scipy":
            self._factor_scipy(H)
        else:
            self._factor_triangle(H)
        # what was factored, for every solve's check: the triangle the backend was given (no
        # copy: a fresh gather per refactor), or H's upper triangle for SuperLU
        self._residual = (
            _Upper(H)
            if self._triangle is None
            else _Upper(U=self._triangle[0], d=self._triangle[1])
        )
        self._failed = None
        return self

    def release(self):
        """Free the numerical factor and keep the symbolic analysis, when the backend keeps
        them apart (PARDISO): memory for work between two factorizations (lagolib.certify.solve
        frees Gauss–Newton's factor while its certificate factors another matrix).  The next
        :meth:`refactor` factors again; until then :meth:`solve` raises.  On qdldl, CHOLMOD (as
        cvxopt holds it) and SuperLU, whose analysis lives in their factor, nothing is freed and
        the factor stays usable."""
        if self.backend == "pardiso" and self._solver is not None and self._failed is None:
            self._solver.release()
            self._residual = self._triangle = self._data = None
            self._failed = "its factor was released (release())"
        return self

    def _given_ordering(self):
        """The ordering passed in (a callable is called once), checked; None when there is none."""
        src = self._ordering_source
        if callable(src):
            src = self._ordering_source = src()
        return None if src is None else _check_ordering(src, self.shape[0])

    def _factor_triangle(self, H):
        """qdldl or PARDISO on the upper triangle of ``H`` (CSR, sorted, float64)."""
        same = self._pattern is not None and (
            (_same_frozen(H.indptr, self._pattern[0]) and _same_frozen(H.indices, self._pattern[1]))
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
        U = sp.csc_matrix if self.backend == "qdldl" else sp.csr_matrix
        U = U((data, indices, indptr), shape=self.shape)
        self._triangle = (U, d)  # d: H's diagonal, the triangle's
        if self.backend == "qdldl":
            try:
                self._factor_qdldl(U, same, d)
            except NotPositiveDefiniteError as exc:
                self._fall_back_to_ordered(H, exc)
                return
        else:
            try:
                if not same and self.backend == "pardiso":
                    self._solver = _Pardiso(U, self.ordering)
                    self.ordering = self._solver.ordering.astype(np.int64)
                elif not same:
                    self._solver = _Cholmod(U, self.ordering)
                self._data = data
                if self.backend == "pardiso":
                    self._solver.factor(data)
                else:
                    self._solver.factor(data, d)
            except NotPositiveDefiniteError as exc:
                self._fall_back(H, f"broke down ({exc})")
                return
            self.nnz_L = self._solver.nnz_L
        # frozen index arrays (LinearSystem's) are kept, not copied: O(nnz) memory at 10^6
        # poses; writable ones are copied, or rewriting them in place would go unnoticed
        self._pattern = tuple(a if _frozen(a) else a.copy() for a in (H.indptr, H.indices))

    def _fall_back(self, H, why):
        """Factor ``H`` with qdldl instead of PARDISO (or CHOLMOD), from now on, and warn (once
        per object).

        PARDISO's factorization can break down on a positive-definite matrix (its nested
        dissection cuts long odometry chains, whose separators' Schur complements cancel) and its
        solution can stay inaccurate after refinement; qdldl (AMD) eliminates such chains from
        their ends.  When qdldl fails too, ``H`` is not positive definite: its error is raised and
        the fast backend stays.
        """
        fast, ordering = self.backend, self.ordering
        self.backend, self._solver, self._pattern = "qdldl", None, None
        self._auto, self._next_backend = False, None  # never back to the fast backend
        try:
            self._factor_triangle(H)
        except NotPositiveDefiniteError:  # qdldl agrees: H is not positive definite
            # the fast backend stays, in its ordering (the caller's, or the one it computed)
            self.backend, self.ordering, self._solver, self._pattern = fast, ordering, None, None
            self._failed = f"{_NAMES[fast]} {why}, and qdldl could not factor the matrix either"
            raise
        if self.backend == "qdldl":  # (else qdldl broke down too and SuperLU took over, warned)
            self.fallback = (
                f"{_NAMES[fast]} {why}; qdldl factored the same matrix and solves with it"
            )
            warnings.warn(f"SparseCholesky: {self.fallback}", BackendWarning, stacklevel=4)

    def _fall_back_to_ordered(self, H, exc):
        """qdldl (AMD) broke down: SuperLU in the given, stable ordering, if there is one.

        AMD may eliminate a long chain toward its anchor (see :func:`elimination_ordering`); the
        caller's ordering eliminates away from it.  Without an ordering, or when SuperLU breaks
        down too, ``exc`` is raised: the matrix is not positive definite.
        """
        order = self._given_ordering()
        if order is None:
            raise exc
        previous, previous_order = self.backend, self.ordering
        self.backend, self.ordering, self._solver, self._pattern = "scipy", order, None, None
        try:
            self._factor_scipy(H)
        except NotPositiveDefiniteError:
            self.backend, self.ordering = previous, previous_order
            raise exc from None
        self.fallback = (
            f"{previous} (AMD ordering) broke down ({exc}); SuperLU factored the same matrix in "
            "the caller's elimination order and solves with it"
        )
        warnings.warn(f"SparseCholesky: {self.fallback}", BackendWarning, stacklevel=5)

    def _factor_qdldl(self, U, same, hdiag):
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
        _check_pivots(d, hdiag[perm], perm, "qdldl")
        if not same:  # the factorization's cost, sum_j c_j^2 over L's columns
            counts = np.diff(L.indptr).astype(np.float64)
            self.mflops = float(np.sum(counts * counts)) / 1e6
            if self._auto and self.mflops >= PARDISO_MIN_MFLOP and self.fallback is None:
                self._next_backend = _fast_backend()

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
        self._usable("SparseCholesky.factors")
        if self.shape[0] == 0:
            return sp.csc_matrix(self.shape), np.zeros(0), np.zeros(0, dtype=np.int64)
        L, d, perm = self._solver.factors()
        L = sp.csc_matrix(L)
        L.sort_indices()
        return L, np.asarray(d, dtype=float), np.asarray(perm, dtype=np.int64)

    def _factor_scipy(self, H):
        self._solver = None
        order = self.ordering
        if order is not None:  # SuperLU in the given order: H permuted, no ordering of its own
            H = H[order][:, order]
        try:
            with single_threaded_blas():
                lu = spla.splu(
                    H.tocsc(),
                    permc_spec="MMD_AT_PLUS_A" if order is None else "NATURAL",
                    diag_pivot_thresh=0.0,
                    options={"SymmetricMode": True},
                )
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise NotPositiveDefiniteError(
                f"sparse Cholesky (SuperLU) failed: {exc}; the matrix is singular"
            ) from None
        rows = lu.perm_c if order is None else order[lu.perm_c]  # rows of the caller's H
        _check_pivots(lu.U.diagonal(), H.diagonal()[lu.perm_c], rows, "SuperLU")
        self._solver = lu if order is None else _Permuted(lu, order)

    def _usable(self, where):
        if self._failed is not None:
            raise NotPositiveDefiniteError(
                f"{where}: no usable factor: {self._failed}; call refactor() with a symmetric "
                "positive-definite matrix first"
            )

    def _solve_once(self, b):
        """One forward and back substitution with the backend's factor (no check)."""
        if self.backend == "pardiso":
            return self._solver.solve(self._data, b)
        if self.backend == "cholmod":
            return self._solver.solve(b)
        if self.backend == "qdldl" and b.ndim == 2:
            return np.column_stack([self._solver.solve(col) for col in b.T]).reshape(b.shape)
        return self._solver.solve(b)

    def solve(self, b):
        """Solve ``H x = b``, checked by its backward error and refined.

        After the backend's substitutions, the componentwise backward error
        ``omega = max_i |b - H x|_i / (|H| |x| + |b|)_i`` (Oettli and Prager 1964) is computed and
        ``x`` is refined, ``x += F^-1 (b - H x)``, while ``omega`` exceeds
        :data:`REFINE_TARGET` and halves at each step (at most :data:`MAX_REFINEMENT_STEPS`).  A
        solution whose ``omega`` stays above :data:`BACKWARD_ERROR_TOL` is never returned:
        PARDISO's is recomputed with qdldl (a :class:`lagolib.BackendWarning` says so), qdldl's
        and SuperLU's raise.  :attr:`last_check` records the outcome.

        Parameters
        ----------
        b : array_like, shape (N,) or (N, k)

        Returns
        -------
        ndarray, same shape as ``b``

        Raises
        ------
        NotPositiveDefiniteError
            The last factorization failed (there is no factor to solve with), or the solution
            overflows or stays inaccurate: ``H`` is numerically singular.

        References
        ----------
        W. Oettli, W. Prager, "Compatibility of approximate solution of linear equations with
        given error bounds for coefficients and right-hand sides", Numer. Math. 6, 1964.
        N. J. Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., SIAM 2002, §12.
        """
        b = _check_rhs(b, self.shape[0], "SparseCholesky.solve")
        self._usable("SparseCholesky.solve")
        if b.size == 0:
            return np.zeros(b.shape)
        x = self._solve_once(b)
        if not np.all(np.isfinite(x)):
            if self.backend in ("pardiso", "cholmod"):
                self._fall_back(self._residual.matrix(), "returned a solution that is not finite")
                return self.solve(b)
            raise NotPositiveDefiniteError(
                f"sparse Cholesky ({self.backend}): the solution overflows float64; the matrix "
                "is numerically singular (pivots too small, e.g. information underflowing to zero)"
            )
        x, check = self._refine(b, x)
        if not check.backward_error <= BACKWARD_ERROR_TOL:
            why = (
                f"left a backward error of {check.backward_error:.2g} after "
                f"{check.refinement_steps} refinement steps"
            )
            if self.backend in ("pardiso", "cholmod"):
                self._fall_back(self._residual.matrix(), why)
                return self.solve(b)
            if self.backend == "qdldl" and self._given_ordering() is not None:
                self._fall_back_to_ordered(
                    self._residual.matrix(), NotPositiveDefiniteError(f"its solve {why}")
                )
                return self.solve(b)
            raise NotPositiveDefiniteError(
                f"sparse Cholesky ({self.backend}): the solution's backward error is "
                f"{check.backward_error:.2g} after {check.refinement_steps} refinement steps "
                f"(accepted: {BACKWARD_ERROR_TOL:g}); the matrix is numerically singular"
            )
        self.last_check = check
        return x

    def _refine(self, b, x):
        """Iterative refinement of ``x`` while its backward error halves; ``(x, SolveCheck)``."""
        r, scale, omega = _backward_error(self._residual, x, b)
        steps = 0
        while omega > REFINE_TARGET and steps < MAX_REFINEMENT_STEPS:
            x1 = x + self._solve_once(r) / scale  # x += F^-1 (b - H x)
            r1, scale1, omega1 = _backward_error(self._residual, x1, b)
            if not omega1 < omega:  # no progress: keep the better solution
                break
            steps += 1
            halved = omega1 <= 0.5 * omega
            x, r, scale, omega = x1, r1, scale1, omega1
            if not halved:
                break
        bs = b * scale  # the residual's scale: norms without overflow
        bnorm, rnorm = _norm2(bs), _norm2(r)
        rel = rnorm / bnorm if bnorm else (np.inf if rnorm else 0.0)
        return x, SolveCheck(self.backend, float(omega), rel, steps)


def _norm2(v):
    """``||v||_2`` (Frobenius for a matrix) by a ufunc sum, not BLAS: ``np.linalg.norm`` calls a
    multi-threaded ``dot`` that, beside another job on the same cores, took 5 ms per call on a
    3 x 10^4 vector (measured)."""
    return float(np.sqrt(np.sum(np.square(v))))


class _Permuted:
    """A factor of ``H[order][:, order]`` that solves with ``H``: ``x[order] = F^-1 b[order]``."""

    def __init__(self, lu, order):
        self.lu, self.order = lu, order

    def solve(self, b):
        x = np.empty_like(b)
        x[self.order] = self.lu.solve(np.ascontiguousarray(b[self.order]))
        return x


@dataclass(frozen=True)
class SolveCheck:
    """How :meth:`SparseCholesky.solve` checked its last solution.

    Attributes
    ----------
    backend : str
        The backend that solved (``"qdldl"`` after a fall-back).
    backward_error : float
        ``max_i |b - H x|_i / (|H| |x| + |b|)_i`` of the returned ``x``.
    relative_residual : float
        ``||b - H x|| / ||b||`` (0 for ``b = 0``).
    refinement_steps : int
        Steps of iterative refinement taken.
    """

    backend: str
    backward_error: float
    relative_residual: float
    refinement_steps: int


class _Upper:
    """``H`` held as its upper triangle ``U`` (a private copy) for the solve's check.

    ``H x = U x + U^T x - d x`` and ``|H| |x|`` likewise: what was factored, whatever the caller
    does to its own array afterwards, in half the memory of ``H``.
    """

    def __init__(self, H=None, *, U=None, d=None):
        if U is None:  # from H (CSR): its upper triangle, copied
            U = sp.triu(H, format="csr")
            U.sort_indices()
            d = U.diagonal()
        self.U, self.d = U, d  # or the triangle a backend was given (CSR or CSC) and its diagonal

    @cached_property
    def _T(self):
        """``U^T`` (the same arrays, read the other way), built once: every solve's check
        multiplies with it twice or more."""
        return self.U.T

    @cached_property
    def _abs(self):
        """``(|U|, |U|^T, |d|)`` when ``U`` is small enough to hold ``|U|`` whole (at most
        ``_ABS_CHUNK`` entries), else None (:func:`_abs_dot` then works in chunks)."""
        U = self.U
        if U.nnz > _ABS_CHUNK:
            return None
        A = type(U)((np.abs(U.data), U.indices, U.indptr), shape=U.shape)  # U's index arrays
        return A, A.T, np.abs(self.d)

    def matvec(self, x):
        d = self.d if x.ndim == 1 else self.d[:, None]
        return self.U @ x + self._T @ x - d * x

    def absvec(self, v):
        held = self._abs
        if held is not None:
            A, AT, ad = held
            return A @ v + AT @ v - (ad if v.ndim == 1 else ad[:, None]) * v
        d = np.abs(self.d) if v.ndim == 1 else np.abs(self.d)[:, None]
        csc = self.U.format == "csc"  # U^T is then CSR, and the other way round
        return (
            _abs_dot(self.U, v, by_columns=csc) + _abs_dot(self._T, v, by_columns=not csc) - d * v
        )

    def matrix(self):
        """``H`` again (CSR, both triangles), for a fall-back's factorization."""
        H = (self.U + self.U.T - sp.diags(self.d)).tocsr()
        H.sort_indices()
        return H


#: Stored entries up to which a solve's check holds ``|U|`` whole (above: in chunks).
_ABS_CHUNK = 1 << 22


def _abs_dot(M, v, *, by_columns=False, chunk=_ABS_CHUNK):
    """``|M| @ v`` without holding ``|M|`` whole: ``M`` CSR (rows in chunks) or CSC
    (``by_columns``), chunks of about ``chunk`` stored entries, so the memory is bounded."""
    if M.nnz <= chunk:
        cls = sp.csc_matrix if by_columns else sp.csr_matrix
        return cls((np.abs(M.data), M.indices, M.indptr), shape=M.shape) @ v
    N, K = M.shape
    out = np.zeros((N,) + v.shape[1:])
    major = K if by_columns else N
    step = max(1, int(chunk * major // M.nnz))
    for c0 in range(0, major, step):
        c1 = min(major, c0 + step)
        a, z = M.indptr[c0], M.indptr[c1]
        parts = (np.abs(M.data[a:z]), M.indices[a:z], M.indptr[c0 : c1 + 1] - a)
        if by_columns:
            out += sp.csc_matrix(parts, shape=(N, c1 - c0)) @ v[c0:c1]
        else:
            out[c0:c1] = sp.csr_matrix(parts, shape=(c1 - c0, K)) @ v
    return out


def _backward_error(H, x, b):
    """``(r, s, omega)``: the residual ``r = s (b - H x)``, its scale ``s`` and the componentwise
    backward error ``omega``.

    ``omega = max_i |r_i| / (|H| |x| + |b|)_i`` (Oettli–Prager): the smallest relative change of
    the entries of ``H`` and ``b`` for which ``x`` is the exact solution.  Scale-invariant, unlike
    ``||r|| / ||b||``, which for a correct solve of a 6 x 10^4-pose chain is 7e-5 and for
    PARDISO's wrong one of a 4 x 10^4-pose LAGO system 1e-12.  ``x`` and ``b`` are first scaled
    by a power of two ``s`` (exact) to at most 1 in magnitude, so that nothing overflows (at
    ``|b| ~ 1e308``, ``|H||x| + |b|`` was ``inf`` and every answer passed); a denominator or
    residual that is not finite gives ``omega = inf``.  ``H`` is an :class:`_Upper`.
    """
    top = max(float(np.max(np.abs(x), initial=0.0)), float(np.max(np.abs(b), initial=0.0)))
    if top == 0.0:
        return np.zeros_like(b), 1.0, 0.0
    s = 2.0 ** -int(np.frexp(top)[1]) if np.isfinite(top) else 1.0
    xs, bs = x * s, b * s
    with np.errstate(over="ignore", invalid="ignore"):
        r = bs - H.matvec(xs)
        denom = H.absvec(np.abs(xs)) + np.abs(bs)
    a = np.abs(r)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(denom > 0, a / np.where(denom > 0, denom, 1.0), np.where(a > 0, np.inf, 0))
    ratio[~(np.isfinite(a) & np.isfinite(denom))] = np.inf
    return r, s, float(ratio.max()) if ratio.size else 0.0


def _rows_key(rows):
    """Rows of a graph as bytes: part of the key of a structural cache entry
    (``PoseGraph._structural``), e.g. the fixed poses of an elimination ordering."""
    return np.sort(np.asarray(rows, dtype=np.int64)).tobytes()


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
    rows together.  On its own it is not safe for pose graphs: a separator that cuts a long
    odometry chain makes the factorization cancel (see :func:`elimination_ordering`, which uses it
    for the cycles only, and which lagolib's Gauss–Newton and LAGO compute once per graph).

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


def elimination_ordering(pattern, anchored=()):
    """A pose order for sparse Cholesky that is stable on long chains and sparse elsewhere.

    Elimination must run *away from the anchor*.  Eliminating a pose whose remaining neighbours
    carry no other information (a leaf pointing away from the anchor) leaves its neighbour's
    Schur complement exactly its own measurements' information: nothing cancels.  Eliminating
    toward the anchor, or the inside of a long chain before its ends (which nested dissection
    does when a separator cuts a chain), builds the information *between* distant poses — about
    ``1/L^3`` of one edge's after ``L`` poses, because heading errors act through lever arms — as
    differences of numbers of order one: on a 6 x 10^4-pose chain the pivots fell to 1e-10 and
    below zero (PARDISO, qdldl and SuperLU each broke down or answered wrongly, depending on their
    orderings), while away from the anchor they stay at the edges' own information.

    So: the 2-core of the pose graph (every pose on a cycle or between cycles) is ordered by
    nested dissection (METIS, :func:`fill_reducing_ordering`; AMD from qdldl without MKL)
    and contracted to one node; the rest is a forest that, rooted at the anchored poses, is
    eliminated children before parents (by decreasing depth), the core at its own depth.

    Parameters
    ----------
    pattern : scipy.sparse matrix, shape (n, n)
        Symmetric pattern of the pose graph of the unknown poses (values ignored, diagonal too).
    anchored : array_like of int
        Poses with information of their own: next to a fixed pose, or with a prior.  Without any,
        the core (or pose 0) is the root.

    Returns
    -------
    ndarray of int, shape (n,)
        Row ``k`` of the reordered matrix is pose ``perm[k]``; expand it to the unknowns with
        :func:`expand_ordering`.

    Examples
    --------
    A chain of five poses anchored at pose 0 is eliminated from its far end:

    >>> import scipy.sparse as sp
    >>> chain = sp.diags([1.0, 1.0], [-1, 1], shape=(5, 5))
    >>> elimination_ordering(chain, anchored=[0]).tolist()
    [4, 3, 2, 1, 0]
    """
    from scipy.sparse import csgraph

    where = "elimination_ordering"
    _check_pattern(pattern, where)
    n = pattern.shape[0]
    A = _adjacency(pattern)
    core = _two_core(A.indptr, A.indices, n)
    anchored = _check_rows(anchored, n, "anchored", where)
    # contract the core to node ``n``; add a virtual root ``n + 1`` joined to every anchored pose
    label = np.arange(n + 2)
    label[:n][core] = n
    rows = np.repeat(np.arange(n), np.diff(A.indptr))
    i, j = label[rows], label[A.indices]
    roots = label[anchored] if anchored.size else np.array([n if core.any() else 0])
    i = np.concatenate([i, np.full(roots.size, n + 1)])
    j = np.concatenate([j, roots])
    keep = i != j
    G = sp.csr_matrix((np.ones(keep.sum()), (i[keep], j[keep])), shape=(n + 2, n + 2))
    _, pred = csgraph.breadth_first_order(G, n + 1, directed=False, return_predecessors=True)
    parent = np.where(pred >= 0, pred, np.arange(n + 2))  # unreachable nodes: their own roots
    depth = _depths(parent)
    within = np.arange(n)  # the order inside the core: nested dissection
    if core.any():
        members = np.flatnonzero(core)
        sub = A[members][:, members]
        inner = fill_reducing_ordering(sub)
        if inner is None:  # no MKL: qdldl's AMD on a diagonally dominant matrix of the pattern
            inner = _amd_ordering(sub)
        within[members[inner]] = np.arange(members.size)
    return np.lexsort((within, -depth[label[:n]])).astype(np.int64)


def _amd_ordering(pattern):
    """qdldl's AMD ordering of a symmetric pattern (that of ``deg + 1`` on the diagonal, ``-1`` off
    it: strictly diagonally dominant, so its factorization cannot fail)."""
    import qdldl

    P = sp.csr_matrix(pattern, dtype=float, copy=True)
    P.data[:] = -1.0
    P.setdiag(0.0)
    P.eliminate_zeros()
    M = P + sp.diags(np.diff(P.indptr) + 1.0)
    _, _, perm = qdldl.Solver(sp.triu(M, format="csc"), upper=True).factors()
    return np.asarray(perm, dtype=np.int64)


def _check_pattern(pattern, where):
    """A square, real scipy.sparse pattern, or an OptionError/OptionTypeError naming it."""
    if not sp.issparse(pattern):
        raise OptionTypeError(
            f"{where}: pattern must be a scipy.sparse matrix; got {type(pattern).__name__}"
        )
    if pattern.ndim != 2 or pattern.shape[0] != pattern.shape[1]:
        raise OptionError(f"{where}: pattern must be square; got shape {pattern.shape}")
    if pattern.dtype.kind not in "biuf":
        raise OptionTypeError(f"{where}: pattern must be real; got dtype {pattern.dtype}")


def _check_rows(rows, n, name, where):
    """Integer row indices in ``[0, n)`` (unique, sorted), or an OptionError naming ``name``."""
    a = np.asarray(rows if rows is not None else "?", dtype=object).ravel()
    ok = all(isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)) for v in a)
    if not ok:
        raise OptionTypeError(f"{where}: {name} must be integer rows; got {rows!r}")
    a = a.astype(np.int64)
    if a.size and (a.min() < 0 or a.max() >= n):
        raise OptionError(f"{where}: {name} must be rows in [0, {n}); got {a.min()}..{a.max()}")
    return np.unique(a)


def core_size(pattern):
    """Number of poses in the 2-core of a pose graph's pattern: those on a cycle or between cycles.

    What is left after removing leaves (poses with one neighbour) repeatedly; the rest is a forest
    of tree-like parts (odometry chains), which every elimination order worth its name factors in
    O(n) with no fill.

    Parameters
    ----------
    pattern : scipy.sparse matrix, shape (n, n)
        Symmetric; values and diagonal ignored.

    Returns
    -------
    int

    Examples
    --------
    >>> import scipy.sparse as sp
    >>> core_size(sp.diags([1.0, 1.0], [-1, 1], shape=(6, 6)))  # a chain: no cycle
    0
    """
    _check_pattern(pattern, "core_size")
    A = _adjacency(pattern)
    return int(_two_core(A.indptr, A.indices, A.shape[0]).sum())


def _adjacency(pattern):
    """The symmetric 0/1 adjacency (CSR, no diagonal) of a pattern."""
    A = sp.csr_matrix(pattern, dtype=float, copy=True)
    A.data[:] = 1.0
    A = A + A.T
    A.setdiag(0.0)
    A.eliminate_zeros()
    return sp.csr_matrix(A, dtype=bool).astype(np.int8)


def _two_core(indptr, indices, n):
    """Mask of the poses in the 2-core: what is left after removing leaves repeatedly.

    A Python loop over the removed poses only (the tree-like parts), each visited once.
    """
    degree = np.diff(indptr).astype(np.int64)
    removed = np.zeros(n, dtype=bool)
    stack = np.flatnonzero(degree <= 1).tolist()
    indptr, indices = indptr.tolist(), indices.tolist()
    deg = degree.tolist()
    while stack:
        v = stack.pop()
        if removed[v]:
            continue
        removed[v] = True
        for u in indices[indptr[v] : indptr[v + 1]]:
            if not removed[u]:
                deg[u] -= 1
                if deg[u] == 1:
                    stack.append(u)
    return ~removed


def _depths(parent):
    """Number of steps from every node to its root (``parent[root] == root``), by pointer
    jumping: ``log2(max depth)`` vectorized rounds."""
    depth = (parent != np.arange(parent.size)).astype(np.int64)
    up = parent.copy()
    while True:
        nxt = up[up]
        moving = up != nxt
        if not moving.any():
            return depth
        depth = depth + np.where(moving, depth[up], 0)
        up = nxt


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


def _same_frozen(a, b):
    """``a`` and ``b`` view the same read-only memory (``b`` is kept alive, so its address is not
    reused): the same index arrays, which nobody can have rewritten in place since.

    LinearSystem hands every iteration's ``H`` the same index arrays, frozen (scipy wraps them in
    new views); recognizing them spares an ``O(nnz)`` comparison per factorization.  Writable
    arrays are compared by value: a caller may have changed the pattern in place.
    """
    return (
        _frozen(a)
        and _frozen(b)
        and a.shape == b.shape
        and a.dtype == b.dtype
        and a.strides == b.strides
        and a.ctypes.data == b.ctypes.data
    )


def _frozen(a):
    """``a`` and every array it views are read-only (none can be written through)."""
    while isinstance(a, np.ndarray):
        if a.flags.writeable:
            return False
        a = a.base
    return True


#: A pivot below this fraction of its row's diagonal entry means the matrix is numerically
#: singular (a weighted Laplacian without an anchor gives 1.7e-13; one anchored by 1e-6 gives
#: 4.6e-8; the pivots of odometry chains eliminated away from the anchor stay above 0.2): the
#: factorization is refused rather than solving with it (its solutions were 5e13 in size with
#: relative residuals of 0.01 to 13, yet backward errors of 1e-16).
PIVOT_TOL = 1e-12


def _check_pivots(d, diag, rows, backend, tol=None):
    """Every pivot ``d[k]`` positive and at least ``tol`` (default :data:`PIVOT_TOL`) of
    ``diag[k]`` (the diagonal entry of its row ``rows[k]`` of ``H``), or
    NotPositiveDefiniteError naming the row."""
    tol = PIVOT_TOL if tol is None else tol
    with np.errstate(divide="ignore", invalid="ignore"):
        ok = (d > 0) & (d >= tol * diag)
    bad = np.flatnonzero(~ok)
    if bad.size:
        k = bad[0]
        what = (
            "is not positive; the matrix is singular or indefinite"
            if not d[k] > 0
            else f"is {d[k] / diag[k]:.2g} of its diagonal entry; the matrix is numerically "
            "singular (e.g. a component without a gauge)"
        )
        raise NotPositiveDefiniteError(
            f"sparse Cholesky ({backend}): pivot {d[k]:.3g} at row {int(rows[k])} {what}",
            pivot=int(rows[k]),
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
    backend : {"auto", "qdldl", "pardiso", "cholmod", "scipy"}

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
