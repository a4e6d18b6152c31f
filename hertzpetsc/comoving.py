"""Floquet-Bloch exponents of a travelling wave on the infinite chain without time integration: the co-moving-frame
quadratic eigenvalue problem (section 3.5 beyond the paper; eqs. nc, ad, invv).

Linearising eq. nc around x_n(t) = u(q n - t) (eq. ad at frequency 1), the Bloch-Floquet solutions
y_n(t) = e^{lambda t} e^{i theta n} w(q n - t), w 2 pi-periodic, solve

    (lambda - d/dxi)^2 w + K_theta w = 0,
    K_theta w = a (w - e^{i theta} w(. + q)) + b (w - e^{-i theta} w(. - q)),   a = V''(u(. + q) - u),  b = a(. - q).

K_theta is Hermitian and >= 0, d/dxi skew: the eigenvalues are symmetric under lambda -> -conj(lambda). Since
y_{n+1}(t + q) = mu y_n(t), the multiplier of F_q = S R(script-T; 0) (time q = script-T at frequency 1, the
amplitude scaling of eq. invv leaves mu unchanged) is mu = exp(lambda q + i theta), and the growth per unit time of
the normalised wave is gamma = q Re lambda / script-T.

Discretisation (z-form). On xi_j = j h, h = pi/K, with z = e^{lambda h}, the standard scheme for
v = e^{-lambda xi} w (the time history of one bead) reads

    z^2 S_- w + z (h^2 K_theta - 2) w + S_+ w = 0,        (S_+- w)_j = w_{j +- 1},

a quadratic pencil in z with O(1) coefficients: free flight is exact (its Jordan blocks stay on |z| = 1), the
sawtooth sits at z = -1 far from the targets, and uniform translation is an exact Jordan chain at z = 1. The shifts
by q use the package's stencils (:mod:`hertzpetsc.stencil`); for an integer q / h, b_j = a_{j - q/h} keeps K_theta
exactly Hermitian. V'' is averaged exactly over each dual cell (r = u(. + q) - u piecewise linear between ``n_sub``
sub-points; over a linear piece the mean of V'' is the divided difference of V'), which resolves the switching
points of contact inside the cells and gives order 2 in h; point samples of V'' (|r|^(alpha-1) where contact
switches) converge erratically.

The eigenvalue problem is solved by SLEPc (:mod:`hertzpetsc.comoving_pep`); the window of eigenvalues that represents
every chain mode, the compacton band and the scans over theta are in :mod:`hertzpetsc.comoving_window`.
"""
import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc

from .advdelay import check_wavenumber
from .diagnostics import sup_norm
from .errors import check_integer
from .stencil import INTEGER_SHIFT_TOLERANCE, full_period, shift_stencil, shifted
from .symmetry import real_sector


# --- coefficients ------------------------------------------------------------------------------------------------
def linear_piece_mean(law, r0, r1):
    """Exact mean of V''(r) over a piece on which r is linear from r0 to r1: (V'(r1) - V'(r0)) / (r1 - r0).

    With g = -r: where both ends are in contact the divided difference of g^alpha is used when the ends differ by
    more than 1e-3 relative (cancellation below 1e3 ulp), else the midpoint value plus its d^2/24 correction (error
    O(d^4)); for alpha = 3/2 the cancellation-free (g1 + sqrt(g0 g1) + g0) / (sqrt g0 + sqrt g1). A piece crossing
    r = 0 gives the exact quotient (one end contributes 0)."""
    alpha = law.alpha
    g0 = np.maximum(-np.asarray(r0, dtype=float), 0.0)
    g1 = np.maximum(-np.asarray(r1, dtype=float), 0.0)
    out = np.zeros(np.broadcast(g0, g1).shape)
    both = (g0 > 0) & (g1 > 0)
    one = (g0 > 0) ^ (g1 > 0)
    a0, a1 = g0[both], g1[both]
    if alpha == 1.5:
        s0, s1 = np.sqrt(a0), np.sqrt(a1)
        out[both] = (a1 + s0 * s1 + a0) / (s0 + s1)
    else:
        d = a1 - a0
        gm = 0.5 * (a0 + a1)
        far = np.abs(d) > 1e-3 * np.maximum(a0, a1)
        val = alpha * gm ** (alpha - 1) + alpha * (alpha - 1) * (alpha - 2) * gm ** (alpha - 3) * d ** 2 / 24
        val[far] = (a1[far] ** alpha - a0[far] ** alpha) / d[far]
        out[both] = val
    G0, G1 = -np.asarray(r0, dtype=float)[one], -np.asarray(r1, dtype=float)[one]
    out[one] = (g1[one] ** alpha - g0[one] ** alpha) / (G1 - G0)
    return out


