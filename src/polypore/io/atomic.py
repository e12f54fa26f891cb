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

Every run folder holds polypore's marker ``.polypore-run.json`` (version, status, the list of
every entry the run wrote) and the lock file ``.polypore-lock`` that a run holds for its whole
duration. A later run (``--force``, or after a failure) deletes only the entries a marker lists:
no command deletes a file it did not write.
"""

from __future__ import annotations

import errno
import json
import logging
import os
import shutil
import socket
import time
import uuid
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from .. import __version__
from ..core.errors import InputError, RunError

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: run folders are not locked
    fcntl = None

__all__ = ["atomic_path", "atomic_write_bytes", "atomic_write_text", "run_directory", "is_staging",
           "remove_stale_stages", "check_output_directory", "read_marker", "MARKER", "LOCK"]

STAGE_PREFIX = ".partial-"
# files whose presence says "this run finished": moved in last, removed first
COMPLETE_MARKERS = ("summary.json", "mesh.json", "convergence.json")
# written by polypore into every run folder: what the run wrote (all that --force may delete),
# and whether it finished or failed
MARKER = ".polypore-run.json"
# locked by the run that owns the folder (see _locked); never deleted
LOCK = ".polypore-lock"
log = logging.getLogger("polypore")
# errors of writing, not of the run: a full disk, a quota, a file system remounted read-only, a failing
# device or network file system (EIO), permissions changed while the run ran
_SPACE_ERRORS = {errno.ENOSPC, errno.EFBIG} | ({errno.EDQUOT} if hasattr(errno, "EDQUOT") else set())
_WRITE_ERRORS = _SPACE_ERRORS | {errno.EROFS, errno.EIO, errno.EACCES, errno.EPERM}
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


# -- the marker: what a run wrote, so that --force deletes nothing else ---------------------------
def _tree(folder: Path, prefix: str = "") -> list[str]:
    """Relative POSIX paths of every entry under ``folder`` (folders and their content)."""
    names = []
    for p in sorted(folder.iterdir()):
        rel = prefix + p.name
        names.append(rel)
        if p.is_dir() and not p.is_symlink():
            names += _tree(p, rel + "/")
    return names


def read_marker(out) -> dict | None:
    """The run marker of folder ``out`` (:data:`MARKER`), None if it has none or it is unreadable.

    Only a marker with a list of entries counts: anything else was not written by polypore.
    """
    try:
        record = json.loads((Path(out) / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or not isinstance(record.get("entries"), list):
        return None
    return record


def _write_marker(out: Path, status: str, entries) -> None:
    # the marker and the lock belong to every run folder; listed so that a reader sees them explained
    names = sorted(set(entries) | {MARKER, LOCK})
    record = {"polypore": __version__, "status": status, "host": socket.gethostname(), "pid": os.getpid(),
              "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "entries": names}
    atomic_write_text(out / MARKER, json.dumps(record, indent=2) + "\n")


def _foreign(out: Path, listed: set[str]) -> list[str]:
    """Entries of ``out`` (relative paths, depth first) that ``listed`` does not account for."""
    foreign = []

    def walk(folder: Path, prefix: str) -> None:
        for p in sorted(folder.iterdir()):
            rel = prefix + p.name
            if rel == LOCK:
                continue          # polypore's by name; reused, never deleted
            if rel not in listed:
                foreign.append(rel + ("/" if p.is_dir() and not p.is_symlink() else ""))
            elif p.is_dir() and not p.is_symlink():
                walk(p, rel + "/")

    walk(out, "")
    return foreign


def _names(entries: list[str], limit: int = 5) -> str:
    shown = ", ".join(repr(e) for e in entries[:limit])
    return shown + (f" and {len(entries) - limit} more" if len(entries) > limit else "")


def _os_error(option: str, what: str, exc: OSError) -> InputError:
    return InputError(option, f"cannot {what}: {exc.strerror or exc}")


def check_output_directory(out, force: bool, option: str = "--out") -> None:
    """Raise InputError (naming ``option``) if ``out`` may not receive a run's results.

    Allowed: a missing or empty folder, one holding only the files of an earlier failed run,
    and with ``force`` one holding only the files of a previous polypore run. What a run wrote
    is what its marker (:data:`MARKER`) lists; a folder with any other entry, or with no marker
    (other files, or a result of a polypore older than the marker), is refused, force or not:
    ``--force`` deletes only what polypore wrote.
    """
    out = Path(out)
    try:
        if out.exists() and not out.is_dir():
            raise InputError(option, f"{str(out)!r} exists and is not a directory")
        if not out.is_dir():
            return
        present = [p.name for p in out.iterdir() if p.name != LOCK]
    except OSError as exc:
        raise _os_error(option, f"use {str(out)!r} as the output folder", exc) from None
    if not present:
        return
    marker = read_marker(out)
    if marker is None:
        raise InputError(option, f"directory {str(out)!r} is not empty and was not written by polypore "
                         f"(it has no {MARKER}, which polypore writes into every run folder; results of "
                         "polypore versions before that marker have none either, and are refused too): "
                         f"it holds {_names(sorted(present))}. polypore deletes only files it wrote, so "
                         f"choose another {option} or empty it yourself")
    try:
        foreign = _foreign(out, set(marker["entries"]))
    except OSError as exc:
        raise _os_error(option, f"list {str(out)!r}", exc) from None
    if foreign:
        raise InputError(option, f"directory {str(out)!r} holds entries a polypore run did not write: "
                         f"{_names(foreign)}; --force deletes only what polypore wrote, so choose another "
                         f"{option} or move them away")
    if marker.get("status") != "failed" and not force:
        raise InputError(option, f"directory {str(out)!r} is not empty: it holds a previous polypore result; "
                         f"choose another {option} or pass --force to replace it")


def _clear(out: Path) -> None:
    """Remove what the marker of ``out`` lists, the marker last; nothing else (not the lock)."""
    marker = read_marker(out)
    if marker is None:
        return
    listed = set(marker["entries"]) - {LOCK}

    def clear(folder: Path, prefix: str) -> None:
        # completion markers first: if this is cut short, what is left does not look complete
        entries = sorted(folder.iterdir(), key=lambda p: (p.name not in COMPLETE_MARKERS, p.name == MARKER))
        for p in entries:
            rel = prefix + p.name
            if rel not in listed or (rel == MARKER):
                continue
            if p.is_dir() and not p.is_symlink():
                clear(p, rel + "/")
                try:
                    p.rmdir()
                except OSError:    # holds something the run did not write: kept, with its folder
                    pass
            else:
                p.unlink(missing_ok=True)

    clear(out, "")
    (out / MARKER).unlink(missing_ok=True)


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


def _holder(fd: int) -> str:
    try:
        record = json.loads(os.pread(fd, 4096, 0).decode("utf-8"))
        return f"process {int(record['pid'])} on host {record['host']!r}, since {record['since']}"
    except (OSError, ValueError, KeyError, TypeError):
        return "holder not recorded yet"


@contextmanager
def _locked(out: Path, option: str) -> Iterator[None]:
    """Hold ``out`` for this process: an exclusive lock on its :data:`LOCK` file.

    ``flock``: the kernel drops the lock when the process ends, however it ends, so a killed run
    never blocks the folder. Raises InputError if another process holds it. Without ``fcntl``
    (Windows) or on a file system without locks the folder is used unlocked (a warning).
    """
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _os_error(option, f"create the output folder {str(out)!r}", exc) from None
    try:
        fd = os.open(out / LOCK, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o644)
    except OSError as exc:
        # a read-only folder or file system: found here, before any of the run's work
        raise _os_error(option, f"write in the output folder {str(out)!r}", exc) from None
    try:
        if fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise InputError(option, f"directory {str(out)!r} is in use by another polypore run "
                                 f"({_holder(fd)}); wait for it to end or choose another {option}") from None
            except OSError as exc:   # ENOLCK, EOPNOTSUPP: some network file systems
                log.warning("cannot lock %s (%s): two runs into it at once would not be detected", out,
                            exc.strerror or exc)
        record = {"pid": os.getpid(), "host": socket.gethostname(), "since": time.strftime("%Y-%m-%d %H:%M:%S")}
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps(record).encode("utf-8"), 0)
        except OSError as exc:
            raise _os_error(option, f"write in {str(out)!r}", exc) from None
        yield
    finally:
        try:
            os.ftruncate(fd, 0)   # idle: no holder
        except OSError:
            pass
        os.close(fd)              # releases the lock


def _stage_name(out: Path) -> str:
    # out's name only helps a reader: cut to 80 bytes (whole characters), with the host's, to stay
    # within a file name's 255 bytes
    short = out.name.encode("utf-8", "surrogateescape")[:80].decode("utf-8", "ignore")
    return f"{STAGE_PREFIX}{short}@{_host()}.{os.getpid()}.{uuid.uuid4().hex[:12]}"


def _fail(out: Path, exc: BaseException) -> None:
    """Replace what the runs wrote in ``out`` by failed.json (and its marker) for ``exc``."""
    try:
        listed = (read_marker(out) or {"entries": []})["entries"]
        if (out / "failed.json").exists() and "failed.json" not in listed:
            return    # someone else's file of that name: not overwritten
        _clear(out)
        # the marker before the file: whatever is in out is always listed
        _write_marker(out, "failed", ["failed.json"])
        atomic_write_text(out / "failed.json", json.dumps(failure_record(exc), indent=2))
        exc.failed_json = out / "failed.json"  # for the command line's message
    except OSError:
        pass  # the run's own error is the one to report


def _publish(stage: Path, out: Path, option: str) -> None:
    """Move the staged files into ``out`` in place of what the previous run there wrote."""
    try:
        foreign = _foreign(out, set((read_marker(out) or {"entries": []})["entries"]))
    except OSError as exc:
        raise _os_error(option, f"list {str(out)!r}", exc) from None
    if foreign:
        # added while the run ran (the folder was checked at the start): never overwritten
        raise InputError(option, f"entries appeared in {str(out)!r} during the run: {_names(foreign)}; "
                         f"the results were not moved in, choose another {option}")
    _clear(out)
    # listed before they appear, complete last: a move cut short leaves a folder that is listed
    # and does not look complete
    entries = _tree(stage)
    _write_marker(out, "incomplete", entries)
    names = sorted((p.name for p in stage.iterdir()), key=lambda n: n in COMPLETE_MARKERS)
    for name in names:
        # shutil.move: a rename, or a copy when out is a mount point on another file system
        shutil.move(str(stage / name), str(out / name))
    _write_marker(out, "finished", entries)
    _sync_dir(out)


@contextmanager
def run_directory(out, *, force: bool = False, option: str = "--out") -> Iterator[Path]:
    """Yield a staging folder for a run's files; on success they replace ``out``'s content.

    ``out`` is checked with :func:`check_output_directory` first (an InputError leaves it
    untouched), then locked for the whole run, the final move included: a second run into
    ``out`` meanwhile gets an InputError. If the block or the move raises anything,
    KeyboardInterrupt included, what earlier runs wrote in ``out`` is replaced by ``failed.json``
    with the reason and the exception propagates. Either way the staging folder is removed, and
    so are the stale ones of killed runs in ``out``'s parent. Every run folder holds a marker
    (:data:`MARKER`) listing what the run wrote, and :data:`LOCK`; nothing else is ever deleted.

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
    with _locked(out, option):
        check_output_directory(out, force, option)   # again, now that no other run can change it
        if not os.access(out.parent, os.W_OK | os.X_OK):
            # the staging folder goes next to out: found now, not after the run's work
            raise InputError(option, f"cannot write in {str(out.parent)!r} (the parent of the output folder, "
                             "where results are staged): permission denied")
        stage = None
        # everything from here on sits inside the try: a signal (SIGTERM/SIGINT raise in the main
        # thread) that lands between creating the stage and entering a later try would otherwise
        # escape without failed.json and leave the stage behind
        try:
            try:
                remove_stale_stages(out.parent)
                stage = out.parent / _stage_name(out)
                _ACTIVE.add(stage)
                try:
                    stage.mkdir()
                except OSError as exc:
                    raise _os_error(option, f"create the staging folder {str(stage)!r}", exc) from None
                yield stage
                _publish(stage, out, option)
            except OSError as exc:
                if exc.errno not in _WRITE_ERRORS:
                    _fail(out, exc)
                    raise
                # a full disk (or one that turned read-only) mid-run: the run failed, say where
                hint = "free some space there or choose another" if exc.errno in _SPACE_ERRORS else "choose another"
                err = RunError(f"cannot write the results into {str(out)!r}: {exc.strerror or exc}; {hint} {option}")
                _fail(out, err)
                raise err from exc
            except BaseException as exc:
                _fail(out, exc)
                raise
        finally:
            if stage is not None:
                _ACTIVE.discard(stage)
                shutil.rmtree(stage, ignore_errors=True)
