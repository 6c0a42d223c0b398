"""Shared fixtures: the backends to cross-check and the reference modules."""

from __future__ import annotations

import os

import numpy as np
import pytest

import rdgpu
from rdgpu.core.errors import BackendUnavailableError
from rdgpu.families import load_module

BACKENDS = ["numpy", "warp", "opencl"]
DTYPES = [np.float32, np.float64]

#: the Warp device of the suite's "warp" backends (``get_backend("warp")`` and the
#: "warp-cells" variant): the CPU unless RDGPU_TEST_WARP_DEVICE names another, e.g.
#: ``cuda:0`` to run the suite on a GPU (OpenCL's device comes from RDGPU_OPENCL_DEVICE)
WARP_DEVICE = os.environ.get("RDGPU_TEST_WARP_DEVICE", "").strip().lower() or "cpu"
if WARP_DEVICE != "cpu":
    from rdgpu.backends import registry as _dispatch

    _real_construct = _dispatch._construct

    def _construct_on_test_device(name, device):
        return _real_construct(name, device or (WARP_DEVICE if name == "warp" else None))

    _dispatch._construct = _construct_on_test_device


def cli(capsys, *argv):
    """Run the ``rdgpu`` command in-process: (exit status, stdout, stderr)."""
    from rdgpu.cli.app import main

    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse: --help and usage errors
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def backend_or_skip(name: str):
    """The backend, or a skip where it cannot run -- a failure on CI, where all must run."""
    try:
        return rdgpu.get_backend(name)
    except BackendUnavailableError as exc:
        if os.environ.get("CI"):
            pytest.fail(f"backend {name} unavailable on CI: {exc}")
        pytest.skip(f"backend {name} unavailable: {exc}")


@pytest.fixture(params=BACKENDS)
def backend(request):
    return backend_or_skip(request.param)


#: every backend plus the GPU launch shapes run on the CPU: Warp's one-thread-per-cell
#: kernels and OpenCL's strided layout
VARIANTS = ["numpy", "warp", "warp-cells", "opencl", "opencl-strided"]


@pytest.fixture(params=VARIANTS)
def variant_backend(request):
    """A backend of :data:`VARIANTS` (skipped where unavailable)."""
    return variant_or_skip(request.param)


def variant_or_skip(name: str):
    """The backend of :data:`VARIANTS` called ``name`` (skipped where unavailable)."""
    base = backend_or_skip(name.split("-")[0])
    if name == "warp-cells":
        from rdgpu.backends.warp_backend import WarpBackend

        return WarpBackend(WARP_DEVICE, launch="cells")
    if name == "opencl-strided":
        from rdgpu.backends.opencl_backend import OpenCLBackend

        return OpenCLBackend(layout="strided", col_stride=4)
    return base


@pytest.fixture(params=DTYPES, ids=["f32", "f64"])
def dtype(request):
    return np.dtype(request.param)


@pytest.fixture(scope="session")
def ref():
    """The NumPy reference modules, by family."""

    class Refs:
        laplacian = load_module("laplacian", "reference.py")
        bernoulli = load_module("bernoulli", "reference.py")
        gray_scott = load_module("gray_scott", "reference.py")
        sor = load_module("sor", "reference.py")
        levelset = load_module("levelset", "reference.py")

    return Refs


def tolerance(dtype, scale: float = 1.0) -> dict:
    """Round-off tolerance for comparing two implementations of one kernel: a few ulps of
    the largest term (``scale``), so it fails on any real disagreement."""
    eps = np.finfo(dtype).eps
    return {"rtol": 16 * eps, "atol": 16 * eps * scale}


def interrupt_after(sim, steps: int, exc: type[BaseException] = KeyboardInterrupt) -> None:
    """Make ``sim``'s stepper raise ``exc`` rather than advance past ``steps`` steps in all
    (a kill at a known point of a run, for the checkpoint and Ctrl-C tests)."""
    real, done = sim.stepper.advance, [0]

    def advance(n: int) -> None:
        if done[0] + n > steps:
            raise exc
        done[0] += n
        real(n)

    sim.stepper.advance = advance
