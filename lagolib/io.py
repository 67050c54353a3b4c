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
:class:`~lagolib.errors.SkippedLinesWarning`.  Whatever ``ignore_unknown`` says, 3D tags
(``VERTEX_SE3:QUAT``, ``EDGE3``, …) are an error ("3D (SE3) graphs are not supported"), and so is
a file that mixes g2o and TORO tags (the message names a line of each).

The grammar the readers accept, the one C's ``strtod``/``strtol`` and g2o's and TORO's readers
agree on for finite decimal numbers:

* a file is ASCII text (UTF-8 is accepted in comments); a UTF-8 byte-order mark at its start is
  ignored; lines end with LF, CRLF or CR and are at most :data:`MAX_LINE_BYTES` long; fields are
  separated by ASCII blanks (space, tab, vertical tab, form feed) — a Unicode space or invisible
  character (no-break space, ideographic space, zero-width space, ...) is not a separator, and
  one in a tag or between two fields is a ParseError naming its line, column and name;
* a vertex id is ``[-+]?[0-9]+`` and must fit int64 (ids are read and written exactly, never
  through float64);
* any other number is ``[-+]?([0-9]+(\\.[0-9]*)?|\\.[0-9]+)([eE][-+]?[0-9]+)?``: not ``nan``,
  ``inf``, ``infinity``, hexadecimal floats, ``1_000`` or non-ASCII digits such as ``٣`` or ``３``
  (which Python's ``float`` accepts); it must be finite after rounding to float64 (``1e999`` is
  not), and an angle must satisfy ``|theta| <= 1e9`` (:data:`lagolib.se2.MAX_ANGLE`);
* an information matrix must pass :func:`lagolib.graph.first_bad_information` (positive definite,
  eigenvalues in [1e-100, 1e100], condition number at most 1e14) in the file's convention and,
  for TORO, again after the rotation into the g2o convention.

Nothing is lost on writing: ids are written as integers and floats with ``repr`` (shortest
round-trip) precision, so ``read_g2o(write_g2o(g))`` gives bit-identical arrays.  For TORO the
conversion to and from the g2o convention is two rotations, which round the information matrices
by a few units in the last place of their largest entry; the TORO writer runs the reader's own
check on what it is about to write and compares what would be read back with the graph (it
refuses, naming the edge and before writing anything, a matrix so ill-conditioned that the
rotation would make it unreadable or change it).  Readers and the TORO writer share that one
check (``_file_information``), so whatever a writer accepts its reader reads back.

