"""The noise family (rdgpu/families/noise): ``normal_fill`` on every backend and launch
shape against the NumPy reference, in both dtypes and several shapes (odd sizes too).

* the Philox words: the reference's equal the Random123 answers and, bit for bit, the
  shared device Philox of every backend (read through the walkers' ``philox`` launcher,
  which calls the same function in each language); the reference's normals follow the
  definition (recomputed pair by pair in Python); ``u1`` and ``u2`` are exact (compared
  with the exact rationals) and ``u1`` lies in ``(0, 1)``;
* the normals within a few ulps of the reference (the backends' ``log``, ``cos``, ``sin``);
* the same bits on every repeat, other numbers for another seed, step or stream, element
  ``k`` independent of the array's length and shape (a longer fill extends a shorter
  one), every element written and none past the end;
* the statistics of 10^6 reference samples (mean, variance, kurtosis, Kolmogorov–Smirnov)
  and the two halves of a pair uncorrelated;
* bad arguments refused with a clear error before anything is written;
* the OpenCL kernel (and the shared ``philox.cl``) clean on Oclgrind.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from conftest import VARIANTS, backend_or_skip, variant_or_skip
from oclgrind_check import check_clean_under_oclgrind, oclgrind_available
from scipy import stats

from rdgpu.backends.arrays import DeviceArray
from rdgpu.families import load_module

REF = load_module("noise", "reference.py")
PHILOX = load_module("", "philox.py")

SHAPES = [(1,), (2,), (7,), (3, 5), (2, 3, 4), (129,)]
DTYPES = [np.float32, np.float64]
#: (seed, step, stream): small, and every word of the counter and key in use
ARGS = [(0, 0, 0), (12345, 7, 1), (2**64 - 1, 2**64 - 1, 2**32 - 1), (2**40 + 3, 2**33 + 5, 9)]
#: the backends' last bits: a few ulps of numbers of size ~1 (log, cos, sin, sqrt)
TOL = {np.dtype(np.float32): dict(rtol=1e-6, atol=1e-6),
       np.dtype(np.float64): dict(rtol=1e-13, atol=1e-13)}
#: an odd length past the Warp backend's row chunks (2^15 elements) and many work-groups
LONG = 100_003
TOP = 0xFFFFFFFF


@pytest.fixture(params=VARIANTS)
def be(request):
    return variant_or_skip(request.param)


def fill(be, shape, dtype, seed, step, stream) -> np.ndarray:
    """``normal_fill`` of a new array on ``be`` (pre-filled with NaN), downloaded."""
    out = be.upload(np.full(shape, np.nan, dtype))
    be.kernel("noise", "normal_fill")(out, seed=seed, step=step, stream=stream)
    return be.download(out)


def as_words(*columns) -> tuple[np.ndarray, ...]:
    """Four uint32 arrays ``(r0, r1, r2, r3)`` from four sequences of integers."""
    return tuple(np.asarray(c, np.uint32) for c in columns)


# ----------------------------------------------------------------- the reference's Philox


def test_reference_words_are_philox():
    """Random123's answer for counter (0, 0, 0, 0) under key (0, 0), and the counter words
    ``(j, step low, step high, stream)`` under the key ``(seed low, seed high)``."""
    got = REF.words(1, seed=0, step=0, stream=0)
    assert tuple(int(w[0]) for w in got) == (0x6627E8D5, 0xE169C58D, 0xBC57AC4C, 0x9B00DBD8)
    seed, step, stream = ARGS[3]
    got = REF.words(300, seed=seed, step=step, stream=stream)
    for j in (0, 1, 255, 299):
        want = PHILOX.philox4x32((j, step % 2**32, step // 2**32, stream),
                                 (seed % 2**32, seed // 2**32))
        assert tuple(int(w[j]) for w in got) == tuple(int(w) for w in want), j


@pytest.mark.parametrize("name", ["numpy", "warp", "opencl"])
@pytest.mark.parametrize("seed,step,stream", ARGS)
def test_device_philox_words_equal_the_reference(name, seed, step, stream):
    """The device Philox the noise kernels call (``philox.cl``, ``warp_philox.py``, shared
    with the walkers) gives the reference's words bit for bit for the noise counters
    ``(j, step low, step high, stream)``."""
    be = backend_or_skip(name)
    n = 1000
    out = be.empty((n, 4), np.uint32)
    be.kernel("walkers", "philox")(out, first=0, t=step, purpose=stream, seed=seed)
    want = np.stack(REF.words(n, seed=seed, step=step, stream=stream), axis=1)
    np.testing.assert_array_equal(be.download(out), want)


def exact_uniforms(r: tuple[int, ...], dtype) -> tuple[Fraction, Fraction]:
    """The definition's ``(u1, u2)`` of one pair's words as exact rationals."""
    r0, r1, r2, r3 = r
    if dtype == np.float32:
        return Fraction(2 * (r0 >> 9) + 1, 2**24), Fraction(r1 >> 8, 2**24)
    return (Fraction(2 * (((r0 >> 6) << 26) + (r2 >> 6)) + 1, 2**53),
            Fraction(((r1 >> 5) << 26) + (r3 >> 6), 2**53))


def _pair_by_hand(r: tuple[int, ...], dtype) -> tuple[float, float]:
    """The definition for one pair: exact ``u1``, ``u2``, then Python's float64 math."""
    u1, u2 = (float(u) for u in exact_uniforms(r, dtype))
    two_pi = float(np.float32(2 * math.pi)) if dtype == np.float32 else 2 * math.pi
    rho = math.sqrt(-2 * math.log(u1))
    return rho * math.cos(two_pi * u2), rho * math.sin(two_pi * u2)


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_reference_follows_the_definition(dtype):
    """Pair ``j``'s cosine half at ``2j``, its sine half at ``2j + 1``; an odd length drops
    the last sine half."""
    seed, step, stream = ARGS[3]
    n = 2001
    words = np.stack(REF.words(1001, seed=seed, step=step, stream=stream), axis=1)
    got = REF.normal_fill(n, dtype, seed=seed, step=step, stream=stream)
    assert got.dtype == dtype and got.shape == (n,)
    want = np.array([_pair_by_hand(tuple(int(w) for w in row), dtype) for row in words])
    np.testing.assert_allclose(got, want.ravel()[:n], **TOL[np.dtype(dtype)])
    u1, u2 = REF.uniforms(tuple(words.T), np.dtype(dtype))
    assert u1.dtype == u2.dtype == dtype
    assert np.all((u1 > 0) & (u1 < 1)) and np.all((u2 >= 0) & (u2 < 1))


