"""The Fermi-Pasta-Ulam(-Tsingou) polynomial law (alpha-beta FPU): V(r) = k r^2/2 + alpha r^3/3 + beta r^4/4. Pure
numpy.

V'(r) = k r + alpha r^2 + beta r^3, V''(r) = k + 2 alpha r + 3 beta r^2: stiffness k > 0, quadratic and cubic
nonlinearities alpha, beta (any real; beta = 0 with alpha = 0 is the harmonic lattice). No scaling symmetry; the
nonlinearity is of order one at bond lengths min(k/|alpha|, sqrt(k/|beta|)). Its closed forms are the linear
lattice's and the weakly nonlinear frequency (:meth:`~hertzpetsc.law.InteractionLaw.stokes_coefficient`, from the
exact Taylor coefficients (k, alpha, beta)).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .errors import check_real
from .law import InteractionLaw


@dataclass(frozen=True)
class FPULaw(InteractionLaw):
    """V(r) = k r^2/2 + alpha r^3/3 + beta r^4/4, k > 0 (module docstring)."""

    name = "fpu"
    k: float = 1.0
    alpha: float = 0.0
    beta: float = 1.0

    def __post_init__(self):
        object.__setattr__(self, "k", check_real("k", self.k, "the FPU stiffness V''(0)", 0.0))
        for name, what in (("alpha", "the FPU quadratic coefficient"), ("beta", "the FPU cubic coefficient")):
            object.__setattr__(self, name, check_real(name, getattr(self, name), what))

    @property
    def reference_amplitude(self) -> float:
        """min(k/|alpha|, sqrt(k/|beta|)) (1 for the harmonic lattice)."""
        scales = [self.k / abs(self.alpha)] if self.alpha else []
        scales += [math.sqrt(self.k / abs(self.beta))] if self.beta else []
        return min(scales, default=1.0)

    @property
    def linear_stiffness(self) -> float:
        return self.k

    @property
    def taylor(self) -> tuple:
        """(V''(0), V'''(0)/2, V''''(0)/6) = (k, alpha, beta)."""
        return self.k, self.alpha, self.beta

    def V(self, r: ArrayLike) -> np.ndarray:
        r = np.asarray(r, float)
        return r * r * (self.k / 2 + r * (self.alpha / 3 + r * self.beta / 4))

    def dV(self, r: ArrayLike) -> np.ndarray:
        r = np.asarray(r, float)
        return r * (self.k + r * (self.alpha + r * self.beta))

    def d2V(self, r: ArrayLike) -> np.ndarray:
        r = np.asarray(r, float)
        return self.k + r * (2 * self.alpha + 3 * self.beta * r)
