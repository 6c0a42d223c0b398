"""Hostile equations and names (issue 19: A2, A8-A11, C): generated names that cannot
collide with user names on any backend, bounded power expansion, nesting and size
limits, literals and parameters the dtype cannot hold, characters outside the language,
bad bounds, and divergence reports that name the real cause."""

from __future__ import annotations

import time

import numpy as np
import pytest
from conftest import backend_or_skip

from rdgpu.core.errors import SimulationDiverged
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.ir import equations as eq
from rdgpu.models import EquationError, define_model

# ---------------------------------------------------------------------------- A2: names
#: user names equal to (or built like) every name the generators use: the buffers and
#: their flat views (in_u, in_u_1d, out_u, pf_F, F_1d, pm_F, p_F), the cell's locals
#: (c_u, f_F, L_u, qw_u, qsw0_u, o0_), the scalars (b_t, b_h, len_x), the coordinates
#: (xc, coord_x), the metric arguments (me_ex), the internal programs' buffers (base_u,
#: lap_u, y__u, k1__u, lin_u), the templates' locals and helpers (r, j, w, e, rs, nx, dx,
#: row, cell, flat, flush, two, real, A, NONNEG, data, indices, q_, k_) and words of the
#: targets (float, int, kernel, local, constant, sizeof, half, wp, const, restrict, bool, double)
COLLIDING_SPECIES = ["u", "u_1d", "in_u", "c_u", "lap_u", "qw_u", "qsw0_u", "base_u",
                     "k1__u", "lin_u", "b_t", "float", "kernel", "wp", "real", "flat"]
COLLIDING_PARAMS = [
    "F", "F_1d", "pf_F", "p_F", "f_F", "pm_F", "in_F", "D", "b__h", "h", "len_y", "r", "j",
    "w", "e", "rs", "nx", "dx", "row", "cell", "flush", "two", "A", "NONNEG", "data",
    "indices", "q_", "k_", "m_", "int", "local", "constant", "sizeof", "half", "const",
    "restrict", "bool", "double", "R0", "xc", "coord_x", "me_ex", "o0_", "L_u", "out_u",
    "y__u"]


def _colliding_model():
    """Each species diffuses and couples to the next one and to parameters (only exact
    operations, so the backends agree bit for bit)."""
    sp, ps = COLLIDING_SPECIES, COLLIDING_PARAMS
    eqs = {}
    for i, s in enumerate(sp):
        nxt = sp[(i + 1) % len(sp)]
        mine = " ".join(f"- {p}*{s}" for p in ps[i::len(sp)])
        eqs[s] = f"0.5*laplace({s}) + 0.25*laplace({nxt}) {mine} + 0.125*{nxt}*{s}"
    params = {p: 0.01 * (k + 1) for k, p in enumerate(ps)}
    return define_model("colliding", eqs, params)


COLLIDING = _colliding_model()


def _run(model, domain, params, backend, **kw):
    st = model.stepper(domain, params, dt=0.02, backend=backend, **kw)
    rng = np.random.default_rng(7)
    shape = domain.shape if isinstance(domain, Grid) else (domain.n_vertices,)
    st.set_state({s: rng.uniform(0, 1, shape) for s in model.species})
    st.advance(3)
    return st.get_state()


def _fields(domain):
    """Parameter fields F and F_1d (and pf_F) beside the scalars."""
    shape = domain.shape if isinstance(domain, Grid) else (domain.n_vertices,)
    rng = np.random.default_rng(3)
    return {"F": rng.uniform(0, 0.1, shape), "F_1d": rng.uniform(0.2, 0.3, shape),
            "pf_F": rng.uniform(0.4, 0.5, shape)}


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["grid2", "mesh"])
@pytest.mark.parametrize("backend_name", ["warp", "opencl"])
def test_user_names_like_generated_names_agree_with_numpy(backend_name, kind):
    """Issue 19 A2: species u beside u_1d (Warp's flat view of u was in_u_1d, the
    argument of species u_1d) and a parameter field F beside F_1d; every name pattern of
    the generators as a user name, rk3 (its combining program reads base_u)."""
    be = backend_or_skip(backend_name)
    domain = Grid((5, 7), bc=("periodic", ("dirichlet", 0.3))) if kind == "grid2" \
        else SurfaceMesh.icosphere(1)
    params = _fields(domain)
    ref = _run(COLLIDING, domain, params, "numpy", method="rk3")
    got = _run(COLLIDING, domain, params, be, method="rk3")
    for s in COLLIDING.species:
        np.testing.assert_array_equal(got[s], ref[s], err_msg=f"{backend_name} {s}")


