#!/usr/bin/env bash
# A newcomer's first session, exactly as the README says: a fresh clone, `make demo`, then the
# README's "Using it" block pasted twice in a row into the same clone (a second paste must succeed
# too: every line writes into its own --out folder with --force). Every command is timed; the
# script stops at the first command that fails and says in which pass.
#
#     bash benchmarks/readme_newcomer.sh [--skip REGEX] [--all] [REPO]    # REPO: default this checkout
#
# By default the lines matching 'dfm-3d' are left out (C5 at 46k and 127k cells: 15 and 55 min a
# pass); --all runs every line, --skip REGEX leaves out the lines matching REGEX (grep -E) instead.
# The lines left out are listed at the start and the end.
set -euo pipefail
skip="dfm-3d"
while [ $# -gt 0 ]; do
  case "$1" in
    --skip) skip="$2"; shift 2 ;;
    --all) skip=""; shift ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
    *) break ;;
  esac
done
repo=$(cd "${1:-$(dirname "$0")/..}" && pwd)
work=$(mktemp -d /tmp/polypore-newcomer-XXXXXX)
trap 'echo "clone kept in $work"' EXIT
git clone -q "$repo" "$work/polypore"
cd "$work/polypore"
awk '/^## Using it/{f=1} f&&/^```$/{n++; next} f&&n==1{print} n==2{exit}' README.md > "$work/block.sh"
if [ -n "$skip" ]; then
  grep -Ev -- "$skip" "$work/block.sh" > "$work/using.sh" || true
  grep -E -- "$skip" "$work/block.sh" > "$work/skipped.sh" || true
else
  cp "$work/block.sh" "$work/using.sh"; : > "$work/skipped.sh"
fi
if [ -s "$work/skipped.sh" ]; then
  echo "left out (--skip '$skip'):"; sed 's/^/    /' "$work/skipped.sh"
fi
t0=$(date +%s)
make demo > "$work/demo.log" 2>&1 || { tail -20 "$work/demo.log"; exit 1; }
echo "make demo: $(( $(date +%s) - t0 )) s"
for pass in 1 2; do
  echo "-- pass $pass: the README block pasted"
  tp=$(date +%s)
  while IFS= read -r line; do
    [ -z "$line" ] && continue
    cmd=${line%%#*}
    t=$(date +%s)
    if [[ $cmd == source* ]]; then
      eval "$cmd"
    else
      eval "$cmd" > "$work/cmd.log" 2>&1 || { echo "FAILED in pass $pass: $cmd"; tail -20 "$work/cmd.log"; exit 1; }
    fi
    printf '%5d s  %s\n' "$(( $(date +%s) - t ))" "$cmd"
  done < "$work/using.sh"
  echo "pass $pass: all $(grep -c . "$work/using.sh") lines passed in $(( $(date +%s) - tp )) s"
done
echo "both passes of the README block passed"
if [ -s "$work/skipped.sh" ]; then
  echo "not run (--skip '$skip'):"; sed 's/^/    /' "$work/skipped.sh"
fi
