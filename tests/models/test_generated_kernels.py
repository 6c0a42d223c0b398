"""The model layer (rdgpu.models) checked thoroughly.

1. Every generated kernel equals its NumPy reference (``run_numpy``) on Warp and OpenCL:
   float32 and float64; odd, non-square and tiny 1-D/2-D/3-D grids with every boundary
   kind per axis (Dirichlet values, mixed tuples) and icospheres; the built-in models, user
   models with cross-diffusion, functions, division, coordinates and time, a bilaplacian,
   bounds, parameter fields and expressions; three steps of euler or rk3 (whose second
   program, a·base + b·(y + h f(y)), is also Heun's).
   Bit-identical where only exact operations are used (``+ - * /``, ``min``, ``max``,
   ``abs``, clamps); within ``8 eps · max|reference|`` where ``exp``, ``pow``... are.
2. The GPU launch shapes run on the CPU (Warp one thread per cell, OpenCL strided columns)
   equal the row shapes.
3. The measured orders of Euler, Heun and RK3 (with a time-dependent forcing, which would
   pull a method with wrong stage times down to order 1).
4. IMEX far past the explicit limit: bounded and close to an explicit reference; its
   errors; Swift-Hohenberg stripes.
5. Stability limits against closed forms, and stepping just above and below them.
6. Errors of the equation language and of the parameters.
7. Parameter expressions against the same parameters given as arrays or host updates.

Compile time dominates (each distinct program, kind and dtype is a Warp module and an
OpenCL program), so shapes and boundary conditions, which are launch arguments, are looped
over inside one test; the models are shared between the groups.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from conftest import backend_or_skip

import rdgpu
from rdgpu.core.errors import StabilityError
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.integrators import ModelStepper
from rdgpu.models import (
    MODELS,
    AllenCahn,
    EquationError,
    build_domain,
    define_model,
    domain_shape,
    resolve_params,
)

# ---------------------------------------------------------------------------- models
#: only exact operations: + - * /, integer powers, min, max, abs, a clamp; cross-diffusion,
#: x y z t Lx, a parameter array (a), an expression of x (g, a field) and one of t (e,
#: inlined in the kernel)
EXACT = define_model(
    "exact-ops",
    {"u": "Du*laplace(u) + c*laplace(v) - u*v/(1 + u*u) + a*(1 - u) + 0.01*x/Lx - 0.02*y"
          " + 0.03*z*t + min(u, v) - abs(v - 0.5) + 0.01*(2 + v)**-2",
     "v": "Dv*laplace(v) - c*laplace(u) + g*max(u - v, 0.1) - v/(2 + v*v) + e"},
    {"Du": 0.2, "Dv": 0.1, "c": 0.05, "a": 0.02, "g": 1.0, "e": 0.0},
    bounds={"u": (0.1, None), "v": (None, 0.6)},
)
EXACT_PARAMS = {"g": "1 + 0.5*x/Lx + 0.1*y*z", "e": "0.01*t - 0.002"}

#: every function of the language, and pow with real exponents of positive arguments
FUNCS = define_model(
    "functions",
    {"u": "Du*laplace(u) + 0.1*exp(-u) - 0.05*sqrt(u*u*v*v + 0.1) + 0.02*tanh(v - u)"
          " + 0.01*abs(u)**1.5 - 0.03*log(1 + u*u) + 0.01*sin(x)*cos(v) + 0.002*tan(u)",
     "v": "Dv*laplace(v) + 0.02*(u*u + 0.5)**2.5 - 0.04*abs(v)**0.5"
          " + 0.01*exp(0.5*v)*tanh(3*u) + 0.01*cos(2*pi*t)*sin(y + z)"
          " + 0.01*cosh(u - v) - 0.01*sinh(0.5*v) + 0.01*floor(3*x)"},
    {"Du": 0.2, "Dv": 0.1},
)

#: Swift-Hohenberg, r u − (1 + Δ)² u − u³
SH = define_model(
    "swift-hohenberg",
    {"u": "(r - 1)*u - 2*laplace(u) - laplace(laplace(u)) - u**3"}, {"r": 0.3})

BUILTINS = sorted(n for n in MODELS if n != "allen-cahn")
#: parameters of the built-ins that exercise field specs and arrays
BUILTIN_PARAMS = {
    "brusselator": {"a": {"kind": "sine", "mean": 5.0, "amplitude": 1.0, "axis": "x"}},
    "barkley": {"b": {"kind": "linear", "start": 0.01, "stop": 0.03, "axis": "x"}},
    "turing": {"beta": {"kind": "random", "low": 11.9, "high": 12.1}},
}
#: (model, method, exact?) of every case of the cross-checks
CASES = {
    **{n: (MODELS[n], "euler", True) for n in BUILTINS},
    "exact-ops": (EXACT, "rk3", True),
    "functions": (FUNCS, "euler", False),
    "swift-hohenberg": (SH, "euler", True),
}
KINDS = ["grid1", "grid2", "grid3", "mesh"]
#: the built-ins run on 2-D grids and one other kind each (every generated program costs a
#: compile; the user models cover every feature on every kind)
BUILTIN_KINDS = {"gray-scott": "grid3", "gray-scott-flow": "grid1", "brusselator": "mesh",
                 "fitzhugh-nagumo": "grid1", "schnakenberg": "grid3", "barkley": "mesh",
                 "turing": "grid1"}
KERNEL_CASES = [(n, k) for n in CASES for k in KINDS
                if n not in BUILTIN_KINDS or k in ("grid2", BUILTIN_KINDS[n])]

BC2 = ["periodic", "neumann", ("dirichlet", 0.7), (("dirichlet", 1.2), "periodic"),
       ("neumann", ("dirichlet", 0.25)), ("periodic", "neumann")]


@functools.cache
def domains(kind: str) -> tuple:
    """The domains of one kind: every boundary kind per axis, tiny and odd shapes."""
    if kind == "grid1":
        return (Grid((1,), dx=0.9, bc="periodic"), Grid((1,), dx=0.9, bc=("dirichlet", 0.6)),
                Grid((7,), dx=0.9, bc="periodic"), Grid((7,), dx=1.1, bc="neumann"),
                Grid((7,), dx=0.9, bc=("dirichlet", 0.3)))
    if kind == "grid2":
        return tuple(Grid(s, dx=1.1, dy=0.9, bc=b) for s in ((1, 1), (3, 5), (5, 2))
                     for b in BC2)
    if kind == "grid3":
        return (Grid((1, 1, 1), dx=0.9, bc="periodic"),
                Grid((1, 1, 1), dx=0.9, bc=("dirichlet", 0.5)),
                Grid((2, 3, 5), dx=1.0, dy=1.2, dz=0.9,
                     bc=("periodic", ("dirichlet", 0.2), "neumann")),
                Grid((3, 4, 1), dx=0.9, dy=1.0, dz=1.1,
                     bc=(("dirichlet", 0.1), "neumann", "periodic")),
                Grid((2, 3, 5), dx=0.9, bc="neumann"),
                Grid((3, 4, 1), dx=0.9, bc=(("dirichlet", 0.4), ("dirichlet", 0.8),
                                            ("dirichlet", 0.6))))
    return (SurfaceMesh.icosphere(1), SurfaceMesh.icosphere(2))


@functools.cache
def case_dt(name: str) -> float:
    """Half the model's explicit limit on the stiffest domain of :func:`domains`."""
    model = CASES[name][0]
    worst = min(model.dt_limit(Grid((2, 2, 2), dx=0.9), {}),
                model.dt_limit(SurfaceMesh.icosphere(2), {}))
    dt = 0.5 * worst
    # the limit is the diffusion's: the reactions of Barkley (1/ε) and BVAM (rates ~1 with
    # diffusion ~1e-3) set a smaller one
    return min(dt, {"barkley": 0.01, "bvam": 0.5}.get(name, dt))


