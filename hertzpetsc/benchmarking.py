"""Helpers for the benchmark scripts: run a worker in its own process (optionally under mpiexec) and keep the
best of several repeats. Wall times are measured inside the worker, around the computation only."""
import json
import os
import resource
import subprocess
import sys


def peak_rss_mb():
    """This process's peak resident set size in MB (Linux reports KB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def launch(script, args, ranks=None, timeout=3600):
    """Run ``python script args`` (under ``mpiexec -n ranks`` if ranks), return its last stdout line as JSON,
    or None if it ran out of time. MPI runs get one OpenBLAS/OpenMP thread per rank (idle library threads
    otherwise spin on the cores the ranks need); serial runs (the SciPy routes) keep the library defaults."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = [sys.executable, script, *map(str, args)]
    if ranks:
        cmd = ["mpiexec", "-n", str(ranks), *cmd]
        env.update(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    r = subprocess.run(["timeout", str(timeout), *cmd], capture_output=True, text=True, env=env)
    if r.returncode == 124:
        return None
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {r.stderr.strip()[-800:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def best_of(repeats, script, args, ranks=None, timeout=3600):
    """The run with the smallest ``wall`` among ``repeats`` runs (None if one timed out)."""
    runs = []
    for _ in range(repeats):
        res = launch(script, args, ranks, timeout)
        if res is None:
            return None
        runs.append(res)
    return min(runs, key=lambda r: r["wall"])


def emit(comm=None, **fields):
    """Print a worker's result as one JSON line on rank 0, with every rank's peak memory (``rss_mb``).

    ``comm`` is an mpi4py communicator (None for a serial worker)."""
    rss = comm.gather(peak_rss_mb(), root=0) if comm is not None else [peak_rss_mb()]
    if comm is None or comm.rank == 0:
        print(json.dumps(dict(rss_mb=rss, **fields)), flush=True)


def write_report(path, lines):
    """Write a benchmark's table (a list of lines) to ``path`` atomically and print it."""
    text = "\n".join(lines) + "\n"
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path + ".tmp", "w") as f:
        f.write(text)
    os.replace(path + ".tmp", path)
    print(text)
