#!/usr/bin/env python3
"""Floquet multipliers modulo shifts along the branch (paper section 3.5, figs. floquet and eigen).

    mpiexec -n 2 python scripts/floquet_scan.py [-refined results/refined_N100.npz] [-branch ...] [-N 100]
        [-q 3*pi/10,7*pi/25] [-method symmetric|dense|slepc] [-nev 10] [-tol_rho 1e-4] [-check_q 9*pi/50]
        [-output runs/floquet_N100.npz] [-table runs/floquet_table_N100.md] [-figures figures]
        [-resume | -force]

Around the refined waves of -refined: rho(F_q) without the four trivial multipliers (translation, time shift,
Jordan partners), the number of multipliers with |lambda| > 1 + tol_rho, the spread of the trivial ones, the
growth rate ln(rho)/script-T; then q_c (the largest q with rho - 1 > tol_rho, bracketed by its stable neighbour)
and q_m (max rho). Verdicts only from the waves they claim: a -q not in the refinement file is an error; without
-q the scan covers the refined q (and says so when that is not every branch q); -refined none scans the
unrefined branch waves. tol_rho: an O(eps) error in the orbit splits double multipliers (the trivial Jordan
blocks, Krein collisions) by O(sqrt(eps)); with eps ~ 1e-10 (refined E plus the flow's error) that is ~1e-5, and
tol_rho = 1e-4 keeps a factor 10. -check_q: rho(Phi_q) of the full-period monodromy against rho(F_q)^(N/m).
Routes: symmetric (default; all 2N multipliers from the wave's cell of N/gcd(m,N) beads over its shortest time
symmetry, by Bloch sectors, each q on one rank and the q dealt to the ranks: hertzpetsc.symmetry), dense (LAPACK
dgeev on the assembled F_q, the paper's route) and slepc (Krylov-Schur on the shell operator, the nev dominant).
"""
import math
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
import slepc4py  # noqa: E402

slepc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.branch import Branch  # noqa: E402
from hertzpetsc.resources import MAX_DENSE_BEADS  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.roles import FLOQUET_ROUTES  # noqa: E402
from hertzpetsc.studies.floquet import FloquetScan  # noqa: E402
from hertzpetsc.studies.refinement import RefinedStates  # noqa: E402

EIGEN_Q = (("3pi/10", 3 * math.pi / 10), ("7pi/25", 7 * math.pi / 25), ("9pi/50", 9 * math.pi / 50),
           ("pi/50", math.pi / 50))


def main():
    opts = AppOptions(__doc__, FloquetScan.ROLES)
    branch_path = opts.path("branch", "results/branch_alpha1.5.npz", "branch file")
    N = opts.integer("N", 100, "beads of the periodic chain", minimum=3, maximum=MAX_DENSE_BEADS)
    refined_path = opts.path("refined", f"results/refined_N{N}.npz", "refinement file, or 'none' for the "
                             "unrefined branch waves")
    qs = opts.numbers("q", "", "wavenumbers (default: every refined q)", valid=(lambda q: q > 0, "> 0"),
                      distinct=True, minimum_count=0)
    method = opts.string("method", "symmetric", "symmetric or dense (all 2N), slepc (the nev dominant)",
                         choices=FLOQUET_ROUTES)
    nev = opts.integer("nev", 10, "multipliers of the slepc route", minimum=1, maximum=2 * N)
    tol_rho = opts.real("tol_rho", 1e-4, "unstable when rho - 1 > tol_rho", valid=(lambda x: x > 0, "> 0"))
    check_q = opts.real("check_q", 9 * math.pi / 50, "q of the rho(Phi_q) = rho(F_q)^(N/m) check", expr=True)
    output, mode, table_path, figures = opts.record_table_figures(
        f"runs/floquet_N{N}.npz", "Floquet file", f"runs/floquet_table_N{N}.md", "floquet.png and eigen.png")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path, figures=figures)
    refined = None if refined_path == "none" else RefinedStates.load(refined_path, comm)
    scan = FloquetScan(Branch.load(branch_path, comm), N, comm, output, mode, refined, qs, method, nev, tol_rho)
    opts.check_unused()
    scan.open()
    print0(f"# N = {N}, method {method}, tol_rho = {tol_rho:g}; waves: {scan.restriction}")
    print0(f"# {'q':>8} {'rho(F_q)':>12} {'outside':>7} {'trivial spread':>14} {'state':>8} {'s':>6}")
    text = scan.run_to_table(table_path, lambda r: print0(       # on a stop: the table of the records done
        f"  {r['q']:8.5f} {r['rho']:12.8f} {r['outside']:7d} {r['trivial_spread']:14.2e} "
        f"{'refined' if r['refined'] else 'branch':>8} {r['seconds']:6.1f}"), lambda: scan.table(check_q))
    scan.destroy()
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        q = [float(r["q"]) for r in scan.store.records]
        rho = [float(r["rho"]) for r in scan.store.records]
        print("wrote " + plotting.plot_floquet_radius(q, rho, tol_rho, figures).path, flush=True)
        print("wrote " + plotting.plot_multipliers(scan.eigen_panels(EIGEN_Q), figures).path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
