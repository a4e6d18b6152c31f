#!/usr/bin/env python3
"""Floquet stability of the precompressed travelling waves in the (q, A) plane, and its boundary located, on a
periodic chain of N beads and on the infinite chain.

    mpiexec -n 2 python scripts/precompression_map.py [-alpha 1.5] [-delta0 1] [-N 100] [-epsilon 1]
        [-m 10,12,14,15,16,18,20,22,24,25] [-q LIST] [-a 0.1,0.3,0.5,0.7,1,1.5,2,3,5,10,20,30,50,100,1000]
        [-a_min 0.01 -a_max 1000 -ds 0] [-cells_per_pi 1000] [-rtol 1e-11] [-tol_rho 1e-6] [-twists 0]
        [-locate chain] [-locate_tol 1e-3] [-output runs/precompression_map.npz]
        [-table runs/precompression_map.md] [-figures figures] [-compare FILE] [-resume | -force | -render]

For q = 2 pi m / N (and the wavenumbers of -q, infinite chain only) and each amplitude a (first sine coefficient
of u; -a, and with -ds > 0 the grid a_min exp(k ds) up to a_max): the wave (Richardson combination of the h = pi/K
and pi/(2K) waves, K = -cells_per_pi) continued in log a from the linear wave, put on the chain; all 2N multipliers
modulo shift on N beads from the sectors of its cell, and with -twists T > 0 the infinite chain's over the cell twists
(bead-level Bloch step <= pi/T), symmetry multipliers deflated by their known eigenvectors (where one left is
within 1e-3 of 1 on N beads, on the orbit refined by Gauss-Newton with the flow at rtol/100); unstable when
rho - 1 > tol_rho. Where the verdict of a chain of -locate (chain, infinite, or none) changes between two amplitudes,
its root is located by bisection in log a to a relative bracket -locate_tol; the gap opening is located on the way;
the uncompressed limit closes each q. With -epsilon != 1 the chain is the dimer (masses 1, epsilon), the waves its
acoustic ones. The q are dealt to the ranks. Table: the located boundary with rho - 1 on both sides, and the
verdicts; figure precompression_map.png.

-render computes nothing: it rewrites -table (and the figure) from the file -output, of this kind or of kind
hertzpetsc-precompression-map-1 (the maps before issue 23: rho - 1 per (q, a) on the dense route); such a file is
not resumed (-resume refuses it and says so); the options that define the computation (-alpha ... -locate_tol) are
refused with -render. -resume refuses a file of other parameters, the amplitudes (-a, -ds grid) included.
-compare FILE (a map of kind -1 of the same alpha, delta0, masses, N, cells_per_pi and rtol, else refused) adds to
the table the verdicts of both maps at the (q, a) both computed, at that file's threshold.

With -beads (hertzpetsc.units: one material, or two alternating, whose bonds have one contact constant) the chain
is that of the beads pressed by -static_force (Hertz alpha = 3/2, delta0 = 1 at the default length scale, the
masses from the beads) instead of -alpha, -delta0, -epsilon; the table adds a section in SI units (A, A_stable,
A_unstable in um, f in Hz, the phase speed omega / q in m/s). A pattern whose bonds differ (e.g. steel,steel,ptfe)
is refused: the map's uncompressed limit is of one law in every bond (scripts/wave.py -beads computes its waves
and multipliers). -render takes no -beads (the file holds the dimensionless chain).
"""
import math
import os
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.chain import IntegrationTolerances  # noqa: E402
from hertzpetsc.model import LatticeModel, law_options  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import prepare_outputs, write_text  # noqa: E402
from hertzpetsc.errors import RecordFileError  # noqa: E402
from hertzpetsc.studies.maps import (MAP_FORMAT_V1, MAP_FORMAT_V2, MapParameters, StabilityMap, TESTS,  # noqa: E402
                                     check_comparable, compare_v1, map_format, map_table, map_v1_as_v2, read_map)
