"""The simulation driver: initial conditions, snapshots, divergence checks, checkpoints and
kill-and-resume (``rdgpu.simulation``).

The driver is tested against a small Gray-Scott model defined here (``ToyGrayScott``, a
ping-pong stepper over ``backend.gray_scott``), so these tests do not depend on
``rdgpu.models``.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import backend_or_skip, interrupt_after

import rdgpu
from rdgpu.core import files
from rdgpu.core.errors import SimulationDiverged, StabilityError
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.simulation import (
    Simulation,
    SimulationInterrupted,
    initial_state,
    remove_stale_temporaries,
    runner,
)

HERE = Path(__file__).resolve()
ROOT = Path(rdgpu.__file__).resolve().parents[1]


from toy_model import SQUARE, TOY, ToyGrayScott, ToyStepper, toy_sim  # noqa: E402,F401


def assert_same_result(a, b):
    assert a.step == b.step
    np.testing.assert_array_equal(a.snapshot_steps, b.snapshot_steps)
    np.testing.assert_array_equal(a.times, b.times)
    for s in a.fields:
        np.testing.assert_array_equal(a.fields[s], b.fields[s])
        np.testing.assert_array_equal(a.snapshots[s], b.snapshots[s])


# ------------------------------------------------------------------- initial conditions
GRID = Grid((40, 50))


@pytest.fixture(scope="module")
def sphere():
    pytest.importorskip("trimesh")
    return SurfaceMesh.icosphere(2)


INITS = [
    {"kind": "uniform", "values": {"u": 1.0, "v": 0.0}, "noise": 0.05},
    SQUARE,
    {"kind": "spots", "values": {"u": 1.0}, "inside": {"u": 0.5, "v": 0.25}, "count": 5,
     "radius": 3, "noise": 0.01},
    {"kind": "patch", "values": {"u": 1.0}, "patch": {"u": "random", "v": [0.2, 0.3]},
     "radius": 0.2},
]


@pytest.mark.parametrize("init", INITS, ids=lambda d: d["kind"])
@pytest.mark.parametrize("where", ["grid", "mesh"])
def test_initial_state_is_seeded_and_reproducible(init, where, sphere):
    domain = GRID if where == "grid" else sphere
    shape = GRID.shape if where == "grid" else (sphere.n_vertices,)
    a = initial_state(init, domain, ("u", "v"), seed=7)
    b = initial_state(init, domain, ("u", "v"), seed=7)
    c = initial_state(init, domain, ("u", "v"), seed=8)
    assert set(a) == {"u", "v"}
    for s in "uv":
        assert a[s].shape == shape and a[s].dtype == np.float64
        np.testing.assert_array_equal(a[s], b[s])
    if init["kind"] != "square":  # square without noise on v would be seed independent
        assert not np.array_equal(a["u"], c["u"])
    f32 = initial_state(init, domain, ("u", "v"), seed=7, dtype=np.float32)
    for s in "uv":
        assert f32[s].dtype == np.float32
        np.testing.assert_array_equal(f32[s], a[s].astype(np.float32))


def test_initial_state_values():
    sq = initial_state({**SQUARE, "noise": 0.0}, GRID, ("u", "v"))
    inside = sq["v"] == 0.25
    assert 0.02 < inside.mean() < 0.06  # 20% of each side -> 4% of the cells
    rows, cols = np.nonzero(inside)
    assert abs(rows.mean() - 19.5) <= 1 and abs(cols.mean() - 24.5) <= 1  # central
    assert np.all(sq["u"][inside] == 0.5) and np.all(sq["u"][~inside] == 1.0)

    noisy = initial_state({"kind": "uniform", "values": 1.0, "noise": 0.05}, GRID, ("u",))
    assert np.abs(noisy["u"] - 1.0).max() <= 0.05 and noisy["u"].std() > 0.01

    spots = initial_state({"kind": "spots", "values": 0.0, "inside": {"v": 1.0}, "count": 1,
                           "radius": 3}, Grid((30, 30)), ("u", "v"))
    assert spots["u"].max() == 0 and spots["v"].sum() == 29  # one disc of radius 3: 29 cells

    patch = initial_state({"kind": "patch", "values": {"u": 1.0}, "patch": {"u": "random"},
                           "radius": 0.2}, GRID, ("u",), seed=3)
    touched = patch["u"] != 1.0
    assert 0.02 < touched.mean() < 0.5  # localized
    assert patch["u"][touched].min() >= -1 and patch["u"][touched].max() <= 1


def test_patch_is_localized_on_a_mesh(sphere):
    f = initial_state({"kind": "patch", "values": {"u": 0.0}, "patch": {"u": 0.7},
                       "radius": 0.3}, sphere, ("u",), seed=0)["u"]
    V = np.asarray(sphere.vertices)
    inside = f == 0.7
    assert 0.02 < inside.mean() < 0.6
    c = V[inside].mean(axis=0)
    assert np.linalg.norm(V[inside] - V[inside][0], axis=1).max() <= 2 * 0.6 + 1e-9
    assert np.linalg.norm(c) > 0.3  # a cap, not spread over the sphere


@pytest.mark.parametrize("init, match", [
    ({"kind": "blob"}, "unknown init kind"),
    ({"kind": "uniform", "nosie": 0.1}, "unknown option"),
    ({"kind": "uniform", "values": {"w": 1.0}}, "unknown species"),
    ({"kind": "square", "values": 1.0}, "needs 'inside'"),
    ({"kind": "square", "inside": 1.0, "size": 2}, "fraction"),
    ({"kind": "patch", "patch": {"u": "noise"}}, "'random'"),
])
def test_bad_init_is_a_clear_error(init, match):
    with pytest.raises(ValueError, match=match):
        initial_state(init, GRID, ("u", "v"))


@pytest.mark.parametrize("name", ["numpy", "warp", "opencl"])
def test_same_initial_state_on_every_backend(name):
    be = backend_or_skip(name)
    ref = initial_state(SQUARE, Grid((32, 32)), ("u", "v"), seed=5, dtype=np.float32)
    sim = toy_sim(be, seed=5)
    got = sim.state()
    for s in "uv":
        np.testing.assert_array_equal(got[s], ref[s])
    res = sim.run(20, progress=False)
    ref_run = toy_sim("numpy", seed=5).run(20, progress=False)
    for s in "uv":
        np.testing.assert_allclose(res.fields[s], ref_run.fields[s], rtol=1e-5, atol=1e-6)
    assert res.backend == be.name and res.device == be.device and res.dtype == "float32"


# ------------------------------------------------------------------------- the driver
def test_snapshots_and_result():
    sim = toy_sim(seed=1)
    res = sim.run(55, snapshot_every=10, progress=False)
    np.testing.assert_array_equal(res.snapshot_steps, [0, 10, 20, 30, 40, 50, 55])
    np.testing.assert_allclose(res.times, res.snapshot_steps * 1.0)
    assert res.snapshots["v"].shape == (7, 32, 32)
    np.testing.assert_array_equal(res.snapshots["v"][-1], res.fields["v"])
    assert res.step == 55 and res.time == 55.0 and sim.step == 55
    assert res.params == {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.060}
    assert res.model == "toy-gray-scott" and res.seed == 1
    assert {"numpy", "warp", "pyopencl", "rdgpu"} <= set(res.versions)

    # each snapshot equals a run stopped there
    other = toy_sim(seed=1)
    for i, k in enumerate(res.snapshot_steps):
        if k:
            other.run(int(k - other.step), progress=False)
        np.testing.assert_array_equal(other.state()["u"], res.snapshots["u"][i])


def test_snapshot_batches_do_not_change_results(monkeypatch):
    ref = toy_sim(seed=2).run(60, snapshot_every=5, progress=False)
    monkeypatch.setattr(runner, "_SNAPSHOT_BUDGET", 1)  # one snapshot per device batch
    small = toy_sim(seed=2).run(60, snapshot_every=5, progress=False)
    assert_same_result(ref, small)


def test_snapshots_stay_on_the_device_between_writes(monkeypatch):
    """Between steps only checks download; snapshots are device copies until flushed."""
    sim = toy_sim(seed=3)
    be = sim.backend
    downloads, copies = [], []
    real_download, real_copy = be.download, be.copy
    monkeypatch.setattr(be, "download", lambda d: downloads.append(1) or real_download(d))
    monkeypatch.setattr(be, "copy", lambda a, b: copies.append(1) or real_copy(a, b))
    sim.run(100, snapshot_every=10, check_every=0, progress=False)
    assert len(copies) == 2 * 11  # 11 snapshots of 2 species, all device-to-device
    assert len(downloads) == 2 * 11 + 2  # one batch download of the snapshots + final state


def test_chunking_does_not_change_arithmetic():
    whole = toy_sim(seed=4).run(250, check_every=0, progress=False)
    sim = toy_sim(seed=4)
    for n in (1, 37, 100, 112):
        sim.run(n, check_every=7, progress=False)
    for s in "uv":
        np.testing.assert_array_equal(whole.fields[s], sim.state()[s])


def test_unstable_dt_is_refused_unless_asked():
    with pytest.raises(StabilityError, match="stability limit"):
        toy_sim(dt=5.0)


def test_divergence_names_step_field_and_cause():
    sim = toy_sim(dt=5.0, check_stability=False, seed=0)
    with pytest.raises(SimulationDiverged) as info:
        sim.run(400, snapshot_every=2, check_every=50, progress=False)
    exc = info.value
    msg = str(exc)
    assert f"step {exc.step}" in msg and f"field {exc.field!r}" in msg
    assert "dt=5 is past the stability limit 1.56" in msg
    assert 0 < exc.step <= 400 and exc.field in ("u", "v")
    res = exc.result
    assert res.diverged == msg
    # the kept state is the last good one: finite, one step before the first bad step
    assert res.step == exc.step - 1 == sim.step
    for s in "uv":
        assert np.isfinite(res.fields[s]).all() and np.abs(res.fields[s]).max() <= 1e6
        np.testing.assert_array_equal(sim.state()[s], res.fields[s])
    assert len(res.snapshot_steps) and res.snapshot_steps[-1] <= res.step
    assert np.isfinite(res.snapshots["u"]).all()
    # replaying confirms the step named is the first bad one
    replay = toy_sim(dt=5.0, check_stability=False, seed=0)
    replay.run(exc.step - 1, check_every=0, progress=False)
    ok = replay.state()
    replay.run(1, check_every=0, progress=False)
    bad = replay.state()
    assert all(np.isfinite(ok[s]).all() and np.abs(ok[s]).max() <= 1e6 for s in "uv")
    assert not (np.isfinite(bad[exc.field]).all() and np.abs(bad[exc.field]).max() <= 1e6)


def test_divergence_within_the_limit_points_at_parameters():
    sim = toy_sim(params={"F": -5.0}, seed=0)  # u <- 6u - 5: exponential blow-up
    with pytest.raises(SimulationDiverged, match="check the parameters") as info:
        sim.run(200, check_every=20, progress=False)
    assert "blow-up bound" in str(info.value) or "NaN" in str(info.value)


def test_unknown_parameter_is_a_clear_error():
    with pytest.raises(ValueError, match="unknown parameter"):
        toy_sim(params={"Q": 1.0})


# ---------------------------------------------------------------------- checkpoints
def test_checkpoint_is_atomic(tmp_path, monkeypatch):
    ck = tmp_path / "run.ckpt.npz"
    sim = toy_sim(seed=6)
    sim.run(100, checkpoint=ck, checkpoint_every=50, progress=False)
    meta, arrays = Simulation.read_checkpoint(ck)
    assert meta["step"] == 100 and meta["model"] == "toy-gray-scott"
    assert meta["params"]["F"] == 0.035 and meta["domain"]["shape"] == [32, 32]
    assert meta["run"] == {"start": 0, "target": 100, "snapshot_every": 0, "check_every": 200,
                           "checkpoint_every": 50}
    np.testing.assert_array_equal(arrays["field__u"], sim.state()["u"])
    before = ck.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == [ck.name]

    # a write that fails half-way leaves the old checkpoint and no temporary file
    def broken(fh, **arrays):
        fh.write(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", broken)
    with pytest.raises(OSError, match="disk full"):
        sim.run(50, checkpoint=ck, checkpoint_every=50, progress=False)
    assert ck.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [ck.name]


def test_checkpoint_goes_through_replace(tmp_path, monkeypatch):
    replaced = []
    real = os.replace
    monkeypatch.setattr(os, "replace", lambda a, b: replaced.append((a, b)) or real(a, b))
    ck = tmp_path / "c.npz"
    toy_sim().run(20, checkpoint=ck, checkpoint_every=10, progress=False)
    assert len(replaced) == 2 and all(Path(b) == ck and Path(a).parent == tmp_path
                                      for a, b in replaced)


class Interrupt(Exception):
    pass


@pytest.mark.parametrize("name", ["numpy", "warp", "opencl"])
def test_resume_after_interruption_is_bitwise_identical(name, tmp_path):
    be = backend_or_skip(name)
    settings = {"snapshot_every": 30, "check_every": 40, "checkpoint_every": 50,
                "progress": False}
    ref = toy_sim(be, seed=9).run(260, **settings)

    sim = toy_sim(be, seed=9)
    real = sim.stepper.advance
    done = [0]

    def dying(n):
        if done[0] + n > 170:  # dies between the checkpoints at 150 and 200
            raise Interrupt
        done[0] += n
        real(n)

    sim.stepper.advance = dying
    ck = tmp_path / "ck.npz"
    with pytest.raises(Interrupt):
        sim.run(260, checkpoint=ck, **settings)
    assert Simulation.read_checkpoint(ck)[0]["step"] == 150

    again = toy_sim(be, seed=9).run(260, resume=ck, **settings)
    assert_same_result(ref, again)
    # Simulation.resume restores everything from the file alone
    restored = Simulation.resume(ck, model=TOY)
    assert restored.step == 260 and restored.backend.device == be.device  # final checkpoint
    later = Simulation.resume(ck, model=TOY).run()
    assert_same_result(ref, later)


_CHILD = """
import importlib.util, sys, time
spec = importlib.util.spec_from_file_location("toy", {test!r})
toy = importlib.util.module_from_spec(spec); spec.loader.exec_module(toy)
sim = toy.toy_sim("numpy", seed=11)
real = sim.stepper.advance
def slow(n):
    time.sleep(0.02)
    real(n)
