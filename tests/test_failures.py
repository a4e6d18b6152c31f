"""The failure matrix: every driver against every class of bad input (a mistyped option, -help, an output that
cannot be written, a missing input, an input of another kind, a bad list, an existing record file without
-resume or -force, a bad solver option), then the same classes as real processes serially and under
``mpiexec -n 2`` with a timeout, and kill-and-resume.

The matrix runs each driver's ``main`` in this process (through its ``guarded_main``: one ``error:`` line and the
exit status), which is what makes it cheap; the process tests show the same lines and statuses from real
processes, on every rank, with no hang and with the files left intact.
"""
import functools
import math
import os
import re
import runpy
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import DATA, SCRIPTS, checkout, one_error_line, run_script, script_env
from hertzpetsc.branch import Branch
from hertzpetsc.options import guarded_main
from hertzpetsc.simulation import read_snapshots

pytestmark = pytest.mark.serial           # the matrix exits through guarded_main; the MPI cases launch mpiexec

BRANCH = f"{DATA}/branch_alpha1.5.npz"
REFINED = f"{DATA}/refined_N100.npz"
FLOQUET = f"{DATA}/floquet_N100.npz"

# driver: (arguments of a run that would start, its input option, its record output option, a bad list,
#          a bad solver option); {t} is a fresh directory, {f} a plain file in it
DRIVERS = {
    "continuation.py": (("-M", 5, "-cells_per_pi", 50, "-q_stop", "0.6*pi", "-output", "{t}/b.npz"), None, "output",
                        None, ("-tw_pc_type", "bogus")),
    "paper_table.py": (("-branch", BRANCH, "-output", "{t}/t.md"), "branch", None, None, None),
    "convergence_h.py": (("-M", 5, "-cells", "20,40,80", "-output", "{t}/c.md"), None, None,
                         ("-cells", "20,40,40"), ("-tw_pc_type", "bogus")),
    "refine_branch.py": (("-branch", BRANCH, "-N", 20, "-q", "2*pi/5", "-output", "{t}/r.npz", "-table", "{t}/r.md"),
                         "branch", "output", ("-q", "2*pi/5,0"), ("-shoot_ts_type", "bogus")),
    "floquet_scan.py": (("-branch", BRANCH, "-refined", REFINED, "-q", "3*pi/10", "-output", "{t}/f.npz", "-table",
                         "{t}/f.md"), "refined", "output", ("-q", "3*pi/10,3*pi/10"), ("-floquet_ts_type", "bogus")),
    "floquet_long.py": (("-branch", BRANCH, "-refined", REFINED, "-reference", FLOQUET, "-sizes", 200, "-q", "7*pi/25",
                         "-output", "{t}/l.md", "-npz", "{t}/l.npz"), "refined", "npz", ("-sizes", 150),
                        ("-floquet_ts_type", "bogus")),
    "long_run.py": (("-branch", BRANCH, "-q", "3*pi/10", "-t_final", 1, "-output", "{t}/run"), "branch", "output",
                    None, ("-chain_ts_type", "bogus")),
    "dynamics_figures.py": (("-runs", "{run}", "-figures", "{t}/fig", "-table", "{t}/d.md"), "runs", None,
                            ("-runs", ""), None),
    "small_q.py": (("-q_stop", "pi/60", "-per_halving", 1, "-cells_per_q", 4, "-progress", "{t}/p.npz", "-output",
                    "{t}/s.md"), None, "progress", None, ("-tw_pc_type", "bogus")),
    "solitary_wave.py": (("-alphas", "1.5", "-cells", "10,20,40", "-lengths", 5, "-output", "{t}/s.md"), None, None,
                         ("-alphas", "1.5,1.5"), ("-sol_pc_type", "bogus")),
    "long_wave.py": (("-branch", BRANCH, "-cells_per_unit", 20, "-output", "{t}/w.md"), "branch", None, None,
                     ("-sol_pc_type", "bogus")),
    "compactons.py": (("-branches", BRANCH, "-q", "7*pi/25", "-travel", 5, "-output", "{t}/c.md"), "branches", None,
                      ("-q", ""), ("-chain_ts_type", "bogus")),
    "paper.py": (("-steps", "paper_table", "-progress", "{t}/p.npz", "-logs", "{t}/logs", "-workdir", checkout()), None,
                 "progress",
                 ("-steps", "paper_table,bogus"), None),
    "bench_branch.py": (("-cells", 100, "-output", "{t}/b.md"), None, "records", ("-cells", "100,100"), None),
    "bench_chain.py": (("-sizes", 20, "-branch", BRANCH, "-output", "{t}/b.md"), "branch", "records", ("-sizes", 30),
                       None),
    "bench_newton.py": (("-cells", 100, "-output", "{t}/b.md"), None, "records", ("-cells", ""), None),
    "bench_floquet.py": (("-sizes", 100, "-branch", BRANCH, "-refined", REFINED, "-output", "{t}/b.md"), "refined",
                         "records", ("-sizes", 150), None),
    "bench_report.py": (("-workloads", "branch", "-output", "{t}/b.md"), None, "records", ("-workloads", "gpu"),
                        None),
    "bench_stability.py": (("-N", 20, "-routes", "symmetric", "-branch", BRANCH, "-output", "{t}/b.md"), "branch",
                           "records", ("-routes", "symmetric,gpu"), None),
    "bench_map.py": (("-N", 20, "-m", 3, "-subset_m", 3, "-a", 0.5, "-ds", 0, "-routes", "subset", "-output",
                      "{t}/b.md"), None, "records", ("-m", "3,3"), None),
    "precompressed_branch.py": (("-q", "3*pi/10", "-cells_per_pi", 50, "-a_min", 0.1, "-a_max", 10, "-ds", 1, "-output",
                                 "{t}/p.npz", "-table", "{t}/p.md"), None, "output", ("-q", "3*pi/10,3*pi/10"),
                                ("-precomp_pc_type", "bogus")),
    "dimer_branch.py": (("-cells_per_pi", 40, "-a", 0.1, "-max_steps", 2, "-output", "{t}/d.npz", "-table", "{t}/d.md"),
                        None, "output", ("-q", "3*pi/10,3*pi/10"), ("-dimer_pc_type", "bogus")),
    "precompression_map.py": (("-N", 20, "-m", 3, "-a", 0.5, "-cells_per_pi", 100, "-output", "{t}/m.npz", "-table",
                               "{t}/m.md"), None, "output", ("-m", "3,3"), ("-floquet_ts_type", "bogus")),
    "boundary_in_q.py": (("-A", 3, "-m", "18,20", "-cells_per_pi", 100, "-output", "{t}/q.npz", "-table",
                          "{t}/q.md"), None, "output", ("-m", "18,18"), ("-floquet_ts_type", "bogus")),
    "rejudge_map.py": (("-source", f"{DATA}/map_v2_small.npz", "-output", "{t}/r.npz", "-table", "{t}/r.md"),
                       "source", "output", None, ("-floquet_ts_type", "bogus")),
    "slow_instabilities.py": (("-branch", BRANCH, "-N", 30, "-q", "2*pi/5", "-grids", "100,200,400", "-n_theta", 3,
                               "-n_twist", 1, "-reference", "none", "-convergence_q", "2*pi/5", "-output", "{t}/s.npz",
                               "-table", "{t}/s.md"), "branch", "output", ("-grids", "100,200"),
                              ("-cm_pep_type", "bogus")),
    "compacton_stability.py": (("-branches", BRANCH, "-q", "pi/5", "-no_solitary", "-no_ring", "-M", 12, "-rear", 3,
                                "-output", "{t}/c.npz", "-table", "{t}/c.md"), "branches", "output",
                               ("-q", "pi/5,pi/5"), ("-cwin_ts_type", "bogus")),
    "solitary_stability.py": (("-alphas", "2", "-c0", "0.5", "-tail", "1e-10", "-output", "{t}/s.npz", "-table",
                               "{t}/s.md"), None, "output", ("-c0", "0.5,0.5"), ("-cwin_ts_type", "bogus")),
    "wave.py": (("-masses", "1,0.5,0.25", "-q", "2*pi/15", "-N", 30, "-cells_per_pi", 60, "-output", "{t}/w.npz",
                 "-table", "{t}/w.md"), None, "output", ("-masses", "1,0"), ("-shoot_ts_type", "bogus")),
    "compacton_dynamics.py": (("-stability", f"{DATA}/compacton_stability.npz", "-q", "7*pi/25", "-N", 40,
                               "-n0", 5, "-travel", 10, "-kinds", "mode", "-no_pairs", "-output", "{t}/d.npz",
                               "-table", "{t}/d.md"), "stability", "output", ("-q", "7*pi/25,7*pi/25"),
                              ("-cdyn_ts_type", "bogus")),
    "driven_response.py": (("-N", 2, "-omega", 1.69, "-p_end", 1.68, "-run_in", 2, "-output", "{t}/r.npz", "-table",
                            "{t}/r.md"), None, "output", ("-masses", ""), ("-drive_snes_type", "bogus")),
    "driven_resonances.py": (("-N", 2, "-modes", 1, "-golden", 4, "-output", "{t}/s.npz", "-table", "{t}/s.md"), None,
                             "output", ("-modes", "1,1"), ("-drive_snes_type", "bogus")),
    "driven_wave_ends.py": (("-branch", BRANCH, "-refined", REFINED, "-q", "2*pi/5", "-sizes", 4, "-rtols", "1e-12", "-samples", 256, "-output", "{t}/w.npz",
                             "-table", "{t}/w.md"), "refined", "output", ("-sizes", "4,4"),
                            ("-drive_snes_type", "bogus")),
    "driven_generation.py": (("-branch", BRANCH, "-N", 8, "-signals", "half_sine", "-omegas", 0.5, "-amplitudes", 0.1, "-gammas", 0.1,
                              "-run_in", 2, "-output", "{t}/g.npz", "-table", "{t}/g.md"), "branch", "output",
                             ("-omegas", "0.5,0.5"), ("-floquet_eps_type", "bogus")),
    "bench_driven.py": (("-N", 2, "-points", 2, "-workloads", "sweep", "-output", "{t}/b.md"), None, "records",
                        ("-workloads", "gpu"), None),
    "bench_long_driven.py": (("-sizes", 20, "-routes", "radius", "-ranks", 1, "-run_in", 2, "-output", "{t}/b.md"),
                             None, "records", ("-sizes", "20,20"), None),
    "restitution.py": (("-velocities", "0.01,0.1", "-output", "{t}/r.npz", "-table", "{t}/r.md"), None, "output",
                       ("-velocities", "0.1,0.1"), ("-chain_ts_type", "bogus")),
    "pulse_decay.py": (("-N", 12, "-skip", 2, "-velocities", 1, "-output", "{t}/p.npz", "-table", "{t}/p.md"), None,
                       "output", ("-velocities", "1,1"), ("-chain_ts_type", "bogus")),
    "beads_to_waves.py": (("-cells", "10,20,40", "-max_velocity", "0.1m/s", "-output", "{t}/b.md"), None, None,
                          ("-cells", "10,20,20"), ("-sol_pc_type", "bogus")),
}


