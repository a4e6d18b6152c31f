#!/usr/bin/env python3
"""Benchmark of the driven chains (issue 22): a frequency sweep with Floquet multipliers at every frequency, and a
periodic response of a long chain by Newton-Krylov shooting.

    python scripts/bench_driven.py [-N 20] [-points 200] [-omega0 0.3] [-omega1 2.3] [-delta0 1] [-gamma 0.05]
        [-amplitude 0.02] [-run_in 30] [-long_N 10000] [-long_gamma 0.2] [-long_run_in 10] [-repeats 1]
        [-workloads sweep,long] [-output runs/bench_driven.md] [-records FILE] [-resume | -force]

sweep: a chain of -N beads (Hertz, alpha 3/2, precompression -delta0, on-site damping -gamma) between an actuator
a cos(omega t) and a wall; -run_in periods from rest at omega0, then the periodic response and all 2N multipliers
at -points equally spaced frequencies from omega0 to omega1 (flows rtol 1e-12, atol 1e-14; shooting tolerance 1e-10
relative). Routes, in one run: hertzpetsc (the driver's route: natural continuation with the secant predictor of
the continuation layer, bordered Newton on SNES with the dense tangent-flow Jacobian, reused as a chord while it
contracts, LAPACK multipliers of the monodromy at each response) on 1 and 2 ranks, and SciPy (solve_ivp DOP853 on
the state and its 2N variational columns at each Newton iteration, numpy.linalg.solve, numpy.linalg.eigvals of the
last monodromy; the previous response as the guess), once with atol 1e-14 on every component and once with the
tangent columns' atol = rtol, as hertzpetsc's multipliers' flow. long: -long_N beads, -long_run_in periods from
rest, then Newton-Krylov shooting (GMRES on tangent-flow products, preconditioned by the linear chain's monodromy)
to 1e-9; time and peak memory per rank on 1 and 2 ranks.
Each measurement in its own process (one BLAS thread per rank), best of -repeats; run on an idle machine.
"""
import math
import os
import sys
import time

from benchlib import BenchRecords, best_of, declare_common, emit, machine, main_or_worker, write_report

RTOL, ATOL, TOL = 1e-12, 1e-14, 1e-10
ALPHA = 1.5


def _grid(req):
    n = req["points"]
    return [req["omega0"] + (req["omega1"] - req["omega0"]) * k / (n - 1) for k in range(n)]


def scipy_sweep(req):
    """The SciPy route (module docstring); returns wall, rho per frequency, Newton iterations, variational flows."""
    import numpy as np
    from scipy.integrate import solve_ivp
    N, d0, g, a = req["N"], req["delta0"], req["gamma"], req["amplitude"]

    def forces(x, t, w):
        xe = np.concatenate([[a * math.cos(w * t)], x, [0.0]])
        c = np.maximum(d0 - np.diff(xe), 0.0)
        return d0 ** ALPHA - c ** ALPHA, ALPHA * c ** (ALPHA - 1)

    def f_state(t, z, w):
        x, v = z[:N], z[N:]
        F, _ = forces(x, t, w)
        return np.concatenate([v, F[1:] - F[:-1] - g * v])

    def f_var(t, z, w):
        x, v = z[:N], z[N:2 * N]
        F, K = forces(x, t, w)
        Y = z[2 * N:].reshape(2 * N, 2 * N)
        yx, yv = Y[:N], Y[N:]
        ye = np.vstack([np.zeros(2 * N), yx, np.zeros(2 * N)])
        dy = np.diff(ye, axis=0)
        ayv = K[1:, None] * dy[1:] - K[:-1, None] * dy[:-1] - g * yv
        return np.concatenate([v, F[1:] - F[:-1] - g * v, yv.ravel(), ayv.ravel()])

    eye = np.eye(2 * N).ravel()
    # 'tangent_atol': the columns' absolute tolerance (else ATOL, as the state's)
    atol_var = np.concatenate([np.full(2 * N, ATOL), np.full(4 * N * N, req.get("tangent_atol", ATOL))])
    grid = _grid(req)
    t0 = time.perf_counter()
    z = np.zeros(2 * N)
    w = grid[0]
    T = 2 * math.pi / w
    for k in range(req["run_in"]):
        z = solve_ivp(f_state, (k * T, (k + 1) * T), z, method="DOP853", rtol=RTOL, atol=ATOL, args=(w,)).y[:, -1]
    rhos, its, flows, worst = [], 0, 0, 0.0
    for w in grid:
        T = 2 * math.pi / w
        for it in range(30):
            sol = solve_ivp(f_var, (0.0, T), np.concatenate([z, eye]), method="DOP853", rtol=RTOL, atol=atol_var,
                            args=(w,))
            flows += 1
            zT = sol.y[:, -1]
            G = zT[:2 * N] - z
            M = zT[2 * N:].reshape(2 * N, 2 * N)
            res = np.max(np.abs(G)) / max(np.max(np.abs(z)), a)
            if res <= TOL:
                break
            z = z + np.linalg.solve(M - np.eye(2 * N), -G)
            its += 1
        else:
            raise RuntimeError(f"SciPy Newton did not converge at omega = {w}")
        worst = max(worst, res)
        rhos.append(float(np.max(np.abs(np.linalg.eigvals(M)))))
    emit(None, wall=time.perf_counter() - t0, rho=rhos, iterations=its, flows=flows, residual=worst)


