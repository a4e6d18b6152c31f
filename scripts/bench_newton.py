#!/usr/bin/env python3
"""Benchmark of the Newton-Krylov path (-tw_solver nk) for eq. ad: Krylov iterations and time per Newton step
as the grid is refined, h = pi*1e-3 .. pi*1e-6 (2 million grid points), on 1 and 2 ranks.

    python scripts/bench_newton.py [-cells 1000,10000,100000,1000000] [-q 0.9*pi] [-repeats 2]
                                   [-output results/bench_newton.md] [-logview_cells 1000000] [-- PETSc options]

One Newton solve of eqs. ad-pbc at q (default 0.9 pi, a shift that is neither 0 nor the half-period reflection)
from the binary oscillation u0 rescaled by (pi/q)^(2/(alpha-1)), alpha = 3/2. Each measurement runs in its own
process (under mpiexec for 2 ranks, one OpenBLAS thread per rank); reported: Newton and Krylov iterations,
wall time of the SNES solve per Newton step (set-up excluded, reported apart), peak resident memory per rank,
best of -repeats. Parallel efficiency = t(1 rank) / (2 t(2 ranks)) per Newton step. For -logview_cells the solve
is run once more with -log_view on 1 and 2 ranks, into results/logview_newton_np{1,2}.txt.
Before anything is allocated the memory is checked (:func:`hertzpetsc.resources.check_memory`): a grid that
would not fit is refused with the estimate. Measure on an otherwise idle machine: 2 ranks share its 2 cores.
"""
import argparse
import math
import os
import platform
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from hertzpetsc.benchmarking import best_of, emit  # noqa: E402


def worker(K, q):
    import petsc4py
    argv, skip = sys.argv[:1], 0
    for a in sys.argv[1:]:                       # PETSc options only (drop --worker, --K value, --q value)
        if skip or a == "--worker":
            skip = 0
        elif a in ("--K", "--q"):
            skip = 1
        else:
            argv.append(a)
    petsc4py.init(argv)
    from mpi4py import MPI
    from petsc4py import PETSc

    from hertzpetsc.advdelay import AdvanceDelayProblem, TravellingWaveSolver, tw_solver
    from hertzpetsc.binary import binary_oscillation
    from hertzpetsc.grid import OddPeriodicGrid
    from hertzpetsc.hertz import HertzPotential
    from hertzpetsc.resources import check_memory

    comm = MPI.COMM_WORLD
    solver = tw_solver()
    check_memory(K, PETSc.COMM_WORLD, solver)
    pot = HertzPotential(1.5)
    grid = OddPeriodicGrid(K, PETSc.COMM_WORLD)
    u = grid.create_vec()          # u0 at the owned points only (nothing of global size on any rank)
    u.setArray(binary_oscillation(pot, grid.owned_points() * grid.h))
    u.scale((math.pi / q) ** pot.rescaling_exponent)
    comm.Barrier()
    t0 = time.perf_counter()
    problem = AdvanceDelayProblem(pot, grid, q)
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
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-cells", default="1000,10000,100000,1000000")
    ap.add_argument("-q", default="0.9*pi")
    ap.add_argument("-repeats", type=int, default=2)
    ap.add_argument("-output", default="results/bench_newton.md")
    ap.add_argument("-logview_cells", type=int, default=1000000, help="0 for no -log_view runs")
    ap.add_argument("-timeout", type=int, default=1800)
    ap.add_argument("--worker", action="store_true")
    ap.add_argument("--K", type=int)
    ap.add_argument("--q", dest="wq", type=float)
    args, extra = ap.parse_known_args()
    if args.worker:
        return worker(args.K, args.wq)
    extra = [a for a in extra if a != "--"]
    try:
        cells = [int(c) for c in args.cells.split(",")]
        q = float(eval(args.q, {"__builtins__": {}}, {"pi": math.pi}))
    except Exception:
        print(f"error: invalid -cells = {args.cells!r} or -q = {args.q!r}", file=sys.stderr)
        return 2
    if not extra or "-tw_solver" not in extra:
        extra = ["-tw_solver", "nk", *extra]
    script = os.path.abspath(__file__)
    load = os.getloadavg()
    lines = [f"One Newton solve of eq. ad at q = {q / math.pi:.4g} pi (alpha = 3/2, from the rescaled u0), options "
             f"`{' '.join(extra)}`; best of {args.repeats}. Machine: {os.cpu_count()} cores, "
             f"{platform.processor() or platform.machine()}; load average (1, 5, 15 min) at start "
             f"{load[0]:.2f}, {load[1]:.2f}, {load[2]:.2f}; {time.strftime('%Y-%m-%d %H:%M')}.\n",
             "| h | unknowns | ranks | Newton its | Krylov its | Krylov / Newton | s / Newton step | set-up (s) | "
             "peak MB/rank | parallel eff. | rel. diff max u (2 vs 1 rank) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for K in cells:
        runs = {}
        for ranks in (1, 2):
            runs[ranks] = best_of(args.repeats, script, ["--worker", "--K", K, "--q", q, *extra], ranks,
                                  args.timeout)
        for ranks, r in runs.items():
            if r is None:
                lines.append(f"| pi/{K} | {K - 1} | {ranks} | timed out ({args.timeout} s) | | | | | | | |")
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
    if args.logview_cells:
        K = args.logview_cells
        for ranks in (1, 2):
            path = os.path.join(ROOT, "results", f"logview_newton_np{ranks}.txt")
            best_of(1, script, ["--worker", "--K", K, "--q", q, *extra, "-log_view", f":{path}"], ranks,
                    args.timeout)
            lines.append(f"\n-log_view of the h = pi/{K} solve on {ranks} rank(s): `{os.path.relpath(path, ROOT)}`")
    text = "\n".join(lines) + "\n"
    out = os.path.join(ROOT, args.output) if not os.path.isabs(args.output) else args.output
    os.makedirs(os.path.dirname(out), exist_ok=True)
    tmp = out + ".tmp"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, out)
    print(text)


if __name__ == "__main__":
    sys.exit(main())
