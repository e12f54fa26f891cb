"""Names of the Newton Jacobian's blocks, in the order the models list their (row, col)
contributions to a :class:`~.pattern.BlockPattern` (whose ``take``/``add``/``put`` address a
block by that number).

The contact-mechanics Jacobian (`models/mechanics.py`) has the first four; the coupled one
(`models/poromechanics.py`) all nine, the pressure rows against the displacement columns also
as a pattern of their own (:class:`PressureRowBlock`) when the block solvers hold the Jacobian by
blocks.
"""

from __future__ import annotations

from enum import IntEnum


class Block(IntEnum):
    """Blocks of the assembled Newton Jacobian (rows × columns; u free displacements, λ scaled
    multipliers, p free pressures)."""

    ELASTIC = 0          # A: u × u
    MULTIPLIER = 1       # Bᵀ β: u × λ
    CONTACT_JUMP = 2     # C_u: λ × u, the contact rows' derivative with respect to the jumps
    CONTACT_MULTIPLIER = 3   # C_λ: λ × λ
    COUPLING = 4         # −G: u × p, the Biot coupling in the momentum balance
    BIOT = 5             # −Gᵀ: p × u, the Biot term in the mass balance
    FLOW = 6             # −Δt A_f: p × p
    DILATANCY = 7        # p × u, the fracture storage of the dilatant slip
    IMPLICIT_CONDUCTIVITY = 8    # p × u, the conductivities at the iterate's aperture


class PressureRowBlock(IntEnum):
    """Blocks of the pressure rows against the displacement columns (block solvers)."""

    BIOT = 0
    DILATANCY = 1
    IMPLICIT_CONDUCTIVITY = 2
