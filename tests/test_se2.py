"""SE(2) algebra: identities checked with hypothesis, and against the homogeneous-matrix definitions."""

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from lagolib import se2

coord = st.floats(-1e3, 1e3, allow_nan=False)
angle = st.floats(-20.0, 20.0, allow_nan=False)
pose = st.tuples(coord, coord, angle).map(np.array)
poses = arrays(
    np.float64,
    st.tuples(st.integers(1, 6), st.just(3)),
    elements=st.floats(-50, 50, allow_nan=False),
)


def close_poses(a, b, atol=1e-9):
    a, b = np.asarray(a), np.asarray(b)
    np.testing.assert_allclose(a[..., :2], b[..., :2], atol=atol, rtol=1e-9)
    np.testing.assert_allclose(se2.wrap_angle(a[..., 2] - b[..., 2]), 0.0, atol=atol)


@given(st.floats(-1e6, 1e6, allow_nan=False))
def test_wrap_angle_range_and_congruence(theta):
    w = se2.wrap_angle(theta)
    assert -np.pi < w <= np.pi
    k = (theta - w) / (2 * np.pi)
    assert abs(k - round(k)) < 1e-6 * max(1.0, abs(theta))


@given(st.floats(-np.pi, np.pi, allow_nan=False, exclude_min=True))
def test_wrap_angle_keeps_angles_in_range_bit_for_bit(theta):
    assert se2.wrap_angle(theta) == theta


def test_wrap_angle_edges():
    assert se2.wrap_angle(np.pi) == np.pi
    assert se2.wrap_angle(-np.pi) == np.pi
    assert se2.wrap_angle(3 * np.pi) == pytest.approx(np.pi)
    assert se2.wrap_angle(1e-300) == 1e-300
    assert se2.wrap_angle(2 * np.pi) == 0.0
    assert se2.wrap_angle(np.array([[7.0, -7.0]])).shape == (1, 2)


@given(pose)
def test_t2v_inverts_v2t(p):
    q = se2.t2v(se2.v2t(p))
    np.testing.assert_allclose(q[:2], p[:2], rtol=0, atol=0)
    assert q[2] == pytest.approx(se2.wrap_angle(p[2]), abs=1e-12)


@given(pose)
def test_v2t_is_rigid(p):
    T = se2.v2t(p)
    np.testing.assert_allclose(T[:2, :2].T @ T[:2, :2], np.eye(2), atol=1e-15)
    np.testing.assert_allclose(np.linalg.det(T[:2, :2]), 1.0, atol=1e-15)
    np.testing.assert_array_equal(T[2], [0, 0, 1])


@given(pose, pose)
def test_compose_is_matrix_product(a, b):
    close_poses(se2.compose(a, b), se2.t2v(se2.v2t(a) @ se2.v2t(b)), atol=1e-9)


@given(pose)
def test_inverse_is_matrix_inverse_and_cancels(p):
    close_poses(se2.inverse(p), se2.t2v(np.linalg.inv(se2.v2t(p))), atol=1e-9)
    close_poses(se2.compose(p, se2.inverse(p)), np.zeros(3), atol=1e-9)
    close_poses(se2.compose(se2.inverse(p), p), np.zeros(3), atol=1e-9)


@given(pose, pose)
def test_between_definition_eq1(pi, pj):
    # Carlone et al. eq. (1) and the lecture notes' X_i^-1 X_j
    R = se2.rotation(pi[2])
    expected = np.r_[R.T @ (pj[:2] - pi[:2]), pj[2] - pi[2]]
    close_poses(se2.between(pi, pj), expected, atol=1e-9)
    close_poses(se2.between(pi, pj), se2.t2v(np.linalg.inv(se2.v2t(pi)) @ se2.v2t(pj)), atol=1e-9)


@given(pose, pose)
def test_between_undoes_compose(a, b):
    close_poses(se2.between(a, se2.compose(a, b)), b, atol=1e-8)
    close_poses(se2.compose(a, se2.between(a, b)), b, atol=1e-8)


@given(pose, pose, pose)
def test_compose_is_associative(a, b, c):
    close_poses(se2.compose(se2.compose(a, b), c), se2.compose(a, se2.compose(b, c)), atol=1e-7)


@settings(max_examples=50)
@given(poses, poses)
def test_vectorized_equals_one_by_one(a, b):
    k = min(len(a), len(b))
    a, b = a[:k], b[:k]
    for f in (se2.compose, se2.between):
        stacked = f(a, b)
        assert stacked.shape == (k, 3)
        for r in range(k):
            np.testing.assert_array_equal(stacked[r], f(a[r], b[r]))
    np.testing.assert_array_equal(se2.v2t(a)[0], se2.v2t(a[0]))


