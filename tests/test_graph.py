"""PoseGraph: validation messages, structure (odometric mask, components), odometry guess, residuals, chi2."""

import networkx as nx
import numpy as np
import pytest

import lagolib
from lagolib import GraphError, PoseGraph, se2, simulate


def small(**override):
    args = dict(
        poses=np.zeros((4, 3)),
        edges=[[0, 1], [1, 2], [2, 3], [3, 0]],
        measurements=[[1, 0, np.pi / 2]] * 4,
        information=np.tile(np.diag([10.0, 10.0, 100.0]), (4, 1, 1)),
    )
    args.update(override)
    return PoseGraph(**args)


def test_construction_and_immutability():
    g = small(ids=[10, 11, 12, 13])
    assert (g.n, g.m) == (4, 4)
    assert g.ids.tolist() == [10, 11, 12, 13]
    for arr in (g.poses, g.edges, g.measurements, g.information, g.ids):
        with pytest.raises(ValueError):
            arr[0] = 1
    assert repr(g) == "PoseGraph(n=4, m=4, odometric=3, loop_closures=1)"


@pytest.mark.parametrize(
    "override, message",
    [
        (dict(poses=np.zeros((4, 2))), r"poses must have shape \(n, 3\)"),
        (
            dict(poses=np.array([[0, 0, 0], [np.nan, 0, 0], [0, 0, 0], [0, 0, 0]])),
            r"pose of vertex id 1 \(index 1\) is not finite",
        ),
        (
            dict(edges=[[0, 1], [1, 2], [2, 3], [3, 4]]),
            r"edge 3 refers to vertex index \[3, 4\] but the graph has 4 vertices",
        ),
        (
            dict(edges=[[0, 1], [1, 2], [2, 2], [3, 0]]),
            r"edge 2 \(vertex ids 2 -> 2\) is a self-loop",
        ),
        (dict(edges=[[0, 1.5], [1, 2], [2, 3], [3, 0]]), r"integer vertex indices"),
        (dict(measurements=[[1, 0, 0]] * 3), r"measurements must have shape \(4, 3\)"),
        (
            dict(measurements=[[1, 0, 0], [1, 0, 0], [np.inf, 0, 0], [1, 0, 0]]),
            r"edge 2 \(vertex ids 2 -> 3\) has a non-finite measurement",
        ),
        (dict(ids=[0, 1, 1, 3]), r"vertex id 1 appears more than once"),
        (dict(ids=[0.0, 1.0, 2.0, 3.0]), r"ids must be 4 integers"),
        (dict(poses=[["a", 0, 0]] * 4), r"poses must be a numeric array"),
        (
            dict(measurements=[[1, 0], [1, 0], [1, 0, 0], [1, 0, 0]]),
            r"measurements must be a numeric",
        ),
        (dict(measurements=[[1, 0]] * 3), r"measurements must have shape \(4, 3\); got \(3, 2\)"),
        (dict(edges=[[0, np.nan], [1, 2], [2, 3], [3, 0]]), r"integer vertex indices"),
        (dict(edges=[[0, np.inf], [1, 2], [2, 3], [3, 0]]), r"integer vertex indices"),
        (dict(edges=[["0", "1"]] * 4), r"edges must be a numeric array"),
        (
            dict(information=np.tile(np.eye(3), (3, 1, 1))),
            r"information must have shape \(4, 3, 3\)",
        ),
    ],
)
def test_invalid_graphs_name_the_problem(override, message):
    with pytest.raises(GraphError, match=message):
        small(**override)


