"""Stability maps (issue 23): the boundary located along an amplitude family and confirmed by the multipliers on
both sides, instability bubbles narrower than the sampling found through Krein crossings (in the amplitude and in
the infinite chain's Bloch parameter), the trivial multipliers of a dimer deflated exactly, the driver on 1 and 2
ranks."""
import math
import os
import pathlib

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import DATA, one_error_line, run_script
from hertzpetsc.bloch import BlochSectors, SymmetricFloquet
from hertzpetsc.chain import IntegrationTolerances
from hertzpetsc.errors import ParameterError
from hertzpetsc.families import AmplitudeFamily
from hertzpetsc.grid import ProfileGrid
from hertzpetsc.model import LatticeModel
from hertzpetsc.slow import DeflatedSectors, twist_scan
from hertzpetsc.studies.maps import (KIND_CROSSING, KIND_EDGE, KIND_GAP, KIND_LIMIT, KIND_POINT, MapParameters,
                                     RichardsonCompanion, StabilityMap, wave_cell)
from hertzpetsc.studies.precompression import wave_orbit

SELF = PETSc.COMM_SELF
TOL = IntegrationTolerances(rtol=1e-11, atol=1e-13)
Q = 0.3 * math.pi                   # 3 wavelengths on a cell of 20 beads
K = 200


def richardson_waves(model, q, amplitudes, K=K):
    """(a, profiles, lam) of the Richardson waves of the family at the given amplitudes (the map's waves)."""
    fam = AmplitudeFamily(model, q, ProfileGrid(K, SELF))
    companion = RichardsonCompanion(model, q, K, SELF)
    try:
        return [(p.a,) + companion.combine(p)[:2] for p in fam.points(amplitudes)]
    finally:
        fam.destroy()
        companion.destroy()


def undeflated_rho(model, q, a, w, lam, N):
    """rho - 1 by the independent route: all 2N multipliers from the cell's sectors (bloch.SymmetricFloquet, the
    four nearest 1 left out as the trivial group)."""
    with SymmetricFloquet(model, SELF, TOL) as sym:
        return sym.spectrum(wave_orbit(model, q, a, w, lam, N, math.pi / K)).rho - 1


def test_located_bubble_is_confirmed_by_the_multipliers_on_both_sides():
    """3 pi/10 on 20 beads between a = 0.5 and 0.65, both stable: a Krein crossing between them (multipliers of
    opposite signatures pass each other) reveals a bubble of instability (about A = 0.60 .. 0.63, in no sample of
    the map), whose two edges the continuation layer locates by bisection to a relative bracket of 1e-3. At each
    end of each bracket the independent undeflated route agrees with the record: stable (rho - 1 ~ 1e-12) on one
    side, unstable on the other (rho - 1 ~ 1e-4: a Krein collision opens as sqrt(A - A*))."""
    model = LatticeModel.hertz(1.5, (1.0,), 1.0)
    study = StabilityMap(MapParameters(model, (Q,), (0.5, 0.65), N=20, cells_per_pi=K, tolerances=TOL,
                                       limit=False), SELF)
    try:
        rows = list(study.run())
    finally:
        study.destroy()
    points = [r for r in rows if r["kind"] == KIND_POINT]
    edges = sorted((r for r in rows if r["kind"] == KIND_EDGE), key=lambda r: r["A"])
    assert [r["rho"] - 1 < 1e-6 for r in points] == [True, True]
    assert len(edges) == 2 and not any(r["kind"] == KIND_CROSSING for r in rows)
    onset, offset = edges
    assert onset["A_stable"] < onset["A_unstable"] < offset["A_unstable"] < offset["A_stable"]
    for edge in edges:
        width = abs(edge["A_unstable"] - edge["A_stable"]) / edge["A_stable"]
        assert width <= 1e-3
        assert edge["rho_stable"] < 1e-6 < edge["rho_unstable"]
        for a, recorded in ((edge["a_stable"], edge["rho_stable"]), (edge["a_unstable"], edge["rho_unstable"])):
            [(a, w, lam)] = richardson_waves(model, Q, [a])
            # the same waves and flows, another route: the multipliers agree to the flow's error (1e-11 rtol);
            # the undeflated route leaves out the trivial group by proximity, which is exact here
            assert abs(undeflated_rho(model, Q, a, w, lam, 20) - recorded) < 1e-8
    assert 0.5 < onset["A"] < offset["A"] < 0.7


def test_twist_scan_finds_a_bubble_narrower_than_its_grid():
    """On the infinite chain the small waves of 3 pi/10 are unstable in a band of twists about 1e-4 wide at A = 0.02
    (a resonance of the linear spectrum, opening as A^2): the grid of 53 twists misses it (all its rho - 1 are
    round-off); the certification between the samples follows the multipliers of each Krein signature by their
    twist slopes, sees a pair of opposite signatures cross between two grid twists and brackets the crossing, which
    lands in the band; a direct twisted run (no cell propagator) at the twist found confirms the growth."""
    model = LatticeModel.hertz(1.5, (1.0,), 1.0)
    [(a, w, lam)] = richardson_waves(model, Q, [0.02])
    cell = wave_orbit(model, Q, a, w, lam, 20, math.pi / K)
    sectors = DeflatedSectors(model, SELF, TOL, twists=None, krein=None)
    try:
        without = twist_scan(sectors, cell, 52, floor=1e-8)
        sectors.krein = 1e-8
        scan = twist_scan(sectors, cell, 52, floor=1e-8)
    finally:
        sectors.destroy()
    assert without.rho_max - 1 < 1e-10 and without.verdict == "sampled"   # measured 3e-15: the grid misses it
    assert scan.verdict == "unstable" and scan.rho_max - 1 > 1e-6          # measured 4.9e-6
    assert abs(scan.theta / math.pi - 0.807) < 0.002
    sym = cell.symmetry
    direct = BlochSectors(model, SELF, TOL)
    try:
        G = direct.monodromy(cell.x, sym.delta(cell.T), scan.theta, sym.k)
    finally:
        direct.destroy()
    mu = np.exp(-1j * sym.j * scan.theta) * np.linalg.eigvals(G) ** sym.m_cell
    # the propagator's blocks against a twisted run: the flows' error (rtol 1e-11)
    assert abs(np.max(np.abs(mu)) - scan.rho_max) < 1e-9


def test_twist_slopes_are_the_derivatives_of_the_multipliers():
    """The first-order twist derivative of every multiplier on the circle (slow.twist_slopes, J v as left
    eigenvector, the exact dG/dTheta of the cell propagator) against central differences of the sectors at
    Theta +- 1e-6 (error O(1e-12) + the flows' 1e-11 / 1e-6), both routes of the sector maps, and the zone modes'
    deflation: the eigenvectors of P are those of the deflated block lifted with their component in the deflated
    space (at A = 3 the zones are decoupled and that component is O(1))."""
    model = LatticeModel.hertz(1.5, (1.0,), 1.0)
    for A in (0.02, 3.0):
        [(a, w, lam)] = richardson_waves(model, Q, [A])
        cell = wave_orbit(model, Q, a, w, lam, 20, math.pi / K)
        with DeflatedSectors(model, SELF, TOL, twists=None, krein=1e-6) as sectors:
            for propagate in (True, False):
                at, _ = sectors.scan(cell, [0.0], propagate=propagate, raw=False, slopes=True)
                theta, e = 1.1, 1e-6
                s0, s1, s2 = at(theta), at(theta - e), at(theta + e)
                on = np.nonzero(s0.signatures != 0)[0]
                assert len(on) >= 10 and np.all(np.isfinite(s0.slopes[on]))     # A = 3: some are off the circle
                for i in on:
                    j1 = np.argmin(np.abs(s1.values - s0.values[i]))
                    j2 = np.argmin(np.abs(s2.values - s0.values[i]))
                    fd = np.angle(s2.values[j2] / s1.values[j1]) / (2 * e)
                    assert abs(fd - s0.slopes[i]) < 1e-6, (A, propagate, fd, s0.slopes[i])


