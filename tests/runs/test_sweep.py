"""Parameter sweeps (rdgpu.sweep, `rdgpu sweep`) and the pattern classes they record."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from importlib.util import find_spec

import imageio.v3 as iio
import numpy as np
import pytest

import rdgpu
from rdgpu.analysis import classify_pattern
from rdgpu.domains.grid import Grid
from rdgpu.runs.sweep import PATTERN_CLASSES, open_sweep
from rdgpu.simulation.driver import Simulation

#: the tests of sweeps need the dask extra (CI installs it with .[test])
needs_dask = pytest.mark.skipif(
    any(find_spec(m) is None for m in ("dask", "distributed", "xarray", "zarr")),
    reason='needs the dask extra: pip install "rdgpu[dask]"')

SHAPE = (48, 48)


def _periodic_distance(shape, centre):
    y, x = np.mgrid[: shape[0], : shape[1]]
    dy = np.minimum(abs(y - centre[0]), shape[0] - abs(y - centre[0]))
    dx = np.minimum(abs(x - centre[1]), shape[1] - abs(x - centre[1]))
    return np.hypot(dy, dx)


def _gaussian_spots(shape=SHAPE, spacing=12, width=2.5):
    """A square lattice of gaussian bumps (high values) on 0."""
    f = np.zeros(shape)
    for cy in range(spacing // 2, shape[0], spacing):
        for cx in range(spacing // 2, shape[1], spacing):
            f += np.exp(-0.5 * (_periodic_distance(shape, (cy, cx)) / width) ** 2)
    return f


# ------------------------------------------------------------------------ classification
def test_classes_of_synthetic_fields():
    grid = Grid(SHAPE, bc="periodic")
    y, x = np.mgrid[: SHAPE[0], : SHAPE[1]]
    bumps = _gaussian_spots()
    stripes = np.sin(2 * np.pi * 4 * x / SHAPE[1])
    # compact islands of high values are "inverted-spots" (holes of the low phase), compact
    # islands of low values in a high sea are "spots"
    assert classify_pattern(bumps, grid, threshold=None) == "inverted-spots"
    assert classify_pattern(-bumps, grid, threshold=None) == "spots"
    assert classify_pattern(stripes, grid, threshold=None) == "stripes"
    assert classify_pattern(np.full(SHAPE, 0.3), grid, threshold=None) == "uniform"
    lone = np.exp(-0.5 * (_periodic_distance(SHAPE, (20, 30)) / 3.0) ** 2)  # one spot
    assert classify_pattern(lone, grid, threshold=None) == "inverted-spots"
    assert classify_pattern(-lone, grid, threshold=None) == "spots"
    assert classify_pattern(-lone, grid, threshold=None, lone=0.0) == "stripes"
    diverged = np.where(x > 30, np.nan, stripes)
    assert classify_pattern(diverged, grid, threshold=None, nonfinite="diverged") == "diverged"
    with pytest.raises(ValueError, match="NaN"):
        classify_pattern(diverged, grid, threshold=None)
    # a stack: one class per member (found from the domain's shape, or members=True)
    stack = np.stack([bumps, -bumps, stripes, np.full(SHAPE, 0.3), diverged])
    expected = ["inverted-spots", "spots", "stripes", "uniform", "diverged"]
    assert classify_pattern(stack, grid, None, nonfinite="diverged") == expected
    assert classify_pattern(stack, None, None, nonfinite="diverged", members=True) == expected


def test_classes_of_a_stack_on_a_mesh():
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

    mesh = SurfaceMesh.icosphere(3)
    z = mesh.vertices[:, 2]
    stack = np.stack([np.cos(3 * np.pi * z), np.ones(mesh.n_vertices)])
    assert classify_pattern(stack, mesh) == ["stripes", "uniform"]


def test_mixed_spots_and_worms():
    """Islands in a sea, half of the area in round spots and half in worms: 'mixed' when
    asked for, else the majority (here the worms: stripes)."""
    f = np.ones((64, 64))
    for c in ((8, 8), (8, 24), (24, 8), (24, 24), (8, 40), (24, 40)):
        f[_periodic_distance(f.shape, c) < 4] = -1  # 6 round islands, ~50 cells each
    for row in (42, 54):
        f[row - 2: row + 2, 4:44] = -1  # 2 worms of 4 x 40 cells
    grid = Grid(f.shape, bc="periodic")
    assert classify_pattern(f, grid, mixed=0.25) == "mixed"
    assert classify_pattern(f, grid) == "stripes"
    spots_only = np.where(np.arange(64)[:, None] > 36, 1.0, f)
    assert classify_pattern(spots_only, grid, mixed=0.25) == "spots"
    with pytest.raises(ValueError, match="mixed"):
        classify_pattern(f, grid, mixed=0.7)


@pytest.fixture(scope="module")
def pearson_states():
    """Final v of three of Pearson's Gray-Scott classes (the presets' parameters and
    spacing) on a 64² torus, seeded by a larger square so they fill it in 4000 steps."""
    init = {"kind": "square", "values": {"u": 1.0, "v": 0.0},
            "inside": {"u": 0.5, "v": 0.25}, "size": 0.3, "noise": 0.05}
    out = {}
    for letter in ("lambda", "delta", "theta"):
        sim = Simulation.from_preset(f"gs-pearson-{letter}", init=init,
                                     domain={"grid": (64, 64), "dx": 2.5 / 256,
                                             "bc": "periodic"})
        res = sim.run(4000, progress=False)
        out[letter] = (res.fields["v"], res.domain)
    return out


def test_classes_of_gray_scott_states(pearson_states):
    """Pearson's λ (islands of high v: inverted spots), δ (islands of low v: spots) and θ
    (stripes), classified on v as the presets are."""
    expect = {"lambda": "inverted-spots", "delta": "spots", "theta": "stripes"}
    for letter, (v, grid) in pearson_states.items():
        assert classify_pattern(v, grid, threshold=None) == expect[letter], letter
    stack = np.stack([pearson_states[k][0] for k in expect])
    assert classify_pattern(stack, grid, threshold=None) == list(expect.values())


# ------------------------------------------------------------------------ axes
def test_parse_axis():
    from rdgpu.runs.sweep import parse_axis

    name, v = parse_axis("F=0.01:0.08:8")
    assert name == "F" and np.array_equal(v, np.linspace(0.01, 0.08, 8))
    assert np.array_equal(parse_axis("k = 0.02, 0.03")[1], [0.02, 0.03])
    assert parse_axis("k=0.05") == ("k", 0.05)
    for bad, match in (("F", "NAME=START:STOP:N"), ("F=0.01:0.08", "START:STOP:N"),
                       ("F=0.01:0.08:0", "at least 1"), ("F=a:b:3", "not a number"),
                       ("F=0.01:0.08:x", "whole number"), ("F=0.1,0.1", "repeat"),
                       ("F=inf", "finite"), ("=0.1", "NAME")):
        with pytest.raises(ValueError, match=match):
            parse_axis(bad)


# ------------------------------------------------------------------------ sweeps
PARAMS = {"F": "0.03:0.05:3", "k": [0.055, 0.06], "Du": 0.16}
KW = {"size": 24, "steps": 600, "backend": "numpy", "batch": 2, "progress": False,
      "init": {"kind": "square", "values": {"u": 1.0, "v": 0.0},
               "inside": {"u": 0.5, "v": 0.25}, "size": 0.4, "noise": 0.05}}


@pytest.fixture(scope="module")
def serial():
    return rdgpu.sweep("gray-scott", PARAMS, scheduler="serial", **KW)


@needs_dask
def test_sweep_dataset(serial):
    ds = serial
    assert ds["u"].dims == ("F", "k", "y", "x") and ds["v"].shape == (3, 2, 24, 24)
    assert ds["pattern"].dims == ("F", "k")
    assert np.allclose(ds["F"], [0.03, 0.04, 0.05]) and np.allclose(ds["k"], [0.055, 0.06])
    assert np.allclose(ds["x"], np.arange(24) + 0.5)
    assert ds.attrs["model"] == "gray-scott" and ds.attrs["steps"] == 600
    assert ds.attrs["dtype"] == "float32" and ds.attrs["backend"] == "numpy"
    assert ds.attrs["dt"] == 1.0 and ds.attrs["param_Du"] == 0.16
    assert ds.attrs["rdgpu_version"] == rdgpu.__version__
    # the classes are those of each member's final v (Gray-Scott's presets classify v)
    assert ds.attrs["classify"] == "v"
    grid = Grid((24, 24), bc="periodic")
    for i in range(3):
        for j in range(2):
            v = ds["v"].values[i, j]
            assert ds["pattern"].values[i, j] == classify_pattern(v, grid, None, mixed=0.25)
    assert len(set(ds["pattern"].values.ravel())) > 1  # not all one class


@needs_dask
def test_sweep_of_a_model_without_ensembles():
    """Allen-Cahn's stepper takes no members: its batches run the members one by one."""
    ds = rdgpu.sweep("allen-cahn", {"b": [-0.1, 0.0, 0.1]}, size=16, steps=50,
                     backend="numpy", scheduler="serial", progress=False)
    assert ds["u"].shape == (3, 16, 16)
    sim = Simulation("allen-cahn", {"grid": (16, 16), "bc": "periodic", "dx": 1.0},
                     {"b": 0.1}, dt=ds.attrs["dt"], backend="numpy")
    alone = sim.run(50, progress=False, check_every=0).fields["u"]
    assert np.array_equal(ds["u"].values[2], alone)


