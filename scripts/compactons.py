#!/usr/bin/env python3
"""Compactons of section 3.3 built from the branch and verified on the lattice (eqs. extens, extens2, twlin,
compacton, defvit, 2compacton); fig. graphulin and space-time plots.

    mpiexec -n 2 python scripts/compactons.py -branches results/branch_alpha1.5.npz,runs/branch_K4000.npz \
        -q 7*pi/25,pi/10 -output results/compactons.md -figures figures

For every branch file and every q (<= q_k) it builds the single compacton U_q and the 2-compacton
U^(2)_{q, theta}, checks eq. ad on the extended grid, then puts each on a free-ended chain, -margin beads of rest
behind it and enough ahead for all of it to pass -travel beads at velocity -c, integrates with the chain TS and
measures what the paper asserts: beads ahead exactly at rest, arrival on time, speed c, shift 2 pi a p, gaps
Delta = a p q and rest behind, unchanged profile (hertzpetsc.compacton.lattice_checks). The table is rewritten
after every case; the figures come from the first branch and the first q. -theta is the extra phase between the
two compactons (theta = q d, d >= min(0, 2 - F(q)) beads; the paper's fig. graphulin uses 2); -c the velocity in
beads per unit time (it fixes the amplitude a = (c q)^(2/(alpha-1))).
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.branch import Branch  # noqa: E402
from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs, write_text  # noqa: E402
from hertzpetsc.studies.base import run_to_table  # noqa: E402
from hertzpetsc.studies.compactons import CompactonStudy  # noqa: E402


def main():
    opts = AppOptions(__doc__, CompactonStudy.ROLES)
    paths = opts.path("branches", "results/branch_alpha1.5.npz", "branch files (comma-separated)")
    qs = opts.numbers("q", "7*pi/25,pi/10", "wavenumbers, each <= q_k", valid=(lambda q: q > 0, "> 0"),
                      distinct=True)
    theta = opts.real("theta", 2.0, "phase between the two compactons")
    c = opts.real("c", 1.0, "velocity in beads per unit time", valid=(lambda x: x > 0, "> 0 beads per unit time"))
    margin = opts.integer("margin", 10, "beads at rest behind the train", minimum=2)
    travel = opts.integer("travel", 100, "beads the whole train travels", minimum=5, maximum=10 ** 7)
    dt = opts.real("dt_snapshot", 0.05, "time between snapshots", valid=(lambda x: x > 0, "> 0"))
    output, figures = opts.table_and_figures("runs/compactons.md", "graphulin.png and the space-time plots")
    opts.done()
    comm = PETSc.COMM_WORLD
    files = [p for p in paths.split(",") if p.strip()]
    if not files:
        raise ParameterError("-branches", paths, "must name at least one branch file")
    prepare_outputs(comm, output, figures=figures)
    study = CompactonStudy([Branch.load(p, comm) for p in files], qs, comm, theta, c, margin, travel, dt)
    opts.check_unused()
    rank0 = comm.getRank() == 0

    def show(case):
        print0(case.row())
        write_text(output, study.table(), comm)          # a killed run leaves the table of its cases
        first = case.train.q == study.branches[0].point(qs[0]).q and case.h == study.branches[0].h
        if figures and rank0 and first:
            from hertzpetsc import plotting
            name = "compacton_spacetime.png" if case.train.count == 1 else "compacton2_spacetime.png"
            plotting.plot_spacetime_velocities(case.times, case.states, figures, name,
                                               f"q = {case.train.q:.4f}, {case.train.count} compacton(s), c = {c:g}")
            if case.train.count == 2:
                plotting.plot_compacton_profiles(study.cases[-2].train, case.train, figures)
    run_to_table(study, output, show)                    # on a stop: the table of the cases done
    print0(f"wrote {output}")


if __name__ == "__main__":
    guarded_main(main)