def test_issue_reproducer_u_beside_u_1d():
    """The issue's reproducer on every backend, the blocked OpenCL kernel included."""
    model = define_model("m", {"u": "0.1*laplace(u) - u", "u_1d": "0.1*laplace(u_1d) + 0*u"},
                         {})
    grid = Grid((16, 12))
    ref = _run(model, grid, {}, "numpy")
    assert np.abs(ref["u_1d"]).max() > 0
    for name, kw in [("warp", {}), ("opencl", {}), ("opencl", {"block_steps": 3})]:
        got = _run(model, grid, {}, backend_or_skip(name), **kw)
        for s in model.species:
            np.testing.assert_array_equal(got[s], ref[s], err_msg=f"{name} {kw} {s}")


@pytest.mark.slow
@pytest.mark.parametrize("backend_name", ["warp", "opencl"])
def test_ensemble_parameters_beside_lookalikes(backend_name):
    """Per-member parameters (read once per row or vertex into _p_F) beside a field F_1d,
    a scalar p_F and a per-member pm_F, on an ensemble grid and mesh."""
    be = backend_or_skip(backend_name)
    model = define_model("m", {"u": "0.2*laplace(u) - F*u + F_1d*u_1d - p_F*pm_F",
                               "u_1d": "0.1*laplace(u_1d) - pm_F*u_1d + c_u",
                               "c_u": "-p_F*c_u + F*u"},
                         {"F": 0.0, "F_1d": 0.0, "p_F": 0.25, "pm_F": 0.0})
    for domain in (Grid((5, 6), bc=("periodic", "neumann")), SurfaceMesh.icosphere(1)):
        shape = domain.shape if isinstance(domain, Grid) else (domain.n_vertices,)
        rng = np.random.default_rng(5)
        params = {"F": np.array([0.5, 0.25]), "pm_F": np.array([0.125, 0.375]),
                  "F_1d": rng.uniform(0, 1, shape)}
        out = []
        for b in ("numpy", be):
            st = model.stepper(domain, params, dt=0.02, backend=b, members=2)
            st.set_state({s: np.random.default_rng(9).uniform(0, 1, (2, *shape))
                          for s in model.species})
            st.advance(3)
            out.append(st.get_state())
        for s in model.species:
            np.testing.assert_array_equal(out[1][s], out[0][s], err_msg=f"{domain} {s}")


def test_blocked_kernel_with_colliding_names():
    be = backend_or_skip("opencl")
    grid = Grid((16, 9))
    params = _fields(grid)
    ref = _run(COLLIDING, grid, params, "numpy")
    got = _run(COLLIDING, grid, params, be, block_steps=3)
    for s in COLLIDING.species:
        np.testing.assert_array_equal(got[s], ref[s], err_msg=s)


KINDS = ["grid1", "grid2", "grid3", "grid2iso", "grid3iso", "grid2metric", "mesh"]


