#!/usr/bin/env python3
"""The coefficient of restitution of a two-bead impact with dissipation in the contact, against the impact velocity,
and its small-dissipation law (Hunt-Crossley: 1 - e = c v; Kuwabara-Kono: 1 - e = C eta v^(1/5) for Hertz).

    python scripts/restitution.py [-contact hunt-crossley|kuwabara-kono] [-damping 0.1] [-unclipped]
        [-velocities 1e-3,3e-3,1e-2,3e-2,0.1,0.3,1] [-alpha 1.5] [-masses 1,1] [-rtol 1e-11]
        [-output runs/restitution.npz] [-table runs/restitution.md] [-resume | -force]
    python scripts/restitution.py -beads steel,brass -radius 4.76mm -contact_coefficient 0.2s/m
        -impact_velocities 1mm/s,1cm/s,10cm/s,1m/s [-length_scale 1um]

Two free beads touching at rest overlap, bead 1 at velocity v towards bead 2; the flow until the contact opens;
e = (v2 - v1) / v after it, at rtol and 100 rtol (the refinement). -damping is Hunt-Crossley's c or Kuwabara-Kono's
eta; -unclipped lets a contact pull (the original papers' form). Records: schema hertzpetsc-restitution-1.

With -beads (hertzpetsc.units: one material for both beads, or two, e.g. steel,brass; -radius one or two) the two
beads are those (Hertz, alpha = 3/2; the masses from the beads) instead of -alpha, -masses; the damping in SI by
-contact_coefficient (Hunt-Crossley c in s/m, Kuwabara-Kono eta in N s/m^1.5) instead of -damping, the impact
velocities in SI by -impact_velocities instead of -velocities. The beads are free (no -static_force): the length
scale -length_scale (default 1 um) only sets the dimensionless units (e, and c v of Hunt-Crossley, do not depend
on it). The table adds a section in SI units (v in m/s).
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.model import law_options  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.contacts import ROLES, Restitution, RestitutionParameters  # noqa: E402
from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.units import bead_options, impact_damping, si_numbers  # noqa: E402


def main():
    opts = AppOptions(__doc__, ROLES)
    p = opts.parameters(RestitutionParameters)
    law_options(opts, supported=False)      # -law: refused but hertz
    output = opts.path("output", "runs/restitution.npz", "restitution file (record store)")
    mode = opts.mode()
    table_path = opts.path("table", "runs/restitution.md", "table")
    beads = bead_options(opts, ("alpha", "masses"), length_scale="1um", free="the two beads of an impact are free "
                         "(no static force; -length_scale sets the units)")
    coefficient = opts.string("contact_coefficient", "", "-beads: the damping in SI units (Hunt-Crossley c, e.g. "
                              "0.2s/m; Kuwabara-Kono eta in N s/m^1.5), instead of -damping")
    si_velocities = si_numbers(opts, beads, "impact_velocities", "velocity", "impact velocities (e.g. 1cm/s)",
                               "velocities")
    opts.done()
    if beads is not None:
        if len(beads.masses) > 2:
            raise ParameterError("-beads", ",".join(b.material.name for b in beads.beads), "an impact is of two "
                                 "beads: give one material (both beads) or two")
        p.update(alpha=1.5, masses=tuple(beads.model().masses * (3 - len(beads.masses))))
        p["velocities"] = p["velocities"] if si_velocities is None else tuple(si_velocities)
    p["damping"] = damping = impact_damping(opts, beads, p["contact"], p["damping"], coefficient)
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path)
    study = Restitution(RestitutionParameters(**p), comm, output, mode)
    opts.check_unused()
    study.open()
    table = None
    if beads is not None:
        print0(beads.summary() + f"\n# {p['contact']} damping {damping:.6g} in the chain's units")

        def table():
            return study.table() + beads.table(study.store.records, [("v", "velocity", lambda r: r["v"])], [
                ("v", lambda r: r["v"]), ("e", lambda r: f"{float(r['e']):.12f}"),
                ("1 - e", lambda r: 1 - float(r["e"])), ("law", lambda r: r["law"])])
    print0(f"# {'v':>10} {'e':>16} {'1 - e':>13} {'law':>13}" + ("" if beads is None else f" {'v [m/s]':>10}"))
    text = study.run_to_table(table_path, lambda r: print0(
        f"  {float(r['v']):10.4g} {float(r['e']):16.12f} {1 - float(r['e']):13.6e} {float(r['law']):13.6e}"
        + ("" if beads is None else f" {beads.columns(r, [('v', 'velocity', lambda x: x['v'])])[0]:>10}")), table)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
