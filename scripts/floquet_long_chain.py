#!/usr/bin/env python3
"""Dominant Floquet multipliers modulo shifts on long chains, matrix-free (paper section 3.5, beyond N = 100).

    mpiexec -n 2 python scripts/floquet_long_chain.py -N 1000,10000 -q 3*pi/10,9*pi/50 [-nev 10]
        [-refined results/refined_N100.npz] [-output results/floquet_long_chains.md]

The wave on N beads (q = 2 pi m / N on the same wavenumbers) is the refined N = 100 state repeated N/100
times: a travelling wave on 100 beads is one on every multiple of 100 beads, so the long chain gets the
refined accuracy without a 2N-column refinement. SLEPc Krylov-Schur on the shell operator S R(script-T; 0)
(each product integrates the chain and one tangent vector over script-T with the tight flow) gives the nev
multipliers of largest magnitude; reported with wall time and the number of operator products.
PETSc prefixes: -chain_ (TS), -floquet_ (EPS, e.g. -floquet_eps_ncv, -floquet_eps_tol).
"""
import math
import sys
import time

import petsc4py

petsc4py.init(sys.argv)
import slepc4py  # noqa: E402

slepc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

import numpy as np  # noqa: E402

from hertzpetsc.branchfile import read_branch, refined_state  # noqa: E402
from hertzpetsc.chain import ChainParameters  # noqa: E402
from hertzpetsc.cli import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.floquet import dominant_multipliers  # noqa: E402
from hertzpetsc.shooting import MEASURE_TOLERANCES  # noqa: E402
from hertzpetsc.waves import wave_on_chain  # noqa: E402


def tiled_state(branch, refined_path, q, N, base=100):
    """The refined base-bead state repeated N/base times (the branch wave if the refined file lacks q)."""
    w = wave_on_chain(branch, q, N)
    if N % base:
        return w.as_array(), w.T, "branch"
    x = refined_state(refined_path, w.q, base) if refined_path else None
    if x is None:
        return w.as_array(), w.T, "branch"
    return np.tile(x, (N // base, 1)), w.T, f"refined N={base}, tiled"


def main():
    opts = AppOptions()
    branch = read_branch(opts.string("branch", "results/branch_alpha1.5.npz"))
    refined_path = opts.string("refined", "results/refined_N100.npz")
    try:
        sizes = [int(s) for s in opts.string("N", "1000,10000").split(",")]
        qs = [float(eval(s, {"__builtins__": {}}, {"pi": math.pi})) for s in
              opts.string("q", "3*pi/10,9*pi/50").split(",")]
    except Exception:
        raise ParameterError("-N/-q", opts.string("N", ""), "must be comma-separated lists") from None
    nev = opts.integer("nev", 10, minimum=1)
    output = opts.string("output", "results/floquet_long_chains.md")
    comm = PETSc.COMM_WORLD
    lines = [f"Dominant multipliers of F_q = S R(script-T; 0), SLEPc Krylov-Schur on the shell operator, nev = {nev}, "
             f"{comm.getSize()} rank(s), tight flow (rtol 1e-14).\n",
             "| N | q | state | rho(F_q) | leading multipliers (modulus) | products | EPS iterations | wall (s) |",
             "|---|---|---|---|---|---|---|---|"]
    for N in sizes:
        for q in qs:
            x0, T, source = tiled_state(branch, refined_path, q, N)
            t0 = time.perf_counter()
            res = dominant_multipliers(ChainParameters(float(branch["alpha"]), N), x0, T, nev, comm,
                                       MEASURE_TOLERANCES)
            wall = time.perf_counter() - t0
            mods = ", ".join(f"{abs(v):.6f}" for v in res.values[:4])
            lines.append(f"| {N} | {q:.4f} | {source} | {abs(res.values[0]):.6f} | {mods} | {res.products} | "
                         f"{res.iterations} | {wall:.1f} |")
            print0(lines[-1])
    text = "\n".join(lines) + "\n"
    if comm.getRank() == 0:
        with open(output, "w") as f:
            f.write(text)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
