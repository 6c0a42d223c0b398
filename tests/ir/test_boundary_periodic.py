"""Periodicity per species and per side (issue 23, item 3): ``bc={"u": "periodic"}`` on a
grid whose own axis is not periodic, and other conditions for some species on the sides
of a periodic axis (`rdgpu.ir.boundary`'s wrapped axes, `rdgpu.domains.boundary.WRAPPED`).

Every backend against the NumPy reference bit for bit on odd, tiny, non-square 1-D to 3-D
grids, both dtypes, with Laplacians, a derivative, a divergence and a bilaplacian; species
that do not interact step bit for bit as alone on a grid with their own conditions; a side
periodic on its own against ghosts written by hand; temporal blocking; mass conserved on
a closed axis mixing periodic and zero-flux species; clear errors.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip
from grid_cases import same_fields

from rdgpu.domains.boundary import SideBC, parse_field_bcs
from rdgpu.domains.grid import Grid
from rdgpu.models import define_model

#: operators that read every kind of neighbour (`tests/ir/test_boundary.py`'s probe)
MODEL = define_model("bc-probe", {
    "u": "0.5*laplace(u) - u*v + 0.1*d_dx(u) - 0.001*laplace(laplace(u))",
    "v": "0.3*div((1 + u*u)*grad(v)) + c*u + 0.2*advect(v, -0.3)"},
    {"c": 0.2})
#: (grid, bc): species periodic on a grid that is not; species with conditions on a grid
#: that is; a side periodic alone
CASES = [
    (Grid((7,), dx=0.9, bc="neumann"), {"u": "periodic", "v": ("value", "0.5*t")}),
    (Grid((1,), dx=0.9, bc="periodic"), {"v": ("dirichlet", 0.2)}),
    (Grid((5,), dx=0.8, bc="periodic"), {"u": {"x-": ("robin", 2.0, "t + 1")}}),
    (Grid((7, 9), dx=0.9, dy=1.1, bc="neumann"),
     {"u": {"x": "periodic", "y-": ("value", 1.0)}, "v": {"y": "periodic"}}),
    (Grid((5, 3), dx=1.2, bc="periodic"),
     {"u": {"x-": ("dirichlet", "y"), "x+": ("neumann", 0.5)}, "v": {"y+": ("value", "c")}}),
    (Grid((4, 6), dx=1.0, bc=("periodic", ("dirichlet", 0.3))),
     {"u": {"x": "periodic"}, "v": {"y-": "neumann"}}),
    (Grid((1, 4), dx=1.0, bc="neumann"), {"u": {"x-": "periodic"}, "v": {"y": "periodic"}}),
    (Grid((3, 5, 4), dx=1.0, dy=0.8, dz=1.3, bc=("periodic", "neumann", "neumann")),
     {"u": {"z-": ("value", "x - y"), "x": "periodic"}, "v": {"z+": ("robin", -0.5, 0.25)}}),
    (Grid((2, 1, 3), dx=0.7, bc="periodic"), {"v": "neumann"}),
]


def _run(grid, bc, backend, dtype, steps=3, members=None, block_steps=None, method="heun"):
    rng = np.random.default_rng(3)
    shape = grid.field_shape if members is None else (members, *grid.field_shape)
    params = {} if members is None else {"c": rng.uniform(0.1, 0.5, members)}
    st = MODEL.stepper(grid, params, dt=0.002, backend=backend, dtype=dtype, method=method,
                       members=members, bc=bc, block_steps=block_steps)
    st.set_state({s: rng.uniform(0.1, 1.0, shape) for s in MODEL.species})
    st.advance(steps)
    return st.get_state()


def _id(case) -> str:
    grid, bc = case
    return "x".join(map(str, grid.field_shape)) + "-" + grid.bcs.x.name


@pytest.mark.parametrize("backend", ["warp", "opencl"])
@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("case", CASES, ids=[_id(c) for c in CASES])
def test_backends_match_reference(backend, dtype, case):
    """Bit for bit with the NumPy reference (no transcendental function is used)."""
    backend_or_skip(backend)
    grid, bc = case
    same_fields(_run(grid, bc, backend, dtype), _run(grid, bc, "numpy", dtype))


@pytest.mark.parametrize("backend", ["warp", "opencl"])
def test_ensemble_matches_reference(backend):
    backend_or_skip(backend)
    grid, bc = CASES[4]
    same_fields(_run(grid, bc, backend, "float64", members=3),
                _run(grid, bc, "numpy", "float64", members=3))


#: two species that never meet: each steps as alone on a grid with its own conditions
APART = define_model("apart", {
    "u": "0.5*laplace(u) + 0.2*d_dx(u) - 0.01*laplace(laplace(u))",
    "v": "0.3*div((1 + v*v)*grad(v)) - 0.1*v"})


@pytest.mark.parametrize("backend", ["numpy", "warp", "opencl"])
@pytest.mark.parametrize("shape", [(9,), (6, 7), (3, 4, 5)], ids=str)
def test_each_species_steps_as_on_its_own_grid(backend, shape):
    """``u`` periodic on a Neumann grid steps bit for bit as on a periodic grid, and ``v``
    with a face value on the sides of a periodic grid as on a grid with that condition:
    the wrapped axis changes nothing but what each species reads."""
    backend_or_skip(backend)
    rng = np.random.default_rng(7)
    start = {s: rng.uniform(0.1, 1.0, shape) for s in "uv"}
    value = {"x-": ("value", 0.75), "x+": ("neumann", -0.5),
             **{a: "neumann" for a in "yz"[:len(shape) - 1]}}

    def run(bcs, bc):
        st = APART.stepper(Grid(shape, dx=0.7, bc=bcs), dt=0.002, backend=backend,
                           dtype="float64", method="rk3", bc=bc)
        st.set_state(start)
        st.advance(4)
        return st.get_state()

    mixed = run("neumann", {"u": "periodic", "v": value})
    again = run("periodic", {"v": value})
    u_alone = run("periodic", None)
    v_alone = run("neumann", {"v": value})
    for s in "uv":
        np.testing.assert_array_equal(mixed[s], again[s], err_msg=s)
    np.testing.assert_array_equal(mixed["u"], u_alone["u"])
    np.testing.assert_array_equal(mixed["v"], v_alone["v"])
    assert not np.array_equal(mixed["u"], run("neumann", None)["u"])


def test_one_side_periodic_against_hand_ghosts():
    """``x-`` periodic alone, ``x+`` a Dirichlet value: one Euler step of ``u_t = Δu``
    reads the last cell beyond the first and ``g`` beyond the last."""
    n, dx, h = 6, 0.5, 0.01
    model = define_model("heat", {"u": "laplace(u)"})
    st = model.stepper(Grid((n,), dx=dx, bc="neumann"), dt=h, backend="numpy",
                       dtype="float64", bc={"u": {"x-": "periodic", "x+": ("dirichlet", 2.0)}})
    u = np.random.default_rng(0).random(n)
    st.set_state({"u": u})
    st.advance(1)
    p = np.concatenate([[u[-1]], u, [2.0]])
    want = u + h * ((p[2:] + p[:-2]) - 2 * u) / dx**2
    np.testing.assert_allclose(st.get_state()["u"].ravel(), want, rtol=1e-14, atol=1e-15)


def test_temporal_blocking_matches_single_steps():
    """OpenCL's blocked passes wrap the bands of an axis periodic for one species only."""
    backend_or_skip("opencl")
    grid = Grid((40, 23), dx=0.9, bc="neumann")
    model = define_model("bc-pair", {"u": "0.5*laplace(u) - 0.1*u*v", "v": "0.2*laplace(v)"})
    bc = {"u": {"y": "periodic"}, "v": {"x-": ("value", "1 + t")}}
    rng = np.random.default_rng(5)
    start = {s: rng.random((40, 23)) for s in "uv"}
    runs = []
    for backend, block in (("opencl", 1), ("opencl", 4), ("numpy", None)):
        st = model.stepper(grid, dt=0.05, backend=backend, dtype="float64", bc=bc,
                           block_steps=block)
        st.set_state(start)
        st.advance(8)
        runs.append(st.get_state())
    same_fields(runs[1], runs[0])
    same_fields(runs[0], runs[2])