def _test_words(count: int) -> list[int]:
    """``count`` 32-bit words: the extremes, the edges of the bits each dtype drops, and
    random ones."""
    edges = [0, 1, TOP, TOP - 1, 2**31, 2**31 - 1, 2**9 - 1, 2**9, 2**6 - 1, 2**6,
             2**5 - 1, 2**5, 2**8 - 1, 2**8, TOP - 2**9 + 1, TOP ^ 2**9]
    rng = np.random.default_rng(20240601)
    return edges + [int(w) for w in rng.integers(0, 2**32, count - len(edges))]


def test_float32_uniforms_are_exact():
    """float32 ``u1 = ((r0 >> 9) + 0.5) · 2**-23`` and ``u2`` computed in float32 are the
    exact rationals (24 significant bits), ``u1`` in ``[2**-24, 1 − 2**-24]``."""
    w = _test_words(4000)
    r = as_words(w, w[::-1], w, w)
    u1, u2 = REF.uniforms(r, np.dtype(np.float32))
    assert u1.dtype == u2.dtype == np.float32
    for k, (a, b) in enumerate(zip(u1.tolist(), u2.tolist(), strict=True)):
        want1, want2 = exact_uniforms(tuple(int(c[k]) for c in r), np.float32)
        assert Fraction(a) == want1 and Fraction(b) == want2, hex(w[k])
    assert u1[0] == 2.0**-24 and u1[2] == 1 - 2.0**-24 and u1.min() > 0 and u1.max() < 1