def test_every_driver_is_in_the_matrix():
    drivers = {f for f in os.listdir(SCRIPTS) if f.endswith(".py") and f != "benchlib.py"}
    assert drivers == set(DRIVERS)


def drive(script, args, capfd, monkeypatch, cwd):
    """Run the driver's main in this process under its guarded_main: (exit status, stdout, stderr lines)."""
    monkeypatch.chdir(cwd)
    monkeypatch.syspath_prepend(SCRIPTS)                      # the benchmarks import their harness
    main = runpy.run_path(os.path.join(SCRIPTS, script), run_name="hz_matrix")["main"]
    opts = PETSc.Options()
    before = set(opts.getAll())
    names = []
    args = [str(a) for a in args]
    i = 0
    while i < len(args):                                      # -name [value]; a flag takes no value
        name, value = args[i][1:], None
        nxt = args[i + 1] if i + 1 < len(args) else None
        if nxt is not None and not (nxt.startswith("-") and not nxt[1:2].isdigit()):
            value = nxt
            i += 1
        i += 1
        opts.setValue(name, value)
        names.append(name)
    capfd.readouterr()
    try:
        guarded_main(main)
        code = 0
    except SystemExit as done:
        code = done.code
    finally:
        for key in set(opts.getAll()) - before:
            opts.delValue(key)
    out = capfd.readouterr()
    return code, out.out, [line for line in out.err.splitlines() if line.strip()]


