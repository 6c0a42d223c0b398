"""Which documented callables lack a numpydoc ``Parameters`` section naming every argument.

The API reference (docs/reference/*.md, one ``::: dotted.name`` per entry) is walked:
modules through their ``__all__`` (or the functions and classes they define), classes
through their public methods and constructor. A callable whose signature has arguments
(besides ``self``/``cls``) must carry a ``Parameters`` section (a class may document its
fields under ``Attributes`` instead) that names each of them; ``*args``/``**kwargs`` are
named with or without their stars.

    python -m tests.docstring_audit            # every gap, with its file
    python -m tests.docstring_audit rdgpu/io   # only gaps defined under that path
"""

from __future__ import annotations

import importlib
import inspect
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_SECTION = re.compile(r"^(?P<title>[A-Z][A-Za-z ]+)\n-{3,}\n", re.M)


def reference_names() -> list[str]:
    names = []
    for page in sorted((ROOT / "docs" / "reference").glob("*.md")):
        for line in page.read_text("utf-8").splitlines():
            if line.startswith(":::"):
                names.append(line[3:].split()[0])
    return names


def _resolve(dotted: str):
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            obj = getattr(obj, attr)
        return obj
    raise ImportError(dotted)


def documented_names(doc: str, titles: tuple[str, ...]) -> set[str] | None:
    """Argument names listed in the docstring's sections of these titles; None if absent."""
    found = None
    marks = list(_SECTION.finditer(doc))
    for k, mark in enumerate(marks):
        if mark.group("title").strip() not in titles:
            continue
        end = marks[k + 1].start() if k + 1 < len(marks) else len(doc)
        body = doc[mark.end():end]
        found = found or set()
        for line in body.splitlines():
            if line and not line[0].isspace():
                for name in line.split(":")[0].split(","):
                    found.add(name.strip().lstrip("*"))
    return found


def _gap(qual: str, fn, docobj, titles) -> tuple[str, str, list[str]] | None:
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return None
    wanted = [name for name in sig.parameters if name not in ("self", "cls")]
    if not wanted:
        return None
    doc = inspect.getdoc(docobj) or ""
    if inspect.isclass(docobj) and "__init__" in vars(docobj) and docobj.__init__.__doc__:
        doc += "\n\n" + inspect.cleandoc(docobj.__init__.__doc__)
    listed = documented_names(doc, titles)
    missing = wanted if listed is None else [n for n in wanted if n not in listed]
    if not missing:
        return None
    try:
        where = str(Path(inspect.getsourcefile(fn)).resolve().relative_to(ROOT))
    except (TypeError, ValueError):
        where = str(Path(inspect.getsourcefile(docobj)).resolve().relative_to(ROOT))
    return qual, where, missing


def gaps() -> list[tuple[str, str, list[str]]]:
    """(dotted name, source file, undocumented arguments) for every gap in the reference."""
    seen: set[int] = set()
    out: list[tuple[str, str, list[str]]] = []

    def visit(qual: str, obj) -> None:
        if id(obj) in seen:
            return
        seen.add(id(obj))
        if inspect.ismodule(obj):
            names = getattr(obj, "__all__", None)
            for name in names if names is not None else list(vars(obj)):
                value = getattr(obj, name, None)
                if name.startswith("_") or not (inspect.isfunction(value)
                                                or inspect.isclass(value)):
                    continue
                if not getattr(value, "__module__", "").startswith("rdgpu"):
                    continue
                if names is None and value.__module__ != obj.__name__:
                    continue
                visit(f"{qual}.{name}", value)
        elif inspect.isclass(obj):
            if issubclass(obj, BaseException):
                return
            init = vars(obj).get("__init__") or vars(obj).get("__new__")
            if init is not None:
                gap = _gap(qual, obj, obj, ("Parameters", "Attributes"))
                if gap:
                    out.append(gap)
            members = {}
            for base in reversed(obj.__mro__):  # inherited methods of rdgpu's own bases too
                if base.__module__.startswith("rdgpu"):
                    members.update(vars(base))
            for name, value in members.items():
                if name.startswith("_"):
                    continue
                if isinstance(value, (staticmethod, classmethod)):
                    value = value.__func__
                if inspect.isfunction(value):
                    gap = _gap(f"{qual}.{name}", value, value, ("Parameters",))
                    if gap:
                        out.append(gap)
        elif inspect.isfunction(obj):
            gap = _gap(qual, obj, obj, ("Parameters",))
            if gap:
                out.append(gap)

    for name in reference_names():
        visit(name, _resolve(name))
    return out


def main(argv: list[str]) -> int:
    found = [g for g in gaps() if not argv or any(g[1].startswith(a) for a in argv)]
    for qual, where, missing in found:
        print(f"{where}: {qual}: {', '.join(missing)}")
    print(f"{len(found)} callables with undocumented arguments")
    return 1 if found else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
