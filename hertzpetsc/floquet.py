"""Floquet multipliers modulo shifts of travelling waves (paper section 3.5).

F_q = S R(script-T(q); 0) around X^(q)(t); on N beads with q = 2 pi m / N, F_q^N = Phi_q^m, so
rho(Phi_q) = rho(F_q)^(N/m) and the wave is unstable iff rho(F_q) > 1. F_q is symplectic (eigenvalues in
quadruplets lambda, 1/lambda, conj), so rho(F_q) >= 1.

Two routes: :func:`dense_multipliers` (all 2N multipliers, LAPACK's dgeev on the assembled F_q, as the paper;
N up to a few hundred) and :func:`dominant_multipliers` (SLEPc Krylov-Schur on the matrix-free shell operator,
the nev multipliers of largest magnitude, options prefix ``floquet_``: -floquet_eps_nev, -floquet_eps_ncv,
-floquet_eps_tol, -floquet_eps_type ...). Translation and time shift give multipliers at 1 with Jordan partners
(Galilean boost, amplitude): four trivial multipliers, which an orbit that is off by epsilon splits by about
sqrt(epsilon); :func:`trivial_multipliers` identifies them.
"""
import math
from dataclasses import dataclass

import numpy as np

from .chain import CHAIN_PREFIX
from .errors import ConvergenceError, ParameterError
from .tangent import MonodromyModShift, TangentFlow

FLOQUET_PREFIX = "floquet_"
N_TRIVIAL = 4


def dense_monodromy(params, x0, T, comm=None, tolerances=None, shift=True):
    """Assembled S R(T; 0) (``shift``) or R(T; 0), 2N x 2N, on every rank (2N tangent vectors at once)."""
    flow = TangentFlow(params, 2 * params.N, comm, tolerances)
    try:
        return flow.monodromy_mod_shift(x0, T)[0] if shift else flow.resolvent(x0, T)[0]
    finally:
        flow.destroy()


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
class EigenResult:
    """Dominant multipliers from SLEPc and the work it took."""

    values: np.ndarray
    vectors: list
    converged: int
    iterations: int
    products: int
    wall_time: float


def dominant_multipliers(params, x0, T, nev=10, comm=None, tolerances=None, prefix=FLOQUET_PREFIX,
                         chain_prefix=CHAIN_PREFIX, initial_space=None, keep_vectors=False, ncv=None,
                         tol=1e-10):
    """The ``nev`` multipliers of largest magnitude of F = S R(T; 0), by SLEPc on the matrix-free operator.

    ``initial_space``: PETSc Vecs (e.g. the previous branch point's eigenvectors) to warm-start Krylov-Schur.
    ``ncv``: subspace dimension (default max(2 nev + 20, 60), capped at 2N; -floquet_eps_ncv overrides);
    ``tol``: Krylov-Schur relative tolerance (-floquet_eps_tol overrides).
    Raises ParameterError if nev exceeds the dimension 2N, ConvergenceError if fewer than nev pairs converge.
    """
    import time

    from slepc4py import SLEPc
    dim = 2 * params.N
    if not (isinstance(nev, (int, np.integer)) and 1 <= nev <= dim):
        raise ParameterError("nev", nev, f"must be an integer in [1, 2N] = [1, {dim}]")
    t0 = time.perf_counter()
    op = MonodromyModShift(params, x0, T, comm, tolerances, chain_prefix)
    A = op.create_mat()
    eps = SLEPc.EPS().create(comm=op.flow.base.comm)
    try:
        eps.setOperators(A)
        eps.setOptionsPrefix(prefix)
        eps.setProblemType(SLEPc.EPS.ProblemType.NHEP)
        eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
        eps.setWhichEigenpairs(SLEPc.EPS.Which.LARGEST_MAGNITUDE)
        # clustered multipliers on the unit circle need a generous subspace (the default ncv converged nothing)
        eps.setDimensions(nev=nev, ncv=min(dim, max(2 * nev + 20, 60) if ncv is None else ncv))
        eps.setTolerances(tol=tol, max_it=500)
        if initial_space:
            eps.setInitialSpace(initial_space)
        eps.setFromOptions()
        nev_eff = eps.getDimensions()[0]
        if nev_eff > dim:
            raise ParameterError("-%seps_nev" % prefix, nev_eff, f"must not exceed the dimension 2N = {dim}")
        eps.solve()
        nconv = eps.getConverged()
        if nconv < nev_eff:
            raise ConvergenceError("Floquet eigensolver (prefix -%s)" % prefix,
                                   f"{nconv} of {nev_eff} multipliers converged ({eps.getConvergedReason()})",
                                   T=float(T))
        vals, vecs = [], []
        for i in range(nev_eff):
            vals.append(eps.getEigenvalue(i))
            if keep_vectors:
                vr = A.createVecRight()
                eps.getEigenvector(i, vr)
                vecs.append(vr)
        vals = np.array(vals)
        order = np.argsort(-np.abs(vals), kind="stable")
        return EigenResult(values=vals[order], vectors=[vecs[i] for i in order] if vecs else [], converged=nconv,
                           iterations=eps.getIterationNumber(), products=op.products,
                           wall_time=time.perf_counter() - t0)
    finally:
        eps.destroy()
        A.destroy()
        op.destroy()


def growth_rate(rho, T):
    """Growth per unit time ln(rho(F_q)) / script-T of the most unstable mode."""
    return math.log(rho) / T
