"""Issue 26: the certificate on the supernodal path, and the pipeline's shared analysis.

The certificate's ``L D L^H`` is now factored in complex Hermitian form (``2 n - 1`` rows) by
MKL PARDISO (``mtype = -4``, inertia from its pivots) or SciPy's SuperLU; the chordal polish
assembles its Newton Hessian in closed form on Gauss–Newton's fixed pattern; ``certify.solve``
shares one symbolic analysis among its Gauss–Newton runs and the polish.  Each engine is
checked against dense linear algebra, and the two engines against each other.
"""

import numpy as np
import pytest
from test_certify import _reduced_dense, _rotated_anisotropic

import lagolib
from lagolib import certify as C
from lagolib import linalg, simulate
from lagolib.errors import BackendError
from lagolib.linalg import _have_cholmod, _mkl_runtime

ENGINES = (
    ["superlu"]
    + (["pardiso"] if _mkl_runtime() is not None else [])
    + (["cholmod"] if _have_cholmod() else [])
)


def _loop(seed=0, laps=3, per_lap=12, sigma_theta=0.3):
    sim = simulate.loop_world(laps=laps, poses_per_lap=per_lap, rng=seed, sigma_theta=sigma_theta)
    rng = np.random.default_rng(seed)
    return sim.graph.with_information(_rotated_anisotropic(sim.graph.m, rng))


@pytest.fixture
def engine(request, monkeypatch):
    """Force the certificate's engine (PARDISO or CHOLMOD is chosen from 5 x 10^4 real rows
    otherwise)."""
    name = request.param
    monkeypatch.setattr(C, "_auto_backend", lambda N: name.replace("superlu", "qdldl"))
    return name


@pytest.mark.parametrize("engine", ENGINES, indirect=True)
def test_positive_definite_verdicts_are_the_dense_inertia(engine):
    """``K + s I_z`` is positive definite iff ``lambda_min(S~) > -s``, at shifts on both sides of
    each of the smallest eigenvalues, at a stationary point and at a point that is not one."""
    g = _loop(3)
    p = C.chordal_problem(g)
    rng = np.random.default_rng(3)
    stationary = C.refine(p, g.poses).poses
    for poses in (stationary, g.poses + rng.normal(0.0, 0.4, g.poses.shape)):
        x = C.to_complex(poses)
        lam = C.multipliers(p, x)
        ev = np.linalg.eigvalsh(_reduced_dense(C.certificate_matrix(p, x).toarray(), p.n))
        factor = C._ShiftedFactor(p, lam)
        assert factor.engine == engine
        gaps = np.diff(ev[:4])
        for k in range(3):
            for side in (-1.0, 1.0):  # just above / below -lambda_k
                s = -ev[k] + side * 0.25 * max(gaps[k], 1e-6)
                assert factor.factor(s) == bool(ev[0] > -s), (k, side, s, ev[:4])


@pytest.mark.parametrize("engine", ENGINES, indirect=True)
def test_negative_pivots_count_the_eigenvalues_below_the_shift(engine):
    """PARDISO's inertia (iparm[21], iparm[22]) is Sylvester's count of the dense eigenvalues."""
    if engine != "pardiso":
        pytest.skip(f"{engine} reports only positive definiteness here")
    g = _loop(5)
    p = C.chordal_problem(g)
    x = C.to_complex(g.poses + np.random.default_rng(5).normal(0.0, 0.4, g.poses.shape))
    lam = C.multipliers(p, x)
    S = C.certificate_matrix(p, x).toarray()
    keep = np.r_[np.arange(1, p.n), p.n + np.arange(p.n)]
    ev = np.linalg.eigvalsh(S[np.ix_(keep, keep)])  # K itself: translations and rotations
    F, U, zpos, _, u_slots = p._hermitian_form
    factor = C._ShiftedFactor(p, lam)
    factor.factor(1.0)  # builds the analysis
    for s in (0.0, 0.5 * abs(ev[0]), 2.0 * abs(ev[0])):
        udata = U.data.copy()
        udata[u_slots] = factor._base + s
        pos, neg, perturbed = factor._pardiso.inertia(udata)
        # K + s I_z differs from K on the rotations only: count its own dense eigenvalues
        Ks = S[np.ix_(keep, keep)] + s * np.diag(np.r_[np.zeros(p.n - 1), np.ones(p.n)])
        want = int(np.sum(np.linalg.eigvalsh(Ks) < 0))
        assert perturbed == 0 and neg == want and pos == F.shape[0] - want


