"""The IR side of the compiler: the one stencil table per domain kind, the stencil walk both
printers share, and the NumPy semantics of a Program against the numpy backend's pass."""

from __future__ import annotations

import re

import numpy as np
import pytest

from rdgpu.backends.opencl_codegen import opencl_source
from rdgpu.backends.registry import get_backend
from rdgpu.backends.target import Target
from rdgpu.backends.warp_codegen import warp_source
from rdgpu.domains import Grid
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.integrators.passes import launch
from rdgpu.ir import equations as eq
from rdgpu.ir.program import Output, Program
from rdgpu.ir.reference import run_numpy
from rdgpu.ir.stencils import STENCIL_KINDS, neighbour_values, stencil_kind


def _program(zero=frozenset()):
    u = eq.parse("D*laplace(u) + u*v", species=("u", "v"), params=("D",))
    v = eq.parse("laplace(v) - u", species=("u", "v"))
    return Program(("u", "v"), (Output("u", u), Output("v", v)), zero)


@pytest.mark.parametrize("kind, count", [("grid1", 2), ("grid2", 4), ("grid3", 6),
                                         ("grid2iso", 8), ("grid3iso", 18),
                                         ("grid2metric", 8), ("mesh", 1)])
def test_the_table_says_what_each_kind_reads(kind, count):
    row = STENCIL_KINDS[kind]
    assert len(row.neighbours) == count
    for nb in row.neighbours:  # a neighbour's ghost rules are its sides, outer axis first
        assert "".join(side for side, _ in nb.ghosts) == (nb.name if kind != "mesh" else "")


def test_the_stencil_kind_comes_from_the_domain_kind():
    assert stencil_kind(Grid((8,))) == "grid1"
    assert stencil_kind(Grid((4, 8)), "isotropic") == "grid2iso"
    assert stencil_kind(Grid((4, 4, 8)), "compact") == "grid3"
    height = np.zeros((6, 8))
    assert stencil_kind(GraphSurface((6, 8), dx=1.0, dy=1.0, height=height)) == "grid2metric"


def test_the_walk_applies_ghosts_inner_axis_first_and_zero_ghosts():
    program = _program(zero=frozenset({"v"}))
    walked = list(neighbour_values(
        program, "grid2iso", lambda nb, i: f"{i}@{nb.name}",
        lambda side, ghost, value: f"[{side}:{ghost}]{value}", frozenset(), str, None))
    assert ("sw", "u", "[s:gy][w:gx]u@sw") in walked
    assert ("e", "v", "[e:0]v@e") in walked
    assert len(walked) == 2 * 8


@pytest.mark.parametrize("kind", sorted(STENCIL_KINDS))
def test_both_printers_read_the_same_neighbours(kind):
    program = _program()
    warp = set(re.findall(r"\b_q([a-z]+)_[uv]\b", warp_source(program, kind, frozenset(),
                                                                np.float64)))
    cl = set(re.findall(r"\b_q([a-z]+)_[uv]\b", opencl_source(program, kind, frozenset(),
                                                              np.float64)))
    expected = {nb.name for nb in STENCIL_KINDS[kind].neighbours}  # a mesh's: its column
    assert cl == expected
    assert warp == expected


@pytest.mark.parametrize("shape", [(9,), (5, 7), (3, 4, 5)])
def test_the_numpy_pass_is_the_reference(shape):
    be = get_backend("numpy")
    target = Target.bind(Grid(shape, dx=0.5, bc="neumann"), be, np.float64)
    rng = np.random.default_rng(0)
    x = {s: rng.random(target.field_shape) for s in ("u", "v")}
    program = _program()
    outs = [be.empty(target.field_shape, np.float64) for _ in range(2)]
    launch(program, target, [be.upload(x["u"]), be.upload(x["v"])], outs, {"D": 0.3}, {})
    expected = run_numpy(program, target, x, {"D": 0.3}, {}, 0.0)
    for o, buf in zip(program.outputs, outs, strict=True):
        assert buf.numpy().tobytes() == expected[o.name].tobytes()
