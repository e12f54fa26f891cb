"""Errors of the lower layers in case-file terms (issue 27).

The mesh generators, discretisations and models raise :class:`~polypore.core.errors.InputError`
naming their own parameters (``tip_size``, ``friction``, ``fracture F1.vertices``); the case file
calls them ``mesh.tip_size``, ``contact.friction``, ``fractures.F1.vertices``. Each site of setup/
that builds a lower-layer object from the case wraps the call in :func:`case_keys`, so that the
command line names the key the user wrote. A field that names a file location (``a.grdecl:ZCORN``)
or a key already in case terms is left alone.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from contextlib import contextmanager

from ..core.errors import InputError


def under(table: str, names: Iterable[str]) -> dict[str, str]:
    """{name: "table.name"}: own parameter names that are keys of one case-file table."""
    return {n: f"{table}.{n}" for n in names}


def case_key(field: str, keys: Mapping[str, str]) -> str | None:
    """``field`` with its leading own-term name replaced by its case-file key, or None.

    A key matches the whole field or its head before ``.`` or ``[`` (not a file location such as
    ``cells.grdecl:ZCORN``); a key ending in a space (``"fracture "``) matches as a prefix
    (``"fracture F1.vertices"``). The longest key wins.
    """
    for own in sorted(keys, key=len, reverse=True):
        if field == own or field.startswith(own) and (
                own.endswith(" ") or field[len(own)] in ".[" and ":" not in field):
            return keys[own] + field[len(own):]
    return None


@contextmanager
def case_keys(keys: Mapping[str, str]):
    """Re-raise an InputError (or MeshError) whose field is an own-term name of ``keys`` with the
    case-file key instead: ``with case_keys({"tip_size": "mesh.tip_size"}): simplicial_mesh(...)``."""
    try:
        yield
    except InputError as exc:
        key = case_key(exc.field, keys)
        if key is None:
            raise
        raise type(exc)(key, exc.detail) from None


# own-term names of the lower layers -> case-file keys, one map per build site
MESH = {**under("mesh", ("lower", "upper", "size", "fracture_size", "tip_size", "tip_grading", "grading", "mirror",
                         "jitter", "rounds", "nodes", "faces", "cells")),
        "amplitude": "mesh.perturb", "front_mesh": "mesh.front", "gmsh": "mesh", "voronoi_mesh": "mesh.generator",
        "axes": "mesh.domain", "hi": "mesh.domain", "n": "mesh.cells", "cell_region": "mesh.regions",
        "parts": "boundaries", "path": "mesh.file", "fracture": "fractures", "fracture ": "fractures.",
        "refine": "mesh.refine"}
CORNERPOINT = {"regions": "mesh.region_keyword", "refine": "mesh.refine"}     # process_grid(regions=), refine_grid
_CONTACT = {**under("contact", ("law", "friction", "threshold", "dynamic_friction", "critical_slip", "beta",
                                "patch_ratio", "a", "b", "reference_rate", "initial_slip_rate", "state_law",
                                "stick_rate", "shear_wave_speed")),
            "start_from": "contact.initial_state_from"}
MECHANICS = {**under("mechanics", ("order", "bubble_stabilisation", "bubble_side", "nodal_stabilisation")),
             **_CONTACT, "beta_scale": "contact.beta", "displacement": "mechanics.boundary",
             "traction": "mechanics.boundary", "elastic": "material", "params": "parameters"}
FLOW = {**under("flow", ("biot_modulus", "biot_coefficient", "fracture_compressibility", "cell_point",
                         "normal_transmissivity_law", "conductivity_law", "boundary", "fracture_boundary",
                         "viscosity", "alpha", "fracture_alpha", "normal_permeability", "aperture", "cell_source",
                         "fracture_source", "initial_pressure", "permeability")),
        "cells": "mesh.cells", "network": "fractures", "params": "parameters", "dt": "time.dt"}
POROMECHANICS = {**MECHANICS, **FLOW, "predictor": "solver.predictor", "matrix_pressure": "mechanics.matrix_pressure",
                 "fracture_pressure": "mechanics.fracture_pressure",
                 **under("flow", ("dilatancy", "pressure_stabilisation"))}
# the solvers' own parameter names (solvers/factory.py, solvers/petsc.py)
SOLVER = {"backend": "solver.linear", "petsc_options": "solver.petsc"}
# what a run raises after its set-up (values of time-dependent expressions, the aperture laws, PETSc
# options PETSc did not use): the runs wrap their solve or march in these
RUN_MECHANICS = {**MECHANICS, **SOLVER}
RUN_FLOW = {**FLOW, **SOLVER}
RUN_POROMECHANICS = {**POROMECHANICS, **SOLVER}
