"""Spectral stability of isolated compactons (paper, section 3.3 and the Discussion's open question), on the
travelling window of :mod:`hertzpetsc.compacton_window`.

:class:`CompactonStabilityScan` follows the exact compacton of each alpha from the largest branch q with F(q) >= 1
down through the requested q (natural continuation in q, :mod:`hertzpetsc.continuation`) to the solitary wave (Delta
= 0, eq. adr), and records per (alpha, q): the refined state, its residual under the refinement's flow and under an
independent flow (another Runge-Kutta pair and tolerance), all 2M window multipliers (LAPACK), the Jordan pair at 1
(mean, split, J v1 = v1, solvability of (J - 1) v2 = v1), the dominant nontrivial multipliers, the unstable ones,
the change of the dominant multipliers when M is doubled, and SLEPc's dominant multipliers on the weighted
shell against the dense ones. File ``hertzpetsc-compacton-stability-1`` (npz), its columns declared in
:data:`STABILITY_KIND`.
:func:`ring_spectrum`: the same compacton on the ring of 2 pi / q beads. The dynamics
of perturbed compactons and the two-compacton test: :mod:`~hertzpetsc.studies.compacton_dynamics`,
:mod:`~hertzpetsc.studies.compacton_pairs`.
"""
from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Optional, Sequence

import numpy as np
from petsc4py import PETSc

from ..chain import IntegrationTolerances
from ..compacton_spectrum import DEFAULT_ETA, WindowStability, sorted_eig, split_jordan_pair, window_spectrum
from ..compacton_window import (DEFAULT_REAR, WINDOW_PREFIX, WINDOW_TOLERANCES, CompactonRefiner, CompactonWindow,
                                ExactCompacton, embed, guess_from_branch)
from ..continuation import Continuation, Natural
from ..branch import Branch
from ..errors import (ParameterError, check_flag, check_instance, check_integer, check_real, check_reals,
                      members)
from ..model import ChainSpec
from ..records import Column, Kind
from ..resources import MAX_DENSE_BEADS
from ..richardson import richardson
from ..roles import uses
from .base import ContinuedScan, point_key

if TYPE_CHECKING:
    from ..branch import Branch

STABILITY_FORMAT = "hertzpetsc-compacton-stability-1"
CHECK_PREFIX = "ccheck_"
# the independent flow of the residual check: another embedded pair (Verner 7(6)) at another tolerance
CHECK_TOLERANCES = IntegrationTolerances(rtol=1e-13, atol=1e-16)
NDOM = 6
TOL_UNSTABLE = 1e-8
DEFAULT_QS = ("1.5, 1.3, 1.1, 3*pi/10, 7*pi/25, 0.7, 9*pi/50, 0.45, pi/10, 0.2, pi/25, pi/50, pi/100, pi/200, "
              "pi/400, pi/800, pi/1600, pi/3200, pi/6400")
_IDENT = "the window's residual max\\|G(Y) - Y\\|"
# the columns of a travelling window's spectrum, shared with the solitary stability file
RESIDUAL_COLUMNS = (
    Column("residual", f"{_IDENT} under the refinement's flow", format=".1e"),
    Column("residual_check", f"{_IDENT} under the independent flow (`-ccheck_`)", format=".1e"),
    Column("iterations", "Gauss-Newton iterations", "count", np.int64, "d"))
JORDAN_COLUMNS = (
    Column("jordan_mean", "mean of the Jordan pair at 1", format=".12f"),
    Column("jordan_split", "split of the Jordan pair at 1", format=".0e"),
    Column("jordan_translation", "\\|J v1 - v1\\| / \\|v1\\|", format=".0e"),
    Column("jordan_generalized", "residual of (J - 1) v2 = v1", format=".0e"),
    Column("max_nontrivial", "largest \\|mu\\| without the Jordan pair", format=".6f"))
