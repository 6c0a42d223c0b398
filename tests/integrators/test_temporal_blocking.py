"""Temporal blocking (rdgpu.integrators.blocking): K Euler steps per pass on OpenCL, bit for bit
K single steps (``block_steps=1``): odd, tiny and non-square grids, both dtypes, every
boundary kind on each axis, K ∈ {2, 3, 8}, band heights that do not divide ny, step counts
that are not multiples of K, Gray-Scott and a model with parameter fields and a
time-dependent parameter; the errors; the automatic policy; one run on Oclgrind."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip
from oclgrind_check import check_clean_under_oclgrind, oclgrind_available

import rdgpu
from rdgpu.domains.grid import Grid
from rdgpu.integrators import blocking
from rdgpu.integrators.blocking import BlockedEuler
from rdgpu.models import MODELS, define_model


@pytest.fixture(autouse=True)
def _opencl():
    why_not = backend_or_skip("opencl").blocked_pass_support()
    if why_not:  # e.g. a GPU (RDGPU_OPENCL_DEVICE), which runs the strided layout
        pytest.skip(f"no blocked passes on this OpenCL device: {why_not}")


GS = MODELS["gray-scott"]
#: parameter fields (k: an array, B: an expression of x, y evaluated on the host), a
#: parameter of t and the coordinates inlined in the kernel, a bound
FORCED = define_model(
    "forced-blocking",
    {"u": "Du*laplace(u) - u*v*v + F*(1 - u) + A",
     "v": "Dv*laplace(v) + u*v*v - (F + k)*v + B*v"},
    {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.06, "A": 0.0, "B": 0.0},
    bounds={"v": (0.0, None)})
BCS = ["periodic", "neumann", ("dirichlet", 0.3)]


def start_state(shape, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {"u": rng.uniform(0.2, 1.0, shape), "v": rng.uniform(0.0, 0.5, shape)}


def forced_params(shape) -> dict:
    k = np.random.default_rng(1).uniform(0.04, 0.07, shape)
    return {"k": k, "A": "0.01*sin(0.3*x - 0.2*y + 0.7*t)", "B": "0.01*cos(0.5*x + y)"}


def run(model, shape, bc, dtype, block_steps, steps, rows=None, params=None,
        stencil="compact", split=None):
    """The state after ``steps`` steps (``split``: in these advance() chunks) and the
    stepper."""
    domain = Grid(shape, bc=bc)
    st = model.stepper(domain, params, dt=0.5, backend="opencl", dtype=dtype,
                       block_steps=block_steps, stencil=stencil)
    if rows is not None:
        st.blocked = BlockedEuler(st, block_steps, rows)
    st.set_state(start_state(shape))
    for n in split or [steps]:
        st.advance(n)
    return st.get_state(), st


def check_same(model, shape, bc, dtype, k, steps, rows=None, params=None, stencil="compact",
               split=None):
    want, ref = run(model, shape, bc, dtype, 1, steps, params=params, stencil=stencil)
    got, st = run(model, shape, bc, dtype, k, steps, rows, params, stencil, split)
    assert ref.blocked is None and st.blocked is not None and st.blocked.steps == k
    assert st.steps_done == ref.steps_done == steps and st.time == ref.time
    first = start_state(shape)
    assert any(not np.array_equal(want[s], first[s]) for s in want), "nothing happened"
    for s in want:
        assert got[s].dtype == np.dtype(dtype)
        assert np.array_equal(got[s], want[s]), (s, np.max(np.abs(got[s] - want[s])))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (2, 5), (6, 1), (3, 3), (13, 11)])
@pytest.mark.parametrize("bc", BCS)
def test_tiny_shapes(shape, bc, dtype):
    """ny below the band and the halo, ny = 1, ny = 2, nx = 1: K = 3, bands of 2 rows."""
    check_same(GS, shape, bc, dtype, 3, 7, rows=2)


@pytest.mark.parametrize("ybc", BCS)
@pytest.mark.parametrize("xbc", BCS)
def test_boundary_kinds_per_axis(ybc, xbc):
    check_same(GS, (23, 17), (ybc, xbc), np.float32, 3, 11, rows=5)


@pytest.mark.parametrize("k,rows,steps", [(2, 3, 9), (3, 7, 10), (8, 5, 19), (8, 64, 17),
                                          (8, None, 16)])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_steps_and_bands(k, rows, steps, dtype):
    """Bands that do not divide ny (29), step counts that are not multiples of K."""
    check_same(GS, (29, 31), ("periodic", "neumann"), dtype, k, steps, rows)
    check_same(GS, (29, 31), (("dirichlet", 0.1), "periodic"), dtype, k, steps, rows)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("bc", BCS)
def test_fields_and_time(bc, dtype):
    """Parameter fields, a parameter of t and x, y, a lower bound."""
    shape = (19, 12)
    st = run(FORCED, shape, bc, dtype, 3, 1, params=forced_params(shape))[1]
    assert st._euler.refs("time") and "k" in st._device_params and "B" in st._device_params
    check_same(FORCED, shape, bc, dtype, 3, 14, rows=4, params=forced_params(shape))
    check_same(FORCED, shape, bc, dtype, 8, 17, params=forced_params(shape))


def test_split_advances():
    """advance(a); advance(b) = advance(a + b) (checkpoints resume bit for bit), the
    passes' times follow steps_done."""
    shape = (17, 9)
    check_same(FORCED, shape, "periodic", np.float32, 3, 20, rows=4,
               params=forced_params(shape), split=[2, 7, 0, 3, 8])


