"""The advance-delay problem for periodic travelling waves (eqs. ad, pbc) on PETSc: residual and Jacobian.

For odd 2 pi-periodic u on the grid of :mod:`hertzpetsc.grid`, the second-order discretisation of eq. ad is

    R_j(u) = (u_{j+1} - 2 u_j + u_{j-1}) / h^2 - V'((tau_q u)_j - u_j) + V'(u_j - (tau_{-q} u)_j) = 0,

j = 1 .. K-1 (the equations at xi = 0, pi and on (pi, 2 pi) follow by oddness). tau_{+-q} are the shift
stencils of :func:`hertzpetsc.stencil.shift_stencil`; the exact Jacobian

    J = D2 + diag(V''(d+) + V''(d-)) - diag(V''(d+)) tau_q - diag(V''(d-)) tau_{-q},
    d+ = tau_q u - u,  d- = u - tau_{-q} u,

is applied matrix-free or assembled as a parallel AIJ matrix. V' and V'' are the lattice model's
(:class:`hertzpetsc.model.LatticeModel`). :mod:`hertzpetsc.twsolver` solves R(u) = 0 with SNES.
"""
import math
import weakref

import numpy as np
from petsc4py import PETSc

from .assembly import RowAssembler, StencilGather, merged_csr
from .errors import ParameterError
from .model import LatticeModel
from .stencil import shift_stencil


def check_wavenumber(q, h=None, name="q"):
    """q must lie in (0, pi] (and span at least one grid step h if h is given); ``name`` is used in errors."""
    try:
        qf = float(q)
    except (TypeError, ValueError):
        raise ParameterError(name, q, "must be a real number in (0, pi]") from None
    if not (0.0 < qf <= math.pi * (1 + 1e-14)):
        raise ParameterError(name, q, "the wavenumber must lie in (0, pi]")
    if h is not None and qf < h * (1 - 1e-12):
        raise ParameterError(name, q, f"must be at least one grid step h = {h:.6g} (refine the grid for smaller q)")
    return min(qf, math.pi)


