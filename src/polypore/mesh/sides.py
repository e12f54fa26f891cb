"""Node sides (scheme.md §3): the nodal displacement unknowns.

For a node s, two cells around s are neighbours when they share a face that
contains s and is not a fracture face; the connected components of that graph are
the sides of s. One graph over all (cell, node) incidences gives every side of
every node in a single connected-components call.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..core.ragged import INDEX, frozen
from .mesh import Mesh


@dataclass(frozen=True, eq=False)
class NodeSides:
    """Sides of every node.

    Attributes
    ----------
    cell_node_side : (nnz(mesh.cell_nodes),) int32
        Side of each (K, s) incidence, aligned with ``mesh.cell_nodes.values``.
    side_node : (n_sides,) int32
        The node of each side.
    """

    cell_node_side: np.ndarray
    side_node: np.ndarray

    @property
    def n_sides(self) -> int:
        return self.side_node.size

    def count_per_node(self, n_nodes: int) -> np.ndarray:
        """(n_nodes,) number of sides of each node."""
        return np.bincount(self.side_node, minlength=n_nodes)

    def nbytes(self) -> int:
        return self.cell_node_side.nbytes + self.side_node.nbytes


def node_sides(mesh: Mesh, fracture_faces: np.ndarray) -> NodeSides:
    """Compute the sides of all nodes once the given faces are cut.

    Sides are numbered node by node and, within a node, by their first (cell, node)
    incidence, so the numbering is reproducible.

    Parameters
    ----------
    fracture_faces : (k,) int
        Mesh faces that are fracture faces (the set F_Γ).
    """
    nn = mesh.n_nodes
    cn = mesh.cell_nodes
    vals = cn.values
    fn = mesh.face_nodes
    fracture_faces = np.asarray(fracture_faces, dtype=np.int64)
    # Only nodes of fracture faces can have several sides: the graph is built on their
    # (cell, node) incidences alone; every other node has one side holding all its cells.
    on_frac = np.zeros(nn, bool)
    on_frac[fn.take(fracture_faces).values] = True
    nsides = np.ones(nn, dtype=INDEX)
    inc = np.flatnonzero(on_frac[vals])
    rank_of_inc = None
    if inc.size:
        keys = cn.rows_of_entries()[inc].astype(np.int64) * nn + vals[inc]
        cut = np.zeros(mesh.n_faces, bool)
        cut[fracture_faces] = True
        touches = np.zeros(mesh.n_faces, bool)
        if fn.nnz:
            touches = np.logical_or.reduceat(on_frac[fn.values], fn.offsets[:-1].astype(np.int64))
        glue = np.flatnonzero((mesh.face_cells[:, 1] >= 0) & ~cut & touches)
        sub = fn.take(glue)
        keep = on_frac[sub.values]
        ent = np.repeat(np.arange(glue.size), sub.counts)[keep]
        nodes = sub.values[keep].astype(np.int64)
        fc = mesh.face_cells[glue[ent]].astype(np.int64)
        a = np.searchsorted(keys, fc[:, 0] * nn + nodes)
        b = np.searchsorted(keys, fc[:, 1] * nn + nodes)
        counts, rank_of_inc = glued_sides(vals[inc], a, b, nn)
        nsides[on_frac] = counts[on_frac]
    side_start = np.zeros(nn + 1, dtype=INDEX)
    np.cumsum(nsides, out=side_start[1:])
    side = side_start[vals]
    if rank_of_inc is not None:
        side[inc] += rank_of_inc
    side_node = np.repeat(np.arange(nn, dtype=INDEX), nsides)
    return NodeSides(frozen(side.astype(INDEX)), frozen(side_node))


def glued_sides(entity: np.ndarray, a: np.ndarray, b: np.ndarray, n_entities: int):
    """Sides of mesh entities (nodes, edges) from their (cell, entity) incidences.

    Incidence i belongs to ``entity[i]``; pairs (a[k], b[k]) glue two incidences of one entity
    across a face that is not a fracture face. The connected components are the sides; an
    entity's sides are ranked by their first (lowest) incidence, so the numbering is reproducible.

    Returns
    -------
    counts : (n_entities,) int
        Sides per entity (0 for an entity without incidences).
    rank : (len(entity),) int32
        Rank of each incidence's side among its entity's sides.
    """
    n = entity.size
    graph = sp.coo_array((np.ones(a.size, dtype=np.int8), (a, b)), shape=(n, n)).tocsr()
    n_loc, local = connected_components(graph, directed=False)
    first = np.full(n_loc, n, dtype=np.int64)
    np.minimum.at(first, local, np.arange(n))
    comp = entity[first]
    order = np.lexsort((first, comp))
    sorted_comp = comp[order]
    head = np.concatenate([[True], sorted_comp[1:] != sorted_comp[:-1]])
    start = np.maximum.accumulate(np.where(head, np.arange(n_loc), 0))
    rank = np.empty(n_loc, dtype=INDEX)
    rank[order] = np.arange(n_loc) - start
    return np.bincount(comp, minlength=n_entities), rank[local]
