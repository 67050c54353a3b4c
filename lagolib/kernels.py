"""Robust kernels (M-estimators): ρ, ψ and the weight w of a whitened residual.

Least squares charges an edge ``e^T Ω e = r²``: the cost grows without bound, so one wrong loop
closure with a residual of 100 σ pulls on the map 100 times harder than a right one at 1 σ.  An
M-estimator replaces ``r²/2`` by a kernel ``ρ(r)`` that grows more slowly (Huber, Cauchy) or not
at all (Geman–McClure, truncated least squares, DCS) beyond a scale ``c``.  Three functions of
the whitened residual norm ``r = sqrt(e^T Ω e) >= 0`` describe a kernel (Zhang 1997, §4; GTSAM's
``noiseModel.mEstimator`` uses the same convention):

* ``ρ(r)`` — the cost of one edge; ``ρ(r) = r²/2`` is least squares;
* ``ψ(r) = dρ/dr`` — the *influence function*: how hard the edge pulls;
* ``w(r) = ψ(r) / r`` — the *weight*: minimizing ``Σ ρ(r_k)`` by Gauss–Newton is least squares
  with each edge's information scaled by ``w(r_k)``, re-evaluated at every iteration
  (iteratively reweighted least squares, IRLS: the gradient ``Σ ψ(r_k) ∂r_k/∂x`` equals
  ``Σ w(r_k) J_k^T Ω_k e_k``).

lagolib reports robust costs as ``Σ 2 ρ(r_k)``, so that an edge inside the quadratic zone
counts its χ² term ``r²`` as :func:`lagolib.chi2` does (GTSAM's graph error is half of it).

Every kernel's scale defaults to :data:`INLIER_THRESHOLD`, ``c = sqrt(χ²₃(0.999)) ≈ 4.033``: a
right edge's ``r²`` is χ²-distributed with 3 degrees of freedom when its information is right,
so 99.9 % of right edges lie inside ``c``.

References
----------
.. [1] Z. Zhang, "Parameter estimation techniques: a tutorial with application to conic
   fitting", Image and Vision Computing 15(1), 1997.
.. [2] P. Agarwal, G. D. Tipaldi, L. Spinello, C. Stachniss, W. Burgard, "Robust map
   optimization using dynamic covariance scaling", ICRA 2013.
.. [3] H. Yang, P. Antonante, V. Tzoumas, L. Carlone, "Graduated non-convexity for robust
   spatial perception: from non-minimal solvers to global outlier rejection", RA-L 5(2), 2020.
"""

from __future__ import annotations

import math

import numpy as np

from .checks import check_real
from .errors import OptionError, OptionTypeError

__all__ = [
    "INLIER_THRESHOLD",
    "Kernel",
    "LeastSquares",
    "Huber",
    "Cauchy",
    "GemanMcClure",
    "TruncatedLeastSquares",
    "DCS",
    "KERNELS",
    "kernel",
    "gnc_weights",
    "gnc_initial_mu",
]

#: ``sqrt(χ²₃(0.999))``: the whitened residual norm below which 99.9 % of right edges lie (3 dof).
INLIER_THRESHOLD = math.sqrt(16.26623619623813)


def _r(r):
    """The residual norms as a float array (``r >= 0`` is the caller's: ``sqrt(e^T Ω e)``)."""
    return np.abs(np.asarray(r, dtype=float))


class Kernel:
    """A robust kernel of the whitened residual norm ``r``; subclasses define ρ, ψ and w.

    Attributes
    ----------
    name : str
        The short name :func:`kernel` and the CLI accept.
    c : float
        The scale: where the kernel departs from least squares.
    """

    name = "kernel"

    def __init__(self, c=INLIER_THRESHOLD):
        self.c = check_real(c, "c", type(self).__name__, minimum=0.0, strict=True)

    def rho(self, r):
        """ρ(r), the cost of one edge, shape of ``r``."""
        raise NotImplementedError

    def psi(self, r):
        """ψ(r) = dρ/dr, the influence function, shape of ``r``."""
        return self.weight(r) * _r(r)

    def weight(self, r):
        """w(r) = ψ(r)/r, the IRLS weight on the edge's information, shape of ``r``."""
        raise NotImplementedError

    def cost(self, chi2):
        """``2 ρ(sqrt(chi2))``: an edge's robust cost in χ² units (``chi2 = e^T Ω e``)."""
        return 2.0 * self.rho(np.sqrt(np.maximum(np.asarray(chi2, dtype=float), 0.0)))

    def __repr__(self):
        return f"{type(self).__name__}(c={self.c:.6g})"

    def __eq__(self, other):
        return type(self) is type(other) and self.c == other.c

    def __hash__(self):
        return hash((type(self).__name__, self.c))


