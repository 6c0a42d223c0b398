"""A benchmark record (`rdgpu.bench.run.run_bench`) as files: ``bench.json`` (the record),
``bench.md`` (`markdown`: the machine, then the peers' section -- one table per dimensions
and dtype, a row per contender and a column per grid edge, in Mcell·steps/s -- and a
section per other row group, each table naming the machine it ran on), ``bench.png``
(`plot`, the peers: rate against cells, log-log, the roofline and the effective LLC
marked) and ``bench-kernels.png`` (the kernel rows, `rdgpu.bench.rows_kernels.plot`);
the plots need matplotlib, the ``media`` extra -- without it there is no plot and `write`
says so.
"""

from __future__ import annotations

import json
from pathlib import Path

from rdgpu.bench.groups import GROUPS, TITLES
from rdgpu.bench.machine import MiB
from rdgpu.bench.rows_kernels import plot as plot_kernels

__all__ = ["markdown", "plot", "write"]


def _cell(row: dict) -> str:
    if row["status"] == "ok":
        return f"{row['mcells']:.0f}"
    return "refused" if row["status"] == "refused" else "–"


def _header(record: dict) -> list[str]:
    m = record["machine"]
    v = m["versions"]
    lines = [f"Machine: {m['cpu']}, {m['cores']} cores; caches as reported: "
             f"{m['reported_caches']}.",
             f"Triad ({m['triad']['how']}): {m['dram_GBps']:.1f} GB/s out of cache, "
             f"{m['cache_GBps']:.1f} GB/s in it; effective LLC "
             f"{record['llc_used'] / MiB:.0f} MiB.",
             f"rdgpu {v['rdgpu']}, NumPy {v['numpy']}, Warp {v['warp']}, PyOpenCL "
             f"{v['pyopencl']}, Python {v['python']}."]
    lines += [f"Note: {n}." for n in record["notes"]]
    return lines


def _table(rows: list[dict], dims: int, dtype: str, record: dict) -> list[str]:
    sizes = sorted({r["size"] for r in rows})
    names = list(dict.fromkeys(r["contender"] for r in rows))
    by = {(r["contender"], r["size"]): r for r in rows}
    nbytes = rows[0]["bytes_per_cell"]
    roof = record["roofline_GBps"] * 1e9 / nbytes / 1e6
    heads = [f"{n}{'²' if dims == 2 else '³'}" + ("" if by[(names[0], n)]["in_cache"]
                                                  else " (DRAM)") for n in sizes]
    out = [f"### {dims}-D, {dtype} (Mcell·steps/s; roofline {roof:.0f})", "",
           "| contender | version | compile s | " + " | ".join(heads) + " |",
           "|---|---|---:|" + "---:|" * len(sizes)]
    for name in names:
        first = by[(name, sizes[0])]
        comp = "" if first["compile_s"] is None else f"{first['compile_s']:.2f}"
        out.append(f"| {name} | {first['version']} | {comp} | "
                   + " | ".join(_cell(by[(name, n)]) for n in sizes) + " |")
    notes = {r["contender"]: r["note"] for r in rows if r["note"]}
    out += [""] + [f"* {name}: {why}" for name, why in notes.items()]
    return out + [""]


def _best_ratio(rows: list[dict]) -> list[str]:
    """One line per grid edge: the best rdgpu rate over the best peer's."""
    out = []
    for n in sorted({r["size"] for r in rows}):
        ok = [r for r in rows if r["size"] == n and r["status"] == "ok"]
        mine = [r["mcells"] for r in ok if r["family"] == "rdgpu"]
        theirs = [r for r in ok if r["family"] == "peer"]
        if mine and theirs:
            best = max(theirs, key=lambda r: r["mcells"])
            out.append(f"* {n}: best rdgpu / best peer ({best['contender']}) = "
                       f"{max(mine) / best['mcells']:.2f}")
    return out + [""] if out else []


def markdown(record: dict) -> str:
    """The record as Markdown: the machine, then the peers' tables (one per (dims,
    dtype)), then a section per other row group."""
    lines = ["# rdgpu bench", ""] + _header(record) + [""]
    if record["rows"]:
        lines += ["## Peers: Gray-Scott, forward Euler, periodic", ""]
    cases = dict.fromkeys((r["dims"], r["dtype"]) for r in record["rows"])
    for dims, dtype in cases:
        rows = [r for r in record["rows"] if (r["dims"], r["dtype"]) == (dims, dtype)]
        lines += _table(rows, dims, dtype, record) + _best_ratio(rows)
    lines += [f"* {name}: {why}" for name, why in record["peers_not_run"].items()]
    groups = record.get("groups", {})
    for name in (n for n in GROUPS if n in groups):
        lines += ["", f"## {TITLES[name]}", "", *groups[name]["markdown"]]
    return "\n".join(lines).rstrip() + "\n"


def plot(record: dict, path: Path) -> str | None:
    """Write the log-log plot to ``path``; returns None, or why there is no plot."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return "no plot: matplotlib is missing (pip install rdgpu[media])"
    cases = list(dict.fromkeys((r["dims"], r["dtype"]) for r in record["rows"]))
    fig, axes = plt.subplots(1, len(cases), figsize=(6 * len(cases), 4.5), squeeze=False)
    names = list(dict.fromkeys(r["contender"] for r in record["rows"]))
    colour = {n: f"C{i % 10}" for i, n in enumerate(names)}  # alike in every panel
    for ax, (dims, dtype) in zip(axes[0], cases, strict=True):
        rows = [r for r in record["rows"] if (r["dims"], r["dtype"]) == (dims, dtype)]
        for name in names:
            pts = sorted((r["cells"], r["mcells"]) for r in rows
                         if r["contender"] == name and r["status"] == "ok")
            if pts:
                ax.plot(*zip(*pts, strict=True), marker="o", label=name, color=colour[name],
                        ls="-" if name.startswith("rdgpu") else "--")
        ax.axhline(rows[0]["roofline_mcells"], color="k", ls="--", label="triad roofline")
        ax.axvline(record["llc_used"] / rows[0]["bytes_per_cell"], color="grey", ls=":",
                   label="effective LLC")
        ax.set(xscale="log", yscale="log", xlabel="cells", ylabel="Mcell·steps/s",
               title=f"{dims}-D {dtype}")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return None


def write(record: dict, out: Path) -> list[str]:
    """``bench.json``, ``bench.md``, and the plots of what ran (``bench.png``: the peers;
    ``bench-kernels.png``: the kernel rows) in ``out`` (created); the notes to print (a
    plot's absence)."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench.json").write_text(json.dumps(record, indent=1, default=str) + "\n")
    (out / "bench.md").write_text(markdown(record))
    notes = []
    if record["rows"]:
        notes.append(plot(record, out / "bench.png"))
    groups = record.get("groups", {})
    if "kernels" in groups:
        ensembles = groups.get("ensembles", {}).get("rows", [])
        notes.append(plot_kernels(groups["kernels"]["rows"], ensembles, groups["memory"],
                                  out / "bench-kernels.png"))
    return [n for n in notes if n]
