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

Window. (theta, lambda) and (theta + q, lambda - i) describe the same chain mode, and (-theta, conj lambda) its
conjugate: every mode of the infinite chain has a representative with theta in [0, pi] (counting the eigenvalues
of the -theta problem) and |Im lambda| <= 1/2, the least oscillatory w, i.e. the best resolved one.

The near-1 band. Each compression zone's translation mode W_0 = u' - p (zero in free flight, C^2) solves the
theta = 0 problem on its own, because no contact link joins two zones; its Bloch sums therefore give, at every
theta, the eigenvalue lambda_b = -i theta / q (mu = 1) with a Jordan partner: m translations per m wavelengths,
as if the wave were m compactons. The scheme splits that block at O(h) (the coefficients are not smooth), which
would read as a spurious |mu| - 1 = O(h); it is identified by its known location and excluded (:class:`SectorWindow`),
and reported separately.

Solver: SLEPc PEP (TOAR), shift-and-invert at a real target z0 = e^{sigma h} (never exactly on an eigenvalue: at
theta = 0, lambda = 0 is one), LU (MUMPS), options prefix ``cm_`` (-cm_pep_*, -cm_st_*, -cm_st_ksp_*, -cm_st_pc_*).
The matrices are AIJ with rows distributed over the communicator. PETSc is real here: for theta other than 0 and
pi the pencil is the real one of twice the size [[Re, -Im], [Im, Re]], whose spectrum is that of theta and -theta;
the eigenvector (x1, x2) tells which (x1 + i x2 lies in the theta problem).
"""
import math
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc

from .diagnostics import sup_norm
from .errors import ConvergenceError, ParameterError
from .stencil import INTEGER_SHIFT_TOLERANCE, full_period, shift_stencil, shifted

COMOVING_PREFIX = "cm_"
WINDOW_IM = 0.5            # |Im lambda| <= 1/2 covers every chain mode (module docstring)
TARGET_OFFSET = 0.0123     # added to every target, so that none falls on an exact eigenvalue (lambda = 0, theta = 0)
DEFAULT_BOX = (-0.3, 0.9)  # Re lambda searched: contains the exponents of the most unstable branch waves


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


def is_integer_shift(sigma):
    return abs(sigma - round(sigma)) <= INTEGER_SHIFT_TOLERANCE


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
        self.u_half = np.asarray(self.u_half, dtype=float)
        self.K = len(self.u_half) - 1
        self.h = math.pi / self.K
        self.sigma = self.q / self.h
        if not (0 < self.q <= math.pi * (1 + 1e-14)):
            raise ParameterError("q", self.q, "the wavenumber must lie in (0, pi]")
        if self.n_sub < 1:
            raise ParameterError("n_sub", self.n_sub, "the sub-pieces per cell must be an integer >= 1")
        law = self.model.law
        u = full_period(self.u_half)
        rp = shifted(u, self.sigma) - u
        self.a = cell_mean_stiffness(law, rp, self.n_sub)
        if is_integer_shift(self.sigma):
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
        if real_theta(theta):
            e = float(np.sign(e.real))
        Kt = (sp.diags(self.a + self.b) - e * (sp.diags(self.a) @ shift_csr(n, self.sigma))
              - np.conj(e) * (sp.diags(self.b) @ shift_csr(n, -self.sigma)))
        return [shift_csr(n, 1.0), ((self.h ** 2) * Kt - 2.0 * sp.identity(n)).tocsr(), shift_csr(n, -1.0)]

    def band_lambda(self, theta):
        """lambda_b = -i theta / q of the compacton band (mu = 1) in the theta problem."""
        return -1j * theta / self.q

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
        # on fine grids the interpolated profile can pass the round-off atol with its O(h^2) regridding error:
        # at least one Newton step (quadratic convergence takes that error to round-off)
        tws.snes.setForceIteration(True)
        tws.solve(problem, u)
        return grid.half_profile(u)
    finally:
        tws.destroy()
        problem.destroy()
        u.destroy()


def real_theta(theta):
    """theta = 0 or pi (mod 2 pi): the pencil is real."""
    return abs(math.sin(theta)) < 1e-14


def realified(A):
    """[[Re A, -Im A], [Im A, Re A]] (CSR): the real matrix of twice the size of a complex A."""
    A = sp.csr_matrix(A)
    Ar, Ai = sp.csr_matrix(A.real), sp.csr_matrix(A.imag)
    return sp.bmat([[Ar, -Ai], [Ai, Ar]], format="csr")


def aij(A, comm):
    """A distributed AIJ matrix holding the real CSR ``A``: each rank inserts its own rows (PETSc's default layout)."""
    A = sp.csr_matrix(A, dtype=float)
    A.sort_indices()
    n = A.shape[0]
    layout = PETSc.Vec().createMPI(n, comm=comm)
    r0, r1 = layout.getOwnershipRange()
    layout.destroy()
    local = A[r0:r1]
    M = PETSc.Mat().createAIJ(size=((r1 - r0, n), (r1 - r0, n)), comm=comm,
                              csr=(local.indptr.astype(PETSc.IntType), local.indices.astype(PETSc.IntType),
                                   local.data))
    M.assemble()
    return M


# --- the SLEPc solver --------------------------------------------------------------------------------------------
@dataclass
class PencilEigenpairs:
    """Converged eigenvalues of a real z-pencil nearest a real target (with the full eigenvectors when asked)."""

    z: np.ndarray
    vectors: list
    errors: np.ndarray
    iterations: int
    seconds: float


class ComovingPEP:
    """SLEPc PEP with shift-and-invert for the co-moving pencils (prefix ``cm_``): TOAR, ST sinvert, KSP preonly,
    LU by MUMPS, eigenvalues nearest the target in magnitude, tolerance 1e-13 (defaults; every knob reachable as
    -cm_pep_*, -cm_st_*). A PEP is configured from the options database once per solve (operator sizes change
    between grids); the constructor configures one on a small pencil, so that bad options fail before any work."""

    # MUMPS's workspace estimate can fall short when the target is close to an eigenvalue (INFOG(1) = -9): more
    # room (ICNTL(14), percent), inserted only for the solve and only where the user did not set it
    MUMPS_DEFAULTS = {"st_mat_mumps_icntl_14": "100"}

    def __init__(self, comm, prefix=COMOVING_PREFIX, nev=12, tol=1e-13):
        self.comm, self.prefix, self.tol = comm, prefix, tol
        self.default_nev = nev
        probe = self._create()
        self.nev = probe.getDimensions()[0]          # -cm_pep_nev overrides the starting nev
        probe.destroy()
        self.solves = 0

    def _create(self):
        from slepc4py import SLEPc
        pep = SLEPc.PEP().create(comm=self.comm)
        pep.setOptionsPrefix(self.prefix)
        pep.setType(SLEPc.PEP.Type.TOAR)
        pep.setProblemType(SLEPc.PEP.ProblemType.GENERAL)
        pep.setDimensions(nev=self.default_nev, ncv=max(2 * self.default_nev + 10, 40))
        pep.setTolerances(tol=self.tol, max_it=200)
        pep.setWhichEigenpairs(SLEPc.PEP.Which.TARGET_MAGNITUDE)
        st = pep.getST()
        st.setType(SLEPc.ST.Type.SINVERT)
        ksp = st.getKSP()
        ksp.setType(PETSc.KSP.Type.PREONLY)
        pc = ksp.getPC()
        pc.setType(PETSc.PC.Type.LU)
        pc.setFactorSolverType("mumps")
        pep.setFromOptions()
        return pep

    @PETSc.Log.EventDecorator("hz_comoving_pep")
    def solve(self, mats, target, nev, want_vectors=False):
        """Eigenpairs of the real pencil sum z^i mats[i] (scipy CSR) nearest the real ``target``; at least ``nev``
        must converge (ConvergenceError otherwise). Vectors, when asked, come complete on every rank."""
        from slepc4py import SLEPc
        t0 = time.perf_counter()
        As = [aij(A, self.comm) for A in mats]
        opts = PETSc.Options()
        inserted = [k for k in self.MUMPS_DEFAULTS if not opts.hasName(self.prefix + k)]
        for k in inserted:
            opts.setValue(self.prefix + k, self.MUMPS_DEFAULTS[k])
        pep = self._create()
        try:
            pep.setOperators(As)
            pep.setTarget(float(target))
            if nev > self.nev:
                pep.setDimensions(nev=nev, ncv=max(2 * nev + 10, 40))
            pep.solve()
            nconv = pep.getConverged()
            if nconv < min(nev, self.nev):
                raise ConvergenceError("co-moving PEP (prefix -%s)" % self.prefix,
                                       f"{nconv} of {nev} eigenpairs converged (reason {pep.getConvergedReason()})",
                                       target=target)
            vr, vi = As[0].createVecs()
            scatter, full = PETSc.Scatter.toAll(vr)
            z, vecs, errs = [], [], []
            for i in range(nconv):
                z.append(complex(pep.getEigenpair(i, vr, vi)))
                errs.append(pep.computeError(i, SLEPc.PEP.ErrorType.BACKWARD))
                if want_vectors:
                    parts = []
                    for v in (vr, vi):
                        scatter.scatter(v, full, PETSc.InsertMode.INSERT_VALUES, PETSc.ScatterMode.FORWARD)
                        parts.append(full.getArray(readonly=True).copy())
                    vecs.append(parts[0] + 1j * parts[1])
            its = pep.getIterationNumber()
            for v in (vr, vi, full):
                v.destroy()
            scatter.destroy()
        finally:
            pep.destroy()
            for A in As:
                A.destroy()
            for k in inserted:
                opts.delValue(self.prefix + k)
        self.solves += 1
        return PencilEigenpairs(np.array(z), vecs, np.array(errs), its, time.perf_counter() - t0)


def sector_side(vectors, n):
    """For eigenvectors (x1, x2) of a realified pencil: +1 when x1 + i x2 carries most of the norm (an eigenvector
    of the theta problem), -1 when x1 - i x2 does (the -theta problem)."""
    out = []
    for v in vectors:
        x1, x2 = v[:n], v[n:]
        p, m = np.linalg.norm(x1 + 1j * x2), np.linalg.norm(x1 - 1j * x2)
        out.append(1.0 if p >= m else -1.0)
    return np.array(out)


@dataclass
class SectorWindow:
    """The eigenvalues lambda with Re lambda in the box and |Im lambda| <= 1/2 at Bloch parameter theta (each with
    its side: +1 the theta problem, -1 the -theta problem; real theta: +1), which of them are the compacton band
    (``band``), the band's spread max |lambda - lambda_b| and the distance from lambda_b to the nearest other
    eigenvalue (``separation``), the radius around the target within which every eigenvalue was found, and the work."""

    theta: float
    K: int
    lam: np.ndarray
    side: np.ndarray
    band: np.ndarray
    band_spread: float
    separation: float
    radius: float
    nev: int
    seconds: float

    def dominant(self):
        """(lambda, theta of its problem) of the largest Re lambda outside the band, or (nan, theta)."""
        keep = ~self.band
        if not keep.any():
            return complex(math.nan), self.theta
        i = int(np.argmax(np.where(keep, self.lam.real, -np.inf)))
        return complex(self.lam[i]), float(self.side[i] * self.theta)


def band_members(lam, side, theta, q, spread_limit):
    """Mask of the compacton band: at theta = 0 the 4 eigenvalues nearest 0 (band pair and Galilean pair), else on
    each side s the 2 nearest lambda_b = -i s theta / q when that lies in the window. Returns (mask, spread,
    separation): members farther than ``spread_limit`` from lambda_b are not taken."""
    mask = np.zeros(len(lam), dtype=bool)
    spread, separation = 0.0, math.inf
    groups = [(0.0, np.ones(len(lam), dtype=bool), 4)] if abs(math.sin(theta / 2)) < 1e-14 else \
        [(s, side == s, 2) for s in ((1.0,) if real_theta(theta) else (1.0, -1.0))]
    for s, on_side, count in groups:
        lam_b = -1j * s * theta / q
        if abs(lam_b.imag) > WINDOW_IM:
            continue
        idx = np.nonzero(on_side)[0]
        order = idx[np.argsort(np.abs(lam[idx] - lam_b))]
        near = [i for i in order[:count] if abs(lam[i] - lam_b) <= spread_limit]
        mask[near] = True
        if near:
            spread = max(spread, float(np.max(np.abs(lam[near] - lam_b))))
        rest = [i for i in order if i not in near]
        if rest:
            separation = min(separation, float(abs(lam[rest[0]] - lam_b)))
    return mask, spread, separation


def sector_window(wave, theta, solver, box=DEFAULT_BOX, max_nev=192):
    """All eigenvalues of the theta problem (and of -theta) in the window, by shift-and-invert at the box centre;
    nev doubles until the converged eigenvalues cover the box. The band is identified within 0.1 of lambda_b (its
    discrete splitting is O(h); the other eigenvalues near it are the acoustic ones, lambda ~ -i c theta)."""
    if not box[0] < box[1]:
        raise ParameterError("box", box, "must be an interval (low, high) of Re lambda")
    centre = 0.5 * (box[0] + box[1]) + TARGET_OFFSET
    need = 1.05 * math.hypot(0.5 * (box[1] - box[0]) + TARGET_OFFSET, WINDOW_IM)
    real = real_theta(theta)
    mats = wave.pencil(theta)
    n = mats[0].shape[0]
    if real:
        mats = [sp.csr_matrix(A.real) if np.iscomplexobj(A.data) else A for A in mats]
    else:
        mats = [realified(A) for A in mats]
    nev, seconds = solver.nev * (1 if real else 2), 0.0
    while True:
        res = solver.solve(mats, math.exp(centre * wave.h), nev, want_vectors=not real)
        seconds += res.seconds
        lam = np.log(res.z.astype(complex)) / wave.h
        dist = np.sort(np.abs(lam - centre))
        radius = float(dist[min(nev, len(dist)) - 1]) if len(dist) else 0.0
        if radius >= need or nev >= max_nev:
            break
        nev *= 2
    side = np.ones(len(lam)) if real else sector_side(res.vectors, n)
    keep = (np.abs(lam.imag) <= WINDOW_IM) & (lam.real >= box[0]) & (lam.real <= box[1]) & \
           (np.abs(lam - centre) <= radius)
    lam, side = lam[keep], side[keep]
    band, spread, separation = band_members(lam, side, theta, wave.q, 0.1)
    return SectorWindow(theta, wave.K, lam, side, band, spread, separation, radius, nev, seconds)


def dense_pencil_eigenvalues(mats):
    """All eigenvalues of A0 + z A1 + z^2 A2 (A2 invertible) by the companion linearisation and LAPACK: the
    independent check of the SLEPc route on small grids."""
    A0, A1, A2 = [np.asarray(A.todense()) if sp.issparse(A) else np.asarray(A) for A in mats]
    n = A0.shape[0]
    inv = np.linalg.inv(A2)
    C = np.zeros((2 * n, 2 * n), dtype=np.result_type(A0, A1, complex))
    C[:n, n:] = np.eye(n)
    C[n:, :n] = -inv @ A0
    C[n:, n:] = -inv @ A1
    return np.linalg.eigvals(C)


@dataclass
class ThetaScan:
    """The worst non-band mode over a theta grid on one profile grid: gamma = q Re lambda / script-T, its theta,
    lambda and mu, the largest band spread (as |mu| - 1 = q spread, the O(h) artefact) and the work."""

    K: int
    thetas: np.ndarray
    growth: np.ndarray          # per theta: the largest non-band gamma
    lam: complex
    theta: float
    gamma: float
    band_mu: float
    min_separation: float
    solves: int
    seconds: float


def theta_scan(wave, thetas, solver, box=DEFAULT_BOX):
    """:func:`sector_window` at every theta of ``thetas`` (in [0, pi])."""
    growth, best, band_mu, sep, solves, secs = [], None, 0.0, math.inf, 0, 0.0
    for th in thetas:
        if not (-1e-14 <= th <= math.pi + 1e-14):
            raise ParameterError("theta", th, "the Bloch parameters must lie in [0, pi]")
        w = sector_window(wave, th, solver, box)
        lam, th_eff = w.dominant()
        g = float(wave.growth(lam)) if lam == lam else -math.inf
        growth.append(g)
        if best is None or g > best[0]:
            best = (g, lam, abs(th_eff))
        band_mu = max(band_mu, wave.q * w.band_spread)
        sep = min(sep, w.separation)
        secs += w.seconds
        solves += 1
    return ThetaScan(wave.K, np.asarray(thetas, dtype=float), np.array(growth), best[1], best[2], best[0], band_mu,
                     sep, solves, secs)


def tracked_exponent(wave, theta, guess, solver, nev=12):
    """The eigenvalue of the theta problem nearest ``guess`` (shift-and-invert at Re guess + TARGET_OFFSET; the
    nev nearest cover |Im lambda| <= 1.5, about two eigenvalues per unit of Im lambda): Richardson sequences."""
    if not np.isfinite(guess):
        raise ParameterError("guess", guess, "the eigenvalue to track must be a finite complex number")
    real = real_theta(theta)
    mats = wave.pencil(theta)
    n = mats[0].shape[0]
    mats = [sp.csr_matrix(A.real) if np.iscomplexobj(A.data) else A for A in mats] if real else \
        [realified(A) for A in mats]
    res = solver.solve(mats, math.exp((guess.real + TARGET_OFFSET) * wave.h), nev if real else 2 * nev,
                       want_vectors=not real)
    lam = np.log(res.z.astype(complex)) / wave.h
    if not real:
        side = sector_side(res.vectors, n)
        lam = np.where(side < 0, np.conj(lam), lam)          # the theta problem's representatives
    return complex(lam[int(np.argmin(np.abs(lam - guess)))])
