"""Running cases, hashing their outputs, recording and checking (package doc)."""

from __future__ import annotations

import hashlib
import json
import math
import platform
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

FORMAT = "rdgpu-golden/1"


@dataclass(frozen=True)
class Case:
    """One golden case: ``run(backend, dtype)`` returns a dict of named outputs (NumPy
    arrays, numbers, strings, or nested dicts/lists/tuples of them)."""

    name: str
    backend: str
    dtype: str  # "float32", "float64", or "-" where the call takes no dtype
    run: Callable[[str, str], Mapping[str, Any]]

    @property
    def key(self) -> str:
        return f"{self.name} [{self.backend}, {self.dtype}]"


def _scalar(x: Any) -> Any:
    """An exact JSON form of a scalar output (floats by their hex, so no digit is lost)."""
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        f = float(x)
        return f.hex() if math.isfinite(f) else repr(f)
    if x is None or isinstance(x, str):
        return x
    raise TypeError(f"golden output of unsupported type {type(x).__name__}: {x!r}")


def _flatten(outputs: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"a.b[0]": leaf}``: nested dicts/lists/tuples opened down to arrays and scalars."""
    flat: dict[str, Any] = {}
    for k in sorted(outputs, key=str):
        v = outputs[k]
        name = f"{prefix}{k}"
        if isinstance(v, Mapping):
            flat.update(_flatten(v, name + "."))
        elif isinstance(v, (list, tuple)):
            flat.update(_flatten({f"[{i}]": x for i, x in enumerate(v)}, name))
        else:
            flat[name] = v
    return flat


def digest(outputs: Mapping[str, Any]) -> dict[str, Any]:
    """``{"hash": sha256 of everything, "arrays": {name: [dtype, shape, sha256]},
    "scalars": {name: exact value}}`` of one case's outputs."""
    total = hashlib.sha256()
    arrays: dict[str, list] = {}
    scalars: dict[str, Any] = {}
    for name, v in _flatten(outputs).items():
        if isinstance(v, np.ndarray):
            a = np.ascontiguousarray(v)
            h = hashlib.sha256(a.tobytes()).hexdigest()
            arrays[name] = [a.dtype.str, list(a.shape), h]
            total.update(f"A|{name}|{a.dtype.str}|{a.shape}|{h}\n".encode())
        else:
            s = _scalar(v)
            scalars[name] = s
            total.update(f"S|{name}|{json.dumps(s)}\n".encode())
    return {"hash": total.hexdigest(), "arrays": arrays, "scalars": scalars}


def run_case(case: Case) -> dict[str, Any]:
    """The case run once, as :func:`digest` gives it (an exception is recorded as its type
    and message, so a case that starts or stops failing is reported too)."""
    try:
        outputs = case.run(case.backend, case.dtype)
    except Exception as exc:  # noqa: BLE001 - a failure is a result to compare
        return {"hash": f"error: {type(exc).__name__}: {exc}", "arrays": {}, "scalars": {}}
    return digest(outputs)


def case_list(only: Iterable[str] | None = None) -> tuple[list[Case], list[str]]:
    """Every case on every available backend, and a note per backend left out."""
    from .cases import all_cases

    return all_cases(only)


def _environment() -> dict[str, Any]:
    import rdgpu

    env: dict[str, Any] = {"python": platform.python_version(), "machine": platform.machine(),
                           "processor": platform.processor(), "numpy": np.__version__,
                           "rdgpu": rdgpu.__version__}
    for info in rdgpu.available_backends():
        env[f"backend:{info.name}"] = info.device if info.available else f"n/a: {info.reason}"
    try:
        import warp

        env["warp"] = warp.config.version
    except Exception:  # noqa: BLE001 - an environment note only
        pass
    return env


def record(path: str | Path | None, cases: list[Case] | None = None,
           notes: Iterable[str] = (), log: Callable[[str], None] | None = None) -> dict:
    """Run ``cases`` (default: all) and write their digests to ``path`` (JSON; ``None``:
    only returned)."""
    if cases is None:
        cases, notes = case_list()
    t0 = time.perf_counter()
    results: dict[str, Any] = {}
    for case in cases:
        t = time.perf_counter()
        results[case.key] = run_case(case)
        if log:
            log(f"{time.perf_counter() - t:7.2f}s  {case.key}  {results[case.key]['hash'][:16]}")
    doc = {"format": FORMAT, "environment": _environment(), "notes": list(notes),
           "seconds": round(time.perf_counter() - t0, 2), "cases": results}
    if path is not None:
        Path(path).write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    return doc


def compare(before: Mapping, after: Mapping) -> list[str]:
    """One line per case whose digest differs (or is missing on one side), naming the
    case, its backend and dtype, and the outputs that changed."""
    problems = []
    b_cases, a_cases = before["cases"], after["cases"]
    for key in sorted(set(b_cases) | set(a_cases)):
        if key not in a_cases:
            problems.append(f"{key}: recorded but not run now")
            continue
        if key not in b_cases:
            problems.append(f"{key}: new case, not in the recording")
            continue
        b, a = b_cases[key], a_cases[key]
        if b["hash"] == a["hash"]:
            continue
        what = []
        if b["hash"].startswith("error:") or a["hash"].startswith("error:"):
            what.append(f"was {b['hash'][:120]!r}, now {a['hash'][:120]!r}")
        for kind in ("arrays", "scalars"):
            for name in sorted(set(b[kind]) | set(a[kind])):
                if b[kind].get(name) != a[kind].get(name):
                    what.append(f"{name}: {b[kind].get(name)} -> {a[kind].get(name)}")
        problems.append(f"{key}: differs ({'; '.join(what) or 'hash'})")
    return problems


def check(path: str | Path, cases: list[Case] | None = None,
          log: Callable[[str], None] | None = None) -> list[str]:
    """Rerun the cases recorded in ``path`` (default: all cases now known) and return the
    differences (:func:`compare`); empty when every result is bit-identical."""
    before = json.loads(Path(path).read_text())
    if before.get("format") != FORMAT:
        raise ValueError(f"{path} is not a golden recording ({FORMAT})")
    notes: Iterable[str] = ()
    if cases is None:  # the recorded cases (a recording made with --only holds a subset)
        cases, notes = case_list()
        cases = [c for c in cases if c.key in before["cases"]]
    after = record(None, cases, notes, log=log)
    problems = compare(before, after)
    if before.get("environment") != after["environment"]:
        diff = {k for k in set(before["environment"]) | set(after["environment"])
                if before["environment"].get(k) != after["environment"].get(k)}
        if problems:
            problems.append(f"note: the environment differs from the recording's "
                            f"({', '.join(sorted(diff))}); hashes are per machine")
    return problems
