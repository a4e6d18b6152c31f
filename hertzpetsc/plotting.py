"""Figures of the paper, from results (branches, refinement and Floquet records, snapshots, waves).

Every ``plot_*`` function returns a :class:`matplotlib.figure.Figure` (:func:`plot_long_wave` and
:func:`plot_branch_figures` a list of them): in a notebook the figure shows as the cell's value, and
``fig.savefig(...)`` writes it anywhere. A file is written only when ``directory`` is given: ``directory/name``
(the file name the drivers write; ``name=`` where a function takes one), atomically, on the calling rank, its path
then in ``fig.path`` (None when nothing was written); the drivers in scripts/ call them so, on rank 0. Called by
scripts and notebooks, never by solvers.

matplotlib is imported lazily, and pyplot not at all: the figures are made by ``Figure`` directly, so this module
chooses no backend (a notebook's inline backend stays) and runs on a machine without a screen.
"""
from __future__ import annotations

import math
import os

from typing import TYPE_CHECKING, Any, Mapping, Optional, Sequence

import numpy as np

from .diagnostics import dispersion, dispersion_long_wave
from .model import LatticeModel
from .records import save_figure

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from .branch import Branch, BranchPoint


def _subplots(*args, figsize, **kwargs):
    """A new :class:`matplotlib.figure.Figure` and its axes (``Figure.subplots``), outside pyplot: no backend is
    chosen or changed, nothing is kept by pyplot's figure manager (a figure nobody holds is freed)."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=figsize)
    return fig, fig.subplots(*args, **kwargs)


def _finish(fig, directory, name, tight=True):
    """The figure, laid out, with ``fig.path`` the file it was written to: ``directory/name`` (atomically, the
    format from the name) when a directory is given, else None and nothing written."""
    if tight:
        fig.tight_layout()
    fig.path = None if directory is None else save_figure(fig, os.path.join(directory, name))
    return fig


def _columns(rows, *keys):
    """One float array per key, over the records ``rows``."""
    return [np.array([float(r[k]) for r in rows]) for k in keys]


def branch_k_alpha(branch: Branch) -> float:
    """Estimate of k_alpha from the branch: ||u||_inf q^(2/(alpha-1)) at its smallest q (eq. normscaling)."""
    return float(branch.column("rescaled_norm")[np.argmin(branch.q)])


def plot_profiles(branch: Branch, directory: Optional[str] = None,
                  qs: Sequence[float] = (math.pi, 3 * math.pi / 10, math.pi / 50)) -> Figure:
    """Fig. profiles (profiles.png): u(xi; q) on a period for the branch points nearest to ``qs``."""
    fig, axes = _subplots(len(qs), 1, figsize=(6, 2.2 * len(qs)))
    xi = branch.xi
    xfull = np.concatenate([xi[:-1], 2 * math.pi - xi[:0:-1]])
    for ax, q in zip(np.atleast_1d(axes), qs):
        point = branch.points[int(np.argmin(np.abs(branch.q - q)))]      # the branch point nearest to q
        ax.plot(xfull, point.u_full, "k-", lw=1)
        ax.set(xlim=(0, 2 * math.pi), ylabel=r"$u(\xi)$")
        ax.set_title(rf"$q = {point.q:.4f}$", fontsize=10)
    np.atleast_1d(axes)[-1].set_xlabel(r"$\xi$")
    return _finish(fig, directory, "profiles.png")


def _plot_power_law(branch, directory, name, field, factor, k_alpha, ylabel, data_label, line_label):
    """Branch values of ``field`` vs q (log scale) with the line factor k_alpha q^(2/(1-alpha))."""
    a = branch.alpha
    k = branch_k_alpha(branch) if k_alpha is None else k_alpha
    q = branch.q
    qq = np.linspace(q.min(), math.pi, 200)
    fig, ax = _subplots(figsize=(6, 4))
    ax.semilogy(q, branch.column(field), "ko", ms=3, label=data_label)
    ax.semilogy(qq, factor * k * qq ** (2 / (1 - a)), "b-", lw=1,
                label=line_label + f", $k_\\alpha$ = {k:.4f}" + (" (branch, min q)" if k_alpha is None else ""))
    ax.set(xlabel="$q$", ylabel=ylabel)
    ax.legend()
    return _finish(fig, directory, name)


def plot_norms(branch: Branch, directory: Optional[str] = None, k_alpha: Optional[float] = None) -> Figure:
    """Fig. normes (normes.png): ||u||_inf vs q (log scale) and the line k_alpha q^(2/(1-alpha))."""
    return _plot_power_law(branch, directory, "normes.png", "norm_inf", 1.0, k_alpha, r"$\|u\|_\infty$",
                           "computed", r"$k_\alpha q^{2/(1-\alpha)}$")


def plot_slopes(branch: Branch, directory: Optional[str] = None, k_alpha: Optional[float] = None) -> Figure:
    """Fig. pentes (pentes.png): free-flight slope p(q) = u'(0) vs q (log scale) and the line (k_alpha/pi)
    q^(2/(1-alpha))."""
    return _plot_power_law(branch, directory, "pentes.png", "slope", 1 / math.pi, k_alpha, "$u'$",
                           "computed $u'(0)$", r"$(k_\alpha/\pi)\, q^{2/(1-\alpha)}$")


def plot_number(branch: Branch, directory: Optional[str] = None) -> Figure:
    """Fig. number (number.png): N(q), the mean number of adjacent interacting beads."""
    fig, ax = _subplots(figsize=(6, 4))
    ax.plot(branch.q, branch.column("N"), "k.-", ms=4, lw=0.8)
    ax.set(xlabel="$q$", ylabel="$N(q)$")
    ax.grid(alpha=0.3)
    return _finish(fig, directory, "number.png")


def plot_free_flight(branch: Branch, directory: Optional[str] = None) -> Figure:
    """Fig. lsq (lsq.png): F(q) = 2 ell(q) / q, with F = 1 and q_k marked."""
    qk = branch.q_k()
    F = branch.column("F")
    fig, ax = _subplots(figsize=(6, 4))
    pos = F > 0  # F(pi) = 0: no free flight for the binary oscillation
    ax.semilogy(branch.q[pos], F[pos], "k.-", ms=4, lw=0.8)
    ax.axhline(1.0, color="gray", lw=0.6)
    if np.isfinite(qk):
        ax.axvline(qk, color="b", lw=0.6, ls="--", label=rf"$q_k = {qk:.3f}$")
        ax.legend()
    ax.set(xlabel="$q$", ylabel=r"$F(q) = 2\ell(q)/q$")
    return _finish(fig, directory, "lsq.png")


def plot_dispersion(branch: Branch, directory: Optional[str] = None, k_alpha: Optional[float] = None) -> Figure:
    """Fig. dispersplot (dispersplot.png): omega(q, A0) (eq. dispers) and its linear approximation at q = 0 (eq.
    disperseq)."""
    law = LatticeModel.hertz(branch.alpha).law
    A0 = float(law.amplitude(law.p0))
    k = branch_k_alpha(branch) if k_alpha is None else k_alpha
    q, norm = branch.q, branch.column("norm_inf")
    qq = np.linspace(0, math.pi, 200)
    fig, ax = _subplots(figsize=(6, 4))
    ax.plot(q, dispersion(norm, A0, law.alpha), "k.-", ms=4, lw=0.8, label=r"$\omega(q, A_0)$")
    ax.plot(qq, dispersion_long_wave(qq, A0, law.alpha, k), "b--", lw=0.8, label="linear approximation")
    ax.set(xlabel="$q$", ylabel=r"$\omega$", ylim=(0, 1.1 * max(1.0, float(np.max(dispersion(norm, A0, law.alpha))))))
    ax.legend()
    return _finish(fig, directory, "dispersplot.png")


def plot_branch_figures(branch: Branch, directory: Optional[str] = None,
                        k_alpha: Optional[float] = None) -> list[Figure]:
    """All figures of section 3.1, in this order: profiles, normes, pentes, number, lsq, dispersplot."""
    return [plot_profiles(branch, directory), plot_norms(branch, directory, k_alpha),
            plot_slopes(branch, directory, k_alpha), plot_number(branch, directory),
            plot_free_flight(branch, directory), plot_dispersion(branch, directory, k_alpha)]


# --- section 3.4: residuals and chain dynamics ---------------------------------------------------------------
def plot_errors(refined: Any, directory: Optional[str] = None) -> Figure:
    """Fig. errors (errors.png): E(q) before (dotted) and after (full) refinement, and r(q) (dash-dot), semi-log, from a
    :class:`~hertzpetsc.studies.refinement.RefinedStates`."""
    order = np.argsort(refined.q)
    q = refined.q[order]
    fig, ax = _subplots(figsize=(6, 4))
    ax.semilogy(q, refined.column("E_before_paper_flow")[order], "k:", label="E(q), branch wave (rtol 1e-12 flow)")
    ax.semilogy(q, refined.column("E_after")[order], "k-", label="E(q), refined (rtol 1e-14 flow)")
    ax.semilogy(q, refined.column("r")[order], "k-.", lw=0.8, label="r(q), last Gauss-Newton step")
    ax.set(xlabel="$q$", ylabel="errors")
    ax.legend(fontsize=8)
    return _finish(fig, directory, "errors.png")


def bond_forces(states: np.ndarray) -> np.ndarray:
    """V'(x_{n+1} - x_n) / (-|.|^alpha) without alpha on the ring: the bond compressions min(x_{n+1} - x_n, 0),
    per snapshot."""
    x = states[..., 0]
    return np.minimum(np.roll(x, -1, axis=-1) - x, 0.0)


def plot_snapshot(x0: np.ndarray, xt: np.ndarray, t: float, directory: Optional[str] = None,
                  name: str = "snapshot.png", title: str = "") -> Figure:
    """Bead displacements at time t (line) against the initial state (dots), as in figs. stabletw, shockbis."""
    fig, ax = _subplots(figsize=(6, 3))
    n = np.arange(1, len(x0) + 1)
    ax.plot(n, xt, "k-", lw=1, label=f"$t = {t:.1f}$")
    ax.plot(n, x0, "b.", ms=3, label="$t = 0$")
    ax.set(xlabel="$n$", ylabel="$x_n$")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    return _finish(fig, directory, name)


def _spacetime(image, times, n0, cmap, label, directory, name, title):
    """``image`` (times x beads, bead j at n0 + j) in grey levels over (n, t), with its colour bar."""
    fig, ax = _subplots(figsize=(6, 4))
    im = ax.imshow(image, aspect="auto", origin="lower", cmap=cmap,
                   extent=(n0 - 0.5, image.shape[1] + n0 - 0.5, times[0], times[-1]))
    fig.colorbar(im, ax=ax, label=label)
    ax.set(xlabel="$n$", ylabel="$t$")
    ax.set_title(title, fontsize=9)
    return _finish(fig, directory, name)


def plot_spacetime_forces(times: np.ndarray, states: np.ndarray, alpha: float, directory: Optional[str] = None,
                          name: str = "forces.png", title: str = "") -> Figure:
    """Interaction forces V'(x_{n+1} - x_n) in grey levels over (n, t) (figs. stabletw ... structures)."""
    return _spacetime(-np.abs(bond_forces(states)) ** alpha, times, 1, "gray", r"$V'(x_{n+1}-x_n)$", directory,
                      name, title)


