"""The whole paper in one run: every study of sections 3.1-3.5 and the appendix, in order, each through its driver,
regenerating every table and figure the README quotes for them (the benchmarks are apart: they need an idle
machine).

Each step runs its driver in a process of its own (under ``mpiexec -n ranks`` where the driver is parallel), with
its output in ``<log dir>/<step>.log``. The pipeline's own record store holds, per step, when it was started and
when it finished: a resumed pipeline skips the finished steps, continues an interrupted step from its own record
file (``-resume``) where the driver has one, and starts the others afresh (``-force`` overwrites the record files
of earlier complete runs, e.g. the committed results).
"""
import fcntl
import os
import sys
import time
from dataclasses import dataclass

from ..errors import HertzPetscError, ParameterError, RecordFileError
from ..options import run_child
from ..records import Column, Kind, NpzRecords, make_directory, prepare_output

PAPER_FORMAT = "hertzpetsc-paper-1"
PAPER_KIND = Kind(PAPER_FORMAT, (
    Column("steps", "the steps of this pipeline, comma-separated", "", str, "s", constant=True),
    Column("name", "a step", "", str, "s"),
    Column("event", "`started` or `done`", "", str, "s"),
    Column("seconds", "the step's wall time (0 for `started`)", "s", format=".0f")))


class StepFailure(HertzPetscError):
    """A step of the pipeline failed: the driver's own last line, and its exit status."""

    def __init__(self, message, exit_status):
        self.exit_status = exit_status
        super().__init__(message)


@dataclass(frozen=True)
class Step:
    """One driver run: ``script`` with ``args``; ``record`` is the record file (or run directory) it resumes."""

    name: str
    section: str
    script: str
    args: tuple
    parallel: bool = True
    record: str = ""

    def arguments(self, resume=False):
        """The driver's arguments: a step with a record file continues it (``resume``) or starts it afresh."""
        return list(self.args) + (["-resume" if resume else "-force"] if self.record else [])


def paper_steps(figures="figures", runs="runs"):
    """The studies of the paper, in the order in which their inputs become available."""
    long_runs = (("q3pi10", "3*pi/10", 4000, ()), ("q7pi25", "7*pi/25", 600, ()),
                 ("q7pi25_tight", "7*pi/25", 600, ("-chain_ts_rtol", "1e-14", "-chain_ts_atol", "1e-16")),
                 ("q9pi50", "9*pi/50", 600, ()), ("qpi50", "pi/50", 1200, ()))
    windows = {"q3pi10": "3760:3980", "q7pi25": "200:420", "q7pi25_tight": "250:470", "q9pi50": "0:600",
               "qpi50": "750:1150"}
    steps = [
        Step("branch", "3.1", "continuation.py", ("-output", "results/branch_alpha1.5.npz", "-figures", figures),
             record="results/branch_alpha1.5.npz"),
        Step("paper_table", "3.1", "paper_table.py", ("-branch", "results/branch_alpha1.5.npz", "-output",
                                                      "results/paper_table.md"), parallel=False),
        Step("convergence_h", "3.1", "convergence_h.py", ("-output", "results/convergence_h.md")),
        Step("solitary_wave", "appendix", "solitary_wave.py", ("-output", "results/solitary.md", "-figures", figures)),
        Step("long_wave", "3.2", "long_wave.py", ("-output", "results/long_wave.md", "-figures", figures),
             parallel=False),
        Step("small_q", "3.2", "small_q.py", ("-progress", f"{runs}/small_q.npz", "-output", "results/small_q.md",
                                              "-figures", figures), record=f"{runs}/small_q.npz"),
        Step("small_q_pi1600", "3.2", "small_q.py", ("-q_stop", "pi/1600", "-progress", f"{runs}/small_q1600.npz",
                                                     "-output", "results/small_q_pi1600.md"),
             record=f"{runs}/small_q1600.npz"),
        Step("branch_K4000", "3.3", "continuation.py", ("-cells_per_pi", "4000", "-output",
                                                        f"{runs}/branch_K4000.npz"), record=f"{runs}/branch_K4000.npz"),
        Step("compactons", "3.3", "compactons.py", ("-branches", f"results/branch_alpha1.5.npz,{runs}/branch_K4000.npz",
                                                    "-q", "7*pi/25,pi/10,pi/50", "-output", "results/compactons.md",
                                                    "-figures", figures)),
        Step("refine_branch", "3.4", "refine_branch.py", ("-output", "results/refined_N100.npz", "-table",
                                                          "results/refinement_table_N100.md", "-figures", figures),
             record="results/refined_N100.npz"),
        Step("floquet_scan", "3.5", "floquet_scan.py", ("-output", "results/floquet_N100.npz", "-table",
                                                        "results/floquet_table_N100.md", "-figures", figures),
             record="results/floquet_N100.npz"),
        Step("floquet_long", "3.5", "floquet_long.py", ("-sizes", "1000,10000", "-output", "results/floquet_long.md",
                                                        "-npz", "results/floquet_long.npz"),
             record="results/floquet_long.npz"),
    ]
    for name, q, t_final, extra in long_runs:
        steps.append(Step(f"long_run_{name}", "3.4", "long_run.py",
                          ("-q", q, "-t_final", str(t_final), "-refined", "results/refined_N100.npz", "-output",
                           f"{runs}/{name}", *extra), record=f"{runs}/{name}"))
    steps.append(Step("dynamics_figures", "3.4", "dynamics_figures.py",
                      ("-runs", ",".join(f"{runs}/{name}:{windows[name]}" for name, *_ in long_runs), "-figures",
                       figures, "-table", "results/long_runs.md"), parallel=False))
    steps += beyond_the_paper_steps(figures, runs)
    steps += driven_steps(figures)
    return steps