def case_params(name: str, domain) -> dict:
    if name == "exact-ops":
        a = np.random.default_rng(7).uniform(0.01, 0.03, domain_shape(domain))
        return {**EXACT_PARAMS, "a": a}
    if name == "gray-scott":
        return {"F": np.random.default_rng(8).uniform(0.03, 0.04, domain_shape(domain))}
    return dict(BUILTIN_PARAMS.get(name, {}))


def case_init(name: str, domain) -> dict:
    shape = domain_shape(domain)
    rng = np.random.default_rng(1)
    model = CASES[name][0]
    if name == "exact-ops":
        return {"u": rng.uniform(0, 1, shape), "v": rng.uniform(0, 1, shape)}
    if name == "functions":
        return {"u": rng.uniform(0.5, 1.5, shape), "v": rng.uniform(0.5, 1.0, shape)}
    if name == "swift-hohenberg":
        return {"u": rng.uniform(-1, 1, shape)}
    x0 = model.steady_guess({})
    return {s: x + 0.1 * (abs(x) + 1) * rng.uniform(-1, 1, shape)
            for s, x in zip(model.species, x0, strict=True)}


def stepper(model, domain, params, dt, backend, dtype=np.float64, method="euler"):
    """A :class:`ModelStepper` built directly: ``Model.stepper`` also computes the
    stability limit (some 500 eigenvalue problems), which the cross-checks do not need."""
    p = resolve_params(model, domain, params, seed=0)
    return ModelStepper(model, domain, p, dt, rdgpu.get_backend(backend), np.dtype(dtype),
                        method)


def run_case(name, domain, backend, dtype, steps=3):
    model, method, _ = CASES[name]
    st = stepper(model, domain, case_params(name, domain), case_dt(name), backend, dtype,
                 method)
    st.set_state(case_init(name, domain))
    st.advance(steps)
    return st.get_state()


@functools.cache
def reference(name: str, kind: str, dtype: str) -> tuple:
    """The NumPy backend's results (``run_numpy``) on every domain of ``kind``."""
    return tuple(run_case(name, d, "numpy", np.dtype(dtype)) for d in domains(kind))


def assert_matches(got, ref, exact, dtype, what):
    """Bit-identical, or within 8 eps of the largest magnitude (functions: each is good to
    a few ulps in every implementation; measured at most 0.6 eps here)."""
    for s in ref:
        assert got[s].dtype == dtype and got[s].shape == ref[s].shape, what
        if exact:
            np.testing.assert_array_equal(got[s], ref[s], err_msg=f"{what} {s}")
        else:
            scale = float(np.max(np.abs(ref[s])))
            np.testing.assert_allclose(got[s], ref[s], rtol=0,
                                       atol=8 * np.finfo(dtype).eps * scale,
                                       err_msg=f"{what} {s}")


def _id(d) -> str:
    if isinstance(d, Grid):
        return f"{d.field_shape} {d.bc}"
    return f"icosphere {d.n_vertices}"


# ---------------------------------------------------------------------------- 1. kernels
@pytest.mark.parametrize("name, kind", KERNEL_CASES, ids=[f"{n}-{k}" for n, k in KERNEL_CASES])
@pytest.mark.parametrize("backend_name", ["warp", "opencl"])
def test_generated_kernels_equal_numpy(backend_name, name, kind, dtype):
    be = backend_or_skip(backend_name)
    exact = CASES[name][2]
    refs = reference(name, kind, dtype.str)
    for domain, ref in zip(domains(kind), refs, strict=True):
        got = run_case(name, domain, be, dtype)
        assert all(np.isfinite(r).all() for r in ref.values()), _id(domain)
        assert_matches(got, ref, exact, dtype, f"{backend_name} {_id(domain)}")


def test_cases_exercise_what_they_claim():
    """The clamp is active, the fields and the t-expression are what the cases say, and
    every case moves its fields (a cross-check of unchanged fields proves little)."""
    grid = domains("grid2")[7]
    p = resolve_params(EXACT, grid, case_params("exact-ops", grid))
    assert isinstance(p["a"], np.ndarray) and isinstance(p["g"], np.ndarray)
    assert p["e"] == EXACT_PARAMS["e"]  # kept as text: inlined in the kernel
    outs = reference("exact-ops", "grid2", "<f8")
    assert all(o["u"].min() >= 0.1 and o["v"].max() <= 0.6 for o in outs)
    assert sum(np.sum(o["u"] == 0.1) for o in outs) >= 2  # the bounds clamp
    assert sum(np.sum(o["v"] == 0.6) for o in outs) >= 2
    for name in CASES:
        init = case_init(name, grid)
        out = reference(name, "grid2", "<f8")[7]
        assert all(not np.array_equal(out[s], init[s]) for s in init), name


