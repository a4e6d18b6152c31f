"""The benchmark harness beside the benchmark scripts (not part of the installed package).

A benchmark script has two faces. Its command line is the options database, like every driver (``python
scripts/bench_x.py -repeats 3 -output ...``). Each measurement runs in a process of its own, started by
:func:`best_of` as ``python scripts/bench_x.py -worker NAME 'JSON request' [PETSc options]`` (under ``mpiexec -n
ranks`` for hertzpetsc routes, with one OpenBLAS/OpenMP thread per rank); :func:`worker_request` recognises that
form before PETSc is initialised (SciPy workers never import it), and the worker prints its result as one JSON
line (:func:`emit`, wall time measured inside the worker around the computation, peak memory per rank).

Results are kept in a record store (:class:`BenchRecords`), one record per measurement, so a killed benchmark
resumes with ``-resume``; the table is rendered from the records at the end.
"""
import json
import os
import platform
import resource
import sys
import tempfile
import time

import numpy as np

WORKER = "-worker"
MAX_CHAIN = 10 ** 7          # beads of a benchmark chain (the SciPy routes hold dense blocks of it)


def worker_request(argv):
    """(name, request dict, PETSc options) when this process is a benchmark worker, else None."""
    if len(argv) >= 4 and argv[1] == WORKER:
        return argv[2], json.loads(argv[3]), argv[4:]
    return None


def peak_rss_mb():
    """This process's peak resident set size in MB (Linux reports KB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def emit(comm=None, **fields):
    """Print a worker's result as one JSON line on rank 0, with every rank's peak memory (``rss_mb``).

    ``comm`` is an mpi4py communicator (None for a serial worker)."""
    rss = comm.gather(peak_rss_mb(), root=0) if comm is not None else [peak_rss_mb()]
    if comm is None or comm.rank == 0:
        print(json.dumps(dict(rss_mb=rss, **fields), default=float), flush=True)


def launch(script, name, request, ranks=None, timeout=3600, petsc_args=(), package=None):
    """Run one worker (under ``mpiexec -n ranks`` if ranks), return its JSON result, or None if it ran out of
    time. Every worker gets one OpenBLAS/OpenMP thread per process, the SciPy routes too (idle library threads
    otherwise spin on the cores the ranks need; hertzpetsc.start sets it for the benchmark and its children unless the
    user set OPENBLAS_NUM_THREADS / OMP_NUM_THREADS). ``package``: a checkout whose
    ``hertzpetsc`` the worker imports instead of this one (another release, measured side by side)."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_ess_singleton_isolated="1", OMPI_MCA_orte_execute_quiet="1")
    if package:
        env["PYTHONPATH"] = os.path.abspath(package) + os.pathsep + env.get("PYTHONPATH", "")
    cmd = [sys.executable, script, WORKER, name, json.dumps(request), *map(str, petsc_args)]
    if ranks:
        cmd = ["mpiexec", "-n", str(ranks), *cmd]
        env.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    from hertzpetsc.options import run_child          # the worker's group ends with this process (no orphans)
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        rc = run_child(cmd, out=out, err=err, env=env, timeout=timeout)
        out.seek(0)
        err.seek(0)
        stdout, stderr = out.read(), err.read()
    if rc == 124:
        return None
    if rc != 0:
        from hertzpetsc.errors import HertzPetscError
        last = [line for line in stderr.splitlines() if line.strip()][-1:] or ["no message"]
        failure = HertzPetscError(f"benchmark worker {name} ({os.path.basename(script)}, {ranks or 1} rank(s)) "
                                  f"failed with exit status {rc}: {last[0].strip()}")
        failure.exit_status = rc if 0 < rc < 126 else 1
        raise failure
    return json.loads(stdout.strip().splitlines()[-1])


def best_of(repeats, script, name, request, ranks=None, timeout=3600, petsc_args=(), package=None):
    """The run with the smallest ``wall`` among ``repeats`` runs (None if one timed out)."""
    runs = []
    for _ in range(repeats):
        res = launch(script, name, request, ranks, timeout, petsc_args, package)
        if res is None:
            return None
        runs.append(res)
    return min(runs, key=lambda r: r["wall"] if r.get("wall") is not None else float("inf"))


def machine(repeats=None):
    """The machine line of a report: cores, processor, load average, date."""
    load = " ".join(f"{v:.2f}" for v in os.getloadavg())
    best = f"best of {repeats}; " if repeats else ""
    return (f"{best}Machine: {os.cpu_count()} cores, {platform.processor() or platform.machine()}; load average "
            f"(1, 5, 15 min) at start {load}; {time.strftime('%Y-%m-%d %H:%M')}")


class BenchRecords:
    """The measurements of one benchmark run as records (key, JSON result): with a ``path`` they are kept in a
    record store as they are taken, so a killed benchmark resumes (``mode='resume'``); without, in memory only."""

    def __init__(self, path, kind, identity, mode="new"):
        self.store, self.done = None, {}
        if path:
            from hertzpetsc.records import NpzRecords
            ident = json.dumps(identity, sort_keys=True)
            self.store = NpzRecords(path, kind, dict(identity=ident), dict(identity=ident), ("key", "result"), None,
                                    mode, dtypes={"key": np.str_, "result": np.str_}, what="benchmark records")
            self.done = {str(r["key"]): json.loads(str(r["result"])) for r in self.store.records}

    def measure(self, key, run):
        """The result stored under ``key``, or ``run()``'s (stored at once). None (a time-out) is stored too."""
        if key not in self.done:
            result = run()
            if result is not None:
                result = dict(result, load=os.getloadavg()[0], when=time.strftime("%Y-%m-%d %H:%M"))
            self.done[key] = result
            if self.store is not None:
                self.store.append(dict(key=key, result=json.dumps(result, default=float)))
        return self.done[key]


def declare_chains(opts, sizes, multiple, why):
    """-branch (the branch file of the waves) and -sizes (chain lengths, multiples of ``multiple``)."""
    branch = opts.path("branch", "results/branch_alpha1.5.npz", "branch file")
    return branch, opts.numbers("sizes", sizes, f"chain lengths (multiples of {multiple})", expr=False, kind=int,
                                valid=(lambda N: multiple <= N <= MAX_CHAIN and N % multiple == 0,
                                       f"a multiple of {multiple} ({why}), at most {MAX_CHAIN}"),
                                distinct=True)


def declare_common(opts, output, repeats=3):
    """The options every benchmark has: -output, -repeats, -records (with -resume / -force)."""
    out = opts.path("output", output, "table")
    reps = opts.integer("repeats", repeats, "repeats of each hertzpetsc measurement (the best is kept)", minimum=1)
    records = opts.path("records", "", "record file of the measurements, for -resume (none if empty)")
    mode = opts.mode()
    if not opts.help:                                  # the table is written at the end: know now that it can be
        from hertzpetsc.records import prepare_output
        prepare_output(out, None, "benchmark table")
    return out, reps, records, mode


def write_report(path, lines, comm=None):
    """Write a benchmark's table (a list of lines) atomically and print it."""
    from hertzpetsc.records import write_text
    text = "\n".join(lines) + "\n"
    write_text(path, text, comm, "benchmark table")
    print(text, flush=True)


def main_or_worker(main, worker):
    """The entry point of a benchmark script: run ``worker(name, request, petsc_args)`` when launched as a worker,
    else initialise PETSc with the command line and run ``main`` as a driver (one-line errors)."""
    request = worker_request(sys.argv)
    if request:
        worker(*request)
        return
    from hertzpetsc.start import init_petsc
    init_petsc(sys.argv)
    from hertzpetsc.options import guarded_main
    guarded_main(main)
