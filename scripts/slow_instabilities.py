#!/usr/bin/env python3
"""Slow instabilities above q_c on the infinite chain (the paper's closing question): gamma(q) by the co-moving
QEP and by the deflated monodromy of the refined waves.

    mpiexec -n 2 python scripts/slow_instabilities.py [-branch results/branch_alpha1.5.npz] [-N 100]
        [-refined results/refined_N100.npz | none] [-q_min 0.9] [-q 3*pi/10,...] [-grids 1000,2000,4000]
        [-n_theta 41] [-n_twist 3] [-refine_tol 1e-12] [-rtol 1e-14] [-theta_longwave 0.05] [-target 1e-9]
        [-validate 7*pi/25,9*pi/50,pi/50] [-reference results/floquet_N100.npz] [-convergence_q 3*pi/10,2*pi/5]
        [-output runs/slow_instabilities.npz] [-table runs/slow_instabilities.md] [-figures figures]
        [-resume | -force]

For every branch q >= q_min (or the listed -q): the co-moving route (theta in [0, pi] on h = pi/grids[0], the
worst mode on the finer grids, Richardson), and for the q = 2 pi m / N also the monodromy route (the wave refined
on its cell over its short time symmetry with the tight flow, -n_twist cell twists, the symmetry multipliers
deflated exactly); the verdict per q (slowly unstable with gamma, or stable within the stated resolution), and the
long-wave slope against the 2x2 Whitham prediction; then the co-moving route's validation at the unstable -validate
q against rho(F_q) of -reference, and the monodromy route at -convergence_q against the orbit's residual and the
flow's tolerance (both appended to the table; computed on every run, on rank 0). Records are written
after each q (-resume continues).
Figure: slow_instabilities.png (gamma(q) on a log scale with the target resolution drawn; -figure_name renames it).
"""
import math
import os
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
import slepc4py  # noqa: E402

slepc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.branch import Branch  # noqa: E402
from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.resources import MAX_DENSE_BEADS  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.slow import TARGET, SlowInstabilities, SlowInstabilityScan  # noqa: E402


def main():
    opts = AppOptions(__doc__, SlowInstabilityScan.ROLES)
    branch_path = opts.path("branch", "results/branch_alpha1.5.npz", "branch file")
    N = opts.integer("N", 100, "beads of the periodic chain of the monodromy route", minimum=3,
                     maximum=MAX_DENSE_BEADS)
    refined_path = opts.path("refined", "none", "refinement file to start the refinement from, or 'none' (branch wave)")
    q_min = opts.real("q_min", 0.9, "smallest branch q scanned (without -q)", expr=True,
                      valid=(lambda q: 0 < q <= math.pi, "in (0, pi]"))
    qs = opts.numbers("q", "", "branch wavenumbers (default: every branch q >= q_min)", valid=(lambda q: q > 0, "> 0"),
                      distinct=True, minimum_count=0)
    grids = opts.numbers("grids", "1000,2000,4000", "K of the co-moving grids h = pi/K (>= 3, doubling)", kind=int,
                         expr=False, valid=(lambda k: k >= 8, ">= 8"))
    n_theta = opts.integer("n_theta", 41, "Bloch parameters of the co-moving scan in [0, pi]", minimum=2)
    n_twist = opts.integer("n_twist", 3, "cell twists of the monodromy route in [0, pi] (0: co-moving only)",
                           minimum=0)
    refine_tol = opts.real("refine_tol", 1e-12, "target E of the refinement", valid=(lambda x: x > 0, "> 0"))
    rtol = opts.real("rtol", 1e-14, "relative tolerance of the flows of the refinement and of the sector maps "
                     "(atol = rtol / 100)", valid=(lambda x: 1e-16 <= x <= 1e-6, "in [1e-16, 1e-6]"))
    theta_lw = opts.real("theta_longwave", 0.05, "theta of the long-wave slope", valid=(lambda x: 0 < x < 0.5,
                                                                                         "in (0, 0.5)"))
    target = opts.real("target", TARGET, "target resolution per unit time", valid=(lambda x: x > 0, "> 0"))
    validate = opts.numbers("validate", "7*pi/25,9*pi/50,pi/50", "unstable chain q where the co-moving route is "
                            "checked against -reference (none if empty)", valid=(lambda q: q > 0, "> 0"),
                            distinct=True, minimum_count=0)
    reference = opts.path("reference", "results/floquet_N100.npz", "Floquet file with rho(F_q) on N beads, or "
                          "'none' (no validation)")
    convergence = opts.numbers("convergence_q", "3*pi/10,2*pi/5", "chain q of the orbit-residual and flow-tolerance "
                               "study of the monodromy route (none if empty)", valid=(lambda q: q > 0, "> 0"),
                               distinct=True, minimum_count=0)
    figure_name = opts.path("figure_name", "slow_instabilities.png", "file name of the figure")
    from matplotlib.figure import Figure
    formats = Figure().canvas.get_supported_filetypes()
    if os.path.splitext(figure_name)[1].lstrip(".").lower() not in formats:
        raise ParameterError("-figure_name", figure_name, "must end in a figure format: ."
                             + ", .".join(sorted(formats)))
    output, mode, table_path, figures = opts.record_table_figures(
        "runs/slow_instabilities.npz", "slow-instability file", "runs/slow_instabilities.md", figure_name)
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path, figures=figures)
    branch = Branch.load(branch_path, comm)
    study = SlowInstabilities(branch, branch_path, N, comm, output, mode, qs, q_min, refined_path, convergence,
                              validate, reference, refine_tol, rtol, n_twist, grids=grids, n_theta=n_theta,
                              target=target, theta_longwave=theta_lw)
    scan = study.scan
    opts.check_unused()
    scan.open()
    print0(f"# alpha = {branch.alpha}, {len(scan.qs)} q, grids {grids}, n_theta {n_theta}, n_twist {n_twist}")
    print0(f"# {'q':>8} {'m':>3} {'gamma cm (K0..)':>30} {'gamma mono':>10} {'raw cluster':>11} {'E':>8} "
           f"{'verdict':>7} {'s':>6}")

    def show(r):
        g = " ".join(f"{v:9.1e}" for v in r["gamma_cm"])
        print0(f"  {r['q']:8.5f} {r['m']:3d} {g:>30} {r['gamma_mono']:10.1e} {r['raw_cluster_mono']:11.1e} "
               f"{r['E_orbit']:8.1e} {r['verdict']:7d} {r['seconds']:6.1f}")
    text = study.run_to_table(table_path, show)        # the scan, then the checks appended to its table
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        print("wrote " + plotting.plot_slow_instabilities(scan.store.records, target, branch.alpha, figures,
                                                          figure_name).path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
