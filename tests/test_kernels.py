"""Robust kernels: ρ, ψ and w against each other (finite differences, sympy) and against GTSAM."""

import math

import numpy as np
import pytest
import sympy

from lagolib import kernels
from lagolib.errors import OptionError, OptionTypeError
from lagolib.kernels import (
    DCS,
    INLIER_THRESHOLD,
    Cauchy,
    GemanMcClure,
    Huber,
    LeastSquares,
    TruncatedLeastSquares,
)

ALL = [LeastSquares, Huber, Cauchy, GemanMcClure, TruncatedLeastSquares, DCS]
# residuals away from the kinks (Huber, TLS and DCS at r = c are not differentiable there)
R = np.linspace(0.05, 12.0, 240)


def _away_from_kink(k, r):
    return np.abs(r - k.c) > 1e-3


@pytest.mark.parametrize("cls", ALL)
@pytest.mark.parametrize("c", [0.7, 1.0, INLIER_THRESHOLD])
def test_psi_is_the_derivative_of_rho(cls, c):
    k = cls(c)
    r = R[_away_from_kink(k, R)]
    h = 1e-6
    fd = (k.rho(r + h) - k.rho(r - h)) / (2 * h)
    np.testing.assert_allclose(k.psi(r), fd, rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize("cls", ALL)
def test_weight_is_psi_over_r_and_rho_is_continuous(cls):
    k = cls(2.0)
    np.testing.assert_allclose(k.weight(R) * R, k.psi(R), rtol=1e-13)
    eps = 1e-9
    assert abs(float(k.rho(k.c + eps)) - float(k.rho(k.c - eps))) < 1e-7
    assert float(k.weight(0.0)) == 1.0  # every kernel is least squares near zero
    assert float(k.rho(0.0)) == 0.0


def test_closed_forms_by_sympy():
    """ρ of Cauchy, Geman–McClure and DCS differentiated by sympy: ψ/r equals lagolib's w."""
    r, c = sympy.symbols("r c", positive=True)
    phi = c**2
    forms = {
        Cauchy: c**2 / 2 * sympy.log(1 + r**2 / c**2),
        GemanMcClure: c**2 * r**2 / (2 * (c**2 + r**2)),
        DCS: sympy.Rational(3, 2) * phi - 2 * phi**2 / (phi + r**2),  # beyond r² = Φ
    }
    for cls, rho in forms.items():
        w = sympy.lambdify((r, c), sympy.simplify(sympy.diff(rho, r) / r))
        k = cls(1.5)
        rr = np.linspace(1.6, 9.0, 50)
        np.testing.assert_allclose(k.weight(rr), w(rr, 1.5), rtol=1e-12)
        np.testing.assert_allclose(k.rho(rr), sympy.lambdify((r, c), rho)(rr, 1.5), rtol=1e-12)


def test_weights_at_known_points():
    assert Huber(2.0).weight([1.0, 4.0]).tolist() == [1.0, 0.5]
    assert Cauchy(1.0).weight([1.0, 3.0]).tolist() == [0.5, 0.1]
    assert GemanMcClure(1.0).weight([1.0]).tolist() == [0.25]
    assert TruncatedLeastSquares(2.0).weight([2.0, 2.0000001]).tolist() == [1.0, 0.0]
    d = DCS(1.0)  # Φ = 1: s = 2/(1 + r²) beyond r = 1
    np.testing.assert_allclose(d.switch([0.5, 1.0, 3.0]), [1.0, 1.0, 0.2])
    np.testing.assert_allclose(d.weight([3.0]), [0.04])
    # bounded costs: 2 ρ -> c² (GM, TLS), 3Φ (DCS)
    assert float(GemanMcClure(2.0).cost(1e30)) == pytest.approx(4.0)
    assert float(TruncatedLeastSquares(2.0).cost(1e30)) == 4.0
    assert float(DCS(2.0).cost(1e30)) == pytest.approx(12.0)


def test_inlier_threshold_is_the_chi2_quantile():
    from scipy.stats import chi2

    assert INLIER_THRESHOLD**2 == pytest.approx(chi2.ppf(0.999, 3), rel=1e-12)


@pytest.mark.parametrize(
    "cls, gtsam_name, scale",
    [
        (Huber, "Huber", lambda c: c),
        (Cauchy, "Cauchy", lambda c: c),
        (GemanMcClure, "GemanMcClure", lambda c: c),
        (TruncatedLeastSquares, "TruncatedLeastSquares", lambda c: c),
        (DCS, "DCS", lambda c: c * c),  # GTSAM's DCS takes Φ (χ² units)
    ],
)
def test_rho_and_weight_equal_gtsam(cls, gtsam_name, scale):
    gtsam = pytest.importorskip("gtsam")
    for c in (0.8, 2.0, INLIER_THRESHOLD):
        k = cls(c)
        g = getattr(gtsam.noiseModel.mEstimator, gtsam_name).Create(scale(c))
        r = R[_away_from_kink(k, R)]
        np.testing.assert_allclose(k.weight(r), [g.weight(float(x)) for x in r], rtol=1e-12)
        np.testing.assert_allclose(k.rho(r), [g.loss(float(x)) for x in r], rtol=1e-12)


def test_gnc_surrogates_reach_their_kernels():
    r = np.linspace(0.0, 10.0, 101)
    c = 2.0
    # GM: μ = 1 is Geman–McClure, μ -> inf least squares
    np.testing.assert_allclose(kernels.gnc_weights("gm", r, 1.0, c), GemanMcClure(c).weight(r))
    assert np.all(kernels.gnc_weights("gm", r, 1e12, c) > 1 - 1e-9)
    # TLS: μ -> inf is TLS (away from r = c), and the weights are continuous in r
    big = kernels.gnc_weights("tls", r, 1e9, c)
    far = np.abs(r - c) > 1e-3
    np.testing.assert_array_equal(big[far], TruncatedLeastSquares(c).weight(r)[far])
    mu = 0.7
    lo, hi = c * math.sqrt(mu / (mu + 1)), c * math.sqrt((mu + 1) / mu)
    w = lambda x: float(kernels.gnc_weights("tls", [x], mu, c)[0])  # noqa: E731
    assert w(lo - 1e-9) == 1.0 and w(lo + 1e-9) == pytest.approx(1.0, abs=1e-7)
    assert w(hi + 1e-9) == 0.0 and w(hi - 1e-9) == pytest.approx(0.0, abs=1e-7)
    # the first μ: GM convex at 2 r_max²/c²; TLS at c²/(2 r_max² - c²), nothing to do when r <= c
    assert kernels.gnc_initial_mu("gm", 10.0, 2.0) == 50.0
    assert kernels.gnc_initial_mu("tls", 10.0, 2.0) == pytest.approx(4.0 / 196.0)
    assert math.isinf(kernels.gnc_initial_mu("tls", 1.0, 2.0))


def test_kernel_factory_and_misuse():
    assert kernels.kernel("huber") == Huber(INLIER_THRESHOLD)
    assert kernels.kernel("dcs", 1.0).phi == 1.0
    k = Cauchy(3.0)
    assert kernels.kernel(k) is k
    with pytest.raises(OptionError, match="unknown robust kernel 'hubber'"):
        kernels.kernel("hubber")
    with pytest.raises(OptionTypeError):
        kernels.kernel(3)
    with pytest.raises(OptionError, match="not also as c"):
        kernels.kernel(k, 2.0)
    with pytest.raises(ValueError, match="c"):
        Huber(-1.0)
    with pytest.raises(ValueError, match="c"):
        Huber(float("nan"))
