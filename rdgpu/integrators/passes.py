"""One fused pass of a `rdgpu.ir.program.Program` on a
`rdgpu.backends.target.Target`: how the steppers (and the model layer's device
right-hand sides) run what they compiled from a model's equations.

A ``Program`` says what one pass over the domain computes (its inputs, parameters and one
expression per output); a ``Target`` binds a domain to a backend and dtype; `launch`
runs one pass through the backend's interface (``Backend.fused_pass``), never by the
backend's name.  Where the rest of the compiler lives:

* `rdgpu.ir.program` — ``Program``, ``Output``, ``PerMember``, literals, the kernel
  signature;
* `rdgpu.ir.stencils` — the one stencil table per domain kind and the stencil walk;
* `rdgpu.ir.reference` — the NumPy semantics (`rdgpu.ir.reference.run_numpy`);
* `rdgpu.backends.warp_codegen`, `rdgpu.backends.opencl_codegen` — the printers
  (one per target) and their passes; the NumPy backend runs the semantics in place.

Values are emitted fully parenthesised in the tree's operation order with ``FP_CONTRACT
OFF`` and literals exact in the dtype, so the backends agree with the NumPy reference bit
for bit where only ``+ − × ÷`` are used, and to a few ulps where a function (``exp``,
``pow``...) is.  Every written value is clamped (``bounds``) then flushed of subnormals.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

from rdgpu.backends.base import DeviceArray
from rdgpu.backends.target import Target
from rdgpu.ir.program import PerMember, Program

__all__ = ["bind", "launch"]


def launch(program: Program, target: Target, inputs: Sequence[DeviceArray],
           outputs: Sequence[DeviceArray], params: Mapping[str, Any],
           scalars: Mapping[str, float], time: float = 0.0) -> None:
    """One pass of ``program`` on ``target``: ``inputs``/``outputs`` in the program's
    order, each of ``target.field_shape``; ``params`` maps each parameter to a number, a
    DeviceArray of ``target.field_shape`` (a field) or a `PerMember`; ``scalars``
    the builtins (``_h``...).  The target's backend compiles the pass
    (``Backend.fused_pass``; a backend that cannot says so)."""
    compiled, fields, member = _compiled(program, target, inputs, outputs, params)
    compiled.launch(target, inputs, outputs, params, fields, member, scalars, time)


def bind(program: Program, target: Target, inputs: Sequence[DeviceArray],
         outputs: Sequence[DeviceArray], params: Mapping[str, Any],
         scalars: Mapping[str, float]) -> Callable[[float], None]:
    """`launch` with everything but the time fixed: ``run(time)`` is one pass, bit for
    bit `launch`'s (``FusedPass.bind``: a backend may set its kernel's arguments once,
    which makes short passes cheaper).  Keep the arrays and ``params`` unchanged while
    holding ``run``, and call it from one thread at a time."""
    compiled, fields, member = _compiled(program, target, inputs, outputs, params)
    return compiled.bind(target, list(inputs), list(outputs), dict(params), fields, member,
                         dict(scalars))


def _compiled(program: Program, target: Target, inputs: Sequence[DeviceArray],
              outputs: Sequence[DeviceArray], params: Mapping[str, Any]):
    """The backend's compiled pass, the parameters given as fields and per member."""
    if len(inputs) != len(program.inputs) or len(outputs) != len(program.outputs):
        raise ValueError("inputs/outputs do not match the program")
    refs = program.refs("param")
    fields = frozenset(p for p in refs if isinstance(params[p], DeviceArray))
    member = frozenset(p for p in refs if isinstance(params[p], PerMember))
    spread = sorted(program.neighbour_params() & fields)
    if spread:
        raise ValueError(f"the parameter field(s) {spread} are read at neighbours inside a "
                         "Laplacian or a divergence of an expression: store the expression "
                         "first (a pre-pass, rdgpu.ir.lowering)")
    return target.backend.fused_pass(program, target, fields, member), fields, member
