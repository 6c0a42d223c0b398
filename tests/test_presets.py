"""The presets reproduce the seed papers' patterns (issue 4 §5), each checked by a test.

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
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import backend_or_skip

from rdgpu.analysis import classify_pattern, phase_components, spiral_tips
from rdgpu.cli.app import main as cli_main
from rdgpu.io.output import load_npz
from rdgpu.models import PRESETS, AllenCahn
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


# AllenCahn.energy documents a splitting error of ~1e-8 relative in this regime (ε = 0.15
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