def plot_deviation(runs: Mapping[str, tuple[np.ndarray, np.ndarray]], directory: Optional[str] = None,
                   name: str = "deviation.png") -> Figure:
    """D(t) = ||S^k X(k T) - X(0)|| / ||X(0)|| for several runs (dict label -> (t, D)), log scale."""
    fig, ax = _subplots(figsize=(6, 4))
    for label, (t, D) in runs.items():
        ax.semilogy(t, np.maximum(D, 1e-16), lw=0.8, label=label)
    ax.set(xlabel="$t$", ylabel="deviation from the travelling wave")
    ax.legend(fontsize=8)
    return _finish(fig, directory, name)


# --- section 3.5: Floquet multipliers ---------------------------------------------------------------------------
def plot_floquet_radius(q: np.ndarray, rho: np.ndarray, tol_rho: float, directory: Optional[str] = None) -> Figure:
    """Fig. floquet (floquet.png): spectral radius of the monodromy matrix modulo shifts vs q."""
    order = np.argsort(q)
    fig, ax = _subplots(figsize=(6, 4))
    ax.plot(np.asarray(q)[order], np.asarray(rho)[order], "k.-", ms=4, lw=0.8)
    ax.axhline(1 + tol_rho, color="gray", lw=0.6, ls="--", label=rf"$1 + {tol_rho:g}$")
    ax.set(xlabel="$q$", ylabel=r"$\rho(\mathcal{F}_q)$")
    ax.legend(fontsize=8)
    return _finish(fig, directory, "floquet.png")


