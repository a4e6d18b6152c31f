"""Periodic grid for odd 2 pi-periodic profiles, its parallel layout, and the long-range shift stencils.

Grid xi_j = j h, h = pi / K, j = 0 .. 2K-1. An odd 2 pi-periodic u has u_0 = u_K = 0 and u_{2K-j} = -u_j, so
the unknowns are u_1 .. u_{K-1}, stored in a PETSc Vec of size K-1 distributed over the communicator (this
restriction to odd profiles removes the translation and constant degeneracies of eq. ad, as in the paper).

A shift u(xi_j + sigma h) spans up to half the domain, so it cannot be a DMDA stencil: every operator is a
list of (offset, weight) pairs relative to j, folded onto the unknowns by oddness and periodicity, and the
values a rank needs are fetched by one VecScatter built once per operator set (:class:`StencilGather`).
The stencils themselves (exact for whole-step shifts, interpolating otherwise) are in :mod:`hertzpetsc.stencil`.
"""
import math

import numpy as np
from petsc4py import PETSc

from .errors import ParameterError


def check_cells_per_pi(cells_per_pi):
    """K must be an integer >= 4 (h = pi/K); returns it as int."""
    try:
        K = int(cells_per_pi)
    except (TypeError, ValueError):
        raise ParameterError("cells_per_pi", cells_per_pi, "must be an integer >= 4 (h = pi / cells_per_pi)") from None
    if K != cells_per_pi or K < 4:
        raise ParameterError("cells_per_pi", cells_per_pi, "must be an integer >= 4 (h = pi / cells_per_pi)")
    return K


class OddPeriodicGrid:
    """The uniform grid of [0, 2 pi) with step h = pi/K, restricted to odd profiles, on a communicator.

    With ``parity = +1`` the profiles are even instead (u_{2K-j} = u_j, unknowns u_0 .. u_K); ``length``
    replaces 2 pi by another period. With ``dirichlet`` (even profiles only) the profile lives on the line and
    vanishes beyond +-length/2 instead of being periodic: the solitary wave of :mod:`hertzpetsc.solitary` (on a
    period, sum_j R_j = 0 for eq. adr and its Jacobian would be singular).
    """

    def __init__(self, cells_per_pi, comm=None, parity=-1, length=2 * math.pi, dirichlet=False):
        self.K = check_cells_per_pi(cells_per_pi)
        if parity not in (-1, 1):
            raise ParameterError("parity", parity, "must be -1 (odd profiles) or +1 (even profiles)")
        if dirichlet and parity < 0:
            raise ParameterError("dirichlet", dirichlet, "is only available for even profiles (parity +1)")
        self.parity = parity
        self.dirichlet = dirichlet
        self.h = 0.5 * length / self.K
        self.comm = comm if comm is not None else PETSc.COMM_WORLD
        self.offset = 1 if parity < 0 else 0          # unknown index = grid index - offset
        self.size = self.K - 1 if parity < 0 else self.K + 1
        # The PETSc default layout, fixed once so that every Vec and Mat of this grid shares it.
        self._template = PETSc.Vec().createMPI(self.size, comm=self.comm)
        self.rstart, self.rend = self._template.getOwnershipRange()

    @property
    def n_points(self):
        return 2 * self.K

    def xi_half(self):
        """Points xi_j = j h, j = 0..K (the half period [0, pi] on which profiles are stored)."""
        return np.arange(self.K + 1) * self.h

    def create_vec(self):
        return self._template.duplicate()

    def owned_points(self):
        """Grid indices j of the unknowns owned by this rank."""
        return np.arange(self.rstart, self.rend, dtype=np.int64) + self.offset

    def fold(self, g):
        """Map full-grid indices g (any integers) to (unknown index, sign); for odd profiles sign 0 where u
        vanishes (xi = 0, pi), -1 on the second half period."""
        if self.dirichlet:
            j = np.abs(np.asarray(g))
            return np.minimum(j, self.K).astype(np.int64), np.where(j <= self.K, 1.0, 0.0)
        r = np.mod(g, 2 * self.K)
        j = np.where(r <= self.K, r, 2 * self.K - r)
        if self.parity > 0:
            return j.astype(np.int64), np.ones(np.shape(g))
        sign = np.where(r < self.K, 1.0, -1.0)
        sign[(r == 0) | (r == self.K)] = 0.0
        idx = np.where(sign != 0.0, j - 1, 0)
        return idx.astype(np.int64), sign

    def half_profile(self, vec):
        """The profile on the half period (K+1 values; zeros at both ends if odd) as a numpy array on every rank."""
        scatter, full = PETSc.Scatter.toAll(vec)
        scatter.scatter(vec, full, PETSc.InsertMode.INSERT_VALUES, PETSc.ScatterMode.FORWARD)
        out = np.zeros(self.K + 1)
        out[self.offset:self.offset + self.size] = full.getArray(readonly=True)
        scatter.destroy()
        full.destroy()
        return out

    def vec_from_half_profile(self, values):
        """A distributed Vec holding the odd profile whose values on [0, pi] are ``values`` (K+1 numbers)."""
        values = np.asarray(values, dtype=float)
        if values.shape != (self.K + 1,):
            raise ParameterError("profile", f"array of shape {values.shape}",
                                 f"must have K+1 = {self.K + 1} values on [0, pi] for cells_per_pi = {self.K}")
        vec = self.create_vec()
        vec.setArray(values[self.rstart + self.offset:self.rend + self.offset])
        return vec


