"""Bad and huge requests to rdgpu.sweep (issue 19, A11 and B): refused before any work,
naming the argument; nothing truncated or read as a number from text.  And the extra that
`rdgpu sweep --out map.png` needs (E5)."""

from __future__ import annotations

import re
import sys
import time
from importlib.util import find_spec
from pathlib import Path

import numpy as np
import pytest

import rdgpu
from rdgpu.core.errors import ResourceLimitError

needs_dask = pytest.mark.skipif(
    any(find_spec(m) is None for m in ("dask", "distributed", "xarray", "zarr")),
    reason='needs the dask extra: pip install "rdgpu[dask]"')

P = {"F": [0.03, 0.04]}
OK = {"steps": 1, "size": 8, "backend": "numpy", "scheduler": "serial", "progress": False}


@needs_dask
@pytest.mark.parametrize("change, error, match", [
    ({"steps": "5"}, TypeError, r"steps must be a whole number.*str '5'"),
    ({"steps": 2.5}, ValueError, r"steps must be a whole number.*2\.5"),
    ({"steps": True}, TypeError, r"steps.*bool"),
    ({"steps": -1}, ValueError, r"steps must be a whole number >= 0"),
    ({"size": 8.7}, ValueError, r"size must be a whole number.*8\.7"),
    ({"size": "8"}, TypeError, r"size must be a whole number.*str"),
    ({"size": (8, 8.5)}, ValueError, r"size.*8\.5"),
    ({"size": 0}, ValueError, r"size must be a whole number >= 1"),
    ({"size": True}, TypeError, r"size.*bool"),
    ({"seed": "3"}, TypeError, r"seed must be a whole number"),
    ({"seed": 1.5}, ValueError, r"seed must be a whole number"),
    ({"dt": "0.5"}, TypeError, r"dt must be"),
    ({"dt": 0.0}, ValueError, r"dt must be"),
    ({"dt": float("nan")}, ValueError, r"dt must be"),
    ({"batch": "2"}, TypeError, r"batch must be a whole number"),
    ({"batch": 2.5}, ValueError, r"batch must be a whole number"),
    ({"workers": 1.5}, ValueError, r"workers must be a whole number"),
])
def test_bad_arguments(change, error, match):
    with pytest.raises(error, match=match):
        rdgpu.sweep("gray-scott", P, **{**OK, **change})


@pytest.mark.parametrize("value", [b"0.03", ["0.03", "0.04"], [True, False], [0.03, "x"],
                                   np.complex128(0.03 + 1j), [0.03 + 0j, 0.04 + 0j],
                                   {"a": 1}, None])
def test_parameter_values_must_be_numbers(value):
    from rdgpu.runs.sweep import axis_values

    with pytest.raises(TypeError, match="parameter F"):
        axis_values("F", value)


def test_parameter_values_that_are_numbers():
    from rdgpu.runs.sweep import axis_values

    assert axis_values("F", np.float32(0.5)) == 0.5
    assert axis_values("F", np.array(2)) == 2.0
    assert list(axis_values("F", np.array([1, 2], dtype=np.int64))) == [1.0, 2.0]


@needs_dask
def test_whole_floats_are_accepted():
    ds = rdgpu.sweep("gray-scott", P, **{**OK, "steps": 2.0, "size": 8.0})
    assert ds.attrs["steps"] == 2 and ds["v"].shape == (2, 8, 8)


@needs_dask
@pytest.mark.parametrize("params", [
    {"F": "0.01:0.08:31623", "k": "0.03:0.07:31623"},  # 10^9 members
    {"F": "0.01:0.08:1000000000"},  # one axis of 10^9 values (8 GB of them alone)
])
def test_huge_sweep_is_refused_before_any_work(params, monkeypatch):
    monkeypatch.setenv("RDGPU_MEMORY_LIMIT", "1G")
    start = time.perf_counter()
    with pytest.raises(ResourceLimitError, match=r"needs about .* of memory.*has 1\.07 GB"):
        rdgpu.sweep("gray-scott", params, **OK)
    assert time.perf_counter() - start < 5


