"""Studies of precompressed and dimer chains (issue 16): amplitude families at fixed q from the linear wave to
the uncompressed limit, the gap opening, dimer families in the mass ratio; the waves of the stability map.

Record files (npz, written as they go, -resume continues, :class:`~hertzpetsc.records.NpzRecords`), their columns
declared in :data:`PRECOMPRESSED_KIND` (:class:`AmplitudeFamilies`) and :data:`DIMER_KIND` (:class:`DimerFamilies`,
with the end state of every q computed, for -resume; older files hold one state, of the last q, and resume that q
only; a ``hertzpetsc-dimer-1`` file is read for its tables and cannot be resumed).

The stability map in (q, A) (record kind ``hertzpetsc-precompression-map-2``) is :mod:`hertzpetsc.studies.maps`,
on the waves of :func:`richardson_wave` / :func:`wave_orbit` here.
"""
from __future__ import annotations

import math
from dataclasses import MISSING, dataclass
from typing import TYPE_CHECKING, Iterator, Optional

import numpy as np

from ..diagnostics import sup_norm
from ..errors import (Checked, ConvergenceError, ParameterError, RecordFileError, check_instance, check_real,
                      check_reals, param)
from ..grid import ProfileGrid, cells_per_pi_param
from ..advdelay import check_branch, check_wavenumber
from ..model import ChainSpec, LatticeModel
from ..families import (AmplitudeFamily, MassFamily, check_amplitude, check_family_amplitude, check_wave_amplitude,
                        uncompressed_limit)
from ..records import Column, Kind
from ..resources import check_memory
from ..roles import uses
from ..twsolver import tw_solver
from .base import Study
from ..richardson import extrapolate
from ..branch import BranchPoint
from ..waves import orbit_on_chain
from .floquet import q_label

if TYPE_CHECKING:
    from petsc4py import PETSc

PRECOMPRESSED_FORMAT = "hertzpetsc-precompressed-1"
PRECOMPRESSED_KIND = Kind(PRECOMPRESSED_FORMAT, (
    Column("alpha", "Hertz exponent", constant=True),
    Column("delta0", "precompression (static overlap)", constant=True),
    Column("cells_per_pi", "grid h = pi / cells_per_pi", "count", np.int64, "d", constant=True),
    Column("a_min", "the amplitude grid a_min exp(k ds) up to a_max: its first a", constant=True),
    Column("a_max", "its last a", constant=True),
    Column("ds", "its step in s = log a", constant=True),
    Column("masses", "the repeating masses: only for a mass pattern (files since 2026-11-28)", shape="p",
           constant=True, optional=True),
    Column("branch", "the linear branch the family starts from (`acoustic` or `optical`): only for a mass pattern",
           "", str, "s", constant=True, optional=True),
    Column("solver_options", "numeric-changing options under `-precomp_` (files since b3184da)", "", str, "s",
           constant=True, optional=True),
    Column("q", "wavenumber", format=".6f"),
    Column("kind", "0 = a point of the s = log a grid, 1 = the gap opening (the longest bond reaches delta0: "
           "2 u(q/2) = delta0 for one mass), 2 = the uncompressed limit delta0 / A = 0 (a and A are inf)", "",
           np.int64, "d"),
    Column("a", "first sine coefficient of u (of the normalised profile for a pattern)", format=".6g"),
    Column("A", "\\|\\|u\\|\\|_inf (the largest over the pattern's profiles)", format=".6g"),
    Column("omega", "frequency", format=".8f"),
    Column("omega_lin", "the branch's linear frequency (closed form)", format=".8f"),
    Column("Omega", "omega A^(-(alpha-1)/2)", format=".8f"),
    Column("lam", "omega^2 / a^(alpha-1), the rescaled unknown", format=".8f"),
    Column("gap", "the longest bond minus delta0, 2 u(q/2) - delta0 for one mass (0 at the gap opening)",
           format=".3e"),
    Column("iterations", "Newton iterations", "count", np.int64, "d"),
))
PRECOMPRESSED_FIELDS = PRECOMPRESSED_KIND.fields
DIMER_FORMAT = "hertzpetsc-dimer-2"
DIMER_KIND = Kind(DIMER_FORMAT, (
    Column("alpha", "Hertz exponent (absent for another law)", constant=True, optional=True),
    Column("delta0", "precompression (absent for another law)", constant=True, optional=True),
    Column("law", "a chain of another law than Hertz's: its name, its parameters beside it (absent for Hertz's)",
           "", str, "s", constant=True, optional=True),
    Column("cells_per_pi", "grid h = pi / cells_per_pi", "count", np.int64, "d", constant=True),
    Column("a", "fixed amplitude (first sine coefficient of the heavy bead's profile u)", constant=True),
    Column("epsilon_end", "the continuation stops once epsilon passes it", constant=True),
    Column("ds", "first arclength step", constant=True),
    Column("ds_max", "largest arclength step", constant=True),
    Column("solver_options", "numeric-changing options under `-dimer_` and `-dimer_natural_`", "", str, "s",
           constant=True, optional=True),
    Column("q", "per-bead wavenumber"),
    Column("epsilon", "mass ratio (masses 1, epsilon)", format=".5f"),
    Column("omega", "frequency", format=".6f"),
    Column("omega_acoustic", "the linear acoustic frequency (closed form)", format=".6f"),
    Column("arclength", "arclength s"),
    Column("tangent_epsilon", "d epsilon / ds (a sign change is a fold)"),
    Column("norm_u", "\\|\\|u_0\\|\\|_inf (heavy bead)"),
    Column("norm_v", "\\|\\|u_1\\|\\|_inf (light bead)"),
    Column("v1", "first sine coefficient of the light bead's profile", format=".4f"),
    Column("v2", "second sine coefficient of the light bead's profile", format=".4f"),
    Column("iterations", "Newton iterations", "count", np.int64, "d"),
    Column("event", "0: a point of the path, 1: a located fold of epsilon, 2: the gap opening located on the path",
           "", np.int64, "d"),
))
DIMER_FIELDS = DIMER_KIND.fields
EVENT_CODES = {None: 0, "fold": 1, "gap": 2}
KIND_GRID, KIND_GAP, KIND_LIMIT = 0, 1, 2


