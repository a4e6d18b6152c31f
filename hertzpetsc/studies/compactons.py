"""Compactons of section 3.3 built from branch points and checked on the lattice (eqs. extens, extens2, twlin,
compacton, defvit): for each branch and q, the single compacton and the 2-compacton with phase theta, eq. ad on
the extended grid, then a run on a free-ended chain and what the paper asserts (:func:`lattice_checks`)."""
import math
import time
from dataclasses import dataclass

from ..branch import Branch
from ..errors import ParameterError, check_instance, check_integer, check_real, check_reals, members
from ..resources import chain_seconds, check_chain_memory, check_work
from ..model import ChainSpec
from ..compacton import (CompactonScales, chain_length, compacton_train, extension_residuals, lattice_checks,
                         placement, simulate_on_chain, train_span)
from ..roles import configure, uses

HEADER = ("| h | q | compactons | F(q) | N(q) | eq. ad residual: extended / period / 2 delta h^-2 | max \\|xdot\\| "
          "ahead | max \\|x - x(0)\\| ahead | arrival delay (dt) | c measured (c = 1) | shift error | gap error | "
          "max \\|xdot\\| behind / v_peak | profile error x / v | wall (s) |")


@dataclass
class CompactonCase:
    """One compacton train on the lattice: the train, its scales, the residuals, the run and its checks."""

    train: object
    h: float
    residuals: tuple
    scales: object
    phi: float
    times: object
    states: object
    checks: object
    wall: float

    def row(self):
        chk, res, train = self.checks, self.residuals, self.train
        cs = ", ".join(f"{c:.7f}" for c in chk.measured_c)
        return (f"| pi/{round(math.pi / self.h)} | {train.q:.4f} | {train.count} | {train.F:.3f} | "
                f"{train.width:.3f} | {res[0]:.1e} / {res[1]:.1e} / {res[2]:.1e} | {chk.max_velocity_ahead:.1e} | "
                f"{chk.max_displacement_ahead:.1e} | {chk.arrival_delay_min:.3f}-{chk.arrival_delay_max:.3f} "
                f"({chk.dt_snapshot:g}) | {cs} | {chk.shift_error:.1e} | {chk.gap_error:.1e} | "
                f"{chk.max_velocity_behind / chk.v_peak:.1e} | {chk.profile_error_x:.1e} / "
                f"{chk.profile_error_v:.1e} | {self.wall:.1f} |")


class CompactonStudy:
    """Single and 2-compactons (phase ``theta`` between them) of every branch at every q (each <= q_k, checked
    when the study is built), each run at ``c`` beads per unit time on a free chain with ``margin`` beads of rest
    behind, until the whole train has passed ``travel`` beads (TS prefix ``chain_``)."""

    ROLES = uses("chain_")

    def __init__(self, branches, qs, comm, theta=2.0, c=1.0, margin=10, travel=100, dt_snapshot=0.05):
        branches = [check_instance("branches", b, Branch, "a Branch (Branch.load(path), hz.compute_branch)")
                    for b in members("branches", branches, "Branches")]
        qs = check_reals("qs", qs, "wavenumbers", 0.0, math.pi, hi_open=False, distinct=True)
        theta = check_real("theta", theta, "the phase between the compactons")
        c = check_real("c", c, "the velocity in beads per unit time", 0.0)
        margin = check_integer("margin", margin, 2, "the beads at rest behind the train")
        travel = check_integer("travel", travel, 5, "the beads the train travels")
        dt_snapshot = check_real("dt_snapshot", dt_snapshot, "the time between snapshots", 0.0)
        self.branches, self.qs, self.comm = branches, qs, comm
        self.theta, self.c, self.margin, self.travel, self.dt = theta, c, margin, travel, dt_snapshot
        seconds = 0.0
        for b in branches:                                   # refuse bad input before any long run
            for q in qs:
                # the shortest run, the single compacton's: t_final = (travel + its length) / c
                t_final = (travel + math.ceil(train_span(compacton_train(b.point(q))))) / c
                if not 0 < dt_snapshot <= t_final:
                    raise ParameterError("dt_snapshot", dt_snapshot, f"must lie in (0, {t_final:g}], the shortest "
                                         f"run's duration t_final = (travel + the compacton's length in beads) / c "
                                         f"at q = {q:.6g}: decrease dt_snapshot or increase travel")
                train = compacton_train(b.point(q), (theta / q,), b.q_k())
                N = chain_length(train, margin, travel + math.ceil(train_span(train)))
                # the run's snapshots are kept: travel / (c dt) states of N beads, 16 bytes per bead each, i.e. one
                # chain column (24 work vectors) per 24 snapshots
                snapshots = travel / (c * dt_snapshot)
                check_chain_memory(N, comm, columns=1 + math.ceil(snapshots / 24), name="travel")
                # the single compacton and the pair, each on at most N beads until the pair has travelled
                seconds += 2 * chain_seconds(N, (travel + math.ceil(train_span(train))) / c)
        check_work("travel", travel, seconds, f"the {2 * len(branches) * len(qs)} compacton runs")
        self.cases = []
        if branches:
            configure(self.ROLES, comm, ChainSpec(branches[0].model, 3, "free"))

    def run(self):
        """Yield each :class:`CompactonCase` as it is done."""
        for b in self.branches:
            h = b.h
            for q in self.qs:
                point = b.point(q)
                for spacings in ((), (self.theta / point.q,)):
                    train = compacton_train(point, spacings)
                    d_grid = round(self.theta / h) * h / point.q
                    res = extension_residuals(compacton_train(point, [d_grid] * len(spacings)))
                    scales = CompactonScales.for_velocity(train, self.c)
                    distance = self.travel + math.ceil(train_span(train))     # the whole train passes `travel`
                    N = chain_length(train, self.margin, distance)
                    phi = placement(train, self.margin)
                    t0 = time.perf_counter()
                    times, states = simulate_on_chain(train, scales, N, phi, distance / self.c, self.dt, self.comm)
                    case = CompactonCase(train, h, res, scales, phi, times, states,
                                         lattice_checks(train, scales, phi, times, states), time.perf_counter() - t0)
                    self.cases.append(case)
                    yield case

    def table(self):
        note = (f"Chain: free ends, {self.margin} beads of rest behind the train; it moves at c = {self.c:g} until "
                f"all of it has passed {self.travel} beads (its length plus {self.travel} beads of travel); theta = "
                f"{self.theta:g} between the two compactons (its grid residual uses theta rounded to a whole number "
                "of steps h). delta = max |u_j - p j h| on the free flight, the computed profile's deviation from a "
                "line, bounds what the switch to the exact line adds to the residual. Errors are relative: shift and "
                "profile x to 2 pi a p, gap to a p q, velocities to the peak velocity. 'arrival delay' = first "
                "snapshot with xdot_n != 0 minus the predicted arrival of the front, over all beads reached; within "
                "[0, dt] means on time.\n\n")
        return note + HEADER + "\n" + "|---" * 15 + "|\n" + "\n".join(c.row() for c in self.cases) + "\n"
