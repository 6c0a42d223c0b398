"""The reductions of rdgpu/families/reduce on every backend and launch shape.

``Backend.max_abs``, bit for bit the
NumPy reference ``float(np.max(np.abs(u)))``: random arrays of odd, tiny, non-square and
multi-chunk shapes in both dtypes; NaN, ±inf and the largest value at many positions
(first, last, vector lanes, chunk edges, peeled tails); negative extremes, -0.0, arrays
whose only non-zeros are subnormal, empty arrays; wrong dtypes and foreign arrays; buffer
reuse between calls and threads; the OpenCL kernel on Oclgrind; the timing of
perf/reduce.py (``rdgpu.backends.reduce_timing``) at tiny sizes (no timing is asserted).

``Backend.sum_squares``: within the rigorous rounding bound of ``math.fsum`` of the
exactly rounded float64 squares (``sum_squares_error_bound``, derived, not tuned), and
the same bits on every repeat; the same shapes, lengths across every tail, chunk and pass
edge, NaN and ±inf at many positions, overflow, ±0, all-subnormal arrays (0 or the exact
value), empty arrays, wrong dtypes and foreign arrays (the tests shared with max_abs, over
``OPS``), an fp64-less OpenCL device, threads, the OpenCL kernel on Oclgrind."""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from fractions import Fraction

import numpy as np
import pytest
from conftest import VARIANTS, backend_or_skip, variant_or_skip
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from oclgrind_check import check_clean_under_oclgrind, oclgrind_available

from rdgpu.families import load_module

REDUCE = load_module("reduce", "reference.py")
reference = REDUCE.max_abs

SHAPES = [1, 7, (3, 5), (1, 1000), (17, 33), (4, 5, 6), 100_003]
#: a length past every chunk and block of the CPU shapes (65 536 elements), past the
#: first pass of Warp's CUDA shape (2^18 threads) and past the 1024 × 256 work-items of
#: OpenCL's strided layout (so its grid-stride loop strides)
LONG = 600_001
#: positions in an array of LONG elements: ends, vector lanes, chunk and block edges
POSITIONS = [0, 1, 3, 7, 8, 15, 16, 31, 63, 64, 65_535, 65_536, 65_537, 131_072,
             262_143, 262_144, 262_145, 300_000, LONG - 17, LONG - 2, LONG - 1]
DTYPES = [np.float32, np.float64]
#: the reductions, as Backend method names
OPS = ["max_abs", "sum_squares"]


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


@pytest.mark.parametrize("op", OPS)
@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
@pytest.mark.parametrize("shape", SHAPES, ids=str)
def test_random_shapes(be, op, shape, dtype):
    """max_abs bit for bit, sum_squares within its bound and repeatable (``check_ss``)."""
    rng = np.random.default_rng(hash(str(shape)) % 2**32)
    a = (rng.standard_normal(shape) * 10.0 ** rng.integers(-30, 30)).astype(dtype)
    checker = check if op == "max_abs" else check_ss
    checker(be, a)
    checker(be, -np.abs(a))  # the extreme is negative


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


@pytest.mark.parametrize("op", OPS)
@pytest.mark.parametrize("shape", [0, (0,), (3, 0), (0, 4, 5)], ids=str)
@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_empty_is_zero(be, op, shape, dtype):
    got = getattr(be, op)(be.upload(np.zeros(shape, dtype)))
    assert got == 0.0 and isinstance(got, float)


@pytest.mark.parametrize("op", OPS)
@pytest.mark.parametrize("dtype", [np.int32, np.float16, np.int64, np.uint8])
def test_wrong_dtype_raises(be, op, dtype):
    with pytest.raises(TypeError, match=rf"{op} takes float32 or float64 arrays, got"):
        getattr(be, op)(be.upload(np.ones((3, 4), dtype)))


@pytest.mark.parametrize("op", OPS)
def test_foreign_array_raises(be, op):
    other = variant_or_skip("numpy" if be.name != "numpy" else "warp")
    with pytest.raises(TypeError, match=f"{op} takes a DeviceArray of the {be.name} backend"):
        getattr(be, op)(other.upload(np.ones(4, np.float32)))
    with pytest.raises(TypeError, match="upload it"):
        getattr(be, op)(np.ones(4, np.float32))


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
from rdgpu.families import load_module
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


