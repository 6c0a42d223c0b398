"""The VisualPDE importer (issue 23, item 8): presets written here in VisualPDE's format
(its ``presets.js`` keys) translate into rdgpu's model, grid, time step, scheme and
initial state, run like the same model written by hand, and what rdgpu cannot translate
is refused by name."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import backend_or_skip

import rdgpu
from rdgpu.cli.app import main as rdgpu_main
from rdgpu.domains.grid import Grid
from rdgpu.integrations.visualpde import RUN_FRAMES, UnsupportedPreset, load
from rdgpu.io.output import load_npz
from rdgpu.models import define_model

GS = {"preset": "gs", "domainScale": "64", "spatialStep": "1", "squareCanvas": True,
      "diffusionStr_1_1": "0.16", "diffusionStr_2_2": "0.08", "dt": 1.0,
      "reactionStr_1": "-u*v^2 + F*(1.0 - u)", "reactionStr_2": "u*v^2 - (F+k)*v",
      "kineticParams": "F = 0.030 in [0, 0.1];k = 0.055;",
      "initCond_1": "1 - 0.5*exp(-((x-L_x/2)^2 + (y-L_y/2)^2)/40)",
      "initCond_2": "0.25*exp(-((x-L_x/2)^2 + (y-L_y/2)^2)/40)",
      "numTimestepsPerFrame": 20, "whatToPlot": "v"}


def test_the_defaults_are_visualpdes_gray_scott():
    """An empty preset is VisualPDE's default: Gray-Scott with D = 0.04, 0.02 on 200² cells
    of 0.5, dt 0.1, forward Euler, periodic."""
    tr = load({})
    assert tr.model.species == ("u", "v")
    assert tr.grid.shape == (200, 200) and tr.grid.dx == 0.5
    assert tr.grid.bcs.x.kind == 0  # periodic
    assert tr.dt == 0.1 and tr.method == "euler" and tr.steps == RUN_FRAMES * 100
    assert tr.model.equations["u"] == "(0.04)*laplace(u) + (-u*v**2 + 0.037*(1.0 - u))"


def test_a_preset_runs_as_the_same_model_written_by_hand():
    tr = load(GS)
    assert tr.model.defaults == {"F": 0.03, "k": 0.055}
    assert tr.grid.shape == (64, 64) and tr.field == "v"
    hand = define_model("hand", {"u": "0.16*laplace(u) - u*v**2 + F*(1 - u)",
                                 "v": "0.08*laplace(v) + u*v**2 - (F + k)*v"},
                        {"F": 0.03, "k": 0.055})
    fields = tr.fields()
    x = (np.arange(64) + 0.5)
    r2 = (x[None, :] - 32) ** 2 + (x[:, None] - 32) ** 2
    np.testing.assert_allclose(fields["v"], 0.25 * np.exp(-r2 / 40), rtol=1e-12)
    out = {}
    for name, model in (("preset", tr.model), ("hand", hand)):
        st = model.stepper(tr.grid, {}, dt=1.0, backend="numpy", dtype="float64")
        st.set_state(fields)
        st.advance(300)
        out[name] = st.get_state()
    for s in "uv":
        np.testing.assert_allclose(out["preset"][s], out["hand"][s], rtol=1e-12, atol=1e-14)
    assert out["preset"]["v"].max() > 0.2  # the spot lives


def test_translation_details():
    """Cross-diffusion in divergence form (a state-dependent coefficient) or as a
    Laplacian (a constant one), dependent parameters, timescales, schemes, minX shifts,
    first derivatives, 1-D second derivatives, Dirichlet values."""
    tr = load({"numSpecies": 2, "crossDiffusion": True, "diffusionStr_1_1": "D",
               "diffusionStr_1_2": "-chi*u", "diffusionStr_2_2": "1", "diffusionStr_2_1": "0",
               "reactionStr_1": "u*(1-u) + c*u_x", "reactionStr_2": "u - v",
               "kineticParams": "D = 1;chi = 2*D in [0, 10];c=0.1",
               "timescales": True, "timescale_2": "0.5", "timesteppingScheme": "AB2",
               "minX": "-L_x/2", "domainScale": "20", "spatialStep": "0.5",
               "boundaryConditions_1": "dirichlet", "boundaryConditions_2": "dirichlet",
               "dirichletStr_1": "0.25", "dirichletStr_2": "L/80"})
    assert tr.model.defaults == {"D": 1.0, "chi": 2.0, "c": 0.1}
    assert tr.model.equations["u"] == ("(D)*laplace(u) + div((-chi*u)*grad(v)) + "
                                       "(u*(1-u) + c*d_dx(u))")
    assert tr.model.equations["v"] == "((1)*laplace(v) + (u - v))/(0.5)"
    assert tr.method == "ab2" and tr.offsets == (-10.0, 0.0)
    # VisualPDE's Dirichlet value is on the boundary: rdgpu's face value, per species
    assert tr.grid.bcs.x.kind == 1 and tr.grid.bcs.y.kind == 1  # neumann, overridden
    assert tr.bc == {"u": dict.fromkeys(("x-", "x+", "y-", "y+"), ("value", "0.25")),
                     "v": dict.fromkeys(("x-", "x+", "y-", "y+"), ("value", "20.0/80"))}
    line = load({"dimension": "1", "numSpecies": 1, "reactionStr_1": "u_xx - u",
                 "diffusionStr_1_1": "0", "initCond_1": "x", "minX": "5",
                 "domainScale": "10", "spatialStep": "1"})
    assert line.grid.shape == (1, 10) or line.grid.shape == (10,)
    assert line.model.equations["u"] == "(laplace(u) - u)"
    np.testing.assert_allclose(line.fields()["u"].ravel(), np.arange(10) + 5.5)
    assert line.fields()["u"].shape == (10,)  # a 1-D field as users hold it: it runs
    ran = line.simulation(backend="numpy", dtype="float64").run(3, progress=False)
    assert ran.fields["u"].shape == (10,) and np.isfinite(ran.fields["u"]).all()
    sided = load({"reactionStr_1": "-u*u_xb + v_yf - cosh(u) + sinh(v)"})
    assert sided.model.equations["u"] == ("(0.04)*laplace(u) + (-u*d_dx_backward(u) + "
                                          "d_dy_forward(v) - cosh(u) + sinh(v))")
    switch = load({"reactionStr_1": "ind(u > 0.5)*u - v", "initCond_1": "ind(x < L_x/2)"})
    assert switch.model.equations["u"] == "(0.04)*laplace(u) + ((u > 0.5)*u - v)"
    half = switch.fields()["u"]
    assert half[:, :100].min() == 1 and half[:, 100:].max() == 0
    noisy = load({"initCond_2": "0.1*RANDN + RAND"})
    a, b = noisy.fields(seed=3)["v"], noisy.fields(seed=3)["v"]
    np.testing.assert_array_equal(a, b)
    assert abs(a.mean() - 0.5) < 0.02 and 0.25 < a.std() < 0.35
    assert not np.array_equal(a, noisy.fields(seed=4)["v"])


def test_parents_json_and_files(tmp_path):
    presets = {"base": dict(GS), "child": {"parent": "base", "kineticParams": "F=0.04;k=0.06"}}
    tr = load(presets["child"], presets=presets)
    assert tr.model.defaults == {"F": 0.04, "k": 0.06} and tr.grid.shape == (64, 64)
    # VisualPDE looks a parent up ignoring case (its presets say "grayScott" for GrayScott)
    folded = load({"parent": "BASE", "kineticParams": "F=0.05;k=0.06"}, presets=presets)
    assert folded.model.defaults == {"F": 0.05, "k": 0.06} and folded.grid.shape == (64, 64)
    path = tmp_path / "gs.json"
    path.write_text(json.dumps(GS))
    assert load(path).model.equations == load(json.dumps(GS)).model.equations
    with pytest.raises(UnsupportedPreset, match="parent = 'nowhere'"):
        load({"parent": "nowhere"})
    with pytest.raises(FileNotFoundError, match="missing.json"):
        load(tmp_path / "missing.json")
    with pytest.raises(ValueError, match="not JSON"):
        load("{not json")


@pytest.mark.parametrize("preset, words", [
    ({"numAlgebraicSpecies": 2, "numSpecies": 2}, "at least one species must evolve"),
    ({"domainViaIndicatorFun": True, "domainIndicatorFun": "I_S < 0.5"}, "'I_S'"),
    ({"boundaryConditions_1": "combo", "boundaryConditions_2": "neumann",
      "comboStr_1": "Left: Sticky = 1"}, "comboStr_1 part 'Left: Sticky = 1'"),
    ({"boundaryConditions_1": "robin", "boundaryConditions_2": "neumann",
      "robinStr_1": "-u^2"}, "not linear in 'u'"),
    ({"boundaryConditions_1": "neumann", "boundaryConditions_2": "neumann",
      "neumannStr_1": "u"}, "reads the species u"),
    ({"boundaryConditions_1": "sticky"}, "boundaryConditions_1 = 'sticky'"),
    ({"reactionStr_1": "ind(u > 0.5) ? 1 : 0"}, "reactionStr_1 = .*logic \\('\\?'\\)"),
    ({"reactionStr_1": "mod(u, 2)"}, "the function 'mod'"),
    ({"reactionStr_1": "Bump(1, 2)"}, "Bump with 2 argument"),
    ({"reactionStr_1": "0.1*WhiteNoise", "reactionStr_2": "WhiteNoise"},
     "WhiteNoise in the equations of 'u' and 'v'"),
    ({"reactionStr_1": "u*WhiteNoise^2"}, "not linear in WhiteNoise"),
    ({"reactionStr_1": "WhiteNoise", "timesteppingScheme": "RK4"},
     "WhiteNoise with timesteppingScheme = 'RK4'"),
    ({"reactionStr_2": "u_xy"}, "u_xy"),
    ({"reactionStr_2": "w*u"}, "the name 'w'"),
    ({"timesteppingScheme": "Leapfrog"}, "timesteppingScheme = 'Leapfrog'"),
    ({"dimension": "3"}, "dimension = '3'"),
    ({"kineticParams": "t = 1"}, "reserved name"),
])
def test_what_rdgpu_cannot_translate_is_refused_by_name(preset, words):
    with pytest.raises(UnsupportedPreset, match=words):
        load(preset)


SH_ALGEBRAIC = {
    "preset": "sh-algebraic", "numSpecies": 2, "numAlgebraicSpecies": 1,
    "speciesNames": "u v", "crossDiffusion": True, "domainScale": "24", "spatialStep": "1",
    "squareCanvas": True, "dt": 0.02, "kineticParams": "r = 0.3;",
    "diffusionStr_1_1": "0", "diffusionStr_1_2": "-1", "diffusionStr_2_1": "1",
    "diffusionStr_2_2": "0", "reactionStr_1": "(r-1)*u - 2*v - u^3", "reactionStr_2": "0",
    "boundaryConditions_2": "dirichlet", "timescales": True, "timescale_2": "5",
    "initCond_1": "0.1*sin(2*pi*x/L_x)", "whatToPlot": "v"}


def test_algebraic_species_are_substituted():
    """VisualPDE's Swift–Hohenberg with the algebraic ``v = Δu`` (cross-diffusion ``D_vu =
    1``, ``D_uv = −1``): rdgpu's model of ``u`` alone, ``−Δv`` a bilaplacian (B = −1) and
    ``−2v`` an anti-diffusion (D = −2); ``v``'s boundary condition and timescale do not
    apply (it has no evolution); the run equals the same model written by hand."""
    tr = load(SH_ALGEBRAIC)
    assert tr.model.species == ("u",) and set(tr.model.algebraic) == {"v"}
    D, B = tr.model.linear_operators()
    assert D.tolist() == [[-2.0]] and B.tolist() == [[-1.0]]
    assert tr.field == "u" and any("algebraic species 'v'" in n for n in tr.notes)
    sim = tr.simulation(backend="numpy", dtype="float64")
    res = sim.run(100, progress=False)
    hand = define_model("hand", {"u": "(r - 1)*u - 2*laplace(u) - laplace(laplace(u)) - u**3"},
                        {"r": 0.3})
    st = hand.stepper(tr.grid, dt=0.02, backend="numpy")
    st.set_state(tr.fields(0))
    st.advance(100)
    np.testing.assert_allclose(res.fields["u"], st.get_state()["u"], rtol=1e-11, atol=1e-12)
    assert res.diverged is None and np.abs(res.fields["u"]).max() > 0.01


def test_an_indicator_domain_is_a_mask():
    """``domainIndicatorFun`` (inside where positive) becomes rdgpu's mask: Gray-Scott on a
    disc with zero-flux sides runs, the cells outside keep their start; a species'
    Dirichlet condition holds on the domain's edge (``mask_bc``); a domain that reads t, or
    conditions that differ between sides, are refused by name."""
    disc = {**GS, "domainViaIndicatorFun": True, "boundaryConditions_1": "neumann",
            "boundaryConditions_2": "neumann",
            "domainIndicatorFun": "(L_min/2.2)^2 - ((x-L_x/2)^2 + (y-L_y/2)^2)"}
    tr = load(disc)
    assert tr.mask is not None and tr.mask.endswith("> 0")
    sim = tr.simulation(backend="numpy")
    res = sim.run(200, progress=False)
    start = tr.fields(0)
    assert 0.5 < res.mask.mean() < 0.8
    np.testing.assert_array_equal(res.fields["v"][~res.mask],
                                  start["v"].astype(np.float32)[~res.mask])
    assert not np.array_equal(res.fields["v"][res.mask], start["v"][res.mask])
    with pytest.raises(UnsupportedPreset, match="reads t: a domain that changes"):
        load({**disc, "domainIndicatorFun": "x < t"})
    # Dirichlet conditions hold on the domain's edge: VisualPDE's value on the face
    held = load({**disc, "boundaryConditions_1": "dirichlet", "dirichletStr_1": "1",
                 "boundaryConditions_2": "neumann"})
    assert held.mask_bc == {"u": ("value", "1")}
    u = held.simulation(backend="numpy").run(200, progress=False).fields["u"]
    assert np.isfinite(u).all()
    with pytest.raises(UnsupportedPreset, match="differ between sides"):
        load({**disc, "boundaryConditions_1": "combo", "boundaryConditions_2": "neumann",
              "comboStr_1": "Left: Dirichlet = 1; Right: Neumann = 0; Top: Neumann = 0; "
                            "Bottom: Neumann = 0;"})


def test_the_command_line_runs_a_preset(tmp_path, capsys):
    path = tmp_path / "gs.json"
    path.write_text(json.dumps(GS))
    data = tmp_path / "run.npz"
    code = rdgpu_main(["run", "--visualpde", str(path), "--steps", "200", "--backend",
                       "numpy", "--dtype", "float64", "--data", str(data), "--quiet"])
    assert code == 0, capsys.readouterr().err
    res = load_npz(data)
    tr = load(GS)
    st = tr.model.stepper(Grid((64, 64), dx=1.0, bc="periodic"), {}, dt=1.0,
                          backend="numpy", dtype="float64")
    st.set_state(tr.fields())
    st.advance(200)
    np.testing.assert_array_equal(res.fields["v"], st.get_state()["v"])
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"domainViaIndicatorFun": True, "domainIndicatorFun": "x < t"}))
    assert rdgpu_main(["run", "--visualpde", str(bad), "--quiet"]) == 2
    assert "a domain that changes during the run" in capsys.readouterr().err
    assert rdgpu_main(["run", "gray-scott", "--visualpde", str(path), "--quiet"]) == 2
    assert "drop MODEL (gray-scott)" in capsys.readouterr().err


@pytest.mark.parametrize("backend_name", ["opencl", "warp"])
def test_every_backend_runs_a_translated_preset(backend_name):
    be = backend_or_skip(backend_name)
    tr = load({**GS, "crossDiffusion": True, "diffusionStr_2_1": "0.01*v",
               "timesteppingScheme": "RK4"})
    out = {}
    for backend in (rdgpu.get_backend("numpy"), be):
        sim = tr.simulation(backend=backend, dtype="float64")
        out[backend.name] = sim.run(20, progress=False).fields["v"]
    np.testing.assert_allclose(out[be.name], out["numpy"], rtol=1e-12, atol=1e-14)


def test_periodic_for_some_species_and_sides():
    """A species periodic where another is not: the grid's axis is Neumann and the
    periodic sides are given per species (``"periodic"``); the run is the hand-written
    model's with that ``bc`` bit for bit."""
    tr = load({**GS, "boundaryConditions_1": "neumann"})
    assert tr.grid.bcs.x.kind == 1 and tr.grid.bcs.y.kind == 1
    assert tr.bc == {"v": dict.fromkeys(("x-", "x+", "y-", "y+"), "periodic")}
    combo = load({**GS, "boundaryConditions_1": "combo", "boundaryConditions_2": "neumann",
                  "comboStr_1": "Left: Dirichlet = 1; Right: Neumann = 0; Top: Periodic;"})
    assert combo.grid.bcs.y.kind == 1
    assert combo.bc == {"u": {"x-": ("value", "1"), "y-": "periodic", "y+": "periodic"}}
    # a flux given by a parameter (VisualPDE's thermal convection): kept as its name
    flux = load({**GS, "kineticParams": "F=0.04;k=0.06;T_b=0.5",
                 "boundaryConditions_2": "combo",
                 "comboStr_2": "Bottom: Neumann = T_b; Left: Periodic; Right: Periodic; "
                               "Top: Robin = 0.25 - 2*v;"})
    assert flux.bc == {"u": {"y-": "periodic", "y+": "periodic"},
                       "v": {"y-": ("neumann", "T_b"), "y+": ("robin", 2.0, 0.25)}}
    assert flux.grid.bcs.x.kind == 0 and flux.grid.bcs.y.kind == 1
    # values that read another species (VisualPDE's penguins hold T at S on the edge)
    held = load({**GS, "boundaryConditions_1": "dirichlet", "dirichletStr_1": "2*v",
                 "boundaryConditions_2": "robin", "robinStr_2": "u - v"})
    assert held.bc["u"]["x-"] == ("value", "2*v")
    kind, a, g = held.bc["v"]["x-"]  # ∂v/∂n = u − v: a = 1, g = u
    assert (kind, a) == ("robin", 1.0) and g.replace(" - 0.0", "").strip("()") == "u"
    res = held.simulation(backend="numpy", dtype="float64").run(5, progress=False)
    assert np.isfinite(res.fields["u"]).all()
    # a field held at its own value is not held at all (VisualPDE's static obstacles)
    static = load({**GS, "boundaryConditions_2": "dirichlet", "dirichletStr_2": "v"})
    assert "v" not in static.bc


