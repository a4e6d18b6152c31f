"""The monodromy route to slow instabilities on the infinite chain: Bloch sectors of the wave's cell with the
symmetry multipliers deflated exactly (section 3.5 beyond the paper; eqs. nc, twper, invv).

For any twist Theta of the refined wave's cell (y_{n+M} = e^{i Theta} y_n: any Bloch parameter of the infinite chain)
the cell's short map G_Theta (:class:`hertzpetsc.bloch.BlochSectors`) gives F_q's block P_Theta = e^{-i j Theta}
G_Theta^{m'} (:mod:`hertzpetsc.symmetry`).

Known multipliers at mu = 1, with their eigenvectors from the orbit itself (no profile, no fit):

* each compression zone's translation: with f = (xdot, xddot) the time-shift direction (eq. nc at the initial
  state) and v the free-flight velocity, the restriction of f - v (1, 0) to the beads of one zone (q n in
  [2 pi k, 2 pi (k + 1))) is an exact eigenvector of P_Theta for every Theta, because no contact link joins two
  zones (the wave's free flights separate them); v is the one number that makes these vectors eigenvectors
  (least squares over the zones, :func:`zone_modes`);
* at Theta = 0 also the uniform translation (1, 0) and its Jordan partner, the Galilean boost (0, 1) / script-T.

Each zone mode's Jordan partner (P - I) w = z is the minimum-norm least-squares solution. In the orthonormal basis
[U, U_perp] of span{z, w} and its complement, U_perp^H P U_perp holds the other multipliers and U^H P U the symmetry
cluster (exactly 1 for an exact orbit: its distance from 1 and ||P U - U U^H P U|| measure the orbit and the flow).
"""
import math
import time
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
from petsc4py import PETSc

from .bloch import BlochSectors
from .continuation import golden_maximum
from .errors import ParameterError
from .floquet import FLOQUET_PREFIX, FLOQUET_TOLERANCES, FloquetSolver, Spectrum
from .symmetry import real_sector


def zone_directions(model, x0, q):
    """Per zone k of the M-bead cell state ``x0`` (M, 2): the restriction to the zone's beads of the time-shift
    direction f = (xdot, xddot) and of the translation t = (1, 0) of its beads of each type c of the mass pattern,
    as arrays f (m', 2M) and t (m', p, 2M). Bead n belongs to zone floor(q n / 2 pi) (the wave's free flight is
    centred on q n = 0 mod 2 pi)."""
    M, p = len(x0), model.cell
    x, v = x0[:, 0], x0[:, 1]
    bond = model.force(np.roll(x, -1) - x, 0)           # bond n = x_{n+1} - x_n, its law that of bond n mod p
    acc = (bond - np.roll(bond, 1)) / model.mass(np.arange(M))  # eq. nc
    zone = np.floor(q * np.arange(M) / (2 * math.pi) + 1e-12).astype(int)
    n_zones = int(zone.max()) + 1
    f, t = np.zeros((n_zones, 2 * M)), np.zeros((n_zones, p, 2 * M))
    for k in range(n_zones):
        on = np.nonzero(zone == k)[0]
        f[k, 2 * on], f[k, 2 * on + 1] = v[on], acc[on]
        for c in range(p):
            t[k, c, 2 * on[on % p == c]] = 1.0
    return f, t


def zone_modes(P, f, t):
    """The zone translation modes z_k = f_k - sum_c v_c t_kc with v_c the free-flight velocity of the beads of type
    c that makes them eigenvectors of P at 1 (least squares over all zones; the residual is then the orbit's and the
    flow's error): (Z (2M, m'), v (a number for one type, else one per type), max relative residual
    ||(P - I) z_k|| / ||z_k||). Directions of v that P does not see (one zone per cell at Theta = 0, where the
    uniform translation is itself exact) are set to 0."""
    I = np.eye(len(P))
    t = t[:, None, :] if t.ndim == 2 else t
    n_zones, p = t.shape[:2]
    A = np.concatenate([((P - I) @ t[k].T) for k in range(n_zones)])          # (m' 2M, p)
    B = np.concatenate([(P - I) @ f[k] for k in range(n_zones)])
    A, B = np.concatenate([A.real, A.imag]), np.concatenate([B.real, B.imag])   # v is real
    U, sv, Vh = np.linalg.svd(A, full_matrices=False)
    keep = sv > 1e-10 * max(1.0, float(np.linalg.norm(B)))
    v = Vh[keep].T @ ((U[:, keep].T @ B) / sv[keep])
    Z = (f - np.einsum("c,kcn->kn", v, t)).T
    res = np.linalg.norm((P - I) @ Z, axis=0) / np.linalg.norm(Z, axis=0)
    return Z, (float(v[0]) if p == 1 else v), float(res.max())


@dataclass
class DeflatedSector:
    """One twist Theta of a wave's cell after deflation: the multipliers that are not symmetry multipliers
    (``values``), the deflated cluster (eigenvalues of U^H P U), the raw cluster (the 2r eigenvalues of P nearest
    1, what an undeflated spectrum shows; None, as P's eigenvalues ``all_values``, where the scan was told not to
    compute them), the residuals of the known eigenvectors, of their partners and of the invariance of span U, the
    free-flight velocity and the size r of the known eigenspace."""

    theta: float
    M: int
    r: int
    values: np.ndarray
    cluster: np.ndarray
    raw_cluster: np.ndarray
    all_values: np.ndarray
    eigenvector_residual: float
    partner_residual: float
    invariance_residual: float
    v_free: float
    seconds: float
    decoupled: bool = True
    signatures: np.ndarray = None     # Krein signatures of ``values`` (DeflatedSectors(krein=True))
    slopes: np.ndarray = None         # d arg(mu)/dTheta of ``values`` on the unit circle (nan elsewhere; with krein)

    def pattern(self):
        """The sector's :func:`krein_pattern`; () without signatures (DeflatedSectors(krein=None))."""
        return () if self.signatures is None else krein_pattern(self.values, self.signatures)

    @property
    def rho(self):
        """The largest |mu| outside the symmetry cluster."""
        return float(np.max(np.abs(self.values))) if len(self.values) else 1.0


