"""Pairwise consistency maximization (lagolib.consistency): clique solver, loop covariance, PCM."""

import itertools

import networkx as nx
import numpy as np
import pytest
from scipy import sparse

from lagolib import se2
from lagolib.consistency import (
    CliqueTimeLimitWarning,
    _loop,
    consistency_graph,
    maximum_clique,
    pcm,
)
from lagolib.errors import GraphError, OptionError, OptionTypeError
from lagolib.graph import PoseGraph
from lagolib.simulate import manhattan_world


def _random_graph(rng, n, p):
    A = np.triu(rng.random((n, n)) < p, 1)
    return A | A.T


def _is_clique(A, c):
    return all(A[i, j] for i, j in itertools.combinations(c, 2))


def _brute_force(A):
    n = len(A)
    for k in range(n, 0, -1):
        for c in itertools.combinations(range(n), k):
            if _is_clique(A, c):
                return k
    return 0


def test_maximum_clique_equals_brute_force_on_small_graphs():
    rng = np.random.default_rng(0)
    sizes = []
    for _ in range(200):
        n = int(rng.integers(1, 13))
        A = _random_graph(rng, n, rng.uniform(0.1, 0.9))
        c = maximum_clique(A)
        assert _is_clique(A, c) and np.all(np.diff(c) > 0)
        assert c.size == _brute_force(A)
        sizes.append(c.size)
    assert sum(sizes) == 650  # a fixed seed: the same graphs, the same cliques


def test_maximum_clique_equals_networkx_on_medium_graphs():
    rng = np.random.default_rng(1)
    for n, p in [(40, 0.5), (60, 0.7), (80, 0.3), (50, 0.9)]:
        A = _random_graph(rng, n, p)
        c = maximum_clique(A)
        _, weight = nx.max_weight_clique(nx.from_numpy_array(A.astype(int)), weight=None)
        assert _is_clique(A, c) and c.size == weight
        assert np.array_equal(maximum_clique(sparse.csr_matrix(A)), c)  # sparse input, same answer


def test_greedy_is_a_maximal_clique():
    rng = np.random.default_rng(2)
    for _ in range(30):
        A = _random_graph(rng, 70, rng.uniform(0.2, 0.9))
        c = maximum_clique(A, exact=False)
        assert _is_clique(A, c)
        outside = np.setdiff1d(np.arange(70), c)
        assert not np.any(A[np.ix_(outside, c)].all(axis=1))  # maximal: nothing can be added
        assert c.size <= maximum_clique(A).size


def test_maximum_clique_is_deterministic_and_breaks_ties_by_index():
    A = np.zeros((6, 6), dtype=bool)
    for i, j in [(0, 1), (2, 3), (4, 5)]:  # three cliques of size 2
        A[i, j] = A[j, i] = True
    assert maximum_clique(A).tolist() == [0, 1]
    assert maximum_clique(np.zeros((3, 3), dtype=bool)).tolist() == [0]
    assert maximum_clique(np.zeros((0, 0), dtype=bool)).tolist() == []


def test_time_limit_warns_and_returns_a_clique():
    rng = np.random.default_rng(3)
    A = _random_graph(rng, 300, 0.9)
    with pytest.warns(CliqueTimeLimitWarning, match="time budget"):
        c = maximum_clique(A, time_limit=1e-3)
    assert _is_clique(A, c)


# ------------------------------------------------------------------ the loop's covariance
def _small_world():
    """25 poses, one backward-stored odometry step, anisotropic rotated information."""
    rng = np.random.default_rng(4)
    n = 25
    truth = np.zeros((n, 3))
    for t in range(1, n):
        truth[t] = se2.compose(truth[t - 1], [1.0, 0.2 * np.sin(t), 0.35])
    odo = [[t, t + 1] for t in range(n - 1)]
    odo[7] = [8, 7]
    edges = np.array(odo + [[2, 20], [5, 23], [0, 14], [21, 3]])
    z = se2.between(truth[edges[:, 0]], truth[edges[:, 1]])
    info = np.empty((len(edges), 3, 3))
    for k in range(len(edges)):
        R = np.linalg.qr(rng.standard_normal((3, 3)))[0]
        info[k] = np.linalg.inv(R @ np.diag([0.02, 0.005, 0.001]) ** 2 @ R.T * (1 + k % 3))
    return truth, edges, z, info