def test_an_indicator_of_a_species_that_never_changes():
    """``domainIndicatorFun = "S < 1"`` with ``S`` static (no reaction, no diffusion): the
    mask is its initial condition's, fixed, and the edge holds ``T`` at ``S``."""
    tr = load({"numSpecies": 2, "speciesNames": "T S", "domainScale": "16",
               "spatialStep": "1", "diffusionStr_1_1": "1", "diffusionStr_2_2": "0",
               "reactionStr_1": "0", "reactionStr_2": "0", "dt": 0.1,
               "boundaryConditions_1": "dirichlet", "dirichletStr_1": "S",
               "boundaryConditions_2": "dirichlet",
               "initCond_2": "2*ind((x-8)^2 + (y-8)^2 < 9)",
               "domainViaIndicatorFun": True, "domainIndicatorFun": "S<1"})
    assert "S" not in tr.mask and tr.mask_bc["T"] == ("value", "S")
    res = tr.simulation(backend="numpy", dtype="float64").run(10, progress=False)
    c = (np.arange(16) + 0.5)
    inside = ((c[None] - 8) ** 2 + (c[:, None] - 8) ** 2 < 9)
    np.testing.assert_array_equal(res.mask.reshape(16, 16), ~inside)
    assert np.isfinite(res.fields["T"]).all()


