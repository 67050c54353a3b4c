"""Reading and writing pose graphs: g2o and TORO files, and plain pose lists.

Two text formats are in use for planar pose graphs; they differ in more than their tags.

========  =====================================================  ===================================
format    line                                                   information applies to
========  =====================================================  ===================================
g2o       ``VERTEX_SE2 id x y theta``                            the error in the measurement's
          ``EDGE_SE2 i j dx dy dth I11 I12 I13 I22 I23 I33``     frame, ``t2v(Z^-1 X_i^-1 X_j)``
TORO      ``VERTEX2 id x y theta``                               the error in frame ``i``,
          ``EDGE2 i j dx dy dth I11 I12 I22 I33 I13 I23``        ``R_i^T (t_j - t_i) - dt``
========  =====================================================  ===================================

Both store the upper triangle of a symmetric information matrix, in a different order.  lagolib
keeps every information matrix in the g2o convention, so TORO matrices are converted on reading,
``Omega_g2o = G^T Omega_toro G`` with ``G = blockdiag(R(dth), 1)``, and back on writing.  (The g2o
translational error is the frame-``i`` error rotated by ``R(dth)^T``; see ``SOURCES.md`` of the
benchmark data, quirk 2.)

Readers are strict: a malformed line raises :class:`~lagolib.errors.ParseError` naming
``file:line`` and what is wrong.  Comment lines (``#``) and blank lines are skipped.  Tags the
format does not define (``EQUIV``, ``FIX``, ``VERTEX_XY``, …) are errors unless
``ignore_unknown=True``, which skips them and says how many in a
:class:`~lagolib.errors.SkippedLinesWarning`.

Nothing is lost on writing: floats are written with ``repr`` precision, so
``read_g2o(write_g2o(read_g2o(f)))`` gives bit-identical arrays.  For TORO the conversion to and
from the g2o convention is two rotations, which round the information matrices by a few units in
the last place.
"""

from __future__ import annotations

import os
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from . import se2
from .errors import GraphError, ParseError, SkippedLinesWarning
from .graph import PoseGraph, describe_bad_information, first_bad_information

__all__ = [
    "read",
    "write",
    "read_g2o",
    "write_g2o",
    "read_toro",
    "write_toro",
    "read_poses",
    "write_poses",
    "detect_format",
]

# position of the six stored numbers in the 3x3 matrix, per format
_UPPER = {
    "g2o": ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)),  # I11 I12 I13 I22 I23 I33
    "toro": ((0, 0), (0, 1), (1, 1), (2, 2), (0, 2), (1, 2)),  # I11 I12 I22 I33 I13 I23
}
_TAGS = {"g2o": ("VERTEX_SE2", "EDGE_SE2"), "toro": ("VERTEX2", "EDGE2")}
_EXTENSIONS = {".g2o": "g2o", ".graph": "toro"}


def _float(tok, path, lineno, what):
    try:
        value = float(tok)
    except ValueError:
        raise ParseError(path, lineno, f"{what} is not a number: {tok!r}") from None
    if not np.isfinite(value):
        raise ParseError(path, lineno, f"{what} is not finite: {tok!r}")
    return value


def _int(tok, path, lineno, what):
    try:
        return int(tok)
    except ValueError:
        raise ParseError(path, lineno, f"{what} is not an integer vertex id: {tok!r}") from None


_VERTEX_FIELDS = ("x", "y", "theta")
_EDGE_FIELDS = ("dx", "dy", "dtheta") + tuple(f"information entry {k}" for k in range(1, 7))


def _data_lines(path):
    """Yield ``(line number, tokens)`` of every line that is not blank or a ``#`` comment."""
    try:
        with open(path, encoding="utf-8") as f:
            for lineno, raw in enumerate(f, 1):
                tok = raw.split()
                if tok and not tok[0].startswith("#"):
                    yield lineno, tok
    except UnicodeDecodeError:
        # text files are decoded in chunks, so the line being read is not the culprit's: find it
        with open(path, "rb") as f:
            bad = next((k for k, raw in enumerate(f, 1) if not _is_utf8(raw)), None)
        raise ParseError(path, bad, "not UTF-8 text: is this a pose-graph file?") from None


def _is_utf8(raw):
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