def test_certified_stable_verdict_bounds_every_twist_between_samples():
    """At A = 0.005 the band of 3 pi/10 (rho - 1 = 3.1e-7) lies below tol_rho = 1e-6: the verdict is 'stable',
    certified between the samples with the bound its weak bubble reaches, and a dense scan of 1500 twists over the
    band's neighbourhood and 1500 over [pi/52, pi] finds nothing above that bound (nor above tol_rho)."""
    model = LatticeModel.hertz(1.5, (1.0,), 1.0)
    [(a, w, lam)] = richardson_waves(model, Q, [0.005])
    cell = wave_orbit(model, Q, a, w, lam, 20, math.pi / K)
    with DeflatedSectors(model, SELF, TOL, twists=None, krein=1e-6) as sectors:
        scan = twist_scan(sectors, cell, 52, floor=1e-6)
        cert = scan.certificate
        assert scan.verdict == "stable" and cert.status == "stable" and not cert.unresolved
        assert 2e-7 < cert.bound < 1e-6                                    # measured 3.09e-7: the weak bubble
        at, _ = sectors.scan(cell, [0.0], propagate=True, raw=False)
        dense = np.concatenate([np.linspace(math.pi / 52, math.pi, 1500),
                                np.linspace(scan.theta - 2e-3, scan.theta + 2e-3, 1500)])
        worst = max(at(t).rho for t in dense) - 1
    assert worst <= cert.bound * (1 + 1e-6) + 1e-12 and worst > 0.9 * cert.bound


def test_trivial_multipliers_of_a_dimer_are_deflated_exactly():
    """A precompressed dimer (masses 1, 0.7) on 20 beads: the time shift, translation and their Jordan partners are
    deflated in the sector Theta = 0 by their known eigenvectors; the other multipliers are the undeflated
    spectrum's to the flow's error, they lie on the unit circle to round-off while the trivial group that an
    undeflated spectrum shows is split by sqrt(orbit error) (the verdict rests on no such spread)."""
    model = LatticeModel.hertz(1.5, (1.0, 0.7), 1.0)
    [(a, w, lam)] = richardson_waves(model, Q, [0.1])
    orbit = wave_orbit(model, Q, a, w, lam, 20, math.pi / K)
    with DeflatedSectors(model, SELF, TOL, twists=None) as deflated, SymmetricFloquet(model, SELF, TOL) as sym:
        spec, ref = deflated.spectrum(orbit), sym.spectrum(orbit)
    sector0 = spec.work["sectors"][0]
    assert sector0.r == 4 and int(np.sum(spec.known)) == 4 and not spec.work["decoupled"]
    assert sector0.eigenvector_residual < 1e-8                              # measured 4e-12
    rest = ref.multipliers[np.argsort(np.abs(ref.multipliers - 1))[4:]]
    assert max(np.min(np.abs(rest - mu)) for mu in spec.multipliers[~spec.known]) < 1e-8
    assert spec.rho - 1 < 1e-10                                            # measured 5e-14
    assert np.max(np.abs(sector0.raw_cluster - 1)) > 1e-8                   # the split Jordan blocks: 3e-7


def test_wave_cell_and_bad_parameters():
    assert (wave_cell(0.3 * math.pi).M, wave_cell(0.3 * math.pi).m_cell) == (20, 3)
    assert wave_cell(2 * math.pi / 3, 2).M == 6                 # a whole number of dimer cells
    with pytest.raises(ParameterError, match="q"):
        wave_cell(1.0)
    model = LatticeModel.hertz(1.5, (1.0,), 1.0)
    with pytest.raises(ParameterError, match="locate"):
        MapParameters(model, (Q,), (1.0,), N=20, locate=("infinite",))
    with pytest.raises(ParameterError, match="invalid q = 1.0: .*twists > 0"):
        MapParameters(model, (1.0,), (1.0,), N=20)             # not a chain wavenumber, no infinite chain
    with pytest.raises(ParameterError, match="N"):
        MapParameters(LatticeModel.hertz(1.5, (1.0, 0.5), 1.0), (Q,), (1.0,), N=21)
    with pytest.raises(ParameterError, match="invalid a = 1e-12: .* at least"):    # before any family is computed
        MapParameters(model, (Q,), (1e-12, 3.0), N=20)


@pytest.mark.serial
def test_driver_on_one_and_two_ranks_resumes_and_refuses_bad_input(tmp_path):
    """Two q on 20 beads with the infinite chain, on 2 ranks and on 1: the same records (each q on one rank; up to
    LAPACK's threads, which differ between the runs: 1e-12); -resume adds a q; bad input is one error line."""
    args = ["-N", 20, "-a", "0.3,3", "-cells_per_pi", 100, "-rtol", "1e-10", "-twists", 64, "-locate",
            "chain,infinite"]
    r = run_script("precompression_map.py", *args, "-m", "3,4", "-output", tmp_path / "two.npz", "-table",
                   tmp_path / "two.md", "-figures", tmp_path, ranks=2)
    assert r.returncode == 0, r.stderr
    r = run_script("precompression_map.py", *args, "-m", "3", "-output", tmp_path / "one.npz", "-table",
                   tmp_path / "one.md")
    assert r.returncode == 0, r.stderr
    r = run_script("precompression_map.py", *args, "-m", "3,4", "-output", tmp_path / "one.npz", "-table",
                   tmp_path / "one.md", "-resume")
    assert r.returncode == 0, r.stderr
    with np.load(tmp_path / "two.npz") as two, np.load(tmp_path / "one.npz") as one:
        assert str(two["format"]) == "hertzpetsc-precompression-map-3"
        k2 = np.lexsort((two["a"], two["kind"], two["q"]))
        k1 = np.lexsort((one["a"], one["kind"], one["q"]))
        assert np.array_equal(two["kind"][k2], one["kind"][k1]) and np.array_equal(two["q"][k2], one["q"][k1])
        for name in ("a", "A", "rho", "rho_inf", "A_stable", "A_unstable"):
            x, y = two[name][k2], one[name][k1]
            assert np.allclose(x, y, rtol=1e-12, atol=1e-12, equal_nan=True), name
        assert np.sum(two["kind"] == KIND_LIMIT) == 2 and np.sum(two["kind"] == KIND_GAP) == 2
    assert (tmp_path / "two.png").exists()
    assert "Located boundary" in (tmp_path / "two.md").read_text()
    r = run_script("precompression_map.py", *args[:-2], "-locate", "infinite", "-twists", 0, "-m", "3",
                   "-output", tmp_path / "bad.npz", "-table", tmp_path / "bad.md")
    assert "-locate" in one_error_line(r)
    r = run_script("precompression_map.py", *args, "-m", "3", "-tol_rho", "1e-5", "-output", tmp_path / "one.npz",
                   "-table", tmp_path / "one.md", "-resume")
    assert "tol_rho" in one_error_line(r)                      # the file's identity names the parameter


