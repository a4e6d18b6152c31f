"""Slow instabilities above q_c on the infinite chain (the paper's closing question, section 3.5 and Discussion): the
largest growth rate gamma(q) = max ln|mu| / script-T over all Bloch parameters, by two independent routes.

* co-moving route (:mod:`hertzpetsc.comoving`, :mod:`~hertzpetsc.comoving_window`, no time integration): the QEP of
  the linearisation in the wave's frame on h = pi/K, theta in [0, pi] on a grid, the compacton band (mu = 1, split
  at O(h) by the scheme) identified by its known location and excluded; the worst mode tracked on 2K and 4K
  (Richardson, order 2);
* monodromy route (:mod:`hertzpetsc.slow`): the wave refined on its cell over its short time symmetry with tight
  flows, the cell's map at twists Theta in [0, pi], the symmetry multipliers (every zone's translation, and at
  Theta = 0 the uniform translation, each with its Jordan partner) deflated exactly.

A wave is *slowly unstable* when the co-moving route's gamma exceeds the target resolution on every grid and
converges (the last two grids agree to 10%): gamma is then the Richardson value. It is *stable within resolution*
when no route measured a gamma above the target, the resolution being the largest gamma either route measured;
and *unresolved* when some gamma exceeds the target but the grids do not agree (finer grids are needed: no bound is
claimed). Grids coarser than :data:`CELLS_PER_Q` cells per q are refused (they cannot resolve the compression
zone) (the co-moving values are rounding of
eigenvalues that the scheme keeps on the axis exactly, lambda -> -conj(lambda); the monodromy values are the
flow's and the orbit's error after deflation). The long-wave end: the largest Re lambda / theta of the eigenvalues
near 0 at a small theta, against the 2x2 Whitham prediction from omega(q, A) (:func:`whitham_slope`).

The record file (npz, record store ``hertzpetsc-slow-1``): one record per q, its columns declared in
:data:`SLOW_KIND`.
"""
from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Callable, Iterator, Mapping, Optional, Sequence

import numpy as np
from petsc4py import PETSc

from ..comoving import ComovingWave, profile_on_grid
from ..comoving_pep import ComovingPEP
from ..comoving_window import sector_window, theta_scan, tracked_exponent
from ..branch import Branch
from ..dealing import dealt
from ..errors import (ConvergenceError, ParameterError, check_instance, check_integer, check_integers, check_real,
                      check_reals)
from ..chain import IntegrationTolerances
from ..model import ChainSpec
from ..records import OPTIONS_COLUMN, Column, Kind, digest_column
from ..resources import check_memory
from ..richardson import richardson
from ..roles import uses
from ..shooting import SHOOT_PREFIX, Refiner, relative_residual
from ..slow import DeflatedSectors
from ..stencil import full_period
from ..symmetry import WaveSymmetry
from ..waves import fits_chain, orbit_on_chain
from .base import Study
from .floquet import _path, q_label

if TYPE_CHECKING:
    from ..branch import Branch, BranchPoint
    from ..waves import Orbit
    from .refinement import RefinedStates