def _parse_lines(path, fmt, ignore_unknown):
    """Split a g2o/TORO file into vertex and edge records, keeping line numbers."""
    vtag, etag = _TAGS[fmt]
    v_ids, v_vals, v_lines = [], [], []
    e_ids, e_vals, e_lines = [], [], []
    skipped = Counter()
    for lineno, tok in _data_lines(path):
        tag = tok[0]
        if tag == etag:
            if len(tok) != 12:
                raise ParseError(
                    path,
                    lineno,
                    f"{etag} needs 11 numbers (i j dx dy dtheta and 6 information entries); "
                    f"got {len(tok) - 1}",
                )
            e_ids.append(tok[1:3])
            e_vals.append(tok[3:])
            e_lines.append(lineno)
        elif tag == vtag:
            if len(tok) != 5:
                raise ParseError(
                    path, lineno, f"{vtag} needs 4 numbers (id x y theta); got {len(tok) - 1}"
                )
            v_ids.append(tok[1:2])
            v_vals.append(tok[2:])
            v_lines.append(lineno)
        elif ignore_unknown:
            skipped[tag] += 1
        else:
            other = "toro" if fmt == "g2o" else "g2o"
            hint = (
                f"this looks like a {other} file: use read_{other} or read"
                if tag in _TAGS[other]
                else "pass ignore_unknown=True to skip such lines"
            )
            raise ParseError(
                path,
                lineno,
                f"unknown tag {tag!r} in a {fmt} file (expected {vtag} or {etag}); {hint}",
            )
    if skipped:
        what = ", ".join(f"{count} {tag}" for tag, count in sorted(skipped.items()))
        warnings.warn(
            f"{path}: skipped {sum(skipped.values())} line(s) with tags lagolib does not read: {what}",
            SkippedLinesWarning,
            stacklevel=4,  # _parse_lines <- _build <- read/read_g2o/read_toro <- the caller
        )
    v_ids = _to_array(v_ids, np.int64, v_lines, path, ("id",), _int).reshape(-1)
    v_vals = _to_array(v_vals, float, v_lines, path, _VERTEX_FIELDS, _float).reshape(-1, 3)
    e_ids = _to_array(e_ids, np.int64, e_lines, path, ("i", "j"), _int).reshape(-1, 2)
    e_vals = _to_array(e_vals, float, e_lines, path, _EDGE_FIELDS, _float).reshape(-1, 9)
    return (v_ids, v_vals, v_lines), (e_ids, e_vals, e_lines)


def _to_array(rows, dtype, lines, path, fields, convert):
    """Convert lists of number strings in one go; on failure, find and name the bad field."""
    try:
        arr = np.array(rows, dtype=dtype) if rows else np.zeros((0, len(fields)), dtype=dtype)
    except (ValueError, OverflowError):  # slow path: names the first bad field, or converts
        arr = np.array(
            [[convert(t, path, n, w) for t, w in zip(row, fields)] for row, n in zip(rows, lines)],
            dtype=dtype,
        )
    if dtype is float:
        bad = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
        if bad.size:
            k = bad[0]
            col = int(np.flatnonzero(~np.isfinite(arr[k]))[0])
            raise ParseError(path, lines[k], f"{fields[col]} is not finite: {rows[k][col]!r}")
    return arr


def _rotation_blocks(dtheta):
    """G = blockdiag(R(dtheta), 1) for each edge, shape (m, 3, 3)."""
    G = np.zeros((len(dtheta), 3, 3))
    G[:, :2, :2] = se2.rotation(dtheta)
    G[:, 2, 2] = 1.0
    return G


def toro_to_g2o_information(information, dtheta):
    """Convert TORO information matrices (frame-``i`` error) to the g2o convention.

    ``Omega_g2o = G^T Omega_toro G`` with ``G = blockdiag(R(dtheta), 1)``: the g2o translational
    error is ``R(dtheta)^T`` times the frame-``i`` error, so ``e_i = G e_g2o``.

    Parameters
    ----------
    information : ndarray, shape (m, 3, 3)
    dtheta : ndarray, shape (m,)
        Measured relative angles.

    Returns
    -------
    ndarray, shape (m, 3, 3)
    """
    G = _rotation_blocks(dtheta)
    return np.einsum("kba,kbc,kcd->kad", G, information, G)


def g2o_to_toro_information(information, dtheta):
    """Inverse of :func:`toro_to_g2o_information`: ``Omega_toro = G Omega_g2o G^T``."""
    G = _rotation_blocks(dtheta)
    return np.einsum("kab,kbc,kdc->kad", G, information, G)


