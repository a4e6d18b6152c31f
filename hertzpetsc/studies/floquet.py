"""Floquet studies of section 3.5: the scan of rho(F_q) along the branch on N beads (q_c, q_m), and the long-chain
spectra by Bloch sectors.

Both write their records as they go: the Floquet file and the Bloch file, their columns declared in
:data:`FLOQUET_KIND` and :data:`BLOCH_KIND`.

A stability verdict is only given for the waves it is computed on: with a refinement file, every scanned q must
be in it (a list naming an unrefined q is an error; without a list the scan is restricted to the refined q,
and the table says so); the unrefined branch waves are only used when asked for explicitly, and a wave whose trivial
multipliers spread by more than tol_rho is not judged (named below the table, left out of q_c).
"""
from __future__ import annotations

import math
import time
from fractions import Fraction
from typing import TYPE_CHECKING, Collection, Iterator, Mapping, Optional, Sequence

import numpy as np
from petsc4py import PETSc

from ..bloch import SymmetricFloquet, bloch_residuals, real_pairs, seeded_dominant_multipliers
from ..branch import Branch
from ..chain import IntegrationTolerances
from ..dealing import dealt
from ..errors import (ParameterError, RecordFileError, check_choice, check_instance, check_integer, check_integers,
                      check_real, check_reals)
from ..floquet import FLOQUET_TOLERANCES, TOL_RHO, DenseFloquet, dense_multipliers, spectral_radius
from ..model import ChainSpec
from ..records import OPTIONS_COLUMN, Column, Kind, check_kind, digest_column, given, load_npz
from ..roles import FLOQUET_ROUTES, floquet_route, uses
from ..verdicts import critical_wavenumbers
from ..waves import orbit_on_chain
from .base import Study
from .refinement import RefinedStates, scan_wavenumbers

if TYPE_CHECKING:
    from ..branch import Branch
    from ..chain import IntegrationTolerances
    from ..waves import Orbit
    from .refinement import RefinedStates