class LeastSquares(Kernel):
    """ρ(r) = r²/2, ψ(r) = r, w(r) = 1: no robustness (``c`` is unused)."""

    name = "ls"

    def rho(self, r):
        r = _r(r)
        return 0.5 * r * r  # ρ(r) = r²/2

    def weight(self, r):
        return np.ones_like(_r(r))


class Huber(Kernel):
    """Huber's kernel: quadratic inside ``c``, linear outside (convex, influence bounded by c).

    ``ρ(r) = r²/2`` for ``r <= c``, ``c r - c²/2`` beyond; ``ψ(r) = min(r, c)``;
    ``w(r) = min(1, c/r)`` (Zhang 1997, Table 1).

    >>> Huber(2.0).weight([1.0, 4.0]).tolist()
    [1.0, 0.5]
    """

    name = "huber"

    def rho(self, r):
        r, c = _r(r), self.c
        return np.where(r <= c, 0.5 * r * r, c * r - 0.5 * c * c)  # ρ(r), Zhang Table 1

    def weight(self, r):
        r, c = _r(r), self.c
        with np.errstate(divide="ignore"):
            return np.where(r <= c, 1.0, c / np.where(r > 0, r, 1.0))  # w(r) = min(1, c/r)


class Cauchy(Kernel):
    """Cauchy's (Lorentzian) kernel: logarithmic growth, influence falling off as 1/r.

    ``ρ(r) = c²/2 log(1 + r²/c²)``; ``ψ(r) = r / (1 + r²/c²)``; ``w(r) = 1 / (1 + r²/c²)``
    (Zhang 1997, Table 1).

    >>> Cauchy(1.0).weight([0.0, 1.0, 3.0]).tolist()
    [1.0, 0.5, 0.1]
    """

    name = "cauchy"

    def rho(self, r):
        r, c = _r(r), self.c
        return 0.5 * c * c * np.log1p((r / c) ** 2)  # ρ(r) = c²/2 log(1 + r²/c²)

    def weight(self, r):
        r, c = _r(r), self.c
        return 1.0 / (1.0 + (r / c) ** 2)  # w(r) = 1/(1 + r²/c²)


class GemanMcClure(Kernel):
    """Geman–McClure: bounded cost (``ρ -> c²/2``), redescending influence.

    ``ρ(r) = c² r² / (2 (c² + r²))``; ``ψ(r) = c⁴ r / (c² + r²)²``;
    ``w(r) = c⁴ / (c² + r²)²`` (Yang et al. 2020, §IV-A with μ = 1; GTSAM's ``GemanMcClure``).

    >>> GemanMcClure(1.0).weight([0.0, 1.0]).tolist()
    [1.0, 0.25]
    """

    name = "gm"

    def rho(self, r):
        r, c2 = _r(r), self.c**2
        return 0.5 * c2 * r * r / (c2 + r * r)  # ρ(r) = c² r² / (2 (c² + r²))

    def weight(self, r):
        r, c2 = _r(r), self.c**2
        return (c2 / (c2 + r * r)) ** 2  # w(r) = c⁴/(c² + r²)²


class TruncatedLeastSquares(Kernel):
    """Truncated least squares: least squares inside ``c``, a constant ``c²/2`` beyond.

    ``ρ(r) = min(r², c²)/2``; ``ψ(r) = r`` inside, 0 beyond; ``w(r) = 1`` inside, 0 beyond
    (Yang et al. 2020).  Not differentiable at ``c`` and flat beyond it: IRLS with
    this kernel alone keeps whatever classification its start implies — graduated
    non-convexity (:func:`lagolib.robust.gnc`) is how it is meant to be minimized.

    >>> TruncatedLeastSquares(2.0).weight([1.0, 3.0]).tolist()
    [1.0, 0.0]
    """

    name = "tls"

    def rho(self, r):
        r, c = _r(r), self.c
        return 0.5 * np.minimum(r * r, c * c)  # ρ(r) = min(r², c²)/2, Yang et al. 2020

    def weight(self, r):
        return np.where(_r(r) <= self.c, 1.0, 0.0)


