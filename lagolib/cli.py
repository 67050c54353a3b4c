"""The ``lagolib`` command.

``lagolib book student-copies OUTDIR [--book BOOKDIR]`` — see :mod:`lagolib.book`.
"""

from __future__ import annotations

import sys

from . import book

COMMANDS = {"book": book.main}
USAGE = "usage: lagolib {book} ...\n  book    the book's tools (lagolib book --help)"


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(USAGE)
        return 0 if argv else 2
    command = COMMANDS.get(argv[0])
    if command is None:
        print(f"lagolib: unknown command {argv[0]!r}\n{USAGE}", file=sys.stderr)
        return 2
    return command(argv[1:])


if __name__ == "__main__":
    sys.exit(main())
