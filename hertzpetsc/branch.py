"""A branch of travelling waves u(.; q) and its file (paper section 3.1), readable with numpy alone.

:class:`BranchPoint` is one converged solution of eqs. ad-pbc with its diagnostics and solver statistics;
:class:`Branch` the points of one continuation on one grid. What takes a wave (the chain's initial states,
compactons, the long-wave comparison, the figures) takes a :class:`BranchPoint` or a :class:`Branch`.

The branch file is a numpy ``.npz`` archive (``numpy.load(path)``), rewritten atomically after every converged
point by the record store (:class:`hertzpetsc.records.NpzRecords`), so a killed run leaves the last complete
file. Its columns (P = number of points, K = cells_per_pi; u is odd and 2 pi-periodic, u(2 pi - xi) = -u(xi))
are declared in :data:`BRANCH_KIND`.

A resumed file must have the same alpha, cells_per_pi and M (and model, where it has one): its identity. The file
reopens with its model (:meth:`Branch.load`).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Mapping, Optional

import numpy as np

from .diagnostics import WaveDiagnostics, crossing
from .errors import ParameterError, RecordFileError
from .model import LatticeModel
from .records import Column, Kind, MemoryRecords, NpzRecords, on_rank0, read_kind
from .stencil import full_period

if TYPE_CHECKING:
    from petsc4py import PETSc

BRANCH_FORMAT = "hertzpetsc-branch-1"
_INT = dict(unit="count", dtype=np.int64, format="d")
BRANCH_KIND = Kind(BRANCH_FORMAT, (
    Column("alpha", "Hertz exponent", constant=True),
    Column("cells_per_pi", "the grid: h = pi / cells_per_pi", constant=True, **_INT),
    Column("h", "grid step pi / cells_per_pi", constant=True),
    Column("M", "the targets q = m pi / M", constant=True, **_INT),
    Column("xi", "grid points j h on [0, pi]", shape="K+1", constant=True),
    Column("meta", "JSON: the run's provenance when the branch was started (the keys of `__provenance__`: software "
           "versions `hertzpetsc`, `petsc`, `petsc4py`, `slepc4py`, `numpy`, `python`, ..., `ranks`, `argv`, "
           "`created`), `params`, `prefix`", "", str, "s", constant=True),
    Column("model", "JSON: the model's description (law by name and parameters, masses, damping) for a branch of "
           "another model than the uncompressed monatomic Hertz chain (API only); absent for it; part of the "
           "identity; `Branch.load` rebuilds it", "", str, "s", constant=True, optional=True),
    Column("q", "wavenumbers, decreasing from pi"),
    Column("norm_inf", "\\|\\|u\\|\\|_inf (parabolic refinement of the grid maximum)"),
    Column("slope", "p(q) = u'(0), the free-flight slope"),
    Column("ell", "free-flight half-length ell(q) (cubic location of the sign change of the shift differences)"),
    Column("N", "N(q) = 2 (pi - ell)/q (eq. defnq)"),
    Column("F", "F(q) = 2 ell/q"),
    Column("T", "inverse velocity script-T(q) = q \\|\\|u\\|\\|_inf^((alpha-1)/2) (eq. invv)"),
    Column("omega_A0", "omega(q, A0), A0 = \\|\\|u0\\|\\|_inf (eq. dispers)"),
    Column("rescaled_norm", "\\|\\|u\\|\\|_inf q^(2/(alpha-1)) (tends to k_alpha, eq. normscaling)"),
    Column("snes_iterations", "SNES iterations at that q (last sub-step)", **_INT),
    Column("ksp_iterations", "KSP iterations at that q (last sub-step)", **_INT),
    Column("residual_norm", "final \\|\\|R(u)\\|\\|_2 of the discrete eq. ad at that q (last sub-step)"),
    Column("snes_reason", "PETSc's converged reason at that q", "", np.int64, "d"),
    Column("substeps", "continuation sub-steps used to reach q (1 = no step reduction)", **_INT),
    Column("wall_time", "seconds spent on the point", "s", format=".1f"),
    Column("u", "profiles u(xi; q) on [0, pi]", shape="K+1"),
))
POINT_FIELDS = BRANCH_KIND.fields[:-1]


@dataclass(frozen=True)
class SolveStats:
    """What SNES did in one solve (at one q: the last continuation sub-step)."""

    reason: int
    iterations: int
    linear_iterations: int
    residual_norm: float
    wall_time: float


@dataclass
class BranchPoint:
    """One converged travelling wave: its profiles on [0, pi] (on every rank), frequency, diagnostics and solver
    statistics.

    x_n(t) = u_c(q n - omega t), c = n mod p (p the model's mass pattern), solves the chain: ``profiles`` holds the
    p odd profiles u_c on [0, pi] (``u_half`` is u_0, the paper's u for p = 1) and ``omega`` the frequency (eq. ad
    fixes omega = 1; the amplitude families store the wave at its physical amplitude and frequency). The paper's
    branch points carry :class:`~hertzpetsc.diagnostics.WaveDiagnostics`; other waves may leave them None."""

    q: float
    u_half: np.ndarray
    h: float
    model: LatticeModel
    diagnostics: WaveDiagnostics = None
    solve: SolveStats = None
    substeps: int = 1
    wall_time: float = 0.0
    profiles: tuple = None
    omega: float = 1.0

    def __post_init__(self):
        if self.profiles is None:
            self.profiles = (np.asarray(self.u_half, dtype=float),)
        if len(self.profiles) != self.model.cell:
            raise ValueError(f"{len(self.profiles)} profiles for a mass pattern of {self.model.cell} beads")

    @property
    def u_full(self) -> np.ndarray:
        """The profile on the whole period [0, 2 pi) (2K values, by oddness)."""
        return full_period(self.u_half)

    def record(self) -> dict:
        """The row of the branch file (:data:`POINT_FIELDS` and the profile ``u``)."""
        s = self.solve
        return dict(q=self.q, u=self.u_half, **self.diagnostics.as_dict(), snes_iterations=s.iterations,
                    ksp_iterations=s.linear_iterations, residual_norm=s.residual_norm, snes_reason=s.reason,
                    substeps=self.substeps, wall_time=self.wall_time)

    @classmethod
    def from_record(cls, row: Mapping, h: float, model: LatticeModel) -> BranchPoint:
        diag = WaveDiagnostics(**{k: float(row[k]) for k in WaveDiagnostics.names()})
        stats = SolveStats(reason=int(row["snes_reason"]), iterations=int(row["snes_iterations"]),
                           linear_iterations=int(row["ksp_iterations"]), residual_norm=float(row["residual_norm"]),
                           wall_time=float(row["wall_time"]))
        return cls(q=float(row["q"]), u_half=np.asarray(row["u"], dtype=float), h=h, model=model,
                   diagnostics=diag, solve=stats, substeps=int(row["substeps"]), wall_time=float(row["wall_time"]))


@dataclass
class Branch:
    """The points of one continuation on the grid h = pi / cells_per_pi (targets q = m pi / M)."""

    model: LatticeModel
    cells_per_pi: int
    M: int
    points: list = field(default_factory=list)
    meta: dict = field(default_factory=dict)

    @property
    def alpha(self) -> float:
        return self.model.alpha

    @property
    def h(self) -> float:
        return math.pi / self.cells_per_pi

    @property
    def xi(self) -> np.ndarray:
        return np.arange(self.cells_per_pi + 1) * self.h

    @property
    def q(self) -> np.ndarray:
        return np.array([p.q for p in self.points])

    @property
    def u(self) -> np.ndarray:
        return np.array([p.u_half for p in self.points]).reshape(len(self.points), self.cells_per_pi + 1)

    def column(self, name: str) -> np.ndarray:
        """A diagnostic or a solver statistic along the branch (one of :data:`POINT_FIELDS`), as an array."""
        if name not in POINT_FIELDS:
            raise ParameterError("name", name, f"must be a field of the branch: one of {', '.join(POINT_FIELDS)}")
        if name in WaveDiagnostics.names():
            return np.array([getattr(p.diagnostics, name) for p in self.points])
        return np.array([p.record()[name] for p in self.points])

    def __len__(self):
        return len(self.points)

    def point(self, q: float, tol: float = 1e-12) -> BranchPoint:
        """The point at wavenumber q, or :class:`RecordFileError` naming the range the branch has."""
        qs = self.q
        i = int(np.argmin(np.abs(qs - q))) if len(qs) else -1
        if i < 0 or abs(qs[i] - q) > tol * max(1.0, abs(q)):
            if len(qs):
                near = sorted(qs[np.argsort(np.abs(qs - q))[:2]])
                have = (f"it has {len(qs)} points, q in [{qs.min():.6g}, {qs.max():.6g}], the nearest "
                        + " and ".join(f"{x:.12g}" for x in near))
            else:
                have = "it is empty"
            raise RecordFileError(f"the branch has no point at q = {q:.12g} ({have})")
        return self.points[i]

    def q_k(self) -> float:
        """q_k where F(q_k) = 1 (paper: q_k ~ 1.8)."""
        return crossing(self.q, self.column("F"), 1.0)

    def model_entry(self) -> dict:
        """{'model': the model's description as JSON} for any model but the uncompressed monatomic Hertz chain, whose
        files hold its alpha alone (as they always did); empty for it."""
        plain = self.model.describe() == {"alpha": self.alpha, "masses": [1.0]}
        return {} if plain else dict(model=json.dumps(self.model.describe(), sort_keys=True))

    def constants(self) -> dict:
        """The per-file entries of the branch file (its identity among them)."""
        return dict(alpha=self.alpha, cells_per_pi=self.cells_per_pi, h=self.h, M=self.M, xi=self.xi,
                    meta=json.dumps(self.meta), **self.model_entry())

    @classmethod
    def load(cls, path: str, comm: Optional[PETSc.Comm] = None, min_points: int = 1) -> Branch:
        """Read a branch file; :class:`RecordFileError` if it is missing, corrupt, of another kind, or holds fewer
        than ``min_points`` points (an interrupted continuation's file may hold none: resume it first). With a
        communicator, rank 0 reads it and every rank gets the branch (or the error)."""
        if comm is not None:
            return on_rank0(comm, cls.load, path, None, min_points, what=f"cannot read branch file {path!r}")
        data = read_kind(path, BRANCH_KIND, "branch file")
        P = len(data["q"])
        if P < min_points:
            raise RecordFileError(f"branch file {path!r} holds {P} point(s), {min_points} needed (an interrupted "
                                  "continuation: continue it with scripts/continuation.py -resume)")
        if data["u"].shape != (P, len(data["xi"])) or any(len(data[k]) != P for k in POINT_FIELDS):
            raise RecordFileError(f"branch file {path!r} is corrupt: inconsistent array shapes")
        try:
            meta = json.loads(str(data["meta"]))
        except ValueError:
            raise RecordFileError(f"branch file {path!r} is corrupt: unreadable meta") from None
        try:
            model = LatticeModel.from_description(json.loads(str(data["model"]))) if "model" in data else \
                LatticeModel.hertz(float(data["alpha"]))
        except (ValueError, ParameterError) as err:
            raise RecordFileError(f"branch file {path!r} holds a model that cannot be rebuilt: {err}") from None
        branch = cls(model, int(data["cells_per_pi"]), int(data["M"]), [], meta)
        rows = [{k: data[k][i] for k in POINT_FIELDS + ("u",)} for i in range(P)]
        branch.points = [BranchPoint.from_record(r, branch.h, branch.model) for r in rows]
        branch.path = path
        return branch


def branch_store(path, branch, comm, mode):
    """The record store of a branch file for ``branch`` (its model, grid and M; its meta is written): resuming
    needs the same alpha, cells_per_pi and M. Collective. ``path`` None: the records are kept in memory."""
    layout = dict(dtypes=BRANCH_KIND.dtypes, shapes={"u": (branch.cells_per_pi + 1,)}, columns=BRANCH_KIND)
    if path is None:
        return MemoryRecords(BRANCH_FORMAT, branch.constants(), BRANCH_KIND.fields, comm, **layout)
    return NpzRecords(path, BRANCH_FORMAT, branch.constants(),
                      dict(alpha=branch.alpha, cells_per_pi=branch.cells_per_pi, M=branch.M, **branch.model_entry()),
                      BRANCH_KIND.fields, comm, mode, what="branch file", **layout)
