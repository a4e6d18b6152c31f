#!/usr/bin/env python3
"""Benchmark: the full branch q = pi -> pi/M (alpha = 3/2, M = 50), hertzpetsc on 1 and 2 ranks against a plain SciPy
implementation of the same discretisation (scipy.sparse Newton with spsolve), in the same run.

    python scripts/bench_branch.py [-cells 1000,50000] [-M 50] [-repeats 3] [-direct_repeats 1] [-previous DIR]
                                   [-output runs/bench_branch.md] [-scipy_timeout 600] [-tw_... options]

hertzpetsc runs both linear-solver paths: -tw_solver direct (LU; MUMPS on 2 ranks) and -tw_solver nk
(Newton-Krylov: GMRES + exact second-difference preconditioner, matrix-free Jacobian), with one OpenBLAS thread
per rank, the SciPy route too (unless OPENBLAS_NUM_THREADS is set). Each measurement runs in its own process
(hertzpetsc under mpiexec); wall time is that of the branch computation (imports excluded), best of -repeats;
peak memory is each process's maximum resident set size (per rank for hertzpetsc). Other -tw_* options go to the
hertzpetsc runs (e.g. -tw_pc_type lu). -records FILE keeps the measurements as they are taken (-resume continues).
-previous DIR: also run the same branch with the hertzpetsc of another checkout (e.g. the previous release:
``git worktree add DIR <commit>``) in the same run, for the side-by-side gate of a change of the solver stack.
The last column compares max u at q = pi/M with the SciPy route's; beyond 1e-8 (AGREE) the row is marked (!) and a
note says that the routes converged to different solutions.
Measure on an otherwise idle machine: two ranks share the machine's two cores.
"""
import math
import os
import sys
import time

from benchlib import BenchRecords, best_of, declare_common, emit, machine, main_or_worker, write_report

# Both routes stop Newton near round-off (SciPy: step <= 1e-12 ||u||), so on the same grid their max u at the last q
# agrees to far below this; beyond it they converged to different solutions, which the table says.
AGREE = 1e-8


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


def worker(name, req, petsc_args):
    # the routes' modules are imported before the clock starts (imports excluded: a package's import time, which
    # grows with its size, is no part of the branch computation)
    if name == "petsc":
        import petsc4py
        petsc4py.init(sys.argv[:1] + petsc_args)
        from mpi4py import MPI

        from hertzpetsc.continuation import BranchContinuation, ContinuationParameters  # noqa: F401
        comm = MPI.COMM_WORLD
        comm.Barrier()
        t0 = time.perf_counter()
        res = hertzpetsc_branch(req["alpha"], req["M"], req["K"])
        comm.Barrier()
        emit(comm, wall=time.perf_counter() - t0, **res)
    else:
        import scipy.sparse.linalg  # noqa: F401

        from hertzpetsc.binary import binary_oscillation  # noqa: F401
        t0 = time.perf_counter()
        res = scipy_branch(req["alpha"], req["M"], req["K"])
        emit(None, wall=time.perf_counter() - t0, **res)


def main():
    from petsc4py import PETSc

    from hertzpetsc.options import AppOptions
    opts = AppOptions(__doc__, {"tw_": ("the hertzpetsc runs' travelling-wave SNES (passed on)", ("snes",))})
    cells = opts.numbers("cells", "1000,50000", "grids h = pi/K", expr=False, kind=int, valid=(lambda K: K >= 4,
                         ">= 4"), distinct=True)
    direct_repeats = opts.integer("direct_repeats", 1, "repeats of the (slow) direct path", minimum=1)
    scipy_timeout = opts.integer("scipy_timeout", 600, "seconds before a SciPy run is given up", minimum=1)
    alpha = opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda a: a > 1, "> 1"))
    M = opts.integer("M", 50, "targets q = m pi / M", minimum=1)
    previous = opts.path("previous", "", "a checkout of another release, measured side by side (none if empty)")
    output, repeats, records_path, mode = declare_common(opts, "runs/bench_branch.md")
    opts.done()
    from hertzpetsc.resources import check_memory
    for K in cells:                          # refused before any worker is started
        check_memory(K, PETSc.COMM_WORLD, name="cells")
    if previous and not os.path.isfile(os.path.join(previous, "hertzpetsc", "__init__.py")):
        from hertzpetsc.errors import ParameterError
        raise ParameterError("-previous", previous, "must be a checkout holding hertzpetsc/ (e.g. a git worktree)")
    extra = [w for k, v in PETSc.Options().getAll().items() if k.startswith("tw_")
             for w in ([f"-{k}"] + ([v] if v not in (None, "") else []))]
    opts.check_unused(passed_on=("tw_",))
    me = os.path.abspath(__file__)
    rec = BenchRecords(records_path, "hertzpetsc-bench-branch-1", dict(alpha=alpha, M=M, extra=extra,
                                                                       **({"previous": previous} if previous else {})),
                       mode)
    lines = [f"Full branch q = pi -> pi/{M}, alpha = {alpha}: wall time of the computation, peak resident memory "
             f"per process; {machine(repeats)}.\n",
             "| h | unknowns | route | ranks | wall (s) | Newton its | Krylov its | peak MB/rank | SciPy / this | "
             f"rel. diff of max u(pi/{M}) vs SciPy |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    disagree = []
    for K in cells:
        req = dict(alpha=alpha, M=M, K=K)
        sci = rec.measure(f"{K} scipy", lambda: best_of(1 if K > 20000 else repeats, me, "scipy", req, None,
                                                        scipy_timeout))
        rows = [("SciPy spsolve", 1, sci)]
        for solver, reps in (("direct", direct_repeats), ("nk", repeats)):
            for ranks in (1, 2):
                res = rec.measure(f"{K} {solver} {ranks}", lambda: best_of(reps, me, "petsc", req, ranks, 3600,
                                                                           ["-tw_solver", solver, *extra]))
                rows.append((f"hertzpetsc {solver}", ranks, res))
                if previous:
                    res = rec.measure(f"{K} {solver} {ranks} previous",
                                      lambda: best_of(reps, me, "petsc", req, ranks, 3600,
                                                      ["-tw_solver", solver, *extra], package=previous))
                    rows.append((f"previous release {solver}", ranks, res))
        for name, ranks, res in rows:
            if res is None:
                lines.append(f"| pi/{K} | {K - 1} | {name} | {ranks} | > {scipy_timeout} (not finished) | | | | | |")
                continue
            ratio = f"{sci['wall'] / res['wall']:.2f}" if sci else "n/a"
            diff = abs(res["norm_inf_last"] - sci["norm_inf_last"]) / sci["norm_inf_last"] if sci else float("nan")
            mark = " (!)" if diff > AGREE else ""
            if mark:
                disagree.append(f"pi/{K} {name} on {ranks} rank(s)")
            lines.append(f"| pi/{K} | {K - 1} | {name} | {ranks} | {res['wall']:.2f} | {res['newton']} | "
                         f"{res.get('krylov', '')} | {max(res['rss_mb']):.0f} | {ratio} | {diff:.1e}{mark} |")
        print("\n".join(lines[-len(rows):]), flush=True)
    if disagree:
        lines.append(f"\n(!) max u(pi/{M}) differs from SciPy's by more than {AGREE:g} ({'; '.join(disagree)}): "
                     "the routes converged to different solutions (large q steps: small -M), so their "
                     "times do not compare the same computation.")
    lines.append(f"\nload average at the end {os.getloadavg()[0]:.2f}")
    write_report(output, lines)


if __name__ == "__main__":
    main_or_worker(main, worker)
