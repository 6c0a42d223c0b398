"""py-pde's noise as rdgpu's (`rdgpu.integrators.noise`): the variance of a ``pde.PDE``
(numbers per field, or expressions: multiplicative noise) or of a built-in PDE class
(``noise=``, a number or one per field), in its interpretation (Itô, Stratonovich, ...:
the same drift term as py-pde's), stepped on the device by Euler–Maruyama
(``EulerSolver``, fixed ``dt``) or Milstein (``MilsteinSolver``).  py-pde's and rdgpu's
update are the same formula, ``s + h f + √(h V / w) ξ`` (plus Milstein's ``¼ (h/w) V'
(ξ² − 1)``), with ``w`` the cell volume; the numbers differ (rdgpu draws them from Philox
on the device, keyed by a seed taken from the PDE's ``rng``, so a PDE given a seeded
generator runs the same twice), so runs agree in distribution, not bit for bit.
Refused by name: noise that varies over the cells (an array variance), an unknown
interpretation, and solvers other than those two.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from rdgpu.integrations.pypde.checks import refuse
from rdgpu.integrators.noise import INTERPRETATIONS
from rdgpu.ir import equations as eq

__all__ = ["SOLVERS", "noise_seed", "pde_noise"]

#: py-pde's solvers that step noise, and rdgpu's method for each
SOLVERS = {"EulerSolver": "euler", "MilsteinSolver": "milstein"}


def pde_noise(pde_obj: Any, species: tuple[str, ...], params: dict[str, Any],
              coords: Callable[[eq.Node], eq.Node | None],
              axes: dict[str, str]) -> dict[str, float | str] | None:
    """rdgpu's ``noise=`` of ``pde_obj`` (species → variance: a number, or an expression
    in rdgpu's names, ``coords`` mapping py-pde's coordinates and ``axes`` its axis
    names), or None for a deterministic PDE."""
    if not getattr(pde_obj, "is_sde", False):
        return None
    how = str(getattr(pde_obj, "noise_interpretation", "ito")).lower()
    if how not in INTERPRETATIONS:
        raise refuse(f"noise_interpretation={how!r} (rdgpu's: {', '.join(INTERPRETATIONS)})")
    exprs = getattr(pde_obj, "noise_expressions", None) or {}
    if exprs:
        out: dict[str, float | str] = {}
        for s in species:
            text = exprs.get(s, "0")
            try:
                tree = eq.parse(text, species=species, params=params,
                                what=f"the noise of {s!r}", laplace=False)
                tree = eq.map_axes(tree, axes)
            except eq.EquationError as exc:
                raise refuse(str(exc)) from None
            out[s] = eq.to_text(eq.substitute(tree, coords))
        return out
    v = np.asarray(getattr(pde_obj, "noise", 0.0))
    if v.dtype == object or not np.isrealobj(v) or v.ndim > 1 or \
            (v.ndim == 1 and v.size not in (1, len(species))):
        raise refuse(f"the noise {getattr(pde_obj, 'noise', None)!r} (a number, or one "
                     f"per field: {len(species)})")
    values = np.broadcast_to(v.astype(np.float64).ravel() if v.ndim else v, len(species))
    return {s: float(x) for s, x in zip(species, values, strict=True)}


def noise_seed(pde_obj: Any) -> int:
    """The Philox key of a run: drawn from the PDE's generator (``rng``), so that a PDE
    made with a seeded one runs the same each time."""
    rng = getattr(pde_obj, "rng", None)
    if rng is None:
        rng = np.random.default_rng()
    return int(rng.integers(0, 2 ** 63))
