"""VisualPDE's expressions in rdgpu's equation language (`rdgpu.integrations.visualpde`).

Names: species and parameters stay, ``L``, ``L_x``, ``dx``... become their numbers, ``x``
and ``y`` are shifted by ``minX``/``minY``, ``u_x``/``u_xf``/``u_xb`` are the central,
forward and backward differences, ``ind(...)`` is dropped (rdgpu's comparisons are 1 or 0).

VisualPDE's own functions are written out in rdgpu's language before the names are read:

* ``H(a)``, the Heaviside function smoothed over ``[−1, 1]`` (GLSL's ``smoothstep(−1, 1,
  a)``): ``s²(3 − 2s)`` with ``s = min(max((a + 1)/2, 0), 1)``;
* ``Bump(X, Y, R)`` (``Bump(X, R)`` in 1-D), the bump of unit maximum and radius ``R`` at
  ``(X, Y)``: ``exp(1 − 1/q)`` with ``q = 1 − r²/R²`` for ``r < R``, and 0 outside (``q``
  held at 1e-30 there, so the exponential underflows to exactly 0, never a NaN);
* ``Gauss(X, Y, s)``, ``Gauss(X, Y, s_x, s_y)``, ``Gauss(X, Y, s_x, s_y, ρ)``, the
  normalised bivariate Gaussian density;
* logic inside comparisons: ``a && b`` is ``a*b``, ``a || b`` is ``max(a, b)`` (``&&``
  binding tighter), each comparison being 1 or 0.

``WhiteNoise`` (and ``WhiteNoise_1`` to ``_4``) stays a name; `noise_terms` turns the
reactions' white noise into rdgpu's ``noise=`` (module doc of `noise_terms`).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from rdgpu.ir import equations as eq
from rdgpu.ir.derivative import derivative

__all__ = ["FUNCTIONS", "NOISE", "Words", "affine_in", "noise_terms"]

#: the functions rdgpu's language has (VisualPDE's spelling is the same)
FUNCTIONS = {"exp", "log", "sqrt", "sin", "cos", "tan", "tanh", "sinh", "cosh", "floor",
             "abs", "min", "max"}
#: VisualPDE's white noise names: N(0, 1) / √(dt·dxᴺ) per cell and step
NOISE = ("WhiteNoise", "WhiteNoise_1", "WhiteNoise_2", "WhiteNoise_3", "WhiteNoise_4")
#: a name, not the exponent of a number (``1e-3``)
_NAME = re.compile(r"(?<![0-9.A-Za-z_])[A-Za-z_][A-Za-z0-9_]*")
_CALL = re.compile(r"(?<![0-9.A-Za-z_])(H|Bump|Gauss)\s*\(")


class Words:
    """VisualPDE's names in an expression made rdgpu's (module doc); ``refuse(message)``
    makes the error to raise."""

    def __init__(self, species, params, constants, offsets, dim,
                 refuse: Callable[[str], Exception], renames: Mapping[str, str] | None = None):
        self.species, self.params, self.constants = species, params, constants
        self.offsets, self.dim, self.refuse = offsets, dim, refuse
        #: VisualPDE's names that run under another (a parameter named ``lambda``)
        self.renames = dict(renames or {})

    def translate(self, text: str, key: str, initial: bool = False) -> str:
        """``text`` (VisualPDE's expression under ``key``) in rdgpu's language;
        ``initial``: ``RAND`` and ``RANDN`` allowed (an initial condition), else the white
        noise names."""
        text = text.strip() or "0"
        if "?" in text:
            raise self.refuse(f"{key} = {text!r}: logic ('?') is not in rdgpu's language")
        source = text
        text = _logic(self._functions(text, key))

        def word(m: re.Match) -> str:
            w = m.group(0)
            if text[m.end():m.end() + 1] == "(":
                if w == "ind":  # an indicator: rdgpu's comparisons are 1 or 0 already
                    return ""
                if w not in FUNCTIONS:
                    raise self.refuse(f"{key} = {source!r}: the function {w!r} (rdgpu has "
                                      f"{', '.join(sorted(FUNCTIONS | {'H', 'Bump', 'Gauss'}))})")
                return w
            return self._name(w, key, source, initial)

        return _NAME.sub(word, text.replace("**", "^")).replace("^", "**")

    def _name(self, w: str, key: str, text: str, initial: bool) -> str:
        if w in self.renames:
            return self.renames[w]
        if w in self.species or w in self.params:
            return w
        if initial and w in ("RAND", "RANDN"):
            return w
        if not initial and w in NOISE:
            return w
        if w in self.constants:
            return repr(self.constants[w])
        if w in ("x", "y"):
            offset = self.offsets["xy".index(w)]
            return w if offset == 0.0 else f"({w} + {offset!r})"
        if w in ("t", "pi"):
            return w
        for s in self.species:
            if w.startswith(s + "_"):
                return self._derivative(s, w[len(s) + 1:], key, text)
        raise self.refuse(f"{key} = {text!r}: the name {w!r} (not a species, a parameter or "
                          "one of x y t pi L L_x L_y L_min dx dy)")

    def _derivative(self, s: str, suffix: str, key: str, text: str) -> str:
        if suffix in ("x", "y", "xf", "yf", "xb", "yb"):  # central, forward, backward
            if suffix[0] == "y" and self.dim == 1:
                raise self.refuse(f"{key} = {text!r}: {s}_{suffix} on a 1-D domain")
            side = {"": "", "f": "_forward", "b": "_backward"}[suffix[1:]]
            return f"d_d{suffix[0]}{side}({s})"
        if suffix == "xx" and self.dim == 1:
            return f"laplace({s})"
        if suffix in ("xx", "yy") and self.dim == 2:
            return f"d2_d{suffix[0]}2({s})"
        raise self.refuse(f"{key} = {text!r}: {s}_{suffix} (rdgpu's language has first "
                          "derivatives, the second ones along an axis and the Laplacian)")

    def _functions(self, text: str, key: str) -> str:
        """``text`` with each call of ``H``, ``Bump`` and ``Gauss`` written out (module
        doc), innermost arguments first."""
        m = _CALL.search(text)
        if m is None:
            return text
        end = _closing(text, m.end() - 1)
        if end is None:
            raise self.refuse(f"{key} = {text!r}: an unclosed parenthesis")
        args = [self._functions(a, key) for a in _split_top(text[m.end():end], ",")]
        body = self._expand(m.group(1), args, key, text)
        return text[:m.start()] + "(" + body + ")" + self._functions(text[end + 1:], key)

    def _expand(self, fn: str, args: list[str], key: str, text: str) -> str:
        a = [f"({x.strip()})" for x in args]
        if fn == "H" and len(a) == 1:
            s = f"min(max(({a[0]} + 1)/2, 0), 1)"
            return f"{s}^2*(3 - 2*{s})"
        if fn == "Bump" and len(a) == 2 and self.dim == 1:
            return f"exp(1 - 1/max(1 - (x - {a[0]})^2/{a[1]}^2, 1e-30))"
        if fn == "Bump" and len(a) == 3 and self.dim == 2:
            r2 = f"((x - {a[0]})^2 + (y - {a[1]})^2)"
            return f"exp(1 - 1/max(1 - {r2}/{a[2]}^2, 1e-30))"
        if fn == "Gauss" and len(a) in (3, 4, 5) and self.dim == 2:
            sx, sy = (a[2], a[2]) if len(a) == 3 else (a[2], a[3])
            rho = a[4] if len(a) == 5 else "0"
            u, v = f"(x - {a[0]})/{sx}", f"(y - {a[1]})/{sy}"
            q = f"(({u})^2 - 2*{rho}*({u})*({v}) + ({v})^2)/(1 - {rho}^2)"
            return f"exp(-{q}/2)/(2*pi*{sx}*{sy}*sqrt(1 - {rho}^2))"
        forms = {"H": "H(a)", "Bump": "Bump(X, R) in 1-D, Bump(X, Y, R) in 2-D",
                 "Gauss": "Gauss(X, Y, s[, s_y[, rho]]) in 2-D"}[fn]
        raise self.refuse(f"{key} = {text!r}: {fn} with {len(args)} argument(s) on a "
                          f"{self.dim}-D domain (translated: {forms})")


def _closing(text: str, open_at: int) -> int | None:
    """The index of the parenthesis closing the one at ``open_at``, or None."""
    depth = 0
    for i in range(open_at, len(text)):
        depth += {"(": 1, ")": -1}.get(text[i], 0)
        if depth == 0:
            return i
    return None


def _split_top(text: str, sep: str) -> list[str]:
    """``text`` split at each ``sep`` outside parentheses."""
    parts, depth, start, i = [], 0, 0, 0
    while i < len(text):
        c = text[i]
        depth += {"(": 1, ")": -1}.get(c, 0)
        if depth == 0 and text.startswith(sep, i):
            parts.append(text[start:i])
            i += len(sep)
            start = i
            continue
        i += 1
    parts.append(text[start:])
    return parts


def _logic(text: str) -> str:
    """``&&`` as a product and ``||`` as a maximum of comparisons (module doc), inside
    every pair of parentheses too."""
    if "&&" not in text and "||" not in text:
        return text
    out, i = [], 0
    while i < len(text):
        if text[i] == "(":
            end = _closing(text, i)
            if end is None:
                return text  # the parser says what is wrong
            out.append("(" + _logic(text[i + 1:end]) + ")")
            i = end + 1
        else:
            out.append(text[i])
            i += 1
    flat = "".join(out)
    ors = _split_top(flat, "||")
    if len(ors) > 1:
        joined = f"({_logic(ors[0])})"
        for part in ors[1:]:
            joined = f"max({joined}, ({_logic(part)}))"
        return joined
    ands = _split_top(flat, "&&")
    return "*".join(f"({a.strip()})" for a in ands) if len(ands) > 1 else flat


def noise_terms(equations: Mapping[str, str], species: Sequence[str], params: Sequence[str],
                refuse: Callable[[str], Exception]) -> tuple[dict[str, str], dict[str, str]]:
    """``(equations without white noise, noise=)``: where species ``s``'s right-hand side
    is ``f + Σ_k c_k·WhiteNoise_k`` (linear in each, checked; the names independent
    normals divided by ``√(dt·dxᴺ)``), Euler's step ``s + dt·f + Σ c_k √(dt/dxᴺ) ξ_k`` is
    rdgpu's Euler–Maruyama step with the variance ``V = Σ c_k²`` (`rdgpu.integrators.
    noise`: ``√(dt·V/w) ξ``, ``w = dxᴺ``).  A name used by two species (correlated noise)
    is refused."""
    names = [*params, *NOISE]
    out, noise, owner = dict(equations), {}, {}
    for s, text in equations.items():
        tree = eq.parse(text, species=list(species), params=names, what=f"the equation of {s!r}")
        used = sorted(eq.names(tree, "param") & set(NOISE))
        if not used:
            continue
        for w in used:
            if w in owner:
                raise refuse(f"{w} in the equations of {owner[w]!r} and {s!r}: one noise "
                             "shared by two species (rdgpu draws each species' own)")
            owner[w] = s
        zero = _at(tree, used, {w: 0.0 for w in used})
        variance = []
        for w in used:
            if not affine_in(tree, w):
                raise refuse(f"the equation of {s!r} is not linear in {w}")
            variance.append(f"({eq.to_text(_coefficient(tree, w))})**2")
        out[s] = eq.to_text(zero)
        noise[s] = " + ".join(variance)
    return out, noise


def _coefficient(tree: eq.Node, w: str) -> eq.Node:
    """``∂tree/∂w`` of a tree affine in parameter ``w`` (`rdgpu.ir.derivative`; its
    spatial operators, which do not hold ``w``, stand aside as names meanwhile)."""
    ops: dict[str, eq.Node] = {}

    def aside(n: eq.Node) -> eq.Node | None:
        if isinstance(n, (eq.Lap, eq.Diff, eq.DivGrad, eq.LapOf)):
            ops.setdefault(f"op#{len(ops)}", n)  # never a user's name
            return eq.Ref("param", next(k for k, v in ops.items() if v == n))
        if isinstance(n, eq.Ref) and n.kind == "param" and n.name == w:
            return eq.Ref("species", w)
        return None

    c = derivative(eq.substitute(tree, aside), w)
    return eq.substitute(c, lambda n: ops.get(n.name) if isinstance(n, eq.Ref)
                         and n.kind == "param" else None)


def _at(tree: eq.Node, names: Sequence[str], values: Mapping[str, float]) -> eq.Node:
    return eq.substitute(tree, lambda n: eq.Num(values[n.name]) if isinstance(n, eq.Ref)
                         and n.kind == "param" and n.name in names else None)


def affine_in(tree: eq.Node, w: str) -> bool:
    """Whether ``tree`` is ``g + c·w`` with ``g``, ``c`` free of the name ``w`` (a species
    or a parameter; checked at random values of every other name, Laplacians and
    derivatives read as free values)."""
    rng = np.random.default_rng(0)
    flat = eq.substitute(tree, lambda n: eq.Ref("param", f"op#{abs(hash(n))}")
                         if isinstance(n, (eq.Lap, eq.Diff, eq.DivGrad, eq.LapOf)) else None)
    refs = {n.name for n in eq.walk(flat) if isinstance(n, eq.Ref)}
    env: dict[str, Any] = {n: rng.uniform(0.5, 1.5, 8) for n in refs}
    values = []
    for v in (0.0, 1.0, 2.0, 3.5):
        env[w] = np.full(8, v)
        with np.errstate(all="ignore"):
            values.append(np.broadcast_to(eq.evaluate(flat, env), (8,)))
    f0, f1, f2, f3 = values
    slope = f1 - f0
    return bool(np.allclose(f2 - f1, slope, rtol=1e-9, atol=1e-12)
                and np.allclose(f3 - f0, 3.5 * slope, rtol=1e-9, atol=1e-12))
