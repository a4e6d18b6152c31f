"""Solving eqs. ad-pbc with PETSc SNES under the options prefix ``tw_`` (and ``sol_`` for the solitary wave).

:class:`TravellingWaveSolver` keeps one SNES (its KSP/PC and work vectors) across the solves of a continuation;
:func:`solve_travelling_wave` is a one-off solve. Two linear-solver paths, chosen by ``-tw_solver``:

* ``direct`` (default): Newton with backtracking line search, assembled J, LU (MUMPS on several ranks). The
  shifts couple points up to half a period apart, so the factors fill in and the cost grows faster than the
  number of grid points.
* ``nk``: Newton-Krylov. J = D2 + K with K bounded as h -> 0, so GMRES preconditioned by the exact inverse of D2
  (:class:`SecondDifferencePC`, O(n), partition-independent) needs a number of iterations independent of h;
  J is applied matrix-free (``-tw_jacobian shell``, default) or assembled (``-tw_jacobian aij``, for algebraic
  preconditioners such as ``-tw_pc_type hypre``). All KSP/PC knobs stay reachable as -tw_ksp_*, -tw_pc_*.

Quasi-Newton, as in the paper, is ``-tw_snes_type qn``, see :data:`QN_DEFAULTS`.
"""
import math
import time

import numpy as np
from petsc4py import PETSc

from .assembly import RowAssembler, StencilGather
from .branch import SolveStats
from .errors import ConvergenceError, ParameterError, callbacks_raise
from .options import inserted_options, user_set

TW_PREFIX = "tw_"


def second_difference(grid):
    """The D2 stencil (1, -2, 1)/h^2 of eq. ad on ``grid`` (columns and weights only: no scatter)."""
    return StencilGather(grid, {"d2": (np.array([-1, 0, 1]), np.array([1.0, -2.0, 1.0]) / grid.h ** 2)},
                         scatter=False)


