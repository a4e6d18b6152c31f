"""Travelling-wave residual E(q) and Gauss-Newton refinement of the initial state (paper section 3.4).

    E(q) = ||S X(script-T) - X(0)||_inf / ||X(0)||_inf,     script-T(q) = q ||u||_inf^((alpha-1)/2)  (eq. invv)

The refinement minimises ||G(X0)||_2^2, G(X0) = S X(script-T; X0) - X0, by Gauss-Newton with the Jacobian
S R(script-T; 0) - I from :class:`~hertzpetsc.tangent.TangentFlow`. That Jacobian is singular at a travelling
wave: translation x_n -> x_n + c and time translation (direction f(X0)) are exact symmetries, and slow modes
(Floquet multipliers near 1) make it nearly singular in a few more directions, with singular values as small as
the residual itself. Steps are therefore restricted to the orthogonal complement of the two symmetry directions
(phase conditions, basis Q) and computed from the SVD of J Q truncated at a relative level; since a residual
evaluation costs one flow and a Jacobian 2N tangent flows, each iteration tries the truncation levels
:data:`TRUNCATIONS` and keeps the step that reduces E most. The dense algebra is done on rank 0 and broadcast,
so every rank applies the same step. As in the paper, the Jacobian is kept across iterations and re-evaluated
only when the steps it gives stop reducing the residual.

Options: the refinement's flows and Gauss-Newton live under the prefix ``shoot_`` (``-shoot_ts_rtol``, ...,
``-shoot_gn_max_it``); E(q) measured with the paper's flow uses the simulations' prefix ``chain_``.
"""
import time
from dataclasses import dataclass, field

import numpy as np
from petsc4py import PETSc

from .chain import CHAIN_PREFIX, Chain, ChainIntegrator, IntegrationTolerances
from .errors import ConvergenceError, ParameterError
from .tangent import TangentFlow

SHOOT_PREFIX = "shoot_"

# The flow used to measure E(q) and to refine: the paper's rtol 1e-12 leaves errors near 1e-9 in X(script-T)
# at some q, which would floor a refined E(q); 1e-14 keeps them below 1e-12.
MEASURE_TOLERANCES = IntegrationTolerances(rtol=1e-14, atol=1e-16)
# The paper's flow (Scilab's rtol 1e-12, atol 1e-14), for E(q) as the paper measured it.
PAPER_TOLERANCES = IntegrationTolerances(rtol=1e-12, atol=1e-14)


class ShiftMap:
    """X0 -> S X(script-T; X0) on a periodic chain, with its own TS (options prefix ``prefix``)."""

    def __init__(self, spec, comm, tolerances, prefix):
        if spec.boundary != "periodic":
            raise ParameterError("boundary", spec.boundary, "travelling waves modulo shifts need a periodic chain")
        self.chain = Chain(spec, comm)
        self.integrator = ChainIntegrator(self.chain, tolerances, prefix)
        self.X = self.chain.create_state()
        self.SX = self.chain.create_state()

    def __call__(self, x0, T):
        """S X(T) as an (N, 2) array on every rank, from the (N, 2) initial state ``x0``."""
        self.chain.set_from_array(self.X, x0)
        self.integrator.integrate(self.X, 0.0, T, dt=self.integrator.initial_step)
        self.chain.shift(self.X, self.SX)
        return self.chain.gather(self.SX)

    def residual(self, orbit):
        """E(q) = ||S X(script-T) - X(0)||_inf / ||X(0)||_inf of an orbit."""
        return relative_residual(orbit.x, self(orbit.x, orbit.T))

    def destroy(self):
        for v in (self.X, self.SX):
            v.destroy()
        self.integrator.destroy()
        self.chain.destroy()


def relative_residual(x0, sxT):
    """E = ||S X(T) - X(0)||_inf / ||X(0)||_inf over positions and velocities."""
    return float(np.max(np.abs(sxT - x0)) / np.max(np.abs(x0)))


def residual_E(orbit, comm, tolerances=PAPER_TOLERANCES, prefix=CHAIN_PREFIX):
    """E(q) of an :class:`~hertzpetsc.waves.Orbit` (one flow over script-T)."""
    smap = ShiftMap(orbit.spec, comm, tolerances, prefix)
    try:
        return smap.residual(orbit)
    finally:
        smap.destroy()


@dataclass
class Refinement:
    """The refined orbit and the history of the Gauss-Newton iteration."""

    orbit: object                          # the refined Orbit
    E_initial: float
    E: float
    r: float                               # relative difference of the last two iterates (paper's r(q))
    iterations: int
    jacobians: int
    history: list = field(default_factory=list)
    sigma_min: float = None                # smallest singular value of the phase-conditioned Jacobian
    wall_time: float = 0.0

    @property
    def x(self):
        return self.orbit.x


def symmetry_complement(chain, x):
    """Orthonormal basis (2N x (2N-2)) of the complement of the translation and time-shift directions at x."""
    N = chain.spec.N
    X, F = chain.create_state(), chain.create_state()
    chain.set_from_array(X, x)
    chain.rhs(None, 0.0, X, F)
    f = chain.gather(F).ravel()
    for v in (X, F):
        v.destroy()
    translation = np.tile([1.0, 0.0], N)
    Q, _ = np.linalg.qr(np.stack([translation, f], axis=1), mode="complete")
    return Q[:, 2:]


