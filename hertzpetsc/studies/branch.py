"""Branch studies: the continuation of section 3.1 written to a branch file, its convergence in h, and the
branch to small q with grids refined as q decreases (section 3.2)."""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Iterator, Mapping, Optional

import numpy as np

from ..branch import BRANCH_FORMAT, BRANCH_KIND, Branch, BranchPoint, branch_store
from ..qbranch import (BranchContinuation, ContinuationParameters, RefiningGrid, continue_branch,
                            paper_targets)
from ..errors import (Checked, ParameterError, RecordFileError, check_instance, check_integer, check_integers,
                      check_prefix, param)
from ..hertz import ALPHA_MAX
from ..model import LatticeModel
from ..records import Column, Kind, is_checking, load_npz, npz_arrays, on_rank0, write_npz
from ..resources import check_memory
from ..richardson import richardson
from ..roles import configure, uses
from ..twsolver import TW_PREFIX
from .base import Study

if TYPE_CHECKING:
    from petsc4py import PETSc

    from ..diagnostics import WaveDiagnostics

TW_ROLE = uses(TW_PREFIX)


class BranchStudy(Study):
    """The branch q = pi -> q_stop through q = m pi / M (eqs. ad-pbc), each point appended to a branch file (or
    kept in memory when ``output`` is None).

    Building it configures the SNES (prefix ``tw_``); :meth:`open` opens the record store (``mode``: new,
    resume or force; collective), and :meth:`run` (which opens it if need be) yields the new points as they are
    saved. ``branch`` holds every point, the resumed ones included.
    """

    Parameters = ContinuationParameters
    FORMAT, FIELDS, COLUMNS = BRANCH_FORMAT, BRANCH_KIND.fields, BRANCH_KIND
    ROLES = TW_ROLE
    WHAT = "branch file"

    def __init__(self, params: ContinuationParameters, output: Optional[str] = None,
                 comm: Optional[PETSc.Comm] = None, mode: str = "new", meta: Optional[Mapping] = None,
                 prefix: str = TW_PREFIX, solver: Optional[str] = None) -> None:
        super().__init__(params, comm, output, mode)
        check_prefix("prefix", prefix)
        if meta is not None:
            check_instance("meta", meta, dict, "a dict of labels (None: none)")
        self.branch = Branch(params.model, params.cells_per_pi, params.M, [], dict(meta or {}))
        self.continuation = BranchContinuation(params, self.comm, prefix, solver)
        self.resumed = 0

    def _open(self):
        """The branch file (or memory); the resumed points seed the continuation."""
        store = branch_store(self.output, self.branch, self.comm, self.mode)
        pts = self.branch.points = [BranchPoint.from_record(r, self.branch.h, self.branch.model) for r in store.records]
        self.resumed = len(pts)          # points found in the file
        if pts:
            self.continuation.resume_from([p.q for p in pts], [p.u_half for p in pts])
        return store

    def planned(self) -> int:
        """The wavenumbers of the branch (m pi / M down to q_stop) not yet in the file."""
        return max(0, len(self.params.targets()) - len(self.open().branch.points))

    def run(self) -> Iterator[BranchPoint]:
        self.open()
        try:
            for point in self.continuation.points():
                self.store.append(point.record())
                self.branch.points.append(point)
                yield point
        finally:
            self.continuation.destroy()


QUANTITIES = ("norm_inf", "slope", "N", "T")
Q_REPORT = (("pi", math.pi), ("3pi/10", 3 * math.pi / 10), ("7pi/25", 7 * math.pi / 25),
            ("9pi/50", 9 * math.pi / 50), ("pi/50", math.pi / 50))