@pytest.mark.parametrize("backend_name", ["warp", "opencl"])
def test_allen_cahn_explicit_on_3d_grids(backend_name, dtype):
    be = backend_or_skip(backend_name)
    ac = MODELS["allen-cahn"]
    for domain in domains("grid3"):
        shape = domain_shape(domain)
        params = {"b": np.random.default_rng(2).uniform(-0.1, 0.1, shape), "eps": 0.8}
        u0 = np.random.default_rng(3).uniform(-1, 1, shape)
        dt = 0.5 * ac.dt_limit(domain)
        out = {}
        for b in ("numpy", be):
            st = ac.stepper(domain, params, dt=dt, backend=b, dtype=dtype)
            st.set_state({"u": u0})
            st.advance(3)
            out[b] = st.get_state()
        # the Bernoulli substep has an exp: a few ulps
        assert_matches(out[be], out["numpy"], False, dtype, f"{backend_name} {_id(domain)}")


@pytest.mark.parametrize("backend_name", ["warp", "opencl"])
def test_species_named_like_kernel_arguments_on_3d_grids(backend_name):
    """Regression: the 3-D kernels named the lower-z neighbour of species ``s`` ``b_s``,
    which is also the argument of the builtins ``_h``, ``_a``, ``_b`` (the step and the
    Runge-Kutta weights): species h, a, b silently read their neighbour as the step (Warp)
    or shadowed it (OpenCL)."""
    be = backend_or_skip(backend_name)
    model = define_model("named", {"h": "0.1*laplace(h) + 0.5*a - h*b",
                                   "a": "0.2*laplace(a) - a*h + 0.1",
                                   "b": "0.05*laplace(b) + a - b"}, {})
    grid = Grid((2, 3, 5), dx=0.9, bc=("periodic", ("dirichlet", 0.2), "neumann"))
    rng = np.random.default_rng(4)
    init = {s: rng.uniform(0, 1, grid.shape) for s in "hab"}
    out = []
    for b in ("numpy", be):
        st = stepper(model, grid, {}, 0.05, b, method="rk3")
        st.set_state(init)
        st.advance(3)
        out.append(st.get_state())
    assert_matches(out[1], out[0], True, np.dtype(np.float64), backend_name)


# ---------------------------------------------------------------------------- 2. launch shapes
@functools.cache
def _variant(name: str):
    """A backend with its launch shape forced (whatever RDGPU_OPENCL_LAYOUT says)."""
    family, shape = name.split("-")
    backend_or_skip(family)
    if family == "warp":
        from rdgpu.backends.warp_backend import WarpBackend

        return WarpBackend("cpu", launch=shape)
    from rdgpu.backends.opencl_backend import OpenCLBackend

    return OpenCLBackend(layout=shape, col_stride=4 if shape == "strided" else None)


#: every kind with the exact-ops model (rk3: the Euler and the combining programs), the
#: functions and the bilaplacian's two passes on grids
SHAPE_CASES = [("exact-ops", k) for k in KINDS] + [
    ("functions", "grid2"), ("swift-hohenberg", "grid2"), ("swift-hohenberg", "grid3")]


@pytest.mark.parametrize("name, kind", SHAPE_CASES, ids=[f"{n}-{k}" for n, k in SHAPE_CASES])
@pytest.mark.parametrize("variant", ["warp-cells", "opencl-strided"])
def test_gpu_launch_shapes_equal_row_shapes(variant, name, kind, dtype):
    be = _variant(variant)
    rows = _variant("warp-rows" if variant == "warp-cells" else "opencl-row")
    if variant == "warp-cells":
        assert be.per_cell and not rows.per_cell
    else:
        assert be.layout == "strided" and rows.layout == "row"
    exact = CASES[name][2]
    refs = reference(name, kind, dtype.str)
    for domain, ref in zip(domains(kind), refs, strict=True):
        got = run_case(name, domain, be, dtype)
        assert_matches(got, ref, exact, dtype, f"{variant} {_id(domain)}")
        # and against the row shape itself (functions: a vectorised loop may call other
        # math routines than a scalar one, so ulps there too)
        assert_matches(got, run_case(name, domain, rows, dtype), exact, dtype,
                       f"{variant} vs rows {_id(domain)}")


def test_opencl_layout_from_environment(monkeypatch):
    backend_or_skip("opencl")
    from rdgpu.backends.opencl_backend import OpenCLBackend

    monkeypatch.setenv("RDGPU_OPENCL_LAYOUT", "strided")
    be = OpenCLBackend()
    assert be.layout == "strided"
    domain = domains("grid2")[9]
    assert_matches(run_case("exact-ops", domain, be, np.dtype(np.float64)),
                   reference("exact-ops", "grid2", "<f8")[9], True, np.dtype(np.float64),
                   "RDGPU_OPENCL_LAYOUT=strided")


# ---------------------------------------------------------------------------- 3. orders
ORDER_N = 16
ORDER_T = 2.0
ORDER_MODELS = {
    # the forcing in the equation, and as a parameter expression of t (inlined)
    "equation": define_model("order-eq", {"u": "D*laplace(u) + u*(1 - u) + 0.5*sin(2*t)"},
                             {"D": 0.1}),
    "parameter": define_model("order-param", {"u": "D*laplace(u) + u*(1 - u) + A"},
                              {"D": 0.1, "A": "0.5*sin(2*t)"}),
}
ORDERS = {"euler": (1.0, (40, 80, 160, 320)), "heun": (2.0, (20, 40, 80, 160)),
          "rk3": (3.0, (20, 40, 80, 160))}


def _order_run(model, method, n):
    grid = Grid((ORDER_N,), dx=2 * np.pi / ORDER_N, bc="periodic")
    x = (np.arange(ORDER_N) + 0.5) * grid.dx
    st = model.stepper(grid, {}, dt=ORDER_T / n, backend="numpy", method=method)
    st.set_state({"u": 0.5 + 0.3 * np.cos(x)})
    st.advance(n)
    return st.get_state()["u"]