def _loop_samples(truth, edges, z, a, b, eta):
    """log(D_a D_b^-1) for K noise samples eta (K, m, 3), composing the noisy odometry."""
    K, n = len(eta), len(truth)
    zs = se2.compose(z[None], se2.exp(eta))  # Z -> Z Exp(eta)
    X = np.zeros((K, n, 3))
    X[:, 0] = truth[0]
    for s in range(n - 1):
        i, j = edges[s]
        step = zs[:, s] if i == s else se2.inverse(zs[:, s])
        X[:, s + 1] = se2.compose(X[:, s], step)

    def D(k):
        i, j = edges[k]
        return se2.compose(se2.compose(X[:, i], zs[:, k]), se2.inverse(X[:, j]))

    return se2.log(se2.compose(D(a), se2.inverse(D(b))))


def test_loop_covariance_matches_monte_carlo():
    truth, edges, z, info = _small_world()
    g = PoseGraph(truth, edges, z, info)
    closures = np.arange(24, 28)
    rng = np.random.default_rng(5)
    chol = np.linalg.cholesky(np.linalg.inv(info))
    K = 20000
    eta = np.einsum("kab,nkb->nka", chol, rng.standard_normal((K, len(edges), 3)))
    worst = 0.0
    for a, b in [(0, 1), (0, 3), (1, 2), (2, 3)]:
        v0, S = _loop(g, closures, a, b)
        assert np.allclose(v0, 0.0, atol=1e-12)
        v = _loop_samples(truth, edges, z, 24 + a, 24 + b, eta)
        # whitened empirical covariance: the identity when Sigma is right
        W = np.linalg.cholesky(np.linalg.inv(S))
        white = W.T @ np.cov(v.T) @ W
        worst = max(worst, np.abs(white - np.eye(3)).max())
        d2 = np.einsum("ka,ab,kb->k", v, np.linalg.inv(S), v)
        assert abs(d2.mean() - 3.0) < 0.1  # chi-square with 3 degrees of freedom
    assert worst < 0.05, worst


# ------------------------------------------------------------------ simulated world
@pytest.fixture(scope="module")
def world():
    return manhattan_world(n_poses=400, closure_probability=0.3, rng=0)


def _with_extra(g, edges, z):
    info = np.concatenate([g.information, np.repeat(g.information[-1:], len(edges), 0)])
    return PoseGraph(
        g.poses, np.vstack([g.edges, edges]), np.vstack([g.measurements, z]), info, ids=g.ids
    )


def test_true_closures_are_mostly_consistent(world):
    g = world.graph
    cg = consistency_graph(g)
    L = cg.closures.size
    iu = np.triu_indices(L, 1)
    frac = cg.adjacency[iu].mean()
    assert L == 803 and 0.99 < frac < 0.999, (L, frac)  # <= 1 % rejected at confidence 0.99
    frac999 = (consistency_graph(g, confidence=0.999).adjacency[iu]).mean()
    assert frac999 > frac and frac999 > 0.997
    assert np.array_equal(cg.closures, np.flatnonzero(g.loop_closure))
    assert np.allclose(cg.d2, cg.d2.T) and not cg.adjacency.diagonal().any()


