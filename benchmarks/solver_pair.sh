#!/usr/bin/env bash
# A case run with PARDISO and with an iterative solver, back to back, same venv (issue 26:
# "emerald-injection: the iterative path within 1.2x PARDISO's CPU time and below its memory; same
# states and λ_n"). Prints each run's wall, CPU (user + sys) and peak memory, the CPU ratio, and the
# largest λ_n difference over every fault face and output. Needs PARDISO (.venv-fast). Run it on a
# quiet machine: one heavy job at a time.
#   bash benchmarks/solver_pair.sh [CASE] [SOLVER] [--set KEY=VALUE ...]
#   defaults: emerald-injection block-direct
set -euo pipefail
cd "$(dirname "$0")/.."
case_=${1:-emerald-injection}; solver=${2:-block-direct}; shift $(( $# > 2 ? 2 : $# ))
py=${PYTHON:-.venv-fast/bin/python}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for s in pardiso "$solver"; do
  PYTHONPATH=src /usr/bin/time -f "%e %U %S %M" -o "$tmp/$s.time" \
    "$py" -m polypore run "$case_" --set solver.linear="$s" "$@" --out "$tmp/$s" >"$tmp/$s.log" 2>&1 \
    || { echo "$s failed:"; tail -5 "$tmp/$s.log"; exit 1; }
  grep "^case " "$tmp/$s.log"
done
"$py" - "$tmp" pardiso "$solver" <<'PY'
import csv, sys
tmp, a, b = sys.argv[1:]
t = {}
for s in (a, b):
    wall, user, sys_, kb = open(f"{tmp}/{s}.time").read().split()[-4:]
    t[s] = (float(wall), float(user) + float(sys_), int(kb) / 1024)
    print(f"{s:>14}: {t[s][0]:.1f} s wall, {t[s][1]:.1f} s CPU, {t[s][2]:.0f} MB peak")
print(f"CPU ratio {b}/{a}: {t[b][1] / t[a][1]:.2f}; memory ratio {t[b][2] / t[a][2]:.2f}")
ra, rb = (list(csv.DictReader(open(f"{tmp}/{s}/fractures.csv"))) for s in (a, b))
same = len(ra) == len(rb) and all(p["state"] == q["state"] for p, q in zip(ra, rb))
dl = max((abs(float(p["lambda_n"]) - float(q["lambda_n"])) for p, q in zip(ra, rb)), default=0.0)
scale = max((abs(float(p["lambda_n"])) for p in ra), default=0.0)
print(f"same contact states at every output: {same}; largest |Δλ_n| {dl:.3g} Pa of {scale:.3g} Pa")
PY
