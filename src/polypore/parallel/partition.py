"""Cell partitions for distributed runs (docs/parallel.md): METIS on the cell graph via pymetis.

Two cells are neighbours when they share a face (fracture faces included: the bubbles and
multipliers of a fracture face couple its two cells). pymetis is the extra ``polypore[mpi]``;
one part needs nothing.
"""

from __future__ import annotations

import numpy as np

from ..core.errors import InputError


def cell_graph(mesh) -> tuple[np.ndarray, np.ndarray]:
    """The cell adjacency in METIS's CSR form.

    Returns
    -------
    xadj : (n_cells + 1,) int64, offsets into adjncy
    adjncy : (2 n_interior_faces,) int64, the neighbour cells of each cell (one entry per shared face)
    """
    K, L = np.asarray(mesh.face_cells, np.int64).T
    inner = (K >= 0) & (L >= 0) & (K != L)
    K, L = K[inner], L[inner]
    rows = np.concatenate([K, L])
    cols = np.concatenate([L, K])
    order = np.argsort(rows, kind="stable")
    xadj = np.zeros(mesh.n_cells + 1, np.int64)
    np.cumsum(np.bincount(rows, minlength=mesh.n_cells), out=xadj[1:])
    return xadj, cols[order]


def partition_cells(mesh, n_parts: int) -> np.ndarray:
    """(n_cells,) int32 part (rank) of every cell: METIS k-way on :func:`cell_graph`, balanced
    cell counts. Deterministic for a given mesh (METIS's fixed seed)."""
    n_parts = int(n_parts)
    if n_parts <= 1:
        return np.zeros(mesh.n_cells, np.int32)
    if mesh.n_cells < n_parts:
        raise InputError("mpiexec -n", f"{n_parts} ranks for {mesh.n_cells} cells: use fewer ranks")
    try:
        import pymetis
    except ImportError:
        raise InputError("mpiexec", "partitioning the mesh needs pymetis: pip install 'polypore[mpi]' "
                         "(docs/parallel.md)") from None
    xadj, adjncy = cell_graph(mesh)
    _, parts = pymetis.part_graph(n_parts, xadj=xadj, adjncy=adjncy)
    parts = np.asarray(parts, np.int32)
    if np.bincount(parts, minlength=n_parts).min() == 0:
        raise InputError("mpiexec -n", f"METIS left a rank without cells ({n_parts} ranks, {mesh.n_cells} cells)")
    return parts