def amplitude_grid(a_min, a_max, ds):
    """a_k = a_min exp(k ds) up to a_max (included): the s = log a grid of the amplitude families."""
    a_min, a_max = check_amplitude(a_min, "a_min"), check_amplitude(a_max, "a_max")
    if not a_max > a_min:
        raise ParameterError("a_max", a_max, f"must exceed a_min = {a_min:g}")
    ds = check_real("ds", ds, "the step in log a", 0.0)
    n = int(math.floor(math.log(a_max / a_min) / ds + 1e-9))
    if n > MAX_AMPLITUDES:
        raise ParameterError("ds", ds, f"gives {n + 1} amplitudes from a_min to a_max: at most {MAX_AMPLITUDES} "
                             f"(ds >= {math.log(a_max / a_min) / MAX_AMPLITUDES:.3g})")
    grid = [a_min * math.exp(k * ds) for k in range(n + 1)]
    if grid[-1] < a_max * (1 - 1e-12):
        grid.append(a_max)
    return grid


MAX_AMPLITUDES = 10000


def _check_delta0_positive(model):
    check_instance("model", model, LatticeModel, "a LatticeModel (e.g. LatticeModel.hertz(1.5, delta0=1))")
    if not model.delta0 > 0:
        raise ParameterError("delta0", model.delta0, "the families of this study need a precompression > 0")


def _at(records, q):
    """The records at wavenumber ``q`` (to 1e-12 relative)."""
    return [r for r in records if abs(float(r["q"]) - q) <= 1e-12 * q]


def _check_qs(q, h=None, name="q", distinct=True):
    """The wavenumbers ``q`` (a number or a sequence of them; each once if ``distinct``) as a tuple of checked
    wavenumbers."""
    return tuple(check_wavenumber(x, h, name) for x in check_reals(name, q, "wavenumbers", distinct=distinct))


