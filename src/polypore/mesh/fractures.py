"""Fracture networks: named fractures mapped onto interior mesh faces (scheme.md §1).

A fracture is a polyline in 2D (it may be kinked) and a planar polygon in 3D.
Its **+ side** is fixed per fracture: n^+ points out of the + cell, from the + side
into the − side, and

* in 2D, n^+ is the polyline's tangent (first to last vertex) turned clockwise,
  so the + side is on the left when walking along the polyline;
* in 3D, n^+ is the polygon's right-hand-rule normal (or the user's ``normal``).

The fracture mesh's (d−2)-dimensional entities ("fracture edges": nodes in 2D,
edges in 3D) are classified as interior, tip, boundary (on ∂Ω), intersection or
kink, which later carries the flow's edge unknowns and the feature report.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.errors import InputError, MeshError
from ..core.ragged import INDEX, Ragged, frozen
from .mesh import Mesh
from .sides import NodeSides, node_sides

INTERIOR, TIP, BOUNDARY, INTERSECTION, KINK = 0, 1, 2, 3, 4
EDGE_KINDS = ("interior", "tip", "boundary", "intersection", "kink")


@dataclass(frozen=True)
class FractureSpec:
    """Geometry of one fracture as the user gives it.

    Attributes
    ----------
    name : str
    vertices : (k, d) float, m
        2D: polyline vertices (k >= 2). 3D: planar polygon vertices (k >= 3), in order.
    normal : (3,) float or None
        3D only: orientation of n^+ (defaults to the right-hand-rule normal).
    """

    name: str
    vertices: np.ndarray
    normal: np.ndarray | None = None


def _fail(name, msg):
    raise InputError(f"fracture {name}", msg)


def validate_spec(spec: FractureSpec, dim: int, box: np.ndarray | None = None, tol: float = 1e-9) -> dict:
    """Check a fracture's geometry; return its derived data (normal(s), measure, frame).

    Raises InputError naming the fracture for: wrong vertex count or dimension,
    repeated vertices, zero length/area, a non-planar 3D polygon, vertices outside
    the box ``box`` (2, d).
    """
    V = np.asarray(spec.vertices, dtype=float)
    name = spec.name
    if V.ndim != 2 or V.shape[1] != dim:
        _fail(name, f"vertices must be a list of {dim}D points, got an array of shape {V.shape}")
    if not np.all(np.isfinite(V)):
        _fail(name, "vertices must be finite numbers")
    need = 2 if dim == 2 else 3
    if len(V) < need:
        _fail(name, f"a {'polyline' if dim == 2 else 'polygon'} needs at least {need} vertices, got {len(V)}")
    scale = float(np.ptp(V, axis=0).max())
    if scale <= 0:
        _fail(name, "degenerate fracture: all vertices coincide")
    if box is not None:
        span = float(np.max(box[1] - box[0]))
        out = np.any((V < box[0] - tol * span) | (V > box[1] + tol * span), axis=1)
        if np.any(out):
            _fail(name, f"vertex {V[np.argmax(out)].tolist()} lies outside the domain "
                        f"{box[0].tolist()}–{box[1].tolist()}; fractures must lie inside Ω")
    if dim == 2:
        seg = np.diff(V, axis=0)
        L = np.hypot(seg[:, 0], seg[:, 1])
        if np.any(L <= tol * scale):
            _fail(name, f"segment {int(np.argmin(L))} has zero length (repeated vertex)")
        tangent = seg / L[:, None]
        return {"vertices": V, "tangent": tangent, "normal": np.stack([tangent[:, 1], -tangent[:, 0]], 1),
                "measure": float(L.sum()), "seg_length": L}
    closed = np.vstack([V, V[:1]])
    if np.any(np.linalg.norm(np.diff(closed, axis=0), axis=1) <= tol * scale):
        _fail(name, "degenerate polygon: two consecutive vertices coincide")
    c = V.mean(0)
    # plane from the SVD (robust for any vertex order), orientation from the vector area
    _, sv, vt = np.linalg.svd(V - c)
    if sv[1] <= 1e-9 * scale:
        _fail(name, "degenerate polygon: its vertices are collinear")
    n = vt[2]
    off = np.abs((V - c) @ n)
    if off.max() > 1e-7 * scale:
        _fail(name, f"polygon is not planar: a vertex is {off.max():.3e} m off its plane")
    e1 = vt[0]
    e2 = np.cross(n, e1)
    P = np.stack([(V - c) @ e1, (V - c) @ e2], axis=1)
    Pc = np.vstack([P, P[:1]])
    m = len(P)
    if m > 3:
        a0, a1 = Pc[:-1][:, None], Pc[1:][:, None]
        b0, b1 = Pc[:-1][None], Pc[1:][None]

        def orient(p, q, r):
            return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])
        d1, d2 = orient(a0, a1, b0), orient(a0, a1, b1)
        d3, d4 = orient(b0, b1, a0), orient(b0, b1, a1)
        i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
        adjacent = (np.abs(i - j) <= 1) | (np.abs(i - j) == m - 1)
        if np.any((d1 * d2 < 0) & (d3 * d4 < 0) & ~adjacent):
            _fail(name, "degenerate polygon: its edges cross each other (self-intersecting)")
    area2 = float((Pc[:-1, 0] * Pc[1:, 1] - Pc[1:, 0] * Pc[:-1, 1]).sum())
    area = 0.5 * abs(area2)
    if area <= 1e-12 * scale ** 2:
        _fail(name, "degenerate polygon: its area is zero")
    if area2 < 0:  # make n the right-hand-rule normal of the vertex order
        n, e2 = -n, -e2
        P[:, 1] *= -1
    if spec.normal is not None:
        nu = np.asarray(spec.normal, float)
        if nu.shape != (3,) or not np.linalg.norm(nu) > 0:
            _fail(name, "normal must be a non-zero 3-vector")
        nu = nu / np.linalg.norm(nu)
        if abs(abs(nu @ n) - 1) > 1e-6:
            _fail(name, f"normal {nu.tolist()} is not perpendicular to the polygon's plane (normal {n.tolist()})")
        if nu @ n < 0:
            n = -n
    return {"vertices": V, "normal": n, "centre": c, "e1": e1, "e2": e2, "poly2d": P, "measure": area}


def self_intersection(vertices, closed: bool, tol: float = 1e-9):
    """The first pair (i, j), i < j, of edges of a polyline (``closed``: a polygon, edge i from
    vertex i to vertex i+1 mod k) that cross, touch or overlap although they are not neighbours,
    or that are neighbours folding back onto each other; None for a simple one.

    3D vertices are projected on their best-fit plane (planarity is checked elsewhere). Edges of
    zero length are left out (a repeated vertex has its own message). O(k²) work, O(k) memory.
    """
    V = np.asarray(vertices, float)
    if V.ndim != 2 or len(V) < 3 or V.shape[1] not in (2, 3) or not np.all(np.isfinite(V)):
        return None
    if V.shape[1] == 3:
        c = V.mean(0)
        _, sv, vt = np.linalg.svd(V - c)
        if sv[1] <= 1e-9 * max(float(np.ptp(V, axis=0).max()), 1e-300):
            return None                  # collinear: no plane to project on (its own message)
        P = (V - c) @ vt[:2].T
    else:
        P = V
    A = P if closed else P[:-1]
    B = np.roll(P, -1, axis=0) if closed else P[1:]
    m = len(A)
    eps = tol * max(float(np.ptp(P, axis=0).max()), 1e-300)
    live = np.linalg.norm(B - A, axis=1) > eps

    def cross(p, q, r):
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (r[..., 0] - p[..., 0])

    def near(p, a, b):     # distance from points p to segments [a, b]
        ab = b - a
        t = np.clip(np.einsum("...d,...d->...", p - a, ab) / np.maximum(np.einsum("...d,...d->...", ab, ab), 1e-300),
                    0.0, 1.0)
        return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)

    for i in range(m - 1):
        if not live[i]:
            continue
        j = np.arange(i + 1, m)
        j = j[live[j]]
        if not j.size:
            continue
        a0, a1, b0, b1 = A[i], B[i], A[j], B[j]
        neighbour = (j == i + 1) | (closed & (i == 0) & (j == m - 1))
        proper = (cross(a0, a1, b0) * cross(a0, a1, b1) < 0) & (cross(b0, b1, a0[None]) * cross(b0, b1, a1[None]) < 0)
        touch = np.minimum.reduce([near(b0, a0, a1), near(b1, a0, a1), near(a0[None], b0, b1), near(a1[None], b0, b1)])
        # neighbours share a vertex: only the far end of one lying on the other (a fold back) counts
        far = np.where(j == i + 1, np.minimum(near(a0[None], b0, b1), near(b1, a0, a1)),
                       np.minimum(near(a1[None], b0, b1), near(b0, a0, a1)))
        hit = np.where(neighbour, far <= eps, proper | (touch <= eps))
        if hit.any():
            return i, int(j[np.argmax(hit)])
    return None


def segment_distances(P: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """(n, m) distances (m) from points P (n, d) to the segments [A_j, B_j] (m, d)."""
    AB = B - A
    L2 = np.maximum(np.einsum("md,md->m", AB, AB), 1e-300)
    t = np.clip(np.einsum("nmd,md->nm", P[:, None, :] - A[None], AB) / L2, 0.0, 1.0)
    return np.linalg.norm(P[:, None, :] - (A[None] + t[..., None] * AB[None]), axis=2)


def _point_segment_distance(X, a, b):
    """(n,) distances from points X (n, d) to the segment [a, b]."""
    return segment_distances(X, a[None], b[None])[:, 0]


def _inside_polygon(P, poly, tol):
    """(k,) bool: points P (k, 2) inside or within tol of the polygon (m, 2)."""
    inside = np.zeros(len(P), bool)
    m = len(poly)
    near = np.zeros(len(P), bool)
    for i in range(m):
        a, b = poly[i], poly[(i + 1) % m]
        cond = (a[1] > P[:, 1]) != (b[1] > P[:, 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            xint = a[0] + (P[:, 1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1])
        inside ^= cond & (P[:, 0] < xint)
        near |= _point_segment_distance(P, a, b) <= tol
    return inside | near


@dataclass(frozen=True, eq=False)
class FractureNetwork:
    """Fracture faces, their orientation and the fracture mesh's features.

    Fracture faces are numbered 0..n-1 ("fracture-face index"), grouped by fracture.

    Attributes
    ----------
    names : tuple of str
    specs : tuple of FractureSpec
    faces : (n,) int32
        Mesh face of each fracture face.
    fracture : (n,) int32
        Fracture index of each fracture face.
    plus_cell, minus_cell : (n,) int32
        K_σ^+ and K_σ^-.
    normal : (n, d)
        n^+ (unit, out of K^+).
    edge_nodes : (n_e, d-1) int32
        Fracture edges (2D: one node; 3D: node pair), sorted.
    edge_faces : Ragged
        Fracture faces (fracture-face indices) around each fracture edge.
    edge_kind : (n_e,) int8
        One of INTERIOR, TIP, BOUNDARY, INTERSECTION, KINK.
    """

    names: tuple
    specs: tuple
    faces: np.ndarray
    fracture: np.ndarray
    plus_cell: np.ndarray
    minus_cell: np.ndarray
    normal: np.ndarray
    edge_nodes: np.ndarray
    edge_faces: Ragged
    edge_kind: np.ndarray
    measures: np.ndarray = field(repr=False)

    @property
    def n_faces(self) -> int:
        return self.faces.size

    def face_index(self, n_mesh_faces: int) -> np.ndarray:
        """(n_mesh_faces,) fracture-face index of every mesh face, -1 elsewhere."""
        out = np.full(n_mesh_faces, -1, dtype=INDEX)
        out[self.faces] = np.arange(self.n_faces, dtype=INDEX)
        return out

    def faces_of(self, name: str) -> np.ndarray:
        """Fracture-face indices of the named fracture."""
        if name not in self.names:
            raise InputError("fracture", f"unknown fracture {name!r}; known: {list(self.names)}")
        return np.flatnonzero(self.fracture == self.names.index(name)).astype(INDEX)

    def nodes_of_kind(self, kind: int) -> np.ndarray:
        """Sorted distinct mesh nodes on fracture edges of the given kind."""
        return np.unique(self.edge_nodes[self.edge_kind == kind])


def _match_faces(mesh: Mesh, geo: dict, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Interior faces lying on a fracture, and for each the fracture normal at the face."""
    g = mesh.geometry
    fn = mesh.face_nodes
    V = geo["vertices"]
    lo, hi = V.min(0) - tol, V.max(0) + tol
    cand = np.flatnonzero(np.all((g.face_centroid >= lo) & (g.face_centroid <= hi), axis=1))
    if mesh.dim == 2:
        nseg = len(V) - 1
        sub = fn.take(cand)
        Xa = mesh.nodes[sub.values[0::2]]
        Xb = mesh.nodes[sub.values[1::2]]
        mid = 0.5 * (Xa + Xb)
        best = np.full(len(cand), -1)
        for k in range(nseg):
            on = ((_point_segment_distance(Xa, V[k], V[k + 1]) <= tol)
                  & (_point_segment_distance(Xb, V[k], V[k + 1]) <= tol)
                  & (_point_segment_distance(mid, V[k], V[k + 1]) <= tol))
            best[on & (best < 0)] = k
        keep = best >= 0
        return cand[keep], geo["normal"][best[keep]]
    n, c = geo["normal"], geo["centre"]
    sub = fn.take(cand)
    dist = np.abs((mesh.nodes[sub.values] - c) @ n)
    owner = np.repeat(np.arange(len(cand)), sub.counts)
    maxd = np.zeros(len(cand))
    np.maximum.at(maxd, owner, dist)
    onplane = maxd <= tol
    cand = cand[onplane]
    sub = fn.take(cand)
    X = mesh.nodes[sub.values] - c
    P = np.stack([X @ geo["e1"], X @ geo["e2"]], axis=1)
    ins = _inside_polygon(P, geo["poly2d"], tol)
    owner = np.repeat(np.arange(len(cand)), sub.counts)
    allin = np.ones(len(cand), bool)
    np.logical_and.at(allin, owner, ins)
    Xc = g.face_centroid[cand] - c
    # a face outside the polygon that only touches its boundary has its centroid outside
    cin = _inside_polygon(np.stack([Xc @ geo["e1"], Xc @ geo["e2"]], 1), geo["poly2d"], 0.0)
    keep = allin & cin
    return cand[keep], np.tile(n, (int(keep.sum()), 1))


