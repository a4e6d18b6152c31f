"""Spectral stability of isolated compactons (paper, section 3.3 and the Discussion's open question), on the
travelling window of :mod:`hertzpetsc.compacton_window`.

:class:`CompactonStabilityScan` follows the exact compacton of each alpha from the largest branch q with
F(q) >= 1 down through the requested q (secant continuation in q) to the solitary wave (Delta = 0, eq. adr),
and records per (alpha, q): the refined state, its residual under the refinement's flow and under an
independent flow (another Runge-Kutta pair and tolerance), all 2M window multipliers (LAPACK), the Jordan pair
at 1 (mean, split, J v1 = v1, solvability of (J - 1) v2 = v1), the dominant nontrivial multipliers, the unstable
ones, the change of the dominant multipliers when M is doubled, and SLEPc's dominant multipliers on the weighted
shell against the dense ones. File ``hertzpetsc-compacton-stability-1`` (npz): constants M, rear, eta, nev,
tol_unstable, rtol; per record: alpha, q, gap, D, residual, residual_check, iterations, jordan_mean, jordan_split,
jordan_translation, jordan_generalized, max_nontrivial, unstable, doubling_change, slepc_change,
slepc_products, slepc_nev, core_first, core_last, seconds, multipliers (2M, all, by modulus), dominant (NDOM
nontrivial), state (M, 2).

:class:`CompactonDynamics` puts an exact compacton on a long free chain (TS prefix ``cdyn_``, max-norm error
control by default), perturbs it by ``amplitude`` times its least-stable mode or by noise, and splits the
moving window's deviation delta_k = W_k - Y* with the Jordan vectors: delta = a v1 + b v2 + rest. File
``hertzpetsc-compacton-dynamics-1``: constants alpha, N, n0, travel, amplitude, rtol, M; per record: q, kind,
mu3, rate (fitted decay of |rest| per bead), rate_first, rate_last, rest_floor, rest_max_late, a_end,
a_predicted, b_start, b_end, dist_end, behind_v, seconds, steps, and the series rest, a, b, dist (travel + 1)
and deviation (travel + 1, M).

:class:`CompactonPairs` is the two-compacton test of section 3.3 (eq. extens2) with each compacton either the
unrefined branch profile or refined at the same gap, to locate the source of the 2-compacton error. File
``hertzpetsc-compacton-pairs-1``: constants alpha, q, h, spacing, travel, M, N, gap; per record: case, rear,
front, error_x, error_v, debris_v, seconds.
"""
import math
import time

import numpy as np
from petsc4py import PETSc

from ..chain import ChainIntegrator, IntegrationTolerances
from ..compacton_window import (DEFAULT_ETA, DEFAULT_REAR, WINDOW_PREFIX, WINDOW_TOLERANCES, CompactonRefiner,
                                CompactonWindow, ExactCompacton, WindowChain, WindowStability,
                                chain_from_window, embed, guess_from_branch, jordan_check, sorted_eig,
                                split_jordan_pair)
from ..errors import ParameterError
from ..model import ChainSpec
from ..records import NpzRecords
from .dealing import dealt

STABILITY_FORMAT = "hertzpetsc-compacton-stability-1"
DYNAMICS_FORMAT = "hertzpetsc-compacton-dynamics-1"
PAIRS_FORMAT = "hertzpetsc-compacton-pairs-1"
CHECK_PREFIX = "ccheck_"
DYNAMICS_PREFIX = "cdyn_"
# the independent flow of the residual check: another embedded pair (Verner 7(6)) at another tolerance
CHECK_TOLERANCES = IntegrationTolerances(rtol=1e-13, atol=1e-16)
DYNAMICS_TOLERANCES = IntegrationTolerances(rtol=1e-13, atol=1e-16)
NDOM = 6
TOL_UNSTABLE = 1e-8
DEFAULT_QS = ("1.5, 1.3, 1.1, 3*pi/10, 7*pi/25, 0.7, 9*pi/50, 0.45, pi/10, 0.2, pi/25, pi/50, pi/100, pi/200, "
              "pi/400, pi/800")
