"""A damaged sweep store (issue 19, A6): a batch's ``done`` flag is trusted only with its
data in place; what can be recomputed is (with a SweepStoreWarning), the rest is a clear
error naming the store, never NaN fields reported as results or a raw JSON/Key error."""

from __future__ import annotations

import json
import shutil
from importlib.util import find_spec
from pathlib import Path

import numpy as np
import pytest

import rdgpu
from rdgpu.runs.store import SweepStoreWarning
from rdgpu.runs.sweep import open_sweep

pytestmark = pytest.mark.skipif(
    any(find_spec(m) is None for m in ("dask", "xarray", "zarr")),
    reason='needs the dask extra: pip install "rdgpu[dask]"')

PARAMS = {"F": [0.03, 0.05], "k": [0.055, 0.06]}
KW = {"size": 8, "steps": 5, "backend": "numpy", "batch": 2, "progress": False,
      "scheduler": "serial"}


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """A finished store (copied for each test) and its Dataset."""
    store = tmp_path_factory.mktemp("sweep") / "s.zarr"
    return store, rdgpu.sweep("gray-scott", PARAMS, store=store, **KW)


@pytest.fixture
def store(made, tmp_path):
    path = tmp_path / "s.zarr"
    shutil.copytree(made[0], path)
    return path


def _chunks(store: Path, name: str) -> list[Path]:
    """The chunk files of array ``name`` (every file but the metadata)."""
    return sorted(p for p in (store / name).rglob("*") if p.is_file()
                  and p.name not in ("zarr.json", ".zarray", ".zattrs", ".zgroup"))


def _rerun(store):
    ran = []
    ds = rdgpu.sweep("gray-scott", PARAMS, store=store, on_batch=ran.append, **KW)
    return ds, ran


@pytest.mark.parametrize("species", ["u", "v"])
def test_deleted_chunk_is_recomputed(made, store, species):
    chunks = _chunks(store, species)
    assert len(chunks) == 4  # one member a chunk
    chunks[-1].unlink()  # a member of the last batch
    with pytest.warns(SweepStoreWarning, match=rf"{store}.*1 batch.*\(1\).*run again"):
        ds, ran = _rerun(store)
    assert ran == [1]
    assert ds.identical(made[1])
    assert np.isfinite(ds[species].values).all()


def test_corrupted_chunk_is_recomputed(made, store):
    chunk = _chunks(store, "v")[0]
    chunk.write_bytes(b"\x00garbage" * 7)
    with pytest.warns(SweepStoreWarning, match="run again"):
        ds, ran = _rerun(store)
    assert ran == [0]
    assert ds.identical(made[1])


def test_lost_pattern_reruns_everything(made, store):
    _chunks(store, "pattern")[0].unlink()  # would read as 0: "uniform" everywhere
    with pytest.warns(SweepStoreWarning, match="pattern"):
        ds, ran = _rerun(store)
    assert sorted(ran) == [0, 1]
    assert ds.identical(made[1])


def test_corrupted_done_flags_rerun_everything(made, store):
    _chunks(store, "done")[0].write_bytes(b"\xff" * 5)
    with pytest.warns(SweepStoreWarning, match="done"):
        ds, ran = _rerun(store)
    assert sorted(ran) == [0, 1]
    assert ds.identical(made[1])


def test_finished_store_runs_nothing(made, store):
    ds, ran = _rerun(store)
    assert ran == [] and ds.identical(made[1])


@pytest.mark.parametrize("target", ["zarr.json", "done/zarr.json", "v/zarr.json"])
def test_garbled_metadata_is_a_clear_error(store, target):
    path = store / target
    if not path.exists():
        pytest.skip("a zarr v2 store")
    path.write_text('{"zarr_format": 3, "node_type": ')
    with pytest.raises(ValueError, match=rf"{store}.*(remove it|choose another)"):
        _rerun(store)


def test_garbled_settings_are_a_clear_error(store):
    meta = store / "zarr.json"
    if not meta.exists():
        pytest.skip("a zarr v2 store")
    doc = json.loads(meta.read_text())
    doc["attributes"]["rdgpu_sweep"] = '{"axes": {"F": [0.03'
    meta.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=rf"{store}.*settings.*not valid JSON.*remove it"):
        _rerun(store)
    with pytest.raises(ValueError, match=rf"{store}.*settings.*not valid JSON"):
        open_sweep(store)


@pytest.mark.parametrize("name", ["v", "pattern", "done"])
def test_deleted_array_is_a_clear_error(store, name):
    shutil.rmtree(store / name)
    with pytest.raises(ValueError, match=rf"{store}.*array '{name}' is missing.*remove it"):
        _rerun(store)


def test_open_sweep_refuses_lost_members(store):
    _chunks(store, "v")[1].unlink()
    with pytest.raises(ValueError, match=rf"{store}.*1 finished member.*'v'.*again"):
        open_sweep(store)


def test_open_sweep_refuses_unreadable_chunks(store):
    _chunks(store, "u")[2].write_bytes(b"not zstd")
    with pytest.raises(ValueError, match=rf"{store}.*does not read.*again"):
        open_sweep(store)
