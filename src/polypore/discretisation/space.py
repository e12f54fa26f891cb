"""The discrete displacement space: node sides + fracture-face bubbles (scheme.md §3).

Scalar unknowns ("slots") are numbered sides first, then bubbles; a vector field is
a (n_slots, d) array and the global degree of freedom of slot a, component i is
``a * d + i``.

* one-sided bubbles (default): one bubble per fracture face σ, held by K_σ^+;
* two-sided bubbles (option): one per side of σ, held by K_σ^+ and K_σ^-.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.ragged import INDEX, Ragged, frozen
from ..mesh import FracturedMesh


class SlotCounts:
    """Sizes and dof numbering shared by the displacement spaces: point slots (node sides, and
    edge sides for P2) first, bubbles after; slot a, component i ↦ dof a·d + i."""

    @property
    def dim(self) -> int:
        return self.fm.mesh.dim

    @property
    def n_sides(self) -> int:
        """Node-side slots (the first slots)."""
        return self.fm.sides.n_sides

    @property
    def n_bubbles(self) -> int:
        return self.bubble_face.size

    @property
    def n_slots(self) -> int:
        return self.n_point_slots + self.n_bubbles

    @property
    def n_dofs(self) -> int:
        return self.dim * self.n_slots

    def dofs(self, slots: np.ndarray, component: int | None = None) -> np.ndarray:
        """Global dofs of the given slots: (k, d), or (k,) for one component."""
        slots = np.asarray(slots, dtype=np.int64)
        d = self.dim
        if component is not None:
            return slots * d + component
        return slots[:, None] * d + np.arange(d)[None, :]


@dataclass(frozen=True, eq=False)
class DisplacementSpace(SlotCounts):
    """Slots of the nodal + bubble space and the local slot lists of every cell.

    Attributes
    ----------
    fm : FracturedMesh
    two_sided : bool
    bubble_face : (n_b,) int32
        Fracture-face index of each bubble.
    bubble_cell : (n_b,) int32
        Cell holding each bubble.
    bubble_sign : (n_b,) int8
        +1 for a + side bubble, -1 for a - side bubble.
    cell_slots : Ragged
        Per cell: its node-side slots (in ``mesh.cell_nodes`` order) then its bubbles.
    cell_n_nodes : (n_cells,) int32
        How many of a cell's slots are nodal (the rest are bubbles).
    """

    fm: FracturedMesh
    two_sided: bool
    bubble_face: np.ndarray
    bubble_cell: np.ndarray
    bubble_sign: np.ndarray
    cell_slots: Ragged
    cell_n_nodes: np.ndarray

    @classmethod
    def build(cls, fm: FracturedMesh, two_sided: bool = False) -> "DisplacementSpace":
        net = fm.network
        nff = net.n_faces
        if two_sided:
            bface = np.concatenate([np.arange(nff), np.arange(nff)])
            bcell = np.concatenate([net.plus_cell, net.minus_cell])
            bsign = np.concatenate([np.ones(nff), -np.ones(nff)])
        else:
            bface, bcell, bsign = np.arange(nff), net.plus_cell, np.ones(nff)
        mesh = fm.mesh
        ns = fm.sides.n_sides
        nc = mesh.n_cells
        cn = mesh.cell_nodes
        # merge nodal slots and bubble slots per cell: order by (cell, kind, position)
        node_cell = cn.rows_of_entries()
        cells = np.concatenate([node_cell, bcell]).astype(np.int64)
        kind = np.concatenate([np.zeros(cn.nnz, np.int8), np.ones(bcell.size, np.int8)])
        slot = np.concatenate([fm.sides.cell_node_side, ns + np.arange(bcell.size)])
        order = np.lexsort((kind, cells))
        counts = np.bincount(cells, minlength=nc)
        return cls(fm, bool(two_sided), frozen(bface.astype(INDEX)), frozen(bcell.astype(INDEX)),
                   frozen(bsign.astype(np.int8)), Ragged.from_counts(counts, slot[order].astype(INDEX)),
                   frozen(cn.counts.astype(INDEX)))

    @property
    def n_point_slots(self) -> int:
        """Slots that are point values (the node sides); the bubbles follow them."""
        return self.n_sides

    def slot_node(self) -> np.ndarray:
        """(n_sides,) node of every side slot."""
        return self.fm.sides.side_node