def test_float64_uniforms_are_exact():
    """float64 ``u1`` (53 significant bits from r0 and r2) and ``u2`` (from r1 and r3) are
    the exact rationals, ``u1`` in ``[2**-53, 1 − 2**-53]``, also for all-ones words."""
    w = _test_words(3000)
    mixed = w[7::] + w[:7]
    r = as_words(w + [TOP, 0, TOP, 0], mixed + [TOP, 0, 0, TOP],
                 mixed + [TOP, 0, 0, TOP], w + [TOP, 0, TOP, 0])
    u1, u2 = REF.uniforms(r, np.dtype(np.float64))
    assert u1.dtype == u2.dtype == np.float64
    for k, (a, b) in enumerate(zip(u1.tolist(), u2.tolist(), strict=True)):
        want1, want2 = exact_uniforms(tuple(int(c[k]) for c in r), np.float64)
        assert Fraction(a) == want1 and Fraction(b) == want2, k
    assert u1[-4] == 1 - 2.0**-53 and u1[-3] == 2.0**-53
    assert Fraction(u1[-4]) == 1 - Fraction(1, 2**53) and u2[-4] == 1 - 2.0**-53
    assert u1.min() > 0 and u1.max() < 1


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_box_muller_extremes(dtype):
    """The largest ``u1`` gives the smallest ``rho``, finite and not flushed; ``u2 = 0``
    gives ``(rho, 0)``; the smallest ``u1`` the largest ``|out|``, ``sqrt(-2 log u1)``."""
    zero, top = [0, 0], [TOP, TOP]
    u1, u2 = REF.uniforms(as_words([0, TOP], zero, [0, TOP], zero), np.dtype(dtype))
    even, odd = REF.box_muller(u1, u2)
    assert even.dtype == odd.dtype == dtype and np.all(odd == 0)
    bits = 24 if dtype == np.float32 else 53
    assert even[1] > 0 and abs(even[1] - math.sqrt(2.0**(1 - bits))) < 1e-3 * even[1]
    assert abs(even[0] - math.sqrt(2 * bits * math.log(2))) < 1e-5
    u1, u2 = REF.uniforms(as_words(top, top, top, top), np.dtype(dtype))
    even, odd = REF.box_muller(u1, u2)
    assert np.all(np.isfinite(even) & np.isfinite(odd) & (even > 0) & (odd < 0))


# ----------------------------------------------------------------- every backend


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
@pytest.mark.parametrize("shape", SHAPES, ids=str)
def test_backend_equals_reference(be, shape, dtype):
    for seed, step, stream in ARGS:
        got = fill(be, shape, dtype, seed, step, stream)
        want = REF.normal_fill(math.prod(shape), dtype, seed=seed, step=step, stream=stream)
        assert got.dtype == dtype and got.shape == shape
        np.testing.assert_allclose(got.ravel(), want, **TOL[np.dtype(dtype)],
                                   err_msg=f"{be!r} {seed, step, stream}")


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_long_fill_equals_reference(be, dtype):
    """Every element of a fill longer than the CPU chunks and work-groups is written and
    right (chunk offsets, the padded last work-group, the odd last pair)."""
    got = fill(be, (LONG,), dtype, 99, 2**32 + 1, 4)
    want = REF.normal_fill(LONG, dtype, seed=99, step=2**32 + 1, stream=4)
    np.testing.assert_allclose(got, want, **TOL[np.dtype(dtype)])


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_repeatable_and_keyed(be, dtype):
    """The same call gives the same bits; another seed, step or stream other numbers."""
    seed, step, stream = 2**40 + 3, 2**33 + 5, 9
    first = fill(be, (LONG,), dtype, seed, step, stream)
    again = fill(be, (LONG,), dtype, seed, step, stream)
    assert first.tobytes() == again.tobytes()
    for other in ((seed + 1, step, stream), (seed ^ 2**63, step, stream),
                  (seed, step + 1, stream), (seed, step ^ 2**32, stream),
                  (seed, step, stream + 1)):
        moved = fill(be, (1000,), dtype, *other)
        assert np.mean(moved == first[:1000]) < 0.01, other


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_longer_fill_extends_shorter(be, dtype):
    """Element ``k`` depends on ``k`` alone, not on the length (odd or even) or the shape:
    every shorter fill is bit for bit a prefix of a longer one."""
    seed, step, stream = 2**40 + 3, 2**33 + 5, 9
    longest = fill(be, (LONG,), dtype, seed, step, stream)
    for shape in ((1,), (2,), (7,), (8,), (129,), (130,), (3, 43), (2, 65), (LONG - 1,)):
        got = fill(be, shape, dtype, seed, step, stream).ravel()
        assert got.tobytes() == longest[:got.size].tobytes(), shape


def _prefix_view(be, base: DeviceArray, n: int) -> DeviceArray:
    """A DeviceArray over the first ``n`` elements of the 1-D ``base`` (its own buffer)."""
    if be.name == "opencl":
        handle = base.handle.get_sub_region(0, n * base.dtype.itemsize)
    else:
        handle = base.handle[:n]
    return DeviceArray(be, handle, (n,), base.dtype)


