"""Writing files so that nothing already there is lost: :func:`atomic_write`.

Every file lagolib writes (g2o and TORO graphs, pose lists, figures, the book's student copies)
goes through :func:`atomic_write`: the content is written to a hidden temporary file in the same
folder (``.NAME.XXXXXXXX.tmp``), flushed to disk, and moved over ``NAME`` with :func:`os.replace`,
which is atomic on POSIX and Windows.  A process killed at any moment of the write (Ctrl-C, the
OOM killer, ``kill -9``, a full disk) therefore leaves either the previous ``NAME`` or the new
one — never a truncated file — and an exception raised while writing removes the temporary file
(only a process killed outright can leave one behind; its name says what it was).

The destination keeps its permission bits (and, where the operating system allows, its owner);
a new file gets the permissions :func:`open` would give it (``0o666`` less the umask).  A symbolic
link is followed (its target is replaced, the link stays), as :func:`open` would.  Where an atomic
replace makes no sense, the file is written in place as :func:`open` would: a destination that
exists and is not a regular file (``/dev/null``, a named pipe).
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat

__all__ = ["atomic_write", "temporary_name"]

#: Characters of the destination's name kept in the temporary file's name (NAME_MAX is 255).
_NAME_KEPT = 200


def temporary_name(path):
    """A fresh temporary file name beside ``path``: ``.NAME.XXXXXXXX.tmp`` in the same folder.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    str
        The name (not created); ``XXXXXXXX`` is 8 random hexadecimal digits.
    """
    path = os.fsdecode(path)
    folder, name = os.path.split(path)
    return os.path.join(folder, f".{name[:_NAME_KEPT]}.{secrets.token_hex(4)}.tmp")


def _target(path):
    """The file to replace: ``path``, or the file a symbolic link at ``path`` points to."""
    path = os.fsdecode(os.fspath(path))
    return os.path.realpath(path) if os.path.islink(path) else path


def _create_beside(target, mode_bits):
    """Create and open (write-only, exclusively) a fresh temporary file beside ``target``."""
    for _ in range(100):
        tmp = temporary_name(target)
        try:
            return tmp, os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, mode_bits)
        except FileExistsError:  # pragma: no cover (2^32 names)
            continue
    raise FileExistsError(f"could not create a temporary file beside {target}")  # pragma: no cover


def _same_owner(tmp, st):
    """Give ``tmp`` the owner and group of the file it replaces, where that is allowed."""
    if not hasattr(os, "chown"):  # pragma: no cover (Windows)
        return
    if (st.st_uid, st.st_gid) != (os.getuid(), os.getgid()):
        with contextlib.suppress(OSError):
            os.chown(tmp, st.st_uid, st.st_gid)


def _fsync_folder(folder):
    """Make the rename durable (POSIX); a folder that cannot be opened or synced is left alone."""
    if os.name != "posix":  # pragma: no cover
        return
    with contextlib.suppress(OSError):
        fd = os.open(folder or ".", os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@contextlib.contextmanager
def atomic_write(path, mode="w", *, encoding=None, newline=None):
    """Open ``path`` for writing so that it is replaced whole or not at all.

    Yields a file object on a hidden temporary file in ``path``'s folder; when the ``with`` block
    ends normally the file is flushed, ``fsync``-ed and moved over ``path`` (:func:`os.replace`).
    When the block raises (any exception, ``KeyboardInterrupt`` included), the temporary file is
    removed, ``path`` is untouched and the exception propagates.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.  Its folder must exist.
    mode : {"w", "wb", "wt"}
        Text or binary, as for :func:`open`.
    encoding, newline : str, optional
        As for :func:`open` (text mode only).

    Yields
    ------
    file object

    Raises
    ------
    IsADirectoryError, FileNotFoundError, PermissionError
        As :func:`open` would, before anything is written: ``path`` is a folder, its folder does
        not exist, or ``path`` exists and is read-only (it is not replaced) or its folder is not
        writable.
    ValueError
        For another ``mode``.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = pathlib.Path(folder) / "out.txt"
    ...     with atomic_write(path, encoding="ascii") as f:
    ...         _ = f.write("whole or nothing")
    ...     print(path.read_text(), sorted(p.name for p in path.parent.iterdir()))
    whole or nothing ['out.txt']
    """
    if mode not in ("w", "wt", "wb"):
        raise ValueError(f"atomic_write: mode must be 'w', 'wt' or 'wb'; got {mode!r}")
    target = _target(path)
    if not target:
        raise FileNotFoundError(2, "No such file or directory", target)
    try:
        st = os.stat(target)
    except FileNotFoundError:
        st = None
    if st is not None and not stat.S_ISREG(st.st_mode):
        if stat.S_ISDIR(st.st_mode):
            raise IsADirectoryError(21, "Is a directory", target)
        # a device or a pipe: nothing to replace, write in place as open() would
        with open(target, mode, encoding=encoding, newline=newline) as f:
            yield f
        return
    if st is not None and not os.access(target, os.W_OK):
        # open(path, "w") refuses a read-only file: so does an atomic write (it could replace it)
        raise PermissionError(13, "Permission denied", target)
    mode_bits = stat.S_IMODE(st.st_mode) if st is not None else 0o666
    try:
        tmp, fd = _create_beside(target, mode_bits)
    except FileNotFoundError as exc:  # as open() says it: name the file, not the temporary one
        raise FileNotFoundError(exc.errno, exc.strerror, target) from None
    except PermissionError as exc:
        folder = os.path.dirname(target) or "."
        raise PermissionError(
            exc.errno,
            f"cannot create a temporary file in the folder {folder} (lagolib writes {target} "
            "there first and then moves it into place, so that a failed write loses nothing)",
            target,
        ) from exc
    try:
        if st is not None:
            os.chmod(tmp, mode_bits)  # exactly the destination's bits, whatever the umask
            _same_owner(tmp, st)
        with open(fd, mode, encoding=encoding, newline=newline, closefd=True) as f:
            fd = None  # the file object owns it now
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            if fd is not None:
                os.close(fd)
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    _fsync_folder(os.path.dirname(target))
