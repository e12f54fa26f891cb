"""Reference solutions computed on fine meshes, for cases without a closed form.

A reference file ``data/<name>-reference.npz`` holds, for one planar fracture, the slip
vector [[u]]_τ and λ_n of a fine run resampled on a regular grid of the fracture's plane
(in-plane frame origin + a e1 + b e2, a ∈ [0, La], b ∈ [0, Lb]) and the maximum slip
extrapolated from a sequence of fine meshes. ``benchmarks/cube_slip.py --reference``
remakes it. Errors of a run (:meth:`ReferenceSlip.errors`): maximum slip, relative L2 of
the slip magnitude over the whole fracture and with the 10 % next to every edge left out
(as in ../shared/evidence/3d-slip-porepy-cube.md), relative L2 of λ_n with the rim left out.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from ..core.errors import InputError

RIM = 0.1   # fraction of each side left out next to the fracture edges ("inner" errors)


@dataclass(frozen=True)
class ReferenceSlip:
    """Slip and λ_n of a fine run on a regular grid of a rectangular fracture's plane.

    Attributes
    ----------
    name : str
    origin, e1, e2 : (3,) float
        Corner of the fracture (m) and orthonormal in-plane directions along its sides.
    a, b : (na,), (nb,) float
        Grid coordinates along e1 and e2, m (from 0 to the side lengths).
    slip : (na, nb, 3) float
        Tangential jump [[u]]_τ at the grid points, m (0 on the edges: tip lines).
    lambda_n : (na, nb) float
        Normal multiplier λ_n, Pa.
    max_slip : float
        Maximum slip magnitude extrapolated to h → 0, m.
    note : str
        How the reference was computed (meshes, extrapolation).
    """

    name: str
    origin: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    a: np.ndarray
    b: np.ndarray
    slip: np.ndarray
    lambda_n: np.ndarray
    max_slip: float
    note: str = ""

    def plane_coordinates(self, X: np.ndarray) -> np.ndarray:
        """(n, 2) in-plane coordinates (a, b) of points X (n, 3), m."""
        R = np.asarray(X, float) - self.origin
        return np.stack([R @ self.e1, R @ self.e2], axis=1)

    def at(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reference slip (n, 3) and λ_n (n,) at points X (n, 3) of the fracture (bilinear)."""
        P = self.plane_coordinates(X)
        P = np.clip(P, [self.a[0], self.b[0]], [self.a[-1], self.b[-1]])
        s = RegularGridInterpolator((self.a, self.b), self.slip)(P)
        ln = RegularGridInterpolator((self.a, self.b), self.lambda_n)(P)
        return s, ln

    def inner(self, X: np.ndarray) -> np.ndarray:
        """(n,) bool: points at least RIM of each side length away from the edges."""
        P = self.plane_coordinates(X) / np.array([self.a[-1], self.b[-1]])
        return np.all((P > RIM) & (P < 1 - RIM), axis=1)

    def errors_of(self, X, area, slip, lambda_n, state_open) -> dict:
        """Errors of per-face values at face centroids X (n, 3) with areas (n,) (m²).

        ``slip`` (n, 3) tangential jumps (m), ``lambda_n`` (n,) (Pa), ``state_open`` (n,) bool.
        """
        s_ref, l_ref = self.at(X)
        mag, mag_ref = np.linalg.norm(slip, axis=1), np.linalg.norm(s_ref, axis=1)
        m = self.inner(X)

        def rel(e, r, keep):
            return float(np.sqrt(np.sum((area * e ** 2)[keep]) / np.sum((area * r ** 2)[keep])))

        every = np.ones(area.size, bool)
        return {"max_slip": float(mag.max(initial=0.0)),
                "max_slip_error_rel": float(abs(mag.max(initial=0.0) - self.max_slip) / self.max_slip),
                "slip_L2_rel": rel(mag - mag_ref, mag_ref, every),
                "slip_L2_rel_inner": rel(mag - mag_ref, mag_ref, m),
                "slip_vector_L2_rel_inner": rel(np.linalg.norm(slip - s_ref, axis=1), mag_ref, m),
                "lambda_n_L2_rel_inner": rel(lambda_n - l_ref, l_ref, m),
                "open_faces": int(np.sum(state_open))}

    def errors(self, problem, st) -> dict:
        """Errors of a static contact solution ``st`` of ``problem`` (ContactMechanics).

        The linear space is measured by its face means at the face centroids. The quadratic space
        (``order = 2``) is measured as a field, at the points of a face rule with its weights:
        comparing its face means with point values would cost O(h²) by itself and hide its
        accuracy (docs/accuracy_3d.md); λ_n is P0 in both and ``open_faces`` counts faces.
        """
        from ..models.contact import OPEN

        n = problem.normal
        ln = np.einsum("fi,fi->f", st.lam, n)
        is_open = np.asarray(st.state) == OPEN
        if hasattr(problem.space, "jump_quadrature"):
            X, W, J = problem.space.jump_quadrature()
            nq = W.size // max(problem.n_ff, 1)
            nn = np.repeat(n, nq, axis=0)
            q = J @ st.u
            qt = q - np.einsum("fi,fi->f", q, nn)[:, None] * nn
            out = self.errors_of(X, W, qt, np.repeat(ln, nq), np.repeat(is_open, nq))
            return out | {"open_faces": int(is_open.sum())}
        X = problem.fm.mesh.geometry.face_centroid[problem.fm.network.faces]
        q = problem.jumps(st)
        qt = q - np.einsum("fi,fi->f", q, n)[:, None] * n
        return self.errors_of(X, problem.face_area, qt, ln, is_open)


