"""The contenders: rdgpu's backends (the fused model stepper, the same with temporal
blocking, the hand-written 2-D kernel) as `Contender` objects, the shape the peers
(`rdgpu.bench.peers`) share, and the check every contender passes before it is timed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rdgpu.backends.registry import get_backend
from rdgpu.bench.devices import spec_of
from rdgpu.bench.problem import PARAMS, Runner, dt_for, real_state, reference_steps, stepper
from rdgpu.core.hardware import package_versions
from rdgpu.domains.boundary import parse_bc

__all__ = ["CHECK_STEPS", "Contender", "check", "rdgpu_contenders"]

CHECK_STEPS = 5
CHECK_SHAPE = {2: (64, 64), 3: (32, 32, 32)}
TOLERANCE = {"float32": 2e-5, "float64": 1e-12}  # max |diff| / (1 + max |reference|)


@dataclass
class Contender:
    """A code timed on the problem: ``make(u, v)`` binds it to a state (its compilation
    happens there or in the first step); ``lacks(dims, dtype)`` is None or why it cannot
    run that case."""

    name: str
    family: str  # "rdgpu" or "peer"
    version: str
    make: Callable[[np.ndarray, np.ndarray], Runner]
    lacks: Callable[[int, str], str | None] = field(default=lambda dims, dtype: None)


def check(contender: Contender, dims: int, dtype: str) -> str | None:
    """None when ``contender`` agrees with rdgpu's NumPy reference over `CHECK_STEPS` steps
    on a small real state (to `TOLERANCE`), else what differed."""
    u, v = real_state(CHECK_SHAPE[dims], dtype)
    ru, rv = reference_steps(u, v, CHECK_STEPS)
    try:
        runner = contender.make(u.copy(), v.copy())
        runner.advance(CHECK_STEPS)
        cu, cv = runner.state()
    except Exception as exc:  # noqa: BLE001 - a peer may fail in any way: reported
        return f"failed: {type(exc).__name__}: {exc}"
    worst = 0.0
    for got, ref in ((cu, ru), (cv, rv)):
        if np.shape(got) != ref.shape:
            return f"state of shape {np.shape(got)}, expected {ref.shape}"
        err = float(np.max(np.abs(np.asarray(got, np.float64) - ref)))
        worst = max(worst, err / (1 + float(np.max(np.abs(ref)))))
    if not worst <= TOLERANCE[dtype]:
        return (f"disagrees with the NumPy reference: relative error {worst:.2e} after "
                f"{CHECK_STEPS} steps (allowed {TOLERANCE[dtype]:.0e})")
    return None


def _stepper_runner(backend, block_steps: int | None):
    def make(u, v):
        st = stepper(u.shape, u.dtype, backend, block_steps)
        st.set_state({"u": u, "v": v})

        def advance(n):
            st.advance(n)
            st.backend.synchronize()

        def state():
            s = st.get_state()
            return s["u"], s["v"]

        return Runner(advance, state)

    return make


def _kernel_runner(be):
    bc = parse_bc("periodic")

    def make(u, v):
        bufs = [be.upload(u), be.upload(v), be.empty(u.shape, u.dtype),
                be.empty(u.shape, u.dtype)]

        def advance(n):
            for _ in range(n):
                be.gray_scott(bufs[0], bufs[1], bufs[2], bufs[3], dt=dt_for(2), dx=1.0,
                              dy=1.0, bc=bc, **PARAMS)
                bufs[:] = [bufs[2], bufs[3], bufs[0], bufs[1]]
            be.synchronize()

        return Runner(advance, lambda: (be.download(bufs[0]), be.download(bufs[1])))

    return make


BLOCK_STEPS = 8  # Euler steps per blocked pass


def _no_blocking(dims: int, dtype: str, be) -> str | None:
    try:
        stepper(CHECK_SHAPE[dims], dtype, be, BLOCK_STEPS)
    except ValueError as exc:
        return str(exc).split(";")[0]
    return None


def rdgpu_contenders(backends: list[str]) -> list[Contender]:
    """For each backend spec: its fused stepper, the stepper with temporal blocking
    (`BLOCK_STEPS` steps a pass, where the backend blocks), and the hand-written 2-D
    kernel.  Raises BackendUnavailableError."""
    version = package_versions()["rdgpu"]
    out = []
    for spec in backends:
        be = get_backend(spec_of(spec))
        out.append(Contender(f"rdgpu {spec}", "rdgpu", version, _stepper_runner(be, 1)))
        if spec != "numpy":
            out.append(Contender(f"rdgpu {spec} blocked", "rdgpu", version,
                                 _stepper_runner(be, BLOCK_STEPS),
                                 lambda d, t, be=be: _no_blocking(d, t, be)))
        out.append(Contender(f"rdgpu {spec} kernel", "rdgpu", version, _kernel_runner(be),
                             lambda d, t: None if d == 2 else "2-D only"))
    return out
