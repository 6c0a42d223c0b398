"""Why a run diverged, when the cause is in the equations rather than the time step.

`cause` evaluates a model's right-hand sides on the last good state in float64 and
looks for where a NaN or an infinity first appears: the innermost operation whose operands
are finite and whose result is not (a division by zero, ``log`` of 0 or of a negative
number, ``sqrt`` of a negative number, an overflow), or whose result the run's dtype cannot
hold (float32 past 3.4e38).  A parameter given as an expression of ``t`` is followed into
its expression (``F = 1/t`` at ``t = 0``).  None when every value is finite and fits: then
the divergence grew over the steps (a time step or a reaction too fast), which the caller
reports.  Used by `rdgpu.simulation.Simulation` (issue 19: such runs were reported as
a time-step problem).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from rdgpu.backends.target import Target
from rdgpu.ir import equations as eq
from rdgpu.ir.program import Output, Program, expression_tree
from rdgpu.ir.reference import run_numpy

__all__ = ["cause"]

#: cells examined operation by operation (the first that go bad)
_CELLS = 64


def cause(sim: Any, state: Mapping[str, np.ndarray], step: int,
          first: str | None = None) -> str | None:
    """The cause of a divergence of ``sim`` (a `Simulation`) from
    ``state`` at ``step`` (module doc), or None; ``first``: the species to look at first.
    Never raises: a diagnosis that fails is no diagnosis."""
    try:
        return _cause(sim, state, step, first)
    except Exception:  # noqa: BLE001 - the divergence report must not fail on its cause
        return None


def _cause(sim, state, step, first):
    model = sim.model
    trees = getattr(model, "trees", None)
    if not trees:
        return None
    dtype = np.dtype(sim.dtype)
    stepper = getattr(sim, "stepper", None)
    target = Target(sim.domain, None, np.dtype(np.float64),
                    stencil=getattr(stepper, "stencil", "compact"),
                    members=getattr(sim, "members", None) or 1)
    shape = target.field_shape  # the kernels' shape ((1, n) for a 1-D grid)
    t = step * float(sim.dt)
    env = _environment(sim, state, target, t)
    laps = {**_laplacians(target, env, trees), **_derivatives(target, env, trees)}
    order = sorted(trees, key=lambda s: s != first)
    # the cells where some equation goes bad, then each operation at those cells
    bad = np.zeros(shape, dtype=bool)
    for s in order:
        with np.errstate(all="ignore"):
            v = np.broadcast_to(eq.evaluate(trees[s], env, lap=lambda n, o: laps[(n, o)],
                                            diff=lambda d: laps[d]), shape)
        bad |= ~_fits(v, dtype)
    if not bad.any():
        return None
    cells = np.flatnonzero(bad)[:_CELLS]
    local = {k: _take(v, shape, cells) for k, v in env.items()}
    local_laps = {k: _take(v, shape, cells) for k, v in laps.items()}
    params = {k: v for k, v in sim.params.items() if isinstance(v, str)}
    for s in order:
        found = _first_bad(trees[s], local, local_laps, dtype, params, sim)
        if found:
            advice = "; use float64 or rescale the model" if "cannot hold" in found else ""
            return (f"{found} in the equation of {s!r} (on the last good state, step {step}, "
                    f"t={t:g}){advice}")
    return None


def _environment(sim, state, target, t) -> dict[str, Any]:
    f64 = np.float64
    shape = target.field_shape
    env: dict[str, Any] = {s: np.asarray(a, dtype=f64).reshape(shape)
                           for s, a in state.items()}
    members = getattr(sim, "members", None)
    for k, v in sim.params.items():
        if isinstance(v, str):
            continue  # an expression of t: evaluated below
        a = np.asarray(v, dtype=f64)
        if a.ndim == 0:
            env[k] = a[()]
        elif members and a.size == members:  # one number per member
            env[k] = a.reshape((members,) + (1,) * len(target.shape))
        else:  # a field: one member's, or each member's
            env[k] = a.reshape(target.shape if a.size == np.prod(target.shape) else shape)
    for c in eq.COORDINATES:
        env[c] = target.coordinate(c)
    env.update({k: f64(v) for k, v in target.lengths().items()})
    env["t"] = f64(t)
    for k, v in sim.params.items():
        if isinstance(v, str):
            with np.errstate(all="ignore"):
                env[k] = eq.evaluate(_param_tree(sim, k), env)
    return env


def _param_tree(sim, name: str) -> eq.Node:
    return expression_tree(name, sim.params[name],
                           {k: v for k, v in sim.params.items() if k != name})


def _laplacians(target, env, trees) -> dict[tuple[str, int], np.ndarray]:
    """Every Laplacian the equations take, in float64, by the NumPy reference."""
    wanted = sorted({lp for tree in trees.values() for lp in eq.laplacians(tree)})
    if not wanted:
        return {}
    shape = target.field_shape
    names = tuple(sorted({n for n, _ in wanted}))
    inputs = {n: env[n] for n in names}
    with np.errstate(all="ignore"):
        first = run_numpy(Program(names, tuple(Output(f"_l_{n}", eq.Lap(n)) for n in names)),
                          target, inputs, {}, {}, 0.0)
        out = {(n, 1): first[f"_l_{n}"].reshape(shape) for n in names}
        if any(o == 2 for _, o in wanted):
            aux = tuple(f"_l_{n}" for n in names)
            second = run_numpy(Program(aux, tuple(Output(f"_ll_{n}", eq.Lap(f"_l_{n}"))
                                                  for n in names), frozenset(aux)),
                               target, first, {}, {}, 0.0)
            out.update({(n, 2): second[f"_ll_{n}"].reshape(shape) for n in names})
    return out


def _derivatives(target, env, trees) -> dict[eq.Diff, np.ndarray]:
    """Every first derivative the equations take, in float64, by the NumPy reference."""
    wanted = sorted({d for tree in trees.values() for d in eq.derivatives(tree)},
                    key=lambda d: (d.name, d.axis, d.side, d.optional))
    if not wanted:
        return {}
    names = tuple(sorted({d.name for d in wanted}))
    program = Program(names, tuple(Output(f"_d{i}", d) for i, d in enumerate(wanted)))
    with np.errstate(all="ignore"):
        got = run_numpy(program, target, {n: env[n] for n in names}, {}, {}, 0.0)
    return {d: got[f"_d{i}"].reshape(target.field_shape) for i, d in enumerate(wanted)}


def _take(v: Any, shape: tuple[int, ...], cells: np.ndarray) -> Any:
    if np.ndim(v) == 0:
        return v
    return np.broadcast_to(v, shape).reshape(-1)[cells]


def _fits(v: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """Finite, and within the dtype's range."""
    with np.errstate(invalid="ignore"):
        return np.isfinite(v) & (np.abs(v) <= float(np.finfo(dtype).max))


