"""Solitary waves of the uncompressed and the precompressed chain on the travelling window
(:mod:`hertzpetsc.compacton_window`, Delta = 0), continued in the precompression at unit speed, and the energy
criterion for their stability (J. Cuevas-Maraver, P. G. Kevrekidis, A. Vainchtein, H. Xu, Phys. Rev. E (2017),
arXiv:1701.04882; H. Xu et al., Nonlinearity (2018), arXiv:1711.03330; after G. Friesecke and R. L. Pego,
Nonlinearity 17 (2004)).

**Scaling.** With V'_d(r) = d^alpha - (d - r)_+^alpha (:class:`hertzpetsc.hertz.HertzLaw`, d the precompression), a
wave x_n(t) of unit speed in the chain of precompression d gives X_n(t) = a x_n(b t), of speed b = a^((alpha-1)/2),
in the chain of precompression a d, with a^(alpha+1) times its energy. So the family of one lattice (delta0 = 1) is
the family at unit speed in d: c = d^(-(alpha-1)/2), H(c) = d^(-(alpha+1)) H_1(d). The sound speed c0 = sqrt(V''(0))
= sqrt(alpha d^(alpha-1)) in units of the wave's speed labels both (c / c0 is the Mach number); c0 = 0 is the
uncompressed chain, whose family is H(c) = H(1) c^(2(alpha+1)/(alpha-1)) (no change of monotonicity anywhere).

**Tails.** Ahead of and behind the wave the chain is linear with V''(0) = c0^2, so r ~ exp(-kappa |n - t|) with
sinh(kappa/2) / (kappa/2) = 1/c0 (the linear dispersion relation at an imaginary wavenumber; :func:`tail_rate`):
a window holds ln(1/tail) / kappa beads on each side of the compression zone (:func:`window_beads`).

**Essential spectrum.** On the linear chain the window map G = S o Phi_1 takes the mode zeta^n, zeta = exp(-eta +
i k), to mu zeta^n with mu = zeta exp(-+ i omega), omega^2 = c0^2 (2 - zeta - 1/zeta). In the space weighted by
exp(eta n) (heavier ahead) the essential spectrum is that curve; its radius max_k |mu| is below 1 for
0 < eta < kappa (a supersonic wave: Pego and Weinstein's weighted space). :func:`essential_radius` is its minimum
over eta: multipliers above it are point spectrum, and a finite window's other multipliers gather near it (the
limit set of finite sections). c0 = 0: the transport is nilpotent (radius 0 for every eta,
:mod:`hertzpetsc.compacton_spectrum`).
The window map is far from normal in plain l2 (its transport part's pseudospectrum fills the unit disk): LAPACK on
J itself puts the finite window's transport multipliers anywhere up to the unit circle, and further out the larger
M. :func:`weighted_multipliers` takes them from W J W^-1, W = diag(exp(eta j)) at the eta of the essential radius
(the same eigenvalues in exact arithmetic), where they stay at the essential radius and the point multipliers do
not depend on M.

**Energy criterion.** Let X_c be the solitary wave of speed c in a fixed lattice, a fixed point of S o Phi_{1/c}.
Then G(X_c) = S Phi_1(X_c) = Phi_{1-1/c}(X_c), and d/dc at c = 1 gives (J - 1) dX_c/dc = f(X) = v1: the Jordan vector
v2 of the window map at 1 is dX_c/dc at fixed lattice, up to multiples of v1. The window chain is Hamiltonian with
H = sum v^2/2 + sum V(r) (V(0) = V'(0) = 0: the beads beyond the free ends rest at r = 0) and v1 = J grad H, so

    omega(v1, v2) = sum_j (ydot_j dv_j - vdot_j dy_j) = dH(v2) = dH/dc        (:func:`symplectic_product`),

whatever multiple of v1 v2 carries (omega(v1, v1) = 0). For the symplectic map of the infinite chain the left
eigenvector at 1 is Omega v1, so omega(v1, v2) = 0 is the solvability condition of (J - 1) v3 = v2: where dH/dc
changes sign the Jordan block at 1 grows and a pair of real multipliers passes through 1 -- the criterion (a change
of sign signals a change of stability; a sign kept along the family proves nothing by itself). d ln H / d ln c at
fixed lattice is invariant under the scaling above, so c dH/dc / H at unit speed is the family's slope at every c.
"""
import math

import numpy as np
from petsc4py import PETSc

from .compacton_spectrum import DEFAULT_ETA, exponential_weight, sorted_eig
from .compacton_window import WINDOW_PREFIX, WINDOW_TOLERANCES, CompactonRefiner, CompactonWindow
from .continuation import ContinuationProblem
from .errors import ParameterError

