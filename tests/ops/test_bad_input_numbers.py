"""Numbers, arrays and backend specs of the functional API, on every backend: the one
number rule of :mod:`rdgpu.core.validation` (no bool, text or complex value taken as a number,
no float truncated to an integer, no masked array's mask ignored), malformed backend
specs, and requests too large refused before anything is read, copied or allocated
(issue 19: A11, B, E5)."""

from __future__ import annotations

import subprocess
import sys
from fractions import Fraction

import numpy as np
import pytest
from conftest import BACKENDS, backend_or_skip

import rdgpu
from rdgpu.core import validation as check
from rdgpu.core.errors import ResourceLimitError

G = np.zeros((4, 6))
ONES = np.ones((4, 6))
GS = {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.06, "dt": 1.0}
FIXED = np.zeros((4, 6), bool)


def masked(a: np.ndarray) -> np.ma.MaskedArray:
    return np.ma.masked_array(a, mask=np.arange(a.size).reshape(a.shape) % 2 == 0)


# (id, call(backend), exception type, message fragment): every call dispatches to ``be``
CASES = [
    # ---- bools as numbers
    ("dx-bool", lambda be: rdgpu.laplacian(G, dx=True, backend=be), TypeError,
     "dx must be a real number, got bool True"),
    ("dy-numpy-bool", lambda be: rdgpu.laplacian(G, dy=np.True_, backend=be), TypeError,
     "dy must be a real number, got bool"),
    ("dt-bool-gs", lambda be: rdgpu.gray_scott(G, G, **{**GS, "dt": True}, backend=be),
     TypeError, "dt must be a real number, got bool True"),
    ("dt-bool-diffusion", lambda be: rdgpu.diffusion_step(G, D=0.1, dt=True, backend=be),
     TypeError, "dt must be a real number, got bool"),
    ("eps-bool-ac", lambda be: rdgpu.allen_cahn(G, eps=np.True_, dt=0.01, backend=be),
     TypeError, "eps must be a real number, got bool"),
    ("tau-bool", lambda be: rdgpu.bernoulli_substep(G, tau=True, eps=1, backend=be),
     TypeError, "tau must be a real number, got bool"),
    ("omega-bool", lambda be: rdgpu.sor_sweep(G, FIXED, omega=True, backend=be), TypeError,
     "omega must be a real number, got bool"),
    ("dtau-bool", lambda be: rdgpu.reinitialize(G, dtau=True, backend=be), TypeError,
     "dtau must be a real number, got bool"),
    ("speed-bool", lambda be: rdgpu.levelset_advance(G, True, dt=0.1, backend=be), TypeError,
     "speed must be a real number, got bool"),
    ("F-bool-field", lambda be: rdgpu.gray_scott(G, G, **{**GS, "F": G > 0}, backend=be),
     TypeError, "F has unsupported dtype bool"),
    ("u-bool-list", lambda be: rdgpu.laplacian([True, False, True], backend=be), TypeError,
     "u has unsupported dtype bool"),
    ("bc-dirichlet-bool", lambda be: rdgpu.laplacian(G, bc=("dirichlet", True), backend=be),
     TypeError, "Dirichlet value must be a real number, got bool True"),
    ("bc-pair-dirichlet-bool",
     lambda be: rdgpu.laplacian(G, bc=("neumann", ("dirichlet", np.False_)), backend=be),
     TypeError, "Dirichlet value must be a real number, got bool"),
    ("steps-bool", lambda be: rdgpu.diffusion_step(G, D=0.1, dt=0.1, steps=np.True_,
                                                   backend=be),
     TypeError, "steps must be an integer, got bool"),
    # ---- text as numbers
    ("u-text-list", lambda be: rdgpu.laplacian(["1", "2", "3"], backend=be), TypeError,
     "u has unsupported dtype <U1 .*text is not converted"),
    ("u-object-list", lambda be: rdgpu.laplacian([1.0, None, 2.0], backend=be), TypeError,
     "u has unsupported dtype object"),
    ("dx-text", lambda be: rdgpu.laplacian(G, dx="1", backend=be), TypeError,
     "dx must be a real number, got str '1'"),
    ("F-bytes", lambda be: rdgpu.gray_scott(G, G, **{**GS, "F": b"0.03"}, backend=be),
     TypeError, "F must be a number or a numeric array, got bytes b'0.03'"),
    ("source-text-list", lambda be: rdgpu.diffusion_step(G, D=0.1, dt=0.1,
                                                         source=[["1"] * 6] * 4, backend=be),
     TypeError, "source has unsupported dtype <U1"),
    ("steps-text", lambda be: rdgpu.levelset_advance(G, 1.0, dt=0.1, steps="5", backend=be),
     TypeError, "steps must be an integer, got str '5'"),
    ("tol-text", lambda be: rdgpu.sor_solve(G, FIXED, tol="1e-6", backend=be), TypeError,
     "tol must be a real number, got str"),
    ("height-text", lambda be: rdgpu.laplacian(G, height=[["0"] * 6] * 4, backend=be),
     TypeError, "height has unsupported dtype <U1"),
    ("bc-dirichlet-text", lambda be: rdgpu.laplacian(G, bc=("dirichlet", "0"), backend=be),
     TypeError, "Dirichlet value must be a real number, got str '0'"),
    # ---- complex values: never cast to real
    ("dt-complex", lambda be: rdgpu.diffusion_step(G, D=0.1, dt=np.complex128(0.5 + 3j),
                                                   backend=be),
     TypeError, "dt must be a real number, got complex128 .*never cast to real"),
    ("Du-complex-zero-imag", lambda be: rdgpu.gray_scott(G, G, **{**GS, "Du": 0.1 + 0j},
                                                         backend=be),
     TypeError, "Du must be a real number, got complex"),
    ("u-complex", lambda be: rdgpu.laplacian(G.astype(complex), backend=be), TypeError,
     "u has unsupported dtype complex128: complex values are never cast"),
    ("u-complex-list", lambda be: rdgpu.laplacian([1 + 1j, 2.0], backend=be), TypeError,
     "u has unsupported dtype complex128"),
    ("k-complex-field", lambda be: rdgpu.gray_scott(G, G, **{**GS, "k": G + 0.06j},
                                                    backend=be),
     TypeError, "k has unsupported dtype complex128"),
    ("speed-complex-field", lambda be: rdgpu.levelset_advance(G, ONES + 0j, dt=0.1,
                                                              backend=be),
     TypeError, "speed has unsupported dtype complex128"),
    ("height-complex", lambda be: rdgpu.laplacian(G, height=G + 1j, backend=be), TypeError,
     "height has unsupported dtype complex128"),
    ("bc-dirichlet-complex", lambda be: rdgpu.laplacian(G, bc=("dirichlet", 1j), backend=be),
     TypeError, "Dirichlet value must be a real number, got complex"),
    # ---- one value, not an array of one
    ("Du-array-of-one", lambda be: rdgpu.gray_scott(G, G, **{**GS, "Du": np.array([0.1])},
                                                    backend=be),
     TypeError, r"Du must be a single number, got an array of shape \(1,\)"),
    ("dt-huge-int", lambda be: rdgpu.diffusion_step(G, D=0.1, dt=10**400, backend=be),
     ValueError, "dt must be finite"),
    # ---- floats never truncated to integers
    ("steps-float", lambda be: rdgpu.diffusion_step(G, D=0.1, dt=0.1, steps=2.5, backend=be),
     TypeError, "steps must be an integer, got float 2.5: a float is never truncated"),
    ("steps-numpy-float", lambda be: rdgpu.gray_scott(G, G, **GS, steps=np.float64(2.0),
                                                      backend=be),
     TypeError, "steps must be an integer, got float"),
    ("iterations-float", lambda be: rdgpu.reinitialize(G, iterations=3.7, backend=be),
     TypeError, "iterations must be an integer, got float 3.7"),
    ("max-sweeps-float", lambda be: rdgpu.sor_solve(G, FIXED, max_sweeps=10.5, backend=be),
     TypeError, "max_sweeps must be an integer, got float 10.5"),
    # ---- masked arrays: the mask is never ignored
    ("u-masked", lambda be: rdgpu.laplacian(masked(ONES), backend=be), TypeError,
     r"u is a NumPy masked array: rdgpu would ignore its mask; pass np.ma.filled\(u, value\)"),
    ("v-masked", lambda be: rdgpu.gray_scott(G, masked(G), **GS, backend=be), TypeError,
     "v is a NumPy masked array"),
    ("F-masked", lambda be: rdgpu.gray_scott(G, G, **{**GS, "F": masked(ONES * 0.03)},
                                             backend=be),
     TypeError, r"F is a NumPy masked array.*np.ma.filled\(F, value\)"),
    ("dt-masked", lambda be: rdgpu.diffusion_step(G, D=0.1, dt=np.ma.masked_array(0.1, True),
                                                  backend=be),
     TypeError, "dt is a NumPy masked array"),
    ("fixed-masked", lambda be: rdgpu.sor_sweep(G, masked(FIXED), omega=1.5, backend=be),
     TypeError, "fixed is a NumPy masked array"),
    ("rhs-masked", lambda be: rdgpu.sor_solve(G, FIXED, rhs=masked(G), backend=be), TypeError,
     "rhs is a NumPy masked array"),
    ("height-masked", lambda be: rdgpu.laplacian(G, height=masked(G), backend=be), TypeError,
     "height is a NumPy masked array"),
    ("phi-masked", lambda be: rdgpu.reinitialize(masked(ONES), backend=be), TypeError,
     "phi is a NumPy masked array"),
    ("out-masked", lambda be: rdgpu.laplacian(G, out=masked(G.copy()), backend=be), TypeError,
     "out is a NumPy masked array"),
    # ---- flags are bools
    ("check-stability-text", lambda be: rdgpu.gray_scott(G, G, **GS, check_stability="no",
                                                         backend=be),
     TypeError, "check_stability must be True or False, got str 'no'"),
    ("subcell-fix-int", lambda be: rdgpu.reinitialize(G, subcell_fix=0, backend=be), TypeError,
     "subcell_fix must be True or False, got int 0"),
    # ---- tol
    ("tol-explicit", lambda be: rdgpu.diffusion_step(G, D=0.1, dt=0.1, tol=-1, backend=be),
     ValueError, "tol=-1 given with method='explicit'"),
    ("tol-negative-implicit", lambda be: rdgpu.diffusion_step(
        G, D=0.1, dt=0.1, method="backward-euler", tol=-1, backend=be),
     ValueError, "tol must be > 0.0, got -1.0"),
    # ---- DLA by walkers and by the nutrient field
    ("walk-sticking-bool", lambda be: rdgpu.random_walk_dla((32, 32), particles=5,
                                                            sticking=True, backend=be),
     TypeError, "sticking must be a real number, got bool"),
    ("walk-particles-float", lambda be: rdgpu.random_walk_dla((32, 32), particles=2.7,
                                                              backend=be),
     TypeError, "particles must be an integer, got float 2.7"),
    ("walk-walkers-bool", lambda be: rdgpu.random_walk_dla((32, 32), particles=5,
                                                           walkers=True, backend=be),
     TypeError, "walkers must be an integer, got bool"),
    ("walk-batch-text", lambda be: rdgpu.random_walk_dla((32, 32), particles=5, batch="64",
                                                         backend=be),
     TypeError, "batch must be an integer, got str"),
    ("walk-seed-float", lambda be: rdgpu.random_walk_dla((32, 32), particles=5, seed=1.5,
                                                         backend=be),
     TypeError, "seed must be an integer, got float"),
    ("walk-margin-bool", lambda be: rdgpu.random_walk_dla((32, 32), particles=5, margin=True,
                                                          backend=be),
     TypeError, "margin must be an integer, got bool"),
    ("dla-eta-bool", lambda be: rdgpu.dla((16, 16), eta=True, steps=1, backend=be), TypeError,
     "eta must be a real number, got bool"),
    ("dla-tol-text", lambda be: rdgpu.dla((16, 16), tol="1e-3", steps=1, backend=be),
     TypeError, "tol must be a real number, got str"),
    ("dla-omega-bool", lambda be: rdgpu.dla((16, 16), omega=True, steps=1, backend=be),
     TypeError, "omega must be a real number, got bool"),
    ("dla-steps-float", lambda be: rdgpu.dla((16, 16), steps=2.5, backend=be), TypeError,
     "steps must be an integer, got float 2.5"),
    ("dla-max-sweeps-float", lambda be: rdgpu.dla((16, 16), steps=1, max_sweeps=100.5,
                                                  backend=be),
     TypeError, "max_sweeps must be an integer, got float 100.5"),
    ("dla-k-bool", lambda be: rdgpu.dla((16, 16), steps=1, k=True, backend=be), TypeError,
     "k must be an integer, got bool"),
    ("dla-shape-fraction", lambda be: rdgpu.dla((16.5, 16), steps=1, backend=be), ValueError,
     "shape must be a whole number >= 0, got 16.5"),
    ("dla-warm-start-text", lambda be: rdgpu.dla((16, 16), steps=1, warm_start="no",
                                                 backend=be),
     TypeError, "warm_start must be True or False"),
]


