"""Floquet multipliers modulo shifts of travelling waves (paper section 3.5).

F_q = S R(script-T(q); 0) around X^(q)(t); on N beads with q = 2 pi m / N, F_q^N = Phi_q^m, so
rho(Phi_q) = rho(F_q)^(N/m) and the wave is unstable iff rho(F_q) > 1. F_q is symplectic (eigenvalues in
quadruplets lambda, 1/lambda, conj), so rho(F_q) >= 1.

Every route is a :class:`FloquetSolver` with one call signature, chosen by object (the shape of BifurcationKit's
Floquet.jl): ``solver.spectrum(orbit, tol_rho=None, nev=None)`` returns a :class:`Spectrum`, sorted by decreasing
modulus in one place. Routes: :class:`DenseFloquet` (all 2N by LAPACK, as the paper), :class:`DominantFloquet`
(SLEPc Krylov-Schur, largest magnitude, matrix-free), :class:`hertzpetsc.bloch.SymmetricFloquet` (all 2N from the
Bloch sectors of the wave's cell, any N = L M) and :class:`hertzpetsc.slow.DeflatedSectors` (symmetry multipliers
deflated). Translation and time shift give four trivial multipliers at 1 (Jordan blocks), which an orbit off by
epsilon splits by about sqrt(epsilon): :func:`trivial_multipliers` identifies them (a deflated route knows its own).
The routes by name: :func:`hertzpetsc.roles.floquet_route`; the role ``floquet_``: :data:`hertzpetsc.roles.REGISTRY`.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Optional, Sequence

import numpy as np

from .chain import IntegrationTolerances
from .errors import (ConvergenceError, ParameterError, callbacks_raise, check_flag, check_instance, check_integer,
                     check_real)
from .model import ChainSpec
from .options import user_set
from .tangent import MonodromyModShift, TangentFlow

if TYPE_CHECKING:
    from petsc4py import PETSc
    from slepc4py import SLEPc

    from .model import ChainSpec
    from .waves import Orbit

FLOQUET_PREFIX = "floquet_"
N_TRIVIAL = 4
# Stability criterion: an O(eps) orbit error splits double multipliers by O(sqrt(eps)); with eps ~ 1e-10 (refined
# E plus the flow's error) that is ~1e-5, and 1e-4 keeps a factor 10.
TOL_RHO = 1e-4
# The radius route's closure (DominantFloquet.closed): the Krylov space has magnified whatever lies outside the
# radius r against the cluster inside (radius rho_c) by at least 1 / CLOSURE, (r / rho_c)^products >= 1 / CLOSURE.
CLOSURE = 1e-4
# The flow of the spectra along the refined waves (as tight as the refinement's).
FLOQUET_TOLERANCES = IntegrationTolerances(rtol=1e-14, atol=1e-16)


def dense_multipliers(F):
    """All eigenvalues of a dense monodromy matrix (LAPACK dgeev), sorted by decreasing modulus."""
    lam = np.linalg.eigvals(F)
    return lam[np.argsort(-np.abs(lam), kind="stable")]


def trivial_multipliers(lam, n=N_TRIVIAL):
    """Indices of the ``n`` multipliers closest to 1 (translation, time shift and their Jordan partners)."""
    return np.argsort(np.abs(np.asarray(lam) - 1.0), kind="stable")[:n]


def spectral_radius(lam, exclude_trivial=True):
    """rho over the multipliers, leaving out the trivial ones (whose splitting is numerical, not dynamical)."""
    return Spectrum(lam, exclude_trivial).rho


@dataclass
class Spectrum:
    """Multipliers of F_q, sorted by decreasing modulus on construction, the trivial ones identified (``known``: a
    mask of deflated symmetry multipliers; else the ``n_trivial`` nearest 1 of a ``complete`` spectrum, four for a
    travelling wave, none for a driven chain) and left out of rho,
    and the verdict. Bloch routes: ``sector`` l of each multiplier (theta_l = 2 pi l / L, M the cell's beads),
    ``modes`` (mu, l, cell eigenvector) of the dominant ones. ``work``: runs, columns, products, wall_time ..."""

    multipliers: np.ndarray
    complete: bool
    tol_rho: float = TOL_RHO
    known: np.ndarray = None
    n_trivial: int = N_TRIVIAL       # symmetry multipliers at 1 of a complete spectrum (0: driven chains)
    sector: np.ndarray = None
    M: int = 0
    L: int = 1
    modes: list = field(default_factory=list)
    work: dict = field(default_factory=dict)

    def __post_init__(self):
        lam = np.asarray(self.multipliers)
        order = np.argsort(-np.abs(lam), kind="stable")          # largest magnitude first, for every route
        self.multipliers = lam[order]
        for name in ("known", "sector"):
            if getattr(self, name) is not None:
                setattr(self, name, np.asarray(getattr(self, name))[order])

    @property
    def trivial(self) -> np.ndarray:
        if self.known is not None:
            return np.nonzero(self.known)[0]
        if not (self.complete and self.n_trivial):
            return np.zeros(0, dtype=int)
        return trivial_multipliers(self.multipliers, self.n_trivial)

    @property
    def rho(self) -> float:
        t = self.trivial
        lam = np.delete(self.multipliers, t) if len(self.multipliers) > len(t) else self.multipliers
        return float(np.max(np.abs(lam)))

    @property
    def trivial_spread(self) -> float:
        """max |mu - 1| over the trivial multipliers (their numerical splitting), nan if not identified."""
        t = self.trivial
        return float(np.max(np.abs(self.multipliers[t] - 1))) if len(t) else math.nan

    @property
    def outside(self) -> int:
        """Multipliers with |mu| > 1 + tol_rho."""
        return int(np.sum(np.abs(self.multipliers) > 1 + self.tol_rho))

    def growth(self, T: float) -> float:
        """ln(rho) / script-T, the growth per unit time of the most unstable mode."""
        return math.log(self.rho) / T


class FloquetSolver:
    """The one call signature of the Floquet routes: :meth:`spectrum`. A route implements ``_spectrum(orbit, tol_rho,
    nev)`` (a :class:`Spectrum`) and :meth:`destroy`; its solvers are configured once, when it is built."""

    def spectrum(self, orbit: "Orbit", tol_rho: Optional[float] = None, nev: Optional[int] = None) -> "Spectrum":
        """The multipliers of F_q = S R(script-T; 0) around ``orbit`` (an :class:`~hertzpetsc.waves.Orbit`), the
        ``nev`` largest if given; ``tol_rho``: the stability threshold of the verdict (default :data:`TOL_RHO`)."""
        if nev is not None and not (isinstance(nev, (int, np.integer)) and 1 <= nev <= 2 * orbit.N):
            raise ParameterError("nev", nev, f"must be an integer in [1, 2N] = [1, {2 * orbit.N}]")
        t0 = time.perf_counter()
        spec = self._spectrum(orbit, TOL_RHO if tol_rho is None else tol_rho, nev)
        spec.work.setdefault("wall_time", time.perf_counter() - t0)
        if nev is None or nev >= len(spec.multipliers):
            return spec
        return replace(spec, multipliers=spec.multipliers[:nev], complete=False, known=None if spec.known is None
                       else spec.known[:nev], sector=None if spec.sector is None else spec.sector[:nev])

    def destroy(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.destroy()


class DenseFloquet(FloquetSolver):
    """The dense monodromy of orbits on one chain: one TS with 2N tangent vectors, configured once (prefix
    ``floquet_``), serving every orbit of a scan; ``with DenseFloquet(...) as d:`` frees it."""

    def __init__(self, spec: ChainSpec, comm: PETSc.Comm, tolerances: IntegrationTolerances = FLOQUET_TOLERANCES,
                 prefix: str = FLOQUET_PREFIX) -> None:
        check_instance("spec", spec, ChainSpec, "a ChainSpec")
        self.flow = TangentFlow(spec, 2 * spec.N, comm, tolerances, prefix)

    def monodromy(self, orbit: Orbit, shift: bool = True, T: Optional[float] = None) -> np.ndarray:
        """Assembled S R(T; 0) (``shift``) or R(T; 0), 2N x 2N, on every rank; T defaults to script-T."""
        T = orbit.T if T is None else T
        return self.flow.monodromy_mod_shift(orbit.x, T)[0] if shift else self.flow.resolvent(orbit.x, T)[0]

    def _spectrum(self, orbit, tol_rho, nev):
        return Spectrum(np.linalg.eigvals(self.monodromy(orbit)), True, tol_rho, work=dict(columns=2 * orbit.N))

    def set_spec(self, spec: ChainSpec) -> None:
        """Follow the chain to another of the same layout (e.g. a driven chain at another driving frequency)."""
        self.flow.set_spec(spec)

    def destroy(self) -> None:
        self.flow.destroy()


class DominantFloquet(FloquetSolver):
    """The ``nev`` multipliers of largest magnitude of F = S R(T; 0) by SLEPc Krylov-Schur on the matrix-free
    operator (:class:`~hertzpetsc.tangent.MonodromyModShift`), for orbits of one chain; the operator and the EPS
    (prefix ``floquet_``: -floquet_eps_nev, -floquet_eps_ncv, -floquet_eps_tol, -floquet_eps_type ...) are
    configured once.

    ``ncv``: subspace dimension (default max(2 nev + 20, 60), capped at 2N: clustered multipliers on the unit circle
    need it); ``tol``: relative tolerance; ``warm``: start from the previous solve's eigenvectors (a scan in q);
    ``shift``: the shift S in beads (1: F_q of a travelling wave; 0: the plain monodromy R(T; 0) of a driven chain);
    ``vectors``: keep the eigenvectors of the last solve (:attr:`vectors`, (2N, nev) on every rank, in the order of
    the returned multipliers).

    ``radius`` r (or ``-floquet_radius``, which takes precedence; also settable per solve, :attr:`radius`): every
    multiplier outside the circle |mu| = r instead of the ``nev`` largest (``nev`` then caps their number). The EPS
    accepts only Ritz values outside r (a region, the complement of the disk: :func:`largest_magnitude`) and stops
    when every Ritz value of its Krylov space (dimension ncv, after at least one restart) outside r has converged:
    the spectrum is then complete outside r to that space's resolution (``work['resolved']``). It is unresolved
    when ``nev`` multipliers outside r converged (more may lie outside) or the restarts ran out with Ritz values
    outside r not converged. Krylov methods converge to a multiplier at the rate |mu| / rho_c per product, rho_c the
    radius of the cluster inside (a damped chain's phonons: e^{-gamma T / 2}), so a multiplier just outside r shows
    as a Ritz value outside r only after about ln(1/eps) / ln(r / rho_c) products: with ``cluster`` = rho_c given
    (:attr:`cluster`, per solve) the test also waits for (rho_c / r)^products <= :data:`CLOSURE` (r <= rho_c
    refused), so r between the cluster and the unit circle decides the cost.
    """

    def __init__(self, spec: ChainSpec, comm: PETSc.Comm, nev: int = 10,
                 tolerances: IntegrationTolerances = FLOQUET_TOLERANCES, prefix: str = FLOQUET_PREFIX,
                 ncv: Optional[int] = None, tol: float = 1e-10, warm: bool = False, shift: int = 1,
                 vectors: bool = False, radius: Optional[float] = None) -> None:
        dim = 2 * check_instance("spec", spec, ChainSpec, "a ChainSpec").N
        if not (check_integer("nev", nev, 1, "the number of multipliers") <= dim):
            raise ParameterError("nev", nev, f"must be an integer in [1, 2N] = [1, {dim}]")
        if ncv is not None:
            ncv = check_integer("ncv", ncv, nev, "the subspace dimension", dim, f"(from nev to 2N = {dim})")
        tol = check_real("tol", tol, "the eigensolver's relative tolerance", 0.0, 1.0)
        self.prefix, self.warm, self.start, self.previous = prefix, check_flag("warm", warm), [], []
        self.keep_vectors, self.vectors = check_flag("vectors", vectors), None
        from petsc4py import PETSc
        given = PETSc.Options(prefix).getString("radius") if user_set(prefix, ("radius",)) else None
        if given is not None:
            try:
                given = float(given)
            except ValueError:
                pass
            given = radius = check_real("-%sradius" % prefix, given, "the radius outside which every multiplier is "
                                        "wanted", 0.0)
        elif radius is not None:
            radius = check_real("radius", radius, "the radius outside which every multiplier is wanted", 0.0)
        self.fixed_radius = given                # the option's, which a caller's default does not replace
        self.radius, self.cluster, self._products0 = radius, None, 0
        # the radius route's slow modes (slow_eigenpairs): set per solve by the caller that knows them, unless
        # -floquet_slow_modes 0
        self.slow, self.use_slow = None, PETSc.Options(prefix).getBool("slow_modes", True)
        self._deflation = []                     # the deflation space's Vecs of the solve under way
        self.op = MonodromyModShift(spec, np.zeros((spec.N, 2)), 1.0, comm, tolerances, prefix, shift)
        self.A = self.op.create_mat()
        # the radius route stops with fewer than nev converged: below the whole space (SLEPc's eigenvectors of such
        # a stop after the Krylov space spanned everything are not the pairs'; check_eigenpairs would refuse them)
        cap = dim if radius is None else max(nev, dim - 1)
        self.eps = largest_magnitude(self.op.base.comm, prefix, nev,
                                     min(cap, max(2 * nev + 20, 60)) if ncv is None else ncv, tol,
                                     None if radius is None else self)
        self.nev = self.eps.getDimensions()[0]
        if self.nev > dim:
            self.destroy()
            raise ParameterError("-%seps_nev" % prefix, self.nev, f"must not exceed the dimension 2N = {dim}")

    def set_spec(self, spec: ChainSpec) -> None:
        """Follow the chain to another of the same layout (e.g. a driven chain at another driving frequency)."""
        self.op.set_spec(spec)

    def start_from(self, vectors: Sequence[PETSc.Vec]) -> None:
        """PETSc Vecs of the chain's layout (e.g. Bloch modes) to start the next solve from (owned by the caller)."""
        self.start = list(vectors)

    def _release(self):
        for v in self.previous:
            v.destroy()
        self.previous = []

    def _spectrum(self, orbit, tol_rho, nev):
        if nev is not None and nev > self.nev:
            raise ParameterError("nev", nev, f"the eigensolver was configured for {self.nev} multipliers")
        op, eps, A = self.op, self.eps, self.A
        op.set_orbit(orbit.x, orbit.T)
        products0 = op.products
        eps.setOperators(A)
        if self.start or self.previous:
            eps.setInitialSpace(self.start or self.previous)
        self.start = []
        found = None
        if self.radius is not None:
            if self.cluster is not None and not self.radius > self.cluster:
                raise ParameterError("-%sradius" % self.prefix, self.radius, "the radius must exceed the modulus of "
                                     f"the cluster of multipliers inside, {self.cluster:.6g}")
            self.eps.getRG().setEllipseParameters(0.0, float(self.radius), 1.0)
            if self.slow is not None:
                found = slow_eigenpairs(op, self.slow, self.radius, self.cluster, self.eps.getTolerances()[0],
                                        self.nev)
                self._deflate(found[1])
            self._products0 = op.products
        try:
            with callbacks_raise():
                eps.solve()
        finally:
            if found is not None:
                self._deflate(None)
        nconv = eps.getConverged()
        if self.radius is not None:
            return self._outside(orbit, tol_rho, nconv, products0, found)
        if nconv < self.nev:
            raise ConvergenceError("Floquet eigensolver (prefix -%s)" % self.prefix,
                                   f"{nconv} of {self.nev} multipliers converged ({eps.getConvergedReason()})",
                                   **({"q": float(orbit.q)} if hasattr(orbit, "q") else {"T": float(orbit.T)}))
        values = np.array([eps.getEigenvalue(i) for i in range(self.nev)])
        if self.keep_vectors:                  # (2N, nev) complex on every rank, in the Spectrum's order
            from .assembly import gathered
            vr, vi = A.createVecRight(), A.createVecRight()
            try:
                columns = []
                for i in np.argsort(-np.abs(values), kind="stable"):
                    eps.getEigenvector(int(i), vr, vi)
                    columns.append(gathered(vr) + 1j * gathered(vi))
            finally:
                vr.destroy()
                vi.destroy()
            self.vectors = np.array(columns).T
        if self.warm:
            self._release()
            for i in np.argsort(-np.abs(values), kind="stable"):
                self.previous.append(A.createVecRight())
                eps.getEigenvector(int(i), self.previous[-1])
        return Spectrum(values, False, tol_rho, work=dict(converged=nconv, iterations=eps.getIterationNumber(),
                                                          products=op.products - products0))

    def closed(self, eps: "SLEPc.EPS", its: int, max_it: int, nconv: int, nev: int) -> int:
        """The stopping test of the radius route (:func:`largest_magnitude`): converged when every Ritz value of the
        Krylov space outside the radius has converged (after at least one restart), or when ``nev`` have (the cap:
        unresolved); diverged when the restarts ran out. Decided on rank 0 (the projected problem is replicated)."""
        from slepc4py import SLEPc
        reason = SLEPc.EPS.ConvergedReason
        ds = eps.getDS()
        n = ds.getDimensions()[0]
        A = ds.getMat(SLEPc.DS.MatType.A)
        try:
            H = A.getDenseArray()[:n, :n].copy()
        finally:
            ds.restoreMat(SLEPc.DS.MatType.A, A)
        outside = int(np.sum(np.abs(np.linalg.eigvals(H)) > self.radius)) if n else 0
        products = self.op.products - self._products0
        resolved = self.cluster is None or products * math.log(self.radius / self.cluster) >= -math.log(CLOSURE)
        if nconv >= nev:
            out = reason.CONVERGED_TOL
        elif its >= 2 and resolved and nconv >= outside:
            out = reason.CONVERGED_USER
        elif its >= max_it:
            out = reason.DIVERGED_ITS
        else:
            out = reason.ITERATING
        return self.op.base.comm.tompi4py().bcast(out, root=0)

    def _outside(self, orbit, tol_rho, nconv, products0, found=None):
        """The multipliers outside the radius of the last solve (with the slow modes ``found`` before it, which the
        solve deflated), their eigenvectors kept; ``work['resolved']``: the stopping test closed the spectrum
        outside r (module docstring of the class)."""
        from slepc4py import SLEPc
        eps, A, r = self.eps, self.A, float(self.radius)
        values = np.array([eps.getEigenvalue(i) for i in range(nconv)], dtype=complex)
        keep = [int(i) for i in np.argsort(-np.abs(values), kind="stable") if abs(values[i]) > r]
        reason = eps.getConvergedReason()
        resolved = reason == SLEPc.EPS.ConvergedReason.CONVERGED_USER or \
            (reason == SLEPc.EPS.ConvergedReason.CONVERGED_TOL and len(keep) < nconv)
        from .assembly import gathered
        vr, vi = A.createVecRight(), A.createVecRight()
        try:
            columns = []
            for i in keep:
                eps.getEigenvector(i, vr, vi)
                columns.append(gathered(vr) + 1j * gathered(vi))
        finally:
            vr.destroy()
            vi.destroy()
        values = values[keep]
        vectors = np.array(columns).T if columns else np.zeros((A.getSize()[0], 0), complex)
        slow = 0
        if found is not None and len(found[0]):
            slow = len(found[0])
            if len(values):
                vectors = self._undeflated(values, vectors, found)
            values, vectors = np.concatenate([found[0], values]), np.concatenate([found[2], vectors], axis=1)
            resolved = resolved and len(values) <= self.nev
        order = np.argsort(-np.abs(values), kind="stable")
        self.vectors = vectors[:, order]
        return Spectrum(values[order], False, tol_rho, work=dict(
            converged=nconv, iterations=eps.getIterationNumber(), products=self.op.products - products0, radius=r,
            resolved=bool(resolved), reason=int(reason), slow=slow,
            krylov_products=self.op.products - self._products0))

    def _undeflated(self, values, W, found):
        """The eigenvectors of F from the deflated solve's (2N, k): SLEPc's lie in the complement of the deflated
        span U (F U = U diag(mu), ``found``), where they are eigenvectors of the projected operator only. With
        g = F w - lambda w = U b (one block product of the k columns), v = w + U a, a_j = b_j / (lambda - mu_j),
        satisfies F v = lambda v."""
        mu, U = found[0], found[2]
        N, k = self.op.spec.N, W.shape[1]
        FW = self.op.apply(np.concatenate([W.real, W.imag], axis=1).reshape(N, 2, 2 * k)).reshape(2 * N, 2 * k)
        G = FW[:, :k] + 1j * FW[:, k:] - W * values
        b = np.linalg.lstsq(U, G, rcond=None)[0]
        return W + U @ (b / (values[None, :] - mu[:, None]))

    def _deflate(self, basis):
        """Make the columns of ``basis`` (2N x m real, orthonormal, on every rank: an invariant subspace of F) the
        EPS's deflation space, or clear it (None): the Krylov space then lives in its complement, whose
        operator has the remaining multipliers of F (the block triangular form of F in [basis, complement])."""
        for v in self._deflation:
            v.destroy()
        self._deflation = []
        if basis is None or not basis.shape[1]:
            self.eps.setDeflationSpace([])
            return
        lo, hi = self.A.getOwnershipRange()
        for j in range(basis.shape[1]):
            v = self.A.createVecRight()
            v.getArray()[:] = basis[lo:hi, j]
            self._deflation.append(v)
        self.eps.setDeflationSpace(self._deflation)

    def destroy(self) -> None:
        self._release()
        for v in self._deflation:
            v.destroy()
        self._deflation = []
        self.eps.destroy()
        self.A.destroy()
        self.op.destroy()


# The slow modes' refinement (slow_eigenpairs): at most this many block products, the basis at most
# SLOW_BASIS x the start's columns (then restarted on the wanted Ritz vectors); the start: R_lin's modes outside the
# radius and as many more as half their number, at least SLOW_MARGIN (the next ones inside, which F may move out).
SLOW_ROUNDS = 30
SLOW_BASIS = 4
SLOW_MARGIN = 4


def _orthonormal(W, against=None, drop=1e-10):
    """An orthonormal basis of the columns of W (real), orthogonalised twice against the orthonormal ``against``
    first; columns that keep less than ``drop`` of their norm are left out."""
    W = np.asarray(W, float)
    if against is not None and against.shape[1]:
        for _ in range(2):
            W = W - against @ (against.T @ W)
    if not W.shape[1]:
        return W
    U, s, _ = np.linalg.svd(W, full_matrices=False)
    return U[:, s > drop * max(1.0, float(np.max(np.linalg.norm(W, axis=0))))] if s.size else U[:, :0]


def slow_eigenpairs(op, slow, radius, cluster, tol, cap, rounds=SLOW_ROUNDS):
    """The multipliers outside ``radius`` that continue the slow modes of the chain linearised about rest (the
    overdamped long waves of a long damped chain, which crowd at 1 within O(1 / N^2): single-vector Krylov needs
    O(N) products to separate them), by a block Davidson iteration on F = ``op``
    (:meth:`~hertzpetsc.tangent.MonodromyModShift.apply`: each round one integration of a block of columns,
    dealt to the ranks), started from ``slow.slow_modes(r0)`` (R_lin's eigenvectors with |mu| > r0, r0 halfway
    in log between ``cluster`` and ``radius``; those outside ``radius`` and :data:`SLOW_MARGIN` or half as many
    more) and expanded by Olsen's correction with the preconditioner
    ``slow.shifted_solve`` = (R_lin - theta I)^-1 (closed form in the sine modes). Rayleigh-Ritz on the basis V
    (orthonormal): the Ritz pairs (theta, u = V s) of V^T F V with |theta| > ``radius``, at most ``cap`` + 1.

    Returns (multipliers (m,), an orthonormal real basis of their eigenvectors' span (2N, m'), the eigenvectors
    (2N, m), complex, unit norm) of the Ritz pairs whose relative residual ||F u - theta u|| / (|theta| ||u||) is
    within ``tol``: an invariant subspace to that residual, which the Krylov stage deflates. The structure only
    speeds the search: whatever it misses or leaves unconverged, the Krylov stage finds."""
    N = op.spec.N
    empty = (np.zeros(0, complex), np.zeros((2 * N, 0)), np.zeros((2 * N, 0), complex))
    r0 = math.sqrt(radius * cluster) if cluster is not None else radius
    mu0, U0 = slow.slow_modes(r0)
    outside = int(np.sum(np.abs(mu0) > radius))
    U0 = U0[:, np.argsort(-np.abs(mu0), kind="stable")[:outside + max(SLOW_MARGIN, outside // 2)]]
    V = _orthonormal(np.concatenate([U0.real, U0.imag], axis=1))
    if not V.shape[1]:
        return empty

    def apply(Y):
        return op.apply(Y.reshape(N, 2, Y.shape[1])).reshape(2 * N, Y.shape[1])
    start, AV = V.shape[1], apply(V)
    for _ in range(rounds):
        theta, S = np.linalg.eig(V.T @ AV)
        order = np.argsort(-np.abs(theta), kind="stable")
        theta, S = theta[order], S[:, order]
        want = np.nonzero(np.abs(theta) > radius)[0][:cap + 1]
        U, W = V @ S[:, want], AV @ S[:, want]
        U_norm = np.linalg.norm(U, axis=0)
        R = W - U * theta[want]
        res = np.linalg.norm(R, axis=0) / (np.abs(theta[want]) * U_norm)
        todo = [j for j in range(len(want)) if res[j] > tol and theta[want[j]].imag >= 0]
        if not todo:
            break
        th = theta[want][todo]
        Mr, Mu = slow.shifted_solve(th, R[:, todo]), slow.shifted_solve(th, U[:, todo])
        e = np.sum(np.conj(U[:, todo]) * Mr, axis=0) / np.sum(np.conj(U[:, todo]) * Mu, axis=0)
        T = e * Mu - Mr                                   # Olsen: (R_lin - theta)^-1 (e u - r), orthogonal to u
        T = np.concatenate([T.real, T.imag[:, np.abs(th.imag) > 0]], axis=1)
        T = T[:, np.all(np.isfinite(T), axis=0)]          # theta on R_lin's spectrum: no correction from it
        T = _orthonormal(T, V)
        if not T.shape[1]:
            break
        if V.shape[1] + T.shape[1] > SLOW_BASIS * start:  # restart on the Ritz vectors of the largest
            keep = S[:, :min(len(theta), max(2 * len(want), start))]
            Q = _orthonormal(np.concatenate([keep.real, keep.imag], axis=1))
            V, AV = V @ Q, AV @ Q
            T = _orthonormal(T, V)
        V, AV = np.concatenate([V, T], axis=1), np.concatenate([AV, apply(T)], axis=1)
    done = [j for j in range(len(want)) if res[j] <= tol]
    if not done:
        return empty
    mu, vec = theta[want][done], U[:, done] / U_norm[done]
    return mu, _orthonormal(np.concatenate([vec.real, vec.imag], axis=1)), vec


def largest_magnitude(comm, prefix, nev, ncv, tol, outside=None):
    """A Krylov-Schur EPS for the multipliers of largest magnitude (the package's one set-up of the dominant routes:
    Floquet, compacton window), configured from the options database under ``prefix`` once. ``outside``: a
    :class:`DominantFloquet` with a radius r: the region |mu| > r (an RG ellipse, complemented; ``-prefix_rg_*``) and
    its stopping test :meth:`DominantFloquet.closed`."""
    from slepc4py import SLEPc
    eps = SLEPc.EPS().create(comm=comm)
    eps.setOptionsPrefix(prefix)
    eps.setProblemType(SLEPc.EPS.ProblemType.NHEP)
    eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
    eps.setWhichEigenpairs(SLEPc.EPS.Which.LARGEST_MAGNITUDE)
    eps.setDimensions(nev=nev, ncv=ncv)
    eps.setTolerances(tol=tol, max_it=500)
    if outside is not None:
        rg = eps.getRG()
        rg.setType(SLEPc.RG.Type.ELLIPSE)
        rg.setEllipseParameters(0.0, float(outside.radius), 1.0)
        rg.setComplement(True)
        eps.setStoppingTest(outside.closed)
    eps.setFromOptions()
    return eps
