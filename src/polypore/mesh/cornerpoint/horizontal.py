"""Top and bottom faces: the cells' (bilinear) quadrilaterals, shared by vertically consecutive
cells whose four corners coincide (pinched-out layers between them included, which were
dropped: Eclipse's PINCH), otherwise boundary faces of the void between them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .strips import E, N, S, W


@dataclass(frozen=True, eq=False)
class HorizontalFaces:
    """Top faces of the cells whose top is not shared (``top_cells``), then every cell's bottom."""

    top_cells: np.ndarray   # (t,) cells whose top face is not the bottom face of the cell above
    nb_next: np.ndarray     # (nc,) the cell below sharing a cell's bottom face, −1 if none
    is_top: np.ndarray      # (nc,) topmost kept cell of its column
    is_bottom: np.ndarray   # (nc,) bottommost kept cell of its column
    node: np.ndarray        # (4 (t + nc),) loop vertices: corners (0,0), (1,0), (1,1), (0,1)
    carrier: np.ndarray     # (4 (t + nc),) the line (side S, E, N, W) from each vertex to the next

    @property
    def n(self) -> int:
        return self.top_cells.size + self.nb_next.size


def horizontal_faces(ci, cj, ck, ny, NT, NB, LT, LB) -> HorizontalFaces:
    nc = ci.size
    col = ci * ny + cj
    corder = np.lexsort((ck, col))
    same_col = col[corder][1:] == col[corder][:-1]
    nb_next = np.full(nc, -1)
    up, dn = corder[:-1], corder[1:]
    sh = same_col & (NB[up] == NT[dn]).all(axis=(1, 2))
    nb_next[up[sh]] = dn[sh]
    is_top = np.ones(nc, bool)
    is_top[dn[same_col]] = False
    is_bottom = np.ones(nc, bool)
    is_bottom[up[same_col]] = False
    covered = np.zeros(nc, bool)                             # top shared with the cell above
    covered[dn[sh]] = True
    top_cells = np.flatnonzero(~covered)
    corners = [(0, 0), (1, 0), (1, 1), (0, 1)]
    sides = [S, E, N, W]

    def loops(cells, Nn, L):
        v = np.stack([Nn[cells, a, b] for a, b in corners], 1)
        c = np.stack([L[cells, s_] for s_ in sides], 1)
        return v.ravel(), c.ravel()
    v_t, c_t = loops(top_cells, NT, LT)
    v_b, c_b = loops(np.arange(nc), NB, LB)
    return HorizontalFaces(top_cells=top_cells, nb_next=nb_next, is_top=is_top, is_bottom=is_bottom,
                           node=np.concatenate([v_t, v_b]), carrier=np.concatenate([c_t, c_b]))
