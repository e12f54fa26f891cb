"""The checks ``polypore run`` makes of a case against its mesh, for ``polypore mesh`` too.

Names a case refers to (boundary parts, regions, wells, monitor points) can only be checked once
the mesh exists: a Gmsh file or a corner-point grid defines them. ``polypore run`` checks them
when it sets up the model; ``polypore mesh`` used to skip that set-up and wrote a mesh for a case
whose ``[[mechanics.boundary]] name = "ymaxx"`` the run then refused (issue 25). Tables a run
needs but a mesh does not (``[material]``) stay optional here: ``polypore mesh`` accepts a case
with only its geometry.
"""

from __future__ import annotations

from ..core.errors import InputError
from .casefile import CaseFile


def check_case_on_mesh(case: CaseFile, fm) -> None:
    """Run the set-up checks of ``polypore run`` that the case's tables allow on the mesh ``fm``
    (InputError naming the field, as the run would): the mechanics set-up when a material is
    given (else the ``[[mechanics.boundary]]`` names), the flow set-up when ``[flow]`` is given,
    ``[initial_state]`` and ``[monitor]`` of a poromechanics case. Nothing is kept."""
    from .flow import flow_setup
    from .insitu import reference_state
    from .mechanics import mechanics_setup
    from .poromechanics import monitor_points

    spec = case.spec
    physics = spec.physics
    mesh = fm.mesh
    if physics != "flow":
        if spec.material is not None or spec.materials:
            mechanics_setup(case, fm)
        elif spec.mechanics is not None:
            for b in spec.mechanics.boundary:
                if b.name not in mesh.boundary:
                    raise InputError(f"mechanics.boundary.{b.name}.name", f"unknown boundary {b.name!r}; this "
                                     f"mesh has {', '.join(sorted(mesh.boundary))}")
    if physics != "mechanics" and spec.flow is not None:
        flow_setup(case, fm)
    if physics == "poromechanics":
        reference_state(case, fm)
        monitor_points(case, mesh)