def _build(path, fmt, ignore_unknown):
    (v_ids, v_vals, v_lines), (e_ids, e_vals, e_lines) = _parse_lines(path, fmt, ignore_unknown)
    vtag, etag = _TAGS[fmt]
    if not len(v_ids) and not len(e_ids):
        raise ParseError(
            path, None, f"no {vtag} or {etag} lines: the file is empty or not a {fmt} file"
        )

    index = {}
    for k, (vid, lineno) in enumerate(zip(v_ids.tolist(), v_lines)):
        if vid in index:
            raise ParseError(
                path,
                lineno,
                f"duplicate vertex id {vid} (first defined on line {v_lines[index[vid]]})",
            )
        index[vid] = k

    vals = e_vals
    no_vertices = not len(v_ids)
    if no_vertices:
        ids = np.unique(e_ids)
        edges = np.searchsorted(ids, e_ids)
    else:
        ids = v_ids
        order = np.argsort(ids, kind="stable")
        pos = np.minimum(np.searchsorted(ids, e_ids, sorter=order), len(ids) - 1)
        edges = order[pos]
        unknown = np.flatnonzero(np.any(ids[edges] != e_ids, axis=1))
        if unknown.size:
            k = unknown[0]
            i, j = e_ids[k].tolist()
            v = i if ids[edges[k, 0]] != i else j
            raise ParseError(
                path, e_lines[k], f"edge {i} -> {j} refers to vertex {v}, which has no {vtag} line"
            )
    for k in np.flatnonzero(edges[:, 0] == edges[:, 1])[:1]:
        raise ParseError(path, e_lines[k], f"edge {e_ids[k, 0]} -> {e_ids[k, 1]} is a self-loop")

    info = np.zeros((len(vals), 3, 3))
    for col, (a, b) in enumerate(_UPPER[fmt]):
        info[:, a, b] = info[:, b, a] = vals[:, 3 + col]
    bad = first_bad_information(info) if len(info) else None
    if bad is not None:
        raise ParseError(path, e_lines[bad], describe_bad_information(info[bad]))
    measurements = vals[:, :3]
    if fmt == "toro":
        info = toro_to_g2o_information(info, measurements[:, 2])

    if no_vertices:
        graph = PoseGraph(np.zeros((len(ids), 3)), edges, measurements, info, ids=ids)
        try:
            return graph.with_poses(graph.odometry_guess(start=np.zeros(3)))
        except GraphError as exc:  # a broken chain: say which file
            raise ParseError(path, None, f"file has no {vtag} lines and {exc}") from exc
    return PoseGraph(v_vals, edges, measurements, info, ids=ids)


def read_g2o(path, *, ignore_unknown=False):
    """Read a planar g2o file (``VERTEX_SE2`` / ``EDGE_SE2`` lines).

    Files with edges but no vertices (SE-Sync's ``manhattan.g2o`` and ``CSAIL.g2o``) are accepted:
    the vertices are created from the ids the edges use, and their poses are composed along the
    odometric chain from the origin (:meth:`PoseGraph.odometry_guess`).

    Parameters
    ----------
    path : str or os.PathLike
    ignore_unknown : bool
        Skip lines with other tags (and warn how many) instead of raising.

    Returns
    -------
    PoseGraph
        Vertices in file order; information matrices as stored (g2o convention).

    Raises
    ------
    ParseError
        ``file:line`` and the problem: unknown tag, wrong number of fields, a field that is not a
        number or not finite, duplicate vertex id, an edge to an unknown vertex, a self-loop, an
        information matrix that is not positive definite, or a file with no vertex or edge.
    """
    return _build(path, "g2o", ignore_unknown)


def read_toro(path, *, ignore_unknown=False):
    """Read a TORO file (``VERTEX2`` / ``EDGE2`` lines, information order I11 I12 I22 I33 I13 I23).

    The information matrices are converted from TORO's frame-``i`` error to the g2o convention
    (module docstring).  Everything else is as :func:`read_g2o`.
    """
    return _build(path, "toro", ignore_unknown)


def detect_format(path):
    """``"g2o"`` or ``"toro"``, from the first vertex or edge tag in the file.

    Raises
    ------
    ParseError
        If no line starts with ``VERTEX_SE2``, ``EDGE_SE2``, ``VERTEX2`` or ``EDGE2``.
    """
    for _, tok in _data_lines(path):
        for fmt, tags in _TAGS.items():
            if tok[0] in tags:
                return fmt
    raise ParseError(
        path,
        None,
        "no VERTEX_SE2/EDGE_SE2 (g2o) or VERTEX2/EDGE2 (TORO) line: not a pose-graph file",
    )


