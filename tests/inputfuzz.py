"""Fuzzing of everything a user hands polypore besides the case's values (issue 25): GRDECL files,
Gmsh ``.msh`` files, the TOML text of a case file itself, and the file system around a run
(tests/unit/setup/test_fuzz_inputs.py, benchmarks/fuzz_inputs.py; the case-file value mutations are
tests/casefuzz.py).

Every example carries its verdict: ``refuse`` (the input is broken: the only right outcome is an
input error, exit 2, or for a failed write exit 1), ``accept`` (the input is valid and must set
up) or ``either`` (a plausible change). An example is run with a hang detector (:func:`guard`)
and judged (:func:`judge`):

* traceback: any exception other than :class:`~polypore.core.errors.InputError` (in-process
  ``polypore.cli.main``: an exception out of it, or "Traceback" on stderr);
* hang: longer than :data:`HANG_SECONDS`;
* silent acceptance: a ``refuse`` example that set up (or exited 0);
* false refusal: an ``accept`` example that was refused;
* bad message: an error naming no field of the case or file, over :data:`MAX_MESSAGE` characters,
  or quoting :data:`CANARY` (a text planted in a file: messages quote no file contents).
"""

from __future__ import annotations

import builtins
import contextlib
import errno
import faulthandler
import io
import math
import os
import re
import shutil
import signal
import stat
import sys
import tempfile
import time
from dataclasses import dataclass
from dataclasses import field as dc_field
from functools import lru_cache
from pathlib import Path
from typing import Callable

from hypothesis import strategies as st

from polypore.core.errors import InputError

HANG_SECONDS = 60.0
MAX_MESSAGE = 4000
CANARY = "CANARYSECRET"
GRDECL_DIR = Path("/work/shared/data/grdecl")
SHARED_GRIDS = ("twocell.grdecl", "sixcells2_described_zsep.grdecl", "sixcells2_described_zoverlap.grdecl",
                "sixcells_lefthanded_hdr1.grdecl", "banal6.grdecl", "simpleb8.grdecl", "concave.grdecl",
                "dual_distorted1.grdecl")
FAMILIES = ("case", "grdecl", "msh", "toml", "fs")


# -- examples, outcomes, verdicts --------------------------------------------------------------------
@dataclass
class Result:
    kind: str                      # "ok", "input" (exit 2 / InputError), "failed" (exit 1)
    field: str | None = None
    message: str = ""
    problems: list = dc_field(default_factory=list)   # extra findings of the example itself (fs: folder state)
    named: bool = False            # the field was checked by the family itself (casefuzz.names_a_field)


@dataclass
class Example:
    family: str
    what: str                       # what was done (for reports)
    expect: str                     # "refuse", "accept" or "either"
    run: Callable[[Path], Result]   # run in a fresh temporary folder
    files: tuple = ()               # names an error's field may start with (the example's files)


class Hang(BaseException):
    """Raised by the hang detector's SIGALRM handler (a BaseException: nothing swallows it)."""


@contextlib.contextmanager
def guard(seconds: float | None = None):
    """Raise :class:`Hang` in the main thread after ``seconds``; faulthandler dumps every thread's
    stack and ends the process if even that does not get through (a hang in native code)."""
    seconds = HANG_SECONDS if seconds is None else seconds

    def alarm(signum, frame):
        raise Hang(f"no result after {seconds:.0f} s")

    old = signal.signal(signal.SIGALRM, alarm)
    faulthandler.dump_traceback_later(seconds * 1.5 + 30, exit=True)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        faulthandler.cancel_dump_traceback_later()
        signal.signal(signal.SIGALRM, old)


@dataclass
class Verdict:
    outcome: str                    # ok / input / failed / traceback / hang
    seconds: float
    problems: list                  # "silent acceptance", "false refusal", "bad message: ..."
    detail: str = ""


def case_field(field: str | None) -> bool:
    from casefuzz import FIELD_HEADS

    head = (field or "").split(".")[0].split("[")[0]
    # a key of the case, an option, or the case argument itself
    return bool(field) and (head in FIELD_HEADS or head in ("case", "RUN_DIR") or field.startswith("--"))


def run_example(ex: Example, root: Path | None = None) -> Verdict:
    """Run one example in a fresh folder under the hang detector and judge it."""
    import traceback

    tmp = Path(tempfile.mkdtemp(prefix=f"fz-{ex.family}-", dir=root))
    t0 = time.perf_counter()
    try:
        with guard():
            res = ex.run(tmp)
    except Hang as exc:
        return Verdict("hang", time.perf_counter() - t0, ["hang"], str(exc))
    except Exception:
        return Verdict("traceback", time.perf_counter() - t0, ["traceback"], traceback.format_exc())
    finally:
        dt = time.perf_counter() - t0
        _rmtree(tmp)
    return judge(ex, res, dt)


def _rmtree(tmp: Path) -> None:
    for p in tmp.rglob("*"):        # FIFOs and symlink loops are removed like files
        try:
            if p.is_symlink() or not p.is_dir():
                p.unlink()
        except OSError:
            pass
    shutil.rmtree(tmp, ignore_errors=True)


def judge(ex: Example, res: Result, seconds: float) -> Verdict:
    problems = [p for p in res.problems if p != "no-fault"]
    expect = "accept" if "no-fault" in res.problems else ex.expect    # the fault was never injected
    if expect == "refuse" and res.kind == "ok":
        problems.append("silent acceptance")
    if expect == "accept" and res.kind != "ok":
        problems.append("false refusal")
    if res.kind != "ok":
        if len(res.message) > MAX_MESSAGE:
            problems.append(f"bad message: {len(res.message)} characters")
        if CANARY in res.message:
            problems.append("bad message: quotes the file's contents")
        f = res.field
        named = res.named or case_field(f) or (f and any(f.startswith(n) for n in ex.files))
        if res.kind == "input" and not named:
            problems.append(f"bad message: field {f!r} names nothing")
    return Verdict(res.kind, seconds, problems, f"{res.field}: {res.message[:300]}" if res.kind != "ok" else "")


