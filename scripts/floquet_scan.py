#!/usr/bin/env python3
"""Floquet multipliers modulo shifts along the branch (paper section 3.5, figs. floquet and eigen).

    mpiexec -n 2 python scripts/floquet_scan.py [-refined results/refined_N100.npz] [-branch ...] [-N 100]
        [-method dense|slepc] [-nev 10] [-tol_rho 1e-4] [-check_q 9*pi/50] [-output results/floquet_N100.npz]
        [-table results/floquet_table_N100.md] [-figures figures] [-resume]

Around the refined waves of -refined (the branch wave of -branch where a q has no refined state): rho(F_q)
without the four trivial multipliers (translation, time shift, Jordan partners), the number of multipliers
with |lambda| > 1 + tol_rho, the spread of the trivial ones, the growth rate ln(rho)/script-T; then
q_c (the largest q with rho - 1 > tol_rho, bracketed by its stable neighbour) and q_m (max rho).
tol_rho: an O(eps) error in the orbit splits double multipliers (the trivial Jordan blocks, Krein collisions)
by O(sqrt(eps)); with eps ~ 1e-10 (refined E plus the flow's error) that is ~1e-5, and tol_rho = 1e-4 keeps a
factor 10. -check_q: rho(Phi_q) of the full-period monodromy against rho(F_q)^(N/m) at that q.
Dense route: LAPACK dgeev on the assembled F_q; slepc: Krylov-Schur on the shell operator (the nev dominant).
PETSc prefixes: -chain_ (TS of the variational equations), -floquet_ (SLEPc EPS, e.g. -floquet_eps_ncv).
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

from hertzpetsc.branchfile import atomic_savez, read_branch, read_refined, refined_lookup  # noqa: E402
from hertzpetsc.chain import ChainParameters  # noqa: E402
from hertzpetsc.cli import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.floquet import (dense_monodromy, dense_multipliers, dominant_multipliers, spectral_radius,  # noqa
                                trivial_multipliers)
from hertzpetsc.shooting import MEASURE_TOLERANCES  # noqa: E402
from hertzpetsc.waves import chain_wavenumbers, wave_on_chain  # noqa: E402

EIGEN_Q = (("3pi/10", 3 * math.pi / 10), ("7pi/25", 7 * math.pi / 25), ("9pi/50", 9 * math.pi / 50),
           ("pi/50", math.pi / 50))


def states(branch, refined, N, q):
    """Initial state (refined if available) and script-T for wavenumber q."""
    w = wave_on_chain(branch, q, N)
    x = refined_lookup(refined, w.q) if refined is not None else None
    if x is not None:
        return x, w.T, "refined"
    return w.as_array(), w.T, "branch"


def main():
    opts = AppOptions()
    branch_path = opts.string("branch", "results/branch_alpha1.5.npz")
    refined_path = opts.string("refined", "results/refined_N100.npz")
    N = opts.integer("N", 100, minimum=3)
    method = opts.string("method", "dense" if N <= 400 else "slepc")
    if method not in ("dense", "slepc"):
        raise ParameterError("-method", method, "must be dense or slepc")
    nev = opts.integer("nev", 10, minimum=1)
    tol_rho = opts.real("tol_rho", 1e-4, valid=(lambda x: x > 0, "must be > 0"))
    check_q = opts.real("check_q", 9 * math.pi / 50, expr=True)
    output = opts.string("output", f"results/floquet_N{N}.npz")
    table_path = opts.string("table", f"results/floquet_table_N{N}.md")
    figures = opts.string("figures", "")
    q_list = opts.numbers("q", "")
    comm = PETSc.COMM_WORLD
    rank0 = comm.getRank() == 0

    branch = read_branch(branch_path)
    refined = read_refined(refined_path) if refined_path and os.path.exists(refined_path) else None
    if refined is not None and refined["N"] != N:
        refined = None
    params = ChainParameters(float(branch["alpha"]), N)
    qs = q_list or chain_wavenumbers(branch["q"], N)
    rows = dict(q=[], rho=[], outside=[], trivial_spread=[], growth=[], source=[], seconds=[])
    spectra = []
    print0(f"# N = {N}, method {method}, tol_rho = {tol_rho:g}")
    print0(f"# {'q':>8} {'rho(F_q)':>12} {'outside':>7} {'trivial spread':>14} {'state':>8} {'s':>6}")
    warm = None
    for q in qs:
        x0, T, source = states(branch, refined, N, q)
        t0 = time.perf_counter()
        if method == "dense":
            lam = dense_multipliers(dense_monodromy(params, x0, T, comm, MEASURE_TOLERANCES))
        else:
            res = dominant_multipliers(params, x0, T, nev, comm, MEASURE_TOLERANCES, initial_space=warm,
                                       keep_vectors=True)
            lam = res.values
            if warm:
                for v in warm:
                    v.destroy()
            warm = res.vectors
        secs = time.perf_counter() - t0
        rho = spectral_radius(lam, exclude_trivial=(method == "dense"))
        triv = np.abs(lam[trivial_multipliers(lam)] - 1).max() if method == "dense" else float("nan")
        outside = int(np.sum(np.abs(lam) > 1 + tol_rho))
        for k, v in zip(rows, (q, rho, outside, triv, math.log(rho) / T, source, secs)):
            rows[k].append(v)
        spectra.append(np.pad(lam, (0, 2 * N - len(lam)), constant_values=np.nan))
        print0(f"  {q:8.5f} {rho:12.8f} {outside:7d} {triv:14.2e} {source:>8} {secs:6.1f}")
        if rank0:
            atomic_savez(output, q=np.array(rows["q"]), rho=np.array(rows["rho"]), outside=np.array(rows["outside"]),
                         trivial_spread=np.array(rows["trivial_spread"]), growth=np.array(rows["growth"]),
                         multipliers=np.array(spectra), N=np.asarray(N), tol_rho=np.asarray(tol_rho),
                         method=np.array(method))
    q, rho = np.array(rows["q"]), np.array(rows["rho"])
    unstable = rho - 1 > tol_rho
    lines = [f"N = {N}, {method} route, tight flow (rtol 1e-14); rho excludes the 4 trivial multipliers; "
             f"unstable: rho - 1 > {tol_rho:g}.\n",
             "| q | rho(F_q) | multipliers outside | trivial spread | ln(rho)/script-T | state |", "|---|---|---|---|---|---|"]
    for i in np.argsort(-q):
        lines.append(f"| {q[i]:.4f} | {rho[i]:.8f} | {rows['outside'][i]} | {rows['trivial_spread'][i]:.1e} | "
                     f"{rows['growth'][i]:.4f} | {rows['source'][i]} |")
    if unstable.any() and (~unstable).any():
        qc_hi = q[~unstable & (q > q[unstable].max())].min() if (~unstable & (q > q[unstable].max())).any() else None
        qc = q[unstable].max()
        lines.append(f"\nq_c in ({qc:.4f}, {qc_hi:.4f}]: largest unstable q = {qc:.4f}, next stable q = {qc_hi:.4f} "
                     "(rho - 1 jumps from 0 at the threshold, so the bracket is the resolution of the q grid)")
    im = int(np.argmax(rho))
    lines.append(f"q_m (max rho) = {q[im]:.4f}, rho = {rho[im]:.6f}; max growth per unit time at q = "
                 f"{q[int(np.argmax(rows['growth']))]:.4f}")
    if check_q and any(abs(check_q - qq) < 1e-9 for qq in q) and method == "dense":
        x0, T, _ = states(branch, refined, N, check_q)
        m = int(round(N * check_q / (2 * math.pi)))
        tau = N / m * T
        Phi = dense_monodromy(params, x0, tau, comm, MEASURE_TOLERANCES, shift=False)
        rho_phi = spectral_radius(dense_multipliers(Phi))
        i = int(np.argmin(np.abs(q - check_q)))
        lines.append(f"consistency at q = {check_q:.4f} (m = {m}): rho(Phi_q) = {rho_phi:.6f} over tau = {tau:.4f}, "
                     f"rho(F_q)^(N/m) = {rho[i] ** (N / m):.6f}, relative difference "
                     f"{abs(rho_phi - rho[i] ** (N / m)) / rho_phi:.1e}")
    text = "\n".join(lines) + "\n"
    if rank0:
        with open(table_path, "w") as f:
            f.write(text)
        if figures:
            from hertzpetsc import plotting
            os.makedirs(figures, exist_ok=True)
            print0("wrote " + plotting.plot_floquet_radius(q, rho, tol_rho, figures))
            sel = [(label, int(np.argmin(np.abs(q - qq)))) for label, qq in EIGEN_Q if np.min(np.abs(q - qq)) < 1e-9]
            print0("wrote " + plotting.plot_multipliers([(label, spectra[i]) for label, i in sel], figures))
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
