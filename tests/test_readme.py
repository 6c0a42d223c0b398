"""Every Python snippet in the README and in the documentation pages (docs/**/*.md) runs as
written (each in a fresh interpreter, in an empty folder, so a snippet cannot lean on an
earlier one or on files of the repository). Blocks that only illustrate (output, shell
commands) are ```text or ```bash, never ```python."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import rdgpu

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").rglob("*.md"))]
PYTHON_BLOCK = re.compile(r"```python\n(.*?)```", flags=re.S)


def snippets(path: Path) -> list[str]:
    return PYTHON_BLOCK.findall(path.read_text(encoding="utf-8"))


SNIPPETS = [(p.relative_to(ROOT).as_posix(), i, code)
            for p in PAGES for i, code in enumerate(snippets(p))]


def test_readme_has_snippets():
    """The short README keeps three: the functional API, a model of your own, a sphere."""
    assert len(snippets(README)) >= 3


def test_docs_have_snippets():
    assert sum(1 for page, _, _ in SNIPPETS if page.startswith("docs/")) >= 10


@pytest.mark.slow
@pytest.mark.parametrize(("page", "index", "code"), SNIPPETS,
                         ids=[f"{page}:{i}" for page, i, _ in SNIPPETS])
def test_snippet_runs(page, index, code, tmp_path):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(Path(rdgpu.__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, (f"{page}, python block {index} failed:\n{code}\n"
                                  f"--- stderr:\n{proc.stderr[-3000:]}")
