"""The ``polypore`` command (interface.md): ``cases``, ``mesh``, ``run``, ``convergence`` and ``schema``.

Exit status: 0 success, 1 a run failed, 2 bad input (the message names the field; also a case
whose estimated cells, time steps or memory exceed the machine or sane bounds, unless
``--no-limits``: :mod:`polypore.setup.limits`), 130 and 143 interrupted by SIGINT and SIGTERM.
Output folders follow one rule (:func:`polypore.io.atomic.run_directory`): a finished command
leaves a complete result, anything else only ``failed.json`` with the reason.
"""

from __future__ import annotations

import argparse
import logging
import math
import signal
import sys
import time
from contextlib import contextmanager
from pathlib import Path

from . import __version__
from .core.errors import InputError, PolyporeError
from .io.atomic import run_directory

log = logging.getLogger("polypore")


def _setup_logging(quiet: bool) -> None:
    log.handlers.clear()
    log.propagate = False
    log.setLevel(logging.WARNING if quiet else logging.INFO)
    if sys.stderr.isatty():
        from rich.logging import RichHandler

        handler = RichHandler(show_path=False, show_level=False, log_time_format="[%X]")
    else:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("[polypore] %(message)s"))
    log.addHandler(handler)


@contextmanager
def _live_status():
    """The live status line (docs/live_progress.md) while the block runs: on rank 0 only, not with
    --quiet nor with POLYPORE_LIVE=0; POLYPORE_LIVE_INTERVAL sets the seconds between the plain
    lines written when stderr is not a terminal (default 30). The line is cleared at the end of the
    block and before every log record."""
    import os

    if not _is_root() or not log.isEnabledFor(logging.INFO) or os.environ.get("POLYPORE_LIVE", "1") == "0":
        yield
        return
    from .io.progress import LiveStatus

    try:
        interval = float(os.environ.get("POLYPORE_LIVE_INTERVAL", "30"))
    except ValueError:
        interval = 30.0
    with LiveStatus(sys.stderr, interval=interval) as status:
        for handler in log.handlers:
            status.guard(handler)
        yield


class Terminated(BaseException):
    """Raised by the SIGTERM handler: a BaseException, like KeyboardInterrupt, so that no
    ``except Exception`` on the way swallows it and the run directory records the failure."""

    def __init__(self, signum: int):
        self.signal = signal.Signals(signum).name
        super().__init__(f"terminated by {self.signal}")


_SIGNALLED: list[int] = []   # signals received while the command runs


def _on_signal(signum, frame):
    _SIGNALLED.append(signum)
    raise KeyboardInterrupt if signum == signal.SIGINT else Terminated(signum)


@contextmanager
def _signals_raise():
    """While a command runs, SIGINT and SIGTERM raise KeyboardInterrupt and :class:`Terminated`
    and are remembered. Only default dispositions are replaced: a caller that ignores a signal
    (a background job ignores SIGINT) or handles it keeps its choice. Each signal is also
    acknowledged at once on stderr (:func:`_acknowledge`)."""
    _SIGNALLED.clear()
    previous = {}
    try:
        for sig, default in ((signal.SIGINT, signal.default_int_handler), (signal.SIGTERM, signal.SIG_DFL)):
            if signal.getsignal(sig) == default:
                previous[sig] = signal.signal(sig, _on_signal)
    except ValueError:  # not the main thread: signals cannot be handled here
        pass
    hook = sys.unraisablehook

    def lost_signal(unraisable):
        # the handler's exception raised inside a __del__ or a weakref callback is dropped by
        # CPython with an "Exception ignored in …" traceback; the signal is remembered and the
        # run stops anyway (_output raises it again), so the user gets the one-line message only
        if previous and isinstance(unraisable.exc_value, (KeyboardInterrupt, Terminated)) and _SIGNALLED:
            return
        hook(unraisable)

    sys.unraisablehook = lost_signal
    try:
        with _acknowledge(set(previous)):
            yield
    finally:
        sys.unraisablehook = hook
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@contextmanager
def _acknowledge(signals: set):
    """Print "<SIG> received; stopping..." as soon as one of ``signals``
    arrives, even while the main thread is inside a long native call (a sparse factorisation).

    Python runs its handler only when the main thread is back in bytecode, which can be minutes
    later. The C-level handler writes the signal's number to the wakeup fd at once
    (:func:`signal.set_wakeup_fd`); a thread blocked on it prints the line. That thread needs
    the GIL: solvers that release it (SuperLU, PARDISO through ctypes) let it print at once,
    one that holds it delays the line until it returns. The line is printed before the
    command's last message: leaving the block drains the pipe first.
    """
    import os
    import threading

    if not signals:
        yield
        return
    r, w = os.pipe()
    os.set_blocking(w, False)      # set_wakeup_fd requires it: the C handler must never block
    try:
        old = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
    except ValueError:  # pragma: no cover - not the main thread
        os.close(r)
        os.close(w)
        yield
        return
    if old != -1:       # someone else's wakeup fd (an event loop): theirs to keep
        signal.set_wakeup_fd(old)
        os.close(r)
        os.close(w)
        yield
        return

    def watch():
        told = set()
        while data := os.read(r, 64):
            for sig in data:
                if sig in signals and sig not in told:
                    told.add(sig)
                    try:
                        from .io.progress import erase_live_line

                        erase_live_line()
                        sys.stderr.write(f"polypore: {signal.Signals(sig).name} received; stopping...\n")
                        sys.stderr.flush()
                    except (OSError, ValueError):
                        pass

    thread = threading.Thread(target=watch, name="polypore-signals", daemon=True)
    thread.start()
    try:
        yield
    finally:
        signal.set_wakeup_fd(-1)
        os.close(w)                 # the thread reads what is left, then end of file
        thread.join(timeout=2.0)
        if not thread.is_alive():
            os.close(r)


