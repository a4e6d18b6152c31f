"""Shared fixtures and helpers. The suite runs serially and again under ``mpiexec -n 2`` (tests marked ``serial``
skip there); tests that compare 1 and 2 ranks do so within one process via COMM_SELF vs COMM_WORLD, or launch
mpiexec themselves (serial-marked, with a timeout)."""
import atexit
import functools
import math
import os
import shutil
import subprocess
import sys
import tempfile

import hertzpetsc.start  # noqa: F401  (one BLAS thread per process, as in the drivers)
import pytest
from petsc4py import PETSc

from hertzpetsc.branch import Branch
from hertzpetsc.qbranch import BranchContinuation, ContinuationParameters
from hertzpetsc.model import ChainSpec, LatticeModel

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPTS = os.path.join(ROOT, "scripts")
# the results files the tests read: frozen copies (tests/data/make_fixtures.py), never results/, which the documented
# commands rewrite
DATA = os.path.join(ROOT, "tests", "data")


def pytest_collection_modifyitems(config, items):
    if PETSc.COMM_WORLD.getSize() > 1:
        skip = pytest.mark.skip(reason="serial-only test (launches its own processes)")
        for item in items:
            if "serial" in item.keywords:
                item.add_marker(skip)


def shared_tmp(tmp_path):
    """One directory for every rank (rank 0's pytest tmp_path), for files a study writes on one rank and reads on all."""
    return PETSc.COMM_WORLD.tompi4py().bcast(str(tmp_path), root=0)


def script_env():
    # A process that imported petsc4py must hand its environment explicitly to mpiexec children.
    env = dict(os.environ)
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", OMPI_MCA_ess_singleton_isolated="1",
               OMPI_MCA_orte_execute_quiet="1", MPLBACKEND="Agg")
    env.pop("HZ_TRACEBACK", None)
    env["PYTHONPATH"] = ROOT + os.pathsep + env.get("PYTHONPATH", "")
    return env


@functools.lru_cache(maxsize=None)
def checkout():
    """A directory laid out as a checkout for the drivers the tests run: its ``results/`` holds links to the test
    data (tests/data), so that a driver's default input (results/branch_alpha1.5.npz, ...) is the test's copy, never
    the repository's results, and its default outputs (runs/) land here."""
    path = tempfile.mkdtemp(prefix="hz-checkout-")
    atexit.register(shutil.rmtree, path, True)
    os.mkdir(os.path.join(path, "results"))
    for name in os.listdir(DATA):
        if name.endswith((".npz", ".md")):
            os.symlink(os.path.join(DATA, name), os.path.join(path, "results", name))
    return path


def run_script(name, *args, ranks=1, timeout=300, cwd=None):
    """Run scripts/<name> (under ``mpiexec -n ranks`` if ranks > 1, always with a timeout) in ``cwd``, by default in
    :func:`checkout`."""
    cmd = [sys.executable, os.path.join(SCRIPTS, name), *map(str, args)]
    if ranks > 1:
        cmd = ["mpiexec", "-n", str(ranks), *cmd]
    return subprocess.run(["timeout", str(timeout), *cmd], capture_output=True, text=True, env=script_env(),
                          cwd=cwd or checkout())


def one_error_line(result):
    """The stderr of a failed driver is one line starting with 'error:' (returned without the prefix)."""
    lines = result.stderr.strip().splitlines()
    assert result.returncode != 0 and len(lines) == 1 and lines[0].startswith("error:"), result.stderr
    return lines[0]


@functools.lru_cache(maxsize=None)
def _branch(alpha, K, M, q_stop, size):
    comm = PETSc.COMM_SELF
    params = ContinuationParameters(alpha=alpha, M=M, cells_per_pi=K, q_stop=q_stop)
    cont = BranchContinuation(params, comm)
    try:
        points = list(cont.points())
    finally:
        cont.destroy()
    return Branch(params.model, K, M, points)


def small_branch(alpha=1.5, K=200, M=10, q_stop=math.pi / 5):
    """A coarse branch (h = pi/K, q = m pi / M down to q_stop) on one rank, computed once per session."""
    return _branch(alpha, K, M, q_stop, PETSc.COMM_WORLD.getSize())


def refine(orbit, comm, tol=1e-10, **kwargs):
    """One-off Gauss-Newton refinement of ``orbit`` (hertzpetsc.shooting.Refiner)."""
    from hertzpetsc.shooting import Refiner
    with Refiner(orbit.spec, comm, tol, **kwargs) as refiner:
        return refiner.refine(orbit)