SLOW_FORMAT = "hertzpetsc-slow-1"
TARGET = 1e-9                       # the resolution asked for, per unit time
SLOW_KIND = Kind(SLOW_FORMAT, (
    Column("alpha", "Hertz exponent", constant=True),
    Column("N", "beads of the chain of the monodromy route", "count", np.int64, "d", constant=True),
    Column("branch", "the branch file (a label)", "", str, "s", constant=True),
    Column("grids", "the co-moving route's grids K (h = pi/K), usually 3", "count", np.int64, "d", "G",
           constant=True),
    Column("n_theta", "Bloch parameters theta in [0, pi] of the co-moving route", "count", np.int64, "d",
           constant=True),
    Column("n_twist", "cell twists of the monodromy route (0: not run)", "count", np.int64, "d", constant=True),
    Column("refine_tol", "target E of the refinement", constant=True),
    Column("rtol", "flow tolerance", constant=True),
    Column("target", "the resolution aimed at (per unit time)", constant=True),
    Column("theta_longwave", "the small theta of the long-wave slope", constant=True),
    digest_column("branch", "branch file"),
    digest_column("refined", "refinement file", "when there is one"),
    OPTIONS_COLUMN,
    Column("q", "wavenumber"),
    Column("m", "wavelengths on N beads (-1: not a chain wavenumber, co-moving route only)", "count", np.int64, "d"),
    Column("T", "script-T (eq. invv)"),
    Column("theta_cm", "theta in [0, pi] of the co-moving route's worst non-band mode (on grids[0])", format=".3f"),
    Column("gamma_cm", "its gamma = q Re lambda / script-T on each grid", shape="G", format=".1e"),
    Column("gamma_cm_extrapolated", "Richardson value (order 2) from the last three grids", format=".2g"),
    Column("order_cm", "the observed order of the last three grids"),
    Column("band_cm", "\\|mu\\| - 1 of the scheme's split compacton band on grids[0] (the O(h) artefact, excluded)",
           format=".1e"),
    Column("separation_cm", "smallest distance from lambda_b to a non-band eigenvalue over theta"),
    Column("twist_mono", "the cell twist Theta of the monodromy route's worst deflated multiplier (nan: not run)"),
    Column("gamma_mono", "ln(max \\|mu\\| outside the symmetry cluster) / script-T", format=".1e"),
    Column("raw_cluster_mono", "max \\|mu\\| - 1 of the symmetry cluster without deflation (the perturbed Jordan "
           "blocks)", format=".1e"),
    Column("cluster_mono", "max \\|mu - 1\\| of the deflated cluster (exactly 0 for an exact orbit)", format=".1e"),
    Column("eigvec_mono", "max relative residual \\|\\|(P - I) z\\|\\| of the known eigenvectors", format=".1e"),
    Column("invariance_mono", "relative residual of the deflated subspace's invariance"),
    Column("E_orbit", "E(q) of the orbit after refinement (N beads over script-T)", format=".1e"),
    Column("E_short", "E(q) of the orbit after refinement on the cell's short map", format=".1e"),
    Column("slope_cm", "largest Re lambda / theta near lambda = 0 at theta_longwave (on grids[1])", format=".1e"),
    Column("slope_whitham", "\\|Im c\\| of the 2x2 Whitham characteristic speeds (nan: not computable)",
           format=".2f"),
    Column("resolution", "the bound per unit time: the largest gamma either route measured", format=".1e"),
    Column("verdict", "1 = slowly unstable, 0 = stable within `resolution`, 2 = unresolved (a gamma above the "
           "target on grids that do not agree)", "", np.int64, "d"),
    Column("seconds", "wall time of the point", "s", format=".1f"),
))
SLOW_FIELDS = SLOW_KIND.fields
MONO_FIELDS = SLOW_FIELDS[SLOW_FIELDS.index("twist_mono"):SLOW_FIELDS.index("slope_cm")]   # nan where not run
# the flow of the refinement and of the sector maps: as tight as rk 8vr allows in double precision
SLOW_TOLERANCES = IntegrationTolerances(rtol=1e-14, atol=1e-16)


def tracked_on_grids(point, grids, scan, solver, comm=PETSc.COMM_SELF):
    """The worst mode of a :func:`~hertzpetsc.comoving_window.theta_scan` followed onto the finer ``grids`` (each from
    the previous grid's exponent, :func:`~hertzpetsc.comoving_window.tracked_exponent`): [(wave, lambda)] per grid."""
    out, lam = [], scan.lam
    for K in grids:
        wave = ComovingWave.from_point(point, K, comm)
        lam = tracked_exponent(wave, scan.theta, lam, solver)
        out.append((wave, lam))
    return out


def mean_kinetic(u_half, h):
    """I = <u'^2>/2 over the period of an odd profile on [0, pi] (centred differences)."""
    u = full_period(u_half)
    du = (np.roll(u, -1) - np.roll(u, 1)) / (2 * h)
    return 0.5 * float(np.mean(du ** 2))


