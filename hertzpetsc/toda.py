"""The Toda lattice (M. Toda, *Theory of Nonlinear Lattices*, ch. 2): an interaction law with periodic travelling
waves in closed form, a check of the whole wave pipeline. Pure numpy (scipy's elliptic functions).

With the bond length r measured from the equilibrium, V(r) = (k/b^2) (e^(-b r) - 1 + b r): V'(r) = (k/b)
(1 - e^(-b r)), V''(r) = k e^(-b r), stiffness k = V''(0) and nonlinearity b (Toda's a b and b; b -> 0 is the
harmonic lattice). The law has no scaling symmetry; its nonlinearity is of order one at bond lengths 1/b.

**Cnoidal waves** (Toda's eqs. (2.2.8)-(2.2.9), moved to the waves of zero mean strain the package computes):
for the elliptic modulus m (parameter m = k_ell^2) and the per-bead wavenumber q, with K(m), E(m) the complete
elliptic integrals and G = 1 / (1/sn^2(K q / pi) - 1 + E/K), the strain of the bond of phase xi = q n - omega t is

    s(xi) = r(K xi / pi) - c,   r(theta) = -(1/b) log(1 + G (dn^2(theta) - E/K)),   c = <r> (its mean),

and omega = (pi / K) sqrt(k / mass) e^(b c / 2) sqrt(G). (Toda's wave has a mean strain c, at zero mean force; the
same lattice measured from r = c is a Toda lattice with k e^(b c), whose constant force cancels between bonds.) At
m -> 0: omega -> 2 sqrt(k/mass) sin(q/2). :meth:`TodaLaw.cnoidal_wave` evaluates it; ``a1`` is the first sine
coefficient of the odd displacement profile u (s(xi - q/2) = sum_j 2 b_j sin(j q/2) cos(j xi)), the amplitude the
fixed-amplitude wave problem imposes (``measure='a1'``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .errors import ParameterError, check_real
from .law import InteractionLaw

# points of the trapezoidal rule (spectrally accurate on the periodic, analytic strain) of the cnoidal wave's mean
# strain and first Fourier coefficient
CNOIDAL_POINTS = 4096


@dataclass(frozen=True)
class CnoidalWave:
    """One periodic travelling wave of the Toda lattice (module docstring): q, the elliptic parameter m, omega, the
    first sine coefficient a1 of the displacement, Toda's mean strain c and the strain s(xi) on ``xi``."""

    q: float
    m: float
    omega: float
    a1: float
    c: float
    xi: np.ndarray
    strain: np.ndarray


@dataclass(frozen=True)
class TodaLaw(InteractionLaw):
    """V(r) = (k/b^2) (e^(-b r) - 1 + b r), k > 0, b > 0 (module docstring)."""

    name = "toda"
    k: float = 1.0
    b: float = 1.0

    def __post_init__(self):
        object.__setattr__(self, "k", check_real("k", self.k, "the Toda lattice's stiffness V''(0)", 0.0))
        object.__setattr__(self, "b", check_real("b", self.b, "the Toda lattice's nonlinearity", 0.0))

    @property
    def reference_amplitude(self) -> float:
        """1/b."""
        return 1.0 / self.b

    @property
    def linear_stiffness(self) -> float:
        return self.k

    @property
    def taylor(self) -> tuple:
        """(V''(0), V'''(0)/2, V''''(0)/6) = (k, -k b / 2, k b^2 / 6)."""
        return self.k, -self.k * self.b / 2, self.k * self.b ** 2 / 6

    def V(self, r: ArrayLike) -> np.ndarray:
        x = -self.b * np.asarray(r, float)
        return self.k / self.b ** 2 * (np.expm1(x) - x)

    def dV(self, r: ArrayLike) -> np.ndarray:
        return -self.k / self.b * np.expm1(-self.b * np.asarray(r, float))

    def d2V(self, r: ArrayLike) -> np.ndarray:
        return self.k * np.exp(-self.b * np.asarray(r, float))

    # --- the closed forms of the periodic travelling waves -----------------------------------------------------
    def cnoidal_wave(self, q: float, m: float, mass: float = 1.0, points: int = CNOIDAL_POINTS) -> CnoidalWave:
        """The cnoidal wave of per-bead wavenumber q in (0, pi] and elliptic parameter m in [0, 1) on a chain of
        beads of ``mass`` (module docstring), its strain on ``points`` phases of a period."""
        from scipy.special import ellipe, ellipj, ellipk
        q = check_real("q", q, "the wavenumber", 0.0, math.pi, hi_open=False)
        m = check_real("m", m, "the elliptic parameter", 0.0, 1.0, lo_open=False)
        K, E = float(ellipk(m)), float(ellipe(m))
        sn = float(ellipj(K * q / math.pi, m)[0])
        G = 1.0 / (1.0 / sn ** 2 - 1.0 + E / K)
        xi = 2 * math.pi * np.arange(points) / points
        dn = ellipj(K * xi / math.pi, m)[2]
        r = -np.log1p(G * (dn ** 2 - E / K)) / self.b
        c = float(np.mean(r))
        omega = math.pi / K * math.sqrt(self.k / mass) * math.exp(self.b * c / 2) * math.sqrt(G)
        c1 = 2.0 * float(np.mean(r * np.cos(xi)))
        return CnoidalWave(q=q, m=m, omega=omega, a1=abs(c1) / (2 * math.sin(q / 2)), c=c, xi=xi, strain=r - c)

    def cnoidal_wave_of(self, q: float, a1: float, mass: float = 1.0) -> CnoidalWave:
        """The cnoidal wave whose displacement has the first sine coefficient a1 > 0 (m found by bisection)."""
        from scipy.optimize import brentq
        a1 = check_real("a1", a1, "the first sine coefficient of the wave", 0.0)
        hi = 1.0 - 1e-12
        if not self.cnoidal_wave(q, hi, mass).a1 > a1:
            raise ParameterError("a1", a1, "beyond the cnoidal waves' range at this q (elliptic parameter 1 - 1e-12)")
        m = brentq(lambda x: self.cnoidal_wave(q, x, mass).a1 - a1, 0.0, hi, xtol=1e-15, rtol=1e-15)
        return self.cnoidal_wave(q, m, mass)
