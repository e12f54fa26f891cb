"""From a poromechanics case to a :class:`~polypore.models.poromechanics.Poromechanics` model.

The case has the mechanics tables of :mod:`.mechanics` (``[material]``, ``[mechanics]``,
``[contact]``), the flow tables of :mod:`.flow` (``[flow]``), ``[time]`` (:mod:`.schedule`)
and optionally ``[initial_state]`` (:mod:`.insitu`) and ``[monitor]``; ``[mechanics] biot`` is
the Biot coefficient b of both equations.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..core.errors import InputError
from ..models.poromechanics import STABILISATION, Poromechanics
from .casefile import CaseFile
from .flow import flow_setup
from .insitu import reference_state
from .mechanics import mechanics_setup

def poro_setup(case: CaseFile, fm):
    """(Poromechanics model, flow setup, mechanics setup) for a case on the mesh ``fm``."""
    spec = case.spec
    if spec.flow is None:
        raise InputError("flow", "a poromechanics case needs flow data: a [flow] table (permeability, viscosity, "
                         "biot_modulus, aperture, normal_permeability, boundary conditions)")
    if spec.time is None:
        raise InputError("time", "a poromechanics case is transient: give [time] with end and step (s)")
    ms = mechanics_setup(case, fm)
    fs = flow_setup(case, fm)
    flow_data = dataclasses.replace(fs.data, biot_coefficient=ms.data.biot)
    ref = reference_state(case, fm)
    model = Poromechanics(fm, ms.data, flow_data, fs.boundary, fracture_boundary=fs.fracture_boundary,
                          cell_source=fs.cell_source, fracture_source=fs.fracture_source, alpha=fs.alpha,
                          fracture_alpha=fs.fracture_alpha, solver=ms.solver,
                          newton=dataclasses.replace(ms.newton, label="poromechanics Newton", stall_iterations=12),
                          initial_traction=None if ref is None else ref.traction(fm),
                          dilatancy=fs.info.get("tan_psi", 0.0),
                          pressure_stabilisation=STABILISATION if fs.info.get("pressure_stabilisation") is None
                          else fs.info["pressure_stabilisation"])
    model.reference = ref
    return model, fs, ms


def monitor_points(case: CaseFile, mesh) -> dict:
    """``[monitor] points = {name = [x, y(, z)]}``: name -> the cell whose centroid is nearest."""
    mon = case.spec.monitor
    if mon is None:
        return {}
    out = {}
    c = mesh.geometry.cell_centroid
    lo, hi = mesh.bounding_box
    for name, x in mon.points.items():
        f = f"monitor.points.{name}"
        if len(x) != mesh.dim:
            raise InputError(f, f"must be {mesh.dim} coordinates (m), got {x}")
        x = np.asarray(x)
        if np.any(x < lo - 1e-9 * np.abs(hi - lo)) or np.any(x > hi + 1e-9 * np.abs(hi - lo)):
            raise InputError(f, f"lies outside the domain {lo.tolist()} – {hi.tolist()}")
        out[name] = int(np.argmin(np.linalg.norm(c - x, axis=1)))
    return out
