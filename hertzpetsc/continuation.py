"""The one continuation layer: natural and pseudo-arclength continuation of any problem with a parameter, with fold
and event detection (the paper's continuation in q, section 3.1, is one use; :mod:`hertzpetsc.qbranch`).

A problem (:class:`ContinuationProblem`) works on an *extended* vector Z = (X, p): its unknowns X and, as the last
entry (on the last rank), the continuation parameter p (q, an amplitude, a mass ratio, delta0, alpha, a driving
frequency ...). Its one corrector :meth:`ContinuationProblem.solve` solves

    F(X; p) = 0,     r . Z = c

for a given row r and value c. The natural algorithm passes the parameter row r = e_p, c = p* (the parameter is
fixed: problems take their fixed-parameter path); pseudo-arclength passes r = W t, c = W t . Z_pred (t the unit
secant tangent in the problem's inner product W, Z_pred = Z_1 + ds t). So both algorithms drive every problem, and
a problem implements one bordered solve.

:class:`Natural` (secant predictor in p, step halving on failure, doubling after success; optionally
pseudo-arclength steps around an S-shaped pair of folds where the halvings stall) and
:class:`PseudoArclength` (secant tangent, step ds adapted to the Newton iterations, halved on failure) are the two
algorithms; :class:`Continuation` is the loop: it keeps the last two points (Vecs), yields a
:class:`ContinuationPoint` per accepted step, detects folds (a sign change of dp/ds) and the sign changes of the
problem's test functions, and locates both on the curve by re-solving with the chord between the bracketing points
as the local coordinate (successive parabolic interpolation for a fold, the Illinois rule for a root). The step
control is bounded: at most ``max_halvings`` reductions per step and ``max_step_changes`` in all, so it cannot cycle
without progress. Resume: :meth:`Continuation.seed` with the last two stored points.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Collection, Iterator, Optional, Sequence, Union

import numpy as np

from .console import note
from .errors import ConvergenceError, ParameterError, check_integer, check_real

if TYPE_CHECKING:
    from petsc4py import PETSc


def illinois(f, a, fa, b, fb, tol, max_iter, bisect=False, bracket=False):
    """A root of f between a and b (fa = f(a), fb = f(b) of opposite signs) by the Illinois rule (regula falsi with
    the stale end's value halved): the last iterate, when the bracket is shorter than ``tol`` or f vanishes there,
    or after ``max_iter`` evaluations. ``bisect``: halve the bracket instead, until it is at most ``tol`` long (a
    verdict's margin, flat on one side, makes the Illinois rule crawl). ``bracket``: return (x, ((a, f(a)), (b,
    f(b)))), the final bracket's ends in increasing order with f's values there (not the halved ones)."""
    raw = {a: fa, b: fb}
    side, x = 0, None
    for _ in range(max_iter):
        x = 0.5 * (a + b) if bisect else (a * fb - b * fa) / (fb - fa)
        fx = raw[x] = f(x)
        width = abs(b - a)                       # the Illinois rule stops on the bracket before this trial
        if fx == 0.0:
            a = b = x
            break
        if fx * fb < 0:
            a, fa = b, fb
            side = 0
        else:
            if side == -1 and not bisect:
                fa *= 0.5
            side = -1
        b, fb = x, fx
        if (abs(b - a) if bisect else width) <= tol:
            break
    if bracket:
        return x, tuple(sorted(((a, raw[a]), (b, raw[b]))))
    return x


def _discard(evals):
    """Destroy the trial solutions of a location that failed (``evals``: parameter -> (Z, its, value))."""
    for Z, _, _ in evals.values():
        Z.destroy()
    evals.clear()


def golden_maximum(f, a, b, tol):
    """(x, f(x)) maximising f on [a, b] by golden-section search to an interval of ``tol`` (f unimodal there), the
    ends included among the candidates (the one golden-section search: Floquet maxima over twists, resonance peaks,
    best-fit phases)."""
    g = (math.sqrt(5) - 1) / 2
    best = max(((a, f(a)), (b, f(b))), key=lambda e: e[1])
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = f(c), f(d)
    while b - a > tol:
        if fc >= fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = f(d)
    return max((best, (c, fc), (d, fd)), key=lambda e: e[1])


class ContinuationError(ConvergenceError):
    """The continuation could not take a step from ``last`` (the last converged point; the caller says what it
    kept)."""

    def __init__(self, parameter, last, failed, reason):
        self.last, self.failed = last, failed
        done = f"last converged {parameter} = {last:.12g}" if last == last else "no point converged"
        RuntimeError.__init__(self, f"continuation stopped: no convergence at {parameter} = {failed:.12g} even "
                                    f"after step reduction ({reason}); {done}")
        self.what, self.reason, self.where = "continuation", reason, {parameter: failed}


class FoldError(ContinuationError):
    """The curve turns back at a fold of the parameter before the step's target (:meth:`Continuation.step_to`
    followed it by pseudo-arclength and came back past the step's start). ``fold``: the point of the curve farthest
    towards the target (the located fold, or the farthest point reached when the fold could not be located), a
    :class:`ContinuationPoint` with the problem's report."""

    def __init__(self, parameter: str, last: float, failed: float, reason: str, fold: ContinuationPoint) -> None:
        super().__init__(parameter, last, failed, reason)
        self.fold = fold


