"""Small graphs the checks compare a student's answer on."""

import numpy as np

from lagolib import PoseGraph


def independent_edges(p_i, p_j, z, information=None) -> PoseGraph:
    """``k`` separate edges as one graph: edge ``e`` joins pose ``e`` to pose ``k + e``.

    Parameters
    ----------
    p_i, p_j : array_like, shape (k, 3)
        The tail and head pose of each edge, ``(x, y, θ)``.
    z : array_like, shape (k, 3)
        Each edge's measurement, the pose of ``j`` in the frame of ``i``.
    information : array_like, shape (k, 3, 3), optional
        g2o-frame information per edge (default: identity).

    Returns
    -------
    PoseGraph
        ``2k`` poses and ``k`` edges, so that lagolib's per-edge functions (``residuals``,
        ``closed_form.sincos_residuals``, …) give the reference answer of every edge at once.

    >>> g = independent_edges(np.zeros((2, 3)), np.ones((2, 3)), np.ones((2, 3)))
    >>> g.edges.tolist()
    [[0, 2], [1, 3]]
    """
    p_i = np.asarray(p_i, dtype=float)
    k = len(p_i)
    if information is None:
        information = np.tile(np.eye(3), (k, 1, 1))
    return PoseGraph(
        poses=np.vstack([p_i, np.asarray(p_j, dtype=float)]),
        edges=np.column_stack([np.arange(k), k + np.arange(k)]),
        measurements=z,
        information=information,
    )