class SecondDifferencePC:
    """Exact distributed solve with the second difference D2 of eq. ad: the preconditioner of ``-tw_solver nk``.

    The Jacobian of eq. ad is J = D2 + K, where D2 (the tridiagonal (1, -2, 1)/h^2, with u_0 = u_K = 0 for odd
    profiles) carries the 1/h^2 and K (the V''-weighted shift couplings) stays bounded as h -> 0; hence D2^{-1} J
    is the identity plus a compact operator and GMRES needs a number of iterations independent of h.

    D2 is taken from the ``name`` stencil of a :class:`~hertzpetsc.assembly.StencilGather` (any tridiagonal
    stencil works; default :func:`second_difference`) and does not depend on u or q, so it is factored once per
    problem. The solve is exact and independent of the partition: each rank factors its diagonal block (LU,
    natural ordering: O(n) for a tridiagonal), and the couplings between neighbouring ranks are restored by the two
    "spikes" B^{-1} e_first, B^{-1} e_last of each block and a 2p x 2p interface system (p ranks), solved
    redundantly after one allgather of 2 numbers per rank per application.
    """

    def __init__(self, grid, stencils=None, name="d2"):
        stencils = second_difference(grid) if stencils is None else stencils
        self.nloc = nloc = grid.rend - grid.rstart
        rows = np.arange(grid.rstart, grid.rend)[:, None]
        cols, coef = stencils.cols[name], stencils.coef[name]
        lower, diag, upper = (np.where(cols == rows + k, coef, 0.0).sum(axis=1) for k in (-1, 0, 1))
        if np.any((np.abs(cols - rows) > 1) & (coef != 0.0)):
            raise ParameterError("stencil", name, "must be tridiagonal for SecondDifferencePC")
        # the diagonal block, as sequential AIJ (CSR rows: lower, diagonal, upper within the block)
        local = np.arange(nloc)
        entries = [(local - 1, lower, local > 0), (local, diag, local >= 0), (local + 1, upper, local < nloc - 1)]
        c, v, keep = (np.stack(column, axis=1) for column in zip(*entries))
        indptr = np.concatenate([[0], np.cumsum(keep.sum(axis=1))]).astype(PETSc.IntType)
        self.block = PETSc.Mat().createAIJ((nloc, nloc), csr=(indptr, c[keep].astype(PETSc.IntType), v[keep]),
                                           comm=PETSc.COMM_SELF)
        self.block.assemble()
        self.ksp = PETSc.KSP().create(comm=PETSc.COMM_SELF)
        self.ksp.setOperators(self.block)
        self.ksp.setType(PETSc.KSP.Type.PREONLY)
        lpc = self.ksp.getPC()
        lpc.setType(PETSc.PC.Type.LU)
        lpc.setFactorOrdering(PETSc.Mat.OrderingType.NATURAL)
        self.rhs = PETSc.Vec().createSeq(nloc, comm=PETSc.COMM_SELF)
        self.sol = self.rhs.duplicate()
        # spikes: the response of the block to the coupling with the last row of the previous rank (g) and the
        # first row of the next rank (k); x_local = B^{-1} f - x_prev g - x_next k
        self.spikes = np.zeros((2, nloc))
        if nloc:
            self.ksp.setUp()
            for i, (pos, weight) in enumerate(((0, lower[0]), (nloc - 1, upper[-1]))):
                self.rhs.set(0.0)
                self.rhs.setValue(pos, weight)
                self.rhs.assemble()
                self.ksp.solve(self.rhs, self.sol)
                self.spikes[i] = self.sol.getArray(readonly=True)
        self.mpi = grid.comm.tompi4py() if grid.comm.getSize() > 1 else None
        if self.mpi is not None:
            ends = np.array([self.spikes[0, 0], self.spikes[0, -1], self.spikes[1, 0], self.spikes[1, -1]]
                            if nloc else [0.0] * 4)
            allends = np.empty((self.mpi.size, 4))
            self.mpi.Allgather(ends, allends)
            counts = np.array(self.mpi.allgather(nloc))
            self._interface_system(allends, counts)

    def _interface_system(self, ends, counts):
        """The 2p x 2p system for z = (x_prev, x_next) of every non-empty rank: x_prev of one rank is the last
        entry of the previous non-empty rank, x_next the first entry of the next one (0 beyond the ends)."""
        self.active = np.flatnonzero(counts > 0)
        p = len(self.active)
        e = ends[self.active]                     # g_first, g_last, k_first, k_last per active rank
        A = np.eye(2 * p)
        for r in range(p):
            if r > 0:        # x_prev[r] = y_last[r-1] - x_prev[r-1] g_last[r-1] - x_next[r-1] k_last[r-1]
                A[r, r - 1] += e[r - 1, 1]
                A[r, p + r - 1] += e[r - 1, 3]
            if r < p - 1:    # x_next[r] = y_first[r+1] - x_prev[r+1] g_first[r+1] - x_next[r+1] k_first[r+1]
                A[p + r, r + 1] += e[r + 1, 0]
                A[p + r, p + r + 1] += e[r + 1, 2]
        self.interface_inverse = np.linalg.inv(A)
        self.my_index = int(np.searchsorted(self.active, self.mpi.rank)) if counts[self.mpi.rank] else -1

    def solve_local(self, x, out):
        """out = D2^{-1} x on the owned rows (numpy arrays; collective on several ranks)."""
        if self.nloc:
            self.rhs.getArray()[:] = x
            self.ksp.solve(self.rhs, self.sol)
            out[:] = self.sol.getArray(readonly=True)
        if self.mpi is None:
            return
        ends = np.array([out[0], out[-1]] if self.nloc else [0.0, 0.0])
        allends = np.empty((self.mpi.size, 2))
        self.mpi.Allgather(ends, allends)
        if self.my_index < 0:
            return
        p = len(self.active)
        b = np.zeros(2 * p)
        b[1:p] = allends[self.active[:-1], 1]       # y_last of the previous active rank
        b[p:2 * p - 1] = allends[self.active[1:], 0]  # y_first of the next active rank
        r = self.my_index
        x_prev, x_next = self.interface_inverse[r] @ b, self.interface_inverse[p + r] @ b
        out -= x_prev * self.spikes[0] + x_next * self.spikes[1]

    def apply(self, pc, x, y):
        self.solve_local(x.getArray(readonly=True), y.getArray())

    def destroy(self, pc=None):
        for obj in (self.ksp, self.block, self.rhs, self.sol):
            obj.destroy()


