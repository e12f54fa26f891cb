"""Exactness of the bubble VEM contact mechanics: affine fields, rigid modes, symmetry, contact branches."""

import numpy as np
import pytest

from polypore.mesh import FracturedMesh, FractureSpec
from polypore.mesh.generators.cartesian import cartesian_mesh, grid_coordinates
from polypore.core.errors import InputError
from polypore.models.contact import OPEN, SLIP, STICK, ContactLaw, linearise_contact
from polypore.models.friction import Coulomb, SlipWeakening, friction_law
from polypore.models.mechanics import ContactMechanics, ContactSpec, DisplacementBC, MechanicsData
from polypore.solvers.linear import rigid_body_modes

G2 = np.array([[1.0e-3, 2.0e-4], [-1.0e-4, -2.0e-3]])
G3 = np.array([[1.0e-3, 2.0e-4, -3.0e-4], [-1.0e-4, 5.0e-4, 1.0e-4], [2.0e-4, -1.0e-4, -2.0e-3]])


def _mesh(kind, dim, fractures):
    """Meshes of the unit square/cube conforming to the horizontal plane y (2D) / z (3D) = 0.5."""
    axes = [grid_coordinates(0, 1, 4, [0.5]) for _ in range(dim)]
    if kind == "cartesian":
        return cartesian_mesh(axes)
    if kind == "perturbed":
        from polypore.mesh.generators.perturb import perturb

        return perturb(cartesian_mesh(axes), 0.25, fractures, seed=3)
    if kind == "voronoi":
        from polypore.mesh.generators.voronoi import voronoi_mesh

        return voronoi_mesh([0] * dim, [1] * dim, 0.3, fractures, seed=1)
    if kind == "agglomerated":
        from polypore.mesh import build_network
        from polypore.mesh.generators.agglomerate import agglomerate

        base = cartesian_mesh([grid_coordinates(0, 1, 6, [0.5]) for _ in range(dim)])
        return agglomerate(base, build_network(base, fractures).faces, rounds=2, seed=2)
    if kind == "simplicial":
        from polypore.mesh.generators.simplicial import simplicial_mesh

        return simplicial_mesh([0] * dim, [1] * dim, fractures, 0.3)
    raise ValueError(kind)


def _plane(dim):
    if dim == 2:
        return [FractureSpec("F", np.array([[0.0, 0.5], [1.0, 0.5]]))]
    return [FractureSpec("F", np.array([[0, 0, 0.5], [1, 0, 0.5], [1, 1, 0.5], [0, 1, 0.5]], float))]