def _check_case_folder(args, out: Path) -> None:
    case = Path(args.case)
    if args.force and case.is_file() and out.resolve() in case.resolve().parents:
        # the folder is replaced as a whole: it must not hold the case being run
        raise InputError("--out", f"{str(out)!r} holds the case file {args.case!r}, which --force would delete; "
                         "choose another --out")


def _check_output(args, out: Path) -> None:
    from .io.atomic import check_output_directory

    _check_case_folder(args, out)
    check_output_directory(out, args.force)


@contextmanager
def _output(args, default_name: str):
    """Claim the output folder (``--out`` or results/<default_name>) for the block: yields
    (folder, staging folder); see :func:`polypore.io.atomic.run_directory`.

    In a distributed run rank 0 writes the results; the other ranks, which compute the same
    replicated results, write into a temporary folder that is deleted (docs/parallel.md).
    """
    from .parallel.context import context

    out = Path(args.out) if args.out else Path("results") / default_name
    ctx = context()
    if ctx is not None and ctx.size > 1:
        ctx.bcast_call(_check_output, args, out)      # rank 0's verdict on every rank
        if not ctx.root:
            import tempfile

            with tempfile.TemporaryDirectory(prefix=f"polypore-rank{ctx.rank}-") as tmp:
                yield out, Path(tmp)
            return
    _check_case_folder(args, out)
    with run_directory(out, force=args.force) as stage:
        yield out, stage
        if _SIGNALLED:
            # the signal's exception was lost: CPython drops exceptions raised inside a __del__
            # or a weakref callback; the run was still asked to stop and must not look complete
            sig = _SIGNALLED[0]
            raise KeyboardInterrupt if sig == signal.SIGINT else Terminated(sig)


def _check_limits(args, case, **kw) -> None:
    """Refuse, before any work, a case beyond the machine or sane bounds (unless --no-limits)."""
    if args.no_limits:
        return
    from .setup.limits import check_limits

    check_limits(case.spec, **kw)


def cmd_cases(args) -> int:
    from .setup.registry import describe_cases

    rows = describe_cases()
    width = max(len(n) for n, _ in rows)
    for name, line in rows:
        print(f"{name:<{width}}  {line}")
    return 0


def cmd_mesh(args) -> int:
    from .io.mesh_output import write_mesh_outputs
    from .runs.common import corner_point_faults
    from .setup.casefile import load_case
    from .setup.checks import check_case_on_mesh
    from .setup.meshing import build_fractured_mesh

    case = load_case(args.case, args.set or [])
    _check_limits(args, case, max_steps=math.inf)   # the mesh only: no time loop
    with _output(args, case.name) as (out, stage):
        t0 = time.perf_counter()
        with _live_status():
            fm = build_fractured_mesh(case)
            check_case_on_mesh(case, fm)        # what `polypore run` would refuse is refused here too
            # the faults of a corner-point grid, logged as a table and kept in mesh.json as in summary.json
            faults = corner_point_faults(case, fm)
            report = write_mesh_outputs(stage, case, fm, seconds=time.perf_counter() - t0, faults=faults)
    _print_mesh_report(report)
    print(f"wrote {out}/: mesh.vtu, fractures.vtu, mesh.json, case.toml")
    return 0


