"""``Backend.max_abs`` (kernels/reduce) on every backend and launch shape, bit for bit the
NumPy reference ``float(np.max(np.abs(u)))``: random arrays of odd, tiny, non-square and
multi-chunk shapes in both dtypes; NaN, ±inf and the largest value at many positions
(first, last, vector lanes, chunk edges, peeled tails); negative extremes, -0.0, arrays
whose only non-zeros are subnormal, empty arrays; wrong dtypes and foreign arrays; buffer
reuse between calls and threads; the OpenCL kernel on Oclgrind; perf/reduce.py at tiny
sizes (no timing is asserted)."""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from conftest import VARIANTS, backend_or_skip, repo_module, variant_or_skip
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from test_oclgrind import check_clean_under_oclgrind, oclgrind_available

from rdgpu.kernel_files import load_module

reference = load_module("reduce", "reference.py").max_abs

SHAPES = [1, 7, (3, 5), (1, 1000), (17, 33), (4, 5, 6), 100_003]
#: a length past every chunk and block of the CPU shapes (65 536 elements), past the
#: first pass of Warp's CUDA shape (2^18 threads) and past the 1024 × 256 work-items of
#: OpenCL's strided layout (so its grid-stride loop strides)
LONG = 600_001
#: positions in an array of LONG elements: ends, vector lanes, chunk and block edges
POSITIONS = [0, 1, 3, 7, 8, 15, 16, 31, 63, 64, 65_535, 65_536, 65_537, 131_072,
             262_143, 262_144, 262_145, 300_000, LONG - 17, LONG - 2, LONG - 1]
DTYPES = [np.float32, np.float64]


def same(got: float, want: float) -> bool:
    """Equal bit for bit as float64 (so 0.0 is not -0.0), or both NaN."""
    if math.isnan(want):
        return math.isnan(got)
    return np.float64(got).view(np.uint64) == np.float64(want).view(np.uint64)


@pytest.fixture(params=VARIANTS)
def be(request):
    return variant_or_skip(request.param)


@pytest.fixture(scope="module")
def noise():
    """LONG values in [-1, 1] per dtype (no special values)."""
    rng = np.random.default_rng(12)
    base = rng.uniform(-1, 1, LONG)
    return {np.dtype(d): base.astype(d) for d in DTYPES}