@pytest.mark.parametrize("forcing", list(ORDER_MODELS))
def test_measured_orders_of_the_explicit_methods(forcing):
    """u_t = 0.1 u_xx + u(1 − u) + ½ sin 2t on a periodic 1-D grid of 16 cells to t = 2,
    errors at four dt against RK3 at dt = 2/1280, the slope of log error against log dt
    fitted.  Measured: 1.00, 2.02, 3.03.  With every stage at the step's start time (a
    wrong stage time) Heun and RK3 measured 1.00: the forcing makes the check sharp."""
    model = ORDER_MODELS[forcing]
    ref = _order_run(model, "rk3", 1280)
    for method, (order, ns) in ORDERS.items():
        errors = [float(np.max(np.abs(_order_run(model, method, n) - ref))) for n in ns]
        assert min(errors) > 1e-9  # far above the reference's error and round-off
        slope = -np.polyfit(np.log(ns), np.log(errors), 1)[0]
        assert slope == pytest.approx(order, abs=0.2), (method, errors)


# ---------------------------------------------------------------------------- 4. IMEX
GS = MODELS["gray-scott"]


def _imex_domain(kind: str):
    """A 2-D grid, a 3-D grid (a Dirichlet face: a non-uniform steady state) and a mesh,
    each spaced so that diffusion is stiff (explicit limit ≈ 0.01-0.02) while the
    reaction is slow (rates ≲ 0.1): the regime IMEX is for."""
    if kind == "grid2":
        return Grid((8, 8), dx=0.1, bc="periodic"), {}
    if kind == "grid3":
        return Grid((4, 4, 4), dx=0.1, bc=("neumann", "periodic", ("dirichlet", 1.0))), {}
    mesh = SurfaceMesh.icosphere(1)
    scale = (mesh.mean_edge_length / 0.1) ** 2
    return mesh, {"Du": 0.16 * scale, "Dv": 0.08 * scale}


@pytest.mark.parametrize("kind", ["grid2", "grid3", "mesh"])
def test_imex_far_past_the_explicit_limit(kind):
    """Gray-Scott from u ≈ 0.5, v ≈ 0.25 (noise of ±0.2, ±0.1) for 200 steps at 20× the
    Euler limit.  The noise is stiff (it decays in a few explicit-limit steps), the
    homogeneous reaction slow: "close" is ``max|imex − ref| <= 5 %`` of how far the
    reference moved, ``max|ref(T) − x(0)|`` (a first-order error in the slow reaction;
    measured 1-3 % on the grid and the mesh; 1e-9 on the 3-D grid, whose Dirichlet face
    holds a non-uniform steady state, which IMEX keeps exactly).  The reference is forward
    Euler at 0.95× its limit over the same time."""
    domain, params = _imex_domain(kind)
    limit = GS.dt_limit(domain, params)
    shape = domain_shape(domain)
    rng = np.random.default_rng(5)
    init = {"u": 0.5 + 0.2 * rng.uniform(-1, 1, shape),
            "v": 0.25 + 0.1 * rng.uniform(-1, 1, shape)}
    T = 200 * 20 * limit
    n = math.ceil(T / (0.95 * limit))
    ref = stepper(GS, domain, params, T / n, "numpy")
    ref.set_state(init)
    ref.advance(n)
    expect = ref.get_state()
    for method in ("imex", "imex-cn"):
        st = stepper(GS, domain, params, 20 * limit, "numpy", method=method)
        st.set_state(init)
        st.advance(200)
        assert st.time == pytest.approx(T)
        got = st.get_state()
        for s in GS.species:
            assert np.isfinite(got[s]).all() and np.abs(got[s]).max() < 2, method
            travel = float(np.max(np.abs(expect[s] - init[s])))
            assert travel > 0.1
            err = float(np.max(np.abs(got[s] - expect[s])))
            assert err <= 0.05 * travel, (method, s, err, travel)


def test_explicit_run_at_the_imex_step_blows_up():
    """The IMEX test's step is genuinely past the explicit limit."""
    domain, params = _imex_domain("grid2")
    limit = GS.dt_limit(domain, params)
    with pytest.raises(StabilityError, match="imex"):
        GS.stepper(domain, params, dt=20 * limit, backend="numpy")
    st = stepper(GS, domain, params, 20 * limit, "numpy")
    rng = np.random.default_rng(5)
    st.set_state({"u": 0.5 + 0.2 * rng.uniform(-1, 1, domain.shape),
                  "v": 0.25 + 0.1 * rng.uniform(-1, 1, domain.shape)})
    with np.errstate(all="ignore"):
        st.advance(40)
    u = st.get_state()["u"]
    assert not np.all(np.abs(u) < 1e3)


def test_imex_limits_and_errors():
    """No linear limit for diagonal diffusion and a stabilised bilaplacian (each limit is a
    bisection over 513 modes, 0.3 s: a few); clear errors where IMEX cannot apply."""
    grid = Grid((6, 8), dx=0.5)
    for method in ("imex", "imex-cn"):
        assert GS.dt_limit(_imex_domain("grid2")[0], {}, method) == math.inf
    mesh, params = _imex_domain("mesh")
    assert GS.dt_limit(mesh, params, "imex") == math.inf
    assert SH.dt_limit(grid, {}, "imex") == math.inf
    cases = [
        ({"u": "u*laplace(u)"}, {}, "state-dependent coefficient"),
        ({"u": "exp(laplace(u)) - u"}, {}, "state-dependent coefficient"),
        ({"u": "D*laplace(u)"}, {"D": np.ones(grid.shape)}, r"\['D'\], which are fields"),
        ({"u": "D*laplace(u)"}, {"D": {"kind": "random", "low": 1, "high": 2}},
         r"\['D'\], which are fields"),
        ({"u": "D*laplace(u)"}, {"D": "1 + 0.1*x"}, r"\['D'\], which are fields"),
        ({"u": "D*laplace(u)"}, {"D": "1 + 0.1*t"}, "time-dependent parameter"),
        ({"u": "laplace(laplace(u))"}, {}, "ill-posed"),
    ]
    for i, (eqs, params, match) in enumerate(cases):
        model = define_model("bad-imex", eqs, {"D": 1.0})
        with pytest.raises(ValueError, match=match):
            model.stepper(grid, params, dt=0.1, backend="numpy",
                          method=("imex", "imex-cn")[i % 2])
    # the same equations step explicitly (field and time-dependent coefficients too)
    model = define_model("ok-explicit", {"u": "D*laplace(u)"}, {"D": 1.0})
    for params in ({"D": np.ones(grid.shape)}, {"D": "1 + 0.1*t"}):
        model.stepper(grid, params, dt=0.01, backend="numpy")


