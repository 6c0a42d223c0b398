"""Random-walker DLA (``rdgpu.random_walk_dla``, rdgpu/families/walkers): Philox-4x32-10 against
its known answers, the same streams and the same clusters on every backend, connected
clusters, the counts, the stopping flags and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import backend_or_skip

import rdgpu
from rdgpu.families import load_module

ref = load_module("walkers", "reference.py")

# Random123's published known-answer vectors of philox4x32-10: (counter, key, output)
KAT = [
    ((0, 0, 0, 0), (0, 0), (0x6627E8D5, 0xE169C58D, 0xBC57AC4C, 0x9B00DBD8)),
    ((0xFFFFFFFF,) * 4, (0xFFFFFFFF, 0xFFFFFFFF),
     (0x408F276D, 0x41C83B0E, 0xA20BC7C6, 0x6D5451FD)),
    ((0x243F6A88, 0x85A308D3, 0x13198A2E, 0x03707344), (0xA4093822, 0x299F31D0),
     (0xD16CFE09, 0x94FDCCEB, 0x5001E420, 0x24126EA1)),
]
BACKENDS = ["numpy", "warp", "opencl"]


def _device_philox(be, n, first, t, purpose, seed) -> np.ndarray:
    out = be.empty((n, 4), np.uint32)
    be.philox(out, first=first, t=t, purpose=purpose, seed=seed)
    return be.download(out)


@pytest.mark.parametrize("ctr,key,expected", KAT)
def test_philox_reference_known_answers(ctr, key, expected):
    assert tuple(int(x) for x in ref.philox4x32(ctr, key)) == expected


@pytest.mark.parametrize("name", BACKENDS)
@pytest.mark.parametrize("ctr,key,expected", KAT)
def test_philox_backend_known_answers(name, ctr, key, expected):
    be = backend_or_skip(name)
    got = _device_philox(be, 1, ctr[0], ctr[1] | ctr[2] << 32, ctr[3], key[0] | key[1] << 32)
    assert tuple(int(x) for x in got[0]) == expected


@pytest.mark.parametrize("name", ["warp", "opencl"])
@pytest.mark.parametrize("first,t,purpose,seed", [(0, 0, 0, 0), (7, 2**33 + 5, 1, 12345),
                                                  (2**32 - 100, 2**40, 2, 2**64 - 1)])
def test_philox_streams_equal_numpy(name, first, t, purpose, seed):
    be = backend_or_skip(name)
    n = 4096 if first == 0 else 100  # the last case wraps the walker word
    expected = _device_philox(rdgpu.get_backend("numpy"), n, first, t, purpose, seed)
    got = _device_philox(be, n, first, t, purpose, seed)
    np.testing.assert_array_equal(got, expected)
    assert len(np.unique(expected)) > 3.9 * n  # not a constant or a short cycle


def _grow(backend, geometry, sticking, **kw):
    args = dict(particles=200, geometry=geometry, sticking=sticking, seed=3, walkers=64)
    args.update(kw)
    return rdgpu.random_walk_dla((64, 64), backend=backend, **args)


@pytest.mark.parametrize("geometry", ["radial", "slab"])
@pytest.mark.parametrize("sticking", [1.0, 0.3])
def test_same_cluster_on_every_backend(geometry, sticking):
    results = {}
    for name in BACKENDS:
        results[name] = _grow(backend_or_skip(name), geometry, sticking)
    base = results["numpy"]
    assert base.stopped == "particles" and base.particles_added == 200
    for name, r in results.items():
        np.testing.assert_array_equal(r.arrival, base.arrival, err_msg=name)
        np.testing.assert_array_equal(r.mask, base.mask, err_msg=name)
        assert (r.walker_steps, r.steps, r.stopped) == (base.walker_steps, base.steps,
                                                        base.stopped), name
    other_seed = _grow("numpy", geometry, sticking, seed=4)
    assert not np.array_equal(other_seed.arrival, base.arrival)


def _assert_connected(arrival: np.ndarray, periodic_x: bool) -> None:
    """Every particle cell is 4-adjacent to a cell that joined before it."""
    a = arrival.astype(np.int64)
    big = np.iinfo(np.int64).max
    pad = np.full((a.shape[0] + 2, a.shape[1] + 2), big)
    pad[1:-1, 1:-1] = np.where(a >= 0, a, big)
    if periodic_x:
        pad[1:-1, 0], pad[1:-1, -1] = pad[1:-1, -2], pad[1:-1, 1]
    earliest = np.minimum.reduce([pad[:-2, 1:-1], pad[2:, 1:-1], pad[1:-1, :-2], pad[1:-1, 2:]])
    cells = a > 0
    assert np.all(earliest[cells] < a[cells])


@pytest.mark.parametrize("geometry", ["radial", "slab"])
@pytest.mark.parametrize("sticking", [1.0, 0.3])
def test_cluster_connected_and_counted(geometry, sticking):
    r = _grow("opencl" if "opencl" in _available() else "numpy", geometry, sticking)
    _assert_connected(r.arrival, geometry == "slab")
    joined = np.sort(r.arrival[r.arrival > 0])
    np.testing.assert_array_equal(joined, np.arange(1, 201))
    seeds = 1 if geometry == "radial" else 64
    assert r.mask.sum() == 200 + seeds and r.mask.dtype == bool
    assert r.arrival.dtype == np.int32 and np.all(r.arrival[~r.mask] == -1)
    assert r.walker_steps == r.steps * 64
    assert r.settings["sticking"] == sticking and r.settings["geometry"] == geometry


def _available():
    return [i.name for i in rdgpu.available_backends() if i.available]


@pytest.mark.parametrize("geometry", ["radial", "slab"])
def test_stops_at_the_edge(geometry):
    shape = (24, 24) if geometry == "radial" else (16, 24)
    results = [rdgpu.random_walk_dla(shape, particles=300, geometry=geometry, walkers=32,
                                     backend=backend_or_skip(b)) for b in BACKENDS]
    r = results[0]
    assert r.stopped == "edge" and 0 < r.particles_added < 300
    assert (r.arrival > 0).sum() == r.particles_added
    _assert_connected(r.arrival, geometry == "slab")
    for other in results[1:]:
        np.testing.assert_array_equal(other.arrival, r.arrival)
    if geometry == "radial":  # the launch circle, margin 5 outside, would leave the grid
        i, j = np.nonzero(r.mask)
        d = np.sqrt((i - 12.0) ** 2 + (j - 12.0) ** 2).max()
        assert np.ceil(d) + 5 > 11
    else:
        assert np.nonzero(r.mask.any(axis=1))[0].max() + 5 > 15


def test_stops_after_max_steps():
    r = rdgpu.random_walk_dla((64, 64), particles=1000, walkers=16, max_steps=10,
                              backend="numpy", batch=4)
    assert r.stopped == "max_steps" and r.steps == 10 and r.walker_steps == 160
    assert r.particles_added == (r.arrival > 0).sum() < 1000


def test_reference_resolve_lowest_id_first_and_release():
    """Two walkers wanting one cell: walker 0 takes it, both are re-released on the ring of
    radius EXT + margin; a walker standing on the object is re-released by the step."""
    shape = (21, 21)
    start, ring = ref.ring_table(10)
    grid = np.zeros(shape, np.uint8)
    grid[10, 10] = 1
    arrival = np.full(shape, -1, np.int32)
    arrival[10, 10] = 0
    pos = np.array([[9, 10], [9, 10], [3, 3]], np.int32)
    want = np.array([1, 1, 0], np.int32)
    state = np.zeros(4, np.int32)
    ref.resolve(grid, arrival, pos, want, state, start, ring, t=0, key=(1, 0), geometry=0,
                margin=5, particles=10, limit=10)
    assert arrival[9, 10] == 1 and state[ref.COUNT] == 1 and state[ref.EXT] == 1
    assert (arrival >= 0).sum() == 2
    for w in (0, 1):
        d = np.hypot(pos[w, 0] - 10, pos[w, 1] - 10)
        assert round(d) == 6
    assert tuple(pos[2]) == (3, 3)  # it did not want to stick: untouched
    pos[2] = (9, 10)  # now on an object cell
    ref.walk_step(grid, pos, want, state, start, ring, t=1, key=(1, 0), geometry=0,
                  thresh=2**32, margin=5)
    assert round(np.hypot(pos[2, 0] - 10, pos[2, 1] - 10)) == 6 and want[2] == 0


@pytest.mark.parametrize("kwargs,match", [
    (dict(shape=(64,)), "shape"),
    (dict(shape=(64, 0)), "too small"),
    (dict(shape=(8, 8)), "too small"),
    (dict(shape=(64, 64.0)), "shape"),
    (dict(sticking=0.0), "sticking"),
    (dict(sticking=1.5), "sticking"),
    (dict(sticking=-0.1), "sticking"),
    (dict(particles=64 * 64), "particles"),
    (dict(particles=0), "particles"),
    (dict(geometry="square"), "geometry"),
    (dict(walkers=0), "walkers"),
    (dict(max_steps=0), "max_steps"),
    (dict(seed=-1), "seed"),
])
def test_bad_input(kwargs, match):
    args = dict(shape=(64, 64), particles=10, backend="numpy")
    args.update(kwargs)
    shape = args.pop("shape")
    with pytest.raises(ValueError, match=match):
        rdgpu.random_walk_dla(shape, **args)


def test_radial_cluster_is_dla_like():
    """Sticking 1, few walkers in flight: the mass-radius dimension (slope of log M(r) on
    log r, r from 3 cells to half the largest radius) is near DLA's 1.7, far from a compact
    disc's 2 and a line's 1."""
    be = backend_or_skip("warp")
    r = rdgpu.random_walk_dla((160, 160), particles=1500, walkers=32, backend=be, seed=0)
    assert r.stopped == "particles"
    i, j = np.nonzero(r.mask)
    d = np.hypot(i - 80, j - 80)
    radii = np.geomspace(3.0, 0.5 * d.max(), 12)
    slope = np.polyfit(np.log(radii), np.log([(d <= x).sum() for x in radii]), 1)[0]
    assert 1.55 < slope < 1.85
