"""Every run can be stopped and every run is bounded (issue 37): SIGINT, SIGTERM and SIGHUP end a driver within
seconds inside one long solver call (the compiled right-hand side called by the TS without Python in between), on 1
and 2 ranks; every chain flow has a step limit; counts that would run for hours are refused before computing."""
import math
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import SCRIPTS, one_error_line, run_script, script_env
from hertzpetsc import kernels, resources
from hertzpetsc.chain import Chain, ChainIntegrator, MIN_STEPS, STEP_LIMIT_FACTOR
from hertzpetsc.errors import ConvergenceError
from hertzpetsc.model import ChainSpec, LatticeModel
from hertzpetsc.records import load_npz

# One period of the drive (2 pi / 0.002 time units) on 3000 beads is one TS solve of minutes (about 20 CPU seconds
# per 600 time units measured): the signal arrives inside it.
LONG_SOLVE = ["-N", "3000", "-omega", "0.002", "-p_end", "0.0021", "-run_in", "1", "-jacobian", "mf", "-floquet",
              "none"]


def _start(cmd, tmp_path, **kwargs):
    """The driver ``cmd`` in a session of its own (SIGINT restored: a shell may have ignored it for background
    jobs), its stdout read by a thread; returns (process, the list its stdout lines go to)."""
    proc = subprocess.Popen(cmd, env=script_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=tmp_path, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL), **kwargs)
    lines = []
    threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True).start()
    return proc, lines


def _signal_inside_the_solve(proc, lines, send, settle=2.0):
    """Wait for the driver's first output line (printed before the run-in starts), give the TS ``settle`` seconds,
    signal it by ``send()``; returns the seconds until it ended (at most 60)."""
    deadline = time.time() + 120
    while not lines and proc.poll() is None and time.time() < deadline:
        time.sleep(0.05)
    assert lines and proc.poll() is None, "the driver did not start its run-in"
    time.sleep(settle)
    assert proc.poll() is None, "the solve ended before the signal"
    t0 = time.time()
    try:
        send()
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    return time.time() - t0


def _ranks(pid, marker):
    """The Python processes below ``pid`` whose command line contains ``marker`` (the ranks of an mpiexec)."""
    found, todo = [], [pid]
    while todo:
        r = subprocess.run(["pgrep", "-P", str(todo.pop())], capture_output=True, text=True)
        for child in map(int, r.stdout.split()):
            todo.append(child)
            try:
                with open(f"/proc/{child}/cmdline", "rb") as f:
                    args = f.read().decode(errors="replace").split("\0")
                if args[0] == sys.executable and any(marker in a for a in args):
                    found.append(child)
            except OSError:
                pass
    return found


@pytest.mark.serial
@pytest.mark.parametrize("signum, status, line", [(signal.SIGTERM, 143, "error: terminated by SIGTERM"),
                                                  (signal.SIGINT, 130, "error: interrupted"),
                                                  (signal.SIGHUP, 129, "error: terminated by SIGHUP")])
def test_a_signal_ends_a_driver_inside_one_long_ts_solve(tmp_path, signum, status, line):
    """The signal arrives while the TS integrates a drive period on the compiled right-hand side: the run ends
    within seconds (not after the solve, minutes later) with the signal's status and one line; the record file it
    opened is complete and no temporary file is left."""
    out = tmp_path / "r.npz"
    proc, lines = _start([sys.executable, os.path.join(SCRIPTS, "driven_response.py"), *LONG_SOLVE, "-output",
                          str(out), "-table", str(tmp_path / "r.md")], tmp_path)
    seconds = _signal_inside_the_solve(proc, lines, lambda: proc.send_signal(signum))
    err = proc.stderr.read()
    assert proc.returncode == status, err
    assert seconds < 10, f"ended {seconds:.1f} s after the signal"
    assert err.strip().splitlines() == [line]
    assert load_npz(str(out), "driven-response file")["format"] == "hertzpetsc-driven-response-1"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.npz"]


