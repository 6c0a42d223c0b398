"""The installed wheel, not only the source tree, finds the kernels."""

from __future__ import annotations

import os
import site
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = """
import numpy as np, rdgpu
from rdgpu.families import kernel_dir
print("RDGPU_FILE", rdgpu.__file__)
print("KERNEL_DIR", kernel_dir())
u = np.random.default_rng(0).random((6, 9))
ref = rdgpu.laplacian(u, backend="numpy")
for name in ("warp", "opencl"):
    out = rdgpu.laplacian(u, backend=name)
    assert np.allclose(out, ref, atol=1e-12), name
    be = rdgpu.get_backend(name)
    assert be.max_abs(be.upload(-u)) == float(np.abs(u).max()), name
    assert np.isclose(be.sum_squares(be.upload(u)), float(np.sum(u * u)), rtol=1e-14), name
    print("OK", name)
"""


def _kernel_files(folder: Path) -> set[str]:
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*")
            if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc"}


def test_kernel_sources_are_package_data():
    """The kernels are ordinary files of the package: no force-include, and the wheel
    takes the whole ``rdgpu`` folder."""
    text = (ROOT / "pyproject.toml").read_text()
    assert "force-include" not in text
    assert 'packages = ["rdgpu"]' in text
    files = _kernel_files(ROOT / "rdgpu" / "families")
    assert {"common.cl", "philox.cl", "model/model.cl", "model/blocked.cl",
            "model/warp_model.py.in", "gray_scott/gray_scott.cl", "noise/noise.cl"} <= files


@pytest.mark.slow
def test_wheel_installs_and_runs_every_backend(tmp_path):
    dist = tmp_path / "dist"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(ROOT)],
        check=True,
    )
    wheel = next(dist.glob("rdgpu-*.whl"))
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    python = env_dir / "bin" / "python"
    # install first: once the parent's packages are visible, pip would see this
    # interpreter's own rdgpu as "already satisfied" and skip the wheel
    subprocess.run([python, "-m", "pip", "install", "-q", "--no-deps", "--no-index", str(wheel)],
                   check=True)
    # reuse this interpreter's dependencies (no network): a .pth appends its site-packages
    # *after* the new environment's own, so the wheel's rdgpu wins over any other copy.
    target = Path(
        subprocess.check_output(
            [python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], text=True
        ).strip()
    )
    parents = [sysconfig.get_paths()["purelib"], *site.getsitepackages()]
    (target / "zz_parent.pth").write_text("\n".join(dict.fromkeys(parents)) + "\n")
    # without PYTHONPATH: a source tree on it would win over the installed wheel
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([python, "-c", SCRIPT], capture_output=True, text=True, cwd=tmp_path,
                         env=env)
    assert out.returncode == 0, out.stderr
    lines = dict(line.split(" ", 1) for line in out.stdout.splitlines())
    assert lines["RDGPU_FILE"].startswith(str(env_dir))
    assert lines["KERNEL_DIR"].startswith(str(env_dir))
    assert Path(lines["KERNEL_DIR"], "gray_scott", "gray_scott.cl").is_file()
    assert Path(lines["KERNEL_DIR"], "reduce", "reduce.cl").is_file()
    # every file of every kernel family (.cl, .py, the .py.in template) is in the wheel
    assert _kernel_files(Path(lines["KERNEL_DIR"])) == _kernel_files(ROOT / "rdgpu" / "families")
    assert "OK warp" in out.stdout and "OK opencl" in out.stdout
