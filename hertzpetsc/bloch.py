"""Floquet multipliers modulo shifts from Bloch sectors of the wave's cell, over the wave's shortest time symmetry
(section 3.5), for any mass pattern.

A travelling wave with q = 2 pi m / N on N beads (periodic, eq. pbcl) repeats every M = N / g beads, and on that
cell the shift by k pattern cells over the time script-T / m' is a symmetry (g, m', k, j: :mod:`hertzpetsc.symmetry`):

    spec(F_q on N beads) = union over l of { e^{-i j theta_l} mu^{m'} : mu in spec(G_theta_l) },

G_theta = S_theta^k R_theta(script-T / m'; 0) the map of the M-bead cell (its masses the pattern's) with twisted
boundary y_M = e^{i theta} y_0, theta_l = 2 pi l / g. G_{-theta} = conj(G_theta): only l = 0, ..., floor(g/2) are
integrated (one TS run of the orbit and 2M columns each); theta = 0 and pi take real tangents, the others a complex
tangent u + i w as two real ones (PETSc is a real build here) -- or, when there are several complex sectors and the
response over T stays within a cell, one run of 2M real columns on three cells gives every sector
(:class:`~hertzpetsc.tangent.CellPropagator`). A chain of L copies is the orbit tiled.

Why not Krylov on the whole chain: for N = 1000 about 600 unstable multipliers crowd annuli of nearly equal moduli
and Krylov-Schur on the shell does not separate them, even started from the Bloch modes
(:func:`seeded_dominant_multipliers`: it confirms them up to a few hundred beads). The dominant sector multipliers
are checked on the full chain by the residuals ||F Y - lambda Y|| of the tiled modes (:func:`bloch_residuals`).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from petsc4py import PETSc

from .chain import Chain, IntegrationTolerances
from .errors import ParameterError, check_choice, check_instance, check_integer, check_prefix
from .floquet import FLOQUET_PREFIX, FLOQUET_TOLERANCES, DominantFloquet, FloquetSolver, Spectrum
from .model import ChainSpec, LatticeModel
from .symmetry import real_sector
from .tangent import LOCAL_RESPONSE, CellPropagator, MonodromyModShift, TangentFlow, twisted_resolvent

if TYPE_CHECKING:
    from .chain import IntegrationTolerances
    from .model import LatticeModel


class TwistedChain(Chain):
    """eq. nc on M beads (the orbit M-periodic) with tangents under the twisted boundary y_{n+M} = e^{i theta} y_n;
    ``complex_modes``: tangents 2p, 2p + 1 are Re and Im of complex mode p (any theta), else real (theta 0 or pi).
    ``theta`` is an attribute: one chain (and its TS) serves every sector of its kind."""

    def __init__(self, spec, n_tangent, comm, complex_modes=True, theta=0.0):
        if spec.boundary != "periodic":
            raise ParameterError("boundary", spec.boundary, "Bloch sectors need a periodic cell")
        super().__init__(spec, comm, n_tangent=int(n_tangent))
        self.complex_modes = complex_modes
        self.theta = float(theta)


class BlochSectors:
    """Dense twisted-cell maps G_theta = S_theta^k R_theta(T; 0), one TS run (2M columns) per sector, for cells of
    any size (whole pattern cells): a chain and a TS per (cell size, real or complex), built on first use (options
    prefix ``floquet_``)."""

    def __init__(self, model, comm, tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX):
        self.model, self.comm, self.tolerances, self.prefix = model, comm, tolerances, prefix
        self._solvers = {}
        self.runs = 0
        self.propagated = 0          # orbits whose sectors came from the cell propagator

    def configure(self):
        """Build a small solver now, so that the ``floquet_ts_*`` options are read and checked before any run."""
        p = self.model.cell
        self._solver(p * -(-(2 * self.comm.getSize() + 1) // p), False)

    def _solver(self, M, complex_modes):
        """The tangent flow of the twisted M-bead cell with 2M real or complex columns (built once)."""
        key = (M, complex_modes)
        if key not in self._solvers:
            self._solvers[key] = TangentFlow(ChainSpec(self.model, M), (4 if complex_modes else 2) * M, self.comm,
                                             self.tolerances, self.prefix, lambda spec, comm, n_tangent:
                                             TwistedChain(spec, n_tangent, comm, complex_modes))
        return self._solvers[key]

    @PETSc.Log.EventDecorator("hz_bloch_sector")
    def monodromy(self, x0, T, theta, shift=1):
        """G_theta (2M x 2M, index 2n + c; complex unless theta is 0 or pi) around the orbit from the M-bead state
        ``x0`` (M, 2), over T, with the twisted shift by k = ``shift`` pattern cells."""
        x0 = np.asarray(x0, dtype=float)
        M = len(x0)
        complex_modes = not real_sector(theta)
        flow = self._solver(M, complex_modes)
        flow.aug.theta = float(theta)
        Y = np.eye(2 * M).reshape(M, 2, 2 * M)
        if complex_modes:                                         # columns (u, w) = (e_k, 0) of complex mode k
            Y = np.stack([Y, np.zeros_like(Y)], axis=3).reshape(M, 2, 4 * M)
        R = flow.run(x0, T, Y)[1].reshape(2 * M, -1)
        if complex_modes:
            R = R[:, 0::2] + 1j * R[:, 1::2]
        self.runs += 1
        return self._twisted_shift(R, theta, shift)

    def _twisted_shift(self, R, theta, shift, dR=None):
        """G_theta = S_theta^k R_theta from the twisted resolvent R (2M x 2M): (S^k y)_n = y_{n+kp}, the rows that
        wrap across the seam times the twist (cos theta for the real sectors theta = 0, pi). Given ``dR`` =
        dR_theta/dtheta: dG_theta/dtheta instead (the wrapped rows' twist differentiated too)."""
        M = len(R) // 2
        kb = shift * self.model.cell
        wrap = slice(2 * (M - kb), None)
        if dR is not None:
            G = np.roll(dR, -2 * kb, axis=0).astype(complex)
            G[wrap] = np.exp(1j * theta) * (G[wrap] + 1j * np.roll(R, -2 * kb, axis=0)[wrap])
            return G
        G = np.roll(R, -2 * kb, axis=0)
        if theta != 0.0:
            G[wrap] = G[wrap] * (math.cos(theta) if real_sector(theta) else np.exp(1j * theta))
        return G

    def monodromies(self, x0, T, thetas, shift=1, among=None):
        """G_theta for several twists around one orbit, in the order of ``thetas`` (a generator), by
        :meth:`sector_maps`: through the cell propagator when two or more of the twists ``among`` are complex (default
        ``thetas``; the whole set when the caller deals them to ranks, so that every rank takes the same route)."""
        among = thetas if among is None else among
        maps = self.sector_maps(x0, T, shift, bool(thetas) and sum(not real_sector(theta) for theta in among) >= 2)
        return (maps(theta) for theta in thetas)

    def sector_maps(self, x0, T, shift=1, propagate=True):
        """The function theta -> G_theta around one orbit (any number of twists, e.g. a scan of the infinite chain's
        Bloch parameters with refinements): every twist from one run of the cell propagator
        (:class:`~hertzpetsc.tangent.CellPropagator`: 2M real columns on three cells) when ``propagate`` and the
        response stays within a cell (cells of 4 beads or more; checked first on the edge beads' 4 columns), else
        one twisted run per call."""
        x0 = np.asarray(x0, dtype=float)
        prop = self._propagate(x0, T) if propagate and len(x0) >= 4 else None
        # this orbit's blocks (a later run makes new arrays)
        return SectorMaps(self, x0, T, shift, None if prop is None else prop.blocks)

    @PETSc.Log.EventDecorator("hz_bloch_propagator")
    def _propagate(self, x0, T):
        """The cell propagator around the orbit, or None if the response reaches beyond a cell."""
        M = len(x0)
        if ("propagator", M) not in self._solvers:
            self._solvers[("propagator", M)] = CellPropagator(self.model, M, self.comm, self.tolerances, self.prefix)
        prop = self._solvers[("propagator", M)]
        if prop.reaches(x0, T) > LOCAL_RESPONSE or not prop.run(x0, T).local:
            return None
        self.runs += 1
        self.propagated += 1
        return prop

    def destroy(self):
        for solver in self._solvers.values():
            solver.destroy()
        self._solvers = {}


class SectorMaps:
    """theta -> G_theta around one orbit (:meth:`BlochSectors.sector_maps`) and its twist derivative dG_theta/dtheta:
    exact from the cell propagator's blocks (R_theta is a trigonometric polynomial of degree 1 in theta), else a
    central difference of two twisted runs (the cells whose response leaves the cell)."""

    # the central difference's step in theta: truncation (STEP^2 |G'''|) and the flows' error over 2 STEP both stay
    # near 1e-10 relative for the default flows
    STEP = 1e-5

    def __init__(self, sectors, x0, T, shift, blocks):
        self.sectors, self.x0, self.T, self.shift, self.blocks = sectors, x0, T, shift, blocks

    def __call__(self, theta):
        if self.blocks is None:
            return self.sectors.monodromy(self.x0, self.T, theta, self.shift)
        return self.sectors._twisted_shift(twisted_resolvent(self.blocks, theta), theta, self.shift)

    def derivative(self, theta):
        """dG_theta/dtheta (complex 2M x 2M)."""
        if self.blocks is None:
            return (self(theta + self.STEP) - self(theta - self.STEP)) / (2 * self.STEP)
        Pm, P0, P1 = self.blocks
        R = P0 + np.exp(-1j * theta) * P1 + np.exp(1j * theta) * Pm
        dR = -1j * np.exp(-1j * theta) * P1 + 1j * np.exp(1j * theta) * Pm
        return self.sectors._twisted_shift(R, theta, self.shift, dR)


class SymmetricFloquet(FloquetSolver):
    """All 2N multipliers of F_q around waves on N beads, any mass pattern, from the sectors of their cells over
    their shortest time symmetry (module docstring). ``split="sectors"``: the sectors dealt round-robin to the ranks
    of ``comm``, each on one rank (the same arithmetic on any number of ranks); ``"beads"``: each sector on all ranks.
    ``n_modes``: keep the cell eigenvectors of that many dominant multipliers (``Spectrum.modes``). Sector flows are
    built once per cell size (prefix ``floquet_``); the spectrum is the same on every rank."""

    def __init__(self, model: LatticeModel, comm: PETSc.Comm, tolerances: IntegrationTolerances = FLOQUET_TOLERANCES,
                 prefix: str = FLOQUET_PREFIX, split: str = "sectors", n_modes: int = 0) -> None:
        check_instance("model", model, LatticeModel, "a LatticeModel")
        check_choice("split", split, ("sectors", "beads"))
        check_prefix("prefix", prefix)
        check_instance("tolerances", tolerances, IntegrationTolerances, "an IntegrationTolerances(rtol, atol)")
        self.comm, self.split, self.n_modes = comm, split, check_integer("n_modes", n_modes, 0)
        self.sectors = BlochSectors(model, PETSc.COMM_SELF if split == "sectors" else comm, tolerances, prefix)
        self.sectors.configure()

    @PETSc.Log.EventDecorator("hz_symmetric_floquet")
    def _spectrum(self, orbit, tol_rho, nev):
        if self.n_modes > 2 * orbit.N:
            raise ParameterError("n_modes", self.n_modes, f"must be an integer in [0, 2N] = [0, {2 * orbit.N}]")
        sym = orbit.symmetry
        M, L, mc, k, jj = sym.M, sym.g, sym.m_cell, sym.k, sym.j
        x0, delta, thetas = orbit.x[:M], sym.delta(orbit.T), sym.sectors()
        size, rank = self.comm.getSize(), self.comm.getRank()
        mine = [l for l in range(len(thetas)) if self.split == "beads" or l % size == rank]
        local, propagated0 = [], self.sectors.propagated
        for l, G in zip(mine, self.sectors.monodromies(x0, delta, [thetas[l] for l in mine], k, among=thetas)):
            mu, V = np.linalg.eig(G)
            lam = np.exp(-1j * jj * thetas[l]) * mu.astype(complex) ** mc
            top = np.argsort(-np.abs(lam), kind="stable")[:self.n_modes]
            local.append((l, lam, [(lam[i], V[:, i] / np.linalg.norm(V[:, i])) for i in top]))
        propagated = self.sectors.propagated > propagated0
        if self.split == "sectors" and size > 1:
            parts = self.comm.tompi4py().allgather((local, propagated))
            local = sorted((item for part, _ in parts for item in part), key=lambda item: item[0])
            propagated = any(used for _, used in parts)
        values, sector, modes = [], [], []
        for l, lam, top in local:
            values.append(lam)
            sector.append(np.full(len(lam), l))
            modes += [(v, l, vec) for v, vec in top]
            if 0 < 2 * l < L:                                       # theta_{L-l} = -theta_l: the conjugate block
                values.append(np.conj(lam))
                sector.append(np.full(len(lam), L - l))
                modes += [(np.conj(v), L - l, np.conj(vec)) for v, vec in top]
        modes.sort(key=lambda mode: -abs(mode[0]))
        return Spectrum(np.concatenate(values), True, tol_rho, sector=np.concatenate(sector), M=M, L=L,
                        modes=modes[:self.n_modes], work=dict(runs=len(thetas), columns=2 * M * len(thetas),
                                                              time=delta, propagated=bool(propagated)))

    def destroy(self) -> None:
        self.sectors.destroy()


def tile_mode(vec, j, L):
    """The N-bead complex eigenvector (N, 2) of F_q from the cell eigenvector ``vec`` (2M,) of sector j:
    y_{n+lM} = e^{i l theta_j} y_n."""
    M = len(vec) // 2
    phase = np.exp(2j * math.pi * j * np.arange(L) / L)
    return (phase[:, None, None] * np.asarray(vec).reshape(1, M, 2)).reshape(L * M, 2)


def real_pairs(modes, L):
    """The distinct real invariant subspaces in a mode list: one (lambda, Y) per conjugate pair, Y (N, 2) complex.

    (lambda, j, v) and (conj lambda, L - j, conj v) span the same real space {Re Y, Im Y}; each is written with
    j <= L/2 (and Im lambda >= 0 in the real sectors j = 0, L/2) and kept once.
    """
    out, seen = [], []
    for lam, j, vec in modes:
        real = j == 0 or 2 * j == L
        if 2 * j > L or (real and lam.imag < 0):
            lam, j, vec = np.conj(lam), (L - j) % L, np.conj(vec)
        if any(j == k and abs(lam - mu) <= 1e-12 * abs(lam) for k, mu in seen):
            continue
        seen.append((j, lam))
        out.append((lam, tile_mode(vec, j, L)))
    return out


def bloch_residuals(orbit, pairs, comm, tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX):
    """Relative residuals ||F Y - lambda Y|| / (|lambda| ||Y||) on the full N-bead chain, matrix-free.

    ``orbit``: the tiled wave on N beads, ``pairs`` from :func:`real_pairs`. F is real, so
    F Re Y = Re(lambda Y) and F Im Y = Im(lambda Y): two shell products per pair (one if Y is real), all in one
    integration of the orbit (:meth:`~hertzpetsc.tangent.MonodromyModShift.apply`). Returns (residuals, products).
    """
    parts, targets, owner = [], [], []
    for i, (lam, Y) in enumerate(pairs):
        for part, target in ((Y.real, (lam * Y).real), (Y.imag, (lam * Y).imag)):
            if np.any(part):
                parts.append(part)
                targets.append(target)
                owner.append(i)
    op = MonodromyModShift(orbit.spec, orbit.x, orbit.T, comm, tolerances, prefix)
    try:
        FY = op.apply(np.stack(parts, axis=2)) if parts else np.zeros((orbit.N, 2, 0))
        num = np.zeros(len(pairs))
        for j, i in enumerate(owner):
            num[i] += float(np.sum((FY[:, :, j] - targets[j]) ** 2))
        res = [math.sqrt(num[i]) / (abs(lam) * float(np.linalg.norm(Y))) for i, (lam, Y) in enumerate(pairs)]
        return np.array(res), op.products
    finally:
        op.destroy()


def seeded_dominant_multipliers(orbit, bloch, nev=10, comm=None, tolerances=FLOQUET_TOLERANCES,
                                prefix=FLOQUET_PREFIX, ncv=None, tol=1e-8):
    """SLEPc Krylov-Schur (prefix ``floquet_``) on the full-chain shell, started from the sum of the tiled Bloch modes
    of ``bloch`` (a :class:`SymmetricFloquet` spectrum of ``orbit`` with >= ``nev`` modes; each Re Y + Im Y
    normalised), which lies in the dominant invariant subspace up to the flow's error; ``ncv`` 2 nev + 10 by default.
    ``tol`` must exceed the modes' accuracy (the flow's: ~1e-9 at the paper's rtol), so 1e-8. A larger multiplier
    the sectors missed is still found: any component along it grows with every product."""
    if len(bloch.modes) < nev:
        raise ParameterError("nev", nev, f"the Bloch result keeps {len(bloch.modes)} modes; ask for at most that "
                                         "many (SymmetricFloquet(n_modes=...))")
    solver = DominantFloquet(orbit.spec, comm, nev, tolerances, prefix, min(2 * orbit.N, 2 * nev + 10)
                             if ncv is None else ncv, tol)
    seed = solver.A.createVecRight()
    try:
        s = sum((Y.real + Y.imag) / np.linalg.norm(Y.real + Y.imag) for _, Y in real_pairs(bloch.modes[:nev], bloch.L))
        solver.op.base.set_from_array(seed, s)
        solver.start_from([seed])
        return solver.spectrum(orbit)
    finally:
        seed.destroy()
        solver.destroy()

