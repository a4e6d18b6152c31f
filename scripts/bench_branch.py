#!/usr/bin/env python3
"""Benchmark: the full branch q = pi -> pi/50 (alpha = 3/2), hertzpetsc on 1 and 2 ranks against a plain SciPy
implementation of the same discretisation (scipy.sparse Newton with spsolve), in the same run.

    python scripts/bench_branch.py [-cells 1000,50000] [-repeats 3] [-direct_repeats 1]
                                   [-output results/bench_branch.md] [-scipy_timeout 600]

hertzpetsc runs both linear-solver paths: -tw_solver direct (LU; MUMPS on 2 ranks) and -tw_solver nk
(Newton-Krylov: GMRES + exact second-difference preconditioner, matrix-free Jacobian), with one OpenBLAS thread
per rank; the SciPy route keeps the library defaults.

Each measurement runs in its own process (hertzpetsc under mpiexec); wall time is that of the branch
computation (imports excluded), best of -repeats; peak memory is each process's maximum resident set size
(per rank for hertzpetsc). Extra arguments after -- go to the hertzpetsc runs (e.g. -- -tw_pc_type lu).
Measure on an otherwise idle machine: two ranks share the machine's two cores.
"""
import argparse
import math
import os
import platform
import sys
import time

from hertzpetsc.benchmarking import best_of, emit


# ---------------------------------------------------------------------------------------------------------
# The SciPy route: what a researcher would write with scipy.sparse, same scheme, predictor and tolerances.
# ---------------------------------------------------------------------------------------------------------
def scipy_branch(alpha, M, K):
    import numpy as np
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from hertzpetsc.binary import binary_oscillation

    h, n = math.pi / K, K - 1
    rows = np.arange(n)
    j = rows + 1

    def shift(offset):                      # odd, 2 pi-periodic folding of u_{j + offset} onto u_1..u_{K-1}
        r = np.mod(j + offset, 2 * K)
        sign = np.where(r < K, 1.0, -1.0)
        sign[(r == 0) | (r == K)] = 0.0
        col = np.where(r < K, r, 2 * K - r) - 1
        keep = sign != 0
        return sp.csr_matrix((sign[keep], (rows[keep], col[keep])), shape=(n, n))

    eye = sp.identity(n, format="csr")
    D2 = (shift(1) - 2 * eye + shift(-1)) / h**2
    dV = lambda x: -np.abs(np.minimum(x, 0)) ** alpha
    d2V = lambda x: alpha * np.abs(np.minimum(x, 0)) ** (alpha - 1)
    e = 2 / (alpha - 1)
    xi = np.arange(K + 1) * h
    u = binary_oscillation(alpha, xi)[1:K]
    hist, newton, out = [], 0, []
    for m in range(M, 0, -1):
        q = m * math.pi / M
        if hist:                            # secant predictor on the rescaled profile q^e u
            (q1, r1) = hist[-1]
            r = r1 if len(hist) == 1 else r1 + (q - q1) / (q1 - hist[0][0]) * (r1 - hist[0][1])
            u = r * q ** (-e)
        s = int(round(q / h))
        Pp, Pm = shift(s), shift(-s)
        atol = 10 * 4 * np.finfo(float).eps * np.max(np.abs(u)) / h**2 * math.sqrt(n)
        for it in range(50):
            dp, dm = Pp @ u - u, u - Pm @ u
            R = D2 @ u - dV(dp) + dV(dm)
            if np.linalg.norm(R) <= atol:
                break
            a, b = d2V(dp), d2V(dm)
            J = D2 + sp.diags(a + b) - sp.diags(a) @ Pp - sp.diags(b) @ Pm
            du = spla.spsolve(J.tocsc(), -R)
            u = u + du
            newton += 1
            if np.linalg.norm(du) <= 1e-12 * np.linalg.norm(u):
                break
        else:
            raise RuntimeError(f"scipy Newton failed at q = {q}")
        hist = (hist + [(q, u * q**e)])[-2:]
        out.append(np.max(np.abs(u)))
    return dict(points=M, newton=newton, norm_inf_last=float(out[-1]))


def hertzpetsc_branch(alpha, M, K):
    from petsc4py import PETSc

    from hertzpetsc.continuation import BranchContinuation, ContinuationParameters
    cont = BranchContinuation(ContinuationParameters(alpha=alpha, M=M, cells_per_pi=K), PETSc.COMM_WORLD)
    newton, krylov, last = 0, 0, None
    for pt in cont.points():
        newton += pt.solve.iterations
        krylov += pt.solve.linear_iterations
        last = pt
    cont.destroy()
    # the grid maximum, as in the SciPy route (the diagnostics' sup norm is parabola-refined)
    return dict(points=M, newton=newton, krylov=krylov, norm_inf_last=float(abs(last.u_half).max()))


