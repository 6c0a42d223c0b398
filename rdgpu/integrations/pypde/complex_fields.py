"""py-pde's complex fields and its variable names outside ASCII, as rdgpu runs them.

* **Names**: a variable that is not an ASCII identifier (py-pde's example writes
  Schrödinger's ``ψ``) runs as a generated name ``f<k>`` (`device_names`), never one of the
  PDE's other names; the equations' text is renamed token by token (`rename`), so ``ψ`` in
  ``"I * laplace(ψ)"`` and nothing else changes.
* **The imaginary unit**: sympy's ``I`` (py-pde parses with sympy) becomes ``1j`` where the
  PDE is complex and ``I`` is none of its variables or constants.
* **Complex fields**: a complex-valued PDE (``pde.complex_valued``, or a complex state)
  declares every variable a complex species (`rdgpu.ir.complex_split`): it runs as its real
  and imaginary parts, the state's ``data.real`` and ``data.imag`` views (`views`), float64
  for ``complex128``, float32 for ``complex64``.  Real boundary data hold the real part; the
  imaginary part takes the same condition with value 0 (`split_bc`): a field held at ``g``
  on a face has ``Re = g``, ``Im = 0`` there, and a flux or Robin condition alike, since
  each is linear.
"""

from __future__ import annotations

import io
import keyword
import tokenize
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from rdgpu.ir.complex_split import parts

__all__ = ["device_names", "real_dtype", "rename", "split_bc", "views"]


def _ascii_identifier(name: str) -> bool:
    return name.isascii() and name.isidentifier() and not keyword.iskeyword(name)


def device_names(variables: Sequence[str], taken: Iterable[str]) -> dict[str, str]:
    """py-pde variable -> rdgpu species name: itself where it is an ASCII identifier, else
    ``f<k>`` with ``k`` the first index whose name (and, for complex parts, ``_re``/
    ``_im`` forms) no variable, constant or other generated name uses."""
    used = {*variables, *taken}
    used |= {p for v in used for p in parts(v)}
    out: dict[str, str] = {}
    k = 0
    for v in variables:
        if _ascii_identifier(v):
            out[v] = v
            continue
        while any(n in used for n in (f"f{k}", *parts(f"f{k}"))):
            k += 1
        out[v] = f"f{k}"
        used |= {f"f{k}", *parts(f"f{k}")}
    return out


def rename(text: str, names: Mapping[str, str], imaginary: bool) -> str:
    """``text`` (a py-pde expression) with each name token of ``names`` replaced and, where
    ``imaginary``, the token ``I`` written ``1j``; nothing else changes."""
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (tokenize.TokenError, SyntaxError, IndentationError):
        return text  # the parser then says what is wrong with it
    out = []
    for tok in tokens:
        if tok.type == tokenize.NAME and tok.string in names:
            tok = tok._replace(string=names[tok.string])
        elif tok.type == tokenize.NAME and imaginary and tok.string == "I":
            tok = tok._replace(string="1j")
        out.append(tok)
    return tokenize.untokenize(out).strip()


def real_dtype(dtype: np.dtype) -> np.dtype:
    """The dtype of the parts of a state of ``dtype`` (itself when real)."""
    return np.empty(0, dtype=dtype).real.dtype


def views(data: np.ndarray, several: bool) -> list[np.ndarray]:
    """py-pde's ``state.data`` as one view per rdgpu species: a FieldCollection's rows
    (``several``) or the single field's data, each complex one as its ``real`` and
    ``imag`` views (writable: a result stored into them lands in the state)."""
    rows = [data[i] for i in range(len(data))] if several else [data]
    if not np.iscomplexobj(data):
        return rows
    return [p for r in rows for p in (r.real, r.imag)]


def split_bc(bc: Mapping[str, Mapping[str, Any]], complex_species: Sequence[str]
             ) -> dict[str, dict[str, Any]]:
    """Per-species conditions of the variables (``{species: {side: condition}}``) for
    their parts: the real part's the variable's, the imaginary part's the same kind with
    value 0 (module doc)."""
    cplx = set(complex_species)
    out: dict[str, dict[str, Any]] = {}
    for s, sides in bc.items():
        if s not in cplx:
            out[s] = dict(sides)
            continue
        re, im = parts(s)
        out[re] = dict(sides)
        out[im] = {side: _zero(c) for side, c in sides.items()}
    return out


def _zero(cond: Any) -> Any:
    """``cond`` with its value 0 (a Robin condition keeps its coefficient)."""
    if isinstance(cond, str):
        return cond
    if cond[0] == "robin":
        return ("robin", cond[1], 0.0)
    return (cond[0], 0.0)
