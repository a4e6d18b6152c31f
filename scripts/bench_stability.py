#!/usr/bin/env python3
"""Benchmark: the full stability scan of sections 3.4-3.5 (Gauss-Newton refinement to E <= 1e-10, then all 2N
Floquet multipliers modulo shifts) at every branch q = 2 pi m / N of the N = 100 chain, in one run:

* the SciPy route a researcher would write: solve_ivp DOP853 on the state and all 2N tangent columns as one
  vectorised system, Gauss-Newton steps by numpy.linalg.lstsq, a fresh F_q at the refined state, numpy eigvals;
* hertzpetsc's default routes (refine_branch.py -method symmetric, then floquet_scan.py -method symmetric: each
  wave on its cell of N/gcd(m,N) beads over its shortest time symmetry, the q dealt to the ranks), 1 and 2 ranks;
* hertzpetsc's paper routes (-method full, then -method dense: the whole chain over script-T), 1 and 2 ranks;
* hertzpetsc's symmetric routes with the numpy right-hand side instead of the compiled one (-<prefix>rhs_compiled 0
  for every flow: the same arithmetic, so the same numbers), 1 rank: what the compiled kernel gains.

    python scripts/bench_stability.py [-N 100] [-routes scipy,symmetric,paper,numpy] [-repeats 1]
                                      [-output runs/bench_stability.md] [-records FILE [-resume]]

Every route starts from the same branch waves (results/branch_alpha1.5.npz interpolated onto the chain) and
stops at the same target E <= -tol. hertzpetsc runs the studies the two drivers run (RefinementScan, then
FloquetScan on its refined states, both writing their record files), with one OpenBLAS thread per rank; the SciPy
route runs in one process with one BLAS thread. Wall times exclude imports; the table also gives, against the
SciPy route, the largest difference of rho(F_q) over the unstable q, and each route's largest E. Measure on an
otherwise idle machine: two ranks share the two cores.
"""
import json
import math
import os
import sys
import tempfile
import time

from benchlib import BenchRecords, best_of, declare_common, emit, machine, main_or_worker, write_report

RTOL_SCIPY, ATOL_SCIPY = 2.3e-14, 1e-16      # DOP853's tightest rtol (100 eps) against hertzpetsc's rtol 1e-14
ROUTES = ("scipy", "symmetric", "paper", "numpy")
# the flows of the scan (refinement, its Jacobian, Floquet sectors, E with the paper's flow): the numpy route's options
NUMPY_RHS = [arg for prefix in ("shoot_", "shoot_jac_", "floquet_", "chain_") for arg in (f"-{prefix}rhs_compiled", "0")]


def initial_waves(branch_path, N, path):
    """The branch waves at every q = 2 pi m / N of the branch, interpolated onto N beads (written to ``path``)."""
    import numpy as np
    from petsc4py import PETSc

    from hertzpetsc.branch import Branch
    from hertzpetsc.model import ChainSpec
    from hertzpetsc.studies.refinement import scan_wavenumbers
    from hertzpetsc.waves import orbit_on_chain
    branch = Branch.load(branch_path, PETSc.COMM_SELF)
    spec = ChainSpec(branch.model, N)
    orbits = [orbit_on_chain(branch.point(q), spec) for q in scan_wavenumbers(branch, N)]
    np.savez(path, q=[o.q for o in orbits], T=[o.T for o in orbits], x=np.array([o.x for o in orbits]),
             alpha=branch.alpha)
    return len(orbits)