def whitham_slope(point, comm, rel_step=0.01):
    """|Im c| of the 2x2 Whitham system built from omega(q, A) alone (no mean flow): for x = a u(q n - omega t)
    the averaged Lagrangian is L = (alpha - 1)/(alpha + 1) omega^beta I(q), beta = 2 (alpha + 1)/(alpha - 1),
    I = <u'^2>/2 of the omega = 1 profile (eq. ad), and k_t + omega_n = 0, (L_omega)_t - (L_k)_n = 0 give
    beta (beta - 1) I c^2 + 2 beta I' c + I'' = 0 at omega = 1. Complex c (an elliptic system) predicts
    modulational instability with Re lambda = |Im c| theta as theta -> 0; 0 when c is real.
    I' and I'' by 5-point differences of profiles solved (SNES ``tw_``) at q (1 + k rel_step), k = -2..2, on the
    branch grid: the discriminant is a difference of nearly equal terms (I ~ q^-8 near q = 0 makes it
    (6400 - 6480) I^2 / q^2 at alpha = 3/2), so the 3-point differences of the branch's own q spacing are too coarse."""
    K = len(point.u_half) - 1
    dq = rel_step * point.q
    I = [mean_kinetic(point.u_half if k == 0 else profile_on_grid(point, K, comm, q=point.q + k * dq), point.h)
         for k in (-2, -1, 0, 1, 2)]
    d1 = (I[0] - 8 * I[1] + 8 * I[3] - I[4]) / (12 * dq)
    d2 = (-I[0] + 16 * I[1] - 30 * I[2] + 16 * I[3] - I[4]) / (12 * dq ** 2)
    alpha = point.model.alpha
    beta = 2 * (alpha + 1) / (alpha - 1)
    disc = beta ** 2 * d1 ** 2 - beta * (beta - 1) * I[2] * d2
    return math.sqrt(-disc) / (beta * (beta - 1) * I[2]) if disc < 0 else 0.0


def monodromy_fields(sectors, refiner, orbit, E):
    """The mono fields of a record: the deflated sectors (:class:`~hertzpetsc.slow.DeflatedSectors`) of ``orbit``,
    its E over script-T and the E of its cell's short map (the ``refiner``'s flow)."""
    best, raw, clus, eig, inv = None, 0.0, 0.0, 0.0, 0.0
    for s in sectors.spectrum(orbit).work["sectors"]:
        g = math.log(s.rho) / orbit.T
        if best is None or g > best[0]:
            best = (g, s.theta)
        if s.r:
            raw = max(raw, float(np.max(np.abs(s.raw_cluster))) - 1)
            clus = max(clus, float(np.max(np.abs(s.cluster - 1))))
        eig, inv = max(eig, s.eigenvector_residual), max(inv, s.invariance_residual)
    sym = orbit.symmetry
    x0 = orbit.x[:sym.M]
    return dict(twist_mono=best[1], gamma_mono=best[0], raw_cluster_mono=raw, cluster_mono=clus, eigvec_mono=eig,
                invariance_mono=inv, E_orbit=E, E_short=relative_residual(x0, refiner.shift_map(sym.M)(
                    x0, sym.delta(orbit.T), sym.k)))


# cells per unit of q on the coarsest co-moving grid: the compression zone, about 4 q long (N(q) <= 5 beads),
# then holds about 80 grid cells; coarser grids cannot resolve the growth they would be asked to bound
CELLS_PER_Q = 20


# Generous caps on the scans' counts (each theta is a quadratic eigenproblem on the grid, each twist a sector's
# monodromy on the wave's cell): beyond them a run takes days.
MAX_THETAS = 10000
MAX_TWISTS = 1000

