"""Specs given to the ``Simulation`` Python API (domains, parameters, field specs, initial
conditions, options, run lengths, checkpoint paths, checkpoints' models): every bad one is
a clear ``TypeError``/``ValueError`` naming what was wrong, raised before any work -- never
a silent cast, truncation or no-op, a raw ``KeyError``/``AttributeError``/``MemoryError``,
or an error after the steps ran (issue 19: A3, A11, B, C)."""

from __future__ import annotations

import json
import os
import time

import numpy as np
import pytest

from rdgpu import ResourceLimitError
from rdgpu.domains.grid import Grid
from rdgpu.simulation.driver import Simulation

models = pytest.importorskip("rdgpu.models")

GRID = {"grid": 8}


def sim(**kw):
    kw.setdefault("backend", "numpy")
    return Simulation(kw.pop("model", "gray-scott"), kw.pop("domain", GRID),
                      kw.pop("params", None), **kw)


# --------------------------------------------------------------- A11, C: bad specs
RANDOM = {"kind": "random", "low": 0.01, "high": 0.05}


@pytest.mark.parametrize("kwargs, error, match", [
    # grids: strings, bools and fractions are not sizes (no silent (8,) or truncation)
    ({"domain": {"grid": "8"}}, TypeError, r"grid shape.*str '8'"),
    ({"domain": {"grid": (8.5, 8)}}, ValueError, r"grid shape.*whole numbers.*8\.5"),
    ({"domain": {"grid": True}}, TypeError, r"grid.*bool"),
    ({"domain": {"grid": (8, "8")}}, TypeError, r"grid.*str"),
    ({"domain": {"grid": 8, "dx": "1"}}, TypeError, r"dx must be a real number"),
    # parameters: bools and bytes are not numbers
    ({"params": {"F": True}}, TypeError, r"parameter 'F'.*bool"),
    ({"params": {"F": b"0.03"}}, TypeError, r"parameter 'F'.*bytes"),
    # field specs: missing, unknown, inverted or non-numeric values
    ({"params": {"F": {"kind": "random", "low": 0.01}}}, ValueError,
     r"parameter 'F'.*random.*needs 'high'"),
    ({"params": {"F": {"kind": "sine"}}}, ValueError, r"parameter 'F'.*sine.*needs 'mean'"),
    ({"params": {"F": {"kind": "linear", "start": 0.01}}}, ValueError, r"needs 'stop'"),
    ({"params": {"F": {**RANDOM, "low": 0.05, "high": 0.01}}}, ValueError,
     r"parameter 'F'.*low 0\.05 > high 0\.01"),
    ({"params": {"F": {**RANDOM, "low": "0.01"}}}, TypeError, r"parameter 'F'.*'low'.*str"),
    ({"params": {"F": {**RANDOM, "high": True}}}, TypeError, r"'high'.*bool"),
    ({"params": {"F": {**RANDOM, "high": float("inf")}}}, ValueError, r"'high'.*finite"),
    ({"params": {"F": {**RANDOM, "seed": 3}}}, ValueError,
     r"parameter 'F'.*unknown key\(s\) \['seed'\].*allowed"),
    ({"params": {"F": {"kind": "sine", "mean": 0.03, "amplitude": 0.01, "axis": 3}}},
     ValueError, r"axis"),
    ({"params": {"F": {"kind": "sine", "mean": 0.03, "amplitude": 0.01, "periods": "2"}}},
     TypeError, r"'periods'"),
    ({"params": {"F": {"low": 0.01}}}, ValueError, r"parameter 'F'.*kind"),
    # initial conditions
    ({"init": "random"}, TypeError, r"init must be a dict.*str 'random'"),
    ({"init": {"kind": "spots", "count": 2.7, "inside": 0.5}}, ValueError,
     r"init spots count must be a whole number >= 1, got 2\.7"),
    ({"init": {"kind": "spots", "count": True, "inside": 0.5}}, TypeError, r"count.*bool"),
    ({"init": {"kind": "square", "inside": 0.5, "center": (2.0, 2.0)}}, ValueError,
     r"init square center.*\[0, 1\].*\(2\.0, 2\.0\)"),
    ({"init": {"kind": "square", "inside": 0.5, "center": (0.5, -0.1)}}, ValueError,
     r"init square center"),
    ({"init": {"kind": "uniform", "values": {"u": "1"}}}, TypeError,
     r"init value of 'u' must be a real number, got str '1'"),
    ({"init": {"kind": "uniform", "values": {"u": True}}}, TypeError, r"bool"),
    # options
    ({"options": {"bogus": 1}}, ValueError, r"unknown option\(s\) \['bogus'\].*allowed.*method"),
    ({"options": {"method": "euler", "tol": -1}}, ValueError, r"tol must be a positive"),
    ({"options": {"method": "imex", "tol": -1}}, ValueError, r"tol must be a positive"),
    ({"options": {"method": "imex", "tol": "1e-6"}}, TypeError, r"tol"),
    ({"options": {"method": "euler", "tol": 1e-6}}, ValueError,
     r"tol.*method 'euler'.*explicit.*does not use"),
    ({"options": {1: 2}}, TypeError, r"option names"),
    ({"options": {"dt": 0.5}}, ValueError, r"\['dt'\] are Simulation's own arguments"),
    # models and presets
    ({"model": None}, TypeError, r"model must be a model name.*or a Model.*NoneType"),
    ({"model": 5}, TypeError, r"model must be .*int"),
])
def test_bad_specs_are_clear_errors(kwargs, error, match):
    with pytest.raises(error, match=match):
        sim(**kwargs)


