"""Backends driven from several threads at once.

The reported failures: with four threads on a cold process (backends ``warp``,
``warp:cpu``, ``opencl``, ``numpy``) the process segfaulted in 4 of 11 runs inside Warp
(two WarpBackends initialising Warp and loading the same modules at once); four threads
sharing one Warp backend gave a wrong ``sor`` result in 1 of 17 runs (recorded launches
whose parameters one thread rewrote while another was about to launch them); OpenCL had
the same race on its shared kernel objects (``set_args`` then enqueue).

* :func:`test_cold_threads_in_fresh_processes` runs ``tests/core/thread_worker.py`` in fresh
  processes (the bugs are in first-use initialisation, so every run must start cold): four
  threads call laplacian, gray_scott, sor_solve, levelset_advance and spmv at once and
  compare every result with NumPy.  The worker shortens Python's thread switch interval
  to 1 µs (default 5 ms), which makes the races far more frequent than in the report:
  on the code before the fix, ``mixed`` crashed in 10 of 10 runs, ``warp`` (shared) in 5
  of 8, ``opencl`` (shared) failed in 6 of 8 (5 wrong SOR results, 1 crash).  So 4 + 4 + 3
  runs miss the old failures with probability below (3/8)⁴ ≈ 2 % per mode, ~1e-5 for the
  three together; each run takes about a second.
* the two ``*_per_thread`` tests force the exact interleaving that the launch races need
  (one thread stopped between setting its arguments and launching, another launching in
  between), so they fail deterministically if launch state is shared again.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import backend_or_skip

from rdgpu.backends import registry as dispatch

ROOT = Path(__file__).resolve().parents[2]
WORKER = Path(__file__).with_name("thread_worker.py")
ROUNDS = 3


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), os.environ.get("PYTHONPATH", "")])}


@pytest.mark.parametrize("mode,runs", [("mixed", 4), ("warp", 4), ("opencl", 3)])
def test_cold_threads_in_fresh_processes(mode, runs):
    for name in {"mixed": ("warp", "opencl"), "warp": ("warp",), "opencl": ("opencl",)}[mode]:
        backend_or_skip(name)
    for run in range(runs):
        proc = subprocess.run([sys.executable, str(WORKER), mode, str(ROUNDS), "1e-6"],
                              capture_output=True, text=True, env=_env(), timeout=300)
        assert proc.returncode == 0, (
            f"{mode} run {run}: exit status {proc.returncode}\n{proc.stdout[-3000:]}\n"
            f"{proc.stderr[-3000:]}")
        assert proc.stdout.strip().endswith(f"OK {mode}: 4 threads x {ROUNDS} rounds")


def _interleaved(first, second, hold):
    """Run ``first`` in thread "A" and ``second`` in thread "B" such that A stops inside
    ``hold`` (its launch call) until B has run completely."""
    a_waiting, b_done = threading.Event(), threading.Event()
    errors = []

    def held(real):
        def call(*args, **kwargs):
            if threading.current_thread().name == "A" and not b_done.is_set():
                a_waiting.set()
                b_done.wait(30)
            return real(*args, **kwargs)
        return call

    def a():
        try:
            first()
        except BaseException as exc:  # noqa: BLE001
            errors.append(exc)

    def b():
        try:
            assert a_waiting.wait(30)
            second()
        except BaseException as exc:  # noqa: BLE001
            errors.append(exc)
        finally:
            b_done.set()

    hold(held)
    threads = [threading.Thread(target=a, name="A"), threading.Thread(target=b, name="B")]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not errors, errors


def _spmv_case(be):
    M = sp.random(300, 300, density=0.05, random_state=1, format="csr")
    A = be.upload_csr(M, np.float64)
    rng = np.random.default_rng(2)
    xs = [rng.random(300) for _ in range(2)]
    d_x = [be.upload(x) for x in xs]
    d_y = [be.empty((300,), np.float64) for _ in range(2)]
    be.spmv(A, d_x[0], d_y[0])  # a launch recorded in this (the main) thread first
    be.copy(be.upload(np.zeros(300)), d_y[0])
    return M, A, xs, d_x, d_y


def test_warp_recorded_launches_are_per_thread(monkeypatch):
    backend_or_skip("warp")
    import warp as wp

    from rdgpu.backends.warp_backend import WarpBackend

    be = WarpBackend("cpu")
    M, A, xs, d_x, d_y = _spmv_case(be)
    _interleaved(lambda: be.spmv(A, d_x[0], d_y[0]), lambda: be.spmv(A, d_x[1], d_y[1]),
                 lambda held: monkeypatch.setattr(wp.Launch, "launch",
                                                  held(wp.Launch.launch)))
    for x, y in zip(xs, d_y, strict=True):  # A launched with its own arguments
        np.testing.assert_allclose(y.numpy(), M @ x, rtol=1e-12, atol=1e-12)


def test_opencl_kernel_objects_are_per_thread(monkeypatch):
    backend_or_skip("opencl")
    import pyopencl as cl

    from rdgpu.backends.opencl_backend import OpenCLBackend

    be = OpenCLBackend()
    M, A, xs, d_x, d_y = _spmv_case(be)
    _interleaved(lambda: be.spmv(A, d_x[0], d_y[0]), lambda: be.spmv(A, d_x[1], d_y[1]),
                 lambda held: monkeypatch.setattr(cl, "enqueue_nd_range_kernel",
                                                  held(cl.enqueue_nd_range_kernel)))
    for x, y in zip(xs, d_y, strict=True):
        np.testing.assert_allclose(y.numpy(), M @ x, rtol=1e-12, atol=1e-12)


def test_get_backend_constructs_each_backend_once(monkeypatch):
    """Eight threads ask for the same new backend at once: one construction, one instance
    (two WarpBackends initialising Warp side by side was the crash)."""
    made = []
    real = dispatch._construct

    def slow(name, device):
        made.append(name)
        time.sleep(0.05)  # a construction takes a while (Warp's init, an OpenCL build)
        return real(name, device)

    monkeypatch.setattr(dispatch, "_construct", slow)
    monkeypatch.setattr(dispatch, "_instances", {})
    start = threading.Barrier(8)
    got = []

    def ask():
        start.wait()
        got.append(dispatch.get_backend("numpy"))

    threads = [threading.Thread(target=ask) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert made == ["numpy"]
    assert len(got) == 8 and all(b is got[0] for b in got)
