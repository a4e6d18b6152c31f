"""The point spectrum of the compacton window map G (:mod:`hertzpetsc.compacton_window`; section 3.3 and the
Discussion): the Jordan block at 1 and the dominant multipliers by SLEPc on a weighted shell.

V''(r) vanishes exactly for r >= 0, so a bead whose bonds stay open during the period is in exact free flight;
ordering the window as (front buffer, core, rear buffer), D_Y G is exactly block lower-triangular with nilpotent
transport blocks (a truncated shift composed with free flight), hence spec(D_Y G) = {0} U spec(core block),
independent of the buffers. On the infinite chain, in the space weighted by exp(eta n) (heavier ahead), the
essential spectrum is the disk |mu| <= exp(-eta) and the rest is spec(core). Krylov-Schur (:class:`WindowStability`,
EPS prefix ``cstab_``) is run on the weighted operator W D_Y G W^-1, W = diag(exp(eta (j - j_ref))), whose transport
part has norm exp(-eta): without the weight the nilpotent blocks' pseudospectrum fills a disk of radius
~ tol^(1/L) and SLEPc accepts spurious multipliers. The multiplier 1 is a Jordan block (translation v1 = the vector
field, (J - 1) v2 = v1): only the pair's mean is accurate, its split is ~ sqrt(integration error).
"""
import time
from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

from .assembly import gathered
from .errors import ConvergenceError, callbacks_raise, check_integer, check_real
from .floquet import Spectrum, largest_magnitude

STABILITY_PREFIX = "cstab_"
DEFAULT_ETA = 2.5


def sorted_eig(J):
    """Eigenvalues (LAPACK dgeev) and right eigenvectors, by decreasing modulus. The vectors are back-transformed
    from dgeev's balancing and may be wrong (:func:`eigenvector`)."""
    lam, V = np.linalg.eig(J)
    order = np.argsort(-np.abs(lam), kind="stable")
    return lam[order], V[:, order]


def kernel_vector(A):
    """The unit right singular vector of A's smallest singular value (A's kernel when A is singular), scaled so
    that its entry of largest modulus is real and positive."""
    x = np.linalg.svd(A)[2][-1].conj()
    i = int(np.argmax(np.abs(x)))
    return x * (abs(x[i]) / x[i])


def eigenvector(J, mu):
    """The right eigenvector of J for the simple multiplier mu: :func:`kernel_vector` of J - mu I.

    Not dgeev's: behind the solitary wave (Delta = 0) the rear bonds are closed by doubly exponentially small
    amounts, so the rear beads' columns of J are tiny but nonzero; dgeev's balancing then scales them by huge
    factors instead of isolating them, and the back-transformed vector of mu_3 is nearly a rear-bead unit vector
    with |J v - mu v| ~ |mu| |v|. The singular vector's residual is at round-off."""
    return kernel_vector(J - mu * np.eye(J.shape[0]))


def split_jordan_pair(lam):
    """(mean, split, the other multipliers): the two multipliers nearest 1 are the Jordan pair."""
    lam = np.asarray(lam)
    near = np.argsort(np.abs(lam - 1.0), kind="stable")[:2]
    pair = lam[near]
    rest = np.delete(lam, near)
    return complex(pair.mean()), float(abs(pair[0] - pair[1])), rest[np.argsort(-np.abs(rest), kind="stable")]


@dataclass
class JordanCheck:
    """The Jordan block at 1: |J v1 - v1| / |v1|, |(J - 1) v2 - v1| / |v1|, the right vectors v1, v2 and the left
    vectors u1, u2 with u_i . v_j = delta_ij (so delta = (u1.delta) v1 + (u2.delta) v2 + a remainder in the other
    modes' span)."""

    translation: float
    generalized: float
    v1: np.ndarray
    v2: np.ndarray
    u1: np.ndarray
    u2: np.ndarray


