"""The measured order in time of ``method="bdf2"`` (and ``"imex"`` for contrast).

    python perf/bdf2_order.py [--backend numpy] [--out perf/results] [--timing opencl]

Writes ``bdf2_order.md`` to ``--out`` (and prints it): for each problem the max error over
the fields at the final time ``T`` for steps ``h = T/n``, and the observed order
``log2(e(h)/e(h/2))`` between neighbouring rows.  Problems (float64, implicit solves to
``tol = 1e-12`` so that the time error is what is measured):

* ``forced mode``: a linear two-species system on a periodic 1-D grid (32 cells, dx =
  0.25), explicit coupling, forced so that ``u = cos(t) φ``, ``v = sin(t) φ`` exactly
  (``φ`` a discrete Fourier mode, ``forced_mode``); the steps are 1-8× the explicit
  limit;
* ``gray-scott``: a Gaussian spot on a periodic 16² grid, ``T = 20``, against SSP-RK3 at
  an eighth of the smallest step (``spot``, ``reference``);
* ``schnakenberg``: the same grid, ``Dv = 40`` (explicit limit 0.006, steps up to 30×
  it), ``T = 2``, against SSP-RK3: stiff, the order reaches 2 only at smaller steps;
* ``gray-scott, mesh``: an icosphere of 162 vertices, the model's mesh defaults.

The problems and the error measure are :mod:`rdgpu.analysis.convergence`'s
(``forced_mode``, ``spot``, ``reference``, ``errors``, ``orders``);
``tests/integrators/test_bdf2.py`` asserts the orders with them.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from rdgpu.analysis.convergence import errors, forced_mode, orders, reference, spot
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.models import MODELS


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
    from rdgpu.integrators.passes import launch

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
