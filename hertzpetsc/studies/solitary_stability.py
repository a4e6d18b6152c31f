"""Spectral stability of solitary waves on the travelling window, uncompressed and precompressed, against the energy
criterion (:mod:`hertzpetsc.solitary_family`; the q -> 0 end of the compacton family of
:mod:`~hertzpetsc.studies.compacton_stability`).

:class:`SolitaryStabilityScan`: for each alpha, the unit-speed solitary wave from eq. adr (:mod:`hertzpetsc.solitary`,
refined on the window) continued in the precompression through the sound speeds c0 (units of the wave's speed;
c0 = 0 the uncompressed chain, c / c0 the Mach number), each point refined on an M-bead window (Delta = 0) whose ends
see the exponential tails at ``tail`` of the deepest compression. Per (alpha, c0): the window multipliers (LAPACK on
the map weighted at the essential radius's eta, :func:`~hertzpetsc.solitary_family.weighted_multipliers`),
the Jordan pair at 1, the weighted essential-spectrum radius, the point multipliers and the unstable ones; the
energy H, its slope d ln H / d ln c at fixed lattice by the Jordan vectors (omega(v1, v2) / H) and by finite
differences of H along the family (delta0 (1 +- 1e-4)); the same wave in the lattice of precompression 1 (c, H, dH/dc);
the truncation (the tails at the window's ends, the change of H, the slope and the point multipliers in a window of
2M beads).

File ``hertzpetsc-solitary-stability-1`` (npz), its columns declared in :data:`SOLITARY_KIND`.
"""
import math
import time
from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

from ..compacton_spectrum import window_spectrum
from ..compacton_window import WINDOW_PREFIX, WINDOW_TOLERANCES, embed
from ..errors import Checked, ParameterError, param
from ..model import LatticeModel
from ..resources import MAX_DENSE_BEADS
from ..roles import uses
from ..solitary import SOL_PREFIX, SolitaryParameters, solve_solitary_wave
from ..solitary_family import (PrecompressionContinuation, essential_radius, guess_from_solitary,
                               precompression_at_unit_speed, symplectic_product, tail_rate, unit_lattice,
                               weighted_multipliers, window_beads, window_energy)
from .base import ContinuedScan
from ..records import Column, Kind
from .compacton_stability import (CHECK_PREFIX, CHECK_TOLERANCES, JORDAN_COLUMNS, NDOM, RESIDUAL_COLUMNS, SECONDS,
                                  TOL_UNSTABLE, UNSTABLE, continue_to, fmt_multiplier)

FORMAT = "hertzpetsc-solitary-stability-1"
FD_STEP = 1e-4                  # relative step in delta0 of the finite-difference slope (error ~ step^2 ~ 1e-8)
POINT_MARGIN = 1.001            # multipliers above this times the essential radius are compared in the 2M window
                                # (a finite window's transport multipliers lie just below it)
CONVERGED = 1e-6                # ... and called point multipliers when the 2M window moves them less than this
                                # (the transport multipliers move by ~1e-3: they approach the essential radius)
