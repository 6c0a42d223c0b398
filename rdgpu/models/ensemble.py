"""Ensembles: M members of one model on one domain, advanced in one launch per step.

A member's parameters are given once for the ensemble: a value is

* a number, an expression string or a field spec: the same for every member;
* an array of shape ``(M,)``: one number per member;
* an array of the domain's shape: one field shared by every member;
* an array of shape ``(M, *domain shape)``: one field per member.

(When the domain's shape is itself ``(M,)``, an array of that shape is read as one number
per member.)  `split_members` turns that into one plain parameter dict per member,
`stack_members` the members' resolved dicts back into what an ensemble kernel reads:
numbers the same for all stay numbers, numbers that differ become a
`PerMember` vector, fields are stacked (or shared when every
member has the same one).  Each member runs exactly as it would alone.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from rdgpu.ir.program import PerMember

__all__ = ["member_seeds", "resolve_members", "split_members", "stack_members"]


def member_seeds(seed: Any, members: int) -> list[int]:
    """One seed per member: an int for all, or a sequence of ``members`` ints."""
    if isinstance(seed, (Sequence, np.ndarray)) and not isinstance(seed, str):
        seeds = list(np.asarray(seed).ravel())
        if len(seeds) != members:
            raise ValueError(f"seed: {len(seeds)} seeds given for {members} members; give "
                             "one int for all or one per member")
        return [int(s) for s in seeds]
    return [int(seed)] * members


def split_members(params: Mapping[str, Any], members: int,
                  shape: tuple[int, ...]) -> list[dict[str, Any]]:
    """One parameter dict per member (see the module doc for the accepted values)."""
    out: list[dict[str, Any]] = [{} for _ in range(members)]
    for name, value in params.items():
        if isinstance(value, PerMember):
            value = np.asarray(value.values)
        if isinstance(value, (list, tuple)):
            value = np.asarray(value)
        if isinstance(value, np.ndarray) and value.ndim > 0:
            if value.shape == (members,):
                for m in range(members):
                    out[m][name] = value[m].item()
                continue
            if value.shape == tuple(shape):
                for m in range(members):
                    out[m][name] = value
                continue
            if value.shape == (members, *shape):
                for m in range(members):
                    out[m][name] = value[m]
                continue
            raise ValueError(
                f"parameter {name!r} has shape {value.shape}; for an ensemble of {members} "
                f"members on a domain of shape {tuple(shape)} give a number, ({members},) "
                f"(one number per member), {tuple(shape)} (one field for all) or "
                f"{(members, *shape)} (one field per member)")
        for m in range(members):
            out[m][name] = value
    return out


def stack_members(resolved: Sequence[Mapping[str, Any]],
                  shape: tuple[int, ...]) -> dict[str, Any]:
    """The ensemble's parameters from each member's resolved ones (numbers, fields of
    ``shape``, or ``t``-expression strings, as ``resolve_params`` gives them)."""
    out: dict[str, Any] = {}
    for name in resolved[0]:
        values = [r[name] for r in resolved]
        if all(isinstance(v, str) for v in values):
            if len(set(values)) > 1:
                raise ValueError(f"parameter {name!r}: every member must have the same "
                                 f"time-dependent expression, got {sorted(set(values))}")
            out[name] = values[0]
        elif any(isinstance(v, str) for v in values):
            raise ValueError(f"parameter {name!r}: a time-dependent expression for some "
                             "members and not others")
        elif all(np.ndim(v) == 0 for v in values):
            numbers = np.asarray(values, dtype=np.float64)
            out[name] = (float(numbers[0]) if (numbers == numbers[0]).all()
                         else PerMember(numbers))
        elif all(v is values[0] for v in values):
            out[name] = values[0]  # one field shared by every member
        else:
            out[name] = np.stack([np.broadcast_to(np.asarray(v, np.float64), shape)
                                  for v in values])
    return out


def resolve_members(resolve, params: Mapping[str, Any], members: int,
                    shape: tuple[int, ...], seed: Any) -> list[dict[str, Any]]:
    """``resolve(member params, seed)`` for every member, called once per distinct
    (parameters, seed): members with equal numbers share one resolved dict, so their
    fields are shared, not copied."""
    seeds = member_seeds(seed, members)
    done: dict[tuple, dict[str, Any]] = {}
    out = []
    for m, given in enumerate(split_members(params, members, shape)):
        drawn = any(isinstance(v, Mapping) for v in given.values())  # specs use the seed
        key = (seeds[m] if drawn else None,) + tuple(
            (k, v if np.ndim(v) == 0 and not isinstance(v, Mapping) else id(v))
            for k, v in sorted(given.items()))
        if key not in done:
            done[key] = resolve(given, seeds[m])
        out.append(done[key])
    return out
