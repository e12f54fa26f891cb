"""Piecewise-smooth exact displacements with their strain, stress, body force and multiplier.

Each solution is given symbolically (sympy) per piece of Ω∖Γ, with a selector telling which
piece a point belongs to; everything else (∇u, σ(u), f = −div σ(u), λ = −σ(u)⁺ n⁺ on Γ) is
derived symbolically and turned into vectorised numpy functions.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Callable

import numpy as np
import sympy as S

X, Y, Z = S.symbols("x y z", real=True)


@dataclass(frozen=True, eq=False)
class PiecewiseSolution:
    """u on pieces of Ω∖Γ, with μ and λ_L constant (Pa).

    Attributes
    ----------
    dim : 2 or 3
    piece : callable (n, d) points -> (n,) piece index
    u, grad, f : lists over pieces of numpy callables (n, d) -> (n, d) / (n, d, d) / (n, d)
    """

    name: str
    dim: int
    piece: Callable
    u_fns: tuple
    grad_fns: tuple
    stress_fns: tuple
    f_fns: tuple

    def _eval(self, fns, P, shape):
        P = np.atleast_2d(np.asarray(P, float))
        out = np.zeros((P.shape[0],) + shape)
        k = self.piece(P)
        for i, fn in enumerate(fns):
            sel = k == i
            if np.any(sel):
                out[sel] = fn(P[sel])
        return out

    def u(self, P, t=0.0):
        """(n, d) displacement in m."""
        return self._eval(self.u_fns, P, (self.dim,))

    def grad(self, P, t=0.0):
        """(n, d, d) ∇u, (∇u)_ij = ∂u_i/∂x_j."""
        return self._eval(self.grad_fns, P, (self.dim, self.dim))

    def stress(self, P, t=0.0):
        """(n, d, d) σ(u) in Pa."""
        return self._eval(self.stress_fns, P, (self.dim, self.dim))

    def body_force(self, P, t=0.0):
        """(n, d) f = −div σ(u) in N/m³."""
        return self._eval(self.f_fns, P, (self.dim,))

    def multiplier(self, P_plus, normal):
        """(n, d) λ = −σ(u)⁺ n⁺ at points evaluated on the + side (caller nudges them into K⁺)."""
        return -np.einsum("nij,nj->ni", self.stress(P_plus), normal)


def _lambdify(exprs, dim, shape):
    syms = (X, Y, Z)[:dim]
    flat = [S.sympify(e) for e in np.ravel(np.array(exprs, dtype=object))]
    fns = [S.lambdify(syms, e, "numpy") for e in flat]

    def fn(P):
        cols = [P[:, k] for k in range(dim)]
        vals = [np.broadcast_to(np.asarray(f(*cols), float), (P.shape[0],)) for f in fns]
        return np.stack(vals, axis=1).reshape((P.shape[0],) + shape)

    return fn


def build_solution(name, dim, pieces, selector, mu, lam) -> PiecewiseSolution:
    """Derive ∇u, σ and f = −div σ for every piece's sympy displacement (a list of d expressions)."""
    syms = (X, Y, Z)[:dim]
    u_f, g_f, s_f, f_f = [], [], [], []
    for u in pieces:
        u = [S.sympify(c) for c in u]
        G = [[S.diff(u[i], syms[j]) for j in range(dim)] for i in range(dim)]
        div = sum(G[i][i] for i in range(dim))
        sig = [[mu * (G[i][j] + G[j][i]) + (lam * div if i == j else 0) for j in range(dim)] for i in range(dim)]
        f = [-sum(S.diff(sig[i][j], syms[j]) for j in range(dim)) for i in range(dim)]
        u_f.append(_lambdify(u, dim, (dim,)))
        g_f.append(_lambdify(G, dim, (dim, dim)))
        s_f.append(_lambdify(sig, dim, (dim, dim)))
        f_f.append(_lambdify(f, dim, (dim,)))
    return PiecewiseSolution(name, dim, selector, tuple(u_f), tuple(g_f), tuple(s_f), tuple(f_f))


@lru_cache(maxsize=None)
def frictionless_3d(mu: float = 1.0, lam: float = 1.0) -> PiecewiseSolution:
    """Case C1 (cases.md): T-shaped network Γ1 = {z = 0}, Γ2 = {x = 0, z < 0}, λ = 0 on Γ."""
    g = -S.sin(S.pi * X / 2) * S.cos(S.pi * Y / 2)
    p = Z**2
    h = S.cos(S.pi * X / 2)
    H = S.integrate(h.subs(X, S.Symbol("s")), (S.Symbol("s"), 0, X))
    pp, pm = Z**4, 2 * Z**4
    top = [g * p, p, X**2 * p]
    left = [h * pp, h * S.diff(pp, Z), -H * S.diff(pp, Z)]
    right = [h * pm, h * S.diff(pm, Z), -H * S.diff(pm, Z)]

    def selector(P):
        return np.where(P[:, 2] >= 0, 0, np.where(P[:, 0] < 0, 1, 2))

    return build_solution("frictionless-3d", 3, [top, left, right], selector, mu, lam)


