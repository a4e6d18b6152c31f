"""The advance-delay problem for periodic travelling waves (eqs. ad, pbc) on PETSc.

For odd 2 pi-periodic u on the grid of :mod:`hertzpetsc.grid`, the second-order discretisation of eq. ad is

    R_j(u) = (u_{j+1} - 2 u_j + u_{j-1}) / h^2 - V'((tau_q u)_j - u_j) + V'(u_j - (tau_{-q} u)_j) = 0,

j = 1 .. K-1 (the equations at xi = 0, pi and on (pi, 2 pi) follow by oddness). tau_{+-q} are the shift
stencils of :func:`hertzpetsc.stencil.shift_stencil`; the exact Jacobian

    J = D2 + diag(V''(d+) + V''(d-)) - diag(V''(d+)) tau_q - diag(V''(d-)) tau_{-q},
    d+ = tau_q u - u,  d- = u - tau_{-q} u,  V''(x) = alpha |x|^(alpha-1) H(-x),

is assembled as a parallel AIJ matrix. :func:`solve_travelling_wave` solves R(u) = 0 with PETSc SNES under the
options prefix ``tw_`` (defaults: Newton with backtracking line search, direct LU, MUMPS on several ranks;
quasi-Newton, as in the paper, is ``-tw_snes_type qn``, see :data:`QN_DEFAULTS`).
"""
import math
import time
from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

from .errors import ConvergenceError, ParameterError
from .grid import RowAssembler, StencilGather
from .hertz import HertzPotential
from .stencil import shift_stencil

TW_PREFIX = "tw_"


def check_wavenumber(q, h=None, name="q"):
    """q must lie in (0, pi] (and span at least one grid step h if h is given); ``name`` is used in errors."""
    try:
        qf = float(q)
    except (TypeError, ValueError):
        raise ParameterError(name, q, "must be a real number in (0, pi]") from None
    if not (0.0 < qf <= math.pi * (1 + 1e-14)):
        raise ParameterError(name, q, "the wavenumber must lie in (0, pi]")
    if h is not None and qf < h * (1 - 1e-12):
        raise ParameterError(name, q, f"must be at least one grid step h = {h:.6g} (refine the grid for smaller q)")
    return min(qf, math.pi)


class AdvanceDelayProblem:
    """Residual and Jacobian of eqs. ad-pbc at one wavenumber q; its methods are the SNES callbacks."""

    def __init__(self, potential, grid, q):
        self.potential = potential if isinstance(potential, HertzPotential) else HertzPotential(potential)
        self.grid = grid
        self.q = check_wavenumber(q, grid.h)
        self.sigma = self.q / grid.h
        h2 = grid.h ** 2
        self.stencils = StencilGather(grid, {
            "d2": (np.array([-1, 0, 1]), np.array([1.0, -2.0, 1.0]) / h2),
            "plus": shift_stencil(self.sigma),
            "minus": shift_stencil(-self.sigma),
        })
        st = self.stencils
        self_cols = np.arange(grid.rstart, grid.rend, dtype=np.int64)[:, None]
        self.assembler = RowAssembler(grid, [st.cols["d2"], self_cols, st.cols["plus"], st.cols["minus"]])

    @property
    def integer_shift(self):
        return len(self.stencils.coef["plus"][0]) == 1 if self.grid.rend > self.grid.rstart else True

    def shift_differences(self, X):
        """d+ = tau_q u - u and d- = u - tau_{-q} u on the owned rows, and D2 u, and the gathered values."""
        st = self.stencils
        g = st.gather(X)
        u = X.getArray(readonly=True)
        return st.apply("plus", g) - u, u - st.apply("minus", g), st.apply("d2", g)

    def formFunction(self, snes, X, F):
        dplus, dminus, d2u = self.shift_differences(X)
        V = self.potential
        F.getArray()[:] = d2u - V.dV(dplus) + V.dV(dminus)

    def _jacobian_blocks(self, X):
        dplus, dminus, _ = self.shift_differences(X)
        a = self.potential.d2V(dplus)[:, None]
        b = self.potential.d2V(dminus)[:, None]
        c = self.stencils.coef
        return [c["d2"], a + b, -a * c["plus"], -b * c["minus"]]

    def create_jacobian(self, X):
        """A new parallel AIJ matrix holding J(X), with this q's nonzero pattern."""
        return self.assembler.create(self._jacobian_blocks(X))

    def formJacobian(self, snes, X, J, P):
        self.assembler.update(P, self._jacobian_blocks(X))
        if J.handle != P.handle:
            J.assemble()

    def residual_norm(self, X):
        F = X.duplicate()
        self.formFunction(None, X, F)
        norm = F.norm(PETSc.NormType.NORM_INFINITY)
        F.destroy()
        return norm

    def destroy(self):
        self.stencils.destroy()


