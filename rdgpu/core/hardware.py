"""The CPU's caches, read once for every user: the temporal-blocking policy
(`rdgpu.integrators.blocking`) and the benchmarks (`rdgpu.bench.machine`).

`cpu_caches` reads ``/sys/devices/system/cpu/cpu*/cache/index*`` (falling back to
``lscpu -B``, then ``getconf``) over the CPUs this process may run on, each distinct cache
instance counted once; `cache_sizes` is the per-instance size of each data level.
"""

from __future__ import annotations

import functools
import os
import re
import subprocess
from dataclasses import asdict, dataclass
from pathlib import Path

from rdgpu.core.conventions import VERSION

__all__ = ["CacheLevel", "Caches", "allowed_cpus", "cache_sizes", "cpu_caches",
           "package_versions", "parse_size"]

_MiB = 1 << 20


@dataclass
class CacheLevel:
    """One cache level: ``size`` bytes per instance, ``instances`` distinct copies serving
    the CPUs this process may use, ``type`` Data / Instruction / Unified."""

    level: int
    type: str
    size: int
    instances: int

    @property
    def total(self) -> int:
        return self.size * self.instances


@dataclass
class Caches:
    """The CPU caches and where they were read (``source``)."""

    levels: list[CacheLevel]
    source: str

    def _data(self, level: int) -> CacheLevel | None:
        return next((c for c in self.levels if c.level == level and c.type != "Instruction"),
                    None)

    @property
    def llc(self) -> int:
        """Bytes of last-level cache, all instances together (0 when unknown)."""
        data = [c for c in self.levels if c.type != "Instruction"]
        return max(data, key=lambda c: c.level).total if data else 0

    @property
    def l2(self) -> int:
        """Bytes of L2 per instance (0 when unknown)."""
        c = self._data(2)
        return c.size if c else 0

    def describe(self) -> str:
        if not self.levels:
            return f"caches unknown ({self.source})"
        parts = [f"L{c.level}{'' if c.type == 'Unified' else c.type[0].lower()} "
                 f"{c.size / 1024:g} KiB x{c.instances}" for c in self.levels]
        return f"{', '.join(parts)}; LLC {self.llc / _MiB:g} MiB in all (from {self.source})"

    def as_dict(self) -> dict:
        return dict(levels=[asdict(c) for c in self.levels], source=self.source,
                    llc_bytes=self.llc, l2_bytes=self.l2)


def parse_size(text: str) -> int:
    """``"32768K"``, ``"1M"``, ``"48 KiB"``, ``"33554432"``, ``"32 MiB (1 instance)"`` →
    bytes (ValueError for anything else)."""
    m = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([KMG]?)(i?B)?\s*(\(\d+ instances?\))?\s*", text,
                     re.IGNORECASE)
    if not m:
        raise ValueError(f"cannot read a cache size from {text!r}")
    return int(float(m.group(1)) * (1 << {"": 0, "K": 10, "M": 20, "G": 30}[m.group(2).upper()]))


def allowed_cpus() -> set[int]:
    try:
        return set(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return set(range(os.cpu_count() or 1))


def _from_sysfs(root: Path = Path("/sys/devices/system/cpu")) -> list[CacheLevel]:
    seen: dict[tuple[int, str, int], set[str]] = {}
    for cpu in sorted(allowed_cpus()):
        for index in sorted((root / f"cpu{cpu}" / "cache").glob("index*")):
            try:
                level = int((index / "level").read_text())
                kind = (index / "type").read_text().strip()
                size = parse_size((index / "size").read_text())
                shared = (index / "shared_cpu_list").read_text().strip() \
                    if (index / "shared_cpu_list").exists() else f"cpu{cpu}"
            except (OSError, ValueError):
                continue
            seen.setdefault((level, kind, size), set()).add(shared)
    return [CacheLevel(level, kind, size, len(sharers))
            for (level, kind, size), sharers in sorted(seen.items())]


def _from_lscpu() -> list[CacheLevel]:
    out = subprocess.run(["lscpu", "-B"], capture_output=True, text=True, timeout=10,
                         check=True).stdout
    levels = []
    for m in re.finditer(r"^L(\d)([di]?) cache:\s*(\d+)(?:\s*\((\d+) instances?\))?", out,
                         re.MULTILINE):
        total, count = int(m.group(3)), int(m.group(4) or 1)
        kind = {"d": "Data", "i": "Instruction", "": "Unified"}[m.group(2)]
        levels.append(CacheLevel(int(m.group(1)), kind, total // count, count))
    return levels


def _from_getconf() -> list[CacheLevel]:
    levels = []
    for level, name, kind in ((1, "LEVEL1_DCACHE_SIZE", "Data"), (2, "LEVEL2_CACHE_SIZE",
                              "Unified"), (3, "LEVEL3_CACHE_SIZE", "Unified"),
                              (4, "LEVEL4_CACHE_SIZE", "Unified")):
        out = subprocess.run(["getconf", name], capture_output=True, text=True, timeout=10)
        value = out.stdout.strip()
        if out.returncode == 0 and value.isdigit() and int(value) > 0:
            levels.append(CacheLevel(level, kind, int(value), 1))
    return levels


def cpu_caches() -> Caches:
    """The CPU caches, from the first source that names any: sysfs, ``lscpu -B``,
    ``getconf``."""
    errors = []
    for source, read in (("sysfs", _from_sysfs), ("lscpu -B", _from_lscpu),
                         ("getconf", _from_getconf)):
        try:
            levels = read()
        except (OSError, subprocess.SubprocessError) as exc:
            errors.append(f"{source}: {exc}")
            continue
        if levels:
            return Caches(levels, source)
        errors.append(f"{source}: nothing")
    return Caches([], "; ".join(errors))


@functools.cache
def cache_sizes() -> dict[int, int]:
    """``{level: bytes}``: one instance of each data (or unified) cache level, the
    smallest where the CPUs differ; empty where no source names any."""
    sizes: dict[int, int] = {}
    for c in cpu_caches().levels:
        if c.type != "Instruction":
            sizes[c.level] = min(sizes.get(c.level, c.size), c.size)
    return sizes


def package_versions() -> dict[str, str]:
    """Versions of rdgpu, Python, NumPy, SciPy, Warp and PyOpenCL (``"missing"`` if absent)."""
    import platform
    from importlib import metadata

    out = {"python": platform.python_version()}
    for name, dist in (("rdgpu", "rdgpu"), ("numpy", "numpy"), ("scipy", "scipy"),
                       ("warp", "warp-lang"), ("pyopencl", "pyopencl")):
        try:
            out[name] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[name] = "missing"
    if out["rdgpu"] == "missing":
        out["rdgpu"] = VERSION
    return out