UNSTABLE = Column("unstable", "multipliers with \\|mu\\| > 1 + tol_unstable", "count", np.int64, "d")
SECONDS = Column("seconds", "wall time", "s", format=".1f")
STABILITY_KIND = Kind(STABILITY_FORMAT, (
    Column("M", "beads of the travelling window", "count", np.int64, "d", constant=True),
    Column("rear", "resting beads kept behind the core", "count", np.int64, "d", constant=True),
    Column("eta", "weight exp(eta n) of the SLEPc shell W J W^-1", constant=True),
    Column("nev", "largest number of SLEPc multipliers asked for", "count", np.int64, "d", constant=True),
    Column("tol_unstable", "unstable when \\|mu\\| > 1 + tol_unstable", constant=True),
    Column("rtol", "flow tolerance of the window map (prefix `-cwin_`)", constant=True),
    Column("branch_alpha<a>_sha256", "content hash of the branch file of each alpha a of the scan "
           "(`branch_alpha1.5_sha256`, `branch_alpha2_sha256`, `branch_alpha2.5_sha256` in the paper's)", "", str, "s",
           constant=True, optional=True),
    Column("solver_options", "number-changing options under `-cwin_`, `-ccheck_`, `-cstab_`", "", str, "s",
           constant=True, optional=True),
    Column("alpha", "Hertz exponent", format="g"),
    Column("q", "wavenumber (0: the solitary wave)"),
    Column("gap", "Delta = a p q, the gap of the resting lattice (eq. defvit)", format=".6g"),
    Column("D", "the shift 2 pi a p of every bead the compacton passes", format=".6f"),
    *RESIDUAL_COLUMNS, *JORDAN_COLUMNS, UNSTABLE,
    Column("doubling_change", "change of the pair's mean and the three dominant multipliers when M is doubled",
           format=".1e"),
    Column("slepc_change", "SLEPc's distance to the LAPACK multipliers", format=".1e"),
    Column("slepc_products", "SLEPc's shell products", "count", np.int64, "d"),
    Column("slepc_nev", "SLEPc's nev", "count", np.int64, "d"),
    Column("core_first", "first bead of the window's core (the bonds that close during a period)", "count",
           np.int64, "d"),
    Column("core_last", "last bead of the window's core", "count", np.int64, "d"),
    SECONDS,
    Column("multipliers", "all window multipliers (LAPACK), by modulus", "1", complex, shape="2M"),
    Column("dominant", "the dominant nontrivial ones (mu_3, mu_4, ...), zero-padded", "1", complex, shape="6"),
    Column("state", "the exact compacton: window state (y, v) in gap-lattice coordinates y_n = x_n - Delta n",
           shape="M, 2"),
))


def scan_sequence(branch, qs, solitary=True):
    """The q of one alpha in computing order: the branch start (its largest q with F(q) >= 1, where a compacton
    exists: eq. extens), then ``qs`` (each <= q_k, else ParameterError) by decreasing q, then 0 (the solitary
    wave)."""
    qs = check_reals("qs", qs, "wavenumbers", distinct=True, empty=True)
    ok = branch.column("F") >= 1.0
    if not ok.any():
        raise ParameterError("branch", "no point with F >= 1", "the branch must reach q <= q_k (F(q) >= 1)")
    q_top, q_k = float(branch.q[ok].max()), float(branch.q_k())
    for q in qs:
        if not (0 < q <= q_k):
            raise ParameterError("-q", q, f"a compacton needs 0 < q <= q_k = {q_k:.6f} at alpha = {branch.alpha:g} "
                                          "(F(q) = 2 ell/q >= 1, eq. extens; q = 0 is -solitary)")
    rest = sorted((q for q in qs if abs(q - q_top) > 1e-12), reverse=True)
    return [q_top] + rest + ([0.0] if solitary else [])