# beads of the compression zone a window holds besides the tails on both sides (the uncompressed solitary wave's
# bonds are closed above 1e-13 of the deepest one over 8 beads)
CORE_BEADS = 12


def check_sound_speed(c0):
    """c0 as a float, or ParameterError unless 0 <= c0 < 1 (a solitary wave is supersonic)."""
    try:
        c0 = float(c0)
    except (TypeError, ValueError):
        raise ParameterError("c0", c0, "must be a number in [0, 1)") from None
    if not 0.0 <= c0 < 1.0:
        raise ParameterError("c0", c0, "the sound speed in units of the wave's speed must be in [0, 1) (0: the "
                                       "uncompressed chain; a solitary wave is supersonic)")
    return c0


def precompression_at_unit_speed(alpha, c0):
    """The precompression d of the chain in which the unit-speed solitary wave has c0 = sqrt(alpha d^(alpha-1))."""
    c0 = check_sound_speed(c0)
    return (c0 * c0 / alpha) ** (1.0 / (alpha - 1.0)) if c0 > 0 else 0.0


def sound_speed(alpha, delta0):
    """sqrt(V''(0)) = sqrt(alpha delta0^(alpha-1)) (unit speed: the inverse Mach number)."""
    return math.sqrt(alpha * delta0 ** (alpha - 1.0)) if delta0 > 0 else 0.0


def tail_rate(c0):
    """kappa > 0 with sinh(kappa/2) / (kappa/2) = 1/c0: the tails' decay per bead (inf for c0 = 0)."""
    c0 = check_sound_speed(c0)
    if c0 == 0.0:
        return math.inf
    lo, hi = 0.0, 2.0
    while math.sinh(hi) / hi < 1.0 / c0:
        hi *= 2.0
    for _ in range(200):                             # sinh(x)/x increases: bisection to the last bit
        mid = 0.5 * (lo + hi)
        if mid == lo or mid == hi:
            break
        if math.sinh(mid) / mid < 1.0 / c0:          # mid > lo >= 0
            lo = mid
        else:
            hi = mid
    return 2.0 * hi


def window_beads(c0, tail):
    """Beads of a window whose ends see the tails at ``tail`` of the deepest compression: the compression zone
    and ln(1/tail) / kappa beads on each side."""
    if not 0 < tail < 1:
        raise ParameterError("tail", tail, "the tail level at the window's ends must be in (0, 1)")
    kappa = tail_rate(c0)
    side = 0 if math.isinf(kappa) else int(math.ceil(math.log(1.0 / tail) / kappa))
    return CORE_BEADS + 2 * side


def _radius(c0, eta, k):
    zeta = np.exp(-eta + 1j * k)
    omega = np.sqrt(c0 * c0 * (2.0 - zeta - 1.0 / zeta) + 0j)
    return float(np.max(np.abs(np.concatenate([zeta * np.exp(1j * omega), zeta * np.exp(-1j * omega)]))))


def essential_radius(c0, points=4097):
    """(min over eta of max_k |mu(k, eta)|, the eta attaining it) for the linear chain of sound speed c0 (module
    docstring): golden-section search in (0, kappa) on a grid of ``points`` wavenumbers. (0, inf) for c0 = 0."""
    c0 = check_sound_speed(c0)
    if c0 == 0.0:
        return 0.0, math.inf
    k = np.linspace(-math.pi, math.pi, points)
    lo, hi = 0.0, tail_rate(c0)
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = hi - g * (hi - lo), lo + g * (hi - lo)
    fa, fb = _radius(c0, a, k), _radius(c0, b, k)
    for _ in range(80):
        if fa < fb:
            hi, b, fb = b, a, fa
            a = hi - g * (hi - lo)
            fa = _radius(c0, a, k)
        else:
            lo, a, fa = a, b, fb
            b = lo + g * (hi - lo)
            fb = _radius(c0, b, k)
    eta = 0.5 * (lo + hi)
    return _radius(c0, eta, k), eta


def weighted_multipliers(J, eta):
    """The eigenvalues of the window map J (2M x 2M, bead-major) by LAPACK on W J W^-1, W = diag(exp(eta (j -
    M/2))), by decreasing modulus. eta = inf (the uncompressed chain, whose transport is nilpotent for every eta):
    the compacton spectrum's eta = 2.5 (unweighted, a window of 96 beads puts spurious multipliers at 0.23, above
    the solitary wave's mu_5); eta is capped at 600 / M so that the weights stay finite."""
    M = J.shape[0] // 2
    eta = min(DEFAULT_ETA if math.isinf(eta) else eta, 600.0 / M)
    w = exponential_weight(M, eta, 0.5 * (M - 1))
    return sorted_eig(w[:, None] * J / w[None, :])[0]