@pytest.mark.serial
def test_maps_before_issue_23_are_rendered_not_resumed_and_the_old_import_path_works(tmp_path):
    """The committed files of kind -1 (dense route, no located boundary): -render rewrites each table exactly as
    its driver wrote it (byte for byte: the same records, the same format) and the figure; -resume refuses the file
    with one error line that says what to do; the study's old import path is the new study."""
    import shutil

    import hertzpetsc.studies.maps as maps
    from hertzpetsc.studies import precompression
    assert precompression.StabilityMap is maps.StabilityMap and precompression.MapParameters is maps.MapParameters
    results = pathlib.Path(DATA)
    for name in ("precompression_map", "precompression_map_dimer0.7", "precompression_map_dimer0.4"):
        with np.load(results / f"{name}.npz") as z:
            assert str(z["format"]) == maps.MAP_FORMAT_V1
        assert maps.map_table(maps.read_map(str(results / f"{name}.npz"))) == (results / f"{name}.md").read_text()
    shutil.copy(results / "precompression_map_dimer0.4.npz", tmp_path / "old.npz")
    r = run_script("precompression_map.py", "-render", "-output", tmp_path / "old.npz", "-table", tmp_path / "old.md",
                   "-figures", tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "old.md").read_text() == (results / "precompression_map_dimer0.4.md").read_text()
    assert (tmp_path / "old.png").exists()
    r = run_script("precompression_map.py", "-epsilon", 0.4, "-m", "10,14,15,20", "-a", "0.1,0.3,1,3,10,100",
                   "-output", tmp_path / "old.npz", "-table", tmp_path / "old.md", "-resume")
    assert "-render" in one_error_line(r) and "-force" in one_error_line(r)


@pytest.mark.serial
def test_files_before_the_twist_certification_render_and_are_not_resumed(tmp_path):
    """Files of the kinds before issue 37's certification (tests/data: a map of kind -2 and a boundary in q of kind
    -1, made by the release before it with `precompression_map.py -N 20 -a 0.3,3 -cells_per_pi 100 -rtol 1e-10
    -twists 64 -locate chain,infinite -m 3` and `boundary_in_q.py -A 3 -m 18,20 -cells_per_pi 100 -rtol 1e-10
    -twists 64 -locate_tol 0.1`): -render rewrites their tables, which say that the infinite chain's verdicts are
    the samples' ('s' where stable, 'samples only' at an edge's stable side); -resume refuses the map with one error
    line that names -render and -force."""
    import shutil
    data = pathlib.Path(__file__).resolve().parent / "data"
    shutil.copy(data / "map_v2_small.npz", tmp_path / "map.npz")
    shutil.copy(data / "boundary_q_v1_small.npz", tmp_path / "bq.npz")
    r = run_script("precompression_map.py", "-render", "-output", tmp_path / "map.npz", "-table", tmp_path / "map.md")
    assert r.returncode == 0, r.stderr
    text = (tmp_path / "map.md").read_text()
    assert "hertzpetsc-precompression-map-2" in text and "verdicts at the twist samples only" in text
    assert "`UU|s`" in text and "samples only" in text
    r = run_script("boundary_in_q.py", "-render", "-output", tmp_path / "bq.npz", "-table", tmp_path / "bq.md")
    assert r.returncode == 0, r.stderr
    text = (tmp_path / "bq.md").read_text()
    assert "hertzpetsc-boundary-q-1" in text and "samples only" in text
    r = run_script("precompression_map.py", "-N", 20, "-a", "0.3,3", "-cells_per_pi", 100, "-rtol", "1e-10",
                   "-twists", 64, "-locate", "chain,infinite", "-m", 3, "-output", tmp_path / "map.npz", "-table",
                   tmp_path / "again.md", "-resume")
    line = one_error_line(r)
    assert r.returncode == 4 and "certification" in line and "-render" in line and "-force" in line


def test_unstable_intervals_pair_the_located_edges():
    """Intervals from the located edges of a q (records as the study writes them): an onset opens, an offset closes;
    unstable at the smallest amplitude opens from 0, an onset never closed runs to inf if the largest amplitude is
    unstable (else its offset was not located: nan), two onsets in a row leave an offset not located (nan), and so
    does a map amplitude whose verdict contradicts the last edge; a chain without edges and stable points has none."""
    from hertzpetsc.studies.maps import KIND_EDGE, unstable_intervals
    nan = math.nan
    rows = [  # q, kind, A, rho, A_stable, A_unstable
        (1.0, KIND_POINT, 0.1, 1.0 + 1e-3, nan, nan), (1.0, KIND_EDGE, 0.2, nan, 0.21, 0.19),
        (1.0, KIND_POINT, 0.3, 1.0, nan, nan), (1.0, KIND_EDGE, 0.5, nan, 0.49, 0.51),
        (1.0, KIND_POINT, 0.7, 1.1, nan, nan), (1.0, KIND_EDGE, 0.8, nan, 0.81, 0.79),
        (1.0, KIND_EDGE, 2.0, nan, 1.99, 2.01), (1.0, KIND_POINT, 3.0, 1.2, nan, nan),
        (2.0, KIND_POINT, 0.1, 1.0, nan, nan), (2.0, KIND_POINT, 3.0, 1.0 + 1e-9, nan, nan)]
    z = {k: np.array([r[i] for r in rows]) for i, k in enumerate(("q", "kind", "A", "rho", "A_stable", "A_unstable"))}
    z["tol_rho"] = 1e-6
    assert unstable_intervals(z) == {1.0: [(0.0, 0.2), (0.5, 0.8), (2.0, math.inf)], 2.0: []}
    z["A_stable"][1], z["A_unstable"][1] = 0.19, 0.21      # the first edge an onset too: an offset not located
    spans = unstable_intervals(z)[1.0]
    # onsets at 0.2 and 0.5 after the unstable first point: two offsets not located
    assert np.array_equal(spans, [(0.0, math.nan), (0.2, math.nan), (0.5, 0.8), (2.0, math.inf)], equal_nan=True)
    # an onset never closed but the largest map amplitude stable: its offset was not located (not inf: the verdict
    # at the map's last amplitude and beyond would be overreached)
    z["rho"][7] = 1.0
    assert np.array_equal(unstable_intervals(z)[1.0][-1], (2.0, math.nan), equal_nan=True)
    # an offset located, then unstable map amplitudes with no onset located (a dimer's infinite chain: rho - 1 dipped
    # below tol_rho at one sample): unstable again from an unknown A (nan) to inf, not stable from the offset on
    rows = [(3.0, KIND_POINT, 0.1, 1.0 + 3e-5, nan, nan), (3.0, KIND_EDGE, 0.15, nan, 0.1501, 0.1499),
            (3.0, KIND_POINT, 0.3, 1.0 + 3e-3, nan, nan), (3.0, KIND_POINT, 3.0, 1.4, nan, nan)]
    z = {k: np.array([r[i] for r in rows]) for i, k in enumerate(("q", "kind", "A", "rho", "A_stable", "A_unstable"))}
    z["tol_rho"] = 1e-6
    assert np.array_equal(unstable_intervals(z)[3.0], [(0.0, 0.15), (math.nan, math.inf)], equal_nan=True)