class AdvanceDelayProblem:
    """Residual and Jacobian of eqs. ad-pbc at one wavenumber q; its methods are the SNES callbacks.

    The three linear maps of eq. ad, D2, tau_q and tau_{-q}, are stacked into one parallel AIJ matrix T (3 rows
    per unknown, built once per q), so that one MatMult (one scatter, compiled code) gives D2 u, tau_q u and
    tau_{-q} u for the residual, for the Jacobian's coefficients V''(d+-), and for the matrix-free Jacobian
    products of the Newton-Krylov path. :meth:`create_jacobian` builds either the assembled AIJ Jacobian
    (``kind='aij'``, for LU and algebraic preconditioners) or that matrix-free operator (``kind='shell'``).
    """

    def __init__(self, model, grid, q):
        if not isinstance(model, LatticeModel):
            raise ParameterError("model", model, "must be a LatticeModel")
        model.require_uniform_masses("the advance-delay problem of eq. ad")
        self.model = model
        self.grid = grid
        self.q = check_wavenumber(q, grid.h)
        self.sigma = self.q / grid.h
        h2 = grid.h ** 2
        # One rank: T is an AIJ matrix on the grid's Vec layout. Several ranks: T is a rank-local SeqAIJ block
        # acting on the values gathered by one VecScatter (the stencils' ``needed`` set): one set of per-row
        # arrays instead of MPIAIJ's diagonal and off-diagonal blocks, which doubled the memory per rank.
        self.parallel = grid.comm.getSize() > 1
        self.stencils = StencilGather(grid, {
            "d2": (np.array([-1, 0, 1]), np.array([1.0, -2.0, 1.0]) / h2),
            "plus": shift_stencil(self.sigma),
            "minus": shift_stencil(-self.sigma),
        }, scatter=self.parallel)
        self._assembler = None
        st = self.stencils
        nloc = grid.rend - grid.rstart
        self.nloc = nloc
        if self.parallel:
            parts = [merged_csr(st.pos[k], st.coef[k]) for k in ("d2", "plus", "minus")]
            st.pos = {}                   # positions are folded into T's columns
        else:
            parts = [_d2_csr(grid, st)] + [merged_csr(st.cols[k], st.coef[k]) for k in ("plus", "minus")]
        offsets = np.cumsum([0] + [p[0][-1] for p in parts])
        indptr = np.concatenate([parts[0][0]] + [p[0][1:] + offsets[i] for i, p in enumerate(parts) if i > 0])
        csr = (indptr.astype(PETSc.IntType), np.concatenate([p[1] for p in parts]),
               np.concatenate([p[2] for p in parts]))
        del parts, indptr
        # the arrays are used in place (petsc4py keeps them alive)
        if self.parallel:
            self.T = PETSc.Mat().createAIJWithArrays((3 * nloc, len(st.needed)), csr, comm=PETSc.COMM_SELF)
        else:
            self.T = PETSc.Mat().createAIJWithArrays(((3 * nloc, 3 * grid.size), (nloc, grid.size)), csr,
                                                     comm=grid.comm)
        self.T.assemble()
        self.w = self.T.createVecLeft()
        self.a = self.b = None            # V''(d+), V''(d-) at the last Jacobian evaluation

    @property
    def integer_shift(self):
        return len(self.stencils.coef["plus"][0]) == 1 if self.grid.rend > self.grid.rstart else True

    @property
    def assembler(self):
        """The CSR pattern of the assembled Jacobian (built on first use: the matrix-free path never needs it)."""
        if self._assembler is None:
            st = self.stencils
            self_cols = np.arange(self.grid.rstart, self.grid.rend, dtype=np.int64)[:, None]
            self._assembler = RowAssembler(self.grid, [st.cols["d2"], self_cols, st.cols["plus"], st.cols["minus"]])
        return self._assembler

    def stacked(self, X):
        """w = T X = (D2 X, tau_q X, tau_{-q} X) on the owned rows (one scatter and one MatMult)."""
        if self.parallel:
            st = self.stencils
            st.scatter.scatter(X, st.local, PETSc.InsertMode.INSERT_VALUES, PETSc.ScatterMode.FORWARD)
            self.T.mult(st.local, self.w)
        else:
            self.T.mult(X, self.w)
        return self.w

    def shift_differences(self, X):
        """d+ = tau_q u - u, d- = u - tau_{-q} u and D2 u on the owned rows (one MatMult with T)."""
        self.stacked(X)
        w = self.w.getArray(readonly=True)
        u = X.getArray(readonly=True)
        n = self.nloc
        return w[n:2 * n] - u, u - w[2 * n:], w[:n]

    def formFunction(self, snes, X, F):
        dplus, dminus, d2u = self.shift_differences(X)
        force, delta0 = self.model.force, self.model.delta0
        F.getArray()[:] = d2u - _on_contact(force, dplus, delta0) + _on_contact(force, dminus, delta0)

    def _coefficients(self, X):
        dplus, dminus, _ = self.shift_differences(X)
        delta0 = self.model.delta0
        self.a = _on_contact(self.model.stiffness, dplus, delta0)
        self.b = _on_contact(self.model.stiffness, dminus, delta0)

    def _jacobian_blocks(self):
        a, b = self.a[:, None], self.b[:, None]
        c = self.stencils.coef
        return [c["d2"], a + b, -a * c["plus"], -b * c["minus"]]

    def create_jacobian(self, X, kind="aij"):
        """J(X) as a new parallel AIJ matrix with this q's pattern (``kind='aij'``), or as a matrix-free operator
        J v = D2 v + (a + b) v - a tau_q v - b tau_{-q} v, a = V''(d+), b = V''(d-) (``kind='shell'``)."""
        self._coefficients(X)
        if kind == "aij":
            return self.assembler.create(self._jacobian_blocks())
        if kind != "shell":
            raise ParameterError("kind", kind, "must be 'aij' or 'shell'")
        g = self.grid
        nloc = g.rend - g.rstart
        J = PETSc.Mat().createPython(((nloc, g.size), (nloc, g.size)), _JacobianProduct(self), comm=g.comm)
        J.setUp()
        return J

    def formJacobian(self, snes, X, J, P):
        self._coefficients(X)
        if P.getType() != PETSc.Mat.Type.PYTHON:
            self.assembler.update(P, self._jacobian_blocks())
        if J.handle != P.handle:
            J.assemble()

    def residual_norm(self, X):
        F = X.duplicate()
        self.formFunction(None, X, F)
        norm = F.norm(PETSc.NormType.NORM_INFINITY)
        F.destroy()
        return norm

    def destroy(self):
        self.stencils.destroy()
        self.T.destroy()
        self.w.destroy()


_D2_CACHE = weakref.WeakKeyDictionary()


def _d2_csr(grid, stencils):
    """CSR rows of the second difference on ``grid`` (independent of q: built once per grid)."""
    csr = _D2_CACHE.get(grid)
    if csr is None:
        csr = _D2_CACHE[grid] = merged_csr(stencils.cols["d2"], stencils.coef["d2"])
    return csr


def _on_contact(f, x, delta0=0.0):
    """f(x) where x < 0 (in contact), 0 elsewhere: V' and V'' vanish for x >= 0, and few entries are in contact.
    With precompression delta0 > 0 the law itself handles contact (V' = delta0^alpha beyond it): f(x) everywhere."""
    if delta0 > 0.0:
        return f(x)
    out = np.zeros_like(x)
    m = x < 0.0
    out[m] = f(x[m])
    return out


class _JacobianProduct:
    """Matrix-free Jacobian of eq. ad (the ``shell`` kind of :meth:`AdvanceDelayProblem.create_jacobian`)."""

    def __init__(self, problem):
        self.problem = problem

    @PETSc.Log.EventDecorator("hz_tw_jacobian_mult")
    def mult(self, mat, x, y):
        p = self.problem
        w = p.stacked(x).getArray(readonly=True)
        v = x.getArray(readonly=True)
        n = p.nloc
        y.getArray()[:] = w[:n] + (p.a + p.b) * v - p.a * w[n:2 * n] - p.b * w[2 * n:]