ALPHA2_SLOW_M = (50, 49, 48, 47, 46, 44, 42, 40, 38, 36, 34, 32, 30, 28, 26, 24, 22, 20, 18, 16, 15, 14, 13, 12, 10)


def beyond_the_paper_steps(figures="figures", runs="runs"):
    """The studies of the paper's open questions and of the chains beyond it (issues 14-16)."""
    steps = [
        Step("slow_instabilities", "3.5", "slow_instabilities.py",
             ("-refined", "results/refined_N100.npz", "-output", "results/slow_instabilities.npz", "-table",
              "results/slow_instabilities.md", "-figures", figures), record="results/slow_instabilities.npz"),
        Step("branch_M200", "3.5", "continuation.py", ("-M", "200", "-q_stop", "27*pi/100", "-output",
                                                        f"{runs}/branch_alpha1.5_M200.npz"),
             record=f"{runs}/branch_alpha1.5_M200.npz"),
        Step("slow_near_qc", "3.5", "slow_instabilities.py",
             ("-branch", f"{runs}/branch_alpha1.5_M200.npz", "-q", ",".join(f"{m}*pi/200" for m in range(54, 63)),
              "-n_twist", "0", "-reference", "none", "-output", "results/slow_instabilities_near_qc.npz", "-table",
              "results/slow_instabilities_near_qc.md", "-figures", figures, "-figure_name",
              "slow_instabilities_near_qc.png"), record="results/slow_instabilities_near_qc.npz"),
        Step("branch_alpha2", "3.3", "continuation.py", ("-alpha", "2", "-output", f"{runs}/branch_alpha2.npz"),
             record=f"{runs}/branch_alpha2.npz"),
        Step("slow_alpha2", "3.5", "slow_instabilities.py",
             ("-branch", f"{runs}/branch_alpha2.npz", "-q", ",".join(f"{m}*pi/50" for m in ALPHA2_SLOW_M),
              "-n_twist", "0", "-reference", "none",
              "-output", "results/slow_instabilities_alpha2.npz", "-table", "results/slow_instabilities_alpha2.md",
              "-figures", figures, "-figure_name", "slow_instabilities_alpha2.png"),
             record="results/slow_instabilities_alpha2.npz"),
        Step("slow_alpha2_mono", "3.5", "slow_instabilities.py",
             ("-branch", f"{runs}/branch_alpha2.npz", "-q", "2*pi/5,3*pi/5,pi", "-reference",
              "none", "-convergence_q", "2*pi/5", "-output", "results/slow_instabilities_alpha2_mono.npz", "-table",
              "results/slow_instabilities_alpha2_mono.md"), record="results/slow_instabilities_alpha2_mono.npz"),
        Step("branch_alpha2.5", "3.3", "continuation.py", ("-alpha", "2.5", "-q_stop", "27*pi/50", "-output",
                                                            f"{runs}/branch_alpha2.5.npz"),
             record=f"{runs}/branch_alpha2.5.npz"),
        Step("compacton_stability", "3.3", "compacton_stability.py",
             ("-branches", f"results/branch_alpha1.5.npz,{runs}/branch_alpha2.npz,{runs}/branch_alpha2.5.npz",
              "-output", "results/compacton_stability.npz", "-table", "results/compacton_stability.md", "-figures",
              figures), record="results/compacton_stability.npz"),
        Step("solitary_stability", "3.3", "solitary_stability.py",
             ("-output", "results/solitary_stability.npz", "-table", "results/solitary_stability.md", "-figures",
              figures), record="results/solitary_stability.npz"),
        Step("compacton_dynamics", "3.3", "compacton_dynamics.py",
             ("-stability", "results/compacton_stability.npz", "-q", "7*pi/25,pi/50", "-output",
              "results/compacton_dynamics.npz", "-table", "results/compacton_dynamics.md", "-pairs_branch",
              f"{runs}/branch_K4000.npz", "-pairs_output", "results/compacton_pairs.npz", "-pairs_table",
              "results/compacton_pairs.md", "-figures", figures),
             parallel=False, record="results/compacton_dynamics.npz"),
        Step("precompressed", "issue 16", "precompressed_branch.py",
             ("-output", "results/precompressed.npz", "-table", "results/precompressed.md", "-figures", figures),
             record="results/precompressed.npz"),
        Step("dimer_a0.1", "issue 16", "dimer_branch.py", ("-a", "0.1", "-cells_per_pi", "400", "-output",
                                                           "results/dimer_a0.1.npz", "-table", "results/dimer_a0.1.md",
                                                           "-figures", figures), record="results/dimer_a0.1.npz"),
        Step("dimer_a0.5", "issue 16", "dimer_branch.py", ("-a", "0.5", "-cells_per_pi", "400", "-output",
                                                           "results/dimer_a0.5.npz", "-table", "results/dimer_a0.5.md"),
             record="results/dimer_a0.5.npz"),
        *(Step(f"precompressed_dimer{eps}", "issue 16", "precompressed_branch.py",
               ("-masses", f"1,{eps}", "-q", "pi/5,7*pi/25,3*pi/10,2*pi/5", "-a_min", "0.1", "-a_max", "1000", "-ds",
                "0.05756462732485115", "-output", f"results/precompressed_dimer{eps}.npz", "-table",
                f"results/precompressed_dimer{eps}.md"), parallel=False, record=f"results/precompressed_dimer{eps}.npz")
          for eps in ("0.9", "0.7", "0.5", "0.4")),
        Step("solitary_stability_M96", "3.3", "solitary_stability.py",
             ("-c0", "0.8,0.85,0.9", "-M", "96", "-output", "results/solitary_stability_M96.npz", "-table",
              "results/solitary_stability_M96.md"), record="results/solitary_stability_M96.npz"),
        Step("wave", "issue 16", "wave.py",
             ("-alpha", "1.5", "-delta0", "1", "-masses", "1,0.5,0.333333333333", "-q", "2*pi/15,4*pi/15", "-A", "0.5",
              "-N", "60", "-sizes", "30000", "-output", "results/wave.npz", "-table", "results/wave.md"),
             record="results/wave.npz"),
        # issue 23: the boundary located on N = 100 and on the infinite chain, compared with the map of kind -1
        # (results/precompression_map.npz, kept as it was: -render re-renders it); the dimers' maps likewise
        Step("precompression_map", "issue 23", "precompression_map.py",
             ("-twists", "512", "-locate", "chain,infinite", "-compare", "results/precompression_map.npz", "-output",
              "results/stability_boundary_alpha1.5.npz", "-table", "results/stability_boundary_alpha1.5.md",
              "-figures", figures), record="results/stability_boundary_alpha1.5.npz"),
        # the infinite chain's boundary located in q at fixed amplitudes, drawn on that map
        Step("boundary_in_q", "issue 23", "boundary_in_q.py",
             ("-map", "results/stability_boundary_alpha1.5.npz", "-output", "results/boundary_in_q_alpha1.5.npz",
              "-table", "results/boundary_in_q_alpha1.5.md", "-figures", figures),
             record="results/boundary_in_q_alpha1.5.npz"),
    ]
    # issue 37: the two q past the gap opening (12pi/25, pi/2) again, with the infinite chain's weak verdicts judged
    # on refined cell orbits (the maps above predate it there)
    for alpha in ("1.5", "2"):
        steps.append(Step(f"stability_boundary_gap_alpha{alpha}", "issue 37", "precompression_map.py",
                          ("-alpha", alpha, "-m", "24,25", "-twists", "512", "-locate", "chain,infinite", "-output",
                           f"results/stability_boundary_gap_alpha{alpha}.npz", "-table",
                           f"results/stability_boundary_gap_alpha{alpha}.md"),
                          record=f"results/stability_boundary_gap_alpha{alpha}.npz"))
    for eps in ("0.9", "0.7", "0.5", "0.4"):
        compare = ("-compare", f"results/precompression_map_dimer{eps}.npz") if eps in ("0.7", "0.4") else ()
        steps.append(Step(f"precompression_map_dimer{eps}", "issue 23", "precompression_map.py",
                          ("-epsilon", eps, "-m", "10,14,15,20", "-a", "0.1,0.3,1,3,10,100", "-twists", "512",
                           "-locate", "chain,infinite", *compare, "-output", f"results/stability_map_dimer{eps}.npz",
                           "-table", f"results/stability_map_dimer{eps}.md"),
                          record=f"results/stability_map_dimer{eps}.npz"))
    return steps


