"""ASCII Eclipse GRDECL reader: corner-point geometry, ACTNUM, MAPAXES, FAULTS, cell properties.

The file is read as text once; comments (``--`` to the end of a line) are removed, keywords
are found line by line (a keyword stands alone on its line, as Eclipse requires), and every
numeric block up to its ``/`` terminator is converted in one call (``np.fromstring``), after
expanding repeat counts ``n*value``. No Python work per value: 500k cells (4 M ZCORN values)
read in a few seconds.
"""

from __future__ import annotations

import re
import stat
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Mapping

import numpy as np

from ...core.errors import InputError
from ...core.ragged import frozen

FEET = 0.3048  # m
# Most values a block's repeat counts may expand to when SPECGRID does not bound it (ZCORN of
# 12.5 M cells): ``1000000000000*0.2`` must be an error, not a MemoryError.
MAX_EXPANDED = 10**8

# keywords without data (section headers, switches)
NO_DATA = frozenset({"ECHO", "NOECHO", "RUNSPEC", "GRID", "EDIT", "PROPS", "REGIONS", "SOLUTION", "SUMMARY",
                     "SCHEDULE", "END", "NONNC", "NEWTRAN", "OLDTRAN", "SKIP", "ENDSKIP", "SKIPREST",
                     "GRIDFILE", "INIT", "NOSIM", "PINCH"})
# keywords with data we read or skip knowingly (the data may contain words and quotes)
STRING_DATA = frozenset({"INCLUDE", "MAPUNITS", "GRIDUNIT", "GDORIENT", "FAULTS", "COORDSYS", "SPECGRID",
                         "DIMENS", "MAPAXES", "TITLE", "GDFILE", "NNC", "EQUALS", "COPY", "MULTIPLY", "ADD",
                         "BOX", "ENDBOX", "MINPV", "MULTFLT", "MULTREGT", "EDITNNC"})
GEOMETRY = ("COORD", "ZCORN", "ACTNUM")
# cell properties with a known meaning (others numeric with nx*ny*nz values are kept by name too)
PROPERTY_UNITS = {"PORO": "–", "NTG": "–", "MULTPV": "–", "PERMX": "mD", "PERMY": "mD", "PERMZ": "mD",
                  "SATNUM": "–", "FIPNUM": "–", "EQLNUM": "–", "PVTNUM": "–", "FACIES": "–",
                  "MULTX": "–", "MULTY": "–", "MULTZ": "–", "DX": "m", "DY": "m", "DZ": "m", "TOPS": "m"}
FACES = {"X": "X", "X+": "X", "I": "X", "I+": "X", "X-": "X-", "I-": "X-",
         "Y": "Y", "Y+": "Y", "J": "Y", "J+": "Y", "Y-": "Y-", "J-": "Y-",
         "Z": "Z", "Z+": "Z", "K": "Z", "K+": "Z", "Z-": "Z-", "K-": "Z-"}

_KEYWORD = re.compile(r"^[ \t]*([A-Za-z][A-Za-z0-9_+\-]{0,7})[ \t]*\r?$", re.M)
_COMMENT_OR_QUOTE = re.compile(r"'[^'\n]*'|--[^\n]*")
_REPEAT = re.compile(r"(?<![^\s])(\d+)\*(\S*)")
_TOKEN = re.compile(r"'([^']*)'|(\S+)")
_NOT_FINITE = re.compile(r"(?i)(?<![^\s*])[+-]?(nan|inf)")
# the largest coordinate or depth taken (m): far beyond the earth (UTM northings in feet are 3e7),
# near enough that the geometry's products of coordinates stay finite
MAX_COORDINATE = 1e9
# Errors name the file, the keyword and the line, but never quote the file's text: mesh.file may
# point at any file the user can read (a system file), and messages end up in logs and web pages.


