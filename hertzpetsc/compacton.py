"""Compactons (paper section 3.3): linear extensions of the periodic travelling waves for q <= q_k.

For q <= q_k (F(q) = 2 ell(q)/q >= 1) the branch profile u(.; q) is linear, u = p xi, on [-ell, ell] and
u = p (xi - 2 pi) on [2 pi - ell, 2 pi + ell], and the intervals are longer than the delay q. Continuing
those lines gives U_q (eq. extens), a solution of eq. ad on the whole line, and gluing shifted copies gives the
2-compacton U^(2) (eq. extens2) and its n-compacton generalisation. Here all of them are one formula:

    U(xi) = p xi + sum_j g(xi - s_j),   g(z) = 0 (z <= ell),  u(z) - p z (ell < z < 2 pi - ell),  -2 pi p (z >= 2 pi - ell),

with s_0 = 0 and s_{j+1} = s_j + 2 pi + theta_j, theta_j = q d_j (d_j = extra beads between compactons j and
j+1; d_j >= 0 in the paper, d_j >= 2 - F(q) suffices too, see :func:`min_spacing`). One bump (n = 1) is U_q;
n = 2 is U^(2)_{q, theta}. On the chain (eqs. twlin, compacton, defvit):

    x_n(t) = a U(q n - omega t + phi) + v t,   omega = a^((alpha-1)/2),   v = a^((alpha+1)/2) p,

bead n is at rest unless q n - omega t + phi - s_j lies in (ell, 2 pi - ell) for some j; the compactons move
at c = omega / q beads per unit time, the gaps outside them are Delta = a p q, and every bead moves forward by
2 pi a p each time a compacton passes. Inside the bumps u comes from the degree-5 Lagrange interpolant of the
branch profile; outside, U is exactly linear, so beads ahead of the train have exactly zero velocity.
"""
import math
from dataclasses import dataclass

import numpy as np

from .errors import ParameterError, check_real
from .model import ChainSpec, LatticeModel
from .stencil import lagrange_periodic


@dataclass(frozen=True)
class CompactonTrain:
    """n >= 1 compactons of wavenumber q (eqs. extens, extens2), built from one branch point."""

    model: LatticeModel
    q: float
    h: float
    p: float              # free-flight slope p(q) = u'(0)
    ell: float            # free-flight half-length ell(q)
    u_full: np.ndarray    # branch profile on the grid j h of [0, 2 pi)
    offsets: tuple        # s_j, the start of each compacton's period

    @property
    def count(self):
        return len(self.offsets)

    @property
    def F(self):
        """F(q) = 2 ell / q, beads in free flight between compression packets (must be >= 1)."""
        return 2 * self.ell / self.q

    @property
    def width(self):
        """N(q) = 2 (pi - ell) / q (eq. defnq): the compacton width in beads."""
        return 2 * (math.pi - self.ell) / self.q

    def bump(self, z, derivative=False, u=None):
        """g(z) = U_q(z) - p z (or g'(z)): zero before the compression region, -2 pi p after it. ``u``: the values
        of u at the points z (grid points), instead of its interpolant."""
        z = np.asarray(z, dtype=float)
        inside = (z > self.ell) & (z < 2 * math.pi - self.ell)
        out = np.zeros_like(z) if derivative else np.where(z >= 2 * math.pi - self.ell, -2 * math.pi * self.p, 0.0)
        if np.any(inside):
            zi = z[inside]
            ui = lagrange_periodic(self.u_full, self.h, zi, derivative=derivative) if u is None else u[inside]
            out[inside] = ui - self.p if derivative else ui - self.p * zi
        return out

    def __call__(self, xi):
        """U(xi) on the whole line."""
        xi = np.asarray(xi, dtype=float)
        return self.p * xi + sum(self.bump(xi - s) for s in self.offsets)

    def derivative(self, xi):
        """U'(xi) on the whole line (exactly p outside the compression regions)."""
        xi = np.asarray(xi, dtype=float)
        return self.p + sum(self.bump(xi - s, derivative=True) for s in self.offsets)

    # --- on the grid: eq. ad on the extended domain ----------------------------------------------------------------
    def grid_values(self, j):
        """U(j h) for integer j, from the grid values of u (no interpolation); needs every s_j on the grid."""
        steps = [s / self.h for s in self.offsets]
        if any(abs(k - round(k)) > 1e-9 for k in steps):
            raise ParameterError("spacings", list(self.offsets),
                                 "grid evaluation needs every offset s_j to be a whole number of steps h")
        j = np.asarray(j, dtype=np.int64)
        n = len(self.u_full)
        U = self.p * self.h * j.astype(float)
        for k in (int(round(k)) for k in steps):
            U = U + self.bump((j - k) * self.h, u=self.u_full[(j - k) % n])
        return U


