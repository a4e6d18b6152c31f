#!/usr/bin/env python3
"""Small-amplitude resonances of a precompressed chain between an actuator a cos(omega t) and a wall, against the
linear chain's normal modes omega_k = 2 sqrt(K/m) sin(k pi / (2 (N + 1))) (uniform masses; K = V''(0) =
alpha delta0^(alpha - 1)) and the damped linear chain's response (closed form: the complex linear system).

    python scripts/driven_resonances.py [-N 20] [-alpha 1.5] [-delta0 1] [-gamma 0.01] [-eta 0] [-masses 1]
        [-amplitude 1e-6] [-modes 1,2,...] [-golden 40] [-tol 1e-10] [-rtol 1e-12]
        [-output runs/driven_resonances.npz] [-table runs/driven_resonances.md] [-figures figures]
        [-resume | -force] [-beads steel -radius 4.76mm -static_force 10N -drive_amplitude 1nm]
        [-contact hunt-crossley|kuwabara-kono -contact_damping c | -contact_coefficient 0.05s/m |
         -restitution 0.95 -impact_velocity 0.1m/s] [-unclipped]

With -beads (hertzpetsc.units) the chain is that of the beads pressed by -static_force (instead of -alpha, -delta0,
-masses; -drive_amplitude instead of -amplitude), and every mode is also shown with its frequencies in Hz, in the
console and in a section of the table in SI units.
-contact adds a dissipation in the contacts (Hunt-Crossley c or Kuwabara-Kono eta by -contact_damping in the chain's
units; with -beads by -contact_coefficient in SI or a restitution measured at an impact velocity): the linear chain
then has, in every bond, the contact's dashpot linearised at the static overlap ((3/2) c delta0^alpha, resp.
eta delta0^(alpha - 1)) beside -eta.
For each mode k: the peak of the last bead's amplitude over omega near omega_k (golden section) from Newton-shooting
periodic responses of the Hertz chain, and from the damped linear chain; the multipliers at the peak against
exp(T lambda) of the linear damped chain. Records: schema hertzpetsc-driven-resonances-1.
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.driven import LinearResonances, ResonanceParameters, drive_options  # noqa: E402

# the SI columns of a mode (hertzpetsc.units.BeadChain.table)
SI_COLUMNS = [("f_k", "frequency", lambda r: r["omega_k"]), ("peak linear", "frequency",
                                                                  lambda r: r["peak_linear"]),
              ("peak shooting", "frequency", lambda r: r["peak_shooting"])]


def main():
    opts = AppOptions(__doc__, LinearResonances.ROLES)
    drive, beads = drive_options(opts, N=20, delta0=1.0, gamma=0.01, amplitude=1e-6, omega=1.0, beads=True)
    p = opts.parameters(ResonanceParameters)
    output, mode, table_path, figures = opts.record_table_figures(
        "runs/driven_resonances.npz", "driven-resonances file", "runs/driven_resonances.md",
        "driven_resonances.png")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path, figures=figures)
    study = LinearResonances(ResonanceParameters(drive, **p), comm, output, mode)
    opts.check_unused()
    study.open()
    table = None
    if beads is not None:
        print0(beads.summary())

        def table():
            return study.table() + beads.table(study.store.records, SI_COLUMNS, [("k", lambda r: r["k"])])
    print0(f"# {'k':>3} {'omega_k':>12} {'peak linear':>12} {'peak shooting':>14} {'mu error':>9}"
           + ("" if beads is None else f" {'f_k [Hz]':>10} {'linear [Hz]':>11} {'shooting [Hz]':>13}"))
    text = study.run_to_table(table_path, lambda r: print0(
        f"  {int(r['k']):3d} {float(r['omega_k']):12.8f} {float(r['peak_linear']):12.8f} "
        f"{float(r['peak_shooting']):14.8f} {float(r['mu_error']):9.1e}" + ("" if beads is None else
                                                                           " {:>10} {:>11} {:>13}".format(
                                                                               *beads.columns(r, SI_COLUMNS)))),
        table)
    records = study.store.records
    study.destroy()
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        print("wrote " + plotting.plot_driven_resonances(records, figures).path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
