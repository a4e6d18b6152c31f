#!/usr/bin/env python3
"""Benchmark: integrating a travelling wave on a periodic chain over one script-T, hertzpetsc (PETSc TS, RK 8(7),
1 and 2 ranks) against scipy.integrate.solve_ivp (DOP853), both with rtol 1e-12, atol 1e-14; and the cost of
one Gauss-Newton refinement at N = 100.

    python scripts/bench_chain.py [-branch results/branch_alpha1.5.npz] [-sizes 100,10000,1000000]
                                  [-repeats 3] [-output runs/bench_chain.md] [-scipy_timeout 600] [-refine_N 100]

The wave is q = 3 pi/10 (15 wavelengths per 100 beads), so N must be a multiple of 20. Each measurement runs in
its own process; wall time excludes start-up and the construction of the initial state; best of -repeats
(one run for N >= 1e6). Peak memory is each process's maximum resident set. -records FILE keeps the measurements
as they are taken (-resume continues). Run on an idle machine.
"""
import math
import os
import sys
import time

from benchlib import BenchRecords, best_of, declare_chains, declare_common, emit, machine, main_or_worker, write_report

Q = 3 * math.pi / 10
RTOL, ATOL = 1e-12, 1e-14


def initial(branch_path, N):
    from hertzpetsc.branch import Branch
    from hertzpetsc.model import ChainSpec
    from hertzpetsc.waves import orbit_on_chain
    branch = Branch.load(branch_path)
    return orbit_on_chain(branch.point(Q), ChainSpec(branch.model, N))


def scipy_worker(branch_path, N):
    import numpy as np
    from scipy.integrate import solve_ivp
    w = initial(branch_path, N)
    alpha = 1.5

    def f(t, y):
        x, v = y[:N], y[N:]
        b = -np.abs(np.minimum(np.roll(x, -1) - x, 0.0)) ** alpha
        return np.concatenate([v, b - np.roll(b, 1)])

    y0 = np.concatenate([w.x[:, 0], w.x[:, 1]])
    t0 = time.perf_counter()
    sol = solve_ivp(f, (0.0, w.T), y0, method="DOP853", rtol=RTOL, atol=ATOL)
    wall = time.perf_counter() - t0
    yT = sol.y[:, -1]
    E = float(np.max(np.abs(np.concatenate([np.roll(yT[:N], -1), np.roll(yT[N:], -1)]) - y0)) / np.max(np.abs(y0)))
    emit(None, wall=wall, steps=len(sol.t) - 1, E=E)


def petsc_worker(branch_path, N, refine_only, petsc_args):
    import petsc4py
    petsc4py.init(sys.argv[:1] + petsc_args)
    from mpi4py import MPI
    from petsc4py import PETSc

    from hertzpetsc.chain import Chain, ChainIntegrator, IntegrationTolerances
    from hertzpetsc.shooting import Refiner
    w = initial(branch_path, N)
    comm = MPI.COMM_WORLD
    if refine_only:
        comm.Barrier()
        t0 = time.perf_counter()
        with Refiner(w.spec, PETSc.COMM_WORLD) as refiner:
            res = refiner.refine(w)
        emit(comm, wall=time.perf_counter() - t0, steps=res.iterations, rhs=res.jacobians, E=res.E)
        return
    chain = Chain(w.spec, PETSc.COMM_WORLD)
    X = chain.create_state()
    chain.set_from_array(X, w.x)
    integ = ChainIntegrator(chain, IntegrationTolerances(RTOL, ATOL))
    comm.Barrier()
    t0 = time.perf_counter()
    steps = integ.integrate(X, 0.0, w.T)
    comm.Barrier()
    wall = time.perf_counter() - t0
    SX = chain.create_state()
    chain.shift(X, SX)
    X0 = chain.create_state()
    chain.set_from_array(X0, w.x)
    SX.axpy(-1.0, X0)
    E = SX.norm(PETSc.NormType.NORM_INFINITY) / X0.norm(PETSc.NormType.NORM_INFINITY)
    emit(comm, wall=wall, steps=steps, E=E)