class ConvergenceStudy(Study):
    """The branch on the grids h = pi / K, K in ``cells`` (at least 3, all different), and at the reported q the
    observed order on the three finest grids and the Richardson value (h^2) from the two finest, with the grids'
    actual ratios (no record file: the table is the result)."""

    ROLES = TW_ROLE

    def __init__(self, model, M, cells, comm=None, prefix=TW_PREFIX):
        check_instance("model", model, LatticeModel, "a LatticeModel (LatticeModel.hertz(alpha))")
        M = check_integer("M", M, 1, "the target wavenumbers q = m pi / M")
        check_prefix("prefix", prefix)
        cells = sorted(check_integers("cells", cells, 4, "grids K (h = pi/K)"))
        if len(cells) < 3 or len(set(cells)) != len(cells):
            raise ParameterError("cells", cells, "needs at least three different grids for an observed order")
        if cells[0] < M:        # the smallest target q = pi/M must be at least every grid's step h = pi/K
            raise ParameterError("cells", cells, f"every grid K must be >= M = {M} (the smallest target q = pi/M at "
                                 "least the grid step h = pi/K): increase the grids or decrease M")
        super().__init__(dict(alpha=model.alpha, M=M, cells=cells), comm)
        check_memory(cells[-1], self.comm, name="cells")
        self.model, self.M, self.cells, self.prefix = model, M, cells, prefix
        self.values = {}
        configure({prefix: TW_ROLE[TW_PREFIX]}, self.comm)

    def run(self):
        """Compute the branch on every grid; yields K after each."""
        for K in self.cells:
            cont = BranchContinuation(ContinuationParameters(model=self.model, M=self.M, cells_per_pi=K),
                                      self.comm, self.prefix)
            try:
                for pt in cont.points():
                    self.values[(K, round(pt.q, 12))] = pt.diagnostics
            finally:
                cont.destroy()
            yield K

    def table(self):
        cells = self.cells
        lines = [f"alpha = {self.model.alpha}, M = {self.M}, grids h = pi/K for K in {list(cells)}; order from the "
                 "three finest grids (their actual ratios); extrapolated = Richardson from the two finest (assumes "
                 "h^2, with their ratio)\n",
                 "| q | quantity | " + " | ".join(f"K = {K}" for K in cells) + " | observed order | extrapolated |",
                 "|---|---|" + "---|" * len(cells) + "---|---|"]
        for label, q in Q_REPORT:
            if any((K, round(q, 12)) not in self.values for K in cells):
                continue                     # not a target of this branch (q = m pi / M)
            for name in QUANTITIES:
                xs = [self.values[(K, round(q, 12))][name] for K in cells]
                order, extrap = richardson(xs, order=2, steps=[math.pi / K for K in cells])
                lines.append(f"| {label} | {name} | " + " | ".join(f"{x:.8g}" for x in xs)
                             + f" | {order:.2f} | {extrap:.8g} |")
        return "\n".join(lines) + "\n"


# --- small q ------------------------------------------------------------------------------------------------------
SMALLQ_FORMAT = "hertzpetsc-smallq-1"
SMALLQ_KIND = Kind(SMALLQ_FORMAT, (
    Column("alpha", "Hertz exponent", constant=True),
    Column("q_stop", "the smallest target q", constant=True),
    Column("q_first", "the first target q: the targets are q_first 2^(-i/per_halving) down to q_stop", constant=True),
    Column("per_halving", "targets per halving of q", "count", np.int64, "d", constant=True),
    Column("cells_per_q", "level l keeps q/h >= cells_per_q 2^l", "count", np.int64, "d", constant=True),
    Column("levels", "the grid levels", "count", np.int64, "d", constant=True),
    Column("solver_options", "number-changing options under `-tw_` (absent from files written before it)", "", str,
           "s", constant=True, optional=True),
    Column("level", "grid level (0 = coarsest)", "count", np.int64, "d"),
    Column("q", "wavenumber"),
    Column("K", "cells_per_pi of the grid at that q (h = pi/K)", "count", np.int64, "d"),
    Column("norm_inf", "\\|\\|u\\|\\|_inf, as in the branch file"),
    Column("slope", "p(q) = u'(0), as in the branch file"),
    Column("N", "N(q), as in the branch file"),
    Column("F", "F(q), as in the branch file"),
    Column("rescaled_norm", "\\|\\|u\\|\\|_inf q^(2/(alpha-1)) (-> k_alpha)"),
))
SMALLQ_FIELDS = SMALLQ_KIND.fields[3:]


