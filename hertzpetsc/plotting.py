"""Figures of the paper, from results (branches, refinement and Floquet records, snapshots, waves). Called by
scripts, never by solvers; each figure is written atomically on the calling rank.

matplotlib is imported lazily with the Agg backend, so this module can be imported on a machine without a screen.
"""
import math
import os

import numpy as np

from .diagnostics import dispersion, dispersion_long_wave
from .hertz import HertzLaw
from .records import save_figure


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, directory, name):
    fig.tight_layout()
    try:
        return save_figure(fig, os.path.join(directory, name))
    finally:
        _pyplot().close(fig)


def _nearest(branch, q):
    return int(np.argmin(np.abs(branch.q - q)))


def branch_k_alpha(branch):
    """Estimate of k_alpha from the branch: ||u||_inf q^(2/(alpha-1)) at its smallest q (eq. normscaling)."""
    return float(branch.column("rescaled_norm")[np.argmin(branch.q)])


def plot_profiles(branch, directory, qs=(math.pi, 3 * math.pi / 10, math.pi / 50)):
    """Fig. profiles: u(xi; q) on a period for the branch points nearest to ``qs``."""
    plt = _pyplot()
    fig, axes = plt.subplots(len(qs), 1, figsize=(6, 2.2 * len(qs)))
    xi = branch.xi
    xfull = np.concatenate([xi[:-1], 2 * math.pi - xi[:0:-1]])
    for ax, q in zip(np.atleast_1d(axes), qs):
        point = branch.points[_nearest(branch, q)]
        ax.plot(xfull, point.u_full, "k-", lw=1)
        ax.set_xlim(0, 2 * math.pi)
        ax.set_ylabel(r"$u(\xi)$")
        ax.set_title(rf"$q = {point.q:.4f}$", fontsize=10)
    np.atleast_1d(axes)[-1].set_xlabel(r"$\xi$")
    return _save(fig, directory, "profiles.png")


def _plot_power_law(branch, directory, name, field, factor, k_alpha, ylabel, data_label, line_label):
    """Branch values of ``field`` vs q (log scale) with the line factor k_alpha q^(2/(1-alpha))."""
    plt = _pyplot()
    a = branch.alpha
    k = branch_k_alpha(branch) if k_alpha is None else k_alpha
    q = branch.q
    qq = np.linspace(q.min(), math.pi, 200)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.semilogy(q, branch.column(field), "ko", ms=3, label=data_label)
    ax.semilogy(qq, factor * k * qq ** (2 / (1 - a)), "b-", lw=1,
                label=line_label + f", $k_\\alpha$ = {k:.4f}" + (" (branch, min q)" if k_alpha is None else ""))
    ax.set_xlabel("$q$")
    ax.set_ylabel(ylabel)
    ax.legend()
    return _save(fig, directory, name)


def plot_norms(branch, directory, k_alpha=None):
    """Fig. normes: ||u||_inf vs q (log scale) and the line k_alpha q^(2/(1-alpha))."""
    return _plot_power_law(branch, directory, "normes.png", "norm_inf", 1.0, k_alpha, r"$\|u\|_\infty$",
                           "computed", r"$k_\alpha q^{2/(1-\alpha)}$")


def plot_slopes(branch, directory, k_alpha=None):
    """Fig. pentes: free-flight slope p(q) = u'(0) vs q (log scale) and the line (k_alpha/pi) q^(2/(1-alpha))."""
    return _plot_power_law(branch, directory, "pentes.png", "slope", 1 / math.pi, k_alpha, "$u'$",
                           "computed $u'(0)$", r"$(k_\alpha/\pi)\, q^{2/(1-\alpha)}$")


