"""Strang splitting of the modified Allen-Cahn model (`rdgpu.models.allen_cahn.AllenCahn`)
on the device: the exact Bernoulli substep (`rdgpu.ops.api.bernoulli_decay`), explicit
or implicit diffusion in between (its form in the functional API, ``rdgpu.allen_cahn``, is
`rdgpu.models.allen_cahn.allen_cahn`).  Its methods are its own (``explicit``,
``implicit``, ``crank-nicolson``); the implicit ones take θ from the IMEX schemes of
`rdgpu.ir.schemes.SCHEMES` (``imex``: θ = 1, ``imex-cn``: θ = ½)."""

from __future__ import annotations

import numpy as np

from rdgpu.backends.target import Target
from rdgpu.integrators.passes import launch
from rdgpu.integrators.stepper import FieldStepper
from rdgpu.ir import equations as eq
from rdgpu.ir.program import Output, Program
from rdgpu.ir.schemes import get_scheme
from rdgpu.ops.api import bernoulli_decay
from rdgpu.ops.implicit import ImplicitDiffusion

__all__ = ["METHODS", "AllenCahnStepper"]

#: Allen-Cahn's diffusion methods and the scheme whose θ each takes (explicit: Euler)
METHODS = {"explicit": "euler", "implicit": "imex", "crank-nicolson": "imex-cn"}


def _strang_program() -> Program:
    """The rest of an explicit Strang step after the first Bernoulli substep ``ū = B(u)``
    (``backend.bernoulli``), in one fused pass: ``B(ū + h (1·Δū + (−b)/ε²))`` with
    ``B(x) = x/√(d + x²(1 − d))`` the exact substep for ``h/2`` (``d = e^{−h/ε²}``; the
    operations of rdgpu/families/bernoulli).  Two passes per step; a resumed run stays bit
    for bit equal to an uninterrupted one (why this form, and what the others measured:
    docs/performance.md, "Models: one fused kernel per step")."""
    names = ("h", "b", "eps2", "d", "omd")
    y = "(u + h*(1.0*laplace(u) + (-b)/eps2))"
    tree = eq.parse(f"{y}/sqrt(d + {y}*{y}*omd)", species=("u",), params=names)
    tree = eq.substitute(tree, lambda n: eq.Ref("builtin", "_" + n.name)
                         if isinstance(n, eq.Ref) and n.name in ("h", "d", "omd") else None)
    return Program(("u",), (Output("u", tree),))


_STRANG = _strang_program()


class AllenCahnStepper(FieldStepper):
    """Strang splitting of the modified Allen-Cahn equation on the device (see
    `rdgpu.models.AllenCahn`).  Per step: Bernoulli ``dt/2`` → diffusion ``dt`` → Bernoulli
    ``dt/2``; three device buffers, no host transfer (the implicit methods download the
    SOR's per-vertex change to test convergence)."""

    def __init__(self, model, domain, params, dt, backend, dtype, method):
        super().__init__(model.species, domain, dt, backend, dtype)
        self.model = model
        self.params = dict(params)
        self.method = method
        eps = float(params["eps"])
        self.decay = bernoulli_decay(self.dt / 2.0, eps, self.dtype)
        b = params["b"]
        self._b = (backend.upload(np.ascontiguousarray(b, dtype=self.dtype))
                   if isinstance(b, np.ndarray) else float(b))
        self._kparams = {"b": self._b, "eps2": eps * eps}
        self._tmp = backend.empty(self.shape, self.dtype)
        if method == "explicit":
            self._target = Target.bind(domain, backend, self.dtype)
        else:
            self._implicit = _implicit_solver(domain, backend, self.dtype, self.dt, method)
            # the source −b/ε² enters the θ-scheme of ū_t = Δū − b/ε² directly:
            # (I − θ dt L) ū' = ū + (1 − θ) dt L ū − dt b/ε²
            self._source = (backend.upload(np.ascontiguousarray(-b / (eps * eps),
                                                                dtype=self.dtype))
                            if isinstance(b, np.ndarray) else -float(b) / (eps * eps))
            self._rhs = backend.empty(self.shape, self.dtype)  # the diffusion result

    def _step(self) -> None:
        be = self.backend
        (x,), (y,) = self._x, self._y
        be.bernoulli(x, self._tmp, decay=self.decay)
        if self.method == "explicit":
            t = self.dtype.type
            launch(_STRANG, self._target, [self._tmp], [y], self._kparams,
                   {"_h": self.dt, "_d": self.decay, "_omd": float(t(1) - t(self.decay))})
            return
        self._implicit.step(self._tmp, self._rhs, source=self._source)
        be.bernoulli(self._rhs, y, decay=self.decay)


def _implicit_solver(domain, backend, dtype, dt, method):
    """The θ-step solver of ``ū_t = Δū + s``: ``(I − θ dt L) out = u + (1 − θ) dt L u +
    dt s`` with the θ of `METHODS`' scheme (backward Euler for ``"implicit"``, ½ for
    ``"crank-nicolson"``), by `rdgpu.ops.implicit.ImplicitDiffusion`: directly by fast
    transforms on a rectangular grid, by multicolour SOR on the device elsewhere."""
    theta = get_scheme(METHODS[method]).theta
    return ImplicitDiffusion(domain, D=1.0, dt=dt, theta=theta, backend=backend, dtype=dtype)