@pytest.mark.parametrize("bc", BCS)
def test_isotropic_stencil(bc):
    check_same(GS, (14, 9), bc, np.float64, 3, 8, rows=4, stencil="isotropic")


def test_simulation_option():
    shape = (16, 24)
    sims = [rdgpu.Simulation("gray-scott", {"grid": shape, "bc": "neumann"}, backend="opencl",
                             dtype="float32", options={"block_steps": k}) for k in (1, 4)]
    assert sims[0].stepper.blocked is None and sims[1].stepper.blocked.steps == 4
    a, b = (s.run(30, progress=False).fields for s in sims)
    for s in a:
        assert np.array_equal(a[s], b[s])


def test_cli_option(capsys, tmp_path):
    from rdgpu.cli.app import main
    from rdgpu.io.output import load_npz

    fields = []
    for k in (1, 4):
        path = tmp_path / f"k{k}.npz"
        code = main(["run", "gray-scott", "--size", "20x24", "--steps", "30", "--backend",
                     "opencl", "--block-steps", str(k), "--data", str(path), "--quiet"])
        assert code == 0, capsys.readouterr().err
        fields.append(load_npz(path).fields)
    for s in fields[0]:
        assert np.array_equal(fields[0][s], fields[1][s])
    for argv, match in [(["gray-scott", "--block-steps", "4", "--backend", "numpy"],
                         "numpy backend has no blocked kernel"),
                        (["allen-cahn", "--block-steps", "4"], "allen-cahn has no blocked"),
                        (["gray-scott", "--block-steps", "0"], "from 1 (off) to 512")]:
        assert main(["run", *argv, "--size", "8x8", "--steps", "2", "--quiet"]) == 2
        assert match in capsys.readouterr().err


# ---------------------------------------------------------------------------- 3-D
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shape", [(1, 1, 1), (1, 3, 4), (2, 5, 3), (7, 4, 6), (11, 3, 5)])
@pytest.mark.parametrize("bc", BCS)
def test_3d_tiny_shapes(shape, bc, dtype):
    """Bands of z-planes: nz below the band and the halo, nz = 1 and 2, short rows."""
    check_same(GS, shape, bc, dtype, 3, 7, rows=2)


@pytest.mark.parametrize("zbc", BCS)
def test_3d_boundary_kinds_per_axis(zbc):
    check_same(GS, (9, 6, 7), (zbc, "neumann", ("dirichlet", 0.2)), np.float32, 3, 8, rows=4)
    check_same(GS, (9, 6, 7), (zbc, ("dirichlet", 0.4), "periodic"), np.float64, 2, 5, rows=3)


