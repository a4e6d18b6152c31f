"""Travelling-wave residual E(q) and Gauss-Newton refinement of the initial state (paper section 3.4).

    E(q) = ||S X(script-T) - X(0)||_inf / ||X(0)||_inf,     script-T(q) = q ||u||_inf^((alpha-1)/2)  (eq. invv)

The refinement solves S^k X(delta; X0) = X0 by the package's Gauss-Newton engine (:mod:`hertzpetsc.gauss_newton`)
with the Jacobian S^k R(delta; 0) - I (:class:`~hertzpetsc.tangent.TangentFlow`). By default (``symmetric``) on the
wave's cell over its shortest time symmetry (:mod:`hertzpetsc.symmetry`, any mass pattern): the refined cell,
repeated, is a travelling wave with exactly the wave's periodicity, at about (M / N)^2 / m' of the cost; else the
paper's S X(script-T) = X(0) on the N beads. E(q) is measured on the N beads over script-T.

On a scale-invariant chain (no precompression, eq. twper) E(q) and the refinement are those of the wave rescaled to
amplitude 1 (:meth:`~hertzpetsc.waves.Orbit.with_amplitude`), the refined wave rescaled back: the flows' absolute
tolerances and the least-squares steps then mean the same at any amplitude.

The Jacobian is singular at a travelling wave (translation, time shift f(X0)) and nearly singular along slow modes:
steps lie in the orthogonal complement of the two symmetry directions (phase conditions) and come from the engine's
truncated SVD. With precompression the period may barely depend on the amplitude (C(q) = 0,
:meth:`~hertzpetsc.hertz.HertzLaw.stokes_coefficient`): script-T fixed then leaves the amplitude direction nearly
singular and the iteration stalls; it is then solved again from the start with script-T an unknown too
(:class:`ShiftMapFixedPoint`), the refined wave's script-T and omega corrected.

The Jacobian's flow is looser (prefix ``shoot_jac_``, rtol 1e-10) than the residual's (``shoot_``, rtol 1e-14): an
error of 1e-10 in J changes a step of size r by 1e-10 r.

E is measured with the residual flow, whose own error over script-T (its floor) varies erratically with the state:
the adaptive steps land differently on the contacts' openings and closings, where the Hertz force is not smooth.
Where the iteration stops above the target (no decrease with a fresh Jacobian, or the iteration limit), the floor is
measured at the refined state (:meth:`ShiftMap.floor`: S X(script-T) by the same flow with its tolerances divided by
``FLOOR_FACTOR``, E_floor the difference of the two, relative to ||X(0)||): the refinement is accepted *at the flow's
floor* when E <= tol + E_floor (the excess over the target is not resolved by the flow) and says so
(:class:`Refinement` ``E_floor``, ``E_fine``); else it did not converge. Roles ``shoot_``, ``shoot_jac_``, ``chain_``
(E with the paper's flow): :data:`hertzpetsc.roles.REGISTRY`.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from petsc4py import PETSc

from .chain import IntegrationTolerances
from .errors import (ConvergenceError, ParameterError, check_flag, check_instance, check_integer, check_prefix,
                     check_real)
from .model import ChainSpec
from .gauss_newton import GaussNewton
from .tangent import TangentFlow

if TYPE_CHECKING:
    from .model import ChainSpec
    from .waves import Orbit

SHOOT_PREFIX = "shoot_"

# The flow used to measure E(q) and to refine: the paper's rtol 1e-12 leaves errors near 1e-9 in X(script-T)
# at some q, which would floor a refined E(q); 1e-14 keeps them near 1e-12 at most states, but not at all of them
# (ShiftMap.floor measures them at one state).
MEASURE_TOLERANCES = IntegrationTolerances(rtol=1e-14, atol=1e-16)
# The paper's flow (Scilab's rtol 1e-12, atol 1e-14), for E(q) as the paper measured it.
PAPER_TOLERANCES = IntegrationTolerances(rtol=1e-12, atol=1e-14)
# The flow of the refinement's Jacobian (prefix shoot_jac_).
JACOBIAN_TOLERANCES = IntegrationTolerances(rtol=1e-10, atol=1e-12)
# The floor of a flow at a state is measured against the same flow with its tolerances divided by FLOOR_FACTOR, but
# not below FINEST_RTOL (a few units of round-off, where the steps' error estimates are rounding themselves).
FLOOR_FACTOR = 10.0
FINEST_RTOL = 1e-15


class ShiftMap(TangentFlow):
    """X0 -> S^k X(T; X0) on a periodic chain: the flow without tangents, with its own TS (options prefix
    ``prefix``)."""

    def __init__(self, spec, comm, tolerances, prefix):
        if spec.boundary != "periodic":
            raise ParameterError("boundary", spec.boundary, "travelling waves modulo shifts need a periodic chain")
        super().__init__(spec, 0, comm, tolerances, prefix)

    def __call__(self, x0, T, shift=1):
        """S^shift X(T) as an (N, 2) array on every rank, from the (N, 2) initial state ``x0`` (S moves bead n+c
        to bead n, c the mass pattern's length)."""
        return np.roll(self.run(x0, T, np.zeros((self.spec.N, 2, 0)))[0], -shift * self.spec.model.cell, axis=0)

    def residual(self, orbit):
        """E(q) = ||S X(script-T) - X(0)||_inf / ||X(0)||_inf of an orbit (a scale-invariant chain's: at amplitude
        1)."""
        orbit = orbit.with_amplitude(1.0)
        return relative_residual(orbit.x, self(orbit.x, orbit.T))

    def floor(self, orbit, factor=FLOOR_FACTOR):
        """E(q) of an orbit measured by this flow and by the same flow with its tolerances divided by ``factor``
        (rtol not below ``FINEST_RTOL``), and this flow's own error in S X(script-T), relative to ||X(0)||_inf,
        estimated by the difference of the two: below it this flow does not resolve E at this state."""
        orbit = orbit.with_amplitude(1.0)
        ts = self.integrator.ts
        rtol, atol = ts.getTolerances()
        fine = max(rtol / factor, min(rtol, FINEST_RTOL))
        sx = self(orbit.x, orbit.T)
        ts.setTolerances(rtol=fine, atol=atol * fine / rtol)
        try:
            sx_fine = self(orbit.x, orbit.T)
        finally:
            ts.setTolerances(rtol=rtol, atol=atol)
        return FlowFloor(relative_residual(orbit.x, sx), relative_residual(orbit.x, sx_fine),
                         float(np.max(np.abs(sx - sx_fine)) / np.max(np.abs(orbit.x))), fine)


@dataclass(frozen=True)
class FlowFloor:
    """E of one state by a flow (``E``) and by the same flow at rtol ``rtol_fine`` (``E_fine``); ``floor``: the
    first flow's error in S X(script-T) relative to ||X(0)||_inf (the difference of the two)."""

    E: float
    E_fine: float
    floor: float
    rtol_fine: float


def relative_residual(x0, sxT):
    """E = ||S X(T) - X(0)||_inf / ||X(0)||_inf over positions and velocities."""
    return float(np.max(np.abs(sxT - x0)) / np.max(np.abs(x0)))


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
    # accepted at the residual flow's floor (tol < E <= tol + E_floor): E with that flow at rtol / FLOOR_FACTOR and
    # that flow's own error in S X(script-T) at the refined state (ShiftMap.floor); NaN where E <= tol
    E_fine: float = math.nan
    E_floor: float = math.nan

    @property
    def at_floor(self) -> bool:
        """Whether E stayed above the target by no more than the residual flow's own error at the refined state."""
        return not math.isnan(self.E_floor)

    @property
    def x(self) -> np.ndarray:
        return self.orbit.x


def vector_field(chain, x):
    """f(X) of eq. nc at the (N, 2) state ``x``, flattened (index 2n + c), on every rank."""
    X, F = chain.create_state(), chain.create_state()
    chain.set_from_array(X, x)
    chain.rhs(None, 0.0, X, F)
    f = chain.gather(F).ravel()
    for v in (X, F):
        v.destroy()
    return f


def symmetry_complement(chain, x):
    """Orthonormal basis (2N x (2N-2)) of the complement of the translation and time-shift directions at x."""
    translation = np.tile([1.0, 0.0], chain.spec.N)
    Q, _ = np.linalg.qr(np.stack([translation, vector_field(chain, x)], axis=1), mode="complete")
    return Q[:, 2:]


class ShiftMapFixedPoint:
    """x = S^shift X(T; x) for the Gauss-Newton engine: rows S^shift X(T; x) - x (measure: their relative size),
    Jacobian S^shift R(T; 0) - I by the tangent flow, steps off the translation and time-shift directions.

    ``free_period``: T is an unknown too, z = (x, T), with the Jacobian's column S^shift f(X(T)); the wave's family
    (amplitude and period together) is then a null direction that the engine's truncated SVD leaves out: the steps
    keep the amplitude and correct the period."""

    def __init__(self, smap, flow, T, shift, free_period=False):
        self.smap, self.flow, self.T, self.shift, self.free_period = smap, flow, T, shift, free_period

    def start(self, x):
        """The unknowns z of the state ``x`` (and the period T when it is free)."""
        z = np.asarray(x, dtype=float).ravel()
        return np.append(z, self.T) if self.free_period else z

    def split(self, z):
        """(the state as (M, 2), T) of the unknowns z."""
        return (z[:-1].reshape(-1, 2), z[-1]) if self.free_period else (z.reshape(-1, 2), self.T)

    def residual(self, z):
        x, T = self.split(z)
        sx = self.smap(x, T, self.shift)
        return (sx - x).ravel(), relative_residual(x, sx)

    def jacobian(self, z):
        x, T = self.split(z)
        M, sxT = self.flow.monodromy_mod_shift(x, T, self.shift)
        A, Q = M - np.eye(x.size), symmetry_complement(self.smap.aug, x)
        if self.free_period:
            A = np.hstack([A, vector_field(self.smap.aug, sxT)[:, None]])
            Q = np.block([[Q, np.zeros((len(Q), 1))], [np.zeros((1, Q.shape[1])), np.ones((1, 1))]])
        return A, Q


class Refiner:
    """Gauss-Newton refinement of travelling-wave orbits, any mass pattern (flows built once per chain length,
    prefix ``shoot_``; the engine :class:`~hertzpetsc.gauss_newton.GaussNewton`); ``with Refiner(...) as r:``.

    ``tol``: the target E(q) (on the N beads over script-T), at least the residual flow's rtol; the iteration
    limit is ``-<prefix>gn_max_it`` (default ``max_iterations``). ``symmetric``: refine on the wave's cell with its
    shortest time symmetry. ``accept_floor``: an iteration that stops above ``tol`` is accepted at the residual
    flow's floor when E exceeds ``tol`` by no more than that flow's error at the refined state (module docstring).
    """

    def __init__(self, spec: ChainSpec, comm: PETSc.Comm, tol: float = 1e-10, max_iterations: int = 20,
                 tolerances: IntegrationTolerances = MEASURE_TOLERANCES, prefix: str = SHOOT_PREFIX,
                 symmetric: bool = True, jacobian_tolerances: IntegrationTolerances = JACOBIAN_TOLERANCES,
                 accept_floor: bool = True) -> None:
        tol = check_real("tol", tol, "the target residual", 0.0)
        check_instance("spec", spec, ChainSpec, "a ChainSpec")
        symmetric = check_flag("symmetric", symmetric)
        check_prefix("prefix", prefix)
        max_iterations = check_integer("max_iterations", max_iterations, 1, "the Gauss-Newton iterations")
        for name, value in (("tolerances", tolerances), ("jacobian_tolerances", jacobian_tolerances)):
            check_instance(name, value, IntegrationTolerances, "an IntegrationTolerances(rtol, atol)")
        self.spec, self.tol, self.comm, self.symmetric = spec, tol, comm, symmetric
        self.accept_floor = accept_floor
        self.tolerances, self.jacobian_tolerances, self.prefix = tolerances, jacobian_tolerances, prefix
        limit = PETSc.Options().getInt(prefix + "gn_max_it", max_iterations)      # an option, else the argument
        self.max_iterations = check_integer(f"-{prefix}gn_max_it", limit, 1)
        self.engine = GaussNewton(comm)
        self._flows = {}
        self.smap = self._maps(spec.N)[0]          # configures both flows (options read now)
        # E is a relative error of X(script-T) measured with the residual flow: below its rtol E is that flow's
        # error, and the steps that still lower it drift along the nearly singular direction of the wave family
        rtol = self.smap.integrator.ts.getTolerances()[0]
        if not self.tol >= rtol:
            self.destroy()
            raise ParameterError("tol", tol, f"the target residual must be at least the residual flow's rtol "
                                 f"{rtol:g} (-{prefix}ts_rtol), below which E(q) is not resolved")

    def _maps(self, N):
        """(state flow, tangent flow with 2N columns) on N beads of the lattice, built once."""
        if N not in self._flows:
            cell = self.spec.with_length(N)
            self._flows[N] = (ShiftMap(cell, self.comm, self.tolerances, self.prefix),
                              TangentFlow(cell, 2 * N, self.comm, self.jacobian_tolerances, self.prefix + "jac_"))
        return self._flows[N]

    def shift_map(self, N: int) -> ShiftMap:
        """The refinement's own state flow (:class:`ShiftMap`) on N beads of the lattice."""
        return self._maps(N)[0]

    def residual(self, orbit: Orbit) -> float:
        """E(q) of ``orbit`` with the refinement's own flow."""
        return self.smap.residual(orbit)

    @PETSc.Log.EventDecorator("hz_refine")
    def refine(self, orbit: "Orbit") -> Refinement:
        """The refined :class:`Refinement` of ``orbit``; :class:`ConvergenceError` if E cannot be brought below
        ``tol`` within the iteration limit, nor (``accept_floor``) below ``tol`` plus the residual flow's error at
        the state where the iteration stopped."""
        t0 = time.perf_counter()
        size, orbit = orbit.amplitude, orbit.with_amplitude(1.0)      # a scale-invariant chain: refined at size 1
        E0 = self.residual(orbit)
        sym = orbit.symmetry
        M, shift, T, m_cell = (sym.M, sym.k, sym.delta(orbit.T), sym.m_cell) if self.symmetric else \
            (orbit.N, 1, orbit.T, 1)
        total_it, jacobians, history, r, sigma_min = 0, 0, [E0], float("nan"), None
        # script-T fixed (the paper's problem); where the period barely depends on the amplitude (C(q) = 0 with
        # precompression) that stalls: then T is an unknown too (on a scale-invariant chain T fixes the amplitude)
        for free_period in (False,) if orbit.spec.model.scale_invariant else (False, True):
            problem = ShiftMapFixedPoint(*self._maps(M), T, shift, free_period)
            z = problem.start(orbit.x[:M])
            # the short map's residual accumulates over the m' maps that make script-T: aim below tol / m'
            target = self.tol / m_cell
            while True:
                res = self.engine.solve(problem, z, target, self.max_iterations - total_it)
                z, total_it, jacobians = res.z, total_it + res.iterations, jacobians + res.jacobians
                r = res.r if res.r == res.r else r
                sigma_min = res.sigma_min if res.sigma_min is not None else sigma_min
                x, T_short = problem.split(z)
                refined = orbit.with_state(np.tile(x, (orbit.N // M, 1)), "refined",
                                           T_short * m_cell if free_period else None)
                E = self.residual(refined)
                history.append(E)
                stalled = res.E > target and total_it < self.max_iterations   # no decrease with a fresh Jacobian
                if E <= self.tol or stalled or total_it >= self.max_iterations or target < 1e-16:
                    break
                target *= 0.1                 # the cell's map converged but E over script-T did not: tighten
            # stopped above the target: at the residual flow's floor if E exceeds it by no more than the flow's
            # own error at the refined state
            floor = self.smap.floor(refined) if E > self.tol and self.accept_floor else None
            at_floor = floor is not None and E <= self.tol + floor.floor
            if E <= self.tol or at_floor or total_it >= self.max_iterations:
                break
        if E > self.tol and not at_floor:
            fine = "" if floor is None else \
                f"; at rtol {floor.rtol_fine:g}: E = {floor.E_fine:.3g}, the flow's floor {floor.floor:.2g}"
            raise ConvergenceError("Gauss-Newton refinement (prefix -%s)" % self.prefix,
                                   f"E = {E:.3g} > {self.tol:g}{fine}", q=orbit.q, iterations=total_it)
        return Refinement(orbit=refined.with_amplitude(size), E_initial=E0, E=E, r=r, iterations=total_it,
                          jacobians=jacobians, history=history, sigma_min=sigma_min,
                          wall_time=time.perf_counter() - t0, E_fine=floor.E_fine if at_floor else math.nan,
                          E_floor=floor.floor if at_floor else math.nan)

    def destroy(self) -> None:
        for smap, flow in self._flows.values():
            smap.destroy()
            flow.destroy()
        self._flows = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.destroy()


def refine(orbit: "Orbit", comm: PETSc.Comm, tol: float = 1e-10, **kwargs) -> Refinement:
    """One-off :meth:`Refiner.refine` of ``orbit`` (``kwargs``: those of :class:`Refiner`); collective over
    ``comm``."""
    with Refiner(orbit.spec, comm, tol, **kwargs) as refiner:
        return refiner.refine(orbit)