def test_swift_hohenberg_imex_stripes():
    """1-D periodic Swift-Hohenberg, r = 0.3, L = 8π on 32 cells: only k = 1 (mode 4) is
    unstable, k = 0.75 and 1.25 are not.  From noise, 200 steps of IMEX at 15× the
    explicit limit (which blows up explicit Euler) reach stripes: dominant mode 4, amplitude
    within 2 % of the one-mode estimate √(4(r − (1 − m_h)²)/3) with the discrete m_h = (4/dx²)
    sin²(dx/2) (measured 0.2 % off: harmonics), and a steady state of the discrete
    equations to ``max|f(u)| < 1e-4`` (measured 3e-5 after 200 steps; IMEX keeps steady
    states exactly, and what is left is the stripes' slow drift to the phase the grid
    pins, |f| ≈ 7e-6 after 300 steps)."""
    n, length, r = 32, 8 * np.pi, 0.3
    grid = Grid((n,), dx=length / n, bc="periodic")
    limit = SH.dt_limit(grid, {})
    dt = 15 * limit
    u0 = 1e-3 * np.random.default_rng(6).standard_normal(n)
    st = SH.stepper(grid, {"r": r}, dt=dt, backend="numpy", method="imex")
    st.set_state({"u": u0})
    st.advance(200)
    u = st.get_state()["u"][0]
    spectrum = np.abs(np.fft.rfft(u)) * 2 / n
    assert int(np.argmax(spectrum)) == 4  # k = 2π·4/L = 1
    m_h = 4 / grid.dx**2 * np.sin(grid.dx / 2) ** 2
    amplitude = math.sqrt(4 * (r - (1 - m_h) ** 2) / 3)
    assert spectrum[4] == pytest.approx(amplitude, rel=0.02)
    # steady: one explicit Euler step of 1e-3 moves it by |f(u)|·1e-3
    probe = stepper(SH, grid, {"r": r}, 1e-3, "numpy")
    probe.set_state({"u": u})
    probe.advance(1)
    assert np.max(np.abs(probe.get_state()["u"][0] - u)) / 1e-3 < 1e-4
    # explicit Euler at the same step blows up
    ex = stepper(SH, grid, {"r": r}, dt, "numpy")
    ex.set_state({"u": u0})
    with np.errstate(all="ignore"):
        ex.advance(150)
    assert not np.all(np.abs(ex.get_state()["u"]) < 1e3)


# ---------------------------------------------------------------------------- 5. limits
def _inv_h2(domain) -> float:
    """Σ 1/h² over the grid's axes (dy, dz are inf along absent axes)."""
    return 1 / domain.dx**2 + 1 / domain.dy**2 + 1 / domain.dz**2


LIMIT_GRIDS = [Grid((8,), dx=0.7), Grid((6, 8), dx=0.7, dy=1.3),
               Grid((4, 6, 8), dx=0.7, dy=1.3, dz=0.5)]


def test_euler_limit_of_diagonal_diffusion():
    model = define_model("two-diffusions", {"u": "D1*laplace(u) - u*v",
                                            "v": "laplace(v)*D2/2 + u"},
                         {"D1": 0.7, "D2": 1.2})
    for grid in LIMIT_GRIDS:
        expect = 1 / (2 * 0.7 * _inv_h2(grid))  # D2/2 = 0.6 < 0.7
        for method in ("euler", "heun", "rk3"):
            assert model.dt_limit(grid, {}, method) == pytest.approx(expect, rel=1e-12)
        assert model.dt_limit(grid, {"D2": 3.0}) == pytest.approx(
            1 / (2 * 1.5 * _inv_h2(grid)), rel=1e-12)
    mesh = SurfaceMesh.icosphere(2)
    assert model.dt_limit(mesh, {}) == pytest.approx(mesh.max_stable_dt(0.7), rel=1e-12)


def test_euler_limit_of_cross_diffusion_and_bilaplacian():
    c, K = 2.0, 0.3
    cgl = define_model("cgl-like", {"u": "laplace(u) - c*laplace(v) + u - u*u*u",
                                    "v": "c*laplace(u) + laplace(v) - v"}, {"c": c})
    bil = define_model("bilaplacian", {"u": "-K*laplace(laplace(u))"}, {"K": K})
    lam = np.linalg.eigvals(np.array([[1.0, -c], [c, 1.0]]))
    for grid in LIMIT_GRIDS:
        m_max = 4 * _inv_h2(grid)
        # −2 Re μ/|μ|² over the eigenvalues μ = −m λ of −m D, smallest at m = m_max
        expect = float(np.min(2 * lam.real / (m_max * np.abs(lam) ** 2)))
        assert expect == pytest.approx(2 / (m_max * (1 + c * c)))
        assert cgl.dt_limit(grid, {}) == pytest.approx(expect, rel=1e-12)
        assert bil.dt_limit(grid, {}) == pytest.approx(2 / (K * m_max**2), rel=1e-12)
        # 2m − m² + (r − 1) (the constant damping (r − 1)u = −0.7u counts, issue 23):
        # limit 2/(m² − 2m + 0.7), smallest at m_max
        assert SH.dt_limit(grid, {}) == pytest.approx(2 / (m_max**2 - 2 * m_max + 0.7),
                                                      rel=1e-12)


