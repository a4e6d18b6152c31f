"""Isolated compactons as fixed points of a window map that travels with them, and the map's point spectrum.

Paper: section 3.3 (eqs. extens, twlin, compacton, defvit) and the Discussion's question on the spectral
stability of isolated compactons. We fix the velocity to c = 1 bead per unit time (a = q^(2/(alpha-1)), so
script-T = 1; any other c follows by scaling). Ahead of the compacton the beads rest on the gap lattice
x_n = Delta n, Delta = a p q (eq. defvit); behind it they rest on x_n = Delta n + D, D = 2 pi a p. In the
gap-lattice coordinates y_n = x_n - Delta n a bond is r_n = Delta + y_{n+1} - y_n (:func:`WindowChain`).

A window of M beads (j = 0 the rearmost, free ends) and the one-bead shift define

    G(Y)_j = Phi_1(Y)_{j+1}  (j < M - 1),   G(Y)_{M-1} = (0, 0)   (the bead entering at the front is at rest),

and an exact compacton of gap Delta is a fixed point of G, provided the window holds every bond that closes
during a period plus a resting bead on each side (the free ends then never carry a force). The fixed points form
a curve (the sub-bead phase): :class:`CompactonRefiner` adds a phase condition and imposes q by the paper's
D / Delta = 2 pi / q, i.e. q y_0 = 2 pi Delta (Delta = 0: the solitary wave, eq. adr). Their spectrum:
:mod:`hertzpetsc.compacton_spectrum`.

Flows use the TS prefix ``cwin_`` (``-cwin_ts_*``). States are (M, 2) arrays (y_j, ydot_j), flattened
bead-major (index 2 j + component) for matrices.
"""
import math
from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

from .chain import Chain, IntegrationTolerances
from .continuation import ContinuationProblem
from .errors import ConvergenceError, ParameterError, check_integer
from .resources import MAX_DENSE_BEADS
from .gauss_newton import GaussNewton
from .model import ChainSpec
from .tangent import TangentFlow

WINDOW_PREFIX = "cwin_"
# the flows whose fixed points and spectra are measured (as the package's MEASURE_TOLERANCES)
WINDOW_TOLERANCES = IntegrationTolerances(rtol=1e-14, atol=1e-16)
DEFAULT_REAR = 6


def WindowChain(spec, comm, gap=0.0, n_tangent=0):
    """The free chain (eq. nc) in gap-lattice coordinates: a :class:`~hertzpetsc.chain.Chain` with
    :attr:`~hertzpetsc.chain.Chain.gap` set (bead n's position is y_n, its bonds r = gap + y_{n+1} - y_n; gap may
    change between integrations)."""
    if spec.boundary != "free":
        raise ParameterError("boundary", spec.boundary, "the compacton window is a free-ended chain")
    chain = Chain(spec, comm, n_tangent)
    chain.gap = gap
    return chain


# the rearmost bond compressed by at least this fraction of the deepest compression closes the rear part
REAR_STEP_LEVEL = 0.1


def rear_step(Y, gap, level=REAR_STEP_LEVEL):
    """(b, D): the beads 0..b behind the compression zone are integrated as y - D, D = y_0 their rest position,
    and bond b carries the extra length -D (:attr:`hertzpetsc.chain.Chain.step`); (-1, 0.0) if no bond is closed.

    Behind a solitary wave (Delta = 0) the bonds stay closed by doubly exponentially small amounts; computed as
    differences of positions ~ D they are round-off, whose sign flips from stage to stage, and for alpha < 2 the
    stiffness alpha |r|^(alpha-1) of such a bond (~1e-8 at alpha = 3/2) switches on and off: the tangent flow's
    error control then cuts the steps a hundredfold. Relative to D these bonds are exact. b is the rearmost bond
    closed by at least ``level`` of the deepest compression, so that during the period (the zone advances one
    bead) the bonds computed across the step stay far above round-off."""
    r = gap + np.diff(np.asarray(Y, float)[:, 0])
    deep = -float(np.min(r))
    if not deep > 0:
        return -1, 0.0
    b = int(np.argmax(-r >= level * deep))
    return b, float(Y[0, 0])


def shift_window(Z):
    """The window's shift on (M, ...) arrays: bead j <- bead j + 1, the front bead zero (at rest on the lattice)."""
    out = np.zeros_like(Z)
    out[:-1] = Z[1:]
    return out