# grid levels of the small-q branch: level L has 2^L times the cells of level 0 (at least 4 cells per pi), and
# 4 x 2^29 is PETSc's 32-bit index range
MAX_LEVELS = 30


@dataclass(frozen=True)
class SmallQParameters(Checked):
    """q from pi down to q_stop through the targets q_first 2^(-i / per_halving); on ``levels`` resolutions, level
    l keeping at least cells_per_q 2^l cells per unit of q below q_first (:class:`RefiningGrid`)."""

    alpha: float = param(1.5, "the Hertz exponent", lo=1.0, hi=ALPHA_MAX, hi_open=False)
    q_stop: float = param(math.pi / 400, "the smallest wavenumber (at most q_first)", lo=0.0, hi=math.pi,
                          hi_open=False, expr=True)
    q_first: float = param(math.pi / 50, "the first wavenumber of the targets", lo=0.0, hi=math.pi, hi_open=False)
    per_halving: int = param(4, "targets per halving of q", lo=1)
    cells_per_q: int = param(20, "grid cells per unit of q at q_first on level 0", lo=4)
    levels: int = param(3, "resolutions (Richardson from the three finest; an order needs three grids; each level "
                        "doubles the grid, beyond 2^29 cells PETSc's index type overflows)", lo=3, hi=MAX_LEVELS)

    def __post_init__(self):
        super().__post_init__()
        if not self.q_stop <= self.q_first:
            raise ParameterError("q_stop", self.q_stop, f"must satisfy 0 < q_stop <= q_first = {self.q_first:.6g} "
                                 "<= pi")
        RefiningGrid(self.q_first, self.cells_per_q)          # validates cells_per_q against q_first

    @property
    def model(self) -> LatticeModel:
        return LatticeModel.hertz(self.alpha)

    def targets(self) -> list[float]:
        """q_first 2^(-i/per_halving), i = 0, 1, ..., with q_stop appended if it falls between."""
        qs, i = [], 0
        while True:
            q = self.q_first * 2.0 ** (-i / self.per_halving)
            if q < self.q_stop * (1 - 1e-12):
                break
            qs.append(q)
            i += 1
        if abs(qs[-1] - self.q_stop) > 1e-12 * self.q_stop:
            qs.append(self.q_stop)
        return qs

    def grid(self, level: int) -> RefiningGrid:
        return RefiningGrid(self.q_first, self.cells_per_q, level)

    def cells_per_pi(self, q: float, level: int) -> int:
        return self.grid(level).cells_per_pi(q)

    def identity(self) -> dict:
        return asdict(self)


def _legacy_smallq_progress(path, params):
    """Rewrite a progress file of the first format (per-level columns, ``params`` JSON) as a record file."""
    data = load_npz(path, "progress file")
    if "format" in data or "params" not in data:
        return
    stored = json.loads(str(data["params"]))
    if stored != params.identity():
        raise RecordFileError(f"{path!r} holds another computation: it was made with {stored} (rerun with those "
                              "options, or with -force to start afresh)")
    if is_checking():
        return True
    records, state = [], {}
    for lev in range(params.levels):
        key = f"L{lev}_"
        if key + "q" not in data:
            continue
        for i, (q, K) in enumerate(zip(data[key + "q"], data[key + "K"])):
            records.append(dict(level=lev, q=float(q), K=int(K), **{f: float(data[key + f][i]) for f in SMALLQ_FIELDS}))
        for j in range(2):
            if key + f"seed{j}_q" in data:
                for part in ("q", "K", "u"):
                    state[f"{key}seed{j}_{part}"] = data[key + f"seed{j}_{part}"]
    write_npz(path, npz_arrays(SMALLQ_FORMAT, params.identity(), SMALLQ_KIND.fields, records, state,
                               SMALLQ_KIND.dtypes))
    return True