def test_constant_damping_tightens_the_explicit_limit():
    """A species' constant damping ``−k s`` is stepped by an explicit method too: the
    limit is ``2/(m_max D + k)`` (``2/k`` without diffusion), not the diffusion's alone
    (``u_t = Δu − u`` once got dt 0.225 > 2/9 by default and diverged); a growth term does
    not loosen it, and IMEX methods keep their limit."""
    grid = LIMIT_GRIDS[1]
    m_max = 4 * _inv_h2(grid)
    decay = define_model("decay", {"u": "laplace(u) - k*u"}, {"k": 3.0})
    assert decay.dt_limit(grid) == pytest.approx(2 / (m_max + 3.0), rel=1e-12)
    assert define_model("ou", {"u": "-k*u"}, {"k": 4.0}).dt_limit(grid) == 0.5
    grow = define_model("grow", {"u": "laplace(u) + u"})
    assert grow.dt_limit(grid) == pytest.approx(2 / m_max, rel=1e-12)
    assert decay.dt_limit(grid, method="imex") == math.inf
    sim = rdgpu.Simulation(define_model("c", {"u": "laplace(u) - u"}), Grid((24, 24)),
                           backend="numpy", init={"kind": "uniform", "values": {"u": 0.0},
                                                            "noise": 1.0})
    assert sim.dt <= 2 / 9
    res = sim.run(400, progress=False)
    assert res.diverged is None and np.abs(res.fields["u"]).max() < 1.0


DIFFUSION = define_model("diffusion", {"u": "D*laplace(u)"}, {"D": 0.7})


@pytest.mark.parametrize("kind", ["grid2", "grid3", "mesh"])
def test_stepping_just_above_and_below_the_euler_limit(kind):
    """Pure diffusion from noise, 500 steps: at 1.05× the limit the stiffest mode grows
    (by |1 − 2·1.05| = 1.1 per step on a grid) past 1e6; at 0.99× the maximum principle
    holds; the stability check refuses the first and accepts the second."""
    domain = {"grid2": LIMIT_GRIDS[1], "grid3": LIMIT_GRIDS[2],
              "mesh": SurfaceMesh.icosphere(2)}[kind]
    limit = DIFFUSION.dt_limit(domain, {})
    u0 = np.random.default_rng(9).uniform(-1, 1, domain_shape(domain))
    out = {}
    for factor in (0.99, 1.05):
        st = stepper(DIFFUSION, domain, {}, factor * limit, "numpy")
        st.set_state({"u": u0})
        st.advance(500)
        out[factor] = float(np.max(np.abs(st.get_state()["u"])))
    assert out[0.99] <= np.max(np.abs(u0))
    assert out[1.05] > 1e6
    with pytest.raises(StabilityError, match="stability limit"):
        DIFFUSION.stepper(domain, {}, dt=1.05 * limit, backend="numpy")
    DIFFUSION.stepper(domain, {}, dt=0.99 * limit, backend="numpy")
    DIFFUSION.stepper(domain, {}, dt=1.05 * limit, backend="numpy", check_stability=False)


def test_allen_cahn_limit_and_energy_on_3d_grids():
    """Regression: Allen-Cahn's explicit limit left out 1/dz² (0.25 on a unit 3-D grid for
    the true 1/6, and steps at 0.99× of it broke the maximum principle), and its energy
    took y for x and left out z."""
    ac = MODELS["allen-cahn"]
    grid = Grid((4, 4, 4), dx=1.0, bc="periodic")
    assert ac.dt_limit(grid) == pytest.approx(1 / 6)
    assert ac.dt_limit(Grid((4, 5, 6), dx=0.5, dy=0.7, dz=0.9)) == pytest.approx(
        1 / (2 * (1 / 0.25 + 1 / 0.49 + 1 / 0.81)))
    assert ac.dt_limit(Grid((6,), dx=0.5)) == pytest.approx(0.125)
    checker = 0.9 * (-1.0) ** np.indices(grid.shape).sum(axis=0)
    st = ac.stepper(grid, {"eps": 1.0}, dt=0.99 * ac.dt_limit(grid), backend="numpy")
    st.set_state({"u": checker})
    st.advance(50)
    assert np.abs(st.get_state()["u"]).max() <= 1.0  # Lemma 3.1 (b = 0)
    # −∂J/∂u = dx dy dz (Δ_h u − (u³ − u + b)/ε²) with the 7-point Laplacian
    rng = np.random.default_rng(10)
    g = Grid((3, 2, 4), dx=0.7, dy=0.9, dz=1.2,
             bc=("periodic", ("dirichlet", 0.3), "neumann"))
    u = rng.uniform(-1, 1, g.shape)
    params = {"b": 0.1, "eps": 0.8}
    lap = stepper(define_model("lap", {"w": "laplace(w)"}, {}), g, {}, 1.0, "numpy")
    lap.set_state({"w": u})
    lap.advance(1)
    expect = -g.cell_volume * ((lap.get_state()["w"] - u) - (u**3 - u + 0.1) / 0.64)
    grad = np.zeros_like(u)
    h = 1e-6
    for idx in np.ndindex(u.shape):
        d = np.zeros_like(u)
        d[idx] = h
        grad[idx] = (AllenCahn.energy(g, u + d, params)
                     - AllenCahn.energy(g, u - d, params)) / (2 * h)
    np.testing.assert_allclose(grad, expect, rtol=1e-6, atol=1e-6)


def test_factored_linear_terms():
    """Regression: a constant factor of a sum with a Laplacian, ``D*(laplace(u) − u)``,
    made the equation count as state-dependent: no stability limit at all (dt_limit inf,
    so any dt passed the check) and IMEX refused it."""
    model = define_model("factored", {"u": "D*(laplace(u) - u)/2", "v": "-(v - laplace(v))*c"},
                         {"D": 1.0, "c": 0.5})
    D, B = model.linear_operators()
    np.testing.assert_array_equal(D, [[0.5, 0.0], [0.0, 0.5]])
    np.testing.assert_array_equal(B, np.zeros((2, 2)))
    grid = LIMIT_GRIDS[1]
    # −m/2 − 1/2 per mode (the damping −u/2 counts): 2/(2 Σ1/h² + 1/2)
    assert model.dt_limit(grid) == pytest.approx(2 / (2 * _inv_h2(grid) + 0.5), rel=1e-12)
    with pytest.raises(StabilityError):
        model.stepper(grid, {}, dt=2 * model.dt_limit(grid), backend="numpy")
    st = model.stepper(grid, {}, dt=10 * model.dt_limit(grid), backend="numpy",
                       method="imex")
    u0 = np.random.default_rng(11).uniform(0, 1, grid.shape)
    st.set_state({"u": u0, "v": u0})
    st.advance(20)
    for s in "uv":  # decays (−u/2 on top of diffusion), stays bounded
        assert np.abs(st.get_state()[s]).max() < np.abs(u0).max()


