#!/usr/bin/env bash
# emerald-injection on its grid and on its 2x2x1 and 2x2x2 refinements (mesh.refine), then the
# poroelastic bounds and the slipping area per fault of each (benchmarks/fault_bounds.py; issue 24,
# docs/fault_bounds.md). Needs PARDISO (.venv-fast: `make .venv-fast/.installed`): the 2x2x2 run has
# ~440k unknowns (8 GB, about 20 minutes on a quiet 2-core machine).
#   bash benchmarks/emerald_refinement.sh [OUT] [--set KEY=VALUE ...]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-results/emerald-refinement}; shift || true
py=${PYTHON:-.venv-fast/bin/python}
for r in "1, 1, 1" "2, 2, 1" "2, 2, 2"; do
  tag=r$(echo "$r" | tr -d ', ')
  /usr/bin/time -f "$tag: %e s wall, %M KB peak" "$py" -m polypore run emerald-injection --out "$out/$tag" --force \
    --set "mesh.refine=[$r]" "$@"
done
"$py" benchmarks/fault_bounds.py "$out"/r111 "$out"/r221 "$out"/r222 --json "$out/bounds.json"