class ContinuationProblem:
    """The hooks a problem gives the continuation layer (defaults where one makes sense, else NotImplementedError).

    ``parameter`` names the continuation parameter; it is the last entry of every extended vector."""

    parameter = "p"

    def create_vec(self) -> PETSc.Vec:
        """A new extended Vec Z = (X, p) (parameter last, on the last rank)."""
        raise NotImplementedError

    def solve(self, Z: PETSc.Vec, row: Optional[PETSc.Vec] = None, value: Optional[float] = None) -> int:
        """Correct Z in place so that F(X; p) = 0 and row . Z = value; row None: the parameter is fixed at its
        entry of Z (natural continuation; ``value``, when given, is that entry, which the caller set: the problem
        need not read it from Z, a reduction). Returns the number of Newton iterations (>= 1); raises
        :class:`~hertzpetsc.errors.ConvergenceError` when it fails."""
        raise NotImplementedError

    def weights(self) -> Optional[PETSc.Vec]:
        """Diagonal weights W of the arclength inner product (a Vec like Z), or None for the Euclidean one."""
        return None

    def predictor_ratio(self, p_from: float, p_to: float) -> float:
        """s(p_from) / s(p_to) for a factor s(p) such that s(p) X varies slowly with p (the secant predictor
        extrapolates s X): 1 (no rescaling)."""
        return 1.0

    def test_functions(self, Z: PETSc.Vec) -> Mapping[str, float]:
        """{name: value} of functions whose sign changes mark events on the curve (none by default)."""
        return {}

    def report(self, Z: PETSc.Vec) -> dict:
        """What a point reports (plain data on every rank); the layer adds the parameter and arclength."""
        return {}


class LazyTests(Mapping):
    """Test-function values computed when first read (and kept): {name: function of no argument}. A problem whose
    tests are expensive returns one, so that locating one test's root does not compute the others; the functions
    must hold what they need (not the Vec Z, which the layer may destroy before they are read)."""

    def __init__(self, functions):
        self._functions, self._values = dict(functions), {}

    def __getitem__(self, name):
        if name not in self._values:
            self._values[name] = float(self._functions[name]())
        return self._values[name]

    def __iter__(self):
        return iter(self._functions)

    def __len__(self):
        return len(self._functions)


@dataclass
class ContinuationPoint:
    """An accepted point: the parameter, the arclength s from the start, dp/ds of the unit tangent (nan for the
    first point), the Newton iterations, the event that located it (None, 'fold' or a test function's name),
    the problem's report and its test functions."""

    parameter: float
    s: float
    dp_ds: float
    iterations: int
    event: str = None
    report: dict = field(default_factory=dict)
    tests: dict = field(default_factory=dict)
    substeps: int = 1
    bracket: tuple = None      # a located root: ((p, value), (p, value)) of the last bracket, the root between them
    # None: located to the layer's tolerance; else why the location stopped (a trial whose corrector failed): the
    # event is only bracketed, by ``bracket`` in the parameter (None for a fold), and the point is the bracket's
    # solved end nearest the root (a fold: the known point beyond the other two)
    unresolved: str = None


def _owns_last(Z):
    """Whether this rank holds the last entry of Z (the parameter)."""
    lo, hi = Z.getOwnershipRange()
    return lo <= Z.getSize() - 1 < hi


def _parameter(Z):
    """The last entry of Z on every rank."""
    local = float(Z.getArray(readonly=True)[-1]) if _owns_last(Z) else 0.0
    comm = Z.getComm().tompi4py()
    return comm.allreduce(local) if comm.Get_size() > 1 else local


def set_parameter(Z, value):
    """Set the last entry of Z (collective)."""
    if _owns_last(Z):
        Z.getArray()[-1] = value


