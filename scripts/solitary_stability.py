#!/usr/bin/env python3
"""Spectral stability of solitary waves, uncompressed and precompressed, on a window that travels with them, against
the energy criterion (a change of sign of dH/dc signals a change of stability; Cuevas-Maraver et al., PRE 2017).

    mpiexec -n 2 python scripts/solitary_stability.py [-alphas 1.5,2,2.5] [-c0 0,0.2,...,0.9] [-M 0] [-tail 1e-12]
        [-output runs/solitary_stability.npz] [-table runs/solitary_stability.md] [-figures figures]
        [-resume | -force]

For each alpha the unit-speed solitary wave of eq. adr is refined on the window (Delta = 0) and continued in the
precompression through the sound speeds -c0 (units of the wave's speed: c / c0 is the Mach number; 0 is the
uncompressed chain, always computed first). Per point: the multipliers (LAPACK on the weighted window map), the
Jordan pair at 1, the weighted essential-spectrum radius and the point multipliers, the energy H and its slope
d ln H / d ln c at fixed lattice from the Jordan vectors and from H along the family, the same wave in the lattice
of precompression 1, and the truncation: the tails at the window's ends and the changes in a window of 2M beads.
-M 0 takes the fewest beads whose ends see the tails of the largest c0 at -tail. Each alpha runs on one rank; the
alphas of a continuation step are dealt to the ranks.
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.solitary_stability import (ROLES, SolitaryStabilityParameters,  # noqa: E402
                                                   SolitaryStabilityScan)


def main():
    opts = AppOptions(__doc__, ROLES)
    p = opts.parameters(SolitaryStabilityParameters)
    output, mode, table, figures = opts.record_table_figures(
        "runs/solitary_stability.npz", "solitary stability file", "runs/solitary_stability.md",
        "solitary_stability.png")
    opts.done()
    comm = PETSc.COMM_WORLD
    params = SolitaryStabilityParameters(**p)
    prepare_outputs(comm, table, figures=figures)
    scan = SolitaryStabilityScan(params, comm, output, mode)
    opts.check_unused()
    scan.open()
    print0(f"# M = {params.M}, tail {params.tail:g}; c0: " + ", ".join(f"{c:g}" for c in params.c0))
    print0(f"# {'alpha':>5} {'c0':>5} {'residual':>9} {'max|mu|':>9} {'r_ess':>9} {'unst':>4} {'dlnH/dlnc':>12} "
           f"{'FD':>12} {'2M chg':>8} {'s':>5}")
    try:                                         # on a stop: the table of the records done
        text = scan.run_to_table(table, lambda r: print0(
            f"  {r['alpha']:5g} {r['c0']:5g} {r['residual']:9.1e} {r['max_nontrivial']:9.6f} "
            f"{r['essential']:9.6f} {r['unstable']:4d} {r['log_slope']:12.8f} {r['log_slope_fd']:12.8f} "
            f"{r['doubling_change']:8.1e} {r['seconds']:5.1f}"), lambda: scan.summary() + "\n" + scan.table())
    finally:
        scan.destroy()
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        print("wrote " + plotting.plot_solitary_stability(scan.rows(), figures).path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