def advance_delay_residual(U, sigma, h, model):
    """The discrete eq. ad at the interior points of consecutive grid values U_j (shift q = sigma h, sigma an
    integer): (U_{j+1} - 2 U_j + U_{j-1}) / h^2 - V'(U_{j+sigma} - U_j) + V'(U_j - U_{j-sigma})."""
    U = np.asarray(U, dtype=float)
    c = slice(sigma, len(U) - sigma)
    Uc = U[c]
    d2 = (U[sigma + 1:len(U) - sigma + 1] - 2 * Uc + U[sigma - 1:len(U) - sigma - 1]) / h ** 2
    return d2 - model.force(U[2 * sigma:] - Uc) + model.force(Uc - U[:len(U) - 2 * sigma])


def free_flight_deviation(train):
    """delta = max |u_j - p j h| over the grid points of the free flight [0, ell]: zero for an exact discrete
    solution (u'' = 0 there), at the solver's tolerance for a computed one."""
    j = np.arange(0, int(train.ell / train.h) + 1)
    return float(np.max(np.abs(train.u_full[j] - train.p * train.h * j)))


def extension_residuals(train, periods=1.0):
    """max |eq. ad residual| of U on the grid of [s_0 - 2 pi periods, s_last + 2 pi (1 + periods)] (the whole
    train plus ``periods`` periods of linear extension on each side), of the periodic profile u on one period,
    and the bound 2 delta / h^2 (:func:`free_flight_deviation`) on what the switch from u to the exact line at
    the edges of the free flight can add to the second difference. The extension and gluing add nothing else:
    the first number is at most the sum of the other two (plus round-off, about eps |U| / h^2)."""
    h, K2 = train.h, len(train.u_full)
    sigma = int(round(train.q / h))
    if abs(train.q / h - sigma) > 1e-9:
        raise ParameterError("q", train.q, "grid residuals need q to be a whole number of steps h")
    pad = int(round(periods * K2)) + sigma + 1
    j = np.arange(int(round(train.offsets[0] / h)) - pad, int(round(train.offsets[-1] / h)) + K2 + pad + 1)
    extended = advance_delay_residual(train.grid_values(j), sigma, h, train.model)
    jp = np.arange(-sigma - 1, K2 + sigma + 1)
    period = advance_delay_residual(train.u_full[jp % K2], sigma, h, train.model)
    return float(np.max(np.abs(extended))), float(np.max(np.abs(period))), 2 * free_flight_deviation(train) / h ** 2


def min_spacing(F):
    """The smallest spacing d (beads) for which gluing is proven: d >= 0 (the paper, eq. extens2, using the free
    flight between the compactons when F < 2) or d >= 2 - F (then U^(2) = U_q on J^- and = U^(1) on J^+, and
    J^- and J^+ cover the line: the paper's argument with theta = q d >= 2 (q - ell))."""
    return min(0.0, 2.0 - F)


def compacton_train(point, spacings=(), q_k=None):
    """The n-compacton of the branch point ``point``, n = len(spacings) + 1, spacings d_j in beads
    (theta_j = q d_j); ``q_k`` (the branch's, if known) only makes the error message more precise.

    Raises ParameterError when F(q) < 1 (q above q_k: no linear extension, eq. extens) or a spacing is below
    :func:`min_spacing` (the compactons would overlap).
    """
    q, diag = point.q, point.diagnostics
    F = diag.F
    if F < 1.0:
        bound = f"q <= q_k = {q_k:.4f}" if q_k is not None and q_k == q_k else "q <= q_k"
        raise ParameterError("q", q, f"compactons need F(q) = 2 ell(q)/q >= 1, i.e. {bound} "
                                     f"(here F = {F:.4f}, eq. extens)")
    d = [float(x) for x in spacings]
    d_min = min_spacing(F)
    bad = [x for x in d if not (math.isfinite(x) and x >= d_min)]
    if bad:
        raise ParameterError("spacings", d, f"every spacing d_j between neighbouring compactons must be >= "
                                            f"{d_min:.4f} beads at q = {q:.6g} (min(0, 2 - F(q)), eq. extens2); "
                                            "smaller spacings make them overlap")
    offsets = [0.0]
    for dj in d:
        offsets.append(offsets[-1] + 2 * math.pi + q * dj)
    return CompactonTrain(model=point.model, q=q, h=point.h, p=diag.slope, ell=diag.ell, u_full=point.u_full,
                          offsets=tuple(offsets))


