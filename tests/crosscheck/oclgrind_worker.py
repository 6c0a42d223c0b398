"""Run every OpenCL kernel family once on tiny inputs on the Oclgrind simulator (both
layouts, both dtypes, every boundary kind) and compare with the NumPy reference; used by
``test_oclgrind.py`` in a subprocess whose stderr carries Oclgrind's reports."""

from __future__ import annotations

import warnings

import numpy as np

import rdgpu
from rdgpu.backends.opencl_backend import OpenCLBackend
from rdgpu.domains.grid import Grid
from rdgpu.models import MODELS, define_model

warnings.simplefilter("ignore")
rng = np.random.default_rng(0)


def _run(model, domain, start, backend, dtype, stencil):
    opts = {} if stencil is None else {"stencil": stencil}
    dt = 0.2 * model.dt_limit(domain, {}, **opts)
    st = model.stepper(domain, {}, dt=dt, backend=backend, dtype=dtype, **opts)
    st.set_state(start)
    st.advance(2)
    return st.get_state()


def close(a, b, dtype):
    tol = 1e-4 if dtype == np.float32 else 1e-10
    np.testing.assert_allclose(a, b, rtol=tol, atol=tol)


for layout in ("row", "strided"):
    be = OpenCLBackend("oclgrind", layout=layout, col_stride=8 if layout == "strided" else None)
    for dtype in (np.float32, np.float64):
        for shape in [(5, 7), (1, 9), (9,)]:
            u = rng.uniform(0, 1, shape).astype(dtype)
            v = rng.uniform(0, 0.5, shape).astype(dtype)
            for bc in ["periodic", "neumann", ("dirichlet", 0.3)]:
                for stencil in (5, 9):
                    close(rdgpu.laplacian(u, bc=bc, stencil=stencil, backend=be),
                          rdgpu.laplacian(u, bc=bc, stencil=stencil, backend="numpy"), dtype)
                gs = {"Du": 0.2, "Dv": 0.1, "F": 0.04, "k": 0.06, "dt": 0.5, "steps": 2, "bc": bc}
                for a, b in zip(rdgpu.gray_scott(u, v, **gs, backend=be),
                                rdgpu.gray_scott(u, v, **gs, backend="numpy"), strict=True):
                    close(a, b, dtype)
                close(rdgpu.levelset_advance(u - 0.5, 1.0, dt=0.2, bc=bc, backend=be),
                      rdgpu.levelset_advance(u - 0.5, 1.0, dt=0.2, bc=bc, backend="numpy"), dtype)
                close(rdgpu.reinitialize(u - 0.5, iterations=3, bc=bc, backend=be),
                      rdgpu.reinitialize(u - 0.5, iterations=3, bc=bc, backend="numpy"), dtype)
            c = np.zeros((4, 6) if len(shape) == 2 else (8,), dtype)
            fixed = np.zeros(c.shape, bool)
            fixed.flat[0], c.flat[0] = True, 1.0
            close(rdgpu.sor_sweep(c, fixed, omega=1.5, rhs=c * 0.1, backend=be),
                  rdgpu.sor_sweep(c, fixed, omega=1.5, rhs=c * 0.1, backend="numpy"), dtype)
            close(rdgpu.bernoulli_substep(u, tau=0.1, eps=0.5, backend=be),
                  rdgpu.bernoulli_substep(u, tau=0.1, eps=0.5, backend="numpy"), dtype)
        # 3-D level sets: an odd box, mixed per-axis conditions
        p3 = rng.uniform(-1, 1, (3, 4, 5)).astype(dtype)
        for bc in ["periodic", (("dirichlet", -0.2), "neumann", "periodic")]:
            close(rdgpu.levelset_advance(p3, p3, dt=0.1, bc=bc, backend=be),
                  rdgpu.levelset_advance(p3, p3, dt=0.1, bc=bc, backend="numpy"), dtype)
            close(rdgpu.reinitialize(p3, iterations=2, bc=bc, backend=be),
                  rdgpu.reinitialize(p3, iterations=2, bc=bc, backend="numpy"), dtype)
        mesh = rdgpu.SurfaceMesh.icosphere(1)
        x = rng.uniform(0, 1, mesh.n_vertices).astype(dtype)
        close(rdgpu.laplacian(x, mesh=mesh, backend=be),
              rdgpu.laplacian(x, mesh=mesh, backend="numpy"), dtype)
        mgs = {"Du": 0.01, "Dv": 0.005, "F": 0.04, "k": 0.06, "dt": 0.1, "mesh": mesh}
        for a, b in zip(rdgpu.gray_scott(x, x * 0.5, **mgs, backend=be),
                        rdgpu.gray_scott(x, x * 0.5, **mgs, backend="numpy"), strict=True):
            close(a, b, dtype)
        close(rdgpu.diffusion_step(x, D=1.0, dt=10.0, method="crank-nicolson", mesh=mesh,
                                   backend=be),
              rdgpu.diffusion_step(x, D=1.0, dt=10.0, method="crank-nicolson", mesh=mesh,
                                   backend="numpy"), dtype)
        # generated model kernels: 1-D to 3-D grids (compact and isotropic stencils, a
        # bilaplacian pre-pass, a derived field in Allen-Cahn's step) and a mesh
        model = define_model("ocl", {
            "u": "Du*laplace(u) - 0.5*laplace(v) + u - u**3 + 0.1*sin(x + t)",
            "v": "Dv*laplace(v) - 0.01*laplace(laplace(v)) + F*exp(-u*u) - v"},
            {"Du": 0.2, "Dv": 0.1, "F": 0.04})
        flat = define_model("ocl-flat", {
            "u": "Du*laplace(u) - u*v*v + F*(1 - u)",
            "v": "Dv*laplace(v) + u*v*v - (F + 0.06)*v"}, {"Du": 0.2, "Dv": 0.1, "F": 0.04})
        for domain in [Grid((9,), bc=("dirichlet", 0.3)), Grid((3, 5), bc="periodic"),
                       Grid((2, 3, 4), bc=("neumann", ("dirichlet", 0.2), "periodic")),
                       Grid((3, 4, 5), bc=(("dirichlet", 0.1), "neumann", "periodic")),
                       mesh]:
            shape = domain.shape if isinstance(domain, Grid) else (mesh.n_vertices,)
            start = {"u": rng.uniform(0, 1, shape), "v": rng.uniform(0, 1, shape)}
            stencils = ["compact", "isotropic"] if isinstance(domain, Grid) else ["compact"]
            for stencil in stencils:
                got, want = ({s: a for s, a in _run(model, domain, start, b, dtype,
                                                    stencil).items()}
                             for b in (be, "numpy"))
                for s in got:
                    close(got[s], want[s], dtype)
            if isinstance(domain, Grid) and domain.ndim > 1:
                # no coordinate: rd_span's flat loop over a plane's interior rows
                got, want = ({s: a for s, a in _run(flat, domain, start, b, dtype,
                                                    "isotropic").items()}
                             for b in (be, "numpy"))
                for s in got:
                    close(got[s], want[s], dtype)
            ac = MODELS["allen-cahn"]
            got, want = (_run(ac, domain, {"u": start["u"] - 0.5}, b, dtype, None)
                         for b in (be, "numpy"))
            close(got["u"], want["u"], dtype)
        print(f"{layout} {np.dtype(dtype).name} ok", flush=True)
