#!/usr/bin/env python3
"""Benchmark: the 10 dominant Floquet multipliers modulo shifts at q = 9pi/50 on N = 100, 1000, 10^4 beads.

hertzpetsc's routes, 1 and 2 ranks: the Bloch route for long chains (hertzpetsc.bloch: all 2N multipliers from
the g//2 + 1 Bloch sectors of the wave's cell of N/g beads, g = gcd(m, N), each over the wave's shortest time
symmetry script-T/m' (hertzpetsc.symmetry), then the residuals of the 10 dominant modes on the full chain,
matrix-free, all shell products in one integration of the orbit), the same followed by SLEPc Krylov-Schur on the full-chain shell started from the Bloch modes, plain
SLEPc Krylov-Schur on the shell (N = 100 only: at N = 1000 it did not converge, > 1100 products), and the dense
route (S R from 2N tangent vectors in one TS, then LAPACK; N = 100 only); against the dense route a SciPy user
would take (assemble the 2N x 2N matrix S R(script-T; 0) column by column with solve_ivp DOP853 on the
variational equations, then numpy.linalg.eigvals), all flows at rtol 1e-12, atol 1e-14.

    python scripts/bench_floquet.py [-sizes 100,1000,10000] [-repeats 1] [-output runs/bench_floquet.md]
                                    [-scipy_limit 600] [-slepc_max 1000] [-plain_max 100] [-records FILE]

The wave is the refined N = 100 state (results/refined_N100.npz) tiled to N beads. The SciPy route is run when
its projected time (from its first columns) is below -scipy_limit seconds; otherwise the projection is
reported. The seeded SLEPc rows are run for N <= -slepc_max, the plain SLEPc and dense rows for N <= -plain_max.
Run on an idle machine.
"""
import math
import os
import sys
import time

from benchlib import BenchRecords, best_of, declare_chains, declare_common, emit, machine, main_or_worker, write_report

Q = 9 * math.pi / 50
RTOL, ATOL = 1e-12, 1e-14


def cell_orbit(branch_path, refined_path):
    """The refined 100-bead wave at q = 9pi/50."""
    from hertzpetsc.branch import Branch
    from hertzpetsc.studies.refinement import RefinedStates
    return RefinedStates.load(refined_path).orbit(Branch.load(branch_path).point(Q))


