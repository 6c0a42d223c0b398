"""The backend seam: a backend defined outside rdgpu (here, in this file) registers itself
and runs a user-defined model through ``Simulation``, bit for bit as the numpy backend does,
with no change inside rdgpu; a backend without the fused-pass method gets a clear error."""

from __future__ import annotations

import numpy as np
import pytest

import rdgpu
from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.backends.registry import get_backend, register_backend, unregister_backend
from rdgpu.backends.target import HostFusedPass
from rdgpu.domains import Grid
from rdgpu.simulation import Simulation


class HostArrays(Backend):
    """A small backend of its own: buffers are NumPy arrays wrapped in a box (so nothing
    can mistake them for the numpy backend's); fused passes run on the host."""

    name = "hostarrays"

    def __init__(self, device: str | None = None):
        self.device = f"host ({device or 'default'})"
        self.passes = 0

    def upload(self, a):
        a = np.array(a, order="C", copy=True)
        return DeviceArray(self, [a], a.shape, a.dtype)

    def download(self, d):
        return d.handle[0].copy()

    def empty(self, shape, dtype):
        dtype = np.dtype(dtype)
        return DeviceArray(self, [np.zeros(shape, dtype)], tuple(shape), dtype)

    def copy(self, src, dst):
        np.copyto(dst.handle[0], src.handle[0].reshape(dst.shape))

    def reshaped(self, d, shape):
        return DeviceArray(self, [d.handle[0].reshape(shape)], tuple(shape), d.dtype)

    def max_abs(self, u):
        a = u.handle[0]
        return float(np.max(np.abs(a))) if a.size else 0.0

    def sum_squares(self, u):
        return float(np.sum(u.handle[0].astype(np.float64) ** 2))

    def fused_pass(self, program, target, fields, member):
        self.passes += 1
        return HostFusedPass(program)


class NoFusedPass(HostArrays):
    """The same backend without a fused pass of its own (the interface's default)."""

    name = "nofused"
    fused_pass = Backend.fused_pass


MODEL = rdgpu.define_model(
    "outside-cross-diffusion",
    {"u": "Du*laplace(u) - 0.5*laplace(v) + u - u**3 - v*exp(-u**2)",
     "v": "Dv*laplace(v) + eps*(u - a*v)"},
    {"Du": 1.0, "Dv": 4.0, "eps": 0.1, "a": 0.5},
)


@pytest.fixture
def registered():
    register_backend("hostarrays", HostArrays, devices="any text")
    register_backend("nofused", NoFusedPass)
    try:
        yield
    finally:
        unregister_backend("hostarrays")
        unregister_backend("nofused")


def _run(backend, method="euler"):
    grid = Grid((12, 16), dx=1.0, bc="periodic")
    sim = Simulation(MODEL, grid, {"a": "0.5 + 0.1*sin(2*pi*x/Lx)"}, dt=0.02,
                     backend=backend, dtype="float64", seed=3,
                     options={"method": method})
    return sim.run(steps=7).fields


@pytest.mark.parametrize("method", ["euler", "rk3"])
def test_a_registered_backend_runs_a_user_model_bit_for_bit(registered, method):
    mine = _run("hostarrays", method)
    reference = _run("numpy", method)
    assert get_backend("hostarrays").passes > 0  # its own passes ran, not numpy's
    for s in ("u", "v"):
        np.testing.assert_array_equal(mine[s], reference[s])
        assert mine[s].tobytes() == reference[s].tobytes()


def test_an_instance_works_too_and_devices_reach_the_factory(registered):
    be = get_backend("hostarrays:gpu7")
    assert be.device == "host (gpu7)"
    np.testing.assert_array_equal(_run(HostArrays())["u"], _run("numpy")["u"])


def test_the_registry_lists_it(registered):
    infos = {i.name: i for i in rdgpu.available_backends()}
    assert infos["hostarrays"].available
    with pytest.raises(ValueError, match="'hostarrays'"):
        get_backend("no-such-backend")
    with pytest.raises(ValueError, match="the nofused backend and takes no device"):
        get_backend("nofused:0")
    with pytest.raises(ValueError, match="already registered"):
        register_backend("hostarrays", HostArrays)


def test_a_backend_without_fused_passes_says_so(registered):
    with pytest.raises(NotImplementedError,
                       match=r"the 'nofused' backend \(NoFusedPass\) cannot run a model's "
                             r"fused pass: it does not implement Backend\.fused_pass"):
        _run("nofused")


def test_a_missing_hand_written_kernel_names_the_backend():
    be = HostArrays()
    u = be.upload(np.zeros((4, 4)))
    with pytest.raises(NotImplementedError, match="'hostarrays' backend .* no bernoulli"):
        be.bernoulli(u, be.empty_like(u), decay=0.5)


def test_register_backend_checks_its_arguments():
    with pytest.raises(ValueError, match="not 'auto'"):
        register_backend("auto", HostArrays)
    with pytest.raises(TypeError, match="factory must be callable"):
        register_backend("x", 3)
