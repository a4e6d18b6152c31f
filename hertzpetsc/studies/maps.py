"""Stability maps of precompressed chains and dimers in the (q, A) plane, with the stability boundary located
(issue 23; section 3.5 beyond the paper).

For each wavenumber q = 2 pi m / N the amplitude family (:class:`~hertzpetsc.families.AmplitudeFamily`, natural
steps in s = log a through the map's amplitudes, prefix ``precomp_``) carries two test functions of the continuation
layer, each the margin ln(rho) - ln(1 + tol_rho) of a verdict:

* ``chain``: rho of all 2N multipliers of F_q on the periodic chain of N beads, from the sectors of the wave's cell
  with the symmetry multipliers deflated by their known eigenvectors (:class:`~hertzpetsc.slow.DeflatedSectors`:
  time shift and translation with their Jordan partners at the cell twist 0, every zone's translation at every twist
  when the zones are decoupled), so that no verdict rests on the numerical splitting of the trivial group; where a
  multiplier that the deflation leaves lies within :data:`NEAR_ONE` of 1 (a nearly defective pair: the translations
  of zones that a contact still joins, just past the gap opening), on the orbit refined on the chain by Gauss-Newton
  and the cells' flow at a hundredth of its tolerances (such a pair moves as the square root of the orbit's and the
  flow's errors);
* ``infinite``: rho over every Bloch parameter of the infinite chain: the cell twists Theta in [0, pi] of the wave's
  cell of M beads (:func:`~hertzpetsc.slow.twist_scan`: a grid of ceil(twists / M) steps, i.e. a bead-level Bloch
  step of at most pi / twists, the largest local maxima refined by golden section, and the twists where an unstable
  mode was last seen: a band of instability narrows to a point at its onset, and is followed there). A stable
  verdict is certified between the samples (:func:`~hertzpetsc.slow.certify_twists`: no band with rho - 1 above
  0.1 tol_rho between them, for modulations up to :func:`longest_modulation` beads) or recorded as unresolved.

Where a verdict changes between two amplitudes of the map, the layer locates the root by bisection in s until the
bracket is at most ``locate_tol`` / 2 long (:class:`~hertzpetsc.continuation.Continuation`, ``bisect``): the located
point's record keeps both ends with their rho - 1, so the boundary is confirmed by the multipliers on both sides. The
gap opening (2 u(q/2) = delta0 for a monatomic chain) is located on the way. Each wave is the Richardson combination
of the h = pi/K wave of the family, solved again from itself (a warm-started corrector stops far above the grid's
floor: :class:`RichardsonCompanion`), and the h = pi/(2K) one solved at the same amplitude from it (initial data with
an O(h^4) error): a wave does not depend on the path by which the family reached it. The uncompressed limit
(delta0 / A = 0) closes each q. The q are dealt to the ranks, each computed on one rank
(:mod:`hertzpetsc.studies.dealing`): the records do not depend on the number of ranks.

Record file (npz, record store, kind ``hertzpetsc-precompression-map-3``; its constants and fields :data:`MAP_FIELDS`
in docs/schemas.md); a record's kind: 0 a point of the map, 1 a located boundary point on N beads, 2 on the infinite
chain, 3 the uncompressed limit, 4 the gap opening, 5 a Krein crossing. Files of kind
``hertzpetsc-precompression-map-1`` (the dense route before issue 23, trivial multipliers the four nearest 1, no
located boundary) and ``-2`` (before the twist certification: the infinite chain's verdicts are its samples') are read
for their tables and figure (:func:`read_map`, :func:`map_table`); they cannot be resumed by this study.
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from fractions import Fraction
from types import SimpleNamespace
from typing import TYPE_CHECKING, Iterator, Mapping, Optional

import numpy as np
from petsc4py import PETSc

from ..chain import IntegrationTolerances
from ..console import note
from ..dealing import dealt
from ..diagnostics import sup_norm
from ..errors import (Checked, ConvergenceError, ParameterError, check_flag, check_instance, check_reals, members,
                      param)
from ..families import (PRECOMP_PREFIX, AmplitudeFamily, FamilyProblem, check_family_amplitude, uncompressed_limit,
                        wave_at)
from ..floquet import FLOQUET_PREFIX
from ..grid import ProfileGrid, cells_per_pi_param
from ..model import ChainSpec
from ..options import inserted_options
from ..qbranch import regrid_half_profile
from ..records import RecordFileError, check_kind, given, load_npz, on_rank0
from ..resources import check_memory
from ..richardson import extrapolate
from ..roles import uses
from ..shooting import Refiner
from ..slow import CERT_MARGIN, DeflatedSectors, crossing_search, twist_scan
from ..symmetry import WaveSymmetry
from ..twsolver import tw_solver
from ..verdicts import (KIND_CROSSING, KIND_EDGE, KIND_EDGE_INF, KIND_GAP, KIND_LIMIT, KIND_POINT,
                        unstable_intervals)
from ..waves import check_chain_wavenumber, fits_chain
from .base import Study
from .floquet import q_label
from .precompression import _check_delta0_positive, _check_qs, amplitude_grid, wave_orbit

if TYPE_CHECKING:
    from ..model import LatticeModel

MAP_FORMAT = "hertzpetsc-precompression-map-3"
MAP_FORMAT_V2 = "hertzpetsc-precompression-map-2"
MAP_FORMAT_V1 = "hertzpetsc-precompression-map-1"
# largest eigenvector residual of the deflated symmetry vectors that leaves a verdict standing (the valid orbits of
# the committed maps stay below 1e-6; a wrong orbit or symmetry group gives O(1))
EIGVEC_MAX = 1e-4
MAP_FIELDS = ("q", "m", "kind", "a", "A", "omega", "rho", "outside", "sector", "cluster", "raw_cluster", "eigvec",
              "decoupled", "rho_inf", "theta_inf", "cluster_inf", "a_stable", "a_unstable", "A_stable", "A_unstable",
              "rho_stable", "rho_unstable", "theta_unstable", "evaluations", "seconds", "cert_inf", "bound_inf",
              "cert_stable", "modulation_inf", "E_chain", "located", "E_cell")
# the infinite chain's certification of a record (cert_inf; cert_stable: of an edge's stable side): 1 stable between
# the twist samples (slow.certify_twists), 0 stable samples not certified between them (unresolved), -1 none
# (unstable, no verdict, or a file of kind -2, whose verdicts are the samples')
CERT_STABLE, CERT_UNRESOLVED, CERT_NONE = 1, 0, -1
TESTS = ("chain", "infinite")
EDGE_KIND = {"chain": KIND_EDGE, "infinite": KIND_EDGE_INF}
MAX_MAP_BEADS = 2000
# deflated spectra of Richardson waves keep rho - 1 below 1e-8 where the wave is stable (the orbit's error after
# deflation); the verdict's margin keeps a factor 100
MAP_TOL_RHO = 1e-6
# A multiplier that the deflation leaves within NEAR_ONE of 1 belongs to a nearly defective pair (the translations of
# zones that a contact still joins, just past the gap opening: their pair 1 +- sqrt(c) in every sector, c the weak
# coupling): the orbit's and the flow's errors move it by their square roots, off the unit circle when c is below
# them. Where the chain's spectrum has one, its verdict is taken on the orbit refined on the chain by Gauss-Newton to
# E <= REFINE_TOL (shooting.Refiner, prefixes shoot_ and shoot_jac_; a Gauss-Newton step from above it lands near
# 1e-13, the flows' floor of E is about 1e-12), with the cells' flow at FINE_FLOW times the map's tolerances: the
# Richardson wave's E (1e-12 .. 1e-9) gave rho - 1 up to 1.3e-5 there, the flow at rtol 1e-11 up to 8e-7 on the
# refined orbit; both together 1e-10.
NEAR_ONE = 1e-3
REFINE_TOL = 1e-11
FINE_FLOW = 1e-2


def certification(scan):
    """The record's code (:data:`CERT_STABLE`, ...) of a :class:`~hertzpetsc.slow.TwistScan`."""
    return {"stable": CERT_STABLE, "unresolved": CERT_UNRESOLVED}.get(scan.verdict, CERT_NONE)


def wave_cell(q, p=1):
    """The shortest cell of a wave of per-bead wavenumber q on the infinite chain of a mass pattern of p beads: q / 2 pi
    = m' / M in lowest terms (denominator at most :data:`MAX_MAP_BEADS`, to 1e-12), M a multiple of p; its
    :class:`~hertzpetsc.symmetry.WaveSymmetry` (one cell: N = M)."""
    f = Fraction(q / (2 * math.pi)).limit_denominator(MAX_MAP_BEADS)
    if abs(float(f) * 2 * math.pi - q) > 1e-12 * max(q, 1.0):
        raise ParameterError("q", q, f"q / 2 pi must be a fraction with a denominator of at most {MAX_MAP_BEADS} "
                             "(the wave's cell on the infinite chain)")
    M, m = f.denominator, f.numerator
    if M % p:
        M, m = M * p // math.gcd(M, p), m * p // math.gcd(M, p)
    return WaveSymmetry(M, m, p)


