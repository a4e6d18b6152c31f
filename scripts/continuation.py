#!/usr/bin/env python3
"""Compute the travelling-wave branch q = pi -> q_stop (paper section 3.1) and its figures.

    mpiexec -n 2 python scripts/continuation.py [options]

Application options (defaults reproduce the paper):
  -alpha 1.5            Hertz exponent (> 1)
  -M 50                 target wavenumbers q = m pi / M
  -cells_per_pi 1000    grid step h = pi / cells_per_pi
  -q_stop pi/M          last wavenumber (any value in (0, pi]; "pi/50" style expressions allowed)
  -max_halvings 8       step reductions allowed per target q
  -max_corrector 0.25   relative change of the rescaled profile that makes a step be rejected and halved
  -output branch.npz    branch file, rewritten after every converged point
  -resume               continue the branch stored in -output (which must exist and match the parameters)
  -figures DIR          write the figures of section 3.1 there (omit for none); the line of figs. normes and
                        pentes uses k_alpha of the solitary wave (hertzpetsc.solitary, -sol_ prefix)
PETSc prefixes: -tw_ for the travelling-wave SNES and its KSP/PC (e.g. -tw_snes_monitor, -tw_snes_type qn,
-tw_ksp_type gmres, -tw_pc_factor_mat_solver_type mumps); -log_view for timings.
  -tw_solver direct     linear solves: 'direct' (LU, MUMPS on several ranks) or 'nk' (Newton-Krylov: GMRES +
                        exact second-difference preconditioner, cost ~ linear in the grid size; for fine grids)
  -tw_jacobian shell    with nk: 'shell' (matrix-free) or 'aij' (assembled, for -tw_pc_type hypre/gamg/...)
A grid that would not fit in memory is refused up front with an estimate (hertzpetsc.resources).
Prints one line per converged point on rank 0: q, Newton iterations, residual, ||u||_inf.
"""
import os
import sys

import petsc4py

petsc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.branchfile import BranchWriter, read_branch  # noqa: E402
from hertzpetsc.cli import AppOptions, guarded_main, print0, run_metadata  # noqa: E402
from hertzpetsc.continuation import BranchContinuation, ContinuationParameters  # noqa: E402
from hertzpetsc.errors import BranchFileError, ParameterError  # noqa: E402


def read_parameters(opts):
    return ContinuationParameters(
        alpha=opts.real("alpha", 1.5),
        M=opts.integer("M", 50, minimum=1),
        cells_per_pi=opts.integer("cells_per_pi", 1000, minimum=4),
        q_stop=opts.real("q_stop", None, expr=True),
        max_halvings=opts.integer("max_halvings", 8, minimum=0),
        max_corrector=opts.real("max_corrector", 0.25, valid=(lambda x: x > 0, "must be > 0")),
    )


def check_resumable(branch, params, path):
    """The stored branch must have been computed with the same discretisation."""
    for name in ("alpha", "M", "cells_per_pi"):
        stored, wanted = branch[name], getattr(params, name)
        if abs(float(stored) - float(wanted)) > 1e-12 * abs(float(wanted)):
            raise ParameterError(f"-{name}", wanted, f"must equal the value {stored} stored in {path} to resume it")
    if len(branch["q"]) == 0:
        raise BranchFileError(f"branch file {path!r} holds no point to resume from")


def main():
    opts = AppOptions()
    params = read_parameters(opts)
    path = opts.string("output", "branch.npz")
    figures = opts.string("figures", "")
    resume = opts.flag("resume")
    comm = PETSc.COMM_WORLD
    rank0 = comm.getRank() == 0

    cont = BranchContinuation(params, comm)
    scalars = dict(alpha=params.alpha, cells_per_pi=params.cells_per_pi, h=params.h, M=params.M)
    existing = None
    if resume:
        existing = read_branch(path)
        check_resumable(existing, params, path)
        print0(f"resuming {path}: {len(existing['q'])} points, last q = {existing['q'][-1]:.6f}")
        cont.resume_from(existing["q"], existing["u"])
    meta = run_metadata(params=dict(vars(params)), prefix="tw_")
    writer = BranchWriter(path, scalars, cont.grid.xi_half(), meta, existing) if rank0 else None

    print0(f"# alpha = {params.alpha}, h = pi/{params.cells_per_pi}, M = {params.M}, ranks = {comm.getSize()}")
    print0(f"# {'q':>10} {'newton':>6} {'residual':>10} {'|u|_inf':>12} {'N(q)':>7} {'T(q)':>7} {'substeps':>8}")
    try:
        for pt in cont.points():
            if rank0:
                writer.append(pt.u_half, **pt.record())
            d = pt.diagnostics
            print0(f"  {pt.q:10.6f} {pt.solve.iterations:6d} {pt.solve.residual_norm:10.3e} "
                   f"{d['norm_inf']:12.6g} {d['N']:7.4f} {d['T']:7.4f} {pt.substeps:8d}")
    finally:
        cont.destroy()

    if figures and rank0:
        from hertzpetsc import plotting
        from hertzpetsc.errors import HertzPetscError
        from hertzpetsc.solitary import SolitaryParameters, solve_solitary_wave
        os.makedirs(figures, exist_ok=True)
        try:     # the line of figs. normes and pentes uses k_alpha of the solitary wave (eq. kal2)
            k_alpha = solve_solitary_wave(SolitaryParameters(params.alpha, 80, 8.0), PETSc.COMM_SELF).k_alpha
        except HertzPetscError as err:
            k_alpha = None
            print0(f"note: no k_alpha from the solitary wave ({err}); the figures use the branch estimate")
        for name in plotting.plot_branch_figures(read_branch(path), figures, k_alpha):
            print0(f"wrote {name}")
    print0(f"wrote {path}")


if __name__ == "__main__":
    guarded_main(main)
