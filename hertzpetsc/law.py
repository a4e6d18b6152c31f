"""The interaction law between neighbouring beads: the protocol every law implements (eq. nc, V' of eq. vhertz).

A law is a frozen dataclass with the bond potential V(r), the force V'(r) and the stiffness V''(r) of a bond of
length r (measured from the chain's static equilibrium, so V'(0) = 0), its parameters by name and whatever closed
forms it knows. The lattice model (:class:`hertzpetsc.model.LatticeModel`) holds one law; every solver asks the
model, never the law's class. A new law is one file: a subclass of :class:`InteractionLaw` with a ``name`` (its key
in record files), its parameters as dataclass fields and the three derivatives; nothing else changes.

What the protocol carries (the defaults say what they cost when a law does not provide it):

* ``name`` and :attr:`~InteractionLaw.parameters` (the dataclass fields): :meth:`~InteractionLaw.describe` (plain
  data for record identities and files), :func:`from_description` (the law again, from the registry of laws by
  name), :meth:`~InteractionLaw.with_parameter` (any parameter is a continuation parameter of the wave problems).
* ``degree``: the exponent d of the law's homogeneity, V'(a r) = a^d V'(r) (eq. twfam's scaling; None when the law
  has none). A travelling wave u = a w then solves the rescaled advance-delay equation with the law
  :meth:`~InteractionLaw.rescaled` ``(a)`` and the frequency variable lam = omega^2 a^(1-d) (d = 1 without one).
* :meth:`~InteractionLaw.rescaled`: the law r -> a^(-d) V'(a r): a homogeneous law is its own rescaling, any other
  is wrapped in a :class:`RescaledLaw`; Hertz knows it in closed form (the precompression divided by a).
  :class:`ScaledLaw` is k V of a law (a bond of another contact constant, in a model's bond pattern).
* :meth:`~InteractionLaw.contact`: where V'' may be non-zero (the rest of the bonds carry no force: the solvers skip
  them); ``separation``: the bond length at which contact is lost (Hertz's delta0; None for a law that never lets go).
* ``linear_stiffness``: V''(0), the stiffness of small oscillations about the equilibrium (0 in a sonic vacuum):
  the linear lattice's frequencies follow from it (omega = 2 sqrt(V''(0)/m) sin(q/2) for one mass).
* ``reference_amplitude``: the bond length at which the law's nonlinearity is of order one (Hertz: delta0; Toda:
  1/b): the scale of the amplitude floors and first steps of the families that start from the linear wave.
* ``kernel_form``: the compiled right-hand side that evaluates the law exactly (``"hertz"``), or None (numpy): a
  subclass that redefines a derivative is never evaluated by its parent's kernel.
* :meth:`~InteractionLaw.check_consistency`: V' against a difference quotient of V, and V'' against one of V' (a law
  whose force and potential disagree is a :class:`~hertzpetsc.errors.ParameterError` naming it, raised when a model
  is built with it).
"""
from __future__ import annotations

import dataclasses
import functools
from typing import Optional

import numpy as np
from numpy.typing import ArrayLike

from .errors import ParameterError, check_real

#: the laws by name (:func:`from_description`); a subclass with a ``name`` registers itself when it is defined
LAWS = {}


