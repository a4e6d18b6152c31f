"""Sparse assembly on a :class:`~hertzpetsc.grid.ProfileGrid`: gathering the values long-range stencils need,
and CSR matrices whose rows are combinations of stencil entries (the advance-delay and solitary-wave Jacobians).

The values a rank needs for a set of stencils are fetched by one VecScatter built once (:class:`StencilGather`);
rows are assembled without any global sort (:func:`merged_csr`, :class:`RowAssembler`).
"""
import numpy as np
from petsc4py import PETSc


def gathered(V):
    """The whole Vec ``V`` as a numpy array on every rank (collective)."""
    scatter, full = PETSc.Scatter.toAll(V)
    try:
        scatter.scatter(V, full, PETSc.InsertMode.INSERT_VALUES, PETSc.ScatterMode.FORWARD)
        return full.getArray(readonly=True).copy()
    finally:
        scatter.destroy()
        full.destroy()


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