def cell_mean_stiffness(law, r, n_sub=8):
    """(1/h) int over [xi_j - h/2, xi_j + h/2] of V''(r(xi)) for the periodic grid values r_j, with r piecewise
    linear between n_sub + 1 equispaced sub-points (its values there by 4-point Lagrange, :func:`shifted`)."""
    r = np.asarray(r, dtype=float)
    ts = np.linspace(-0.5, 0.5, n_sub + 1)
    sub = np.array([shifted(r, t) if abs(t) > 1e-14 else r for t in ts])
    return linear_piece_mean(law, sub[:-1], sub[1:]).mean(axis=0)


def shift_csr(n, sigma):
    """(T w)_j = w(xi_j + sigma h) on n periodic points, with the package's shift stencil (scipy CSR)."""
    offsets, weights = shift_stencil(sigma)
    j = np.arange(n)
    rows = np.tile(j, len(offsets))
    cols = np.concatenate([(j + o) % n for o in offsets])
    return sp.csr_matrix((np.repeat(weights, n), (rows, cols)), shape=(n, n))


@dataclass
class ComovingWave:
    """A wave's profile on h = pi/K (K + 1 values on [0, pi], odd) with its cell-averaged contact coefficients
    a ~ V''(u(. + q) - u), b ~ V''(u - u(. - q)) and its script-T (eq. invv)."""

    model: object
    q: float
    u_half: np.ndarray
    n_sub: int = 8

    def __post_init__(self):
        check_wavenumber(self.q)
        self.n_sub = check_integer("n_sub", self.n_sub, 1, "the sub-pieces per cell")
        self.u_half = np.asarray(self.u_half, dtype=float)
        self.K = len(self.u_half) - 1
        self.h = math.pi / self.K
        self.sigma = self.q / self.h
        law = self.model.law
        u = full_period(self.u_half)
        rp = shifted(u, self.sigma) - u
        self.a = cell_mean_stiffness(law, rp, self.n_sub)
        if abs(self.sigma - round(self.sigma)) <= INTEGER_SHIFT_TOLERANCE:
            self.b = np.roll(self.a, int(round(self.sigma)))
        else:
            self.b = cell_mean_stiffness(law, u - shifted(u, -self.sigma), self.n_sub)
        self.T = self.q * sup_norm(self.u_half) ** ((self.model.alpha - 1) / 2)

    @classmethod
    def from_point(cls, point, K=None, comm=None, prefix="tw_", n_sub=8):
        """The wave of a branch point on h = pi/K: the branch profile itself (K of the branch), or the discrete
        eq. ad solved by the travelling-wave SNES (prefix ``tw_``) from the profile interpolated onto K."""
        K0 = len(point.u_half) - 1
        if K is None or K == K0:
            return cls(point.model, point.q, point.u_half, n_sub)
        return cls(point.model, point.q, profile_on_grid(point, K, comm or PETSc.COMM_SELF, prefix), n_sub)

    def pencil(self, theta):
        """The z-pencil [A0, A1, A2] (P(z) = A0 + z A1 + z^2 A2) at Bloch parameter theta, scipy CSR, complex unless
        theta is 0 or pi."""
        n = 2 * self.K
        e = np.exp(1j * theta)
        if real_sector(theta):
            e = float(np.sign(e.real))
        Kt = (sp.diags(self.a + self.b) - e * (sp.diags(self.a) @ shift_csr(n, self.sigma))
              - np.conj(e) * (sp.diags(self.b) @ shift_csr(n, -self.sigma)))
        return [shift_csr(n, 1.0), ((self.h ** 2) * Kt - 2.0 * sp.identity(n)).tocsr(), shift_csr(n, -1.0)]

    def multiplier(self, lam, theta):
        """mu = exp(lambda q + i theta) of F_q."""
        return np.exp(np.asarray(lam) * self.q + 1j * theta)

    def growth(self, lam):
        """gamma = q Re lambda / script-T (per unit time of the normalised wave)."""
        return self.q * np.real(lam) / self.T


def profile_on_grid(point, K, comm, prefix="tw_", q=None):
    """The discrete eq. ad on h = pi/K at the branch point's q (or at a nearby ``q``), by the travelling-wave SNES
    from the branch profile interpolated (degree 5) onto the grid; K + 1 values on [0, pi]."""
    from .advdelay import AdvanceDelayProblem
    from .qbranch import regrid_half_profile
    from .grid import ProfileGrid
    from .twsolver import TravellingWaveSolver
    grid = ProfileGrid(K, comm)
    u = grid.vec_from_half_profile(regrid_half_profile(point.u_half, K))
    problem = AdvanceDelayProblem(point.model, grid, point.q if q is None else q)
    tws = TravellingWaveSolver(grid, prefix)
    try:
        tws.solve(problem, u)       # at least one Newton step (TravellingWaveSolver): the regridding error is O(h^2)
        return grid.half_profile(u)
    finally:
        tws.destroy()
        problem.destroy()
        u.destroy()
