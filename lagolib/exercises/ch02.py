"""Checks for the exercises of chapter 2, least-squares graph SLAM (lecture notes, "Least Square SLAM").

* Exercise 2.1 (implement) — :func:`check_jacobians`: the Jacobian blocks ``A_ij``, ``B_ij`` of one
  edge ("Compute the blocks of the Jacobian"), against :func:`lagolib.gauss_newton.edge_jacobians`
  and central finite differences of the error.
* Exercise 2.2 (implement) — :func:`check_edge_contribution`: what one edge adds to ``H`` and ``b``
  ("Building the Linear System", steps 3 and 4), against
  :func:`lagolib.gauss_newton.build_linear_system_loop`, with an anisotropic, rotated ``Omega``.
* Exercise 2.3 (predict) — :func:`check_structure`: the number of non-zero 3x3 blocks of ``H`` and
  the dimension of its null space for the graph of :func:`structure_graph` (no gauge).
* Exercise 2.4 (explore) — :func:`check_damping`: how Levenberg–Marquardt's initial damping changes
  the number of iterations and the optimum (:func:`damping_sweep`).

Every check prints one line starting ``Exercise 2.k`` (see :mod:`lagolib.exercises`) and returns
True or False; none raises on a wrong answer.
"""

from __future__ import annotations

import numpy as np

from lagolib import PoseGraph, datasets, optimize, se2
from lagolib.exercises._coerce import Bool, Choice, Function, Int, RealArray, Tuple
from lagolib.exercises._feedback import (
    NOT_ATTEMPTED,
    call_student,
    check,
    compare_array,
    compare_choice,
    compare_int,
    is_placeholder,
    verdict,
)
from lagolib.gauss_newton import LinearSystem, build_linear_system_loop, edge_jacobians
from lagolib.graph import edge_errors

__all__ = [
    "check_jacobians",
    "check_edge_contribution",
    "structure_graph",
    "check_structure",
    "DAMPING_LAMBDAS",
    "damping_sweep",
    "check_damping",
    "EDGE_SYMBOLS",
    "jacobian_entry_reference",
    "check_jacobian_entry",
]

_RTOL, _ATOL = 1e-7, 1e-9


def _close(a, b, rtol=_RTOL, atol=_ATOL) -> bool:
    """Same shape and equal within ``atol + rtol |b|`` (False for anything not numeric)."""
    try:
        a = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        return False
    b = np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= atol + rtol * np.abs(b)))


# ----------------------------------------------------------------------------- exercise 2.1
def _jacobian_cases():
    """Five seeded edges ``(p_i, p_j, z)``: positions within ±5 m, any headings."""
    rng = np.random.default_rng(2021)
    cases = []
    for _ in range(5):
        p_i, p_j, z = rng.uniform(-1.0, 1.0, size=(3, 3)) * [5.0, 5.0, np.pi]
        cases.append((p_i, p_j, z))
    return cases


def _finite_differences(p_i, p_j, z, h=1e-6):
    """Central differences of ``e_ij`` with respect to ``x_i`` and ``x_j`` (angle wrapped)."""

    def diff(which):
        cols = []
        for u in np.eye(3):
            plus = [p_i, p_j]
            minus = [p_i, p_j]
            plus[which] = plus[which] + h * u
            minus[which] = minus[which] - h * u
            d = edge_errors(plus[0], plus[1], z) - edge_errors(minus[0], minus[1], z)
            d[2] = se2.wrap_angle(d[2])
            cols.append(d / (2 * h))
        return np.column_stack(cols)

    return diff(0), diff(1)


