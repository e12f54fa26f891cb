"""Gmsh: a shared session helper and the reader of ``.msh`` files (versions 2.2 and 4.1).

Physical groups of the cell dimension d become cell regions; groups of dimension
d−1 whose elements are all boundary faces become named boundary parts, those whose
elements are all interior faces are fracture groups (returned by :func:`read_msh`).
"""

from __future__ import annotations

import dataclasses
import logging
import re
import time
from contextlib import contextmanager
from pathlib import Path
from types import MappingProxyType

import numpy as np

from ..core.errors import InputError, MeshError
from ..core.paths import not_a_file
from ..core.ragged import INDEX, frozen
from ..core.signals import rearm_signal_handlers
from .build import _void_keys, mesh_from_cells
from .mesh import Mesh

log = logging.getLogger("polypore")

# (dimension, number of corner nodes) -> meshio/build.py cell name; gmsh lists corner nodes first
_KINDS = {(2, 3): "triangle", (2, 4): "quad", (3, 4): "tetra", (3, 8): "hexahedron", (3, 6): "wedge",
          (3, 5): "pyramid"}


@contextmanager
def gmsh_session(options: dict | None = None, model: str = "polypore"):
    """Run gmsh on a fresh model, silent and single-threaded; always clean up.

    If gmsh is already initialised by a caller, its session is kept: a new model is
    added (and removed afterwards) and the options set here are restored.

    Parameters
    ----------
    options : mapping name -> number, optional
        Extra gmsh numeric options for this session.
    """
    import gmsh

    own = not gmsh.isInitialized()
    if own:
        # no config files and no signal handler: quiet, reproducible, usable off the main thread
        gmsh.initialize([], readConfigFiles=False, interruptible=False)
        rearm_signal_handlers()   # gmsh resets SIGTERM and SIGPIPE at C level (core/signals.py)
        previous_model = None
    else:
        previous_model = gmsh.model.getCurrent()
    opts = {"General.Terminal": 0, "General.NumThreads": 1, "Mesh.MaxNumThreads3D": 1}
    opts.update(options or {})
    saved = {}
    try:
        for name, value in opts.items():
            try:
                saved[name] = gmsh.option.getNumber(name)
            except Exception:  # an option this gmsh version does not have (e.g. Mesh.RandomSeed)
                continue
            gmsh.option.setNumber(name, value)
        gmsh.model.add(model)
        gmsh.logger.start()
        yield gmsh
    finally:
        try:
            gmsh.logger.stop()
        except Exception:  # pragma: no cover - only if the logger never started
            pass
        if own:
            gmsh.finalize()
            rearm_signal_handlers()
        else:
            gmsh.model.remove()
            if previous_model:
                gmsh.model.setCurrent(previous_model)
            for name, value in saved.items():
                gmsh.option.setNumber(name, value)


def gmsh_last_error(gmsh, exc: Exception) -> str:
    """The most useful text about a gmsh failure: its error/warning lines, else the exception."""
    try:
        lines = [m for m in gmsh.logger.get() if m.startswith(("Error", "Warning"))]
    except Exception:  # pragma: no cover
        lines = []
    msg = "; ".join(lines[-3:]) if lines else str(exc)
    return msg.replace("\n", " ").strip() or type(exc).__name__


def read_msh(path: str, isolate: bool = True) -> tuple[Mesh, dict]:
    """Read a Gmsh mesh file.

    2D meshes (triangles, quadrilaterals, all z = 0) get (n, 2) nodes; 3D meshes may
    mix tetrahedra, hexahedra, prisms and pyramids. Higher-order elements keep their
    corner nodes only.

    Parameters
    ----------
    path : str
        A ``.msh`` file, format 2.2 or 4.1.
    isolate : bool
        Open it with gmsh in a forked child process (:func:`_isolated`); False in a distributed
        run (MPI does not like forks).

    Returns
    -------
    mesh : Mesh
        Regions from the physical groups of dimension d (``default`` for cells in none),
        boundary parts from the physical groups of dimension d−1 on ∂Ω.
    fractures : dict name -> (k,) int32
        Sorted mesh face ids of every physical group of dimension d−1 made of interior faces.

    Raises
    ------
    InputError
        Field ``mesh.file``: missing or unreadable file, no supported cells, or a group
        mixing boundary and interior faces or containing elements that are no mesh faces.
    """
    p = Path(path)
    what = not_a_file(p)
    if what is not None:
        raise InputError("path", f"{str(p)!r} {what}; mesh.file takes a Gmsh .msh file")
    with open(p, "rb") as fh:
        head = fh.read(4096).lstrip()
    # gmsh would run any other text as a .geo script (which can call the shell): refuse it
    if not head.startswith(b"$MeshFormat"):
        raise InputError("path", f"{str(p)!r} is not a Gmsh mesh file: it must start with $MeshFormat "
                         "(formats 2.2 and 4.1, ASCII or binary)")
    _check_ascii_numbers(p, head)
    t0 = time.perf_counter()
    data = _isolated(_open, str(p)) if isolate else _open(str(p))
    mesh, groups = _build(str(p), *data)
    log.info("read %s: %d cells, %d fracture group(s) in %.2f s", p.name, mesh.n_cells, len(groups),
             time.perf_counter() - t0)
    return mesh, groups