def test_unstable_intervals_read_the_uncompressed_limit():
    """The limit's verdict (kind 3, A = inf) ends the walk: stable map amplitudes and an unstable limit give an
    interval to inf whose onset was not located (nan: '?'), an onset whose last map amplitude is unstable but whose
    limit is stable has its offset not located (nan), an unstable limit continues an open interval to inf; without a
    limit record the largest map amplitude decides, as before."""
    from hertzpetsc.studies.maps import KIND_EDGE, map_table, unstable_intervals
    nan, inf = math.nan, math.inf
    rows = [  # q, kind, A, rho, A_stable, A_unstable
        (1.0, KIND_POINT, 0.1, 1.0, nan, nan), (1.0, KIND_POINT, 0.2, 1.0, nan, nan),
        (1.0, KIND_LIMIT, inf, 1.1, nan, nan),
        (2.0, KIND_POINT, 0.1, 1.0, nan, nan), (2.0, KIND_EDGE, 0.15, nan, 0.149, 0.151),
        (2.0, KIND_POINT, 0.2, 1.1, nan, nan), (2.0, KIND_LIMIT, inf, 1.0, nan, nan),
        (3.0, KIND_POINT, 0.1, 1.0, nan, nan), (3.0, KIND_EDGE, 0.15, nan, 0.149, 0.151),
        (3.0, KIND_POINT, 0.2, 1.1, nan, nan), (3.0, KIND_LIMIT, inf, 1.1, nan, nan),
        (4.0, KIND_POINT, 0.1, 1.0, nan, nan), (4.0, KIND_LIMIT, inf, 1.0, nan, nan)]
    z = {k: np.array([r[i] for r in rows]) for i, k in enumerate(("q", "kind", "A", "rho", "A_stable", "A_unstable"))}
    z["tol_rho"] = 1e-6
    spans = unstable_intervals(z)
    assert np.array_equal(spans[1.0], [(nan, inf)], equal_nan=True)
    assert np.array_equal(spans[2.0], [(0.15, nan)], equal_nan=True)
    assert spans[3.0] == [(0.15, inf)] and spans[4.0] == []
    keep = z["kind"] != KIND_LIMIT                      # no limit record: the largest amplitude decides
    assert unstable_intervals({k: (v[keep] if k != "tol_rho" else v) for k, v in z.items()}) == \
        {1.0: [], 2.0: [(0.15, inf)], 3.0: [(0.15, inf)], 4.0: []}
    # the table: '[?, inf]' where the onset before the limit was not located
    z = {k: np.array(v) for k, v in maps_file("stability_boundary_alpha2_N100.npz").items()}
    q = float(z["q"][0])
    mine = np.isclose(z["q"], q)
    z["rho"][mine & (z["kind"] == KIND_POINT)] = 1.0
    z["kind"][mine & (z["kind"] == KIND_EDGE)] = 99     # no edges for this q
    z["rho"][mine & (z["kind"] == KIND_LIMIT)] = 1.1
    from hertzpetsc.studies.floquet import q_label
    row = next(line for line in map_table(z).splitlines() if line.startswith(f"| {q_label(q)} |") and "[" in line)
    assert "[?, inf]" in row


def maps_file(name):
    from hertzpetsc.studies.maps import read_map
    return read_map(os.path.join(DATA, name))


def test_a_deflation_that_does_not_hold_gives_no_verdict(capfd):
    """A record whose symmetry vectors are not eigenvectors of its sector maps (eigenvector residual above
    maps.EIGVEC_MAX) keeps rho = nan with a note, and the table marks it '?', never '.' or 'U'."""
    from types import SimpleNamespace
    from hertzpetsc.studies import maps
    study = maps.StabilityMap(maps.MapParameters(LatticeModel.hertz(1.5, delta0=1.0), (2 * math.pi * 20 / 100,),
                                                 (0.1,)), SELF)
    chain = dict(rho=1.4, outside=3, sector=0.0, cluster=1.3, raw=0.1, eigvec=0.42, decoupled=True, E=math.nan)
    probe = SimpleNamespace(chain=lambda entry: chain)
    q = 2 * math.pi * 20 / 100
    row = study._row(q, maps.KIND_LIMIT, math.inf, math.inf, 0.9, probe, {})
    assert math.isnan(row["rho"]) and row["outside"] == -1 and row["eigvec"] == 0.42
    assert "eigenvector residual 4.2e-01" in capfd.readouterr().err
    chain["eigvec"] = 1e-9
    assert study._row(q, maps.KIND_LIMIT, math.inf, math.inf, 0.9, probe, {})["rho"] == 1.4
    z = maps.read_map(os.path.join(DATA, "stability_boundary_alpha2_N100.npz"))
    z = {k: np.array(v) for k, v in z.items()}
    lim = np.nonzero((z["kind"] == maps.KIND_LIMIT) & np.isclose(z["q"], q))[0]
    z["rho"][lim] = math.nan
    row = next(line for line in maps.map_table(z).splitlines() if line.startswith("| 2pi/5 |") and "`" in line)
    assert "|?`" in row and "'?' no verdict" in maps.map_table(z)


def test_simplest_fraction_is_the_smallest_denominator_in_the_interval():
    """Against a search over all denominators: the Stern-Brocot descent returns a member of the closed interval
    whose denominator no member has a smaller one."""
    from fractions import Fraction
    from hertzpetsc.studies.maps import simplest_fraction
    rng = np.random.default_rng(7)
    for _ in range(200):
        lo = Fraction(int(rng.integers(1, 10 ** 6)), 10 ** 6)
        hi = lo + Fraction(int(rng.integers(1, 10 ** 4)), 10 ** 7)
        x = simplest_fraction(lo, hi)
        assert lo <= x <= hi
        best = next(d for d in range(1, 10 ** 7) if math.floor(hi * d) >= math.ceil(lo * d))
        assert x.denominator == best
    assert simplest_fraction(Fraction(1, 3), Fraction(1, 2)) == Fraction(1, 2)