FIELDS = ("alpha", "q", "gap", "D", "residual", "residual_check", "iterations", "jordan_mean", "jordan_split",
          "jordan_translation", "jordan_generalized", "max_nontrivial", "unstable", "doubling_change",
          "slepc_change", "slepc_products", "slepc_nev", "core_first", "core_last", "seconds")


def top_wavenumber(branch):
    """The largest branch q with F(q) >= 1 (a compacton exists: eq. extens), and q_k."""
    F = branch.column("F")
    ok = F >= 1.0
    if not ok.any():
        raise ParameterError("branch", "no point with F >= 1", "the branch must reach q <= q_k (F(q) >= 1)")
    return float(branch.q[ok].max()), float(branch.q_k())


def scan_sequence(branch, qs, solitary=True):
    """The q of one alpha in computing order: the branch start, then ``qs`` (each <= q_k, else ParameterError)
    by decreasing q, then 0 (the solitary wave)."""
    q_top, q_k = top_wavenumber(branch)
    for q in qs:
        if not (0 < q <= q_k):
            raise ParameterError("-q", q, f"a compacton needs 0 < q <= q_k = {q_k:.6f} at alpha = {branch.alpha:g} "
                                          "(F(q) = 2 ell/q >= 1, eq. extens; q = 0 is -solitary)")
    rest = sorted((q for q in qs if abs(q - q_top) > 1e-12), reverse=True)
    return [q_top] + rest + ([0.0] if solitary else [])


def _key(alpha, q):
    return (round(float(alpha), 10), round(float(q), 12))