class SlowInstabilityScan(Study):
    """gamma(q) above q_c by the co-moving and the monodromy routes (module docstring), written as it goes.

    ``qs``: branch wavenumbers; those fitting N beads (q = 2 pi m / N) get the monodromy route too (refined from the
    states of ``refined`` when given, else from the branch wave). ``grids``: K of the co-moving grids (at least 3,
    doubling); ``n_theta``: Bloch parameters of the co-moving scan in [0, pi]; ``n_twist``: cell twists of the
    monodromy route in [0, pi] (0 disables it). Prefixes: ``cm_`` (the PEP), ``tw_`` (profiles on the finer grids),
    ``shoot_`` / ``shoot_jac_`` (the refinement), ``floquet_`` (the sector maps). Each q is computed on one rank,
    the q dealt to the ranks. ``output`` None: the records are kept in memory.
    """

    FORMAT, FIELDS, DTYPES, COLUMNS = SLOW_FORMAT, SLOW_FIELDS, SLOW_KIND.dtypes, SLOW_KIND
    ROLES = uses("cm_", "tw_", "shoot_", "shoot_jac_", floquet_=("ts",))
    WHAT, LABELS = "slow-instability file", ("branch",)

    def __init__(self, branch: Branch, branch_path: str, N: int, comm: Optional[PETSc.Comm] = None,
                 output: Optional[str] = None, mode: str = "new", qs: Optional[Sequence[float]] = None,
                 refined: Optional[RefinedStates] = None, grids: Sequence[int] = (1000, 2000, 4000),
                 n_theta: int = 41, n_twist: int = 3, refine_tol: float = 1e-12,
                 tolerances: IntegrationTolerances = SLOW_TOLERANCES, target: float = TARGET,
                 theta_longwave: float = 0.05) -> None:
        grids = check_integers("grids", grids, 4, "grids K (h = pi/K)", distinct=True)
        n_theta = check_integer("n_theta", n_theta, 2, "the Bloch parameters of the co-moving scan", MAX_THETAS)
        n_twist = check_integer("n_twist", n_twist, 0, "the cell twists of the monodromy route", MAX_TWISTS)
        check_instance("branch_path", branch_path, str, "the branch file's path (a label)")
        theta_longwave = check_real("theta_longwave", theta_longwave, "the long-wave Bloch parameter", 0.0, 0.5)
        refine_tol = check_real("refine_tol", refine_tol, "the refinement's target E", 0.0, 1.0)
        check_instance("tolerances", tolerances, IntegrationTolerances, "an IntegrationTolerances(rtol, atol)")
        target = check_real("target", target, "the PEP's target")
        if refined is not None:
            from .refinement import RefinedStates
            check_instance("refined", refined, RefinedStates, "a RefinedStates (RefinedStates.load(path)) or None")
        check_instance("branch", branch, Branch, "a Branch (Branch.load(path), hz.compute_branch)")
        check_integer("N", N, 2, "the beads of the periodic chain")
        qs = None if qs is None else check_reals("qs", qs, "wavenumbers", 0.0, math.pi, hi_open=False, distinct=True,
                                                 empty=True)
        if len(grids) < 3 or any(b != 2 * a for a, b in zip(grids, grids[1:])):
            raise ParameterError("-grids", ",".join(map(str, grids)), "must be at least 3 grids K, each twice the "
                                 "previous (Richardson of order 2)")
        if n_theta < 2:
            raise ParameterError("-n_theta", n_theta, "must be an integer >= 2 (theta = 0 and pi at least)")
        if n_twist < 0:
            raise ParameterError("-n_twist", n_twist, "must be an integer >= 0 (0: no monodromy route)")
        if not 0 < theta_longwave < 0.5:
            raise ParameterError("-theta_longwave", theta_longwave, "must lie in (0, 0.5)")
        super().__init__(None, comm, output, mode)
        self.branch, self.branch_path, self.N, self.refined = branch, branch_path, N, refined
        self.grids, self.n_theta, self.n_twist = list(grids), n_theta, n_twist
        self.refine_tol, self.tolerances, self.target = refine_tol, tolerances, target
        self.theta_longwave = theta_longwave
        self.qs = [branch.point(q).q for q in (qs if qs else branch.q)]
        coarse = [q for q in self.qs if q * grids[0] / math.pi < CELLS_PER_Q * (1 - 1e-12)]
        if coarse:
            q0 = coarse[0]
            raise ParameterError("-grids", ",".join(map(str, grids)), "the coarsest grid has "
                                 f"{q0 * grids[0] / math.pi:.3g} cells per q at q = {q0:.6g}: at least {CELLS_PER_Q} are needed (K >= "
                                 f"{math.ceil(CELLS_PER_Q * math.pi / q0)}) to resolve the compression zone")
        check_memory(grids[-1], self.comm, "direct", name="grids")        # the finest co-moving grid's solves
        self.spec = ChainSpec(branch.model, N)
        self.pep = ComovingPEP(PETSc.COMM_SELF)
        self.sectors = (DeflatedSectors(branch.model, PETSc.COMM_SELF, tolerances,
                                        twists=np.linspace(0.0, math.pi, n_twist)) if n_twist else None)
        # the study's own fallback where E stalls above refine_tol (refine): not the refiner's floor acceptance
        self.refiner = (Refiner(self.spec, PETSc.COMM_SELF, refine_tol, tolerances=tolerances, prefix=SHOOT_PREFIX,
                                symmetric=True, accept_floor=False) if n_twist else None)
        self.SHAPES = {"gamma_cm": (len(grids),)}

    def constants(self) -> dict:
        return dict(alpha=self.branch.alpha, N=self.N, branch=self.branch_path, grids=list(self.grids),
                    n_theta=self.n_theta, n_twist=self.n_twist, refine_tol=self.refine_tol,
                    rtol=self.tolerances.rtol, target=self.target, theta_longwave=self.theta_longwave)

    def inputs(self) -> dict[str, str]:
        return dict(branch=self.branch_path, refined=_path(self.refined))

    # --- the two routes ---------------------------------------------------------------------------------------
    def comoving(self, point: BranchPoint) -> dict:
        """The co-moving route at one branch point: dict of the cm fields."""
        wave = ComovingWave.from_point(point, self.grids[0], PETSc.COMM_SELF)
        scan = theta_scan(wave, np.linspace(0.0, math.pi, self.n_theta), self.pep)
        finer = tracked_on_grids(point, self.grids[1:], scan, self.pep)
        gammas = [scan.gamma] + [float(w.growth(lam)) for w, lam in finer]
        lw = sector_window(finer[0][0], self.theta_longwave, self.pep, box=(-0.05, 0.05))
        near = (np.abs(lw.lam) <= 1.5 * self.theta_longwave / point.q) & ~lw.band
        slope = float(np.max(lw.lam.real[near]) / self.theta_longwave) if near.any() else math.nan
        return dict(T=wave.T, theta_cm=scan.theta, gamma_cm=np.array(gammas),
                    gamma_cm_extrapolated=richardson(gammas, 2.0, 2)[1], order_cm=richardson(gammas, 2.0)[0],
                    band_cm=scan.band_mu, separation_cm=scan.min_separation, slope_cm=slope)

    def refine(self, point: BranchPoint) -> tuple[Orbit, float]:
        """The wave on N beads refined on its cell with the tight flow: (orbit, E over script-T). Starts from the
        refinement file's state when it has this q. E stalls above refine_tol at the flow's floor (e.g. long
        cells): then within 10 refine_tol, else the starting state as it is (E_orbit and E_short say what the
        deflation worked with)."""
        orbit = (self.refined.orbit(point, self.spec) if self.refined is not None and self.refined.has(point.q)
                 else orbit_on_chain(point, self.spec))
        for tol in (self.refine_tol, 10 * self.refine_tol):
            self.refiner.tol = tol
            try:
                res = self.refiner.refine(orbit)
                return res.orbit, res.E
            except ConvergenceError:
                pass
            finally:
                self.refiner.tol = self.refine_tol
        return orbit, self.refiner.residual(orbit)

    def verdict(self, row: Mapping) -> tuple[float, int]:
        """(resolution, verdict): slowly unstable (1) when the co-moving gamma exceeds the target on every grid
        and the last two agree to 10% (gamma = the Richardson value); stable within the largest gamma measured (0)
        when that is below the target; else unresolved (2): the resolution shown is not below what it would
        bound."""
        g = np.asarray(row["gamma_cm"], dtype=float)
        if np.all(g > self.target) and abs(g[-1] - g[-2]) <= 0.1 * g[-1]:
            return abs(g[-1] - g[-2]) / 3, 1
        measured = [float(np.max(np.abs(g)))]
        if row["gamma_mono"] == row["gamma_mono"]:
            measured.append(abs(float(row["gamma_mono"])))
        return max(measured), 0 if max(measured) <= self.target else 2

    def point(self, q: float) -> dict:
        t0 = time.perf_counter()
        point = self.branch.point(q)
        row = dict(q=q, m=-1, **self.comoving(point), **dict.fromkeys(MONO_FIELDS, math.nan))
        if self.n_twist and fits_chain(q, self.N):
            row["m"] = int(round(q * self.N / (2 * math.pi)))
            row.update(monodromy_fields(self.sectors, self.refiner, *self.refine(point)))     # the monodromy route
        row["slope_whitham"] = whitham_slope(point, PETSc.COMM_SELF) if q < math.pi * (1 - 1e-9) else math.nan
        row["resolution"], row["verdict"] = self.verdict(row)
        row["seconds"] = time.perf_counter() - t0
        return row

    def run(self) -> Iterator[dict]:
        """Compute every q not yet in the file; yields each record after saving it."""
        todo = self.open()._todo(self.qs)
        costs = [1.0 + (WaveSymmetry(self.N, int(round(q * self.N / (2 * math.pi)))).cost() * 50
                        if self.n_twist and fits_chain(q, self.N) else 0.0) for q in todo]
        for q, row in dealt(todo, costs, self.comm, self.point):
            yield self.store.append(row)

    def destroy(self) -> None:
        if self.sectors is not None:
            self.sectors.destroy()
        if self.refiner is not None:
            self.refiner.destroy()

    # --- the table --------------------------------------------------------------------------------------------
    def table(self) -> str:
        rows = sorted(self.store.records, key=lambda r: float(r["q"]))
        K = self.grids
        lines = [f"alpha = {self.branch.alpha}; gamma = max ln|mu| / script-T over the infinite chain (per unit time "
                 f"of the normalised wave); target resolution {self.target:g}. Co-moving route: z-form QEP, "
                 f"cell-averaged V'', {self.n_theta} theta in [0, pi] on K = {K[0]}, the worst mode tracked on K = "
                 f"{', '.join(map(str, K[1:]))} (h = pi/K); band: |mu| - 1 of the scheme's O(h) split of the exact "
                 f"compacton band (excluded). Monodromy route (m on N = {self.N}): symmetric refinement to E <= "
                 f"{self.refine_tol:g} (flow rtol {self.tolerances.rtol:g}), {self.n_twist} cell twists in [0, pi], "
                 "symmetry multipliers deflated (zone translations + Jordan partners; translation + boost at "
                 "Theta = 0); raw cluster: |mu| - 1 of that group undeflated.\n",
                 "| q | m | theta (cm) | gamma cm, K = " + " / ".join(map(str, K)) + " | gamma mono | raw cluster "
                 "|mu|-1 | deflated cluster |mu-1| | eigvec res. | E (script-T / short map) | band (cm) | slope cm / "
                 "Whitham | resolution | verdict |",
                 "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in rows:
            m = int(r["m"])
            g = " / ".join(f"{v:.1e}" for v in np.asarray(r["gamma_cm"]))
            mono = ["{gamma_mono}", "{raw_cluster_mono}", "{cluster_mono}", "{eigvec_mono}", "{E_orbit} / {E_short}"] \
                if m > 0 else ["n/a"] * 5
            verdict = {1: f"slowly unstable, gamma = {r['gamma_cm_extrapolated']:.2g}", 0: "stable within resolution",
                       2: "unresolved (refine the grids)"}[int(r["verdict"])]
            lines.append(SLOW_KIND.row(r, f"{q_label(float(r['q']))} ({r['q']:.4f})", m if m > 0 else "-",
                                       "{theta_cm}", g, *mono, "{band_cm}", "{slope_cm} / {slope_whitham}",
                                       "{resolution}", verdict))
        return "\n".join(lines) + "\n"


def validation_grids(q, cells_per_q=40, base=1000):
    """Three doubling grids starting at the smallest base * 2^k with at least ``cells_per_q`` cells per q (fewer cells
    per q leave a Richardson remainder of the order of the validation's tolerance; see the results file)."""
    K = base
    while q * K / math.pi < cells_per_q:
        K *= 2
    return [K, 2 * K, 4 * K]


def comoving_validation(branch, qs, N, reference, comm=PETSc.COMM_SELF):
    """The co-moving route where the answer is known: for q = 2 pi m / N with a reference rho(F_q) (the Floquet
    scan's, ``reference`` = {round(q, 12): rho}), the largest |mu| over theta_j = 2 pi j / N (j = 0 .. N/2) on the
    first grid of :func:`validation_grids`, tracked on the two finer ones, Richardson (order 2). Rows of dicts."""
    pep = ComovingPEP(comm)
    rows = []
    for q in qs:
        point = branch.point(q)
        grids = validation_grids(point.q)
        wave = ComovingWave.from_point(point, grids[0], comm)
        scan = theta_scan(wave, [2 * math.pi * j / N for j in range(N // 2 + 1)], pep)
        if scan.lam != scan.lam:
            raise ParameterError("-validate", q, "has no mode outside the compacton band: validate at unstable q")
        mus = [abs(wave.multiplier(scan.lam, scan.theta))] + [abs(w.multiplier(lam, scan.theta)) for w, lam in
                                                              tracked_on_grids(point, grids[1:], scan, pep, comm)]
        mu = richardson(mus, 2.0, 2)[1]
        ref = reference.get(round(point.q, 12), math.nan)
        rows.append(dict(q=point.q, theta=scan.theta, grids=grids, mus=mus, order=richardson(mus, 2.0)[0], mu=mu,
                         reference=ref, difference=mu - ref))
    return rows


def validation_table(rows, N):
    lines = [f"Validation of the co-moving route against rho(F_q) of the Floquet scan on N = {N} beads (refined "
             f"waves, symmetric route): largest |mu| over theta_j = 2 pi j / {N}, three grids with >= 40 cells per q, "
             "Richardson of order 2.\n",
             "| q | theta / pi | grids K | \\|mu\\| on the grids | observed order | extrapolated | rho(F_q) "
             "reference | difference |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {q_label(r['q'])} | {r['theta'] / math.pi:.3f} | {', '.join(map(str, r['grids']))} | "
                     f"{', '.join(f'{m:.10f}' for m in r['mus'])} | {r['order']:.2f} | {r['mu']:.10f} | "
                     f"{r['reference']:.10f} | {r['difference']:+.1e} |")
    return "\n".join(lines) + "\n"


def orbit_convergence(branch, qs, N, refined, settings, comm=PETSc.COMM_SELF, n_twist=3):
    """How the monodromy route's numbers move with the orbit's residual and the flow's tolerance: for each q (a
    chain wavenumber) and each (label, refine_tol or None, rtol) of ``settings`` (None: the state as given, the
    refinement file's or the branch wave, no refinement), E over script-T and over the short map, the undeflated
    cluster's max |mu| - 1, the deflated gamma and the known eigenvectors' residual (max over ``n_twist`` twists).
    A true instability stays when E and rtol shrink; an artefact shrinks with them."""
    spec = ChainSpec(branch.model, N)
    rows = []
    for q in qs:
        point = branch.point(q)
        start = refined.orbit(point, spec) if refined is not None and refined.has(point.q) else \
            orbit_on_chain(point, spec)
        for label, tol, rtol in settings:
            tolerances = IntegrationTolerances(rtol=rtol, atol=rtol / 100)
            refiner = Refiner(spec, comm, tol if tol else 1.0, tolerances=tolerances, prefix=SHOOT_PREFIX,
                              symmetric=True)
            sectors = DeflatedSectors(branch.model, comm, tolerances, twists=np.linspace(0.0, math.pi, n_twist))
            try:
                orbit = refiner.refine(start).orbit if tol else start
                f = monodromy_fields(sectors, refiner, orbit, refiner.residual(orbit))
            finally:
                refiner.destroy()
                sectors.destroy()
            rows.append(dict(q=point.q, m=orbit.m, label=label, rtol=rtol, E=f["E_orbit"], E_short=f["E_short"],
                             raw=f["raw_cluster_mono"], gamma=f["gamma_mono"], eig=f["eigvec_mono"]))
    return rows


def convergence_table(rows):
    lines = ["Monodromy route against the orbit's residual and the flow's tolerance (max over the cell twists): E over "
             "script-T on the N beads and over the cell's short map (same flow), the undeflated symmetry cluster, "
             "the deflated growth rate, the residual of the known eigenvectors.\n",
             "| q | m | orbit | flow rtol | E (script-T) | E (short map) | raw cluster \\|mu\\| - 1 | "
             "sqrt(E short) | gamma deflated | eigenvector residual |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {q_label(r['q'])} | {r['m']} | {r['label']} | {r['rtol']:g} | {r['E']:.1e} | "
                     f"{r['E_short']:.1e} | {r['raw']:.1e} | {math.sqrt(r['E_short']):.1e} | {r['gamma']:.1e} | "
                     f"{r['eig']:.1e} |")
    return "\n".join(lines) + "\n"


# --- the scan with the checks appended to its table, as scripts/slow_instabilities.py runs it -------------------------
class SlowInstabilities:
    """The driver's run: the :class:`SlowInstabilityScan` of ``qs`` (empty: every branch q >= ``q_min``), then on
    rank 0 the monodromy route against the orbit's residual and the flow's tolerance at the chain wavenumbers
    ``convergence`` (:func:`orbit_convergence`, when ``n_twist``; the state as given, refined to 100 refine_tol at
    rtol 1e-12, and to refine_tol at ``rtol``) and the co-moving route against rho(F_q) of the Floquet file
    ``reference`` at ``validate`` (:func:`comoving_validation`; 'none': not run), both appended to the scan's table.
    The inputs are read and checked when it is built (``refined``: a refinement file or 'none'), before any
    computation; the other parameters are the scan's."""

    def __init__(self, branch: Branch, branch_path: str, N: int, comm: PETSc.Comm, output: Optional[str],
                 mode: str, qs: Sequence[float], q_min: float, refined: str, convergence: Sequence[float],
                 validate: Sequence[float], reference: str, refine_tol: float = 1e-12, rtol: float = 1e-14,
                 n_twist: int = 3, grids: Sequence[int] = (1000, 2000, 4000), n_theta: int = 41,
                 target: float = TARGET, theta_longwave: float = 0.05) -> None:
        from ..records import on_rank0
        from .floquet import floquet_reference
        from .refinement import RefinedStates
        if not qs:
            qs = [q for q in branch.q if q >= q_min * (1 - 1e-12)]
            if not qs:
                raise ParameterError("-q_min", q_min, f"must not exceed the branch's largest q = {max(branch.q):.6g}")
        for q in convergence if n_twist else ():
            if not fits_chain(q, N):
                raise ParameterError("-convergence_q", q, f"must list chain wavenumbers 2 pi m / N, N = {N}")
        self.refined = None if refined == "none" else RefinedStates.load(refined, comm)
        # the validation's reference is read now: a missing one is an error before any computation, not a table of nan
        self.reference_rho = (on_rank0(comm, floquet_reference, reference, branch.alpha, N, what="cannot read "
                                       "-reference") if validate and reference != "none" else None)
        self.branch, self.N, self.comm = branch, N, comm
        self.convergence = list(convergence) if n_twist else []
        self.validate = list(validate) if reference != "none" else []
        self.settings = [("as given", None, 1e-14), ("refined", refine_tol * 100, 1e-12), ("refined", refine_tol, rtol)]
        self.n_twist = n_twist
        self.scan = SlowInstabilityScan(branch, branch_path, N, comm, output, mode, qs, self.refined,
                                        refine_tol=refine_tol, tolerances=IntegrationTolerances(rtol=rtol,
                                                                                                atol=rtol / 100),
                                        n_twist=n_twist, grids=grids, n_theta=n_theta, target=target,
                                        theta_longwave=theta_longwave)

    def run_to_table(self, path: str, show: Optional[Callable[[dict], None]] = None) -> str:
        """The scan (:func:`~hertzpetsc.studies.base.run_to_table`), its solvers freed, then the appended checks;
        the table written to ``path`` and returned. Collective."""
        from ..console import print0
        from ..records import on_rank0, write_text
        text = self.scan.run_to_table(path, show)        # on a stop: the table of the records done
        self.scan.destroy()
        if self.convergence:
            print0("# orbit residual and flow tolerance at q = " + ", ".join(f"{q:.5f}" for q in self.convergence))
            rows = on_rank0(self.comm, orbit_convergence, self.branch, self.convergence, self.N, self.refined,
                            self.settings, PETSc.COMM_SELF, self.n_twist, what="orbit convergence")
            text += "\n" + convergence_table(rows)
        if self.validate:
            print0("# validation of the co-moving route at q = " + ", ".join(f"{q:.5f}" for q in self.validate))
            rows = on_rank0(self.comm, comoving_validation, self.branch, self.validate, self.N, self.reference_rho,
                            what="co-moving validation")
            text += "\n" + validation_table(rows, self.N)
        if self.convergence or self.validate:
            write_text(path, text, self.comm)
        return text