def check(be, a: np.ndarray) -> float:
    got = be.max_abs(be.upload(a))
    want = reference(a)
    assert isinstance(got, float)
    assert same(got, want), (got, want, a.dtype, a.shape)
    return got


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
@pytest.mark.parametrize("shape", SHAPES, ids=str)
def test_random_shapes(be, shape, dtype):
    rng = np.random.default_rng(hash(str(shape)) % 2**32)
    a = (rng.standard_normal(shape) * 10.0 ** rng.integers(-30, 30)).astype(dtype)
    check(be, a)
    check(be, -np.abs(a))  # the extreme is negative


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
@pytest.mark.parametrize("pos", POSITIONS)
def test_special_values_anywhere(be, noise, pos, dtype):
    """The largest value, a NaN (either sign), ±inf: found wherever they sit."""
    dtype = np.dtype(dtype)
    a = noise[dtype].copy()
    a[pos] = -2.5
    assert check(be, a) == 2.5
    for bad, want in ((np.inf, math.inf), (-np.inf, math.inf)):
        a[pos] = bad
        assert check(be, a) == want
    a[pos] = np.nan
    assert math.isnan(check(be, a))
    a[pos] = -np.nan  # sign bit set
    assert math.isnan(check(be, a))
    a[(pos + LONG // 2) % LONG] = -np.inf  # NaN wins over inf, wherever each is
    assert math.isnan(check(be, a))


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
@pytest.mark.parametrize("n", [1, 2, 5, 17, 100])
def test_nan_in_short_arrays(be, n, dtype):
    """Short arrays (tails only, no full vector) with a NaN at each position."""
    for pos in range(n):
        a = np.linspace(-3, 2, n).astype(dtype)
        a[pos] = np.nan
        assert math.isnan(check(be, a))


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_extremes_zeros_and_subnormals(be, dtype):
    dtype = np.dtype(dtype)
    fi = np.finfo(dtype)
    assert check(be, np.array([-fi.max, 1.0, fi.max / 2], dtype)) == float(fi.max)
    assert check(be, np.full(1000, -fi.max, dtype)) == float(fi.max)
    assert check(be, np.array([fi.tiny, -fi.tiny], dtype)) == float(fi.tiny)
    got = check(be, np.full((7, 9), -0.0, dtype))  # -0.0 gives +0.0
    assert got == 0.0 and math.copysign(1.0, got) == 1.0
    assert check(be, np.zeros(100_003, dtype)) == 0.0
    # the only non-zeros are subnormal: they count (no flush-to-zero, no DAZ)
    sub = np.zeros(100_003, dtype)
    sub[[5, 4096, 70_000, 100_002]] = [fi.smallest_subnormal, -fi.tiny / 2,
                                       3 * fi.smallest_subnormal, -fi.smallest_subnormal]
    assert check(be, sub) == float(dtype.type(fi.tiny / 2)) > 0
    lone = np.zeros(33, dtype)
    lone[-1] = -fi.smallest_subnormal
    assert check(be, lone) == float(fi.smallest_subnormal) > 0


@pytest.mark.parametrize("shape", [0, (0,), (3, 0), (0, 4, 5)], ids=str)
@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_empty_is_zero(be, shape, dtype):
    assert be.max_abs(be.upload(np.zeros(shape, dtype))) == 0.0


@pytest.mark.parametrize("dtype", [np.int32, np.float16, np.int64, np.uint8])
def test_wrong_dtype_raises(be, dtype):
    with pytest.raises(TypeError, match=r"max_abs takes float32 or float64 arrays, got"):
        be.max_abs(be.upload(np.ones((3, 4), dtype)))


def test_foreign_array_raises(be):
    other = variant_or_skip("numpy" if be.name != "numpy" else "warp")
    with pytest.raises(TypeError, match=f"DeviceArray of the {be.name} backend"):
        be.max_abs(other.upload(np.ones(4, np.float32)))
    with pytest.raises(TypeError, match="upload it"):
        be.max_abs(np.ones(4, np.float32))


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_large_then_small_reuses_no_stale_partials(be, noise, dtype):
    """A long array with a large value, then short ones: the partial buffers a call reuses
    must not carry the previous call's maxima."""
    dtype = np.dtype(dtype)
    big = noise[dtype].copy()
    big[LONG - 1] = 1e30
    assert check(be, big) == float(dtype.type(1e30))
    for n in (LONG - 1, 70_000, 65_536, 1000, 3):
        assert check(be, noise[dtype][:n]) <= 1.0


def test_threads(be, noise):
    """Several threads reducing different arrays at once each get their own answer."""
    arrays = []
    for k in range(8):
        a = noise[np.dtype(np.float32 if k % 2 else np.float64)][: 50_000 + 37_000 * k].copy()
        a[(k * 7919) % a.size] = k + 2.0
        arrays.append(be.upload(a))
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda d: be.max_abs(d), arrays * 3))
    assert got == [k + 2.0 for k in range(8)] * 3


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), dtype=st.sampled_from(DTYPES), variant=st.sampled_from(VARIANTS))
def test_property_any_floats(data, dtype, variant):
    """Any float values (NaN, ±inf, subnormals, ±0 included) and shapes up to 3-D."""
    be = variant_or_skip(variant)
    shape = data.draw(hnp.array_shapes(min_dims=1, max_dims=3, min_side=0, max_side=40))
    a = data.draw(hnp.arrays(dtype, shape, elements=st.floats(width=np.dtype(dtype).itemsize * 8)))
    got = be.max_abs(be.upload(a))
    assert same(got, reference(a)), (got, a)


