#!/usr/bin/env python3
"""From a chain's datasheet to its dimensionless model (hertzpetsc.units): the contact constant, the scales, the
sound speed and cut-off frequency in SI (closed forms against the package's linear lattice converted back), and the
solitary wave's speed in m/s at given maximal bead velocities (the uncompressed chain of the same beads).

    python scripts/beads_to_waves.py [-beads steel] [-radius 4.76mm] [-static_force 10N]
        [-max_velocity 0.01m/s,0.1m/s,1m/s] [-cells 80,160,320] [-output runs/beads_to_waves.md]

-beads: materials of hertzpetsc.materials (steel, chrome_steel, brass, aluminium, glass, ptfe, or custom with
-youngs, -poisson, -density); the solitary wave needs one material.
The numbers of docs/from-beads-to-waves.md are this driver's default output.
"""
import math
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs, write_text  # noqa: E402
from hertzpetsc.roles import configure, uses  # noqa: E402
from hertzpetsc.studies.solitary import unit_wave_velocity  # noqa: E402
from hertzpetsc.units import BeadChain, bead_options, parse_quantity  # noqa: E402

# the closed-form check's wavenumber for c0: omega(q)/q = c0 (1 - q^2/24 + ...)
Q_SOUND = 1e-3


def main():
    opts = AppOptions(__doc__, uses("sol_"))
    velocities = opts.string("max_velocity", "0.01m/s,0.1m/s,1m/s", "maximal bead velocities of the solitary "
                             "waves, comma-separated")
    cells = opts.numbers("cells", "80,160,320", "three grids n of the solitary wave (step 1/n, even), for the "
                         "extrapolation", expr=False, kind=int,
                         valid=(lambda n: 2 <= n <= 10 ** 5 and n % 2 == 0, "an even integer in [2, 1e5]"),
                         distinct=True, minimum_count=3)
    output = opts.path("output", "runs/beads_to_waves.md", "table")
    chain = bead_options(opts, replaces=(), beads="steel", static_force="10N")      # the page's steel chain
    opts.done()
    if chain is None:
        raise ParameterError("-beads", "", "give the beads' materials (e.g. steel)")
    if len(cells) != 3:
        raise ParameterError("-cells", cells, "three grids for the extrapolation")
    vs = [parse_quantity("-max_velocity", v.strip(), "velocity") for v in velocities.split(",")]
    if not vs or not all(v > 0 for v in vs):
        raise ParameterError("-max_velocity", velocities, "velocities > 0, comma-separated (e.g. 0.1m/s)")
    if chain.static_force <= 0:
        raise ParameterError("-static_force", chain.static_force, "the sound speed and cut-off need a "
                             "precompression > 0")
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, output)
    configure(uses("sol_"), comm)
    opts.check_unused()

    model = chain.model()
    lines = ["# From the datasheet to the waves (hertzpetsc.units)", "", "## The chain and its scales", "",
             "\n\n".join(x[2:] for x in chain.summary().splitlines()), "",
             f"dimensionless model: {model.describe()}", "",
             "## Linear waves: the package's lattice converted to SI against the closed forms", "",
             "| quantity | lattice, in SI | closed form | relative difference |", "|---|---|---|---|"]
    f_c = chain.to_si("frequency", max(model.linear_frequencies(math.pi)))
    c0 = chain.to_si("speed", model.linear_frequencies(Q_SOUND)[0] / Q_SOUND)
    for name, got, want, unit in (("cut-off frequency f_c", f_c, chain.cutoff_frequency(), "Hz"),
                                  (f"sound speed c0 (omega(q)/q at q = {Q_SOUND:g})", c0, chain.sound_speed(),
                                   "m/s")):
        lines.append(f"| {name} | {got:.7g} {unit} | {want:.7g} {unit} | {abs(got / want - 1):.1e} |")
    print0("\n".join(lines))
    if len(chain.masses) == 1:
        free = BeadChain(chain.beads, 0.0, chain.L)
        v1, order, L = unit_wave_velocity(1.5, tuple(sorted(cells)))
        sol = ["", "## Solitary waves of the uncompressed chain (static force 0)", "",
               f"maximal bead velocity of the unit-speed wave (eq. adr): v1 = {v1:.7f} (Richardson from n = "
               f"{', '.join(map(str, sorted(cells)))} on [-{L:g}, {L:g}], observed order {order:.2f}); the speed "
               "at the maximal bead velocity v is c = (v / v1)^(1/5) in units of 2R / tau (tau of any length "
               "scale); Nesterenko's long-wave formula 0.9314 (4 E^2 / (pi^2 rho^2 (1 - nu^2)^2))^(1/5) v^(1/5) "
               "beside it (the continuum limit, one material).", "",
               "| v_max [m/s] | speed [m/s] | Nesterenko (long wave) [m/s] |", "|---|---|---|"]
        mat = chain.beads[0].material
        for v in vs:
            nest = 0.9314 * (4 * mat.youngs ** 2 / (math.pi ** 2 * mat.density ** 2 * (1 - mat.poisson ** 2) ** 2)) \
                ** 0.2 * v ** 0.2
            sol.append(f"| {v:g} | {free.solitary_speed(v, v1):.5g} | {nest:.5g} |")
        print0("\n".join(sol))
        lines += sol
    write_text(output, "\n".join(lines) + "\n", comm)
    print0(f"wrote {output}")


if __name__ == "__main__":
    guarded_main(main)