def cmd_run(args) -> int:
    from .runs.dispatch import run_case
    from .setup.casefile import load_case

    case = load_case(args.case, args.set or [])
    _check_limits(args, case)
    with _output(args, case.name) as (out, stage):
        with _live_status():
            summary = run_case(case, stage)
    peaks = _rank_peaks()
    if not _is_root():
        return 0
    steps = summary["steps"]
    st = steps[-1] if steps else {}
    parts = [f"{summary['mesh']['cells']} cells, {summary['mesh']['unknowns']} unknowns"]
    if len(steps) > 1:
        parts.append(f"{len(steps)} time steps")
    if "newton_iterations" in st:
        # the total is the cost of the run; the residual and contact states are the final ones
        n = sum(s["newton_iterations"] for s in steps)
        nf = summary.get("totals", {}).get("newton_iterations_failed", 0)
        parts.append(f"{n} Newton iteration{'' if n == 1 else 's'}" + (f" (+{nf} in failed attempts)" if nf else ""))
        parts.append(f"{'at the end ' if len(steps) > 1 else ''}residual {st['residual']:.2e}, "
                     f"faces open {st['open']}, stick {st['stick']}, slip {st['slip']}")
    parts.append(f"{summary['totals']['seconds']:.1f} s, peak {summary['totals']['peak_memory_mb']:.0f} MB"
                 + (f" (ranks: {'/'.join(f'{p:.0f}' for p in peaks)} MB)" if peaks else ""))
    print(f"case {case.name}: " + "; ".join(parts))
    for line in _time_split_lines(summary["totals"]):
        print(line)
    for name, v in summary.get("errors", {}).items():
        print(f"  {name} = {v:.4e}")
    print(f"wrote {out}/")
    return 0


def _time_split_lines(totals: dict) -> list[str]:
    """One line per rank (one for a serial run): where the time went, wall and CPU seconds
    (summary.json's ``totals``; docs/parallel.md, "Time split")."""
    if "seconds_krylov" not in totals:
        return []
    from .core.timing import split_labels

    rows = totals.get("ranks") or [totals]
    # named by what ran: a direct solver's factorisation and solves, not a preconditioner and Krylov
    keys = tuple((totals.get("labels") or split_labels(totals.get("linear_solver"))).items())
    out = []
    for r, t in enumerate(rows):
        who = f" rank {r}" if len(rows) > 1 else ""
        parts = [f"{label} {t[f'seconds_{k}']:.1f} s" for k, label in keys]
        cpu = "/".join(f"{t['cpu'][f'seconds_{k}']:.1f}" for k, _ in keys)
        out.append(f"  time{who}: " + ", ".join(parts) + f" (CPU {cpu} s)")
    return out


def _rank_peaks() -> list[float] | None:
    """Peak resident memory of every rank (MB) on rank 0 of a distributed run; None otherwise."""
    from .parallel.context import context

    ctx = context()
    if ctx is None or ctx.size == 1:
        return None
    from .runs.common import peak_memory_mb

    return ctx.comm.gather(peak_memory_mb(), root=0)


def _abort_other_ranks() -> None:
    """A bug on one rank of a distributed run: print it and abort every rank (MPI_Abort) rather than
    leave the others waiting in a collective operation."""
    from .parallel.context import context

    ctx = context()
    if ctx is None or ctx.size == 1:
        return
    import traceback

    traceback.print_exc()
    sys.stderr.flush()
    ctx.comm.Abort(1)


def _stop_every_rank(message: str, status: int) -> None:
    """Report an error that ends the run. Serially: print it. Distributed: every rank usually
    raises the same one (the same checks on the same broadcast data) and rank 0 reports it; when
    only some ranks raise it, the others would wait for them in a collective forever, so the
    rank prints it with its number and aborts every rank (MPI_Abort with ``status``)."""
    from .parallel.context import context

    ctx = context()
    if ctx is None or ctx.size == 1:
        print(f"polypore: {message}", file=sys.stderr)
        return
    if ctx.errors_agree():
        if ctx.root:
            print(f"polypore: {message}", file=sys.stderr)
        return
    print(f"polypore: {message} (rank {ctx.rank} of {ctx.size}; the other ranks did not stop: aborting them)",
          file=sys.stderr)
    sys.stderr.flush()
    ctx.comm.Abort(status)


def _is_root() -> bool:
    from .parallel.context import context

    ctx = context()
    return ctx is None or ctx.root


