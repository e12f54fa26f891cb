"""Symmetric quadrature rules on the reference simplex, in barycentric coordinates.

Each rule is ``(L, w)``: points L (n_q, d + 1) (barycentric, rows sum to 1) and weights w
(n_q,) summing to 1, so that ∫_T f ≈ |T| Σ_q w_q f(Σ_i L_qi x_i) for a simplex T with
vertices x_i. All weights are positive.
"""

from __future__ import annotations

import numpy as np


def _orbit(*bary) -> np.ndarray:
    """Distinct permutations of one barycentric point."""
    from itertools import permutations

    return np.unique(np.array(list(permutations(bary)), float), axis=0)


def _rule(groups) -> tuple[np.ndarray, np.ndarray]:
    pts = [_orbit(*p) for p, _ in groups]
    L = np.vstack(pts)
    w = np.concatenate([np.full(len(p), wt) for p, (_, wt) in zip(pts, groups)])
    return L, w / w.sum()     # tabulated weights carry 15 digits: make them sum to 1 exactly


# segment, degree 5: 3-point Gauss
_g = np.sqrt(0.15)
SEGMENT_5 = (np.array([[0.5 + _g, 0.5 - _g], [0.5, 0.5], [0.5 - _g, 0.5 + _g]]), np.array([5.0, 8.0, 5.0]) / 18.0)

# triangle, degree 2: three interior points
TRIANGLE_2 = _rule([((2 / 3, 1 / 6, 1 / 6), 1 / 3)])

# triangle, degree 4: 6 points (Dunavant)
TRIANGLE_4 = _rule([((1 - 2 * 0.445948490915965, 0.445948490915965, 0.445948490915965), 0.223381589678011),
                    ((1 - 2 * 0.091576213509771, 0.091576213509771, 0.091576213509771), 0.109951743655322)])

# tetrahedron, degree 2: 4 points
_a = 0.1381966011250105
TETRA_2 = _rule([((1 - 3 * _a, _a, _a, _a), 0.25)])

# tetrahedron, degree 5: 14 points (Walkington), positive weights
_a1, _a2, _b = 0.0927352503108912264, 0.3108859192633006, 0.0455037041256496494
TETRA_5 = _rule([((1 - 3 * _a1, _a1, _a1, _a1), 0.0734930431163619495),
                 ((1 - 3 * _a2, _a2, _a2, _a2), 0.1126879257180158507),
                 ((0.5 - _b, 0.5 - _b, _b, _b), 0.0425460207770814664)])


def cell_rule(dim: int, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """A rule exact for polynomials of ``degree`` (≤ 5 in 3D, ≤ 4 in 2D) on a triangle / tetrahedron."""
    if dim == 2:
        return TRIANGLE_2 if degree <= 2 else TRIANGLE_4
    return TETRA_2 if degree <= 2 else TETRA_5


def face_rule(dim: int) -> tuple[np.ndarray, np.ndarray]:
    """A rule on a face of a d-simplex (segment or triangle), exact for degree 4 or more."""
    return SEGMENT_5 if dim == 2 else TRIANGLE_4
