#!/usr/bin/env python3
"""Benchmark of the multipliers of long damped, driven chains (issue 41 item 1): every multiplier outside a radius
(floquet 'radius') beside the route before it (floquet 'slepc': the -nev dominant ones) and, where the chain is
short enough, the dense route (all 2N by LAPACK), on 1 and 2 ranks.

    python scripts/bench_long_driven.py [-sizes 200,1000] [-ranks 1,2] [-omega 1] [-gamma 0.05] [-delta0 1]
        [-amplitude 0.2] [-run_in 30] [-routes radius,slepc,dense] [-nev 4] [-radius_nev 16] [-dense_max 200]
        [-slepc_max 1000]
        [-radius_N10000 0.998] [-previous DIR] [-timeout 600] [-output runs/bench_long_driven.md] [-records FILE]
        [-resume | -force]
        [-floquet_radius r -floquet_eps_tol ... (the Floquet role's options, passed to every worker)]

Each chain: N beads (Hertz, alpha 3/2, precompression -delta0, on-site damping -gamma) between an actuator
a cos(omega t) and a wall; -run_in periods from rest, then the periodic response by Newton-Krylov shooting (flows
rtol 1e-12), then its multipliers by each route, timed alone (wall, tangent products, peak memory per rank). The
radius route's r is -floquet_radius if given, else the default e^(-gamma T / 4) (driven.default_radius); for
N = 10000 -radius_N10000 (its ten longest, overdamped waves at omega = 1, gamma = 0.05). The slepc route is run
for N <= -slepc_max, the dense one for N <= -dense_max; a measurement past -timeout seconds is 'not finished'.
The radius route: the slow modes first (floquet.slow_eigenpairs: 'slow' multipliers by block products started
from the linear chain's overdamped long waves), then Krylov-Schur on the rest ('Krylov' products); -floquet_slow_modes
0 leaves the first stage out. -previous DIR: the radius route also with the hertzpetsc of another checkout (e.g. a
git worktree of the previous release), side by side.
Each measurement in its own process (one BLAS thread per rank). On a loaded machine the times are indicative only.
"""
import math
import os
import sys
import time

from benchlib import BenchRecords, best_of, declare_common, emit, machine, main_or_worker, write_report

ALPHA, RTOL = 1.5, 1e-12


def worker(name, req, petsc_args):
    import petsc4py
    petsc4py.init(sys.argv[:1] + petsc_args)
    import numpy as np
    from mpi4py import MPI
    from petsc4py import PETSc

    from hertzpetsc.driven import Drive, HarmonicWave, PeriodicShooting
    from hertzpetsc.model import LatticeModel
    from hertzpetsc.studies.driven import tolerances_of
    N = req["N"]
    drive = Drive(LatticeModel.hertz(ALPHA, delta0=req["delta0"], gamma=req["gamma"]), N, HarmonicWave(),
                  req["amplitude"], req["omega"])
    comm = MPI.COMM_WORLD
    prob = PeriodicShooting(drive, PETSc.COMM_WORLD, jacobian="mf", floquet=name, nev=req["nev"], tol=1e-10,
                            tolerances=tolerances_of(RTOL, req["amplitude"]))
    comm.Barrier()
    t0 = time.perf_counter()
    r = prob.solve_response(prob.run_in(np.zeros((N, 2)), req["run_in"]))
    comm.Barrier()
    t1 = time.perf_counter()
    products = prob.counters["products"]
    mu = prob.multipliers(x=r.x, p=drive.omega)
    comm.Barrier()
    t2 = time.perf_counter()
    work = getattr(prob, "floquet_work", {})
    emit(comm, response=t1 - t0, wall=t2 - t1, products=prob.counters["products"] - products, count=len(mu),
         slow=work.get("slow"), krylov=work.get("krylov_products"),
         moduli=[float(v) for v in np.abs(mu)], mu=[[float(v.real), float(v.imag)] for v in mu],
         radius=prob.radius, residual=r.residual)
    prob.destroy()


