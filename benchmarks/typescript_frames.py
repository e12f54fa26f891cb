"""Turn a terminal capture (``script -q -f -c "polypore run ..." FILE``) into text for
docs/live_progress.md: the log lines as they stay on the screen, and the live status line's frames
(each redraw is "\\r\\x1b[K" + the line), one every ``--every`` seconds of run time, each shown
where it stood between the log lines.

    python benchmarks/typescript_frames.py FILE [--every 10]
"""

from __future__ import annotations

import argparse
import re

ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")
RUN = re.compile(r"run (?:(\d+) h )?(?:(\d+) min )?(\d+) s")


def run_seconds(frame: str) -> float | None:
    m = RUN.search(frame)
    if not m:
        return None
    h, mi, s = (int(x) if x else 0 for x in m.groups())
    return 3600 * h + 60 * mi + s


def frames(text: str, every: float):
    """Yields ("log", line) and ("live", frame) in the order of the capture."""
    last = -1e9
    pending = None
    for chunk in re.split(r"(\r\x1b\[K|\n)", text):
        if chunk in ("\r\x1b[K", "\n") or not chunk.strip():
            continue
        clean = ANSI.sub("", chunk).replace("\r", "").rstrip()
        if not clean:
            continue
        if " · run " in clean or clean.startswith(("working", "meshing")):
            t = run_seconds(clean)
            pending = clean
            if t is not None and t - last >= every:
                yield "live", clean
                last, pending = t, None
        else:
            if clean.startswith(("Script started", "Script done")):
                continue
            yield "log", clean


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("file")
    ap.add_argument("--every", type=float, default=10.0)
    args = ap.parse_args()
    text = open(args.file, encoding="utf-8", errors="replace").read()
    for kind, line in frames(text, args.every):
        print(("  live │ " if kind == "live" else "       ") + line)


if __name__ == "__main__":
    main()