class CompactonStabilityScan(ContinuedScan):
    """Exact compactons and their window spectra against q for each branch (alpha) (module docstring).

    Each (alpha, q) is computed on one rank (COMM_SELF), the alphas of a continuation step dealt to the ranks, so
    the records do not depend on the number of ranks. Prefixes: ``cwin_`` (the window flows), ``ccheck_`` (the
    independent residual flow), ``cstab_`` (the EPS: ``-cstab_eps_*``)."""

    FORMAT, FIELDS, DTYPES, COLUMNS = STABILITY_FORMAT, STABILITY_KIND.fields, STABILITY_KIND.dtypes, STABILITY_KIND
    ROLES = uses("cwin_", "ccheck_", "cstab_")
    WHAT, LABELS = "compacton stability file", ("nev",)

    def __init__(self, branches: Sequence[Branch], qs: Sequence[float], comm: Optional[PETSc.Comm] = None,
                 output: Optional[str] = None, mode: str = "new", M: int = 18, rear: int = DEFAULT_REAR, nev: int = 3,
                 eta: float = DEFAULT_ETA, solitary: bool = True, tol_unstable: float = TOL_UNSTABLE,
                 tolerances: IntegrationTolerances = WINDOW_TOLERANCES) -> None:
        branches = [check_instance("branches", b, Branch, "a Branch (Branch.load(path), hz.compute_branch)")
                    for b in members("branches", branches, "Branches")]
        if not branches:
            raise ParameterError("-branches", "", "give at least one branch file")
        M = check_integer("M", M, 4, "the window's beads (its map and the doubled window's are dense)",
                          MAX_DENSE_BEADS // 2)
        rear = check_integer("rear", rear, 2, "the beads at rest behind the zone")
        nev = check_integer("nev", nev, 1, "the dominant multipliers")
        eta = check_real("eta", eta, "the weight's rate", 0.0, lo_open=False)
        solitary = check_flag("solitary", solitary)
        check_real("tol_unstable", tol_unstable, "the instability threshold on |mu| - 1", 0.0)
        check_instance("tolerances", tolerances, IntegrationTolerances, "an IntegrationTolerances(rtol, atol)")
        self.branches = {round(b.alpha, 10): b for b in branches}
        if len(self.branches) != len(branches):
            raise ParameterError("-branches", [b.alpha for b in branches], "one branch per alpha")
        self.sequences = {a: scan_sequence(b, qs, solitary) for a, b in self.branches.items()}
        super().__init__(None, comm, output, mode)
        self.M, self.rear, self.nev, self.eta = int(M), int(rear), int(nev), float(eta)
        self.SHAPES = {"multipliers": (2 * self.M,), "dominant": (NDOM,), "state": (self.M, 2)}
        self.tol_unstable, self.tolerances = tol_unstable, tolerances
        # configure every solver now (bad options and bad sizes fail before any computation)
        for a, b in self.branches.items():
            guess_from_branch(b.point(self.sequences[a][0]), self.M, self.rear, b.q_k())
        self._tools = {}
        WindowStability(self._solvers(next(iter(self.branches)))[0], self.nev, self.eta).destroy()

    def constants(self) -> dict:
        return dict(M=self.M, rear=self.rear, eta=self.eta, nev=self.nev, tol_unstable=self.tol_unstable,
                    rtol=self.tolerances.rtol)

    def inputs(self) -> dict[str, str]:
        return {f"branch_alpha{a:g}": getattr(b, "path", "") for a, b in self.branches.items()}

    # --- per-rank solvers (COMM_SELF), one set per alpha ---------------------------------------------------------
    def _solvers(self, alpha):
        if alpha not in self._tools:
            model = self.branches[alpha].model
            w = CompactonWindow(model, self.M, PETSc.COMM_SELF, self.tolerances, WINDOW_PREFIX)
            w2 = CompactonWindow(model, 2 * self.M, PETSc.COMM_SELF, self.tolerances, WINDOW_PREFIX)
            chk = CompactonWindow(model, self.M, PETSc.COMM_SELF, CHECK_TOLERANCES, CHECK_PREFIX, "7vr")
            self._tools[alpha] = (w, w2, chk, CompactonRefiner(w), CompactonRefiner(w2))
        return self._tools[alpha]

    def compute(self, item: tuple[float, int]) -> dict:
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
            seeds = [refiner.pack(exact_compacton(r)) for r in self.preceding(alpha, i)]
            exact = continue_to(refiner, seeds, q)["compacton"]
        Y, gap = exact.Y, exact.gap
        core = w.core(Y, gap)
        # a compacton's zone must leave resting beads on both sides; the solitary wave's doubly exponential tails
        # reach the window's ends (above 1e-13 of the peak compression): its truncation is the 2M change
        if q > 0 and (core[0] < 1 or core[-1] > self.M - 3):
            raise ParameterError("-M", self.M, f"at alpha = {alpha:g}, q = {q:.6g} the compression zone reaches "
                                 f"beads {core[0]}..{core[-1]} of the window: enlarge -M or change -rear")
        _, lam, mean, split, rest, jc = window_spectrum(w, Y, gap)
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
        s_mean, _, s_rest = split_jordan_pair(sl.multipliers[:max(nev, 2)])
        slepc_change = max([abs(s_mean - mean)] + [float(np.min(np.abs(lam - v))) for v in s_rest])
        unstable = int(np.sum(np.abs(rest) > 1 + self.tol_unstable))
        return dict(alpha=alpha, q=q, gap=gap, D=exact.D, residual=exact.residual,
                    residual_check=chk.residual(Y, gap), iterations=exact.iterations, jordan_mean=mean.real,
                    jordan_split=split, jordan_translation=jc.translation, jordan_generalized=jc.generalized,
                    max_nontrivial=float(abs(rest[0])), unstable=unstable, doubling_change=doubling,
                    slepc_change=slepc_change, slepc_products=sl.work["products"], slepc_nev=nev,
                    core_first=int(core[0]), core_last=int(core[-1]), seconds=time.perf_counter() - t0, multipliers=lam,
                    dominant=np.pad(dominant, (0, NDOM - len(dominant))), state=Y)

    def cost(self, q: float) -> float:
        """The solitary wave (q = 0) costs about five compactons."""
        return 1.0 + 4.0 * (q == 0)

    def destroy(self) -> None:
        for tools in self._tools.values():
            for t in tools[:3]:
                t.destroy()
        self._tools = {}

    # --- output ---------------------------------------------------------------------------------------------
    def rows(self) -> list[dict]:
        return sorted(self.store.records, key=lambda r: (float(r["alpha"]), -float(r["q"]) if r["q"] else 1.0))

    def record(self, alpha: float, q: float) -> dict:
        for r in self.store.records:
            if point_key(r["alpha"], r["q"]) == point_key(alpha, q):
                return r
        raise ParameterError("q", q, f"not in the compacton stability file at alpha = {alpha:g}")

    def table(self) -> str:
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
            dom = ", ".join(fmt_multiplier(v) for v in r["dominant"][:3])
            lines.append(STABILITY_KIND.row(
                r, "{alpha}", q_text(float(r["q"])), "{gap}", "{D}", "{core_first}-{core_last}",
                "{residual} / {residual_check}", "{iterations}", "{jordan_mean} ({jordan_split})",
                "{jordan_translation}, {jordan_generalized}", dom, "{max_nontrivial}", int(r["unstable"]) or "none",
                "{doubling_change}", "{slepc_change} ({slepc_nev}, {slepc_products})", "{seconds}"))
        return "\n".join(lines) + "\n"

    def summary(self) -> str:
        """One line per alpha: max nontrivial |mu| over the scan, at the largest q and at q = 0, unstable count,
        worst residual and worst convergence checks."""
        lines = ["| alpha | q scanned | max nontrivial \\|mu\\| (at q) | at the largest q | at q = 0 (solitary) | "
                 "unstable multipliers | max residual / check | max 2M change | max SLEPc - dense |",
                 "|---|---|---|---|---|---|---|---|---|"]
        for a, rs in self.by_alpha():
            qs = np.array([float(r["q"]) for r in rs])
            mu = np.array([float(r["max_nontrivial"]) for r in rs])
            top = rs[int(np.argmax(qs))]
            sol = [r for r in rs if float(r["q"]) == 0]
            pos = qs[qs > 0]
            lines.append(f"| {a:g} | {len(rs)}: {pos.min() if len(pos) else 0:.5f} - {qs.max():.4f}"
                         f"{' and 0' if sol else ''} | {mu.max():.6f} ({q_text(qs[int(np.argmax(mu))])}) | "
                         f"{float(top['max_nontrivial']):.6f} (q = {float(top['q']):.4f}) | "
                         + (f"{float(sol[0]['max_nontrivial']):.6f}" if sol else "n/a") +
                         f" | {sum(int(r['unstable']) for r in rs) or 'none'} | "
                         f"{max(float(r['residual']) for r in rs):.1e} / "
                         f"{max(float(r['residual_check']) for r in rs):.1e} | "
                         f"{max(float(r['doubling_change']) for r in rs):.1e} | "
                         f"{max(float(r['slepc_change']) for r in rs):.1e} |")
        return "\n".join(lines) + "\n"

    def limit_table(self) -> str:
        """The q -> 0 limit of the compacton family against the solitary wave (q = 0), per alpha: D and the dominant
        multipliers mu_3, mu_4, mu_5 at the three smallest q, the observed order, the value extrapolated in q with
        the leading order 1 (the gap Delta = q D / 2 pi opens every bond by O(q)) and the solitary wave's."""
        lines = ["| alpha | quantity | at the three smallest q | observed order | extrapolated to q = 0 (order 1) | "
                 "solitary wave (q = 0) | extrapolated - solitary | smallest q - solitary |",
                 "|---|---|---|---|---|---|---|---|"]
        for a, rs in self.by_alpha():
            sol = [r for r in rs if float(r["q"]) == 0]
            small = sorted((r for r in rs if float(r["q"]) > 0), key=lambda r: -float(r["q"]))[-3:]
            if not sol or len(small) < 3:
                continue
            qs = [float(r["q"]) for r in small]
            quantities = [("D", lambda r: float(r["D"]))] + [
                (f"mu_{k + 3}", lambda r, k=k: complex(r["dominant"][k]).real) for k in range(3)]
            for name, get in quantities:
                values = [get(r) for r in small]
                order, limit = richardson(values, order=1.0, steps=qs)
                exact = get(sol[0])
                lines.append(f"| {a:g} | {name} | " + ", ".join(f"{v:.6f}" for v in values) + " (q = "
                             + ", ".join(q_text(q).split(" ")[0] for q in qs) + f") | {order:.3f} | {limit:.7f} | "
                             f"{exact:.7f} | {limit - exact:+.1e} | {values[-1] - exact:+.1e} |")
        return "\n".join(lines) + "\n"


def fmt_multiplier(v):
    v = complex(v)
    return f"{v.real:.6f}{v.imag:+.6f}i" if abs(v.imag) > 1e-10 else f"{v.real:.6f}"


def q_text(q):
    if q == 0:
        return "0 (solitary)"
    k = math.pi / q
    return f"pi/{k:.0f} ({q:.5f})" if abs(k - round(k)) < 1e-9 else f"{q:.5f}"


def continue_to(problem, seeds, value):
    """The report of the point at ``value`` by natural continuation (:mod:`hertzpetsc.continuation`) of ``problem``
    from the ``seeds`` (one or two packed points, destroyed here); pinned by the phase condition, so the corrector
    may move far."""
    cont = Continuation(problem, Natural(max_corrector=math.inf))
    try:
        cont.seed(seeds)
        return cont.step_to(value).report
    finally:
        for Z in seeds:
            Z.destroy()
        cont.destroy()


def exact_compacton(record):
    """The ExactCompacton of a stability record."""
    return ExactCompacton(float(record["q"]), float(record["gap"]), np.array(record["state"]),
                          float(record["residual"]), int(record["iterations"]))


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
