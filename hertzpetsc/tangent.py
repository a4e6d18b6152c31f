"""The tangent-linear flow of the chain over a time T, built once and used twice: by the Gauss-Newton refinement
(section 3.4, Jacobian S R(script-T; 0) - I) and by the Floquet analysis (section 3.5, F_q = S R(script-T; 0)).

:class:`TangentFlow` integrates X' = f(X) together with k tangent vectors Y' = Df(X) Y in one TS (the chain DMDA
with 2(1+k) dof per bead), so that R(T; 0) Y0 comes out with the same adaptive steps as X(T).
:meth:`TangentFlow.monodromy_mod_shift` assembles S R(T; 0) densely (k = 2N columns, for N up to a few hundred);
:class:`MonodromyModShift` is the same map as a matrix-free ``Mat.createPython`` operator (one product = one
integration with k = 1) for SLEPc.
"""
import numpy as np
from petsc4py import PETSc

from .chain import Chain, ChainIntegrator


def stack_tangents(x, Y):
    """The chain's augmented state (n, 2 + 2k) from the state ``x`` (n, 2) and k tangent columns ``Y`` (n, 2, k)."""
    x = np.asarray(x, float)
    n, k = len(x), np.shape(Y)[2]
    return np.concatenate([x.reshape(n, 2), np.asarray(Y, float).reshape(n, 2, k).transpose(0, 2, 1).reshape(n, 2 * k)],
                          axis=1)


def split_tangents(z, k):
    """(state (n, 2), tangent columns (n, 2, k)) from an augmented state ``z`` (n, 2 + 2k)."""
    n = len(z)
    return z[:, :2].copy(), z[:, 2:].reshape(n, k, 2).transpose(0, 2, 1).copy()


class TangentFlow:
    """Flow and tangent-linear flow of a chain over [0, T], with k tangent vectors at a time; its TS has the
    options prefix of the role it serves (``shoot_`` for the refinement, ``floquet_`` for the spectra)."""

    def __init__(self, spec, n_tangent, comm, tolerances, prefix):
        self.spec = spec
        self.k = int(n_tangent)
        self.aug = Chain(spec, comm, n_tangent=self.k)
        self.base = Chain(spec, comm)                  # same N and comm: same ownership ranges
        self.integrator = ChainIntegrator(self.aug, tolerances, prefix)
        self.Z = self.aug.create_state()

    def set_spec(self, spec):
        """Move both chains to another chain of the same layout (:meth:`~hertzpetsc.chain.Chain.set_spec`: e.g. an
        actuator's signal at another driving frequency)."""
        self.aug.set_spec(spec)
        self.base.set_spec(spec)
        self.spec = spec

    def run(self, x0, T, Y0):
        """Integrate from the state ``x0`` (N, 2) and tangent columns ``Y0`` (N, 2, k), both given on every rank.

        Returns (X(T) as (N, 2), R(T; 0) Y0 as (N, 2, k)) on every rank.
        """
        N, k = self.spec.N, self.k
        self.aug.set_from_array(self.Z, stack_tangents(np.asarray(x0, float).reshape(N, 2),
                                                       np.asarray(Y0, float).reshape(N, 2, k)))
        self.integrator.integrate(self.Z, 0.0, T, dt=self.integrator.initial_step)
        return split_tangents(self.aug.gather(self.Z), k)

    def resolvent(self, x0, T):
        """Dense R(T; 0) (2N x 2N, index 2n + c for bead n, component c) and X(T), on every rank.

        Requires k = 2N; the columns are the images of the unit vectors e_{2n+c}.
        """
        N = self.spec.N
        if self.k != 2 * N:
            raise ValueError(f"the dense resolvent needs n_tangent = 2N = {2 * N}, not {self.k}")
        xT, RY = self.run(x0, T, np.eye(2 * N).reshape(N, 2, 2 * N))
        return RY.reshape(2 * N, 2 * N), xT

    def monodromy_mod_shift(self, x0, T, shift=1):
        """Dense S^shift R(T; 0) and S^shift X(T), on every rank (S moves bead n+c to bead n, c the mass pattern's
        length)."""
        R, xT = self.resolvent(x0, T)
        c = self.spec.model.cell * shift
        return np.roll(R, -2 * c, axis=0), np.roll(xT, -c, axis=0)

    def destroy(self):
        self.Z.destroy()
        self.integrator.destroy()
        self.aug.destroy()
        self.base.destroy()


class MonodromyModShift:
    """Matrix-free F = S^shift R(T; 0) around the orbit from ``x0``: a ``Mat.createPython`` context (``shift`` 0:
    the plain monodromy R(T; 0), e.g. of a driven chain, which has no shift symmetry).

    Each product integrates the chain and one tangent vector over [0, T] (the orbit is recomputed, which keeps
    memory at O(N)); ``products`` counts them.
    """

    def __init__(self, spec, x0, T, comm, tolerances, prefix, shift=1):
        self.shift = int(shift)
        self.flow = TangentFlow(spec, 1, comm, tolerances, prefix)
        base = self.flow.base
        self.x0_local = np.asarray(x0, dtype=float).reshape(spec.N, 2)[base.xs:base.xe].copy()
        self.T = float(T)
        self.products = 0
        self._RY = base.create_state()

    def set_orbit(self, x0, T):
        """Move the operator to another orbit of the same chain (the next wavenumber of a scan)."""
        base = self.flow.base
        self.x0_local = np.asarray(x0, dtype=float).reshape(self.flow.spec.N, 2)[base.xs:base.xe].copy()
        self.T = float(T)

    def mult(self, mat, x, y):
        """y = S R(T; 0) x, all in the chain's distributed layout (no gathering)."""
        flow, base = self.flow, self.flow.base
        z = flow.Z.getArray().reshape(base.nloc, 4)
        z[:, :2] = self.x0_local
        z[:, 2:] = x.getArray(readonly=True).reshape(base.nloc, 2)
        flow.integrator.integrate(flow.Z, 0.0, self.T, dt=flow.integrator.initial_step)
        if self.shift:
            self._RY.getArray()[:] = flow.Z.getArray(readonly=True).reshape(base.nloc, 4)[:, 2:].ravel()
            base.shift(self._RY, y)
        else:
            y.getArray()[:] = flow.Z.getArray(readonly=True).reshape(base.nloc, 4)[:, 2:].ravel()
        self.products += 1

    def create_mat(self):
        """The PETSc shell matrix (2N x 2N, the chain's layout)."""
        base = self.flow.base
        n_local = 2 * base.nloc
        N2 = 2 * self.flow.spec.N
        mat = PETSc.Mat().createPython(((n_local, N2), (n_local, N2)), context=self, comm=base.comm)
        mat.setUp()
        return mat

    def destroy(self, mat=None):
        """Free the flow; also called by petsc4py (with the matrix) when the shell matrix is destroyed."""
        if self.flow is not None:
            self._RY.destroy()
            self.flow.destroy()
            self.flow = None
