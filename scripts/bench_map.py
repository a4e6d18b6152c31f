#!/usr/bin/env python3
"""Benchmark: the stability map of the precompressed chain in (q, A) and its boundary (issue 23), in one run:

* ``map``: the map (StabilityMap, the precompression_map.py driver's study) of the wavenumbers q = 2 pi m / N of -m
  times the amplitudes of -a and the geometric grid (-a_min, -a_max, -ds), all 2N multipliers on N beads (deflated
  sector route), nothing located, no infinite chain: target <= 10 min on 2 ranks for 40 q x 60 amplitudes;
* ``boundary``: the same map with the boundary located on N beads and on the infinite chain (-twists Bloch parameters
  per pi, -locate chain,infinite): target <= 30 min on 2 ranks for one alpha;
* ``boundary_q``: the boundary located in q on the infinite chain at the amplitudes A = max |u| of -levels
  (QBoundary, the boundary_in_q.py driver's study) between the wavenumbers of -m: with ``boundary``, the whole
  boundary of one alpha;
* ``dense`` against ``subset``: the route the map had before issue 23 (Richardson waves of the amplitude families,
  then the dense monodromy S R(script-T; 0) of all 2N columns over script-T on N beads, LAPACK eigenvalues) and the
  new route on the same few wavenumbers (-subset_m) and amplitudes, one rank each: the gain at equal work.

    python scripts/bench_map.py [-alpha 1.5] [-N 100] [-m 6,...,45] [-subset_m 10,15,20,25] [-a 0.1,...,1000]
        [-a_min 0.01] [-a_max 1000] [-ds 0.2302585] [-twists 1024] [-levels 0.1,0.3,1,1.5,2,3,5,10,30,100,inf]
        [-routes map,boundary,dense,subset] [-previous DIR] [-repeats 1] [-log_view] [-output runs/bench_map.md]
        [-records FILE [-resume]]

-previous DIR: the boundary routes also with the hertzpetsc of another checkout (e.g. the commit before a change:
``git worktree add DIR REV``, its compiled kernel copied or built), side by side in the same run; their records are
compared with this checkout's.

Each measurement runs in its own process (under mpiexec for 2 ranks), one BLAS thread per rank; wall times exclude
imports and include the record file's writes. With -log_view the boundary route's PETSc log (events hz_* of the
sector maps, twist scans, Floquet flows, and the SNES of the wave solves) is written beside the table
(logview_map_boundary_np2.txt; with -previous also logview_map_boundary_previous_np2.txt). Measure on an
otherwise idle machine: two ranks share the two cores.
"""
import json
import math
import os
import sys
import tempfile
import time

from benchlib import BenchRecords, best_of, declare_common, emit, machine, main_or_worker, write_report

ROUTES = ("map", "boundary", "boundary_q", "dense", "subset")
ALL_ROUTES = "map,boundary,dense,subset"
DEFAULT_LEVELS = "0.1,0.3,1,1.5,2,3,5,10,30,100,inf"
DEFAULT_M = ",".join(str(m) for m in range(6, 46))
DEFAULT_A = "0.1,0.3,0.5,0.7,1,1.5,2,3,5,10,20,30,50,100,1000"