sim.stepper.advance = slow
sim.run(3000, snapshot_every=250, check_every=100, checkpoint={ck!r}, checkpoint_every=100,
        progress=False)
print("finished")
"""


def test_kill_and_resume(tmp_path):
    """SIGKILL a subprocess after its first checkpoint; resuming gives the same result as
    an uninterrupted run, bit for bit."""
    ck = tmp_path / "killed.npz"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), str(HERE.parents[1]), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-c", _CHILD.format(test=str(HERE), ck=str(ck))],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 60
        while not ck.exists():
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no checkpoint after 60 s"
            time.sleep(0.01)
        time.sleep(0.15)  # let it run on a bit: killed at an arbitrary moment
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait(30)
    assert proc.returncode == -signal.SIGKILL
    meta, _ = Simulation.read_checkpoint(ck)
    assert 100 <= meta["step"] < 3000 and meta["step"] % 100 == 0

    resumed = Simulation.resume(ck, model=TOY).run(progress=False)
    ref = toy_sim("numpy", seed=11).run(3000, snapshot_every=250, check_every=100,
                                        progress=False)
    assert_same_result(ref, resumed)
    assert len(ref.snapshot_steps) == 13


def test_resume_rejects_another_simulation(tmp_path):
    ck = tmp_path / "c.npz"
    toy_sim(seed=1).run(20, checkpoint=ck, checkpoint_every=10, progress=False)
    with pytest.raises(ValueError, match="other parameters"):
        toy_sim(params={"F": 0.03}).run(40, resume=ck)
    with pytest.raises(ValueError, match="dt="):
        toy_sim(dt=0.5).run(40, resume=ck)
    with pytest.raises(ValueError, match="does not exist"):
        toy_sim().run(40, resume=tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match="not a readable"):
        toy_sim().run(40, resume=tmp_path / "junk.npz")


# ------------------------------------------------------------- with the real models
def test_mesh_run_with_a_field_parameter_resumes_bitwise(tmp_path):
    models = pytest.importorskip("rdgpu.models")
    pytest.importorskip("trimesh")
    mesh = SurfaceMesh.icosphere(2)
    b = np.where(np.asarray(mesh.vertices)[:, 2] > 0, -0.1, 0.1)
    init = {"kind": "patch", "values": {"u": 1.0}, "patch": {"u": "random"}, "radius": 0.4}

    def make():
        return Simulation(models.MODELS["allen-cahn"], mesh, {"b": b, "eps": 0.3},
                          backend="numpy", dtype="float64", seed=2, init=init)

    settings = {"snapshot_every": 25, "check_every": 20, "checkpoint_every": 40,
                "progress": False}
    ref = make().run(130, **settings)
    sim = make()
    interrupt_after(sim, 90, Interrupt)
    with pytest.raises(Interrupt):
        sim.run(130, checkpoint=tmp_path / "m.npz", **settings)
    resumed = Simulation.resume(tmp_path / "m.npz")  # model looked up by name
    assert resumed.step == 80 and resumed.domain.n_vertices == mesh.n_vertices
    np.testing.assert_array_equal(resumed.params["b"], b)
    assert_same_result(ref, resumed.run(progress=False))


def test_from_preset(tmp_path):
    models = pytest.importorskip("rdgpu.models")
    preset = models.Preset(
        name="tiny", model="gray-scott", params={"F": 0.03, "k": 0.055}, dt=1.0, steps=40,
        domain={"grid": (16, 16)}, init=SQUARE, source="a test", expect="spots",
        snapshot_every=10, seed=5,
    )
    sim = Simulation.from_preset(preset, backend="numpy")
    assert sim.params["F"] == 0.03 and sim.seed == 5 and sim.domain.shape == (16, 16)
    res = sim.run(progress=False)
    assert res.step == 40 and list(res.snapshot_steps) == [0, 10, 20, 30, 40]
    other = Simulation.from_preset(preset, backend="numpy", params={"k": 0.06}, seed=1,
                                   domain={"grid": (8, 12)})
    assert other.params == {**sim.params, "k": 0.06} and other.shape == (8, 12)


# ------------------------------------------------ checkpoints hold only checked states
def test_a_diverging_run_never_checkpoints_a_bad_state(tmp_path):
    """The issue's case: checkpoints every 50 steps, checks every 200, divergence at step 4:
    the checkpoint at step 50 used to hold NaN.  Now every state written is checked first;
    an earlier good checkpoint at that path is kept as it was."""
    models = pytest.importorskip("rdgpu.models")
    ck = tmp_path / "p.npz"
    with pytest.raises(SimulationDiverged) as info:
        Simulation("gray-scott", {"grid": 32}, dt=10.0, check_stability=False,
                   backend="numpy").run(1000, checkpoint=ck, checkpoint_every=50,
                                        progress=False)
    assert info.value.step == 4 and models.MODELS["gray-scott"].name in str(info.value)
    assert not ck.exists()

    toy_sim(seed=1).run(100, checkpoint=ck, checkpoint_every=50, progress=False)
    before = ck.read_bytes()
    for check_every in (200, 0):
        with pytest.raises(SimulationDiverged):
            toy_sim(dt=5.0, check_stability=False).run(
                400, checkpoint=ck, checkpoint_every=25, check_every=check_every,
                progress=False)
        assert ck.read_bytes() == before
        meta, arrays = Simulation.read_checkpoint(ck)
        assert meta["step"] == 100 and np.isfinite(arrays["field__u"]).all()


def test_checkpoints_between_checks_are_checked(tmp_path, monkeypatch):
    """Checkpoints at steps that are no multiple of check_every: each one is checked, on
    exactly the state that is written."""
    checked, written = [], []
    real_bad, real_write = runner.Runner.find_bad, runner.Runner.write_checkpoint

    def find_bad(self, state):
        checked.append({s: a.copy() for s, a in state.items()})
        return real_bad(self, state)

    def write(self, state):
        written.append(state)
        assert any(all(np.array_equal(c[s], state[s]) for s in state) for c in checked)
        return real_write(self, state)

    monkeypatch.setattr(runner.Runner, "find_bad", find_bad)
    monkeypatch.setattr(runner.Runner, "write_checkpoint", write)
    toy_sim().run(90, check_every=40, checkpoint=tmp_path / "c.npz", checkpoint_every=30,
                  progress=False)
    assert len(written) == 3  # steps 30, 60, 90


# ---------------------------------------------------- resume refuses another domain
@pytest.mark.parametrize("domain, fragments", [
    (Grid((16, 16), bc="neumann", dx=2.0),
     ["dx 1.0 in the checkpoint, 2.0 here", "dy 1.0 in the checkpoint, 2.0 here",
      "bc periodic in the checkpoint, neumann here"]),
    (Grid((16, 16), dy=0.5), ["dy 1.0 in the checkpoint, 0.5 here"]),
    (Grid((16, 16), bc=("periodic", ("dirichlet", 0.0))),
     ["bc periodic in the checkpoint, periodic (y)/dirichlet(0) (x) here"]),
    (Grid((16, 20)), ["shape 16x16 in the checkpoint, 16x20 here"]),
])
def test_resume_refuses_another_domain(tmp_path, domain, fragments):
    ck = tmp_path / "c.npz"
    toy_sim(shape=(16, 16)).run(20, checkpoint=ck, progress=False)
    other = Simulation(TOY, domain, dt=0.1, backend="numpy")
    other.dt = 1.0  # the same dt as the checkpoint's: only the domain differs
    with pytest.raises(ValueError, match="was written on another domain") as info:
        other.run(40, resume=ck)
    for text in fragments:
        assert text in str(info.value)
    assert other.step == 0


def test_resume_refuses_another_mesh(tmp_path):
    models = pytest.importorskip("rdgpu.models")
    pytest.importorskip("trimesh")
    ac = models.MODELS["allen-cahn"]
    ck = tmp_path / "m.npz"
    params = {"eps": 0.3}
    Simulation(ac, SurfaceMesh.icosphere(2), params, dt=1e-3, backend="numpy").run(
        5, checkpoint=ck, progress=False)
    for mesh, text in ((SurfaceMesh.icosphere(2, radius=1.5), "vertex positions differ"),
                       (SurfaceMesh.icosphere(1), "162 vertices and 320 faces in the "
                                                  "checkpoint, 42 vertices and 80 faces here")):
        with pytest.raises(ValueError, match=text):
            Simulation(ac, mesh, params, dt=1e-3, backend="numpy").run(10, resume=ck)
    ok = Simulation(ac, SurfaceMesh.icosphere(2), params, dt=1e-3, backend="numpy")
    assert ok.run(10, resume=ck, progress=False).step == 10


# ----------------------------------------------------------- stale temporary files
def _dead_pid():
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_killed_writers_temporaries_are_removed(tmp_path):
    ck = tmp_path / "run.npz"
    host = files._host_tag()
    dead = _dead_pid()
    old = time.time() - 2 * 3600
    names = {
        "stale": f".run.npz.{host}.{dead}.k2j4h1xx.tmp",  # a killed writer's: removed
        "live": f".run.npz.{host}.{os.getpid()}.abcdefgh.tmp",  # a live writer's: kept
        "remote": f".run.npz.otherhost.{dead}.abcdefgh.tmp",  # another machine's: kept
        "other file": f".run.npz.bak.{host}.{dead}.abcdefgh.tmp",  # run.npz.bak's: kept
        "legacy old": ".run.npz.q1w2e3r4.tmp",  # no writer id, 2 h old: removed
        "legacy new": ".run.npz.z9x8c7v6.tmp",  # no writer id, fresh: kept
        "unrelated": "notes.tmp",
    }
    for key, name in names.items():
        (tmp_path / name).write_bytes(b"x" * 1000)
        if key == "legacy old":
            os.utime(tmp_path / name, (old, old))
    toy_sim().run(20, checkpoint=ck, checkpoint_every=10, progress=False)
    left = {p.name for p in tmp_path.iterdir()}
    assert names["stale"] not in left and names["legacy old"] not in left
    assert {names[k] for k in ("live", "remote", "other file", "legacy new", "unrelated")} \
        <= left
    assert ck.name in left

    # on resume too
    (tmp_path / names["stale"]).write_bytes(b"x")
    Simulation.resume(ck, model=TOY)
    assert not (tmp_path / names["stale"]).exists()
    (tmp_path / names["stale"]).write_bytes(b"x")
    toy_sim().run(30, resume=ck, progress=False)
    assert not (tmp_path / names["stale"]).exists()


def test_temporary_names_carry_the_writer(tmp_path, monkeypatch):
    seen = []
    real = os.replace
    monkeypatch.setattr(os, "replace", lambda a, b: seen.append(Path(a).name) or real(a, b))
    toy_sim().run(10, checkpoint=tmp_path / "c.npz", progress=False)
    assert seen and all(n.startswith(f".c.npz.{files._host_tag()}.{os.getpid()}.")
                        and n.endswith(".tmp") for n in seen)


_CHILD_WRITER = """
import sys, numpy as np
sys.path.insert(0, {root!r})
from pathlib import Path
from rdgpu.core import files
def slow(fh, **arrays):  # a writer that is killed while it writes
    fh.write(b"partial")
    fh.flush()
    print("writing", flush=True)
    import time; time.sleep(60)