def scipy_scan(waves_path, tol):
    """The SciPy route on every wave of ``waves_path``: (per-q records, refinement seconds, Floquet seconds)."""
    import numpy as np
    from scipy.integrate import solve_ivp
    data = np.load(waves_path)
    alpha = float(data["alpha"])
    N = data["x"].shape[1]
    eye = np.eye(2 * N)

    def f(t, z):
        x, v = z[:N], z[N:2 * N]
        Y = z[2 * N:].reshape(2 * N, 2 * N)            # rows: (x_n) then (v_n); columns: the tangents
        r = np.roll(x, -1) - x
        c = np.minimum(r, 0.0)
        b = -np.abs(c) ** alpha                         # V'(r) on the bonds n -> n + 1
        s = alpha * np.abs(c) ** (alpha - 1)            # V''(r)
        ks = s[:, None] * (np.roll(Y[:N], -1, axis=0) - Y[:N])
        return np.concatenate([v, b - np.roll(b, 1), Y[N:].ravel(), (ks - np.roll(ks, 1, axis=0)).ravel()])

    def f_state(z):
        x, v = z[:N], z[N:]
        b = -np.abs(np.minimum(np.roll(x, -1) - x, 0.0)) ** alpha
        return np.concatenate([v, b - np.roll(b, 1)])

    def shifted_flow(x0, T):
        """(S X(T), S R(T; 0)) from one integration of the state and the 2N unit tangents."""
        z0 = np.concatenate([x0[:, 0], x0[:, 1], eye.ravel()])
        zT = solve_ivp(f, (0.0, T), z0, method="DOP853", rtol=RTOL_SCIPY, atol=ATOL_SCIPY).y[:, -1]
        xT, R = zT[:2 * N], zT[2 * N:].reshape(2 * N, 2 * N)
        S = np.roll(np.arange(N), -1)
        idx = np.concatenate([S, N + S])
        return xT[idx], R[idx]

    records, t_refine, t_floquet = [], 0.0, 0.0
    for q, T, x in zip(data["q"], data["T"], data["x"]):
        t0 = time.perf_counter()
        z = np.concatenate([x[:, 0], x[:, 1]])
        its = 0
        while True:
            sz, F = shifted_flow(np.stack([z[:N], z[N:]], axis=1), T)
            g = sz - z
            E = np.max(np.abs(g)) / np.max(np.abs(z))
            if E <= tol or its >= 20:
                break
            # Gauss-Newton with the paper's two phase conditions (no step along the translation x_n -> x_n + c
            # nor along the flow f(z)): F - I is singular in those two directions.
            phase = np.stack([np.r_[np.ones(N), np.zeros(N)] / math.sqrt(N), f_state(z)])
            phase[1] /= np.linalg.norm(phase[1])
            z = z + np.linalg.lstsq(np.vstack([F - eye, phase]), np.r_[-g, 0.0, 0.0], rcond=None)[0]
            its += 1
        t1 = time.perf_counter()
        lam = np.linalg.eigvals(F)                     # F_q at the refined state (its last integration)
        t2 = time.perf_counter()
        t_refine += t1 - t0
        t_floquet += t2 - t1
        records.append(dict(q=float(q), E=float(E), its=its, multipliers=lam))
    return records, t_refine, t_floquet


def scipy_worker(req):
    t0 = time.perf_counter()
    records, t_refine, t_floquet = scipy_scan(req["waves"], req["tol"])
    wall = time.perf_counter() - t0
    emit(None, wall=wall, refine=t_refine, floquet=t_floquet, E_max=max(r["E"] for r in records),
         multipliers={f"{r['q']:.12f}": [[z.real, z.imag] for z in r["multipliers"]] for r in records},
         iterations=sum(r["its"] for r in records),
         unconverged=[[r["q"], r["E"], r["its"]] for r in records if r["E"] > req["tol"]])


def petsc_worker(name, req, petsc_args):
    import petsc4py
    petsc4py.init(sys.argv[:1] + petsc_args)
    from mpi4py import MPI
    from petsc4py import PETSc

    from hertzpetsc.branch import Branch
    from hertzpetsc.studies.floquet import FloquetScan
    from hertzpetsc.studies.refinement import RefinedStates, RefinementScan
    comm = PETSc.COMM_WORLD
    work = comm.tompi4py().bcast(tempfile.mkdtemp(prefix="bench_stability_") if comm.getRank() == 0 else None)
    N, tol = req["N"], req["tol"]
    comm.tompi4py().Barrier()
    t0 = time.perf_counter()
    branch = Branch.load(req["branch"], comm)
    symmetric = name in ("symmetric", "numpy")
    refinement = RefinementScan(branch, req["branch"], N, comm, f"{work}/refined.npz", "force", tol=tol,
                                symmetric=symmetric)
    refined = list(refinement.run())
    comm.tompi4py().Barrier()
    t1 = time.perf_counter()
    scan = FloquetScan(branch, N, comm, f"{work}/floquet.npz", "force", RefinedStates.load(f"{work}/refined.npz",
                       comm), method="symmetric" if symmetric else "dense")
    rows = list(scan.run())
    scan.destroy()
    comm.tompi4py().Barrier()
    t2 = time.perf_counter()
    records = comm.tompi4py().allgather(rows)
    rho = {f"{float(r['q']):.12f}": float(r["rho"]) for part in records for r in part}
    E = [float(r["E_after"]) for part in comm.tompi4py().allgather(refined) for r in part]
    emit(MPI.COMM_WORLD, wall=t2 - t0, refine=t1 - t0, floquet=t2 - t1, E_max=max(E), rho=rho,
         iterations=sum(int(r["iterations"]) for r in refined))


def worker(name, req, petsc_args):
    if name == "scipy":
        scipy_worker(req)
    else:
        petsc_worker(name, req, petsc_args)