def cmd_convergence(args) -> int:
    from .runs.convergence import format_table, run_convergence
    from .setup.casefile import load_case

    case = load_case(args.case, args.set or [])
    if args.levels < 2:
        raise InputError("--levels", f"need at least 2 levels to fit a rate, got {args.levels}")
    _check_limits(args, case, levels=args.levels)
    with _output(args, f"{case.name}-convergence") as (out, stage):
        with _live_status():
            result = run_convergence(case, args.levels, stage)
    print(format_table(result))
    print(f"wrote {out}/: convergence.csv, convergence.json, convergence.png")
    return 0


def cmd_plot(args) -> int:
    import json

    folder = Path(args.run_dir)
    summary = folder / "summary.json"
    if not summary.is_file():
        raise InputError("RUN_DIR", f"{str(folder)!r} holds no summary.json: give the folder of a finished "
                         "'polypore run'")
    try:
        info = json.loads(summary.read_text())
    except (OSError, ValueError) as exc:
        raise InputError("RUN_DIR", f"cannot read {str(summary)!r}: {exc}") from None
    if info.get("model") != "poromechanics" or info.get("mesh", {}).get("dim") != 3:
        raise InputError("RUN_DIR", f"{str(folder)!r} is a {info.get('mesh', {}).get('dim', '?')}D "
                         f"{info.get('model', '?')} run; 'polypore plot' redraws 3D poromechanics runs "
                         "(the other runs write all their plots when they run)")
    missing = [n for n in ("fractures.csv", "solution.pvd") if not (folder / n).is_file()]
    if missing:
        raise InputError("RUN_DIR", f"{str(folder)!r} lacks {', '.join(missing)}: not a complete run folder")
    from .runs.coupled import replot

    try:
        written = replot(folder, args.out)
    except (OSError, ValueError, KeyError) as exc:
        raise InputError("RUN_DIR", f"cannot redraw {str(folder)!r}: {type(exc).__name__}: {exc}") from None
    for f in written:
        print(f"wrote {f}")
    return 0


def cmd_schema(args) -> int:
    import json

    from .setup.schema import json_schema

    text = json.dumps(json_schema(), indent=2, ensure_ascii=False) + "\n"
    if args.out is None:
        sys.stdout.write(text)
        return 0
    from .io.atomic import atomic_write_text

    out = Path(args.out)
    if out.is_dir():
        raise InputError("--out", f"{str(out)!r} is a folder; give the path of the JSON file to write")
    try:
        atomic_write_text(out, text)
    except OSError as exc:
        raise InputError("--out", f"cannot write {str(out)!r}: {exc.strerror or exc}") from None
    print(f"wrote {out}")
    return 0


def _print_mesh_report(report: dict) -> None:
    m = report["mesh"]
    lines = [f"case {report['case']}: {m['dim']}D, {m['cells']} cells, {m['faces']} faces, {m['nodes']} nodes, "
             f"{m['node_sides']} node sides (displacement unknowns {m['dim'] * m['node_sides']} nodal)",
             f"  h max {m['h_max']:.4g} m, h mean {m['h_mean']:.4g} m, |Ω| = {m['volume']:.6g}, "
             f"faces per cell {m['faces_per_cell'][0]}–{m['faces_per_cell'][1]}, non-planar faces {m['nonplanar_faces']}",
             f"  boundary parts: " + ", ".join(f"{k} ({v})" for k, v in m["boundary"].items()),
             f"  regions: " + ", ".join(f"{k} ({v})" for k, v in m["regions"].items())]
    for name, f in report["fractures"].items():
        extra = []
        if f["tips"]:
            extra.append(f"{f['tips']} tip{'s' if f['tips'] > 1 else ''}")
        if f["kinks"]:
            extra.append(f"{f['kinks']} kink{'s' if f['kinks'] > 1 else ''}")
        if f["intersects"]:
            extra.append("intersects " + ", ".join(f["intersects"]))
        if f["reaches_boundary"]:
            extra.append("reaches ∂Ω")
        lines.append(f"  fracture {name}: {f['faces']} faces, measure {f['measure']:.6g}"
                     + (f"; {'; '.join(extra)}" if extra else ""))
    print("\n".join(lines))