class InteractionLaw:
    """Base class of the interaction laws (module docstring). Subclasses are frozen dataclasses."""

    #: the law's key in record files (None: not registered, e.g. a wrapper)
    name = None
    #: exponent d of V'(a r) = a^d V'(r) used for the rescaled unknowns of the wave problems (None: no scaling)
    degree = None
    #: the bond length at which contact is lost (None: never)
    separation = None
    #: the compiled right-hand side's form that evaluates this law exactly (None: none, numpy)
    kernel_form = None

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.__dict__.get("name"):
            LAWS[cls.name] = cls

    def V(self, r: ArrayLike) -> np.ndarray:
        """V(r), normalised by V(0) = 0."""
        raise NotImplementedError

    def dV(self, r: ArrayLike) -> np.ndarray:
        """V'(r), the force of a bond of length r."""
        raise NotImplementedError

    def d2V(self, r: ArrayLike) -> np.ndarray:
        """V''(r), the bond's linearised stiffness."""
        raise NotImplementedError

    def contact(self, r: ArrayLike) -> np.ndarray:
        """Boolean mask of the bonds that may carry a force or a stiffness (all of them by default)."""
        return np.ones(np.shape(r), dtype=bool)

    @property
    def linear_stiffness(self) -> float:
        """V''(0)."""
        return float(self.d2V(np.zeros(1))[0])

    @property
    def reference_amplitude(self) -> float:
        """The bond length at which the nonlinearity is of order one (default 1)."""
        return 1.0

    @property
    def taylor(self) -> tuple:
        """(V''(0), V'''(0)/2, V''''(0)/6), the force's Taylor coefficients at the equilibrium (default: central
        differences of V'' of step 1e-3 of the reference amplitude, relative error ~1e-6; laws give them exactly)."""
        e = 1e-3 * self.reference_amplitude
        k2, kp, km = (float(v) for v in self.d2V(np.array([0.0, e, -e])))
        return k2, (kp - km) / (4 * e), (kp - 2 * k2 + km) / (6 * e * e)

    def stokes_coefficient(self, q: ArrayLike) -> np.ndarray:
        """C(q) in omega / omega_lin - 1 = C a^2 + O(a^4) for the monatomic chain (a: first sine coefficient of the
        displacement): C = cos^2(q/2) (k3/K)^2 + (3/2) sin^2(q/2) k4/K from the Taylor coefficients (K, k3, k4)
        (Lindstedt-Poincare at zero mean strain: the cubic term directly, the quadratic one through the second
        harmonic; Hertz's closed form is its case)."""
        K, k3, k4 = self.taylor
        if not K > 0:
            raise ParameterError("law", self.describe(), "the weakly nonlinear coefficient needs V''(0) > 0")
        s2 = np.sin(np.asarray(q, dtype=float) / 2) ** 2
        return (1 - s2) * (k3 / K) ** 2 + 1.5 * s2 * k4 / K

    @property
    def scale_degree(self) -> float:
        """The exponent used by the rescaled wave problems: ``degree`` if the law has one, else 1."""
        return 1.0 if self.degree is None else float(self.degree)

    # --- parameters by name -----------------------------------------------------------------------------------
    @property
    def parameters(self) -> tuple:
        """The names of the law's parameters (its dataclass fields)."""
        return tuple(f.name for f in dataclasses.fields(self)) if dataclasses.is_dataclass(self) else ()

    def parameter(self, name: str) -> float:
        """The value of the parameter ``name`` (ParameterError naming it if the law has none of that name)."""
        self._check_parameter(name)
        return getattr(self, name)

    def with_parameter(self, name: str, value: float) -> InteractionLaw:
        """The same law (the same class) with the parameter ``name`` set to ``value``, validated by the law."""
        self._check_parameter(name, value)
        return dataclasses.replace(self, **{name: value})

    def _check_parameter(self, name, value=None):
        if name not in self.parameters:
            have = ", ".join(self.parameters) or "none"
            raise ParameterError(name, value, f"is not a parameter of the {self.name or type(self).__name__} law "
                                 f"(its parameters: {have})")

    def rescaled(self, a: float) -> InteractionLaw:
        """The law r -> a^(-d) V'(a r) (d = :attr:`scale_degree`): u = a w turns m omega^2 u'' = V'(...) into
        m lam w'' = V'_a(...), lam = omega^2 a^(1-d). A law homogeneous of its ``degree`` is its own rescaling."""
        a = check_scale(a)
        if self.degree is not None:
            return self
        return RescaledLaw(self, a, self.scale_degree)

    def describe(self) -> dict:
        """The law as plain data (record identities): its name and parameters."""
        if self.name is None:
            raise NotImplementedError(f"{type(self).__name__} has no name: give the law class a name")
        return dict(law=self.name, **{k: float(getattr(self, k)) for k in self.parameters})

    def check_consistency(self) -> None:
        """ParameterError naming the law if V' is not the derivative of V, or V'' not that of V' (central
        differences at a few bond lengths on both sides of 0, in units of :attr:`reference_amplitude`). A law
        that the compiled kernel evaluates (``kernel_form``: the package's Hertz code, tested) is not re-checked: its
        models are built at every step of a continuation in the amplitude."""
        if self.kernel_form is not None:
            return
        try:
            hash(self)
        except TypeError:
            return _check(self)
        _check_once(self)


def check_scale(a, name="a"):
    """a must be a finite number > 0 (an amplitude or a scale)."""
    return check_real(name, a, "the scale", 0.0)


# bond lengths of the consistency check, in units of the reference amplitude, and the relative tolerance of a central
# difference of step 1e-4 (truncation ~1e-9 r^2 V'''/V', round-off ~1e-12; a wrong derivative is off by O(1))
CHECK_POINTS = (-0.8, -0.45, -0.15, 0.1, 0.35, 0.7)
CHECK_STEP, CHECK_RTOL = 1e-4, 1e-5


@functools.lru_cache(maxsize=256)
def _check_once(law):
    _check(law)


def _check(law):
    s = law.reference_amplitude
    s = s if 1e-100 < s < 1e100 else 1.0
    r = s * np.array(CHECK_POINTS)
    e = CHECK_STEP * s
    for f, F, names in ((law.V, law.dV, ("force V'", "potential V")),
                        (law.dV, law.d2V, ("stiffness V''", "force V'"))):
        with np.errstate(all="ignore"):        # parameters far out (a diverging iterate): points that overflow
            exact = np.asarray(F(r), float)     # are not judged
            fd = (np.asarray(f(r + e), float) - np.asarray(f(r - e), float)) / (2 * e)
        finite = np.isfinite(exact) & np.isfinite(fd)
        if not finite.any():
            continue
        scale = max(float(np.max(np.abs(exact[finite]))), float(np.max(np.abs(fd[finite]))), 1e-300)
        bad = finite & ~(np.abs(fd - exact) <= CHECK_RTOL * scale)
        if np.any(bad):
            i = int(np.argmax(bad))
            what = law.describe() if law.name is not None else type(law).__name__
            raise ParameterError("law", what, f"its {names[0]} disagrees with the derivative of its {names[1]} at "
                                 f"r = {r[i]:.6g}: {exact[i]:.10g} against the difference quotient {fd[i]:.10g}")


