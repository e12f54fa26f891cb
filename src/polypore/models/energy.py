"""Discrete energy balance of one poromechanics step (scheme.md §6, docs/poromechanics.md).

Testing the equilibrium equation with δu = u^n − u^{n−1} and the flow balances with p^n
(every unknown: cells, faces, traces, fracture faces, edges) and adding, the coupling terms
cancel (−Σ|K| b p_K div^K δu + Σ|σ| p_f [[δu]]_n against the storage |K| b div^K δu and
|σ|(d_f^n − d_f^{n−1}) = −|σ|[[δu]]_n), which gives the exact identity

    ΔE + D_friction + D_viscous + D_contact_n + D_numerical + X_τ = W

with E = ½ a(u, u) + ½ Σ|K| p_K²/M + ½ Σ|σ| c_f d_f^{n−1} p_f² + ½ S_δ(p, p) (elastic + storage +
pressure stabilisation; S_δ is the model's pressure-jump form, whose mass-balance term
S_δ(p^n − p^{n−1}, q) tested with p^n gives ½ S_δ(p^n, p^n) − ½ S_δ(p^{n−1}, p^{n−1}) + ½ S_δ(δp, δp)),
D_friction = Σ|σ| r_σ |Δ[[u]]_τ| (r = F λ_n Coulomb, g Tresca, 0 frictionless),
D_viscous = Δt [Σ_K Σ_σ F_Kσ (p_K − p_σ) + Σ_σ Σ_e F_σe (p_f − p_e)
                + Σ_± |σ| Λ_f/η (p_±σ − p_f)²]
(with C_f, Λ_f at d_f^{n−1}), D_contact_n = Σ|σ| λ_n [[δu]]_n = −Σ|σ| λ_n^n [[u^{n−1}]]_n ≥ 0,
D_numerical = ½ a(δu, δu) + ½ Σ|K| δp_K²/M + ½ Σ|σ| c_f d_f^{n−1} δp_f² + ½ S_δ(δp, δp) ≥ 0
(implicit Euler),
X_τ = Σ|σ| λ_τ·Δ[[u]]_τ − D_friction (= 0 at a solution of the contact law) and
W = ℓ^n·δu (body force, tractions, σ⁰, the reference traction λ⁰) + R^n·δu (Dirichlet reactions)
  + Δt [Σ|K| h_m p_K + Σ|σ| h_f p_f − Σ_{∂Ω faces} F_Kσ p_σ − Σ_{∂Ω fracture ends} F_e p_e]
  − Σ|σ| tan ψ p_f Δ|[[u − u⁰]]_τ| (dilatancy, C6; zero without it).

Hence the estimate of the slides, ΔE + D_friction + D_viscous ≤ W. Everything here is
recomputed from the states with the physical coupling, independently of the Newton residual,
so that a wrong sign in the model's coupling shows up as a violation.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .friction import RateLaw


@dataclass
class EnergyTerms:
    """Energy terms of one step, in J (J/m in 2D).

    ``elastic``, ``storage`` and ``stabilisation`` (½ S_δ(p, p), the pressure-jump form of
    :meth:`Poromechanics.stabilisation_matrix`) are the energies at the end of the step;
    ``delta_*`` their changes over the step (computed as ½ a(δu, u^n + u^{n−1}) etc. to avoid
    cancellation);
    dissipations and works are over the step. ``scale`` bounds the round-off of the balance
    (sum of the magnitudes of every product entering it).
    """

    time: float
    dt: float
    elastic: float
    storage: float
    delta_elastic: float
    delta_storage: float
    friction_dissipation: float
    viscous_dissipation: float
    viscous_matrix: float
    viscous_fracture: float
    viscous_exchange: float
    contact_normal: float
    contact_tangential_excess: float
    numerical_dissipation: float
    load_work: float
    reaction_work: float
    fluid_source_work: float
    fluid_boundary_work: float
    scale: float
    dilatancy_work: float = 0.0
    stabilisation: float = 0.0
    delta_stabilisation: float = 0.0
    # Σ|σ| λ_n (|[[u]]_n^n| + |[[u]]_n^{n−1}|) over the patches closed at both ends of the step:
    # the most work their normal jumps, 0 at an exact solution, can do at Newton's tolerance
    unresolved_normal: float = 0.0

    @property
    def source_work(self) -> float:
        """W: work of loads, Dirichlet reactions, fluid sources, boundary flow and dilatancy."""
        return (self.load_work + self.reaction_work + self.fluid_source_work + self.fluid_boundary_work
                + self.dilatancy_work)

    @property
    def balance(self) -> float:
        """W − (ΔE + D_friction + D_viscous): ≥ 0 (up to round-off) by the energy estimate."""
        return self.source_work - (self.delta_elastic + self.delta_storage + self.delta_stabilisation
                                   + self.friction_dissipation + self.viscous_dissipation)

    @property
    def defect(self) -> float:
        """Defect of the exact identity: balance − (D_contact_n + D_numerical + X_τ) ≈ 0."""
        return self.balance - (self.contact_normal + self.numerical_dissipation + self.contact_tangential_excess)

    def summary(self) -> dict:
        """The ``energy`` entry of summary.json (interface.md); ``storage`` includes the
        stabilisation's ½ S_δ(p, p), so that Δ(elastic + storage) + dissipations ≤ source_work."""
        return {"elastic": self.elastic, "storage": self.storage + self.stabilisation,
                "friction_dissipation": self.friction_dissipation,
                "viscous_dissipation": self.viscous_dissipation, "source_work": self.source_work}

    def as_dict(self) -> dict:
        return {**asdict(self), "source_work": self.source_work, "balance": self.balance, "defect": self.defect}


