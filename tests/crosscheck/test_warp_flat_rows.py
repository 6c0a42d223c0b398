"""The Warp CPU row loops index flat views at row base + column (``warp_common.flat``,
``row_base``) so that LLVM vectorises them; the one-thread-per-cell kernels (the CUDA
shape, run here on the CPU) compute each cell on their own.  Both shapes must give the same
bits for every family they share a cell formula in, at shapes that exercise the peeled edge
columns, single rows and columns, and the multi-threaded row chunks; grids whose flat
index would overflow 32 bits are refused."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("warp")

import rdgpu  # noqa: E402
from rdgpu.backends.warp_backend import MAX_CELLS, WarpBackend, check_cells  # noqa: E402
from rdgpu.domains.boundary import parse_bc  # noqa: E402
from rdgpu.domains.graph_surface import GraphSurface  # noqa: E402
from rdgpu.domains.grid import Grid  # noqa: E402
from rdgpu.models.library import MODELS  # noqa: E402

# (ny, nx): single rows and columns, two columns (no interior), odd, and 300×257 (above the
# split threshold: row chunks from the thread pool, so row0 > 0)
SHAPES = [(1, 1), (1, 6), (5, 1), (2, 2), (3, 5), (300, 257)]
BCS = ["periodic", "neumann", ("dirichlet", 0.7), (("dirichlet", -0.3), "periodic")]
DTYPES = [np.float32, np.float64]


@pytest.fixture(scope="module")
def shapes_of_launch():
    """``(rows, cells)``: the CPU's row-loop backend and the one-thread-per-cell one."""
    return WarpBackend("cpu"), WarpBackend("cpu", launch="cells")


def rand(shape, dtype, seed, low=-1.0, high=1.0):
    return np.random.default_rng(seed).uniform(low, high, shape).astype(dtype)


def same_bits(run, backends):
    """``run(backend)`` on both launch shapes: equal bit for bit (NaN-safe), and finite."""
    rows, cells = (np.asarray(run(be)) for be in backends)
    assert rows.dtype == cells.dtype and rows.shape == cells.shape
    assert np.isfinite(rows).all()
    assert rows.tobytes() == cells.tobytes()


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
@pytest.mark.parametrize("bc", BCS, ids=["per", "neu", "dir", "dir-per"])
@pytest.mark.parametrize("shape", SHAPES, ids=str)
def test_grid_families(shapes_of_launch, shape, bc, dtype):
    u = rand(shape, dtype, 1, 0.0, 1.0)
    v = rand(shape, dtype, 2, 0.0, 0.5)
    field = rand(shape, dtype, 3, 0.02, 0.06)
    for stencil in (5, 9):
        same_bits(lambda be, s=stencil: rdgpu.laplacian(
            u, dx=0.5, dy=0.5 if s == 9 else 0.8, bc=bc, stencil=s, backend=be),
            shapes_of_launch)
    for F, k in ((0.035, 0.06), (field, 0.06), (0.035, field + 0.01)):
        same_bits(lambda be, F=F, k=k: np.stack(rdgpu.gray_scott(
            u, v, steps=2, Du=0.16, Dv=0.08, F=F, k=k, dt=0.9, dx=1.0, dy=1.3, bc=bc,
            backend=be)), shapes_of_launch)
    phi = rand(shape, dtype, 4, -3.0, 3.0)
    for speed in (-0.8, rand(shape, dtype, 5)):
        same_bits(lambda be, s=speed: rdgpu.levelset_advance(
            phi, s, dt=0.2, steps=2, dx=0.9, dy=0.6, bc=bc, backend=be), shapes_of_launch)
    for subcell in (True, False):
        same_bits(lambda be, s=subcell: rdgpu.reinitialize(
            phi, dx=0.9, dy=0.6, iterations=2, bc=bc, subcell_fix=s, backend=be),
            shapes_of_launch)
    parsed = parse_bc(bc)
    if not any(a.kind == 0 and n % 2 for a, n in zip((parsed.y, parsed.x), shape, strict=True)):
        fixed = np.random.default_rng(12).random(shape) < 0.2  # (odd periodic axes: refused)
        for rhs in (None, field):
            same_bits(lambda be, rhs=rhs: rdgpu.sor_sweep(
                u, fixed, omega=1.7, rhs=rhs, dx=0.5, dy=0.7, bc=bc, backend=be),
                shapes_of_launch)


