"""The command line's modules: the parser loads no model (``rdgpu --help`` stays fast), the
commands import rdgpu at module level (no cycle back to the parser), and the domain is
described through the Domain protocol."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np

import rdgpu.cli
from rdgpu.cli.checks import describe_domain, is_grid_3d
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid

CLI = Path(rdgpu.cli.__file__).parent
#: the imports of rdgpu inside functions that the command line keeps, each for a reason
#: written beside it (here: the --param parser of `rdgpu sweep`, loaded at parse time)
LAZY = {("options.py", "parse_sweep_param", "rdgpu.runs.sweep")}


def _imports(tree: ast.AST) -> list[tuple[str, str | None]]:
    """``(module, enclosing function or None)`` of every import of an rdgpu module."""
    out = []

    def visit(node: ast.AST, function: str | None) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                visit(child, child.name)
                continue
            if isinstance(child, ast.ImportFrom) and (child.module or "").startswith("rdgpu"):
                out.append((child.module, function))
            elif isinstance(child, ast.Import):
                out.extend((a.name, function) for a in child.names
                           if a.name.startswith("rdgpu"))
            visit(child, function)

    visit(tree, None)
    return out


def test_rdgpu_is_imported_at_module_level_and_nothing_imports_the_parser():
    for path in sorted(CLI.glob("*.py")):
        for module, function in _imports(ast.parse(path.read_text())):
            if function is not None:
                assert (path.name, function, module) in LAZY, (path.name, function, module)
            if path.name not in ("__init__.py", "__main__.py"):
                assert module != "rdgpu.cli.app", f"{path.name} imports the parser"


def test_help_loads_neither_the_models_nor_the_simulation():
    code = ("import sys\nfrom rdgpu.cli import main\n"
            "assert main(['--help']) == 0 and main(['run', '--help']) == 0\n"
            "assert main(['sweep', '--help']) == 0\n"
            "heavy = [m for m in ('rdgpu.models', 'rdgpu.simulation', 'rdgpu.cli.run')"
            " if m in sys.modules]\n"
            "assert not heavy, heavy\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr


def test_domains_in_words():
    assert describe_domain(Grid((32, 48), dx=0.5)) == "32x48 grid (dx=0.5, periodic)"
    bc = ("neumann", ("dirichlet", 1.0), "periodic")
    assert describe_domain(Grid((4, 5, 6), bc=bc)) == \
        "4x5x6 grid (dx=1, neumann/dirichlet/periodic)"
    assert describe_domain(Grid((60,))) == "1-D grid of 60 cells (dx=1, periodic)"
    surface = GraphSurface((8, 8), dx=0.25, height=np.zeros((8, 8)))
    assert describe_domain(surface) == "graph surface over a 8x8 grid (dx=0.25)"
    assert is_grid_3d(Grid((4, 5, 6))) and not is_grid_3d(surface)
