#!/usr/bin/env python3
"""Convergence in the grid step h of the branch diagnostics (second-order scheme, section 3.1).

    mpiexec -n 2 python scripts/convergence_h.py [-alpha 1.5] [-M 50] [-cells 250,500,1000,2000,4000]
                                                  [-output results/convergence_h.md]

Computes the branch q = pi -> pi/M on each grid h = pi/K, and for those of q = pi, 3pi/10, 7pi/25, 9pi/50, pi/50
that are on it (q = m pi / M) reports
||u||_inf, p(q), N(q), T(q) on each grid, the observed order log2(|d_{h,h/2}| / |d_{h/2,h/4}|) on the three
finest grids, and the Richardson extrapolation X_{h/2} + (X_{h/2} - X_h)/3.
PETSc prefix: -tw_ (travelling-wave SNES).
"""
import math
import sys

import petsc4py

petsc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.cli import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.continuation import BranchContinuation, ContinuationParameters  # noqa: E402
from hertzpetsc.errors import ParameterError  # noqa: E402

QUANTITIES = ("norm_inf", "slope", "N", "T")
Q_REPORT = (("pi", math.pi), ("3pi/10", 3 * math.pi / 10), ("7pi/25", 7 * math.pi / 25),
            ("9pi/50", 9 * math.pi / 50), ("pi/50", math.pi / 50))


def study(alpha, M, cells):
    values = {}
    for K in cells:
        cont = BranchContinuation(ContinuationParameters(alpha=alpha, M=M, cells_per_pi=K), PETSc.COMM_WORLD)
        try:
            for pt in cont.points():
                values[(K, round(pt.q, 12))] = pt.diagnostics
        finally:
            cont.destroy()
        print0(f"# branch on h = pi/{K} done")
    return values


def report(alpha, M, cells, values):
    lines = [f"alpha = {alpha}, M = {M}, grids h = pi/K for K in {list(cells)}; order from the three finest grids; "
             "extrapolated = Richardson from the two finest (assumes h^2)\n",
             "| q | quantity | " + " | ".join(f"K = {K}" for K in cells) + " | observed order | extrapolated |",
             "|---|---|" + "---|" * len(cells) + "---|---|"]
    for label, q in Q_REPORT:
        if any((K, round(q, 12)) not in values for K in cells):
            continue                     # not a target of this branch (q = m pi / M)
        for name in QUANTITIES:
            xs = [values[(K, round(q, 12))][name] for K in cells]
            a, b, c = xs[-3:]
            order = math.log2(abs(a - b) / abs(b - c)) if abs(b - c) > 0 and abs(a - b) > 0 else float("nan")
            extrap = c + (c - b) / 3
            lines.append(f"| {label} | {name} | " + " | ".join(f"{x:.8g}" for x in xs)
                         + f" | {order:.2f} | {extrap:.8g} |")
    return "\n".join(lines) + "\n"


def main():
    opts = AppOptions()
    alpha = opts.real("alpha", 1.5)
    M = opts.integer("M", 50, minimum=1)
    cells = sorted(opts.numbers("cells", "250,500,1000,2000,4000", expr=False, kind=int))
    if len(cells) < 3:
        raise ParameterError("-cells", cells, "needs at least three grids for an observed order")
    output = opts.string("output", "results/convergence_h.md")
    text = report(alpha, M, cells, study(alpha, M, cells))
    if PETSc.COMM_WORLD.getRank() == 0:
        with open(output, "w") as f:
            f.write(text)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
