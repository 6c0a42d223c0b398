"""The scheme registry (:mod:`rdgpu.ir.schemes`, :mod:`rdgpu.integrators`): the tableaux
are what they claim (order conditions, Shu-Osher stages equal to the tableau), names and
aliases resolve, new schemes register, and every method list (model, CLI help, docs, error
messages) is the registry's."""

from __future__ import annotations

import itertools
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import backend_or_skip

import rdgpu
from rdgpu.cli.app import build_parser
from rdgpu.domains.grid import Grid
from rdgpu.integrators import (
    SCHEMES,
    ExplicitScheme,
    ExponentialScheme,
    ImexScheme,
    MultistepScheme,
    get_scheme,
    method_names,
    register_scheme,
)
from rdgpu.models import MODELS, define_model

ROOT = Path(rdgpu.__file__).resolve().parents[1]
EXPLICIT = [s for s in SCHEMES.values() if isinstance(s, ExplicitScheme)]
#: every scheme that steps the whole right-hand side explicitly (Runge-Kutta, multistep)
STEPPED = [s for s in SCHEMES.values() if not s.implicit]


def _butcher(s: ExplicitScheme) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = s.stages
    a = np.zeros((n, n))
    for i, row in enumerate(s.a):
        a[i, :i] = row
    return a, np.array(s.b), np.array(s.c)


def _order_conditions(a, b, c) -> dict[int, list[float]]:
    """The residuals of the order conditions of orders 1 to 4 (Butcher's trees)."""
    one = np.ones(len(b))
    ac = a @ c
    return {
        1: [b @ one - 1],
        2: [b @ c - 1 / 2],
        3: [b @ c**2 - 1 / 3, b @ ac - 1 / 6],
        4: [b @ c**3 - 1 / 4, b @ (c * ac) - 1 / 8, b @ (a @ c**2) - 1 / 12,
            b @ (a @ ac) - 1 / 24],
    }


@pytest.mark.parametrize("scheme", EXPLICIT, ids=lambda s: s.name)
def test_tableau_has_its_order(scheme):
    a, b, c = _butcher(scheme)
    np.testing.assert_allclose(a.sum(axis=1), c, atol=1e-15)  # consistent nodes
    res = _order_conditions(a, b, c)
    for order in range(1, scheme.order + 1):
        assert np.max(np.abs(res[order])) < 1e-14, (scheme.name, order)
    if scheme.order < 4:  # and not more: the next order's conditions fail
        assert np.max(np.abs(res[scheme.order + 1])) > 1e-3


@pytest.mark.parametrize("scheme", STEPPED, ids=lambda s: s.name)
def test_every_explicit_scheme_has_its_measured_order(scheme):
    """``u_t = Δu`` on a periodic grid from one Fourier mode, whose semi-discrete solution
    is ``e^{−λt} u0``: float64 errors at dt, dt/2, dt/4 fall as dt^order (least-squares
    slope within 0.1)."""
    from rdgpu.domains.grid import Grid
    from rdgpu.models import define_model

    heat = define_model("heat", {"u": "laplace(u)"})
    n, dx, t_end = 16, 0.5, 0.4
    grid = Grid((n,), dx=dx, bc="periodic")
    u0 = np.sin(2 * np.pi * np.arange(n) / n)
    exact = np.exp(-(2 - 2 * np.cos(2 * np.pi / n)) / dx**2 * t_end) * u0
    errors = []
    for dt in (0.1, 0.05, 0.025):
        # one smooth mode: dt = 0.1 is past Adams-Bashforth 2's limit only for the
        # grid's highest modes, which hold nothing but round-off here
        st = heat.stepper(grid, dt=dt, backend="numpy", method=scheme.name,
                          check_stability=False)
        st.set_state({"u": u0})
        st.advance(round(t_end / dt))
        errors.append(np.max(np.abs(st.get_state()["u"].ravel() - exact)))
    slope = np.polyfit(np.log([0.1, 0.05, 0.025]), np.log(errors), 1)[0]
    assert slope == pytest.approx(scheme.order, abs=0.1), errors


@pytest.mark.parametrize("scheme", [s for s in EXPLICIT if s.shu_osher is not None],
                         ids=lambda s: s.name)