# the driven chains' responses (docs/driven.md): (name, ranks > 1, arguments of driven_response.py); each writes
# results/<name>.npz and .md; a figure where one is committed
DRIVEN_RESPONSES = (
    ("driven_response_N20_precompressed", False, True,
     "-N 20 -delta0 1 -gamma 0.02 -amplitude 0.2 -omega 0.3 -p_end 2.6 -max_corrector 3 -max_steps 500 -switch 20"),
    ("driven_response_N1000_precompressed", True, True,
     "-N 1000 -delta0 1 -gamma 0.05 -amplitude 0.2 -omega 0.3 -p_end 2.6 -mode grid -points 116 "
     "-grid_max_corrector 100 -jacobian mf -floquet none -run_in 30"),
    ("driven_response_N200_precompressed", False, True,
     "-N 200 -delta0 1 -gamma 0.05 -amplitude 0.2 -omega 0.3 -p_end 2.6 -max_corrector 3 -max_steps 400"),
    ("driven_response_N100_precompressed", False, False,
     "-N 100 -delta0 1 -gamma 0.02 -amplitude 0.2 -omega 0.3 -p_end 2.6 -max_corrector 3 -max_steps 1000"),
    ("driven_response_N100_precompressed_a0.5", False, False,
     "-N 100 -delta0 1 -gamma 0.02 -amplitude 0.5 -omega 0.3 -p_end 2.6 -max_corrector 3 -max_steps 1000"),
    ("driven_response_N200_precompressed_a0.5", False, False,
     "-N 200 -delta0 1 -gamma 0.02 -amplitude 0.5 -omega 0.3 -p_end 2.6 -max_corrector 3 -max_steps 1000"),
    ("driven_response_N200_vacuum_low", False, True,
     "-N 200 -delta0 0 -gamma 0.05 -amplitude 0.5 -omega 0.1 -p_end 0.6 -ds_max 0.02 -max_steps 300"),
    ("driven_response_N20_vacuum", False, True,
     "-N 20 -delta0 0 -gamma 0.05 -amplitude 0.5 -omega 1.2 -p_end 0.1 -max_steps 20"),
    ("driven_response_N20_vacuum_low", False, True,
     "-N 20 -delta0 0 -gamma 0.05 -amplitude 0.5 -omega 0.1 -p_end 0.6 -ds_max 0.02"),
)