def worker(name, req, petsc_args):
    if name == "scipy":
        scipy_worker(req["branch"], req["N"])
    else:
        petsc_worker(req["branch"], req["N"], name == "refine", petsc_args)


def main():
    from hertzpetsc.options import AppOptions
    opts = AppOptions(__doc__)
    branch, sizes = declare_chains(opts, "100,10000,1000000", 20, "q = 3 pi/10 on the chain")
    scipy_timeout = opts.integer("scipy_timeout", 600, "seconds before a SciPy run is given up", minimum=1)
    refine_N = opts.integer("refine_N", 100, "chain of the refinement measurement (0: none)", minimum=0)
    output, repeats, records_path, mode = declare_common(opts, "runs/bench_chain.md")
    opts.done()
    from petsc4py import PETSc

    from hertzpetsc.resources import check_chain_memory
    for N in sizes:                          # refused before any worker is started (the SciPy route's arrays too)
        check_chain_memory(N, PETSc.COMM_WORLD, name="sizes")
    initial(branch, sizes[0])                                # the workers' input, checked before any worker runs
    opts.check_unused()
    me = os.path.abspath(__file__)
    rec = BenchRecords(records_path, "hertzpetsc-bench-chain-1", dict(branch=branch), mode)
    lines = [f"Travelling wave q = 3pi/10 over one script-T on a periodic chain; rtol {RTOL:g}, atol {ATOL:g}; "
             f"(1 repeat for N >= 1e6); {machine(repeats)}.\n",
             "| N | route | ranks | wall (s) | steps | steps/s | E(q) after one script-T | peak MB/rank | "
             "SciPy time / this |", "|---|---|---|---|---|---|---|---|---|"]
    for N in sizes:
        rep = 1 if N >= 10 ** 6 else repeats
        req = dict(branch=branch, N=N)
        sci = rec.measure(f"{N} scipy", lambda: best_of(rep, me, "scipy", req, None, scipy_timeout))
        rows = [("SciPy solve_ivp DOP853", 1, sci)]
        for ranks in (1, 2):
            rows.append(("hertzpetsc TS rk 8vr", ranks,
                         rec.measure(f"{N} petsc {ranks}", lambda: best_of(rep, me, "petsc", req, ranks))))
        for name, ranks, res in rows:
            if res is None:
                lines.append(f"| {N} | {name} | {ranks} | > {scipy_timeout} (not finished) | | | | | |")
                continue
            ratio = f"{sci['wall'] / res['wall']:.2f}" if sci else "n/a"
            lines.append(f"| {N} | {name} | {ranks} | {res['wall']:.3f} | {res['steps']} | "
                         f"{res['steps'] / res['wall']:.1f} | {res['E']:.1e} | {max(res['rss_mb']):.0f} | {ratio} |")
        print("\n".join(lines[-3:]), flush=True)
    if refine_N:
        lines += ["", f"One Gauss-Newton refinement at N = {refine_N}, q = 3pi/10 (dense Jacobian S R - I from "
                  f"{2 * refine_N} tangent vectors, tight flow rtol 1e-14):", "",
                  "| ranks | wall (s) | Gauss-Newton iterations | Jacobians | E after | peak MB/rank |",
                  "|---|---|---|---|---|---|"]
        for ranks in (1, 2):
            res = rec.measure(f"refine {refine_N} {ranks}", lambda: best_of(repeats, me, "refine",
                                                                            dict(branch=branch, N=refine_N), ranks))
            lines.append(f"| {ranks} | {res['wall']:.2f} | {res['steps']} | {res['rhs']} | {res['E']:.1e} | "
                         f"{max(res['rss_mb']):.0f} |")
    write_report(output, lines)


if __name__ == "__main__":
    main_or_worker(main, worker)
