#!/usr/bin/env python3
"""Convergence in the grid step h of the branch diagnostics (second-order scheme, section 3.1).

    mpiexec -n 2 python scripts/convergence_h.py [-alpha 1.5] [-M 50] [-cells 250,500,1000,2000,4000]
                                                  [-output runs/convergence_h.md]

Computes the branch q = pi -> pi/M on each grid h = pi/K, and for those of q = pi, 3pi/10, 7pi/25, 9pi/50, pi/50
that are on it (q = m pi / M) reports ||u||_inf, p(q), N(q), T(q) on each grid, the observed order
log2(|d_{h,h/2}| / |d_{h/2,h/4}|) on the three finest grids, and the Richardson extrapolation
X_{h/2} + (X_{h/2} - X_h)/3.
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.model import LatticeModel, law_options  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_output  # noqa: E402
from hertzpetsc.studies.branch import ConvergenceStudy  # noqa: E402


def main():
    opts = AppOptions(__doc__, ConvergenceStudy.ROLES)
    alpha = opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda a: a > 1, "> 1"))
    law_options(opts, supported=False)      # -law: refused but hertz
    M = opts.integer("M", 50, "target wavenumbers q = m pi / M", minimum=1)
    cells = opts.numbers("cells", "250,500,1000,2000,4000", "grids K (h = pi/K), at least three, all different",
                         expr=False, kind=int, valid=(lambda K: K >= 4, ">= 4"), distinct=True, minimum_count=3)
    output = opts.path("output", "runs/convergence_h.md", "table")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_output(output, comm)
    study = ConvergenceStudy(LatticeModel.hertz(alpha), M, cells, comm)
    opts.check_unused()
    print0(study.run_to_table(output, lambda K: print0(f"# branch on h = pi/{K} done")))   # on a stop: grids done


if __name__ == "__main__":
    guarded_main(main)
