"""Smoothed-aggregation AMG set up without copies of the finest operator.

pyamg's ``smoothed_aggregation_solver`` holds, while it builds the finest level of a large S,
a strength matrix (a copy of S), ω/ρ D⁻¹S (two more copies, one scaled from the other) and the
full product S P for the Galerkin operator, which made its set-up a large run's memory peak
(docs/iterative_cornerpoint.md, sixth session). :func:`sa_hierarchy` builds that finest level
itself, with the same defaults and the same mathematics, and leaves the (small) coarser levels to pyamg:

* strength: pyamg's symmetric measure with θ = 0 keeps every stored entry of S, and the
  aggregation reads only the pattern, so S itself is the strength matrix (pyamg has this
  shortcut commented out);
* candidates improved by four symmetric Gauss–Seidel sweeps on S B = 0, then the tentative
  prolongator T (``fit_candidates``), as pyamg does;
* P = T − (ω/ρ) D⁻¹ S T with ω = 4/3 and ρ the spectral radius estimate of D⁻¹S (pyamg's
  estimator, on an operator rather than a scaled copy), formed block of rows by block of rows;
* R = Pᵀ as a transposed view of P (pyamg stores it as a second matrix), and the coarse operator
  Rᵀ S P summed over blocks of rows of S.

Levels below the finest are pyamg's, from the coarse operator in the block form pyamg gives it
(blocks of the near-null space's width).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..core.csr import csr_rows

# Rows of S per block of the products S T and S P (bounds their temporaries)
ROW_BLOCK = 25_000

SMOOTHER = ("block_gauss_seidel", {"sweep": "symmetric"})       # pyamg's default for SA
IMPROVE = ("block_gauss_seidel", {"sweep": "symmetric", "iterations": 4})
OMEGA = 4.0 / 3.0


def _row_blocks(n: int):
    return [(a, min(a + ROW_BLOCK, n)) for a in range(0, n, ROW_BLOCK)]


def sa_hierarchy(S, B, max_coarse: int = 1000, coarse_solver: str = "splu"):
    """pyamg MultilevelSolver of smoothed aggregation on S (csr, SPD) with near-null space B (n, k)
    (None: constants).

    Same defaults as ``pyamg.smoothed_aggregation_solver(S, B=B, strength="symmetric",
    max_coarse=max_coarse, coarse_solver=coarse_solver)`` (module docstring); the random start
    of the spectral radius estimate comes from NumPy's global state, as in pyamg.
    """
    import pyamg
    from pyamg.aggregation.aggregate import standard_aggregation
    from pyamg.aggregation.tentative import fit_candidates
    from pyamg.multilevel import MultilevelSolver
    from pyamg.relaxation.smoothing import change_smoothers
    from pyamg.relaxation.utils import relaxation_as_linear_operator
    from pyamg.util.linalg import approximate_spectral_radius

    S = sp.csr_matrix(S)
    S.sort_indices()
    n = S.shape[0]
    B = np.ones((n, 1)) if B is None else np.asarray(B, float).reshape(n, -1)     # pyamg's default: constants
    if n <= max_coarse:
        return pyamg.smoothed_aggregation_solver(S, B=B, strength="symmetric", max_coarse=max_coarse,
                                                 coarse_solver=coarse_solver)
    S.symmetry = "hermitian"
    agg, _ = standard_aggregation(S)
    B = relaxation_as_linear_operator(IMPROVE, S, np.zeros((n, 1))) @ B
    T, Bc = fit_candidates(agg, B)
    T = sp.csr_matrix(T)
    del agg
    dinv = 1.0 / S.diagonal()
    DS = spla.LinearOperator(S.shape, matvec=lambda v: dinv * (S @ np.ravel(v)), dtype=float)
    scale = OMEGA / approximate_spectral_radius(DS) * dinv
    parts = []
    for a, b in _row_blocks(n):
        U = csr_rows(S, a, b) @ T
        U.data *= np.repeat(scale[a:b], np.diff(U.indptr))
        parts.append(sp.csr_matrix(csr_rows(T, a, b) - U))
        del U
    del T
    P = sp.csr_matrix(sp.vstack(parts, format="csr"))
    del parts
    Ac = None
    for a, b in _row_blocks(n):
        Pr = csr_rows(P, a, b)
        term = Pr.T @ (csr_rows(S, a, b) @ P)
        Ac = term if Ac is None else Ac + term
        del term
    k = B.shape[1]
    Ac = sp.bsr_array(sp.csr_array(Ac), blocksize=(k, k))
    coarse = pyamg.smoothed_aggregation_solver(Ac, B=Bc, strength="symmetric", max_coarse=max_coarse,
                                               coarse_solver=coarse_solver)
    fine = MultilevelSolver.Level()
    fine.A, fine.B, fine.P, fine.R = S, B, P, P.T
    ml = MultilevelSolver([fine] + coarse.levels, coarse_solver=coarse_solver)
    change_smoothers(ml, SMOOTHER, SMOOTHER)
    return ml
