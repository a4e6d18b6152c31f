#!/usr/bin/env python3
"""Floquet stability of the precompressed travelling waves in the (q, A) plane, on a periodic chain.

    mpiexec -n 2 python scripts/precompression_map.py [-alpha 1.5] [-delta0 1] [-N 100] [-epsilon 1]
        [-m 10,12,14,15,16,18,20,22,24,25]
        [-a 0.1,0.3,0.5,0.7,1,1.5,2,3,5,10,20,30,50,100,1000] [-cells_per_pi 1000] [-rtol 1e-11]
        [-tol_rho 1e-4] [-output results/precompression_map.npz] [-table results/precompression_map.md]
        [-figures figures] [-resume | -force]

For q = 2 pi m / N and each amplitude a (first sine coefficient of u): the wave from the Richardson combination
of the h = pi/K and pi/(2K) amplitude continuations, put on the N-bead chain of the precompressed law, and all 2N
Floquet multipliers modulo shift (dense monodromy S R(script-T; 0)); plus the uncompressed limit A = inf. With
-epsilon != 1 the chain is the dimer (masses 1, epsilon), the waves its acoustic ones at that mass ratio (natural
continuation in a from the linear wave) and S the shift by one cell. Table:
rho - 1 per (q, a) (U: unstable, rho - 1 > tol_rho). Figure: precompression_map.png. Solver prefixes: -floquet_
(the variational flow, -floquet_ts_*), -precomp_ (the wave solves).
"""
import math
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.chain import IntegrationTolerances  # noqa: E402
from hertzpetsc.model import LatticeModel  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs, write_text  # noqa: E402
from hertzpetsc.studies.precompression import MapParameters, StabilityMap  # noqa: E402

ROLES = StabilityMap.ROLES


def main():
    opts = AppOptions(__doc__, ROLES)
    alpha = opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda x: x > 1, "> 1"))
    delta0 = opts.real("delta0", 1.0, "precompression (static overlap)", valid=(lambda x: x > 0, "> 0"))
    N = opts.integer("N", 100, "beads of the periodic chain", minimum=3)
    epsilon = opts.real("epsilon", 1.0, "mass of every second bead (1: monatomic chain; else the dimer's acoustic "
                        "waves)", valid=(lambda x: x > 0, "> 0"))
    ms = opts.numbers("m", "10,12,14,15,16,18,20,22,24,25", "wavelengths on the chain (q = 2 pi m / N)", kind=int,
                      valid=(lambda m: 1 <= m <= N // 2, f"in [1, N/2]"), distinct=True)
    amps = opts.numbers("a", "0.1,0.3,0.5,0.7,1,1.5,2,3,5,10,20,30,50,100,1000", "amplitudes (first sine coefficient of u)",
                        valid=(lambda x: x > 0, "> 0"), distinct=True)
    K = opts.integer("cells_per_pi", 1000, "coarser grid of the Richardson pair (h = pi/K and pi/2K)", minimum=4)
    rtol = opts.real("rtol", 1e-11, "flow tolerance (atol = rtol/100)", valid=(lambda x: 0 < x < 1, "in (0, 1)"))
    tol_rho = opts.real("tol_rho", 1e-4, "unstable when rho - 1 > tol_rho", valid=(lambda x: x > 0, "> 0"))
    output, mode, table_path, figures = opts.record_table_figures(
        "results/precompression_map.npz", "stability-map file", "results/precompression_map.md",
        "precompression_map.png")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path, figures=figures)
    qs = [2 * math.pi * m / N for m in ms]
    masses = (1.0,) if epsilon == 1.0 else (1.0, epsilon)
    study = StabilityMap(MapParameters(LatticeModel.hertz(alpha, masses, delta0), qs, amps, N, K,
                                       IntegrationTolerances(rtol=rtol, atol=rtol / 100), tol_rho), comm, output, mode)
    study.configure()
    opts.check_unused()
    study.open()
    print0(f"# N = {N}, alpha = {alpha:g}, delta0 = {delta0:g}, h = pi/{K} and pi/{2 * K}, rtol {rtol:g}")
    print0(f"# {'q':>8} {'a':>8} {'A':>10} {'rho - 1':>10} {'outside':>7} {'trivial':>8} {'s':>6}")
    for r in study.run():
        print0(f"  {r['q']:8.5f} {r['a']:8.4g} {r['A']:10.4g} {r['rho'] - 1:10.3e} {r['outside']:7d} "
               f"{r['trivial_spread']:8.1e} {r['seconds']:6.1f}")
    text = study.table()
    study.destroy()
    write_text(table_path, text, comm)
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        print("wrote " + plotting.plot_precompression_map(*study.grid_values(), tol_rho, figures), flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
