"""The symmetries of a travelling wave on a periodic chain, and the smaller problems they reduce it to (section 3.5).

The wave x_n(t) = u_c(q n - omega t) (c = n mod p, p the mass pattern's length; p = 1 is the paper's chain) with
q = 2 pi m / N on N beads is counted in pattern cells: N / p cells, per-cell wavenumber p q, m wavelengths. The map
F_q = S R(script-T; 0) (S: the shift by one cell, script-T = p q / omega) leaves two symmetries unused:

* **space**: with g = gcd(m, N / p) the wave repeats every M = N / g beads (M / p cells), so F_q commutes with the
  shift by M beads and splits into g Bloch sectors theta_l = 2 pi l / g of the M-bead cell (:mod:`hertzpetsc.bloch`);
* **time**: on the cell the wave has m' = m / g wavelengths, coprime with its M / p cells. With k m' = 1 + j M / p,
  x_{n+kp}(t + delta) = x_n(t) for delta = script-T / m' (p q k - omega delta = 2 pi j). So G_theta =
  S_theta^k R_theta(delta; 0) on the twisted cell (y_{n+M} = e^{i theta} y_n) has G_theta^{m'} = e^{i j theta} F_theta:

      spec(F_q on N beads) = union over l of { e^{-i j theta_l} mu^{m'} : mu in spec(G_theta_l) },

at about 1 / m of the work of F_q on the N beads. A travelling wave is a fixed point of X0 -> S^k X(delta; X0) on the
cell, which also enforces its exact periodicity in time (a fixed point of the paper's map over script-T may drift
along the near-degenerate directions that move the m compression zones apart).
"""
import math
from dataclasses import dataclass

from .errors import ParameterError


@dataclass(frozen=True)
class WaveSymmetry:
    """m wavelengths on N beads of a lattice whose mass pattern has p beads: the cell (M = N / g beads, m_cell = m / g
    wavelengths), the shift k (in pattern cells) and the time fraction 1 / m_cell of the short map, and
    j = (k m_cell - 1) / (M / p)."""

    N: int
    m: int
    p: int = 1

    def __post_init__(self):
        if not (isinstance(self.p, int) and self.p >= 1 and self.N % self.p == 0):
            raise ParameterError("N", self.N, f"must be a multiple of the mass pattern's length p = {self.p}")
        if not (1 <= self.m <= self.N):
            raise ParameterError("m", self.m, f"the number of wavelengths must lie in [1, N] = [1, {self.N}]")

    @property
    def g(self):
        return math.gcd(self.m, self.N // self.p)

    @property
    def M(self):
        """Beads of the cell (a whole number of pattern cells)."""
        return self.N // self.g

    @property
    def m_cell(self):
        """Wavelengths on the cell (coprime with its M / p pattern cells)."""
        return self.m // self.g

    @property
    def k(self):
        """The shift of the short map in pattern cells: k m_cell = 1 (mod M / p), 0 < k <= M / p."""
        cells = self.M // self.p
        return pow(self.m_cell, -1, cells) if cells > 1 else 1

    @property
    def j(self):
        """(k m_cell - 1) / (M / p): G^{m_cell} = S^{1 + j M / p} R(script-T) = e^{i j theta} F in the sector theta."""
        return (self.k * self.m_cell - 1) // (self.M // self.p)

    def delta(self, T):
        """The time of the short map, script-T / m_cell."""
        return T / self.m_cell

    def sectors(self):
        """The Bloch angles theta_l = 2 pi l / g to integrate (l = 0 .. g // 2: the others are conjugates)."""
        return [2 * math.pi * l / self.g for l in range(self.g // 2 + 1)]

    def cost(self):
        """Work relative to the dense route (2N columns on N beads over script-T): sectors weighted by their
        real (theta = 0, pi) or complex (twice) arithmetic, 2M columns on M beads, over 1 / m_cell of the time."""
        thetas = self.sectors()
        real = sum(1 for th in thetas if th in (0.0, math.pi))
        return (real + 2 * (len(thetas) - real)) * (self.M / self.N) ** 2 / self.m_cell


def real_sector(theta):
    """theta = 0 or pi (mod 2 pi): the twist e^{i theta} = +-1 is real (real tangents, real pencils suffice)."""
    return abs(math.sin(theta)) < 1e-14
