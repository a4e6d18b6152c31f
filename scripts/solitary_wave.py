#!/usr/bin/env python3
"""The unit-velocity solitary wave and k_alpha (paper appendix), with convergence in the grid step and the
domain length.

    mpiexec -n 2 python scripts/solitary_wave.py [-alphas 1.5,2,2.5] [-cells 10,20,40,80,160] [-lengths 5,6,7,8,10]
        [-half_length 8] [-output runs/solitary.md] [-figures figures]

For each alpha: k_alpha on grids delta = 1/n (n in -cells) at L = -half_length, the observed order and the Richardson
extrapolation (h^2); and k_alpha for L in -lengths at the finest n. Figure ondesol.png: r(s) and y(s) for the
first alpha on the finest grid.
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.base import run_to_table  # noqa: E402
from hertzpetsc.studies.solitary import SolitaryStudy  # noqa: E402


def main():
    opts = AppOptions(__doc__, SolitaryStudy.ROLES)
    alphas = opts.numbers("alphas", "1.5,2,2.5", "Hertz exponents", expr=False, valid=(lambda a: a > 1, "> 1"),
                          distinct=True)
    cells = opts.numbers("cells", "10,20,40,80,160", "grids n (delta = 1/n, even), at least three, all different",
                         expr=False, kind=int, valid=(lambda n: 2 <= n <= 10 ** 5 and n % 2 == 0,
                                                      "an even integer in [2, 1e5]"),
                         distinct=True, minimum_count=3)
    lengths = opts.numbers("lengths", "5,6,7,8,10", "half-lengths L of the domain study", expr=False,
                           valid=(lambda L: 3 <= L <= 1000, "in [3, 1000]"), distinct=True)
    half_length = opts.real("half_length", 8.0, "the domain [-L, L] of the grid study (alpha near 1 has a slow tail: "
                            "larger L)", valid=(lambda L: 3 <= L <= 1000, "in [3, 1000]"))
    output, figures = opts.table_and_figures("runs/solitary.md", "ondesol.png")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, output, figures=figures)
    study = SolitaryStudy(alphas, cells, lengths, comm, half_length)
    opts.check_unused()
    run_to_table(study, output, lambda alpha: print0("\n".join(study.section(alpha))))    # on a stop: alphas done
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        print("wrote " + plotting.plot_solitary(study.finest[alphas[0]], figures).path, flush=True)
    print0(f"wrote {output}")


if __name__ == "__main__":
    guarded_main(main)
