"""Plot Newton and GMRES iterations per step of the partial C5 runs (docs/c5_46k_block_partial.json).

    .venv/bin/python benchmarks/c5_partial_plot.py      # → docs/c5_46k_block_partial.png

The JSON holds the per-step lines of the logs of two stopped 46k-tetrahedra runs (block-amg
solver, one- and two-sided bubbles); completed runs are tabulated by benchmarks/c5_table.py.
"""

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

src = Path("docs/c5_46k_block_partial.json")
data = json.loads(src.read_text())["runs"]
fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
for name, run in data.items():
    t = [s["time"] for s in run["steps"]]
    a1.plot(t, [s["newton_iterations"] for s in run["steps"]], "o-", ms=3, label=f"46k {name}")
    a2.plot(t, [s["gmres_iterations"] / s["newton_iterations"] for s in run["steps"]], "o-", ms=3,
            label=f"46k {name}")
    cut = [s["time"] for s in run["steps"] if s["failed_attempts_before"]]
    a1.plot(cut, [0.5] * len(cut), "x", color=a1.lines[-1].get_color())
for a, lab in ((a1, "Newton iterations per time step (x: step cut)"), (a2, "mean GMRES iterations per Newton step")):
    a.axvline(50.0, color="0.5", ls=":", lw=0.8)
    a.set_xlabel("t (s)")
    a.set_ylabel(lab)
    a.grid(alpha=0.3)
    a.legend(fontsize=8)
a1.set_ylim(bottom=0)
a2.set_ylim(bottom=0)
fig.suptitle("C5 (dfm-3d), 46 153 tetrahedra, block-amg solver: first 29–30 of 50 steps", fontsize=10)
fig.tight_layout()
fig.savefig("docs/c5_46k_block_partial.png", dpi=120)
print("wrote docs/c5_46k_block_partial.png")
