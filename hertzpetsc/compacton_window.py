"""Isolated compactons as fixed points of a window map that travels with them, and the map's point spectrum.

Paper: section 3.3 (eqs. extens, twlin, compacton, defvit) and the Discussion's question on the spectral
stability of isolated compactons. We fix the velocity to c = 1 bead per unit time (a = q^(2/(alpha-1)), so
script-T = 1; any other c follows by scaling). Ahead of the compacton the beads rest on the gap lattice
x_n = Delta n, Delta = a p q (eq. defvit); behind it they rest on x_n = Delta n + D, D = 2 pi a p. In the
gap-lattice coordinates y_n = x_n - Delta n a bond is r_n = Delta + y_{n+1} - y_n (:class:`WindowChain`).

A window of M beads (j = 0 the rearmost, free ends) and the one-bead shift define

    G(Y)_j = Phi_1(Y)_{j+1}  (j < M - 1),   G(Y)_{M-1} = (0, 0)   (the bead entering at the front is at rest),

and an exact compacton of gap Delta is a fixed point of G, provided the window holds every bond that closes
during a period plus a resting bead on each side (the free ends then never carry a force). The fixed points form
a curve (the sub-bead phase), so :class:`CompactonRefiner` adds a phase condition; q is imposed through the
paper's D / Delta = 2 pi / q, i.e. q y_0 = 2 pi Delta, with Delta an unknown (Delta = 0: the solitary wave,
eq. adr, with the q condition dropped).

Spectrum. V''(r) vanishes exactly for r >= 0, so a bead whose bonds stay open during the period is in exact
free flight; ordering the window as (front buffer, core, rear buffer), D_Y G is exactly block lower-triangular
with nilpotent transport blocks (a truncated shift composed with free flight), hence
spec(D_Y G) = {0} U spec(core block), independent of the buffers. On the infinite chain, in the space weighted
by exp(eta n) (heavier ahead), the essential spectrum is the disk |mu| <= exp(-eta) and the rest is spec(core).
Krylov-Schur (:class:`WindowStability`, EPS prefix ``cstab_``) is run on the weighted operator
W D_Y G W^-1, W = diag(exp(eta (j - j_ref))), whose transport part has norm exp(-eta): without the weight the
nilpotent blocks' pseudospectrum fills a disk of radius ~ tol^(1/L) and SLEPc accepts spurious multipliers.
The multiplier 1 is a Jordan block (translation v1 = the vector field; speed direction v2, (J - 1) v2 = v1):
only the pair's mean is accurate, its split is ~ sqrt(integration error).

Flows use the TS prefix ``cwin_`` (``-cwin_ts_*``). States are (M, 2) arrays (y_j, ydot_j), flattened
bead-major (index 2 j + component) for matrices.
"""
import math
import time
from dataclasses import dataclass, field

import numpy as np
from petsc4py import PETSc

from .chain import Chain, ChainIntegrator, IntegrationTolerances
from .errors import ConvergenceError, ParameterError
from .model import ChainSpec
from .tangent import split_tangents, stack_tangents

WINDOW_PREFIX = "cwin_"
STABILITY_PREFIX = "cstab_"
# the flows whose fixed points and spectra are measured (as the package's MEASURE_TOLERANCES)
WINDOW_TOLERANCES = IntegrationTolerances(rtol=1e-14, atol=1e-16)
DEFAULT_ETA = 2.5
DEFAULT_REAR = 6


class WindowChain(Chain):
    """The chain (eq. nc) in gap-lattice coordinates: bead n's position is y_n, its bonds r = gap + y_{n+1} - y_n.

    Implemented by adding gap * (local bead index) to the ghosted positions, so every consumer of positions in
    :class:`~hertzpetsc.chain.Chain` (right-hand side, tangents, Jacobian, energy) sees the lab-frame bonds; the
    offset is relative to the first owned bead, so its round-off is eps * gap * (beads per rank). ``gap`` is an
    attribute that may change between integrations.
    """

    def __init__(self, spec, comm, gap=0.0, n_tangent=0):
        if spec.boundary != "free":
            raise ParameterError("boundary", spec.boundary, "the compacton window is a free-ended chain")
        super().__init__(spec, comm, n_tangent)
        self.gap = float(gap)