@dataclass(frozen=True)
class SolveResult:
    """Outcome of one SNES solve at one q."""

    q: float
    reason: int
    iterations: int
    linear_iterations: int
    residual_norm: float
    wall_time: float


def default_tolerances(grid, u_scale):
    """SNES tolerances that reach round-off of the discrete equations.

    Round-off in the second difference is about 4 eps |u| / h^2 per row, so the 2-norm of the residual cannot
    go much below sqrt(K) times that; atol is ten times this floor. stol stops once the Newton update is
    1e-12 of the solution (the next update would be far below round-off).
    """
    eps = np.finfo(float).eps
    atol = 10 * 4 * eps * max(u_scale, 1e-300) / grid.h ** 2 * math.sqrt(grid.size)
    return dict(rtol=1e-12, atol=atol, stol=1e-12, max_it=50)


# Defaults for -tw_snes_type qn (the paper used Broyden's method). With PETSc 3.18, L-BFGS scaled by the
# Jacobian with the critical-point line search converges along the whole branch; the Broyden variants
# (-tw_snes_qn_type broyden) diverge at the first step from u0 whatever the scaling. Inserted only for the
# solve, and only where the user did not set them.
QN_DEFAULTS = {"snes_qn_scale_type": "jacobian", "snes_linesearch_type": "cp"}

# A converged point must satisfy ||R||_2 <= ACCEPT_FACTOR * atol (atol from the solution's own scale): guards
# against SNES stopping on a small relative step far from a solution (possible with -snes_divergence_tolerance -1).
ACCEPT_FACTOR = 1e3


def create_snes(problem, J, prefix=TW_PREFIX, tolerances=None):
    """SNES with the paper-reproducing defaults, then the options database under ``prefix`` (read once)."""
    comm = problem.grid.comm
    snes = PETSc.SNES().create(comm=comm)
    snes.setOptionsPrefix(prefix)
    snes.setType(PETSc.SNES.Type.NEWTONLS)
    F = problem.grid.create_vec()
    snes.setFunction(problem.formFunction, F)
    snes.setJacobian(problem.formJacobian, J, J)
    if tolerances:
        snes.setTolerances(**tolerances)
    ksp = snes.getKSP()
    ksp.setType(PETSc.KSP.Type.PREONLY)
    pc = ksp.getPC()
    pc.setType(PETSc.PC.Type.LU)
    if comm.getSize() > 1:
        pc.setFactorSolverType("mumps")
    opts = PETSc.Options()
    inserted = []
    if opts.getString(prefix + "snes_type", "") == "qn":
        for key, value in QN_DEFAULTS.items():
            if not opts.hasName(prefix + key):
                opts.setValue(prefix + key, value)
                inserted.append(prefix + key)
    try:
        snes.setFromOptions()
    finally:
        for key in inserted:
            opts.delValue(key)
    F.destroy()
    return snes


@PETSc.Log.EventDecorator("hz_tw_solve")
def solve_travelling_wave(problem, u, prefix=TW_PREFIX, tolerances=None):
    """Solve eqs. ad-pbc at ``problem.q`` by SNES from the initial guess ``u`` (overwritten by the solution).

    Raises :class:`ConvergenceError` with the converged reason and q if SNES fails.
    """
    t0 = time.perf_counter()
    if tolerances is None:
        tolerances = default_tolerances(problem.grid, u.norm(PETSc.NormType.NORM_INFINITY))
    J = problem.create_jacobian(u)
    snes = create_snes(problem, J, prefix, tolerances)
    try:
        snes.solve(None, u)
        reason = snes.getConvergedReason()
        result = SolveResult(q=problem.q, reason=int(reason), iterations=snes.getIterationNumber(),
                             linear_iterations=snes.getLinearSolveIterations(),
                             residual_norm=float(snes.getFunctionNorm()), wall_time=time.perf_counter() - t0)
    finally:
        snes.destroy()
        J.destroy()
    if result.reason <= 0:
        raise ConvergenceError("travelling-wave SNES (prefix -%s)" % prefix, result.reason, q=problem.q)
    accept = ACCEPT_FACTOR * default_tolerances(problem.grid, u.norm(PETSc.NormType.NORM_INFINITY))["atol"]
    if not result.residual_norm <= accept:
        raise ConvergenceError("travelling-wave SNES (prefix -%s)" % prefix,
                               f"{result.reason}, but residual {result.residual_norm:.3g} > {accept:.3g}",
                               q=problem.q)
    return result
