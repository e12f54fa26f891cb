"""Tetrahedral meshes with anisotropic crack-front cells around planar fractures (3D).

``mesh.front = "anisotropic"`` of the simplicial generator. Along a crack front (a fracture edge
inside the solid) the displacement jump vanishes like √r, r the distance to the front, while it
varies smoothly *along* the front. Isotropic tetrahedra graded towards the front are as small
along it as across it; here the cells next to a front are thin across it and long along it.

Construction, for every fracture (a convex planar polygon strictly inside the box, all of whose
edges are crack fronts):

1. **Ring**: a triangulation of the square [−ρ, ρ]² of the plane normal to a front, in the
   coordinates (o, n) = (in-plane distance outwards from the front, distance along the fracture
   normal): the front is the origin, the fracture the ray o ∈ [−ρ, 0], n = 0. K nested squares of
   SECTORS = 8 points each (corners and side midpoints), of radii ρ (1 − k/K)^β, β = 1/(1 − γ)
   (γ = tip_grading: the node positions of the size law h ∝ r^γ), K the smallest count whose
   innermost radius is at most tip_size, joined to the origin by a fan. It is symmetric about
   the fracture plane and has 1 + 8K nodes (33 for K = 4).
2. **Tubes**: every edge of the polygon sweeps the ring along itself. The sweep layers are graded
   towards both ends of the edge (the polygon's corners, where the fronts meet) by the law
   h(d) = fracture_size (d/ρ)^γ floored at tip_size, d the distance to the nearer corner, and are
   fracture_size apart in the middle. The tubes of two edges meeting at a corner are cut by the
   bisector (mitre) plane there; both use the same ring, so their nodes coincide on it.
3. **Core**: the polygon shrunk by ρ, triangulated by gmsh with the tubes' inner nodes on its
   boundary (size fracture_size), extruded along the normal through the ring's nodes on its
   inner side o = −ρ (n = −ρ, 0, ρ).
4. The tubes and the core fill the slab {in-plane offset ≤ ρ, |n| ≤ ρ} around the fracture with
   prisms, each split into three tetrahedra by the smallest-node-index rule (every quadrilateral
   face cut by the diagonal through its smallest node: conforming across cells).
5. **Fill**: gmsh tetrahedralises the box minus the slabs, the slabs' surface triangles kept,
   the size growing from the slabs' surface sizes up to ``size`` (slope ``grading``).

The fracture is a union of faces: the core's mid-layer triangles and the tubes' faces on the ring
segment. Cells touching a front have size ~tip_size across it and the local layer spacing
(fracture_size in the middle of an edge) along it; at the corners every direction is graded.

Why it helps and what it costs: docs/accuracy_3d.md, "Anisotropic crack-front cells" (figures in
docs/cube_slip_anisotropic.md, made by benchmarks/cube_slip.py --anisotropic).
"""

from __future__ import annotations

import logging
import time

import numpy as np
from scipy.spatial import cKDTree

from ...core.errors import InputError, MeshError
from ...core.ragged import INDEX
from ..build import mesh_from_cells
from ..fractures import validate_spec
from ..mesh import Mesh
from ..msh import gmsh_session

log = logging.getLogger("polypore")

# default ring radius ρ in units of fracture_size (shrunk to fit the fracture and the box)
RING_RADIUS = 0.3
# points on each square of the ring (its corners and side midpoints)
SECTORS = 8
# largest exponent β of the ring radii ρ (1 − k/K)^β (γ → 1)
MAX_BETA = 6.0
# the slab must stay this fraction of ρ clear of the box boundary and of other slabs
CLEARANCE = 0.25
# the core polygon (fracture shrunk by ρ) must keep each edge at least this fraction of its length
CORE_MIN = 0.1
# growth of the fill's cell size per unit distance from the slabs
GRADING = 0.4
# seeds tried for the fill
FILL_ATTEMPTS = 5


def _law(d, h_far, radius, gamma, h_min):
    """Size h(d) = h_far (d/radius)^γ, floored at h_min and capped at h_far."""
    d = np.maximum(np.asarray(d, float), 0.0)
    return np.clip(h_far * (d / radius) ** gamma, h_min, h_far)


