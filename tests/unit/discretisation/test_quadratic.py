"""The quadratic displacement space on simplices (mechanics.order = 2): quadrature, exactness on
quadratic fields (with and without a bonded fracture), rigid modes, symmetry, the inf-sup role of
the 3D face bubbles, convergence rates, a sliding crack, poromechanics, and bad input."""

from __future__ import annotations

import itertools
from math import factorial

import numpy as np
import pytest
from scipy.linalg import null_space

from polypore.cases.exact import SingleCrack, build_solution
from polypore.core.errors import InputError
from polypore.discretisation import QuadraticSpace
from polypore.discretisation.quadrature import SEGMENT_5, TETRA_2, TETRA_5, TRIANGLE_2, TRIANGLE_4
from polypore.mesh import FracturedMesh, FractureSpec
from polypore.mesh.build import mesh_from_cells
from polypore.mesh.generators.cartesian import cartesian_mesh, grid_coordinates
from polypore.mesh.generators.perturb import perturb
from polypore.mesh.generators.simplicial import simplicial_mesh
from polypore.models.contact import SLIP, STICK
from polypore.models.fracture_geometry import arc_length
from polypore.models.mechanics import ContactMechanics, ContactSpec, DisplacementBC, MechanicsData, TractionBC
from polypore.solvers.linear import rigid_body_modes

MU, LAM = 3.0e9, 2.0e9
BOX = ("xmin", "xmax", "ymin", "ymax", "zmin", "zmax")


def _plane(dim):
    if dim == 2:
        return [FractureSpec("F", np.array([[0.0, 0.5], [1.0, 0.5]]))]
    return [FractureSpec("F", np.array([[0, 0, 0.5], [1, 0, 0.5], [1, 1, 0.5], [0, 1, 0.5]], float))]


@pytest.fixture(scope="module", params=[2, 3], ids=["2d", "3d"])
def perturbed(request):
    """A perturbed gmsh triangulation / tetrahedralisation of the unit box conforming to the plane
    y (z) = 0.5."""
    dim = request.param
    specs = _plane(dim)
    mesh = simplicial_mesh([0] * dim, [1] * dim, specs, 0.2 if dim == 2 else 0.3)
    return perturb(mesh, 0.2, specs, seed=1), specs


def _data(fm, bcs, order=2, **kw):
    nc = fm.mesh.n_cells
    return MechanicsData(mu=np.full(nc, MU), lam=np.full(nc, LAM), displacement=bcs, order=order,
                         contact=kw.pop("contact", ContactSpec("coulomb", 10.0, 0.0)), **kw)


# ---- quadrature ---------------------------------------------------------------------------------
@pytest.mark.parametrize("rule,degree", [(SEGMENT_5, 5), (TRIANGLE_2, 2), (TRIANGLE_4, 4), (TETRA_2, 2), (TETRA_5, 5)])
def test_quadrature_rules_integrate_monomials_exactly(rule, degree):
    L, w = rule
    n = L.shape[1]
    assert np.all(w > 0) and abs(w.sum() - 1) < 1e-15
    for alpha in itertools.product(range(degree + 1), repeat=n):
        if sum(alpha) > degree:
            continue
        exact = factorial(n - 1) * np.prod([factorial(a) for a in alpha]) / factorial(n - 1 + sum(alpha))
        assert abs(w @ np.prod(L ** np.array(alpha), axis=1) - exact) < 1e-14, alpha