def _check_algorithm(alg, positive, **integers):
    """The checks of both algorithms' step control, in this order: the integers max_halvings (>= 0),
    max_step_changes (>= 1) and ``integers`` (name: least value), then max_corrector and ``positive`` > 0."""
    for name, least in dict(max_halvings=0, max_step_changes=1, **integers).items():
        object.__setattr__(alg, name, check_integer(name, getattr(alg, name), least))
    for name in ("max_corrector",) + positive:
        value = getattr(alg, name)
        if not (isinstance(value, float) and value == math.inf):      # max_step, max_corrector: inf, no bound
            object.__setattr__(alg, name, check_real(name, value, f"{name}", 0.0))


@dataclass(frozen=True)
class Natural:
    """Natural continuation: steps in the parameter, secant predictor (in s(p) X,
    :meth:`~ContinuationProblem.predictor_ratio`), step halved on failure (or when the corrector moves X by more than
    ``max_corrector``, relative, sup norm, or a test function's own solve raises ConvergenceError) and doubled after a
    success, up to the next target; no step longer than ``max_step`` in the parameter. ``around_folds`` > 0: when
    the halvings are exhausted (natural steps cannot pass a fold of the parameter: they stall at it), at most that
    many pseudo-arclength steps from the last two points, until the parameter passes the target (then a natural step
    back to it), so that the curve is followed through an S-shaped pair of folds; the curve turning back past the
    step's start (a single fold) ends the step as a failure. 0: every exhausted step is a failure."""

    max_halvings: int = 8
    max_corrector: float = 0.25
    max_step_changes: int = 64
    max_step: float = math.inf
    around_folds: int = 0

    def __post_init__(self):
        _check_algorithm(self, ("max_step",), around_folds=0)


@dataclass(frozen=True)
class PseudoArclength:
    """Pseudo-arclength continuation: unknowns (X, p), secant tangent t in the problem's inner product, the row
    t . (Z - Z_pred) = 0; the step ds grows by ``growth`` after steps of at most ``easy`` Newton iterations, up to
    ``ds_max``, and is halved on failure (at most ``max_halvings`` times per step, never below ``ds_min``). A
    corrector that needs more than ``max_iterations`` or lands farther than ``max_corrector`` ds from the
    prediction is a failure (it may have jumped to another part of the curve), and so is a point whose test
    functions raise ConvergenceError (e.g. multipliers that fail their closed-form checks)."""

    ds: float = 0.02
    ds_min: float = 1e-8
    ds_max: float = 0.1
    growth: float = 1.5
    easy: int = 3
    max_halvings: int = 8
    max_step_changes: int = 64
    max_iterations: int = 12
    max_corrector: float = 1.0

    def __post_init__(self):
        for name in ("ds", "ds_min", "ds_max"):
            object.__setattr__(self, name, check_real(name, getattr(self, name), "the arclength step", 0.0))
        if not self.ds_min <= self.ds <= self.ds_max:
            raise ParameterError("ds", self.ds, f"must lie in [ds_min, ds_max] = [{self.ds_min:g}, {self.ds_max:g}]")
        object.__setattr__(self, "growth", check_real("growth", self.growth, "the step's growth factor", 1.0,
                                                      lo_open=False))
        _check_algorithm(self, (), max_iterations=1, easy=0)


class ContinuationUse:
    """A use of the layer: its ``problem`` and the :class:`Continuation` on it; :meth:`destroy` frees both."""

    def _use(self, problem, prefix, solver, algorithm, **options):
        """Take ``problem`` (an :class:`~hertzpetsc.advdelay.AdvanceDelayProblem`) with its SNES under ``prefix`` built
        now (``solver``: its linear solves; the Z layout for pseudo-arclength) and the layer on it (``options``:
        those of :class:`Continuation`)."""
        problem.prefix = prefix
        problem.solver(isinstance(algorithm, PseudoArclength), prefix, solver)
        self.problem = problem
        self.continuation = Continuation(problem, algorithm, **options)

    def destroy(self) -> None:
        self.continuation.destroy()
        self.problem.destroy()


