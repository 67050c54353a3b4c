"""Incidence matrices, spanning trees, fundamental circuits and cycle bases (Carlone et al. 2011)."""

import networkx as nx
import numpy as np
import pytest

import lagolib
from lagolib import GraphError, PoseGraph, se2, simulate
from lagolib import topology as T


def _graph(n, edges, z=None):
    m = len(edges)
    z = np.zeros((m, 3)) if z is None else np.asarray(z, dtype=float)
    return PoseGraph(np.zeros((n, 3)), edges, z, np.tile(np.eye(3), (m, 1, 1)))


@pytest.fixture(scope="module")
def grid():
    return simulate.grid_world(rows=6, cols=7, rng=3).graph


@pytest.fixture(scope="module")
def laps():
    return simulate.loop_world(laps=3, poses_per_lap=16, closure_probability=0.7, rng=4).graph


def test_incidence_matrix_columns_and_rank(grid):
    A = T.incidence_matrix(grid)
    assert A.shape == (grid.n, grid.m)
    dense = A.toarray()
    e = grid.edges
    np.testing.assert_array_equal(dense[e[:, 0], np.arange(grid.m)], -1.0)
    np.testing.assert_array_equal(dense[e[:, 1], np.arange(grid.m)], 1.0)
    np.testing.assert_array_equal(dense.sum(axis=0), 0.0)
    # Prop. 1: rank n for n + 1 connected nodes, full row rank after deleting any row
    assert np.linalg.matrix_rank(dense) == grid.n - 1
    for anchor in (0, 17, grid.n - 1):
        Ar = T.reduced_incidence_matrix(grid, anchor).toarray()
        assert Ar.shape == (grid.n - 1, grid.m)
        assert np.linalg.matrix_rank(Ar) == grid.n - 1
        np.testing.assert_array_equal(Ar, np.delete(dense, anchor, axis=0))


def test_rank_of_a_disconnected_graph_counts_components():
    g = _graph(6, [(0, 1), (1, 2), (2, 0), (3, 4), (4, 5)])
    assert np.linalg.matrix_rank(T.incidence_matrix(g).toarray()) == 6 - 2
    assert T.cyclomatic_number(g) == 5 - 6 + 2


def test_position_incidence_matrix_is_kron_with_explicit_stacking(laps):
    A = T.reduced_incidence_matrix(laps)
    A2 = T.position_incidence_matrix(A)
    np.testing.assert_array_equal(A2.toarray(), np.kron(A.toarray(), np.eye(2)))
    # rho = [x1 y1 x2 y2 ...]: A2^T rho stacks [x_j - x_i, y_j - y_i] per edge
    rng = np.random.default_rng(0)
    P = rng.normal(size=(laps.n, 2))
    P[0] = 0.0  # the anchor
    diff = (A2.T @ P[1:].ravel()).reshape(-1, 2)
    np.testing.assert_allclose(diff, P[laps.edges[:, 1]] - P[laps.edges[:, 0]], atol=1e-15)


@pytest.mark.parametrize("kind", ["odometric", "bfs"])
def test_spanning_tree_structure(laps, kind):
    tree = T.spanning_tree(laps, kind)
    assert tree.edges.size == laps.n - 1
    assert tree.d == laps.m - laps.n + 1 == T.cyclomatic_number(laps)
    # the tree edges alone connect all vertices
    sub = _graph(laps.n, laps.edges[tree.edges])
    assert sub.is_connected
    assert tree.order[0] == tree.root and set(tree.order) == set(range(laps.n))
    pos = np.empty(laps.n, dtype=int)
    pos[tree.order] = np.arange(laps.n)
    child = tree.order[1:]
    assert np.all(pos[tree.parent[child]] < pos[child])  # parents come first
    np.testing.assert_array_equal(tree.depth[child], tree.depth[tree.parent[child]] + 1)
    if kind == "odometric":  # Prop. 2 / Cor. 3: chords are the loop closures
        np.testing.assert_array_equal(tree.chords, np.flatnonzero(laps.loop_closure))
    else:
        dist = nx.single_source_shortest_path_length(nx.Graph(laps.edges.tolist()), 0)
        np.testing.assert_array_equal(tree.depth, [dist[v] for v in range(laps.n)])


def test_potentials_are_tree_path_sums(laps):
    tree = T.spanning_tree(laps, "bfs", anchor=5)
    values = np.random.default_rng(1).normal(size=laps.m)
    phi = tree.potentials(values)
    for v in (0, 7, 30, laps.n - 1):
        edges, signs = tree.path(tree.root, v)
        assert phi[v] == pytest.approx(signs @ values[edges], abs=1e-12)
    assert phi[tree.root] == 0.0


