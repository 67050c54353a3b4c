"""Tables the chapters print: HTML in JupyterLab and on the book's site, aligned text elsewhere.

A printed table of many columns wraps its lines in a 1280-pixel window and becomes unreadable;
:class:`Table` renders as an HTML table instead (numbers right-aligned and never broken, the
table scrolling sideways inside its own box when it is wider than the page), and as aligned
plain text where there is no HTML (a terminal, a doctest, ``print``).

>>> t = Table([["odometric", 5, 1729.0], ["default", 14, 881.25]],
...           columns=["tree", "wrong k", "χ²"], formats={"χ²": "{:.1f}"})
>>> print(t)
tree       wrong k      χ²
odometric        5  1729.0
default         14   881.2
>>> "<table" in t._repr_html_() and "<th>wrong k</th>" in t._repr_html_()
True
"""

from __future__ import annotations

import html
import numbers

from .errors import OptionError

__all__ = ["Table"]


def _is_number(value) -> bool:
    return isinstance(value, numbers.Number) and not isinstance(value, bool)


class Table:
    """Rows of values under named columns; shown as HTML in Jupyter, as text by ``print``.

    Parameters
    ----------
    rows : sequence of sequences
        One sequence per row, as many values as there are columns.
    columns : sequence of str
        The column headings.
    caption : str, optional
        A line above the table (HTML ``<caption>``; the first line of the text form).
    formats : dict, optional
        ``{column: format string}``, e.g. ``{"χ²": "{:.1f}"}``; other numbers are shown with
        ``"{:g}"``-like defaults (integers as they are), text as it is.

    Raises
    ------
    OptionError
        A row whose length differs from the number of columns (naming the row), or a format for a
        column that does not exist.
    """

    def __init__(self, rows, columns, *, caption: str | None = None, formats=None):
        self.columns = [str(c) for c in columns]
        self.rows = [list(r) for r in rows]
        self.caption = caption
        self.formats = dict(formats or {})
        for k, row in enumerate(self.rows):
            if len(row) != len(self.columns):
                raise OptionError(
                    f"Table: row {k} has {len(row)} values for {len(self.columns)} columns "
                    f"({self.columns}); give one value per column"
                )
        unknown = sorted(set(self.formats) - set(self.columns))
        if unknown:
            raise OptionError(
                f"Table: formats names columns {unknown} that are not in {self.columns}"
            )

    def _cell(self, column: str, value) -> str:
        fmt = self.formats.get(column)
        if value is None:
            return ""
        if fmt is not None and _is_number(value):
            return fmt.format(value)
        if isinstance(value, numbers.Integral) and not isinstance(value, bool):
            return str(int(value))
        if _is_number(value):
            return f"{float(value):.6g}"
        return str(value)

    def _numeric(self, j: int) -> bool:
        values = [r[j] for r in self.rows if r[j] is not None]
        return bool(values) and all(_is_number(v) for v in values)

    def __str__(self) -> str:
        text = [[self._cell(c, r[j]) for j, c in enumerate(self.columns)] for r in self.rows]
        widths = [max([len(c)] + [len(t[j]) for t in text]) for j, c in enumerate(self.columns)]
        right = [self._numeric(j) for j in range(len(self.columns))]

        def line(cells):
            out = [
                (cell.rjust(w) if r else cell.ljust(w)) for cell, w, r in zip(cells, widths, right)
            ]
            return "  ".join(out).rstrip()

        lines = ([self.caption] if self.caption else []) + [line(self.columns)]
        lines += [line(t) for t in text]
        return "\n".join(lines)

    __repr__ = __str__

    def _repr_html_(self) -> str:
        right = [self._numeric(j) for j in range(len(self.columns))]
        head = "".join(f"<th>{html.escape(c)}</th>" for c in self.columns)
        body = []
        for r in self.rows:
            cells = []
            for j, c in enumerate(self.columns):
                style = ' style="text-align:right;white-space:nowrap"' if right[j] else ""
                cells.append(f"<td{style}>{html.escape(self._cell(c, r[j]))}</td>")
            body.append("<tr>" + "".join(cells) + "</tr>")
        caption = f"<caption>{html.escape(self.caption)}</caption>" if self.caption else ""
        return (
            '<div class="lagolib-table" style="overflow-x:auto;max-width:100%">'
            '<table style="border-collapse:collapse;font-size:90%">'
            f"{caption}<thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table></div>"
        )