def shift_window(Z):
    """The window's shift on (M, ...) arrays: bead j <- bead j + 1, the front bead zero (at rest on the lattice)."""
    out = np.zeros_like(Z)
    out[:-1] = Z[1:]
    return out


class WindowFlow:
    """Phi_1 of the M-bead window chain with k tangent columns in one TS (prefix ``cwin_``), for k = 0, 1, 2M + 1
    (built on first use). Arrays in and out are given on every rank."""

    def __init__(self, model, M, comm, tolerances=WINDOW_TOLERANCES, prefix=WINDOW_PREFIX, rk_type="8vr"):
        if not (isinstance(M, (int, np.integer)) and M >= 4):
            raise ParameterError("M", M, "the window needs at least 4 beads")
        self.spec = ChainSpec(model, int(M), "free")
        self.model, self.M, self.comm = model, int(M), comm
        self.tolerances, self.prefix, self.rk_type = tolerances, prefix, rk_type
        self._flows = {}
        self.integrations = 0
        self._get(0)                   # reads and checks the -cwin_ts_* options now

    def _get(self, k):
        if k not in self._flows:
            chain = WindowChain(self.spec, self.comm, 0.0, n_tangent=k)
            integ = ChainIntegrator(chain, self.tolerances, self.prefix, self.rk_type)
            self._flows[k] = (chain, integ, chain.create_state())
        return self._flows[k]

    def run(self, Y, gap, tangents=None, T=1.0, monitor=None):
        """(Y(T) (M, 2), R(T) tangents (M, 2, k) or None) from Y (M, 2) and tangents (M, 2, k)."""
        M = self.M
        Y = np.asarray(Y, float).reshape(M, 2)
        k = 0 if tangents is None else tangents.shape[2]
        chain, integ, Z = self._get(k)
        chain.gap = float(gap)
        chain.set_from_array(Z, Y if k == 0 else stack_tangents(Y, tangents))
        if monitor is not None:
            integ.ts.setMonitor(lambda ts, i, t, X: monitor(chain, X))
        try:
            integ.integrate(Z, 0.0, T, dt=integ.initial_step)
        finally:
            if monitor is not None:
                integ.ts.cancelMonitor()
        self.integrations += 1
        out = chain.gather(Z)
        return (out, None) if k == 0 else split_tangents(out, k)

    def destroy(self):
        for chain, integ, Z in self._flows.values():
            Z.destroy()
            integ.destroy()
            chain.destroy()
        self._flows = {}


