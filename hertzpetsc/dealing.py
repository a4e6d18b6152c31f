"""Independent computations dealt to the ranks of a communicator, each run on one rank, results gathered in rounds.

A scan over wavenumbers whose computations are independent (refinements, spectra by symmetry) runs each one on a
single rank (``PETSc.COMM_SELF``): no communication inside a computation, and the same arithmetic whatever the
number of ranks, so the results do not depend on it at all. The items are dealt by the longest-processing-time
rule on estimated costs; after each round every rank has every result of the round (an allgather), so that rank 0
can record them as they come. An error on one rank is passed to every rank in the same round, so all raise it.
"""
from .errors import HertzPetscError
from .records import _rebuild, _sent


def lpt_plan(costs, size):
    """For each rank, the indices of the items it computes (largest estimated cost first, each item to the least
    loaded rank)."""
    plan, load = [[] for _ in range(size)], [0.0] * size
    for i in sorted(range(len(costs)), key=lambda i: -costs[i]):
        r = min(range(size), key=lambda r: load[r])
        plan[r].append(i)
        load[r] += costs[i]
    return plan


def dealt(items, costs, comm, compute):
    """Yield (item, result) for every item, ``result = compute(item)`` run on one rank; collective on ``comm``."""
    size, rank = comm.getSize(), comm.getRank()
    plan = lpt_plan(costs, size)
    mpi = comm.tompi4py() if size > 1 else None
    for r in range(max((len(p) for p in plan), default=0)):
        mine = plan[rank][r] if r < len(plan[rank]) else None
        result = None
        if mine is not None:
            try:
                result = (mine, compute(items[mine]), None)
            except HertzPetscError as err:
                if mpi is None:
                    raise
                result = (mine, None, _sent(err))
        done = mpi.allgather(result) if mpi is not None else [result]
        failed = [entry[2] for entry in done if entry is not None and entry[2] is not None]
        if failed:
            raise _rebuild(*failed[0])
        for entry in done:
            if entry is not None:
                yield items[entry[0]], entry[1]
