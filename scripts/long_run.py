#!/usr/bin/env python3
"""Long-time simulation of a travelling wave on a periodic chain, with snapshots written as they are taken.

    mpiexec -n 2 python scripts/long_run.py -branch results/branch_alpha1.5.npz -q 3*pi/10 -t_final 4000 \
        -output runs/q3pi10 [-refined results/refined_N100.npz] [-N 100] [-snapshots_per_T 4] [-resume]

The initial state is the refined one for this q when -refined names a refinement file that has it, else the
wave of the branch file interpolated onto the chain. Snapshots every script-T / snapshots_per_T; at the
multiples of script-T the deviation from the exact travelling wave D(t) = ||S^k X(k T) - X(0)|| / ||X(0)|| is
computed (paper: stable at q = 3pi/10 over t ~ 4000, destroyed near t ~ 360 at q = 7pi/25). Writes
``summary.json`` in the output directory: destruction time (first D > 0.1), the times D first exceeds 1e-6,
1e-3, max D, relative energy drift. -resume continues a killed run from its last snapshot.
PETSc prefix: -chain_ (TS; default -chain_ts_rk_type 8vr, -chain_ts_rtol 1e-12, -chain_ts_atol 1e-14).
"""
import json
import math
import os
import sys
import time

import petsc4py

petsc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

import numpy as np  # noqa: E402

from hertzpetsc.branchfile import read_branch, refined_state  # noqa: E402
from hertzpetsc.chain import Chain, ChainIntegrator, ChainParameters  # noqa: E402
from hertzpetsc.cli import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.simulation import (SnapshotFile, check_times, first_crossing, state_digest,  # noqa: E402
                                   wave_deviation)
from hertzpetsc.waves import wave_on_chain  # noqa: E402

DESTRUCTION_LEVEL = 0.1


def main():
    opts = AppOptions()
    branch_path = opts.string("branch", "results/branch_alpha1.5.npz")
    q = opts.real("q", 3 * math.pi / 10, expr=True)
    N = opts.integer("N", 100, minimum=3)
    t_final = opts.real("t_final", 100.0)
    per_T = opts.integer("snapshots_per_T", 4, minimum=1)
    output = opts.string("output", "runs/run")
    refined_path = opts.string("refined", "")
    resume = opts.flag("resume")
    comm = PETSc.COMM_WORLD
    rank0 = comm.getRank() == 0

    branch = read_branch(branch_path)
    wave = wave_on_chain(branch, q, N)
    x0, source = wave.as_array(), "branch (interpolated)"
    if refined_path:
        got = refined_state(refined_path, wave.q, N)
        if got is not None:
            x0, source = got, "refined"
    dt_snap = wave.T / per_T
    check_times(t_final, dt_snap)
    params = ChainParameters(float(branch["alpha"]), N, "periodic")
    chain = Chain(params, comm)
    integ = ChainIntegrator(chain)
    ts = integ.ts
    header = dict(alpha=params.alpha, N=N, boundary="periodic", q=wave.q, T=wave.T, branch=branch_path,
                  initial_state=source, initial_state_sha256=state_digest(x0), snapshot_dt=dt_snap,
                  rtol=ts.getTolerances()[0], atol=ts.getTolerances()[1], ts=f"{ts.getType()} {ts.getRKType()}")
    if resume:
        snaps = SnapshotFile.open(output, header)
        if rank0:
            snaps.truncate_partial()
        comm.tompi4py().Barrier()
        times, energies, states = snaps.read()
        if len(times) == 0:
            t, x, E0 = 0.0, x0, None
        else:
            t, x, E0 = float(times[-1]), states[-1], float(energies[0])
        print0(f"resuming {output} at t = {t:.6g} ({len(times)} snapshots)")
    else:
        snaps = SnapshotFile.create(output, header) if rank0 else SnapshotFile(output, header)
        t, x, E0 = 0.0, x0, None
    X = chain.create_state()
    chain.set_from_array(X, x)
    if E0 is None:
        E0 = chain.energy(X)
        if rank0:
            snaps.append(0.0, E0, x0)
    k = int(round(t / dt_snap))
    t0 = time.perf_counter()
    steps = 0
    print0(f"# q = {wave.q:.6f}, N = {N}, script-T = {wave.T:.6f}, initial state: {source}, t_final = {t_final}")
    while (k + 1) * dt_snap <= t_final * (1 + 1e-12):
        steps += integ.integrate(X, k * dt_snap, (k + 1) * dt_snap)
        k += 1
        E = chain.energy(X)
        state = chain.gather(X)
        if rank0:
            snaps.append(k * dt_snap, E, state)
        if k % (per_T * 50) == 0:
            print0(f"  t = {k * dt_snap:10.3f}  energy drift {(E - E0) / E0:+.2e}  steps {steps}")
    wall = time.perf_counter() - t0
    times, energies, states = snaps.read() if rank0 else (None, None, None)
    if rank0:
        tD, D = wave_deviation(times, states, x0, wave.T)
        summary = dict(q=wave.q, N=N, T=wave.T, initial_state=source, t_final=float(times[-1]),
                       snapshots=len(times), steps_this_session=steps, wall_time_this_session=wall,
                       energy_drift=float(np.max(np.abs(energies - energies[0])) / energies[0]),
                       max_deviation=float(D.max()), destruction_level=DESTRUCTION_LEVEL,
                       destruction_time=first_crossing(tD, D, DESTRUCTION_LEVEL),
                       time_D_above_1em6=first_crossing(tD, D, 1e-6),
                       time_D_above_1em3=first_crossing(tD, D, 1e-3), ts=header["ts"],
                       rtol=header["rtol"], atol=header["atol"])
        with open(os.path.join(output, "summary.json"), "w") as f:
            json.dump(summary, f, indent=1)
        print0(json.dumps(summary, indent=1))
    integ.destroy()
    chain.destroy()


if __name__ == "__main__":
    guarded_main(main)
