"""The layer contract of docs/architecture.md, checked on the source (tests/import_graph.py
reads the imports with :mod:`ast`; nothing is imported).

* every import of an rdgpu module goes to its own layer or a lower one;
* no import cycle between modules at import time (a shrinking known list), not even
  through the allowed lazy imports;
* imports of rdgpu modules inside functions only where :data:`LAZY_IMPORTS` says why;
* no relative imports; no module over 700 lines; no function over 100 lines
  (:data:`LONG_FUNCTIONS` lists the exceptions, each with its reason);
* outside ``rdgpu/backends/`` nothing compares a backend's name or reads its private
  members; outside ``rdgpu/domains/`` no ``isinstance`` on a domain class; no private name
  taken from another module;
* parameters holding a domain, a model or a backend name its type, not ``Any`` (counted
  per file).

What breaks a rule today is listed in :data:`KNOWN_VIOLATIONS`, one line each. A new
violation fails its test, and so does a listed one that is gone: the list only shrinks and
stays true. ``python -m tests.test_architecture`` prints the list as the code has it now,
and ``--write`` puts it in this file: after a merge, read its diff before committing it.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from tests import import_graph as ig

#: imports of rdgpu modules inside functions that serve the user, each with its reason
LAZY_IMPORTS: dict[str, str] = {
    "rdgpu.backends.registry -> rdgpu.backends.numpy_backend":
        "the registry builds a backend when it is first asked for (one factory each)",
    "rdgpu.backends.registry -> rdgpu.backends.warp_backend":
        "warp-lang loads only when the Warp backend is asked for; missing, it is a "
        "BackendUnavailableError",
    "rdgpu.backends.registry -> rdgpu.backends.opencl_backend":
        "pyopencl and PoCL load only when the OpenCL backend is asked for; missing, it is "
        "a BackendUnavailableError",
    "rdgpu -> rdgpu.io.display":
        "`import rdgpu` stays light: a notebook's picture of a Result loads matplotlib, "
        "imageio and the io layer only when a Result is shown",
    "rdgpu.cli.options -> rdgpu.runs.sweep":
        "`rdgpu --help` and every other command stay fast: rdgpu.runs.sweep loads the "
        "simulation and model layers (0.1-0.2 s), needed only to parse `rdgpu sweep --param`",
}

#: "<check>: <finding>" for every violation the code has today (see the module docstring)
KNOWN_VIOLATIONS: frozenset[str] = frozenset({
    # cycle (0)
    # upward (0)
    # lazy (0)
    # private (0)
    # long modules (0)
    # backend peeks (0)
    # domain isinstance (0)
    # any hints (0)
})


@pytest.fixture(scope="module")
def found() -> dict[str, set[str]]:
    return ig.findings()


@pytest.fixture(scope="module")
def imports() -> list[ig.Import]:
    return ig.scan()


def _compare(check: str, now: set[str], allowed: set[str] = frozenset()) -> None:
    known = {v.split(": ", 1)[1] for v in KNOWN_VIOLATIONS if v.startswith(check + ": ")}
    new = sorted(now - known - set(allowed))
    gone = sorted(known - now)
    lines = [f"new {check} (fix them; the rule is in docs/architecture.md):"] if new else []
    lines += [f"    {check}: {item}" for item in new]
    if gone:
        lines.append(f"fixed {check}: remove these lines from KNOWN_VIOLATIONS in "
                     "tests/test_architecture.py:")
        lines += [f"    {check}: {item}" for item in gone]
    assert not lines, "\n".join(lines)


def test_every_package_has_a_layer():
    for module in ig.module_files():
        ig.layer_of(module)  # KeyError names a package missing from LAYERS


def test_imports_go_down_the_layers(found):
    _compare("upward", found["UPWARD"])


def test_no_import_cycles_at_import_time(found):
    # a cycle: the modules of one strongly connected component, sorted (the packages a
    # module's import runs first count: importing rdgpu.a.b runs rdgpu/a/__init__.py)
    _compare("cycle", found["CYCLES"])


def test_allowed_lazy_imports_close_no_cycle(imports, found):
    imports = [i for i in imports if i.kind == "module" or (
        i.kind == "function" and f"{i.importer} -> {i.target}" in LAZY_IMPORTS)]
    graph = ig.runtime_graph([ig.Import(i.importer, i.target, "module", "", (), i.line)
                              for i in imports])
    assert {", ".join(c) for c in ig.cycles(graph)} == found["CYCLES"]


def test_lazy_imports_are_listed_with_a_reason(found):
    assert all(reason.strip() for reason in LAZY_IMPORTS.values())
    stale = sorted(set(LAZY_IMPORTS) - found["LAZY"])
    assert not stale, f"LAZY_IMPORTS lists imports that are gone: {stale}"
    _compare("lazy", found["LAZY"], set(LAZY_IMPORTS))


def test_no_relative_imports():
    assert ig.relative_imports() == set()


def test_no_private_names_across_modules(found):
    _compare("private", found["PRIVATE"])


def test_no_module_over_700_lines(found):
    _compare("long_modules", found["LONG_MODULES"])


#: functions allowed over :data:`MAX_FUNCTION_LINES` lines ("path::name": the reason)
LONG_FUNCTIONS: dict[str, str] = {
    **{f"rdgpu/families/{family}/warp_kernels.py::{name}":
       "a closure building one family's Warp kernels for one dtype: its span is the "
       "nested @wp.func/@wp.kernel bodies (each under 80 lines), which Warp needs defined "
       "inside it to specialise on the dtype"
       for family, name in (("gray_scott", "_build"), ("laplacian", "_build"),
                            ("levelset", "_build_reinit"), ("sor", "_build"))},
}
#: the longest a function of rdgpu may be (its whole span, nested functions included)
MAX_FUNCTION_LINES = 100


def long_functions(limit: int = MAX_FUNCTION_LINES) -> dict[str, int]:
    """``"path::name": lines`` of every function of rdgpu/ longer than ``limit``: its whole
    span (nested functions included) less its docstring, which is documentation, not code."""
    import ast

    out = {}
    for path in sorted(ig.PACKAGE.rglob("*.py")):
        rel = path.relative_to(ig.ROOT).as_posix()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                first = node.body[0]
                if (isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
                        and isinstance(first.value.value, str)):
                    lines -= first.end_lineno - first.lineno + 1
                if lines > limit:
                    out[f"{rel}::{node.name}"] = lines
    return out


def test_no_function_over_100_lines():
    found = long_functions()
    new = sorted(f"{k} ({found[k]} lines)" for k in set(found) - set(LONG_FUNCTIONS))
    assert not new, ("split these functions where they mix ideas (or list one in "
                     f"LONG_FUNCTIONS with its reason): {new}")
    gone = sorted(set(LONG_FUNCTIONS) - set(found))
    assert not gone, f"remove from LONG_FUNCTIONS (now <= {MAX_FUNCTION_LINES} lines): {gone}"
    assert all(reason.strip() for reason in LONG_FUNCTIONS.values())


def test_backend_seam_outside_backends(found):
    _compare("backend_peeks", found["BACKEND_PEEKS"])


def test_no_isinstance_on_domains_outside_domains(found):
    _compare("domain_isinstance", found["DOMAIN_ISINSTANCE"])


def test_domains_models_and_backends_are_typed(found):
    # "path: N": N parameters named domain/grid/mesh/surface/model/backend/be hinted Any
    _compare("any_hints", found["ANY_HINTS"])


# the scanner itself, on small sources


def _imports(tmp_path, monkeypatch, files: dict[str, str]) -> list[ig.Import]:
    root = tmp_path / "rdgpu"
    for rel, text in {"__init__.py": "", **files}.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        (path.parent / "__init__.py").touch()
        path.write_text(text)
    monkeypatch.setattr(ig, "ROOT", tmp_path)
    monkeypatch.setattr(ig, "PACKAGE", root)
    return ig.scan()


def test_scanner_kinds_targets_and_cycles(tmp_path, monkeypatch):
    imports = _imports(tmp_path, monkeypatch, {
        "core/a.py": "from rdgpu.ops import api\nimport rdgpu.core.b as b\n",
        "core/b.py": ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                      "    from rdgpu.models.m import M\n"
                      "def f():\n    from rdgpu.core.a import _x\n"),
        "ops/api.py": "import rdgpu.core.a\n",
        "models/m.py": "",
    })
    got = {(i.importer, i.target, i.kind, i.function) for i in imports}
    assert got == {
        ("rdgpu.core.a", "rdgpu.ops.api", "module", ""),
        ("rdgpu.core.a", "rdgpu.core.b", "module", ""),
        ("rdgpu.core.b", "rdgpu.models.m", "typing", ""),
        ("rdgpu.core.b", "rdgpu.core.a", "function", "f"),
        ("rdgpu.ops.api", "rdgpu.core.a", "module", ""),
    }
    assert ig.upward(imports) == {"rdgpu.core.a -> rdgpu.ops.api",
                                  "rdgpu.core.b -> rdgpu.models.m"}
    assert ig.private(imports) == {"rdgpu.core.b -> rdgpu.core.a._x"}
    assert ig.cycles(ig.runtime_graph(imports)) == [("rdgpu.core.a", "rdgpu.ops.api")]
    assert ig.hidden_cycles(imports) == [("rdgpu.core.a", "rdgpu.core.b", "rdgpu.ops.api")]


def test_scanner_finds_backend_peeks_and_domain_checks(tmp_path, monkeypatch):
    _imports(tmp_path, monkeypatch, {
        "models/c.py": ("def launch(be, d, x):\n"
                        "    if be.name == 'warp' or d.backend._cells:\n"
                        "        return isinstance(x, (Grid, SurfaceMesh))\n"
                        "    return be.upload(x), f'{be.name}', model.name == 'x'\n"
                        "def g(domain: Any, model: 'Model', backend: Any | None = None):\n"
                        "    pass\n"),
        "backends/w.py": "def f(be):\n    return be._cells, be.name == 'warp'\n",
        "domains/d.py": "def f(x):\n    return isinstance(x, Grid)\n",
    })
    assert ig.backend_peeks() == {"rdgpu/models/c.py::launch: be.name compared",
                                  "rdgpu/models/c.py::launch: d.backend._cells"}
    assert ig.domain_isinstance() == {"rdgpu/models/c.py::launch: Grid, SurfaceMesh"}
    assert ig.any_hints() == {"rdgpu/models/c.py: 2"}


# the list, regenerated


#: each check's prefix in KNOWN_VIOLATIONS, and its key in ig.findings()
CHECKS = (("cycle", "CYCLES"), ("upward", "UPWARD"), ("lazy", "LAZY"), ("private", "PRIVATE"),
          ("long_modules", "LONG_MODULES"), ("backend_peeks", "BACKEND_PEEKS"),
          ("domain_isinstance", "DOMAIN_ISINSTANCE"), ("any_hints", "ANY_HINTS"))


def known_block() -> str:
    """The body of KNOWN_VIOLATIONS for the code as it is now."""
    found = ig.findings()
    lines = []
    for check, key in CHECKS:
        items = sorted(found[key] - (set(LAZY_IMPORTS) if check == "lazy" else set()))
        lines.append(f"    # {check.replace('_', ' ')} ({len(items)})")
        for item in items:
            line = f"    {f'{check}: {item}'!r},"
            lines.append(line + ("  # noqa: E501" if len(line) > 100 else ""))
    return "\n".join(lines) + "\n"


def _write_known() -> None:
    path = Path(__file__)
    text = path.read_text()
    start = text.index("KNOWN_VIOLATIONS: frozenset[str] = frozenset({\n")
    start = text.index("\n", start) + 1
    end = text.index("})\n", start)
    path.write_text(text[:start] + known_block() + text[end:])


if __name__ == "__main__":
    if sys.argv[1:] == ["--write"]:
        _write_known()
    else:
        print(known_block(), end="")