def draw_multipliers(ax: Axes, lam: np.ndarray, title: Optional[str] = None, ms: float = 5,
                     inner: Optional[float] = None) -> Axes:
    """Multipliers ``lam`` in the complex plane with the unit circle (and the circle of radius ``inner``, dotted), on
    the matplotlib axes ``ax`` (fig. eigen)."""
    th = np.linspace(0, 2 * math.pi, 400)
    lam = np.asarray(lam)
    lam = lam[np.isfinite(lam)]
    ax.plot(np.cos(th), np.sin(th), "b-", lw=0.6)
    if inner is not None:
        ax.plot(inner * np.cos(th), inner * np.sin(th), "g:", lw=0.6)
    ax.plot(lam.real, lam.imag, "k+", ms=ms)
    ax.set_aspect("equal")
    if title:
        ax.set_title(title, fontsize=10)
    return ax


def plot_multipliers(panels: Sequence[tuple[str, np.ndarray]], directory: Optional[str] = None) -> Figure:
    """Fig. eigen (eigen.png): multipliers in the complex plane with the unit circle; ``panels`` = [(label,
    multipliers)]."""
    fig, axes = _subplots(2, 2, figsize=(8, 8))
    for ax, (label, lam) in zip(axes.ravel(), panels):
        draw_multipliers(ax, lam, f"q = {label}")
    return _finish(fig, directory, "eigen.png")


# --- appendix: the solitary wave -------------------------------------------------------------------------------
def plot_solitary(wave: Any, directory: Optional[str] = None) -> Figure:
    """Fig. ondesol (ondesol.png): r(s) (top) and the displacement y(s) (bottom) of the unit-velocity solitary wave."""
    s = np.concatenate([-wave.s[:0:-1], wave.s])
    r = np.concatenate([wave.r[:0:-1], wave.r])
    y = np.concatenate([-wave.y[:0:-1], wave.y])
    fig, (a1, a2) = _subplots(2, 1, figsize=(6, 5))
    a1.plot(s, r, "k-", lw=1)
    a1.set_ylabel("$r(s)$")
    a2.plot(s, y, "k-", lw=1)
    a2.axhline(wave.k_alpha, color="gray", lw=0.5, ls="--")
    a2.axhline(-wave.k_alpha, color="gray", lw=0.5, ls="--")
    a2.set(ylabel="$y(s)$", xlabel="$s$")
    a1.set_title(rf"$\alpha = {wave.params.alpha}$, $k_\alpha = {wave.k_alpha:.5f}$", fontsize=10)
    return _finish(fig, directory, "ondesol.png")


def plot_long_wave(wave: Any, point: BranchPoint, directory: Optional[str] = None, zoom: float = 0.3) -> list[Figure]:
    """Figs. approxz (the rescaled profile of a branch point near pi against the inner solution) and approx
    (against the composite approximation of eq. solapprox over the period)."""
    from .longwave import composite_profile, inner_solution
    u_half, q = point.u_half, point.q
    K = len(u_half) - 1
    xi = np.arange(2 * K + 1) * math.pi / K
    ut = q ** point.model.law.rescaling_exponent * np.concatenate([u_half, -u_half[-2::-1]])
    near = np.abs(xi - math.pi) <= zoom
    figures = []
    for name, shown, approximation, label in (
            ("approxz.png", near, lambda x: inner_solution(wave, (x - math.pi) / q), "inner solution (eq. inner)"),
            ("approx.png", slice(None), lambda x: composite_profile(wave, q, x), "composite (eq. solapprox)")):
        fig, ax = _subplots(figsize=(6, 4))
        ax.plot(xi[shown], ut[shown], "k-", lw=1.2, label=rf"computed, $q = {q:.4f}$")
        ax.plot(xi[shown], approximation(xi[shown]), "b-", lw=0.8, label=label)
        ax.set(xlabel=r"$\xi$", ylabel=r"$\tilde u(\xi)$")
        ax.legend(fontsize=8)
        figures.append(_finish(fig, directory, name))
    return figures


# --- section 3.3: compactons ------------------------------------------------------------------------------------
def plot_compacton_profiles(single: Any, double: Any, directory: Optional[str] = None) -> Figure:
    """Fig. graphulin (graphulin.png): U_q (eq. extens, top) and U^(2)_{q, theta} (eq. extens2, bottom), with the
    compression regions (ell, 2 pi - ell) + s_j shaded."""
    fig, axes = _subplots(2, 1, figsize=(6, 6))
    for ax, train in zip(axes, (single, double)):
        xi = np.linspace(-2 * math.pi, train.offsets[-1] + 4 * math.pi, 2000)
        ax.plot(xi, train(xi), "k-", lw=1)
        for s in train.offsets:
            ax.axvspan(s + train.ell, s + 2 * math.pi - train.ell, color="0.85", lw=0)
        theta = "" if train.count == 1 else rf", $\theta = {train.offsets[1] - 2 * math.pi:.3g}$"
        ax.set(xlabel=r"$\xi$", ylabel="$U_q$" if train.count == 1 else "$U^{(2)}_{q,\\theta}$")
        ax.set_title(rf"$q = {train.q:.4f}$, $F(q) = {train.F:.3f}$" + theta, fontsize=9)
    return _finish(fig, directory, "graphulin.png")