def main():
    from hertzpetsc.options import AppOptions
    opts = AppOptions(__doc__)
    from hertzpetsc.resources import MAX_DENSE_BEADS, chain_seconds, check_chain_memory, check_work
    sizes = opts.numbers("sizes", "200,1000", "chain lengths", expr=False, kind=int,
                         valid=(lambda N: 2 <= N <= 10 ** 6, "in [2, 1e6]"), distinct=True)
    ranks = opts.numbers("ranks", "1,2", "numbers of MPI ranks", expr=False, kind=int,
                         valid=(lambda n: 1 <= n <= 64, "in [1, 64]"), distinct=True)
    omega = opts.real("omega", 1.0, "driving frequency", valid=(lambda x: x > 0, "> 0"))
    gamma = opts.real("gamma", 0.05, "on-site damping", valid=(lambda x: x > 0, "> 0"))
    delta0 = opts.real("delta0", 1.0, "precompression", valid=(lambda x: x > 0, "> 0 (Newton-Krylov's "
                                                                  "preconditioner needs V''(0) > 0)"))
    amplitude = opts.real("amplitude", 0.2, "actuator amplitude", valid=(lambda x: x > 0, "> 0"))
    run_in = opts.integer("run_in", 30, "periods from rest before Newton-Krylov", minimum=0)
    routes = opts.words("routes", "radius,slepc,dense", "routes measured", choices=("radius", "slepc", "dense"))
    nev = opts.integer("nev", 4, "slepc: the dominant multipliers", minimum=1)
    cap = opts.integer("radius_nev", 16, "radius: the most multipliers outside the radius", minimum=1)
    dense_max = opts.integer("dense_max", 200, "largest N of the dense route", minimum=0, maximum=MAX_DENSE_BEADS)
    slepc_max = opts.integer("slepc_max", 1000, "largest N of the slepc route", minimum=0)
    big_radius = opts.real("radius_N10000", 0.998, "the radius at N = 10000 (unless -floquet_radius)",
                           valid=(lambda x: 0 < x, "> 0"))
    previous = opts.path("previous", "", "a checkout of another version: the radius route measured with it too, "
                         "side by side")
    timeout = opts.integer("timeout", 600, "seconds before a measurement counts as not finished", minimum=1)
    output, repeats, records_path, mode = declare_common(opts, "runs/bench_long_driven.md", repeats=1)
    # the Floquet role's options given on the command line go to every worker (-floquet_radius, -floquet_eps_tol ...)
    from petsc4py import PETSc
    floquet_args = []
    for key, value in PETSc.Options().getAll().items():
        if key.startswith("floquet_"):
            floquet_args += [f"-{key}"] + ([str(value)] if value != "" else [])
            PETSc.Options().getString(key)           # used: passed on
    opts.done()
    opts.check_unused()
    if previous and not opts.help and not os.path.isfile(os.path.join(previous, "hertzpetsc", "__init__.py")):
        from hertzpetsc.errors import ParameterError
        raise ParameterError("-previous", previous, "must be a checkout holding hertzpetsc/ (e.g. a git worktree)")
    if not opts.help:
        for N in sizes:
            check_chain_memory(N, PETSc.COMM_WORLD, columns=3, name="sizes")
            check_work("run_in", run_in, len(ranks) * len(routes) * repeats * chain_seconds(N, run_in * 2 * math.pi
                                                                                             / omega),
                       f"run-ins of {run_in} periods on {N} beads")
    me = os.path.abspath(__file__)
    T = 2 * math.pi / omega
    rec = BenchRecords(records_path, "hertzpetsc-bench-longdriven-1",
                       dict(omega=omega, gamma=gamma, delta0=delta0, amplitude=amplitude, run_in=run_in, nev=nev, cap=cap,
                            floquet=floquet_args, big_radius=big_radius, **({"previous": previous} if previous
                                                                              else {})), mode)
    lines = [f"Multipliers of long driven chains; {machine(repeats)}. One BLAS thread per process. Timings taken "
             "while other jobs loaded the machine are indicative only.\n",
             f"Chain: alpha = {ALPHA}, delta0 = {delta0:g}, on-site damping gamma = {gamma:g}, actuator a cos(omega t), "
             f"a = {amplitude:g}, omega = {omega:g}, wall; {run_in} periods from rest, then Newton-Krylov shooting "
             f"to 1e-10 (flows rtol {RTOL:g}). The phonons' circle |mu| = e^(-gamma T / 2) = "
             f"{math.exp(-gamma * T / 2):.6f}; the default radius e^(-gamma T / 4) = {math.exp(-gamma * T / 4):.6f}. "
             f"Routes: radius (every multiplier outside r, at most {cap}; SLEPc Krylov-Schur with the region |mu| > r "
             f"and the closure test), slepc (the {nev} dominant, the route before), dense (all 2N, LAPACK). "
             "'wall': the multipliers alone (the response's time beside it); 'products': tangent-flow products "
             "(single columns; radius route: those of the slow modes' block integrations + the Krylov stage's, and "
             "'slow': the multipliers the first stage found); 'found': multipliers returned; 'largest': their moduli "
             "(at most 6). " + (f"Route 'radius, previous': the radius route with the hertzpetsc of {previous}. "
                                if previous else "")
             + (f"Floquet options: {' '.join(floquet_args)}." if floquet_args else ""),
             "",
             "| N | route | ranks | r | wall (s) | response (s) | products | slow | found | largest | peak MB/rank |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    plan = [(route, None) for route in routes]
    if previous and "radius" in routes:
        plan.insert(routes.index("radius") + 1, ("radius", previous))
    for N in sizes:
        for route, package in plan:
            if (route == "dense" and N > dense_max) or (route == "slepc" and N > slepc_max):
                continue
            args = list(floquet_args)
            if route == "radius" and N == 10000 and "-floquet_radius" not in args:
                args += ["-floquet_radius", str(big_radius)]
            if route != "radius":
                args = [a for i, a in enumerate(args) if a != "-floquet_radius"
                        and (i == 0 or args[i - 1] != "-floquet_radius")]
            req = dict(N=N, omega=omega, gamma=gamma, delta0=delta0, amplitude=amplitude, run_in=run_in,
                       nev=cap if route == "radius" else nev)
            label = f"{route}, previous" if package else route
            for n in ranks:
                res = rec.measure(f"{N} {label} {n}", lambda: best_of(repeats, me, route, req, n, timeout,
                                                                      petsc_args=args, package=package))
                if res is None:
                    lines.append(f"| {N} | {label} | {n} | | not finished (> {timeout} s) | | | | | | |")
                    print(lines[-1], flush=True)
                    continue
                r = f"{res['radius']:.6g}" if res.get("radius") is not None else ""
                largest = ", ".join(f"{v:.6f}" for v in res["moduli"][:6])
                products = "n/a" if route == "dense" else str(res["products"]) if res.get("krylov") is None or \
                    not res.get("slow") else f"{res['products']} ({res['krylov']} Krylov)"
                lines.append(f"| {N} | {label} | {n} | {r} | {res['wall']:.1f} | {res['response']:.1f} | "
                             f"{products} | {res.get('slow') if res.get('slow') is not None else ''} | "
                             f"{res['count']} | {largest} | " + ", ".join(f"{v:.0f}" for v in res["rss_mb"]) + " |")
                print(lines[-1], flush=True)
    write_report(output, lines)


if __name__ == "__main__":
    main_or_worker(main, worker)
