#!/usr/bin/env python3
"""The unit-velocity solitary wave and k_alpha (paper appendix), with convergence in the grid step and the
domain length.

    mpiexec -n 2 python scripts/solitary_wave.py [-alphas 1.5,2,2.5] [-cells 10,20,40,80,160] [-lengths 5,6,7,8,10]
        [-output results/solitary.md] [-figures figures]

For each alpha: k_alpha on grids delta = 1/n (n in -cells) at L = 8, the observed order and the Richardson
extrapolation (h^2); and k_alpha for L in -lengths at the finest n. Figure ondesol.png: r(s) and y(s) for the
first alpha on the finest grid.
PETSc prefix: -sol_ (the solitary-wave SNES, e.g. -sol_snes_monitor).
"""
import math
import os
import sys

import petsc4py

petsc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.cli import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.solitary import SolitaryParameters, solve_solitary_wave  # noqa: E402


def main():
    opts = AppOptions()
    alphas = opts.numbers("alphas", "1.5,2,2.5", expr=False)
    cells = sorted(opts.numbers("cells", "10,20,40,80,160", expr=False, kind=int))
    lengths = sorted(opts.numbers("lengths", "5,6,7,8,10", expr=False))
    output = opts.string("output", "results/solitary.md")
    figures = opts.string("figures", "")
    if len(cells) < 3:
        raise ParameterError("-cells", cells, "needs at least three grids for an observed order")
    comm = PETSc.COMM_WORLD
    lines = ["k_alpha = -sum_k r(k + 1/2) (eq. kal2) of the unit-velocity solitary wave of eq. adr, grid step "
             "delta = 1/n on [-L, L]; order from the three finest grids; extrapolated = Richardson (delta^2).\n"]
    first = None
    for alpha in alphas:
        ks = []
        for n in cells:
            w = solve_solitary_wave(SolitaryParameters(alpha, n, 8.0), comm)
            ks.append(w.k_alpha)
            if alpha == alphas[0] and n == cells[-1]:
                first = w                      # the figure: first alpha, finest grid
        a, b, c = ks[-3:]
        order = math.log2(abs(a - b) / abs(b - c))
        extrap = c + (c - b) / 3
        lines += [f"\n### alpha = {alpha}\n", "| n (delta = 1/n) | " + " | ".join(str(n) for n in cells)
                  + " | observed order | extrapolated |", "|---|" + "---|" * (len(cells) + 2),
                  "| k_alpha (L = 8) | " + " | ".join(f"{k:.8f}" for k in ks) + f" | {order:.2f} | {extrap:.7f} |"]
        # the domain study accepts any tail (tail_tolerance 1) and reports it
        wl = [solve_solitary_wave(SolitaryParameters(alpha, cells[-1], L, tail_tolerance=1.0), comm) for L in lengths]
        lines += ["", "| L | " + " | ".join(f"{L:g}" for L in lengths) + " |", "|---|" + "---|" * len(lengths),
                  f"| k_alpha (n = {cells[-1]}) | " + " | ".join(f"{w.k_alpha:.10f}" for w in wl) + " |",
                  "| max \\|r\\| at \\|s\\| >= L-1, relative | " + " | ".join(f"{w.tail:.1e}" for w in wl) + " |"]
        print0("\n".join(lines[-9:]))
    text = "\n".join(lines) + "\n"
    if comm.getRank() == 0:
        with open(output, "w") as f:
            f.write(text)
        if figures:
            from hertzpetsc import plotting
            os.makedirs(figures, exist_ok=True)
            print0("wrote " + plotting.plot_solitary(first, figures))
    print0(f"wrote {output}")


if __name__ == "__main__":
    guarded_main(main)