def _pos4(a):
    """max(0, a)^4: C³ across a = 0, so f = −div σ stays bounded."""
    return S.Piecewise((a**4, a > 0), (0, True))


FRICTION_C2 = 0.5
SLIP_AMPLITUDE_C2 = 300.0


def contact_manufactured(dim: int, mu: float = 1.0, lam: float = 1.0, F: float = FRICTION_C2) -> PiecewiseSolution:
    """Case C2 (cases.md): a Tresca/Coulomb manufactured solution with open, slip and stick zones.

    Γ = {y = 0 (2D) / z = 0 (3D), −1 < x < 1/2} in Ω = (−1, 1)^d: it reaches ∂Ω at x = −1 and
    has a tip at x = 1/2. K⁺ is below Γ, n⁺ = e_y (e_z). With e the normal coordinate (y or z):

    * u_c = e (τ(x)/μ, s(x)/(λ+2μ)) on all of Ω (normal/tangential parts in the (x, e) plane) has
      traction σ(u_c) n⁺ = (τ, s) on e = 0, so λ = −(τ, s): λ_n = −s, λ_τ = −τ e_x;
    * w = (f + e g, h + e k) with g = −h', k = −λ f'/(λ+2μ), added above Γ only, has zero
      traction on e = 0 and gives the jump [[u]] = −(f, h).

    Zones along Γ: x < −1/2 open (s = τ = 0, h = (−1/2 − x)^4 > 0); −1/2 < x < 1/10 slip
    (h = 0, f = C (x+1/2)^4 (1/10 − x)^4 > 0, τ = F|s|, so λ_τ ∥ [[u]]_τ and |λ_τ| = F λ_n);
    1/10 < x < 1/2 stick (f = h = 0, |τ| = F|s| χ with χ < 1). s = −r/(r + 0.2⁴),
    r = (x + 1/2)^4_+, so that λ_n is O(1) where the fracture is closed. The Tresca
    variant uses the threshold g(x) = F|s(x)|, which makes the same u, λ its solution.
    """
    e = Y if dim == 2 else Z
    x = X
    r4 = _pos4(x + S.Rational(1, 2))
    s_ = -r4 / (r4 + S.Rational(1, 5) ** 4)   # rises smoothly from 0 at x = −1/2 to O(1) by x ≈ −0.3
    chi = 1 - 10 * _pos4(x - S.Rational(1, 10))
    tau = -F * s_ * chi
    f = SLIP_AMPLITUDE_C2 * _pos4(x + S.Rational(1, 2)) * _pos4(S.Rational(1, 10) - x)
    h = _pos4(-S.Rational(1, 2) - x)
    g = -S.diff(h, x)
    k = -lam * S.diff(f, x) / (lam + 2 * mu)
    uc_t, uc_n = e * tau / mu, e * s_ / (lam + 2 * mu)
    w_t, w_n = f + e * g, h + e * k
    if dim == 2:
        below = [uc_t, uc_n]
        above = [uc_t + w_t, uc_n + w_n]
    else:
        below = [uc_t, 0, uc_n]
        above = [uc_t + w_t, 0, uc_n + w_n]

    def selector(P):
        return np.where(P[:, dim - 1] >= 0, 1, 0)

    return build_solution(f"contact-manufactured-{dim}d", dim, [below, above], selector, mu, lam)


SOLUTIONS = {"frictionless-3d": frictionless_3d,
             "contact-2d": lambda mu, lam: contact_manufactured(2, mu, lam),
             "contact-3d": lambda mu, lam: contact_manufactured(3, mu, lam)}
PROFILES = ("single-crack", "penny-shaped-crack")   # analytic profiles, wired in mechanics_setup


def get_solution(name: str, mu: float, lam: float):
    from ..core.errors import InputError

    if name in SOLUTIONS:
        return SOLUTIONS[name](float(mu), float(lam))
    from .reference import REFERENCES

    raise InputError("exact.solution", f"unknown exact solution {name!r}; allowed: "
                     f"{', '.join(list(SOLUTIONS) + list(PROFILES) + list(REFERENCES))}")


# ---------------------------------------------------------------------------- error measures

def _plus_points(problem):
    """Fracture-face centroids nudged into K⁺ (exact data evaluated on the + piece)."""
    g = problem.fm.mesh.geometry
    net = problem.fm.network
    xc = g.face_centroid[net.faces]
    return xc + 1e-12 * (g.cell_centroid[net.plus_cell] - xc)


