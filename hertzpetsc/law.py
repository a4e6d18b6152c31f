"""The interaction law between neighbouring beads: the protocol every law implements (eq. nc, V' of eq. vhertz).

A law is a frozen object with the bond potential V(r), the force V'(r) and the stiffness V''(r) of a bond of length
r (measured from the chain's static equilibrium, so V'(0) = 0), and whatever closed forms it knows. The lattice
model (:class:`hertzpetsc.model.LatticeModel`) holds one law; every solver asks the model, never the law's class.
A new law is a subclass of :class:`InteractionLaw` (the three derivatives, and optionally the closed forms below) and
needs no change anywhere else.

Closed forms a law may provide (the defaults say what they cost when it does not):

* ``degree``: the exponent d of the law's homogeneity, V'(a r) = a^d V'(r) (eq. twfam's scaling; None when the law
  has none). A travelling wave u = a w then solves the rescaled advance-delay equation with the law
  :meth:`rescaled` ``(a)`` and the frequency variable lam = omega^2 a^(1-d).
* :meth:`rescaled`: the law r -> a^(-d) V'(a r), by default a :class:`RescaledLaw` wrapper (any law, any d);
  Hertz knows it in closed form (the precompression divided by a).
* :meth:`contact`: where V'' may be non-zero (the rest of the bonds carry no force: the solvers skip them).
* ``linear_stiffness``: V''(0), the stiffness of small oscillations about the equilibrium (0 in a sonic vacuum).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .errors import check_real


class InteractionLaw:
    """Base class of the interaction laws (module docstring). Subclasses are frozen dataclasses."""

    #: exponent d of V'(a r) = a^d V'(r) used for the rescaled unknowns of the wave problems (None: no scaling)
    degree = None

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
    def scale_degree(self) -> float:
        """The exponent used by the rescaled wave problems: ``degree`` if the law has one, else 1."""
        return 1.0 if self.degree is None else float(self.degree)

    def rescaled(self, a: float) -> InteractionLaw:
        """The law r -> a^(-d) V'(a r) (d = :attr:`scale_degree`): u = a w turns m omega^2 u'' = V'(...) into
        m lam w'' = V'_a(...), lam = omega^2 a^(1-d)."""
        return RescaledLaw(self, check_scale(a), self.scale_degree)

    def describe(self) -> dict:
        """The law as plain data (record identities)."""
        raise NotImplementedError


def check_scale(a, name="a"):
    """a must be a finite number > 0 (an amplitude or a scale)."""
    return check_real(name, a, "the scale", 0.0)


class RescaledLaw(InteractionLaw):
    """r -> a^(-d) V'(a r) of any law (the default :meth:`InteractionLaw.rescaled`)."""

    def __init__(self, base, a, d):
        self.base, self.a, self.d = base, float(a), float(d)
        self.degree = base.degree

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
