#!/usr/bin/env python3
"""The paper's open question (Discussion, last paragraph): which simple driving signals generate periodic
travelling waves in a damped chain? A long chain driven at one end (wall at the other) by a harmonic signal or a
train of half-sine pulses: the periodic response, its stability, and how close its bulk is to the branch's
travelling waves (local wavenumber and amplitude, shape distance, decay along the chain), over the driving
frequency, amplitude and damping.

    mpiexec -n 2 python scripts/driven_generation.py [-branch results/branch_alpha1.5.npz] [-N 60] [-alpha 1.5]
        [-delta0 0] [-eta 0] [-contact hunt-crossley|kuwabara-kono -contact_damping c [-unclipped]]
        [-signals harmonic,half_sine] [-width 0.5] [-omegas 0.2,0.3,0.5]
        [-amplitudes 0.1,0.5] [-gammas 0.02,0.05] [-run_in 60] [-tol 1e-9] [-rtol 1e-12] [-bulk 0.25,0.75]
        [-samples 128] [-output runs/driven_generation.npz] [-table runs/driven_generation.md]
        [-figures figures] [-resume | -force]
        [-beads steel -radius 4.76mm -static_force 10N [-contact_coefficient 0.05s/m | -restitution 0.95
         -impact_velocity 0.1m/s]]

-contact adds a dissipation in the contacts (hertzpetsc.dissipation: Hunt-Crossley c or Kuwabara-Kono eta given by
-contact_damping, in the chain's units; a contact never pulls unless -unclipped) to the damping of every case.
With -beads (hertzpetsc.units: one material, the branch's family being monatomic) the chain is that of the beads
pressed by -static_force (Hertz alpha = 3/2, the branch's exponent; delta0 = 1 at the default length scale)
instead of -alpha, -delta0; the contact damping may then be given in SI (-contact_coefficient, or -restitution
at -impact_velocity), and the table adds a section in SI units (f in Hz, a and the bulk amplitude in um, gamma in
kg/s, the bulk's phase speed omega / q in m/s).
Each case: -run_in driving periods from rest, Newton (dense Jacobian for N <= 200, Newton-Krylov above), the
multipliers, then the response sampled -samples times per period. The cases are dealt to the ranks. Records:
schema hertzpetsc-driven-generation-1.
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.branch import Branch  # noqa: E402
from hertzpetsc.model import Damping, LatticeModel, law_options  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.driven import WAVEFORMS, Generation, GenerationParameters  # noqa: E402
from hertzpetsc.units import bead_options, contact_options  # noqa: E402

SI_COLUMNS = [("f", "frequency", lambda r: r["omega"]), ("a", "length", lambda r: r["amplitude"]),
              ("gamma", "damping", lambda r: r["gamma"]), ("A bulk", "length", lambda r: r["amp_bulk"]),
              ("c bulk", "speed", lambda r: float(r["omega"]) / float(r["q_bulk"]))]


def main():
    opts = AppOptions(__doc__, Generation.ROLES)
    branch_path = opts.path("branch", "results/branch_alpha1.5.npz", "branch file (the travelling-wave family)")
    alpha = opts.real("alpha", 1.5, "Hertz exponent (must be the branch's)", valid=(lambda x: x > 1, "> 1"))
    law_options(opts, supported=False)      # -law: refused but hertz
    delta0 = opts.real("delta0", 0.0, "precompression")
    eta = opts.real("eta", 0.0, "damping between neighbours")
    beads = bead_options(opts, ("alpha", "delta0"), one_bead="the bulk is compared with the branch's monatomic "
                         "family: give one material (a pattern's driven responses: scripts/driven_response.py "
                         "-beads)")
    contact = contact_options(opts, beads, si=True)
    p = opts.parameters(GenerationParameters, N=60, signals="harmonic,half_sine", omegas="0.2,0.3,0.5",
                        amplitudes="0.1,0.5", gammas="0.02,0.05")
    output, mode, table_path, figures = opts.record_table_figures(
        "runs/driven_generation.npz", "driven-generation file", "runs/driven_generation.md",
        "driven_generation.png")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path, figures=figures)
    branch = Branch.load(branch_path, comm)
    model = LatticeModel.hertz(alpha, (1.0,), delta0, 0.0, eta) if beads is None else beads.model(0.0, eta)
    if contact is not None:
        model = LatticeModel(model.law, model.masses, Damping(0.0, eta, contact))
    study = Generation(GenerationParameters(branch, model, **p, branch_path=branch_path), comm, output, mode)
    opts.check_unused()
    study.open()
    table = None
    if beads is not None:
        print0(beads.summary())

        def table():
            return study.table() + beads.table(study.store.records, SI_COLUMNS, [
                ("signal", lambda r: WAVEFORMS[int(r["waveform"])]), ("omega", lambda r: r["omega"]),
                ("a", lambda r: r["amplitude"]), ("gamma", lambda r: r["gamma"]),
                ("periodic", lambda r: "yes" if int(r["ok"]) else "no")])
    print0(f"# {'signal':>9} {'omega':>6} {'a':>6} {'gamma':>6} {'ok':>3} {'rho':>8} {'q':>7} {'A/A_fam':>8} "
           f"{'D':>6}" + ("" if beads is None else f" {'f [Hz]':>10} {'a [um]':>10} {'A bulk [um]':>11}"))
    text = study.run_to_table(table_path, lambda r: print0(
        f"  {WAVEFORMS[int(r['waveform'])]:>9} {float(r['omega']):6.3g} {float(r['amplitude']):6.3g} "
        f"{float(r['gamma']):6.3g} {int(r['ok']):3d} {float(r['rho']):8.4f} {float(r['q_bulk']):7.4f} "
        f"{float(r['family_ratio']):8.3g} {float(r['distance']):6.3f}" + ("" if beads is None else
                                                                          " {:>10} {:>10} {:>11}".format(
            *[beads.columns(r, SI_COLUMNS)[k] for k in (0, 1, 3)]))), table)
    records = study.store.records
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        print("wrote " + plotting.plot_driven_generation(records, figures).path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