# ---------------------------------------------------------------------------- Oclgrind
OCLGRIND_WORKER = """
import math
import numpy as np
from rdgpu.backends.opencl_backend import OpenCLBackend
from rdgpu.kernel_files import load_module
ref = load_module("reduce", "reference.py").max_abs
rng = np.random.default_rng(3)
for layout in ("row", "strided"):
    be = OpenCLBackend("oclgrind", layout=layout)
    for dtype in (np.float32, np.float64):
        for shape in [1, 7, (3, 5), (17, 33), 1000]:
            a = rng.standard_normal(shape).astype(dtype)
            assert be.max_abs(be.upload(a)) == ref(a), (layout, dtype, shape)
            a.flat[-1] = np.nan
            assert math.isnan(be.max_abs(be.upload(a))), (layout, dtype, shape)
        sub = np.zeros(40, dtype)
        sub[39] = -np.finfo(dtype).smallest_subnormal
        assert be.max_abs(be.upload(sub)) == ref(sub) > 0
        print(layout, np.dtype(dtype).name, "ok", flush=True)
"""


@pytest.mark.skipif(not oclgrind_available(), reason="Oclgrind is not installed")
def test_reduce_kernel_under_oclgrind():
    """Both layouts, both dtypes: no invalid access, no data race in the local-memory tree,
    results equal to the reference."""
    check_clean_under_oclgrind(["-c", OCLGRIND_WORKER], 4)


# ---------------------------------------------------------------------------- perf/reduce.py
def test_benchmark_script_runs_at_tiny_sizes():
    """perf/reduce.py's rows (every backend, both dtypes, results checked by the script)
    and its scalar-build OpenCL backend, which must leave the shared programs alone."""
    from rdgpu.backends import opencl_backend

    bench = repo_module("perf/reduce.py")
    backends = {name: backend_or_skip(name) for name in ("opencl", "warp", "numpy")}
    before = dict(opencl_backend._PROGRAMS)
    backends["opencl scalar"] = bench.scalar_opencl()
    assert opencl_backend._PROGRAMS == before
    a = np.array([1.0, -3.0, np.finfo(np.float32).smallest_subnormal], np.float32)
    assert backends["opencl scalar"].max_abs(backends["opencl scalar"].upload(a)) == 3.0
    rows = bench.measure(backends, {"tiny": 0, "L2": 4096}, seconds=0.0)
    assert len(rows) == 2 * 2 * len(backends)
    assert all(r["us"] > 0 and r["GBps"] > 0 for r in rows)
    text = bench.table(rows, triad=10.0)
    assert text.count("\n") == len(rows) + 1 and "opencl scalar" in text


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_warp_pool_chunks(dtype, monkeypatch):
    """Warp's CPU reduction over an array large enough for the thread pool (one chunk per
    8 MiB): every chunk's blocks count, a NaN or the largest value in any chunk is found."""
    from rdgpu.backends import warp_backend

    be = backend_or_skip("warp")
    dtype = np.dtype(dtype)
    n = 3 * warp_backend.REDUCE_SPLIT_BYTES // dtype.itemsize + 17
    offsets = []
    launch = be._launch
    monkeypatch.setattr(be, "_launch", lambda k, dim, args, key: (offsets.append(key),
                                                                   launch(k, dim, args, key)))
    a = np.random.default_rng(5).uniform(-1, 1, n).astype(dtype)
    for pos in (0, n // 3 + 5, n // 2, n - 1):
        b = a.copy()
        b[pos] = -7.0
        assert check(be, b) == 7.0
        b[(pos + n // 2) % n] = np.nan
        assert math.isnan(check(be, b))
    if warp_backend._cpu_count() > 1:
        assert len(set(offsets)) > 1  # the pool ran chunks at several block offsets