def state_energy(model, st) -> tuple[float, float]:
    """(½ a(u, u), ½ Σ|K| p_K²/M) of a state, J (J/m in 2D); fracture storage excluded
    (its coefficient is lagged per step, see :func:`step_energy`)."""
    u = st.u.ravel()
    vol = model.fm.mesh.geometry.cell_volume
    pK = st.p[model.dofs.n:]
    return 0.5 * float(u @ (model.mech.A @ u)), 0.5 * float(np.sum(vol * pK * pK / model.flow.biot_modulus))


def step_energy(model, old, new) -> EnergyTerms:
    """Every term of the discrete energy identity of the step old → new (module docstring).

    Parameters
    ----------
    model : Poromechanics
    old, new : PoroState at t^{n−1} and t^n
    """
    t, dt = new.time, new.time - old.time
    u, u0 = new.u.ravel(), old.u.ravel()
    du = u - u0
    Au = model.mech.A @ u
    elastic, d_el, storage, d_st, stab, d_stab, num, scale = _stored_terms(model, old, new, u, u0, du, Au)
    fric, cn, xt, s_contact, unresolved = _contact_terms(model, old, new, du, dt)
    load_w, reac_w, s_work = _work_terms(model, new, du, Au, t)
    v_m, v_f, v_x, src_w, bnd_w, s_flow = _flow_terms(model, new, t, dt)
    dil_w, s_dil = _dilatancy_work(model, old, new)
    # the scale's parts summed in the order the terms are listed (the figures of earlier runs)
    scale += s_contact
    scale += s_work
    scale += s_flow
    scale += s_dil
    return EnergyTerms(t, dt, elastic, storage, d_el, d_st, fric, v_m + v_f + v_x, v_m, v_f, v_x, cn, xt, num,
                       load_w, reac_w, src_w, bnd_w, scale, dil_w, stab, d_stab, unresolved)


def _stored_terms(model, old, new, u, u0, du, Au):
    """Stored energies and their changes: elastic ½ a(u, u), storage ½ Σ |K|/M p_K² (and the
    fracture compressibility's, with the step's coefficient d_f^{n−1}), the stabilisation's ½ S_δ(p, p);
    the implicit-Euler dissipation ``num`` (½ a(δu, δu) + ½ storage(δp, δp) + ½ S_δ(δp, δp)) and the
    terms' scale."""
    mech, dofs, nf = model.mech, model.dofs, model.n_ff
    A = mech.A
    # -- elastic: ½a(u,u) − ½a(u0,u0) = ½ a(δu, u + u0), and ½ a(δu, δu) of implicit Euler
    elastic = 0.5 * float(u @ Au)
    d_el = 0.5 * float(du @ (Au + A @ u0))
    num = 0.5 * float(du @ (A @ du))
    # -- storage (matrix, and fracture compressibility with the step's coefficient d_f^{n−1})
    vol = model.fm.mesh.geometry.cell_volume / model.flow.biot_modulus     # |K|/M, per cell (layered storage)
    pK, pK0 = new.p[dofs.n:], old.p[dofs.n:]
    storage = 0.5 * float(np.sum(vol * pK * pK))
    d_st = 0.5 * float(np.sum(vol * (pK - pK0) * (pK + pK0)))
    num += 0.5 * float(np.sum(vol * (pK - pK0) ** 2))
    scale = abs(elastic) + 0.5 * abs(float(u0 @ (A @ u0))) + abs(num) + float(np.sum(vol * (pK * pK + pK0 * pK0)))
    cf = float(model.flow.data.fracture_compressibility)
    pf, pf0 = new.p[dofs.frac], old.p[dofs.frac]
    if cf > 0 and nf:
        w = mech.face_area * old.aperture * cf
        storage += 0.5 * float(np.sum(w * pf * pf))
        d_st += 0.5 * float(np.sum(w * (pf - pf0) * (pf + pf0)))
        num += 0.5 * float(np.sum(w * (pf - pf0) ** 2))
        scale += float(np.sum(w * (pf * pf + pf0 * pf0)))
    # -- pressure stabilisation S_δ(p^n − p^{n−1}, p^n): stored ½ S_δ(p, p), dissipated ½ S_δ(δp, δp)
    ws = model.stabilisation_weights
    jn, j0 = model.stabilisation_jumps(new.p), model.stabilisation_jumps(old.p)
    stab = 0.5 * float(ws @ (jn * jn))
    d_stab = 0.5 * float(ws @ ((jn - j0) * (jn + j0)))
    num += 0.5 * float(ws @ ((jn - j0) ** 2))
    scale += float(ws @ (jn * jn + j0 * j0))
    return elastic, d_el, storage, d_st, stab, d_stab, num, scale


