"""Quadratic (P2 Lagrange) displacement space on simplicial meshes (``mechanics.order = 2``).

On triangles / tetrahedra the nodal + bubble space of :mod:`.space` is P1 in the bulk, whose
fracture compliance error is O(h²) (docs/accuracy_3d.md). This space is continuous P2 on each
side of Γ, discontinuous across it, with the same P0 multipliers on the face-mean jumps.

Slots (scalar unknowns), numbered in this order:

* node sides: ``fm.sides`` exactly as in :mod:`.space` (a node on Γ has one slot per side);
* edge sides: every mesh edge (from ``cell_nodes``), an edge lying in a fracture face split into
  one slot per group of its cells connected across non-fracture faces containing it (the node
  side rule of scheme.md §3, applied to edges: tip edges keep one slot, edges inside Γ get two);
* face bubbles (3D only): one per fracture face on its + side (both sides if ``two_sided``),
  the conforming cubic b_σ = 60 λ_a λ_b λ_c of the cell holding it, scaled to face mean 1.

Basis on a simplex with barycentrics λ_i: λ_i(2λ_i − 1) at vertices, 4 λ_i λ_j at edge midpoints,
so slot values are point values at vertices and edge midpoints.

Why face bubbles in 3D: the mean over a triangle of a P2 trace sees its edge midpoints only
(weights 1/3 each, vertex weights 0), and each midpoint is shared by the two fracture faces of
an interior fracture edge. A multiplier with λ_σ = −λ_σ' on every pair of faces sharing an
edge is then orthogonal to every face-mean jump; it exists when the dual graph of the fracture
triangulation is bipartite (every interior vertex of even degree), as on structured meshes
(tests/unit/discretisation/test_quadratic.py builds one). The bubble gives each face its own control of its jump.
In 2D the face is an edge whose midpoint slot is split per side and carries weight 2/3 in the
face mean (1/6 at the vertices): each face already controls its own jump, so there is no bubble.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..core.errors import InputError
from ..core.ragged import INDEX, frozen
from ..mesh import FracturedMesh
from ..mesh.sides import glued_sides
from .faces import side_slots
from .space import SlotCounts
from .quadrature import cell_rule, face_rule

# local edges of a simplex, on its sorted cell_nodes
LOCAL_EDGES = {2: np.array([[0, 1], [1, 2], [0, 2]]), 3: np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])}
# edges of a face, on its face_nodes order (2D: the face is its own edge)
FACE_EDGES = {2: np.array([[0, 1]]), 3: np.array([[0, 1], [1, 2], [2, 0]])}
# face mean of a P2 trace: weights of its vertex and edge slots
TRACE_MEAN = {2: (np.array([1 / 6, 1 / 6]), np.array([2 / 3])), 3: (np.zeros(3), np.full(3, 1 / 3))}
BUBBLE_SCALE = 60.0    # 60 λ_a λ_b λ_c has mean 1 over its face (∫_σ λ_a λ_b λ_c = |σ|/60)


def _edge_keys(a: np.ndarray, b: np.ndarray, n_nodes: int) -> np.ndarray:
    return np.minimum(a, b).astype(np.int64) * n_nodes + np.maximum(a, b)


@dataclass(frozen=True, eq=False)
class QuadraticSpace(SlotCounts):
    """Slots of the P2 space on a simplicial fractured mesh.

    Attributes
    ----------
    fm : FracturedMesh
    two_sided : bool
        Face bubbles on both sides of every fracture face (3D).
    cell_slots : (n_cells, n_loc) int32
        Per cell: its d + 1 vertex slots (sorted ``cell_nodes`` order), then its edge slots
        (``LOCAL_EDGES`` order); n_loc = 6 (2D) or 10 (3D).
    edge_nodes : (n_edges, 2) int32
        Nodes of every edge, sorted.
    cell_edge : (n_cells, n_e) int32
        Edge of every local edge.
    face_edge : (n_faces, n_ef) int32
        Edge of every face edge (``FACE_EDGES`` order).
    edge_side_edge : (n_edge_sides,) int32
        Edge of every edge side.
    bubble_face, bubble_cell : (n_b,) int32
        Fracture-face index and holding cell of each bubble.
    bubble_sign : (n_b,) int8
        +1 on the + side, −1 on the − side.
    bubble_vertex : (n_b,) int8
        Local vertex of the holding cell opposite the bubble's face.
    """

    fm: FracturedMesh
    two_sided: bool
    cell_slots: np.ndarray
    edge_nodes: np.ndarray
    cell_edge: np.ndarray
    face_edge: np.ndarray
    edge_side_edge: np.ndarray
    bubble_face: np.ndarray
    bubble_cell: np.ndarray
    bubble_sign: np.ndarray
    bubble_vertex: np.ndarray

    @classmethod
    def build(cls, fm: FracturedMesh, two_sided: bool = False, face_bubbles: bool = True) -> "QuadraticSpace":
        """The P2 space of ``fm``; ``face_bubbles=False`` drops the 3D face bubbles (for the
        inf-sup check of the module docstring only: the multipliers may then be singular).

        Raises
        ------
        InputError
            ``mechanics.order``: a cell is not a triangle (2D) / tetrahedron (3D).
        """
        mesh, net = fm.mesh, fm.network
        d, nn, nc = mesh.dim, mesh.n_nodes, mesh.n_cells
        cn = mesh.cell_nodes
        bad = (cn.counts != d + 1) | (mesh.cell_faces.counts != d + 1)
        if np.any(bad):
            raise InputError("order", f"order 2 (quadratic displacements) needs a simplicial mesh "
                             f"({'triangles' if d == 2 else 'tetrahedra'}); {int(bad.sum())} of {nc} cells are "
                             "other polytopes: use mesh.generator = \"simplicial\" or order 1")
        cnodes = cn.values.reshape(nc, d + 1)
        le = LOCAL_EDGES[d]
        ekeys, cell_edge = np.unique(_edge_keys(cnodes[:, le[:, 0]], cnodes[:, le[:, 1]], nn).ravel(),
                                     return_inverse=True)
        cell_edge = cell_edge.reshape(nc, le.shape[0]).astype(INDEX)
        fnodes = mesh.face_nodes.values.reshape(mesh.n_faces, d)
        fe = FACE_EDGES[d]
        fkeys = _edge_keys(fnodes[:, fe[:, 0]], fnodes[:, fe[:, 1]], nn)
        face_edge = np.searchsorted(ekeys, fkeys).astype(INDEX)
        edge_side, edge_side_edge = _edge_sides(mesh, net.faces, cell_edge, face_edge, ekeys.size)
        ns = fm.sides.n_sides
        cell_slots = np.concatenate([fm.sides.cell_node_side.reshape(nc, d + 1), ns + edge_side], axis=1)
        nff = net.n_faces
        if d == 3 and face_bubbles:
            if two_sided:
                bface = np.concatenate([np.arange(nff), np.arange(nff)])
                bcell = np.concatenate([net.plus_cell, net.minus_cell])
                bsign = np.concatenate([np.ones(nff), -np.ones(nff)])
            else:
                bface, bcell, bsign = np.arange(nff), net.plus_cell, np.ones(nff)
        else:
            bface = bcell = bsign = np.zeros(0, INDEX)
        # the cell vertex that is not a node of the face
        on_face = (cnodes[bcell][:, :, None] == fnodes[net.faces[bface]][:, None, :]).any(axis=2)
        bvert = np.argmin(on_face, axis=1) if bface.size else np.zeros(0, INDEX)
        edge_nodes = np.stack([ekeys // nn, ekeys % nn], axis=1).astype(INDEX)
        return cls(fm, bool(two_sided), frozen(cell_slots.astype(INDEX)), frozen(edge_nodes), frozen(cell_edge),
                   frozen(face_edge), frozen(edge_side_edge), frozen(bface.astype(INDEX)), frozen(bcell.astype(INDEX)),
                   frozen(np.asarray(bsign).astype(np.int8)), frozen(bvert.astype(np.int8)))

    # ---- sizes ----------------------------------------------------------------------------
    @property
    def n_edge_sides(self) -> int:
        return self.edge_side_edge.size

    @property
    def n_point_slots(self) -> int:
        """Slots that are point values (node and edge sides); the bubbles follow them."""
        return self.n_sides + self.n_edge_sides

    # ---- points and faces ----------------------------------------------------------------------
    def slot_points(self) -> np.ndarray:
        """(n_point_slots, d) the vertex / edge midpoint of every point slot, m.

        For a vertex or edge with several sides (on Γ) the point is nudged 1e-12 of the way
        towards a cell of the side, so that data discontinuous across Γ are evaluated on the
        side's own piece (as ``models.mechanics._side_points`` does for the P1 space).
        """
        mesh = self.fm.mesh
        g = mesh.geometry
        nc = mesh.n_cells
        sides = self.fm.sides
        cell_of = np.repeat(np.arange(nc), self.dim + 1)
        Xn = _nudged(mesh.nodes[sides.side_node], sides.side_node, sides.cell_node_side, cell_of, g.cell_centroid,
                     self.n_sides)
        mid = 0.5 * (mesh.nodes[self.edge_nodes[:, 0]] + mesh.nodes[self.edge_nodes[:, 1]])
        ne = self.cell_edge.shape[1]
        eslots = self.cell_slots[:, self.dim + 1:].ravel() - self.n_sides
        Xe = _nudged(mid[self.edge_side_edge], self.edge_side_edge, eslots, np.repeat(np.arange(nc), ne),
                     g.cell_centroid, self.n_edge_sides)
        return np.vstack([Xn, Xe])

    def face_slots(self, faces: np.ndarray, cells: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Vertex slots (k, d) (``face_nodes`` order) and edge slots (k, n_ef) (``FACE_EDGES``
        order) of the given faces seen from ``cells`` (default: ``face_cells[:, 0]``)."""
        mesh = self.fm.mesh
        d = self.dim
        faces = np.asarray(faces, np.int64)
        cells = mesh.face_cells[faces, 0] if cells is None else np.asarray(cells, np.int64)
        fnodes = mesh.face_nodes.values.reshape(mesh.n_faces, d)[faces]
        vs = side_slots(self, np.repeat(cells, d), fnodes.ravel()).reshape(len(faces), d)
        fe = self.face_edge[faces]
        loc = np.argmax(self.cell_edge[cells][:, None, :] == fe[:, :, None], axis=2)
        es = self.cell_slots[cells[:, None], d + 1 + loc]
        return vs, es

    def face_mean_operator(self, faces: np.ndarray, cells: np.ndarray | None = None) -> sp.csr_array:
        """(len(faces), n_slots): v ↦ (1/|σ|)∫_σ of the P2 trace from ``cells`` (bubbles excluded)."""
        vs, es = self.face_slots(faces, cells)
        wv, we = TRACE_MEAN[self.dim]
        k = len(vs)
        rows = np.repeat(np.arange(k), vs.shape[1] + es.shape[1])
        cols = np.concatenate([vs, es], axis=1).ravel()
        vals = np.tile(np.concatenate([wv, we]), k)
        keep = vals != 0
        return sp.csr_array((vals[keep], (rows[keep], cols[keep])), shape=(k, self.n_slots))

    def jump_operator(self) -> sp.csr_array:
        """(n_fracture_faces, n_slots) face-mean jump [[v]]_σ = mean⁺ − mean⁻ + bubbles."""
        net = self.fm.network
        Mp = self.face_mean_operator(net.faces, net.plus_cell)
        Mm = self.face_mean_operator(net.faces, net.minus_cell)
        B = sp.csr_array((self.bubble_sign.astype(float),
                          (self.bubble_face, self.n_point_slots + np.arange(self.n_bubbles))), shape=Mp.shape)
        J = (Mp - Mm + B).tocsr()
        J.eliminate_zeros()         # an unsplit slot (tip edge, off-Γ vertex) cancels out
        return J

    def trace_quadrature(self, faces: np.ndarray, cells: np.ndarray | None = None):
        """Quadrature of ∫_σ g·v on the given faces, exact for a P2 trace times a quadratic g.

        Returns
        -------
        points : (k·n_q, d) m
        weights : (k·n_q,) m^(d-1)
        values : csr (k·n_q, n_slots)
            Trace basis values at the points (bubbles excluded: they vanish off Γ).
        """
        mesh = self.fm.mesh
        d = self.dim
        faces = np.asarray(faces, np.int64)
        L, w = face_rule(d)
        fe = FACE_EDGES[d]
        phi = np.concatenate([L * (2 * L - 1), 4 * L[:, fe[:, 0]] * L[:, fe[:, 1]]], axis=1)   # (n_q, n_loc)
        X = mesh.nodes[mesh.face_nodes.values.reshape(mesh.n_faces, d)[faces]]               # (k, d, d)
        P = np.einsum("qi,kid->kqd", L, X).reshape(-1, d)
        W = (mesh.geometry.face_area[faces][:, None] * w).ravel()
        vs, es = self.face_slots(faces, cells)
        slots = np.concatenate([vs, es], axis=1)                                               # (k, n_loc)
        k, nq = len(faces), len(w)
        rows = np.broadcast_to(np.arange(k * nq).reshape(k, nq, 1), (k, nq, phi.shape[1]))
        cols = np.broadcast_to(slots[:, None, :], rows.shape)
        vals = np.broadcast_to(phi[None], rows.shape)
        V = sp.csr_array((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(k * nq, self.n_slots))
        return P, W, V


    def jump_quadrature(self):
        """The jump [[v]](x) as a field at the points of a face rule on every fracture face (the
        P2 traces and the bubbles' values), for L2 norms and point values of the slip.

        Returns
        -------
        points : (n_ff·n_q, d) m, face-major
        weights : (n_ff·n_q,) m^(d-1)
        values : csr (n_ff·n_q, n_slots)
        """
        net = self.fm.network
        P, W, Vp = self.trace_quadrature(net.faces, net.plus_cell)
        Vm = self.trace_quadrature(net.faces, net.minus_cell)[2]
        L = face_rule(self.dim)[0]
        nq = L.shape[0]
        # a face bubble's trace is 60 Π λ_i over the face's own vertices, whatever their order
        rows = (self.bubble_face.astype(np.int64)[:, None] * nq + np.arange(nq)).ravel()
        cols = np.repeat(self.n_point_slots + np.arange(self.n_bubbles), nq)
        vals = (self.bubble_sign[:, None] * BUBBLE_SCALE * np.prod(L, axis=1)).ravel()
        B = sp.csr_array((vals, (rows, cols)), shape=Vp.shape)
        return P, W, (Vp - Vm + B).tocsr()

    def jump_at(self, ff: np.ndarray, L: np.ndarray) -> sp.csr_array:
        """The jump [[v]](x) at arbitrary points of fracture faces: the field of
        :meth:`jump_quadrature` (P2 traces of both sides and the face bubbles) at given points.

        Parameters
        ----------
        ff : (k,) int, the fracture face (index into ``fm.network.faces``) holding each point
        L : (k, d) barycentric coordinates of each point in its face (``face_nodes`` order)

        Returns
        -------
        values : csr (k, n_slots), row i: v ↦ [[v]] at point i (one component: apply to (n_slots, d))
        """
        net = self.fm.network
        ff = np.asarray(ff, np.int64)
        L = np.asarray(L, float)
        k, fe = L.shape[0], FACE_EDGES[self.dim]
        phi = np.concatenate([L * (2 * L - 1), 4 * L[:, fe[:, 0]] * L[:, fe[:, 1]]], axis=1)   # (k, n_loc)
        rows = np.repeat(np.arange(k), phi.shape[1])
        V = sp.csr_array((k, self.n_slots))
        for cells, sign in ((net.plus_cell, 1.0), (net.minus_cell, -1.0)):
            slots = np.concatenate(self.face_slots(net.faces[ff], cells[ff]), axis=1)        # (k, n_loc)
            V = V + sp.csr_array(((sign * phi).ravel(), (rows, slots.ravel())), shape=V.shape)
        # a face bubble's trace is 60 Π λ_i over the face's own vertices, whatever their order
        B = sp.csr_array((self.bubble_sign.astype(float),
                          (self.bubble_face, self.n_point_slots + np.arange(self.n_bubbles))),
                         shape=(net.n_faces, self.n_slots))
        V = (V + sp.diags_array(BUBBLE_SCALE * np.prod(L, axis=1)) @ B[ff]).tocsr()
        V.eliminate_zeros()         # an unsplit slot (tip edge, off-Γ vertex) cancels out
        return V


def _nudged(X, owner, inc_slot, inc_cell, centroid, n):
    """Points X (n, d) of slots owned by ``owner`` (n,); those of an owner with several slots moved
    1e-12 of the way towards the centroid of the first cell (incidence order) of their slot."""
    first = np.full(n, -1, np.int64)
    first[inc_slot[::-1]] = np.arange(inc_slot.size)[::-1]
    multi = np.bincount(owner)[owner] > 1
    X = X.copy()
    X[multi] += 1e-12 * (centroid[inc_cell[first[multi]]] - X[multi])
    return X


def _edge_sides(mesh, fracture_faces, cell_edge, face_edge, n_edges):
    """Sides of every edge (scheme.md §3's node-side rule for edges).

    Two cells around an edge are neighbours when they share a face containing it that is not a
    fracture face; only edges of fracture faces can have several sides, so the graph is built
    on their (cell, edge) incidences alone. Sides are numbered edge by edge, and within an edge
    by their first incidence (lowest cell).

    Returns
    -------
    cell_edge_side : (n_cells, n_e) int32, edge_side_edge : (n_edge_sides,) int32
    """
    nc, ne = cell_edge.shape
    flat = cell_edge.ravel()
    cut_edge = np.zeros(n_edges, bool)
    cut_edge[face_edge[fracture_faces].ravel()] = True
    nsides = np.ones(n_edges, np.int64)
    inc = np.flatnonzero(cut_edge[flat])
    if inc.size:
        keys = (inc // ne).astype(np.int64) * n_edges + flat[inc]
        order = np.argsort(keys)
        keys, inc = keys[order], inc[order]
        glue = (mesh.face_cells[:, 1] >= 0)
        glue[fracture_faces] = False
        f, k = np.nonzero(glue[:, None] & cut_edge[face_edge])
        e = face_edge[f, k].astype(np.int64)
        fc = mesh.face_cells[f].astype(np.int64)
        a = np.searchsorted(keys, fc[:, 0] * n_edges + e)
        b = np.searchsorted(keys, fc[:, 1] * n_edges + e)
        counts, rank = glued_sides(flat[inc], a, b, n_edges)
        nsides[cut_edge] = counts[cut_edge]
    first_side = np.zeros(n_edges + 1, np.int64)
    np.cumsum(nsides, out=first_side[1:])
    side = first_side[flat]
    if inc.size:
        side[inc] += rank
    return side.reshape(nc, ne).astype(INDEX), np.repeat(np.arange(n_edges, dtype=INDEX), nsides)


# ---- basis tables ---------------------------------------------------------------------------------
def p2_tables(L: np.ndarray, d: int) -> tuple[np.ndarray, np.ndarray]:
    """P2 basis at barycentric points L (n_q, d+1): values (n_q, n_loc) and the coefficients
    C (n_q, n_loc, d+1) with ∇φ_a = Σ_i C_{a,i} ∇λ_i."""
    le = LOCAL_EDGES[d]
    nq, nv = L.shape
    phi = np.concatenate([L * (2 * L - 1), 4 * L[:, le[:, 0]] * L[:, le[:, 1]]], axis=1)
    C = np.zeros((nq, nv + len(le), nv))
    C[:, np.arange(nv), np.arange(nv)] = 4 * L - 1
    e = nv + np.arange(len(le))
    C[:, e, le[:, 0]] = 4 * L[:, le[:, 1]]
    C[:, e, le[:, 1]] = 4 * L[:, le[:, 0]]
    return phi, C


def bubble_tables(L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Face bubbles 60 Π_{i≠m} λ_i of a tetrahedron at barycentric points L (n_q, 4), for each
    opposite vertex m: values (n_q, 4) and coefficients C (n_q, 4, 4) of ∇λ_i."""
    nq = L.shape[0]
    phi = np.empty((nq, 4))
    C = np.zeros((nq, 4, 4))
    for m in range(4):           # four fixed local faces, not a loop over mesh entities
        f = [i for i in range(4) if i != m]
        phi[:, m] = BUBBLE_SCALE * np.prod(L[:, f], axis=1)
        for k in f:
            C[:, m, k] = BUBBLE_SCALE * np.prod(L[:, [i for i in f if i != k]], axis=1)
    return phi, C


@dataclass(frozen=True, eq=False)
class QuadraticOperators:
    """Quadrature-point operators of a :class:`QuadraticSpace` (same interface as ``Operators``).

    Cells holding a face bubble (cubic) use a degree-5 rule, the others a degree-2 rule
    (exact for the P2 stiffness with a constant material).

    Attributes
    ----------
    space : QuadraticSpace
    D : tuple of d csr (n_qp, n_slots)
        ∂_j φ_a at every quadrature point: (∇v)(x_q)_{ij} = (D[j] @ v)[q, i].
    value : csr (n_qp, n_slots)
        φ_a(x_q).
    qp_cell : (n_qp,) int32; qp_weight : (n_qp,) m^d; qp_point : (n_qp, d) m
    mean : csr (n_cells, n_slots)
        Cell mean (1/|K|)∫_K v.
    grad_mean : tuple of d csr (n_cells, n_slots)
        Cell mean of ∂_j v (= ∇v at the centroid without bubbles).
    jump : csr (n_fracture_faces, n_slots)
        Face-mean jump [[v]]_σ.
    stab, stab_cell : None
        The P2 space is conforming on each side of Γ: no stabilisation.
    """

    space: QuadraticSpace
    D: tuple
    value: sp.csr_array
    qp_cell: np.ndarray
    qp_weight: np.ndarray
    qp_point: np.ndarray
    mean: sp.csr_array
    grad_mean: tuple
    jump: sp.csr_array
    stab: None = None
    stab_cell: None = None

    @classmethod
    def build(cls, space: QuadraticSpace) -> "QuadraticOperators":
        mesh = space.fm.mesh
        d, nc, nslots = mesh.dim, mesh.n_cells, space.n_slots
        X = mesh.nodes[mesh.cell_nodes.values.reshape(nc, d + 1)]          # (nc, d+1, d)
        E = X[:, 1:] - X[:, :1]
        inv = np.linalg.inv(E)
        gl = np.empty((nc, d + 1, d))                                     # ∇λ_i per cell, 1/m
        gl[:, 1:] = inv.transpose(0, 2, 1)
        gl[:, 0] = -gl[:, 1:].sum(axis=1)
        vol = np.abs(np.linalg.det(E)) / (2.0 if d == 2 else 6.0)
        holds = np.zeros(nc, bool)
        holds[space.bubble_cell] = True
        rows, cols, gvals, vvals, qcell, qw, qpt = [], [], [], [], [], [], []
        base = 0
        for cells, degree in ((np.flatnonzero(~holds), 2), (np.flatnonzero(holds), 5)):
            if not cells.size:
                continue
            L, w = cell_rule(d, degree)
            k, nq = cells.size, w.size
            phi, C = p2_tables(L, d)
            q = base + np.arange(k * nq).reshape(k, nq)
            base += k * nq
            G = np.einsum("qai,kid->kqad", C, gl[cells])                   # (k, nq, n_loc, d)
            shape = G.shape[:3]
            rows.append(np.broadcast_to(q[:, :, None], shape).ravel())
            cols.append(np.broadcast_to(space.cell_slots[cells][:, None, :], shape).ravel())
            gvals.append(G.reshape(-1, d))
            vvals.append(np.broadcast_to(phi[None], shape).ravel())
            qcell.append(np.repeat(cells, nq))
            qw.append((vol[cells][:, None] * w).ravel())
            qpt.append(np.einsum("qi,kid->kqd", L, X[cells]).reshape(-1, d))
            if degree == 5 and space.n_bubbles:
                pos = np.full(nc, -1, np.int64)
                pos[cells] = np.arange(k)
                bc, m = space.bubble_cell, space.bubble_vertex.astype(np.int64)
                phib, Cb = bubble_tables(L)
                Gb = np.einsum("bqi,bid->bqd", Cb[:, m, :].transpose(1, 0, 2), gl[bc])   # (n_b, nq, d)
                rows.append(q[pos[bc]].ravel())
                cols.append(np.repeat(space.n_point_slots + np.arange(space.n_bubbles), nq))
                gvals.append(Gb.reshape(-1, d))
                vvals.append(phib[:, m].T.ravel())
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        gvals = np.concatenate(gvals)
        nqp = base
        D = tuple(sp.csr_array((gvals[:, j], (rows, cols)), shape=(nqp, nslots)) for j in range(d))
        value = sp.csr_array((np.concatenate(vvals), (rows, cols)), shape=(nqp, nslots))
        qp_cell = np.concatenate(qcell).astype(INDEX)
        qp_weight = np.concatenate(qw)
        S = sp.csr_array((qp_weight / vol[qp_cell], (qp_cell, np.arange(nqp))), shape=(nc, nqp))
        return cls(space, D, value, frozen(qp_cell), frozen(qp_weight), frozen(np.concatenate(qpt)),
                   (S @ value).tocsr(), tuple((S @ Dj).tocsr() for Dj in D), space.jump_operator())

    def gradient(self, v: np.ndarray) -> np.ndarray:
        """(n_cells, d, d) cell mean of ∇v for slot values v (n_slots, d)."""
        return np.stack([G @ v for G in self.grad_mean], axis=2)

    def qp_gradient(self, v: np.ndarray) -> np.ndarray:
        """(n_qp, d, d) ∇v at the quadrature points."""
        return np.stack([Dj @ v for Dj in self.D], axis=2)