class StencilGather:
    """Fetches, for the rows owned by this rank, the values that a set of stencils needs.

    ``stencils`` maps a name to (offsets, weights) relative to the row's grid index. For each name the rows get
    ``cols`` (global unknown indices, shape rows x width) and ``coef`` (weights times the folding signs, 0 where
    the point is xi = 0 or pi); :meth:`apply` evaluates sum_k coef_k u[cols_k] from the gathered values.
    The scatter is built once, here.
    """

    def __init__(self, grid, stencils, scatter=True):
        self.grid = grid
        rows = grid.owned_points()
        self.cols, self.coef = {}, {}
        needed = [np.arange(grid.rstart, grid.rend, dtype=np.int64)]
        for name, (offsets, weights) in stencils.items():
            idx, sign = grid.fold(rows[:, None] + np.asarray(offsets)[None, :])
            # Points where u vanishes by symmetry contribute nothing: point them at the row's own unknown
            # (a column every row has anyway) with coefficient 0, so they add no matrix entries.
            idx = np.where(sign != 0.0, idx, (rows - grid.offset)[:, None])
            self.cols[name] = idx
            self.coef[name] = sign * np.asarray(weights, dtype=float)[None, :]
            needed.append(idx.ravel())
        self.scatter = self.local = None
        if not scatter:         # only cols/coef wanted (e.g. to assemble matrices); gather() unavailable
            return
        # the sorted set of needed unknowns and each entry's position in it, in O(n) (a mask, not a sort)
        mask = np.zeros(grid.size, dtype=bool)
        for idx in needed:
            mask[idx] = True
        self.needed = np.flatnonzero(mask)
        lookup = np.cumsum(mask, dtype=np.int64) - 1
        del mask
        self.pos = {name: lookup[self.cols[name]] for name in stencils}
        del lookup
        self.local = PETSc.Vec().createSeq(len(self.needed), comm=PETSc.COMM_SELF)
        iset = PETSc.IS().createGeneral(self.needed.astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        self.scatter = PETSc.Scatter().create(grid._template, iset, self.local, None)
        iset.destroy()

    def gather(self, vec):
        """Values of ``vec`` at ``self.needed`` (a numpy view valid until the next gather)."""
        self.scatter.scatter(vec, self.local, PETSc.InsertMode.INSERT_VALUES, PETSc.ScatterMode.FORWARD)
        return self.local.getArray(readonly=True)

    def apply(self, name, gathered):
        return (self.coef[name] * gathered[self.pos[name]]).sum(axis=1)

    def destroy(self):
        if self.scatter is not None:
            self.scatter.destroy()
            self.local.destroy()


def merged_csr(cols, vals):
    """CSR arrays (indptr, indices, values) of rows given as (rows x width) column and value arrays, with the
    entries of a row that hit the same column summed and columns sorted.

    Rows whose columns already increase strictly (all rows of a shift stencil away from the folding points
    xi = 0, pi) are copied as they are; only the others are sorted and merged. O(n w), no global sort.
    """
    cols = np.asarray(cols, dtype=np.int64)
    vals = np.broadcast_to(np.asarray(vals, dtype=float), cols.shape)
    nrows, width = cols.shape
    good = (np.diff(cols, axis=1) > 0).all(axis=1)
    bad = np.flatnonzero(~good)
    counts = np.full(nrows, width, dtype=np.int64)
    if len(bad):
        bcols, bvals = cols[bad], vals[bad]
        order = np.argsort(bcols, axis=1, kind="stable")
        bcols = np.take_along_axis(bcols, order, axis=1)
        bvals = np.take_along_axis(bvals, order, axis=1)
        first = np.ones(bcols.shape, dtype=bool)
        first[:, 1:] = bcols[:, 1:] != bcols[:, :-1]
        group = np.cumsum(first.ravel()) - 1
        bvalues = np.bincount(group, weights=bvals.ravel(), minlength=group[-1] + 1)
        bcount = first.sum(axis=1)
        counts[bad] = bcount
        bindices = bcols[first]
    indptr = np.concatenate([[0], np.cumsum(counts)])
    indices = np.empty(indptr[-1], dtype=np.int64)
    values = np.empty(indptr[-1])
    if len(bad) < nrows:
        pos = (indptr[:-1][good][:, None] + np.arange(width)[None, :]).ravel()
        indices[pos] = cols[good].ravel()
        values[pos] = vals[good].ravel()
    if len(bad):
        starts = np.repeat(indptr[bad], bcount)
        within = np.arange(len(bindices)) - np.repeat(np.cumsum(bcount) - bcount, bcount)
        indices[starts + within] = bindices
        values[starts + within] = bvalues
    return indptr.astype(PETSc.IntType), indices.astype(PETSc.IntType), values


class RowAssembler:
    """CSR assembly of matrices whose rows are linear combinations of stencil entries.

    ``blocks`` is a list of (rows x width) global column arrays; entries of a row that hit the same column are
    summed. The pattern is fixed at construction; :meth:`values` maps per-entry values (same shapes) to the
    CSR value array, and :meth:`create`/:meth:`update` build or refill a parallel AIJ matrix.
    """

    def __init__(self, grid, blocks):
        self.grid = grid
        nrows = grid.rend - grid.rstart
        cols = np.concatenate([np.asarray(b, dtype=np.int64).reshape(nrows, -1) for b in blocks], axis=1)
        width = cols.shape[1]
        # sort each (short) row, merge repeated columns: O(n w log w), no global sort
        order = np.argsort(cols, axis=1, kind="stable")
        cols = np.take_along_axis(cols, order, axis=1)
        first = np.ones(cols.shape, dtype=bool)
        first[:, 1:] = cols[:, 1:] != cols[:, :-1]
        self.entry_to_csr = np.empty(nrows * width, dtype=np.int64)
        self.entry_to_csr[(np.arange(nrows, dtype=np.int64)[:, None] * width + order).ravel()] = \
            np.cumsum(first.ravel()) - 1
        self.indices = cols[first].astype(PETSc.IntType)
        self.indptr = np.concatenate([[0], np.cumsum(first.sum(axis=1))]).astype(PETSc.IntType)
        self.nnz = len(self.indices)

    def values(self, blocks):
        flat = np.concatenate([np.asarray(b, dtype=float).reshape(len(self.indptr) - 1, -1) for b in blocks],
                              axis=1).ravel()
        return np.bincount(self.entry_to_csr, weights=flat, minlength=self.nnz)

    def create(self, blocks):
        g = self.grid
        nloc = g.rend - g.rstart
        mat = PETSc.Mat().create(comm=g.comm)
        mat.setSizes(((nloc, g.size), (nloc, g.size)))
        mat.setType(PETSc.Mat.Type.AIJ)
        mat.setPreallocationCSR((self.indptr, self.indices, self.values(blocks)))
        mat.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        mat.setOption(PETSc.Mat.Option.NO_OFF_PROC_ENTRIES, True)      # rows are owned: no stash exchange
        mat.assemble()
        return mat

    def update(self, mat, blocks):
        mat.setValuesCSR(self.indptr, self.indices, self.values(blocks))
        mat.assemble()
