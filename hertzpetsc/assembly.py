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


def _merge_pattern(cols):
    """(entry -> CSR position, indices, indptr) of rows with the given (rows x width) columns: each (short) row
    sorted, repeated columns merged; O(n w log w), no global sort."""
    order = np.argsort(cols, axis=1, kind="stable")
    cols = np.take_along_axis(cols, order, axis=1)
    first = np.ones(cols.shape, dtype=bool)
    first[:, 1:] = cols[:, 1:] != cols[:, :-1]
    where = np.empty(cols.size, dtype=np.int64)
    where[(np.arange(len(cols), dtype=np.int64)[:, None] * cols.shape[1] + order).ravel()] = \
        np.cumsum(first.ravel()) - 1
    indptr = np.concatenate([[0], np.cumsum(first.sum(axis=1))]).astype(PETSc.IntType)
    return where, cols[first].astype(PETSc.IntType), indptr


def merged_csr(cols, vals):
    """CSR arrays (indptr, indices, values) of rows given as (rows x width) column and value arrays, with the
    entries of a row that hit the same column summed and columns sorted."""
    cols = np.asarray(cols, dtype=np.int64)
    where, indices, indptr = _merge_pattern(cols)
    vals = np.broadcast_to(np.asarray(vals, dtype=float), cols.shape).ravel()
    return indptr, indices, np.bincount(where, weights=vals, minlength=len(indices)).astype(float, copy=False)


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
        self.entry_to_csr, self.indices, self.indptr = _merge_pattern(cols)
        self.nnz = len(self.indices)

    def values(self, blocks):
        flat = np.concatenate([np.asarray(b, dtype=float).reshape(len(self.indptr) - 1, -1) for b in blocks],
                              axis=1).ravel()
        return np.bincount(self.entry_to_csr, weights=flat, minlength=self.nnz)

    def create(self, blocks):
        g = self.grid
        n = (g.rend - g.rstart, g.size)
        mat = PETSc.Mat().createAIJ((n, n), csr=(self.indptr, self.indices, self.values(blocks)), comm=g.comm)
        mat.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        mat.setOption(PETSc.Mat.Option.NO_OFF_PROC_ENTRIES, True)      # rows are owned: no stash exchange
        mat.assemble()
        return mat

    def update(self, mat, blocks):
        mat.setValuesCSR(self.indptr, self.indices, self.values(blocks))
        mat.assemble()
