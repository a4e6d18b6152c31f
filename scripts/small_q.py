#!/usr/bin/env python3
"""The branch down to q = pi/400 with the grid refined as q decreases; Richardson extrapolation in h (sec. 3.2).

    mpiexec -n 2 python scripts/small_q.py [-q_stop pi/400] [-per_halving 4] [-cells_per_q 20] [-levels 3]
        [-progress runs/small_q.npz] [-resume] [-output results/small_q.md] [-figures figures]

Level l keeps q / h >= cells_per_q 2^l, doubling the grid each time q halves below pi/50 (hertzpetsc.smallq);
the levels are the three resolutions of the extrapolation. After every converged point the progress file
(npz: per level the q, K, diagnostics and the last two profiles) is rewritten atomically; -resume continues a
killed run from it. The table gives, at every target q, ||u||_inf q^(2/(alpha-1)) on each level, its observed
order and extrapolated value against k_alpha of the solitary wave (hertzpetsc.solitary, extrapolated in its own
grid step), and the extrapolated ||u||_inf, p(q), N(q). Figure smallq.png: the product on each level and
extrapolated, against q, with k_alpha.
PETSc prefixes: -tw_ (travelling-wave SNES), -sol_ (solitary wave).
"""
import json
import math
import os
import sys

import petsc4py

petsc4py.init(sys.argv)
from petsc4py import PETSc  # noqa: E402

import numpy as np  # noqa: E402

from hertzpetsc.branchfile import atomic_savez, load_npz  # noqa: E402
from hertzpetsc.cli import AppOptions, guarded_main, print0, run_metadata  # noqa: E402
from hertzpetsc.errors import ParameterError, RunFileError  # noqa: E402
from hertzpetsc.smallq import FIELDS, SmallQParameters, continue_refining, richardson  # noqa: E402
from hertzpetsc.solitary import SolitaryParameters, solve_solitary_wave  # noqa: E402


def load_progress(path, params, levels):
    """{level: [(q, K, diagnostics)]} and {level: [(q, K, u_half)] (last two)} from a progress file."""
    data = load_npz(path, "progress file", RunFileError)
    stored = json.loads(str(data["params"]))
    if stored != params_dict(params, levels):
        raise ParameterError("-resume", path, f"the progress file was made with {stored}; "
                                              "rerun with those options or without -resume")
    rows, seeds = {}, {}
    for lev in range(levels):
        key = f"L{lev}_"
        if key + "q" not in data:
            continue
        rows[lev] = [(float(q), int(K), {f: float(data[key + f][i]) for f in FIELDS})
                     for i, (q, K) in enumerate(zip(data[key + "q"], data[key + "K"]))]
        seeds[lev] = [(float(data[key + f"seed{j}_q"]), int(data[key + f"seed{j}_K"]), data[key + f"seed{j}_u"])
                      for j in range(2) if key + f"seed{j}_q" in data]
    return rows, seeds


def params_dict(params, levels):
    return dict(alpha=params.alpha, q_stop=params.q_stop, q_first=params.q_first, per_halving=params.per_halving,
                cells_per_q=params.cells_per_q, levels=levels)


def save_progress(path, params, levels, rows, seeds):
    arrays = dict(params=json.dumps(params_dict(params, levels)))
    for lev, r in rows.items():
        key = f"L{lev}_"
        arrays[key + "q"] = np.array([x[0] for x in r])
        arrays[key + "K"] = np.array([x[1] for x in r])
        for f in FIELDS:
            arrays[key + f] = np.array([x[2][f] for x in r])
        for j, (q, K, u) in enumerate(seeds.get(lev, [])):
            arrays[key + f"seed{j}_q"], arrays[key + f"seed{j}_K"], arrays[key + f"seed{j}_u"] = q, K, u
    atomic_savez(path, **arrays)


def k_alpha_extrapolated(alpha):
    ks = [solve_solitary_wave(SolitaryParameters(alpha, n, 8.0), PETSc.COMM_SELF).k_alpha for n in (80, 160, 320)]
    return richardson(ks)[1]