def deflate(P, known, partners_of, extra=(), vectors=False, nearest=0):
    """Deflate the known eigenvectors ``known`` (columns, eigenvalue 1 of P) and their Jordan partners.

    ``partners_of``: columns whose partners are computed (minimum-norm least squares of (P - I) w = z);
    ``extra``: further (eigenvector, partner) columns known in closed form; ``nearest``: then that many eigenvalues
    nearest 1 of the deflated matrix join the cluster (the partners of known eigenvectors not computed: with the
    exact eigenvector deflated, its partner's eigenvalue is 1 to the orbit's error, not to its square root). Returns
    (values outside, cluster eigenvalues, partner residual, invariance residual, r, the values' eigenvectors (columns,
    in P's space) if ``vectors`` else None); with nothing known, P's eigenvalues and r = 0."""
    n, I = len(P), np.eye(len(P))
    Zs = np.asarray(partners_of, dtype=complex).reshape(n, -1)
    W = np.linalg.lstsq(P - I, Zs, rcond=1e-10)[0]
    partner_res = float(np.max(np.linalg.norm((P - I) @ W - Zs, axis=0) / np.linalg.norm(Zs, axis=0), initial=0.0))
    B = np.concatenate([np.asarray(c, dtype=complex).reshape(n, -1) for c in (known, W, *extra)], axis=1)
    Q, R = np.linalg.qr(B, mode="complete")
    d = np.abs(np.diag(R))
    r = int(np.sum(d > 1e-10 * d.max(initial=0.0)))
    if r != B.shape[1]:
        raise ParameterError("known eigenvectors", B.shape[1], f"must be independent (rank {r}); the orbit is not "
                             "a travelling wave of the chain or its zones touch")
    U, Uperp = Q[:, :r], Q[:, r:]
    A11 = U.conj().T @ P @ U
    invariance = float(np.linalg.norm(P @ U - U @ A11) / np.linalg.norm(P))
    cluster = np.linalg.eigvals(A11)
    D = Uperp.conj().T @ P @ Uperp
    values, Y = np.linalg.eig(D) if vectors else (np.linalg.eigvals(D), None)
    if nearest:
        near = np.argsort(np.abs(values - 1.0), kind="stable")[:nearest]
        cluster = np.concatenate([cluster, values[near]])
        values = np.delete(values, near)
        Y = None if Y is None else np.delete(Y, near, axis=1)
        r += len(near)
    if Y is None:
        return values, cluster, partner_res, invariance, r, None
    # P [U, Uperp] = [U, Uperp] [[A11, A12], [0, D]]: the eigenvector of P for (lam, y) of D is Uperp y + U z with
    # (A11 - lam) z = -A12 y (lam is no cluster eigenvalue)
    A12 = U.conj().T @ P @ Uperp
    k = len(A11)
    if k and len(values):
        shifted = A11[None, :, :] - values[:, None, None] * np.eye(k)[None, :, :]
        Z = np.linalg.solve(shifted, -(A12 @ Y).T[:, :, None])[:, :, 0].T
    else:
        Z = np.zeros((k, len(values)))
    return values, cluster, partner_res, invariance, r, Uperp @ Y + U @ Z


def symplectic_form(model, M):
    """J (2M x 2M, index 2n + c) of eq. nc's symplectic form on a cell of M beads: w(u, v) = sum_n m_n (u_n vdot_n -
    udot_n v_n) = u^T J v; the cell maps preserve v^H J v (a Bloch twist makes it Hermitian times i)."""
    J = np.zeros((2 * M, 2 * M))
    m = model.mass(np.arange(M))
    J[2 * np.arange(M), 2 * np.arange(M) + 1] = m
    J[2 * np.arange(M) + 1, 2 * np.arange(M)] = -m
    return J


def krein_signatures(values, V, J, tol):
    """The Krein signature of each multiplier: the sign of Im(v^H J v) for the eigenvector v of a multiplier on the
    unit circle (| ln|mu| | <= ``tol``); 0 for one off the circle, or whose form is below 1e-8 of |v|^2 max(m)
    (isotropic: at a collision)."""
    form = np.imag(np.einsum("ij,ij->j", V.conj(), J @ V))
    size = np.sum(np.abs(V) ** 2, axis=0) * float(np.max(np.abs(J)))
    on = np.abs(np.log(np.abs(values))) <= tol
    return np.where(on & (np.abs(form) > 1e-8 * size), np.sign(form), 0).astype(int)