class CompactonWindow:
    """The window map G of an M-bead window (module docstring) and its derivatives: Phi_1 of the window chain with
    k = 0, 1 or 2M + 1 tangent columns in one TS (:class:`~hertzpetsc.tangent.TangentFlow`, prefix ``cwin_``, built on
    first use). Arrays in and out are given on every rank."""

    def __init__(self, model, M, comm, tolerances=WINDOW_TOLERANCES, prefix=WINDOW_PREFIX, rk_type="8vr"):
        self.M = check_integer("M", M, 4, "the window's number of beads", MAX_DENSE_BEADS,
                               "(its map's Jacobian is dense: (2M)^2 entries)")
        self.model, self.comm, self.spec = model, comm, ChainSpec(model, self.M, "free")
        self.tolerances, self.prefix, self.rk_type = tolerances, prefix, rk_type
        self._flows = {}
        self._flow(0)                  # reads and checks the -cwin_ts_* options now

    def _flow(self, k):
        if k not in self._flows:
            self._flows[k] = TangentFlow(self.spec, k, self.comm, self.tolerances, self.prefix, rk_type=self.rk_type)
        return self._flows[k]

    def run(self, Y, gap, tangents=None, T=1.0, monitor=None):
        """(Y(T) (M, 2), R(T) tangents (M, 2, k) or None) from Y (M, 2) and tangents (M, 2, k). The beads behind
        the compression zone are integrated relative to the rear bead's position (:func:`rear_step`)."""
        k = 0 if tangents is None else tangents.shape[2]
        flow = self._flow(k)
        Y = np.array(Y, float).reshape(self.M, 2)
        b, D = rear_step(Y, gap)
        Y[:b + 1, 0] -= D
        flow.aug.gap = float(gap)
        flow.aug.step = (b, -D)
        YT, W = flow.run(Y, T, np.zeros((self.M, 2, 0)) if k == 0 else tangents, monitor)
        YT[:b + 1, 0] += D
        return YT, (W if k else None)

    @property
    def dim(self):
        return 2 * self.M

    def map(self, Y, gap):
        """G(Y), (M, 2)."""
        YT, _ = self.run(Y, gap)
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
        YT, W = self.run(Y, gap, T0)
        W[:, 0, n] -= np.arange(M)
        G, GW = shift_window(YT), shift_window(W).reshape(n, n + 1)
        return G, GW[:, :n].copy(), GW[:, n].copy()

    def apply(self, Y, gap, x):
        """J x by one tangent integration (the matrix-free product); x and the result are (2M,)."""
        _, W = self.run(Y, gap, np.asarray(x, float).reshape(self.M, 2, 1))
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

    def core(self, Y, gap):
        """Bead indices of the core: beads of the bonds closed at t = 0 or at a time step of the period (r_j <
        -1e-13 x the largest compression: a compacton's other bonds are exactly open; the solitary wave's doubly
        exponential tails are counted only above that level), and the bead that enters them by the shift."""
        Y = np.asarray(Y, float).reshape(self.M, 2)
        r_min = gap + np.diff(Y[:, 0])
        self.run(Y, gap, monitor=lambda chain, X: np.minimum(r_min, chain.bonds(chain.gather(X)), out=r_min))
        b = np.nonzero(r_min < -1e-13 * max(0.0, -float(r_min.min())))[0]
        if not len(b):
            raise ParameterError("Y", "no closed bond", "the window holds no compression zone")
        return np.arange(max(b.min() - 1, 0), min(b.max() + 1, self.M - 1) + 1)

    def destroy(self):
        for flow in self._flows.values():
            flow.destroy()
        self._flows = {}


# --- initial guesses and window sizes -------------------------------------------------------------------------------
def guess_from_branch(point, M, rear=DEFAULT_REAR, q_k=None):
    """The unrefined compacton of a branch point at c = 1 in the window (eqs. extens, twlin, compacton, defvit),
    from :func:`hertzpetsc.compacton.compacton_train`: (Y (M, 2) in gap-lattice coordinates, y = 0 ahead, gap).
    ParameterError when q > q_k (F(q) < 1) or the window leaves fewer than 2 resting beads behind the zone (and the
    bead it advances by) or 3 ahead."""
    from .compacton import CompactonScales, chain_state, compacton_train, placement
    train = compacton_train(point, (), q_k)
    if rear < 2:
        raise ParameterError("-rear", rear, "at least 2 resting beads behind the compression zone")
    need = rear + int(math.ceil(train.width)) + 2 + 3
    if M < need:
        raise ParameterError("-M", M, f"the window is too short for the compression zone at q = {point.q:.6g}: it is "
                                      f"{train.width:.2f} beads wide, so M >= {need} with {rear} beads behind")
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


