"""The grid of a travelling-wave profile and its parallel layout: odd or even, periodic or on a truncated line.

Grid xi_j = j h, h = pi / K (for the default period 2 pi), j = 0 .. 2K-1. An odd 2 pi-periodic u has
u_0 = u_K = 0 and u_{2K-j} = -u_j, so the unknowns are u_1 .. u_{K-1}, stored in a PETSc Vec of size K-1
distributed over the communicator (this restriction to odd profiles removes the translation and constant
degeneracies of eq. ad, as in the paper). Even profiles (the solitary wave's r, eq. adr) have the unknowns
u_0 .. u_K, periodic or vanishing beyond the truncated line.

A shift u(xi_j + sigma h) spans up to half the domain, so it cannot be a DMDA stencil: :meth:`ProfileGrid.fold`
maps any grid index to an unknown and a sign, and :mod:`hertzpetsc.assembly` gathers and assembles the
long-range stencils (:mod:`hertzpetsc.stencil`) on this layout.
"""
from __future__ import annotations

import math

import numpy as np
from petsc4py import PETSc
from numpy.typing import ArrayLike

from .assembly import gathered
from .errors import ParameterError, check_real, param


def check_cells_per_pi(cells_per_pi):
    """K must be an integer >= 4 (h = pi/K) whose whole period's 2K values PETSc's index type can count; returns it
    as int (the memory a solver needs on it: :func:`~hertzpetsc.resources.check_memory`)."""
    return cells_per_pi_param(4).metadata["param"].check("cells_per_pi", cells_per_pi)


def cells_per_pi_param(default):
    """The field ``cells_per_pi`` of a study's parameters (:func:`~hertzpetsc.errors.param`), K as
    :func:`check_cells_per_pi` takes it."""
    from .resources import MAX_UNKNOWNS
    return param(default, "the grid h = pi / cells_per_pi", lo=4, hi=MAX_UNKNOWNS // 2)


class ProfileGrid:
    """The uniform grid of [0, 2 pi) with step h = pi/K, restricted to odd profiles, on a communicator.

    With ``parity = +1`` the profiles are even instead (u_{2K-j} = u_j, unknowns u_0 .. u_K); with ``parity = 0``
    they have no symmetry (unknowns u_0 .. u_{2K-1}: the whole period; the waves of mass patterns of three or more
    beads, where n -> -n exchanges bead types); ``length`` replaces 2 pi by another period. With ``dirichlet`` (even
    profiles only) the profile lives on the line and vanishes beyond +-length/2 instead of being periodic: the
    solitary wave of :mod:`hertzpetsc.solitary` (on a period, sum_j R_j = 0 for eq. adr and its Jacobian would be
    singular).
    """

    def __init__(self, cells_per_pi: int, comm: PETSc.Comm, parity: int = -1, length: float = 2 * math.pi,
                 dirichlet: bool = False) -> None:
        self.K = check_cells_per_pi(cells_per_pi)
        if parity not in (-1, 0, 1):
            raise ParameterError("parity", parity, "must be -1 (odd profiles), +1 (even) or 0 (no symmetry)")
        if dirichlet and parity < 0:
            raise ParameterError("dirichlet", dirichlet, "is only available for even profiles (parity +1)")
        self.parity, self.dirichlet, self.comm = parity, dirichlet, comm
        self.h = 0.5 * check_real("length", length, "the period", 0.0) / self.K
        self.offset = 1 if parity < 0 else 0          # unknown index = grid index - offset
        self.size = self.K - 1 if parity < 0 else (self.K + 1 if parity > 0 else 2 * self.K)
        self.n_half = self.K + 1 if parity else 2 * self.K      # values of a half profile (xi_half)
        # The PETSc default layout, fixed once so that every Vec and Mat of this grid shares it.
        self._template = PETSc.Vec().createMPI(self.size, comm=self.comm)
        self.rstart, self.rend = self._template.getOwnershipRange()

    def xi_half(self) -> np.ndarray:
        """Points xi_j = j h, j = 0..K (the half period [0, pi] on which profiles are stored); the whole period
        (j = 0 .. 2K-1) when the profiles have no symmetry."""
        return np.arange(self.n_half) * self.h

    def create_vec(self) -> PETSc.Vec:
        return self._template.duplicate()

    def owned_points(self) -> np.ndarray:
        """Grid indices j of the unknowns owned by this rank."""
        return np.arange(self.rstart, self.rend, dtype=np.int64) + self.offset

    def fold(self, g: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Map full-grid indices g (any integers) to (unknown index, sign); for odd profiles sign 0 where u
        vanishes (xi = 0, pi), -1 on the second half period."""
        if self.dirichlet:
            j = np.abs(np.asarray(g))
            return np.minimum(j, self.K).astype(np.int64), np.where(j <= self.K, 1.0, 0.0)
        r = np.mod(g, 2 * self.K)
        if self.parity == 0:
            return r.astype(np.int64), np.ones(np.shape(g))
        j = np.where(r <= self.K, r, 2 * self.K - r)
        if self.parity > 0:
            return j.astype(np.int64), np.ones(np.shape(g))
        sign = np.where(r < self.K, 1.0, -1.0)
        sign[(r == 0) | (r == self.K)] = 0.0
        idx = np.where(sign != 0.0, j - 1, 0)
        return idx.astype(np.int64), sign

    def half_profile(self, vec: PETSc.Vec) -> np.ndarray:
        """The profile on the half period (K+1 values; zeros at both ends if odd; the whole period's 2K values
        without symmetry) as a numpy array on every rank."""
        out = np.zeros(self.n_half)
        out[self.offset:self.offset + self.size] = gathered(vec)
        return out

    def vec_from_half_profile(self, values: ArrayLike) -> PETSc.Vec:
        """A distributed Vec holding the odd profile whose values on [0, pi] are ``values`` (K+1 numbers)."""
        values = np.asarray(values, dtype=float)
        if values.shape != (self.n_half,):
            raise ParameterError("profile", f"array of shape {values.shape}",
                                 f"must have {self.n_half} values on [0, {'pi' if self.parity else '2 pi'}) for "
                                 f"cells_per_pi = {self.K}")
        vec = self.create_vec()
        vec.setArray(values[self.rstart + self.offset:self.rend + self.offset])
        return vec

