#!/usr/bin/env python3
"""Benchmark: the 10 dominant Floquet multipliers modulo shifts at q = 9pi/50, hertzpetsc's matrix-free route
(SLEPc Krylov-Schur on the shell operator, 1 and 2 ranks) and its dense route (S R assembled from 2N tangent
vectors integrated in one TS, then LAPACK) against the dense route a SciPy user would take
(assemble the 2N x 2N matrix S R(script-T; 0) column by column with solve_ivp DOP853 on the variational
equations, then numpy.linalg.eigvals), both flows at rtol 1e-12, atol 1e-14.

    python scripts/bench_floquet.py [-sizes 100] [-repeats 1] [-output results/bench_floquet.md]
                                    [-scipy_limit 600]

The wave is the refined N = 100 state (results/refined_N100.npz) tiled to N beads. The SciPy route is run when
its projected time (from its first 4 columns) is below -scipy_limit seconds; otherwise the projection is
reported. Run on an idle machine. The default stops at N = 100: for N = 1000 the matrix-free Krylov-Schur does
not converge in reasonable time yet (see the README).
"""
import argparse
import math
import os
import platform
import sys
import time

from hertzpetsc.benchmarking import best_of, emit

Q = 9 * math.pi / 50
RTOL, ATOL = 1e-12, 1e-14


