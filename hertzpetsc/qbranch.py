"""The paper's branch: continuation of odd travelling waves in q, from the binary oscillation at q = pi down through
a list of target wavenumbers (section 3.1), on a fixed grid or on grids refined as q decreases; a use of the one
continuation layer (:mod:`hertzpetsc.continuation`) on the advance-delay problem (:mod:`hertzpetsc.advdelay`).

Predictor: secant extrapolation of the rescaled profile q^(2/(alpha-1)) u, which stays O(1) along the whole
branch while u grows like q^(-2/(alpha-1)) (eq. normscaling). Step control: if SNES fails, or the corrector moves
the rescaled profile by more than ``max_corrector`` (relative, sup norm), the step is halved (intermediate q need
not be on the grid: shifts are interpolated) and retried, up to ``max_halvings`` consecutive times; after a
success the step doubles again (up to the next target). Each target point is yielded as soon as it has converged,
so the caller can save it.

The grid is a policy: :class:`FixedGrid` (the paper's h = pi/1000), or :class:`RefiningGrid`, which keeps at
least ``cells_per_q`` cells per unit of q below ``q_first`` by doubling the grid each time q halves; when the
grid changes, the last two profiles are interpolated (degree-5 Lagrange, below the scheme's O(h^2)) onto the new
grid and the secant predictor goes on there (section 3.2, small q).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Iterator, Optional, Sequence

import numpy as np

from .advdelay import AdvanceDelayProblem, check_wavenumber
from .binary import binary_oscillation
from .branch import BranchPoint
from .continuation import ContinuationError, ContinuationUse, Natural
from .diagnostics import point_diagnostics
from .errors import ConvergenceError, ParameterError, check_instance, check_integer
from .grid import ProfileGrid, check_cells_per_pi
from .hertz import HertzLaw, check_alpha
from .model import LatticeModel
from .resources import check_memory
from .stencil import full_period, lagrange_periodic
from .twsolver import TW_PREFIX, tw_solver

if TYPE_CHECKING:
    from petsc4py import PETSc

    from .twsolver import TravellingWaveSolver


@dataclass(frozen=True)
class ContinuationParameters:
    """Parameters of a branch computation; the defaults are the paper's (alpha = 3/2, h = pi 1e-3, M = 50).

    The lattice is ``model`` (a :class:`~hertzpetsc.model.LatticeModel`), or the paper's chain with exponent
    ``alpha``; the targets are q = m pi / M from pi down to ``q_stop`` (default pi / M), and q_stop itself.
    """

    alpha: float = None
    M: int = 50
    cells_per_pi: int = 1000
    q_stop: float = None
    max_halvings: int = 8
    max_corrector: float = 0.25
    model: LatticeModel = field(default=None, compare=False)

    def __post_init__(self):
        model = self.model
        if model is None:
            model = LatticeModel.hertz(check_alpha(1.5 if self.alpha is None else self.alpha))
        else:
            check_instance("model", model, LatticeModel, "a LatticeModel (LatticeModel.hertz(alpha))")
            if self.alpha is not None and check_alpha(self.alpha) != model.alpha:
                raise ParameterError("alpha", self.alpha, f"differs from the model's exponent {model.alpha}")
        if not isinstance(model.law, HertzLaw) or model.law.kernel_form is None:
            raise ParameterError("model", model.describe(), "the q-branch starts from the Hertz law's binary "
                                 "oscillation (lemma binary): other laws have their waves at a given amplitude "
                                 "(AmplitudeFamily, WavenumberFamily, wave_at)")
        if model.cell != 1 or model.delta0 != 0:
            raise ParameterError("model", model.describe(), "the q-branch (eq. ad at omega = 1 from the binary "
                                 "oscillation) is the uncompressed monatomic chain's; a precompressed chain or a mass "
                                 "pattern has its waves at a given amplitude (wave_at, AmplitudeFamily)")
        object.__setattr__(self, "model", model)
        object.__setattr__(self, "alpha", model.alpha)
        object.__setattr__(self, "M", check_integer("M", self.M, 1, note="(wavenumbers q = m pi / M)"))
        object.__setattr__(self, "cells_per_pi", check_cells_per_pi(self.cells_per_pi))
        default_stop = self.q_stop is None
        q_stop = math.pi / self.M if default_stop else self.q_stop
        object.__setattr__(self, "q_stop", check_wavenumber(q_stop, name="q_stop"))
        if self.q_stop < self.h and default_stop:
            raise ParameterError("M", self.M, f"gives the default q_stop = pi / M below the grid step h = "
                                 f"pi/{self.cells_per_pi}: M must be at most cells_per_pi")
        if self.q_stop < self.h:
            raise ParameterError("q_stop", self.q_stop, f"must be at least the grid step h = pi/{self.cells_per_pi}"
                                 f" = {self.h:.6g}; increase cells_per_pi")
        Natural(self.max_halvings, self.max_corrector)         # their checks

    @property
    def h(self) -> float:
        return math.pi / self.cells_per_pi

    def targets(self) -> list[float]:
        """The wavenumbers to report: m pi / M from pi down to q_stop, then q_stop itself if it is off that grid."""
        return paper_targets(self.M, self.q_stop)


def paper_targets(M, q_stop):
    """m pi / M from pi down to q_stop, then q_stop itself if it is off that list."""
    qs = [m * math.pi / M for m in range(M, 0, -1) if m * math.pi / M >= q_stop * (1 - 1e-12)]
    if abs(qs[-1] - q_stop) > 1e-12 * q_stop:
        qs.append(q_stop)
    return qs


# --- grid policies ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FixedGrid:
    """One grid h = pi / cells_per_pi for the whole branch."""

    cells: int = 1000

    def cells_per_pi(self, q):
        return self.cells


@dataclass(frozen=True)
class RefiningGrid:
    """At least ``cells_per_q`` 2^level cells per unit of q below q_first: K = K0 2^(k + level), K0 =
    cells_per_q pi / q_first, k the number of halvings of q_first that q is below (section 3.2)."""

    q_first: float = math.pi / 50
    cells_per_q: int = 20
    level: int = 0

    def __post_init__(self):
        object.__setattr__(self, "cells_per_q", check_integer("cells_per_q", self.cells_per_q, 4))
        object.__setattr__(self, "level", check_integer("level", self.level, 0))

    def cells_per_pi(self, q):
        K0 = int(round(self.cells_per_q * math.pi / self.q_first))
        k = max(0, math.ceil(math.log2(self.q_first / q) - 1e-9))
        return K0 * 2 ** (k + self.level)


def regrid_half_profile(u_half, K_new):
    """An odd profile on [0, pi] (K+1 values) interpolated onto the grid of K_new cells per pi."""
    K = len(u_half) - 1
    if K == K_new:
        return np.asarray(u_half, dtype=float).copy()
    xi = np.arange(K_new + 1) * math.pi / K_new
    out = lagrange_periodic(full_period(u_half), math.pi / K, xi)
    out[0] = out[-1] = 0.0
    return out


class BranchContinuation(ContinuationUse):
    """Continuation of eqs. ad-pbc in q on one grid: the paper's problem (:class:`AdvanceDelayProblem`, parameter
    q) driven by the continuation layer's :class:`~hertzpetsc.continuation.Natural` algorithm (secant predictor on
    the rescaled profile, step halving). Iterate :meth:`points` to get the branch point by point.

    One SNES (and KSP/PC) serves the whole branch; its options (prefix ``tw_``) are read once, here.
    """

    def __init__(self, params: ContinuationParameters, comm: PETSc.Comm, prefix: str = TW_PREFIX,
                 solver: Optional[str] = None, cells_per_pi: Optional[int] = None) -> None:
        self.params = params
        self.model = params.model
        self.prefix = prefix
        K = params.cells_per_pi if cells_per_pi is None else cells_per_pi
        solver = tw_solver(prefix, solver)
        check_memory(K, comm, solver)
        self.grid = ProfileGrid(K, comm)
        self._use(AdvanceDelayProblem(self.model, self.grid, math.pi, parameter="q"), prefix, solver,
                  Natural(params.max_halvings, params.max_corrector))

    @property
    def history(self) -> list:
        return self.continuation.history

    @property
    def solver(self) -> TravellingWaveSolver:
        """The travelling-wave SNES of the branch (:class:`~hertzpetsc.twsolver.TravellingWaveSolver`)."""
        return self.problem.solver(False)

    def resume_from(self, qs: Sequence[float], profiles: Sequence[np.ndarray]) -> None:
        """Seed the predictor with already computed points (the last two), given on any grid."""
        seeds = [self.problem.pack([regrid_half_profile(prof, self.grid.K)], parameter=float(q))
                 for q, prof in zip(list(qs)[-2:], list(profiles)[-2:])]
        self.continuation.seed(seeds)
        for Z in seeds:
            Z.destroy()

    def _point(self, cp, wall):
        u_half = cp.report["profiles"][0]
        q = cp.parameter
        diag = point_diagnostics(u_half, q, self.grid.h, self.model.alpha)
        return BranchPoint(q=q, u_half=u_half, h=self.grid.h, model=self.model, diagnostics=diag,
                           solve=self.problem.stats, substeps=cp.substeps, wall_time=wall)

    def start(self) -> BranchPoint:
        """Solve at q = pi from the sampled binary oscillation u0 (lemma binary)."""
        t0 = time.perf_counter()
        Z = self.problem.pack([binary_oscillation(self.model.law, self.grid.xi_half())], parameter=math.pi)
        try:
            cp = self.continuation.start(Z)
        except ConvergenceError as err:
            raise ContinuationError("q", float("nan"), math.pi, err.reason) from None
        finally:
            Z.destroy()
        return self._point(cp, time.perf_counter() - t0)

    def step_to(self, q_target: float) -> BranchPoint:
        """Continue from the last converged point to ``q_target``, halving the step on failure."""
        t0 = time.perf_counter()
        cp = self.continuation.step_to(q_target)
        return self._point(cp, time.perf_counter() - t0)

    def points(self, targets: Optional[Sequence[float]] = None) -> Iterator[BranchPoint]:
        """Yield the branch points at the targets not yet computed (all of them, from u0 at q = pi, unless
        :meth:`resume_from` seeded the continuation)."""
        targets = self.params.targets() if targets is None else targets
        if not self.history:
            yield self.start()
        q_done = self.continuation.parameter
        for q in targets:
            if q < q_done * (1 - 1e-12):
                yield self.step_to(q)


def continue_branch(params, targets, grids, comm, seeds=(), prefix=TW_PREFIX, solver=None):
    """Yield the branch points at ``targets`` (decreasing, from pi), each on the grid ``grids.cells_per_pi(q)``.

    ``seeds``: the last converged points of an interrupted run, as (q, u_half) on any grid (the last two seed the
    predictor; the continuation goes on after the last). When the grid changes, the last two profiles are
    interpolated onto the new grid. The first point, q = pi, starts from the binary oscillation.
    """
    history = [(float(q), np.asarray(u, dtype=float)) for q, u in seeds][-2:]
    cont, K_cur = None, None
    try:
        for q in targets:
            if history and q >= history[-1][0] * (1 - 1e-12):
                continue
            K = grids.cells_per_pi(q)
            if K != K_cur:
                if cont is not None:
                    cont.destroy()
                cont = BranchContinuation(params, comm, prefix, solver, cells_per_pi=K)
                cont.resume_from([h[0] for h in history], [h[1] for h in history])
                K_cur = K
            for point in cont.points([q]):        # from u0 at pi first if nothing is computed yet
                history = (history + [(point.q, point.u_half)])[-2:]
            yield point
    finally:
        if cont is not None:
            cont.destroy()
