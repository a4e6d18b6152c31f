#!/usr/bin/env python3
"""Frequency (or amplitude) response of a driven, damped chain (issue 22): periodic responses by shooting, continued
with their Floquet multipliers, folds, period doublings, Neimark-Sacker points and period-doubled branches.

    mpiexec -n 2 python scripts/driven_response.py -N 20 -delta0 1 -gamma 0.02 -amplitude 0.2 -omega 0.3 -p_end 0.5

First response: -run_in periods from rest, then Newton; then pseudo-arclength to -p_end (events located and
confirmed by the multipliers on both sides) or -points values (-mode grid; events bracketed); -switch S steps on
each period-doubled branch. Records: hertzpetsc-driven-response-1 (docs/schemas.md).

In SI units (hertzpetsc.units): -beads steel -radius 4.76mm -static_force 10N -drive_amplitude 0.1um
-drive_frequency 10kHz [-p_end_si 12kHz] define the chain and the drive instead of -alpha, -delta0, -masses,
-amplitude, -omega (-gamma, -eta stay dimensionless: gamma m / tau in kg/s); each row is also shown with the
parameter in Hz (or um) and the force on the wall beyond the static force in N, and the table gets a section in SI units.

Dissipation in the contacts (hertzpetsc.dissipation; beside -gamma, -eta): -contact hunt-crossley|kuwabara-kono with
-contact_damping c (Hunt-Crossley's c or Kuwabara-Kono's eta in the chain's units); with -beads instead
-contact_coefficient 0.05s/m (SI) or -restitution 0.95 -impact_velocity 0.1m/s (a measured restitution); a contact
never pulls unless -unclipped. The multipliers' Liouville check then integrates tr Df along the orbit.
"""
import math
import os
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.continuation import Natural  # noqa: E402
from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs  # noqa: E402
from hertzpetsc.studies.driven import (EVENT_NAMES, MAX_POINTS, ResponseCurve, ResponseParameters,  # noqa: E402
                                       corner_arclength, drive_options)
from hertzpetsc.units import parse_quantity  # noqa: E402


def si_p_end(text, kind, opts, beads):
    """-p_end_si in SI units (refused without -beads, or with -p_end)."""
    if beads is None or opts.db.hasName("p_end"):
        raise ParameterError("-p_end_si", text, "is in SI units: give -beads, and not -p_end")
    value = parse_quantity("-p_end_si", text, kind)
    return 2 * math.pi * value if kind == "frequency" else value


def main():
    opts = AppOptions(__doc__, ResponseCurve.ROLES)
    drive, beads = drive_options(opts, beads=True)
    parameter = opts.string("parameter", "omega", "continuation parameter", choices=("omega", "amplitude"))
    p = opts.parameters(ResponseParameters, skip=("nmult",), p_end=0.3)
    p_end_si = opts.string("p_end_si", "", "-beads: the end value in SI units (a frequency for omega, e.g. 12kHz; "
                           "a length for amplitude), instead of -p_end")
    si_kind = "frequency" if parameter == "omega" else "length"
    if p_end_si and not opts.help:
        value = si_p_end(p_end_si, si_kind, opts, beads)          # refused first without -beads
        p["p_end"] = beads.from_si("angular_frequency" if parameter == "omega" else "length", value)
    mode = opts.string("mode", "arclength", "pseudo-arclength or a grid of values", choices=("arclength", "grid"))
    points = opts.integer("points", 200, "grid mode: number of parameter values (start and p_end included)", minimum=2,
                          maximum=MAX_POINTS + 1)          # the study's limit of the grid (the start excluded)
    ds = opts.real("ds", 0.02, "first arclength step")
    ds_max = opts.real("ds_max", 0.05, "largest arclength step (>= -ds)")
    max_corrector = opts.real("max_corrector", 1.5, "largest corrector distance, in steps (corners of the curve)",
                              valid=(lambda x: x > 0, "> 0"))
    grid_max_corrector = opts.real("grid_max_corrector", Natural.max_corrector, "grid mode: largest relative change "
                                   "of the state by one corrector before the step is halved (a long chain, whose "
                                   "response changes entirely between frequencies: large)",
                                   valid=(lambda x: x > 0, "> 0"))
    output, omode, table_path, figures = opts.record_table_figures(
        "runs/driven_response.npz", "driven-response file", "runs/driven_response.md", "the response figure")
    name = opts.string("name", "driven_response", "figure name (without .png)")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, table_path, figures=figures)
    p0 = drive.value(parameter)
    grid = None
    if mode == "grid":
        grid = [p0 + (p["p_end"] - p0) * k / (points - 1) for k in range(1, points)]
    algorithm = corner_arclength(ds, ds_max, max_corrector) if mode == "arclength" else \
        Natural(max_corrector=grid_max_corrector)
    study = ResponseCurve(ResponseParameters(drive, parameter, algorithm=algorithm, grid=grid, **p), comm, output,
                          omode)
    opts.check_unused()
    study.open()
    print0(f"# {drive.describe()}")
    si = None if beads is None else [(parameter, si_kind, lambda r: r["p"]), ("wall force - F0", "force",
                                                                             lambda r: r["force_right"])]
    if beads is not None:
        print0(beads.summary() + f"\n# damping gamma = {beads.to_si('damping', drive.gamma):.6g} kg/s")
    print0(f"# {'branch':>6} {parameter:>12} {'event':>16} {'rho':>10} {'residual':>9} {'force':>10}"
           + ("" if si is None else f" {'[Hz]' if parameter == 'omega' else '[um]':>12} {'dF [N]':>10}"))

    def show(r):
        ev = EVENT_NAMES[int(r["event"])] or ""
        print0(f"  {int(r['branch']):6d} {float(r['p']):12.8f} {ev:>16} {float(r['rho']):10.6f} "
               f"{float(r['residual']):9.1e} {float(r['force_right']):10.4g}"
               + ("" if si is None else " {:>12} {:>10}".format(*beads.columns(r, si))))

    def table():
        lead = [("branch", lambda r: r["branch"]), ("event", lambda r: EVENT_NAMES[int(r["event"])] or ""),
                (parameter, lambda r: r["p"])]
        return study.table() + ("" if si is None else beads.table(study.store.records, si, lead))
    text = study.run_to_table(table_path, show, table)  # on a stop: the table of the records done, then the error
    records = study.store.records
    study.destroy()
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        print("wrote " + plotting.plot_driven_response(records, parameter, figures, name + ".png",
                                                        os.path.basename(output)).path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
