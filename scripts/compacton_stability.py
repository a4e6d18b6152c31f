#!/usr/bin/env python3
"""Spectral stability of isolated compactons (paper section 3.3 and its Discussion): exact compactons on a window
that travels with them, and the window map's multipliers, against q, for each branch (alpha).

    mpiexec -n 2 python scripts/compacton_stability.py \
        -branches results/branch_alpha1.5.npz,runs/branch_alpha2.npz,runs/branch_alpha2.5.npz \
        [-q 1.5,...,pi/6400] [-no_solitary] [-M 18] [-rear 6] [-nev 3] [-eta 2.5] \
        [-output runs/compacton_stability.npz] [-table runs/compacton_stability.md] [-figures figures] \
        [-resume | -force]

For each branch the scan starts at the branch's largest q with F(q) >= 1 (the compacton of that branch point,
hertzpetsc.compacton, refined by Gauss-Newton on the window map), continues in q through -q (each <= q_k) and
ends at the solitary wave (q = 0, Delta = 0; the table then ends with the q -> 0 limit of the family against it)
unless -no_solitary. Per q: residual (refinement flow and an independent flow), all 2M multipliers (LAPACK), the
Jordan pair at 1, the dominant nontrivial multipliers, the unstable ones, their change when M is doubled, and SLEPc
Krylov-Schur on the exponentially weighted shell (weight exp(eta j); -nev multipliers at most, only those above
2 exp(-eta)) against LAPACK. Each (alpha, q) runs on one rank; the alphas of a continuation step are dealt to the
ranks.
Ring check (-ring_q, skipped with -no_ring): the exact compacton of the first alpha at each -ring_q on a periodic
chain of 2 pi / q beads, which is the paper's periodic wave: rho(F_q) with the feedback, against the isolated one.
"""
import math
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
import slepc4py  # noqa: E402

slepc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.branch import Branch  # noqa: E402
from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.resources import MAX_DENSE_BEADS  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs, write_text  # noqa: E402
from hertzpetsc.roles import uses  # noqa: E402
from hertzpetsc.waves import fits_chain  # noqa: E402
from hertzpetsc.studies.compacton_stability import (DEFAULT_QS, TOL_UNSTABLE, CompactonStabilityScan,  # noqa: E402
                                                    ring_spectrum)

PI_50 = 0.06283185307179587        # the figure's second spectrum: the q nearest pi/50
ROLES = dict(CompactonStabilityScan.ROLES, **uses(floquet_=("ts",)))     # the ring check's dense monodromy


