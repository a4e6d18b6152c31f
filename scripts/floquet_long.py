#!/usr/bin/env python3
"""Floquet multipliers modulo shifts on long chains, N = 1000 and 10^4 (section 3.5, GitHub issue 4 item 5).

    mpiexec -n 2 python scripts/floquet_long.py [-sizes 1000,10000] [-q 7*pi/25,9*pi/50,pi/50,3*pi/10]
        [-refined results/refined_N100.npz] [-branch results/branch_alpha1.5.npz] [-nev 10] [-tol_rho 1e-4]
        [-slepc_sizes 1000] [-split sectors|beads] [-output results/floquet_long.md] [-npz results/floquet_long.npz]

The wave on N = L * 100 beads at q = 2 pi m / 100 is the refined 100-bead wave tiled L times. All 2N multipliers
come from the L//2 + 1 Bloch sectors of the 100-bead cell (hertzpetsc.bloch, one TS run of 200 complex tangent
columns each, sectors dealt to the ranks); then, on the full N-bead chain and matrix-free (shell distributed
over the ranks): the residuals ||F Y - lambda Y|| / (|lambda| ||Y||) of the tiled Bloch modes of the nev dominant
multipliers, and for N in -slepc_sizes (default none: at N = 1000 it did not converge in 13 min) SLEPc
Krylov-Schur started from those modes. rho excludes the four
trivial multipliers (sector theta = 0); "outside" counts |lambda| > 1 + tol_rho over all 2N multipliers.
Flow tolerances: the paper's (rtol 1e-12, atol 1e-14; -chain_ts_rtol / -chain_ts_atol override).
PETSc prefixes: -chain_ (TS of the variational equations, cell sectors and full-chain shell), -floquet_ (SLEPc).
"""
import math
import os
import sys
import time

import petsc4py

petsc4py.init(sys.argv)
import slepc4py  # noqa: E402

slepc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

import numpy as np  # noqa: E402

from hertzpetsc.bloch import (bloch_multipliers, bloch_residuals, check_cell, real_pairs,  # noqa: E402
                              seeded_dominant_multipliers)
from hertzpetsc.branchfile import atomic_savez, read_branch, read_refined, refined_lookup  # noqa: E402
from hertzpetsc.chain import ChainParameters, IntegrationTolerances  # noqa: E402
from hertzpetsc.cli import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.errors import RunFileError  # noqa: E402
from hertzpetsc.floquet import spectral_radius  # noqa: E402
from hertzpetsc.waves import check_chain_wavenumber, wave_on_chain  # noqa: E402

Q_DEFAULT = "7*pi/25,9*pi/50,pi/50,3*pi/10"


def q_label(q):
    """q as a fraction of pi (7pi/25), from the nearest denominator <= 100."""
    from fractions import Fraction
    f = Fraction(q / math.pi).limit_denominator(100)
    return f"{f.numerator if f.numerator != 1 else ''}pi/{f.denominator}" if f.denominator != 1 else f"{f.numerator}pi"