def wave(branch_path, refined_path, N):
    """The refined 100-bead wave at q = 9pi/50 tiled to N beads, and script-T."""
    import numpy as np

    from hertzpetsc.branchfile import read_branch, refined_state
    from hertzpetsc.waves import wave_on_chain
    w = wave_on_chain(read_branch(branch_path), Q, N)
    x = refined_state(refined_path, w.q, 100)
    return np.tile(x, (N // 100, 1)), w.T


def scipy_worker(branch_path, refined_path, N, limit):
    import numpy as np
    from scipy.integrate import solve_ivp
    x0, T = wave(branch_path, refined_path, N)
    alpha = 1.5

    def f(t, z):
        x, v, y, w = z[:N], z[N:2 * N], z[2 * N:3 * N], z[3 * N:]
        r = np.roll(x, -1) - x
        b = -np.abs(np.minimum(r, 0.0)) ** alpha
        k = alpha * np.abs(np.minimum(r, 0.0)) ** (alpha - 1)
        dy = np.roll(y, -1) - y
        kd = k * dy
        return np.concatenate([v, b - np.roll(b, 1), w, kd - np.roll(kd, 1)])

    state0 = np.concatenate([x0[:, 0], x0[:, 1]])
    F = np.zeros((2 * N, 2 * N))
    t0 = time.perf_counter()
    for j in range(2 * N):
        e = np.zeros(2 * N)
        e[(j % 2) * N + j // 2] = 1.0              # unit vector on (x_n or v_n), bead-major column order
        sol = solve_ivp(f, (0, T), np.concatenate([state0, e]), method="DOP853", rtol=RTOL, atol=ATOL)
        yT = sol.y[2 * N:, -1]
        F[:, j] = np.stack([np.roll(yT[:N], -1), np.roll(yT[N:], -1)], axis=1).ravel()
        if j == 3:
            projected = (time.perf_counter() - t0) / 4 * 2 * N
            if projected > limit:
                emit(None, wall=None, projected=projected)
                return
    lam = np.linalg.eigvals(F)
    wall = time.perf_counter() - t0
    lam = lam[np.argsort(-np.abs(lam))][:10]
    emit(None, wall=wall, rho=float(abs(lam[0])), products=2 * N)


def petsc_worker(branch_path, refined_path, N, dense=False):
    import petsc4py
    petsc4py.init(sys.argv[:1])
    import slepc4py
    slepc4py.init(sys.argv[:1])
    from mpi4py import MPI
    from petsc4py import PETSc

    from hertzpetsc.chain import ChainParameters, IntegrationTolerances
    from hertzpetsc.floquet import dominant_multipliers
    x0, T = wave(branch_path, refined_path, N)
    comm = MPI.COMM_WORLD
    params, tol = ChainParameters(1.5, N), IntegrationTolerances(RTOL, ATOL)
    comm.Barrier()
    t0 = time.perf_counter()
    if dense:
        from hertzpetsc.floquet import dense_monodromy, dense_multipliers, spectral_radius
        rho, products = spectral_radius(dense_multipliers(dense_monodromy(params, x0, T, PETSc.COMM_WORLD, tol))), 2 * N
    else:
        res = dominant_multipliers(params, x0, T, 10, PETSc.COMM_WORLD, tol)
        rho, products = float(abs(res.values[0])), res.products
    wall = time.perf_counter() - t0
    emit(comm, wall=wall, rho=rho, products=products)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-branch", default="results/branch_alpha1.5.npz")
    ap.add_argument("-refined", default="results/refined_N100.npz")
    ap.add_argument("-sizes", default="100")
    ap.add_argument("-repeats", type=int, default=1)
    ap.add_argument("-output", default="results/bench_floquet.md")
    ap.add_argument("-scipy_limit", type=float, default=600.0)
    ap.add_argument("--worker")
    ap.add_argument("--N", type=int)
    args = ap.parse_args()
    if args.worker == "scipy":
        return scipy_worker(args.branch, args.refined, args.N, args.scipy_limit)
    if args.worker in ("petsc", "petsc_dense"):
        return petsc_worker(args.branch, args.refined, args.N, dense=args.worker == "petsc_dense")
    try:
        sizes = [int(s) for s in args.sizes.split(",")]
    except ValueError:
        sizes = []
    if not sizes or any(N < 100 or N % 100 for N in sizes) or args.repeats < 1:
        print(f"error: invalid -sizes {args.sizes!r} / -repeats {args.repeats}: sizes must be multiples of 100 "
              "(the refined 100-bead wave is tiled), repeats >= 1", file=sys.stderr)
        return 2
    me = os.path.abspath(__file__)
    lines = [f"10 dominant multipliers of F_q, q = 9pi/50, rtol {RTOL:g}; best of {args.repeats}. Machine: "
             f"{os.cpu_count()} cores, {platform.machine()}; load average at start {os.getloadavg()[0]:.2f}; "
             f"{time.strftime('%Y-%m-%d')}.\n",
             "| N | route | ranks | wall (s) | operator products (columns) | rho(F_q) | peak MB/rank | SciPy / this |",
             "|---|---|---|---|---|---|---|---|"]
    for N in sizes:
        common = ["-branch", args.branch, "-refined", args.refined, "--N", N]
        sci = best_of(1, me, ["--worker", "scipy", "-scipy_limit", args.scipy_limit, *common], None, 3600)
        rows = [("SciPy dense (solve_ivp columns + eigvals)", 1, sci)]
        for worker, name in (("petsc", "hertzpetsc SLEPc shell"), ("petsc_dense", "hertzpetsc dense (2N tangents)")):
            for ranks in (1, 2):
                rows.append((name, ranks, best_of(args.repeats, me, ["--worker", worker, *common], ranks)))
        for name, ranks, res in rows:
            if res.get("wall") is None:
                lines.append(f"| {N} | {name} | {ranks} | not run: projected {res['projected']:.0f} s > "
                             f"{args.scipy_limit:.0f} s | {2 * N} | | | |")
                continue
            ratio = f"{sci['wall'] / res['wall']:.2f}" if sci and sci.get("wall") else "n/a"
            lines.append(f"| {N} | {name} | {ranks} | {res['wall']:.1f} | {res['products']} | {res['rho']:.6f} | "
                         f"{max(res['rss_mb']):.0f} | {ratio} |")
        print("\n".join(lines[-3:]), flush=True)
    text = "\n".join(lines) + "\n"
    with open(args.output, "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    sys.exit(main())