# -- set-up of a case file (no mesh cache: the files change under the same names) -----------------------
def set_up_file(case_path: Path) -> Result:
    """Load the case file at ``case_path`` and set it up (casefuzz.set_up without its mesh cache)."""
    import casefuzz
    from polypore.setup.casefile import load_case
    from polypore.setup.meshing import build_fractured_mesh

    try:
        case = load_case(str(case_path))
        saved = casefuzz._mesh
        casefuzz._mesh = build_fractured_mesh
        try:
            casefuzz.set_up(case)
        finally:
            casefuzz._mesh = saved
    except InputError as exc:
        return Result("input", exc.field, str(exc))
    return Result("ok")


# -- 1. GRDECL -----------------------------------------------------------------------------------
GRDECL_CASE = """name = "fz"
[mesh]
generator = "grdecl"
file = "{file}"
[material]
E = 1.0e10
nu = 0.25
[[mechanics.boundary]]
name = "bottom"
u = [0, 0, 0]
"""
BAD_NUMBERS = ["nan", "NaN", "inf", "-inf", "1e999", "-1e999", "abc", "-3*2", "0*1", "1e12*0.2", "1..2", "0x10",
               "1,5", "2*", "*", "'7'", "1e", "--", "1e300", "-1e300", "+Inf", "3*nan", CANARY]


@lru_cache(maxsize=None)
def grdecl_bases() -> dict:
    """name -> GRDECL text (comments removed): the small shared grids and a faulted grid written by
    polypore's own writer."""
    from polypore.mesh.cornerpoint import FaultSpec, generate_grid, write_grdecl
    from polypore.mesh.cornerpoint.reader import _strip_comments

    out = {}
    for name in SHARED_GRIDS:
        if (GRDECL_DIR / name).is_file():
            out[name] = _strip_comments((GRDECL_DIR / name).read_text())
    g = generate_grid(4, 3, 2, extent=(400.0, 300.0, 20.0), top=1000.0, faults=[FaultSpec("i", 2, 5.0, name="F1")],
                      properties=False)
    with tempfile.TemporaryDirectory() as d:
        out["faulted.grdecl"] = _strip_comments(write_grdecl(g, Path(d) / "f.grdecl").read_text())
    return out


_KW = re.compile(r"^[ \t]*([A-Za-z][A-Za-z0-9_+\-]{0,7})[ \t]*\r?$", re.M)


def blocks(text: str) -> dict:
    """keyword -> (start of the keyword, start of its data, position of its '/') for the data keywords."""
    out = {}
    for m in _KW.finditer(text):
        kw = m.group(1).upper()
        if kw in ("ECHO", "NOECHO") or kw in out:
            continue
        s = text.find("/", m.end())
        if s >= 0:
            out[kw] = (m.start(), m.end(), s)
    return out


def dims_of(text: str) -> tuple:
    b = blocks(text)
    kw = "SPECGRID" if "SPECGRID" in b else "DIMENS"
    return tuple(int(t) for t in text[b[kw][1]:b[kw][2]].split()[:3])


def _tokens(text, b, kw):
    """(start, end) of every value token of keyword ``kw``."""
    s, e = b[kw][1], b[kw][2]
    return [(s + m.start(), s + m.end()) for m in re.finditer(r"\S+", text[s:e])]


GRDECL_KINDS = ("truncate", "bad_value", "actnum", "dims", "missing", "duplicate", "no_slash", "bytes", "include",
                "include_ok", "inverted", "flat", "inactive", "faults", "nudge", "canary", "valid")


