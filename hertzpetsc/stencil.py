"""Finite-difference stencils on the periodic grid xi_j = j h, shared by the PETSc solver and numpy post-processing."""
import math

import numpy as np

# A shift within this distance of a grid point, in units of h, is treated as a whole number of steps.
INTEGER_SHIFT_TOLERANCE = 1e-9


def shift_stencil(sigma):
    """Offsets and weights with u(xi_j + sigma h) ~ sum_k w_k u_{j + o_k}.

    Exact (one point) when sigma is a whole number; otherwise 4-point Lagrange interpolation on
    floor(sigma) - 1 .. floor(sigma) + 2, whose O(h^4) error (O(h^3) where u is only C^3) does not spoil the
    second-order scheme. The stencil of -sigma mirrors that of sigma, so shifted odd profiles stay odd.
    """
    f = math.floor(sigma + 0.5)
    if abs(sigma - f) <= INTEGER_SHIFT_TOLERANCE:
        return np.array([f], dtype=np.int64), np.array([1.0])
    f = math.floor(sigma)
    t = sigma - f
    w = np.array([-t * (t - 1) * (t - 2) / 6, (t + 1) * (t - 1) * (t - 2) / 2,
                  -(t + 1) * t * (t - 2) / 2, (t + 1) * t * (t - 1) / 6])
    return np.arange(f - 1, f + 3, dtype=np.int64), w


def full_period(u_half):
    """Values on [0, 2 pi) (2K points) from the K+1 values on [0, pi], by oddness."""
    u_half = np.asarray(u_half, dtype=float)
    return np.concatenate([u_half[:-1], -u_half[:0:-1]])


def shifted(u_full, sigma):
    """(tau_{sigma h} u)_j on the periodic grid, with :func:`shift_stencil`."""
    offsets, weights = shift_stencil(sigma)
    n = len(u_full)
    j = np.arange(n)
    return sum(w * u_full[(j + o) % n] for o, w in zip(offsets, weights))


def lagrange_periodic(values, h, points, derivative=False, width=6):
    """Evaluate at ``points`` the piecewise Lagrange interpolant of degree width-1 (and its derivative if
    ``derivative``) of periodic samples ``values[j] = f(j h)``, using the ``width`` grid points around each point.

    Exact at grid points for the values; with width 6 the error is O(h^6) (O(h^5) for the derivative) for smooth
    f, and no worse than the O(h^2) of the discrete profiles for the C^{3,1/2} travelling waves.
    """
    values = np.asarray(values, dtype=float)
    n = len(values)
    s = np.asarray(points, dtype=float) / h
    j0 = np.floor(s).astype(np.int64) - (width // 2 - 1)
    t = s - j0
    nodes = np.arange(width)
    out = np.zeros_like(s)
    for k in nodes:
        others = nodes[nodes != k]
        if not derivative:
            w = np.prod([(t - m) / (k - m) for m in others], axis=0)
        else:
            w = np.zeros_like(s)
            for l in others:
                rest = others[others != l]
                w += np.prod([(t - m) / (k - m) for m in rest], axis=0) / (k - l)
            w /= h
        out += w * values[(j0 + k) % n]
    return out