def dense_monodromy(orbit, comm, tolerances, shift=True, T=None):
    """One-off dense S R(T; 0) (hertzpetsc.floquet.DenseFloquet)."""
    from hertzpetsc.floquet import DenseFloquet
    with DenseFloquet(orbit.spec, comm, tolerances) as dense:
        return dense.monodromy(orbit, shift, T)


def chain(N, alpha=1.5, boundary="periodic"):
    return ChainSpec(LatticeModel.hertz(alpha), N, boundary)


@pytest.fixture
def clean_options():
    """Delete any option a test inserts into the (process-global) PETSc options database."""
    opts = PETSc.Options()
    before = set(opts.getAll())
    yield opts
    for key in set(opts.getAll()) - before:
        opts.delValue(key)


def chain_arrays(spec, x, t=0.0, eps=1e-7):
    """(f, dense Jacobian, forward differences of step eps, compiled kernel or None) of the chain's right-hand side at
    the (N, 2) state x."""
    import numpy as np
    from hertzpetsc.chain import Chain
    comm = PETSc.COMM_WORLD
    ch = Chain(spec, comm)
    X, F, G = ch.create_state(), ch.create_state(), ch.create_state()
    J = ch.create_jacobian()
    try:
        ch.set_from_array(X, x)
        ch.rhs(None, t, X, F)
        f0 = ch.gather(F).ravel()
        ch.rhs_jacobian(None, t, X, J, J)
        n = 2 * spec.N
        dense = np.zeros((n, n))
        lo, hi = J.getOwnershipRange()
        dense[lo:hi] = J.getValues(np.arange(lo, hi, dtype=PETSc.IntType), np.arange(n, dtype=PETSc.IntType))
        dense = comm.tompi4py().allreduce(dense)
        fd = np.zeros_like(dense)
        for k in range(n):
            e = np.asarray(x, float).ravel().copy()
            e[k] += eps
            ch.set_from_array(X, e.reshape(-1, 2))
            ch.rhs(None, t, X, G)
            fd[:, k] = (ch.gather(G).ravel() - f0) / eps
        return f0, dense, fd, ch.kernel
    finally:
        for v in (X, F, G, J):
            v.destroy()
        ch.destroy()


def resolvent_differences(flow, x0, T, h):
    """Central differences of step h of the state flow of a tangent flow (``flow.run`` with no tangents) over [0, T]
    at x0 (N, 2): the finite-difference resolvent, column by column."""
    import numpy as np
    N = x0.shape[0]
    fd = np.zeros((2 * N, 2 * N))
    for j in range(2 * N):
        xs = []
        for s in (1, -1):
            e = x0.ravel().copy()
            e[j] += s * h
            xs.append(flow.run(e.reshape(N, 2), T, np.zeros((N, 2, 2 * N)))[0].ravel())
        fd[:, j] = (xs[0] - xs[1]) / (2 * h)
    return fd


def dense_and_slepc_agree(drive, p, extra=None):
    """The response of ``drive`` at its parameter value p (run in from rest for 10 periods) by the dense bordered
    Newton and by Newton-Krylov agree to 1e-9, both to residual 1e-10; their four dominant multipliers, LAPACK on the
    dense monodromy and SLEPc on the matrix-free one, agree to 1e-8 after a gap of 1e-3 in modulus.
    ``extra(dense, mf, mu_dense)``: the caller's further checks, before the solvers are destroyed."""
    import numpy as np
    from hertzpetsc.driven import PeriodicShooting
    comm = PETSc.COMM_WORLD
    dense = PeriodicShooting(drive, comm)
    mf = PeriodicShooting(drive, comm, jacobian="mf", floquet="slepc", nev=4)
    try:
        x0 = dense.run_in(np.zeros((drive.N, 2)), 10)
        rd, rm = dense.solve_response(x0), mf.solve_response(x0)
        assert rd.residual < 1e-10 and rm.residual < 1e-10
        assert np.max(np.abs(rd.x - rm.x)) < 1e-9 * np.max(np.abs(rd.x))
        mu_d, mu_s = dense.multipliers(x=rd.x, p=p), mf.multipliers(x=rd.x, p=p)
        assert np.abs(mu_d[3]) - np.abs(mu_d[4]) > 1e-3          # a gap after the fourth
        assert np.max(np.abs(np.sort_complex(mu_d[:4]) - np.sort_complex(mu_s[:4]))) < 1e-8
        if extra is not None:
            extra(dense, mf, mu_d)
    finally:
        dense.destroy()
        mf.destroy()