def _problem(fm, G, law="coulomb", friction=10.0, two_sided=False, stab=1.0):
    nc = fm.mesh.n_cells
    bnames = [b for b in ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")[: 2 * fm.mesh.dim]]
    bcs = [DisplacementBC(b, tuple(range(fm.mesh.dim)), lambda X, t: X @ G.T) for b in bnames]
    data = MechanicsData(mu=np.full(nc, 3.0e9), lam=np.full(nc, 2.0e9), displacement=bcs,
                         contact=ContactSpec(law, friction, 0.0), two_sided=two_sided, stabilisation=stab)
    return ContactMechanics(fm, data)


KINDS = ["cartesian", "perturbed", "voronoi", "agglomerated", "simplicial"]


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("with_fracture", [False, True])
def test_affine_displacement_is_reproduced(kind, dim, with_fracture):
    specs = _plane(dim)
    mesh = _mesh(kind, dim, specs)
    fm = FracturedMesh.build(mesh, specs if with_fracture else [])
    G = G2 if dim == 2 else G3
    for two_sided in (False, True) if with_fracture else (False,):
        P = _problem(fm, G, two_sided=two_sided)
        st = P.solve(verbose=False)
        # gradients, nodal values and (bonded, compressed) fractures: exact to round-off
        assert np.abs(P.gradients(st) - G).max() < 1e-11 * np.abs(G).max()
        X = mesh.nodes[fm.sides.side_node]
        assert np.abs(st.u[: fm.sides.n_sides] - X @ G.T).max() < 1e-13
        assert np.abs(st.u[fm.sides.n_sides:]).max(initial=0) < 1e-13   # bubbles of an affine field vanish
        if with_fracture:
            assert np.all(st.state == STICK)
            assert np.abs(P.jumps(st)).max() < 1e-13
            sigma = P.stress(st)[0]
            lam_exact = -(sigma @ P.normal.T).T          # λ = −σ n⁺
            assert np.allclose(st.lam, lam_exact, rtol=1e-9, atol=1e-9 * np.abs(sigma).max())


@pytest.mark.parametrize("kind,dim", [("cartesian", 3), ("perturbed", 3), ("voronoi", 2), ("simplicial", 3),
                                      ("agglomerated", 2)])
def test_rigid_modes_in_kernel_and_symmetry(kind, dim):
    specs = _plane(dim)
    fm = FracturedMesh.build(_mesh(kind, dim, specs), specs)
    for stab in (0.0, 1.0):
        P = _problem(fm, G2 if dim == 2 else G3, stab=stab)
        A = P.A.tocsr()
        assert abs(A - A.T).max() <= 1e-12 * abs(A).max()
        # rigid motions: nodal sides take x ↦ a + ω × x, bubbles 0
        sides = fm.sides
        R = rigid_body_modes(fm.mesh.nodes[sides.side_node])
        R = np.vstack([R, np.zeros((P.space.n_bubbles * dim, R.shape[1]))])
        assert np.abs(A @ R).max() <= 1e-12 * abs(A).max()
    # the stabilised form is positive definite on non-rigid fields: a random field has positive energy
    v = np.random.default_rng(0).standard_normal(P.n_dofs)
    assert v @ (P.A @ v) > 0


def test_contact_branches_at_the_kinks():
    n = np.array([[0.0, 1.0]])
    beta = np.array([2.0])
    area = np.array([1.0])
    law = ContactLaw(Coulomb(np.array([0.5])), beta)
    # y_n = 0 exactly: open
    *_, st = linearise_contact(law, np.array([[0.3, 0.0]]), np.zeros((1, 2)), np.zeros((1, 2)), n, area)
    assert st[0] == OPEN
    # |y_τ| = r = F y_n exactly, or below it by less than STICK_SLIP_TIE (round-off: a face that slipped
    # in the previous step): slip, whatever the round-off; clearly inside the cone: stick; above: slip
    lam = np.array([[0.5, 1.0]])
    for dl, want in ((0.0, SLIP), (-1e-12, SLIP), (1e-12, SLIP), (-1e-6, STICK)):
        *_, st = linearise_contact(law, lam + [[dl, 0]], np.zeros((1, 2)), np.zeros((1, 2)), n, area)
        assert st[0] == want, dl
    # the projection's value is the exact one inside the band (continuous across the cone)
    C, *_ = linearise_contact(law, lam - [[1e-12, 0]], np.zeros((1, 2)), np.zeros((1, 2)), n, area)
    assert np.allclose(C, 0.0, atol=1e-15)


@pytest.mark.parametrize("kind", ["coulomb", "tresca", "frictionless", "slip-weakening"])
def test_contact_jacobian_matches_finite_differences(kind):
    """The generalised derivative of every law's projection equations (central differences away
    from kinks); slip-weakening with slip paths before, inside and past its weakening range, so
    that its ∂r/∂s term is exercised and also absent."""
    rng = np.random.default_rng(1)
    nf, d = 40, 3
    n = rng.standard_normal((nf, d))
    n /= np.linalg.norm(n, axis=1)[:, None]
    fs = rng.uniform(0.4, 0.8, nf)
    law = ContactLaw(friction_law(kind, nf, friction=fs, threshold=rng.uniform(0.1, 1.0, nf),
                                  dynamic_friction=0.5 * fs, critical_slip=rng.uniform(0.2, 1.0, nf)),
                     rng.uniform(0.5, 2.0, nf))
    state = law.friction_law.initial_state(nf)
    if kind == "slip-weakening":
        state = state + rng.uniform(0.0, 1.2, (nf, 1))
    lam = rng.standard_normal((nf, d))
    q = 0.5 * rng.standard_normal((nf, d))
    s = q.copy()
    area = rng.uniform(0.5, 1.5, nf)
    C, dl, dq, st = linearise_contact(law, lam, q, s, n, area, state)
    assert len(set(st.tolist())) >= 2
    if kind == "slip-weakening":
        nt = np.linalg.norm(s - np.einsum("fi,fi->f", s, n)[:, None] * n, axis=1)
        weak = (st == SLIP) & (state[:, 0] + nt < law.friction_law.critical_slip)
        assert weak.sum() >= 3 and ((st == SLIP) & ~weak).sum() >= 1
    eps = 1e-6
    for k in range(d):
        e = np.zeros((nf, d))
        e[:, k] = eps
        Cl = (linearise_contact(law, lam + e, q, s, n, area, state)[0]
              - linearise_contact(law, lam - e, q, s, n, area, state)[0]) / (2 * eps)
        Cq = (linearise_contact(law, lam, q + e, s + e, n, area, state)[0]
              - linearise_contact(law, lam, q - e, s - e, n, area, state)[0]) / (2 * eps)
        assert np.allclose(Cl, dl[:, :, k], atol=1e-6)
        assert np.allclose(Cq, dq[:, :, k], atol=1e-6)


def test_slip_weakening_radius_and_state():
    """F(δ) falls linearly from F_s to F_d over D_c and stays; the state accumulates the slip path;
    a law without state keeps none; coefficients out of range are errors naming the key."""
    law = SlipWeakening(np.array([0.6, 0.6, 0.6]), np.array([0.4, 0.4, 0.4]), np.array([1e-3, 1e-3, 1e-3]))
    F, dF = law.coefficient(np.array([0.0, 5e-4, 2e-3]))
    assert np.allclose(F, [0.6, 0.5, 0.4]) and np.allclose(dF, [-200.0, -200.0, 0.0])
    st = law.advance(law.initial_state(3), np.array([[3e-4, 4e-4, 0.0], [0.0, 0.0, 0.0], [1e-3, 0.0, 0.0]]), 1.0)
    assert np.allclose(st[:, 0], [5e-4, 0.0, 1e-3])
    r = law.radius(np.array([1e6, -1.0, 2e6]), np.zeros((3, 3)), st, 1.0)
    assert np.allclose(r.value, [0.5e6, 0.0, 0.8e6]) and np.allclose(r.d_normal, [0.5, 0.0, 0.4])
    assert set(law.state_fields(st)) == {"slip_path", "friction_coefficient"}
    c = Coulomb(np.array([0.5]))
    assert c.initial_state(4).shape == (4, 0) and c.state_fields(c.initial_state(4)) == {}
    assert c.instability_hint is None and "nucleation length" in law.instability_hint
    with pytest.raises(InputError, match="^dynamic_friction:"):
        SlipWeakening(np.array([0.5]), np.array([0.6]), np.array([1e-3]))
    with pytest.raises(InputError, match="^critical_slip:"):
        friction_law("slip-weakening", 1, friction=0.6, dynamic_friction=0.4, critical_slip=0.0)
    with pytest.raises(InputError, match="^dynamic_friction:"):
        friction_law("slip-weakening", 1, friction=0.6, critical_slip=1e-3)
    with pytest.raises(InputError, match="^law:"):
        friction_law("rate-and-stat", 1)
    with pytest.raises(InputError, match="^friction:"):
        friction_law("rate-and-state", 1)


@pytest.mark.parametrize("dim,kind", [(2, "voronoi"), (3, "perturbed"), (3, "simplicial")])
def test_interpolate_is_exact_on_piecewise_affine_fields(dim, kind):
    """I_D of a field affine on each side of Γ: nodal values, bubbles 0, ∇^K exact, jumps = exact mean jumps."""
    specs = _plane(dim)
    fm = FracturedMesh.build(_mesh(kind, dim, specs), specs)
    G = G2 if dim == 2 else G3
    jump = np.array([1e-3, -2e-3, 5e-4][:dim])

    nz = fm.network.normal[0, dim - 1]          # n⁺ = ±e_y / e_z; K⁺ lies on the side n⁺ points away from

    def u(X, t=0.0):
        return X @ G.T + np.where((X[:, dim - 1:] - 0.5) * nz < 0, jump, 0.0)    # K⁺ carries the extra shift

    for two_sided in (False, True):
        P = _problem(fm, G, two_sided=two_sided)
        v = P.interpolate(u)
        assert np.abs(P.ops.gradient(v) - G).max() < 1e-12
        assert np.abs(v[P.space.n_sides:]).max() < 1e-13
        assert np.allclose(P.jump_scalar @ v, jump, atol=1e-13)


def test_interpolate_bubble_captures_the_face_mean_of_a_quadratic():
    specs = _plane(2)
    fm = FracturedMesh.build(_mesh("cartesian", 2, specs), specs)
    P = _problem(fm, G2)
    v = P.interpolate(lambda X, t=0.0: np.stack([X[:, 0] ** 2, 0 * X[:, 0]], 1))
    # on a face [a, b] of y = 0.5: mean of x^2 minus the mean of the nodal values (trapezoid)
    faces = fm.network.faces[P.space.bubble_face]
    X = fm.mesh.nodes[fm.mesh.face_nodes.values.reshape(-1, 2)[faces]]
    a, b = X[:, 0, 0], X[:, 1, 0]
    exact = (a * a + a * b + b * b) / 3 - (a * a + b * b) / 2
    assert np.allclose(v[P.space.n_sides:, 0], exact, atol=1e-15)


def test_block_amg_solver_matches_the_direct_solution():
    """GMRES + AMG on the condensed displacement block gives the direct solver's Newton solution."""
    pytest.importorskip("pyamg")
    from polypore.setup.casefile import load_case
    from polypore.runs.static import solve_static

    ref = solve_static(load_case("coulomb-3d", ["mesh.size=0.4", "solver.linear=superlu"]))
    blk = solve_static(load_case("coulomb-3d", ["mesh.size=0.4", "solver.linear=block-amg"]))
    (p0, s0), (p1, s1) = ref[:2], blk[:2]
    assert np.array_equal(s0.state, s1.state)
    assert np.abs(s1.u - s0.u).max() <= 1e-6 * np.abs(s0.u).max()
    assert np.abs(s1.lam - s0.lam).max() <= 1e-6 * np.abs(s0.lam).max()
    assert len(p1.solver.iterations) == s1.newton_iterations and max(p1.solver.iterations) < 300
