#!/usr/bin/env python3
"""Compactons of section 3.3 built from the branch and verified on the lattice (eqs. extens, extens2, twlin,
compacton, defvit, 2compacton); fig. graphulin and space-time plots.

    mpiexec -n 2 python scripts/compactons.py -branches results/branch_alpha1.5.npz,runs/branch_K4000.npz \
        -q 7*pi/25,pi/10 -output results/compactons.md -figures figures

For every branch file and every q (<= q_k) it builds the single compacton U_q and the 2-compacton
U^(2)_{q, theta}, checks eq. ad on the extended grid, then puts each on a free-ended chain, -margin beads of rest
behind it and enough ahead for all of it to pass -travel beads at velocity -c, integrates with the chain TS and
measures what the paper asserts: beads ahead exactly at rest, arrival on time, speed c, shift 2 pi a p, gaps
Delta = a p q and rest behind, unchanged profile (hertzpetsc.compacton.lattice_checks). The table is rewritten
after every case. Options:
  -branches LIST      branch files (comma-separated); a finer h shows which deviations are discretisation error
  -q LIST             wavenumbers on the branches, each <= q_k ("pi/10" style allowed)   [7*pi/25,pi/10]
  -theta 2            extra phase between the two compactons (theta = q d, d >= min(0, 2 - F(q)) beads; the
                      paper's fig. graphulin uses 2)
  -c 1                compacton velocity in beads per unit time (fixes the amplitude a = (c q)^(2/(alpha-1)))
  -margin 10 -travel 100 -dt_snapshot 0.05
  -output FILE -figures DIR (figures from the first branch and the first q)
PETSc prefix: -chain_ (TS; default RK 8(7), rtol 1e-12, atol 1e-14).
"""
import math
import sys
import time

import petsc4py

petsc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc import plotting  # noqa: E402
from hertzpetsc.branchfile import read_branch  # noqa: E402
from hertzpetsc.cli import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.compacton import (CompactonScales, chain_length, compacton_train, extension_residuals,  # noqa: E402
                                  lattice_checks, placement, simulate_on_chain, train_span)

HEADER = ("| h | q | compactons | F(q) | N(q) | eq. ad residual: extended / period / 2 delta h^-2 | max \\|xdot\\| ahead | "
          "max \\|x - x(0)\\| ahead | arrival delay (dt) | c measured (c = 1) | shift error | gap error | "
          "max \\|xdot\\| behind / v_peak | profile error x / v | wall (s) |")


def row(train, h, res, chk, wall):
    cs = ", ".join(f"{c:.7f}" for c in chk["measured_c"])
    return (f"| pi/{round(math.pi / h)} | {train.q:.4f} | {train.count} | {train.F:.3f} | {train.width:.3f} | "
            f"{res[0]:.1e} / {res[1]:.1e} / {res[2]:.1e} | {chk['max_velocity_ahead']:.1e} | {chk['max_displacement_ahead']:.1e} | "
            f"{chk['arrival_delay_min']:.3f}-{chk['arrival_delay_max']:.3f} ({chk['dt_snapshot']:g}) | {cs} | "
            f"{chk['shift_error']:.1e} | {chk['gap_error']:.1e} | {chk['max_velocity_behind'] / chk['v_peak']:.1e} | "
            f"{chk['profile_error_x']:.1e} / {chk['profile_error_v']:.1e} | {wall:.1f} |")


def main():
    opts = AppOptions()
    paths = [p for p in opts.string("branches", "results/branch_alpha1.5.npz").split(",") if p]
    qs = opts.numbers("q", "7*pi/25,pi/10")
    theta = opts.real("theta", 2.0)
    c = opts.real("c", 1.0, valid=(lambda x: x > 0, "must be > 0 beads per unit time"))
    margin = opts.integer("margin", 10, minimum=2)
    travel = opts.integer("travel", 100, minimum=5)
    dt = opts.real("dt_snapshot", 0.05, valid=(lambda x: x > 0, "must be > 0"))
    output = opts.string("output", "results/compactons.md")
    figures = opts.string("figures", "")
    rank0 = PETSc.COMM_WORLD.getRank() == 0
    branches = [read_branch(p) for p in paths]
    for b in branches:                                   # refuse bad input before any long run
        for q in qs:
            compacton_train(b, q, (theta / q,))
    rows = []
    note = (f"Chain: free ends, {margin} beads of rest behind the train; it moves at c = {c:g} until all of it "
            f"has passed {travel} beads (its length plus {travel} beads of travel); theta = {theta:g} between the two compactons (its grid residual uses theta "
            "rounded to a whole number of steps h). delta = max |u_j - p j h| on the free flight, the computed "
            "profile's deviation from a line, bounds what the switch to the exact line adds to the residual. "
            "Errors are relative: shift and profile x to 2 pi a p, gap to a p q, velocities to the peak velocity. "
            "'arrival delay' = first snapshot with xdot_n != 0 minus the predicted arrival of the front, over all "
            "beads reached; within [0, dt] means on time.\n\n")
    for path, b in zip(paths, branches):
        h = float(b["h"])
        for q in qs:
            single = compacton_train(b, q)
            d = theta / single.q
            for spacings in ((), (d,)):
                train = compacton_train(b, q, spacings)
                d_grid = round(theta / h) * h / single.q
                res = extension_residuals(compacton_train(b, q, [d_grid] * len(spacings)))
                scales = CompactonScales.for_velocity(train, c)
                distance = travel + math.ceil(train_span(train))     # the whole train passes `travel` beads
                N = chain_length(train, margin, distance)
                phi = placement(train, margin)
                t0 = time.perf_counter()
                times, states = simulate_on_chain(train, scales, N, phi, distance / c, dt)
                wall = time.perf_counter() - t0
                chk = lattice_checks(train, scales, phi, times, states)
                rows.append(row(train, h, res, chk, wall))
                print0(rows[-1])
                if rank0:
                    with open(output, "w") as f:
                        f.write(note + HEADER + "\n" + "|---" * 15 + "|\n" + "\n".join(rows) + "\n")
                if figures and rank0 and path == paths[0] and q == qs[0]:
                    name = "compacton_spacetime.png" if not spacings else "compacton2_spacetime.png"
                    plotting.plot_spacetime_velocities(times, states, figures, name,
                                                       f"q = {train.q:.4f}, {train.count} compacton(s), c = {c:g}")
                    if spacings:
                        plotting.plot_compacton_profiles(single, train, figures)
    print0(f"wrote {output}")


if __name__ == "__main__":
    guarded_main(main)
