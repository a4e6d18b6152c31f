"""The tangent-linear flow of the chain over a time T, built once and used twice: by the Gauss-Newton refinement
(section 3.4, Jacobian S R(script-T; 0) - I) and by the Floquet analysis (section 3.5, F_q = S R(script-T; 0)).

:class:`TangentFlow` integrates X' = f(X) together with k tangent vectors Y' = Df(X) Y in one TS (the chain DMDA
with 2(1+k) dof per bead), so that R(T; 0) Y0 comes out with the same adaptive steps as X(T).
:meth:`TangentFlow.monodromy_mod_shift` assembles S R(T; 0) densely (k = 2N columns, for N up to a few hundred);
:class:`MonodromyModShift` is the same map as a matrix-free ``Mat.createPython`` operator (one product = one
integration with k = 1) for SLEPc.

:func:`liouville_integral`: int_0^T tr Df dt along an orbit, Liouville's log det R(T; 0) where the damping depends
on the state (contact dissipation).

:class:`CellPropagator`: for an orbit that repeats every M beads, the flow of the infinite chain in three cell
blocks, from one run on three cells; every Bloch sector's map of the cell follows from them (section 3.5).
"""
from __future__ import annotations

import math
from typing import Callable, Optional

import numpy as np
from numpy.typing import ArrayLike
from petsc4py import PETSc

from .chain import Chain, ChainIntegrator, IntegrationTolerances
from .errors import ParameterError, check_instance, check_integer
from .model import ChainSpec
from .symmetry import real_sector


