"""The measured order in time of ``method="bdf2"`` (and ``"imex"`` for contrast).

    python perf/bdf2_order.py [--backend numpy] [--out perf/results] [--timing opencl]

Writes ``bdf2_order.md`` to ``--out`` (and prints it): for each problem the max error over
the fields at the final time ``T`` for steps ``h = T/n``, and the observed order
``log2(e(h)/e(h/2))`` between neighbouring rows.  Problems (float64, implicit solves to
``tol = 1e-12`` so that the time error is what is measured):

* ``forced mode``: a linear two-species system on a periodic 1-D grid (32 cells, dx =
  0.25), explicit coupling, forced so that ``u = cos(t) φ``, ``v = sin(t) φ`` exactly
  (``φ`` a discrete Fourier mode, :func:`forced_mode`); the steps are 1-8× the explicit
  limit;
* ``gray-scott``: a Gaussian spot on a periodic 16² grid, ``T = 20``, against SSP-RK3 at
  an eighth of the smallest step (:func:`spot`, :func:`reference`);
* ``schnakenberg``: the same grid, ``Dv = 40`` (explicit limit 0.006, steps up to 30×
  it), ``T = 2``, against SSP-RK3: stiff, the order reaches 2 only at smaller steps;
* ``gray-scott, mesh``: an icosphere of 162 vertices, the model's mesh defaults.

The tests (``tests/integrators/test_bdf2.py``) use :func:`forced_mode`, :func:`spot` and
:func:`errors` and assert the orders.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.models import MODELS, define_model, domain_shape


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


def spot(domain: Any) -> dict[str, np.ndarray]:
    """Gray-Scott's ``u = 1 − ½g``, ``v = ¼g`` with ``g`` a Gaussian spot (variance 4 on a
    grid with dx = 1, centred; on a unit sphere a cap around +z)."""
    if isinstance(domain, Grid):
        yy, xx = np.indices(domain.shape)
        cy, cx = (domain.shape[0] - 1) / 2 + 0.5, (domain.shape[1] - 1) / 2 + 0.5
        g = np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / 8.0)
    else:
        g = np.exp(-4.0 * (1.0 - np.asarray(domain.vertices)[:, 2]))
    return {"u": 1.0 - 0.5 * g, "v": 0.25 * g}


def run(model, domain, params, init, T: float, n: int, method: str = "bdf2",
        backend: str = "numpy", tol: float | None = 1e-12) -> dict[str, np.ndarray]:
    """The fields after ``n`` steps of ``T/n`` (float64)."""
    st = model.stepper(domain, params, dt=T / n, backend=backend, method=method,
                       check_stability=False, tol=tol)
    st.set_state(init)
    st.advance(n)
    return st.get_state()


def reference(model, domain, params, init, T: float, n_max: int) -> dict[str, np.ndarray]:
    """SSP-RK3 at half the explicit limit and at most ``T/(8 n_max)``: at ⅛ of the
    smallest step tested its third-order error is far below the tested methods'."""
    n = max(math.ceil(T / (0.5 * model.dt_limit(domain, params, "euler"))), 8 * n_max)
    return run(model, domain, params, init, T, n, "rk3")


def errors(model, domain, params, init, T: float, ns, ref: dict[str, np.ndarray],
           method: str = "bdf2", backend: str = "numpy") -> list[float]:
    """Max error over every field at ``T`` for each ``n`` of ``ns``."""
    out = []
    for n in ns:
        got = run(model, domain, params, init, T, n, method, backend)
        shape = domain_shape(domain)
        out.append(max(float(np.max(np.abs(got[s].reshape(shape) - ref[s].reshape(shape))))
                       for s in model.species))
    return out


def orders(ns, errs) -> list[float]:
    """``log(e_i/e_{i+1}) / log(n_{i+1}/n_i)`` between neighbouring rows."""
    return [math.log(errs[i] / errs[i + 1]) / math.log(ns[i + 1] / ns[i])
            for i in range(len(ns) - 1)]


def problems():
    """``(name, model, domain, params, init, T, ns, reference)`` of the module doc."""
    model, grid, params, init, exact = forced_mode()
    yield "forced mode (exact solution)", model, grid, params, init, 2.0, \
        [8, 16, 32, 64, 128], exact(2.0)
    grid = Grid((16, 16), dx=1.0, bc="periodic")
    gs, sch = MODELS["gray-scott"], MODELS["schnakenberg"]
    yield "gray-scott 16² (RK3 reference)", gs, grid, {}, spot(grid), 20.0, \
        [10, 20, 40, 80, 160], None
    yy, xx = np.indices(grid.shape)
    init = {"u": 1.0 + 0.3 * np.sin(2 * np.pi * xx / 16) * np.cos(2 * np.pi * yy / 16),
            "v": 0.9 + 0.2 * np.cos(2 * np.pi * (xx + yy) / 16)}
    yield "schnakenberg 16², Dv = 40 (RK3 reference)", sch, grid, {}, init, 2.0, \
        [10, 20, 40, 80, 160, 320], None
    mesh = SurfaceMesh.icosphere(2)
    yield f"gray-scott, icosphere of {mesh.n_vertices} vertices (RK3 reference)", gs, mesh, \
        gs.domain_defaults(mesh), spot(mesh), 20.0, [10, 20, 40, 80, 160], None


