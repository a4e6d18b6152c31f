#!/usr/bin/env python3
"""Figures and table of the long runs (paper section 3.4, figs. stabletw, unstabletw, shockbis, structures).

    python scripts/dynamics_figures.py -runs runs/q3pi10,runs/q7pi25,runs/q9pi50,runs/qpi50 -figures figures \
        -table results/long_runs.md

For each run directory written by long_run.py: the displacements at the last snapshot taken after a whole
number of time periods against the initial state, the interaction forces V'(x_{n+1} - x_n) in grey levels over the last 220 time units (or around
-window T0,T1 when given as name:T0:T1), and the deviation D(t) from the travelling wave for all runs in one
plot. The table lists, per run, the destruction time (first D > 0.1), the first times D > 1e-6 and 1e-3,
max D, and the relative energy drift. Needs numpy and matplotlib only.
"""
import argparse
import json
import os
import sys

import numpy as np

from hertzpetsc import plotting
from hertzpetsc.errors import HertzPetscError
from hertzpetsc.simulation import SnapshotFile, wave_deviation


def load(directory):
    snaps = SnapshotFile.open(directory)
    t, E, X = snaps.read()
    with open(os.path.join(directory, "summary.json")) as f:
        summary = json.load(f)
    return snaps.header, summary, t, E, X


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-runs", required=True, help="comma-separated run directories, each optionally dir:t0:t1")
    ap.add_argument("-figures", default="figures")
    ap.add_argument("-table", default="results/long_runs.md")
    args = ap.parse_args(argv)
    os.makedirs(args.figures, exist_ok=True)
    rows = ["| run | q | script-T | initial state | t_final | destruction time (D > 0.1) | D > 1e-6 at | "
            "D > 1e-3 at | max D | energy drift | integrator |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    deviations = {}
    try:
        for spec in args.runs.split(","):
            parts = spec.split(":")
            d = parts[0]
            name = os.path.basename(os.path.normpath(d))
            header, s, t, E, X = load(d)
            t0, t1 = (float(parts[1]), float(parts[2])) if len(parts) == 3 else (max(0.0, t[-1] - 220), t[-1])
            sel = (t >= t0) & (t <= t1)
            title = f"q = {header['q']:.4f}, N = {header['N']}"
            # the last snapshot after a whole number of time periods tau = 2 pi script-T / q: an intact wave is
            # then back on the initial state, unshifted (as in fig. stabletw)
            periods = t / (2 * np.pi * header["T"] / header["q"])
            whole = np.nonzero(np.abs(periods - np.round(periods)) < 1e-6 * np.maximum(1, periods))[0]
            j = whole[-1] if len(whole) else len(t) - 1
            plotting.plot_snapshot(X[0, :, 0], X[j, :, 0], t[j], args.figures, f"{name}_snapshot.png", title)
            plotting.plot_spacetime_forces(t[sel], X[sel], header["alpha"], args.figures, f"{name}_forces.png",
                                           title + f", t in [{t0:.0f}, {t1:.0f}]")
            deviations[f"q = {header['q']:.4f}"] = wave_deviation(t, X, X[0], header["T"])
            rows.append(f"| {name} | {header['q']:.4f} | {header['T']:.4f} | {header['initial_state']} | "
                        f"{s['t_final']:.0f} | {s['destruction_time']:.1f} | {s['time_D_above_1em6']:.1f} | "
                        f"{s['time_D_above_1em3']:.1f} | {s['max_deviation']:.2e} | {s['energy_drift']:.1e} | "
                        f"{s['ts']}, rtol {s['rtol']:g} |")
    except (HertzPetscError, OSError, KeyError) as err:
        print(f"error: cannot read the runs: {err}", file=sys.stderr)
        return 4
    plotting.plot_deviation(deviations, args.figures)
    text = ("D(t) = ||S^k X(k script-T) - X(0)||_inf / ||X(0)||_inf; 'nan' = never reached.\n\n"
            + "\n".join(rows) + "\n")
    with open(args.table, "w") as f:
        f.write(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
