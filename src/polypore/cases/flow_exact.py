"""Manufactured mixed-dimensional Darcy solutions (cases ``darcy-manufactured-2d/3d`` and tests).

Ω = (0, 1)^d, s = x − ½, ζ = (last coordinate) − ½, e(y) = 1 + y²/2 in 3D (1 in 2D),
X(s) = 1 + c s²(3/4 − 2s) (X' = 6c s(¼ − s) vanishes at s = 0 and at the tip s = ¼).
Γ₁ = {s = 0} crosses Ω (+ side s < 0); Γ₂ = {ζ = 0, 0 ≤ s ≤ ¼} meets Γ₁ (T junction) and
has a tip at s = ¼ (a tip line in 3D, where Γ₂ also reaches y = 0 and y = 1). With
κ = K_m/η, Λ = Λ_f/η (exchange flux density Λ Δp), C = C_f/η, q(ζ) = 1 − cos 2πζ and
P = X(s) cos 2πζ e(y)::

    p⁺ = P + a⁺ q (s − κ/Λ)   (s < 0),        p⁻ = P + a⁻ q (s + κ/Λ)   (s > 0),
    p_f1 = P(s = 0) = cos 2πζ e(y),             p_f2 = P(ζ = 0) = X(s) e(y).

Exchange on Γ₁ holds exactly: −κ∂ₓp⁺ = Λ(p⁺ − p_f1) = −κ a⁺ q and κ∂ₓp⁻ = Λ(p⁻ − p_f1) =
κ a⁻ q, so the traces jump by [[p]] = −κ(a⁺ + a⁻) q/Λ and the fracture leaks
κ q (a⁻ − a⁺). On Γ₂, q = q' = 0 and ∂_ζ P = 0: no jump, no exchange, p_f2 is the matrix
trace, ∂ₛ p_f2 = 0 at the tip (no-flow) and at the junction, where p_f1 = p_f2. Sources:
h_m = −κΔp±, h_f1 = −C Δ_τ p_f1 − κ q (a⁻ − a⁺), h_f2 = −C Δ_τ p_f2 (derived by hand,
checked by finite differences in tests/convergence/test_flow_convergence.py).

All quantities are dimensionless in the built-in cases (K_m = η = 1); in SI units pressures
are in Pa, κ in m²/(Pa·s), Λ in m/(Pa·s), C in m³/(Pa·s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.errors import InputError
from ..mesh import FractureSpec

PI = np.pi
NAMES = ("darcy-manufactured-2d", "darcy-manufactured-3d")


def fracture_specs(dim: int) -> list[FractureSpec]:
    """Γ₁ ("G1", crossing Ω at x = ½) and Γ₂ ("G2", T junction, tip at x = ¾)."""
    if dim == 2:
        return [FractureSpec("G1", np.array([[0.5, 0.0], [0.5, 1.0]])),
                FractureSpec("G2", np.array([[0.5, 0.5], [0.75, 0.5]]))]
    return [FractureSpec("G1", np.array([[0.5, 0, 0], [0.5, 1, 0], [0.5, 1, 1], [0.5, 0, 1.0]]),
                         normal=np.array([1.0, 0, 0])),
            FractureSpec("G2", np.array([[0.5, 0, 0.5], [0.75, 0, 0.5], [0.75, 1, 0.5], [0.5, 1, 0.5]]))]


def _cols(X, dim):
    X = np.atleast_2d(np.asarray(X, float))
    z = X[:, 2] if dim == 3 else np.zeros(X.shape[0])
    return X[:, 0], X[:, 1], z


@dataclass(frozen=True)
class DarcyManufactured:
    """The manufactured solution and its sources.

    Parameters
    ----------
    dim : 2 or 3.
    kappa : K_m/η, m²/(Pa·s) (isotropic).  lam : Λ_f/η, m/(Pa·s).  cond : C_f/η, m³/(Pa·s).
    a_plus, a_minus : slopes of the jump terms (a⁺ + a⁻ ≠ 0 gives a pressure jump, a⁻ ≠ a⁺ a leak).
    c_x : amplitude c of X(s).
    """

    dim: int
    kappa: float = 1.0
    lam: float = 1.0
    cond: float = 0.5
    a_plus: float = 1.0
    a_minus: float = -0.5
    c_x: float = 16.0

    # -- profile X(s) --------------------------------------------------------------------------
    def px(self, s):
        return 1 + self.c_x * s ** 2 * (0.75 - 2 * s)

    def dpx(self, s):
        return 6 * self.c_x * s * (0.25 - s)

    def d2px(self, s):
        return 6 * self.c_x * (0.25 - 2 * s)

    def _parts(self, x, y, z):
        x, y, z = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float), np.asarray(z, float))
        s = x - 0.5
        zeta = (y if self.dim == 2 else z) - 0.5
        e = np.ones_like(s) if self.dim == 2 else 1 + 0.5 * y ** 2
        e2 = 0.0 if self.dim == 2 else 1.0                     # e''
        P = self.px(s) * np.cos(2 * PI * zeta) * e
        q = 1 - np.cos(2 * PI * zeta)
        return s, zeta, e, e2, P, q

    # -- matrix --------------------------------------------------------------------------------
    def p(self, x, y, z=0.0, t=0.0):
        """Matrix pressure p± (Pa); on Γ₁ itself (|s| ≤ 1e−12) the fracture value P."""
        s, zeta, e, e2, P, q = self._parts(x, y, z)
        r = self.kappa / self.lam
        plus = P + self.a_plus * q * (s - r)
        minus = P + self.a_minus * q * (s + r)
        return np.where(s < -1e-12, plus, np.where(s > 1e-12, minus, P))

    def grad(self, X, side):
        """∇p (k, d) at points X (k, d) on the given side (+1: s < 0, −1: s > 0), Pa/m."""
        x, y, z = _cols(X, self.dim)
        s, zeta, e, e2, P, q = self._parts(x, y, z)
        a = np.where(side > 0, self.a_plus, self.a_minus)
        off = np.where(side > 0, -self.kappa / self.lam, self.kappa / self.lam)
        c4 = self.px(s)
        c2, s2 = np.cos(2 * PI * zeta), np.sin(2 * PI * zeta)
        gx = self.dpx(s) * c2 * e + a * q
        gz = -2 * PI * c4 * s2 * e + a * (2 * PI * s2) * (s + off)
        if self.dim == 2:
            return np.stack([gx, gz], 1)
        return np.stack([gx, c4 * c2 * y, gz], 1)

    def h_m(self, x, y, z=0.0, t=0.0):
        """Matrix source h_m = −κΔp (1/s)."""
        s, zeta, e, e2, P, q = self._parts(x, y, z)
        c2 = np.cos(2 * PI * zeta)
        lapP = self.d2px(s) * c2 * e - 4 * PI ** 2 * P + self.px(s) * c2 * e2
        a = np.where(s < 0, self.a_plus, self.a_minus)
        off = np.where(s < 0, -self.kappa / self.lam, self.kappa / self.lam)
        return -self.kappa * (lapP + a * 4 * PI ** 2 * c2 * (s + off))

    # -- fractures -----------------------------------------------------------------------------
    def p_f(self, X, on1):
        """Fracture pressure (Pa) at points X (k, d); ``on1`` (k,) bool: the point is on Γ₁."""
        s, zeta, e, e2, P, q = self._parts(*_cols(X, self.dim))
        return np.where(on1, np.cos(2 * PI * zeta) * e, self.px(s) * e)

    def h_f(self, X, on1):
        """Fracture source h_f (m/s) at points X on Γ₁ (``on1``) or Γ₂."""
        s, zeta, e, e2, P, q = self._parts(*_cols(X, self.dim))
        c2 = np.cos(2 * PI * zeta)
        lap1 = -4 * PI ** 2 * c2 * e + c2 * e2
        lap2 = self.d2px(s) * e + self.px(s) * e2
        return np.where(on1, -self.cond * lap1 - self.kappa * q * (self.a_minus - self.a_plus), -self.cond * lap2)

    def traces(self, X, on1):
        """(k, 2) exact + and − matrix traces at fracture points (on Γ₂ both equal p_f)."""
        pf = self.p_f(X, on1)
        Xp, Xm = np.array(X, float), np.array(X, float)
        Xp[:, 0] -= 1e-9
        Xm[:, 0] += 1e-9
        trp = np.where(on1, self.p(*_cols(Xp, self.dim)), pf)
        trm = np.where(on1, self.p(*_cols(Xm, self.dim)), pf)
        return np.stack([trp, trm], 1)


def gamma1_mask(fm, field: str = "exact.solution") -> np.ndarray:
    """(n_ff,) bool: fracture faces on Γ₁ = {x = ½}; checks the network is G1 ∪ G2 of the solution.

    Raises InputError (naming ``field``) if the case's fractures are not those of the solution.
    """
    net = fm.network
    names = list(net.names)
    if sorted(names) != ["G1", "G2"]:
        raise InputError(field, f"the manufactured Darcy solution needs exactly the fractures G1 (x = 0.5) and G2 "
                         f"(tip at x = 0.75); the case has {names}")
    xf = fm.mesh.geometry.face_centroid[net.faces]
    on1 = net.fracture == names.index("G1")
    zeta = xf[:, fm.mesh.dim - 1]
    ok1 = np.abs(xf[on1, 0] - 0.5) < 1e-9
    ok2 = (np.abs(zeta[~on1] - 0.5) < 1e-9) & (xf[~on1, 0] > 0.5) & (xf[~on1, 0] < 0.75 + 1e-9)
    if not (ok1.all() and ok2.all()):
        raise InputError(field, "the fractures G1/G2 do not match the manufactured solution's geometry "
                         "(G1 on x = 0.5, G2 on the last coordinate = 0.5 for 0.5 ≤ x ≤ 0.75)")
    if not np.all(np.asarray(net.normal)[on1, 0] > 0):
        raise InputError(field, "the + side of G1 must be x < 0.5 (n⁺ = e_x): order its 2D vertices with y "
                         "increasing, or give normal = [1, 0, 0] in 3D")
    return on1


def flow_errors(model, sol, exact: DarcyManufactured, on1: np.ndarray) -> dict:
    """Relative discrete L2 errors of a steady FlowSolution against ``exact``.

    Returns
    -------
    dict with ``p_cell_L2`` (p_K at centroids, weights |K|), ``p_fracture_L2`` (p_f at face
    centroids, weights |σ|), ``p_trace_L2`` (both traces) and ``grad_p_L2`` (broken gradient
    ‖∇_Kσ p − ∇p(x_K)‖ with weights |σ| d_Kσ/d, relative to ‖∇p(x_K)‖ weighted by |K|).
    """
    mesh, net = model.mesh, model.network
    g = mesh.geometry
    xc, vol = g.cell_centroid, g.cell_volume
    pc = exact.p(*_cols(xc, mesh.dim))
    out = {"p_cell_L2": float(np.sqrt(np.sum(vol * (sol.cell - pc) ** 2) / np.sum(vol * pc ** 2)))}
    xf = g.face_centroid[net.faces]
    af = g.face_area[net.faces]
    pf = exact.p_f(xf, on1)
    out["p_fracture_L2"] = float(np.sqrt(np.sum(af * (sol.fracture - pf) ** 2) / np.sum(af * pf ** 2)))
    tr = exact.traces(xf, on1)
    out["p_trace_L2"] = float(np.sqrt(np.sum(af[:, None] * (sol.trace - tr) ** 2) / np.sum(af[:, None] * tr ** 2)))
    gK, gKs, w = model.assembler.hfv.gradients(sol.cell, slot_values(model, sol))
    side = np.where(xc[:, 0] < 0.5, 1, -1)
    gex = exact.grad(xc, side)
    rows = mesh.cell_faces.rows_of_entries()
    out["grad_p_L2"] = float(np.sqrt(np.sum(w * np.sum((gKs - gex[rows]) ** 2, 1)) / np.sum(vol * np.sum(gex ** 2, 1))))
    return out


def slot_values(model, sol) -> np.ndarray:
    """Face values seen from each (cell, face) slot: p_σ, or on a fracture face the cell's side trace."""
    d = model.assembler.dofs
    x = np.zeros(d.n)
    ok = d.face >= 0
    x[d.face[ok]] = sol.face[ok]
    x[d.trace] = sol.trace
    return x[d.slot]
