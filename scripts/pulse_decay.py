#!/usr/bin/env python3
"""A pulse launched into a long Hertz chain with dissipation in the contacts: its amplitude along the chain and the
decay law (A^p linear in the bead index: p = -1 Hunt-Crossley, p = -1/5 Kuwabara-Kono for Hertz).

    python scripts/pulse_decay.py [-contact hunt-crossley|kuwabara-kono] [-damping 0.01] [-unclipped]
        [-velocities 1,0.5] [-N 200] [-skip 20] [-sample 0.02] [-alpha 1.5] [-rtol 1e-10]
        [-output runs/pulse_decay.npz] [-table runs/pulse_decay.md] [-resume | -force]
    python scripts/pulse_decay.py -beads steel -radius 4.76mm -contact_coefficient 0.05s/m
        -striker_velocities 0.1m/s,0.05m/s [-length_scale 1um] [-N 200]

A free chain of N beads at rest, bead 0 launched at each velocity v0; the amplitude A_n of bead n is its largest
velocity (sampled every -sample, the peak interpolated by a parabola); the decay law fitted over beads
-skip..N - 1 - -skip: the exponent p whose A^p is most nearly linear, and d(A^p)/dn per unit damping at the law's p
(the same for every v0 where the law holds). Records: schema hertzpetsc-pulse-1.

With -beads (hertzpetsc.units: one material; the chain is monatomic) the beads are those (Hertz, alpha = 3/2)
instead of -alpha; the damping in SI by -contact_coefficient (Hunt-Crossley c in s/m, Kuwabara-Kono eta in
N s/m^1.5) instead of -damping, the striker velocities in SI by -striker_velocities instead of -velocities. The chain
is free (no -static_force): -length_scale (default 1 um) only sets the dimensionless units. The table adds a section
in SI units (v0 and the amplitudes A_n, bead velocities, in m/s).
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.model import law_options  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.contacts import ROLES, PulseDecay, PulseParameters  # noqa: E402
from hertzpetsc.units import bead_options, impact_damping, si_numbers  # noqa: E402


def main():
    opts = AppOptions(__doc__, ROLES)
    p = opts.parameters(PulseParameters)
    law_options(opts, supported=False)      # -law: refused but hertz
    output = opts.path("output", "runs/pulse_decay.npz", "pulse file (record store)")
    mode = opts.mode()
    table_path = opts.path("table", "runs/pulse_decay.md", "table")
    beads = bead_options(opts, ("alpha",), length_scale="1um", one_bead="the pulse runs into a monatomic chain: give "
                         "one material (a pattern's waves: scripts/wave.py -beads, its driven responses: "
                         "scripts/driven_response.py -beads)", free="the chain of the pulse is free (no static force; "
                         "-length_scale sets the units)")
    coefficient = opts.string("contact_coefficient", "", "-beads: the damping in SI units (Hunt-Crossley c, e.g. "
                              "0.05s/m; Kuwabara-Kono eta in N s/m^1.5), instead of -damping")
    si_velocities = si_numbers(opts, beads, "striker_velocities", "velocity", "striker velocities (e.g. 0.1m/s)",
                               "velocities")
    opts.done()
    if beads is not None:
        p["alpha"] = 1.5
        p["velocities"] = p["velocities"] if si_velocities is None else tuple(si_velocities)
    p["damping"] = damping = impact_damping(opts, beads, p["contact"], p["damping"], coefficient)
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path)
    study = PulseDecay(PulseParameters(**p), comm, output, mode)
    N, skip = p["N"], p["skip"]
    opts.check_unused()
    study.open()
    table, si = None, [("v0", "velocity", lambda r: r["v0"]), (f"A_{skip}", "velocity", lambda r: r["amplitude"][skip]),
                       (f"A_{N - 1 - skip}", "velocity", lambda r: r["amplitude"][N - 1 - skip])]
    if beads is not None:
        print0(beads.summary() + f"\n# {p['contact']} damping {damping:.6g} in the chain's units")

        def table():
            return study.table() + beads.table(study.store.records, si, [
                ("v0", lambda r: r["v0"]), ("p fitted", lambda r: r["p_fit"])])
    print0(f"# {'v0':>8} {'A_skip':>10} {'A_last':>10} {'p fitted':>9}"
           + ("" if beads is None else f" {'v0 [m/s]':>10} {'A_skip [m/s]':>12} {'A_last [m/s]':>12}"))
    text = study.run_to_table(table_path, lambda r: print0(
        f"  {float(r['v0']):8.4g} {float(r['amplitude'][skip]):10.6f} {float(r['amplitude'][N - 1 - skip]):10.6f} "
        f"{float(r['p_fit']):9.4f}" + ("" if beads is None else " {:>10} {:>12} {:>12}".format(
            *beads.columns(r, si)))), table)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