@dataclass(frozen=True, eq=False)
class CornerPointGrid:
    """A corner-point grid as read from a GRDECL file (or generated).

    Indices (i, j, k) are 0-based in arrays; the FAULTS records keep the file's 1-based,
    inclusive ranges. Depths are positive downwards, as in the file; lengths in m.

    Attributes
    ----------
    dims : (nx, ny, nz) tuple of int
    coord : (nx+1, ny+1, 6) float64, m
        Pillar (i, j): top point (x, y, depth) then bottom point (x, y, depth), in the grid's
        local frame (before MAPAXES).
    zcorn : (2nx, 2ny, 2nz) float64, m
        Corner depths: cell (i, j, k) has its corner (di, dj, dk) ∈ {0, 1}^3 at
        ``zcorn[2i+di, 2j+dj, 2k+dk]`` (dk = 0 top, 1 bottom; di, dj = 0 on the low-index side).
    actnum : (nx, ny, nz) bool
        Active cells.
    mapaxes : (3, 2) float64 or None, m
        MAPAXES points: a point on the y axis, the origin, a point on the x axis.
    faults : mapping name -> tuple of (i1, i2, j1, j2, k1, k2, face)
        FAULTS records, 1-based inclusive; face one of ``X``, ``X-``, ``Y``, ``Y-``, ``Z``, ``Z-``.
    properties : mapping name -> (nx, ny, nz) float64
        Cell keywords (PORO, NTG, MULTPV, PERMX/Y/Z in mD, ... any numeric keyword with
        nx·ny·nz values), in the file's units.
    source : str
        File name (or ``"generated"``), for messages.
    """

    dims: tuple
    coord: np.ndarray
    zcorn: np.ndarray
    actnum: np.ndarray
    mapaxes: np.ndarray | None = None
    faults: Mapping[str, tuple] = field(default_factory=dict)
    properties: Mapping[str, np.ndarray] = field(default_factory=dict)
    source: str = "generated"

    def __post_init__(self):
        nx, ny, nz = (int(d) for d in self.dims)
        object.__setattr__(self, "dims", (nx, ny, nz))
        src = self.source

        def arr(name, a, shape, dtype):
            a = np.asarray(a, dtype=dtype)
            if a.shape != shape:
                raise InputError(f"{src}:{name}", f"expected shape {shape}, got {a.shape}")
            return frozen(a)
        object.__setattr__(self, "coord", arr("COORD", self.coord, (nx + 1, ny + 1, 6), float))
        object.__setattr__(self, "zcorn", arr("ZCORN", self.zcorn, (2 * nx, 2 * ny, 2 * nz), float))
        object.__setattr__(self, "actnum", arr("ACTNUM", self.actnum, (nx, ny, nz), bool))
        if self.mapaxes is not None:
            object.__setattr__(self, "mapaxes", arr("MAPAXES", self.mapaxes, (3, 2), float))
        object.__setattr__(self, "faults", MappingProxyType({str(k): tuple(tuple(r) for r in v)
                                                             for k, v in dict(self.faults).items()}))
        object.__setattr__(self, "properties", MappingProxyType(
            {str(k): arr(k, v, (nx, ny, nz), float) for k, v in dict(self.properties).items()}))

    @property
    def n_cells(self) -> int:
        nx, ny, nz = self.dims
        return nx * ny * nz

    def cell_corners(self) -> np.ndarray:
        """(nx, ny, nz, 2, 2, 2) corner depths, indexed [i, j, k, di, dj, dk] (m)."""
        nx, ny, nz = self.dims
        return self.zcorn.reshape(nx, 2, ny, 2, nz, 2).transpose(0, 2, 4, 1, 3, 5)


# -- text handling ------------------------------------------------------------------------------
def _strip_comments(text: str) -> str:
    if "--" not in text:
        return text
    return _COMMENT_OR_QUOTE.sub(lambda m: m.group(0) if m.group(0)[0] == "'" else "", text)


def _find_slash(text: str, start: int, quoted: bool) -> int:
    """Position of the '/' ending the record that starts at ``start`` (-1 if none)."""
    if not quoted:
        return text.find("/", start)
    pos = start
    while True:
        s = text.find("/", pos)
        q = text.find("'", pos)
        if q < 0 or s < 0 or s < q:
            return s
        q2 = text.find("'", q + 1)
        if q2 < 0:
            return s
        pos = q2 + 1