@pytest.mark.parametrize("kind", KINDS)
def test_generated_sources_never_rebind_a_name(kind):
    """Every kind, without compiling: no Warp function assigns to one of its arguments
    (Warp's flat view in_u_1d = flat(in_u) replaced the argument of species u_1d) or binds
    a generated name twice; no OpenCL kernel
    declares a name twice or as one of its arguments."""
    import ast
    import re

    from rdgpu.backends.opencl_codegen import blocked_source, opencl_source
    from rdgpu.backends.warp_codegen import warp_source

    st = COLLIDING.stepper(Grid((4, 4)), {}, dt=0.01, backend="numpy", method="rk3")
    fields = frozenset({"F", "F_1d", "pf_F"})
    for program in (st._euler, st._combine):
        for member in (frozenset(), frozenset({"p_F", "pm_F"})):
            src = warp_source(program, kind, fields, np.float32, member)
            for fn in ast.walk(ast.parse(src)):
                if not isinstance(fn, ast.FunctionDef):
                    continue
                args = {a.arg for a in fn.args.args}
                bound = [t.id for node in ast.walk(fn) if isinstance(node, ast.Assign)
                         for t in node.targets if isinstance(t, ast.Name)]
                assert not args & set(bound), (fn.name, sorted(args & set(bound)))
                twice = {b for b in bound if bound.count(b) > 1 and b.startswith("_")}
                assert not twice, (fn.name, twice)
            sources = [opencl_source(program, kind, fields, np.float32, member)]
            if kind == "grid2" and program is st._euler:
                sources.append(blocked_source(program, kind, fields, np.float32, member))
            for src in sources:
                for kernel in re.split(r"\n(?=__kernel|INLINE)", src):
                    head, _, body = kernel.partition("{")
                    args = set(re.findall(r"(\w+)\s*(?:,|\))", head))
                    decl = re.findall(r"(?:const real|real|__global [^*]*\*)\s*(\w+)\s*=",
                                      body)
                    assert not args & set(decl), sorted(args & set(decl))
                    assert len(decl) == len(set(decl)), sorted(
                        d for d in decl if decl.count(d) > 1)


@pytest.mark.parametrize("name", ["_u", "__u", "_"])
def test_leading_underscore_is_refused(name):
    with pytest.raises(EquationError, match="names starting with '_' are reserved"):
        define_model("m", {name: "-1"}, {})
    with pytest.raises(EquationError, match="names starting with '_' are reserved"):
        define_model("m", {"u": "-u"}, {name: 1.0})
    # and the parser does not know such a name in an equation
    with pytest.raises(EquationError, match=f"the unknown name '{name}'"):
        define_model("m", {"u": f"-u + {name}"}, {})


@pytest.mark.parametrize("name, match", [
    ("sin", "reserved name"), ("min", "reserved name"), ("laplace", "reserved name"),
    ("global", "a keyword"), ("lambda", "a keyword"), ("None", "a keyword"),
    ("u-1", "not a valid identifier"), ("", "not a valid identifier"),
])
def test_names_of_the_language_are_refused(name, match):
    with pytest.raises(EquationError, match=match):
        define_model("m", {name: "-1"}, {})


def test_generated_names_are_injective():
    """Every (role, buffer) pair gets its own identifier, none a user name."""
    from rdgpu.ir.names import ident

    seen = {}
    roles = ["in", "out", "pf", "pm", "p", "c", "f", "lap", "qw", "qsw", "qsw0", "vin"]
    for role in roles:
        for name in ["u", "u_1d", "in_u", "_lap_u", "w_u", "sw0_u"]:
            got = ident(role, name)
            assert got.startswith("_") and got not in seen, (role, name, seen.get(got))
            seen[got] = (role, name)
    with pytest.raises(ValueError):
        ident("in_1d", "u")


# ---------------------------------------------------------------------------- A8: powers
def test_nested_powers_define_quickly_and_evaluate():
    for levels in (4, 5, 8):
        text = "-" + "(" * levels + "u" + "".join(")**16" for _ in range(levels))
        t0 = time.perf_counter()
        m = define_model("p", {"u": text}, {})
        assert time.perf_counter() - t0 < 0.5, levels
        size = sum(1 for _ in eq.walk(m.trees["u"]))
        assert size <= eq.MAX_EXPANDED_NODES + 8, size
    # (u**16)**16 = u**256, evaluated (as pow past the budget) correctly
    m = define_model("p", {"u": "((u**16)**16)**-1 + (u**3)**2"}, {})
    u = np.array([0.5, 1.001, 1.5, -1.01])
    got = m.rates([u], {})[0]
    np.testing.assert_allclose(got, u ** -256.0 + u ** 6.0, rtol=1e-13)
    # small powers still expand into multiplications (exact on every backend)
    assert not any(isinstance(n, eq.Call) for n in eq.walk(define_model(
        "p", {"u": "(u*u + 1)**4 - u**-3"}, {}).trees["u"]))