def twist_slopes(values, V, G, dG, J, m_cell, j, theta, tol):
    """Krein signatures and d arg(mu)/dTheta of the multipliers ``values`` mu = e^{-i j Theta} lambda^{m'} of
    P_Theta = e^{-i j Theta} G_Theta^{m'} (columns of ``V``: their eigenvectors), by first-order perturbation: J v is
    the left eigenvector of a multiplier on the circle (G^H J G = J), so

        d arg(mu)/dTheta = -j + m' Im( v^H J G' v / (lambda v^H J v) ),     G' = dG_Theta/dTheta,

    with v an eigenvector of G. Where two eigenvalues of G give (nearly) one of P, P's eigenvectors mix them: there
    the eigenvectors of G on their span are used (signatures and slopes of each). Slopes are nan off the circle."""
    V = np.array(V, dtype=complex)
    GV = G @ V
    norm = np.sum(np.abs(V) ** 2, axis=0)
    lam = np.sum(V.conj() * GV, axis=0) / norm
    scale = max(np.linalg.norm(G, 2), 1e-300)
    mixed = np.linalg.norm(GV - V * lam, axis=0) / (np.sqrt(norm) * scale) > 1e-8
    done = np.zeros(len(values), bool)
    for i in np.nonzero(mixed)[0]:
        if done[i]:
            continue
        group = np.nonzero(np.abs(values - values[i]) <= 1e-4 * max(1.0, abs(values[i])))[0]
        Q = np.linalg.qr(V[:, group])[0]
        mu, Y = np.linalg.eig(Q.conj().T @ G @ Q)
        # each P value of the group takes the G eigenvector whose power predicts it best
        predicted = np.exp(-1j * j * theta) * mu ** m_cell
        cost = np.abs(predicted[None, :] - values[group][:, None])
        taken = set()
        for g in np.argsort(np.min(cost, axis=1)):
            k = min((k for k in range(len(mu)) if k not in taken), key=lambda k: cost[g, k])
            taken.add(k)
            V[:, group[g]], lam[group[g]] = Q @ Y[:, k], mu[k]
        done[group] = True
    form = np.sum(V.conj() * (J @ V), axis=0)
    size = np.sum(np.abs(V) ** 2, axis=0) * float(np.max(np.abs(J)))
    on = np.abs(np.log(np.abs(values))) <= tol
    signatures = np.where(on & (np.abs(form.imag) > 1e-8 * size), np.sign(form.imag), 0).astype(int)
    with np.errstate(divide="ignore", invalid="ignore"):          # the form vanishes only off the circle
        rate = np.sum(V.conj() * (J @ (dG @ V)), axis=0) / (lam * form)
    return signatures, np.where(signatures != 0, -j + m_cell * rate.imag, np.nan)


def krein_pattern(values, signatures):
    """The Krein signatures of the multipliers on the unit circle read around it by angle, as a canonical cyclic
    sequence (the least rotation): two multipliers of opposite signatures that pass each other (through a collision,
    and an instability bubble between) change it, a common rotation or same-signature crossings do not."""
    on = np.nonzero(signatures)[0]
    seq = tuple(int(signatures[i]) for i in on[np.argsort(np.angle(values[on]), kind="stable")])
    if not seq:
        return seq
    return min(seq[k:] + seq[:k] for k in range(len(seq)))


# Zone translations are deflated when they are eigenvectors to this relative residual: exact ones (zones that no
# contact joins: every uncompressed wave, precompressed waves well beyond the gap opening) have the orbit's and the
# flow's error (1e-12 .. 1e-8); zones that a contact joins for part of the period have residuals of the coupling.
ZONE_TOL = 1e-6


def known_vectors(model, orbit, P, theta, decoupled=None):
    """The symmetry eigenvectors of P_Theta at 1 for ``orbit`` (module docstring): (known columns, the columns whose
    partners are computed, closed-form (eigenvector, partner) extras, the number of partners taken as the nearest 1
    after deflation (:func:`deflate`), the known columns' largest residual, v, decoupled).

    ``decoupled``: whether the zone translations are exact (None: decided from their residual against
    :data:`ZONE_TOL`, where that is informative, i.e. the cell holds several zones or Theta != 0; with one zone at
    Theta = 0 the only symmetry modes are the wave's time shift and the uniform translation). Zones joined by a
    contact (a precompressed wave below its gap opening) leave at Theta = 0 the time shift f of the whole cell, and
    the uniform translation with the boost; f's partner (the family's amplitude direction, an eigenvector itself in
    the linear limit, where the least-squares partner fails) is the eigenvalue nearest 1 once they are deflated; at
    Theta != 0 nothing."""
    M = orbit.symmetry.M
    f, t = zone_directions(model, orbit.x[:M], orbit.q)
    Z, v, zone_res = zone_modes(P, f, t)
    if decoupled is None:
        # decoupled when the zone translations are eigenvectors (without precompression no contact of the paper's
        # chain outlives a compression zone, but a mass pattern's light beads may carry one across the zones'
        # boundaries: the residual decides for every law), where that is informative
        decoupled = (len(f) > 1 or abs(theta) > 1e-14) and bool(zone_res <= ZONE_TOL)
    I = np.eye(2 * M)

    def residual(vec):
        return float(np.linalg.norm((P - I) @ vec) / np.linalg.norm(vec))

    none = np.zeros((2 * M, 0))
    known, partners, eig_res = (Z, Z, zone_res) if decoupled else (none, none, 0.0)
    extra, nearest = (), 0
    if abs(theta) < 1e-14:                     # uniform translation and the Galilean boost (0, 1) / script-T
        trans, boost = np.tile([1.0, 0.0], M), np.tile([0.0, 1.0], M) / orbit.T
        if not decoupled:                      # the whole cell's time shift; its partner: the nearest 1 left
            whole = f.sum(axis=0)
            known, partners, nearest = whole[:, None], none, 1
            eig_res = residual(whole)
        known = np.concatenate([known, trans[:, None]], axis=1)
        eig_res = max(eig_res, residual(trans))
        extra = (boost,)
    return known, partners, extra, nearest, eig_res, v, decoupled


