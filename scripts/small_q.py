#!/usr/bin/env python3
"""The branch down to q = pi/400 with the grid refined as q decreases; Richardson extrapolation in h (sec. 3.2).

    mpiexec -n 2 python scripts/small_q.py [-q_stop pi/400] [-per_halving 4] [-cells_per_q 20] [-levels 3]
        [-progress runs/small_q.npz] [-resume | -force] [-output runs/small_q.md] [-figures figures]

Level l keeps q / h >= cells_per_q 2^l, doubling the grid each time q halves below pi/50 (the RefiningGrid policy
of hertzpetsc.qbranch); the levels are the three resolutions of the extrapolation. After every converged
point the progress file (a record store: the diagnostics per level and q, and the last two profiles of each
level) is rewritten atomically; -resume continues a killed run from it. The table gives, at every target q,
||u||_inf q^(2/(alpha-1)) on each level, its observed order and extrapolated value against k_alpha of the
solitary wave (extrapolated in its own grid step), and the extrapolated ||u||_inf, p(q), N(q). Figure smallq.png:
the product on each level and extrapolated, against q, with k_alpha (a JSON summary beside the table).
"""
import math
import os
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

import numpy as np  # noqa: E402

from hertzpetsc.model import law_options  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0, run_metadata  # noqa: E402
from hertzpetsc.records import prepare_outputs, write_json  # noqa: E402
from hertzpetsc.roles import uses  # noqa: E402
from hertzpetsc.studies.branch import SmallQParameters, SmallQStudy  # noqa: E402
from hertzpetsc.studies.solitary import k_alpha_extrapolated  # noqa: E402


def main():
    opts = AppOptions(__doc__, uses("tw_", "sol_"))
    law_options(opts, supported=False)      # -law: refused but hertz
    params = SmallQParameters(**opts.parameters(SmallQParameters, skip=("q_first",)))
    progress = opts.path("progress", "runs/small_q.npz", "progress file (record store)")
    mode = opts.mode()
    output, figures = opts.table_and_figures("runs/small_q.md", "smallq.png")
    opts.done()
    comm = PETSc.COMM_WORLD
    prepare_outputs(comm, output, figures=figures)
    study = SmallQStudy(params, progress, comm, mode)
    opts.check_unused()
    k_alpha, half_length = k_alpha_extrapolated(params.alpha)
    study.open()

    def show(item):
        level, q, K, d = item
        print0(f"level {level}: q = pi/{math.pi / q:7.2f}  K = {K:6d}  ||u|| q^(2/(alpha-1)) = "
               f"{d.rescaled_norm:.7f}  N = {d.N:.5f}")
    # on a stop: why there is no table
    text = study.run_to_table(output, show, lambda: study.table(k_alpha, half_length))
    write_json(os.path.splitext(output)[0] + ".json", dict(meta=run_metadata(), **study.summary(k_alpha, half_length)),
               comm)
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        table, ext, _ = study.extrapolations()
        plotting.plot_small_q(np.array(params.targets()), table["rescaled_norm"],
                              np.array([e[1] for e in ext["rescaled_norm"]]), k_alpha, figures)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
