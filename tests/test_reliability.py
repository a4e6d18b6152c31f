"""Reliability promises of the drivers that start processes or run long (issue 21's classes): signals end every
child and leave resumable files, one writer per pipeline, ranks that disagree on an option, bounded step control."""
import json
import math
import os
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import ROOT, SCRIPTS, one_error_line, script_env, shared_tmp
from hertzpetsc.errors import ConvergenceError
from hertzpetsc.qbranch import BranchContinuation, ContinuationParameters
from hertzpetsc.records import read_kind
from hertzpetsc.studies.paper import PAPER_KIND


def _cmdline(pid):
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read().replace(b"\0", b" ").decode(errors="replace")
    except OSError:                                  # ended (a zombie's command line is empty too)
        return ""


def _children_of(pattern, root):
    """The processes below ``root`` (its children, theirs ...) whose command line contains ``pattern``: this test's
    own, not those of another run on the machine."""
    found, todo = [], [root]
    while todo:
        r = subprocess.run(["pgrep", "-P", str(todo.pop())], capture_output=True, text=True)
        for pid in map(int, r.stdout.split()):
            todo.append(pid)
            if pattern in _cmdline(pid):
                found.append(pid)
    return found


def _alive(pids, pattern):
    return [pid for pid in pids if pattern in _cmdline(pid)]