@pytest.mark.parametrize("backend_name", ["numpy", "warp", "opencl"])
def test_deep_power_runs_on_every_backend(backend_name):
    be = backend_or_skip(backend_name)
    model = define_model("p", {"u": "0.1*laplace(u) - 0.01*(((u**16)**16)**16)"}, {})
    grid = Grid((6,), bc="periodic")
    st = model.stepper(grid, {}, dt=0.1, backend=be)
    u0 = np.linspace(0.99, 1.0005, 6)
    st.set_state({"u": u0})
    st.advance(1)
    lap = np.roll(u0, 1) + np.roll(u0, -1) - 2 * u0
    expect = u0 + 0.1 * (0.1 * lap - 0.01 * u0 ** 4096.0)
    np.testing.assert_allclose(st.get_state()["u"].ravel(), expect, rtol=1e-12)


# ---------------------------------------------------------------------------- A9: literals
@pytest.mark.parametrize("backend_name", ["numpy", "warp", "opencl"])
def test_literal_beyond_the_dtype_is_refused(backend_name):
    be = backend_or_skip(backend_name)
    model = define_model("m", {"u": "1e39*u - 1e39*u"})
    grid = Grid((4,))
    with pytest.raises(ValueError, match="equation of 'u'.*1e\\+39.*float32"):
        model.stepper(grid, {}, dt=0.1, backend=be, dtype=np.float32)
    model.stepper(grid, {}, dt=0.1, backend=be, dtype=np.float64)  # fits


def test_parameters_and_bounds_beyond_the_dtype_are_refused():
    model = define_model("m", {"u": "Du*laplace(u) - k*u"}, {"Du": 0.1, "k": 1.0},
                         bounds={"u": (None, 1e39)})
    grid = Grid((4,))
    f32 = {"dt": 0.1, "backend": "numpy", "dtype": np.float32}
    with pytest.raises(ValueError, match="bound.*'u'.*1e\\+39.*float32"):
        model.stepper(grid, {}, **f32)
    model = define_model("m", {"u": "Du*laplace(u) - k*u"}, {"Du": 0.1, "k": 1.0})
    with pytest.raises(ValueError, match="parameter 'Du'.*1e\\+39.*float32"):
        model.stepper(grid, {"Du": 1e39}, **f32)
    with pytest.raises(ValueError, match="parameter 'k'.*float32"):
        model.stepper(grid, {"k": np.array([0, 1, 2, 1e39])}, **f32)
    with pytest.raises(ValueError, match="parameter 'k'.*float32"):
        model.stepper(grid, {"k": "1e39 + 0*t"}, **f32)
    # float64 holds them (the damping −1e39·u sets a stability limit of 2e-39: off here)
    model.stepper(grid, {"k": np.array([0, 1, 2, 1e39])}, dt=0.1, backend="numpy",
                  check_stability=False)


# ---------------------------------------------------------------------------- A10: characters
@pytest.mark.parametrize("text, shown", [
    ("-u # + v", "'#'"), ("-u\n+ v", "'\\\\n'"), ("-u\r+ v", "'\\\\r'"),
    ("u; v", "';'"), ("u \\\n+ v", "'\\\\\\\\'"), ("u @ v", "'@'"), ("u $ v", "'\\$'"),
    ("u & v", "'&'"), ("u[0]", "'\\[', '\\]'"), ("u % 2", "'%'"), ("'a'*u", "\"'\""),
    ("u\u00a0+ v", "'\\\\xa0'"), ("u + vé", "'é'"),
])
def test_characters_outside_the_language_are_named(text, shown):
    with pytest.raises(EquationError, match=f"character.*{shown}"):
        define_model("m", {"u": text, "v": "-v"})
    with pytest.raises(EquationError, match=f"character.*{shown}"):
        define_model("m", {"u": "-u + k"}, {"k": text.replace("v", "1").replace("u", "2")})\
            .stepper(Grid((4,)), {}, dt=0.1, backend="numpy")