def piecewise_errors(problem, st, sol: PiecewiseSolution) -> dict:
    """grad_u_L2 = ‖∇^D u_D − ∇u‖_{L2(Ω∖Γ)} (∇u at cell centroids), lambda_L2 and lambda_h12
    (discrete L2 and h^{1/2}-weighted L2 on Γ of λ_D − λ), plus relative versions."""
    mesh = problem.fm.mesh
    g = mesh.geometry
    G = problem.gradients(st)
    Gex = sol.grad(g.cell_centroid)
    vol = g.cell_volume
    e = np.sqrt(np.sum(vol * np.sum((G - Gex) ** 2, axis=(1, 2))))
    ref = np.sqrt(np.sum(vol * np.sum(Gex ** 2, axis=(1, 2))))
    out = {"grad_u_L2": float(e), "grad_u_L2_rel": float(e / ref) if ref > 0 else float("nan")}
    if problem.n_ff:
        lam_ex = sol.multiplier(_plus_points(problem), problem.normal)
        A = problem.face_area
        h = g.face_diameter[problem.fm.network.faces]
        dl = np.sum((st.lam - lam_ex) ** 2, axis=1)
        out["lambda_L2"] = float(np.sqrt(np.sum(A * dl)))
        out["lambda_h12"] = float(np.sqrt(np.sum(h * A * dl)))
    return out


@dataclass(frozen=True)
class SingleCrack:
    """Case C3 (cases.md): analytic λ_n and slip along an inclined crack under compression.

    λ_n = σ̄ sin²ψ; |[[u]]_τ|(ξ) = 4(1 − ν²)/E σ̄ sin ψ (cos ψ − F sin ψ) sqrt(ℓ² − (ℓ − ξ)²)
    (plane strain; the slides print 1 − ν, the plane-strain value has 1 − ν²).
    """

    sigma: float
    psi: float
    half_length: float
    E: float
    nu: float
    friction: float

    def lambda_n(self, xi):
        return np.full_like(np.asarray(xi, float), self.sigma * np.sin(self.psi) ** 2)

    def slip(self, xi):
        xi = np.asarray(xi, float)
        ell = self.half_length
        amp = 4 * (1 - self.nu ** 2) / self.E * self.sigma * np.sin(self.psi) * (
            np.cos(self.psi) - self.friction * np.sin(self.psi))
        return amp * np.sqrt(np.clip(ell ** 2 - (ell - xi) ** 2, 0, None))

    def errors(self, problem, st, s) -> dict:
        A = problem.face_area
        q = problem.jumps(st)
        n = problem.normal
        qn = np.einsum("fi,fi->f", q, n)
        slip = np.linalg.norm(q - qn[:, None] * n, axis=1)
        ln = np.einsum("fi,fi->f", st.lam, n)
        se, le = self.slip(s), self.lambda_n(s)
        # λ_n next to the tips follows the discrete crack-tip singularity (errors ~ h^{-1/2} on
        # the last faces, whatever the mesh size), so its L2 error has an O(1) part from the tip
        # faces; the error away from the tips (|ξ − ℓ| ≤ 0.9 ℓ) and the h^{1/2}-weighted one
        # (the H^{-1/2} stand-in of C1) show the convergence of the rest.
        far = np.abs(s - self.half_length) <= 0.9 * self.half_length
        net = problem.fm.network
        h = problem.fm.mesh.geometry.face_diameter[net.faces]
        # (T⁺ − T⁻)/2: the one-sided tractions of the two cells of each face averaged (the
        # discrete T⁺ and −T⁻ differ); its normal part against the analytic −λ_n
        S = problem.stress(st)
        t_avg = 0.5 * np.einsum("fij,fj->fi", S[net.plus_cell] + S[net.minus_cell], n)
        tn = -np.einsum("fi,fi->f", t_avg, n)
        return {"slip_L2_rel": float(np.sqrt(np.sum(A * (slip - se) ** 2) / np.sum(A * se ** 2))),
                "lambda_n_L2_rel": float(np.sqrt(np.sum(A * (ln - le) ** 2) / np.sum(A * le ** 2))),
                "lambda_n_L2_rel_away_from_tips": float(np.sqrt(np.sum((A * (ln - le) ** 2)[far])
                                                                / np.sum((A * le ** 2)[far]))),
                "lambda_n_h12": float(np.sqrt(np.sum(h * A * (ln - le) ** 2))),
                "traction_n_L2_rel": float(np.sqrt(np.sum(A * (tn - le) ** 2) / np.sum(A * le ** 2)))}