def _jacobian_problem(A, B, p_i, p_j, z):
    """None if ``(A, B)`` are the blocks of the edge, else the sentence saying what is wrong."""
    _, A_ref, B_ref = edge_jacobians(p_i, p_j, z)
    for name, got in (("A_ij", A), ("B_ij", B)):  # float arrays, read by call_student
        if got.shape != (3, 3):
            return f"{name} has shape {got.shape}, expected (3, 3)."
    if _close(A, B_ref) and _close(B, A_ref):
        return (
            "A and B are swapped: A_ij = de/dx_i is the block with the extra third column "
            "(turning x_i swings x_j around it); B_ij = de/dx_j is just a rotation."
        )
    # the rotation of x_i alone instead of x_i's heading plus the measured one
    _, A_alt, B_alt = edge_jacobians(p_i, p_j, np.asarray(z) * [1.0, 1.0, 0.0])
    for name, got, ref, alt in (("A_ij", A, A_ref, A_alt), ("B_ij", B, B_ref, B_alt)):
        if _close(got, ref):
            continue
        if _close(got, alt):
            return (
                f"{name} uses the rotation R(theta_i); the error is expressed in the frame of the "
                "measurement, so the rotation is R(theta_i + theta_z)."
            )
        if name == "A_ij" and _close(np.asarray(got, float)[:, :2], ref[:, :2]):
            col = np.asarray(got, float)[:, 2]
            if _close(col[:2], ref[:2, 2]):
                return (
                    f"A_ij is right except its entry [2, 2], de_theta/dtheta_i (yours is "
                    f"{col[2]:.6g}): how does the angle error theta_j - theta_i - theta_z change "
                    "when theta_i grows a little?"
                )
            rows = [r for r in range(3) if not _close(col[r], ref[r, 2])]
            return (
                f"A_ij's first two columns are right, its third column de/dtheta_i is not (row"
                f"{'s' if len(rows) > 1 else ''} {', '.join(map(str, rows))} of it): how does "
                "turning x_i move x_j as seen from x_i, rotated into the measurement's frame?"
            )
        return compare_array(got, ref, name=name)
    return None


_BLOCKS = Tuple(
    RealArray((3, 3)), RealArray((3, 3)), names=("A_ij", "B_ij"), what="two 3x3 arrays, (A, B)"
)


@check("2.1", jacobian_blocks=Function(_BLOCKS))
def check_jacobians(jacobian_blocks) -> bool:
    """Exercise 2.1: the Jacobian blocks of one edge.

    Calls ``jacobian_blocks(p_i, p_j, z)`` (each a pose ``(x, y, theta)``, shape (3,)) on five
    seeded random edges and compares the returned ``(A, B)``, each shape (3, 3), with
    ``A_ij = de_ij/dx_i`` and ``B_ij = de_ij/dx_j`` of :func:`lagolib.gauss_newton.edge_jacobians`
    (lecture notes, "Compute the blocks of the Jacobian") and with central finite differences of
    the error ``e_ij = t2v(Z_ij^-1 X_i^-1 X_j)``.  Diagnoses swapped blocks, a transpose, a flipped
    sign, ``R(theta_i)`` in place of ``R(theta_i + theta_z)`` and a wrong third column of ``A``.

    Returns
    -------
    bool
        Whether every block matched (also recorded for :func:`lagolib.exercises.passed`).
    """
    hint = (
        "compare your blocks with the sympy matrices d.A and d.B printed in section 1, entry by "
        "entry, for the edge named above.",
        "B_ij = de/dx_j is the rotation blockdiag(R(theta_i + theta_z)^T, 1); A_ij = -B_ij "
        "except its third column, the derivative of R(theta_i + theta_z)^T (t_j - t_i) by "
        "theta_i (and -1 for the angle).",
        "with c = cos(theta_i + theta_z), s = sin(theta_i + theta_z) and (dx, dy) = t_j - t_i: "
        "B_ij's rows are (c, s, 0), (-s, c, 0), (0, 0, 1); A_ij's third column is "
        "(-s dx + c dy, -c dx - s dy, -1).",
    )
    worst_ref = worst_fd = 0.0
    cases = _jacobian_cases()
    for k, (p_i, p_j, z) in enumerate(cases):
        out, problem = call_student(
            jacobian_blocks, p_i.copy(), p_j.copy(), z.copy(), name="jacobian_blocks"
        )
        if problem is None:
            problem = _jacobian_problem(*out, p_i, p_j, z)
        if problem is not None:
            if problem != NOT_ATTEMPTED:
                where = (
                    f"on edge {k + 1} of {len(cases)} (p_i = {np.round(p_i, 3).tolist()}, "
                    f"p_j = {np.round(p_j, 3).tolist()}, z = {np.round(z, 3).tolist()}): "
                )
                problem = where + problem
            return verdict("2.1", problem, hint=hint)
        A, B = out
        _, A_ref, B_ref = edge_jacobians(p_i, p_j, z)
        A_fd, B_fd = _finite_differences(p_i, p_j, z)
        worst_ref = max(worst_ref, np.abs(A - A_ref).max(), np.abs(B - B_ref).max())
        worst_fd = max(worst_fd, np.abs(A - A_fd).max(), np.abs(B - B_fd).max())
    return verdict(
        "2.1",
        None,
        correct=(
            f"on {len(cases)} random edges A and B match lagolib's edge_jacobians to "
            f"{worst_ref:.1e} and central finite differences to {worst_fd:.1e}."
        ),
    )


