#!/usr/bin/env python3
"""Travelling waves of the precompressed dimer chain (masses 1, epsilon), continued in epsilon from 1.

    mpiexec -n 2 python scripts/dimer_branch.py [-alpha 1.5] [-delta0 1] [-q 3*pi/10] [-a 0.5]
        [-cells_per_pi 200] [-epsilon_end 0.3] [-max_steps 200] [-ds 0.02] [-ds_max 0.1]
        [-output runs/dimer.npz] [-table runs/dimer.md] [-figures figures] [-resume | -force]

Per-bead wavenumber q, one odd profile per bead of the cell (u: mass 1, v: mass epsilon), fixed amplitude a (first
sine coefficient of u). From the monatomic wave at epsilon = 1 (two natural steps), pseudo-arclength in
(u, v, lam, epsilon) through folds in epsilon, until epsilon passes epsilon_end or max_steps. Table: epsilon
reached, omega at both ends, ||v|| / ||u||, folds. Figure: dimer_epsilon.png.

-beads is refused: the continuation varies the second bead's mass epsilon, which no pattern of beads (one mass
ratio) does; the waves of a dimer of given beads (e.g. steel,brass) in SI units are scripts/wave.py's and
scripts/precompressed_branch.py's -beads.
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.model import LatticeModel, law_options  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.precompression import DimerFamilies, DimerParameters  # noqa: E402
from hertzpetsc.units import bead_options  # noqa: E402


def main():
    opts = AppOptions(__doc__, DimerFamilies.ROLES)
    alpha = opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda x: x > 1, "> 1"))
    law_options(opts, supported=False)      # -law: refused but hertz
    delta0 = opts.real("delta0", 1.0, "precompression (static overlap)", valid=(lambda x: x > 0, "> 0"))
    p = opts.parameters(DimerParameters, q="3*pi/10")
    output, mode, table_path, figures = opts.record_table_figures(
        "runs/dimer.npz", "dimer file", "runs/dimer.md", "dimer_epsilon.png")
    bead_options(opts, refused="this driver continues the mass ratio epsilon from 1, which no pattern of beads does "
                 "(one ratio): the waves of a dimer of given beads in SI units are scripts/wave.py -beads steel,brass "
                 "and scripts/precompressed_branch.py -beads steel,brass")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path, figures=figures)
    study = DimerFamilies(DimerParameters(LatticeModel.hertz(alpha, delta0=delta0), **p), comm, output, mode)
    study.configure()
    opts.check_unused()
    study.open()
    print0(f"# alpha = {alpha:g}, delta0 = {delta0:g}, a = {p['a']:g}, h = pi/{p['cells_per_pi']}")
    print0(f"# {'q':>8} {'epsilon':>9} {'omega':>10} {'||v||/||u||':>11} {'d eps/ds':>10}")
    text = study.run_to_table(table_path, lambda r: print0(
        f"  {r['q']:8.5f} {r['epsilon']:9.5f} {r['omega']:10.6f} {r['norm_v'] / r['norm_u']:11.4f} "
        f"{r['tangent_epsilon']:10.2e}"))
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        print("wrote " + plotting.plot_dimer_epsilon(study.curves(), figures).path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