@pytest.mark.parametrize("engine", ENGINES, indirect=True)
def test_eigenvalues_and_bound_equal_the_dense_schur_complement(engine):
    g = _loop(7)
    p = C.chordal_problem(g)
    rng = np.random.default_rng(7)
    for poses in (C.refine(p, g.poses).poses, g.poses + rng.normal(0.0, 0.4, g.poses.shape)):
        cert = C.certify(p, poses, eigenvalues=3)
        x = C.to_complex(poses)
        ev = np.linalg.eigvalsh(_reduced_dense(C.certificate_matrix(p, x).toarray(), p.n))
        scale = np.abs(ev).max()
        np.testing.assert_allclose(cert.eigenvalues, ev[:3], atol=1e-9 * scale)
        assert cert.certified == (ev[0] >= -cert.eta)
        bound = cert.multipliers.sum() + p.n * min(ev[0], 0.0)
        assert cert.lower_bound == pytest.approx(bound, abs=1e-8 * scale)
        assert cert.backward_error <= C.SOLVE_TOL


def test_the_engines_give_the_same_certificates(monkeypatch):
    """On a 1500-pose world at its optimum and at a local minimum of a noisy loop."""
    if len(ENGINES) < 2:
        pytest.skip("neither MKL nor CHOLMOD is installed")
    world = simulate.manhattan_world(n_poses=1500, extent=24, rng=2).graph
    pw = C.chordal_problem(world)
    at_optimum = C.refine(pw, C.solve(world).chordal_poses).poses
    g = _loop(1, laps=4, per_lap=8, sigma_theta=0.5)
    pl = C.chordal_problem(g)
    local = C.refine(pl, lagolib.optimize(g, g.poses, method="lm").poses).poses
    out = {}
    for name in ENGINES:
        monkeypatch.setattr(C, "_auto_backend", lambda N, name=name: name.replace("superlu", "q"))
        out[name] = [C.certify(pw, at_optimum, eigenvalues=2), C.certify(pl, local)]
    for name in ENGINES[1:]:
        for a, b in zip(out["superlu"], out[name]):
            assert a.certified == b.certified
            assert a.lower_bound == pytest.approx(b.lower_bound, rel=1e-10)
            np.testing.assert_allclose(a.eigenvalues, b.eigenvalues, rtol=1e-7, atol=1e-9)
            assert b.backward_error <= C.SOLVE_TOL
    for name in ENGINES:
        assert out[name][0].certified and not out[name][1].certified


@pytest.mark.parametrize("engine", ENGINES, indirect=True)
def test_a_bad_factorization_is_refused_on_every_engine(engine, monkeypatch):
    g = _loop(3)
    p = C.chordal_problem(g)
    x = C.refine(p, g.poses).poses
    if engine == "pardiso":
        solve = C._PardisoSolve.solve
        monkeypatch.setattr(C._PardisoSolve, "solve", lambda self, b: 1.6 * solve(self, b))
    elif engine == "cholmod":
        solve = C._Cholmod.solve
        monkeypatch.setattr(C._Cholmod, "solve", lambda self, b: 1.6 * solve(self, b))
    else:
        splu = C.spla.splu

        class Off:
            def __init__(self, lu):
                self.lu, self.perm_r, self.U = lu, lu.perm_r, lu.U

            def solve(self, b):
                return 1.6 * self.lu.solve(b)

        monkeypatch.setattr(C.spla, "splu", lambda *a, **k: Off(splu(*a, **k)))
    with pytest.raises(BackendError, match="backward error"):
        C.certify(p, x)