def window_energy(model, Y, gap=0.0):
    """H = sum v^2 / 2 + sum V(r) of a window state Y (M, 2) (the beads beyond its ends at rest at r = 0)."""
    Y = np.asarray(Y, float)
    return float(0.5 * np.sum(Y[:, 1] ** 2) + np.sum(model.potential(gap + np.diff(Y[:, 0]))))


def symplectic_product(u, v):
    """omega(u, v) = sum_j (u_y v_v - u_v v_y) of two bead-major vectors (2M,)."""
    u, v = np.asarray(u), np.asarray(v)
    return float(np.sum(u[0::2] * v[1::2] - u[1::2] * v[0::2]))


def unit_lattice(alpha, delta0, H, dH_dc):
    """(c, H(c), dH/dc) of the same wave in the lattice of precompression 1 (module docstring) from its energy H
    and slope dH/dc at unit speed in the lattice of precompression ``delta0`` > 0."""
    if not delta0 > 0:
        raise ParameterError("delta0", delta0, "the unit lattice needs a precompression > 0")
    a = 1.0 / delta0
    b = a ** ((alpha - 1.0) / 2.0)
    return b, a ** (alpha + 1.0) * H, a ** (alpha + 1.0) / b * dH_dc


def guess_from_solitary(wave, M, centre):
    """The window state (M, 2) of the unit-speed solitary wave of eq. adr (:mod:`hertzpetsc.solitary`): x_n(t) =
    y(n - t) (eq. depsol2), bead ``centre`` at s = 0, in window coordinates y_n + k_alpha (0 ahead, D = 2 k_alpha
    behind); velocities -y'(s) by central differences on the profile's grid (a guess: refined on the window)."""
    n = wave.params.cells_per_unit
    K = len(wave.y) - 1

    def y_at(idx):                                   # y on the grid index idx (any sign), odd, -k_alpha beyond L
        idx = np.asarray(idx)
        inside = np.where(np.abs(idx) <= K, wave.y[np.minimum(np.abs(idx), K)], -wave.k_alpha)
        return np.sign(idx) * inside
    m = (np.arange(M) - int(centre)) * n
    pos = y_at(m) + wave.k_alpha
    vel = -(y_at(m + 1) - y_at(m - 1)) * n / 2.0
    return np.stack([pos, vel], axis=1)


class PrecompressionContinuation(ContinuationProblem):
    """The unit-speed solitary wave (Delta = 0) of an M-bead window continued in the precompression d (natural
    continuation, :mod:`hertzpetsc.continuation`): Z = (Y, d); :meth:`solve` refines on the window of the chain of
    precompression d (:class:`~hertzpetsc.compacton_window.CompactonRefiner` at q = 0; the window of the last d is
    kept) and each point reports its :class:`~hertzpetsc.compacton_window.ExactCompacton`."""

    parameter = "delta0"

    def __init__(self, model, M, comm, tolerances=WINDOW_TOLERANCES, prefix=WINDOW_PREFIX, rk_type="8vr"):
        self.model, self.M, self.comm, self.tolerances, self.prefix = model, int(M), comm, tolerances, prefix
        self.rk_type = rk_type
        self._window, self._d, self.last = None, None, None

    def window(self, delta0):
        """The window of the chain of precompression ``delta0`` (built when d changes)."""
        if self._d != delta0:
            if self._window is not None:
                self._window.destroy()
            self._window = CompactonWindow(self.model.with_delta0(delta0), self.M, self.comm, self.tolerances,
                                           self.prefix, self.rk_type)
            self._d = delta0
        return self._window

    def refine(self, Y, delta0):
        self.last = CompactonRefiner(self.window(delta0)).refine(Y, 0.0, 0.0)
        return self.last

    def create_vec(self):
        return PETSc.Vec().createSeq(2 * self.M + 1, comm=PETSc.COMM_SELF)

    def pack(self, Y, delta0):
        Z = self.create_vec()
        Z.setArray(np.append(np.asarray(Y, float).ravel(), delta0))
        return Z

    def solve(self, Z, row=None, value=None):
        if row is not None:
            raise ParameterError("row", "pseudo-arclength", "the solitary window is continued in delta0 naturally")
        z = Z.getArray()
        ex = self.refine(z[:-1].reshape(self.M, 2), float(z[-1]))
        z[:-1] = ex.Y.ravel()
        return max(1, ex.iterations)

    def report(self, Z):
        return dict(wave=self.last)

    def destroy(self):
        if self._window is not None:
            self._window.destroy()
        self._window, self._d = None, None