def test_shu_osher_stages_are_the_tableau(scheme):
    """One step of a nonlinear, time-dependent scalar ODE in both forms agrees (float64)."""
    def f(y, t):
        return np.sin(y) + t * np.cos(3 * y)

    a, b, c = _butcher(scheme)
    for x, t, h in itertools.product((0.3, -1.2), (0.0, 0.7), (0.1, 0.013)):
        k = []
        for i in range(scheme.stages):
            k.append(f(x + h * sum(a[i, j] * k[j] for j in range(i)), t + c[i] * h))
        butcher = x + h * sum(bi * ki for bi, ki in zip(b, k, strict=True))
        y = x + h * f(x, t)
        for sa, sb, sc in scheme.shu_osher:
            y = sa * x + sb * (y + h * f(y, t + sc * h))
        assert y == pytest.approx(butcher, rel=1e-14, abs=1e-15)


def test_names_aliases_and_errors():
    assert method_names() == tuple(SCHEMES)
    assert {"euler", "heun", "rk3", "rk4", "imex", "imex-cn", "bdf2"} <= set(SCHEMES)
    assert get_scheme("SSPRK3").name == "rk3"
    assert get_scheme("explicit").name == "euler"
    assert get_scheme("sbdf2") is SCHEMES["bdf2"]
    assert set(method_names(implicit=True)) == {
        n for n, s in SCHEMES.items() if isinstance(s, (ImexScheme, ExponentialScheme))}
    with pytest.raises(ValueError, match="unknown method 'rk7'; allowed: " +
                       re.escape(", ".join(method_names()))):
        get_scheme("rk7")
    with pytest.raises(ValueError, match="taken"):
        register_scheme(SCHEMES["rk4"])
    with pytest.raises(TypeError, match="ExplicitScheme, an ImexScheme, an ExponentialScheme "
                                        "or a MultistepScheme"):
        register_scheme("rk4")
    with pytest.raises(ValueError, match="two weights beta summing to 1"):
        MultistepScheme("ab-bad", 2, beta=(1.5, -0.4), title="bad", real_stability=1.0)
    with pytest.raises(ValueError, match="strictly lower-triangular"):
        ExplicitScheme("bad", 1, a=((1.0,),), b=(1.0,), c=(0.0,), title="bad",
                       real_stability=2.0)
    with pytest.raises(ValueError, match="lower-case"):
        register_scheme(ExplicitScheme("RK1", 1, a=((),), b=(1.0,), c=(0.0,), title="x",
                                       real_stability=2.0))
    with pytest.raises(ValueError, match="steps 1"):
        ImexScheme("bdf3", 3, theta=1.0, steps=3, title="bad")
    gs = MODELS["gray-scott"]
    with pytest.raises(ValueError, match=re.escape(", ".join(method_names()))):
        gs.dt_limit(Grid((8, 8)), method="rk7")


def test_a_registered_scheme_runs_in_every_model():
    """Ralston's 2nd-order method, registered from outside: a method of every model,
    stepped from its tableau, second order on ``u' = −u``."""
    ralston = ExplicitScheme("ralston", 2, a=((), (2 / 3,)), b=(0.25, 0.75), c=(0.0, 2 / 3),
                             title="Ralston", real_stability=2.0)
    register_scheme(ralston)
    try:
        model = define_model("decay", {"u": "-u"}, {})
        assert "ralston" in model.methods and "ralston" in MODELS["gray-scott"].methods
        errs = []
        for dt in (0.1, 0.05):
            st = model.stepper(Grid((4,)), dt=dt, backend="numpy", method="ralston")
            st.set_state({"u": np.ones(4)})
            st.advance(round(1.0 / dt))
            errs.append(abs(st.get_state()["u"][0, 0] - np.exp(-1.0)))
        assert np.log2(errs[0] / errs[1]) == pytest.approx(2.0, abs=0.1)
    finally:
        del SCHEMES["ralston"]
    assert "ralston" not in MODELS["gray-scott"].methods


def test_cli_help_lists_the_registry():
    run = next(a for a in build_parser()._subparsers._group_actions[0].choices.values()
               if any("--method" in o.option_strings for o in a._actions))
    (method,) = [o for o in run._actions if "--method" in o.option_strings]
    assert ", ".join(method_names()) in method.help