@dataclass(frozen=True)
class MapParameters(Checked):
    """The stability map: the precompressed ``model`` (any mass pattern), wavenumbers ``q`` (whole numbers of
    wavelengths on N beads), amplitudes ``a`` (first sine coefficient of the first bead type's profile), N beads (at
    most :data:`MAX_MAP_BEADS`), the coarser grid of the Richardson pair (K, 2K), the flow's tolerances, the
    verdict's threshold tol_rho; ``twists``: the infinite chain's bead-level Bloch parameters per pi (0: no infinite
    chain); ``locate``: the verdicts whose changes are located (subset of 'chain', 'infinite'), to a relative
    bracket ``locate_tol`` in a; ``limit``: add the uncompressed limit (delta0 / A = 0) of each q."""

    model: object
    q: tuple
    a: tuple
    N: int = param(100, "beads of the periodic chain", lo=1, hi=MAX_MAP_BEADS)
    cells_per_pi: int = cells_per_pi_param(1000)
    tolerances: IntegrationTolerances = IntegrationTolerances(rtol=1e-11, atol=1e-13)
    tol_rho: float = param(MAP_TOL_RHO, "the verdict's threshold: unstable when rho - 1 > tol_rho", lo=0.0,
                           hi=1.0)
    twists: int = param(0, "infinite chain: bead-level Bloch parameters per pi (0: not computed)", lo=0, hi=10 ** 6)
    locate: tuple = ("chain",)
    locate_tol: float = param(1e-3, "the relative bracket of a located boundary point", lo=0.0, hi=0.5)
    limit: bool = True

    def __post_init__(self):
        _check_shared(self)
        p = self.model.cell
        if self.N % p:
            raise ParameterError("N", self.N, f"must be a multiple of the mass pattern's length {p} in [{p}, "
                                 f"{MAX_MAP_BEADS}]")
        qs = _check_qs(self.q, math.pi / self.cells_per_pi)
        for q in qs:
            if not fits_chain(q, self.N):
                if not self.twists:
                    raise ParameterError("q", q, f"not a wavenumber 2 pi m / N of the chain of N = {self.N} beads: "
                                         "such a q is computed on the infinite chain only, which needs twists > 0")
                wave_cell(q, p)
        object.__setattr__(self, "q", qs)
        amps = []
        for a in sorted(check_family_amplitude(self.model, a, "a") for a in check_reals("a", self.a, "amplitudes")):
            if not amps or a > amps[-1] * (1 + 1e-9):
                amps.append(a)
        if not amps:
            raise ParameterError("a", self.a, "give at least one amplitude")
        object.__setattr__(self, "a", tuple(amps))
        locate = (self.locate,) if isinstance(self.locate, str) else self.locate
        if not (isinstance(locate, (tuple, list)) and all(isinstance(name, str) and name in TESTS for name in locate)):
            raise ParameterError("locate", self.locate, f"must be a subset of {', '.join(TESTS)}")
        if "infinite" in locate and not self.twists:
            raise ParameterError("locate", ",".join(locate), "locating the infinite chain's boundary needs twists > 0")
        object.__setattr__(self, "locate", tuple(locate))
        object.__setattr__(self, "limit", check_flag("limit", self.limit))


def _check_shared(params):
    """The checks the map and the boundary in q share: a precompressed model of the Hertz law in every bond (the
    uncompressed limit delta0 / A = 0 and the gap opening are that law's: another law, or bonds of laws of their own,
    is refused), then the declared fields (:class:`~hertzpetsc.errors.Checked`) and the flow's tolerances."""
    _check_delta0_positive(params.model)
    law = params.model.law.describe()
    if "law" in law or params.model.bonds is not None:
        raise ParameterError("model", params.model.describe(), "the stability map and its boundaries are of the "
                             "precompressed Hertz chain, one law in every bond (the uncompressed limit delta0 / A = 0 "
                             "and the gap opening are that law's): another law's or bond pattern's waves and "
                             "multipliers are scripts/wave.py's (-law, -beads) and hertzpetsc.api.wave's")
    Checked.__post_init__(params)
    check_instance("tolerances", params.tolerances, IntegrationTolerances, "an IntegrationTolerances(rtol, atol)")


class RichardsonCompanion:
    """The wave on h = pi/(2K) at the amplitude of a wave of the h = pi/K family (Newton from its profiles
    interpolated, prefix of the family; ``measure``: the family's, what its a is), and their Richardson combination
    (second order: O(h^4) initial data).

    The family's wave is first solved again on its own grid from itself (:meth:`polished`): a continuation corrector
    stops once the residual is below the SNES atol, which a warm start from a close predictor (the interpolation of a
    bisection's bracket) reaches in one iteration far above the grid's round-off floor. The orbit's error then
    shifts the multipliers; near a defective pair (the zone translations of a wave just past its gap opening, whose
    zones a contact still joins) it splits them by its square root, off the unit circle: an instability of no
    wave. One Newton iteration from below atol lands on the floor (a full step, without line search)."""

    def __init__(self, model, q, K, comm, prefix=PRECOMP_PREFIX, measure="a1"):
        self.K = K
        self.coarse, self.problem = (FamilyProblem(model, ProfileGrid(k, comm), q, amplitude=1.0, measure=measure,
                                                   parameter="log_a") for k in (K, 2 * K))
        for problem in (self.coarse, self.problem):
            problem.prefix = prefix
        # the polish takes the full Newton step (unless the user chose a line search): from a wave on its floor no
        # step decreases the residual, which a line search takes for a failure
        with inserted_options(prefix, {"snes_linesearch_type": "basic"}):
            self.coarse.solver(False, prefix)
        self.problem.solver(False, prefix)

    @staticmethod
    def _solved(problem, profiles, lam, a):
        """(profiles, lam) of ``problem`` at amplitude ``a`` by Newton from (profiles, lam) (on its grid)."""
        s = math.log(a)
        problem.set_parameter("log_a", s)
        Z = problem.pack(profiles, lam, s)
        try:
            problem.solve(Z)
            return problem.half_profiles(Z), float(problem._scalars(Z)[0])
        finally:
            Z.destroy()

    def polished(self, point):
        """(profiles, lam) of ``point`` (an AmplitudePoint of the K grid) solved again from itself (class
        docstring)."""
        return self._solved(self.coarse, [np.asarray(w) for w in point.profiles], point.lam, point.a)

    def fine(self, point):
        """(profiles, lam) on the fine grid at the amplitude of ``point`` (an AmplitudePoint of the K grid)."""
        return self._solved(self.problem, [regrid_half_profile(w, 2 * self.K) for w in point.profiles], point.lam,
                            point.a)

    def combine(self, point):
        """(profiles, lam): the Richardson combination of ``point`` (:meth:`polished`) and its fine-grid
        companion; and (fine profiles, lam) of the companion."""
        coarse, lam1 = self.polished(point)
        point = SimpleNamespace(a=point.a, profiles=coarse, lam=lam1)
        fine, lam2 = self.fine(point)
        return [extrapolate(np.asarray(w1), np.asarray(w2)[::2]) for w1, w2 in zip(coarse, fine)], \
            extrapolate(lam1, lam2), (fine, lam2)

    def destroy(self):
        self.coarse.destroy()
        self.problem.destroy()


