"""The grid families launch from their own folders (``rdgpu/families/<family>/<launchers>.py``,
bound by ``Backend.kernel``): a backend without a family's launcher says which one it
lacks, and the families' argument checks, written once, refuse the same input with the
same error on every backend."""

from __future__ import annotations

import numpy as np
import pytest

from rdgpu.backends.numpy_backend import NumpyBackend
from rdgpu.domains import Grid
from rdgpu.families.grid_checks import field_or_number, is_field

BC = Grid((4, 6), dx=1.0, bc="neumann").bcs
BC3 = Grid((3, 4, 6), dx=1.0, bc="neumann").bcs
LS = dict(dt=0.1, dx=1.0, dy=1.0)
RI = dict(dtau=0.1, width=1.0, dx=1.0, dy=1.0)
GS = dict(Du=0.16, Dv=0.08, F=0.035, k=0.06, dt=1.0, dx=1.0, dy=1.0)
SOR = dict(color=0, omega=1.5, dx=1.0, dy=1.0)


class Elsewhere(NumpyBackend):
    """The numpy backend's arrays, with launchers the families do not have."""

    name = "elsewhere"
    launchers = "elsewhere"


def _calls(be):
    """Every grid family's public kernel method, called once with good arguments."""
    u = be.upload(np.ones((4, 6)))
    u3 = be.upload(np.ones((3, 4, 6)))
    mask = be.upload(np.zeros((4, 6), np.uint8))
    change = be.empty((4,), np.float64)
    metric = tuple(be.upload(np.ones((4, 6))) for _ in range(4))
    return {
        "laplacian.laplacian":
            lambda: be.laplacian(u, be.empty_like(u), dx=1.0, dy=1.0, bc=BC, stencil=5),
        "metric.metric_laplacian":
            lambda: be.metric_laplacian(u, metric, be.empty_like(u)),
        "gray_scott.gray_scott":
            lambda: be.gray_scott(u, u, be.empty_like(u), be.empty_like(u), bc=BC, **GS),
        "sor.sor_half_sweep":
            lambda: be.sor_half_sweep(be.empty_like(u), mask, None, change, bc=BC, **SOR),
        "levelset.levelset_step":
            lambda: be.levelset_step(u, 1.0, be.empty_like(u), bc=BC, **LS),
        "levelset.reinit_step":
            lambda: be.reinit_step(u3, u3, be.empty_like(u3), bc=BC3, dz=1.0, **RI),
    }


@pytest.mark.parametrize("kernel", sorted(_calls(NumpyBackend())))
def test_a_backend_without_the_launcher_names_the_family(kernel):
    with pytest.raises(NotImplementedError,
                       match=rf"the 'elsewhere' backend \(Elsewhere\) has no {kernel} kernel"):
        _calls(Elsewhere())[kernel]()
    _calls(NumpyBackend())[kernel]()  # the numpy launchers have it


def test_a_launcher_module_without_the_op_names_it():
    with pytest.raises(NotImplementedError, match="has no laplacian.no_such_op kernel"):
        NumpyBackend().kernel("laplacian", "no_such_op")


def test_the_bound_launcher_is_kept():
    be = NumpyBackend()
    bound = be.kernel("sor", "sor_half_sweep")
    assert be.kernel("sor", "sor_half_sweep") is bound
    assert bound.__name__ == "sor.sor_half_sweep" and "half-sweep" in bound.__doc__


def _bad_inputs(be):
    """(call, error, message) the shared checks give, whatever the backend."""
    u = be.upload(np.ones((4, 6)))
    u32 = be.upload(np.ones((4, 6), np.float32))
    flat = be.upload(np.ones(6))
    out = be.empty_like(u)
    mask = be.upload(np.zeros((4, 6), np.uint8))
    change = be.empty((4,), np.float64)
    u3 = be.upload(np.ones((3, 4, 6)))
    return [
        (lambda: be.laplacian(flat, be.empty_like(flat), dx=1.0, dy=1.0, bc=BC, stencil=5),
         ValueError, r"laplacian input must be a 2-D \[ny, nx\] array, got shape \(6,\)"),
        (lambda: be.laplacian(u, be.empty_like(u32), dx=1.0, dy=1.0, bc=BC, stencil=5),
         ValueError, "laplacian output: shape/dtype"),
        (lambda: be.laplacian(u, out, dx=1.0, dy=2.0, bc=BC, stencil=9),
         ValueError, "the 9-point stencil needs dx == dy"),
        (lambda: be.laplacian(u, out, dx=1.0, dy=1.0, bc=BC, stencil=7),
         ValueError, "stencil must be 5 or 9, got 7"),
        (lambda: be.gray_scott(u, u, out, be.empty_like(u), bc=BC, **{**GS, "F": u32}),
         ValueError, r"gray_scott F field must have the grid's shape \(4, 6\) and dtype "
                     "float64, got"),
        (lambda: be.gray_scott(u, u, out, be.empty_like(u), bc=BC,
                               **{**GS, "k": np.zeros(3)}),
         TypeError, "gray_scott k must be a number or a device array"),
        (lambda: be.sor_half_sweep(u, be.upload(np.zeros((4, 6), bool)), None, change,
                                   bc=BC, **SOR),
         ValueError, r"sor fixed must be a uint8 mask of shape \(4, 6\), got bool"),
        (lambda: be.sor_half_sweep(u, mask, 0.5, change, bc=BC, **SOR),
         TypeError, "sor rhs must be None"),
        (lambda: be.sor_half_sweep(u, mask, None, change, bc=BC, **{**SOR, "color": 2}),
         ValueError, "sor color must be 0 or 1, got 2"),
        (lambda: be.levelset_step(u3, 1.0, be.empty_like(u3), bc=BC3, **LS),
         ValueError, r"levelset: a 3-D phi \(3, 4, 6\) needs the plane spacing dz"),
        (lambda: be.reinit_step(u, u32, out, bc=BC, **RI),
         ValueError, "reinit phi0: shape/dtype"),
    ]


def test_every_backend_refuses_the_same_input_alike(backend):
    for call, error, match in _bad_inputs(backend):
        with pytest.raises(error, match=match):
            call()


def test_a_field_is_a_device_array():
    be = NumpyBackend()
    u = be.upload(np.ones((2, 3)))
    assert is_field(u) and not is_field(1.5) and not is_field(np.float32(2))
    assert not field_or_number(np.float64(0.5), u, "F") and field_or_number(u, u, "F")
    assert not field_or_number(np.array(0.5), u, "F")  # a 0-d array is a number
