"""Checks for the exercises of chapter 5, *Estimating orientations*.

The chapter is ``book/05_orientation_estimation.ipynb``; its exercises:

* 5.1 (implement) :func:`check_phase1` — phase 1 of LAGO, the BLUE of the orientations
  (Carlone et al. 2011, eq. 13), with sparse matrices;
* 5.2 (implement) :func:`check_regularize_chord` — the regularization of one chord: its cycle sum
  ``(𝒞 δ)_c`` (eq. 22) and its number of turns ``k`` (eq. 23, rounded);
* 5.3 (predict) :func:`check_n_regularized` — how many chords of :func:`closure_world`'s graph need
  regularization with the odometric tree;
* 5.4 (explore) :func:`check_noise_tolerance` — the heading noise at which each spanning tree's
  rounding first picks a wrong ``k`` in :func:`explore_world`.

Every check compares with :mod:`lagolib.lago` (``phase1_orientations``, ``regularize``), prints one
verdict line (see :mod:`lagolib.exercises`) and returns True or False; it never raises on a wrong
answer.
"""

from __future__ import annotations

import contextlib
import functools

import numpy as np

from lagolib import se2, simulate, topology
from lagolib.checks import check_real
from lagolib.exercises._coerce import Function, Int, Real, RealArray, Tuple
from lagolib.exercises._feedback import (
    NOT_ATTEMPTED,
    call_student,
    check,
    compare_array,
    compare_int,
    compare_number,
    matches,
    verdict,
)
from lagolib.graph import PoseGraph
from lagolib.lago import phase1_orientations, regularize, split_information

__all__ = [
    "CLOSURES",
    "SIGMA_GRID",
    "closure_world",
    "explore_world",
    "wrong_k",
    "DenseMatrixRefused",
    "nothing_dense",
    "check_phase1",
    "check_regularize_chord",
    "check_n_regularized",
    "check_noise_tolerance",
    "VARIANCE_SYMBOLS",
    "TRIANGLE_EDGES",
    "triangle_graph",
    "blue_variance_reference",
    "check_blue_variance",
]

TWO_PI = 2.0 * np.pi

# exercise 5.3: the loop closures (tail, head) added to a 3-lap square loop of 20 poses per lap
CLOSURES = ((2, 22), (27, 7), (7, 9), (18, 23), (4, 46), (12, 33), (31, 27), (40, 59), (50, 53))

# exercise 5.4: the heading noise levels of the slider, rad
SIGMA_GRID = tuple(round(0.02 * k, 2) for k in range(1, 31))
_EXPLORE_TREES = ("odometric", "min_uncertainty")


# ---------------------------------------------------------------------------------------------
# 5.1


