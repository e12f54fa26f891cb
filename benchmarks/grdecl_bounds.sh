#!/usr/bin/env bash
# Injection runs on the faulted grids of /work/shared/data/grdecl/ (except Emerald: its case is
# the built-in emerald-injection) and benchmarks/fault_bounds.py on them, one after the other.
#
#     benchmarks/grdecl_bounds.sh [OUT_DIR]        # default results/grdecl-bounds
#     PYTHON=/path/to/python benchmarks/grdecl_bounds.sh ...   # default: python3 (polypore importable)
#
# The cases are benchmarks/cases/grdecl-*.toml (absolute paths to the shared grids). Each run goes
# to OUT_DIR/<case>/ (its log in OUT_DIR/<case>.log, wall time and peak memory from `time -v` when
# /usr/bin/time exists); the bounds are printed and written to OUT_DIR/fault_bounds.json.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
out="${1:-results/grdecl-bounds}"
py="${PYTHON:-python3}"
mkdir -p "$out"
runs=()
for case in "$here"/cases/grdecl-*.toml; do
    name="$(basename "$case" .toml)"
    echo "== $name"
    timer=()
    [ -x /usr/bin/time ] && timer=(/usr/bin/time -v)
    if "${timer[@]}" "$py" -m polypore run "$case" --out "$out/$name" --force > "$out/$name.log" 2>&1; then
        grep -E "^case |Elapsed \(wall|Maximum resident" "$out/$name.log" || true
        runs+=("$out/$name")
    else
        echo "   FAILED (see $out/$name.log):"; tail -3 "$out/$name.log"
    fi
done
[ ${#runs[@]} -gt 0 ] && "$py" "$here/fault_bounds.py" "${runs[@]}" --json "$out/fault_bounds.json"
