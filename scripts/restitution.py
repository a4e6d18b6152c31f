#!/usr/bin/env python3
"""The coefficient of restitution of a two-bead impact with dissipation in the contact, against the impact velocity,
and its small-dissipation law (Hunt-Crossley: 1 - e = c v; Kuwabara-Kono: 1 - e = C eta v^(1/5) for Hertz).

    python scripts/restitution.py [-contact hunt-crossley|kuwabara-kono] [-damping 0.1] [-unclipped]
        [-velocities 1e-3,3e-3,1e-2,3e-2,0.1,0.3,1] [-alpha 1.5] [-masses 1,1] [-rtol 1e-11]
        [-output runs/restitution.npz] [-table runs/restitution.md] [-resume | -force]

Two free beads touching at rest overlap, bead 1 at velocity v towards bead 2; the flow until the contact opens;
e = (v2 - v1) / v after it, at rtol and 100 rtol (the refinement). -damping is Hunt-Crossley's c or Kuwabara-Kono's
eta; -unclipped lets a contact pull (the original papers' form). Records: schema hertzpetsc-restitution-1.
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.model import law_options  # noqa: E402
from hertzpetsc.dissipation import KINDS  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.contacts import ROLES, Restitution, RestitutionParameters  # noqa: E402


def main():
    opts = AppOptions(__doc__, ROLES)
    contact = opts.string("contact", "hunt-crossley", "the contact dissipation", choices=tuple(KINDS))
    damping = opts.real("damping", 0.1, "Hunt-Crossley c or Kuwabara-Kono eta", valid=(lambda x: x >= 0, ">= 0"))
    unclipped = opts.flag("unclipped", "let a contact pull (no clipping of the contact force at 0)")
    velocities = opts.numbers("velocities", "1e-3,3e-3,1e-2,3e-2,0.1,0.3,1", "impact velocities", expr=False,
                              valid=(lambda v: v > 0, "> 0"), distinct=True)
    alpha = opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda a: a > 1, "> 1"))
    law_options(opts, supported=False)      # -law: refused but hertz
    masses = opts.numbers("masses", "1,1", "the two beads' masses", expr=False, valid=(lambda m: m > 0, "> 0"),
                          minimum_count=2)
    rtol = opts.real("rtol", 1e-11, "flow tolerance (also 100 rtol: the refinement)",
                     valid=(lambda x: 0 < x < 1e-4, "in (0, 1e-4)"))
    output = opts.path("output", "runs/restitution.npz", "restitution file (record store)")
    mode = opts.mode()
    table_path = opts.path("table", "runs/restitution.md", "table")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path)
    study = Restitution(RestitutionParameters(contact, damping, tuple(velocities), not unclipped, alpha,
                                              tuple(masses), rtol), comm, output, mode)
    opts.check_unused()
    study.open()
    print0(f"# {'v':>10} {'e':>16} {'1 - e':>13} {'law':>13}")
    text = study.run_to_table(table_path, lambda r: print0(
        f"  {float(r['v']):10.4g} {float(r['e']):16.12f} {1 - float(r['e']):13.6e} {float(r['law']):13.6e}"))
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
