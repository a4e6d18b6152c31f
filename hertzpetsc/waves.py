"""Travelling waves of eq. ad put on a chain (eq. twper): orbits x_n(t) = a u(q n - a^((alpha-1)/2) t), a = 1/||u||.

On a periodic chain of N beads the wavenumber must be q = 2 pi m / N (m integer), so that x_{n+N} = x_n. Bead
positions q n are generally not grid points of the branch profile: u and u' there come from the degree-5
Lagrange interpolant of the profile (:func:`hertzpetsc.stencil.lagrange_periodic`), whose error is below the
profile's own O(h^2) discretisation error.

An :class:`Orbit` is what the chain-side analyses take: the chain, the initial state, the wavenumber and the time
script-T after which S X(script-T) = X(0) (eq. invv), and where the state came from (the interpolated branch
profile, or a Gauss-Newton refinement of it).
"""
import math
from dataclasses import dataclass, replace

import numpy as np

from .errors import ParameterError
from .model import ChainSpec
from .stencil import lagrange_periodic


@dataclass(frozen=True)
class Orbit:
    """A travelling wave on a chain: X(0) = (x_n, xdot_n) with S X(T) = X(0), T = script-T."""

    spec: ChainSpec
    q: float
    m: int                # wavelengths on the chain, q = 2 pi m / N
    T: float              # script-T = q / omega
    x: np.ndarray         # (N, 2) initial state
    omega: float          # frequency a^((alpha-1)/2)
    source: str = "branch"

    @property
    def period(self):
        """Time period tau(q) = 2 pi / omega = (N/m) script-T of every bead (section 3.5)."""
        return 2 * math.pi / self.omega

    @property
    def N(self):
        return self.spec.N

    def with_state(self, x, source):
        """The same wave with another initial state (e.g. the refined one)."""
        x = np.asarray(x, dtype=float)
        if x.shape != (self.N, 2):
            raise ParameterError("state", x.shape, f"must have shape (N, 2) = ({self.N}, 2)")
        return replace(self, x=x, source=source)

    def tiled(self, L):
        """The wave on L times as many beads (the state repeated: the same script-T, m times L)."""
        return Orbit(self.spec.with_length(L * self.N), self.q, self.m * L, self.T, np.tile(self.x, (L, 1)),
                     self.omega, self.source)


def fits_chain(q, N):
    """Whether N q / (2 pi) is a positive whole number (a whole number of wavelengths on N beads)."""
    m = N * q / (2 * math.pi)
    return abs(m - round(m)) <= 1e-9 * max(1.0, m) and round(m) >= 1


def chain_wavenumbers(qs, N):
    """The wavenumbers among ``qs`` that fit a periodic chain of N beads, as floats."""
    return [float(q) for q in qs if fits_chain(q, N)]


def check_chain_wavenumber(q, N):
    """m = N q / (2 pi) must be a whole number: returns m, or raises ParameterError naming N."""
    m = N * q / (2 * math.pi)
    if not fits_chain(q, N):
        raise ParameterError("N", N, f"N q / (2 pi) = {m:.6g} must be a positive integer for q = {q:.6g} "
                                     "(the chain must hold a whole number of wavelengths)")
    return int(round(m))


def orbit_on_chain(point, spec, phase=0.0, time=0.0):
    """The travelling wave of branch point ``point`` on the periodic chain ``spec`` at ``time``:
    x_n = a u(q n - omega t + phase), a = 1 / ||u||_inf (the paper's normalisation, section 3.4)."""
    if spec.boundary != "periodic":
        raise ParameterError("boundary", spec.boundary, "a travelling wave modulo shifts needs a periodic chain")
    if spec.model != point.model:
        raise ParameterError("model", spec.model.describe(), f"differs from the branch's {point.model.describe()}")
    q = point.q
    m = check_chain_wavenumber(q, spec.N)
    a = 1.0 / point.diagnostics.norm_inf
    omega = a ** ((point.model.alpha - 1) / 2)
    u_full = point.u_full
    xi = np.mod(q * np.arange(spec.N) - omega * time + phase, 2 * math.pi)
    x = a * lagrange_periodic(u_full, point.h, xi)
    v = -a * omega * lagrange_periodic(u_full, point.h, xi, derivative=True)
    return Orbit(spec=spec, q=q, m=m, T=q / omega, x=np.stack([x, v], axis=1), omega=omega, source="branch")