def build_network(mesh: Mesh, specs, tol: float | None = None) -> FractureNetwork:
    """Map fractures onto mesh faces, orient them and classify the fracture edges.

    Raises
    ------
    InputError
        For a bad fracture geometry, a fracture outside Ω, a fracture that does not
        conform to the mesh (its faces do not cover it), overlapping fractures or a
        fracture lying on ∂Ω.
    """
    specs = tuple(specs)
    names = tuple(s.name for s in specs)
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise InputError("fracture", f"fracture name {dup!r} is used twice; names must be unique")
    box = mesh.bounding_box
    span = float(np.max(box[1] - box[0]))
    if tol is None:
        tol = 1e-8 * span
    bface = mesh.face_cells[:, 1] < 0
    faces, fracs, normals, measures = [], [], [], []
    for i, spec in enumerate(specs):
        geo = validate_spec(spec, mesh.dim, box)
        f, nrm = _match_faces(mesh, geo, tol)
        on_bdry = bface[f]
        if np.any(on_bdry):
            raise InputError(f"fracture {spec.name}", "lies on the boundary of the domain; a fracture must be "
                             "inside Ω (it may reach ∂Ω, not run along it)")
        covered = float(mesh.geometry.face_area[f].sum())
        if abs(covered - geo["measure"]) > 1e-6 * geo["measure"]:
            raise MeshError(f"fracture {spec.name}",
                            f"does not conform to the mesh: mesh faces cover {100 * covered / geo['measure']:.2f}% "
                            f"of its {'length' if mesh.dim == 2 else 'area'} {geo['measure']:.6g}; the mesh must "
                            "have faces along the whole fracture (mesh it with the fracture embedded)")
        faces.append(f)
        fracs.append(np.full(f.size, i))
        normals.append(nrm)
        measures.append(geo["measure"])
    faces = np.concatenate(faces).astype(INDEX) if faces else np.zeros(0, INDEX)
    fracs = np.concatenate(fracs).astype(INDEX) if fracs else np.zeros(0, INDEX)
    normals = np.concatenate(normals) if normals else np.zeros((0, mesh.dim))
    if np.unique(faces).size != faces.size:
        u, c = np.unique(faces, return_counts=True)
        dup = u[c > 1][0]
        who = [names[k] for k in fracs[faces == dup]]
        raise InputError("fracture", f"fractures {who} overlap (they share face {dup}); fractures may cross "
                         "but not overlap")
    return _assemble_network(mesh, names, specs, faces, fracs, normals, measures)