class CompactonWindow:
    """The window map G of an M-bead window (module docstring) and its derivatives."""

    def __init__(self, model, M, comm, tolerances=WINDOW_TOLERANCES, prefix=WINDOW_PREFIX, rk_type="8vr"):
        self.model, self.M, self.comm = model, int(M), comm
        self.flow = WindowFlow(model, M, comm, tolerances, prefix, rk_type)

    @property
    def dim(self):
        return 2 * self.M

    def map(self, Y, gap):
        """G(Y), (M, 2)."""
        YT, _ = self.flow.run(Y, gap)
        return shift_window(YT)

    def residual(self, Y, gap):
        """max |G(Y) - Y| (absolute: positions are O(D), velocities O(v_peak))."""
        return float(np.max(np.abs(self.map(Y, gap) - np.asarray(Y).reshape(self.M, 2))))

    def jacobian(self, Y, gap):
        """(G(Y), J = D_Y G (2M x 2M, bead-major), dG/dDelta (2M,)) from one integration with 2M + 1 tangents.

        The gap column starts as dy_j = j (the lattice's own displacement: it changes every bond by 1) and the
        lattice part is removed after the flow: d y_{j+1}(T) / dDelta = R(T) e - (j + 1)."""
        M, n = self.M, self.dim
        T0 = np.zeros((M, 2, n + 1))
        T0.reshape(n, n + 1)[:, :n] = np.eye(n)
        T0[:, 0, n] = np.arange(M)
        YT, W = self.flow.run(Y, gap, T0)
        W[:, 0, n] -= np.arange(M)
        G, GW = shift_window(YT), shift_window(W).reshape(n, n + 1)
        return G, GW[:, :n].copy(), GW[:, n].copy()

    def apply(self, Y, gap, x):
        """J x by one tangent integration (the matrix-free product); x and the result are (2M,)."""
        _, W = self.flow.run(Y, gap, np.asarray(x, float).reshape(self.M, 2, 1))
        return shift_window(W[:, :, 0]).ravel()

    def vector_field(self, Y, gap):
        """dY/dt at Y (the translation mode v1 of a compacton), (2M,)."""
        Y = np.asarray(Y, float).reshape(self.M, 2)
        f = self.model.force(gap + np.diff(Y[:, 0]))
        acc = np.zeros(self.M)
        acc[:-1] += f
        acc[1:] -= f
        if not self.model.uniform_masses:
            acc /= self.model.mass(np.arange(self.M))
        return np.stack([Y[:, 1], acc], axis=1).ravel()

    def closed_bonds(self, Y, gap, relative=1e-13):
        """Bonds j (beads j, j+1) closed at t = 0 or at a time step of the period: r_j < -relative x the largest
        compression (a compacton's other bonds are exactly open; the solitary wave's doubly exponential tails
        are counted only above that level)."""
        r_min = np.full(self.M - 1, np.inf)

        def watch(chain, X):
            y = chain.gather(X)[:, 0]
            np.minimum(r_min, gap + np.diff(y), out=r_min)
        Y = np.asarray(Y, float).reshape(self.M, 2)
        watch_start = gap + np.diff(Y[:, 0])
        np.minimum(r_min, watch_start, out=r_min)
        self.flow.run(Y, gap, monitor=watch)
        deepest = max(0.0, -float(r_min.min()))
        return np.nonzero(r_min < -relative * deepest)[0]

    def core(self, Y, gap):
        """Bead indices of the core: beads of the closed bonds, and the bead that enters them by the shift."""
        b = self.closed_bonds(Y, gap)
        if not len(b):
            raise ParameterError("Y", "no closed bond", "the window holds no compression zone")
        return np.arange(max(b.min() - 1, 0), min(b.max() + 1, self.M - 1) + 1)

    def destroy(self):
        self.flow.destroy()


def bead_indices(beads):
    """Bead-major state indices (2 j, 2 j + 1) of the given beads."""
    beads = np.asarray(beads)
    return np.stack([2 * beads, 2 * beads + 1], axis=1).ravel()


# --- initial guesses and window sizes -------------------------------------------------------------------------------
def window_length(width, rear=DEFAULT_REAR, front=4):
    """Beads of a window for a compacton N(q) = ``width`` beads wide: ``rear`` at rest behind, the compression
    zone plus the bead it advances by, and ``front`` ahead."""
    return rear + int(math.ceil(width)) + 2 + front


def check_window(M, width, rear, q=None):
    """ParameterError unless the window leaves at least 2 resting beads behind and 3 ahead of the zone."""
    if rear < 2:
        raise ParameterError("-rear", rear, "at least 2 resting beads behind the compression zone")
    need = window_length(width, rear, 3)
    if M < need:
        at = f" at q = {q:.6g}" if q is not None else ""
        raise ParameterError("-M", M, f"the window is too short for the compression zone{at}: it is "
                                      f"{width:.2f} beads wide, so M >= {need} with {rear} beads behind")


def guess_from_branch(point, M, rear=DEFAULT_REAR, q_k=None):
    """The unrefined compacton of a branch point at c = 1 in the window (eqs. extens, twlin, compacton, defvit),
    from :func:`hertzpetsc.compacton.compacton_train`: (Y (M, 2) in gap-lattice coordinates, y = 0 ahead, gap).
    ParameterError when q > q_k (F(q) < 1) or the window is too short."""
    from .compacton import CompactonScales, chain_state, compacton_train, placement
    train = compacton_train(point, (), q_k)
    check_window(M, train.width, rear, point.q)
    sc = CompactonScales.for_velocity(train, 1.0)
    X = chain_state(train, sc, M, placement(train, rear))
    y = X[:, 0] - sc.gap * np.arange(M)
    return np.stack([y - y[-1], X[:, 1]], axis=1), sc.gap


