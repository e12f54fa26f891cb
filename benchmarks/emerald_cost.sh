#!/usr/bin/env bash
# Cost of emerald-injection: an earlier revision against this checkout, back to back, same venv
# (issue 24: "unknowns and time within 1.3x today's"). Needs PARDISO (.venv-fast). Run it on a
# quiet machine: one heavy job at a time.
#   bash benchmarks/emerald_cost.sh [REV]      # default REV: d36a75a (before issue 24)
set -euo pipefail
cd "$(dirname "$0")/.."
rev=${1:-d36a75a}
py=${PYTHON:-.venv-fast/bin/python}
tmp=$(mktemp -d)
trap 'git worktree remove --force "$tmp/base" >/dev/null 2>&1 || true; rm -rf "$tmp"' EXIT
git worktree add -q --detach "$tmp/base" "$rev"
for v in base head; do
  src=$([ "$v" = base ] && echo "$tmp/base/src" || echo "$PWD/src")
  PYTHONPATH=$src /usr/bin/time -f "$v ($([ $v = base ] && echo "$rev" || git rev-parse --short HEAD)): %e s wall, %U s user, %S s sys, %M KB peak" \
    "$py" -m polypore run emerald-injection --out "$tmp/run-$v" --force 2>&1 | grep -E "^case |wall,"
done
