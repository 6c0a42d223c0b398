"""The install sized to the need: the core (NumPy, SciPy, ducc0, Warp, PyOpenCL + PoCL, tqdm) runs
the kernels, Simulation and ``rdgpu run --data``; every optional package, made unimportable
(``sys.modules[name] = None``, as Python does for a package that is not there), gives an
ImportError that names the extra installing it."""

from __future__ import annotations

import json
import pickle
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from conftest import cli

import rdgpu
from rdgpu.core import optional as _optional
from rdgpu.core.optional import EXTRAS, PIP_NAMES, MissingExtraError, available, check, require
from rdgpu.domains.grid import Grid
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.io import images, output

ROOT = Path(__file__).resolve().parents[2]
OPTIONAL = sorted((m, extra) for extra, modules in EXTRAS.items() for m in modules)
#: what the core install holds (distribution names, normalised)
CORE = {"numpy", "scipy", "ducc0", "warp-lang", "pyopencl", "pocl-binary-distribution", "tqdm"}


def _hint(extra: str) -> str:
    return f'pip install "rdgpu[{extra}]"'


def _tetrahedron() -> SurfaceMesh:
    """A closed mesh built without trimesh."""
    v = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=np.float64)
    f = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    return SurfaceMesh(v, f)


# ------------------------------------------------------------------------ pyproject.toml
def _pyproject() -> dict:
    try:
        import tomllib
    except ImportError:  # Python 3.10
        tomllib = pytest.importorskip("tomli")
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def _names(requirements: list[str]) -> set[str]:
    """Distribution names of requirement strings, each with its own extras:
    ``"dask[distributed]>=2024.1"`` → {"dask", "distributed"}."""
    out = set()
    for req in requirements:
        m = re.match(r"\s*([A-Za-z0-9._-]+)\s*(?:\[([^\]]*)\])?", req)
        assert m, f"unreadable requirement {req!r}"
        out.add(m.group(1).lower().replace("_", "-"))
        out.update(e.strip().lower() for e in (m.group(2) or "").split(",") if e.strip())
    return out


def test_core_dependencies_hold_no_optional_package():
    project = _pyproject()["project"]
    core = _names(project["dependencies"])
    assert core == CORE
    optional = {PIP_NAMES.get(m, m).replace("_", "-") for m, _ in OPTIONAL}
    assert not core & optional
    extras = project["optional-dependencies"]
    for extra in EXTRAS:
        assert not core & _names(extras[extra]), extra


@pytest.mark.parametrize(("module", "extra"), OPTIONAL)
def test_each_optional_module_is_in_its_extra(module, extra):
    extras = _pyproject()["project"]["optional-dependencies"]
    assert PIP_NAMES.get(module, module) in _names(extras[extra])


def test_all_and_test_extras_hold_every_extra():
    extras = _pyproject()["project"]["optional-dependencies"]
    assert extras["all"] == [f"rdgpu[{','.join(EXTRAS)}]"]
    assert "rdgpu[all]" in extras["test"]
    # docs: the site; bench: the peers `rdgpu bench --peers` times (other tools, not rdgpu)
    assert set(extras) == {*EXTRAS, "all", "bench", "docs", "test"}
    assert "rdgpu[bench]" not in extras["test"]  # CI never needs the peers