def embed(Y, M_new, add_rear):
    """The window state in a longer window: ``add_rear`` resting beads behind (at y = y_0), the rest ahead (y = 0)."""
    Y = np.asarray(Y, float)
    add_front = M_new - len(Y) - add_rear
    if add_rear < 0 or add_front < 0:
        raise ParameterError("M", M_new, f"the new window must hold the old one ({len(Y)} beads)")
    rear = np.tile([Y[0, 0], 0.0], (add_rear, 1))
    return np.concatenate([rear, Y, np.zeros((add_front, 2))])


# --- refinement -------------------------------------------------------------------------------------------------
@dataclass
class ExactCompacton:
    """A refined compacton: window state Y (M, 2), gap Delta, q (0: the solitary wave), residual max|G(Y) - Y|."""

    q: float
    gap: float
    Y: np.ndarray
    residual: float
    iterations: int
    history: list = field(default_factory=list)
    seconds: float = 0.0

    @property
    def M(self):
        return len(self.Y)

    @property
    def D(self):
        """The displacement a passing compacton gives each bead (y_0, the rear beads' position)."""
        return float(self.Y[0, 0])

    @property
    def v_peak(self):
        return float(np.max(np.abs(self.Y[:, 1])))


class CompactonRefiner:
    """Gauss-Newton on R(Y, Delta) = [G(Y) - Y; psi . (Y - Y_ref); q y_0 - 2 pi Delta] (2M + 2 equations, 2M + 1
    unknowns; consistent because of the Jordan block at 1), least squares by LAPACK on rank 0 and broadcast.
    psi is the vector field at the start (the translation direction). ``q = 0`` or ``fix_gap``: Delta fixed."""

    def __init__(self, window, tol=1e-13, max_iterations=20, residual_tol=1e-10):
        self.window, self.tol, self.max_iterations, self.residual_tol = window, tol, max_iterations, residual_tol
        mpi = window.comm.tompi4py()
        self._bcast = (lambda x: x) if mpi.Get_size() == 1 else (lambda x: mpi.bcast(x, root=0))
        self._rank0 = mpi.Get_rank() == 0

    def refine(self, Y0, gap0, q, fix_gap=False):
        w, M, n = self.window, self.window.M, self.window.dim
        fix_gap = fix_gap or q == 0
        t0 = time.perf_counter()
        Y, gap = np.array(Y0, float).reshape(M, 2), float(gap0)
        Yref = Y.ravel().copy()
        psi = w.vector_field(Y, gap)
        psi /= np.linalg.norm(psi)
        history, best = [], None
        for it in range(self.max_iterations + 1):
            G, J, Jg = w.jacobian(Y, gap)
            F = (G - Y).ravel()
            cond = [psi @ (Y.ravel() - Yref)] + ([] if fix_gap else [q * Y[0, 0] - 2 * math.pi * gap])
            res = float(np.max(np.abs(F)))
            total = max(res, float(np.max(np.abs(cond))))
            history.append(dict(residual=res, conditions=float(np.max(np.abs(cond))), gap=gap))
            if best is None or total < best[0]:
                best = (total, Y.copy(), gap, res, it)
            scale = float(np.max(np.abs(Y)))
            if total < self.tol * scale or it == self.max_iterations:
                break
            if it >= 3 and total > 0.5 * max(history[-2]["residual"], history[-2]["conditions"]):
                break                                   # stagnation at the flow's error
            A = np.zeros((n + len(cond), n + (0 if fix_gap else 1)))
            A[:n, :n] = J - np.eye(n)
            A[n, :n] = psi
            if not fix_gap:
                A[:n, n] = Jg
                A[n + 1, 0] = q
                A[n + 1, n] = -2 * math.pi
            step = np.linalg.lstsq(A, -np.concatenate([F, cond]), rcond=None)[0] if self._rank0 else None
            step = self._bcast(step)
            Y = Y + step[:n].reshape(M, 2)
            if not fix_gap:
                gap += float(step[n])
        _, Y, gap, res, it = best
        if not res <= self.residual_tol:
            raise ConvergenceError("compacton Gauss-Newton (window map)", f"residual {res:.2e}", q=float(q))
        return ExactCompacton(q=float(q), gap=gap, Y=Y, residual=res, iterations=it, history=history,
                              seconds=time.perf_counter() - t0)

    def continue_to(self, previous, q):
        """Refine at q from a secant prediction on (Y, Delta) through the last two ExactCompactons (or one)."""
        if len(previous) >= 2:
            a, b = previous[-2], previous[-1]
            s = (q - b.q) / (b.q - a.q)
            Y, gap = b.Y + s * (b.Y - a.Y), b.gap + s * (b.gap - a.gap)
        else:
            Y, gap = previous[-1].Y, previous[-1].gap
        return self.refine(Y, 0.0 if q == 0 else gap, q)