def _known(kw: str) -> bool:
    """Whether ``kw`` is a keyword this reader knows by name."""
    return kw in NO_DATA or kw in STRING_DATA or kw in GEOMETRY or kw in PROPERTY_UNITS or kw == "FAULTS"


def _tokens(record: str) -> list:
    """Tokens of a record with words and quoted strings (quotes removed)."""
    return [a if a or b == "" else b for a, b in _TOKEN.findall(record)]


def _expanded_size(block: str) -> int:
    """Number of values a block holds once its repeat counts ``n*value`` are expanded."""
    return len(block.split()) + sum(int(m.group(1)) - 1 for m in _REPEAT.finditer(block))


def _on_line(line) -> str:
    return f" (keyword on line {line()})" if line is not None else ""


def _numbers(block: str, kw: str, where: str, limit: tuple | None = None, line=None) -> np.ndarray:
    """Numeric values of a data block (repeat counts expanded, ``n*`` defaults as NaN).

    ``limit`` is ``(values needed, grid dimensions text)``; repeat counts that would expand
    beyond it (or beyond :data:`MAX_EXPANDED`) are an error naming ``line()``, the keyword's
    line, before any memory is taken.
    """
    word = _NOT_FINITE.search(block)
    if word:
        # a written nan or inf (n* defaults are NaN too, and refused as such by the caller)
        k = len(block[:word.start()].split()) + 1
        raise InputError(f"{where}:{kw}", f"value {k} is not a finite number{_on_line(line)}; {kw} takes "
                         "finite numbers")
    if "*" in block:
        size = _expanded_size(block)
        need = limit[0] if limit is not None else None
        if size > MAX_EXPANDED or (need is not None and size > need):
            at = f" (repeat counts expanded; keyword on line {line()})" if line is not None else \
                " (repeat counts expanded)"
            if need is not None and need <= MAX_EXPANDED:
                raise InputError(f"{where}:{kw}", f"{kw} has {size} values, {limit[1]} needs {need}{at}")
            raise InputError(f"{where}:{kw}", f"{kw} has {size} values, more than the {MAX_EXPANDED} the "
                             f"reader takes per keyword{at}")
        block = _REPEAT.sub(lambda m: (" " + (m.group(2) or "nan")) * int(m.group(1)), block)
    if "d" in block or "D" in block:
        block = block.replace("d", "e").replace("D", "e")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            values = np.fromstring(block, sep=" ")
        except (ValueError, DeprecationWarning):
            values = None
    if values is not None:
        big = np.flatnonzero(np.isinf(values))
        if big.size:
            raise InputError(f"{where}:{kw}", f"value {big[0] + 1} (after repeat counts are expanded) overflows: "
                             f"beyond ±1.8e308{_on_line(line)}; {kw} takes finite numbers")
        return values
    for k, tok in enumerate(block.split()):
        try:
            float(tok)
        except ValueError:
            raise InputError(f"{where}:{kw}", f"value {k + 1} (after repeat counts are expanded) is not a number"
                             f"{_on_line(line)}; {kw} takes numbers (repeat counts written n*value) ended by "
                             "'/'") from None
    raise InputError(f"{where}:{kw}", "could not read the numbers")  # pragma: no cover


