#!/usr/bin/env python3
"""Benchmark: integrating a travelling wave on a periodic chain over one script-T, hertzpetsc (PETSc TS, RK 8(7),
1 and 2 ranks) against scipy.integrate.solve_ivp (DOP853), both with rtol 1e-12, atol 1e-14; and the cost of
one Gauss-Newton refinement at N = 100.

    python scripts/bench_chain.py [-branch results/branch_alpha1.5.npz] [-sizes 100,10000,1000000]
                                  [-repeats 3] [-output results/bench_chain.md] [-scipy_timeout 600]

The wave is q = 3 pi/10 (15 wavelengths per 100 beads), so N must be a multiple of 20. Each measurement runs in
its own process; wall time excludes start-up and the construction of the initial state; best of -repeats
(one run for N >= 1e6). Peak memory is each process's maximum resident set. Run on an idle machine.
"""
import argparse
import math
import os
import platform
import sys
import time

from hertzpetsc.benchmarking import best_of, emit, write_report

Q = 3 * math.pi / 10
RTOL, ATOL = 1e-12, 1e-14


def initial(branch_path, N):
    from hertzpetsc.branchfile import read_branch
    from hertzpetsc.waves import wave_on_chain
    return wave_on_chain(read_branch(branch_path), Q, N)


def scipy_worker(branch_path, N):
    import numpy as np
    from scipy.integrate import solve_ivp
    w = initial(branch_path, N)
    alpha = 1.5

    def f(t, y):
        x, v = y[:N], y[N:]
        b = -np.abs(np.minimum(np.roll(x, -1) - x, 0.0)) ** alpha
        return np.concatenate([v, b - np.roll(b, 1)])

    y0 = np.concatenate([w.x, w.v])
    t0 = time.perf_counter()
    sol = solve_ivp(f, (0.0, w.T), y0, method="DOP853", rtol=RTOL, atol=ATOL)
    wall = time.perf_counter() - t0
    yT = sol.y[:, -1]
    E = float(np.max(np.abs(np.concatenate([np.roll(yT[:N], -1), np.roll(yT[N:], -1)]) - y0)) / np.max(np.abs(y0)))
    steps = len(sol.t) - 1
    emit(None, wall=wall, steps=steps, E=E)


def petsc_worker(branch_path, N, refine_only):
    import petsc4py
    petsc4py.init(sys.argv[:1])
    from mpi4py import MPI
    from petsc4py import PETSc

    from hertzpetsc.chain import Chain, ChainIntegrator, ChainParameters, IntegrationTolerances
    w = initial(branch_path, N)
    comm = MPI.COMM_WORLD
    params = ChainParameters(1.5, N)
    if refine_only:
        from hertzpetsc.shooting import refine
        comm.Barrier()
        t0 = time.perf_counter()
        res = refine(params, w.as_array(), w.T, PETSc.COMM_WORLD)
        wall = time.perf_counter() - t0
        emit(comm, wall=wall, steps=res.iterations, rhs=res.jacobians, E=res.E)
        return
    chain = Chain(params, PETSc.COMM_WORLD)
    X = chain.create_state()
    chain.set_from_array(X, w.as_array())
    integ = ChainIntegrator(chain, IntegrationTolerances(RTOL, ATOL))
    comm.Barrier()
    t0 = time.perf_counter()
    steps = integ.integrate(X, 0.0, w.T)
    comm.Barrier()
    wall = time.perf_counter() - t0
    SX = chain.create_state()
    chain.shift(X, SX)
    X0 = chain.create_state()
    chain.set_from_array(X0, w.as_array())
    SX.axpy(-1.0, X0)
    E = SX.norm(PETSc.NormType.NORM_INFINITY) / X0.norm(PETSc.NormType.NORM_INFINITY)
    emit(comm, wall=wall, steps=steps, E=E)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-branch", default="results/branch_alpha1.5.npz")
    ap.add_argument("-sizes", default="100,10000,1000000")
    ap.add_argument("-repeats", type=int, default=3)
    ap.add_argument("-output", default="results/bench_chain.md")
    ap.add_argument("-scipy_timeout", type=int, default=600)
    ap.add_argument("--worker")
    ap.add_argument("--N", type=int)
    args = ap.parse_args()
    if args.worker == "scipy":
        return scipy_worker(args.branch, args.N)
    if args.worker in ("petsc", "refine"):
        return petsc_worker(args.branch, args.N, args.worker == "refine")
    try:
        sizes = [int(s) for s in args.sizes.split(",")]
    except ValueError:
        print(f"error: invalid -sizes = {args.sizes!r}: must be comma-separated integers", file=sys.stderr)
        return 2
    bad = [N for N in sizes if N < 20 or N % 20]
    if bad or args.repeats < 1:
        print(f"error: invalid -sizes {bad} or -repeats {args.repeats}: N must be a multiple of 20 "
              "(q = 3 pi/10 on the chain), repeats >= 1", file=sys.stderr)
        return 2
    me = os.path.abspath(__file__)
    lines = [f"Travelling wave q = 3pi/10 over one script-T on a periodic chain; rtol {RTOL:g}, atol {ATOL:g}; "
             f"best of {args.repeats} (1 for N >= 1e6). Machine: {os.cpu_count()} cores, {platform.machine()}; "
             f"load average at start {os.getloadavg()[0]:.2f}; {time.strftime('%Y-%m-%d')}.\n",
             "| N | route | ranks | wall (s) | steps | steps/s | E(q) after one script-T | peak MB/rank | "
             "SciPy time / this |", "|---|---|---|---|---|---|---|---|---|"]
    for N in sizes:
        rep = 1 if N >= 10 ** 6 else args.repeats
        common = ["-branch", args.branch, "--N", N]
        sci = best_of(rep, me, ["--worker", "scipy", *common], None, args.scipy_timeout)
        rows = [("SciPy solve_ivp DOP853", 1, sci)]
        for ranks in (1, 2):
            rows.append(("hertzpetsc TS rk 8vr", ranks, best_of(rep, me, ["--worker", "petsc", *common], ranks)))
        for name, ranks, res in rows:
            if res is None:
                lines.append(f"| {N} | {name} | {ranks} | > {args.scipy_timeout} (not finished) | | | | | |")
                continue
            ratio = f"{sci['wall'] / res['wall']:.2f}" if sci else "n/a"
            lines.append(f"| {N} | {name} | {ranks} | {res['wall']:.3f} | {res['steps']} | "
                         f"{res['steps'] / res['wall']:.1f} | {res['E']:.1e} | {max(res['rss_mb']):.0f} | {ratio} |")
        print("\n".join(lines[-3:]), flush=True)
    lines += ["", "One Gauss-Newton refinement at N = 100, q = 3pi/10 (dense Jacobian S R - I from 200 tangent "
              "vectors, tight flow rtol 1e-14):", "",
              "| ranks | wall (s) | Gauss-Newton iterations | Jacobians | E after | peak MB/rank |", "|---|---|---|---|---|---|"]
    for ranks in (1, 2):
        res = best_of(args.repeats, me, ["--worker", "refine", "-branch", args.branch, "--N", 100], ranks)
        lines.append(f"| {ranks} | {res['wall']:.2f} | {res['steps']} | {res['rhs']} | {res['E']:.1e} | "
                     f"{max(res['rss_mb']):.0f} |")
    write_report(args.output, lines)


if __name__ == "__main__":
    sys.exit(main())