def test_broadcasting_one_against_many():
    a = np.array([1.0, 2.0, 0.3])
    b = np.arange(12.0).reshape(4, 3)
    out = se2.compose(a, b)
    assert out.shape == (4, 3)
    np.testing.assert_array_equal(out[2], se2.compose(a, b[2]))


def test_rotation_matrix():
    np.testing.assert_allclose(se2.rotation(np.pi / 2), [[0, -1], [1, 0]], atol=1e-16)
    assert se2.rotation(np.zeros((2, 5))).shape == (2, 5, 2, 2)


def test_bad_shapes_are_reported():
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 3\)"):
        se2.compose(np.zeros(2), np.zeros(3))
    with pytest.raises(ValueError, match=r"\(\.\.\., 3, 3\)"):
        se2.t2v(np.eye(2))


def test_log_and_exp_are_inverse_and_match_gtsam():
    rng = np.random.default_rng(50)
    v = rng.normal(size=(400, 3)) * [3, 3, 1]
    v[:, 2] = rng.uniform(-3.1, 3.1, 400)  # log returns angles in (-pi, pi]
    v[:20, 2] *= 1e-6  # through the small-angle series
    v[20, 2] = 0.0
    np.testing.assert_allclose(se2.log(se2.exp(v)), v, atol=1e-12)
    p = rng.normal(size=(400, 3)) * [3, 3, 1.5]
    p[:, 2] = se2.wrap_angle(p[:, 2])
    np.testing.assert_allclose(se2.exp(se2.log(p)), p, atol=1e-12)
    gtsam = pytest.importorskip("gtsam")
    for k in range(0, 400, 7):
        np.testing.assert_allclose(
            se2.log(p[k]), gtsam.Pose2.Logmap(gtsam.Pose2(*p[k])), atol=1e-12
        )
        q = gtsam.Pose2.Expmap(v[k])
        np.testing.assert_allclose(se2.exp(v[k]), [q.x(), q.y(), q.theta()], atol=1e-12)


def test_log_jacobian_equals_central_differences_on_both_sides_of_the_series():
    rng = np.random.default_rng(51)
    p = rng.normal(size=(300, 3)) * [2, 2, 1]
    p[:100, 2] = rng.uniform(-0.03, 0.03, 100)  # around the switch at |theta| = 0.02
    D = se2.log_jacobian(p)
    h = 1e-6
    for a in range(3):
        d = np.zeros(3)
        d[a] = h
        F = (se2.log(p + d) - se2.log(p - d)) / (2 * h)
        np.testing.assert_allclose(D[..., a], F, atol=1e-8)


def test_log_is_continuous_at_the_series_switch():
    theta = np.array([0.02 - 1e-15, 0.02, 0.02 + 1e-15, -0.02])
    p = np.stack([np.full(4, 2.0), np.full(4, -1.0), theta], axis=1)
    out = se2.log(p)
    assert np.ptp(out[:3, 0]) < 1e-14 and np.ptp(out[:3, 1]) < 1e-14
    D = se2.log_jacobian(p)
    assert np.ptp(D[:3], axis=0).max() < 1e-13


def test_max_angle_is_where_angle_reductions_stay_consistent():
    """Below MAX_ANGLE, wrap_angle and the reduction inside cos/sin agree to 1e-7 rad; beyond, the
    disagreement grows with |theta| (float64's spacing is 1.2e-7 at 1e9, 1.2e-4 at 1e12)."""
    rng = np.random.default_rng(20)

    def disagreement(limit):
        theta = rng.uniform(-limit, limit, 20000)
        d = se2.wrap_angle(se2.wrap_angle(theta) - np.arctan2(np.sin(theta), np.cos(theta)))
        return np.abs(d).max()

    assert se2.MAX_ANGLE == 1e9
    assert disagreement(se2.MAX_ANGLE) < 1e-7
    assert disagreement(1e12) > 1e-6


@pytest.mark.parametrize(
    "call",
    [
        lambda z: se2.wrap_angle(z[:, 2]),
        lambda z: se2.rotation(z[:, 2]),
        lambda z: se2.v2t(z),
        lambda z: se2.compose(z, z.real),
        lambda z: se2.between(z.real, z),
        lambda z: se2.inverse(z),
        lambda z: se2.log(z),
        lambda z: se2.exp(z),
        lambda z: se2.log_jacobian(z),
        lambda z: se2.t2v(np.eye(3) + 1e-3j),
    ],
)
def test_complex_input_is_refused_not_truncated(call):
    z = np.array([[1.0 + 0.5j, 2.0, 0.3]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's ComplexWarning would mean a silent truncation
        with pytest.raises(TypeError, match=r"must be real; got a complex array"):
            call(z)