@pytest.mark.serial
def test_sigterm_ends_the_pipeline_step_and_its_ranks_then_resume_finishes(tmp_path):
    """SIGTERM (what timeout, kill and batch schedulers send) to the paper pipeline: status 143, one error line,
    the running step's mpiexec and ranks ended; -resume then runs the step to its end."""
    args = [sys.executable, os.path.join(SCRIPTS, "paper.py"), "-steps", "convergence_h", "-progress",
            str(tmp_path / "p.npz"), "-logs", str(tmp_path / "logs"), "-workdir", str(tmp_path)]
    proc = subprocess.Popen(args, env=script_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=ROOT)
    marker = "scripts/convergence_h.py"
    deadline = time.time() + 60
    while time.time() < deadline and not _children_of(marker, proc.pid):
        time.sleep(0.2)
    step = _children_of(marker, proc.pid)
    assert step, "the step did not start"
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 143
    assert err.strip().splitlines() == ["error: terminated by SIGTERM"]
    time.sleep(1.0)
    assert not _alive(step, marker)
    r = subprocess.run(args + ["-resume"], env=script_env(), capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "convergence_h" in r.stdout
    progress = read_kind(str(tmp_path / "p.npz"), PAPER_KIND, "progress file")     # the declared columns
    assert PAPER_KIND.check(progress) == ([], []) and [str(e) for e in progress["event"]].count("done") == 1


@pytest.mark.serial
def test_sigterm_to_a_benchmark_ends_its_workers_and_their_ranks(tmp_path):
    """A benchmark's worker (here under mpiexec, 2 ranks) runs in a process group that ends with the benchmark: no
    worker or rank keeps computing after SIGTERM."""
    args = [sys.executable, os.path.join(SCRIPTS, "bench_branch.py"), "-cells", "400000", "-M", "50",
            "-output", str(tmp_path / "b.md")]
    proc = subprocess.Popen(args, env=script_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=ROOT)
    marker = '"K": 400000'                           # the workers' request, on their command lines
    deadline = time.time() + 60
    while time.time() < deadline and not _children_of(marker, proc.pid):
        time.sleep(0.2)
    workers = _children_of(marker, proc.pid)
    assert workers, "no worker started"
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    time.sleep(1.0)
    assert not _alive(workers, marker)


@pytest.mark.serial
def test_a_second_pipeline_on_the_same_progress_file_is_refused(tmp_path):
    """While a pipeline holds its progress file (stopped with SIGSTOP once its step runs, so that it cannot finish
    first: the step takes about a second), a second pipeline on that file is refused, naming the holder."""
    args = [sys.executable, os.path.join(SCRIPTS, "paper.py"), "-steps", "convergence_h", "-progress",
            str(tmp_path / "p.npz"), "-logs", str(tmp_path / "logs"), "-workdir", str(tmp_path)]
    first = subprocess.Popen(args, env=script_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT)
    try:
        deadline = time.time() + 60
        while time.time() < deadline and not _children_of("scripts/convergence_h.py", first.pid):
            time.sleep(0.05)
        first.send_signal(signal.SIGSTOP)
        assert first.poll() is None, "the pipeline ended before it could be held"
        second = subprocess.run(args + ["-resume"], env=script_env(), capture_output=True, text=True, cwd=ROOT,
                                timeout=120)
        assert "being written by process" in one_error_line(second)
    finally:
        first.send_signal(signal.SIGCONT)
        first.send_signal(signal.SIGTERM)
        first.wait(timeout=60)


@pytest.mark.serial
def test_ranks_given_different_options_fail_in_one_line_without_hanging(tmp_path):
    common = ["-output", str(tmp_path / "x.npz"), "-table", str(tmp_path / "x.md")]
    script = os.path.join(SCRIPTS, "precompressed_branch.py")
    cmd = ["timeout", "60", "mpiexec", "-n", "1", sys.executable, script, "-q", "0.5", *common, ":", "-n", "1",
           sys.executable, script, "-q", "0.6", *common]
    r = subprocess.run(cmd, env=script_env(), capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    assert "the ranks were given different values" in one_error_line(r)


def test_continuation_near_alpha_1_stops_in_bounded_work():
    """alpha = 1.01 (rescaling exponent 200): the step control gives up with one error instead of halving and
    doubling forever; the bounded number of step changes caps the work. Work is counted in corrector solves, not
    seconds: each target q costs at most max_step_changes + 1 of them (one per change of step, one accepted)."""
    params = ContinuationParameters(alpha=1.01, M=10, cells_per_pi=200)
    cont = BranchContinuation(params, PETSc.COMM_SELF)
    layer, solves = cont.continuation, []
    bound = params.M * (layer.algorithm.max_step_changes + 1)
    solve = layer._solve

    def counted(*args, **kwargs):
        solves.append(1)
        assert len(solves) <= bound, "the step control kept changing the step"
        return solve(*args, **kwargs)

    layer._solve = counted
    try:
        with pytest.raises(ConvergenceError, match="continuation stopped"):
            for _ in cont.points():
                pass
    finally:
        cont.destroy()
    assert 0 < len(solves) <= bound


@pytest.mark.serial
def test_an_empty_branch_file_is_named_not_an_internal_error(tmp_path):
    """A continuation killed before its first point leaves a branch file with no point: the drivers that read it
    say so in one line (status 4, a file error) instead of failing with an internal error."""
    from conftest import run_script
    from hertzpetsc.studies.branch import BranchStudy
    BranchStudy(ContinuationParameters(M=10, cells_per_pi=100), str(tmp_path / "b.npz"), PETSc.COMM_SELF).open()
    for script, extra in (("refine_branch.py", ["-output", tmp_path / "r.npz", "-table", tmp_path / "r.md"]),
                          ("paper_table.py", ["-output", tmp_path / "t.md"])):
        r = run_script(script, "-branch", tmp_path / "b.npz", *extra, timeout=60)
        assert r.returncode == 4 and "holds 0 point(s)" in one_error_line(r), (script, r.stderr)


@pytest.mark.serial
def test_a_resume_from_another_input_or_other_solver_options_is_refused(tmp_path):
    """Record identities hold the input files' content and the number-changing solver options: a refinement
    resumed with another branch file, or with another -shoot_ts_rtol, is refused, naming the difference (one line,
    status 4), instead of mixing two computations in one file."""
    from conftest import DATA, run_script
    import shutil
    other = tmp_path / "other.npz"
    shutil.copy(f"{DATA}/branch_alpha1.5.npz", other)
    with open(other, "ab") as f:                     # another file (same content would be the same input)
        f.write(b"\0")
    args = ["-N", 20, "-q", "2*pi/5", "-output", tmp_path / "r.npz", "-table", tmp_path / "r.md"]
    r = run_script("refine_branch.py", "-branch", f"{DATA}/branch_alpha1.5.npz", *args, timeout=120)
    assert r.returncode == 0, r.stderr
    r = run_script("refine_branch.py", "-branch", other, *args, "-resume", timeout=120)
    assert r.returncode == 4 and "branch_sha256" in one_error_line(r)
    r = run_script("refine_branch.py", "-branch", f"{DATA}/branch_alpha1.5.npz", *args, "-resume",
                   "-shoot_ts_rtol", "1e-13", timeout=120)
    assert r.returncode == 4 and "solver_options" in one_error_line(r)
    r = run_script("refine_branch.py", "-branch", f"{DATA}/branch_alpha1.5.npz", *args, "-resume",
                   "-shoot_ts_monitor", timeout=120)          # a monitor changes no number: accepted
    assert r.returncode == 0, r.stderr


@pytest.mark.serial
def test_a_documented_option_of_a_solver_the_run_does_not_create_is_accepted_and_said(tmp_path):
    """-floquet_eps_nev is an option of floquet_scan's role floquet_ (its -help lists it), read only when the run
    creates the EPS (-method slepc): with -method symmetric it is accepted with one note (status 0), not refused as
    unknown; a typo beside it is still refused."""
    from conftest import DATA, run_script
    args = ["-q", "7*pi/25", "-refined", f"{DATA}/refined_N100.npz", "-output", tmp_path / "f.npz",
            "-table", tmp_path / "f.md", "-method", "symmetric", "-floquet_eps_nev", "5"]
    r = run_script("floquet_scan.py", *args, timeout=120)
    notes = [line for line in r.stderr.splitlines() if line.strip()]
    assert r.returncode == 0 and len(notes) == 1 and notes[0].startswith("note: -floquet_eps_nev 5 not used"), r.stderr
    r = run_script("floquet_scan.py", *args, "-force", "-floquet_eps_nevv", "5", timeout=120)
    assert r.returncode == 2 and "unknown option -floquet_eps_nevv" in one_error_line(r)


def _resumable_studies():
    """Every study on the Study base (the driven response curve among them) with a tiny parameter set: (name,
    factory(output, mode))."""
    from hertzpetsc.driven import Drive, HarmonicWave
    from hertzpetsc.model import LatticeModel
    from hertzpetsc.studies.driven import ResponseCurve, ResponseParameters
    from hertzpetsc.studies.maps import MapParameters, StabilityMap
    from hertzpetsc.studies.precompression import (AmplitudeFamilies, AmplitudeParameters, DimerFamilies,
                                                   DimerParameters)
    from hertzpetsc.studies.wave import WaveParameters, WaveStudy
    pre = LatticeModel.hertz(1.5, delta0=0.5)
    trimer = LatticeModel.hertz(1.5, (1.0, 0.5, 1 / 3), delta0=1.0)
    comm = PETSc.COMM_WORLD
    driven = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.1), 2, HarmonicWave(), 0.05, 0.5)
    return {
        # pseudo-arclength: the resumed run takes the step size the interrupted one had reached
        "driven response": lambda out, mode: ResponseCurve(ResponseParameters(
            driven, "omega", 0.75, run_in=5, max_steps=6, samples=16), comm, out, mode),
        "amplitude families": lambda out, mode: AmplitudeFamilies(AmplitudeParameters(
            pre, (3 * math.pi / 10, math.pi / 2), cells_per_pi=100, a_min=0.01, a_max=100, ds=0.5), comm, out, mode),
        "dimer families": lambda out, mode: DimerFamilies(DimerParameters(
            pre, (math.pi / 4, math.pi / 2), a=0.2, cells_per_pi=100, epsilon_end=0.9, max_steps=3), comm, out, mode),
        "stability map": lambda out, mode: StabilityMap(MapParameters(
            pre, (math.pi / 5, 3 * math.pi / 10), (0.3, 3.0), N=20, cells_per_pi=100), comm, out, mode),
        "wave": lambda out, mode: WaveStudy(WaveParameters(
            trimer, (2 * math.pi / 15, 4 * math.pi / 15), A=0.5, cells_per_pi=200, N=30), comm, out, mode),
    }