@pytest.mark.parametrize("name", ["numpy", "warp", "opencl"])
@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_odd_length_writes_nothing_past_the_end(name, dtype):
    """An odd fill writes its last pair's cosine half only: the element after the end
    (still in the buffer underneath) keeps its value."""
    be = backend_or_skip(name)
    for n in (1, 7, 129):
        base = be.upload(np.full(n + 1, 7, dtype))
        be.kernel("noise", "normal_fill")(_prefix_view(be, base, n), seed=3, step=4, stream=5)
        got = be.download(base)
        assert got[n] == 7, n
        np.testing.assert_allclose(got[:n], REF.normal_fill(n, dtype, seed=3, step=4, stream=5),
                                   **TOL[np.dtype(dtype)])


@pytest.mark.parametrize("name", ["numpy", "warp", "opencl"])
def test_empty_array(name):
    be = backend_or_skip(name)
    out = be.empty((0, 3), np.float32)
    be.kernel("noise", "normal_fill")(out, seed=1, step=2, stream=3)
    assert be.download(out).shape == (0, 3)


OCLGRIND_WORKER = """
import numpy as np
from rdgpu.backends.opencl_backend import OpenCLBackend
from rdgpu.families import load_module

ref = load_module("noise", "reference.py")
for layout in ("row", "strided"):
    be = OpenCLBackend(device="oclgrind", layout=layout, col_stride=4)
    for dtype in (np.float32, np.float64):
        for shape in ((3, 43), (1,), (2, 4)):
            n = int(np.prod(shape))
            out = be.upload(np.full(shape, np.nan, dtype))
            be.kernel("noise", "normal_fill")(out, seed=2**40 + 3, step=2**33 + 5, stream=9)
            want = ref.normal_fill(n, dtype, seed=2**40 + 3, step=2**33 + 5, stream=9)
            tol = 1e-6 if dtype == np.float32 else 1e-13
            np.testing.assert_allclose(be.download(out).ravel(), want, rtol=tol, atol=tol)
        print(layout, np.dtype(dtype).name, "ok", flush=True)
words = be.empty((50, 4), np.uint32)
be.kernel("walkers", "philox")(words, first=0, t=5, purpose=1, seed=7)
want = np.stack(ref.words(50, seed=7, step=5, stream=1), axis=1)
assert np.array_equal(be.download(words), want)
print("walkers philox ok", flush=True)
"""


@pytest.mark.skipif(not oclgrind_available(), reason="Oclgrind is not installed")
def test_noise_kernel_under_oclgrind():
    """Both layouts, both dtypes, odd and even lengths, the padded last work-group and the
    shared ``philox.cl`` (also through the walkers' program): no invalid access, results
    equal to the reference."""
    check_clean_under_oclgrind(["-c", OCLGRIND_WORKER], 5)


# ----------------------------------------------------------------- statistics


def test_statistics_of_a_million_samples():
    n = 10**6
    x = REF.normal_fill(n, np.float64, seed=20240601, step=17, stream=2)
    assert abs(x.mean()) < 5 / math.sqrt(n)
    assert abs(x.var() - 1) < 5 * math.sqrt(2 / n)
    # the kurtosis of a normal is 3, its estimate's standard deviation sqrt(24 / n)
    assert abs(stats.kurtosis(x, fisher=False) - 3) < 5 * math.sqrt(24 / n)
    assert abs(stats.skew(x)) < 5 * math.sqrt(6 / n)
    assert stats.kstest(x, "norm").pvalue > 1e-4
    # another stream is independent of this one: their correlation is ~ N(0, 1/n)
    y = REF.normal_fill(n, np.float64, seed=20240601, step=17, stream=3)
    assert abs(np.corrcoef(x, y)[0, 1]) < 5 / math.sqrt(n)
    # neighbours within one stream too (within a pair and across pairs)
    assert abs(np.corrcoef(x[:-1], x[1:])[0, 1]) < 5 / math.sqrt(n)


def test_float32_statistics():
    n = 10**6
    x = REF.normal_fill(n, np.float32, seed=7, step=0, stream=0).astype(np.float64)
    assert abs(x.mean()) < 5 / math.sqrt(n)
    assert abs(x.var() - 1) < 5 * math.sqrt(2 / n)
    assert abs(stats.kurtosis(x, fisher=False) - 3) < 5 * math.sqrt(24 / n)
    assert stats.kstest(x, "norm").pvalue > 1e-4


