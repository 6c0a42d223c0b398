"""Masked domains (issue 23, item 4; `rdgpu.integrators.masks`): fields evolve inside a
mask only, with zero flux across its edge.  Every backend equals the NumPy reference bit
for bit on odd grids, both dtypes and every boundary kind; a 1-D mask is a Neumann grid of
its size bit for bit; diffusion conserves the mass inside to round-off and leaves the
outside unchanged; the masked disc's lowest Neumann eigenvalue converges to the exact
``j'₁₁²/R²`` with rdgpu's disc mesh; bad masks are refused by name."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import backend_or_skip
from scipy.sparse.linalg import eigsh

import rdgpu
from rdgpu.cli.app import main
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.models import define_model

PAIR = define_model("masked-pair", {
    "u": "0.2*laplace(u) - u*v*v + 0.03*(1 - u) + 0.05*d_dx(v)",
    "v": "div((0.05 + 0.05*u)*grad(v)) + u*v*v - 0.09*v"})
HEAT = define_model("heat", {"u": "laplace(u)"})
DISC = "(x - Lx/2)**2 + (y - Ly/2)**2 < (0.4*Lx)**2"
#: the first nonzero Neumann eigenvalue of the unit disc: j'₁₁² (j'₁₁ = 1.8411837813...)
J11 = 1.8411837813406593 ** 2


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shape, bc", [((9,), "neumann"), ((7, 11), "periodic"),
                                       ((12, 9), ("dirichlet", 0.5)), ((5, 6, 7), "neumann")])
def test_every_backend_matches_the_reference(backend, dtype, shape, bc):
    grid = Grid(shape, dx=0.8, bc=bc)
    rng = np.random.default_rng(5)
    fields = {"u": rng.uniform(0.3, 1, grid.field_shape), "v": rng.uniform(0, 0.5,
                                                                          grid.field_shape)}
    mask = "x + 0.5*sin(y) > 1.3" if len(shape) > 1 else "x > 1.3"
    runs = []
    for be in ("numpy", backend):
        st = PAIR.stepper(grid, dt=0.2, backend=be, dtype=dtype, mask=mask, method="heun")
        st.set_state(fields)
        st.advance(7)
        runs.append(st.get_state())
    inside = st.mask.reshape(grid.field_shape) > 0
    assert 0 < inside.sum() < inside.size
    for s in "uv":
        np.testing.assert_array_equal(runs[1][s], runs[0][s], err_msg=s)
        out = runs[0][s].reshape(grid.field_shape)
        assert np.array_equal(out[~inside], fields[s].astype(dtype)[~inside])


def test_a_one_dimensional_mask_is_a_neumann_grid():
    """Cells 0..12 of a periodic 20-cell line masked: bit for bit a 13-cell Neumann line
    (every neighbour outside reads as the edge cell: the Neumann ghost)."""
    u0 = np.random.default_rng(1).uniform(0, 1, 20)
    st = HEAT.stepper(Grid((20,), bc="periodic"), dt=0.3, backend="numpy", mask="x < 13")
    st.set_state({"u": u0})
    st.advance(40)
    alone = HEAT.stepper(Grid((13,), bc="neumann"), dt=0.3, backend="numpy")
    alone.set_state({"u": u0[:13]})
    alone.advance(40)
    got = st.get_state()["u"].ravel()
    np.testing.assert_array_equal(got[:13], alone.get_state()["u"].ravel())
    np.testing.assert_array_equal(got[13:], u0[13:])


def test_diffusion_conserves_the_mass_inside(backend):
    grid = Grid((48, 40), bc="periodic")
    u0 = np.random.default_rng(2).uniform(0, 1, grid.shape)
    model = define_model("d", {"u": "div((1 + 0.5*u)*grad(u))"})
    st = model.stepper(grid, dt=0.05, backend=backend, mask=DISC)
    st.set_state({"u": u0})
    st.advance(300)
    u = st.get_state()["u"].reshape(grid.shape)
    inside = st.mask.reshape(grid.shape) > 0
    assert u[inside].sum() == pytest.approx(u0[inside].sum(), rel=1e-12)
    assert np.array_equal(u[~inside], u0[~inside])
    assert u[inside].std() < 0.2 * u0[inside].std()  # it diffused


def _masked_operator(n: int, radius: float) -> tuple[sp.csr_matrix, np.ndarray]:
    """The masked Laplacian of a disc of ``radius`` on an n² grid over [0, 2.5 R]²,
    assembled independently (each cell: its inside neighbours' differences), and the
    mask."""
    grid = Grid((n, n), dx=2.5 * radius / n, bc="neumann")
    st = HEAT.stepper(grid, dt=1e-3, backend="numpy", check_stability=False,
                      mask=f"(x - Lx/2)**2 + (y - Ly/2)**2 < {radius}**2")
    inside = st.mask.reshape(n, n) > 0
    index = -np.ones((n, n), dtype=int)
    index[inside] = np.arange(inside.sum())
    rows, cols, vals = [], [], []
    h2 = grid.dx ** 2
    for i, j in zip(*np.nonzero(inside), strict=True):
        for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            a, b = i + di, j + dj
            if 0 <= a < n and 0 <= b < n and inside[a, b]:
                rows += [index[i, j], index[i, j]]
                cols += [index[a, b], index[i, j]]
                vals += [1 / h2, -1 / h2]
    L = sp.csr_matrix((vals, (rows, cols)), shape=(inside.sum(),) * 2)
    # the stepper's own operator on a random field is this matrix's product
    u = np.random.default_rng(0).uniform(0, 1, (n, n))
    lap = _step_rate(st, u, grid)
    np.testing.assert_allclose(lap[inside], L @ u[inside], rtol=1e-12, atol=1e-9)
    return L, inside


def _step_rate(st, u, grid):
    """``(one Euler step − u)/dt``: the stepper's right-hand side."""
    st.set_state({"u": u}, steps=0)
    st.advance(1)
    return (st.get_state()["u"].reshape(grid.shape) - u) / st.dt


def test_the_masked_disc_converges_with_the_disc_mesh():
    """The smallest nonzero eigenvalue of ``−Δ`` with zero flux on the unit disc, j'₁₁² =
    3.3900: the masked grid's (a staircase edge: first order) and the disc mesh's
    (`SurfaceMesh.disc`) approach it as they refine, within 2 % at the finest."""
    masked = []
    for n in (40, 80, 160):
        L, _ = _masked_operator(n, 1.0)
        vals = eigsh(-L, k=3, sigma=-0.1, which="LM", return_eigenvectors=False)
        masked.append(sorted(vals)[1])  # past the constant's 0
    mesh = [SurfaceMesh.disc(rings=r).smallest_eigenvalue()[0] for r in (8, 16, 32)]
    err_masked = [abs(v - J11) / J11 for v in masked]
    err_mesh = [abs(v - J11) / J11 for v in mesh]
    assert err_masked[-1] < 0.02 and err_mesh[-1] < 0.002
    assert err_masked[-1] < err_masked[0] and err_mesh[-1] < err_mesh[0]
    assert abs(masked[-1] - mesh[-1]) / J11 < 0.02


def test_bad_masks_are_refused():
    grid = Grid((8, 8), bc="neumann")
    cases = [
        ({"mask": "x < 0"}, ValueError, "holds no cell"),
        ({"mask": "x < t"}, ValueError, "uses t"),
        ({"mask": "z < 2"}, ValueError, "axis the grid lacks"),
        ({"mask": "q < 2"}, ValueError, "q"),
        ({"mask": np.ones((8, 9))}, ValueError, "shape \\(8, 9\\)"),
        ({"mask": np.full((8, 8), np.nan)}, ValueError, "not finite"),
        ({"mask": "x < 4", "method": "etdrk4"}, ValueError, "explicit Runge-Kutta and"),
        ({"mask": "x < 4", "method": "ab2"}, ValueError, "explicit Runge-Kutta and"),
        ({"mask": "x < 4", "stencil": "isotropic"}, ValueError, "isotropic stencil"),
    ]
    for kw, exc, msg in cases:
        with pytest.raises(exc, match=msg):
            HEAT.stepper(grid, dt=0.1, backend="numpy", **kw)
    with pytest.raises(ValueError, match="masked"):
        HEAT.stepper(grid, dt=0.1, backend=backend_or_skip("opencl"), mask="x < 4",
                     block_steps=2)
    with pytest.raises(ValueError, match="not on a mesh"):
        HEAT.stepper(SurfaceMesh.icosphere(1), dt=0.01, backend="numpy", mask="x < 0")


def test_the_command_line_masks_a_disc_and_reads_a_picture(tmp_path):
    """``--mask EXPR`` and ``--mask PICTURE``: the run's picture is grey outside the mask
    (the same cells for both), the pattern inside."""
    import imageio.v3 as iio

    pic = tmp_path / "mask.png"
    yy, xx = np.mgrid[0:64, 0:64]
    iio.imwrite(pic, (((xx - 31.5) ** 2 + (yy - 31.5) ** 2 < 25.6 ** 2) * 255).astype(np.uint8))
    outs = []
    for mask in ("(x-Lx/2)**2 + (y-Ly/2)**2 < (0.4*Lx)**2", str(pic)):
        out = tmp_path / f"run{len(outs)}.png"
        assert main(["run", "gray-scott", "--size", "64", "--steps", "300", "--backend",
                     "numpy", "--mask", mask, "--out", str(out), "--quiet"]) == 0
        outs.append(iio.imread(out)[..., :3])
    grey = np.all(outs[0] == 128, axis=2)
    assert grey[0, 0] and not grey[32, 32]
    np.testing.assert_array_equal(grey, np.all(outs[1] == 128, axis=2))
    res = rdgpu.Simulation("gray-scott", Grid((16, 16)), backend="numpy",
                           options={"mask": "x < Lx/2"}).run(5, progress=False)
    assert res.mask.shape == (16, 16) and res.mask[:, :8].all() and not res.mask[:, 8:].any()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_edge_conditions_match_the_reference(backend, dtype):
    """``mask_bc``: a face value of x and t for ``u``, Robin for ``v`` reading ``u`` at
    the edge cell on the mask's edge; every backend equals the NumPy reference bit for bit
    (only + − × ÷)."""
    grid = Grid((9, 13), dx=0.7, bc="periodic")
    rng = np.random.default_rng(8)
    fields = {s: rng.uniform(0.2, 1, grid.shape) for s in "uv"}
    edge = {"u": ("value", "0.5 + 0.1*x*t"), "v": ("robin", 2.0, "0.3*u")}
    runs = []
    for be in ("numpy", backend):
        st = PAIR.stepper(grid, dt=0.1, backend=be, dtype=dtype, mask=DISC, mask_bc=edge)
        st.set_state(fields)
        st.advance(6)
        runs.append(st.get_state())
    for s in "uv":
        np.testing.assert_array_equal(runs[1][s], runs[0][s], err_msg=s)
    plain = PAIR.stepper(grid, dt=0.1, backend="numpy", dtype=dtype, mask=DISC)
    plain.set_state(fields)
    plain.advance(6)
    assert not np.array_equal(plain.get_state()["u"], runs[0]["u"])  # the edge counts


def test_a_masked_line_with_a_face_value_is_a_grid_with_that_condition():
    """Cells 0..12 of a periodic line, the face value 1 on the mask's edge: bit for bit a
    13-cell grid with ``bc={"u": ("value", 1)}`` on both sides."""
    u0 = np.random.default_rng(4).uniform(0, 1, 20)
    st = HEAT.stepper(Grid((20,), bc="periodic"), dt=0.3, backend="numpy", mask="x < 13",
                      mask_bc={"u": ("value", 1.0)})
    st.set_state({"u": u0})
    st.advance(40)
    alone = HEAT.stepper(Grid((13,), bc="neumann"), dt=0.3, backend="numpy",
                         bc={"u": ("value", 1.0)})
    alone.set_state({"u": u0[:13]})
    alone.advance(40)
    np.testing.assert_array_equal(st.get_state()["u"].ravel()[:13],
                                  alone.get_state()["u"].ravel())
    with pytest.raises(ValueError, match="mask_bc names 'w'"):
        HEAT.stepper(Grid((20,)), dt=0.3, backend="numpy", mask="x < 13",
                     mask_bc={"w": "neumann"})
    with pytest.raises(ValueError, match="unknown condition"):
        HEAT.stepper(Grid((20,)), dt=0.3, backend="numpy", mask="x < 13",
                     mask_bc={"u": ("sticky", 1)})
