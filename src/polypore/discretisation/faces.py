"""Face-based operators of the displacement space: face means from one side, side lookup."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .space import DisplacementSpace


def side_slots(space: DisplacementSpace, cells: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Side slot v_{Ks} of each (cell K, node s) pair; s must be a node of K. Shapes (k,)."""
    mesh = space.fm.mesh
    cn = mesh.cell_nodes
    nn = mesh.n_nodes
    keys = cn.rows_of_entries().astype(np.int64) * nn + cn.values
    want = np.asarray(cells, np.int64) * nn + np.asarray(nodes, np.int64)
    pos = np.searchsorted(keys, want)
    if np.any(pos >= keys.size) or np.any(keys[np.minimum(pos, keys.size - 1)] != want):
        raise ValueError("side_slots: a node is not a node of the given cell")
    return space.fm.sides.cell_node_side[pos]


def face_entries(space: DisplacementSpace, faces: np.ndarray, cells: np.ndarray | None = None):
    """Per (face, node) entries of the given faces seen from ``cells`` (default: face_cells[:, 0]).

    Returns
    -------
    row : (m,) index into ``faces`` of each entry
    node : (m,) node id
    slot : (m,) side slot of (cell, node)
    weight : (m,) ω_s^σ
    """
    mesh = space.fm.mesh
    fn = mesh.face_nodes
    faces = np.asarray(faces, np.int64)
    if cells is None:
        cells = mesh.face_cells[faces, 0]
    sub = fn.take(faces)
    row = sub.rows_of_entries()
    wpos = np.repeat(fn.offsets[faces], sub.counts) + (np.arange(sub.nnz) - np.repeat(sub.offsets[:-1], sub.counts))
    node = sub.values
    slot = side_slots(space, np.repeat(np.asarray(cells, np.int64), sub.counts), node)
    return row, node, slot, mesh.geometry.face_node_weight[wpos]


def face_mean_operator(space: DisplacementSpace, faces: np.ndarray, cells: np.ndarray | None = None) -> sp.csr_array:
    """(len(faces), n_slots): v ↦ v̄_{Kσ} = Σ_s ω_s^σ v_{Ks} (scheme.md §3, face mean from K)."""
    row, _, slot, w = face_entries(space, faces, cells)
    return sp.csr_array((w, (row, slot)), shape=(len(faces), space.n_slots))
