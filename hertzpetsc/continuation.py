"""Continuation of odd travelling waves in q, from the binary oscillation at q = pi down to q_stop (default pi/M)
through the targets q = m pi / M (paper section 3.1).

Predictor: secant extrapolation of the rescaled profile q^(2/(alpha-1)) u, which stays O(1) along the whole
branch while u grows like q^(-2/(alpha-1)) (eq. normscaling). Step control: the targets are q = m pi / M; if
SNES fails, or the corrector moves the rescaled profile by more than ``max_corrector`` (relative, sup norm),
the step is halved (intermediate q need not be on the grid: shifts are interpolated) and retried, up to
``max_halvings`` consecutive times; after a success the step doubles again (up to the next target). Each
target point is yielded as soon as it has converged, so the caller can save it.
"""
import math
from dataclasses import dataclass, field

import numpy as np
from petsc4py import PETSc

from .advdelay import (TW_PREFIX, check_wavenumber, tw_solver, AdvanceDelayProblem, SolveResult,
                       TravellingWaveSolver)
from .binary import binary_oscillation
from .diagnostics import point_diagnostics
from .errors import ConvergenceError, ParameterError
from .grid import OddPeriodicGrid, check_cells_per_pi
from .hertz import HertzPotential, check_alpha
from .resources import check_memory


@dataclass(frozen=True)
class ContinuationParameters:
    """Parameters of a branch computation; the defaults are the paper's (alpha = 3/2, h = pi 1e-3, M = 50)."""

    alpha: float = 1.5
    M: int = 50
    cells_per_pi: int = 1000
    q_stop: float = None
    max_halvings: int = 8
    max_corrector: float = 0.25

    def __post_init__(self):
        object.__setattr__(self, "alpha", check_alpha(self.alpha))
        if not (isinstance(self.M, (int, np.integer)) and self.M >= 1):
            raise ParameterError("M", self.M, "must be an integer >= 1 (wavenumbers q = m pi / M)")
        object.__setattr__(self, "cells_per_pi", check_cells_per_pi(self.cells_per_pi))
        if self.q_stop is None:
            object.__setattr__(self, "q_stop", math.pi / self.M)
        object.__setattr__(self, "q_stop", check_wavenumber(self.q_stop, name="q_stop"))
        if self.q_stop < self.h:
            raise ParameterError("q_stop", self.q_stop, f"must be at least the grid step h = pi/{self.cells_per_pi}"
                                 f" = {self.h:.6g}; increase cells_per_pi")
        if not (isinstance(self.max_halvings, (int, np.integer)) and self.max_halvings >= 0):
            raise ParameterError("max_halvings", self.max_halvings, "must be an integer >= 0")
        if not self.max_corrector > 0:
            raise ParameterError("max_corrector", self.max_corrector, "must be > 0")

    @property
    def h(self):
        return math.pi / self.cells_per_pi

    def targets(self):
        """The wavenumbers to report: m pi / M from pi down to q_stop, then q_stop itself if it is off that grid."""
        qs = [m * math.pi / self.M for m in range(self.M, 0, -1) if m * math.pi / self.M >= self.q_stop * (1 - 1e-12)]
        if abs(qs[-1] - self.q_stop) > 1e-12 * self.q_stop:
            qs.append(self.q_stop)
        return qs


@dataclass
class BranchPoint:
    """One converged point: its profile on [0, pi] (on every rank), solver statistics and diagnostics."""

    q: float
    u_half: np.ndarray
    solve: SolveResult
    substeps: int
    wall_time: float
    diagnostics: dict = field(default_factory=dict)

    def record(self):
        """The per-point fields of the branch file (:data:`hertzpetsc.branchfile.POINT_FIELDS`)."""
        return dict(q=self.q, snes_iterations=self.solve.iterations,
                    ksp_iterations=self.solve.linear_iterations, residual_norm=self.solve.residual_norm,
                    snes_reason=self.solve.reason, substeps=self.substeps, wall_time=self.wall_time,
                    **self.diagnostics)


class ContinuationError(ConvergenceError):
    """The branch could not be continued past ``last_q`` (all points up to it were yielded)."""

    def __init__(self, last_q, failed_q, reason):
        self.last_q, self.failed_q = last_q, failed_q
        last = (f"last converged q = {last_q:.12g}, everything up to it is saved" if last_q == last_q
                else "no point converged")
        RuntimeError.__init__(self, f"continuation stopped: no convergence at q = {failed_q:.12g} even after step "
                                    f"reduction ({reason}); {last}")
        self.what, self.reason, self.where = "continuation", reason, dict(q=failed_q)