@pytest.mark.parametrize("k,rows,steps", [(2, 3, 9), (8, 5, 19), (8, None, 16)])
def test_3d_steps_bands_fields_and_time(k, rows, steps):
    """Bands that do not divide nz, steps not multiples of K, parameter fields, t and the
    coordinates, the isotropic stencil."""
    shape = (13, 6, 5)
    check_same(GS, shape, ("periodic", "neumann", "periodic"), np.float32, k, steps, rows)
    check_same(FORCED, shape, (("dirichlet", 0.1), "periodic", "neumann"), np.float64, k,
               steps, rows, params=forced_params(shape))
    check_same(GS, (7, 5, 5), "periodic", np.float64, k, steps, rows, stencil="isotropic")


def test_3d_ensembles_and_simulation():
    """Members are volumes one after the other: each member's bands stay in it."""
    sims = [rdgpu.Simulation("gray-scott", {"grid": (6, 5, 7), "bc": "neumann"},
                             backend="opencl", dtype="float32", members=3,
                             options={"block_steps": k}) for k in (1, 4)]
    assert sims[0].stepper.blocked is None and sims[1].stepper.blocked.steps == 4
    a, b = (s.run(22, progress=False).fields for s in sims)
    for s in a:
        assert a[s].shape == (3, 6, 5, 7) and np.array_equal(a[s], b[s])


# ---------------------------------------------------------------------------- errors
@pytest.mark.parametrize("bad", [0, -2, 2.5, True, "4"])
def test_bad_block_steps(bad):
    with pytest.raises(ValueError, match="block_steps must be None"):
        GS.stepper(Grid((8, 8)), dt=0.5, backend="opencl", block_steps=bad)


@pytest.mark.parametrize("case,match", [
    ({"backend": "numpy"}, "numpy backend has no blocked kernel"),
    ({"backend": "warp"}, "warp backend has no blocked kernel"),
    ({"method": "heun"}, "only 'euler'"),
    ({"domain": Grid((9,))}, "blocked passes run on 2-D and 3-D grids"),
    ({"domain": rdgpu.SurfaceMesh.icosphere(1), "dt": 1e-4}, "blocked passes run on 2-D"),
    ({"model": MODELS["swift-hohenberg"], "method": "euler", "dt": 1e-3}, "bilaplacian"),
])
def test_ineligible(case, match):
    """Asked explicitly: an error naming the reason; automatic: single steps."""
    case = dict(case)
    model = case.pop("model", GS)
    kw = {"domain": Grid((8, 8)), "dt": 0.5, "backend": "opencl", **case}
    domain = kw.pop("domain")
    with pytest.raises(ValueError, match=match) as info:
        model.stepper(domain, block_steps=4, **kw)
    assert "block_steps=1" in str(info.value)
    assert model.stepper(domain, block_steps=None, **kw).blocked is None
    assert model.stepper(domain, block_steps=1, **kw).blocked is None


def test_strided_layout_refused():
    from rdgpu.backends.opencl_backend import OpenCLBackend

    be = OpenCLBackend(layout="strided", col_stride=4)
    with pytest.raises(ValueError, match="row layout"):
        GS.stepper(Grid((8, 8)), dt=0.5, backend=be, block_steps=2)


def test_blocked_euler_arguments():
    st = GS.stepper(Grid((8, 8)), dt=0.5, backend="opencl", block_steps=1)
    with pytest.raises(ValueError, match=">= 2 steps"):
        BlockedEuler(st, 1)
    with pytest.raises(ValueError, match="rows must be >= 1"):
        BlockedEuler(st, 2, 0)


