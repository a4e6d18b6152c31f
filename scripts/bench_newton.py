#!/usr/bin/env python3
"""Benchmark of the Newton-Krylov path (-tw_solver nk) for eq. ad: Krylov iterations and time per Newton step
as the grid is refined, h = pi*1e-3 .. pi*1e-6 (2 million grid points), on 1 and 2 ranks.

    python scripts/bench_newton.py [-cells 1000,10000,100000,1000000] [-q 0.9*pi] [-repeats 2]
                                   [-output runs/bench_newton.md] [-logview_cells 1000000] [-tw_... options]

One Newton solve of eqs. ad-pbc at q (default 0.9 pi, a shift that is neither 0 nor the half-period reflection)
from the binary oscillation u0 rescaled by (pi/q)^(2/(alpha-1)), alpha = 3/2. Each measurement runs in its own
process (under mpiexec for 2 ranks, one OpenBLAS thread per rank); reported: Newton and Krylov iterations,
wall time of the SNES solve per Newton step (set-up excluded, reported apart), peak resident memory per rank,
best of -repeats. Parallel efficiency = t(1 rank) / (2 t(2 ranks)) per Newton step. For -logview_cells the solve
is run once more with -log_view on 1 and 2 ranks, into logview_newton_np{1,2}.txt beside -output. -tw_* options go to
the solves (default -tw_solver nk). Before anything is allocated the memory is checked
(:func:`hertzpetsc.resources.check_memory`): a grid that would not fit is refused with the estimate.
Measure on an otherwise idle machine: 2 ranks share its 2 cores.
"""
import math
import os
import sys
import time

from benchlib import BenchRecords, best_of, declare_common, emit, machine, main_or_worker, write_report

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def worker(name, req, petsc_args):
    import petsc4py
    petsc4py.init(sys.argv[:1] + petsc_args)
    from mpi4py import MPI
    from petsc4py import PETSc

    from hertzpetsc.advdelay import AdvanceDelayProblem
    from hertzpetsc.binary import binary_oscillation
    from hertzpetsc.grid import ProfileGrid
    from hertzpetsc.model import LatticeModel
    from hertzpetsc.resources import check_memory
    from hertzpetsc.twsolver import TravellingWaveSolver, tw_solver

    K, q = req["K"], req["q"]
    comm = MPI.COMM_WORLD
    solver = tw_solver()
    check_memory(K, PETSc.COMM_WORLD, solver)
    model = LatticeModel.hertz(1.5)
    grid = ProfileGrid(K, PETSc.COMM_WORLD)
    u = grid.create_vec()          # u0 at the owned points only (nothing of global size on any rank)
    u.setArray(binary_oscillation(model.law, grid.owned_points() * grid.h))
    u.scale((math.pi / q) ** model.law.rescaling_exponent)
    comm.Barrier()
    t0 = time.perf_counter()
    problem = AdvanceDelayProblem(model, grid, q)
    tws = TravellingWaveSolver(grid)
    comm.Barrier()
    setup = time.perf_counter() - t0
    res = tws.solve(problem, u)
    comm.Barrier()
    wall = time.perf_counter() - t0 - setup
    umax = u.norm(PETSc.NormType.NORM_INFINITY)
    tws.destroy()
    problem.destroy()
    emit(comm, wall=wall, setup=setup, newton=res.iterations, krylov=res.linear_iterations,
         residual=res.residual_norm, umax=umax, solver=solver)


def main():
    from petsc4py import PETSc

    from hertzpetsc.options import AppOptions
    opts = AppOptions(__doc__, {"tw_": ("the solves' travelling-wave SNES (passed on)", ("snes",))})
    cells = opts.numbers("cells", "1000,10000,100000,1000000", "grids h = pi/K", expr=False, kind=int,
                         valid=(lambda K: K >= 4, ">= 4"), distinct=True)
    q = opts.real("q", 0.9 * math.pi, "wavenumber", expr=True, valid=(lambda x: 0 < x <= math.pi, "in (0, pi]"))
    logview = opts.integer("logview_cells", 1000000, "grid of the -log_view runs (0: none)", minimum=0)
    timeout = opts.integer("timeout", 1800, "seconds before a run is given up", minimum=1)
    output, repeats, records_path, mode = declare_common(opts, "runs/bench_newton.md", repeats=2)
    opts.done()
    from hertzpetsc.resources import check_memory
    for K in cells:                          # refused before any worker is started
        check_memory(K, PETSc.COMM_WORLD, name="cells")
    extra = [w for k, v in PETSc.Options().getAll().items() if k.startswith("tw_")
             for w in ([f"-{k}"] + ([v] if v not in (None, "") else []))]
    opts.check_unused(passed_on=("tw_",))
    if "-tw_solver" not in extra:
        extra = ["-tw_solver", "nk", *extra]
    script = os.path.abspath(__file__)
    rec = BenchRecords(records_path, "hertzpetsc-bench-newton-1", dict(q=q, extra=extra), mode)
    lines = [f"One Newton solve of eq. ad at q = {q / math.pi:.4g} pi (alpha = 3/2, from the rescaled u0), options "
             f"`{' '.join(extra)}`; {machine(repeats)}.\n",
             "| h | unknowns | ranks | Newton its | Krylov its | Krylov / Newton | s / Newton step | set-up (s) | "
             "peak MB/rank | parallel eff. | rel. diff max u (2 vs 1 rank) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for K in cells:
        runs = {ranks: rec.measure(f"{K} {ranks}", lambda: best_of(repeats, script, "newton", dict(K=K, q=q), ranks,
                                                                    timeout, extra)) for ranks in (1, 2)}
        for ranks, r in runs.items():
            if r is None:
                lines.append(f"| pi/{K} | {K - 1} | {ranks} | timed out ({timeout} s) | | | | | | | |")
                continue
            per = r["wall"] / max(r["newton"], 1)
            eff = diff = ""
            if ranks == 2 and runs[1] is not None:
                eff = f"{runs[1]['wall'] / (2 * r['wall']):.0%}"
                diff = f"{abs(r['umax'] - runs[1]['umax']) / runs[1]['umax']:.1e}"
            lines.append(f"| pi*{1 / K:.0e} | {K - 1} | {ranks} | {r['newton']} | {r['krylov']} | "
                         f"{r['krylov'] / max(r['newton'], 1):.1f} | {per:.3g} | {r['setup']:.2f} | "
                         f"{max(r['rss_mb']):.0f} | {eff} | {diff} |")
        print("\n".join(lines[-2:]), flush=True)
    if logview:
        for ranks in (1, 2):
            path = os.path.join(os.path.dirname(os.path.abspath(output)), f"logview_newton_np{ranks}.txt")
            best_of(1, script, "newton", dict(K=logview, q=q), ranks, timeout, [*extra, "-log_view", f":{path}"])
            lines.append(f"\n-log_view of the h = pi/{logview} solve on {ranks} rank(s): `{os.path.relpath(path, ROOT)}`")
    write_report(output, lines)


if __name__ == "__main__":
    main_or_worker(main, worker)