# ---------------------------------------------------------------------------- 6. errors
ALLOWED = "allowed: species \\(u, v\\), parameters \\(D, k\\)"
BAD_EQUATIONS = [
    ("D*laplace(u) + w", "the unknown name 'w'"),
    ("erf(u)", "the unknown function 'erf'"),
    ("min(u)", "min\\(\\) with 1 argument\\(s\\) \\(it takes 2\\)"),
    ("exp(u, v)", "exp\\(\\) with 2 argument\\(s\\) \\(it takes 1\\)"),
    ("laplace(u, v)", "laplace\\(\\) with other than one argument"),
    ("laplace(grad(u))", "the unknown function 'grad'"),
    ("div(u)", "div\\(u\\) \\(div takes D\\*grad\\(species\\)"),
    ("div(grad(u + v))", "grad\\(u \\+ v\\) inside div\\(\\) \\(grad takes one species\\)"),
    ("u < v < 1", "the chained comparison 'u < v < 1'"),
    ("u && v", "the character\\(s\\) '&', outside the language"),
    ("u = 1", "is not a valid expression"),
    ("u.real", "'u.real' \\(Attribute syntax\\)"),
    ("'a'*u", "the character\\(s\\) \"'\""),
    ("1j*u", "the constant 1j \\(only real numbers are allowed\\)"),
    ("True*u", "the constant True"),
    ("1e400*u", "the number 1e400, which is too large"),
    ("lambda q: q", "the character\\(s\\) ':'"),
    ("exp(u)(v)", "the call 'exp\\(u\\)\\(v\\)'"),
    ("u(v)", "the unknown function 'u'"),
    ("np.exp(u)", "the call 'np.exp\\(u\\)'"),
    ("u if v else 1", "\\(IfExp syntax\\)"),
    ("u[0]", "the character\\(s\\) '\\[', '\\]'"),
    ("lambda q, r, s: q", "the character\\(s\\) ':'"),
    ("u, v", "'\\(u, v\\)' \\(Tuple syntax\\)"),
    ("u // 2", "the operator 'FloorDiv'"),
    ("u +", "is not a valid expression"),
]


@pytest.mark.parametrize("text, match", BAD_EQUATIONS, ids=[t for t, _ in BAD_EQUATIONS])
def test_bad_equations_name_the_token_and_what_is_allowed(text, match):
    with pytest.raises(EquationError, match=f"{match}.*; {ALLOWED}, x y z t, Lx Ly Lz, pi"):
        define_model("bad", {"u": text, "v": "laplace(v)"}, {"D": 1.0, "k": 0.5})


BAD_NAMES = [
    ({"x": "laplace(x)"}, {}, "species name 'x' is a reserved name"),
    ({"laplace": "1"}, {}, "species name 'laplace' is a reserved name"),
    ({"pi": "1"}, {}, "species name 'pi' is a reserved name"),
    ({"u": "laplace(u)"}, {"t": 1.0}, "parameter name 't' is a reserved name"),
    ({"u": "u"}, {"exp": 1.0}, "parameter name 'exp' is a reserved name"),
    ({"u": "u"}, {"Lx": 1.0}, "parameter name 'Lx' is a reserved name"),
    ({"u": "u"}, {"_a": 1.0}, "names starting with '_' are reserved"),
    ({"u": "u"}, {"u": 1.0}, "names used both as species and parameter: \\['u'\\]"),
    ({"for": "1"}, {}, "'for' is not a valid identifier"),
    ({"1u": "1"}, {}, "'1u' is not a valid identifier"),
    ({"ü": "1"}, {}, "must be ASCII"),
    ({}, {}, "equations map each species"),
]


@pytest.mark.parametrize("eqs, params, match", BAD_NAMES, ids=[m for *_, m in BAD_NAMES])
def test_reserved_and_duplicate_names(eqs, params, match):
    with pytest.raises(EquationError, match=match):
        define_model("bad", eqs, params)


def test_bad_parameters_and_fields():
    model = define_model("m", {"u": "D*laplace(u) - k*u"}, {"D": 1.0, "k": 0.5})
    grid = Grid((4, 5))
    cases = [
        ({"G": 1.0}, ValueError, "no parameter\\(s\\) \\['G'\\]; its parameters are "
                                 "\\['D', 'k'\\]"),
        ({"k": np.ones((5, 4))}, ValueError, "'k' has shape \\(5, 4\\); a field must match "
                                             "the domain's shape \\(4, 5\\)"),
        ({"k": [1.0, 2.0]}, ValueError, "'k' has shape \\(2,\\)"),
        ({"k": float("nan")}, ValueError, "'k' must be finite, got nan"),
        ({"k": float("inf")}, ValueError, "'k' must be finite, got inf"),
        ({"k": np.full((4, 5), np.nan)}, ValueError, "field 'k' contains NaN or Inf"),
        ({"k": "sqrt(x - 1)"}, ValueError, "field 'k' contains NaN or Inf"),
        ({"k": "log(-1 - 0*x)"}, ValueError, "field 'k' contains NaN or Inf"),
        ({"k": "log(-1)"}, ValueError, "'k' = 'log\\(-1\\)' is nan"),
        ({"k": "w*2"}, EquationError, "parameter 'k' 'w\\*2' uses the unknown name 'w'"),
        ({"k": "laplace(u)"}, EquationError, "a parameter expression has no Laplacian"),
        ({"k": True}, TypeError, "'k' must be a number, an array, a field spec or an "
                                 "expression string, got True"),
        ({"k": None}, TypeError, "got None"),
        ({"k": {"kind": "gaussian"}}, ValueError, "unknown parameter field kind "
                                                  "'gaussian'"),
    ]
    for params, exc, match in cases:
        with pytest.raises(exc, match=match):
            model.stepper(grid, params, dt=0.1, backend="numpy")
    for kw, exc, match in [({"method": "bogus"}, ValueError, "unknown method 'bogus'; "
                                                             "allowed: euler, heun, midpoint, rk3"),
                           ({"dtype": np.float16}, TypeError, "float32 or float64"),
                           ({"dt": -1.0}, ValueError, "positive"),
                           ({"dt": float("nan")}, ValueError, "positive")]:
        with pytest.raises(exc, match=match):
            model.stepper(grid, {}, **{"dt": 0.1, "backend": "numpy", **kw})
    st = model.stepper(grid, {}, dt=0.1, backend="numpy")
    with pytest.raises(ValueError, match="field 'u' has shape \\(5, 4\\), the domain "
                                         "\\(4, 5\\)"):
        st.set_state({"u": np.ones((5, 4))})
    with pytest.raises(KeyError, match="missing \\['u'\\]"):
        st.set_state({"v": np.ones((4, 5))})
    # a mesh field has one value per vertex
    mesh = SurfaceMesh.icosphere(1)
    with pytest.raises(ValueError, match="domain's shape \\(42,\\)"):
        model.stepper(mesh, {"k": np.ones(40)}, dt=0.01, backend="numpy")