FLOQUET_FORMAT = "hertzpetsc-floquet-1"
FLOQUET_KIND = Kind(FLOQUET_FORMAT, (
    Column("N", "beads of the periodic chain", "count", np.int64, "d", constant=True),
    Column("alpha", "Hertz exponent", constant=True),
    Column("tol_rho", "verdict threshold: unstable when rho - 1 > tol_rho", constant=True),
    Column("method", "`symmetric`, `dense` or `slepc`", "", str, "s", constant=True),
    Column("refined_file", "the refinement file of the waves ('' for the unrefined branch waves)", "", str, "s",
           constant=True),
    Column("note", "which waves were scanned (e.g. `refined waves`)", "", str, "s", constant=True),
    digest_column("branch", "branch file"),
    digest_column("refined", "refinement file", "when there is one"),
    OPTIONS_COLUMN,
    Column("q", "wavenumbers", format=".4f"),
    Column("rho", "spectral radius of F_q, the four trivial multipliers excluded", format=".8f"),
    Column("outside", "multipliers with \\|mu\\| > 1 + tol_rho", "count", np.int64, "d"),
    Column("trivial_spread", "spread of the four trivial multipliers around 1 (the orbit error's sqrt)",
           format=".1e"),
    Column("growth", "ln(rho) / script-T, the growth rate per unit time", format=".4f"),
    Column("refined", "1 if the refined wave was used", "", np.int64, "d"),
    Column("seconds", "wall time of the q", "s", format=".1f"),
    Column("multipliers", "all multipliers (the `slepc` route: its `nev`, padded with nan)", dtype=complex,
           shape="2N"),
))
FLOQUET_FIELDS = FLOQUET_KIND.fields[:-1]
BLOCH_FORMAT = "hertzpetsc-bloch-1"
_INT = dict(unit="count", dtype=np.int64, format="d")
BLOCH_KIND = Kind(BLOCH_FORMAT, (
    Column("alpha", "Hertz exponent", constant=True),
    Column("M", "beads of the refined wave that is tiled (the refinement file's N)", constant=True, **_INT),
    Column("nev", "dominant multipliers kept and checked on the full chain", constant=True, **_INT),
    Column("tol_rho", "outside the circle: \\|lambda\\| > 1 + tol_rho", constant=True),
    Column("split", "`sectors` (dealt to the ranks) or `beads` (each sector over all ranks)", "", str, "s",
           constant=True),
    Column("rtol", "flow tolerance", constant=True),
    Column("refined_file", "the refinement file of the cell (a label)", "", str, "s", constant=True),
    digest_column("branch", "branch file"),
    digest_column("refined", "refinement file"),
    Column("solver_options", "number-changing options under `-floquet_` (absent from files written before it)", "",
           str, "s", constant=True, optional=True),
    Column("N", "beads of the long chain (a multiple of M)", **_INT),
    Column("q", "wavenumber"),
    Column("rho", "rho(F_q) on N beads, trivial multipliers excluded", format=".8f"),
    Column("rho_cell", "the sector theta = 0, i.e. rho of the M-bead chain", format=".8f"),
    Column("outside", "multipliers with \\|lambda\\| > 1 + tol_rho among all 2N", **_INT),
    Column("residual", "max relative \\|\\|F Y - lambda Y\\|\\| of the tiled dominant modes on the full chain "
           "(matrix-free)", format=".1e"),
    Column("seconds", "time of the Bloch sectors", "s", format=".1f"),
    Column("slepc_products", "seeded SLEPc on the full chain: shell products (-1: not run)", **_INT),
    Column("slepc_seconds", "its seconds (nan: not run)", "s", format=".1f"),
    Column("dominant", "the nev dominant multipliers", "1", complex, shape="nev"),
    Column("dominant_theta", "their Bloch parameter theta / 2 pi per M-bead cell", shape="nev"),
    # what the table prints besides, recorded since; a file written before lacks them: -1 or nan on load
    Column("runs", "Bloch work: TS runs in all", optional=True, **_INT),
    Column("columns", "Bloch work: tangent columns in all", optional=True, **_INT),
    Column("propagated", "1: every sector from the cell propagator on 3 cells", "", np.int64, "d",
           optional=True),
    Column("res_products", "the residual check: shell products", optional=True, **_INT),
    Column("res_seconds", "the residual check: seconds", "s", format=".1f", optional=True),
    Column("slepc_dist", "max distance of SLEPc's multipliers to the Bloch ones (nan: not run)",
           format=".1e", optional=True),
))
BLOCH_DETAIL = {"runs": -1, "columns": -1, "propagated": -1, "res_products": -1, "res_seconds": math.nan,
                "slepc_dist": math.nan}


def q_label(q):
    """q as a fraction of pi (7pi/25) when it is one, with a denominator <= 1000, to 1e-12; else its decimal value
    (q = 1 is '1', not the nearest fraction 7pi/22)."""
    f = Fraction(q / math.pi).limit_denominator(1000)
    if abs(float(f) * math.pi - q) > 1e-12 * max(q, 1.0):
        return f"{q:.6g}"
    numerator = f"{f.numerator if f.numerator != 1 else ''}pi"
    return f"{numerator}/{f.denominator}" if f.denominator != 1 else numerator


def _path(source):
    """The file a branch or refinement came from ('' for none or one computed in memory)."""
    return getattr(source, "path", "") or ""


def _check_scan(refined, tol_rho, tolerances):
    """The arguments the Floquet and Bloch scans share: a RefinedStates or None, tol_rho in (0, 1), the flows'
    IntegrationTolerances."""
    if refined is not None:
        check_instance("refined", refined, RefinedStates, "a RefinedStates (RefinedStates.load(path)) or None")
    check_real("tol_rho", tol_rho, "the verdict's threshold on rho - 1", 0.0, 1.0)
    check_instance("tolerances", tolerances, IntegrationTolerances, "an IntegrationTolerances(rtol, atol)")