def driven_steps(figures="figures"):
    """The driven, damped chains of the paper's Discussion (issue 22, docs/driven.md), after the refined waves the
    exact boundary driving imposes: the frequency responses, the resonances, the wave imposed at both ends, the
    simple signals; then the tables of the stability maps of kind -1 (made before issue 23 by a route since replaced:
    rendered from their files, not recomputed)."""
    steps = []
    for name, parallel, figure, args in DRIVEN_RESPONSES:
        steps.append(Step(name, "Discussion", "driven_response.py",
                          (*args.split(), "-output", f"results/{name}.npz", "-table", f"results/{name}.md",
                           *(("-figures", figures) if figure else ()), "-name", name),
                          parallel=parallel, record=f"results/{name}.npz"))
    steps += [
        Step("driven_resonances", "Discussion", "driven_resonances.py",
             ("-N", "20", "-delta0", "1", "-gamma", "0.01", "-amplitude", "1e-6", "-output",
              "results/driven_resonances.npz", "-table", "results/driven_resonances.md", "-figures", figures),
             parallel=False, record="results/driven_resonances.npz"),
        Step("driven_wave_ends", "Discussion", "driven_wave_ends.py",
             ("-branch", "results/branch_alpha1.5.npz", "-refined", "results/refined_N100.npz", "-output",
              "results/driven_wave_ends.npz", "-table", "results/driven_wave_ends.md", "-figures", figures),
             parallel=False, record="results/driven_wave_ends.npz"),
        Step("driven_generation", "Discussion", "driven_generation.py",
             ("-branch", "results/branch_alpha1.5.npz", "-N", "40", "-omegas", "0.15,0.3,0.5", "-run_in", "40",
              "-output", "results/driven_generation.npz", "-table", "results/driven_generation.md", "-figures",
              figures), parallel=False, record="results/driven_generation.npz")]
    for name in ("precompression_map", "precompression_map_dimer0.7", "precompression_map_dimer0.4"):
        steps.append(Step(f"render_{name}", "issue 16", "precompression_map.py",
                          ("-render", "-output", f"results/{name}.npz", "-table", f"results/{name}.md"),
                          parallel=False))
    return steps