def test_cycle_basis_matrix(laps):
    basis = T.cycle_basis(laps)
    d = laps.m - laps.n + 1
    assert basis.C.shape == (d, laps.m) and basis.d == d
    ordered = basis.ordered.toarray()
    np.testing.assert_array_equal(ordered[:, :d], np.eye(d))  # eq. (19): [I_d B]
    assert set(np.unique(basis.B.toarray())) <= {-1.0, 0.0, 1.0}
    # every circuit enters each node as often as it leaves it
    assert abs(basis.C @ T.incidence_matrix(laps).T).max() == 0.0
    # the circuits are independent and span the cycle space (Theorem 2)
    assert np.linalg.matrix_rank(basis.C.toarray()) == d


@pytest.mark.parametrize("maker", ["grid", "manhattan", "laps"])
def test_cyclomatic_number_matches_networkx(maker, grid, laps):
    g = {
        "grid": grid,
        "laps": laps,
        "manhattan": simulate.manhattan_world(n_poses=150, rng=2).graph,
    }[maker]
    G = nx.MultiGraph()
    G.add_nodes_from(range(g.n))
    G.add_edges_from(g.edges.tolist())
    simple = nx.Graph(G)
    parallel = G.number_of_edges() - simple.number_of_edges()
    assert len(nx.cycle_basis(simple)) + parallel == T.cyclomatic_number(g)
    assert T.cycle_basis(g, "bfs").d == T.cyclomatic_number(g)


def test_fundamental_circuits_close_up_on_noiseless_data():
    sim = simulate.loop_world(laps=3, poses_per_lap=12, noiseless=True)
    g = sim.graph
    tree = T.spanning_tree(g)
    for chord in tree.chords:
        edges, signs = T.fundamental_circuit(g, tree, chord)
        assert edges[0] == chord
        # composing the measurements around the circuit gives the identity transform
        X = np.eye(3)
        for k, s in zip(edges, signs, strict=True):
            z = g.measurements[k] if s > 0 else se2.inverse(g.measurements[k])
            X = X @ se2.v2t(z)
        np.testing.assert_allclose(X, np.eye(3), atol=1e-12)


def test_cycle_sums_via_potentials_equal_the_matrix(benchmark):
    g = lagolib.read(benchmark("intel"))
    for kind in ("odometric", "bfs"):
        reg = lagolib.lago.regularize(g, kind)
        C = T.cycle_basis(g, reg.tree).C
        np.testing.assert_allclose(C @ reg.delta, reg.cycle_sums, atol=1e-9)
        nu = -2 * np.pi * np.round(C @ reg.delta / (2 * np.pi))
        np.testing.assert_allclose(reg.delta_bar[reg.chords] - reg.delta[reg.chords], nu)


def test_parallel_edges_and_backward_odometry():
    # 0 -> 1 twice, 2 -> 1 stored backward (as in GTSAM's .graph files), 2 -> 0 closes the loop
    g = _graph(3, [(0, 1), (0, 1), (2, 1), (2, 0)])
    tree = T.odometric_tree(g)
    np.testing.assert_array_equal(np.sort(tree.edges), [0, 2])
    np.testing.assert_array_equal(tree.chords, [1, 3])
    basis = T.cycle_basis(g)
    np.testing.assert_array_equal(basis.C.toarray(), [[-1, 1, 0, 0], [1, 0, -1, 1]])


def test_errors_name_the_problem():
    broken = _graph(4, [(0, 1), (2, 3), (0, 2), (1, 3)])
    with pytest.raises(GraphError, match=r"vertex ids 1 and 2.*tree='bfs'"):
        T.odometric_tree(broken)
    assert T.bfs_tree(broken).edges.size == 3
    apart = _graph(4, [(0, 1), (2, 3)])
    with pytest.raises(GraphError, match="not connected: 2 components"):
        T.bfs_tree(apart)
    with pytest.raises(GraphError, match="anchor: vertex id 9 is not in the graph"):
        T.reduced_incidence_matrix(apart, anchor=9)
    with pytest.raises(ValueError, match="tree must be one of"):
        T.spanning_tree(apart, "dfs")
    with pytest.raises(GraphError, match="not a chord"):
        T.fundamental_circuit(broken, T.bfs_tree(broken), 0)