def plot_spacetime_velocities(times: np.ndarray, states: np.ndarray, directory: Optional[str] = None,
                              name: str = "velocities.png", title: str = "") -> Figure:
    """Bead velocities xdot_n over (n, t): compactons travel through beads at rest (white = exactly 0)."""
    return _spacetime(states[..., 1], times, 0, "gray_r", r"$\dot x_n$", directory, name, title)


# --- section 3.2 beyond the paper: small q -------------------------------------------------------------------------
def plot_small_q(q: np.ndarray, levels: Sequence[np.ndarray], extrapolated: np.ndarray, k_alpha: float,
                 directory: Optional[str] = None) -> Figure:
    """||u||_inf q^(2/(alpha-1)) against q on each grid level and extrapolated in h, with k_alpha (eq.
    normscaling): the long-wave limit beyond the paper's q = pi/50."""
    fig, ax = _subplots(figsize=(6, 4))
    for lev, values in enumerate(levels):
        ax.semilogx(q, values, ".-", lw=0.6, ms=3, color=str(0.7 - 0.25 * lev), label=f"level {lev}")
    ax.semilogx(q, extrapolated, "k.-", lw=1.2, label="extrapolated in $h$")
    ax.axhline(k_alpha, color="b", lw=0.8, ls="--", label=rf"$k_\alpha = {k_alpha:.5f}$")
    ax.set(xlabel="$q$", ylabel=r"$\|u\|_\infty\, q^{2/(\alpha-1)}$")
    ax.legend(fontsize=8)
    return _finish(fig, directory, "smallq.png")


# --- isolated compactons: window spectra and perturbed dynamics (hertzpetsc.studies.compacton_stability) ---------
def plot_compacton_max_multiplier(rows: Sequence[Mapping], directory: Optional[str] = None) -> Figure:
    """Largest nontrivial |mu| of the compacton window map against q (log q), one curve per alpha; the solitary
    wave (q = 0) as a dashed level."""
    fig, ax = _subplots(figsize=(6, 4))
    for k, a in enumerate(sorted({float(r["alpha"]) for r in rows})):
        rs = [r for r in rows if float(r["alpha"]) == a]
        q, mu = _columns(rs, "q", "max_nontrivial")
        pos = q > 0
        order = np.argsort(q[pos])
        line, = ax.semilogx(q[pos][order], mu[pos][order], ".-", ms=5, lw=0.8, label=rf"$\alpha = {a:g}$")
        if (~pos).any():
            ax.axhline(mu[~pos][0], color=line.get_color(), lw=0.6, ls="--")
    ax.axhline(1.0, color="k", lw=0.6)
    ax.set(xlabel="$q$", ylabel=r"max nontrivial $|\mu|$ (window map)")
    ax.set_title("isolated compactons; dashed: solitary wave ($q \\to 0$)", fontsize=9)
    ax.set_ylim(0, 1.05)
    ax.legend(fontsize=8)
    return _finish(fig, directory, "compacton_stability_mu.png")


def plot_compacton_spectra(rows: Sequence[Mapping], eta: float, directory: Optional[str] = None) -> Figure:
    """All window multipliers of the given records in the complex plane, with the unit circle and the circle
    exp(-eta) below which the transport part lies in the weighted space."""
    fig, axes = _subplots(1, len(rows), figsize=(4 * len(rows), 4))
    for ax, r in zip(np.atleast_1d(axes), rows):
        draw_multipliers(ax, r["multipliers"], rf"$\alpha = {float(r['alpha']):g}$, $q = {float(r['q']):.4f}$", ms=6,
                         inner=math.exp(-eta))
    return _finish(fig, directory, "compacton_stability_spectra.png")


def plot_solitary_stability(rows: Sequence[Mapping], directory: Optional[str] = None) -> Figure:
    """Left: the energy slope d ln H / d ln c at fixed lattice against the Mach number c / c0 (Jordan vectors: lines,
    finite differences along the family: circles), the uncompressed value 2(alpha+1)/(alpha-1) dashed; right: the
    largest nontrivial |mu| of the window map and the weighted essential-spectrum radius against c0."""
    fig, (ax, bx) = _subplots(1, 2, figsize=(10, 4))
    for a in sorted({float(r["alpha"]) for r in rows}):
        rs = sorted((r for r in rows if float(r["alpha"]) == a), key=lambda r: float(r["c0"]))
        c0, slope, fd = _columns(rs, "c0", "log_slope", "log_slope_fd")
        pos = c0 > 0
        line, = ax.plot(1 / c0[pos], slope[pos], "-", lw=0.9, label=rf"$\alpha = {a:g}$")
        ax.plot(1 / c0[pos], fd[pos], "o", mfc="none", color=line.get_color(), ms=5)
        ax.axhline(2 * (a + 1) / (a - 1), color=line.get_color(), lw=0.6, ls="--")
        bx.plot(c0, [float(r["max_nontrivial"]) for r in rs], ".-", color=line.get_color(), lw=0.9,
                label=rf"max $|\mu|$, $\alpha = {a:g}$")
    ess = sorted({(float(r["c0"]), float(r["essential"])) for r in rows})
    bx.plot([e[0] for e in ess], [e[1] for e in ess], "k:", lw=0.9, label=r"$r_{ess}$")
    bx.axhline(1.0, color="k", lw=0.6)
    ax.set_xscale("log")
    ax.set_xticks([1.1, 1.25, 1.5, 2, 3, 5])
    ax.set_xticklabels(["1.1", "1.25", "1.5", "2", "3", "5"])
    ax.minorticks_off()
    ax.set(xlabel="Mach number $c / c_0$", ylabel=r"$d \ln H / d \ln c$ (fixed lattice)")
    ax.set_title("energy criterion: no change of sign", fontsize=9)
    ax.legend(fontsize=8)
    bx.set(xlabel="$c_0 / c$", ylabel=r"window multipliers", ylim=(0, 1.05))
    bx.set_title("spectral route: largest nontrivial multiplier", fontsize=9)
    bx.legend(fontsize=7)
    return _finish(fig, directory, "solitary_stability.png")


