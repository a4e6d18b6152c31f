"""The lattice model: the chain's physics in one frozen, validated object (eq. nc).

    m_n x_n'' = V'(x_{n+1} - x_n) - V'(x_n - x_{n-1})

:class:`LatticeModel` holds the interaction law between neighbours (:class:`~hertzpetsc.hertz.HertzLaw`, eq.
vhertz, with its exponent alpha) and the masses m_n, which repeat a pattern (the paper's chain: all masses 1).
:class:`ChainSpec` is a finite chain of that lattice: N beads and a boundary condition (periodic, eq. pbcl; free
ends; fixed walls). Every consumer (the advance-delay problem, the solitary wave, the chain's right-hand side,
Jacobian and energy, the tangent flow, the waves) takes one of these and asks it for forces, stiffnesses,
energies and masses, so a new law or a mass pattern is a change here and in nowhere else.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from .errors import ParameterError
from .hertz import HertzLaw

BOUNDARIES = ("periodic", "free", "fixed")


def _check_masses(masses):
    try:
        m = tuple(float(x) for x in masses)
    except (TypeError, ValueError):
        raise ParameterError("masses", masses, "must be a non-empty list of positive numbers") from None
    if not m or not all(math.isfinite(x) and x > 0 for x in m):
        raise ParameterError("masses", masses, "every mass of the pattern must be a finite number > 0")
    return m


@dataclass(frozen=True)
class LatticeModel:
    """Interaction law and mass pattern of the infinite chain; the default is the paper's (alpha = 3/2, m_n = 1)."""

    law: HertzLaw = field(default_factory=HertzLaw)
    masses: tuple = (1.0,)

    def __post_init__(self):
        if not isinstance(self.law, HertzLaw):
            raise ParameterError("law", self.law, "must be a HertzLaw")
        object.__setattr__(self, "masses", _check_masses(self.masses))

    @classmethod
    def hertz(cls, alpha=1.5, masses=(1.0,), delta0=0.0):
        """The Hertzian chain with exponent alpha (eq. vhertz), the given mass pattern and precompression
        delta0 >= 0 (static overlap of neighbours; 0 is the paper's uncompressed chain)."""
        return cls(HertzLaw(alpha, delta0), masses)

    @property
    def alpha(self):
        return self.law.alpha

    @property
    def delta0(self):
        """The precompression (static overlap between neighbours), 0 for the paper's chain."""
        return self.law.delta0

    def with_masses(self, masses):
        """The same law with another mass pattern."""
        return LatticeModel(self.law, masses)

    def with_delta0(self, delta0):
        """The same masses with the law's precompression replaced by delta0."""
        return LatticeModel(HertzLaw(self.alpha, delta0), self.masses)

    @property
    def cell(self):
        """Beads in the repeating mass pattern."""
        return len(self.masses)

    @property
    def uniform_masses(self):
        """True when every bead has mass 1 (the paper's chain)."""
        return all(m == 1.0 for m in self.masses)

    # --- the forces, as every solver evaluates them ------------------------------------------------------------
    def force(self, r):
        """V'(r), the force a bond of length r exerts (eq. vhertz)."""
        return self.law.dV(r)

    def stiffness(self, r):
        """V''(r), the bond's linearised stiffness."""
        return self.law.d2V(r)

    def potential(self, r):
        """V(r), the bond's energy (eq. ham)."""
        return self.law.V(r)

    def mass(self, n):
        """m_n for bead indices n (any integers: the pattern repeats)."""
        return np.asarray(self.masses)[np.mod(np.asarray(n), self.cell)]

    def require_uniform_masses(self, what):
        """ParameterError unless every mass is 1 (for computations only written for the paper's chain)."""
        if not self.uniform_masses:
            raise ParameterError("masses", list(self.masses), f"{what} is written for the monatomic chain "
                                 "(all masses 1)")

    def describe(self):
        """The model as plain data (for record identities and file metadata); delta0 only when nonzero, so that
        the identities of the uncompressed chain's records are unchanged."""
        out = dict(alpha=self.alpha, masses=list(self.masses))
        if self.delta0 > 0.0:
            out["delta0"] = self.delta0
        return out


@dataclass(frozen=True)
class ChainSpec:
    """A finite chain of ``model``: N beads with a boundary condition (periodic: eq. pbcl)."""

    model: LatticeModel
    N: int
    boundary: str = "periodic"

    def __post_init__(self):
        if not isinstance(self.model, LatticeModel):
            raise ParameterError("model", self.model, "must be a LatticeModel")
        if not (isinstance(self.N, (int, np.integer)) and not isinstance(self.N, bool) and self.N >= 2):
            raise ParameterError("N", self.N, "the number of beads must be an integer >= 2")
        object.__setattr__(self, "N", int(self.N))
        if self.boundary not in BOUNDARIES:
            raise ParameterError("boundary", self.boundary, f"must be one of {', '.join(BOUNDARIES)}")
        if self.N % self.model.cell:
            raise ParameterError("N", self.N, f"must be a multiple of the mass pattern's length {self.model.cell}")

    @classmethod
    def hertz(cls, alpha=1.5, N=100, boundary="periodic", masses=(1.0,), delta0=0.0):
        """N beads of the Hertzian chain with exponent alpha (the paper's, with unit masses and no
        precompression, by default)."""
        return cls(LatticeModel.hertz(alpha, masses, delta0), N, boundary)

    @property
    def alpha(self):
        return self.model.alpha

    def with_length(self, N):
        """The same lattice and boundary on N beads."""
        return ChainSpec(self.model, N, self.boundary)