def network_from_faces(mesh: Mesh, named_faces: dict, normals: dict | None = None) -> FractureNetwork:
    """Fracture network from given mesh faces (imported meshes: physical groups).

    Parameters
    ----------
    named_faces : mapping name -> (k,) int mesh face ids
    normals : mapping name -> (d,) reference normal, optional
        n^+ of each face is the face normal turned to agree with it. Without one, the
        reference is the dominant face-normal direction (eigenvector of Σ |σ| n ⊗ n),
        signed so that its largest component is positive.
    """
    normals = normals or {}
    names = tuple(named_faces)
    g = mesh.geometry
    faces, fracs, nrms, measures = [], [], [], []
    for i, name in enumerate(names):
        f = np.unique(np.asarray(named_faces[name], dtype=INDEX))
        if f.size == 0:
            raise InputError(f"fracture {name}", "has no faces in the mesh")
        if np.any(mesh.face_cells[f, 1] < 0):
            raise InputError(f"fracture {name}", "contains boundary faces; fracture faces must be interior")
        n = g.face_normal[f]
        if name in normals and normals[name] is not None:
            ref = np.asarray(normals[name], float)
        else:
            T = np.einsum("k,ki,kj->ij", g.face_area[f], n, n)
            ref = np.linalg.eigh(T)[1][:, -1]
            ref = ref * np.sign(ref[np.argmax(np.abs(ref))])
        dots = n @ ref / np.linalg.norm(ref)
        if np.any(np.abs(dots) < 0.1):
            raise InputError(f"fracture {name}", "is too curved to orient its + side from one reference normal; "
                             "give its `normal`, or split it into fractures that are closer to planar")
        faces.append(f)
        fracs.append(np.full(f.size, i))
        nrms.append(np.where(dots[:, None] > 0, n, -n))
        measures.append(float(g.face_area[f].sum()))
    faces = np.concatenate(faces).astype(INDEX) if faces else np.zeros(0, INDEX)
    if np.unique(faces).size != faces.size:
        raise InputError("fracture", "two fracture groups share faces; fractures may cross but not overlap")
    fracs = np.concatenate(fracs).astype(INDEX) if fracs else np.zeros(0, INDEX)
    nrms = np.concatenate(nrms) if nrms else np.zeros((0, mesh.dim))
    specs = tuple(FractureSpec(n, np.zeros((0, mesh.dim))) for n in names)
    return _assemble_network(mesh, names, specs, faces, fracs, nrms, measures)