@pytest.mark.parametrize("name", sorted(_resumable_studies()))
def test_a_study_killed_after_any_record_resumes_to_the_uninterrupted_file(name, tmp_path):
    """A run stopped after its k-th record (the generator abandoned: the file then holds k records and the resume
    state, as after a kill between two writes) and resumed gives the uninterrupted run's file, every array equal to
    the bit (timings apart), for k = 1, 2 (inside the start of a continuation), the middle and the last but one:
    nothing skipped, nothing recomputed differently. On several ranks MUMPS sums in an order that varies from run to
    run (two uninterrupted 2-rank runs of the dimer families differ by 4e-14 in the tangent), and the map's
    multipliers, integrated by an adaptive TS from waves that differ by that round-off, follow it: rho by 2e-10, the
    undeflated trivial group's spread by 3e-8. There the arrays agree to 1e-8 relative and 1e-6 absolute: far below
    the verdicts' tol_rho (1e-6 in the map) and any step a continuation takes, above that spread."""
    make = _resumable_studies()[name]
    exact = PETSc.COMM_WORLD.getSize() == 1
    tmp_path = pathlib.Path(shared_tmp(tmp_path))
    whole = tmp_path / "whole.npz"
    rows = list(make(str(whole), "new").run())
    assert len(rows) >= 2
    ref = np.load(whole)
    for k in sorted({1, 2, len(rows) // 2, len(rows) - 1}):
        path = str(tmp_path / f"cut{k}.npz")
        run = make(path, "new").run()
        for _ in range(k):
            next(run)
        run.close()
        rest = list(make(path, "resume").run())
        assert len(rest) == len(rows) - k, (k, len(rest))
        got = np.load(path)
        assert sorted(got.files) == sorted(ref.files)
        for key in ref.files:
            if "seconds" in key or "wall" in key:
                continue
            if key == "__provenance__":                  # what made each file: the resumed one names both runs
                assert len(json.loads(str(got[key]))["earlier"]) == 1 and "earlier" not in json.loads(str(ref[key]))
                continue
            a, b = ref[key], got[key]
            assert a.shape == b.shape, (k, key)
            if exact or a.dtype.kind not in "fc":
                assert np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"), (k, key)
            else:
                assert np.allclose(a, b, rtol=1e-8, atol=1e-6, equal_nan=True), (k, key, np.abs(a - b).max())


def test_a_child_is_ended_even_when_an_interrupted_wait_left_its_lock_held():
    """run_child's ending of a child's group reaps it without Popen.wait, whose lock a signal raised inside an earlier
    wait can leave held (a held paper pipeline stayed after SIGTERM, blocked for ever in its wait, its mpiexec a
    zombie): with the lock held, the child is still ended and reaped within the grace."""
    import threading
    from hertzpetsc.options import _end_group
    child = subprocess.Popen(["sleep", "60"], start_new_session=True)
    child._waitpid_lock.acquire()
    done = threading.Thread(target=_end_group, args=(child, 2.0), daemon=True)
    done.start()
    done.join(20)
    try:
        assert not done.is_alive() and child.returncode == -signal.SIGTERM
    finally:
        child._waitpid_lock.release()
        child.kill()