@functools.lru_cache(maxsize=None)
def long_run_directory():
    """A finished long run (20 beads, one time unit), made once: the input of dynamics_figures.py's cases, which
    reads its runs before it checks its options."""
    path = os.path.join(checkout(), "runs", "matrix_run")
    r = run_script("long_run.py", "-branch", BRANCH, "-q", "3*pi/10", "-N", 20, "-t_final", 1, "-output", path,
                   "-force")
    assert r.returncode == 0, r.stderr
    return path


def fill(args, t):
    return [str(a).replace("{t}", str(t)).replace("{run}", long_run_directory() if "{run}" in str(a) else "")
            for a in args]


def swap(args, option, value):
    """``args`` with -option set to value (appended if absent)."""
    args = list(args)
    if f"-{option}" not in args:
        return args + [f"-{option}", value]
    args[args.index(f"-{option}") + 1] = value
    return args


def offers_empty_for_none(script):
    """The driver's source (or the benchmark harness it declares its options with) has an option 'none if empty'."""
    with open(os.path.join(SCRIPTS, script)) as f:
        text = f.read()
    return "none if empty" in text or "declare_common(" in text


EMPTY_FOR_NONE = tuple(sorted(s for s in DRIVERS if offers_empty_for_none(s)))


def cases():
    for script, (base, inp, record, bad_list, bad_solver) in DRIVERS.items():
        yield script, "typo"
        yield script, "help"
        yield script, "unwritable"
        if inp:
            yield script, "missing input"
            yield script, "wrong kind"
        if record:
            yield script, "existing record"
        if bad_list:
            yield script, "bad list"
        if bad_solver:
            yield script, "bad solver option"
        if script in EMPTY_FOR_NONE:
            yield script, "empty for none"