from hertzpetsc.studies.precompression import amplitude_grid  # noqa: E402
from hertzpetsc.verdicts import KIND_EDGE, KIND_EDGE_INF  # noqa: E402
from hertzpetsc.units import BEAD_OPTIONS, bead_options  # noqa: E402

# the options that define the computation (refused with -render, which reads it from the file)
COMPUTATION = ("alpha", "delta0", "N", "epsilon", "m", "q", "a", "a_min", "a_max", "ds", "cells_per_pi", "rtol",
               "tol_rho", "twists", "locate", "locate_tol") + BEAD_OPTIONS
# the SI section with -beads: the records of finite amplitude (nan where a column does not apply)
SI_COLUMNS = [("A", "length", lambda r: r["A"]), ("f", "frequency", lambda r: _wave(r, r["omega"])),
              ("c", "speed", lambda r: _wave(r, float(r["omega"]) / float(r["q"]))),
              ("A_stable", "length", lambda r: r["A_stable"]), ("A_unstable", "length", lambda r: r["A_unstable"])]


def _wave(r, value):
    """A wave's value of a record, nan for a located edge (its two sides are in the edge's other columns)."""
    return math.nan if int(r["kind"]) in (KIND_EDGE, KIND_EDGE_INF,) else value


SI_LEAD = [("q", lambda r: r["q"]), ("kind", lambda r: str(int(r["kind"]))), ("a", lambda r: r["a"]),
           ("rho - 1", lambda r: float(r["rho"]) - 1)]