@st.composite
def grdecl_examples(draw, kinds=None):
    name = draw(st.sampled_from(sorted(grdecl_bases())))
    text = grdecl_bases()[name]
    b = blocks(text)
    nx, ny, nz = dims_of(text)
    extra = {}                     # other files: name -> text or a special kind
    fractures = ""
    kind = draw(st.sampled_from(kinds or GRDECL_KINDS))
    expect = "refuse"
    geometry = [k for k in ("COORD", "ZCORN", "ACTNUM") if k in b]
    if kind == "truncate":
        kw = draw(st.sampled_from(geometry))
        toks = _tokens(text, b, kw)
        n = draw(st.integers(1, min(len(toks), 12)))
        a = draw(st.integers(0, len(toks) - n))
        text = text[:toks[a][0]] + text[toks[a + n - 1][1]:]
        what = f"{kw}: {n} value(s) dropped at {a}"
    elif kind == "bad_value":
        kw = draw(st.sampled_from(geometry))
        toks = _tokens(text, b, kw)
        a, z = draw(st.sampled_from(toks))
        bad = draw(st.sampled_from(BAD_NUMBERS))
        text = text[:a] + bad + text[z:]
        what = f"{kw}: value {text[a:a + len(bad)]!r} in place of a number"
    elif kind == "actnum":
        bad = draw(st.sampled_from(["2", "-1", "0.5", "1e10", "1.0000001", "3*2", "-0.0001"]))
        vals = ["1"] * (nx * ny * nz)
        vals[draw(st.integers(0, len(vals) - 1))] = bad
        if bad == "3*2" and len(vals) >= 3:
            vals = vals[:-2]
        if "ACTNUM" in b:
            a, s, e = b["ACTNUM"]
            text = text[:s] + "\n" + " ".join(vals) + "\n" + text[e:]
        else:
            text += "\nACTNUM\n" + " ".join(vals) + "\n/\n"
        what = f"ACTNUM with a value {bad}"
    elif kind == "dims":
        kw = "SPECGRID" if "SPECGRID" in b else "DIMENS"
        toks = _tokens(text, b, kw)
        i = draw(st.integers(0, 2))
        v = draw(st.sampled_from([str(dims_of(text)[i] + 1), str(max(dims_of(text)[i] - 1, 0)), "0", "-1",
                                  "1000000000", "10**3", "abc", "2.5", str(10**30)]))
        a, z = toks[i]
        text = text[:a] + v + text[z:]
        what = f"{kw}: dimension {i + 1} = {v}"
    elif kind == "missing":
        kw = draw(st.sampled_from([k for k in ("COORD", "ZCORN", "SPECGRID") if k in b]))
        a, s, e = b[kw]
        text = text[:a] + text[e + 1:]
        what = f"{kw} removed"
    elif kind == "duplicate":
        kw = draw(st.sampled_from(sorted(b)))
        a, s, e = b[kw]
        text = text[:e + 1] + "\n" + text[a:e + 1] + text[e + 1:]
        what = f"{kw} twice (the same data)"
        expect = "either"
    elif kind == "no_slash":
        kw = draw(st.sampled_from([k for k in ("COORD", "ZCORN", "ACTNUM", "SPECGRID") if k in b]))
        e = b[kw][2]
        text = text[:e] + " " + text[e + 1:]
        what = f"{kw}: terminating '/' removed"
    elif kind == "bytes":
        raw = bytearray(text.encode())
        ins = draw(st.sampled_from([b"\x00", b"\xff\xfe", b"\xc3\x28", b"\x80", bytes([draw(st.integers(0, 255))]),
                                    b"\x00" * 100, b"\r", b"\t"]))
        at = draw(st.integers(0, len(raw)))
        raw[at:at] = ins
        extra["__raw__"] = bytes(raw)
        what = f"bytes {bytes(ins[:4])!r} inserted at {at}"
        expect = "either"
    elif kind == "include":
        target = draw(st.sampled_from(["missing", "self", "directory", "/dev/zero", "fifo", "loop", "empty",
                                       "garbage", "/proc/self/mem", "/etc/shadow"]))
        inc = {"missing": "nope.grdecl", "self": "grid.grdecl", "directory": "sub", "/dev/zero": "/dev/zero",
               "fifo": "pipe.grdecl", "loop": "loop.grdecl", "empty": "empty.grdecl", "garbage": "junk.grdecl",
               "/proc/self/mem": "/proc/self/mem", "/etc/shadow": "/etc/shadow"}[target]
        extra.update({"sub": "dir", "pipe.grdecl": "fifo", "loop.grdecl": "symlinkloop", "empty.grdecl": "",
                      "junk.grdecl": f"{CANARY} some words\n"})
        at = draw(st.sampled_from([0, b["COORD"][0]]))
        text = text[:at] + f"\nINCLUDE\n '{inc}' /\n\n" + text[at:]
        what = f"INCLUDE of {target}"
        expect = "either" if target == "empty" else "refuse"
    elif kind == "include_ok":
        kw = draw(st.sampled_from(geometry))
        a, s, e = b[kw]
        extra["part.grdecl"] = text[a:e + 1] + "\n"
        text = text[:a] + "INCLUDE\n 'part.grdecl' /\n" + text[e + 1:]
        what = f"{kw} moved to an INCLUDE file"
        expect = "accept"
    elif kind in ("inverted", "flat"):
        toks = _tokens(text, b, "ZCORN")
        vals = [text[a:z] for a, z in toks]
        if "*" in " ".join(vals):
            kind = "flat"
        if kind == "flat":
            new = [vals[0].split("*")[-1]] * (8 * nx * ny * nz)
            what = "ZCORN: every corner at one depth (zero thickness)"
        else:
            import numpy as np
            z = np.array([float(v) for v in vals]).reshape(2 * nz, 2 * ny * 2 * nx)
            new = [repr(float(v)) for v in z[::-1].ravel()]        # bottoms above tops
            what = "ZCORN: layers upside down (negative thickness)"
        text = text[:b["ZCORN"][1]] + "\n" + " ".join(new) + "\n" + text[b["ZCORN"][2]:]
    elif kind == "inactive":
        vals = f"{nx * ny * nz}*0"
        if "ACTNUM" in b:
            text = text[:b["ACTNUM"][1]] + "\n" + vals + "\n" + text[b["ACTNUM"][2]:]
        else:
            text += f"\nACTNUM\n{vals}\n/\n"
        what = "ACTNUM: every cell inactive"
    elif kind == "faults":
        rng = [1, nx, 1, ny, 1, nz]
        sub = draw(st.sampled_from(["out", "zero", "order", "face", "items", "ints"]))
        face = "X"
        if sub == "out":
            i = draw(st.integers(0, 5))
            rng[i] = [nx, nx, ny, ny, nz, nz][i] + draw(st.integers(1, 10**6))
        elif sub == "zero":
            rng[draw(st.integers(0, 5))] = draw(st.sampled_from([0, -1]))
        elif sub == "order":
            i = 2 * draw(st.integers(0, 2))
            hi = [nx, ny, nz][i // 2]
            if hi == 1:
                rng[i], rng[i + 1] = 2, 1
            else:
                rng[i], rng[i + 1] = hi, 1
        elif sub == "face":
            face = draw(st.sampled_from(["Q", "XY", "", "1"]))
        rec = " ".join(str(v) for v in rng)
        if sub == "items":
            rec = rec + " 7"
        if sub == "ints":
            rec = rec.replace(" 1", " 1.5", 1)
        recline = f"'FX' {rec} '{face}' /"
        if "FAULTS" in b:
            a = b["FAULTS"][1]
            text = text[:a] + "\n" + recline + text[a:]
        else:
            text += f"\nFAULTS\n{recline}\n/\n"
        what = f"FAULTS record {sub}: {recline}"
    elif kind == "nudge":
        kw = draw(st.sampled_from([k for k in ("COORD", "ZCORN") if k in b]))
        toks = [t for t in _tokens(text, b, kw) if "*" not in text[t[0]:t[1]]]
        a, z = draw(st.sampled_from(toks))
        f = draw(st.sampled_from([1 + 1e-9, 1 - 1e-9, 1.001, 0.999, 1.1, 0.9, 2.0, 0.0, -1.0]))
        new = repr(float(text[a:z]) * f)
        text = text[:a] + new + text[z:]
        what = f"{kw}: a value times {f}"
        expect = "either"
    elif kind == "canary":
        at = draw(st.sampled_from([0, b["COORD"][1], b["ZCORN"][2], len(text)]))
        text = text[:at] + f"\n{CANARY} the rest of a line\n" + text[at:]
        what = "a line of text in the file"
    else:
        what = "unchanged"
        expect = "accept"
    if name == "faulted.grdecl" and draw(st.booleans()):
        fractures = '\n[[fractures]]\nname = "F1"\nfriction = 0.6\n'
    raw = extra.pop("__raw__", None)

    def run(tmp: Path) -> Result:
        (tmp / "grid.grdecl").write_bytes(raw if raw is not None else text.encode())
        for fname, content in extra.items():
            p = tmp / fname
            if content == "dir":
                p.mkdir()
            elif content == "fifo":
                os.mkfifo(p)
            elif content == "symlinkloop":
                p.symlink_to(p)
            else:
                p.write_text(content)
        (tmp / "case.toml").write_text(GRDECL_CASE.format(file="grid.grdecl") + fractures)
        return set_up_file(tmp / "case.toml")

    files = ("grid.grdecl", "part.grdecl", "nope.grdecl", "sub", "pipe.grdecl", "loop.grdecl", "empty.grdecl",
             "junk.grdecl", "shadow", "/")
    return Example("grdecl", f"{name}: {what}", expect, run, files)


# -- 2. Gmsh .msh ----------------------------------------------------------------------------------
MSH_CASE_2D = """name = "fz"
[mesh]
generator = "file"
file = "m.msh"
[[fractures]]
name = "F"
group = "frac"
[material]
E = 1.0e9
nu = 0.25
[[mechanics.boundary]]
name = "bottom"
u = [0.0, 0.0]
[[mechanics.boundary]]
name = "top"
u = [0.0, -0.001]
[contact]
friction = 0.5
"""
MSH_CASE_3D = MSH_CASE_2D.replace("[0.0, 0.0]", "[0.0, 0.0, 0.0]").replace("[0.0, -0.001]", "[0.0, 0.0, -0.001]")


def _write_msh(path: Path, dim: int, version: float, binary: bool) -> None:
    import gmsh

    gmsh.initialize([], readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        occ = gmsh.model.occ
        if dim == 2:
            body = occ.addRectangle(0, 0, 0, 1, 1)
            frac = occ.addLine(occ.addPoint(0.2, 0.5, 0), occ.addPoint(0.8, 0.5, 0))
        else:
            body = occ.addBox(0, 0, 0, 1, 1, 1)
            frac = occ.addRectangle(0.2, 0.2, 0.5, 0.6, 0.6)
        _, omap = occ.fragment([(dim, body)], [(dim - 1, frac)])
        occ.synchronize()
        gmsh.model.addPhysicalGroup(dim, [t for _, t in gmsh.model.getEntities(dim)], name="rock")
        gmsh.model.addPhysicalGroup(dim - 1, [t for _, t in omap[1]], name="frac")
        import numpy as np
        for side, coord in (("bottom", 0.0), ("top", 1.0)):
            tags = [t for d, t in gmsh.model.getEntities(dim - 1)
                    if np.allclose(np.reshape(gmsh.model.getBoundingBox(d, t), (2, 3))[:, dim - 1], coord, atol=1e-6)]
            gmsh.model.addPhysicalGroup(dim - 1, tags, name=side)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.34 if dim == 2 else 0.5)
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.option.setNumber("Mesh.Binary", int(binary))
        gmsh.model.mesh.generate(dim)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
        from polypore.core.signals import rearm_signal_handlers
        rearm_signal_handlers()


@lru_cache(maxsize=None)
def msh_bases() -> dict:
    """name -> (bytes, dim): small Gmsh meshes, ASCII 2.2 and 4.1, binary 4.1."""
    out = {}
    with tempfile.TemporaryDirectory() as d:
        for dim, version, binary in ((2, 4.1, False), (2, 2.2, False), (3, 4.1, False), (2, 4.1, True)):
            name = f"{dim}d-v{version}{'-bin' if binary else ''}.msh"
            _write_msh(Path(d) / name, dim, version, binary)
            out[name] = ((Path(d) / name).read_bytes(), dim)
    return out


def _section(text: str, name: str) -> tuple[int, int]:
    a = text.index(f"${name}\n") + len(name) + 2
    return a, text.index(f"$End{name}", a)


MSH_ASCII_KINDS = ("truncate", "number", "nan", "missing_node", "degenerate", "element_type", "header", "garbage",
                   "empty", "no_header", "canary", "valid")
MSH_BINARY_KINDS = ("truncate", "header", "garbage", "empty", "valid", "flip")
MSH_KINDS = tuple(dict.fromkeys(MSH_ASCII_KINDS + MSH_BINARY_KINDS))


@st.composite
def msh_examples(draw, kinds=None):
    kind = draw(st.sampled_from(kinds or MSH_KINDS))
    names = [n for n in sorted(msh_bases()) if kind in (MSH_BINARY_KINDS if "-bin" in n else MSH_ASCII_KINDS)]
    name = draw(st.sampled_from(names))
    raw, dim = msh_bases()[name]
    ascii_ = "-bin" not in name
    v2 = "v2.2" in name
    expect = "refuse"
    text = raw.decode("latin-1")
    if kind == "truncate":
        at = draw(st.integers(0, len(raw) - 1))
        what = f"truncated at byte {at} of {len(raw)}"
        raw = raw[:at]
        expect = "either"     # a cut in the last section's end tag may still read
        if at < text.index("$EndElements"):
            expect = "refuse"
    elif kind == "flip":
        at = draw(st.integers(0, len(raw) - 1))
        raw = raw[:at] + bytes([raw[at] ^ (1 << draw(st.integers(0, 7)))]) + raw[at + 1:]
        what = f"binary: a bit flipped at byte {at}"
        expect = "either"
    elif kind in ("number", "nan"):
        a, z = _section(text, "Nodes")
        lines = text[a:z].split("\n")
        # node lines: 3 coordinates (v4: lines of x y z; v2: tag x y z)
        cand = [i for i, ln in enumerate(lines) if len(ln.split()) == (4 if v2 else 3)]
        i = draw(st.sampled_from(cand))
        parts = lines[i].split()
        j = draw(st.integers(1 if v2 else 0, len(parts) - 1))
        if kind == "nan":
            parts[j] = draw(st.sampled_from(["nan", "inf", "-inf", "1e999", "NaN"]))
            what = f"node coordinate {parts[j]}"
        else:
            parts[j] = draw(st.sampled_from(["abc", "1..2", "0x1p3", "", "1e", "--1", "0.5x", "1e+", "NaNx"]))
            what = f"node coordinate {parts[j]!r}"
            expect = "either" if parts[j] == "0x1p3" else "refuse"
        lines[i] = " ".join(parts)
        raw = (text[:a] + "\n".join(lines) + text[z:]).encode("latin-1")
    elif kind in ("missing_node", "degenerate"):
        a, z = _section(text, "Elements")
        lines = text[a:z].split("\n")
        # element lines of the cells: v2 "tag type ntags tags... nodes"; v4 "tag nodes..." inside a block
        if v2:
            cand = [i for i, ln in enumerate(lines) if len(ln.split()) >= 6 and
                    ln.split()[1] in (("2", "3") if dim == 2 else ("4", "5"))]
        else:
            cand = [i for i, ln in enumerate(lines) if len(ln.split()) == (4 if dim == 2 else 5)
                    and i > 0 and len(lines[i - 1].split()) in (4, 5)]
            cand = [i for i in cand if _v4_block_dim(lines, i) == dim]
        i = draw(st.sampled_from(cand))
        parts = lines[i].split()
        nodes = list(range(len(parts) - dim - 1, len(parts)))
        if kind == "missing_node":
            parts[draw(st.sampled_from(nodes))] = str(draw(st.sampled_from([10**6, 0, 2**31 + 5, -1])))
            what = f"cell {parts[0]} refers to node {parts[nodes[0]]}.."
        else:
            k1, k2 = draw(st.sampled_from([(p, q) for p in nodes for q in nodes if p < q]))
            parts[k2] = parts[k1]
            what = f"cell {parts[0]} with a repeated node"
        lines[i] = " ".join(parts)
        raw = (text[:a] + "\n".join(lines) + text[z:]).encode("latin-1")
    elif kind == "element_type":
        a, z = _section(text, "Elements")
        lines = text[a:z].split("\n")
        if v2:
            cand = [i for i, ln in enumerate(lines) if len(ln.split()) >= 6]
            i = draw(st.sampled_from(cand))
            parts = lines[i].split()
            parts[1] = str(draw(st.sampled_from([99, 0, 15, 7, -2])))
        else:
            cand = [i for i, ln in enumerate(lines) if len(ln.split()) == 4 and _v4_is_block_header(lines, i)]
            i = draw(st.sampled_from(cand))
            parts = lines[i].split()
            parts[2] = str(draw(st.sampled_from([99, 0, 15, 7, -2])))
        lines[i] = " ".join(parts)
        raw = (text[:a] + "\n".join(lines) + text[z:]).encode("latin-1")
        what = f"element type changed: {lines[i]}"
        expect = "either"      # a point element in place of a line still reads; the mesh decides
    elif kind == "header":
        new = draw(st.sampled_from(["2.2 0 8", "4.1 0 8", "4.1 1 8", "2.2 1 8", "3.0 0 8", "99 0 8", "4.1 0 4",
                                    "-1 0 8", "nan 0 8"]))
        a, z = _section(text, "MeshFormat")
        old = raw[a:z].split(b"\n")[0].decode()
        raw = raw[:a] + new.encode() + raw[a + len(old):]
        what = f"header {old!r} -> {new!r}"
        expect = "either" if new == old or new.replace(" 4", " 8") == old or not ascii_ and new == "4.1 0 8" \
            else "refuse"     # ASCII files ignore the data size; a binary one is also ASCII-readable? no: refuse
    elif kind == "garbage":
        n = draw(st.integers(1, 5000))
        import random
        junk = draw(st.binary(min_size=n, max_size=n)) if n < 200 else \
            random.Random(draw(st.integers(0, 2**32))).randbytes(n)
        a = raw.index(b"$EndMeshFormat") + len(b"$EndMeshFormat\n")
        raw = raw[:a] + junk
        what = f"{n} random bytes after the header"
    elif kind == "empty":
        raw = draw(st.sampled_from([b"", b"\n", b"$MeshFormat\n", b"$MeshFormat\n$EndMeshFormat\n"]))
        what = f"file {raw!r}"
    elif kind == "no_header":
        raw = raw[raw.index(b"$EndMeshFormat") + 15:]
        what = "no $MeshFormat section"
    elif kind == "canary":
        raw = raw.replace(b"$Nodes", f"{CANARY}\n$Nodes".encode(), 1)
        what = "a line of text before $Nodes"
        expect = "either"
    else:
        what = "unchanged"
        expect = "accept"
    case = MSH_CASE_2D if dim == 2 else MSH_CASE_3D

    def run(tmp: Path) -> Result:
        (tmp / "m.msh").write_bytes(raw)
        (tmp / "case.toml").write_text(case)
        return set_up_file(tmp / "case.toml")

    return Example("msh", f"{name}: {what}", expect, run, ())


def _v4_is_block_header(lines, i) -> bool:
    """Whether line i of a v4 $Elements section is an entity block header (dim tag type count)."""
    p = lines[i].split()
    if len(p) != 4 or i == 0:
        return False
    j = i - 1                      # the previous block ended where this one starts (or the section header)
    return len(lines[j].split()) == 4 and (j == 0 or True) and p[0] in "0123"


def _v4_block_dim(lines, i) -> int:
    """The dimension of the v4 element block line i belongs to (-1 if unknown)."""
    j = i
    while j > 0:
        j -= 1
        p = lines[j].split()
        if len(p) == 4 and p[0] in "0123" and int(p[3]) >= 1 and int(p[2]) in range(1, 40):
            # a block header: dim tag type count; the element lines follow it
            if j + int(p[3]) >= i:
                return int(p[0])
    return -1


# -- 3. TOML text ----------------------------------------------------------------------------------
def tiny_case() -> str:
    from test_run_dirs import TINY

    return TINY


TOML_KINDS = ("array_bomb", "table_bomb", "header_bomb", "oversized", "sparse_huge", "long_string", "big_array",
              "many_keys", "long_key", "nul", "utf8", "bom", "crlf", "duplicate", "dotted_conflict", "deep_ok", "valid")


@st.composite
def toml_examples(draw, quick: bool = False, kinds=None):
    """TOML texts of a case file; ``quick``: the big ones smaller (seconds instead of tens)."""
    base = tiny_case()
    kind = draw(st.sampled_from(kinds or TOML_KINDS))
    expect = "refuse"
    sparse = 0
    if kind == "array_bomb":
        n = draw(st.sampled_from([33, 100, 10**3, 10**4] + ([] if quick else [10**5])))
        text = base + f"\n[parameters]\nbomb = {'[' * n}1{']' * n}\n"
        what = f"arrays nested {n} deep"
    elif kind == "table_bomb":
        n = draw(st.sampled_from([33, 100, 10**3, 10**4] + ([] if quick else [10**5])))
        text = base + f"\n[parameters]\nbomb = {'{a = ' * n}1{'}' * n}\n"
        what = f"inline tables nested {n} deep"
    elif kind == "header_bomb":
        n = draw(st.sampled_from([33, 10**3] + ([] if quick else [10**4, 10**5])))
        text = base + "\n[" + ".".join(["a"] * n) + "]\nx = 1\n"
        what = f"a table header {n} keys deep"
    elif kind == "oversized":
        mb = draw(st.sampled_from([9] if quick else [20, 50]))
        text = base + ("#" * 1023 + "\n") * (mb * 1024)
        what = f"{mb} MB of comments"
    elif kind == "sparse_huge":
        sparse = draw(st.sampled_from([50, 100, 200])) * 2**20
        text = base
        what = f"{sparse >> 20} MB file (sparse: NUL bytes after the case)"
    elif kind == "long_string":
        n = draw(st.sampled_from([10**5] if quick else [10**6, 10 * 2**20]))
        text = base.replace('name = "tiny"', f'name = "tiny"\ndescription = "{"x" * n}"')
        what = f"a {n}-character description"
        expect = "either"
    elif kind == "big_array":
        n = draw(st.sampled_from([10**4] if quick else [10**5, 10**6]))
        key = draw(st.sampled_from(["mesh.cells", "fractures.F.vertices", "parameters.p", "mesh.lower"]))
        arr = "[" + ", ".join(["0.5"] * n) + "]" if key != "fractures.F.vertices" else \
            "[" + ", ".join(["[0.5, 0.5]"] * n) + "]"
        text = base + f'\n[parameters]\n' if key == "parameters.p" else base
        if key == "parameters.p":
            text += f"p = {arr}\n"
        elif key == "mesh.cells":
            text = text.replace("cells = [8, 8]", f"cells = {arr}")
        elif key == "mesh.lower":
            text = text.replace("lower = [0.0, 0.0]", f"lower = {arr}")
        else:
            text = text.replace("vertices = [[0.25, 0.5], [0.75, 0.5]]", f"vertices = {arr}")
        what = f"{key}: an array of {n} elements"
    elif kind == "many_keys":
        n = draw(st.sampled_from([10**3] if quick else [10**3, 10**5]))
        where = draw(st.sampled_from(["top", "material"]))
        keys = "".join(f"k{i} = {i}\n" for i in range(n))
        text = keys + base if where == "top" else base.replace("[material]\n", "[material]\n" + keys)
        what = f"{n} unknown keys ({where})"
    elif kind == "long_key":
        n = draw(st.sampled_from([300, 10**4, 10**6]))
        text = base.replace("[material]\n", f"[material]\n{'k' * n} = 1\n")
        what = f"a {n}-character unknown key"
    elif kind == "nul":
        at = draw(st.integers(0, len(base)))
        text = base[:at] + "\x00" + base[at:]
        what = f"a NUL byte at {at}"
        expect = "refuse" if base[at - 1:at] != "\n" or True else "either"
    elif kind == "utf8":
        at = draw(st.integers(0, len(base)))
        text = None
        raw = base[:at].encode() + draw(st.sampled_from([b"\xff", b"\xc3\x28", b"\x80\x80", b"\xed\xa0\x80"])) + \
            base[at:].encode()
        what = f"invalid UTF-8 at byte {at}"
    elif kind == "bom":
        text = "\ufeff" + base
        what = "a UTF-8 byte-order mark"
        expect = "accept"
    elif kind == "crlf":
        text = base.replace("\n", "\r\n")
        what = "CRLF line ends"
        expect = "accept"
    elif kind == "duplicate":
        text = base.replace("nu = 0.25", "nu = 0.25\nnu = 0.3")
        what = "material.nu twice"
    elif kind == "dotted_conflict":
        sub = draw(st.sampled_from(["value_then_table", "table_then_dotted", "array_then_table"]))
        if sub == "value_then_table":
            text = base + "\nmaterial.E = 2e9\n"
        elif sub == "table_then_dotted":
            text = "mesh = 1\n" + base
        else:
            text = base + "\n[mechanics]\nboundary = 1\n"
        what = f"dotted-key conflict: {sub}"
    elif kind == "deep_ok":
        n = draw(st.sampled_from([5, 20, 32]))
        text = base + f"\n[parameters]\nbomb = {'[' * n}1{']' * n}\n"
        what = f"an unknown parameter nested {n} deep"
        expect = "either"
    else:
        text = base
        what = "unchanged"
        expect = "accept"
    if kind != "utf8":
        raw = text.encode()

    def run(tmp: Path) -> Result:
        p = tmp / "case.toml"
        p.write_bytes(raw)
        if sparse:
            with open(p, "r+b") as f:
                f.truncate(sparse)
        try:
            return set_up_file(p)
        finally:
            p.unlink()

    # unknown keys are named as given
    return Example("toml", what, expect, run, ("k",) if kind in ("many_keys", "long_key") else ())


# -- 4. file-system faults through polypore.cli.main ------------------------------------------------
WRITES = ("open", "os.replace", "shutil.move", "os.fsync", "os.mkdir", "os.write")


def cli_main(argv) -> Result:
    """``polypore.cli.main(argv)`` in-process: Result from its exit status and stderr; an exception
    out of it propagates (a traceback), and so does "Traceback" on stderr."""
    from polypore.cli import main

    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main(argv)
        except SystemExit as exc:        # argparse
            code = exc.code
    text = err.getvalue()
    if "Traceback" in text:
        raise RuntimeError(f"traceback on stderr:\n{text}")
    kind = {0: "ok", 2: "input", 1: "failed"}.get(code)
    if kind is None:
        raise RuntimeError(f"exit status {code}: {text[-2000:]}")
    line = text.strip().splitlines()[-1] if text.strip() else ""
    m = re.match(r"polypore: (?:error: |run failed: )?(?P<field>[^ :]+(?: [^ :]+)?): ", line)
    field = m.group("field") if (m and kind == "input") else None
    return Result(kind, field, text)


@contextlib.contextmanager
def fail_writes(nth: int, err: int, counter: list):
    """The ``nth`` write-side call (open for writing, os.replace, shutil.move, os.fsync, os.mkdir,
    os.write) raises OSError(err); ``counter[0]`` counts the calls. Not counted: os.mkdir of a
    folder that exists (Path.mkdir(exist_ok=True) ignores its error) and the fsync of a folder
    (atomic._sync_dir, best effort once the results are in place)."""
    real = {"open": builtins.open, "os.replace": os.replace, "shutil.move": shutil.move, "os.fsync": os.fsync,
            "os.mkdir": os.mkdir, "os.write": os.write}

    def wrap(name):
        fn = real[name]

        def f(*a, **k):
            if name == "open":
                mode = a[1] if len(a) > 1 else k.get("mode", "r")
                if not any(c in mode for c in "wax+"):
                    return fn(*a, **k)
            if name == "os.mkdir" and a and os.path.isdir(a[0]):
                return fn(*a, **k)          # Path.mkdir(exist_ok=True) of a folder that exists: no write
            if name == "os.fsync" and a and stat.S_ISDIR(os.fstat(a[0]).st_mode):
                return fn(*a, **k)          # a folder's fsync after the results are in: best effort by design
            counter[0] += 1
            if counter[0] == nth:
                raise OSError(err, os.strerror(err))
            return fn(*a, **k)
        return f

    builtins.open, os.replace, shutil.move, os.fsync, os.mkdir, os.write = (wrap(n) for n in WRITES)
    try:
        yield
    finally:
        builtins.open, os.replace, shutil.move, os.fsync, os.mkdir, os.write = (real[n] for n in WRITES)


def _folder_problems(out: Path) -> list:
    """A failed command leaves nothing, or failed.json only (with polypore's marker and lock)."""
    if not out.is_dir():
        return []
    left = sorted(p.name for p in out.iterdir() if p.name not in (".polypore-run.json", ".polypore-lock"))
    stages = [p.name for p in out.parent.glob(".partial-*")]
    probs = []
    if left not in ([], ["failed.json"]):
        probs.append(f"failed run left {left[:6]}")
    if stages:
        probs.append(f"staging folder left behind: {stages}")
    return probs


@lru_cache(maxsize=None)
def write_calls(command: str) -> int:
    """How many write-side calls (:func:`fail_writes`) a clean ``polypore -q COMMAND`` of the tiny case makes."""
    with tempfile.TemporaryDirectory() as d:
        case = Path(d) / "tiny.toml"
        case.write_text(tiny_case())
        counter = [0]
        with fail_writes(0, errno.EIO, counter):
            res = cli_main(["-q", command, str(case), "--out", str(Path(d) / "out")])
        assert res.kind == "ok", res
    return counter[0]


FS_KINDS = ("case_missing", "case_dir", "case_fifo", "case_devzero", "case_loop", "case_unreadable", "out_under_file",
            "out_long", "out_proc", "out_root", "disk_full", "eio", "write_fault", "grdecl_dir", "grdecl_fifo", "grdecl_devzero",
            "valid")
# the errors of the write_fault kind: a quota, a file too large, a read-only remount, permissions changed mid-run
WRITE_FAULTS = ("EDQUOT", "EFBIG", "EROFS", "EACCES", "EPERM")


@st.composite
def fs_examples(draw, kinds=None):
    kind = draw(st.sampled_from(kinds or FS_KINDS))
    command = draw(st.sampled_from(["mesh", "run"]))
    expect = "refuse"
    nth = draw(st.integers(1, write_calls(command)))
    what = f"{command}: {kind}"
    fault = {"disk_full": "ENOSPC", "eio": "EIO"}.get(kind) or (
        draw(st.sampled_from(WRITE_FAULTS)) if kind == "write_fault" else None)
    if fault:
        what += f" ({fault}) at write call {nth}"
    if kind == "valid":
        expect = "accept"

    def run(tmp: Path) -> Result:
        case = tmp / "tiny.toml"
        case.write_text(tiny_case())
        out = tmp / "out"
        arg = str(case)
        pre = contextlib.nullcontext()
        if kind == "case_missing":
            arg = str(tmp / "nope.toml")
        elif kind == "case_dir":
            (tmp / "d.toml").mkdir()
            arg = str(tmp / "d.toml")
        elif kind == "case_fifo":
            os.mkfifo(tmp / "p.toml")
            arg = str(tmp / "p.toml")
        elif kind == "case_devzero":
            arg = "/dev/zero"
        elif kind == "case_loop":
            (tmp / "l.toml").symlink_to(tmp / "l.toml")
            arg = str(tmp / "l.toml")
        elif kind == "case_unreadable":
            pre = _unreadable(case)
        elif kind == "out_under_file":
            (tmp / "f").write_text("x")
            out = tmp / "f" / "out"
        elif kind == "out_long":
            out = tmp / ("x" * 300)
        elif kind == "out_proc":
            out = Path("/proc/polypore-fuzz")
        elif kind == "out_root":
            out = Path("/")
        elif kind in ("grdecl_dir", "grdecl_fifo", "grdecl_devzero"):
            target = {"grdecl_dir": "g.grdecl", "grdecl_fifo": "g.grdecl", "grdecl_devzero": "/dev/zero"}[kind]
            if kind == "grdecl_dir":
                (tmp / "g.grdecl").mkdir()
            elif kind == "grdecl_fifo":
                os.mkfifo(tmp / "g.grdecl")
            case.write_text(GRDECL_CASE.format(file=target))
        counter = [0]
        if fault:
            pre = fail_writes(nth, getattr(errno, fault), counter)
        with pre:
            res = cli_main(["-q", command, arg, "--out", str(out)])
        if fault:
            if counter[0] < nth:
                res.kind = "ok-no-fault" if res.kind == "ok" else res.kind   # fewer writes than nth
            if res.kind == "input" and res.field is None:
                res.field = "--out"
        if res.kind != "ok" and res.kind != "ok-no-fault" and not str(out).startswith("/proc") and out != Path("/"):
            try:
                res.problems += _folder_problems(out)
            except OSError:
                pass
        if res.kind == "ok-no-fault":
            res.kind = "ok"
            res.problems.append("no-fault")      # not a fault example after all: judged as valid
        return res

    return Example("fs", what, expect, run, ())


@contextlib.contextmanager
def _unreadable(path: Path):
    """Reading ``path`` raises PermissionError (root reads any file: chmod would not do)."""
    real_open, real_read = builtins.open, Path.read_bytes
    target = str(path.resolve())

    def is_target(p):
        try:
            return str(Path(p).resolve()) == target
        except (OSError, TypeError, ValueError):
            return False

    def fake_open(file, *a, **k):
        if isinstance(file, (str, os.PathLike)) and is_target(file):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(file))
        return real_open(file, *a, **k)

    def fake_read(self):
        if is_target(self):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(self))
        return real_read(self)

    builtins.open, Path.read_bytes = fake_open, fake_read
    try:
        yield
    finally:
        builtins.open, Path.read_bytes = real_open, real_read


