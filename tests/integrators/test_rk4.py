"""Classic RK4 in the model layer (``method="rk4"``), added as one tableau in
:mod:`rdgpu.ir.schemes`: its measured order is 4 on problems with exact solutions, every
backend runs it, and ``rdgpu run --method rk4`` works."""

from __future__ import annotations

import numpy as np
import pytest

import rdgpu
from rdgpu.cli.app import main
from rdgpu.domains.grid import Grid
from rdgpu.io.output import load_npz
from rdgpu.models import MODELS, define_model

HEAT = define_model("heat", {"u": "D*laplace(u)"}, {"D": 1.0})


def _order(errors: list[float], ratio: float = 2.0) -> float:
    """The least-squares slope of log(error) against log(dt) over dt, dt/2, dt/4."""
    dts = ratio ** -np.arange(len(errors))
    return float(np.polyfit(np.log(dts), np.log(errors), 1)[0])


def _run(model, domain, u0, dt, t_end, method="rk4", backend="numpy"):
    st = model.stepper(domain, dt=dt, backend=backend, method=method)
    st.set_state({"u": u0})
    st.advance(round(t_end / dt))
    return st.get_state()["u"].reshape(u0.shape)


def test_rk4_order_on_a_fourier_mode():
    """``u_t = Δu`` on a periodic grid from one Fourier mode: the semi-discrete solution is
    ``e^{−λt} u0`` with λ the mode's eigenvalue of ``−Δ_h``; float64 errors at dt, dt/2,
    dt/4 fall as dt⁴."""
    n, dx, t_end = 16, 0.5, 0.4
    grid = Grid((n,), dx=dx, bc="periodic")
    x = np.arange(n) * dx
    u0 = np.sin(2 * np.pi * x / (n * dx))
    lam = (2 - 2 * np.cos(2 * np.pi / n)) / dx**2
    exact = np.exp(-lam * t_end) * u0
    errors = [np.max(np.abs(_run(HEAT, grid, u0, dt, t_end) - exact))
              for dt in (0.1, 0.05, 0.025)]
    assert _order(errors) == pytest.approx(4.0, abs=0.1)
    # the explicit stability limit is Euler's (RK4's region contains Euler's disk)
    assert HEAT.dt_limit(grid, method="rk4") == HEAT.dt_limit(grid, method="euler")


def test_rk4_order_with_time_in_the_equation():
    """``u_t = cos(t) u``, ``u(0) = 1``: ``u = e^{sin t}``; the stage times ``t + c_i h``
    matter (wrong nodes would give order 1)."""
    model = define_model("clock", {"u": "cos(t)*u"}, {})
    grid = Grid((4,))
    errors = [abs(_run(model, grid, np.ones(4), dt, 2.0)[0] - np.exp(np.sin(2.0)))
              for dt in (0.2, 0.1, 0.05)]
    assert _order(errors) == pytest.approx(4.0, abs=0.1)


@pytest.mark.slow  # compiles six programs per backend (~10 s with warm caches)
def test_rk4_on_every_backend_and_with_bounds_and_bilaplacian():
    """Warp and OpenCL compile the rate and the stage sums (bit for bit the NumPy
    reference without functions); a bilaplacian's pre-pass and a bound are applied to
    every stage value."""
    model = define_model("sh", {"u": "-0.1*laplace(laplace(u)) - 0.5*laplace(u) - u*u*u"},
                         {}, bounds={"u": (-0.5, None)})
    grid = Grid((6, 8), dx=1.0, bc="periodic")
    u0 = np.random.default_rng(0).uniform(-1, 1, grid.shape)
    ref = _run(model, grid, u0, 0.05, 0.5)
    assert ref.min() >= -0.5
    for info in rdgpu.available_backends():
        name = info.name
        if info.available and name != "numpy":
            np.testing.assert_array_equal(_run(model, grid, u0, 0.05, 0.5, backend=name),
                                          ref, err_msg=name)


def test_cli_runs_rk4(tmp_path, capsys):
    out = tmp_path / "run.npz"
    code = main(["run", "gray-scott", "--method", "rk4", "--size", "16x16", "--steps", "4",
                 "--backend", "numpy", "--data", str(out)])
    assert code in (0, None)
    result = load_npz(out)
    assert result.step == 4
    assert "rk4" in MODELS["gray-scott"].methods