def plot_compacton_dynamics(records: Sequence[Mapping], directory: Optional[str] = None) -> Figure:
    """Left: |rest| (deviation from the Jordan block at 1) against the beads travelled, with |mu_3|^k; right: the
    first record's deviation per window bead (space-time, log10)."""
    fig, (ax, bx) = _subplots(1, 2, figsize=(11, 4))
    for r in records:
        rest = np.asarray(r["rest"])
        k = np.arange(len(rest))
        line, = ax.semilogy(k, np.maximum(rest, 1e-18), lw=0.7, label=f"q = {float(r['q']):.4f}, {r['kind']}")
        if str(r["kind"]) == "mode":
            pred = rest[0] * np.abs(complex(r["mu3"])) ** k
            keep = pred > 1e-16
            ax.semilogy(k[keep], pred[keep], ls="--", lw=0.7, color=line.get_color())
    ax.set_xscale("symlog", linthresh=50)
    ax.set(xlabel="beads travelled $k$ (= time)", ylabel=r"$|\delta_k - a v_1 - b v_2|$ (relative)")
    ax.set_title(r"dashed: $|\mu_3|^k$", fontsize=9)
    ax.legend(fontsize=7)
    r = records[0]
    dev = np.log10(np.maximum(np.asarray(r["deviation"]), 1e-18))
    im = bx.pcolormesh(np.arange(dev.shape[0]), np.arange(dev.shape[1]), dev.T, cmap="viridis",
                       vmin=max(dev.min(), -14), shading="nearest")
    fig.colorbar(im, ax=bx, label=r"$\log_{10}$ |deviation| (window bead)")
    bx.set_xscale("symlog", linthresh=50)
    bx.set(xlabel="time = beads travelled", ylabel="window bead (moving frame)")
    bx.set_title(f"q = {float(r['q']):.4f}, {r['kind']}: perturbed compacton, moving frame", fontsize=9)
    return _finish(fig, directory, "compacton_dynamics.png")


# --- beyond the paper: slow instabilities above q_c on the infinite chain --------------------------------------------
def plot_slow_instabilities(records: Sequence[Mapping], target: float, alpha: float, directory: Optional[str] = None,
                            name: str = "slow_instabilities.png") -> Figure:
    """gamma(q) on a log scale from the slow-instability records: the co-moving route on each grid and the
    deflated monodromy route (|gamma|: both are rounding-level where stable), the undeflated symmetry cluster
    (ln(1 + raw |mu| - 1) / script-T, what an undeflated spectrum shows) and the target resolution."""
    rows = sorted(records, key=lambda r: float(r["q"]))
    q, T = _columns(rows, "q", "T")
    g = np.array([np.abs(np.asarray(r["gamma_cm"], dtype=float)) for r in rows])
    floor = 1e-17
    fig, ax = _subplots(figsize=(7, 4.2))
    for k in range(g.shape[1]):
        ax.semilogy(q, np.maximum(g[:, k], floor), "o-" if k == g.shape[1] - 1 else ".",
                    ms=3 + k, lw=0.6, color=str(0.6 - 0.3 * k / max(1, g.shape[1] - 1)),
                    label=f"co-moving QEP, grid {k}" + (" (finest)" if k == g.shape[1] - 1 else ""))
    mono = np.array([abs(float(r["gamma_mono"])) for r in rows])
    raw = np.array([math.log1p(max(float(r["raw_cluster_mono"]), 0.0)) for r in rows]) / T
    ok = np.isfinite(mono)
    if ok.any():
        ax.semilogy(q[ok], np.maximum(mono[ok], floor), "s", ms=4, color="tab:blue", mfc="none",
                    label="monodromy, symmetry multipliers deflated")
        ax.semilogy(q[ok], np.maximum(raw[ok], floor), "x", ms=4, color="tab:red",
                    label="monodromy, symmetry cluster undeflated")
    ax.axhline(target, color="k", ls="--", lw=0.8, label=f"target resolution {target:g}")
    unstable = np.array([int(r["verdict"]) for r in rows]) == 1
    if unstable.any():
        ax.semilogy(q[unstable], g[unstable, -1], "r*", ms=9, label="slowly unstable")
    ax.set(xlabel="$q$", ylabel=r"$|\gamma(q)| = \max \ln|\mu| / \mathcal{T}$")
    ax.set_title(rf"$\alpha = {alpha:g}$: growth rates on the infinite chain", fontsize=9)
    ax.legend(fontsize=7, loc="best")
    return _finish(fig, directory, name)