def table(backend: str = "numpy") -> str:
    lines = ["# BDF2: the measured order in time", "",
             f"`python perf/bdf2_order.py --backend {backend}` (float64; max error over the "
             "fields at T; order = log2 of the ratio of neighbouring errors).", ""]
    for name, model, domain, params, init, T, ns, ref in problems():
        t0 = time.perf_counter()
        if ref is None:
            ref = reference(model, domain, params, init, T, max(ns))
        limit = model.dt_limit(domain, params, "euler")
        e_bdf = errors(model, domain, params, init, T, ns, ref, "bdf2", backend)
        e_imex = errors(model, domain, params, init, T, ns, ref, "imex", backend)
        o_bdf, o_imex = orders(ns, e_bdf), orders(ns, e_imex)
        lines += [f"## {name}", "",
                  f"T = {T:g}, explicit limit {limit:.3g}; {time.perf_counter() - t0:.1f} s",
                  "", "| n | h | h / limit | bdf2 error | order | imex error | order |",
                  "|---:|---:|---:|---:|---:|---:|---:|"]
        for i, n in enumerate(ns):
            ob = f"{o_bdf[i - 1]:.2f}" if i else ""
            oi = f"{o_imex[i - 1]:.2f}" if i else ""
            lines.append(f"| {n} | {T / n:.4g} | {T / n / limit:.2f} | {e_bdf[i]:.3e} | {ob} "
                         f"| {e_imex[i]:.3e} | {oi} |")
        lines.append("")
    return "\n".join(lines)


def timing(backend: str, size: int = 128, steps: int = 20) -> str:
    """Wall time per step of ``imex`` and ``bdf2`` (and of their explicit passes alone) for
    Gray-Scott on a periodic ``size²`` grid, float32, dt = 1, after two warm-up steps;
    best of three runs of ``steps`` steps."""
    from rdgpu.models.compiler import launch

    gs = MODELS["gray-scott"]
    grid = Grid((size, size), dx=1.0, bc="periodic")
    rows = [f"## cost per step: gray-scott {size}², float32, dt = 1, {backend}", "",
            "| method | ms per step | explicit pass alone, ms |", "|---|---:|---:|"]
    for method in ("imex", "bdf2"):
        st = gs.stepper(grid, {}, dt=1.0, backend=backend, dtype=np.float32, method=method)
        st.set_state(spot(grid))
        st.advance(2)  # compiled, and BDF2 past its start step
        per_step = math.inf
        for _ in range(3):  # best of three: the machine is shared
            st.backend.synchronize()
            t0 = time.perf_counter()
            st.advance(steps)
            st.backend.synchronize()
            per_step = min(per_step, (time.perf_counter() - t0) / steps)
        program, extra = (st._bdf2, st._prev) if method == "bdf2" else (st._euler, [])
        ins = [*st._x, *extra]
        launch(program, st.target, ins, st._y, st._device_params,
           {"_h": 1.0, "_b": 2 / 3, "_tp": 0.0})
        explicit = math.inf
        for _ in range(3):
            st.backend.synchronize()
            t0 = time.perf_counter()
            for _ in range(steps):
                launch(program, st.target, ins, st._y, st._device_params,
                       {"_h": 1.0, "_b": 2 / 3, "_tp": 0.0})
            st.backend.synchronize()
            explicit = min(explicit, (time.perf_counter() - t0) / steps)
        rows.append(f"| {method} | {1e3 * per_step:.2f} | {1e3 * explicit:.3f} |")
    return "\n".join(rows) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", default="numpy", help="numpy (default), warp or opencl")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results"))
    ap.add_argument("--timing", metavar="BACKEND", default="opencl",
                    help="also time a step of each method on BACKEND (default opencl; "
                    "'none' to skip)")
    args = ap.parse_args()
    text = table(args.backend)
    if args.timing != "none":
        text += "\n" + timing(args.timing)
    print(text)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "bdf2_order.md").write_text(text + "\n")


if __name__ == "__main__":
    main()
