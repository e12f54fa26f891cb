"""Result files of a run (interface.md): summary.json, fractures.csv, run directories.

A run writes into a hidden staging directory next to DIR and moves the files into DIR only
when it has succeeded, summary.json last: a failed run leaves no file that looks complete
(only ``failed.json`` with the reason); see :func:`polypore.io.atomic.run_directory`.
"""

from __future__ import annotations

import csv
import io
import json
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import numpy as np

from .atomic import atomic_write_text, is_staging, run_directory

CSV_COLUMNS = ("step", "time", "fracture", "face", "x", "y", "z", "s", "area", "jump_n", "jump_t", "jump_x", "jump_y",
               "jump_z", "lambda_n", "lambda_t", "state", "aperture", "p_f", "delta_cfs", "slip_tendency")


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if np.isfinite(v) else None
    return obj


def write_json(path, data: dict) -> None:
    atomic_write_text(path, json.dumps(_jsonable(data), indent=2))


def fracture_rows(step: int, time: float, names, fracture, centroid, s, area, jump, normal, lam, state_names,
                  aperture=None, p_f=None, delta_cfs=None, slip_tendency=None) -> list[dict]:
    """Rows of fractures.csv for one output time (arrays over fracture faces); the optional columns
    (poromechanics: aperture, p_f, ΔCFS, slip tendency) are empty when not given."""
    n = len(fracture)
    d = jump.shape[1]
    jn = np.einsum("fi,fi->f", jump, normal)
    jt = np.linalg.norm(jump - jn[:, None] * normal, axis=1)
    ln = np.einsum("fi,fi->f", lam, normal)
    lt = np.linalg.norm(lam - ln[:, None] * normal, axis=1)
    cols = {
        "step": np.full(n, step), "time": np.full(n, time), "fracture": np.asarray(names)[fracture],
        "face": np.arange(n), "x": centroid[:, 0], "y": centroid[:, 1],
        "z": centroid[:, 2] if d == 3 else np.full(n, ""), "s": np.where(np.isnan(s), "", s) if d == 2 else np.full(n, ""),
        "area": area, "jump_n": jn, "jump_t": jt, "jump_x": jump[:, 0], "jump_y": jump[:, 1],
        "jump_z": jump[:, 2] if d == 3 else np.full(n, ""), "lambda_n": ln, "lambda_t": lt,
        "state": np.asarray(state_names), "aperture": aperture if aperture is not None else np.full(n, ""),
        "p_f": p_f if p_f is not None else np.full(n, ""),
        "delta_cfs": delta_cfs if delta_cfs is not None else np.full(n, ""),
        "slip_tendency": slip_tendency if slip_tendency is not None else np.full(n, ""),
    }
    return cols


def write_fractures_csv(path, blocks: list[dict]) -> None:
    """fractures.csv from a list of column blocks (one per output time), see :func:`fracture_rows`."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for cols in blocks:
        n = len(cols["face"])
        fmt = {k: [f"{v:.10g}" if isinstance(v, (float, np.floating)) else str(v) for v in cols[k]] for k in CSV_COLUMNS}
        w.writerows(zip(*(fmt[k] for k in CSV_COLUMNS))) if n else None
    atomic_write_text(path, buf.getvalue())


@contextmanager
def staged_run_directory(out: Path) -> Iterator[Path]:
    """Yield a folder to write a run's files into (see :func:`polypore.io.atomic.run_directory`).

    Inside the command line's run directory ``out`` already is the staging folder and is
    yielded as is: the command line moves it into place, after everything it does. Called
    directly, this opens a run directory of its own on ``out``, replacing a previous result.
    """
    if is_staging(out):
        yield Path(out)
        return
    with run_directory(out, force=True) as stage:
        yield stage