# --- issue 16: precompressed and dimer chains ----------------------------------------------------------------------
def plot_precompressed_omega(curves: Mapping, alpha: float, delta0: float, directory: Optional[str] = None) -> Figure:
    """omega(q, A) of the precompressed chain against the acoustic omega_lin(q) (left) and, rescaled as
    omega A^(-(alpha-1)/2), against its uncompressed limit (right); open circles: the gap opening A_gap(q).
    ``curves``: {q: (A, omega, omega_lin, Omega0, (A_gap, omega_gap))}."""
    fig, (ax1, ax2) = _subplots(1, 2, figsize=(10, 4))
    e = (alpha - 1) / 2
    for i, (q, (A, omega, omega_lin, Omega0, (A_gap, omega_gap))) in enumerate(sorted(curves.items())):
        color = f"C{i}"
        label = f"q = {q / math.pi:.3g}$\\pi$"
        ax1.semilogx(A, omega / omega_lin, "-", color=color, lw=1, label=label)
        ax2.semilogx(A, omega * A ** (-e), "-", color=color, lw=1, label=label)
        if np.isfinite(Omega0):
            ax2.axhline(Omega0, color=color, ls="--", lw=0.7)
        if np.isfinite(A_gap):
            ax1.semilogx([A_gap], [omega_gap / omega_lin], "o", mfc="none", color=color)
            ax2.semilogx([A_gap], [omega_gap * A_gap ** (-e)], "o", mfc="none", color=color)
    ax1.set(xlabel=r"$A = \|u\|_\infty$" + f" ($\\delta_0$ = {delta0:g})", ylabel=r"$\omega / \omega_{lin}(q)$")
    ax2.set(xlabel=r"$A$", ylabel=r"$\omega A^{-(\alpha-1)/2}$ (dashed: uncompressed limit)", yscale="log")
    ax1.legend(fontsize=8)
    return _finish(fig, directory, "precompressed_omega.png")


def plot_dimer_epsilon(curves: Mapping, directory: Optional[str] = None) -> Figure:
    """Dimer waves continued in the mass ratio epsilon: omega (solid) and the linear acoustic frequency (dashed),
    and ||v||_inf of the light bead, against epsilon. ``curves``: {q: (epsilon, omega, omega_acoustic, norm_v)}."""
    fig, (ax1, ax2) = _subplots(1, 2, figsize=(10, 4))
    for i, (q, (eps, omega, omega_ac, norm_v)) in enumerate(sorted(curves.items())):
        color = f"C{i}"
        ax1.plot(eps, omega, ".-", color=color, ms=2, lw=0.8, label=f"q = {q / math.pi:.3g}$\\pi$")
        ax1.plot(eps, omega_ac, "--", color=color, lw=0.7)
        ax2.plot(eps, norm_v, ".-", color=color, ms=2, lw=0.8)
    ax1.set(xlabel=r"$\epsilon$ ($m_2 / m_1$)", ylabel=r"$\omega$ (dashed: linear acoustic branch)")
    ax2.set(xlabel=r"$\epsilon$", ylabel=r"$\|v\|_\infty$ (light bead)")
    ax1.legend(fontsize=8)
    return _finish(fig, directory, "dimer_epsilon.png")


def plot_stability_map(z: Mapping, directory: Optional[str] = None, name: str = "precompression_map.png") -> Figure:
    """The stability map of a ``hertzpetsc-precompression-map-2`` file's arrays ``z`` in the (q, A) plane: one panel
    per chain (N beads; the infinite chain when computed): the map's verdicts (open: stable; filled, coloured by
    log10(rho - 1): unstable), the located boundary points (triangles up: onset, down: offset), the unstable
    intervals between them (red bars), the uppermost located edge of each q joined along q, the gap opening A_gap(q)
    (dashed) and q_c of the uncompressed limit (shaded: between the largest q unstable at A = infinity and the next
    stable q of the map)."""
    from .verdicts import critical_wavenumbers
    from .verdicts import unstable_intervals
    tol = float(z["tol_rho"])
    kind = np.asarray(z["kind"])
    q, A = np.asarray(z["q"], float), np.asarray(z["A"], float)
    panels = [("rho", 1, f"N = {int(z['N'])}")]
    if int(z["twists"]):
        panels.append(("rho_inf", 2, "infinite chain"))
    fig, axes = _subplots(1, len(panels), figsize=(6 * len(panels), 4.8), squeeze=False)
    rho_all = np.concatenate([np.asarray(z[key], float) for key, _, _ in panels])
    bad_all = rho_all[np.isfinite(rho_all) & (rho_all - 1 > tol)]
    vmin = np.log10(tol)
    vmax = max(vmin + 1, float(np.log10(bad_all.max() - 1))) if len(bad_all) else vmin + 1
    gap = kind == 4
    order = np.argsort(q[gap])
    finite = np.isfinite(A) & (A > 0)
    lo_A, hi_A = (A[finite].min(), A[finite].max()) if finite.any() else (1e-2, 1e3)
    for ax, (key, edge, title) in zip(axes[0], panels):
        rho = np.asarray(z[key], float)
        pts = (kind == 0) & np.isfinite(rho)
        bad = pts & (rho - 1 > tol)
        ax.scatter(q[pts & ~bad], A[pts & ~bad], s=6, facecolors="none", edgecolors="0.6", lw=0.5, label="stable")
        sc = ax.scatter(q[bad], A[bad], s=8, c=np.log10(rho[bad] - 1), cmap="viridis", vmin=vmin, vmax=vmax,
                        label="unstable")
        located = kind == edge
        onset = located & (np.asarray(z["A_unstable"], float) > np.asarray(z["A_stable"], float))
        ax.scatter(q[onset], A[onset], marker="^", s=22, c="r", edgecolors="k", lw=0.4, label="onset (located)",
                   zorder=3)
        ax.scatter(q[located & ~onset], A[located & ~onset], marker="v", s=22, c="orange", edgecolors="k", lw=0.4,
                   label="offset (located)", zorder=3)
        for qq, spans in unstable_intervals(z, key).items():
            for a1, a2 in spans:
                if not (a1 == a1 and a2 == a2):        # an edge not located: nothing to draw between
                    continue
                ax.plot([qq, qq], [max(a1, lo_A), min(a2, hi_A)], color="r", lw=2.5, alpha=0.35,
                        solid_capstyle="butt", zorder=1)
        top_q = np.unique(q[located])
        if len(top_q) > 1:           # the uppermost located edge of each q: where the verdict becomes final
            ax.plot(top_q, [A[located & (q == qq)].max() for qq in top_q], "k-", lw=0.7, zorder=2, label="uppermost edge")
        if gap.any():
            ax.plot(q[gap][order], A[gap][order], "b--", lw=0.9, label=r"$A_{gap}(q)$")
        limit = (kind == 3) & np.isfinite(rho)
        # q_c lies between the largest q unstable at A = inf and the next stable one
        q_lo, q_hi, _ = critical_wavenumbers(q[limit], rho[limit], tol) if limit.any() else (math.nan, None, None)
        if q_hi is not None:
            ax.axvspan(q_lo, q_hi, color="0.85", zorder=0, label=r"$q_c$ (uncompressed) in here")
        elif q_lo == q_lo:
            ax.axvline(q_lo, color="k", ls=":", lw=0.9, label=r"$q_c$ (uncompressed) above")
        ax.set(yscale="log", xlabel="$q$", ylabel=r"$A = \|u\|_\infty$")
        ax.set_title(title, fontsize=10)
        ax.legend(fontsize=7, loc="upper right")
    fig.colorbar(sc, ax=list(axes[0]), label=r"$\log_{10}(\rho - 1)$")
    fig.suptitle(rf"$\alpha = {float(z['alpha']):g}$, $\delta_0 = {float(z['delta0']):g}$, masses "
                 + ", ".join(f"{m:g}" for m in np.asarray(z["masses"], float)), fontsize=10)
    return _finish(fig, directory, name, tight=False)


