"""Files rdgpu writes and reads (``rdgpu.core.files``, ``rdgpu.core.npzread``, the writers of
``rdgpu.output``): no device node, pipe or folder is ever replaced; a failed write names
its file and leaves no partial file; one writer per checkpoint; damaged or hostile NPZ
files are clear errors, checked before anything is unpacked; flat pictures of fields
uniform to round-off; one argument order for the writers; the movie frame rate."""

from __future__ import annotations

import errno
import json
import os
import stat
import struct
import subprocess
import sys
import warnings
import zipfile
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from rdgpu.core import files
from rdgpu.core.errors import ResourceLimitError
from rdgpu.core.files import CheckpointLock, FileInUseError, check_writable
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.io import images, output, rendering
from rdgpu.io.images import FlatFieldWarning
from rdgpu.io.writers import FPS_RANGE, check_fps
from rdgpu.simulation import runner
from rdgpu.simulation.driver import Simulation

ROOT = Path(__file__).resolve().parents[2]


def sim(**kw):
    return Simulation("gray-scott", {"grid": 8}, None, backend="numpy", **kw)


@pytest.fixture(scope="module")
def result():
    return sim(seed=2).run(20, snapshot_every=10, progress=False)


def tetrahedron() -> SurfaceMesh:
    v = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=np.float64)
    return SurfaceMesh(v, np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]]))


def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# ------------------------------------------------------------ A7: never replace a node
def _fifo(tmp_path: Path, name: str) -> Path:
    p = tmp_path / name
    os.mkfifo(p)
    return p


WRITERS = {
    "checkpoint (run)": ("c.npz", lambda p, r: sim().run(10, checkpoint=p, progress=False)),
    "checkpoint (save)": ("c.npz", lambda p, r: sim().save_checkpoint(p)),
    "data file": ("d.npz", lambda p, r: output.save_npz(p, r)),
    "picture": ("u.png", lambda p, r: output.save_png(p, r.fields["u"], r.domain)),
    "1-D picture": ("l.png", lambda p, r: output.save_png(p, np.arange(8.0), Grid((8,)))),
    "3-D slices": ("s.png", lambda p, r: output.save_png(p, np.random.rand(4, 4, 4),
                                                         view="slices")),
    "images.save_png": ("i.png", lambda p, r: images.save_png(p, r.fields["u"])),
    "movie": ("m.gif", lambda p, r: output.save_movie(p, r.snapshots["u"], r.domain)),
    "mesh file": ("t.ply", lambda p, r: output.save_mesh(p, tetrahedron(),
                                                         {"u": np.arange(4.0)})),
    "write_outputs --data": ("w.npz", lambda p, r: output.write_outputs(r, data=p)),
    "write_outputs --out": ("w.png", lambda p, r: output.write_outputs(r, png=p)),
}


@pytest.mark.parametrize("how", ["fifo", "symlink to /dev/null"])
@pytest.mark.parametrize("writer", sorted(WRITERS))
def test_no_writer_replaces_what_is_not_a_regular_file(tmp_path, result, writer, how):
    name, write = WRITERS[writer]
    if how == "fifo":
        target = _fifo(tmp_path, name)
        kind = r"a named pipe \(FIFO\)"
    else:
        target = tmp_path / name
        target.symlink_to("/dev/null")
        kind = "a character device"
    with pytest.raises(ValueError, match=rf"exists and is {kind}, not a regular file"):
        write(target, result)
    mode = os.lstat(target).st_mode
    assert stat.S_ISFIFO(mode) if how == "fifo" else stat.S_ISLNK(mode)
    assert leftovers(tmp_path) == [name]  # no temporary, no lock file left


def test_the_run_is_refused_before_any_step(tmp_path):
    s = sim()
    with pytest.raises(ValueError, match="checkpoint .* named pipe"):
        s.run(10, checkpoint=_fifo(tmp_path, "c.npz"), progress=False)
    assert s.step == 0


@pytest.mark.parametrize("path, error, match", [
    ("", ValueError, "the path is empty"),
    ("a\0b.npz", ValueError, "cannot contain a NUL byte"),
    (".", ValueError, "is a folder"),
    ("x" * 300 + ".npz", ValueError, r"the file name is 304 bytes long"),
    (3, TypeError, "must be a path"),
])
def test_check_writable_refuses(path, error, match):
    with pytest.raises(error, match=match):
        check_writable(path, "the checkpoint")


