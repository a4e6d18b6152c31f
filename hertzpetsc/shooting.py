"""Travelling-wave residual E(q) and Gauss-Newton refinement of the initial state (paper section 3.4).

    E(q) = ||S X(script-T) - X(0)||_inf / ||X(0)||_inf,     script-T(q) = q ||u||_inf^((alpha-1)/2)  (eq. invv)

The refinement minimises ||G(X0)||_2^2, G(X0) = S X(script-T; X0) - X0, by Gauss-Newton with the Jacobian
S R(script-T; 0) - I from :class:`~hertzpetsc.tangent.TangentFlow`. That Jacobian is singular at a travelling
wave: translation x_n -> x_n + c and time translation are exact symmetries, so it has a two-dimensional kernel
(their Jordan partners, the Galilean boost and the amplitude, are not in it). Each step is the least-squares
solution with those two directions removed: a truncated SVD dropping the ``nullity`` smallest singular values
(reported, with the gap to the next one). As in the paper, the Jacobian is kept across iterations and only
re-evaluated when a step fails to reduce the residual.
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


class ShiftMap:
    """X0 -> S X(script-T; X0) on a periodic chain, with its own TS (prefix ``chain_`` by default)."""

    def __init__(self, params, comm=None, tolerances=None, prefix=CHAIN_PREFIX):
        if params.boundary != "periodic":
            raise ParameterError("boundary", params.boundary, "travelling waves modulo shifts need a periodic chain")
        self.chain = Chain(params, comm)
        self.integrator = ChainIntegrator(self.chain, tolerances, prefix)
        self.X = self.chain.create_state()
        self.SX = self.chain.create_state()

    def __call__(self, x0, T):
        """S X(T) as an (N, 2) array on every rank, from the (N, 2) initial state ``x0``."""
        self.chain.set_from_array(self.X, x0)
        self.integrator.integrate(self.X, 0.0, T)
        self.chain.shift(self.X, self.SX)
        return self.chain.gather(self.SX)

    def destroy(self):
        for v in (self.X, self.SX):
            v.destroy()
        self.integrator.destroy()
        self.chain.destroy()


def relative_residual(x0, sxT):
    """E = ||S X(T) - X(0)||_inf / ||X(0)||_inf over positions and velocities."""
    return float(np.max(np.abs(sxT - x0)) / np.max(np.abs(x0)))


def residual_E(params, x0, T, comm=None, tolerances=None):
    """E(q) for the initial state ``x0`` (N, 2) over script-T ``T``."""
    smap = ShiftMap(params, comm, tolerances)
    try:
        return relative_residual(np.asarray(x0).reshape(-1, 2), smap(x0, T))
    finally:
        smap.destroy()


@dataclass
class RefinementResult:
    """Refined state and the history of the Gauss-Newton iteration."""

    x: np.ndarray
    E_initial: float
    E: float
    r: float                               # relative difference of the last two iterates (paper's r(q))
    iterations: int
    jacobians: int
    history: list = field(default_factory=list)
    dropped_singular_values: np.ndarray = None
    next_singular_value: float = None
    wall_time: float = 0.0


def truncated_lstsq(J, g, nullity):
    """argmin ||J d + g||_2 over the complement of the ``nullity`` weakest right singular directions."""
    U, s, Vt = np.linalg.svd(J)
    keep = len(s) - nullity
    d = -(Vt[:keep].T @ ((U[:, :keep].T @ g) / s[:keep]))
    return d, s[keep:], s[keep - 1]


def refine(params, x0, T, comm=None, tol=1e-10, max_iterations=20, nullity=2, tolerances=MEASURE_TOLERANCES,
           prefix=CHAIN_PREFIX):
    """Gauss-Newton refinement of the travelling-wave initial state ``x0`` (N, 2) until E <= ``tol``.

    Raises :class:`ConvergenceError` if E cannot be brought below ``tol`` in ``max_iterations`` iterations.
    """
    if not tol > 0:
        raise ParameterError("tol", tol, "the target residual must be positive")
    t0 = time.perf_counter()
    N = params.N
    smap = ShiftMap(params, comm, tolerances, prefix)
    flow = TangentFlow(params, 2 * N, comm, tolerances, prefix)
    try:
        x = np.asarray(x0, dtype=float).reshape(N, 2).copy()
        g = (smap(x, T) - x).ravel()
        scale = np.max(np.abs(x))
        E0 = E = float(np.max(np.abs(g)) / scale)
        history, jacobians, J, fresh, r = [E], 0, None, False, float("nan")
        dropped, nxt = None, None
        it = 0
        while E > tol and it < max_iterations:
            if J is None:
                M, _ = flow.monodromy_mod_shift(x, T)
                J = M - np.eye(2 * N)
                jacobians += 1
                fresh = True
            d, dropped, nxt = truncated_lstsq(J, g, nullity)
            x_new = x + d.reshape(N, 2)
            g_new = (smap(x_new, T) - x_new).ravel()
            E_new = float(np.max(np.abs(g_new)) / np.max(np.abs(x_new)))
            if E_new < E or fresh:
                r = float(np.max(np.abs(x_new - x)) / np.max(np.abs(x_new)))
                x, g, E = x_new, g_new, E_new
                history.append(E)
                it += 1
                if E_new >= history[-2] * 0.5 and not fresh:
                    J = None          # slow progress with a stale Jacobian: re-evaluate it
                fresh = False
            else:
                J = None              # the stale Jacobian gave no decrease: re-evaluate and retry
        if E > tol:
            raise ConvergenceError("Gauss-Newton refinement", f"E = {E:.3g} > {tol:g}", iterations=it)
        return RefinementResult(x=x, E_initial=E0, E=E, r=r, iterations=it, jacobians=jacobians, history=history,
                                dropped_singular_values=dropped, next_singular_value=nxt,
                                wall_time=time.perf_counter() - t0)
    finally:
        smap.destroy()
        flow.destroy()