REFERENCES = ("cube-slip-3d",)


def load_reference(name: str, field: str = "exact.solution") -> ReferenceSlip:
    """The built-in reference ``name`` (one of REFERENCES). Raises InputError if unknown or missing."""
    if name not in REFERENCES:
        raise InputError(field, f"unknown reference {name!r}; allowed: {', '.join(REFERENCES)}")
    path = resources.files("polypore.cases") / "data" / f"{name}-reference.npz"
    if not path.is_file():
        raise InputError(field, f"the reference file {name}-reference.npz is missing from the installation; "
                         "remake it with benchmarks/cube_slip.py --reference")
    with np.load(str(path)) as z:
        return ReferenceSlip(name, z["origin"], z["e1"], z["e2"], z["a"], z["b"], z["slip"], z["lambda_n"],
                             float(z["max_slip"]), str(z["note"]))


def resample(X, slip, lambda_n, origin, e1, e2, lengths, n: int = 121) -> dict:
    """Arrays of a reference file from a fine run's per-face values (X (m, 3), slip (m, 3), λ_n (m,)).

    Linear interpolation of the face values on an n × n' grid (n' by the aspect ratio);
    the slip is set to 0 on the edges (tip lines) and extended by the nearest face value
    between the edge and the first face centroids for λ_n.
    """
    from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator

    origin, e1, e2 = (np.asarray(v, float) for v in (origin, e1, e2))
    La, Lb = lengths
    a = np.linspace(0.0, La, n)
    b = np.linspace(0.0, Lb, int(round(n * Lb / La)) | 1)
    R = np.asarray(X, float) - origin
    P = np.stack([R @ e1, R @ e2], axis=1)
    A, B = np.meshgrid(a, b, indexing="ij")
    G = np.stack([A.ravel(), B.ravel()], axis=1)
    vals = np.column_stack([slip, lambda_n])
    out = LinearNDInterpolator(P, vals)(G)
    miss = ~np.all(np.isfinite(out), axis=1)
    out[miss] = NearestNDInterpolator(P, vals)(G[miss])
    out = out.reshape(a.size, b.size, 4)
    s = out[..., :3]
    s[[0, -1], :, :] = 0.0
    s[:, [0, -1], :] = 0.0
    return {"origin": origin, "e1": e1, "e2": e2, "a": a, "b": b, "slip": s, "lambda_n": out[..., 3]}
