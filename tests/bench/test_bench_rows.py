"""The row groups of ``rdgpu bench`` beyond the peers (`rdgpu.bench.groups`): each runs on
tiny sizes (`quick_options`, NumPy) and gives its rows and its section of bench.md; the
kernels' and the mesh kernels' checks; the command's ``--rows``.  Never a timed
assertion."""

from __future__ import annotations

import json

import pytest

from rdgpu.backends.registry import get_backend
from rdgpu.bench import machine, rows_kernels, rows_mesh
from rdgpu.bench.context import Context, kernel_sizes
from rdgpu.bench.groups import GROUPS, TITLES, quick_options, run_groups
from rdgpu.bench.machine import MiB
from rdgpu.bench.report import markdown, write
from rdgpu.bench.rows_kernels import BYTES_PER_CELL, check_kernel
from rdgpu.bench.rows_states import blocking
from rdgpu.bench.run import Options, run_bench
from rdgpu.cli.app import build_parser
from rdgpu.cli.bench import options_from
from rdgpu.cli.bench_options import KERNEL_NAMES, ROW_GROUPS

try:
    import trimesh  # noqa: F401 - the mesh rows' icosphere
except ImportError:
    HAVE_TRIMESH = False
else:
    HAVE_TRIMESH = True


def _tiny():
    g = quick_options()
    g.kernels = ["laplacian", "gray_scott"]
    g.mesh_vertices, g.members, g.numpy_members, g.sweep_steps = 200, 4, 4, 0
    g.walker_steps, g.early, g.late = 10, 2, 4
    return g


@pytest.fixture(scope="module")
def record():
    opts = Options(rows=[g for g in GROUPS if g != "peers"], backends=[], seconds=0.01,
                   triad_max=2 * MiB, triad_seconds=0.001, groups=_tiny(), quick=True,
                   full=True)
    with pytest.MonkeyPatch.context() as mp:  # NumPy's triad: no numba compilation
        mp.setattr(machine, "_numba_triad", lambda: None)
        return run_bench(opts)


def test_every_group_gives_rows_and_a_section(record):
    groups = record["groups"]
    assert record["rows"] == [] and set(groups["devices"]) == {"numpy"}
    text = markdown(record)
    assert "## Peers" not in text
    for name in GROUPS[1:]:
        if name == "mesh" and not HAVE_TRIMESH:
            assert "trimesh" in groups[name]["markdown"][0]
            continue
        assert groups[name]["rows"], name
        assert f"## {TITLES[name]}" in text
        assert any(line.startswith("Ran on: ") for line in groups[name]["markdown"]), name
    json.dumps(record, default=str)


def test_kernel_rows_checked_and_timed(record):
    rows = record["groups"]["kernels"]["rows"]
    assert {(r["kernel"], r["size"]) for r in rows} == {("laplacian", 64), ("gray_scott", 64)}
    assert all(r["status"] == "ok" and r["mcells"] > 0 and r["speedup"] == 1.0 for r in rows)
    assert all(r["bytes_per_cell"] == BYTES_PER_CELL[r["kernel"]] for r in rows)


def test_mesh_rows_against_scipy(record):
    pytest.importorskip("trimesh")
    rows = record["groups"]["mesh"]["rows"]
    assert {r["backend"] for r in rows} == {"scipy", "numpy"}
    assert all(r["status"] == "ok" and r["vs_scipy"] > 0 for r in rows)


def test_models_ensembles_growth_states_blocking(record):
    g = record["groups"]
    assert g["models"]["rows"][0]["model"] == "gray-scott (hand-written)"
    assert len(g["models"]["rows"]) > 5
    ens = g["ensembles"]["rows"]
    assert [r["kernel"] for r in ens] == ["ensemble", "ensemble-single"]
    assert ens[0]["vs_single"] > 0 and ens[0]["sweep_source"] == "not run"
    kinds = {(r["kernel"], r["backend"]) for r in g["growth"]["rows"]}
    assert {("dla", "plain NumPy"), ("dla", "numpy"), ("walkers", "numpy")} <= kinds
    assert all(r["finite"] for r in g["real-states"]["rows"])
    assert g["blocking"]["rows"] == [dict(kernel="blocking", backend="numpy",
                                          config="not run",
                                          note=g["blocking"]["rows"][0]["note"])]
    assert "no blocked passes" in "\n".join(g["blocking"]["markdown"])


