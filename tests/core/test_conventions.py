"""rdgpu.core.conventions (dtypes, axis names) and rdgpu.core.hardware (the CPU caches):
the shared constants and probes, owned once."""

from __future__ import annotations

import numpy as np
import pytest

from rdgpu.core import hardware
from rdgpu.core.conventions import (
    AXIS_NAMES,
    REAL_DTYPE_NAMES,
    REAL_DTYPES,
    axis_names,
    is_real,
)


def test_real_dtypes():
    assert REAL_DTYPES == (np.dtype(np.float32), np.dtype(np.float64))
    assert REAL_DTYPE_NAMES == ("float32", "float64")
    assert is_real(np.float32) and is_real("float64") and is_real(np.dtype("f4"))
    assert not any(is_real(d) for d in (None, np.float16, int, "int64", "complex128", "bad"))


def test_axis_names():
    assert AXIS_NAMES == ("z", "y", "x")
    assert [axis_names(n) for n in (1, 2, 3)] == [("x",), ("y", "x"), ("z", "y", "x")]
    with pytest.raises(ValueError, match="ndim must be 1, 2 or 3, got 4"):
        axis_names(4)


def test_parse_size():
    assert hardware.parse_size("32 MiB (1 instance)") == 32 << 20
    assert hardware.parse_size("2 MiB (2 instances)") == 2 << 20
    assert hardware.parse_size("48K") == 48 << 10
    assert hardware.parse_size("33554432") == 33554432
    assert hardware.parse_size("1.5 KiB") == 1536
    with pytest.raises(ValueError, match="cannot read a cache size from 'lots'"):
        hardware.parse_size("lots")


def test_cache_sizes_agree_with_cpu_caches(tmp_path, monkeypatch):
    root = tmp_path / "cpu"
    for cpu in (0, 1):
        for k, (level, kind, size, shared) in enumerate(
                [(1, "Data", "48K", f"{cpu}"), (1, "Instruction", "32K", f"{cpu}"),
                 (2, "Unified", "2048K", f"{cpu}"), (3, "Unified", "32768K", "0-1")]):
            d = root / f"cpu{cpu}" / "cache" / f"index{k}"
            d.mkdir(parents=True)
            for name, text in (("level", str(level)), ("type", kind), ("size", size),
                               ("shared_cpu_list", shared)):
                (d / name).write_text(text + "\n")
    monkeypatch.setattr(hardware, "allowed_cpus", lambda: {0, 1})
    levels = hardware._from_sysfs(root)
    caches = hardware.Caches(levels, "sysfs")
    assert caches.llc == 32 << 20 and caches.l2 == 2 << 20
    monkeypatch.setattr(hardware, "cpu_caches", lambda: caches)
    hardware.cache_sizes.cache_clear()
    try:
        assert hardware.cache_sizes() == {1: 48 << 10, 2: 2 << 20, 3: 32 << 20}
    finally:
        hardware.cache_sizes.cache_clear()