def main():
    import numpy as np

    from hertzpetsc.options import AppOptions
    from hertzpetsc.resources import MAX_DENSE_BEADS
    opts = AppOptions(__doc__)
    branch = opts.path("branch", "results/branch_alpha1.5.npz", "branch file")
    N = opts.integer("N", 100, "beads of the periodic chain", minimum=3, maximum=MAX_DENSE_BEADS)
    tol = opts.real("tol", 1e-10, "target E(q) of every refinement", valid=(lambda x: x > 0, "> 0"))
    routes = opts.words("routes", ",".join(ROUTES), "routes to run", choices=ROUTES)
    output, repeats, records_path, mode = declare_common(opts, "runs/bench_stability.md", repeats=1)
    opts.done()
    from hertzpetsc.branch import Branch
    Branch.load(branch)                                      # the workers' input, checked before any worker runs
    opts.check_unused()
    os.environ.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")      # the SciPy route too: one core each
    work = tempfile.mkdtemp(prefix="bench_stability_")
    waves = os.path.join(work, "waves.npz")
    count = initial_waves(branch, N, waves)
    me = os.path.abspath(__file__)
    rec = BenchRecords(records_path, "hertzpetsc-bench-stability-1", dict(branch=branch, N=N, tol=tol), mode)
    req = dict(branch=branch, N=N, tol=tol, waves=waves)
    start = machine(repeats)
    runs = []
    labels = {"scipy": "SciPy (solve_ivp DOP853, state + 2N tangents; lstsq with phase conditions; eigvals)",
              "symmetric": "hertzpetsc, symmetric routes (refine_branch.py, floquet_scan.py defaults)",
              "paper": "hertzpetsc, paper routes (-method full, -method dense)",
              "numpy": "hertzpetsc, symmetric routes, numpy right-hand side (-*_rhs_compiled 0)"}
    for route in routes:
        for ranks in {"scipy": (None,), "numpy": (1,)}.get(route, (1, 2)):
            key = f"{route} {ranks or 1}"
            args = NUMPY_RHS if route == "numpy" else ()
            res = rec.measure(key, lambda: best_of(1 if route == "scipy" else repeats, me, route, req, ranks, 7200,
                                                   args))
            runs.append((route, ranks or 1, res))
            print(key, json.dumps({k: v for k, v in (res or {}).items() if k not in ("rho", "multipliers")}),
                  flush=True)
    sci = next((res for route, _, res in runs if route == "scipy" and res), None)
    if sci:                   # rho without the four trivial multipliers, identified as in the hertzpetsc routes
        from hertzpetsc.floquet import spectral_radius
        sci["rho"] = {q: spectral_radius(np.array([complex(*z) for z in lam]), exclude_trivial=True)
                      for q, lam in sci["multipliers"].items()}
    lines = [f"Stability scan on N = {N} beads: the {count} branch q = 2 pi m / {N}, refinement to E <= {tol:g}, "
             f"then all {2 * N} Floquet multipliers modulo shifts. {start}; load average at the end "
             f"{os.getloadavg()[0]:.2f}. One BLAS thread per rank. SciPy: rtol {RTOL_SCIPY:g}, atol "
             f"{ATOL_SCIPY:g}; hertzpetsc: rtol 1e-14, atol 1e-16. 'max |rho - rho_SciPy|' is over the q where "
             "the SciPy route reached the target E and finds rho - 1 > 1e-4. The load average is the one-minute "
             "average when the row's measurement started.\n",
             "| route | ranks | refinement (s) | Floquet (s) | total (s) | GN iterations | max E | "
             "max \\|rho - rho_SciPy\\| | SciPy / this | load at start |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for route, ranks, res in runs:
        if res is None:
            lines.append(f"| {labels[route]} | {ranks} | timed out | | | | | | | |")
            continue
        diff, ratio = "", ""
        if sci:
            failed = {f"{q:.12f}" for q, _, _ in sci.get("unconverged", [])}
            unstable = [q for q, r in sci["rho"].items() if r - 1 > 1e-4 and q not in failed]
            diff = f"{max(abs(res['rho'][q] - sci['rho'][q]) for q in unstable):.1e}"
            ratio = f"{sci['wall'] / res['wall']:.1f}"
        lines.append(f"| {labels[route]} | {ranks} | {res['refine']:.1f} | {res['floquet']:.1f} | {res['wall']:.1f} "
                     f"| {res['iterations']} | {res['E_max']:.1e} | {diff} | {ratio} | {res.get('load', 0):.2f} |")
    for q, E, its in (sci or {}).get("unconverged", []):
        lines.append(f"\nSciPy route: E = {E:.1e} > {tol:g} after {its} Gauss-Newton steps at q = {q:.6f}.")
    write_report(output, lines)


if __name__ == "__main__":
    main_or_worker(main, worker)
