"""The flat-span grid kernels (OpenCL ``rd_span``, Warp ``spans``): a span of a plane's
interior rows walked as one loop, the x-edge cells recomputed with the boundary rule.

Every span size (one row, a few, the whole interior, spans that do not divide it) on odd,
non-square, tiny and 3-D grids, ensembles, every boundary kind per axis, compact and
isotropic stencils and a bilaplacian, both dtypes: bit for bit the one-row-per-work-item
kernel and the NumPy reference.  Programs that read the x or y coordinate (or a metric)
keep the row kernel.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip

import rdgpu
from rdgpu.backends import opencl_codegen, warp_codegen
from rdgpu.domains.grid import Grid
from rdgpu.integrators import ModelStepper
from rdgpu.models import MODELS, define_model, resolve_params

#: exact operations only (so every backend is bit-identical to NumPy): cross-diffusion, a
#: per-cell parameter field, time, z (constant along a span)
FLAT = define_model(
    "flat-ops",
    {"u": "Du*laplace(u) + c*laplace(v) - u*v*v + a*(1 - u) + 0.01*z*t",
     "v": "Dv*laplace(v) + u*v*v - (a + 0.06)*v - 0.01*laplace(laplace(v))"},
    {"Du": 0.2, "Dv": 0.1, "c": 0.02, "a": 0.04})
#: reads y: keeps the row kernel
WITH_Y = define_model("with-y", {"u": "0.2*laplace(u) - u + 0.01*y"}, {})

GRIDS = [
    Grid((3, 3), dx=0.9, bc="periodic"),
    Grid((11, 7), dx=1.1, dy=0.9, bc=(("dirichlet", 0.3), "periodic")),
    Grid((6, 13), dx=0.9, bc=("periodic", ("dirichlet", 0.2))),
    Grid((9, 5), dx=0.9, bc="neumann"),
    Grid((4, 6, 5), dx=1.0, dy=1.2, dz=0.9, bc=("periodic", ("dirichlet", 0.2), "neumann")),
    Grid((3, 5, 3), dx=0.9, bc=(("dirichlet", 0.1), "neumann", "periodic")),
    Grid((2, 9, 4), dx=0.9, bc="periodic"),
]


def _run(model, grid, backend, dtype, stencil, members=None, steps=3):
    shape = grid.shape if members is None else (members, *grid.shape)
    rng = np.random.default_rng(5)
    params = {"a": rng.uniform(0.03, 0.05, grid.shape)} if "a" in model.defaults else {}
    p = resolve_params(model, grid, params, seed=0)
    st = ModelStepper(model, grid, p, 0.02, rdgpu.get_backend(backend), np.dtype(dtype),
                      "euler", stencil=stencil, members=members)
    st.set_state({s: rng.uniform(0.2, 1.0, shape) for s in model.species})
    st.advance(steps)
    return st.get_state()


def _spans_off(monkeypatch, backend_name):
    if backend_name == "opencl":
        monkeypatch.setattr(opencl_codegen, "SPAN_CELLS", 0)
    else:
        monkeypatch.setattr(warp_codegen, "SPAN_CELLS", 0)


def _set_span_cells(monkeypatch, backend_name, cells):
    module = opencl_codegen if backend_name == "opencl" else warp_codegen
    monkeypatch.setattr(module, "SPAN_CELLS", cells)


@pytest.mark.parametrize("stencil", ["compact", "isotropic"])
@pytest.mark.parametrize("backend_name", ["opencl", "warp"])
def test_spans_equal_rows_and_numpy(backend_name, stencil, dtype, monkeypatch):
    be = backend_or_skip(backend_name)
    for n, grid in enumerate(GRIDS):
        if stencil == "isotropic":  # needs equal spacings
            grid = Grid(grid.shape, dx=0.9, bc=grid.bc)
        for members in (None, 3) if n % 2 else (None,):
            want = _run(FLAT, grid, "numpy", dtype, stencil, members)
            with monkeypatch.context() as m:
                _spans_off(m, backend_name)
                rows = _run(FLAT, grid, be, dtype, stencil, members)
            # spans of 1 row, of 2 rows (not dividing most interiors), of the whole interior
            for cells in (1, 2 * grid.shape[-1], 1 << 20):
                with monkeypatch.context() as m:
                    _set_span_cells(m, backend_name, cells)
                    got = _run(FLAT, grid, be, dtype, stencil, members)
                for s in want:
                    what = f"{backend_name} {grid.shape} {grid.bc} members={members} {cells}"
                    np.testing.assert_array_equal(got[s], want[s], err_msg=what)
                    np.testing.assert_array_equal(got[s], rows[s], err_msg=what)


@pytest.mark.parametrize("backend_name", ["opencl", "warp"])
def test_which_programs_walk_spans(backend_name, monkeypatch):
    """Spans are used where they may be (a coordinate-free program on a grid) and nowhere
    else (a program reading y), and a grid of two rows takes the row kernel; every one
    equals NumPy."""
    be = backend_or_skip(backend_name)
    module = opencl_codegen if backend_name == "opencl" else warp_codegen
    seen = []

    def spy(program, kind):
        seen.append(original(program, kind))
        return seen[-1]

    original = module.flat_rows
    monkeypatch.setattr(module, "flat_rows", spy)
    for model, grid, walks in [(FLAT, GRIDS[1], True), (WITH_Y, GRIDS[1], False),
                               (MODELS["gray-scott"], Grid((2, 40), bc="periodic"), True)]:
        seen.clear()
        got = _run(model, grid, be, np.float32, "compact")
        assert seen and set(seen) == {walks}, model.name
        want = _run(model, grid, "numpy", np.float32, "compact")
        for s in want:
            np.testing.assert_array_equal(got[s], want[s], err_msg=model.name)
    assert not original(None, "mesh")


def test_span_split_covers_every_interior_row():
    """`spans` cuts each plane's interior rows into spans that cover them once, of about
    the asked cells, with four spans per unit of parallel work where rows allow."""
    from rdgpu.backends.target import spans

    assert spans(2, 50, 1, 8192, 2) == (0, 0) and spans(50, 2, 1, 8192, 2) == (0, 0)
    assert spans(50, 50, 1, 0, 2) == (0, 0) and spans(257, 50, 1, 8192, 2) == (0, 0)
    for nx, ny, planes, cells, units in [(96, 96, 96, 8192, 2), (256, 2048, 1, 8192, 2),
                                         (64, 64, 1024, 8192, 2), (5, 3, 1, 8192, 16),
                                         (7, 40, 1, 1, 1), (200, 9, 1, 8192, 8)]:
        span, count = spans(nx, ny, planes, cells, units)
        assert 1 <= span <= ny - 2
        assert (count - 1) * span < ny - 2 <= count * span  # every row once, no empty span
        if span > 1:  # not cut finer than needed
            assert planes * count >= 4 * units
            assert span <= max(1, -(-cells // nx))