SOLITARY_KIND = Kind(FORMAT, (
    Column("alphas", "Hertz exponents of the scan", shape="A", constant=True),
    Column("sound_speeds", "the sound speeds c0 of the scan, 0 first", shape="S", constant=True),
    Column("M", "beads of the travelling window", "count", np.int64, "d", constant=True),
    Column("tail", "the tails at the window's ends (relative to the deepest compression) M was chosen for",
           constant=True),
    Column("tol_unstable", "unstable when \\|mu\\| > 1 + tol_unstable", constant=True),
    Column("rtol", "flow tolerance of the window map (prefix `-cwin_`)", constant=True),
    Column("solver_options", "number-changing options under `-cwin_`, `-ccheck_`, `-sol_`", "", str, "s",
           constant=True, optional=True),
    Column("alpha", "Hertz exponent", format="g"),
    Column("c0", "sound speed sqrt(V''(0)) in units of the wave's speed (1/c0 the Mach number; 0: uncompressed)",
           format="g"),
    Column("delta0", "precompression of the unit-speed wave's chain, (c0^2 / alpha)^(1/(alpha-1))", format=".6g"),
    Column("kappa", "decay rate of the tails per bead, sinh(kappa/2)/(kappa/2) = 1/c0 (inf at c0 = 0)",
           format=".4f"),
    *RESIDUAL_COLUMNS,
    Column("D", "the displacement the wave leaves behind (2 k_alpha at c0 = 0)"),
    Column("H", "energy sum v^2/2 + sum V(r) of the window at unit speed (V(0) = V'(0) = 0)", format=".10f"),
    Column("log_slope", "d ln H / d ln c at fixed lattice, omega(v1, v2) / H from the Jordan vectors at 1",
           format=".8f"),
    Column("log_slope_fd", "the same from H along the family (finite differences in delta0, +-1e-4 relative); nan "
           "at c0 = 0", format=".8f"),
    Column("speed", "the same wave in the lattice of precompression 1: its speed c (inf at c0 = 0)", format=".6f"),
    Column("H_unit", "there, H(c) (inf at c0 = 0)"),
    Column("dHdc_unit", "there, dH/dc (inf at c0 = 0)", format=".6g"),
    *JORDAN_COLUMNS,
    Column("essential", "radius of the weighted essential spectrum (minimum over eta)", format=".6f"),
    Column("eta", "the eta attaining it (inf at c0 = 0)", format=".3f"),
    Column("points", "multipliers above 1.001 `essential` that the window of 2M beads moves by less than 1e-6",
           "count", np.int64, "d"),
    UNSTABLE,
    Column("tail_front", "\\|r\\| of the window's first bond relative to the deepest compression", format=".0e"),
    Column("tail_rear", "\\|r\\| of the window's last bond relative to the deepest compression", format=".0e"),
    Column("doubling_change", "in the window of 2M beads: max of the relative change of H and of the slope, and of "
           "the point multipliers' change", format=".1e"),
    SECONDS,
    Column("multipliers", "all window multipliers (LAPACK on the weighted map), by modulus", "1", complex,
           shape="2M"),
    Column("dominant", "the dominant nontrivial ones (mu_3, mu_4, ...)", "1", complex, shape="6"),
    Column("state", "the wave: window state (y, v), 0 ahead, D behind", shape="M, 2"),
))
ROLES = uses(WINDOW_PREFIX, CHECK_PREFIX, SOL_PREFIX)


@dataclass(frozen=True)
class SolitaryStabilityParameters(Checked):
    """alphas > 1; sound speeds c0 in [0, 1) (0, the uncompressed chain, is always computed first); M beads of the
    window (0: the fewest whose ends see the tails of the largest c0 at ``tail``); unstable: |mu| > 1 +
    tol_unstable."""

    alphas: tuple = param((1.5, 2.0, 2.5), "Hertz exponents", lo=1.0, distinct=True)
    c0: tuple = param((0.0, 0.2, 0.4, 0.6, 0.7, 0.8, 0.85, 0.9), "sound speeds sqrt(V''(0)) in units of the wave's "
                      "speed (0: the uncompressed chain; a solitary wave is supersonic)", lo=0.0, lo_open=False,
                      hi=1.0, distinct=True)
    M: int = param(0, "beads of the window (0: from the tails of the largest c0)", lo=0)
    tail: float = param(1e-12, "the tails at the window's ends, relative to the deepest compression", lo=0.0,
                        hi=1e-6)
    tol_unstable: float = param(TOL_UNSTABLE, "the instability threshold: unstable when |mu| > 1 + tol_unstable",
                                lo=0.0)

    def __post_init__(self):
        super().__post_init__()
        c0 = tuple(sorted(set(self.c0) | {0.0}))
        object.__setattr__(self, "c0", c0)
        need = window_beads(c0[-1], self.tail)
        M = self.M or need
        if not need <= M <= MAX_DENSE_BEADS // 4:
            raise ParameterError("M", self.M, f"the window needs {need} beads for tails of {self.tail:g} at c0 = "
                                              f"{c0[-1]:g} (0: that many), and at most {MAX_DENSE_BEADS // 4} "
                                              "(its dense map and the doubled window's)")
        object.__setattr__(self, "M", M)


