"""Diagnostics of a travelling-wave profile and of a branch (paper section 3.1). Pure numpy.

Profiles are given on the half period: ``u_half[j] = u(j h)``, j = 0..K, h = pi/K, extended by oddness.
"""
import math
from dataclasses import asdict, dataclass, fields

import numpy as np

from .model import LatticeModel
from .stencil import full_period, shifted


@dataclass(frozen=True)
class WaveDiagnostics:
    """The scalar diagnostics of one branch point (section 3.1, eqs. defnq, invv, dispers, normscaling)."""

    norm_inf: float          # ||u||_inf
    slope: float             # p(q) = u'(0), the free-flight slope
    ell: float               # free-flight half-length ell(q)
    N: float                 # N(q) = 2 (pi - ell)/q, mean number of adjacent interacting beads (eq. defnq)
    F: float                 # F(q) = 2 ell/q, mean number of adjacent beads in free flight
    T: float                 # inverse velocity script-T(q) = q ||u||^((alpha-1)/2) (eq. invv)
    omega_A0: float          # omega(q, A0), A0 = ||u0||_inf (eq. dispers)
    rescaled_norm: float     # ||u||_inf q^(2/(alpha-1)) -> k_alpha (eq. normscaling)

    @classmethod
    def names(cls):
        return tuple(f.name for f in fields(cls))

    def as_dict(self):
        return asdict(self)

    def __getitem__(self, name):
        """``diagnostics["N"]``: the spelling of the time when diagnostics were a dict."""
        return getattr(self, name)


def sup_norm(u_half):
    """||u||_inf, refined by the parabola through the largest grid value and its neighbours.

    The grid maximum alone jumps by O(h^2) as the maximiser moves between grid points, which would hide the
    scheme's smooth h^2 convergence; the parabolic vertex is a smooth functional of the grid values.
    """
    u = np.abs(np.asarray(u_half, dtype=float))
    j = int(np.argmax(u))
    if j == 0 or j == len(u) - 1:
        return float(u[j])
    a, b, c = u[j - 1], u[j], u[j + 1]
    curv = a - 2 * b + c
    return float(b - (a - c) ** 2 / (8 * curv)) if curv < 0 else float(b)


def free_flight_half_length(u_half, q, h):
    """ell(q): both shift differences d+ = u(xi+q) - u(xi) and d- = u(xi) - u(xi-q) are >= 0 on [-ell, ell].

    On the grid, g_j = min(d+_j, d-_j) for xi_j in [0, pi]; ell lies between the last grid point with g >= 0
    and the first with g < 0. It is located as the root, in that cell, of the cubic interpolating the
    difference that changes sign there at the four surrounding grid points (linear interpolation would leave
    an O(h^2 d''/d') error that oscillates with the crossing's position in its cell and is large where the
    compression region is steep). ell = 0 if g_0 <= 0, as at q = pi where u(xi + pi) - u(xi) = -2 u(xi);
    ell = pi if g never becomes negative on [0, pi].
    """
    u_full = full_period(u_half)
    sigma = q / h
    K = len(u_half) - 1
    n = 2 * K
    dplus = shifted(u_full, sigma) - u_full
    dminus = u_full - shifted(u_full, -sigma)
    g = np.minimum(dplus, dminus)[:K + 1]
    # g_0 = u(q) > 0 in exact arithmetic for q < pi; round-off on an exact zero must not count as contact.
    tiny = 64 * np.finfo(float).eps * np.max(np.abs(u_half))
    neg = np.nonzero(g < -tiny)[0]
    if len(neg) == 0:
        return math.pi
    j = int(neg[0])
    if j == 0 or g[j - 1] <= tiny:
        return (j - 1) * h if j > 0 else 0.0
    d = dplus if dplus[j] < -tiny else dminus
    y = d[np.arange(j - 2, j + 2) % n]           # values at t = -1, 0, 1, 2 with t = (xi - xi_{j-1}) / h
    c = np.polyfit([-1.0, 0.0, 1.0, 2.0], y, 3)
    lo, hi = 0.0, 1.0                            # y(0) >= 0 > y(1): bisection keeps the cubic's root in the cell
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if np.polyval(c, mid) >= 0:
            lo = mid
        else:
            hi = mid
    return (j - 1 + 0.5 * (lo + hi)) * h


def point_diagnostics(u_half, q, h, alpha):
    """All scalar diagnostics of one branch point (section 3.1, eqs. defnq, invv, dispers)."""
    law = LatticeModel.hertz(alpha).law
    a = law.alpha
    norm = sup_norm(u_half)
    ell = free_flight_half_length(u_half, q, h)
    A0 = float(law.amplitude(law.p0))  # ||u0||_inf, so that omega(pi, A0) = 1 (fig. dispersplot)
    return WaveDiagnostics(
        norm_inf=norm,
        slope=float(u_half[1] / h),                   # p(q) = u'(0) = (u_1 - u_{-1}) / 2h (u odd): exact in free flight
        ell=ell,
        N=2 * (math.pi - ell) / q,                    # eq. defnq: mean number of adjacent interacting beads
        F=2 * ell / q,                                # mean number of adjacent beads in free flight
        T=q * norm ** ((a - 1) / 2),                  # inverse velocity script-T(q), eq. invv
        omega_A0=dispersion(norm, A0, a),             # omega(q, A0), eq. dispers
        rescaled_norm=norm * q ** law.rescaling_exponent,   # ||u||_inf q^(2/(alpha-1)) -> k_alpha (eq. normscaling)
    )


def dispersion(norm_inf, A, alpha):
    """omega(q, A) = A^((alpha-1)/2) ||u(.;q)||_inf^((1-alpha)/2) (eq. dispers)."""
    return A ** ((alpha - 1) / 2) * np.asarray(norm_inf, dtype=float) ** ((1 - alpha) / 2)


def dispersion_long_wave(q, A, alpha, k_alpha):
    """The linear approximation omega ~ k_alpha^((1-alpha)/2) A^((alpha-1)/2) q as q -> 0 (eq. disperseq)."""
    return k_alpha ** ((1 - alpha) / 2) * A ** ((alpha - 1) / 2) * np.asarray(q, dtype=float)


def crossing(q, values, level):
    """The q where ``values`` (sampled along the branch at ``q``) crosses ``level``, by linear interpolation.

    Returns the crossing at the largest q if there are several, and nan if there is none.
    """
    q = np.asarray(q, dtype=float)
    v = np.asarray(values, dtype=float) - level
    order = np.argsort(q)[::-1]
    q, v = q[order], v[order]
    for i in range(len(q) - 1):
        if v[i] == 0:
            return float(q[i])
        if v[i] * v[i + 1] < 0:
            return float(q[i] + (q[i + 1] - q[i]) * v[i] / (v[i] - v[i + 1]))
    return float(q[-1]) if len(v) and v[-1] == 0 else math.nan