def _phase1_cases():
    """Two seeded graphs with heterogeneous orientation information, and their A, δ̄, ω.

    1. a 2-lap circular loop with proportional noise (closures are far more precise than the
       turning odometry), anchor = the smallest id;
    2. a 60-pose Manhattan world whose information is anisotropic, rotated and x/y–θ-coupled (so
       ``ω = P_δ⁻¹`` from :func:`lagolib.lago.split_information` is not ``Ω[2, 2]``), anchored
       at a vertex in the middle.
    """
    rng = np.random.default_rng(51)
    loop = simulate.loop_world(
        laps=2, poses_per_lap=12, shape="circle", noise="proportional", sigma_theta=0.1, rng=rng
    ).graph
    man = simulate.manhattan_world(n_poses=60, rng=rng).graph
    m = man.m
    axis = se2.rotation(rng.uniform(-np.pi, np.pi, m))
    cov = np.zeros((m, 3, 3))
    cov[:, :2, :2] = axis @ np.diag([0.05**2, 0.3**2]) @ np.swapaxes(axis, 1, 2)
    cov[:, 2, 2] = rng.uniform(0.01, 0.1, m) ** 2
    cov[:, 0, 2] = cov[:, 2, 0] = 0.4 * 0.05 * np.sqrt(cov[:, 2, 2])
    info = np.linalg.inv(cov)
    man = PoseGraph(man.poses, man.edges, man.measurements, 0.5 * (info + info.transpose(0, 2, 1)))
    cases = []
    for g, anchor in ((loop, None), (man, int(man.ids[man.n // 2]))):
        reg = regularize(g, anchor=anchor, margin_warning=0)
        omega = split_information(g)[1]
        A = topology.reduced_incidence_matrix(g, anchor)
        ref = phase1_orientations(g, reg.delta_bar, anchor=anchor, omega_delta=omega).estimate
        cases.append((g, A, reg.delta_bar, omega, ref))
    return cases


def _weighted_solve(A, delta, w):
    Ad = A.toarray()
    return np.linalg.solve(Ad @ (w[:, None] * Ad.T), Ad @ (w * delta))


class DenseMatrixRefused(Exception):
    """Raised inside a student's function that makes a sparse matrix dense (exercise 5.1)."""


def _sparse_classes():
    """The scipy.sparse classes that define ``toarray`` or ``todense`` themselves."""
    import scipy.sparse as sp

    found = set()
    for name in dir(sp):
        cls = getattr(sp, name)
        if isinstance(cls, type) and issubclass(cls, (sp.spmatrix, sp.sparray)):
            found.update(
                k for k in cls.__mro__ if "toarray" in vars(k) or "todense" in vars(k)
            )
    return found


@contextlib.contextmanager
def nothing_dense(refused: list):
    """While the block runs, making a sparse *matrix* dense raises :class:`DenseMatrixRefused`.

    ``.toarray()`` and ``.todense()`` of every scipy.sparse class refuse a result with more than
    one row and more than one column (a vector, (n, 1) or (1, n), may be made dense: spsolve
    does so with a sparse right-hand side); each refusal is appended to ``refused`` as
    ``(method, shape)``, so that a function that catches the exception is still seen.  The
    methods are restored when the block ends, whatever happens in it.
    """
    saved = []

    def guard(method, original):
        @functools.wraps(original)
        def refuse(self, *args, **kwargs):
            shape = tuple(getattr(self, "shape", ()))
            if len(shape) == 2 and min(shape) > 1:
                refused.append((method, shape))
                raise DenseMatrixRefused(
                    f".{method}() on a {shape[0]}×{shape[1]} sparse matrix: exercise 5.1 keeps "
                    "every matrix sparse"
                )
            return original(self, *args, **kwargs)

        return refuse

    try:
        for cls in _sparse_classes():
            for method in ("toarray", "todense"):
                if method in vars(cls):
                    original = vars(cls)[method]
                    saved.append((cls, method, original))
                    setattr(cls, method, guard(method, original))
        yield refused
    finally:
        for cls, method, original in saved:
            setattr(cls, method, original)


@check("5.1", phase1=Function(RealArray(("n",))))
def check_phase1(phase1) -> bool:
    """Exercise 5.1: ``phase1(A, delta_bar, omega)`` → ``θ̂``, shape (n,) (Carlone et al. 2011, eq. 13).

    Called on two seeded graphs (a 2-lap loop with proportional noise; a 60-pose Manhattan world
    with anisotropic, rotated, x/y–θ-coupled information, anchored in the middle) with ``A`` the
    sparse reduced incidence matrix (n, m), ``delta_bar`` the regularized relative orientations
    (m,) and ``omega`` = ``P_δ⁻¹`` per edge (m,); compared with
    :func:`lagolib.lago.phase1_orientations` (rtol 1e-7).  The exercise asks for nothing dense:
    the student's function runs under :func:`nothing_dense`, and a solution that calls
    ``.toarray()`` or ``.todense()`` on a matrix (more than one row and column) is "not yet",
    however right its θ̂.  Diagnosed: the weights ignored (ordinary least squares), variances
    used instead of information (``1/ω``), the anchor's row returned too, a column vector, θ̂
    wrapped.
    """
    ex = "5.1"
    levels = (
        "eq. (13) is a weighted least-squares problem: its normal equations are "
        "A P_δ⁻¹ Aᵀ θ̂ = A P_δ⁻¹ δ̄, with P_δ⁻¹ the diagonal matrix of omega (information, not "
        "variance).",
        "keep everything sparse: P_δ⁻¹ as sp.diags(omega), the (n, n) information matrix as a "
        "product of sparse matrices, and scipy.sparse.linalg.spsolve to solve it; the "
        "right-hand side needs no matrix at all (omega * delta_bar is elementwise).",
        "θ̂ = spsolve(I, r) with I = A P_δ⁻¹ Aᵀ (sparse, converted .tocsc()) and r = A times the "
        "vector omega * delta_bar; return it as it is: shape (n,), not wrapped.",
    )
    worst, sizes = 0.0, []
    for (g, A, delta_bar, omega, ref), kind in zip(_phase1_cases(), ("loop", "Manhattan world")):
        with nothing_dense([]) as refused:
            got, problem = call_student(
                phase1,
                A.copy(),
                delta_bar.copy(),
                omega.copy(),
                name="phase1(A, delta_bar, omega)",
            )
        if refused:
            method, shape = refused[0]
            return verdict(
                ex,
                f"your phase1 made a sparse matrix dense (.{method}() on a {shape[0]}×{shape[1]} "
                "matrix), and the check refuses it: exercise 5.1 keeps every matrix sparse. A "
                "dense A P_δ⁻¹ Aᵀ for a map of 10⁵ poses holds n² = 10¹⁰ numbers (80 GB), a "
                "dense solve costs n³.",
                hint=(
                    "no .toarray() or .todense(), and no np.linalg.lstsq / solve / inv: form the "
                    "information matrix as a product of sparse matrices and solve it with "
                    "scipy.sparse.linalg.spsolve.",
                    *levels[1:],
                ),
            )
        if problem:
            return verdict(
                ex,
                problem,
                hint=(
                    "A is a scipy.sparse matrix of shape (n, m), delta_bar and omega numpy "
                    "arrays of shape (m,); return a numpy array of shape (n,).",
                    *levels,
                ),
            )
        what = f"on a {g.n}-pose graph with {g.m} edges"
        arr = got  # a float array: call_student read it
        if arr.shape == (ref.size, 1):
            return verdict(
                ex,
                f"{what} your θ̂ has shape {arr.shape}, a column; the reference is a flat vector "
                f"of shape {ref.shape}.",
                hint=("return a 1-D array: np.ravel(...) or spsolve's own result.",),
            )
        if arr.shape == (ref.size + 1,):
            return verdict(
                ex,
                f"{what} your θ̂ has {arr.size} entries, one per vertex; the anchor's "
                f"orientation is fixed to 0 and is not an unknown ({ref.size} expected).",
                hint=("A has one row per non-anchor vertex: solve for exactly A.shape[0] values.",),
            )
        if matches(got, _weighted_solve(A, delta_bar, np.ones_like(omega)), 1e-7):
            return verdict(
                ex,
                f"{what} you solved A Aᵀ θ = A δ̄: ordinary least squares, every edge weighted "
                "the same.",
                hint=(
                    "eq. (13) weights each edge by its information P_δ⁻¹ = omega: "
                    "A P_δ⁻¹ Aᵀ θ = A P_δ⁻¹ δ̄.",
                    *levels[1:],
                ),
            )
        if matches(got, _weighted_solve(A, delta_bar, 1.0 / omega), 1e-7):
            return verdict(
                ex,
                f"{what} you weighted the edges by 1/omega, their variances: the noisiest edges "
                "then count the most.",
                hint=("omega already is P_δ⁻¹ (information); use it as it is.", *levels[1:]),
            )
        if (
            arr.shape == ref.shape
            and np.allclose(se2.wrap_angle(arr - ref), 0.0, rtol=0, atol=1e-7)
            and not np.allclose(arr, ref, rtol=1e-7, atol=1e-9)
        ):
            turns = int(np.round(np.abs(arr - ref).max() / TWO_PI))
            return verdict(
                ex,
                f"{what} your θ̂ equals the reference modulo 2π, but some entries are off by "
                f"whole turns (up to {turns}): was θ̂ wrapped?",
                hint=(
                    "eq. (13) is a linear solve; return its solution as it is. The regularized "
                    "δ̄ carries the turns, and θ̂ keeps them (it is not wrapped).",
                ),
            )
        problem = compare_array(got, ref, name="your θ̂", rtol=1e-7, atol=1e-9)
        if problem:
            return verdict(ex, f"{what} " + problem, hint=levels)
        worst = max(worst, float(np.abs(arr - ref).max()))
        sizes.append(f"a {g.n}-pose {kind} with {g.m} edges")
    return verdict(
        ex,
        None,
        correct="θ̂ matches lagolib.lago.phase1_orientations on both graphs "
        f"({sizes[0]}, {sizes[1]}; largest difference {worst:.1e} rad).",
    )


# ---------------------------------------------------------------------------------------------
# 5.2


def _chord_graph():
    """A seeded 3-lap circular loop (12 poses per lap), clockwise, with varied loop closures.

    Closures one lap back (tail first), two laps back stored backwards (head first), 17 steps
    forward (510°: the closure measures a wrapped 150°), and short ones; noise σθ = 0.08 rad.
    Two chords' measured angles are then moved so that their circuits sum to ±(π − 0.15) off a
    whole number of turns — next to the rounding boundary.
    """
    truth = simulate.loop_world(laps=3, poses_per_lap=12, shape="circle", noiseless=True).truth
    truth = truth * np.array([1.0, -1.0, -1.0])  # mirrored: the robot turns right
    n = len(truth)
    chain = [(k, k + 1) for k in range(n - 1)]
    loops = [(k - 12, k) for k in (12, 15, 20, 26, 31)]
    loops += [(k, k - 24) for k in (24, 29, 35)]
    loops += [(k, k + 17) for k in (1, 8, 14)]
    loops += [(3, 5), (22, 19), (30, 35)]
    sim = simulate.measure(truth, chain + loops, sigma_theta=0.08, rng=52)
    g = sim.graph
    reg = regularize(g, "odometric", margin_warning=0)
    z = g.measurements.copy()
    for c, target in ((1, np.pi - 0.15), (7, -(np.pi - 0.15))):  # positions among the chords
        e = reg.chords[c]
        s = reg.cycle_sums[c]
        residual = s - TWO_PI * np.round(s / TWO_PI)
        z[e, 2] = se2.wrap_angle(z[e, 2] + target - residual)
    return PoseGraph(g.poses, g.edges, z, g.information)


def _k_candidates(turns):
    """Wrong formulas for k from the cycle sums in turns, with what each one did."""
    return (
        (
            np.round(turns),
            "the opposite sign: eq. (22) asks for C ν = −C δ, so the correction removes the "
            "turns the circuit summed to instead of adding more",
        ),
        (
            -np.floor(turns),
            "np.floor where eq. (23) rounds to the nearest whole number of turns: "
            "floor(0.93) is 0, not 1",
        ),
        (
            -np.ceil(turns),
            "np.ceil where eq. (23) rounds to the nearest whole number of turns: "
            "ceil(1.07) is 2, not 1",
        ),
        (-np.trunc(turns), "int()/np.trunc, which cuts towards zero: 1.9 turns become 1, not 2"),
        (np.floor(turns), "the opposite sign and np.floor instead of rounding"),
        (np.ceil(turns), "the opposite sign and np.ceil instead of rounding"),
        (np.trunc(turns), "the opposite sign and int() (truncation) instead of rounding"),
    )


_CHORD = Tuple(Real(), Real(), names=("cycle_sum", "k"), what="two numbers, (cycle_sum, k)")
_CHORD_RETURN = "end the function with `return cycle_sum, k`: two numbers, k a whole one."
_CHORD_LEVELS = (
    "the circuit is the chord plus the tree path back; `edges` lists them (the chord first) "
    "and `signs` says which way each is walked.",
    "eq. (22): (𝒞δ)_c sums ±delta around the circuit, not wrapped; eq. (23) then removes its "
    "whole turns: the nearest whole number of turns, with the opposite sign.",
    "cycle_sum: the sum of signs times delta over `edges` (numpy indexing: delta[edges]), "
    "not wrapped; k: minus the sum in turns (÷ 2π), rounded to the nearest integer, as an int.",
)


@check("5.2", regularize_chord=Function(_CHORD))
def check_regularize_chord(regularize_chord) -> bool:
    """Exercise 5.2: ``regularize_chord(delta, edges, signs)`` → ``(cycle_sum, k)`` for one chord.

    ``delta`` (m,) are the measured relative orientations wrapped to (−π, π]; ``edges, signs =
    lagolib.topology.fundamental_circuit(graph, tree, chord)`` (the chord first).  ``cycle_sum``
    is ``(𝒞 δ)_c = Σ signs · delta[edges]`` (Carlone et al. 2011, eq. 22) and ``k`` the whole
    number of turns added to the chord, ``-round(cycle_sum / 2π)`` (eq. 23, rounded).  Called for
    every chord of a seeded clockwise 3-lap loop (closures one and two laps back, stored both
    ways; 17-step closures; two circuits summing to ±(π − 0.15) off a whole turn) with the
    odometric and the minimum-uncertainty tree, and compared with
    :func:`lagolib.lago.regularize` (``cycle_sums``, ``k``).  Diagnosed: the pair returned as
    ``(k, cycle_sum)``; in the sum: the tree path left out, the chord left out, the signs
    ignored, the opposite sign, the sum wrapped; in ``k``: the sign, floor/ceil/truncation
    instead of rounding, a fraction of a turn.
    """
    ex = "5.2"
    g = _chord_graph()
    got_s, got_k, ref_s, ref_k, where = [], [], [], [], []
    for tree in ("odometric", "min_uncertainty"):
        reg = regularize(g, tree, margin_warning=0)
        delta = np.asarray(reg.delta)
        for c, chord in enumerate(reg.chords):
            edges, signs = topology.fundamental_circuit(g, reg.tree, chord)
            value, problem = call_student(
                regularize_chord,
                delta.copy(),
                edges.copy(),
                signs.copy(),
                name="regularize_chord(delta, edges, signs)",
            )
            if problem:
                return verdict(ex, problem, hint=(_CHORD_RETURN, *_CHORD_LEVELS))
            s, k = value  # two floats: call_student read them
            a, b = (int(v) for v in g.ids[g.edges[chord]])
            s_ref = float(reg.cycle_sums[c])
            where.append((tree, int(chord), a, b, delta, edges, signs))
            got_s.append(s)
            got_k.append(k)
            ref_s.append(s_ref)
            ref_k.append(int(reg.k[chord]))
    # the cycle sums, chord by chord
    for s, k, s_ref, k_ref, (tree, chord, a, b, delta, edges, _signs) in zip(
        got_s, got_k, ref_s, ref_k, where
    ):
        problem = compare_number(s, s_ref, name="cycle_sum", rtol=1e-9, atol=1e-9)
        if problem is None:
            continue
        head = (
            f"for the chord {chord} ({a} -> {b}) with the {tree!r} tree, whose circuit has "
            f"{edges.size} edges, "
        )
        if matches(k, s_ref) and matches(s, k_ref):
            return verdict(
                ex,
                head + f"your function returned ({s!r}, {k!r}): k first, then the sum. The "
                "exercise asks for the pair in the order (cycle_sum, k).",
                hint=(_CHORD_RETURN,),
            )
        if matches(s, delta[chord]):
            return verdict(
                ex,
                head + "your cycle_sum is the chord's own angle delta[chord]: the tree path is "
                "missing.",
                hint=(
                    "the circuit is the chord plus the tree path back: sum over all of `edges`.",
                    *_CHORD_LEVELS[1:],
                ),
            )
        if abs(delta[chord]) > 1e-6 and matches(s, s_ref - delta[chord]):
            return verdict(
                ex,
                head + "your cycle_sum is the tree path alone: the chord itself is missing.",
                hint=(
                    "the fundamental circuit is the chord plus the tree path (Def. 1); `edges` "
                    "starts with the chord (sign +1).",
                    *_CHORD_LEVELS[1:],
                ),
            )
        if matches(s, np.sum(delta[edges])):
            return verdict(
                ex,
                head + "your cycle_sum adds the angles without their signs.",
                hint=(
                    "an edge walked against its direction (sign −1) turns the robot by −delta.",
                    *_CHORD_LEVELS[1:],
                ),
            )
        if matches(s, -s_ref):
            return verdict(
                ex,
                head + "your cycle_sum has the opposite sign: the circuit walks the chord "
                "forwards (sign +1, first in `edges`).",
                hint=("use the signs as given: +1 for the chord.", *_CHORD_LEVELS[1:]),
            )
        if matches(s, se2.wrap_angle(s_ref)):
            return verdict(
                ex,
                head + "your cycle_sum is wrapped into (−π, π]: the whole turns that k must "
                "remove are gone.",
                hint=("do not wrap the sum; only the rounding to whole turns comes after it.",),
            )
        return verdict(ex, head + problem, hint=_CHORD_LEVELS)
    # k, over all chords at once: a wrong formula is recognized by matching everywhere
    ks = np.array(got_k)
    ref_k = np.array(ref_k)
    turns = np.array(ref_s) / TWO_PI
    wrong = np.flatnonzero(ks != ref_k)
    if not wrong.size:
        near = np.abs(turns - np.round(turns))
        return verdict(
            ex,
            None,
            correct=f"cycle sums and k match lagolib.lago.regularize on all {ks.size} chords "
            f"(k from {int(ref_k.min())} to {int(ref_k.max())}; the closest to the rounding "
            f"boundary summed to {near.max():.3f} turns off a whole turn).",
        )
    w = int(wrong[0])
    tree, chord, a, b = where[w][:4]
    head = (
        # the cycle sums are right here: the turns are the student's own sum / 2π
        f"your cycle sums are right, but not every k ({wrong.size} of {ks.size} chords differ); "
        f"the first: the chord {chord} ({a} -> {b}) with the {tree!r} tree, whose circuit sums "
        f"to {turns[w]:+.3f} turns, gets your k = {got_k[w]:g}"
    )
    k_levels = (
        "k is the whole number of turns eq. (23) puts on the chord, ν_c = 2π k, so that the "
        "corrected circuit sums to (nearly) zero.",
        "eq. (22)–(23): round the circuit's sum, in turns (÷ 2π), to the nearest whole number, "
        "and take the opposite sign.",
        _CHORD_LEVELS[2],
    )
    if not np.all(ks == np.round(ks)):
        return verdict(ex, head + ": k must be a whole number of turns.", hint=k_levels)
    for candidate, what in _k_candidates(turns):
        if np.array_equal(ks, candidate):
            return verdict(ex, head + f": you used {what}.", hint=k_levels[1:])
    return verdict(ex, head + ".", hint=k_levels)


# ---------------------------------------------------------------------------------------------
# 5.3


def closure_world():
    """The graph of exercise 5.3: 3 laps of a square, 20 poses per lap, and nine loop closures.

    The truth is ``lagolib.simulate.loop_world(laps=3, poses_per_lap=20, noiseless=True).truth``
    (a left turn of π/2 after every 5 poses); the edges are the odometric chain and the closures
    :data:`CLOSURES`, measured with ``lagolib.simulate.measure(truth, edges, sigma_theta=0.02,
    rng=53)``.

    Returns
    -------
    Simulation
    """
    truth = simulate.loop_world(laps=3, poses_per_lap=20, noiseless=True).truth
    chain = [(k, k + 1) for k in range(len(truth) - 1)]
    return simulate.measure(truth, chain + list(CLOSURES), sigma_theta=0.02, rng=53)


@check("5.3", n_predicted=Int())
def check_n_regularized(n_predicted) -> bool:
    """Exercise 5.3: the predicted number of chords with ``k ≠ 0`` in :func:`closure_world`.

    Compared with ``lagolib.lago.regularize(graph, "odometric").n_regularized`` (Table I's last
    column for this graph); the actual count and every chord's ``k`` are printed with a right
    answer, and every ``k`` is the last hint level after a wrong one.  Diagnosed: every
    closure counted, only the closures spanning a whole lap or more counted (the rounding
    boundary is half a turn), and the closures that cross the lap's start line counted.
    """
    ex = "5.3"
    sim = closure_world()
    g = sim.graph
    reg = regularize(g, "odometric", margin_warning=0)
    n = reg.n_regularized
    turn = np.unwrap(sim.truth[:, 2])
    listing = ", ".join(
        f"{int(g.edges[e, 0])}->{int(g.edges[e, 1])}: k={int(reg.k[e]):+d}" for e in reg.chords
    )
    problem = compare_int(n_predicted, n, name="your prediction")
    if problem is None:
        return verdict(
            ex,
            None,
            correct=f"{n} of the {reg.tree.d} chords need regularization with the odometric "
            f"tree ({listing}).",
        )
    if problem == NOT_ATTEMPTED:
        return verdict(ex, problem)
    i, j = g.edges[reg.chords, 0], g.edges[reg.chords, 1]
    swing = np.abs(turn[j] - turn[i])  # how far the odometry turns between the chord's ends
    full_laps = int(np.count_nonzero(swing > TWO_PI - 0.5))
    crossing = int(np.count_nonzero((reg.k[reg.chords] != 0) | ((i // 20) != (j // 20))))
    hint = (
        "the circuit of a chord i → j of the odometric tree is the closure plus the odometry "
        "walked back from j to i: what does it sum to, when the odometry turns by Δ between "
        "the two poses and the closure measures Δ wrapped?",
        "a chord needs k ≠ 0 when the odometry between its two poses turns by more than half a "
        "turn (180°) either way: the closure itself measures that angle wrapped into (−180°, "
        "180°], and the circuit's sum is the difference.",
        f"lagolib's regularize, chord by chord: {listing}.",
    )
    if n_predicted == reg.tree.d:
        problem += (
            f" There are {reg.tree.d} chords, but not every loop closure's circuit winds around."
        )
    elif n_predicted == full_laps:
        problem += (
            " You may have counted only the closures whose poses are a whole lap (360°) or more "
            "apart."
        )
    elif n_predicted == crossing:
        problem += " Crossing the start line of a lap does not by itself make a circuit wind."
    return verdict(ex, problem, hint=hint)


# ---------------------------------------------------------------------------------------------
# 5.4


def explore_world(sigma_theta):
    """The world of exercise 5.4 at heading noise ``sigma_theta`` (rad).

    ``lagolib.simulate.loop_world(laps=4, poses_per_lap=40, sigma_theta=sigma_theta, rng=1)``:
    the 4-lap square loop of chapter 5, sections 5–6.  The same seed draws the same standard
    normal noise at every ``sigma_theta``, so raising ``sigma_theta`` scales one noise sample.
    Worlds are remembered (they are read-only), so moving the chapter's slider back and forth
    and the check reuse them.

    Returns
    -------
    Simulation
    """
    return _explore_world(check_real(sigma_theta, "sigma_theta", "explore_world", minimum=0.0))


@functools.lru_cache(maxsize=64)
def _explore_world(sigma_theta):
    sim = simulate.loop_world(laps=4, poses_per_lap=40, sigma_theta=sigma_theta, rng=1)
    truth = sim.truth.copy()
    truth.setflags(write=False)  # shared between calls: nobody may change it
    return simulate.Simulation(sim.graph, truth)


def wrong_k(sim, reg):
    """Which chords of ``reg`` (a :class:`~lagolib.lago.Regularization`) got a wrong ``k``.

    The noise of each edge's angle (measurement minus truth, wrapped) summed around each chord's
    fundamental circuit (eq. 22) is what ``𝒞 δ̄`` should be; rounding went wrong where the
    regularized sum differs from it by a whole turn.

    Returns
    -------
    ndarray of bool, shape (d,)
    """
    g = sim.graph
    true_delta = se2.between(sim.truth[g.edges[:, 0]], sim.truth[g.edges[:, 1]])[:, 2]
    noise = se2.wrap_angle(g.measurements[:, 2] - true_delta)
    phi = reg.tree.potentials(noise)
    i, j = g.edges[reg.chords, 0], g.edges[reg.chords, 1]
    noise_sums = noise[reg.chords] + phi[i] - phi[j]
    return np.abs(reg.residual_sums - noise_sums) > np.pi


@functools.lru_cache(maxsize=1)
def _thresholds():
    """Per tree: the first σθ of :data:`SIGMA_GRID` with a margin below 0.1 (LAGO warns) and the
    first with a wrong ``k``, in :func:`explore_world`."""
    out = {t: {"warn": None, "wrong": None} for t in _EXPLORE_TREES}
    for s in SIGMA_GRID:
        sim = explore_world(s)
        for t in _EXPLORE_TREES:
            if out[t]["wrong"] is not None:
                continue
            reg = regularize(sim.graph, t, margin_warning=0)
            if out[t]["warn"] is None and reg.margin.min() < 0.1:
                out[t]["warn"] = s
            if wrong_k(sim, reg).any():
                out[t]["wrong"] = s
        if all(out[t]["wrong"] is not None for t in _EXPLORE_TREES):
            break
    return out


@check("5.4", first_wrong_odometric=Real(), first_wrong_min_uncertainty=Real())
def check_noise_tolerance(first_wrong_odometric, first_wrong_min_uncertainty) -> bool:
    """Exercise 5.4: the smallest σθ of :data:`SIGMA_GRID` at which each tree picks a wrong ``k``.

    In :func:`explore_world`, with ``lagolib.lago.regularize(graph, tree)`` for the odometric and
    the minimum-uncertainty tree, a chord's ``k`` is wrong when :func:`wrong_k` says so.  Both
    answers are compared exactly (they are values of the grid); a right answer prints both
    thresholds and the noise at which LAGO starts warning (a margin below 0.1 turns), a wrong
    one has the warning levels as its last hint.  Diagnosed: the warning's
    noise level given instead of the failure's, the two trees swapped, a value not on the grid.
    """
    ex = "5.4"
    th = _thresholds()
    answers = {"odometric": first_wrong_odometric, "min_uncertainty": first_wrong_min_uncertainty}
    summary = (
        f"the odometric tree first picks a wrong k at σθ = {th['odometric']['wrong']:.2f} rad "
        f"(warning from {th['odometric']['warn']:.2f}), the minimum-uncertainty tree at "
        f"{th['min_uncertainty']['wrong']:.2f} rad (warning from "
        f"{th['min_uncertainty']['warn']:.2f}): "
        f"{th['min_uncertainty']['wrong'] / th['odometric']['wrong']:.1f} times the noise."
    )
    for tree, got in answers.items():
        name = f"first_wrong_{tree}"
        ref = th[tree]["wrong"]
        problem = compare_number(got, ref, name=name, rtol=0, atol=1e-6)
        if problem is None:
            continue
        if problem == NOT_ATTEMPTED:
            return verdict(ex, NOT_ATTEMPTED)
        g = got  # read by @check as one finite real number
        other = "min_uncertainty" if tree == "odometric" else "odometric"
        theirs = answers[other]
        swapped = (
            isinstance(theirs, float)
            and abs(g - th[other]["wrong"]) < 1e-6
            and abs(theirs - th[tree]["wrong"]) < 1e-6
        )
        read = "read the smallest slider value at which the tree's 'wrong k' count leaves 0."
        warned = (
            f"where each tree starts to warn (a margin below 0.1 turns): odometric at σθ = "
            f"{th['odometric']['warn']:.2f}, min_uncertainty at {th['min_uncertainty']['warn']:.2f}"
            " rad; the first wrong k comes a few slider steps later."
        )
        if abs(g - th[tree]["warn"]) < 1e-6:
            problem = (
                f"{name} = {g:.2f} is where the {tree!r} tree's smallest margin drops below 0.1 "
                "turns — where LAGO starts to warn — but every k is still right there."
            )
            hint = ("keep raising σθ until the 'wrong k' count of that tree leaves 0.",)
        elif swapped:
            problem = "your two thresholds are swapped."
            hint = ("first_wrong_odometric belongs to tree='odometric'.",)
        elif min(abs(g - s) for s in SIGMA_GRID) > 1e-6:
            problem = f"{name} = {g!r} is not one of the slider's values (0.02, 0.04, …, 0.60)."
            hint = (read, warned)
        elif g < ref:
            problem = f"at {name} = {g:.2f} every k of the {tree!r} tree is still right."
            hint = ("raise σθ further, one slider step at a time.", read, warned)
        else:
            problem = f"the {tree!r} tree already picks a wrong k at a smaller σθ than {g:.2f}."
            hint = ("lower σθ step by step: you want the first value with a wrong k.", warned)
        return verdict(ex, problem, hint=hint)
    return verdict(ex, None, correct=summary)


# --- derive exercises ---
# Exercise 5.5 (derive) — :func:`check_blue_variance`: the variance of θ̂_2 in the smallest loop,
# 0 → 1 → 2 (odometry, variances a and b) closed by 0 → 2 (variance c), from the BLUE's
# covariance P_θ̂ = (A P_δ^-1 A^T)^-1 (Carlone et al. 2011, eq. 13), as a formula in a, b, c.

import sympy as _sp  # noqa: E402

from lagolib.exercises._derive import Formula, formula_comparison  # noqa: E402

#: exercise 5.5's symbols: the orientation variances of the edges 0 → 1, 1 → 2 and 0 → 2
VARIANCE_SYMBOLS = _sp.symbols("a b c", positive=True)
#: exercise 5.5's graph: the odometry 0 → 1 → 2 and the loop closure 0 → 2
TRIANGLE_EDGES = ((0, 1), (1, 2), (0, 2))


def triangle_graph(variances=(1.0, 1.0, 1.0), turns=(0.3, -0.2, 0.1)) -> PoseGraph:
    """Exercise 5.5's graph with numbers: orientation variances and measured turns per edge.

    Parameters
    ----------
    variances : sequence of 3 floats
        ``P_δ`` of the edges 0 → 1, 1 → 2, 0 → 2 (rad²).
    turns : sequence of 3 floats
        Their measured relative orientations ``δ`` (rad).

    Returns
    -------
    PoseGraph
        3 poses, 3 edges; position information 1, orientation information ``1 / variance``.
    """
    variances = [
        check_real(v, "variances", "triangle_graph", minimum=0.0, strict=True) for v in variances
    ]
    info = np.zeros((3, 3, 3))
    info[:, 0, 0] = info[:, 1, 1] = 1.0
    info[:, 2, 2] = 1.0 / np.asarray(variances)
    z = np.zeros((3, 3))
    z[:, 0] = 1.0
    z[:, 2] = turns
    return PoseGraph(np.zeros((3, 3)), np.array(TRIANGLE_EDGES), z, info)


def blue_variance_reference():
    """``Var θ̂_2``: entry (2, 2) of ``P_θ̂ = (A P_δ^-1 A^T)^-1`` (Carlone et al. 2011, eq. 13).

    ``A`` is lagolib's reduced incidence matrix of :func:`triangle_graph` (rows θ_1, θ_2; one
    column per edge), ``P_δ = diag(a, b, c)``; sympy inverts the 2×2 information matrix.
    """
    a, b, c = VARIANCE_SYMBOLS
    A = _sp.Matrix(topology.reduced_incidence_matrix(triangle_graph()).toarray()).applyfunc(
        lambda v: _sp.Integer(round(v))
    )
    information = A * _sp.diag(a, b, c).inv() * A.T
    return _sp.factor(_sp.simplify(information.inv()[1, 1]))


def _blue_variance_slips():
    """Known wrong answers of exercise 5.5 and the sentence that names each."""
    a, b, c = VARIANCE_SYMBOLS
    return [
        (
            a * (b + c) / (a + b + c),
            "that is the variance of θ̂_1, the pose in the middle; the exercise asks for θ̂_2, "
            "the pose the loop closure reaches.",
        ),
        (
            a + b,
            "that is the variance of the odometry alone (0 → 1 → 2): the loop closure 0 → 2 "
            "also measures θ_2, and the BLUE uses it.",
        ),
        (
            c,
            "that is the loop closure's variance alone: the odometry 0 → 1 → 2 also measures "
            "θ_2, and the BLUE uses it.",
        ),
        (
            1 / (1 / a + 1 / b + 1 / c),
            "that combines the three edges as if each measured θ_2 on its own; the two "
            "odometry edges measure it only together, one after the other.",
        ),
    ]


_BLUE_VARIANCE_HINTS = (
    "eq. (13): P_θ̂ = (A P_δ^-1 A^T)^-1. A has a row for θ_1 and one for θ_2 (the anchor θ_0 "
    "has none) and a column per edge (−1 at its tail, +1 at its head); P_δ = diag(a, b, c). "
    "sympy does the algebra: (A * P.inv() * A.T).inv()[1, 1].",
    "the information matrix A P_δ^-1 A^T is [[1/a + 1/b, −1/b], [−1/b, 1/b + 1/c]]; the (2, 2) "
    "entry of the inverse of [[p, q], [q, s]] is p / (p s − q²).",
    "check your formula against intuition: θ_2 is reached by two independent routes, the "
    "odometry (variance a + b) and the loop closure (variance c), and the BLUE combines "
    "independent estimates like resistors in parallel.",
)


@check("5.5", var_theta2=Formula(VARIANCE_SYMBOLS, example="a*b/(a + 2*c)"))
def check_blue_variance(var_theta2) -> bool:
    """Exercise 5.5: ``Var θ̂_2`` of the 3-pose loop as a formula in ``a``, ``b``, ``c``.

    The answer is a string sympy reads or a sympy expression in :data:`VARIANCE_SYMBOLS` (all
    positive).  It is compared with :func:`blue_variance_reference` by
    :func:`lagolib.exercises._derive.formula_comparison`: a wrong formula gets the term (or the
    denominator) that is wrong, never the reference.
    """
    result = formula_comparison(
        var_theta2,
        blue_variance_reference(),
        symbols=VARIANCE_SYMBOLS,
        name="your Var θ̂_2",
        slips=_blue_variance_slips(),
    )
    if result.problem is not None:
        return verdict("5.5", result.problem, hint=_BLUE_VARIANCE_HINTS)
    return verdict(
        "5.5", None, correct=f"your Var θ̂_2 is entry (2, 2) of eq. (13)'s P_θ̂: {result.detail}."
    )