class TangentFlow:
    """Flow and tangent-linear flow of a chain over [0, T], with k >= 0 tangent vectors at a time; its TS has the
    options prefix of the role it serves (``shoot_`` for the refinement, ``floquet_`` for the spectra, ``cwin_`` for
    the compacton window), the chain built by ``chain`` (e.g. the Bloch cell's) and the Runge-Kutta pair
    ``rk_type``."""

    def __init__(self, spec: ChainSpec, n_tangent: int, comm: PETSc.Comm, tolerances: Optional[IntegrationTolerances],
                 prefix: str, chain: type[Chain] = Chain, rk_type: str = "8vr") -> None:
        self.spec = check_instance("spec", spec, ChainSpec, "a ChainSpec")
        self.k = check_integer("n_tangent", n_tangent, 0, "the number of tangent vectors")
        self.aug = chain(spec, comm, n_tangent=self.k)
        self.integrator = ChainIntegrator(self.aug, tolerances, prefix, rk_type)
        self.Z = self.aug.create_state()

    def set_spec(self, spec: ChainSpec) -> None:
        """Move the flow to another chain of the same layout (:meth:`~hertzpetsc.chain.Chain.set_spec`: e.g. an
        actuator's signal at another driving frequency)."""
        self.aug.set_spec(spec)
        self.spec = spec

    def run(self, x0: ArrayLike, T: float, Y0: ArrayLike,
            monitor: Optional[Callable[[Chain, PETSc.Vec], None]] = None) -> tuple[np.ndarray, np.ndarray]:
        """Integrate from the state ``x0`` (N, 2) and tangent columns ``Y0`` (N, 2, k), both given on every rank;
        ``monitor(chain, X)`` is called at every step.

        Returns (X(T) as (N, 2), R(T; 0) Y0 as (N, 2, k)) on every rank.
        """
        N, k, ts = self.spec.N, self.k, self.integrator.ts
        z = np.empty((N, 2 + 2 * k))                  # bead-major: x, xdot, then (y, ydot) of each column
        z[:, :2] = np.asarray(x0, float).reshape(N, 2)
        z[:, 2:] = np.asarray(Y0, float).reshape(N, 2, k).transpose(0, 2, 1).reshape(N, 2 * k)
        self.aug.set_from_array(self.Z, z)
        if monitor is not None:
            ts.setMonitor(lambda ts, i, t, X: monitor(self.aug, X))
        try:
            self.integrator.integrate(self.Z, 0.0, T, dt=self.integrator.initial_step)
        finally:
            if monitor is not None:
                ts.monitorCancel()
        z = self.aug.gather(self.Z)
        return z[:, :2].copy(), z[:, 2:].reshape(N, k, 2).transpose(0, 2, 1).copy()

    def resolvent(self, x0: ArrayLike, T: float) -> tuple[np.ndarray, np.ndarray]:
        """Dense R(T; 0) (2N x 2N, index 2n + c for bead n, component c) and X(T), on every rank.

        Requires k = 2N; the columns are the images of the unit vectors e_{2n+c}.
        """
        N = self.spec.N
        if self.k != 2 * N:
            raise ValueError(f"the dense resolvent needs n_tangent = 2N = {2 * N}, not {self.k}")
        xT, RY = self.run(x0, T, np.eye(2 * N).reshape(N, 2, 2 * N))
        return RY.reshape(2 * N, 2 * N), xT

    def monodromy_mod_shift(self, x0: ArrayLike, T: float, shift: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Dense S^shift R(T; 0) and S^shift X(T), on every rank (S moves bead n+c to bead n, c the mass pattern's
        length)."""
        R, xT = self.resolvent(x0, T)
        c = self.spec.model.cell * shift
        return np.roll(R, -2 * c, axis=0), np.roll(xT, -c, axis=0)

    def destroy(self) -> None:
        self.Z.destroy()
        self.integrator.destroy()
        self.aug.destroy()


def liouville_integral(spec: ChainSpec, x0: ArrayLike, T: float, comm: PETSc.Comm,
                       tolerances: Optional[IntegrationTolerances] = None, prefix: str = "floquet_",
                       samples: int = 1024) -> tuple[float, float]:
    """(int_0^T tr Df(X(t)) dt, its error estimate) along the orbit from ``x0`` (N, 2): Liouville's log det R(T; 0)
    when the damping depends on the state (contact dissipation, :meth:`~hertzpetsc.chain.Chain.velocity_trace`).
    Simpson's rule on ``samples`` intervals of the state flow; the error estimate is its difference from Simpson on
    half as many (not divided by 15: the integrand has kinks where contacts open, close or clip)."""
    n = check_integer("samples", samples, 4, "the quadrature's intervals")
    n += n % 4
    chain = Chain(spec, comm)
    integ = ChainIntegrator(chain, tolerances, prefix)
    X = chain.create_state()
    try:
        chain.set_from_array(X, np.asarray(x0, float).reshape(spec.N, 2))
        ts = np.linspace(0.0, float(T), n + 1)
        tr = np.empty(n + 1)
        tr[0] = chain.velocity_trace(X, 0.0)
        for i in range(1, n + 1):
            integ.integrate(X, ts[i - 1], ts[i], dt=integ.initial_step if i == 1 else None)
            tr[i] = chain.velocity_trace(X, ts[i])
    finally:
        X.destroy()
        integ.destroy()
        chain.destroy()

    def simpson(f, h):
        return h / 3.0 * (f[0] + f[-1] + 4.0 * f[1:-1:2].sum() + 2.0 * f[2:-1:2].sum())
    h = float(T) / n
    fine, coarse = simpson(tr, h), simpson(tr[::2], 2 * h)
    return float(fine), float(abs(fine - coarse))


# The block flows MonodromyModShift keeps (one per column count and communicator): a block Davidson's blocks change
# size from round to round, and each flow holds its Runge-Kutta stages, O(N k) each.
BLOCK_FLOWS = 3


class MonodromyModShift:
    """Matrix-free F = S^shift R(T; 0) around the orbit from ``x0``: a ``Mat.createPython`` context (``shift`` 0:
    the plain monodromy R(T; 0), e.g. of a driven chain, which has no shift symmetry).

    Each product integrates the chain and one tangent vector over [0, T] (the orbit is recomputed, which keeps
    memory at O(N)); :meth:`apply` takes a block of vectors through one integration. ``products`` counts the
    vectors, ``integrations`` the TS runs; the flows of the last :data:`BLOCK_FLOWS` block sizes are kept.
    """

    def __init__(self, spec, x0, T, comm, tolerances, prefix, shift=1):
        self.spec, self.comm, self.tolerances, self.prefix = spec, comm, tolerances, prefix
        if shift not in (0, 1):
            raise ParameterError("shift", shift, "must be 1 (F = S R, a travelling wave) or 0 (R, a driven chain)")
        self.shift = int(shift)
        self.flow = TangentFlow(spec, 1, comm, tolerances, prefix)
        self.base = Chain(spec, comm)      # the chain of one vector: same N and comm, same ownership ranges
        self.products = self.integrations = 0
        self._RY = self.base.create_state()
        self._blocks = {}
        self.set_orbit(x0, T)

    def set_spec(self, spec):
        """Move the operator to another chain of the same layout (:meth:`TangentFlow.set_spec`)."""
        self.spec = spec
        self.base.set_spec(spec)
        self.flow.set_spec(spec)
        for flow in self._blocks.values():
            flow.set_spec(spec)

    def set_orbit(self, x0, T):
        """Move the operator to another orbit of the same chain (the next wavenumber of a scan)."""
        self.x0 = np.asarray(x0, dtype=float).reshape(self.spec.N, 2).copy()
        self.x0_local = self.x0[self.base.xs:self.base.xe].copy()
        self.T = float(T)

    def apply(self, Y):
        """F Y for k vectors at once, ``Y`` (N, 2, k) given on every rank: one integration of the orbit with the k
        tangent columns (instead of k integrations of the orbit with one); (N, 2, k) on every rank.

        On several ranks, with at least as many vectors as ranks, the vectors are dealt to the ranks and each rank
        integrates the whole chain with its share (no communication per stage: the ranks do not wait for each
        other 13 times a step); an error on one rank is raised on every rank."""
        Y = np.asarray(Y, dtype=float)
        k, size = Y.shape[2], self.comm.getSize()
        self.products += k
        self.integrations += 1
        if size == 1 or k < size:
            return self._integrate(Y, self.comm)
        from .dealing import dealt
        FY = np.empty_like(Y)
        shares = [list(range(r, k, size)) for r in range(size)]             # equal costs: share r on rank r
        for cols, part in dealt(shares, [1] * size, self.comm, lambda c: self._integrate(Y[:, :, c], PETSc.COMM_SELF)):
            FY[:, :, cols] = part
        return FY

    def _integrate(self, Y, comm):
        """S^shift R(T; 0) Y by one TangentFlow on ``comm`` (built once per column count and communicator)."""
        key = (Y.shape[2], comm.getSize())
        if key not in self._blocks:
            while len(self._blocks) >= BLOCK_FLOWS:      # the oldest first (dicts keep their insertion order)
                self._blocks.pop(next(iter(self._blocks))).destroy()
            self._blocks[key] = TangentFlow(self.spec, Y.shape[2], comm, self.tolerances, self.prefix)
        _, RY = self._blocks[key].run(self.x0, self.T, Y)
        return np.roll(RY, -self.spec.model.cell, axis=0) if self.shift else RY

    def mult(self, mat, x, y):
        """y = S^shift R(T; 0) x, all in the chain's distributed layout (no gathering)."""
        flow, base = self.flow, self.base
        z = flow.Z.getArray().reshape(base.nloc, 4)
        z[:, :2] = self.x0_local
        z[:, 2:] = x.getArray(readonly=True).reshape(base.nloc, 2)
        flow.integrator.integrate(flow.Z, 0.0, self.T, dt=flow.integrator.initial_step)
        RY = self._RY if self.shift else y                # R(T; 0) x: y itself, or shifted into y
        RY.getArray()[:] = flow.Z.getArray(readonly=True).reshape(base.nloc, 4)[:, 2:].ravel()
        if self.shift:
            base.shift(self._RY, y)
        self.products += 1
        self.integrations += 1

    def create_mat(self):
        """The PETSc shell matrix (2N x 2N, the chain's layout)."""
        base = self.base
        n_local = 2 * base.nloc
        N2 = 2 * self.flow.spec.N
        mat = PETSc.Mat().createPython(((n_local, N2), (n_local, N2)), context=self, comm=base.comm)
        mat.setUp()
        return mat

    def destroy(self, mat=None):
        """Free the flow; also called by petsc4py (with the matrix) when the shell matrix is destroyed."""
        if self.flow is not None:
            self._RY.destroy()
            self.base.destroy()
            self.flow.destroy()
            self.flow = None
            for flow in self._blocks.values():
                flow.destroy()
            self._blocks = {}


# The cell propagator is used when the response in the halves of the neighbouring cells away from cell 0 is below this
# fraction of the largest response: the blocks it neglects (two cells away) are smaller still, far below the flows'
# rtol (>= 1e-14).
LOCAL_RESPONSE = 1e-15


class CellPropagator:
    """The tangent flow over [0, T] of an orbit that repeats every M beads, as three cell blocks of the infinite
    chain: P_l (2M x 2M, index 2n + c), the response in cell l = -1, 0, 1 to data in cell 0.

    On the cell with the twisted boundary y_{n+M} = e^{i theta} y_n (a Bloch sector, :mod:`hertzpetsc.bloch`) the
    data in cell l are e^{i l theta} times those in cell 0, so the twisted resolvent is

        R_theta(T; 0) = P_0 + e^{-i theta} P_1 + e^{i theta} P_{-1}       (:func:`twisted_resolvent`),

    exactly when the response two cells away vanishes: in time T a perturbation has to cross a whole cell of M
    beads, and the lattice's coupling makes that decay faster than exponentially in M (out of contact, Hertz bonds
    carry none at all). One run of 2M real columns on 3M periodic beads (the columns: the unit vectors of cell 0)
    gives the three blocks, instead of one run of 2M complex columns per sector; :attr:`local` says whether the
    response stayed within reach (:meth:`reaches`: the halves of cells +-1 away from cell 0 saw less than
    :data:`LOCAL_RESPONSE` of the largest response). The TS has the prefix of the role (``floquet_``).
    """

    def __init__(self, model, M, comm, tolerances, prefix):
        self.M = int(M)
        self.flow = TangentFlow(ChainSpec(model, 3 * self.M), 2 * self.M, comm, tolerances, prefix)
        self.probe = TangentFlow(ChainSpec(model, 3 * self.M), 4, comm, tolerances, prefix)
        self.blocks = None
        self.local = False

    def _far(self, RY):
        """The largest response in the halves of cells 1 and -1 away from cell 0 (RY: (3M, 2, columns))."""
        M, h = self.M, self.M // 2
        return float(max(np.max(np.abs(RY[M + h:2 * M])), np.max(np.abs(RY[2 * M:3 * M - h]))))

    def reaches(self, x0, T):
        """The relative response in the far halves of the neighbouring cells to data on the two beads at the edges
        of cell 0 (4 columns: the beads nearest to those halves), a cheap test before :meth:`run`."""
        M = self.M
        Y = np.zeros((3 * M, 2, 4))
        for j, (bead, c) in enumerate(((0, 0), (0, 1), (M - 1, 0), (M - 1, 1))):
            Y[bead, c, j] = 1.0
        _, RY = self.probe.run(np.tile(np.asarray(x0, float), (3, 1)), T, Y)
        return self._far(RY) / max(1.0, float(np.max(np.abs(RY))))

    def run(self, x0, T):
        """Compute P_{-1}, P_0, P_1 around the orbit from the M-bead state ``x0`` (M, 2) over T (given on every
        rank); sets :attr:`local`. Returns self."""
        M = self.M
        Y = np.zeros((3 * M, 2, 2 * M))
        Y[:M] = np.eye(2 * M).reshape(M, 2, 2 * M)
        _, RY = self.flow.run(np.tile(np.asarray(x0, float), (3, 1)), T, Y)
        R = RY.reshape(6 * M, 2 * M)
        self.blocks = (R[4 * M:], R[:2 * M], R[2 * M:4 * M])          # P_{-1}, P_0, P_1
        self.local = self._far(RY) <= LOCAL_RESPONSE * float(np.max(np.abs(R)))
        return self

    def destroy(self):
        self.flow.destroy()
        self.probe.destroy()


def twisted_resolvent(blocks, theta):
    """R_theta = P_0 + e^{-i theta} P_1 + e^{i theta} P_{-1} from the cell blocks (P_{-1}, P_0, P_1) of a
    :class:`CellPropagator` run (real for theta = 0, pi)."""
    Pm, P0, P1 = blocks
    if real_sector(theta):
        return P0 + (1.0 if math.cos(theta) > 0 else -1.0) * (P1 + Pm)
    return P0 + np.exp(-1j * theta) * P1 + np.exp(1j * theta) * Pm
