"""The long-wave limit (paper section 3.2): the composite inner/outer approximation of the rescaled profile.

With u~ = q^(2/(alpha-1)) u (eq. adresc0), the outer solution is (k_alpha/pi) xi, the inner one y_sol((xi - pi)/q)
(eq. inner, the unit-velocity solitary wave of :mod:`hertzpetsc.solitary`), and their composite (eq. solapprox)

    u~_app(xi) = (k_alpha/pi) xi + y_sol((xi - pi)/q) - k_alpha             on [0, pi],
                 (k_alpha/pi) (xi - 2 pi) + y_sol((xi - pi)/q) + k_alpha    on [pi, 2 pi].

y_sol is taken from the solitary wave's grid by linear interpolation (error delta^2 |y''| / 8 ~ 1e-5 for the
default delta = 1/160, below the long-wave errors compared here) and set to -+k_alpha beyond its domain.
"""
import math

import numpy as np


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


def compare_with_branch(wave, q, u_half, alpha, window=0.1):
    """Errors of the composite and inner approximations against the computed profile at wavenumber q.

    Returns the max |u~ - u~_app| over the period and over |xi - pi| <= window, the max |u~ - inner| over the
    window, all relative to k_alpha, and the rescaled norm ||u~||_inf against k_alpha (eq. normscaling).
    """
    K = len(u_half) - 1
    xi = np.arange(2 * K) * math.pi / K
    u_full = np.concatenate([u_half[:-1], -u_half[:0:-1]])
    ut = q ** (2 / (alpha - 1)) * u_full
    app = composite_profile(wave, q, xi)
    near = np.abs(xi - math.pi) <= window
    inner = inner_solution(wave, (xi - math.pi) / q)
    k = wave.k_alpha
    return dict(q=q, max_error=float(np.max(np.abs(ut - app)) / k),
                window_error=float(np.max(np.abs(ut - app)[near]) / k),
                inner_window_error=float(np.max(np.abs(ut - inner)[near]) / k),
                rescaled_norm=float(np.max(np.abs(ut))), k_alpha=k)