# --- on the chain ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CompactonScales:
    """Scales of the chain solution x_n(t) = a U(q n - omega t + phi) + v t (eqs. twlin, compacton, defvit)."""

    a: float
    omega: float     # a^((alpha-1)/2)
    v: float         # a^((alpha+1)/2) p, the Galilean boost that brings the beads outside the compactons to rest
    c: float         # omega / q, beads per unit time
    gap: float       # Delta = a p q
    shift: float     # 2 pi a p, the displacement of a bead when one compacton passes it

    @classmethod
    def for_velocity(cls, train, c):
        """The scales that make the compactons travel at c > 0 beads per unit time (a = (c q)^(2/(alpha-1)))."""
        c = check_real("c", c, "the compacton velocity (beads per unit time)", 0.0)
        alpha = train.model.alpha
        a = (c * train.q) ** (2 / (alpha - 1))
        omega = a ** ((alpha - 1) / 2)
        return cls(a=a, omega=omega, v=a * omega * train.p, c=omega / train.q, gap=a * train.p * train.q,
                   shift=2 * math.pi * a * train.p)


def chain_state(train, scales, N, phi, t=0.0):
    """(N, 2) array of (x_n, xdot_n) at time t, n = 0..N-1 (eqs. twlin and compacton)."""
    xi = train.q * np.arange(N) - scales.omega * t + phi
    x = scales.a * train(xi) + scales.v * t
    v = scales.v - scales.a * scales.omega * train.derivative(xi)
    return np.stack([x, v], axis=1)


def placement(train, rear_bead):
    """phi putting the rear edge of the train (xi - s_0 = ell) at bead ``rear_bead`` at t = 0: beads
    0..rear_bead are behind the train, at rest. (The train moves towards larger n; its last compacton leads.)"""
    return train.ell - train.q * rear_bead


def train_span(train):
    """Beads from the rear edge of the first compression region to the front edge of the last."""
    return (train.offsets[-1] + 2 * math.pi - 2 * train.ell) / train.q


def chain_length(train, margin, travel):
    """Beads needed for the train to travel ``travel`` beads with ``margin`` resting beads behind and ahead."""
    return int(math.ceil(2 * margin + train_span(train) + travel))


def simulate_on_chain(train, scales, N, phi, t_final, dt_snapshot, comm, tolerances=None):
    """Integrate the chain (eq. nc, free ends, TS prefix -chain_) from :func:`chain_state` at t = 0; returns the
    snapshot times and the (snapshots, N, 2) states, on every rank."""
    from .chain import Chain, ChainIntegrator
    if not (t_final > 0 and dt_snapshot > 0 and dt_snapshot <= t_final):
        raise ParameterError("dt_snapshot", dt_snapshot, f"must lie in (0, t_final = {t_final}]")
    chain = Chain(ChainSpec(train.model, N, "free"), comm)
    integ = ChainIntegrator(chain, tolerances)
    X = chain.create_state()
    chain.set_from_array(X, chain_state(train, scales, N, phi))
    k_final = int(round(t_final / dt_snapshot))
    times = dt_snapshot * np.arange(k_final + 1)
    states = [chain.gather(X)]
    try:
        for k in range(k_final):
            integ.integrate(X, times[k], times[k + 1])
            states.append(chain.gather(X))
    finally:
        X.destroy()
        integ.destroy()
        chain.destroy()
    return times, np.array(states)


@dataclass(frozen=True)
class LatticeChecks:
    """What :func:`lattice_checks` measured (errors relative as documented there)."""

    c: float
    shift: float
    gap: float
    v_peak: float
    t_final: float
    max_velocity_ahead: float
    max_displacement_ahead: float
    arrival_delay_min: float
    arrival_delay_max: float
    dt_snapshot: float
    measured_c: list
    beads_passed: int
    shift_error: float
    max_velocity_behind: float
    gap_error: float
    profile_error_x: float
    profile_error_v: float