# ----------------------------------------------------------------------------- exercise 2.2
def _rotated_information(rng):
    """An anisotropic information matrix with principal axes rotated and x/y/theta coupled."""
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q @ np.diag(rng.uniform(0.5, 2.0, 3) * [50.0, 800.0, 3000.0]) @ q.T


def _contribution_cases():
    """Three seeded edges ``(p_i, p_j, z, Omega)`` with noisy measurements and rotated ``Omega``."""
    rng = np.random.default_rng(2022)
    cases = []
    for _ in range(3):
        p_i, p_j = rng.uniform(-1.0, 1.0, size=(2, 3)) * [4.0, 4.0, np.pi]
        z = se2.between(p_i, p_j) + rng.normal(scale=[0.2, 0.2, 0.1])
        cases.append((p_i, p_j, z, _rotated_information(rng)))
    return cases


def _reference_contribution(p_i, p_j, z, omega):
    """``(H_ii, H_ij, H_jj, b_i, b_j)`` of one edge from the notes' loop on a one-edge graph."""
    pair = PoseGraph(
        poses=np.array([p_i, p_j]), edges=[[0, 1]], measurements=[z], information=[omega]
    )
    H, b = build_linear_system_loop(pair)
    H = H.toarray()
    return H[:3, :3], H[:3, 3:], H[3:, 3:], b[:3], b[3:]


def _contribution_mistakes(e, A, B, W):
    """For each output, ``[(wrong value, what it is), ...]`` — the usual slips."""
    T = np.transpose

    # the sentences name the slip, not the right product (that is the hints' last level)
    def block(X, Y, xn, yn):
        return [
            (X @ W @ Y, f"{xn} Omega {yn}: the transpose of {xn} is missing"),
            (T(X) @ Y @ W, f"{xn}^T {yn} Omega: Omega is on the wrong side"),
            (W @ T(X) @ Y, f"Omega {xn}^T {yn}: Omega is on the wrong side"),
            (T(X) @ Y, f"{xn}^T {yn}: Omega is missing"),
        ]

    def vector(X, xn, other):
        return [
            (X @ W @ e, f"{xn} Omega e: the transpose of {xn} is missing"),
            (T(X) @ e, f"{xn}^T e: Omega is missing"),
            (
                -(T(X) @ W @ e),
                f"-{xn}^T Omega e: b has a plus sign; the minus sign belongs to the normal "
                "equations H dx = -b",
            ),
            (T(other[0]) @ W @ e, f"{other[1]}^T Omega e: that uses the other block"),
        ]

    AtOA, AtOB, BtOA, BtOB = T(A) @ W @ A, T(A) @ W @ B, T(B) @ W @ A, T(B) @ W @ B
    return {
        "H_ii": block(A, A, "A", "A") + [(BtOB, "B^T Omega B: that is H_jj")],
        "H_ij": [
            (
                BtOA,
                "B^T Omega A: that is H_ji, the transpose of H_ij (H_ij has the rows of x_i and "
                "the columns of x_j)",
            ),
            (AtOA, "A^T Omega A: that is H_ii"),
            (
                BtOB,
                "B^T Omega B: that is H_jj — the label the notes' slide gives this product is "
                "swapped",
            ),
        ]
        + block(A, B, "A", "B"),
        "H_jj": block(B, B, "B", "B")
        + [
            (
                AtOB,
                "A^T Omega B: the notes' slide, step 4, labels this product H^jj, but it is "
                "the off-diagonal block H_ij",
            ),
            (AtOA, "A^T Omega A: that is H_ii"),
        ],
        "b_i": vector(A, "A", (B, "B")),
        "b_j": vector(B, "B", (A, "A")),
    }