def test_serial_sweep_equals_members_run_alone(serial):
    init = KW["init"]
    for F, k in ((0.03, 0.055), (0.05, 0.06), (0.04, 0.06)):
        sim = Simulation("gray-scott", {"grid": (24, 24), "bc": "periodic", "dx": 1.0},
                         {"F": F, "k": k, "Du": 0.16}, dt=1.0, backend="numpy", seed=0,
                         init=init)
        res = sim.run(600, progress=False, check_every=0)
        for s in ("u", "v"):
            member = serial[s].sel(F=F, k=k, method="nearest").values
            assert np.array_equal(member, res.fields[s]), (F, k, s)


@needs_dask
def test_zarr_store_streams_and_resumes(tmp_path, serial):
    store = tmp_path / "map.zarr"
    stored = []

    class Stop(Exception):
        pass

    def stop_after_two(b):
        stored.append(b)
        if len(stored) == 2:
            raise Stop

    with pytest.raises(Stop):
        rdgpu.sweep("gray-scott", PARAMS, scheduler="serial", store=store,
                    on_batch=stop_after_two, **KW)
    partial = open_sweep(store)
    assert (partial["pattern"].values != "").sum() == 4  # 2 batches of 2 members
    assert np.isnan(partial["u"].values[2]).all()  # F = 0.05 never ran
    rerun = []
    ds = rdgpu.sweep("gray-scott", PARAMS, scheduler="serial", store=store,
                     on_batch=rerun.append, **KW)
    assert sorted(rerun) == [2]  # only the missing batch
    assert ds.identical(serial)
    again = []
    assert rdgpu.sweep("gray-scott", PARAMS, scheduler="serial", store=store,
                       on_batch=again.append, **KW).identical(serial)
    assert again == []
    with pytest.raises(ValueError, match="other settings.*steps: 600 there, 700 now"):
        rdgpu.sweep("gray-scott", PARAMS, scheduler="serial", store=store,
                    **{**KW, "steps": 700})
    with pytest.raises(ValueError, match="other settings.*axes"):
        rdgpu.sweep("gray-scott", {**PARAMS, "F": "0.03:0.05:4"}, scheduler="serial",
                    store=store, **KW)
    # resumed elsewhere, without naming the batch size: the store's
    again = []
    sweep_module = sys.modules["rdgpu.runs.sweep"]
    with pytest.MonkeyPatch.context() as mp:  # nothing left to run: no cluster is started
        mp.setattr(sweep_module, "_client", lambda *a: pytest.fail("a cluster was started"))
        assert rdgpu.sweep("gray-scott", PARAMS, scheduler="local", store=store,
                           on_batch=again.append, **{**KW, "batch": None}).identical(serial)
    assert again == []
    other = tmp_path / "other.zarr"
    other.mkdir()
    with pytest.raises(ValueError, match="not"):
        rdgpu.sweep("gray-scott", PARAMS, scheduler="serial", store=other, **KW)


