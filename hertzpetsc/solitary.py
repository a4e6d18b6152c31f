"""The solitary wave of unit velocity and k_alpha (paper appendix, eqs. adr, kal2, depsol2).

Relative displacements r(s) = y(s + 1/2) - y(s - 1/2) of the solitary wave x_n(t) = y(n - t) solve

    r''(s) = V'(r(s+1)) - 2 V'(r(s)) + V'(r(s-1))                                   (eq. adr)

with r even, negative and decaying super-exponentially. We solve it on [-L, L] with step delta = 1/n (n even,
so that the unit shift and the half-integers are grid points), second-order differences, r even and r = 0
beyond +-L (justified once |r| has decayed below the tail tolerance at |s| >= L - 1, which is checked: a given L
too short is refused, an L not given is chosen, from 8 enlarged by 1.5x up to 40.5 until the check passes; on a
period instead, the equations would sum to zero and the Jacobian be singular). PETSc SNES under the prefix ``sol_``
(the same Newton/LU defaults as the travelling waves), started from the exact compacton of the continuum limit
w'' = 12 (w^(1/alpha) - w), w = |r|^alpha (Nesterenko's and Ahnert-Pikovsky's profile): w = A cos^m(kappa s),
m = 2 alpha/(alpha-1), kappa = sqrt(12)/m, A = (m/(m-1))^(alpha/(alpha-1)), for |kappa s| < pi/2.
Then k_alpha = -sum_{k>=0} r(k + 1/2) (eq. kal2) and y(s) = sum_{k>=0} r(k+1/2-s) - r(k+1/2) (eq. depsol2).
"""
import math
import time
from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np
from petsc4py import PETSc

from .assembly import RowAssembler, StencilGather
from .errors import ConvergenceError, ParameterError, callbacks_raise, check_integer, check_real
from .grid import ProfileGrid
from .hertz import check_alpha
from .model import LatticeModel
from .resources import check_memory
from .twsolver import ACCEPT_FACTOR, create_snes

SOL_PREFIX = "sol_"
# L tried in turn when none is given (x 1.5 each; alpha near 1: a slow tail)
AUTO_HALF_LENGTHS = (8.0, 12.0, 18.0, 27.0, 40.5)


# The finest grid of the solitary wave: 2 L n unknowns on the line (L up to the largest of AUTO_HALF_LENGTHS) must
# fit in memory on the direct solver; 10^6 cells per unit is already far beyond the convergence studies (n <= 160).
MAX_CELLS_PER_UNIT = 10 ** 6

@dataclass(frozen=True)
class SolitaryParameters:
    """alpha > 1; grid step 1/cells_per_unit (even); half-length L of the truncated line (None: chosen by
    :func:`solve_solitary_wave` from ``AUTO_HALF_LENGTHS``); tail tolerance."""

    alpha: float = 1.5
    cells_per_unit: int = 40
    half_length: float = None
    tail_tolerance: float = 1e-13

    def __post_init__(self):
        object.__setattr__(self, "alpha", check_alpha(self.alpha))
        n = check_integer("cells_per_unit", self.cells_per_unit, 2, hi=MAX_CELLS_PER_UNIT,
                          note="(even: unit shift and half-integers on the grid)")
        if n % 2:
            raise ParameterError("cells_per_unit", n, "must be an even integer >= 2 (unit shift and half-integers "
                                 "on the grid)")
        object.__setattr__(self, "cells_per_unit", n)
        if self.half_length is not None:
            L = check_real("half_length", self.half_length, "the half-length of the line", 3.0, lo_open=False)
            if abs(L * n - round(L * n)) >= 1e-9:
                raise ParameterError("half_length", self.half_length, "must be >= 3 and a multiple of the grid step "
                                     f"1/{n}")
            object.__setattr__(self, "half_length", L)
        object.__setattr__(self, "tail_tolerance", check_real("tail_tolerance", self.tail_tolerance, "the tail "
                                                              "tolerance", 0.0))

    @property
    def K(self):
        return int(round(self.half_length * self.cells_per_unit))


