#!/usr/bin/env python3
"""Figures and table of the long runs (paper section 3.4, figs. stabletw, unstabletw, shockbis, structures).

    python scripts/dynamics_figures.py -runs runs/q3pi10,runs/q7pi25,runs/q9pi50,runs/qpi50 -figures figures \
        -table results/long_runs.md

For each run directory written by long_run.py (either snapshot format): the displacements at the last snapshot
taken after a whole number of time periods against the initial state, the interaction forces V'(x_{n+1} - x_n)
in grey levels over the last 220 time units (or over a window given as dir:T0:T1), and the deviation D(t) from
the travelling wave for all runs in one plot. The table lists, per run, the destruction time (first D > 0.1),
the first times D > 1e-6 and 1e-3, max D, and the relative energy drift.
"""
import json
import os
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from hertzpetsc import plotting  # noqa: E402
from hertzpetsc.errors import ParameterError, RecordFileError  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_output, write_text  # noqa: E402
from hertzpetsc.simulation import read_snapshots, wave_deviation  # noqa: E402


def parse_run(spec):
    """dir or dir:t0:t1."""
    parts = spec.split(":")
    if len(parts) not in (1, 3) or not parts[0]:
        raise ParameterError("-runs", spec, "each run is a directory, or directory:t0:t1")
    try:
        window = (float(parts[1]), float(parts[2])) if len(parts) == 3 else None
    except ValueError:
        raise ParameterError("-runs", spec, "the window t0:t1 must be two numbers") from None
    return parts[0], window


def read_run(d):
    """The snapshots and the summary of a finished long run (RecordFileError naming the run otherwise)."""
    snaps = read_snapshots(d)
    try:
        with open(os.path.join(d, "summary.json")) as f:
            summary = json.load(f)
    except (OSError, ValueError):
        raise RecordFileError(f"run {d!r} has no readable summary.json (finish it with long_run.py -resume)")
    if len(snaps.times) == 0:
        raise RecordFileError(f"run {d!r} has no snapshot")
    return snaps, summary


def main():
    opts = AppOptions(__doc__)
    runs = opts.path("runs", "", "comma-separated run directories, each optionally dir:t0:t1")
    figures = opts.path("figures", "runs/figures", "directory for the figures")
    table = opts.path("table", "runs/long_runs.md", "table")
    opts.done()
    specs = [parse_run(s) for s in runs.split(",")] if runs.strip() else []
    if not specs:
        raise ParameterError("-runs", runs, "must name at least one run directory")
    loaded = [(d, window, *read_run(d)) for d, window in specs]
    alphas = sorted({float(snaps.header["alpha"]) for _, _, snaps, _ in loaded})
    if len(alphas) > 1:                         # one table, one chain: its rows name q, not alpha
        raise ParameterError("-runs", runs, "must name runs of one Hertz exponent: these are of alpha = "
                             + ", ".join(f"{a:g}" for a in alphas))
    prepare_output(table)
    prepare_output(os.path.join(figures, "deviation.png"), what="figure")
    opts.check_unused()
    rank0 = PETSc.COMM_WORLD.getRank() == 0     # figures are drawn on rank 0
    rows = ["| run | q | script-T | initial state | t_final | destruction time (D > 0.1) | D > 1e-6 at | "
            "D > 1e-3 at | max D | energy drift | integrator |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    deviations = {}
    for d, window, snaps, s in loaded:
        name = os.path.basename(os.path.normpath(d))
        header, t, X = snaps.header, snaps.times, snaps.states
        t0, t1 = window if window else (max(0.0, t[-1] - 220), t[-1])
        sel = (t >= t0) & (t <= t1)
        title = f"q = {header['q']:.4f}, N = {header['N']}"
        # the last snapshot after a whole number of time periods tau = 2 pi script-T / q: an intact wave is then
        # back on the initial state, unshifted (as in fig. stabletw)
        periods = t / (2 * np.pi * header["T"] / header["q"])
        whole = np.nonzero(np.abs(periods - np.round(periods)) < 1e-6 * np.maximum(1, periods))[0]
        j = whole[-1] if len(whole) else len(t) - 1
        if rank0:
            plotting.plot_snapshot(X[0, :, 0], X[j, :, 0], t[j], figures, f"{name}_snapshot.png", title)
            plotting.plot_spacetime_forces(t[sel], X[sel], header["alpha"], figures, f"{name}_forces.png",
                                           title + f", t in [{t0:.0f}, {t1:.0f}]")
        deviations[f"q = {header['q']:.4f}"] = wave_deviation(t, X, X[0], header["T"])
        rows.append(f"| {name} | {header['q']:.4f} | {header['T']:.4f} | {header['initial_state']} | "
                    f"{s['t_final']:.0f} | {s['destruction_time']:.1f} | {s['time_D_above_1em6']:.1f} | "
                    f"{s['time_D_above_1em3']:.1f} | {s['max_deviation']:.2e} | {s['energy_drift']:.1e} | "
                    f"{s['ts']}, rtol {s['rtol']:g} |")
    if rank0:
        plotting.plot_deviation(deviations, figures)
    text = ("D(t) = ||S^k X(k script-T) - X(0)||_inf / ||X(0)||_inf; 'nan' = never reached.\n\n"
            + "\n".join(rows) + "\n")
    write_text(table, text)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