@pytest.mark.parametrize("script,failure", list(cases()))
def test_failure_matrix(script, failure, tmp_path, capfd, monkeypatch):
    base, inp, record, bad_list, bad_solver = DRIVERS[script]
    args = fill(base, tmp_path)
    (tmp_path / "afile").write_text("not a directory")
    if failure == "typo":
        code, _, err = drive(script, args + ["-alpah", "2"], capfd, monkeypatch, tmp_path)
        assert code == 2 and len(err) == 1 and err[0].startswith("error: unknown option -alpah"), err
    elif failure == "help":
        work = tmp_path / "help"
        work.mkdir()
        code, out, err = drive(script, ["-help"], capfd, monkeypatch, work)
        assert code == 0 and not err and "Application options" in out
        assert list(work.iterdir()) == []                       # nothing computed, nothing written
    elif failure == "unwritable":
        # every file the run writes is checked before any computation: the record, the output and the table
        options = [record] if record else []
        options += [o for o in ("output", "table") if f"-{o}" in args and o not in options]
        for option in options or ["table"]:
            t0 = time.perf_counter()
            code, _, err = drive(script, swap(args, option, str(tmp_path / "afile" / "x")), capfd, monkeypatch,
                                 tmp_path)
            assert code == 4 and len(err) == 1 and "is not a directory" in err[0], (option, err)
            assert time.perf_counter() - t0 < 30, option          # refused up front, not after the work
    elif failure == "missing input":
        code, _, err = drive(script, swap(args, inp, str(tmp_path / "missing.npz")), capfd, monkeypatch, tmp_path)
        assert code == 4 and len(err) == 1 and ("does not exist" in err[0] or "missing" in err[0]), err
    elif failure == "wrong kind":
        other = FLOQUET if inp != "runs" else str(tmp_path)
        code, _, err = drive(script, swap(args, inp, other), capfd, monkeypatch, tmp_path)
        assert code == 4 and len(err) == 1, err
        assert "but a" in err[0] or "no run in" in err[0] or "not a hertzpetsc" in err[0], err
    elif failure == "existing record":
        target = args[args.index(f"-{record}") + 1] if f"-{record}" in args else str(tmp_path / "rec.npz")
        if f"-{record}" not in args:
            args += [f"-{record}", target]
        os.makedirs(target, exist_ok=True) if record == "output" and script == "long_run.py" else None
        (tmp_path / "run" / "run.json").write_text("{}") if script == "long_run.py" else open(target, "w").close()
        code, _, err = drive(script, args, capfd, monkeypatch, tmp_path)
        assert code == 4 and len(err) == 1 and "-resume" in err[0] and "-force" in err[0], err
    elif failure == "bad list":
        option, value = bad_list[0].lstrip("-"), bad_list[1]
        code, _, err = drive(script, swap(args, option, value), capfd, monkeypatch, tmp_path)
        assert code == 2 and len(err) == 1 and (f"-{option}" in err[0] or "q_k" in err[0]), err
    elif failure == "empty for none":
        # every option whose -help says "none if empty" takes an empty value: the run then stops at the typo given
        # after it (checked once everything was read), not at the empty value
        _, out, _ = drive(script, ["-help"], capfd, monkeypatch, tmp_path)
        names = re.findall(r"^\s+-(\w+) .*none if empty", out, re.M)
        assert names
        for name in names:
            code, _, err = drive(script, swap(args, name, "") + ["-alpah", "2"], capfd, monkeypatch, tmp_path)
            assert code == 2 and len(err) == 1 and err[0].startswith("error: unknown option -alpah"), (name, err)
    elif failure == "bad solver option":
        code, _, err = drive(script, args + list(bad_solver), capfd, monkeypatch, tmp_path)
        assert code == 5 and len(err) == 1 and "bogus" in err[0] and f"from the option -{bad_solver[0][1:]}" in err[0]


