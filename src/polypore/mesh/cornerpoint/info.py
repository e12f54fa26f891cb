"""What a processed mesh keeps of its corner-point grid (:class:`CornerPointInfo`) and the
face and boundary labels shared by the processor's stages."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ...core.errors import InputError
from ...core.ragged import INDEX

FACE_I, FACE_J, FACE_K = 0, 1, 2          # info.face_kind: lateral on an i pair, on a j pair; top / bottom
BOUNDARY_NAMES = ("west", "east", "south", "north", "top", "bottom", "internal")


@dataclass(frozen=True, eq=False)
class CornerPointInfo:
    """What the processed mesh keeps of its corner-point grid.

    Attributes (n_c mesh cells, n_f mesh faces)
    ------------------------------------------
    dims : (nx, ny, nz)
    origin : (2,) float64, m
        Map x, y of the mesh's origin (map coordinates = mesh coordinates + origin).
    cell_ijk : (n_c, 3) int32
        0-based (i, j, k) of every mesh cell.
    cell_index : (n_c,) int32
        Natural (Eclipse) index i + nx (j + ny k) of every mesh cell.
    face_kind : (n_f,) int8
        0: lateral face between i-neighbours (on an i pillar pair), 1: between j-neighbours,
        2: top / bottom face.
    face_pair : (n_f,) int32
        Pillar pair of lateral faces (i pairs (i, j) -> i·ny + j, then j pairs (i, j) ->
        (nx+1)·ny + i·(ny+1) + j), −1 for top / bottom faces.
    face_displaced : (n_f,) bool
        Interior lateral faces whose two cells' corners do not coincide (fault faces), before
        snapping (``snap``: a fault keeps the faces whose corners snapping made coincide).
    boundary : mapping name -> (k,) int32
        ``west``, ``east``, ``south``, ``north``: lateral faces towards −i, +i, −j, +j whose
        void is open to that side of the grid (no kept cell beyond them along their row or
        column in the void's layers); ``top``, ``bottom``: top / bottom faces of the columns'
        extreme cells and the fault scarps exposed above / below the neighbouring column;
        ``internal``: the other voids (holes of inactive cells, vertical gaps). They
        partition the boundary faces.
    faults : mapping name -> (k,) int32
        Fault faces (see :mod:`.faults`): named from FAULTS, else ``fault_1``, ``fault_2``...
    handedness : str
        ``"right"`` if (i, j, up) is a right-handed frame in the output coordinates.
    ztol : float
        Depth tolerance used to merge corner depths on a pillar (m).
    n_active, n_collapsed : int
        Active cells in the grid; active cells dropped as collapsed (zero thickness).
    snap : float
        Relative depth tolerance of the snapping of nearly coincident corners (``process_grid``).
    n_snapped : int
        Pillar nodes merged into a neighbour by that snapping.
    seconds : mapping stage -> s
        Processing time per stage: ``nodes`` (corner depths, pillar nodes), ``faces``
        (lines, overlaps, edge insertion, splitting), ``mesh`` (topology checks and
        geometry), ``faults``.
    """

    dims: tuple
    origin: np.ndarray
    cell_ijk: np.ndarray
    cell_index: np.ndarray
    face_kind: np.ndarray
    face_pair: np.ndarray
    face_displaced: np.ndarray
    boundary: Mapping[str, np.ndarray]
    faults: Mapping[str, np.ndarray] = field(default_factory=dict)
    handedness: str = "right"
    ztol: float = 0.0
    n_active: int = 0
    n_collapsed: int = 0
    snap: float = 0.0
    n_snapped: int = 0
    seconds: Mapping[str, float] = field(default_factory=dict)

    def cell_values(self, values: np.ndarray) -> np.ndarray:
        """Per-mesh-cell values of an (nx, ny, nz) array, e.g. ``grid.properties["PORO"]``."""
        values = np.asarray(values)
        if values.shape[:3] != tuple(self.dims):
            raise InputError("cell_values", f"expected an array of shape {tuple(self.dims)}, got {values.shape}")
        i, j, k = self.cell_ijk.T
        return values[i, j, k]

    def cell_name(self, cell: int) -> str:
        """"(i, j, k)" of mesh cell ``cell``, 1-based as in the GRDECL file (for messages)."""
        i, j, k = (int(a) + 1 for a in self.cell_ijk[cell])
        return f"({i}, {j}, {k})"

    def cells_in(self, i=None, j=None, k=None) -> np.ndarray:
        """(m,) int32 mesh cells whose 0-based (i, j, k) lie in the given ranges.

        Each of i, j, k is None (all), an int or an inclusive (first, last) pair; e.g. a
        vertical well through column (10, 12) in layers 3 to 7: ``cells_in(10, 12, (3, 7))``.
        """
        keep = np.ones(self.cell_ijk.shape[0], bool)
        for axis, r in enumerate((i, j, k)):
            if r is None:
                continue
            lo, hi = (r, r) if np.isscalar(r) else (int(r[0]), int(r[1]))
            keep &= (self.cell_ijk[:, axis] >= lo) & (self.cell_ijk[:, axis] <= hi)
        return np.flatnonzero(keep).astype(INDEX)