def test_from_preset_with_a_non_name():
    with pytest.raises(TypeError, match=r"preset must be a preset name.*int 5"):
        Simulation.from_preset(5)


@pytest.mark.parametrize("shape, error", [("8", TypeError), ((8.5, 8), ValueError),
                                          ((True, 8), TypeError), (8, TypeError)])
def test_grid_shapes_are_whole_numbers(shape, error):
    with pytest.raises(error, match="grid shape"):
        Grid(shape)


def test_whole_floats_and_numpy_ints_still_make_grids():
    assert Grid((8.0, np.int64(6))).shape == (8, 6)
    assert sim(domain={"grid": (8.0, 8)}).shape == (8, 8)


def test_good_field_specs_still_work():
    s = sim(params={"F": RANDOM, "k": {"kind": "sine", "mean": 0.06, "amplitude": 0.001}})
    assert 0.01 <= s.params["F"].min() and s.params["F"].max() <= 0.05
    assert s.params["k"].shape == (8, 8)
    # low == high is a constant field, not an error
    assert np.all(sim(params={"F": {**RANDOM, "high": 0.01}}).params["F"] == 0.01)


def test_a_square_at_the_edge_still_sets_cells():
    s = sim(init={"kind": "square", "values": {"u": 1.0, "v": 0.0}, "inside": {"v": 0.5},
                  "center": (1.0, 0.0)})
    assert s.state()["v"].max() == np.float32(0.5)


def test_spots_need_no_more_than_one_per_cell():
    with pytest.raises(ValueError, match=r"count 65.*64 cells"):
        sim(init={"kind": "spots", "count": 65, "inside": 0.5})


# ------------------------------------------------------------ B: huge requests, refused
@pytest.fixture
def small_machine(monkeypatch):
    monkeypatch.setenv("RDGPU_MEMORY_LIMIT", "1G")


@pytest.mark.parametrize("kwargs", [
    {"members": 10**9},
    {"domain": {"grid": 10**6}},
    {"domain": {"grid": (10**4, 10**4, 10**4)}},
])
def test_huge_simulations_are_refused_before_allocating(small_machine, kwargs):
    t0 = time.perf_counter()
    with pytest.raises(ResourceLimitError, match=r"needs about .* of memory.*this machine has"):
        sim(**kwargs)
    assert time.perf_counter() - t0 < 5


def test_a_billion_spots_are_refused(small_machine):
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"count 1000000000"):
        sim(init={"kind": "spots", "count": 10**9, "inside": 0.5})
    assert time.perf_counter() - t0 < 5


def test_snapshot_storage_is_estimated_before_the_run(small_machine):
    s = sim()
    with pytest.raises(ResourceLimitError, match=r"snapshots"):
        s.run(10**15, snapshot_every=1, progress=False)
    assert s.step == 0


@pytest.mark.parametrize("steps", [1e20, 10**20, 2**53 + 1])
def test_absurd_step_counts_are_refused(steps):
    s = sim()
    with pytest.raises(ValueError, match=r"steps"):
        s.run(steps, progress=False)
    assert s.step == 0


# ---------------------------------------------------- C: checkpoint paths, checked first
@pytest.fixture
def a_file(tmp_path):
    p = tmp_path / "plain.txt"
    p.write_text("x")
    return p


