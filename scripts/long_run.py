#!/usr/bin/env python3
"""Long-time simulation of a travelling wave on a periodic chain, with snapshots written as they are taken.

    mpiexec -n 2 python scripts/long_run.py -branch results/branch_alpha1.5.npz -q 3*pi/10 -t_final 4000 \
        -output runs/q3pi10 [-refined results/refined_N100.npz] [-N 100] [-snapshots_per_T 4] [-resume | -force]

The initial state is the refined one for this q when -refined names a refinement file (which must have it),
else the wave of the branch file interpolated onto the chain. Snapshots every script-T / snapshots_per_T,
each with the integrator's step, so that -resume continues a killed run to the same trajectory; at the
multiples of script-T the deviation from the exact travelling wave D(t) = ||S^k X(k T) - X(0)|| / ||X(0)|| is
computed (paper: stable at q = 3pi/10 over t ~ 4000, destroyed near t ~ 360 at q = 7pi/25). Writes
``summary.json`` in the output directory: destruction time (first D > 0.1), the times D first exceeds 1e-6,
1e-3, max D, relative energy drift. An existing run directory is only continued (-resume) or overwritten (-force).
"""
import json
import math
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.branch import Branch  # noqa: E402
from hertzpetsc.model import ChainSpec  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.progress import Progress  # noqa: E402
from hertzpetsc.studies.longrun import LongRun  # noqa: E402
from hertzpetsc.studies.refinement import RefinedStates  # noqa: E402
from hertzpetsc.waves import orbit_on_chain  # noqa: E402


def main():
    opts = AppOptions(__doc__, LongRun.ROLES)
    branch_path = opts.path("branch", "results/branch_alpha1.5.npz", "branch file")
    q = opts.real("q", 3 * math.pi / 10, "wavenumber (a branch point with N q / (2 pi) integer)", expr=True,
                  valid=(lambda x: x > 0, "> 0"))
    N = opts.integer("N", 100, "beads of the periodic chain", minimum=3, maximum=10 ** 8)
    t_final = opts.real("t_final", 100.0, "final time", valid=(lambda t: 0 < t <= 1e9, "in (0, 1e9]"))
    per_T = opts.integer("snapshots_per_T", 4, "snapshots per script-T", minimum=1)
    output = opts.path("output", "runs/run", "run directory")
    refined_path = opts.path("refined", "", "refinement file with the refined state at q (none if empty)")
    mode = opts.mode()
    opts.done()
    comm = PETSc.COMM_WORLD
    branch = Branch.load(branch_path, comm)
    spec = ChainSpec(branch.model, N)
    point = branch.point(q)
    orbit = RefinedStates.load(refined_path, comm).orbit(point, spec) if refined_path else orbit_on_chain(point, spec)
    run = LongRun(orbit, t_final, per_T, output, comm, mode)
    opts.check_unused()
    run.open()
    if mode == "resume":
        print0(f"resuming {output} at t = {run.resumed_at:.6g} ({len(run.store.records)} snapshots)")
    print0(f"# q = {orbit.q:.6f}, N = {N}, script-T = {orbit.T:.6f}, initial state: {orbit.source}, "
           f"t_final = {t_final}")
    start = run.resumed_at if run.store.records else 0.0          # (resumed_at: nan for a new run)
    progress = Progress(t_final, "time units", "long run", start=start, comm=comm)

    def show(t, drift, steps):
        print0(f"  t = {t:10.3f}  energy drift {drift:+.2e}  steps {steps}")
        progress.update(t)          # on a terminal: the time left, now and then
    run.run(show)
    summary = run.write_summary()
    run.destroy()
    print0(json.dumps(summary.as_dict(), indent=1))


if __name__ == "__main__":
    guarded_main(main)