def test_boundary_in_q_is_confirmed_on_both_sides_and_resumes(tmp_path):
    """At A = 3 the infinite chain is unstable at 9pi/25 and stable at 2pi/5 (the map's located edges in A: 3.763
    and 2.216): the edge in q between them is located to the requested bracket through cells of few beads; the
    multipliers of its two ends are on both sides of the verdict's threshold; a second run of the file computes
    nothing; bad parameters name themselves."""
    from fractions import Fraction
    from hertzpetsc.studies.maps import KIND_EDGE_INF, QBoundary, QBoundaryParameters
    model = LatticeModel.hertz(1.5, (1.0,), 1.0)
    params = QBoundaryParameters(model, (3.0,), (9 * math.pi / 25, 2 * math.pi / 5), cells_per_pi=K,
                                 tolerances=TOL, twists=64, locate_tol=0.05)
    path = str(tmp_path / "q.npz")
    study = QBoundary(params, SELF, path)
    try:
        rows = list(study.run())
    finally:
        study.destroy()
    edges = [r for r in rows if r["kind"] == KIND_EDGE_INF]
    assert len(edges) == 1
    e = edges[0]
    assert e["rho_stable"] <= params.tol_rho < e["rho_unstable"]
    assert 9 * math.pi / 25 < e["q_unstable"] < e["q_stable"] < 2 * math.pi / 5       # the tongue closes as q grows
    assert abs(e["q_stable"] - e["q_unstable"]) <= 0.5 * params.locate_tol * min(e["q_stable"], e["q_unstable"])
    samples = [r for r in rows if r["kind"] == 0]
    assert len(samples) == 2 + e["evaluations"]
    for r in samples:                                   # each sample on its wave's cell, q / 2 pi = m / M
        x = Fraction(r["q"] / (2 * math.pi)).limit_denominator(2000)
        assert x.denominator == r["M"] and abs(float(x) * 2 * math.pi - r["q"]) < 1e-12
    again = QBoundary(params, SELF, path, mode="resume")
    try:
        assert list(again.run()) == []
        assert "| 3 |" in again.table()
    finally:
        again.destroy()
    with pytest.raises(ParameterError, match="masses"):
        QBoundaryParameters(LatticeModel.hertz(1.5, (1.0, 0.5), 1.0), (3.0,), (Q,))
    with pytest.raises(ParameterError, match="max_cell"):
        QBoundaryParameters(model, (3.0,), (Q,), max_cell=10)             # 3pi/10 needs a cell of 20 beads
    with pytest.raises(ParameterError, match="A"):
        QBoundaryParameters(model, (-1.0,), (Q,))


@pytest.mark.serial
def test_boundary_in_q_driver_on_one_and_two_ranks(tmp_path):
    """Two amplitudes dealt to two ranks give the records of one rank (each level on one rank); -render rewrites the
    table from the file; a bad amplitude is one error line."""
    args = ["-A", "3,3.5", "-m", "18,20", "-cells_per_pi", 100, "-rtol", "1e-10", "-twists", 64, "-locate_tol", 0.1]
    r = run_script("boundary_in_q.py", *args, "-output", tmp_path / "two.npz", "-table", tmp_path / "two.md",
                   "-figures", tmp_path, ranks=2)
    assert r.returncode == 0, r.stderr
    r = run_script("boundary_in_q.py", *args, "-output", tmp_path / "one.npz", "-table", tmp_path / "one.md")
    assert r.returncode == 0, r.stderr
    with np.load(tmp_path / "two.npz") as two, np.load(tmp_path / "one.npz") as one:
        assert str(two["format"]) == "hertzpetsc-boundary-q-2"
        k2, k1 = np.lexsort((two["q"], two["kind"], two["A"])), np.lexsort((one["q"], one["kind"], one["A"]))
        assert np.array_equal(two["kind"][k2], one["kind"][k1]) and np.array_equal(two["q"][k2], one["q"][k1])
        assert np.allclose(two["rho_inf"][k2], one["rho_inf"][k1], rtol=1e-12, atol=1e-12)
        assert np.sum(two["kind"] == 2) == 2                  # one edge per level, between 9pi/25 and 2pi/5
    assert (tmp_path / "two.png").exists()
    r = run_script("boundary_in_q.py", "-output", tmp_path / "two.npz", "-table", tmp_path / "again.md", "-render")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "again.md").read_text() == (tmp_path / "two.md").read_text()
    r = run_script("boundary_in_q.py", *args[2:], "-A", "0,3", "-output", tmp_path / "bad.npz")
    assert "-A" in one_error_line(r)
    r = run_script("boundary_in_q.py", "-A", "1,inf", "-N", 10, "-m", 2, "-output", tmp_path / "bad.npz")
    assert r.returncode == 2 and "-m" in one_error_line(r)        # a parameter error (it exited 4, a file's)


def test_a_map_of_small_amplitudes_reaches_its_uncompressed_limit():
    """The limit (delta0 / A = 0) is solved from the map's largest amplitude; from a = 0.3 delta0 its Newton did not
    converge (reason -5, the run stopped). It then starts from a = LIMIT_FROM_A delta0, and gives the limit that a
    map reaching a = 100 delta0 gives from there: the same wave (omega to 1e-9, the two starts' solver tolerance)
    and verdict."""
    model = LatticeModel.hertz(1.5, (1.0,), 1.0)
    limits = []
    for a in ((0.3,), (0.3, 100.0)):
        study = StabilityMap(MapParameters(model, (math.pi / 3,), a, N=6, cells_per_pi=100, locate=()), SELF)
        try:
            limits.append(next(r for r in study.run() if r["kind"] == KIND_LIMIT))
        finally:
            study.destroy()
    assert limits[0]["omega"] == pytest.approx(limits[1]["omega"], rel=1e-9)
    assert limits[0]["outside"] == limits[1]["outside"]


def small_map(a, output=None, mode="new", locate=()):
    return StabilityMap(MapParameters(LatticeModel.hertz(2.0, (1.0,), 0.5), (math.pi / 3,), a, N=6, cells_per_pi=100,
                                      locate=locate, limit=False), SELF, output, mode)


def test_resume_refuses_other_amplitudes(tmp_path):
    """-resume with another amplitude list (or -ds grid) is refused naming a: each q's family, located edges and
    limit depend on all the map's amplitudes (it had marked the q done and left out the new amplitude). A file
    written before the amplitudes were stored resumes with its own parameters."""
    from hertzpetsc.errors import RecordFileError
    path = str(tmp_path / "m.npz")
    study = small_map((0.3, 3.0), path)
    try:
        assert [r["a"] for r in study.run() if r["kind"] == KIND_POINT] == pytest.approx([0.3, 3.0], rel=1e-14)
    finally:
        study.destroy()
    with np.load(path) as z:
        assert z["amplitudes"].tolist() == pytest.approx([0.3, 3.0], rel=1e-14)
        old = {k: z[k] for k in z.files if k != "amplitudes"}
    for a in ((0.3, 3.0, 10.0), (0.3,), (0.3, 2.0)):
        study = small_map(a, path, "resume")
        try:
            with pytest.raises(RecordFileError, match=r"amplitudes = \[0\.3, 3\.0\] there, .* requested, set by a \(-a"):
                list(study.run())
        finally:
            study.destroy()
    study = small_map((3.0, 0.3), path, "resume")       # the same amplitudes: nothing to compute
    try:
        assert list(study.run()) == []
    finally:
        study.destroy()
    np.savez(tmp_path / "old.npz", **old)
    study = small_map((0.3, 3.0), str(tmp_path / "old.npz"), "resume")
    try:
        assert list(study.run()) == []                  # no amplitudes stored: not compared, nothing to compute
    finally:
        study.destroy()


def test_a_failed_companion_wave_fails_the_family_step():
    """alpha = 1.2, pi/4: the family's natural step from a = 1 to 10 converges on the h = pi/K grid to a wave whose
    h = pi/2K companion Newton does not converge (a wave of the coarse grid only); the companion is solved in the
    map's test functions, whose failure escaped the layer (the run stopped). It now fails the step, which is halved
    and retried: the map reaches a = 10 on the wave that the map through 2 and 5 finds."""
    model = LatticeModel.hertz(1.2, (1.0,), 1.0)
    rows = {}
    for a in ((0.1, 1.0, 10.0), (0.1, 1.0, 2.0, 5.0, 10.0)):
        study = StabilityMap(MapParameters(model, (math.pi / 4,), a, N=40, cells_per_pi=200, limit=False), SELF)
        try:
            rows[a] = next(r for r in study.run() if r["kind"] == KIND_POINT and abs(r["a"] - 10) < 1e-9)
        finally:
            study.destroy()
    one, other = rows.values()
    # the same wave (the two Newton solves' tolerance) and its spectrum (the flows' rtol 1e-11)
    assert one["omega"] == pytest.approx(other["omega"], rel=1e-9)
    assert one["A"] == pytest.approx(other["A"], rel=1e-9)
    assert one["rho"] == pytest.approx(other["rho"], rel=1e-8)