def _fifo(folder):
    """A path that exists and is no regular file (a named pipe: never a real device node
    here, which a regression would replace)."""
    p = folder / "pipe.npz"
    os.mkfifo(p)
    return p


@pytest.mark.parametrize("make, match", [
    (lambda d, f: d, r"is a folder; give a file name"),
    (lambda d, f: "", r"checkpoint.*empty"),
    (lambda d, f: str(d / "a\0b.npz"), r"NUL"),
    (lambda d, f: f / "c.npz", r"is not a folder"),
    (lambda d, f: d / ("x" * 300 + ".npz"), r"file name is 304 bytes long"),
    (lambda d, f: d / ("x" * 240 + ".npz"), r"temporary file"),
    (lambda d, f: _fifo(d), r"exists and is .*not a regular file"),
])
def test_bad_checkpoint_paths_fail_before_the_run(tmp_path, a_file, make, match):
    path = make(tmp_path, a_file)
    s = sim()
    with pytest.raises(ValueError, match=match) as info:
        s.run(30, checkpoint=path, checkpoint_every=10, progress=False)
    assert s.step == 0  # refused before any step
    if str(path):
        assert repr(str(path))[1:20] in str(info.value) or str(path)[:20] in str(info.value)


def test_a_missing_checkpoint_folder_is_still_made(tmp_path):
    ck = tmp_path / "new" / "folder" / "c.npz"
    sim().run(10, checkpoint=ck, progress=False)
    assert ck.is_file()


# -------------------------------------------------- A11: checkpoint metadata checked
def _rewrite_meta(src, dst, **changes):
    with np.load(src) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["meta"]))
    for k, v in changes.items():
        if k.startswith("run_"):
            meta["run"][k[4:]] = v
        else:
            meta[k] = v
    arrays["meta"] = np.array(json.dumps(meta))
    np.savez(dst, **arrays)


@pytest.fixture(scope="module")
def good_checkpoint(tmp_path_factory):
    d = tmp_path_factory.mktemp("ck")
    ck = d / "good.npz"
    sim().run(20, checkpoint=ck, checkpoint_every=10, progress=False)
    return ck


@pytest.mark.parametrize("changes, match", [
    ({"step": -5}, r"'step'.*-5"),
    ({"time": -5.0}, r"'time'"),
    ({"time": 1e9}, r"'time'.*step"),
    ({"dt": -1.0}, r"'dt'"),
    ({"run_start": -1}, r"run settings.*start"),
    ({"run_target": 5}, r"step 20.*past.*target 5"),
    ({"run_snapshot_every": 2.5}, r"snapshot_every"),
    ({"run_check_every": -1}, r"check_every"),
    ({"run_start": 30}, r"start 30.*after.*step 20"),
])
def test_checkpoint_run_metadata_is_checked(good_checkpoint, tmp_path, changes, match):
    bad = tmp_path / "bad.npz"
    _rewrite_meta(good_checkpoint, bad, **changes)
    with pytest.raises(ValueError, match=match) as info:
        Simulation.resume(bad)
    assert str(bad) in str(info.value)
    with pytest.raises(ValueError, match=match):
        sim().run(40, resume=bad, progress=False)


# ------------------------------------------- A3: a checkpoint's equations always win
DECAY = {"u": "-0.5*u", "v": "-0.5*v"}


def _impostor():
    """A user model that takes a built-in's name, with other equations."""
    return models.define_model("gray-scott", DECAY, {"Du": 0.16, "Dv": 0.08, "F": 0.035,
                                                     "k": 0.06})


def _user_sim(**kw):
    kw.setdefault("dt", 0.1)
    return sim(model=_impostor(), **kw)


@pytest.fixture
def user_checkpoint(tmp_path):
    ck = tmp_path / "user.npz"
    _user_sim().run(20, checkpoint=ck, checkpoint_every=10, progress=False)
    return ck


def test_a_user_model_with_a_builtin_name_resumes_as_itself(user_checkpoint):
    ref = _user_sim().run(40, progress=False)
    resumed = Simulation.resume(user_checkpoint)
    assert resumed.model.equations == DECAY
    assert resumed.model is not models.MODELS["gray-scott"]
    res = resumed.run(40, progress=False)  # steps count from the interrupted call's start
    assert res.step == 40
    np.testing.assert_array_equal(res.fields["u"], ref.fields["u"])


def test_a_builtin_model_passed_against_user_equations_is_refused(user_checkpoint):
    with pytest.raises(ValueError, match=r"equation of 'u'.*-0\.5\*u.*Du\*laplace"):
        Simulation.resume(user_checkpoint, model=models.MODELS["gray-scott"])
    with pytest.raises(ValueError, match=r"equation of 'u'"):
        sim(dt=0.1).run(40, resume=user_checkpoint, progress=False)


