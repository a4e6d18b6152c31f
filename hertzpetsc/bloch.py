"""Floquet multipliers modulo shifts from Bloch sectors of the wave's cell, over the wave's shortest time symmetry
(section 3.5; :mod:`hertzpetsc.symmetry`).

A travelling wave with q = 2 pi m / N on N beads (periodic, eq. pbcl) repeats every M = N / gcd(m, N) beads, so its
variational equations have M-periodic coefficients and F_q = S R(script-T; 0) commutes with the shift by M beads.
Splitting the perturbations into Bloch waves y_{n+M} = e^{i theta} y_n, theta_l = 2 pi l / g (g = N / M cells)
makes F_q block diagonal; and on the cell, whose m' = m / g wavelengths are coprime with M, the k-bead shift over
the time script-T / m' is a symmetry too. So

    spec(F_q on N beads) = union over l of { e^{-i j theta_l} mu^{m'} : mu in spec(G_theta_l) },

G_theta = S_theta^k R_theta(script-T / m'; 0) the map of the M-bead cell with twisted boundary y_M = e^{i theta} y_0
(the k-bead shift carries the same twist), k m' = 1 + j M. The coefficients are real, so G_{-theta} = conj(G_theta):
only l = 0, ..., floor(g/2) are integrated; theta = 0 and pi are real sectors (real tangents), the others carry a
complex tangent u + i w as two real tangents (PETSc is a real build here). One TS run per sector integrates the
orbit and the 2M columns -- or, when there are several complex sectors and the response over T stays within a cell,
one run of 2M real columns on three cells gives every sector (:class:`~hertzpetsc.tangent.CellPropagator`).

Why not Krylov on the whole chain: for N = 1000 about 600 unstable multipliers crowd annuli of nearly equal
moduli (the 10 largest differ by 1e-5 relative) and Krylov-Schur on the shell operator does not separate them.
The sectors give every multiplier; the dominant ones are then checked on the full chain, matrix-free, by the
residuals ||F Y - lambda Y|| of the tiled Bloch modes (:func:`bloch_residuals`, two shell products per pair, all in
one integration).
SLEPc started from those modes (:func:`seeded_dominant_multipliers`, prefix ``floquet_``) confirms them on
chains of a few hundred beads (45 products at N = 80, 120 at N = 300), but at N = 1000 it did not converge in
13 minutes either: the start vector does not help Krylov-Schur rank Ritz values that close.
"""
import math
import time
from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

from .chain import Chain, ChainIntegrator
from .errors import ParameterError
from .floquet import FLOQUET_PREFIX, FLOQUET_TOLERANCES, TOL_RHO, Spectrum, dominant_multipliers
from .model import ChainSpec
from .symmetry import WaveSymmetry
from .tangent import LOCAL_RESPONSE, CellPropagator, MonodromyModShift


def check_cell(N, M):
    """L = N / M for a chain of N beads made of cells of M beads; ParameterError naming N otherwise."""
    if not (isinstance(N, (int, np.integer)) and N >= M and N % M == 0):
        raise ParameterError("N", N, f"the chain length must be a positive multiple of the wave's period M = {M} "
                                     "beads (N = L M, L >= 1)")
    return N // M


