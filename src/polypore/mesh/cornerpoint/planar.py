"""Warped faces split into planar triangles (``nonplanar`` of :func:`.process.process_grid`)."""

from __future__ import annotations

import numpy as np

from ...core.errors import InputError
from ...core.ragged import INDEX, Ragged

NONPLANAR_TOL = 1e-12      # relative distance of a node to its face's plane above which a face is split


def split_nonplanar_faces(X: np.ndarray, faces: Ragged, mode: str = "centre", is_vertex: np.ndarray | None = None,
                          tol: float = NONPLANAR_TOL, candidates: np.ndarray | None = None):
    """Split warped faces into planar triangles (see ``nonplanar`` of :func:`process_grid`).

    The centre node of a split face is the average of its polygon vertices (``is_vertex``,
    aligned with ``faces.values``; default all nodes), not of the nodes inserted on its edges:
    for a quadrilateral whose edges carry collinear inserted nodes the triangles then cover
    exactly the four triangles around the bilinear face's midpoint, so that the cell volume
    stays the trilinear (corner-point) one. ``candidates`` (n_faces,) bool: the faces that may
    be warped (default all).

    Returns ``(X, faces, parent)``: the nodes (new centre nodes appended), the faces (kept
    ones first, in order, then the triangles) and the original face of every face.
    Triangles keep the orientation of their face.
    """
    if mode not in ("centre", "diagonal", "keep"):
        raise InputError("nonplanar", f"must be 'centre', 'diagonal' or 'keep', got {mode!r}")
    nf = len(faces)
    if mode == "keep":
        return X, faces, np.arange(nf)
    warped = np.zeros(nf, bool)
    for m, rows, conn in faces.groups():
        if m == 3:
            continue
        if candidates is not None:
            sel = candidates[rows]
            rows, conn = rows[sel], conn[sel]
        if m == 4:
            # a quadrilateral's nodes are all ±w·n/4 off its vector-area plane, w = a − b + c − d
            a, b, c, d = (X[conn[:, i]] for i in range(4))
            n = np.cross(c - a, d - b)
            w = a - b + c - d
            dist = np.abs(np.einsum("ki,ki->k", w, n)) / (4 * np.maximum(np.linalg.norm(n, axis=1), 1e-300))
            size = np.maximum(np.linalg.norm(c - a, axis=1), np.linalg.norm(d - b, axis=1))
            warped[rows] = dist > tol * size
            continue
        P = X[conn]
        c = P.mean(1)
        Y = P - c[:, None]
        A = 0.5 * np.cross(Y, np.roll(Y, -1, axis=1)).sum(1)
        n = A / np.maximum(np.linalg.norm(A, axis=1), 1e-300)[:, None]
        dist = np.abs(np.einsum("kmi,ki->km", Y, n)).max(1)
        warped[rows] = dist > tol * 2 * np.linalg.norm(Y, axis=2).max(1)
    keep = np.flatnonzero(~warped)
    counts, values, parent = [faces.counts[keep]], [faces.take(keep).values], [keep]
    new_nodes = []
    n0 = X.shape[0]
    for m, rows, conn in faces.groups():
        sel = warped[rows]
        if not sel.any():
            continue
        rows, conn = rows[sel], conn[sel]
        if mode == "diagonal" and m == 4:
            a, b, c, d = (X[conn[:, i]] for i in range(4))

            def cosang(p, q, r, t):
                n1, n2 = np.cross(q - p, r - p), np.cross(r - p, t - p)
                return np.einsum("ki,ki->k", n1, n2) / np.maximum(
                    np.linalg.norm(n1, axis=1) * np.linalg.norm(n2, axis=1), 1e-300)
            c1, c2 = cosang(a, b, c, d), cosang(b, c, d, a)
            ok = np.maximum(c1, c2) > 0
            first = c1 >= c2
            q = conn[ok]
            tri = np.where(first[ok][:, None, None], np.stack([q[:, [0, 1, 2]], q[:, [0, 2, 3]]], 1),
                           np.stack([q[:, [1, 2, 3]], q[:, [1, 3, 0]]], 1))
            counts.append(np.full(2 * tri.shape[0], 3))
            values.append(tri.ravel())
            parent.append(np.repeat(rows[ok], 2))
            rows, conn = rows[~ok], conn[~ok]
            if not rows.size:
                continue
        cid = n0 + sum(len(v) for v in new_nodes) + np.arange(rows.size)
        if is_vertex is None:
            new_nodes.append(X[conn].mean(1))
        else:
            w = is_vertex[faces.positions(rows, m)].astype(float)
            new_nodes.append(np.einsum("km,kmi->ki", w, X[conn]) / w.sum(1)[:, None])
        tri = np.stack([np.broadcast_to(cid[:, None], conn.shape), conn, np.roll(conn, -1, axis=1)], 2)
        counts.append(np.full(tri.shape[0] * m, 3))
        values.append(tri.ravel())
        parent.append(np.repeat(rows, m))
    if new_nodes:
        X = np.vstack([X] + new_nodes)
    return X, Ragged.from_counts(np.concatenate(counts), np.concatenate(values).astype(INDEX)), np.concatenate(parent)


def pairs_may_warp(top, bot, p0, p1) -> np.ndarray:
    """(k,) bool: lateral faces on the pillar pairs (p0, p1) may be warped. A pair of coplanar
    pillars (parallel or meeting) carries planar faces only: those are not checked."""
    Tq = top[np.stack([p0, p1], 1)]
    Dq = bot[np.stack([p0, p1], 1)] - Tq
    w = np.einsum("ki,ki->k", Tq[:, 1] - Tq[:, 0], np.cross(Dq[:, 0], Dq[:, 1]))
    mag = (np.linalg.norm(Tq[:, 1] - Tq[:, 0], axis=1) * np.linalg.norm(Dq[:, 0], axis=1)
           * np.linalg.norm(Dq[:, 1], axis=1))
    return np.abs(w) > 1e-14 * mag
