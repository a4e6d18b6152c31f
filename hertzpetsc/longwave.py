"""The long-wave limit (paper section 3.2): the composite inner/outer approximation of the rescaled profile.

With u~ = q^(2/(alpha-1)) u (eq. adresc0), the outer solution is (k_alpha/pi) xi, the inner one y_sol((xi - pi)/q)
(eq. inner, the unit-velocity solitary wave of :mod:`hertzpetsc.solitary`), and their composite (eq. solapprox)

    u~_app(xi) = (k_alpha/pi) xi + y_sol((xi - pi)/q) - k_alpha             on [0, pi],
                 (k_alpha/pi) (xi - 2 pi) + y_sol((xi - pi)/q) + k_alpha    on [pi, 2 pi].

y_sol is taken from the solitary wave's grid by linear interpolation (error delta^2 |y''| / 8 ~ 1e-5 for the
default delta = 1/160, below the long-wave errors compared here) and set to -+k_alpha beyond its domain.
"""
import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LongWaveComparison:
    """Errors of the composite and inner approximations at one q, relative to k_alpha (eq. solapprox)."""

    q: float
    max_error: float             # max |u~ - u~_app| over the period
    window_error: float          # the same over |xi - pi| <= window
    inner_window_error: float    # max |u~ - y_sol((xi - pi)/q)| over the window
    rescaled_norm: float         # ||u~||_inf, against k_alpha (eq. normscaling)
    k_alpha: float


def inner_solution(wave, s):
    """y_sol(s) on the real line from a :class:`~hertzpetsc.solitary.SolitaryWave` (odd extension)."""
    s = np.asarray(s, dtype=float)
    grid = np.concatenate([-wave.s[:0:-1], wave.s])
    y = np.concatenate([-wave.y[:0:-1], wave.y])
    return np.interp(s, grid, y, left=wave.k_alpha, right=-wave.k_alpha)


def composite_profile(wave, q, xi):
    """u~_app(xi) of eq. solapprox for xi in [0, 2 pi]."""
    xi = np.asarray(xi, dtype=float)
    k = wave.k_alpha
    inner = inner_solution(wave, (xi - math.pi) / q)
    return np.where(xi <= math.pi, k / math.pi * xi + inner - k, k / math.pi * (xi - 2 * math.pi) + inner + k)


def compare_with_branch(wave, point, window=0.1):
    """Errors of the composite and inner approximations against the branch point's profile (a
    :class:`LongWaveComparison`: over the period and over |xi - pi| <= window, relative to k_alpha)."""
    q = point.q
    u_full = point.u_full
    K = len(u_full) // 2
    xi = np.arange(2 * K) * math.pi / K
    ut = q ** point.model.law.rescaling_exponent * u_full
    app = composite_profile(wave, q, xi)
    near = np.abs(xi - math.pi) <= window
    inner = inner_solution(wave, (xi - math.pi) / q)
    k = wave.k_alpha
    return LongWaveComparison(q=q, max_error=float(np.max(np.abs(ut - app)) / k),
                              window_error=float(np.max(np.abs(ut - app)[near]) / k),
                              inner_window_error=float(np.max(np.abs(ut - inner)[near]) / k),
                              rescaled_norm=float(np.max(np.abs(ut))), k_alpha=k)
