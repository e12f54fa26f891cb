"""Cell sides on pillar pairs: lines, strips, voids, and the pairs of strips that may overlap.

On a pillar pair (the two pillars shared by two laterally adjacent columns) every cell side is
a strip between two *lines*, its top and bottom edges; a line joins a node on each pillar.
Pillar pairs: i pairs (i, j) -> i·ny + j, then j pairs (i, j) -> (nx+1)·ny + i·(ny+1) + j.
Each pair has two roles: A, the column on its −i / −j side (whose east / north side lies on
it), and B, the column on its +i / +j side. Per (pair, role) the strips are the cell sides,
sorted down the column, and the voids between them: above the top cell, gaps between cells,
below the bottom cell, or the whole pair when the column has no kept cell (sentinel lines
above and below everything). Everything is sorting and grouping: no loop over pillars,
cells or faces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BIG = 1.0e30                     # depth of the sentinel lines above / below every column
CELL, ABOVE, INNER, BELOW, EMPTY = 0, 1, 2, 3, 4          # kinds of strips
W, E, S, N = 0, 1, 2, 3          # cell sides: i-min, i-max, j-min, j-max


@dataclass(frozen=True, eq=False)
class Lines:
    """The unique lines (NL of them, then the two sentinels NL, NL + 1) and the cells' sides."""

    LT: np.ndarray       # (nc, 4) top line of every cell side (W, E, S, N)
    LB: np.ndarray       # (nc, 4) bottom line
    ln0: np.ndarray      # (NL,) node at s = 0 (first pillar of the pair)
    ln1: np.ndarray      # (NL,) node at s = 1
    Z0: np.ndarray       # (NL + 2,) depth at s = 0, sentinels ∓BIG
    Z1: np.ndarray       # (NL + 2,) depth at s = 1
    N0: np.ndarray       # (NL + 2,) node at s = 0, −1 for the sentinels
    N1: np.ndarray

    @property
    def NL(self) -> int:
        return self.ln0.size


S0 = ((0, 0), (1, 0), (0, 0), (0, 1))      # corner (di, dj) at s = 0 of the sides W, E, S, N
S1 = ((0, 1), (1, 1), (1, 0), (1, 1))      # at s = 1


def side_nodes(nid, cells, sides):
    """(k, 4) nodes (top s=0, top s=1, bottom s=0, bottom s=1) of the given cell sides."""
    d0 = np.array(S0)[sides]
    d1 = np.array(S1)[sides]
    return np.stack([nid[cells, d0[:, 0], d0[:, 1], 0], nid[cells, d1[:, 0], d1[:, 1], 0],
                     nid[cells, d0[:, 0], d0[:, 1], 1], nid[cells, d1[:, 0], d1[:, 1], 1]], 1)


def side_pairs(ci, cj, nx, ny):
    """(nc, 4) pillar pair of every cell side W, E, S, N."""
    NI = (nx + 1) * ny
    return np.stack([ci * ny + cj, (ci + 1) * ny + cj, NI + ci * (ny + 1) + cj, NI + ci * (ny + 1) + cj + 1], 1)


def make_lines(Q, NT, NB, node_rank, R, node_z) -> Lines:
    """The unique lines of the cells' sides (Q: (nc, 4) pairs of the sides W, E, S, N; NT, NB:
    (nc, di, dj) top / bottom corner nodes; node_rank: rank of a node on its pillar, < R)."""
    n0 = np.concatenate([np.stack([NT[:, a, b] for a, b in S0], 1), np.stack([NB[:, a, b] for a, b in S0], 1)], 1)
    n1 = np.concatenate([np.stack([NT[:, a, b] for a, b in S1], 1), np.stack([NB[:, a, b] for a, b in S1], 1)], 1)
    key = (np.concatenate([Q, Q], 1).astype(np.int64) * R + node_rank[n0]) * R + node_rank[n1]
    _, first, inv = np.unique(key, return_index=True, return_inverse=True)
    lid = inv.reshape(key.shape)
    ln0, ln1 = n0.ravel()[first], n1.ravel()[first]
    return Lines(LT=lid[:, :4], LB=lid[:, 4:], ln0=ln0, ln1=ln1,
                 Z0=np.concatenate([node_z[ln0], [-BIG, BIG]]), Z1=np.concatenate([node_z[ln1], [-BIG, BIG]]),
                 N0=np.concatenate([ln0, [-1, -1]]), N1=np.concatenate([ln1, [-1, -1]]))


@dataclass(frozen=True, eq=False)
class Strips:
    """Every strip (cell side or void) per (pair, role), sorted by pair, role, then depth."""

    q: np.ndarray        # pillar pair
    isB: np.ndarray      # role B (the column on the +i / +j side of the pair)
    top: np.ndarray      # top line
    bot: np.ndarray      # bottom line
    cell: np.ndarray     # cell, −1 for a void
    kind: np.ndarray     # CELL, ABOVE, INNER, BELOW or EMPTY
    k0: np.ndarray       # layers of a void (k0 > k1: a gap without missing cells), of a cell its k
    k1: np.ndarray