def test_time_expression_singular_at_zero():
    """Regression: an expression of t that is not finite at t = 0 (a forcing 0.1/t for a
    run resumed at t > 0) raised ZeroDivisionError while the stability limit looked at the
    parameters."""
    model = define_model("decay", {"u": "laplace(u) - k*u"}, {"k": 0.0})
    grid = Grid((6,))
    assert model.dt_limit(grid, {"k": "0.1/t"}) == pytest.approx(0.5)
    st = model.stepper(grid, {"k": "0.1/t"}, dt=0.1, backend="numpy")
    st.set_state({"u": np.ones(6)}, steps=1)  # from t = 0.1
    st.advance(2)
    expect = (1 - 0.1 * (0.1 / 0.1)) * (1 - 0.1 * (0.1 / 0.2))
    np.testing.assert_allclose(st.get_state()["u"], expect, rtol=1e-14)


def test_mesh_presets_build():
    """Regression: build_domain imported SurfaceMesh from a module that does not exist."""
    mesh = build_domain({"mesh": "sphere", "subdivisions": 1})
    assert isinstance(mesh, SurfaceMesh) and mesh.n_vertices == 42


# ---------------------------------------------------------------------------- 7. expressions
GSX = define_model("gs-param", {"u": "Du*laplace(u) - u*v**2 + F*(1 - u)",
                                "v": "Dv*laplace(v) + u*v**2 - (F + k)*v"},
                   {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.06})


@pytest.mark.parametrize("backend_name", ["numpy", "warp", "opencl"])
def test_expression_of_x_equals_the_array(backend_name, dtype):
    be = backend_or_skip(backend_name)
    grid = Grid((6, 10), dx=0.9, dy=1.1, bc=("neumann", "periodic"))
    x = (np.arange(10) + 0.5) * 0.9
    y = (np.arange(6) + 0.5) * 1.1
    Lx = 10 * 0.9
    F = 0.03 + 0.01 * np.sin(2 * np.pi * x / Lx)[None, :] + 0.002 * y[:, None]
    rng = np.random.default_rng(12)
    init = {"u": 1 - 0.3 * rng.random(grid.shape), "v": 0.3 * rng.random(grid.shape)}
    out = []
    for value in ("0.03 + 0.01*sin(2*pi*x/Lx) + 0.002*y", F):
        st = stepper(GSX, grid, {"F": value}, 1.0, be, dtype)
        st.set_state(init)
        st.advance(5)
        out.append(st.get_state())
    for s in GSX.species:
        np.testing.assert_array_equal(out[0][s], out[1][s])
    # on a mesh: the vertex coordinates
    mesh = SurfaceMesh.icosphere(1)
    V = mesh.vertices
    F = 0.03 + 0.01 * V[:, 0] * V[:, 2] - 0.005 * V[:, 1]
    init = {"u": 1 - 0.3 * rng.random(42), "v": 0.3 * rng.random(42)}
    out = []
    for value in ("0.03 + 0.01*x*z - 0.005*y", F):
        st = stepper(GSX, mesh, {"F": value}, 0.2, be, dtype)
        st.set_state(init)
        st.advance(3)
        out.append(st.get_state())
    for s in GSX.species:
        np.testing.assert_array_equal(out[0][s], out[1][s])


@pytest.mark.parametrize("method", ["euler", "heun"])
def test_expression_of_t_equals_host_updates(dtype, method):
    """F(t) inlined in the kernel (evaluated per cell in the dtype at each stage's time)
    against F set on the host before each step (Euler) or stage (Heun: F(t) then
    F(t + h)), evaluated in float64: equal to round-off (8 eps of the fields; measured
    ≤ 0.5 eps), and far from a run with F constant."""
    grid = Grid((5, 7), dx=1.0, bc="periodic")
    rng = np.random.default_rng(13)
    init = {"u": 1 - 0.3 * rng.random(grid.shape), "v": 0.3 * rng.random(grid.shape)}
    dt, steps = 1.0, 20

    def F(t):
        return 0.035 + 0.01 * np.sin(0.3 * t)

    st = stepper(GSX, grid, {"F": "0.035 + 0.01*sin(0.3*t)"}, dt, "numpy", dtype, method)
    st.set_state(init)
    st.advance(steps)
    got = st.get_state()
    state = init
    for n in range(steps):
        t = n * dt
        if method == "euler":
            one = stepper(GSX, grid, {"F": F(t)}, dt, "numpy", dtype)
            one.set_state(state, steps=n)
            one.advance(1)
            state = one.get_state()
        else:  # Heun by hand: x1 = x + h f(x, t); x' = ½x + ½(x1 + h f(x1, t + h))
            a = stepper(GSX, grid, {"F": F(t)}, dt, "numpy", dtype)
            a.set_state(state)
            a.advance(1)
            x1 = a.get_state()
            b = stepper(GSX, grid, {"F": F(t + dt)}, dt, "numpy", dtype)
            b.set_state(x1)
            b.advance(1)
            x2 = b.get_state()
            h = np.dtype(dtype).type(0.5)
            state = {s: h * state[s].astype(dtype) + h * x2[s] for s in GSX.species}
    const = stepper(GSX, grid, {"F": 0.035}, dt, "numpy", dtype, method)
    const.set_state(init)
    const.advance(steps)
    eps = np.finfo(dtype).eps
    for s in GSX.species:
        np.testing.assert_allclose(got[s], state[s], rtol=0, atol=8 * eps)
        assert np.max(np.abs(got[s] - const.get_state()[s])) > 1e-4
