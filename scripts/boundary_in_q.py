#!/usr/bin/env python3
"""The stability boundary of the precompressed travelling waves on the infinite chain, located in q at fixed
amplitudes A = ||u||_inf (issue 23: the boundary in A at each q is precompression_map.py's).

    mpiexec -n 2 python scripts/boundary_in_q.py [-alpha 1.5] [-delta0 1] [-A 0.1,0.3,1,1.5,2,3,5,10,30,100,inf]
        [-N 100] [-m 10,12,14,15,16,18,20,22,24,25] [-q LIST] [-cells_per_pi 1000] [-rtol 1e-11] [-tol_rho 1e-6]
        [-twists 512] [-locate_tol 1e-3] [-max_cell 400] [-map FILE] [-output runs/boundary_in_q.npz]
        [-table runs/boundary_in_q.md] [-figures figures] [-resume | -force | -render]

At each amplitude A (inf: the uncompressed limit) and each grid wavenumber (q = 2 pi m / N and -q): the wave with
max |u| = A (a border row of eq. ad; Richardson combination of h = pi/K and pi/(2K), K = -cells_per_pi) and rho over
every Bloch parameter of the infinite chain (the cell twists of its wave, bead-level step <= pi/-twists, maxima
refined, symmetry multipliers deflated; a weak instability, rho - 1 < 1e-3, judged on the cell orbit refined by
Gauss-Newton with the flow at rtol/100, as in precompression_map.py); unstable when rho - 1 > -tol_rho. Where the verdict changes between two
grid q, the edge is located by bisection in q, each sample the q / 2 pi of fewest beads per cell in the middle third
of the bracket (at most -max_cell), to a relative bracket -locate_tol / 2. The amplitudes are dealt to the ranks.
Table: the located edges with rho - 1 on both sides, and the grid's verdicts; figure boundary_in_q.png (with -map, a
map file of precompression_map.py, on the plane with that map's located edges). -render computes nothing: it
rewrites -table and the figure from -output.

With -beads (hertzpetsc.units: one material; the boundary in q is located for monatomic chains) the chain is that
of the beads pressed by -static_force (Hertz alpha = 3/2, delta0 = 1 at the default length scale) instead of
-alpha, -delta0, and -A_si gives the amplitudes in SI units (e.g. 0.5um,1um) instead of -A; the table adds a
section in SI units (A in um, f in Hz, the phase speed omega / q in m/s, the located edges' wavenumbers per metre
of chain). -render takes no -beads (the file holds the dimensionless chain).
"""
import math
import os
import sys

from hertzpetsc.start import init_petsc

init_petsc(sys.argv)
from petsc4py import PETSc  # noqa: E402

from hertzpetsc.chain import IntegrationTolerances  # noqa: E402
from hertzpetsc.errors import ParameterError  # noqa: E402
from hertzpetsc.model import LatticeModel, law_options  # noqa: E402
from hertzpetsc.options import AppOptions, guarded_main, print0  # noqa: E402
from hertzpetsc.records import check_kind, load_npz, on_rank0, prepare_outputs, write_text  # noqa: E402
from hertzpetsc.studies.maps import (QMAP_FORMAT, QMAP_FORMAT_V1, QBoundary, QBoundaryParameters,  # noqa: E402
                                     check_same_chain, q_boundary_table, read_map)
from hertzpetsc.verdicts import KIND_EDGE_INF  # noqa: E402
from hertzpetsc.units import BEAD_OPTIONS, bead_options, si_numbers  # noqa: E402

# the SI section with -beads: the records of finite amplitude (nan where a column does not apply)
SI_COLUMNS = [("A", "length", lambda r: r["A"]), ("f", "frequency", lambda r: _wave(r, r["omega"])),
              ("c", "speed", lambda r: _wave(r, float(r["omega"]) / float(r["q"]))),
              ("k_stable", "wavenumber", lambda r: r["q_stable"]), ("k_unstable", "wavenumber", lambda r: r["q_unstable"])]


def _wave(r, value):
    """A wave's value of a record, nan for a located edge (its two sides are in the edge's other columns)."""
    return math.nan if int(r["kind"]) in (KIND_EDGE_INF,) else value


SI_LEAD = [("A", lambda r: r["A"]), ("kind", lambda r: str(int(r["kind"]))), ("q", lambda r: r["q"]),
           ("rho - 1", lambda r: float(r["rho_inf"]) - 1)]


