#!/usr/bin/env python3
"""Do the dynamics agree with the compacton's window spectrum? Exact compactons, perturbed, on a long free chain;
and the two-compacton test (which compacton carries the 2-compacton error of section 3.3).

    mpiexec -n 2 python scripts/compacton_dynamics.py [-stability results/compacton_stability.npz] [-alpha 1.5] \
        [-q 7*pi/25,pi/50,0] [-N 2100] [-n0 50] [-travel 1000] [-amplitude 1e-8] [-kinds mode,noise] \
        [-output runs/compacton_dynamics.npz] [-table runs/compacton_dynamics.md] [-figures figures] \
        [-pairs_branch results/branch_alpha1.5.npz] [-pairs_q pi/50] [-spacing 132] [-pairs_travel 100] \
        [-pairs_output runs/compacton_pairs.npz] [-pairs_table runs/compacton_pairs.md] [-resume | -force]
        [-no_dynamics] [-no_pairs]

Dynamics: each exact compacton of -q (from the stability file, at -alpha) is placed at bead -n0 of a free chain of
-N beads in gap-lattice coordinates, perturbed by -amplitude times its least-stable mode (mode) or Gaussian noise
(noise), relative to D and v_peak, and run for -travel units of time (one bead each). At every integer time the
moving window's deviation is split with the Jordan vectors of the multiplier 1: delta = a v1 + b v2 + rest; the
fitted decay rate of |rest| is compared with ln|mu_3| (per script-T = 1), the phase a with a_10 + (k - 10) b_10.
Pairs (-pairs_q, skipped with -no_pairs): the compacton of the branch point, unrefined or refined at the same gap, alone
and as front/rear of a pair -spacing beads apart, run until the rear one has passed -pairs_travel beads beyond
the front one's start; errors against the exact translation.
"""
import math
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.model import law_options  # noqa: E402
from hertzpetsc.branch import Branch  # noqa: E402
from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs, write_text  # noqa: E402
from hertzpetsc.studies.compacton_dynamics import CompactonDynamics  # noqa: E402
from hertzpetsc.studies.compacton_pairs import CompactonPairs  # noqa: E402


def main():
    opts = AppOptions(__doc__, CompactonDynamics.ROLES)
    stability = opts.path("stability", "results/compacton_stability.npz", "compacton stability file")
    alpha = opts.real("alpha", 1.5, "Hertz exponent of the compactons", valid=(lambda a: a > 1, "> 1"))
    law_options(opts, supported=False)      # -law: refused but hertz
    qs = opts.numbers("q", "7*pi/25,pi/50,0", "wavenumbers in the stability file (0: the solitary wave)",
                      valid=(lambda q: q >= 0, ">= 0"), distinct=True)
    if opts.flag("no_dynamics", "only the two-compacton test"):
        qs = []
    N = opts.integer("N", 2100, "beads of the free chain", minimum=10, maximum=10 ** 7)
    n0 = opts.integer("n0", 50, "first bead of the compacton's window", minimum=1)
    travel = opts.integer("travel", 1000, "units of time = beads of travel", minimum=10, maximum=10 ** 7)
    amplitude = opts.real("amplitude", 1e-8, "size of the perturbation (relative to D and v_peak)",
                          valid=(lambda x: 0 < x < 1, "in (0, 1): a perturbation, split linearly"))
    kinds = opts.words("kinds", "mode,noise", "perturbations", choices=("mode", "noise"))
    output, mode, table, figures = opts.record_table_figures(
        "runs/compacton_dynamics.npz", "compacton dynamics file", "runs/compacton_dynamics.md",
        "compacton_dynamics.png")
    pairs_branch = opts.path("pairs_branch", "results/branch_alpha1.5.npz", "branch of the two-compacton test")
    pairs_q = opts.numbers("pairs_q", "pi/50", "q of the two-compacton test", valid=(lambda q: q > 0, "> 0"))
    if opts.flag("no_pairs", "skip the two-compacton test"):
        pairs_q = []
    spacing = opts.integer("spacing", 132, "beads between the two compactons' windows", minimum=8)
    pairs_travel = opts.integer("pairs_travel", 100, "beads the rear compacton passes beyond the front one's start",
                                minimum=1)
    pairs_output = opts.path("pairs_output", "runs/compacton_pairs.npz", "two-compacton record file")
    pairs_table = opts.path("pairs_table", "runs/compacton_pairs.md", "two-compacton table")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table, pairs_table, figures=figures)
    dyn = None
    if qs:
        dyn = CompactonDynamics.from_stability(stability, alpha, qs, comm, output, mode, N=N, n0=n0, travel=travel,
                                               amplitude=amplitude, kinds=kinds)
    pairs = None
    if pairs_q:
        if len(pairs_q) > 1:
            raise ParameterError("-pairs_q", pairs_q, "one wavenumber")
        try:
            pairs = CompactonPairs(Branch.load(pairs_branch, comm), pairs_q[0], comm, pairs_output, mode, spacing,
                                   pairs_travel)
        except ParameterError as err:             # the pairs' travel is this driver's -pairs_travel
            if err.name != "travel":
                raise
            raise ParameterError("-pairs_travel", err.value, err.valid) from None
    opts.check_unused()
    try:
        if dyn is not None:
            print0(f"# {'q':>9} {'kind':>6} {'rate':>8} {'ln|mu3|':>8} {'late max|rest|':>14} {'|delta|(T)':>10} "
                   f"{'s':>6}")

            def show(r):
                print0(f"  {r['q']:9.6f} {r['kind']:>6} {r['rate']:8.4f} {math.log(abs(r['mu3'])):8.4f} "
                       f"{r['rest_max_late']:14.1e} {r['dist_end']:10.1e} {r['seconds']:6.1f}")
                write_text(table, dyn.table(), comm)         # a killed run leaves the table of its records
            text = dyn.run_to_table(table, show)             # on a stop: the table of the records done
            if figures and comm.getRank() == 0:
                from hertzpetsc import plotting
                print("wrote " + plotting.plot_compacton_dynamics(dyn.store.records, figures).path, flush=True)
            print0(text)
        if pairs is not None:
            print0(pairs.run_to_table(pairs_table, lambda r: print0(
                f"  {r['case']:>6} rear {r['rear'] or '-':>9} front {r['front']:>9}: error x {r['error_x']:.1e}"
                f", v {r['error_v']:.1e}, debris {r['debris_v']:.1e} ({r['seconds']:.1f} s)")))
    finally:
        for s in (dyn, pairs):
            if s is not None:
                s.destroy()


if __name__ == "__main__":
    guarded_main(main)
