#!/usr/bin/env python3
"""E(q) along the branch before and after Gauss-Newton refinement on a periodic chain (paper section 3.4).

    mpiexec -n 2 python scripts/refine_branch.py -branch results/branch_alpha1.5.npz [-N 100] [-tol 1e-10]
        [-output results/refined_N100.npz] [-table results/refinement_table.md] [-figures figures] [-resume]

For every branch point whose q = 2 pi m / N fits the chain: E(q) of the interpolated branch wave, with the
paper's flow (rtol 1e-12, atol 1e-14) and with the tight flow (rtol 1e-14, atol 1e-16) used for refinement;
Gauss-Newton refinement to E <= tol; E(q) of the refined state with both flows; r(q). The refined states are
written after each q (-resume skips the q already in -output). Figure: errors.png (fig. errors).
PETSc prefix: -chain_ (the TS of every flow; the tolerances above are set in code, per flow).
"""
import math
import os
import sys

import petsc4py

petsc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

import numpy as np  # noqa: E402

from hertzpetsc.branchfile import RefinedWriter, read_branch, read_refined  # noqa: E402
from hertzpetsc.chain import ChainParameters, IntegrationTolerances  # noqa: E402
from hertzpetsc.cli import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.errors import ParameterError, RunFileError  # noqa: E402
from hertzpetsc.shooting import refine, residual_E  # noqa: E402
from hertzpetsc.waves import chain_wavenumbers, wave_on_chain  # noqa: E402

PAPER_FLOW = IntegrationTolerances(1e-12, 1e-14)


def table(data, N):
    lines = [f"N = {N} beads. E(q) = ||S X(script-T) - X(0)||_inf / ||X(0)||_inf. 'paper flow': adaptive RK 8(7) "
             "with rtol 1e-12, atol 1e-14 (the paper's tolerances); 'tight flow': rtol 1e-14, atol 1e-16 (used for "
             "the refinement and its E). r = relative change of the last Gauss-Newton step.\n",
             "| q | m | E before (paper flow) | E before (tight flow) | E after (tight flow) | E after (paper flow) "
             "| r(q) | GN its | Jacobians |", "|---|---|---|---|---|---|---|---|---|"]
    for i in np.argsort(-data["q"]):
        q = data["q"][i]
        lines.append(f"| {q:.4f} | {int(round(q * N / (2 * math.pi)))} | {data['E_before_paper_flow'][i]:.2e} | "
                     f"{data['E_before'][i]:.2e} | {data['E_after'][i]:.2e} | {data['E_after_paper_flow'][i]:.2e} | "
                     f"{data['r'][i]:.1e} | {int(data['iterations'][i])} | {int(data['jacobians'][i])} |")
    return "\n".join(lines) + "\n"


def main():
    opts = AppOptions()
    branch_path = opts.string("branch", "results/branch_alpha1.5.npz")
    N = opts.integer("N", 100, minimum=3)
    tol = opts.real("tol", 1e-10, valid=(lambda x: x > 0, "must be > 0"))
    output = opts.string("output", f"results/refined_N{N}.npz")
    table_path = opts.string("table", f"results/refinement_table_N{N}.md")
    figures = opts.string("figures", "")
    resume = opts.flag("resume")
    q_only = opts.real("q", None, expr=True)
    comm = PETSc.COMM_WORLD
    rank0 = comm.getRank() == 0

    branch = read_branch(branch_path)
    alpha = float(branch["alpha"])
    params = ChainParameters(alpha, N)
    qs = chain_wavenumbers(branch["q"], N)
    if q_only is not None:
        qs = [q for q in qs if abs(q - q_only) <= 1e-12 * q_only]
        if not qs:
            raise ParameterError("-q", q_only, f"must be a branch wavenumber 2 pi m / N with N = {N}")
    if not qs:
        raise ParameterError("-N", N, "no branch wavenumber q has N q / (2 pi) integer")
    existing = None
    if resume and os.path.exists(output):
        existing = read_refined(output)
        if existing["N"] != N or abs(existing["alpha"] - alpha) > 1e-12:
            raise RunFileError(f"{output!r} holds another computation (N = {existing['N']}, alpha = "
                               f"{existing['alpha']})")
    done = set(np.round(existing["q"], 12)) if existing else set()
    writer = RefinedWriter(output, alpha, N, branch_path, existing) if rank0 else None
    print0(f"# N = {N}, alpha = {alpha}, {len(qs)} wavenumbers, target E <= {tol:g}")
    print0(f"# {'q':>8} {'E before':>10} {'E after':>10} {'its':>4} {'jac':>4} {'time':>6}")
    for q in qs:
        if round(q, 12) in done:
            continue
        wave = wave_on_chain(branch, q, N)
        x0 = wave.as_array()
        E_paper = residual_E(params, x0, wave.T, comm, PAPER_FLOW)
        res = refine(params, x0, wave.T, comm, tol=tol)
        E_after_paper = residual_E(params, res.x, wave.T, comm, PAPER_FLOW)
        if rank0:
            writer.append(res.x, q=q, E_before_paper_flow=E_paper, E_before=res.E_initial,
                          E_after=res.E, E_after_paper_flow=E_after_paper, r=res.r, iterations=res.iterations,
                          jacobians=res.jacobians, wall_time=res.wall_time, sigma_min=res.sigma_min)
        print0(f"  {q:8.5f} {res.E_initial:10.2e} {res.E:10.2e} {res.iterations:4d} {res.jacobians:4d} "
               f"{res.wall_time:6.1f}")
    if rank0:
        data = read_refined(output)
        text = table(data, N)
        with open(table_path, "w") as f:
            f.write(text)
        print0(f"max E after refinement: {data['E_after'].max():.2e} (tight flow); wrote {output}, {table_path}")
        if figures:
            from hertzpetsc import plotting
            os.makedirs(figures, exist_ok=True)
            print0("wrote " + plotting.plot_errors(data, figures))


if __name__ == "__main__":
    guarded_main(main)