# ---- exactness ------------------------------------------------------------------------------------
def _quadratic_field(dim, rng, plane_traction_constant):
    """u = G x + H(x, x) with H symmetric in its last two indices; with ``plane_traction_constant``
    H is drawn from the maps whose traction σ(u)·e_d is constant along the planes x_d = const (so
    that the P0 multipliers can equal it exactly)."""
    basis = []
    for i in range(dim):
        for j in range(dim):
            for k in range(j, dim):
                H = np.zeros((dim,) * 3)
                H[i, j, k] = H[i, k, j] = 1.0
                basis.append(H)

    def dsigma(H):        # ∂_k σ_ij, with ∂_k ∇u_ij = 2 H_ijk
        dG = 2 * H
        return MU * (dG + dG.transpose(1, 0, 2)) + LAM * np.einsum("llk->k", dG) * np.eye(dim)[:, :, None]

    coef = rng.standard_normal(len(basis))
    if plane_traction_constant:
        M = np.array([dsigma(H)[:, dim - 1, : dim - 1].ravel() for H in basis]).T
        N = null_space(M)
        assert N.shape[1] >= dim       # a rich enough family (4 maps in 2D, 12 in 3D)
        coef = N @ rng.standard_normal(N.shape[1])
    H = sum(c * B for c, B in zip(coef, basis))
    H *= 1e-4 / np.abs(H).max()
    G = 1e-4 * rng.standard_normal((dim, dim)) - 2e-3 * np.eye(dim)     # compresses the plane

    def u(X, t=0.0):
        return X @ G.T + np.einsum("ijk,nj,nk->ni", H, X, X)

    def grad(X):
        return G + 2 * np.einsum("ijk,nk->nij", H, X)

    def sigma(X):
        e = 0.5 * (grad(X) + grad(X).transpose(0, 2, 1))
        return 2 * MU * e + LAM * np.trace(e, axis1=1, axis2=2)[:, None, None] * np.eye(dim)

    f = -(2 * MU * np.einsum("ijj->i", H) + 2 * (MU + LAM) * np.einsum("jji->i", H))   # −div σ
    return u, grad, sigma, (lambda X, t=0.0: np.tile(f, (len(X), 1)))


@pytest.mark.parametrize("fracture", ["none", "one-sided", "two-sided"])
def test_quadratic_displacement_is_reproduced(perturbed, fracture):
    mesh, specs = perturbed
    dim = mesh.dim
    u, grad, sigma, f = _quadratic_field(dim, np.random.default_rng(dim), fracture != "none")
    fm = FracturedMesh.build(mesh, specs if fracture != "none" else [])
    bcs = [DisplacementBC(b, tuple(range(dim)), u) for b in BOX[: 2 * dim] if b != "xmax"]
    # xmax carries the (affine) traction σ(u) n: checks the P2 face quadrature of tractions
    trac = [TractionBC("xmax", lambda X, t: sigma(X)[:, :, 0])]
    P = ContactMechanics(fm, _data(fm, bcs, traction=trac, body_force=f, two_sided=fracture == "two-sided"))
    st = P.solve(verbose=False)
    exact = P.interpolate(u)
    assert np.abs(exact[P.space.n_point_slots:]).max(initial=0) < 1e-13 * np.abs(exact).max()   # no bubble part
    assert np.abs(st.u - exact).max() < 1e-10 * np.abs(exact).max()
    Gc = grad(mesh.geometry.cell_centroid)
    assert np.abs(P.gradients(st) - Gc).max() < 1e-10 * np.abs(Gc).max()
    assert np.abs(P.ops.qp_gradient(st.u) - grad(P.ops.qp_point)).max() < 1e-10 * np.abs(Gc).max()
    if fracture != "none":
        assert np.all(st.state == STICK)
        assert np.abs(P.jumps(st)).max() < 1e-13
        xc = mesh.geometry.face_centroid[fm.network.faces]
        lam_exact = -np.einsum("nij,nj->ni", sigma(xc), P.normal)          # λ = −σ n⁺
        assert np.abs(st.lam - lam_exact).max() < 1e-9 * np.abs(lam_exact).max()


