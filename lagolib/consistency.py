"""Pairwise consistency maximization (PCM): keep the largest set of mutually consistent closures.

Two loop closures are *pairwise consistent* when the loop they form with the odometry closes
within its first-order uncertainty.  PCM (Mangelson, Dominic, Eustice and Vasudevan, ICRA 2018)
builds the *consistency graph* — one vertex per loop closure, an edge between every consistent
pair — and keeps a maximum clique of it: the largest set of closures that agree with each other
pairwise.  Wrong closures rarely agree with the right ones, so they fall out, even when a few
wrong closures agree among themselves (a group smaller than the set of right closures loses).

The test of a pair ``a = (i -> j, Z_a)``, ``b = (k -> l, Z_b)`` uses the dead-reckoning poses
``X_t`` (the odometry composed, :meth:`lagolib.graph.PoseGraph.odometry_guess`).  Each closure has
a world-frame discrepancy ``D_a = X_i Z_a X_j^-1`` (the identity if the odometry were exact and the
closure right), and the loop ``i -Z_a-> j -odometry-> l -Z_b^-1-> k -odometry-> i`` is

    M_ab = D_a D_b^-1                      (world frame; = X_i L X_i^-1 for the loop L in frame i)
    v_ab = log(M_ab),    d²_ab = v_ab^T Sigma_ab^-1 v_ab <= chi2.ppf(confidence, 3)

(Mangelson et al. 2018: the Mahalanobis norm of the loop's error; equation numbers unchecked).
``Sigma_ab`` is the loop's first-order covariance under the odometry's and the two closures'
noise; :func:`consistency_graph` derives it below.  Because ``log(X M X^-1) = Ad(X) log(M)``
exactly, the world-frame statistic equals the one of the loop written in any pose's frame.

The maximum clique is found by :func:`maximum_clique`: an exact branch and bound with greedy
colouring bounds on bitsets (Tomita & Seki 2003; San Segundo et al. 2011), after a k-core pruning
by the greedy heuristic's clique (the bound of Pattabiraman et al. 2015's PMC, which Mangelson et
al. use).

Examples
--------
>>> import numpy as np
>>> from lagolib.consistency import maximum_clique
>>> A = np.zeros((5, 5), dtype=bool)
>>> for i, j in [(0, 1), (0, 2), (1, 2), (2, 3), (3, 4)]:
...     A[i, j] = A[j, i] = True
>>> maximum_clique(A).tolist()
[0, 1, 2]

References
----------
J. G. Mangelson, D. Dominic, R. M. Eustice and R. Vasudevan, "Pairwise Consistency Maximization
for Robust Multi-Robot Map Merging", ICRA 2018.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.stats import chi2 as _chi2

from . import se2
from .checks import check_bool, check_real
from .errors import GraphError, LagolibWarning, OptionError, OptionTypeError
from .graph import check_graph

__all__ = [
    "maximum_clique",
    "consistency_graph",
    "pcm",
    "ConsistencyGraph",
    "PCMResult",
    "CliqueTimeLimitWarning",
]

CHUNK = 20_000
"""Closure pairs evaluated at once by :func:`consistency_graph` (bounds its memory: ~20 MB)."""


class CliqueTimeLimitWarning(LagolibWarning):
    """:func:`maximum_clique` hit its ``time_limit``: the clique returned may not be maximum."""


# =========================================================================== maximum clique
def _adjacency(adjacency, where):
    """A symmetric boolean adjacency (dense or scipy sparse) as a CSR matrix without diagonal."""
    if sparse.issparse(adjacency):
        A = sparse.csr_matrix(adjacency)
    else:
        a = np.asarray(adjacency)
        if a.dtype == object or a.dtype.kind not in "biuf":
            raise OptionTypeError(
                f"{where}: adjacency must be a boolean (or 0/1) matrix; got dtype {a.dtype}"
            )
        if a.ndim != 2 or a.shape[0] != a.shape[1]:
            raise OptionError(f"{where}: adjacency must be a square matrix; got shape {a.shape}")
        A = sparse.csr_matrix(a)
    if A.shape[0] != A.shape[1]:
        raise OptionError(f"{where}: adjacency must be a square matrix; got shape {A.shape}")
    if A.dtype.kind not in "biuf":
        raise OptionTypeError(
            f"{where}: adjacency must be a boolean (or 0/1) matrix; got dtype {A.dtype}"
        )
    A.eliminate_zeros()
    if A.nnz and not np.all(A.data == 1):
        bad = A.data[A.data != 1][0]
        raise OptionError(f"{where}: adjacency entries must be 0/1 or bool; got {bad!r}")
    A = A.astype(bool)
    asym = A != A.T
    if asym.nnz:
        r, c = asym.nonzero()
        raise OptionError(
            f"{where}: adjacency must be symmetric; entry ({r[0]}, {c[0]}) differs from "
            f"({c[0]}, {r[0]})"
        )
    A.setdiag(False)
    A.eliminate_zeros()
    return A.tocsr()


def _greedy(A):
    """Greedy clique: repeatedly add the candidate with most neighbours among the candidates.

    ``A`` is a CSR boolean adjacency without diagonal; ties go to the lowest index.  Degrees
    within the candidate set are updated incrementally (each removed candidate lowers its
    neighbours' counts once), so the whole run costs O(nnz).
    """
    n = A.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    indptr, indices = A.indptr, A.indices
    deg = np.diff(indptr).astype(np.int64)  # neighbours among the candidates
    cand = np.ones(n, dtype=bool)
    clique = []
    while cand.any():
        score = np.where(cand, deg, -1)
        v = int(np.argmax(score))  # first maximum: lowest index
        clique.append(v)
        keep = np.zeros(n, dtype=bool)
        keep[indices[indptr[v] : indptr[v + 1]]] = True
        removed = np.flatnonzero(cand & ~keep)  # v itself and its non-neighbours
        cand &= keep
        if removed.size:  # each removed vertex no longer counts for its neighbours
            rows = A[removed]
            deg -= np.bincount(rows.indices, minlength=n)
    return np.sort(np.array(clique, dtype=np.int64))


def _core_prune(A, k):
    """Vertices of the k-core of ``A`` (every vertex keeps >= k neighbours), as a bool mask."""
    n = A.shape[0]
    alive = np.ones(n, dtype=bool)
    deg = np.diff(A.indptr).astype(np.int64)
    while True:
        drop = alive & (deg < k)
        if not drop.any():
            return alive
        alive &= ~drop
        deg -= np.bincount(A[np.flatnonzero(drop)].indices, minlength=n)


class _TimeUp(Exception):
    pass


def _branch_and_bound(A, lower, deadline):
    """Maximum clique of ``A`` larger than ``lower`` vertices, or None (exact; bitsets).

    Vertices are renumbered by non-increasing degree (ties by index), so bit ``p`` of a bitset is
    the ``p``-th vertex of that order; each node colours its candidates greedily in that order
    (San Segundo et al. 2011's BBMC) — a vertex coloured ``c`` can extend the current clique by at
    most ``c`` vertices (Tomita & Seki 2003), which prunes the branch when ``|R| + c <= best``.
    """
    n = A.shape[0]
    deg = np.diff(A.indptr)
    order = np.lexsort((np.arange(n), -deg))  # position -> vertex
    pos = np.empty(n, dtype=np.int64)
    pos[order] = np.arange(n)
    nbr = []
    for v in order:
        bits = np.zeros(n, dtype=bool)
        bits[pos[A.indices[A.indptr[v] : A.indptr[v + 1]]]] = True
        nbr.append(int.from_bytes(np.packbits(bits, bitorder="little").tobytes(), "little"))
    best = [lower, None]
    clique = []
    nodes = [0]

    def colour(P):
        """Candidates of ``P`` and their colour numbers, by non-decreasing colour."""
        verts, cols = [], []
        U, c = P, 0
        while U:
            c += 1
            Q = U
            while Q:
                low = Q & -Q
                v = low.bit_length() - 1
                U ^= low
                Q &= ~nbr[v]
                Q ^= low
                verts.append(v)
                cols.append(c)
        return verts, cols

    def expand(P):
        nodes[0] += 1
        if deadline is not None and nodes[0] % 256 == 0 and time.perf_counter() > deadline:
            raise _TimeUp
        verts, cols = colour(P)
        size = len(clique)
        for idx in range(len(verts) - 1, -1, -1):
            if size + cols[idx] <= best[0]:
                return
            v = verts[idx]
            clique.append(v)
            newP = P & nbr[v]
            if newP:
                expand(newP)
            elif len(clique) > best[0]:
                best[0], best[1] = len(clique), list(clique)
            clique.pop()
            P &= ~(1 << v)

    optimal = True
    try:
        expand((1 << n) - 1)
    except _TimeUp:
        optimal = False
    found = None if best[1] is None else np.sort(order[np.array(best[1], dtype=np.int64)])
    return found, optimal, nodes[0]


def _maximum_clique(A, exact, deadline):
    """(clique, optimal) for a checked CSR adjacency."""
    greedy = _greedy(A)
    if not exact or A.shape[0] == 0:
        return greedy, True
    # a clique larger than the greedy one lives in the (|greedy|)-core: prune everything else
    alive = np.flatnonzero(_core_prune(A, greedy.size))
    if alive.size <= greedy.size:
        return greedy, True
    sub = A[alive][:, alive].tocsr()
    import sys

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, alive.size + 100))
    try:
        found, optimal, _ = _branch_and_bound(sub, greedy.size, deadline)
    finally:
        sys.setrecursionlimit(limit)
    if found is None:
        return greedy, optimal
    return np.sort(alive[found]), optimal


def maximum_clique(adjacency, *, exact=True, time_limit=None):
    """A maximum clique of an undirected graph: the most vertices that are pairwise adjacent.

    Parameters
    ----------
    adjacency : array_like of bool, shape (L, L), or scipy.sparse matrix
        Symmetric; entries 0/1 or bool; the diagonal is ignored.
    exact : bool
        True: branch and bound, the clique is maximum (unless ``time_limit`` runs out).  False:
        the greedy heuristic only — repeatedly add the candidate with most neighbours among the
        remaining candidates; a maximal clique, fast (O(edges)), not always maximum.
    time_limit : float, optional
        Seconds for the branch and bound; when they run out the largest clique found so far is
        returned with a :class:`CliqueTimeLimitWarning`.

    Returns
    -------
    ndarray of int, shape (k,)
        Sorted vertex indices.  Deterministic: ties go to lower indices.

    Raises
    ------
    OptionError, OptionTypeError
        If ``adjacency`` is not a square symmetric 0/1 matrix, or an option is invalid.

    Notes
    -----
    The exact search first runs the greedy heuristic (a clique of ``g`` vertices), removes every
    vertex outside the ``g``-core (a larger clique needs ``>= g`` neighbours per vertex: Mangelson
    et al.'s use of Pattabiraman et al.'s PMC), and then branches with colouring bounds (Tomita &
    Seki 2003) on Python-int bitsets (San Segundo et al. 2011).  On consistency graphs — many
    mutually consistent right closures, wrong ones connected sparsely — the pruning leaves only
    the right closures and the bound closes the search in few nodes.

    References
    ----------
    J. G. Mangelson et al., "Pairwise Consistency Maximization for Robust Multi-Robot Map
    Merging", ICRA 2018.  E. Tomita and T. Seki, "An efficient branch-and-bound algorithm for
    finding a maximum clique", DMTCS 2003.  P. San Segundo, D. Rodríguez-Losada and A. Jiménez,
    "An exact bit-parallel algorithm for the maximum clique problem", Comput. Oper. Res. 2011.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.ones((4, 4), dtype=bool)
    >>> A[0, 3] = A[3, 0] = False
    >>> maximum_clique(A).tolist()
    [0, 1, 2]
    >>> maximum_clique(A, exact=False).tolist()
    [0, 1, 2]
    """
    where = "maximum_clique"
    exact = check_bool(exact, "exact", where)
    if time_limit is not None:
        time_limit = check_real(time_limit, "time_limit", where, minimum=0.0, strict=True)
    A = _adjacency(adjacency, where)
    deadline = None if time_limit is None else time.perf_counter() + time_limit
    clique, optimal = _maximum_clique(A, exact, deadline)
    if not optimal:
        warnings.warn(
            f"maximum_clique: its time budget of {time_limit} s ran out; the clique of {clique.size} "
            "vertices returned may not be maximum",
            CliqueTimeLimitWarning,
            stacklevel=2,
        )
    return clique


# =========================================================================== consistency graph
def _adjoint(p):
    """SE(2) adjoint of poses ``p`` (..., 3): ``[[R, (y, -x)^T], [0, 0, 1]]``, shape (..., 3, 3).

    ``X Exp(xi) X^-1 = Exp(Ad(X) xi)`` for twists ``xi = (v_x, v_y, omega)``.
    """
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    Ad = np.zeros(p.shape[:-1] + (3, 3))
    Ad[..., 0, 0], Ad[..., 0, 1], Ad[..., 0, 2] = c, -s, p[..., 1]
    Ad[..., 1, 0], Ad[..., 1, 1], Ad[..., 1, 2] = s, c, -p[..., 0]
    Ad[..., 2, 2] = 1.0
    return Ad


def _compose(a, b):
    """``a ⊕ b`` without checks (arrays already validated), shape (..., 3)."""
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack(
        [
            a[..., 0] + c * b[..., 0] - s * b[..., 1],
            a[..., 1] + s * b[..., 0] + c * b[..., 1],
            se2.wrap_angle(a[..., 2] + b[..., 2]),
        ],
        axis=-1,
    )


def _inverse(p):
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    return np.stack(
        [-(c * p[..., 0] + s * p[..., 1]), s * p[..., 0] - c * p[..., 1], -p[..., 2]], axis=-1
    )


@dataclass(frozen=True)
class ConsistencyGraph:
    """The pairwise consistency graph of a pose graph's loop closures.

    Attributes
    ----------
    closures : ndarray of int, shape (L,)
        Edge indices of the closures; vertex ``a`` of the consistency graph is edge
        ``closures[a]``.
    adjacency : ndarray of bool, shape (L, L)
        ``d2 <= threshold`` off the diagonal (symmetric, False on the diagonal).
    d2 : ndarray of float32, shape (L, L)
        Squared Mahalanobis distance of each pair's loop (0 on the diagonal).
    threshold : float
        ``chi2.ppf(confidence, 3)``.
    confidence : float
    poses : ndarray, shape (n, 3)
        The dead-reckoning poses the test linearizes at (rows of the graph).
    seconds : float
        Time to build it.
    """

    closures: np.ndarray
    adjacency: np.ndarray
    d2: np.ndarray
    threshold: float
    confidence: float
    poses: np.ndarray
    seconds: float


@dataclass(frozen=True)
class PCMResult:
    """The outcome of :func:`pcm`.

    Attributes
    ----------
    inlier : ndarray of bool, shape (m,)
        Edges kept: every edge that is not a tested closure, and the closures of the clique.
    clique : ndarray of int
        Edge indices of the closures kept (sorted).
    consistency : ConsistencyGraph
    optimal : bool
        False only when ``time_limit`` cut the clique search short.
    seconds_graph, seconds_clique : float
        Time to build the consistency graph and to find the clique.
    """

    inlier: np.ndarray
    clique: np.ndarray
    consistency: ConsistencyGraph
    optimal: bool
    seconds_graph: float
    seconds_clique: float


def _chain(graph, where):
    """Chain edges, dead-reckoning poses, rank of each row and per-step covariance prefix sums."""
    try:
        edge, forward = graph.odometric_chain()
    except GraphError as exc:
        raise GraphError(
            f"{where}: pairwise consistency needs the odometry between consecutive poses: {exc}"
        ) from exc
    X = graph.odometry_guess()
    rank = graph.order
    by_rank = np.argsort(graph.ids, kind="stable")
    Xr = X[by_rank]  # poses in chain order
    # step s goes from chain pose s to s+1.  A forward edge: X_{s+1} = X_s Z_s Exp(eta_s), so
    # the world-frame perturbation grows by xi_s = Ad(X_{s+1}) eta_s; a backward edge
    # (s+1 -> s): X_{s+1} = X_s Exp(-eta_s) Z_s^-1, xi_s = -Ad(X_s) eta_s
    cov = np.linalg.inv(graph.information[edge])  # Omega_s^-1, g2o frame (measurement's end)
    frame = np.where(forward[:, None], Xr[1:], Xr[:-1])
    Ad = _adjoint(frame)
    Q = Ad @ cov @ np.swapaxes(Ad, -1, -2)  # Q_s = Ad Omega_s^-1 Ad^T, world frame
    P = np.concatenate([np.zeros((1, 3, 3)), np.cumsum(Q, axis=0)])  # P_t = sum_{s<t} Q_s
    return edge, X, rank, np.ascontiguousarray(P.transpose(1, 2, 0))


def _closures(graph, closures, chain_edges, where):
    if closures is None:
        mask = graph.loop_closure.copy()
        mask[chain_edges] = False  # backward-stored chain edges are odometry, not closures
        return np.flatnonzero(mask)
    c = np.asarray(closures)
    if c.dtype == bool:
        if c.shape != (graph.m,):
            raise OptionError(
                f"{where}: closures as a mask must have shape ({graph.m},); got {c.shape}"
            )
        c = np.flatnonzero(c)
    elif c.dtype.kind not in "iu" or c.ndim != 1:
        raise OptionTypeError(
            f"{where}: closures must be a 1-D array of edge indices or a bool mask of shape "
            f"({graph.m},); got dtype {c.dtype}, shape {c.shape}"
        )
    c = c.astype(np.int64)
    bad = c[(c < 0) | (c >= graph.m)]
    if bad.size:
        raise OptionError(f"{where}: closures holds edge {bad[0]}, but the graph has {graph.m}")
    if np.unique(c).size != c.size:
        raise OptionError(f"{where}: closures lists an edge twice")
    on_chain = np.intersect1d(c, chain_edges)
    if on_chain.size:
        raise OptionError(
            f"{where}: closures holds edge {on_chain[0]}, which is on the odometric chain the "
            "test composes (its noise would be counted twice); pass loop closures only"
        )
    return np.sort(c)


def _mm(A, B):
    """Product of 3x3 matrices stored entry-wise (lists of (N,) arrays or scalars; 0 skipped).

    Structure-of-arrays: ~5x faster than ``np.matmul`` on (N, 3, 3) stacks, and the zeros of
    the SE(2) adjoints' last row cost nothing.
    """
    out = [[0.0] * 3 for _ in range(3)]
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                a, b = A[i][k], B[k][j]
                if _zero(a) or _zero(b):
                    continue
                acc = a * b if _zero(acc) else acc + a * b
            out[i][j] = acc
    return out


def _zero(x):
    return isinstance(x, float) and x == 0.0


def _tr(A):
    return [[A[j][i] for j in range(3)] for i in range(3)]


def _add(A, B, sign=1.0):
    return [[A[i][j] + sign * B[i][j] for j in range(3)] for i in range(3)]


def _soa_adjoint(p):
    """SE(2) adjoint entry-wise: ``[[c, -s, y], [s, c, -x], [0, 0, 1]]`` for poses p (N, 3)."""
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    return [[c, -s, p[:, 1]], [s, c, -p[:, 0]], [0.0, 0.0, 1.0]]


def _gather(S, idx):
    """Rows ``idx`` of an entry-wise matrix stack ``S`` (3, 3, K)."""
    return [[S[i, j][idx] for j in range(3)] for i in range(3)]


def _pair_terms(ca, cb, pre, P):
    """Loop statistic v (N, 3) and covariance Sigma (entry-wise 3x3 of (N,)) for closure rows."""
    D, Rc, ri, rj = pre
    Da, Db = D[ca], D[cb]
    M = _compose(Da, _inverse(Db))  # M_ab = D_a D_b^-1
    theta = M[:, 2]
    c, _ = se2._half_cot(theta)
    h = 0.5 * theta
    # v_ab = log(M_ab) (se2.log): zero for two right closures up to noise
    v = np.stack([c * M[:, 0] + h * M[:, 1], -h * M[:, 0] + c * M[:, 1], theta], axis=1)
    AdD, AdM = _soa_adjoint(Da), _soa_adjoint(M)
    minus = [[-x for x in row] for row in AdD]
    # dv = dD_a - Ad(M) dD_b, with dD_a = eps_i - Ad(D_a) eps_j + Ad(X_i Z_a) eta_a:
    # coefficients of eps_i, eps_j, eps_k, eps_l are I, -Ad(D_a), -Ad(M), Ad(M) Ad(D_b) = Ad(D_a)
    eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    C = [eye, minus, [[-x for x in row] for row in AdM], AdD]
    # closure noise: Sigma = R_a + Ad(M) R_b Ad(M)^T, R_a = Ad(X_i Z_a) Omega_a^-1 Ad(X_i Z_a)^T
    S = _add(_gather(Rc, ca), _mm(_mm(AdM, _gather(Rc, cb)), _tr(AdM)))
    t = np.stack([ri[ca], rj[ca], ri[cb], rj[cb]], axis=1)  # chain ranks of i, j, k, l
    ts = np.sort(t, axis=1)
    # odometry step s in [t_(q-1), t_(q)) moves exactly the poses ranked >= t_(q): its weight is
    # W_q = sum_{p: t_p >= t_(q)} C_p.  Steps before t_(1) move all four poses together (gauge
    # at the earliest pose: they change only the frame the loop is written in, L = X_(1)^-1 M X_(1))
    for q in range(1, 4):
        above = [(t[:, p] >= ts[:, q]).astype(float) for p in range(4)]
        W = [[0.0] * 3 for _ in range(3)]
        for p in range(4):
            for i in range(3):
                for j in range(3):
                    x = C[p][i][j]
                    if not _zero(x):
                        W[i][j] = W[i][j] + above[p] * x
        seg = _add(_gather(P, ts[:, q]), _gather(P, ts[:, q - 1]), -1.0)  # P_t(q) - P_t(q-1)
        S = _add(S, _mm(_mm(W, seg), _tr(W)))  # Sigma += W_q (P_t(q) - P_t(q-1)) W_q^T
    return v, S


def _sym_quadratic(S, v):
    """``v^T S^-1 v`` for symmetric positive definite 3x3 ``S`` (entry-wise), ``v`` (N, 3).

    Closed-form LDL^T of a 3x3 matrix, vectorized.
    """
    a, b, c = S[0][0], S[0][1], S[0][2]
    d, e, f = S[1][1], S[1][2], S[2][2]
    l10 = b / a
    l20 = c / a
    d1 = d - l10 * b
    l21 = (e - l20 * b) / d1
    d2 = f - l20 * c - l21 * (e - l20 * b)
    y0 = v[:, 0]
    y1 = v[:, 1] - l10 * y0
    y2 = v[:, 2] - l20 * y0 - l21 * y1
    return y0 * y0 / a + y1 * y1 / d1 + y2 * y2 / d2


def _precompute(graph, closures, X, rank):
    e = graph.edges[closures]
    Xi, Xj = X[e[:, 0]], X[e[:, 1]]
    Z = graph.measurements[closures]
    XiZ = _compose(Xi, Z)
    D = _compose(XiZ, _inverse(Xj))  # D_a = X_i Z_a X_j^-1
    Ad = _adjoint(XiZ)
    Rc = Ad @ np.linalg.inv(graph.information[closures]) @ np.swapaxes(Ad, -1, -2)
    return D, np.ascontiguousarray(Rc.transpose(1, 2, 0)), rank[e[:, 0]], rank[e[:, 1]]


def _loop(graph, closures, a, b):
    """(v, Sigma) of the loop of closures ``closures[a]``, ``closures[b]`` (for tests, teaching)."""
    _, X, rank, P = _chain(graph, "consistency_graph")
    pre = _precompute(graph, np.asarray(closures), X, rank)
    v, S = _pair_terms(np.array([a]), np.array([b]), pre, P)
    S = np.array([[np.broadcast_to(x, (1,))[0] for x in row] for row in S])
    return v[0], S


def consistency_graph(graph, closures=None, *, confidence=0.99):
    """Which pairs of loop closures agree with each other and the odometry (Mangelson et al. 2018).

    For closures ``a = (i -> j, Z_a)`` and ``b = (k -> l, Z_b)``, with the dead-reckoning poses
    ``X`` and ``D_a = X_i Z_a X_j^-1``::

        v_ab = log(D_a D_b^-1)                                   shape (3,)
        d²_ab = v_ab^T Sigma_ab^-1 v_ab,  consistent iff d²_ab <= chi2.ppf(confidence, 3)

    (Mangelson et al. 2018).  ``Sigma_ab`` is exact to first order: with
    world-frame perturbations ``X_t -> Exp(eps_t) X_t``, ``eps_t = sum_{s<t} xi_s``,
    ``xi_s = Ad(X_{s+1}) eta_s`` for the odometry step ``s`` (noise ``eta_s ~ N(0, Omega_s^-1)``
    in the g2o frame of the step's end) and closure noise ``Z_a -> Z_a Exp(eta_a)``::

        dD_a = eps_i - Ad(D_a) eps_j + Ad(X_i Z_a) eta_a
        dv   = dD_a - Ad(D_a D_b^-1) dD_b

    and the covariance of ``sum_p C_p eps_{t_p}`` is a sum over the segments between the sorted
    indices of prefix sums ``P_t = sum_{s<t} Ad(X_{s+1}) Omega_s^-1 Ad(X_{s+1})^T``, each weighted
    by the coefficients of the indices above it.  The steps before the earliest of the four poses
    are left out: they only move the frame the loop is seen in (the gauge).  ``Sigma_ab`` is the
    covariance of the left perturbation of ``M_ab``; it is that of ``v_ab`` where the test's
    hypothesis holds (``M_ab = I``, where ``d log = I``); for a wrong pair (``M_ab`` far from
    ``I``) ``v_ab`` is large whatever the Jacobian of ``log``.

    Parameters
    ----------
    graph : PoseGraph
        Must have an odometric chain (an edge between every pair of consecutive ids).
    closures : array_like of int or bool mask of shape (m,), optional
        Edges to test; default: every edge off the odometric chain.
    confidence : float
        In (0, 1); the chi-square quantile with 3 degrees of freedom is the threshold.

    Returns
    -------
    ConsistencyGraph

    Raises
    ------
    GraphError
        If the graph has no odometric chain (PCM needs the odometry), or is invalid.
    OptionError, OptionTypeError
        If ``closures`` or ``confidence`` is invalid (the message names it).

    Notes
    -----
    All ``L (L - 1) / 2`` pairs are evaluated, :data:`CHUNK` at a time: ~3 s and ~130 MB for
    ``L = 3000``.  ``d2`` is stored as float32 (``4 L²`` bytes).

    References
    ----------
    J. G. Mangelson, D. Dominic, R. M. Eustice and R. Vasudevan, "Pairwise Consistency
    Maximization for Robust Multi-Robot Map Merging", ICRA 2018.

    Examples
    --------
    >>> import numpy as np
    >>> from lagolib.simulate import manhattan_world
    >>> g = manhattan_world(n_poses=300, rng=0).graph
    >>> cg = consistency_graph(g)
    >>> cg.adjacency.shape == (cg.closures.size, cg.closures.size)
    True
    >>> round(float(cg.threshold), 3)
    11.345
    """
    where = "consistency_graph"
    start = time.perf_counter()
    check_graph(graph, where)
    confidence = check_real(confidence, "confidence", where, minimum=0.0, maximum=1.0, strict=True)
    chain_edges, X, rank, P = _chain(graph, where)
    closures = _closures(graph, closures, chain_edges, where)
    L = closures.size
    pre = _precompute(graph, closures, X, rank)
    d2 = np.zeros((L, L), dtype=np.float32)
    a0 = 0
    while a0 < L - 1:  # rows a0..a1-1, each paired with every later closure
        a1, count = a0, 0
        while a1 < L - 1 and (count == 0 or count + (L - 1 - a1) <= CHUNK):
            count += L - 1 - a1
            a1 += 1
        lens = L - 1 - np.arange(a0, a1)
        ca = np.repeat(np.arange(a0, a1), lens)
        cb = np.concatenate([np.arange(a + 1, L) for a in range(a0, a1)])
        v, S = _pair_terms(ca, cb, pre, P)
        q = _sym_quadratic(S, v)
        d2[ca, cb] = q
        d2[cb, ca] = q
        a0 = a1
    threshold = float(_chi2.ppf(confidence, 3))
    adjacency = d2 <= threshold
    np.fill_diagonal(adjacency, False)
    return ConsistencyGraph(
        closures=closures,
        adjacency=adjacency,
        d2=d2,
        threshold=threshold,
        confidence=confidence,
        poses=X,
        seconds=time.perf_counter() - start,
    )


#: :func:`pcm`'s default budget for the clique search, in seconds: on consistency graphs of a
#: few thousand closures the exact search can take far longer (M3500 with 1000 random wrong
#: closures did not finish in 20 s), and a budget turns a hang into a warned, best-so-far answer.
PCM_TIME_LIMIT = 30.0


def pcm(graph, *, confidence=0.999, exact=True, time_limit=PCM_TIME_LIMIT):
    """Pairwise consistency maximization: keep a maximum clique of mutually consistent closures.

    Parameters
    ----------
    graph : PoseGraph
        With an odometric chain; every edge off the chain is a candidate closure.
    confidence : float
        Of the pairwise test (:func:`consistency_graph`).  The default 0.999, not 0.99: a
        maximum clique must leave out one closure of every pair that fails the test, so even
        1 % of right pairs failing by chance costs many right closures (on a 400-pose world
        at 0.99: 104 of them).
    exact : bool
        Exact maximum clique (True) or the greedy heuristic (:func:`maximum_clique`).
    time_limit : float or None
        Seconds for the clique search (default :data:`PCM_TIME_LIMIT`; None: no limit); when
        it runs out a :class:`CliqueTimeLimitWarning` says so and ``optimal`` is False.

    Returns
    -------
    PCMResult

    Raises
    ------
    GraphError
        If the graph has no odometric chain.
    OptionError, OptionTypeError
        If an option is invalid.

    References
    ----------
    J. G. Mangelson, D. Dominic, R. M. Eustice and R. Vasudevan, "Pairwise Consistency
    Maximization for Robust Multi-Robot Map Merging", ICRA 2018, Algorithm 1.

    Examples
    --------
    >>> import numpy as np
    >>> from lagolib.graph import PoseGraph
    >>> from lagolib.simulate import manhattan_world
    >>> g = manhattan_world(n_poses=300, rng=0).graph
    >>> k = int(np.flatnonzero(g.loop_closure)[0])
    >>> z = g.measurements.copy()
    >>> z[k, 0] += 5.0  # a wrong closure: 5 m off
    >>> bad = PoseGraph(g.poses, g.edges, z, g.information, ids=g.ids)
    >>> result = pcm(bad, confidence=0.999)
    >>> bool(result.inlier[k]), bool(np.all(result.inlier[bad.odometric]))
    (False, True)
    """
    where = "pcm"
    check_graph(graph, where)
    exact = check_bool(exact, "exact", where)
    if time_limit is not None:
        time_limit = check_real(time_limit, "time_limit", where, minimum=0.0, strict=True)
    cg = consistency_graph(graph, confidence=confidence)
    start = time.perf_counter()
    deadline = None if time_limit is None else start + time_limit
    A = sparse.csr_matrix(cg.adjacency)
    members, optimal = _maximum_clique(A, exact, deadline)
    seconds = time.perf_counter() - start
    clique = cg.closures[members]
    inlier = np.ones(graph.m, dtype=bool)
    inlier[cg.closures] = False
    inlier[clique] = True
    return PCMResult(
        inlier=inlier,
        clique=clique,
        consistency=cg,
        optimal=bool(optimal),
        seconds_graph=cg.seconds,
        seconds_clique=seconds,
    )