def test_compare_refuses_a_map_of_another_computation():
    """-compare: the verdicts of maps of other alpha, delta0, masses, N, grid or flow tolerance are not compared
    (the first differing constant is named); tol_rho may differ (the comparison is at the old threshold)."""
    from hertzpetsc.errors import RecordFileError
    from hertzpetsc.studies.maps import check_comparable, compare_v1
    old = maps_file("precompression_map.npz")
    new = maps_file("stability_boundary_alpha1.5_N100.npz")
    assert "agree at" in compare_v1(new, old)
    for key, value in (("alpha", 2.0), ("delta0", 0.5), ("masses", [1.0, 0.7]), ("N", 60), ("cells_per_pi", 200),
                       ("rtol", 1e-10)):
        with pytest.raises(RecordFileError, match=f"another computation: {key} = "):
            compare_v1(dict(new, **{key: np.asarray(value)}), old, path="x.npz")
    check_comparable(dict(new, tol_rho=np.asarray(1e-3)), old, "x.npz")


@pytest.mark.serial
def test_driver_refuses_changed_computations(tmp_path):
    """One error line each, naming the option: -resume with another -a (exit 4), -compare of a map of another alpha
    (exit 4, -render and computing), -q without -twists (exit 2, -q: the infinite chain only), an option of the
    computation with -render (exit 2)."""
    args = ["-alpha", 2, "-delta0", 0.5, "-N", 6, "-m", 1, "-cells_per_pi", 100, "-locate", "none"]
    out = ["-output", tmp_path / "m.npz", "-table", tmp_path / "m.md"]
    r = run_script("precompression_map.py", *args, "-a", "0.3,3", *out)
    assert r.returncode == 0, r.stderr
    r = run_script("precompression_map.py", *args, "-a", "0.3,3,10", *out, "-resume")
    assert r.returncode == 4 and "(-a" in one_error_line(r)
    old = os.path.join(DATA, "precompression_map.npz")
    r = run_script("precompression_map.py", "-render", "-compare", old, *out)
    assert r.returncode == 4 and "alpha = 1.5 there, 2 in this map" in one_error_line(r)
    r = run_script("precompression_map.py", *args, "-a", "0.3", "-compare", old, "-output", tmp_path / "c.npz",
                   "-table", tmp_path / "c.md")
    assert r.returncode == 4 and "alpha = 1.5 there" in one_error_line(r) and not (tmp_path / "c.npz").exists()
    r = run_script("precompression_map.py", *args, "-q", "pi/7", "-a", "0.3", "-output", tmp_path / "q.npz")
    assert r.returncode == 2 and one_error_line(r).startswith("error: invalid -q = ") and "twists > 0" in r.stderr
    r = run_script("precompression_map.py", "-render", "-alpha", 3, *out)
    assert r.returncode == 2 and one_error_line(r).startswith("error: invalid -alpha = ")


def test_a_wave_reached_by_a_warm_start_is_the_cold_wave():
    """alpha = 2, pi/2 on 100 beads, just past the gap opening (A_gap = 0.968): the zones' contact is weak, each
    zone's translation is nearly an eigenvector, and every sector holds a pair of multipliers 1 +- i s with s about
    1e-6, whose splitting goes as the square root of the orbit's error. The bubble search between a = 1 and 1.5 steps
    the family by bisection; a corrector from the interpolation of the bracket stopped after one Newton iteration
    below the SNES atol, 80 times the converged residual: at a = 1.0063555 the orbit's error was 4.3e-10 (1.2e-11
    cold), the pair split off the circle (rho - 1 = 1.2e-5) and the map located a band A = 1.0572 - 1.0625 that the
    wave computed alone (rho - 1 = 4e-11) does not have. The map's waves are now solved again from themselves: every
    wave it evaluates is the cold one to the grid's round-off floor, and no edge is located. Which is right: the
    orbit refined on the chain by Gauss-Newton (E <= 1e-13) has the pair on the circle."""
    from hertzpetsc.model import ChainSpec
    from hertzpetsc.shooting import Refiner
    from hertzpetsc.studies import maps
    model, q, K = LatticeModel.hertz(2.0, (1.0,), 1.0), math.pi / 2, 1000
    waves = []
    wave = maps.MapProbe.wave

    def kept(self, entry):
        e = wave(self, entry)
        waves.append((e["point"].a, e["w"][0], e["lam"]))
        return e
    maps.MapProbe.wave = kept
    study = StabilityMap(MapParameters(model, (q,), (1.0, 1.5), N=100, cells_per_pi=K, tolerances=TOL, limit=False),
                         SELF)
    try:
        rows = list(study.run())
    finally:
        maps.MapProbe.wave = wave
        study.destroy()
    assert not any(r["kind"] == KIND_EDGE for r in rows)
    assert all(r["rho"] - 1 < 1e-6 for r in rows if r["kind"] == KIND_POINT)
    searched = sorted({a for a, _, _ in waves if 1.0 < a < 1.5})
    assert len(searched) >= 3                           # the bubble search stepped the family between the two
    a_mid = min(searched, key=lambda a: abs(a - 1.0063555))
    [(_, (w_cold,), lam_cold)] = richardson_waves(model, q, [a_mid], K)      # from the linear wave, cold
    for a, w, lam in waves:
        if a == a_mid:
            # one Newton iteration from a converged K wave moves it by at most 2e-11 (its round-off floor); the
            # warm-started wave was 6e-10 away
            assert np.max(np.abs(w - w_cold)) < 1e-10 and abs(lam - lam_cold) < 1e-9
    with Refiner(ChainSpec(model, 100), SELF, 1e-12) as refiner:
        orbit = refiner.refine(wave_orbit(model, q, a_mid, [w_cold], lam_cold, 100, math.pi / K)).orbit
    route = DeflatedSectors(model, SELF, TOL, twists=None, krein=1e-6)
    try:
        spec = route.spectrum(orbit, 1e-6)
    finally:
        route.destroy()
    assert spec.rho - 1 < 1e-8
    pair = [s.values[np.argsort(np.abs(s.values - 1))[:2]] for s in spec.work["sectors"][1:]]
    assert all(np.all(np.abs(v.imag) > 100 * np.abs(np.abs(v) - 1)) for v in pair)


