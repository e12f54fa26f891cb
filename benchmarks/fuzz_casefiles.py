"""Fuzz the case files: 10,000 random mutations of the built-in cases and of ``--set`` overrides
(tests/casefuzz.py) through load and set-up; prints the outcomes (successes, input errors by
field), the slowest examples and any other exception (a bug: the run stops at the first).

    python benchmarks/fuzz_casefiles.py [--examples 10000] [--seed 0] [--actions nudge,set,...]
"""

from __future__ import annotations

import argparse
import collections
import logging
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from hypothesis import HealthCheck, given, seed, settings  # noqa: E402

from casefuzz import ACTIONS, NAMES, _mesh, base_case, mutated_cases, names_a_field, outcome  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--examples", type=int, default=10_000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--actions", default=",".join(ACTIONS), help="mutations to draw from (default: %(default)s)")
    args = ap.parse_args(argv)
    logging.getLogger("polypore").setLevel(logging.ERROR)   # set-up warnings (mirror with one-sided bubbles)
    for name in NAMES:                     # the coarse meshes, outside the timings
        _mesh(base_case(name))
    counts, fields, slow = collections.Counter(), collections.Counter(), []

    @seed(args.seed)
    @settings(max_examples=args.examples, database=None, deadline=None, phases=["generate"],
              suppress_health_check=list(HealthCheck))
    @given(mutated_cases(tuple(args.actions.split(","))))
    def run(example):
        case, what = example
        t0 = time.perf_counter()
        kind, field = outcome(case)
        dt = time.perf_counter() - t0
        slow.append((dt, what, kind, field))
        slow.sort(key=lambda r: -r[0])
        del slow[5:]
        counts[kind] += 1
        if kind == "input":
            if not names_a_field(field, case):
                counts["input error naming no field"] += 1
                print(f"no field: {field!r} after {what}")
            fields[".".join(field.split(".")[:2]).split("[")[0]] += 1

    t0 = time.perf_counter()
    run()
    total = time.perf_counter() - t0
    n = counts["ok"] + counts["input"]
    print(f"{n} examples in {total:.1f} s ({1e3 * total / max(n, 1):.1f} ms each): {counts['ok']} set up, "
          f"{counts['input']} input errors, {counts['input error naming no field']} naming no field, 0 other "
          "exceptions")
    print("input errors by field (table.key):")
    for f, c in fields.most_common():
        print(f"  {c:6d}  {f}")
    print("slowest examples:")
    for dt, what, kind, field in slow:
        print(f"  {dt:6.2f} s  {kind}{f' ({field})' if field else ''}: {'; '.join(what)[:200]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