_CONTRIBUTION = Tuple(
    *[RealArray((3, 3))] * 3,
    *[RealArray((3,))] * 2,
    names=("H_ii", "H_ij", "H_jj", "b_i", "b_j"),
    what="five arrays, (H_ii, H_ij, H_jj, b_i, b_j)",
)


@check("2.2", edge_contribution=Function(_CONTRIBUTION))
def check_edge_contribution(edge_contribution) -> bool:
    """Exercise 2.2: what one edge adds to ``H`` and ``b``.

    Calls ``edge_contribution(e, A, B, Omega)`` — the error ``e`` (shape (3,)), the Jacobian
    blocks ``A``, ``B`` and the information matrix ``Omega`` (each shape (3, 3)) of three seeded
    edges with anisotropic, rotated ``Omega`` — and compares the returned
    ``(H_ii, H_ij, H_jj, b_i, b_j)`` (3x3, 3x3, 3x3, (3,), (3,)) with the blocks that
    :func:`lagolib.gauss_newton.build_linear_system_loop` (lecture notes, "Building the Linear
    System", steps 3 and 4) assembles for a one-edge graph.  Names the usual slips: a missing
    transpose, ``Omega`` on the wrong side or missing, ``H_ji`` for ``H_ij``, the notes' swapped
    ``H^jj`` label, a minus sign in ``b``.
    """
    hint = (
        "write the edge's Jacobian as the block row J_ij = (... A ... B ...) over x_i and x_j, "
        "and expand J^T Omega J and J^T Omega e block by block (steps 3 and 4 of the notes).",
        "Omega always sits in the middle and the transposed block on the left; H_ij has the "
        "rows of x_i and the columns of x_j.",
        "J^T Omega J has the blocks A^T Omega A, A^T Omega B, B^T Omega A, B^T Omega B and "
        "J^T Omega e the blocks A^T Omega e, B^T Omega e.",
    )
    names = ("H_ii", "H_ij", "H_jj", "b_i", "b_j")
    cases = _contribution_cases()
    worst = 0.0
    for k, (p_i, p_j, z, omega) in enumerate(cases):
        e, A, B = edge_jacobians(p_i, p_j, z)
        out, problem = call_student(
            edge_contribution, e.copy(), A.copy(), B.copy(), omega.copy(), name="edge_contribution"
        )
        if problem is None:
            refs = _reference_contribution(p_i, p_j, z, omega)
            mistakes = _contribution_mistakes(e, A, B, omega)
            for name, got, ref in zip(names, out, refs):
                problem = compare_array(got, ref, name=name)
                if problem is None:
                    worst = max(worst, np.abs(got - ref).max() / np.abs(ref).max())
                    continue
                if problem == NOT_ATTEMPTED:
                    break
                for value, what in mistakes[name]:
                    if _close(got, value):
                        problem = f"your {name} is {what}."
                        break
                break
        if problem is not None:
            if problem != NOT_ATTEMPTED:
                problem = f"on edge {k + 1} of {len(cases)}: {problem}"
            return verdict("2.2", problem, hint=hint)
    return verdict(
        "2.2",
        None,
        correct=(
            f"on {len(cases)} edges with rotated, anisotropic Omega all five blocks match the "
            f"notes' loop (build_linear_system_loop) to {worst:.1e} relative."
        ),
    )