def test_a_parameter_named_by_a_python_keyword():
    """``lambda`` runs as ``lambda_`` (rdgpu's language is Python's), said in the notes;
    the run is the one with the parameter so named."""
    tr = load({**GS, "kineticParams": "F = 0.03;k = 0.055;lambda = 2;lambda_ = 1;",
               "reactionStr_1": "-u*v^2 + F*(1.0 - u)*lambda/2"})
    assert tr.model.defaults["lambda__"] == 2.0 and tr.model.defaults["lambda_"] == 1.0
    assert "lambda__/2" in tr.model.equations["u"].replace(" ", "")
    assert any("'lambda' runs as 'lambda__'" in n for n in tr.notes)
    got = tr.simulation(backend="numpy", dtype="float64").run(30, progress=False).fields
    hand = rdgpu.Simulation(tr.model, Grid((64, 64), dx=1.0, bc="neumann"), {}, dt=tr.dt,
                            backend="numpy", dtype="float64", fields=tr.fields(),
                            options={"method": tr.method}, bc={"v": "periodic"})
    want = hand.run(30, progress=False).fields
    for s in ("u", "v"):
        np.testing.assert_array_equal(got[s], want[s])


def test_boundary_conditions_per_species_and_side():
    """VisualPDE's Dirichlet (face values), fluxes, linear Robin conditions and combos,
    translated side by side; a run holds a Dirichlet face value and feels a flux."""
    tr = load({**GS, "boundaryConditions_1": "combo", "boundaryConditions_2": "robin",
               "comboStr_1": "Left: Dirichlet = 1 + 0*t; Right: Neumann = 0.5; "
                             "Top: Robin = 2 - 3*u; Bottom: Neumann = 0;",
               "robinStr_2": "-F*v + x/L_x"})
    assert tr.grid.bcs.x.kind == 1 and tr.grid.bcs.y.kind == 1
    assert tr.bc["u"] == {"x-": ("value", "1 + 0*t"), "x+": ("neumann", "0.5"),
                          "y+": ("robin", 3.0, 2.0)}
    assert set(tr.bc["v"]) == {"x-", "x+", "y-", "y+"}
    kind, a, g = tr.bc["v"]["x+"]
    assert kind == "robin" and "F" in a and "x" in g
    # periodic along y for both, Dirichlet 1 on the left and 0 on the right for u
    heat = load({"numSpecies": 1, "diffusionStr_1_1": "1", "reactionStr_1": "0",
                 "domainScale": "16", "spatialStep": "1", "dt": 0.2, "initCond_1": "0",
                 "boundaryConditions_1": "combo",
                 "comboStr_1": "Left: Dirichlet = 1; Right: Dirichlet = 0; Top: Periodic; "
                               "Bottom: Periodic"})
    assert heat.grid.bcs.y.kind == 0 and heat.grid.bcs.x.kind == 1
    # VisualPDE's reading of a combo: a side not named is periodic, a part naming no side
    # is ignored (both noted); Ghost sets the ghost cell (rdgpu's own Dirichlet)
    same = load({"numSpecies": 1, "boundaryConditions_1": "combo", "reactionStr_1": "0",
                 "comboStr_1": "Left: Ghost = 2; Right: Dirichlet = 0; Neumann = 0"})
    assert same.grid.bcs.y.kind == 0
    assert same.bc == {"u": {"x-": ("dirichlet", "2"), "x+": ("value", "0")}}
    assert any("names no side" in n for n in same.notes)
    assert any("no condition on y-" in n for n in same.notes)
    u = heat.simulation(backend="numpy", dtype="float64").run(4000).fields["u"]
    x = (np.arange(16) + 0.5) / 16
    np.testing.assert_allclose(u, np.broadcast_to(1 - x, u.shape), atol=1e-6)