def strips(Q, LT, LB, ck, NL: int, NQ: int, nz: int) -> Strips:
    """The strips of all (pair, role) groups: cell sides and the voids around them."""
    nc = ck.size
    ST, SB = NL, NL + 1                                      # sentinel lines
    role = np.array([1, 0, 1, 0])                            # west/south sides are role B (1)
    g = (Q * 2 + role).ravel()
    kk = np.repeat(ck, 4)
    order = np.lexsort((kk, g))
    gs, ks = g[order], kk[order]
    cs = np.repeat(np.arange(nc), 4)[order]
    ts, bs = LT.ravel()[order], LB.ravel()[order]
    del order, g, kk
    head = np.ones(gs.size, bool)
    head[1:] = gs[1:] != gs[:-1]
    tail = np.ones(gs.size, bool)
    tail[:-1] = head[1:]
    inner = ~head.copy()
    inner[1:] &= bs[:-1] != ts[1:]
    inner_idx = np.flatnonzero(inner)
    empty_g = np.setdiff1d(np.arange(2 * NQ), gs[head])
    nh, nt, ne = int(head.sum()), int(tail.sum()), empty_g.size
    rg = np.concatenate([gs, gs[head], gs[inner_idx], gs[tail], empty_g])
    rord = np.concatenate([2 * ks, 2 * ks[head] - 1, 2 * ks[inner_idx] - 1, 2 * ks[tail] + 1, np.zeros(ne, np.int64)])
    rtop = np.concatenate([ts, np.full(nh, ST), bs[inner_idx - 1], bs[tail], np.full(ne, ST)])
    rbot = np.concatenate([bs, ts[head], ts[inner_idx], np.full(nt, SB), np.full(ne, SB)])
    rcell = np.concatenate([cs, np.full(nh + inner_idx.size + nt + ne, -1)])
    rkind = np.concatenate([np.full(cs.size, CELL), np.full(nh, ABOVE), np.full(inner_idx.size, INNER),
                            np.full(nt, BELOW), np.full(ne, EMPTY)]).astype(np.int8)
    rk0 = np.concatenate([ks, np.zeros(nh, np.int64), ks[inner_idx - 1] + 1, ks[tail] + 1, np.full(ne, -1)])
    rk1 = np.concatenate([ks, ks[head] - 1, ks[inner_idx] - 1, np.full(nt, nz - 1), np.full(ne, -1)])
    del gs, ks, cs, ts, bs, head, tail, inner, inner_idx
    o = np.lexsort((rord, rg))
    rg = rg[o]
    return Strips(q=rg // 2, isB=(rg % 2).astype(bool), top=rtop[o], bot=rbot[o], cell=rcell[o], kind=rkind[o],
                  k0=rk0[o], k1=rk1[o])


def overlapping_pairs(st: Strips, Z0, Z1, zlo: float, zhi: float):
    """Candidate pairs (a, b) of strips, a of role A and b of role B on the same pillar pair,
    at least one a cell, both of positive thickness somewhere, that overlap with positive area.

    Candidates come from sorting the strips by pair and depth range (one searchsorted); the
    final test is exact: strips lying on one side of each other at both pillars (touching at
    most) have no overlap of positive area, the others do.
    """
    A = np.flatnonzero(~st.isB)
    B = np.flatnonzero(st.isB)
    scale = 0.5 / max(zhi - zlo, 1e-300)

    def key(q, z):
        return q + 0.25 + (np.clip(z, zlo, zhi) - zlo) * scale

    rq, rtop, rbot = st.q, st.top, st.bot
    rzmin = np.minimum(Z0[rtop], Z1[rtop])
    rzmax = np.maximum(Z0[rbot], Z1[rbot])
    pad = 1e-7
    lo = np.searchsorted(key(rq[B], rzmax[B]), key(rq[A], rzmin[A]) - pad, side="right")
    hi = np.searchsorted(key(rq[B], rzmin[B]), key(rq[A], rzmax[A]) + pad, side="left")
    cnt = np.maximum(hi - lo, 0)
    ca = np.repeat(A, cnt)
    cb = B[np.repeat(lo - np.cumsum(cnt) + cnt, cnt) + np.arange(cnt.sum())]
    del lo, hi, cnt, rzmin, rzmax
    # a cell side of zero thickness at both pillars (top line = bottom line) has no face
    keep = ((st.cell[ca] >= 0) | (st.cell[cb] >= 0)) & (rq[ca] == rq[cb]) & (rtop[ca] != rbot[ca]) \
        & (rtop[cb] != rbot[cb])
    ca, cb = ca[keep], cb[keep]
    tA, bA, tB, bB = rtop[ca], rbot[ca], rtop[cb], rbot[cb]
    below = (Z0[tA] >= Z0[bB]) & (Z1[tA] >= Z1[bB])
    above = (Z0[bA] <= Z0[tB]) & (Z1[bA] <= Z1[tB])
    keep = ~(below | above)
    return ca[keep], cb[keep]
