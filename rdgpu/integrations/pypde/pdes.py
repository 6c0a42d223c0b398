"""The py-pde PDE classes the rdgpu backend runs, as equations of rdgpu's language
(`rdgpu.integrations.pypde.backend.translate`): a ``pde.PDE``'s own expressions, or the
equations of each built-in class with its constants."""

from __future__ import annotations

from typing import Any

import pde

from rdgpu.integrations.pypde.checks import refuse

__all__ = ["SUPPORTED", "builtin_equations", "expression_equations", "pde_classes"]

#: the classes, in words (messages)
SUPPORTED = ("pde.PDE (ReactionDiffusionPDE too), DiffusionPDE, AllenCahnPDE, "
             "SwiftHohenbergPDE, CahnHilliardPDE, KPZInterfacePDE, KuramotoSivashinskyPDE, "
             "WavePDE, KleinGordonPDE")


def pde_classes() -> tuple[type, ...]:
    """The PDE classes rdgpu runs (a subclass runs as its nearest one of these)."""
    return (pde.PDE, pde.DiffusionPDE, pde.AllenCahnPDE, pde.SwiftHohenbergPDE,
            pde.CahnHilliardPDE, pde.KPZInterfacePDE, pde.KuramotoSivashinskyPDE, pde.WavePDE,
            pde.KleinGordonPDE)


def builtin_equations(pde_obj: Any) -> tuple[dict[str, str], dict[str, float],
                                             dict[str, Any], Any]:
    """``(equations, constants, bc data per species, (name, bc) of the inner Laplacian
    or None)`` of a built-in PDE class."""
    cls = type(pde_obj).__name__
    if isinstance(pde_obj, pde.DiffusionPDE):
        return ({"c": "diffusivity*laplace(c)"},
                {"diffusivity": float(pde_obj.diffusivity)}, {"c": pde_obj.bc}, None)
    if isinstance(pde_obj, pde.AllenCahnPDE):
        return ({"c": "mobility*((interface_width*laplace(c) - c**3) + c)"},
                {"mobility": float(pde_obj.mobility),
                 "interface_width": float(pde_obj.interface_width)}, {"c": pde_obj.bc}, None)
    if isinstance(pde_obj, pde.SwiftHohenbergPDE):
        return ({"c": "((((rate - kc2**2)*c - 2*kc2*laplace(c)) - laplace(laplace(c)))"
                      " + delta*c**2) - c**3"},
                {"rate": float(pde_obj.rate), "kc2": float(pde_obj.kc2),
                 "delta": float(pde_obj.delta)}, {"c": pde_obj.bc}, ("bc_lap", pde_obj.bc_lap))
    if isinstance(pde_obj, pde.KPZInterfacePDE):  # py-pde's gradient_squared is central
        return ({"c": "nu*laplace(c) + lmbda*gradient_squared(c)"},
                {"nu": float(pde_obj.nu), "lmbda": float(pde_obj.lmbda)}, {"c": pde_obj.bc},
                None)
    if isinstance(pde_obj, pde.KuramotoSivashinskyPDE):
        return ({"c": "-nu*laplace(laplace(c)) - laplace(c) - 0.5*gradient_squared(c)"},
                {"nu": float(pde_obj.nu)}, {"c": pde_obj.bc}, ("bc_lap", pde_obj.bc_lap))
    if isinstance(pde_obj, pde.CahnHilliardPDE):  # the outer Laplacian's (μ's) bc: bc_mu
        return ({"c": "laplace(c**3 - c - interface_width*laplace(c))"},
                {"interface_width": float(pde_obj.interface_width)}, {"c": pde_obj.bc_c},
                ("bc_mu", pde_obj.bc_mu))
    if isinstance(pde_obj, (pde.KleinGordonPDE, pde.WavePDE)):
        # u_t = v, v_t = c² Δu (− μ² u): the Laplacian of u only, under pde_obj.bc
        mass = float(getattr(pde_obj, "mass", 0.0))
        v_rate = "speed2*laplace(u)" + (" - mass2*u" if mass != 0 else "")
        consts = {"speed2": float(pde_obj.speed) ** 2}
        if mass != 0:
            consts["mass2"] = mass ** 2
        return {"u": "v", "v": v_rate}, consts, {"u": pde_obj.bc, "v": pde_obj.bc}, None
    if cls in SUPPORTED:  # a user's class that shares a built-in class's name
        raise refuse(f"the PDE class {type(pde_obj).__module__}.{cls}, not py-pde's own "
                     f"pde.{cls} (supported: {SUPPORTED}, and their subclasses)")
    raise refuse(f"the PDE class {cls} (supported: {SUPPORTED})")


def expression_equations(pde_obj: Any) -> tuple[dict[str, str], dict[str, Any],
                                                dict[str, Any]]:
    """``(equations, constants, bc data per species)`` of a ``pde.PDE``."""
    if getattr(pde_obj, "post_step_hook", None) is not None:
        raise refuse("a post_step_hook (it would run on the host every step)")
    bcs = {}
    for s in pde_obj.variables:
        for key in (f"{s}:laplace", "*:laplace", f"{s}:*", "*:*"):
            if key in pde_obj.bcs:
                bcs[s] = pde_obj.bcs[key]
                break
    other = sorted(k for k in pde_obj.bcs if not k.endswith((":laplace", ":*")))
    if other:
        raise refuse(f"boundary conditions for the operators {other} (only laplace has "
                     "boundary conditions here)")
    return dict(pde_obj.rhs), dict(pde_obj.consts), bcs