# Relative singular-value cut-offs tried at each Gauss-Newton iteration (0: plain least squares on J Q).
TRUNCATIONS = (0.0, 1e-9, 1e-7, 1e-5, 1e-3)


def phase_conditioned_steps(J, g, Q, comm):
    """Candidate steps d = Q c, c the SVD-truncated least-squares solution of J Q c = -g at each level of
    :data:`TRUNCATIONS`; computed on rank 0 and broadcast. Also returns the smallest singular value of J Q."""
    mpi = comm.tompi4py()
    out = None
    if mpi.rank == 0:
        U, sv, Vt = np.linalg.svd(J @ Q, full_matrices=False)
        coef = U.T @ -g
        steps = []
        for cut in TRUNCATIONS:
            keep = sv > cut * sv[0]
            steps.append(Q @ (Vt[keep].T @ (coef[keep] / sv[keep])))
        out = (steps, float(sv[-1]))
    return mpi.bcast(out, root=0)


class Refiner:
    """Gauss-Newton refinement of travelling-wave orbits on one chain (flows built once, prefix ``shoot_``).

    ``tol``: the target E; the iteration limit is ``-<prefix>gn_max_it`` (default ``max_iterations``).
    """

    def __init__(self, spec, comm, tol=1e-10, max_iterations=20, tolerances=MEASURE_TOLERANCES,
                 prefix=SHOOT_PREFIX):
        if not tol > 0:
            raise ParameterError("tol", tol, "the target residual must be positive")
        self.spec, self.tol = spec, tol
        self.max_iterations = PETSc.Options().getInt(prefix + "gn_max_it", max_iterations)
        if self.max_iterations < 1:
            raise ParameterError(f"-{prefix}gn_max_it", self.max_iterations, "must be an integer >= 1")
        self.smap = ShiftMap(spec, comm, tolerances, prefix)
        self.flow = TangentFlow(spec, 2 * spec.N, comm, tolerances, prefix)
        self.comm = comm

    def residual(self, orbit):
        """E(q) of ``orbit`` with the refinement's own flow."""
        return self.smap.residual(orbit)

    @PETSc.Log.EventDecorator("hz_refine")
    def refine(self, orbit):
        """The refined :class:`Refinement` of ``orbit``; :class:`ConvergenceError` if E cannot be brought below
        ``tol`` within the iteration limit."""
        t0 = time.perf_counter()
        N, T, smap, flow = self.spec.N, orbit.T, self.smap, self.flow
        x = np.asarray(orbit.x, dtype=float).reshape(N, 2).copy()
        sx = smap(x, T)
        g = (sx - x).ravel()
        E0 = E = relative_residual(x, sx)
        history, jacobians, J, fresh, r = [E], 0, None, False, float("nan")
        sigma_min = None
        it = 0
        while E > self.tol and it < self.max_iterations:
            if J is None:
                M, _ = flow.monodromy_mod_shift(x, T)
                J = M - np.eye(2 * N)
                Q = symmetry_complement(smap.chain, x)
                jacobians += 1
                fresh = True
                steps, sigma_min = phase_conditioned_steps(J, g, Q, self.comm)
            else:
                steps, _ = phase_conditioned_steps(J, g, Q, self.comm)
            best = None
            for d in steps:
                x_new = x + d.reshape(N, 2)
                sx = smap(x_new, T)
                g_new, E_new = (sx - x_new).ravel(), relative_residual(x_new, sx)
                if best is None or E_new < best[2]:
                    best = (x_new, g_new, E_new)
            x_new, g_new, E_new = best
            if E_new < E:
                r = float(np.max(np.abs(x_new - x)) / np.max(np.abs(x_new)))
                x, g, E = x_new, g_new, E_new
                history.append(E)
                it += 1
                if E > 0.1 * history[-2] and not fresh:
                    J = None          # slow progress with a stale Jacobian: re-evaluate it
                fresh = False
            elif not fresh:
                J = None              # the stale Jacobian gives no decrease: re-evaluate and retry
            else:
                break                 # no decrease even with a fresh Jacobian
        if E > self.tol:
            raise ConvergenceError("Gauss-Newton refinement (prefix -%s)" % self.smap.integrator.ts.getOptionsPrefix(),
                                   f"E = {E:.3g} > {self.tol:g}", q=orbit.q, iterations=it)
        return Refinement(orbit=orbit.with_state(x, "refined"), E_initial=E0, E=E, r=r, iterations=it,
                          jacobians=jacobians, history=history, sigma_min=sigma_min,
                          wall_time=time.perf_counter() - t0)

    def destroy(self):
        self.smap.destroy()
        self.flow.destroy()


def refine(orbit, comm, tol=1e-10, **kwargs):
    """One-off :meth:`Refiner.refine` of ``orbit``."""
    refiner = Refiner(orbit.spec, comm, tol, **kwargs)
    try:
        return refiner.refine(orbit)
    finally:
        refiner.destroy()
