"""How many of VisualPDE's presets rdgpu translates and runs (issue 23's count).

    python perf/visualpde_census.py PATH/TO/presets.js [--backend numpy] [--steps 20]

``presets.js`` is VisualPDE's ``sim/scripts/RD/presets.js`` (public repository
Pecnut/visual-pde, MIT), a file the user has: nothing is downloaded.  Each
``presets["name"] = {...};`` object literal is read by a small JavaScript-literal reader
(`read_presets`), translated by `rdgpu.integrations.visualpde.load` (parents looked up
among the others) and, where it translates, run for ``--steps`` steps on ``--backend``
(float32, the preset's own ``dt`` and scheme, no stability check: VisualPDE's steps are
its own); a run counts when its fields stay finite.  Prints the totals and the refusals
grouped by their reason's first words.
"""

from __future__ import annotations

import argparse
import collections
import re
from pathlib import Path
from typing import Any

import numpy as np

_HEAD = re.compile(r'presets\[\s*"((?:[^"\\]|\\.)*)"\s*\]\s*=\s*')


class _Reader:
    """A recursive-descent reader of JavaScript object literals (strings, numbers,
    true/false/null, arrays, objects with bare or quoted keys, comments, trailing
    commas)."""

    def __init__(self, text: str, pos: int):
        self.text, self.pos = text, pos

    def _skip(self) -> None:
        t = self.text
        while self.pos < len(t):
            if t[self.pos].isspace():
                self.pos += 1
            elif t.startswith("//", self.pos):
                end = t.find("\n", self.pos)
                self.pos = len(t) if end < 0 else end + 1
            elif t.startswith("/*", self.pos):
                self.pos = t.index("*/", self.pos) + 2
            else:
                return

    def value(self) -> Any:
        self._skip()
        c = self.text[self.pos]
        if c == "{":
            return self._object()
        if c == "[":
            return self._array()
        if c in "\"'`":
            return self._string()
        m = re.compile(r"0[xX][0-9a-fA-F]+|-?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|true|false"
                       r"|null|undefined").match(self.text, self.pos)
        if not m:
            raise ValueError(f"unexpected {self.text[self.pos:self.pos + 20]!r}")
        self.pos = m.end()
        word = m.group(0)
        words = {"true": True, "false": False, "null": None, "undefined": None}
        if word in words:
            return words[word]
        if word[:2] in ("0x", "0X"):
            return int(word, 16)
        return int(word) if word.lstrip("-").isdigit() else float(word)

    def _string(self) -> str:
        quote = self.text[self.pos]
        self.pos += 1
        out = []
        while self.text[self.pos] != quote:
            ch = self.text[self.pos]
            if ch == "\\":
                nxt = self.text[self.pos + 1]
                out.append({"n": "\n", "t": "\t", "r": "\r"}.get(nxt, nxt))
                self.pos += 2
            else:
                out.append(ch)
                self.pos += 1
        self.pos += 1
        return "".join(out)

    def _array(self) -> list:
        self.pos += 1
        out = []
        while True:
            self._skip()
            if self.text[self.pos] == "]":
                self.pos += 1
                return out
            out.append(self.value())
            self._skip()
            if self.text[self.pos] == ",":
                self.pos += 1

    def _object(self) -> dict:
        self.pos += 1
        out = {}
        while True:
            self._skip()
            if self.text[self.pos] == "}":
                self.pos += 1
                return out
            if self.text[self.pos] in "\"'":
                key = self._string()
            else:
                m = re.compile(r"[A-Za-z_$][\w$]*").match(self.text, self.pos)
                if not m:
                    raise ValueError(f"bad key at {self.text[self.pos:self.pos + 20]!r}")
                key, self.pos = m.group(0), m.end()
            self._skip()
            if self.text[self.pos] != ":":
                raise ValueError(f"expected ':' after {key!r}")
            self.pos += 1
            out[key] = self.value()
            self._skip()
            if self.text[self.pos] == ",":
                self.pos += 1


def read_presets(text: str) -> dict[str, dict]:
    """Every ``presets["name"] = {...}`` of ``text``, by name."""
    out = {}
    for m in _HEAD.finditer(text):
        out[m.group(1)] = _Reader(text, m.end()).value()
    return out


def census(presets: dict[str, dict], backend: str, steps: int) -> dict[str, Any]:
    """``{"runs": [...], "refused": {name: reason}, "failed": {name: reason}}``."""
    from rdgpu.integrations.visualpde import UnsupportedPreset, load

    runs, refused, failed = [], {}, {}
    for name, p in presets.items():
        try:
            tr = load(p, presets=presets)
        except UnsupportedPreset as exc:
            refused[name] = str(exc)
            continue
        except Exception as exc:  # noqa: BLE001 - a census records every failure
            failed[name] = f"load: {type(exc).__name__}: {exc}"
            continue
        try:
            sim = tr.simulation(backend=backend, dtype="float32", check_stability=False)
            res = sim.run(min(steps, tr.steps), progress=False)
            if not all(np.isfinite(a).all() for a in res.fields.values()):
                failed[name] = "run: not finite"
                continue
        except Exception as exc:  # noqa: BLE001
            failed[name] = f"run: {type(exc).__name__}: {str(exc)[:160]}"
            continue
        runs.append(name)
    return {"runs": runs, "refused": refused, "failed": failed}


def _reason(text: str) -> str:
    """A refusal's kind: the part before its first colon or parenthesis, numbers out."""
    head = re.split(r"[:(]", text, maxsplit=1)[0]
    head = re.sub(r"_\d+", "_i", head)
    return re.sub(r"'[^']*'", "'…'", head).strip()[:80]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("presets", type=Path)
    ap.add_argument("--backend", default="numpy")
    ap.add_argument("--steps", type=int, default=20)
    args = ap.parse_args()
    presets = read_presets(args.presets.read_text(encoding="utf-8"))
    out = census(presets, args.backend, args.steps)
    n = len(presets)
    print(f"{n} presets: {len(out['runs'])} translate and run, {len(out['refused'])} "
          f"refused by name, {len(out['failed'])} failed")
    kinds = collections.Counter(_reason(r) for r in out["refused"].values())
    print("\nrefused, by reason:")
    for reason, count in kinds.most_common():
        print(f"{count:5d}  {reason}")
    if out["failed"]:
        print("\nfailed:")
        for name, why in sorted(out["failed"].items()):
            print(f"  {name}: {why}")


if __name__ == "__main__":
    main()