def main():
    opts = AppOptions()
    branch_path = opts.string("branch", "results/branch_alpha1.5.npz")
    refined_path = opts.string("refined", "results/refined_N100.npz")
    sizes = opts.numbers("sizes", "1000,10000", expr=False, kind=int)
    qs = opts.numbers("q", Q_DEFAULT)
    nev = opts.integer("nev", 10, minimum=1)
    tol_rho = opts.real("tol_rho", 1e-4, valid=(lambda x: x > 0, "must be > 0"))
    slepc_sizes = opts.numbers("slepc_sizes", "", expr=False, kind=int)
    split = opts.string("split", "sectors")
    output = opts.string("output", "results/floquet_long.md")
    npz = opts.string("npz", "results/floquet_long.npz")
    comm = PETSc.COMM_WORLD
    tol = IntegrationTolerances()

    branch = read_branch(branch_path)
    refined = read_refined(refined_path)
    M = refined["N"]
    cell = ChainParameters(float(branch["alpha"]), M)
    for N in sizes:
        check_cell(N, M)
    ref100 = {}
    if os.path.exists(f"results/floquet_N{M}.npz"):
        with np.load(f"results/floquet_N{M}.npz") as z:
            ref100 = {round(float(a), 12): float(b) for a, b in zip(z["q"], z["rho"])}
    rows, store = [], dict(N=[], q=[], rho=[], rho_cell=[], outside=[], dominant=[], dominant_theta=[],
                           residual=[], seconds=[], slepc_products=[], slepc_seconds=[])
    print0(f"# cell M = {M}, ranks {comm.getSize()}, split {split}, nev {nev}")
    for N in sizes:
        for q in qs:
            w = wave_on_chain(branch, q, M)
            x = refined_lookup(refined, w.q)
            if x is None:
                raise RunFileError(f"{refined_path!r} has no refined state at q = {w.q:.12g}")
            m = check_chain_wavenumber(w.q, N)
            L = N // M
            t0 = time.perf_counter()
            b = bloch_multipliers(cell, x, w.T, N, comm, tol, split=split, n_modes=nev)
            t_bloch = time.perf_counter() - t0
            rho = spectral_radius(b.values)
            rho_cell = spectral_radius(b.sector_values(0))
            outside = int(np.sum(np.abs(b.values) > 1 + tol_rho))
            full = ChainParameters(cell.alpha, N)
            xN = np.tile(x, (L, 1))
            pairs = real_pairs(b.modes, L)
            t0 = time.perf_counter()
            res, res_products = bloch_residuals(full, xN, w.T, pairs, comm, tol)
            t_res = time.perf_counter() - t0
            slepc = None
            if N in slepc_sizes:
                s = seeded_dominant_multipliers(full, xN, w.T, b, nev=nev, comm=comm, tolerances=tol)
                dist = max(float(np.min(np.abs(b.values[:nev + 2] - v))) for v in s.values)
                slepc = dict(products=s.products, seconds=s.wall_time, dist=dist, rho=float(abs(s.values[0])))
            dom = np.array([mu for mu, _, _ in b.modes])
            theta = np.array([j / L for _, j, _ in b.modes])          # theta / (2 pi)
            row = dict(N=N, q=w.q, m=m, L=L, rho=rho, rho_cell=rho_cell, rho100=ref100.get(round(w.q, 12)),
                       outside=outside, dom=dom, theta=theta, runs=b.runs, columns=b.columns, t_bloch=t_bloch,
                       res=float(np.max(res)), res_products=res_products, t_res=t_res, slepc=slepc)
            rows.append(row)
            for k, v in (("N", N), ("q", w.q), ("rho", rho), ("rho_cell", rho_cell), ("outside", outside),
                         ("dominant", dom), ("dominant_theta", theta), ("residual", row["res"]),
                         ("seconds", t_bloch), ("slepc_products", slepc["products"] if slepc else -1),
                         ("slepc_seconds", slepc["seconds"] if slepc else np.nan)):
                store[k].append(v)
            print0(f"  N {N:6d} q {q_label(w.q):>8} rho {rho:.8f} (cell {rho_cell:.8f}) outside {outside:5d} "
                   f"bloch {t_bloch:7.1f} s ({b.runs} runs), residual {row['res']:.1e} ({res_products} products, "
                   f"{t_res:.1f} s)" + (f", SLEPc {slepc['products']} products {slepc['seconds']:.1f} s, "
                                        f"|diff| {slepc['dist']:.1e}" if slepc else ""))
            if comm.getRank() == 0:
                atomic_savez(npz, **{k: np.array(v) for k, v in store.items()})
    lines = [f"Floquet multipliers modulo shifts on N = L x {M} beads (the refined {M}-bead wave tiled), by Bloch "
             f"sectors theta_j = 2 pi j / L of the {M}-bead cell (hertzpetsc.bloch), {comm.getSize()} rank(s), "
             f"sectors split over ranks ({split}); flow rtol {tol.rtol:g}, atol {tol.atol:g}. rho excludes the 4 "
             f"trivial multipliers; outside: |lambda| > 1 + {tol_rho:g} among all 2N. rho(cell) is sector theta = 0, "
             f"i.e. the N = {M} chain; rho(N={M} table) is results/floquet_table_N{M}.md (rtol 1e-14). Residual: "
             "max relative ||F Y - lambda Y|| of the tiled Bloch modes of the dominant multipliers on the full "
             f"chain (matrix-free, {2} shell products per complex pair). SLEPc: Krylov-Schur on the full-chain shell "
             "started from those modes (products, time, max distance of its multipliers to the Bloch ones).\n",
             "| N | q | m | rho(F_q) | rho(cell) | rho(N=100 table) | outside | Bloch runs x columns | Bloch time (s) "
             "| residual (products, s) | SLEPc seeded (products, s, max diff) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ref = f"{r['rho100']:.8f}" if r["rho100"] is not None else "n/a"
        sl = (f"{r['slepc']['products']}, {r['slepc']['seconds']:.1f}, {r['slepc']['dist']:.1e}" if r["slepc"]
              else "not run")
        lines.append(f"| {r['N']} | {q_label(r['q'])} | {r['m']} | {r['rho']:.8f} | {r['rho_cell']:.8f} | {ref} | "
                     f"{r['outside']} | {r['runs']} x {r['columns'] // r['runs']} | {r['t_bloch']:.1f} | "
                     f"{r['res']:.1e} ({r['res_products']}, {r['t_res']:.1f}) | {sl} |")
    lines.append(f"\nThe {nev} dominant multipliers (|lambda|, arg lambda / pi, theta / 2 pi):\n")
    for r in rows:
        dom = ", ".join(f"{abs(v):.6f} @ {np.angle(v) / math.pi:+.4f} [{t:.3f}]" for v, t in zip(r["dom"], r["theta"]))
        lines.append(f"- N = {r['N']}, q = {q_label(r['q'])}: {dom}")
    text = "\n".join(lines) + "\n"
    if comm.getRank() == 0:
        tmp = f"{output}.tmp-{os.getpid()}"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, output)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
