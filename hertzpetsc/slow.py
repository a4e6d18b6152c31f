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

import numpy as np
from petsc4py import PETSc

from .bloch import BlochSectors
from .errors import ParameterError
from .floquet import FLOQUET_PREFIX, FLOQUET_TOLERANCES, FloquetSolver, Spectrum


def cell_map(sectors, orbit, theta):
    """P_Theta = e^{-i j Theta} G_Theta^{m'} (2M x 2M, index 2n + c) of ``orbit`` (an N-bead wave), and its cell."""
    sym = orbit.symmetry
    G = sectors.monodromy(orbit.x[:sym.M], sym.delta(orbit.T), theta, sym.k)
    P = np.linalg.matrix_power(G, sym.m_cell)
    if theta != 0.0:
        P = np.exp(-1j * sym.j * theta) * P
    return P, sym


def zone_directions(model, x0, q):
    """Per zone k of the M-bead cell state ``x0`` (M, 2): the restriction to the zone's beads of the time-shift
    direction f = (xdot, xddot) and of the translation t = (1, 0), as (m', 2M) arrays f_k, t_k. Bead n belongs to
    zone floor(q n / 2 pi) (the wave's free flight is centred on q n = 0 mod 2 pi)."""
    M = len(x0)
    x, v = x0[:, 0], x0[:, 1]
    acc = (model.force(np.roll(x, -1) - x) - model.force(x - np.roll(x, 1))) / model.mass(np.arange(M))  # eq. nc
    zone = np.floor(q * np.arange(M) / (2 * math.pi) + 1e-12).astype(int)
    n_zones = int(zone.max()) + 1
    f, t = np.zeros((n_zones, 2 * M)), np.zeros((n_zones, 2 * M))
    for k in range(n_zones):
        on = np.nonzero(zone == k)[0]
        f[k, 2 * on], f[k, 2 * on + 1] = v[on], acc[on]
        t[k, 2 * on] = 1.0
    return f, t


def zone_modes(P, f, t):
    """The zone translation modes z_k = f_k - v t_k with v the free-flight velocity that makes them eigenvectors of
    P at 1 (least squares over all zones; the residual is then the orbit's and the flow's error): (Z (2M, m'), v,
    max relative residual ||(P - I) z_k|| / ||z_k||)."""
    A = (P - np.eye(len(P))) @ t.T
    B = (P - np.eye(len(P))) @ f.T
    AA = float(np.real(np.vdot(A.ravel(), A.ravel())))
    # one zone per cell at Theta = 0: t is the uniform translation, itself exact, and any v will do
    v = float(np.real(np.vdot(A.ravel(), B.ravel())) / AA) if AA > 1e-20 * max(1.0, np.linalg.norm(B) ** 2) else 0.0
    Z = (f - v * t).T
    res = np.linalg.norm((P - np.eye(len(P))) @ Z, axis=0) / np.linalg.norm(Z, axis=0)
    return Z, v, float(res.max())


@dataclass
class DeflatedSector:
    """One twist Theta of a wave's cell after deflation: the multipliers that are not symmetry multipliers
    (``values``), the deflated cluster (eigenvalues of U^H P U), the raw cluster (the 2r eigenvalues of P nearest
    1, what an undeflated spectrum shows), the residuals of the known eigenvectors, of their partners and of the
    invariance of span U, the free-flight velocity and the size r of the known eigenspace."""

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

    @property
    def rho(self):
        """The largest |mu| outside the symmetry cluster."""
        return float(np.max(np.abs(self.values))) if len(self.values) else 1.0