class DCS(Kernel):
    """Dynamic covariance scaling (Agarwal et al. 2013): switchable constraints in closed form.

    Switchable constraints (Sünderhauf & Protzel 2012) give each loop closure a switch
    ``s ∈ [0, 1]`` that scales its information by ``s²``, with a prior ``Φ (1 - s)²`` that
    keeps the switch on.  Agarwal et al. (2013) eliminate the switch variable and scale the
    closure in closed form by ``s = min(1, 2Φ / (Φ + χ²))`` with ``χ² = r²``, so the weight on
    the information is ``w(r) = s²`` (GTSAM's ``mEstimator.DCS(Φ)`` weight).  Here ``Φ = c²``
    (the scale in χ² units, :data:`INLIER_THRESHOLD` squared by default; the paper's
    experiments use Φ = 1 with their graphs' information).

    ``ρ`` is the cost whose IRLS weight this is (``ψ = w r``, integrated): ``r²/2`` for
    ``r² <= Φ``, ``3Φ/2 - 2Φ² / (Φ + r²)`` beyond — bounded by ``3Φ/2``.

    >>> DCS(1.0).switch([0.5, 3.0]).tolist()  # Φ = 1
    [1.0, 0.2]
    """

    name = "dcs"

    @property
    def phi(self):
        """Φ = c², the switch prior's weight (χ² units)."""
        return self.c**2

    def switch(self, r):
        """The scaling ``s = min(1, 2Φ/(Φ + r²))`` of Agarwal et al. (2013), in [0, 1]."""
        r, phi = _r(r), self.phi
        return np.minimum(1.0, 2.0 * phi / (phi + r * r))

    def rho(self, r):
        r, phi = _r(r), self.phi
        return np.where(r * r <= phi, 0.5 * r * r, 1.5 * phi - 2.0 * phi**2 / (phi + r * r))

    def weight(self, r):
        return self.switch(r) ** 2  # information scaled by s²


#: The kernels by name (the CLI's ``--robust`` and :func:`kernel`).
KERNELS = {
    k.name: k for k in (LeastSquares, Huber, Cauchy, GemanMcClure, TruncatedLeastSquares, DCS)
}


def kernel(spec, c=None, *, where="kernel"):
    """A :class:`Kernel` from a name (``"huber"``, ``"cauchy"``, ``"gm"``, ``"tls"``, ``"dcs"``,
    ``"ls"``) and a scale (default :data:`INLIER_THRESHOLD`), or a Kernel passed through.

    >>> kernel("cauchy", 2.0)
    Cauchy(c=2)
    """
    if isinstance(spec, Kernel):
        if c is not None:
            raise OptionError(f"{where}: give the scale in the Kernel object, not also as c={c!r}")
        return spec
    if not isinstance(spec, str):
        raise OptionTypeError(
            f"{where}: the robust kernel must be a name ({', '.join(KERNELS)}) or a "
            f"lagolib.kernels.Kernel; got {type(spec).__name__}"
        )
    if spec not in KERNELS:
        raise OptionError(
            f"{where}: unknown robust kernel {spec!r}; choose one of {', '.join(KERNELS)}"
        )
    return KERNELS[spec](INLIER_THRESHOLD if c is None else c)


# ----------------------------------------------------------------------------- GNC surrogates
def gnc_initial_mu(kind, r_max, c):
    """The first control parameter μ of graduated non-convexity (Yang et al. 2020, §V).

    GM starts convex at ``μ = 2 r_max² / c²`` (then μ decreases to 1); TLS at
    ``μ = c² / (2 r_max² - c²)`` (then μ increases), where ``r_max`` is the largest residual
    of the least-squares solution.  ``r_max <= c`` (nothing to reject) gives GM ``μ = 1`` and
    TLS ``μ = inf``: the surrogate is already the kernel.
    """
    c2, r2 = c * c, r_max * r_max
    if kind == "gm":
        return max(1.0, 2.0 * r2 / c2)
    if 2.0 * r2 <= c2:
        return math.inf
    return c2 / (2.0 * r2 - c2)


def gnc_weights(kind, r, mu, c):
    """The weights of GNC's surrogate kernel at control parameter μ (Yang et al. 2020, §V).

    * ``"gm"``: ``w = (μ c² / (μ c² + r²))²`` — least squares as μ → ∞, Geman–McClure at μ = 1;
    * ``"tls"``: ``w = 1`` for ``r² <= μ/(μ+1) c²``, ``w = 0`` for ``r² >= (μ+1)/μ c²`` and
      ``w = c sqrt(μ (μ+1)) / r - μ`` between — convex as μ → 0, TLS as μ → ∞.

    Parameters
    ----------
    kind : {"gm", "tls"}
    r : array_like, shape (k,)
        Whitened residual norms.
    mu, c : float

    Returns
    -------
    ndarray, shape (k,)
    """
    r = _r(r)
    c2 = c * c
    if kind == "gm":
        return (mu * c2 / (mu * c2 + r * r)) ** 2  # the GM surrogate's weight, Yang et al. §V-A
    if math.isinf(mu):
        return np.where(r <= c, 1.0, 0.0)
    lo, hi = mu / (mu + 1.0) * c2, (mu + 1.0) / mu * c2
    with np.errstate(divide="ignore"):
        middle = c * math.sqrt(mu * (mu + 1.0)) / np.where(r > 0, r, 1.0) - mu
    return np.where(r * r <= lo, 1.0, np.where(r * r >= hi, 0.0, middle))  # Yang et al. §V-B
