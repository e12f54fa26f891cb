"""The mesh generators a case file can name, in one registry.

Each entry says which ``[mesh]`` keys the generator reads (the schema refuses the others), which
function of `setup/` builds its mesh and which estimates its cell count before it is built
(`limits.py`: the size check and the automatic solver choice). A new generator is an entry here
and its two functions; `tests/unit/setup/test_generators_registry.py` checks that every entry resolves, so
a generator without an estimate is an error, not a silent NaN.

The functions are named, not imported, so that the schema can read the keys without loading the
mesh generators (gmsh among them).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

_BOX = frozenset({"lower", "upper", "seed", "perturb"})
_CORNERPOINT = frozenset({"nonplanar", "region_keyword", "snap", "refine"})


@dataclass(frozen=True)
class Generator:
    """One mesh generator.

    Attributes
    ----------
    keys : the ``[mesh]`` keys it reads (besides ``generator``)
    build : "module:function" in `polypore.setup`; box generators: ``f(mesh_table, lower, upper,
        fracture_specs, interfaces) -> Mesh``, the others ``f(case, spec, t0) -> FracturedMesh``
    estimate : "module:function" in `polypore.setup`: ``f(spec) -> (cells, the field that sets them)``
    box : meshes the box [lower, upper] around the case's fractures (else the grid or file is
        the geometry)
    """

    keys: frozenset
    build: str
    estimate: str
    box: bool = True


REGISTRY = {
    "cartesian": Generator(_BOX | {"cells", "size"}, "meshing:build_cartesian", "limits:cells_cartesian"),
    "simplicial": Generator(_BOX | {"size", "fracture_size", "grading", "tip_size", "tip_grading", "mirror", "front"},
                            "meshing:build_simplicial", "limits:cells_simplicial"),
    "voronoi": Generator(_BOX | {"size"}, "meshing:build_voronoi", "limits:cells_voronoi"),
    "agglomerated": Generator(_BOX | {"size", "fracture_size", "grading", "rounds"}, "meshing:build_agglomerated",
                              "limits:cells_agglomerated"),
    "file": Generator(frozenset({"file"}), "meshing:build_file", "limits:cells_file", box=False),
    "grdecl": Generator(frozenset({"file"}) | _CORNERPOINT, "meshing:build_cornerpoint", "limits:cells_grdecl",
                        box=False),
    "cornerpoint": Generator(frozenset({"cells", "extent", "top", "dip", "faults", "pinchout", "pillar_angle",
                                        "inactive", "seed", "layer_permeability"}) | _CORNERPOINT,
                             "meshing:build_cornerpoint", "limits:cells_cornerpoint", box=False),
}


def resolve(ref: str):
    """The function ``"module:function"`` of `polypore.setup`."""
    module, name = ref.split(":")
    return getattr(importlib.import_module(f"polypore.setup.{module}"), name)