def test_piecewise_quadratic_field_interpolation_and_jumps(perturbed):
    """A field quadratic on each side of Γ, discontinuous across it: its interpolate has no bubble
    part, the jump field at face points is the exact jump and the face-mean jumps its exact means."""
    mesh, specs = perturbed
    dim = mesh.dim
    fm = FracturedMesh.build(mesh, specs)
    rng = np.random.default_rng(5)
    H = 1e-3 * rng.standard_normal((2, dim, dim, dim))
    c = 1e-3 * rng.standard_normal((2, dim))
    nz = fm.network.normal[0, dim - 1]

    def piece(k, X):
        return c[k] + np.einsum("ijk,nj,nk->ni", H[k], X, X)

    def u(X, t=0.0):             # K⁺ lies on the side n⁺ points away from
        return np.where(((X[:, dim - 1] - 0.5) * nz < 0)[:, None], piece(0, X), piece(1, X))

    P = ContactMechanics(fm, _data(fm, [DisplacementBC("xmin", tuple(range(dim)), u)]))
    v = P.interpolate(u)
    assert np.abs(v[P.space.n_point_slots:]).max(initial=0) < 1e-13 * np.abs(v).max()
    X, W, Jq = P.space.jump_quadrature()
    exact = piece(0, X) - piece(1, X)
    # (point slots on Γ are evaluated 1e-12 h inside their side: round-off of that size)
    assert np.abs(Jq @ v - exact).max() < 1e-11 * np.abs(exact).max()
    nq = W.size // fm.network.n_faces
    means = np.einsum("fq,fqi->fi", W.reshape(-1, nq), exact.reshape(-1, nq, dim)) / P.face_area[:, None]
    assert np.abs(P.jump_scalar @ v - means).max() < 1e-11 * np.abs(exact).max()


@pytest.mark.parametrize("two_sided", [False, True])
def test_jump_at_points_matches_the_face_rule_field_and_the_facewise_evaluation(perturbed, two_sided):
    """``QuadraticSpace.jump_at`` (benchmarks/cube_slip.py's slip on a grid): at the face rule's
    points it is ``jump_quadrature``'s field; at random points, the P2 traces of both sides plus the
    bubbles evaluated face by face (the evaluation the benchmark used to carry), to 1e-14."""
    from polypore.discretisation.quadratic import BUBBLE_SCALE, FACE_EDGES
    from polypore.discretisation.quadrature import face_rule

    mesh, specs = perturbed
    d = mesh.dim
    fm = FracturedMesh.build(mesh, specs)
    space, net = QuadraticSpace.build(fm, two_sided=two_sided), fm.network
    rng = np.random.default_rng(7)
    u = rng.standard_normal((space.n_slots, d))
    Lq = face_rule(d)[0]
    nq = Lq.shape[0]
    Jq = space.jump_quadrature()[2]
    at_rule = space.jump_at(np.repeat(np.arange(net.n_faces), nq), np.tile(Lq, (net.n_faces, 1)))
    assert np.abs(at_rule @ u - Jq @ u).max() <= 1e-14 * np.abs(Jq @ u).max()
    k = rng.integers(0, net.n_faces, 200)
    L = rng.random((k.size, d))
    L /= L.sum(axis=1, keepdims=True)
    fe = FACE_EDGES[d]
    phi = np.concatenate([L * (2 * L - 1), 4 * L[:, fe[:, 0]] * L[:, fe[:, 1]]], axis=1)
    ref = np.zeros((k.size, d))
    for cells, sign in ((net.plus_cell, 1.0), (net.minus_cell, -1.0)):
        slots = np.concatenate(space.face_slots(net.faces[k], cells[k]), axis=1)
        ref += sign * np.einsum("nj,njc->nc", phi, u[slots])
    for b in range(space.n_bubbles):
        on = k == space.bubble_face[b]
        ref[on] += space.bubble_sign[b] * BUBBLE_SCALE * np.prod(L[on], axis=1)[:, None] * u[space.n_point_slots + b]
    assert np.abs(space.jump_at(k, L) @ u - ref).max() <= 1e-14 * np.abs(ref).max()


