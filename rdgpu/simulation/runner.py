"""The time loop of one `Simulation.run <rdgpu.simulation.Simulation.run>` call
(`Runner`): advancing in chunks, device-side snapshot buffers downloaded in batches,
NaN/Inf/blow-up checks (replaying from the last good state to name the first bad step;
freezing diverged ensemble members), checkpoints, and Ctrl-C taken at the end of a chunk.
"""

from __future__ import annotations

import signal
import threading
import time as _time
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.core.errors import SimulationDiverged, SimulationInterrupted
from rdgpu.models import diagnose
from rdgpu.simulation.checkpoints import checkpoint_arrays, describe_domain, write_checkpoint
from rdgpu.simulation.defaults import accepts, default_dt, model_bound
from rdgpu.simulation.result import Result

if TYPE_CHECKING:
    from rdgpu.simulation.driver import Simulation

__all__ = ["Runner", "restore"]

#: the time loop also stops at every multiple of this (progress bar updates)
_CHUNK = 100
#: device memory for snapshot buffers before a batch is downloaded
_SNAPSHOT_BUDGET = 256 * 2**20


def _bad(a: np.ndarray, bound: float) -> tuple[bool, str]:
    """Whether ``a`` has NaN, Inf or values past ``bound``, and what."""
    finite = np.isfinite(a)
    if not finite.all():
        n_nan = int(np.isnan(a).sum())
        n_inf = int(a.size - finite.sum() - n_nan)
        parts = ([f"{n_nan} NaN"] if n_nan else []) + ([f"{n_inf} Inf"] if n_inf else [])
        return True, " and ".join(parts) + " value(s)"
    peak = float(np.abs(a).max()) if a.size else 0.0
    if peak > bound:
        return True, f"max |value| {peak:.3g} past the blow-up bound {bound:g}"
    return False, ""


def restore(stepper: Any, state: Mapping[str, np.ndarray], step: int) -> None:
    """``stepper.set_state(state)`` at ``step`` (its clock too, where it keeps one: the
    time of a time-dependent model, BDF2's previous level)."""
    if accepts(stepper.set_state, "steps"):
        stepper.set_state(state, steps=step)
    else:
        stepper.set_state(state)


class _DeferSigint:
    """While active in the main thread (and SIGINT has Python's default handler), Ctrl-C
    only sets ``requested``; a second Ctrl-C raises ``KeyboardInterrupt`` at once."""

    def __init__(self) -> None:
        self.requested = False
        self.installed = False

    def _handler(self, signum: int, frame: Any) -> None:
        self.requested = True
        signal.signal(signal.SIGINT, signal.default_int_handler)

    def __enter__(self) -> _DeferSigint:
        if threading.current_thread() is threading.main_thread() and \
                signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            try:
                signal.signal(signal.SIGINT, self._handler)
                self.installed = True
            except (ValueError, OSError):  # not the main interpreter, or no signals here
                pass
        return self

    def __exit__(self, *exc: Any) -> None:
        if self.installed and signal.getsignal(signal.SIGINT) == self._handler:
            signal.signal(signal.SIGINT, signal.default_int_handler)