def continuum_compacton(alpha, s):
    """The compacton r(s) of the continuum limit (the initial guess; exact for w'' = 12 (w^(1/alpha) - w))."""
    m = 2 * alpha / (alpha - 1)
    kappa = math.sqrt(12.0) / m
    A = (m / (m - 1)) ** (alpha / (alpha - 1))
    c = np.cos(np.clip(kappa * np.asarray(s, dtype=float), -math.pi / 2, math.pi / 2))
    return -(A ** (1 / alpha)) * c ** (m / alpha)


class SolitaryWaveProblem:
    """Residual and exact Jacobian of the discretised eq. adr for even r; methods are SNES callbacks."""

    def __init__(self, params, comm):
        self.params = params
        self.model = LatticeModel.hertz(params.alpha)
        self.grid = ProfileGrid(params.K, comm, parity=1, length=2 * params.half_length, dirichlet=True)
        p = params.cells_per_unit
        self.stencils = StencilGather(self.grid, {
            "d2": (np.array([-1, 0, 1]), np.array([1.0, -2.0, 1.0]) * p ** 2),
            "plus": (np.array([p]), np.array([1.0])),
            "minus": (np.array([-p]), np.array([1.0])),
        })
        st = self.stencils
        self_cols = np.arange(self.grid.rstart, self.grid.rend, dtype=np.int64)[:, None]
        self.assembler = RowAssembler(self.grid, [st.cols["d2"], self_cols, st.cols["plus"], st.cols["minus"]])

    def formFunction(self, snes, X, F):
        st, force = self.stencils, self.model.force
        g = st.gather(X)
        f = force(g)
        r = X.getArray(readonly=True)
        F.getArray()[:] = st.apply("d2", g) - (st.apply("plus", f) - 2 * force(r) + st.apply("minus", f))

    def _blocks(self, X):
        st, stiffness = self.stencils, self.model.stiffness
        g = st.gather(X)
        k = stiffness(g)
        r = X.getArray(readonly=True)
        return [st.coef["d2"], 2 * stiffness(r)[:, None], -st.coef["plus"] * k[st.pos["plus"]],
                -st.coef["minus"] * k[st.pos["minus"]]]

    def formJacobian(self, snes, X, J, P):
        self.assembler.update(P, self._blocks(X))
        if J.handle != P.handle:
            J.assemble()

    def destroy(self):
        self.stencils.destroy()


@dataclass
class SolitaryWave:
    """r and y on s = j / cells_per_unit, j = 0..K (r even, y odd), k_alpha and solver statistics."""

    params: SolitaryParameters
    s: np.ndarray
    r: np.ndarray
    y: np.ndarray
    k_alpha: float
    iterations: int
    residual_norm: float
    tail: float
    wall_time: float


def displacement_profile(r_half, n):
    """y(s_j) of eq. depsol2 and k_alpha of eq. kal2 from r on s_j = j/n, j = 0..K (r = 0 beyond)."""
    K = len(r_half) - 1
    half = n // 2
    k_idx = np.arange(half, 2 * K + 1, n)      # grid indices of k + 1/2, k = 0, 1, ... (shifted by s <= L below)
    k_alpha = -float(np.sum(r_half[k_idx[k_idx <= K]]))

    def r_at(idx):
        idx = np.abs(idx)
        return np.where(idx <= K, r_half[np.minimum(idx, K)], 0.0)

    j = np.arange(K + 1)
    y = np.array([np.sum(r_at(k_idx - jj)) for jj in j]) + k_alpha
    return y, k_alpha


def max_bead_velocity(wave):
    """max_n |x_n'| of the unit-speed solitary wave x_n(t) = y(n - t): max |y'|, from y on the grid (central
    differences, y odd; second order in the grid step like the wave itself)."""
    y, n = wave.y, wave.params.cells_per_unit
    full = np.concatenate([-y[:0:-1], y])
    return float(np.max(np.abs(full[2:] - full[:-2])) * n / 2)