class PaperPipeline:
    """Run :func:`paper_steps` (or ``only`` of them), the drivers of the repository ``root``, in the directory
    ``workdir`` (default ``root``: the steps' results/, figures/ and runs/ paths are relative to it) with ``ranks``
    ranks, keeping the progress in ``progress`` (mode new, resume or force) and each step's output in ``logs``."""

    def __init__(self, root, progress, logs, mode="new", ranks=2, steps=None, only=None, python=sys.executable,
                 workdir=None):
        steps = list(steps or paper_steps())
        names = [s.name for s in steps]
        if only:
            unknown = [n for n in only if n not in names]
            if unknown:
                raise ParameterError("-steps", ",".join(only), f"{unknown[0]!r} is not a step; the steps are "
                                     + ", ".join(names))
            steps = [s for s in steps if s.name in only]
        self.root, self.logs, self.ranks, self.python, self.steps = root, logs, ranks, python, steps
        self.workdir = workdir or root
        self.progress, self.mode, self.store = progress, mode, None

    def open(self):
        """Open the progress file, holding its lock (one pipeline writes it at a time)."""
        if self.store is None:
            make_directory(self.progress, "pipeline progress file")
            self._lock = open(self.progress + ".lock", "a+")
            try:
                fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                self._lock.seek(0)
                holder = self._lock.read().strip() or "another process"
                self._lock.close()
                raise RecordFileError(f"pipeline progress file {self.progress!r} is being written by {holder}: wait "
                                      "for it to end (or end it) before resuming") from None
            self._lock.seek(0)
            self._lock.truncate()
            self._lock.write(f"process {os.getpid()}\n")
            self._lock.flush()
            names = ",".join(s.name for s in self.steps)
            self.store = NpzRecords(self.progress, PAPER_FORMAT, dict(steps=names), dict(steps=names),
                                    PAPER_KIND.fields, None, self.mode, dtypes=PAPER_KIND.dtypes,
                                    what="pipeline progress file", columns=PAPER_KIND)
            make_directory(os.path.join(self.logs, "log"), "log")
        return self

    def _events(self, name):
        return [str(r["event"]) for r in self.store.records if str(r["name"]) == name]

    def command(self, step):
        """The command line of a step: continued (-resume) if it was interrupted and has a record, else afresh."""
        interrupted = "started" in self._events(step.name)
        args = step.arguments(interrupted and os.path.exists(os.path.join(self.workdir, step.record)))
        cmd = [self.python, os.path.join(self.root, "scripts", step.script), *args]
        return (["mpiexec", "-n", str(self.ranks), *cmd] if step.parallel and self.ranks > 1 else cmd), args

    def run(self):
        """Yield (index, step, seconds or None if it was already done, the arguments used) step by step."""
        self.open()
        for i, step in enumerate(self.steps, 1):
            if "done" in self._events(step.name):
                yield i, step, None, ()
                continue
            cmd, args = self.command(step)
            log = os.path.join(self.logs, f"{step.name}.log")
            record = os.path.join(self.workdir, step.record) if step.record else ""
            # the step's outputs must be writable before it is recorded as started (a run directory: its files)
            for path in [log] + ([os.path.join(record, "run.json") if os.path.isdir(record)
                                  or not os.path.splitext(record)[1] else record] if record else []):
                prepare_output(path, None, f"output of step {step.name}")
            self.store.append(dict(name=step.name, event="started", seconds=0.0))
            t0 = time.perf_counter()
            with open(log, "w") as out:
                rc = run_child(cmd, self.workdir, out)
            seconds = time.perf_counter() - t0
            if rc != 0:
                with open(log) as f:
                    tail = [line.strip() for line in f.read().splitlines() if line.strip()][-1:]
                raise StepFailure(f"step {i} ({step.name}, scripts/{step.script}) failed with exit status {rc}: "
                                  + (tail[0] if tail else "no output") + f" (log: {log})", rc)
            self.store.append(dict(name=step.name, event="done", seconds=seconds))
            yield i, step, seconds, args