class _Parser:
    def __init__(self):
        self.raw: dict = {}          # keyword -> (values, file)
        self.faults: dict = {}
        self.specgrid = None
        self.mapaxes = None
        self.grid_scale = 1.0        # GRIDUNIT FEET -> m
        self.map_scale = 1.0

    def parse_file(self, path: Path, depth: int = 0):
        if depth > 20:
            raise InputError(str(path), "INCLUDE nested more than 20 levels (an include loop?)")
        try:
            # a FIFO would block the read forever, a device (/dev/zero) never end it: regular files only
            if not stat.S_ISREG(path.stat().st_mode):
                raise InputError(str(path), "is not a regular file (a folder, a pipe or a device); "
                                 "INCLUDE and mesh.file take GRDECL files")
            text = path.read_text(errors="replace")
        except OSError as exc:
            raise InputError(str(path), f"cannot read the file: {exc.strerror or exc}") from None
        text = _strip_comments(text)
        where = path.name

        def line_of(at: int) -> int:
            return text.count("\n", 0, at) + 1
        pos, n = 0, len(text)
        seen, seen_line = 0, 1       # lines counted incrementally: one pass over the text in all
        while pos < n:
            m = _KEYWORD.search(text, pos)
            if not m:
                rest = text[pos:].strip()
                if rest and rest != "/":
                    raise InputError(where, f"unexpected text on line {line_of(pos + text[pos:].index(rest[0]))} "
                                     "after the last keyword; a GRDECL file is keywords, each alone on its line, "
                                     "with data ended by '/'")
                break
            stray = text[pos:m.start()].strip().strip("/").strip()
            if stray:
                at = pos + text[pos:m.start()].index(stray[0])
                raise InputError(where, f"unexpected text on line {line_of(at)}, before the keyword on line "
                                 f"{line_of(m.start())}; data must follow its keyword and end with '/'")
            kw = m.group(1).upper()
            kw_start = m.start()
            pos = m.end()
            seen_line += text.count("\n", seen, kw_start)
            seen = kw_start
            # an unknown keyword is named by its line in errors: a word of an arbitrary file is not quoted
            label = kw if _known(kw) else f"keyword on line {seen_line}"
            if kw in NO_DATA:
                continue
            if kw == "FAULTS":
                pos = self._faults(text, pos, where, line_of)
                continue
            quoted = kw in STRING_DATA
            slash = _find_slash(text, pos, quoted)
            if slash < 0:
                raise InputError(f"{where}:{label}", "has no terminating '/'")
            block = text[pos:slash]
            if kw not in STRING_DATA and kw not in GEOMETRY and kw not in PROPERTY_UNITS:
                # an unknown keyword without data: the next keyword comes before any '/'
                if any(k.group(1).upper() in NO_DATA | STRING_DATA | set(GEOMETRY) | set(PROPERTY_UNITS)
                       for k in _KEYWORD.finditer(block)):
                    continue
            pos = slash + 1
            if kw == "INCLUDE":
                toks = _tokens(block)
                if len(toks) != 1:
                    raise InputError(f"{where}:INCLUDE", f"expected one file name, got {len(toks)} items (line "
                                     f"{line_of(kw_start)})")
                inc = Path(toks[0])
                if not inc.is_absolute():
                    inc = path.parent / inc
                self.parse_file(inc, depth + 1)
            elif kw in ("SPECGRID", "DIMENS"):
                toks = _tokens(block)
                try:
                    dims = tuple(int(t) for t in toks[:3])
                except ValueError:
                    raise InputError(f"{where}:{kw}", f"nx ny nz must be integers (line {line_of(kw_start)})") \
                        from None
                if len(toks) > (5 if kw == "SPECGRID" else 3):
                    # the '/' is missing: the record ran on into the next keywords
                    raise InputError(f"{where}:{kw}", f"has {len(toks)} items (line {line_of(kw_start)}); "
                                     f"{kw} takes {'nx ny nz [numres [F]]' if kw == 'SPECGRID' else 'nx ny nz'} "
                                     "ended by '/'")
                if len(dims) != 3 or min(dims) < 1:
                    raise InputError(f"{where}:{kw}", f"needs three positive integers nx ny nz, got {dims} (line "
                                     f"{line_of(kw_start)})")
                if kw == "SPECGRID" and len(toks) >= 5 and toks[4].upper() == "T":
                    raise InputError(f"{where}:SPECGRID", "radial (cylindrical, 'T') grids are not supported; "
                                     "allowed: Cartesian corner-point grids ('F')")
                if kw == "SPECGRID" or self.specgrid is None:
                    self.specgrid = (dims, where, kw)
            elif kw == "MAPAXES":
                v = _numbers(block, kw, where)
                if v.size != 6:
                    raise InputError(f"{where}:MAPAXES", f"has {v.size} values, needs 6 (three points x y)")
                self.mapaxes = v.reshape(3, 2)
            elif kw in ("GRIDUNIT", "MAPUNITS"):
                toks = _tokens(block)
                unit = toks[0].strip().upper() if toks else "METRES"
                if unit.startswith("FEET") or unit == "FT":
                    scale = FEET
                elif unit.startswith("MET") or unit == "M":
                    scale = 1.0
                else:
                    raise InputError(f"{where}:{kw}", f"unknown unit (line {line_of(kw_start)}); allowed: METRES, "
                                     "FEET")
                if kw == "GRIDUNIT":
                    self.grid_scale = scale
                else:
                    self.map_scale = scale
            elif kw in STRING_DATA:
                continue             # known keywords we do not use
            else:
                limit = self._size_needed(kw)
                if limit is not None and kw not in GEOMETRY and kw not in PROPERTY_UNITS \
                        and "*" in block and _expanded_size(block) != limit[0]:
                    continue         # an unknown keyword not per cell is dropped anyway: do not expand it
                self.raw[kw] = (_numbers(block, label, where, limit,
                                         lambda: text.count("\n", 0, kw_start) + 1), where)

    def _size_needed(self, kw: str):
        """(values keyword ``kw`` needs, the reason) once SPECGRID is known, else None."""
        if self.specgrid is None:
            return None
        (nx, ny, nz), _, dkw = self.specgrid
        need = {"COORD": 6 * (nx + 1) * (ny + 1), "ZCORN": 8 * nx * ny * nz}.get(kw, nx * ny * nz)
        return need, f"{dkw} {nx}×{ny}×{nz}"

    def _faults(self, text: str, pos: int, where: str, line_of) -> int:
        while True:
            slash = _find_slash(text, pos, True)
            if slash < 0:
                raise InputError(f"{where}:FAULTS", "has no terminating '/' (end the list with an empty record '/')")
            toks = _tokens(text[pos:slash])
            start = pos + len(text[pos:slash]) - len(text[pos:slash].lstrip())
            pos = slash + 1
            if not toks:
                return pos
            rec = f"the record on line {line_of(start)}"
            if len(toks) != 8:
                raise InputError(f"{where}:FAULTS", f"{rec} has {len(toks)} items; expected "
                                 "'name' i1 i2 j1 j2 k1 k2 face")
            try:
                rng = tuple(int(t) for t in toks[1:7])
            except ValueError:
                raise InputError(f"{where}:FAULTS", f"{rec}: i1 i2 j1 j2 k1 k2 must be "
                                 "integers") from None
            face = FACES.get(toks[7].upper())
            if face is None:
                raise InputError(f"{where}:FAULTS", f"{rec}: the face is not one of "
                                 "X, X-, Y, Y-, Z, Z- (or I, J, K)")
            self.faults.setdefault(toks[0], []).append(rng + (face,))