class PeriodicSecondDifferencePC:
    """The inner solve of ``-tw_solver nk`` for whole-period profiles (no symmetry): (D2 - I)^{-1} with the
    periodic second difference (singular alone: the constants), factored once by PETSc (LU on one rank, MUMPS on
    several). The shift stands for the bounded V'' part of the Jacobian on the lowest modes; GMRES corrects the
    rest, and the gauge border removes the constants and translations."""

    def __init__(self, grid, shift=1.0):
        d2 = second_difference(grid)
        diag = np.arange(grid.rstart, grid.rend, dtype=np.int64)[:, None]
        asm = RowAssembler(grid, [d2.cols["d2"], diag])
        self.A = asm.create([d2.coef["d2"], np.full((grid.rend - grid.rstart, 1), -float(shift))])
        self.ksp = PETSc.KSP().create(comm=grid.comm)
        self.ksp.setOperators(self.A)
        self.ksp.setType(PETSc.KSP.Type.PREONLY)
        pc = self.ksp.getPC()
        pc.setType(PETSc.PC.Type.LU)
        if grid.comm.getSize() > 1:
            pc.setFactorSolverType("mumps")
        self.ksp.setUp()
        self.x, self.y = self.A.createVecs()

    def solve_local(self, x, out):
        self.x.getArray()[:] = x
        self.ksp.solve(self.x, self.y)
        out[:] = self.y.getArray(readonly=True)

    def destroy(self, pc=None):
        for obj in (self.ksp, self.A, self.x, self.y):
            obj.destroy()


class BlockSecondDifferencePC:
    """The preconditioner of ``-tw_solver nk`` for p profiles and border scalars (a mass pattern, the
    fixed-amplitude form, a free continuation parameter): (m_c lam D2)^{-1} on each profile's rows (``scales`` =
    m_c lam, set at every Jacobian evaluation) and the identity on the scalars. The border is a low-rank change,
    which GMRES absorbs in a few iterations."""

    def __init__(self, inner, p, nloc):
        self.inner, self.p, self.nloc = inner, p, nloc
        self.scales = [1.0] * p

    def apply(self, pc, x, y):
        xa, ya = x.getArray(readonly=True), y.getArray()
        n = self.nloc
        for c in range(self.p):
            self.inner.solve_local(xa[c * n:(c + 1) * n], ya[c * n:(c + 1) * n])
            if self.scales[c] != 1.0:
                ya[c * n:(c + 1) * n] /= self.scales[c]
        ya[self.p * n:] = xa[self.p * n:]

    def destroy(self, pc=None):
        self.inner.destroy()


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


TW_SOLVERS = ("direct", "nk")

# The GMRES tolerance of the Newton-Krylov path (-tw_solver nk, :class:`SecondDifferencePC`): it keeps Newton
# quadratic down to round-off of the discrete equations.
NK_KSP_RTOL = 1e-10


def tw_solver(prefix=TW_PREFIX, solver=None):
    """The linear-solver path: ``solver`` if given, else ``-<prefix>solver`` from the options database, else
    'direct'. 'direct' is LU (MUMPS on several ranks); 'nk' is Newton-Krylov (GMRES + exact D2 solve)."""
    if solver is None:
        solver = PETSc.Options().getString(prefix + "solver", "direct")
    if solver not in TW_SOLVERS:
        raise ParameterError(f"-{prefix}solver", solver, "must be one of " + ", ".join(TW_SOLVERS))
    return solver


