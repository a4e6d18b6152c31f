#!/usr/bin/env python3
"""The paper's exact boundary driving (Discussion): refined travelling waves of the periodic chain imposed at both
ends of a finite undamped chain are periodic responses; their Floquet multipliers in the finite driven chain
against the periodic chain's, for q above and below q_c: does driving the ends stabilise or destabilise the wave?

    mpiexec -n 2 python scripts/driven_wave_ends.py [-branch results/branch_alpha1.5.npz]
        [-refined results/refined_N100.npz] [-q 5*pi/50,9*pi/50,...] [-sizes 10,20,40] [-rtols 1e-12,1e-14]
        [-samples 8192] [-output runs/driven_wave_ends.npz] [-table runs/driven_wave_ends.md]
        [-figures figures] [-resume | -force]

Beads 1..N of the periodic chain of P beads (the refinement file's) between actuators moving as beads 0 and N + 1
of the wave (its profile sampled from the refined chain on >= -samples points); Newton from the wave; all 2N
multipliers over tau = 2 pi / omega; rho(F_q)^(P/m) of the periodic chain for comparison; each at every flow
tolerance of -rtols (the convergence of the multipliers). Records: schema hertzpetsc-driven-wave-ends-1.
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.branch import Branch  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.driven import WaveEnds, WaveEndsParameters  # noqa: E402
from hertzpetsc.studies.refinement import RefinedStates  # noqa: E402


def main():
    opts = AppOptions(__doc__, WaveEnds.ROLES)
    branch_path = opts.path("branch", "results/branch_alpha1.5.npz", "branch file")
    refined_path = opts.path("refined", "results/refined_N100.npz", "refinement file (the periodic chain's waves)")
    p = opts.parameters(WaveEndsParameters, skip=("nmult",), sizes="10,20,40",
                        q="5*pi/50,9*pi/50,13*pi/50,14*pi/50,15*pi/50,16*pi/50,20*pi/50,30*pi/50,40*pi/50")
    output, mode, table_path, figures = opts.record_table_figures(
        "runs/driven_wave_ends.npz", "driven wave-ends file", "runs/driven_wave_ends.md", "driven_wave_ends.png")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path, figures=figures)
    branch = Branch.load(branch_path, comm)
    refined = RefinedStates.load(refined_path, comm)
    p["q"] = tuple(branch.point(q).q for q in p["q"])
    study = WaveEnds(WaveEndsParameters(branch, refined, **p, branch_path=branch_path, refined_path=refined_path),
                     comm, output, mode)
    opts.check_unused()
    study.open()
    print0(f"# {'q':>8} {'N':>4} {'rtol':>7} {'imposed':>9} {'residual':>9} {'rho':>12} {'rho periodic':>12}")
    text = study.run_to_table(table_path, lambda r: print0(
        f"  {float(r['q']):8.5f} {int(r['N']):4d} {float(r['rtol']):7.0e} {float(r['imposed']):9.1e} "
        f"{float(r['residual']):9.1e} {float(r['rho']):12.8f} {float(r['rho_periodic']):12.8f}"))
    records = study.store.records
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        print("wrote " + plotting.plot_driven_wave_ends(records, figures).path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
