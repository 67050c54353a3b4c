"""Issue 15: the sparse backends (qdldl, MKL PARDISO, SuperLU), selected inversion, the block pattern.

Every backend must give the same answers to 1e-10; PARDISO runs where MKL is installed (CI
installs it through the ``test`` extra) and a subprocess runs the same pipeline with MKL hidden
(``LAGOLIB_MKL_RT=off``), so both paths are exercised in one run.  Graphs carry anisotropic,
rotated information (isotropic information would hide frame errors).
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse as sp

import lagolib
from lagolib import gauss_newton as gn
from lagolib import linalg, simulate
from lagolib.errors import NotPositiveDefiniteError, OptionError, OptionTypeError
from lagolib.uncertainty import information_matrix, marginal_covariances, relative_covariances

HAVE_PARDISO = "pardiso" in linalg.available_backends()
needs_pardiso = pytest.mark.skipif(not HAVE_PARDISO, reason="MKL is not installed")
FACTORING = (
    ["qdldl", "scipy"]
    + (["pardiso"] if HAVE_PARDISO else [])
    + (["cholmod"] if linalg._have_cholmod() else [])
)


def rotated_information(m, rng):
    """Anisotropic information, rotated in x-y and coupled to theta: ``R^T diag R``, (m, 3, 3)."""
    a = rng.uniform(0, np.pi, m)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros((m, 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    R[:, 2, 0] = 0.3  # a shear between x and theta
    D = np.zeros((m, 3, 3))
    D[:, [0, 1, 2], [0, 1, 2]] = rng.uniform([50, 400, 900], [100, 2000, 4000], (m, 3))
    return np.swapaxes(R, 1, 2) @ D @ R


def anisotropic_world(n_poses, seed):
    rng = np.random.default_rng(seed)
    sim = simulate.manhattan_world(
        n_poses=n_poses, rng=rng, extent=max(4, int(np.sqrt(n_poses / 3)))
    )
    g = sim.graph
    return lagolib.PoseGraph(g.poses, g.edges, g.measurements, rotated_information(g.m, rng))


@pytest.fixture(scope="module")
def world():
    return anisotropic_world(400, 150)


def test_available_backends_and_auto():
    have = linalg.available_backends()
    assert have[0] == "qdldl" and have[-1] == "scipy"
    H = sp.identity(5, format="csr")
    assert linalg.SparseCholesky(H).backend == "qdldl"  # small: the teaching default
    big = sp.identity(linalg.PARDISO_MIN_SIZE, format="csr")
    fast = "cholmod" if linalg._have_cholmod() else "qdldl"
    assert linalg.SparseCholesky(big).backend == ("pardiso" if HAVE_PARDISO else fast)


@pytest.mark.parametrize("backend", FACTORING)
def test_backends_agree_on_a_gauss_newton_system(world, backend):
    system = gn.LinearSystem(world, fixed=[0])
    H, b, _ = system.assemble(world.poses)
    dense = np.linalg.solve(H.toarray(), b)  # small graph: a dense reference
    F = linalg.SparseCholesky(H, backend)
    x = F.solve(b)
    assert np.max(np.abs(x - dense)) <= 1e-10 * np.max(np.abs(dense))
    B = np.column_stack([b, 2 * b, -b])  # several right-hand sides at once
    np.testing.assert_allclose(F.solve(B), dense[:, None] * [1, 2, -1], rtol=1e-9, atol=1e-12)
    # a new matrix with the same pattern reuses the analysis; a new pattern gets a new one
    H2, b2, _ = system.assemble(world.poses + 0.01)
    np.testing.assert_allclose(
        F.refactor(H2).solve(b2), np.linalg.solve(H2.toarray(), b2), rtol=1e-8, atol=1e-10
    )
    H3 = system.damped(H2, 5.0)
    np.testing.assert_allclose(
        F.refactor(H3).solve(b2), np.linalg.solve(H3.toarray(), b2), rtol=1e-8, atol=1e-10
    )
    if backend not in ("scipy", "cholmod"):  # (neither reports its factor's size)
        assert F.nnz_L >= H.shape[0] + (sp.triu(H, 1).nnz)  # L holds at least H's pattern


@needs_pardiso
def test_pardiso_reuses_its_analysis_for_the_same_pattern(world):
    system = gn.LinearSystem(world, fixed=[0])
    H, _, _ = system.assemble(world.poses)
    F = linalg.SparseCholesky(H, "pardiso")
    analysis = F._solver
    F.refactor(system.assemble(world.poses * 1.01)[0])  # LinearSystem's next H
    assert F._solver is analysis
    F.refactor(H.copy())  # equal pattern in new arrays
    assert F._solver is analysis
    N = H.shape[0]
    assert H[0, N - 1] == 0  # not in the pattern
    new = sp.csr_matrix(([1.0, 1.0], ([0, N - 1], [N - 1, 0])), shape=H.shape)
    F.refactor(H + new)  # a new symmetric pair of entries
    assert F._solver is not analysis


@pytest.mark.parametrize("backend", FACTORING)
@pytest.mark.parametrize(
    "M, what",
    [
        ([[1.0, 2.0], [2.0, 1.0]], "indefinite"),
        ([[1.0, 0.0], [0.0, -1.0]], "negative diagonal"),
        ([[1.0, 0.0], [0.0, 0.0]], "zero diagonal"),
    ],
)
def test_not_positive_definite_is_named(backend, M, what):
    with pytest.raises(NotPositiveDefiniteError, match="singular|indefinite"):
        linalg.SparseCholesky(sp.csr_matrix(np.array(M)), backend)


def _random_spd(n, seed):
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=0.08, random_state=rng)
    H = sp.csr_matrix(A @ A.T + sp.identity(n))
    H.sort_indices()
    return H


@pytest.mark.parametrize("backend", FACTORING)
def test_duplicate_entries_are_summed_as_scipy_sums_them(backend):
    """A CSR matrix may store one position twice (scipy means the sum); every backend must read
    the sum — before, qdldl refused it, CHOLMOD raised and PARDISO answered wrong."""
    H = _random_spd(30, 3)
    d = H.diagonal()
    coo = H.tocoo()
    off = coo.row != coo.col
    rows = np.concatenate([coo.row[off], np.arange(30), np.arange(30)])
    cols = np.concatenate([coo.col[off], np.arange(30), np.arange(30)])
    vals = np.concatenate([coo.data[off], 0.25 * d, 0.75 * d])  # each diagonal stored twice
    order = np.lexsort((cols, rows))
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=30))])
    D = sp.csr_matrix((vals[order], cols[order], indptr), shape=(30, 30))
    assert not D.has_canonical_format and np.allclose(D.toarray(), H.toarray())
    b = np.arange(1.0, 31.0)
    x = linalg.SparseCholesky(D, backend).solve(b)
    np.testing.assert_allclose(x, np.linalg.solve(H.toarray(), b), rtol=1e-10, atol=0)


@pytest.mark.parametrize("backend", FACTORING)
def test_a_pattern_rewritten_in_place_is_analysed_again(backend):
    """Index arrays the caller changes in place are a new pattern, not the one analysed."""
    H = sp.csr_matrix(np.array([[4.0, 1.0, 0.0], [1.0, 4.0, 1.0], [0.0, 1.0, 4.0]]))
    F = linalg.SparseCholesky(H, backend)
    B = np.array([[4.0, 0.0, 1.0], [0.0, 4.0, 1.0], [1.0, 1.0, 4.0]])
    new = sp.csr_matrix(B)
    H.indptr[:], H.indices[:], H.data[:] = new.indptr, new.indices, new.data
    x = F.refactor(H).solve(np.ones(3))
    np.testing.assert_allclose(x, np.linalg.solve(B, np.ones(3)), rtol=1e-12)


def test_gauss_newton_systems_share_frozen_index_arrays(world):
    """LinearSystem's H share read-only index arrays: the backends know the pattern by address,
    with no O(nnz) comparison and no copy."""
    system = gn.LinearSystem(world, prior=lagolib.Prior.from_sigmas(0, world.poses[0], [0.1] * 3))
    H1, H2 = system.assemble(world.poses)[0], system.assemble(world.poses + 0.01)[0]
    assert H1.has_canonical_format and linalg._same_frozen(H1.indices, H2.indices)
    F = linalg.SparseCholesky(H1, "qdldl", check=False)
    assert F._pattern[1] is H1.indices  # kept, not copied
    with pytest.raises(ValueError):
        H1.indices[0] = 1  # nobody can rewrite them


@pytest.mark.parametrize("backend", [b for b in FACTORING if b in ("pardiso", "cholmod")])
def test_the_given_ordering_survives_a_failed_refactor(backend):
    """A failed refactor (the damped loop's rejected step) and a good one after it keep the
    caller's ordering: the fallback path restores it, it never drops to the backend's own."""
    H = _random_spd(40, 1)
    p = np.arange(40)[::-1].copy()
    off = (H - sp.diags(H.diagonal())).tocsr()
    F = linalg.SparseCholesky(H, backend, ordering=p)
    with pytest.raises(NotPositiveDefiniteError):
        F.refactor((H + 50 * off).tocsr())  # the same pattern, indefinite
    with pytest.raises(NotPositiveDefiniteError):
        F.solve(np.ones(40))  # nothing usable after the failure
    F.refactor(H)
    assert F.backend == backend
    np.testing.assert_array_equal(F.ordering, p)
    np.testing.assert_allclose(F.solve(np.ones(40)), np.linalg.solve(H.toarray(), np.ones(40)))


@pytest.mark.skipif(not linalg._have_cholmod(), reason="cvxopt (CHOLMOD) is not installed")
def test_cholmod_leaves_cvxopt_options_alone_across_threads():
    """cvxopt's cholmod.options are module-wide: lagolib sets them under a lock, per call."""
    import threading

    from cvxopt import cholmod

    saved = dict(cholmod.options)
    cholmod.options.clear()
    mats = [_random_spd(40, 1), _random_spd(60, 2)]
    errors = []

    def work(H, order):
        try:
            for _ in range(40):
                F = linalg.SparseCholesky(H, "cholmod", ordering=order)
                np.testing.assert_allclose(
                    H @ F.solve(np.ones(H.shape[0])), np.ones(H.shape[0]), atol=1e-9
                )
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [
        threading.Thread(target=work, args=(mats[0], np.arange(40)[::-1].copy())),
        threading.Thread(target=work, args=(mats[1], None)),
    ]
    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        leaked = dict(cholmod.options)
    finally:
        sys.setswitchinterval(old)
        cholmod.options.clear()
        cholmod.options.update(saved)
    assert not errors and leaked == {}


@pytest.mark.skipif(not linalg._have_cholmod(), reason="cvxopt (CHOLMOD) is not installed")
def test_cholmod_breakdown_names_a_row_of_h():
    H = _random_spd(30, 4)
    F = linalg.SparseCholesky(H, "cholmod")  # the order is known from now on
    coo = H.tocoo()
    i, j = next((a, b) for a, b in zip(coo.row, coo.col) if a < b)  # a stored pair
    bad = H.tolil()
    bad[i, i] = 1e-3
    bad[i, j] = bad[j, i] = 5.0
    bad = bad.tocsr()
    assert bad.nnz == H.nnz  # the same pattern: only the numerical factorization runs
    with pytest.raises(NotPositiveDefiniteError) as err:
        F._solver.factor(bad.data[F._upper[0]], bad.diagonal())
    row = err.value.pivot
    assert f"row {row}" in str(err.value)
    # in CHOLMOD's elimination order, the rows up to the named one are the first that are not
    # positive definite (dense reference)
    order = F._solver.perm
    k = int(np.flatnonzero(order == row)[0])
    D = bad.toarray()
    lead = lambda j: np.linalg.eigvalsh(D[np.ix_(order[:j], order[:j])]).min()  # noqa: E731
    assert lead(k) > 0 >= lead(k + 1)


@needs_pardiso
def test_pardiso_missing_diagonal_entry_names_the_row():
    H = sp.csr_matrix(np.array([[2.0, 1.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 2.0]]))
    H.eliminate_zeros()  # row 1 stores no diagonal at all
    with pytest.raises(NotPositiveDefiniteError, match="row 1"):
        linalg.SparseCholesky(H, "pardiso")


def test_pardiso_unavailable_is_an_option_error_that_says_how_to_install(monkeypatch):
    monkeypatch.setattr(linalg, "_MKL", {"lib": None, "why": "MKL is not installed (test)"})
    assert "pardiso" not in linalg.available_backends()
    big = sp.identity(linalg.PARDISO_MIN_SIZE, format="csr")
    fast = "cholmod" if linalg._have_cholmod() else "qdldl"  # CHOLMOD stands in when installed
    assert linalg.SparseCholesky(big).backend == fast
    with pytest.raises(OptionError, match=r"lagolib\[fast\]"):
        linalg.SparseCholesky(sp.identity(3, format="csr"), "pardiso")


def test_factors_only_from_qdldl():
    H = sp.csr_matrix(np.array([[4.0, 1.0], [1.0, 3.0]]))
    with pytest.raises(OptionError, match="qdldl"):
        linalg.SparseCholesky(H, "scipy").factors()
    L, d, perm = linalg.SparseCholesky(H, "qdldl").factors()
    P = sp.csr_matrix((np.ones(2), (perm, np.arange(2))), shape=(2, 2))
    eye = sp.identity(2)
    np.testing.assert_allclose(
        (P @ (eye + L) @ sp.diags(d) @ (eye + L).T @ P.T).toarray(), H.toarray()
    )


# ---------------------------------------------------------------- selected inversion


def test_selected_inverse_equals_the_dense_inverse_on_the_factor_pattern(world):
    H, _ = information_matrix(world)
    S = linalg.selected_inverse(H)
    dense = np.linalg.inv(H.toarray())
    r, c = H.nonzero()  # the pattern of H lies inside that of L + L^T
    np.testing.assert_allclose(
        S.entries(r, c), dense[r, c], rtol=1e-9, atol=1e-14 * abs(dense).max()
    )
    F = linalg.SparseCholesky(H, "qdldl")
    L, _, perm = F.factors()
    lr, lc = L.nonzero()  # every entry computed, in H's numbering
    np.testing.assert_allclose(
        S.entries(perm[lr], perm[lc]),
        dense[perm[lr], perm[lc]],
        rtol=1e-8,
        atol=1e-13 * abs(dense).max(),
    )
    blocks = S.blocks(3 * np.arange(H.shape[0] // 3)[:, None] + np.arange(3))
    assert blocks.shape == (H.shape[0] // 3, 3, 3)
    np.testing.assert_allclose(blocks[7], dense[21:24, 21:24], rtol=1e-9)


def test_selected_inverse_on_random_spd_matrices():
    rng = np.random.default_rng(151)
    for N, density in [(1, 1.0), (2, 1.0), (30, 0.2), (200, 0.02), (120, 0.3)]:
        A = sp.random(N, N, density=density, random_state=rng)
        H = sp.csr_matrix(A @ A.T + sp.identity(N))
        S = linalg.selected_inverse(H)
        dense = np.linalg.inv(H.toarray())
        r, c = H.nonzero()
        np.testing.assert_allclose(S.entries(r, c), dense[r, c], rtol=1e-9, atol=1e-13)


def test_selected_inverse_entries_off_the_pattern_are_refused():
    H = sp.csr_matrix(sp.diags([2.0, 3.0, 4.0]))  # diagonal: L has no off-diagonal entries
    S = linalg.selected_inverse(H)
    np.testing.assert_allclose(S.entries([0, 1, 2], [0, 1, 2]), [0.5, 1 / 3, 0.25])
    with pytest.raises(OptionError, match=r"entry \(0, 2\).*not on the pattern"):
        S.entries([0], [2])
    with pytest.raises(OptionError, match="rows in"):
        S.entries([3], [0])
    with pytest.raises(OptionError, match="shape"):
        S.blocks([0, 1])
    with pytest.raises(OptionTypeError, match="SparseCholesky"):
        linalg.selected_inverse(H, factor="qdldl")
    other = linalg.SparseCholesky(sp.csr_matrix(sp.diags([2.0, 3.0, 5.0])), "qdldl")
    with pytest.raises(OptionError, match="not a factorization of H"):
        linalg.selected_inverse(H, factor=other)  # same shape and pattern, another matrix
    same = linalg.selected_inverse(H, factor=linalg.SparseCholesky(H, "qdldl"))
    np.testing.assert_allclose(same.entries([0, 1, 2], [0, 1, 2]), [0.5, 1 / 3, 0.25])


@pytest.mark.parametrize("frame", ["global", "local"])
def test_marginals_by_selected_inversion_equal_column_solves(world, frame):
    x = lagolib.optimize(world).poses
    a = marginal_covariances(world, poses=x, frame=frame)
    b = marginal_covariances(world, poses=x, frame=frame, method="solves", batch=17)
    assert np.all(a[0] == 0)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12 * np.abs(b).max())
    prior = gn.Prior(5, x[5], rotated_information(1, np.random.default_rng(3))[0])
    kw = dict(poses=x, fixed=[], prior=[prior], frame=frame)
    np.testing.assert_allclose(
        marginal_covariances(world, [9, 3, 9], **kw),
        marginal_covariances(world, [9, 3, 9], method="solves", **kw),
        rtol=1e-9,
    )
    np.testing.assert_allclose(
        relative_covariances(world, 11, [0, 11, 40], poses=x, frame=frame),
        relative_covariances(world, 11, [0, 11, 40], poses=x, frame=frame, method="solves"),
        rtol=1e-9,
        atol=1e-15,
    )


def test_marginal_method_is_checked(world):
    with pytest.raises(OptionError, match="method"):
        marginal_covariances(world, method="dense")


# ---------------------------------------------------------------- the block-level pattern


def scalar_pattern_reference(system, graph):
    """The pattern as it was computed before issue 15: np.unique over all 36 m scalar keys."""
    red = np.full(graph.n, -1)
    red[system.free] = np.arange(system.free.size)
    N, comp = system.N, np.arange(3)
    blk = red[np.repeat(graph.edges, 3, axis=1)]
    rows6 = np.where(blk >= 0, 3 * blk + np.tile(comp, 2), -1)
    pblk = red[system._prior_idx]
    rows3 = np.where(pblk[:, None] >= 0, 3 * pblk[:, None] + comp, -1)
    keys = []
    for rows in (rows6, rows3, 3 * np.arange(system.free.size)[:, None] + comp):
        R = np.broadcast_to(rows[:, :, None], rows.shape + rows.shape[1:])
        C = np.broadcast_to(rows[:, None, :], R.shape)
        keep = ((R >= 0) & (C >= 0)).ravel()
        keys.append((R.ravel() * N + C.ravel())[keep])
    return np.unique(np.concatenate(keys))


@pytest.mark.parametrize(
    "fixed, priors",
    [([0], []), ([0, 5, 17], []), ([], [3]), ([2], [2, 7]), ([0], [0]), ("all", [])],
)
def test_block_pattern_equals_the_scalar_pattern_and_the_dense_sum(world, fixed, priors):
    fixed = list(range(world.n)) if fixed == "all" else fixed
    rng = np.random.default_rng(152)
    prior = [gn.Prior(k, world.poses[k] + 0.1, rotated_information(1, rng)[0]) for k in priors]
    system = gn.LinearSystem(world, fixed=fixed, prior=prior)
    H, b, _ = system.assemble(world.poses + 0.02)
    keys = scalar_pattern_reference(system, world)
    coo = H.tocoo()
    assert H.nnz == keys.size == system.nnz
    np.testing.assert_array_equal(np.sort(coo.row.astype(np.int64) * system.N + coo.col), keys)
    # the dense sum of J^T Omega J, edge by edge (lecture notes, "The Linear system")
    dense = np.zeros((system.N, system.N))
    red = np.full(world.n, -1)
    red[system.free] = np.arange(system.free.size)
    x = world.poses + 0.02
    for k, (i, j) in enumerate(world.edges):
        e, A, B = gn.edge_jacobians(x[i], x[j], world.measurements[k])
        J = {i: A, j: B}
        for p in (i, j):
            for q in (i, j):
                if red[p] >= 0 and red[q] >= 0:
                    block = J[p].T @ world.information[k] @ J[q]
                    dense[3 * red[p] : 3 * red[p] + 3, 3 * red[q] : 3 * red[q] + 3] += block
    for pr in prior:  # vertex ids are row numbers in simulated worlds
        r = red[pr.vertex]
        if r >= 0:
            _, Jp = gn.prior_jacobian(x[pr.vertex][None], np.asarray(pr.mean)[None])
            dense[3 * r : 3 * r + 3, 3 * r : 3 * r + 3] += (
                Jp[0].T @ np.asarray(pr.information) @ Jp[0]
            )
    np.testing.assert_allclose(H.toarray(), dense, rtol=1e-12, atol=1e-9)


# ---------------------------------------------------------------- with and without MKL

_PIPELINE = r"""
import json, sys
import numpy as np
import lagolib
from lagolib import linalg
sys.path.insert(0, {tests!r})
from test_backends import anisotropic_world
linalg.PARDISO_MIN_SIZE = 20_000  # so that this 21 000-row graph takes the PARDISO path
g = anisotropic_world(7000, 153)
x0 = lagolib.lago_solve(g).poses
res = lagolib.optimize(g, x0, max_iterations=4)
cov = lagolib.uncertainty.marginal_covariances(g, [0, 100, 6999], poses=res.poses)
F = linalg.SparseCholesky(lagolib.uncertainty.information_matrix(g, res.poses)[0])
print(json.dumps(dict(backends=linalg.available_backends(), auto=F.backend, lago=x0.tolist(),
                      poses=res.poses.tolist(), chi2=res.chi2, cov=cov.tolist())))
"""


def _run_pipeline(env_extra):
    env = dict(os.environ, **env_extra)
    code = _PIPELINE.format(tests=os.path.dirname(__file__))
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600
    )
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def without_mkl():
    """The default install: neither MKL nor cvxopt's CHOLMOD."""
    return _run_pipeline({"LAGOLIB_MKL_RT": "off", "LAGOLIB_CHOLMOD": "off"})


def test_without_mkl_the_default_install_runs_on_qdldl(without_mkl):
    assert without_mkl["backends"] == ["qdldl", "scipy"] and without_mkl["auto"] == "qdldl"


@pytest.mark.skipif(not linalg._have_cholmod(), reason="cvxopt (CHOLMOD) is not installed")
def test_with_cholmod_and_without_the_results_agree(without_mkl):
    """``pip install "lagolib[cholmod]"`` without MKL: the large systems go to CHOLMOD."""
    cholmod = _run_pipeline({"LAGOLIB_MKL_RT": "off"})
    assert "pardiso" not in cholmod["backends"] and cholmod["auto"] == "cholmod"
    for key in ("lago", "poses"):
        a, b = np.array(cholmod[key]), np.array(without_mkl[key])
        assert np.max(np.abs(a - b)) <= 1e-10 * max(1.0, np.max(np.abs(b))), key
    assert cholmod["chi2"] == pytest.approx(without_mkl["chi2"], rel=1e-10)
    np.testing.assert_allclose(cholmod["cov"], without_mkl["cov"], rtol=1e-9, atol=1e-15)


@needs_pardiso
def test_with_and_without_mkl_the_results_agree(without_mkl):
    with_mkl = _run_pipeline({})
    assert with_mkl["auto"] == "pardiso"
    for key in ("lago", "poses"):
        a, b = np.array(with_mkl[key]), np.array(without_mkl[key])
        assert np.max(np.abs(a - b)) <= 1e-10 * max(1.0, np.max(np.abs(b))), key
    assert with_mkl["chi2"] == pytest.approx(without_mkl["chi2"], rel=1e-10)
    np.testing.assert_allclose(with_mkl["cov"], without_mkl["cov"], rtol=1e-9, atol=1e-15)


def test_assembly_in_chunks_equals_one_chunk(world, monkeypatch):
    prior = [gn.Prior(3, world.poses[3] + 0.1, rotated_information(1, np.random.default_rng(4))[0])]
    whole = gn.LinearSystem(world, fixed=[0, 9], prior=prior).assemble(world.poses + 0.05)
    monkeypatch.setattr(gn, "_CHUNK", 7)  # edges per chunk
    parts = gn.LinearSystem(world, fixed=[0, 9], prior=prior).assemble(world.poses + 0.05)
    np.testing.assert_allclose(parts[0].toarray(), whole[0].toarray(), rtol=1e-13, atol=1e-9)
    np.testing.assert_allclose(parts[1], whole[1], rtol=1e-13, atol=1e-12)
    assert parts[2] == pytest.approx(whole[2], rel=1e-13)


class _GenericSystem(gn.LinearSystem):
    """The same system through the generic path: J from edge_jacobians, J^T Omega J by matmul."""

    def _terms(self, poses):
        return super()._terms(poses)


@pytest.mark.parametrize("error", ["t2v", "log"])
def test_closed_form_blocks_equal_the_jacobian_products(world, error):
    x = world.poses + 0.2 * np.random.default_rng(157).standard_normal(world.poses.shape)
    prior = [gn.Prior(4, x[4] + 0.3, rotated_information(1, np.random.default_rng(5))[0])]
    fast = gn.LinearSystem(world, fixed=[2], prior=prior, error=error)
    slow = _GenericSystem(world, fixed=[2], prior=prior, error=error)
    assert fast._closed_form and not slow._closed_form
    (Hf, bf, cf), (Hs, bs, cs) = fast.assemble(x), slow.assemble(x)
    scale = abs(Hs).max()
    assert abs(Hf - Hs).max() <= 1e-13 * scale and abs(Hf - Hf.T).max() == 0
    np.testing.assert_allclose(bf, bs, rtol=1e-12, atol=1e-13 * np.abs(bs).max())
    assert cf == pytest.approx(cs, rel=1e-14)


def test_information_checked_in_chunks_names_the_right_edge(monkeypatch):
    from lagolib import graph as graph_module

    monkeypatch.setattr(graph_module, "_CHECK_CHUNK", 5)  # matrices per chunk
    rng = np.random.default_rng(154)
    m = 23
    info = rotated_information(m, rng)
    info[17] = -info[17]  # not positive definite, in the fourth chunk
    edges = np.column_stack([np.arange(m), np.arange(1, m + 1)])
    with pytest.raises(lagolib.GraphError, match=r"17|\b17\b") as err:
        lagolib.PoseGraph(np.zeros((m + 1, 3)), edges, np.zeros((m, 3)), info)
    assert err.value.edge == 17


def test_selected_inverse_beyond_int32_keys():
    """N > 46341 rows: row * N overflows int32 (the factor's indices are int32)."""
    sim = simulate.loop_world(laps=2, poses_per_lap=7800, rng=np.random.default_rng(155))
    g = sim.graph
    H, free = information_matrix(g)
    assert H.shape[0] ** 2 > 2**31
    S = linalg.selected_inverse(H)
    F = linalg.SparseCholesky(H, "qdldl")
    rng = np.random.default_rng(156)
    for k in rng.choice(free.size, 4, replace=False):
        rows = 3 * k + np.arange(3)
        E = np.zeros((H.shape[0], 3))
        E[rows, [0, 1, 2]] = 1.0
        ref = F.solve(E)[rows]
        np.testing.assert_allclose(
            S.blocks(rows[None])[0], ref, rtol=1e-9, atol=1e-12 * abs(ref).max()
        )