def test_user_equations_against_a_builtin_checkpoint_are_refused(tmp_path):
    ck = tmp_path / "builtin.npz"
    sim(dt=0.1).run(20, checkpoint=ck, checkpoint_every=10, progress=False)
    with pytest.raises(ValueError, match=r"equation of 'u'"):
        Simulation.resume(ck, model=_impostor())
    with pytest.raises(ValueError, match=r"equation of 'u'"):
        _user_sim().run(40, resume=ck, progress=False)
    # the built-in itself still resumes
    assert Simulation.resume(ck).run(progress=False).step == 20


def test_the_same_user_model_passed_explicitly_resumes(user_checkpoint):
    s = Simulation.resume(user_checkpoint, model=_impostor())
    assert s.model.equations == DECAY
    assert _user_sim().run(20, resume=user_checkpoint, progress=False).step == 20


# ---------------------------------------------------------------- the same, from the CLI
def test_the_cli_resumes_a_user_model_with_a_builtin_name_as_itself(tmp_path, monkeypatch):
    from rdgpu.cli.app import main

    monkeypatch.chdir(tmp_path)
    base = ["run", "gray-scott", "--equation", "u=-0.5*u", "--equation", "v=-0.5*v",
            "--size", "8", "--dt", "0.1", "--backend", "numpy", "--quiet"]
    assert main([*base, "--steps", "20", "--checkpoint", "ck.npz", "--data", "a.npz"]) == 0
    assert main(["run", "gray-scott", "--resume", "ck.npz", "--steps", "40", "--backend",
                 "numpy", "--quiet", "--data", "b.npz"]) == 0
    assert main([*base, "--steps", "40", "--data", "c.npz"]) == 0  # uninterrupted
    with np.load(tmp_path / "b.npz") as b, np.load(tmp_path / "c.npz") as c:
        assert json.loads(str(b["meta"]))["step"] == 40
        for s in ("u", "v"):
            np.testing.assert_array_equal(b[f"final_{s}"], c[f"final_{s}"])


def test_a_user_model_with_a_field_spec_default_resumes_as_itself(tmp_path):
    """Defaults the checkpoint cannot keep as numbers (a field spec) still leave the
    equations in it, so the resumed model is the user's, not the built-in of its name."""
    model = models.define_model("gray-scott", DECAY, {
        "Du": 0.16, "Dv": 0.08, "F": {"kind": "random", "low": 0.01, "high": 0.05},
        "k": 0.06})
    ck = tmp_path / "spec.npz"
    ref = sim(model=model, dt=0.1).run(40, progress=False)
    sim(model=model, dt=0.1).run(20, checkpoint=ck, progress=False)
    resumed = Simulation.resume(ck)
    assert resumed.model.equations == DECAY
    res = resumed.run(40, progress=False)
    np.testing.assert_array_equal(res.fields["v"], ref.fields["v"])


def test_the_model_layer_checks_specs_and_tol_itself():
    """The checks sit where the values are used (param_field, the model stepper), so the
    model layer called directly refuses the same specs."""
    gs = models.MODELS["gray-scott"]
    grid = Grid((8, 8))
    with pytest.raises(ValueError, match=r"parameter 'F'.*needs 'high'"):
        models.resolve_params(gs, grid, {"F": {"kind": "random", "low": 0.01}})
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['bogus'\]"):
        models.param_field({**RANDOM, "bogus": 1}, grid, np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"tol must be a positive number"):
        gs.stepper(grid, dt=1.0, backend="numpy", method="imex", tol=-1)
    with pytest.raises(ValueError, match=r"tol must be a positive number"):
        gs.stepper(grid, dt=1.0, backend="numpy", method="heun", tol=-1)


def test_recorded_equations_equal_to_the_builtins_resume_the_builtin(tmp_path):
    """A user model that is the built-in in all but identity (same equations, spacing
    aside, same defaults) resumes as the built-in itself, its display range kept."""
    gs = models.MODELS["gray-scott"]
    twin = models.define_model("gray-scott", {s: e.replace("*", " * ")
                                              for s, e in gs.equations.items()},
                               dict(gs.defaults))
    ck = tmp_path / "twin.npz"
    sim(model=twin).run(20, checkpoint=ck, progress=False)
    assert Simulation.resume(ck).model is gs