def test_write_gives_the_kernels_plot(record, tmp_path):
    pytest.importorskip("matplotlib")
    assert write(record, tmp_path) == []
    assert (tmp_path / "bench-kernels.png").stat().st_size > 0
    assert not (tmp_path / "bench.png").exists()  # no peer rows


class _WrongGrayScott:
    """The NumPy backend with Gray-Scott's F off by 40 %: a backend doing other maths."""

    def __init__(self):
        self.inner = get_backend("numpy")

    def __getattr__(self, name):
        return getattr(self.inner, name)

    def gray_scott(self, *args, **kw):
        self.inner.gray_scott(*args, **{**kw, "F": 0.05})


def test_kernel_check_passes_and_refuses():
    assert check_kernel("sor_sweep", get_backend("numpy")) is None
    wrong = _WrongGrayScott()
    assert "disagrees" in check_kernel("gray_scott", wrong)
    ctx = Context(backends={"wrong": wrong}, memory={"cpu": {"llc": MiB, "GBps": 10.0}},
                  llc=MiB, sizes=[64], seconds=0.01, machine={"cpu": "x", "cores": 1},
                  say=lambda line: None)
    (row,) = rows_kernels.run(ctx, ["gray_scott"])
    assert row["status"] == "refused" and "mcells" not in row
    assert "refused: disagrees" in "\n".join(rows_kernels.markdown([row], ctx))


def test_kernel_sizes_in_cache_and_beyond():
    small, mid, large = kernel_sizes(64 * MiB, 8, 16)
    assert small * small * 16 <= 16 * MiB and large * large * 8 >= 256 * MiB
    assert small < mid < large and all(n % 64 == 0 for n in (small, mid, large))


def test_names_alike():
    assert ROW_GROUPS == GROUPS and KERNEL_NAMES == tuple(BYTES_PER_CELL)


def test_rows_option(tmp_path):
    parser = build_parser()
    args = parser.parse_args(["bench", "--rows", "all", "--quick", "--kernels", "laplacian",
                              "--out", str(tmp_path)])
    opts = options_from(args)
    assert opts.rows == list(GROUPS) and opts.quick and opts.groups.kernels == ["laplacian"]
    assert opts.groups.kernel_sizes == [64]
    default = options_from(parser.parse_args(["bench", "--out", str(tmp_path)]))
    assert default.rows == ["peers"] and default.groups.kernel_sizes is None


def test_blocking_rows_on_a_backend_that_blocks():
    try:
        be = get_backend("opencl")
    except Exception as exc:  # noqa: BLE001 - no OpenCL here
        pytest.skip(f"no OpenCL: {exc}")
    if be.blocked_pass_support() is not None:
        pytest.skip(be.blocked_pass_support())
    ctx = Context(backends={"opencl": be}, memory={"cpu": {"llc": MiB, "GBps": 10.0}},
                  llc=MiB, sizes=[64], seconds=0.01, machine={"cpu": "x", "cores": 1},
                  say=lambda line: None)
    rows = blocking(ctx, (64, 128), (64, 128), [2], [32])
    assert [r["config"] for r in rows] == ["single step", "blocked K=2 B=32",
                                           "compute ceiling: single step in the LLC"]
    assert all(r["mcells"] > 0 and r["x_roofline"] > 0 for r in rows)


def test_a_group_missing_its_package_says_so(monkeypatch):
    def no_trimesh(frequency):
        raise ImportError("No module named 'trimesh'")

    monkeypatch.setattr(rows_mesh, "geodesic_sphere", no_trimesh)
    got = run_groups(["mesh"], [], _tiny(), {"cpu": "x", "cores": 1}, MiB, 10.0, 0.01,
                     say=lambda line: None)
    assert got["mesh"]["rows"] == [] and "trimesh" in got["mesh"]["markdown"][0]
