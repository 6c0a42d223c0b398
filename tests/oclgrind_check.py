"""Running a script under Oclgrind (the OpenCL simulator) and asserting it reports no
out-of-bounds access and no data race (shared by the cross-checks and the blocking tests)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import rdgpu


def oclgrind_available() -> bool:
    try:
        import pyopencl as cl

        return any("oclgrind" in p.name.lower() for p in cl.get_platforms())
    except Exception:  # noqa: BLE001 - no pyopencl or no platform at all
        return False


def check_clean_under_oclgrind(args: list[str], oks: int) -> None:
    """Run ``python *args`` (with this rdgpu, Oclgrind's race checks on): it must exit 0,
    print `` ok`` ``oks`` times, and Oclgrind must report no invalid access or race."""
    env = {**os.environ, "OCLGRIND_DATA_RACES": "1", "PYTHONPATH": os.pathsep.join(
        [str(Path(rdgpu.__file__).resolve().parents[1]), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, *args], capture_output=True, text=True,
                          env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.count(" ok") == oks, proc.stdout
    reports = [line for line in proc.stderr.splitlines()
               if any(k in line for k in ("Invalid read", "Invalid write", "data race",
                                          "out of bounds", "Invalid access"))]
    assert not reports, "\n".join(reports[:20]) + "\n" + proc.stderr[-2000:]