@dataclass(frozen=True)
class AmplitudeParameters(Checked):
    """The amplitude families: the precompressed ``model`` (any mass pattern), per-bead wavenumbers ``q``, grid
    h = pi / cells_per_pi, amplitudes a_min exp(k ds) up to a_max (at most :data:`MAX_AMPLITUDES`), each family
    from the linear wave of ``branch`` ('acoustic': the lowest frequency of the pattern; 'optical': the highest)."""

    model: LatticeModel
    q: tuple = param(MISSING, "per-bead wavenumbers", "reals", lo=0.0, hi=math.pi, hi_open=False, distinct=True,
                     expr=True)
    cells_per_pi: int = cells_per_pi_param(1000)
    a_min: float = param(1e-3, "the first amplitude (first sine coefficient of u), in [delta0 max(sqrt(eps), "
                         "eps^(1/(2(alpha-1)))), 0.1 delta0]", lo=0.0)
    a_max: float = param(1e3, "the last amplitude", lo=0.0)
    ds: float = param(0.1, "the step in s = log a", lo=0.0)
    branch: str = param("acoustic", "the linear branch the families start from", choices=("acoustic", "optical"))

    def __post_init__(self):
        _check_delta0_positive(self.model)
        super().__post_init__()
        for q in _check_qs(self.q, math.pi / self.cells_per_pi):
            check_branch(self.model, q, self.branch)
        amplitude_grid(self.a_min, self.a_max, self.ds)
        check_family_amplitude(self.model, self.a_min, "a_min", start=True)