def _first_bad(tree: eq.Node, env, laps, dtype, params, sim) -> str | None:
    """The innermost, leftmost operation of ``tree`` that goes bad from good operands,
    described; None if there is none."""
    memo: dict[int, Any] = {}
    found: list[str] = []

    def value(n: eq.Node):
        key = id(n)
        if key in memo:
            return memo[key]
        if isinstance(n, eq.Num):
            out = np.float64(n.value)
        elif isinstance(n, eq.Ref):
            out = env[n.name]
            if n.kind == "param" and n.name in params and not found \
                    and not _fits(np.asarray(out), dtype).all():
                inner = _first_bad(_param_tree(sim, n.name), env, laps, dtype, {}, sim)
                text = f"parameter {n.name!r} = {params[n.name]!r}"
                found.append(f"{text}: {inner}, read" if inner else
                             f"{text} is not finite, read")
        elif isinstance(n, eq.Lap):
            out = laps[(n.name, n.order)]
        elif isinstance(n, eq.Diff):
            out = laps[n]
        else:
            kids = [value(k) for k in eq.children(n)]
            with np.errstate(all="ignore"):
                out = _apply(n, kids)
            if not found and all(_fits(np.asarray(k), dtype).all() for k in kids) \
                    and not _fits(np.asarray(out), dtype).all():
                found.append(_describe(n, kids, out, dtype))
        memo[key] = out
        return out

    value(tree)
    return found[0] if found else None


def _apply(n: eq.Node, kids: list) -> Any:
    if isinstance(n, eq.Neg):
        return -kids[0]
    if isinstance(n, eq.Bin):
        a, b = kids
        return {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide}[n.op](a, b)
    fn = {"min": np.minimum, "max": np.maximum, "pow": np.power, "abs": np.absolute}.get(
        n.fn) or getattr(np, n.fn)
    return fn(*kids)


def _describe(n: eq.Node, kids: list, out: Any, dtype: np.dtype) -> str:
    text = eq.to_text(n)
    out = np.asarray(out)
    if isinstance(n, eq.Bin) and n.op == "/" and np.any(np.asarray(kids[1]) == 0):
        return f"a division by zero, {text}"
    if isinstance(n, eq.Call) and n.fn == "log":
        return (f"the log of 0, {text}" if np.any(np.asarray(kids[0]) == 0)
                else f"the log of a negative number, {text}")
    if isinstance(n, eq.Call) and n.fn == "sqrt":
        return f"the sqrt of a negative number, {text}"
    if isinstance(n, eq.Call) and n.fn == "pow" and np.isnan(out).any():
        return f"a negative number to a non-integer power, {text}"
    if np.isnan(out).any():
        return f"{text} is NaN"
    finite = out[np.isfinite(out)]
    if finite.size and dtype != np.float64:
        peak = float(finite[np.argmax(np.abs(finite))])
        return (f"{text} reaching {peak:.4g}, which {dtype.name} cannot hold (the largest is "
                f"{float(np.finfo(dtype).max):.4g})")
    return f"{text} overflows float64"
