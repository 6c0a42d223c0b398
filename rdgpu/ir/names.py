"""The identifiers of generated kernels (Warp, OpenCL C): unable to collide with one another,
with a template's own names or with a word of the target language.

A user's names (species, parameters) never start with ``_`` (`rdgpu.models.model.
_identifier` refuses them), and a program's other buffers are ``_``-prefixed internal names
(``_lap_u``, ``_base_u``...).  Every identifier the generators build from such a name is
``_{role}_{name}`` (`ident`), the role a lowercase word without ``_`` (``in``, ``out``,
``pf``, ``c``, ``qw``...).  The role ends at the second ``_``, so two different (role, name)
pairs never give the same identifier; the templates' own names (``r``, ``j``, ``nx``,
``flat``, ``real``, ``b_t``, ``len_x``...) do not start with ``_``, or (the Warp constants
``_c0``...) have one ``_`` only; and no word of Python, Warp or OpenCL C starts with ``_`` and
a lowercase letter (OpenCL's reserved words start with ``__``).  Before this, Warp's flat
view of species ``u``, ``in_u_1d``, was the argument of a species ``u_1d`` (issue 19).
"""

from __future__ import annotations

import re

__all__ = ["flat_view", "ident", "split"]

_ROLE = re.compile(r"[a-z][a-z0-9]*\Z")


def ident(role: str, name: str) -> str:
    """The identifier of buffer or value ``name`` in ``role`` (module doc)."""
    if not _ROLE.match(role):
        raise ValueError(f"a role is a lowercase word without '_', got {role!r}")
    if not name:
        raise ValueError("an empty name")
    return f"_{role}_{name}"


def split(identifier: str) -> tuple[str, str]:
    """``(role, name)`` of an identifier made by `ident`."""
    role, sep, name = identifier[1:].partition("_")
    if not identifier.startswith("_") or not sep or not _ROLE.match(role) or not name:
        raise ValueError(f"{identifier!r} is not a generated identifier")
    return role, name


def flat_view(identifier: str) -> str:
    """The identifier of the flat view of buffer argument ``identifier`` (Warp grids):
    role ``v`` + the buffer's role (``_in_u`` → ``_vin_u``)."""
    role, name = split(identifier)
    return ident("v" + role, name)