# -- 0. case-file value mutations (tests/casefuzz.py) -------------------------------------------------
@st.composite
def case_examples(draw):
    import casefuzz

    case, what = draw(casefuzz.mutated_cases())

    def run(tmp: Path) -> Result:
        if isinstance(case, InputError):       # a --set refused by apply_override
            return Result("input", case.field, str(case), named=casefuzz.names_a_field(case.field, case))
        try:
            casefuzz.set_up(case)
        except InputError as exc:
            return Result("input", exc.field, str(exc), named=casefuzz.names_a_field(exc.field, case))
        return Result("ok")

    return Example("case", "; ".join(what)[:300], "either", run, ())


KINDS = {"case": None, "grdecl": GRDECL_KINDS, "msh": MSH_KINDS, "toml": TOML_KINDS, "fs": FS_KINDS}
STRATEGIES = {"case": case_examples, "grdecl": grdecl_examples, "msh": msh_examples, "toml": toml_examples,
              "fs": fs_examples}


def examples(families=FAMILIES, weights=None):
    """Examples of the given families, drawn with the given relative weights (default equal)."""
    weights = weights or {f: 1 for f in families}
    pool = [f for f in families for _ in range(int(weights.get(f, 1)))]
    return st.sampled_from(pool).flatmap(lambda f: STRATEGIES[f]())


def warm_up(families=FAMILIES) -> None:
    """Build the base files (and the coarse case meshes) outside the timings."""
    if "grdecl" in families:
        grdecl_bases()
    if "msh" in families:
        msh_bases()
    if "fs" in families:
        write_calls("mesh"), write_calls("run")
    if "case" in families:
        import casefuzz
        for name in casefuzz.NAMES:
            casefuzz._mesh(casefuzz.base_case(name))