# a number as the MSH format writes it; gmsh's C reader takes a prefix of anything else ("1e" is 1)
_NOT_A_NUMBER = re.compile(rb"(?<!\S)(?![-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?!\S))\S+")


def _check_ascii_numbers(p: Path, head: bytes) -> None:
    """InputError if the $Nodes or $Elements section of an ASCII file holds a token that is not a
    number: gmsh reads "1e" as 1 and "0.5x" as 0.5, a corrupted file silently read as another mesh."""
    fmt = head.split(b"\n", 2)[1].split() if head.count(b"\n") >= 2 else []
    if len(fmt) < 2 or fmt[1] != b"0":
        return                                        # binary (or malformed: gmsh says so)
    data = p.read_bytes()
    for name in (b"Nodes", b"Elements"):
        a = data.find(b"$" + name + b"\n")
        z = data.find(b"$End" + name, a + 1)
        if a < 0 or z < 0:
            continue
        a += len(name) + 2
        bad = _NOT_A_NUMBER.search(data, a, z)
        if bad:
            line = data.count(b"\n", 0, bad.start()) + 1
            token = bad.group(0)[:20].decode("ascii", "replace")
            raise InputError("path", f"{str(p)!r} line {line}: {token!r} in ${name.decode()} is not a number; "
                             "the nodes and elements of a Gmsh mesh file are numbers")


def _open(path: str):
    with gmsh_session() as gmsh:
        try:
            gmsh.open(path)
            return _extract(gmsh)
        except InputError:
            raise
        except Exception as exc:
            raise InputError("path", f"cannot read {path!r} as a Gmsh mesh (format 2.2 or 4.1): "
                             f"{gmsh_last_error(gmsh, exc)}") from None


def _isolated(fn, path: str):
    """``fn(path)`` in a forked child process: gmsh crashes (SIGSEGV) on some malformed files (an
    element whose type was changed, in a MSH 2.2 file), which would end polypore itself without a
    word; a crash of the child is an InputError naming the file. In-process where there is no fork
    (Windows)."""
    import os
    import pickle
    import signal

    if not hasattr(os, "fork"):
        return fn(path)
    from ..core.interruptible import stop_worker

    stop_worker()      # no thread that ran SuperLU may be torn down in the child (core/interruptible.py)
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:                                      # the child: never returns
        status = 0
        try:
            os.close(r)
            try:
                out = ("ok", fn(path))
            except InputError as exc:
                out = ("input", (exc.field, exc.detail))
            except BaseException as exc:              # reported by the parent, as it would be in-process
                out = ("error", (type(exc).__name__, str(exc)))
            with os.fdopen(w, "wb") as f:
                f.write(pickle.dumps(out, protocol=pickle.HIGHEST_PROTOCOL))
        except BaseException:
            status = 1
        finally:
            os._exit(status)
    os.close(w)
    try:
        with os.fdopen(r, "rb") as f:
            raw = f.read()
        _, status = os.waitpid(pid, 0)
    except BaseException:                             # interrupted (SIGINT, SIGTERM): the child goes too
        try:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
        except OSError:
            pass
        raise
    if os.WIFSIGNALED(status) or not raw:
        sig = os.WTERMSIG(status) if os.WIFSIGNALED(status) else None
        how = f"gmsh crashed on it ({signal.Signals(sig).name})" if sig else "its reader ended without a result"
        raise InputError("path", f"cannot read {path!r} as a Gmsh mesh (format 2.2 or 4.1): {how}; the file is "
                         "malformed")
    kind, value = pickle.loads(raw)
    if kind == "input":
        raise InputError(*value)
    if kind == "error":
        raise RuntimeError(f"reading {path!r} failed in its child process: {value[0]}: {value[1]}")
    return value


def _extract(gmsh):
    """Nodes, cell blocks (per entity) and physical groups of the open model."""
    tags, coords, _ = gmsh.model.mesh.getNodes()
    tags = np.asarray(tags, np.int64)
    X = np.asarray(coords, float).reshape(-1, 3)
    # elements per entity; keep (dim, kind, entity, conn as node tags)
    blocks = []
    for dim, ent in gmsh.model.getEntities():
        if dim == 0:
            continue
        types, _, nodes = gmsh.model.mesh.getElements(dim, ent)
        for t, nt in zip(types, nodes):
            name, edim, _, nn, _, nprim = gmsh.model.mesh.getElementProperties(t)
            conn = np.asarray(nt, np.int64).reshape(-1, nn)[:, :nprim]
            blocks.append((edim, nprim, name, ent, conn))
    groups = []
    for dim, tag in gmsh.model.getPhysicalGroups():
        name = gmsh.model.getPhysicalName(dim, tag) or f"{dim}:{tag}"
        ents = [int(e) for e in gmsh.model.getEntitiesForPhysicalGroup(dim, tag)]
        groups.append((dim, tag, name, ents))
    return tags, X, blocks, groups