def test_ci_runs_the_readmes_test_command():
    """The README's test command installs the test extra (everything) and ``.ci/run``
    runs it."""
    command = 'python -m pip install ".[test]" && python -m pytest'
    assert command in (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    assert all(part in ci.splitlines() for part in command.split(" && "))


# ------------------------------------------------------------------------ the helper
@pytest.mark.parametrize(("module", "extra"), OPTIONAL)
def test_a_missing_module_names_its_extra(module, extra, monkeypatch):
    monkeypatch.setitem(sys.modules, module, None)
    assert not available(module)
    with pytest.raises(MissingExtraError) as info:
        require(module, "doing the thing")
    assert info.value.extra == extra and info.value.module == module
    package = PIP_NAMES.get(module, module)
    assert str(info.value) == f"doing the thing needs {package}: {_hint(extra)}"
    back = pickle.loads(pickle.dumps(info.value))  # e.g. raised in a Dask worker
    assert (str(back), back.extra, back.module) == (str(info.value), extra, module)
    with pytest.raises(ImportError, match=re.escape(_hint(extra))):
        check(f"{module}.sub", "doing the thing")


def test_a_broken_install_says_so(tmp_path, monkeypatch):
    """Installed but failing to import (a missing dependency of its own): the cause is
    shown, not only the extra."""
    (tmp_path / "meshio").mkdir()
    (tmp_path / "meshio" / "__init__.py").write_text("import rdgpu_no_such_module_xyz\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "meshio", raising=False)
    with pytest.raises(MissingExtraError, match="installed but fails to import.*"
                       r"rdgpu_no_such_module_xyz.*rdgpu\[mesh\]"):
        require("meshio", "reading with meshio")


def test_a_core_or_unknown_module_is_refused():
    for name in ("numpy", "scipy.sparse", "pyvsta"):
        with pytest.raises(ValueError, match="not an optional package of rdgpu"):
            require(name, "x")
    with pytest.raises(ValueError, match="the extras are mesh, media, dask, pypde"):
        _optional.install_hint("gui")


def test_present_modules_are_returned():
    for module, _ in OPTIONAL:
        if available(module):
            assert require(module, "x") is sys.modules[module]
            check(module, "x")


# ------------------------------------------------------------ library calls, one missing
def _field() -> np.ndarray:
    return np.random.default_rng(0).random((6, 8))


CALLS = {
    "png": ("imageio", "media", "writing PNG pictures",
            lambda tmp: output.save_png(tmp / "a.png", _field(), Grid((6, 8)))),
    "colours": ("matplotlib", "media", "colouring pictures", lambda tmp: images.to_rgb(_field())),
    "line plot": ("matplotlib", "media", "plotting a 1-D field",
                  lambda tmp: output.save_png(tmp / "a.png", _field()[0], Grid((8,)))),
    "gif": ("imageio", "media", "writing GIF movies",
            lambda tmp: output.save_movie(tmp / "m.gif", np.stack([_field()] * 2))),
    "mesh picture": ("pyvista", "mesh", "rendering the mesh",
                     lambda tmp: output.save_png(tmp / "a.png", np.arange(4.0), _tetrahedron())),
    "vtk file": ("pyvista", "mesh", "SurfaceMesh.to_pyvista",
                 lambda tmp: _tetrahedron().save(tmp / "a.vtk")),
    "icosphere": ("trimesh", "mesh", "SurfaceMesh.icosphere",
                  lambda tmp: SurfaceMesh.icosphere(1)),
    "sweep": ("xarray", "dask", "rdgpu.sweep",
              lambda tmp: rdgpu.sweep("gray-scott", {"F": [0.03, 0.04]}, steps=1,
                                      scheduler="serial")),
}


@pytest.mark.parametrize("case", sorted(CALLS))
def test_a_library_call_names_the_missing_extra(case, tmp_path, monkeypatch):
    module, extra, purpose, call = CALLS[case]
    monkeypatch.setitem(sys.modules, module, None)
    with pytest.raises(MissingExtraError) as info:
        call(tmp_path)
    package = PIP_NAMES.get(module, module)
    assert str(info.value) == f"{purpose} needs {package}: {_hint(extra)}"
    assert not list(tmp_path.iterdir())  # refused before anything was written


# ------------------------------------------------------------ the CLI, one missing
RUN = ["run", "gray-scott", "--size", "16", "--steps", "2", "--quiet"]
CLI_CASES = {
    "png": ("imageio", "media", [*RUN, "--out", "a.png"]),
    "default png": ("matplotlib", "media", RUN),
    "mp4": ("imageio_ffmpeg", "media", [*RUN, "--snapshot-every", "1", "--movie", "m.mp4"]),
    "mesh": ("pyvista", "mesh", ["run", "gray-scott", "--mesh", "uv-sphere", "--steps", "2",
                                 "--quiet", "--out", "a.png"]),
    "isosurface": ("pyvista", "mesh", ["run", "gray-scott", "--size", "4x4x4", "--steps", "1",
                                       "--quiet", "--view", "isosurface", "--out", "a.png"]),
    "cmap": ("matplotlib", "media", [*RUN, "--cmap", "magma", "--out", "a.png"]),
    "dla": ("imageio", "media", ["run", "dla", "--size", "16", "--steps", "2", "--quiet"]),
    "sweep": ("distributed", "dask", ["sweep", "gray-scott", "--param", "F=0.03,0.04",
                                      "--steps", "1", "--quiet"]),
    "sweep map": ("matplotlib", "media", ["sweep", "gray-scott", "--param", "F=0.03,0.04",
                                          "--size", "8", "--steps", "1", "--quiet"]),
}


@pytest.mark.parametrize("case", sorted(CLI_CASES))
def test_the_cli_names_the_missing_extra_before_running(case, capsys, tmp_path, monkeypatch):
    module, extra, argv = CLI_CASES[case]
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, module, None)
    code, out, err = cli(capsys, *argv)
    assert code == 1
    assert err.startswith("rdgpu: error: ") and err.count("\n") == 1
    assert f"needs {PIP_NAMES.get(module, module)}: {_hint(extra)}" in err
    assert not list(tmp_path.iterdir())  # nothing ran, nothing was written
    if case.startswith("default"):
        assert "or give --data PATH.npz" in err


def test_the_cli_writes_data_without_media(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for module in EXTRAS["media"]:
        monkeypatch.setitem(sys.modules, module, None)
    code, _, err = cli(capsys, *RUN, "--data", "a.npz")
    assert code == 0, err
    with np.load(tmp_path / "a.npz") as z:
        assert np.isfinite(z["final_u"]).all() and z["final_u"].shape == (16, 16)


# ------------------------------------------------------------ the core alone
CORE_SCRIPT = """
import contextlib, io, json, sys
blocked = json.loads(sys.argv[1])
for name in blocked:
    sys.modules[name] = None  # as if not installed: import raises ModuleNotFoundError
import numpy as np
import rdgpu
from rdgpu.cli import main
from rdgpu.domains import Grid

rng = np.random.default_rng(0)
u = rng.random((12, 10))
ref = rdgpu.laplacian(u, backend="numpy")
ran = []
for info in rdgpu.available_backends():
    if info.available and info.name != "numpy":
        out = rdgpu.laplacian(u, backend=info.name)
        assert np.allclose(out, ref, atol=1e-12), info.name
        ran.append(info.name)
u2, v2 = rdgpu.gray_scott(np.ones((8, 8)), np.zeros((8, 8)), Du=0.16, Dv=0.08, F=0.035,
                          k=0.06, dt=1.0, steps=3)
sim = rdgpu.Simulation("gray-scott", Grid((16, 16)), {}, dt=1.0, seed=1)
result = sim.run(4)
assert all(np.isfinite(f).all() for f in result.fields.values())
err = io.StringIO()
with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
    data = main(["run", "gray-scott", "--size", "16", "--steps", "2", "--quiet", "--data",
                 sys.argv[2] + "/a.npz"])
    picture = main(["run", "gray-scott", "--size", "16", "--steps", "2", "--quiet", "--out",
                    sys.argv[2] + "/a.png"])
loaded = sorted(m for m in blocked if sys.modules.get(m) is not None)
print(json.dumps({"ran": ran, "data": data, "picture": picture, "err": err.getvalue(),
                  "loaded": loaded, "sim": sim.backend.name}))
"""


def test_the_core_runs_with_every_extra_missing(tmp_path):
    """A fresh interpreter without any optional package (nor VTK, pyvista's renderer):
    ``import rdgpu``, the kernels on every backend here, Simulation and ``rdgpu run --data``
    work; ``rdgpu run --out`` names the media extra."""
    blocked = [m for m, _ in OPTIONAL] + ["vtk", "vtkmodules"]
    script = textwrap.dedent(CORE_SCRIPT)
    proc = subprocess.run([sys.executable, "-c", script, json.dumps(blocked), str(tmp_path)],
                          capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["loaded"] == []
    here = [i.name for i in rdgpu.available_backends() if i.available and i.name != "numpy"]
    assert report["ran"] == here
    assert report["data"] == 0 and (tmp_path / "a.npz").is_file()
    assert report["picture"] == 1 and not (tmp_path / "a.png").exists()
    assert f"writing the PNG picture needs imageio: {_hint('media')}" in report["err"]