@pytest.mark.parametrize("name", BACKENDS)
@pytest.mark.parametrize("call, exc, fragment", [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_bad_numbers(name, call, exc, fragment):
    be = backend_or_skip(name)
    with pytest.raises(exc, match=fragment):
        call(be)


def test_enough_cases():
    assert len(CASES) >= 60


# ---------------------------------------------------------------------------- the rules
def test_scalar_takes_real_numbers_of_every_kind():
    for x in (0.5, 1, np.float32(0.5), np.int64(3), np.array(0.25), Fraction(1, 4)):
        assert check.scalar(x, "x") == float(x)


def test_whole_takes_integers_and_refuses_fractions():
    assert check.whole(np.int32(7), "n") == 7 and check.whole(np.array(3), "n") == 3
    assert check.whole(8.0, "n", floats=True) == 8  # a whole float where floats are allowed
    with pytest.raises(ValueError, match="n must be a whole number >= 0, got 8.7"):
        check.whole(8.7, "n", floats=True)
    with pytest.raises(TypeError, match="n must be an integer, got float 8.0"):
        check.whole(8.0, "n")
    with pytest.raises(ValueError, match="n must be <= 5, got 6"):
        check.whole(6, "n", maximum=5)
    assert check.flag(np.True_, "f") is True


def test_one_integer_check():
    """``sim_checks.whole`` (Simulation, sweeps) is the shared ``validation.whole`` with
    whole floats allowed: same rules (a 0-d array is taken, a float past 2**53 refused),
    and ``sweep`` uses the public check, not a private one of ``simulation``."""
    from rdgpu.runs import sweep
    from rdgpu.simulation import checks as sim_checks

    assert sim_checks.whole(np.array(4), "steps") == 4 and sim_checks.whole(1e4, "n") == 10000
    with pytest.raises(ValueError, match="n must be a whole number >= 0, got .*a float that large"):
        check.whole(2.0**60, "n", floats=True)
    with pytest.raises(ValueError, match="steps must be a whole number >= 0, got 2.5"):
        sim_checks.whole(2.5, "steps")
    with pytest.raises(ValueError, match="k must be a whole number >= 1 and <= 3, got 4"):
        sim_checks.whole(4, "k", 1, 3)
    with pytest.raises(TypeError, match="tol must be a real number, got bool True"):
        sim_checks.real(True, "tol")
    assert sweep.whole is sim_checks.whole and not hasattr(sweep, "_whole")


# ---------------------------------------------------------------------------- backend specs
@pytest.mark.parametrize("spec, fragment", [
    ("numpy:gpu", "the numpy backend runs on this CPU and takes no device; use 'numpy'"),
    ("numpy:", "takes no device"),
    ("auto:0", "'auto' picks the backend and its device"),
    ("opencl:", "has an empty device after ':'"),
    ("warp:", "has an empty device after ':'"),
    ("warp:nonsense", "unknown Warp device 'nonsense'; allowed: 'warp:cpu', 'warp:cuda'"),
    ("warp:cuda:x", "unknown Warp device 'cuda:x'"),
])
def test_malformed_backend_spec(spec, fragment, monkeypatch):
    G1 = np.zeros(4)
    with pytest.raises(ValueError, match=fragment):
        rdgpu.laplacian(G1, backend=spec)
    with pytest.raises(ValueError, match=fragment):
        rdgpu.set_backend(spec)
    monkeypatch.setenv("RDGPU_BACKEND", spec)  # the environment's spec too
    with pytest.raises(ValueError, match=fragment):
        rdgpu.laplacian(G1)


def test_well_formed_specs_still_work():
    assert rdgpu.get_backend(" NumPy ").name == "numpy"
    backend_or_skip("warp")
    assert rdgpu.get_backend("warp:CPU").name == "warp"


# ---------------------------------------------------------------------------- sizes (B)
def view(value, shape, dtype=np.float32):
    """A zero-stride view of ``shape``: no memory of its own."""
    return np.broadcast_to(dtype(value), shape)


@pytest.mark.parametrize("name", BACKENDS)
def test_huge_zero_stride_view_refused_before_it_is_read(name, monkeypatch):
    """A 2^34-cell broadcast view was materialised by the input check: now refused from
    its shape -- the 32-bit cell limit of Warp and OpenCL, the memory estimate on numpy --
    before a value is read (its NaN is not what the message reports)."""
    monkeypatch.setenv("RDGPU_MEMORY_LIMIT", "16G")
    be = backend_or_skip(name)
    u = view(np.nan, (2**17, 2**17))
    fragment = ("needs about 412 GB of memory" if name == "numpy" else
                rf"u has 17,179,869,184 cells .*too many for the {name} kernels")
    with pytest.raises(ResourceLimitError, match=fragment):
        rdgpu.laplacian(u, backend=be)


@pytest.mark.parametrize("name", ["warp", "opencl"])
def test_2_31_cells_refused_on_32_bit_backends(name, monkeypatch):
    """2^31 cells: one past what the Warp and OpenCL kernels index (the README's limit);
    refused before any copy or upload (was OOM-killed at 12 GB first)."""
    monkeypatch.delenv("RDGPU_MEMORY_LIMIT", raising=False)
    be = backend_or_skip(name)
    shape = (2**16, 2**15)
    with pytest.raises(ResourceLimitError, match="at most 2,147,483,647 cells"):
        rdgpu.laplacian(view(0.0, shape), backend=be)
    with pytest.raises(ResourceLimitError, match="u has 2,147,483,648 cells"):
        rdgpu.bernoulli_substep(view(0.0, (2**11, 2**10, 2**10)), tau=1, eps=1, backend=be)
    for alloc in (lambda: be.empty(shape, np.float32), lambda: be.upload(view(0.0, shape))):
        with pytest.raises(ResourceLimitError, match="too large for the .* kernels"):
            alloc()


def test_terra_cell_grid_is_refused_from_the_estimate(monkeypatch):
    """10^12 cells: a raw MemoryError before; now the shared estimate's message, naming the
    argument."""
    monkeypatch.setenv("RDGPU_MEMORY_LIMIT", "16G")
    u = view(1.0, (10**6, 10**6), np.float64)
    with pytest.raises(ResourceLimitError,
                       match=r"u of shape \(1000000, 1000000\) needs about 32 TB of memory"):
        rdgpu.laplacian(u, backend="numpy")
    with pytest.raises(ResourceLimitError, match=r"phi of shape \(1000000, 1000000\)"):
        rdgpu.reinitialize(u, backend="numpy")


@pytest.mark.parametrize("name", BACKENDS)
def test_zero_stride_views_that_fit_run(name):
    """A broadcast view that fits is checked once per distinct value and runs."""
    be = backend_or_skip(name)
    out = rdgpu.laplacian(view(2.0, (64, 64), np.float64), backend=be)
    np.testing.assert_array_equal(out, np.zeros((64, 64)))
    with pytest.raises(ValueError, match="u contains 4096 NaN or Inf"):
        rdgpu.laplacian(view(np.nan, (64, 64), np.float64), backend=be)


def test_value_checks_never_materialise_a_view():
    """2^40 cells (8 TB as float64) counted in well under a second, in no memory."""
    assert check.count_nonfinite(view(np.nan, (2**20, 2**20), np.float64)) == 2**40
    assert not check.has_subnormals(view(1.0, (2**20, 2**20), np.float64))
    rows = np.broadcast_to(np.array([1.0, np.inf, 1e-310]), (2**30, 3))  # a stride-0 axis
    assert check.count_nonfinite(rows) == 2**30
    assert check.has_subnormals(rows)


def test_blocks_cover_large_arrays_exactly(monkeypatch):
    """Values checked block by block: every element seen once, contiguous or not."""
    monkeypatch.setattr(check, "CHECK_BLOCK", 7)
    a = np.ones((13, 11))
    a[12, 9] = np.nan
    a[0, 0] = np.inf
    assert check.count_nonfinite(a) == 2
    assert check.count_nonfinite(a.T) == 2  # not C-contiguous
    assert check.count_nonfinite(a[::2, ::3]) == 2
    b = np.ones((2, 40))
    b[1, 39] = 1e-320
    assert check.has_subnormals(b.T) and not check.has_subnormals(np.ones((3, 50)).T)


@pytest.mark.parametrize("name", BACKENDS)
def test_walkers_refused_from_the_estimate(name, monkeypatch):
    """random_walk_dla(walkers=10**9) allocated >10 GB on the host before failing."""
    monkeypatch.setenv("RDGPU_MEMORY_LIMIT", "16G")
    be = backend_or_skip(name)
    with pytest.raises(ResourceLimitError,
                       match="random_walk_dla with 1,000,000,000 walkers on a 64x64 grid "
                             "needs about 160 GB"):
        rdgpu.random_walk_dla((64, 64), walkers=10**9, backend=be)
    with pytest.raises(ResourceLimitError, match="on a 40000x40000 grid needs about"):
        rdgpu.random_walk_dla((40000, 40000), backend=be)


@pytest.mark.parametrize("name", BACKENDS)
def test_dla_refused_from_the_estimate(name, monkeypatch):
    monkeypatch.setenv("RDGPU_MEMORY_LIMIT", "10M")
    be = backend_or_skip(name)
    with pytest.raises(ResourceLimitError, match="dla on a 2048x2048 grid needs about"):
        rdgpu.dla((2048, 2048), steps=1, backend=be)


def test_front_snapshots_refused_from_the_estimate(monkeypatch):
    """``run(10**12, snapshot_every=1)`` of a front: refused before its first step."""
    monkeypatch.setenv("RDGPU_MEMORY_LIMIT", "1G")
    from rdgpu.growth.fronts import RDFront

    sim = rdgpu.Simulation.from_preset("turing-seed003-spots", backend="numpy")
    front = RDFront(sim)
    with pytest.raises(ResourceLimitError, match="front_growth with 1,000,000,000,000 snapshots"):
        front.run(10**12, snapshot_every=1)
    assert front.steps_done == 0
    for kwargs, fragment in ((dict(radius=True), "radius must be a real number, got bool"),
                             (dict(beta_scale="1"), "beta_scale must be a real number, got str"),
                             (dict(a0=0.5j), "a0 must be a real number, got complex"),
                             (dict(reinit_every=2.5), "reinit_every must be an integer, got float"),
                             (dict(substep="yes"), "substep must be True or False"),
                             (dict(phi0=masked(np.ones((64, 64)))), "phi0 is a NumPy masked")):
        with pytest.raises(TypeError, match=fragment):
            RDFront(sim, **kwargs)
    with pytest.raises(TypeError, match="steps must be an integer, got float 2.5"):
        rdgpu.front_growth(preset="turing-seed003-spots", steps=2.5, backend="numpy")


# ---------------------------------------------------------------------------- E5
def test_lazy_names_are_attributes_and_listed():
    """``rdgpu.fronts``, ``rdgpu.analysis``, ``rdgpu.output`` were no attributes after
    ``import rdgpu``, and ``dir(rdgpu)`` hid the names imported on first use; every name
    ``dir`` lists resolves, and none of this imports an optional package."""
    code = (
        "import sys, rdgpu\n"
        "names = dir(rdgpu)\n"
        "mods = [rdgpu.fronts.__name__, rdgpu.analysis.__name__, rdgpu.output.__name__]\n"
        "heavy = sorted(m for m in ('dask', 'matplotlib', 'pyvista', 'h5py', 'zarr', 'pde', "
        "'xarray', 'trimesh', 'warp', 'pyopencl') if m in sys.modules)\n"
        "missing = [n for n in names if not n.startswith('__') and not hasattr(rdgpu, n)]\n"
        "print(mods, heavy, missing, sep='|')\n"
        "print('|'.join(names))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, check=True)
    first, listing = proc.stdout.strip().splitlines()
    mods, heavy, missing = first.split("|")
    assert mods == "['rdgpu.growth.fronts', 'rdgpu.analysis', 'rdgpu.output']"
    assert heavy == "[]", heavy
    assert missing == "[]", missing
    names = set(listing.split("|"))
    for lazy in ("Simulation", "define_model", "SurfaceMesh", "sweep", "sweep_map", "dla",
                 "dla_image", "random_walk_dla", "front_growth", "GraphSurface", "fronts",
                 "analysis", "output", "interop", "surfaces"):
        assert lazy in names, lazy


# ------------------------------------------------------------ ImplicitDiffusion, directly
@pytest.mark.parametrize("kwargs, exc, fragment", [
    (dict(tol=True), TypeError, "tol must be a real number, got bool True"),
    (dict(tol="1e-5"), TypeError, "tol must be a real number, got str '1e-5'"),
    (dict(D="1"), TypeError, "D must be a real number, got str"),
    (dict(dt=True), TypeError, "dt must be a real number, got bool"),
    (dict(dt=0.5 + 1j), TypeError, "dt must be a real number, got complex"),
    (dict(theta=b"1"), TypeError, "theta must be a real number, got bytes"),
    (dict(omega=True), TypeError, "omega must be a real number, got bool"),
    (dict(max_sweeps=10.5), TypeError, "max_sweeps must be an integer, got float 10.5"),
    (dict(max_sweeps=True), TypeError, "max_sweeps must be an integer, got bool"),
    (dict(max_sweeps=0), ValueError, "max_sweeps must be >= 1, got 0"),
    (dict(check_every="2"), TypeError, "check_every must be an integer, got str"),
    (dict(check_every=1.5), TypeError, "check_every must be an integer, got float 1.5"),
])
def test_implicit_diffusion_numbers(kwargs, exc, fragment):
    """Constructed directly, ImplicitDiffusion takes its numbers through the shared checks
    (it used float()/int(): tol=True was 1.0, tol="1e-5" parsed, max_sweeps=10.5 cut)."""
    from rdgpu.domains.grid import Grid
    from rdgpu.ops.implicit import ImplicitDiffusion

    args = {"D": 1.0, "dt": 0.1, **kwargs}
    with pytest.raises(exc, match=fragment):
        ImplicitDiffusion(Grid((4, 4)), backend="numpy", **args)


def test_implicit_diffusion_source_is_a_real_number():
    from rdgpu.domains.grid import Grid
    from rdgpu.ops.implicit import ImplicitDiffusion

    solver = ImplicitDiffusion(Grid((4, 4)), D=1.0, dt=0.1, backend="numpy")
    with pytest.raises(TypeError, match="source must be a real number, got str"):
        solver.means("1")
