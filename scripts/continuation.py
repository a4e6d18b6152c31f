#!/usr/bin/env python3
"""Compute the travelling-wave branch q = pi -> q_stop (paper section 3.1) and its figures.

    mpiexec -n 2 python scripts/continuation.py [options]

Writes the branch file (-output) point by point; -resume continues it, -force overwrites it. Prints one line per
converged point on rank 0: q, Newton iterations, residual, ||u||_inf, N(q), script-T(q), sub-steps.
A grid that would not fit in memory is refused up front with an estimate (hertzpetsc.resources).
"""
import math
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.model import law_options  # noqa: E402
from hertzpetsc.qbranch import ContinuationParameters  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0, run_metadata  # noqa: E402
from hertzpetsc.progress import Progress  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.roles import uses  # noqa: E402
from hertzpetsc.studies.branch import BranchStudy  # noqa: E402


def main():
    opts = AppOptions(__doc__, uses("tw_", "sol_"))
    law_options(opts, supported=False)      # -law: refused but hertz
    params = ContinuationParameters(
        alpha=opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda a: a > 1, "> 1")),
        M=opts.integer("M", 50, "target wavenumbers q = m pi / M", minimum=1),
        cells_per_pi=opts.integer("cells_per_pi", 1000, "grid step h = pi / cells_per_pi", minimum=4),
        q_stop=opts.real("q_stop", None, "last wavenumber, in (0, pi] (default pi/M)", expr=True,
                         valid=(lambda q: 0 < q <= math.pi * (1 + 1e-14), "in (0, pi]")),
        max_halvings=opts.integer("max_halvings", 8, "step reductions allowed per target q", minimum=0),
        max_corrector=opts.real("max_corrector", 0.25, "relative change of the rescaled profile that makes a step "
                                "be rejected and halved", valid=(lambda x: x > 0, "> 0")))
    output = opts.path("output", "runs/branch.npz", "branch file, rewritten after every converged point")
    mode = opts.mode()
    figures = opts.path("figures", "", "directory for the figures of section 3.1 (none if empty)")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, figures=figures)
    study = BranchStudy(params, output, comm, mode, run_metadata(params=dict(alpha=params.alpha, M=params.M,
                        cells_per_pi=params.cells_per_pi, q_stop=params.q_stop), prefix="tw_"))
    opts.check_unused()
    k_alpha = None
    if figures:     # the line of figs. normes and pentes uses k_alpha of the solitary wave (eq. kal2)
        from hertzpetsc.solitary import SolitaryParameters, solve_solitary_wave
        k_alpha = solve_solitary_wave(SolitaryParameters(params.alpha, 80), PETSc.COMM_SELF).k_alpha
    study.open()
    if study.resumed:
        print0(f"resuming {output}: {study.resumed} points, last q = {study.branch.points[-1].q:.6f}")
    print0(f"# alpha = {params.alpha}, h = pi/{params.cells_per_pi}, M = {params.M}, ranks = {comm.getSize()}")
    print0(f"# {'q':>10} {'newton':>6} {'residual':>10} {'|u|_inf':>12} {'N(q)':>7} {'T(q)':>7} {'substeps':>8}")
    progress = Progress(study.planned(), "points", "branch", comm=comm)     # on a terminal: the time left
    for done, pt in enumerate(study.run(), 1):
        d = pt.diagnostics
        print0(f"  {pt.q:10.6f} {pt.solve.iterations:6d} {pt.solve.residual_norm:10.3e} "
               f"{d.norm_inf:12.6g} {d.N:7.4f} {d.T:7.4f} {pt.substeps:8d}")
        progress.update(done)
    if figures:
        from hertzpetsc import plotting
        if comm.getRank() == 0:
            for fig in plotting.plot_branch_figures(study.branch, figures, k_alpha):
                print(f"wrote {fig.path}", flush=True)
    print0(f"wrote {output}")


if __name__ == "__main__":
    guarded_main(main)
