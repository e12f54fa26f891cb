"""Where the memory of a distributed ``polypore run`` goes, per rank and per phase (docs/parallel.md,
"Memory per rank").

    OMP_NUM_THREADS=1 mpiexec -n 2 .venv-mpi/bin/python benchmarks/mpi_memory.py dfm-3d \
        --set mesh.size=0.06 --set solver.linear=block-petsc --set time.end=4 --set 'time.output_times=[4.0]'

The run is ``polypore run`` itself; the phases are timed by wrapping the functions that do them
(mesh, model set-up and its parts, the initial state, residual + Jacobian, the block
preconditioner's P and the PETSc matrices, PCSetUp, KSPSolve). For each phase and rank:

* ``kept``: resident memory after the phase minus before it (MB; the first call), what it leaves
  behind;
* ``peak``: the highest resident memory during the phase above its start (MB; the largest over
  all calls), its transient. The kernel's high-water mark (VmHWM) is reset at every phase
  boundary through ``/proc/self/clear_refs`` (Linux), so nested phases each get their own.

At the end each rank also lists the bytes held by the model's large arrays (NumPy arrays and
SciPy matrices reachable from the model and the solver, each buffer counted once), by attribute.
Rank 0 prints a JSON report of every rank; ``--json FILE`` writes it.
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from collections import defaultdict

import numpy as np


def _status() -> dict:
    out = {}
    with open("/proc/self/status") as f:
        for ln in f:
            k, _, v = ln.partition(":")
            if k in ("VmRSS", "VmHWM"):
                out[k] = int(v.split()[0]) / 1024.0
    return out


_TRIM = None


def _trim():
    """Give the freed heap pages back to the kernel (glibc's malloc_trim), so that the resident
    memory measured is the live one: without it the heap keeps the pages of freed temporaries
    (109 of the 122 MB the poromechanics pattern set-up seemed to keep on C5 at 23k cells)."""
    global _TRIM
    if _TRIM is None:
        try:
            import ctypes

            _TRIM = ctypes.CDLL("libc.so.6").malloc_trim
        except (OSError, AttributeError):
            _TRIM = False
    if _TRIM:
        _TRIM(0)


def _reset_hwm():
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass


class Phases:
    """Nested phases with their kept and transient-peak memory (MB) and seconds."""

    def __init__(self, trim=False):
        self.trim = trim
        self.stack = []                      # [name, rss at entry, peak so far]
        self.timeline = []                   # (name, rss at entry, peak during, rss at exit)
        self.rows = defaultdict(lambda: {"calls": 0, "kept_first": None, "kept_total": 0.0, "peak": 0.0,
                                         "seconds": 0.0, "cpu": 0.0})

    def _fold(self):
        if self.trim:
            _trim()
        hwm = _status()["VmHWM"]
        for fr in self.stack:
            fr[2] = max(fr[2], hwm)
        _reset_hwm()

    def wrap(self, owner, attr, name=None):
        fn = getattr(owner, attr)
        label = name or attr
        phases = self

        @functools.wraps(fn)
        def inner(*a, **k):
            phases._fold()
            rss0 = _status()["VmRSS"]
            fr = [label, rss0, rss0]
            phases.stack.append(fr)
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                return fn(*a, **k)
            finally:
                phases._fold()
                phases.stack.pop()
                rss1 = _status()["VmRSS"]
                row = phases.rows[label]
                row["calls"] += 1
                if row["kept_first"] is None:
                    row["kept_first"] = rss1 - rss0
                row["kept_total"] += rss1 - rss0
                row["peak"] = max(row["peak"], fr[2] - rss0)
                phases.timeline.append((label.strip(), round(rss0, 1), round(fr[2], 1), round(rss1, 1)))
                row["seconds"] += time.perf_counter() - t0
                row["cpu"] += time.process_time() - c0

        setattr(owner, attr, inner)


def held_bytes(roots: dict) -> dict:
    """Bytes of the NumPy buffers reachable from each named root (each buffer counted once, in the
    first root that reaches it), MB."""
    import scipy.sparse as sp

    seen_obj, seen_buf = set(), set()
    out = {}

    def buf_id(a):
        while isinstance(a, np.ndarray) and a.base is not None and isinstance(a.base, np.ndarray):
            a = a.base
        return id(a), a.nbytes if isinstance(a, np.ndarray) else 0

    def walk(o, depth=0):
        if depth > 12 or id(o) in seen_obj:
            return 0
        seen_obj.add(id(o))
        if isinstance(o, np.ndarray):
            if o.dtype == object:
                return sum(walk(x, depth + 1) for x in o.ravel())
            i, n = buf_id(o)
            if i in seen_buf:
                return 0
            seen_buf.add(i)
            return n
        if sp.issparse(o):
            return sum(walk(getattr(o, k), depth + 1) for k in ("data", "indices", "indptr", "row", "col", "offsets")
                       if hasattr(o, k))
        if isinstance(o, dict) or type(o).__name__ == "mappingproxy":
            return sum(walk(v, depth + 1) for v in o.values())
        if isinstance(o, (list, tuple, set, frozenset)):
            return sum(walk(v, depth + 1) for v in o)
        if isinstance(o, (str, bytes, int, float, bool, type(None))) or callable(o) and not hasattr(o, "__dict__"):
            return 0
        if type(o).__module__.startswith(("petsc4py", "mpi4py")):
            return 0
        d = getattr(o, "__dict__", None)
        tot = walk(d, depth + 1) if d is not None else 0
        for s in getattr(type(o), "__slots__", ()):
            if hasattr(o, s):
                tot += walk(getattr(o, s), depth + 1)
        return tot

    for name, obj in roots.items():
        out[name] = walk(obj) / 2**20
    return out


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("case")
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--out", default=None)
    ap.add_argument("--json", default=None)
    ap.add_argument("--trim", action="store_true", help="malloc_trim at every phase boundary: kept = live memory")
    args = ap.parse_args(argv)

    import polypore.cli as cli
    import polypore.models.flow as mflow
    import polypore.models.mechanics as mmech
    import polypore.models.poromechanics as mporo
    import polypore.runs.coupled as coupled
    import polypore.solvers.petsc as spetsc
    import polypore.solvers.petsc_fieldsplit as fs

    ph = Phases(args.trim)
    ph.wrap(coupled, "build_fractured_mesh", "mesh (build + broadcast)")
    ph.wrap(coupled, "poro_setup", "model set-up (all)")
    ph.wrap(mmech.ContactMechanics, "__init__", "  mechanics set-up (space, operators, A, pattern)")
    ph.wrap(mflow.FlowModel, "__init__", "  flow set-up (HFV operators, assembler)")
    P = mporo.Poromechanics
    for a in ("_setup_coupling", "_setup_stabilisation", "_setup_flow_dofs", "_setup_pattern"):
        ph.wrap(P, a, "  poro " + a.lstrip("_"))
    ph.wrap(P, "initial_state", "initial state (static contact solve)")
    ph.wrap(P, "step_context", "step context (flow matrix, scaling)")
    ph.wrap(P, "_linearise", "residual + Jacobian (poro)")
    ph.wrap(mmech.ContactMechanics, "linearise", "residual + Jacobian (contact)")
    for cls in (fs.PetscBlockPoroSolver, fs.PetscBlockContactSolver):
        ph.wrap(cls, "solve", f"{cls.__name__}.solve (all)")
    ph.wrap(fs._FieldSplitBase, "_matrices", "  P pattern/values + PETSc J, P (fieldsplit)")
    ph.wrap(fs._FieldSplitBase, "_condensed", "  S_uu, S_pp, S_pu, Bt Cl̂⁻¹Cû + PETSc J (condensed)")
    ph.wrap(fs, "lumped_coupling", "  lumped coupling of Ŝ_p (new step)")
    ph.wrap(fs, "modified_contact_blocks", "  Cl̂, Cû (modified contact blocks)")
    ph.wrap(spetsc.KrylovDriver, "_setup", "  PCSetUp")
    ph.wrap(spetsc.KrylovDriver, "_krylov", "  KSPSolve")
    held = {}

    real_setup = coupled.poro_setup

    def capture(*a, **k):
        out = real_setup(*a, **k)
        held["model"] = out[0]
        return out

    coupled.poro_setup = capture

    start_mb = _status()["VmRSS"]
    cmd = ["run", args.case, *[x for s in args.set for x in ("--set", s)], "--force"]
    if args.out:
        cmd += ["--out", args.out]
    t0 = time.perf_counter()
    rc = cli.main(cmd)
    from polypore.parallel.context import context

    ctx = context()
    model = held.get("model")
    roots = {}
    if model is not None:
        fm = model.fm
        roots = {"mesh (FracturedMesh)": fm, "mechanics.space": model.mech.space, "mechanics.ops": model.mech.ops}
        # then attribute by attribute: the model's own, the mechanics', the flow's, the solver's
        for prefix, obj in (("solver.", model.solver), ("mech.", model.mech), ("flow.assembler.", model.flow.assembler),
                            ("flow.", model.flow), ("poro.", model)):
            for k, v in vars(obj).items():
                roots[prefix + k] = v
    if args.trim:
        _trim()
    me = {"end_mb": _status()["VmRSS"], "rank": 0 if ctx is None else ctx.rank, "phases": dict(ph.rows), "held_mb": held_bytes(roots),
          "peak_mb": _status()["VmHWM"], "start_mb": start_mb, "timeline": ph.timeline, "peak_run_mb": __import__("resource").getrusage(
              __import__("resource").RUSAGE_SELF).ru_maxrss / 1024, "seconds": time.perf_counter() - t0}
    allr = [me] if ctx is None else ctx.comm.gather(me, root=0)
    if ctx is None or ctx.root:
        for r in allr:
            print(f"--- rank {r['rank']}: peak {r['peak_run_mb']:.0f} MB", file=sys.stderr)
            for name, row in r["phases"].items():
                print(f"  {name:<58} calls {row['calls']:>3}  kept {row['kept_first'] or 0:7.1f} MB"
                      f" (all calls {row['kept_total']:7.1f})  peak +{row['peak']:7.1f} MB  {row['seconds']:7.2f} s"
                      f"  cpu {row['cpu']:7.2f} s", file=sys.stderr)
            top = sorted(r["held_mb"].items(), key=lambda kv: -kv[1])
            print(f"  held in all: {sum(v for _, v in top):.1f} MB; start of run {r['start_mb']:.0f} MB, "
                  f"end {r['end_mb']:.0f} MB", file=sys.stderr)
            for name, mb in top[:25]:
                print(f"  held: {name:<52} {mb:8.1f} MB", file=sys.stderr)
        if args.json:
            with open(args.json, "w") as f:
                json.dump(allr, f, indent=1)
    return rc


if __name__ == "__main__":
    sys.exit(main())
