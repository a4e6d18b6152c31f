#!/usr/bin/env python3
"""Travelling waves of the precompressed Hertz chain: omega(q, A) from the linear wave to the uncompressed limit.

    mpiexec -n 2 python scripts/precompressed_branch.py [-alpha 1.5] [-delta0 1] [-masses 1]
        [-branch acoustic|optical] [-q 3*pi/10,7*pi/25,pi/2,4*pi/5] [-cells_per_pi 1000] [-a_min 1e-3] [-a_max 1e3]
        [-ds 0.1] [-output runs/precompressed.npz] [-table runs/precompressed.md] [-figures figures]
        [-resume | -force] [-beads steel -radius 4.76mm -static_force 10N]

-masses: the repeating mass pattern (q is per bead; the family starts from the linear wave of -branch, the
pattern's lowest or highest frequency at q; a is then the first sine coefficient of the normalised profile and
A = max_c ||u_c||_inf). C(q) has its closed form for one mass only.

At each q: continuation in s = log a (a: first sine coefficient of u; rescaled unknowns w = u / a and
lam = omega^2 / a^(alpha-1)) from a_min to a_max by steps ds, the gap opening 2 u(q/2) = delta0 located on the
way (regula falsi in s), then the uncompressed limit delta0 / A = 0 on the same grid. A family that folds in a
(an S past the gap opening) is followed around its folds by pseudo-arclength; one that turns back ends with an
error naming the fold. a_min: at most 0.1 delta0 (the family starts from the linear wave), at least the amplitude
below which it is lost in floating point (families.amplitude_floor). Table: C(q) (closed form and
fit), A_gap, Omega = omega A^(-(alpha-1)/2) at the largest A, its limit Omega0 and the rate coefficient c1.
Figure: precompressed_omega.png.
With -beads (hertzpetsc.units) the chain is that of the beads pressed by -static_force (instead of -alpha, -delta0,
-masses; a and A in units of the length scale, by default the static overlap: delta0 = 1), and every row is also
shown in SI units (A in um, frequency in Hz, phase speed in m/s); the table gets a section in SI units: per q, the
first and last amplitude of the grid and the gap opening.
"""
import math
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.hertz import check_delta0  # noqa: E402
from hertzpetsc.model import LatticeModel, law_options  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.precompression import (KIND_GAP, KIND_GRID, AmplitudeFamilies,  # noqa: E402
                                                AmplitudeParameters)
from hertzpetsc.units import bead_options  # noqa: E402

# the SI columns of a row (hertzpetsc.units.BeadChain.table)
SI_COLUMNS = [("A", "length", lambda r: r["A"]), ("f", "frequency", lambda r: r["omega"]),
              ("phase speed", "speed", lambda r: r["omega"] / r["q"])]


def si_rows(records):
    """The rows of the SI section: per q, the first and last grid amplitudes and the gap opening, by q then A."""
    out = []
    for q in sorted({float(r["q"]) for r in records}):
        at = [r for r in records if float(r["q"]) == q]
        grid = sorted((r for r in at if int(r["kind"]) == KIND_GRID), key=lambda r: float(r["a"]))
        out += sorted(grid[:1] + [r for r in at if int(r["kind"]) == KIND_GAP] + (grid[-1:] if len(grid) > 1 else []),
                      key=lambda r: float(r["A"]))
    return out


def main():
    opts = AppOptions(__doc__, AmplitudeFamilies.ROLES)
    alpha = opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda x: x > 1, "> 1"))
    delta0 = opts.real("delta0", 1.0, "precompression (static overlap)", valid=(lambda x: x > 0, "> 0"))
    law_options(opts, supported=False)      # -law: refused but hertz (the study's families are Hertz's)
    masses = opts.numbers("masses", "1", "the repeating mass pattern", valid=(lambda m: m > 0, "> 0"))
    p = opts.parameters(AmplitudeParameters, q="3*pi/10,7*pi/25,pi/2,4*pi/5")
    output, mode, table_path, figures = opts.record_table_figures(
        "runs/precompressed.npz", "precompressed-wave file", "runs/precompressed.md", "precompressed_omega.png")
    beads = bead_options(opts)
    opts.done()
    if beads is not None:
        alpha, delta0, masses = 1.5, beads.model().delta0, beads.model().masses
    comm = PETSc.COMM_WORLD
    model = LatticeModel.hertz(alpha, tuple(masses), check_delta0(delta0)) if beads is None else beads.model()
    prepare_outputs(comm, table_path, figures=figures)
    study = AmplitudeFamilies(AmplitudeParameters(model, **p), comm, output, mode)
    study.configure()
    opts.check_unused()
    study.open()
    P = study.params
    print0(f"# alpha = {alpha:g}, delta0 = {delta0:g}, masses {','.join(f'{m:g}' for m in masses)}, {P.branch}, "
           f"h = pi/{P.cells_per_pi}, a in [{P.a_min:g}, {P.a_max:g}], ds = {P.ds:g}")
    table = None
    if beads is not None:
        print0(beads.summary())

        def table():
            return study.table() + beads.table(si_rows(study.store.records), SI_COLUMNS,
                                               [("q", lambda r: r["q"]), ("omega", lambda r: r["omega"])])
    print0(f"# {'q':>8} {'kind':>4} {'a':>10} {'A':>10} {'omega':>12} {'Omega':>10} {'its':>3}"
           + ("" if beads is None else f" {'A [um]':>10} {'f [Hz]':>10} {'c [m/s]':>10}"))
    text = study.run_to_table(table_path, lambda r: print0(
        f"  {r['q']:8.5f} {r['kind']:4d} {r['a']:10.4g} {r['A']:10.4g} {r['omega']:12.8f} {r['Omega']:10.6f} "
        f"{r['iterations']:3d}" + ("" if beads is None or not math.isfinite(r["A"]) else " " + " ".join(
            f"{v:>10}" for v in beads.columns(r, SI_COLUMNS)))), table)
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        print("wrote " + plotting.plot_precompressed_omega(study.curves(), alpha, delta0, figures).path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