def test_rigid_modes_are_the_kernel_and_the_matrix_is_symmetric(perturbed):
    mesh, specs = perturbed
    fm = FracturedMesh.build(mesh, specs)
    dim = mesh.dim
    P = ContactMechanics(fm, _data(fm, [DisplacementBC(b, tuple(range(dim)), lambda X, t: 0 * X) for b in BOX[:2]]))
    A = P.A.tocsr()
    assert abs(A - A.T).max() <= 1e-13 * abs(A).max()
    R = np.zeros((P.n_dofs, 3 if dim == 2 else 6))
    R[: P.space.n_point_slots * dim] = rigid_body_modes(P.slot_points)
    assert np.abs(A @ R).max() <= 1e-12 * abs(A).max() * np.abs(R).max()
    assert np.array_equal(P.rigid_modes(), R[P.free])
    # a P2 field that is affine on one side of Γ and a different affine field on the other is in
    # the kernel only if both are rigid: a random field has positive energy
    v = np.random.default_rng(0).standard_normal(P.n_dofs)
    assert v @ (A @ v) > 0
    # slots: node sides first, then edge sides (split on Γ, which cuts the box), then bubbles
    net = fm.network
    vs, es = P.space.face_slots(net.faces, net.plus_cell)
    vm, em = P.space.face_slots(net.faces, net.minus_cell)
    assert np.all(vs != vm) and np.all(es != em)
    assert np.all(vs < P.space.n_sides) and np.all((es >= P.space.n_sides) & (es < P.space.n_point_slots))
    assert P.space.n_bubbles == (net.n_faces if dim == 3 else 0)


def _kuhn_mesh(n):
    """The unit cube cut into n³ cubes of 6 tetrahedra each around the main diagonal (Kuhn): every
    coordinate plane is triangulated with one diagonal direction, so the dual graph of its
    triangles is bipartite."""
    g = np.linspace(0, 1, n + 1)
    X = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    ijk = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    node = lambda c: (c[:, 0] * (n + 1) + c[:, 1]) * (n + 1) + c[:, 2]   # noqa: E731
    tets = []
    for perm in itertools.permutations(range(3)):
        c = ijk.copy()
        verts = [node(c)]
        for ax in perm:
            c[:, ax] += 1
            verts.append(node(c))
        tets.append(np.stack(verts, 1))
    return mesh_from_cells(X, {"tetra": np.concatenate(tets)})


def test_face_bubbles_remove_the_checkerboard_multiplier_mode():
    """Without 3D face bubbles the face-mean jumps of the P2 traces miss the multiplier that
    alternates in sign between neighbouring fracture triangles (structured mesh: bipartite dual
    graph); with them the jump operator has full rank."""
    specs = [FractureSpec("F", np.array([[0.25, 0.25, 0.5], [0.75, 0.25, 0.5], [0.75, 0.75, 0.5], [0.25, 0.75, 0.5]]))]
    fm = FracturedMesh.build(_kuhn_mesh(4), specs)
    net = fm.network
    assert net.n_faces == 8
    # 2-colour the fracture triangles: neighbours (sharing an edge) get opposite signs
    fe = QuadraticSpace.build(fm).face_edge[net.faces]
    colour = np.zeros(net.n_faces)
    colour[0] = 1
    for _ in range(net.n_faces):          # propagation sweeps on 8 faces (test helper)
        for a, b in itertools.permutations(range(net.n_faces), 2):
            if np.intersect1d(fe[a], fe[b]).size and colour[a] and not colour[b]:
                colour[b] = -colour[a]
    assert np.all(colour != 0)
    for a, b in itertools.combinations(range(net.n_faces), 2):
        if np.intersect1d(fe[a], fe[b]).size:
            assert colour[a] == -colour[b]          # bipartite
    bare = QuadraticSpace.build(fm, face_bubbles=False).jump_operator()
    assert np.abs(bare.T @ colour).max() < 1e-14
    assert np.linalg.matrix_rank(bare.toarray()) == net.n_faces - 1
    full = QuadraticSpace.build(fm).jump_operator().toarray()
    assert np.linalg.svd(full, compute_uv=False).min() > 0.5


