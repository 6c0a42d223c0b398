"""Bad input to the ``Simulation`` Python API: every case is a ``TypeError`` or a
``ValueError`` that names the argument (or the file) and says what is allowed -- never a
silent conversion, a raw ``BadZipFile``/``EOFError``/``IndexError``, or a NaN run."""

from __future__ import annotations

import zipfile

import numpy as np
import pytest

from rdgpu.io.output import save_npz
from rdgpu.simulation.driver import Simulation

GRID = {"grid": 8}


def sim(**kw):
    kw.setdefault("backend", "numpy")
    return Simulation(kw.pop("model", "gray-scott"), kw.pop("domain", GRID),
                      kw.pop("params", None), **kw)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A good checkpoint and damaged copies of it, and other files that are no checkpoint."""
    d = tmp_path_factory.mktemp("bad")
    good = d / "good.npz"
    res = sim().run(20, checkpoint=good, checkpoint_every=10, progress=False)
    data = good.read_bytes()
    (d / "truncated.npz").write_bytes(data[: len(data) // 2])
    (d / "empty.npz").write_bytes(b"")
    (d / "garbage.npz").write_bytes(b"PK\x03\x04" + bytes(range(256)) * 8)
    (d / "text.npz").write_text("not a checkpoint\n")
    np.save(d / "array.npy", np.zeros(3))
    np.savez(d / "plain.npz", x=np.zeros(3))
    np.savez(d / "badmeta.npz", meta=np.array("{not json"))
    with np.load(good) as z:  # a checkpoint whose field arrays were dropped
        keep = {k: z[k] for k in z.files if not k.startswith("field__")}
    np.savez(d / "nofields.npz", **keep)
    save_npz(d / "data.npz", res)  # a --data file, not a checkpoint
    (d / "garbage.obj").write_text("this is not\na mesh\n")
    (d / "badindex.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")
    return d


# ------------------------------------------------------------------------- run(steps)
@pytest.mark.parametrize("kwargs, error, match", [
    ({"steps": 2.7}, ValueError, r"steps must be a whole number >= 0, got 2\.7"),
    ({"steps": True}, TypeError, r"steps must be a whole number.*bool"),
    ({"steps": -1}, ValueError, r"steps must be a whole number >= 0, got -1"),
    ({"steps": "10"}, TypeError, r"steps must be a whole number.*str"),
    ({"steps": float("nan")}, ValueError, r"steps must be a whole number"),
    ({"steps": None, "snapshot_every": 0.5}, ValueError, r"snapshot_every must be a whole"),
    ({"steps": 10, "check_every": -5}, ValueError, r"check_every must be a whole number"),
    ({"steps": 10, "checkpoint_every": 2.5}, ValueError, r"checkpoint_every must be"),
    ({"steps": 10, "checkpoint": 3}, TypeError, r"checkpoint must be a path"),
])
def test_bad_run_arguments(kwargs, error, match):
    s = sim()
    steps = kwargs.pop("steps")
    with pytest.raises(error, match=match):
        s.run(steps, progress=False, **kwargs)
    assert s.step == 0  # nothing ran


def test_whole_floats_are_steps():
    """run(1e2) is 100 steps, like run(100) (a float with a whole value is no typo)."""
    a = sim().run(1e2, progress=False)
    b = sim().run(100, progress=False)
    assert a.step == 100
    np.testing.assert_array_equal(a.fields["v"], b.fields["v"])


# ----------------------------------------------------------------------- construction
def test_complex_fields_are_refused():
    u = np.full((8, 8), 1.0 + 0.5j)
    with pytest.raises(TypeError, match=r"field 'u' is complex \(complex128\)"):
        sim(fields={"u": u, "v": np.zeros((8, 8))})
    with pytest.raises(TypeError, match="field 'v' must hold real numbers"):
        sim(fields={"u": np.ones((8, 8)), "v": np.full((8, 8), "a")})


@pytest.mark.parametrize("kwargs, error, match", [
    ({"model": "no-such-model"}, ValueError, "unknown model 'no-such-model'"),
    ({"fields": {"u": np.ones((8, 9)), "v": np.zeros((8, 8))}}, ValueError,
     r"field 'u' must have shape \(8, 8\), got \(8, 9\)"),
    ({"fields": {"u": np.ones((8, 8))}}, ValueError, r"fields missing for species \['v'\]"),
    ({"fields": {"u": np.ones((8, 8)), "v": np.zeros((8, 8)), "w": np.zeros((8, 8))}},
     ValueError, r"unknown species \['w'\]"),
    ({"fields": {"u": np.full((8, 8), np.nan), "v": np.zeros((8, 8))}}, ValueError,
     r"field 'u' has 64 NaN or Inf"),
    ({"fields": {"u": np.full((8, 8), 1e300), "v": np.zeros((8, 8))}}, ValueError,
     r"field 'u' has 64 NaN or Inf value\(s\) as float32"),
    ({"params": {"F": float("nan")}}, ValueError, "parameter 'F' must be finite"),
    ({"params": {"F": np.full((8, 8), np.nan)}}, ValueError, "parameter field 'F' contains NaN"),
    ({"params": {"F": 0.03 + 0.01j}}, TypeError, "parameter 'F' is complex"),
    ({"params": {"F": np.full((8, 8), 0.03 + 0j)}}, TypeError, "parameter 'F' is complex"),
    ({"params": {"F": np.full((4, 4), 0.03)}}, ValueError, r"must have shape \(8, 8\)"),
    ({"params": {"Q": 1.0}}, ValueError, r"unknown parameter\(s\) \['Q'\]"),
    ({"params": [("F", 0.03)]}, TypeError, "params must be a dict"),
    ({"seed": -1}, ValueError, "seed must be a whole number >= 0, got -1"),
    ({"seed": 2.5}, ValueError, "seed must be a whole number >= 0, got 2.5"),
    ({"dt": float("nan")}, ValueError, "dt must be a positive number"),
    ({"dt": -1.0}, ValueError, "dt must be a positive number"),
    ({"dt": True}, TypeError, "dt must be a positive number, got bool"),
    ({"dt": "1"}, TypeError, "dt must be a positive number, got str"),
    ({"dtype": "complex64"}, ValueError, "dtype must be float32 or float64"),
    ({"dtype": "no-such-type"}, ValueError, "dtype must be float32 or float64"),
    ({"domain": {"grid": 8, "spacing": 1}}, ValueError, r"unknown grid option"),
    ({"domain": {"mesh": "no-such-mesh.obj"}}, ValueError, "neither a generator"),
])
def test_bad_simulation_arguments(kwargs, error, match):
    with pytest.raises(error, match=match):
        sim(**kwargs)


@pytest.mark.parametrize("name, match", [
    ("garbage.obj", r"^mesh file '.*garbage\.obj' has no vertices .*: it is not an OBJ "
                    r"triangle mesh \(OBJ, PLY"),
    ("badindex.obj", r"^mesh file '.*badindex\.obj', line 4 "
                     r"\('f 1 2 7'\): vertex index 7 is past the 3 vertices"),
])
def test_a_bad_mesh_file_is_named(files, name, match):
    pytest.importorskip("trimesh")
    with pytest.raises(ValueError, match=match):
        sim(domain={"mesh": str(files / name)})


# ------------------------------------------------------------------------ checkpoints
@pytest.mark.parametrize("name, match", [
    ("truncated.npz", r"is not a readable rdgpu checkpoint \(\d+ bytes; truncated or corrupt"),
    ("empty.npz", r"is empty \(0 bytes\)"),
    ("garbage.npz", r"is not a readable rdgpu checkpoint .*truncated or corrupt"),
    ("text.npz", "is not a readable rdgpu checkpoint"),
    ("array.npy", r"is not a readable rdgpu checkpoint .*not an NPZ archive"),
    ("plain.npz", "an NPZ file without rdgpu's metadata"),
    ("badmeta.npz", "its metadata is not valid JSON"),
    ("nofields.npz", r"arrays \['field__u', 'field__v'\] are missing"),
    ("data.npz", r"is an rdgpu data file \(--data\), not a checkpoint"),
    ("missing.npz", "does not exist"),
])
@pytest.mark.parametrize("how", ["resume", "run", "read"])
def test_a_bad_checkpoint_is_a_clear_error(files, name, match, how):
    path = files / name
    with pytest.raises(ValueError, match=match) as info:
        if how == "resume":
            Simulation.resume(path)
        elif how == "run":
            sim().run(40, resume=path, progress=False)
        else:
            Simulation.read_checkpoint(path)
    assert not isinstance(info.value, (zipfile.BadZipFile, EOFError, KeyError))
    assert info.value.__cause__ is None or isinstance(info.value.__cause__, ValueError)
    assert str(path) in str(info.value)


def test_the_good_checkpoint_still_resumes(files):
    """The damaged files above are damaged copies of a checkpoint that works."""
    res = Simulation.resume(files / "good.npz").run(progress=False)
    assert res.step == 20
