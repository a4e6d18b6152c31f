"""Shared fixtures. The suite runs serially and again under ``mpiexec -n 2`` (tests marked ``serial`` skip
there); tests that compare 1 and 2 ranks do so within one process via COMM_SELF vs COMM_WORLD, or launch
mpiexec themselves (serial-marked, with a timeout)."""
import os
import subprocess
import sys

import pytest
from petsc4py import PETSc

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPTS = os.path.join(ROOT, "scripts")


def pytest_collection_modifyitems(config, items):
    if PETSc.COMM_WORLD.getSize() > 1:
        skip = pytest.mark.skip(reason="serial-only test (launches its own processes)")
        for item in items:
            if "serial" in item.keywords:
                item.add_marker(skip)


def script_env():
    # A process that imported petsc4py must hand its environment explicitly to mpiexec children.
    env = dict(os.environ)
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", MPLBACKEND="Agg")
    env["PYTHONPATH"] = ROOT + os.pathsep + env.get("PYTHONPATH", "")
    return env


def run_script(name, *args, ranks=1, timeout=300, cwd=None):
    """Run scripts/<name> (under ``mpiexec -n ranks`` if ranks > 1, always with a timeout)."""
    cmd = [sys.executable, os.path.join(SCRIPTS, name), *map(str, args)]
    if ranks > 1:
        cmd = ["mpiexec", "-n", str(ranks), *cmd]
    return subprocess.run(["timeout", str(timeout), *cmd], capture_output=True, text=True, env=script_env(),
                          cwd=cwd)


@pytest.fixture
def clean_options():
    """Delete any option a test inserts into the (process-global) PETSc options database."""
    opts = PETSc.Options()
    before = set(opts.getAll())
    yield opts
    for key in set(opts.getAll()) - before:
        opts.delValue(key)