# ---- convergence -------------------------------------------------------------------------------
def test_convergence_rates_2d():
    """Smooth solution, Dirichlet data, three triangulations: P2 converges at order 2 in H¹ and 3
    in L² (P1 at 1 in H¹ on the same meshes)."""
    import sympy as S

    x, y = S.symbols("x y", real=True)
    sol = build_solution("smooth", 2, [[1e-3 * S.sin(2 * x + 1) * S.cos(3 * y), 1e-3 * S.exp(x - y)]],
                         lambda P: np.zeros(len(P), int), MU, LAM)
    hs, e1, e0, p1 = [0.2, 0.1, 0.05], [], [], []
    for h in hs:
        fm = FracturedMesh.build(simplicial_mesh([0, 0], [1, 1], [], h), [])
        bcs = [DisplacementBC(b, (0, 1), sol.u) for b in BOX[:4]]
        for order in (1, 2):
            P = ContactMechanics(fm, _data(fm, bcs, order=order, body_force=sol.body_force))
            st = P.solve(verbose=False)
            if order == 1:
                g = fm.mesh.geometry
                p1.append(np.sqrt(np.sum(g.cell_volume * np.sum((P.gradients(st) - sol.grad(g.cell_centroid)) ** 2,
                                                                axis=(1, 2)))))
                continue
            ops = P.ops
            w, X = ops.qp_weight, ops.qp_point
            e1.append(np.sqrt(w @ np.sum((ops.qp_gradient(st.u) - sol.grad(X)) ** 2, axis=(1, 2))))
            e0.append(np.sqrt(w @ np.sum((ops.value @ st.u - sol.u(X)) ** 2, axis=1)))
    rate = lambda e: np.polyfit(np.log(hs), np.log(e), 1)[0]   # noqa: E731
    # measured: H¹ 1.96, L² 2.87, P1 H¹ 1.03; P2 error 1.9 % of P1's on the finest mesh
    assert rate(e1) > 1.8 and rate(e0) > 2.7 and 0.8 < rate(p1) < 1.3
    assert e1[-1] < 0.1 * p1[-1]


# ---- contact ------------------------------------------------------------------------------------
def test_sliding_crack_slip_against_the_analytic_solution():
    """Case C3 (single inclined crack under compression, Coulomb): P2 against P1 on one mesh."""
    psi, ell, sigma, E, nu = np.deg2rad(20.0), 1.0, 1.0e8, 25.0e9, 0.25
    F = np.tan(np.deg2rad(30.0))
    a = ell * np.array([np.cos(psi), np.sin(psi)])
    specs = [FractureSpec("crack", np.array([-a, a]))]
    mesh = simplicial_mesh([-40, -40], [40, 40], specs, 4.0, fracture_size=0.1, grading=0.3, mirror="fractures")
    fm = FracturedMesh.build(mesh, specs)
    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    zero = lambda X, t: 0 * X   # noqa: E731
    exact = SingleCrack(sigma, psi, ell, E, nu, F)
    err = {}
    for order in (1, 2):
        nc = mesh.n_cells
        data = MechanicsData(mu=np.full(nc, mu), lam=np.full(nc, lam),
                             displacement=[DisplacementBC("xmin", (0,), zero), DisplacementBC("ymin", (1,), zero)],
                             traction=[TractionBC("xmax", lambda X, t: np.tile([-sigma, 0.0], (len(X), 1)))],
                             contact=ContactSpec("coulomb", F, 0.0), two_sided=True, order=order)
        P = ContactMechanics(fm, data)
        st = P.solve(verbose=False)
        assert np.all(st.state == SLIP)
        err[order] = exact.errors(P, st, arc_length(fm))
    # measured: slip 10.9 % (P1) and 3.7 % (P2); λ_n 0.41 % and 0.025 %
    assert err[2]["slip_L2_rel"] < 0.05 and err[2]["slip_L2_rel"] < 0.5 * err[1]["slip_L2_rel"]
    assert err[2]["lambda_n_L2_rel"] < 0.002


