"""The long-run file format: a run directory of snapshots written as they are taken (section 3.4).

A run directory holds ``run.json`` (what the run is: chain, initial state digest, tolerances, snapshot interval;
``format`` = ``hertzpetsc-longrun-2``) and ``snapshots.f64``, an append-only file of float64 records
``[t, energy, dt, x_1..x_N, xdot_1..xdot_N]``, each flushed to disk when taken (the record store's append layout,
:class:`hertzpetsc.records.AppendRecords`). ``dt`` is the time step the integrator will start the next interval
with, so that a resumed run repeats the uninterrupted one's arithmetic: a killed run loses at most the interval in
flight and resumes to the same trajectory. Resuming with another run's parameters is refused. Directories of the
first format (no ``format`` key, records ``[t, energy, x, xdot]``) are still read, but cannot be resumed exactly.
Read without PETSc: ``np.fromfile(path).reshape(-1, 3 + 2N)``.
"""
import hashlib
import os
from dataclasses import dataclass

import numpy as np

from .errors import ParameterError, RecordFileError, check_real
from .records import AppendRecords, Column, Kind

LONGRUN_FORMAT = "hertzpetsc-longrun-2"
# run.json's keys (constants) and the parts of each snapshot record, in their order (fields)
LONGRUN_KIND = Kind(LONGRUN_FORMAT, (
    Column("alpha", "Hertz exponent", constant=True),
    Column("N", "beads of the periodic chain", "count", int, "d", constant=True),
    Column("boundary", "`periodic`", "", str, "s", constant=True),
    Column("q", "wavenumber of the wave", constant=True),
    Column("T", "script-T (eq. invv)", constant=True),
    Column("initial_state", "`refined` or the branch", "", str, "s", constant=True),
    Column("initial_state_sha256", "digest of the initial (N, 2) float64 state", "", str, "s", constant=True),
    Column("snapshot_dt", "script-T / snapshots_per_T", constant=True),
    Column("rtol", "the flow's relative tolerance", constant=True),
    Column("atol", "the flow's absolute tolerance", constant=True),
    Column("ts", "the TS and RK types", "", str, "s", constant=True),
    Column("masses", "the mass pattern", shape="p", constant=True),
    Column("t", "time of the snapshot"),
    Column("energy", "the chain's energy"),
    Column("dt", "the step the integrator starts the next interval with (what makes a resume repeat the "
           "uninterrupted run)"),
    Column("x", "positions x_1 .. x_N", shape="N"),
    Column("xdot", "velocities xdot_1 .. xdot_N", shape="N"),
))
HEADER, DATA = "run.json", "snapshots.f64"
# header keys that define a run: resuming requires them to be equal
IDENTITY = ("alpha", "N", "boundary", "initial_state_sha256", "snapshot_dt", "rtol", "atol", "ts")


def state_digest(state):
    return hashlib.sha256(np.ascontiguousarray(np.asarray(state, dtype=np.float64)).tobytes()).hexdigest()


@dataclass
class Snapshots:
    """The records of a run directory: times, energies, integrator steps dt (nan for the first format) and
    states (n, N, 2)."""

    header: dict
    times: np.ndarray
    energies: np.ndarray
    steps: np.ndarray
    states: np.ndarray


def record_length(N):
    return 3 + 2 * int(N)


def snapshot_store(directory, header, comm, mode):
    """The record store of a long run (collective). ``header`` must hold the :data:`IDENTITY` keys and N."""
    if mode == "resume":
        stored = AppendRecords.read_header(directory) if os.path.exists(os.path.join(directory, HEADER)) else {}
        if stored and stored.get("format") != LONGRUN_FORMAT:
            raise RecordFileError(f"{directory!r} was written by an older hertzpetsc (no integrator step in its "
                                  "records): it can be read, but not resumed exactly; rerun with -force")
    return AppendRecords(directory, LONGRUN_FORMAT, header, {k: header[k] for k in IDENTITY},
                         record_length(header["N"]), comm, mode, HEADER, DATA, what="run directory",
                         columns=LONGRUN_KIND)


def snapshot_record(t, energy, dt, state):
    state = np.asarray(state, dtype=np.float64)
    return np.concatenate([[t, energy, dt], state[:, 0], state[:, 1]])


def decode(rows, N, has_step=True):
    """Snapshots fields from an (n, record) array."""
    rows = np.asarray(rows, dtype=np.float64).reshape(len(rows), -1)
    k = 3 if has_step else 2
    steps = rows[:, 2] if has_step else np.full(len(rows), np.nan)
    states = np.stack([rows[:, k:k + N], rows[:, k + N:]], axis=2)
    return rows[:, 0], rows[:, 1], steps, states


def read_snapshots(directory):
    """All complete records of a run directory (either format), without PETSc."""
    header = AppendRecords.read_header(directory)
    N = int(header["N"])
    has_step = header.get("format") == LONGRUN_FORMAT
    length = record_length(N) if has_step else 2 + 2 * N
    path = os.path.join(directory, DATA)
    raw = np.fromfile(path, dtype=np.float64) if os.path.exists(path) else np.zeros(0)
    n = len(raw) // length
    times, energies, steps, states = decode(raw[:n * length].reshape(n, length), N, has_step)
    return Snapshots(header, times, energies, steps, states)


def check_times(t_final, snapshot_dt):
    for name, v in (("t_final", t_final), ("snapshot_dt", snapshot_dt)):
        check_real(name, v, "the time", 0.0)
    if snapshot_dt > t_final:
        raise ParameterError("snapshot_dt", snapshot_dt, f"must not exceed t_final = {t_final}")


def wave_deviation(times, states, x0, T, tol=1e-9):
    """D(t) = ||S^k X(t) - X(0)||_inf / ||X(0)||_inf at the snapshot times t = k script-T (k integer).

    An exact travelling wave has S^k X(k script-T) = X(0); returns (times, D) at those snapshots.
    """
    k = times / T
    on = np.abs(k - np.round(k)) < tol * np.maximum(1.0, k)
    scale = np.max(np.abs(x0))
    D = [np.max(np.abs(np.roll(s, -int(round(kk)), axis=0) - x0)) / scale for s, kk in zip(states[on], k[on])]
    return times[on], np.array(D)


def first_crossing(times, values, level):
    """First time at which ``values`` exceeds ``level`` (nan if never)."""
    above = np.nonzero(np.asarray(values) > level)[0]
    return float(times[above[0]]) if len(above) else float("nan")