def plot_number(branch, directory):
    """Fig. number: N(q), the mean number of adjacent interacting beads."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(branch.q, branch.column("N"), "k.-", ms=4, lw=0.8)
    ax.set_xlabel("$q$")
    ax.set_ylabel("$N(q)$")
    ax.grid(alpha=0.3)
    return _save(fig, directory, "number.png")


def plot_free_flight(branch, directory):
    """Fig. lsq: F(q) = 2 ell(q) / q, with F = 1 and q_k marked."""
    plt = _pyplot()
    qk = branch.q_k()
    F = branch.column("F")
    fig, ax = plt.subplots(figsize=(6, 4))
    pos = F > 0  # F(pi) = 0: no free flight for the binary oscillation
    ax.semilogy(branch.q[pos], F[pos], "k.-", ms=4, lw=0.8)
    ax.axhline(1.0, color="gray", lw=0.6)
    if np.isfinite(qk):
        ax.axvline(qk, color="b", lw=0.6, ls="--", label=rf"$q_k = {qk:.3f}$")
        ax.legend()
    ax.set_xlabel("$q$")
    ax.set_ylabel(r"$F(q) = 2\ell(q)/q$")
    return _save(fig, directory, "lsq.png")


def plot_dispersion(branch, directory, k_alpha=None):
    """Fig. dispersplot: omega(q, A0) (eq. dispers) and its linear approximation at q = 0 (eq. disperseq)."""
    plt = _pyplot()
    law = HertzLaw(branch.alpha)
    A0 = float(law.amplitude(law.p0))
    k = branch_k_alpha(branch) if k_alpha is None else k_alpha
    q, norm = branch.q, branch.column("norm_inf")
    qq = np.linspace(0, math.pi, 200)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(q, dispersion(norm, A0, law.alpha), "k.-", ms=4, lw=0.8, label=r"$\omega(q, A_0)$")
    ax.plot(qq, dispersion_long_wave(qq, A0, law.alpha, k), "b--", lw=0.8, label="linear approximation")
    ax.set_xlabel("$q$")
    ax.set_ylabel(r"$\omega$")
    ax.set_ylim(0, 1.1 * max(1.0, float(np.max(dispersion(norm, A0, law.alpha)))))
    ax.legend()
    return _save(fig, directory, "dispersplot.png")


def plot_branch_figures(branch, directory, k_alpha=None):
    """All figures of section 3.1; returns the paths written."""
    return [plot_profiles(branch, directory), plot_norms(branch, directory, k_alpha),
            plot_slopes(branch, directory, k_alpha), plot_number(branch, directory),
            plot_free_flight(branch, directory), plot_dispersion(branch, directory, k_alpha)]


# --- section 3.4: residuals and chain dynamics ---------------------------------------------------------------
def plot_errors(refined, directory):
    """Fig. errors: E(q) before (dotted) and after (full) refinement, and r(q) (dash-dot), semi-log, from a
    :class:`~hertzpetsc.studies.refinement.RefinedStates`."""
    plt = _pyplot()
    order = np.argsort(refined.q)
    q = refined.q[order]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.semilogy(q, refined.column("E_before_paper_flow")[order], "k:", label="E(q), branch wave (rtol 1e-12 flow)")
    ax.semilogy(q, refined.column("E_after")[order], "k-", label="E(q), refined (rtol 1e-14 flow)")
    ax.semilogy(q, refined.column("r")[order], "k-.", lw=0.8, label="r(q), last Gauss-Newton step")
    ax.set_xlabel("$q$")
    ax.set_ylabel("errors")
    ax.legend(fontsize=8)
    return _save(fig, directory, "errors.png")


def bond_forces(states, boundary="periodic"):
    """V'(x_{n+1} - x_n) / (-|.|^alpha) without alpha: the bond compressions min(x_{n+1} - x_n, 0), per snapshot."""
    x = states[..., 0]
    r = np.roll(x, -1, axis=-1) - x if boundary == "periodic" else np.diff(x, axis=-1)
    return np.minimum(r, 0.0)