def _graded_integral(length, h_far, radius, gamma, h_min):
    """(x (4001,), ∫_0^x dx/h) on a fixed sampling of [0, length], and the number of intervals."""
    x = np.linspace(0.0, length, 4001)
    g = 1.0 / _law(np.minimum(x, length - x), h_far, radius, gamma, h_min)
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(x))])
    return x, integral, max(1, int(np.ceil(min(integral[-1], 1e15) - 1e-9)))


def graded_count(length, h_far, radius, gamma, h_min) -> int:
    """The number of intervals :func:`graded_positions` makes, without making them (size guards)."""
    return _graded_integral(length, h_far, radius, gamma, h_min)[2]


def graded_positions(length, h_far, radius, gamma, h_min):
    """Node positions in [0, length] with spacing h(distance to the nearer end) (see :func:`_law`):
    the number of intervals is ⌈∫ dx/h⌉ (at least 1), the nodes equidistribute ∫ dx/h."""
    x, integral, n = _graded_integral(length, h_far, radius, gamma, h_min)
    t = np.interp(np.linspace(0.0, integral[-1], n + 1), integral, x)
    t[0], t[-1] = 0.0, length
    return t


def split_prisms(prisms: np.ndarray) -> np.ndarray:
    """(3p, 4) tetrahedra of prisms (p, 6) = (a, b, c, a', b', c') (a' above a, ...), by the smallest-
    index rule: each quadrilateral face is cut by the diagonal through its smallest node, so that
    two prisms sharing a face cut it alike (Dompierre et al. 1999: always possible for prisms)."""
    P = np.asarray(prisms, np.int64)
    # rotate/reflect each prism so that its smallest node is a (position 0)
    pos = np.argmin(P, axis=1)
    perms = np.array([[0, 1, 2, 3, 4, 5], [1, 2, 0, 4, 5, 3], [2, 0, 1, 5, 3, 4],
                      [3, 5, 4, 0, 2, 1], [4, 3, 5, 1, 0, 2], [5, 4, 3, 2, 1, 0]])
    Q = np.take_along_axis(P, perms[pos], axis=1)
    a, b, c, a2, b2, c2 = Q.T
    # the face (b, c, c', b') opposite a: cut by b–c' or by c–b', whichever holds its smallest node;
    # the faces through a are cut by a–b' and a–c'
    bc2 = (np.minimum(b, c2) < np.minimum(c, b2))[:, None]
    t1 = np.where(bc2, np.stack([a, b, c, c2], 1), np.stack([a, b, c, b2], 1))
    t2 = np.where(bc2, np.stack([a, b, c2, b2], 1), np.stack([a, b2, c, c2], 1))
    t3 = np.stack([a, b2, c2, a2], 1)
    return np.concatenate([t1, t2, t3])


