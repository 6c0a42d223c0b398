"""One benchmark run: the machine measured, the sizes chosen, every contender checked then
timed (the ``peers`` group), then the other row groups of ``Options.rows``
(`rdgpu.bench.groups`), all gathered in one JSON-ready record (`run_bench`).

A row is one contender on one case (dimensions, dtype, grid edge): ``status`` is ``"ok"``
(``mcells``: Mcell·steps/s, the best batch of steps over ``seconds``, the best of
``rounds`` rounds taking the contenders in turn), ``"refused"`` (it
disagreed with the NumPy reference: ``note`` says how; it is never timed) or ``"skipped"``
(it cannot run that case: ``note`` says why).  ``compile_s`` is the first step's time in
the check (compilation, apart from the timing).  The roofline is the out-of-cache triad
bandwidth ÷ the bytes a step moves per cell; ``pct_roofline`` is given only for grids
whose state exceeds the effective LLC.
"""

from __future__ import annotations

import sys
import time
from dataclasses import asdict, dataclass, field

from rdgpu.bench.contenders import CHECK_SHAPE, CHECK_STEPS, Contender, check, rdgpu_contenders
from rdgpu.bench.devices import best_batch_seconds
from rdgpu.bench.groups import GROUPS, GroupOptions, run_groups
from rdgpu.bench.machine import MiB, grid_sizes, machine_record, triad_sweep
from rdgpu.bench.peers import PEERS, peer_contenders
from rdgpu.bench.problem import TILE, bytes_per_cell, real_state
from rdgpu.bench.rows_kernels import BYTES_PER_CELL
from rdgpu.core.hardware import cpu_caches

__all__ = ["Options", "QUICK_SIZES", "check_options", "run_bench", "time_rate"]

#: the edges of a ``--quick`` run
QUICK_SIZES = {2: [128], 3: [32]}


@dataclass
class Options:
    """What to run: the row groups ``rows`` (of `GROUPS`), rdgpu ``backends`` (specs, or
    the GPU labels of `rdgpu.bench.devices`), ``peers`` (names of `PEERS`), ``dims``,
    ``dtypes``, grid edges (``sizes``: ``{dims: [edge, ...]}``; None: from the cache; the
    2-D edges are the kernel rows' too), ``seconds`` of timing per row and ``rounds`` of
    the peers' rows (the contenders in turn, the best round each), the triad sweep up
    to ``triad_max`` bytes, the other groups' sizes (``groups``), ``quick`` and ``full``
    (the slowest rows too: NumPy on the real states)."""

    rows: list[str] = field(default_factory=lambda: ["peers"])

    backends: list[str] = field(default_factory=lambda: ["opencl", "warp"])
    peers: list[str] = field(default_factory=list)
    dims: list[int] = field(default_factory=lambda: [2, 3])
    dtypes: list[str] = field(default_factory=lambda: ["float32"])
    sizes: dict[int, list[int]] | None = None
    seconds: float = 0.5
    rounds: int = 2
    triad_max: int = 2048 * MiB
    triad_seconds: float = 0.1
    groups: GroupOptions = field(default_factory=GroupOptions)
    quick: bool = False
    full: bool = False


def _say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def time_rate(runner, cells: int, seconds: float) -> float:
    """Best Mcell·steps/s of ``runner`` (`rdgpu.bench.devices.best_batch_seconds` of its
    ``advance``)."""
    return cells / best_batch_seconds(runner.advance, seconds) / 1e6


def check_options(opts: Options) -> None:
    """ValueError naming the option when ``opts`` cannot run (before any work)."""
    bad = [r for r in opts.rows if r not in GROUPS]
    if bad or not opts.rows:
        raise ValueError(f"rows: unknown {bad or 'none'}; known: {', '.join(GROUPS)} or all")
    bad = [k for k in opts.groups.kernels if k not in BYTES_PER_CELL]
    if bad:
        raise ValueError(f"kernels: unknown {bad}; known: {', '.join(BYTES_PER_CELL)}")
    if not opts.dims or any(d not in TILE for d in opts.dims):
        raise ValueError(f"dims: expected 2 and/or 3, got {opts.dims}")
    if not opts.dtypes or any(t not in ("float32", "float64") for t in opts.dtypes):
        raise ValueError(f"dtype: expected float32 and/or float64, got {opts.dtypes}")
    unknown = [p for p in opts.peers if p not in PEERS]
    if unknown:
        raise ValueError(f"peers: unknown {unknown}; known: {', '.join(PEERS)}")
    if not opts.seconds > 0:
        raise ValueError(f"seconds: expected a positive number, got {opts.seconds}")
    if isinstance(opts.rounds, bool) or not isinstance(opts.rounds, int) or opts.rounds < 1:
        raise ValueError(f"rounds: expected a whole number >= 1, got {opts.rounds!r}")
    for dims in opts.dims if opts.sizes else ():
        bad = [n for n in opts.sizes.get(dims, []) if n <= 0 or n % TILE[dims]]
        if bad or not opts.sizes.get(dims):
            raise ValueError(f"sizes: a {dims}-D grid's edge must be a positive multiple of "
                             f"{TILE[dims]} (the real state's tile); got {bad or 'none'}")


def _sizes(opts: Options, dims: int, llc: int) -> list[int]:
    if opts.sizes:
        return list(opts.sizes[dims])
    worst = max(bytes_per_cell(t) for t in opts.dtypes)
    return grid_sizes(llc, dims, worst, TILE[dims])