@needs_dask
def test_netcdf_store(tmp_path, serial):
    path = tmp_path / "map.nc"
    ds = rdgpu.sweep("gray-scott", PARAMS, scheduler="serial", store=path, **KW)
    assert ds.identical(serial)
    back = open_sweep(path)
    assert np.array_equal(back["v"].values, serial["v"].values)
    assert list(back["pattern"].values.ravel()) == list(serial["pattern"].values.ravel())


@needs_dask
def test_sweep_input_errors():
    with pytest.raises(ValueError, match="unknown parameter.*'G'.*Du, Dv, F, k"):
        rdgpu.sweep("gray-scott", {"G": [1, 2]}, steps=1, scheduler="serial")
    with pytest.raises(ValueError, match="nothing to sweep"):
        rdgpu.sweep("gray-scott", {"F": 0.03}, steps=1, scheduler="serial")
    with pytest.raises(ValueError, match=r"\.zarr.*\.nc"):
        rdgpu.sweep("gray-scott", {"F": [0.03, 0.04]}, steps=1, store="x.h5",
                    scheduler="serial")
    with pytest.raises(ValueError, match="scheduler must be"):
        rdgpu.sweep("gray-scott", {"F": [0.03, 0.04]}, steps=1, size=8, scheduler="gpu")
    with pytest.raises(ValueError, match="classify"):
        rdgpu.sweep("gray-scott", {"F": [0.03, 0.04]}, steps=1, size=8, classify="w",
                    scheduler="serial")


