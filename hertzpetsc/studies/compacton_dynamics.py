"""Does the window spectrum (:mod:`hertzpetsc.studies.compacton_stability`) predict the dynamics (section 3.3,
Discussion)? :class:`CompactonDynamics` puts an exact compacton on a long free chain, perturbs it and splits the
moving window's deviation with the Jordan vectors. File ``hertzpetsc-compacton-dynamics-1``, its columns declared
in :data:`DYNAMICS_KIND`.
"""
from __future__ import annotations

import math
import time
from typing import Iterator, Mapping, Optional, Sequence

import numpy as np
from petsc4py import PETSc

from ..chain import ChainIntegrator, IntegrationTolerances
from ..compacton_spectrum import eigenvector, window_spectrum
from ..compacton_window import CompactonWindow, WindowChain, embed
from ..errors import ParameterError, check_integer, check_real
from ..model import ChainSpec, LatticeModel
from ..resources import chain_seconds, check_chain_memory, check_work
from ..options import inserted_options
from ..records import Column, Kind, on_rank0, read_kind
from ..roles import uses
from .base import Study
from .compacton_stability import STABILITY_KIND, exact_compacton, fmt_multiplier, q_text

DYNAMICS_FORMAT = "hertzpetsc-compacton-dynamics-1"
DYNAMICS_PREFIX = "cdyn_"
DYNAMICS_TOLERANCES = IntegrationTolerances(rtol=1e-13, atol=1e-16)
# Seconds per bead and unit of time of these flows (max-norm error control, rtol 1e-13, about 93 steps per unit):
# 164.4 s for 2100 beads over 1000 units (results/compacton_dynamics.md, q = 0.87965, mode, 1 rank)
DYNAMICS_SECONDS = 7.8e-5


def dynamics_integrator(chain, tolerances=DYNAMICS_TOLERANCES, prefix=DYNAMICS_PREFIX):
    """The chain TS under ``prefix`` with the adaptor's error norm defaulting to the max norm
    (``-<prefix>ts_adapt_wnormtype infinity``): the RMS norm of a mostly resting long chain lets local errors of
    the few moving beads through. The default is inserted for this set-up only (a given value wins)."""
    with inserted_options(prefix, {"ts_adapt_wnormtype": "INFINITY"}):
        return ChainIntegrator(chain, tolerances, prefix)


def stability_records(path: str, alpha: float, qs: Sequence[float], comm: PETSc.Comm) -> list[dict]:
    """The records of the compacton stability file ``path`` at ``alpha`` and each of ``qs`` (read on rank 0; a
    ParameterError naming -q and what the file has where it has no compacton)."""
    def read():
        data = read_kind(path, STABILITY_KIND, "compacton stability file")
        return {k: data[k] for k in ("alpha", "q", "gap", "residual", "iterations", "dominant", "state")}
    data = on_rank0(comm, read, what=f"cannot read compacton stability file {path!r}")
    out = []
    for q in qs:
        hit = [i for i in range(len(data["q"])) if abs(data["alpha"][i] - alpha) < 1e-9 and
               abs(data["q"][i] - q) <= 1e-9 * max(q, 1e-3)]
        if not hit:
            have = sorted({round(float(a), 4) for a in data["alpha"]})
            qa = sorted(float(x) for a, x in zip(data["alpha"], data["q"]) if abs(a - alpha) < 1e-9)
            raise ParameterError("-q", q, f"the stability file has no compacton there (alpha in {have}; at alpha = "
                                          f"{alpha:g}: {len(qa)} q" + (f" in [{qa[0]:.6g}, {qa[-1]:.6g}])" if qa
                                                                      else ")"))
        out.append({k: data[k][hit[0]] for k in data})
    return out