def test_surrounding_whitespace_and_tabs_are_fine():
    m = define_model("m", {"u": "\n  -u\t+ 1  \n"})
    assert m.rates([np.array([2.0])], {})[0] == -1.0


# ---------------------------------------------------------------------------- A11: bounds
@pytest.mark.parametrize("bounds, match", [
    ({"u": (1, 0)}, "lower bound 1.* above its upper bound 0"),
    ({"u": (float("nan"), 1)}, "NaN"),
    ({"u": (0, float("nan"))}, "NaN"),
    ({"u": ("a", 1)}, "a number or None"),
    ({"u": (True, None)}, "a number or None"),
    ({"u": (0, 1, 2)}, "a pair"),
    ({"u": 5}, "a pair"),
    ({"u": (float("inf"), None)}, "lower bound of 'u' is inf"),
    ({"u": (None, float("-inf"))}, "upper bound of 'u' is -inf"),
])
def test_bad_bounds_are_refused(bounds, match):
    with pytest.raises(ValueError, match=match):
        define_model("m", {"u": "-u"}, {}, bounds=bounds)


def test_infinite_bounds_mean_no_bound():
    m = define_model("m", {"u": "-u"}, {}, bounds={"u": (float("-inf"), float("inf"))})
    assert m.bounds == {"u": (None, None)}
    assert define_model("m", {"u": "-u"}, bounds={"u": (0.5, 0.5)}).bounds["u"] == (0.5, 0.5)


# ---------------------------------------------------------------------------- C: limits
@pytest.mark.parametrize("text, match", [
    ("-" * 3000 + "u", "nests .*deep.*limit"),
    ("+".join(["u"] * 5000), "nests .*deep.*limit"),
    ("(" * 300 + "u" + ")" * 300, "nest"),
    ("+".join(["u"] * (eq.MAX_DEPTH + 2)), f"limit is {eq.MAX_DEPTH}"),
    ("1" * 400 + "*u", "the number 1111.* \\(400 digits\\), which is too large"),
    ("1e400*u", "the number 1e400, which is too large"),
    ("1" * 5000 + "*u", "too large|digits"),
])
def test_size_and_depth_limits(text, match):
    t0 = time.perf_counter()
    with pytest.raises(EquationError, match=match):
        define_model("m", {"u": text})
    assert time.perf_counter() - t0 < 2


def test_wide_expressions_past_the_node_budget_are_refused():
    def balanced(k):
        return "u" if k == 0 else f"({balanced(k - 1)}*{balanced(k - 1)})"

    text = balanced(15)  # 15 deep but 2**15 names
    with pytest.raises(EquationError, match="nodes.*limit"):
        define_model("m", {"u": text})


@pytest.mark.slow
def test_limits_at_the_edge_still_compile():
    """The deepest allowed sums run on every backend: an equation whose deepest term reads
    a parameter of t that is itself as deep (inlined in the kernel, so the generated source
    nests its parentheses twice as deep: Python's parser and Warp's code generator take
    them)."""
    def deepest(make):
        for n in range(eq.MAX_DEPTH, 0, -1):
            try:
                return make(n)
            except EquationError:
                continue

    def text(n):
        return "F*u + " + "+".join(f"{k}e-3*u" for k in range(n)) + " - u"

    eqn = deepest(lambda n: eq.parse(text(n), species=["u"], params=["F"]) and text(n))
    force = deepest(lambda n: eq.parse("+".join(["0.001*t"] * n)) and
                    "+".join(["0.001*t"] * n))
    assert eq.size_and_depth(eq.parse(eqn, species=["u"], params=["F"]))[1] >= \
        eq.MAX_DEPTH - 1
    assert eq.size_and_depth(eq.parse(force))[1] >= eq.MAX_DEPTH - 1
    model = define_model("m", {"u": eqn}, {"F": force})
    grid = Grid((5,))
    out = {}
    for name in ("numpy", "warp", "opencl"):
        be = backend_or_skip(name)
        st = model.stepper(grid, {}, dt=0.01, backend=be, method="rk3")
        st.set_state({"u": np.ones(5)})
        st.advance(2)
        out[name] = st.get_state()["u"]
    for name in out:
        np.testing.assert_allclose(out[name], out["numpy"], rtol=1e-12)


