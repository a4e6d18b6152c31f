#!/usr/bin/env python3
"""A pulse launched into a long Hertz chain with dissipation in the contacts: its amplitude along the chain and the
decay law (A^p linear in the bead index: p = -1 Hunt-Crossley, p = -1/5 Kuwabara-Kono for Hertz).

    python scripts/pulse_decay.py [-contact hunt-crossley|kuwabara-kono] [-damping 0.01] [-unclipped]
        [-velocities 1,0.5] [-N 200] [-skip 20] [-sample 0.02] [-alpha 1.5] [-rtol 1e-10]
        [-output runs/pulse_decay.npz] [-table runs/pulse_decay.md] [-resume | -force]

A free chain of N beads at rest, bead 0 launched at each velocity v0; the amplitude A_n of bead n is its largest
velocity (sampled every -sample, the peak interpolated by a parabola); the decay law fitted over beads
-skip..N - 1 - -skip: the exponent p whose A^p is most nearly linear, and d(A^p)/dn per unit damping at the law's p
(the same for every v0 where the law holds). Records: schema hertzpetsc-pulse-1.
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.model import law_options  # noqa: E402
from hertzpetsc.dissipation import KINDS  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.contacts import ROLES, PulseDecay, PulseParameters  # noqa: E402


def main():
    opts = AppOptions(__doc__, ROLES)
    contact = opts.string("contact", "hunt-crossley", "the contact dissipation", choices=tuple(KINDS))
    damping = opts.real("damping", 0.01, "Hunt-Crossley c or Kuwabara-Kono eta", valid=(lambda x: x > 0, "> 0"))
    unclipped = opts.flag("unclipped", "let a contact pull (no clipping of the contact force at 0)")
    velocities = opts.numbers("velocities", "1,0.5", "striker velocities v0", expr=False,
                              valid=(lambda v: v > 0, "> 0"), distinct=True)
    N = opts.integer("N", 200, "beads", minimum=10)
    skip = opts.integer("skip", 20, "beads left out of the fit at each end", minimum=0)
    sample = opts.real("sample", 0.02, "sampling interval of the velocities", valid=(lambda x: 0 < x < 1, "in (0, 1)"))
    alpha = opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda a: a > 1, "> 1"))
    law_options(opts, supported=False)      # -law: refused but hertz
    rtol = opts.real("rtol", 1e-10, "flow tolerance", valid=(lambda x: 0 < x < 1e-4, "in (0, 1e-4)"))
    output = opts.path("output", "runs/pulse_decay.npz", "pulse file (record store)")
    mode = opts.mode()
    table_path = opts.path("table", "runs/pulse_decay.md", "table")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path)
    study = PulseDecay(PulseParameters(contact, damping, tuple(velocities), N, not unclipped, alpha, skip, sample,
                                       rtol), comm, output, mode)
    opts.check_unused()
    study.open()
    print0(f"# {'v0':>8} {'A_skip':>10} {'A_last':>10} {'p fitted':>9}")
    text = study.run_to_table(table_path, lambda r: print0(
        f"  {float(r['v0']):8.4g} {float(r['amplitude'][skip]):10.6f} {float(r['amplitude'][N - 1 - skip]):10.6f} "
        f"{float(r['p_fit']):9.4f}"))
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
