"""Floquet multipliers modulo shifts of travelling waves (paper section 3.5).

F_q = S R(script-T(q); 0) around X^(q)(t); on N beads with q = 2 pi m / N, F_q^N = Phi_q^m, so
rho(Phi_q) = rho(F_q)^(N/m) and the wave is unstable iff rho(F_q) > 1. F_q is symplectic (eigenvalues in
quadruplets lambda, 1/lambda, conj), so rho(F_q) >= 1.

Two routes: :func:`dense_multipliers` (all 2N multipliers, LAPACK's dgeev on the assembled F_q, as the paper;
N up to a few hundred) and :func:`dominant_multipliers` (SLEPc Krylov-Schur on the matrix-free shell operator,
the nev multipliers of largest magnitude, options prefix ``floquet_``: -floquet_eps_nev, -floquet_eps_ncv,
-floquet_eps_tol, -floquet_eps_type ...). Translation and time shift give multipliers at 1 with Jordan partners
(Galilean boost, amplitude): four trivial multipliers, which an orbit that is off by epsilon splits by about
sqrt(epsilon); :func:`trivial_multipliers` identifies them. A :class:`Spectrum` is the result: the
multipliers, which are trivial, rho and the verdict.

Options: the prefix ``floquet_`` holds the flow of the variational equations (``-floquet_ts_rtol`` ...) and the
eigensolver (``-floquet_eps_nev`` ...).
"""
import math
import time
from dataclasses import dataclass

import numpy as np

from .chain import IntegrationTolerances
from .errors import ConvergenceError, ParameterError
from .tangent import MonodromyModShift, TangentFlow

FLOQUET_PREFIX = "floquet_"
N_TRIVIAL = 4
# Stability criterion: an O(eps) orbit error splits double multipliers by O(sqrt(eps)); with eps ~ 1e-10 (refined
# E plus the flow's error) that is ~1e-5, and 1e-4 keeps a factor 10.
TOL_RHO = 1e-4
# The flow of the spectra along the refined waves (as tight as the refinement's).
FLOQUET_TOLERANCES = IntegrationTolerances(rtol=1e-14, atol=1e-16)


class DenseFloquet:
    """The dense monodromy of orbits on one chain: one TS with 2N tangent vectors, configured once (prefix
    ``floquet_``), serving every orbit of a scan."""

    def __init__(self, spec, comm, tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX):
        self.flow = TangentFlow(spec, 2 * spec.N, comm, tolerances, prefix)

    def set_spec(self, spec):
        """Follow the chain to another of the same layout (e.g. a driven chain at another driving frequency)."""
        self.flow.set_spec(spec)

    def monodromy(self, orbit, shift=True, T=None):
        """Assembled S R(T; 0) (``shift``) or R(T; 0), 2N x 2N, on every rank; T defaults to script-T."""
        T = orbit.T if T is None else T
        return self.flow.monodromy_mod_shift(orbit.x, T)[0] if shift else self.flow.resolvent(orbit.x, T)[0]

    def spectrum(self, orbit, tol_rho=None):
        """All 2N multipliers of F_q as a :class:`Spectrum`."""
        return Spectrum(dense_multipliers(self.monodromy(orbit)), True, TOL_RHO if tol_rho is None else tol_rho)

    def destroy(self):
        self.flow.destroy()


def dense_monodromy(orbit, comm, tolerances=FLOQUET_TOLERANCES, shift=True, prefix=FLOQUET_PREFIX, T=None):
    """One-off :meth:`DenseFloquet.monodromy`."""
    dense = DenseFloquet(orbit.spec, comm, tolerances, prefix)
    try:
        return dense.monodromy(orbit, shift, T)
    finally:
        dense.destroy()


def dense_multipliers(F):
    """All eigenvalues of a dense monodromy matrix (LAPACK dgeev), sorted by decreasing modulus."""
    lam = np.linalg.eigvals(F)
    return lam[np.argsort(-np.abs(lam), kind="stable")]


def trivial_multipliers(lam, n=N_TRIVIAL):
    """Indices of the ``n`` multipliers closest to 1 (translation, time shift and their Jordan partners)."""
    return np.argsort(np.abs(np.asarray(lam) - 1.0), kind="stable")[:n]


def spectral_radius(lam, exclude_trivial=True):
    """rho over the multipliers, leaving out the trivial ones (whose splitting is numerical, not dynamical)."""
    lam = np.asarray(lam)
    if exclude_trivial and len(lam) > N_TRIVIAL:
        lam = np.delete(lam, trivial_multipliers(lam))
    return float(np.max(np.abs(lam)))


@dataclass
class Spectrum:
    """Multipliers of F_q (sorted by decreasing modulus) with the trivial ones identified, and the verdict.

    ``complete``: all 2N multipliers (dense route) or only the dominant ones (SLEPc); the trivial multipliers are
    only identified, and left out of rho, in a complete spectrum.
    """

    multipliers: np.ndarray
    complete: bool
    tol_rho: float = TOL_RHO
    n_trivial: int = N_TRIVIAL       # 0 for orbits without symmetry multipliers (driven chains)

    @property
    def trivial(self):
        return trivial_multipliers(self.multipliers, self.n_trivial) if self.complete else np.zeros(0, dtype=int)

    @property
    def rho(self):
        lam = np.asarray(self.multipliers)
        if self.complete and self.n_trivial and len(lam) > self.n_trivial:
            lam = np.delete(lam, self.trivial)
        return float(np.max(np.abs(lam)))

    @property
    def trivial_spread(self):
        """max |mu - 1| over the trivial multipliers (their numerical splitting), nan if not identified."""
        t = self.trivial
        return float(np.max(np.abs(self.multipliers[t] - 1))) if len(t) else math.nan

    @property
    def outside(self):
        """Multipliers with |mu| > 1 + tol_rho."""
        return int(np.sum(np.abs(self.multipliers) > 1 + self.tol_rho))

    @property
    def unstable(self):
        return self.rho - 1 > self.tol_rho

    def growth(self, T):
        """ln(rho) / script-T, the growth per unit time of the most unstable mode."""
        return growth_rate(self.rho, T)