def scipy_worker(branch_path, refined_path, N, limit):
    import numpy as np
    from scipy.integrate import solve_ivp
    w = cell_orbit(branch_path, refined_path).tiled(N // 100)
    x0, T = w.x, w.T
    alpha = 1.5

    def f(t, z):
        x, v, y, u = z[:N], z[N:2 * N], z[2 * N:3 * N], z[3 * N:]
        r = np.roll(x, -1) - x
        b = -np.abs(np.minimum(r, 0.0)) ** alpha
        k = alpha * np.abs(np.minimum(r, 0.0)) ** (alpha - 1)
        dy = np.roll(y, -1) - y
        kd = k * dy
        return np.concatenate([v, b - np.roll(b, 1), u, kd - np.roll(kd, 1)])

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


def petsc_worker(name, branch_path, refined_path, N, petsc_args):
    import petsc4py
    petsc4py.init(sys.argv[:1] + petsc_args)
    import slepc4py
    slepc4py.init(sys.argv[:1] + petsc_args)
    import numpy as np
    from mpi4py import MPI
    from petsc4py import PETSc

    from hertzpetsc.bloch import bloch_residuals, real_pairs, seeded_dominant_multipliers
    from hertzpetsc.chain import IntegrationTolerances
    from hertzpetsc.bloch import SymmetricFloquet
    from hertzpetsc.floquet import DenseFloquet, DominantFloquet
    cell = cell_orbit(branch_path, refined_path)
    L = N // 100
    full = cell.tiled(L)
    comm = MPI.COMM_WORLD
    tol = IntegrationTolerances(RTOL, ATOL)
    out = {}
    comm.Barrier()
    t0 = time.perf_counter()
    if name in ("bloch", "bloch_slepc"):
        with SymmetricFloquet(cell.spec.model, PETSc.COMM_WORLD, tol, n_modes=10) as fast:
            b = fast.spectrum(full)
        if name == "bloch_slepc":
            res = seeded_dominant_multipliers(full, b, 10, PETSc.COMM_WORLD, tol)
            out = dict(rho=float(abs(res.multipliers[0])), products=res.work["products"], residual=None)
        else:
            r, products = bloch_residuals(full, real_pairs(b.modes, b.L), PETSc.COMM_WORLD, tol)
            out = dict(rho=float(abs(b.multipliers[0])), products=products, residual=float(np.max(r)))
        out.update(runs=b.work["runs"], columns=b.work["columns"], propagated=b.work["propagated"])
    elif name == "petsc_dense":
        with DenseFloquet(full.spec, PETSc.COMM_WORLD, tol) as dense:
            out = dict(rho=dense.spectrum(full).rho, products=2 * N)
    else:
        with DominantFloquet(full.spec, PETSc.COMM_WORLD, 10, tol) as dominant:
            res = dominant.spectrum(full)
        out = dict(rho=float(abs(res.multipliers[0])), products=res.work["products"])
    emit(comm, wall=time.perf_counter() - t0, **out)


def worker(name, req, petsc_args):
    if name == "scipy":
        scipy_worker(req["branch"], req["refined"], req["N"], req["limit"])
    else:
        petsc_worker(name, req["branch"], req["refined"], req["N"], petsc_args)


def main():
    from hertzpetsc.options import AppOptions
    opts = AppOptions(__doc__)
    branch, sizes = declare_chains(opts, "100,1000,10000", 100, "the refined wave is tiled")
    refined = opts.path("refined", "results/refined_N100.npz", "refinement file (N = 100)")
    slepc_max = opts.integer("slepc_max", 1000, "largest N of the seeded SLEPc rows", minimum=0)
    plain_max = opts.integer("plain_max", 100, "largest N of the plain SLEPc and dense rows", minimum=0)
    scipy_limit = opts.real("scipy_limit", 600.0, "SciPy runs projected longer than this are not run (s)",
                            valid=(lambda x: x > 0, "> 0"))
    output, repeats, records_path, mode = declare_common(opts, "runs/bench_floquet.md", repeats=1)
    opts.done()
    cell_orbit(branch, refined)                              # the workers' input, checked before any worker runs
    opts.check_unused()
    me = os.path.abspath(__file__)
    rec = BenchRecords(records_path, "hertzpetsc-bench-floquet-1", dict(branch=branch, refined=refined), mode)
    lines = [f"10 dominant multipliers of F_q, q = 9pi/50, rtol {RTOL:g}; {machine(repeats)}. Bloch: g//2 + 1 "
             "sector runs of the wave's cell (g = gcd(m, N) = N/100 here: 200 complex tangent columns each, over "
             "script-T/9, the wave's time symmetry), or, where two or more sectors are complex, every sector from "
             "one run of the cell's 200 real columns on three cells (the cell propagator, hertzpetsc.tangent), then "
             "on the full chain either the residuals of the dominant "
             "modes (products = shell products over script-T, all in one integration, max relative residual in "
             "brackets) or seeded SLEPc "
             "(products = shell products).\n",
             "| N | route | ranks | wall (s) | operator products (columns) | rho(F_q) | peak MB/rank | SciPy / this |",
             "|---|---|---|---|---|---|---|---|"]
    for N in sizes:
        req = dict(branch=branch, refined=refined, N=N, limit=scipy_limit)
        sci = rec.measure(f"{N} scipy", lambda: best_of(1, me, "scipy", req, None, 3600))
        rows = [("SciPy dense (solve_ivp columns + eigvals)", 1, sci)]
        workers = [("bloch", "hertzpetsc Bloch sectors + full-chain residuals")]
        if N <= slepc_max:
            workers.append(("bloch_slepc", "hertzpetsc Bloch sectors + seeded SLEPc shell"))
        if N <= plain_max:
            workers += [("petsc", "hertzpetsc SLEPc shell (plain)"), ("petsc_dense", "hertzpetsc dense (2N tangents)")]
        for name, label in workers:
            for ranks in (1, 2):
                rows.append((label, ranks, rec.measure(f"{N} {name} {ranks}",
                                                       lambda: best_of(repeats, me, name, req, ranks))))
        for label, ranks, res in rows:
            if res is None:
                lines.append(f"| {N} | {label} | {ranks} | timed out | | | | |")
                continue
            if res.get("wall") is None:
                lines.append(f"| {N} | {label} | {ranks} | not run: projected {res['projected']:.0f} s > "
                             f"{scipy_limit:.0f} s | {2 * N} | | | |")
                continue
            ratio = f"{sci['wall'] / res['wall']:.2f}" if sci and sci.get("wall") else "n/a"
            prod = str(res["products"])
            if res.get("runs"):
                prod = f"{res['runs']} x {res['columns'] // res['runs']} + {res['products']}"
                if res.get("propagated"):
                    prod = f"{res['runs']} sectors from 1 x 200 on 3 cells + {res['products']}"
                if res.get("residual") is not None:
                    prod += f" (residual {res['residual']:.0e})"
            lines.append(f"| {N} | {label} | {ranks} | {res['wall']:.1f} | {prod} | {res['rho']:.6f} | "
                         f"{max(res['rss_mb']):.0f} | {ratio} |")
        print("\n".join(lines[-len(rows):]), flush=True)
    lines.append(f"\nNot run above -plain_max = {plain_max}: plain Krylov-Schur on the shell (at N = 1000, "
                 "0.5 s per product, it converged nothing: nev 4, tol 1e-8, ncv 80 after > 1100 products; nev 1, tol "
                 "1e-6 after 25 min; about 600 unstable multipliers crowd annuli of nearly equal moduli) and the dense "
                 "2N-tangent TS (state of (4N + 2) N doubles: 32 MB per vector at N = 1000, 3.2 GB at N = 10^4). "
                 f"Seeded SLEPc not run above -slepc_max = {slepc_max} (about 50-120 shell products).")
    write_report(output, lines)


if __name__ == "__main__":
    main_or_worker(main, worker)