@pytest.mark.serial
def test_sigterm_ends_both_ranks_inside_one_long_ts_solve(tmp_path):
    """Under mpiexec -n 2, SIGTERM to the ranks (what a batch scheduler does) inside the distributed TS solve: both
    ranks end within seconds, quietly, and mpiexec passes on their status 143."""
    proc, lines = _start(["timeout", "300", "mpiexec", "-n", "2", sys.executable,
                          os.path.join(SCRIPTS, "driven_response.py"), *LONG_SOLVE, "-output", str(tmp_path / "r.npz"),
                          "-table", str(tmp_path / "r.md")], tmp_path)

    def to_ranks():
        ranks = _ranks(proc.pid, "driven_response.py")
        assert len(ranks) == 2, ranks
        for pid in ranks:
            os.kill(pid, signal.SIGTERM)

    seconds = _signal_inside_the_solve(proc, lines, to_ranks)
    err = proc.stderr.read()
    assert proc.returncode == 143, err
    assert seconds < 15, f"ended {seconds:.1f} s after the signal"
    assert "Traceback" not in err and "internal error" not in err


@pytest.mark.serial
def test_timeout_ends_an_mpiexec_run_inside_one_long_ts_solve(tmp_path):
    """timeout signals its whole process group (mpiexec and the ranks): the run ends within seconds of it, with a
    non-zero status (mpiexec's own when it was signalled too) and no traceback."""
    proc, lines = _start(["mpiexec", "-n", "2", sys.executable, os.path.join(SCRIPTS, "driven_response.py"),
                          *LONG_SOLVE, "-output", str(tmp_path / "r.npz"), "-table", str(tmp_path / "r.md")], tmp_path)
    seconds = _signal_inside_the_solve(proc, lines, lambda: os.killpg(proc.pid, signal.SIGTERM))
    err = proc.stderr.read()
    assert proc.returncode != 0
    assert seconds < 15, f"ended {seconds:.1f} s after the signal"
    assert "Traceback" not in err and "internal error" not in err


NESTED = """
import sys, petsc4py
petsc4py.init(sys.argv)
from petsc4py import PETSc
from slepc4py import SLEPc
from hertzpetsc.chain import Chain, ChainIntegrator
from hertzpetsc.model import ChainSpec, LatticeModel
from hertzpetsc.options import guarded_main

class Flow:
    # a shell operator whose product is a long flow on the compiled right-hand side (a Python callback of SLEPc)
    def __init__(self):
        self.chain = Chain(ChainSpec(LatticeModel.hertz(1.5), 20000), PETSc.COMM_SELF)
        self.integ = ChainIntegrator(self.chain)
    def mult(self, A, x, y):
        x.copy(y)
        y.getArray()[::2] *= 0.1
        print("flow", flush=True)
        self.integ.integrate(y, 0.0, 1e4)

def main():
    flow = Flow()
    n = 2 * flow.chain.spec.N
    A = PETSc.Mat().createPython([n, n], flow, comm=PETSc.COMM_SELF)
    A.setUp()
    eps = SLEPc.EPS().create(comm=PETSc.COMM_SELF)
    eps.setOperators(A)
    eps.setProblemType(SLEPc.EPS.ProblemType.NHEP)
    try:
        eps.solve()
    finally:
        print("finally", flush=True)

guarded_main(main)
"""


@pytest.mark.serial
def test_a_signal_inside_a_flow_inside_a_slepc_product_is_the_signal(tmp_path):
    """SIGTERM inside a compiled flow that a Python shell's product runs for SLEPc: the Terminated raised in the
    callback comes back through SLEPc as itself (not a PETSc error, not an internal error); finally blocks run."""
    proc, lines = _start([sys.executable, "-c", NESTED], tmp_path)
    seconds = _signal_inside_the_solve(proc, lines, lambda: proc.send_signal(signal.SIGTERM), settle=1.0)
    err = proc.stderr.read()
    assert proc.returncode == 143, err
    assert seconds < 10
    assert err.strip().splitlines() == ["error: terminated by SIGTERM"]
    assert lines[-1].strip() == "finally"


