"""The refinement scan of section 3.4: E(q) of the branch waves on a periodic chain before and after Gauss-Newton
refinement, and the refinement file that the Floquet, Bloch and long-run studies read the refined waves from.

The refinement file is a numpy ``.npz`` archive (record store, rewritten atomically after each q), its columns
declared in :data:`REFINED_KIND`.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Iterator, Mapping, Optional, Sequence

import numpy as np
from petsc4py import PETSc

from ..chain import CHAIN_PREFIX
from ..branch import Branch
from ..dealing import dealt
from ..errors import ParameterError, RecordFileError, check_instance, check_integer, check_real, check_reals
from ..model import ChainSpec
from ..records import OPTIONS_COLUMN, Column, Kind, digest_column, given, on_rank0, read_kind
from ..roles import uses
from ..shooting import PAPER_TOLERANCES, SHOOT_PREFIX, Refiner, ShiftMap
from ..symmetry import WaveSymmetry
from ..waves import chain_wavenumbers, check_chain_wavenumber, orbit_on_chain
from .base import Study

if TYPE_CHECKING:
    from ..branch import Branch, BranchPoint
    from ..waves import Orbit

REFINED_FORMAT = "hertzpetsc-refined-1"
REFINED_KIND = Kind(REFINED_FORMAT, (
    Column("alpha", "Hertz exponent", constant=True),
    Column("N", "beads of the periodic chain", "count", np.int64, "d", constant=True),
    Column("branch", "path of the branch file the waves came from (a label)", "", str, "s", constant=True),
    Column("tol", "target E of the refinement", constant=True),
    digest_column("branch", "branch file"),
    OPTIONS_COLUMN,
    Column("q", "wavenumbers 2 pi m / N", format=".4f"),
    Column("E_before_paper_flow", "E(q) of the interpolated branch wave with the paper's flow (rtol 1e-12, atol "
           "1e-14)", format=".2e"),
    Column("E_before", "E(q) of the interpolated branch wave, tight flow (rtol 1e-14)", format=".2e"),
    Column("E_after", "E(q) of the refined state, tight flow", format=".2e"),
    Column("E_after_paper_flow", "E(q) of the refined state with the paper's flow", format=".2e"),
    Column("r", "relative size of the last Gauss-Newton step (the paper's r(q))", format=".1e"),
    Column("iterations", "Gauss-Newton iterations (stored as floats)", "count", format=".0f"),
    Column("jacobians", "Jacobian evaluations (stored as floats)", "count", format=".0f"),
    Column("wall_time", "seconds", "s", format=".1f"),
    Column("sigma_min", "smallest singular value of the phase-conditioned Jacobian", format=".2e"),
    Column("E_after_floor", "where the refinement stopped above `tol` at the tight flow's floor (`E_after` <= `tol` "
           "+ `E_after_floor`): that flow's own error in S X(script-T) at the refined state; NaN at every other q "
           "(files written before these fields: read as NaN)", format=".0e", optional=True),
    Column("E_after_fine", "there, `E_after` measured with the tight flow's tolerances divided by 10; NaN "
           "elsewhere", format=".2e", optional=True),
    Column("x", "refined state (x_n, xdot_n) at t = 0", shape="N, 2"),
))
# fields added after files were written (a file without them: NaN, no q at the flow's floor)
REFINED_ADDED = {"E_after_floor": math.nan, "E_after_fine": math.nan}


class RefinedStates:
    """The refined waves of a refinement file (N beads), looked up by q."""

    def __init__(self, path: str, data: Mapping[str, np.ndarray]) -> None:
        self.path, self.data = path, data
        self.N, self.alpha = int(data["N"]), float(data["alpha"])
        self.q = np.asarray(data["q"], dtype=float)

    @classmethod
    def load(cls, path: str, comm: Optional[PETSc.Comm] = None) -> RefinedStates:
        """Read a refinement file (with a communicator: on rank 0, the result or the error on every rank)."""
        if comm is not None:
            return on_rank0(comm, cls.load, path, what=f"cannot read refinement file {path!r}")
        return cls(path, read_kind(path, REFINED_KIND, "refinement file"))

    def column(self, name: str) -> np.ndarray:
        """A field over the file's q (a field added after the file was written: its default)."""
        if name not in self.data and name in REFINED_ADDED:
            return np.full(len(self.q), REFINED_ADDED[name])
        return np.asarray(self.data[name])

    def has(self, q: float) -> bool:
        return self.state(q) is not None

    def state(self, q: float) -> Optional[np.ndarray]:
        """The refined (N, 2) state at q, or None."""
        i = np.nonzero(np.abs(self.q - q) <= 1e-12 * max(1.0, q))[0]
        return self.data["x"][i[0]] if len(i) else None

    def check_alpha(self, alpha: float, of: str = "the branch's") -> None:
        """RecordFileError unless the waves were refined at Hertz exponent ``alpha`` (waves of another chain are
        never mixed with a branch of this one)."""
        if abs(alpha - self.alpha) > 1e-12:
            raise RecordFileError(f"refinement file {given(self.path)} is for alpha = {self.alpha:g}, not {of} "
                                  f"{alpha:g}")

    def orbit(self, point: BranchPoint, spec: Optional[ChainSpec] = None) -> Orbit:
        """The refined orbit of branch point ``point`` on the file's chain (RecordFileError if it lacks q)."""
        spec = spec or ChainSpec(point.model, self.N)
        if spec.N != self.N:
            raise RecordFileError(f"refinement file {given(self.path)} is for N = {self.N} beads, not {spec.N}")
        self.check_alpha(point.model.alpha)
        x = self.state(point.q)
        if x is None:
            raise RecordFileError(f"refinement file {given(self.path)} has no refined state at q = {point.q:.12g}")
        return orbit_on_chain(point, spec).with_state(x, "refined")


