"""Boundary parts of a processed corner-point grid (``west`` ... ``internal``, BOUNDARY_NAMES).

A lateral face towards a void is on the west (east, south, north) side when no kept cell lies
beyond it in the void's layers along its row (column): the void is open to that side of the
grid (missing columns, inactive cells at the edge); otherwise the void is inside (a hole:
``internal``). Voids above / below the neighbouring column's cells: ``top`` / ``bottom``.
Top faces of the topmost kept cells are ``top``, bottom faces of the bottommost ``bottom``;
the others (vertical gaps) ``internal``.
"""

from __future__ import annotations

import numpy as np

from .horizontal import HorizontalFaces
from .strips import ABOVE, BELOW, EMPTY, Strips

TOP, BOTTOM, INTERNAL = 4, 5, 6            # indices in BOUNDARY_NAMES (west, east, south, north: 0..3)


def boundary_groups(st: Strips, ca, cb, pair_i, hz: HorizontalFaces, ci, cj, ck, dims) -> np.ndarray:
    """(nL + nH,) index in BOUNDARY_NAMES of every boundary face, −1 for interior faces.

    Lateral faces first (strip pairs ``ca`` (role A), ``cb`` (role B) on pairs with ``pair_i``),
    then the top and bottom faces of ``hz``.
    """
    nx, ny, nz = dims
    nL = ca.size
    group = np.full(nL + hz.n, -1, np.int8)
    first_ik = np.full((ny, nz), nx)
    last_ik = np.full((ny, nz), -1)
    first_jk = np.full((nx, nz), ny)
    last_jk = np.full((nx, nz), -1)
    np.minimum.at(first_ik, (cj, ck), ci)
    np.maximum.at(last_ik, (cj, ck), ci)
    np.minimum.at(first_jk, (ci, ck), cj)
    np.maximum.at(last_jk, (ci, ck), cj)
    cA, cB = st.cell[ca], st.cell[cb]
    bl = np.flatnonzero((cA < 0) | (cB < 0))
    on_A = cA[bl] >= 0                                       # the cell is A's: the void lies on the +i / +j side
    void = np.where(on_A, cb[bl], ca[bl])
    cell = np.where(on_A, cA[bl], cB[bl])
    kind_v = st.kind[void]
    li, lj, lk = ci[cell], cj[cell], ck[cell]
    k0 = np.where(kind_v == EMPTY, lk, st.k0[void])
    k1 = np.where(kind_v == EMPTY, lk, st.k1[void])
    is_i = pair_i[bl]

    def range_ext(table, row, fn, fill):
        """fn (min or max) of table[row, k0..k1] per face (fill where the range is empty)."""
        flat = np.append(table.ravel(), fill)
        s = row * nz + np.clip(k0, 0, nz - 1)
        e = row * nz + np.clip(k1, 0, nz - 1) + 1
        ok = k1 >= k0
        idx = np.stack([np.where(ok, s, flat.size - 1), np.where(ok, e, flat.size - 1)], 1).ravel()
        out = fn.reduceat(flat, np.minimum(idx, flat.size - 1))[0::2]
        return np.where(ok, out, fill)
    open_w = range_ext(first_ik, lj, np.minimum, -1) >= li
    open_e = range_ext(last_ik, lj, np.maximum, nx) <= li
    open_s = range_ext(first_jk, li, np.minimum, -1) >= lj
    open_n = range_ext(last_jk, li, np.maximum, ny) <= lj
    side = np.where(is_i, np.where(on_A, np.where(open_e, 1, INTERNAL), np.where(open_w, 0, INTERNAL)),
                    np.where(on_A, np.where(open_n, 3, INTERNAL), np.where(open_s, 2, INTERNAL)))
    group[bl] = np.select([kind_v == ABOVE, kind_v == BELOW], [TOP, BOTTOM], side)
    nt = hz.top_cells.size
    group[nL:nL + nt] = np.where(hz.is_top[hz.top_cells], TOP, INTERNAL)
    hb = hz.nb_next < 0
    group[nL + nt:][hb] = np.where(hz.is_bottom[hb], BOTTOM, INTERNAL)
    return group
