#!/usr/bin/env python3
"""Floquet multipliers modulo shifts on long chains, N = 1000 and 10^4 (section 3.5), by Bloch sectors.

    mpiexec -n 2 python scripts/floquet_long.py [-sizes 1000,10000] [-q 7*pi/25,9*pi/50,pi/50,3*pi/10]
        [-refined results/refined_N100.npz] [-branch results/branch_alpha1.5.npz] [-nev 10] [-tol_rho 1e-4]
        [-slepc_sizes 1000] [-split sectors|beads] [-reference results/floquet_N100.npz]
        [-output runs/floquet_long.md] [-npz runs/floquet_long.npz] [-resume | -force]

The wave on N = L * 100 beads at q = 2 pi m / 100 is the refined 100-bead wave tiled L times. All 2N multipliers
come from the L//2 + 1 Bloch sectors of the 100-bead cell (hertzpetsc.bloch, one TS run of 200 complex tangent
columns each, sectors dealt to the ranks); then, on the full N-bead chain and matrix-free (shell distributed
over the ranks): the residuals ||F Y - lambda Y|| / (|lambda| ||Y||) of the tiled Bloch modes of the nev dominant
multipliers, and for N in -slepc_sizes (default none: at N = 1000 it did not converge in 13 min) SLEPc
Krylov-Schur started from those modes. rho excludes the four trivial multipliers (sector theta = 0); "outside"
counts |lambda| > 1 + tol_rho over all 2N multipliers. -reference: a Floquet scan file whose rho(N = 100) the
table quotes. Flow tolerances: the paper's (rtol 1e-12, atol 1e-14; -floquet_ts_rtol / -floquet_ts_atol
override). Records go to -npz as they are computed (-resume continues).
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
import slepc4py  # noqa: E402

slepc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.branch import Branch  # noqa: E402
from hertzpetsc.chain import IntegrationTolerances  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import on_rank0, prepare_output  # noqa: E402
from hertzpetsc.studies.floquet import BlochScan, floquet_reference, q_label  # noqa: E402
from hertzpetsc.studies.refinement import RefinedStates  # noqa: E402


def main():
    opts = AppOptions(__doc__, BlochScan.ROLES)
    branch_path = opts.path("branch", "results/branch_alpha1.5.npz", "branch file")
    refined_path = opts.path("refined", "results/refined_N100.npz", "refinement file of the cell")
    sizes = opts.numbers("sizes", "1000,10000", "chain lengths N (multiples of the cell)", expr=False, kind=int,
                         valid=(lambda n: 0 < n <= 10 ** 7, "in [1, 1e7]"), distinct=True)
    qs = opts.numbers("q", "7*pi/25,9*pi/50,pi/50,3*pi/10", "wavenumbers (refined on the cell)",
                      valid=(lambda q: q > 0, "> 0"), distinct=True)
    nev = opts.integer("nev", 10, "dominant multipliers checked on the full chain", minimum=1)
    tol_rho = opts.real("tol_rho", 1e-4, "outside the circle: |lambda| > 1 + tol_rho", valid=(lambda x: x > 0, "> 0"))
    slepc_sizes = opts.numbers("slepc_sizes", "", "N on which to run seeded SLEPc", expr=False, kind=int,
                               valid=(lambda n: n > 0, "> 0"), minimum_count=0)
    split = opts.string("split", "sectors", "sectors dealt to ranks, or each sector over all ranks",
                        choices=("sectors", "beads"))
    reference = opts.path("reference", "results/floquet_N100.npz", "Floquet scan quoted for rho(N = 100), or 'none'")
    output = opts.path("output", "runs/floquet_long.md", "table")
    npz = opts.path("npz", "runs/floquet_long.npz", "Bloch records (record store)")
    mode = opts.mode()
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_output(output, comm)
    refined = RefinedStates.load(refined_path, comm)
    branch = Branch.load(branch_path, comm)
    refined.check_alpha(branch.alpha)
    quoted = (on_rank0(comm, floquet_reference, reference, branch.alpha, refined.N, what="cannot read -reference")
              if reference != "none" else {})
    scan = BlochScan(branch, refined, sizes, qs, comm, npz, mode, nev, tol_rho, slepc_sizes, split,
                     IntegrationTolerances(), quoted)
    opts.check_unused()
    scan.open()
    print0(f"# cell M = {scan.M}, ranks {comm.getSize()}, split {split}, nev {nev}")

    def show(item):
        r, e = item
        sl = e["slepc"]
        print0(f"  N {r['N']:6d} q {q_label(r['q']):>8} rho {r['rho']:.8f} (cell {r['rho_cell']:.8f}) outside "
               f"{r['outside']:5d} bloch {r['seconds']:7.1f} s ({e['runs']} runs), residual {r['residual']:.1e} "
               f"({e['res_products']} products, {e['t_res']:.1f} s)"
               + (f", SLEPc {sl['products']} products {sl['seconds']:.1f} s, |diff| {sl['dist']:.1e}" if sl else ""))
    text = scan.run_to_table(output, show, lambda: scan.table(comm.getSize()))    # on a stop: the records done
    scan.destroy()
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
