"""Dissipation in the contacts: bond forces that depend on the overlap and its rate and act only in contact.

A bond n of the chain (eq. nc) joins beads n, n + 1; its length is r = x_{n+1} - x_n, its overlap d = delta0 - r
(the law's precompression delta0 included: the beads touch while d > 0) and the overlap's rate d' = -(x_{n+1}' -
x_n') = -dv. The elastic contact force of the law is P = K d^alpha (eq. vhertz; K = 1 in the dimensionless chain,
alpha the law's exponent) and the bond's tension is f = V'(r) = delta0^alpha - P. The two classical contact dampings
add the compressive force

    Hunt-Crossley:   P_d = K d^alpha (3/2) c d'         (F = K d^(3/2) (1 + (3/2) c d') for alpha = 3/2)
    Kuwabara-Kono:   P_d = eta d^(alpha - 1) d'         (F = K d^(3/2) + eta d^(1/2) d' for alpha = 3/2)

that is the tension f_d = g(d) dv with g >= 0: the bond's power -f_d dv = -g dv^2 <= 0 is dissipated. Both vanish
out of contact (d <= 0). With ``clipped=True`` (the default, the usual choice: *a contact never pulls*) the total
contact force P + P_d is kept >= 0: f_d = min(g dv, P), so while the beads separate fast enough the contact force is 0
instead of an attraction; ``clipped=False`` is the unclipped form of the original papers (Hunt-Crossley's force
pulls when d' < -2 / (3 c), Kuwabara-Kono's at the end of every restitution).

Small dissipation (one impact of relative velocity v, the undamped impact's energy loss): Hunt-Crossley 1 - e = c v
for any alpha (:func:`hunt_crossley_restitution`), Kuwabara-Kono 1 - e = C eta v^((alpha - 1)/(alpha + 1)) (v^(1/5) for
Hertz; :func:`kuwabara_kono_restitution`), e the coefficient of restitution.

:meth:`ContactDissipation.bond_terms` gives the tension f_d and its exact derivatives df_d/dr, df_d/d(dv): the
chain's right-hand side, Jacobian, tangent flow and power balance (:class:`hertzpetsc.chain.Chain`) read them.
Pure numpy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np
from numpy.typing import ArrayLike

from .errors import ParameterError, check_flag, check_real


def contact_exponent(law) -> tuple[float, float]:
    """(alpha, delta0) of a contact law: P = d^alpha with d = delta0 - r (the Hertz law, eq. vhertz); a
    ParameterError for a law without contact (no exponent alpha)."""
    alpha = getattr(law, "alpha", None)
    if alpha is None:
        raise ParameterError("law", type(law).__name__, "contact dissipation needs a contact law P = d^alpha with an "
                             "exponent alpha and a precompression delta0 (the Hertz law)")
    return float(alpha), float(getattr(law, "delta0", 0.0))


class ContactDissipation:
    """The protocol of a contact damping (module docstring): frozen dataclasses with the field ``clipped`` that give
    g(d) and g'(d) (:meth:`power_form`, or :meth:`coefficient` and :meth:`derivative` of their own, evaluated in
    numpy only)."""

    #: the name in records (LatticeModel.describe)
    kind = ""
    clipped = True

    def __post_init__(self):
        object.__setattr__(self, "clipped", check_flag("clipped", self.clipped))

    def power_form(self, alpha: float) -> tuple[tuple[float, float], tuple[float, float]]:
        """((G, e), (G', e')) with g(d) = G d^e and g'(d) = G' d^e' (both dampings are powers of the overlap)."""
        raise NotImplementedError

    def coefficient(self, d: np.ndarray, alpha: float) -> np.ndarray:
        """g(d) >= 0 of f_d = g(d) dv, for d > 0."""
        (g, e), _ = self.power_form(alpha)
        return g * d ** e

    def derivative(self, d: np.ndarray, alpha: float) -> np.ndarray:
        """g'(d), for d > 0."""
        _, (g, e) = self.power_form(alpha)
        return g * d ** e

    def kernel_form(self, law) -> Optional[tuple[tuple[float, float], tuple[float, float]]]:
        """:meth:`power_form` at the law's exponent for the compiled right-hand side (:mod:`hertzpetsc.kernels`),
        which evaluates :meth:`bond_terms` in the same operations; None (numpy) when a subclass redefines g, g' or
        the bond terms."""
        cls = type(self)
        if any(getattr(cls, n) is not getattr(ContactDissipation, n) for n in ("coefficient", "derivative",
                                                                             "bond_terms")):
            return None
        return self.power_form(contact_exponent(law)[0])

    def describe(self) -> dict:
        raise NotImplementedError

    def linear_dashpot(self, law) -> float:
        """The dashpot of a bond linearised at rest, at the overlap delta0 (the precompression): df_d/d(dv) =
        g(delta0) (Hunt-Crossley (3/2) c K delta0^alpha, Kuwabara-Kono eta delta0^(alpha - 1), K = 1; 0 in the
        sonic vacuum); df_d/dr = -g'(delta0) dv vanishes at rest. A small-amplitude motion of a precompressed chain
        sees it as a dashpot eta in every bond (the linear response of a driven chain, its preconditioner)."""
        return float(self.bond_terms(law, np.zeros(1), np.zeros(1))[2][0])

    def bond_terms(self, law, r: ArrayLike, dv: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(f_d, df_d/dr, df_d/d(dv)) of bonds of length r and velocity difference dv (arrays of one shape; dv may
        have a trailing axis of columns only through the caller): 0 out of contact; where clipped f_d = P = d^alpha,
        df_d/dr = -alpha d^(alpha - 1), df_d/d(dv) = 0."""
        alpha, delta0 = contact_exponent(law)
        r = np.asarray(r, float)
        dv = np.asarray(dv, float)
        d = delta0 - r
        touch = d > 0.0
        ds = np.where(touch, d, 1.0)                 # no powers of d <= 0 (0 out of contact)
        g = np.where(touch, self.coefficient(ds, alpha), 0.0)
        f = g * dv
        dfr = np.where(touch, -self.derivative(ds, alpha) * dv, 0.0)
        dfv = g
        if self.clipped:
            P = np.where(touch, ds ** alpha, 0.0)
            pull = touch & (f > P)
            f = np.where(pull, P, f)
            dfr = np.where(pull, -alpha * ds ** (alpha - 1.0), dfr)
            dfv = np.where(pull, 0.0, dfv)
        return f, dfr, dfv


@dataclass(frozen=True)
class HuntCrossley(ContactDissipation):
    """Hunt-Crossley: compressive force K d^alpha (1 + (3/2) c d'), c >= 0 (the damping per unit impact velocity:
    1 - e = c v for small c v)."""

    c: float = 0.0
    clipped: bool = True
    kind = "hunt-crossley"

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "c", check_real("c", self.c, "the Hunt-Crossley damping", 0.0, lo_open=False))

    def power_form(self, alpha):
        return (1.5 * self.c, alpha), (1.5 * self.c * alpha, alpha - 1.0)

    def describe(self):
        return dict(contact=self.kind, contact_c=self.c, contact_clipped=self.clipped)


@dataclass(frozen=True)
class KuwabaraKono(ContactDissipation):
    """Kuwabara-Kono: compressive force K d^alpha + eta d^(alpha - 1) d' (eta d^(1/2) d' for Hertz), eta >= 0.
    Its g'(d) ~ d^(alpha - 2) is unbounded at the onset of contact (integrable: the tangent flow's steps shrink
    there)."""

    eta: float = 0.0
    clipped: bool = True
    kind = "kuwabara-kono"

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "eta", check_real("eta_c", self.eta, "the Kuwabara-Kono damping", 0.0,
                                                   lo_open=False))

    def power_form(self, alpha):
        return (self.eta, alpha - 1.0), (self.eta * (alpha - 1.0), alpha - 2.0)

    def describe(self):
        return dict(contact=self.kind, contact_eta=self.eta, contact_clipped=self.clipped)


KINDS = {"hunt-crossley": HuntCrossley, "kuwabara-kono": KuwabaraKono}


def from_description(description: dict):
    """The contact damping a model's :meth:`~hertzpetsc.model.LatticeModel.describe` dictionary names (its
    ``contact``, ``contact_c`` or ``contact_eta``, ``contact_clipped`` keys), or None when it names none."""
    kind = description.get("contact")
    if kind is None:
        return None
    if kind not in KINDS:
        raise ParameterError("contact", kind, f"must be one of {', '.join(KINDS)}")
    value = description.get("contact_c" if kind == "hunt-crossley" else "contact_eta", 0.0)
    return KINDS[kind](value, bool(description.get("contact_clipped", True)))


def contact_dissipation(kind: str, value: float, clipped: bool = True):
    """The contact damping named ``kind`` ('none', 'hunt-crossley' with c = value, 'kuwabara-kono' with eta = value),
    or None for 'none' (the drivers' -contact, -contact_damping, -contact_clipped)."""
    if kind == "none":
        return None
    if kind not in KINDS:
        raise ParameterError("contact", kind, f"must be one of none, {', '.join(KINDS)}")
    return KINDS[kind](value, clipped)


# --- the small-dissipation laws of one impact ----------------------------------------------------------------------
def hunt_crossley_restitution(c: float, v: float) -> float:
    """1 - e to first order in c v of a Hunt-Crossley impact at relative velocity v: the undamped impact's loss
    Delta E = (2/3)(3/2) c m v^3 (any alpha, the reduced mass m), 1 - e = Delta E / (2 E) = c v."""
    return c * v


def kuwabara_kono_restitution(eta: float, v: float, mass: float = 0.5, alpha: float = 1.5) -> float:
    """1 - e to first order in eta of a Kuwabara-Kono impact at relative velocity v, reduced mass ``mass`` (two unit
    beads: 1/2), K = 1: Delta E = 2 eta v d_max^alpha I, d_max = ((alpha + 1) m v^2 / 2)^(1/(alpha + 1)),
    I = int_0^1 s^(alpha - 1) (1 - s^(alpha + 1))^(1/2) ds = B(alpha/(alpha + 1), 3/2) / (alpha + 1); so
    1 - e = Delta E / (m v^2) = C eta v^((alpha - 1)/(alpha + 1)) (v^(1/5) for alpha = 3/2)."""
    a = alpha
    dmax = ((a + 1.0) * mass * v * v / 2.0) ** (1.0 / (a + 1.0))
    z = a / (a + 1.0)
    integral = math.gamma(z) * math.gamma(1.5) / math.gamma(z + 1.5) / (a + 1.0)
    return 2.0 * eta * v * dmax ** a * integral / (mass * v * v)