@needs_dask
def test_sweep_estimate_counts_the_dataset_and_store(monkeypatch, tmp_path):
    """400 members of 64² float32 x 2 species: 13 MB of results; a 10 MB limit refuses it,
    naming the Dataset and the store, and leaves no store behind."""
    monkeypatch.setenv("RDGPU_MEMORY_LIMIT", "10M")
    store = tmp_path / "m.zarr"
    with pytest.raises(ResourceLimitError, match=r"400 members.*Dataset.*store"):
        rdgpu.sweep("gray-scott", {"F": "0.01:0.08:20", "k": "0.03:0.07:20"},
                    **{**OK, "size": 64}, store=store)
    assert not store.exists()


# --------------------------------------------------------------------- the extra (E5)
ROOT = Path(__file__).resolve().parents[2]


def _extra(name: str) -> set[str]:
    try:
        import tomllib
    except ImportError:  # Python 3.10
        tomllib = pytest.importorskip("tomli")
    with open(ROOT / "pyproject.toml", "rb") as f:
        reqs = tomllib.load(f)["project"]["optional-dependencies"][name]
    out = set()
    for r in reqs:
        base = re.split(r"[<>=!~;\[ ]", r, maxsplit=1)[0].lower()
        if base == "rdgpu":  # rdgpu[a,b]: the extras it names
            for other in re.search(r"\[(.*)\]", r).group(1).split(","):
                out |= _extra(other.strip())
        else:
            out.add(base)
    return out


def test_readme_sweep_install_brings_the_map():
    """The sweep section of docs/many-runs.md installs one extra and then draws ``--out map.png``:
    that extra brings every package the sweep and its map import."""
    readme = (ROOT / "docs" / "many-runs.md").read_text()
    section = readme[readme.index("## Parameter maps"):]
    cmd = re.search(r'pip install "\.\[([a-z,]+)\]"', section) or re.search(
        r"pip install \"?'?\.\[([a-z,]+)\]", section)
    assert cmd, "the sweep section's install command"
    assert "--out map.png" in section
    installed = set()
    for extra in cmd.group(1).split(","):
        installed |= _extra(extra)
    from rdgpu.core.optional import PIP_NAMES

    needed = {"dask", "distributed", "xarray", "zarr", "matplotlib"}
    missing = {PIP_NAMES.get(m, m) for m in needed} - {i.split("[")[0] for i in installed}
    missing -= {"distributed"} if "dask" in installed else set()  # dask[distributed]
    assert not missing, f"the sweep section's install lacks {missing}"


def test_missing_matplotlib_names_an_extra_that_brings_it(monkeypatch, tmp_path):
    pytest.importorskip("xarray")
    from rdgpu.core.optional import MissingExtraError

    ds = rdgpu.sweep("gray-scott", P, **OK) if find_spec("zarr") else None
    if ds is None:
        pytest.skip("needs the dask extra")
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(MissingExtraError) as info:
        rdgpu.sweep_map(ds, tmp_path / "map.png")
    extra = info.value.extra
    assert f'rdgpu[{extra}]' in str(info.value)
    assert "matplotlib" in _extra(extra)


def test_cli_missing_matplotlib_names_the_extra(capsys, tmp_path, monkeypatch):
    from rdgpu.cli.app import main

    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    monkeypatch.setattr("rdgpu.core.optional.available", lambda m: m.partition(".")[0]
                        != "matplotlib")
    assert main(["sweep", "gray-scott", "--param", "F=0.03,0.04", "--steps", "1",
                 "--out", "map.png"]) == 1
    err = capsys.readouterr().err
    extra = re.search(r'pip install "rdgpu\[(\w+)\]"', err).group(1)
    assert "matplotlib" in err and "matplotlib" in _extra(extra)
    assert not (tmp_path / "map.png").exists()
