"""Linear estimation: the best linear unbiased estimator and first-order uncertainty propagation.

The two tools LAGO is made of (Carlone et al. 2011, §IV):

- :func:`blue` — for the linear model ``z = H^T x + noise``, noise information ``Omega``
  (covariance ``P = Omega^-1``), the BLUE ``x̂ = (H Ω H^T)^-1 H Ω z`` with information
  ``H Ω H^T``.  Eq. (13) is the instance ``H = A``, ``z = δ``, ``Ω = P_δ^-1``; eq. (14) and (15)
  are two more.
- :func:`propagate_covariance` — ``P_y = J P_x J^T`` for ``y = g(x)`` linearized with Jacobian
  ``J`` (eq. 10–11), and :func:`joint_information`, the block inverse of the covariance of
  ``[a + J b; b]`` (§IV-D) that lets phase 2 stay in information form.

Everything is sparse; the estimate comes from a sparse Cholesky factorization
(:class:`lagolib.linalg.SparseCholesky`), and covariance *blocks* are computed on request by
solving against columns of the identity — no dense inverse.

References
----------
.. [1] J. M. Mendel, *Lessons in Estimation Theory for Signal Processing, Communications, and
   Control*, Prentice-Hall, 1995 (the BLUE).
.. [2] L. Carlone, R. Aragues, J. A. Castellanos, B. Bona, "A Linear Approximation for
   Graph-based Simultaneous Localization and Mapping", RSS 2011, eq. (10)–(15).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .checks import check_choice, real_array
from .errors import OptionError, OptionTypeError
from .linalg import BACKENDS, SparseCholesky

__all__ = ["BLUE", "blue", "information_form", "propagate_covariance", "joint_information"]


def _real_array(value, name, where):
    """A float csr matrix for sparse ``value``, else :func:`lagolib.checks.real_array`."""
    if not sp.issparse(value):
        return real_array(value, name, where)
    if np.iscomplexobj(value.data):
        raise OptionTypeError(f"{where}: {name} must be real; got complex values")
    return sp.csr_matrix(value, dtype=float)


def _check_finite(a, name, where):
    data = a.data if sp.issparse(a) else a
    if not np.all(np.isfinite(data)):
        raise OptionError(f"{where}: {name} has non-finite entries (nan or inf)")
    return a


def _as_information(information, size, where="information_form"):
    """A sparse (size, size) information matrix from a matrix or from its diagonal."""
    information = _check_finite(
        _real_array(information, "information", where), "information", where
    )
    if sp.issparse(information):
        W = information
    else:
        W = sp.diags(information) if information.ndim == 1 else sp.csr_matrix(information)
    if W.shape != (size, size):
        raise OptionError(
            f"{where}: the information matrix must have shape ({size}, {size}) (or ({size},) for "
            f"its diagonal) to match z; got {W.shape}"
        )
    return W


def information_form(H, z, information):
    """Normal equations of ``z = H^T x + noise``: ``(H Ω H^T, H Ω z)``.

    Parameters
    ----------
    H : scipy.sparse matrix, shape (N, M)
        Transposed design matrix: ``M`` measurements of ``N`` unknowns.
    z : array_like, shape (M,)
    information : scipy.sparse matrix or ndarray, shape (M, M) or (M,)
        ``Ω = P^-1``; a 1-D array is its diagonal.

    Returns
    -------
    I : scipy.sparse.csc_matrix, shape (N, N)
        Information of the estimate, ``H Ω H^T``.
    eta : ndarray, shape (N,)
        Information vector ``H Ω z``.
    """
    H, z, W = _measurement_model(H, z, information, "information_form")
    HW = H @ W
    return sp.csc_matrix(HW @ H.T), HW @ z


def _measurement_model(H, z, information, where):
    """``H`` (sparse), ``z`` and ``Ω`` (sparse) checked: real, finite, matching shapes."""
    H = _real_array(H, "H", where)
    H = _check_finite(H if sp.issparse(H) else sp.csr_matrix(np.atleast_2d(H)), "H", where)
    z = _check_finite(_real_array(z, "z", where), "z", where)
    if z.shape != (H.shape[1],):
        raise OptionError(
            f"{where}: z must have shape ({H.shape[1]},) to match H {H.shape}; got {z.shape}"
        )
    return H, z, _as_information(information, H.shape[1], where)


@dataclass(eq=False)
class BLUE:
    """A linear estimate in information form.

    Attributes
    ----------
    estimate : ndarray, shape (N,)
    information : scipy.sparse.csc_matrix, shape (N, N)
        The inverse of the estimate's covariance.
    factor : SparseCholesky
        Cholesky factorization of ``information``, reused by :meth:`covariance`.
    """

    estimate: np.ndarray
    information: sp.csc_matrix
    factor: SparseCholesky

    def covariance(self, rows=None):
        """Covariance block ``P[rows][:, rows]`` (the whole ``P`` when ``rows`` is None).

        Computed by solving ``I X = E_rows``: ``O(len(rows))`` sparse solves, never ``inv(I)``.

        Parameters
        ----------
        rows : array_like of int, optional

        Returns
        -------
        ndarray, shape (k, k)
        """
        N = self.information.shape[0]
        if rows is None:
            rows = np.arange(N)
        else:
            rows = np.atleast_1d(np.asarray(rows))
            if rows.dtype.kind not in "iu" or rows.ndim != 1:
                raise OptionTypeError(f"BLUE.covariance: rows must be integers; got {rows!r}")
            if rows.size and (rows.min() < -N or rows.max() >= N):
                raise OptionError(
                    f"BLUE.covariance: rows must lie in [0, {N}); got {rows.min()}..{rows.max()}"
                )
        E = np.zeros((N, rows.size))
        E[rows, np.arange(rows.size)] = 1.0
        X = self.factor.solve(E)
        P = X[rows]
        return 0.5 * (P + P.T)


def blue(H, z, information, *, backend="auto", ordering=None, start=None, auto_rows=None):
    """Best linear unbiased estimator of ``x`` from ``z = H^T x + noise``.

    ``x̂ = (H Ω H^T)^-1 H Ω z``, ``P_x̂ = (H Ω H^T)^-1``, with ``Ω = P^-1`` the noise information
    (Carlone et al. 2011, eq. (13) with ``H = A``, ``z = δ``, ``Ω = P_δ^-1``).

    Parameters
    ----------
    H : scipy.sparse matrix, shape (N, M)
    z : array_like, shape (M,)
    information : scipy.sparse matrix or ndarray, shape (M, M) or (M,)
        A 1-D array is the diagonal of ``Ω``.
    backend : {"auto", "qdldl", "pardiso", "cholmod", "scipy"}
        Sparse Cholesky backend.
    ordering : array_like of int, shape (N,), optional
        Fill-reducing ordering for PARDISO (:class:`lagolib.linalg.SparseCholesky`).
    auto_rows : int or callable, optional
        Rows that decide ``backend="auto"`` (:class:`lagolib.linalg.SparseCholesky`).
    start : array_like, shape (N,), optional
        A point near the estimate.  The normal equations are then solved for the correction,
        ``x̂ = x0 + (H Ω H^T)^-1 H Ω (z - H^T x0)``: the same estimate in exact arithmetic, and far
        more accurate when ``H Ω H^T`` is ill-conditioned and ``x0`` nearly explains ``z``.  LAGO
        starts from its spanning tree's composition: on a 4 x 10^4-pose chain (condition number
        about 5e17) the direct solve is wrong by 1e-3 to 1e-1 (it depends on the backend's
        rounding), the correction form exact to rounding.

    Returns
    -------
    BLUE

    Raises
    ------
    OptionError, OptionTypeError
        Non-finite, complex or mis-shaped ``H``, ``z`` or ``information``; unknown ``backend``.
    NotPositiveDefiniteError
        If ``H Ω H^T`` is singular: ``x`` is not observable from ``z`` (for orientations: the
        graph is disconnected or no node is anchored, Prop. 1).

    Examples
    --------
    Two noisy readings of one quantity, the second twice as precise:

    >>> import numpy as np, scipy.sparse as sp
    >>> est = blue(sp.csr_matrix([[1.0, 1.0]]), [1.0, 4.0], [1.0, 2.0])
    >>> est.estimate, est.covariance()
    (array([3.]), array([[0.33333333]]))
    """
    backend = check_choice(backend, "backend", "blue", ("auto",) + BACKENDS)
    H, z, W = _measurement_model(H, z, information, "blue")
    x = np.zeros(H.shape[0])
    if start is not None:
        x = _check_finite(_real_array(start, "start", "blue"), "start", "blue")
        if x.shape != (H.shape[0],):
            raise OptionError(f"blue: start must have shape ({H.shape[0]},); got {x.shape}")
    HW = H @ W
    info = sp.csc_matrix(HW @ H.T)
    factor = SparseCholesky(info, backend, ordering=ordering, auto_rows=auto_rows)
    return BLUE(_corrections(factor, H, HW, z, x), info, factor)


#: :func:`blue` refines its estimate by at most this many corrections from the measurement residual.
MAX_CORRECTIONS = 3


def _corrections(factor, H, HW, z, x):
    """``x += (H Ω H^T)^-1 H Ω (z - H^T x)`` until the correction stops shrinking.

    The first correction is the estimate (from ``x = 0``, or from ``start``); the next ones are
    iterative refinement of the *least-squares* problem: the residual ``z - H^T x`` is formed in
    measurement space, where it is small and well represented, not as ``H Ω z - (H Ω H^T) x``.
    On two 5000-pose chains joined at both ends (LAGO's phase 3) one solve left the poses 1e-7
    to 3e-6 from the exact BLUE, depending on the backend; the corrections reach 1e-13.
    """
    previous = np.inf
    for _ in range(1 + MAX_CORRECTIONS):
        dx = factor.solve(HW @ (z - H.T @ x))
        x = x + dx
        size = float(np.linalg.norm(dx))
        if size <= 4 * np.finfo(float).eps * float(np.linalg.norm(x)) or size > 0.5 * previous:
            break
        previous = size
    return x


def propagate_covariance(J, P):
    """First-order propagation of a covariance: ``P_y = J P_x J^T`` (Carlone et al. 2011, eq. 10).

    Parameters
    ----------
    J : ndarray or scipy.sparse matrix, shape (M, N)
        Jacobian of ``y = g(x)`` at the estimate (eq. 11 for LAGO's phase 2).
    P : ndarray or scipy.sparse matrix, shape (N, N)

    Returns
    -------
    ndarray or scipy.sparse matrix, shape (M, M)
        Sparse when both inputs are.
    """
    out = J @ P @ J.T
    return out if sp.issparse(out) else np.asarray(out)


def joint_information(W, J, Lam):
    """Information matrix of ``y = [a + J b; b]`` for independent ``a`` and ``b``.

    With ``P_a = W^-1`` and ``P_b = Λ^-1``, ``P_y = [[P_a + J P_b J^T, J P_b], [P_b J^T, P_b]]``
    (eq. 10 with the Jacobian ``[[I, J], [0, I]]``) and its inverse, by blockwise inversion, is
    (Carlone et al. 2011, §IV-D)::

        P_y^-1 = [[ W,        -W J          ],
                  [ -J^T W,   Λ + J^T W J   ]]

    so ``P_y`` never needs to be formed: all blocks stay as sparse as ``W``, ``J`` and ``Λ``.

    Parameters
    ----------
    W : scipy.sparse matrix, shape (M, M)
        Information of ``a`` (LAGO: ``P_Δg^-1``).
    J : scipy.sparse matrix, shape (M, N)
    Lam : scipy.sparse matrix, shape (N, N)
        Information of ``b`` (LAGO: ``P_θ̂^-1``).

    Returns
    -------
    scipy.sparse.csr_matrix, shape (M + N, M + N)
    """
    W, J, Lam = sp.csr_matrix(W), sp.csr_matrix(J), sp.csr_matrix(Lam)
    WJ = W @ J
    return sp.bmat([[W, -WJ], [-WJ.T, Lam + J.T @ WJ]], format="csr")