# --- the same from real processes, serially and on 2 ranks -------------------------------------------------------
@pytest.mark.parametrize("ranks", [1, 2])
def test_processes_fail_in_one_line_on_every_rank(tmp_path, ranks):
    (tmp_path / "afile").write_text("x")
    checks = [
        (("continuation.py", "-alpah", "2"), 2, "unknown option -alpah 2; did you mean -alpha?"),
        (("continuation.py", "-output", tmp_path / "afile" / "b.npz"), 4, "is not a directory"),
        (("continuation.py", "-q_stop", "pi/2", "-output", tmp_path / "b.npz", "-tw_pc_type", "bogus"), 5,
         "Unable to find requested PC type bogus (from the option -tw_pc_type bogus)"),
        (("floquet_scan.py", "-q", "3*pi/10", "-refined", tmp_path / "missing.npz", "-output", tmp_path / "f.npz",
          "-table", tmp_path / "f.md"), 4, "does not exist"),
        (("refine_branch.py", "-q", "2*pi/5", "-N", 20, "-output", tmp_path / "r.npz", "-table",
          tmp_path / "afile" / "t.md"), 4, "is not a directory"),
        (("bench_driven.py", "-workloads", "long", "-long_N", 0, "-output", tmp_path / "b.md"), 2,
         "invalid -long_N = 0: the only workload is long"),
    ]
    for (script, *args), status, needle in checks:
        t0 = time.perf_counter()
        r = run_script(script, *args, ranks=ranks, timeout=120, cwd=tmp_path)
        assert r.returncode == status and needle in one_error_line(r), (script, r.returncode, r.stderr)
        assert time.perf_counter() - t0 < 60                 # ends within seconds, never a hang
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]      # nothing written by a failed run


def test_help_computes_nothing_on_two_ranks(tmp_path):
    """-help: the driver's options and solver roles first, on a screen or two, no PETSc banner; -help solvers adds
    PETSc's own options of each role. Neither computes nor writes anything."""
    r = run_script("continuation.py", "-help", ranks=2, cwd=tmp_path)
    assert r.returncode == 0 and "-cells_per_pi 1000" in r.stdout and "-tw_*" in r.stdout
    lines = r.stdout.splitlines()
    assert lines[0].startswith("Compute the travelling-wave branch") and len(lines) <= 60
    assert "Petsc Release Version" not in r.stdout and "-tw_snes_type <" not in r.stdout
    r = run_script("continuation.py", "-help", "solvers", ranks=2, cwd=tmp_path)
    assert r.returncode == 0 and r.stdout.splitlines()[0].startswith("Compute the travelling-wave branch")
    assert "-tw_snes_type <" in r.stdout and "-sol_snes_type <" in r.stdout      # PETSc's own options of the roles
    assert list(tmp_path.iterdir()) == []