# --- spectrum ---------------------------------------------------------------------------------------------------
def sorted_eig(J):
    """Eigenvalues (LAPACK dgeev) and right eigenvectors, by decreasing modulus."""
    lam, V = np.linalg.eig(J)
    order = np.argsort(-np.abs(lam), kind="stable")
    return lam[order], V[:, order]


def split_jordan_pair(lam):
    """(mean, split, the other multipliers): the two multipliers nearest 1 are the Jordan pair."""
    lam = np.asarray(lam)
    near = np.argsort(np.abs(lam - 1.0), kind="stable")[:2]
    pair = lam[near]
    rest = np.delete(lam, near)
    return complex(pair.mean()), float(abs(pair[0] - pair[1])), rest[np.argsort(-np.abs(rest), kind="stable")]


@dataclass
class JordanCheck:
    """The Jordan block at 1: |J v1 - v1| / |v1|, |(J - 1) v2 - v1| / |v1|, the right vectors v1, v2 and the left
    vectors u1, u2 with u_i . v_j = delta_ij (so delta = (u1.delta) v1 + (u2.delta) v2 + a remainder in the other
    modes' span)."""

    translation: float
    generalized: float
    v1: np.ndarray
    v2: np.ndarray
    u1: np.ndarray
    u2: np.ndarray


def jordan_check(window, J, Y, gap):
    n = J.shape[0]
    A = J - np.eye(n)
    v1 = window.vector_field(Y, gap)
    v2 = np.linalg.lstsq(A, v1, rcond=None)[0]
    v2 -= (v2 @ v1) / (v1 @ v1) * v1
    nv1 = np.linalg.norm(v1)
    # left vectors: u2 spans the left kernel of A; u1 solves A^T u1 = u2 (up to the left kernel)
    u2 = np.linalg.svd(A.T)[2][-1]
    u2 = u2 / (u2 @ v2)
    u1 = np.linalg.lstsq(A.T, u2, rcond=None)[0]
    u1 -= (u1 @ v2) * u2
    return JordanCheck(float(np.linalg.norm(J @ v1 - v1) / nv1), float(np.linalg.norm(A @ v2 - v1) / nv1),
                       v1, v2, u1, u2)


def exponential_weight(M, eta, j_ref):
    """Diagonal of W = diag(exp(eta (j - j_ref))) on the bead-major state (heavier ahead)."""
    w = np.exp(eta * (np.arange(M) - j_ref))
    return np.repeat(w, 2)


class WeightedWindowOperator:
    """W D_Y G W^-1 as a ``Mat.createPython`` context: one tangent integration per product."""

    def __init__(self, window, Y, gap, weight):
        self.window, self.Y, self.gap, self.w = window, np.asarray(Y, float), float(gap), np.asarray(weight)
        self.products = 0
        self._gather = None

    def mult(self, mat, x, y):
        if self._gather is None:
            self._gather, self._full = PETSc.Scatter.toAll(x)
        self._gather.scatter(x, self._full, PETSc.InsertMode.INSERT_VALUES, PETSc.ScatterMode.FORWARD)
        xs = self._full.getArray(readonly=True)
        out = self.w * self.window.apply(self.Y, self.gap, xs / self.w)
        lo, hi = y.getOwnershipRange()
        y.getArray()[:] = out[lo:hi]
        self.products += 1

    def destroy(self, mat=None):
        if self._gather is not None:
            self._gather.destroy()
            self._full.destroy()
            self._gather = None