np.savez = slow
files.atomic_savez(Path({ck!r}), {{"x": np.zeros(3)}})
"""


def test_a_killed_writer_leaves_a_temporary_that_the_next_run_removes(tmp_path):
    ck = tmp_path / "run.npz"
    proc = subprocess.Popen([sys.executable, "-c", _CHILD_WRITER.format(root=str(ROOT),
                                                                        ck=str(ck))],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "writing"
        temps = [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
        assert len(temps) == 1 and f".{proc.pid}." in temps[0].name
        remove_stale_temporaries(ck)  # the writer is alive: its file stays
        assert temps[0].exists()
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait(30)
    assert temps[0].exists()  # SIGKILL: no cleanup of its own
    toy_sim().run(10, checkpoint=ck, progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == [ck.name]


# ------------------------------------------------------------------------- Ctrl-C
def test_ctrl_c_stops_at_a_chunk_boundary_with_the_state_there(tmp_path):
    """SIGINT during run(): the run finishes the chunk of steps it is in, checks that
    state, checkpoints it, and raises SimulationInterrupted (a KeyboardInterrupt) with it;
    resuming from that checkpoint gives the uninterrupted result bit for bit."""
    settings = {"snapshot_every": 30, "check_every": 40, "progress": False}
    ref = toy_sim(seed=3).run(400, **settings)
    sim = toy_sim(seed=3)
    real, done = sim.stepper.advance, [0]

    def advance(n):
        if done[0] <= 130 < done[0] + n:
            signal.raise_signal(signal.SIGINT)  # Ctrl-C in the middle of a chunk
        done[0] += n
        real(n)

    sim.stepper.advance = advance
    ck = tmp_path / "c.npz"
    with pytest.raises(SimulationInterrupted) as info:
        sim.run(400, checkpoint=ck, checkpoint_every=1000, **settings)
    exc = info.value
    assert isinstance(exc, KeyboardInterrupt)
    assert exc.step == sim.step == done[0] == 150  # the chunk boundary after step 130
    assert exc.checkpoint == ck and Simulation.read_checkpoint(ck)[0]["step"] == 150
    res = exc.result
    assert res.step == 150 and list(res.snapshot_steps) == [0, 30, 60, 90, 120, 150]
    np.testing.assert_array_equal(res.fields["u"], sim.state()["u"])
    assert "interrupted at step 150" in str(exc)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert_same_result(ref, toy_sim(seed=3).run(400, resume=ck, **settings))


def test_other_keyboard_interrupts_keep_the_last_checked_state():
    """A KeyboardInterrupt at an unknown point of a chunk: the simulation goes back to the
    last checked state, which the exception carries."""
    sim = toy_sim(seed=4)
    interrupt_after(sim, 170)
    with pytest.raises(SimulationInterrupted) as info:
        sim.run(400, snapshot_every=25, check_every=40, progress=False)
    res = info.value.result
    assert res.step == sim.step == info.value.step == 160
    assert list(res.snapshot_steps) == [0, 25, 50, 75, 100, 125, 150]
    ref = toy_sim(seed=4).run(160, check_every=0, progress=False)
    np.testing.assert_array_equal(res.fields["v"], ref.fields["v"])
    np.testing.assert_array_equal(sim.state()["v"], ref.fields["v"])