class _Fracture:
    """Frame and tube data of one fracture."""

    def __init__(self, spec, lower, upper):
        geo = validate_spec(spec, 3, np.stack([lower, upper]))
        self.name = spec.name
        self.N = geo["normal"]
        self.centre = geo["centre"]
        e1, e2 = geo["e1"], geo["e2"]
        if np.cross(e1, e2) @ self.N < 0:
            e2 = -e2
        self.e1, self.e2 = e1, e2
        V = np.asarray(spec.vertices, float)
        P = np.stack([(V - self.centre) @ e1, (V - self.centre) @ e2], axis=1)
        area2 = float(np.sum(P[:, 0] * np.roll(P[:, 1], -1) - np.roll(P[:, 0], -1) * P[:, 1]))
        if area2 < 0:       # counter-clockwise in (e1, e2)
            P, V = P[::-1], V[::-1]
        # drop vertices on a straight line (a turn of 0 is no corner)
        keep = []
        m = len(P)
        for i in range(m):
            a, b, c = P[i - 1], P[i], P[(i + 1) % m]
            cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
            if cross < -1e-9 * np.linalg.norm(b - a) * np.linalg.norm(c - b):
                raise InputError(f"fracture {spec.name}", "mesh.front = \"anisotropic\" needs convex fracture "
                                 f"polygons; the corner {V[i].tolist()} is re-entrant")
            if cross > 1e-12 * np.linalg.norm(b - a) * np.linalg.norm(c - b):
                keep.append(i)
        self.P = P[keep]
        m = len(self.P)
        D = np.roll(self.P, -1, axis=0) - self.P
        self.L = np.linalg.norm(D, axis=1)
        self.d = D / self.L[:, None]                                   # edge directions (2D)
        self.u = np.stack([self.d[:, 1], -self.d[:, 0]], axis=1)       # outward normals (2D, ccw polygon)
        # tan(β/2) at every vertex, β the turning angle (π − interior angle)
        cosb = np.einsum("ij,ij->i", np.roll(self.d, 1, axis=0), self.d)
        sinb = np.roll(self.d, 1, axis=0)[:, 0] * self.d[:, 1] - np.roll(self.d, 1, axis=0)[:, 1] * self.d[:, 0]
        self.tan_half = sinb / (1.0 + cosb)
        self.m = m

    def to3d(self, Q, n=0.0):
        """3D points of in-plane coordinates Q (k, 2) at normal offsets n."""
        Q = np.asarray(Q, float)
        return (self.centre + Q[:, :1] * self.e1 + Q[:, 1:2] * self.e2
                + np.asarray(n, float).reshape(-1, 1) * self.N)

    def slab_distance(self, p, rho) -> float:
        """Distance (m) from the point p (3,) to the slab of radius ρ: the in-plane distance (the largest
        over the edges of the distance beyond the edge's offset line) and the normal distance beyond
        ±ρ, combined (exact off a face, a lower bound off the slab's edges and corners)."""
        X = np.asarray(p, float) - self.centre
        q = np.array([X @ self.e1, X @ self.e2])
        d_in = max(0.0, float(np.max(np.einsum("ij,ij->i", q - self.P, self.u))) - rho)
        d_n = max(0.0, abs(float(X @ self.N)) - rho)
        return float(np.hypot(d_in, d_n))

    def max_radius(self) -> float:
        """Largest ρ leaving every edge of the core polygon CORE_MIN of its length."""
        t = self.tan_half
        shrink = t + np.roll(t, -1)                  # edge i loses ρ (tan(β_i/2) + tan(β_{i+1}/2))
        return float(np.min((1 - CORE_MIN) * self.L / shrink))

    def slab_corners(self, rho) -> np.ndarray:
        """(2m, 3) corners of the slab: the polygon offset by ρ (mitred), at n = ±ρ."""
        W = self.P + rho * (self.u + np.roll(self.u, 1, axis=0)) / (1 + np.einsum(
            "ij,ij->i", self.u, np.roll(self.u, 1, axis=0)))[:, None]
        return np.concatenate([self.to3d(W, np.full(len(W), rho)), self.to3d(W, np.full(len(W), -rho))])


def polar_ring(rho, sectors, radii):
    """Nodes (k, 2) and triangles of the ring [−ρ, ρ]² made of nested squares: ``sectors`` points on
    the square boundary (at the angles π + 2πj/sectors, ``sectors`` a multiple of 4), scaled by
    ``radii`` (decreasing, radii[0] = 1), joined to the origin by a fan. The crack direction
    (angle π) is a ray of points; the mesh is symmetric about n = 0."""
    th = np.pi + 2 * np.pi * np.arange(sectors) / sectors
    c, s = np.cos(th), np.sin(th)
    scale = rho / np.maximum(np.abs(c), np.abs(s))
    B = np.stack([c * scale, s * scale], axis=1)
    B[np.abs(B) < 1e-14 * rho] = 0.0
    X = [np.zeros((1, 2))] + [r * B for r in radii]
    X = np.concatenate(X)
    T = []
    j = np.arange(sectors)
    jn = (j + 1) % sectors
    ring = lambda k, i: 1 + k * sectors + i       # noqa: E731
    K = len(radii)
    T.append(np.stack([np.zeros(sectors, int), ring(K - 1, j), ring(K - 1, jn)], 1))
    for k in range(K - 1):
        # quad (outer j, outer j+1, inner j+1, inner j): cut by its shorter diagonal (a tie by the
        # side of n = 0, so that the cut is mirrored about it)
        a, b, cc, d = ring(k, j), ring(k, jn), ring(k + 1, jn), ring(k + 1, j)
        ac = np.linalg.norm(X[a] - X[cc], axis=1)
        bd = np.linalg.norm(X[b] - X[d], axis=1)
        up = np.where(np.abs(ac - bd) <= 1e-9 * rho, s[j] + s[jn] >= 0, ac < bd)
        T.append(np.where(up[:, None], np.stack([a, b, cc], 1), np.stack([a, b, d], 1)))
        T.append(np.where(up[:, None], np.stack([a, cc, d], 1), np.stack([b, cc, d], 1)))
    return X, np.concatenate(T)