class WindowFixedPoint:
    """The rows [G(Y) - Y; psi . (Y - Y_ref); q y_0 - 2 pi Delta] (the last one unless the gap is fixed: q = 0 or
    ``fix_gap``) in z = (Y, Delta) or Y, psi the vector field at the start; measure max|R| / max|Y|."""

    def __init__(self, window, Y, gap, q, fix_gap):
        self.window, self.q, self.gap, self.fix_gap, self.n = window, float(q), float(gap), fix_gap, window.dim
        self.Yref = np.asarray(Y, float).ravel().copy()
        psi = window.vector_field(Y, gap)
        self.psi = psi / np.linalg.norm(psi)

    def split(self, z):
        return z[:self.n].reshape(-1, 2), self.gap if self.fix_gap else float(z[self.n])

    def residual(self, z):
        Y, gap = self.split(z)
        cond = [self.psi @ (Y.ravel() - self.Yref)] + ([] if self.fix_gap else [self.q * Y[0, 0] - 2 * math.pi * gap])
        R = np.concatenate([(self.window.map(Y, gap) - Y).ravel(), cond])
        return R, float(np.max(np.abs(R)) / np.max(np.abs(Y)))

    def jacobian(self, z):
        Y, gap = self.split(z)
        n = self.n
        _, J, Jg = self.window.jacobian(Y, gap)
        A = np.zeros((n + 1 + (not self.fix_gap), n + (not self.fix_gap)))
        A[:n, :n] = J - np.eye(n)
        A[n, :n] = self.psi
        if not self.fix_gap:
            A[:n, n], A[n + 1, 0], A[n + 1, n] = Jg, self.q, -2 * math.pi
        return A, None


class CompactonRefiner(ContinuationProblem):
    """Exact compactons of a window: Gauss-Newton (:class:`~hertzpetsc.gauss_newton.GaussNewton`, plain least squares,
    a fresh Jacobian at every iterate) on the rows of :class:`WindowFixedPoint` (consistent because of the Jordan block
    at 1); ``tol``: the target max|R| / max|Y|, ``residual_tol``: the largest max|G(Y) - Y| accepted. Also the
    continuation problem in q (natural): Z = (Y, Delta, q) (:meth:`pack`), :meth:`solve` refines at the q of Z from its
    (Y, Delta), each point reports its :class:`ExactCompacton`."""

    parameter = "q"

    def __init__(self, window, tol=1e-13, max_iterations=20, residual_tol=1e-10):
        self.window, self.tol, self.max_iterations, self.residual_tol = window, tol, max_iterations, residual_tol
        self.engine = GaussNewton(window.comm, truncations=(0.0,), reuse_jacobian=False)
        self.last = None

    def refine(self, Y0, gap0, q, fix_gap=False):
        """The :class:`ExactCompacton` at ``q`` from the window state ``Y0`` (M, 2) and gap ``gap0``."""
        Y0 = np.asarray(Y0, float).reshape(self.window.M, 2)
        problem = WindowFixedPoint(self.window, Y0, gap0, q, fix_gap or q == 0)
        z0 = Y0.ravel() if problem.fix_gap else np.append(Y0.ravel(), gap0)
        res = self.engine.solve(problem, z0, self.tol, self.max_iterations)
        Y, gap = problem.split(res.z)
        residual = float(np.max(np.abs(res.rows[:problem.n])))
        if not residual <= self.residual_tol:
            raise ConvergenceError("compacton Gauss-Newton (window map)", f"residual {residual:.2e}", q=float(q))
        return ExactCompacton(q=float(q), gap=gap, Y=Y.copy(), residual=residual, iterations=res.iterations)

    # --- the continuation problem in q --------------------------------------------------------------------------
    def create_vec(self):
        """Z on every rank (the window's unknowns are: the engine applies the same steps everywhere)."""
        return PETSc.Vec().createSeq(self.window.dim + 2, comm=PETSc.COMM_SELF)

    def pack(self, compacton):
        """The extended vector Z = (Y, Delta, q) of an :class:`ExactCompacton` (a new Vec)."""
        Z = self.create_vec()
        Z.setArray(np.concatenate([compacton.Y.ravel(), [compacton.gap, compacton.q]]))
        return Z

    def solve(self, Z, row=None, value=None):
        """Refine at the q of Z (Delta = 0 at q = 0) and write the compacton into Z; natural continuation only."""
        if row is not None:
            raise ParameterError("row", "pseudo-arclength", "the compacton window is continued in q naturally")
        z = Z.getArray()
        q = float(z[-1])
        self.last = self.refine(z[:-2].reshape(-1, 2), 0.0 if q == 0 else z[-2], q)
        z[:] = np.concatenate([self.last.Y.ravel(), [self.last.gap, q]])
        return self.last.iterations

    def report(self, Z):
        return dict(compacton=self.last)
