"""Fuzz polypore's inputs (issue 25): case-file value mutations (tests/casefuzz.py) and GRDECL files,
Gmsh .msh files, the TOML text of case files and file-system faults around a run
(tests/inputfuzz.py), each example with a 60 s hang detector and an expected verdict. Prints per
family the examples, successes, input errors, run failures, tracebacks, hangs, silent acceptances
(a broken input that set up), false refusals and bad messages, then the 5 slowest examples; every
bug is reported (the first ones in full) and the run goes on, unless --stop.

    python benchmarks/fuzz_inputs.py [--examples 10000] [--seed 0] [--families case,grdecl,msh,toml,fs]
                                     [--weights case=50,grdecl=15,msh=12,toml=10,fs=13] [--stop]

(benchmarks/fuzz_casefiles.py is the case-file family alone, with its input errors by field.)
"""

from __future__ import annotations

import argparse
import collections
import logging
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from hypothesis import HealthCheck, given, seed, settings  # noqa: E402

import inputfuzz  # noqa: E402

WEIGHTS = "case=50,grdecl=15,msh=12,toml=10,fs=13"
COLUMNS = ("examples", "ok", "input", "failed", "traceback", "hang", "silent acceptance", "false refusal",
           "bad message")


class Stop(Exception):
    pass


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--examples", type=int, default=10_000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--families", default=",".join(inputfuzz.FAMILIES))
    ap.add_argument("--weights", default=WEIGHTS, help="relative weights (default: %(default)s)")
    ap.add_argument("--stop", action="store_true", help="stop at the first bug")
    ap.add_argument("--hang-seconds", type=float, default=inputfuzz.HANG_SECONDS)
    args = ap.parse_args(argv)
    families = tuple(args.families.split(","))
    inputfuzz.HANG_SECONDS = args.hang_seconds
    weights = {k: int(v) for k, v in (kv.split("=") for kv in args.weights.split(","))}
    logging.getLogger("polypore").setLevel(logging.CRITICAL)
    t0 = time.perf_counter()
    inputfuzz.warm_up(families)
    print(f"warm-up (base files, coarse meshes): {time.perf_counter() - t0:.1f} s")
    stats = {f: collections.Counter() for f in families}
    slow, bugs = [], []
    root = Path(tempfile.mkdtemp(prefix="polypore-fuzz-"))

    def one(ex):
        v = inputfuzz.run_example(ex, root)
        c = stats[ex.family]
        c["examples"] += 1
        c[v.outcome if v.outcome in COLUMNS else "ok"] += 1
        for p in v.problems:
            if p not in ("hang", "traceback"):    # counted as outcomes
                c[p.split(":")[0]] += 1
        slow.append((v.seconds, ex.family, ex.what, v.outcome))
        slow.sort(key=lambda r: -r[0])
        del slow[5:]
        if v.problems and v.problems != ["no-fault"]:
            bugs.append((ex, v))
            if len(bugs) <= 20:
                print(f"BUG [{ex.family}] {ex.what[:200]} (expected {ex.expect}, got {v.outcome}): {v.problems}\n"
                      f"    {v.detail.strip()[-1500:]}", flush=True)
            if args.stop:
                raise Stop

    # each family its share of the examples, drawn kind by kind (an equal part each): hypothesis,
    # left to pick the kinds, spends its examples on the kinds with the most variants (the position
    # of a NUL byte) once the small ones are exhausted. A kind with fewer distinct examples than
    # its part is run whole and the rest goes to the others (each example is distinct).
    total_w = sum(weights.get(f, 1) for f in families)
    share = {f: round(args.examples * weights.get(f, 1) / total_w) for f in families}
    share[families[0]] += args.examples - sum(share.values())

    def draw(strategy, n, k):
        run = seed(args.seed + k)(settings(max_examples=n, database=None, deadline=None, phases=["generate"],
                                           suppress_health_check=list(HealthCheck))(given(strategy)(one)))
        run()

    t0 = time.perf_counter()
    # the case-file family last: it takes what the others could not use (all their distinct examples run)
    order = sorted(families, key=lambda f: inputfuzz.KINDS[f] is None)
    try:
        for f in order:
            t1 = time.perf_counter()
            kinds = inputfuzz.KINDS[f]
            if kinds is None:
                n = args.examples - sum(stats[g]["examples"] for g in families if g != f)
                draw(inputfuzz.STRATEGIES[f](), n, 0)
            else:
                active, rnd = list(kinds), 0
                while stats[f]["examples"] < share[f] and active:
                    for kind in list(active):
                        left = share[f] - stats[f]["examples"]
                        if left <= 0:
                            break
                        ask = min(left, max(1, left // len(active)))
                        before = stats[f]["examples"]
                        draw(inputfuzz.STRATEGIES[f](kinds=(kind,)), ask, 1000 * rnd)
                        if stats[f]["examples"] - before < ask:
                            active.remove(kind)          # every distinct example of the kind was run
                    rnd += 1
            print(f"{f}: {stats[f]['examples']} examples in {time.perf_counter() - t1:.1f} s", flush=True)
    except Stop:
        print("stopped at the first bug (--stop)")
    total = time.perf_counter() - t0
    n = sum(c["examples"] for c in stats.values())
    print(f"\n{n} examples in {total:.1f} s ({1e3 * total / max(n, 1):.1f} ms each), pid {os.getpid()}")
    width = max(len(f) for f in families + ("total",))
    print(f"{'family':<{width}}  " + "  ".join(f"{c:>8}" if len(c) <= 8 else c for c in COLUMNS))
    tot = collections.Counter()
    for f in families:
        tot.update(stats[f])
        print(f"{f:<{width}}  " + "  ".join(f"{stats[f][c]:>{max(8, len(c))}}" for c in COLUMNS))
    print(f"{'total':<{width}}  " + "  ".join(f"{tot[c]:>{max(8, len(c))}}" for c in COLUMNS))
    print("slowest examples:")
    for dt, fam, what, kind in slow:
        print(f"  {dt:6.2f} s  [{fam}] {kind}: {what[:160]}")
    if len(bugs) > 20:
        print(f"... and {len(bugs) - 20} more bugs")
    inputfuzz._rmtree(root)
    return 1 if bugs else 0


if __name__ == "__main__":
    sys.exit(main())