def main():
    opts = AppOptions(__doc__, StabilityMap.ROLES)
    alpha = opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda x: x > 1, "> 1"))
    law_options(opts, supported=False)      # -law: refused but hertz
    delta0 = opts.real("delta0", 1.0, "precompression (static overlap)", valid=(lambda x: x > 0, "> 0"))
    p = opts.parameters(MapParameters)
    N = p.pop("N")
    epsilon = opts.real("epsilon", 1.0, "mass of every second bead (1: monatomic chain; else the dimer's acoustic "
                        "waves)", valid=(lambda x: x > 0, "> 0"))
    ms = opts.numbers("m", "10,12,14,15,16,18,20,22,24,25", "wavelengths on the chain (q = 2 pi m / N)", kind=int,
                      valid=(lambda m: 1 <= m <= N // 2, "in [1, N/2]"), distinct=True)
    extra_q = opts.numbers("q", "", "further wavenumbers, on the infinite chain only (q / 2 pi a fraction; pi "
                           "allowed)", valid=(lambda q: 0 < q <= math.pi, "in (0, pi]"), distinct=True,
                           minimum_count=0)
    amps = opts.numbers("a", "0.1,0.3,0.5,0.7,1,1.5,2,3,5,10,20,30,50,100,1000", "amplitudes (first sine coefficient "
                        "of u)", valid=(lambda x: x > 0, "> 0"), distinct=True)
    a_min = opts.real("a_min", 0.01, "smallest amplitude of the geometric grid (with -ds > 0)",
                      valid=(lambda x: x > 0, "> 0"))
    a_max = opts.real("a_max", 1000.0, "largest amplitude of the geometric grid", valid=(lambda x: x > 0, "> 0"))
    ds = opts.real("ds", 0.0, "step in log a of the geometric grid added to -a (0: none)",
                   valid=(lambda x: x >= 0, ">= 0"))
    rtol = opts.real("rtol", 1e-11, "flow tolerance (atol = rtol/100)", valid=(lambda x: 0 < x < 1, "in (0, 1)"))
    locate = opts.words("locate", "chain", "verdicts whose changes are located: chain, infinite, or none",
                        choices=TESTS + ("none",))
    output, mode, table_path, figures = opts.record_table_figures(
        "runs/precompression_map.npz", "stability-map file", "runs/precompression_map.md",
        "precompression_map.png")
    compare = opts.path("compare", "", "a map of kind hertzpetsc-precompression-map-1 to compare the verdicts with "
                        "(none if empty)")
    render = opts.render_flag(" (either kind)")
    beads = bead_options(opts, ("alpha", "delta0", "epsilon"), equal_bonds="the map's uncompressed limit is of one "
                         "law in every bond; the waves and multipliers of such a pattern are scripts/wave.py -beads")
    opts.done()
    comm = PETSc.COMM_WORLD
    if compare and map_format(compare, comm) != MAP_FORMAT_V1:
        raise RecordFileError(f"-compare {compare!r}: not a stability map of kind {MAP_FORMAT_V1}")
    if render:
        opts.render(mode, lambda: read_map(output, comm),
                    lambda z: write_figure_and_table(comm, z, table_path, figures, compare), table_path, figures,
                    COMPUTATION)
        return
    if mode == "resume" and map_format(output, comm) in (MAP_FORMAT_V1, MAP_FORMAT_V2):
        before = ("the route before issue 23 ({}, no located boundary)" if map_format(output, comm) == MAP_FORMAT_V1
                  else "the twist sampling before the certification of issue 37 ({})")
        raise RecordFileError(f"-output {output!r} is a stability map of " + before.format(map_format(output, comm))
                              + ": it cannot be resumed; -render rewrites its table and figure, -force recomputes it "
                              "(or give another -output)")
    prepare_outputs(comm, table_path, figures=figures)
    qs = [2 * math.pi * m / N for m in ms] + list(extra_q)
    grid = amplitude_grid(a_min, a_max, ds) if ds > 0 else []
    masses = (1.0,) if epsilon == 1.0 else (1.0, epsilon)
    model = LatticeModel.hertz(alpha, masses, delta0) if beads is None else beads.model()
    if beads is not None:
        alpha, delta0, masses = model.alpha, model.delta0, model.masses
    study = StabilityMap(MapParameters(model, qs, tuple(amps) + tuple(grid), N, **p, tolerances=IntegrationTolerances(
        rtol=rtol, atol=rtol / 100), locate=tuple(w for w in locate if w != "none")), comm, output, mode)
    K, twists = p["cells_per_pi"], p["twists"]
    if compare:                                        # before any computation: a map of the same computation
        check_comparable(study.constants(), read_map(compare, comm), compare)
    study.configure()
    opts.check_unused()
    study.open()
    print0(f"# N = {N}, alpha = {alpha:g}, delta0 = {delta0:g}, masses {', '.join(f'{m:g}' for m in masses)}, "
           f"h = pi/{K} and pi/{2 * K}, rtol {rtol:g}, {len(study.a_values)} amplitudes, twists {twists}")
    if beads is not None:
        print0(beads.summary())
    print0(f"# {'q':>8} {'kind':>4} {'a':>10} {'A':>10} {'rho - 1':>10} {'inf - 1':>10} {'s':>6}")
    # the table of this run's records, also when an error stops it (then with the error below it)
    study.run_to_table(table_path, lambda r: print0(
        f"  {r['q']:8.5f} {r['kind']:4d} {r['a']:10.5g} {r['A']:10.5g} {r['rho'] - 1:10.3e} "
        f"{r['rho_inf'] - 1:10.3e} {r['seconds']:6.1f}"))
    z = study.arrays()
    si = "" if beads is None else beads.table([r for r in study.store.records if math.isfinite(float(r["a"]))],
                                              SI_COLUMNS, SI_LEAD)
    study.destroy()
    write_figure_and_table(comm, z, table_path, figures, compare, si)


def write_figure_and_table(comm, z, table_path, figures, compare="", si=""):
    text = map_table(z)
    if compare and str(z["format"]) != MAP_FORMAT_V1:
        text += compare_v1(z, read_map(compare, comm), path=compare)
    text += si
    write_text(table_path, text, comm)
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        name = os.path.splitext(os.path.basename(table_path))[0] + ".png"
        v2 = map_v1_as_v2(z) if str(z["format"]) == MAP_FORMAT_V1 else z
        print("wrote " + plotting.plot_stability_map(v2, figures, name).path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