def _configure(snes, prefix, solver, grid, stencils=None, blocks=None):
    """The code defaults of the linear solves, then snes.setFromOptions() with :data:`QN_DEFAULTS` inserted for the
    call only (where the user set none); returns the nk preconditioner's context (None for 'direct'). ``blocks`` =
    (p, nloc): a layout of p profiles and border scalars (the nk preconditioner is then
    :class:`BlockSecondDifferencePC`; LU is MUMPS, whose pivoting handles the zero diagonal of the border rows,
    also on one rank)."""
    ksp = snes.getKSP()
    pc = ksp.getPC()
    context = None
    if solver == "direct":
        ksp.setType(PETSc.KSP.Type.PREONLY)
        pc.setType(PETSc.PC.Type.LU)
        if grid.comm.getSize() > 1 or blocks is not None:
            pc.setFactorSolverType("mumps")
    else:
        ksp.setType(PETSc.KSP.Type.GMRES)
        ksp.setTolerances(rtol=NK_KSP_RTOL)
        pc.setType(PETSc.PC.Type.PYTHON)
        context = PeriodicSecondDifferencePC(grid) if grid.parity == 0 else SecondDifferencePC(grid, stencils)
        if blocks is not None:
            context = BlockSecondDifferencePC(context, *blocks)
        pc.setPythonContext(context)
    defaults = QN_DEFAULTS if PETSc.Options().getString(prefix + "snes_type", "") == "qn" else {}
    with inserted_options(prefix, defaults):
        snes.setFromOptions()
    return context


def create_snes(problem, J, prefix=TW_PREFIX, tolerances=None, solver=None):
    """SNES with the paper-reproducing defaults, then the options database under ``prefix`` (read once).
    ``solver``: the linear solves' defaults (:func:`tw_solver`; 'nk' needs the problem's ``stencils["d2"]``), which
    -<prefix>ksp_type, -<prefix>pc_type, ... can change."""
    solver = tw_solver(prefix, solver)
    snes = PETSc.SNES().create(comm=problem.grid.comm)
    snes.setOptionsPrefix(prefix)
    snes.setType(PETSc.SNES.Type.NEWTONLS)
    F = problem.grid.create_vec()
    snes.setFunction(problem.formFunction, F)
    snes.setJacobian(problem.formJacobian, J, J)
    if tolerances:
        snes.setTolerances(**tolerances)
    _configure(snes, prefix, solver, problem.grid, getattr(problem, "stencils", None))
    F.destroy()
    return snes