def _select_wavenumbers(branch, N, qs, refined):
    """The scanned q and, for the table, a note on how they were restricted."""
    fitting = scan_wavenumbers(branch, N, qs)
    if refined is None:
        return fitting, "unrefined branch waves (interpolated onto the chain)"
    if refined.N != N:
        raise RecordFileError(f"refinement file {given(refined.path)} is for N = {refined.N} beads, not {N}")
    refined.check_alpha(branch.alpha)
    missing = [q for q in fitting if not refined.has(q)]
    if qs:
        if missing:
            raise RecordFileError(f"refinement file {refined.path!r} has no refined state at q = {missing[0]:.12g}: "
                                  "refine it first (refine_branch.py -q ...), or scan the unrefined branch wave "
                                  "explicitly with -refined none")
        return fitting, "refined waves"
    kept = [q for q in fitting if refined.has(q)]
    if not kept:
        raise RecordFileError(f"refinement file {refined.path!r} holds none of the branch's wavenumbers on N = {N}")
    if missing:
        return kept, (f"refined waves; restricted to the {len(kept)} refined q in [{min(kept):.4f}, {max(kept):.4f}] "
                      f"({len(missing)} branch q on N = {N} have no refined state)")
    return kept, "refined waves"


class FloquetScan(Study):
    """rho(F_q) along the branch on N beads around the refined waves (section 3.5, figs. floquet, eigen).

    ``method``: 'symmetric' (all 2N multipliers from the wave's cell over its shortest time symmetry,
    :mod:`hertzpetsc.symmetry`; each q on one rank, the q dealt to the ranks), 'dense' (all 2N, LAPACK on the
    assembled F_q, as the paper: the reference route) or 'slepc' (the ``nev`` dominant ones, Krylov-Schur on the
    matrix-free operator, warm-started from the previous q). Prefix ``floquet_`` (its flow ``-floquet_ts_*`` and
    eigensolver ``-floquet_eps_*``). ``output`` None: the records are kept in memory.
    """

    FORMAT, FIELDS, DTYPES, COLUMNS = FLOQUET_FORMAT, FLOQUET_KIND.fields, FLOQUET_KIND.dtypes, FLOQUET_KIND
    ROLES = uses("floquet_")
    WHAT = "Floquet file"

    def __init__(self, branch: Branch, N: int, comm: Optional[PETSc.Comm] = None, output: Optional[str] = None,
                 mode: str = "new", refined: Optional[RefinedStates] = None, qs: Optional[Sequence[float]] = None,
                 method: str = "symmetric", nev: int = 10, tol_rho: float = TOL_RHO,
                 tolerances: IntegrationTolerances = FLOQUET_TOLERANCES) -> None:
        if method not in FLOQUET_ROUTES:
            raise ParameterError("-method", method, "must be one of " + ", ".join(FLOQUET_ROUTES))
        super().__init__(None, comm, output, mode)
        check_instance("branch", branch, Branch, "a Branch (Branch.load(path), hz.compute_branch)")
        _check_scan(refined, tol_rho, tolerances)
        nev = check_integer("nev", nev, 1, "the multipliers of the slepc route")
        self.branch, self.N, self.method, self.nev = branch, N, method, nev
        self.tol_rho, self.tolerances, self.refined = tol_rho, tolerances, refined
        self.spec = ChainSpec(branch.model, N)
        self.qs, self.restriction = _select_wavenumbers(branch, N, qs, refined)
        self.SHAPES = {"multipliers": (2 * N,)}
        self.spectra = {}
        self.solver = floquet_route(method, self.spec, PETSc.COMM_SELF if method == "symmetric" else self.comm, nev,
                                    tolerances, warm=True)

    LABELS = ("note",)

    def constants(self) -> dict:
        return dict(N=self.N, alpha=self.branch.alpha, tol_rho=self.tol_rho, method=self.method,
                    refined_file=_path(self.refined), note=self.restriction)

    def inputs(self) -> dict[str, str]:
        return dict(branch=_path(self.branch), refined=_path(self.refined))

    def orbit(self, q: float) -> Orbit:
        point = self.branch.point(q)
        if self.refined is not None:
            return self.refined.orbit(point, self.spec)
        return orbit_on_chain(point, self.spec)

    def _spectrum(self, q):
        orbit = self.orbit(q)
        t0 = time.perf_counter()
        spec = self.solver.spectrum(orbit, self.tol_rho)
        lam, seconds = spec.multipliers, time.perf_counter() - t0
        return dict(q=q, rho=spec.rho, outside=spec.outside, trivial_spread=spec.trivial_spread,
                    growth=spec.growth(orbit.T), refined=int(orbit.source == "refined"), seconds=seconds,
                    multipliers=np.pad(lam, (0, 2 * self.N - len(lam)), constant_values=np.nan))

    def planned(self) -> int:
        """The wavenumbers not yet in the file."""
        return len(self.open()._todo(self.qs))

    def run(self) -> Iterator[dict]:
        """Compute the spectrum at every q not yet in the file; yields the record after saving it. The symmetric
        route deals the q to the ranks (each on one rank); the others distribute each q over the ranks, in order
        (the SLEPc route starts from the previous q's eigenvectors)."""
        todo = self.open()._todo(self.qs)
        rows = (dealt(todo, [self.orbit(q).symmetry.cost() for q in todo], self.comm, self._spectrum)
                if self.method == "symmetric" else ((q, self._spectrum(q)) for q in todo))
        for _, row in rows:
            yield self.store.append(row)

    def destroy(self) -> None:
        self.solver.destroy()

    def consistency(self, q: float) -> str:
        """rho(Phi_q) of the full-period monodromy against rho(F_q)^(N/m) at q (dense route): text for the table."""
        row = next(r for r in self.store.records if abs(float(r["q"]) - q) <= 1e-12 * q)
        orbit = self.orbit(q)
        tau = orbit.N / orbit.m * orbit.T
        dense = DenseFloquet(self.spec, self.comm, self.tolerances)
        try:
            Phi = dense.monodromy(orbit, shift=False, T=tau)
        finally:
            dense.destroy()
        rho_phi = spectral_radius(dense_multipliers(Phi))
        rho = float(row["rho"])
        return (f"consistency at q = {q:.4f} (m = {orbit.m}): rho(Phi_q) = {rho_phi:.6f} over tau = {tau:.4f}, "
                f"rho(F_q)^(N/m) = {rho ** (orbit.N / orbit.m):.6f}, relative difference "
                f"{abs(rho_phi - rho ** (orbit.N / orbit.m)) / rho_phi:.1e}")

    def table(self, check_q: Optional[float] = None) -> str:
        rows = sorted(self.store.records, key=lambda r: -float(r["q"]))
        q = np.array([float(r["q"]) for r in rows])
        rho = np.array([float(r["rho"]) for r in rows])
        growth = np.array([float(r["growth"]) for r in rows])
        flow = f"rtol {self.tolerances.rtol:g}"
        lines = [f"N = {self.N}, {self.method} route, tight flow ({flow}); rho excludes the 4 trivial multipliers; "
                 f"unstable: rho - 1 > {self.tol_rho:g}. Waves: {self.restriction}.\n",
                 "| q | rho(F_q) | multipliers outside | trivial spread | ln(rho)/script-T | state |",
                 "|---|---|---|---|---|---|"]
        for r in rows:
            # the SLEPc route sees nev multipliers only: when all are outside, more may be; the trivial ones unseen
            outside, spread = int(r["outside"]), float(r["trivial_spread"])
            outside = f">= {outside}" if self.method == "slepc" and outside >= self.nev else str(outside)
            lines.append(FLOQUET_KIND.row(r, "{q}", "{rho}", outside, "n/a" if math.isnan(spread) else f"{spread:.1e}",
                                          "{growth}", "refined" if int(r["refined"]) else "branch"))
        if not len(rows):
            return "\n".join(lines) + "\n"
        # a wave whose trivial multipliers spread by more than tol_rho (an unrefined one) cannot be judged there
        unresolved = np.array([float(r["trivial_spread"]) > self.tol_rho for r in rows])
        if unresolved.any():
            lines.append(f"\nnot judged: q = {', '.join(f'{x:.4f}' for x in q[unresolved])}: the trivial "
                         f"multipliers spread by more than tol_rho = {self.tol_rho:g}, so rho - 1 is not resolved "
                         "there (refine the wave: refine_branch.py)")
            q, rho, growth = q[~unresolved], rho[~unresolved], growth[~unresolved]
            if not len(q):
                return "\n".join(lines) + "\n"
        qc, qc_hi, qm = critical_wavenumbers(q, rho, self.tol_rho)
        span = f" (within the scanned q in [{q.min():.4f}, {q.max():.4f}]" + (", judged" if unresolved.any() else
                                                                             "") + ")"
        if qc == qc and qc_hi is not None:
            lines.append(f"\nq_c in ({qc:.4f}, {qc_hi:.4f}]: largest unstable q = {qc:.4f}, next stable q = "
                         f"{qc_hi:.4f} (rho - 1 jumps from 0 at the threshold, so the bracket is the resolution of "
                         "the q grid)" + span)
        elif qc == qc:
            lines.append(f"\nevery scanned q up to the largest, {q.max():.4f}, is unstable: q_c >= {qc:.4f}" + span)
        else:
            lines.append("\nno scanned q is unstable" + span)
        im = int(np.argmax(rho))
        lines.append(f"q_m (max rho) = {qm:.4f}, rho = {rho[im]:.6f}; max growth per unit time at q = "
                     f"{q[int(np.argmax(growth))]:.4f}")
        if check_q is not None and self.method != "slepc" and np.min(np.abs(q - check_q)) < 1e-9:
            lines.append(self.consistency(float(q[int(np.argmin(np.abs(q - check_q)))])))
        return "\n".join(lines) + "\n"

    def eigen_panels(self, labels: Sequence[tuple[str, float]]) -> list[tuple[str, np.ndarray]]:
        """[(label, multipliers)] of the records at the (label, q) pairs that were scanned (fig. eigen)."""
        return [(label, np.asarray(r["multipliers"])) for label, q in labels for r in self.store.records
                if abs(float(r["q"]) - q) < 1e-9]


