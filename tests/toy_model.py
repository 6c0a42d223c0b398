"""A toy model for the driver tests: forward-Euler Gray-Scott through the hand-written
kernel, bound by the Model/Stepper contract that ``Simulation`` expects (shared by
tests/simulation and tests/io)."""

from __future__ import annotations

import numpy as np

from rdgpu.core.errors import StabilityError
from rdgpu.domains.grid import Grid
from rdgpu.ops.api import gray_scott_dt_limit
from rdgpu.simulation import Simulation


class ToyStepper:
    """Forward-Euler Gray-Scott on a grid, fields ping-ponged on the device."""

    species = ("u", "v")

    def __init__(self, grid, params, dt, backend, dtype):
        self.grid, self.dt, self.backend, self.dtype = grid, dt, backend, np.dtype(dtype)
        self.p = {k: (backend.upload(np.ascontiguousarray(v, self.dtype))
                      if isinstance(v, np.ndarray) else float(v)) for k, v in params.items()}
        self.cur = self.nxt = None

    def set_state(self, fields):
        be = self.backend
        self.cur = {s: be.upload(np.ascontiguousarray(fields[s], self.dtype)) for s in self.species}
        self.nxt = {s: be.empty_like(self.cur[s]) for s in self.species}

    def state(self):
        return dict(self.cur)

    def advance(self, steps):
        p, g = self.p, self.grid
        for _ in range(steps):
            self.backend.gray_scott(
                self.cur["u"], self.cur["v"], self.nxt["u"], self.nxt["v"], Du=p["Du"],
                Dv=p["Dv"], F=p["F"], k=p["k"], dt=self.dt, dx=g.dx, dy=g.dy, bc=g.bcs,
            )
            self.cur, self.nxt = self.nxt, self.cur

    def get_state(self):
        return {s: self.cur[s].numpy() for s in self.species}


class ToyGrayScott:
    name = "toy-gray-scott"
    species = ("u", "v")
    defaults = {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.060}
    description = "Gray-Scott for the driver tests"
    default_init = {"kind": "square", "values": {"u": 1.0, "v": 0.0},
                    "inside": {"u": 0.5, "v": 0.25}, "size": 0.2, "noise": 0.05}

    def dt_limit(self, domain, params):
        return gray_scott_dt_limit(params["Du"], params["Dv"], domain.dx, domain.dy)

    def stepper(self, domain, params, *, dt, backend, dtype, check_stability=True):
        if check_stability and dt > self.dt_limit(domain, params):
            raise StabilityError("dt is past the stability limit")
        return ToyStepper(domain, params, dt, backend, dtype)


TOY = ToyGrayScott()
SQUARE = ToyGrayScott.default_init


def toy_sim(backend="numpy", shape=(32, 32), **kw):
    kw.setdefault("dt", 1.0)
    return Simulation(TOY, Grid(shape), kw.pop("params", None), backend=backend, **kw)