@pytest.mark.serial
@pytest.mark.skipif(kernels.status() != "compiled", reason="the compiled kernel is not built")
def test_sigint_in_process_interrupts_the_compiled_flow_and_the_next_flow_runs():
    """In a notebook: Ctrl-C (SIGINT) during a long compiled flow raises KeyboardInterrupt within a step; the flag is
    cleared, so the next flow runs to its end and gives the same state as a flow never interrupted."""
    small = Chain(ChainSpec(LatticeModel.hertz(1.5), 20), PETSc.COMM_SELF)
    spec = ChainSpec(LatticeModel.hertz(1.5), 20000)
    chain = Chain(spec, PETSc.COMM_SELF)
    integ, short = ChainIntegrator(chain), ChainIntegrator(small)
    X, Y = chain.create_state(), small.create_state()
    x = np.zeros((spec.N, 2))
    x[:, 1] = 0.1 * np.sin(2 * np.pi * np.arange(spec.N) / 50)

    def short_flow():
        small.set_from_array(Y, x[:20])
        short.integrate(Y, 0.0, 2.0, dt=short.initial_step)
        return Y.getArray().copy()

    killer = None
    # a notebook's handler (a shell ignores SIGINT for its background jobs, and Python then installs none: the flow
    # would run on for hours)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        before = short_flow()
        chain.set_from_array(X, x)
        t0 = time.time()
        # from another process: a thread of this one would wait for the GIL that the solve holds
        killer = subprocess.Popen(["sh", "-c", f"sleep 0.5; kill -INT {os.getpid()}"])
        with pytest.raises(KeyboardInterrupt):
            integ.integrate(X, 0.0, 1e5, dt=integ.initial_step)
        assert time.time() - t0 < 5
        assert 0.0 < integ.ts.getTime() < 1e5
        assert np.array_equal(short_flow(), before)
    finally:
        signal.signal(signal.SIGINT, previous)
        if killer is not None:
            killer.wait()
        for obj in (X, Y, integ, short, chain, small):
            obj.destroy()


def test_a_flow_whose_step_collapses_fails_within_its_step_limit():
    """A free chain compressed by 1e10 per bond: the adaptive step collapses (to 1e-13); the flow fails with a
    ConvergenceError naming the step limit and the option that raises it, after MIN_STEPS + STEP_LIMIT_FACTOR
    (t1 - t0) / dt0 steps (a fraction of a second), not after hours; -chain_ts_max_steps sets another limit."""
    spec = ChainSpec(LatticeModel.hertz(1.5), 8, "free")
    chain = Chain(spec, PETSc.COMM_WORLD)
    X = chain.create_state()
    x = np.zeros((8, 2))
    x[:, 0] = -1e10 * np.arange(8)
    try:
        for given in (None, 5000):
            opts = PETSc.Options()
            if given:
                opts["chain_ts_max_steps"] = given
            try:
                integ = ChainIntegrator(chain)
            finally:
                opts.delValue("chain_ts_max_steps")
            limit = integ.step_limit(0.1)
            assert limit == (given or MIN_STEPS + STEP_LIMIT_FACTOR * round(0.1 / integ.initial_step))
            chain.set_from_array(X, x)
            try:
                with pytest.raises(ConvergenceError, match=r"step limit of %d steps.*-chain_ts_max_steps" % limit):
                    integ.integrate(X, 0.0, 0.1, dt=integ.initial_step)
                assert integ.ts.getStepNumber() == limit
            finally:
                integ.destroy()
    finally:
        X.destroy()
        chain.destroy()


def test_a_state_that_overflows_is_a_convergence_error_not_a_petsc_error():
    """Positions of 1e100: the forces overflow within a step; PETSc's norm sees the infinity (error 72) and the
    flow raises ConvergenceError (exit status 3 in a driver) saying so, on every rank."""
    spec = ChainSpec(LatticeModel.hertz(1.5), 8)
    chain = Chain(spec, PETSc.COMM_WORLD)
    integ = ChainIntegrator(chain)
    X = chain.create_state()
    try:
        x = np.zeros((8, 2))
        x[:, 0] = 1e100 * np.random.default_rng(1).standard_normal(8)
        chain.set_from_array(X, x)
        with pytest.raises(ConvergenceError, match="the state overflowed"):
            integ.integrate(X, 0.0, 1.0, dt=integ.initial_step)
    finally:
        X.destroy()
        integ.destroy()
        chain.destroy()


@pytest.mark.serial
@pytest.mark.parametrize("ranks", [1, 2])
def test_a_run_in_of_days_is_refused_before_computing_with_the_estimate(tmp_path, ranks):
    """driven_response.py -run_in 10^8 (10 beads, omega = 1: 6.3e8 units of time): refused in one line that names
    -run_in, gives the estimate in hours and says how to raise the limit, on every rank, before any computation
    (no record file written); -max_hours must be >= 0."""
    args = ["-N", 10, "-omega", 1, "-p_end", 1.2, "-output", tmp_path / "r.npz", "-table", tmp_path / "r.md"]
    r = run_script("driven_response.py", *args, "-run_in", 10 ** 8, ranks=ranks, timeout=120)
    line = one_error_line(r)
    assert r.returncode == 2
    hours = resources.chain_seconds(10, 10 ** 8 * 2 * math.pi) / 3600
    assert line.startswith("error: invalid -run_in = 100000000:") and f"about {hours:.3g} hours" in line, line
    assert "-max_hours" in line
    assert not (tmp_path / "r.npz").exists()
    r = run_script("driven_response.py", *args, "-max_hours", -1, timeout=120)
    assert "invalid -max_hours = '-1'" in one_error_line(r)


