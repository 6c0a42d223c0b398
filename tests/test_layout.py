"""The tests' layout (issue 20, rule 6): no file under tests/ imports or loads anything from
perf/ or examples/.  What a test needs of a study or a benchmark lives in the package
(``rdgpu.analysis.convergence``, ``rdgpu.analysis.pinning``,
``rdgpu.analysis.rough_patterns``, ``rdgpu.backends.reduce_timing``), which the scripts
import too, or, where only tests need it, in a helper module at tests/ top level
(``toy_model.py``).

The scan reads the sources (nothing is imported): an ``import`` of ``perf``, ``examples``
or of a script's name; a loader (``spec_from_file_location``, ``SourceFileLoader``,
``runpy.run_path``, ``import_module``, ``repo_module``) or a ``sys.path`` change whose
arguments name those folders; and any string of code (not a docstring) holding a path
into them, which also catches the code of child processes and paths built first.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests"
FOLDERS = ("perf", "examples")
#: the names a script of those folders is importable by once its folder is on sys.path
SCRIPTS = {p.stem for f in FOLDERS for p in (ROOT / f).glob("*.py")}
#: the tests' own helper modules (``import toy_model``) are not scripts of those folders
HELPERS = {p.stem for p in TESTS.glob("*.py")}
LOADERS = {"spec_from_file_location", "SourceFileLoader", "run_path", "run_module",
           "import_module", "repo_module"}
PATH_CHANGES = {"insert", "append", "extend"}
#: a path into one of the folders, or the folder's bare name as a path component
NAMES_A_FOLDER = re.compile(r"(^|[/\\'\"\s])(perf|examples)([/\\'\"]|$)")


def _docstrings(tree: ast.AST) -> set[int]:
    """ids of the string constants that are docstrings."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                out.add(id(body[0].value))
    return out


def _name_of(func: ast.expr) -> str:
    """The called name: ``f`` of ``f(...)`` or ``a.b.f(...)``."""
    if isinstance(func, ast.Attribute):
        return func.attr
    return func.id if isinstance(func, ast.Name) else ""


def offences(source: str) -> list[str]:
    """What in ``source`` (a test file's text) imports or loads from perf/ or examples/."""
    tree = ast.parse(source)
    found = []
    scripts = (SCRIPTS | set(FOLDERS)) - HELPERS
    docstrings = _docstrings(tree)
    for node in ast.walk(tree):
        line = getattr(node, "lineno", 0)
        if isinstance(node, ast.Import):
            found += [f"line {line}: import {a.name}" for a in node.names
                      if a.name.split(".")[0] in scripts]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 \
                and (node.module or "").split(".")[0] in scripts:
            found.append(f"line {line}: from {node.module} import ...")
        elif isinstance(node, ast.Call):
            name = _name_of(node.func)
            text = ast.unparse(node) if name in LOADERS | PATH_CHANGES else ""
            if name == "repo_module":
                found.append(f"line {line}: repo_module(...)")
            elif name in LOADERS and re.search(r"\b(perf|examples)\b", text):
                found.append(f"line {line}: {name}(...) on perf/ or examples/")
            elif name in PATH_CHANGES and "sys.path" in text \
                    and re.search(r"\b(perf|examples)\b", text):
                found.append(f"line {line}: sys.path.{name}(...) with perf/ or examples/")
        elif isinstance(node, ast.FunctionDef) and node.name == "repo_module":
            found.append(f"line {line}: def repo_module")
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) \
                and id(node) not in docstrings:
            if NAMES_A_FOLDER.search(node.value):
                found.append(f"line {line}: a path into perf/ or examples/: {node.value[:60]!r}")
            found += [f"line {line}, code in a string: {o}" for o in _code_offences(node.value)]
    return found


def _code_offences(text: str) -> list[str]:
    """:func:`offences` of a string that is Python code importing something (a child
    process's code, its ``str.format`` fields read as names); none for any other string."""
    if "import" not in text:
        return []
    text = re.sub(r"\{[^{}]*\}", "_", text)
    try:
        tree = ast.parse(text)
    except (SyntaxError, ValueError):
        return []
    if not any(isinstance(n, (ast.Import, ast.ImportFrom)) for n in ast.walk(tree)):
        return []
    return offences(text)


def test_no_test_imports_or_loads_perf_or_examples():
    """Every file under tests/ but this one (which names the folders to look for them)."""
    me = Path(__file__).resolve()
    bad = {str(p.relative_to(ROOT)): off for p in sorted(TESTS.rglob("*.py"))
           if p.resolve() != me and (off := offences(p.read_text(encoding="utf-8")))}
    assert not bad, f"tests must not import or load perf/ or examples/ (issue 20, rule 6): {bad}"


def test_the_scan_finds_each_way_in():
    """Each way a test could reach a script is found; docstrings and the package are not."""
    assert SCRIPTS >= {"bdf2_order", "reduce", "seed000_study", "metric"}
    ways = [
        "import bdf2_order",
        "from perf.reduce import measure",
        "from examples import seed002_roughness",
        "STUDY = repo_module('examples/seed002_roughness.py')",
        "import importlib.util\n"
        "spec = importlib.util.spec_from_file_location('r', ROOT / 'perf' / 'reduce.py')",
        "import runpy\nrunpy.run_path(str(ROOT / 'examples' / 'gallery.py'))",
        "import sys\nsys.path.insert(0, str(ROOT / 'perf'))",
        "CHILD = 'import sys; sys.path.insert(0, \"perf\"); import reduce'",
        'CHILD = """\nimport sys\nsys.path.insert(0, {root!r} + "/x")\nimport metric\n"""',
        "script = 'perf/surface_rds.py'",
    ]
    for code in ways:
        assert offences(code), code
    fine = ['"""Seed 000\'s study (``examples/seed000_study.py``, ``perf/reduce.py``)."""\n'
            "from rdgpu.analysis.pinning import run_case\n"
            "import toy_model\n"
            "import importlib\nimportlib.import_module('rdgpu.growth.dla')\n"
            "import sys\nsys.path.insert(0, str(ROOT))\n"]
    for code in fine:
        assert not offences(code), offences(code)
