"""Atomic file writes and run directories: outputs appear complete or not at all.

Files: data go to a temporary file in the target's directory (same file system, so the
final :func:`os.replace` is an atomic rename); the temporary is removed if anything
fails, so an interrupted run never leaves a truncated output behind.

Run directories (:func:`run_directory`), one rule: a finished run leaves a complete
result; anything else (an error, SIGINT, SIGTERM) leaves only ``failed.json`` with the
reason. Results are written into a hidden staging folder next to the output folder,
``.partial-<name>@<host>.<pid>.<random>``, and moved in when the run has succeeded; the
owner's host and process id in the name let a later run remove the staging folders of
runs that were killed outright (SIGKILL, power loss).
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import uuid
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from ..core.errors import InputError

__all__ = ["atomic_path", "atomic_write_bytes", "atomic_write_text", "run_directory", "is_staging",
           "remove_stale_stages"]

STAGE_PREFIX = ".partial-"
# files whose presence says "this run finished": moved in last, removed first
COMPLETE_MARKERS = ("summary.json", "mesh.json", "convergence.json")
# any of these says "this folder holds a polypore result", which --force may replace
RESULT_MARKERS = COMPLETE_MARKERS + ("failed.json", "case.toml")
_ACTIVE: set[Path] = set()


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


# -- run directories ----------------------------------------------------------------------------
def _host() -> str:
    # '@' and the last two '.' separate the fields of a stage name; keep them out of the host
    return socket.gethostname().replace("@", "_")[:80] or "localhost"


def _stage_owner(name: str) -> tuple[str, int] | None:
    """(host, pid) encoded in a staging folder's name, None for names this module did not make."""
    if not name.startswith(STAGE_PREFIX) or "@" not in name:
        return None
    host, _, rest = name.rpartition("@")[2].rpartition(".")[0].rpartition(".")
    try:
        return host, int(rest)
    except ValueError:
        return None


def _alive(pid: int) -> bool:
    if os.name == "nt":  # os.kill(pid, 0) would terminate the process there: never judge it dead
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def remove_stale_stages(parent) -> list[Path]:
    """Remove staging folders in ``parent`` left by runs of this host that no longer exist.

    Returns
    -------
    list of pathlib.Path
        The folders removed. Folders of live processes and of other hosts (a shared file
        system) are kept: their owner may still be running.
    """
    removed = []
    try:
        entries = list(Path(parent).iterdir())
    except OSError:
        return removed
    host = _host()
    for entry in entries:
        owner = _stage_owner(entry.name)
        if owner and owner[0] == host and owner[1] != os.getpid() and not _alive(owner[1]) and entry.is_dir():
            shutil.rmtree(entry, ignore_errors=True)
            removed.append(entry)
    return removed


def is_staging(path) -> bool:
    """True if ``path`` is the staging folder of a :func:`run_directory` open in this process."""
    return Path(os.path.abspath(path)) in _ACTIVE


def _leftovers(out: Path) -> list[Path]:
    # failed.json and old staging folders are what a failed or killed run leaves: not worth keeping
    return [p for p in out.iterdir() if p.name != "failed.json" and not p.name.startswith(STAGE_PREFIX)]


def check_output_directory(out, force: bool, option: str = "--out") -> None:
    """Raise InputError (naming ``option``) if ``out`` may not receive a run's results.

    Allowed: a missing or empty folder, one holding only ``failed.json`` of an earlier failed
    run, and with ``force`` a folder holding a previous polypore result (``summary.json``,
    ``failed.json``, ``case.toml``, ``mesh.json`` or ``convergence.json``); never a file, nor
    with ``force`` a folder of other files, which would be deleted.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(option, f"{str(out)!r} exists and is not a directory")
    if not out.is_dir() or not _leftovers(out):
        return
    if not force:
        raise InputError(option, f"directory {str(out)!r} is not empty; choose another {option} or pass --force "
                         "(which replaces a previous polypore result)")
    if not any((out / m).exists() for m in RESULT_MARKERS):
        raise InputError(option, f"directory {str(out)!r} does not hold a polypore result (none of "
                         f"{', '.join(RESULT_MARKERS)}), and --force would delete its files; choose another "
                         f"{option} or empty it yourself")


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


def _clear(out: Path) -> None:
    # completion markers first: if this is cut short, what is left does not look complete
    entries = sorted(out.iterdir(), key=lambda p: p.name not in COMPLETE_MARKERS)
    for p in entries:
        _remove(p)


def _sync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def failure_record(exc: BaseException) -> dict:
    """Content of failed.json for the exception that ended a run: a reason that is never empty."""
    if isinstance(exc, KeyboardInterrupt):
        return {"error": "interrupted by the user (SIGINT)", "type": "KeyboardInterrupt", "signal": "SIGINT"}
    record = {"error": str(exc) or type(exc).__name__, "type": type(exc).__name__}
    for key in ("signal", "field"):
        if getattr(exc, key, None):
            record[key] = getattr(exc, key)
    return record


@contextmanager
def run_directory(out, *, force: bool = False, option: str = "--out") -> Iterator[Path]:
    """Yield a staging folder for a run's files; on success they replace ``out``'s content.

    ``out`` is checked with :func:`check_output_directory` first (an InputError leaves it
    untouched). If the block raises anything, KeyboardInterrupt included, ``out`` is left
    holding only ``failed.json`` with the reason and the exception propagates. Either way the
    staging folder is removed, and so are the stale ones of killed runs in ``out``'s parent.

    Parameters
    ----------
    out : str or os.PathLike
        The output folder; created if missing.
    force : bool
        Replace a previous polypore result in ``out`` (``--force``).
    option : str
        Name of the option that gave ``out``, for error messages.
    """
    check_output_directory(out, force, option)
    out = Path(os.path.abspath(out))
    if out.parent == out:
        raise InputError(option, f"{str(out)!r} is a file system root; choose a folder inside it")
    stage = None
    # everything from here on sits inside the try: a signal (SIGTERM/SIGINT raise in the main
    # thread) that lands between creating the stage and entering a later try would otherwise
    # escape without failed.json and leave the stage behind
    try:
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            remove_stale_stages(out.parent)
            # out's name only helps a reader: cut, with the host's, to keep within a file name's 255 bytes
            stage = out.parent / f"{STAGE_PREFIX}{out.name[:80]}@{_host()}.{os.getpid()}.{uuid.uuid4().hex[:12]}"
            _ACTIVE.add(stage)
            stage.mkdir()
            yield stage
        except BaseException as exc:
            try:
                out.mkdir(parents=True, exist_ok=True)
                _clear(out)
                atomic_write_text(out / "failed.json", json.dumps(failure_record(exc), indent=2))
                exc.failed_json = out / "failed.json"  # for the command line's message
            except OSError:
                pass  # the run's own error is the one to report
            raise
        out.mkdir(parents=True, exist_ok=True)
        _clear(out)
        # shutil.move: a rename, or a copy when out is a mount point on another file system
        names = sorted((p.name for p in stage.iterdir()), key=lambda n: n in COMPLETE_MARKERS)
        for name in names:
            shutil.move(str(stage / name), str(out / name))
        _sync_dir(out)
    finally:
        if stage is not None:
            _ACTIVE.discard(stage)
            shutil.rmtree(stage, ignore_errors=True)