def test_a_multiplier_near_one_is_judged_on_the_refined_orbit():
    """alpha = 3/2, pi/2 on 100 beads at a = 1 (A = 1.029, past the gap opening at 0.845): the Richardson wave's
    orbit error E is about 4e-10 (the law's (delta0 - r)^(3/2) limits the extrapolation), which splits the nearly
    defective zone-translation pair at 1 off the unit circle: rho - 1 = 3e-6 on the deflated sectors and on all 200
    multipliers alike (the dense route), and the map said unstable here and located a band A = 1.0239 - 1.0344
    around it. The orbit refined on the chain by Gauss-Newton has the pair on the circle on both routes; the map's
    verdict is now that orbit's (E_chain recorded)."""
    from hertzpetsc.floquet import DenseFloquet
    from hertzpetsc.model import ChainSpec
    from hertzpetsc.shooting import Refiner
    from hertzpetsc.studies.maps import REFINE_TOL
    model, q, N, K = LatticeModel.hertz(1.5, (1.0,), 1.0), math.pi / 2, 100, 1000
    study = StabilityMap(MapParameters(model, (q,), (1.0,), N=N, cells_per_pi=K, tolerances=TOL, locate=(),
                                       limit=False), SELF)
    try:
        [row] = [r for r in study.run() if r["kind"] == KIND_POINT]
    finally:
        study.destroy()
    assert row["E_chain"] <= REFINE_TOL and row["rho"] - 1 < 1e-7
    [(a, w, lam)] = richardson_waves(model, q, [1.0], K)
    orbit = wave_orbit(model, q, a, w, lam, N, math.pi / K)
    with Refiner(ChainSpec(model, N), SELF, REFINE_TOL) as refiner:
        assert refiner.residual(orbit) > 1e-10
        refined = refiner.refine(orbit).orbit
    with DenseFloquet(ChainSpec(model, N), SELF, TOL) as dense:
        # every multiplier (the trivial group too, split by the square root of the flow's error, about 1e-8)
        rho = [float(np.max(np.abs(np.linalg.eigvals(dense.monodromy(o))))) - 1 for o in (orbit, refined)]
    assert rho[0] > 1e-6 and rho[1] < 1e-7