@dataclass
class EigenResult:
    """Dominant multipliers from SLEPc and the work it took."""

    values: np.ndarray
    vectors: list
    converged: int
    iterations: int
    products: int
    wall_time: float


class DominantFloquet:
    """The ``nev`` multipliers of largest magnitude of F = S R(T; 0) by SLEPc Krylov-Schur on the matrix-free
    operator (:class:`~hertzpetsc.tangent.MonodromyModShift`), for orbits of one chain; the operator and the EPS
    (prefix ``floquet_``: -floquet_eps_nev, -floquet_eps_ncv, -floquet_eps_tol, -floquet_eps_type ...) are
    configured once.

    ``ncv``: subspace dimension (default max(2 nev + 20, 60), capped at 2N; clustered multipliers on the unit
    circle need a generous subspace: the default ncv converged nothing); ``tol``: relative tolerance.
    """

    def __init__(self, spec, comm, nev=10, tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX, ncv=None,
                 tol=1e-10, shift=1):
        from slepc4py import SLEPc
        dim = 2 * spec.N
        if not (isinstance(nev, (int, np.integer)) and 1 <= nev <= dim):
            raise ParameterError("nev", nev, f"must be an integer in [1, 2N] = [1, {dim}]")
        self.prefix, self.dim = prefix, dim
        self.op = MonodromyModShift(spec, np.zeros((spec.N, 2)), 1.0, comm, tolerances, prefix, shift)
        self.A = self.op.create_mat()
        eps = self.eps = SLEPc.EPS().create(comm=self.op.flow.base.comm)
        eps.setOperators(self.A)
        eps.setOptionsPrefix(prefix)
        eps.setProblemType(SLEPc.EPS.ProblemType.NHEP)
        eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
        eps.setWhichEigenpairs(SLEPc.EPS.Which.LARGEST_MAGNITUDE)
        eps.setDimensions(nev=nev, ncv=min(dim, max(2 * nev + 20, 60) if ncv is None else ncv))
        eps.setTolerances(tol=tol, max_it=500)
        eps.setFromOptions()
        self.nev = eps.getDimensions()[0]
        if self.nev > dim:
            self.destroy()
            raise ParameterError("-%seps_nev" % prefix, self.nev, f"must not exceed the dimension 2N = {dim}")

    def set_spec(self, spec):
        """Follow the chain to another of the same layout (e.g. a driven chain at another driving frequency)."""
        self.op.flow.set_spec(spec)

    def solve(self, orbit, initial_space=None, keep_vectors=False):
        """The dominant multipliers around ``orbit`` (an :class:`EigenResult`); ``initial_space``: PETSc Vecs
        (e.g. the previous branch point's eigenvectors) to warm-start Krylov-Schur. ConvergenceError if fewer
        than nev pairs converge."""
        t0 = time.perf_counter()
        op, eps, A = self.op, self.eps, self.A
        op.set_orbit(orbit.x, orbit.T)
        products0 = op.products
        eps.setOperators(A)
        if initial_space:
            eps.setInitialSpace(initial_space)
        eps.solve()
        nconv = eps.getConverged()
        if nconv < self.nev:
            raise ConvergenceError("Floquet eigensolver (prefix -%s)" % self.prefix,
                                   f"{nconv} of {self.nev} multipliers converged ({eps.getConvergedReason()})",
                                   **({"q": float(orbit.q)} if hasattr(orbit, "q") else {"T": float(orbit.T)}))
        vals, vecs = [], []
        for i in range(self.nev):
            vals.append(eps.getEigenvalue(i))
            if keep_vectors:
                vr = A.createVecRight()
                eps.getEigenvector(i, vr)
                vecs.append(vr)
        vals = np.array(vals)
        order = np.argsort(-np.abs(vals), kind="stable")
        return EigenResult(values=vals[order], vectors=[vecs[i] for i in order] if vecs else [], converged=nconv,
                           iterations=eps.getIterationNumber(), products=op.products - products0,
                           wall_time=time.perf_counter() - t0)

    def destroy(self):
        self.eps.destroy()
        self.A.destroy()
        self.op.destroy()


def dominant_multipliers(orbit, nev=10, comm=None, tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX,
                         initial_space=None, keep_vectors=False, ncv=None, tol=1e-10):
    """One-off :meth:`DominantFloquet.solve` (ParameterError if nev exceeds the dimension 2N)."""
    solver = DominantFloquet(orbit.spec, comm, nev, tolerances, prefix, ncv, tol)
    try:
        return solver.solve(orbit, initial_space, keep_vectors)
    finally:
        solver.destroy()


def growth_rate(rho, T):
    """Growth per unit time ln(rho(F_q)) / script-T of the most unstable mode."""
    return math.log(rho) / T
