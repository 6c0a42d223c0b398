"""rdgpu's imports, read from the source with :mod:`ast` (nothing is imported).

:mod:`tests.test_architecture` checks the layer contract of docs/architecture.md with it,
and ``python -m tests.import_graph [out.svg]`` prints the layer-to-layer imports and draws
the picture of the layers (docs/img/layers.svg) from them.

An *import* here is one ``import``/``from ... import`` statement (or an
``importlib.import_module("rdgpu....")`` call with a literal name) that names an rdgpu
module; where it sits decides its kind:

* ``module`` — runs when the importing module is imported;
* ``typing`` — under ``if TYPE_CHECKING:``, never runs;
* ``function`` — inside a function: runs on the call (a lazy import).
"""

from __future__ import annotations

import ast
import functools
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "rdgpu"

#: the layers, lowest first: a module imports only from its own layer or a lower one
LAYERS: tuple[tuple[str, ...], ...] = (
    ("core",),
    ("families",),
    ("domains",),
    ("ir",),
    ("backends",),
    ("ops",),
    ("integrators",),
    ("models",),
    ("simulation",),
    ("io", "analysis", "growth"),
    ("runs", "integrations", "bench"),
    ("cli",),
    ("rdgpu",),  # rdgpu/__init__.py and the facades
)

#: the top-level modules of the public facades, in the top layer with rdgpu/__init__.py
FACADES = ("output", "surfaces", "pypde")


@dataclass(frozen=True)
class Import:
    """One import of an rdgpu module by an rdgpu module."""

    importer: str  # dotted module name
    target: str  # dotted module name (a package means its __init__.py)
    kind: str  # "module", "typing" or "function"
    function: str  # qualified name of the enclosing function ("" at module level)
    names: tuple[str, ...]  # the names taken by ``from ... import`` (empty otherwise)
    line: int