def test_docs_table_is_the_registry():
    """docs/equations.md §7's table of methods names exactly the registry's schemes, with
    their orders; the time-stepping paragraph of docs/models.md names each."""
    text = (ROOT / "docs" / "equations.md").read_text(encoding="utf-8")
    table = text[text.index("| method | scheme | order |"):]
    table = table[:table.index("\n\n")]
    rows = re.findall(r"^\| `([^`]+)` \|.*\| (\d)[^|]*\|$", table, flags=re.M)
    assert [name for name, _ in rows] == list(method_names())
    assert all(int(order) == SCHEMES[name].order for name, order in rows)
    readme = (ROOT / "docs" / "models.md").read_text(encoding="utf-8")
    start = readme.index("Time stepping (`options={\"method\": ...}`")
    paragraph = readme[start:readme.index("\n\n", start)]
    missing = [n for n in method_names() if f"`{n}`" not in paragraph]
    assert not missing, f"docs/models.md's time-stepping paragraph does not name {missing}"


def test_the_integrators_do_not_import_the_model_layer():
    """integrators/ is the layer below models/ (no cycle): the functional API and the
    scheme data load neither, and importing the integrators loads no module of
    rdgpu.models."""
    code = ("import sys, rdgpu.ops.api, rdgpu.ir.schemes; "
            "loaded = lambda *p: sorted(m for m in sys.modules if m.startswith(p)); "
            "print(loaded('rdgpu.integrators', 'rdgpu.models')); "
            "import rdgpu.integrators; print(loaded('rdgpu.models'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert out.stdout.split() == ["[]", "[]"]


def test_allen_cahn_methods_take_their_theta_from_the_registry():
    """Allen-Cahn's own method names (its model's ``methods``) map onto registry schemes:
    explicit diffusion is Euler's, the implicit ones the IMEX θ-schemes'."""
    from rdgpu.integrators.allen_cahn import METHODS
    from rdgpu.models import AllenCahn

    assert tuple(METHODS) == AllenCahn.methods
    assert not get_scheme(METHODS["explicit"]).implicit
    assert [get_scheme(METHODS[m]).theta for m in ("implicit", "crank-nicolson")] == [1.0, 0.5]


def test_adams_bashforth_2():
    """AB2 is one pass over x and x₋ (its first step Euler): every backend is the NumPy
    reference bit for bit; its stability limit is half of Euler's for diffusion and the
    step just past it blows up while the one just below does not; a run resumed from
    ``get_state(history=True)`` is the uninterrupted one bit for bit."""
    gs = MODELS["gray-scott"]
    grid = Grid((24, 20), dx=1.0, bc=("periodic", "neumann"))
    assert gs.dt_limit(grid, method="ab2") == pytest.approx(
        gs.dt_limit(grid, method="euler") / 2, rel=1e-9)
    rng = np.random.default_rng(0)
    start = {"u": rng.uniform(0.3, 1, grid.shape), "v": rng.uniform(0, 0.3, grid.shape)}

    def run(backend, steps, state=None, dt=0.5):
        st = gs.stepper(grid, {}, dt=dt, backend=backend, dtype="float64", method="ab2")
        st.set_state(state or start)
        st.advance(steps)
        return st

    ref = run("numpy", 30).get_state()
    for name in ("opencl", "warp"):
        got = run(backend_or_skip(name), 30).get_state()
        for s in ref:
            np.testing.assert_array_equal(got[s], ref[s])
    half = run("numpy", 12)
    resumed = run("numpy", 18, half.get_state(history=True))
    for s in ref:
        np.testing.assert_array_equal(resumed.get_state()[s], ref[s])
    heat = define_model("heat2", {"u": "laplace(u)"})
    line = Grid((32,), dx=1.0, bc="periodic")
    limit = heat.dt_limit(line, method="ab2")
    assert limit == pytest.approx(0.25, rel=1e-9)  # 1/(D·4/h²)
    noise = np.random.default_rng(1).uniform(-1, 1, line.shape)
    for dt, grows in ((0.99 * limit, False), (1.05 * limit, True)):
        st = heat.stepper(line, dt=dt, backend="numpy", method="ab2", check_stability=False)
        st.set_state({"u": noise})
        st.advance(400)
        assert (np.abs(st.get_state()["u"]).max() > 10) == grows