def test_missing_dask_is_named(monkeypatch):
    monkeypatch.setitem(sys.modules, "xarray", None)
    with pytest.raises(ImportError, match=r'pip install "rdgpu\[dask\]"'):
        rdgpu.sweep("gray-scott", {"F": [0.03, 0.04]}, steps=1, scheduler="serial")


def test_import_rdgpu_needs_no_dask():
    code = ("import sys, rdgpu; print(sorted(m for m in ('dask', 'distributed', 'xarray', "
            "'zarr') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"


# ------------------------------------------------------------------------ on Dask
@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=None) as c, distributed.Client(c) as cl:
        yield cl


@needs_dask
@pytest.mark.slow
def test_local_cluster_equals_serial(cluster, serial, tmp_path):
    ds = rdgpu.sweep("gray-scott", PARAMS, scheduler=cluster, store=tmp_path / "c.zarr", **KW)
    assert ds.identical(serial)
    # by the scheduler's address, as `--scheduler tcp://host:port` does
    address = cluster.scheduler_info()["address"]
    assert address.startswith("tcp://")
    assert rdgpu.sweep("gray-scott", PARAMS, scheduler=address, **KW).identical(serial)


@needs_dask
@pytest.mark.slow
def test_killed_worker_batch_is_rerun(cluster, serial, tmp_path):
    """SIGKILL a worker process while it runs a batch: Dask runs that batch again on
    another worker, and the Dataset is bit for bit the serial one."""
    killed = []

    def kill_a_busy_worker(b):
        if killed:
            return
        pids = cluster.run(os.getpid)
        busy = [addr for addr, keys in cluster.processing().items() if keys]
        assert busy, "no batch running: the sweep is too short for this test"
        os.kill(pids[busy[0]], signal.SIGKILL)
        killed.append(pids[busy[0]])

    params = {"F": "0.03:0.05:3", "k": [0.055, 0.06, 0.065], "Du": 0.16}
    kw = {**KW, "steps": 1500, "batch": 1}  # batches of about 0.5 s
    reference = rdgpu.sweep("gray-scott", params, scheduler="serial", **kw)
    ds = rdgpu.sweep("gray-scott", params, scheduler=cluster, store=tmp_path / "k.zarr",
                     on_batch=kill_a_busy_worker, **kw)
    assert killed
    assert killed[0] not in cluster.run(os.getpid).values()
    assert max(cluster.run_on_scheduler(_times_started).values()) >= 2  # a batch ran again
    assert ds.identical(reference)


