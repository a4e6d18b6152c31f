"""Long runs of a travelling wave on a periodic chain (section 3.4, figs. stabletw, unstabletw, shockbis): snapshots
written as they are taken (:mod:`hertzpetsc.simulation`), exact resume, and the summary of what happened.

D(t) = ||S^k X(k script-T) - X(0)||_inf / ||X(0)||_inf is the distance to the exact travelling wave at the
multiples of script-T; the wave counts as destroyed when D > 0.1 (paper: stable at q = 3pi/10 over t ~ 4000,
destroyed near t ~ 360 at q = 7pi/25).
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Callable, Optional

import numpy as np

from ..chain import CHAIN_PREFIX, Chain, ChainIntegrator
from ..errors import ParameterError, check_instance, check_integer, check_real
from ..resources import INTEGRATE_SECONDS, chain_seconds, check_chain_memory, check_work
from ..records import write_json
from ..roles import uses
from ..simulation import (check_times, decode, first_crossing, snapshot_record, snapshot_store, state_digest,
                          wave_deviation)
from ..waves import Orbit
from .base import Study

if TYPE_CHECKING:
    from petsc4py import PETSc

    from ..waves import Orbit

DESTRUCTION_LEVEL = 0.1


@dataclass(frozen=True)
class LongRunSummary:
    """What a long run shows (``summary.json`` in its directory)."""

    q: float
    N: int
    T: float
    initial_state: str
    t_final: float
    snapshots: int
    steps_this_session: int
    wall_time_this_session: float
    energy_drift: float
    max_deviation: float
    destruction_level: float
    destruction_time: float
    time_D_above_1em6: float
    time_D_above_1em3: float
    ts: str
    rtol: float
    atol: float

    def as_dict(self):
        return asdict(self)


class LongRun(Study):
    """The orbit integrated to ``t_final`` with ``snapshots_per_T`` snapshots per script-T into the run directory
    ``output`` (TS prefix ``chain_``; default RK 8(7), rtol 1e-12, atol 1e-14 as the paper). ``mode='resume'``
    continues a killed run from its last snapshot, with the integrator's step, to the same trajectory."""

    ROLES = uses(CHAIN_PREFIX)
    WHAT = "run directory"

    def __init__(self, orbit: Orbit, t_final: float, snapshots_per_T: int, output: str,
                 comm: Optional[PETSc.Comm] = None, mode: str = "new", prefix: str = CHAIN_PREFIX) -> None:
        super().__init__(None, comm, output, mode)
        self.orbit = check_instance("orbit", orbit, Orbit, "an Orbit (hz.orbit, a refined wave)")
        t_final = check_real("t_final", t_final, "the final time", 0.0)
        snapshots_per_T = check_integer("snapshots_per_T", snapshots_per_T, 1, "the snapshots per script-T")
        self.dt_snap = orbit.T / snapshots_per_T
        if t_final > 0 and self.dt_snap > t_final:       # the interval is derived: name the two arguments
            raise ParameterError("t_final", t_final, f"must be >= script-T / snapshots_per_T = {self.dt_snap:.6g} "
                                 f"(one snapshot interval, script-T = {orbit.T:.6g}): increase t_final or "
                                 "snapshots_per_T")
        check_times(t_final, self.dt_snap)
        check_work("t_final", t_final, chain_seconds(orbit.N, t_final), f"a run of {orbit.N} beads to t = {t_final:g}")
        snapshots = t_final / self.dt_snap
        check_work("snapshots_per_T", snapshots_per_T, snapshots * INTEGRATE_SECONDS,
                   f"{snapshots:.3g} snapshots (one integration each)")
        check_chain_memory(orbit.N, self.comm)
        self.t_final, self.snapshots_per_T = t_final, snapshots_per_T
        self.chain = Chain(orbit.spec, self.comm)
        self.integrator = ChainIntegrator(self.chain, prefix=prefix)
        ts = self.integrator.ts
        rtol, atol = ts.getTolerances()
        self.header = dict(alpha=orbit.spec.model.alpha, N=orbit.N, boundary="periodic", q=orbit.q, T=orbit.T,
                           initial_state=orbit.source, initial_state_sha256=state_digest(orbit.x),
                           snapshot_dt=self.dt_snap, rtol=rtol, atol=atol, ts=f"{ts.getType()} {ts.getRKType()}",
                           masses=list(orbit.spec.model.masses))
        self.steps, self.wall = 0, 0.0

    def _open(self):
        """The run directory (collective): a new one, or the snapshots of the run to resume."""
        return snapshot_store(self.output, self.header, self.comm, self.mode)

    @property
    def resumed_at(self) -> float:
        """The time of the last snapshot found when the run was opened (nan for a new run)."""
        return float(self.store.records[-1][0]) if self.store.records else math.nan

    def run(self, progress: Optional[Callable[[float, float, int], None]] = None,
            every: int = 50) -> None:
        """Integrate from the last snapshot to t_final; ``progress(t, energy_drift, steps)`` is called every
        ``every`` script-T."""
        self.open()
        chain, integ = self.chain, self.integrator
        X = chain.create_state()
        try:
            if self.store.records:
                times, _, steps, states = decode(np.asarray(self.store.records[-1])[None, :], self.orbit.N)
                t, dt, x = float(times[0]), float(steps[0]), states[0]
                chain.set_from_array(X, x)
                E0 = float(self.store.records[0][1])
            else:
                x, t = self.orbit.x, 0.0
                chain.set_from_array(X, x)
                E0 = chain.energy(X)
                dt = integ.ts.getTimeStep()
                self.store.append(snapshot_record(0.0, E0, dt, x))
            k = int(round(t / self.dt_snap))
            t0 = time.perf_counter()
            per_progress = self.snapshots_per_T * every
            while (k + 1) * self.dt_snap <= self.t_final * (1 + 1e-12):
                self.steps += integ.integrate(X, k * self.dt_snap, (k + 1) * self.dt_snap, dt=dt)
                dt = integ.ts.getTimeStep()
                k += 1
                E = chain.energy(X)
                self.store.append(snapshot_record(k * self.dt_snap, E, dt, chain.gather(X)))
                if progress is not None and k % per_progress == 0:
                    progress(k * self.dt_snap, (E - E0) / E0, self.steps)
            self.wall += time.perf_counter() - t0
        finally:
            X.destroy()

    def summary(self) -> LongRunSummary:
        times, energies, _, states = decode(np.array(self.store.records), self.orbit.N)
        tD, D = wave_deviation(times, states, states[0], self.orbit.T)
        h = self.header
        return LongRunSummary(q=self.orbit.q, N=self.orbit.N, T=self.orbit.T, initial_state=h["initial_state"],
                              t_final=float(times[-1]), snapshots=len(times), steps_this_session=self.steps,
                              wall_time_this_session=self.wall,
                              energy_drift=float(np.max(np.abs(energies - energies[0])) / energies[0]),
                              max_deviation=float(D.max()), destruction_level=DESTRUCTION_LEVEL,
                              destruction_time=first_crossing(tD, D, DESTRUCTION_LEVEL),
                              time_D_above_1em6=first_crossing(tD, D, 1e-6),
                              time_D_above_1em3=first_crossing(tD, D, 1e-3), ts=h["ts"], rtol=h["rtol"], atol=h["atol"])

    def write_summary(self) -> LongRunSummary:
        summary = self.summary()
        write_json(os.path.join(self.output, "summary.json"), summary.as_dict(), self.comm)
        return summary

    def destroy(self) -> None:
        self.integrator.destroy()
        self.chain.destroy()