def _nodes_triangles(gmsh):
    tags, coords, _ = gmsh.model.mesh.getNodes()
    tags = np.asarray(tags, np.int64)
    X = np.asarray(coords, float).reshape(-1, 3)[:, :2]
    _, enodes = gmsh.model.mesh.getElementsByType(2)
    lookup = np.full(int(tags.max()) + 1, -1, np.int64)
    lookup[tags] = np.arange(tags.size)
    T = lookup[np.asarray(enodes, np.int64).reshape(-1, 3)]
    used, inv = np.unique(T, return_inverse=True)
    return X[used], inv.reshape(T.shape)


def _core(gmsh, boundary, h):
    """Triangulation of the polygon through the 2D points ``boundary`` (ccw), with exactly those
    boundary nodes (first in the returned node array, in order)."""
    geo = gmsh.model.geo
    seg = np.linalg.norm(np.roll(boundary, -1, axis=0) - boundary, axis=1)
    local = np.minimum(seg, np.roll(seg, 1))
    pts = [geo.addPoint(x, y, 0.0, float(min(hh, h))) for (x, y), hh in zip(boundary, local)]
    lines = [geo.addLine(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
    geo.addPlaneSurface([geo.addCurveLoop(lines)])
    geo.synchronize()
    for c in lines:
        gmsh.model.mesh.setTransfiniteCurve(c, 2)
    gmsh.model.mesh.generate(2)
    X, T = _nodes_triangles(gmsh)
    # put the boundary nodes first, in the given order
    idx = cKDTree(X).query(boundary)[1]
    if np.max(np.linalg.norm(X[idx] - boundary, axis=1)) > 1e-9 * float(np.ptp(boundary)):
        raise MeshError("gmsh", "gmsh moved the core polygon's boundary nodes")
    rest = np.setdiff1d(np.arange(len(X)), idx)
    order = np.concatenate([idx, rest])
    new = np.empty(len(X), np.int64)
    new[order] = np.arange(len(X))
    return X[order], new[T]


def ring_radii(rho, tip, gamma):
    """Radii ρ (1 − k/K)^β, k = 0 … K−1, of the ring's squares: the nodes of the law h ∝ r^γ
    (β = 1/(1 − γ), capped at MAX_BETA), K the smallest count whose innermost radius ρ K^−β is at
    most ``tip`` (at least 2)."""
    beta = min(1.0 / (1.0 - gamma), MAX_BETA) if gamma < 1 else MAX_BETA
    K = max(2, int(np.ceil((rho / tip) ** (1.0 / beta) - 1e-9)))
    return rho * (1.0 - np.arange(K) / K) ** beta


def _slab(fr: _Fracture, rho, fsize, tip, gamma, seed):
    """Nodes (k, 3) and prisms (p, 6) of the slab of one fracture."""
    radii = ring_radii(rho, tip, gamma)
    R, RT = polar_ring(rho, SECTORS, radii / rho)
    inner = np.flatnonzero(np.abs(R[:, 0] + rho) <= 1e-9 * rho)
    log.debug("ring: %d nodes, radii %s", len(R), np.round(radii, 5).tolist())
    inner = inner[np.argsort(R[inner, 1])]
    n_layers = R[inner, 1]
    nodes, prisms = [], []
    base = 0
    core_boundary = []
    nr = len(R)
    for i in range(fr.m):
        j = (i + 1) % fr.m
        tau = graded_positions(fr.L[i], fsize, rho, gamma, tip) / fr.L[i]
        o = R[:, 0]
        start = -o * fr.tan_half[i]
        end = fr.L[i] + o * fr.tan_half[j]
        ell = start[None, :] + tau[:, None] * (end - start)[None, :]            # (K+1, nr)
        Q = (fr.P[i][None, None, :] + ell[..., None] * fr.d[i] + o[None, :, None] * fr.u[i])
        X = fr.to3d(Q.reshape(-1, 2), np.tile(R[:, 1], len(tau)))
        nodes.append(X)
        K = len(tau) - 1
        log.debug("edge %d: %d layers", i, K)
        lay = base + nr * np.arange(K)[:, None, None]
        prisms.append(np.concatenate([RT[None] + lay, RT[None] + lay + nr], axis=2).reshape(-1, 6))
        base += X.shape[0]
        # the core boundary along this edge: o = −ρ, the layers but the last (the next edge's first)
        core_boundary.append(fr.P[i] + ell[:-1, inner[0]][:, None] * fr.d[i] - rho * fr.u[i])
    core_boundary = np.concatenate(core_boundary)
    opts = {"Mesh.RandomSeed": int(seed), "Mesh.MeshSizeFromCurvature": 0, "Mesh.MeshSizeFromPoints": 1,
            "Mesh.MeshSizeExtendFromBoundary": 1, "Mesh.MeshSizeMax": float(fsize)}
    with gmsh_session(opts) as gmsh:
        C, CT = _core(gmsh, core_boundary, fsize)
    nc = len(C)
    X = fr.to3d(np.tile(C, (len(n_layers), 1)), np.repeat(n_layers, nc))
    nodes.append(X)
    lay = base + nc * np.arange(len(n_layers) - 1)[:, None, None]
    prisms.append(np.concatenate([CT[None] + lay, CT[None] + lay + nc], axis=2).reshape(-1, 6))
    return np.concatenate(nodes), np.concatenate(prisms)


def _merge(X, cells, span):
    """Merge coincident nodes (within 1e-10 span)."""
    tree = cKDTree(X)
    pairs = tree.query_pairs(1e-10 * span, output_type="ndarray")
    rep = np.arange(len(X))
    if len(pairs):
        # union-find light: map every node to the smallest index of its cluster
        import scipy.sparse as sp
        from scipy.sparse.csgraph import connected_components

        g = sp.coo_array((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(X), len(X)))
        _, lab = connected_components(g, directed=False)
        first = np.full(lab.max() + 1, len(X))
        np.minimum.at(first, lab, np.arange(len(X)))
        rep = first[lab]
    used, inv = np.unique(rep, return_inverse=True)
    return X[used], inv[cells]


def _boundary_triangles(tets):
    faces = np.concatenate([tets[:, [0, 1, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 3]], tets[:, [1, 2, 3]]])
    key = np.sort(faces, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[cnt[inv.ravel()] == 1]


def _fill(lower, upper, X, surfaces, size, grading, seed, h_surface, distances, algorithm=1):
    """Tetrahedra of the box minus the slabs: the slabs' surface triangles ``surfaces`` (lists of
    (k, 3) node indices into X) kept, the size h_surface + grading · (distance to the slab), at
    most ``size`` (``distances``: the distance functions of the slabs). Returns the new nodes
    (numbered after X) and the tetrahedra."""
    opts = {"Mesh.RandomSeed": int(seed), "Mesh.MeshSizeExtendFromBoundary": 1, "Mesh.MeshSizeFromPoints": 0,
            "Mesh.MeshSizeFromCurvature": 0, "Mesh.MeshSizeMax": float(size),
            "Mesh.MeshSizeMin": float(min(h_surface)) * 0.5, "Mesh.Algorithm3D": int(algorithm)}
    ext = upper - lower
    with gmsh_session(opts) as gmsh:
        occ = gmsh.model.occ
        occ.addBox(*lower, *ext)
        occ.synchronize()
        box_surfaces = [t for _, t in gmsh.model.getEntities(2)]

        def size_at(dim, tag, x, y, z, lc):
            p = (x, y, z)
            return float(min([size] + [hs + grading * d(p) for d, hs in zip(distances, h_surface)]))

        gmsh.model.mesh.setSizeCallback(size_at)
        slab_tags = []
        first = 1
        for s in surfaces:
            used = np.unique(s)
            tag = gmsh.model.addDiscreteEntity(2)
            gmsh.model.mesh.addNodes(2, tag, (first + used).tolist(), X[used].ravel().tolist())
            gmsh.model.mesh.addElementsByType(tag, 2, [], (first + s).ravel().tolist())
            slab_tags.append(tag)
        gmsh.model.addDiscreteEntity(3, -1, box_surfaces + slab_tags)
        try:
            gmsh.model.mesh.generate(3)
        finally:
            gmsh.model.mesh.removeSizeCallback()
        tags, coords, _ = gmsh.model.mesh.getNodes()
        tags = np.asarray(tags, np.int64)
        Y = np.asarray(coords, float).reshape(-1, 3)
        _, enodes = gmsh.model.mesh.getElementsByType(4)
        T = np.asarray(enodes, np.int64).reshape(-1, 4)
    if T.size == 0:
        raise MeshError("gmsh", "gmsh produced no tetrahedra around the fracture slabs")
    log.debug("fill: %d nodes, %d tetrahedra (algorithm %d)", len(Y), len(T), algorithm)
    # the slabs' surface nodes are matched by position (gmsh may renumber), the others are new
    span = float(np.max(upper - lower))
    surf = np.unique(np.concatenate([s.ravel() for s in surfaces]))
    dist, near = cKDTree(X[surf]).query(Y)
    mine = dist <= 1e-9 * span
    lookup = np.full(int(tags.max()) + 1, -1, np.int64)
    lookup[tags[mine]] = surf[near[mine]]
    lookup[tags[~mine]] = len(X) + np.arange(int((~mine).sum()))
    T = lookup[T]
    # gmsh must have kept the slabs' surface triangles (no Steiner points on them)
    faces = np.sort(np.concatenate([T[:, [0, 1, 2]], T[:, [0, 1, 3]], T[:, [0, 2, 3]], T[:, [1, 2, 3]]]), axis=1)
    want = np.sort(np.concatenate(surfaces), axis=1)
    n = len(X) + len(Y)
    key = lambda F: (F[:, 0] * n + F[:, 1]) * n + F[:, 2]      # noqa: E731
    missing = int(np.sum(~np.isin(key(want), key(faces))))
    if missing:
        raise MeshError("gmsh", f"gmsh did not keep {missing} of the {len(want)} surface triangles of the "
                        "fracture slabs when filling the box around them")
    return Y[~mine], T


def front_mesh(lower, upper, fractures, size: float, *, fracture_size: float | None = None, interfaces=(),
               tip_size: float | None = None, tip_grading: float = 0.5, grading: float = GRADING,
               front_radius: float | None = None, seed: int = 0) -> Mesh:
    """Tetrahedra of a box with anisotropic cells along the fronts of planar fractures.

    Parameters
    ----------
    lower, upper : (3,) float, m
        The box.
    fractures : sequence of FractureSpec
        Convex planar polygons strictly inside the box, apart from each other: every edge is a
        crack front.
    size : float, m
        Cell size far from the fractures.
    fracture_size : float, m
        Cell size on the fractures away from their fronts, and spacing of the layers along a
        front away from the corners (default ``size``).
    tip_size : float, m
        Largest innermost ring radius (the cells touching a front are about this size across it)
        and the smallest layer spacing along a front (at the corners); default fracture_size/40.
    tip_grading : float
        γ ∈ (0, 1]: the ring radii and the layers along the fronts follow h ∝ r^γ.
    interfaces : sequence of FractureSpec
        Must be empty (region boundaries are not supported).
    front_radius : float, m
        ρ, the half-width of the front tubes (default RING_RADIUS · fracture_size), shrunk so that
        the shrunk polygon keeps CORE_MIN of every edge and the slab stays clear of the box.

    Raises
    ------
    InputError
        Not 3D, bad sizes, a fracture that is not convex, touches the box or comes close to
        another one.
    """
    lower = np.asarray(lower, float).ravel()
    upper = np.asarray(upper, float).ravel()
    if lower.size != 3 or upper.shape != lower.shape:
        raise InputError("front_mesh", "\"anisotropic\" fronts are made for 3D boxes only; in 2D a crack front "
                         "is a point and the isotropic tip grading (mesh.tip_size) is already optimal")
    if np.any(upper <= lower):
        raise InputError("upper", f"must exceed lower {lower.tolist()} in every direction, got {upper.tolist()}")
    for key, v in (("size", size), ("fracture_size", fracture_size), ("tip_size", tip_size),
                   ("front_radius", front_radius)):
        if v is not None and not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
            raise InputError(key, f"must be a positive number (m), got {v}")
    if not (isinstance(tip_grading, (int, float)) and 0 < tip_grading <= 1):
        raise InputError("tip_grading", f"must be an exponent in (0, 1], got {tip_grading}")
    fsize = float(min(size, fracture_size or size))
    tip = float(tip_size if tip_size is not None else fsize / 40)
    tip = min(tip, fsize)
    if len(interfaces):
        raise InputError("front_mesh", "\"anisotropic\" fronts do not make meshes conforming to region "
                         "boundaries ([[regions]] inside the box); use mesh.front = \"isotropic\"")
    if not fractures:
        raise InputError("front_mesh", "\"anisotropic\" grades the mesh around fracture fronts, and the case has "
                         "no fractures; use mesh.front = \"isotropic\"")
    span = float(np.max(upper - lower))
    est = np.prod(upper - lower) / size ** 3
    if est > 5e7:
        raise InputError("size", f"{size} m would give about {est:.3g} cells in the bulk alone; use a larger size")
    t0 = time.perf_counter()
    frs = [_Fracture(s, lower, upper) for s in fractures]
    radii = []
    for fr in frs:
        rho = float(front_radius if front_radius is not None else RING_RADIUS * fsize)
        rho = min(rho, fr.max_radius())
        # clear of the box: the slab's corners at least CLEARANCE ρ inside
        corners = fr.slab_corners(1.0)          # linear in ρ about the polygon: scale
        base = fr.slab_corners(0.0)
        dirn = corners - base
        for _ in range(60):
            Y = base + (1 + CLEARANCE) * rho * dirn
            if np.all(Y > lower) and np.all(Y < upper):
                break
            rho *= 0.9
        if rho < 2 * tip:
            raise InputError(f"fracture {fr.name}", f"is too close to the box boundary for anisotropic fronts: a "
                             f"tube of radius {rho:.3g} m around its edges would not fit (need at least twice "
                             f"tip_size = {tip:.3g} m); move it inside or use mesh.front = \"isotropic\"")
        radii.append(rho)
    # slabs apart from each other: their corner hulls separated (sampled distance)
    for a in range(len(frs)):
        for b in range(a + 1, len(frs)):
            Pa = frs[a].slab_corners(radii[a] * (1 + CLEARANCE))
            Pb = frs[b].slab_corners(radii[b] * (1 + CLEARANCE))
            if _hulls_overlap(Pa, Pb):
                raise InputError("fracture", f"fractures {frs[a].name!r} and {frs[b].name!r} are too close for "
                                 "anisotropic fronts (their front tubes would overlap); the fractures of "
                                 "mesh.front = \"anisotropic\" must be apart, or use \"isotropic\"")
    nodes, tets, surfaces, hs = [], [], [], []
    base = 0
    for fr, rho in zip(frs, radii):
        X, prisms = _slab(fr, rho, fsize, tip, float(tip_grading), seed)
        X, prisms = _merge(X, prisms, span)
        T = split_prisms(prisms)
        nodes.append(X)
        tets.append(T + base)
        surfaces.append(_boundary_triangles(T) + base)
        edge = np.linalg.norm(X[surfaces[-1][:, 0] - base] - X[surfaces[-1][:, 1] - base], axis=1)
        hs.append(float(np.median(edge)))
        log.debug("slab %s: surface median edge %.4g m", fr.name, hs[-1])
        base += len(X)
    X = np.concatenate(nodes)
    T = np.concatenate(tets)
    # gmsh's boundary recovery now and then leaves a flat tetrahedron on a slab face or a Steiner
    # point in it: another seed avoids it
    problem = ""
    for attempt in range(FILL_ATTEMPTS):
        try:
            Y, T2 = _fill(lower, upper, X, surfaces, float(size), float(grading), seed + attempt, hs,
                          [lambda p, fr=fr, rho=rho: fr.slab_distance(p, rho) for fr, rho in zip(frs, radii)])
        except MeshError as exc:
            problem = str(exc)
            continue
        except Exception as exc:
            problem = f"gmsh could not fill the box around the fracture slabs: {exc}"
            continue
        Z = np.concatenate([X, Y])
        if _worst_quality(Z, T2) > 1e-6:
            break
        problem = "gmsh left a flat tetrahedron next to a fracture slab"
    else:
        raise MeshError("gmsh", f"{problem} (seeds {seed} to {seed + FILL_ATTEMPTS - 1}); change mesh.size or "
                        "mesh.fracture_size slightly, or use mesh.front = \"isotropic\"")
    X = np.concatenate([X, Y])
    T = np.concatenate([T, T2]).astype(INDEX)
    E = X[T[:, 1:]] - X[T[:, :1]]
    volume = float(np.abs(np.einsum("ki,ki->k", E[:, 0], np.cross(E[:, 1], E[:, 2]))).sum()) / 6
    if abs(volume - np.prod(upper - lower)) > 1e-9 * np.prod(upper - lower):
        raise MeshError("gmsh", f"the anisotropic-front mesh does not tile the box: its cells hold {volume:.9g} m³ "
                        f"of {np.prod(upper - lower):.9g}")
    used, inv = np.unique(T, return_inverse=True)
    mesh = mesh_from_cells(X[used], {"tetra": inv.reshape(T.shape).astype(INDEX)})
    log.info("anisotropic fronts: %d tetrahedra (%d in the slabs, ρ = %s m) in %.2f s", mesh.n_cells,
             sum(len(t) for t in tets), ", ".join(f"{r:.3g}" for r in radii), time.perf_counter() - t0)
    return mesh


def _worst_quality(X, T) -> float:
    """Smallest 6√2 |V| / (longest edge)³ of the tetrahedra (1 for the regular one)."""
    E = X[T[:, [1, 2, 3, 2, 3, 3]]] - X[T[:, [0, 0, 0, 1, 1, 2]]]
    lmax = np.max(np.linalg.norm(E, axis=2), axis=1)
    V = np.abs(np.einsum("ki,ki->k", E[:, 0], np.cross(E[:, 1], E[:, 2])))
    return float(np.min(V * np.sqrt(2) / lmax ** 3)) if len(T) else 1.0


def _hulls_overlap(A, B) -> bool:
    """Whether the convex hulls of the point sets A and B intersect (no separating plane among the
    face normals of either hull and the cross products of their edge directions)."""
    from itertools import combinations

    def axes(P):
        out = []
        for i, j, k in combinations(range(len(P)), 3):
            n = np.cross(P[j] - P[i], P[k] - P[i])
            if np.linalg.norm(n) > 1e-12:
                out.append(n / np.linalg.norm(n))
        return out

    for n in axes(A) + axes(B):
        a, b = A @ n, B @ n
        if a.max() < b.min() or b.max() < a.min():
            return False
    return True