# ----------------------------------------------------------------------------- exercise 2.3
def structure_graph() -> PoseGraph:
    """The small graph of exercise 2.3: 7 poses, 10 edges, two connected components.

    Poses 0–3 are joined by every pair (a complete graph on four poses) and 0–1 is measured twice;
    poses 4–6 form a chain whose edge 5–6 is measured twice.  Nothing joins the two groups.
    Poses and measurements are seeded; every edge has information ``diag(100, 100, 400)``.
    """
    rng = np.random.default_rng(23)
    poses = np.column_stack(
        [rng.uniform(-3, 3, 7), rng.uniform(-3, 3, 7), rng.uniform(-np.pi, np.pi, 7)]
    )
    edges = np.array(
        [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2], [1, 3], [0, 1], [4, 5], [5, 6], [5, 6]]
    )
    z = se2.between(poses[edges[:, 0]], poses[edges[:, 1]])
    z = z + rng.normal(scale=[0.05, 0.05, 0.02], size=z.shape)
    info = np.broadcast_to(np.diag([100.0, 100.0, 400.0]), (len(edges), 3, 3))
    return PoseGraph(poses, edges, z, info)


def _structure(graph):
    """Non-zero 3x3 blocks of ``H`` (nothing fixed) and the dimension of its null space."""
    H = LinearSystem(graph).assemble(graph.poses)[0].toarray()
    n = graph.n
    blocks = int(np.count_nonzero(np.any(H.reshape(n, 3, n, 3) != 0, axis=(1, 3))))
    eig = np.linalg.eigvalsh(H)  # a 21 x 21 illustration, not a solve path
    null = int(np.count_nonzero(eig < 1e-9 * eig.max()))
    return blocks, null


@check("2.3", n_blocks=Int(), null_dim=Int())
def check_structure(n_blocks, null_dim) -> bool:
    """Exercise 2.3: predict the structure of ``H`` for :func:`structure_graph` (nothing fixed).

    Compares ``n_blocks`` — the number of 3x3 blocks of ``H`` that are not zero — and ``null_dim``
    — the dimension of the null space of ``H`` (no prior, no fixed pose) — with what lagolib's
    ``H`` (:class:`lagolib.gauss_newton.LinearSystem`) has.  The actual values are printed with a
    right answer; after a wrong one the hints lead to them (the counts of pairs and components).
    """
    g = structure_graph()
    blocks, null = _structure(g)
    pairs = len({tuple(sorted(map(int, e))) for e in g.edges})
    count, _ = g.components()
    if is_placeholder(n_blocks) or is_placeholder(null_dim):
        return verdict("2.3", NOT_ATTEMPTED)
    actual = (
        f"lagolib's H has {blocks} non-zero blocks ({g.n} diagonal + 2 x {pairs} pairs of joined "
        f"poses) and a null space of dimension {null} ({count} components x 3)."
    )
    problems, nudges, methods = [], [], []
    p = compare_int(n_blocks, blocks, name="n_blocks")
    if p is not None:
        why = {
            g.n
            + 2 * g.m: "you counted edges: two measurements between the same two poses add into "
            "the same blocks",
            g.n + pairs: "each pair of joined poses fills two off-diagonal blocks, H_ij and "
            "H_ji = H_ij^T",
            2 * pairs: "every pose also has its diagonal block H_ii",
            g.n
            + g.m: "each pair of joined poses fills two off-diagonal blocks, and parallel edges "
            "share them",
            g.n * g.n: "H is sparse: block (i, j) is non-zero only when an edge joins i and j",
        }.get(n_blocks)
        problems.append(p[:-1] + (f": {why}." if why else "."))
        nudges.append("which blocks of H does one edge (i, j) touch?")
        methods.append(
            "count the diagonal blocks, then two blocks (H_ij and H_ji) per distinct pair of "
            "poses that an edge joins — a pair measured twice counts once"
        )
    p = compare_int(null_dim, null, name="null_dim")
    if p is not None:
        why = {
            3: "that is the null space of a connected graph's H: is this graph connected?",
            0: "with nothing fixed, a rigid motion of all poses changes no error, so H is "
            "singular",
        }.get(null_dim)
        problems.append(f"{p[:-1]}: {why}" + ("" if why.endswith("?") else ".") if why else p)
        nudges.append("which motions of the poses leave every error unchanged?")
        methods.append(
            "a planar rigid motion has 3 degrees of freedom (x, y, rotation), and every part "
            "of the graph that no edge joins to the rest can be moved rigidly on its own"
        )
    if problems:
        return verdict(
            "2.3",
            " ".join(problems),
            hint=(
                "; ".join(nudges),
                "; ".join(methods) + ".",
                f"in the printed edge list: {g.m} edges join {pairs} distinct pairs of poses, "
                f"in {count} connected components.",
            ),
        )
    return verdict("2.3", None, correct=actual)