def read(path, *, ignore_unknown=False):
    """Read a g2o or TORO pose-graph file, detecting the format from its tags.

    See :func:`read_g2o` and :func:`read_toro`.
    """
    return _build(path, detect_format(path), ignore_unknown)


def _fmt_rows(rows):
    return [" ".join(map(repr, row)) for row in rows]


def write_g2o(graph, path):
    """Write ``graph`` as a g2o file; floats are written with ``repr`` (round-trip) precision."""
    _write(graph, path, "g2o")


def write_toro(graph, path):
    """Write ``graph`` as a TORO file, converting the information back to TORO's convention."""
    _write(graph, path, "toro")


def write(graph, path, format=None):
    """Write ``graph`` to ``path`` as ``format`` (``"g2o"`` or ``"toro"``).

    Without ``format`` the extension decides: ``.g2o`` is g2o and ``.graph`` is TORO.
    """
    if format is None:
        format = _EXTENSIONS.get(Path(path).suffix.lower())
        if format is None:
            raise ValueError(
                f"cannot tell the format of {os.fspath(path)!r} from its extension; "
                "pass format='g2o' or format='toro'"
            )
    if format not in _TAGS:
        raise ValueError(f"format must be 'g2o' or 'toro'; got {format!r}")
    _write(graph, path, format)


def _write(graph, path, fmt):
    vtag, etag = _TAGS[fmt]
    info = graph.information
    if fmt == "toro":
        info = g2o_to_toro_information(info, graph.measurements[:, 2])
    upper = np.stack([info[:, a, b] for a, b in _UPPER[fmt]], axis=-1)
    ids = graph.ids
    vertex_rows = np.column_stack([ids, graph.poses]).tolist()
    edge_vals = np.column_stack([graph.measurements, upper]).tolist()
    edge_ids = ids[graph.edges].tolist()
    lines = [f"{vtag} {int(r[0])} {repr(r[1])} {repr(r[2])} {repr(r[3])}" for r in vertex_rows]
    lines += [f"{etag} {i} {j} {v}" for (i, j), v in zip(edge_ids, _fmt_rows(edge_vals))]
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(lines))
        f.write("\n")


def read_poses(path):
    """Read a plain list of poses (ground-truth files): ``x y theta`` or ``id x y theta`` per line.

    With three columns the id is the line's position among the data lines, from 0 (as in
    Olson's ``manhattanOlson3500_nodes_groundTruth.dat``); with four the first column is the id
    (as in ``ring/groundTruth/poses.txt``).

    Returns
    -------
    ids : ndarray of int64, shape (n,)
    poses : ndarray, shape (n, 3)

    Raises
    ------
    ParseError
        For a line with another number of columns than the first, a non-number, or a duplicate id.
    """
    ids, rows, width = [], [], None
    for lineno, tok in _data_lines(path):
        if width is None:
            width = len(tok)
            if width not in (3, 4):
                raise ParseError(
                    path,
                    lineno,
                    f"expected 'x y theta' or 'id x y theta'; got {len(tok)} columns",
                )
        if len(tok) != width:
            raise ParseError(
                path, lineno, f"expected {width} columns like the first line; got {len(tok)}"
            )
        if width == 4:
            ids.append(_int(tok[0], path, lineno, "id"))
        else:
            ids.append(len(rows))
        rows.append([_float(t, path, lineno, w) for t, w in zip(tok[width - 3 :], _VERTEX_FIELDS)])
    if not rows:
        raise ParseError(path, None, "no poses in the file")
    ids = np.array(ids, dtype=np.int64)
    uniq, counts = np.unique(ids, return_counts=True)
    if np.any(counts > 1):
        raise ParseError(path, None, f"vertex id {uniq[counts > 1][0]} appears more than once")
    return ids, np.array(rows, dtype=float)


def write_poses(path, poses, ids=None):
    """Write poses as ``id x y theta`` lines (readable by :func:`read_poses`), ``repr`` precision."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    ids = np.arange(len(poses)) if ids is None else np.asarray(ids, dtype=np.int64)
    rows = poses.tolist()
    with open(path, "w", encoding="utf-8") as f:
        f.writelines(
            f"{int(i)} {repr(r[0])} {repr(r[1])} {repr(r[2])}\n" for i, r in zip(ids, rows)
        )
