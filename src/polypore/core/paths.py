"""What is wrong with a path given as an input file, for error messages."""

from __future__ import annotations

import errno
import stat
from pathlib import Path

__all__ = ["not_a_file"]


def not_a_file(path) -> str | None:
    """Why ``path`` cannot be read as an input file ("does not exist", "is a folder, not a file",
    "is not a regular file (...)", "cannot be read: ..."), or None for a regular file.

    A FIFO or a device is refused by name: reading one would block forever (a FIFO nobody writes
    to) or never end (/dev/zero).
    """
    try:
        mode = Path(path).stat().st_mode
    except OSError as exc:
        if exc.errno in (errno.ENOENT, errno.ENOTDIR):
            return "does not exist"
        return f"cannot be read: {exc.strerror or exc}"      # a symbolic-link loop, a name too long
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "is a folder, not a file"
    return "is not a regular file (a pipe, a socket or a device)"