def floquet_reference(path, alpha=None, N=None):
    """{round(q, 12): rho} from a Floquet file (either format); a missing or unreadable file is an error naming it
    (a reference that is not there must not become a table of nan), and so is one of another Hertz exponent
    ``alpha`` or chain length ``N`` than the table quotes it for (where the file says)."""
    data = load_npz(path, "Floquet reference file")
    if "format" in data:
        check_kind(data, path, FLOQUET_FORMAT, "Floquet file")
    for name, want in (("alpha", alpha), ("N", N)):
        if want is not None and name in data and abs(float(data[name]) - want) > 1e-12 * max(1.0, abs(want)):
            raise RecordFileError(f"Floquet file {given(path)} is for {name} = {float(data[name]):g}, not {want:g} "
                                  "(the reference must be of the same chain)")
    return {round(float(a), 12): float(b) for a, b in zip(data["q"], data["rho"])}


class BlochScan(Study):
    """All 2N multipliers of F_q on N = L M beads from Bloch sectors of the refined M-bead wave, the residuals of
    the dominant modes on the full chain (matrix-free) and, for N in ``slepc_sizes``, seeded SLEPc (sec. 3.5)."""

    FORMAT, FIELDS, DTYPES, COLUMNS = BLOCH_FORMAT, BLOCH_KIND.fields, BLOCH_KIND.dtypes, BLOCH_KIND
    ROLES = uses("floquet_")
    WHAT, LABELS, ADDED = "Bloch file", ("split", "refined_file"), BLOCH_DETAIL

    def __init__(self, branch: Branch, refined: RefinedStates, sizes: Sequence[int], qs: Sequence[float],
                 comm: Optional[PETSc.Comm] = None, output: Optional[str] = None, mode: str = "new", nev: int = 10,
                 tol_rho: float = TOL_RHO, slepc_sizes: Collection[int] = (), split: str = "sectors",
                 tolerances: IntegrationTolerances = FLOQUET_TOLERANCES,
                 reference: Optional[Mapping[float, float]] = None) -> None:
        super().__init__(None, comm, output, mode)
        check_instance("branch", branch, Branch, "a Branch (Branch.load(path), hz.compute_branch)")
        check_instance("refined", refined, RefinedStates, "a RefinedStates (RefinedStates.load(path))")
        _check_scan(refined, tol_rho, tolerances)
        sizes = check_integers("sizes", sizes, 2, "chain lengths", distinct=True)
        slepc_sizes = check_integers("slepc_sizes", slepc_sizes, 2, "chain lengths", distinct=True, empty=True)
        qs = check_reals("qs", qs, "wavenumbers", 0.0, math.pi, hi_open=False, distinct=True)
        nev = check_integer("nev", nev, 1, "the dominant multipliers")
        check_choice("split", split, ("sectors", "beads"))
        self.branch, self.refined = branch, refined
        self.M = refined.N
        self.cell = ChainSpec(branch.model, self.M)
        for N in sizes:
            if N % self.M:
                raise ParameterError("-sizes", N, f"every chain length must be a multiple of the refined wave's "
                                     f"{self.M} beads (it is tiled)")
        unknown = sorted(set(slepc_sizes) - set(sizes))
        if unknown:
            raise ParameterError("-slepc_sizes", ",".join(map(str, unknown)), "every N must be one of -sizes "
                                 f"({','.join(map(str, sizes))}): SLEPc runs on the chains the scan computes")
        if split not in ("sectors", "beads"):
            raise ParameterError("-split", split, "must be sectors or beads")
        self.solver = SymmetricFloquet(branch.model, self.comm, tolerances, split=split, n_modes=nev)
        self.sizes, self.nev, self.tol_rho, self.split = list(sizes), nev, tol_rho, split
        self.slepc_sizes, self.tolerances, self.reference = set(slepc_sizes), tolerances, reference or {}
        self.orbits = [refined.orbit(branch.point(q), self.cell) for q in qs]
        self.SHAPES = {"dominant": (nev,), "dominant_theta": (nev,)}
        self.extra = {}

    def constants(self) -> dict:
        return dict(alpha=self.branch.alpha, M=self.M, nev=self.nev, tol_rho=self.tol_rho, split=self.split,
                    rtol=self.tolerances.rtol, refined_file=_path(self.refined))

    inputs = FloquetScan.inputs          # the branch and the refinement file

    def run(self) -> Iterator[tuple[dict, dict]]:
        self.open()
        done = {(int(r["N"]), round(float(r["q"]), 12)) for r in self.store.records}
        for N in self.sizes:
            L = N // self.M
            for cell in self.orbits:
                key = (N, round(cell.q, 12))
                if key in done:
                    continue
                t0 = time.perf_counter()
                full = cell.tiled(L)
                b = self.solver.spectrum(full, self.tol_rho)
                t_bloch = time.perf_counter() - t0
                t0 = time.perf_counter()
                res, res_products = bloch_residuals(full, real_pairs(b.modes, b.L), self.comm, self.tolerances)
                t_res = time.perf_counter() - t0
                slepc = None
                if N in self.slepc_sizes:
                    s = seeded_dominant_multipliers(full, b, self.nev, self.comm, self.tolerances)
                    slepc = dict(products=s.work["products"], seconds=s.work["wall_time"],
                                 rho=float(abs(s.multipliers[0])),
                                 dist=max(float(np.min(np.abs(b.multipliers[:self.nev + 2] - v)))
                                          for v in s.multipliers))
                # sector l of the wave's cell (b.M beads) is theta = 2 pi l / b.L per cell, i.e. theta_l per = l / L per
                # refined cell of M beads: the refined cell's own spectrum is that of the sectors periodic over it
                per = self.M // b.M
                cell_sectors = np.isin(b.sector, [l for l in range(b.L) if (l * per) % b.L == 0])
                row = dict(N=N, q=cell.q, rho=b.rho, rho_cell=spectral_radius(b.multipliers[cell_sectors]),
                           outside=b.outside, residual=float(np.max(res)),
                           seconds=t_bloch, slepc_products=slepc["products"] if slepc else -1,
                           slepc_seconds=slepc["seconds"] if slepc else math.nan,
                           dominant=np.array([mu for mu, _, _ in b.modes]),
                           dominant_theta=np.array([(j * per / b.L) % 1.0 for _, j, _ in b.modes]),
                           runs=b.work["runs"], columns=b.work["columns"], propagated=int(bool(b.work["propagated"])),
                           res_products=res_products, res_seconds=t_res,
                           slepc_dist=slepc["dist"] if slepc else math.nan)
                self.extra[key] = dict(m=full.m, L=L, runs=b.work["runs"], columns=b.work["columns"],
                                       res_products=res_products, t_res=t_res, slepc=slepc,
                                       propagated=b.work["propagated"])
                self.store.append(row)
                yield row, self.extra[key]

    def destroy(self) -> None:
        self.solver.destroy()

    def table(self, ranks: int) -> str:
        M = self.M
        lines = [f"Floquet multipliers modulo shifts on N = L x {M} beads (the refined {M}-bead wave tiled), by Bloch "
                 f"sectors theta_j = 2 pi j / L of the {M}-bead cell (hertzpetsc.bloch), {ranks} rank(s), sectors "
                 f"split over ranks ({self.split}); flow rtol {self.tolerances.rtol:g}, atol {self.tolerances.atol:g}."
                 f" rho excludes the 4 trivial multipliers; outside: |lambda| > 1 + {self.tol_rho:g} among all 2N. "
                 f"rho(cell) is sector theta = 0, i.e. the N = {M} chain; rho(N={M} table) is the Floquet scan's "
                 "(rtol 1e-14). Residual: max relative ||F Y - lambda Y|| of the tiled Bloch modes of the dominant "
                 "multipliers on the full chain (matrix-free, 2 shell products per complex pair, all in one "
                 "integration). Bloch 'from 1 x 2M on 3 cells': every sector from the cell propagator "
                 "(hertzpetsc.tangent.CellPropagator). SLEPc: "
                 "Krylov-Schur on the full-chain shell started from those modes (products, time, max distance of "
                 "its multipliers to the Bloch ones).\n",
                 "| N | q | m | rho(F_q) | rho(cell) | rho(N=100 table) | outside | Bloch runs x columns | Bloch time (s) "
                 "| residual (products, s) | SLEPc seeded (products, s, max diff) |",
                 "|---|---|---|---|---|---|---|---|---|---|---|"]
        dominant, older = [], False
        for r in self.store.records:
            N, q = int(r["N"]), float(r["q"])
            L = N // M
            ref = self.reference.get(round(q, 12))
            runs, cols = int(r["runs"]), int(r["columns"])
            if runs < 0:            # a record from before the work was recorded: the sector count, marked *
                older = True
                work = f"{L // 2 + 1} x {2 * M}*"
            elif r["propagated"]:
                work = f"{runs} from 1 x {cols // runs} on 3 cells"
            else:
                work = f"{runs} x {cols // runs}"
            res_detail = f"({int(r['res_products'])}, {float(r['res_seconds']):.1f})" if r["res_products"] >= 0 else "*"
            slepc = "not run"
            if r["slepc_products"] >= 0:
                dist = float(r["slepc_dist"])
                slepc = (f"{int(r['slepc_products'])}, {float(r['slepc_seconds']):.1f}, "
                         + (f"{dist:.1e}" if math.isfinite(dist) else "*"))
            older = older or r["res_products"] < 0 or slepc.endswith("*")
            lines.append(BLOCH_KIND.row(r, "{N}", q_label(q), int(round(N * q / (2 * math.pi))), "{rho}", "{rho_cell}",
                                        f"{ref:.8f}" if ref is not None else "n/a", "{outside}", work, "{seconds}",
                                        "{residual} " + res_detail, slepc))
            dom = ", ".join(f"{abs(v):.6f} @ {np.angle(v) / math.pi:+.4f} [{t:.3f}]"
                            for v, t in zip(r["dominant"], r["dominant_theta"]))
            dominant.append(f"- N = {N}, q = {q_label(q)}: {dom}")
        if older:
            lines.append("\n* not recorded in this file (written before they were): Bloch work is L//2 + 1 sectors "
                         "x 2M columns, the residual's products and time and SLEPc's max diff are not known.")
        lines.append(f"\nThe {self.nev} dominant multipliers (|lambda|, arg lambda / pi, theta / 2 pi):\n")
        return "\n".join(lines + dominant) + "\n"
