"""The BLUE in information form and first-order propagation, against dense textbook formulas."""

import numpy as np
import pytest
import scipy.sparse as sp

from lagolib import NotPositiveDefiniteError
from lagolib.estimation import blue, information_form, joint_information, propagate_covariance


def _spd(rng, k):
    M = rng.normal(size=(k, k))
    return M @ M.T + k * np.eye(k)


def test_blue_equals_the_dense_formula():
    rng = np.random.default_rng(0)
    N, M = 7, 20
    H = sp.random(N, M, density=0.4, random_state=1, format="csr") + sp.hstack(
        [sp.identity(N), sp.csr_matrix((N, M - N))]
    )
    Omega = _spd(rng, M)  # correlated measurement noise
    z = rng.normal(size=M)
    est = blue(H, z, sp.csr_matrix(Omega))
    Hd = H.toarray()
    info = Hd @ Omega @ Hd.T
    np.testing.assert_allclose(est.information.toarray(), info, rtol=1e-13)
    np.testing.assert_allclose(est.estimate, np.linalg.solve(info, Hd @ Omega @ z), rtol=1e-10)
    P = np.linalg.inv(info)
    np.testing.assert_allclose(est.covariance(), P, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(est.covariance([5, 1]), P[np.ix_([5, 1], [5, 1])], rtol=1e-10)


def test_blue_with_a_diagonal_is_weighted_least_squares():
    rng = np.random.default_rng(1)
    H = sp.csr_matrix(rng.normal(size=(3, 12)))
    w = rng.uniform(0.5, 4.0, size=12)
    z = rng.normal(size=12)
    est = blue(H, z, w)
    x_ls = np.linalg.lstsq(np.sqrt(w)[:, None] * H.toarray().T, np.sqrt(w) * z, rcond=None)[0]
    np.testing.assert_allclose(est.estimate, x_ls, rtol=1e-10)
    info, eta = information_form(H, z, np.diag(w))
    np.testing.assert_allclose(info.toarray(), est.information.toarray(), rtol=1e-14)


def test_blue_is_unbiased_and_its_covariance_is_the_spread():
    rng = np.random.default_rng(2)
    H = sp.csr_matrix(rng.normal(size=(2, 6)))
    sigma = rng.uniform(0.1, 0.5, size=6)
    x = np.array([1.0, -2.0])
    runs = np.array(
        [blue(H, H.T @ x + sigma * rng.standard_normal(6), sigma**-2).estimate for _ in range(2000)]
    )
    P = blue(H, np.zeros(6), sigma**-2).covariance()
    np.testing.assert_allclose(runs.mean(axis=0), x, atol=4 * np.sqrt(P.diagonal().max() / 2000))
    np.testing.assert_allclose(np.cov(runs.T), P, rtol=0.1, atol=0.1 * np.abs(P).max())


def test_unobservable_unknown_is_reported():
    H = sp.csr_matrix(np.array([[1.0, -1.0], [-1.0, 1.0]]))  # differences only: no anchor
    with pytest.raises(NotPositiveDefiniteError):
        blue(H, [0.0, 0.0], [1.0, 1.0], backend="scipy")
    with pytest.raises(ValueError, match=r"shape \(2, 2\)"):
        blue(H, [0.0, 0.0], np.eye(3))


def test_joint_information_is_the_block_inverse_of_eq_10():
    rng = np.random.default_rng(3)
    M, N = 6, 4
    Pa, Pb = _spd(rng, M), _spd(rng, N)
    J = rng.normal(size=(M, N))
    Hj = np.block([[np.eye(M), J], [np.zeros((N, M)), np.eye(N)]])
    Pz = propagate_covariance(Hj, np.block([[Pa, np.zeros((M, N))], [np.zeros((N, M)), Pb]]))
    # the explicit form of §IV-C
    np.testing.assert_allclose(Pz[:M, :M], Pa + J @ Pb @ J.T, rtol=1e-12)
    np.testing.assert_allclose(Pz[:M, M:], J @ Pb, rtol=1e-12)
    info = joint_information(
        sp.csr_matrix(np.linalg.inv(Pa)), sp.csr_matrix(J), sp.csr_matrix(np.linalg.inv(Pb))
    )
    np.testing.assert_allclose(info.toarray(), np.linalg.inv(Pz), rtol=1e-9, atol=1e-12)


def test_propagate_covariance_stays_sparse():
    J = sp.random(5, 8, density=0.3, random_state=0, format="csr")
    P = sp.diags(np.arange(1.0, 9.0))
    out = propagate_covariance(J, P)
    assert sp.issparse(out)
    np.testing.assert_allclose(out.toarray(), J.toarray() @ P.toarray() @ J.toarray().T)