DYNAMICS_KIND = Kind(DYNAMICS_FORMAT, (
    Column("alpha", "Hertz exponent", constant=True),
    Column("N", "beads of the free chain", "count", np.int64, "d", constant=True),
    Column("n0", "starting bead", "count", np.int64, "d", constant=True),
    Column("travel", "beads travelled (T)", "count", np.int64, "d", constant=True),
    Column("amplitude", "size of the perturbation, relative to D and v_peak", constant=True),
    Column("rtol", "flow tolerance (prefix `-cdyn_`)", constant=True),
    Column("M", "window beads", "count", np.int64, "d", constant=True),
    Column("stability_sha256", "sha256 of the stability file the compactons were read from (absent from files "
           "written before it)", "", str, "s", constant=True, optional=True),
    Column("solver_options", "number-changing options under `-cdyn_`, `-cwin_` (absent from files written before "
           "it)", "", str, "s", constant=True, optional=True),
    Column("q", "wavenumber"),
    Column("kind", "`mode` (the mu_3 eigenvector) or `noise` (Gaussian)", "", str, "s"),
    Column("mu3", "the dominant nontrivial multiplier", "1", complex),
    Column("rate", "fitted decay rate of \\|rest\\| per bead, over k = rate_first .. rate_last", format=".4f"),
    Column("rate_first", "first k of the fit", "count", format=".0f"),
    Column("rate_last", "last k of the fit", "count", format=".0f"),
    Column("rest_floor", "median of \\|rest\\| over k >= T/2", format=".1e"),
    Column("rest_max_late", "max of \\|rest\\| over k >= 50", format=".1e"),
    Column("a_end", "the phase a(T)", format=".3e"),
    Column("a_predicted", "its linear prediction a_10 + (T - 10) b_10", format=".3e"),
    Column("b_start", "the speed coefficient b at k = 10", format=".3e"),
    Column("b_end", "the speed coefficient b at T", format=".3e"),
    Column("dist_end", "\\|delta\\|(T), relative", format=".1e"),
    Column("behind_v", "max \\|v\\| of the beads left behind / v_peak", format=".1e"),
    Column("seconds", "wall time", "s", format=".1f"),
    Column("steps", "TS steps", "count", np.int64, "d"),
    *(Column(k, f"the series {k} over k = 0 .. T: delta_k = a v1 + b v2 + rest (Jordan vectors of mu = 1), max "
             "norms relative", shape="T+1") for k in ("rest", "a", "b", "dist")),
    Column("deviation", "\\|rest\\| per window bead (moving frame)", shape="T+1, M"),
))