def jordan_check(window, J, Y, gap):
    n = J.shape[0]
    A = J - np.eye(n)
    v1 = window.vector_field(Y, gap)
    v2 = np.linalg.lstsq(A, v1, rcond=None)[0]
    v2 -= (v2 @ v1) / (v1 @ v1) * v1
    nv1 = np.linalg.norm(v1)
    # left vectors: u2 spans the left kernel of A; u1 solves A^T u1 = u2 (up to the left kernel)
    u2 = kernel_vector(A.T)
    u2 = u2 / (u2 @ v2)
    u1 = np.linalg.lstsq(A.T, u2, rcond=None)[0]
    u1 -= (u1 @ v2) * u2
    return JordanCheck(float(np.linalg.norm(J @ v1 - v1) / nv1), float(np.linalg.norm(A @ v2 - v1) / nv1),
                       v1, v2, u1, u2)


def window_spectrum(window, Y, gap, multipliers=None):
    """(J = D_Y G at Y, its multipliers (``multipliers(J)``; default :func:`sorted_eig`'s), the Jordan pair's mean and
    split and the other multipliers (:func:`split_jordan_pair`), the :class:`JordanCheck`)."""
    _, J, _ = window.jacobian(Y, gap)
    lam = sorted_eig(J)[0] if multipliers is None else multipliers(J)
    return (J, lam) + split_jordan_pair(lam) + (jordan_check(window, J, Y, gap),)


def exponential_weight(M, eta, j_ref):
    """Diagonal of W = diag(exp(eta (j - j_ref))) on the bead-major state (heavier ahead)."""
    return np.repeat(np.exp(eta * (np.arange(M) - j_ref)), 2)


class WeightedWindowOperator:
    """W D_Y G W^-1 as a ``Mat.createPython`` context: one tangent integration per product."""

    def __init__(self, window, Y, gap, weight):
        self.window, self.Y, self.gap, self.w = window, np.asarray(Y, float), float(gap), np.asarray(weight)
        self.products = 0

    def mult(self, mat, x, y):
        out = self.w * self.window.apply(self.Y, self.gap, gathered(x) / self.w)
        lo, hi = y.getOwnershipRange()
        y.getArray()[:] = out[lo:hi]
        self.products += 1


class WindowStability:
    """Dominant multipliers of the window map by SLEPc Krylov-Schur (largest magnitude) on the weighted shell,
    EPS prefix ``cstab_`` (``-cstab_eps_*``); ``nev`` multipliers are asked for (they must lie above exp(-eta) to
    be meaningful: below, the transport part's pseudospectrum)."""

    def __init__(self, window, nev=3, eta=DEFAULT_ETA, tol=1e-12, prefix=STABILITY_PREFIX):
        nev = check_integer("-nev", nev, 1, "the number of multipliers", window.dim,
                            f"(the window map has dimension 2M = {window.dim})")
        eta = check_real("-eta", eta, f"the weight's rate (exp(eta M) finite, M = {window.M})", 0.0,
                         700.0 / window.M, lo_open=False, hi_open=False)
        self.window, self.nev, self.eta, self.prefix = window, nev, eta, prefix
        self.eps = largest_magnitude(window.comm, prefix, self.nev, min(window.dim, max(2 * self.nev + 1,
                                                                                        self.nev + 15)), tol)

    def solve(self, Y, gap, j_ref):
        """The converged multipliers (at least nev) as a :class:`~hertzpetsc.floquet.Spectrum` whose work holds
        their residual errors (in its order), the products, iterations and eta."""
        w = self.window
        ctx = WeightedWindowOperator(w, Y, gap, exponential_weight(w.M, self.eta, j_ref))
        A = PETSc.Mat().createPython([w.dim, w.dim], ctx, comm=w.comm)
        A.setUp()
        t0 = time.perf_counter()
        try:
            self.eps.setOperators(A)
            with callbacks_raise():
                self.eps.solve()
            nconv = self.eps.getConverged()
            if nconv < self.eps.getDimensions()[0]:
                raise ConvergenceError(f"window EPS (prefix -{self.prefix}eps_)", int(self.eps.getConvergedReason()),
                                       converged=nconv)
            vals = np.array([complex(self.eps.getEigenvalue(i)) for i in range(nconv)])
            errs = np.array([self.eps.computeError(i) for i in range(nconv)])
        finally:
            A.destroy()
        order = np.argsort(-np.abs(vals), kind="stable")
        return Spectrum(vals[order], False, work=dict(errors=errs[order], products=ctx.products, eta=self.eta,
                                                      iterations=self.eps.getIterationNumber(),
                                                      wall_time=time.perf_counter() - t0))

    def destroy(self):
        self.eps.destroy()