class SolitaryStabilityScan(ContinuedScan):
    """Solitary waves (module docstring): each alpha on one rank (COMM_SELF), the alphas of a continuation step
    dealt to the ranks, so the records do not depend on the number of ranks. Prefixes: ``cwin_`` (window flows),
    ``ccheck_`` (independent residual flow), ``sol_`` (eq. adr)."""

    Parameters = SolitaryStabilityParameters
    FORMAT, FIELDS, DTYPES, COLUMNS = FORMAT, SOLITARY_KIND.fields, SOLITARY_KIND.dtypes, SOLITARY_KIND
    ROLES = ROLES
    WHAT, PARAMETER = "solitary stability file", "c0"
    NAMES = dict(sound_speeds="c0 (-c0)", M="M (-M; 0: from tail, -tail, and the largest c0)")

    def __init__(self, params, comm=None, output=None, mode="new"):
        super().__init__(params, comm, output, mode)
        self.sequences = {a: params.c0 for a in params.alphas}
        self.SHAPES = {"multipliers": (2 * params.M,), "dominant": (NDOM,), "state": (params.M, 2)}
        self.configure()
        self._tools = {}

    def constants(self):
        p = self.params
        return dict(alphas=list(p.alphas), sound_speeds=list(p.c0), M=p.M, tail=p.tail, tol_unstable=p.tol_unstable,
                    rtol=WINDOW_TOLERANCES.rtol)

    # --- per-rank solvers (COMM_SELF), one set per alpha ---------------------------------------------------------
    def _solvers(self, alpha):
        if alpha not in self._tools:
            model, M = LatticeModel.hertz(alpha), self.params.M
            self._tools[alpha] = (PrecompressionContinuation(model, M, PETSc.COMM_SELF),
                                  PrecompressionContinuation(model, 2 * M, PETSc.COMM_SELF),
                                  PrecompressionContinuation(model, M, PETSc.COMM_SELF, CHECK_TOLERANCES, CHECK_PREFIX,
                                                             "7vr"),
                                  PrecompressionContinuation(model, M, PETSc.COMM_SELF))
        return self._tools[alpha]

    def _wave(self, alpha, i):
        """The refined window state at the i-th sound speed: from eq. adr (i = 0) or by continuation in delta0
        from the records of the (up to two) preceding ones."""
        cont_problem = self._solvers(alpha)[0]
        M = self.params.M
        if i == 0:
            wave = solve_solitary_wave(SolitaryParameters(alpha, 40), PETSc.COMM_SELF)
            return cont_problem.refine(guess_from_solitary(wave, M, M // 2), 0.0)
        seeds = [cont_problem.pack(r["state"], float(r["delta0"])) for r in self.preceding(alpha, i)]
        return continue_to(cont_problem, seeds, precompression_at_unit_speed(alpha, self.params.c0[i]))["wave"]

    def compute(self, item):
        """The record of (alpha, index in the sound speeds)."""
        alpha, i = item
        t0 = time.perf_counter()
        p = self.params
        c0 = p.c0[i]
        d = precompression_at_unit_speed(alpha, c0)
        family, doubled, check, offset = self._solvers(alpha)
        ex = self._wave(alpha, i)
        Y, w = ex.Y, family.window(d)
        model = w.model
        essential, eta = essential_radius(c0)
        _, lam, mean, split, rest, jc = window_spectrum(w, Y, 0.0, lambda J: weighted_multipliers(J, eta))
        H = window_energy(model, Y)
        slope = symplectic_product(jc.v1, jc.v2) / H           # c dH/dc / H at c = 1: omega(v1, v2) = dH/dc
        slope_fd = math.nan
        if d > 0:       # the slope from H along the family: d ln H/d ln c = 2/(alpha-1) (alpha+1 - d ln H_1/d ln d)
            Hs = [window_energy(model.with_delta0(d * (1 + s)), offset.refine(Y, d * (1 + s)).Y) for s in
                  (-FD_STEP, FD_STEP)]
            dlog = (math.log(Hs[1]) - math.log(Hs[0])) / (math.log1p(FD_STEP) - math.log1p(-FD_STEP))
            slope_fd = 2.0 / (alpha - 1.0) * (alpha + 1.0 - dlog)
        speed, H_unit, dHdc_unit = unit_lattice(alpha, d, H, slope * H) if d > 0 else (math.inf, math.inf, math.inf)
        # the same wave in a window of 2M beads (M/2 more at rest behind), re-refined: the truncation's effect
        e2 = doubled.refine(embed(Y, 2 * p.M, p.M // 2), d)
        *_, rest2, jc2 = window_spectrum(doubled.window(d), e2.Y, 0.0, lambda J: weighted_multipliers(J, eta))
        H2 = window_energy(model, e2.Y)
        compared = [v for v in rest[:NDOM] if abs(v) > max(POINT_MARGIN * essential, 1e-3)]
        moved = [float(np.min(np.abs(rest2 - v))) for v in compared]
        points = [m for m in moved if m < CONVERGED]          # the others move: the finite window's transport part
        doubling = max([abs(H2 - H) / H, abs(symplectic_product(jc2.v1, jc2.v2) / H2 - slope) / slope] + points)
        r = np.diff(Y[:, 0])
        deepest = float(np.max(np.abs(r)))
        return dict(alpha=alpha, c0=c0, delta0=d, kappa=tail_rate(c0), residual=ex.residual,
                    residual_check=check.window(d).residual(Y, 0.0), iterations=ex.iterations, D=ex.D, H=H,
                    log_slope=slope, log_slope_fd=slope_fd, speed=speed, H_unit=H_unit, dHdc_unit=dHdc_unit,
                    jordan_mean=mean.real, jordan_split=split, jordan_translation=jc.translation,
                    jordan_generalized=jc.generalized, max_nontrivial=float(abs(rest[0])), essential=essential,
                    eta=eta, points=len(points), unstable=int(np.sum(np.abs(rest) > 1 + p.tol_unstable)),
                    tail_front=abs(float(r[-1])) / deepest, tail_rear=abs(float(r[0])) / deepest,
                    doubling_change=doubling, seconds=time.perf_counter() - t0, multipliers=lam,
                    dominant=np.pad(rest[:NDOM], (0, max(0, NDOM - len(rest)))), state=Y)

    def destroy(self):
        for tools in self._tools.values():
            for t in tools:
                t.destroy()
        self._tools = {}

    # --- output ---------------------------------------------------------------------------------------------
    def rows(self):
        return sorted(self.records, key=lambda r: (float(r["alpha"]), float(r["c0"])))

    def table(self):
        p = self.params
        lines = [f"Solitary waves (Delta = 0) at unit speed on a window of M = {p.M} beads (tails at the ends "
                 f"<= {p.tail:g} of the deepest compression), continued in the precompression delta0 = (c0^2 / "
                 "alpha)^(1/(alpha-1)); c0 = sqrt(V''(0)) in units of the wave's speed (c0 = 0: the uncompressed "
                 "chain; c / c0 the Mach number). Multipliers: LAPACK on the 2M x 2M window map weighted by "
                 "exp(eta j) (eta of r_ess; 2.5 at c0 = 0); the Jordan pair at 1 by its mean (split); r_ess: the "
                 "weighted essential-spectrum radius (min over eta); point: "
                 f"multipliers above {POINT_MARGIN:g} r_ess moved < {CONVERGED:g} by a window of 2M beads; "
                 f"unstable: |mu| > 1 + {p.tol_unstable:g}. Energy slope d ln H / d ln c at fixed lattice: "
                 "omega(v1, v2) / H from the Jordan vectors, and from H along the family (finite differences in "
                 "delta0, +- 1e-4 relative; c0 = 0: the closed form 2(alpha+1)/(alpha-1)). Lattice of "
                 "precompression 1: speed c and dH/dc of the same wave. 2M: max relative change of H and the "
                 "slope, and max change of the point multipliers, in the doubled window.\n",
                 "| alpha | c0 | c/c0 | delta0 | kappa | residual / check | Jordan pair (split) | dominant mu_3, "
                 "mu_4, mu_5 | r_ess (eta) | point | unstable | H | d ln H/d ln c: omega / FD | c, dH/dc "
                 "(delta0 = 1) | tails front / rear | 2M change | s |",
                 "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in self.rows():
            a, c0 = float(r["alpha"]), float(r["c0"])
            fd = float(r["log_slope_fd"])
            fd_text = f"{fd:.8f}" if math.isfinite(fd) else f"{2 * (a + 1) / (a - 1):.8f} (closed form)"
            mach = f"{1 / c0:.4f}" if c0 > 0 else "inf"
            unit = (f"{float(r['speed']):.6f}, {float(r['dHdc_unit']):.6g}" if math.isfinite(float(r["speed"]))
                    else "(scale-free)")
            dom = ", ".join(fmt_multiplier(v) for v in r["dominant"][:3])
            lines.append(SOLITARY_KIND.row(
                r, "{alpha}", "{c0}", mach, "{delta0}", "{kappa}", "{residual} / {residual_check}",
                "{jordan_mean} ({jordan_split})", dom, "{essential} ({eta})", "{points}", int(r["unstable"]) or "none",
                "{H}", "{log_slope} / " + fd_text, unit, "{tail_front} / {tail_rear}", "{doubling_change}",
                "{seconds}"))
        return "\n".join(lines) + "\n"

    def summary(self):
        """One line per alpha: the energy slope's range and sign, the largest multiplier, unstable ones, the
        verdicts of both routes."""
        lines = ["| alpha | c0 scanned | d ln H / d ln c (min ... max) | sign of dH/dc | energy criterion | max "
                 "nontrivial \\|mu\\| (at c0) | unstable multipliers | spectral verdict | max \\|omega - FD\\| / FD | "
                 "max 2M change |", "|---|---|---|---|---|---|---|---|---|---|"]
        for a, rs in self.by_alpha():
            s = np.array([float(r["log_slope"]) for r in rs])
            fd = np.array([float(r["log_slope_fd"]) for r in rs])
            ok = np.isfinite(fd)
            mu = np.array([float(r["max_nontrivial"]) for r in rs])
            k = int(np.argmax(mu))
            unstable = sum(int(r["unstable"]) for r in rs)
            sign = "> 0 throughout" if (s > 0).all() else ("< 0 throughout" if (s < 0).all() else "changes")
            crit = "no change of stability along the family" if sign != "changes" else "a change of stability"
            lines.append(f"| {a:g} | {len(rs)}: {min(float(r['c0']) for r in rs):g} ... "
                         f"{max(float(r['c0']) for r in rs):g} | {s.min():.4f} ... {s.max():.4f} | {sign} | {crit} | "
                         f"{mu[k]:.6f} ({float(rs[k]['c0']):g}) | {unstable or 'none'} | "
                         f"{'unstable' if unstable else 'stable'} | "
                         + (f"{np.max(np.abs(s[ok] - fd[ok]) / np.abs(fd[ok])):.1e}" if ok.any() else "n/a") +
                         f" | {max(float(r['doubling_change']) for r in rs):.1e} |")
        return "\n".join(lines) + "\n"
