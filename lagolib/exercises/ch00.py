"""Checks for the preface's exercise: counting with the three sources' notations.

===========  =========  ==========================================================================
exercise     kind       check
===========  =========  ==========================================================================
0.1          predict    :func:`check_notation` — Carlone's ``n``, the shape of his ``A``, and the
                        length of the lecture notes' state vector, for :func:`notation_graph`
===========  =========  ==========================================================================

The check prints one line starting ``Exercise 0.1`` (correct / not yet / not attempted yet, see
:mod:`lagolib.exercises`) and returns True or False; it never raises on a wrong answer.
"""

from __future__ import annotations

from lagolib import PoseGraph, simulate, topology
from lagolib.exercises._coerce import Int, Shape
from lagolib.exercises._feedback import (
    NOT_ATTEMPTED,
    check,
    compare_int,
    is_placeholder,
    verdict,
)

__all__ = ["notation_graph", "check_notation"]


def notation_graph() -> PoseGraph:
    """The exercise's graph: three laps of a square, 4 poses per lap (12 poses, 19 edges)."""
    return simulate.loop_world(laps=3, poses_per_lap=4).graph


@check(
    "0.1",
    n_unknown=Int(),
    A_shape=Shape(2, "a shape, a tuple of 2 whole numbers (rows, columns)"),
    state_length=Int(),
)
def check_notation(n_unknown, A_shape, state_length):
    """Exercise 0.1: counts for :func:`notation_graph` in the sources' notations.

    Compares ``n_unknown`` with Carlone et al.'s ``n`` (the nodes are ``n + 1``; the anchor's pose
    is known), ``A_shape`` with the shape of the reduced incidence matrix ``A``
    (:func:`lagolib.topology.reduced_incidence_matrix`), and ``state_length`` with the length of
    the lecture notes' state vector ``x`` (three numbers for every pose; the notes fix the gauge
    with a prior on ``x_0``, not by leaving a pose out).

    Parameters
    ----------
    n_unknown : int
    A_shape : tuple of two ints
        Also a list or a 1-d integer array (``A.shape`` as numpy gives it); a dict, a set, a
        string, bools or fractions are reported as not a shape.
    state_length : int

    Returns
    -------
    bool
    """
    ex = "0.1"
    if any(is_placeholder(a) for a in (n_unknown, A_shape, state_length)):
        return verdict(ex, NOT_ATTEMPTED)
    graph = notation_graph()
    nodes, m = graph.n, graph.m
    n = nodes - 1
    A = topology.reduced_incidence_matrix(graph).shape
    problems = []
    wrong = compare_int(n_unknown, n, name="n_unknown")
    if wrong is not None:
        if n_unknown == nodes:
            wrong = (
                f"n_unknown = {nodes} counts every pose: Carlone's n leaves the anchor out (his "
                "graph has n + 1 nodes, and its anchor's pose is known)."
            )
        problems.append(wrong)
    shape = A_shape  # read by @check as a tuple of two ints
    if shape != A:
        if shape == (nodes, m):
            problems.append(
                f"A_shape = {shape} is the shape of 𝒜, the full incidence matrix: A drops the "
                "anchor's row."
            )
        elif shape == A[::-1]:
            problems.append(
                f"A_shape = {shape} is transposed: A has a row per unknown pose and "
                "a column per edge."
            )
        else:
            wrong_dims = [w for w, a, b in zip(("rows", "columns"), shape, A) if a != b]
            problems.append(
                f"A_shape = {shape}: its number of {' and of '.join(wrong_dims)} is not A's "
                "(a row per unknown pose, a column per edge)."
            )
    wrong = compare_int(state_length, 3 * nodes, name="state_length")
    if wrong is not None:
        if state_length == 3 * n:
            wrong = (
                f"state_length = {3 * n} leaves x_0 out: the notes keep every pose in x and fix "
                "the gauge with a prior on x_0."
            )
        elif state_length == 4 * nodes:
            wrong = f"state_length = {4 * nodes} is Lodi Rizzini's (x, y, c, s): the notes use (x, y, θ)."
        problems.append(wrong)
    if problems:
        return verdict(
            ex,
            " ".join(problems),
            hint=(
                "the preface's notation table has a row on n vs n + 1 nodes and on the state.",
                "Carlone's n counts the poses to estimate, not the anchor; his A has one row per "
                "estimated pose and one column per edge; the notes' x stacks (x, y, θ) of every "
                "pose, x_0 included.",
            ),
        )
    return verdict(
        ex,
        None,
        correct=f"n = {n}, A is {A[0]}×{A[1]}, x has {3 * nodes} entries ({nodes} poses, {m} edges).",
    )