class AmplitudeFamilies(Study):
    """omega(q, A) of the precompressed chain (any mass pattern): at each q, the continuation in s = log a from
    a_min to a_max (:class:`~hertzpetsc.families.AmplitudeFamily`, prefix ``precomp_``), the gap opening
    located on the way, and the uncompressed limit on the same grid. Records per point (module docstring)."""

    Parameters = AmplitudeParameters
    FORMAT, FIELDS, COLUMNS = PRECOMPRESSED_FORMAT, PRECOMPRESSED_FIELDS, PRECOMPRESSED_KIND
    DTYPES = PRECOMPRESSED_KIND.dtypes
    ROLES = uses("precomp_")
    WHAT = "precompressed-wave file"

    def __init__(self, params: AmplitudeParameters, comm: Optional[PETSc.Comm] = None,
                 output: Optional[str] = None, mode: str = "new") -> None:
        super().__init__(params, comm, output, mode)
        self.model, self.qs, self.K, self.branch = params.model, list(params.q), params.cells_per_pi, params.branch
        self.amplitudes = amplitude_grid(params.a_min, params.a_max, params.ds)
        check_memory(self.K, self.comm, tw_solver("precomp_"))

    def constants(self) -> dict:
        p = self.params
        pattern = {} if self.model.cell == 1 and self.branch == "acoustic" else dict(
            masses=list(self.model.masses), branch=self.branch)            # monatomic files keep their identity
        return dict(self.model.law_identity(), cells_per_pi=self.K, a_min=p.a_min, a_max=p.a_max, ds=p.ds,
                    **pattern)

    def omega_lin(self, q: float) -> float:
        """The linear frequency of the family's branch at q (closed form, :meth:`LatticeModel.linear_frequencies`)."""
        return float(self.model.linear_frequencies(q)[0 if self.branch == "acoustic" else -1])

    def _row(self, point, kind):
        return dict(q=point.q, kind=kind, a=point.a, A=point.A, omega=point.omega, omega_lin=self.omega_lin(point.q),
                    Omega=point.Omega, lam=point.lam, gap=point.gap, iterations=point.iterations)

    def run(self) -> Iterator[dict]:
        """Compute every q not complete in the file; yields each new record after saving it."""
        self.open()
        grid = ProfileGrid(self.K, self.comm)
        for q in self.qs:
            done = {(int(r["kind"]), round(float(r["a"]), 10)) for r in _at(self.store.records, q)}
            if any(k == KIND_LIMIT for k, _ in done):
                continue
            fam = AmplitudeFamily(self.model, q, grid, branch=self.branch)
            try:
                gap_found = any(k == KIND_GAP for k, _ in done)
                for a in self.amplitudes:
                    point = fam.step_to(a)
                    for gap in fam.events():
                        if not gap_found:
                            gap_found = True
                            yield self.store.append(self._row(gap, KIND_GAP))
                    if (KIND_GRID, round(a, 10)) not in done:
                        yield self.store.append(self._row(point, KIND_GRID))
                limit = uncompressed_limit(self.model, q, grid, point)
            finally:
                fam.destroy()
            row = dict(q=q, kind=KIND_LIMIT, a=math.inf, A=math.inf, omega=math.inf, omega_lin=self.omega_lin(q),
                       Omega=limit["Omega0"], lam=limit["lam"], gap=math.inf, iterations=limit["iterations"])
            yield self.store.append(row)

    def rows(self, q: float) -> tuple[list[dict], Optional[dict], Optional[dict]]:
        """(grid points sorted by a, gap record or None, limit record or None) at q."""
        recs = _at(self.store.records, q)
        grid = sorted((r for r in recs if int(r["kind"]) == KIND_GRID), key=lambda r: float(r["a"]))
        gap = next((r for r in recs if int(r["kind"]) == KIND_GAP), None)
        limit = next((r for r in recs if int(r["kind"]) == KIND_LIMIT), None)
        return grid, gap, limit

    def summary(self, q: float) -> dict:
        """Per q: the small-amplitude coefficient (fit of omega/omega_lin - 1 on the smallest amplitudes, on this
        grid against the closed form's omega_lin: includes the O(h^2) offset of the scheme), A_gap, Omega at the
        largest A, Omega0 and c1 = (Omega - Omega0) A / delta0 at the largest two A."""
        d0 = self.model.delta0
        grid, gap, limit = self.rows(q)
        out = dict(q=q, C_theory=round(float(self.model.law.stokes_coefficient(q)), 15) + 0.0
                   if self.model.cell == 1 else math.nan)           # the closed form is the monatomic chain's
        small = [r for r in grid if float(r["a"]) <= 0.05 * d0]
        if len(small) >= 3:
            a = np.array([float(r["a"]) for r in small])
            y = np.array([float(r["omega"]) / float(r["omega_lin"]) - 1 for r in small])
            coef = np.linalg.lstsq(np.stack([np.ones_like(a), a ** 2, a ** 4], 1), y, rcond=None)[0]
            out.update(offset_h=float(coef[0]), C_fit=float(coef[1]))
        if gap is not None:
            out.update(A_gap=float(gap["A"]), omega_gap=float(gap["omega"]), a_gap=float(gap["a"]))
        if grid:
            out.update(A_max=float(grid[-1]["A"]), Omega_max=float(grid[-1]["Omega"]))
        if limit is not None:
            out["Omega0"] = float(limit["Omega"])
            if len(grid) >= 2:
                (A1, O1), (A2, O2) = [(float(r["A"]), float(r["Omega"]) - out["Omega0"]) for r in grid[-2:]]
                out.update(c1=O2 * A2 / d0, c1_previous=O1 * A1 / d0)
                if O1 > 0 and O2 > 0:
                    out["rate"] = math.log(O1 / O2) / math.log(A2 / A1)
        far = [r for r in grid if float(r["A"]) >= 20 * d0]
        if len(far) >= 4:
            # extrapolation without the eta = 0 solve: Omega = Omega0 + c1 x + c2 x^2, x = delta0 / A
            x = np.array([d0 / float(r["A"]) for r in far])
            y = np.array([float(r["Omega"]) for r in far])
            out["Omega0_fit"] = float(np.linalg.lstsq(np.stack([np.ones_like(x), x, x ** 2], 1), y, rcond=None)[0][0])
        return out

    def table(self) -> str:
        alpha, d0 = self.model.alpha, self.model.delta0
        chain = "monatomic chain" if self.model.cell == 1 else (
            f"chain of masses {', '.join(f'{m:g}' for m in self.model.masses)} (repeated), {self.branch} family")
        lines = [f"schema: {PRECOMPRESSED_FORMAT}; precompressed {chain}, alpha = {alpha:g}, delta0 = {d0:g}, "
                 f"h = pi/{self.K}; amplitude continuation in s = log a (a: first sine coefficient of u), "
                 f"a from {self.amplitudes[0]:g} to {self.amplitudes[-1]:g}.\n",
                 "Columns: C(q) closed form (alpha-1)(alpha-1-sin^2(q/2))/(4 delta0^2) and the fit "
                 "omega/omega_lin - 1 = c0 + C a^2 + D a^4 over a <= 0.05 delta0 on this grid (c0: the scheme's O(h^2)"
                 " offset of the linear frequency); A_gap where 2 u(q/2) = delta0 and omega there; Omega = "
                 "omega A^(-(alpha-1)/2) at the largest A; Omega0 its uncompressed limit (delta0/A = 0, same grid); "
                 "c1 = (Omega - Omega0) A / delta0 at the two largest A; rate: the exponent p of Omega - Omega0 ~ "
                 "(delta0/A)^p between them; Omega0 fit: Omega0 + c1 x + c2 x^2 (x = delta0/A) fitted over "
                 "A >= 20 delta0, without the limit solve.\n",
                 "| q | omega_lin | C(q) theory | C fit (c0) | A_gap | omega(A_gap) | A_max | Omega(A_max) | Omega0 | "
                 "Omega0 fit | c1 (previous A) | rate |",
                 "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for q in self.qs:
            s = self.summary(q)
            fmt = lambda k, f="{:.6f}": f.format(s[k]) if k in s else "n/a"   # noqa: E731
            theory = f"{s['C_theory']:.6f}" if math.isfinite(s["C_theory"]) else "n/a"
            lines.append(f"| {q_label(q)} | {self.omega_lin(q):.6f} | {theory} | "
                         + (f"{s['C_fit']:.6f} ({s['offset_h']:.1e})" if "C_fit" in s else "n/a")
                         + f" | {fmt('A_gap')} | {fmt('omega_gap')} | {fmt('A_max', '{:.4g}')} | {fmt('Omega_max')} | "
                         f"{fmt('Omega0', '{:.8f}')} | {fmt('Omega0_fit', '{:.8f}')} | "
                         + (f"{s['c1']:.5f} ({s['c1_previous']:.5f})" if "c1" in s else "n/a")
                         + f" | {fmt('rate', '{:.4f}')} |")
        return "\n".join(lines) + "\n"

    def curves(self) -> dict[float, tuple]:
        """{q: (A, omega, omega_lin, Omega0, (A_gap, omega_gap) or nans)} for the figure."""
        out = {}
        for q in self.qs:
            grid, gap, limit = self.rows(q)
            if not grid:
                continue
            out[q] = (np.array([float(r["A"]) for r in grid]), np.array([float(r["omega"]) for r in grid]),
                      float(grid[0]["omega_lin"]), float(limit["Omega"]) if limit is not None else math.nan,
                      (float(gap["A"]), float(gap["omega"])) if gap is not None else (math.nan, math.nan))
        return out


def sine_coefficient(u_half, k):
    """(1/pi) int_0^{2 pi} u sin(k xi) of an odd profile given on [0, pi] (trapezoid rule, spectrally accurate)."""
    K = len(u_half) - 1
    return float(2.0 / K * np.dot(np.sin(k * np.arange(K + 1) * math.pi / K), u_half))


MAX_STEPS = 100000


@dataclass(frozen=True)
class DimerParameters(Checked):
    """The dimer families: the precompressed monatomic ``model`` (the dimer has masses 1, epsilon), per-bead
    wavenumbers ``q``, amplitude a (first sine coefficient of the heavy bead's profile), grid h = pi /
    cells_per_pi, pseudo-arclength from epsilon = 1 until epsilon_end or max_steps (at most :data:`MAX_STEPS`)
    steps of ds (first) .. ds_max."""

    model: LatticeModel
    q: tuple = param(MISSING, "per-bead wavenumbers (the dimer's zone: q <= pi/2)", "reals", lo=0.0,
                     hi=math.pi / 2, hi_open=False, distinct=True, expr=True)
    a: float = param(0.5, "the amplitude (first sine coefficient of u)", lo=0.0)
    cells_per_pi: int = cells_per_pi_param(200)
    epsilon_end: float = param(0.3, "the last mass ratio (continuation from epsilon = 1 down)", lo=0.0, hi=1.0)
    max_steps: int = param(200, "the arclength steps per q", lo=1, hi=MAX_STEPS)
    ds: float = param(0.02, "the first arclength step", lo=0.0, hi=1.0, hi_open=False)
    ds_max: float = param(0.1, "the largest arclength step", lo=0.0, hi=1.0, hi_open=False)

    def __post_init__(self):
        _check_delta0_positive(self.model)
        if self.model.cell != 1:
            raise ParameterError("masses", list(self.model.masses), "give the monatomic model; the dimer is built "
                                 "from it")
        super().__post_init__()
        _check_qs(self.q, math.pi / self.cells_per_pi)
        object.__setattr__(self, "a", check_wave_amplitude(self.model, self.a, "a"))
        if self.ds > self.ds_max:
            raise ParameterError("ds", self.ds, f"must not exceed ds_max = {self.ds_max:g}")


class DimerFamilies(Study):
    """Dimer waves (masses 1, epsilon) at fixed q and amplitude a, continued in epsilon from 1 by pseudo-arclength
    (:class:`~hertzpetsc.families.MassFamily`, prefix ``dimer_``) until epsilon passes epsilon_end or
    ``max_steps``. A q whose continuation stops (no convergence after step halving) keeps its saved points and
    the table says where it stopped."""

    Parameters = DimerParameters
    FORMAT, FIELDS, DTYPES, COLUMNS = DIMER_FORMAT, DIMER_FIELDS, DIMER_KIND.dtypes, DIMER_KIND
    ROLES = uses("dimer_", "dimer_natural_")
    WHAT = "dimer file"

    def __init__(self, params: DimerParameters, comm: Optional[PETSc.Comm] = None, output: Optional[str] = None,
                 mode: str = "new") -> None:
        super().__init__(params, comm, output, mode)
        p = params
        self.model = LatticeModel(p.model.law, (1.0, 1.0))
        self.qs, self.a, self.K = list(p.q), p.a, p.cells_per_pi
        self.epsilon_end, self.max_steps, self.ds, self.ds_max = p.epsilon_end, p.max_steps, p.ds, p.ds_max
        check_memory(self.K, self.comm, tw_solver("dimer_"), profiles=2)
        self.stopped = {}

    def constants(self) -> dict:
        return dict(self.model.law_identity(), cells_per_pi=self.K, a=self.a, epsilon_end=self.epsilon_end,
                    ds=self.ds, ds_max=self.ds_max)

    def _row(self, q, p):
        w = p.wave
        return dict(q=q, epsilon=p.epsilon, omega=w.omega,
                    omega_acoustic=float(self.model.with_masses((1.0, p.epsilon)).linear_frequencies(q)[0]),
                    arclength=p.arclength, tangent_epsilon=p.tangent_epsilon, norm_u=self.a * sup_norm(w.profiles[0]),
                    norm_v=self.a * sup_norm(w.profiles[1]), v1=self.a * sine_coefficient(w.profiles[1], 1),
                    v2=self.a * sine_coefficient(w.profiles[1], 2), iterations=w.iterations,
                    event=EVENT_CODES[getattr(p, "event", None)])

    def _natural_state(self, state, q, problem):
        """The saved state with its vectors in the ranks' independent order. Files written before that order (no
        ``state_layout``) hold them in the layout of the writer's ranks, which they do not record: it is the split of
        the grid over r ranks (PETSc's, r = 1, 2, ...) whose last profiles give back the last record's ||u||,
        ||v|| and v1."""
        if str(state.get("layout", "")) == "natural":
            return state
        Z = np.asarray(state["Z"])
        n, last = problem.grid.size, self._regular(q)[-1]
        want = [float(last[k]) for k in ("norm_u", "norm_v", "v1")]
        for r in range(1, n + 1):
            order = problem.natural_order(Z.shape[1], n // r + (np.arange(r) < n % r))
            u, v = (np.concatenate([[0.0], w, [0.0]]) for w in np.split(Z[-1][order][:2 * n], 2))
            got = [self.a * sup_norm(u), self.a * sup_norm(v), self.a * sine_coefficient(v, 1)]
            if np.allclose(got, want, rtol=1e-10, atol=0.0):
                return dict(state, Z=Z[:, order], layout="natural")
        raise RecordFileError(f"{self.WHAT} {self.output!r}: its saved state (state_Z) does not match its last "
                              f"record at q = {q!r}: rerun with -force")

    def _regular(self, q):
        """The records of the regular points of the path at q (events left out)."""
        return [r for r in _at(self.store.records, q) if int(r.get("event", 0)) == 0]

    def _progress(self, q):
        """(regular points saved for q, finished?) from the records."""
        rows = self._regular(q)
        if not rows:
            return 0, False
        return len(rows), self._ended(rows) or len(rows) - 2 >= self.max_steps or q in self.stopped

    def _ended(self, rows):
        """Whether the path's last regular point passed epsilon_end (or epsilon 0): the path is complete."""
        last = float(rows[-1]["epsilon"])
        return (last - self.epsilon_end) * (1.0 - self.epsilon_end) < 0 or last <= 0

    STATE_KEYS = ("Z", "s", "ds", "normalised")

    def _end_states(self):
        """{round(q, 12): state} of the q's whose end state the file holds (plain arrays, natural layout but for an
        older file's one state, made natural in :meth:`run`)."""
        state = self.store.state
        if "q" not in state:
            return {}
        qs = np.asarray(state["q"], dtype=float)
        if qs.ndim == 0:                   # a file written before the end state of every q was kept: the last q's
            return {round(float(qs), 12): dict({k: state[k] for k in self.STATE_KEYS}, q=float(qs),
                                               layout=str(state.get("layout", "")))}
        return {round(float(q), 12): dict({k: state[k][i] for k in self.STATE_KEYS}, q=float(q), layout="natural")
                for i, q in enumerate(qs)}

    def _state_arrays(self):
        """The store's state: the end state of every q held, stacked along a first axis (``state_q`` (m,), ...)."""
        ends = list(self._ends.values())
        return dict(q=np.array([e["q"] for e in ends]), layout="natural",
                    **{k: np.array([np.asarray(e[k]) for e in ends]) for k in self.STATE_KEYS})

    def _save(self, q, row, mc=None):
        """Append ``row``; with ``mc``, the family's state replaces q's end state (collective)."""
        if mc is None:
            return self.store.append(row)
        self._ends[round(q, 12)] = dict(mc.snapshot(), q=q)
        return self.store.append(row, state=self._state_arrays())

    def run(self) -> Iterator[dict]:
        """Continue every q not finished in the file: a q in progress resumes from its saved end state (the last
        two points and the step), a larger -max_steps extends a finished path; yields each new record after saving
        it (with the end state of its q for a resume). A file that lacks the end state of a q to continue (one
        written when only the last q's was kept) is refused, naming the q."""
        self.open()
        grid = ProfileGrid(self.K, self.comm)
        self._ends = self._end_states()
        todo = [(q, *self._progress(q)) for q in self.qs]
        for q, saved, finished in todo:
            if saved >= 2 and not finished and round(q, 12) not in self._ends:
                held = ", ".join(q_label(e["q"]) for e in self._ends.values()) or "none"
                raise RecordFileError(
                    f"{self.WHAT} {self.output!r} holds no end state of q = {q_label(q)} (only of q = {held}: it was "
                    "written when a file kept the last q's alone), so -resume cannot continue it without restarting "
                    "it: resume the other q's alone (-q), or recompute it without -resume (-force, or another "
                    "-output)")
        for key, end in list(self._ends.items()):
            if end["layout"] != "natural":          # an older file's state, in its writer's rank layout
                mc = MassFamily(self.model, end["q"], grid, self.a, ds=self.ds, ds_max=self.ds_max)
                try:
                    self._ends[key] = self._natural_state(end, end["q"], mc.problem)
                finally:
                    mc.destroy()
        for q, saved, finished in todo:
            if finished:
                continue
            mc = MassFamily(self.model, q, grid, self.a, ds=self.ds, ds_max=self.ds_max)
            try:
                if saved >= 2:
                    mc.restore(self._ends[round(q, 12)])
                else:
                    # the two start points; the state (both points) is saved with the second: a run stopped after
                    # the first recomputes them and saves the second (the first is the same computation)
                    points = list(mc.start())
                    for i, p in enumerate(points[saved:], saved):
                        yield self._save(q, self._row(q, p), mc if i == len(points) - 1 else None)
                    saved = len(points)
                try:
                    for p in mc.run(self.epsilon_end, self.max_steps - (saved - 2)):
                        row = self._row(q, p)
                        if p.event is not None:
                            # an event row keeps the state of the previous point: a resume recomputes this step
                            # and finds the event again (not saved twice)
                            if any(int(r["event"]) == row["event"] and abs(float(r["epsilon"]) - p.epsilon) <= 1e-9
                                   for r in _at(self.store.records, q)):
                                continue
                            self._save(q, row)
                        else:
                            self._save(q, row, mc)
                        yield row
                except ConvergenceError as err:
                    self.stopped[q] = str(err)
            finally:
                mc.destroy()

    def table(self) -> str:
        lines = [f"schema: {DIMER_FORMAT}; precompressed dimer (masses 1, epsilon), alpha = {self.model.alpha:g}, "
                 f"delta0 = {self.model.delta0:g}, h = pi/{self.K}, fixed amplitude a = {self.a:g} (first sine "
                 "coefficient of the heavy bead's profile u); pseudo-arclength in epsilon from 1. v1, v2: first and "
                 "second sine coefficients of the light bead's profile v at the end.\n",
                 "| q | points | epsilon reached (min) | omega at epsilon = 1 | omega at the end | ||v||/||u|| at the end "
                 "| v1, v2 at the end | folds (sign changes of d epsilon/ds) | omega_acoustic(linear) at the end "
                 "| located: folds, gap opening (epsilon) |",
                 "|---|---|---|---|---|---|---|---|---|---|"]
        names = {v: k for k, v in EVENT_CODES.items()}
        for q in self.qs:
            rows = self._regular(q)
            if not rows:
                continue
            events = ", ".join(f"{names[int(r['event'])]} {float(r['epsilon']):.6f}"
                               + (" (unresolved)" if int(r.get("iterations", 1)) == 0 else "")
                               for r in _at(self.store.records, q) if int(r.get("event", 0)) != 0) or "none"
            t = np.array([float(r["tangent_epsilon"]) for r in rows])
            t = t[np.isfinite(t)]
            folds = int(np.sum(np.sign(t[1:]) != np.sign(t[:-1]))) if len(t) > 1 else 0
            last = rows[-1]
            least = min(r["epsilon"] for r in rows)
            lines.append(DIMER_KIND.row(last, q_label(q), len(rows), f"{{epsilon}} ({least:.5f})",
                                        f"{rows[0]['omega']:.6f}", "{omega}", f"{last['norm_v'] / last['norm_u']:.4f}",
                                        "{v1}, {v2}", folds, "{omega_acoustic}", events))
        for q, why in self.stopped.items():
            lines.append(f"\nq = {q_label(q)}: stopped: {why}")
        for q in self.qs:
            rows = self._regular(q)
            if rows and q not in self.stopped and not self._ended(rows):
                lines.append(f"\nq = {q_label(q)}: -max_steps = {self.max_steps} reached at epsilon = "
                             f"{float(rows[-1]['epsilon']):.5f}, before -epsilon_end = {self.epsilon_end:g} (-resume "
                             "with a larger -max_steps goes on)")
        return "\n".join(lines) + "\n"

    def curves(self) -> dict[float, tuple]:
        out = {}
        for q in self.qs:
            rows = self._regular(q)
            if rows:
                out[q] = tuple(np.array([float(r[k]) for r in rows]) for k in ("epsilon", "omega", "omega_acoustic",
                                                                                 "norm_v"))
        return out


# --- Floquet stability in (q, A) ------------------------------------------------------------------------------
def richardson_wave(model, q, a_values, K, comm):
    """The waves at the amplitudes ``a_values`` (increasing) on the grids K and 2K combined by Richardson (second
    order): [(a, half profiles on the K grid, lam)], then (inf, profiles, lam) of the uncompressed limit; initial
    data whose orbit error is O(h^4)."""
    sols = []
    for k in (K, 2 * K):
        grid = ProfileGrid(k, comm)
        cont = AmplitudeFamily(model, q, grid)
        try:
            pts = list(cont.points(a_values))
            limit = uncompressed_limit(model, q, grid, pts[-1])
        finally:
            cont.destroy()
        sols.append([(p.a, p.profiles, p.lam) for p in pts] + [(math.inf, limit["profiles"], limit["lam"])])
    return [(a1, [extrapolate(v1, v2[::2]) for v1, v2 in zip(w1, w2)], extrapolate(l1, l2))
            for (a1, w1, l1), (_, w2, l2) in zip(*sols)]


def wave_orbit(model, q, a, profiles, lam, N, h):
    """The wave u_c = a w_c of the rescaled profiles ``profiles`` (grid step h) with omega^2 = a^(d-1) lam on N beads
    of ``model`` (a = inf: the uncompressed limit, on the same model without precompression)."""
    if not math.isfinite(a):
        model, a = model.with_delta0(0.0), 1.0
    point = BranchPoint(q, np.asarray(profiles[0]), h, model.rescaled(a), profiles=tuple(profiles),
                        omega=math.sqrt(lam))
    return orbit_on_chain(point, ChainSpec(model, N), scale=a)
