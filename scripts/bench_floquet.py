#!/usr/bin/env python3
"""Benchmark: the 10 dominant Floquet multipliers modulo shifts at q = 9pi/50 on N = 100, 1000, 10^4 beads.

hertzpetsc's routes, 1 and 2 ranks: the Bloch route for long chains (hertzpetsc.bloch: all 2N multipliers from
the L//2 + 1 sectors of the 100-bead cell, then the residuals of the 10 dominant modes on the full chain,
matrix-free), the same followed by SLEPc Krylov-Schur on the full-chain shell started from the Bloch modes, plain
SLEPc Krylov-Schur on the shell (N = 100 only: at N = 1000 it did not converge, > 1100 products), and the dense
route (S R from 2N tangent vectors in one TS, then LAPACK; N = 100 only); against the dense route a SciPy user
would take (assemble the 2N x 2N matrix S R(script-T; 0) column by column with solve_ivp DOP853 on the
variational equations, then numpy.linalg.eigvals), all flows at rtol 1e-12, atol 1e-14.

    python scripts/bench_floquet.py [-sizes 100,1000,10000] [-repeats 1] [-output results/bench_floquet.md]
                                    [-scipy_limit 600] [-slepc_max 1000] [-plain_max 100]

The wave is the refined N = 100 state (results/refined_N100.npz) tiled to N beads. The SciPy route is run when
its projected time (from its first columns) is below -scipy_limit seconds; otherwise the projection is
reported. The seeded SLEPc rows are run for N <= -slepc_max, the plain SLEPc and dense rows for N <= -plain_max.
Run on an idle machine.
"""
import argparse
import math
import os
import platform
import sys
import time

from hertzpetsc.benchmarking import best_of, emit, write_report

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
        if j < 4:                                  # project from the first columns; give up early if hopeless
            projected = (time.perf_counter() - t0) / (j + 1) * 2 * N
            if projected > limit:
                emit(None, wall=None, projected=projected)
                return
    lam = np.linalg.eigvals(F)
    wall = time.perf_counter() - t0
    lam = lam[np.argsort(-np.abs(lam))][:10]
    emit(None, wall=wall, rho=float(abs(lam[0])), products=2 * N)