@pytest.mark.parametrize("shape", [(1, 1, 5), (3, 4, 5), (6, 7, 41)], ids=str)
@pytest.mark.parametrize("bc", BCS[:3], ids=["per", "neu", "dir"])
def test_levelset_3d(shapes_of_launch, shape, bc):
    phi = rand(shape, np.float32, 6, -3.0, 3.0)
    for speed in (-0.8, rand(shape, np.float32, 7)):
        same_bits(lambda be, s=speed: rdgpu.levelset_advance(
            phi, s, dt=0.1, steps=2, dx=0.9, dy=0.6, dz=0.7, bc=bc, backend=be),
            shapes_of_launch)
    same_bits(lambda be: rdgpu.reinitialize(
        phi, dx=0.9, dy=0.6, dz=0.7, iterations=2, bc=bc, backend=be), shapes_of_launch)


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
@pytest.mark.parametrize("shape", SHAPES, ids=str)
def test_metric_laplacian(shapes_of_launch, shape, dtype):
    surface = GraphSurface(shape, dx=0.9, dy=1.1, height=rand(shape, np.float64, 8, -0.5, 0.5))
    for members in ((), (3,)):
        u = rand((*members, *shape), dtype, 9)

        def run(be, u=u):
            out = be.empty(u.shape, dtype)
            be.metric_laplacian(be.upload(u), be.upload_metric(surface, dtype), out)
            return be.download(out)

        same_bits(run, shapes_of_launch)


@pytest.mark.parametrize("name", ["gray-scott", "allen-cahn", "brusselator"])
@pytest.mark.parametrize("domain", [Grid((300, 257), bc="periodic"),
                                    Grid((17, 23), dx=1.2, bc=("dirichlet", 0.3)),
                                    Grid((9, 10, 11), bc="neumann"), Grid((129,))],
                         ids=["2d-big", "2d-dir", "3d", "1d"])
def test_generated_models(shapes_of_launch, domain, name):
    model = MODELS[name]
    params = {"eps": 0.3} if name == "allen-cahn" else {}
    start = {s: rand(domain.shape, np.float64, 10 + i, 0.1, 0.9)
             for i, s in enumerate(model.species)}

    def run(be):
        st = model.stepper(domain, params, dt=0.5 * model.dt_limit(domain, params),
                           backend=be, dtype=np.float32)
        st.set_state(start)
        st.advance(3)
        return np.stack(list(st.get_state().values()))

    same_bits(run, shapes_of_launch)


@pytest.mark.parametrize("n", [1, 17, 4096 * 3 + 5, 300 * 257])
def test_bernoulli(shapes_of_launch, n):
    u = rand((n,), np.float32, 11, -2.0, 2.0)
    same_bits(lambda be: rdgpu.bernoulli_substep(u, tau=0.03, eps=0.2, backend=be),
              shapes_of_launch)


def test_grids_past_32_bit_indices_are_refused(shapes_of_launch):
    check_cells(MAX_CELLS, (MAX_CELLS,))  # the largest allowed
    with pytest.raises(ValueError, match=r"65536x32768 = 2147483648 cells is too large.*"
                                         r"32-bit ints, at most 2147483647 cells"):
        check_cells(2**31, (2**16, 2**15))
    be = shapes_of_launch[0]
    # the launchers check before touching the (here absent) kernels and arguments
    with pytest.raises(ValueError, match="too large for the Warp kernels"):
        be.run_grid((None, None), (2**16, 2**15), [])
    with pytest.raises(ValueError, match="2048x1024x1024 = 2147483648 cells"):
        be.run_grid3((None, None), (2**11, 2**10, 2**10), [])