class CompactonDynamics(Study):
    """Exact compactons (stability records, one alpha) on a free chain of N beads in gap-lattice coordinates
    (:func:`WindowChain`, TS prefix ``cdyn_``), perturbed by ``amplitude`` times the least-stable mode ('mode')
    or Gaussian noise ('noise') on the window (relative to D for positions and v_peak for velocities); after each
    unit of time (one bead of travel) the window W_k at beads n0 + k.. is compared with Y*:
    delta = a v1 + b v2 + rest (Jordan vectors). Linear prediction: b constant, a_k = a_0 + k b, and
    |rest| ~ |mu_3|^k down to the flow's floor. Records keyed by (q, kind); ``source``: the stability file the
    records were read from (its content is part of the identity)."""

    FORMAT, FIELDS, DTYPES, COLUMNS = DYNAMICS_FORMAT, DYNAMICS_KIND.fields, DYNAMICS_KIND.dtypes, DYNAMICS_KIND
    ROLES = uses("cdyn_", "cwin_")
    WHAT = "compacton dynamics file"

    def __init__(self, records: Sequence[Mapping], model: LatticeModel, comm: Optional[PETSc.Comm] = None,
                 output: Optional[str] = None, mode: str = "new", N: int = 2100, n0: int = 50, travel: int = 1000,
                 amplitude: float = 1e-8, kinds: Sequence[str] = ("mode", "noise"), seed: int = 12345,
                 tolerances: IntegrationTolerances = DYNAMICS_TOLERANCES, source: str = "") -> None:
        if not records:
            raise ParameterError("-q", "", "no compacton to run")
        self.cases = [exact_compacton(r) for r in records]
        self.mu3 = {round(float(r["q"]), 12): complex(r["dominant"][0]) for r in records}
        self.alpha = float(records[0]["alpha"])
        M = self.cases[0].M
        N, n0 = check_integer("N", N, 10, "the beads of the free chain"), check_integer("n0", n0, 1, "the first bead")
        travel = check_integer("travel", travel, 1, "the units of time (beads of travel)")
        amplitude = check_real("amplitude", amplitude, "the perturbation (relative to D and v_peak; the split with "
                               "the Jordan vectors is linear)", 0.0, 1.0)
        if n0 < 1 or N < n0 + travel + M + 2:
            raise ParameterError("-N", N, f"the chain must hold n0 + travel + M + 2 = {n0 + travel + M + 2} beads")
        for kind in kinds:
            if kind not in ("mode", "noise"):
                raise ParameterError("-kinds", kind, "each must be mode or noise")
        runs = len(self.cases) * len(kinds)
        check_work("travel", travel, chain_seconds(N, travel * runs, DYNAMICS_SECONDS),
                   f"{runs} run(s) of {N} beads over {travel} units of time")
        super().__init__(None, comm, output, mode)
        self.source = source
        check_chain_memory(N, self.comm)
        self.model, self.N, self.n0, self.travel = model, int(N), int(n0), int(travel)
        self.amplitude, self.kinds, self.seed, self.tolerances = float(amplitude), list(kinds), seed, tolerances
        self.window = CompactonWindow(model, M, PETSc.COMM_SELF)
        chain = WindowChain(ChainSpec(model, self.N, "free"), self.comm, 0.0)
        self.chain, self.integ = chain, dynamics_integrator(chain, tolerances)
        self.SHAPES = dict({k: (self.travel + 1,) for k in ("rest", "a", "b", "dist")}, deviation=(self.travel + 1, M))

    @classmethod
    def from_stability(cls, path: str, alpha: float, qs: Sequence[float], comm: Optional[PETSc.Comm] = None,
                       output: Optional[str] = None, mode: str = "new", N: int = 2100, n0: int = 50,
                       travel: int = 1000, amplitude: float = 1e-8,
                       kinds: Sequence[str] = ("mode", "noise")) -> CompactonDynamics:
        """The study of the exact compactons of the stability file ``path`` at ``alpha`` and ``qs``
        (:func:`stability_records`; the file's content is part of the identity)."""
        comm = comm if comm is not None else PETSc.COMM_WORLD
        return cls(stability_records(path, alpha, qs, comm), LatticeModel.hertz(alpha), comm, output, mode, N, n0,
                   travel, amplitude, kinds, source=path)

    def constants(self) -> dict:
        return dict(alpha=self.alpha, N=self.N, n0=self.n0, travel=self.travel, amplitude=self.amplitude,
                    rtol=self.tolerances.rtol, M=self.cases[0].M)

    def inputs(self) -> dict:
        return dict(stability=self.source)

    def perturbation(self, kind: str, scale: np.ndarray, V: np.ndarray) -> np.ndarray:
        M = len(scale) // 2
        if kind == "noise":
            p = np.random.default_rng(self.seed).standard_normal(2 * M) * scale
        else:
            p = np.real(V)
        return (self.amplitude * p / np.max(np.abs(p / scale))).reshape(M, 2)

    def run(self) -> Iterator[dict]:
        self.open()
        done = {(round(float(r["q"]), 12), str(r["kind"])) for r in self.store.records}
        for ex in self.cases:
            todo = [k for k in self.kinds if (round(ex.q, 12), k) not in done]
            if todo:
                yield from self._run_case(ex, todo)

    def _run_case(self, ex, kinds):
        w, M = self.window, ex.M
        J, _, _, _, rest_mu, jc = window_spectrum(w, ex.Y, ex.gap)
        v3 = eigenvector(J, rest_mu[0])
        scale = np.tile([ex.D, ex.v_peak], M)
        ystar = ex.Y.ravel()
        self.chain.gap = ex.gap
        mu3 = self.mu3[round(ex.q, 12)]
        for kind in kinds:
            X = self.chain.create_state()
            self.chain.set_from_array(X, embed(ex.Y + self.perturbation(kind, scale, v3), self.N, self.n0))
            series = {k: np.zeros(self.travel + 1) for k in ("rest", "a", "b", "dist")}
            deviation = np.zeros((self.travel + 1, M))
            t0 = time.perf_counter()
            steps = 0
            try:
                for k in range(self.travel + 1):
                    if k:
                        steps += self.integ.integrate(X, k - 1.0, float(k),
                                                      dt=self.integ.initial_step if k == 1 else None)
                    full = self.chain.gather(X)
                    d = full[self.n0 + k:self.n0 + k + M].ravel() - ystar
                    a, b = jc.u1 @ d, jc.u2 @ d
                    r = (d - a * jc.v1 - b * jc.v2) / scale
                    series["rest"][k], series["a"][k], series["b"][k] = np.max(np.abs(r)), a, b
                    series["dist"][k] = np.max(np.abs(d / scale))
                    deviation[k] = np.max(np.abs(r.reshape(M, 2)), axis=1)
                behind = float(np.max(np.abs(full[:self.n0 + self.travel, 1]))) / ex.v_peak
            finally:
                X.destroy()
            row = dict(q=ex.q, kind=kind, mu3=mu3, behind_v=behind, seconds=time.perf_counter() - t0,
                       steps=steps, deviation=deviation, **series, **self.fit(series))
            yield self.store.append(row)

    def fit(self, s: Mapping[str, np.ndarray]) -> dict:
        """Decay rate of |rest| over k >= 1 while it stays above 30 x its floor (median over k in [T/2, T]), at most
        25 points; the late maximum of |rest|; the phase a(T) against a_10 + (T - 10) b_10."""
        rest, a, b, T = s["rest"], s["a"], s["b"], self.travel
        floor = float(np.median(rest[T // 2:]))
        stop = next((k for k in range(1, T + 1) if rest[k] < 30 * floor), T + 1)
        ks = np.arange(1, stop)[:25]
        rate = float(np.polyfit(ks, np.log(rest[ks]), 1)[0]) if len(ks) >= 3 else math.nan
        k10 = min(10, T)
        return dict(rate=rate, rate_first=float(ks[0]) if len(ks) else math.nan,
                    rate_last=float(ks[-1]) if len(ks) else math.nan, rest_floor=floor,
                    rest_max_late=float(np.max(rest[min(50, T):])), a_end=float(a[-1]),
                    a_predicted=float(a[k10] + (T - k10) * b[k10]), b_start=float(b[k10]), b_end=float(b[-1]),
                    dist_end=float(s["dist"][-1]))

    def table(self) -> str:
        M = self.cases[0].M
        lines = [f"alpha = {self.alpha:g}: exact compactons (M = {M} window) on a free chain of {self.N} beads at "
                 f"bead {self.n0}, perturbed by {self.amplitude:g} x (mode: the eigenvector of the dominant "
                 f"nontrivial multiplier mu_3; noise: Gaussian, seed {self.seed}) relative to D and v_peak, "
                 f"travelling {self.travel} beads (TS -cdyn_, rtol {self.tolerances.rtol:g}, max-norm error "
                 "control). delta_k = W_k - Y* = a v1 + b v2 + rest (Jordan vectors of mu = 1); prediction: "
                 "|rest| ~ |mu_3|^k (rate ln|mu_3| per bead = per script-T), b constant, a_k = a_10 + (k - 10) b_10."
                 " |rest| and |delta| relative (max over the window). Noise also gives the resting beads ahead of the "
                 "zone velocities: they drift freely until the zone reaches them, so |rest| first grows about linearly "
                 "for up to M beads (the window map's nilpotent transport part, no multiplier) and only then decays by "
                 "|mu_3| per bead; its rate fitted from k = 1 mixes the two.\n",
                 "| q | perturbation | mu_3 | fitted rate of \\|rest\\| (k range) | ln\\|mu_3\\| | ratio | floor of "
                 "\\|rest\\| (median, k >= T/2) | max \\|rest\\|, k >= 50 | b at k = 10 -> T | a(T) / predicted | "
                 "\\|delta\\|(T) | max \\|v\\| left behind / v_peak | TS steps | s |",
                 "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in sorted(self.store.records, key=lambda r: (-float(r["q"]), str(r["kind"]))):
            ln3 = math.log(abs(r["mu3"]))
            lines.append(DYNAMICS_KIND.row(
                r, q_text(float(r["q"])), "{kind}", fmt_multiplier(complex(r["mu3"])),
                "{rate} ({rate_first}-{rate_last})", f"{ln3:.4f}", f"{r['rate'] / ln3:.4f}", "{rest_floor}",
                "{rest_max_late}", "{b_start} -> {b_end}", "{a_end} / {a_predicted}", "{dist_end}", "{behind_v}",
                "{steps}", "{seconds}"))
        return "\n".join(lines) + "\n"

    def destroy(self) -> None:
        self.integ.destroy()
        self.chain.destroy()
        self.window.destroy()
