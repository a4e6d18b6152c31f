"""The co-moving pencils of :mod:`hertzpetsc.comoving` on SLEPc.

Solver: SLEPc PEP (TOAR), shift-and-invert at a real target z0 = e^{sigma h} (never exactly on an eigenvalue: at
theta = 0, lambda = 0 is one), LU (MUMPS), options prefix ``cm_`` (-cm_pep_*, -cm_st_*, -cm_st_ksp_*, -cm_st_pc_*).
The matrices are AIJ with rows distributed over the communicator. PETSc is real here: for theta other than 0 and
pi the pencil is the real one of twice the size [[Re, -Im], [Im, Re]], whose spectrum is that of theta and -theta;
the eigenvector (x1, x2) tells which (x1 + i x2 lies in the theta problem).
"""
import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc

from .assembly import gathered
from .errors import ConvergenceError, callbacks_raise, check_signals
from .options import inserted_options

COMOVING_PREFIX = "cm_"


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


class ComovingPEP:
    """SLEPc PEP with shift-and-invert for the co-moving pencils (prefix ``cm_``): TOAR, ST sinvert, KSP preonly,
    LU by MUMPS, eigenvalues nearest the target in magnitude, tolerance 1e-13 (defaults; every knob reachable as
    -cm_pep_*, -cm_st_*). A PEP is configured from the options database once per solve (operator sizes change
    between grids); the constructor configures one on a small pencil, so that bad options fail before any work."""

    # MUMPS's workspace estimate can fall short when the target is close to an eigenvalue (INFOG(1) = -9): more
    # room (ICNTL(14), percent), inserted only for the solve and only where the user did not set it
    MUMPS_DEFAULTS = {"st_mat_mumps_icntl_14": "100"}

    def __init__(self, comm, prefix=COMOVING_PREFIX, nev=12, tol=1e-13):
        self.comm, self.prefix, self.tol, self.default_nev = comm, prefix, tol, nev
        probe = self._create()
        self.nev = probe.getDimensions()[0]          # -cm_pep_nev overrides the starting nev
        probe.destroy()

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
        pep.setMonitor(check_signals)          # no Python callback otherwise: a signal ends the solve per iteration
        return pep

    @PETSc.Log.EventDecorator("hz_comoving_pep")
    def solve(self, mats, target, nev, want_vectors=False):
        """(z, vectors): the converged eigenvalues of the real pencil sum z^i mats[i] (scipy CSR) nearest the real
        ``target`` and, when asked, their eigenvectors complete on every rank (else []); at least ``nev`` must
        converge (ConvergenceError otherwise)."""
        As = [aij(A, self.comm) for A in mats]
        with inserted_options(self.prefix, self.MUMPS_DEFAULTS):
            pep = self._create()
            try:
                pep.setOperators(As)
                pep.setTarget(float(target))
                if nev > self.nev:
                    pep.setDimensions(nev=nev, ncv=max(2 * nev + 10, 40))
                with callbacks_raise():
                    pep.solve()
                nconv = pep.getConverged()
                if nconv < min(nev, self.nev):
                    raise ConvergenceError("co-moving PEP (prefix -%s)" % self.prefix, f"{nconv} of {nev} eigenpairs "
                                           f"converged (reason {pep.getConvergedReason()})", target=target)
                vr, vi = As[0].createVecs()
                z, vecs = [], []
                for i in range(nconv):
                    z.append(complex(pep.getEigenpair(i, vr, vi)))
                    if want_vectors:
                        vecs.append(gathered(vr) + 1j * gathered(vi))
                vr.destroy()
                vi.destroy()
            finally:
                pep.destroy()
                for A in As:
                    A.destroy()
        return np.array(z), vecs
