"""Faults of a processed corner-point grid: found from the geometry, named, selectable as fractures.

A **fault face** is an interior lateral face whose two cells' corners do not coincide (the
columns are displaced along the pillar pair; judged before the snapping of :mod:`.nodes`),
plus every interior face that the FAULTS keyword names (a named fault keeps its zero-throw
parts). Faces named by FAULTS take that name (the first record naming a cell face wins). The
other fault faces are grouped into connected fault surfaces, in map view: two pillar pairs
carrying fault faces are connected through a pillar they share when that pillar carries
exactly two of them (the fault goes on, possibly turning) or when they are collinear (at a T
or X junction the straight branches go on, the others end). Groups are named ``fault_1``,
``fault_2``, ... in the order of their smallest pillar pair, keyed by the (i, j) of its first
pillar (then i pair before j pair): integers of the grid, so that the names do not change
with the snapping or the ``nonplanar`` face option (which renumber the faces and may drop
sliver faces of a fault, never its pillar pairs). A pillar pair belongs to one group only.

Orientation (:func:`fractured_mesh`): n⁺ is made coherent along each connected surface
(the + side stays on the same side of the fault trace through turns), then signed so that
the largest component of the surface's mean normal is positive.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.sparse import coo_array
from scipy.sparse.csgraph import connected_components

from ...core.errors import InputError
from ...core.ragged import INDEX, frozen
from ..fractures import FracturedMesh, FractureSpec, _assemble_network
from ..mesh import Mesh
from ..sides import node_sides

SIDE_OF_FACE = {"X": 1, "X-": 0, "Y": 3, "Y-": 2}          # FAULTS face -> cell side (W, E, S, N)


def _pair_geometry(pairs: np.ndarray, nx: int, ny: int):
    """Pillars (i, j) at both ends of pillar pairs and their direction (0: i pair, 1: j pair)."""
    NI = (nx + 1) * ny
    is_i = pairs < NI
    qj = pairs - NI
    i = np.where(is_i, pairs // ny, qj // (ny + 1))
    j = np.where(is_i, pairs % ny, qj % (ny + 1))
    end = np.stack([np.stack([i, j], 1), np.stack([i + (~is_i), j + is_i], 1)], 1)    # (k, 2 ends, 2)
    return end, (~is_i).astype(np.int8)


def pair_keys(pairs: np.ndarray, nx: int, ny: int) -> np.ndarray:
    """(k,) int64 sort keys of pillar pairs: (i, j) of their first pillar, then i pair before j pair.

    Integers of the grid only, so that the order of faults (their names) does not depend on
    the face numbering or on floating-point geometry.
    """
    end, d = _pair_geometry(np.asarray(pairs, dtype=np.int64), nx, ny)
    return (end[:, 0, 0] * (ny + 1) + end[:, 0, 1]) * 2 + d


def _pair_graph(pairs: np.ndarray, nx: int, ny: int):
    """Connections between fault pillar pairs through shared pillars, with the relation of
    their coherent orientations (+1 same A→B sense, −1 opposite)."""
    end, d = _pair_geometry(pairs, nx, ny)
    k = pairs.size
    pil = (end[..., 0] * (ny + 1) + end[..., 1]).ravel()          # (2k,) pillar of each pair end
    who = np.repeat(np.arange(k), 2)
    which = np.tile([0, 1], k)
    o = np.argsort(pil, kind="stable")
    pil, who, which = pil[o], who[o], which[o]
    head = np.r_[True, pil[1:] != pil[:-1]]
    gid = np.cumsum(head) - 1
    gstart = np.flatnonzero(head)
    count = np.bincount(gid)
    slot = np.arange(pil.size) - gstart[gid]
    if slot.size and slot.max() >= 4:
        raise AssertionError("a pillar with more than four pillar pairs")
    tab = np.full((gstart.size, 4), -1)
    tab[gid, slot] = np.arange(pil.size)
    ea, eb = [], []
    for a in range(4):
        for b in range(a + 1, 4):
            x, y = tab[:, a], tab[:, b]
            ok = (x >= 0) & (y >= 0)
            x, y, c = x[ok], y[ok], count[ok]
            ok = (c == 2) | (d[who[x]] == d[who[y]])
            ea.append(x[ok])
            eb.append(y[ok])
    ea = np.concatenate(ea) if ea else np.zeros(0, int)
    eb = np.concatenate(eb) if eb else np.zeros(0, int)
    # coherent orientation: sign of n_AB · left(direction of travel) arriving along one pair
    # and leaving along the other through the shared pillar
    nAB = np.where(d[:, None] == 0, np.array([1, 0]), np.array([0, 1]))

    def sigma(e, arriving):
        p = who[e]
        here = end[p, which[e]]
        other = end[p, 1 - which[e]]
        t = here - other if arriving else other - here
        left = np.stack([-t[:, 1], t[:, 0]], 1)
        return np.sign((nAB[p] * left).sum(1))
    rel = sigma(ea, True) * sigma(eb, False)
    return who[ea], who[eb], rel


def _components(k: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    g = coo_array((np.ones(a.size, np.int8), (a, b)), shape=(k, k))
    return connected_components(g, directed=False)[1]


def _fault_keyword_faces(mesh: Mesh, info, grid, lateral: np.ndarray):
    """Name index (into the FAULTS names) of every interior lateral face, −1 if not named."""
    nx, ny, nz = info.dims
    names = list(grid.faults)
    keys, rank = [], []
    r = 0
    for n_i, name in enumerate(names):
        for (i1, i2, j1, j2, k1, k2, face) in grid.faults[name]:
            if face not in SIDE_OF_FACE:
                continue                                    # Z faults: not lateral
            i, j, k = np.meshgrid(np.arange(i1 - 1, i2), np.arange(j1 - 1, j2), np.arange(k1 - 1, k2),
                                  indexing="ij")
            nat = (i + nx * (j + ny * k)).ravel().astype(np.int64)
            keys.append(nat * 4 + SIDE_OF_FACE[face])
            rank.append(np.full(nat.size, r * len(names) + n_i))
            r += 1
    out = np.full(lateral.size, -1)
    if not keys:
        return names, out
    keys = np.concatenate(keys)
    rank = np.concatenate(rank)
    o = np.lexsort((rank, keys))
    keys, rank = keys[o], rank[o]
    first = np.r_[True, keys[1:] != keys[:-1]]
    keys, name_of = keys[first], rank[first] % len(names)
    fc = mesh.face_cells[lateral]
    is_i = info.face_kind[lateral] == 0
    ka = info.cell_index[fc[:, 0]].astype(np.int64) * 4 + np.where(is_i, 1, 3)    # A's east / north side
    kb = info.cell_index[fc[:, 1]].astype(np.int64) * 4 + np.where(is_i, 0, 2)    # B's west / south side
    for kq in (kb, ka):                                     # A's record wins over B's
        pos = np.minimum(np.searchsorted(keys, kq), keys.size - 1)
        hit = keys[pos] == kq
        out = np.where(hit, name_of[pos], out)
    return names, out


def detect_faults(mesh: Mesh, info, grid=None):
    """The info with its ``faults`` (name -> face ids) found from the geometry and FAULTS.

    Parameters
    ----------
    mesh : Mesh
    info : CornerPointInfo
    grid : CornerPointGrid, optional
        For the FAULTS keyword (names).
    """
    nx, ny, _ = info.dims
    lateral = np.flatnonzero((info.face_kind < 2) & (mesh.face_cells[:, 1] >= 0))
    named_idx = np.full(lateral.size, -1)
    names = []
    if grid is not None and grid.faults:
        names, named_idx = _fault_keyword_faces(mesh, info, grid, lateral)
    faults = {}
    for n_i, name in enumerate(names):
        f = lateral[named_idx == n_i]
        if f.size:
            faults[name] = f
    rest = lateral[(named_idx < 0) & info.face_displaced[lateral]]
    if rest.size:
        pairs, inv = np.unique(info.face_pair[rest], return_inverse=True)
        a, b, _ = _pair_graph(pairs, nx, ny)
        comp = _components(pairs.size, a, b)
        lab = comp[inv]
        # named in the order of their smallest pair key (integers of the grid: a face option or
        # the snapping renumbers the faces and may drop sliver faces, never a fault's pairs)
        first = np.full(comp.max() + 1, np.iinfo(np.int64).max)
        np.minimum.at(first, comp, pair_keys(pairs, nx, ny))
        order = np.argsort(first)
        n = 0
        for c in order:                                     # one per fault (a handful)
            n += 1
            while f"fault_{n}" in faults:
                n += 1
            faults[f"fault_{n}"] = rest[lab == c]
    faults = {k: frozen(np.sort(v).astype(INDEX)) for k, v in faults.items()}
    from types import MappingProxyType
    return dataclasses.replace(info, faults=MappingProxyType(faults))


def fault_faces(info, names=None) -> dict:
    """Face ids of the selected faults (all when ``names`` is None), for FracturedMesh.

    Raises InputError naming an unknown fault and listing the known ones.
    """
    if names is None:
        names = list(info.faults)
    out = {}
    for n in names:
        if n not in info.faults:
            raise InputError("faults", f"unknown fault {n!r}; this grid has {sorted(info.faults)}")
        out[n] = info.faults[n]
    return out


def fault_normals(mesh: Mesh, info, faces: np.ndarray) -> np.ndarray:
    """(k, 3) coherent n⁺ references of the given lateral faces (one fault or several).

    Along every connected surface (map-view connectivity of its pillar pairs) the + side stays
    on one side of the trace; each surface is then signed so that the largest component of
    its area-weighted mean normal is positive.
    """
    nx, ny, _ = info.dims
    faces = np.asarray(faces, dtype=np.int64)
    g = mesh.geometry
    pairs, inv = np.unique(info.face_pair[faces], return_inverse=True)
    if (pairs < 0).any():
        raise InputError("faults", "a fault face must be a lateral face (on a pillar pair)")
    a, b, rel = _pair_graph(pairs, nx, ny)
    k = pairs.size
    # doubled graph: (p, +) = p, (p, −) = p + k; relation +1 joins (a,+)-(b,+), −1 joins (a,+)-(b,−)
    da = np.concatenate([a, a + k])
    db = np.concatenate([np.where(rel > 0, b, b + k), np.where(rel > 0, b + k, b)])
    lab2 = _components(2 * k, da, db)
    comp = _components(k, a, b)
    root = np.full(comp.max() + 1, k)
    np.minimum.at(root, comp, np.arange(k))
    o = np.where(lab2[:k] == lab2[root[comp]], 1.0, -1.0)
    # face normals point from the face's first cell (side A) to its second (side B)
    n = g.face_normal[faces] * o[inv][:, None]
    fcomp = comp[inv]
    mean = np.zeros((comp.max() + 1, 3))
    np.add.at(mean, fcomp, g.face_area[faces][:, None] * n)
    big = np.argmax(np.abs(mean), axis=1)
    sgn = np.sign(mean[np.arange(mean.shape[0]), big])
    sgn[sgn == 0] = 1.0
    return n * sgn[fcomp][:, None]


def fractured_mesh(mesh: Mesh, info, names=None) -> FracturedMesh:
    """A :class:`FracturedMesh` whose fractures are the selected faults (all by default).

    Faults not selected stay bonded (ordinary interior faces). Fault intersections and
    faults ending inside the grid are handled by the fracture network (edges classified as
    intersection / tip) and the node sides.
    """
    sel = fault_faces(info, names)
    if not sel:
        return FracturedMesh(mesh, _assemble_network(mesh, (), (), np.zeros(0, INDEX), np.zeros(0, INDEX),
                                                     np.zeros((0, 3)), []), node_sides(mesh, np.zeros(0, INDEX)))
    fnames = tuple(sel)
    faces = np.concatenate([sel[n] for n in fnames]).astype(INDEX)
    fracs = np.concatenate([np.full(sel[n].size, i) for i, n in enumerate(fnames)]).astype(INDEX)
    if np.unique(faces).size != faces.size:
        raise InputError("faults", "two selected faults share faces")
    normals = np.concatenate([fault_normals(mesh, info, sel[n]) for n in fnames])
    measures = [float(mesh.geometry.face_area[sel[n]].sum()) for n in fnames]
    specs = tuple(FractureSpec(n, np.zeros((0, 3))) for n in fnames)
    network = _assemble_network(mesh, fnames, specs, faces, fracs, normals, measures)
    return FracturedMesh(mesh, network, node_sides(mesh, network.faces))


def fault_report(mesh: Mesh, info, names=None) -> dict:
    """Size and attitude of the faults (all when ``names`` is None), from their faces.

    Returns name -> dict with

    - ``faces``: number of mesh faces;
    - ``cells``: ``{"hanging_wall": n, "footwall": m}`` cells touching the fault on each side:
      the side its upward mean normal points into (above the fault), and the other side (for a
      vertical fault the side of the mean normal signed as in :func:`fault_normals`);
    - ``area_m2``: total face area (m²);
    - ``dip_deg``: dip of the mean plane from horizontal (degrees, 0–90);
    - ``dip_azimuth_deg``, ``strike_deg``: compass directions, degrees clockwise from north =
      +y of the mesh (map coordinates, x east), in [0, 360): the direction the plane dips
      towards, and strike = dip azimuth − 90° (right-hand rule: the plane dips to the right
      of the strike direction);
    - ``planarity``: |Σ A n| / Σ A of the coherently oriented faces (1 for a plane, smaller
      for curved or turning faults, whose mean attitude is less meaningful).

    The mean plane is that of the area-weighted mean of the coherent normals n⁺ (
    :func:`fault_normals`), not of a fit, so that a fault's report does not depend on its
    faces' numbering.
    """
    g = mesh.geometry
    out = {}
    for name in (list(info.faults) if names is None else names):
        f = fault_faces(info, [name])[name].astype(np.int64)
        n = fault_normals(mesh, info, f)
        A = g.face_area[f]
        m = (A[:, None] * n).sum(0)
        up = 1.0 if m[2] >= 0 else -1.0                     # the hanging wall is above the plane
        mlen = float(np.linalg.norm(m))
        u = up * m / max(mlen, 1e-300)
        # the second cell of a face is the one its normal points to
        to_b = np.einsum("fi,fi->f", g.face_normal[f], up * n) > 0
        fc = mesh.face_cells[f]
        hang = np.where(to_b, fc[:, 1], fc[:, 0])
        foot = np.where(to_b, fc[:, 0], fc[:, 1])
        h = float(np.hypot(u[0], u[1]))
        dip = float(np.degrees(np.arctan2(h, u[2])))
        # an upward normal leans towards the dip direction
        az = float(np.degrees(np.arctan2(u[0], u[1]))) % 360.0 if h > 1e-12 else 0.0
        out[name] = {"faces": int(f.size),
                     "cells": {"hanging_wall": int(np.unique(hang).size), "footwall": int(np.unique(foot).size)},
                     "area_m2": float(A.sum()), "dip_deg": dip, "dip_azimuth_deg": az,
                     "strike_deg": (az - 90.0) % 360.0, "planarity": mlen / max(float(A.sum()), 1e-300)}
    return out


def fault_table(report: dict, fractures: dict | None = None) -> list[str]:
    """Lines of a compact table of :func:`fault_report` (``fractures``: fault -> the name of
    the contact surface using it, shown in a column)."""
    fractures = fractures or {}
    head = (f"{'fault':<12} {'contact':<10} {'faces':>6} {'cells hw/fw':>11} {'area (m²)':>10} {'dip':>5} "
            f"{'dip az':>6} {'strike':>6}")
    rows = [head]
    for name, r in report.items():
        c = r["cells"]
        rows.append(f"{name:<12} {fractures.get(name, '-'):<10} {r['faces']:>6} "
                    f"{c['hanging_wall']:>5}/{c['footwall']:<5} {r['area_m2']:>10.4g} {r['dip_deg']:>4.0f}° "
                    f"{r['dip_azimuth_deg']:>5.0f}° {r['strike_deg']:>5.0f}°")
    return rows