def study_worker(name, req, petsc_args):
    """The map (StabilityMap, routes map and boundary) or the boundary in q (QBoundary at the levels req["A"],
    route boundary_q) of the wavenumbers 2 pi m / N of req["m"], on PETSc.COMM_WORLD, its records in a scratch file."""
    import petsc4py
    petsc4py.init(sys.argv[:1] + petsc_args)
    from mpi4py import MPI
    from petsc4py import PETSc

    from hertzpetsc.model import LatticeModel
    from hertzpetsc.studies.maps import (KIND_EDGE, KIND_EDGE_INF, KIND_POINT, MapParameters, QBoundary,
                                         QBoundaryParameters, StabilityMap)
    comm = PETSc.COMM_WORLD
    work = comm.tompi4py().bcast(tempfile.mkdtemp(prefix="bench_map_") if comm.getRank() == 0 else None)
    N = req["N"]
    model, qs = LatticeModel.hertz(req["alpha"], (1.0,), 1.0), tuple(2 * math.pi * m / N for m in req["m"])
    comm.tompi4py().Barrier()
    t0 = time.perf_counter()
    if name == "boundary_q":
        study = QBoundary(QBoundaryParameters(model, tuple(req["A"]), qs, twists=req["twists"]), comm,
                          f"{work}/boundary_q.npz", "force")
    else:
        study = StabilityMap(MapParameters(model, qs, tuple(req["a"]), N, twists=req["twists"],
                                           locate=tuple(req["locate"]), limit=req["limit"]), comm, f"{work}/map.npz",
                             "force")
    rows = list(study.run())
    study.destroy()
    comm.tompi4py().Barrier()
    wall = time.perf_counter() - t0
    kinds = [int(r["kind"]) for r in rows]
    if name == "boundary_q":
        emit(MPI.COMM_WORLD, wall=wall, points=len(rows) - kinds.count(KIND_EDGE_INF), edges=0,
             edges_infinite=kinds.count(KIND_EDGE_INF),
             rho={f"{float(r['q']):.12f} {float(r['A']):.12g} {int(r['kind'])}": float(r["rho_inf"]) for r in rows})
    else:
        emit(MPI.COMM_WORLD, wall=wall, points=kinds.count(KIND_POINT), edges=kinds.count(KIND_EDGE),
             edges_infinite=kinds.count(KIND_EDGE_INF),
             rho={f"{float(r['q']):.12f} {float(r['a']):.12g}": float(r["rho"]) for r in rows
                  if int(r["kind"]) == KIND_POINT})


def dense_worker(req, petsc_args):
    """The map's route before issue 23 (studies/precompression.py at 33d3841): per q the Richardson waves at every
    amplitude, then per wave the dense monodromy on N beads (DenseFloquet) and its eigenvalues."""
    import petsc4py
    petsc4py.init(sys.argv[:1] + petsc_args)
    from petsc4py import PETSc

    from hertzpetsc.chain import IntegrationTolerances
    from hertzpetsc.floquet import DenseFloquet
    from hertzpetsc.model import ChainSpec, LatticeModel
    from hertzpetsc.studies.precompression import richardson_wave, wave_orbit
    comm = PETSc.COMM_SELF
    N, K = req["N"], 1000
    model = LatticeModel.hertz(req["alpha"], (1.0,), 1.0)
    t0 = time.perf_counter()
    dense = DenseFloquet(ChainSpec(model, N), comm, IntegrationTolerances(rtol=1e-11, atol=1e-13))
    rho = {}
    try:
        for m in req["m"]:
            q = 2 * math.pi * m / N
            for a, w, lam in richardson_wave(model, q, list(req["a"]), K, comm)[:-1]:
                spec = dense.spectrum(wave_orbit(model, q, a, w, lam, N, math.pi / K))
                rho[f"{q:.12f} {a:.12g}"] = spec.rho
    finally:
        dense.destroy()
    emit(None, wall=time.perf_counter() - t0, points=len(rho), edges=0, edges_infinite=0, rho=rho)


def worker(name, req, petsc_args):
    if name == "dense":
        dense_worker(req, petsc_args)
    else:
        study_worker(name, req, petsc_args)