def killed_after(cmd, cwd, ready, timeout=120):
    """Start cmd in its own session, wait until ready() holds, then kill the whole process group (SIGKILL)."""
    proc = subprocess.Popen(["timeout", str(timeout), *cmd], cwd=cwd, env=script_env(), start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t0 = time.time()
    while not ready():
        assert proc.poll() is None and time.time() - t0 < timeout, "the run ended before it could be killed"
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    marker = str(cmd[-1])                      # the run's own output path: every rank of it, wherever it is
    subprocess.run(["pkill", "-9", "-f", marker])
    while subprocess.run(["pgrep", "-f", marker], capture_output=True).returncode == 0:
        time.sleep(0.05)


def mpi(script, *args):
    return ["mpiexec", "-n", "2", sys.executable, os.path.join(SCRIPTS, script), *map(str, args)]


def test_a_killed_long_run_resumes_to_the_same_trajectory(tmp_path):
    """kill -9 of a 2-rank long run in the middle, -resume: the snapshots equal those of an uninterrupted run bit
    for bit (each record carries the integrator's step); the partial trailing record is dropped."""
    args = ("-branch", BRANCH, "-q", "3*pi/10", "-N", 100, "-t_final", 40, "-refined", REFINED)
    r = run_script("long_run.py", *args, "-output", tmp_path / "full", ranks=2)
    assert r.returncode == 0, r.stderr
    data = tmp_path / "cut" / "snapshots.f64"
    killed_after(mpi("long_run.py", *args, "-output", tmp_path / "cut"), tmp_path,
                 lambda: data.exists() and data.stat().st_size > 40 * 203 * 8)
    cut = read_snapshots(str(tmp_path / "cut")).times[-1]
    assert 0 < cut < 40
    r = run_script("long_run.py", *args, "-output", tmp_path / "cut", "-resume", ranks=2)
    assert r.returncode == 0 and "resuming" in r.stdout, r.stderr
    full, resumed = read_snapshots(str(tmp_path / "full")), read_snapshots(str(tmp_path / "cut"))
    assert np.array_equal(full.times, resumed.times) and np.array_equal(full.states, resumed.states)
    assert not [p for p in (tmp_path / "cut").iterdir() if ".tmp" in p.name]


def test_a_killed_branch_resumes_to_the_same_branch(tmp_path):
    """kill -9 of a 2-rank continuation after some points, -resume: the branch file was complete at every point
    and the resumed branch equals the uninterrupted one to the solver tolerance (1e-10 relative)."""
    args = ("-cells_per_pi", 4000, "-q_stop", "pi/5")
    r = run_script("continuation.py", *args, "-output", tmp_path / "full.npz", ranks=2)
    assert r.returncode == 0, r.stderr

    def some_points():
        try:
            return len(Branch.load(str(tmp_path / "cut.npz"))) >= 10
        except Exception:
            return False
    killed_after(mpi("continuation.py", *args, "-output", tmp_path / "cut.npz"), tmp_path, some_points)
    n = len(Branch.load(str(tmp_path / "cut.npz")))
    r = run_script("continuation.py", *args, "-output", tmp_path / "cut.npz", "-resume", ranks=2)
    assert r.returncode == 0 and f"resuming {tmp_path / 'cut.npz'}: {n} points" in r.stdout, r.stderr
    full, resumed = Branch.load(str(tmp_path / "full.npz")), Branch.load(str(tmp_path / "cut.npz"))
    assert np.array_equal(full.q, resumed.q)
    assert np.max(np.abs(full.u - resumed.u)) <= 1e-10 * np.max(np.abs(full.u))
    assert math.isclose(resumed.q[-1], math.pi / 5)


def test_floquet_long_resumed_table_and_slepc_sizes(tmp_path, capfd, monkeypatch):
    """A resumed floquet_long.py table equals the uninterrupted one (SLEPc, work and residual detail read from the
    records, not from the session); -slepc_sizes outside -sizes is refused in one line before computing."""
    base = fill(DRIVERS["floquet_long.py"][0], tmp_path)
    code, _, err = drive("floquet_long.py", base + ["-slepc_sizes", 300], capfd, monkeypatch, tmp_path)
    assert code == 2 and len(err) == 1 and "-slepc_sizes" in err[0] and "(200)" in err[0], err
    assert not (tmp_path / "l.npz").exists()
    code, _, err = drive("floquet_long.py", base + ["-slepc_sizes", 200], capfd, monkeypatch, tmp_path)
    assert code == 0, err
    first = (tmp_path / "l.md").read_text()
    resumed = swap(base, "output", tmp_path / "r.md") + ["-slepc_sizes", 200, "-resume"]
    code, _, err = drive("floquet_long.py", resumed, capfd, monkeypatch, tmp_path)
    assert code == 0, err
    assert (tmp_path / "r.md").read_text() == first and "not run" not in first


def test_a_refinement_target_below_the_flows_rtol_is_refused(tmp_path, capfd, monkeypatch):
    """wave.py -tol 1e-15 (below the residual flow's rtol 1e-14) drifted along the wave family with exit 0."""
    base = fill(DRIVERS["wave.py"][0], tmp_path)
    code, _, err = drive("wave.py", swap(base, "tol", "1e-15"), capfd, monkeypatch, tmp_path)
    assert code == 2 and len(err) == 1 and "-tol" in err[0] and "-shoot_ts_rtol" in err[0], err


# a size, count or amplitude far beyond what the machine or the method allows: refused in one line (the option
# named, status 2) before anything is allocated or computed, never MemoryError, an overflow or hours of work
OVERSIZED = {
    "continuation.py": ("cells_per_pi", "1000000000000"),
    "convergence_h.py": ("cells", "20,40,1000000000000"),
    "refine_branch.py": ("N", "1000000000"),
    "floquet_scan.py": ("N", "1000000000"),
    "floquet_long.py": ("sizes", "100000000000"),
    "long_run.py": ("t_final", "1e15"),
    "small_q.py": ("q_stop", "1e-12"),
    "solitary_wave.py": ("cells", "10,20,1000000000000"),
    "long_wave.py": ("cells_per_unit", "1000000000000"),
    "compactons.py": ("travel", "1000000000000"),
    "precompressed_branch.py": ("cells_per_pi", "1000000000000"),
    "dimer_branch.py": ("cells_per_pi", "1000000000000"),
    "precompression_map.py": ("N", "1000000000"),
    "boundary_in_q.py": ("cells_per_pi", "1000000000000"),
    "slow_instabilities.py": ("N", "1000000000"),
    "compacton_stability.py": ("M", "1000000000"),
    "compacton_dynamics.py": ("N", "1000000000000"),
    "solitary_stability.py": ("M", "1000000000"),
    "wave.py": ("cells_per_pi", "1000000000000"),
    "bench_branch.py": ("cells", "1000000000000"),
    "bench_chain.py": ("sizes", "1000000000000"),
    "bench_newton.py": ("cells", "1000000000000"),
    "bench_floquet.py": ("sizes", "100000000000"),
    "bench_stability.py": ("N", "1000000000"),
    "driven_response.py": ("N", "1000000000"),
    "driven_resonances.py": ("N", "1000000000"),
    "driven_wave_ends.py": ("sizes", "1000000000"),
    "driven_generation.py": ("N", "1000000000"),
    "bench_driven.py": ("N", "1000000000"),
    "bench_long_driven.py": ("sizes", "1000000000"),
    "bench_map.py": ("N", "1000000000"),
    "pulse_decay.py": ("N", "1000000000000"),
    "beads_to_waves.py": ("cells", "10,20,1000000000000"),
}


@pytest.mark.parametrize("script", sorted(OVERSIZED))
def test_oversized_requests_are_refused_up_front(script, tmp_path, capfd, monkeypatch):
    base = DRIVERS[script][0]
    option, value = OVERSIZED[script]
    t0 = time.perf_counter()
    code, _, err = drive(script, swap(fill(base, tmp_path), option, value), capfd, monkeypatch, tmp_path)
    assert code == 2 and len(err) == 1 and f"-{option}" in err[0], err
    assert time.perf_counter() - t0 < 30
