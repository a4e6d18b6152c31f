"""Travelling waves of eq. ad put on a chain (eq. twper): orbits x_n(t) = s u_c(q n - omega t), c = n mod p, for any
mass pattern of p beads (the paper's chain: p = 1, s = 1/||u||, omega = s^((alpha-1)/2)).

On a periodic chain of N beads the wavenumber must be q = 2 pi m / N (m integer), so that x_{n+N} = x_n. Bead
positions q n are generally not grid points of the profiles: u_c and u_c' there come from the degree-5 Lagrange
interpolant (:func:`hertzpetsc.stencil.lagrange_periodic`), whose error is below the profiles' own O(h^2)
discretisation error.

An :class:`Orbit` is what the chain-side analyses take: the chain, the initial state, the wavenumber, script-T with
S X(script-T) = X(0) (eq. invv), and the state's source (the branch profile, or its refinement).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np
from numpy.typing import ArrayLike

from .errors import ParameterError, check_real
from .diagnostics import sup_norm
from .model import ChainSpec
from .stencil import full_period, lagrange_periodic
from .symmetry import WaveSymmetry


@dataclass(frozen=True)
class Orbit:
    """A travelling wave on a chain: X(0) = (x_n, xdot_n) with S X(T) = X(0), T = script-T."""

    spec: ChainSpec
    q: float
    m: int                # wavelengths on the chain, q = 2 pi m / N
    T: float              # script-T = p q / omega (p the mass pattern's length)
    x: np.ndarray         # (N, 2) initial state
    omega: float          # frequency (the paper's chain: a^((alpha-1)/2))
    source: str = "branch"
    amplitude: float = 1.0  # the wave's size s max_c ||u_c||_inf (eq. twper; 1: the paper's normalisation)

    @property
    def N(self) -> int:
        return self.spec.N

    @property
    def symmetry(self) -> WaveSymmetry:
        """The wave's :class:`~hertzpetsc.symmetry.WaveSymmetry` (cell, short map, Bloch sectors)."""
        return WaveSymmetry(self.N, self.m, self.spec.model.cell)

    def with_state(self, x: ArrayLike, source: str, T: Optional[float] = None) -> Orbit:
        """The same wave with another initial state (e.g. the refined one) and, given, another script-T (omega
        = p q / T)."""
        x = np.asarray(x, dtype=float)
        if x.shape != (self.N, 2):
            raise ParameterError("state", x.shape, f"must have shape (N, 2) = ({self.N}, 2)")
        if T is None or T == self.T:
            return replace(self, x=x, source=source)
        return replace(self, x=x, source=source, T=T, omega=self.omega * (self.T / T))

    def tiled(self, L: int) -> "Orbit":
        """The wave on L times as many beads (the state repeated: the same script-T, m times L)."""
        return Orbit(self.spec.with_length(L * self.N), self.q, self.m * L, self.T, np.tile(self.x, (L, 1)),
                     self.omega, self.source, self.amplitude)

    def with_amplitude(self, A: float) -> "Orbit":
        """The same wave of size A on a scale-invariant chain (eq. twper: x -> a x, xdot -> a^((d+1)/2) xdot,
        script-T -> a^(-(d-1)/2) script-T, a = A / amplitude); itself when A is its size or the chain has no such
        scaling."""
        if A == self.amplitude or not self.spec.model.scale_invariant:
            return self
        a = check_real("A", A, "the amplitude", 0.0) / self.amplitude
        e = (self.spec.model.law.scale_degree - 1) / 2
        return replace(self, x=self.x * np.array([a, a ** (1 + e)]), T=self.T / a ** e, omega=self.omega * a ** e,
                       amplitude=A)


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


def orbit_on_chain(point: "BranchPoint", spec: ChainSpec, phase: float = 0.0, time: float = 0.0,
                   scale: Optional[float] = None) -> Orbit:
    """The travelling wave of ``point`` (a :class:`~hertzpetsc.branch.BranchPoint`: p profiles u_c, frequency omega)
    on the periodic chain ``spec`` at ``time``: x_n = s u_c(q n - s^((d-1)/2) omega t + phase), c = n mod p, with
    script-T = p q / (s^((d-1)/2) omega), the time after which the shift by one cell (p beads) maps the state back.

    ``scale`` s uses the law's exact scaling (degree d, :mod:`hertzpetsc.law`): the chain's law must be the point's
    rescaled by 1/s. Default: the paper's normalisation s = 1 / max_c ||u_c||_inf (section 3.4) when the law is
    scale-invariant (eq. ad fixes the shape only), else 1 (the wave as stored); the orbit's ``amplitude`` is
    s max_c ||u_c||_inf (1 in the paper's normalisation); the interpolation: module docstring."""
    if spec.boundary != "periodic":
        raise ParameterError("boundary", spec.boundary, "a travelling wave modulo shifts needs a periodic chain")
    model, q, p = point.model, point.q, point.model.cell
    size = max(sup_norm(u) for u in point.profiles)
    if scale is None:
        scale = 1.0 / size if model.rescaled(2.0) == model else 1.0
    seen = model if scale == 1.0 else model.rescaled(1.0 / scale)
    if not same_lattice(spec.model, seen):
        raise ParameterError("model", spec.model.describe(), f"differs from the wave's {seen.describe()} (scale "
                                                             f"{scale:.6g})")
    m = check_chain_wavenumber(q, spec.N)
    omega = scale ** ((model.law.scale_degree - 1) / 2) * point.omega
    n = np.arange(spec.N)
    xi = np.mod(q * n - omega * time + phase, 2 * math.pi)
    x = np.empty((spec.N, 2))
    for c, u in enumerate(point.profiles):       # odd half profiles on [0, pi], or whole periods of 2 pi / h values
        u, beads = np.asarray(u, dtype=float), n % p == c
        full = u if len(u) == round(2 * math.pi / point.h) else full_period(u)
        x[beads, 0] = scale * lagrange_periodic(full, point.h, xi[beads])
        x[beads, 1] = -scale * omega * lagrange_periodic(full, point.h, xi[beads], derivative=True)
    return Orbit(spec=spec, q=q, m=m, T=p * q / omega, x=x, omega=omega, source="branch",
                 amplitude=1.0 if scale == 1.0 / size else scale * size)


def same_lattice(a, b, rtol=1e-12):
    """The same masses and damping, and laws whose parameters agree to ``rtol`` (a rescaled law is rounded; a bond
    pattern's laws each)."""
    return type(a.law) is type(b.law) and _close(a.describe(), b.describe(), rtol)


def _close(x, y, rtol):
    if isinstance(x, dict) or isinstance(y, dict):
        return isinstance(x, dict) and isinstance(y, dict) and x.keys() == y.keys() and \
            all(_close(x[k], y[k], rtol) for k in x)
    if isinstance(x, str) or isinstance(y, str):
        return x == y
    if isinstance(x, list) and x and isinstance(x[0], dict):
        return isinstance(y, list) and len(x) == len(y) and all(_close(u, v, rtol) for u, v in zip(x, y))
    return bool(np.allclose(x, y, rtol=rtol, atol=0.0))