def _assemble_network(mesh, names, specs, faces, fracs, normals, measures) -> FractureNetwork:
    fnorm = mesh.geometry.face_normal[faces]
    agree = np.einsum("ki,ki->k", fnorm, normals) > 0
    fc = mesh.face_cells[faces]
    plus = np.where(agree, fc[:, 0], fc[:, 1]).astype(INDEX)
    minus = np.where(agree, fc[:, 1], fc[:, 0]).astype(INDEX)
    nplus = np.where(agree[:, None], fnorm, -fnorm)
    edge_nodes, edge_faces, kind = _classify_edges(mesh, faces, fracs)
    return FractureNetwork(names, specs, frozen(faces), frozen(fracs), frozen(plus), frozen(minus), frozen(nplus),
                           frozen(edge_nodes), edge_faces, frozen(kind), frozen(np.asarray(measures, float)))


def _classify_edges(mesh: Mesh, faces: np.ndarray, fracs: np.ndarray):
    dim = mesh.dim
    nn = mesh.n_nodes
    sub = mesh.face_nodes.take(faces)
    owner = np.repeat(np.arange(faces.size), sub.counts)
    # boundary nodes / boundary edges of the mesh
    bsub = mesh.face_nodes.take(mesh.boundary_faces)
    if dim == 2:
        keys = sub.values.astype(np.int64)
        bkeys = np.unique(bsub.values)
    else:
        nxt = np.roll(np.arange(sub.nnz), -1)
        last = sub.offsets[1:] - 1
        nxt[last] = sub.offsets[:-1]
        a, b = sub.values, sub.values[nxt]
        keys = np.minimum(a, b).astype(np.int64) * nn + np.maximum(a, b)
        bn = np.roll(np.arange(bsub.nnz), -1)
        if bsub.nnz:
            bn[bsub.offsets[1:] - 1] = bsub.offsets[:-1]
        ba, bb = bsub.values, bsub.values[bn]
        bkeys = np.unique(np.minimum(ba, bb).astype(np.int64) * nn + np.maximum(ba, bb))
    ukeys, inv = np.unique(keys, return_inverse=True)
    order = np.argsort(inv, kind="stable")
    counts = np.bincount(inv, minlength=ukeys.size)
    edge_faces = Ragged.from_counts(counts, owner[order])
    on_bdry = np.isin(ukeys, bkeys)
    # distinct fractures per edge
    ef = fracs[owner[order]]
    row = np.repeat(np.arange(ukeys.size), counts)
    pair = np.unique(row.astype(np.int64) * (fracs.max(initial=0) + 1) + ef)
    nfrac = np.bincount(pair // (fracs.max(initial=0) + 1), minlength=ukeys.size)
    kind = np.full(ukeys.size, INTERIOR, dtype=np.int8)
    kind[(counts == 1) & ~on_bdry] = TIP
    kind[on_bdry] = BOUNDARY
    kind[(nfrac >= 2) | (counts >= 3)] = INTERSECTION
    if dim == 2:
        two = np.flatnonzero((counts == 2) & (nfrac == 1) & ~on_bdry)
        if two.size:
            f0 = edge_faces.values[edge_faces.offsets[two]]
            f1 = edge_faces.values[edge_faces.offsets[two] + 1]
            n0 = mesh.geometry.face_normal[faces[f0]]
            n1 = mesh.geometry.face_normal[faces[f1]]
            cosang = np.abs(np.einsum("ki,ki->k", n0, n1))
            kind[two[cosang < 1 - 1e-10]] = KINK
        edge_nodes = ukeys.astype(INDEX)[:, None]
    else:
        edge_nodes = np.stack([ukeys // nn, ukeys % nn], axis=1).astype(INDEX)
    return edge_nodes, edge_faces, kind


@dataclass(frozen=True, eq=False)
class FracturedMesh:
    """A mesh, its fracture network and the node sides they define."""

    mesh: Mesh
    network: FractureNetwork
    sides: NodeSides

    @classmethod
    def build(cls, mesh: Mesh, specs=(), tol: float | None = None) -> "FracturedMesh":
        """Map fracture geometries onto the mesh and compute the node sides."""
        network = build_network(mesh, specs, tol)
        return cls(mesh, network, node_sides(mesh, network.faces))

    @classmethod
    def from_faces(cls, mesh: Mesh, named_faces: dict, normals: dict | None = None) -> "FracturedMesh":
        """Fractures given as mesh faces (imported meshes), then the node sides."""
        network = network_from_faces(mesh, named_faces, normals)
        return cls(mesh, network, node_sides(mesh, network.faces))

    def side_counts(self) -> np.ndarray:
        """(n_nodes,) number of sides of every node."""
        return self.sides.count_per_node(self.mesh.n_nodes)

    def report(self) -> dict:
        """Per-fracture statistics and features for ``polypore mesh`` / summary.json."""
        net, mesh = self.network, self.mesh
        out = {}
        for i, name in enumerate(net.names):
            ff = np.flatnonzero(net.fracture == i)
            mine = np.zeros(net.edge_nodes.shape[0], bool)
            sel = np.isin(net.edge_faces.values, ff)
            mine[np.unique(net.edge_faces.rows_of_entries()[sel])] = True
            others = set()
            inter = mine & (net.edge_kind == INTERSECTION)
            if inter.any():
                rows = np.flatnonzero(inter)
                sub = net.edge_faces.take(rows)
                others = {net.names[k] for k in np.unique(net.fracture[sub.values])} - {name}
            out[name] = {
                "faces": int(ff.size),
                "measure": float(mesh.geometry.face_area[net.faces[ff]].sum()),
                "tips": int(np.count_nonzero(mine & (net.edge_kind == TIP))),
                "kinks": int(np.count_nonzero(mine & (net.edge_kind == KINK))),
                "intersection_edges": int(np.count_nonzero(inter)),
                "intersects": sorted(others),
                "reaches_boundary": bool(np.any(mine & (net.edge_kind == BOUNDARY))),
            }
        return out
