"""Stress changes along a displaced (offset) dipping fault from a uniform pressure change in the
reservoir: closed-form plane-strain inclusion solution (Jansen, Singhal & Vossepoel 2019 setting).

Setting (derivation: ``docs/displaced_fault_reference.md``). An infinite, homogeneous, isotropic,
linear poro-elastic full space in plane strain (coordinates x horizontal, y upward, m), Biot
coefficient α, Poisson's ratio ν. The pore pressure changes by a uniform Δp (Pa) inside a region
Ω and not outside. The total stress change is then, with η = α (1 − 2ν) / (2 (1 − ν)) and
ψ = (1/2π) ∫_Ω ln|x − x'| dA' (∇²ψ = χ_Ω),

    Δσ_xx = −2ηΔp ψ_,yy,   Δσ_yy = −2ηΔp ψ_,xx,   Δσ_xy = 2ηΔp ψ_,xy     (tension positive),

independent of the Young's modulus. For a polygon the Hessian of ψ is a sum over its edges
(a, b) with unit tangent e (counter-clockwise) and outward normal m:

    ψ_,ij = −(1/2π) Σ_edges [ ln(r_a/r_b) e_i m_j + Θ m_i m_j ],
    Θ = −atan2((a − x) × (b − x), (a − x)·(b − x)),

r_a = |x − a|: the logarithms make the stress singular (∝ ln r) at the corners, Θ (the angle the
edge subtends) jumps by 2π across the edge, which carries the jump of the stress across ∂Ω.

Geometry of the displaced fault. The fault is the line x = y cot θ through the origin (θ the dip
from horizontal, 0 < θ ≤ 90°; the fault dips towards −x). The hanging wall (left, x < y cot θ)
holds the reservoir for y_a ≤ y ≤ y_b, the footwall (right) for y_c ≤ y ≤ y_d, with

    y_a = −h/2 − t/2,  y_b = h/2 − t/2   (hanging wall: lowered by t/2),
    y_c = −h/2 + t/2,  y_d = h/2 + t/2   (footwall: raised by t/2),

h the reservoir thickness and t the throw (t > 0: normal-fault offset). Each block extends to
infinity away from the fault (``width=None``, laterally infinite as we understand the paper's
setting) or to x = ∓width. :func:`displaced_fault_grid` builds the geometry as a corner-point slab.

Sign conventions on the fault (reported by :func:`fault_stress_changes`):

* n = (sin θ, −cos θ), the unit normal pointing from the hanging wall into the footwall;
  e = (cos θ, sin θ), the up-dip unit tangent; s = y / sin θ, the along-dip coordinate (m).
* Δσ_n = −n·Δσ·n: normal stress change, **compression positive** (total stress).
* Δτ = e·Δσ·n: the up-dip component of the traction the footwall exerts on the hanging wall.
  Δτ > 0 is the shear a normal-faulting stress state puts on the fault (the footwall holds the
  hanging wall up against sliding down-dip): it drives **normal slip** (hanging wall down-dip);
  Δτ < 0 drives reverse slip. (Check: θ → 0, e = x̂, n = −ŷ gives Δτ = −Δσ_xy, and a simple
  shear σ_xy > 0 moves the upper side, the hanging wall, along +x = up-dip: reverse sense,
  Δτ < 0.)
* σ·n is continuous across the fault even where the fault bounds the reservoir (traction
  continuity), so Δσ_n and Δτ are single-valued there; only the along-fault normal stress e·σ·e
  jumps, by −2ηΔp from the non-reservoir to the reservoir side.
* The effective normal stress change uses the fault's pressure change Δp_f: Δσ'_n = Δσ_n − Δp_f,
  with Δp_f = Δp where the reservoir lies on at least one side of the fault, else 0 (polypore's
  λ_n = −σ_nn − p_f: the fault fluid pressure enters with coefficient 1).
* polypore: with n⁺ = n (K⁺ the hanging wall), Δλ_n = Δσ'_n and Δλ_τ = −Δτ e (λ = −T⁺).

The scaling factor C = (1 − 2ν) α Δp / (2π (1 − ν)) = 2ηΔp/(2π) is the prefactor of every term.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TWO_PI = 2.0 * np.pi


def eta(alpha: float, nu: float) -> float:
    """Poroelastic stress coefficient η = α (1 − 2ν) / (2 (1 − ν)) (dimensionless)."""
    return alpha * (1.0 - 2.0 * nu) / (2.0 * (1.0 - nu))


def scaling_factor(dp: float, alpha: float, nu: float) -> float:
    """C = (1 − 2ν) α Δp / (2π (1 − ν)) in Pa: the stress scale of the closed form."""
    return 2.0 * eta(alpha, nu) * dp / TWO_PI


def _cross(u, v):
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _dot(u, v):
    return u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1]


def _cw(e):
    """e rotated by −90°: the outward normal of an edge of a counter-clockwise boundary."""
    return np.array([e[1], -e[0]])


def _angle(u, v, on_sign, tol):
    """−atan2(u × v, u·v) per point; on the segment itself (u × v ≈ 0, u·v < 0) the sign of the
    cross product is replaced by ``on_sign`` (the side the point is approached from)."""
    c = _cross(u, v)
    d = _dot(u, v)
    if on_sign is not None:
        on = (np.abs(c) <= tol * np.sqrt(_dot(u, u) * _dot(v, v))) & (d < 0.0)
        c = np.where(on, np.copysign(0.0, on_sign), c)
    return -np.arctan2(c, d)


def _approach_sign(approach, chord):
    """Sign of the cross product u × v on a segment with direction ``chord`` when the point is
    approached from the side ``approach`` (n, 2): −approach × chord (limit x + δ·approach)."""
    if approach is None:
        return None
    return -_cross(approach, np.broadcast_to(chord, approach.shape))


def potential_hessian(points, vertices, ray=None, approach=None, tol: float = 1e-10) -> np.ndarray:
    """Hessian of ψ = (1/2π) ∫_Ω ln|x − x'| dA' for a polygonal region Ω.

    Parameters
    ----------
    points : (n, 2) array, m
        Evaluation points (not at a vertex: the Hessian is logarithmically singular there).
    vertices : (m, 2) array, m
        Boundary vertices, counter-clockwise.
    ray : (2,) array, optional
        If given, Ω is unbounded: its boundary arrives at ``vertices[0]`` from infinity along
        the direction −ray and leaves ``vertices[-1]`` to infinity along +ray (a half-strip
        extending along ``ray``); otherwise the polygon is closed by the edge last → first.
    approach : (n, 2) array, optional
        For points on an edge: the limit is taken from x + δ·approach, δ → 0⁺ (points
        within ``tol`` relative of an edge count as on it). Off the boundary it is unused.

    Returns
    -------
    (n, 2, 2) array
        ψ_,ij (dimensionless); its trace is χ_Ω (1 inside, 0 outside).
    """
    P = np.atleast_2d(np.asarray(points, float))
    V = np.asarray(vertices, float)
    A = None if approach is None else np.broadcast_to(np.asarray(approach, float), P.shape)
    H = np.zeros((P.shape[0], 2, 2))
    lnr = 0.5 * np.log(np.sum((P[:, None, :] - V[None, :, :]) ** 2, axis=-1))  # (n, m)
    edges = [(k, k + 1) for k in range(len(V) - 1)]
    if ray is None:
        edges.append((len(V) - 1, 0))
    for ka, kb in edges:
        chord = V[kb] - V[ka]
        e = chord / np.hypot(*chord)
        m = _cw(e)
        th = _angle(V[ka] - P, V[kb] - P, _approach_sign(A, chord), tol)
        H -= ((lnr[:, ka] - lnr[:, kb])[:, None, None] * np.outer(e, m)
              + th[:, None, None] * np.outer(m, m)) / TWO_PI
    if ray is not None:
        d = np.asarray(ray, float) / np.hypot(*ray)
        e_in = -d
        m_in = _cw(e_in)
        # The two rays' logarithms at infinity cancel (antiparallel rays, same e ⊗ m); what is
        # left is ln(r_last / r_first) e_in ⊗ m_in. The far closing arc subtends no angle.
        th_in = _angle(np.broadcast_to(d, P.shape), V[0] - P, _approach_sign(A, e_in), tol)
        th_out = _angle(V[-1] - P, np.broadcast_to(d, P.shape), _approach_sign(A, d), tol)
        H -= ((lnr[:, -1] - lnr[:, 0])[:, None, None] * np.outer(e_in, m_in)
              + (th_in + th_out)[:, None, None] * np.outer(m_in, m_in)) / TWO_PI
    return H


def stress_from_hessian(H, dp: float, alpha: float, nu: float) -> np.ndarray:
    """(n, 2, 2) total stress change (Pa, tension positive) from ψ_,ij: σ = 2ηΔp (ψ_,ij − δ_ij ∇²ψ)."""
    tr = H[:, 0, 0] + H[:, 1, 1]
    return 2.0 * eta(alpha, nu) * dp * (H - tr[:, None, None] * np.eye(2))


@dataclass(frozen=True)
class DisplacedFault:
    """Reservoir offset by a dipping fault (see the module docstring for the geometry).

    Attributes
    ----------
    thickness : float, m
        Reservoir thickness h.
    throw : float, m
        Offset t ≥ 0 (hanging wall lowered by t/2, footwall raised by t/2).
    dip : float, degrees
        Dip θ of the fault from horizontal, 0 < θ ≤ 90.
    width : float or None, m
        Lateral extent: each block ends at x = ∓width (vertical sides); None: infinite.
    """

    thickness: float = 200.0
    throw: float = 0.0
    dip: float = 60.0
    width: float | None = None

    @property
    def corners_y(self) -> np.ndarray:
        """(4,) elevations y_a, y_b (hanging wall bottom, top), y_c, y_d (footwall bottom, top), m."""
        h, t = self.thickness, self.throw
        return np.array([-h / 2 - t / 2, h / 2 - t / 2, -h / 2 + t / 2, h / 2 + t / 2])

    @property
    def cot(self) -> float:
        return np.cos(np.radians(self.dip)) / np.sin(np.radians(self.dip))

    def fault_point(self, y) -> np.ndarray:
        """(n, 2) points of the fault line at elevations y (m)."""
        y = np.atleast_1d(np.asarray(y, float))
        return np.stack([y * self.cot, y], axis=-1)

    @property
    def normal(self) -> np.ndarray:
        """Unit normal n from the hanging wall into the footwall."""
        th = np.radians(self.dip)
        return np.array([np.sin(th), -np.cos(th)])

    @property
    def tangent(self) -> np.ndarray:
        """Up-dip unit tangent e."""
        th = np.radians(self.dip)
        return np.array([np.cos(th), np.sin(th)])

    def blocks(self) -> list[tuple[np.ndarray, np.ndarray | None]]:
        """The two reservoir blocks as (counter-clockwise vertices (k, 2), ray or None)."""
        ya, yb, yc, yd = self.corners_y
        Pa, Pb, Pc, Pd = self.fault_point([ya, yb, yc, yd])
        if self.width is None:
            return [(np.array([Pa, Pb]), np.array([-1.0, 0.0])),
                    (np.array([Pd, Pc]), np.array([1.0, 0.0]))]
        W = float(self.width)
        return [(np.array([[-W, ya], Pa, Pb, [-W, yb]]), None),
                (np.array([Pc, [W, yc], [W, yd], Pd]), None)]

    def inside(self, points) -> np.ndarray:
        """(n,) bool: strictly inside the reservoir (open set)."""
        P = np.atleast_2d(np.asarray(points, float))
        ya, yb, yc, yd = self.corners_y
        xf = P[:, 1] * self.cot
        W = np.inf if self.width is None else self.width
        left = (P[:, 0] < xf) & (P[:, 0] > -W) & (P[:, 1] > ya) & (P[:, 1] < yb)
        right = (P[:, 0] > xf) & (P[:, 0] < W) & (P[:, 1] > yc) & (P[:, 1] < yd)
        return left | right

    def hessian(self, points, approach=None) -> np.ndarray:
        """(n, 2, 2) ψ_,ij of the whole reservoir (sum over the two blocks)."""
        P = np.atleast_2d(np.asarray(points, float))
        return sum(potential_hessian(P, V, ray, approach) for V, ray in self.blocks())

    def stress(self, points, dp: float, alpha: float = 1.0, nu: float = 0.25, approach=None) -> np.ndarray:
        """(n, 2, 2) total stress change (Pa, tension positive) at points (n, 2), m.

        On the reservoir boundary pass ``approach`` (n, 2): the one-sided limit from x + δ·approach.
        The effective stress change (tension positive, σ' = σ + α p I) is this plus α Δp I inside.
        """
        return stress_from_hessian(self.hessian(points, approach), dp, alpha, nu)

    def fault_pressure(self, y, dp: float) -> np.ndarray:
        """(n,) Δp_f on the fault at elevations y: Δp where the reservoir touches the fault on at
        least one side (closed intervals), else 0."""
        y = np.atleast_1d(np.asarray(y, float))
        ya, yb, yc, yd = self.corners_y
        touch = ((y >= ya) & (y <= yb)) | ((y >= yc) & (y <= yd))
        return np.where(touch, dp, 0.0)

    def fault_stress_changes(self, y, dp: float, alpha: float = 1.0, nu: float = 0.25) -> dict:
        """Normal and shear stress changes along the fault at elevations y (n,), m.

        Returns a dict of (n,) arrays: ``y``, ``s`` (along-dip coordinate y / sin θ, m),
        ``sigma_n`` (Δσ_n, total, compression positive, Pa), ``tau`` (Δτ, Pa, positive: the
        footwall's traction on the hanging wall points up-dip, normal-slip sense), ``dp_fault`` (Δp_f, Pa), ``sigma_n_eff`` (Δσ_n − Δp_f, Pa), and the
        along-fault normal stress ``sigma_ee_hw``, ``sigma_ee_fw`` (tension positive, Pa) on the
        hanging-wall and footwall sides (they differ by 2ηΔp where the fault bounds the reservoir).
        Δσ_n and Δτ are computed on the hanging-wall side; σ·n is continuous across the fault.
        The corners y_a … y_d are logarithmic singularities (inf/nan there).
        """
        y = np.atleast_1d(np.asarray(y, float))
        P = self.fault_point(y)
        n, e = self.normal, self.tangent
        s_hw = self.stress(P, dp, alpha, nu, approach=np.broadcast_to(-n, P.shape))
        s_fw = self.stress(P, dp, alpha, nu, approach=np.broadcast_to(n, P.shape))
        tn = s_hw @ n
        dpf = self.fault_pressure(y, dp)
        sig_n = -(tn @ n)
        return {"y": y, "s": y / np.sin(np.radians(self.dip)), "sigma_n": sig_n, "tau": tn @ e,
                "dp_fault": dpf, "sigma_n_eff": sig_n - dpf,
                "sigma_ee_hw": np.einsum("i,nij,j->n", e, s_hw, e),
                "sigma_ee_fw": np.einsum("i,nij,j->n", e, s_fw, e)}

    def fault_closed_form(self, y, dp: float, alpha: float = 1.0, nu: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
        """Δσ_n and Δτ (Pa, conventions of the module) on the fault at elevations y (n,), m, from the
        explicit fault formulas of the laterally infinite reservoir (``width`` must be None)::

            L = ln(|y − y_a| |y − y_d| / (|y − y_b| |y − y_c|)),  k = χ_hw(y) + χ_fw(y),
            Δσ_n = C (π sin²θ k − sinθ cosθ L),   Δτ = −C (π sinθ cosθ k + sin²θ L),

        χ_hw = 1 on y_a < y < y_b (the fault bounds the hanging-wall block), χ_fw on y_c < y < y_d,
        C = (1 − 2ν) α Δp / (2π (1 − ν)). Same values as :meth:`fault_stress_changes` (which sums
        the edge terms); derivation in ``docs/displaced_fault_reference.md``.
        """
        if self.width is not None:
            raise ValueError("the explicit fault formulas are for laterally infinite blocks (width=None)")
        y = np.atleast_1d(np.asarray(y, float))
        ya, yb, yc, yd = self.corners_y
        th = np.radians(self.dip)
        sn, cs = np.sin(th), np.cos(th)
        L = np.log(np.abs(y - ya) * np.abs(y - yd) / (np.abs(y - yb) * np.abs(y - yc)))
        k = ((y > ya) & (y < yb)).astype(float) + ((y > yc) & (y < yd))
        C = scaling_factor(dp, alpha, nu)
        return C * (np.pi * sn * sn * k - sn * cs * L), -C * (np.pi * sn * cs * k + sn * sn * L)

    def fault_face_means(self, y1, y2, dp: float, alpha: float = 1.0, nu: float = 0.25) -> dict:
        """Means of Δσ_n, Δτ and Δσ'_n over fault segments [y1, y2] (elevations, y1 < y2, m), exact,
        for the laterally infinite reservoir (``width`` None): the mean of ln|y − y_k| over a segment
        is [F(y2 − y_k) − F(y1 − y_k)] / (y2 − y1), F(u) = u ln|u| − u, finite even at a corner.

        A segment should not straddle a corner (k(y) is taken at its midpoint, as is Δp_f). These
        are the values a P0 (face-wise constant) approximation converges to face by face; point
        values at a face's centroid are not, next to the logarithmic corners. Returns a dict of
        (n,) arrays ``sigma_n``, ``tau``, ``dp_fault``, ``sigma_n_eff`` (Pa, conventions of the module).
        """
        if self.width is not None:
            raise ValueError("the face means are for laterally infinite blocks (width=None)")
        y1 = np.atleast_1d(np.asarray(y1, float))
        y2 = np.atleast_1d(np.asarray(y2, float))
        ya, yb, yc, yd = self.corners_y

        def F(u):
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(u == 0.0, 0.0, u * np.log(np.abs(u)) - u)

        def mean_ln(yk):
            return (F(y2 - yk) - F(y1 - yk)) / (y2 - y1)

        L = mean_ln(ya) + mean_ln(yd) - mean_ln(yb) - mean_ln(yc)
        ym = 0.5 * (y1 + y2)
        k = ((ym > ya) & (ym < yb)).astype(float) + ((ym > yc) & (ym < yd))
        th = np.radians(self.dip)
        sn, cs = np.sin(th), np.cos(th)
        C = scaling_factor(dp, alpha, nu)
        sig_n = C * (np.pi * sn * sn * k - sn * cs * L)
        dpf = self.fault_pressure(ym, dp)
        return {"sigma_n": sig_n, "tau": -C * (np.pi * sn * cs * k + sn * sn * L), "dp_fault": dpf,
                "sigma_n_eff": sig_n - dpf}

    def corner_log_coefficients(self, dp: float, alpha: float = 1.0, nu: float = 0.25) -> np.ndarray:
        """(4, 2) coefficients (Pa) of ln r in (Δσ_n, Δτ) on the fault near the corners y_a … y_d:
        Δσ_n ≈ A_n ln r + O(1), Δτ ≈ A_τ ln r + O(1) at a distance r from the corner along the fault.

        From the vertex terms −(1/2π) ln r_k (e_out ⊗ m_out − e_in ⊗ m_in) of every block that has
        a vertex there (coinciding corners, e.g. t = h, add up).
        """
        out = np.zeros((4, 2))
        n, e = self.normal, self.tangent
        Yc = self.corners_y
        Pc = self.fault_point(Yc)
        for V, ray in self.blocks():
            k = len(V)
            for j in range(k):
                if ray is not None:
                    e_out = ray if j == k - 1 else V[j + 1] - V[j]
                    e_in = ray * -1.0 if j == 0 else V[j] - V[j - 1]
                else:
                    e_out = V[(j + 1) % k] - V[j]
                    e_in = V[j] - V[j - 1]
                e_out = e_out / np.hypot(*e_out)
                e_in = e_in / np.hypot(*e_in)
                G = -(np.outer(e_out, _cw(e_out)) - np.outer(e_in, _cw(e_in))) / TWO_PI
                S = stress_from_hessian(G[None], dp, alpha, nu)[0]
                hit = np.hypot(*(Pc - V[j]).T) < 1e-9 * self.thickness
                out[hit, 0] += -(n @ S @ n)
                out[hit, 1] += e @ S @ n
        return out


def graded_sizes(length: float, s0: float = 25.0, ratio: float = 1.2) -> list[float]:
    """Cell sizes s0, s0 r, s0 r², … filling ``length`` (m) for :func:`displaced_fault_grid`'s
    graded ``columns`` and ``layers_*``; the remainder is a cell of its own if it is at least half
    the next size, else it is added to the last cell."""
    sizes, s = [], s0
    while sum(sizes) + s < length:
        sizes.append(s)
        s *= ratio
    rest = length - sum(sizes)
    if rest >= 0.5 * s:
        sizes.append(rest)
    else:
        sizes[-1] += rest
    return sizes


def displaced_fault_grid(fault: DisplacedFault, *, half_width: float = 2000.0, half_height: float = 2000.0,
                         nx: int = 40, nz_reservoir: int = 8, nz_above: int = 12, nz_below: int = 12,
                         strike_length: float | None = None, depth: float = 3000.0,
                         columns=None, layers_above=None, layers_below=None, core: float = 0.0):
    """A corner-point grid of the displaced fault: a slab one cell thick along the strike.

    Grid frame (GRDECL): x across the fault, y along the strike, depth positive downwards; the
    module's elevation is y_elev = ``depth`` − depth (the reservoir's mid-depth at y_elev = 0, the
    fault through x = 0 there). Pillars are straight and lie in x–depth planes: the pillar line
    i = nx/2 follows the fault (x = y_elev cot θ), the others lean less and less towards the
    lateral sides, where they are vertical (x = ∓half_width), so the lateral sides are planes for
    rollers. Horizons are horizontal on each side of the fault: nz_above layers from the top
    (y_elev = half_height) to the reservoir's top, nz_reservoir layers in the reservoir, nz_below
    to the bottom (y_elev = −half_height); the hanging wall's reservoir lies at y_a … y_b, the
    footwall's at y_c … y_d (the model's top and bottom stay flat). Every cell is a hexahedron
    with planar faces; the reservoir cells tile the blocks of ``DisplacedFault(h, t, θ,
    width=half_width)`` exactly.

    Parameters
    ----------
    fault : DisplacedFault
        Thickness, throw (< 2 half_height − h) and dip; its ``width`` is not used.
    half_width, half_height : float, m
        The slab spans x ∈ [−half_width, half_width], y_elev ∈ [−half_height, half_height];
        pillars do not cross if half_height < half_width tan θ.
    nx : int
        Columns across (even: the fault is the pillar line nx/2).
    nz_reservoir, nz_above, nz_below : int
        Layers.
    strike_length : float, m
        Slab thickness along y (default half_width / nx · 2, one column's width).
    depth : float, m
        Depth of the reservoir's mid-plane.
    columns : sequence of float, m, optional
        Graded columns: widths from the fault outwards (the same on both sides; the outermost
        is stretched or shrunk so that they reach ±half_width, and must stay positive); replaces
        ``nx`` (nx = 2 len(columns)). Default: nx equal columns.
    layers_above, layers_below : sequence of float, m, optional
        Graded layers: thicknesses from the reservoir's top upwards (resp. its bottom downwards),
        the outermost adjusted on each side to reach ±half_height; replace nz_above / nz_below.
        Default: equal layers.
    core : float, m
        Pillars with |x| ≤ core at the reservoir's mid-plane are parallel to the fault, the lean
        then decreasing linearly to vertical at ±half_width (0: from the fault on, as by
        default). With graded columns this keeps the cells near the fault the same when the
        slab is made wider or taller. Pillars do not cross if half_height < (half_width − core) tan θ.

    Returns
    -------
    CornerPointGrid
        dims (nx, 1, nz_above + nz_reservoir + nz_below), FAULTS record ``F`` on the pillar line
        nx/2 over all layers, cell keyword RESNUM (1 in the reservoir, 0 elsewhere: use
        ``regions="RESNUM"`` when processing) and PORO, NTG, PERMX/Y/Z, FIPNUM as the
        generator's.
    """
    from ..core.errors import InputError
    from ..mesh.cornerpoint.reader import CornerPointGrid

    L, D, h = float(half_width), float(half_height), float(fault.thickness)
    if columns is not None:
        nx = 2 * len(columns)
    nx = int(nx)
    if nx < 2 or nx % 2:
        raise InputError("displaced_fault_grid.nx", f"must be even and ≥ 2, got {nx}")
    if layers_above is not None:
        nz_above = len(layers_above)
    if layers_below is not None:
        nz_below = len(layers_below)
    cot = fault.cot
    core = float(core)
    if not 0.0 <= core < L:
        raise InputError("displaced_fault_grid.core", f"must be in [0, half_width), got {core}")
    if D * cot >= L - core:
        raise InputError("displaced_fault_grid", f"pillars cross: half_height {D} ≥ (half_width − core) tan θ = "
                         f"{(L - core) / cot:g}")
    ya, yb, yc, yd = fault.corners_y
    if min(ya, yc) <= -D or max(yb, yd) >= D:
        raise InputError("displaced_fault_grid", "the reservoir must lie inside the slab")
    ly = 2.0 * L / nx if strike_length is None else float(strike_length)
    nz = int(nz_above) + int(nz_reservoir) + int(nz_below)

    def graded(sizes, length, what):
        # offsets 0 … length of the given cell sizes, the last one adjusted to reach length
        off = np.concatenate([[0.0], np.cumsum(np.asarray(sizes, float))])
        off[-1] = length
        if np.any(np.diff(off) <= 0.0):
            raise InputError(f"displaced_fault_grid.{what}", f"the sizes do not fit in {length:g} m with a positive "
                             "outermost cell")
        return off

    # pillars: x at elevation y is x0 + w cot θ y, w = 1 on the fault (and in the core), 0 on the lateral sides
    if columns is None:
        x0 = np.linspace(-L, L, nx + 1)
    else:
        half = graded(columns, L, "columns")
        x0 = np.concatenate([-half[::-1], half[1:]])
    w = np.clip((L - np.abs(x0)) / (L - core), 0.0, 1.0)
    ytop, ybot = D, -D
    coord = np.zeros((nx + 1, 2, 6))
    for j, yy in enumerate((0.0, ly)):
        coord[:, j, 0], coord[:, j, 1], coord[:, j, 2] = x0 + w * cot * ytop, yy, depth - ytop
        coord[:, j, 3], coord[:, j, 4], coord[:, j, 5] = x0 + w * cot * ybot, yy, depth - ybot

    def horizons(bottom, top):
        # elevations of the nz + 1 horizons of one side, top down
        up = (np.linspace(D, top, int(nz_above) + 1) if layers_above is None
              else top + graded(layers_above, D - top, "layers_above")[::-1])
        down = (np.linspace(bottom, -D, int(nz_below) + 1) if layers_below is None
                else bottom - graded(layers_below, bottom + D, "layers_below"))
        return np.concatenate([up, np.linspace(top, bottom, int(nz_reservoir) + 1)[1:], down[1:]])

    side = np.where(np.arange(nx) < nx // 2, 0, 1)                       # 0 hanging wall, 1 footwall
    H = np.stack([horizons(ya, yb), horizons(yc, yd)])                    # (2, nz + 1)
    k = np.arange(2 * nz)
    elev = H[side][:, (k // 2) + (k % 2)]                                 # (nx, 2nz): cell top/bottom
    zcorn = np.repeat(depth - elev, 2, axis=0)[:, None, :] * np.ones((1, 2, 1))
    res = np.zeros((nx, 1, nz))
    res[:, :, int(nz_above):int(nz_above) + int(nz_reservoir)] = 1.0
    kz = np.broadcast_to(np.arange(nz)[None, None, :], (nx, 1, nz))
    # RESNUM: GRDECL keywords have at most 8 characters (the reader rejects longer ones)
    props = {"RESNUM": res, "PORO": np.full((nx, 1, nz), 0.2), "NTG": np.ones((nx, 1, nz)),
             "PERMX": np.full((nx, 1, nz), 100.0), "PERMY": np.full((nx, 1, nz), 100.0),
             "PERMZ": np.full((nx, 1, nz), 10.0), "FIPNUM": (kz + 1).astype(float)}
    p = nx // 2
    return CornerPointGrid((nx, 1, nz), coord, zcorn, np.ones((nx, 1, nz), bool), None,
                           {"F": [(p, p, 1, 1, 1, nz, "X")]}, props, "displaced-fault")