def lattice_checks(train, scales, phi, times, states):
    """What section 3.3 asserts about the chain solution, measured on simulated snapshots (eq. compacton):

    - rest ahead: max |xdot_n| and max |x_n(t) - x_n(0)| over the beads at least one bead ahead of the
      leading compression region (exactly zero for an exact integration of an exact compacton);
    - arrival: for those beads, the first snapshot with xdot_n != 0 minus the predicted time at which
      xi_n - s_last crosses 2 pi - ell (in [0, dt] when the front arrives on time);
    - speed: c fitted to the times at which each bead's velocity peaks (xi_n - s_j = pi), per compacton;
    - shift: x_n(t_final) - x_n(0) against (number of compactons) 2 pi a p for the beads the whole train passed;
    - rest behind and gaps: the velocities and the gaps x_{n+1} - x_n left behind, against 0 and Delta = a p q;
    - profile: the final state against the exact one, relative to the shift and to the peak velocity.
    """
    q, ell, omega = train.q, train.ell, scales.omega
    two_pi = 2 * math.pi
    x, v = states[..., 0], states[..., 1]
    N = x.shape[1]
    xi0 = q * np.arange(N) + phi
    xi = xi0[None, :] - omega * times[:, None]
    s_last, s_first = train.offsets[-1], train.offsets[0]
    dt = times[1] - times[0]
    v_peak = scales.a * omega * (train.p - float(train.derivative(np.array([s_first + math.pi]))[0]))
    out = dict(c=scales.c, shift=scales.shift, gap=scales.gap, v_peak=v_peak, t_final=float(times[-1]))

    ahead = xi - s_last >= two_pi - ell + q
    out["max_velocity_ahead"] = float(np.max(np.abs(v[ahead]))) if ahead.any() else math.nan
    out["max_displacement_ahead"] = float(np.max(np.abs((x - x[0])[ahead]))) if ahead.any() else math.nan

    t_star = (xi0 - s_last - (two_pi - ell)) / omega
    reached = (t_star > 0) & (t_star < times[-1] - dt)
    moving = np.abs(v) > 0
    arrival = []
    for n in np.nonzero(reached)[0]:
        k = np.nonzero(moving[:, n])[0]
        if len(k):
            arrival.append(times[k[0]] - t_star[n])
    out["arrival_delay_min"] = float(np.min(arrival)) if arrival else math.nan
    out["arrival_delay_max"] = float(np.max(arrival)) if arrival else math.nan
    out["dt_snapshot"] = float(dt)

    half = (math.pi - ell) / omega                 # half the time a bead spends compressed
    speeds = []
    for s in train.offsets:
        t_peak_pred = (xi0 - s - math.pi) / omega
        beads, t_peak = [], []
        for n in np.nonzero((t_peak_pred > times[0] + half) & (t_peak_pred < times[-1] - half))[0]:
            window = np.nonzero(np.abs(times - t_peak_pred[n]) < half)[0]
            k = window[np.argmax(v[window, n])]
            if 0 < k < len(times) - 1:
                y0, y1, y2 = v[k - 1, n], v[k, n], v[k + 1, n]
                curv = y0 - 2 * y1 + y2
                beads.append(n)
                t_peak.append(times[k] + (0.5 * dt * (y0 - y2) / curv if curv < 0 else 0.0))
        speeds.append(float(np.polyfit(t_peak, beads, 1)[0]) if len(beads) >= 2 else math.nan)
    out["measured_c"] = speeds

    passed = (xi0 - s_last >= two_pi - ell) & (xi[-1] - s_first <= ell - q)
    out["beads_passed"] = int(passed.sum())
    out.update(shift_error=math.nan, max_velocity_behind=math.nan, gap_error=math.nan)
    if passed.any():
        dx = x[-1, passed] - x[0, passed]
        out["shift_error"] = float(np.max(np.abs(dx - train.count * scales.shift)) / scales.shift)
        out["max_velocity_behind"] = float(np.max(np.abs(v[-1, passed])))
        pairs = passed[1:] & passed[:-1]
        gaps = np.diff(x[-1])[pairs]
        out["gap_error"] = float(np.max(np.abs(gaps - scales.gap)) / scales.gap) if pairs.any() else math.nan
    exact = chain_state(train, scales, N, phi, times[-1])
    out["profile_error_x"] = float(np.max(np.abs(x[-1] - exact[:, 0])) / scales.shift)
    out["profile_error_v"] = float(np.max(np.abs(v[-1] - exact[:, 1])) / v_peak)
    return LatticeChecks(**out)
