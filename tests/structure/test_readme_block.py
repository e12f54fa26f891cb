"""README's "Using it" block can be pasted twice in a row (issue 25): every command that writes a
result folder names its own --out and passes --force (benchmarks/readme_newcomer.sh runs it twice)."""

import re
import shlex
from pathlib import Path

README = Path(__file__).resolve().parents[2] / "README.md"


def block_lines():
    text = README.read_text()
    using = text[text.index("## Using it"):]
    block = re.search(r"```\n(.*?)```", using, flags=re.S).group(1)
    return [line.split("#")[0].strip() for line in block.splitlines() if line.strip()]


def test_readme_first_lines_are_kept():
    assert README.read_text().startswith("# polypore\n\n```\nmake demo   #")
    assert "\nmake test   #" in README.read_text()[:400]


def test_every_result_writing_line_has_its_own_out_and_force():
    outs = []
    for line in block_lines():
        words = shlex.split(line)
        if words[:1] != ["polypore"] or words[1] not in ("run", "mesh", "convergence"):
            continue
        assert "--force" in words, line
        assert "--out" in words, line
        outs.append(words[words.index("--out") + 1])
    assert len(outs) >= 12 and len(set(outs)) == len(outs)           # no two lines share a folder
    dfm3d = [l for l in block_lines() if "dfm-3d" in l]
    assert len(dfm3d) == 2 and all("--force" in l for l in dfm3d)