def test_a_signal_ends_a_polynomial_eigensolve_that_calls_no_python(monkeypatch):
    """SLEPc's PEP on assembled matrices calls no Python but its monitor: the monitor runs Python's pending signal
    handlers (errors.check_signals), and what they raise ends the solve and comes back from it as itself. Here the
    handler is replaced by one that raises at the second iteration, as guarded_main's does on SIGTERM."""
    import scipy.sparse as sp
    from hertzpetsc import comoving_pep
    from hertzpetsc.errors import Terminated
    calls = []

    def pending(*args):
        calls.append(args)
        if len(calls) == 2:
            raise Terminated(signal.SIGTERM)

    monkeypatch.setattr(comoving_pep, "check_signals", pending)
    n = 200
    lap = sp.diags([np.ones(n - 1), -2 * np.ones(n), np.ones(n - 1)], [-1, 0, 1], format="csr")
    mats = [lap, sp.identity(n, format="csr") * 0.1, sp.identity(n, format="csr")]
    solver = comoving_pep.ComovingPEP(PETSc.COMM_SELF, nev=40, tol=1e-14)
    with pytest.raises(Terminated):
        solver.solve(mats, -0.5, 40)
    assert len(calls) == 2


@pytest.mark.serial
@pytest.mark.parametrize("ranks", [1, 2])
def test_the_sweeps_bad_driver_inputs_end_in_one_line_on_every_rank(tmp_path, ranks):
    """Found by the sweep of issue 37 (each ended otherwise): -levels 10^9 (an internal error converting 2^(10^9) to
    text; 10^20 ran until killed), -points 10^9 (a list of 10^9 grid values built for minutes before the study's
    limit), -p_end_si without -beads (an internal AttributeError), wave.py -cells_per_pi 10^9 (16 GB of NaN profiles
    made before the memory check, killed after 90 s): one error line naming the option and its range,
    status 2, within the timeout, on every rank."""
    out = ["-output", tmp_path / "r.npz", "-table", tmp_path / "r.md"]
    for script, args, words in [
            ("small_q.py", ["-levels", 10 ** 9, "-progress", tmp_path / "p.npz"], "invalid -levels = '1000000000': "
             "must be an integer >= 3 and <= 30"),
            ("small_q.py", ["-levels", "99999999999999999999", "-progress", tmp_path / "p.npz"], "invalid -levels"),
            ("driven_response.py", ["-mode", "grid", "-points", 10 ** 9, *out], "invalid -points = '1000000000': "
             "must be an integer >= 2 and <= 100001"),
            ("driven_response.py", ["-p_end_si", "12kHz", *out], "invalid -p_end_si = '12kHz': is in SI units: "
             "give -beads"),
            ("wave.py", ["-cells_per_pi", 10 ** 9, *out], "invalid -cells_per_pi = 1000000000: needs about")]:
        r = run_script(script, *args, ranks=ranks, timeout=60)
        assert r.returncode == 2 and words in one_error_line(r), (script, args, r.stderr[-500:])


@pytest.mark.serial
@pytest.mark.parametrize("ranks", [1, 2])
def test_check_and_errors_with_a_shell_floquet_operator_end_without_a_crash(tmp_path, ranks):
    """driven_response.py -floquet slepc builds SLEPc's shell operator before the options are checked: -check (and an
    error after it is built: an unknown option) left it to PETSc's finalize at the interpreter's exit, whose
    destroy called into a finalized Python (SEGV, status 59/139 after the check line). guarded_main frees main's
    objects first: status 0 with the check line, status 2 with the error line."""
    out = ["-N", 10, "-floquet", "slepc", "-output", tmp_path / "r.npz", "-table", tmp_path / "r.md"]
    r = run_script("driven_response.py", *out, "-check", ranks=ranks, timeout=60)
    assert r.returncode == 0 and r.stderr.strip() == "", r.stderr[-500:]
    assert r.stdout.strip().splitlines()[-1].startswith("check: options, inputs and outputs valid")
    r = run_script("driven_response.py", *out, "-bogus", 1, ranks=ranks, timeout=60)
    assert r.returncode == 2 and one_error_line(r).startswith("error: unknown option -bogus 1"), r.stderr[-500:]
