"""The split of a model's right-hand sides that the IMEX and exponential schemes step: each
species' own ``α Δs + β Δ²s`` with constant coefficients (implicit, or exact), and the rest
(`rdgpu.integrators.stepper`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from rdgpu.ir import equations as eq
from rdgpu.ir.program import PerMember

__all__ = ["linear_split", "scalar_numbers"]


def scalar_numbers(params: Mapping[str, Any]) -> dict[str, float | None]:
    """Each parameter's value where it is one number for every cell, member and time,
    else None."""
    return {k: (float(v) if np.ndim(v) == 0 and not isinstance(v, (str, PerMember))
                else None) for k, v in params.items()}


def linear_split(species: Sequence[str], trees: Mapping[str, eq.Node],
                 written: Mapping[str, Any], params: Mapping[str, Any], method: str,
                 inline: Mapping[str, eq.Node]) -> dict[str, tuple[float, float, list[eq.Node]]]:
    """Per species ``(α, β, terms)``: the constant coefficients of its own ``α Δs + β
    Δ²s`` and the other terms of its right-hand side (the reactions, then other
    species' Laplacians and bilaplacians), what the IMEX and exponential schemes step
    explicitly; a ``ValueError`` naming the method where the split does not exist.
    ``written``: the model's linear parts as written (`rdgpu.models.Model.linear`);
    ``inline``: the parameters inlined as expressions of ``t``."""
    merged = scalar_numbers(params)
    out = {}
    for s in species:
        lin = eq.linear_parts(trees[s])
        if lin is None and written[s] is not None:
            # linear as written: a parameter expression of t made a coefficient vary
            raise ValueError(
                f"method {method!r}: in the equation of {s!r} a Laplacian's "
                f"coefficient uses a time-dependent parameter ({', '.join(sorted(inline))}"
                "); an implicit term needs a constant coefficient")
        if lin is None:
            raise ValueError(
                f"method {method!r}: the equation of {s!r} has a Laplacian with a "
                "state-dependent coefficient, which cannot be implicit; use an explicit "
                "method")
        alpha = _constant(lin.diffusion.get(s), merged, s, "laplace", method)
        beta = _constant(lin.bilaplacian.get(s), merged, s, "laplace(laplace)", method)
        if beta > 0:
            raise ValueError(
                f"method {method!r}: the bilaplacian of {s!r} has the coefficient "
                f"{beta} > 0 (ill-posed, anti-diffusive at every scale)")
        terms: list[eq.Node] = []
        if lin.rest is not None:
            terms.append(lin.rest)
        for r, c in lin.diffusion.items():
            if r != s:
                terms.append(eq.Bin("*", c, eq.Lap(r)))
        for r, c in lin.bilaplacian.items():
            if r != s:
                terms.append(eq.Bin("*", c, eq.Lap(r, 2)))
        out[s] = (alpha, beta, terms)
    return out


def _constant(c: eq.Node | None, merged: Mapping[str, float | None], s: str, what: str,
              method: str) -> float:
    if c is None:
        return 0.0
    names = eq.names(c, "param")
    bad = [p for p in names if merged.get(p) is None]
    if bad:
        raise ValueError(
            f"method {method!r}: the coefficient of {what}({s}) in the equation of "
            f"{s!r} uses the parameter(s) {bad}, which are fields, time-dependent or "
            "differ between ensemble members; an implicit term needs one constant "
            "coefficient")
    return float(eq.evaluate(c, {p: merged[p] for p in names}))
