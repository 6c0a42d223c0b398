"""The implicit methods' choice of diffusion solver, ``solver=``: through
``Model.stepper``, ``Simulation(options=)`` and ``rdgpu run --solver``; bad values refused
before any work."""

from __future__ import annotations

import numpy as np
import pytest

from rdgpu.cli import main
from rdgpu.domains.grid import Grid
from rdgpu.models import MODELS
from rdgpu.simulation import Simulation

BR = MODELS["brusselator"]


def _solvers(stepper) -> set[str]:
    return {s.solver for each in stepper._solvers.values() for s in each}


@pytest.mark.parametrize("solver", ["auto", "transform", "sor"])
def test_stepper_takes_the_solver(solver):
    st = BR.stepper(Grid((12, 10), bc="periodic"), dt=0.05, backend="numpy", method="imex",
                    solver=solver)
    assert _solvers(st) == {"sor" if solver == "sor" else "transform"}


def test_both_solvers_agree_to_the_tolerance():
    grid = Grid((16, 12), bc="neumann")
    out = {}
    for solver in ("transform", "sor"):
        st = BR.stepper(grid, dt=0.05, backend="numpy", method="imex", dtype=np.float64,
                        solver=solver, tol=1e-10)
        rng = np.random.default_rng(3)
        st.set_state({s: 1.0 + 0.1 * rng.standard_normal((16, 12)) for s in st.species})
        st.advance(5)
        out[solver] = st.get_state()
    for s in out["sor"]:
        np.testing.assert_allclose(out["transform"][s], out["sor"][s], rtol=0, atol=1e-7)


def test_bad_solver_refused():
    with pytest.raises(ValueError, match="solver must be one of"):
        BR.stepper(Grid((8, 8)), dt=0.05, backend="numpy", method="imex", solver="lu")


def test_simulation_option():
    sim = Simulation("brusselator", {"grid": (12, 12), "bc": "periodic"},
                     dt=0.05, backend="numpy", options={"method": "imex", "solver": "sor"})
    assert _solvers(sim.stepper) == {"sor"}


def test_cli_solver(tmp_path, capsys):
    code = main(["run", "brusselator", "--method", "imex", "--dt", "0.05", "--size", "16",
                 "--steps", "4", "--solver", "sor", "--backend", "numpy", "--quiet",
                 "--data", str(tmp_path / "b.npz")])
    assert code == 0
    capsys.readouterr()
    assert main(["run", "brusselator", "--solver", "lu"]) == 2
    assert "--solver: invalid choice: 'lu'" in capsys.readouterr().err
