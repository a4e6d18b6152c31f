"""The one continuation layer (hertzpetsc.continuation) on a problem whose fold is known in closed form: the
discrete Bratu problem u'' + lambda e^u = 0 on (0, 1), u(0) = u(1) = 0. Its continuum fold is lambda_c = 8 y^2 /
cosh^2 y with y tanh y = 1; the second-order scheme's fold differs by O(h^2)."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from hertzpetsc.continuation import (Continuation, ContinuationError, ContinuationProblem, FoldError, LazyTests,
                                     Natural, PseudoArclength)
from hertzpetsc.errors import ConvergenceError, ParameterError


class Bratu(ContinuationProblem):
    """Z = (u_1 .. u_n, lambda) on one rank; dense bordered Newton (the test's own corrector)."""

    parameter = "lambda"

    def __init__(self, n):
        self.n, self.h = n, 1.0 / (n + 1)
        self.D = (np.diag(-2.0 * np.ones(n)) + np.diag(np.ones(n - 1), 1) + np.diag(np.ones(n - 1), -1)) / self.h ** 2
        self.solves = 0

    def create_vec(self):
        return PETSc.Vec().createSeq(self.n + 1, comm=PETSc.COMM_SELF)

    def weights(self):
        W = self.create_vec()
        W.set(self.h)
        W.getArray()[-1] = 1.0
        return W

    def solve(self, Z, row=None, value=None):
        self.solves += 1
        z = Z.getArray()
        r = None if row is None else row.getArray(readonly=True).copy()
        for it in range(1, 30):
            u, lam = z[:-1], z[-1]
            if not np.all(np.abs(u) < 50):
                break                                   # diverging (beyond the fold)
            A = np.zeros((self.n + 1, self.n + 1))
            A[:-1, :-1] = self.D + np.diag(lam * np.exp(u))
            A[:-1, -1] = np.exp(u)
            if r is None:
                A[-1, -1], g = 1.0, 0.0
            else:
                A[-1], g = r, r @ z - value
            d = np.linalg.solve(A, -np.concatenate([self.D @ u + lam * np.exp(u), [g]]))
            z += d
            if np.max(np.abs(d)) < 1e-13 * max(1.0, np.max(np.abs(z))):
                return it
        raise ConvergenceError("Bratu Newton", "no convergence", **{"lambda": float(z[-1])})

    def test_functions(self, Z):
        return {"u_max - 2": float(np.max(Z.getArray(readonly=True)[:-1]) - 2.0)}

    def report(self, Z):
        return {"u_max": float(np.max(Z.getArray(readonly=True)[:-1]))}


def lambda_c():
    y = 1.2
    for _ in range(50):
        y -= (y * math.tanh(y) - 1) / (math.tanh(y) + y / math.cosh(y) ** 2)
    return 8 * y * y / math.cosh(y) ** 2


def bratu_from_rest(n, algorithm, lam, problem=None):
    """The Bratu problem on n points (or a subclass ``problem``), its continuation and the start vector (u = 0,
    lambda = lam)."""
    prob = (problem or Bratu)(n)
    cont = Continuation(prob, algorithm)
    Z = prob.create_vec()
    Z.set(0.0)
    Z.getArray()[-1] = lam
    return prob, cont, Z


def run_to_fold(n, algorithm=None, problem=None):
    prob, cont, Z = bratu_from_rest(n, algorithm or PseudoArclength(ds=0.05, ds_max=0.3), 0.5, problem)
    try:
        cont.start(Z)
        cont.step_to(0.6)
        points = []
        for p in cont.run(max_steps=80):
            points.append(p)
            if p.event is None and p.parameter < 2.0 and p.dp_ds < 0:
                break
    finally:
        Z.destroy()
        cont.destroy()
    return points


def test_fold_of_the_bratu_problem_is_located_to_the_discretisation_error():
    lc = lambda_c()
    folds = []
    for n in (99, 199):
        points = run_to_fold(n)
        found = [p for p in points if p.event == "fold"]
        assert len(found) == 1, [p.event for p in points]
        folds.append(found[0].parameter)
        # the fold is the largest lambda on the computed curve
        assert found[0].parameter >= max(p.parameter for p in points) - 1e-12
    e1, e2 = (lc - folds[0]) / lc, (lc - folds[1]) / lc
    assert 0 < e2 < e1 < 1e-4                          # the scheme's fold lies below the continuum one, O(h^2)
    assert abs(math.log2(e1 / e2) - 2.0) < 0.02         # observed order 2 (h halved)
    assert abs((4 * folds[1] - folds[0]) / 3 - lc) < 1e-7 * lc   # Richardson removes the h^2 term


def test_an_event_is_located_where_its_test_function_vanishes():
    points = run_to_fold(99)
    events = [p for p in points if p.event == "u_max - 2"]
    assert len(events) == 1
    assert abs(events[0].report["u_max"] - 2.0) < 1e-8
    # u_max = 2 on the upper branch, after the fold
    fold = next(p for p in points if p.event == "fold")
    assert events[0].s > fold.s


def test_natural_continuation_stops_at_the_fold_with_a_bounded_number_of_solves():
    prob = Bratu(49)
    cont = Continuation(prob, Natural(max_halvings=6))
    Z = prob.create_vec()
    Z.set(0.0)
    Z.getArray()[-1] = 1.0
    try:
        cont.start(Z)
        with pytest.raises(ContinuationError) as err:
            cont.step_to(4.0)                     # beyond the fold: no solution
        assert "lambda" in str(err.value)
        assert 3.4 < cont.parameter < lambda_c()
        assert prob.solves < 200
    finally:
        Z.destroy()
        cont.destroy()


def test_natural_steps_no_longer_than_max_step():
    """step_to(1.0) from 0.1 with max_step = 0.2 corrects at ceil(0.9 / 0.2) = 5 parameters (each step as long as
    allowed, the last shortened to land on the target), and lands where one long step lands (every converged
    corrector taken: max_corrector = inf)."""
    ends = {}
    for max_step in (math.inf, 0.2):
        prob = Bratu(19)
        cont = Continuation(prob, Natural(max_corrector=math.inf, max_step=max_step))
        Z = prob.create_vec()
        Z.set(0.0)
        Z.getArray()[-1] = 0.1
        try:
            cont.start(Z)
            solves = prob.solves
            cont.step_to(1.0)
            ends[max_step] = (prob.solves - solves, cont.history[-1][0].getArray().copy())
        finally:
            Z.destroy()
            cont.destroy()
    assert ends[math.inf][0] == 1 and ends[0.2][0] == 5
    assert np.max(np.abs(ends[0.2][1] - ends[math.inf][1])) < 1e-12


def test_algorithm_parameters_are_validated():
    with pytest.raises(ParameterError):
        PseudoArclength(ds=0.0)
    with pytest.raises(ParameterError):
        PseudoArclength(ds=1.0, ds_max=0.5)
    with pytest.raises(ParameterError):
        Natural(max_halvings=-1)
    with pytest.raises(ParameterError, match="max_step"):
        Natural(max_step=0.0)
    with pytest.raises(ParameterError):
        Continuation(Bratu(5), algorithm="arclength")


class RejectingBratu(Bratu):
    """The Bratu problem whose test functions fail once (ConvergenceError, as multipliers that fail their closed-form
    checks do): at the first point past lambda = 1.5."""

    rejected = None

    def test_functions(self, Z):
        lam = float(Z.getArray(readonly=True)[-1])
        if lam > 1.5 and self.rejected is None:
            self.rejected = lam
            raise ConvergenceError("test functions", "closed-form check", **{"lambda": lam})
        return super().test_functions(Z)


def test_a_point_whose_test_functions_fail_is_a_rejected_arclength_step():
    """A pseudo-arclength point whose test functions raise ConvergenceError is not accepted: the step is halved (as
    a failed corrector's) and the curve goes on past it."""
    prob = RejectingBratu(29)
    cont = Continuation(prob, PseudoArclength(ds=0.2, ds_max=0.2))
    Z = prob.create_vec()
    Z.set(0.0)
    Z.getArray()[-1] = 1.0
    try:
        cont.start(Z)
        cont.step_to(1.2)
        points = [p for _, p in zip(range(6), cont.run())]
    finally:
        Z.destroy()
        cont.destroy()
    assert prob.rejected is not None and points[-1].parameter > prob.rejected
    assert all(abs(p.parameter - prob.rejected) > 1e-12 for p in points)
    steps = np.diff([p.s for p in points if p.event is None])
    assert np.min(steps) < 0.75 * np.max(steps)        # the step that met the failure was halved


class FlatBratu(Bratu):
    """The Bratu problem with a verdict's margin as test: flat (-1e-6) while u_max < 1/2, then u_max - 1/2 - 1e-6 (the
    Illinois rule crawls on such a function); and a second test that counts its evaluations."""

    def __init__(self, n):
        super().__init__(n)
        self.counted = 0

    def test_functions(self, Z):
        u_max = float(np.max(Z.getArray(readonly=True)[:-1]))

        def counted():
            self.counted += 1
            return 1.0
        return LazyTests({"margin": lambda: max(u_max - 0.5, 0.0) - 1e-6, "other": counted})


def test_bisection_locates_a_flat_sided_root_to_the_step_and_keeps_the_bracket():
    """Natural steps lambda = 1 -> 3 cross u_max = 1/2 + 1e-6 on the lower branch: located by bisection to a bracket of
    1e-4 in lambda in about log2(2 / 1e-4) = 15 trials, the bracket's ends of opposite signs; the lazy second test is
    not evaluated at the trials."""
    prob = FlatBratu(29)
    cont = Continuation(prob, Natural(), bisect=("margin",), locate_step=1e-4)
    Z = prob.create_vec()
    Z.set(0.0)
    Z.getArray()[-1] = 1.0
    try:
        cont.start(Z)
        substeps = cont.step_to(3.0).substeps
        counted = prob.counted
        events = cont.take_events()
    finally:
        Z.destroy()
        cont.destroy()
    assert [e.event for e in events] == ["margin"]
    (p1, g1), (p2, g2) = events[0].bracket
    assert p1 < p2 and p2 - p1 <= 1e-4 and g1 < 0 < g2
    assert p1 <= events[0].parameter <= p2
    assert abs(events[0].report["u_max"] - 0.5) < 1e-4           # the root, to the bracket's 1e-4 in lambda
    assert counted == substeps + 1                             # at the natural points only, not at the ~15 trials
    with pytest.raises(ParameterError):
        Continuation(Bratu(5), Natural(), locate_step=0.0)


class BlindBratu(FlatBratu):
    """FlatBratu whose corrector fails at every lambda of ``blind`` (an interval): a bisection trial there does not
    converge, as a wave's corrector inside a stability map's bisection may not."""

    blind = (math.inf, math.inf)

    def solve(self, Z, row=None, value=None):
        lam = float(Z.getArray(readonly=True)[-1]) if value is None else value
        if self.blind[0] <= lam <= self.blind[1]:
            raise ConvergenceError("Bratu Newton", "no convergence (blind)", **{"lambda": lam})
        return super().solve(Z, row, value)


def _margin_events(prob):
    cont = Continuation(prob, Natural(), bisect=("margin",), locate_step=1e-4)
    Z = prob.create_vec()
    Z.set(0.0)
    Z.getArray()[-1] = 1.0
    try:
        cont.start(Z)
        cont.step_to(3.0)
        return cont.take_events()
    finally:
        Z.destroy()
        cont.destroy()


def test_a_root_whose_bisection_fails_is_kept_bracketed_and_unresolved(capfd):
    """A bisection trial whose corrector fails (lambda within 0.01 of the root u_max = 1/2 + 1e-6) does not drop the
    event (as it did): it is reported, unresolved, with the bracket of the solved trials around the root (wider than
    the locate_step of a located one, its ends of opposite signs) and a note."""
    located = _margin_events(BlindBratu(29))
    assert [e.event for e in located] == ["margin"] and getattr(located[0], "unresolved", None) is None
    root = located[0].parameter
    prob = BlindBratu(29)
    prob.blind = (root - 0.01, root + 0.01)
    events = _margin_events(prob)
    assert [e.event for e in events] == ["margin"]
    e = events[0]
    assert e.unresolved is not None and "blind" in e.unresolved
    (p1, g1), (p2, g2) = e.bracket
    assert p1 < prob.blind[0] and prob.blind[1] < p2 and g1 < 0 < g2      # the root between, the ends solved
    assert p2 - p1 > 1e-4                                                 # not the located bracket
    assert e.parameter in (p1, p2) and abs(e.report["u_max"] - 0.5) < 0.05  # an end, reported
    assert "note: the event 'margin' of lambda was not located" in capfd.readouterr().err


class Cubic(ContinuationProblem):
    """x^3 - x = p: an S-shaped curve in p, folds at x = -+1/sqrt(3), p = +-2/(3 sqrt(3)). Z = (x, p); 2x2 Newton."""

    parameter = "p"

    def create_vec(self):
        return PETSc.Vec().createSeq(2, comm=PETSc.COMM_SELF)

    def solve(self, Z, row=None, value=None):
        z = Z.getArray()
        r = None if row is None else row.getArray(readonly=True).copy()
        for it in range(1, 30):
            x, p = z
            A = np.array([[3 * x * x - 1, -1.0], [0.0, 1.0] if r is None else list(r)])
            g = 0.0 if r is None else r @ z - value
            d = np.linalg.solve(A, -np.array([x ** 3 - x - p, g]))
            z += d
            if np.max(np.abs(d)) < 1e-14 * max(1.0, np.max(np.abs(z))):
                return it
        raise ConvergenceError("cubic Newton", "no convergence", p=float(z[1]))


def _cubic_from(p0, around_folds):
    prob = Cubic()
    cont = Continuation(prob, Natural(max_halvings=6, around_folds=around_folds))
    Z = prob.create_vec()
    lower = min(np.real(r) for r in np.roots([1, 0, -1, -p0]) if abs(np.imag(r)) < 1e-12)
    Z.getArray()[:] = [lower, p0]
    cont.start(Z)
    Z.destroy()
    cont.step_to(p0 + 0.05)
    return cont


def test_natural_steps_go_around_an_s_shaped_pair_of_folds():
    """Natural steps from the lower branch (p = -1) to p = 1 stall at the fold p = 2/(3 sqrt(3)) (the corrector
    guard refuses the jump to the upper branch); with ``around_folds`` the layer follows the curve by
    pseudo-arclength through both folds (located, in order) and lands on the upper branch's x^3 - x = 1."""
    cont = _cubic_from(-1.0, 0)
    with pytest.raises(ContinuationError):
        cont.step_to(1.0)
    cont.destroy()
    cont = _cubic_from(-1.0, 50)
    try:
        point = cont.step_to(1.0)
        x = float(cont.history[-1][0].getArray()[0])
        folds = [e.parameter for e in cont.take_events() if e.event == "fold"]
    finally:
        cont.destroy()
    upper = max(np.real(r) for r in np.roots([1, 0, -1, -1]) if abs(np.imag(r)) < 1e-12)
    assert point.parameter == 1.0 and abs(x - upper) < 1e-12
    pf = 2 / (3 * math.sqrt(3))
    assert len(folds) == 2 and abs(folds[0] - pf) < 1e-8 and abs(folds[1] + pf) < 1e-8


def test_natural_steps_around_a_single_fold_stop_with_the_fold_named():
    """Beyond the Bratu fold the curve turns back: the detour ends (bounded) with an error naming the fold, a
    FoldError whose farthest point is the located fold (the largest lambda of the curve)."""
    prob, cont, Z = bratu_from_rest(49, Natural(max_halvings=6, around_folds=100), 1.0)
    try:
        cont.start(Z)
        cont.step_to(2.0)
        with pytest.raises(ContinuationError, match="turns back at a fold of lambda = ") as err:
            cont.step_to(4.0)
        fold = float(str(err.value).split("fold of lambda = ")[1].split(" ")[0])
        assert abs(fold - lambda_c()) < 1e-3 * lambda_c()           # the scheme's fold, O(h^2) from the continuum
        assert isinstance(err.value, FoldError) and err.value.fold.event == "fold"
        assert err.value.fold.parameter == pytest.approx(fold, rel=1e-11)           # the message's 12 digits
        assert prob.solves < 400
    finally:
        Z.destroy()
        cont.destroy()


def test_a_fold_whose_location_fails_is_kept_at_the_curve_point_beyond_it(capfd):
    """Pseudo-arclength through the Bratu fold with the arclength corrector failing on every point within 1e-4 in
    lambda of the located fold (the location's trials land there, the regular steps do not): the fold was dropped
    (no event); it is now reported, unresolved, at the curve's point beyond the other two (lambda within 1e-3 below
    the located fold: the step's point nearest it), with a note."""
    fold = next(p for p in run_to_fold(99) if p.event == "fold").parameter

    class Blind(Bratu):
        def solve(self, Z, row=None, value=None):
            its = super().solve(Z, row, value)
            if row is not None and abs(float(Z.getArray(readonly=True)[-1]) - fold) < 1e-4:
                raise ConvergenceError("Bratu Newton", "no convergence (blind)", **{"lambda": fold})
            return its
    capfd.readouterr()
    points = run_to_fold(99, problem=Blind)
    folds = [p for p in points if p.event == "fold"]
    assert len(folds) == 1 and getattr(folds[0], "unresolved", None) is not None
    assert fold - 1e-3 < folds[0].parameter < fold
    assert "note: the fold of lambda was not located" in capfd.readouterr().err
