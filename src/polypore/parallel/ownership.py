"""Which cells a rank owns and which it sees as ghosts: the ownership notion of the mesh.

Every rank holds the whole mesh today (docs/parallel.md), so the owned cells are the rank's part
of the partition and the ghosts are the cells of other ranks that share a face with one of them
(the layer a face-based discretisation reads). A distributed mesh would hold the owned and ghost
cells only and fill the same object; the models ask for ``owner`` (the rank of every cell they
hold) and nothing else, so they would not change.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class CellOwnership:
    """Ownership of a mesh's cells on one rank.

    Attributes
    ----------
    rank : this rank;  size : ranks in the run
    owner : (n_cells,) int32 rank owning each cell
    owned : (n_cells,) bool, cells of this rank
    ghost : (n_cells,) bool, cells of other ranks sharing a face with an owned cell
    """

    rank: int
    size: int
    owner: np.ndarray
    owned: np.ndarray
    ghost: np.ndarray

    @classmethod
    def of(cls, mesh, owner: np.ndarray, rank: int, size: int) -> "CellOwnership":
        """The ownership on ``rank`` of the partition ``owner`` (n_cells,) of ``mesh``."""
        owner = np.asarray(owner, np.int32)
        if owner.shape != (mesh.n_cells,):
            raise ValueError(f"owner has shape {owner.shape}, the mesh has {mesh.n_cells} cells")
        owned = owner == rank
        K, L = np.asarray(mesh.face_cells, np.int64).T
        inner = (K >= 0) & (L >= 0)
        K, L = K[inner], L[inner]
        ghost = np.zeros(mesh.n_cells, bool)
        ghost[L[owned[K] & ~owned[L]]] = True
        ghost[K[owned[L] & ~owned[K]]] = True
        return cls(int(rank), int(size), owner, owned, ghost)

    @classmethod
    def serial(cls, mesh) -> "CellOwnership":
        """One rank owns every cell; no ghosts."""
        return cls.of(mesh, np.zeros(mesh.n_cells, np.int32), 0, 1)


def cell_ownership(mesh) -> CellOwnership:
    """The ownership of ``mesh``'s cells on this rank: the run's partition under ``mpiexec``
    (:meth:`.context.Distributed.partition`), every cell owned when serial."""
    from .context import context

    ctx = context()
    if ctx is None:
        return CellOwnership.serial(mesh)
    return CellOwnership.of(mesh, ctx.partition(mesh), ctx.rank, ctx.size)