class TravellingWaveSolver:
    """One SNES for eqs. ad-pbc, kept across the solves of a continuation on one grid.

    The SNES, its KSP/PC (for 'nk' the factored second difference) and work vectors are built, and the options
    database under ``prefix`` read, once; each :meth:`solve` hands SNES the problem at its current parameters and
    a Jacobian with that q's pattern. ``solver`` as in :func:`create_snes`. ``layout``: the
    :class:`~hertzpetsc.advdelay.AdvanceDelayProblem` whose X (or, ``extended``, Z) Vecs are solved for, when they
    are not the grid's own (a mass pattern, the fixed-amplitude form, a free parameter). Tolerances given to
    :meth:`solve` (by default from the round-off floor of the discrete equations) apply unless the user set
    -<prefix>snes_rtol/atol/stol/max_it. Every solve takes at least one Newton iteration.
    """

    def __init__(self, grid, prefix=TW_PREFIX, solver=None, layout=None, extended=False):
        self.grid, self.prefix = grid, prefix
        self.solver = tw_solver(prefix, solver)
        self.problem = self._deferred = None
        self.snes = PETSc.SNES().create(comm=grid.comm)
        self.snes.setOptionsPrefix(prefix)
        self.snes.setType(PETSc.SNES.Type.NEWTONLS)
        self.snes.setForceIteration(True)
        plain = layout is None or (layout.simple and not extended)
        if plain:
            self.F = grid.create_vec()
        else:
            self.F = layout.create_vec() if extended else layout.create_state()
        self.snes.setFunction(self._function, self.F)
        self.pc_context = _configure(self.snes, prefix, self.solver, grid,
                                     blocks=None if plain else (layout.p, layout.nloc))
        opts = PETSc.Options()
        default_kind = "shell" if self.solver == "nk" else "aij"
        self.jacobian_kind = opts.getString(prefix + "jacobian", default_kind)
        if self.jacobian_kind not in ("aij", "shell"):
            raise ParameterError(f"-{prefix}jacobian", self.jacobian_kind, "must be 'aij' (assembled, for LU and "
                                 "algebraic preconditioners) or 'shell' (matrix-free)")
        self._user_set = user_set(prefix + "snes_", ("rtol", "atol", "stol", "max_it"))

    def _reset(self):
        """After a solve that an exception left from a callback this class does not own (a shell product's, the
        preconditioner's: a signal's): PETSc 3.26 leaves its work vectors locked, so they are freed and the next
        solve makes new ones. On one rank only: on two, 3.26 deadlocked in the reset's wake; the residual and the
        Jacobian, where the exceptions of a Newton iterate arise, defer theirs instead (:meth:`_function`)."""
        if self.snes.getComm().getSize() == 1:
            self.snes.reset()
            self.snes.setFunction(self._function, self.F)

    def _function(self, snes, X, F):
        """The residual; an exception it raises (a Newton iterate out of the parameter's range, a signal) is kept
        and F set to NaN, which ends the solve at once (SNES's NaN checks, on every rank through the norm), and
        :meth:`solve` raises it after SNES has returned: raised through PETSc, it would leave SNES's vectors
        locked (PETSc 3.26)."""
        if self._deferred is None:
            try:
                self.problem.formFunction(snes, X, F)
                return
            except BaseException as err:
                self._deferred = err
        F.set(math.nan)

    def _jacobian(self, snes, X, J, P):
        """The Jacobian; an exception is kept as in :meth:`_function` (J left as it was: the next residual ends
        the solve)."""
        if self._deferred is None:
            try:
                self.problem.formJacobian(snes, X, J, P)
            except BaseException as err:
                self._deferred = err

    def _tolerances(self, problem, u):
        tol = default_tolerances(self.grid, problem.tolerance_scale(u))
        tol["atol"] *= math.sqrt(u.getSize() / self.grid.size)
        return tol

    @PETSc.Log.EventDecorator("hz_tw_solve")
    def solve(self, problem, u, tolerances=None):
        """Solve eqs. ad-pbc at the problem's parameters from the initial guess ``u`` (overwritten by the
        solution). Raises :class:`ConvergenceError` with the converged reason and q if SNES fails."""
        t0 = time.perf_counter()
        if tolerances is None:
            tolerances = self._tolerances(problem, u)
        self.snes.setTolerances(**{k: v for k, v in tolerances.items() if k not in self._user_set})
        J = problem.create_jacobian(u, self.jacobian_kind)
        self.problem = problem
        problem.preconditioner = self.pc_context if isinstance(self.pc_context, BlockSecondDifferencePC) else None
        self.snes.setJacobian(self._jacobian, J, J)
        self._deferred = None
        try:
            try:
                with callbacks_raise():
                    self.snes.solve(None, u)
            except BaseException:
                self._reset()
                raise
            if self._deferred is not None:
                raise self._deferred
            snes = self.snes
            result = SolveStats(reason=int(snes.getConvergedReason()),
                                 iterations=snes.getIterationNumber(),
                                 linear_iterations=snes.getLinearSolveIterations(),
                                 residual_norm=float(snes.getFunctionNorm()), wall_time=time.perf_counter() - t0)
        finally:
            self.problem = self._deferred = None
            J.destroy()        # SNES keeps its reference until the next solve
        what = "travelling-wave SNES (prefix -%s)" % self.prefix
        where = dict(q=problem.q)
        if getattr(problem, "parameter", "q") != "q":
            where[problem.parameter] = problem.get_parameter(problem.parameter)
        if result.reason <= 0:
            raise ConvergenceError(what, result.reason, **where)
        accept = ACCEPT_FACTOR * self._tolerances(problem, u)["atol"]
        if not result.residual_norm <= accept:
            raise ConvergenceError(what, f"{result.reason}, but residual {result.residual_norm:.3g} > {accept:.3g}",
                                   **where)
        return result

    def destroy(self):
        self.snes.destroy()
        self.F.destroy()


def solve_travelling_wave(problem, u, prefix=TW_PREFIX, tolerances=None, solver=None):
    """Solve eqs. ad-pbc at ``problem.q`` by SNES from the initial guess ``u`` (overwritten by the solution),
    with a one-off :class:`TravellingWaveSolver`. Raises :class:`ConvergenceError` if SNES fails."""
    tws = TravellingWaveSolver(problem.grid, prefix, solver)
    try:
        return tws.solve(problem, u, tolerances)
    finally:
        tws.destroy()