def read_grdecl(path) -> CornerPointGrid:
    """Read an ASCII GRDECL file (with its INCLUDE files) into a :class:`CornerPointGrid`.

    Reads SPECGRID (or DIMENS), COORD, ZCORN, ACTNUM (default: all active), MAPAXES,
    GRIDUNIT / MAPUNITS (FEET converted to m), FAULTS and every numeric keyword with one
    value per cell (PORO, PERMX, NTG, MULTPV, FACIES, ...). INCLUDE paths are relative to
    the including file. Keywords without data (ECHO, NOECHO, section names) and other known
    keywords (GDORIENT, COORDSYS, ...) are skipped.

    Raises
    ------
    InputError
        Naming the file and keyword: a missing SPECGRID, COORD or ZCORN, a wrong number of
        values ("ZCORN has 123 values, SPECGRID 10×10×3 needs 2400"; repeat counts are checked
        before they are expanded, with the keyword's line), a value that is not a number, an
        ACTNUM value other than 0 or 1, a FAULTS record outside the grid.
    """
    path = Path(path)
    p = _Parser()
    p.parse_file(path)
    where = path.name
    if p.specgrid is None:
        raise InputError(f"{where}:SPECGRID", "missing: the grid dimensions nx ny nz are needed")
    (nx, ny, nz), _, dkw = p.specgrid
    dims_txt = f"{dkw} {nx}×{ny}×{nz}"
    ncell = nx * ny * nz

    def get(kw, need, required=True):
        if kw not in p.raw:
            if required:
                raise InputError(f"{where}:{kw}", f"missing; a corner-point grid needs COORD and ZCORN")
            return None
        v, src = p.raw.pop(kw)
        if v.size != need:
            raise InputError(f"{src}:{kw}", f"{kw} has {v.size} values, {dims_txt} needs {need}")
        if np.isnan(v).any():
            raise InputError(f"{src}:{kw}", "has defaulted values (n*); every value must be given")
        return v

    def check_actnum(v, src):
        # Eclipse's ACTNUM is 0 (inactive) or 1 (active); another value is a broken file, not "active"
        bad = np.flatnonzero((v != 0) & (v != 1))
        if bad.size:
            idx = int(bad[0])
            i, j, k = idx % nx + 1, idx // nx % ny + 1, idx // (nx * ny) + 1
            raise InputError(f"{src}:ACTNUM", f"value {v[idx]:g} at cell (i, j, k) = ({i}, {j}, {k}) "
                             f"({bad.size} such values); ACTNUM takes 0 (inactive) or 1 (active) only")

    coord = get("COORD", 6 * (nx + 1) * (ny + 1)) * p.grid_scale
    zcorn = get("ZCORN", 8 * ncell) * p.grid_scale
    for kw, v in (("COORD", coord), ("ZCORN", zcorn)):
        far = np.flatnonzero(np.abs(v) > MAX_COORDINATE)
        if far.size:
            raise InputError(f"{where}:{kw}", f"value {far[0] + 1} is {v[far[0]]:.3g} m; {kw} takes coordinates "
                             f"within ±{MAX_COORDINATE:.0e} m")
    act_src = p.raw.get("ACTNUM", (None, where))[1]
    act = get("ACTNUM", ncell, required=False)
    if act is not None:
        check_actnum(act, act_src)
    coord = coord.reshape(ny + 1, nx + 1, 6).transpose(1, 0, 2)
    zcorn = zcorn.reshape(2 * nz, 2 * ny, 2 * nx).T
    actnum = np.ones((nx, ny, nz), bool) if act is None else (act.reshape(nz, ny, nx).T != 0)
    props = {}
    for kw in list(p.raw):
        v, src = p.raw.pop(kw)
        if v.size == ncell:
            props[kw] = v.reshape(nz, ny, nx).T
        elif kw in PROPERTY_UNITS:
            raise InputError(f"{src}:{kw}", f"{kw} has {v.size} values, {dims_txt} needs {ncell}")
    for name, recs in p.faults.items():
        for r in recs:
            i1, i2, j1, j2, k1, k2, _ = r
            if not (1 <= i1 <= i2 <= nx and 1 <= j1 <= j2 <= ny and 1 <= k1 <= k2 <= nz):
                raise InputError(f"{where}:FAULTS", f"fault {name!r} record {r[:6]} lies outside the grid "
                                 f"{nx}×{ny}×{nz}; need 1 ≤ i1 ≤ i2 ≤ {nx}, 1 ≤ j1 ≤ j2 ≤ {ny}, 1 ≤ k1 ≤ k2 ≤ {nz}")
    mapaxes = None if p.mapaxes is None else p.mapaxes * p.map_scale
    return CornerPointGrid((nx, ny, nz), np.ascontiguousarray(coord), zcorn, actnum, mapaxes,
                           {k: tuple(v) for k, v in p.faults.items()}, props, where)
