"""A fused pass bound once (`rdgpu.integrators.passes.bind`, ``FusedPass.bind``): the
arguments set once, only the time per launch.  Bit for bit `launch` at every time, on
every backend, grid kind, mesh, ensemble, parameter field and per-member parameter; the
bound pass keeps its arrays alive; the steppers bind each pass once per buffer pair and
never bind arrays that are not their own.
"""

from __future__ import annotations

import gc

import numpy as np
import pytest
from conftest import backend_or_skip

from rdgpu.backends.target import Target
from rdgpu.domains import Grid
from rdgpu.domains.mesh import SurfaceMesh
from rdgpu.integrators import ModelStepper
from rdgpu.integrators.passes import bind, launch
from rdgpu.ir import equations as eq
from rdgpu.ir.program import Output, PerMember, Program
from rdgpu.ir.reference import run_numpy
from rdgpu.models import MODELS, define_model, resolve_params

BACKENDS = ["numpy", "opencl", "warp"]
TIMED = ("u", "v")


def _program() -> Program:
    """Reads the time, a parameter (field, per member or a number) and both species."""
    u = eq.parse("D*laplace(u) + u*v*sin(t) + c", species=TIMED, params=("D", "c"))
    v = eq.parse("laplace(v) - u*t", species=TIMED)
    return Program(TIMED, (Output("u", u), Output("v", v)))


def _domains():
    return [Grid((7,), dx=0.5, bc="periodic"),
            Grid((5, 9), dx=0.5, dy=0.7, bc=(("dirichlet", 0.2), "neumann")),
            Grid((3, 4, 5), dx=0.9, bc=("periodic", "neumann", ("dirichlet", 0.1))),
            Grid((2, 3), dx=1.0, bc="periodic"),
            SurfaceMesh.icosphere(1)]


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("dtype", ["float32", "float64"])
@pytest.mark.parametrize("members", [None, 3])
@pytest.mark.parametrize("how", ["number", "field", "member"])
def test_a_bound_pass_is_launch_bit_for_bit_at_every_time(backend, dtype, members, how):
    be = backend_or_skip(backend)
    dt = np.dtype(dtype)
    rng = np.random.default_rng(3)
    program = _program()
    for domain in _domains():
        if how == "member" and members is None:
            continue
        target = Target.bind(domain, be, dt, members=members or 1)
        shape = target.field_shape
        ins = [be.upload(rng.uniform(0.1, 1.0, shape).astype(dt)) for _ in TIMED]
        c = {"number": 0.25, "field": be.upload(rng.uniform(0, 1, shape).astype(dt)),
             "member": PerMember(be.upload(rng.uniform(0, 1, members or 1).astype(dt)))}[how]
        params = {"D": 0.3, "c": c}
        bound = [be.empty(shape, dt) for _ in TIMED]
        full = [be.empty(shape, dt) for _ in TIMED]
        run = bind(program, target, ins, bound, params, {})
        for time in (0.0, 1.5, -0.75, 1.5):
            run(time)
            launch(program, target, ins, full, params, {}, time)
            for b, f in zip(bound, full, strict=True):
                np.testing.assert_array_equal(b.numpy(), f.numpy())
        if how == "number" and members is None:  # and the NumPy semantics
            x = {s: a.numpy() for s, a in zip(TIMED, ins, strict=True)}
            ref = run_numpy(program, target, x, params, {}, 1.5)
            for o, b in zip(program.outputs, bound, strict=True):
                np.testing.assert_allclose(b.numpy(), ref[o.name], rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("backend", ["opencl", "warp"])
def test_a_bound_pass_keeps_its_arrays(backend):
    """The caller's last reference to an input gone, new arrays allocated (maybe at the
    freed addresses): the bound pass still reads its own input."""
    be = backend_or_skip(backend)
    target = Target.bind(Grid((6, 10), dx=0.5, bc="periodic"), be, np.dtype("float64"))
    rng = np.random.default_rng(1)
    host = [rng.uniform(0.1, 1.0, target.field_shape) for _ in TIMED]
    outs = [be.empty(target.field_shape, np.float64) for _ in TIMED]
    run = bind(_program(), target, [be.upload(h) for h in host], outs, {"D": 0.3, "c": 0.1},
               {})
    gc.collect()
    clutter = [be.upload(np.full(target.field_shape, 9.0)) for _ in range(8)]
    run(0.5)
    expected = [be.empty(target.field_shape, np.float64) for _ in TIMED]
    launch(_program(), target, [be.upload(h) for h in host], expected, {"D": 0.3, "c": 0.1},
           {}, 0.5)
    for o, e in zip(outs, expected, strict=True):
        np.testing.assert_array_equal(o.numpy(), e.numpy())
    assert all(np.all(c.numpy() == 9.0) for c in clutter)


WAVE = define_model("timed-wave", {"u": "0.2*laplace(u) + 0.1*sin(3*t)*v",
                                   "v": "0.1*laplace(v) - 0.05*u*t"}, {})


@pytest.mark.parametrize("backend", ["opencl", "warp"])
@pytest.mark.parametrize("method, most", [("euler", 2), ("heun", 4), ("rk3", 6),
                                          ("rk4", 16)])
def test_steppers_bind_each_pass_once_per_buffer_pair(backend, method, most):
    """A time-dependent model stepped on its own buffers: the bound passes are a few per
    scheme (not one per step) and the result is the NumPy backend's, step by step."""
    grid = Grid((6, 11), dx=0.5, bc="periodic")
    rng = np.random.default_rng(2)
    init = {s: rng.uniform(0.1, 1.0, grid.shape) for s in WAVE.species}
    out = {}
    for name in ("numpy", backend):
        be = backend_or_skip(name)
        st = ModelStepper(WAVE, grid, resolve_params(WAVE, grid, {}, seed=0), 0.05, be,
                          np.float64, method)
        st.set_state(init)
        st.advance(40)
        out[name] = st.get_state()
        if name != "numpy":
            assert 0 < len(st._bound) <= most
    for s in WAVE.species:
        np.testing.assert_allclose(out[backend][s], out["numpy"][s], rtol=1e-12, atol=1e-12)


def test_the_exponential_steps_bind_nothing():
    """ETDRK4 evaluates its rates on arrays uploaded per stage: launched in full, never
    bound (a bound pass would keep them alive)."""
    be = backend_or_skip("opencl")
    grid = Grid((16, 16), dx=1.0, bc="periodic")
    model = MODELS["swift-hohenberg"]
    st = ModelStepper(model, grid, resolve_params(model, grid, {}, seed=0), 0.5, be,
                      np.float64, "etdrk4")
    st.set_state({"u": np.random.default_rng(0).normal(0, 0.1, grid.shape)})
    st.advance(5)
    assert st._bound == {}
