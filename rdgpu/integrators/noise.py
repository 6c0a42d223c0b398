"""Noise of a stepper (``noise=``): Itô stochastic equations, stepped by Euler–Maruyama or
Milstein, their Gaussian increments drawn on the device from Philox (the ``noise`` kernel
family), so a run is reproducible bit for bit on each backend.

The equations are py-pde's (``PDE(..., noise=...)``, Itô): each species ``s`` with a
variance ``V_s`` (a number, or a pointwise expression of the species, parameters, x, y, z
and t: multiplicative noise) obeys ``∂t s = f_s + √V_s η_s``, ``η_s`` space-time white
noise, ``⟨η_s(x, t) η_s(x', t')⟩ = δ(x − x') δ(t − t')``, independent between species.  On a
domain whose points stand for the volumes ``w`` (``domain.point_weights``: a grid's cell
``dx·dy``, a mesh's vertex areas) one step ``h`` is

* Euler–Maruyama (method ``"euler"``): ``s' = s + h f_s + √(h V_s / w) ξ``;
* Milstein (method ``"milstein"``): that plus ``¼ (h/w) V_s' (ξ² − 1)``, ``V_s' = ∂V_s/∂s``
  (`rdgpu.ir.derivative`; for additive noise the two are the same),

and, for an equation read in another sense than Itô's (``noise_interpretation``, py-pde's
names: `INTERPRETATIONS`, ``α`` = ½ for Stratonovich's), both add the drift ``½ α (h/w)
V_s'`` that makes it the Itô equation,

``ξ`` a standard normal number per point, species and step, all evaluated at the step's
start (``s``, ``t``).  The numbers: ``rdgpu.families.noise`` fills one buffer per noisy
species before the step, point ``k`` (its index in the stepper's buffer) from
``philox4x32((k // 2, step, stream = species index), seed)`` (an ensemble's members are
consecutive, so each has its own numbers); the step index is the stepper's
``steps_done``, so a run resumed from a checkpoint at step ``n`` draws what the run would
have drawn.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.ir import equations as eq
from rdgpu.ir.derivative import derivative
from rdgpu.ir.program import PerMember
from rdgpu.ir.schemes import SCHEMES

if TYPE_CHECKING:
    from rdgpu.backends.base import Backend, DeviceArray
    from rdgpu.domains.base import Domain
    from rdgpu.ir.schemes import Scheme

__all__ = ["INTERPRETATIONS", "Noise", "draw", "noise_buffers", "parse_noise", "stepper_noise"]

#: the step forms of the noisy methods (`rdgpu.ir.schemes.ExplicitScheme.noise`)
FORMS = ("euler-maruyama", "milstein")
#: the senses of a stochastic equation (py-pde's names) and their drift factors α
INTERPRETATIONS = {"ito": 0.0, "itô": 0.0, "stratonovich": 0.5, "anti-ito": 1.0,
                   "anti-itô": 1.0, "hänggi-klimontovich": 1.0, "hanggi-klimontovich": 1.0}
#: the name of the inverse point volumes where they differ between points (an input field)
INVERSE_VOLUME = "_icv"


@dataclass(frozen=True)
class Noise:
    """The parsed noise of a stepper: ``variance`` per noisy species (trees), the seed and
    the step form (`FORMS`); ``inverse_volume``: ``1/w`` as one number, or None where it is
    a field (`INVERSE_VOLUME`, ``volumes`` its values)."""

    variance: dict[str, eq.Node]
    seed: int
    form: str
    inverse_volume: float | None
    #: each noisy species' stream: its index among the model's species
    streams: tuple[int, ...] = ()
    volumes: np.ndarray | None = None
    #: the drift factor α of the interpretation (`INTERPRETATIONS`; 0: Itô)
    drift: float = 0.0

    def buffer(self, s: str) -> str:
        """The input name of species ``s``'s normal numbers."""
        return f"_xi_{s}"

    @property
    def inputs(self) -> tuple[str, ...]:
        """The names the step's pass reads besides the fields: the numbers, then the
        inverse volumes where they are a field."""
        names = tuple(self.buffer(s) for s in self.variance)
        return names if self.inverse_volume is not None else (*names, INVERSE_VOLUME)

    def term(self, s: str) -> eq.Node | None:
        """What one step adds to species ``s`` (module doc), or None without noise."""
        v = self.variance.get(s)
        if v is None:
            return None
        h = eq.Ref("builtin", "_h")
        icv = (eq.Num(self.inverse_volume) if self.inverse_volume is not None
               else eq.Ref("species", INVERSE_VOLUME))
        xi = eq.Ref("species", self.buffer(s))
        hw = eq.Bin("*", h, icv)
        out: eq.Node = eq.Bin("*", eq.Call("sqrt", (eq.Bin("*", hw, v),)), xi)
        dv = derivative(v, s)
        if dv == eq.Num(0.0):
            return out
        if self.drift:
            out = eq.Bin("+", eq.Bin("*", eq.Bin("*", eq.Num(0.5 * self.drift), hw), dv), out)
        if self.form == "milstein":
            corr = eq.Bin("*", eq.Bin("*", eq.Num(0.25), hw), dv)
            out = eq.Bin("+", out, eq.Bin("*", corr, eq.Bin("-", eq.Bin("*", xi, xi),
                                                           eq.Num(1.0))))
        return out