# ----------------------------------------------------------------------------- exercise 2.4
#: The initial dampings of exercise 2.4.
DAMPING_LAMBDAS = (1e-5, 1e-3, 1e-1, 1e1, 1e3, 1e5)


def damping_sweep(graph=None, lambdas=DAMPING_LAMBDAS):
    """Levenberg–Marquardt from the stored poses for each ``lambda_initial``.

    Parameters
    ----------
    graph : PoseGraph, optional
        Default: the shipped example ``square_loop``.
    lambdas : sequence of float

    Returns
    -------
    list of (float, int, float)
        ``(lambda_initial, iterations, final chi2)`` per damping.
    """
    if graph is None:
        graph = datasets.example("square_loop").graph
    out = []
    for lam in lambdas:
        r = optimize(graph, method="lm", lambda_initial=lam)
        out.append((float(lam), int(r.iterations), float(r.chi2)))
    return out


_TRENDS = ("more", "fewer", "same")


@check("2.4", trend=Choice(_TRENDS), same_optimum=Bool())
def check_damping(trend, same_optimum) -> bool:
    """Exercise 2.4: Levenberg–Marquardt's initial damping, explored on ``square_loop``.

    ``trend`` — ``"more"``, ``"fewer"`` or ``"same"``: how the number of iterations changes as
    ``lambda_initial`` grows from 1e-5 to 1e5; ``same_optimum`` — True or False: whether every
    damping reaches the same χ² (to 1e-9 relative).  Both are compared with
    :func:`damping_sweep` on the shipped ``square_loop``.
    """
    if is_placeholder(trend) or is_placeholder(same_optimum):
        return verdict("2.4", NOT_ATTEMPTED)
    sweep = damping_sweep()
    its = [s[1] for s in sweep]
    chis = np.array([s[2] for s in sweep])
    expected_trend = "more" if its[-1] > its[0] else "fewer" if its[-1] < its[0] else "same"
    spread = float((chis.max() - chis.min()) / chis.min())
    expected_same = spread < 1e-9
    table = ", ".join(f"{lam:.0e}: {it}" for lam, it, _ in sweep)
    actual = f"iterations per lambda_initial {table}; final chi2 spread {spread:.1e} relative."
    problems, nudges, whys = [], [], []
    p = compare_choice(trend, expected_trend, _TRENDS, name="trend")
    if p is not None:
        problems.append(p)
        nudges.append(
            "compare the iterations printed for the smallest and the largest lambda_initial "
            "(only the two ends of the sweep count)"
        )
        whys.append(
            "a large lambda I swamps H, so the first steps are short gradient steps, and lambda "
            "shrinks only tenfold per accepted step"
        )
    p = compare_choice(same_optimum, expected_same, [True, False], name="same_optimum")
    if p is not None:
        problems.append(p)
        nudges.append("compare the final chi2 column, to all its digits")
        whys.append(
            "the damping changes the path to the minimum, not the minimum: at convergence "
            "lambda has shrunk and the step is Gauss-Newton's"
        )
    if problems:
        return verdict(
            "2.4",
            " ".join(problems),
            hint=(
                "; ".join(nudges) + ".",
                "; ".join(whys) + ".",
                "the check's sweep: " + actual,
            ),
        )
    return verdict("2.4", None, correct=actual)


# --- derive exercises ---
# Exercise 2.5 (derive) — :func:`check_jacobian_entry`: the entry ∂e_x/∂θ_i of the lecture notes'
# Jacobian block A_ij ("Compute the blocks of the Jacobian"), a formula in the symbols of
# :func:`lagolib.symbolic.pose_symbols`, against sympy's derivative (lagolib.symbolic).

