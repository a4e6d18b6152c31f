"""Floquet multipliers modulo shifts on long chains by Bloch (Floquet-in-space) decomposition (section 3.5).

A travelling wave (eq. twper) with q = 2 pi m / M repeats every M beads, x_{n+M}(t) = x_n(t). On N = L M beads
(periodic, eq. pbcl) the variational equations of eq. nc then have M-periodic coefficients V''(x_{n+1} - x_n),
so F_q = S R(script-T(q); 0) commutes with the shift by M beads. Splitting the perturbations into Bloch waves
y_{n+M} = e^{i theta} y_n, theta_j = 2 pi j / L (j = 0, ..., L-1), makes F_q block diagonal:

    spec(F_q on N beads) = union over j of spec(F_theta_j),

where F_theta = S_theta R_theta(script-T; 0) is the 2M x 2M (complex) map of an M-bead chain whose tangent
vectors obey the twisted boundary y_M = e^{i theta} y_0, y_{-1} = e^{-i theta} y_{M-1} (the one-bead shift S
carries the same twist). theta = 0 is the M-bead periodic problem itself. The coefficients are real, so
F_{-theta} = conj(F_theta): only j = 0, ..., floor(L/2) are integrated, the other sectors are their conjugates.

PETSc is a real build here, so a complex tangent u + i w is carried as two real tangents (u, w) of the chain
DMDA (:class:`TwistedChain`, the chain's right-hand side with the twist applied to the ghost beads at the
periodic wrap); one TS run per sector integrates the orbit and the 2M columns R_theta e_k.

Why not Krylov on the whole chain: for N = 1000 about 600 unstable multipliers crowd annuli of nearly equal
moduli (the 10 largest differ by 1e-5 relative) and Krylov-Schur on the shell operator does not separate them.
The sectors give every multiplier; the dominant ones are then checked on the full chain, matrix-free, by the
residuals ||F Y - lambda Y|| of the tiled Bloch modes (:func:`bloch_residuals`, two shell products per pair).
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
from .floquet import FLOQUET_PREFIX, FLOQUET_TOLERANCES, dominant_multipliers
from .tangent import MonodromyModShift


def check_cell(N, M):
    """L = N / M for a chain of N beads made of cells of M beads; ParameterError naming N otherwise."""
    if not (isinstance(N, (int, np.integer)) and N >= M and N % M == 0):
        raise ParameterError("N", N, f"the chain length must be a positive multiple of the wave's period M = {M} "
                                     "beads (N = L M, L >= 1)")
    return N // M


def sector_angles(L):
    """theta_j = 2 pi j / L for the integrated sectors j = 0, ..., floor(L/2)."""
    return [2 * math.pi * j / L for j in range(L // 2 + 1)]


class TwistedChain(Chain):
    """eq. nc on M beads with 2k real tangents = k complex tangents u + i w under y_{n+M} = e^{i theta} y_n.

    Tangent 2p is the real part u of complex mode p, tangent 2p + 1 its imaginary part w. The orbit itself is
    M-periodic. ``theta`` is an attribute: one chain (and its TS) serves every sector.
    """

    def __init__(self, spec, n_modes, comm, theta=0.0):
        if spec.boundary != "periodic":
            raise ParameterError("boundary", spec.boundary, "Bloch sectors need a periodic cell")
        spec.model.require_uniform_masses("the Bloch decomposition")
        super().__init__(spec, comm, n_tangent=2 * int(n_modes))
        self.n_modes = int(n_modes)
        self.theta = float(theta)

    def _ghosted(self, X):
        """Ghosted local values with the twist e^{-i theta} (left of bead 0) / e^{i theta} (right of bead M-1)."""
        self.da.globalToLocal(X, self.local)
        a = self.local.getArray().reshape(self.nloc + 2, self.dof)
        if self.theta != 0.0:
            c, s = math.cos(self.theta), math.sin(self.theta)
            t = a[:, 2:].reshape(self.nloc + 2, self.n_modes, 2, 2)     # bead, mode, (u, w), (y, ydot)
            for row, sign, wraps in ((0, -1.0, self.xs == 0), (-1, 1.0, self.xe == self.spec.N)):
                if wraps:
                    u, w = t[row, :, 0, :].copy(), t[row, :, 1, :].copy()
                    t[row, :, 0, :] = c * u - sign * s * w
                    t[row, :, 1, :] = sign * s * u + c * w
        return a


class BlochSectors:
    """Dense F_theta = S_theta R_theta(T; 0) of an M-bead cell, one TS run (2M complex columns) per sector."""

    def __init__(self, spec, comm, tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX):
        self.spec = spec
        self.chain = TwistedChain(spec, 2 * spec.N, comm)
        self.integrator = ChainIntegrator(self.chain, tolerances, prefix)
        self.Z = self.chain.create_state()
        self.runs = 0

    @PETSc.Log.EventDecorator("hz_bloch_sector")
    def monodromy(self, x0, T, theta):
        """F_theta (2M x 2M complex, index 2n + c) around the orbit from the M-bead state ``x0`` (M, 2)."""
        M = self.spec.N
        ch = self.chain
        ch.theta = float(theta)
        z = np.zeros((M, ch.dof))
        z[:, :2] = np.asarray(x0, dtype=float).reshape(M, 2)
        cols = z[:, 2:].reshape(M, 2 * M, 2, 2)                 # bead, column k, (u, w), (y, ydot)
        k = np.arange(2 * M)
        cols[k // 2, k, 0, k % 2] = 1.0                          # u = e_k, w = 0
        ch.set_from_array(self.Z, z)
        self.integrator.integrate(self.Z, 0.0, T, dt=self.integrator.initial_step)   # whatever ran before
        out = ch.gather(self.Z)[:, 2:].reshape(M, 2 * M, 2, 2)
        R = (out[:, :, 0, :] + 1j * out[:, :, 1, :]).transpose(0, 2, 1).reshape(2 * M, 2 * M)
        F = np.roll(R, -2, axis=0)                               # (S y)_n = y_{n+1}
        F[-2:] *= np.exp(1j * theta)                             # y_M = e^{i theta} y_0
        self.runs += 1
        return F

    def destroy(self):
        self.Z.destroy()
        self.integrator.destroy()
        self.chain.destroy()


@dataclass
class BlochResult:
    """All 2N multipliers of F_q on N = L M beads, sorted by decreasing modulus, with their sectors.

    ``sector[i]`` is j in 0..L-1 (theta_j = 2 pi j / L); ``modes`` holds, for the ``n_modes`` largest multipliers,
    (lambda, j, v) with v the 2M complex cell eigenvector (unit 2-norm); ``runs`` the TS runs (sectors
    integrated), ``columns`` the complex tangent columns integrated (2M per sector).
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

    def sector_values(self, j):
        return self.values[self.sector == j]