def deflate(P, known, partners_of=None, extra=()):
    """Deflate the known eigenvectors ``known`` (columns, eigenvalue 1 of P) and their Jordan partners.

    ``partners_of``: columns whose partners are computed (minimum-norm least squares of (P - I) w = z; default all
    of ``known``); ``extra``: further (eigenvector, partner) columns known in closed form. Returns (values outside,
    cluster eigenvalues, partner residual, invariance residual, r)."""
    n = len(P)
    known = np.asarray(known, dtype=complex)
    Zs = known if partners_of is None else np.asarray(partners_of, dtype=complex)
    W, *_ = np.linalg.lstsq(P - np.eye(n), Zs, rcond=1e-10)
    partner_res = float(np.max(np.linalg.norm((P - np.eye(n)) @ W - Zs, axis=0) / np.linalg.norm(Zs, axis=0)))
    cols = [known, W] + [np.asarray(e, dtype=complex).reshape(n, -1) for e in extra]
    B = np.concatenate(cols, axis=1)
    Q, R = np.linalg.qr(B, mode="complete")
    d = np.abs(np.diag(R))
    r = int(np.sum(d > 1e-10 * d.max()))
    if r != B.shape[1]:
        raise ParameterError("known eigenvectors", B.shape[1], f"must be independent (rank {r}); the orbit is not "
                             "a travelling wave of the chain or its zones touch")
    U, Uperp = Q[:, :r], Q[:, r:]
    A11 = U.conj().T @ P @ U
    invariance = float(np.linalg.norm(P @ U - U @ A11) / np.linalg.norm(P))
    values = np.linalg.eigvals(Uperp.conj().T @ P @ Uperp)
    return values, np.linalg.eigvals(A11), partner_res, invariance, r


class DeflatedSectors(FloquetSolver):
    """Deflated sector spectra of refined waves on their cells for any twist (the flow ``floquet_``, as the Bloch
    routes; build once, reuse for every wave). :meth:`spectrum` gathers the sectors at the cell twists ``twists``
    (in [0, pi]): the multipliers of each and its deflated cluster, which are the known (trivial) ones; the
    :class:`DeflatedSector` of each twist is in ``work["sectors"]``."""

    def __init__(self, model, comm, tolerances=FLOQUET_TOLERANCES, prefix=FLOQUET_PREFIX, twists=(0.0,)):
        self.model, self.twists = model, [float(t) for t in twists]
        self.sectors = BlochSectors(model, comm, tolerances, prefix)
        self.sectors.configure()

    @PETSc.Log.EventDecorator("hz_deflated_sector")
    def sector(self, orbit, theta):
        """The :class:`DeflatedSector` of ``orbit`` (a refined wave on N beads) at twist ``theta`` in [0, pi] per
        cell of M = N / gcd(m, N) beads."""
        if not (-1e-14 <= theta <= math.pi + 1e-14):
            raise ParameterError("theta", theta, "the cell's twist must lie in [0, pi]")
        t0 = time.perf_counter()
        P, sym = cell_map(self.sectors, orbit, theta)
        x0 = orbit.x[:sym.M]
        f, t = zone_directions(self.model, x0, orbit.q)
        Z, v, eig_res = zone_modes(P, f, t)
        extra = ()
        known = Z
        if abs(theta) < 1e-14:                 # uniform translation and the Galilean boost (0, 1) / script-T
            M = sym.M
            trans, boost = np.tile([1.0, 0.0], M), np.tile([0.0, 1.0], M) / orbit.T
            known = np.concatenate([Z, trans[:, None]], axis=1)
            eig_res = max(eig_res, float(np.linalg.norm((P - np.eye(2 * M)) @ trans) / np.linalg.norm(trans)))
            extra = (boost,)
        values, cluster, partner_res, invariance, r = deflate(P, known, Z, extra)
        lam = np.linalg.eigvals(P)
        raw = lam[np.argsort(np.abs(lam - 1.0))[:r]]
        return DeflatedSector(theta, sym.M, r, values, cluster, raw, lam, eig_res, partner_res, invariance, v,
                              time.perf_counter() - t0)

    def _spectrum(self, orbit, tol_rho, nev):
        sectors = [self.sector(orbit, theta) for theta in self.twists]
        values = np.concatenate([np.concatenate([s.values, s.cluster]) for s in sectors])
        known = np.concatenate([np.arange(len(s.values) + len(s.cluster)) >= len(s.values) for s in sectors])
        return Spectrum(values, True, tol_rho, known=known, work=dict(sectors=sectors))

    def destroy(self):
        self.sectors.destroy()
