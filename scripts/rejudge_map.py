#!/usr/bin/env python3
"""The weak infinite-chain verdicts of a stability-map or boundary-in-q file judged again on the refined cell orbit
(issue 37).

    python scripts/rejudge_map.py -source results/stability_boundary_alpha1.5.npz
        [-output runs/rejudge_map.npz] [-table runs/rejudge_map.md] [-resume | -force | -render]

Every record of -source (precompression_map.py's or boundary_in_q.py's file) whose infinite-chain verdict is a weak
instability, tol_rho < rho - 1 < 1e-3, judged on the Richardson cell orbit (no E_cell) is judged again with the
file's own parameters by the map's route: the wave at the record's q and amplitude, the twist scan of its cell orbit,
then that orbit refined by Gauss-Newton to E <= 1e-11 and scanned again with the flow at rtol/100. The q are dealt
to the ranks. Table: per record the old and new rho - 1 and verdicts, the refined orbit's E, and how many verdicts
changed. -render computes nothing: it rewrites -table from -output.
"""
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import check_kind, load_npz, on_rank0, prepare_outputs, write_text  # noqa: E402
from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.studies.rejudge import REJUDGE_FORMAT, MapRejudging, RejudgeParameters, rejudging_table  # noqa: E402


def main():
    opts = AppOptions(__doc__, MapRejudging.ROLES)
    source = opts.path("source", "", "the stability-map or boundary-in-q file whose weak verdicts are judged again")
    output = opts.path("output", "runs/rejudge_map.npz", "re-judging file (record store)")
    mode = opts.mode()
    table_path = opts.path("table", "runs/rejudge_map.md", "table")
    render = opts.render_flag()
    opts.done()
    comm = PETSc.COMM_WORLD
    if render:
        def read():
            z = on_rank0(comm, lambda: load_npz(output, "re-judging file"), what="re-judging file")
            check_kind(z, output, REJUDGE_FORMAT, "re-judging file")
            return z
        opts.render(mode, read, lambda z: write_table(comm, table_path, rejudging_table(z)), table_path, "",
                    computation=("source",))
        return
    if not source:
        raise ParameterError("-source", "(none)", "give the stability-map or boundary-in-q file to judge again")
    prepare_outputs(comm, table_path)
    study = MapRejudging(RejudgeParameters(source), comm, output, mode)
    study.configure()
    opts.check_unused()
    study.open()
    print0(f"# {source}: {len(study.todo)} weak infinite-chain verdicts to judge again "
           f"({study.planned()} not in {output} yet)")
    print0(f"# {'index':>5} {'q':>8} {'A':>10} {'old - 1':>10} {'unrefined':>10} {'new - 1':>10} {'E_cell':>8} "
           f"{'s':>6}")
    text = study.run_to_table(table_path, lambda r: print0(
        f"  {r['index']:5d} {r['q']:8.5f} {r['A']:10.5g} {r['rho_old'] - 1:10.3e} {r['rho_unrefined'] - 1:10.3e} "
        f"{r['rho_new'] - 1:10.3e} {r['E_cell']:8.1e} {r['seconds']:6.1f}"))
    study.destroy()
    print0(text)


def write_table(comm, path, text):
    write_text(path, text, comm)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