# ------------------------------------------------------------------ rdgpu.backends.reduce_timing
def test_reduce_timing_runs_at_tiny_sizes():
    """rdgpu.backends.reduce_timing (perf/reduce.py's rows: every backend, both dtypes,
    results checked) and its scalar-build OpenCL backend, which must leave the shared
    programs alone."""
    from rdgpu.backends import opencl_backend
    from rdgpu.backends import reduce_timing as bench

    backends = {name: backend_or_skip(name) for name in ("opencl", "warp", "numpy")}
    before = dict(opencl_backend.PROGRAMS)
    backends["opencl scalar"] = bench.scalar_opencl()
    assert opencl_backend.PROGRAMS == before
    a = np.array([1.0, -3.0, np.finfo(np.float32).smallest_subnormal], np.float32)
    assert backends["opencl scalar"].max_abs(backends["opencl scalar"].upload(a)) == 3.0
    # one sequential accumulator: 1 + 9 + (a subnormal's square, or 0 under DAZ) rounds to 10
    assert backends["opencl scalar"].sum_squares(backends["opencl scalar"].upload(a)) == 10.0
    rows = bench.measure(backends, {"tiny": 0, "L2": 4096}, seconds=0.0)
    assert len(rows) == 2 * 2 * 2 * len(backends)  # sizes, dtypes, ops, backends
    assert {r["op"] for r in rows} == {"max_abs", "sum_squares"}
    assert all(r["us"] > 0 and r["GBps"] > 0 for r in rows)
    text = bench.table(rows, triad=10.0)
    assert text.count("\n") == len(rows) + 1 and "opencl scalar" in text


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_warp_pool_chunks(dtype, monkeypatch):
    """Warp's CPU reduction over an array large enough for the thread pool (one chunk per
    8 MiB): every chunk's blocks count, a NaN or the largest value in any chunk is found."""
    from rdgpu.backends import warp_backend
    from rdgpu.families.reduce import warp as reduce_warp

    be = backend_or_skip("warp:cpu")  # the CPU thread pool, whatever RDGPU_TEST_WARP_DEVICE says
    dtype = np.dtype(dtype)
    n = 3 * reduce_warp.SPLIT_BYTES // dtype.itemsize + 17
    offsets = []
    launch = be.launch
    monkeypatch.setattr(be, "launch", lambda k, dim, args, key: (offsets.append(key),
                                                                   launch(k, dim, args, key)))
    a = np.random.default_rng(5).uniform(-1, 1, n).astype(dtype)
    for pos in (0, n // 3 + 5, n // 2, n - 1):
        b = a.copy()
        b[pos] = -7.0
        assert check(be, b) == 7.0
        b[(pos + n // 2) % n] = np.nan
        assert math.isnan(check(be, b))
    if warp_backend.cpu_count() > 1:
        assert len(set(offsets)) > 1  # the pool ran chunks at several block offsets


# ============================================================================ sum_squares
ss_reference = REDUCE.sum_squares


def within_bound(got: float, a: np.ndarray) -> bool:
    """``got`` is within the rigorous rounding bound of the correctly rounded sum of the
    squares (rdgpu/families/reduce/reference.py: ``sum_squares_error_bound``), compared exactly."""
    exact = REDUCE.sum_squares_exact(a)
    return abs(Fraction(got) - Fraction(exact)) <= REDUCE.sum_squares_error_bound(a, exact)


def bits(x: float) -> int:
    return int(np.float64(x).view(np.uint64))


def check_ss(be, a: np.ndarray) -> float:
    """``be.sum_squares`` of ``a``: a float within the bound, the same bits on a second call
    and on a second upload (deterministic)."""
    d = be.upload(a)
    got = be.sum_squares(d)
    assert isinstance(got, float)
    assert within_bound(got, a), (got, REDUCE.sum_squares_exact(a), a.dtype, a.shape)
    assert bits(be.sum_squares(d)) == bits(got)
    assert bits(be.sum_squares(be.upload(a))) == bits(got)
    return got


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_sum_squares_lengths(be, noise, dtype):
    """Every tail length (0..15 past whole vectors of 16) and lengths around the chunk,
    block and pass edges, up to LONG; the sum grows with n (squares are non-negative)."""
    dtype = np.dtype(dtype)
    lengths = [*range(1, 18), 63, 64, 65, 1023, 65_535, 65_536, 65_537, 65_551, 131_073,
               262_143, 262_144, 262_145, 262_159, LONG]
    sums = [check_ss(be, noise[dtype][:n]) for n in lengths]
    assert all(x <= y for x, y in zip(sums, sums[1:], strict=False))


def test_sum_squares_bound_catches_float32_accumulation(noise):
    """The bound is tight enough to matter: summing the float32 squares in float32 (a
    single accumulator, as a naive kernel would) falls outside it."""
    a = noise[np.dtype(np.float32)]
    acc = np.float32(0)
    for x in np.square(a[:20_000]):  # (20 000 sequential float32 adds)
        acc = np.float32(acc + x)
    assert not within_bound(float(acc), a[:20_000])
    assert within_bound(float(np.sum(np.square(a[:20_000], dtype=np.float64))), a[:20_000])


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
@pytest.mark.parametrize("pos", POSITIONS)
def test_sum_squares_nan_and_inf_anywhere(be, noise, pos, dtype):
    """A NaN (either sign) gives NaN, ±inf gives inf, NaN wins over inf, wherever each is."""
    a = noise[np.dtype(dtype)].copy()
    for bad in (np.inf, -np.inf):
        a[pos] = bad
        assert be.sum_squares(be.upload(a)) == math.inf
    a[pos] = np.nan
    assert math.isnan(be.sum_squares(be.upload(a)))
    a[pos] = -np.nan
    assert math.isnan(be.sum_squares(be.upload(a)))
    a[(pos + LONG // 2) % LONG] = -np.inf
    assert math.isnan(be.sum_squares(be.upload(a)))


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
@pytest.mark.parametrize("n", [1, 2, 5, 8, 9, 17, 100])
def test_sum_squares_specials_in_short_arrays(be, n, dtype):
    """Short arrays (tails only, or one vector and a tail): NaN and inf at each position."""
    for pos in range(n):
        a = np.linspace(-3, 2, n).astype(dtype)
        a[pos] = -np.inf
        assert be.sum_squares(be.upload(a)) == math.inf
        a[pos] = np.nan
        assert math.isnan(be.sum_squares(be.upload(a)))


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_sum_squares_extremes_zeros_and_overflow(be, dtype):
    dtype = np.dtype(dtype)
    fi = np.finfo(dtype)
    # float32 squares cannot overflow a double: 1000 x max^2 is finite
    big = np.full(1000, -fi.max, dtype)
    if dtype == np.float32:
        assert math.isfinite(check_ss(be, big))
    else:  # max^2 overflows: inf; so does a sum of finite squares beyond DBL_MAX
        assert be.sum_squares(be.upload(big)) == math.inf
        assert be.sum_squares(be.upload(np.full(20, 1e154))) == math.inf
    got = check_ss(be, np.full((7, 9), -0.0, dtype))  # -0.0 squared is +0.0
    assert got == 0.0 and math.copysign(1.0, got) == 1.0
    assert check_ss(be, np.zeros(100_003, dtype)) == 0.0
    # tiny^2: 1.4e-76 in float64 (counted) from float32; below the subnormals from float64
    assert (check_ss(be, np.array([fi.tiny, -fi.tiny], dtype)) > 0) == (dtype == np.float32)
    # exact in float64: 3^2 + 4^2 (and 100 003 ones)
    assert check_ss(be, np.array([3.0, -4.0], dtype)) == 25.0
    assert check_ss(be, np.ones(100_003, dtype)) == 100_003.0


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_sum_squares_all_subnormal(be, dtype):
    """Only subnormals: OpenCL (-cl-denorms-are-zero) and Warp (FTZ/DAZ threads) may read
    them as 0, the others count them, so 0 and the exact value are both right; a square
    below 1e-76 (float32) or 0 (float64: rounds to 0) never matters to a mean-square test."""
    dtype = np.dtype(dtype)
    fi = np.finfo(dtype)
    sub = np.zeros(100_003, dtype)
    sub[[5, 4096, 70_000, 100_002]] = [fi.smallest_subnormal, -fi.tiny / 2,
                                       3 * fi.smallest_subnormal, -fi.smallest_subnormal]
    exact = REDUCE.sum_squares_exact(sub)
    assert (exact > 0) == (dtype == np.float32)
    assert be.sum_squares(be.upload(sub)) in (0.0, exact)


def test_sum_squares_needs_fp64_on_opencl(monkeypatch):
    """An OpenCL device without doubles is refused at call time, with what to do."""
    from rdgpu.core.errors import BackendUnavailableError

    be = variant_or_skip("opencl")
    d = be.upload(np.ones(4, np.float32))
    monkeypatch.setattr(be, "fp64", False)
    with pytest.raises(BackendUnavailableError, match="no float64 support.*another backend"):
        be.sum_squares(d)


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_sum_squares_same_order_on_warp_and_opencl_rows(noise, dtype):
    """Warp's CPU blocks and OpenCL's row layout sum in the same documented order (16 lanes
    per 65 536-element chunk, a tree over the lanes, the host's float64 sum of the
    partials): the same bits."""
    from rdgpu.families.reduce import opencl as reduce_opencl
    from rdgpu.families.reduce import warp as reduce_warp

    warp, ocl = variant_or_skip("warp"), variant_or_skip("opencl")
    if ocl.layout != "row":
        pytest.skip("the OpenCL device runs the strided layout")
    assert reduce_warp.BLOCK == reduce_opencl.CHUNK
    for n in (9, 17, 65_551, LONG):
        a = noise[np.dtype(dtype)][:n]
        assert bits(warp.sum_squares(warp.upload(a))) == bits(ocl.sum_squares(ocl.upload(a)))


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_sum_squares_large_then_small_reuses_no_stale_partials(be, noise, dtype):
    dtype = np.dtype(dtype)
    big = noise[dtype].copy()
    big[LONG - 1] = 1e30
    assert check_ss(be, big) >= 1e60
    for n in (LONG - 1, 70_000, 65_536, 1000, 3):
        check_ss(be, noise[dtype][:n])


def test_sum_squares_threads(be, noise):
    """Threads reducing different arrays at once each get the bits of a lone call."""
    arrays = [be.upload(noise[np.dtype(np.float32 if k % 2 else np.float64)]
                        [: 50_000 + 37_000 * k]) for k in range(8)]
    alone = [be.sum_squares(d) for d in arrays]
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda d: be.sum_squares(d), arrays * 3))
    assert [bits(x) for x in got] == [bits(x) for x in alone] * 3


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), dtype=st.sampled_from(DTYPES), variant=st.sampled_from(VARIANTS))
def test_sum_squares_property_any_floats(data, dtype, variant):
    """Any float values (NaN, ±inf, subnormals, ±0 included; float64 below 1e150 in
    magnitude, so that finite sums stay finite) and shapes up to 3-D."""
    be = variant_or_skip(variant)
    shape = data.draw(hnp.array_shapes(min_dims=1, max_dims=3, min_side=0, max_side=40))
    width = np.dtype(dtype).itemsize * 8
    limit = {} if width == 32 else {"min_value": -1e150, "max_value": 1e150}
    finite = st.floats(width=width, allow_nan=False, allow_infinity=False, **limit)
    special = st.sampled_from([np.nan, -np.nan, np.inf, -np.inf])
    a = data.draw(hnp.arrays(dtype, shape, elements=finite | special if
                             data.draw(st.booleans()) else finite))
    got = be.sum_squares(be.upload(a))
    if np.isnan(a).any():
        assert math.isnan(got)
    elif np.isinf(a).any():
        assert got == math.inf
    else:
        assert within_bound(got, a), (got, a)


SUM_SQUARES_OCLGRIND_WORKER = """
import math
from fractions import Fraction
import numpy as np
from rdgpu.backends.opencl_backend import OpenCLBackend
from rdgpu.families import load_module
ref = load_module("reduce", "reference.py")
rng = np.random.default_rng(4)
for layout in ("row", "strided"):
    be = OpenCLBackend("oclgrind", layout=layout)
    for dtype in (np.float32, np.float64):
        for shape in [1, 7, 8, 9, (3, 5), (17, 33), 1000]:
            a = rng.standard_normal(shape).astype(dtype)
            got = be.sum_squares(be.upload(a))
            exact = ref.sum_squares_exact(a)
            assert abs(Fraction(got) - Fraction(exact)) <= ref.sum_squares_error_bound(a, exact)
            assert got == be.sum_squares(be.upload(a)), (layout, dtype, shape)
            a.flat[-1] = np.inf
            assert be.sum_squares(be.upload(a)) == math.inf, (layout, dtype, shape)
            a.flat[0] = np.nan
            assert math.isnan(be.sum_squares(be.upload(a))), (layout, dtype, shape)
        print(layout, np.dtype(dtype).name, "ok", flush=True)
"""


@pytest.mark.skipif(not oclgrind_available(), reason="Oclgrind is not installed")
def test_sum_squares_kernel_under_oclgrind():
    """Both layouts, both dtypes, tails of every kind: no invalid access, no data race in
    the local-memory tree, results within the bound and repeatable, NaN and inf."""
    check_clean_under_oclgrind(["-c", SUM_SQUARES_OCLGRIND_WORKER], 4)