def _checked(c: Contender, dims: int, dtype: str) -> tuple[str | None, float | None]:
    """``(why refused or skipped, compile seconds)``: the contender's first step timed on
    a check-sized grid (its compilation), then the check."""
    lacks = c.lacks(dims, dtype)
    if lacks is not None:
        return lacks, None
    u, v = real_state(CHECK_SHAPE[dims], dtype)
    t0 = time.perf_counter()
    try:
        c.make(u, v).advance(1)
    except Exception as exc:  # noqa: BLE001 - reported by the check below
        _say(f"  {c.name}: first step failed: {exc}")
    compile_s = time.perf_counter() - t0
    return check(c, dims, dtype), compile_s


def _case_rows(contenders: list[Contender], dims: int, dtype: str, sizes: list[int],
               llc: int, roof_bw: float, seconds: float, rounds: int) -> list[dict]:
    """Every contender's rows of one (dims, dtype): each checked once, then timed in
    ``rounds`` rounds that take the contenders in turn at each size (a contender's best
    round counts), so that a machine whose speed drifts over minutes hits all alike."""
    rows: dict[tuple[str, int], dict] = {}
    for c in contenders:
        why, compile_s = _checked(c, dims, dtype)
        status = "ok" if why is None else ("skipped" if compile_s is None else "refused")
        for n in sizes:
            cells = n ** dims
            nbytes = bytes_per_cell(dtype)
            rows[c.name, n] = dict(
                dims=dims, dtype=dtype, size=n, cells=cells, contender=c.name,
                family=c.family, version=c.version, status=status, note=why,
                compile_s=compile_s, bytes_per_cell=nbytes, in_cache=cells * nbytes <= llc,
                roofline_mcells=roof_bw * 1e9 / nbytes / 1e6)
            if status != "ok":
                _say(f"  {dims}-D {dtype} {n:>5} {c.name:24s} {status}: {why}")
    for r in range(rounds):
        for n in sizes:
            for c in contenders:
                row = rows[c.name, n]
                if row["status"] != "ok":
                    continue
                runner = c.make(*real_state((n,) * dims, dtype))
                rate = time_rate(runner, row["cells"], seconds)
                del runner
                row["mcells"] = max(rate, row.get("mcells", 0.0))
                _say(f"  {dims}-D {dtype} {n:>5} {c.name:24s} {rate:9.0f} Mcell/s"
                     f" (round {r + 1} of {rounds})")
    for row in rows.values():
        if "mcells" in row and not row["in_cache"]:
            row["pct_roofline"] = 100 * row["mcells"] / row["roofline_mcells"]
    return [rows[c.name, n] for c in contenders for n in sizes]


def _machine(opts: Options) -> tuple[dict, int, float, list[str]]:
    """The machine record, the LLC used for sizes and marks, the roofline's GB/s, notes."""
    _say(f"triad sweep up to {opts.triad_max / MiB:.0f} MiB ...")
    record = machine_record(triad_sweep(opts.triad_max, opts.triad_seconds))
    notes = []
    llc, caches = record["llc"], cpu_caches()
    if llc is None:
        llc = caches.llc or 32 * MiB
        notes.append(f"the triad sweep (up to {opts.triad_max / MiB:.0f} MiB) did not leave "
                     f"the cache: the OS-reported LLC ({llc / MiB:.0f} MiB) is used, and the "
                     "roofline is the sweep's largest point")
    elif llc <= caches.l2:
        notes.append(f"the triad sweep saw a cache of {llc / MiB:.0f} MiB, no more than one "
                     f"L2 ({caches.l2 / MiB:.0f} MiB): a busy machine disturbed it; the "
                     f"OS-reported LLC ({(caches.llc or 32 * MiB) / MiB:.0f} MiB) is used")
        llc = caches.llc or 32 * MiB
    _say(f"effective LLC {llc / MiB:.0f} MiB; triad {record['dram_GBps']:.1f} GB/s out of "
         f"cache, {record['cache_GBps']:.1f} GB/s in it")
    return record, llc, record["dram_GBps"], notes


def _peer_rows(opts: Options, contenders: list[Contender] | None, llc: int,
               bw: float) -> tuple[list[dict], dict[str, str]]:
    skipped: dict[str, str] = {}
    if contenders is None:
        contenders = rdgpu_contenders(opts.backends)
        peers, skipped = peer_contenders(opts.peers)
        contenders += peers
    rows = []
    for dims in opts.dims:
        sizes = _sizes(opts, dims, llc)
        for dtype in opts.dtypes:
            _say(f"{dims}-D {dtype}: edges {sizes}")
            rows += _case_rows(contenders, dims, dtype, sizes, llc, bw, opts.seconds,
                               opts.rounds)
    return rows, skipped


def run_bench(opts: Options, contenders: list[Contender] | None = None) -> dict:
    """Measure the machine, then run the row groups of ``opts.rows``: the peers (check and
    time every contender -- rdgpu's ``opts.backends`` and ``opts.peers``, or
    ``contenders`` as given -- on every case) and the others (`run_groups`): the record."""
    record, llc, bw, notes = _machine(opts)
    rows, skipped = (_peer_rows(opts, contenders, llc, bw) if "peers" in opts.rows
                     else ([], {}))
    groups = {}
    if any(r != "peers" for r in opts.rows):
        if opts.sizes and 2 in opts.sizes and opts.groups.kernel_sizes is None:
            opts.groups.kernel_sizes = list(opts.sizes[2])
        groups = run_groups(opts.rows, opts.backends, opts.groups, record, llc, bw,
                            opts.seconds, quick=opts.quick, full=opts.full, say=_say)
    return {"machine": record, "llc_used": llc, "roofline_GBps": bw,
            "options": asdict(opts), "peers_not_run": skipped, "notes": notes,
            "check": {"steps": CHECK_STEPS, "shapes": CHECK_SHAPE},
            "peers_known": list(PEERS), "rows": rows, "groups": groups}
