"""Edge conformity: every node lying on a line or on a pillar segment is inserted into every
face having an edge along that line or segment.

The *carriers* are the lines and the pillars with the nodes on them, in order: one block per
line (its node at s = 0, its crossings by s, its node at s = 1), then one per pillar (its used
nodes by depth). An edge end's position in its carrier's block is found by gathers (no
search), and the nodes strictly between an edge's two ends are inserted into the face loop.
Each edge of each cell surface then appears exactly twice, with opposite orientations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .overlap import LateralFaces
from .strips import Lines


@dataclass(frozen=True, eq=False)
class Carriers:
    NL: int               # carriers < NL are lines, NL + p is pillar p
    n_pnodes: int         # nodes ≥ n_pnodes are crossings
    start: np.ndarray     # (NL + NP + 1,) offsets of the carriers' blocks in ``node``
    node: np.ndarray      # the nodes of every carrier, in order
    ppos: np.ndarray      # (n_pnodes,) position of every used pillar node in its pillar's block
    xpos: np.ndarray      # (2 n_x,) position of every crossing in the blocks of its two lines
    x_a: np.ndarray       # (n_x,) first line of every crossing
    N0: np.ndarray        # (NL + 2,) node at s = 0 of every line

    def position(self, c, v):
        """Position of node v in the block of its carrier c (both (k,))."""
        pos = np.empty(c.size, np.int64)
        on_pillar = c >= self.NL
        pos[on_pillar] = self.ppos[v[on_pillar]]
        isx = np.flatnonzero(~on_pillar & (v >= self.n_pnodes))
        if isx.size:
            xi = v[isx] - self.n_pnodes
            pos[isx] = np.where(self.x_a[xi] == c[isx], self.xpos[xi], self.xpos[self.x_a.size + xi])
        ln = np.flatnonzero(~on_pillar & (v < self.n_pnodes))
        cl = c[ln]
        pos[ln] = np.where(self.N0[cl] == v[ln], self.start[cl], self.start[cl + 1] - 1)
        if not np.array_equal(self.node[pos], v):
            raise AssertionError("corner-point processing: an edge end is not on its carrier")
        return pos


def carriers(used_nodes: np.ndarray, node_pillar: np.ndarray, NP: int, L: Lines, lat: LateralFaces) -> Carriers:
    """The carriers' blocks; ``used_nodes``: sorted pillar nodes that are cell corners."""
    NL = L.NL
    n_pnodes = node_pillar.size
    x_a, x_b, x_s = lat.x_a, lat.x_b, lat.x_s
    n_x = x_a.size
    up_pil = node_pillar[used_nodes]
    p_count = np.bincount(up_pil, minlength=NP)
    inc_line = np.concatenate([x_a, x_b])
    inc_x = np.concatenate([np.arange(n_x), np.arange(n_x)])
    o = np.lexsort((inc_x, np.concatenate([x_s, x_s]), inc_line))
    ncross = np.bincount(inc_line, minlength=NL)
    start = np.zeros(NL + NP + 1, np.int64)
    np.cumsum(np.concatenate([ncross + 2, p_count]), out=start[1:])
    node = np.empty(int(start[-1]), np.int64)
    node[start[:NL]] = L.ln0
    node[start[1:NL + 1] - 1] = L.ln1
    il = inc_line[o]
    first_inc = np.cumsum(ncross) - ncross
    pos_inc = start[il] + 1 + (np.arange(o.size) - first_inc[il])
    node[pos_inc] = n_pnodes + inc_x[o]
    xpos = np.empty(2 * n_x, np.int64)
    xpos[o] = pos_inc
    ppos = np.zeros(n_pnodes, np.int64)
    pfirst = np.cumsum(p_count) - p_count
    ppos[used_nodes] = start[NL + up_pil] + (np.arange(used_nodes.size) - pfirst[up_pil])
    node[ppos[used_nodes]] = used_nodes
    return Carriers(NL=NL, n_pnodes=n_pnodes, start=start, node=node, ppos=ppos, xpos=xpos, x_a=x_a, N0=L.N0)


def insert_edge_nodes(face, node, carrier, n_faces: int, car: Carriers):
    """Face loops with the nodes lying on their edges inserted.

    ``face``, ``node``, ``carrier`` (e,): the loop vertices of all faces (faces in order, each
    loop in order) and the carrier of the edge from each vertex to the next. Returns the
    expanded loops (flat), whether each entry is a polygon vertex (not an inserted node), and
    the node count per face.
    """
    fo = np.zeros(n_faces + 1, np.int64)
    np.cumsum(np.bincount(face, minlength=n_faces), out=fo[1:])
    e_next = np.arange(node.size) + 1
    e_next[fo[1:] - 1] = fo[:-1]
    iu = car.position(carrier, node)
    iv = car.position(carrier, node[e_next])
    del e_next
    n_ins = np.abs(iv - iu) - 1
    if (n_ins < 0).any():
        raise AssertionError("corner-point processing: a degenerate edge")
    start = np.zeros(node.size, np.int64)                    # output position of every edge's first node
    np.cumsum(1 + n_ins[:-1], out=start[1:])
    total = int(start[-1] + 1 + n_ins[-1]) if node.size else 0
    fnodes = np.empty(total, np.int64)
    is_vertex = np.zeros(total, bool)
    fnodes[start] = node
    is_vertex[start] = True
    ins = np.flatnonzero(n_ins > 0)
    if ins.size:
        k = n_ins[ins]
        eid = np.repeat(ins, k)
        j = np.arange(eid.size) - np.repeat(np.cumsum(k) - k, k) + 1
        fnodes[start[eid] + j] = car.node[iu[eid] + j * np.sign(iv[eid] - iu[eid])]
    fcount = np.bincount(face, weights=1 + n_ins, minlength=n_faces).astype(np.int64)
    return fnodes, is_vertex, fcount


def orient_loops(fnodes, is_vertex, fcount, flip):
    """Reverse the loops of the faces with ``flip``."""
    foff = np.zeros(fcount.size + 1, np.int64)
    np.cumsum(fcount, out=foff[1:])
    frow = np.repeat(np.arange(fcount.size), fcount)
    local = np.arange(fnodes.size) - foff[frow]
    src = np.where(flip[frow], foff[frow] + fcount[frow] - 1 - local, np.arange(fnodes.size))
    return fnodes[src], is_vertex[src]