def plot_snapshot(x0, xt, t, directory, name, title=""):
    """Bead displacements at time t (line) against the initial state (dots), as in figs. stabletw, shockbis."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 3))
    n = np.arange(1, len(x0) + 1)
    ax.plot(n, xt, "k-", lw=1, label=f"$t = {t:.1f}$")
    ax.plot(n, x0, "b.", ms=3, label="$t = 0$")
    ax.set_xlabel("$n$")
    ax.set_ylabel("$x_n$")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    return _save(fig, directory, name)


def plot_spacetime_forces(times, states, alpha, directory, name, title=""):
    """Interaction forces V'(x_{n+1} - x_n) in grey levels over (n, t) (figs. stabletw ... structures)."""
    plt = _pyplot()
    f = -np.abs(bond_forces(states)) ** alpha
    fig, ax = plt.subplots(figsize=(6, 4))
    im = ax.imshow(f, aspect="auto", origin="lower", cmap="gray",
                   extent=(0.5, states.shape[1] + 0.5, times[0], times[-1]))
    fig.colorbar(im, ax=ax, label=r"$V'(x_{n+1}-x_n)$")
    ax.set_xlabel("$n$")
    ax.set_ylabel("$t$")
    ax.set_title(title, fontsize=9)
    return _save(fig, directory, name)


def plot_deviation(runs, directory, name="deviation.png"):
    """D(t) = ||S^k X(k T) - X(0)|| / ||X(0)|| for several runs (dict label -> (t, D)), log scale."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    for label, (t, D) in runs.items():
        ax.semilogy(t, np.maximum(D, 1e-16), lw=0.8, label=label)
    ax.set_xlabel("$t$")
    ax.set_ylabel("deviation from the travelling wave")
    ax.legend(fontsize=8)
    return _save(fig, directory, name)


# --- section 3.5: Floquet multipliers ---------------------------------------------------------------------------
def plot_floquet_radius(q, rho, tol_rho, directory):
    """Fig. floquet: spectral radius of the monodromy matrix modulo shifts vs q."""
    plt = _pyplot()
    order = np.argsort(q)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(np.asarray(q)[order], np.asarray(rho)[order], "k.-", ms=4, lw=0.8)
    ax.axhline(1 + tol_rho, color="gray", lw=0.6, ls="--", label=rf"$1 + {tol_rho:g}$")
    ax.set_xlabel("$q$")
    ax.set_ylabel(r"$\rho(\mathcal{F}_q)$")
    ax.legend(fontsize=8)
    return _save(fig, directory, "floquet.png")


def plot_multipliers(panels, directory):
    """Fig. eigen: multipliers in the complex plane with the unit circle; ``panels`` = [(label, multipliers)]."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(8, 8))
    th = np.linspace(0, 2 * math.pi, 400)
    for ax, (label, lam) in zip(axes.ravel(), panels):
        lam = np.asarray(lam)
        lam = lam[np.isfinite(lam)]
        ax.plot(np.cos(th), np.sin(th), "b-", lw=0.6)
        ax.plot(lam.real, lam.imag, "k+", ms=5)
        ax.set_aspect("equal")
        ax.set_title(f"q = {label}", fontsize=10)
    return _save(fig, directory, "eigen.png")


# --- appendix: the solitary wave -------------------------------------------------------------------------------
def plot_solitary(wave, directory):
    """Fig. ondesol: r(s) (top) and the displacement y(s) (bottom) of the unit-velocity solitary wave."""
    plt = _pyplot()
    s = np.concatenate([-wave.s[:0:-1], wave.s])
    r = np.concatenate([wave.r[:0:-1], wave.r])
    y = np.concatenate([-wave.y[:0:-1], wave.y])
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(6, 5))
    a1.plot(s, r, "k-", lw=1)
    a1.set_ylabel("$r(s)$")
    a2.plot(s, y, "k-", lw=1)
    a2.axhline(wave.k_alpha, color="gray", lw=0.5, ls="--")
    a2.axhline(-wave.k_alpha, color="gray", lw=0.5, ls="--")
    a2.set_ylabel("$y(s)$")
    a2.set_xlabel("$s$")
    a1.set_title(rf"$\alpha = {wave.params.alpha}$, $k_\alpha = {wave.k_alpha:.5f}$", fontsize=10)
    return _save(fig, directory, "ondesol.png")