def solve_solitary_wave(params, comm, prefix=SOL_PREFIX):
    """Compute the unit-velocity solitary wave and k_alpha (``wave.params.half_length`` is the L used);
    ParameterError if L is too short for the tail tolerance (a given L, or 40.5 when L is chosen), ConvergenceError
    if SNES fails or lands on the trivial solution r = 0."""
    if params.half_length is not None:
        return _check_tail(_solve(params, comm, prefix))
    for L in AUTO_HALF_LENGTHS:
        wave = _solve(replace(params, half_length=L), comm, prefix)
        if wave.tail <= params.tail_tolerance:
            return wave
    return _check_tail(wave)


def _check_tail(wave):
    params = wave.params
    if wave.tail > params.tail_tolerance:
        raise ParameterError("half_length", params.half_length,
                             f"too short: |r| at |s| >= L - 1 is {wave.tail:.1e} of its maximum, above the tolerance "
                             f"{params.tail_tolerance:g}; increase L")
    return wave


@PETSc.Log.EventDecorator("hz_solitary_solve")
def _solve(params, comm, prefix):
    """The solve of :func:`solve_solitary_wave` at a given L, without the tail check."""
    t0 = time.perf_counter()
    try:
        check_memory(params.K, comm, "direct")
    except ParameterError as err:
        raise ParameterError("cells_per_unit", params.cells_per_unit, f"with the half-length L = "
                             f"{params.half_length:g}, the line has {params.K} cells: {err.valid}") from None
    s = np.arange(params.K + 1) / params.cells_per_unit
    # round-off floor of the residual: ~4 eps |r| n^2 per row (|r| <= 1.5), times sqrt(K) in the 2-norm
    atol = 10 * 4 * np.finfo(float).eps * 1.5 * params.cells_per_unit ** 2 * math.sqrt(params.K + 1)
    with _compacton_start(params, comm) as (prob, X, J):
        snes = create_snes(prob, J, prefix, dict(rtol=1e-13, atol=atol, stol=1e-14, max_it=100))
        try:
            with callbacks_raise():
                snes.solve(None, X)
            reason, its, fnorm = snes.getConvergedReason(), snes.getIterationNumber(), snes.getFunctionNorm()
            r = prob.grid.half_profile(X)
        finally:
            snes.destroy()
    what = "solitary-wave SNES (prefix -%s)" % prefix
    if reason <= 0:
        raise ConvergenceError(what, int(reason), alpha=params.alpha)
    if fnorm > ACCEPT_FACTOR * atol:
        raise ConvergenceError(what, f"{reason}, but residual {fnorm:.3g} > {ACCEPT_FACTOR * atol:.3g}",
                               alpha=params.alpha)
    if not r.min() < -0.1:
        raise ConvergenceError(what, "converged to the trivial solution r = 0", alpha=params.alpha)
    tail = float(np.max(np.abs(r[s >= params.half_length - 1])) / np.max(np.abs(r)))
    y, k_alpha = displacement_profile(r, params.cells_per_unit)
    return SolitaryWave(params=params, s=s, r=r, y=y, k_alpha=k_alpha, iterations=its, residual_norm=float(fnorm),
                        tail=tail, wall_time=time.perf_counter() - t0)


@contextmanager
def _compacton_start(params, comm):
    """(problem, X, J) of a solve: X the continuum compacton on the grid, J its Jacobian; freed on exit."""
    prob = SolitaryWaveProblem(params, comm)
    X = prob.grid.vec_from_half_profile(continuum_compacton(params.alpha, np.arange(params.K + 1)
                                                            / params.cells_per_unit))
    J = prob.assembler.create(prob._blocks(X))
    try:
        yield prob, X, J
    finally:
        J.destroy()
        X.destroy()
        prob.destroy()