def test_weights_spread_over_thirteen_orders_give_one_verdict_on_every_engine(monkeypatch):
    """A chain with information 1e-6 beside 1e7: K + s I_z is positive definite (dense) with a
    pivot 1e-13 of its diagonal, accurate nonetheless; every engine must say so, and certify
    alike (CHOLMOD once refused it by a relative pivot check, and certify() raised)."""
    rng = np.random.default_rng(0)
    poses = np.column_stack([np.arange(3.0), rng.normal(0, 0.1, 3), rng.normal(0, 0.3, 3)])
    z = np.column_stack([np.ones(2), rng.normal(0, 0.1, 2), rng.normal(0, 0.3, 2)])
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    info = [1e-6 * Q @ np.diag([1.0, 2.0, 3.0]) @ Q.T, 1e7 * Q @ np.diag([1.0, 2.0, 3.0]) @ Q.T]
    g = lagolib.PoseGraph(poses, [(0, 1), (1, 2)], z, info)
    p = C.chordal_problem(g)
    x = C.refine(p, g.poses).poses
    lam = C.multipliers(p, C.to_complex(x))
    ev = np.linalg.eigvalsh(_reduced_dense(C.certificate_matrix(p, C.to_complex(x)).toarray(), 3))
    certs = {}
    for name in ENGINES:
        monkeypatch.setattr(C, "_auto_backend", lambda N, name=name: name.replace("superlu", "q"))
        factor = C._ShiftedFactor(p, lam)
        for s in (-0.5 * ev[0], 2.0 * abs(ev[0]), 1e-5):
            assert factor.factor(s) == bool(ev[0] > -s), (name, s, ev[:2])
        certs[name] = C.certify(p, x)
    for name, cert in certs.items():
        assert cert.certified == certs["superlu"].certified == (ev[0] >= -cert.eta), name
        assert cert.lower_bound == pytest.approx(certs["superlu"].lower_bound, rel=1e-9), name


def _newton_reference(p, poses, free):
    """``H = 2 Re(P^H S P)`` and ``b = 2 Re(P^H M x)`` by the definition: dense products of the
    complex matrices (the readable form of :class:`ChordalNewtonSystem`)."""
    n = p.n
    x = C.to_complex(poses)
    lam = C.multipliers(p, x)
    S = C.certificate_matrix(p, x).toarray()
    P = np.zeros((2 * n, 3 * free.size), dtype=complex)
    for r, i in enumerate(free):
        P[i, 3 * r], P[i, 3 * r + 1] = 1.0, 1j  # dx, dy move t_i
        P[n + i, 3 * r + 2] = 1j * x[n + i]  # omega moves z_i along its circle
    assert np.allclose(S @ x, p.M @ x - np.r_[np.zeros(n), lam * x[n:]])
    return 2.0 * (P.conj().T @ S @ P).real, 2.0 * (P.conj().T @ (p.M @ x)).real


