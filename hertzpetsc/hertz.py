"""The Hertz contact law between neighbouring beads and the closed forms of the binary oscillation (section 2.1).

Pure numpy, no PETSc. ``x`` may be a scalar or an array everywhere. :class:`HertzLaw` implements the law protocol
of :mod:`hertzpetsc.law`; :class:`hertzpetsc.model.LatticeModel` puts it together with the masses and damping.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np
from numpy.typing import ArrayLike

from .errors import ParameterError, check_real
from .law import InteractionLaw, check_scale


# The largest Hertz exponent: the binary oscillation's scale 2^alpha (eq. vhertz at overlap 2 |u|) is a finite float
# up to alpha = 1023; beyond, the paper's starting wave overflows.
ALPHA_MAX = 1000.0


def check_alpha(alpha):
    """Return ``alpha`` as a float, or raise :class:`ParameterError` unless 1 < alpha <= :data:`ALPHA_MAX` (eq.
    vhertz)."""
    return check_real("alpha", alpha, "the Hertz exponent", 1.0, ALPHA_MAX, hi_open=False)


def check_delta0(delta0, alpha=None):
    """Return the precompression ``delta0`` as a float, or raise :class:`ParameterError` unless delta0 >= 0 and, for
    the exponent ``alpha``, delta0^(alpha+1) (the static bond's energy) and its square are finite floats (the bound
    of :func:`hertzpetsc.families.amplitude_ceiling`: beyond it no wave has a finite energy)."""
    hi = None if alpha is None else math.sqrt(float(np.finfo(float).max)) ** (1.0 / (alpha + 1.0))
    return check_real("delta0", delta0, "the precompression (static overlap)", 0.0, hi, lo_open=False)


def abs_power(a, e):
    """a^e for a >= 0. Exponents that are whole or half-whole numbers up to 4 (alpha = 3/2, 2, 5/2, ...) use
    products and one sqrt, several times faster than the general power, which dominates the chain's right-hand
    side; they agree with a ** e to a few ulp."""
    k, half = power_recipe(e)
    if k >= 0:
        out = np.sqrt(a) if half else np.ones_like(a)
        for _ in range(k):
            out = out * a
        return out
    return a ** e


def power_recipe(e):
    """(k, half) of :func:`abs_power` for the exponent e: k products and a sqrt if half, or k = -1 for the general
    power."""
    n2 = 2.0 * e
    if n2 == round(n2) and 0 <= n2 <= 8:
        return divmod(int(round(n2)), 2)
    return -1, 0


def compressed_force(x, delta0, alpha):
    """delta0^alpha - (delta0 - x)_+^alpha for delta0 > 0, to a few ulp relative also when |x| << delta0.

    In contact (x < delta0), with c = delta0, d = delta0 - x: for whole alpha = n, c^n - d^n = x sum_j c^(n-1-j)
    d^j; for half-whole alpha = n/2, with s = sqrt(c), t = sqrt(d), c^alpha - d^alpha = s^n - t^n = x sum_j
    s^(n-1-j) t^j / (s + t): the difference c - d = x is exact, and the sum of positive terms is well conditioned.
    Other exponents: -delta0^alpha expm1(alpha log1p(-x/delta0)). The compiled right-hand side
    (``_chain_kernel.c``, ``force``) does the same operations in the same order."""
    k, half = power_recipe(alpha)
    if k < 0:
        ratio = np.minimum(x / delta0, 1.0)
        # log1p(-1) = -inf: out of contact, V' = delta0^alpha; a compression far beyond any wave's (a diverging
        # Newton iterate, x ~ -1e300) gives an infinite force, which the solver rejects, without a warning
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            return -delta0 ** alpha * np.expm1(alpha * np.log1p(-ratio))
    gap = np.maximum(delta0 - x, 0.0)
    if half:
        s, t, n = math.sqrt(delta0), np.sqrt(gap), 2 * k + 1
    else:
        s, t, n = delta0, gap, k
    p, sp = np.ones_like(gap), 1.0
    for _ in range(n - 1):
        sp = sp * s
        p = p * t + sp
    out = x * p / (s + t) if half else x * p
    return np.where(x >= delta0, delta0 ** alpha, out)[()]


@dataclass(frozen=True)
class HertzLaw(InteractionLaw):
    """V(x) = |x|^(1+alpha) H(-x) / (1+alpha) (eq. vhertz) and the symmetrised W (eq. int), for alpha > 1.

    With a precompression (static overlap) ``delta0`` > 0 the bond length x is measured from the compressed
    equilibrium: V'(x) = delta0^alpha - (delta0 - x)_+^alpha = delta0^alpha + V'_0(x - delta0), so V'(0) = 0,
    V''(0) = alpha delta0^(alpha-1), and contact is lost (a gap opens) for x >= delta0. delta0 = 0 is the paper's
    law and evaluates exactly as before. The closed forms below (W, c_alpha, period, p0) are those of delta0 = 0.
    """

    name = "hertz"
    alpha: float = 1.5
    delta0: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "alpha", check_alpha(self.alpha))
        object.__setattr__(self, "delta0", check_delta0(self.delta0, self.alpha))

    @property
    def degree(self) -> float:
        """V'_delta0(a r) = a^alpha V'_(delta0/a)(r): homogeneous of degree alpha up to the precompression."""
        return self.alpha

    def rescaled(self, a: float) -> HertzLaw:
        """r -> a^(-alpha) V'(a r), in closed form: the same exponent with the precompression delta0 / a (a = inf:
        the uncompressed limit delta0 / a = 0)."""
        if a == math.inf:
            return replace(self, delta0=0.0)
        return replace(self, delta0=self.delta0 / check_scale(a))

    @property
    def separation(self) -> Optional[float]:
        """delta0: a bond that long has lost contact (None without precompression: every bond at r >= 0 has)."""
        return self.delta0 if self.delta0 > 0.0 else None

    @property
    def reference_amplitude(self) -> float:
        """delta0: the amplitude at which contact is lost (0 for the uncompressed chain, which has no scale)."""
        return self.delta0

    @property
    def kernel_form(self) -> Optional[str]:
        """'hertz' (the compiled right-hand side evaluates this law) unless a subclass redefines V, V', V'' or the
        contact mask."""
        cls = type(self)
        same = all(getattr(cls, n) is getattr(HertzLaw, n) for n in ("V", "dV", "d2V", "contact"))
        return "hertz" if same else None

    def stokes_coefficient(self, q: ArrayLike) -> np.ndarray:
        """C(q) in omega / omega_lin - 1 = C(q) a^2 + O(a^4) for the monatomic precompressed chain (a: first sine
        coefficient, or ||u||_inf, of the wave): C = (alpha-1)(alpha-1-sin^2(q/2)) / (4 delta0^2), from the cubic
        Taylor term of V' directly and the quadratic one through the second harmonic (Lindstedt-Poincare at fixed
        mean overlap)."""
        if not self.delta0 > 0:
            raise ParameterError("delta0", self.delta0, "the weakly nonlinear coefficient needs a precompression > 0")
        s2 = np.sin(np.asarray(q, dtype=float) / 2) ** 2
        return (self.alpha - 1) * (self.alpha - 1 - s2) / (4 * self.delta0 ** 2)

    @property
    def taylor(self) -> tuple:
        """(V''(0), V'''(0)/2, V''''(0)/6) = alpha delta0^(alpha-1) (1, -(alpha-1)/(2 delta0),
        (alpha-1)(alpha-2)/(6 delta0^2)) (a subclass with derivatives of its own: differences of its V'')."""
        if self.kernel_form is None or not self.delta0 > 0:
            return InteractionLaw.taylor.fget(self)
        a, d = self.alpha, self.delta0
        K = a * d ** (a - 1)
        return K, -K * (a - 1) / (2 * d), K * (a - 1) * (a - 2) / (6 * d * d)

    def contact(self, r: ArrayLike) -> np.ndarray:
        """Bonds in contact (r < 0) for the uncompressed law, whose V' and V'' vanish elsewhere; every bond with
        precompression (V' = delta0^alpha once contact is lost)."""
        if self.delta0 > 0.0:
            return np.ones(np.shape(r), dtype=bool)
        return np.asarray(r) < 0.0

    def describe(self) -> dict:
        """alpha, and delta0 when nonzero (so that the uncompressed chain's record identities are unchanged; no
        ``law`` key: a description without one is Hertz's); a subclass with a name of its own adds it."""
        if type(self).name != "hertz":
            return InteractionLaw.describe(self)
        return dict(alpha=self.alpha, **({"delta0": self.delta0} if self.delta0 > 0.0 else {}))

    @property
    def linear_stiffness(self) -> float:
        """K = V''(0) = alpha delta0^(alpha-1) (0 for the uncompressed chain); a subclass with derivatives of its
        own: its V''(0)."""
        if self.kernel_form is None:
            return InteractionLaw.linear_stiffness.fget(self)
        return self.alpha * self.delta0 ** (self.alpha - 1.0)

    # --- V and its derivatives (eq. vhertz); H(-x) makes them vanish for x >= 0 (no contact) ---
    def V(self, x: ArrayLike) -> np.ndarray:
        """V(x), normalised by V(0) = 0 (with precompression: delta0^alpha x + ((delta0-x)_+^(1+alpha) -
        delta0^(1+alpha)) / (1+alpha), whose linear part sums to zero over a periodic chain)."""
        if self.delta0 > 0.0:
            d, a = self.delta0, self.alpha
            return d ** a * x + (abs_power(np.maximum(d - x, 0.0), 1.0 + a) - d ** (1.0 + a)) / (1.0 + a)
        return abs_power(-np.minimum(x, 0.0), 1.0 + self.alpha) / (1.0 + self.alpha)

    def dV(self, x: ArrayLike) -> np.ndarray:
        """V'(x) = -|x|^alpha H(-x): the contact force, non-positive; with precompression
        delta0^alpha - (delta0 - x)_+^alpha, without cancellation when |x| << delta0 (:func:`compressed_force`)."""
        if self.delta0 > 0.0:
            return compressed_force(np.asarray(x, dtype=float), self.delta0, self.alpha)
        return -abs_power(-np.minimum(x, 0.0), self.alpha)

    def d2V(self, x: ArrayLike) -> np.ndarray:
        """V''(x) = alpha |x|^(alpha-1) H(-x), continuous for alpha > 1 (alpha (delta0 - x)_+^(alpha-1) with
        precompression)."""
        if self.delta0 > 0.0:
            return self.alpha * abs_power(np.maximum(self.delta0 - np.asarray(x, dtype=float), 0.0),
                                          self.alpha - 1.0)
        return self.alpha * abs_power(-np.minimum(x, 0.0), self.alpha - 1.0)

    # --- symmetrised potential W(x) = V(-2|x|)/2 = 2^alpha |x|^(1+alpha)/(1+alpha) (theorem 1) ---
    def W(self, x: ArrayLike) -> np.ndarray:
        return 2.0 ** self.alpha * np.abs(x) ** (1.0 + self.alpha) / (1.0 + self.alpha)

    def dW(self, x: ArrayLike) -> np.ndarray:
        return 2.0 ** self.alpha * np.abs(x) ** self.alpha * np.sign(x)

    # --- closed forms of lemma binary ---
    @property
    def c_alpha(self) -> float:
        """c_alpha of the period law (eq. period)."""
        a = self.alpha
        z = 1.0 / (1.0 + a)
        return 2.0 * math.sqrt(math.pi) * (1.0 + a) ** (-a / (1.0 + a)) * math.gamma(z) / math.gamma(z + 0.5)

    def period(self, p: ArrayLike) -> np.ndarray:
        """Period T(p) = c_alpha p^((1-alpha)/(1+alpha)) of u'' + W'(u) = 0, u(0) = 0, u'(0) = p (eq. period)."""
        return self.c_alpha * np.asarray(p, dtype=float) ** ((1.0 - self.alpha) / (1.0 + self.alpha))

    @property
    def p0(self) -> float:
        """Initial slope p0 of the binary oscillation, T(p0) = 2 pi (eq. ci)."""
        a = self.alpha
        z = 1.0 / (1.0 + a)
        g = math.sqrt(math.pi) * math.gamma(z + 0.5) / math.gamma(z)
        return (1.0 + a) ** (a / (1.0 - a)) * g ** ((1.0 + a) / (1.0 - a))

    def amplitude(self, p: ArrayLike) -> np.ndarray:
        """u_max = [p^2 (1+alpha)]^(1/(1+alpha)) / 2, the maximum of the solution with slope p at 0 (lemma binary)."""
        return 0.5 * (np.asarray(p, dtype=float) ** 2 * (1.0 + self.alpha)) ** (1.0 / (1.0 + self.alpha))

    @property
    def rescaling_exponent(self) -> float:
        """2/(alpha-1): u ~ k_alpha q^(-2/(alpha-1)) as q -> 0 (eq. normscaling)."""
        return 2.0 / (self.alpha - 1.0)

