"""Cell permeability tensors from PERMX, PERMY, PERMZ (mD) and NTG."""

from __future__ import annotations

import numpy as np

from ...core.errors import InputError
from .info import CornerPointInfo
from .pillars import pillar_points
from .reader import CornerPointGrid

MILLIDARCY = 9.869233e-16      # m²


def cell_permeability(grid: CornerPointGrid, info: CornerPointInfo, *, apply_mapaxes: bool = True,
                      ntg: bool = True) -> np.ndarray:
    """(n_c, 3, 3) permeability tensors in m² from PERMX, PERMY, PERMZ (mD).

    The tensor is diag(PERMX, PERMY, PERMZ) in the frame of the cell's column: e_i along the
    mean direction of its i edges (map x, y, horizontal), e_j orthogonal to it in the
    horizontal plane on the side of the j edges, e_z vertical; PERMY defaults to PERMX and
    PERMZ to PERMX too when absent. With ``ntg`` the horizontal values are multiplied by NTG
    (as Eclipse does for transmissibilities). Dip is not followed (fine for gentle dips).
    """
    if "PERMX" not in grid.properties:
        raise InputError(f"{grid.source}:PERMX", "missing: the permeability needs PERMX (mD)")
    kx = info.cell_values(grid.properties["PERMX"])
    ky = info.cell_values(grid.properties["PERMY"]) if "PERMY" in grid.properties else kx
    kz = info.cell_values(grid.properties["PERMZ"]) if "PERMZ" in grid.properties else kx
    if ntg and "NTG" in grid.properties:
        f = info.cell_values(grid.properties["NTG"])
        kx, ky = kx * f, ky * f
    vals = np.stack([kx, ky, kz], 1) * MILLIDARCY
    if np.any(vals < 0) or not np.all(np.isfinite(vals)):
        raise InputError(f"{grid.source}:PERMX", "permeabilities must be finite and ≥ 0")
    nx, ny, _ = grid.dims
    top, bot = pillar_points(grid, apply_mapaxes)
    P = (0.5 * (top[:, :2] + bot[:, :2])).reshape(nx + 1, ny + 1, 2)
    i, j = info.cell_ijk[:, 0], info.cell_ijk[:, 1]
    ei = 0.5 * (P[i + 1, j] - P[i, j] + P[i + 1, j + 1] - P[i, j + 1])
    ej = 0.5 * (P[i, j + 1] - P[i, j] + P[i + 1, j + 1] - P[i + 1, j])
    ei /= np.maximum(np.linalg.norm(ei, axis=1), 1e-300)[:, None]
    perp = np.stack([-ei[:, 1], ei[:, 0]], 1)
    ej = perp * np.where(np.einsum("ki,ki->k", perp, ej) >= 0, 1.0, -1.0)[:, None]
    R = np.zeros((i.size, 3, 3))
    R[:, :2, 0], R[:, :2, 1], R[:, 2, 2] = ei, ej, 1.0
    return np.einsum("kab,kb,kcb->kac", R, vals, R)