def test_a_weak_infinite_chain_instability_is_judged_on_the_refined_cell_orbit():
    """alpha = 3/2, 12pi/25 (a cell of 25 beads) at a = 1.01 (A = 1.041, past the gap opening at 0.896): the twist
    scan of the Richardson cell orbit finds rho - 1 of a few 1e-6 at small twists (the zones' translations, near 1
    over the twists, split by the orbit's error as on N beads), and the map said unstable there on the infinite
    chain while the 100-bead chain, refined, is stable. A weak instability (tol_rho < rho - 1 < NEAR_ONE) is now
    judged on the cell orbit refined by Gauss-Newton, with the flow at FINE_FLOW (E_cell recorded)."""
    from hertzpetsc.studies.maps import MAP_TOL_RHO, REFINE_TOL
    model, q, K = LatticeModel.hertz(1.5, (1.0,), 1.0), 12 * math.pi / 25, 1000
    study = StabilityMap(MapParameters(model, (q,), (1.01,), N=100, cells_per_pi=K, tolerances=TOL, locate=(),
                                       limit=False, twists=512), SELF)
    try:
        [row] = [r for r in study.run() if r["kind"] == KIND_POINT]
        sym = wave_cell(q, model.cell)
        [(a, w, lam)] = richardson_waves(model, q, [1.01], K)
        cell = wave_orbit(model, q, a, w, lam, sym.M, math.pi / K)
        unrefined = twist_scan(study.route(model), cell, -(-512 // sym.M), floor=MAP_TOL_RHO)
    finally:
        study.destroy()
    assert unrefined.rho_max - 1 > MAP_TOL_RHO                # the map's verdict before: unstable
    assert row["E_cell"] <= REFINE_TOL and row["rho_inf"] - 1 < MAP_TOL_RHO


def test_a_published_weak_verdict_is_judged_again_on_the_refined_cell_orbit(tmp_path, monkeypatch):
    """A map computed as before the refinement of weak verdicts (NEAR_ONE at tol_rho: no refinement) at alpha = 3/2,
    pi/2 (a cell of 4 beads), a = 1 (A = 1.029, past the gap opening): its infinite-chain record is a weak
    instability (rho - 1 a few 1e-6, the zones' translations split by the Richardson orbit's error) with no E_cell.
    The re-judging study reads that file, recomputes the record's Richardson cell orbit (its rho reproduced) and
    judges it on the orbit refined to E <= REFINE_TOL: stable (rho - 1 ~ 1e-7), the verdict changed in the table. A
    record already refined (E_cell finite) is not judged again."""
    from hertzpetsc.studies import maps
    from hertzpetsc.studies.rejudge import MapRejudging, RejudgeParameters, weak_records
    model, q, tol = LatticeModel.hertz(1.5, (1.0,), 1.0), math.pi / 2, maps.MAP_TOL_RHO
    path = str(tmp_path / "map.npz")
    with monkeypatch.context() as m:
        m.setattr(maps, "NEAR_ONE", tol)                          # the maps before the refinement
        study = StabilityMap(MapParameters(model, (q,), (1.0,), N=4, cells_per_pi=1000, tolerances=TOL, locate=(),
                                           limit=False, twists=512), SELF, path)
        try:
            [old] = [r for r in study.run() if r["kind"] == KIND_POINT]
        finally:
            study.destroy()
    assert tol < old["rho_inf"] - 1 < maps.NEAR_ONE and math.isnan(old["E_cell"])
    again = MapRejudging(RejudgeParameters(path), SELF, str(tmp_path / "rejudged.npz"))
    try:
        [row] = list(again.run())
        table = again.table()
    finally:
        again.destroy()
    # the Richardson cell orbit's number reproduced: the same wave, its scan with the old twist as a hint (the
    # golden-section refinement of the maxima ends within 1e-3 of a grid step: 4e-4 of rho - 1 here)
    assert row["rho_old"] == old["rho_inf"]
    assert abs(row["rho_unrefined"] - old["rho_inf"]) <= 1e-2 * (old["rho_inf"] - 1)
    assert row["E_cell"] <= maps.REFINE_TOL and row["rho_new"] - 1 < tol
    assert "1 verdicts judged again; 1 changed (unstable before, stable or unresolved now): pi/2 at A = 1.0288" in table
    z = dict(np.load(path))
    assert weak_records(z)[0] == [(row["index"], 0)]
    z["E_cell"] = np.where(np.arange(len(z["kind"])) == row["index"], 1e-13, np.asarray(z["E_cell"], float))
    assert not len(weak_records(z)[0])


def test_the_weak_verdicts_to_judge_again_include_an_unrefined_edges_unstable_end():
    """In a map written before E_cell an infinite-chain edge whose record is its stable end holds a weak verdict at
    its unstable end (rho_unstable at a_unstable: alpha = 2, 12pi/25, the onset at A = 1.075 had 3.0e-6 there): it
    is judged again (side 1), as a record's own weak rho_inf is (side 0); strong instabilities, stable verdicts, the
    N-bead edges and a map whose weak evaluations were refined (E_cell) are not."""
    from hertzpetsc.studies.rejudge import weak_records
    from hertzpetsc.verdicts import KIND_EDGE_INF
    z = dict(tol_rho=1e-6, kind=np.array([KIND_POINT, KIND_EDGE_INF, KIND_EDGE_INF, KIND_EDGE, KIND_POINT]),
             rho_inf=1 + np.array([3e-6, 1e-11, 2e-6, 1e-11, 5e-3]), a=np.array([1.0, 1.02, 1.03, 1.04, 2.0]),
             a_unstable=np.array([np.nan, 1.021, 1.03, 1.041, np.nan]),
             rho_unstable=np.array([np.nan, 3e-6, 2e-6, 3e-6, np.nan]))
    assert weak_records(z)[0] == [(0, 0), (1, 1), (2, 0)]
    assert weak_records(dict(z, E_cell=np.full(5, np.nan)))[0] == [(0, 0), (2, 0)]


def test_a_rejudging_table_of_a_stopped_run_says_what_is_not_judged_yet():
    """The table of a re-judging file holding 2 of its source's 3 weak verdicts (a run stopped, or in progress) says
    so; the changed verdict is named with its q and A, the unchanged one's relative agreement given."""
    from hertzpetsc.studies.rejudge import REJUDGE_FIELDS, rejudging_table
    z = {k: np.array([0.0, 0.0]) for k in REJUDGE_FIELDS}
    z.update(index=np.array([4, 7]), side=np.array([0, 1]), kind=np.array([KIND_POINT, 2]),
             q=np.array([math.pi / 2, math.pi / 5]), A=np.array([1.0288, 0.3]), a=np.array([1.0, 0.29]),
             rho_old=1 + np.array([3e-6, 5e-4]), rho_new=1 + np.array([2e-7, 5.5e-4]), cert_new=np.array([0, -1]),
             rho_unrefined=1 + np.array([3e-6, 5e-4]))
    z.update(tol_rho=1e-6, near_one=1e-3, refine_tol=1e-11, source="x.npz", source_format="m", alpha=1.5,
             delta0=1.0, masses=np.array([1.0]), cells_per_pi=1000, twists=512, rtol=1e-11, weak=3, limits_left=0)
    text = rejudging_table(z)
    assert "2 verdicts judged again; 1 changed (unstable before, stable or unresolved now): pi/2 at A = 1.0288" in text
    assert "rho - 1 within 1.0e-01 relative" in text and "1 of the source's 3 weak verdicts not judged yet" in text
    assert "| 7 (unstable end) | edge (inf) | pi/5" in text and "| unstable | unresolved |" in text


@pytest.mark.serial
def test_rejudge_driver_on_one_and_two_ranks_resumes_and_renders(tmp_path):
    """scripts/rejudge_map.py on a small map of kind -2 (tests/data, 3pi/10 on 20 beads): its one weak verdict (an
    infinite-chain edge's, rho - 1 = 1.45e-5) judged again, the same record on 1 and 2 ranks; -resume adds nothing,
    -render rewrites the same table; the provenance names the source's digest."""
    import json
    source = os.path.join(DATA, "map_v2_small.npz")
    tables = []
    for ranks in (1, 2):
        out = tmp_path / f"r{ranks}.npz"
        r = run_script("rejudge_map.py", "-source", source, "-output", out, "-table", tmp_path / f"r{ranks}.md",
                       ranks=ranks)
        assert r.returncode == 0, r.stderr
        tables.append((tmp_path / f"r{ranks}.md").read_text())
    one, two = (dict(np.load(tmp_path / f"r{n}.npz")) for n in (1, 2))
    assert list(one["index"]) == list(two["index"]) == [0] and one["rho_new"][0] - 1 > float(one["tol_rho"])
    assert abs(one["rho_new"][0] - two["rho_new"][0]) <= 1e-12 and one["E_cell"][0] <= 1e-11
    assert "1 verdicts judged again; 0 changed" in tables[0]
    about = json.loads(str(one["__provenance__"]))
    assert about["inputs"]["source"]["sha256"] == str(one["source_sha256"])
    r = run_script("rejudge_map.py", "-source", source, "-output", tmp_path / "r1.npz", "-table",
                   tmp_path / "again.md", "-resume")
    assert r.returncode == 0 and "(0 not in" in r.stdout, r.stderr
    r = run_script("rejudge_map.py", "-render", "-output", tmp_path / "r1.npz", "-table", tmp_path / "render.md")
    assert r.returncode == 0 and (tmp_path / "render.md").read_text() == tables[0], r.stderr


def test_the_boundary_in_q_judges_a_weak_verdict_on_the_refined_cell_orbit():
    """The boundary in q reads the map's probe (MapProbe.infinite): at alpha = 3/2, pi/2, A = 1.0288 (the map's
    a = 1 of the test above) its record is judged on the refined cell orbit and says so (E_cell), and the
    refiner's prefixes are among its roles (their options read, in the file's identity)."""
    from fractions import Fraction
    from hertzpetsc.studies.maps import MAP_TOL_RHO, REFINE_TOL, QBoundary, QBoundaryParameters
    model = LatticeModel.hertz(1.5, (1.0,), 1.0)
    study = QBoundary(QBoundaryParameters(model, (1.0288,), (math.pi / 2,), cells_per_pi=1000, tolerances=TOL), SELF)
    try:
        row = study.evaluate(Fraction(1, 4), 1.0288)
    finally:
        study.destroy()
    assert row["E_cell"] <= REFINE_TOL and row["rho_inf"] - 1 < MAP_TOL_RHO
    assert {"shoot_", "shoot_jac_"} <= set(QBoundary.ROLES)


def test_an_edge_whose_bisection_fails_is_in_the_table_as_unresolved(monkeypatch, capfd):
    """The bubble of test_located_bubble_is_confirmed_by_the_multipliers_on_both_sides with the family's corrector
    failing within 1e-3 in log a of its onset: the layer dropped the onset, and the table showed the offset alone,
    without a word. The onset is now a record (located 0) whose bracket holds the located onset, wider than the
    bisection's 1e-3, shown 'unresolved' in the table (its interval's end '?'), with a note; the offset is
    unchanged."""
    from hertzpetsc.errors import ConvergenceError
    from hertzpetsc.families import FamilyProblem
    from hertzpetsc.studies.maps import map_table

    def edges():
        study = StabilityMap(MapParameters(LatticeModel.hertz(1.5, (1.0,), 1.0), (Q,), (0.5, 0.65), N=20,
                                           cells_per_pi=K, tolerances=TOL, limit=False), SELF)
        try:
            rows = list(study.run())
            return sorted((r for r in rows if r["kind"] == KIND_EDGE), key=lambda r: r["A"]), \
                map_table(study.arrays())
        finally:
            study.destroy()
    (onset, offset), _ = edges()
    assert onset["located"] == offset["located"] == 1
    s_on, solve = math.log(onset["a"]), FamilyProblem.solve

    def blind(self, Z, row=None, value=None):
        if row is None and value is not None and abs(value - s_on) <= 1e-3:
            raise ConvergenceError("precompressed wave", "no convergence (blind)", log_a=value)
        return solve(self, Z, row, value)
    monkeypatch.setattr(FamilyProblem, "solve", blind)
    capfd.readouterr()
    found, table = edges()
    assert len(found) == 2
    bracketed, same = found
    assert bracketed["located"] == 0 and same["located"] == 1 and same["A"] == offset["A"]
    assert bracketed["a_stable"] < onset["a"] < bracketed["a_unstable"]          # the onset within its bracket
    assert abs(math.log(bracketed["a_unstable"] / bracketed["a_stable"])) > 2e-3  # wider than the blind window
    assert bracketed["rho_stable"] < 1e-6 < bracketed["rho_unstable"]
    row = next(line for line in table.splitlines() if f"| {bracketed['A_stable']:.6g} |" in line)
    assert "| onset, unresolved |" in row and "1 edge unresolved" in table
    assert f"[?, {same['A']:.5g}]" in table
    assert "note: the event 'chain' of log_a was not located" in capfd.readouterr().err
