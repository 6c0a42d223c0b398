"""The presets reproduce the seed papers' patterns, each measured by a test.

test_presets: The presets reproduce the seed papers' patterns (issue 4 §5), each checked by a test.

Every pattern is *measured*: ``rdgpu.analysis.classify_pattern`` over the connected
regions of the two phases (field and threshold from the preset's ``classify``), or
``rdgpu.analysis.spiral_tips`` for the Barkley spirals.  Where a preset is too large for
CI (a 2-core CPU, no GPU) the test scales the grid down, keeping ``dx``, ``dt`` and the
parameters, and runs fewer steps; each such reduction below says what was checked: the
full-size presets (OpenCL, float32, all their steps) gave the same classes, and the
scaled runs give their class from the step count used here on for the whole of a longer
run, on several seeds.

Then every preset runs five steps from the command line on every backend.

Measured here, and documented in the tests: the modified Allen-Cahn field on the sphere
(ε = 0.15 mean edge, 3000 steps of ε²/2) decays to a constant from |b| ≈ 0.30 (seed 0:
between 0.2875 and 0.306; seeds 0-2: always from 0.32), as seed 000 reports ("about 0.3"),
well below 2/(3√3) ≈ 0.385, past which u³ − u + b has a single real root; its energy rises
by at most 9.9e-9 J(0) in one step (J(0) = |Γ|/(4ε²), the energy of u ≡ 0), a splitting
error that falls by 14× when dt is halved.

test_new_presets: The seeds' remaining models as presets, each pattern measured.

* complex Ginzburg-Landau (seed 004 §4, Fig. 12): the phase defects of ``u + iv``
  (:func:`rdgpu.analysis.phase_defects`, checked first on synthetic vortex fields);
* Swift-Hohenberg (seed 004 §5): stripes and hexagons at the wavenumber ``k_c = 1``, run
  implicitly (IMEX) far beyond the explicit step limit;
* Meinhardt's five-chemical stripes (seed 003 eq. 2.16, Figs. 2.5-2.6);
* Turing's 1-D model on a ring of 60 cells (seed 003 eq. 2.14, Fig. 2.3): its peaks;
* Gray-Scott with ``F(x)`` and ``k(y)`` given as expressions (seed 004 Fig. 7): the pattern
  differs across the domain;
* Gray-Scott on a 3-D grid: connected components of the two phases.

Where a preset is too large for a 2-core CI machine the test runs it on a smaller grid of
the same spacing, step and parameters (each place says so, with what was measured at full
size).  Every preset also runs from the command line in tests/models/test_presets.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import backend_or_skip

from rdgpu.analysis import (
    classify_pattern,
    dispersion,
    grid_wavenumber,
    phase_components,
    phase_defects,
    spiral_tips,
)
from rdgpu.cli.app import main as cli_main
from rdgpu.core.errors import StabilityError
from rdgpu.domains.grid import Grid
from rdgpu.io.output import load_npz
from rdgpu.ir import equations as eq
from rdgpu.models import MODELS, PRESETS, AllenCahn
from rdgpu.simulation import Simulation, initial_state

BACKENDS = ["numpy", "warp", "opencl"]


# ---------------------------------------------------------------------------- helpers
def _simulate(name, backend, *, size=None, init=None, steps=None, dtype="float32",
              params=None, seed=None, dt=None):
    """Run preset ``name`` (on a ``size``² grid of the same dx if given) and return
    ``(simulation, result)``."""
    p = PRESETS[name]
    domain = None
    if size is not None:
        domain = {**p.domain, "grid": (size, size)}
    sim = Simulation.from_preset(p, backend=backend_or_skip(backend), domain=domain,
                                 init=init, dtype=dtype, params=params, seed=seed, dt=dt)
    res = sim.run(p.steps if steps is None else steps, snapshot_every=0, progress=False)
    assert res.diverged is None and res.step == (p.steps if steps is None else steps)
    return sim, res


def _classify(name, sim, res) -> str:
    c = PRESETS[name].classify
    return classify_pattern(res.fields[c["field"]], sim.domain, threshold=c["threshold"])


def _field(name, res) -> np.ndarray:
    return np.asarray(res.fields[PRESETS[name].classify["field"]], dtype=np.float64)


def _tiles_with_both_phases(f: np.ndarray, threshold=None, tiles: int = 4) -> float:
    """Fraction of the ``tiles × tiles`` blocks of a grid field that hold both phases: 1
    when the pattern has filled the domain (not just grown around the initial square)."""
    if threshold is None:
        threshold = 0.5 * (f.min() + f.max())
    ny, nx = f.shape
    hi = (f > threshold)[: ny - ny % tiles, : nx - nx % tiles]
    share = hi.reshape(tiles, ny // tiles, tiles, nx // tiles).mean(axis=(1, 3))
    return float(((share > 0) & (share < 1)).mean())


# ------------------------------------------------------------------- seed 001: Gray-Scott
# Seed 001's 300² grid scaled to 128² (dt = dx = 1, the same initial square of a tenth of
# the side).  At 300² (30 000 / 20 000 steps) the presets give stripes / spots; at 128²
# the class is the same from step 1000 (stripes) / 3000 (spots) through 20 000, seeds 0-3.
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ["gs-seed001-stripes", "gs-seed001-spots"])
def test_seed001_gray_scott(name, backend):
    sim, res = _simulate(name, backend, size=128, steps=10_000)
    assert _classify(name, sim, res) == PRESETS[name].expect
    v = _field(name, res)
    assert _tiles_with_both_phases(v) == 1.0  # the pattern fills the grid
    if name.endswith("spots"):  # a lattice of many spots (~85 at 128², ~470 at 300²)
        assert len(phase_components(v, sim.domain, None)["low"]) >= 40


# Issue 23: the differential flow (upwind advect of v) lines the labyrinth up across the
# flow.  Orientation: the power of v's spectrum weighted by |k_x|/|k| (|k_y|/|k| for a flow
# along y): 2/π ≈ 0.64 for an isotropic pattern, 1 for stripes across x.  Measured at 128²,
# 12 000 steps: 0.70 without flow, 0.98 with it.
def _across(v: np.ndarray, axis: int) -> float:
    n_y, n_x = v.shape
    power = np.abs(np.fft.fft2(v - v.mean())) ** 2
    k = [np.fft.fftfreq(n_y)[:, None], np.fft.fftfreq(n_x)[None, :]]
    norm = np.hypot(*k)
    norm[0, 0] = 1.0
    return float((power * np.abs(k[axis]) / norm).sum() / power.sum())


@pytest.mark.parametrize("backend", ["opencl", "warp"])
def test_the_differential_flow_lines_the_labyrinth_up_across_it(backend):
    name = "gs-differential-flow"
    found = {}
    for flow in ({"Vx": 0.04}, {"Vx": 0.0}, {"Vx": 0.0, "Vy": -0.04}):
        sim, res = _simulate(name, backend, size=128, steps=12_000, params=flow)
        assert _classify(name, sim, res) == "stripes"
        v = res.fields["v"]
        found[tuple(flow.values())] = (_across(v, 1), _across(v, 0))
    assert found[(0.04,)][0] > 0.9  # wave vectors along the flow: stripes across it
    assert found[(0.0, -0.04)][1] > 0.9  # the same for a flow down y
    assert found[(0.0,)][0] < 0.8 and found[(0.0,)][1] < 0.8  # no flow: no direction


# Pearson 1993: his 256² grid of dx = 2.5/256 scaled to 128² of the same dx, with his
# 20 × 20-cell initial square (size 20/128).  Full size (60 000 steps) gives the classes of
# the presets; at 128² the class holds from 3000 (delta, theta, lambda) or 6000 (kappa)
# steps through 30 000, seeds 0 and 1.
PEARSON = {"delta": 10_000, "theta": 10_000, "kappa": 10_000, "lambda": 10_000}


@pytest.mark.parametrize("letter", sorted(PEARSON))
def test_pearson_classes(letter):
    name = f"gs-pearson-{letter}"
    init = {**PRESETS[name].init, "size": 20 / 128}
    sim, res = _simulate(name, "opencl", size=128, init=init, steps=PEARSON[letter])
    assert _classify(name, sim, res) == PRESETS[name].expect
    assert _tiles_with_both_phases(_field(name, res)) == 1.0


# ----------------------------------------------------------- seed 000: Allen-Cahn, sphere
def _phases(sim, res):
    """Number of components of each phase (u < 0, u > 0), and the share of each phase
    held by its largest component."""
    comps = phase_components(res.fields["u"], sim.domain, 0.0)
    lo, hi = comps["low"], comps["high"]
    return len(lo), len(hi), lo[0] / lo.sum(), hi[0] / hi.sum()


@pytest.mark.parametrize("backend", ["warp", "opencl"])
@pytest.mark.parametrize("name", ["ac-sphere-spots", "ac-sphere-stripes",
                                  "ac-sphere-inverted-spots"])
def test_allen_cahn_sphere_classes(name, backend):
    """b = -0.25 spots (islands of u < 0 in a sea of u > 0), b = 0 stripes, b = +0.25
    inverted spots, from random data on the unit sphere (the presets as they are; the
    NumPy backend runs them in the energy test below, and test_models checks that every
    backend's stepper equals it to round-off)."""
    sim, res = _simulate(name, backend)
    assert _classify(name, sim, res) == PRESETS[name].expect
    low, high, sea_low, sea_high = _phases(sim, res)
    b = sim.params["b"]
    if b < 0:  # measured: ~294 islands of u < 0; u > 0 one sea (and a few specks)
        assert low > 100 and sea_high > 0.99
    elif b > 0:
        assert high > 100 and sea_low > 0.99
    else:  # a labyrinth frozen on the mesh: both phases in ~170 pieces, each phase's
        # largest holding 50-75 % of it, half the sphere each
        assert low > 10 and high > 10 and sea_low > 0.3 and sea_high > 0.3
        assert 0.4 < np.mean(res.fields["u"] > 0) < 0.6


def _distance_to_patch(sim) -> np.ndarray:
    """Euclidean distance of every vertex to the initial patch (where u(0) ≠ 0)."""
    from scipy.spatial import cKDTree

    u0 = initial_state(sim.init, sim.domain, ("u",), sim.seed)["u"]
    V = np.asarray(sim.domain.vertices)
    return cKDTree(V[u0 != 0]).query(V)[0]


@pytest.mark.parametrize("name", ["ac-sphere-local-spots", "ac-sphere-local-inverted-spots",
                                  "ac-sphere-local-spreads"])
def test_allen_cahn_localized_patterns(name):
    """Random data in a patch (9 % of the sphere), u = 0 elsewhere: for b = ∓0.08 the
    minority phase stays inside the patch (measured: within one edge, 0.039, of it) and
    the favoured one takes the rest; for b = 0 both phases appear everywhere (measured:
    29-72 % of the vertices farther than 0.2 from the patch end with u < 0, seeds 0-2)."""
    sim, res = _simulate(name, "opencl")
    u = np.asarray(res.fields["u"], dtype=np.float64)
    assert _classify(name, sim, res) == PRESETS[name].expect
    dist = _distance_to_patch(sim)
    h = sim.domain.mean_edge_length
    far = dist > 0.2
    assert 0.05 < np.mean(dist == 0) < 0.15 and far.mean() > 0.8
    b = sim.params["b"]
    if b != 0:
        minority = u < 0 if b < 0 else u > 0
        assert minority.sum() > 20  # the pattern survives in the patch ...
        assert dist[minority].max() <= 2 * h  # ... and stays there
        assert np.all(np.sign(u[far]) == -np.sign(b))
    else:
        neg = np.mean(u[far] < 0)
        assert 0.1 < neg < 0.9, neg  # it spread: both phases far from the patch
        assert np.mean(np.abs(u[far]) > 0.5) > 0.9  # and u left 0 there


def _decays(b: float) -> tuple[bool, np.ndarray]:
    sim, res = _simulate("ac-sphere-uniform", "opencl", params={"b": b}, dtype="float64")
    u = np.asarray(res.fields["u"])
    return bool(np.ptp(u) < 1e-6), u


def _stable_root(b: float) -> float:
    """The root of u³ − u + b of the favoured phase (sign opposite to b)."""
    roots = np.roots([1.0, 0.0, -1.0, b])
    real = roots[np.abs(roots.imag) < 1e-12].real
    return float(real.max() if b < 0 else real.min())


def _split_fixed_point(b: float, eps: float, dt: float) -> float:
    """The constant that one Strang step (Bernoulli dt/2, u − dt b/ε², Bernoulli dt/2)
    maps to itself near the root: what a uniform field converges to.  At dt = ε²/2 it
    differs from the root by ~1 % (the splitting error of a step of half the reaction
    time)."""
    decay = math.exp(-dt / eps**2)

    def bern(u):
        return u / math.sqrt(decay + u * u * (1.0 - decay))

    u = _stable_root(b)
    for _ in range(500):
        u = bern(bern(u) - dt * b / eps**2)
    return u


def test_allen_cahn_decays_to_a_constant_past_a_threshold():
    """The preset 'ac-sphere-uniform' (b = -0.35) decays to the constant root of
    u³ − u + b; bisection on |b| (3000 steps, seed 0) puts the onset of decay in
    (0.2875, 0.306] -- measured ~0.30, as seed 000 reports, well below 2/(3√3) ≈ 0.385
    where the second stable root disappears.  (Seeds 1-2: spots survive at 0.30, a single
    island at 0.31, uniform from 0.32.)  The same for b > 0 by symmetry."""
    sim, res = _simulate("ac-sphere-uniform", "opencl", dtype="float64")
    b0, eps = sim.params["b"], sim.params["eps"]
    assert _classify("ac-sphere-uniform", sim, res) == "uniform"
    constant = _split_fixed_point(b0, eps, sim.dt)
    np.testing.assert_allclose(res.fields["u"], constant, rtol=0, atol=1e-10)
    assert constant == pytest.approx(_stable_root(b0), rel=0.02)  # 1.1303 vs 1.1429

    lo, hi = 0.25, 0.40
    assert not _decays(-lo)[0]
    assert _decays(-hi)[0]
    for _ in range(3):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if _decays(-mid)[0] else (mid, hi)
    assert 0.25 < lo < hi <= 0.31  # measured: (0.2875, 0.30625]
    assert hi < 2 / (3 * math.sqrt(3))
    decayed, u = _decays(+0.32)
    assert decayed and np.allclose(u, _split_fixed_point(0.32, eps, sim.dt), atol=1e-10)
    assert not _decays(+0.28)[0]


def _energy_increases(name, *, dt_factor=1.0, steps=None):
    """Per-step energy changes ``J_{n+1} - J_n`` over a run of the preset (float64,
    NumPy backend), the energies, ``J(0) = |Γ|/(4ε²)`` and the simulation.

    J is evaluated for batches of states at once (the cotangent form
    ``½ uᵀ(−W)u + Σ A_i ((u_i² − 1)²/4 + b u_i)/ε²``), checked against
    ``AllenCahn.energy`` at the first and the last step: one call per step costs
    milliseconds where OpenBLAS threads compete for a loaded 2-core machine."""
    p = PRESETS[name]
    sim = Simulation.from_preset(p, backend="numpy", dtype="float64", dt=p.dt * dt_factor)
    st, mesh = sim.stepper, sim.domain
    b, eps = sim.params["b"], sim.params["eps"]
    W, A = mesh.weights, np.asarray(mesh.areas)

    def energies(U):  # one state per row
        grad = 0.5 * np.einsum("ij,ij->i", U, -(W @ U.T).T)
        return grad + (((U * U - 1.0) ** 2 / 4.0 + b * U) * A).sum(axis=1) / eps**2

    n = int((p.steps if steps is None else steps) / dt_factor)
    J, batch = [], [st.get_state()["u"]]
    for k in range(1, n + 1):
        st.advance(1)
        batch.append(st.get_state()["u"])
        if len(batch) == 250 or k == n:
            J.extend(energies(np.array(batch)))
            batch = []
    J = np.asarray(J)
    assert J.size == n + 1
    first = initial_state(sim.init, mesh, ("u",), sim.seed)["u"]
    assert J[0] == pytest.approx(AllenCahn.energy(mesh, first, sim.params), rel=1e-12)
    assert J[-1] == pytest.approx(AllenCahn.energy(mesh, st.get_state()["u"], sim.params),
                                  rel=1e-12, abs=1e-9 * abs(J[0]))
    return np.diff(J), J, mesh.total_area / (4 * eps**2), sim


# docs/equations.md §2 documents a splitting error of ~1e-8 relative in this regime (ε = 0.15
# mean edge, dt = ε²/2); measured per-step rises, in units of J(0): spots 9.9e-9, inverted
# spots 8.5e-9, stripes 6.8e-11.  The bound below is the documented ~1e-8 with a factor 2.
SPLITTING_TOL = 2e-8


@pytest.mark.parametrize("name", ["ac-sphere-spots", "ac-sphere-stripes",
                                  "ac-sphere-inverted-spots"])
def test_allen_cahn_energy_never_increases(name):
    dJ, J, scale, sim = _energy_increases(name)
    assert J[-1] < 0.5 * J[0]  # the energy falls by a lot ...
    assert dJ.max() <= SPLITTING_TOL * scale, dJ.max() / scale  # ... and never rises
    u = sim.stepper.get_state()["u"]  # (and the NumPy backend gives the preset's pattern)
    assert classify_pattern(u, sim.domain, 0.0) == PRESETS[name].expect


def test_allen_cahn_energy_rise_is_a_splitting_error():
    """The tiny rises fall with dt at least like dt² (measured over the first 1000 steps,
    which hold the largest rise: 9.9e-9 → 7.1e-10 J(0), 14×, for dt/2)."""
    coarse = _energy_increases("ac-sphere-spots", steps=1000)[0].max()
    fine = _energy_increases("ac-sphere-spots", dt_factor=0.5, steps=1000)[0].max()
    assert coarse > 0 and fine <= coarse / 4


# ------------------------------------------ seed 004: Brusselator, FitzHugh-Nagumo, Barkley
# size, steps: the presets' 200² (400² for fig1) grids scaled down; full size gives the
# same classes; at these sizes the class holds from 6000 (brusselator-spots, fig1,
# fitzhugh-nagumo-spots) or 4000 (fitzhugh-nagumo-stripes at 100²) steps through 20 000,
# seeds 0 and 1 (0-2 for the stripes).
SEED004 = {
    "brusselator-spots": (64, 10_000),
    "brusselator-stripes": (64, 10_000),
    "brusselator-seed004-fig1": (128, 10_000),
    "fitzhugh-nagumo-stripes": (100, 8_000),
    "fitzhugh-nagumo-spots": (64, 10_000),
}


@pytest.mark.parametrize("name", sorted(SEED004))
def test_seed004_spots_and_stripes(name):
    size, steps = SEED004[name]
    sim, res = _simulate(name, "opencl", size=size, steps=steps)
    assert _classify(name, sim, res) == PRESETS[name].expect
    assert _tiles_with_both_phases(_field(name, res)) == 1.0


@pytest.mark.parametrize("backend", ["warp", "opencl"])
def test_the_masked_disc_grows_its_labyrinth_inside_only(backend):
    """gs-masked-disc on 96² (stripes from 6000 steps, seeds 0-1): the labyrinth inside the
    disc, the cells outside exactly as they started."""
    sim, res = _simulate("gs-masked-disc", backend, size=96, steps=6000)
    assert _classify("gs-masked-disc", sim, res) == "stripes"
    start = initial_state(sim.init, sim.domain, sim.species, sim.seed, sim.dtype)
    outside = ~res.mask
    assert 0.3 < outside.mean() < 0.4
    for s in sim.species:
        np.testing.assert_array_equal(res.fields[s][outside],
                                      start[s].reshape(res.mask.shape)[outside])


@pytest.mark.parametrize("backend", ["warp", "opencl"])
def test_noise_alone_starts_the_brusselators_turing_pattern(backend):
    """brusselator-noise on 64² (stripes from 4000 steps, seeds 0-2): from the exact
    homogeneous steady state, noise grows the Turing labyrinth over the whole grid; the
    same run without the preset's noise stays uniform."""
    sim, res = _simulate("brusselator-noise", backend, size=64)
    assert _classify("brusselator-noise", sim, res) == "stripes"
    assert _tiles_with_both_phases(_field("brusselator-noise", res)) == 1.0
    p = PRESETS["brusselator-noise"]
    quiet = Simulation(p.model, {**p.domain, "grid": (64, 64)}, p.params, dt=p.dt,
                       init=p.init, backend=backend_or_skip(backend))
    u = quiet.run(2000, progress=False).fields["u"]
    assert np.ptp(u) == 0.0


@pytest.mark.parametrize("backend", ["warp", "opencl"])
def test_barkley_spirals(backend):
    """The preset's 200² grid; the tips form by step 1000 (measured: 6 for seed 0; 2-6 for
    seeds 0-3) and persist while the spirals rotate.  On a torus the tips come in pairs of
    opposite winding, so there are at least two."""
    name = "barkley-spirals"
    center = PRESETS[name].classify["center"]
    sim, res = _simulate(name, backend, steps=2000)
    tips = spiral_tips(res.fields["u"], res.fields["v"], sim.domain, center=center)
    before = res.fields["u"].copy()
    res = sim.run(1000, snapshot_every=0, progress=False)
    after = spiral_tips(res.fields["u"], res.fields["v"], sim.domain, center=center)
    assert tips >= 2 and tips % 2 == 0 and after == tips
    assert np.mean(np.abs(res.fields["u"] - before) > 0.5) > 0.05  # the waves move


# --------------------------------------------------------------- seed 003: Turing's spots
@pytest.mark.parametrize("backend", BACKENDS)
def test_turing_seed003_spots(backend):
    """The preset as it is: 64², D_a = 0.25, dt = 0.5, 8000 steps; ~77 spots."""
    name = "turing-seed003-spots"
    sim, res = _simulate(name, backend)
    assert _classify(name, sim, res) == "spots"
    assert len(phase_components(_field(name, res), sim.domain, None)["low"]) >= 40


# ----------------------------------------------------------- every preset, every backend
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", sorted(PRESETS))
def test_every_preset_runs_from_the_cli(name, backend, tmp_path, capsys):
    backend_or_skip(backend)
    p = PRESETS[name]
    data = tmp_path / "run.npz"
    argv = ["run", p.model, "--preset", name, "--steps", "5", "--backend", backend,
            "--data", str(data), "--quiet"]
    if "grid" in p.domain:  # (a mesh would be rendered by pyvista: tested elsewhere)
        argv += ["--out", str(tmp_path / "run.png")]
    code = cli_main(argv)
    assert code == 0, capsys.readouterr().err
    res = load_npz(data)
    assert res.step == 5 and res.model == p.model and res.backend == backend
    for s, f in res.fields.items():
        assert np.isfinite(f).all(), s
    if "grid" in p.domain:
        assert res.fields[p.classify.get("field", "u")].shape == tuple(p.domain["grid"])
        assert (tmp_path / "run.png").stat().st_size > 0


# ----------------------------------------------------------- issue 11: disc, rough sphere
@pytest.mark.parametrize("name", ["swift-hohenberg-disc", "gray-scott-rough-sphere"])
def test_disc_and_rough_sphere_presets(name):
    """Seed 004 Fig. 13's stripes on a disc, and spots on a heat-filtered rough sphere
    (seed 002 §5): the presets reach their classes (opencl: 8 s and 1 s here)."""
    sim, res = _simulate(name, "opencl")
    assert _classify(name, sim, res) == PRESETS[name].expect
    if name == "gray-scott-rough-sphere":
        radii = np.linalg.norm(sim.domain.vertices, axis=1)
        assert 0.5 < np.ptp(radii) <= 3.0 + 1e-9  # rough: bumps of up to ±1.5
        assert len(phase_components(_field(name, res), sim.domain, None)["high"]) >= 20


# ------------------------------------------------------------ formerly test_new_presets.py
def _sim(name, *, grid=None, backend="opencl", dtype="float32", **kw):
    """A simulation of preset ``name``, on ``grid`` (a shape, same spacing and sides) if
    given."""
    p = PRESETS[name]
    domain = None if grid is None else {**p.domain, "grid": tuple(grid)}
    return Simulation.from_preset(p, backend=backend_or_skip(backend), domain=domain,
                                  dtype=dtype, **kw)


def _advance(sim, steps):
    res = sim.run(steps, snapshot_every=0, progress=False)
    assert res.diverged is None
    return {s: np.asarray(f, dtype=np.float64) for s, f in res.fields.items()}


def _matched(a: np.ndarray, b: np.ndarray, shape, tol: float = 1.5) -> float:
    """Fraction of the points ``a`` (rows of (row, col)) with a point of ``b`` within
    ``tol`` cells (distances wrapped on the periodic ``shape``)."""
    if len(a) == 0:
        return 1.0
    if len(b) == 0:
        return 0.0
    d = np.abs(a[:, None, :] - b[None, :, :])
    n = np.asarray(shape, dtype=np.float64)
    d = np.minimum(d, n - d)
    return float(np.mean(np.hypot(d[..., 0], d[..., 1]).min(axis=1) <= tol))


# ---------------------------------------------------------------- phase defects (synthetic)
def _vortex(shape, centre, charge=1):
    """``((x − x₀) + i·sign·(y − y₀))`` on cell indices (x = column, y = row)."""
    rows, cols = np.indices(shape, dtype=np.float64)
    return (cols - centre[1]) + 1j * charge * (rows - centre[0])


def test_phase_defects_of_one_vortex_and_its_mirror_image():
    shape = (24, 32)
    A = _vortex(shape, (10.3, 20.6))
    pos, q = phase_defects(A.real, A.imag)
    assert q.tolist() == [1]
    np.testing.assert_allclose(pos[0], [10.5, 20.5])  # the plaquette around (10.3, 20.6)
    pos, q = phase_defects(A.real, -A.imag)  # the complex conjugate winds the other way
    assert q.tolist() == [-1] and np.allclose(pos[0], [10.5, 20.5])
    # a phase shift, a positive amplitude and a shifted centre change nothing
    B = 3.0 * np.exp(1j * 0.7) * A * (1.0 + 0.5 * np.cos(np.arange(shape[1]) / 3.0))
    pos2, q2 = phase_defects(B.real + 1.0, B.imag - 2.0, center=(1.0, -2.0))
    assert q2.tolist() == [1] and np.allclose(pos2, [[10.5, 20.5]])
    assert spiral_tips(A.real, A.imag, center=(0.0, 0.0)) == 1


def test_phase_defects_of_a_vortex_pair_and_a_double_vortex():
    shape = (32, 40)
    A = _vortex(shape, (8.2, 10.7), +1) * _vortex(shape, (20.6, 30.1), -1)
    pos, q = phase_defects(A.real, A.imag)
    order = np.argsort(pos[:, 0])
    assert q[order].tolist() == [1, -1]
    np.testing.assert_allclose(pos[order], [[8.5, 10.5], [20.5, 30.5]])
    # a double vortex: the phase turns by 4π around it, more than the four steps of a
    # plaquette can follow (each is taken in (−π, π]), so it shows as charge 2 spread over
    # neighbouring plaquettes
    D = _vortex(shape, (15.4, 15.6)) ** 2
    pos, q = phase_defects(D.real, D.imag)
    assert q.sum() == 2 and np.all(q > 0) and np.abs(pos - [15.5, 15.5]).max() <= 1.0
    # smooth fields without a zero have none
    z = np.exp(1j * np.indices(shape).sum(axis=0) * 0.3)
    assert len(phase_defects(z.real, z.imag)[1]) == 0


def test_phase_defects_on_a_torus_sum_to_zero():
    """A random smooth periodic field: many defects, total charge 0 (the phase is
    single-valued on the torus), and they move with the field (``np.roll``), across the
    periodic sides too."""
    rng = np.random.default_rng(3)
    ny, nx = 48, 64
    grid = Grid((ny, nx), bc="periodic")
    spec = np.zeros((ny, nx), complex)
    modes = 6
    spec[:modes, :modes] = rng.normal(size=(modes, modes)) + 1j * rng.normal(size=(modes, modes))
    spec[-modes + 1:, :modes] = rng.normal(size=(modes - 1, modes)) \
        + 1j * rng.normal(size=(modes - 1, modes))
    A = np.fft.ifft2(spec)
    pos, q = phase_defects(A.real, A.imag, grid)
    assert len(q) >= 10 and q.sum() == 0 and set(np.abs(q).tolist()) == {1}
    # a bounded grid drops the plaquettes across the sides: a subset of the same defects
    pos_b, q_b = phase_defects(A.real, A.imag)
    assert len(q_b) <= len(q) and _matched(pos_b, pos, (ny, nx), 0.0) == 1.0
    shifted = np.roll(A, (5, -7), axis=(0, 1))
    pos_s, q_s = phase_defects(shifted.real, shifted.imag, grid)
    assert sorted(q_s.tolist()) == sorted(q.tolist())
    moved = (pos + [5, -7]) % [ny, nx]
    assert _matched(moved, pos_s, (ny, nx), 0.0) == 1.0
    assert spiral_tips(A.real, A.imag, grid, center=(0.0, 0.0)) == len(q)


def test_phase_defects_rejects_what_it_cannot_measure():
    with pytest.raises(ValueError, match="same shape"):
        phase_defects(np.zeros((4, 4)), np.zeros((4, 5)))
    with pytest.raises(ValueError, match="2-D"):
        phase_defects(np.zeros((4, 4, 4)), np.zeros((4, 4, 4)), Grid((4, 4, 4)))


# ------------------------------------------------------- complex Ginzburg-Landau (seed 004)
def _defect_history(name, size, *, seed=0, settle=200.0, every=50.0, samples=6):
    """Defects of preset ``name`` on a ``size``² grid (the preset's spacing, step and
    sides) after ``settle``, then every ``every`` time units: counts, total charges and
    the fraction of each sample's defects found again (within 1.5 cells) in the next."""
    sim = _sim(name, grid=(size, size), seed=seed)
    f = _advance(sim, round(settle / sim.dt))
    prev = phase_defects(f["u"], f["v"], sim.domain)
    counts, charges, kept = [len(prev[1])], [int(prev[1].sum())], []
    for _ in range(samples):
        f = _advance(sim, round(every / sim.dt))
        cur = phase_defects(f["u"], f["v"], sim.domain)
        counts.append(len(cur[1]))
        charges.append(int(cur[1].sum()))
        kept.append(_matched(prev[0], cur[0], (size, size)))
        prev = cur
    # saturated: |A| stays near the uniform oscillation's 1/√b3 (measured: at most 1.5×)
    assert np.all(np.hypot(f["u"], f["v"]) < 2.0 / math.sqrt(sim.params["b3"]))
    return np.array(counts), np.array(charges), np.array(kept)


def test_cgl_model_is_eq_62_in_real_form():
    """The right-hand sides equal ``A + (1 + i b1)ΔA − (b3 − i)|A|²A`` split into real and
    imaginary parts (Laplacians given as numbers here), and the uniform oscillation
    ``|A|² = 1/b3`` is a solution: its amplitude does not change."""
    m = MODELS["complex-ginzburg-landau"]
    rng = np.random.default_rng(0)
    A, L = (rng.normal(size=8) + 1j * rng.normal(size=8) for _ in range(2))
    b1, b3 = 0.7, 0.56
    want = A + (1 + 1j * b1) * L - (b3 - 1j) * np.abs(A) ** 2 * A
    env = {"u": A.real, "v": A.imag, "b1": b1, "b3": b3}
    lap = {"u": L.real, "v": L.imag}
    got = [eq.evaluate(m.trees[s], env, lap=lambda name, order: lap[name])
           for s in ("u", "v")]
    np.testing.assert_allclose(got[0] + 1j * got[1], want, rtol=1e-12)
    a = 1 / math.sqrt(b3)
    du, dv = m.rates([a * math.cos(0.3), a * math.sin(0.3)], {"b1": b1, "b3": b3})
    assert abs(du * math.cos(0.3) + dv * math.sin(0.3)) < 1e-12  # d|A|/dt = 0


def test_cgl_seed004_fig12_spiral_defect_turbulence():
    """Fig. 12's b1 = 0, b3 = 0.56 on 128² Neumann cells (the preset: 200², 217 defects
    at t = 500): from t = 200 the number of defects fluctuates about a steady mean
    (measured, seeds 0-2: 71-105) and the set renews itself -- at most 9 % of the defects
    are found again 50 time units later.  Same numerics at b3 = 1 ('cgl-frozen-spirals'):
    the spirals freeze, 24-26 defects that all stay put."""
    counts, charges, kept = _defect_history("cgl-seed004-fig12", 128)
    assert counts.min() >= 50 and counts.max() <= 150, counts
    assert len(set(counts.tolist())) > 2  # defects are created and annihilated
    assert kept.max() < 0.3, kept  # and they move
    assert np.all(np.abs(charges) <= 10)  # (Neumann sides: charge can leave, not much)

    counts, charges, kept = _defect_history("cgl-frozen-spirals", 128)
    assert 10 <= counts[0] <= 60 and np.all(counts == counts[0]), counts
    assert np.all(charges == 0) and kept.min() == 1.0, kept


def test_cgl_defect_turbulence_past_the_benjamin_feir_line():
    """b1 = 2 > b3 = 0.5: defect turbulence on a 128² torus (the preset: 200², 332 defects
    at t = 400): measured 134-168 defects, at most 14 % found again after 50 time units,
    total charge 0 at every sample."""
    counts, charges, kept = _defect_history("cgl-defect-turbulence", 128, samples=4)
    assert counts.min() >= 100 and counts.max() <= 220, counts
    assert np.all(charges == 0)
    assert kept.max() < 0.3, kept


# --------------------------------------------------------------- Swift-Hohenberg (seed 004)
def _mean_wavenumber(u: np.ndarray, dx: float) -> float:
    """Power-weighted mean |k| of the structure factor of a periodic 2-D field."""
    power = np.abs(np.fft.fft2(u - u.mean())) ** 2
    ky = 2 * np.pi * np.fft.fftfreq(u.shape[0], dx)
    kx = 2 * np.pi * np.fft.fftfreq(u.shape[1], dx)
    return float((np.hypot(ky[:, None], kx[None, :]) * power).sum() / power.sum())


@pytest.mark.parametrize("name", ["sh-seed004-stripes", "sh-hexagons"])
def test_swift_hohenberg_presets_run_implicitly_far_past_the_explicit_limit(name):
    p = PRESETS[name]
    model = MODELS[p.model]
    assert p.options["method"] == "imex"
    for domain in (p.build_domain(), Grid((64, 64), dx=p.domain["dx"], bc="periodic")):
        limit = model.dt_limit(domain, p.params, "euler")  # 0.0141 at dx = π/4
        assert p.dt >= 10 * limit, (p.dt, limit)
        assert model.dt_limit(domain, p.params, "imex") >= p.dt
    with pytest.raises(StabilityError, match="stability limit"):  # explicit: refused
        model.stepper(p.build_domain(), p.params, dt=p.dt, backend="numpy", method="euler")


def _swift_hohenberg(name, *, seed=0):
    """The preset on 64² cells of dx = π/4 (8 wavelengths across; the preset: 128², 16)
    to t = 200 (400 implicit steps of 0.5)."""
    sim = _sim(name, grid=(64, 64), seed=seed, dtype="float64")
    u = _advance(sim, 400)["u"]
    return sim, u


def test_swift_hohenberg_stripes_at_wavenumber_one():
    """r = 0.2, g = 0 (Fig. 13's parameters): a labyrinth of stripes -- both phases of u
    in a few long bands (measured, seeds 0-2: 2-4 pieces each) -- at the critical
    wavenumber: the structure factor's mean |k| is 0.996-1.011 (the full preset: 1.010);
    the amplitude stays bounded (|u| ≤ 0.75)."""
    sim, u = _swift_hohenberg("sh-seed004-stripes")
    assert classify_pattern(u, sim.domain, 0.0) == "stripes"
    comps = phase_components(u, sim.domain, 0.0)
    assert len(comps["high"]) <= 8 and len(comps["low"]) <= 8
    assert _mean_wavenumber(u, sim.domain.dx) == pytest.approx(1.0, abs=0.05)
    assert 0.4 < np.abs(u).max() < 1.0


def test_swift_hohenberg_hexagons_with_a_quadratic_term():
    """r = 0.1, g = 1: a hexagonal lattice of u > 0 spots (classify_pattern's compact
    islands of high values in a connected sea) of mean |k| ≈ 1 (measured 0.996-0.997; full
    preset 1.001), as many as a perfect lattice of spacing a = 4π/√3 holds, L²/(√3 a²/2) =
    55.4 on this grid (measured 52-54; the full preset 219 of 221.7)."""
    sim, u = _swift_hohenberg("sh-hexagons")
    assert classify_pattern(u, sim.domain, 0.0) == "inverted-spots"
    assert _mean_wavenumber(u, sim.domain.dx) == pytest.approx(1.0, abs=0.05)
    L = 64 * sim.domain.dx
    a = 4 * math.pi / math.sqrt(3)
    ideal = L * L / (math.sqrt(3) / 2 * a * a)
    spots = phase_components(u, sim.domain, 0.0)["high"]
    assert len(spots) == pytest.approx(ideal, rel=0.1), (len(spots), ideal)
    assert spots.max() < 3 * np.median(spots)  # islands of one size, no merged stripes


# ------------------------------------------------------------ Meinhardt's stripes (seed 003)
def _meinhardt(name, *, seed=0):
    """The preset as it is (80², dt = 1): the fields 5000 steps before the end and at the
    end."""
    sim = _sim(name, seed=seed)
    before = _advance(sim, PRESETS[name].steps - 5000)
    return sim, before, _advance(sim, 5000)


def _dominant_wavelength(f: np.ndarray) -> float:
    """``n/m`` for the ring ``m`` of Fourier modes (|k| binned in units of ``2π/n``) that
    holds the most power, on an ``n × n`` periodic field of unit spacing."""
    n = f.shape[0]
    power = np.abs(np.fft.fft2(f - f.mean())) ** 2
    m = np.fft.fftfreq(n) * n
    ring = np.rint(np.hypot(m[:, None], m[None, :])).astype(int)
    return n / int(np.argmax(np.bincount(ring.ravel(), power.ravel())))


def _stripes_of_two_colours(sim, f):
    """What both presets share: g1 in stripes (classify_pattern), g2 high exactly where g1
    is low (correlation −1.000 measured), half the grid each, and a dominant wavelength of
    about ten cells (measured: 10.0 for the rings, 8.9 for the random stripes)."""
    g1, g2 = f["g1"], f["g2"]
    assert classify_pattern(g1, sim.domain, None) == "stripes"
    assert np.corrcoef(g1.ravel(), g2.ravel())[0, 1] < -0.95
    assert 0.4 < phase_components(g1, sim.domain, None)["fraction_high"] < 0.6
    wavelength = _dominant_wavelength(g1)
    assert 8.0 <= wavelength <= 11.5, wavelength
    return wavelength


def test_meinhardt_rings_from_a_central_perturbation():
    """Fig. 2.5: a perturbation at the centre of the 80² grid grows into concentric rings
    of alternating g1 and g2 (7 bands of g1 along the central row) that keep the 4-fold
    symmetry of the square perturbation exactly and stop moving (max change 0.0012 over the
    last 5000 steps)."""
    sim, before, f = _meinhardt("meinhardt-seed003-rings")
    _stripes_of_two_colours(sim, f)
    g1 = f["g1"]
    np.testing.assert_array_equal(g1, np.rot90(g1))  # centre (39.5, 39.5): exact symmetry
    row = g1[40] > 0.5 * (g1.min() + g1.max())
    assert np.count_nonzero(row != np.roll(row, 1)) // 2 == 7
    assert np.abs(g1 - before["g1"]).max() < 0.01


def test_meinhardt_random_stripes():
    """Fig. 2.6: random noise everywhere gives a labyrinth of g1 / g2 stripes (the largest
    g1 band about 130-200 times as long as wide); under 1 % of the cells change by more than
    0.2 over the last 5000 of 30 000 steps (measured: seeds 0-3, at most 0.13 %)."""
    sim, before, f = _meinhardt("meinhardt-seed003-random")
    _stripes_of_two_colours(sim, f)
    comps = phase_components(f["g1"], sim.domain, None)
    assert comps["elongation_high"][0] > 50
    assert np.mean(np.abs(f["g1"] - before["g1"]) > 0.2) < 0.01


# ------------------------------------------------------------ Turing's 1-D model (seed 003)
def _ring_peaks(b: np.ndarray, prominence: float = 0.5) -> np.ndarray:
    """Indices of the peaks of ``b`` on a ring (the line's ends joined)."""
    from scipy.signal import find_peaks

    n = b.size
    idx, _ = find_peaks(np.concatenate([b, b, b]), prominence=prominence)
    return np.sort(idx[(idx >= n) & (idx < 2 * n)] - n)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_turing_1d_ring_of_60_cells_has_seven_peaks(seed):
    """Fig. 2.3: b on 60 cells every 4000 steps from 4000 to 20 000 (the figure's frames
    (a)-(f) after the start): 7 peaks (b ≈ 6.5-8 between troughs clamped at 0) at the same
    cells in every frame; measured for seeds 0-9.  Seven is the ring's least stable mode at
    a = b = 4, β = 12 (its growth rate is the largest of the 31; the spread of β makes it
    grow)."""
    name = "turing-seed003-1d"
    p = PRESETS[name]
    model = MODELS[p.model]
    m = np.arange(31)
    scalar = {**p.params, "beta": 12.0}
    gamma = dispersion(model, scalar, grid_wavenumber(m, 60), state=[4.0, 4.0])
    assert int(np.argmax(gamma)) == 7

    sim = _sim(name, seed=seed, dtype="float64")
    frames = [_advance(sim, 4000)["v"].ravel() for _ in range(p.steps // 4000)]
    assert frames[0].shape == (60,)
    first = _ring_peaks(frames[0])
    assert len(first) == 7, first
    for b in frames[1:]:
        np.testing.assert_array_equal(_ring_peaks(b), first)
    b = frames[-1]
    assert classify_pattern(b, sim.domain, None) == p.expect  # 7 bands of each phase
    assert b.min() == 0.0 and 6.0 < b[first].min() and b.max() < 9.0
    gaps = np.diff(np.concatenate([first, [first[0] + 60]]))
    assert gaps.min() >= 6 and gaps.max() <= 11  # evenly spaced, 60/7 ≈ 8.6 apart


# ----------------------------------------------- Gray-Scott with F(x), k(y) (seed 004 Fig. 7)
def test_gray_scott_fig7_parameters_are_expressions_and_the_pattern_varies():
    """The preset's F and k are expressions of x and y, evaluated at the cell centres into
    fields (F constant along y, k along x).  On 128² (the preset's 400² scaled down, the
    same expressions: one period across) after 10 000 steps, by quarter of the domain
    (measured, seeds 0-2; the full preset after 20 000 steps in brackets), the share of
    cells with v > 0.1: F high / k low 0.99-1.00 (0.99), one v-filled region; F low / k
    high 0.18-0.21 (0.13), 16-18 isolated spots; the two mixed quarters 0.39-0.42 (0.37)
    and 0.60-0.69 (0.62)."""
    name = "gs-seed004-fig7"
    n = 128
    sim = _sim(name, grid=(n, n))
    F, k = sim.params["F"], sim.params["k"]
    x = (np.arange(n) + 0.5) / n  # cell centres over Lx = n dx
    np.testing.assert_allclose(F, np.broadcast_to(0.037 + 0.0185 * np.sin(2 * np.pi * x),
                                                  (n, n)), rtol=1e-12)
    np.testing.assert_allclose(k, np.broadcast_to(
        (0.06 + 0.0075 * np.sin(2 * np.pi * x))[:, None], (n, n)), rtol=1e-12)
    v = _advance(sim, 10_000)["v"]
    h = n // 2  # sin > 0 on the first half of each axis: F high on the left, k at the top
    quarter = {"F+k-": v[h:, :h], "F-k+": v[:h, h:], "F+k+": v[:h, :h], "F-k-": v[h:, h:]}
    share = {q: float(np.mean(b > 0.1)) for q, b in quarter.items()}
    assert share["F+k-"] > 0.95, share
    assert len(phase_components(quarter["F+k-"], None, 0.1)["high"]) == 1
    assert share["F-k+"] < 0.3, share
    assert classify_pattern(quarter["F-k+"], None, 0.1) == "inverted-spots"
    assert len(phase_components(quarter["F-k+"], None, 0.1)["high"]) >= 10
    assert 0.3 < share["F+k+"] < 0.8 and 0.3 < share["F-k-"] < 0.8, share


# --------------------------------------------------------------------- Gray-Scott in 3-D
def _periodic_components(mask: np.ndarray) -> np.ndarray:
    """Sizes (cells, largest first) of the connected regions of ``mask`` on a periodic 3-D
    grid: face neighbours (scipy.ndimage.label), with the labels that touch across each
    pair of opposite sides joined."""
    from scipy import ndimage
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    labels, n = ndimage.label(mask)
    a, b = [], []
    for axis in range(mask.ndim):
        lo, hi = np.take(labels, 0, axis=axis).ravel(), np.take(labels, -1, axis=axis).ravel()
        both = (lo > 0) & (hi > 0)
        a.append(lo[both])
        b.append(hi[both])
    a, b = np.concatenate(a), np.concatenate(b)
    links = coo_matrix((np.ones(a.size), (a, b)), shape=(n + 1, n + 1))
    _, root = connected_components(links, directed=False)
    sizes = np.bincount(root[labels[mask]])
    return np.sort(sizes[sizes > 0])[::-1]


def _gray_scott_3d(name, size, steps, seed=0):
    sim = _sim(name, grid=(size, size, size), seed=seed)
    assert sim.domain.ndim == 3
    f = _advance(sim, steps)
    v = f["v"]
    assert v.shape == (size,) * 3
    high = v > 0.5 * (v.min() + v.max())
    return f, high, _periodic_components(high), _periodic_components(~high)


def test_periodic_components_join_across_the_sides():
    mask = np.zeros((6, 7, 8), bool)
    mask[2, 3, [0, 1, 7]] = True  # one bar through the x side
    mask[[0, 5], 1, 1] = True  # a pair through the z side
    mask[3, 5, 4] = True  # an island
    np.testing.assert_array_equal(_periodic_components(mask), [3, 2, 1])
    np.testing.assert_array_equal(_periodic_components(np.ones((3, 3, 3), bool)), [27])


def _slice_classes(v: np.ndarray, step: int = 4) -> dict[str, int]:
    """classify_pattern of every ``step``-th plane of a periodic cube along each axis (the
    3-D field's midrange as threshold): sheets cut into stripes, blobs into spots."""
    n = v.shape[0]
    plane = Grid((n, n), bc="periodic")
    threshold = 0.5 * (v.min() + v.max())
    classes = [classify_pattern(np.take(v, i, axis=axis), plane, threshold)
               for axis in range(3) for i in range(0, n, step)]
    return {c: classes.count(c) for c in set(classes)}


def test_gray_scott_3d_labyrinth_of_sheets():
    """Seed 001's stripe parameters on a 32³ torus (the preset: 64³, 24 000 steps; here
    8000 steps of the same dt = 0.5): both phases of v are one connected region each
    (measured, seeds 0-3 and at 64³), v is high in 46-47 % of the cells (39 % at 64³), and
    22-24 of 24 planes through the box classify as stripes: sheets, not tubes."""
    f, high, hi, lo = _gray_scott_3d("gs-3d-labyrinth", 32, 8000)
    v, u = f["v"], f["u"]
    assert len(hi) == 1 and len(lo) == 1
    assert 0.3 < high.mean() < 0.6
    assert _slice_classes(v).get("stripes", 0) >= 20
    checker = np.indices(u.shape).sum(axis=0) % 2 * 2 - 1
    assert abs(np.mean(u * checker)) < 1e-4  # no grid-scale checkerboard (dt = 1: 0.08)


def test_gray_scott_3d_blobs():
    """F = 0.030, k = 0.068 on a 32³ torus, 12 000 steps of dt = 0.5 (the preset: 64³,
    24 000 steps, 120 blobs): ten seed balls divide into isolated round blobs of high v in
    one connected sea -- measured, seeds 0-3: 15-18 blobs (one per ~2000 cells, as at 64³),
    most of 200-230 cells (a ball of radius ~3.7), v high in 10-11 % of the cells, and
    22-24 of 24 planes classify as isolated spots of high v."""
    f, high, hi, lo = _gray_scott_3d("gs-3d-blobs", 32, 12_000)
    v = f["v"]
    assert len(lo) == 1
    assert 10 <= len(hi) <= 25, hi
    assert 150 <= np.median(hi) <= 300 and hi.max() < 1000, hi
    assert 0.05 < high.mean() < 0.15
    assert _slice_classes(v).get("inverted-spots", 0) >= 20