def test_closed_form_newton_system_equals_the_product_of_the_complex_matrices():
    g = _loop(11, laps=2, per_lap=8)
    p = C.chordal_problem(g)
    poses = g.poses + np.random.default_rng(11).normal(0.0, 0.3, g.poses.shape)
    system = C.ChordalNewtonSystem(p, fixed=[int(g.ids[0])])
    H, b, f = system.assemble(poses)
    H_ref, b_ref = _newton_reference(p, poses, system.free)
    scale = np.abs(H_ref).max()
    np.testing.assert_allclose(H.toarray(), H_ref, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(b, b_ref, rtol=0, atol=1e-12 * np.abs(b_ref).max())
    assert f == pytest.approx(C.chordal_cost(p, poses), rel=1e-13)
    # the pattern is Gauss-Newton's: one symbolic analysis serves both
    gn = lagolib.gauss_newton.LinearSystem(g, fixed=[int(g.ids[0])])
    Hgn = gn.assemble(poses)[0]
    assert np.array_equal(H.indptr, Hgn.indptr) and np.array_equal(H.indices, Hgn.indices)


# ----------------------------------------------------------------------------- backend="auto"
def _heavy_system(seed=4):
    """H of a 600-pose world with 150 random long closures (fill far above its row count's)."""
    g = simulate.manhattan_world(n_poses=600, extent=15, rng=seed).graph
    g = simulate.add_outliers(g, 150, policy="random", rng=seed).graph
    system = lagolib.gauss_newton.LinearSystem(g, fixed=[int(g.ids[0])])
    return system, system.assemble(g.poses)


@pytest.mark.skipif(len(ENGINES) < 2, reason="MKL is not installed")
def test_auto_moves_to_pardiso_after_a_costly_first_factorization(monkeypatch):
    from lagolib import linalg

    system, (H, b, _) = _heavy_system()
    reference = linalg.SparseCholesky(H, "qdldl", check=False)
    monkeypatch.setattr(linalg, "PARDISO_MIN_MFLOP", 0.1 * reference.mflops)
    factor = linalg.SparseCholesky(H, "auto", check=False, ordering=system.ordering)
    assert factor.backend == "qdldl" and factor.mflops == pytest.approx(reference.mflops)
    x1 = factor.solve(-b)
    factor.refactor(H)  # the second factorization: PARDISO, in the system's ordering
    assert factor.backend == "pardiso" and factor.fallback is None
    x2 = factor.solve(-b)
    np.testing.assert_allclose(x2, x1, rtol=0, atol=1e-9 * np.abs(x1).max())
    assert factor.last_check.backward_error <= linalg.BACKWARD_ERROR_TOL
    # below the threshold, or with a backend asked for by name, qdldl stays
    monkeypatch.setattr(linalg, "PARDISO_MIN_MFLOP", 10.0 * reference.mflops)
    for backend in ("auto", "qdldl"):
        f = linalg.SparseCholesky(H, backend, check=False)
        f.refactor(H)
        assert f.backend == "qdldl"


def test_auto_stays_on_qdldl_without_mkl(monkeypatch):
    from lagolib import linalg

    system, (H, b, _) = _heavy_system()
    monkeypatch.setattr(linalg, "PARDISO_MIN_MFLOP", 0.0)
    monkeypatch.setattr(linalg, "_mkl_runtime", lambda: None)
    monkeypatch.setenv("LAGOLIB_CHOLMOD", "off")  # the default install: neither
    f = linalg.SparseCholesky(H, "auto", check=False)
    f.refactor(H)
    assert f.backend == "qdldl" and f.mflops > 0


@pytest.mark.skipif(not linalg._have_cholmod(), reason="cvxopt (CHOLMOD) is not installed")
def test_auto_moves_to_cholmod_without_mkl(monkeypatch):
    from lagolib import linalg

    system, (H, b, _) = _heavy_system()
    x = linalg.SparseCholesky(H, "qdldl", check=False).solve(-b)
    monkeypatch.setattr(linalg, "PARDISO_MIN_MFLOP", 0.0)
    monkeypatch.setattr(linalg, "_mkl_runtime", lambda: None)
    f = linalg.SparseCholesky(H, "auto", check=False, ordering=system.ordering)
    f.refactor(H)
    assert f.backend == "cholmod"
    np.testing.assert_allclose(f.solve(-b), x, rtol=0, atol=1e-9 * np.abs(x).max())


@pytest.mark.skipif(len(ENGINES) < 2, reason="MKL is not installed")
def test_a_released_factor_cannot_be_used_and_refactors_as_before():
    from lagolib import linalg
    from lagolib.errors import NotPositiveDefiniteError

    system, (H, b, _) = _heavy_system(5)
    f = linalg.SparseCholesky(H, "pardiso", check=False, ordering=system.ordering)
    x = f.solve(-b)
    f.release()
    with pytest.raises(NotPositiveDefiniteError, match="released"):
        f.solve(-b)
    f.refactor(H)  # the analysis was kept: a numerical factorization only
    np.testing.assert_allclose(f.solve(-b), x, rtol=0, atol=1e-12 * np.abs(x).max())
    q = linalg.SparseCholesky(H, "qdldl", check=False)
    q.release()  # nothing to free apart: the factor stays usable
    np.testing.assert_allclose(q.solve(-b), x, rtol=0, atol=1e-9 * np.abs(x).max())