class SmallQStudy(Study):
    """The branch below q_first on ``levels`` resolutions (section 3.2): at every target q the observed order and
    the Richardson values of ||u||_inf, p(q), N(q) and ||u||_inf q^(2/(alpha-1)) (-> k_alpha).

    The progress file (``progress``) is a record store: one record per (level, q), and the last two profiles of
    each level as its state, from which a killed run resumes (``mode='resume'``; files of the first format are
    converted).
    """

    Parameters = SmallQParameters
    FORMAT, FIELDS, DTYPES, COLUMNS = SMALLQ_FORMAT, SMALLQ_KIND.fields, SMALLQ_KIND.dtypes, SMALLQ_KIND
    ROLES = TW_ROLE
    WHAT = "progress file"

    def __init__(self, params: SmallQParameters, progress: Optional[str] = None, comm: Optional[PETSc.Comm] = None,
                 mode: str = "new", prefix: str = TW_PREFIX) -> None:
        super().__init__(params, comm, progress, mode)
        self._check_memory(params)
        self.prefix, self.progress = prefix, progress
        self.continuation = ContinuationParameters(model=params.model, M=1, cells_per_pi=params.grid(0).cells_per_pi(
            params.q_first))
        configure({prefix: TW_ROLE[TW_PREFIX]}, self.comm)

    def _check_memory(self, params):
        """check_memory of the finest level's grid at q_stop, refused as q_stop with the smallest q_stop that fits
        (K doubles at each halving of q_first). Collective."""
        finest = params.levels - 1
        K = params.cells_per_pi(params.q_stop, finest)
        try:
            check_memory(K, self.comm, name="q_stop")
        except ParameterError as e:
            halvings = 0
            while True:
                try:
                    check_memory(params.cells_per_pi(params.q_first / 2 ** halvings, finest), self.comm)
                except ParameterError:
                    break
                halvings += 1
            bound = (f"must be >= q_first / 2^{halvings - 1} = {params.q_first / 2 ** (halvings - 1):.6g}"
                     if halvings else "no q_stop fits (decrease cells_per_q or levels)")
            raise ParameterError("q_stop", params.q_stop, f"{bound} on this machine: the finest level's grid, "
                                 f"K = {K} cells per pi, {e.valid.rsplit(': ', 1)[0]}") from None

    def constants(self) -> dict:
        return self.params.identity()

    identity = constants             # the progress files hold no solver options

    def _open(self):
        """The progress file (one of the first format converted when resumed), or memory."""
        if self.progress is not None and self.mode == "resume":
            legacy = on_rank0(self.comm, _legacy_smallq_progress, self.progress, self.params,
                              what=f"cannot read progress file {self.progress!r}")
            if legacy and is_checking():        # -check: its identity is checked; it is converted when run
                return None
        return super()._open()

    def rows(self, level: int) -> list[dict]:
        return [r for r in self.store.records if int(r["level"]) == level]

    def _seeds(self, level):
        st = self.store.state
        out = []
        for j in range(2):
            key = f"L{level}_seed{j}_"
            if key + "q" in st:
                out.append((float(st[key + "q"]), np.asarray(st[key + "u"], dtype=float)))
        return out

    def run(self) -> Iterator[tuple[int, float, int, WaveDiagnostics]]:
        """Yield (level, q, K, diagnostics) for every new target point, each saved before the next is tried."""
        self.open()
        p = self.params
        M0 = max(1, round(math.pi / p.q_first))
        path = paper_targets(M0, p.q_first) + p.targets()[1:]
        for level in range(p.levels):
            done = self.rows(level)
            if done and float(done[-1]["q"]) <= p.q_stop * (1 + 1e-12):
                continue
            seeds = self._seeds(level)
            for point in continue_branch(self.continuation, path, p.grid(level), self.comm, seeds, self.prefix):
                if point.q > p.q_first * (1 + 1e-12):
                    continue                   # on the way from pi to q_first
                K = int(round(math.pi / point.h))
                seeds = (seeds + [(point.q, point.u_half)])[-2:]
                state = {}
                for j, (q, u) in enumerate(seeds):
                    state.update({f"L{level}_seed{j}_q": q, f"L{level}_seed{j}_K": len(u) - 1,
                                  f"L{level}_seed{j}_u": u})
                d = point.diagnostics
                self.store.append(dict(level=level, q=point.q, K=K, **{f: d[f] for f in SMALLQ_FIELDS}), state)
                yield level, point.q, K, d

    def extrapolations(self) -> tuple[dict, dict, dict]:
        """{field: [(order, extrapolated) per target]} and the table of values [field][level, target]."""
        p = self.params
        targets = p.targets()
        lookup = [{round(float(r["q"]), 12): r for r in self.rows(lev)} for lev in range(p.levels)]
        missing = [q for q in targets if any(round(q, 12) not in lookup[lev] for lev in range(p.levels))]
        if missing:
            raise RecordFileError(f"the progress file lacks q = {missing[0]:.6g} on some level (run to the end first)")
        table = {f: np.array([[float(lookup[lev][round(q, 12)][f]) for q in targets] for lev in range(p.levels)])
                 for f in SMALLQ_FIELDS}
        ext = {f: [richardson(table[f][-3:, i]) for i in range(len(targets))] for f in SMALLQ_FIELDS}
        K_fine = {round(q, 12): int(lookup[-1][round(q, 12)]["K"]) for q in targets}
        return table, ext, K_fine

    def table(self, k_alpha: float, half_length: float = 8.0) -> str:
        p = self.params
        targets = p.targets()
        table, ext, K_fine = self.extrapolations()
        levels = p.levels
        lines = [f"alpha = {p.alpha}; level l keeps q/h >= {p.cells_per_q} 2^l (grid doubled each time q "
                 f"halves below pi/50); k_alpha = {k_alpha:.7f} (solitary wave, n = 80, 160, 320, "
                 f"L = {half_length:g}, extrapolated). "
                 "Orders and extrapolations from the three finest levels.\n",
                 "| q | pi/q | K (finest) | " + " | ".join(f"product, level {lev}" for lev in range(levels))
                 + " | order | product extrapolated | minus k_alpha | \\|\\|u\\|\\|_inf extrapolated | p(q) "
                 "extrapolated | N(q) extrapolated | N order |", "|---" * (levels + 10) + "|"]
        for i, q in enumerate(targets):
            o, r = ext["rescaled_norm"][i]
            lines.append(f"| {q:.6f} | {math.pi / q:.2f} | {K_fine[round(q, 12)]} | "
                         + " | ".join(f"{table['rescaled_norm'][lev, i]:.7f}" for lev in range(levels))
                         + f" | {o:.2f} | {r:.7f} | {r - k_alpha:+.2e} | {ext['norm_inf'][i][1]:.6e} | "
                         f"{ext['slope'][i][1]:.6e} | {ext['N'][i][1]:.5f} | {ext['N'][i][0]:.2f} |")
        return "\n".join(lines) + "\n"

    def summary(self, k_alpha: float, half_length: float = 8.0) -> dict:
        """The extrapolated products and N(q) against q (the JSON beside the table)."""
        _, ext, _ = self.extrapolations()
        return dict(k_alpha=k_alpha, half_length=half_length, q=self.params.targets(),
                    product=[e[1] for e in ext["rescaled_norm"]], N=[e[1] for e in ext["N"]],
                    params=asdict(self.params))