def from_description(description: dict) -> InteractionLaw:
    """The law a :meth:`InteractionLaw.describe` dictionary describes, from the registry by name (a description
    without ``law`` is Hertz's: the files written before laws had names); other keys are ignored."""
    name = description.get("law", "hertz")
    if name not in LAWS:
        raise ParameterError("law", name, f"is not a known law (known: {', '.join(sorted(LAWS))}; a law declared "
                             "outside the package is known once its class is defined)")
    cls = LAWS[name]
    return cls(**{f.name: description[f.name] for f in dataclasses.fields(cls) if f.name in description})


@dataclasses.dataclass(frozen=True)
class RescaledLaw(InteractionLaw):
    """r -> a^(-d) V'(a r) of any law (the default :meth:`InteractionLaw.rescaled`); equal to another of the same
    base, a and d."""

    base: InteractionLaw
    a: float
    d: float

    def __post_init__(self):
        object.__setattr__(self, "a", float(self.a))
        object.__setattr__(self, "d", float(self.d))

    @property
    def degree(self) -> Optional[float]:
        return self.base.degree

    @property
    def separation(self) -> Optional[float]:
        return None if self.base.separation is None else self.base.separation / self.a

    @property
    def reference_amplitude(self) -> float:
        return self.base.reference_amplitude / self.a

    @property
    def parameters(self) -> tuple:
        return ()

    def V(self, r):
        return self.base.V(self.a * np.asarray(r, float)) / self.a ** (self.d + 1)

    def dV(self, r):
        return self.base.dV(self.a * np.asarray(r, float)) / self.a ** self.d

    def d2V(self, r):
        return self.base.d2V(self.a * np.asarray(r, float)) / self.a ** (self.d - 1)

    def contact(self, r):
        return self.base.contact(self.a * np.asarray(r, float))

    def rescaled(self, a):
        return RescaledLaw(self.base, self.a * check_scale(a), self.d)

    def describe(self):
        return dict(self.base.describe(), scale=self.a)

    def check_consistency(self):
        self.base.check_consistency()


@dataclasses.dataclass(frozen=True)
class ScaledLaw(InteractionLaw):
    """k V(r) of a law ``base`` (k > 0): a bond of another contact constant (issue 38 item 3). Two beads whose Hertz
    contact constant is K_c, pressed by the chain's static force F0, are in the chain's units (force scale K L^alpha)
    the Hertz law with precompression (F0 / K_c)^(1/alpha) / L scaled by k = K_c / K. Its parameters are the base's
    and ``k``; the compiled kernel does not evaluate it (numpy)."""

    name = "scaled"
    base: InteractionLaw
    k: float = 1.0

    def __post_init__(self):
        base = self.base
        if isinstance(base, dict):
            base = from_description(base)
        if not isinstance(base, InteractionLaw):
            raise ParameterError("base", base, "must be an InteractionLaw")
        object.__setattr__(self, "base", base)
        object.__setattr__(self, "k", check_real("k", self.k, "the law's scale factor", 0.0))

    @property
    def degree(self) -> Optional[float]:
        return self.base.degree

    @property
    def separation(self) -> Optional[float]:
        return self.base.separation

    @property
    def reference_amplitude(self) -> float:
        return self.base.reference_amplitude

    @property
    def linear_stiffness(self) -> float:
        return self.k * self.base.linear_stiffness

    @property
    def taylor(self) -> tuple:
        return tuple(self.k * t for t in self.base.taylor)

    @property
    def parameters(self) -> tuple:
        return self.base.parameters + ("k",)

    def parameter(self, name: str) -> float:
        return self.k if name == "k" else self.base.parameter(name)

    def with_parameter(self, name: str, value: float) -> InteractionLaw:
        if name == "k":
            return ScaledLaw(self.base, value)
        return ScaledLaw(self.base.with_parameter(name, value), self.k)

    def V(self, r: ArrayLike) -> np.ndarray:
        return self.k * self.base.V(r)

    def dV(self, r: ArrayLike) -> np.ndarray:
        return self.k * self.base.dV(r)

    def d2V(self, r: ArrayLike) -> np.ndarray:
        return self.k * self.base.d2V(r)

    def contact(self, r: ArrayLike) -> np.ndarray:
        return self.base.contact(r)

    def rescaled(self, a: float) -> InteractionLaw:
        return ScaledLaw(self.base.rescaled(a), self.k)

    def describe(self) -> dict:
        return dict(law=self.name, k=self.k, base=self.base.describe())

    def check_consistency(self) -> None:
        self.base.check_consistency()