def main():
    opts = AppOptions(__doc__, ROLES)
    paths = opts.path("branches", "results/branch_alpha1.5.npz", "branch files (comma-separated), one per alpha")
    qs = opts.numbers("q", DEFAULT_QS, "wavenumbers below the branch's start, each in (0, q_k]",
                      valid=(lambda q: q > 0, "> 0"), distinct=True, minimum_count=0)
    solitary = not opts.flag("no_solitary", "skip the solitary wave (q = 0, Delta = 0)")
    M = opts.integer("M", 18, "beads of the window (its dense map and the doubled window's: (4M)^2 entries)",
                     minimum=8, maximum=MAX_DENSE_BEADS // 4)
    rear = opts.integer("rear", 6, "beads at rest behind the compression zone in the starting window", minimum=2)
    nev = opts.integer("nev", 3, "dominant multipliers asked of SLEPc (at most 2M)", minimum=1)
    eta = opts.real("eta", 2.5, "exponential weight exp(eta j) of the SLEPc operator", valid=(lambda x: x >= 0,
                                                                                                ">= 0"))
    ring_qs = opts.numbers("ring_q", "pi/25,pi/50", "q of the ring check (the scan's first alpha; 2 pi / q beads)",
                           valid=(lambda q: q > 0, "> 0"))
    if opts.flag("no_ring", "skip the ring check"):
        ring_qs = []
    tol = opts.real("tol_unstable", TOL_UNSTABLE, "unstable: |mu| > 1 + tol_unstable", valid=(lambda x: x > 0, "> 0"))
    output, mode, table, figures = opts.record_table_figures(
        "runs/compacton_stability.npz", "compacton stability file", "runs/compacton_stability.md",
        "compacton_stability_mu.png and compacton_stability_spectra.png")
    opts.done()
    if nev > 2 * M:
        raise ParameterError("-nev", nev, f"the window map has dimension 2M = {2 * M}: 1 <= nev <= {2 * M}")
    comm = PETSc.COMM_WORLD
    files = [p.strip() for p in paths.split(",") if p.strip()]
    if not files:
        raise ParameterError("-branches", paths, "must name at least one branch file")
    prepare_outputs(comm, table, figures=figures)
    branches = [Branch.load(p, comm) for p in files]
    for b, p in zip(branches, files):
        if not b.alpha > 1:
            raise ParameterError("alpha", b.alpha, f"the Hertz exponent of {p} must be > 1")
    scan = CompactonStabilityScan(branches, qs, comm, output, mode, M, rear, nev, eta, solitary, tol)
    a0 = min(b.alpha for b in branches)
    for q in ring_qs:                            # checked now, not after the scan
        if not any(abs(x - q) <= 1e-12 * max(1.0, q) for x in scan.sequences[a0]):
            raise ParameterError("-ring_q", q, f"must be one of the scanned q at alpha = {a0:g} (-q), or give "
                                 "-no_ring to skip the ring check")
        if not (fits_chain(q, round(2 * math.pi / q)) and round(2 * math.pi / q) >= M + 2):
            raise ParameterError("-ring_q", q, f"the ring needs 2 pi / q to be a whole number of beads >= M + 2 = "
                                 f"{M + 2}")
    opts.check_unused()
    scan.open()
    print0(f"# M = {M}, rear = {rear}, eta = {eta:g}, nev = {nev}; q per alpha: " +
           "; ".join(f"{a:g}: {len(s)}" for a, s in scan.sequences.items()))
    print0(f"# {'alpha':>5} {'q':>9} {'residual':>9} {'check':>9} {'pair mean':>16} {'max|mu|':>9} {'unst':>4} "
           f"{'2M chg':>8} {'SLEPc':>8} {'s':>5}")

    def records_text():
        text = scan.summary() + "\n" + scan.table()
        if solitary:
            text += ("\nThe q -> 0 end of the family: the three smallest q extrapolated to q = 0 (Richardson with "
                     "the leading order 1: the gap Delta = q D / 2 pi opens every bond by O(q)) against the solitary "
                     "wave itself.\n\n" + scan.limit_table())
        return text
    try:                                         # on a stop: the table of the records done
        text = scan.run_to_table(table, lambda r: print0(
            f"  {r['alpha']:5g} {r['q']:9.6f} {r['residual']:9.1e} {r['residual_check']:9.1e} "
            f"{r['jordan_mean']:16.13f} {r['max_nontrivial']:9.6f} {r['unstable']:4d} "
            f"{r['doubling_change']:8.1e} {r['slepc_change']:8.1e} {r['seconds']:5.1f}"), records_text)
    finally:
        scan.destroy()
    if ring_qs:
        lines = [f"\nThe same exact compactons (alpha = {a0:g}) on a periodic chain of N = 2 pi / q beads, i.e. the "
                 "paper's periodic waves, with the dense F_q = S R(script-T) (hertzpetsc.floquet, -floquet_ flow): "
                 "rho excludes the 4 trivial multipliers; outside: |mu| > 1 + 1e-4; residual: max|S X(1) - X(0) - "
                 "(Delta, 0)|.\n", "| q | N | residual | rho(F_q) | multipliers outside | max nontrivial \\|mu\\| "
                 "isolated (window) |", "|---|---|---|---|---|---|"]
        for q in ring_qs:
            rec = scan.record(a0, q)
            model = next(b for b in branches if b.alpha == a0).model
            N, spectrum, residual = ring_spectrum(rec, model, comm)
            lines.append(f"| {q:.6f} | {N} | {residual:.1e} | {spectrum.rho:.6f} | {spectrum.outside} | "
                         f"{float(rec['max_nontrivial']):.6f} |")
            print0(lines[-1])
        text += "\n".join(lines) + "\n"
        write_text(table, text, comm)
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        rows = scan.rows()
        print("wrote " + plotting.plot_compacton_max_multiplier(rows, figures).path, flush=True)
        a0 = min(float(r["alpha"]) for r in rows)
        mine = [r for r in rows if float(r["alpha"]) == a0]
        positive = [r for r in mine if float(r["q"]) > 0] or mine
        picks = [max(mine, key=lambda r: float(r["q"])), min(positive, key=lambda r: abs(float(r["q"]) - PI_50))]
        print("wrote " + plotting.plot_compacton_spectra(picks, eta, figures).path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