Writers never leave a half-written file: each writes a hidden temporary file beside the
destination and moves it into place (:func:`lagolib.files.atomic_write`), so a write that fails
or is killed leaves the previous file as it was.
"""

from __future__ import annotations

import os
import re
import unicodedata
import warnings
from collections import Counter
from itertools import compress, cycle
from pathlib import Path

import numpy as np

from . import se2
from .checks import check_bool, check_choice
from .errors import (
    GraphError,
    GraphTypeError,
    OptionError,
    OptionTypeError,
    ParseError,
    SkippedLinesWarning,
)
from .files import atomic_write
from .graph import (
    _ANGLE_BOUND,
    PoseGraph,
    _numeric,
    check_poses,
    describe_bad_information,
    first_bad_information,
    first_duplicate,
    vertex_ids,
)

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
    "MAX_LINE_BYTES",
]

MAX_LINE_BYTES = 1 << 16
"""Longest line the readers accept (64 KiB; a g2o edge line is about 150 bytes)."""
_CHUNK = 1 << 20

# position of the six stored numbers in the 3x3 matrix, per format
_UPPER = {
    "g2o": ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)),  # I11 I12 I13 I22 I23 I33
    "toro": ((0, 0), (0, 1), (1, 1), (2, 2), (0, 2), (1, 2)),  # I11 I12 I22 I33 I13 I23
}
_TAGS = {"g2o": ("VERTEX_SE2", "EDGE_SE2"), "toro": ("VERTEX2", "EDGE2")}
_RECORD = {  # tag -> (format, is_edge)
    tag.encode(): (fmt, k == 1) for fmt, tags in _TAGS.items() for k, tag in enumerate(tags)
}
_EXTENSIONS = {".g2o": "g2o", ".graph": "toro"}
_3D_TAG = re.compile(rb"(?:VERTEX|EDGE|PARAMS)_SE3.*|VERTEX3|EDGE3|VERTEX_TRACKXYZ")

# the strict number grammar (module docstring)
_INT = rb"[-+]?[0-9]+"
_FLOAT = rb"[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"
_INT_RE = re.compile(_INT)
_FLOAT_RE = re.compile(_FLOAT)
_NON_FINITE_RE = re.compile(rb"[-+]?(?:nan|inf|infinity)", re.IGNORECASE)
_INT64_MIN, _INT64_MAX = int(np.iinfo(np.int64).min), int(np.iinfo(np.int64).max)

_VERTEX_FIELDS = ("id", "x", "y", "theta")
_EDGE_FIELDS = ("i", "j", "dx", "dy", "dtheta") + tuple(
    f"information entry {k}" for k in range(1, 7)
)


def _line_pattern(n_int, n_float):
    """Regex for ``n_int`` ids then ``n_float`` numbers, joined by single spaces."""
    return re.compile(b" ".join([_INT] * n_int + [_FLOAT] * n_float))


_VERTEX_RE = _line_pattern(1, 3)
_EDGE_RE = _line_pattern(2, 9)
_POSE_RE = {3: _line_pattern(0, 3), 4: _line_pattern(1, 3)}


def _text(tok):
    return tok.decode("utf-8", "backslashreplace")


def _check_path(path, where):
    if isinstance(path, bool) or not isinstance(path, str | bytes | os.PathLike):
        raise OptionTypeError(
            f"{where}: path must be a file name (str or os.PathLike); got {path!r} "
            f"({type(path).__name__})"
        )
    return path


# ----------------------------------------------------------------------------- lines and tokens
def _raw_lines(path):
    """Yield ``(line number, bytes)`` for each line, without its line break.

    Reads in binary, in blocks: a line break is LF, CRLF or CR; a line longer than
    :data:`MAX_LINE_BYTES` raises (so ``/dev/zero`` does not exhaust memory); a UTF-8 byte-order
    mark at the start is dropped; a UTF-16 file is named as such; a line that is not UTF-8 text
    or holds a NUL byte raises.
    """
    with open(path, "rb") as f:
        pending, lineno, first = b"", 0, True
        while True:
            chunk = f.read(_CHUNK)
            buf = pending + chunk
            if first and (len(buf) >= 3 or not chunk):
                first = False
                if buf.startswith((b"\xff\xfe", b"\xfe\xff")):
                    raise ParseError(
                        path,
                        1,
                        "the file is UTF-16 text (it starts with a UTF-16 byte-order mark); "
                        "save it as ASCII or UTF-8",
                    )
                if buf.startswith(b"\xef\xbb\xbf"):
                    buf = buf[3:]
            if first:  # fewer than 3 bytes so far: the byte-order mark may be incomplete
                lines, pending = [], buf
            elif not chunk or buf.endswith(b"\n"):
                lines, pending = buf.splitlines(), b""
            else:
                lines = buf.splitlines()
                # the last line is incomplete (or its CR may be half of a CRLF): keep it
                pending = lines.pop() + (b"\r" if buf.endswith(b"\r") else b"") if lines else b""
            clean = buf.isascii() and b"\x00" not in buf  # the common case: no per-line checks
            for line in lines:
                lineno += 1
                if len(line) > MAX_LINE_BYTES:
                    raise ParseError(path, lineno, _too_long())
                if not clean:
                    _check_text(line, path, lineno)
                yield lineno, line
            if len(pending) > MAX_LINE_BYTES:
                raise ParseError(path, lineno + 1, _too_long())
            if not chunk:
                return


def _too_long():
    return (
        f"line longer than {MAX_LINE_BYTES} bytes: not a pose-graph line (is this a binary "
        "file, or one without line breaks?)"
    )


def _check_text(line, path, lineno):
    """Raise ParseError for a line that is not UTF-8 text or holds a NUL byte."""
    if not line.isascii():
        try:
            line.decode("utf-8")
        except UnicodeDecodeError:
            raise ParseError(path, lineno, "not UTF-8 text: is this a pose-graph file?") from None
    if b"\x00" in line:
        raise ParseError(
            path, lineno, "NUL byte in the line: a binary file, not a pose-graph text file"
        )


def _data_lines(path):
    """Yield ``(line number, tokens)`` of every line that is not blank or a ``#`` comment.

    Tokens are ``bytes``, split at ASCII blanks only.  A line that is not UTF-8 text, or that
    holds a NUL byte, raises ParseError.
    """
    for lineno, line in _raw_lines(path):
        tok = line.split()
        if tok and not tok[0].startswith(b"#"):
            if not line.isascii():
                _check_separators(line, path, lineno)
            yield lineno, tok


def _char(c):
    """``U+00A0 (NO-BREAK SPACE)``: a character named so that an invisible one can be found."""
    return f"U+{ord(c):04X} ({unicodedata.name(c, 'unnamed')})"


def _first_non_ascii(token):
    """The first non-ASCII character of a token (bytes), described by :func:`_char`."""
    text = token.decode("utf-8", "replace")
    return next((_char(c) for c in text if ord(c) > 127), "a non-ASCII byte")


def _check_separators(line, path, lineno):
    """Raise ParseError for a Unicode space or invisible character used as a field separator.

    Fields are separated by ASCII blanks (as g2o's and TORO's C++ readers split them).  A
    no-break space, an ideographic space, a zero-width space, a byte-order mark or another
    invisible character in a line's first token or between two fields glues them into one
    token — a known tag becomes unknown, which ``ignore_unknown=True`` would then drop
    silently, or two columns become one — so it is reported, with its column.  One at the end of
    a later token (``1<NBSP> 2``) is left to the field's own message, which names it as well.
    """
    text = line.decode("utf-8", "replace")
    blank = " \t\n\r\x0b\x0c"
    start = len(text) - len(text.lstrip(blank))
    tag_end = next((k for k in range(start, len(text)) if text[k] in blank), len(text))
    for k, c in enumerate(text):
        if ord(c) <= 127 or unicodedata.category(c) not in ("Zs", "Zl", "Zp", "Cc", "Cf"):
            continue
        in_tag = k < tag_end  # the tag (or a pose list's first column) must be exact
        gluing = k + 1 < len(text) and text[k + 1] not in blank
        if in_tag or gluing:
            column = k + 1
            raise ParseError(
                path,
                lineno,
                f"column {column}: the character {_char(c)} is not a field separator; fields "
                "are separated by ASCII spaces or tabs — replace it with a space (or delete it)",
            )


def _bad_token(tok, field, path, lineno, integer):
    """The ParseError for a token that does not match the grammar (or None if it does)."""
    text = _text(tok)
    if integer:
        if _INT_RE.fullmatch(tok):
            return None
        return ParseError(
            path,
            lineno,
            f"{field} is not an integer vertex id: {text!r} (ids are decimal integers like 42)",
        )
    if _FLOAT_RE.fullmatch(tok):
        return None
    if _NON_FINITE_RE.fullmatch(tok):
        return ParseError(path, lineno, f"{field} is not finite: {text!r}")
    hint = "numbers are ASCII decimals like -1.5e-3"
    if not tok.isascii():
        hint += f"; it holds the non-ASCII character {_first_non_ascii(tok)}"
    return ParseError(path, lineno, f"{field} is not a number: {text!r} ({hint})")


def _check_fields(tok, pattern, fields, n_int, path, lineno):
    """Raise the ParseError for the first field of ``tok`` outside the grammar, if any."""
    if pattern.fullmatch(b" ".join(tok)):
        return
    for k, (t, field) in enumerate(zip(tok, fields)):
        exc = _bad_token(t, field, path, lineno, k < n_int)
        if exc is not None:
            raise exc
    raise ParseError(path, lineno, "malformed line")  # pragma: no cover (the fields all matched)


def _id(tok, field, path, lineno):
    """The int64 value of an id token that matched the grammar (exactly: never via float64)."""
    # int() refuses strings of more than 4300 digits (leading zeros included): convert only the
    # significant digits, and no more than 20 of them (int64 has 19)
    digits = tok.lstrip(b"+-").lstrip(b"0") or b"0"
    value = None if len(digits) > 20 else (-1 if tok[:1] == b"-" else 1) * int(digits)
    if value is None or not _INT64_MIN <= value <= _INT64_MAX:
        shown = _text(tok) if len(tok) <= 60 else f"{_text(tok[:30])}...({len(tok)} digits)"
        raise ParseError(
            path,
            lineno,
            f"{field} {shown} is outside the int64 range [{_INT64_MIN}, {_INT64_MAX}] of vertex "
            "ids",
        )
    return value


def _floats(values, width, lines, fields, path, angle_col, tokens):
    """The ``(n, width)`` array of ``values``; checks finiteness and the angle bound, naming the
    line and field (and the token as written) of the first failure."""
    arr = np.array(values, dtype=float).reshape(-1, width)
    bad = ~np.isfinite(arr)
    bad[:, angle_col] |= np.abs(arr[:, angle_col]) > se2.MAX_ANGLE
    rows = np.flatnonzero(bad.any(axis=1))
    if rows.size:
        k = rows[0]
        col = int(np.flatnonzero(bad[k])[0])
        tok = _text(tokens[k * width + col])
        if not np.isfinite(arr[k, col]):
            raise ParseError(path, lines[k], f"{fields[col]} is not finite: {tok!r}")
        raise ParseError(
            path,
            lines[k],
            f"{fields[col]} {tok} rad is too large: |angle| must be <= {_ANGLE_BOUND} "
            "(float64 cannot reduce larger angles consistently, see lagolib.se2); wrap it to "
            "(-pi, pi]",
        )
    return arr


# ----------------------------------------------------------------------------- graph files
def _not_planar(path, lineno, tag):
    return ParseError(
        path,
        lineno,
        f"{_text(tag)}: 3D (SE3) graphs are not supported; lagolib reads planar g2o "
        "(VERTEX_SE2/EDGE_SE2) and TORO (VERTEX2/EDGE2) files",
    )


def _scan(path, fmt, ignore_unknown):
    """Split a g2o/TORO file into vertex and edge records, keeping line numbers.

    Errors are reported for the first offending line of the file, whatever the kind of error.
    """
    first = None  # (tag, line) of the first vertex/edge line of the file's format
    vertices = _Records("vertex", 1, 3, path)
    edges = _Records("edge", 2, 9, path)
    skipped = Counter()

    def fail(exc):
        """Raise ``exc``, unless an earlier line already holds a bad number."""
        _convert_all(vertices, edges)
        raise exc

    for lineno, tok in _data_lines(path):
        tag = tok[0]
        record = _RECORD.get(tag)
        if record is None:
            if _3D_TAG.fullmatch(tag):
                fail(_not_planar(path, lineno, tag))
            if ignore_unknown:
                skipped[_text(tag)] += 1
                continue
            advice = (
                f"it holds the non-ASCII character {_first_non_ascii(tag)}: tags are ASCII"
                if not tag.isascii()
                else "pass ignore_unknown=True to skip such lines"
            )
            fail(
                ParseError(
                    path,
                    lineno,
                    f"unknown tag {_text(tag)!r} in a {fmt} file (expected "
                    f"{' or '.join(_TAGS[fmt])}); {advice}",
                )
            )
        rec_fmt, is_edge = record
        if rec_fmt != fmt:
            if first is None:
                fail(
                    ParseError(
                        path,
                        lineno,
                        f"unknown tag {_text(tag)!r} in a {fmt} file (expected "
                        f"{' or '.join(_TAGS[fmt])}); this looks like a {rec_fmt} file: use "
                        f"read_{rec_fmt} or read",
                    )
                )
            fail(
                ParseError(
                    path,
                    lineno,
                    f"the file mixes g2o and TORO tags: {first[0]} on line {first[1]} and "
                    f"{_text(tag)} on line {lineno}; a file must use one format (g2o: "
                    "VERTEX_SE2/EDGE_SE2, TORO: VERTEX2/EDGE2)",
                )
            )
        if first is None:
            first = (_text(tag), lineno)
        rec = edges if is_edge else vertices
        if len(tok) != rec.width + 1:
            what = "i j dx dy dtheta and 6 information entries" if is_edge else "id x y theta"
            fail(
                ParseError(
                    path,
                    lineno,
                    f"{_text(tag)} needs {rec.width} numbers ({what}); got {len(tok) - 1}",
                )
            )
        rec.tokens += tok[1:]
        rec.lines.append(lineno)
    if skipped:
        what = ", ".join(f"{count} {tag}" for tag, count in sorted(skipped.items()))
        warnings.warn(
            f"{path}: skipped {sum(skipped.values())} line(s) with tags lagolib does not read: {what}",
            SkippedLinesWarning,
            stacklevel=4,  # _scan <- _build <- read/read_g2o/read_toro <- the caller
        )
    (v_ids, v_vals), (e_ids, e_vals) = _convert_all(vertices, edges)
    return (v_ids[:, 0], v_vals, vertices.lines), (e_ids, e_vals, edges.lines)


class _Records:
    """The number tokens of one kind of line (``n_int`` ids, then ``n_float`` numbers each)."""

    def __init__(self, kind, n_int, n_float, path):
        self.fields = _EDGE_FIELDS if kind == "edge" else _VERTEX_FIELDS
        self.n_int, self.width, self.path = n_int, n_int + n_float, path
        self.tokens, self.lines = [], []

    def convert(self):
        """``(ids, values)`` as int64 ``(k, n_int)`` and float ``(k, n_float)`` arrays.

        Fast path: a token is in the grammar exactly when it uses only the characters
        ``0-9 + - . e E`` (``0-9 + -`` for an id) and Python's ``float`` (``int``) accepts it —
        without underscores, blanks, ``nan``/``inf`` or non-ASCII digits, the grammar of
        ``float``/``int`` is the file grammar.  When anything fails, the slow path checks line by
        line with the grammar's regexes, so the first bad line and field are named.
        """
        n_int, width, tokens = self.n_int, self.width, self.tokens
        is_id = [k < n_int for k in range(width)]
        id_tok = list(compress(tokens, cycle(is_id)))
        num_tok = list(compress(tokens, cycle([not i for i in is_id])))
        ok = not b"".join(id_tok).translate(None, b"0123456789+-") and not b"".join(
            num_tok
        ).translate(None, b"0123456789+-.eE")
        if ok and max(map(len, id_tok), default=0) <= 20:
            try:
                ids = np.array([int(t) for t in id_tok], dtype=np.int64)
                values = [float(t) for t in num_tok]
            except (ValueError, OverflowError):  # outside the grammar or int64: find where
                ok = False
        else:
            ok = False
        if not ok:
            ids = self._careful()
            values = [float(t) for t in num_tok]
        values = _floats(
            values, width - n_int, self.lines, self.fields[n_int:], self.path, 2, num_tok
        )
        return ids.reshape(-1, n_int), values

    def _careful(self):
        """Check line by line with the grammar's regexes; raise the ParseError for the first line
        with a token outside the grammar or an id outside int64, else return the ids."""
        n_int, width, path = self.n_int, self.width, self.path
        pattern = _EDGE_RE if width == 11 else _VERTEX_RE
        ids = []
        for k, lineno in enumerate(self.lines):
            row = self.tokens[k * width : (k + 1) * width]
            _check_fields(row, pattern, self.fields, n_int, path, lineno)
            ids += [_id(t, field, path, lineno) for t, field in zip(row[:n_int], self.fields)]
        return np.array(ids, dtype=np.int64)


def _convert_all(*records):
    """Convert each kind of record; if several hold errors, raise the one on the earliest line."""
    out, errors = [], []
    for rec in records:
        try:
            out.append(rec.convert())
        except ParseError as exc:
            errors.append(exc)
    if errors:
        raise min(errors, key=lambda exc: exc.line)
    return out


def toro_to_g2o_information(information, dtheta):
    """Convert TORO information matrices (frame ``i``) to the g2o frame: ``Gᵀ Ω G``.

    ``G = blockdiag(R(dtheta), 1)``: the g2o translational error is ``R(dtheta)ᵀ`` times the
    frame-``i`` error.  The conversion is :func:`lagolib.se2.information_from_frame_i`.

    Parameters
    ----------
    information : ndarray, shape (m, 3, 3)
        Frame ``i`` (as TORO files store it).
    dtheta : ndarray, shape (m,)
        Measured relative angles.

    Returns
    -------
    ndarray, shape (m, 3, 3)
        g2o frame.
    """
    return se2.information_from_frame_i(information, dtheta)


def g2o_to_toro_information(information, dtheta):
    """Inverse of :func:`toro_to_g2o_information`: ``G Ω Gᵀ`` (:func:`lagolib.se2.information_to_frame_i`)."""
    return se2.information_to_frame_i(information, dtheta)


def _matrices(upper, fmt):
    """Symmetric 3x3 matrices from the six stored numbers per edge, shape (m, 6) -> (m, 3, 3)."""
    info = np.zeros((len(upper), 3, 3))
    for col, (a, b) in enumerate(_UPPER[fmt]):
        info[:, a, b] = info[:, b, a] = upper[:, col]
    return info


def _file_information(upper, dtheta, fmt):
    """What the reader makes of the six stored numbers per edge: ``(index, reason)`` of the
    first unusable matrix (``index`` None when all are fine) and the g2o-convention matrices.

    The one validation of a file's information that readers and writers share: the readers
    build their graph from the matrices returned here (exactly symmetric, so that
    :class:`~lagolib.graph.PoseGraph` stores and checks these very bits), and the TORO writer
    calls it on what it is about to write, so that it never writes a file its reader rejects.
    (The g2o writer stores the graph's matrices exactly, and the graph checked them with the
    same :func:`~lagolib.graph.first_bad_information`.)
    """
    info = _matrices(upper, fmt)
    bad = first_bad_information(info)
    if bad is not None:
        return bad, describe_bad_information(info[bad]), info
    if fmt == "toro":
        info = toro_to_g2o_information(info, dtheta)
        # the rotation leaves the matrices asymmetric by rounding; PoseGraph would store (and
        # check) their symmetric part, so that is what is checked here, bit for bit
        info = 0.5 * (info + np.swapaxes(info, 1, 2))
        bad = first_bad_information(info)
        if bad is not None:
            return (
                bad,
                "after the rotation from TORO's frame i into the g2o convention, "
                + describe_bad_information(info[bad]),
                info,
            )
    return None, None, info


def _build(path, fmt, ignore_unknown):
    (v_ids, v_vals, v_lines), (e_ids, e_vals, e_lines) = _scan(path, fmt, ignore_unknown)
    vtag, etag = _TAGS[fmt]
    if not len(v_ids) and not len(e_ids):
        raise ParseError(
            path, None, f"no {vtag} or {etag} lines: the file is empty or not a {fmt} file"
        )

    first_line = {}
    for vid, lineno in zip(v_ids.tolist(), v_lines):
        if vid in first_line:
            raise ParseError(
                path,
                lineno,
                f"duplicate vertex id {vid} (first defined on line {first_line[vid]})",
            )
        first_line[vid] = lineno

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

    measurements = e_vals[:, :3]
    bad, reason, info = _file_information(e_vals[:, 3:], measurements[:, 2], fmt)
    if bad is not None:
        i, j = e_ids[bad].tolist()
        raise ParseError(path, e_lines[bad], f"edge {i} -> {j}: {reason}")

    try:
        if no_vertices:
            graph = PoseGraph(np.zeros((len(ids), 3)), edges, measurements, info, ids=ids)
            try:
                return graph.with_poses(graph.odometry_guess(start=np.zeros(3)))
            except GraphError as exc:  # a broken chain: say which file
                raise ParseError(path, None, f"file has no {vtag} lines and {exc}") from exc
        return PoseGraph(v_vals, edges, measurements, info, ids=ids)
    except ParseError:
        raise
    except GraphError as exc:  # the checks above should have caught it; still name the line
        line = (
            e_lines[exc.edge]
            if exc.edge is not None
            else v_lines[exc.vertex]
            if exc.vertex is not None and v_lines
            else None
        )
        raise ParseError(path, line, str(exc)) from exc


def read_g2o(path, *, ignore_unknown=False):
    """Read a planar g2o file (``VERTEX_SE2`` / ``EDGE_SE2`` lines).

    Files with edges but no vertices (SE-Sync's ``manhattan.g2o`` and ``CSAIL.g2o``) are accepted:
    the vertices are created from the ids the edges use, and their poses are composed along the
    odometric chain from the origin (:meth:`PoseGraph.odometry_guess`).

    Parameters
    ----------
    path : str or os.PathLike
    ignore_unknown : bool
        Skip lines with other tags (and warn how many) instead of raising.  3D tags and TORO tags
        are errors either way.

    Returns
    -------
    PoseGraph
        Vertices in file order; information matrices as stored (g2o convention).

    Raises
    ------
    ParseError
        ``file:line`` and the problem: unknown tag, 3D tag, TORO tags, wrong number of fields, a
        field outside the number grammar (module docstring) or not finite, an angle beyond
        ``1e9``, an id outside int64, duplicate vertex id, an edge to an unknown vertex, a
        self-loop, an unusable information matrix, a line longer than :data:`MAX_LINE_BYTES`,
        text that is not UTF-8, or a file with no vertex or edge.
    OptionTypeError
        If ``path`` is not a file name or ``ignore_unknown`` not a bool.
    """
    _check_path(path, "read_g2o")
    check_bool(ignore_unknown, "ignore_unknown", "read_g2o")
    return _build(path, "g2o", ignore_unknown)


def read_toro(path, *, ignore_unknown=False):
    """Read a TORO file (``VERTEX2`` / ``EDGE2`` lines, information order I11 I12 I22 I33 I13 I23).

    The information matrices are converted from TORO's frame-``i`` error to the g2o convention
    (module docstring).  Everything else is as :func:`read_g2o`.
    """
    _check_path(path, "read_toro")
    check_bool(ignore_unknown, "ignore_unknown", "read_toro")
    return _build(path, "toro", ignore_unknown)


def detect_format(path):
    """``"g2o"`` or ``"toro"``, from the first vertex or edge tag in the file.

    Raises
    ------
    ParseError
        If no line starts with ``VERTEX_SE2``, ``EDGE_SE2``, ``VERTEX2`` or ``EDGE2``, or a 3D tag
        comes first.
    """
    _check_path(path, "detect_format")
    for lineno, tok in _data_lines(path):
        record = _RECORD.get(tok[0])
        if record is not None:
            return record[0]
        if _3D_TAG.fullmatch(tok[0]):
            raise _not_planar(path, lineno, tok[0])
    raise ParseError(
        path,
        None,
        "no VERTEX_SE2/EDGE_SE2 (g2o) or VERTEX2/EDGE2 (TORO) line: not a pose-graph file",
    )


def read(path, *, ignore_unknown=False):
    """Read a g2o or TORO pose-graph file, the format given by its first vertex or edge tag.

    See :func:`read_g2o` and :func:`read_toro`; a file mixing the two formats' tags is an error.
    """
    _check_path(path, "read")
    check_bool(ignore_unknown, "ignore_unknown", "read")
    return _build(path, detect_format(path), ignore_unknown)


# ----------------------------------------------------------------------------- writing graphs
def write_g2o(graph, path):
    """Write ``graph`` as a g2o file; ids exactly, floats with ``repr`` (round-trip) precision."""
    _write(graph, path, "g2o", "write_g2o")


def write_toro(graph, path):
    """Write ``graph`` as a TORO file, converting the information back to TORO's convention.

    Raises
    ------
    GraphError
        If an information matrix is so ill-conditioned that after the rotation into TORO's frame
        (and back, on reading) it would no longer be a usable information matrix, or would read
        back further than 1e-13 of its largest entry from the graph's; the message names the
        edge, and nothing is written.  Write such a graph with :func:`write_g2o`, which stores
        it exactly.
    """
    _write(graph, path, "toro", "write_toro")


def write(graph, path, format=None):
    """Write ``graph`` to ``path`` as ``format`` (``"g2o"`` or ``"toro"``).

    Without ``format`` the extension decides: ``.g2o`` is g2o and ``.graph`` is TORO.

    Raises
    ------
    OptionError
        For another ``format``, or no format and an unknown extension.
    """
    _check_path(path, "write")
    if format is None:
        format = _EXTENSIONS.get(Path(os.fsdecode(path)).suffix.lower())
        if format is None:
            raise OptionError(
                f"write: cannot tell the format of {os.fsdecode(path)!r} from its extension; "
                "pass format='g2o' or format='toro'"
            )
    check_choice(format, "format", "write", tuple(_TAGS))
    _write(graph, path, format, "write")


def _fmt(values):
    return " ".join(map(repr, values))


def _write(graph, path, fmt, where):
    if not isinstance(graph, PoseGraph):
        raise GraphTypeError(
            f"{where}: graph must be a lagolib.PoseGraph; got {type(graph).__name__}"
        )
    _check_path(path, where)
    if graph.n == 0:
        raise GraphError(
            f"{where}: the graph has no vertices; there is nothing a reader could read"
        )
    vtag, etag = _TAGS[fmt]
    upper = _stored_information(graph, fmt, where)
    vertex_lines = (
        f"{vtag} {vid} {_fmt(p)}\n" for vid, p in zip(graph.ids.tolist(), graph.poses.tolist())
    )
    edge_vals = np.column_stack([graph.measurements, upper]).tolist()
    edge_ids = graph.ids[graph.edges].tolist()
    edge_lines = (f"{etag} {i} {j} {_fmt(v)}\n" for (i, j), v in zip(edge_ids, edge_vals))
    with atomic_write(path, "w", encoding="ascii", newline="\n") as f:
        f.writelines(vertex_lines)
        f.writelines(edge_lines)


#: How far (relative to its largest entry) a matrix read back from a TORO file may be from the
#: graph's: the two rotations (writer and reader) round by a few units in the last place.
_TORO_RTOL = 1e-13


def _stored_information(graph, fmt, where):
    """The six numbers per edge the writer stores, shape (m, 6), checked to read back.

    g2o stores the graph's (exactly symmetric) matrices exactly, and the graph checked them with
    the reader's check.  TORO stores them rotated into frame ``i``; the reader's own
    :func:`_file_information` is run on what will be written, and what it reads back must
    equal the graph's matrix to :data:`_TORO_RTOL` of its largest entry — otherwise the graph is
    refused (GraphError naming the edge) before anything is written.
    """
    info = graph.information
    if fmt == "g2o" or not graph.m:
        return np.stack([info[:, a, b] for a, b in _UPPER[fmt]], axis=-1)
    dtheta = graph.measurements[:, 2]
    toro = g2o_to_toro_information(info, dtheta)
    toro = 0.5 * (toro + np.swapaxes(toro, 1, 2))
    upper = np.stack([toro[:, a, b] for a, b in _UPPER[fmt]], axis=-1)
    bad, reason, back = _file_information(upper, dtheta, fmt)
    if bad is None:
        scale = np.max(np.abs(info), axis=(1, 2))
        drift = np.max(np.abs(back - info), axis=(1, 2))
        far = np.flatnonzero(~(drift <= _TORO_RTOL * scale))
        if far.size:
            bad = int(far[0])
            reason = (
                f"it would read back as {back[bad].tolist()}, {drift[bad] / scale[bad]:.2g} of "
                "its largest entry away"
            )
    if bad is not None:
        i, j = graph.ids[graph.edges[bad]].tolist()
        raise GraphError(
            f"{where}: edge {bad} (vertex ids {i} -> {j}) cannot be written in TORO's "
            f"convention: {reason}.  (Its g2o-convention matrix is "
            f"{info[bad].tolist()}.)  Nothing was written.  Write the graph as g2o (write_g2o), "
            "which stores information exactly, or make the matrix better conditioned",
            edge=int(bad),
        )
    return upper


# ----------------------------------------------------------------------------- pose lists
def read_poses(path):
    """Read a plain list of poses (ground-truth files): ``x y theta`` or ``id x y theta`` per line.

    With three columns the id is the line's position among the data lines, from 0 (as in
    Olson's ``manhattanOlson3500_nodes_groundTruth.dat``); with four the first column is the id
    (as in ``ring/groundTruth/poses.txt``).  The grammar is the one of :func:`read_g2o` (module
    docstring).

    Returns
    -------
    ids : ndarray of int64, shape (n,)
    poses : ndarray, shape (n, 3)

    Raises
    ------
    ParseError
        For a line with another number of columns than the first, a field outside the grammar or
        not finite, an angle beyond ``1e9``, an id outside int64, or a duplicate id (the message
        names both lines).
    """
    _check_path(path, "read_poses")
    ids, vals, lines, width = [], [], [], None
    seen = {}
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
        fields = _VERTEX_FIELDS[4 - width :]
        _check_fields(tok, _POSE_RE[width], fields, width - 3, path, lineno)
        vid = _id(tok[0], "id", path, lineno) if width == 4 else len(lines)
        if vid in seen:
            raise ParseError(
                path,
                lineno,
                f"duplicate vertex id {vid}: it appears on line {seen[vid]} and on line {lineno}",
            )
        seen[vid] = lineno
        ids.append(vid)
        vals += tok[width - 3 :]
        lines.append(lineno)
    if not lines:
        raise ParseError(path, None, "no poses in the file")
    poses = _floats([float(t) for t in vals], 3, lines, _VERTEX_FIELDS[1:], path, 2, vals)
    return np.array(ids, dtype=np.int64), poses


def write_poses(path, poses, ids=None):
    """Write poses as ``id x y theta`` lines (readable by :func:`read_poses`), ``repr`` precision.

    Parameters
    ----------
    path : str or os.PathLike
    poses : array_like, shape (n, 3)
        Finite poses with ``|theta| <= 1e9`` (:data:`lagolib.se2.MAX_ANGLE`).
    ids : array_like of int, shape (n,), optional
        Unique int64 vertex ids, one per pose (default ``0 .. n-1``); written exactly.

    Raises
    ------
    GraphError
        For poses of another shape, no poses, ``ids`` of another length than ``poses`` or not
        unique integers in int64, or a pose that is not finite or has an absurd angle — anything
        :func:`read_poses` would not read back.
    GraphTypeError
        For complex or non-numeric arrays.
    """
    _check_path(path, "write_poses")
    poses = _numeric(poses, "write_poses: poses", float)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise GraphError(f"write_poses: poses must have shape (n, 3); got {poses.shape}")
    n = len(poses)
    if n == 0:
        raise GraphError("write_poses: no poses to write; read_poses could not read the file")
    if ids is None:
        ids = np.arange(n, dtype=np.int64)
    else:
        if np.ndim(ids) == 1 and len(ids) != n:
            raise GraphError(
                f"write_poses: ids has {len(ids)} entries but poses has {n} rows; give one id "
                "per pose"
            )
        ids = vertex_ids(ids, n, "write_poses: ids")
    twice = first_duplicate(ids)
    if twice is not None:
        a, b = twice
        raise GraphError(
            f"write_poses: vertex id {ids[a]} is given twice (rows {a} and {b}); ids must be "
            "unique",
            vertex=b,
        )
    check_poses(poses, ids, "write_poses: pose")
    with atomic_write(path, "w", encoding="ascii", newline="\n") as f:
        f.writelines(f"{i} {_fmt(p)}\n" for i, p in zip(ids.tolist(), poses.tolist()))
