"""The discrete displacement space: node sides + fracture-face bubbles (scheme.md §3).

Scalar unknowns ("slots") are numbered sides first, then bubbles; a vector field is
a (n_slots, d) array and the global degree of freedom of slot a, component i is
``a * d + i``.

* one-sided bubbles (default): one bubble per fracture face σ, held by K_σ^+ (or, with side
  "regular", by the cell of which σ is the more regular face: :func:`bubble_sides`);
* two-sided bubbles (option): one per side of σ, held by K_σ^+ and K_σ^-.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.ragged import INDEX, Ragged, frozen
from ..mesh import FracturedMesh
from .contact_patches import side_cross_sections


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


# a one-sided bubble moves to the − cell only where that cell's cross-section normal to the face
# is this many times smaller than the + cell's: faces regular on both sides keep the + side
REGULAR_MARGIN = 2.0


def bubble_sides(fm: FracturedMesh, side: str = "regular") -> np.ndarray:
    """(n_ff,) +1 / −1: the side holding each fracture face's one-sided bubble.

    "regular" puts it in the cell whose cross-section A_K normal to σ is the smaller (the cell
    of which σ is the more regular face). Why: the bubble's stabilisation weight |σ|²/|K|
    (:func:`~polypore.assembly.elasticity.elasticity_matrix`) is what resists the face's own slip
    mode; in a cell that is large across the fault a sliver's bubble is |K|/|σ|² soft and slips
    tens of times more than its neighbours (docs/contact_patches.md, "The bubble's cell"), while in the
    cell of which it is a regular face it is as stiff as any regular face's."""
    nff = fm.network.n_faces
    if side == "plus":
        return np.ones(nff, np.int8)
    if side != "regular":
        raise ValueError(f"side must be 'plus' or 'regular', got {side!r}")
    a = side_cross_sections(fm)
    return np.where(REGULAR_MARGIN * a[1] < a[0], -1, 1).astype(np.int8)


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
    def build(cls, fm: FracturedMesh, two_sided: bool = False, side: str = "regular") -> "DisplacementSpace":
        """The space of ``fm``.

        Parameters
        ----------
        two_sided : one bubble on each side of every fracture face
        side : for one-sided bubbles, "regular" (default): the cell in which σ is the more
            regular face, the − cell where its cross-section normal to σ is less than
            1/:data:`REGULAR_MARGIN` of the + cell's (:func:`bubble_sides`); or "plus", the scheme's
            + side cell.
        """
        net = fm.network
        nff = net.n_faces
        if two_sided:
            bface = np.concatenate([np.arange(nff), np.arange(nff)])
            bcell = np.concatenate([net.plus_cell, net.minus_cell])
            bsign = np.concatenate([np.ones(nff), -np.ones(nff)])
        else:
            bsign = bubble_sides(fm, side)
            bface, bcell = np.arange(nff), np.where(bsign > 0, net.plus_cell, net.minus_cell)
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
