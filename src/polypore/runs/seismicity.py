"""The event catalogue of a rate-and-state run (issue 28): episodes where a fault's peak slip rate
exceeds a seismic threshold, with their size.

An event on a fault starts in the first accepted sub-step in which some face of that fault slides
faster than ``threshold`` (m/s; the hypocentre is the fastest of those faces) and ends in the
first sub-step after which none does. Over the event every face of the fault adds its slip
increment; the faces that exceeded the threshold at least once make the ruptured area. The
seismic moment is M₀ = Σ μ_s Δs |σ| over the fault's faces (N·m in 3D, N·m per metre of strike
in 2D) and, in 3D, M_w = (2/3)(log₁₀ M₀ − 9.1) (Hanks and Kanamori 1979, M₀ in N·m). Slip
outside events is aseismic and reported apart, per fault, as its moment.

Every sub-step also adds a row to the run's seismicity series (:meth:`EventCatalogue.series`,
seismicity.csv): the peak slip rate of each fault, the cumulative seismic and aseismic moments and
the cumulative injected volume ΔV, the quantity of McGarr's (2014) bound M₀,max = μ_s ΔV.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_write_text

SEISMIC_RATE = 1e-3         # m/s: the default threshold of an event (issue 28)
COLUMNS = ("fault", "onset_s", "end_s", "duration_s", "hypocentre_face", "hypocentre_x", "hypocentre_y",
           "hypocentre_z", "ruptured_area", "mean_slip_m", "peak_slip_m", "peak_slip_rate_m_s", "moment",
           "magnitude_mw", "injected_volume")


def moment_magnitude(m0: float) -> float:
    """M_w = (2/3)(log₁₀ M₀ − 9.1), M₀ in N·m (Hanks and Kanamori 1979)."""
    return (2.0 / 3.0) * (np.log10(m0) - 9.1) if m0 > 0 else float("-inf")


@dataclass
class _Open:
    onset: float
    hypocentre: int
    slip: np.ndarray              # (faces of the fault,) slip since the onset, m
    ruptured: np.ndarray          # (faces of the fault,) bool
    peak_rate: float


@dataclass
class EventCatalogue:
    """Events per fault from the accepted sub-steps (:meth:`add`).

    Parameters
    ----------
    fracture : (n_ff,) fault index of each face;  names : fault names
    area : (n_ff,) |σ| (m² in 3D, m in 2D);  shear_modulus : (n_ff,) μ_s next to each face, Pa
    centroid : (n_ff, d) face centroids, m;  dim : 2 or 3;  threshold : m/s
    """

    fracture: np.ndarray
    names: tuple
    area: np.ndarray
    shear_modulus: np.ndarray
    centroid: np.ndarray
    dim: int
    threshold: float = SEISMIC_RATE
    events: list = field(default_factory=list)
    aseismic_moment: np.ndarray | None = None
    _open: dict = field(default_factory=dict)

    def __post_init__(self):
        self.aseismic_moment = np.zeros(len(self.names))
        self.seismic_moment = 0.0           # of all events so far, the running ones' slip included
        self.injected = 0.0                 # ΔV since the start: m³ (m² per metre in 2D)
        self._faces = [np.flatnonzero(self.fracture == j) for j in range(len(self.names))]
        self._rows: list = []               # the series: (t, ΔV, seismic M₀, aseismic M₀, peak rate per fault...)

    def add(self, t0: float, t1: float, rate: np.ndarray, slip: np.ndarray, injected: float = 0.0) -> None:
        """An accepted sub-step t0 → t1 (s) with face slip rates ``rate`` and slip increments
        ``slip`` (n_ff,), m/s and m, and the volume injected in it (m³; m² per metre in 2D)."""
        self.injected += injected
        peaks = []
        for j, faces in enumerate(self._faces):
            v, s = rate[faces], slip[faces]
            peaks.append(float(v.max()) if faces.size else 0.0)
            fast = v > self.threshold
            ev = self._open.get(j)
            if ev is None and fast.any():
                i = int(np.argmax(np.where(fast, v, -np.inf)))
                ev = self._open[j] = _Open(t0, int(faces[i]), np.zeros(len(faces)), np.zeros(len(faces), bool), 0.0)
            dm = float(np.sum(self.shear_modulus[faces] * self.area[faces] * s))
            if ev is None:
                self.aseismic_moment[j] += dm
                continue
            self.seismic_moment += dm
            ev.slip += s
            ev.ruptured |= fast
            ev.peak_rate = max(ev.peak_rate, float(v.max()))
            if not fast.any():
                self._close(j, t1)
        self._rows.append((t1, self.injected, self.seismic_moment, float(self.aseismic_moment.sum()), *peaks))

    def series(self) -> dict:
        """The sub-steps' series: ``time`` (s), ``injected_volume`` (m³; m² per metre in 2D),
        ``seismic_moment`` and ``aseismic_moment`` (cumulative, N·m; per metre in 2D) and
        ``peak_slip_rate`` {fault: (n,) m/s}, each over the accepted sub-steps."""
        a = np.array(self._rows, float).reshape(-1, 4 + len(self.names))
        return {"time": a[:, 0], "injected_volume": a[:, 1], "seismic_moment": a[:, 2], "aseismic_moment": a[:, 3],
                "peak_slip_rate": {n: a[:, 4 + j] for j, n in enumerate(self.names)}}

    def write_series(self, path: Path) -> None:
        """seismicity.csv: one row per accepted sub-step (:meth:`series`)."""
        import io

        buf = io.StringIO()
        w = csv.writer(buf)
        w.writerow(["time_s", "injected_volume", "seismic_moment", "aseismic_moment",
                    *(f"peak_slip_rate_{n}" for n in self.names)])
        w.writerows([f"{v:.9g}" for v in row] for row in self._rows)
        atomic_write_text(path, buf.getvalue())

    def _close(self, j: int, end: float) -> None:
        ev = self._open.pop(j)
        faces = self._faces[j]
        a, mu = self.area[faces], self.shear_modulus[faces]
        m0 = float(np.sum(mu * a * ev.slip))
        rup = ev.ruptured
        area = float(a[rup].sum())
        x = np.zeros(3)
        x[:self.dim] = self.centroid[ev.hypocentre]
        self.events.append({
            "fault": self.names[j], "onset_s": ev.onset, "end_s": end, "duration_s": end - ev.onset,
            "hypocentre_face": int(np.searchsorted(faces, ev.hypocentre)), "hypocentre_x": float(x[0]),
            "hypocentre_y": float(x[1]), "hypocentre_z": float(x[2]) if self.dim == 3 else None,
            "ruptured_area": area, "mean_slip_m": float(np.sum(a[rup] * ev.slip[rup]) / area) if area > 0 else 0.0,
            "peak_slip_m": float(ev.slip.max()), "peak_slip_rate_m_s": ev.peak_rate, "moment": m0,
            "magnitude_mw": moment_magnitude(m0) if self.dim == 3 else None, "injected_volume": self.injected})

    def finish(self, end: float) -> None:
        """Close the events still running at the end of the run (their end is the run's)."""
        for j in list(self._open):
            self._close(j, end)

    def write(self, path: Path) -> None:
        """The catalogue as CSV (one row per event, COLUMNS; empty values where not defined)."""
        import io

        buf = io.StringIO()
        w = csv.writer(buf)
        w.writerow(COLUMNS)
        for e in self.events:
            w.writerow(["" if e[c] is None else (f"{e[c]:.9g}" if isinstance(e[c], float) else e[c]) for c in COLUMNS])
        atomic_write_text(path, buf.getvalue())

    def summary(self) -> dict:
        """summary.json's block: the threshold, the events' count and largest size, the aseismic
        moment per fault, and the units."""
        units = "N·m" if self.dim == 3 else "N·m per metre of strike (2D)"
        big = max(self.events, key=lambda e: e["moment"]) if self.events else None
        return {"threshold_m_s": self.threshold, "events": len(self.events), "moment_units": units,
                "injected_volume": self.injected, "seismic_moment": self.seismic_moment,
                "largest": None if big is None else {k: big[k] for k in ("fault", "onset_s", "moment", "magnitude_mw")},
                "aseismic_moment": {n: float(m) for n, m in zip(self.names, self.aseismic_moment, strict=True)}}