def _times_started(dask_scheduler) -> dict[str, int]:
    """How many times each task of a sweep went to a worker (from the scheduler's log)."""
    keys = {str(t[0]) for t in dask_scheduler.transition_log}
    return {k: sum(1 for t in dask_scheduler.story(k) if t[2] == "processing")
            for k in keys if k.startswith("rdgpu-sweep-")}


# ------------------------------------------------------------------------ the CLI
@needs_dask
def test_cli_writes_the_map_and_the_dataset(tmp_path):
    import imageio.v3 as iio
    import xarray as xr

    from rdgpu.cli.app import main

    png, store = tmp_path / "map.png", tmp_path / "map.zarr"
    code = main(["sweep", "gray-scott", "--param", "F=0.03:0.05:4", "--param",
                 "k=0.055,0.06,0.065", "--size", "16", "--steps", "200", "--out", str(png),
                 "--data", str(store), "--scheduler", "serial", "--backend", "numpy",
                 "--quiet"])
    assert code == 0
    img = iio.imread(png)
    assert img.shape[0] > 200 and img.shape[1] > img.shape[0]  # 4 columns x 3 rows of tiles
    assert img[..., :3].std() > 10  # not blank
    ds = xr.open_zarr(store, consolidated=False)
    assert ds["v"].dims == ("F", "k", "y", "x") and ds["v"].shape == (4, 3, 16, 16)
    assert bool(ds["done"].all())
    assert np.isfinite(ds["v"].values).all()


@pytest.mark.parametrize("argv, status, message", [
    (["--param", "F=0.01:0.08"], 2, "START:STOP:N"),
    (["--param", "G=0.01:0.08:4"], 2, "--param G: model gray-scott has parameters"),
    (["--param", "F=0.03"], 2, "nothing to sweep"),
    (["--param", "F=0.03,0.04", "--out", "map.jpg"], 2, "--out must end in .png"),
    (["--param", "F=0.03,0.04", "--data", "map.h5"], 2, "--data must end in .zarr"),
    (["--param", "F=0.03,0.04", "--species", "w"], 2, "--species 'w'"),
])
def test_cli_errors(argv, status, message, capsys, tmp_path, monkeypatch):
    from rdgpu.cli.app import main

    monkeypatch.chdir(tmp_path)
    assert main(["sweep", "gray-scott", *argv]) == status
    err = capsys.readouterr().err
    assert message in err and err.startswith("rdgpu: error:")


def test_cli_missing_dask(capsys, tmp_path, monkeypatch):
    from rdgpu.cli.app import main

    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "distributed", None)
    assert main(["sweep", "gray-scott", "--param", "F=0.03,0.04", "--steps", "1"]) == 1
    assert 'pip install "rdgpu[dask]"' in capsys.readouterr().err


@needs_dask
@pytest.mark.slow
def test_model_from_equations_on_a_cluster(cluster):
    """A model defined by its equations travels to the workers as its equations."""
    from rdgpu.models import define_model

    model = define_model("gs-own", {"u": "Du*laplace(u) - u*v**2 + F*(1 - u)",
                                    "v": "Dv*laplace(v) + u*v**2 - (F + k)*v"},
                         {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.06})
    kw = {**KW, "size": 16, "steps": 100, "dt": 1.0}
    ds = rdgpu.sweep(model, {"F": [0.03, 0.04, 0.05]}, scheduler=cluster, **kw)
    assert ds.attrs["model"] == "gs-own" and ds["v"].shape == (3, 16, 16)
    assert ds.identical(rdgpu.sweep(model, {"F": [0.03, 0.04, 0.05]}, scheduler="serial",
                                    **kw))


@needs_dask
def test_the_dataset_shows_itself_in_a_notebook(serial):
    png = serial.rdgpu._repr_png_()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    image = iio.imread(png)
    assert image.ndim == 3 and image.shape[0] > 50 and image.shape[1] > 50
    assert image[..., :3].std() > 10  # not blank
    page = serial.rdgpu._repr_html_()
    assert "<th>F</th>" in page and "<th>k</th>" in page and "3 values" in page
    assert "Du = 0.16" in page and "wall time" in page and " s</td>" in page
    counts = serial.rdgpu.summary()
    assert sum(counts.values()) == 6 and set(counts) <= set(PATTERN_CLASSES)
    assert serial.copy().rdgpu.wall_s is None