def plot_q_boundary(z: Mapping, directory: Optional[str] = None, name: str = "boundary_in_q.png",
                    zmap: Optional[Mapping] = None) -> Figure:
    """The infinite chain's boundary located in q at fixed A (a ``hertzpetsc-boundary-q-1`` file's arrays ``z``) in
    the (q, A) plane: each located edge as its bracket in q (red), the grid verdicts (open: stable, filled:
    unstable); with ``zmap`` (a stability-map file with the infinite chain) that map's edges located in A at its q
    (triangles) and A_gap(q) (dashed). A = inf is drawn at the top of the axis."""
    tol = float(z["tol_rho"])
    A, q, kind, grid = (np.asarray(z[k], float) for k in ("A", "q", "kind", "grid"))
    rho = np.asarray(z["rho_inf"], float)
    finite = A[np.isfinite(A)]
    top = (finite.max() if len(finite) else 1.0) * 3
    shown = np.where(np.isfinite(A), A, top)
    fig, ax = _subplots(figsize=(6.5, 4.8))
    pts = grid == 1
    bad = pts & (rho - 1 > tol)
    ax.scatter(q[pts & ~bad], shown[pts & ~bad], s=10, facecolors="none", edgecolors="0.5", lw=0.6,
               label="stable (grid q)")
    ax.scatter(q[bad], shown[bad], s=10, c="0.3", label="unstable (grid q)")
    edge = kind == 2
    qs, qu = np.asarray(z["q_stable"], float)[edge], np.asarray(z["q_unstable"], float)[edge]
    ax.errorbar(q[edge], shown[edge], xerr=np.abs(qu - qs) / 2, fmt="|", color="r", ms=9, mew=1.2,
                label="edge located in q")
    for i, qc in enumerate(q[edge & ~np.isfinite(A)]):
        ax.axvline(qc, color="k", ls=":", lw=0.9, label=r"$q_c$ (uncompressed, located)" if i == 0 else None)
    if zmap is not None and int(zmap["twists"]):
        mk, mq, mA = np.asarray(zmap["kind"]), np.asarray(zmap["q"], float), np.asarray(zmap["A"], float)
        ax.scatter(mq[mk == 2], mA[mk == 2], marker="^", s=18, c="orange", edgecolors="k", lw=0.4,
                   label="edge located in A (map)", zorder=3)
        gap = mk == 4
        order = np.argsort(mq[gap])
        ax.plot(mq[gap][order], mA[gap][order], "b--", lw=0.9, label=r"$A_{gap}(q)$")
    ax.set_yscale("log")
    if not np.all(np.isfinite(A)):
        ax.axhline(top, color="0.8", lw=0.6)
        ax.text(ax.get_xlim()[0], top, r" $A = \infty$", va="bottom", fontsize=7)
    ax.set(xlabel="$q$", ylabel=r"$A = \|u\|_\infty$")
    ax.set_title(rf"infinite chain, $\alpha = {float(z['alpha']):g}$, $\delta_0 = {float(z['delta0']):g}$: "
                 "boundary located in $q$", fontsize=10)
    ax.legend(fontsize=7, loc="upper right")
    return _finish(fig, directory, name, tight=False)


# --- driven, damped chains (issue 22) ---------------------------------------------------------------------------------
_EVENT_MARKERS = {1: ("o", "fold"), 2: ("s", "period doubling"), 3: ("D", "Neimark-Sacker")}