def petsc_sweep(req, petsc_args):
    import petsc4py
    petsc4py.init(sys.argv[:1] + petsc_args)
    from mpi4py import MPI
    from petsc4py import PETSc

    from hertzpetsc.driven import Drive, HarmonicWave
    from hertzpetsc.model import LatticeModel
    from hertzpetsc.studies.driven import ResponseCurve, ResponseParameters

    grid = _grid(req)
    drive = Drive(LatticeModel.hertz(ALPHA, delta0=req["delta0"], gamma=req["gamma"]), req["N"], HarmonicWave(),
                  req["amplitude"], grid[0])
    comm = MPI.COMM_WORLD
    study = ResponseCurve(ResponseParameters(drive, "omega", grid[-1], tol=TOL, rtol=RTOL, grid=tuple(grid[1:]),
                                             run_in=req["run_in"], samples=0, max_steps=len(grid)), PETSc.COMM_WORLD)
    spent = dict(accurate=0.0, jacobian=0.0)
    monodromy = study.problem.monodromy

    def timed(x, p, accurate=True):                 # where the time goes: the two tangent flows
        t = time.perf_counter()
        try:
            return monodromy(x, p, accurate)
        finally:
            spent["accurate" if accurate else "jacobian"] += time.perf_counter() - t
    study.problem.monodromy = timed
    comm.Barrier()
    t0 = time.perf_counter()
    recs = list(study.run())
    comm.Barrier()
    wall = time.perf_counter() - t0
    c = study.problem.counters
    study.destroy()
    emit(comm, wall=wall, rho=[float(r["rho"]) for r in recs], iterations=int(sum(int(r["iterations"]) for r in recs)),
         flows=c["tangent_flows"], state_flows=c["state_flows"], residual=max(float(r["residual"]) for r in recs),
         accurate_s=spent["accurate"], jacobian_s=spent["jacobian"])


def petsc_long(req, petsc_args):
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
    prob = PeriodicShooting(drive, PETSc.COMM_WORLD, jacobian="mf", floquet="none", tol=1e-9,
                            tolerances=tolerances_of(RTOL, req["amplitude"]))
    comm.Barrier()
    t0 = time.perf_counter()
    x = prob.run_in(np.zeros((N, 2)), req["run_in"])
    t1 = time.perf_counter()
    start = prob.residual(x)
    r = prob.solve_response(x)
    comm.Barrier()
    t2 = time.perf_counter()
    emit(comm, wall=t2 - t0, run_in=t1 - t0, newton=t2 - t1, iterations=r.iterations, residual=r.residual,
         start=start, products=prob.counters["products"], flows=prob.counters["state_flows"])
    prob.destroy()


def worker(name, req, petsc_args):
    if name == "scipy":
        scipy_sweep(req)
    elif name == "sweep":
        petsc_sweep(req, petsc_args)
    else:
        petsc_long(req, petsc_args)