from lagolib import symbolic as _symbolic  # noqa: E402
from lagolib.exercises._derive import Formula, formula_comparison  # noqa: E402

#: the symbols of exercise 2.5: x_i, y_i, theta_i, x_j, y_j, theta_j, x_z, y_z, theta_z
EDGE_SYMBOLS = (
    *_symbolic.pose_symbols("i"),
    *_symbolic.pose_symbols("j"),
    *_symbolic.pose_symbols("z"),
)


def jacobian_entry_reference():
    """``∂e_x/∂θ_i``: entry (0, 2) of ``A_ij``, as sympy differentiates the notes' error.

    ``e_ij = t2v(Z_ij^-1 X_i^-1 X_j)`` is built and differentiated by
    :func:`lagolib.symbolic.edge_jacobians` (nothing typed in).
    """
    return _symbolic.edge_jacobians().A[0, 2]


def _jacobian_entry_slips(reference):
    """Known wrong answers of exercise 2.5 and the sentence that names each."""
    theta_z = _symbolic.pose_symbols("z")[2]
    A = _symbolic.edge_jacobians().A
    return [
        (
            reference.subs(theta_z, 0),
            "it rotates by θ_i alone. The translation error lives in the frame of the "
            "measurement (frame i turned by the measured θ_z), so the rotation that multiplies "
            "t_j − t_i is R(θ_i + θ_z).",
        ),
        (
            A[1, 2],
            "that is ∂e_y/∂θ_i, the derivative of the error's second entry; the exercise asks "
            "for the first, e_x.",
        ),
        (
            A[0, 0],
            "that is ∂e_x/∂x_i, the derivative by the position x_i; the exercise asks for the "
            "derivative by the heading θ_i.",
        ),
    ]


_JACOBIAN_ENTRY_HINTS = (
    "only the first part of e_x depends on θ_i: e_x is the first entry of "
    "R(θ_i + θ_z)^T (t_j − t_i) − R(θ_z)^T t_z, and the measurement's part R(θ_z)^T t_z does not "
    "move with θ_i. Write e_x out (the printed d.e[0] is it) and differentiate term by term.",
    "with φ = θ_i + θ_z (so dφ/dθ_i = 1): d cos φ/dθ_i = −sin φ and d sin φ/dθ_i = cos φ; the "
    "differences x_j − x_i and y_j − y_i are constants for this derivative.",
    "the result has exactly two terms, one in sin(θ_i + θ_z) and one in cos(θ_i + θ_z): the one "
    "in sin comes from the cos(θ_i + θ_z)·(x_j − x_i) of e_x, the one in cos from its "
    "sin(θ_i + θ_z)·(y_j − y_i).",
)


@check("2.5", de_x_dtheta_i=Formula(EDGE_SYMBOLS, example="2*x_i*sin(theta_z)"))
def check_jacobian_entry(de_x_dtheta_i) -> bool:
    """Exercise 2.5: ``∂e_x/∂θ_i``, the entry in row 1, column 3 of ``A_ij``, as a formula.

    The answer is a string sympy reads or a sympy expression in :data:`EDGE_SYMBOLS` (``θ_i``
    may be written ``theta_i``).  It is compared with :func:`jacobian_entry_reference` by
    :func:`lagolib.exercises._derive.formula_comparison`: sympy's proof that the difference is
    0, or agreement at random points when sympy cannot simplify it; a wrong formula gets the
    term that is wrong, never the reference.
    """
    reference = jacobian_entry_reference()
    result = formula_comparison(
        de_x_dtheta_i,
        reference,
        symbols=EDGE_SYMBOLS,
        name="your ∂e_x/∂θ_i",
        slips=_jacobian_entry_slips(reference),
    )
    if result.problem is not None:
        return verdict("2.5", result.problem, hint=_JACOBIAN_ENTRY_HINTS)
    return verdict(
        "2.5",
        None,
        correct=f"your ∂e_x/∂θ_i is sympy's derivative of e_x by θ_i: {result.detail}.",
    )