def test_mass_conserved_with_mixed_sides():
    """``u`` periodic in x and zero-flux in y, ``v`` zero-flux on the sides of the
    periodic x axis: both masses stay to round-off under divergence-form diffusion."""
    grid = Grid((6, 9), dx=0.5, dy=0.7, bc=("neumann", "periodic"))
    model = define_model("pair", {"u": "div((1 + v*v)*grad(u))", "v": "0.5*laplace(v)"})
    rng = np.random.default_rng(2)
    start = {s: rng.random((6, 9)) for s in "uv"}
    st = model.stepper(grid, dt=0.01, backend="numpy", dtype="float64",
                       bc={"v": {"x": "neumann"}})
    st.set_state(start)
    st.advance(50)
    got = st.get_state()
    for s in "uv":
        assert got[s].sum() == pytest.approx(start[s].sum(), rel=1e-13), s
    same = model.stepper(grid, dt=0.01, backend="numpy", dtype="float64")
    same.set_state(start)
    same.advance(50)
    assert not np.allclose(same.get_state()["v"], got["v"])


def test_parse_periodic_forms():
    grid = Grid((4, 5), bc=("neumann", "periodic"))
    got = parse_field_bcs({"u": "periodic", "v": {"x-": ("value", 1), "y": "periodic"}},
                          grid.bcs, 2, ["u", "v"])
    assert got["u"] == {"y-": SideBC("periodic"), "y+": SideBC("periodic")}
    assert got["v"] == {"x-": SideBC("value", 1.0), "y-": SideBC("periodic"),
                        "y+": SideBC("periodic")}
    assert SideBC("periodic").to_json() == "periodic"


@pytest.mark.parametrize("bc, match", [
    ({"u": ("periodic", 1)}, "unknown condition"),
    ({"u": {"x-": ["periodic"]}}, "unknown condition"),
    ({"u": {"z": "periodic"}}, "axes are x y"),
])
def test_errors(bc, match):
    model = define_model("heat", {"u": "laplace(u)"})
    with pytest.raises(ValueError, match=match):
        model.stepper(Grid((4, 4), bc="neumann"), dt=0.01, backend="numpy", bc=bc)


def test_periodic_refused_on_a_mask_edge():
    model = define_model("heat", {"u": "laplace(u)"})
    with pytest.raises(ValueError, match="'periodic' is a grid side's condition"):
        model.stepper(Grid((8, 8), bc="neumann"), dt=0.01, backend="numpy",
                      mask="x < 4", mask_bc={"u": "periodic"})