def _build(path, tags, X, blocks, groups):
    cells3 = [b for b in blocks if b[0] == 3]
    cells2 = [b for b in blocks if b[0] == 2]
    if cells3:
        dim, cells, faces = 3, cells3, cells2
    elif cells2:
        dim, cells, faces = 2, cells2, [b for b in blocks if b[0] == 1]
    else:
        raise InputError("path", f"{path!r} has no 2D or 3D cells (found only "
                         f"{sorted({b[2] for b in blocks}) or 'no elements'}); supported: triangles, quadrangles, "
                         "tetrahedra, hexahedra, prisms, pyramids")
    bad = sorted({b[2] for b in cells if (dim, b[1]) not in _KINDS})
    if bad:
        raise InputError("path", f"{path!r} has unsupported {dim}D elements {bad}; supported: "
                         + ", ".join(k for (d, _), k in _KINDS.items() if d == dim))
    # node tags -> compact indices of the nodes that cells use
    lookup = np.full(int(tags.max(initial=0)) + 1, -1, np.int64)
    lookup[tags] = np.arange(tags.size)
    used = np.zeros(tags.size, bool)
    for b in cells:
        used[lookup[b[4]].ravel()] = True
    if dim == 2 and np.any(X[used, 2] != 0):
        raise InputError("path", f"{path!r} is a surface mesh that does not lie in the plane z = 0; "
                         "2D meshes must have z = 0 everywhere")
    new = np.cumsum(used) - 1
    nodes = X[used, :dim]

    def renum(conn):
        idx = lookup[conn]
        if np.any(idx < 0) or np.any(~used[idx]):
            return None
        return new[idx].astype(INDEX)

    # cell blocks by kind (mesh_from_cells numbers cells block after block)
    kinds = {}
    for b in cells:
        kinds.setdefault(_KINDS[(dim, b[1])], []).append(b)
    phys_cells = {}
    for gdim, tag, name, ents in groups:
        if gdim == dim:
            for e in ents:
                phys_cells.setdefault(e, name)  # an entity in two groups keeps the first
    region_names = list(dict.fromkeys(n for d, _, n, _ in groups if d == dim))  # in physical-tag order
    blocks_out, region = {}, []
    for kind, bl in kinds.items():
        conn = np.concatenate([renum(b[4]) for b in bl])
        ent = np.concatenate([np.full(len(b[4]), b[3], np.int64) for b in bl])
        # MSH 2 writes an element once per physical group it belongs to: keep the first copy
        _, first = np.unique(_void_keys(conn), return_index=True)
        first.sort()
        blocks_out[kind] = conn[first]
        region.append(ent[first])
    ent_of_cell = np.concatenate(region)
    names = list(region_names)
    if any(e not in phys_cells for e in np.unique(ent_of_cell)):
        names.append("default")
    index = {n: i for i, n in enumerate(names)}
    ents = np.unique(ent_of_cell)
    ent_region = np.array([index[phys_cells.get(int(e), "default")] for e in ents])
    cell_region = ent_region[np.searchsorted(ents, ent_of_cell)]
    try:
        mesh = mesh_from_cells(nodes, blocks_out, cell_region=cell_region, region_names=names)
    except MeshError as exc:
        raise MeshError("path", f"{path!r} is not a valid mesh: {exc}") from None

    # lower-dimensional groups: match their elements to mesh faces by node sets
    face_rows = {}
    for b in faces:
        face_rows.setdefault(b[3], []).append(b[4])
    fkeys = {}
    for m, ids, conn in mesh.face_nodes.groups():
        keys = _void_keys(conn)
        order = np.argsort(keys)
        fkeys[m] = (ids[order], keys[order])
    boundary, fractures = {}, {}
    for gdim, tag, name, gents in groups:
        if gdim != dim - 1:
            continue
        rows = [r for e in gents for r in face_rows.get(e, [])]
        if not rows:
            continue
        found = []
        for conn in rows:
            c = renum(conn)
            m = conn.shape[1]
            ok = c is not None and m in fkeys
            if ok:
                ids, keys = fkeys[m]
                want = _void_keys(c)
                pos = np.minimum(np.searchsorted(keys, want), len(keys) - 1)
                ok = bool(np.all(keys[pos] == want))
            if not ok:
                raise InputError("path", f"physical group {name!r} of {path!r} has elements that are not "
                                 f"faces of the {dim}D cells; a group of dimension {dim - 1} must consist of cell faces")
            found.append(ids[pos])
        f = np.unique(np.concatenate(found)).astype(INDEX)
        on_bdry = mesh.face_cells[f, 1] < 0
        if on_bdry.all():
            boundary[name] = frozen(f)
        elif not on_bdry.any():
            fractures[name] = f
        else:
            raise InputError("path", f"physical group {name!r} of {path!r} mixes {int(on_bdry.sum())} boundary "
                             f"and {int((~on_bdry).sum())} interior faces; a group must be either a boundary part "
                             "or a fracture (interior faces)")
    if boundary:
        # a group named like a box side (xmin, ...) replaces it: the file knows best
        names = dict(mesh.boundary)
        names.update(boundary)
        mesh = dataclasses.replace(mesh, boundary=MappingProxyType(names))
    return mesh, fractures