def worker(kind, alpha, M, K):
    if kind == "petsc":
        import petsc4py
        petsc4py.init(sys.argv[:1] + [a for a in sys.argv[1:] if a.startswith("-tw_") or not a.startswith("--")])
        from mpi4py import MPI
        comm = MPI.COMM_WORLD
        comm.Barrier()
        t0 = time.perf_counter()
        res = hertzpetsc_branch(alpha, M, K)
        comm.Barrier()
        wall = time.perf_counter() - t0
        emit(comm, wall=wall, **res)
    else:
        t0 = time.perf_counter()
        res = scipy_branch(alpha, M, K)
        wall = time.perf_counter() - t0
        emit(None, wall=wall, **res)


def best(kind, ranks, alpha, M, K, extra, repeats, timeout):
    args = ["--worker", kind, "--alpha", alpha, "--M", M, "--K", K, *extra]
    return best_of(repeats, os.path.abspath(__file__), args, ranks if kind == "petsc" else None, timeout)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-cells", default="1000,50000", help="grids h = pi/K (comma-separated K)")
    ap.add_argument("-repeats", type=int, default=3)
    ap.add_argument("-direct_repeats", type=int, default=1, help="repeats of the (slow) direct path")
    ap.add_argument("-output", default="results/bench_branch.md")
    ap.add_argument("-scipy_timeout", type=int, default=600)
    ap.add_argument("-alpha", type=float, default=1.5)
    ap.add_argument("-M", type=int, default=50)
    ap.add_argument("--worker")
    ap.add_argument("--alpha", dest="walpha", type=float)
    ap.add_argument("--M", dest="wM", type=int)
    ap.add_argument("--K", dest="wK", type=int)
    args, extra = ap.parse_known_args()
    if args.worker:
        return worker(args.worker, args.walpha, args.wM, args.wK)
    extra = [a for a in extra if a != "--"]
    try:
        cells = [int(c) for c in args.cells.split(",")]
    except ValueError:
        print(f"error: invalid -cells = {args.cells!r}: must be a comma-separated list of integers", file=sys.stderr)
        return 2
    if args.repeats < 1:
        print(f"error: invalid -repeats = {args.repeats}: must be >= 1", file=sys.stderr)
        return 2
    load = os.getloadavg()[0]
    lines = [f"Full branch q = pi -> pi/{args.M}, alpha = {args.alpha}: wall time of the computation (best of "
             f"{args.repeats}), peak resident memory per process. Machine: {os.cpu_count()} cores, "
             f"{platform.processor() or platform.machine()}; load average at start {load:.2f}; "
             f"{time.strftime('%Y-%m-%d')}.\n",
             "| h | unknowns | route | ranks | wall (s) | Newton its | Krylov its | peak MB/rank | SciPy / this | "
             "rel. diff of max u(pi/50) vs SciPy |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for K in cells:
        sci = best("scipy", 1, args.alpha, args.M, K, [], 1 if K > 20000 else args.repeats, args.scipy_timeout)
        rows = [("SciPy spsolve", 1, sci)]
        for solver, repeats in (("direct", args.direct_repeats), ("nk", args.repeats)):
            for ranks in (1, 2):
                res = best("petsc", ranks, args.alpha, args.M, K, ["-tw_solver", solver, *extra], repeats, 3600)
                rows.append((f"hertzpetsc {solver}", ranks, res))
        for name, ranks, res in rows:
            if res is None:
                lines.append(f"| pi/{K} | {K - 1} | {name} | {ranks} | > {args.scipy_timeout} (not finished) "
                             "| | | | | |")
                continue
            ratio = f"{sci['wall'] / res['wall']:.2f}" if sci else "n/a"
            diff = abs(res["norm_inf_last"] - sci["norm_inf_last"]) / sci["norm_inf_last"] if sci else float("nan")
            lines.append(f"| pi/{K} | {K - 1} | {name} | {ranks} | {res['wall']:.2f} | {res['newton']} | "
                         f"{res.get('krylov', '')} | {max(res['rss_mb']):.0f} | {ratio} | {diff:.1e} |")
        print("\n".join(lines[-3:]), flush=True)
    lines.append(f"\nload average at the end {os.getloadavg()[0]:.2f}")
    text = "\n".join(lines) + "\n"
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    with open(args.output, "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    sys.exit(main())
