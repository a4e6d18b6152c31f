"""The two-compacton test of section 3.3 (eq. extens2), each compacton unrefined or refined at the same gap, to
locate the source of the 2-compacton error. File ``hertzpetsc-compacton-pairs-1``, its columns declared in
:data:`PAIRS_KIND`."""
from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Iterator, Optional

import numpy as np
from petsc4py import PETSc

from ..compacton_window import DEFAULT_REAR, CompactonRefiner, CompactonWindow, WindowChain, embed, guess_from_branch
from ..branch import Branch
from ..errors import ParameterError, check_instance, check_integer, check_real
from ..model import ChainSpec
from ..records import OPTIONS_COLUMN, Column, Kind, digest_column
from ..resources import MAX_DENSE_BEADS, chain_seconds, check_chain_memory, check_work
from .base import Study
from .compacton_dynamics import DYNAMICS_SECONDS, DYNAMICS_TOLERANCES, CompactonDynamics, dynamics_integrator
from .compacton_stability import q_text

if TYPE_CHECKING:
    from ..branch import Branch
    from ..chain import IntegrationTolerances

PAIRS_FORMAT = "hertzpetsc-compacton-pairs-1"
PAIRS_KIND = Kind(PAIRS_FORMAT, (
    Column("alpha", "Hertz exponent", constant=True),
    Column("q", "wavenumber of the branch point", constant=True),
    Column("h", "grid step of the branch", constant=True),
    Column("spacing", "beads between the rear and the front window", "count", np.int64, "d", constant=True),
    Column("travel", "beads travelled beyond the spacing (the run lasts spacing + travel)", "count", np.int64, "d",
           constant=True),
    Column("M", "window beads", "count", np.int64, "d", constant=True),
    Column("N", "beads of the free chain", "count", np.int64, "d", constant=True),
    Column("gap", "the common gap Delta = a p q", constant=True),
    digest_column("branch", "branch file"),
    OPTIONS_COLUMN,
    Column("case", "`single` or `two`", "", str, "s"),
    Column("rear", "the rear compacton: `unrefined` (the branch profile), `refined` (the window map's fixed point) "
           "or '' (none)", "", str, "s"),
    Column("front", "the front compacton, as `rear`", "", str, "s"),
    Column("error_x", "max over all beads of \\|X(T) - X(0) translated by T beads\\| in x, relative to D",
           format=".1e"),
    Column("error_v", "the same in v, relative to v_peak", format=".1e"),
    Column("debris_v", "max \\|v\\| behind the rear compacton / v_peak", format=".1e"),
    Column("seconds", "wall time", "s", format=".1f"),
))
PAIR_FIELDS = PAIRS_KIND.fields
PAIR_CASES = (("single", "", "unrefined"), ("single", "", "refined"), ("two", "unrefined", "unrefined"),
              ("two", "refined", "refined"), ("two", "unrefined", "refined"), ("two", "refined", "unrefined"))