def _contact_terms(model, old, new, du, dt):
    """Friction dissipation on the slip increment, normal work and tangential excess, per multiplier
    (patch, discretisation/contact_patches.py): Σ_P |P| λ_P·Δ[[u]]_P = Σ_σ |σ| λ_σ·Δ[[u]]_σ; and their scale."""
    if not model.n_ff:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    mech, d = model.mech, model.dim
    n = mech.c_normal
    area = mech.c_area
    dq = (mech.Jcv @ du).reshape(mech.n_c, d)
    dqn = np.einsum("fi,fi->f", dq, n)
    dqt = dq - dqn[:, None] * n
    lam = mech.patch_values(new.lam)
    ln = np.einsum("fi,fi->f", lam, n)
    lt = lam - ln[:, None] * n
    # the friction law's radius at the converged traction and the step's slip, from its state
    # before the step: the radius the step's Newton iteration used
    fl = mech.law.friction_law
    slip = np.linalg.norm(dqt, axis=1)
    if isinstance(fl, RateLaw):
        # a rate law's radius at |Δ[[u]]_τ|/Δt: at slip rates whose step slip is below the jumps'
        # round-off (1e-12 m/s over 0.01 s) that rate is noise and r(V) with it; its dissipation
        # is λ_τ·Δ[[u]]_τ itself (= r |Δ[[u]]_τ| at a solution, λ_τ ∥ Δ[[u]]_τ), X_τ = 0
        r = np.linalg.norm(lt, axis=1)
        fric = float(np.sum(area * np.einsum("fi,fi->f", lt, dqt)))
    else:
        r = fl.radius(ln, dqt, model.friction_state(old), dt).value
        fric = float(np.sum(area * r * slip))
    cn = float(np.sum(area * ln * dqn))
    xt = float(np.sum(area * np.einsum("fi,fi->f", lt, dqt))) - fric
    # closed at both ends of the step, a patch's normal jump is 0 up to Newton's tolerance, and
    # λ_n Δ[[u]]_n ≥ 0, which the estimate assumes, up to the work of that residue (−3.3e-8 J from
    # 5e-18 m jumps in a 5 ms step of a rate-and-state run, 1e-8 of its scale: docs/rate_state_design.md)
    ln_old = np.einsum("fi,fi->f", mech.patch_values(old.lam), n)
    both = (ln > 0) & (ln_old > 0)
    qn_new = np.einsum("fi,fi->f", (mech.Jcv @ new.u.ravel()).reshape(mech.n_c, d), n)
    qn_old = np.einsum("fi,fi->f", (mech.Jcv @ old.u.ravel()).reshape(mech.n_c, d), n)
    unresolved = float(np.sum((area * ln * (np.abs(qn_new) + np.abs(qn_old)))[both]))
    return (fric, cn, xt, float(np.sum(area * (np.abs(ln * dqn) + np.linalg.norm(lt, axis=1) * slip + r * slip))),
            unresolved)


def _work_terms(model, new, du, Au, t):
    """Mechanical work: the loads at t^n on δu and the Dirichlet reactions (physical coupling −G p);
    and their scale."""
    mech = model.mech
    F = model.load_vector(t)
    Gp = model.G @ new.p
    Bl = mech.Bcv.T @ mech.patch_values(new.lam).ravel()
    R = Au + Bl - Gp - F
    fixed = mech.fixed
    load_w = float(F @ du)
    reac_w = float(R[fixed] @ du[fixed])
    adu = np.abs(du)
    return load_w, reac_w, float(adu @ (np.abs(Au) + np.abs(Bl) + np.abs(Gp) + 2 * np.abs(F)))