# ---- poromechanics ------------------------------------------------------------------------------
def test_terzaghi_with_quadratic_displacements():
    """The Biot coupling b ∫_K p div v by quadrature: undrained response, consolidation against
    the series solution and the discrete energy identity on a triangulated column."""
    from test_poromechanics import TZ, ZERO, _lame, _terzaghi_constants, terzaghi_pressure

    from polypore.models.energy import check_energy
    from polypore.models.flow import FlowData, Pressure
    from polypore.models.poromechanics import Poromechanics

    mu, lam = _lame(TZ["E"], TZ["nu"])
    fm = FracturedMesh.build(simplicial_mesh([0, 0], [0.1, TZ["H"]], [], 0.05), [])
    nc = fm.mesh.n_cells
    md = MechanicsData(mu=np.full(nc, mu), lam=np.full(nc, lam), order=2,
                       displacement=[DisplacementBC("ymin", (0, 1), ZERO), DisplacementBC("xmin", (0,), ZERO),
                                     DisplacementBC("xmax", (0,), ZERO)],
                       traction=[TractionBC("ymax", lambda X, t: np.tile([0.0, -TZ["load"] * (t > 0)], (len(X), 1)))])
    fd = FlowData(permeability=TZ["k"], viscosity=TZ["eta"], biot_modulus=TZ["M"], biot_coefficient=TZ["b"])
    P = Poromechanics(fm, md, fd, {"ymax": Pressure(0.0)})
    Kd, cv, p0 = _terzaghi_constants()
    Tc = TZ["H"] ** 2 / cv
    st, info = P.step(P.initial_state(0.0), 1e-6 * Tc)
    z = fm.mesh.geometry.cell_centroid[:, 1]
    # undrained: p = b M σ/(K_d + b² M) below the drained top cells, settlement σ H/(K_d + b² M)
    assert np.abs(P.cell_pressure(st) / p0 - 1)[z < 0.9].max() < 1e-4
    top = np.isclose(P.mech.slot_points[:, 1], TZ["H"])
    settle = TZ["load"] * TZ["H"] / (Kd + TZ["b"] ** 2 * TZ["M"])
    assert np.allclose(st.u[: P.mech.space.n_point_slots][top, 1], -settle, rtol=2e-3)
    energies = [info.energy]
    for _ in range(40):
        st, info = P.step(st, 0.005 * Tc)
        energies.append(info.energy)
    # measured 2.7e-3 (the same as order 1: the pressure error is the flow scheme's)
    assert np.abs(P.cell_pressure(st) - terzaghi_pressure(z, st.time)).max() < 1e-2 * p0
    assert not check_energy(energies)
    assert max(abs(e.defect) / e.scale for e in energies) < 1e-12


# ---- input --------------------------------------------------------------------------------------
@pytest.mark.parametrize("order", [3, 0, True, 1.5])
def test_bad_order_names_the_field(order):
    with pytest.raises(InputError) as exc:
        MechanicsData(mu=1.0, lam=1.0, order=order)
    assert exc.value.field == "order"


def test_order_2_needs_a_simplicial_mesh():
    mesh = cartesian_mesh([grid_coordinates(0, 1, 3), grid_coordinates(0, 1, 3)])
    fm = FracturedMesh.build(mesh, [])
    bcs = [DisplacementBC("xmin", (0, 1), lambda X, t: 0 * X)]
    with pytest.raises(InputError) as exc:
        ContactMechanics(fm, _data(fm, bcs))
    assert exc.value.field == "order" and "simplicial" in str(exc.value)