class Continuation:
    """The continuation loop over a :class:`ContinuationProblem` with a :class:`Natural` or
    :class:`PseudoArclength` algorithm (module docstring). Collective over the problem's communicator."""

    def __init__(self, problem: ContinuationProblem, algorithm: Union[Natural, PseudoArclength],
                 detect_folds: bool = True, locate_tol: float = 1e-9, locate_max: int = 40,
                 bisect: Collection[str] = (), locate_step: Optional[float] = None) -> None:
        if not isinstance(algorithm, (Natural, PseudoArclength)):
            raise ParameterError("algorithm", algorithm, "must be Natural(...) or PseudoArclength(...)")
        if locate_step is not None and not (locate_step > 0 and math.isfinite(locate_step)):
            raise ParameterError("locate_step", locate_step, "must be a finite number > 0 (or None)")
        self.problem, self.algorithm = problem, algorithm
        # test functions located by bisection (values that are not smooth across the root, e.g. a verdict's margin,
        # flat on one side, which slows the Illinois rule); locate_step: stop when the bracket is at most this long
        # in the parameter (natural steps), else locate_tol times the bracketing step
        self.bisect, self.locate_step = frozenset(bisect), locate_step
        # the natural steps (also the first steps of a pseudo-arclength run)
        self.natural = algorithm if isinstance(algorithm, Natural) else Natural()
        self.detect_folds, self.locate_tol, self.locate_max = detect_folds, locate_tol, locate_max
        self.history = []          # [(Z, s, tests)] of the last two accepted points
        self._known = {}           # id(Z) -> (Z, parameter) of the history's points (read without a reduction)
        self.s = 0.0
        self.ds = getattr(algorithm, "ds", None)
        self.changes = 0
        self.W = problem.weights()
        self.events = []           # points located by natural steps (fold-free events), taken by the caller

    # --- vector helpers ------------------------------------------------------------------------------------
    def _dot(self, a, b):
        if self.W is None:
            return a.dot(b)
        w = a.copy()
        w.pointwiseMult(w, self.W)
        out = w.dot(b)
        w.destroy()
        return out

    def _norm(self, a):
        return math.sqrt(max(self._dot(a, a), 0.0))

    def _accept(self, Z, its, parameter=None, tests=None):
        """Append Z to the history (``parameter``: Z's, when the caller knows it; else read from Z; ``tests``: its
        test functions, when the caller has them)."""
        p = _parameter(Z) if parameter is None else parameter
        tests = self.problem.test_functions(Z) if tests is None else tests
        self._remember(Z, self.s, tests, p)
        return ContinuationPoint(parameter=p, s=self.s, dp_ds=math.nan, iterations=its,
                                 report=self.problem.report(Z), tests=tests)

    def _remember(self, Z, s, tests, p):
        self.history.append((Z, s, tests))
        self._known[id(Z)] = (Z, p)
        while len(self.history) > 2:
            old = self.history.pop(0)[0]
            self._known.pop(id(old), None)
            old.destroy()

    def _p(self, Z):
        """The parameter of Z: kept for the points of the history (a natural step needs no reduction for it),
        else read from Z (collective)."""
        known = self._known.get(id(Z))
        return known[1] if known is not None and known[0] is Z else _parameter(Z)

    def _solve(self, Z, row=None, value=None):
        its = self.problem.solve(Z, row, value)
        if its < 1:
            raise ConvergenceError("continuation corrector", "a step was accepted without a Newton iteration",
                                   **{self.problem.parameter: _parameter(Z)})
        return its

    # --- start, resume --------------------------------------------------------------------------------------
    def start(self, Z0: PETSc.Vec) -> ContinuationPoint:
        """Correct the first point at its parameter (natural); Z0 is copied. Returns its ContinuationPoint."""
        Z = Z0.copy()
        its = self._solve(Z)
        return self._accept(Z, its)

    def seed(self, states: Sequence[PETSc.Vec], arclengths: Optional[Sequence[float]] = None) -> None:
        """Resume from stored points: ``states`` are the last (up to two) extended Vecs, oldest first, already
        solutions (copied, not corrected)."""
        for k, Z in enumerate(states[-2:]):
            self._remember(Z.copy(), arclengths[k] if arclengths else 0.0, self.problem.test_functions(Z),
                           _parameter(Z))
        if self.history:
            self.s = self.history[-1][1]

    @property
    def parameter(self) -> float:
        return self._p(self.history[-1][0]) if self.history else math.nan

    @property
    def previous(self) -> float:
        """The parameter of the point accepted before the last (nan if none)."""
        return self._p(self.history[0][0]) if len(self.history) == 2 else math.nan

    # --- natural steps ----------------------------------------------------------------------------------------
    def _natural_predict(self, p_new):
        prob = self.problem
        Z1 = self.history[-1][0]
        p1 = self._p(Z1)
        Z = Z1.copy()
        Z0 = self.history[0][0] if len(self.history) == 2 else None
        p0 = self._p(Z0) if Z0 is not None else p1
        if abs(p1 - p0) > 1e-12 * max(1.0, abs(p1)):      # else the same point twice: no secant
            f = (p_new - p1) / (p1 - p0)
            Z.scale((1 + f) * prob.predictor_ratio(p1, p_new))
            Z.axpy(-f * prob.predictor_ratio(p0, p_new), Z0)
        else:
            Z.scale(prob.predictor_ratio(p1, p_new))
        set_parameter(Z, p_new)
        return Z

    def step_to(self, p_target: float) -> ContinuationPoint:
        """Natural continuation from the last point to ``p_target`` (intermediate steps are not reported)."""
        alg = self.natural
        p_start = self.parameter
        # the last two points, to go around a fold from (natural steps near it crawl: their secant is ill-conditioned)
        start = ([(Z.copy(), s) for Z, s, _ in self.history]
                 if alg.around_folds and not self._detouring and len(self.history) == 2 else None)
        try:
            return self._natural_steps(p_start, p_target, start)
        finally:
            for Z, _ in start or ():
                Z.destroy()

    def _natural_steps(self, p_start, p_target, start):
        alg = self.natural
        p_last = p_start
        dp = math.copysign(min(abs(p_target - p_last), alg.max_step), p_target - p_last)
        total_its, halvings, substeps = 0, 0, 0
        while True:
            p = p_target if abs(p_last + dp - p_target) <= 1e-14 * max(1.0, abs(p_target)) else p_last + dp
            Z = self._natural_predict(p)
            pred = Z.copy()
            failure = None
            try:
                its = self._solve(Z, None, p)
                total_its += its
                size = self._corrector_size(Z, pred)
                if size > alg.max_corrector:
                    failure = f"corrector moved the solution by {size:.3g} > max_corrector"
                else:
                    # every test read now (the loop below reads them all): a test function whose own solve fails
                    # (e.g. LazyTests of a companion wave) fails the step, which is halved like a failed corrector
                    tests = self.problem.test_functions(Z)
                    for name in tests:
                        tests[name]
            except ConvergenceError as err:
                failure = f"reason {err.reason}"
            pred.destroy()
            if failure is not None:
                Z.destroy()
                halvings += 1
                self.changes += 1
                if halvings > alg.max_halvings or self.changes > alg.max_step_changes:
                    if start is None:
                        raise ContinuationError(self.problem.parameter, p_last, p, failure)
                    self._around_fold(start, p_start, p_target, p_last, p, failure)
                    self._detouring = True              # the step back to the target: no second detour
                    try:
                        return self.step_to(p_target)
                    finally:
                        self._detouring = False
                dp *= 0.5
                continue
            halvings = 0
            substeps += 1
            self.s += abs(p - p_last)
            previous = self.history[-1]
            point = self._accept(Z, total_its, parameter=p, tests=tests)
            for name, value in point.tests.items():
                g0 = previous[2].get(name)
                if g0 is not None and g0 * value < 0:
                    located = self._locate_root(previous[0], Z, previous[1], name, g0, value, natural=True)
                    if located is not None:
                        self.events.append(located)
            if p == p_target:
                self.changes = 0
                point.substeps = substeps
                return point
            p_last = p
            dp = p_target - p_last if abs(2 * dp) >= abs(p_target - p_last) else 2 * dp
            dp = math.copysign(min(abs(dp), alg.max_step), dp)

    _detouring = False

    def _around_fold(self, start, p_start, p_target, p_last, p_failed, failure):
        """Pseudo-arclength steps (:meth:`step`) from the two points ``start`` [(Z, s)] (the last two before the
        natural steps to ``p_target`` from ``p_start``), at most ``around_folds``, until the parameter passes
        ``p_target`` (the natural step to it then starts from the last two of them). The first step is the two
        points' distance, and no step is longer than it or the natural step; the folds and the roots of the test
        functions located on the way join :attr:`events` (those the natural steps had located are not repeated).
        Raises :class:`ContinuationError` (the natural step's ``failure``, at ``p_failed`` from ``p_last``; the
        continuation is then back at ``start``) when the steps fail, or the curve turns back past ``p_start`` (a
        :class:`FoldError` naming the fold, with the curve's farthest point), or it has not passed the target after
        ``around_folds`` steps."""
        alg = self.natural
        self.seed([Z for Z, _ in start], [s for _, s in start])
        chord, dist = self._chord(start[0][0], start[1][0])          # the history's two points (copies of them)
        chord.destroy()
        longest = max(abs(p_target - p_start), dist)
        known, folds, furthest = list(self.events), [], None
        same = max(1e-6 * longest, self.locate_step or 0.0)      # a root the natural steps located
        saved = self.algorithm, self.ds, self._pending
        self.algorithm = PseudoArclength(ds=dist, ds_min=min(dist, 1e-12 * longest), ds_max=longest)
        self.ds, self._pending, self.changes, self._detouring = dist, [], 0, True
        direction = math.copysign(1.0, p_target - p_start)
        why = f"{failure}; then {alg.around_folds} pseudo-arclength steps did not pass it"
        turned = None
        try:
            for _ in range(alg.around_folds):
                point = self.step()
                if furthest is None or (point.parameter - furthest.parameter) * direction > 0:
                    furthest = point
                if point.event is not None:
                    if point.event == "fold":
                        folds.append(point.parameter)
                    if not any(e.event == point.event and abs(e.parameter - point.parameter) <= same for e in known):
                        self.events.append(point)
                    continue
                if (point.parameter - p_target) * direction >= 0:
                    while self._pending:
                        self.events.append(self._pending.pop(0))
                    return
                if (point.parameter - p_start) * direction < 0:
                    at = f" = {folds[-1]:.12g}" if folds else ""
                    why = (f"{failure}; the curve turns back at a fold of {self.problem.parameter}{at} "
                           f"(pseudo-arclength steps came back past the step's start {p_start:.12g})")
                    turned = furthest
                    break
        except ContinuationError as err:
            why = f"{failure}; then pseudo-arclength steps failed too ({err.reason})"
        finally:
            self.algorithm, self.ds, self._pending = saved
            self._detouring = False
        self.seed([Z for Z, _ in start], [s for _, s in start])      # back where the natural steps started
        if turned is not None:
            raise FoldError(self.problem.parameter, p_last, p_failed, why, turned)
        raise ContinuationError(self.problem.parameter, p_last, p_failed, why)

    def _corrector_size(self, Z, pred):
        """||X - X_pred||_inf / ||X||_inf (the parameter left out): both norms from the local arrays, in one
        reduction."""
        z, zp = Z.getArray(readonly=True), pred.getArray(readonly=True)
        k = len(z) - 1 if _owns_last(Z) else len(z)
        local = np.array([np.max(np.abs(z[:k] - zp[:k]), initial=0.0), np.max(np.abs(z[:k]), initial=0.0)])
        comm = Z.getComm().tompi4py()
        if comm.Get_size() > 1:
            from mpi4py import MPI
            comm.Allreduce(MPI.IN_PLACE, local, op=MPI.MAX)
        return local[0] / max(local[1], 1e-300)

    # --- pseudo-arclength steps -----------------------------------------------------------------------------
    def _arclength_solve(self, t, Z1, ds):
        """The point at W-projected distance ds from Z1 along t (None if the corrector fails, needs too many
        iterations or lands too far from the prediction)."""
        Zp = Z1.copy()
        Zp.axpy(ds, t)
        pred = Zp.copy()
        row = t.copy()
        if self.W is not None:
            row.pointwiseMult(row, self.W)
        value = row.dot(Zp)
        alg = self.algorithm
        try:
            its = self._solve(Zp, row, value)
        except ConvergenceError:
            its = None
        row.destroy()
        if its is not None:
            pred.axpy(-1.0, Zp)
            if its > alg.max_iterations or self._norm(pred) > alg.max_corrector * abs(ds):
                its = None
        pred.destroy()
        if its is None:
            Zp.destroy()
            return None, 0
        return Zp, its

    def step(self) -> ContinuationPoint:
        """One pseudo-arclength step (needs two points: :meth:`start` then :meth:`step_to` or :meth:`seed`);
        returns the new ContinuationPoint, or first the fold or event points located in the step (the regular
        point then follows at the next calls)."""
        alg = self.algorithm
        if not isinstance(alg, PseudoArclength):
            raise ParameterError("algorithm", alg, "step() is pseudo-arclength; natural continuation uses step_to()")
        if len(self.history) < 2:
            raise ParameterError("points", len(self.history), "pseudo-arclength needs two points to start")
        if self._pending:
            return self._pending.pop(0)
        (Zm, sm, _), (Z1, s1, tests1) = self.history
        pm, p1 = self._p(Zm), self._p(Z1)
        t = self._chord(Zm, Z1)[0]
        ds, halvings = self.ds, 0
        while True:
            Z, its = self._arclength_solve(t, Z1, ds)
            if Z is not None:
                try:                   # as in natural steps: a point whose test functions fail is not accepted
                    tests = self.problem.test_functions(Z)
                    for name in tests:
                        tests[name]
                    break
                except ConvergenceError:
                    Z.destroy()
            halvings += 1
            self.changes += 1
            if halvings > alg.max_halvings or ds * 0.5 < alg.ds_min or self.changes > alg.max_step_changes:
                dp = _parameter(t)
                t.destroy()
                raise ContinuationError(self.problem.parameter, p1, p1 + ds * dp, "arclength corrector")
            ds *= 0.5
        t.destroy()
        self.changes = 0
        Zm = Zm.copy()                 # _accept destroys the oldest point of the history (Z1 stays in it)
        self.s = s1 + ds
        point = self._accept(Z, its, tests=tests)
        t_new = self._chord(Z1, Z)[0]
        point.dp_ds = _parameter(t_new)
        t_new.destroy()
        located = []
        if self.detect_folds and (p1 - pm) * (point.parameter - p1) < 0:
            located.append(self._locate_fold(Zm, Z1, Z, sm))
        for name, value in point.tests.items():
            if name in tests1 and tests1[name] * value < 0:
                located.append(self._locate_root(Z1, Z, s1, name, tests1[name], value))
        Zm.destroy()
        located = sorted((p for p in located if p is not None), key=lambda p: p.s)
        if its <= alg.easy and halvings == 0:
            self.ds = min(alg.ds_max, alg.growth * ds)
        elif halvings:
            self.ds = ds
        if located:
            self._pending = located[1:] + [point]
            return located[0]
        return point

    _pending = ()

    def _chord(self, Za, Zb):
        """Unit W-direction from Za to Zb (the secant tangent when they are the last two points) and their
        W-distance."""
        c = Zb.copy()
        c.axpy(-1.0, Za)
        n = self._norm(c)
        if not n > 0:
            c.destroy()
            raise ParameterError("points", "identical", "the last two points coincide: no tangent")
        c.scale(1.0 / n)
        return c, n

    def _on_chord(self, origin, c, evals, value_of):
        """A function sigma -> value at the curve point whose W-projection on the chord c from ``origin`` is sigma
        (re-solved with the arclength row); the solved points are kept in ``evals``."""
        def at(sigma):
            Z, its = self._arclength_solve(c, origin, sigma)
            if Z is None:
                raise ConvergenceError("event location", "arclength corrector", sigma=sigma)
            v = value_of(Z)
            if sigma in evals:
                evals[sigma][0].destroy()
            evals[sigma] = (Z, its, v)
            return v
        return at

    def _located(self, evals, sigma, s, name, bracket=None):
        """The ContinuationPoint of the solved point ``evals[sigma]`` (arclength s; the caller frees the others)."""
        Z, its, _ = evals.pop(sigma)
        point = ContinuationPoint(parameter=_parameter(Z), s=s, dp_ds=0.0 if name == "fold" else math.nan,
                                  iterations=its, event=name, report=self.problem.report(Z),
                                  tests=self.problem.test_functions(Z), bracket=bracket)
        Z.destroy()
        return point

    def _locate_fold(self, Zm, Z1, Z2, s_origin):
        """The extremum of p between Zm and Z2 (p(Z1) beyond both): successive parabolic interpolation in the
        projection sigma on the chord Zm -> Z2, started from the three known points."""
        c, length = self._chord(Zm, Z2)
        d = Z1.copy()
        d.axpy(-1.0, Zm)
        sigma1 = self._dot(c, d)
        d.destroy()
        evals = {}
        at = self._on_chord(Zm, c, evals, _parameter)
        xs, ps = [0.0, sigma1, length], [_parameter(Zm), _parameter(Z1), _parameter(Z2)]
        try:
            x = None
            for _ in range(self.locate_max):
                (a, b, e), (fa, fb, fe) = xs, ps
                den = (b - a) * (fb - fe) - (b - e) * (fb - fa)
                if den == 0.0:
                    break
                x_new = b - 0.5 * ((b - a) ** 2 * (fb - fe) - (b - e) ** 2 * (fb - fa)) / den
                x_new = min(max(x_new, a), e)
                done = x is not None and abs(x_new - x) <= self.locate_tol * length
                x = x_new
                fx = at(x)
                if done:
                    break
                # keep the point with the extreme p and its two neighbours
                cand = sorted(zip(xs + [x], ps + [fx]))
                sign = 1.0 if fb >= max(fa, fe) else -1.0
                k = max(range(len(cand)), key=lambda i: sign * cand[i][1])
                k = min(max(k, 1), len(cand) - 2)
                xs, ps = [u[0] for u in cand[k - 1:k + 2]], [u[1] for u in cand[k - 1:k + 2]]
            if x is None:
                raise ConvergenceError("fold location", "degenerate parabola", sigma=sigma1)
            return self._located(evals, x, s_origin + x, "fold")
        except ConvergenceError as err:
            # the fold is kept, unresolved: at Z1, the known point beyond the other two
            return self._unresolved("fold", Z1, s_origin + sigma1, None, err)
        finally:
            _discard(evals)
            c.destroy()

    def _locate_root(self, Z1, Z2, s_origin, name, g1, g2, natural=False):
        """The zero of the test function ``name`` between Z1 and Z2 (values g1, g2 of opposite signs) by the
        Illinois rule: in the projection on the chord Z1 -> Z2, or, between ``natural`` points, in the parameter
        (bisection for the tests in ``bisect``), each trial solved from the linear interpolation of Z1 and Z2, the
        located point keeping the last bracket. A trial whose corrector fails ends the location: the root is then
        kept as bracketed only (:meth:`_unresolved`), never dropped."""
        evals, c = {}, None
        trial = []                 # the trial being solved (a failure: inside the Illinois rule's current bracket)
        if natural:
            a, b = _parameter(Z1), _parameter(Z2)
            tol = self.locate_step if self.locate_step is not None else self.locate_tol * abs(b - a)

            def at(p):
                trial[:] = [p]
                Z = Z1.copy()
                f = (p - a) / (b - a)
                Z.scale(1 - f)
                Z.axpy(f, Z2)
                set_parameter(Z, p)
                try:
                    its = self._solve(Z, None, p)
                    v = self.problem.test_functions(Z)[name]
                except ConvergenceError:
                    Z.destroy()
                    raise
                if p in evals:
                    evals[p][0].destroy()
                evals[p] = (Z, its, v)
                return v
        else:
            c, b = self._chord(Z1, Z2)
            a, tol = 0.0, self.locate_tol * b
            on_chord = self._on_chord(Z1, c, evals, lambda Z: self.problem.test_functions(Z)[name])

            def at(sigma):
                trial[:] = [sigma]
                return on_chord(sigma)
        try:
            x, bracket = illinois(at, a, g1, b, g2, tol, self.locate_max, bisect=natural and name in self.bisect,
                                  bracket=True)
            return self._located(evals, x, s_origin + abs(x - a), name, bracket if natural else None)
        except ConvergenceError as err:
            # the current bracket: the solved trials next to the failed one (the Illinois rule's evaluations all lie
            # at or outside its bracket), in the parameter
            known = sorted([(a, g1, Z1), (b, g2, Z2)] + [(x, v, Z) for x, (Z, _, v) in evals.items()],
                           key=lambda e: e[0])
            x_fail = trial[0] if trial else 0.5 * (a + b)
            k = next((i for i in range(1, len(known)) if known[i][0] > x_fail), len(known) - 1)
            lo, hi = known[k - 1], known[k]
            if lo[1] * hi[1] > 0:                 # (not expected) the failed trial outside a sign change: the ends
                lo, hi = known[0], known[-1]
            end = min((lo, hi), key=lambda e: abs(e[1]))
            bracket = tuple((self._p(Z), v) for _, v, Z in (lo, hi))
            return self._unresolved(name, end[2], s_origin + abs(end[0] - a), bracket, err)
        finally:
            _discard(evals)
            if c is not None:
                c.destroy()

    def _unresolved(self, name, Z, s, bracket, err):
        """The event ``name`` that its location could not resolve (``err``: the failed trial's ConvergenceError),
        as the solved point Z (arclength s) with its ``bracket``, marked :attr:`ContinuationPoint.unresolved`, and
        a note saying so: a failed location is reported, never silent."""
        p = self._p(Z)
        between = (f"bracketed in [{min(bracket[0][0], bracket[1][0]):.12g}, {max(bracket[0][0], bracket[1][0]):.12g}]"
                   if bracket is not None else f"kept at the curve's point {self.problem.parameter} = {p:.12g}")
        reason = str(err)
        note(f"{'the fold' if name == 'fold' else 'the event ' + repr(name)} of {self.problem.parameter} was not "
             f"located (a trial failed: {reason}); unresolved, {between}", Z.getComm())
        return ContinuationPoint(parameter=p, s=s, dp_ds=0.0 if name == "fold" else math.nan, iterations=0,
                                 event=name, report=self.problem.report(Z), tests=self.problem.test_functions(Z),
                                 bracket=bracket, unresolved=reason)

    def take_events(self) -> list[ContinuationPoint]:
        """The points located by the natural steps since the last call (sorted by arclength)."""
        out, self.events = sorted(self.events, key=lambda p: p.s), []
        return out

    def run(self, until: Optional[float] = None, max_steps: int = 1000) -> Iterator[ContinuationPoint]:
        """Pseudo-arclength steps until the parameter passes ``until`` (or max_steps); yields each point."""
        for _ in range(max_steps):
            point = self.step()
            yield point
            if until is not None and point.event is None and (point.parameter - until) * (self.previous - until) <= 0:
                return

    def destroy(self) -> None:
        for Z, _, _ in self.history:
            Z.destroy()
        self.history = []
        self._known = {}