def _flow_terms(model, new, t, dt):
    """Flow: viscous dissipation (matrix, fractures, matrix–fracture exchange) with the step's
    conductivities (lagged by default), the sources' and the boundary's work; and their scale."""
    mesh, asm, dofs, nf = model.fm.mesh, model.asm, model.dofs, model.n_ff
    p = new.p
    pK, pf = p[dofs.n:], p[dofs.frac]
    ex, fc = model.conductivities(new.flux_aperture) if nf else (np.zeros(0), np.zeros(0))
    cf_ = mesh.cell_faces
    rows = cf_.rows_of_entries()
    Fm = asm.cell_fluxes(pK, p)
    dpm = pK[rows] - p[dofs.slot]
    v_m = dt * float(Fm @ dpm)
    fe = asm.fcells.face_edges
    pe = p[dofs.edge]
    Ff = asm.fhfv_unit.scaled(fc).fluxes(pf, pe[fe.values]) if nf else np.zeros(0)
    dpf = pf[fe.rows_of_entries()] - pe[fe.values] if nf else np.zeros(0)
    v_f = dt * float(Ff @ dpf)
    jt = p[dofs.trace] - pf[:, None] if nf else np.zeros((0, 2))
    v_x = dt * float(np.sum(ex[:, None] * jt * jt))
    hm, hf = model.flow.sources(t)
    src_w = dt * float(hm @ pK + hf @ pf)
    on_b = np.zeros(mesh.n_faces, bool)
    on_b[mesh.boundary_faces] = True
    eb = on_b[cf_.values]
    edge_out = np.bincount(fe.values, weights=Ff, minlength=pe.size) if nf else np.zeros(pe.size)
    bedges = np.zeros(pe.size, bool)
    for edges in model.flow.edge_parts.values():
        bedges[edges] = True
    bnd_w = -dt * float(Fm[eb] @ p[dofs.slot[eb]] + edge_out[bedges] @ pe[bedges])
    ap = np.abs(p)
    scale = dt * float(np.abs(Fm) @ (np.abs(pK[rows]) + ap[dofs.slot]) + np.abs(Ff) @ (np.abs(pf[fe.rows_of_entries()])
                                                                                      + np.abs(pe[fe.values]))
                       + np.sum(ex[:, None] * jt * jt) + np.abs(hm) @ np.abs(pK) + np.abs(hf) @ np.abs(pf))
    return v_m, v_f, v_x, src_w, bnd_w, scale


def _dilatancy_work(model, old, new):
    """Dilatancy (C6): the storage term |σ| tan ψ Δ|[[u − u⁰]]_τ| of the flow rows has no
    counterpart in the equilibrium (the dilatant law is not derived from a potential), so its
    product with p_f is counted as work done on the fluid: W_dil = −Σ|σ| tan ψ p_f Δ|[[u − u⁰]]_τ|;
    and its scale."""
    if not (model.n_ff and np.any(model.tan_psi > 0)):
        return 0.0, 0.0
    rel1 = model.tangential_slip(model.jumps(new.u))[0]
    rel0 = model.tangential_slip(model.jumps(old.u))[0]
    dil = model.mech.face_area * model.tan_psi * (rel1 - rel0) * new.p[model.dofs.frac]
    return -float(dil.sum()), float(np.abs(dil).sum())


def check_energy(terms, rtol: float = 1e-9) -> list[str]:
    """Violations of ΔE + D_friction + D_viscous ≤ W (+ rtol × scale + the work of the closed
    patches' unresolved normal jumps, ``unresolved_normal``), one message per step.

    Parameters
    ----------
    terms : iterable of EnergyTerms
    rtol : round-off tolerance relative to each step's ``scale``
    """
    out = []
    for k, e in enumerate(terms):
        tol = rtol * e.scale + e.unresolved_normal
        if not e.balance >= -tol:
            out.append(f"step {k} (t = {e.time:g} s): ΔE + friction + viscous exceeds the work by "
                       f"{-e.balance:.3e} J (tolerance {tol:.1e}; "
                       f"ΔE = {e.delta_elastic + e.delta_storage + e.delta_stabilisation:.3e},"
                       f" friction {e.friction_dissipation:.3e}, viscous {e.viscous_dissipation:.3e}, "
                       f"work {e.source_work:.3e})")
    return out
