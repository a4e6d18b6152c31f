"""Families of travelling waves beyond the paper's q-branch, as uses of the one continuation layer on the one
advance-delay problem (:mod:`hertzpetsc.continuation`, :mod:`hertzpetsc.advdelay`): any lattice model (law with
precompression, mass pattern) in its fixed-amplitude form (u_c = a w_c, lam = omega^2 a^(1-d)).

* :class:`AmplitudeFamily`: the waves at fixed q continued in s = log a (natural steps, secant predictor) from the
  linear wave (a -> 0), with the gap opening (the largest bond length reaching delta0, so that contact is lost
  somewhere in the wave) located as an event of the layer; :func:`uncompressed_limit`: the delta0 / a = 0 wave on
  the same grid (the paper's wave rescaled).
* :class:`WavenumberFamily`: the waves at a fixed amplitude continued in q (natural steps) from the amplitude
  family's wave at a first q.
* :class:`MassFamily`: a dimer's waves at fixed q and a, continued in the mass m_1 = epsilon by pseudo-arclength
  (through folds, which the layer detects).
* :func:`wave_at`: the wave of a given model at a given (q, A = max |u|), A imposed as a border row;
  :func:`wave_of_amplitude`: the same for any model (scale-invariant ones by the paper's branch, rescaled), ready
  to be put on a chain.

Closed forms live with the model: the linear frequencies (:meth:`~hertzpetsc.model.LatticeModel.linear_frequencies`)
and the Hertz law's weakly nonlinear coefficient (:meth:`~hertzpetsc.hertz.HertzLaw.stokes_coefficient`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Callable, Collection, Iterable, Iterator, Mapping, Optional, Sequence

import numpy as np

from .advdelay import AdvanceDelayProblem, check_wavenumber, profile_sup
from .assembly import gathered
from .branch import BranchPoint
from .continuation import ContinuationError, ContinuationUse, FoldError, LazyTests, Natural, PseudoArclength
from .errors import ConvergenceError, ParameterError, check_real
from .stencil import full_period, lagrange_periodic

if TYPE_CHECKING:
    from .grid import ProfileGrid
    from .model import LatticeModel

PRECOMP_PREFIX = "precomp_"
DIMER_PREFIX = "dimer_"


def check_amplitude(a, name="amplitude"):
    """a must be a finite number > 0."""
    return check_real(name, a, "the wave amplitude", 0.0)


# The largest first amplitude of a family, in units of the law's reference amplitude (Hertz: delta0): it starts from
# the linear wave, the limit a << delta0.
START_MAX = 0.1


def amplitude_floor(model):
    """The smallest amplitude (a or A) at which a family of the precompressed ``model`` keeps its amplitude:
    delta0 max(sqrt(eps), eps^(1/(2(d-1)))), d the law's degree, delta0 its reference amplitude (the second term only
    for d > 1: a law without a scaling (d = 1) keeps lam = omega^2). Below sqrt(eps) delta0, omega / omega_lin - 1 =
    C a^2 (C ~ (d-1)^2 / (4 delta0^2)) is below round-off: omega is the linear one whatever a. Below
    eps^(1/(2(d-1))) delta0 the rescaled law's stiffness, hence lam = omega^2 a^(1-d) ~ (delta0 / a)^(d-1), exceeds
    1/sqrt(eps): the Newton's stopping tolerance, scaled by lam max(lam, ||w||_inf) (the round-off floor,
    :func:`~hertzpetsc.twsolver.default_tolerances`), then accepts the predictor itself (omega off by the step)."""
    eps = float(np.finfo(float).eps)
    d = model.law.scale_degree
    return model.reference_amplitude * max(math.sqrt(eps), eps ** (1.0 / (2.0 * (d - 1.0))) if d > 1 else 0.0)


def amplitude_ceiling(model):
    """The largest amplitude (a or A) of a wave of ``model``: ((sqrt(max float))^(1/(d+1)) - delta0) / 2, d the law's
    degree. The wave's energy per bond is V(2A + delta0) ~ (2A + delta0)^(d+1) (velocities omega A and forces
    (2A + delta0)^d have squares of the same order or below): up to this bound it and its square (the norms of the
    chain's states and residuals) are finite floats; beyond it they overflow."""
    big = math.sqrt(float(np.finfo(float).max)) ** (1.0 / (model.law.scale_degree + 1.0))
    return 0.99 * max(big - model.delta0, 0.0) / 2.0        # 0.99: the powers' rounding at the bound


def check_wave_amplitude(model, a, name="amplitude", lo=0.0):
    """a must be a finite number in (0, :func:`amplitude_ceiling`] (``lo``: the family's floor, named in the range);
    ``name`` is used in errors."""
    a = check_amplitude(a, name)
    hi = amplitude_ceiling(model)
    if not a <= hi:
        span = f"[{lo:.3g}, {hi:.3g}]" if lo > 0 else f"(0, {hi:.3g}]"
        raise ParameterError(name, a, f"the wave amplitude must lie in {span}: at most ((max float)^(1/(2(alpha+1))) "
                             "- delta0) / 2, beyond which the wave's energy and its square overflow")
    return a


def check_family_amplitude(model, a, name="amplitude", start=False):
    """a (> 0, finite) must be at least :func:`amplitude_floor`, and, for the ``start`` of a family from the linear
    wave, at most START_MAX delta0, else at most :func:`amplitude_ceiling`; ``name`` is used in errors."""
    a = check_amplitude(a, name)
    ref = model.reference_amplitude
    lo, hi = amplitude_floor(model), (START_MAX * ref if start else math.inf)
    if not lo <= a <= hi:
        d0 = "delta0" if "delta0" in model.parameters else "r0"
        floor = (f"at least {d0} max(sqrt(eps), eps^(1/(2(alpha-1)))) = {lo:.3g} ({d0} = {ref:g}"
                 f"{'' if d0 == 'delta0' else ', the law reference amplitude'}; below, the amplitude is lost in "
                 "floating point)")
        if start:
            raise ParameterError(name, a, f"the first amplitude of a family must lie in [{lo:.3g}, {hi:.3g}]: at most "
                                 f"{START_MAX:g} {d0} (it starts from the linear wave, a << {d0}) and {floor}")
        raise ParameterError(name, a, f"the wave amplitude must be {floor}")
    return check_wave_amplitude(model, a, name, lo)


@dataclass(frozen=True)
class AmplitudePoint:
    """One wave of a family: a (the scale of the normalised profile: first sine coefficient, or A itself for the
    'sup' measure), A = max_c ||u_c||_inf, omega, Omega = omega A^(-(d-1)/2), lam, the gap indicator (> 0: a
    bond is out of contact somewhere in the wave), the rescaled half profiles w_c (u_c = a w_c), Newton
    iterations, and the dimer's m_1."""

    q: float
    a: float
    A: float
    omega: float
    Omega: float
    lam: float
    gap: float
    profiles: tuple
    iterations: int
    m1: float = float("nan")
    event: str = None          # a located point: the test function whose root it is ('gap', or a caller's test)
    bracket: tuple = None      # ... and the last bracket ((s, value), (s, value)) in s = log a around the root
    unresolved: str = None     # ... None, or why its location stopped: bracketed only, the point an end (iterations 0)
    normalised: int = 0        # the profile c* whose measure is 1 (the family's normalisation)

    @property
    def s(self) -> float:
        return math.log(self.a)

    def branch_point(self, model: LatticeModel, h: float) -> BranchPoint:
        """The wave as a :class:`~hertzpetsc.branch.BranchPoint` at its physical amplitude (u_c = a w_c, omega)."""
        prof = tuple(self.a * np.asarray(w) for w in self.profiles)
        return BranchPoint(q=self.q, u_half=prof[0], h=h, model=model, profiles=prof, omega=self.omega)


class FamilyFold(ConvergenceError):
    """An amplitude family that turns back at a fold before the amplitude asked for: followed through the fold by
    pseudo-arclength, the curve returns to smaller amplitudes. ``fold``: the wave farthest along the family (an
    :class:`AmplitudePoint`: the largest amplitude it reaches), ``branch``: the linear wave the family starts from,
    ``target``: the amplitude asked for (``name``: 'A' = max |u|, or 'a' the first sine coefficient). The message
    names the other branch of a mass pattern, which may have the wave (:meth:`as_option`: its driver option)."""

    def __init__(self, q: float, branch: str, fold: AmplitudePoint, target: float, name: str, cell: int) -> None:
        self.q, self.branch, self.fold, self.target, self.name, self.cell = q, branch, fold, target, name, cell
        self.other = {"acoustic": "optical", "optical": "acoustic"}[branch] if cell > 1 else None
        at = (f"A = max |u| = {fold.A:.6g}" if name == "A" else
              f"a = {fold.a:.6g} (first sine coefficient; A = max |u| = {fold.A:.6g})")
        self.why = (f"the {branch} family at q = {q:.12g} (per bead) folds at {at}, omega = {fold.omega:.6g}: followed "
                    f"through the fold by pseudo-arclength it turns back to smaller amplitudes and does not reach "
                    f"{name} = {target:.6g}")
        hint = (f"the {self.other} family may have it (hz.wave_at(..., branch=\"{self.other}\"), "
                f"hz.wave(..., branch=\"{self.other}\"), or -branch {self.other} in wave.py and "
                "precompressed_branch.py)" if self.other else
                f"a monatomic chain has no other family here; amplitudes up to {fold.A:.6g} have waves")
        self.what, self.reason, self.where = "amplitude continuation", "fold", dict(q=q, **{name: target})
        RuntimeError.__init__(self, f"{self.why}; {hint}")

    def as_option(self, options: Collection[str]) -> FamilyFold:
        """In a driver with a ``-branch`` option: the same error naming that option only."""
        if self.other is None or "branch" not in options:
            return self
        err = FamilyFold(self.q, self.branch, self.fold, self.target, self.name, self.cell)
        RuntimeError.__init__(err, f"{self.why}; the {self.other} family may have it: run again with "
                                   f"-branch {self.other}")
        return err


class FamilyProblem(AdvanceDelayProblem):
    """The fixed-amplitude advance-delay problem with the family's test function (the gap indicator) and report."""

    def gap(self, profiles):
        """max bond length - delta0 over the wave (in units of u = a w; delta0: the law's ``separation``): 2 u(q/2)
        - delta0 for a monatomic odd wave (the bond across xi = 0 is the longest); for a pattern the largest over c of
        the refined maximum of tau_q u_{c+1} - u_c less bond c's separation."""
        a = self.amplitude if math.isfinite(self.amplitude) else 1.0
        h = self.grid.h
        if self.p == 1:
            w_half_q = float(lagrange_periodic(full_period(profiles[0]), h, np.array([self.q / 2]))[0])
            return 2 * a * w_half_q - self.model.law.separation
        longest = -math.inf
        xi = np.arange(2 * self.grid.K) * h
        whole = [w if self.full else full_period(w) for w in profiles]
        for c in range(self.p):
            up = lagrange_periodic(whole[(c + 1) % self.p], h, xi + self.q)
            r = up - whole[c]
            j = int(np.argmax(r))
            a3 = r[[(j - 1) % len(r), j, (j + 1) % len(r)]]
            curv = a3[0] - 2 * a3[1] + a3[2]
            r_max = a3[1] - (a3[0] - a3[2]) ** 2 / (8 * curv) if curv < 0 else a3[1]
            longest = max(longest, a * r_max - self.model.bond_law(c).separation)   # bond c's own separation
        return longest

    # the caller's tests: a function of the AmplitudePoint returning {name: function of no argument} (values read
    # when the layer needs them, :class:`~hertzpetsc.continuation.LazyTests`)
    extra_tests = None

    def test_functions(self, Z):
        self.set_parameter(self.parameter, self._scalars(Z)[-1])
        point = self.point(Z, 0)
        functions = {"gap": lambda: point.gap} if self.model.law.separation is not None and \
            math.isfinite(self.amplitude) else {}
        if self.extra_tests is not None:
            functions.update(self.extra_tests(point))
        return LazyTests(functions)

    def point(self, V, iterations):
        """The :class:`AmplitudePoint` of an X or Z Vec at the problem's current parameters."""
        return self._wave(self.half_profiles(V), float(self._scalars(V)[0]), iterations)

    def located(self, cp, current):
        """The :class:`AmplitudePoint` of the layer's ContinuationPoint ``cp`` (from its report, at its parameter);
        the problem's parameter is then set to ``current`` (the continuation's last)."""
        self.set_parameter(self.parameter, cp.parameter)
        point = self._wave(cp.report["profiles"], cp.report["lam"], cp.iterations)
        self.set_parameter(self.parameter, current)
        return point

    def _wave(self, prof, lam, iterations):
        a = self.amplitude
        norm = max(profile_sup(w, self.full) for w in prof)
        d = self.model.law.scale_degree
        omega = self._omega_from(lam)
        return AmplitudePoint(q=self.q, a=a, A=a * norm, omega=omega,
                              Omega=math.sqrt(max(lam, 0.0)) * norm ** (-(d - 1) / 2), lam=lam,
                              gap=self.gap(prof) if self.model.law.separation is not None else math.inf,
                              profiles=tuple(prof),
                              iterations=iterations, m1=float(self.masses[1]) if self.p > 1 else 1.0,
                              normalised=self.normalised)


# A mass pattern's family is guarded against natural steps that land on another branch (docs/beyond-the-paper.md,
# dimers): steps of ln 3 and ln(10/3) did so, and so did a step of ln 1.5 across a dimer's gap opening, where its
# corrector moved (w, lam) by 26 % (steps within the family: at most 19 % once the secant predictor has two points).
PATTERN_MAX_STEP = math.log(1.5)
PATTERN_MAX_CORRECTOR = 0.25
# A family may fold in a (an S-shaped pair of folds: the precompressed trimer 1, 1/2, 1/3 at q = 2 pi/15 just past
# its gap opening), where natural steps stall: the layer then follows the curve by at most this many
# pseudo-arclength steps (:class:`~hertzpetsc.continuation.Natural`, ``around_folds``).
AROUND_FOLDS = 100


class AmplitudeFamily(ContinuationUse):
    """Travelling waves of ``model`` at fixed q, continued in s = log a from the linear wave (module docstring):
    the layer's natural algorithm (secant predictor on (w, lam), step halving on failure, at most
    ``max_halvings``). One SNES under ``prefix``. ``branch``: the acoustic or optical linear wave to start from;
    ``measure``: what a is ('a1': the first sine coefficient of the normalised profile; 'sup': A = max |u|).
    ``max_step``, ``max_corrector``: the layer's guards against a step landing on another branch, the longest
    natural step in log a and the largest corrector (relative, on (w, lam)); None: PATTERN_MAX_STEP and
    PATTERN_MAX_CORRECTOR for a mass pattern, none for the monatomic chain (every converged step taken, as when
    its families were computed). ``around_folds``: the layer's pseudo-arclength steps through a fold of a where the
    natural steps stall (0: none, the step fails)."""

    def __init__(self, model: LatticeModel, q: float, grid: ProfileGrid, prefix: str = PRECOMP_PREFIX,
                 branch: str = "acoustic", max_halvings: int = 6, measure: str = "a1", solver: Optional[str] = None,
                 tests: Optional[Callable[[AmplitudePoint], dict]] = None, bisect: Sequence[str] = (),
                 locate_step: Optional[float] = None, max_step: Optional[float] = None,
                 max_corrector: Optional[float] = None, around_folds: int = AROUND_FOLDS) -> None:
        model.require_linear_stiffness("the amplitude family starts from the linear wave: it needs a precompression "
                                       "> 0")
        self.model, self.grid, self.branch = model, grid, branch
        problem = FamilyProblem(model, grid, q, amplitude=1.0, measure=measure, parameter="log_a")
        self.q = problem.q
        problem.extra_tests = tests
        pattern = len(model.masses) > 1
        if max_step is None:
            max_step = PATTERN_MAX_STEP if pattern else math.inf
        if max_corrector is None:
            max_corrector = PATTERN_MAX_CORRECTOR if pattern else math.inf
        self._use(problem, prefix, solver, Natural(max_halvings=max_halvings, max_corrector=max_corrector,
                                                   max_step=max_step, around_folds=around_folds),
                  bisect=bisect, locate_step=locate_step)

    def step_to(self, a_target: float) -> AmplitudePoint:
        """The wave at amplitude a_target: the first from the linear wave at min(a_target, START_MAX delta0) continued
        to a_target, the next by continuation from the last point (intermediate steps halved on failure)."""
        a = check_amplitude(a_target)
        if not self.continuation.history:
            check_family_amplitude(self.model, a, "a")
            a0 = min(a, START_MAX * self.model.reference_amplitude)     # the linear wave: a guess for a << delta0
            self.problem.set_parameter("a", a0)
            prof, lam = self.problem.linear_guess(self.branch)
            Z = self.problem.pack(prof, lam, parameter=math.log(a0))
            try:
                cp = self.continuation.start(Z)
            finally:
                Z.destroy()
            self._gap = self.problem.located(cp, cp.parameter).gap
            if a0 == a:
                return self.problem.located(cp, cp.parameter)
        located = self._gap_events()
        try:
            cp = self.continuation.step_to(math.log(a))
        except FoldError as err:
            fold = self.problem.located(err.fold, self.continuation.parameter)
            raise FamilyFold(self.q, self.branch, fold, a, self._name, self.model.cell) from None
        except ContinuationError as err:
            raise ConvergenceError("amplitude continuation", err.reason, q=self.q,
                                   **{self._name: math.exp(err.failed)}) from None
        point = self.problem.located(cp, cp.parameter)
        if (point.gap > 0) != (self._gap > 0) and self._gap_events() == located:
            # the gap indicator changed sign but the layer located no root between: the step crossed to another
            # branch (precompressed_branch.py -masses 1,0.01 -q pi/4 -alpha 2 at ds = 0.1 did; its location then
            # fails, an unresolved root: the two points may lie on different branches)
            failed = [cp for cp in self.continuation.events if cp.event == "gap" and cp.unresolved is not None]
            why = (f" (its location failed between {self._name} = {math.exp(failed[-1].bracket[0][0]):.12g} and "
                   f"{math.exp(failed[-1].bracket[1][0]):.12g}: {failed[-1].unresolved})" if failed else "")
            raise ConvergenceError("amplitude continuation", "the gap indicator changed sign with no gap opening "
                                   f"located{why}: a step jumped to another branch (take smaller steps)", q=self.q, a=a)
        self._gap = point.gap
        return point

    solve_at = step_to                  # the wave at amplitude a, by its first name

    @property
    def _name(self):
        """What the family's amplitude is called in messages: A (= max |u|, the 'sup' measure) or a."""
        return "A" if self.problem.measure == "sup" else "a"
    _gap = math.nan

    def _gap_events(self):
        """The number of gap openings the layer has located (not unresolved) and not handed out yet."""
        return sum(1 for cp in self.continuation.events if cp.event == "gap" and cp.unresolved is None)

    def points(self, amplitudes: Iterable[float]) -> Iterator[AmplitudePoint]:
        """Yield the waves at the increasing amplitudes ``amplitudes``."""
        for a in amplitudes:
            yield self.step_to(a)

    def events(self) -> list[AmplitudePoint]:
        """The points located since the last call (AmplitudePoints: the gap openings, and the roots of the caller's
        ``tests``), each with its ``event`` and ``bracket`` (``unresolved``: a root whose location failed, bracketed
        only)."""
        return [replace(self.problem.located(cp, self.continuation.parameter), event=cp.event, bracket=cp.bracket,
                        unresolved=cp.unresolved) for cp in self.continuation.take_events()]


class WavenumberFamily(ContinuationUse):
    """Travelling waves of ``model`` at a fixed amplitude ``a`` (``measure`` 'a1': the first sine coefficient, 'sup':
    A = max |u|), continued in the wavenumber q by the layer's natural algorithm (secant predictor, step halving up
    to ``max_halvings``) from the wave at ``q_start``, itself reached from the linear wave by an
    :class:`AmplitudeFamily` (any law with V''(0) > 0). One SNES under ``prefix``."""

    def __init__(self, model: LatticeModel, a: float, grid: ProfileGrid, q_start: float,
                 prefix: str = PRECOMP_PREFIX, branch: str = "acoustic", measure: str = "a1",
                 solver: Optional[str] = None, max_halvings: int = 6) -> None:
        fam = AmplitudeFamily(model, q_start, grid, prefix, branch, measure=measure, solver=solver)
        try:
            self.first = fam.step_to(a)
            normalised = fam.problem.normalised
        finally:
            fam.destroy()
        self.model, self.grid, self.a = model, grid, self.first.a
        self._use(FamilyProblem(model, grid, self.first.q, amplitude=self.a, measure=measure, normalised=normalised,
                                parameter="q"), prefix, solver, Natural(max_halvings=max_halvings))
        Z = self.problem.pack(self.first.profiles, self.first.lam, parameter=self.first.q)
        try:
            self.continuation.start(Z)
        finally:
            Z.destroy()

    def step_to(self, q: float) -> AmplitudePoint:
        """The wave at wavenumber q (in (0, pi], at least one grid step), by natural steps from the last one."""
        q = check_wavenumber(q, self.grid.h)
        try:
            cp = self.continuation.step_to(q)
        except ContinuationError as err:
            raise ConvergenceError("wavenumber continuation", err.reason, a=self.a, q=err.failed) from None
        return self.problem.located(cp, cp.parameter)

    def points(self, wavenumbers: Iterable[float]) -> Iterator[AmplitudePoint]:
        """Yield the waves at the wavenumbers ``wavenumbers`` in the order given."""
        for q in wavenumbers:
            yield self.step_to(q)


def uncompressed_limit(model: LatticeModel, q: float, grid: ProfileGrid, start: AmplitudePoint,
                       prefix: str = PRECOMP_PREFIX) -> dict:
    """The delta0 / a = 0 wave on ``grid`` from the AmplitudePoint ``start`` (a large-amplitude wave of the family,
    normalised as it is): Omega(q, 0) = ||u(.;q)||^((1-alpha)/2) of eq. dispers on the same grid, with ||u|| =
    max_c ||u_c||_inf over a mass pattern's profiles (the amplitude A of the family's points)."""
    problem = FamilyProblem(model, grid, q, amplitude=math.inf, normalised=start.normalised, parameter="q")
    problem.prefix = prefix
    try:
        X = problem.pack(start.profiles, start.lam)
        stats = problem.solve_state(X)
        lam = float(problem._scalars(X)[0])
        profiles = problem.half_profiles(X)
        norm = max(profile_sup(w, problem.full) for w in profiles)
        X.destroy()
    finally:
        problem.destroy()
    return dict(Omega0=math.sqrt(lam) * norm ** (-(model.alpha - 1) / 2), lam=lam, norm=norm,
                iterations=stats.iterations, profile=profiles[0], profiles=profiles)


@dataclass(frozen=True)
class MassPoint:
    """One dimer wave of the mass-ratio family: m_1 = epsilon, the wave (:class:`AmplitudePoint`), the arclength
    and d epsilon / ds of the unit tangent (a sign change is a fold; nan at the starting points); ``event`` is
    'fold' for a located fold (``unresolved``: why its location failed; the point is then a curve's point near it,
    its wave's iterations 0)."""

    epsilon: float
    wave: AmplitudePoint
    arclength: float
    tangent_epsilon: float
    event: str = None
    unresolved: str = None


class MassFamily(ContinuationUse):
    """Dimer waves (masses 1, epsilon) at fixed q and amplitude a, continued in epsilon from ``epsilon_start`` by
    the layer's pseudo-arclength algorithm (unknowns (w_0, w_1, lam, epsilon); inner product (h/pi) sum w^2 +
    lam^2 + epsilon^2; step ds from ``ds``, grown by 1.5 after easy steps up to ``ds_max``, halved on failure up to
    ``max_halvings``). The two starting points are natural: the amplitude family at epsilon_start and
    epsilon_start + first_step (prefix ``<prefix>natural_``). One SNES (``prefix``) for the arclength steps."""

    def __init__(self, model: LatticeModel, q: float, grid: ProfileGrid, a: float, prefix: str = DIMER_PREFIX,
                 ds: float = 0.02, ds_max: float = 0.1, max_halvings: int = 8, branch: str = "acoustic",
                 solver: Optional[str] = None) -> None:
        if model.cell != 2:
            raise ParameterError("masses", list(model.masses), "must be a pattern of two masses (a dimer)")
        model.require_linear_stiffness("the dimer family is computed for a precompression > 0")
        self.model, self.grid, self.q, self.a = model, grid, check_wavenumber(q, grid.h), check_amplitude(a)
        self.prefix, self.branch, self.solver_kind = prefix, branch, solver
        self._use(FamilyProblem(model, grid, q, amplitude=self.a, parameter="epsilon"), prefix, solver,
                  PseudoArclength(ds=min(ds, ds_max), ds_min=1e-10, ds_max=ds_max, max_halvings=max_halvings))

    def start(self, epsilon_start: float = 1.0, first_step: float = -0.01) -> list[MassPoint]:
        """Two natural points, at epsilon_start and epsilon_start + first_step (the direction of the path)."""
        out, states = [], []
        for e in (epsilon_start, epsilon_start + first_step):
            fam = AmplitudeFamily(self.model.with_masses((self.model.masses[0], e)), self.q, self.grid,
                                  self.prefix + "natural_", self.branch, solver=self.solver_kind)
            try:
                p = list(fam.points(np.geomspace(min(1e-3, self.a), self.a, 12)))[-1]
                self.problem.normalised = fam.problem.normalised
            finally:
                fam.destroy()
            self.problem.set_parameter("epsilon", e)
            states.append(self.problem.pack(p.profiles, p.lam, e))
            out.append(MassPoint(e, p, 0.0, float("nan")))
        chord, dist = self.continuation._chord(*states)
        chord.destroy()
        self.continuation.seed(states, [0.0, dist])
        for Z in states:
            Z.destroy()
        return out

    def snapshot(self) -> dict:
        """What a resume needs (collective; plain arrays, the same on every rank): the last two points' extended
        vectors in the ranks' independent order (:meth:`~hertzpetsc.advdelay.AdvanceDelayProblem.natural_order`;
        ``layout`` says so), their arclengths, the next step and the normalised profile."""
        hist = self.continuation.history
        order = self.problem.natural_order(self.problem.sizes(True)[1])
        return dict(Z=np.array([gathered(Z)[order] for Z, _, _ in hist]), s=np.array([s for _, s, _ in hist]),
                    ds=float(self.continuation.ds), normalised=int(self.problem.normalised), layout="natural")

    def restore(self, snap: Mapping) -> None:
        """Continue from a :meth:`snapshot` (instead of :meth:`start`), on any number of ranks."""
        self.problem.normalised = int(snap["normalised"])
        states, vectors = [], np.asarray(snap["Z"])
        order = self.problem.natural_order(vectors.shape[1])
        back = np.argsort(order)                     # the inverse permutation: Z's entries from the natural ones
        for natural in vectors:
            Z = self.problem.create_vec()
            lo, hi = Z.getOwnershipRange()
            Z.getArray()[:] = natural[back[lo:hi]]
            states.append(Z)
        self.continuation.seed(states, [float(v) for v in snap["s"]])
        self.continuation.ds = float(snap["ds"])
        for Z in states:
            Z.destroy()
        self.problem.set_parameter("epsilon", self.continuation.parameter)

    def step(self) -> MassPoint:
        """One pseudo-arclength step (or a located fold first); returns the MassPoint."""
        try:
            cp = self.continuation.step()
        except ContinuationError as err:
            raise ConvergenceError("mass-ratio continuation", err.reason, q=self.q, epsilon=err.failed) from None
        wave = self.problem.located(cp, self.continuation.parameter)
        return MassPoint(cp.parameter, wave, cp.s, cp.dp_ds, cp.event, cp.unresolved)

    def run(self, epsilon_end: float, max_steps: int = 400) -> Iterator[MassPoint]:
        """Yield MassPoints (and the located events) until epsilon passes epsilon_end, or after max_steps regular
        points, or at epsilon <= 0."""
        steps = 0
        while steps < max_steps:
            p = self.step()
            yield p
            if p.event is not None:
                continue
            steps += 1
            if (p.epsilon - epsilon_end) * (self.model.masses[1] - epsilon_end) < 0 or p.epsilon <= 0:
                return


def wave_at(model: LatticeModel, q: float, A: float, grid: ProfileGrid, prefix: str = PRECOMP_PREFIX,
            branch: str = "acoustic", a_start: float = 1e-3, ds: float = 0.25,
            solver: Optional[str] = None) -> AmplitudePoint:
    """The travelling wave of ``model`` with per-bead wavenumber q and amplitude A = max_c ||u_c||_inf: A is a
    border row of the problem (measure 'sup'), reached by natural steps in log A of size ``ds`` from the linear wave
    at ``a_start`` delta0 (precompressed lattices; at least :func:`amplitude_floor`, as A must be). Returns the
    AmplitudePoint (omega at that A)."""
    A = check_family_amplitude(model, A, "A")
    fam = AmplitudeFamily(model, q, grid, prefix, branch, measure="sup", solver=solver)
    try:
        a0 = min(max(a_start * model.reference_amplitude, amplitude_floor(model)), A)
        n = max(1, int(math.ceil((math.log(A) - math.log(a0)) / ds)))
        return list(fam.points(np.geomspace(a0, A, n + 1)))[-1]
    finally:
        fam.destroy()


def wave_of_amplitude(model: LatticeModel, q: float, A: float, grid: ProfileGrid, prefix: str = PRECOMP_PREFIX,
                      branch: str = "acoustic") -> tuple[BranchPoint, float]:
    """The wave of any ``model`` at per-bead wavenumber q and amplitude A = max_c ||u_c||_inf, as (``BranchPoint``,
    scale) for :func:`~hertzpetsc.waves.orbit_on_chain` (``scale=``): with a linear stiffness V''(0) > 0
    (precompression; Toda, FPU), :func:`wave_at` (A
    imposed, the point at its physical amplitude, scale 1); without (eq. ad is scale-invariant), the q-branch from
    the binary oscillation continued to q on ``grid`` (steps pi / round(pi / q)), scaled by A / ||u||_inf.
    Collective over the grid's communicator."""
    A = check_wave_amplitude(model, A, "A")
    if model.law.linear_stiffness > 0:
        return wave_at(model, q, A, grid, prefix, branch).branch_point(model, grid.h), 1.0
    from .qbranch import BranchContinuation, ContinuationParameters
    cont = BranchContinuation(ContinuationParameters(model=model, M=max(1, round(math.pi / q)),
                                                     cells_per_pi=grid.K, q_stop=q), grid.comm)
    try:
        point = list(cont.points())[-1]
    finally:
        cont.destroy()
    return point, A / point.diagnostics.norm_inf
