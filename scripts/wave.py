#!/usr/bin/env python3
"""A travelling wave of a chain of your own choosing, refined, and its stability (hertzpetsc.studies.wave).

    mpiexec -n 2 python scripts/wave.py [-alpha 1.5] [-delta0 1] [-masses 1,0.5,0.333333] [-q 2*pi/15] [-A 0.5]
        [-branch acoustic|optical] [-cells_per_pi 400] [-N 90] [-sizes 30000] [-tol 1e-10] [-tol_rho 1e-4]
        [-output runs/wave.npz] [-table runs/wave.md] [-resume | -force]
        [-beads steel -radius 4.76mm -static_force 10N [-length_scale 1um]] [-law toda -law_k 1 -law_b 1]

With -beads (hertzpetsc.units: materials, radii, the static force) the chain is that of the beads (the Hertz
exponent 3/2, delta0 = 1 at the default length scale, the static overlap; masses from the beads) instead of -alpha,
-delta0, -masses; -A stays in units of the length scale, and every row is also shown in SI units (frequency in Hz,
phase speed in m/s, A in um), in a section of the table below the dimensionless one.

-law NAME (hertzpetsc.law's registry: toda, fpu, ...; hertz by default, given by -alpha, -delta0) with its parameters
-law_<name> value (e.g. -law toda -law_k 1 -law_b 2; -law fpu -law_k 1 -law_alpha 0.5 -law_beta 1; a parameter not
given keeps the law's default) computes the waves of another interaction law: instead of -alpha, -delta0 and -beads.

At each q (per bead: a pattern of p masses has the wavenumber p q per cell; q N / (2 pi) whole): the wave with
amplitude A = max |u| (eq. ad for the mass pattern, A a border row; from the linear wave of -branch for delta0 > 0,
the pattern's lowest or highest frequency at q, and from the paper's branch for delta0 = 0 and one mass), put on a
periodic chain of N beads, refined by Gauss-Newton on its cell (E before and after), its Floquet multipliers
modulo shift from the Bloch sectors of the wave's cell on N beads and on each longer chain of -sizes. One line
and one table row per q; a q that does not converge is named below the table, the others go on, and the
driver exits with status 3; a family that folds before A says at which A and which branch to try.
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.model import LatticeModel, law_options  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.wave import WaveParameters, WaveStudy  # noqa: E402
from hertzpetsc.units import bead_options  # noqa: E402

# the SI columns of a row (hertzpetsc.units.BeadChain.table)
SI_COLUMNS = [("f", "frequency", lambda r: r["omega"]), ("phase speed", "speed", lambda r: r["omega"] / r["q"])]


def main():
    opts = AppOptions(__doc__, WaveStudy.ROLES)
    alpha = opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda x: x > 1, "> 1"))
    delta0 = opts.real("delta0", 1.0, "precompression (static overlap); 0: the sonic vacuum (one mass only)",
                       valid=(lambda x: x >= 0, ">= 0"))
    masses = opts.numbers("masses", "1", "the repeating mass pattern", valid=(lambda m: m > 0, "> 0"))
    p = opts.parameters(WaveParameters, q="2*pi/15", A=0.5, N=90)
    output = opts.path("output", "runs/wave.npz", "wave file (record store)")
    mode = opts.mode()
    table_path = opts.path("table", "runs/wave.md", "table")
    law = law_options(opts)
    beads = bead_options(opts)
    opts.done()
    comm = PETSc.COMM_WORLD
    model = LatticeModel.hertz(alpha, tuple(masses), delta0) if beads is None else beads.model()
    if law is not None:
        model = LatticeModel(law, tuple(masses))
    study = WaveStudy(WaveParameters(model, **p), comm, output, mode)
    prepare_outputs(comm, table_path)
    study.configure()
    opts.check_unused()
    study.open()
    P = study.params
    print0(f"# chain {model.describe()}, {P.branch} branch, A = {P.A:g}, h = pi/{P.cells_per_pi}, N = {P.N}"
           + (f", sizes {list(P.sizes)}" if P.sizes else ""))
    si, table = None, None
    if beads is not None:
        print0(beads.summary() + f"\n# A = {beads.show('length', P.A)}")
        si = [("A", "length", lambda r: P.A)] + SI_COLUMNS

        def table():
            return study.table() + beads.table(study.store.records, si, [("q", lambda r: r["q"]),
                                                                          ("omega", lambda r: r["omega"])])
    print0(f"# {'q':>9} {'omega':>12} {'E before':>9} {'E after':>9} {'rho - 1':>10} {'outside':>7} {'s':>6}"
           + ("" if si is None else f" {'f [Hz]':>12} {'c [m/s]':>12}"))
    text = study.run_to_table(table_path, lambda r: print0(
        f"  {r['q']:9.6f} {r['omega']:12.8f} {r['E_profile']:9.1e} {r['E_refined']:9.1e} {r['rho'] - 1:10.2e} "
        f"{r['outside']:7d} {r['seconds']:6.1f}" + ("" if si is None else " " + " ".join(
            f"{v:>12}" for v in beads.columns(r, SI_COLUMNS)))), table)
    print0(text)
    if study.failed:                         # the table holds every q that converged; exit 3 names the first failure
        raise next(iter(study.failed.values()))


if __name__ == "__main__":
    guarded_main(main)
