"""The Python blocks of README.md and docs/*.md run as written, each in a fresh folder as a new
user pastes them after `pip install ./python` (tests/docs_blocks.rs runs the shell blocks)."""

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
FENCE = re.compile(r"^```python\n(.*?)^```$", re.MULTILINE | re.DOTALL)


def python_blocks():
    for doc in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        text = doc.read_text()
        for match in FENCE.finditer(text):
            line = text.count("\n", 0, match.start()) + 1
            yield pytest.param(match.group(1), id=f"{doc.relative_to(REPO)}:{line}")


BLOCKS = list(python_blocks())


def test_readme_has_a_python_block():
    assert BLOCKS, "README.md shows the module in a python block"


@pytest.mark.parametrize("code", BLOCKS)
def test_python_block_runs_as_written(code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "<block>", "exec"), {"__name__": "__main__"})
