"""Every ```python block of the README and docs/*.md runs (examples in the docs are tests)."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FILES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
BLOCKS = [(f, k, code) for f in FILES
          for k, code in enumerate(re.findall(r"```python\n(.*?)```", f.read_text(), flags=re.S))]


def test_the_docs_have_examples():
    names = {f.name for f, _, _ in BLOCKS}
    assert {"contact.md", "flow.md", "poromechanics.md"} <= names


@pytest.mark.parametrize("path,k,code", BLOCKS, ids=[f"{f.name}[{k}]" for f, k, _ in BLOCKS])
def test_doc_example_runs(path, k, code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(code, f"{path.name}[{k}]", "exec"), {"__name__": "__doc_example__"})