class CompactonPairs(Study):
    """The compacton of a branch point at c = 1, unrefined (the branch profile, eqs. extens, compacton) or refined
    at the same gap (window map, Delta fixed), alone or with a second one ``spacing`` beads behind (eq. extens2),
    on a free chain in gap-lattice coordinates (TS ``cdyn_``), run until the rear one has passed ``travel`` beads
    beyond the front one's start. Errors against the exactly translated initial chain (x relative to D, v to
    v_peak) and the debris left behind the rear compacton (max |v| / v_peak)."""

    FORMAT, FIELDS, DTYPES, COLUMNS = PAIRS_FORMAT, PAIR_FIELDS, PAIRS_KIND.dtypes, PAIRS_KIND
    ROLES = CompactonDynamics.ROLES
    WHAT, LABELS = "compacton pairs file", ("N", "gap")

    def __init__(self, branch: Branch, q: float, comm: Optional[PETSc.Comm] = None, output: Optional[str] = None,
                 mode: str = "new", spacing: int = 132, travel: int = 100, M: int = 18, rear: int = DEFAULT_REAR,
                 margin: int = 10, tolerances: IntegrationTolerances = DYNAMICS_TOLERANCES) -> None:
        super().__init__(None, comm, output, mode)
        self.branch = check_instance("branch", branch, Branch, "a Branch (Branch.load(path), hz.compute_branch)")
        self.q = check_real("q", q, "the wavenumber", 0.0, math.pi, hi_open=False)
        self.spacing, self.travel, self.M, self.rear, self.margin = (
            check_integer(name, value, lo, what, hi) for name, value, lo, what, hi in (
                ("spacing", spacing, 8, "the beads between the two windows", None),
                ("travel", travel, 1, "the beads of travel", None),
                ("M", M, 4, "the window's beads (its map and the doubled window's are dense)", MAX_DENSE_BEADS // 2),
                ("rear", rear, 2, "the beads at rest behind the zone", None),
                ("margin", margin, 2, "the beads at rest", None)))
        Yu, gap = guess_from_branch(branch.point(self.q), self.M, self.rear, branch.q_k())
        if self.spacing < self.M:
            raise ParameterError("-spacing", spacing, f"the two windows must not overlap: spacing >= M = {self.M}")
        self.gap, self.states = gap, {"unrefined": Yu}
        self.tolerances = tolerances
        self.T = self.spacing + self.travel
        self.N = self.margin + self.spacing + self.M + self.T + self.margin
        check_work("travel", travel, chain_seconds(self.N, self.T * len(PAIR_CASES), DYNAMICS_SECONDS),
                   f"{len(PAIR_CASES)} runs of {self.N} beads over {self.T} units of time")
        check_chain_memory(self.N, self.comm, name="travel")
        self.model = branch.model
        self.chain = WindowChain(ChainSpec(self.model, self.N, "free"), self.comm, gap)
        self.integ = dynamics_integrator(self.chain, tolerances)

    def constants(self) -> dict:
        return dict(alpha=self.branch.alpha, q=self.q, h=self.branch.h, spacing=self.spacing, travel=self.travel,
                    M=self.M, N=self.N, gap=self.gap)

    def inputs(self) -> dict:
        return dict(branch=getattr(self.branch, "path", "") or "")

    def initial(self, rear: Optional[str], front: str) -> np.ndarray:
        """(N, 2) gap-lattice chain: the front window at bead margin + spacing, the rear one spacing beads behind."""
        nf = self.margin + self.spacing
        X = embed(self.states[front], self.N, nf)
        if rear:
            X[:nf] += embed(self.states[rear], nf, self.margin)
        return X

    def run(self) -> Iterator[dict]:
        self.open()
        w = CompactonWindow(self.model, self.M, PETSc.COMM_SELF)
        try:
            if "refined" not in self.states:
                ex = CompactonRefiner(w).refine(self.states["unrefined"], self.gap, self.q, fix_gap=True)
                self.states["refined"], self.refined_residual = ex.Y, ex.residual
            self.unrefined_residual = w.residual(self.states["unrefined"], self.gap)
        finally:
            w.destroy()
        done = {(str(r["case"]), str(r["rear"]), str(r["front"])) for r in self.store.records}
        v_peak = float(np.max(np.abs(self.states["unrefined"][:, 1])))
        D = float(self.states["unrefined"][0, 0])
        for case in PAIR_CASES:
            if case in done:
                continue
            kind, rear, front = case
            X0 = self.initial(rear, front)
            X = self.chain.create_state()
            self.chain.set_from_array(X, X0)
            t0 = time.perf_counter()
            try:
                self.integ.integrate(X, 0.0, float(self.T), dt=self.integ.initial_step)
                XT = self.chain.gather(X)
            finally:
                X.destroy()
            # the exact translation by T beads (c = 1): bead n at T is bead n - T at 0, or at rest behind
            n = np.arange(self.N)
            err = np.abs(XT - X0[np.maximum(n - self.T, 0)])
            rear_start = self.margin if rear else self.margin + self.spacing
            behind = slice(0, rear_start + self.T - 2)
            row = dict(case=kind, rear=rear, front=front, error_x=float(np.max(err[:, 0])) / D,
                       error_v=float(np.max(err[:, 1])) / v_peak,
                       debris_v=float(np.max(np.abs(XT[behind, 1]))) / v_peak, seconds=time.perf_counter() - t0)
            yield self.store.append(row)

    def table(self) -> str:
        lines = [f"alpha = {self.branch.alpha:g}, q = {q_text(self.q)}, branch h = "
                 f"pi/{round(math.pi / self.branch.h)}; c = 1, gap Delta = {self.gap:.6g} (the branch's a p q, "
                 "shared by all cases; 'refined' = the window map's fixed point at this gap). Unrefined window "
                 f"residual max|G(Y) - Y| = {self.unrefined_residual:.1e}, refined {self.refined_residual:.1e}. "
                 f"Free chain of {self.N} beads; "
                 f"front compacton at bead {self.margin + self.spacing}, rear one {self.spacing} beads behind; run "
                 f"for T = {self.T} (the rear one passes {self.travel} beads beyond the front one's start). Errors: "
                 "max over beads of |X(T) - X(0) translated by T beads|, x relative to D, v to v_peak; debris: max |v| "
                 "behind the rear compacton / v_peak.\n",
                 "| compactons | rear | front | profile error x | profile error v | debris behind / v_peak | s |",
                 "|---|---|---|---|---|---|---|"]
        for r in self.store.records:
            lines.append(PAIRS_KIND.row(r, "{case}", r["rear"] or "-", "{front}", "{error_x}", "{error_v}",
                                        "{debris_v}", "{seconds}"))
        return "\n".join(lines) + "\n"

    def destroy(self) -> None:
        self.integ.destroy()
        self.chain.destroy()
