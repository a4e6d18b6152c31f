"""Travelling waves of eq. ad put on a chain (eq. twper): x_n(t) = a u(q n - a^((alpha-1)/2) t), a = 1/||u||_inf.

On a periodic chain of N beads the wavenumber must be q = 2 pi m / N (m integer), so that x_{n+N} = x_n. Bead
positions q n are generally not grid points of the branch profile: u and u' there come from the degree-5
Lagrange interpolant of the profile (:func:`hertzpetsc.stencil.lagrange_periodic`), whose error is below the
profile's own O(h^2) discretisation error.
"""
import math
from dataclasses import dataclass

import numpy as np

from .branchfile import point_index
from .errors import ParameterError
from .stencil import full_period, lagrange_periodic


@dataclass(frozen=True)
class TravellingWaveState:
    """Initial state (x_n(0), xdot_n(0)) of a travelling wave, with its scales (eq. twper, eq. invv)."""

    q: float
    m: int
    N: int
    a: float            # amplitude factor, 1/||u||_inf
    omega: float        # frequency a^((alpha-1)/2)
    T: float            # script-T = q / omega, the time after which S X(T) = X(0)
    x: np.ndarray
    v: np.ndarray

    @property
    def period(self):
        """Time period tau(q) = 2 pi / omega = (N/m) script-T of every bead (section 3.5)."""
        return 2 * math.pi / self.omega

    def as_array(self):
        """(N, 2) array of (x_n, xdot_n)."""
        return np.stack([self.x, self.v], axis=1)


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


def wave_on_chain(branch, q, N, phase=0.0, time=0.0):
    """The state at ``time`` of the travelling wave of branch point q on N beads: x_n = a u(q n - omega t + phase)."""
    i = point_index(branch, q)
    q = float(branch["q"][i])
    m = check_chain_wavenumber(q, N)
    alpha, h = float(branch["alpha"]), float(branch["h"])
    a = 1.0 / float(branch["norm_inf"][i])
    omega = a ** ((alpha - 1) / 2)
    u_full = full_period(branch["u"][i])
    xi = np.mod(q * np.arange(N) - omega * time + phase, 2 * math.pi)
    x = a * lagrange_periodic(u_full, h, xi)
    v = -a * omega * lagrange_periodic(u_full, h, xi, derivative=True)
    return TravellingWaveState(q=q, m=m, N=N, a=a, omega=omega, T=q / omega, x=x, v=v)