class BranchContinuation:
    """Continuation of eqs. ad-pbc in q. Iterate :meth:`points` to get the branch point by point."""

    def __init__(self, params, comm=None, prefix=TW_PREFIX, solver=None):
        self.params = params
        self.potential = HertzPotential(params.alpha)
        self.prefix = prefix
        solver = tw_solver(prefix, solver)
        check_memory(params.cells_per_pi, comm if comm is not None else PETSc.COMM_WORLD, solver)
        self.grid = OddPeriodicGrid(params.cells_per_pi, comm)
        # one SNES (and KSP/PC) for the whole branch, options read once (-tw_solver direct|nk, -tw_ksp_type, ...)
        self.solver = TravellingWaveSolver(self.grid, prefix, solver)
        self.exponent = self.potential.rescaling_exponent
        self.history = []   # the last two converged (q, rescaled profile Vec), intermediate q included

    def _remember(self, q, u):
        r = u.copy()
        r.scale(q ** self.exponent)
        self.history.append((q, r))
        while len(self.history) > 2:
            self.history.pop(0)[1].destroy()

    def predict(self, q_new):
        """Secant predictor on the rescaled profile (or the rescaled last point when only one is known)."""
        (q1, r1) = self.history[-1]
        r = r1.copy()
        if len(self.history) == 2:
            q0, r0 = self.history[0]
            r.axpy((q_new - q1) / (q1 - q0), r1)
            r.axpy(-(q_new - q1) / (q1 - q0), r0)
        r.scale(q_new ** (-self.exponent))
        return r

    def resume_from(self, qs, profiles):
        """Seed the predictor with already computed points (the last two of a branch file)."""
        for q, prof in zip(qs[-2:], profiles[-2:]):
            u = self.grid.vec_from_half_profile(prof)
            self._remember(float(q), u)
            u.destroy()

    def _solve_at(self, q, guess):
        problem = AdvanceDelayProblem(self.potential, self.grid, q)
        try:
            result = self.solver.solve(problem, guess)
        finally:
            problem.destroy()
        return result

    def _corrector_size(self, q, u, pred):
        diff = u.copy()
        diff.axpy(-1.0, pred)
        size = diff.norm(PETSc.NormType.NORM_INFINITY) / max(u.norm(PETSc.NormType.NORM_INFINITY), 1e-300)
        diff.destroy()
        return size

    def _point(self, q, u, result, substeps, wall):
        u_half = self.grid.half_profile(u)
        diag = point_diagnostics(u_half, q, self.grid.h, self.params.alpha)
        return BranchPoint(q=q, u_half=u_half, solve=result, substeps=substeps, wall_time=wall,
                           diagnostics=diag)

    def start(self):
        """Solve at q = pi from the sampled binary oscillation u0 (lemma binary)."""
        u = self.grid.vec_from_half_profile(binary_oscillation(self.potential, self.grid.xi_half()))
        q = math.pi
        try:
            result = self._solve_at(q, u)
        except ConvergenceError as err:
            raise ContinuationError(float("nan"), q, err.reason) from None
        self._remember(q, u)
        point = self._point(q, u, result, 1, result.wall_time)
        u.destroy()
        return point

    def step_to(self, q_target):
        """Continue from the last converged point to ``q_target``, halving the step on failure."""
        q_last = self.history[-1][0]
        dq = q_target - q_last
        substeps, wall, halvings = 0, 0.0, 0
        while True:
            q = q_last + dq if abs(q_last + dq - q_target) > 1e-14 * q_target else q_target
            u = self.predict(q)
            pred = u.copy()
            failure = None
            try:
                result = self._solve_at(q, u)
                wall += result.wall_time
                size = self._corrector_size(q, u, pred)
                if size > self.params.max_corrector:
                    failure = f"corrector moved the profile by {size:.3g} > max_corrector"
            except ConvergenceError as err:
                failure = f"SNES reason {err.reason}"
            pred.destroy()
            if failure is not None:
                u.destroy()
                halvings += 1
                if halvings > self.params.max_halvings:
                    raise ContinuationError(q_last, q, failure)
                dq *= 0.5
                continue
            substeps += 1
            halvings = 0          # max_halvings bounds consecutive reductions, not their total
            self._remember(q, u)
            if q == q_target:
                point = self._point(q, u, result, substeps, wall)
                u.destroy()
                return point
            u.destroy()
            q_last = q
            dq = q_target - q_last if abs(2 * dq) >= abs(q_target - q_last) else 2 * dq

    def points(self):
        """Yield the branch points at the targets not yet computed (all of them, from u0 at q = pi, unless
        :meth:`resume_from` seeded the continuation)."""
        targets = self.params.targets()
        if not self.history:
            yield self.start()
        q_done = self.history[-1][0]
        for q in targets:
            if q < q_done * (1 - 1e-12):
                yield self.step_to(q)

    def destroy(self):
        for _, r in self.history:
            r.destroy()
        self.history = []
        if self.solver is not None:
            self.solver.destroy()
            self.solver = None