def test_check_writable_folders(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match=r"'.*file' is not a folder"):
        check_writable(tmp_path / "file" / "sub" / "c.npz", "the checkpoint")
    with pytest.raises(ValueError, match="is a folder; give a file name"):
        check_writable(tmp_path, "the checkpoint")
    assert check_writable(tmp_path / "new" / "c.npz", "x") == tmp_path / "new" / "c.npz"
    assert check_writable(tmp_path / "file", "x") == tmp_path / "file"  # replaced: fine


@pytest.mark.parametrize("bad, match", [
    (lambda d: d / "folder", "is a folder"),
    (lambda d: "", "the path is empty"),
    (lambda d: d / "file" / "c.npz", "is not a folder"),
])
def test_checkpoint_paths_are_checked_before_the_run(tmp_path, bad, match):
    (tmp_path / "folder").mkdir()
    (tmp_path / "file").write_text("x")
    s = sim()
    with pytest.raises(ValueError, match=match):
        s.run(10, checkpoint=bad(tmp_path), checkpoint_every=5, progress=False)
    assert s.step == 0


def test_the_cli_never_replaces_a_fifo(tmp_path, capsys):
    from rdgpu.cli.app import main

    for option in ("--checkpoint", "--data"):
        fifo = _fifo(tmp_path, f"x{option}.npz")
        code = main(["run", "gray-scott", "--size", "8", "--steps", "10", "--quiet",
                     "--out", str(tmp_path / "o.png"), option, str(fifo)])
        assert code != 0 and "named pipe" in capsys.readouterr().err
        assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