def plot_long_wave(wave, point, directory, zoom=0.3):
    """Figs. approxz (the rescaled profile of a branch point near pi against the inner solution) and approx
    (against the composite approximation of eq. solapprox over the period)."""
    from .longwave import composite_profile, inner_solution
    plt = _pyplot()
    u_half, q = point.u_half, point.q
    K = len(u_half) - 1
    xi = np.arange(2 * K + 1) * math.pi / K
    ut = q ** point.model.law.rescaling_exponent * np.concatenate([u_half, -u_half[-2::-1]])
    near = np.abs(xi - math.pi) <= zoom
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(xi[near], ut[near], "k-", lw=1.2, label=rf"computed, $q = {q:.4f}$")
    ax.plot(xi[near], inner_solution(wave, (xi[near] - math.pi) / q), "b-", lw=0.8, label="inner solution (eq. inner)")
    ax.set_xlabel(r"$\xi$")
    ax.set_ylabel(r"$\tilde u(\xi)$")
    ax.legend(fontsize=8)
    first = _save(fig, directory, "approxz.png")
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(xi, ut, "k-", lw=1.2, label=rf"computed, $q = {q:.4f}$")
    ax.plot(xi, composite_profile(wave, q, xi), "b-", lw=0.8, label="composite (eq. solapprox)")
    ax.set_xlabel(r"$\xi$")
    ax.set_ylabel(r"$\tilde u(\xi)$")
    ax.legend(fontsize=8)
    return [first, _save(fig, directory, "approx.png")]


# --- section 3.3: compactons ------------------------------------------------------------------------------------
def plot_compacton_profiles(single, double, directory):
    """Fig. graphulin: U_q (eq. extens, top) and U^(2)_{q, theta} (eq. extens2, bottom), with the compression
    regions (ell, 2 pi - ell) + s_j shaded."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(6, 6))
    for ax, train in zip(axes, (single, double)):
        xi = np.linspace(-2 * math.pi, train.offsets[-1] + 4 * math.pi, 2000)
        ax.plot(xi, train(xi), "k-", lw=1)
        for s in train.offsets:
            ax.axvspan(s + train.ell, s + 2 * math.pi - train.ell, color="0.85", lw=0)
        ax.set_xlabel(r"$\xi$")
        theta = "" if train.count == 1 else rf", $\theta = {train.offsets[1] - 2 * math.pi:.3g}$"
        ax.set_ylabel("$U_q$" if train.count == 1 else "$U^{(2)}_{q,\\theta}$")
        ax.set_title(rf"$q = {train.q:.4f}$, $F(q) = {train.F:.3f}$" + theta, fontsize=9)
    return _save(fig, directory, "graphulin.png")


def plot_spacetime_velocities(times, states, directory, name, title=""):
    """Bead velocities xdot_n over (n, t): compactons travel through beads at rest (white = exactly 0)."""
    plt = _pyplot()
    v = states[..., 1]
    fig, ax = plt.subplots(figsize=(6, 4))
    im = ax.imshow(v, aspect="auto", origin="lower", cmap="gray_r",
                   extent=(-0.5, states.shape[1] - 0.5, times[0], times[-1]))
    fig.colorbar(im, ax=ax, label=r"$\dot x_n$")
    ax.set_xlabel("$n$")
    ax.set_ylabel("$t$")
    ax.set_title(title, fontsize=9)
    return _save(fig, directory, name)


# --- section 3.2 beyond the paper: small q -------------------------------------------------------------------------
def plot_small_q(q, levels, extrapolated, k_alpha, directory):
    """||u||_inf q^(2/(alpha-1)) against q on each grid level and extrapolated in h, with k_alpha (eq.
    normscaling): the long-wave limit beyond the paper's q = pi/50."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    for lev, values in enumerate(levels):
        ax.semilogx(q, values, ".-", lw=0.6, ms=3, color=str(0.7 - 0.25 * lev), label=f"level {lev}")
    ax.semilogx(q, extrapolated, "k.-", lw=1.2, label="extrapolated in $h$")
    ax.axhline(k_alpha, color="b", lw=0.8, ls="--", label=rf"$k_\alpha = {k_alpha:.5f}$")
    ax.set_xlabel("$q$")
    ax.set_ylabel(r"$\|u\|_\infty\, q^{2/(\alpha-1)}$")
    ax.legend(fontsize=8)
    return _save(fig, directory, "smallq.png")