def scan_wavenumbers(branch, N, qs=None):
    """The q of the scan: those of ``qs`` (each must be a branch point fitting N beads), or every branch q that
    fits the chain. ParameterError naming the option otherwise."""
    check_instance("branch", branch, Branch, "a Branch (Branch.load(path), hz.compute_branch)")
    check_integer("N", N, 2, "the beads of the periodic chain")
    qs = () if qs is None else check_reals("qs", qs, "wavenumbers", 0.0, math.pi, hi_open=False, distinct=True,
                                           empty=True)
    if qs:
        for q in qs:
            branch.point(q)
            check_chain_wavenumber(q, N)
        return [branch.point(q).q for q in qs]
    fitting = chain_wavenumbers(branch.q, N)
    if not fitting:
        raise ParameterError("-N", N, "no branch wavenumber q has N q / (2 pi) integer")
    return fitting


class RefinementScan(Study):
    """E(q) before and after Gauss-Newton refinement for the branch waves at ``qs`` on N beads (section 3.4).

    ``symmetric``: refine on each wave's cell with its shortest time symmetry (:mod:`hertzpetsc.shooting`); else
    the paper's map over script-T on the N beads. Each q is refined on one rank, the q dealt to the ranks (the
    results do not depend on their number). The refinement's flows and Gauss-Newton use the prefix ``shoot_`` (tight
    flow, rtol 1e-14); E with the paper's flow uses ``chain_``. Each refined state is appended to the refinement
    file ``output`` as soon as its round is done (kept in memory when ``output`` is None).
    """

    FORMAT, FIELDS, ADDED, COLUMNS = REFINED_FORMAT, REFINED_KIND.fields, REFINED_ADDED, REFINED_KIND
    ROLES = uses("shoot_", "shoot_jac_", "chain_")
    WHAT, LABELS = "refinement file", ("branch",)

    def __init__(self, branch: Branch, branch_path: str, N: int, comm: Optional[PETSc.Comm] = None,
                 output: Optional[str] = None, mode: str = "new", qs: Optional[Sequence[float]] = None,
                 tol: float = 1e-10, symmetric: bool = True) -> None:
        super().__init__(None, comm, output, mode)
        self.qs = scan_wavenumbers(branch, N, qs)
        check_instance("branch_path", branch_path, str, "the branch file's path (a label)")
        tol = check_real("tol", tol, "the target E(q) of the refinement", 0.0, 1.0)
        self.branch, self.branch_path, self.N, self.tol = branch, branch_path, N, tol
        self.spec = ChainSpec(branch.model, N)
        self.SHAPES = {"x": (N, 2)}
        self.refiner = Refiner(self.spec, PETSc.COMM_SELF, tol, prefix=SHOOT_PREFIX, symmetric=symmetric)
        self.paper_flow = ShiftMap(self.spec, PETSc.COMM_SELF, PAPER_TOLERANCES, CHAIN_PREFIX)

    def constants(self) -> dict:
        return dict(alpha=self.branch.alpha, N=self.N, branch=self.branch_path, tol=self.tol)

    def inputs(self) -> dict[str, str]:
        return dict(branch=self.branch_path)

    def _refine(self, q):
        orbit = orbit_on_chain(self.branch.point(q), self.spec)
        E_paper = self.paper_flow.residual(orbit)
        res = self.refiner.refine(orbit)
        E_after_paper = self.paper_flow.residual(res.orbit)
        return dict(q=q, x=res.x, E_before_paper_flow=E_paper, E_before=res.E_initial, E_after=res.E,
                    E_after_paper_flow=E_after_paper, r=res.r, iterations=res.iterations, jacobians=res.jacobians,
                    wall_time=res.wall_time, sigma_min=res.sigma_min, E_after_floor=res.E_floor,
                    E_after_fine=res.E_fine)

    def planned(self) -> int:
        """The wavenumbers not yet in the file."""
        return len(self.open()._todo(self.qs))

    def run(self) -> Iterator[dict]:
        """Refine every q not yet in the file; yields the record (a dict of the fields) after saving it."""
        todo = self.open()._todo(self.qs)
        costs = [WaveSymmetry(self.N, check_chain_wavenumber(q, self.N)).cost() for q in todo]
        try:
            for q, row in dealt(todo, costs, self.comm, self._refine):
                yield self.store.append(row)
        finally:
            self.refiner.destroy()
            self.paper_flow.destroy()

    def table(self) -> str:
        rows = sorted(self.store.records, key=lambda r: -float(r["q"]))
        N = self.N
        lines = [f"N = {N} beads. E(q) = ||S X(script-T) - X(0)||_inf / ||X(0)||_inf. 'paper flow': adaptive RK "
                 "8(7) with rtol 1e-12, atol 1e-14 (the paper's tolerances); 'tight flow': rtol 1e-14, atol 1e-16 "
                 "(used for the refinement and its E). r = relative change of the last Gauss-Newton step. Refinement: "
                 + ("on the wave's cell over its shortest time symmetry (hertzpetsc.symmetry).\n" if self.refiner.symmetric
                    else "on the N beads over script-T (the paper's map).\n"),
                 "| q | m | E before (paper flow) | E before (tight flow) | E after (tight flow) | E after (paper flow) "
                 "| r(q) | GN its | Jacobians |", "|---|---|---|---|---|---|---|---|---|"]
        floors = []
        for r in rows:
            q = float(r["q"])
            floor = not math.isnan(float(r["E_after_floor"]))
            if floor:
                floors.append(f"- q = {q:.4f}: E after {r['E_after']:.2e} > {self.tol:g}, within the tight flow's "
                              f"own error at the refined state, {r['E_after_floor']:.1e} (its S X(script-T) against "
                              f"the same flow's at a tenth of its tolerances, which gives E = "
                              f"{r['E_after_fine']:.2e}).")
            lines.append(REFINED_KIND.row(r, "{q}", int(round(q * N / (2 * math.pi))), "{E_before_paper_flow}",
                                          "{E_before}", "{E_after}" + (" (floor)" if floor else ""),
                                          "{E_after_paper_flow}", "{r}", "{iterations}", "{jacobians}"))
        if floors:
            lines += ["", "Refined to the tight flow's floor (the iteration stopped above the target E <= "
                      f"{self.tol:g}; hertzpetsc.shooting):"] + floors
        return "\n".join(lines) + "\n"
