"""The communicator context of a distributed run (docs/parallel.md, "Distributed runs"): whether
this process runs under ``mpiexec``, COMM_WORLD with this rank and the cell partitions, and the
broadcast of rank 0's results. One context per process, started by the command line
(:func:`activate`) and read where a layer must know whether it runs distributed
(:func:`context`: None in a serial run). No physics here.
"""

from __future__ import annotations

import copyreg
import io
import logging
import os
import pickle
import types

import numpy as np

from ..core.errors import InputError

log = logging.getLogger("polypore")

# set by mpiexec/mpirun: Open MPI, MPICH/Hydra (and Intel MPI), Slurm's PMI-2
_SIZE_VARS = ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE")
MPI_INSTALL = ("a distributed run needs petsc4py and mpi4py built for this machine's MPI: "
               "pip install 'polypore[mpi]' and Debian's python3-petsc4py python3-mpi4py (`make test-mpi` "
               "builds .venv-mpi that way; docs/parallel.md)")


def launched_ranks() -> int:
    """Ranks of the ``mpiexec`` that started this process (from its environment; 0 when not
    started by mpiexec). Read without importing MPI."""
    for name in _SIZE_VARS:
        v = os.environ.get(name)
        if v and v.isdigit():
            return int(v)
    return 0


class Distributed:
    """The MPI context of a distributed run: COMM_WORLD (mpi4py), this rank, the cell partitions.

    Attributes
    ----------
    comm : mpi4py.MPI.Comm (COMM_WORLD)
    rank, size : int
    """

    def __init__(self):
        try:
            from mpi4py import MPI
            from petsc4py import PETSc  # noqa: F401  (PETSc on the same MPI)
        except ImportError:
            raise InputError("mpiexec", MPI_INSTALL) from None
        self.MPI = MPI
        self.comm = MPI.COMM_WORLD
        self.rank = self.comm.Get_rank()
        self.size = self.comm.Get_size()
        # a communicator of its own for agreeing on an error (errors_agree): a barrier there
        # cannot be matched against a collective another rank is waiting in on COMM_WORLD
        self.error_comm = self.comm.Dup()
        self._parts: dict = {}

    def errors_agree(self, timeout: float = 10.0) -> bool:
        """Called by a rank that stops on an error: True when every rank stops too (each calls
        this within ``timeout`` seconds: the same user error raised everywhere), False when some
        rank is still computing or waiting for this one (then only an abort ends the run)."""
        import time

        req = self.error_comm.Ibarrier()
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if req.Test():
                return True
            time.sleep(0.01)
        return False

    @property
    def root(self) -> bool:
        return self.rank == 0

    def bcast_call(self, fn, *args, **kw):
        """``fn(*args, **kw)`` on rank 0, its result broadcast (pickled) to every rank. An exception
        on rank 0 is raised on every rank, so no rank waits for a value that never comes."""
        blob = err = None
        if self.root:
            try:
                out = fn(*args, **kw)
                blob = _dumps(out)
            except Exception as exc:       # noqa: BLE001 — re-raised on every rank below
                err = exc
        err = self.comm.bcast(None if err is None else _portable_error(err), root=0)
        if err is not None:
            raise _rebuilt_error(err)
        blob = self.comm.bcast(blob, root=0)
        return out if self.root else pickle.loads(blob)

    def partition(self, mesh) -> np.ndarray:
        """(n_cells,) int32 rank of every cell (METIS on rank 0, broadcast); cached per mesh."""
        key = id(mesh)
        hit = self._parts.get(key)
        if hit is not None and hit[0] is mesh:
            return hit[1]
        from .partition import partition_cells

        parts = self.bcast_call(partition_cells, mesh, self.size)
        counts = np.bincount(parts, minlength=self.size)
        log.info("partition: %d cells on %d rank%s (%s cells per rank)", mesh.n_cells, self.size,
                 "" if self.size == 1 else "s",
                 "/".join(str(int(c)) for c in counts))
        self._parts[key] = (mesh, parts)
        return parts


def _portable_error(exc: BaseException) -> tuple:
    """An exception as (class, args, attributes): polypore's errors take (field, message) in their
    constructor, which pickle's default (class(*args)) does not call right."""
    return type(exc), exc.args, dict(getattr(exc, "__dict__", {}))


def _rebuilt_error(err: tuple) -> BaseException:
    cls, args, attrs = err
    exc = cls.__new__(cls)
    exc.args = args
    exc.__dict__.update(attrs)
    return exc


def read_only_mapping(d: dict) -> types.MappingProxyType:
    """Rebuilds a pickled ``MappingProxyType`` (see :func:`_dumps`)."""
    return types.MappingProxyType(d)


def _dumps(obj) -> bytes:
    """Pickle with read-only mappings (the mesh's ``types.MappingProxyType`` fields) as themselves."""
    buf = io.BytesIO()
    p = pickle.Pickler(buf, protocol=pickle.HIGHEST_PROTOCOL)
    p.dispatch_table = copyreg.dispatch_table.copy()
    p.dispatch_table[types.MappingProxyType] = lambda m: (read_only_mapping, (dict(m),))
    p.dump(obj)
    return buf.getvalue()


_CONTEXT: Distributed | None = None


def activate() -> Distributed:
    """Start the distributed mode (the CLI does this under mpiexec); InputError when petsc4py or
    mpi4py is missing."""
    global _CONTEXT
    if _CONTEXT is None:
        _CONTEXT = Distributed()
    return _CONTEXT


def deactivate() -> None:
    global _CONTEXT
    _CONTEXT = None


def context() -> Distributed | None:
    """The active :class:`Distributed` context, or None in a serial run."""
    return _CONTEXT