@dataclass
class DominantMultipliers:
    values: np.ndarray
    errors: np.ndarray
    products: int
    iterations: int
    seconds: float
    eta: float


class WindowStability:
    """Dominant multipliers of the window map by SLEPc Krylov-Schur (largest magnitude) on the weighted shell,
    EPS prefix ``cstab_`` (``-cstab_eps_*``); ``nev`` multipliers are asked for (they must lie above exp(-eta) to
    be meaningful: below, the transport part's pseudospectrum)."""

    def __init__(self, window, nev=3, eta=DEFAULT_ETA, tol=1e-12, prefix=STABILITY_PREFIX):
        from slepc4py import SLEPc
        if not (isinstance(nev, (int, np.integer)) and 1 <= nev <= window.dim):
            raise ParameterError("-nev", nev, f"the window map has dimension 2M = {window.dim}: 1 <= nev <= "
                                              f"{window.dim}")
        if not (math.isfinite(eta) and 0 <= eta <= 700.0 / max(window.M, 1)):
            raise ParameterError("-eta", eta, f"the weight exp(eta M) must stay finite: 0 <= eta <= "
                                              f"{700.0 / window.M:.3g} for M = {window.M}")
        self.window, self.nev, self.eta = window, int(nev), float(eta)
        eps = SLEPc.EPS().create(comm=window.comm)
        eps.setOptionsPrefix(prefix)
        eps.setProblemType(SLEPc.EPS.ProblemType.NHEP)
        eps.setType(SLEPc.EPS.Type.KRYLOVSCHUR)
        eps.setWhichEigenpairs(SLEPc.EPS.Which.LARGEST_MAGNITUDE)
        eps.setDimensions(nev=self.nev, ncv=min(window.dim, max(2 * self.nev + 1, self.nev + 15)))
        eps.setTolerances(tol=tol, max_it=500)
        eps.setFromOptions()
        self.eps = eps

    def solve(self, Y, gap, j_ref):
        """The converged multipliers (at least nev, by decreasing modulus) and their residual errors."""
        w = self.window
        ctx = WeightedWindowOperator(w, Y, gap, exponential_weight(w.M, self.eta, j_ref))
        A = PETSc.Mat().createPython([w.dim, w.dim], ctx, comm=w.comm)
        A.setUp()
        t0 = time.perf_counter()
        try:
            self.eps.setOperators(A)
            self.eps.solve()
            nconv = self.eps.getConverged()
            if nconv < self.eps.getDimensions()[0]:
                raise ConvergenceError("window EPS (prefix -cstab_eps_)", int(self.eps.getConvergedReason()),
                                       converged=nconv)
            vals = np.array([complex(self.eps.getEigenvalue(i)) for i in range(nconv)])
            errs = np.array([self.eps.computeError(i) for i in range(nconv)])
        finally:
            A.destroy()
            ctx.destroy()
        order = np.argsort(-np.abs(vals), kind="stable")
        return DominantMultipliers(vals[order], errs[order], ctx.products, self.eps.getIterationNumber(),
                                   time.perf_counter() - t0, self.eta)

    def destroy(self):
        self.eps.destroy()


# --- the window state on a long chain ---------------------------------------------------------------------------
def chain_from_window(Y, N, n0):
    """(N, 2) gap-lattice state of a free chain with the window state at beads n0..n0+M-1: at rest behind (y = D)
    and ahead (y = 0)."""
    Y = np.asarray(Y, float)
    X = np.zeros((N, 2))
    X[:n0, 0] = Y[0, 0]
    X[n0:n0 + len(Y)] = Y
    return X