def main():
    from hertzpetsc.options import AppOptions
    from hertzpetsc.studies.precompression import amplitude_grid
    opts = AppOptions(__doc__)
    alpha = opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda x: x > 1, "> 1"))
    N = opts.integer("N", 100, "beads of the periodic chain", minimum=3, maximum=2000)
    ms = opts.numbers("m", DEFAULT_M, "wavelengths on the chain of the map (q = 2 pi m / N)", kind=int,
                      valid=(lambda m: 1 <= m <= N // 2, "in [1, N/2]"), distinct=True)
    subset = opts.numbers("subset_m", "10,15,20,25", "wavelengths of the side-by-side comparison with the dense route",
                          kind=int, valid=(lambda m: 1 <= m <= N // 2, "in [1, N/2]"), distinct=True)
    amps = opts.numbers("a", DEFAULT_A, "amplitudes (first sine coefficient of u)", valid=(lambda x: x > 0, "> 0"),
                        distinct=True)
    a_min = opts.real("a_min", 0.01, "smallest amplitude of the geometric grid", valid=(lambda x: x > 0, "> 0"))
    a_max = opts.real("a_max", 1000.0, "largest amplitude of the geometric grid", valid=(lambda x: x > 0, "> 0"))
    ds = opts.real("ds", math.log(10) / 10, "step in log a of the geometric grid (0: none)",
                   valid=(lambda x: x >= 0, ">= 0"))
    twists = opts.integer("twists", 1024, "infinite chain of the boundary route: Bloch parameters per pi", minimum=1)
    levels = opts.numbers("levels", DEFAULT_LEVELS, "amplitudes A = max |u| of the boundary in q (inf: the "
                          "uncompressed limit; the options database does not tell -A from -a)", expr=False,
                          valid=(lambda x: x > 0, "> 0"), distinct=True)
    routes = opts.words("routes", ALL_ROUTES, "routes to run", choices=ROUTES)
    previous = opts.path("previous", "", "a checkout of another version: the boundary routes measured with it too, "
                         "side by side (none if empty)")
    log_view = opts.flag("log_view", "write the boundary route's PETSc -log_view beside the table")
    output, repeats, records_path, mode = declare_common(opts, "runs/bench_map.md", repeats=1)
    opts.done()
    opts.check_unused()
    if previous and not os.path.isfile(os.path.join(previous, "hertzpetsc", "__init__.py")):
        from hertzpetsc.errors import ParameterError
        raise ParameterError("-previous", previous, "must be a checkout holding hertzpetsc/ (e.g. a git worktree)")
    grid = sorted(set(round(a, 12) for a in list(amps) + (amplitude_grid(a_min, a_max, ds) if ds > 0 else [])))
    a_values = [a for i, a in enumerate(grid) if i == 0 or a > grid[i - 1] * (1 + 1e-9)]
    me = os.path.abspath(__file__)
    identity = dict(alpha=alpha, N=N, m=ms, subset=subset, a=a_values, twists=twists,
                    **({"A": levels} if "boundary_q" in routes else {}),
                    **({"previous": previous} if previous else {}))
    rec = BenchRecords(records_path, "hertzpetsc-bench-map-1", identity, mode)
    base = dict(alpha=alpha, N=N, a=a_values, twists=0, locate=[], limit=True)
    plans = {"map": (dict(base, m=ms), 2, ()),
             "boundary": (dict(base, m=ms, twists=twists, locate=["chain", "infinite"]), 2,
                          ("-log_view", ":" + os.path.join(os.path.dirname(output) or ".",
                                                           "logview_map_boundary_np2.txt"))
                          if log_view else ()),
             "boundary_q": (dict(base, m=ms, twists=twists, A=levels), 2, ()),
             "dense": (dict(base, m=subset), None, ()),
             "subset": (dict(base, m=subset, limit=False), 1, ())}      # the dense route's work: no limit
    start = machine(repeats)
    results = {}
    rows = []
    for route in routes:
        req, ranks, args = plans[route]
        results[route] = rec.measure(f"{route} {ranks or 1}", lambda: best_of(repeats, me, route, req, ranks,
                                                                               14400, args))
        rows.append((route, False))
        print(route, json.dumps({k: v for k, v in (results[route] or {}).items() if k != "rho"}), flush=True)
        if previous and route.startswith("boundary"):
            # its own -log_view file beside this checkout's
            prev_args = tuple(a.replace("_np2.txt", "_previous_np2.txt") for a in args)
            results[route, "previous"] = rec.measure(
                f"{route} {ranks or 1} previous", lambda: best_of(repeats, me, route, req, ranks, 14400, prev_args,
                                                                  package=previous))
            rows.append((route, True))
    labels = {"map": f"map: {len(ms)} q x {len(a_values)} a, all {2 * N} multipliers on N = {N} (deflated sectors)",
              "boundary": f"boundary: the map + located boundary on N = {N} and on the infinite chain "
                          f"(twists {twists})",
              "boundary_q": f"boundary in q on the infinite chain at {len(levels)} amplitudes (twists {twists})",
              "dense": f"dense route before issue 23 (DenseFloquet), {len(subset)} q x {len(a_values)} a",
              "subset": f"this map's route on the same {len(subset)} q x {len(a_values)} a"}
    targets = {"map": 600.0, "boundary": 1800.0, "boundary_q": 1800.0}
    lines = [f"Stability map of the precompressed chain, alpha = {alpha:g}, delta0 = 1, N = {N}; amplitudes a from "
             f"{a_values[0]:g} to {a_values[-1]:g} ({len(a_values)}); waves: Richardson of h = pi/1000, pi/2000; "
             f"flow rtol 1e-11. {start}; load average at the end {os.getloadavg()[0]:.2f}. One BLAS thread per "
             "rank. Wall times under load are indicative only (the machine is shared): compare rows measured at "
             "similar load.\n",
             "| route | ranks | points | located (N / infinite) | wall (s) | s per point | projected to 40 q x 60 a "
             "(s) | target (s) | load at start |",
             "|---|---|---|---|---|---|---|---|---|"]
    for route, prev in rows:
        res, ranks = results[(route, "previous") if prev else route], plans[route][1] or 1
        label = f"{labels[route]}, {previous}" if prev else labels[route]
        if res is None:
            lines.append(f"| {label} | {ranks} | timed out | | | | | | |")
            continue
        per = res["wall"] / max(res["points"], 1)
        projected = "" if route == "boundary_q" else f"{per * 40 * 60:.0f}"     # not a map of points
        lines.append(f"| {label} | {ranks} | {res['points']} | {res['edges']} / {res['edges_infinite']} | "
                     f"{res['wall']:.1f} | {per:.2f} | {projected} | {targets.get(route, '')} | "
                     f"{res.get('load', 0):.2f} |")
    if {"boundary", "boundary_q"} <= set(routes) and results["boundary"] and results["boundary_q"]:
        whole = results["boundary"]["wall"] + results["boundary_q"]["wall"]
        lines.append(f"\nThe whole boundary of alpha = {alpha:g} (located in A on N = {N} and on the infinite chain, "
                     f"then in q on the infinite chain): {whole:.1f} s on 2 ranks (target 1800 s).")
    for route, prev in rows:
        old = results.get((route, "previous")) if not prev else None
        new_ = results[route]
        if old and new_:
            keys = sorted(set(old["rho"]) & set(new_["rho"]))
            diff = max((abs(old["rho"][k] - new_["rho"][k]) for k in keys), default=float("nan"))
            lines.append(f"\nSide by side ({route}): {previous} {old['wall']:.1f} s, this checkout "
                         f"{new_['wall']:.1f} s ({old['wall'] / new_['wall']:.2f}x); records {len(keys)} in common of "
                         f"{len(old['rho'])} / {len(new_['rho'])}, largest |rho difference| {diff:.1e}.")
    dense, sub = results.get("dense"), results.get("subset")
    if dense and sub:
        common = sorted(set(dense["rho"]) & set(sub["rho"]))
        tol = 1e-4
        agree = sum((dense["rho"][k] - 1 > tol) == (sub["rho"][k] - 1 > tol) for k in common)
        lines.append(f"\nSide by side on {len(common)} points: dense route {dense['wall']:.1f} s, this route "
                     f"{sub['wall']:.1f} s on one rank each: {dense['wall'] / sub['wall']:.1f}x; verdicts at the "
                     f"previous threshold rho - 1 > {tol:g} agree at {agree} of {len(common)} points.")
    lines.append("\nProjection: the wall time per map point (wave, located boundary points and limits included) times "
                 "the 2400 points of the issue's 40 q x 60 a; the cost per point depends on q (the wave's cell of M "
                 "beads: N / M sectors of 2M columns), so a projection from a few q is indicative only.")
    write_report(output, lines)


if __name__ == "__main__":
    main_or_worker(main, worker)
