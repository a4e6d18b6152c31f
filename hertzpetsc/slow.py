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
    acc = (model.force(np.roll(x, -1) - x) - model.force(x - np.roll(x, 1))) / model.mass(np.arange(M))  # eq. nc
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
    return values, cluster, partner_res, invariance, r, None if Y is None else Uperp @ Y


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

    def _deflated(self, orbit, P, theta, decoupled=None, raw=True):
        t0 = time.perf_counter()
        known, partners, extra, nearest, eig_res, v, decoupled = known_vectors(self.model, orbit, P, theta, decoupled)
        values, cluster, partner_res, invariance, r, V = deflate(P, known, partners, extra, self.krein is not None,
                                                                 nearest)
        signatures = None if self.krein is None else \
            krein_signatures(values, V, symplectic_form(self.model, len(P) // 2), self.krein)
        if r and raw:
            lam = np.linalg.eigvals(P)
            nearest_one = lam[np.argsort(np.abs(lam - 1.0))[:r]]
        elif r:
            lam = nearest_one = None
        else:
            lam, nearest_one = values, np.zeros(0, dtype=complex)
        return DeflatedSector(theta, len(P) // 2, r, values, cluster, nearest_one, lam, eig_res, partner_res,
                              invariance, v, time.perf_counter() - t0, decoupled, signatures)

    @PETSc.Log.EventDecorator("hz_deflated_sector")
    def sector(self, orbit, theta):
        """The :class:`DeflatedSector` of ``orbit`` (a wave on N beads) at twist ``theta`` in [0, pi] per cell of
        M = N / gcd(m, N) beads (one twisted run)."""
        return self.scan(orbit, [theta], propagate=False)[1][0]

    @PETSc.Log.EventDecorator("hz_deflated_scan")
    def scan(self, orbit, thetas, propagate=None, raw=True):
        """A function theta -> :class:`DeflatedSector` of ``orbit`` (every twist from the same cell maps: one
        propagator run when the response stays within a cell, :meth:`~hertzpetsc.bloch.BlochSectors.sector_maps`;
        ``propagate`` None: when ``thetas`` holds two complex twists or more; ``raw``: also P's own eigenvalues,
        the raw cluster), the zones' decoupling decided once, at the first informative twist of ``thetas``
        (Theta = 0 if the cell holds several zones); and the sectors at ``thetas``."""
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
            s = self._deflated(orbit, P, theta, state["decoupled"], raw)
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


@dataclass
class TwistScan:
    """The infinite chain's multipliers around one wave, over the Bloch parameters Theta in [0, pi] of its cell:
    the grid of ``n_grid`` + 1 twists, the hints, the bisections of Krein crossings and the refinements around the
    largest local maxima of rho (``thetas``, ``rho`` sorted by Theta); the worst twist and its rho, the crossings of
    multipliers of opposite Krein signatures seen between two stable grid twists (``crossings``) and those whose
    bubble of instability was found (``bubbles``), the deflated cluster's largest |mu - 1| over the scan, whether
    the zones were decoupled."""

    thetas: np.ndarray
    rho: np.ndarray
    theta: float
    rho_max: float
    n_grid: int
    cluster: float
    eigenvector_residual: float
    decoupled: bool
    crossings: int = 0
    bubbles: int = 0


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


@PETSc.Log.EventDecorator("hz_twist_scan")
def twist_scan(sectors, orbit, n_grid, hints=(), refine=3, floor=0.0, resolution=1e-3):
    """rho over the cell twists of ``orbit`` (a :class:`~hertzpetsc.waves.Orbit` on its cell; the infinite chain's
    Bloch parameters Theta in [0, pi]): the grid Theta_j = j pi / n_grid, the ``hints`` (twists where an unstable
    mode was seen before: a narrow band near its onset is followed there), then a golden-section refinement of rho
    around the ``refine`` largest local maxima with rho - 1 > ``floor`` and around every hint, between its
    neighbours, to ``resolution`` of the grid step. ``sectors``: a :class:`DeflatedSectors` (symmetry multipliers
    deflated at Theta = 0, and at every Theta when the zones are decoupled).

    Twists in (0, pi / n_grid) are not searched: as Theta -> 0 the four long-wave multipliers tend to the deflated
    symmetry cluster, and below a few times its numerical splitting (sqrt of the orbit's error) their crossings are
    artefacts; a long-wave (modulational) instability shows at the first grid twist when its band reaches it."""
    at, first = sectors.scan(orbit, [0.0], propagate=True, raw=False)
    seen = {0.0: first[0]}

    def sector(theta):
        theta = min(max(float(theta), 0.0), math.pi)
        if theta not in seen:
            seen[theta] = at(theta)
        return seen[theta]

    def rho(theta):
        return sector(theta).rho

    step = math.pi / n_grid
    hints = [float(h) for h in hints if step <= h <= math.pi]
    grid = list(np.linspace(0.0, math.pi, n_grid + 1))
    for theta in grid + hints:
        rho(theta)
    crossings = bubbles = 0
    if sectors.krein is not None:
        # between stable grid twists (from the first: below it the long-wave modes), a change of the Krein pattern
        # is a crossing of opposite signatures: its bubble is searched by bisection
        for t1, t2 in zip(grid[1:-1], grid[2:]):
            s1, s2 = sector(t1), sector(t2)
            if s1.rho - 1 > floor or s2.rho - 1 > floor or s1.pattern() == s2.pattern():
                continue
            crossings += 1
            found = crossing_search(sector, lambda s: s.rho - 1 > floor, lambda s: s.pattern(), t1, t2,
                                    s1.pattern(), max(0.1 * floor, 1e-12))
            if found is not None:
                bubbles += 1
                hints.append(found[0])
    xs = sorted(seen)
    ys = [seen[x].rho for x in xs]
    peaks = [i for i in range(1, len(xs)) if ys[i] - 1 > floor and ys[i] >= ys[i - 1]
             and (i == len(xs) - 1 or ys[i] >= ys[i + 1])]
    peaks = sorted(peaks, key=lambda i: -ys[i])[:refine] + [xs.index(h) for h in hints]
    for i in sorted(set(peaks)):
        # not below the first grid twist: there the long-wave modes (the symmetry modes' continuation) are split
        # by the orbit's error as the time shift's Jordan block is (module docstring)
        lo, hi = max(xs[i - 1], step), xs[min(i + 1, len(xs) - 1)]
        if hi > lo:
            golden_maximum(rho, lo, hi, resolution * step)
    xs = np.array(sorted(seen))
    ys = np.array([seen[x].rho for x in xs])
    k = int(np.argmax(ys))
    every = list(seen.values())
    return TwistScan(thetas=xs, rho=ys, theta=float(xs[k]), rho_max=float(ys[k]), n_grid=n_grid,
                     cluster=max((float(np.max(np.abs(s.cluster - 1))) for s in every if s.r), default=0.0),
                     eigenvector_residual=max(s.eigenvector_residual for s in every),
                     decoupled=any(s.decoupled for s in every), crossings=crossings, bubbles=bubbles)
