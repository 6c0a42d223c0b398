"""Backend selection: available_backends, set_backend, use_backend, RDGPU_BACKEND, auto."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import rdgpu
from rdgpu.backends import registry as dispatch


@pytest.fixture(autouse=True)
def _reset_default():
    yield
    rdgpu.set_backend(None)


def test_available_backends_reports_all_three():
    infos = {i.name: i for i in rdgpu.available_backends()}
    assert set(infos) >= {"numpy", "warp", "opencl"}
    assert infos["numpy"].available
    for info in infos.values():
        assert (info.device if info.available else info.reason)
        assert str(info).startswith(info.name)


def test_precedence_call_over_context_over_default(monkeypatch):
    monkeypatch.setenv("RDGPU_BACKEND", "warp")
    assert rdgpu.get_backend().name == "warp"
    rdgpu.set_backend("numpy")
    assert rdgpu.get_backend().name == "numpy"
    with rdgpu.use_backend("opencl") as be:
        assert be.name == "opencl"
        assert rdgpu.get_backend().name == "opencl"
        assert rdgpu.get_backend("numpy").name == "numpy"
        with rdgpu.use_backend("warp"):
            assert rdgpu.get_backend().name == "warp"
        assert rdgpu.get_backend().name == "opencl"
    assert rdgpu.get_backend().name == "numpy"


def test_auto_prefers_opencl_on_cpu(monkeypatch):
    monkeypatch.setattr(dispatch, "_cuda_available", lambda: False)
    dispatch._instances.pop(("auto", None), None)
    try:
        assert rdgpu.get_backend("auto").name == "opencl"
    finally:
        dispatch._instances.pop(("auto", None), None)


def test_auto_falls_back_when_opencl_missing(monkeypatch):
    def no_opencl(name, device):
        if name == "opencl":
            raise rdgpu.BackendUnavailableError("no OpenCL platform (test)")
        return real(name, device)

    real = dispatch._construct
    monkeypatch.setattr(dispatch, "_cuda_available", lambda: False)
    monkeypatch.setattr(dispatch, "_construct", no_opencl)
    monkeypatch.setattr(dispatch, "_instances", {})
    assert rdgpu.get_backend("auto").name == "warp"


def test_environment_variable_selects_backend():
    code = "import rdgpu; print(rdgpu.get_backend().name)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**__import__("os").environ, "RDGPU_BACKEND": "numpy"}, check=True)
    assert out.stdout.strip() == "numpy"


def test_opencl_device_by_name_and_index():
    be = rdgpu.get_backend("opencl")
    word = be.device.split()[0].split("-")[0]  # e.g. "pthread" for PoCL's CPU device
    by_name = rdgpu.get_backend(f"opencl:{word}")
    assert by_name.name == "opencl" and by_name.device == be.device
    by_index = rdgpu.get_backend("opencl:0:0")
    assert by_index.name == "opencl"
    u = np.random.default_rng(0).random((5, 7))
    np.testing.assert_allclose(rdgpu.laplacian(u, backend=by_name),
                               rdgpu.laplacian(u, backend="numpy"), atol=1e-12)


def test_opencl_device_from_environment():
    be = rdgpu.get_backend("opencl")
    word = be.device.split()[0].split("-")[0]
    code = "import rdgpu; print(rdgpu.get_backend('opencl').device)"
    env = {**__import__("os").environ, "RDGPU_OPENCL_DEVICE": word}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True)
    assert out.stdout.strip() == be.device
    env["RDGPU_OPENCL_DEVICE"] = "no-such-device"
    bad = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert bad.returncode != 0 and "no-such-device" in bad.stderr


def test_same_result_from_every_backend_via_context():
    u = np.random.default_rng(1).random((9, 10))
    results = []
    for name in ("numpy", "warp", "opencl"):
        with rdgpu.use_backend(name):
            results.append(rdgpu.laplacian(u, bc="neumann"))
    for r in results[1:]:
        np.testing.assert_allclose(r, results[0], atol=1e-12)