def sector_angles(L):
    """theta_j = 2 pi j / L for the integrated sectors j = 0, ..., floor(L/2)."""
    return [2 * math.pi * j / L for j in range(L // 2 + 1)]


def real_sector(theta):
    """theta = 0 or pi: the twist is real (+-1) and real tangents suffice."""
    return abs(math.sin(theta)) < 1e-14


class TwistedChain(Chain):
    """eq. nc on M beads with tangents under the twisted boundary y_{n+M} = e^{i theta} y_n.

    ``complex_modes``: tangent 2p is the real part u of complex mode p, tangent 2p + 1 its imaginary part w (any
    theta); otherwise the tangents are real and theta must be 0 or pi (twist +-1). The orbit itself is M-periodic.
    ``theta`` is an attribute: one chain (and its TS) serves every sector of its kind.
    """

    def __init__(self, spec, n_tangent, comm, complex_modes=True, theta=0.0):
        if spec.boundary != "periodic":
            raise ParameterError("boundary", spec.boundary, "Bloch sectors need a periodic cell")
        spec.model.require_uniform_masses("the Bloch decomposition")
        super().__init__(spec, comm, n_tangent=int(n_tangent))
        self.complex_modes = complex_modes
        self.n_modes = int(n_tangent) // 2 if complex_modes else int(n_tangent)
        self.theta = float(theta)


class BlochSectors:
    """Dense twisted-cell maps G_theta = S_theta^k R_theta(T; 0), one TS run (2M columns) per sector, for cells of
    any size: a chain and a TS per (cell size, real or complex), built on first use (options prefix ``floquet_``)."""

    def __init__(self, model, comm, tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX):
        self.model, self.comm, self.tolerances, self.prefix = model, comm, tolerances, prefix
        self._solvers = {}
        self.runs = 0
        self.propagated = 0          # orbits whose sectors came from the cell propagator

    def configure(self):
        """Build a small solver now, so that the ``floquet_ts_*`` options are read and checked before any run."""
        self._solver(2 * self.comm.getSize() + 1, False)

    def _solver(self, M, complex_modes):
        key = (M, complex_modes)
        if key not in self._solvers:
            chain = TwistedChain(ChainSpec(self.model, M), (4 if complex_modes else 2) * M, self.comm, complex_modes)
            integrator = ChainIntegrator(chain, self.tolerances, self.prefix)
            self._solvers[key] = (chain, integrator, chain.create_state())
        return self._solvers[key]

    @PETSc.Log.EventDecorator("hz_bloch_sector")
    def monodromy(self, x0, T, theta, shift=1):
        """G_theta (2M x 2M, index 2n + c; complex unless theta is 0 or pi) around the orbit from the M-bead state
        ``x0`` (M, 2), over T, with the k = ``shift`` bead twisted shift."""
        x0 = np.asarray(x0, dtype=float)
        M = len(x0)
        complex_modes = not real_sector(theta)
        ch, integrator, Z = self._solver(M, complex_modes)
        ch.theta = float(theta)
        z = np.zeros((M, ch.dof))
        z[:, :2] = x0
        k = np.arange(2 * M)
        if complex_modes:
            cols = z[:, 2:].reshape(M, 2 * M, 2, 2)              # bead, column, (u, w), (y, ydot)
            cols[k // 2, k, 0, k % 2] = 1.0                       # u = e_k, w = 0
        else:
            cols = z[:, 2:].reshape(M, 2 * M, 2)                  # bead, column, (y, ydot)
            cols[k // 2, k, k % 2] = 1.0
        ch.set_from_array(Z, z)
        integrator.integrate(Z, 0.0, T, dt=integrator.initial_step)   # the same first step whatever ran before
        out = ch.gather(Z)[:, 2:]
        if complex_modes:
            out = out.reshape(M, 2 * M, 2, 2)
            R = (out[:, :, 0, :] + 1j * out[:, :, 1, :]).transpose(0, 2, 1).reshape(2 * M, 2 * M)
        else:
            R = out.reshape(M, 2 * M, 2).transpose(0, 2, 1).reshape(2 * M, 2 * M)
        self.runs += 1
        return twisted_shift(R, theta, shift)

    def monodromies(self, x0, T, thetas, shift=1, among=None):
        """G_theta for several twists around one orbit, in the order of ``thetas`` (a generator): from the cell
        propagator (:class:`~hertzpetsc.tangent.CellPropagator`: one run of 2M real columns on three cells) when it
        is cheaper than the twisted runs of the twists ``among`` (default ``thetas``; the whole set when the caller
        deals them to ranks, so that every rank takes the same route: two complex sectors or more) and the orbit's
        response stays within a cell (checked first on the edge beads' 4 columns); else :meth:`monodromy` for
        each."""
        x0 = np.asarray(x0, dtype=float)
        M = len(x0)
        prop = None
        among = thetas if among is None else among
        if thetas and sum(1 for theta in among if not real_sector(theta)) >= 2 and M >= 4:
            prop = self._propagate(x0, T)
        for theta in thetas:
            yield twisted_shift(prop.twisted(theta), theta, shift) if prop else self.monodromy(x0, T, theta, shift)

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
            if isinstance(solver, CellPropagator):
                solver.destroy()
                continue
            chain, integrator, Z = solver
            Z.destroy()
            integrator.destroy()
            chain.destroy()
        self._solvers = {}


def twisted_shift(R, theta, shift):
    """G_theta = S_theta^k R_theta from the twisted resolvent R (2M x 2M): (S^k y)_n = y_{n+k}, the rows that wrap
    across the seam times the twist (cos theta for the real sectors theta = 0, pi)."""
    M = len(R) // 2
    G = np.roll(R, -2 * shift, axis=0)
    if theta != 0.0:
        G[2 * (M - shift):] = G[2 * (M - shift):] * (math.cos(theta) if real_sector(theta) else np.exp(1j * theta))
    return G


@dataclass
class BlochResult:
    """All 2N multipliers of F_q on N = L M beads, sorted by decreasing modulus, with their sectors.

    M is the wave's cell (beads), L = N / M the number of cells; ``sector[i]`` is l in 0..L-1 (theta_l = 2 pi l / L);
    ``modes`` holds, for the ``n_modes`` largest multipliers, (lambda, l, v) with v the 2M complex cell eigenvector
    (unit 2-norm); ``runs`` the TS runs (sectors integrated), ``columns`` the tangent columns integrated (2M per
    sector), ``time`` the integration time of each run (script-T / m'); ``propagated``: the sectors came instead
    from one run of 2M real columns on three cells (:class:`~hertzpetsc.tangent.CellPropagator`).
    """

    N: int
    M: int
    L: int
    values: np.ndarray
    sector: np.ndarray
    modes: list
    runs: int
    columns: int
    wall_time: float
    time: float = 0.0
    propagated: bool = False

    def sector_values(self, j):
        return self.values[self.sector == j]


def sector_solver(model, comm, split="sectors", tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX):
    """The :class:`BlochSectors` that :func:`bloch_multipliers` uses for ``split`` (each sector on one rank, or
    distributed over ``comm``), to be built once and reused for several wavenumbers."""
    if split not in ("sectors", "beads"):
        raise ParameterError("split", split, "must be 'sectors' or 'beads'")
    sectors = BlochSectors(model, PETSc.COMM_SELF if split == "sectors" else comm, tolerances, prefix)
    sectors.configure()
    return sectors


def bloch_multipliers(orbit, N, comm, tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX, split="sectors",
                      n_modes=0, sectors=None):
    """All 2N multipliers of F_q on N beads (a multiple of ``orbit.N``) for the wave ``orbit`` repeated, from the
    sectors of its cell over its shortest time symmetry (module docstring).

    ``split="sectors"``: the sectors are dealt round-robin to the ranks of ``comm``, each integrated on one rank (no
    communication inside a run, the same arithmetic on any number of ranks); ``"beads"``: every sector on all ranks
    of ``comm`` (the cell's DMDA distributed). ``n_modes``: keep the eigenvectors of that many dominant multipliers
    (for :func:`tile_mode`). ``sectors``: a :func:`sector_solver` for this split to reuse (one is built and freed
    otherwise). The result is the same on every rank.
    """
    L0 = check_cell(N, orbit.N)
    if split not in ("sectors", "beads"):
        raise ParameterError("split", split, "must be 'sectors' or 'beads'")
    if not (isinstance(n_modes, (int, np.integer)) and 0 <= n_modes <= 2 * N):
        raise ParameterError("n_modes", n_modes, f"must be an integer in [0, 2N] = [0, {2 * N}]")
    t0 = time.perf_counter()
    sym = WaveSymmetry(N, orbit.m * L0)
    M, L, mc, k, jj = sym.M, sym.g, sym.m_cell, sym.k, sym.j
    x0, delta = orbit.x[:M], sym.delta(orbit.T)
    thetas = sym.sectors()
    size, rank = comm.getSize(), comm.getRank()
    mine = [l for l in range(len(thetas)) if split == "beads" or l % size == rank]
    own = sectors is None
    if own:
        sectors = sector_solver(orbit.spec.model, comm, split, tolerances, prefix)
    local, propagated0 = [], sectors.propagated
    try:
        for l, G in zip(mine, sectors.monodromies(x0, delta, [thetas[l] for l in mine], k, among=thetas)):
            mu, V = np.linalg.eig(G)
            lam = np.exp(-1j * jj * thetas[l]) * mu.astype(complex) ** mc
            top = np.argsort(-np.abs(lam), kind="stable")[:n_modes]
            local.append((l, lam, [(lam[i], V[:, i] / np.linalg.norm(V[:, i])) for i in top]))
        propagated = sectors.propagated > propagated0
    finally:
        if own:
            sectors.destroy()
    if split == "sectors" and size > 1:
        parts = comm.tompi4py().allgather((local, propagated))
        local = [item for part, _ in parts for item in part]
        propagated = any(used for _, used in parts)
    local.sort(key=lambda item: item[0])
    values, sector, modes = [], [], []
    for l, lam, top in local:
        values.append(lam)
        sector.append(np.full(len(lam), l))
        modes += [(v, l, vec) for v, vec in top]
        if 0 < 2 * l < L:                                       # theta_{L-l} = -theta_l: the conjugate block
            values.append(np.conj(lam))
            sector.append(np.full(len(lam), L - l))
            modes += [(np.conj(v), L - l, np.conj(vec)) for v, vec in top]
    values, sector = np.concatenate(values), np.concatenate(sector)
    order = np.argsort(-np.abs(values), kind="stable")
    modes.sort(key=lambda mode: -abs(mode[0]))
    return BlochResult(N=N, M=M, L=L, values=values[order], sector=sector[order], modes=modes[:n_modes],
                       runs=len(thetas), columns=2 * M * len(thetas), wall_time=time.perf_counter() - t0, time=delta,
                       propagated=bool(propagated))


class SymmetricFloquet:
    """All 2N multipliers of F_q around waves on N beads, from their cells' sectors over their shortest time
    symmetry (:func:`bloch_multipliers` with N = the orbit's own length): the fast route of the scans, on one rank
    (``comm``, COMM_SELF in the scans); the sector flows are built once per cell size (prefix ``floquet_``)."""

    def __init__(self, model, comm, tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX):
        self.comm = comm
        self.sectors = BlochSectors(model, comm, tolerances, prefix)
        self.sectors.configure()

    def spectrum(self, orbit, tol_rho=TOL_RHO):
        return Spectrum(bloch_multipliers(orbit, orbit.N, self.comm, sectors=self.sectors).values, True, tol_rho)

    def destroy(self):
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
        real_sector = j == 0 or 2 * j == L
        if 2 * j > L or (real_sector and lam.imag < 0):
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


def seed_vectors(spec, pairs, comm):
    """One PETSc start vector in the N-bead chain layout: the sum of Re Y + Im Y over the pairs, each normalised."""
    ch = Chain(spec, comm)
    v = ch.create_state()
    s = np.zeros((spec.N, 2))
    for _, Y in pairs:
        w = Y.real + Y.imag
        s += w / np.linalg.norm(w)
    ch.set_from_array(v, s)
    ch.destroy()
    return [v]


def seeded_dominant_multipliers(orbit, bloch, nev=10, comm=None, tolerances=FLOQUET_TOLERANCES,
                                prefix=FLOQUET_PREFIX, ncv=None, tol=1e-8):
    """SLEPc Krylov-Schur (prefix ``floquet_``) on the full-chain shell, started from the Bloch modes.

    ``bloch``: a :class:`BlochResult` with at least ``nev`` modes. Krylov-Schur iterates on one start vector,
    so the tiled modes are summed into one (:func:`seed_vectors`), which lies in the dominant invariant subspace
    up to the flow's error; default subspace ``ncv`` = 2 nev + 10 (-floquet_eps_ncv overrides). Converges in a
    few restarts for N up to a few hundred beads; not at N = 1000 (see the module docstring). ``tol`` must
    exceed the accuracy of the modes, i.e. of the flow: with the paper's rtol 1e-12 their residuals are ~1e-9,
    so the default is 1e-8 (-floquet_eps_tol overrides). The seed does not stop Krylov-Schur from finding a
    larger multiplier the Bloch sectors missed: any component along it is amplified by every product.
    """
    if len(bloch.modes) < nev:
        raise ParameterError("nev", nev, f"the Bloch result keeps {len(bloch.modes)} modes; ask for at most that "
                                         "many (bloch_multipliers(n_modes=...))")
    seed = seed_vectors(orbit.spec, real_pairs(bloch.modes[:nev], bloch.L), comm)
    try:
        return dominant_multipliers(orbit, nev, comm, tolerances, prefix, initial_space=seed,
                                    ncv=ncv if ncv is not None else min(2 * orbit.N, 2 * nev + 10), tol=tol)
    finally:
        for v in seed:
            v.destroy()