def test_a_shifted_closure_is_inconsistent_with_the_true_ones(world):
    g = world.graph
    k = int(np.flatnonzero(g.loop_closure)[10])
    z = g.measurements.copy()
    z[k, 0] += 5.0  # 5 m off
    bad = PoseGraph(g.poses, g.edges, z, g.information, ids=g.ids)
    cg = consistency_graph(bad)
    a = int(np.flatnonzero(cg.closures == k)[0])
    others = np.delete(np.arange(cg.closures.size), a)
    assert cg.adjacency[a, others].mean() < 0.01
    assert np.median(cg.d2[a, others]) > 5 * cg.threshold


def test_pcm_removes_random_and_grouped_wrong_closures(world):
    g, truth = world.graph, world.truth
    rng = np.random.default_rng(6)
    n = g.n
    edges, z = [], []
    while len(edges) < 20:  # random wrong closures
        i, j = rng.integers(0, n, 2)
        if abs(i - j) > 10:
            edges.append([i, j])
            z.append([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-np.pi, np.pi)])
    # a group of 5 mutually consistent wrong closures: i+s -> j+s, all off by the same transform
    i, j, off = 50, 300, np.array([2.0, -1.5, 0.7])
    moved_j = se2.compose(truth[j], off)  # as if pose j stood elsewhere
    for s in range(5):
        edges.append([i + s, j + s])
        z.append(
            se2.between(truth[i + s], se2.compose(moved_j, se2.between(truth[j], truth[j + s])))
        )
    bad = _with_extra(g, np.array(edges), np.array(z))
    wrong = np.zeros(bad.m, dtype=bool)
    wrong[g.m :] = True
    cg = consistency_graph(bad)
    group = np.flatnonzero(np.isin(cg.closures, np.arange(g.m + 20, bad.m)))
    assert cg.adjacency[np.ix_(group, group)].sum() == 20  # the group agrees with itself
    # at 0.99 about 0.3 % of right pairs fail by chance, and a maximum clique drops every closure
    # that fails with one kept: 0.999 keeps far more of the right ones
    result = pcm(bad, confidence=0.999)
    assert result.optimal
    assert not np.any(result.inlier & wrong)  # every wrong closure removed
    dropped = int(np.sum(~result.inlier & ~wrong))
    assert dropped <= 20, dropped  # few right ones lost
    assert np.all(result.inlier[bad.odometric])
    greedy = pcm(bad, confidence=0.999, exact=False)
    assert not np.any(greedy.inlier & wrong)
    assert greedy.clique.size <= result.clique.size


# ------------------------------------------------------------------ bad input
def test_bad_input_raises_lagolib_errors(world):
    g = world.graph
    with pytest.raises(OptionError, match="square"):
        maximum_clique(np.zeros((2, 3), dtype=bool))
    with pytest.raises(OptionError, match="symmetric"):
        maximum_clique(np.array([[0, 1], [0, 0]], dtype=bool))
    with pytest.raises(OptionTypeError, match="adjacency"):
        maximum_clique(np.array([["a", "b"], ["c", "d"]]))
    with pytest.raises(OptionError, match="0/1"):
        maximum_clique(np.array([[0, 2], [2, 0]]))
    with pytest.raises(OptionError, match="time_limit"):
        maximum_clique(np.eye(2, dtype=bool), time_limit=-1.0)
    with pytest.raises(OptionTypeError, match="exact"):
        maximum_clique(np.eye(2, dtype=bool), exact="yes")
    with pytest.raises(OptionError, match="confidence"):
        consistency_graph(g, confidence=1.0)
    with pytest.raises(OptionError, match="closures"):
        consistency_graph(g, closures=[g.m + 5])
    with pytest.raises(OptionError, match="odometric chain"):
        consistency_graph(g, closures=[0])
    with pytest.raises(OptionError, match="twice"):
        consistency_graph(g, closures=[g.m - 1, g.m - 1])
    broken = PoseGraph(g.poses, g.edges[1:], g.measurements[1:], g.information[1:], ids=g.ids)
    with pytest.raises(GraphError, match="pairwise consistency needs the odometry"):
        pcm(broken)