# ------------------------------------------------------ D: failed writes name the file
def _enospc(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


def _partial_then_enospc(uri, *args, **kwargs):
    Path(uri).write_bytes(b"\x89PNG partial")
    _enospc()


@pytest.mark.parametrize("what, name, patch, write", [
    ("the checkpoint", "c.npz", ("numpy", "savez"),
     lambda p, r: sim().run(10, checkpoint=p, progress=False)),
    ("the data file", "d.npz", ("numpy", "savez_compressed"), lambda p, r: output.save_npz(p, r)),
    ("the picture", "o.png", ("imageio.v3", "imwrite"),
     lambda p, r: output.save_png(p, r.fields["u"], r.domain)),
    ("the picture", "l.png", ("imageio.v3", "imwrite"),
     lambda p, r: output.save_png(p, np.random.rand(4, 4, 4), view="slices")),
    ("the movie", "m.gif", ("imageio.v3", "imwrite"),
     lambda p, r: output.save_movie(p, r.snapshots["u"], r.domain)),
])
def test_a_full_disk_names_the_file_and_leaves_the_old_one(tmp_path, result, monkeypatch,
                                                           what, name, patch, write):
    import importlib

    target = tmp_path / name
    target.write_bytes(b"old")
    module = importlib.import_module(patch[0])
    monkeypatch.setattr(module, patch[1], _partial_then_enospc if patch[1] == "imwrite"
                        else _enospc)
    with pytest.raises(OSError) as info:
        write(target, result)
    assert info.value.errno == errno.ENOSPC
    assert info.value.filename == str(target)
    assert f"No space left on device (writing {what})" in str(info.value)
    assert str(target) in str(info.value)
    assert target.read_bytes() == b"old"  # atomic: the old file stays whole
    assert leftovers(tmp_path) == [name]  # no temporary, no lock


def test_a_new_picture_that_fails_leaves_no_empty_file(tmp_path, result, monkeypatch):
    import imageio.v3

    monkeypatch.setattr(imageio.v3, "imwrite", _partial_then_enospc)
    for name in ("o.png", "m.gif"):
        with pytest.raises(OSError, match=name):
            if name.endswith(".png"):
                output.save_png(tmp_path / name, result.fields["u"], result.domain)
            else:
                output.save_movie(tmp_path / name, result.snapshots["u"], result.domain)
    assert leftovers(tmp_path) == []


def test_the_line_plot_is_atomic(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    monkeypatch.setattr(Figure, "savefig", lambda self, f, **kw: _partial_then_enospc(f))
    with pytest.raises(OSError, match="l.png"):
        output.save_png(tmp_path / "l.png", np.arange(8.0), Grid((8,)))
    assert leftovers(tmp_path) == []


# ---------------------------------------------------------- D: one writer per checkpoint
def test_a_second_writer_of_a_checkpoint_is_refused(tmp_path):
    ck = tmp_path / "c.npz"
    with CheckpointLock(ck):
        lock = files.lock_path(ck)
        assert lock.read_text().split() == [files._host_tag(), str(os.getpid())]
        s = sim()
        with pytest.raises(FileInUseError, match=rf"process {os.getpid()} on .*lock file"):
            s.run(10, checkpoint=ck, progress=False)
        assert s.step == 0 and not ck.exists()
    assert not files.lock_path(ck).exists()  # released
    sim().run(10, checkpoint=ck, progress=False)
    assert leftovers(tmp_path) == ["c.npz"]


_HOLDER = """
import sys, time
sys.path.insert(0, {root!r})
from rdgpu.core.files import CheckpointLock
with CheckpointLock({ck!r}):
    print("locked", flush=True)
    time.sleep(60)
"""


def test_another_process_holding_the_lock_refuses_the_run(tmp_path):
    ck = tmp_path / "c.npz"
    proc = subprocess.Popen([sys.executable, "-c", _HOLDER.format(root=str(ROOT), ck=str(ck))],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "locked"
        with pytest.raises(FileInUseError, match=rf"being written by process {proc.pid} on"):
            sim().run(10, checkpoint=ck, progress=False)
        proc.kill()  # a killed holder: its lock is stale and taken over
        proc.wait(30)
        assert files.lock_path(ck).exists()
        sim().run(10, checkpoint=ck, progress=False)
    finally:
        proc.kill()
        proc.wait(30)
    assert leftovers(tmp_path) == ["c.npz"]


def test_a_stale_lock_file_is_taken_over(tmp_path):
    ck = tmp_path / "c.npz"
    files.lock_path(ck).write_text(f"{files._host_tag()} 999999999\n")
    sim().run(10, checkpoint=ck, progress=False)
    assert leftovers(tmp_path) == ["c.npz"]


@pytest.mark.parametrize("exc", [KeyboardInterrupt, RuntimeError])
def test_the_lock_is_released_on_errors_and_ctrl_c(tmp_path, monkeypatch, exc):
    ck = tmp_path / "c.npz"

    def boom(self):
        assert files.lock_path(ck).exists()
        raise exc("stop")

    monkeypatch.setattr(runner.Runner, "go", boom)
    with pytest.raises(exc):
        sim().run(10, checkpoint=ck, progress=False)
    assert not files.lock_path(ck).exists()


# ------------------------------------------------------------- C: reading NPZ files
@pytest.fixture(scope="module")
def npz_files(tmp_path_factory, result):
    d = tmp_path_factory.mktemp("npz")
    good = output.save_npz(d / "good.npz", result)
    with np.load(good) as z:
        arrays = {k: z[k] for k in z.files}
    np.savez(d / "nokey.npz", **{k: v for k, v in arrays.items() if k != "final_u"})
    np.savez(d / "badjson.npz", **{**arrays, "meta": np.array("{not json")})
    np.savez(d / "badparams.npz", **{**arrays, "params": np.array("[1,")})
    meta = json.loads(str(arrays["meta"]))
    np.savez(d / "nospecies.npz", **{**arrays, "meta": np.array(json.dumps(
        {k: v for k, v in meta.items() if k != "species"}))})
    (d / "empty.npz").write_bytes(b"")
    data = bytearray(good.read_bytes())
    data[len(data) // 3] ^= 0x10  # one flipped bit in the compressed data
    (d / "bitflip.npz").write_bytes(bytes(data))
    sim().run(10, checkpoint=d / "checkpoint.npz", progress=False)
    return d


@pytest.mark.parametrize("name, match", [
    ("nokey.npz", r"arrays \['final_u'\] are missing; write it again"),
    ("badjson.npz", r"is not a readable rdgpu data file \(its metadata is not valid JSON\)"),
    ("badparams.npz", r"its 'params' is not valid JSON"),
    ("nospecies.npz", r"its metadata has no valid 'species'"),
    ("empty.npz", r"data file .* is empty \(0 bytes\)"),
    ("bitflip.npz", r"is not a readable rdgpu data file \(\d+ bytes; truncated or corrupt"),
    ("checkpoint.npz", r"is an rdgpu checkpoint \(--checkpoint\), not a data file \(--data\)"),
    ("missing.npz", "does not exist"),
])
def test_load_npz_errors_are_clear(npz_files, name, match):
    path = npz_files / name
    with pytest.raises(ValueError, match=match) as info:
        output.load_npz(path)
    assert type(info.value) is ValueError and str(path) in str(info.value)
    assert info.value.__cause__ is None


def test_the_good_data_file_loads(npz_files, result):
    back = output.load_npz(npz_files / "good.npz")
    np.testing.assert_array_equal(back.fields["u"], result.fields["u"])


def _zip_with(src: Path, dst: Path, member: str, payload: bytes) -> None:
    """``src`` with ``member`` replaced by ``payload`` (deflated)."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            if info.filename != member:
                zout.writestr(info.filename, zin.read(info))
        zout.writestr(member, payload)


def _npy_header(shape, dtype) -> bytes:
    import io

    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buf, {"descr": np.lib.format.dtype_to_descr(np.dtype(dtype)), "fortran_order": False,
              "shape": shape})
    return buf.getvalue()


def _declare_size(path: Path, member: str, size: int) -> None:
    """Make the zip's central directory declare ``size`` uncompressed bytes for ``member``
    (the data stay what they are: a forged "bomb" that costs nothing to build)."""
    data = bytearray(path.read_bytes())
    name = member.encode()
    at = data.find(b"PK\x01\x02")
    while at >= 0:
        n = struct.unpack_from("<H", data, at + 28)[0]
        if bytes(data[at + 46: at + 46 + n]) == name:
            struct.pack_into("<I", data, at + 24, size)
        at = data.find(b"PK\x01\x02", at + 4)
    path.write_bytes(bytes(data))


def test_a_zip_bomb_checkpoint_is_refused_before_unpacking(tmp_path, monkeypatch):
    good = tmp_path / "good.npz"
    sim().run(10, checkpoint=good, progress=False)
    calls = []
    real = np.lib.format.read_array
    monkeypatch.setattr(np.lib.format, "read_array",
                        lambda fh, **kw: calls.append(fh.name) or real(fh, **kw))
    # a field whose header says 8x8 float32 padded with 32 MiB of zeros
    padded = tmp_path / "padded.npz"
    _zip_with(good, padded, "field__u.npy",
              _npy_header((8, 8), "<f4") + bytes(256) + bytes(32 * 2**20))
    with pytest.raises(ValueError, match=r"array 'field__u' declares 33554\d+ bytes but its "
                                         r"header describes \d+ \(\(8, 8\) float32\)"):
        Simulation.read_checkpoint(padded)
    assert all("meta" in c for c in calls)  # only the metadata was unpacked
    # a field that declares 1 GiB, consistent with its own header but not with the grid
    bomb = tmp_path / "bomb.npz"
    header = _npy_header((2**28,), "<f4")
    _zip_with(good, bomb, "field__u.npy", header + bytes(64))
    _declare_size(bomb, "field__u.npy", len(header) + 2**30)
    calls.clear()
    with pytest.raises(ValueError, match=r"field 'u' has shape \(268435456,\), 268435456 "
                                         r"points, but the metadata describes 64"):
        Simulation.read_checkpoint(bomb)
    assert all("meta" in c for c in calls)


def test_reading_a_file_larger_than_memory_is_refused(tmp_path, monkeypatch):
    good = tmp_path / "good.npz"
    sim().run(10, checkpoint=good, progress=False)
    monkeypatch.setenv("RDGPU_MEMORY_LIMIT", "1K")
    with pytest.raises(ResourceLimitError, match=r"reading the checkpoint '.*good\.npz'"):
        Simulation.read_checkpoint(good)


def test_pickled_arrays_are_refused(tmp_path, result):
    good = output.save_npz(tmp_path / "good.npz", result)
    with np.load(good) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["times"] = np.array([{"a": 1}], dtype=object)
    np.savez(tmp_path / "obj.npz", **arrays)
    with pytest.raises(ValueError, match="holds Python objects"):
        output.load_npz(tmp_path / "obj.npz")


# ------------------------------------------------------------------- E2: flat pictures
def _colours(img: np.ndarray) -> int:
    return len(np.unique(img.reshape(-1, img.shape[-1]), axis=0))


@pytest.mark.parametrize("values", [(0.9999990, 0.9999995), (-1e-20, 1e-20), (3e7, 3e7 + 1)])
def test_a_field_uniform_to_round_off_is_drawn_flat(tmp_path, values):
    rng = np.random.default_rng(0)
    f = rng.uniform(*values, size=(16, 16))
    with pytest.warns(FlatFieldWarning, match="uniform to round-off"):
        p = output.save_png(tmp_path / "u.png", f, Grid((16, 16)))
    assert _colours(iio.imread(p)) == 1
    with pytest.warns(FlatFieldWarning):
        m = output.save_movie(tmp_path / "m.gif", np.stack([f, f[::-1]]), Grid((16, 16)))
    assert _colours(iio.imread(m, index=None)[..., :3]) == 1
    with pytest.warns(FlatFieldWarning):
        s = output.save_png(tmp_path / "s.png", np.stack([f] * 4), view="slices")
    assert _colours(iio.imread(s)) == 2  # one colour and the white gaps


def test_a_small_real_pattern_is_not_flattened(tmp_path):
    f = 1.0 + 1e-4 * np.sin(np.arange(256.0)).reshape(16, 16)  # far above round-off
    with warnings.catch_warnings():
        warnings.simplefilter("error", FlatFieldWarning)
        p = output.save_png(tmp_path / "u.png", f, Grid((16, 16)))
    assert _colours(iio.imread(p)) > 20
    # a fixed colour range is kept: round-off in a fixed range draws as it is
    g = np.random.default_rng(1).uniform(0.9999990, 0.9999995, (16, 16))
    q = output.save_png(tmp_path / "q.png", g, Grid((16, 16)), vmin=0.9999990, vmax=0.9999995)
    assert _colours(iio.imread(q)) > 20


def test_a_flat_1d_field_is_a_flat_line(tmp_path):
    pytest.importorskip("matplotlib")
    f = np.random.default_rng(0).uniform(0.9999990, 0.9999995, 64)
    with pytest.warns(FlatFieldWarning):
        output.save_png(tmp_path / "l.png", f, Grid((64,)))


# ------------------------------------------------------------ E5: one argument order
def test_writers_take_the_path_first_and_the_old_order_is_deprecated(tmp_path, result):
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        new = output.save_npz(tmp_path / "new.npz", result)
        output.save_mesh(tmp_path / "new.ply", tetrahedron(), {"u": np.arange(4.0)})
    with pytest.warns(DeprecationWarning, match=r"save_npz\(path, result\)"):
        old = output.save_npz(result, tmp_path / "old.npz")
    assert old == tmp_path / "old.npz"
    np.testing.assert_array_equal(output.load_npz(old).fields["u"],
                                  output.load_npz(new).fields["u"])
    with pytest.warns(DeprecationWarning, match=r"save_mesh\(path, mesh, fields\)"):
        output.save_mesh(tetrahedron(), tmp_path / "old.ply", {"u": np.arange(4.0)})
    assert (tmp_path / "old.ply").read_bytes() == (tmp_path / "new.ply").read_bytes()
    with pytest.raises(TypeError, match="must be a path"), pytest.warns(DeprecationWarning):
        output.save_npz(result, result)


def test_the_suite_refuses_the_old_order(tmp_path, result):
    """pyproject's filterwarnings makes rdgpu's deprecation an error in the tests (outside
    pytest.warns), so no test keeps the earlier order unnoticed."""
    with pytest.raises(DeprecationWarning, match="takes the path first"):
        output.save_npz(result, tmp_path / "old.npz")


def test_render_mesh_png_old_order(tmp_path, monkeypatch):
    monkeypatch.setattr(rendering, "render_mesh", lambda mesh, field, **kw:
                        np.full((4, 4, 3), 7, np.uint8) if isinstance(mesh, SurfaceMesh)
                        else pytest.fail("the mesh was not passed as the mesh"))
    with pytest.warns(DeprecationWarning, match=r"render_mesh_png\(path, field, mesh\)"):
        p = output.render_mesh_png(tetrahedron(), np.arange(4.0), tmp_path / "a.png")
    q = output.render_mesh_png(tmp_path / "b.png", np.arange(4.0), tetrahedron())
    assert p.read_bytes() == q.read_bytes()


# --------------------------------------------------------------------- the frame rate
@pytest.mark.parametrize("fps, error", [
    (0, ValueError), (-1, ValueError), (float("nan"), ValueError), (float("inf"), ValueError),
    (1e9, ValueError), (1e-9, ValueError), (True, TypeError), ("10", TypeError),
])
def test_bad_frame_rates_are_refused(tmp_path, result, fps, error):
    with pytest.raises(error, match=rf"fps must be a number of frames per second from "
                                    rf"{FPS_RANGE[0]:g} to {FPS_RANGE[1]:g}, got"):
        check_fps(fps)
    with pytest.raises(error, match="fps must be"):
        output.save_movie(tmp_path / "m.gif", result.snapshots["u"], result.domain, fps=fps)
    with pytest.raises(error, match="fps must be"):  # before the picture is written
        output.write_outputs(result, png=tmp_path / "o.png", movie=tmp_path / "m.gif", fps=fps)
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("fps", FPS_RANGE)
def test_the_ends_of_the_frame_rate_range_work(tmp_path, result, fps):
    assert check_fps(np.float64(fps)) == fps
    p = output.save_movie(tmp_path / "m.gif", result.snapshots["u"], result.domain, fps=fps)
    assert iio.immeta(p, index=0)["duration"] == pytest.approx(1000 / fps)