@pytest.mark.parametrize("dtype", DTYPES, ids=["f32", "f64"])
def test_pair_halves_uncorrelated(dtype):
    """``out[2j]`` and ``out[2j + 1]`` over 10^6 pairs: uncorrelated, their squares too
    (independent, as Box–Muller's two halves are), each half standard normal."""
    pairs = 10**6
    x = REF.normal_fill(2 * pairs, dtype, seed=11, step=2**40, stream=6).astype(np.float64)
    even, odd = x[0::2], x[1::2]
    assert abs(np.corrcoef(even, odd)[0, 1]) < 5 / math.sqrt(pairs)
    assert abs(np.corrcoef(even**2, odd**2)[0, 1]) < 5 / math.sqrt(pairs)
    for half in (even, odd):
        assert abs(half.mean()) < 5 / math.sqrt(pairs)
        assert abs(half.var() - 1) < 5 * math.sqrt(2 / pairs)
        assert stats.kstest(half, "norm").pvalue > 1e-4


# ----------------------------------------------------------------- bad arguments


def _sentinel(be, dtype=np.float32, shape=(4, 6)):
    return be.upload(np.full(shape, 7, dtype))


@pytest.mark.parametrize("name", ["numpy", "warp", "opencl"])
@pytest.mark.parametrize("kwargs,error,match", [
    (dict(seed=-1), ValueError, r"seed must be >= 0, got -1"),
    (dict(seed=2**64), ValueError, r"seed must be <= 18446744073709551615"),
    (dict(step=-5), ValueError, r"step must be >= 0"),
    (dict(step=2**64), ValueError, r"step must be <= 18446744073709551615"),
    (dict(stream=2**32), ValueError, r"stream must be <= 4294967295, got 4294967296"),
    (dict(stream=-1), ValueError, r"stream must be >= 0"),
    (dict(seed=1.0), TypeError, r"seed must be an integer, got float"),
    (dict(stream=True), TypeError, r"stream must be an integer.*bool"),
    (dict(step="3"), TypeError, r"step must be an integer.*text"),
])
def test_bad_numbers(name, kwargs, error, match):
    be = backend_or_skip(name)
    out = _sentinel(be)
    args = {**dict(seed=1, step=2, stream=3), **kwargs}
    with pytest.raises(error, match=match):
        be.kernel("noise", "normal_fill")(out, **args)
    assert np.all(be.download(out) == 7)  # nothing written


@pytest.mark.parametrize("name", ["numpy", "warp", "opencl"])
@pytest.mark.parametrize("dtype", [np.float16, np.int32, np.uint32, np.int64])
def test_bad_dtype(name, dtype):
    be = backend_or_skip(name)
    out = be.upload(np.full((5,), 7, dtype))
    with pytest.raises(TypeError, match=r"out must be float32 or float64, got "
                                        + np.dtype(dtype).name):
        be.kernel("noise", "normal_fill")(out, seed=1, step=2, stream=3)
    assert np.all(be.download(out) == 7)


@pytest.mark.parametrize("name", ["numpy", "warp"])
def test_non_contiguous(name):
    """A strided view (a DeviceArray over a sliced NumPy or Warp array) is refused."""
    be = backend_or_skip(name)
    base = _sentinel(be, np.float64)
    view = base.handle[:, ::2]
    out = DeviceArray(be, view, (4, 3), np.dtype(np.float64))
    with pytest.raises(ValueError, match="out must be C-contiguous"):
        be.kernel("noise", "normal_fill")(out, seed=1, step=2, stream=3)
    assert np.all(be.download(base) == 7)


@pytest.mark.parametrize("name", ["warp", "opencl"])
def test_foreign_or_host_array(name):
    be = backend_or_skip(name)
    host = np.zeros(5)
    with pytest.raises(TypeError, match=f"out must be a DeviceArray of the {name} backend, "
                                        "got ndarray"):
        be.kernel("noise", "normal_fill")(host, seed=1, step=2, stream=3)
    other = backend_or_skip("numpy").upload(np.full(5, 7.0))
    with pytest.raises(TypeError, match="got the numpy backend"):
        be.kernel("noise", "normal_fill")(other, seed=1, step=2, stream=3)
    assert np.all(other.handle == 7)
