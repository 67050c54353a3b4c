"""Sparse symmetric positive-definite solves: Cholesky with pluggable backends, and PCG.

The lecture notes ("Consequences of the Sparsity") name the two ways to solve ``H dx = -b``:

1. **sparse Cholesky decomposition** — :class:`SparseCholesky` factors ``H = L D L^T`` after a
   fill-reducing ordering and then solves by two triangular substitutions.  Backends:

   ``"qdldl"``
       The QDLDL ``L D L^T`` factorization (OSQP's) with an AMD ordering; the symbolic analysis is
       kept, so :meth:`SparseCholesky.refactor` on a matrix with the same pattern is cheaper.
   ``"scipy"``
       SuperLU from :mod:`scipy.sparse.linalg` in symmetric mode (minimum degree on ``A + A^T``,
       diagonal pivots).  Always available.

   ``backend="auto"`` takes qdldl when it is installed (it is a dependency of lagolib) — on
   city10000's 30k x 30k system it is about 3x faster than SuperLU here
   (``benchmarks/bench_gauss_newton.py`` prints both).

2. **conjugate gradients** — :func:`pcg`, written out so that a chapter can count its
   iterations, with a Jacobi or 3x3 block-Jacobi preconditioner.

No function here forms a dense matrix.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .checks import check_bool, check_choice, check_int, check_real, real_array
from .errors import NotPositiveDefiniteError, OptionError, OptionTypeError

__all__ = [
    "SparseCholesky",
    "available_backends",
    "solve_spd",
    "pcg",
    "PCGResult",
]

BACKENDS = ("qdldl", "scipy")


def available_backends():
    """The Cholesky backends importable here, fastest first (``"scipy"`` is always there)."""
    out = []
    try:
        import qdldl  # noqa: F401

        out.append("qdldl")
    except ImportError:  # pragma: no cover - qdldl is a dependency
        pass
    out.append("scipy")
    return tuple(out)


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


class SparseCholesky:
    """Factorization of a sparse symmetric positive-definite matrix, for repeated solves.

    Parameters
    ----------
    H : scipy.sparse matrix, shape (N, N)
        Symmetric positive definite; both triangles stored (only the upper one is read by qdldl).
    backend : {"auto", "qdldl", "scipy"}
    check : bool
        Check that ``H`` (and every later one given to :meth:`refactor`) is finite and
        symmetric — ``O(nnz)``; lagolib's optimizer, which builds ``H`` symmetric, skips it.

    Raises
    ------
    OptionError, OptionTypeError
        ``H`` is not a square, finite, symmetric sparse matrix; unknown ``backend``.
    NotPositiveDefiniteError
        If a pivot of the factorization is not positive: ``H`` is singular or indefinite
        (for a pose graph: a pose or component without a gauge, see
        :func:`lagolib.gauss_newton.check_gauge`).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> H = sp.csc_matrix(np.array([[4.0, 1.0], [1.0, 3.0]]))
    >>> SparseCholesky(H).solve(np.array([1.0, 2.0])).round(6)
    array([0.090909, 0.636364])
    """

    def __init__(self, H, backend="auto", *, check=True):
        backend = check_choice(backend, "backend", "SparseCholesky", ("auto",) + BACKENDS)
        self._check = check_bool(check, "check", "SparseCholesky")
        _check_square(H, "SparseCholesky", check=False)
        if backend == "auto":
            backend = available_backends()[0]
        self.backend = backend
        self.shape = H.shape
        self._solver = None
        self.refactor(H)

    def refactor(self, H):
        """Factor a new matrix with the same shape (and, for speed, the same sparsity pattern)."""
        _check_square(H, "SparseCholesky", check=self._check)
        if H.shape != self.shape:
            raise OptionError(f"SparseCholesky.refactor needs shape {self.shape}; got {H.shape}")
        if self.shape[0] == 0:
            return self
        if self.backend == "qdldl":
            self._factor_qdldl(H)
        else:
            self._factor_scipy(H)
        return self

    def _factor_qdldl(self, H):
        import qdldl

        U = sp.triu(H, format="csc")
        try:
            same = (
                self._solver is not None
                and np.array_equal(U.indptr, self._pattern[0])
                and np.array_equal(U.indices, self._pattern[1])
            )
            if same:  # the symbolic analysis holds only for the same pattern
                self._solver.update(U, upper=True)
            else:
                self._solver = qdldl.Solver(U, upper=True)
        except (RuntimeError, ValueError):  # ValueError: qdldl's "Matrix A is empty" (H = 0)
            self._solver = None
            what = "the matrix is zero" if U.nnz == 0 else "the matrix is singular or indefinite"
            raise NotPositiveDefiniteError(f"sparse Cholesky (qdldl) failed: {what}") from None
        self._pattern = (U.indptr.copy(), U.indices.copy())
        _, d, perm = self._solver.factors()
        bad = np.flatnonzero(~(d > 0))
        if bad.size:
            raise NotPositiveDefiniteError(
                f"sparse Cholesky (qdldl): pivot {d[bad[0]]:.3g} at row {perm[bad[0]]} is not "
                "positive; the matrix is singular or indefinite",
                pivot=int(perm[bad[0]]),
            )

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
        if self.backend == "qdldl" and b.ndim == 2:
            x = np.column_stack([self._solver.solve(col) for col in b.T]).reshape(b.shape)
        else:
            x = self._solver.solve(b)
        if not np.all(np.isfinite(x)):
            raise NotPositiveDefiniteError(
                f"sparse Cholesky ({self.backend}): the solution overflows float64; the matrix "
                "is numerically singular (pivots too small, e.g. information underflowing to zero)"
            )
        return x


def solve_spd(H, b, backend="auto"):
    """Solve ``H x = b`` for sparse symmetric positive-definite ``H`` by sparse Cholesky.

    Parameters
    ----------
    H : scipy.sparse matrix, shape (N, N)
    b : array_like, shape (N,) or (N, k)
    backend : {"auto", "qdldl", "scipy"}

    Returns
    -------
    ndarray, same shape as ``b``
    """
    return SparseCholesky(H, backend).solve(b)


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
