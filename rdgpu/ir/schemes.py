"""Time-stepping schemes as data: the registry every stepper of rdgpu reads.

A scheme is what a method name (``options={"method": ...}``, ``--method``) stands for:

* `ExplicitScheme` — an explicit Runge-Kutta method as its Butcher tableau ``(a, b,
  c)``: ``k_i = f(x + h Σ_j a_ij k_j, t + c_i h)``, ``x' = x + h Σ_i b_i k_i``.  The model
  layer (`rdgpu.integrators.ModelStepper`) steps any tableau; a scheme that also
  gives ``shu_osher`` stages is stepped in that form instead (each stage one fused pass
  ``a·x + b·(y + h f(y, t + c h))`` after a first Euler stage), which is how Euler, Heun
  and SSP-RK3 have always run (their results stay bit for bit).
* `ImexScheme` — an implicit-explicit scheme: each species' own linear spatial
  terms implicit, the rest explicit (`rdgpu.integrators.stepper`).  ``steps=1``: the
  θ-scheme ``P (x' − x) = h f(x)`` (``θ = 1`` backward Euler, ``½`` Crank-Nicolson);
  ``steps=2``: the semi-implicit BDF2 (SBDF2), whose first step is the ``θ = 1`` one.
* `MultistepScheme` — an explicit Adams-Bashforth scheme ``x' = x + h Σ_j β_j f(x₋ⱼ)``
  (``"ab2"``, VisualPDE's): one fused pass reads the fields and the previous level (kept
  by the stepper, as SBDF2's) and evaluates ``f`` at both; its first step is Euler's.
* `ExponentialScheme` — exponential time differencing: each species' own linear spatial
  terms ``α Δs + β Δ²s`` integrated exactly in transform space, the rest ``N``
  explicitly (`rdgpu.integrators.exponential`: ETDRK4 of Cox & Matthews 2002 with the
  coefficients of Kassam & Trefethen 2005).  ``implicit`` is True for it as for the IMEX
  schemes: the linear part sets no stability limit (``inf``), its coefficients must be
  constants and the stencil compact; it solves no system, so ``tol`` does not apply.

Adding a scheme is one entry here (or `register_scheme` from a user's script); the
method lists of the CLI help, the error messages and the docs come from `SCHEMES`.
This module is pure data (no rdgpu imports): the model layer, the functional API's
``diffusion_step``, the py-pde steppers and `rdgpu.integrators` all read it.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

__all__ = ["EULER", "SCHEMES", "ExplicitScheme", "ExponentialScheme", "ImexScheme",
           "MultistepScheme", "Scheme", "get_scheme", "method_names", "register_scheme"]


@dataclass(frozen=True)
class ExplicitScheme:
    """An explicit Runge-Kutta scheme (module doc).  ``a``: the strictly lower triangle of
    the Butcher matrix, row ``i`` with ``i`` entries (row 0 empty); ``order``: its order of
    accuracy; ``real_stability``: the length of its stability interval on the negative
    real axis (Euler 2); ``shu_osher``: ``None``, or the stages after the first Euler stage
    as ``(a, b, c)``, each ``y ← a·x + b·(y + h f(y, t + c h))``; ``noise``: how it steps
    stochastic equations (`rdgpu.integrators.noise`: ``"euler-maruyama"``,
    ``"milstein"``), None: it does not."""

    name: str
    order: int
    a: tuple[tuple[float, ...], ...]
    b: tuple[float, ...]
    c: tuple[float, ...]
    title: str
    real_stability: float
    aliases: tuple[str, ...] = ()
    shu_osher: tuple[tuple[float, float, float], ...] | None = None
    noise: str | None = None

    implicit = False

    def __post_init__(self) -> None:
        n = len(self.b)
        if len(self.c) != n or len(self.a) != n or \
                any(len(row) != i for i, row in enumerate(self.a)):
            raise ValueError(f"scheme {self.name!r}: a Butcher tableau of {n} stages needs "
                             f"{n} weights b, {n} nodes c and a strictly lower-triangular a "
                             "(row i with i entries)")

    @property
    def stages(self) -> int:
        return len(self.b)


@dataclass(frozen=True)
class ImexScheme:
    """An implicit-explicit scheme (module doc): ``theta`` of its one-step form (for
    ``steps=2``, the start step's), ``steps`` the time levels it reads."""

    name: str
    order: int
    theta: float
    steps: int
    title: str
    aliases: tuple[str, ...] = ()

    implicit = True

    @property
    def noise(self) -> str | None:
        """The stochastic step form: a one-step scheme's explicit pass is an Euler step,
        so noise enters it as Euler–Maruyama's increment (semi-implicit Euler–Maruyama);
        SBDF2 takes none."""
        return "euler-maruyama" if self.steps == 1 else None

    def __post_init__(self) -> None:
        if self.steps not in (1, 2) or not 0.0 <= self.theta <= 1.0:
            raise ValueError(f"scheme {self.name!r}: an IMEX scheme has steps 1 (the "
                             "θ-scheme) or 2 (SBDF2) and 0 <= theta <= 1, got steps="
                             f"{self.steps!r}, theta={self.theta!r}")


@dataclass(frozen=True)
class ExponentialScheme:
    """An exponential integrator (module doc): the linear part exact, ``stages``
    evaluations of the rest ``N`` per step.  ``implicit`` (True): the linear part is not
    stepped explicitly, so it sets no stability limit and needs constant coefficients
    and the compact stencil; ``solves`` (False): no system is solved, ``tol`` does not
    apply."""

    name: str
    order: int
    stages: int
    title: str
    aliases: tuple[str, ...] = ()

    implicit = True
    solves = False


@dataclass(frozen=True)
class MultistepScheme:
    """An explicit linear multistep scheme of the Adams-Bashforth family: ``x' = x + h
    Σ_j beta_j f(x₋ⱼ, t − j h)`` over the ``steps`` levels ``x₀ = x, x₋₁, …`` (``beta[0]``
    weighs the newest); the first steps, before the history exists, are forward Euler.
    ``real_stability``: the length of its stability interval on the negative real axis
    (Adams-Bashforth 2: 1, half of Euler's)."""

    name: str
    order: int
    beta: tuple[float, ...]
    title: str
    real_stability: float
    aliases: tuple[str, ...] = ()

    implicit = False

    def __post_init__(self) -> None:
        if len(self.beta) != 2 or abs(sum(self.beta) - 1.0) > 1e-14:
            raise ValueError(f"scheme {self.name!r}: a multistep scheme has two weights "
                             f"beta summing to 1 (a consistent two-level scheme), got "
                             f"{self.beta!r}")

    @property
    def steps(self) -> int:
        return len(self.beta)


Scheme = ExplicitScheme | ImexScheme | ExponentialScheme | MultistepScheme

#: every method by its canonical name, in the order the help lists them
SCHEMES: dict[str, Scheme] = {}
_ALIASES: dict[str, str] = {}


def register_scheme(scheme: Scheme, *, replace: bool = False) -> Scheme:
    """Add ``scheme`` to `SCHEMES` (its name and aliases become method names of every
    model).  A name already taken is refused unless ``replace``."""
    if not isinstance(scheme, (ExplicitScheme, ImexScheme, ExponentialScheme,
                               MultistepScheme)):
        raise TypeError(f"a scheme is an ExplicitScheme, an ImexScheme, an "
                        f"ExponentialScheme or a MultistepScheme, got "
                        f"{type(scheme).__name__}")
    names = (scheme.name, *scheme.aliases)
    bad = [n for n in names if not isinstance(n, str) or not n or n != n.lower()]
    if bad:
        raise ValueError(f"scheme names and aliases are non-empty lower-case strings (method "
                         f"names match in any case), got {bad}")
    taken = sorted(n for n in names if n in SCHEMES or n in _ALIASES)
    if taken and not replace:
        raise ValueError(f"method name(s) {taken} are taken; pass replace=True to replace "
                         "a scheme")
    SCHEMES[scheme.name] = scheme
    for alias in scheme.aliases:
        _ALIASES[alias] = scheme.name
    return scheme


def get_scheme(name: str, allowed: tuple[str, ...] | None = None) -> Scheme:
    """The scheme of method ``name`` (a canonical name or an alias, any case); ``allowed``:
    the canonical names accepted (default: every registered one)."""
    key = str(name).lower()
    key = key if key in SCHEMES else _ALIASES.get(key, key)
    names = method_names() if allowed is None else allowed
    if key not in SCHEMES or key not in names:
        raise ValueError(f"unknown method {name!r}; allowed: {', '.join(names)}")
    return SCHEMES[key]


def method_names(implicit: bool | None = None) -> tuple[str, ...]:
    """The canonical method names, in registry order (``implicit``: only those that solve
    implicitly, or only the explicit ones)."""
    return tuple(n for n, s in SCHEMES.items() if implicit is None or s.implicit == implicit)


def _q(*xs: int | str) -> tuple[float, ...]:
    """Exact rationals, written as text (``"1/6"``), as floats."""
    return tuple(float(Fraction(x)) for x in xs)


#: forward Euler: the default method, and the explicit pass of every IMEX step
EULER = register_scheme(ExplicitScheme(
    "euler", 1, a=((),), b=(1.0,), c=(0.0,), title="forward Euler",
    real_stability=2.0, aliases=("explicit", "forward-euler", "euler-maruyama"), shu_osher=(),
    noise="euler-maruyama"))
register_scheme(ExplicitScheme(
    "heun", 2, a=((), (1.0,)), b=(0.5, 0.5), c=(0.0, 1.0), title="Heun (SSP-RK2)",
    real_stability=2.0, aliases=("rk2",), shu_osher=((0.5, 0.5, 1.0),)))
register_scheme(ExplicitScheme(
    "midpoint", 2, a=((), (0.5,)), b=(0.0, 1.0), c=(0.0, 0.5),
    title="explicit midpoint (VisualPDE's RK2)", real_stability=2.0))
register_scheme(ExplicitScheme(
    "rk3", 3, a=((), (1.0,), (0.25, 0.25)), b=_q("1/6", "1/6", "2/3"), c=(0.0, 1.0, 0.5),
    title="Shu-Osher SSP-RK3", real_stability=2.5127453266183286, aliases=("ssprk3",),
    shu_osher=((0.75, 0.25, 1.0), (1.0 / 3.0, 2.0 / 3.0, 0.5))))
register_scheme(ExplicitScheme(
    "rk4", 4, a=((), (0.5,), (0.0, 0.5), (0.0, 0.0, 1.0)), b=_q("1/6", "1/3", "1/3", "1/6"),
    c=(0.0, 0.5, 0.5, 1.0), title="classic Runge-Kutta", real_stability=2.785293563405282))
register_scheme(MultistepScheme(
    "ab2", 2, beta=(1.5, -0.5), title="Adams-Bashforth 2 (VisualPDE's)", real_stability=1.0,
    aliases=("adams-bashforth",)))
register_scheme(ExplicitScheme(
    "milstein", 1, a=((),), b=(1.0,), c=(0.0,),
    title="Milstein (stochastic equations; forward Euler without noise)",
    real_stability=2.0, shu_osher=(), noise="milstein"))
register_scheme(ImexScheme(
    "imex", 1, theta=1.0, steps=1, title="IMEX backward Euler", aliases=("imex-be",)))
register_scheme(ImexScheme(
    "imex-cn", 1, theta=0.5, steps=1, title="IMEX Crank-Nicolson diffusion"))
register_scheme(ImexScheme(
    "bdf2", 2, theta=1.0, steps=2, title="semi-implicit BDF2 (SBDF2)", aliases=("sbdf2",)))
register_scheme(ExponentialScheme(
    "etdrk4", 4, stages=4, title="exponential time differencing RK4 (Cox-Matthews)",
    aliases=("etd-rk4",)))