def parse_noise(noise: Any, species: tuple[str, ...], params: Mapping[str, Any],
                inline: Mapping[str, eq.Node]) -> dict[str, eq.Node]:
    """The variance tree of each noisy species from ``noise``: a number or expression for
    every species, or a mapping of species (and ``"*"``, every species not named) to
    numbers or expressions (py-pde's spellings).  ``params``: the stepper's device
    parameters, ``inline``: those given as expressions.  Zero variances are dropped."""
    if isinstance(noise, Mapping):
        bad = sorted(str(k) for k in noise if k != "*" and k not in species)
        if bad:
            raise ValueError(f"noise names {', '.join(map(repr, bad))}, not species of the "
                             f"model; allowed: {', '.join(species)} and '*' (every other)")
        given = {s: noise.get(s, noise.get("*", 0.0)) for s in species}
    else:
        given = dict.fromkeys(species, noise)
    scalars = sorted(p for p, v in params.items()
                     if isinstance(v, (int, float, PerMember)) and not isinstance(v, bool))
    names = [*scalars, *(p for p in params if p not in scalars), *inline]
    out: dict[str, eq.Node] = {}
    for s, v in given.items():
        what = f"noise of {s!r}"
        if isinstance(v, str):
            try:
                tree = eq.parse(v, species=species, params=names, what=what, laplace=False)
            except eq.EquationError as exc:
                raise ValueError(str(exc)) from None
            if eq.derivatives(tree):
                raise ValueError(f"{what} {v!r} takes a derivative; a variance is pointwise")
            out[s] = eq.substitute(tree, lambda n: inline.get(n.name)
                                   if isinstance(n, eq.Ref) and n.kind == "param" else None)
            continue
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer,
                                                                 np.floating)):
            raise TypeError(f"{what} must be a number or an expression (a string), got "
                            f"{type(v).__name__}")
        if not math.isfinite(float(v)) or float(v) < 0:
            raise ValueError(f"{what} is a variance: a finite number >= 0, got {v!r}")
        if float(v) > 0:
            out[s] = eq.Num(float(v))
    return out


def stepper_noise(noise: Any, seed: Any, domain: Domain, scheme: Scheme,
                  species: tuple[str, ...], params: Mapping[str, Any],
                  inline: Mapping[str, eq.Node], interpretation: str = "ito") -> Noise | None:
    """The `Noise` of a stepper (module doc), or None: no noise, or only zero variances.
    ``seed``: the Philox key, a whole number in ``[0, 2**64)``; ``interpretation``: a key
    of `INTERPRETATIONS`."""
    drift = INTERPRETATIONS.get(str(interpretation).lower())
    if drift is None:
        raise ValueError(f"noise_interpretation must be one of "
                         f"{', '.join(map(repr, INTERPRETATIONS))}, got {interpretation!r}")
    if noise is None:
        return None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) \
            or not 0 <= int(seed) < 2 ** 64:
        raise ValueError(f"noise_seed must be a whole number in [0, 2**64), got {seed!r}")
    variance = parse_noise(noise, species, params, inline)
    if not variance:
        return None
    form = getattr(scheme, "noise", None)
    if form not in FORMS:
        able = [n for n, s in SCHEMES.items() if getattr(s, "noise", None) in FORMS]
        raise ValueError(f"noise runs with the stochastic methods {', '.join(able)}, not "
                         f"with {scheme.name!r}")
    streams = tuple(species.index(s) for s in variance)
    w = np.asarray(domain.point_weights, dtype=np.float64)
    if not np.all(w > 0):
        raise ValueError("noise needs every point of the domain to stand for a positive "
                         "volume (domain.point_weights)")
    if np.all(w == w.flat[0]):
        return Noise(variance, int(seed), form, 1.0 / float(w.flat[0]), streams, None, drift)
    return Noise(variance, int(seed), form, None, streams, w, drift)


def noise_buffers(noise: Noise, backend: Backend, shape: tuple[int, ...], kernel_shape:
                  tuple[int, ...], dtype: np.dtype) -> list[DeviceArray]:
    """The device buffers of `Noise.inputs` for a stepper's fields of ``shape`` (an
    ensemble's ``(members, *kernel_shape)``): one per noisy species, then the inverse
    volumes where they are a field."""
    out = [backend.empty(shape, dtype) for _ in noise.variance]
    if noise.inverse_volume is None:
        inv = (1.0 / noise.volumes).reshape(kernel_shape)
        out.append(backend.upload(np.ascontiguousarray(np.broadcast_to(inv, shape),
                                                        dtype=dtype)))
    return out


def draw(noise: Noise, backend: Backend, buffers: list[DeviceArray], step: int) -> None:
    """Fill the number buffers of ``buffers`` for step ``step`` (module doc)."""
    fill = backend.kernel("noise", "normal_fill")
    for k, buf in zip(noise.streams, buffers, strict=False):
        fill(buf, seed=noise.seed, step=int(step), stream=k)
