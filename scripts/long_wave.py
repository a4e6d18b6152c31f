#!/usr/bin/env python3
"""The long-wave limit (paper section 3.2): the computed branch against the solitary-wave inner solution and
the composite approximation (eq. solapprox); the rescaled norm ||u||_inf q^(2/(alpha-1)) against k_alpha.

    python scripts/long_wave.py [-branch results/branch_alpha1.5.npz] [-cells_per_unit 160] [-window 0.1]
        [-output results/long_wave.md] [-figures figures]

Errors are relative to k_alpha: over the period, and over |xi - pi| <= window (the paper: agreement in a domain
of width ~0.2 around pi). Figures approxz.png (zoom near pi, with the inner solution) and approx.png (the
composite over the period) at the smallest q of the branch.
PETSc prefix: -sol_ (the solitary-wave SNES).
"""
import math
import os
import sys

import petsc4py

petsc4py.init(sys.argv)

import numpy as np  # noqa: E402

from hertzpetsc.branchfile import read_branch  # noqa: E402
from hertzpetsc.cli import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.longwave import compare_with_branch  # noqa: E402
from hertzpetsc.solitary import SolitaryParameters, solve_solitary_wave  # noqa: E402

Q_REPORT = 10     # the branch points with the 10 smallest q


def main():
    opts = AppOptions()
    branch = read_branch(opts.string("branch", "results/branch_alpha1.5.npz"))
    n = opts.integer("cells_per_unit", 160, minimum=2)
    window = opts.real("window", 0.1, valid=(lambda x: 0 < x < math.pi, "must lie in (0, pi)"))
    output = opts.string("output", "results/long_wave.md")
    figures = opts.string("figures", "")
    alpha = float(branch["alpha"])
    from petsc4py import PETSc
    wave = solve_solitary_wave(SolitaryParameters(alpha, n, 8.0), PETSc.COMM_SELF)
    order = np.argsort(branch["q"])[:Q_REPORT]
    rows = [compare_with_branch(wave, float(branch["q"][i]), branch["u"][i], alpha, window) for i in order]
    lines = [f"alpha = {alpha}, branch h = pi/{branch['cells_per_pi']}; k_alpha = {wave.k_alpha:.7f} (solitary wave, "
             f"delta = 1/{n}). Errors relative to k_alpha; window |xi - pi| <= {window}.\n",
             "| q | composite, max over the period | composite, max in the window | inner solution, max in the window "
             "| \\|u\\|_inf q^(2/(alpha-1)) | minus k_alpha |", "|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['q']:.4f} | {r['max_error']:.4f} | {r['window_error']:.4f} | {r['inner_window_error']:.4f} "
                     f"| {r['rescaled_norm']:.5f} | {r['rescaled_norm'] - wave.k_alpha:+.5f} |")
    text = "\n".join(lines) + "\n"
    if PETSc.COMM_WORLD.getRank() == 0:
        with open(output, "w") as f:
            f.write(text)
        if figures:
            from hertzpetsc import plotting
            os.makedirs(figures, exist_ok=True)
            i = order[0]
            for path in plotting.plot_long_wave(wave, float(branch["q"][i]), branch["u"][i], alpha, figures):
                print0("wrote " + path)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
