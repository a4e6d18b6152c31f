#!/usr/bin/env python3
"""The long-wave limit (paper section 3.2): the computed branch against the solitary-wave inner solution and
the composite approximation (eq. solapprox); the rescaled norm ||u||_inf q^(2/(alpha-1)) against k_alpha.

    python scripts/long_wave.py [-branch results/branch_alpha1.5.npz] [-cells_per_unit 160] [-window 0.1]
        [-output runs/long_wave.md] [-figures figures]

Errors are relative to k_alpha: over the period, and over |xi - pi| <= window (the paper: agreement in a domain
of width ~0.2 around pi). Figures approxz.png (zoom near pi, with the inner solution) and approx.png (the
composite over the period) at the smallest q of the branch.
"""
import math
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.branch import Branch  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs, write_text  # noqa: E402
from hertzpetsc.studies.longwave import LongWaveStudy  # noqa: E402


def main():
    opts = AppOptions(__doc__, LongWaveStudy.ROLES)
    branch_path = opts.path("branch", "results/branch_alpha1.5.npz", "branch file")
    n = opts.integer("cells_per_unit", 160, "grid of the solitary wave (delta = 1/n, even)", minimum=2,
                     maximum=10 ** 5)
    window = opts.real("window", 0.1, "half-width of the window around pi", valid=(lambda x: 0 < x < math.pi,
                                                                                  "in (0, pi)"))
    output, figures = opts.table_and_figures("runs/long_wave.md", "approxz.png and approx.png")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, output, figures=figures)
    study = LongWaveStudy(Branch.load(branch_path, comm), n, window)
    opts.check_unused()
    text = study.table()
    write_text(output, text, comm)
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        for fig in plotting.plot_long_wave(study.wave, study.smallest, figures):
            print("wrote " + fig.path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
