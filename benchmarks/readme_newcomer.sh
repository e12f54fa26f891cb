#!/usr/bin/env bash
# A newcomer's first session, exactly as the README says: a fresh clone, `make demo`, then every
# command of the README's "Using it" block pasted in order (the dfm-3d lines left out: 15-55 min),
# each timed. Exits non-zero at the first command that fails.
#
#     bash benchmarks/readme_newcomer.sh [REPO]      # REPO defaults to this checkout
set -euo pipefail
repo=$(cd "${1:-$(dirname "$0")/..}" && pwd)
work=$(mktemp -d /tmp/polypore-newcomer-XXXXXX)
trap 'echo "clone kept in $work"' EXIT
git clone -q "$repo" "$work/polypore"
cd "$work/polypore"
t0=$(date +%s)
make demo > "$work/demo.log" 2>&1 || { tail -20 "$work/demo.log"; exit 1; }
echo "make demo: $(( $(date +%s) - t0 )) s"
awk '/^## Using it/{f=1} f&&/^```$/{n++; next} f&&n==1{print} n==2{exit}' README.md | grep -v "dfm-3d" > "$work/using.sh"
while IFS= read -r line; do
  [ -z "$line" ] && continue
  cmd=${line%%#*}
  t=$(date +%s)
  if [[ $cmd == source* ]]; then
    eval "$cmd"
  else
    eval "$cmd" > "$work/cmd.log" 2>&1 || { echo "FAILED: $cmd"; tail -20 "$work/cmd.log"; exit 1; }
  fi
  printf '%5d s  %s\n' "$(( $(date +%s) - t ))" "$cmd"
done < "$work/using.sh"
echo "all README commands passed"
