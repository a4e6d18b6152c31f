"""The symmetries of a travelling wave on a periodic chain, and the smaller problems they reduce it to (section 3.5).

The wave x_n(t) = u(q n - omega t) with q = 2 pi m / N on N beads has two symmetries that the paper's F_q = S R(T; 0)
(T = script-T) does not use:

* **space**: with g = gcd(m, N) it repeats every M = N / g beads, so F_q commutes with the shift by M beads and
  splits into g Bloch sectors theta_l = 2 pi l / g of the M-bead cell (:mod:`hertzpetsc.bloch`);
* **time**: on the cell the wave has m' = m / g wavelengths with gcd(m', M) = 1. With k the inverse of m' modulo M
  (k m' = 1 + j M), the wave is invariant under the shift by k beads combined with the time delta = T / m':
  x_{n+k}(t + delta) = x_n(t), because q k - omega delta = 2 pi (k m' - 1) / M = 2 pi j. So the map
  G_theta = S_theta^k R_theta(delta; 0) (the k-bead shift on the twisted cell, y_{n+M} = e^{i theta} y_n) has
  G_theta^{m'} = S_theta^{k m'} R_theta(T; 0) = e^{i j theta} F_theta, and

      spec(F_q on N beads) = union over l of { e^{-i j theta_l} mu^{m'} : mu in spec(G_theta_l) }.

A multiplier of F_q therefore costs an integration over T / m' of 2M tangent columns on M beads instead of T with 2N
columns on N beads: about m times less work. The refinement uses the same map: a travelling wave is a fixed point of
X0 -> S^k X(delta; X0) on the cell, which also enforces the wave's exact periodicity in time (a fixed point of the
paper's map over T may drift along the near-degenerate directions that move the m compression zones apart).
"""
import math
from dataclasses import dataclass

from .errors import ParameterError


@dataclass(frozen=True)
class WaveSymmetry:
    """m wavelengths on N beads: the cell (M = N / g beads, m_cell = m / g wavelengths), the bead shift k and the
    time fraction 1 / m_cell of the short map, and j = (k m_cell - 1) / M."""

    N: int
    m: int

    def __post_init__(self):
        if not (1 <= self.m <= self.N):
            raise ParameterError("m", self.m, f"the number of wavelengths must lie in [1, N] = [1, {self.N}]")

    @property
    def g(self):
        return math.gcd(self.m, self.N)

    @property
    def M(self):
        """Beads of the cell."""
        return self.N // self.g

    @property
    def m_cell(self):
        """Wavelengths on the cell (coprime with M)."""
        return self.m // self.g

    @property
    def k(self):
        """The bead shift of the short map: k m_cell = 1 (mod M), 0 < k <= M."""
        return pow(self.m_cell, -1, self.M) if self.M > 1 else 1

    @property
    def j(self):
        """(k m_cell - 1) / M: G^{m_cell} = S^{1 + j M} R(T) = e^{i j theta} F in the sector theta."""
        return (self.k * self.m_cell - 1) // self.M

    def delta(self, T):
        """The time of the short map, script-T / m_cell."""
        return T / self.m_cell

    def sectors(self):
        """The Bloch angles theta_l = 2 pi l / g to integrate (l = 0 .. g // 2: the others are conjugates)."""
        return [2 * math.pi * l / self.g for l in range(self.g // 2 + 1)]

    def cost(self):
        """Work relative to the dense route (2N columns on N beads over script-T): sectors weighted by their
        real (theta = 0, pi) or complex (twice) arithmetic, 2M columns on M beads, over 1 / m_cell of the time."""
        real = sum(1 for th in self.sectors() if th in (0.0, math.pi))
        complex_ = len(self.sectors()) - real
        return (real + 2 * complex_) * (self.M / self.N) ** 2 / self.m_cell