@pytest.mark.parametrize("where", ["default", "given"])
def test_parameter_division_by_zero_names_the_parameter(where):
    grid = Grid((4,))
    if where == "default":  # refused when the model is defined
        with pytest.raises(ValueError, match="parameter 'F' = '1/0' is inf"):
            define_model("m", {"u": "-F*u"}, {"F": "1/0"})
        with pytest.raises(EquationError, match="parameter 'F' '1 / ' is not a valid"):
            define_model("m", {"u": "-F*u"}, {"F": "1 / "})
        model = define_model("m", {"u": "-F*u - k*u"}, {"F": "0.1", "k": 0.0})
        given = {"F": "1/k"}
    else:
        model = define_model("m", {"u": "-F*u"}, {"F": 0.1})
        given = {"F": "1/0"}
    shown = "parameter 'F' = '1/0' is inf" if where == "given" else \
        "parameter 'F' = '1/k' is inf"
    with pytest.raises(ValueError, match=shown):
        model.stepper(grid, given, dt=0.1, backend="numpy")
    with pytest.raises(ValueError, match=shown):
        model.dt_limit(grid, given)
    from rdgpu.models import resolve_params

    with pytest.raises(ValueError, match=shown):
        resolve_params(model, grid, given)


def test_cli_param_division_by_zero(capsys):
    from conftest import cli

    code, out, err = cli(capsys, "run", "m", "--equation", "u=-F*u", "--param", "F=1/0",
                         "--size", "8", "--steps", "2", "--backend", "numpy",
                         "--out", "")
    assert code == 2, (out, err)
    assert "parameter 'F'" in err and "Traceback" not in err


# ---------------------------------------------------------------------------- C: divergence
def _diverge(eqs, params=None, dtype="float64", **kw):
    from rdgpu.simulation.driver import Simulation

    model = define_model("bad", eqs, params or {})
    sim = Simulation(model, {"grid": (8,)}, dt=0.1, backend="numpy", dtype=dtype,
                     fields={s: np.full(8, 0.5) for s in model.species}, **kw)
    with pytest.raises(SimulationDiverged) as info:
        sim.run(5)
    return info.value


@pytest.mark.parametrize("eqs, params, match", [
    ({"u": "-u/0"}, {}, "division by zero, \\(\\(-u\\) / 0\\.0\\) in the equation of 'u'"),
    ({"u": "log(u - u)"}, {}, "log of 0.*log\\(\\(u - u\\)\\)"),
    ({"u": "sqrt(-1 - u)"}, {}, "sqrt of a negative"),
    ({"u": "-F*u"}, {"F": "1/t"}, "parameter 'F'.*division by zero.*\\(1\\.0 / t\\).*t=0"),
    ({"u": "exp(2000*u)"}, {}, "exp.*overflows float64"),
])
def test_divergence_names_the_real_cause(eqs, params, match):
    exc = _diverge(eqs, params)
    assert exc.step == 1
    assert "dt=" not in exc.cause, exc.cause
    assert np.asarray(exc.result.fields["u"]).max() == 0.5  # the last good state kept
    import re

    assert re.search(match, exc.cause), exc.cause


def test_divergence_from_float32_overflow_names_the_dtype():
    # (its damping −1e40·u alone sets the stability limit 2e-40: checked off to see the run)
    exc = _diverge({"u": "-u*1e30*1e10"}, {}, dtype="float32", check_stability=False)
    assert "(((-u) * 1e+30) * 10000000000.0) reaching -5e+39, which float32 cannot hold " \
        "(the largest is 3.403e+38) in the equation of 'u'" in exc.cause, exc.cause