def main():
    opts = AppOptions(__doc__, QBoundary.ROLES)
    alpha = opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda x: x > 1, "> 1"))
    law_options(opts, supported=False)      # -law: refused but hertz
    delta0 = opts.real("delta0", 1.0, "precompression (static overlap)", valid=(lambda x: x > 0, "> 0"))
    levels = opts.numbers("A", "0.1,0.3,1,1.5,2,3,5,10,30,100,inf", "amplitudes A = max |u| (inf: the uncompressed "
                          "limit)", expr=False, valid=(lambda x: x > 0, "> 0"), distinct=True)
    N = opts.integer("N", 100, "the grid wavenumbers are q = 2 pi m / N", minimum=2)
    ms = opts.numbers("m", "10,12,14,15,16,18,20,22,24,25", "grid wavelengths on N beads (q = 2 pi m / N)", kind=int,
                      valid=(lambda m: 1 <= m <= N // 2, "in [1, N/2]"), distinct=True, minimum_count=0)
    extra_q = opts.numbers("q", "", "further grid wavenumbers (q / 2 pi a fraction; pi allowed)",
                           valid=(lambda q: 0 < q <= math.pi, "in (0, pi]"), distinct=True, minimum_count=0)
    rtol = opts.real("rtol", 1e-11, "flow tolerance (atol = rtol/100)", valid=(lambda x: 0 < x < 1, "in (0, 1)"))
    p = opts.parameters(QBoundaryParameters)
    map_path = opts.path("map", "", "a stability-map file (precompression_map.py) drawn with the edges (none if "
                         "empty)")
    output, mode, table_path, figures = opts.record_table_figures(
        "runs/boundary_in_q.npz", "boundary-in-q file", "runs/boundary_in_q.md", "boundary_in_q.png")
    render = opts.render_flag()
    beads = bead_options(opts, ("alpha", "delta0"), one_bead="the boundary in q is located for monatomic chains (a "
                         "pattern's map in amplitude: scripts/precompression_map.py -beads, its waves: scripts/wave.py "
                         "-beads)")
    si_levels = si_numbers(opts, beads, "A_si", "length", "amplitudes A = max |u| (e.g. 1um)", "A")
    opts.done()
    if si_levels is not None:
        levels = si_levels
    model = LatticeModel.hertz(alpha, delta0=delta0) if beads is None else beads.model()
    alpha, delta0 = model.alpha, model.delta0
    comm = PETSc.COMM_WORLD
    zmap = read_map(map_path, comm) if map_path else None
    if render:
        def read():
            z = on_rank0(comm, lambda: _read(output), what="boundary-in-q file")
            if zmap is not None:
                check_same_chain(zmap, z["alpha"], z["delta0"], map_path)
            return z
        opts.render(mode, read, lambda z: write_figure_and_table(comm, z, zmap, table_path, figures), table_path,
                    figures, BEAD_OPTIONS + ("A_si",))
        return
    if zmap is not None:
        check_same_chain(zmap, alpha, delta0, map_path)
    if len(ms) + len(extra_q) < 2:
        raise ParameterError("-m", ",".join(str(m) for m in ms), "with -q, at least two grid wavenumbers between "
                             "which to locate")
    prepare_outputs(comm, table_path, figures=figures)
    qs = [2 * math.pi * m / N for m in ms] + list(extra_q)
    study = QBoundary(QBoundaryParameters(model, tuple(levels), tuple(qs), **p, tolerances=IntegrationTolerances(
        rtol=rtol, atol=rtol / 100)), comm, output, mode)
    K, twists = p["cells_per_pi"], p["twists"]
    study.configure()
    opts.check_unused()
    study.open()
    print0(f"# alpha = {alpha:g}, delta0 = {delta0:g}, h = pi/{K} and pi/{2 * K}, rtol {rtol:g}, "
           f"{len(study.params.A)} amplitudes, {len(study.params.q)} grid q, twists {twists}")
    table = None
    if beads is not None:
        print0(beads.summary())

        def table():
            return study.table() + beads.table([r for r in study.store.records if math.isfinite(float(r["A"]))],
                                               SI_COLUMNS, SI_LEAD)
    print0(f"# {'A':>8} {'kind':>4} {'q':>10} {'cell':>5} {'rho - 1':>10} {'Theta':>7} {'s':>6}")
    text = study.run_to_table(table_path, lambda r: print0(      # on a stop: the table of the records done
        f"  {r['A']:8.4g} {r['kind']:4d} {r['q']:10.6f} {r['M']:5d} {r['rho_inf'] - 1:10.3e} "
        f"{r['theta_inf']:7.4f} {r['seconds']:6.1f}"), table)
    z = study.arrays()
    study.destroy()
    figure_and_table(comm, z, zmap, table_path, figures, text)


def _read(path):
    z = load_npz(path, "boundary-in-q file")
    if str(z.get("format", "")) != QMAP_FORMAT_V1:          # files before the twist certification: render only
        check_kind(z, path, QMAP_FORMAT, "boundary-in-q file")
    return z


def write_figure_and_table(comm, z, zmap, table_path, figures):
    text = q_boundary_table(z)
    write_text(table_path, text, comm)
    figure_and_table(comm, z, zmap, table_path, figures, text)


def figure_and_table(comm, z, zmap, table_path, figures, text):
    if figures and comm.getRank() == 0:
        from hertzpetsc import plotting
        name = os.path.splitext(os.path.basename(table_path))[0] + ".png"
        print("wrote " + plotting.plot_q_boundary(z, figures, name, zmap).path, flush=True)
    print0(text)


if __name__ == "__main__":
    guarded_main(main)
