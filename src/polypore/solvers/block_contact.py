"""Krylov solver for the semi-smooth Newton systems of contact problems (3D sizes).

The Newton Jacobian has the block form (u: displacement dofs, l: multiplier dofs)

    [ A    Bt ] [du]   [ru]
    [ Cu   Cl ] [dl] = [rc]

with Cl block-diagonal (one d×d block per fracture face). Where a face is closed, its Cl
block is singular (the row is a constraint on the jump), so the multipliers cannot be
condensed exactly. The preconditioner condenses them with a regularised block
Cl_ρ = Cl + ρ s I (s the face's coupling scale, ‖Cu‖ of its rows): this turns closed faces
into penalty springs of the stiffness of the neighbouring cells, and

    S = A − Bt Cl_ρ⁻¹ Cu

is an elasticity-like matrix on which smoothed-aggregation AMG with the rigid-body
near-nullspace works. GMRES on the full system, right-preconditioned by
(u = AMG_S⁻¹ (ru − Bt Cl_ρ⁻¹ rc), l = Cl_ρ⁻¹ (rc − Cu u)), converges in a few tens of
iterations; the regularisation only affects the preconditioner, never the solution.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..core.errors import RunError

log = logging.getLogger("polypore")


@dataclass
class BlockContactSolver:
    """Solve the 2×2 contact Newton system with GMRES + AMG on the condensed matrix.

    Parameters
    ----------
    n_u : number of displacement unknowns (the first block)
    d : block size of the multipliers (2 or 3)
    near_nullspace : (n_u, k) rigid-body modes of the free displacement dofs
    rho : regularisation of the closed-face blocks (dimensionless)
    rtol, maxiter : GMRES tolerance (relative residual) and iteration cap
    """

    n_u: int
    d: int
    near_nullspace: np.ndarray | None = None
    rho: float = 1.0
    rtol: float = 1e-8
    maxiter: int = 300
    restart: int = 100
    iterations: list = field(default_factory=list)
    seconds: float = 0.0

    def solve(self, J, rhs) -> np.ndarray:
        import pyamg

        t0 = time.perf_counter()
        J = sp.csr_matrix(J)
        n_u, d = self.n_u, self.d
        A = J[:n_u, :n_u]
        Bt = J[:n_u, n_u:]
        Cu = J[n_u:, :n_u]
        Cl = J[n_u:, n_u:]
        Cinv, S = _condense(A, Bt, Cu, Cl, d, self.rho)
        ml = pyamg.smoothed_aggregation_solver(S, B=self.near_nullspace, strength="symmetric", max_coarse=1000)
        amg = ml.aspreconditioner(cycle="V")

        def apply(r):
            ru, rc = r[:n_u], r[n_u:]
            xu = amg @ (ru - Bt @ (Cinv @ rc))
            xc = Cinv @ (rc - Cu @ xu)
            return np.concatenate([xu, xc])

        x = _gmres(J, rhs, apply, self)
        self.seconds += time.perf_counter() - t0
        log.debug("block contact solver: %d GMRES iterations, %.2f s", self.iterations[-1], time.perf_counter() - t0)
        return x


def _condense(A, Bt, Cu, Cl, d: int, rho: float):
    """(Cl_ρ⁻¹ as csr, S = A − Bt Cl_ρ⁻¹ Cu symmetrised): closed faces become springs (module docstring)."""
    nf = Cl.shape[0] // d
    if nf == 0:
        return sp.csr_matrix((0, 0)), sp.csr_matrix(A)
    blocks = _diag_blocks(Cl, nf, d)
    rowscale = np.sqrt(np.asarray(Cu.multiply(Cu).sum(axis=1)).ravel()).reshape(nf, d).max(axis=1)
    reg = blocks + rho * np.maximum(rowscale, 1e-300)[:, None, None] * np.eye(d)
    Cinv = _block_diag_csr(np.linalg.inv(reg))
    S = (A - Bt @ Cinv @ Cu).tocsr()
    return Cinv, (0.5 * (S + S.T)).tocsr()


def _gmres(J, rhs, apply, solver):
    """Right-preconditioned GMRES with iteration count and failure message (shared by both solvers)."""
    n = J.shape[0]
    M = spla.LinearOperator((n, n), matvec=apply, dtype=float)
    its = [0]

    def cb(_):
        its[0] += 1

    x, info = spla.gmres(J, rhs, M=M, rtol=solver.rtol, restart=solver.restart, maxiter=solver.maxiter,
                         callback=cb, callback_type="pr_norm")
    solver.iterations.append(its[0])
    if info != 0:
        res = np.linalg.norm(J @ x - rhs) / max(np.linalg.norm(rhs), 1e-300)
        raise RunError(f"GMRES did not reach rtol={solver.rtol:g} in {its[0]} iterations (relative residual "
                       f"{res:.2e}); try solver.linear = 'pardiso'")
    return x


def _diag_blocks(C: sp.csr_matrix, nf: int, d: int) -> np.ndarray:
    """(nf, d, d) diagonal blocks of a block-diagonal csr matrix."""
    C = C.tocoo()
    out = np.zeros((nf, d, d))
    f = C.row // d
    keep = (C.col // d) == f
    np.add.at(out, (f[keep], C.row[keep] % d, C.col[keep] % d), C.data[keep])
    return out


def _block_diag_csr(blocks: np.ndarray) -> sp.csr_matrix:
    nf, d, _ = blocks.shape
    rows = (np.arange(nf)[:, None, None] * d + np.arange(d)[None, :, None]) + 0 * np.arange(d)[None, None, :]
    cols = (np.arange(nf)[:, None, None] * d + np.arange(d)[None, None, :]) + 0 * np.arange(d)[None, :, None]
    return sp.csr_matrix((blocks.ravel(), (rows.ravel(), cols.ravel())), shape=(nf * d, nf * d))


@dataclass
class BlockPoroSolver:
    """GMRES for the coupled step Jacobian [u, l, p] with a block lower-triangular preconditioner.

    Blocks: the (u, l) part is condensed as in :class:`BlockContactSolver` into S; the
    pressure block gets the algebraic fixed-stress-type Schur approximation
    Ŝ = F − G_pu diag(S)⁻¹ G_up (sparse); AMG on S (rigid-body near-nullspace) and on Ŝ.
    Apply: x_u = S⁻¹ r_u, x_p = Ŝ⁻¹ (r_p − G_pu x_u), x_l = Cl_ρ⁻¹ (r_l − Cu x_u).

    Parameters
    ----------
    n_u, d, n_l : sizes of the displacement block, the multiplier block size, the multiplier count × d
    """

    n_u: int
    d: int
    n_l: int
    near_nullspace: np.ndarray | None = None
    rho: float = 0.1
    rtol: float = 1e-8
    maxiter: int = 400
    restart: int = 100
    iterations: list = field(default_factory=list)
    seconds: float = 0.0

    def solve(self, J, rhs) -> np.ndarray:
        import pyamg

        t0 = time.perf_counter()
        J = sp.csr_matrix(J)
        nu, nl, d = self.n_u, self.n_l, self.d
        po = nu + nl
        A, Bt, Gup = J[:nu, :nu], J[:nu, nu:po], J[:nu, po:]
        Cu, Cl = J[nu:po, :nu], J[nu:po, nu:po]
        Gpu, F = J[po:, :nu], J[po:, po:]
        nf = nl // d
        Cinv, S = _condense(A, Bt, Cu, Cl, d, self.rho)
        dS = S.diagonal()
        Sp = (F - Gpu @ sp.diags(1.0 / dS) @ Gup).tocsr()
        Sp = 0.5 * (Sp + Sp.T)
        sign = -1.0 if np.mean(Sp.diagonal()) < 0 else 1.0   # AMG wants a positive definite operator
        ml_u = pyamg.smoothed_aggregation_solver(S, B=self.near_nullspace, strength="symmetric", max_coarse=1000)
        ml_p = pyamg.smoothed_aggregation_solver(sign * Sp, strength="symmetric", max_coarse=1000)
        Mu, Mp = ml_u.aspreconditioner(cycle="V"), ml_p.aspreconditioner(cycle="V")

        def apply(r):
            ru, rl, rp = r[:nu], r[nu:po], r[po:]
            xu = Mu @ (ru - Bt @ (Cinv @ rl)) if nf else Mu @ ru
            xp = sign * (Mp @ (rp - Gpu @ xu))
            xl = Cinv @ (rl - Cu @ xu) if nf else rl
            return np.concatenate([xu, xl, xp])

        x = _gmres(J, rhs, apply, self)
        self.seconds += time.perf_counter() - t0
        return x