# ---------------------------------------------------------------------------- policy
def test_automatic_policy(monkeypatch):
    """On for eligible programs whose fields exceed the last-level cache, with the most
    steps whose scratch fits in L2; off below the LLC, or with no cache information."""
    domain = Grid((64, 100))  # 2 species × 2 buffers × 6400 cells × 4 bytes = 102 400 bytes
    monkeypatch.setattr(blocking, "cache_sizes", lambda: {2: 3 * 2 * 100 * 4 * 5, 3: 100_000})
    st = GS.stepper(domain, dt=0.5, backend="opencl", dtype=np.float32)
    assert st.blocked is not None and st.blocked.steps == 6  # 5 levels of rings fit in L2
    ref = GS.stepper(domain, dt=0.5, backend="opencl", dtype=np.float32, block_steps=1)
    for s_ in (st, ref):
        s_.set_state(start_state(domain.shape))
        s_.advance(15)
    for name, a in st.get_state().items():
        assert np.array_equal(a, ref.get_state()[name])
    monkeypatch.setattr(blocking, "cache_sizes", lambda: {2: 10_000_000, 3: 200_000})
    assert GS.stepper(domain, dt=0.5, backend="opencl", dtype=np.float32).blocked is None
    monkeypatch.setattr(blocking, "cache_sizes", lambda: {2: 10_000_000, 3: 100_000})
    # the halo of K − 1 rows stays under 1/8 of the 64 rows: K = 8, not AUTO_STEPS
    assert GS.stepper(domain, dt=0.5, backend="opencl").blocked.steps == 8
    tall = Grid((256, 100))
    assert GS.stepper(tall, dt=0.5, backend="opencl").blocked.steps == blocking.AUTO_STEPS
    assert GS.stepper(Grid((15, 2000)), dt=0.5, backend="opencl").blocked is None
    monkeypatch.setattr(blocking, "cache_sizes", lambda: {2: 1000, 3: 100_000})
    assert GS.stepper(domain, dt=0.5, backend="opencl").blocked is None  # no level fits
    monkeypatch.setattr(blocking, "cache_sizes", dict)
    assert GS.stepper(domain, dt=0.5, backend="opencl").blocked is None
    assert GS.stepper(domain, dt=0.5, backend="warp").blocked is None


def test_cache_sizes():
    sizes = blocking.cache_sizes()
    if not sizes:
        pytest.skip("no cache information on this machine")
    assert blocking.last_level_cache() == sizes[max(sizes)] > 0


# ---------------------------------------------------------------------------- Oclgrind
WORKER = """
import numpy as np
from rdgpu.backends.opencl_backend import OpenCLBackend
from rdgpu.domains import Grid
from rdgpu.models import MODELS
be = OpenCLBackend("oclgrind")
rng = np.random.default_rng(0)
for dtype in (np.float32, np.float64):
    for shape, bc in [((7, 5), "periodic"), ((6, 4), ("neumann", ("dirichlet", 0.3))),
                      ((2, 3), ("dirichlet", 0.2)), ((1, 4), "periodic"),
                      ((5, 3, 4), "periodic"), ((4, 3, 3), (("dirichlet", 0.1), "neumann",
                                                             "periodic"))]:
        start = {"u": rng.uniform(0, 1, shape), "v": rng.uniform(0, 0.5, shape)}
        out = []
        for k in (1, 3):
            st = MODELS["gray-scott"].stepper(Grid(shape, bc=bc), dt=0.5, backend=be,
                                              dtype=dtype, block_steps=k)
            if k > 1:
                from rdgpu.integrators.blocking import BlockedEuler
                st.blocked = BlockedEuler(st, k, 2)
            st.set_state(start)
            st.advance(4)
            out.append(st.get_state())
        assert all(np.array_equal(out[0][s], out[1][s]) for s in "uv"), (dtype, shape, bc)
        print(np.dtype(dtype).name, shape, "ok", flush=True)
"""


@pytest.mark.slow
@pytest.mark.skipif(not oclgrind_available(), reason="Oclgrind is not installed")
def test_blocked_kernel_under_oclgrind():
    """No out-of-bounds scratch or grid access, no data race, bit for bit."""
    check_clean_under_oclgrind(["-c", WORKER], 12)
