"""The Newton-Krylov path of eq. ad (-tw_solver nk): exact D2 preconditioner, agreement with the direct path,
h-independent Krylov counts, rank independence, option handling and the up-front memory refusal."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from hertzpetsc.advdelay import AdvanceDelayProblem
from hertzpetsc.binary import binary_oscillation
from hertzpetsc.qbranch import BranchContinuation, ContinuationParameters
from hertzpetsc.errors import ParameterError
from hertzpetsc.grid import ProfileGrid
from hertzpetsc.model import LatticeModel
from hertzpetsc.resources import check_memory, estimate_memory
from hertzpetsc.twsolver import SecondDifferencePC, TravellingWaveSolver, solve_travelling_wave

POT = LatticeModel.hertz(1.5)
COMM = PETSc.COMM_WORLD


def solve(K, q, solver, comm=COMM):
    """Solve at q by a short continuation from u0 (steps of at most pi/10); profile and Krylov counts."""
    g = ProfileGrid(K, comm)
    u = g.vec_from_half_profile(binary_oscillation(POT.law, g.xi_half()))
    tws = TravellingWaveSolver(g, solver=solver)
    qs = list(np.arange(math.pi, q, -math.pi / 10)) + [q]
    guess_q, its = math.pi, []
    for qq in qs:
        u.scale((guess_q / qq) ** POT.law.rescaling_exponent)
        guess_q = qq
        prob = AdvanceDelayProblem(POT, g, qq)
        res = tws.solve(prob, u)
        its.append((res.iterations, res.linear_iterations))
        prob.destroy()
    tws.destroy()
    out = g.half_profile(u)
    u.destroy()
    return out, its


def test_preconditioner_inverts_the_second_difference_exactly():
    """SecondDifferencePC applied to D2 x gives x back, whatever the partition (run under mpiexec -n 2 too)."""
    g = ProfileGrid(97, COMM)
    prob = AdvanceDelayProblem(POT, g, 1.0)
    pc = SecondDifferencePC(g, prob.stencils)
    x = g.vec_from_half_profile(np.concatenate([[0], np.random.default_rng(3).standard_normal(96), [0]]))
    _, _, d2x = prob.shift_differences(x)
    f, y = x.duplicate(), x.duplicate()
    f.getArray()[:] = d2x
    pc.apply(None, f, y)
    y.axpy(-1.0, x)
    assert y.norm() <= 1e-12 * x.norm()
    pc.destroy()
    prob.destroy()


@pytest.mark.parametrize("q", [0.7 * math.pi, 2.0])      # whole-step and interpolated shifts
def test_newton_krylov_agrees_with_direct(q):
    direct, _ = solve(160, q, "direct")
    nk, its = solve(160, q, "nk")
    assert np.max(np.abs(nk - direct)) <= 1e-10 * np.max(np.abs(direct))
    assert all(k > n for n, k in its)           # it really took the Krylov path


def test_matrix_free_product_equals_assembled_jacobian():
    g = ProfileGrid(120, COMM)
    u = g.vec_from_half_profile(binary_oscillation(POT.law, g.xi_half()) * 1.3)
    v = g.vec_from_half_profile(np.sin(g.xi_half()) + 0.2 * np.sin(7 * g.xi_half()))
    prob = AdvanceDelayProblem(POT, g, 2.0)
    A, S = prob.create_jacobian(u, "aij"), prob.create_jacobian(u, "shell")
    ya, ys = v.duplicate(), v.duplicate()
    A.mult(v, ya)
    S.mult(v, ys)
    ys.axpy(-1.0, ya)
    assert ys.norm() <= 1e-13 * ya.norm()
    for obj in (A, S, ya, ys, u, v):
        obj.destroy()
    prob.destroy()


def test_krylov_iterations_do_not_grow_with_the_grid():
    """D2^{-1} J = I + compact: Krylov iterations per Newton step stay bounded when K doubles (twice)."""
    per_step = []
    for K in (200, 400, 800, 1600):
        _, its = solve(K, 0.5 * math.pi, "nk")
        per_step.append(sum(k for _, k in its) / sum(n for n, _ in its))
    assert max(per_step) <= 10, per_step
    assert per_step[-1] <= per_step[0] + 1.0, per_step


def test_one_rank_equals_all_ranks():
    """Under mpiexec -n 2: the distributed Newton-Krylov solve equals the serial one to solver tolerance."""
    serial, its_s = solve(160, 0.5, "nk", PETSc.COMM_SELF)
    parallel, its_p = solve(160, 0.5, "nk", PETSc.COMM_WORLD)
    assert np.max(np.abs(serial - parallel)) <= 1e-10 * np.max(np.abs(serial))
    assert [n for n, _ in its_s] == [n for n, _ in its_p]


def test_branch_with_newton_krylov_reproduces_the_direct_branch():
    kw = dict(M=10, cells_per_pi=200, q_stop=math.pi / 5)
    out = {}
    for solver in ("direct", "nk"):
        cont = BranchContinuation(ContinuationParameters(**kw), COMM, solver=solver)
        out[solver] = list(cont.points())
        cont.destroy()
    for a, b in zip(out["direct"], out["nk"]):
        assert a.q == b.q and b.solve.linear_iterations > b.solve.iterations
        assert np.max(np.abs(a.u_half - b.u_half)) <= 1e-10 * np.max(a.u_half)


def test_solver_is_selected_from_the_options_database(clean_options):
    g = ProfileGrid(100, COMM)
    default = TravellingWaveSolver(g)
    assert default.solver == "direct"          # the default is unchanged
    default.destroy()
    clean_options.setValue("tw_solver", "nk")
    tws = TravellingWaveSolver(g)
    assert tws.solver == "nk" and tws.jacobian_kind == "shell"
    assert tws.snes.getKSP().getType() == "gmres" and tws.snes.getKSP().getPC().getType() == "python"
    tws.destroy()
    # an assembled Jacobian and an algebraic preconditioner, all from the options database
    clean_options.setValue("tw_jacobian", "aij")
    clean_options.setValue("tw_pc_type", "bjacobi")
    g2 = ProfileGrid(100, COMM)
    u = g2.vec_from_half_profile(binary_oscillation(POT.law, g2.xi_half()))
    prob = AdvanceDelayProblem(POT, g2, math.pi)
    res = solve_travelling_wave(prob, u)
    assert res.reason > 0 and res.linear_iterations > res.iterations
    prob.destroy()


@pytest.mark.parametrize("name,value", [("tw_solver", "cholesky"), ("tw_jacobian", "dense")])
def test_bad_solver_options_are_rejected(clean_options, name, value):
    clean_options.setValue(name, value)
    with pytest.raises(ParameterError, match=f"-{name}.*must be"):
        TravellingWaveSolver(ProfileGrid(50, COMM))


def test_too_fine_grid_is_refused_before_allocation():
    """2e9 cells per pi (~2 TB) is refused with the estimate and the largest grid that fits."""
    with pytest.raises(ParameterError, match=r"cells_per_pi.*needs about .* GiB.*must be <= \d+"):
        check_memory(1_000_000_000, PETSc.COMM_SELF, "nk")
    with pytest.raises(ParameterError, match=r"cells_per_pi.*index type"):
        check_memory(2 ** 31 + 10, PETSc.COMM_SELF, "nk")
    # a machine with 1 GiB available: 10 million cells do not fit, 100 000 do
    with pytest.raises(ParameterError, match="cells_per_pi"):
        check_memory(10_000_000, PETSc.COMM_SELF, "nk", available=2.0 ** 30)
    check_memory(100_000, PETSc.COMM_SELF, "nk", available=2.0 ** 30)
    # the continuation refuses up front (no grid, no Vec of 1e9 entries is ever created)
    with pytest.raises(ParameterError, match="cells_per_pi.*GiB"):
        BranchContinuation(ContinuationParameters(cells_per_pi=1_000_000_000), COMM, solver="nk")


def test_memory_estimate_splits_over_ranks():
    one, total1 = estimate_memory(10 ** 6, 1, "nk")
    two, total2 = estimate_memory(10 ** 6, 2, "nk")
    assert two < 0.6 * one and total2 > total1
    assert estimate_memory(10 ** 6, 1, "direct")[0] > one
    with pytest.raises(ParameterError, match="solver"):
        estimate_memory(1000, 1, "qr")


@pytest.mark.serial
def test_newton_benchmark_script(tmp_path):
    from conftest import run_script
    out = tmp_path / "bench_newton.md"
    r = run_script("bench_newton.py", "-cells", "100,200", "-repeats", 1, "-logview_cells", 0, "-output", out,
                   timeout=600)
    assert r.returncode == 0, r.stderr
    rows = [l for l in out.read_text().splitlines() if l.startswith("| pi*")]
    assert len(rows) == 4 and all(int(l.split("|")[5]) > int(l.split("|")[4]) for l in rows)


class _IterateLeavesTheRange(AdvanceDelayProblem):
    """eq. ad whose residual raises at its ``fail_at``-th evaluation, as a Newton iterate whose parameter leaves its
    range does (advdelay's free-parameter solves)."""

    def __init__(self, *args, fail_at, **kw):
        super().__init__(*args, **kw)
        self.fail_at, self.calls = fail_at, 0

    def formFunction(self, snes, X, F):
        self.calls += 1
        if self.calls == self.fail_at:
            raise ParameterError("amplitude", 0.0, "the wave amplitude must be a finite number > 0")
        super().formFunction(snes, X, F)


@pytest.mark.parametrize("solver", ["direct", "nk"])
def test_an_exception_in_the_residual_ends_the_solve_and_the_next_solve_runs(solver):
    """A residual that raises mid-solve: the solve ends with that exception (not a PETSc error), the residual is not
    evaluated again, and the same solver's next solve gives what a new solver gives. Raised through PETSc, the
    exception left SNES's vectors locked on PETSc 3.26 (error 73 at the next solve under mpiexec -n 2; 3.18's
    optimised build does not check locks): the solver keeps it and ends the solve with a NaN residual instead."""
    g = ProfileGrid(120, COMM)
    start = g.vec_from_half_profile(binary_oscillation(POT.law, g.xi_half()))
    tws = TravellingWaveSolver(g, solver=solver)
    bad = _IterateLeavesTheRange(POT, g, 0.9 * math.pi, fail_at=3)
    u = start.copy()
    u.scale((math.pi / (0.9 * math.pi)) ** POT.law.rescaling_exponent)
    guess = u.copy()
    with pytest.raises(ParameterError, match="amplitude"):
        tws.solve(bad, u)
    assert bad.calls == 3
    results = []
    for solver_now in (tws, TravellingWaveSolver(g, solver=solver)):
        prob = AdvanceDelayProblem(POT, g, 0.9 * math.pi)
        w = guess.copy()
        assert solver_now.solve(prob, w).reason > 0
        results.append(g.half_profile(w))
        prob.destroy()
        solver_now.destroy()
        w.destroy()
    # the same Newton path from the same guess: equal but for round-off (MUMPS on two ranks is not bitwise
    # reproducible from run to run)
    assert np.max(np.abs(results[0] - results[1])) <= 1e-12 * np.max(np.abs(results[1]))
    for obj in (bad, start, u, guess):
        obj.destroy()
