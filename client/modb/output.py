"""Where modb's output goes: open_output, through which every file modb writes is opened (BVH,
glTF, reports, downloads), and output_target, which tells beforehand how (and whether) a path can be
written."""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import stat
import sys
from collections.abc import Iterator
from typing import IO


# Where a name leads into /proc (/dev/stdout, /dev/fd/N, /proc/self/fd/N), its "symlinks" are open
# descriptors rather than names: such a path is opened as it is, never replaced.
_DESCRIPTOR_FOLDERS = ("/proc/", "/dev/fd/")


def _follow(path: str) -> str:
    """The name writing to `path` lands on: its symlinks followed, each from its own folder (a
    dangling one to the name it gives); a path into /proc as it is."""
    where = os.path.abspath(path)
    for _ in range(40):  # the kernel's limit on symlinks in one lookup
        where = os.path.join(os.path.realpath(os.path.dirname(where)), os.path.basename(where))
        if where.startswith(_DESCRIPTOR_FOLDERS) or not os.path.islink(where):
            return where
        where = os.path.join(os.path.dirname(where), os.readlink(where))
    raise OSError(errno.ELOOP, os.strerror(errno.ELOOP), path)


def output_target(
    path: str | os.PathLike, allow_stdout: bool = False, replace_symlink: bool = False
) -> tuple[str, str, os.stat_result | None]:
    """How open_output writes `path`, without writing anything: ("stdout", "-", None),
    ("replace", file, its stat or None when absent) or ("direct", node, its stat).

    Raises OSError for what cannot be written: a directory, a folder that does not exist.
    """
    text = os.fspath(path)
    if allow_stdout and text == "-":
        return "stdout", text, None
    if not text:
        raise FileNotFoundError(errno.ENOENT, "an empty file name", text)
    if replace_symlink and os.path.islink(text):
        return "replace", os.path.abspath(text), os.lstat(text)
    where = _follow(text)
    try:
        st = os.stat(where)
    except FileNotFoundError:
        folder = os.path.dirname(where)
        if not os.path.isdir(folder):
            raise FileNotFoundError(errno.ENOENT, "its folder does not exist", folder) from None
        return "replace", where, None
    if stat.S_ISDIR(st.st_mode):
        raise IsADirectoryError(errno.EISDIR, "is a directory, not a file", text)
    if os.path.islink(text):  # written in place: the target's own entry (and hard links) stay
        return "direct", where, st
    if stat.S_ISREG(st.st_mode) and not where.startswith(_DESCRIPTOR_FOLDERS):
        return "replace", where, st
    return "direct", where, st  # a character or block device, a FIFO, an open descriptor


@contextlib.contextmanager
def open_output(
    path: str | os.PathLike,
    mode: str = "w",
    *,
    allow_stdout: bool = False,
    replace_symlink: bool = False,
) -> Iterator[IO]:
    """The one way modb opens a file to write (BVH, reports, downloads): as the target's kind asks.

    - a regular file, or none yet: written under a temporary name in the same folder, then renamed
      over it, so that the name never holds half a file (a failed write leaves the old one); the
      old file's permissions are kept.
    - a character or block device, a FIFO, /dev/stdout and the like: written straight into, never
      replaced (replacing /dev/null with a regular file would break the system).
    - a symlink: followed, and what it points at written in place (the link, the target's own
      directory entry and any hard links to it stay), unless `replace_symlink`, which replaces the
      link itself.
    - a directory: IsADirectoryError.
    - `-` with `allow_stdout`: standard output.

    `mode` is "w" (text, UTF-8) or "wb".
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"open_output writes in mode 'w' or 'wb', not {mode!r}")
    binary = mode == "wb"
    kind, where, st = output_target(path, allow_stdout, replace_symlink)
    if kind == "stdout":
        out = sys.stdout.buffer if binary else sys.stdout
        yield out
        out.flush()
        return
    encoding = None if binary else "utf-8"
    if kind == "direct":
        with open(where, mode, encoding=encoding) as f:
            yield f
        return
    folder, name = os.path.split(where)
    while True:
        # within NAME_MAX (255) for any name
        tmp = os.path.join(folder, f".{name[:200]}.{secrets.token_hex(4)}.partial")
        try:  # O_EXCL: a name nobody else holds, not even as a symlink
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
            break
        except FileExistsError:
            continue
    try:
        f = open(fd, mode, encoding=encoding)
    except BaseException:
        os.close(fd)
        os.unlink(tmp)
        raise
    try:
        if st is not None and not stat.S_ISLNK(st.st_mode):
            os.fchmod(fd, stat.S_IMODE(st.st_mode))
            if (st.st_uid, st.st_gid) != (os.geteuid(), os.getegid()):
                with contextlib.suppress(OSError):  # only root can give a file away
                    os.fchown(fd, st.st_uid, st.st_gid)
        with f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, where)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
