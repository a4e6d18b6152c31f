#!/usr/bin/env python3
"""Every study of the paper's sections 3.1-3.5 and its appendix, in order, regenerating the tables and figures
the README quotes for them (hertzpetsc.studies.paper; the benchmarks are separate: they need an idle machine).

    python scripts/paper.py [-ranks 2] [-steps branch,paper_table,...] [-progress runs/paper.npz] [-resume | -force]
        [-logs runs/paper_logs] [-workdir DIR]

One progress line per step (its section, the time it took) and the total; on a terminal also the time
left at the pace of the steps so far. Each step's output goes to
<logs>/<step>.log. A killed pipeline continues with -resume: finished steps are skipped, an interrupted one
continues from its own record file where its driver has one. Called by `bash scripts/hz.sh paper`.
"""
import os
import sys
import time

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)

from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.progress import Progress  # noqa: E402
from hertzpetsc.studies.paper import PaperPipeline, paper_steps  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    opts = AppOptions(__doc__)
    ranks = opts.integer("ranks", 2, "ranks of the parallel steps", minimum=1)
    names = [s.name for s in paper_steps()]
    only = opts.words("steps", ",".join(names), "steps to run, in the pipeline's order", choices=names)
    progress = opts.path("progress", "runs/paper.npz", "progress file (record store)")
    logs = opts.path("logs", "runs/paper_logs", "directory of the steps' logs")
    workdir = opts.path("workdir", "", "directory the steps run in: their results/, figures/ and runs/ are there "
                        "(none if empty: the repository's)")
    mode = opts.mode()
    opts.done()
    if workdir and not os.path.isdir(workdir):
        raise ParameterError("-workdir", workdir, "must be an existing directory")
    opts.check_unused()
    pipeline = PaperPipeline(ROOT, os.path.join(ROOT, progress), os.path.join(ROOT, logs), mode, ranks,
                             only=only if only != names else None,
                             workdir=os.path.abspath(workdir) if workdir else None)
    t0 = time.perf_counter()
    n = len(pipeline.steps)
    progress = Progress(n, "steps", "pipeline", interval=0.0)        # on a terminal: the time left after each step
    for i, step, seconds, args in pipeline.run():
        how = "done before" if seconds is None else f"{seconds:8.1f} s" + (" (resumed)" if "-resume" in args else "")
        print0(f"[{i:2d}/{n}] sec. {step.section:8s} {step.name:24s} {how}")
        if seconds is None:
            progress.start += 1                                        # not at this run's pace
        elif i < n:
            progress.update(i)
    print0(f"total {time.perf_counter() - t0:.1f} s for {n} steps")


if __name__ == "__main__":
    guarded_main(main)
