"""Overlaps of two strips on a pillar pair: the lateral faces, their crossing nodes and the
carrier (line or pillar) of every edge.

In the plane (position s along the pair, depth) a strip is the region between its top and
bottom lines; the overlap of a strip of role A with one of role B is a convex polygon with at
most 8 vertices (nodes on the pillars, crossings of two lines, pinches), computed for all
candidate pairs at once. The crossing of two lines is computed once, from the canonical
(sorted) pair of lines, and is one node for all the faces touching it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.ragged import INDEX
from .strips import Lines, Strips


def _cross(L, M, Z0, Z1):
    """Crossing of lines L and M strictly between the pillars, computed from the ordered pair."""
    a, b = np.minimum(L, M), np.maximum(L, M)
    a0, a1, b0, b1 = Z0[a], Z1[a], Z0[b], Z1[b]
    d0, d1 = a0 - b0, a1 - b1
    ok = ((d0 < 0) & (d1 > 0)) | ((d0 > 0) & (d1 < 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(ok, d0 / np.where(ok, d0 - d1, 1.0), 0.5)
    return ok, s, a0 + s * (a1 - a0), a, b


def _at(L, s, Z0, Z1):
    return Z0[L] + s * (Z1[L] - Z0[L])


@dataclass(frozen=True, eq=False)
class LateralFaces:
    """Lateral faces (overlaps of positive area), their loops in slot order and the crossings."""

    ca: np.ndarray        # (nL,) strip of role A, of role B
    cb: np.ndarray
    pq: np.ndarray        # (nL,) pillar pair
    face: np.ndarray      # (e,) face of every loop vertex (faces in order, vertices in loop order)
    node: np.ndarray      # (e,) node of every loop vertex (pillar nodes, then crossings n_pnodes + x)
    carrier: np.ndarray   # (e,) line (< NL) or NL + pillar along which the edge to the next vertex runs
    x_s: np.ndarray       # (n_x,) crossings: position along the pair, depth, the two lines (x_a < x_b), pair
    x_z: np.ndarray
    x_a: np.ndarray
    x_b: np.ndarray
    x_q: np.ndarray


def pair_pillars(pq, nx, ny):
    """Pillars at s = 0 and s = 1 of pillar pairs pq, and whether they are i pairs."""
    NI = (nx + 1) * ny
    pair_i = pq < NI
    qi = np.where(pair_i, pq // ny, (pq - NI) // (ny + 1))
    qj = np.where(pair_i, pq % ny, (pq - NI) % (ny + 1))
    p0 = qi * (ny + 1) + qj
    return p0, np.where(pair_i, p0 + 1, p0 + ny + 1), pair_i


def lateral_faces(st: Strips, ca, cb, L: Lines, n_pnodes: int, nx: int, ny: int) -> LateralFaces:
    """The overlap polygons of the candidate strip pairs (ca, cb) with at least three vertices."""
    NL = L.NL
    poly = _polygons(st.top[ca], st.bot[ca], st.top[cb], st.bot[cb], L.Z0, L.Z1, L.N0, L.N1)
    ok = poly["count"] >= 3
    # crossing nodes: one per crossing pair of lines, numbered after the pillar nodes
    sub = poly["sub"]
    xmask = poly["xa"] >= 0
    xmask &= ok[sub][:, None]
    xr, xc = np.nonzero(xmask)
    xa, xb = poly["xa"][xr, xc].astype(np.int64), poly["xb"][xr, xc].astype(np.int64)
    ukey, xfirst, xinv = np.unique(xa * (NL + 2) + xb, return_index=True, return_inverse=True)
    node = poly["node"]
    node[sub[xr], xc] = n_pnodes + xinv
    x_s, x_z = poly["s"][xr, xc][xfirst], poly["z"][xr, xc][xfirst]
    x_a, x_b = xa[xfirst], xb[xfirst]
    x_q = st.q[ca[sub[xr[xfirst]]]]
    ca, cb = ca[ok], cb[ok]
    valid = poly["valid"][ok]
    node = node[ok]
    stype_all = poly["stype"][ok]
    lines_all = poly["lines"][ok]
    del poly, xmask, xr, xc, xa, xb
    nL = ca.size
    pq = st.q[ca]
    # lateral face loops (flat, slot order) and the carrier of every edge
    rows, cols = np.nonzero(valid)
    lat_node = node[rows, cols]
    lat_st = stype_all[rows, cols]
    lat_lines = lines_all[rows, cols]                        # (e, 4)
    del stype_all, lines_all, valid, node
    cntf = np.bincount(rows, minlength=nL)
    offs = np.zeros(nL + 1, np.int64)
    np.cumsum(cntf, out=offs[1:])
    nxt = np.arange(rows.size) + 1
    nxt[offs[1:] - 1] = offs[:-1]
    st_v, lines_v = lat_st[nxt], lat_lines[nxt]
    on_pillar = (lat_st == st_v) & (lat_st < 2)
    # the edge runs along the line both ends lie on: most share their first line
    common = np.where(lat_lines[:, 0] == lines_v[:, 0], lat_lines[:, 0], -1)
    slow = np.flatnonzero((common < 0) & ~on_pillar)
    if slow.size:
        lu, lv = lat_lines[slow], lines_v[slow]
        match = (lu[:, :, None] == lv[:, None, :]).any(2) & (lu >= 0)
        common[slow] = np.where(match.any(1), lu[np.arange(slow.size), np.argmax(match, 1)], -1)
        if np.any(common[slow] < 0):
            raise AssertionError("corner-point processing: an edge of a lateral face has no carrier line")
    p0, p1, _ = pair_pillars(pq, nx, ny)
    pil_car = NL + np.where(lat_st == 0, p0[rows], p1[rows])
    carrier = np.where(on_pillar, pil_car, common)
    return LateralFaces(ca=ca, cb=cb, pq=pq, face=rows, node=lat_node, carrier=carrier,
                        x_s=x_s, x_z=x_z, x_a=x_a, x_b=x_b, x_q=x_q)


def _polygons(tA, bA, tB, bB, Z0, Z1, N0, N1) -> dict:
    """Overlap polygons of the strips [tA, bA] and [tB, bB] on a pillar pair, in 8 slots.

    Slots, in loop order (upper chain left to right, lower chain right to left):
    0 top at s=0, 1 crossing tA×tB, 2 top at s=1, 3 right pinch, 4 bottom at s=1,
    5 crossing bA×bB, 6 bottom at s=0, 7 left pinch. A slot is valid if the polygon has
    that vertex; ``stype`` is 0 / 1 (on the pillar at s = 0 / 1) or 2 (a crossing);
    ``lines`` (n, 8, 4) the lines the vertex lies on, −1 padded (the edge between two
    vertices runs along their common line, or along the pillar when both are on it);
    crossings: ``s``, ``z`` (position along the pair, depth) and ``xa`` < ``xb`` their lines.
    """
    n = tA.size
    shape = (n, 8)
    valid = np.zeros(shape, bool)
    node = np.full(shape, -1, np.int64)
    stype = np.full(shape, 2, np.int8)
    lines = np.full(shape + (4,), -1, INDEX)
    h_end = []
    for end, Zs, Ns, slot_t, slot_b in ((0, Z0, N0, 0, 6), (1, Z1, N1, 2, 4)):
        zta, ztb, zba, zbb = Zs[tA], Zs[tB], Zs[bA], Zs[bB]
        upper_a = zta >= ztb
        lower_a = zba <= zbb
        h = np.where(lower_a, zba, zbb) - np.where(upper_a, zta, ztb)
        lt = np.where(upper_a, tA, tB)
        lb = np.where(lower_a, bA, bB)
        lt2 = np.where(zta == ztb, np.where(upper_a, tB, tA), lt)
        lb2 = np.where(zba == zbb, np.where(lower_a, bB, bA), lb)
        valid[:, slot_t] = h >= 0
        node[:, slot_t] = Ns[lt]
        stype[:, slot_t] = end
        # a vertex pinched on the pillar (h = 0) also lies on the bottom line(s)
        lines[:, slot_t, 0], lines[:, slot_t, 1] = lt, lt2
        pinched = h == 0
        lines[pinched, slot_t, 2], lines[pinched, slot_t, 3] = lb[pinched], lb2[pinched]
        valid[:, slot_b] = h > 0
        node[:, slot_b] = Ns[lb]
        stype[:, slot_b] = end
        lines[:, slot_b, 0], lines[:, slot_b, 1] = lb, lb2
        h_end.append(h)
    both_ends = (h_end[0] >= 0) & (h_end[1] >= 0)

    # crossings: only where two of the four lines swap order between the pillars (faults)
    def swaps(L, M):
        return (Z0[L] - Z0[M]) * (Z1[L] - Z1[M]) < 0
    sub = np.flatnonzero(swaps(tA, tB) | swaps(bA, bB) | swaps(tA, bB) | swaps(tB, bA))
    s = np.zeros((sub.size, 8))
    z = np.zeros((sub.size, 8))
    xa = np.full((sub.size, 8), -1, INDEX)
    xb = np.full((sub.size, 8), -1, INDEX)
    tA, bA, tB, bB, both = tA[sub], bA[sub], tB[sub], bB[sub], both_ends[sub]
    vs = valid[sub]
    ls = lines[sub]

    def put(slot, ok, sx, zx, a, b, la, lb_):
        vs[:, slot] |= ok
        s[ok, slot], z[ok, slot] = sx[ok], zx[ok]
        ls[ok, slot, 0], ls[ok, slot, 1] = la[ok], lb_[ok]
        xa[ok, slot], xb[ok, slot] = a[ok], b[ok]

    # upper chain kink tA×tB: inside both strips (always, by concavity, when both ends are)
    ok, sx, zx, a, b = _cross(tA, tB, Z0, Z1)
    ok &= both | ((zx <= _at(bA, sx, Z0, Z1)) & (zx <= _at(bB, sx, Z0, Z1)))
    put(1, ok, sx, zx, a, b, tA, tB)
    ok, sx, zx, a, b = _cross(bA, bB, Z0, Z1)
    ok &= both | ((zx >= _at(tA, sx, Z0, Z1)) & (zx >= _at(tB, sx, Z0, Z1)))
    put(5, ok, sx, zx, a, b, bA, bB)
    # pinches: the top of one strip meets the bottom of the other on the polygon's boundary
    for t_, b_, t_o, b_o in ((tA, bB, tB, bA), (tB, bA, tA, bB)):
        ok, sx, zx, a, b = _cross(t_, b_, Z0, Z1)
        ok &= (zx >= _at(t_o, sx, Z0, Z1)) & (zx <= _at(b_o, sx, Z0, Z1)) & ~both
        right_end = Z0[t_] < Z0[b_]                 # the polygon lies on the left of the pinch
        for slot, side in ((3, right_end), (7, ~right_end)):
            put(slot, ok & side & ~vs[:, slot], sx, zx, a, b, t_, b_)
    valid[sub] = vs
    lines[sub] = ls
    return {"valid": valid, "node": node, "stype": stype, "lines": lines, "sub": sub, "s": s, "z": z,
            "xa": xa, "xb": xb, "count": valid.sum(1)}