def main():
    from hertzpetsc.options import AppOptions
    opts = AppOptions(__doc__)
    from hertzpetsc.driven import JACOBIAN_RTOL
    from hertzpetsc.resources import MAX_DENSE_BEADS, chain_seconds, check_chain_memory, check_work
    from hertzpetsc.studies.driven import MAX_POINTS
    N = opts.integer("N", 20, "beads of the swept chain (dense Jacobian and multipliers)", minimum=1,
                     maximum=MAX_DENSE_BEADS)
    points = opts.integer("points", 200, "frequencies of the sweep", minimum=2, maximum=MAX_POINTS)
    omega0 = opts.real("omega0", 0.3, "first frequency", valid=(lambda x: x > 0, "> 0"))
    omega1 = opts.real("omega1", 2.3, "last frequency", valid=(lambda x: x > 0, "> 0"))
    delta0 = opts.real("delta0", 1.0, "precompression", valid=(lambda x: x >= 0, ">= 0"))
    gamma = opts.real("gamma", 0.05, "on-site damping", valid=(lambda x: x >= 0, ">= 0"))
    amplitude = opts.real("amplitude", 0.02, "actuator amplitude", valid=(lambda x: x >= 0, ">= 0"))
    run_in = opts.integer("run_in", 30, "periods from rest before the first Newton", minimum=0)
    long_N = opts.integer("long_N", 10000, "beads of the long chain (0: no long workload)", minimum=0)
    long_gamma = opts.real("long_gamma", 0.2, "on-site damping of the long chain", valid=(lambda x: x >= 0, ">= 0"))
    long_run_in = opts.integer("long_run_in", 10, "periods from rest before Newton-Krylov (long chain)", minimum=0)
    workloads = opts.words("workloads", "sweep,long", "what to measure", choices=("sweep", "long"))
    output, repeats, records_path, mode = declare_common(opts, "runs/bench_driven.md", repeats=1)
    opts.done()
    opts.check_unused()
    if set(workloads) == {"long"} and not long_N:
        from hertzpetsc.errors import ParameterError
        raise ParameterError("-long_N", long_N, "the only workload is long: give its beads (>= 2), or add sweep to "
                             "-workloads")
    if not opts.help:                    # before any worker starts: the sweep's tangent flow, the long chain's state
        from petsc4py import PETSc
        check_chain_memory(N, PETSc.COMM_WORLD, columns=2 + 2 * N, name="N")
        if "long" in workloads and long_N:
            check_chain_memory(long_N, PETSc.COMM_WORLD, columns=3, name="long_N")
        # the run-ins' state flows, estimated (the SciPy route and each repeat run them again)
        runs = 2 + repeats
        check_work("run_in", run_in, runs * chain_seconds(N, run_in * 2 * math.pi / omega0),
                   f"{runs} run-ins of {run_in} periods on {N} beads")
        if "long" in workloads:
            check_work("long_run_in", long_run_in, repeats * chain_seconds(long_N, long_run_in * 2 * math.pi),
                       f"{repeats} run-in(s) of {long_run_in} periods on {long_N} beads")
    me = os.path.abspath(__file__)
    sweep = dict(N=N, points=points, omega0=omega0, omega1=omega1, delta0=delta0, gamma=gamma, amplitude=amplitude,
                 run_in=run_in)
    long = dict(N=long_N, delta0=delta0, gamma=long_gamma, amplitude=0.1, omega=1.0, run_in=long_run_in)
    rec = BenchRecords(records_path, "hertzpetsc-bench-driven-1", dict(sweep=sweep, long=long), mode)
    lines = [f"Driven chains; {machine(repeats)}. One BLAS thread per process, SciPy's too.\n"]
    if "sweep" in workloads:
        lines += [f"Frequency sweep: N = {N} beads, alpha = {ALPHA}, delta0 = {delta0:g}, gamma = {gamma:g}, actuator "
                  f"a cos(omega t), a = {amplitude:g}, wall; {run_in} periods from rest at omega = {omega0:g}, then "
                  f"the periodic response and all {2 * N} Floquet multipliers at {points} frequencies from {omega0:g} "
                  f"to {omega1:g}; flows rtol {RTOL:g}, atol {ATOL:g}; shooting tolerance {TOL:g}. 'flows': flows of "
                  f"the state with {2 * N} tangent columns (hertzpetsc: plus 'state flows' without); max |d rho|: "
                  "the largest difference of the spectral radius to the SciPy route's over the frequencies; "
                  "'multipliers' flows', 'Jacobians' flows': hertzpetsc's time in the fully resolved tangent flows "
                  "(the multipliers at each response) and in the Newton Jacobians' (steps of the state's error). "
                  "hertzpetsc resolves the multipliers' tangent columns to atol = rtol (they start as unit vectors: "
                  "the monodromy to rtol in norm) and the Newton Jacobians' steps to the state's error at rtol "
                  f"{JACOBIAN_RTOL:g} (driven.JACOBIAN_RTOL); the second SciPy row gives SciPy the same columns' "
                  "tolerance.\n",
                  "| route | ranks | wall (s) | Newton iterations | flows with tangents | state flows | max residual | "
                  "max \\|d rho\\| | peak MB/rank | SciPy / this | multipliers' flows (s) | Jacobians' flows (s) |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        sci = rec.measure("sweep scipy", lambda: best_of(repeats, me, "scipy", sweep, None, 7200))
        columns = dict(sweep, tangent_atol=RTOL)
        sci_columns = rec.measure("sweep scipy tangent atol",
                                  lambda: best_of(repeats, me, "scipy", columns, None, 7200))
        rows = [("SciPy (solve_ivp DOP853 + variational equations, numpy solve, eigvals)", 1, sci),
                (f"SciPy, the same with the tangent columns' atol = rtol = {RTOL:g}", 1, sci_columns)]
        for ranks in (1, 2):
            rows.append(("hertzpetsc (ResponseCurve, grid mode)", ranks,
                         rec.measure(f"sweep petsc {ranks}", lambda: best_of(repeats, me, "sweep", sweep, ranks))))
        for name, ranks, res in rows:
            if res is None:
                lines.append(f"| {name} | {ranks} | not finished | | | | | | | | | |")
                continue
            drho = max(abs(a - b) for a, b in zip(res["rho"], sci["rho"])) if sci else math.nan
            ratio = f"{sci['wall'] / res['wall']:.2f}" if sci else "n/a"
            lines.append(f"| {name} | {ranks} | {res['wall']:.1f} | {res['iterations']} | {res['flows']} | "
                         f"{res.get('state_flows', 'n/a')} | {res['residual']:.1e} | {drho:.1e} | "
                         f"{max(res['rss_mb']):.0f} | {ratio} | "
                         + " | ".join(f"{res[k]:.1f}" if k in res else "n/a" for k in ("accurate_s", "jacobian_s"))
                         + " |")
        print("\n".join(lines[-3:]), flush=True)
    if "long" in workloads and long_N:
        lines += ["", f"Long chain: N = {long_N} beads, delta0 = {delta0:g}, gamma = {long_gamma:g}, a = 0.1, omega = "
                  f"1, wall; {long_run_in} periods from rest, then Newton-Krylov shooting (GMRES, one tangent-flow "
                  "product per iteration, preconditioned by the linear chain's (R_lin - I)^-1: "
                  "driven.LinearChainPreconditioner) to 1e-9 relative.\n",
                  "| ranks | wall (s) | run-in (s) | Newton-Krylov (s) | residual before Newton | Newton iterations | "
                  "tangent products | residual | peak MB/rank |", "|---|---|---|---|---|---|---|---|---|"]
        for ranks in (1, 2):
            res = rec.measure(f"long {ranks}", lambda: best_of(repeats, me, "long", long, ranks, 7200))
            if res is None:
                lines.append(f"| {ranks} | not finished | | | | | | | |")
                continue
            lines.append(f"| {ranks} | {res['wall']:.1f} | {res['run_in']:.1f} | {res['newton']:.1f} | "
                         f"{res['start']:.1e} | {res['iterations']} | {res['products']} | {res['residual']:.1e} | "
                         + ", ".join(f"{v:.0f}" for v in res["rss_mb"]) + " |")
    write_report(output, lines)


if __name__ == "__main__":
    main_or_worker(main, worker)
