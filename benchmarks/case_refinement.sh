#!/usr/bin/env bash
# A case on its grid and on its 2x2x2 corner-point refinement (mesh.refine), then the poroelastic
# bounds and the refinement comparison of every fault (slip on the coarse faces, potency;
# benchmarks/fault_bounds.py --refinement; issue 24, docs/fault_bounds.md).
#   bash benchmarks/case_refinement.sh CASE [OUT] [--set KEY=VALUE ...]
# e.g. bash benchmarks/case_refinement.sh benchmarks/cases/grdecl-b.toml /tmp/b-refinement
set -euo pipefail
cd "$(dirname "$0")/.."
case=${1:?usage: case_refinement.sh CASE [OUT] [--set KEY=VALUE ...]}; shift
out=${1:-results/case-refinement}; shift || true
py=${PYTHON:-.venv-fast/bin/python}
for r in "1, 1, 1" "2, 2, 2"; do
  tag=r$(echo "$r" | tr -d ', ')
  /usr/bin/time -f "$tag: %e s wall, %M KB peak" "$py" -m polypore run "$case" --out "$out/$tag" --force \
    --set "mesh.refine=[$r]" "$@"
done
"$py" benchmarks/fault_bounds.py "$out"/r111 "$out"/r222 --refinement --json "$out/refinement.json"