def main():
    opts = AppOptions()
    params = SmallQParameters(alpha=opts.real("alpha", 1.5), q_stop=opts.real("q_stop", math.pi / 400, expr=True),
                              per_halving=opts.integer("per_halving", 4, minimum=1),
                              cells_per_q=opts.integer("cells_per_q", 20, minimum=4))
    levels = opts.integer("levels", 3, minimum=3)
    progress = opts.string("progress", "runs/small_q.npz")
    output = opts.string("output", "results/small_q.md")
    figures = opts.string("figures", "")
    rank0 = PETSc.COMM_WORLD.getRank() == 0
    rows, seeds = load_progress(progress, params, levels) if opts.flag("resume") else ({}, {})
    if rank0:
        os.makedirs(os.path.dirname(progress) or ".", exist_ok=True)
    for lev in range(levels):
        rows.setdefault(lev, [])
        if rows[lev] and rows[lev][-1][0] <= params.q_stop * (1 + 1e-12):
            continue

        def save(q, K, u_half, diag, lev=lev):
            rows[lev].append((q, K, {f: diag[f] for f in FIELDS}))
            seeds[lev] = (seeds.get(lev, []) + [(q, K, u_half)])[-2:]
            if rank0:
                save_progress(progress, params, levels, rows, seeds)
            print0(f"level {lev}: q = pi/{math.pi / q:7.2f}  K = {K:6d}  ||u|| q^(2/(alpha-1)) = "
                   f"{diag['rescaled_norm']:.7f}  N = {diag['N']:.5f}")

        for _ in continue_refining(params, lev, done=seeds.get(lev), on_point=save):
            pass
    k_alpha = k_alpha_extrapolated(params.alpha)
    targets = params.targets()
    lookup = [{round(q, 12): d for q, K, d in rows[lev]} for lev in range(levels)]
    table = {f: np.array([[lookup[lev][round(q, 12)][f] for q in targets] for lev in range(levels)]) for f in FIELDS}
    K_fine = dict((round(q, 12), K) for q, K, d in rows[levels - 1])
    ext = {f: [richardson(table[f][-3:, i]) for i in range(len(targets))] for f in FIELDS}
    lines = [f"alpha = {params.alpha}; level l keeps q/h >= {params.cells_per_q} 2^l (grid doubled each time q "
             f"halves below pi/50); k_alpha = {k_alpha:.7f} (solitary wave, n = 80, 160, 320, extrapolated). "
             "Orders and extrapolations from the three finest levels.\n",
             "| q | pi/q | K (finest) | " + " | ".join(f"product, level {lev}" for lev in range(levels))
             + " | order | product extrapolated | minus k_alpha | \\|\\|u\\|\\|_inf extrapolated | p(q) extrapolated "
             "| N(q) extrapolated | N order |", "|---" * (levels + 9) + "|"]
    for i, q in enumerate(targets):
        o, r = ext["rescaled_norm"][i]
        lines.append(f"| {q:.6f} | {math.pi / q:.2f} | {K_fine[round(q, 12)]} | "
                     + " | ".join(f"{table['rescaled_norm'][lev, i]:.7f}" for lev in range(levels))
                     + f" | {o:.2f} | {r:.7f} | {r - k_alpha:+.2e} | {ext['norm_inf'][i][1]:.6e} | "
                     f"{ext['slope'][i][1]:.6e} | {ext['N'][i][1]:.5f} | {ext['N'][i][0]:.2f} |")
    text = "\n".join(lines) + "\n"
    if rank0:
        with open(output, "w") as f:
            f.write(text)
        with open(os.path.splitext(output)[0] + ".json", "w") as f:
            json.dump(dict(meta=run_metadata(), k_alpha=k_alpha, q=targets,
                           product=[e[1] for e in ext["rescaled_norm"]], N=[e[1] for e in ext["N"]]), f, indent=1)
        if figures:
            from hertzpetsc import plotting
            plotting.plot_small_q(np.array(targets), table["rescaled_norm"],
                                  np.array([e[1] for e in ext["rescaled_norm"]]), k_alpha, figures)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
