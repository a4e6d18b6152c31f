"""Long chain simulations with snapshots written as they are taken (paper section 3.4, figs. stabletw ...).

A run directory holds ``run.json`` (what the run is: chain, initial state digest, tolerances, snapshot interval)
and ``snapshots.f64``, an append-only file of float64 records ``[t, energy, x_1..x_N, xdot_1..xdot_N]``, each
flushed to disk when taken. A killed run loses at most the interval in flight: resuming reads the last complete
record (a partial trailing record is discarded) and integrates on from it. Resuming with another run's
parameters is refused. Read without PETSc: ``np.fromfile(path).reshape(-1, 2 + 2N)``.
"""
import hashlib
import json
import os
from dataclasses import dataclass

import numpy as np

from .errors import ParameterError, RunFileError


# header keys that define a run: resuming requires them to be equal
IDENTITY = ("alpha", "N", "boundary", "initial_state_sha256", "snapshot_dt", "rtol", "atol", "ts")


def state_digest(state):
    return hashlib.sha256(np.ascontiguousarray(np.asarray(state, dtype=np.float64)).tobytes()).hexdigest()


class SnapshotFile:
    """The snapshot record file of a run directory (open on one rank only for writing)."""

    def __init__(self, directory, header):
        self.directory = directory
        self.header = header
        self.record = 2 + 2 * int(header["N"])
        self.path = os.path.join(directory, "snapshots.f64")

    @classmethod
    def create(cls, directory, header):
        os.makedirs(directory, exist_ok=True)
        tmp = os.path.join(directory, "run.json.tmp")
        with open(tmp, "w") as f:
            json.dump(header, f, indent=1)
        os.replace(tmp, os.path.join(directory, "run.json"))
        open(os.path.join(directory, "snapshots.f64"), "wb").close()
        return cls(directory, header)

    @classmethod
    def open(cls, directory, expected=None):
        """Open an existing run; if ``expected`` is given its identity keys must match the stored header."""
        path = os.path.join(directory, "run.json")
        if not os.path.exists(path):
            raise RunFileError(f"no run to resume in {directory!r} (run.json missing)")
        try:
            with open(path) as f:
                header = json.load(f)
        except ValueError:
            raise RunFileError(f"{path!r} is corrupt") from None
        if expected is not None:
            for key in IDENTITY:
                if header.get(key) != expected.get(key):
                    raise RunFileError(f"the snapshots in {directory!r} belong to another run: {key} = "
                                       f"{header.get(key)!r} there, {expected.get(key)!r} requested")
        return cls(directory, header)

    def read(self):
        """(times, energies, states (n, N, 2)) of the complete records."""
        raw = np.fromfile(self.path, dtype=np.float64) if os.path.exists(self.path) else np.zeros(0)
        n = len(raw) // self.record
        rec = raw[: n * self.record].reshape(n, self.record)
        N = int(self.header["N"])
        states = np.stack([rec[:, 2:2 + N], rec[:, 2 + N:]], axis=2)
        return rec[:, 0], rec[:, 1], states

    def truncate_partial(self):
        """Drop a partial trailing record left by a killed run."""
        size = os.path.getsize(self.path)
        whole = size // (8 * self.record) * 8 * self.record
        if whole != size:
            with open(self.path, "r+b") as f:
                f.truncate(whole)

    def append(self, t, energy, state):
        state = np.asarray(state, dtype=np.float64)
        rec = np.concatenate([[t, energy], state[:, 0], state[:, 1]])
        with open(self.path, "ab") as f:
            f.write(rec.tobytes())
            f.flush()
            os.fsync(f.fileno())


@dataclass
class RunSummary:
    t_final: float
    snapshots: int
    steps: int
    energy_drift: float
    wall_time: float


def check_times(t_final, snapshot_dt):
    for name, v in (("t_final", t_final), ("snapshot_dt", snapshot_dt)):
        if not (np.isfinite(v) and v > 0):
            raise ParameterError(name, v, "must be a positive time")
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