def sector_solver(spec, comm, split="sectors", tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX):
    """The :class:`BlochSectors` that :func:`bloch_multipliers` uses for ``split`` (each sector on one rank, or
    distributed over ``comm``), to be built once and reused for several wavenumbers."""
    if split not in ("sectors", "beads"):
        raise ParameterError("split", split, "must be 'sectors' or 'beads'")
    return BlochSectors(spec, PETSc.COMM_SELF if split == "sectors" else comm, tolerances, prefix)


def bloch_multipliers(cell, N, comm, tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX, split="sectors",
                      n_modes=0, sectors=None):
    """All multipliers of F_q on N beads from the orbit ``cell`` on the M-bead cell (M = ``cell.N``).

    ``split="sectors"``: the sectors are dealt round-robin to the ranks of ``comm``, each integrated on one
    rank (no communication inside a run, the same arithmetic on any number of ranks); ``"beads"``: every sector
    on all ranks of ``comm`` (the cell's DMDA distributed). ``n_modes``: keep the eigenvectors of that many
    dominant multipliers (for :func:`tile_mode`). ``sectors``: a :func:`sector_solver` for this split to reuse
    (one is built and freed otherwise). The result is the same on every rank.
    """
    params, x0, T = cell.spec, cell.x, cell.T
    M = params.N
    L = check_cell(N, M)
    if split not in ("sectors", "beads"):
        raise ParameterError("split", split, "must be 'sectors' or 'beads'")
    if not (isinstance(n_modes, (int, np.integer)) and 0 <= n_modes <= 2 * N):
        raise ParameterError("n_modes", n_modes, f"must be an integer in [0, 2N] = [0, {2 * N}]")
    x0 = np.asarray(x0, dtype=float)
    if x0.shape != (M, 2):
        raise ParameterError("x0", x0.shape, f"the cell state must have shape (M, 2) = ({M}, 2)")
    t0 = time.perf_counter()
    thetas = sector_angles(L)
    size, rank = comm.getSize(), comm.getRank()
    mine = [j for j in range(len(thetas)) if split == "beads" or j % size == rank]
    own = sectors is None
    if own:
        sectors = sector_solver(params, comm, split, tolerances, prefix)
    local = []
    try:
        for j in mine:
            lam, V = np.linalg.eig(sectors.monodromy(x0, T, thetas[j]))
            top = np.argsort(-np.abs(lam), kind="stable")[:n_modes]
            local.append((j, lam, [(lam[i], V[:, i] / np.linalg.norm(V[:, i])) for i in top]))
    finally:
        if own:
            sectors.destroy()
    if split == "sectors" and size > 1:
        local = [item for part in comm.tompi4py().allgather(local) for item in part]
    local.sort(key=lambda item: item[0])
    values, sector, modes = [], [], []
    for j, lam, top in local:
        values.append(lam)
        sector.append(np.full(len(lam), j))
        modes += [(v, j, vec) for v, vec in top]
        if 0 < 2 * j < L:                                       # theta_{L-j} = -theta_j: the conjugate block
            values.append(np.conj(lam))
            sector.append(np.full(len(lam), L - j))
            modes += [(np.conj(v), L - j, np.conj(vec)) for v, vec in top]
    values, sector = np.concatenate(values), np.concatenate(sector)
    order = np.argsort(-np.abs(values), kind="stable")
    modes.sort(key=lambda mode: -abs(mode[0]))
    return BlochResult(N=N, M=M, L=L, values=values[order], sector=sector[order], modes=modes[:n_modes],
                       runs=len(thetas), columns=2 * M * len(thetas), wall_time=time.perf_counter() - t0)


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
    F Re Y = Re(lambda Y) and F Im Y = Im(lambda Y): two shell products per pair (one if Y is real).
    Returns (residuals, products).
    """
    op = MonodromyModShift(orbit.spec, orbit.x, orbit.T, comm, tolerances, prefix)
    base = op.flow.base
    x, y = base.create_state(), base.create_state()
    res = []
    try:
        for lam, Y in pairs:
            num = 0.0
            for part, target in ((Y.real, (lam * Y).real), (Y.imag, (lam * Y).imag)):
                if not np.any(part):
                    continue
                base.set_from_array(x, part)
                op.mult(None, x, y)
                num += float(np.sum((base.gather(y) - target) ** 2))
            res.append(math.sqrt(num) / (abs(lam) * float(np.linalg.norm(Y))))
        return np.array(res), op.products
    finally:
        x.destroy()
        y.destroy()
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

