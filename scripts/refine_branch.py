#!/usr/bin/env python3
"""E(q) along the branch before and after Gauss-Newton refinement on a periodic chain (paper section 3.4).

    mpiexec -n 2 python scripts/refine_branch.py -branch results/branch_alpha1.5.npz [-N 100] [-tol 1e-10]
        [-q 3*pi/10,7*pi/25] [-method symmetric|full] [-output runs/refined_N100.npz] [-table runs/refinement_table_N100.md]
        [-figures figures] [-resume | -force]

For every branch point whose q = 2 pi m / N fits the chain (or the listed -q): E(q) of the interpolated branch
wave with the paper's flow (rtol 1e-12, atol 1e-14) and with the tight flow (rtol 1e-14, atol 1e-16) used for
refinement; Gauss-Newton refinement to E <= tol (or, where the iteration stops above tol, to the tight flow's
floor: E within tol plus that flow's own error at the refined state, marked in the table); E(q) of the refined state
with both flows; r(q). -method symmetric (default) refines on the wave's cell of N/gcd(m,N) beads over its shortest
time symmetry (the state is then exactly invariant under it), each q on one rank and the q dealt to the ranks; full
is the paper's Gauss-Newton on the whole chain over script-T. The refined states are written after each q
(-resume skips the q already in -output). Figure: errors.png (fig. errors).
"""
import math
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.branch import Branch  # noqa: E402
from hertzpetsc.resources import MAX_DENSE_BEADS  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.refinement import RefinedStates, RefinementScan  # noqa: E402


def main():
    opts = AppOptions(__doc__, RefinementScan.ROLES)
    branch_path = opts.path("branch", "results/branch_alpha1.5.npz", "branch file")
    N = opts.integer("N", 100, "beads of the periodic chain", minimum=3, maximum=MAX_DENSE_BEADS)
    tol = opts.real("tol", 1e-10, "target E(q) of the refinement", valid=(lambda x: x > 0, "> 0"))
    qs = opts.numbers("q", "", "wavenumbers to refine (default: every branch q with N q / (2 pi) integer)",
                      valid=(lambda q: q > 0, "> 0"), distinct=True, minimum_count=0)
    method = opts.string("method", "symmetric", "symmetric (the wave's cell over its time symmetry) or full "
                         "(all N beads over script-T)", choices=("symmetric", "full"))
    output, mode, table_path, figures = opts.record_table_figures(
        f"runs/refined_N{N}.npz", "refinement file", f"runs/refinement_table_N{N}.md", "errors.png")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path, figures=figures)
    scan = RefinementScan(Branch.load(branch_path, comm), branch_path, N, comm, output, mode, qs, tol,
                           symmetric=method == "symmetric")
    opts.check_unused()
    scan.open()
    print0(f"# N = {N}, alpha = {scan.branch.alpha}, {len(scan.qs)} wavenumbers, target E <= {tol:g}")
    print0(f"# {'q':>8} {'E before':>10} {'E after':>10} {'its':>4} {'jac':>4} {'time':>6}")
    scan.run_to_table(table_path, lambda r: print0(      # on a stop: the table of the records done
        f"  {r['q']:8.5f} {r['E_before']:10.2e} {r['E_after']:10.2e} {r['iterations']:4d} "
        f"{r['jacobians']:4d} {r['wall_time']:6.1f}" + ("" if math.isnan(r["E_after_floor"]) else
                                                         f"  at the flow's floor {r['E_after_floor']:.1e}")))
    refined = RefinedStates.load(output, comm)
    floor = ~np.isnan(refined.column("E_after_floor"))
    print0(f"max E after refinement: {refined.column('E_after').max():.2e} (tight flow)"
           + (f"; at the flow's floor at q = {', '.join(f'{q:.4f}' for q in refined.q[floor])}" if floor.any() else "")
           + f"; wrote {output}, {table_path}")
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        print("wrote " + plotting.plot_errors(refined, figures).path, flush=True)


if __name__ == "__main__":
    guarded_main(main)