def bloch_worker(branch_path, refined_path, N, slepc=False):
    """Bloch sectors of the 100-bead cell (dealt to the ranks), then residuals or seeded SLEPc on the N-bead chain."""
    import petsc4py
    petsc4py.init(sys.argv[:1])
    import slepc4py
    slepc4py.init(sys.argv[:1])
    import numpy as np
    from mpi4py import MPI
    from petsc4py import PETSc

    from hertzpetsc.bloch import bloch_multipliers, bloch_residuals, real_pairs, seeded_dominant_multipliers
    from hertzpetsc.chain import ChainParameters, IntegrationTolerances
    x0, T = wave(branch_path, refined_path, N)
    cell, L = x0[:100], N // 100
    comm = MPI.COMM_WORLD
    tol = IntegrationTolerances(RTOL, ATOL)
    full = ChainParameters(1.5, N)
    comm.Barrier()
    t0 = time.perf_counter()
    b = bloch_multipliers(ChainParameters(1.5, 100), cell, T, N, PETSc.COMM_WORLD, tol, n_modes=10)
    if slepc:
        res = seeded_dominant_multipliers(full, x0, T, b, 10, PETSc.COMM_WORLD, tol)
        rho, products, check = float(abs(res.values[0])), res.products, None
    else:
        r, products = bloch_residuals(full, x0, T, real_pairs(b.modes, L), PETSc.COMM_WORLD, tol)
        rho, check = float(abs(b.values[0])), float(np.max(r))
    wall = time.perf_counter() - t0
    emit(comm, wall=wall, rho=rho, products=products, runs=b.runs, columns=b.columns, residual=check)


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
    ap.add_argument("-sizes", default="100,1000,10000")
    ap.add_argument("-slepc_max", type=int, default=1000)
    ap.add_argument("-plain_max", type=int, default=100)
    ap.add_argument("-repeats", type=int, default=1)
    ap.add_argument("-output", default="results/bench_floquet.md")
    ap.add_argument("-scipy_limit", type=float, default=600.0)
    ap.add_argument("--worker")
    ap.add_argument("--N", type=int)
    args = ap.parse_args()
    if args.worker == "scipy":
        return scipy_worker(args.branch, args.refined, args.N, args.scipy_limit)
    if args.worker in ("bloch", "bloch_slepc"):
        return bloch_worker(args.branch, args.refined, args.N, slepc=args.worker == "bloch_slepc")
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
    uptime = " ".join(f"{v:.2f}" for v in os.getloadavg())
    lines = [f"10 dominant multipliers of F_q, q = 9pi/50, rtol {RTOL:g}; best of {args.repeats}. Machine: "
             f"{os.cpu_count()} cores, {platform.machine()}; load average (1, 5, 15 min) at start {uptime}; "
             f"{time.strftime('%Y-%m-%d')}. Bloch: L//2 + 1 sector runs of the 100-bead cell (200 complex tangent "
             "columns each), then on the full chain either the residuals of the dominant modes (products = shell "
             "products, max relative residual in brackets) or seeded SLEPc (products = shell products).\n",
             "| N | route | ranks | wall (s) | operator products (columns) | rho(F_q) | peak MB/rank | SciPy / this |",
             "|---|---|---|---|---|---|---|---|"]
    for N in sizes:
        common = ["-branch", args.branch, "-refined", args.refined, "--N", N]
        sci = best_of(1, me, ["--worker", "scipy", "-scipy_limit", args.scipy_limit, *common], None, 3600)
        rows = [("SciPy dense (solve_ivp columns + eigvals)", 1, sci)]
        workers = [("bloch", "hertzpetsc Bloch sectors + full-chain residuals")]
        if N <= args.slepc_max:
            workers.append(("bloch_slepc", "hertzpetsc Bloch sectors + seeded SLEPc shell"))
        if N <= args.plain_max:
            workers += [("petsc", "hertzpetsc SLEPc shell (plain)"), ("petsc_dense", "hertzpetsc dense (2N tangents)")]
        for worker, name in workers:
            for ranks in (1, 2):
                rows.append((name, ranks, best_of(args.repeats, me, ["--worker", worker, *common], ranks)))
        for name, ranks, res in rows:
            if res is None:
                lines.append(f"| {N} | {name} | {ranks} | timed out | | | | |")
                continue
            if res.get("wall") is None:
                lines.append(f"| {N} | {name} | {ranks} | not run: projected {res['projected']:.0f} s > "
                             f"{args.scipy_limit:.0f} s | {2 * N} | | | |")
                continue
            ratio = f"{sci['wall'] / res['wall']:.2f}" if sci and sci.get("wall") else "n/a"
            prod = str(res["products"])
            if res.get("runs"):
                prod = f"{res['runs']} x {res['columns'] // res['runs']} + {res['products']}"
                if res.get("residual") is not None:
                    prod += f" (residual {res['residual']:.0e})"
            lines.append(f"| {N} | {name} | {ranks} | {res['wall']:.1f} | {prod} | {res['rho']:.6f} | "
                         f"{max(res['rss_mb']):.0f} | {ratio} |")
        print("\n".join(lines[-len(rows):]), flush=True)
    lines.append(f"\nNot run above -plain_max = {args.plain_max}: plain Krylov-Schur on the shell (at N = 1000, "
                 "0.5 s per product, it converged nothing: nev 4, tol 1e-8, ncv 80 after > 1100 products; nev 1, tol "
                 "1e-6 after 25 min; about 600 unstable multipliers crowd annuli of nearly equal moduli) and the dense "
                 "2N-tangent TS (state of (4N + 2) N doubles: 32 MB per vector at N = 1000, 3.2 GB at N = 10^4). "
                 f"Seeded SLEPc not run above -slepc_max = {args.slepc_max} (about 50-120 shell products).")
    write_report(args.output, lines)


if __name__ == "__main__":
    sys.exit(main())
