"""A peer agrees (issue 4 §6): seed 001's Gray-Scott problem solved by py-pde and by rdgpu.

Both codes run the same discrete problem -- a periodic Cartesian grid, the 5-point
Laplacian, forward (explicit) Euler with a fixed time step -- so they must give the same
field to round-off, not merely the same pattern.  What makes py-pde run that problem:

* ``pde.CartesianGrid(..., periodic=True)`` and py-pde's finite-difference ``laplace``,
  whose 2-D stencil is the 5-point one while the option
  ``operators.cartesian.laplacian_2d_corner_weight`` is 0 (its default; 1/2 or 1/3 give
  9-point stencils) and ``use_spectral`` is off (its default).  The test sets the corner
  weight to 0 where the option exists and checks py-pde's operator against
  ``rdgpu.laplacian`` on a random field.
* the Euler solver with ``adaptive=False`` and a fixed ``dt`` (py-pde already turns
  adaptivity off when ``dt`` is given; the test says so and checks from ``ret_info`` that
  the run took exactly ``t_range/dt`` steps of that ``dt``, not adapted).  py-pde 0.59
  names it ``"euler"``; the older ``"explicit"`` (``ExplicitSolver(scheme="euler")``) is
  deprecated there and used only where ``"euler"`` is not registered.
* py-pde's ``"numpy"`` backend: the stepping loop runs in Python, the right-hand side is
  still numba-compiled (the ``laplace`` operator and the lambdified expressions).  With
  the ``"numba"`` backend the whole stepper is compiled too, which doubles the
  compilation time for no gain on a 400-step run.  numba's ``fastmath`` (py-pde's
  default) may reorder the arithmetic: agreement is to round-off, not bitwise.

Grid axes: py-pde's data ``[i, j]`` has ``i`` along its first axis, mapped to rdgpu's rows
(``y``); the cells are anisotropic (``dx ≠ dy``), so a transposed mapping would fail.

Cost: py-pde's first ``solve`` spends ~18 s (2-core CPU, py-pde 0.59, numba 0.68) compiling
with numba (not cached across processes); it runs once per module and every rdgpu backend
is compared with that one result; the rest of the file takes ~3 s.  Measured agreement
after 400 steps (v has moved by 0.42 from its start): max |Δ| = 7.8e-16 on the numpy, Warp
and OpenCL backends (float64); the test asks for 1e-10.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip

pde = pytest.importorskip("pde")

import rdgpu  # noqa: E402
from rdgpu.domains.grid import Grid  # noqa: E402
from rdgpu.models import MODELS  # noqa: E402
from rdgpu.simulation import initial_state  # noqa: E402

# seed 001's parameters and initial condition (u = 0.5 everywhere, v = 0.25 in a central
# square, noise 0.05) on a smaller, non-square grid of anisotropic cells
PARAMS = {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.060}
NY, NX = 40, 48
DY, DX = 1.0, 1.25
DT = 1.0  # the forward-Euler limit 1/(2 Du (1/dx² + 1/dy²)) is 1.9
STEPS = 400
INIT = {"kind": "square", "values": {"u": 0.5, "v": 0.0}, "inside": {"u": 0.5, "v": 0.25},
        "size": 0.2, "noise": 0.05}
CORNER = "operators.cartesian.laplacian_2d_corner_weight"


def _five_point() -> None:
    try:
        pde.config[CORNER] = 0.0
    except (KeyError, AttributeError):  # pragma: no cover - older py-pde: 5-point only
        pass


@pytest.fixture(scope="module")
def peer_grid():
    _five_point()
    # py-pde axis 0 <-> rdgpu rows (y), axis 1 <-> columns (x)
    grid = pde.CartesianGrid([[0.0, NY * DY], [0.0, NX * DX]], [NY, NX], periodic=True)
    np.testing.assert_allclose(grid.discretization, [DY, DX])
    return grid


def _solver_kwargs() -> dict:
    registered = getattr(pde.solvers, "registered_solvers", dict)()
    if "euler" in registered:
        return {"solver": "euler", "adaptive": False}
    return {"solver": "explicit", "scheme": "euler", "adaptive": False}  # pragma: no cover


@pytest.fixture(scope="module")
def peer_run(peer_grid):
    """(initial fields, py-pde's u and v after STEPS steps)."""
    ours = Grid((NY, NX), dx=DX, dy=DY, bc="periodic")
    start = initial_state(INIT, ours, ("u", "v"), seed=1, dtype=np.float64)
    p = PARAMS
    eq = pde.PDE(
        {"u": f"{p['Du']} * laplace(u) - u * v**2 + {p['F']} * (1 - u)",
         "v": f"{p['Dv']} * laplace(v) + u * v**2 - ({p['F']} + {p['k']}) * v"},
        bc="periodic",
    )
    state = pde.FieldCollection([pde.ScalarField(peer_grid, start["u"], label="u"),
                                 pde.ScalarField(peer_grid, start["v"], label="v")])
    final, info = eq.solve(state, t_range=STEPS * DT, dt=DT, tracker=None, ret_info=True,
                           backend="numpy", **_solver_kwargs())
    solver = info["solver"]
    assert solver["steps"] == STEPS and solver["dt"] == DT
    assert not solver.get("dt_adaptive", False)
    return start, {"u": np.array(final[0].data), "v": np.array(final[1].data)}


def test_pypde_laplace_is_the_5_point_stencil(peer_grid):
    a = np.random.default_rng(0).standard_normal((NY, NX))
    theirs = pde.ScalarField(peer_grid, a).laplace("periodic").data
    mine = rdgpu.laplacian(a, dx=DX, dy=DY, bc="periodic", stencil=5, backend="numpy")
    np.testing.assert_allclose(theirs, mine, rtol=0, atol=1e-12)


@pytest.mark.parametrize("backend_name", ["numpy", "warp", "opencl"])
def test_gray_scott_agrees_with_pypde(peer_run, backend_name):
    start, theirs = peer_run
    be = backend_or_skip(backend_name)
    grid = Grid((NY, NX), dx=DX, dy=DY, bc="periodic")
    st = MODELS["gray-scott"].stepper(grid, PARAMS, dt=DT, backend=be, dtype=np.float64)
    st.set_state(start)
    st.advance(STEPS)
    ours = st.get_state()
    # the pattern has grown well past the initial square: not a trivial comparison
    assert np.abs(theirs["v"] - start["v"]).max() > 0.1
    assert np.abs(ours["v"] - start["v"]).max() > 0.1
    for s in ("u", "v"):
        np.testing.assert_allclose(ours[s], theirs[s], rtol=0, atol=1e-10)
