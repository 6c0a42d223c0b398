"""Convergence studies: manufactured solutions and the measured order of a time stepper.

* `forced_mode` — a linear two-species system on a periodic 1-D grid, forced so that
  ``u = cos(t) φ``, ``v = sin(t) φ`` solve it exactly (``φ`` a discrete Fourier mode);
* `spot` — Gray-Scott's Gaussian spot on a grid or on a unit sphere;
* `run_fixed_steps`, `reference` (SSP-RK3 at a tiny step), `errors` and
  `orders` — the error at ``T`` for steps ``h = T/n`` and the observed order between
  neighbouring ``n``;
* `space_time_error` — seed 002 §4's manufactured reaction-diffusion system on a
  rough surface (``rdgpu/families/metric/exact.py``), space and time refined together.

``perf/bdf2_order.py`` and ``perf/surface_rds.py`` print the tables; the tests
(``tests/integrators/test_bdf2.py``, ``tests/theory/test_surface_rds.py``) assert the orders.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from rdgpu.domains.grid import Grid
from rdgpu.families import load_module
from rdgpu.models import define_model, domain_shape
from rdgpu.simulation.driver import Simulation

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["errors", "forced_mode", "orders", "reference", "run_fixed_steps",
           "space_time_error", "spot", "SURFACE_T"]

#: the final time of `space_time_error`
SURFACE_T = 0.5


def forced_mode(n_cells: int = 32, length: float = 8.0, k: int = 4):
    """``(model, grid, params, init, exact)``: ``u_t = Du Δu + a u + b v + F_u(t) φ``,
    ``v_t = Dv Δv + c u + d v + F_v(t) φ`` on a periodic 1-D grid, ``φ = sin(wx)`` an
    eigenvector of the 3-point Laplacian (eigenvalue ``−m``), ``F`` chosen so that ``u =
    cos(t) φ``, ``v = sin(t) φ`` solve it exactly; ``exact(T)`` is that solution."""
    dx = length / n_cells
    grid = Grid((n_cells,), dx=dx, bc="periodic")
    m = 4 / dx**2 * math.sin(math.pi * k / n_cells) ** 2
    Du, Dv, a, b, c, d = 1.0, 0.5, -0.5, 1.0, -1.0, 0.2
    params = {"Du": Du, "Dv": Dv, "a": a, "b": b, "c": c, "d": d,
              "w": 2 * math.pi * k / length,
              "p1": Du * m - a, "p2": -1 - b, "q1": 1 - c, "q2": Dv * m - d}
    model = define_model("forced-mode", {
        "u": "Du*laplace(u) + a*u + b*v + (p1*cos(t) + p2*sin(t))*sin(w*x)",
        "v": "Dv*laplace(v) + c*u + d*v + (q1*cos(t) + q2*sin(t))*sin(w*x)"}, params)
    phi = np.sin(params["w"] * (np.arange(n_cells) + 0.5) * dx)

    def exact(T: float) -> dict[str, np.ndarray]:
        return {"u": math.cos(T) * phi[None], "v": math.sin(T) * phi[None]}

    return model, grid, params, {"u": phi.copy(), "v": np.zeros_like(phi)}, exact


def spot(domain: Domain) -> dict[str, np.ndarray]:
    """Gray-Scott's ``u = 1 − ½g``, ``v = ¼g`` with ``g`` a Gaussian spot (variance 4 on a
    grid with dx = 1, centred; on a unit sphere a cap around +z)."""
    if not domain.unstructured:
        yy, xx = np.indices(domain.shape)
        cy, cx = (domain.shape[0] - 1) / 2 + 0.5, (domain.shape[1] - 1) / 2 + 0.5
        g = np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / 8.0)
    else:
        g = np.exp(-4.0 * (1.0 - np.asarray(domain.vertices)[:, 2]))
    return {"u": 1.0 - 0.5 * g, "v": 0.25 * g}


def run_fixed_steps(model, domain, params, init, T: float, n: int, method: str = "bdf2",
                    backend: str = "numpy", tol: float | None = 1e-12) -> dict[str, np.ndarray]:
    """The fields after ``n`` steps of ``T/n`` (float64; implicit solves to ``tol``)."""
    st = model.stepper(domain, params, dt=T / n, backend=backend, method=method,
                       check_stability=False, tol=tol)
    st.set_state(init)
    st.advance(n)
    return st.get_state()


def reference(model, domain, params, init, T: float, n_max: int) -> dict[str, np.ndarray]:
    """SSP-RK3 at half the explicit limit and at most ``T/(8 n_max)``: at ⅛ of the
    smallest step tested its third-order error is far below the tested methods'."""
    n = max(math.ceil(T / (0.5 * model.dt_limit(domain, params, "euler"))), 8 * n_max)
    return run_fixed_steps(model, domain, params, init, T, n, "rk3")


def errors(model, domain, params, init, T: float, ns, ref: dict[str, np.ndarray],
           method: str = "bdf2", backend: str = "numpy") -> list[float]:
    """Max error over every field at ``T`` for each ``n`` of ``ns``."""
    out = []
    for n in ns:
        got = run_fixed_steps(model, domain, params, init, T, n, method, backend)
        shape = domain_shape(domain)
        out.append(max(float(np.max(np.abs(got[s].reshape(shape) - ref[s].reshape(shape))))
                       for s in model.species))
    return out


def orders(ns, errs) -> list[float]:
    """``log(e_i/e_{i+1}) / log(n_{i+1}/n_i)`` between neighbouring rows."""
    return [math.log(errs[i] / errs[i + 1]) / math.log(ns[i + 1] / ns[i])
            for i in range(len(ns) - 1)]


def space_time_error(n: int, method: str, backend: str = "numpy",
                     dtype: str = "float64") -> float:
    """Seed 002 §4's manufactured two-species system (``manufactured_rds``: a graph surface
    over ``[0, 2π]²``, exact solution ``u = e^{−t}φ``, ``v = e^{−t}ψ``) on ``n²`` cells,
    ``n/4`` steps to `SURFACE_T` (``dt ∝ dx``) by ``method``: the max over the species
    of the relative ℓ² error."""
    problem = load_module("metric", "exact.py").manufactured_rds(n)
    model = define_model("manufactured", problem["equations"],
                         {"Du": 1.0, "Dv": 0.5, "Au": 0.0, "Av": 0.0, "P": 0.0})
    steps = max(n // 4, 1)
    sim = Simulation(model, problem["domain"], problem["params"], dt=SURFACE_T / steps,
                     backend=backend, dtype=dtype, fields=problem["fields"],
                     options={"method": method})
    result = sim.run(steps, progress=False)
    return max(float(np.sqrt(np.mean((result.fields[s] - e) ** 2) / np.mean(e**2)))
               for s, e in zip("uv", problem["exact"](SURFACE_T), strict=True))
