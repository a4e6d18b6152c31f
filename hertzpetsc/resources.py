"""Memory and time a run needs, checked before anything is allocated or computed.

A request that would not fit (a grid too fine for the machine) is refused up front with
:class:`~hertzpetsc.errors.ParameterError`, naming cells_per_pi, the estimated memory and the largest grid that
fits, instead of being killed by the kernel part-way. The estimates are per unknown, measured as peak resident
memory (results/bench_newton.md) with a safety margin, plus a fixed per-process cost (Python, numpy, PETSc, MPI).
Likewise a run whose estimated computing time exceeds a limit (:func:`check_work`: -max_hours, default
:data:`DEFAULT_MAX_HOURS`) is refused with the estimate, from costs per unit of work measured once (the constants
below say where).
"""
import math
import os

from petsc4py import PETSc

from .errors import ParameterError, check_real

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


def physical_memory():
    """The machine's physical memory, bytes (the same on every rank of one machine, unlike what is available)."""
    return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))


def check_chain_size(N, columns=1, name="N"):
    """Raise :class:`ParameterError` naming ``name`` if a chain of N beads carrying ``columns`` state columns has
    more unknowns than PETSc's index type counts, or needs more than the machine's physical memory (local and
    deterministic: no collective, the same verdict on every rank; :func:`check_chain_memory` is the finer check
    against the memory available)."""
    N, columns = int(N), int(columns)
    if 2 * N * columns > MAX_UNKNOWNS:
        raise ParameterError(name, N, f"gives {2 * N * columns} unknowns ({columns} column(s)), more than PETSc's "
                             f"index type allows ({MAX_UNKNOWNS})")
    total = BYTES_PER_BEAD_COLUMN * N * columns
    if total > physical_memory():
        raise ParameterError(name, N, f"a chain of {N} beads with {columns} column(s) needs about {total / GIB:.1f} "
                             f"GiB, more than this machine's {physical_memory() / GIB:.1f} GiB")


def check_chain_memory(N, comm=None, columns=1, name="N", available=None):
    """Raise :class:`ParameterError` naming ``name`` if a chain of N beads carrying ``columns`` state columns (the
    state plus tangents) would not fit in memory or in PETSc's index type. Collective on ``comm``."""
    comm, available = _shared_memory(comm, available)
    N, columns = int(N), int(columns)
    check_chain_size(N, columns, name)
    total = PROCESS_BYTES * comm.getSize() + BYTES_PER_BEAD_COLUMN * N * columns
    if total > USABLE_FRACTION * available:
        fits = int((USABLE_FRACTION * available - PROCESS_BYTES * comm.getSize()) / (BYTES_PER_BEAD_COLUMN * columns))
        raise ParameterError(name, N, f"a chain of {N} beads with {columns} column(s) needs about {total / GIB:.1f} "
                             f"GiB but {available / GIB:.1f} GiB are available: at most {max(fits, 0)} beads")
    return total


# --- work: a run estimated to take hours beyond the limit is refused before it computes ----------------------------
# The limit (hours of computing on the reference machine, 2 cores) of the estimates below; drivers set it from
# -max_hours (0: none), Python from set_work_limit. The documented commands take at most about 20 minutes each.
DEFAULT_MAX_HOURS = 6.0
# Seconds per bead and unit of time of the chain's state flow (adaptive RK 8(7), rtol 1e-12, RMS error norm, one
# rank): 0.275 s for 10^4 beads over script-T = 1.2010 at q = 3 pi/10, 84 steps (results/bench_chain.md, 2026-11-22,
# idle machine). Tighter flows take more steps per unit of time (e.g. the compacton dynamics' max-norm flows at rtol
# 1e-13: 7.8e-5, results/compacton_dynamics.md), driven chains at low frequencies fewer.
CHAIN_SECONDS = 2.3e-5
# Seconds of one integration call beyond its steps (TS set-up, Python): 12 us per call at N = 20 (5000 calls of one
# step each, best of 5; measured 2026-12-06 on the shared machine under load: an upper bound).
INTEGRATE_SECONDS = 1.2e-5

_work_limit = DEFAULT_MAX_HOURS


def set_work_limit(hours):
    """The limit (hours) of :func:`check_work`; 0 or inf: none. Drivers set it from -max_hours."""
    global _work_limit
    hours = math.inf if hours == 0 or hours == math.inf else check_real("max_hours", hours, "the computing-time "
                                                                         "limit in hours (0: none)", 0.0)
    _work_limit = hours
    return hours


def work_limit():
    """The limit (hours) of :func:`check_work` (inf: none)."""
    return _work_limit


def chain_seconds(beads, time, per_bead=CHAIN_SECONDS):
    """The estimated seconds of state flows of ``beads`` beads (summed over the flows) over ``time`` units of time
    (summed likewise): per_bead (seconds per bead and unit of time, :data:`CHAIN_SECONDS`) x beads x time."""
    return per_bead * float(beads) * float(time)


def _duration(seconds):
    return f"{seconds / 3600:.3g} hours" if seconds >= 3600 else f"{seconds / 60:.3g} minutes"


def check_work(name, value, seconds, what):
    """Raise :class:`ParameterError` naming ``name`` (whose ``value`` makes the run long) when the estimated
    ``seconds`` of ``what`` (the work, in words) exceed the limit (:func:`set_work_limit`, -max_hours); local and
    deterministic: every rank given the same arguments decides alike."""
    if seconds > _work_limit * 3600.0:
        raise ParameterError(name, value, f"{what} would take about {_duration(seconds)} of computing (estimated "
                             f"from measured costs), more than the limit of {_work_limit:g} hours: -max_hours H "
                             "raises it (0: none; hertzpetsc.resources.set_work_limit in Python)")
    return seconds