class DeflatedSectors(FloquetSolver):
    """Deflated sector spectra of waves on their cells for any twist (the flow ``floquet_``, as the Bloch routes;
    build once, reuse for every wave), any mass pattern, with or without precompression. :meth:`spectrum` gathers
    the sectors at the cell twists ``twists`` (in [0, pi]; None: the chain's own sectors theta_l = 2 pi l / g and
    their conjugates, i.e. all 2N multipliers of F_q on N beads): the multipliers of each and its deflated cluster,
    which are the known (trivial) ones; the :class:`DeflatedSector` of each twist is in ``work["sectors"]``.
    :meth:`scan`: any set of twists of one orbit (the infinite chain's Bloch parameters)."""

    def __init__(self, model, comm, tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX, twists=(0.0,), krein=None):
        self.model = model
        self.krein = krein           # None, or the tolerance on | ln|mu| | of a multiplier on the unit circle
        self.twists = None if twists is None else [float(t) for t in twists]
        self.sectors = BlochSectors(model, comm, tolerances, prefix)
        self.sectors.configure()

    def _deflated(self, orbit, P, theta, decoupled=None, raw=True, G=None, dG=None):
        t0 = time.perf_counter()
        known, partners, extra, nearest, eig_res, v, decoupled = known_vectors(self.model, orbit, P, theta, decoupled)
        values, cluster, partner_res, invariance, r, V = deflate(P, known, partners, extra, self.krein is not None,
                                                                 nearest)
        signatures = slopes = None
        if self.krein is not None:
            J = symplectic_form(self.model, len(P) // 2)
            if dG is None:
                signatures = krein_signatures(values, V, J, self.krein)
            else:
                sym = orbit.symmetry
                signatures, slopes = twist_slopes(values, V, G, dG, J, sym.m_cell, sym.j, theta, self.krein)
        if r and raw:
            lam = np.linalg.eigvals(P)
            nearest_one = lam[np.argsort(np.abs(lam - 1.0))[:r]]
        elif r:
            lam = nearest_one = None
        else:
            lam, nearest_one = values, np.zeros(0, dtype=complex)
        return DeflatedSector(theta, len(P) // 2, r, values, cluster, nearest_one, lam, eig_res, partner_res,
                              invariance, v, time.perf_counter() - t0, decoupled, signatures, slopes)

    @PETSc.Log.EventDecorator("hz_deflated_sector")
    def sector(self, orbit, theta):
        """The :class:`DeflatedSector` of ``orbit`` (a wave on N beads) at twist ``theta`` in [0, pi] per cell of
        M = N / gcd(m, N) beads (one twisted run)."""
        return self.scan(orbit, [theta], propagate=False)[1][0]

    @PETSc.Log.EventDecorator("hz_deflated_scan")
    def scan(self, orbit, thetas, propagate=None, raw=True, slopes=False):
        """A function theta -> :class:`DeflatedSector` of ``orbit`` (every twist from the same cell maps: one
        propagator run when the response stays within a cell, :meth:`~hertzpetsc.bloch.BlochSectors.sector_maps`;
        ``propagate`` None: when ``thetas`` holds two complex twists or more; ``raw``: also P's own eigenvalues,
        the raw cluster; ``slopes``: also the multipliers' twist derivatives, :func:`twist_slopes`, with Krein
        signatures), the zones' decoupling decided once, at the first informative twist of ``thetas`` (Theta = 0 if
        the cell holds several zones); and the sectors at ``thetas``."""
        sym = orbit.symmetry
        if propagate is None:
            propagate = sum(1 for theta in thetas if not real_sector(theta)) >= 2
        maps = self.sectors.sector_maps(orbit.x[:sym.M], sym.delta(orbit.T), sym.k, propagate)
        state = dict(decoupled=None)

        def at(theta):
            if not (-1e-14 <= theta <= math.pi + 1e-14):
                raise ParameterError("theta", theta, "the cell's twist must lie in [0, pi]")
            G = maps(theta)
            P = np.linalg.matrix_power(G, sym.m_cell)
            if theta != 0.0:
                P = np.exp(-1j * sym.j * theta) * P
            dG = maps.derivative(theta) if slopes and self.krein is not None else None
            s = self._deflated(orbit, P, theta, state["decoupled"], raw, G, dG)
            if state["decoupled"] is None and (sym.m_cell > 1 or abs(theta) > 1e-14):
                state["decoupled"] = s.decoupled
            return s

        order = sorted(range(len(thetas)), key=lambda i: (sym.m_cell == 1 and abs(thetas[i]) < 1e-14, i))
        out = [None] * len(thetas)
        for i in order:
            out[i] = at(float(thetas[i]))
        return at, out

    def _spectrum(self, orbit, tol_rho, nev):
        if self.twists is not None:
            sectors = [self.sector(orbit, theta) for theta in self.twists]
            values = np.concatenate([np.concatenate([s.values, s.cluster]) for s in sectors])
            known = np.concatenate([np.arange(len(s.values) + len(s.cluster)) >= len(s.values) for s in sectors])
            return Spectrum(values, True, tol_rho, known=known, work=dict(sectors=sectors))
        sym = orbit.symmetry
        thetas = sym.sectors()
        _, sectors = self.scan(orbit, thetas)
        values, known, label = [], [], []
        for l, s in enumerate(sectors):
            for conj in ((False, True) if 0 < 2 * l < sym.g else (False,)):
                part = np.concatenate([s.values, s.cluster])
                values.append(np.conj(part) if conj else part)
                known.append(np.arange(len(part)) >= len(s.values))
                label.append(np.full(len(part), sym.g - l if conj else l))
        return Spectrum(np.concatenate(values), True, tol_rho, known=np.concatenate(known),
                        sector=np.concatenate(label), M=sym.M, L=sym.g,
                        work=dict(sectors=sectors, decoupled=any(s.decoupled for s in sectors)))

    def destroy(self):
        self.sectors.destroy()


# --- stability over the whole twist circle ----------------------------------------------------------------------------
# A verdict 'stable' claims rho - 1 <= tol_rho at every twist of [theta_min, pi], not only at the samples. Between two
# stable samples the multipliers of each Krein signature are matched by their twist slopes (twist_slopes) and each
# curve arg mu(Theta) is the cubic Hermite interpolant of its values and slopes, with the error estimate
# |trapezoid defect| + h |slope change| / 8 (the defect is h^3 |phi'''| / 12, the second term the largest departure
# from the chord that the end slopes allow). Multipliers leave the circle only by colliding with one of the opposite
# signature (Krein); in the 2 x 2 normal form of such a collision, with relative angular speed s of the pair, a
# bubble of instability of height c (log |mu|) has width 4 c / s. So a pair whose interpolated gap keeps its sign by
# more than the error estimate cannot collide in the interval, and a pair that crosses (or nearly touches) inside an
# interval of width h between stable ends holds at most a bubble of height s h / 4. CERT_MARGIN tol_rho is the
# height certified; pairs above it are refined (the predicted crossing bracketed to that width, the near miss sampled
# at its closest approach) until they are certified, a sample is unstable, or the budget ends: 'unresolved'.
CERT_MARGIN = 0.1
# the matching of one interval is refused (the interval halved) when a curve's interpolation error estimate exceeds
# this fraction of its distance to the nearest multiplier of the other signature at either end
MATCH_FRACTION = 0.25


def _wrap(x):
    """x in (-pi, pi]."""
    return np.angle(np.exp(1j * np.asarray(x)))


def _hermite_extremes(g0, g1, d0, d1, h):
    """For cubic Hermite interpolants on [0, h] (arrays of end values g, slopes d): the smallest |g| over the
    interval, the point where it is reached, and whether g changes sign (a root)."""
    # H(t) = g0 + d0 t + c2 t^2 + c3 t^3
    c2 = (3 * (g1 - g0) / h - 2 * d0 - d1) / h
    c3 = (d0 + d1 - 2 * (g1 - g0) / h) / h ** 2
    cand = [np.zeros_like(g0), np.full_like(g0, h)]
    disc = (2 * c2) ** 2 - 12 * c3 * d0
    with np.errstate(invalid="ignore", divide="ignore"):
        sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
        for sign in (1.0, -1.0):
            t = np.where(np.abs(c3) > 1e-300, (-2 * c2 + sign * sq) / (6 * c3),
                         np.where(np.abs(c2) > 1e-300, -d0 / (2 * c2), np.nan))
            cand.append(np.where((t > 0) & (t < h), t, np.nan))
    T = np.stack(cand)
    H = g0 + d0 * T + c2 * T ** 2 + c3 * T ** 3
    Habs = np.where(np.isnan(H), np.inf, np.abs(H))
    k = np.argmin(Habs, axis=0)
    idx = np.arange(len(g0))
    sign_change = (np.sign(g0) != np.sign(g1)) | np.any(np.where(np.isnan(H), False, np.sign(H) != np.sign(g0)), axis=0)
    return Habs[k, idx], T[k, idx], sign_change


def _hermite_root(g0, g1, d0, d1, h):
    """A root in (0, h) of the cubic Hermite interpolant of (g0, d0), (g1, d1), g0 g1 < 0 (bisection safeguarding
    Newton, to 1e-12 h)."""
    c2 = (3 * (g1 - g0) / h - 2 * d0 - d1) / h
    c3 = (d0 + d1 - 2 * (g1 - g0) / h) / h ** 2
    lo, hi = 0.0, h
    t = -g0 * h / (g1 - g0)
    for _ in range(60):
        H = g0 + t * (d0 + t * (c2 + t * c3))
        if abs(H) <= 1e-15 * (abs(g0) + abs(g1)):
            break
        if np.sign(H) == np.sign(g0):
            lo = t
        else:
            hi = t
        dH = d0 + t * (2 * c2 + 3 * t * c3)
        t = t - H / dH if dH != 0 else 0.5 * (lo + hi)
        if not lo < t < hi:
            t = 0.5 * (lo + hi)
        if hi - lo < 1e-12 * h:
            break
    return t


def _match(sa, sb, h, sign):
    """Indices (i, j) matching the multipliers of Krein signature ``sign`` at the two ends of an interval by their
    predicted positions (slopes), the lifted increments of arg mu, and each curve's interpolation error estimate;
    None if the counts differ or a slope is missing."""
    ia, ib = np.nonzero(sa.signatures == sign)[0], np.nonzero(sb.signatures == sign)[0]
    if len(ia) != len(ib):
        return None
    pa, pb = np.angle(sa.values[ia]), np.angle(sb.values[ib])
    da, db = sa.slopes[ia], sb.slopes[ib]
    if not (np.all(np.isfinite(da)) and np.all(np.isfinite(db))):
        return None
    if not len(ia):
        return ia, ib, np.zeros(0), np.zeros(0)
    # the defect of the trapezoid rule for each candidate pair: small for the right partner
    mean = 0.5 * h * (da[:, None] + db[None, :])
    cost = np.abs(_wrap(pb[None, :] - pa[:, None] - mean))
    order = np.argsort(cost, axis=None, kind="stable")
    row, col = np.full(len(ia), -1), np.full(len(ib), -1)
    for flat in order:
        i, j = divmod(int(flat), len(ib))
        if row[i] < 0 and col[j] < 0:
            row[i], col[j] = j, i
    j = row
    defect = _wrap(pb[j] - pa - mean[np.arange(len(ia)), j])
    increment = mean[np.arange(len(ia)), j] + defect
    error = np.abs(defect) + h * np.abs(db[j] - da) / 8
    return ia, ib[j], increment, error


@dataclass
class TwistCertificate:
    """What the samples of a twist scan certify over [theta_min, pi] (module note above :data:`CERT_MARGIN`):
    ``status`` 'stable' (rho - 1 <= ``bound`` at every twist between the samples, bound <= CERT_MARGIN tol_rho),
    'unstable' (a sample with rho - 1 > tol_rho: ``theta``), or 'unresolved' (``unresolved`` intervals left when
    the budget ended); ``pairs``: collisions bounded by their bubble's height, ``samples``: twists added."""

    status: str
    bound: float
    theta_min: float
    samples: int
    pairs: int = 0
    theta: float = math.nan
    unresolved: tuple = ()


def _curves(s, other):
    """The multipliers of sample ``s`` on the unit circle that the curve analysis follows: those with a Krein
    signature, less, for each pair inside a (weak) bubble at the ``other`` end (signature 0 there), the multipliers
    of each signature nearest to that pair's angle (the bubble's pair, still on the circle at this end)."""
    keep = s.signatures != 0
    off = np.angle(other.values[other.signatures == 0])
    for angle in off[::2]:
        for sign in (1, -1):
            cand = np.nonzero(keep & (s.signatures == sign))[0]
            if len(cand):
                keep[cand[np.argmin(np.abs(_wrap(np.angle(s.values[cand]) - angle)))]] = False
    return SimpleNamespace(theta=s.theta, values=s.values[keep], signatures=s.signatures[keep],
                           slopes=s.slopes[keep])


def _interval(sa, sb, h, height):
    """One interval between two stable samples: (bound, offsets) -- the largest bubble height that its colliding or
    nearly colliding pairs allow (0 if none), and the offsets in (0, h) of the samples that would resolve the pairs
    above ``height`` (none when the interval is certified); None if its ends cannot be matched (halve it). A pair
    inside a bubble at either end (bounded by the caller) is left out at both ends (:func:`_curves`)."""
    sa, sb = _curves(sa, sb), _curves(sb, sa)
    plus, minus = _match(sa, sb, h, 1), _match(sa, sb, h, -1)
    if plus is None or minus is None:
        return None
    ip, jp, incp, errp = plus
    im, jm, incm, errm = minus
    if not len(ip) or not len(im):
        return 0.0, []
    arg = np.angle(sa.values)
    ga = _wrap(arg[ip][:, None] - arg[im][None, :])              # gap of each (+, -) pair at both ends, lifted
    gb = ga + incp[:, None] - incm[None, :]
    da = sa.slopes[ip][:, None] - sa.slopes[im][None, :]
    db = sb.slopes[jp][:, None] - sb.slopes[jm][None, :]
    err = errp[:, None] + errm[None, :]
    # a curve is followed reliably when its error estimate is a small part of its distance to the other signature
    dist_p = np.minimum(np.min(np.abs(ga), axis=1), np.min(np.abs(gb), axis=1))
    dist_m = np.minimum(np.min(np.abs(ga), axis=0), np.min(np.abs(gb), axis=0))
    suspect = ((errp > MATCH_FRACTION * dist_p)[:, None] | (errm > MATCH_FRACTION * dist_m)[None, :]).ravel()
    g0, g1, d0, d1 = (x.ravel() for x in (ga, gb, da, db))
    low, where, crosses = _hermite_extremes(g0, g1, d0, d1, h)
    safe = ~suspect & ~crosses & (low > err.ravel() + 1e-12)
    s = np.maximum(np.maximum(np.abs(d0), np.abs(d1)), np.abs(g1 - g0) / h)
    bubble = s * h / 4
    bounded = ~safe & ~suspect & (bubble <= height)
    open_ = ~safe & ~bounded
    bound = float(np.max(bubble[bounded], initial=0.0))
    offsets = set()
    for k in np.nonzero(open_)[0]:
        t = where[k] if (0 < where[k] < h and not suspect[k]) else 0.5 * h
        if crosses[k] and not suspect[k] and np.sign(g0[k]) != np.sign(g1[k]):
            t = _hermite_root(g0[k], g1[k], d0[k], d1[k], h)
            # bracket the predicted crossing to the width whose bubble bound is the certified height
            w = 0.9 * 4 * height / max(s[k], 1e-300)
            offsets.update((t - w / 2, t + w / 2))
        else:
            offsets.add(t)
    return bound, sorted({min(max(t, 0.02 * h), 0.98 * h) for t in offsets})


def certify_twists(sector, thetas, tol_rho, budget=4000, min_width=1e-12, margin=CERT_MARGIN, longwave=0.0,
                   longwave_budget=32):
    """:class:`TwistCertificate` of the stable samples ``thetas`` (sorted, the first is theta_min) of one scan:
    ``sector(theta)`` a :class:`DeflatedSector` with Krein signatures and slopes; at most ``budget`` twists added;
    intervals narrower than ``min_width`` are not split further. The intervals below ``longwave`` (the grid's first
    twist: the long-wave twists) are certified downwards, each with at most ``longwave_budget`` twists: the first
    that does not close ends the certified range there (theta_min rises to its upper end) instead of leaving the
    verdict unresolved."""
    height = margin * tol_rho
    xs = sorted(set(float(t) for t in thetas))
    state = dict(added=0, bound=0.0, pairs=0, bubbles={})

    def close(a, b, allowed):
        """Certify [a, b] with at most ``allowed`` added twists: (the intervals left, the unstable twist or None)."""
        stack, left, start = [(a, b)], [], state["added"]
        while stack:
            a, b = stack.pop()
            sa, sb = sector(a), sector(b)
            for s in (sa, sb):
                if s.rho - 1 > tol_rho:
                    return left, s.theta
                if np.any(s.signatures == 0) and s.theta not in state["bubbles"]:
                    # inside a weak bubble (a pair off the circle by less than tol_rho): its maximum over the twists
                    # around (unimodal: the 2 x 2 normal form), evaluated as a sample
                    lo, hi = max(xs[0], s.theta - (b - a)), min(math.pi, s.theta + (b - a))
                    top, value = golden_maximum(lambda t: sector(t).rho, lo, hi, 1e-3 * (hi - lo))
                    state["bubbles"][s.theta] = value - 1
                    if value - 1 > tol_rho:
                        return left, top
                    state["bound"] = max(state["bound"], value - 1)
            out = _interval(sa, sb, b - a, height)
            if out is not None and not out[1]:
                state["bound"] = max(state["bound"], out[0])
                state["pairs"] += int(out[0] > 0)
                continue
            cuts = [0.5 * (b - a)] if out is None else out[1]
            if b - a < min_width or state["added"] - start + len(cuts) > allowed:
                left.append((a, b))
                continue
            points = [a] + [a + c for c in cuts] + [b]
            state["added"] += len(cuts)
            stack.extend(list(zip(points[:-1], points[1:]))[::-1])
        return left, None

    def result(status, theta_min, theta=math.nan, unresolved=()):
        return TwistCertificate(status, math.inf if status == "unstable" else state["bound"], theta_min,
                                state["added"], state["pairs"], theta, tuple(unresolved))

    unresolved = []
    upper = [(a, b) for a, b in zip(xs[:-1], xs[1:]) if a >= longwave]
    for a, b in upper:
        left, bad = close(a, b, max(budget - state["added"], 0))
        if bad is not None:
            return result("unstable", xs[0], bad)
        unresolved += left
    theta_min = xs[0]
    for a, b in reversed([(a, b) for a, b in zip(xs[:-1], xs[1:]) if a < longwave]):
        left, bad = close(a, b, longwave_budget)
        if bad is not None:
            return result("unstable", xs[0], bad)
        if left:
            theta_min = b
            break
    return result("unresolved" if unresolved else "stable", theta_min, unresolved=unresolved)


@dataclass
class TwistScan:
    """The infinite chain's multipliers around one wave, over the Bloch parameters Theta in [0, pi] of its cell:
    the grid of ``n_grid`` + 1 twists, the hints, the refinements around the largest local maxima of rho and the
    certification's samples (``thetas``, ``rho`` sorted by Theta); the worst twist and its rho, the deflated
    cluster's largest |mu - 1| over the scan, whether the zones were decoupled, and the
    :class:`TwistCertificate` of a scan whose samples are all stable (None when it found an unstable twist, or was
    run without Krein signatures)."""

    thetas: np.ndarray
    rho: np.ndarray
    theta: float
    rho_max: float
    n_grid: int
    cluster: float
    eigenvector_residual: float
    decoupled: bool
    certificate: TwistCertificate = None
    floor: float = 0.0
    theta_min: float = 0.0

    @property
    def verdict(self):
        """'unstable' (a twist with rho - 1 above the scan's floor), 'stable' (certified between the samples),
        'unresolved' (stable samples, not certified between them), or 'sampled' (no certification asked)."""
        if self.rho_max - 1 > self.floor:
            return "unstable"
        c = self.certificate
        return c.status if c is not None else "sampled"


def crossing_search(evaluate, unstable, pattern, a, b, pa, min_width):
    """A point of an instability bubble between two stable samples a < b whose Krein patterns differ (``pa``: a's):
    bisection keeping the half whose end patterns differ, until a sample is unstable (returned with its value) or the
    interval is narrower than ``min_width`` (None: the crossing's bubble, if any, is narrower). Returns (the unstable
    sample, its value, the stable samples a, b around it)."""
    while b - a > min_width:
        c = 0.5 * (a + b)
        value = evaluate(c)
        if unstable(value):
            return c, value, a, b
        pc = pattern(value)
        if pc != pa:
            b = c
        else:
            a, pa = c, pc
    return None


# The long-wave multipliers of a cell twist Theta -> 0 (those that the deflation leaves of the symmetry cluster at 1)
# tend to 1 linearly: |mu - 1| / Theta tends to a constant while they are resolved; below, the orbit's and the flow's
# errors split them as they split the Jordan blocks at Theta = 0, and their crossings (pairs off the circle) are
# artefacts. A scan identifies them at a quarter and an eighth of its grid's first twist (the multipliers nearest 1
# whose |mu - 1| halves with Theta, to 10 %), then halves the twist while they keep |mu - 1| / Theta within
# LONGWAVE_DRIFT of its value at the twice larger twist and stay on the circle with a Krein signature, at most
# LONGWAVE_DEPTH times; the last such twist is theta_min (without long-wave multipliers: the grid's first twist).
LONGWAVE_DRIFT = 0.02
LONGWAVE_DEPTH = 24


def _nearest_one(s, theta, k):
    """|mu - 1| / theta of the k multipliers of sector ``s`` nearest 1, and whether each has a Krein signature."""
    i = np.argsort(np.abs(s.values - 1))[:k]
    signed = np.ones(len(i), bool) if s.signatures is None else s.signatures[i] != 0
    return np.abs(s.values[i] - 1) / theta, signed


def longwave_limit(sector, theta1):
    """The smallest cell twist a scan resolves (module note above :data:`LONGWAVE_DRIFT`): ``sector(theta)`` the
    deflated sector, ``theta1`` the grid's first twist."""
    theta = theta1 / 4
    ra, _ = _nearest_one(sector(2 * theta), 2 * theta, 4)
    ref, _ = _nearest_one(sector(theta), theta, 4)
    k = 0
    while k < min(len(ra), len(ref)) and abs(ref[k] - ra[k]) <= 0.1 * ra[k]:
        k += 1
    if not k:
        return theta1
    ref = ref[:k]
    for _ in range(LONGWAVE_DEPTH):
        rates, signed = _nearest_one(sector(theta / 2), theta / 2, k)
        if np.any(np.abs(rates - ref) > LONGWAVE_DRIFT * ref) or not np.all(signed):
            break
        theta, ref = theta / 2, rates
    return theta


# The certification's default budget: 64 twists per grid interval on cells of up to CERT_CELL beads, scaled by
# (CERT_CELL / M)^3 beyond (a twist costs dense algebra of order M^3 on a cell of M beads): longer cells are left
# unresolved rather than run for hours (their matrix-free sectors are issue 41's).
CERT_CELL = 100


def certification_budget(n_grid, M):
    """The twists :func:`certify_twists` may add to a scan of ``n_grid`` intervals on a cell of M beads."""
    return int(64 * n_grid * min(1.0, (CERT_CELL / M) ** 3))


@PETSc.Log.EventDecorator("hz_twist_scan")
def twist_scan(sectors, orbit, n_grid, hints=(), refine=3, floor=0.0, resolution=1e-3, budget=None):
    """rho over the cell twists of ``orbit`` (a :class:`~hertzpetsc.waves.Orbit` on its cell; the infinite chain's
    Bloch parameters Theta in [0, pi]): the grid Theta_j = j pi / n_grid, the ``hints`` (twists where an unstable
    mode was seen before: a narrow band near its onset is followed there), then a golden-section refinement of rho
    around the ``refine`` largest local maxima with rho - 1 > ``floor`` and around every hint, between its
    neighbours, to ``resolution`` of the grid step. ``sectors``: a :class:`DeflatedSectors` (symmetry multipliers
    deflated at Theta = 0, and at every Theta when the zones are decoupled). With Krein signatures
    (``sectors.krein``), a scan whose samples are all stable is certified between them (:func:`certify_twists`, at
    most ``budget`` twists added, default :func:`certification_budget`): a band of instability narrower than the
    grid is found there, or bounded below CERT_MARGIN ``floor``.

    Below the grid's first twist pi / n_grid the scan halves the twist down to :func:`longwave_limit`, where the
    long-wave multipliers stop being resolved (their crossings there are artefacts of the orbit's error); the
    certification closes these long-wave intervals downwards and stops at the first it cannot close. The scan
    covers [theta_min, pi] (``theta_min``; Theta = 0 too): modulations of at most 2 pi M / theta_min beads, M the
    cell; the samples below theta_min do not count."""
    certify = sectors.krein is not None
    at, first = sectors.scan(orbit, [0.0], propagate=True, raw=False, slopes=certify)
    seen = {0.0: first[0]}

    def sector(theta):
        theta = min(max(float(theta), 0.0), math.pi)
        if theta not in seen:
            seen[theta] = at(theta)
        return seen[theta]

    def rho(theta):
        return sector(theta).rho

    def refine_peaks(hints):
        xs = sorted(seen)
        ys = [seen[x].rho for x in xs]
        peaks = [i for i in range(1, len(xs)) if ys[i] - 1 > floor and ys[i] >= ys[i - 1]
                 and (i == len(xs) - 1 or ys[i] >= ys[i + 1])]
        peaks = sorted(peaks, key=lambda i: -ys[i])[:refine] + [xs.index(h) for h in hints if h in seen]
        for i in sorted(set(peaks)):
            # not below theta_min: there the long-wave modes (the symmetry modes' continuation) are split by the
            # orbit's error as the time shift's Jordan block is (longwave_limit)
            lo, hi = max(xs[i - 1], step), xs[min(i + 1, len(xs) - 1)]
            if hi > lo:
                golden_maximum(rho, lo, hi, resolution * (hi - lo))

    grid = list(np.linspace(0.0, math.pi, n_grid + 1))
    # the zones' decoupling is decided at the first twist after 0 (DeflatedSectors.scan): at pi, where a contact
    # across the cell's edge shows most (a small twist would take nearly decoupled zones for decoupled ones)
    rho(math.pi)
    # the long-wave twists below the grid, halved down to where the long-wave multipliers are resolved; the sample
    # below (the first unresolved) does not count
    step = longwave_limit(sector, grid[1])
    for x in [x for x in seen if 0.0 < x < step]:
        del seen[x]
    hints = [float(h) for h in hints if step <= h <= math.pi]
    for theta in grid + hints:
        rho(theta)
    refine_peaks(hints)
    certificate = None
    if certify and max(s.rho for s in seen.values()) - 1 <= floor:
        certificate = certify_twists(sector, [x for x in sorted(seen) if x >= step], floor,
                                     certification_budget(n_grid, len(orbit.x[:orbit.symmetry.M]))
                                     if budget is None else budget, longwave=grid[1])
        if certificate.status == "unstable":
            refine_peaks([certificate.theta])
            certificate = None
    if certificate is not None:
        step = certificate.theta_min                  # the long-wave twists that the certification closed
    xs = np.array(sorted(seen))
    ys = np.array([seen[x].rho for x in xs])
    k = int(np.argmax(np.where((xs == 0.0) | (xs >= step), ys, -np.inf)))
    every = list(seen.values())
    return TwistScan(thetas=xs, rho=ys, theta=float(xs[k]), rho_max=float(ys[k]), n_grid=n_grid, theta_min=step,
                     cluster=max((float(np.max(np.abs(s.cluster - 1))) for s in every if s.r), default=0.0),
                     eigenvector_residual=max(s.eigenvector_residual for s in every),
                     decoupled=any(s.decoupled for s in every), certificate=certificate, floor=floor)