def test_non_positive_definite_information_names_the_edge():
    info = np.tile(np.eye(3), (4, 1, 1))
    info[2] = np.diag([1.0, -1.0, 1.0])
    with pytest.raises(
        GraphError, match=r"edge 2 \(vertex ids 2 -> 3\).*not positive definite"
    ) as exc:
        small(information=info)
    assert exc.value.edge == 2
    info[2] = [[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]
    with pytest.raises(GraphError, match=r"edge 2 .*not symmetric"):
        small(information=info)
    info[2] = np.zeros((3, 3))
    with pytest.raises(GraphError, match=r"edge 2 .*not positive definite"):
        small(information=info)


def test_empty_graph_is_allowed():
    g = PoseGraph(np.zeros((1, 3)), [], [], [])
    assert (g.n, g.m, g.is_connected) == (1, 0, True)
    assert lagolib.chi2(g) == 0.0


def test_lagolib_errors_are_catchable_as_one_class():
    with pytest.raises(lagolib.LagolibError):
        small(ids=[0, 0, 1, 2])


def test_odometric_mask_follows_id_order_not_index_order():
    # rows stored out of id order: ids 30, 10, 20 -> id order is rows 1, 2, 0
    g = PoseGraph(
        np.zeros((3, 3)),
        [[1, 2], [2, 0], [0, 1], [1, 0]],
        np.zeros((4, 3)),
        np.tile(np.eye(3), (4, 1, 1)),
        ids=[30, 10, 20],
    )
    assert g.odometric.tolist() == [True, True, False, False]
    assert g.loop_closure.tolist() == [False, False, True, True]
    assert g.order.tolist() == [2, 0, 1]


def test_edges_stored_backwards_and_duplicates_are_kept():
    g = small(edges=[[1, 0], [1, 2], [1, 2], [3, 2]])
    assert g.m == 4
    assert g.edges.tolist() == [[1, 0], [1, 2], [1, 2], [3, 2]]
    assert g.odometric.tolist() == [False, True, True, False]


def test_components_match_networkx():
    rng = np.random.default_rng(7)
    for trial in range(20):
        n = int(rng.integers(2, 30))
        m = int(rng.integers(1, 40))
        e = rng.integers(0, n, size=(m, 2))
        e = e[e[:, 0] != e[:, 1]]
        g = PoseGraph(
            np.zeros((n, 3)), e, np.zeros((len(e), 3)), np.tile(np.eye(3), (len(e), 1, 1))
        )
        G = nx.Graph()
        G.add_nodes_from(range(n))
        G.add_edges_from(e.tolist())
        count, labels = g.components()
        assert count == nx.number_connected_components(G), trial
        assert g.is_connected == nx.is_connected(G)
        for comp in nx.connected_components(G):
            assert len({labels[v] for v in comp}) == 1


def test_odometry_guess_composes_the_chain():
    sim = simulate.loop_world(laps=2, poses_per_lap=8, noiseless=True)
    g = sim.graph
    np.testing.assert_allclose(g.odometry_guess(start=sim.truth[0]), sim.truth, atol=1e-12)
    # the composition written out one step at a time (the readable version)
    x = [sim.truth[0]]
    odo = g.edges[g.odometric]
    for k in np.argsort(odo[:, 0]):
        x.append(se2.compose(x[-1], g.measurements[g.odometric][k]))
    np.testing.assert_allclose(g.odometry_guess(), np.array(x), atol=1e-12)


def test_odometry_guess_uses_backward_edges_and_reports_gaps():
    truth = np.array([[0, 0, 0], [1, 0, 0.5], [1.5, 1, 1.0], [1, 2, 2.0]])
    edges = np.array([[0, 1], [2, 1], [2, 3]])  # the middle link is stored backwards
    z = se2.between(truth[edges[:, 0]], truth[edges[:, 1]])
    g = PoseGraph(np.zeros((4, 3)), edges, z, np.tile(np.eye(3), (3, 1, 1)))
    np.testing.assert_allclose(g.odometry_guess(), truth, atol=1e-12)
    gap = PoseGraph(
        np.zeros((4, 3)), edges[[0, 2]], z[[0, 2]], np.tile(np.eye(3), (2, 1, 1)), ids=[5, 6, 7, 8]
    )
    with pytest.raises(GraphError, match=r"no edge between vertex ids 6 and 7 \(1 gap"):
        gap.odometry_guess()


def test_odometry_guess_picks_the_first_of_duplicate_edges():
    info = np.tile(np.eye(3), (2, 1, 1))
    g = PoseGraph(np.zeros((2, 3)), [[0, 1], [0, 1]], [[1, 0, 0], [2, 0, 0]], info)
    assert g.odometry_guess()[1, 0] == 1.0


def test_with_poses():
    g = small()
    h = g.with_poses(np.ones((4, 3)))
    assert np.all(h.poses == 1) and np.all(g.poses == 0)
    assert h.edges is g.edges
    with pytest.raises(GraphError, match=r"poses must have shape \(4, 3\)"):
        g.with_poses(np.ones((3, 3)))
    with pytest.raises(GraphError, match=r"not finite"):
        g.with_poses(np.full((4, 3), np.nan))


def residual_by_definition(z, xi, xj):
    """The lecture notes' e_ij = t2v(Z_ij^-1 (X_i^-1 X_j)), with 3x3 matrices."""
    inv = np.linalg.inv
    return se2.t2v(inv(se2.v2t(z)) @ inv(se2.v2t(xi)) @ se2.v2t(xj))


def test_residuals_equal_the_matrix_definition():
    rng = np.random.default_rng(3)
    sim = simulate.manhattan_world(n_poses=60, rng=rng)
    x = sim.graph.poses + rng.normal(scale=0.3, size=(sim.graph.n, 3))
    e = lagolib.residuals(sim.graph, x)
    for k, (i, j) in enumerate(sim.graph.edges):
        np.testing.assert_allclose(
            e[k], residual_by_definition(sim.graph.measurements[k], x[i], x[j]), atol=1e-12
        )


def test_chi2_is_the_weighted_sum():
    sim = simulate.grid_world(rng=5)
    g = sim.graph
    e = lagolib.residuals(g)
    expected = sum(e[k] @ g.information[k] @ e[k] for k in range(g.m))
    assert lagolib.chi2(g) == pytest.approx(expected, rel=1e-13)
    assert lagolib.chi2(g, per_edge=True).shape == (g.m,)
    assert lagolib.chi2(g, sim.truth) < lagolib.chi2(g)


def test_chi2_at_truth_is_zero_for_noiseless_measurements():
    sim = simulate.loop_world(laps=3, poses_per_lap=20, noiseless=True)
    assert lagolib.chi2(sim.graph, sim.truth) < 1e-20


def test_residual_angle_is_wrapped():
    g = PoseGraph(
        np.array([[0, 0, 3.0], [0, 0, -3.0]]),
        [[0, 1]],
        [[0, 0, 0.28318530717958623]],
        np.eye(3)[None],
    )
    # theta_j - theta_i - theta_z = -6.283...  which wraps to ~0
    assert abs(lagolib.residuals(g)[0, 2]) < 1e-15


def test_residuals_reject_wrong_pose_shape():
    with pytest.raises(GraphError, match=r"poses must have shape \(4, 3\)"):
        lagolib.chi2(small(), np.zeros((5, 3)))


# ----------------------------------------------------------------------------- hardened inputs
@pytest.mark.parametrize(
    "inside, outside, problem",
    [
        (np.diag([1e100, 1e100, 1e100]), np.diag([1.01e100, 1e99, 1e99]), "overflows"),
        (np.diag([1e-100, 1e-100, 1e-100]), np.diag([0.99e-100, 1e-100, 1e-100]), "underflows"),
        (np.diag([1.0, 1.0, 1e-13]), np.diag([1.0, 1.0, 1e-15]), "numerically singular"),
        (np.diag([1e-100, 1e-100, 1e-100]), np.diag([1e-320, 1e-320, 1e-320]), "underflows"),
    ],
)
def test_information_limits(inside, outside, problem):
    """Eigenvalues in [1e-100, 1e100] and condition numbers up to 1e14 are accepted."""
    info = np.tile(np.diag([10.0, 10.0, 100.0]), (4, 1, 1))
    info[1] = inside
    assert small(information=info).information[1].tolist() == inside.tolist()
    info[1] = outside
    assert lagolib.graph.first_bad_information(info) == 1
    with pytest.raises(GraphError, match=rf"edge 1 \(vertex ids 1 -> 2\): information .*{problem}"):
        small(information=info)


def test_angle_bound_is_max_angle():
    bound = se2.MAX_ANGLE
    assert bound == 1e9
    ok = small(poses=[[0, 0, 0], [0, 0, bound], [0, 0, -bound], [0, 0, 0]])
    assert ok.poses[1, 2] == bound
    beyond = np.nextafter(bound, np.inf)
    with pytest.raises(
        GraphError, match=r"vertex id 2 \(index 2\) has the angle -1000000000.0000001"
    ):
        small(poses=[[0, 0, 0], [0, 0, 0], [0, 0, -beyond], [0, 0, 0]])
    with pytest.raises(
        GraphError, match=r"edge 0 \(vertex ids 0 -> 1\) has the measured angle"
    ) as exc:
        small(measurements=[[1, 0, beyond]] + [[1, 0, 0]] * 3)
    assert exc.value.edge == 0
    with pytest.raises(GraphError, match=r"vertex id 3 \(index 3\) has the angle"):
        ok.with_poses([[0, 0, 0]] * 3 + [[0, 0, 1e12]])


def test_ids_are_int64_and_never_wrapped():
    extremes = [-(2**63), 2**63 - 1, 2**53 + 1, 0]
    assert small(ids=extremes).ids.tolist() == extremes
    for ids in (np.array([0, 1, 2, 2**63], dtype=np.uint64), [0, 1, 2, 2**63], [0, 1, 2, 2**64]):
        with pytest.raises(
            GraphError, match=r"ids: vertex id 1844674407370955161[56]|92233720368"
        ) as exc:
            small(ids=ids)
        assert exc.value.vertex == 3


def test_errors_carry_the_vertex_index():
    with pytest.raises(GraphError) as exc:
        small(poses=[[0, 0, 0], [0, 0, 0], [0, np.inf, 0], [0, 0, 0]])
    assert (exc.value.vertex, exc.value.edge) == (2, None)
    with pytest.raises(GraphError) as exc:
        small(ids=[5, 6, 5, 7])
    assert exc.value.vertex == 2


def test_complex_and_text_arrays_are_type_errors():
    from lagolib.errors import GraphTypeError

    for override in (
        dict(poses=np.zeros((4, 3), dtype=complex)),
        dict(measurements=np.full((4, 3), 1 + 1e-9j)),
        dict(information=np.tile(np.eye(3), (4, 1, 1)).astype(complex)),
        dict(poses=[["0", "0", "0"]] * 4),
    ):
        with pytest.raises(GraphTypeError) as exc:
            small(**override)
        assert isinstance(exc.value, TypeError)
    with pytest.raises(GraphTypeError, match=r"poses must be a numeric array of real numbers"):
        lagolib.chi2(small(), np.zeros((4, 3), dtype=complex))


def test_with_information_replaces_every_matrix_and_keeps_the_rest():
    g = lagolib.datasets.example("grid100").graph
    h = g.with_information(np.diag([1.0, 2.0, 3.0]))
    assert h.m == g.m and np.array_equal(h.edges, g.edges) and np.array_equal(h.ids, g.ids)
    np.testing.assert_array_equal(
        h.information, np.broadcast_to(np.diag([1.0, 2.0, 3.0]), (g.m, 3, 3))
    )
    np.testing.assert_array_equal(h.measurements, g.measurements)
    np.testing.assert_array_equal(h.poses, g.poses)
    per_edge = np.tile(np.diag([5.0, 5.0, 7.0]), (g.m, 1, 1))
    np.testing.assert_array_equal(g.with_information(per_edge).information, per_edge)
    with pytest.raises(GraphError, match="information"):
        g.with_information(np.diag([1.0, -2.0, 3.0]))
    with pytest.raises(GraphError, match="information"):
        g.with_information(np.eye(2))