def module_files() -> dict[str, Path]:
    """Every module of the package: dotted name -> file."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def package_of(module: str) -> str:
    """The first-level package a module belongs to (``rdgpu`` for the top modules)."""
    parts = module.split(".")
    if len(parts) == 1 or (len(parts) == 2 and parts[1] in FACADES):
        return "rdgpu"
    return parts[1]


def layer_of(module: str) -> int:
    """Index into :data:`LAYERS` (KeyError for a package the table does not name)."""
    pkg = package_of(module)
    for i, names in enumerate(LAYERS):
        if pkg in names:
            return i
    raise KeyError(f"{module}: package {pkg!r} has no layer in tests/import_graph.py LAYERS")


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


class _Visitor(ast.NodeVisitor):
    def __init__(self, module: str, is_package: bool, known: set[str]):
        self.module = module
        self.is_package = is_package
        self.known = known
        self.stack: list[str] = []  # enclosing classes and functions
        self.depth = 0  # enclosing functions
        self.typing = 0
        self.found: list[Import] = []

    def _kind(self) -> str:
        return "function" if self.depth else ("typing" if self.typing else "module")

    def _add(self, target: str, names: tuple[str, ...], node: ast.AST) -> None:
        self.found.append(Import(self.module, target, self._kind(), ".".join(self.stack),
                                 names, node.lineno))

    def _resolve(self, name: str) -> str:
        """The longest prefix of ``name`` that is a module of the package."""
        parts = name.split(".")
        while parts and ".".join(parts) not in self.known:
            parts.pop()
        return ".".join(parts)

    def visit_FunctionDef(self, node: ast.FunctionDef | ast.AsyncFunctionDef) -> None:
        self.stack.append(node.name)
        self.depth += 1
        self.generic_visit(node)
        self.depth -= 1
        self.stack.pop()

    visit_AsyncFunctionDef = visit_FunctionDef

    def visit_ClassDef(self, node: ast.ClassDef) -> None:
        self.stack.append(node.name)
        self.generic_visit(node)
        self.stack.pop()

    def visit_If(self, node: ast.If) -> None:
        if _is_type_checking(node.test):
            self.typing += 1
            for child in node.body:
                self.visit(child)
            self.typing -= 1
            for child in node.orelse:
                self.visit(child)
        else:
            self.generic_visit(node)

    def visit_Import(self, node: ast.Import) -> None:
        for alias in node.names:
            if alias.name.split(".")[0] == "rdgpu":
                self._add(self._resolve(alias.name), (), node)

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        base = node.module or ""
        if node.level:  # relative: resolve against this module's package
            parts = self.module.split(".")
            keep = len(parts) - node.level + (1 if self.is_package else 0)
            base = ".".join(parts[:keep] + ([base] if base else []))
        if base.split(".")[0] != "rdgpu":
            return
        names = tuple(a.name for a in node.names)
        submodules = [f"{base}.{n}" for n in names if f"{base}.{n}" in self.known]
        if submodules:  # ``from rdgpu.x import module``: an import of that module
            for sub in submodules:
                self._add(sub, (), node)
            rest = tuple(n for n in names if f"{base}.{n}" not in self.known)
            if rest:
                self._add(self._resolve(base), rest, node)
        else:
            self._add(self._resolve(base), names, node)

    def visit_Call(self, node: ast.Call) -> None:
        func = node.func
        if (isinstance(func, ast.Attribute) and func.attr == "import_module" and node.args
                and isinstance(node.args[0], ast.Constant)
                and isinstance(node.args[0].value, str)
                and node.args[0].value.startswith("rdgpu")):
            self._add(self._resolve(node.args[0].value), (), node)
        self.generic_visit(node)


def parse(path: Path) -> ast.Module:
    """The syntax tree of one file (read once while the file is unchanged)."""
    return _parse(str(path), path.stat().st_mtime_ns)


@functools.cache
def _parse(path: str, mtime_ns: int) -> ast.Module:
    return ast.parse(Path(path).read_text(), filename=path)


def scan() -> list[Import]:
    """Every import of an rdgpu module in the package."""
    files = module_files()
    known = set(files)
    out: list[Import] = []
    for module, path in files.items():
        v = _Visitor(module, path.name == "__init__.py", known)
        v.visit(parse(path))
        out.extend(i for i in v.found if i.target and i.target != module)
    return out


def _ancestors(module: str) -> list[str]:
    parts = module.split(".")
    return [".".join(parts[:i]) for i in range(2, len(parts))]


def runtime_graph(imports: list[Import]) -> dict[str, set[str]]:
    """Module -> the modules importing it runs at once: its module-level imports, each
    with the packages above the target that Python imports first (the root ``rdgpu`` and
    the importer's own packages left out, as every module of them would otherwise
    reach them)."""
    graph: dict[str, set[str]] = defaultdict(set)
    for i in imports:
        if i.kind != "module":
            continue
        own = set(_ancestors(i.importer)) | {i.importer}
        for t in (*_ancestors(i.target), i.target):
            if t not in own:
                graph[i.importer].add(t)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[tuple[str, ...]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[tuple[str, ...]] = []
    counter = [0]
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))

    def strong(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(tuple(sorted(comp)))

    for v in sorted(graph):
        if v not in index:
            strong(v)
    return sorted(out)


def layer_edges(imports: list[Import]) -> dict[tuple[str, str], dict[str, int]]:
    """(importing package, imported package) -> count of imports per kind."""
    out: dict[tuple[str, str], dict[str, int]] = defaultdict(lambda: defaultdict(int))
    for i in imports:
        a, b = package_of(i.importer), package_of(i.target)
        if a != b:
            out[a, b][i.kind] += 1
    return out


def upward(imports: list[Import]) -> set[str]:
    """``importer -> target`` for every import (of any kind) of a higher layer."""
    return {f"{i.importer} -> {i.target}" for i in imports
            if layer_of(i.target) > layer_of(i.importer)}


def lazy(imports: list[Import]) -> set[str]:
    """``importer -> target`` for every import of an rdgpu module inside a function."""
    return {f"{i.importer} -> {i.target}" for i in imports if i.kind == "function"}


def private(imports: list[Import]) -> set[str]:
    """``importer -> target._name`` for every private name one module takes from another."""
    return {f"{i.importer} -> {i.target}.{n}" for i in imports for n in i.names
            if n.startswith("_") and not n.startswith("__")}


def hidden_cycles(imports: list[Import]) -> list[tuple[str, ...]]:
    """The cycles once the imports inside functions count too (they only hide them)."""
    graph: dict[str, set[str]] = defaultdict(set)
    for i in imports:
        if i.kind != "typing":
            graph[i.importer].add(i.target)
    return cycles(graph)


def relative_imports() -> set[str]:
    """``module:line`` of every relative import (rdgpu imports its modules absolutely)."""
    return {f"{m}:{n.lineno}" for m, path in module_files().items()
            for n in ast.walk(parse(path)) if isinstance(n, ast.ImportFrom) and n.level}


def long_modules(limit: int = 700) -> dict[str, int]:
    """Path -> line count of every module over ``limit`` lines."""
    out = {}
    for path in module_files().values():
        n = len(path.read_text().splitlines())
        if n > limit:
            out[path.relative_to(ROOT).as_posix()] = n
    return out


_BACKEND_NAMES = ("numpy", "warp", "opencl")
_DOMAIN_CLASSES = ("Grid", "GraphSurface", "SurfaceMesh")


def _terminal(node: ast.expr) -> str:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    if isinstance(node, ast.Call):
        return _terminal(node.func)
    return ""


def _backendish(node: ast.expr) -> bool:
    """An expression that, by its name, holds a backend (``be``, ``backend``,
    ``target.backend``, ``get_backend(...)``, ``warp_backend``, ...)."""
    t = _terminal(node).lstrip("_")
    return t in ("be", "bk", "backend", "get_backend") or t.endswith("_backend")


class _Seams(ast.NodeVisitor):
    """Backend names and private members, and isinstance checks on domain classes."""

    def __init__(self, path: str):
        self.path = path
        self.stack: list[str] = []
        self.peeks: set[str] = set()
        self.domain_checks: set[str] = set()

    def _where(self) -> str:
        return f"{self.path}::{'.'.join(self.stack) or '<module>'}"

    def visit_FunctionDef(self, node: ast.FunctionDef | ast.AsyncFunctionDef) -> None:
        self.stack.append(node.name)
        self.generic_visit(node)
        self.stack.pop()

    visit_AsyncFunctionDef = visit_FunctionDef
    visit_ClassDef = visit_FunctionDef

    def visit_Compare(self, node: ast.Compare) -> None:
        operands = [node.left, *node.comparators]
        names = [o for o in operands if isinstance(o, ast.Attribute) and o.attr == "name"]
        literal = any(isinstance(o, ast.Constant) and o.value in _BACKEND_NAMES
                      for o in operands)
        for o in names:
            if _backendish(o.value) or literal:
                self.peeks.add(f"{self._where()}: {ast.unparse(o)} compared")
        self.generic_visit(node)

    def visit_Attribute(self, node: ast.Attribute) -> None:
        if node.attr.startswith("_") and not node.attr.startswith("__") \
                and _backendish(node.value):
            self.peeks.add(f"{self._where()}: {ast.unparse(node)}")
        self.generic_visit(node)

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        if (node.module or "").startswith("rdgpu.backends"):
            for a in node.names:
                if a.name.startswith("_"):
                    self.peeks.add(f"{self._where()}: {node.module}.{a.name} imported")

    def visit_Call(self, node: ast.Call) -> None:
        if _terminal(node.func) in ("isinstance", "issubclass") and len(node.args) == 2:
            kinds = node.args[1]
            items = kinds.elts if isinstance(kinds, ast.Tuple) else [kinds]
            found = sorted({_terminal(k) for k in items} & set(_DOMAIN_CLASSES))
            if found:
                self.domain_checks.add(f"{self._where()}: {', '.join(found)}")
        self.generic_visit(node)


def _seams() -> tuple[set[str], set[str]]:
    peeks: set[str] = set()
    checks: set[str] = set()
    for path in module_files().values():
        rel = path.relative_to(ROOT).as_posix()
        v = _Seams(rel)
        v.visit(parse(path))
        if not rel.startswith("rdgpu/backends/"):
            peeks |= v.peeks
        if not rel.startswith("rdgpu/domains/"):
            checks |= v.domain_checks
    return peeks, checks


def backend_peeks() -> set[str]:
    """Outside rdgpu/backends/: a backend's name compared, or a private member of a
    backend (or of a backend module) read, as ``path::function: expression``."""
    return _seams()[0]


def domain_isinstance() -> set[str]:
    """Outside rdgpu/domains/: ``isinstance`` on a domain class, as
    ``path::function: classes``."""
    return _seams()[1]


#: parameters that hold a domain, a model or a backend, by their usual names
_TYPED_PARAMETERS = ("domain", "grid", "mesh", "surface", "model", "backend", "be")


def any_hints() -> set[str]:
    """``path: count`` of the parameters named in :data:`_TYPED_PARAMETERS` annotated
    ``Any`` (they should name the real type, imported under ``TYPE_CHECKING``)."""
    out = set()
    for path in module_files().values():
        count = 0
        for node in ast.walk(parse(path)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                args = node.args
                for arg in (*args.posonlyargs, *args.args, *args.kwonlyargs):
                    if arg.arg in _TYPED_PARAMETERS and arg.annotation is not None \
                            and ast.unparse(arg.annotation) in ("Any", "Any | None"):
                        count += 1
        if count:
            out.add(f"{path.relative_to(ROOT).as_posix()}: {count}")
    return out


def findings() -> dict[str, set[str]]:
    """Every check of tests/test_architecture.py by its name there: what it finds now."""
    imports = scan()
    peeks, checks = _seams()
    return {
        "CYCLES": {", ".join(c) for c in cycles(runtime_graph(imports))},
        "UPWARD": upward(imports),
        "LAZY": lazy(imports),
        "PRIVATE": private(imports),
        "HIDDEN_CYCLES": {", ".join(c) for c in hidden_cycles(imports)},
        "LONG_MODULES": set(long_modules()),
        "BACKEND_PEEKS": peeks,
        "DOMAIN_ISINSTANCE": checks,
        "ANY_HINTS": any_hints(),
    }


def _package_layer(pkg: str) -> int:
    return next(i for i, row in enumerate(LAYERS) if pkg in row)


def draw(path: Path) -> None:
    """The layers as rows of boxes, lowest at the bottom; an arrow per package-to-package
    import that runs at import time (grey: only downward; red: upward, a violation),
    dashed for lazy (function-level) ones."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

    edges = layer_edges(scan())
    width = max(len(row) for row in LAYERS)
    pos: dict[str, tuple[float, float]] = {}
    for y, row in enumerate(LAYERS):
        for k, pkg in enumerate(row):
            pos[pkg] = ((k - (len(row) - 1) / 2) * 2.6, y * 1.1)
    fig, ax = plt.subplots(figsize=(9, 11))
    for (a, b), kinds in sorted(edges.items()):
        if a not in pos or b not in pos:
            continue
        up = _package_layer(b) > _package_layer(a)
        static = kinds.get("module", 0) + kinds.get("typing", 0)
        # downward imports leave and enter the boxes on the left, upward ones on the right
        side = 0.55 if up else -0.55
        start = (pos[a][0] + side, pos[a][1])
        end = (pos[b][0] + side, pos[b][1])
        # bulging outwards, away from the column of boxes
        rad = 0.3 if (pos[b][1] < pos[a][1]) != up else -0.3
        ax.add_patch(FancyArrowPatch(start, end, arrowstyle="-|>", mutation_scale=9,
                                     linestyle="-" if static else "--",
                                     color="#c0392b" if up else "#7f8c9a",
                                     lw=1.3 if up else 0.6, alpha=0.95 if up else 0.5,
                                     shrinkA=2, shrinkB=2,
                                     connectionstyle=f"arc3,rad={rad}", zorder=1))
    labels = {"rdgpu": "rdgpu/__init__\n+ output, surfaces, pypde"}
    for pkg, (x, y) in pos.items():
        half = 1.25 if pkg == "rdgpu" else 0.8
        ax.add_patch(FancyBboxPatch((x - half, y - 0.28), 2 * half, 0.56,
                                    boxstyle="round,pad=0.02", fc="#eaf2fb", ec="#2c5d8a",
                                    zorder=2))
        ax.text(x, y, labels.get(pkg, pkg), ha="center", va="center", zorder=3,
                fontsize=9 if pkg == "rdgpu" else 11, family="monospace")
    ax.text(-width * 1.3 - 0.4, -0.9, "grey: imports downward (allowed)    red: imports "
            "upward (violations, listed in tests/test_architecture.py)\nsolid: at import "
            "time    dashed: only inside functions (lazy)", fontsize=8, va="top")
    ax.set_xlim(-width * 1.3 - 0.5, width * 1.3 + 0.5)
    ax.set_ylim(-1.4, len(LAYERS) * 1.1 - 0.4)
    ax.set_axis_off()
    ax.set_title("rdgpu: the layers, lowest first (drawn from the imports by "
                 "tests/import_graph.py)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, metadata={"Date": None} if path.suffix == ".svg" else None)
    plt.close(fig)


def main(argv: list[str]) -> int:
    if argv[:1] == ["--known"]:  # what the known lists of test_architecture.py would be
        for name, found in findings().items():
            print(f"{name} = {{")
            for item in sorted(found):
                print(f"    {item!r},")
            print("}")
        return 0
    imports = scan()
    for (a, b), kinds in sorted(layer_edges(imports).items()):
        print(f"{a:>13} -> {b:<13} " + ", ".join(f"{k} {n}" for k, n in sorted(kinds.items())))
    for comp in cycles(runtime_graph(imports)):
        print("cycle:", ", ".join(comp))
    if argv:
        draw(Path(argv[0]))
        print("wrote", argv[0])
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