class MapProbe:
    """The test functions of one q's amplitude family (module docstring): per amplitude the Richardson wave, its
    deflated spectrum on N beads and its twist scan on the infinite chain, each computed once, when first read;
    ``measure``: what the family's a is (:class:`~hertzpetsc.families.AmplitudeFamily`); ``refine_all``: every
    infinite-chain verdict on the refined cell orbit, not only the weak ones (:data:`NEAR_ONE`; the re-judging of a
    map's weak records, :mod:`hertzpetsc.studies.rejudge`)."""

    def __init__(self, study, q, model=None, measure="a1", refine_all=False):
        self.study, self.q, self.measure = study, q, measure
        self.model = study.model if model is None else model
        self.refine_all = refine_all
        self._companion, self._refiners = None, {}
        self.cache, self.hints, self.evaluations = {}, [], {name: 0 for name in TESTS}

    @property
    def companion(self):
        if self._companion is None:
            self._companion = RichardsonCompanion(self.model, self.q, self.study.K, PETSc.COMM_SELF,
                                                  measure=self.measure)
        return self._companion

    def refiner(self, N):
        """The Gauss-Newton refiner of orbits on N beads (the chain's, or the infinite chain's cell), built once."""
        if N not in self._refiners:
            self._refiners[N] = Refiner(ChainSpec(self.model, N), PETSc.COMM_SELF, REFINE_TOL)
        return self._refiners[N]

    def entry(self, point):
        key = math.log(point.a)
        for k, v in self.cache.items():
            if abs(k - key) <= 1e-12 * max(1.0, abs(key)):
                return v
        self.cache[key] = entry = dict(point=point)
        return entry

    def tests(self, point):
        """{name: function} for :class:`~hertzpetsc.continuation.LazyTests` (FamilyProblem.extra_tests)."""
        entry = self.entry(point)
        margin = math.log1p(self.study.tol_rho)
        out = {}
        if "chain" in self.study.locate and fits_chain(self.q, self.study.N):
            out["chain"] = lambda: math.log(self.chain(entry)["rho"]) - margin
        if "infinite" in self.study.locate:
            out["infinite"] = lambda: math.log(self.infinite(entry)["rho"]) - margin
        return out

    def wave(self, entry):
        if "w" not in entry:
            p = entry["point"]
            try:
                w, lam, fine = self.companion.combine(p)
            except ConvergenceError:
                # the step to this wave fails (the continuation halves it): its entry goes, so that the wave the
                # retried step reaches at this amplitude is not read from it
                self.cache = {k: v for k, v in self.cache.items() if v is not entry}
                raise
            entry.update(w=w, lam=lam, fine=fine, A=p.a * max(sup_norm(x) for x in w))
        return entry

    def chain(self, entry):
        if "chain" not in entry:
            st, e = self.study, self.wave(entry)
            orbit = wave_orbit(self.model, self.q, entry["point"].a, e["w"], e["lam"], st.N, math.pi / st.K)
            spec = st.route(self.model).spectrum(orbit, st.tol_rho)
            E = math.nan
            if np.min(np.abs(spec.multipliers[~spec.known] - 1), initial=math.inf) < NEAR_ONE:
                # a nearly defective pair at 1: the verdict of the refined orbit (NEAR_ONE)
                refined = self.refiner(st.N).refine(orbit)
                orbit, E = refined.orbit, refined.E
                spec = st.route(self.model, fine=True).spectrum(orbit, st.tol_rho)
            sectors = spec.work["sectors"]
            rest = ~spec.known
            top = int(np.argmax(np.abs(spec.multipliers) * rest))
            sym = orbit.symmetry
            entry["omega"] = orbit.omega
            entry["chain"] = dict(
                rho=spec.rho, outside=int(np.sum(np.abs(spec.multipliers[rest]) > 1 + st.tol_rho)),
                sector=2 * math.pi * float(spec.sector[top]) / sym.g, cluster=spec.trivial_spread,
                raw=max((float(np.max(np.abs(s.raw_cluster))) - 1 for s in sectors if s.r), default=0.0),
                eigvec=max(s.eigenvector_residual for s in sectors), decoupled=bool(spec.work["decoupled"]),
                patterns=tuple(s.pattern() for s in sectors), E=E)
            self.evaluations["chain"] += 1
        return entry["chain"]

    def infinite(self, entry):
        if "infinite" not in entry:
            st, e = self.study, self.wave(entry)
            sym = wave_cell(self.q, self.model.cell)
            cell = wave_orbit(self.model, self.q, entry["point"].a, e["w"], e["lam"], sym.M, math.pi / st.K)
            n_grid = max(2, -(-st.twists // sym.M))
            scan = twist_scan(st.route(self.model), cell, n_grid, hints=self.hints, floor=st.tol_rho)
            E, unrefined = math.nan, scan.rho_max
            if self.refine_all or st.tol_rho < scan.rho_max - 1 < NEAR_ONE:
                # a weak instability: the long-wave multipliers near 1 (the zones' translations over the twists)
                # are split by the orbit's error as on N beads (NEAR_ONE): the verdict of the refined cell orbit
                refined = self.refiner(sym.M).refine(cell)
                cell, E = refined.orbit, refined.E
                scan = twist_scan(st.route(self.model, fine=True), cell, n_grid, hints=self.hints, floor=st.tol_rho)
            if scan.rho_max - 1 > st.tol_rho:
                self.hints = ([scan.theta] + [h for h in self.hints if abs(h - scan.theta) > 1e-9])[:3]
            entry["omega"] = cell.omega
            c = scan.certificate
            entry["infinite"] = dict(rho=scan.rho_max, theta=scan.theta, cluster=scan.cluster, M=sym.M,
                                     decoupled=scan.decoupled, cert=certification(scan),
                                     bound=c.bound if c is not None else math.nan,
                                     modulation=2 * math.pi * sym.M / scan.theta_min, E=E, unrefined=unrefined)
            self.evaluations["infinite"] += 1
        return entry["infinite"]

    def at(self, s):
        """The cache entry of the amplitude a = exp(s)."""
        return min(self.cache.items(), key=lambda kv: abs(kv[0] - s))[1]

    def destroy(self):
        if self._companion is not None:
            self._companion.destroy()
        for refiner in self._refiners.values():
            refiner.destroy()


def limit_probe(study, q, grid, probe, point):
    """(probe, entry) of the uncompressed limit (delta0 / A = 0) of ``study``'s model at q: the Richardson
    combination of the limits on ``grid`` and on the companion's grid, reached from the family's ``point`` (a large
    amplitude) and its companion wave; the probe is of the delta0 = 0 chain (the caller destroys it)."""
    entry = probe.wave(probe.entry(point))
    fine, lam2 = entry["fine"]
    coarse = uncompressed_limit(study.model, q, grid, point)
    companion = probe.companion.problem
    fine = uncompressed_limit(study.model, q, companion.grid,
                              SimpleNamespace(profiles=fine, lam=lam2, normalised=companion.normalised))
    w = [extrapolate(np.asarray(w1), np.asarray(w2)[::2]) for w1, w2 in zip(coarse["profiles"], fine["profiles"])]
    lam = extrapolate(coarse["lam"], fine["lam"])
    # the probe of the delta0 = 0 chain on this wave (a = inf: wave_orbit takes the wave as it is)
    return MapProbe(study, q, study.model.with_delta0(0.0)), dict(point=SimpleNamespace(a=math.inf), w=w, lam=lam,
                                                                    A=math.inf)


def saved_as_dealt(study, jobs, costs, key, belongs):
    """Run ``study.compute`` on each job, dealt to the ranks by cost; save each record the store does not hold yet
    (``key``: its identity within the job; ``belongs(record, job)``: a stored record of that job: a job in progress
    when a run stopped is recomputed, its records are the same) and yield it."""
    for job, rows in dealt(jobs, costs, study.comm, study.compute):
        have = {key(r) for r in study.store.records if belongs(r, job)}
        for row in rows:
            if key(row) not in have:
                yield study.store.append(row)


class StabilityMap(Study):
    """The stability map and boundary of waves of a precompressed ``model`` (module docstring). Prefixes:
    ``precomp_`` (the wave solves), ``floquet_`` (the flows of the cell maps), ``shoot_`` and ``shoot_jac_`` (the
    refinement where a multiplier is near 1)."""

    Parameters = MapParameters
    FORMAT, FIELDS = MAP_FORMAT, MAP_FIELDS
    DTYPES = {"m": np.int64, "kind": np.int64, "outside": np.int64, "decoupled": np.int64, "evaluations": np.int64,
              "cert_inf": np.int64, "cert_stable": np.int64, "located": np.int64}
    ROLES = uses("precomp_", "shoot_", "shoot_jac_", floquet_=("ts",))
    ADDED = {"E_chain": math.nan, "located": 1, "E_cell": math.nan}
    WHAT = "stability-map file"
    NAMES = dict(amplitudes="a (-a, with the -ds grid)", masses="model's masses (-epsilon, or -beads)",
                 alpha="model's Hertz exponent (-alpha)", delta0="model's precompression (-delta0, or -static_force "
                 "and -length_scale with -beads)", law="model's law", bonds="model's bonds (-beads)")

    def __init__(self, params: MapParameters, comm: Optional[PETSc.Comm] = None, output: Optional[str] = None,
                 mode: str = "new") -> None:
        super().__init__(params, comm, output, mode)
        p = params
        self.model, self.N, self.qs, self.a_values = p.model, p.N, list(p.q), list(p.a)
        self.K, self.tolerances, self.tol_rho, self.twists = p.cells_per_pi, p.tolerances, p.tol_rho, p.twists
        self.locate, self.locate_tol, self.limit = p.locate, p.locate_tol, p.limit
        check_memory(2 * self.K, PETSc.COMM_SELF, tw_solver(PRECOMP_PREFIX), profiles=self.model.cell)
        self._routes = {}

    def constants(self) -> dict:
        return dict(self.model.law_identity(), masses=list(self.model.masses), N=self.N, cells_per_pi=self.K,
                    rtol=self.tolerances.rtol, tol_rho=self.tol_rho, twists=self.twists,
                    locate=",".join(self.locate) or "none", locate_tol=self.locate_tol, amplitudes=self.a_values)

    def route(self, model: LatticeModel, fine: bool = False) -> DeflatedSectors:
        """The deflated sector route of ``model`` on one rank (built once per model, prefix ``floquet_``); ``fine``:
        its flow at :data:`FINE_FLOW` times the map's tolerances."""
        key = (repr(model.describe()), fine)
        if key not in self._routes:
            tol = self.tolerances if not fine else IntegrationTolerances(rtol=FINE_FLOW * self.tolerances.rtol,
                                                                         atol=FINE_FLOW * self.tolerances.atol)
            # Krein signatures where crossings are searched: along a (chain) and over the twists (infinite chain)
            self._routes[key] = DeflatedSectors(model, PETSc.COMM_SELF, tol, FLOQUET_PREFIX, twists=None,
                                                krein=self.tol_rho if self.locate or self.twists else None)
        return self._routes[key]

    # --- one q -------------------------------------------------------------------------------------------------
    def _row(self, q, kind, a, A, omega, probe=None, entry=None):
        nan = math.nan
        row = dict.fromkeys(MAP_FIELDS, nan)
        row.update(q=q, m=check_chain_wavenumber(q, self.N) if fits_chain(q, self.N) else -1, kind=kind, a=a, A=A,
                   omega=omega, outside=-1, decoupled=-1, evaluations=0, seconds=0.0, cert_inf=CERT_NONE,
                   cert_stable=CERT_NONE, located=1)
        if entry is not None:
            if fits_chain(q, self.N):
                c = probe.chain(entry)
                row.update(rho=c["rho"], outside=c["outside"], sector=c["sector"], cluster=c["cluster"],
                           raw_cluster=c["raw"], eigvec=c["eigvec"], decoupled=int(c["decoupled"]), E_chain=c["E"])
                if not c["eigvec"] <= EIGVEC_MAX:
                    # the symmetry vectors are not eigenvectors of this orbit's sector maps: the deflated
                    # spectrum is not the wave's, no verdict (rho nan), said once per record
                    row.update(rho=nan, outside=-1)
                    note(f"q = {q:.6g}, a = {a:g}: the deflation's eigenvector residual {c['eigvec']:.1e} exceeds "
                         f"{EIGVEC_MAX:g}; no verdict recorded (rho = nan)", PETSc.COMM_SELF)
            if self.twists:
                i = probe.infinite(entry)
                row.update(rho_inf=i["rho"], theta_inf=i["theta"], cluster_inf=i["cluster"], cert_inf=i["cert"],
                           bound_inf=i["bound"], modulation_inf=i["modulation"], E_cell=i["E"],
                           decoupled=int(i["decoupled"]) if row["decoupled"] < 0 else row["decoupled"])
            row["omega"] = entry.get("omega", omega)
        return row

    def _edge(self, q, probe, event, seconds):
        (s1, g1), (s2, _) = event.bracket
        stable, unstable = (probe.at(s1), probe.at(s2)) if g1 <= 0 else (probe.at(s2), probe.at(s1))
        name = event.event
        get = getattr(probe, name)                      # probe.chain or probe.infinite
        located = probe.entry(event)
        row = self._row(q, EDGE_KIND[name], event.a, probe.wave(located)["A"], event.omega, probe, located)
        row.update(a_stable=stable["point"].a, a_unstable=unstable["point"].a, A_stable=probe.wave(stable)["A"],
                   A_unstable=probe.wave(unstable)["A"], rho_stable=get(stable)["rho"] - 1,
                   rho_unstable=get(unstable)["rho"] - 1,
                   theta_unstable=get(unstable)["sector" if name == "chain" else "theta"], seconds=seconds,
                   cert_stable=get(stable)["cert"] if name == "infinite" else CERT_NONE)
        return row

    def compute(self, q: float) -> list[dict]:
        """Every record of one q (on this rank), in order of amplitude; the uncompressed limit last."""
        grid = ProfileGrid(self.K, PETSc.COMM_SELF)
        probe = MapProbe(self, q)
        fam = AmplitudeFamily(self.model, q, grid, tests=probe.tests, bisect=self.locate,
                              locate_step=0.5 * self.locate_tol)
        rows, point, previous = [], None, None
        try:
            for a in self.a_values:
                t0 = time.perf_counter()
                before = dict(probe.evaluations)
                point = fam.step_to(a)
                entry = probe.entry(point)
                row = self._row(q, KIND_POINT, point.a, probe.wave(entry)["A"], point.omega, probe, entry)
                if previous is not None and "chain" in self.locate and fits_chain(q, self.N):
                    rows += self._bubble(q, fam, probe, previous, entry)
                rows += self._events(q, fam, probe, t0, before, rows)
                row["seconds"] = time.perf_counter() - t0
                rows.append(row)
                previous = entry
            if self.limit:
                rows.append(self._limit(q, fam, probe, point))
        finally:
            fam.destroy()
            probe.destroy()
        return sorted(rows, key=lambda r: (r["a"], r["kind"] != KIND_POINT))

    def _events(self, q, fam, probe, t0, before, rows):
        """The records of the points the family located since the last call: the gap opening and the boundary
        points, each once (a search that steps the family back and forth across a root locates it again)."""
        out = []
        for event in fam.events():
            kind = KIND_GAP if event.event == "gap" else EDGE_KIND.get(event.event)
            if kind is None or (kind != KIND_GAP and event.event not in self.locate) or any(
                    r["kind"] == kind and abs(math.log(r["a"] / event.a)) <= self.locate_tol for r in rows + out):
                continue
            if kind == KIND_GAP:
                out.append(self._row(q, KIND_GAP, event.a, event.A, event.omega))
            else:
                out.append(self._edge(q, probe, event, time.perf_counter() - t0))
                out[-1]["evaluations"] = probe.evaluations[event.event] - before[event.event]
            if event.unresolved is not None:
                # its bisection stopped at a trial that failed: the record is a solved end of the bracket
                # (located 0), the edge shown as bracketed only (the layer said why in a note; an unresolved gap
                # opening stops the family: AmplitudeFamily.step_to)
                out[-1]["located"] = 0
        return out

    def _bubble(self, q, fam, probe, first, last):
        """Between two stable amplitudes of the map whose sectors' Krein patterns differ (a crossing of multipliers
        of opposite signatures: an instability bubble between them, perhaps narrower than the map's step), the
        bubble by bisection in log a keeping the half whose patterns differ; when a sample is unstable, the family
        steps to it from both stable sides, so that the layer locates both edges; else a record of the crossing
        (kind 5). The family ends where it was, at ``last``."""
        c1, c2 = probe.chain(first), probe.chain(last)
        tol = self.tol_rho
        if c1["rho"] - 1 > tol or c2["rho"] - 1 > tol or c1["patterns"] == c2["patterns"]:
            return []
        lo, hi = math.log(first["point"].a), math.log(last["point"].a)
        found = crossing_search(lambda s: probe.chain(probe.entry(fam.step_to(math.exp(s)))),
                                lambda c: c["rho"] - 1 > tol, lambda c: c["patterns"], lo, hi, c1["patterns"],
                                0.5 * self.locate_tol)
        if found is None:
            # no sample above tol_rho: the crossing's bubble (if any) is narrower than the bracket, or weaker
            row = self._row(q, KIND_CROSSING, last["point"].a, probe.wave(last)["A"], math.nan)
            row.update(a_stable=first["point"].a, a_unstable=last["point"].a, A_stable=probe.wave(first)["A"],
                       A_unstable=probe.wave(last)["A"], rho_stable=c1["rho"] - 1, rho_unstable=c2["rho"] - 1)
            if abs(fam.continuation.parameter - hi) > 1e-12:
                fam.step_to(math.exp(hi))
            return [row]
        # the family is at the unstable sample, coming from one stable end around it (the layer located that edge):
        # a step to the other end locates the other edge
        _, _, a, b = found
        came_from = fam.continuation.previous
        for target in (b if abs(came_from - a) < abs(came_from - b) else a, hi):
            if abs(target - fam.continuation.parameter) > 1e-12:
                fam.step_to(math.exp(target))
        return []

    def _limit(self, q, fam, probe, point):
        """The uncompressed limit (delta0 / A = 0) from the largest amplitude, on both grids, and its spectra; if
        that amplitude is too small for the limit's Newton to converge from it, from a = LIMIT_FROM_A delta0 (the
        family continued there without the map's tests)."""
        t0 = time.perf_counter()
        try:
            limit, entry = limit_probe(self, q, fam.grid, probe, point)
        except ConvergenceError:
            if not point.a < LIMIT_FROM_A * self.model.delta0:
                raise
            bare = AmplitudeFamily(self.model, q, fam.grid)
            try:
                point = list(bare.points(amplitude_grid(point.a, LIMIT_FROM_A * self.model.delta0,
                                                        math.log(10) / 4)))[-1]
            finally:
                bare.destroy()
            limit, entry = limit_probe(self, q, fam.grid, probe, point)
        try:
            row = self._row(q, KIND_LIMIT, math.inf, math.inf, math.nan, limit, entry)
        finally:
            limit.destroy()
        row["seconds"] = time.perf_counter() - t0
        return row

    # --- the study ---------------------------------------------------------------------------------------------
    def _complete(self, q):
        mine = [r for r in self.store.records if abs(float(r["q"]) - q) <= 1e-12 * q]
        return any(int(r["kind"]) == KIND_LIMIT for r in mine) if self.limit else \
            sum(1 for r in mine if int(r["kind"]) == KIND_POINT) >= len(self.a_values)

    def cost(self, q: float) -> float:
        """Estimated work of one q (for dealing): the chain's sectors and the infinite chain's scan."""
        chain = WaveSymmetry(self.N, check_chain_wavenumber(q, self.N), self.model.cell).cost() * 50 \
            if fits_chain(q, self.N) else 0.0
        M = wave_cell(q, self.model.cell).M
        return 1.0 + chain + (math.ceil(self.twists / M) * (M / 20) ** 3 / 20 if self.twists else 0.0)

    def run(self) -> Iterator[dict]:
        """Compute every q not complete in the file (a q in progress is recomputed: its records are the same);
        yields each new record after saving it."""
        self.open()
        todo = [q for q in self.qs if not self._complete(q)]
        yield from saved_as_dealt(self, todo, [self.cost(q) for q in todo],
                                  lambda r: (int(r["kind"]), round(float(r["a"]), 10)),
                                  lambda r, q: abs(float(r["q"]) - q) <= 1e-12 * q)

    def destroy(self) -> None:
        for route in self._routes.values():
            route.destroy()
        self._routes = {}

    # --- tables and figures ------------------------------------------------------------------------------------
    def table(self) -> str:
        return map_table(self.arrays())


# --- the boundary located in q at fixed amplitude (the infinite chain) ----------------------------------------------
QMAP_FORMAT = "hertzpetsc-boundary-q-2"
QMAP_FORMAT_V1 = "hertzpetsc-boundary-q-1"
QMAP_FIELDS = ("A", "q", "M", "kind", "grid", "omega", "rho_inf", "theta_inf", "cluster_inf", "q_stable",
               "q_unstable", "rho_stable", "rho_unstable", "theta_unstable", "evaluations", "seconds", "cert_inf",
               "bound_inf", "cert_stable", "modulation_inf", "E_cell")
# the uncompressed limit of a level A = inf is reached from the family's wave at this amplitude (delta0 units)
LIMIT_FROM_A = 1000.0
# the largest cell of a bisection wavenumber by default: the twist scans' dense 2M x 2M sector maps grow as M^2 in
# memory and M^3 in time; an edge next to a fraction of small denominator b is then bracketed to about
# 1 / (b QB_MAX_CELL) in q / 2 pi, and the edge's record says how far it got
QB_MAX_CELL = 400


def simplest_fraction(lo, hi):
    """The fraction of smallest denominator in the closed interval [lo, hi] (Fractions, 0 <= lo <= hi): the
    continued-fraction descent of the Stern-Brocot tree."""
    fl = math.floor(lo)
    if fl == lo:
        return Fraction(fl)
    if fl + 1 <= hi:
        return Fraction(fl + 1)
    return fl + 1 / simplest_fraction(1 / (hi - fl), 1 / (lo - fl))


@dataclass(frozen=True)
class QBoundaryParameters(Checked):
    """The stability boundary on the infinite chain located in q at fixed amplitudes: the precompressed monatomic
    ``model``, the amplitudes ``A`` = ||u||_inf (inf: the uncompressed limit), the grid of wavenumbers ``q`` between
    which the verdict's changes are located to ``locate_tol`` (a bracket of at most locate_tol / 2 relative in q),
    every wavenumber (grid or bisection) with q / 2 pi a fraction whose cell has at most ``max_cell`` beads; the
    Richardson grid K = ``cells_per_pi``, the flow's tolerances, tol_rho and the twists per pi as for the map."""

    model: object
    A: tuple
    q: tuple
    cells_per_pi: int = cells_per_pi_param(1000)
    tolerances: IntegrationTolerances = IntegrationTolerances(rtol=1e-11, atol=1e-13)
    tol_rho: float = param(MAP_TOL_RHO, "the verdict's threshold: unstable when rho - 1 > tol_rho", lo=0.0,
                           hi=1.0)
    twists: int = param(512, "bead-level Bloch parameters per pi", lo=1, hi=10 ** 6)
    locate_tol: float = param(1e-3, "the relative bracket of a located edge (at most half of it)", lo=0.0, hi=0.5)
    max_cell: int = param(QB_MAX_CELL, "the largest cell (beads) of a bisection wavenumber", lo=2, hi=MAX_MAP_BEADS)

    def __post_init__(self):
        _check_shared(self)
        if self.model.cell != 1:
            raise ParameterError("masses", list(self.model.masses), "the boundary in q is located for monatomic "
                                 "chains (the dimers' infinite chains are unstable at every amplitude of their maps)")
        qs = sorted(set(_check_qs(self.q, math.pi / self.cells_per_pi, distinct=False)))
        for q in qs:
            if wave_cell(q).M > self.max_cell:
                raise ParameterError("q", q, f"q / 2 pi must be a fraction with a denominator of at most max_cell = "
                                     f"{self.max_cell}")
        object.__setattr__(self, "q", tuple(qs))
        amps = {math.inf if A == math.inf else check_family_amplitude(self.model, A, "A")
                for A in members("A", self.A, "amplitudes")}
        if not amps:
            raise ParameterError("A", self.A, "give at least one amplitude")
        object.__setattr__(self, "A", tuple(sorted(amps)))


class QBoundary(Study):
    """The infinite chain's stability boundary located in q at fixed amplitudes A (issue 23): at each A the wave at
    every grid q (:func:`~hertzpetsc.families.wave_at`, A a border row; Richardson pair h = pi/K, pi/(2K)) and its
    twist scan (:meth:`MapProbe.infinite`: a weak instability judged on the refined cell orbit, ``E_cell``, as in the
    map); where the verdict changes between two grid q, bisection in q through the
    simplest fraction q / 2 pi of the middle third of the bracket (its cell the fewest beads) until the bracket is at
    most ``locate_tol`` / 2 relative. Each A on one rank (the levels are dealt); every evaluation a record (kind 0;
    ``grid`` 1 for the grid q), each located edge a record of kind 2 with both sides. Prefixes as the map's."""

    Parameters = QBoundaryParameters
    FORMAT, FIELDS = QMAP_FORMAT, QMAP_FIELDS
    DTYPES = {"M": np.int64, "kind": np.int64, "grid": np.int64, "evaluations": np.int64, "cert_inf": np.int64,
              "cert_stable": np.int64}
    ROLES = StabilityMap.ROLES                      # the weak verdicts on the refined cell orbit (NEAR_ONE)
    ADDED = {"E_cell": math.nan}
    WHAT = "boundary-in-q file"
    NAMES = dict(StabilityMap.NAMES, levels="A (-A)", grid_q="q (-m with -N, and -q)")
    locate, N = ("infinite",), 0
    route = StabilityMap.route

    def __init__(self, params: QBoundaryParameters, comm: Optional[PETSc.Comm] = None, output: Optional[str] = None,
                 mode: str = "new") -> None:
        super().__init__(params, comm, output, mode)
        p = params
        self.model, self.K, self.tolerances, self.tol_rho, self.twists = (p.model, p.cells_per_pi, p.tolerances,
                                                                          p.tol_rho, p.twists)
        check_memory(2 * self.K, PETSc.COMM_SELF, tw_solver(PRECOMP_PREFIX), profiles=1)
        self._routes = {}

    def constants(self) -> dict:
        p = self.params
        return dict(self.model.law_identity(), masses=list(self.model.masses), levels=list(p.A), grid_q=list(p.q),
                    cells_per_pi=self.K, rtol=self.tolerances.rtol, tol_rho=self.tol_rho, twists=self.twists,
                    locate_tol=p.locate_tol, max_cell=p.max_cell)

    def evaluate(self, x: Fraction, A: float) -> dict:
        """The record of the wave at q = 2 pi x (x a Fraction), amplitude A, on the infinite chain."""
        t0 = time.perf_counter()
        q = 2 * math.pi * float(x)
        grid = ProfileGrid(self.K, PETSc.COMM_SELF)
        probe = MapProbe(self, q, measure="sup")
        limit = None
        try:
            point = wave_at(self.model, q, min(A, LIMIT_FROM_A * self.model.delta0), grid)
            entry = probe.entry(point)
            if math.isfinite(A):
                scan = probe.infinite(entry)
            else:
                limit, entry = limit_probe(self, q, grid, probe, point)
                scan = limit.infinite(entry)
        finally:
            probe.destroy()
            if limit is not None:
                limit.destroy()
        return dict(dict.fromkeys(QMAP_FIELDS, math.nan), A=A, q=q, M=scan["M"], kind=KIND_POINT, grid=0,
                    omega=entry.get("omega", math.nan), rho_inf=scan["rho"], theta_inf=scan["theta"],
                    cluster_inf=scan["cluster"], cert_inf=scan["cert"], bound_inf=scan["bound"],
                    modulation_inf=scan["modulation"], E_cell=scan["E"],
                    cert_stable=CERT_NONE, evaluations=1, seconds=time.perf_counter() - t0)

    def unstable(self, row: Mapping) -> bool:
        return row["rho_inf"] - 1 > self.tol_rho

    def compute(self, A: float) -> list[dict]:
        """Every record of the level A (on this rank): the grid q, then each located edge after its samples."""
        p = self.params
        cells = [Fraction(c.m, c.M) for c in map(wave_cell, p.q)]
        rows = [dict(self.evaluate(x, A), grid=1) for x in cells]
        grid = list(zip(cells, rows))
        for (x1, r1), (x2, r2) in zip(grid, grid[1:]):
            if self.unstable(r1) == self.unstable(r2):
                continue
            (xs_, rs), (xu, ru) = ((x1, r1), (x2, r2)) if not self.unstable(r1) else ((x2, r2), (x1, r1))
            n = 0
            while abs(xu - xs_) > 0.5 * p.locate_tol * min(xu, xs_):
                lo, hi = min(xs_, xu), max(xs_, xu)
                third = (hi - lo) / 3
                x = simplest_fraction(lo + third, hi - third)
                if x.denominator > p.max_cell:
                    note(f"A = {A:g}: the bracket q / 2 pi in [{lo}, {hi}] holds no cell of at most max_cell = "
                         f"{p.max_cell} beads in its middle third; the edge is located to {float((hi - lo) / lo):.1e}",
                         PETSc.COMM_SELF)
                    break
                row = self.evaluate(x, A)
                rows.append(row)
                n += 1
                if self.unstable(row):
                    xu, ru = x, row
                else:
                    xs_, rs = x, row
            edge = dict(ru)
            edge.update(kind=KIND_EDGE_INF, grid=0, q=math.pi * float(xs_ + xu), M=0,
                        q_stable=2 * math.pi * float(xs_), q_unstable=2 * math.pi * float(xu),
                        rho_stable=rs["rho_inf"] - 1, rho_unstable=ru["rho_inf"] - 1,
                        theta_unstable=ru["theta_inf"], cert_stable=rs["cert_inf"],
                        modulation_inf=rs["modulation_inf"], evaluations=n, seconds=sum(
                            r["seconds"] for r in rows[-n:]) if n else 0.0)
            rows.append(edge)
        return rows

    def _complete(self, A):
        mine = [r for r in self.store.records if float(r["A"]) == A]
        grid = {round(float(r["q"]), 12): r for r in mine if int(r["grid"]) == 1}
        if len(grid) < len(self.params.q):
            return False
        rows = [grid[round(q, 12)] for q in self.params.q if round(q, 12) in grid]
        changes = sum(self.unstable(a) != self.unstable(b) for a, b in zip(rows, rows[1:]))
        return sum(1 for r in mine if int(r["kind"]) == KIND_EDGE_INF) >= changes

    def run(self) -> Iterator[dict]:
        """Compute every level A not complete in the file (a level in progress is recomputed: its records are the
        same); yields each new record after saving it."""
        self.open()
        todo = [A for A in self.params.A if not self._complete(A)]
        yield from saved_as_dealt(self, todo, [1.0 + math.log1p(min(A, LIMIT_FROM_A)) for A in todo],
                                  lambda r: (int(r["kind"]), round(float(r["q"]), 12)),
                                  lambda r, A: float(r["A"]) == A)

    destroy = StabilityMap.destroy

    def table(self) -> str:
        return q_boundary_table(self.arrays())


def _brackets(stable, unstable, mine, name, unresolved=None):
    """What the located edges' rows show of their brackets: the largest relative width |unstable - stable| / min of
    the rows ``mine`` (a table claims the resolution its rows have, not the one asked for); ``unresolved``: the rows
    whose bisection failed (bracketed only), counted apart."""
    apart = np.zeros(len(mine), bool) if unresolved is None else mine & unresolved
    s, u = np.asarray(stable, float)[mine & ~apart], np.asarray(unstable, float)[mine & ~apart]
    more = (f"; {int(apart.sum())} edge{'s' if apart.sum() > 1 else ''} unresolved (a bisection trial failed: "
            f"bracketed only, its width in the table)") if apart.any() else ""
    if not len(s):
        return "no edge located" + more
    width = float(np.max(np.abs(u - s) / np.minimum(s, u)))
    return f"the {len(s)} located edges within brackets of at most {width:.1e} (relative, in {name})" + more


def q_boundary_table(z):
    """The Markdown table of a boundary-in-q file's arrays: the located edges per amplitude, then the grid's
    verdicts (each stable one certified between its twist samples, or unresolved; a file of kind -1 holds the
    verdicts at its samples only)."""
    tol = float(z["tol_rho"])
    A, q, kind, grid = (np.asarray(z[k], float) for k in ("A", "q", "kind", "grid"))
    rho = np.asarray(z["rho_inf"], float)
    certified = "cert_inf" in z
    cert = np.asarray(z["cert_inf"]) if certified else np.full(len(A), CERT_NONE)
    edges = np.nonzero(kind == KIND_EDGE_INF)[0]
    qs_, qu_ = np.asarray(z["q_stable"], float), np.asarray(z["q_unstable"], float)
    lines = [f"schema: {str(z.get('format', QMAP_FORMAT))}; alpha = {float(z['alpha']):g}, delta0 = "
             f"{float(z['delta0']):g}; the infinite chain (cell twists, bead-level Bloch step <= pi/{int(z['twists'])}, "
             f"maxima refined; symmetry multipliers deflated"
             + (f"; a stable verdict certified between its twist samples: any band of instability there has rho - 1 "
                f"<= {CERT_MARGIN * tol:g} or the located maximum of a weaker band, for modulations up to the beads "
                f"of the column 'modulations'"
                if certified else "; verdicts at the twist samples only, before the twist certification")
             + f"); waves at A = ||u||_inf (border row), Richardson of h = pi/{int(z['cells_per_pi'])} and "
             f"pi/{2 * int(z['cells_per_pi'])}; flow rtol {float(z['rtol']):g}; unstable when rho - 1 > {tol:g}; "
             f"edges located by bisection in q through the simplest q / 2 pi of the middle third (cells of at most "
             f"{int(z['max_cell'])} beads), asked to a bracket of {float(z['locate_tol']) / 2:g} (relative); "
             + _brackets(qs_, qu_, kind == KIND_EDGE_INF, "q") + ".\n",
             "### Located edges\n",
             "Each row: at amplitude A, the wavenumber where the verdict changes, between q (stable side) and q "
             "(unstable side), with rho - 1 on both sides (the multipliers' distance to the unit circle), the cell "
             "twist Theta of the unstable mode, and whether the stable side is certified between its twist samples.\n",
             "| A | q stable | q unstable | relative width | rho - 1 stable side | rho - 1 unstable side | Theta | "
             "evaluations | stable side between twists | modulations (beads) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for i in edges[np.lexsort((q[edges], A[edges]))]:
        qs, qu = float(qs_[i]), float(qu_[i])
        side = ({CERT_STABLE: "certified", CERT_UNRESOLVED: "unresolved"}.get(int(z["cert_stable"][i]), "n/a")
                if certified else "samples only")
        lines.append(f"| {A[i]:g} | {qs:.6f} | {qu:.6f} | {abs(qu - qs) / min(qs, qu):.1e} | "
                     f"{float(z['rho_stable'][i]):.1e} | {float(z['rho_unstable'][i]):.1e} | "
                     f"{float(z['theta_unstable'][i]):.4f} | {int(z['evaluations'][i])} | {side} | "
                     f"{_modulation(z, i)} |")
    gq = sorted(set(q[grid == 1].tolist()))
    lines += ["\n### Verdicts at the grid wavenumbers\n",
              "rho - 1 on the infinite chain per amplitude (rows) and grid q (columns); U: unstable"
              + ("; u: unresolved (stable at every twist sample, not certified between them)" if certified else "")
              + ".\n",
              "| A | " + " | ".join(q_label(x) for x in gq) + " |", "|---|" + "---|" * len(gq)]
    for level in sorted(set(A.tolist())):
        cells = []
        for x in gq:
            i = np.nonzero((A == level) & (grid == 1) & (q == x))[0]
            cell = _rho_cell(rho, i, tol)
            if len(i) and certified and cert[i[0]] == CERT_UNRESOLVED:
                cell += " u"
            cells.append(cell)
        lines.append(f"| {level:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _modulation(z, i):
    """The longest modulation (beads) covered by the certified stable verdict of record i ('n/a' without one)."""
    if "modulation_inf" not in z or not math.isfinite(float(z["modulation_inf"][i])):
        return "n/a"
    return f"{float(z['modulation_inf'][i]):.3g}"


def read_map(path, comm=None):
    """The arrays of a stability-map file of any kind (``format``: :data:`MAP_FORMAT`, :data:`MAP_FORMAT_V2` or
    :data:`MAP_FORMAT_V1`), read on rank 0 and given to every rank; :class:`~hertzpetsc.errors.RecordFileError` for
    any other file."""
    def load():
        z = load_npz(path, "stability-map file")
        if str(z.get("format", "")) not in (MAP_FORMAT_V1, MAP_FORMAT_V2):
            check_kind(z, path, MAP_FORMAT, "stability-map file")
        return z
    return on_rank0(comm, load, what="stability-map file")


def map_format(path, comm=None):
    """The ``format`` of an existing record file (None if there is no file or it is not a record archive)."""
    def peek():
        if not os.path.exists(path):
            return None
        try:
            return str(load_npz(path, "file").get("format", ""))
        except RecordFileError:
            return None
    return on_rank0(comm, peek, what="stability-map file")


def map_v1_as_v2(z):
    """The arrays of a ``-1`` file in the layout of this kind, for the figure: its (q, a) records as map points
    (kind 0), a = inf as the uncompressed limit (kind 3); nothing located, no infinite chain."""
    a = np.asarray(z["a"], float)
    n = len(a)
    nan = np.full(n, math.nan)
    out = {k: z[k] for k in ("alpha", "delta0", "masses", "N", "cells_per_pi", "rtol", "tol_rho", "q", "a", "A",
                             "omega", "rho", "outside")}
    out.update(format=MAP_FORMAT_V1, twists=0, locate="none", locate_tol=math.nan,
               kind=np.where(np.isfinite(a), KIND_POINT, KIND_LIMIT), cluster=np.asarray(z["trivial_spread"], float))
    for k in MAP_FIELDS:
        out.setdefault(k, nan)
    return out


def _matching(q, a, qq, aa):
    """The indices of the records at the wavenumber qq (to 1e-12 relative) and amplitude aa (to 1e-10; inf: the
    uncompressed limit)."""
    return np.nonzero((np.abs(q - qq) <= 1e-12 * qq) & ((a == aa) | np.isclose(a, aa, rtol=1e-10, atol=0)))[0]


def _rho_cell(rho, i, tol):
    """A table cell: rho - 1 of the first record of the indices ``i``, with U where unstable; empty without one."""
    return "" if not len(i) else f"{rho[i[0]] - 1:.1e}" + (" U" if rho[i[0]] - 1 > tol else "")


def map_v1_table(z):
    """The table of a ``-1`` file, as its driver wrote it: rho - 1 per (q, a), U where unstable, A = inf last."""
    q, a, rho = (np.asarray(z[k], float) for k in ("q", "a", "rho"))
    spread = np.asarray(z["trivial_spread"], float)
    tol = float(z["tol_rho"])
    qs = list(dict.fromkeys(q.tolist()))
    amps = sorted(set(float(x) for x in a if math.isfinite(x)))
    masses = ", ".join(f"{m:g}" for m in np.asarray(z["masses"], float))
    lines = [f"schema: {MAP_FORMAT_V1}; rho(F_q) (trivial multipliers excluded) of the precompressed waves on N = "
             f"{int(z['N'])} beads, alpha = {float(z['alpha']):g}, delta0 = {float(z['delta0']):g}, masses "
             f"{masses} (repeated); initial data from the Richardson combination of h = pi/{int(z['cells_per_pi'])} "
             f"and pi/{2 * int(z['cells_per_pi'])}; flow rtol {float(z['rtol']):g}; unstable (U) when rho - 1 > "
             f"{tol:g}. Rows: q; columns: a (first sine coefficient; A = ||u||_inf is in the record file), last column "
             "the uncompressed limit A = inf. Each cell: rho - 1 (max trivial spread in the last line).\n"]
    lines += ["| q | " + " | ".join(f"a = {x:g}" for x in amps) + " | A = inf |", "|" + "---|" * (len(amps) + 2)]
    worst = 0.0
    for qq in qs:
        found = [_matching(q, a, qq, x) for x in amps + [math.inf]]
        worst = max([worst] + [float(spread[i[0]]) for i in found if len(i)])
        lines.append(f"| {q_label(qq)} ({qq:.4f}) | " + " | ".join(_rho_cell(rho, i, tol) for i in found) + " |")
    lines.append(f"\nmax trivial spread {worst:.1e}")
    return "\n".join(lines) + "\n"


# the constants of two maps that must agree for their verdicts to be compared (tol_rho may differ: the comparison is
# at the old map's threshold)
COMPARED = ("alpha", "delta0", "masses", "N", "cells_per_pi", "rtol")


def check_comparable(z, old, path):
    """:class:`~hertzpetsc.errors.RecordFileError` naming the first of :data:`COMPARED` that differs between this
    map's constants ``z`` and the ``-1`` map ``old`` (file ``path``): another computation is not compared."""
    for key in COMPARED:
        mine, theirs = np.atleast_1d(np.asarray(z[key], float)), np.atleast_1d(np.asarray(old[key], float))
        if mine.shape != theirs.shape or not np.allclose(mine, theirs, rtol=1e-12, atol=0):
            show = (lambda v: ", ".join(f"{x:g}" for x in v))
            raise RecordFileError(f"-compare {path!r} is a map of another computation: {key} = {show(theirs)} there, "
                                  f"{show(mine)} in this map (compare maps of the same {', '.join(COMPARED)})")


def check_same_chain(zmap, alpha, delta0, path):
    """RecordFileError unless the stability map ``zmap`` (file ``path``, drawn beside a boundary in q) is of the
    monatomic chain of ``alpha`` and ``delta0``: a figure never draws the edges of another chain as this one's."""
    theirs = dict(alpha=float(zmap["alpha"]), delta0=float(zmap["delta0"]),
                  masses=[float(m) for m in np.atleast_1d(zmap["masses"])])
    mine = dict(alpha=float(alpha), delta0=float(delta0), masses=[1.0] * len(theirs["masses"]))
    for key in ("alpha", "delta0", "masses"):
        if not np.allclose(theirs[key], mine[key], rtol=1e-12, atol=0):
            raise RecordFileError(f"stability-map file {given(path)} is a map of another chain: {key} = "
                                  f"{theirs[key]} there, {mine[key]} in this boundary")


def compare_v1(z, old, tol=None, path="the other map"):
    """A Markdown section: the verdicts of this map (arrays ``z``) against a ``-1`` map (``old``, file ``path``) at
    the (q, a) both computed, at the old threshold (``tol``: the old file's tol_rho); rho's agreement where rho - 1 >
    10 tol. Maps of another computation are refused (:func:`check_comparable`)."""
    check_comparable(z, old, path)
    tol = float(old["tol_rho"]) if tol is None else tol
    kind = np.asarray(z["kind"])
    qn, an, rn = (np.asarray(z[k], float) for k in ("q", "a", "rho"))
    usable = (kind == KIND_POINT) | (kind == KIND_LIMIT)
    common, agree, worst, differ = 0, 0, 0.0, []
    for q, a, r in zip(*(np.asarray(old[k], float) for k in ("q", "a", "rho"))):
        i = _matching(qn, an, q, a)
        i = i[usable[i]]
        if not len(i):
            continue
        common += 1
        new = rn[i[0]]
        if (r - 1 > tol) == (new - 1 > tol):
            agree += 1
        else:
            differ.append(f"{q_label(q)}, a = {a:g}: rho - 1 = {r - 1:.1e} before, {new - 1:.1e} now")
        if r - 1 > 10 * tol:
            worst = max(worst, abs(new - r) / (r - 1))
    lines = ["\n### Against the map before issue 23\n",
             f"At the {common} (q, a) computed by both (the dense route's map, kind -1, unstable when rho - 1 > "
             f"{tol:g}): the verdicts at that threshold agree at {agree} of {common}; where rho - 1 > {10 * tol:g}, "
             f"rho - 1 agrees to {worst:.1e} relative." + (" Verdicts that differ: " + "; ".join(differ) + "."
                                                            if differ else "")]
    return "\n".join(lines) + "\n"


def unresolved_mark(r, i):
    """The edges table's mark of an edge whose location failed (``located`` 0: bracketed only); '' else and for
    files before the field."""
    return ", unresolved" if "located" in r and int(r["located"][i]) == 0 else ""


def _side(r, i, certified):
    """The edges tables' last cell: whether an infinite-chain edge's stable side is certified between its twist
    samples (certified, unresolved; 'samples' for a file before the certification; n/a for an N-bead edge)."""
    if int(r["kind"][i]) != KIND_EDGE_INF:
        return "n/a"
    if not certified or "cert_stable" not in r:
        return "samples only"
    return {CERT_STABLE: "certified", CERT_UNRESOLVED: "unresolved"}.get(int(r["cert_stable"][i]), "n/a")


def _largest(values):
    """The largest finite value (nan when there is none: a q of the infinite chain only has no chain spectra)."""
    finite = np.asarray(values, float)
    finite = finite[np.isfinite(finite)]
    return float(finite.max()) if len(finite) else math.nan


def map_table(z):
    """The Markdown tables of a map file's arrays: for this kind the located boundary, then the verdicts; a ``-1``
    file's table as its driver wrote it."""
    if str(z.get("format", "")) == MAP_FORMAT_V1:
        return map_v1_table(z)
    tol = float(z["tol_rho"])
    twists = int(z["twists"])
    kinds, qarr = np.asarray(z["kind"]), np.asarray(z["q"], float)
    spans = {key: unstable_intervals(z, key) for key in (("rho", "rho_inf") if twists else ("rho",))}

    def shown(key, q):
        if q not in spans.get(key, {}):
            return "n/a"
        return "none" if not spans[key][q] else ", ".join(f"[{lo:.5g}, {hi:.5g}]".replace("nan", "?")
                                                          for lo, hi in spans[key][q])

    certified = str(z.get("format", "")) != MAP_FORMAT_V2

    def mark(x, cert=None):                    # '?': no verdict (rho nan: the deflation did not hold)
        if not math.isfinite(float(x)):
            return "?"
        if float(x) - 1 > tol:
            return "U"
        if cert is None:
            return "."
        return ("." if int(cert) == CERT_STABLE else "u") if certified else "s"

    def marks(rho, pts, lim, cert=None):       # the map's amplitudes in order, then the limit after '|'
        c = (lambda i: None) if cert is None else (lambda i: cert[i])
        return "`" + "".join(mark(rho[i], c(i)) for i in pts) + ("|" + mark(rho[lim[0]], c(lim[0])) if len(lim)
                                                                     else "") + "`"

    # one row of each table per q: the located edges, the unstable intervals, the verdicts
    edges, intervals, verdicts = [], [], []
    for q in sorted(set(qarr.tolist())):
        mine = np.abs(qarr - q) <= 1e-12 * q
        r = {k: np.asarray(z[k])[mine] for k in MAP_FIELDS if k in z}
        for i in np.nonzero((r["kind"] == KIND_EDGE) | (r["kind"] == KIND_EDGE_INF))[0]:
            As, Au = float(r["A_stable"][i]), float(r["A_unstable"][i])
            edges.append(f"| {q_label(q)} | {'N' if r['kind'][i] == KIND_EDGE else 'inf'} | {As:.6g} | {Au:.6g} | "
                         f"{abs(Au - As) / min(As, Au):.1e} | {float(r['rho_stable'][i]):.1e} | "
                         f"{float(r['rho_unstable'][i]):.1e} | {float(r['theta_unstable'][i]):.4f} | "
                         f"{'onset' if Au > As else 'offset'}{unresolved_mark(r, i)} | {int(r['evaluations'][i])} | "
                         f"{_side(r, i, certified)} |")
        pts = np.nonzero(r["kind"] == KIND_POINT)[0]
        pts = pts[np.argsort(r["a"][pts])]
        lim = np.nonzero(r["kind"] == KIND_LIMIT)[0]
        gap = np.nonzero(r["kind"] == KIND_GAP)[0]
        gap_A = f"{float(r['A'][gap[0]]):.4f}" if len(gap) else "n/a"
        cert = r.get("cert_inf", np.full(len(r["kind"]), CERT_NONE))
        points = (r["kind"] == KIND_POINT) | (r["kind"] == KIND_LIMIT)
        covered = r["modulation_inf"][points & (cert == CERT_STABLE)] if "modulation_inf" in r else []
        longest = f"{float(np.min(covered)):.3g}" if len(covered) else "n/a"
        intervals.append(f"| {q_label(q)} | {gap_A} | {shown('rho', q)} | {shown('rho_inf', q)} | {longest} |")
        verdicts.append(f"| {q_label(q)} | {gap_A} | {marks(r['rho'], pts, lim)} | "
                        + (marks(r["rho_inf"], pts, lim, cert) if twists else "n/a")
                        + f" | {_largest(r['cluster'][pts]):.1e} | {_largest(r['eigvec'][pts]):.1e} |")
    amps = sorted(set(float(a) for a, k in zip(np.asarray(z["a"]), kinds) if k == KIND_POINT))
    bracketed = "located" in z and bool(np.any(np.asarray(z["located"]) == 0))     # a location that failed
    unresolved = bool(np.any(((kinds == KIND_POINT) | (kinds == KIND_LIMIT)) & ~np.isfinite(np.asarray(z["rho"], float))))
    lines = [f"schema: {str(z.get('format', MAP_FORMAT))}; alpha = {float(z['alpha']):g}, "
             f"delta0 = {float(z['delta0']):g}, masses "
             f"{', '.join(f'{m:g}' for m in np.asarray(z['masses']))} (repeated), N = {int(z['N'])}; waves: "
             f"Richardson of h = pi/{int(z['cells_per_pi'])} and pi/{2 * int(z['cells_per_pi'])}; flow rtol "
             f"{float(z['rtol']):g}; symmetry multipliers deflated; unstable when rho - 1 > {tol:g}; infinite chain: "
             + ((f"cell twists with a bead-level Bloch step <= pi/{twists}, maxima refined; " + (
                 f"a stable verdict certified between its twist samples (any band of instability there has rho - 1 "
                 f"<= {CERT_MARGIN * tol:g} or the located maximum of a weaker band: slow.certify_twists) for "
                 f"modulations up to the beads of the column 'longest modulation' (the shortest coverage of the q's "
                 f"stable verdicts)" if certified else "verdicts at the twist samples only (a file of kind "
                 f"{MAP_FORMAT_V2}, before the twist certification)")) if twists else "not computed")
             + f"; boundary located by bisection in log a, asked to a bracket of {float(z['locate_tol']):g} "
             f"(relative, in a); "
             + _brackets(z["A_stable"], z["A_unstable"], (kinds == KIND_EDGE) | (kinds == KIND_EDGE_INF), "A",
                         np.asarray(z["located"]) == 0 if "located" in z else None)
             + ".\n",
             "### Located boundary\n",
             "Each row: an amplitude where the verdict changes, between A (stable side) and A (unstable side); "
             "rho - 1 of the chain (N beads or the infinite chain) at both ends: the multipliers' distance to the unit "
             "circle on each side; Theta: the sector angle (N) or cell twist (infinite chain) of the unstable mode; "
             "the edge is an onset (stable below, unstable above) or an offset"
             + (" ('unresolved': a trial of its bisection failed, the edge only bracketed by the two A)" if bracketed
                else "") + ".\n",
             "| q | chain | A stable | A unstable | relative width | rho - 1 stable side | rho - 1 unstable side | "
             "Theta | edge | bisections | stable side between twists |",
             "|---|---|---|---|---|---|---|---|---|---|---|", *edges,
             "\n### Unstable intervals\n",
             "Per q, the intervals of A = ||u||_inf where the wave is unstable, between located edges (each within "
             "its bracket: widths above); 0: from below the smallest map amplitude; inf: up to the uncompressed "
             "limit; ?: an edge not located (a window found between two edges of the same kind, or a change of the "
             "verdict between the largest map amplitude and the uncompressed limit"
             + (", or an unresolved edge: its bracket above" if bracketed else "") + ").\n",
             "| q | A_gap | N beads | infinite chain | longest modulation of the stable verdicts (beads) |",
             "|---|---|---|---|---|",
             *intervals,
             "\n### Verdicts on the map\n",
             f"Amplitudes a (first sine coefficient) of the map: {', '.join(f'{a:.4g}' for a in amps)}. Per q, one "
             "character per amplitude, increasing: '.' stable, 'U' unstable (rho - 1 > tol_rho)"
             + (("; infinite chain: '.' stable and certified between the twist samples, 'u' unresolved (stable at "
                 "every twist sample, the certification did not close)") if certified and twists else
                "; infinite chain: 's' stable at the twist samples (not certified between them)" if twists else "")
             + (f", '?' no verdict (the deflation's eigenvector residual above {EIGVEC_MAX:g})" if unresolved else "")
             + ", then the uncompressed limit after '|'; A_gap: the located gap opening; largest deflated cluster |mu - 1| and "
             "eigenvector residual over the row (what the deflation removed, and how exact it was).\n",
             "| q | A_gap | N beads | infinite chain | cluster (N) | eigenvector residual |",
             "|---|---|---|---|---|---|", *verdicts]
    return "\n".join(lines) + "\n"
