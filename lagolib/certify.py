r"""Is it the global optimum?  The planar problem in complex form, a dual certificate, and escape.

Gauss–Newton (:func:`lagolib.optimize`) and LAGO find *an* answer; neither says whether it is the
best one.  On MIT, Gauss–Newton from odometry stops at χ² 770.66 where 41.16 is reachable, and its
last step is as small as at the true optimum.  This module answers the question with the duality
argument of Carlone, Rosen, Calafiore, Leonard and Dellaert (TRO 2016) and SE-Sync (Rosen,
Carlone, Bandeira and Leonard, IJRR 2019), written out for the plane:

1. **The chordal problem in complex form.**  A pose is ``t_i = x_i + i y_i`` and
   ``z_i = exp(i theta_i)`` (``|z_i| = 1``); a measurement is ``t~_ij`` and ``R~_ij =
   exp(i delta_ij)`` (frame ``i``).  The cost

   .. math:: f(x) = \sum_{ij} \kappa_{ij} |z_j - z_i \tilde R_{ij}|^2
                    + \tau_{ij} |t_j - t_i - z_i \tilde t_{ij}|^2 = x^H M x,
             \qquad x = [t; z] \in \mathbb{C}^{2n}

   is a Hermitian quadratic form (:func:`data_matrix`); all the non-convexity is in
   ``|z_i| = 1``.  SE-Sync's objective (its Problem 1) is the same with ``||R_j - R_i
   R~||_F^2 = 2 |z_j - z_i R~|^2``; :func:`chordal_problem` takes ``kappa = Omega_33`` and ``tau =
   2 / tr(Omega_tt^-1)`` from the g2o information, so ``f`` equals χ² to second order for
   isotropic information, and SE-Sync's objective is ``f`` of
   ``graph.with_information(metrics.sesync_weights(graph).information)``.
2. **A local solver** for ``f`` (:func:`refine`): Newton's method on ``(x, y, theta)`` with the
   exact Hessian ``2 Re(P^H S P)`` and Levenberg's damping (or Gauss–Newton on the chordal
   residuals) — the loop of :func:`lagolib.optimize`.
3. **The certificate** (:func:`certify`): at a stationary point the Lagrange multipliers of
   ``|z_i|^2 = 1`` are ``lambda_i = Re(conj(z_i) (M x)_{n+i})`` and
   ``S = M - blkdiag(0, diag(lambda))`` satisfies ``S x = 0``.  If ``S`` is positive
   semidefinite, ``x`` is a global minimum: for every feasible ``y``,
   ``y^H M y = y^H S y + sum(lambda) >= sum(lambda) = f(x)``.  Translations are free, so they are
   eliminated (``S~``, the Schur complement on the rotations); for every feasible ``y`` and
   *any* ``lambda``, ``f(y) >= sum(lambda) + n min(lambda_min(S~), 0)`` — a lower bound on the
   global optimum ``f*`` (weak duality), and ``f* >= 0`` too.  ``f(x)`` minus the bound is the
   *gap*: how far above ``f*`` the point can be.  The point is **certified** when the gap is
   within the certificate's tolerance (``2 n eta0``, :func:`certify`).
4. **Escape** (:func:`escape`): a rejected point ``x`` is a saddle of the rank-2 relaxation
   (rotations ``y_i`` unit vectors of ``C^2``, the Burer–Monteiro factor of SE-Sync's
   semidefinite relaxation): along ``[x, alpha v]``, ``v`` the eigenvector of ``lambda_min(S~) <
   0``, the cost falls as ``f + alpha^2 lambda_min``.  Newton's method continues at rank 2
   (:func:`refine_lifted`), the result is rounded to poses (:func:`round_solution`), polished and
   certified again — SE-Sync's Riemannian staircase.  When the relaxation's own optimum is not
   rank one, the relaxation is not tight and nothing can be certified: its value is then the best
   lower bound.
5. :func:`solve` — the pipeline to call: LAGO → Gauss–Newton → chordal polish → certificate
   (→ escape → polish → round → certificate, until certified or out of budget) → Gauss–Newton.
   It always ends with an answer: when the staircase cannot go on, the best point, the best
   lower bound found (every certificate's bound is valid) and the reason.

No dense ``n x n`` matrix is formed: ``M``, ``S`` and the factorizations are sparse, and
``lambda_min`` comes from shift-and-invert Lanczos on a sparse ``L D L^T`` factor.

References
----------
.. [1] L. Carlone, D. M. Rosen, G. Calafiore, J. J. Leonard, F. Dellaert, "Lagrangian duality in
   3D SLAM: verification techniques and optimal solutions" (IROS 2015) and "Planar pose graph
   optimization: duality, optimal solutions, and verification", IEEE Trans. Robotics 32(3), 2016.
.. [2] D. M. Rosen, L. Carlone, A. S. Bandeira, J. J. Leonard, "SE-Sync: a certifiably correct
   algorithm for synchronization over the special Euclidean group", IJRR 38(2-3), 2019.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .checks import check_bool, check_choice, check_int, check_real, real_array
from .errors import (
    BackendError,
    GraphError,
    NotPositiveDefiniteError,
    OptionError,
    OptionTypeError,
)
from .gauss_newton import (
    LinearSystem,
    OptimizeResult,
    _GaussNewtonSteps,
    _LevenbergMarquardtDamping,
    _LinearSolver,
    _minimize,
    _optimize,
    _Trace,
    optimize,
)
from .graph import PoseGraph, as_graph_poses, chi2
from .lago import RegularizationWarning, lago, pose_ordering
from .linalg import (
    SparseCholesky,
    _auto_backend,
    _Cholmod,
    _Pardiso,
    single_threaded_blas,
)
from .metrics import sesync_parameters

__all__ = [
    "ChordalProblem",
    "chordal_problem",
    "to_complex",
    "from_complex",
    "data_matrix",
    "chordal_cost",
    "refine",
    "optimal_translations",
    "multipliers",
    "certificate_matrix",
    "reduced_certificate_matrix",
    "Certificate",
    "certify",
    "escape",
    "lifted_cost",
    "refine_lifted",
    "round_solution",
    "ChordalSystem",
    "ChordalNewtonSystem",
    "LiftedSystem",
    "SolveResult",
    "solve",
    "ETA",
    "MAX_ITERATIONS",
    "SOLVE_TOL",
]

#: The relative decrease at which :func:`solve` stops the rank-``r`` polish to try rounding.
LOOSE_TOL = 1e-7
#: :func:`solve`'s cap of Newton iterations for one loose and one tight rank-``r`` polish: near
#: a rank-deficient optimum Newton converges only linearly (254 iterations were seen on a
#: 1000-pose world with sigma_theta 0.5), and the certificate of the relaxation needs only
#: stationarity to its tolerance.  A tight polish stopped at its cap goes on (within
#: ``max_iterations``) while its certificate finds it not stationary.
LIFTED_ITERATIONS = (100, 150)

#: :func:`solve`'s default budget of Newton iterations of the rank-``r`` polishes, summed over
#: the whole staircase (their dominant cost; an iteration at rank ``r`` factors a ``(4 r - 1) n``
#: system): the pipeline's running time is bounded by a count, not by a clock.  Measured on
#: Manhattan worlds with sigma_theta 0.8-1.0: 300 poses reach a certified rank-3 or rank-4
#: relaxation in 200-390 iterations; 1000 poses stop at 400 iterations after 86 s with a
#: relative gap of 1.5 % (1.2 % after the 581 iterations, 290 s, that finish it).
MAX_ITERATIONS = 400

#: The certificate's relative tolerance.  With ``eta0 = ETA * max(mean|lambda|, 1e-5 *
#: mean(diag M_zz))`` (:func:`certify`), a point is certified when its gap is at most
#: ``2 n eta0``: half for ``lambda_min(S~) >= -eta0``, half for ``f - sum(lambda) <= n eta0``
#: (how stationary the point is); the second term keeps it above rounding when the multipliers
#: vanish.  ``eta0`` is also the default ``eta``.
ETA = 1e-7

#: Componentwise backward error ``max_i |b - A x|_i / (|A| |x| + |b|)_i`` (Oettli and Prager;
#: :class:`lagolib.linalg.SparseCholesky` checks its solves the same way, to the same 1e-12) above
#: which a solve with the certificate's factorization is refined (at most ``_REFINE_STEPS`` steps
#: of iterative refinement) and, if it stays above, refused with a
#: :class:`~lagolib.errors.BackendError`.  A stable ``L D L^T`` solve is at about 1e-16.  (Not
#: ``|A x - b| / |b|``: near ``lambda_min`` the shifted matrices are nearly singular by design,
#: and that ratio is then about ``eps`` times their condition number for an exact factorization.)
SOLVE_TOL = 1e-12
_REFINE_STEPS = 3


# ----------------------------------------------------------------------------- the problem
def _diagonal_slots(F):
    """Data slot of every diagonal entry of a CSC (or CSR) matrix with sorted indices, shape (N,)."""
    col = np.repeat(np.arange(F.shape[0]), np.diff(F.indptr))
    on_diag = np.flatnonzero(F.indices == col)
    slots = np.full(F.shape[0], -1, dtype=np.int64)
    slots[col[on_diag]] = on_diag
    return slots


def _multipliers(X, MX, n):
    """``lambda_i = Re(sum_c conj(Y_ic) (M X)_{n+i,c})`` for ``X`` of shape (2 n,) or (2 n, r)."""
    prod = X[n:].conj() * MX[n:]
    return (prod if prod.ndim == 1 else prod.sum(axis=1)).real


@dataclass(frozen=True, eq=False)
class ChordalProblem:
    """The chordal cost's data, per edge, in complex form.

    Attributes
    ----------
    graph : PoseGraph
    i, j : ndarray of int, shape (m,)
        Rows (into ``graph.poses``) of each edge's two poses.
    t_meas : ndarray of complex, shape (m,)
        ``t~_ij = dx + i dy``, the measured translation in the frame of pose ``i``.
    R_meas : ndarray of complex, shape (m,)
        ``R~_ij = exp(i dtheta)``.
    kappa, tau : ndarray, shape (m,)
        Rotation and translation weights (> 0).
    """

    graph: PoseGraph
    i: np.ndarray
    j: np.ndarray
    t_meas: np.ndarray
    R_meas: np.ndarray
    kappa: np.ndarray
    tau: np.ndarray

    @property
    def n(self):
        return self.graph.n

    @property
    def m(self):
        return self.graph.m

    @cached_property
    def _unit(self):
        """``(problem with kappa, tau divided by s, s)``, ``s`` the median weight: the same
        minimizers, costs of order 1 per edge — what the local solvers iterate on."""
        s = float(np.median(np.concatenate([self.kappa, self.tau])))
        if s == 1.0:
            return self, 1.0
        unit = ChordalProblem(
            self.graph, self.i, self.j, self.t_meas, self.R_meas, self.kappa / s, self.tau / s
        )
        if "M" in self.__dict__:  # M is linear in the weights: not assembled twice
            unit.__dict__["M"] = self.M / s
        return unit, s

    def _drop_matrices(self):
        """Forget the cached matrices (``M`` and the forms built from it); they are built
        again when needed."""
        for name in ("M", "_unit", "_M_real", "_real_form", "_hermitian_form",
                     "_translation_factor", "_f_scale"):  # fmt: skip
            self.__dict__.pop(name, None)

    @cached_property
    def M(self):
        """The data matrix, :func:`data_matrix` (computed once)."""
        return data_matrix(self)

    @cached_property
    def _f_scale(self):
        """``ETA * 1e-5 * tr(M_zz)``: the cost below which ``f`` counts as zero (rounding in the
        rotation block of ``M``; ``n`` times the floor of the certificate's default ``eta``)."""
        return ETA * 1e-5 * float(np.sum(self.M.diagonal()[self.n :].real))

    @cached_property
    def _M_real(self):
        """``[[Re M, -Im M], [Im M, Re M]]``, shape (4 n, 4 n): ``y^H M y`` on ``[Re y; Im y]``."""
        M = self.M
        return sp.bmat([[M.real, -M.imag], [M.imag, M.real]], format="csr")

    @cached_property
    def _real_form(self):
        """``K`` at zero multipliers: ``_M_real`` without the rows and columns of the first
        translation (``Re t_0``, ``Im t_0``), so rows ``[Re t_1.., Re z, Im t_1.., Im z]``; the
        rows of ``Re z, Im z`` and the data slots of their diagonal (stored: ``M_zz``'s diagonal
        holds ``sum kappa > 0``)."""
        n = self.n
        keep = np.setdiff1d(np.arange(4 * n), [0, 2 * n])
        F = self._M_real[keep][:, keep].tocsc()
        F.eliminate_zeros()  # M's imaginary part stores zeros where M is real
        F.sort_indices()
        N = 2 * n - 1
        zrows = np.stack([n - 1 + np.arange(n), N + n - 1 + np.arange(n)])
        return F, zrows, _diagonal_slots(F)[zrows.ravel()]

    @cached_property
    def _hermitian_form(self):
        """``M'``: ``M`` without the first translation's row and column (``t_0`` is the gauge),
        complex Hermitian of shape (2 n - 1, 2 n - 1), in a stable fill-reducing order of the
        poses (:func:`lagolib.lago.pose_ordering`, :func:`lagolib.linalg.elimination_ordering`
        on the pose graph away from pose 0; each pose's rows ``t_i, z_i`` together):
        ``(F, U, zpos, f_slots, u_slots)`` with ``F`` the whole matrix (CSC, sorted), ``U`` its
        upper triangle (CSR, int32 indices, what PARDISO reads), ``zpos`` the position of
        ``z_i``'s row, and the data slots of the rotation diagonal in ``F`` and ``U``
        (``M_zz``'s diagonal holds ``sum kappa > 0``, so it is stored)."""
        n = self.n
        # Gauss-Newton's (and LAGO's) order with pose 0 fixed, computed once per graph; pose 0
        # last: every pose is eliminated away from it
        order = np.append(1 + pose_ordering(self.graph, int(self.graph.ids[0])), 0)
        rows = np.full((n, 2), -1, dtype=np.int64)
        rows[1:, 0], rows[:, 1] = np.arange(n - 1), n - 1 + np.arange(n)
        perm = rows[order].ravel()
        perm = perm[perm >= 0] + 1  # rows of M (row 0, t_0, left out)
        F = self.M[perm][:, perm].tocsc()
        F.sort_indices()
        ipos = np.empty(2 * n, dtype=np.int64)
        ipos[perm] = np.arange(perm.size)
        zpos = ipos[n + np.arange(n)]
        U = sp.triu(F, format="csr")
        U.sort_indices()
        U = sp.csr_matrix(
            (U.data, U.indices.astype(np.int32), U.indptr.astype(np.int32)), shape=U.shape
        )
        return F, U, zpos, _diagonal_slots(F)[zpos], _diagonal_slots(U)[zpos]

    @cached_property
    def _translation_factor(self):
        """Cholesky factor of ``M_tt`` without the anchor's row, and what
        :func:`optimal_translations` multiplies: ``(factor, keep, M_tz[keep], M_tt[keep, 0])``."""
        n = self.n
        keep = np.arange(1, n)
        Mtt = self.M[:n, :n].real.tocsc()[keep]
        factor = SparseCholesky(sp.csc_matrix(Mtt[:, keep]), check=False)
        return factor, keep, self.M[:n, n:][keep].tocsr(), Mtt[:, [0]].toarray()


def chordal_problem(graph):
    """The chordal problem of a pose graph, weights from its g2o information matrices.

    ``kappa = Omega_33`` and ``tau = 2 / tr(Omega_tt^-1)`` (SE-Sync's rule,
    :func:`lagolib.metrics.sesync_parameters`): the translation term is isotropic, so it is the
    same in the frame of pose ``i`` (where the information lives, g2o convention) and in the world
    frame (where the complex residual ``t_j - t_i - z_i t~_ij`` lives); the cross terms
    ``Omega_13, Omega_23`` are dropped.  With isotropic information ``Omega = diag(w, w, k)``,
    ``f = chi2`` to second order in the residuals.

    Parameters
    ----------
    graph : PoseGraph

    Returns
    -------
    ChordalProblem

    Raises
    ------
    GraphError
        Fewer than 2 poses, or more than one connected component.
    """
    if not isinstance(graph, PoseGraph):
        raise OptionTypeError(
            f"chordal_problem: graph must be a PoseGraph; got {type(graph).__name__}"
        )
    if graph.n < 2:
        raise GraphError(
            f"chordal_problem: the graph has {graph.n} pose(s); a certificate of global optimality "
            "needs at least 2 poses joined by edges"
        )
    count, labels = graph.components()
    if count > 1:
        sizes = np.sort(np.bincount(labels))[::-1]
        shown = ", ".join(map(str, sizes[:6].tolist())) + (", ..." if count > 6 else "")
        lone = int(graph.ids[np.flatnonzero(labels != 0)[0]])
        raise GraphError(
            f"chordal_problem: the graph is not connected: {count} components (sizes {shown}); "
            f"the certificate, like LAGO, is defined on connected components: vertex id {lone} "
            "is not connected to the first vertex — certify each component "
            "(PoseGraph.components gives the labels), or add the missing edges"
        )
    kappa, tau = sesync_parameters(graph)
    z = graph.measurements
    return ChordalProblem(
        graph=graph,
        i=graph.edges[:, 0].astype(np.int64),
        j=graph.edges[:, 1].astype(np.int64),
        t_meas=z[:, 0] + 1j * z[:, 1],
        R_meas=np.exp(1j * z[:, 2]),
        kappa=kappa,
        tau=tau,
    )


def _problem(graph_or_problem, where):
    if isinstance(graph_or_problem, ChordalProblem):
        return graph_or_problem
    if isinstance(graph_or_problem, PoseGraph):
        return chordal_problem(graph_or_problem)
    raise OptionTypeError(
        f"{where}: expected a PoseGraph or ChordalProblem; got {type(graph_or_problem).__name__}"
    )


def to_complex(poses):
    """Poses ``(x, y, theta)`` as ``x = [t; z]``: ``t = x + i y``, ``z = exp(i theta)``.

    Parameters
    ----------
    poses : ndarray, shape (n, 3)

    Returns
    -------
    ndarray of complex, shape (2 n,)
    """
    poses = _real_matrix(poses, "poses", "to_complex", 3)
    return np.concatenate([poses[:, 0] + 1j * poses[:, 1], np.exp(1j * poses[:, 2])])


def from_complex(x):
    """``x = [t; z]`` back to poses ``(x, y, angle(z))``; ``|z_i|`` need not be 1.

    Parameters
    ----------
    x : ndarray of complex, shape (2 n,)

    Returns
    -------
    ndarray, shape (n, 3)
    """
    x = _complex_array(x, "x", "from_complex")
    if x.ndim != 1 or x.size % 2:
        raise OptionError(
            f"from_complex: x must be a vector of even length 2 n; got shape {x.shape}"
        )
    n = x.size // 2
    return np.column_stack([x[:n].real, x[:n].imag, np.angle(x[n:])])


def _real_matrix(value, name, where, cols):
    """A finite real float array of shape (k, cols), or a lagolib error naming ``name``."""
    arr = real_array(value, name, where)
    if arr.ndim != 2 or arr.shape[1] != cols or not np.all(np.isfinite(arr)):
        raise OptionError(
            f"{where}: {name} must be a finite real array of shape (n, {cols}); got shape "
            f"{arr.shape}"
        )
    return arr


def _complex_array(value, name, where):
    """A finite complex array, or an OptionError naming ``name``."""
    try:
        arr = np.asarray(value, dtype=complex)
    except (TypeError, ValueError):
        raise OptionError(f"{where}: {name} must be a numeric (complex) array") from None
    if not np.all(np.isfinite(arr)):
        raise OptionError(f"{where}: {name} must be finite")
    return arr


def data_matrix(problem):
    """The Hermitian data matrix ``M`` with ``f(x) = x^H M x`` (Carlone et al., TRO 2016).

    Per edge the residuals are linear in ``x = [t; z]``: ``r_t = a^T x`` with ``a = e_j - e_i -
    t~_ij e_{n+i}`` and ``r_z = b^T x`` with ``b = e_{n+j} - R~_ij e_{n+i}``, so
    ``|r|^2 = x^H conj(a) a^T x`` and

    .. math:: M = \\sum_{ij} \\tau_{ij} \\bar a a^T + \\kappa_{ij} \\bar b b^T

    Parameters
    ----------
    problem : ChordalProblem or PoseGraph

    Returns
    -------
    scipy.sparse.csr_matrix of complex, shape (2 n, 2 n)
        Hermitian, positive semidefinite; 13 entries per edge before summing duplicates.
    """
    p = _problem(problem, "data_matrix")
    n, i, j, tau, kappa = p.n, p.i, p.j, p.tau, p.kappa
    # translation term: indices (j, i, n+i) with coefficients a = (1, -1, -t~)
    idx_t = np.stack([j, i, n + i], axis=1)  # (m, 3)
    a = np.stack([np.ones(p.m), -np.ones(p.m), -p.t_meas], axis=1).astype(complex)
    # rotation term: indices (n+j, n+i) with coefficients b = (1, -R~)
    idx_z = np.stack([n + j, n + i], axis=1)
    b = np.stack([np.ones(p.m), -p.R_meas], axis=1).astype(complex)
    rows = np.concatenate(
        [np.repeat(idx_t, 3, axis=1).ravel(), np.repeat(idx_z, 2, axis=1).ravel()]
    )
    cols = np.concatenate([np.tile(idx_t, 3).ravel(), np.tile(idx_z, 2).ravel()])
    vals = np.concatenate(
        [
            (tau[:, None, None] * a.conj()[:, :, None] * a[:, None, :]).ravel(),  # tau conj(a) a^T
            (
                kappa[:, None, None] * b.conj()[:, :, None] * b[:, None, :]
            ).ravel(),  # kappa conj(b) b^T
        ]
    )
    M = sp.csr_matrix((vals, (rows, cols)), shape=(2 * n, 2 * n))
    return ((M + M.conj().T) * 0.5).tocsr()  # exactly Hermitian (duplicates summed in any order)


def chordal_cost(problem, poses, *, per_edge=False):
    """The chordal cost ``f`` as the direct sum over edges (no matrix).

    .. math:: f = \\sum_{ij} \\kappa_{ij} |z_j - z_i \\tilde R_{ij}|^2
                  + \\tau_{ij} |t_j - t_i - z_i \\tilde t_{ij}|^2

    Parameters
    ----------
    problem : ChordalProblem or PoseGraph
    poses : array_like, shape (n, 3), or complex ``x = [t; z]`` of shape (2 n,)
        ``|z_i|`` is taken as given (1 for poses).
    per_edge : bool
        Return the ``m`` terms instead of their sum.

    Returns
    -------
    float, or ndarray of shape (m,)
    """
    p = _problem(problem, "chordal_cost")
    per_edge = check_bool(per_edge, "per_edge", "chordal_cost")
    x = _as_x(p, poses, "chordal_cost")
    n = p.n
    t, z = x[:n], x[n:]
    r_z = z[p.j] - z[p.i] * p.R_meas
    r_t = t[p.j] - t[p.i] - z[p.i] * p.t_meas
    terms = p.kappa * np.abs(r_z) ** 2 + p.tau * np.abs(r_t) ** 2
    return terms if per_edge else float(terms.sum())


def _as_x(p, poses, where, *, lifted=False, unit=False):
    """Poses (n, 3) or a complex ``x = [t; z]`` (2 n,) — or, with ``lifted``, a complex
    ``X = [T; Y]`` of shape (2 n, r) — as a complex array."""
    arr = np.asarray(poses)
    if np.iscomplexobj(arr):
        n = p.n
        ok = arr.shape == (2 * n,) or (
            lifted and arr.ndim == 2 and arr.shape[0] == 2 * n and arr.shape[1] >= 1
        )
        if not ok or not np.all(np.isfinite(arr)):
            want = f"({2 * n},)" + (f" or ({2 * n}, r) with r >= 1" if lifted else "")
            raise OptionError(
                f"{where}: a complex x = [t; z] must have shape {want} and be finite; "
                f"got shape {arr.shape}"
            )
        if unit:
            norms = np.abs(arr[n:]) if arr.ndim == 1 else np.linalg.norm(arr[n:], axis=1)
            bad = np.flatnonzero(np.abs(norms - 1.0) > 1e-8)
            if bad.size:
                raise OptionError(
                    f"{where}: the rotations z must have |z_i| = 1 (the constraint the certificate "
                    f"is about); |z_{bad[0]}| = {norms[bad[0]]:.6g} — normalize them, or pass poses"
                )
        return arr
    return to_complex(as_graph_poses(p.graph, poses, "poses", "poses"))


# ----------------------------------------------------------------------------- local solver
class ChordalSystem(LinearSystem):
    """``H`` and ``b`` of the chordal cost over ``(x, y, theta)`` per pose (Gauss–Newton).

    Per edge the residual is real, ``r = [t_j - t_i - R(theta_i) t~; cos theta_j -
    cos(theta_i + delta); sin theta_j - sin(theta_i + delta)]`` (4 entries), weighted by
    ``diag(tau, tau, kappa, kappa)``: ``r^T W r`` is the edge's term of ``f``.  The sparsity
    pattern, assembly and update are :class:`lagolib.gauss_newton.LinearSystem`'s.
    """

    def __init__(self, problem, *, fixed=(), like=None):
        super().__init__(problem.graph, fixed=fixed, like=like)
        self.problem = problem
        w = np.stack([problem.tau, problem.tau, problem.kappa, problem.kappa], axis=1)
        self._W = w[:, :, None] * np.eye(4)  # (m, 4, 4)

    def _edge_weights(self):
        """``diag(tau, tau, kappa, kappa)`` per edge, shape (m, 4, 4)."""
        return self._W

    def _terms(self, poses):
        """Residuals ``r`` (m, 4) and their Jacobians (m, 4, 6) w.r.t. ``(x_i, y_i, theta_i,
        x_j, y_j, theta_j)``; no priors."""
        p = self.problem
        pi, pj = poses[p.i], poses[p.j]
        c, s = np.cos(pi[:, 2]), np.sin(pi[:, 2])
        a, b = p.t_meas.real, p.t_meas.imag
        ang = pi[:, 2] + np.angle(p.R_meas)
        m = p.m
        e = np.empty((m, 4))
        e[:, 0] = pj[:, 0] - pi[:, 0] - (c * a - s * b)  # t_j - t_i - R(theta_i) t~
        e[:, 1] = pj[:, 1] - pi[:, 1] - (s * a + c * b)
        e[:, 2] = np.cos(pj[:, 2]) - np.cos(ang)  # z_j - z_i R~
        e[:, 3] = np.sin(pj[:, 2]) - np.sin(ang)
        J = np.zeros((m, 4, 6))
        J[:, 0, 0] = J[:, 1, 1] = -1.0
        J[:, 0, 3] = J[:, 1, 4] = 1.0
        J[:, 0, 2] = s * a + c * b  # -dR/dtheta t~
        J[:, 1, 2] = -(c * a - s * b)
        J[:, 2, 2], J[:, 3, 2] = np.sin(ang), -np.cos(ang)
        J[:, 2, 5], J[:, 3, 5] = -np.sin(pj[:, 2]), np.cos(pj[:, 2])
        return e, J, np.zeros((0, 3)), np.zeros((0, 3, 3))

    def objective(self, poses):
        """The chordal cost ``f`` at ``poses`` (shape (n, 3))."""
        return chordal_cost(self.problem, poses)


class _FixedPattern:
    """Sparse matrices put on one pattern, fixed per problem, so that the factorization's
    symbolic analysis (qdldl's AMD ordering) is computed once and reused by every iteration:
    sparse products drop entries that happen to be zero, so their pattern changes with the
    values."""

    def __init__(self, template):
        t = (abs(template) + sp.identity(template.shape[0])).tocsr()
        t.sum_duplicates()
        t.sort_indices()
        self.shape, self.indptr, self.indices = t.shape, t.indptr, t.indices
        self.indptr.setflags(write=False)  # frozen: the factorization knows them by address
        self.indices.setflags(write=False)
        rows = np.repeat(np.arange(t.shape[0], dtype=np.int64), np.diff(t.indptr))
        self.keys = rows * t.shape[1] + t.indices
        self.diag = np.searchsorted(
            self.keys, np.arange(t.shape[0], dtype=np.int64) * (t.shape[1] + 1)
        )

    def put(self, H):
        """``H`` (any pattern inside the template) on the fixed pattern, as CSR."""
        c = H.tocoo()
        slot = np.searchsorted(self.keys, c.row.astype(np.int64) * self.shape[1] + c.col)
        data = np.bincount(slot, weights=c.data, minlength=self.keys.size)
        return self._matrix(data)

    def damped(self, H, lam):
        """``H + lam I`` on the same pattern."""
        data = H.data.copy()
        data[self.diag] += lam
        return self._matrix(data)

    def _matrix(self, data):
        H = sp.csr_matrix((data, self.indices, self.indptr), shape=self.shape)
        H.has_canonical_format = True  # the template's: sorted, no duplicates
        return H


def _template(Ps, M_real):
    """Every entry ``P^T (M + diag) P`` can have, from absolute values (no cancellation)."""
    S = abs(M_real) + sp.identity(M_real.shape[0])
    out = None
    for P in Ps:
        A = abs(P)
        A.data[:] = 1.0
        term = A.T @ (S @ A)
        out = term if out is None else out + term
    return out


class ChordalNewtonSystem(ChordalSystem):
    r"""The exact (Riemannian) Hessian of ``f`` over ``(x, y, theta)``: Newton's method.

    Move pose ``p`` by ``u_p = (dx, dy, omega)``: ``t_p += dx + i dy`` and ``z_p *=
    exp(i omega)``, to first order ``x + P u`` with ``P`` taking ``omega_p`` to ``i z_p``.  Then

    .. math:: f(u) = f + 2 \mathrm{Re}(x^H M P u) + u^T \mathrm{Re}(P^H S P) u + O(|u|^3),

    with ``S = M - blkdiag(0, diag(lambda))`` the certificate's matrix at the current point
    (the ``-lambda_i omega_i^2`` is the circle's curvature).  So ``b = 2 Re(P^H M x)`` and
    ``H = 2 Re(P^H S P)`` — the certificate's ``S`` restricted to the tangent directions, which
    is indefinite near a saddle; Levenberg's damping (:func:`refine`'s ``method="lm"``) handles
    that.

    Assembled in closed form on Gauss–Newton's fixed pattern (:class:`ChordalSystem`, the
    chordal residuals ``r = A P u`` are linear in ``u`` to first order, so ``Re(P^H M P) =
    J^T W J``): ``H = 2 (J^T W J - diag(0, 0, lambda))`` per pose and ``b = 2 J^T W r``, ``O(m)``
    — the same matrix as the products of the real forms, on the pattern (and so the symbolic
    analysis) of :func:`lagolib.optimize`'s ``H`` for the same graph and fixed poses.
    """

    def assemble(self, poses):
        """``H = 2 Re(P^H S P)`` (free poses, (3 k, 3 k)), ``b = 2 Re(P^H M x)`` and ``f``."""
        H, b, f = super().assemble(poses)  # J^T W J, J^T W r and the sum of the edge terms
        lam = _edge_multipliers(self.problem, to_complex(poses))  # at the current point
        H.data[self._diag_slot[2::3]] -= lam[self.free]  # the circles' curvature, -lambda_i
        H.data *= 2.0
        # f as the sum of the edge terms: x^H M x cancels, and at f ~ 0 it can come out
        # negative — a sum of squares is never reported below zero
        return H, 2.0 * b, f


def _edge_multipliers(p, x):
    """:func:`multipliers` without ``M``: ``(M x)_{n+i} = df / d conj(z_i)`` summed over the
    edges at pose ``i`` — ``-tau r_t conj(t~) - kappa r_z conj(R~)`` where it is the first pose,
    ``kappa r_z`` where it is the second — and ``lambda_i = Re(conj(z_i) (M x)_{n+i})``."""
    n = p.n
    t, z = x[:n], x[n:]
    r_t = t[p.j] - t[p.i] - z[p.i] * p.t_meas  # t_j - t_i - z_i t~
    r_z = z[p.j] - z[p.i] * p.R_meas  # z_j - z_i R~
    at_i = -p.tau * r_t * p.t_meas.conj() - p.kappa * r_z * p.R_meas.conj()
    at_j = p.kappa * r_z
    Mx = (
        np.bincount(p.i, at_i.real, n)
        + np.bincount(p.j, at_j.real, n)
        + 1j * (np.bincount(p.i, at_i.imag, n) + np.bincount(p.j, at_j.imag, n))
    )
    return (z.conj() * Mx).real


def refine(
    problem,
    initial=None,
    *,
    method="newton",
    max_iterations=200,
    tol=1e-14,
    step_tol=1e-12,
    verbose=False,
):
    """Minimize the chordal cost ``f`` locally from ``initial``: Newton (default) or Gauss–Newton.

    The loop is :func:`lagolib.optimize`'s; the first pose (row 0 of ``graph.poses``) is held
    fixed.  The weights are divided by their median first (same minimizers), so that the result
    does not depend on the information's overall scale.  ``method="newton"`` uses the exact
    Hessian (:class:`ChordalNewtonSystem`) with Levenberg's damping, raised until
    ``H + lambda I`` is positive definite — quadratic convergence, and safe near saddles.
    ``method="gn"`` is Gauss–Newton on the chordal residuals (:class:`ChordalSystem`): simpler,
    linear convergence when the residuals are large (48 iterations on INTEL where Newton needs
    a handful).  Started at a χ² optimum the first step is small but not zero: the two costs
    have nearby, different minima.

    Parameters
    ----------
    problem : ChordalProblem or PoseGraph
    initial : array_like, shape (n, 3), optional
        Default ``graph.poses``.
    method : {"newton", "gn"}
    max_iterations : int
    tol, step_tol : float
        As in :func:`lagolib.optimize`; the defaults polish to the last digits, which the
        certificate needs (it reads the multipliers off the gradient).
    verbose : bool

    Returns
    -------
    OptimizeResult
        ``error="chordal"``; ``chi2`` and ``chi2_history`` hold the chordal cost ``f``.
    """
    return _refine(**locals(), solver=None)


def _refine(problem, initial, *, method, max_iterations, tol, step_tol, verbose, solver):
    """:func:`refine` with ``solver`` a :class:`lagolib.gauss_newton._LinearSolver` to reuse
    (or None): the Newton matrix has Gauss–Newton's pattern, so :func:`solve` factors both
    with one symbolic analysis."""
    t0 = time.perf_counter()
    p = _problem(problem, "refine")
    where = "refine"
    method = check_choice(method, "method", where, ("newton", "gn"))
    max_iterations = check_int(max_iterations, "max_iterations", where, minimum=0)
    tol = check_real(tol, "tol", where, minimum=0.0)
    step_tol = check_real(step_tol, "step_tol", where, minimum=0.0)
    verbose = check_bool(verbose, "verbose", where)
    x = as_graph_poses(p.graph, initial, "initial", "initial guess")
    fixed = [int(p.graph.ids[0])] if p.n else []
    unit, scale = p._unit  # weights scaled to order 1: the damping's limits are absolute
    if solver is None:
        solver = _LinearSolver("cholesky", "auto")
    like = solver.system  # Gauss-Newton's, in solve(): the same pattern
    if method == "gn":
        system, control = ChordalSystem(unit, fixed=fixed, like=like), _GaussNewtonSteps(10)
    else:
        system = ChordalNewtonSystem(unit, fixed=fixed, like=like)
        control = _LevenbergMarquardtDamping(1e-8)
    solve_ = solver.bind(system)
    trace = _Trace(method, verbose)
    x, f, stop = _minimize(
        system, x, control, solve_, trace, max_iterations, tol, step_tol, None, flat_steps=True
    )
    converged, reason = stop or (False, f"reached max_iterations={max_iterations}")
    trace.timings["total"] = time.perf_counter() - t0
    return OptimizeResult(
        poses=x,
        chi2=f * scale,
        chi2_history=[h * scale for h in trace.history],
        step_norms=trace.steps,
        iterations=trace.iterations,
        converged=converged,
        reason=reason,
        method=method,
        error="chordal",
        graph=p.graph.with_poses(x),
        lambdas=trace.lambdas,
        step_fractions=trace.fractions,
        timings=trace.timings,
    )


def optimal_translations(problem, z, t_anchor=0j):
    """The translations that minimize ``f`` for given rotations ``z`` (a linear solve).

    ``f`` is quadratic in ``t``: ``M_tt t = -M_tz z`` with ``M_tt`` the ``tau``-weighted graph
    Laplacian, solved with the first pose's translation held at ``t_anchor``.

    Parameters
    ----------
    problem : ChordalProblem or PoseGraph
    z : ndarray of complex, shape (n,) or (n, r)
        Rotations (or the rows ``Y`` of a lifted point, one column at a time).
    t_anchor : complex, or sequence of r complex

    Returns
    -------
    ndarray of complex, shape of ``z``
    """
    where = "optimal_translations"
    p = _problem(problem, where)
    n = p.n
    Z = _complex_array(z, "z", where)
    if Z.ndim not in (1, 2) or Z.shape[0] != n or (Z.ndim == 2 and Z.shape[1] < 1):
        raise OptionError(f"{where}: z must have shape ({n},) or ({n}, r); got {Z.shape}")
    Z2 = Z[:, None] if Z.ndim == 1 else Z
    anchor = _complex_array(t_anchor, "t_anchor", where)
    if anchor.ndim > 1 or anchor.size not in (1, Z2.shape[1]):
        raise OptionError(
            f"{where}: t_anchor must be one complex number or {Z2.shape[1]} of them (one per "
            f"column of z); got shape {anchor.shape}"
        )
    anchor = np.broadcast_to(anchor.ravel(), (Z2.shape[1],))
    factor, keep, Mtz, Mt0 = p._translation_factor
    rhs = -(Mtz @ Z2) - Mt0 * anchor[None, :]
    r = Z2.shape[1]
    sol = factor.solve(np.concatenate([rhs.real, rhs.imag], axis=1))
    T = np.empty_like(Z2)
    T[0] = anchor
    T[keep] = sol[:, :r] + 1j * sol[:, r:]
    return T[:, 0] if Z.ndim == 1 else T


# ----------------------------------------------------------------------------- certificate
def multipliers(problem, x):
    """Lagrange multipliers of ``|z_i|^2 = 1``: ``lambda_i = Re(conj(z_i) (M x)_{n+i})``.

    At a stationary point ``(M x)_{n+i} = lambda_i z_i`` (first-order condition of
    ``x^H M x - sum lambda_i (|z_i|^2 - 1)``); the real part of ``conj(z_i) (M x)_{n+i}`` is that
    ``lambda_i`` at any point, and its imaginary part is the gradient along the circle.

    Parameters
    ----------
    problem : ChordalProblem or PoseGraph
    x : array_like, shape (n, 3) poses, or complex (2 n,)

    Returns
    -------
    ndarray, shape (n,)
    """
    p = _problem(problem, "multipliers")
    x = _as_x(p, x, "multipliers")
    return _multipliers(x, p.M @ x, p.n)


def certificate_matrix(problem, x):
    """``S = M - blkdiag(0, diag(lambda))``, shape (2 n, 2 n), sparse Hermitian.

    At a stationary point ``S x = 0``, and ``S [1; 0] = 0`` (a global translation); ``x`` is a
    global minimum when ``S`` is positive semidefinite.

    Returns
    -------
    scipy.sparse.csr_matrix of complex, shape (2 n, 2 n)
    """
    p = _problem(problem, "certificate_matrix")
    lam = multipliers(p, x)
    n = p.n
    return (p.M - sp.diags(np.concatenate([np.zeros(n), lam]))).tocsr()


def reduced_certificate_matrix(problem, x):
    """``K``: ``S`` without the first pose's translation, as a real symmetric matrix.

    Translations are unconstrained and ``f`` does not change when all move together, so fixing
    ``t_0`` loses nothing: the Schur complement of ``K`` on the rotations is ``S~ = S_zz -
    S_zt S_tt^+ S_tz``, whose eigenvalues the certificate tests.  ``K`` is real:
    ``[[Re K, -Im K], [Im K, Re K]]`` on ``[Re v; Im v]``, so every eigenvalue appears twice.

    Returns
    -------
    K : scipy.sparse.csc_matrix, shape (4 n - 2, 4 n - 2)
    zrows : ndarray of int, shape (2, n)
        Rows of ``Re z`` and ``Im z`` in ``K``.
    """
    p = _problem(problem, "reduced_certificate_matrix")
    lam = multipliers(p, x)
    F, zrows, slots = p._real_form
    data = F.data.copy()
    data[slots] -= np.tile(lam, 2)  # S = M - blkdiag(0, diag(lambda))
    return sp.csc_matrix((data, F.indices, F.indptr), shape=F.shape), zrows


def _certificate_engine(rows):
    """The engine of the certificate's complex factorization of ``rows`` rows: ``"pardiso"`` or
    ``"cholmod"`` where ``SparseCholesky(backend="auto")`` would take that backend for the real
    form's ``2 rows``, else ``"superlu"``."""
    fast = _auto_backend(2 * rows)
    return fast if fast in ("pardiso", "cholmod") else "superlu"


class _ShiftedFactor:
    """Sparse ``L D L^H`` of ``K + s I_z`` for several shifts ``s``, and its inertia.

    ``K`` is the certificate matrix ``S`` without the first translation
    (:func:`reduced_certificate_matrix`), factored in its complex Hermitian form ``M' -
    diag(0, lambda) + s I_z`` of ``2 n - 1`` rows (``ChordalProblem._hermitian_form``, built and
    ordered once per problem; only the rotation diagonal changes with ``lam`` and ``s``): half
    the rows of the real form and a quarter of its factor's entries.  Positive definite iff no
    pivot was perturbed or exchanged and every pivot is positive; the number of negative
    pivots is the number of eigenvalues of ``S~`` below ``-s`` (Sylvester's law of inertia).

    Three engines, chosen as :class:`lagolib.linalg.SparseCholesky`'s ``backend="auto"``
    chooses for ``4 n - 2`` real rows (:func:`_certificate_engine`): MKL PARDISO (``mtype =
    -4``, complex Hermitian indefinite, supernodal, 1 x 1 pivots in the given order, the inertia
    from ``iparm[21], iparm[22]``), CHOLMOD from cvxopt (supernodal complex ``L L^H`` in the
    given order; positive definite iff it succeeds: every pivot positive) — both with
    the symbolic analysis once per certificate, one numerical factorization per shift — or
    SciPy's SuperLU on the complex matrix with diagonal pivots (``U``'s diagonal is ``D``).

    A factorization is trusted only after a check: every solve measures its componentwise
    backward error ``max_i |b - A x|_i / (|A| |x| + |b|)_i`` (two sparse products), refines a bad
    one (:data:`SOLVE_TOL`, at most ``_REFINE_STEPS`` steps) and refuses one that stays bad
    (:class:`~lagolib.errors.BackendError`); a positive definite verdict is checked by one such
    solve of a fixed random right-hand side.  ``backward_error`` is the largest one seen.  A
    factorization that is not positive definite is never solved with.
    """

    def __init__(self, problem, lam):
        F, U, self._zpos, self._f_slots, self._u_slots = problem._hermitian_form
        self._F, self._U = F, U
        self._base = F.data[self._f_slots] - lam  # M_zz's diagonal minus the multipliers
        self.engine = _certificate_engine(F.shape[0])
        self._pardiso = self._cholmod = None  # the analysis, once (PARDISO, CHOLMOD)
        self._u_diag = _diagonal_slots(U)  # where U's diagonal sits (CHOLMOD's pivot check)
        self._lu = self._A = self._abs = None
        self.shift = None
        self.backward_error = 0.0

    def factor(self, shift):
        """Factor ``K + shift I_z``; True when it is positive definite (and then checked)."""
        self._lu, self.shift = None, shift
        data = self._F.data.copy()
        data[self._f_slots] = self._base + shift
        A = sp.csc_matrix((data, self._F.indices, self._F.indptr), shape=self._F.shape)
        N = A.shape[0]
        if self.engine == "pardiso":
            udata = self._U.data.copy()
            udata[self._u_slots] = self._base + shift
            if self._pardiso is None:  # given order (the problem's): no METIS of its own
                self._pardiso = _Pardiso(self._U, np.arange(N, dtype=np.int32), mtype=-4)
            positive, _, perturbed = self._pardiso.inertia(udata)
            if positive != N or perturbed:
                return False  # an indefinite factor is never solved with
            self._lu = _PardisoSolve(self._pardiso, udata)
        elif self.engine == "cholmod":
            udata = self._U.data.copy()
            udata[self._u_slots] = self._base + shift
            if self._cholmod is None:  # given order (the problem's), as PARDISO
                self._cholmod = _Cholmod(self._U, np.arange(N), dtype=complex)
            # U's rows read as L's columns: the values conjugated.  The verdict is CHOLMOD's
            # own (every pivot positive), as PARDISO's and SuperLU's: a small pivot left by
            # cancellation can be accurate (information weights 1e-6 beside 1e7), and the
            # solve's backward-error check below judges the factor's accuracy
            try:
                self._cholmod.factor(np.conj(udata), udata[self._u_diag].real, pivot_tol=0.0)
            except NotPositiveDefiniteError:
                return False  # nothing to solve with (the factor is refused)
            self._lu = self._cholmod
        else:
            try:
                with single_threaded_blas():  # small supernodes: threads only wait
                    lu = spla.splu(
                        A,
                        permc_spec="NATURAL",
                        diag_pivot_thresh=0.0,
                        options={"SymmetricMode": True},
                    )
            except RuntimeError:  # an exactly zero pivot: singular, not positive definite
                return False
            no_swap = np.array_equal(lu.perm_r, np.arange(N))
            if not (no_swap and np.all(lu.U.diagonal().real > 0)):
                return False
            self._lu = lu
        self._A = A
        self._abs = sp.csc_matrix((np.abs(data), A.indices, A.indptr), shape=A.shape)  # |A|
        # the verdict rests on the factors: one solve must reproduce its right-hand side
        probe = np.random.default_rng(0).standard_normal((N, 2)) @ np.array([1.0, 1j])
        self._solve_ordered(probe)
        return True

    def _solve_ordered(self, b):
        """``A^-1 b`` in the factor's order, with the backward-error check."""
        if self.engine != "superlu":
            return self._checked_solve(b)
        with single_threaded_blas():
            return self._checked_solve(b)

    def _checked_solve(self, b):
        x = self._lu.solve(b)
        abs_b = np.abs(b)
        for step in range(_REFINE_STEPS + 1):
            r = b - self._A @ x
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.abs(r) / (self._abs @ np.abs(x) + abs_b)  # Oettli-Prager
            ratio[r == 0.0] = 0.0
            err = float(np.max(ratio)) if ratio.size else 0.0
            if not math.isfinite(err) or err <= SOLVE_TOL or step == _REFINE_STEPS:
                break
            x = x + self._lu.solve(r)  # one step of iterative refinement
        self.backward_error = max(self.backward_error, err)
        if not err <= SOLVE_TOL:
            relative = float(np.linalg.norm(r) / max(np.linalg.norm(b), np.finfo(float).tiny))
            which = {"pardiso": "PARDISO", "cholmod": "CHOLMOD"}.get(self.engine, "SuperLU")
            raise BackendError(
                f"certify: the sparse L D L^H factorization ({which}) of the certificate matrix "
                f"K + {self.shift:.3g} I_z ({self._A.shape[0]} complex rows) is inaccurate: a "
                f"solve with it has backward error {err:.3g} (relative residual |Ax - b| / |b| = "
                f"{relative:.3g}) after {_REFINE_STEPS} steps of iterative refinement, above "
                f"{SOLVE_TOL:g}; its verdict cannot be trusted — rescale the information matrices "
                "(weights spanning many orders of magnitude), or report the graph"
            )
        return x

    def solve_rotations(self, v):
        """``(S~ + shift I)^-1`` in real form: ``v`` of shape (2 n,) holds ``[Re y; Im y]`` of a
        rotation vector ``y``; the translations are eliminated by the solve (checked, see the
        class)."""
        if self._lu is None:  # pragma: no cover - the callers solve with positive definite factors
            raise NotPositiveDefiniteError("certify: no positive definite factor to solve with")
        n = self._zpos.size
        rhs = np.zeros(self._A.shape[0], dtype=complex)
        rhs[self._zpos] = v[:n] + 1j * v[n:]
        out = self._solve_ordered(rhs)[self._zpos]
        return np.concatenate([out.real, out.imag])


class _PardisoSolve:
    """``solve(b)`` with one PARDISO factorization (its values ``data``)."""

    def __init__(self, pardiso, data):
        self._pardiso, self._data = pardiso, data

    def solve(self, b):
        return self._pardiso.solve(self._data, b)


@dataclass
class Certificate:
    """What :func:`certify` found.

    Attributes
    ----------
    certified : bool
        ``gap <= tolerance``: ``f`` is within ``tolerance`` of the global minimum ``f*`` of the
        chordal cost (proven by the factorizations, up to their checked rounding).
    f : float
        Chordal cost at the point (the sum of the edge terms: never negative).
    multipliers : ndarray, shape (n,)
        ``lambda_i``.
    eta : float
        The shift of the first test (the ``eta`` given, or the default ``eta0``): one
        factorization of ``K + eta I_z`` passed or failed.
    eigenvalues : ndarray
        The smallest eigenvalues of ``S~`` computed (ascending; empty when the first test
        certified the point and no eigenvalue was asked for).
    lower_bound : float
        The dual bound ``sum(lambda) + n min(lambda_min, 0) <= f*``, with ``lambda_min = -eta``
        when no eigenvalue was computed.  It can be negative (a rejected point's bound is often
        far below zero; a noiseless graph's is ``-n eta``): ``f* >= max(lower_bound, 0)``, and
        ``gap`` uses the latter.
    gap : float
        ``f - max(lower_bound, 0) >= 0``: how far above ``f*`` the point can be, at most.
    relative_gap : float
        ``gap / max(f, f_scale)``: relative to ``f``, and to the rounding scale ``f_scale`` when
        ``f`` is smaller (a noiseless graph or a tree, ``f ~ 0``).
    tolerance : float
        ``2 n eta0 = 2 max(ETA sum|lambda_i|, f_scale)``: the largest gap that certifies.
    f_scale : float
        ``ETA * 1e-5 * tr(M_zz)``: the cost below which ``f`` counts as zero (rounding in the
        rotation block of ``M``).
    gradient : float
        ``max |Im(conj(z_i) (M x)_{n+i})|`` and ``max |(M x)_t|`` together: how stationary the
        point is (the multipliers are exact only at a stationary point).
    eigenvector : ndarray of complex, shape (n,), or None
        The rotation part of the eigenvector of ``lambda_min`` (unit norm) whenever
        ``lambda_min`` was computed — always when not certified.  Its Rayleigh quotient was
        checked against ``lambda_min`` independently of the factorization.
    backward_error : float
        The largest componentwise backward error of the solves with the factorizations (checked
        against :data:`SOLVE_TOL`).
    seconds : float
    """

    certified: bool
    f: float
    multipliers: np.ndarray
    eta: float
    eigenvalues: np.ndarray
    lower_bound: float
    gap: float
    relative_gap: float
    gradient: float
    eigenvector: np.ndarray | None = None
    seconds: float = 0.0
    tolerance: float = 0.0
    f_scale: float = 0.0
    backward_error: float = 0.0

    @property
    def lambda_min(self):
        """The smallest eigenvalue of ``S~`` if computed, else None (then ``> -eta``)."""
        return float(self.eigenvalues[0]) if self.eigenvalues.size else None

    @property
    def stationarity(self):
        """``f - sum(lambda)`` (``x^H S x``): 0 at a stationary point."""
        return self.f - float(np.sum(self.multipliers))

    @property
    def saddle(self):
        """Not certified because of negative curvature: ``lambda_min(S~) < -tolerance / (2 n)``
        (``-eta0``).  Then :func:`escape` leaves the point along ``eigenvector``; a point that is
        not certified and not a saddle is not stationary enough (refine it further)."""
        lm = self.lambda_min
        n = max(self.multipliers.size, 1)
        return (
            not self.certified
            and self.eigenvector is not None
            and lm is not None
            and lm < -self.tolerance / (2 * n)
        )

    def __repr__(self):
        lm = "not computed" if self.lambda_min is None else f"{self.lambda_min:.4g}"
        return (
            f"Certificate(certified={self.certified}, f={self.f:.10g}, lambda_min={lm}, "
            f"eta={self.eta:.3g}, lower_bound={self.lower_bound:.10g}, gap={self.gap:.3g}, "
            f"relative_gap={self.relative_gap:.3g})"
        )


def _smallest(factor, shift, k):
    """The ``k`` smallest eigenvalues of ``S~`` and the first eigenvector, by shift-and-invert
    Lanczos: ``factor`` holds ``K + shift I_z`` (positive definite, so ``-shift < lambda_min``),
    and the rotation block of its inverse is ``(S~ + shift I)^-1``."""
    nz = 2 * factor._zpos.size

    def op(v):
        return factor.solve_rotations(np.ravel(v))

    A = spla.LinearOperator((nz, nz), matvec=op, dtype=float)
    kk = min(2 * k, nz - 1)  # every eigenvalue of the real form appears twice
    v0 = np.random.default_rng(0).standard_normal(nz)
    try:
        mu, vec = spla.eigsh(A, k=kk, which="LA", v0=v0, tol=1e-12)
    except spla.ArpackNoConvergence as exc:  # keep what converged, if anything did
        mu, vec = exc.eigenvalues, exc.eigenvectors
        if mu is None or not np.size(mu):
            raise BackendError(
                f"certify: Lanczos (ARPACK) found no eigenvalue of S~ at shift {shift:.3g}: "
                f"{exc}; report the graph"
            ) from None
    lam = 1.0 / mu - shift
    order = np.argsort(lam)
    lam, vec = lam[order], vec[:, order]
    n = nz // 2
    v = vec[:n, 0] + 1j * vec[n:, 0]
    return _pairs(lam)[:k], v / np.linalg.norm(v)


def _eigenvalues(factor, shift, k):
    """:func:`_smallest`, with ``lambda_2 .. lambda_k`` computed again at a second shift when the
    first one is too close to ``-lambda_min``: ARPACK converges every Ritz value to a tolerance
    relative to the largest, ``1 / (lambda_min + shift)``, so when ``lambda_2 + shift`` is many
    orders of magnitude larger (a certified point, ``lambda_min ~ 0``, tested at ``shift =
    eta``) the others lose digits (1.8e-8 relative on ``square_loop``).  The second shift puts
    ``-lambda_min`` half the spectral gap away; ``lambda_min`` and its eigenvector are the first
    run's.  ``factor`` ends factored at the last shift used."""
    values, v = _smallest(factor, shift, k)
    if values.size >= 2:
        gap = float(values[1] - values[0])
        if gap > 1e3 * float(values[0] + shift):
            second = shift + 0.5 * gap
            if factor.factor(second):  # K + shift I is positive definite, so this one is too
                again, _ = _smallest(factor, second, k)
                if again.size == values.size:
                    values = np.concatenate([values[:1], again[1:]])
    return values, v


def _pairs(lam):
    """One of each pair of equal eigenvalues of a complex matrix's real form (sorted input)."""
    out, i = [], 0
    atol = 1e-9 * float(np.max(np.abs(lam))) if lam.size else 0.0
    while i < lam.size:
        out.append(lam[i])
        same = i + 1 < lam.size and abs(lam[i + 1] - lam[i]) <= 1e-6 * abs(lam[i]) + atol
        i += 2 if same else 1
    return np.array(out)


def _rayleigh(p, lam, v):
    """``v^H S~ v / v^H v`` without the factorization, and the size of the terms it sums:
    ``S~``'s quadratic form is ``[t; v]^H S [t; v]`` at the translations that minimize it
    (:func:`optimal_translations`), i.e. the chordal cost of ``[t; v]`` (a sum of edge terms)
    minus ``sum(lambda_i |v_i|^2)``; the terms can cancel, and rounding is relative to them."""
    t = optimal_translations(p, v, 0j)
    x = np.concatenate([t, v])
    vv = float(np.vdot(v, v).real)
    weighted = np.abs(lam) * np.abs(v) ** 2
    av, at = np.abs(v), np.abs(t)
    size = float(
        np.sum(p.tau * (at[p.j] + at[p.i] + av[p.i] * np.abs(p.t_meas)) ** 2)
        + np.sum(p.kappa * (av[p.j] + av[p.i]) ** 2)
        + np.sum(weighted)
    )
    rho = (chordal_cost(p, x) - float(np.sum(lam * np.abs(v) ** 2))) / vv
    return rho, size / vv


def _check_eigenvector(p, lam, value, v, shift):
    """The inertia of a factorization decided which eigenvalue Lanczos found: check it against
    the Rayleigh quotient of its eigenvector, computed another way (:func:`_rayleigh`), to
    ``1e-6`` relative and ``1e-10`` of the size of the terms that quotient sums (rounding in them
    is about 1e-16; a factorization that is wrong is off by the spacing of the spectrum)."""
    rho, size = _rayleigh(p, lam, v)
    if abs(rho - value) <= 1e-6 * (abs(value) + abs(shift)) + 1e-10 * size:
        return
    raise BackendError(
        f"certify: the factorizations are inconsistent: Lanczos gives lambda_min(S~) = "
        f"{value:.6g} but its eigenvector's Rayleigh quotient, computed without them, is "
        f"{rho:.6g}; the certificate cannot be trusted — rescale the information matrices "
        "(weights spanning many orders of magnitude), or report the graph"
    )


def certify(problem, poses, *, eta=None, eigenvalues=0):
    """Certify that ``poses`` is a global minimum of the chordal cost — or bound how far it is.

    **What is proven.**  For any multipliers ``lambda``, ``f* >= sum(lambda) + n
    min(lambda_min(S~), 0)`` (the dual bound, ``lower_bound``) and ``f* >= 0``.  The *gap*
    ``f - max(lower_bound, 0)`` bounds how far above the global minimum ``f*`` the point is.
    The point is **certified** when the gap is at most the tolerance ``2 n eta0``, with

    ``eta0 = ETA * max(mean|lambda_i|, 1e-5 * mean(diag M_zz))``   (``ETA = 1e-7``):

    ``S~`` is singular at a stationary point (``S~ z = 0``), so ``lambda_min`` is 0 in exact
    arithmetic and ``±(rounding)`` in floating point, and the multipliers are read off a point
    the local solver reached only to its tolerance.  Both errors scale with the multipliers: at
    a certified optimum of the benchmarks ``|lambda_min|`` is 1e-13 to 1e-10 of ``mean|lambda|``,
    at a local minimum that is not global it is 1e-4 or more.  When the residuals vanish
    (noiseless graphs, trees) so do the multipliers, and rounding in ``M`` sets the scale (the
    second term; ``n`` times it is ``f_scale``).  In words: certified means ``lambda_min(S~) >=
    -eta0`` and ``f - sum(lambda) <= n eta0`` together, up to how the ``2 n eta0`` is shared.

    **How.**  A sparse ``L D L^T`` factorization of ``K + eta I_z``
    (:func:`reduced_certificate_matrix`) succeeds exactly when ``lambda_min(S~) > -eta``: one
    factorization, the same work as one Gauss–Newton iteration on a 4/3 larger system; it
    proves ``f* >= sum(lambda) - n eta``.  When that certifies the point, nothing else is
    computed (unless ``eigenvalues`` asks).  Otherwise — the test failed, or ``eta`` was too
    large for its bound to certify, or the point is not stationary — ``lambda_min`` and its
    eigenvector come from shift-and-invert Lanczos, after a few factorizations that bracket
    ``lambda_min`` within a factor of 2 (the number of negative pivots of ``L D L^T`` is the
    number of eigenvalues below the shift, Sylvester's law of inertia), and the bound is
    ``sum(lambda) + n min(lambda_min, 0)``.  Every factorization is checked (its solves'
    backward error, :data:`SOLVE_TOL`; the eigenvector's Rayleigh quotient recomputed without
    it) and refused with a :class:`~lagolib.errors.BackendError` when it fails the check.

    Parameters
    ----------
    problem : ChordalProblem or PoseGraph
    poses : array_like, shape (n, 3)
        A stationary point of the chordal cost (:func:`refine`); elsewhere the multipliers, and
        so the bound, are poor (``Certificate.gradient`` says how stationary it is).
    eta : float, optional
        The shift of the first test, ``>= 0`` (absolute, in the units of ``f`` per pose): its
        factorization accepts ``lambda_min(S~) > -eta`` and proves ``f* >= sum(lambda) - n
        eta``.  It sets the work and which bound is reported, never what "certified" means: a
        large ``eta`` proves a weak bound, so ``lambda_min`` is then computed (a local minimum
        is not certified whatever ``eta``); ``eta = 0`` tests ``S~`` itself, which is singular
        at a stationary point, so ``lambda_min`` is computed whenever rounding makes it
        negative.  Default ``eta0``, the largest shift whose bound can still certify.
    eigenvalues : int
        Also compute this many smallest eigenvalues of ``S~`` when certified (``>= 0``; one is
        always computed when not certified).

    Returns
    -------
    Certificate
    """
    t0 = time.perf_counter()
    p = _problem(problem, "certify")
    where = "certify"
    k = check_int(eigenvalues, "eigenvalues", where, minimum=0)
    X = _as_x(p, poses, where, lifted=True, unit=True)
    X = X[:, None] if X.ndim == 1 else X
    n = p.n
    if n < 2:
        raise OptionError(f"{where}: the graph needs at least 2 poses; it has {n}")
    MX = p.M @ X
    lam = _multipliers(X, MX, n)  # lambda_i = Re(conj(z_i) (M x)_{n+i})
    rgrad = MX[n:] - lam[:, None] * X[n:]  # the gradient's component along the spheres
    gradient = float(max(np.max(np.abs(rgrad)), np.max(np.abs(MX[:n]))))
    if k > n:
        raise OptionError(f"{where}: eigenvalues must be at most n = {n}; got {k}")
    f_scale = p._f_scale
    tolerance = 2.0 * max(ETA * float(np.sum(np.abs(lam))), f_scale)
    eta0 = tolerance / (2 * n)  # = ETA * max(mean|lambda|, 1e-5 * mean(diag M_zz))
    eta = eta0 if eta is None else check_real(eta, "eta", where, minimum=0.0)
    f = lifted_cost(p, X)  # the sum of edge terms: x^H M x can cancel to a negative number
    lam_sum = float(lam.sum())
    factor = _ShiftedFactor(p, lam)
    psd = factor.factor(eta)  # K + eta I_z = L D L^T with D > 0  <=>  lambda_min(S~) > -eta
    eigvals, vec = np.zeros(0), None
    floor = 1e-14 * (float(np.max(np.abs(lam))) + float(np.mean(p.M.diagonal()[n:].real)))
    if psd and f - max(lam_sum - n * eta, 0.0) <= tolerance:  # the one test certifies
        lam_min = -eta
        if k:
            eigvals, vec = _eigenvalues(factor, eta, k)
            _check_eigenvector(p, lam, eigvals[0], vec, eta)
            lam_min = float(eigvals[0])
    else:  # compute lambda_min: a shift within a factor of 2 of it, then Lanczos there
        if psd and eta > 2.0 * floor:  # eta proves too little: look below it
            shift = floor if factor.factor(floor) else _bracket(factor, floor, eta)
        elif psd:
            shift = eta
        else:
            lo = max(eta, floor)
            shift = _bracket(factor, lo, float(np.max(np.abs(lam))) + 2.0 * lo)
        eigvals, vec = _eigenvalues(factor, shift, max(k, 1))
        _check_eigenvector(p, lam, eigvals[0], vec, shift)
        lam_min = float(eigvals[0])
    bound = lam_sum + n * min(lam_min, 0.0)
    gap = max(f - max(bound, 0.0), 0.0)
    return Certificate(
        certified=bool(gap <= tolerance),
        f=f,
        multipliers=lam,
        eta=float(eta),
        eigenvalues=eigvals,
        lower_bound=bound,
        gap=gap,
        relative_gap=gap / max(f, f_scale, np.finfo(float).tiny),
        gradient=gradient,
        eigenvector=vec,
        seconds=time.perf_counter() - t0,
        tolerance=tolerance,
        f_scale=f_scale,
        backward_error=factor.backward_error,
    )


def _bracket(factor, lo, hi):
    """A shift ``s`` with ``K + s I_z`` positive definite and ``K + (s/2) I_z`` not, given that
    ``lo`` fails and ``hi`` succeeds (``hi > max lambda_i``: ``S~ = M~ - diag(lambda)`` and
    ``M~`` is positive semidefinite).  Bisection on ``log s``; ``factor`` ends factored at the
    returned shift."""
    for _ in range(200):  # log2 of the ratio halves every pass: at most ~11 passes in float64
        if not hi > 2.0 * lo:
            break
        mid = math.sqrt(lo * hi)
        if factor.factor(mid):
            hi = mid
        else:
            lo = mid
    if not factor.factor(hi):  # pragma: no cover - hi was positive definite before
        raise NotPositiveDefiniteError("certify: lost positive definiteness at a tested shift")
    return hi


# ----------------------------------------------------------------------------- escape
def lifted_cost(problem, X):
    """``f(X) = tr(X^H M X)`` for a lifted ``X = [T; Y]``, shape (2 n, r), rows of ``Y`` unit.

    At ``r = 1`` this is the chordal cost; for ``r > 1`` it is the cost of the rank-``r``
    relaxation (Burer–Monteiro), whose minimum over all ``r`` is the semidefinite relaxation's
    value — a lower bound on the chordal optimum ``f*``.
    """
    p = _problem(problem, "lifted_cost")
    X = _as_x(p, X, "lifted_cost", lifted=True)
    X = X[:, None] if X.ndim == 1 else X
    return sum(chordal_cost(p, X[:, c]) for c in range(X.shape[1]))


class LiftedSystem:
    """Newton's method for ``tr(X^H M X)`` with the rows of ``Y`` on unit spheres of ``C^r``.

    The rank-``r`` generalization of :class:`ChordalNewtonSystem`: pose ``i`` moves by
    ``dT_i`` (``2 r`` reals) and by ``B_i w_i`` along its sphere (``B_i``: an orthonormal basis of
    the tangent space of the real ``2 r``-vector ``y_i``, from a Householder reflection;
    ``w_i``: ``2 r - 1`` reals), then ``y_i`` is normalized again.  ``H = 2 P^T (I_r ⊗ S) P``
    and ``b = 2 P^T vec(M X)`` with ``S`` the certificate's matrix at the current point.  The
    first pose is held fixed.  Used by :func:`solve`'s staircase; :func:`_minimize` runs it.
    """

    def __init__(self, problem, r):
        self.problem, self.r = problem, r
        self.graph = problem.graph
        self.priors, self._prior_info = [], np.zeros((0, 3, 3))
        n = problem.n
        self.free = np.arange(1, n)
        self.d = 4 * r - 1  # unknowns per pose
        self.N = self.d * self.free.size
        self._pattern = None

    def _unpack(self, X):
        """Real rows of ``Y``: shape (n, 2 r), ``[Re y_i, Im y_i]``."""
        n = self.problem.n
        return np.concatenate([X[n:].real, X[n:].imag], axis=1)

    def _basis(self, X):
        """Orthonormal tangent bases ``B_i``, shape (k, 2 r, 2 r - 1), for the free poses."""
        y = self._unpack(X)[self.free]
        D = y.shape[1]
        sign = np.where(y[:, 0] >= 0, 1.0, -1.0)
        v = y.copy()
        v[:, 0] += sign  # Householder vector: (I - 2 v v^T / v^T v) y = -sign e_0
        Hh = np.eye(D)[None] - 2.0 * v[:, :, None] * v[:, None, :] / np.sum(v * v, 1)[:, None, None]
        return Hh[:, :, 1:]

    def _P(self, X):
        """``P`` (real form, per column of ``X``): list of ``r`` sparse (4 n, N) matrices."""
        n, r, k = self.problem.n, self.r, self.free.size
        B = self._basis(X)  # (k, 2r, 2r-1)
        base = self.d * np.arange(k)
        Ps = []
        for c in range(r):
            rows, cols, vals = [], [], []
            rows += [self.free, 2 * n + self.free]  # Re T_ic, Im T_ic
            cols += [base + 2 * c, base + 2 * c + 1]
            vals += [np.ones(k), np.ones(k)]
            for part, off in ((c, n), (r + c, 3 * n)):  # Re Y_ic, Im Y_ic
                rr = np.repeat(off + self.free, 2 * r - 1)
                cc = (base[:, None] + 2 * r + np.arange(2 * r - 1)).ravel()
                rows.append(rr)
                cols.append(cc)
                vals.append(B[:, part, :].ravel())
            Ps.append(
                sp.csr_matrix(
                    (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                    shape=(4 * n, self.N),
                )
            )
        return Ps

    def assemble(self, X):
        """``H = 2 P^T (I_r ⊗ S) P``, ``b = 2 P^T vec(M X)`` and ``f`` at the lifted ``X``."""
        p, n = self.problem, self.problem.n
        MX = p.M @ X
        lam = _multipliers(X, MX, n)
        S = p._M_real - sp.diags(np.concatenate([np.zeros(n), lam, np.zeros(n), lam]))
        Ps = self._P(X)
        if self._pattern is None:
            self._pattern = _FixedPattern(_template(Ps, p._M_real))
        H = sp.csr_matrix((self.N, self.N))
        b = np.zeros(self.N)
        for c, P in enumerate(Ps):
            H = H + P.T @ (S @ P)
            b += P.T @ np.concatenate([MX[:, c].real, MX[:, c].imag])
        H = self._pattern.put(H + H.T)  # 2 sym(P^T S P)
        return H, 2.0 * b, lifted_cost(p, X)

    def objective(self, X):
        """``tr(X^H M X)``, as the sum of edge terms."""
        return lifted_cost(self.problem, X)

    def _gauge(self, X):
        """Tangent coordinates of the symmetries left when the first pose is fixed: ``X -> X A``
        with ``A`` skew-Hermitian and ``y_0 A = 0`` (``(r - 1)^2`` directions; none at r = 1).
        ``f`` is constant along them, so ``H`` is singular there."""
        n, r = self.problem.n, self.r
        if r < 2:
            return np.zeros((self.N, 0))
        q = X[n]  # y_0, unit row of C^r
        # orthonormal columns W with q W = 0
        _, _, Vh = np.linalg.svd(q[None, :])
        W = Vh.conj().T[:, 1:]  # (r, r-1): q @ W = 0
        gens = []
        for a in range(r - 1):
            for b in range(a, r - 1):
                E = np.zeros((r - 1, r - 1), dtype=complex)
                if a == b:
                    E[a, a] = 1j
                    gens.append(E)
                else:
                    E1, E2 = E.copy(), E.copy()
                    E1[a, b], E1[b, a] = 1.0, -1.0
                    E2[a, b], E2[b, a] = 1j, 1j
                    gens += [E1, E2]
        B = self._basis(X)
        T, Y = X[self.free], X[n + self.free]
        cols = []
        for C in gens:
            A = W @ C @ W.conj().T
            dT, dY = T @ A, Y @ A
            u = np.empty((self.free.size, self.d))
            u[:, 0 : 2 * r : 2], u[:, 1 : 2 * r : 2] = dT.real, dT.imag
            u[:, 2 * r :] = np.einsum("kab,ka->kb", B, np.concatenate([dY.real, dY.imag], axis=1))
            cols.append(u.ravel())
        return np.column_stack(cols)

    def update(self, X, dx):
        """Move by ``dx`` (tangent coordinates, symmetry directions removed) and normalize
        the rows of ``Y`` again (the retraction)."""
        n, r = self.problem.n, self.r
        G = self._gauge(X)
        if G.shape[1]:  # move across the symmetry orbits only (the step along them is noise)
            dx = dx - G @ np.linalg.lstsq(G, dx, rcond=None)[0]
        u = dx.reshape(-1, self.d)
        out = X.copy()
        out[self.free] += u[:, 0 : 2 * r : 2] + 1j * u[:, 1 : 2 * r : 2]
        y = self._unpack(X)
        y[self.free] += np.einsum("kab,kb->ka", self._basis(X), u[:, 2 * r :])
        y /= np.linalg.norm(y, axis=1, keepdims=True)  # retraction: back onto the spheres
        out[n:] = y[:, :r] + 1j * y[:, r:]
        return out

    def damped(self, H, lam):
        """``H + lam I`` on ``H``'s fixed pattern."""
        return self._pattern.damped(H, lam)


def refine_lifted(problem, X, *, max_iterations=300, tol=1e-14, step_tol=1e-12):
    """Newton (with Levenberg's damping) on the rank-``r`` relaxation from ``X``.

    Parameters
    ----------
    problem : ChordalProblem or PoseGraph
    X : ndarray of complex, shape (2 n, r)
        Rows of ``Y = X[n:]`` of unit norm.
    max_iterations : int
    tol, step_tol : float
        As in :func:`refine`.

    Returns
    -------
    X : ndarray of complex, shape (2 n, r)
    f : float
    iterations : int
    """
    where = "refine_lifted"
    p = _problem(problem, where)
    max_iterations = check_int(max_iterations, "max_iterations", where, minimum=0)
    tol = check_real(tol, "tol", where, minimum=0.0)
    step_tol = check_real(step_tol, "step_tol", where, minimum=0.0)
    X = _as_x(p, X, where, lifted=True, unit=True)
    X = X[:, None] if X.ndim == 1 else X
    unit, scale = p._unit  # weights scaled to order 1: the damping's limits are absolute
    system = LiftedSystem(unit, X.shape[1])
    trace = _Trace("lm", False)
    control = _LevenbergMarquardtDamping(1e-8)
    X, f, _ = _minimize(
        system,
        X,
        control,
        _LinearSolver("cholesky", "auto"),
        trace,
        max_iterations,
        tol,
        step_tol,
        None,
    )
    return X, f * scale, trace.iterations


def escape(problem, X, certificate, *, max_halvings=40):
    """Escape a point the certificate rejected: add a column along the eigenvector (a saddle).

    At rank ``r + 1`` the rejected point ``[X, 0]`` is stationary, and along ``[0, v]``, with
    ``v`` the eigenvector of ``lambda_min(S~) < 0``, the cost falls as ``f + alpha^2
    lambda_min`` (SE-Sync's saddle escape, one step of the Riemannian staircase): the new
    column opens a direction the rank-``r`` problem does not have.  Rows are normalized again and
    translations re-solved (:func:`optimal_translations`); ``alpha`` starts at ``sqrt(n)``
    (entries of ``v`` the size of the ``y_i``) and is halved until ``f`` decreases.

    Parameters
    ----------
    problem : ChordalProblem or PoseGraph
    X : poses (n, 3) or complex ``x`` (2 n,) or ``X`` (2 n, r)
        The rejected point.
    certificate : Certificate
        Its certificate: not certified, with ``lambda_min < 0`` and its eigenvector (a saddle,
        :attr:`Certificate.saddle`; a point that is not stationary has no such direction).
    max_halvings : int

    Returns
    -------
    X : ndarray of complex, shape (2 n, r + 1)
    alpha : float
        The step; 0.0 (and ``X`` unchanged, padded) when no step decreased ``f``.
    """
    p = _problem(problem, "escape")
    if not isinstance(certificate, Certificate):
        raise OptionTypeError(
            f"escape: certificate must be the Certificate of the point (certify(problem, X)); "
            f"got {type(certificate).__name__}"
        )
    if certificate.certified:
        raise OptionError(
            "escape: the point's certificate says it is certified (f is within "
            f"{certificate.tolerance:.3g} of the global minimum): there is nothing to escape; "
            "escape needs the Certificate of a point that was not certified"
        )
    lm = certificate.lambda_min
    if certificate.eigenvector is None or lm is None or not lm < 0.0:
        shown = "not computed" if lm is None else f"{lm:.6g}"
        raise OptionError(
            f"escape: the certificate has no direction of negative curvature (lambda_min(S~) "
            f"{shown}): the point is not certified because it is not stationary (f - "
            f"sum(lambda) = {certificate.stationarity:.6g}, above the tolerance "
            f"{certificate.tolerance:.3g}); refine it further, then certify it again"
        )
    max_halvings = check_int(max_halvings, "max_halvings", "escape", minimum=0)
    if certificate.eigenvector.shape != (p.n,):
        raise OptionError(
            f"escape: the certificate's eigenvector has {certificate.eigenvector.size} entries and "
            f"the graph {p.n} poses: it belongs to another graph; certify this point first"
        )
    X = _as_x(p, X, "escape", lifted=True, unit=True)
    X = X[:, None] if X.ndim == 1 else X
    n = p.n
    v = certificate.eigenvector / np.linalg.norm(certificate.eigenvector)
    f0 = lifted_cost(p, X)
    alpha = math.sqrt(n)
    for _ in range(max_halvings + 1):
        Y = np.column_stack([X[n:], alpha * v])
        Y /= np.linalg.norm(Y, axis=1, keepdims=True)
        T = optimal_translations(p, Y, X[0].tolist() + [0j])
        Xn = np.vstack([T, Y])
        if lifted_cost(p, Xn) < f0:
            return Xn, alpha
        alpha *= 0.5
    return np.column_stack([X, np.zeros(2 * n)]), 0.0


def _anchored(x, pose0):
    """Poses of ``x = [t; z]`` moved rigidly so that the first one is ``pose0``."""
    n = x.size // 2
    rot = np.exp(1j * pose0[2]) * np.conj(x[n]) / abs(x[n])
    t = (pose0[0] + 1j * pose0[1]) + rot * (x[:n] - x[0])
    return from_complex(np.concatenate([t, rot * x[n:]]))


def round_solution(problem, X):
    """Round a lifted ``X`` (2 n, r) to poses: the dominant direction of ``Y``, unit modulus.

    ``Y = U Sigma V^H``; ``z_i = u_i / |u_i|`` for the first left singular vector ``u`` (rank
    one when the relaxation is tight, and then the rounding is exact), translations by
    :func:`optimal_translations`; the result is moved rigidly so that the first pose is the
    graph's first pose.

    Returns
    -------
    ndarray, shape (n, 3)
    """
    p = _problem(problem, "round_solution")
    X = _as_x(p, X, "round_solution", lifted=True, unit=True)
    X = X[:, None] if X.ndim == 1 else X
    n = p.n
    Y = X[n:]
    _, V = np.linalg.eigh(Y.conj().T @ Y)  # r x r: V's last column is the top right vector
    u = Y @ V[:, -1]
    z = u / np.maximum(np.abs(u), 1e-300)
    t = optimal_translations(p, z, 0j)
    return _anchored(np.concatenate([t, z]), p.graph.poses[0])


# ----------------------------------------------------------------------------- the pipeline
@dataclass
class SolveResult:
    """What :func:`solve` returns.

    Attributes
    ----------
    poses : ndarray, shape (n, 3)
        The χ² (lecture notes') optimum reached by Gauss–Newton from the best chordal point
        (step 5 of :func:`solve`).  The certificate is about the chordal cost: that this is
        also χ²'s global minimum is likely, not proven.
    chi2 : float
        Its χ².
    chordal_poses : ndarray, shape (n, 3)
        The chordal minimum that was certified (or the best one found).
    f : float
        Its chordal cost (a sum of squares: never negative).
    certificate : Certificate
        The certificate of ``chordal_poses``.
    certified : bool
        ``gap <= certificate.tolerance``: ``f`` is within the certificate's tolerance of the
        global chordal optimum — by ``chordal_poses``' own certificate, or by the lower bound
        of a relaxation.
    escapes : int
        Escape steps taken (each one rank up the Riemannian staircase).
    lower_bound : float
        The best lower bound on the global chordal optimum found on the way (every
        certificate's, the relaxations' included, and 0: ``f`` is a sum of squares); ``f* >=
        lower_bound``.
    start_chi2 : float
        χ² of the start (LAGO's or ``initial``).
    reason : str
        Why the pipeline stopped: "certified ...", or "not certified: " and which budget ran
        out, or why the staircase could not go on.
    stages : list of dict
        ``{"stage", "chi2", "f", "seconds", ...}`` per step of the pipeline, in order.
    timings : dict
        Seconds per kind of stage (``"lago"``, ``"gauss_newton"``, ``"refine"``, ``"certify"``,
        ``"escape"``) and ``"total"``.
    graph : PoseGraph
        The input graph with ``poses``.
    iterations : int
        Newton iterations of the rank-``r`` polishes (``r >= 2``), the budget
        ``max_iterations`` counts.
    """

    poses: np.ndarray
    chi2: float
    chordal_poses: np.ndarray
    f: float
    certificate: Certificate
    certified: bool
    escapes: int
    reason: str
    stages: list
    timings: dict
    graph: PoseGraph
    lower_bound: float = float("nan")
    start_chi2: float = float("nan")
    iterations: int = 0

    @property
    def gap(self):
        """``f - lower_bound``: how far above the global chordal optimum ``f`` can be."""
        return max(self.f - self.lower_bound, 0.0)

    @property
    def relative_gap(self):
        """``gap / max(f, certificate.f_scale)``: relative to ``f``, and to the rounding scale
        of the cost when ``f`` is smaller (``f ~ 0``: a noiseless graph, a tree)."""
        return self.gap / max(self.f, self.certificate.f_scale, np.finfo(float).tiny)

    def __repr__(self):
        return (
            f"SolveResult(chi2={self.chi2:.10g}, f={self.f:.10g}, certified={self.certified}, "
            f"gap={self.gap:.3g}, escapes={self.escapes}, reason={self.reason!r})"
        )


def solve(
    graph,
    initial=None,
    *,
    tree=None,
    max_escapes=10,
    max_iterations=MAX_ITERATIONS,
    eta=None,
    verbose=False,
):
    """The pipeline to call: LAGO → Gauss–Newton → chordal polish → certificate (→ escape).

    1. ``initial``, or LAGO (:func:`lagolib.lago_solve`) with ``tree`` (default: LAGO's); a
       :class:`lagolib.RegularizationWarning` is not raised but noted in the LAGO stage
       (``"warning"``) — the certificate decides what the warning can only suspect;
    2. Gauss–Newton on χ² (:func:`lagolib.optimize`, LM if Gauss–Newton fails);
    3. :func:`refine` — the chordal cost's local minimum next to it;
    4. :func:`certify`; if not certified, climb the Riemannian staircase: :func:`escape` to
       rank ``r + 1``, a loose :func:`refine_lifted` (to ``LOOSE_TOL``), round to poses
       (:func:`round_solution`), :func:`refine` and :func:`certify`; only if that fails, polish
       the relaxation tight and certify it (again while its polish stopped at a cap before a
       stationary point).  Until certified (by a point's own certificate, or because a
       relaxation's lower bound is within the tolerance of the best point's ``f``), until a
       certified relaxation is not rank one (not tight: its value is then the bound), until a
       budget runs out, or until the staircase cannot go on (a point that is not certified
       has no direction of negative curvature to escape along, or no step decreases the cost);
    5. Gauss–Newton on χ² from the best chordal point — the answer, in the basin the
       certificate vouches for (the polish or an escape may have left the first one's).

    It always ends with an answer: when the staircase stops, the best point found, the best
    lower bound (every certificate's bound is valid, certified or not), the gap and the reason.

    Parameters
    ----------
    graph : PoseGraph
        Connected.
    initial : array_like, shape (n, 3), optional
        Start here instead of LAGO (e.g. ``graph.poses``, the odometry).
    tree : str, optional
        LAGO's spanning tree (:func:`lagolib.lago.regularize`).
    max_escapes : int
        The budget of escape steps, each one rank up the staircase (``>= 0``).  An escape costs
        a rank-``r`` Newton polish (the dominant cost: a few to a few tens of factorizations of
        a ``(4 r - 1) n`` system), a rounding, a rank-one polish and a certificate.
    max_iterations : int
        The budget of Newton iterations of the rank-``r`` polishes (``r >= 2``), summed over the
        staircase (``>= 0``; default :data:`MAX_ITERATIONS`): with ``max_escapes`` it bounds the
        running time by counts, not by a clock.  Each polish is also capped on its own
        (``LIFTED_ITERATIONS``).
    eta : float, optional
        :func:`certify`'s first shift (how much work a certificate does, not what certified
        means).
    verbose : bool
        One line per stage.

    Returns
    -------
    SolveResult
    """
    t_start = time.perf_counter()
    where = "solve"
    if not isinstance(graph, PoseGraph):
        raise OptionTypeError(f"{where}: graph must be a PoseGraph; got {type(graph).__name__}")
    max_escapes = check_int(max_escapes, "max_escapes", where, minimum=0)
    max_iterations = check_int(max_iterations, "max_iterations", where, minimum=0)
    if eta is not None:
        eta = check_real(eta, "eta", where, minimum=0.0)
    verbose = check_bool(verbose, "verbose", where)
    p = chordal_problem(graph)  # checks n >= 2 and connectivity before any work
    # one factorization object for Gauss-Newton, the chordal polish and the final Gauss-Newton:
    # their matrices share the pose graph's pattern, so the ordering and the symbolic analysis
    # are computed once
    shared = _LinearSolver("cholesky", "auto")
    stages, timings = (
        [],
        dict.fromkeys(("lago", "gauss_newton", "refine", "certify", "escape"), 0.0),
    )

    def record(stage, kind, seconds, **info):
        timings[kind] += seconds
        stages.append({"stage": stage, "seconds": seconds, **info})
        if verbose:
            extra = "  ".join(
                f"{k} {v:.10g}" if isinstance(v, float) else f"{k} {v}" for k, v in info.items()
            )
            print(f"{stage:<28s} {seconds * 1e3:8.1f} ms  {extra}")

    def certified_stage(stage, point):
        c = certify(p, point, eta=eta)
        record(stage, "certify", c.seconds, certified=c.certified, lambda_min=_lm(c))
        return c

    def polish(X, r, cap, spent, label, tol=1e-14):
        """``refine_lifted`` within the budget: ``(X, stopped by its own test, spent)``."""
        cap = min(cap, max_iterations - spent)
        t = time.perf_counter()
        X, f_X, it = refine_lifted(p, X, tol=tol, max_iterations=cap)
        record(f"rank-{r} polish{label}", "refine", time.perf_counter() - t, f=f_X, iterations=it)
        return X, it < cap, spent + it

    def certify_or_stop(stage, point, r):
        """``(Certificate, None)``, or ``(None, reason)`` when its factorization failed its
        check: the staircase stops there with what it has."""
        try:
            return certified_stage(stage, point), None
        except BackendError as exc:
            return None, f"not certified: the certificate at rank {r} cannot be trusted: {exc}"

    if initial is None:
        t = time.perf_counter()
        kw = {} if tree is None else {"tree": tree}
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RegularizationWarning)
            start = lago(graph, **kw).poses
        for w in caught:  # the certificate settles what the warning can only suspect
            if not issubclass(w.category, RegularizationWarning):  # pragma: no cover
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        info = {"chi2": chi2(graph, start)}
        if any(issubclass(w.category, RegularizationWarning) for w in caught):
            info["warning"] = "LAGO's regularization may be wrong (RegularizationWarning)"
        record("LAGO", "lago", time.perf_counter() - t, **info)
    else:
        start = as_graph_poses(graph, initial, "initial", "initial guess")
    start_chi2 = chi2(graph, start)
    gn = _gauss_newton(graph, start, shared)
    record(
        "Gauss-Newton", "gauss_newton", gn.timings["total"], chi2=gn.chi2, iterations=gn.iterations
    )
    ref = _polish(p, gn.poses, shared)
    record("chordal polish", "refine", ref.timings["total"], f=ref.chi2, iterations=ref.iterations)
    if shared.factor is not None:  # the certificate factors another matrix meanwhile
        shared.factor.release()
    cert = certified_stage("certificate", ref.poses)
    best, best_cert, bound = ref.poses, cert, max(cert.lower_bound, 0.0)
    X, X_cert, r = to_complex(ref.poses)[:, None], cert, 1
    escapes = spent = 0
    polished = True  # the last polish of X stopped by its own test, not at its cap
    reason = None
    while reason is None:
        if best_cert.certified:
            reason = "certified" + (
                f" after {escapes} escape(s), through rank {r}" if escapes else ""
            )
            break
        if best_cert.f - bound <= best_cert.tolerance:
            reason = (
                f"certified by the lower bound of the rank-{r} relaxation: f is within "
                f"{best_cert.f - bound:.3g} of it (tolerance {best_cert.tolerance:.3g})"
            )
            break
        if r > 1 and X_cert.certified:  # the relaxation's optimum, and it is not rank one
            reason = (
                f"not certified: the rank-{r} relaxation is certified optimal but its "
                "solution is not rank one (the relaxation is not tight); the gap is the bound"
            )
            break
        if not X_cert.saddle:  # not certified, and no direction of negative curvature
            if r > 1 and not polished and spent < max_iterations:
                # the rank-r polish stopped at its cap before a stationary point: polish on
                X, polished, spent = polish(X, r, LIFTED_ITERATIONS[1], spent, " (tight)")
                X_cert, failure = certify_or_stop(f"rank-{r} certificate", X, r)
                if X_cert is None:
                    reason = failure
                    break
                bound = max(bound, X_cert.lower_bound)
                continue
            where_ = "the chordal polish" if r == 1 else f"the rank-{r} polish"
            if r > 1 and not polished:
                why = f"was stopped by max_iterations={max_iterations} (the staircase's budget)"
            else:
                why = "stopped"
            reason = (
                f"not certified: {where_} {why} at a point that is not stationary (f - "
                f"sum(lambda) = {X_cert.stationarity:.3g}, lambda_min(S~) {_lm_text(X_cert)}, "
                f"tolerance {X_cert.tolerance:.3g}): the certificate has no direction of "
                "negative curvature to escape along; the gap is the bound"
            )
            break
        if escapes >= max_escapes:
            reason = f"not certified: the budget of max_escapes={max_escapes} ran out"
            break
        if spent >= max_iterations:
            reason = (
                "not certified: the Newton iterations of the staircase's polishes reached "
                f"max_iterations={max_iterations}"
            )
            break
        t = time.perf_counter()
        X, alpha = escape(p, X, X_cert)  # one rank up, along the eigenvector of lambda_min
        record(f"escape to rank {X.shape[1]}", "escape", time.perf_counter() - t, alpha=alpha)
        if alpha == 0.0:  # pragma: no cover - the second-order decrease is guaranteed
            reason = "not certified: no escape step decreases the cost"
            break
        escapes += 1
        r = X.shape[1]
        # a loose polish at rank r is enough to find the basin: rounding + the rank-one Newton
        # polish converge fast; near a rank-deficient optimum Newton at rank r is only linear
        X, polished, spent = polish(X, r, LIFTED_ITERATIONS[0], spent, "", tol=LOOSE_TOL)
        ref = _polish(p, round_solution(p, X), shared)  # back to rank one
        record(
            "round + chordal polish",
            "refine",
            ref.timings["total"],
            f=ref.chi2,
            iterations=ref.iterations,
        )
        cert, failure = certify_or_stop("certificate", ref.poses, r)
        if cert is None:
            reason = failure
            break
        bound = max(bound, cert.lower_bound)
        if cert.certified or cert.f < best_cert.f:
            best, best_cert = ref.poses, cert
        if best_cert.certified or best_cert.f - bound <= best_cert.tolerance:
            continue  # certified: said at the top of the loop
        # not yet: polish the relaxation to the last digits and ask its certificate
        X, polished, spent = polish(X, r, LIFTED_ITERATIONS[1], spent, " (tight)")
        X_cert, failure = certify_or_stop(f"rank-{r} certificate", X, r)
        if X_cert is None:
            reason = failure
            break
        bound = max(bound, X_cert.lower_bound)
    # Gauss-Newton on chi2 from the chordal point that was certified: the polish (and any
    # escape) may have left the basin of the first Gauss-Newton result; the certificate's
    # matrices are not needed by it (memory: they would sit beside its factor)
    p._drop_matrices()
    final = _gauss_newton(graph, best, shared)
    record(
        "Gauss-Newton",
        "gauss_newton",
        final.timings["total"],
        chi2=final.chi2,
        iterations=final.iterations,
    )
    timings["total"] = time.perf_counter() - t_start
    return SolveResult(
        poses=final.poses,
        chi2=final.chi2,
        chordal_poses=best,
        f=best_cert.f,
        certificate=best_cert,
        certified=reason.startswith("certified"),
        escapes=escapes,
        reason=reason,
        stages=stages,
        timings=timings,
        graph=graph.with_poses(final.poses),
        lower_bound=bound,
        start_chi2=start_chi2,
        iterations=spent,
    )


def _lm(cert):
    return "> -eta" if cert.lambda_min is None else cert.lambda_min


def _lm_text(cert):
    return (
        f"> -{cert.eta:.3g} (not computed)"
        if cert.lambda_min is None
        else f"= {cert.lambda_min:.3g}"
    )


def _gauss_newton(graph, start, solver=None):
    """Gauss–Newton on χ² from ``start``; Levenberg–Marquardt when Gauss–Newton cannot proceed.
    ``solver`` (a ``_LinearSolver``) is reused by every run."""

    def run(x, method):
        options = dict(_OPTIMIZE_DEFAULTS, method=method)
        return _optimize(graph, x, **options, solver=solver)

    try:
        res = run(start, "gn")
    except NotPositiveDefiniteError:
        return run(start, "lm")
    if not res.converged:
        lm = run(res.poses, "lm")
        if lm.chi2 < res.chi2:
            return lm
    return res


def _polish(problem, start, solver):
    """:func:`refine` with its defaults, factoring with ``solver``."""
    return _refine(problem, start, **_REFINE_DEFAULTS, solver=solver)


def _defaults(fn, skip):
    """``fn``'s keyword defaults, without ``skip``."""
    import inspect

    params = inspect.signature(fn).parameters.values()
    return {p.name: p.default for p in params if p.name not in skip and p.default is not p.empty}


_OPTIMIZE_DEFAULTS = _defaults(optimize, ("initial", "method"))
_REFINE_DEFAULTS = _defaults(refine, ("initial",))