class Runner:
    """One ``Simulation.run`` call: the loop, device snapshot buffers, checks, checkpoints."""

    def __init__(self, sim: Simulation, run: dict, snaps: dict[str, list], snap_steps: list[int],
                 checkpoint: Any, progress: bool) -> None:
        self.sim = sim
        self.be = sim.backend
        self.run = run
        self.snaps = snaps
        self.snap_steps = list(snap_steps)
        self.checkpoint = None if checkpoint is None else Path(checkpoint)
        self.progress = progress
        self.pending: list[tuple[int, dict]] = []  # (step, device buffers) not yet downloaded
        self.free: list[dict] = []
        se = run["snapshot_every"]
        per_snap = max(1, len(sim.species) * int(np.prod(sim.field_shape))
                       * sim.dtype.itemsize)
        expected = (run["target"] - run["start"]) // se + 2 if se else 1
        self.batch = max(1, min(expected, _SNAPSHOT_BUDGET // per_snap))
        self.last_good: tuple[int, dict[str, np.ndarray]] | None = None

    # -- snapshots
    def take_snapshot(self, step: int) -> None:
        if (self.snap_steps and self.snap_steps[-1] == step) or \
                (self.pending and self.pending[-1][0] == step):
            return
        if len(self.pending) >= self.batch:
            self.flush()
        bufs = self.free.pop() if self.free else None
        live = self.sim.stepper.state()
        if bufs is None:
            bufs = {s: self.be.empty_like(live[s]) for s in self.sim.species}
        for s in self.sim.species:
            self.be.copy(live[s], bufs[s])
        self.pending.append((step, bufs))

    def flush(self) -> None:
        for step, bufs in self.pending:
            for s in self.sim.species:
                self.snaps[s].append(bufs[s].numpy().reshape(self.sim.field_shape))
            self.snap_steps.append(step)
            self.free.append(bufs)
        self.pending.clear()

    # -- checks
    def find_bad(self, state: Mapping[str, np.ndarray]) -> tuple[str, str] | None:
        for s in self.sim.species:
            bad, what = _bad(state[s], model_bound(self.sim.model, s))
            if bad:
                return s, what
        return None

    def bad_members(self, state: Mapping[str, np.ndarray]) -> dict[int, tuple[str, str]]:
        """Ensembles: ``{member: (field, what)}`` for the members not yet frozen whose
        state is bad."""
        sim = self.sim
        out: dict[int, tuple[str, str]] = {}
        for s in sim.species:
            a = state[s].reshape(sim.members, -1)
            with np.errstate(invalid="ignore"):
                suspect = ~(np.abs(a) <= model_bound(sim.model, s)).all(axis=1)
            for m in np.flatnonzero(suspect):
                m = int(m)
                if m not in sim.frozen and m not in out:
                    out[m] = (s, _bad(a[m], model_bound(sim.model, s))[1])
        return out

    def freeze(self, step: int, state: dict[str, np.ndarray],
               bad: dict[int, tuple[str, str]]) -> None:
        """Put the diverged members back to their last good state and freeze them there;
        raise `SimulationDiverged` when no member is left running."""
        sim = self.sim
        good_step, good = self.last_good
        for m, (s, what) in sorted(bad.items()):
            for k in state.keys() & good.keys():
                state[k][m] = good[k][m]
            sim.frozen[m] = (f"member {m} diverged between steps {good_step} and {step}: "
                             f"field {s!r} has {what}; frozen at step {good_step}")
            warnings.warn(f"{sim.model.name}: {sim.frozen[m]}", RuntimeWarning, stacklevel=4)
        sim.stepper.set_state(state)
        if len(sim.frozen) == sim.members:
            message = (f"{sim.model.name}: every member of the ensemble diverged by step "
                       f"{step}; each is kept at its last good state (see "
                       "Result.diverged_members)")
            raise SimulationDiverged(message, step=step, field=next(iter(bad.values()))[0],
                                     cause="every member diverged",
                                     result=self.result(state, diverged=message))

    def hold_frozen(self) -> None:
        """Ensembles: write the frozen members' kept state back over what the steps did."""
        sim = self.sim
        if not sim.frozen or self.last_good is None:
            return
        state = sim.host_state(history=True)
        kept = self.last_good[1]
        for m in sim.frozen:
            for k in state.keys() & kept.keys():
                state[k][m] = kept[k][m]
        sim.stepper.set_state(state)

    def diverged(self, step: int, state: dict[str, np.ndarray], species: str, what: str):
        """Find the first bad step by replaying from the last good state, leave the
        simulation there, and raise."""
        sim = self.sim
        if self.last_good is None:  # checks were off: nothing good to go back to
            message = (f"{sim.model.name} diverged by step {step} (t={step * sim.dt:g}): "
                       f"field {species!r} has {what}; no checked state to keep "
                       "(check_every=0)")
            raise SimulationDiverged(message, step=step, field=species, cause="unknown",
                                     result=None)
        good_step, good = self.last_good
        first_bad, bad_field, bad_what = step, species, what
        if step - good_step > 1:
            restore(sim.stepper, good, good_step)
            for k in range(good_step + 1, step + 1):
                sim.stepper.advance(1)
                cur = sim.host_state(history=True)
                found = self.find_bad(cur)
                if found:
                    first_bad, (bad_field, bad_what) = k, found
                    break
                good_step, good = k, cur
        restore(sim.stepper, good, good_step)
        sim.step = good_step
        # keep the good snapshots up to the last good step
        self.flush()
        keep = [i for i, k in enumerate(self.snap_steps) if k <= good_step]
        for s in sim.species:
            self.snaps[s] = [self.snaps[s][i] for i in keep]
        self.snap_steps = [self.snap_steps[i] for i in keep]
        # a division by zero, log(0), an overflow of the dtype... in the equations
        cause = diagnose.cause(sim, good, good_step, bad_field)
        if cause is None and sim.dt > sim.dt_limit:
            cause = (f"dt={sim.dt:g} is past the stability limit {sim.dt_limit:.4g} of "
                     f"{sim.model.name} on this domain (the run had check_stability=False); "
                     f"use dt <= {sim.dt_limit:.4g}")
        elif cause is None and getattr(getattr(sim.stepper, "scheme", None), "implicit", False):
            own = default_dt(sim.model, sim.domain, sim.params, {})
            cause = (f"method {sim.stepper.method!r} steps the diffusion implicitly (stable at "
                     f"any dt) but the reaction terms explicitly, and they are unstable at "
                     f"dt={sim.dt:g}; use a smaller dt (the model's default is {own:.4g})")
        elif cause is None:
            cause = (f"dt={sim.dt:g} is within the diffusion stability limit "
                     f"{sim.dt_limit:.4g}; check the parameters (a stiff or unbounded reaction "
                     "term, or try a smaller dt)")
        message = (f"{sim.model.name} diverged at step {first_bad} (t={first_bad * sim.dt:g}): "
                   f"field {bad_field!r} has {bad_what}; likely cause: {cause}. "
                   f"Kept the last good state, step {good_step}")
        result = self.result(good, diverged=message)
        raise SimulationDiverged(message, step=first_bad, field=bad_field, cause=cause,
                                 result=result)

    # -- checkpoints
    def write_checkpoint(self, state: dict[str, np.ndarray]) -> None:
        self.flush()
        write_checkpoint(self.checkpoint, checkpoint_arrays(self.sim, state, self.run,
                                                            self.snaps, self.snap_steps))

    def result(self, fields: dict[str, np.ndarray], diverged: str | None = None) -> Result:
        sim = self.sim
        snaps = {s: (np.stack(self.snaps[s]) if self.snaps[s]
                     else np.zeros((0, *sim.field_shape), sim.dtype)) for s in sim.species}
        steps = np.asarray(self.snap_steps, dtype=np.int64)
        diverged = diverged or (f"{len(sim.frozen)} of {sim.members} members diverged and "
                                f"were frozen" if sim.frozen else None)
        return Result(
            model=sim.model.name, fields={s: fields[s] for s in sim.species}, snapshots=snaps,
            times=steps * sim.dt, snapshot_steps=steps, step=sim.step, time=sim.time, dt=sim.dt,
            params=dict(sim.params), domain=sim.domain,
            domain_info=describe_domain(sim.domain, sim.domain_source),
            backend=sim.backend.name, device=sim.backend.device, dtype=sim.dtype.name,
            seed=sim.seed, init=sim.init, wall_seconds=_time.perf_counter() - self.t0,
            diverged=diverged, members=sim.members, diverged_members=dict(sim.frozen),
            mask=_mask(sim),
        )

    # -- the loop
    def next_stop(self, step: int) -> int:
        stop = self.run["target"]
        for every in (_CHUNK, self.run["snapshot_every"], self.run["check_every"],
                      self.run["checkpoint_every"]):
            if every:
                stop = min(stop, (step // every + 1) * every)
        return stop

    def check(self, step: int) -> dict[str, np.ndarray]:
        """Download the state at ``step`` and check it; raise SimulationDiverged if bad,
        else it becomes the last good state."""
        if self.last_good is not None and self.last_good[0] == step:
            return self.last_good[1]
        state = self.sim.host_state(history=True)
        if self.sim.members is not None:
            bad = self.bad_members(state)
            if bad:
                self.freeze(step, state, bad)
        else:
            found = self.find_bad(state)
            if found:
                self.diverged(step, state, *found)
        self.last_good = (step, state)
        return state

    def chunk(self, step: int, bar: Any) -> int:
        """Advance to the next stop; snapshot, check and checkpoint there."""
        sim, run = self.sim, self.run
        se, ce, ke = run["snapshot_every"], run["check_every"], run["checkpoint_every"]
        stop = self.next_stop(step)
        sim.stepper.advance(stop - step)
        self.hold_frozen()
        step = sim.step = stop
        if bar is not None:
            bar.update(stop - bar.n - run["start"])
        end = step == run["target"]
        if se and (step % se == 0 or end):
            self.take_snapshot(step)
        checkpoint_now = self.checkpoint is not None and ((ke and step % ke == 0) or end)
        if (ce and (step % ce == 0 or end)) or checkpoint_now:
            state = self.check(step)  # a checkpoint is written only from a checked state
            if checkpoint_now:
                self.write_checkpoint(state)
        return step

    def interrupted(self, step: int, *, exact: bool) -> SimulationInterrupted:
        """The exception for a run stopped at ``step`` (``exact``: by the deferred SIGINT,
        at a chunk boundary; otherwise by a KeyboardInterrupt at an unknown point)."""
        sim = self.sim
        written = None
        if exact:
            state = self.check(step)  # raises SimulationDiverged on a bad state
            if self.checkpoint is not None:
                if not (self.run["checkpoint_every"] and step % self.run["checkpoint_every"]
                        == 0) and step != self.run["target"]:
                    self.write_checkpoint(state)
                written = self.checkpoint
            self.flush()
            result = self.result(state)
            where = f"step {step}"
        elif self.last_good is not None:
            good_step, good = self.last_good
            restore(sim.stepper, good, good_step)
            sim.step = good_step
            self.pending = [(k, b) for k, b in self.pending if k <= good_step]
            self.flush()
            keep = [i for i, k in enumerate(self.snap_steps) if k <= good_step]
            for s in sim.species:
                self.snaps[s] = [self.snaps[s][i] for i in keep]
            self.snap_steps = [self.snap_steps[i] for i in keep]
            result = self.result(good)
            where = f"step {good_step} (the last checked state)"
        else:
            result = None
            where = "an unknown step (no state had been checked: check_every=0)"
        message = f"{sim.model.name} interrupted at {where} of a run to step " \
                  f"{self.run['target']}" + (f"; checkpoint {str(written)!r} is at that step"
                                             if written is not None else "")
        return SimulationInterrupted(message, step=None if result is None else result.step,
                                     result=result, checkpoint=written)

    def go(self) -> Result:
        sim, run = self.sim, self.run
        self.t0 = _time.perf_counter()
        se, ce = run["snapshot_every"], run["check_every"]
        target = run["target"]
        step = sim.step
        if ce or self.checkpoint is not None:
            first = sim.host_state(history=True)
            found = self.find_bad(first)
            if found and sim.members is not None:
                bad = self.bad_members(first)
                if bad:
                    m, (s, what) = min(bad.items())
                    raise ValueError(f"the initial field {s!r} of member {m} has {what}")
            elif found:
                raise ValueError(f"the initial field {found[0]!r} has {found[1]}")
            self.last_good = (step, first)
        if se and step % se == 0 or (se and step == target):
            self.take_snapshot(step)
        bar = None
        if self.progress and target > step:
            from tqdm.auto import tqdm

            bar = tqdm(total=target - run["start"], initial=step - run["start"],
                       desc=sim.model.name, unit="step", delay=1.0, leave=False)
        try:
            with _DeferSigint() as sigint, np.errstate(over="ignore", invalid="ignore"):
                try:
                    while step < target:
                        step = self.chunk(step, bar)
                        if sigint.requested:
                            raise self.interrupted(step, exact=True)
                except SimulationInterrupted:
                    raise
                except KeyboardInterrupt as exc:
                    raise self.interrupted(step, exact=False) from exc
                if sigint.requested:  # Ctrl-C during the last chunk: the run is complete
                    raise self.interrupted(step, exact=True)
        finally:
            if bar is not None:
                bar.close()
        if se and not (self.snap_steps and self.snap_steps[-1] == step) and \
                not (self.pending and self.pending[-1][0] == step):
            self.take_snapshot(step)
        self.flush()
        final = sim.host_state()
        if self.checkpoint is not None and target == run["start"]:
            self.write_checkpoint(self.check(step))
        return self.result(final)


def _mask(sim: Any) -> np.ndarray | None:
    """A masked run's mask as booleans of the domain's field shape, or None."""
    values = getattr(sim.stepper, "mask", None)
    return None if values is None else np.asarray(values, dtype=bool).reshape(sim.shape)