class CompactonStabilityScan:
    """Exact compactons and their window spectra against q for each branch (alpha) (module docstring).

    Each (alpha, q) is computed on one rank (COMM_SELF), the alphas of a continuation step dealt to the ranks, so
    the records do not depend on the number of ranks. Prefixes: ``cwin_`` (the window flows), ``ccheck_`` (the
    independent residual flow), ``cstab_`` (the EPS: ``-cstab_eps_*``)."""

    def __init__(self, branches, qs, comm, output, mode="new", M=18, rear=DEFAULT_REAR, nev=3, eta=DEFAULT_ETA,
                 solitary=True, tol_unstable=TOL_UNSTABLE, tolerances=WINDOW_TOLERANCES):
        if not branches:
            raise ParameterError("-branches", "", "give at least one branch file")
        self.branches = {round(b.alpha, 10): b for b in branches}
        if len(self.branches) != len(branches):
            raise ParameterError("-branches", [b.alpha for b in branches], "one branch per alpha")
        self.sequences = {a: scan_sequence(b, qs, solitary) for a, b in self.branches.items()}
        self.comm, self.M, self.rear, self.nev, self.eta = comm, int(M), int(rear), int(nev), float(eta)
        self.tol_unstable, self.tolerances = tol_unstable, tolerances
        # configure every solver now (bad options and bad sizes fail before any computation)
        for a, b in self.branches.items():
            guess_from_branch(b.point(self.sequences[a][0]), self.M, self.rear, b.q_k())
        probe = CompactonWindow(branches[0].model, self.M, PETSc.COMM_SELF, tolerances, WINDOW_PREFIX)
        try:
            CompactonWindow(branches[0].model, self.M, PETSc.COMM_SELF, CHECK_TOLERANCES, CHECK_PREFIX,
                            "7vr").destroy()
            WindowStability(probe, self.nev, self.eta).destroy()
        finally:
            probe.destroy()
        self._open = lambda: NpzRecords(output, STABILITY_FORMAT,
                                        dict(M=self.M, rear=self.rear, eta=self.eta, nev=self.nev,
                                             tol_unstable=tol_unstable, rtol=tolerances.rtol),
                                        dict(M=self.M, rear=self.rear, eta=self.eta, rtol=tolerances.rtol),
                                        FIELDS + ("multipliers", "dominant", "state"), comm, mode,
                                        dtypes={"multipliers": complex, "dominant": complex, "iterations": np.int64,
                                                "unstable": np.int64, "slepc_products": np.int64,
                                                "slepc_nev": np.int64, "core_first": np.int64, "core_last": np.int64},
                                        shapes={"multipliers": (2 * self.M,), "dominant": (NDOM,),
                                                "state": (self.M, 2)}, what="compacton stability file")
        self.store = None
        self._tools = {}

    def open(self):
        if self.store is None:
            self.store = self._open()
        return self

    # --- per-rank solvers (COMM_SELF), one set per alpha ---------------------------------------------------------
    def _solvers(self, alpha):
        if alpha not in self._tools:
            model = self.branches[alpha].model
            w = CompactonWindow(model, self.M, PETSc.COMM_SELF, self.tolerances, WINDOW_PREFIX)
            w2 = CompactonWindow(model, 2 * self.M, PETSc.COMM_SELF, self.tolerances, WINDOW_PREFIX)
            chk = CompactonWindow(model, self.M, PETSc.COMM_SELF, CHECK_TOLERANCES, CHECK_PREFIX, "7vr")
            self._tools[alpha] = (w, w2, chk, CompactonRefiner(w), CompactonRefiner(w2))
        return self._tools[alpha]

    def _previous(self, alpha, i):
        """The ExactCompactons of the (up to two) preceding q of this alpha, from the records."""
        seq = self.sequences[alpha]
        byq = {_key(r["alpha"], r["q"]): r for r in self.store.records}
        out = []
        for q in seq[max(0, i - 2):i]:
            r = byq[_key(alpha, q)]
            out.append(ExactCompacton(float(r["q"]), float(r["gap"]), np.array(r["state"]), float(r["residual"]),
                                      int(r["iterations"])))
        return out

    def compute(self, item):
        """The record of (alpha, index in its sequence)."""
        alpha, i = item
        t0 = time.perf_counter()
        w, w2, chk, refiner, refiner2 = self._solvers(alpha)
        branch = self.branches[alpha]
        q = self.sequences[alpha][i]
        if i == 0:
            Y, gap = guess_from_branch(branch.point(q), self.M, self.rear, branch.q_k())
            exact = refiner.refine(Y, gap, q)
        else:
            exact = refiner.continue_to(self._previous(alpha, i), q)
        Y, gap = exact.Y, exact.gap
        core = w.core(Y, gap)
        # a compacton's zone must leave resting beads on both sides; the solitary wave's doubly exponential tails
        # reach the window's ends (above 1e-13 of the peak compression): its truncation is the 2M change
        if q > 0 and (core[0] < 1 or core[-1] > self.M - 3):
            raise ParameterError("-M", self.M, f"at alpha = {alpha:g}, q = {q:.6g} the compression zone reaches "
                                 f"beads {core[0]}..{core[-1]} of the window: enlarge -M or change -rear")
        _, J, _ = w.jacobian(Y, gap)
        lam, _ = sorted_eig(J)
        mean, split, rest = split_jordan_pair(lam)
        jc = jordan_check(w, J, Y, gap)
        dominant = rest[:NDOM]
        # M doubled: the same compacton, embedded and re-refined, its dominant multipliers
        e2 = refiner2.refine(embed(Y, 2 * self.M, self.M // 2), gap, q)
        lam2 = sorted_eig(w2.jacobian(e2.Y, e2.gap)[1])[0]
        mean2, _, rest2 = split_jordan_pair(lam2)
        k = min(3, len(dominant))
        doubling = max(abs(mean2 - mean), float(np.max(np.abs(rest2[:k] - dominant[:k]))))
        # SLEPc on the weighted shell: the multipliers above 2 exp(-eta), at most nev
        above = int(np.sum(np.abs(rest) > 2 * math.exp(-self.eta)))
        nev = max(2, min(self.nev, 2 + above))
        stab = WindowStability(w, nev, self.eta)
        try:
            sl = stab.solve(Y, gap, 0.5 * (core[0] + core[-1]))
        finally:
            stab.destroy()
        s_mean, _, s_rest = split_jordan_pair(sl.values[:max(nev, 2)])
        slepc_change = max([abs(s_mean - mean)] + [float(np.min(np.abs(lam - v))) for v in s_rest])
        unstable = int(np.sum(np.abs(rest) > 1 + self.tol_unstable))
        return dict(alpha=alpha, q=q, gap=gap, D=exact.D, residual=exact.residual,
                    residual_check=chk.residual(Y, gap), iterations=exact.iterations, jordan_mean=mean.real,
                    jordan_split=split, jordan_translation=jc.translation, jordan_generalized=jc.generalized,
                    max_nontrivial=float(abs(rest[0])), unstable=unstable, doubling_change=doubling,
                    slepc_change=slepc_change, slepc_products=sl.products, slepc_nev=nev, core_first=int(core[0]),
                    core_last=int(core[-1]), seconds=time.perf_counter() - t0, multipliers=lam,
                    dominant=np.pad(dominant, (0, NDOM - len(dominant))), state=Y)

    def run(self):
        """Compute every (alpha, q) not in the file, by continuation steps; yields each record after saving it."""
        self.open()
        done = {_key(r["alpha"], r["q"]) for r in self.store.records}
        depth = max(len(s) for s in self.sequences.values())
        for i in range(depth):
            items = [(a, i) for a, s in self.sequences.items() if i < len(s) and _key(a, s[i]) not in done]
            if not items:
                continue
            costs = [1.0 + 4.0 * (self.sequences[a][i] == 0) for a, _ in items]
            for _, row in dealt(items, costs, self.comm, self.compute):
                self.store.append(row)
                yield row

    def destroy(self):
        for tools in self._tools.values():
            for t in tools[:3]:
                t.destroy()
        self._tools = {}

    # --- output ---------------------------------------------------------------------------------------------
    def rows(self):
        return sorted(self.store.records, key=lambda r: (float(r["alpha"]), -float(r["q"]) if r["q"] else 1.0))

    def record(self, alpha, q):
        for r in self.store.records:
            if _key(r["alpha"], r["q"]) == _key(alpha, q):
                return r
        raise ParameterError("q", q, f"not in the compacton stability file at alpha = {alpha:g}")

    def table(self):
        lines = [f"Exact compactons (c = 1) on a window of M = {self.M} beads ({self.rear} at rest behind the "
                 f"compression zone at the start), window map G = shift o Phi_1 (hertzpetsc.compacton_window). "
                 f"Residual: max|G(Y) - Y| under the refinement's flow (8vr, rtol {self.tolerances.rtol:g}) / under "
                 f"an independent flow (7vr, rtol {CHECK_TOLERANCES.rtol:g}). Multipliers: LAPACK on the "
                 f"2M x 2M Jacobian; the Jordan pair at 1 is given by its mean (split in brackets; J v1 = v1 and "
                 f"(J - 1) v2 = v1 residuals); 'dominant' are the nontrivial ones; unstable: |mu| > 1 + "
                 f"{self.tol_unstable:g}. 2M: max change of the pair's mean and the 3 dominant multipliers when "
                 f"the window is doubled (re-refined). SLEPc: Krylov-Schur on the weighted shell (eta = {self.eta:g},"
                 f" nev multipliers above 2 exp(-eta)), max distance to the dense ones (nev, products). q = 0 is the "
                 "solitary wave (Delta = 0).\n",
                 "| alpha | q | Delta | D | closed zone (beads) | residual / check | GN its | Jordan pair mean "
                 "(split) | J v1 = v1, (J-1) v2 = v1 | dominant nontrivial mu_3, mu_4, mu_5 | max nontrivial \\|mu\\| "
                 "| unstable | 2M change | SLEPc - dense (nev, products) | s |",
                 "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in self.rows():
            dom = ", ".join(_fmt(v) for v in r["dominant"][:3])
            lines.append(f"| {float(r['alpha']):g} | {_qtext(float(r['q']))} | {float(r['gap']):.6g} | "
                         f"{float(r['D']):.6f} | {int(r['core_first'])}-{int(r['core_last'])} | "
                         f"{float(r['residual']):.1e} / {float(r['residual_check']):.1e} | {int(r['iterations'])} | "
                         f"{float(r['jordan_mean']):.12f} ({float(r['jordan_split']):.0e}) | "
                         f"{float(r['jordan_translation']):.0e}, {float(r['jordan_generalized']):.0e} | {dom} | "
                         f"{float(r['max_nontrivial']):.6f} | {int(r['unstable']) or 'none'} | "
                         f"{float(r['doubling_change']):.1e} | {float(r['slepc_change']):.1e} "
                         f"({int(r['slepc_nev'])}, {int(r['slepc_products'])}) | {float(r['seconds']):.1f} |")
        return "\n".join(lines) + "\n"

    def summary(self):
        """One line per alpha: max nontrivial |mu| over the scan, at the largest q and at q = 0, unstable count,
        worst residual and worst convergence checks."""
        lines = ["| alpha | q scanned | max nontrivial \\|mu\\| (at q) | at the largest q | at q = 0 (solitary) | "
                 "unstable multipliers | max residual / check | max 2M change | max SLEPc - dense |",
                 "|---|---|---|---|---|---|---|---|---|"]
        for a in sorted({float(r["alpha"]) for r in self.store.records}):
            rs = [r for r in self.rows() if float(r["alpha"]) == a]
            qs = np.array([float(r["q"]) for r in rs])
            mu = np.array([float(r["max_nontrivial"]) for r in rs])
            top = rs[int(np.argmax(qs))]
            sol = [r for r in rs if float(r["q"]) == 0]
            pos = qs[qs > 0]
            lines.append(f"| {a:g} | {len(rs)}: {pos.min() if len(pos) else 0:.5f} - {qs.max():.4f}"
                         f"{' and 0' if sol else ''} | {mu.max():.6f} ({_qtext(qs[int(np.argmax(mu))])}) | "
                         f"{float(top['max_nontrivial']):.6f} (q = {float(top['q']):.4f}) | "
                         + (f"{float(sol[0]['max_nontrivial']):.6f}" if sol else "n/a") +
                         f" | {sum(int(r['unstable']) for r in rs) or 'none'} | "
                         f"{max(float(r['residual']) for r in rs):.1e} / "
                         f"{max(float(r['residual_check']) for r in rs):.1e} | "
                         f"{max(float(r['doubling_change']) for r in rs):.1e} | "
                         f"{max(float(r['slepc_change']) for r in rs):.1e} |")
        return "\n".join(lines) + "\n"


def _fmt(v):
    v = complex(v)
    return f"{v.real:.6f}{v.imag:+.6f}i" if abs(v.imag) > 1e-10 else f"{v.real:.6f}"


def _qtext(q):
    if q == 0:
        return "0 (solitary)"
    k = math.pi / q
    return f"pi/{k:.0f} ({q:.5f})" if abs(k - round(k)) < 1e-9 else f"{q:.5f}"


def exact_compacton(record):
    """The ExactCompacton of a stability record."""
    return ExactCompacton(float(record["q"]), float(record["gap"]), np.array(record["state"]),
                          float(record["residual"]), int(record["iterations"]))


# --- dynamics on a long free chain ------------------------------------------------------------------------------
def dynamics_integrator(chain, tolerances=DYNAMICS_TOLERANCES, prefix=DYNAMICS_PREFIX):
    """The chain TS under ``prefix`` with the adaptor's error norm defaulting to the max norm
    (``-<prefix>ts_adapt_wnormtype infinity``): the RMS norm of a mostly resting long chain lets local errors of
    the few moving beads through. The default is inserted for this set-up only (a given value wins)."""
    opts = PETSc.Options()
    name = prefix + "ts_adapt_wnormtype"
    inserted = not opts.hasName(name)
    if inserted:
        opts.setValue(name, "INFINITY")
    try:
        return ChainIntegrator(chain, tolerances, prefix)
    finally:
        if inserted:
            opts.delValue(name)


DYN_FIELDS = ("q", "kind", "mu3", "rate", "rate_first", "rate_last",
              "rest_floor", "rest_max_late", "a_end", "a_predicted", "b_start", "b_end", "dist_end", "behind_v",
              "seconds", "steps")


class CompactonDynamics:
    """Exact compactons (stability records, one alpha) on a free chain of N beads in gap-lattice coordinates
    (:class:`WindowChain`, TS prefix ``cdyn_``), perturbed by ``amplitude`` times the least-stable mode ('mode')
    or Gaussian noise ('noise') on the window (relative to D for positions and v_peak for velocities); after each
    unit of time (one bead of travel) the window W_k at beads n0 + k.. is compared with Y*:
    delta = a v1 + b v2 + rest (Jordan vectors). Linear prediction: b constant, a_k = a_0 + k b, and
    |rest| ~ |mu_3|^k down to the flow's floor. Records keyed by (q, kind)."""

    def __init__(self, records, model, comm, output, mode="new", N=2100, n0=50, travel=1000, amplitude=1e-8,
                 kinds=("mode", "noise"), seed=12345, tolerances=DYNAMICS_TOLERANCES):
        if not records:
            raise ParameterError("-q", "", "no compacton to run")
        self.cases = [exact_compacton(r) for r in records]
        self.mu3 = {round(float(r["q"]), 12): complex(r["dominant"][0]) for r in records}
        self.alpha = float(records[0]["alpha"])
        M = self.cases[0].M
        if n0 < 1 or N < n0 + travel + M + 2:
            raise ParameterError("-N", N, f"the chain must hold n0 + travel + M + 2 = {n0 + travel + M + 2} beads")
        for kind in kinds:
            if kind not in ("mode", "noise"):
                raise ParameterError("-kinds", kind, "each must be mode or noise")
        self.model, self.comm, self.N, self.n0, self.travel = model, comm, int(N), int(n0), int(travel)
        self.amplitude, self.kinds, self.seed, self.tolerances = float(amplitude), list(kinds), seed, tolerances
        self.window = CompactonWindow(model, M, PETSc.COMM_SELF)
        chain = WindowChain(ChainSpec(model, self.N, "free"), comm, 0.0)
        self.chain, self.integ = chain, dynamics_integrator(chain, tolerances)
        ident = dict(alpha=self.alpha, N=self.N, n0=self.n0, travel=self.travel, amplitude=self.amplitude,
                     rtol=tolerances.rtol, M=M)
        self._open = lambda: NpzRecords(output, DYNAMICS_FORMAT, ident, ident,
                                        DYN_FIELDS + ("rest", "a", "b", "dist", "deviation"), comm, mode,
                                        dtypes={"kind": str, "steps": np.int64, "mu3": complex},
                                        shapes={**{k: (self.travel + 1,) for k in ("rest", "a", "b", "dist")},
                                                "deviation": (self.travel + 1, M)}, what="compacton dynamics file")
        self.store = None

    def open(self):
        if self.store is None:
            self.store = self._open()
        return self

    def perturbation(self, kind, scale, V):
        M = len(scale) // 2
        if kind == "noise":
            p = np.random.default_rng(self.seed).standard_normal(2 * M) * scale
        else:
            p = np.real(V)
        return (self.amplitude * p / np.max(np.abs(p / scale))).reshape(M, 2)

    def run(self):
        self.open()
        done = {(round(float(r["q"]), 12), str(r["kind"])) for r in self.store.records}
        for ex in self.cases:
            todo = [k for k in self.kinds if (round(ex.q, 12), k) not in done]
            if todo:
                yield from self._run_case(ex, todo)

    def _run_case(self, ex, kinds):
        w, M = self.window, ex.M
        _, J, _ = w.jacobian(ex.Y, ex.gap)
        lam, V = sorted_eig(J)
        _, _, rest_mu = split_jordan_pair(lam)
        i3 = int(np.argmin(np.abs(lam - rest_mu[0])))
        jc = jordan_check(w, J, ex.Y, ex.gap)
        scale = np.tile([ex.D, ex.v_peak], M)
        ystar = ex.Y.ravel()
        self.chain.gap = ex.gap
        mu3 = self.mu3[round(ex.q, 12)]
        for kind in kinds:
            X = self.chain.create_state()
            self.chain.set_from_array(X, chain_from_window(ex.Y + self.perturbation(kind, scale, V[:, i3]),
                                                           self.N, self.n0))
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
            self.store.append(row)
            yield row

    def fit(self, s):
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

    def table(self):
        M = self.cases[0].M
        lines = [f"alpha = {self.alpha:g}: exact compactons (M = {M} window) on a free chain of {self.N} beads at "
                 f"bead {self.n0}, perturbed by {self.amplitude:g} x (mode: the eigenvector of the dominant "
                 f"nontrivial multiplier mu_3; noise: Gaussian, seed {self.seed}) relative to D and v_peak, "
                 f"travelling {self.travel} beads (TS -cdyn_, rtol {self.tolerances.rtol:g}, max-norm error "
                 "control). delta_k = W_k - Y* = a v1 + b v2 + rest (Jordan vectors of mu = 1); prediction: "
                 "|rest| ~ |mu_3|^k (rate ln|mu_3| per bead = per script-T), b constant, a_k = a_10 + (k - 10) b_10."
                 " |rest| and |delta| relative (max over the window).\n",
                 "| q | perturbation | mu_3 | fitted rate of \\|rest\\| (k range) | ln\\|mu_3\\| | ratio | floor of "
                 "\\|rest\\| (median, k >= T/2) | max \\|rest\\|, k >= 50 | b at k = 10 -> T | a(T) / predicted | "
                 "\\|delta\\|(T) | max \\|v\\| left behind / v_peak | TS steps | s |",
                 "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in sorted(self.store.records, key=lambda r: (-float(r["q"]), str(r["kind"]))):
            rate, ln3 = float(r["rate"]), math.log(abs(complex(r["mu3"])))
            lines.append(f"| {_qtext(float(r['q']))} | {r['kind']} | {_fmt(complex(r['mu3']))} | {rate:.4f} "
                         f"({float(r['rate_first']):.0f}-{float(r['rate_last']):.0f}) | {ln3:.4f} | "
                         f"{rate / ln3:.4f} | {float(r['rest_floor']):.1e} | {float(r['rest_max_late']):.1e} | "
                         f"{float(r['b_start']):.3e} -> {float(r['b_end']):.3e} | {float(r['a_end']):.3e} / "
                         f"{float(r['a_predicted']):.3e} | {float(r['dist_end']):.1e} | {float(r['behind_v']):.1e} | "
                         f"{int(r['steps'])} | {float(r['seconds']):.1f} |")
        return "\n".join(lines) + "\n"

    def destroy(self):
        self.integ.destroy()
        self.chain.destroy()
        self.window.destroy()


# --- two compactons: which one carries the error -------------------------------------------------------------
PAIR_FIELDS = ("case", "rear", "front", "error_x", "error_v", "debris_v", "seconds")
PAIR_CASES = (("single", "", "unrefined"), ("single", "", "refined"), ("two", "unrefined", "unrefined"),
              ("two", "refined", "refined"), ("two", "unrefined", "refined"), ("two", "refined", "unrefined"))


class CompactonPairs:
    """The compacton of a branch point at c = 1, unrefined (the branch profile, eqs. extens, compacton) or refined
    at the same gap (window map, Delta fixed), alone or with a second one ``spacing`` beads behind (eq. extens2),
    on a free chain in gap-lattice coordinates (TS ``cdyn_``), run until the rear one has passed ``travel`` beads
    beyond the front one's start. Errors against the exactly translated initial chain (x relative to D, v to
    v_peak) and the debris left behind the rear compacton (max |v| / v_peak)."""

    def __init__(self, branch, q, comm, output, mode="new", spacing=132, travel=100, M=18, rear=DEFAULT_REAR,
                 margin=10, tolerances=DYNAMICS_TOLERANCES):
        self.branch, self.q, self.comm = branch, float(q), comm
        self.spacing, self.travel, self.M, self.rear, self.margin = int(spacing), int(travel), int(M), int(rear), \
            int(margin)
        Yu, gap = guess_from_branch(branch.point(q), self.M, self.rear, branch.q_k())
        if self.spacing < self.M:
            raise ParameterError("-spacing", spacing, f"the two windows must not overlap: spacing >= M = {self.M}")
        self.gap, self.states = gap, {"unrefined": Yu}
        self.tolerances = tolerances
        self.T = self.spacing + self.travel
        self.N = self.margin + self.spacing + self.M + self.T + self.margin
        self.model = branch.model
        self._open = lambda: NpzRecords(output, PAIRS_FORMAT,
                                        dict(alpha=branch.alpha, q=self.q, h=branch.h, spacing=self.spacing,
                                             travel=self.travel, M=self.M, N=self.N, gap=gap),
                                        dict(alpha=branch.alpha, q=self.q, h=branch.h, spacing=self.spacing,
                                             travel=self.travel, M=self.M), PAIR_FIELDS, comm, mode,
                                        dtypes={"case": str, "rear": str, "front": str}, what="compacton pairs file")
        self.chain = WindowChain(ChainSpec(self.model, self.N, "free"), comm, gap)
        self.integ = dynamics_integrator(self.chain, tolerances)
        self.store = None

    def open(self):
        if self.store is None:
            self.store = self._open()
        return self

    def refined(self):
        if "refined" not in self.states:
            w = CompactonWindow(self.model, self.M, PETSc.COMM_SELF)
            try:
                ex = CompactonRefiner(w).refine(self.states["unrefined"], self.gap, self.q, fix_gap=True)
            finally:
                w.destroy()
            self.states["refined"], self.refined_residual = ex.Y, ex.residual
            self.unrefined_residual = None
        return self.states["refined"]

    def initial(self, rear, front):
        """(N, 2) gap-lattice chain: the front window at bead margin + spacing, the rear one spacing beads behind."""
        X = np.zeros((self.N, 2))
        nf = self.margin + self.spacing
        Yf = self.states[front]
        X[:nf, 0] = Yf[0, 0]
        X[nf:nf + self.M] = Yf
        if rear:
            Yr = self.states[rear]
            nr = nf - self.spacing
            X[:nr, 0] += Yr[0, 0]
            X[nr:nr + self.M] = Yr + np.array([Yf[0, 0], 0.0])
        return X

    def run(self):
        self.open()
        self.refined()
        w = CompactonWindow(self.model, self.M, PETSc.COMM_SELF)
        try:
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
            self.store.append(row)
            yield row

    def table(self):
        lines = [f"alpha = {self.branch.alpha:g}, q = {_qtext(self.q)}, branch h = "
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
            lines.append(f"| {r['case']} | {r['rear'] or '-'} | {r['front']} | {float(r['error_x']):.1e} | "
                         f"{float(r['error_v']):.1e} | {float(r['debris_v']):.1e} | {float(r['seconds']):.1f} |")
        return "\n".join(lines) + "\n"

    def destroy(self):
        self.integ.destroy()
        self.chain.destroy()


# --- the same compacton with the periodic chain's feedback ---------------------------------------------------
def ring_spectrum(record, model, comm, tolerances=None):
    """The exact compacton of a stability record on a periodic chain of N = 2 pi / q beads (x_n = Delta n + y_n,
    the window completed by resting beads at y = 0 ahead; eq. pbcl closes it since N Delta = D): the paper's
    periodic wave at q, whose F_q = S R(script-T) (script-T = 1 at c = 1) is then analysed densely
    (:class:`hertzpetsc.floquet.DenseFloquet`, prefix ``floquet_``). Returns (N, Spectrum, residual of S X(1) =
    X(0) + (Delta, 0), the boost of one bead))."""
    from ..floquet import FLOQUET_TOLERANCES, TOL_RHO, DenseFloquet, Spectrum, dense_multipliers
    from ..waves import fits_chain
    ex = exact_compacton(record)
    q = ex.q
    N = int(round(2 * math.pi / q)) if q > 0 else 0
    if q <= 0 or not fits_chain(q, N) or N < ex.M + 2:
        raise ParameterError("-ring_q", q, f"the ring needs 2 pi / q to be a whole number of beads >= M + 2 = "
                                           f"{ex.M + 2}")
    x = np.zeros((N, 2))
    x[:ex.M] = ex.Y
    x[:, 0] += ex.gap * np.arange(N)
    spec = ChainSpec(model, N, "periodic")
    dense = DenseFloquet(spec, comm, tolerances or FLOQUET_TOLERANCES)
    try:
        F, xT = dense.flow.monodromy_mod_shift(x, 1.0)
        spectrum = Spectrum(dense_multipliers(F), True, TOL_RHO)
    finally:
        dense.destroy()
    residual = float(np.max(np.abs(xT - x - np.array([ex.gap, 0.0]))))
    return N, spectrum, residual