def plot_driven_response(records: Sequence[Mapping], parameter: str = "omega", directory: Optional[str] = None,
                         name: str = "driven_response.png", title: str = "") -> Figure:
    """A response curve: the largest force transmitted to the right end (Pozharskiy et al. 2015's observable) and
    the largest Floquet multiplier modulus against the parameter; stable points solid, unstable dotted; events
    marked; switched (period-doubled) branches in colour."""
    fig, (ax, bx) = _subplots(2, 1, figsize=(6.5, 6), sharex=True)
    branches = sorted({int(r["branch"]) for r in records})
    for j in branches:
        rs = [r for r in records if int(r["branch"]) == j]
        regular = [r for r in rs if int(r["event"]) == 0]
        if not regular:
            continue
        p, f, rho, amp = _columns(regular, "p", "force_right", "rho", "amp_max")
        y = f if np.any(np.isfinite(f)) else amp
        color = "k" if j == 0 else f"C{j}"
        if not np.any(np.isfinite(rho)):           # no multipliers (floquet none): no verdict to draw
            ax.plot(p, y, "-", color="0.4", lw=1.2, label=f"branch {j} (period {int(rs[0]['periods'])} T; "
                    "multipliers not computed)")
            bx.text(0.5, 0.5, "multipliers not computed", ha="center", va="center", transform=bx.transAxes)
            continue
        for axis, v, label in ((ax, y, f"branch {j} (period {int(rs[0]['periods'])} T; solid: stable)"),
                               (bx, rho, None)):
            axis.plot(p, v, ":", color=color, lw=0.9)
            axis.plot(p, np.where(rho < 1, v, np.nan), "-", color=color, lw=1.6, label=label)
        for r in rs:
            ev = int(r["event"])
            if ev in _EVENT_MARKERS:
                m, lab = _EVENT_MARKERS[ev]
                yv = float(r["force_right"]) if np.isfinite(float(r["force_right"])) else float(r["amp_max"])
                for axis, v in ((ax, yv), (bx, float(r["rho"]))):
                    axis.plot(float(r["p"]), v, m, mfc="r" if int(r["confirmed"]) else "none", mec="r", ms=6)
    for ev, (m, lab) in _EVENT_MARKERS.items():
        ax.plot([], [], m, mfc="r", mec="r", label=lab)
    ax.set_ylabel("max force on the wall")
    ax.legend(fontsize=7)
    if title:
        ax.set_title(title, fontsize=9)
    bx.axhline(1.0, color="0.6", lw=0.8)
    bx.set(ylabel=r"$\max |\mu|$",
           xlabel={"omega": r"$\omega$", "amplitude": "$a$", "gamma": r"$\gamma$"}.get(parameter, parameter))
    return _finish(fig, directory, name)


def plot_driven_resonances(records: Sequence[Mapping], directory: Optional[str] = None,
                           name: str = "driven_resonances.png") -> Figure:
    """Small-amplitude resonances: peak frequencies from shooting and from the damped linear chain against the
    normal modes omega_k, and their differences."""
    fig, (ax, bx) = _subplots(2, 1, figsize=(6, 5.5), sharex=True)
    recs = sorted(records, key=lambda r: int(r["k"]))
    k = np.array([int(r["k"]) for r in recs])
    wk, pl, ps = _columns(recs, "omega_k", "peak_linear", "peak_shooting")
    ax.plot(k, wk, "k-", lw=1, label=r"$\omega_k$ (closed form)")
    ax.plot(k, pl, "o", mfc="none", mec="C0", label="peak, damped linear chain")
    ax.plot(k, ps, "x", color="C3", label="peak, shooting (Hertz chain)")
    ax.set_ylabel("frequency")
    ax.legend(fontsize=8)
    bx.semilogy(k, np.abs(pl - wk), "o-", mfc="none", color="C0", label="|peak linear - omega_k|")
    bx.semilogy(k, np.maximum(np.abs(ps - pl), 1e-16), "x-", color="C3", label="|peak shooting - peak linear|")
    bx.set_xlabel("mode $k$")
    bx.legend(fontsize=8)
    return _finish(fig, directory, name)


def plot_driven_wave_ends(records: Sequence[Mapping], directory: Optional[str] = None,
                          name: str = "driven_wave_ends.png") -> Figure:
    """rho of the travelling wave with driven ends (finite chain, tightest tolerance) against the periodic chain's
    rho(F_q)^(P/m), against q, one curve per chain length."""
    fig, ax = _subplots(figsize=(6.5, 4.2))
    rt = min(float(r["rtol"]) for r in records)
    recs = [r for r in records if float(r["rtol"]) == rt]
    qs = sorted({float(r["q"]) for r in recs})
    per = [next(float(r["rho_periodic"]) for r in recs if float(r["q"]) == q) for q in qs]
    ax.semilogy(qs, np.array(per) - 1 + 1e-16, "k-o", ms=4, label="periodic chain, $\\rho(F_q)^{P/m} - 1$")
    for i, N in enumerate(sorted({int(r["N"]) for r in recs})):
        rr = sorted((r for r in recs if int(r["N"]) == N), key=lambda r: float(r["q"]))
        ax.semilogy([float(r["q"]) for r in rr], [float(r["rho"]) - 1 + 1e-16 for r in rr], "s--", ms=4,
                    color=f"C{i}", label=f"ends driven, N = {N}")
    ax.set(xlabel="$q$", ylabel=r"$\rho - 1$ over $\tau = 2\pi/\omega$")
    ax.legend(fontsize=8)
    return _finish(fig, directory, name)


def plot_driven_generation(records: Sequence[Mapping], directory: Optional[str] = None,
                           name: str = "driven_generation.png") -> Figure:
    """The generation map: per case the shape distance D of the bulk to the branch's wave against omega (one
    curve per signal, amplitude and damping), and the bead amplitudes A_n along the chain for each case."""
    fig, (ax, bx) = _subplots(2, 1, figsize=(6.5, 7))
    ok = [r for r in records if int(r["ok"])]
    groups = sorted({(int(r["waveform"]), float(r["amplitude"]), float(r["gamma"])) for r in ok})
    names = ("harmonic", "half-sine")
    for i, (w, a, g) in enumerate(groups):
        rs = sorted((r for r in ok if (int(r["waveform"]), float(r["amplitude"]), float(r["gamma"])) == (w, a, g)),
                    key=lambda r: float(r["omega"]))
        om = [float(r["omega"]) for r in rs]
        lab = f"{names[w]}, a = {a:g}, $\\gamma$ = {g:g}"
        ax.plot(om, [float(r["distance"]) for r in rs], "o-" if w == 0 else "s--", ms=4, color=f"C{i % 10}", label=lab)
        for r in rs:
            bx.semilogy(np.arange(1, len(r["A_n"]) + 1), r["A_n"], "-" if w == 0 else "--", lw=0.8,
                        color=f"C{i % 10}")
    ax.set(xlabel=r"$\omega$", ylabel="shape distance $D$ to the branch's wave")
    ax.legend(fontsize=7)
    bx.set(xlabel="bead $n$", ylabel="amplitude $A_n$")
    return _finish(fig, directory, name)
