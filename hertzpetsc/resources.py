"""Memory needed by the travelling-wave solvers, checked before anything is allocated.

A request that would not fit (a grid too fine for the machine) is refused up front with
:class:`~hertzpetsc.errors.ParameterError`, naming cells_per_pi, the estimated memory and the largest grid that
fits, instead of being killed by the kernel part-way. The estimates are per unknown, measured as peak resident
memory (results/bench_newton.md) with a safety margin, plus a fixed per-process cost (Python, numpy, PETSc, MPI).
"""
import os

from petsc4py import PETSc

from .errors import ParameterError

GIB = 2.0 ** 30
# fixed cost of one process (interpreter, numpy, petsc4py, MPI), bytes
PROCESS_BYTES = 150e6
# peak bytes per unknown over all ranks, measured (results/bench_newton.md, bench_branch.md) plus ~50 % margin:
# 'nk' (stencil arrays, the stacked shift matrix T, GMRES basis, tridiagonal factor; 650 B measured) and
# 'direct' (LU fill of the long-range shifts, up to ~4 kB measured along the branch)
BYTES_PER_UNKNOWN = {"nk": 1000.0, "direct": 6000.0}
# fraction of the available memory a run may plan to use
USABLE_FRACTION = 0.9
# PETSc's index type bounds the number of unknowns
MAX_UNKNOWNS = int(2 ** (8 * PETSc.IntType(0).itemsize - 1) - 1)


def available_memory():
    """Memory available to new processes, bytes (MemAvailable of /proc/meminfo, else physical memory)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))


def _shared_memory(comm, available):
    """(``comm`` or COMM_WORLD, ``available`` or rank 0's :func:`available_memory` on every rank). Collective."""
    comm = comm if comm is not None else PETSc.COMM_WORLD
    if available is None:
        available = available_memory()
        if comm.getSize() > 1:
            available = comm.tompi4py().bcast(available, root=0)
    return comm, available


def estimate_memory(cells_per_pi, ranks, solver="nk", profiles=1):
    """(bytes per rank, bytes in total) for a travelling-wave solve with p (K - 1) unknowns (p = ``profiles``, the
    mass pattern's length) on ``ranks`` ranks."""
    if solver not in BYTES_PER_UNKNOWN:
        raise ParameterError("solver", solver, "must be one of " + ", ".join(BYTES_PER_UNKNOWN))
    unknowns = max(int(cells_per_pi) - 1, 0) * int(profiles)
    per_rank = PROCESS_BYTES + BYTES_PER_UNKNOWN[solver] * unknowns / ranks
    return per_rank, per_rank * ranks


def check_memory(cells_per_pi, comm=None, solver="nk", available=None, profiles=1, name="cells_per_pi"):
    """Raise :class:`ParameterError` (naming cells_per_pi) if the grid would not fit on this machine.

    All ranks of ``comm`` are assumed to share one machine's memory (the ranks of a run on this 2-core box);
    rank 0's figure of the available memory is used on every rank, so all ranks agree. Collective on ``comm``.
    """
    comm, available = _shared_memory(comm, available)
    ranks = comm.getSize()
    K = int(cells_per_pi)
    if profiles * (K - 1) + 2 > MAX_UNKNOWNS:
        limit = (MAX_UNKNOWNS - 2) // profiles + 1
        raise ParameterError(name, cells_per_pi, f"gives {profiles * (K - 1)} unknowns, more than PETSc's "
                             f"index type allows ({MAX_UNKNOWNS}): must be <= {limit}")
    per_rank, total = estimate_memory(K, ranks, solver, profiles)
    usable = USABLE_FRACTION * available
    if total > usable:
        k_max = int((usable / ranks - PROCESS_BYTES) * ranks / BYTES_PER_UNKNOWN[solver] / profiles) + 1
        fits = f"must be <= {k_max}" if k_max >= 4 else "no grid fits"
        raise ParameterError(name, cells_per_pi,
                             f"needs about {total / GIB:.1f} GiB ({per_rank / GIB:.2f} GiB on each of {ranks} "
                             f"rank(s), solver '{solver}') but {available / GIB:.1f} GiB are available: {fits} "
                             "on this machine")
    return per_rank, total


# beads of a chain whose dense monodromy or Gauss-Newton Jacobian ((2N)^2 doubles: 0.8 GB at 5000) is formed
MAX_DENSE_BEADS = 5000
# bytes per bead and per state column (x, xdot) of a chain integrated by TS: the state and about 20 RK work vectors
BYTES_PER_BEAD_COLUMN = 2 * 8 * 24


def check_chain_memory(N, comm=None, columns=1, name="N", available=None):
    """Raise :class:`ParameterError` naming ``name`` if a chain of N beads carrying ``columns`` state columns (the
    state plus tangents) would not fit in memory or in PETSc's index type. Collective on ``comm``."""
    comm, available = _shared_memory(comm, available)
    N, columns = int(N), int(columns)
    if 2 * N * columns > MAX_UNKNOWNS:
        raise ParameterError(name, N, f"gives {2 * N * columns} unknowns, more than PETSc's index type allows "
                             f"({MAX_UNKNOWNS})")
    total = PROCESS_BYTES * comm.getSize() + BYTES_PER_BEAD_COLUMN * N * columns
    if total > USABLE_FRACTION * available:
        fits = int((USABLE_FRACTION * available - PROCESS_BYTES * comm.getSize()) / (BYTES_PER_BEAD_COLUMN * columns))
        raise ParameterError(name, N, f"a chain of {N} beads with {columns} column(s) needs about {total / GIB:.1f} "
                             f"GiB but {available / GIB:.1f} GiB are available: at most {max(fits, 0)} beads")
    return total