def _case_arguments(p, default_out: str) -> None:
    p.add_argument("case", metavar="CASE", help="built-in case name or path to a TOML case file")
    p.add_argument("--out", metavar="DIR", help=f"output directory (default: {default_out})")
    p.add_argument("--set", metavar="KEY=VALUE", action="append", help="override a case field, e.g. mesh.size=0.1")
    p.add_argument("--force", action="store_true", help="replace a previous polypore result in the output "
                   "directory: only what polypore wrote there is deleted, a folder holding anything else is "
                   "refused")
    p.add_argument("--no-limits", action="store_true", help="run even when the estimated cells, time steps or "
                   "memory exceed the machine or sane bounds")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="polypore", description="Poromechanics of fractured rock with frictional "
                                "contact on polytopal meshes.")
    p.add_argument("--version", action="version", version=f"polypore {__version__}")
    p.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors on stderr")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    c = sub.add_parser("cases", help="list the built-in cases")
    c.set_defaults(func=cmd_cases)
    m = sub.add_parser("mesh", help="build and write a case's mesh and print its statistics")
    _case_arguments(m, "results/<case>/")
    m.set_defaults(func=cmd_mesh)
    r = sub.add_parser("run", help="run a case and write its results")
    _case_arguments(r, "results/<case>/")
    r.set_defaults(func=cmd_run)
    c = sub.add_parser("convergence", help="mesh-refinement study of a case with an exact solution")
    _case_arguments(c, "results/<case>-convergence/")
    c.add_argument("--levels", type=int, default=3, help="number of meshes (each halves the mesh size)")
    c.set_defaults(func=cmd_convergence)
    pl = sub.add_parser("plot", help="redraw the monitor plots of a finished 3D poromechanics run's folder")
    pl.add_argument("run_dir", metavar="RUN_DIR", help="the folder a 'polypore run' wrote")
    pl.add_argument("--out", metavar="DIR", help="folder for the PNG files (default: RUN_DIR)")
    pl.set_defaults(func=cmd_plot)
    s = sub.add_parser("schema", help="print the JSON Schema of case files (for TOML editors)")
    s.add_argument("--out", metavar="FILE", help="write it to FILE instead of printing it")
    s.set_defaults(func=cmd_schema)
    return p


def _start_distributed(args) -> bool:
    """Under mpiexec (docs/parallel.md): start the distributed mode; False (with a one-line
    message) when more than one rank was started without petsc4py/mpi4py. One rank without them
    runs serially."""
    from .parallel.context import activate, launched_ranks

    n = launched_ranks()
    if n < 1 or args.func in (cmd_cases, cmd_schema, cmd_plot):
        return True
    try:
        ctx = activate()
    except InputError as exc:
        if n == 1:
            return True
        print(f"polypore: error: {exc}", file=sys.stderr)
        return False
    if ctx.rank > 0:
        log.setLevel(logging.ERROR)           # rank 0 reports; the others compute the same
    log.info("distributed run on %d MPI rank%s (PETSc)", ctx.size, "" if ctx.size == 1 else "s")
    return True


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    _setup_logging(args.quiet)
    if not _start_distributed(args):
        return 2
    try:
        with _signals_raise():
            status = args.func(args)
            sys.stdout.flush()   # a closed pipe raises here, inside the handlers below, not at exit
            return status
    except InputError as exc:
        _stop_every_rank(f"error: {exc}", 2)
        return 2
    except PolyporeError as exc:
        _stop_every_rank(f"run failed: {exc}", exc.exit_status)
        return exc.exit_status
    except BrokenPipeError:
        # stdout piped into a program that stopped reading (`| head -1`, `| grep -q`): not an error
        # of the run. Python's documented recipe: point stdout at devnull, so that the flush at exit
        # does not raise again, and leave quietly (before `except Exception`, which would catch it)
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except Exception:
        _abort_other_ranks()
        raise
    except (KeyboardInterrupt, Terminated) as exc:
        # one line, no traceback: the reason and, once the output folder was claimed, where it is recorded
        where = getattr(exc, "failed_json", None)
        name = getattr(exc, "signal", "SIGINT")
        what = "interrupted by the user (SIGINT)" if name == "SIGINT" else str(exc)
        print(f"polypore: {what}" + (f"; wrote {where}" if where else ""), file=sys.stderr)
        status = 128 + signal.Signals[name].value
        from .core.interruptible import abandoned

        if abandoned():
            # a factorisation is still running on its thread: the interpreter's shutdown would
            # free what it uses and crash it; everything the run had to record is written
            import os

            logging.shutdown()
            for stream in (sys.stdout, sys.stderr):
                try:
                    stream.flush()
                except (OSError, ValueError):
                    pass
            os._exit(status)
        return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
