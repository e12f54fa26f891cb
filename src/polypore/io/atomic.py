"""Atomic file writes: a file either appears complete under its name or not at all.

Data go to a temporary file in the target's directory (same file system, so the
final :func:`os.replace` is an atomic rename); the temporary is removed if
anything fails, so an interrupted run never leaves a truncated output behind.
"""

from __future__ import annotations

import os
import uuid
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

__all__ = ["atomic_path", "atomic_write_bytes", "atomic_write_text"]


def _temp_name(path: Path) -> Path:
    # hidden, unique per process and call: concurrent writers never share a temporary;
    # not created here so that the writer's open() applies the usual umask permissions
    return path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:12]}.tmp")


def _fsync(file: Path) -> None:
    # data on disk before the rename: after a power loss the name never points at
    # an empty or partial file (rename is journaled, buffered data are not)
    fd = os.open(file, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextmanager
def atomic_path(path) -> Iterator[Path]:
    """Yield a temporary path to write; rename it onto ``path`` only if the block succeeds.

    Parent directories of ``path`` are created. On success the temporary is synced
    to disk, then renamed. If the block raises, writes nothing, or the rename fails,
    the temporary file is removed and ``path`` is left untouched.

    Parameters
    ----------
    path : str or os.PathLike
        Final file name.

    Yields
    ------
    pathlib.Path
        A not yet existing file name in the same directory as ``path``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _temp_name(path)
    try:
        yield tmp
        if not tmp.exists():
            raise FileNotFoundError(f"atomic_path: nothing was written to the temporary file for {path}")
        _fsync(tmp)
        os.replace(tmp, path)
    except BaseException:
        # BaseException too: a KeyboardInterrupt mid-write must not leave debris
        try:
            tmp.unlink()
        except FileNotFoundError:
            pass
        raise


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; return the path."""
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
    return path


def atomic_write_text(path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically; return the path."""
    return atomic_write_bytes(path, text.encode(encoding))
