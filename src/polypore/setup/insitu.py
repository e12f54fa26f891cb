"""The ``[initial_state]`` table (C6): a gravitational in-situ equilibrium the run starts from.

Keys (SI units; checked by :class:`polypore.setup.schema.case.InitialState`)::

    [initial_state]
    gravity = 9.81            # g (m/s²), acting along −x_d (the last coordinate is up)
    rock_density = 2260.0     # ρ_r (kg/m³): σ_v = ρ_r g z
    fluid_density = 1000.0    # ρ_w (kg/m³): p_h = p_s + ρ_w g z
    stress_ratio = 0.7        # k = σ_h/σ_v in (0, ∞)
    stress_ratio_max = 1.2    # 3D, optional: k_H = σ_H/σ_v of the largest horizontal stress (default k)
    azimuth = 30.0            # 3D: direction of σ_H, degrees from +x towards +y
    surface = 0.0             # elevation of the ground surface (m): depth z = surface − x_d ≥ 0
    surface_pressure = 0.0    # p_s (Pa)
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..core.errors import InputError
from .casefile import CaseFile


@dataclasses.dataclass(frozen=True)
class ReferenceState:
    """The ``[initial_state]`` table: a gravitational in-situ equilibrium (C6).

    Depth z = surface − x_d (x_d the last coordinate, up). Total stress (compression < 0)
    σ⁰ = −diag(k σ_v, …, σ_v) with σ_v = ρ_r g z (in 3D with ``stress_ratio_max`` k_H, plus
    −(k_H − k) σ_v a aᵀ, a the horizontal unit vector at ``azimuth`` from +x); hydrostatic pressure p_h = p_s + ρ_w g z.
    σ⁰ is in equilibrium with the rock weight ρ_r g and with the lithostatic load on the top,
    and p_h with the fluid weight, so the run computes increments from this state: the
    pressures of the ``[flow]`` table (initial, boundary) are relative to p_h, the mechanical
    loads are increments, and the fracture faces start from λ⁰ = −(σ⁰ n⁺ + p_h n⁺), the
    effective in-situ traction, on which the contact law acts.

    Attributes (SI): gravity g (m/s²), rock_density ρ_r and fluid_density ρ_w (kg/m³),
    stress_ratio k = σ_h/σ_v, surface (m), surface_pressure p_s (Pa).
    """

    gravity: float
    rock_density: float
    fluid_density: float
    stress_ratio: float
    surface: float
    surface_pressure: float
    stress_ratio_max: float | None = None
    azimuth: float = 0.0

    def depth(self, x: np.ndarray) -> np.ndarray:
        return self.surface - x[:, -1]

    def stress(self, x: np.ndarray) -> np.ndarray:
        """(n, d, d) σ⁰ at points x (n, d), Pa."""
        n, d = x.shape
        sv = self.rock_density * self.gravity * self.depth(x)
        diag = np.full((n, d), self.stress_ratio) * sv[:, None]
        diag[:, -1] = sv
        s0 = -np.einsum("ni,ij->nij", diag, np.eye(d))
        if d == 3 and self.stress_ratio_max is not None:
            # σ_H = k_H σ_v along the azimuth a: add (k_H − k) σ_v a aᵀ in the horizontal plane
            th = np.radians(self.azimuth)
            a = np.array([np.cos(th), np.sin(th), 0.0])
            s0 -= ((self.stress_ratio_max - self.stress_ratio) * sv)[:, None, None] * np.outer(a, a)[None]
        return s0

    def pressure(self, x: np.ndarray) -> np.ndarray:
        """(n,) p_h at points x, Pa."""
        return self.surface_pressure + self.fluid_density * self.gravity * self.depth(x)

    def traction(self, fm) -> np.ndarray:
        """(n_ff, d) λ⁰ = −(σ⁰ n⁺ + p_h n⁺) at the fracture-face centroids, Pa."""
        net = fm.network
        x = fm.mesh.geometry.face_centroid[net.faces]
        n = net.normal
        return -(np.einsum("fij,fj->fi", self.stress(x), n) + self.pressure(x)[:, None] * n)


def reference_state(case: CaseFile, fm) -> ReferenceState | None:
    """The ``[initial_state]`` table (checked by the schema) for the mesh ``fm``, or None."""
    s = case.spec.initial_state
    if s is None:
        return None
    top = float(fm.mesh.nodes[:, -1].max())
    if top > s.surface + 1e-9 * max(1.0, abs(s.surface)):
        raise InputError("initial_state.surface", f"the domain reaches the elevation {top:g} m above the surface "
                         f"{s.surface:g} m; the depth must be ≥ 0 everywhere")
    if s.stress_ratio_max is not None and fm.mesh.dim != 3:
        raise InputError("initial_state.stress_ratio_max", "applies to 3D meshes only (in 2D the horizontal stress is "
                         "stress_ratio σ_v)")
    return ReferenceState(s.gravity, s.rock_density, s.fluid_density, s.stress_ratio, s.surface, s.surface_pressure,
                          s.stress_ratio_max, s.azimuth)
