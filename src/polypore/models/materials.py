"""Elastic material data (plain frozen dataclasses, SI units)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.errors import InputError


@dataclass(frozen=True)
class Elastic:
    """Isotropic linear elasticity.

    Attributes
    ----------
    E : float, Young's modulus in Pa (> 0)
    nu : float, Poisson's ratio, in (−1, 0.5)
    """

    E: float
    nu: float

    def __post_init__(self):
        check_elastic(self.E, self.nu)

    @property
    def mu(self) -> float:
        """Shear modulus μ = E / (2(1 + ν)) in Pa."""
        return self.E / (2 * (1 + self.nu))

    @property
    def lam(self) -> float:
        """Lamé's first parameter λ_L = E ν / ((1 + ν)(1 − 2ν)) in Pa (3D and plane strain)."""
        return self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))

    @classmethod
    def from_lame(cls, mu: float, lam: float) -> "Elastic":
        if not mu > 0 or not lam > -2 * mu / 3:
            raise InputError("lam", f"need μ > 0 and λ > −2μ/3, got μ={mu!r}, λ={lam!r}")
        return cls(mu * (3 * lam + 2 * mu) / (lam + mu), lam / (2 * (lam + mu)))


def check_elastic(E, nu, field: str = "elastic") -> None:
    """InputError naming the field unless 0 < E < ∞ and −1 < ν < 1/2 (elementwise)."""
    E = np.asarray(E, float)
    nu = np.asarray(nu, float)
    bad = E[~((E > 0) & np.isfinite(E))].ravel()
    if bad.size:
        raise InputError(f"{field}.E", f"Young's modulus must be positive and finite (Pa), got {float(bad[0])!r}")
    bad = nu[~((nu > -1) & (nu < 0.5))].ravel()
    if bad.size:
        raise InputError(f"{field}.nu", f"Poisson's ratio must lie in (−1, 0.5), got {float(bad[0])!r}")


def lame(E: np.ndarray, nu: np.ndarray, field: str = "elastic") -> tuple[np.ndarray, np.ndarray]:
    """(μ, λ_L) in Pa from E (Pa) and ν, elementwise; InputError naming ``field.E`` or
    ``field.nu`` unless E > 0 and −1 < ν < 1/2 (outside, λ_L or μ would be ≤ 0 or infinite)."""
    check_elastic(E, nu, field)
    E = np.asarray(E, float)
    nu = np.asarray(nu, float)
    return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
