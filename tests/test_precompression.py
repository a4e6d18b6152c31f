"""Precompressed monatomic chains (issue 16): the law, the bordered amplitude continuation, its two limits, the gap
opening, Floquet on the chain, the drivers and their bad input."""
import math
import os

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import one_error_line, run_script, small_branch
from hertzpetsc.advdelay import AdvanceDelayProblem
from hertzpetsc.chain import IntegrationTolerances
from hertzpetsc.errors import ConvergenceError, ParameterError
from hertzpetsc.floquet import DenseFloquet
from hertzpetsc.grid import ProfileGrid
from hertzpetsc.hertz import HertzLaw
from hertzpetsc.model import ChainSpec, LatticeModel
from hertzpetsc.families import AmplitudeFamily, check_amplitude, uncompressed_limit
from hertzpetsc.stencil import full_period, shifted
from hertzpetsc.studies.precompression import amplitude_grid, wave_orbit

COMM = PETSc.COMM_WORLD
Q = 0.3 * math.pi


def test_law_is_the_shifted_hertz_law():
    """V'_delta(r) = delta^alpha + V'_0(r - delta); V'(0) = 0, V''(0) = alpha delta^(alpha-1); V' = dV/dr, V'' = dV'/dr."""
    r = np.linspace(-3, 3, 601)
    for alpha, d in ((1.5, 1.0), (2.5, 0.7)):
        law, law0 = HertzLaw(alpha, d), HertzLaw(alpha)
        assert np.allclose(law.dV(r), d ** alpha + law0.dV(r - d), rtol=1e-13, atol=1e-13)
        assert law.dV(0.0) == 0.0 and law.V(0.0) == 0.0
        assert law.d2V(0.0) == pytest.approx(alpha * d ** (alpha - 1), rel=1e-15)
        e = 1e-6   # central differences: O(e^2) = 1e-12 relative, V'' is smooth away from r = d
        rr = r[np.abs(r - d) > 1e-3]
        assert np.allclose((law.V(rr + e) - law.V(rr - e)) / (2 * e), law.dV(rr), rtol=1e-7, atol=1e-8)
        assert np.allclose((law.dV(rr + e) - law.dV(rr - e)) / (2 * e), law.d2V(rr), rtol=1e-7, atol=1e-8)
    # no cancellation for |r| << delta: V'(r) = K r (1 + O(r / delta)) to the last digits
    small = np.array([1e-12, -1e-12])
    assert np.allclose(HertzLaw(1.5, 1e3).dV(small) / small, 1.5 * 1e3 ** 0.5, rtol=1e-9)


@pytest.mark.parametrize("alpha", [1.5, 2.0, 2.5, 3.0, 1.7])
def test_compressed_force_is_accurate_to_a_few_ulp(alpha):
    """delta^alpha - (delta - r)_+^alpha (hertz.compressed_force: sums of positive terms for whole and half-whole
    alpha, expm1/log1p otherwise) against the binomial series for |r| <= 1e-4 delta (six terms: truncation
    (1e-4)^6 / 1e-4 = 1e-20 relative) and against the direct difference where it does not cancel (r <= -3 delta:
    the difference is at least 1 - 4^-alpha of the larger power); 8 ulp. Out of contact: delta^alpha exactly."""
    eps = np.finfo(float).eps
    delta = 0.7
    law = HertzLaw(alpha, delta)
    e = np.concatenate([-np.logspace(-12, -4, 60), np.logspace(-12, -4, 60)])
    series, binom = np.zeros_like(e), 1.0
    for j in range(1, 7):
        binom *= (alpha - j + 1) / j
        series -= binom * (-e) ** j
    ref = delta ** alpha * series
    assert np.max(np.abs(law.dV(delta * e) - ref) / np.abs(ref)) <= 8 * eps
    far = -delta * np.linspace(3.0, 10.0, 50)
    direct = delta ** alpha - (delta - far) ** alpha
    assert np.max(np.abs(law.dV(far) - direct) / np.abs(direct)) <= 8 * eps
    assert np.all(law.dV(np.array([delta, 2 * delta, 1e3])) == delta ** alpha)


def test_delta0_zero_is_the_paper_chain_bit_for_bit():
    """delta0 = 0 and unit masses evaluate exactly the paper's expressions (same code path), and the record
    identity is unchanged."""
    m0, m = LatticeModel.hertz(1.5), LatticeModel.hertz(1.5, (1.0,), 0.0)
    assert m0 == m and m.describe() == dict(alpha=1.5, masses=[1.0])
    assert "delta0" in LatticeModel.hertz(1.5, delta0=0.5).describe()
    r = np.random.default_rng(3).standard_normal(50)
    assert np.array_equal(m.force(r), -np.sqrt(-np.minimum(r, 0)) * (-np.minimum(r, 0)))
    grid = ProfileGrid(40, PETSc.COMM_SELF)
    X = grid.create_vec()
    X.setArray(r[:grid.size])
    F0, F1 = X.duplicate(), X.duplicate()
    AdvanceDelayProblem(m0, grid, 0.77).formFunction(None, X, F0)
    AdvanceDelayProblem(m, grid, 0.77).formFunction(None, X, F1)
    assert np.array_equal(F0.getArray(), F1.getArray())


def test_precompressed_advance_delay_problem_matches_its_definition():
    """AdvanceDelayProblem with delta0 > 0 (V' nonzero beyond contact) against eq. ad evaluated with numpy."""
    grid = ProfileGrid(64, PETSc.COMM_SELF)
    model = LatticeModel.hertz(1.5, delta0=0.3)
    q = 16 * grid.h                                       # integer shift: the numpy shift is exact
    u_half = np.sin(grid.xi_half()) * 0.8
    X = grid.vec_from_half_profile(u_half)
    F = X.duplicate()
    AdvanceDelayProblem(model, grid, q).formFunction(None, X, F)
    u = full_period(u_half)
    d2 = (np.roll(u, -1) - 2 * u + np.roll(u, 1)) / grid.h ** 2
    ref = d2 - model.force(shifted(u, 16) - u) + model.force(u - shifted(u, -16))
    assert np.allclose(F.getArray(), ref[1:grid.K], rtol=1e-12, atol=1e-12)


def _coefficient(q, alpha, delta0, K, amplitudes):
    """C_h from omega/omega_lin,h - 1 = C a^2 + D a^4 + E a^6 at the given a (discrete linear frequency)."""
    model = LatticeModel.hertz(alpha, delta0=delta0)
    cont = AmplitudeFamily(model, q, ProfileGrid(K, COMM))
    try:
        pts = list(cont.points(amplitudes))
        _, lam = cont.problem.linear_guess()
        omega_lin_h = math.sqrt(lam) * cont.problem.amplitude ** ((alpha - 1) / 2)
    finally:
        cont.destroy()
    y = np.array([p.omega / omega_lin_h - 1 for p in pts])
    return np.linalg.lstsq(np.stack([amplitudes ** 2, amplitudes ** 4, amplitudes ** 6], 1), y, rcond=None)[0][0]


@pytest.mark.parametrize("q, alpha, delta0", [(0.3 * math.pi, 1.5, 1.0), (0.8 * math.pi, 1.5, 1.0),
                                              (0.3 * math.pi, 2.5, 2.0)])
def test_small_amplitude_coefficient(q, alpha, delta0):
    """omega / omega_lin - 1 = C(q) a^2 + O(a^4), C = (alpha-1)(alpha-1-sin^2(q/2)) / (4 delta0^2): C_h on h = pi/200
    and pi/400 against the scheme's own linear frequency, then Richardson (second order). Measured: relative
    error 2e-8 .. 6e-8 after Richardson (the O(h^4) remainder and the fit's truncation at a^6), 3e-4 before;
    the ratio (C_2K - C) / (C_K - C) is 0.25 to 3 digits (second order)."""
    a = delta0 * np.array([0.01, 0.02, 0.03, 0.04])
    C_K, C_2K = (_coefficient(q, alpha, delta0, K, a) for K in (200, 400))
    C = HertzLaw(alpha, delta0).stokes_coefficient(q)
    assert abs((4 * C_2K - C_K) / 3 / C - 1) < 1e-6
    assert abs((C_2K - C) / (C_K - C) - 0.25) < 0.02


def test_large_amplitude_limit_is_the_uncompressed_wave():
    """omega A^(-(alpha-1)/2) -> Omega0 = ||u(.;q)||^((1-alpha)/2) (eq. dispers) at rate delta0/A: the eta = 0 solve
    reproduces the paper's branch on the same grid (same discrete equations, other normalisation: solver
    tolerance), and (Omega - Omega0) A / delta0 settles to a constant c1 (measured: changes by 2e-4 relative from
    A = 1e3 to 1e4, by 2e-3 from 1e2 to 1e3, consistent with an O(delta0/A) next term)."""
    K = 200
    model = LatticeModel.hertz(1.5, delta0=1.0)
    grid = ProfileGrid(K, COMM)
    cont = AmplitudeFamily(model, Q, grid)
    try:
        pts = list(cont.points(amplitude_grid(1e-3, 1e4, math.log(10) / 4)))
        limit = uncompressed_limit(model, Q, grid, pts[-1])
    finally:
        cont.destroy()
    branch = small_branch(K=K)
    norm = branch.point(Q).diagnostics.norm_inf
    assert limit["Omega0"] == pytest.approx(norm ** -0.25, rel=1e-11)
    by_A = {round(math.log10(p.a)): p for p in pts if abs(math.log10(p.a) - round(math.log10(p.a))) < 1e-9}
    c1 = {k: (by_A[k].Omega - limit["Omega0"]) * by_A[k].A for k in (2, 3, 4)}
    assert c1[4] > 0
    assert abs(c1[3] / c1[4] - 1) < 2e-3 and abs(c1[2] / c1[3] - 1) < 2e-2
    assert np.all(np.diff([p.A for p in pts]) > 0)          # no fold in s = log a
    assert [p.omega for p in pts][0] == pytest.approx(model.linear_frequencies(Q)[0], rel=1e-4)  # h^2/24 ~ 1e-5


def test_the_optical_dimer_wave_at_the_zone_edge_reaches_its_uncompressed_limit():
    """At per-bead q = pi/2 (the dimer's zone edge) the optical wave is carried by the light bead (its linear wave
    leaves the heavy one at rest), so its family normalises profile 1; the delta0 / a = 0 solve starts from the
    family's last wave with the same normalisation (with profile 0's it began at residual 1 and diverged) and
    gives the Omega0 that the family's Omega = Omega0 + c1 delta0 / A + O((delta0 / A)^2) extrapolates to
    (three-term fit over A >= 100: error O((delta0 / A)^3) ~ 1e-6 at A = 100)."""
    model = LatticeModel.hertz(1.5, masses=(1.0, 0.5), delta0=1.0)
    grid = ProfileGrid(100, COMM)
    fam = AmplitudeFamily(model, math.pi / 2, grid, branch="optical")
    try:
        pts = list(fam.points(amplitude_grid(1e-2, 1e3, math.log(10) / 4)))
        assert pts[-1].normalised == 1
        limit = uncompressed_limit(model, math.pi / 2, grid, pts[-1])
    finally:
        fam.destroy()
    assert limit["iterations"] <= 4
    far = [p for p in pts if p.A >= 100]
    x = np.array([1.0 / p.A for p in far])
    fit = np.linalg.lstsq(np.stack([np.ones_like(x), x, x ** 2], 1), [p.Omega for p in far], rcond=None)[0][0]
    assert limit["Omega0"] == pytest.approx(fit, rel=1e-6)


def test_gap_opening():
    """The gap indicator 2 u(q/2) - delta0 vanishes at the located point, where the largest extension u(xi+q) - u(xi)
    on the grid equals delta0 (O(h^2): the grid misses the maximiser by up to h/2 on a smooth maximum); A_gap
    Richardson (pi/200, pi/400) against the independent scipy prototype's 1.9170281 (Richardson of pi/500 and
    pi/1000; measured difference here 3e-7, O(h^4))."""
    A_gap = []
    for K in (200, 400):
        grid = ProfileGrid(K, COMM)
        cont = AmplitudeFamily(LatticeModel.hertz(1.5, delta0=1.0), Q, grid)
        try:
            pts = list(cont.points(amplitude_grid(0.5, 3.0, 0.3)))
            gaps = cont.events()            # located by the continuation layer between the natural steps
        finally:
            cont.destroy()
        assert len(gaps) == 1
        gap = gaps[0]
        assert any(pts[k - 1].gap < 0 <= pts[k].gap and pts[k - 1].a < gap.a < pts[k].a for k in range(1, len(pts)))
        assert abs(gap.gap) < 1e-9
        u = full_period(gap.a * gap.profiles[0])
        sigma = int(round(Q / grid.h))
        assert np.max(shifted(u, sigma) - u) == pytest.approx(1.0, abs=grid.h ** 2)
        A_gap.append(gap.A)
    assert (4 * A_gap[1] - A_gap[0]) / 3 == pytest.approx(1.9170281, abs=2e-6)
    assert 1 / (2 * math.sin(Q / 2)) < A_gap[1]          # the linear estimate is below (softening in extension)


def test_floquet_depends_on_delta0_over_A_only():
    """Exact scaling x -> 2x, delta0 -> 2 delta0, t -> 2^(-(alpha-1)/2) t: the waves (delta0 = 1, a) and (delta0 = 2, 2a)
    on the chain have the same Floquet multipliers modulo shift (to the flow's tolerance); at a small amplitude the
    wave is linearly stable (|mu| = 1 up to the trivial splitting)."""
    N, q = 10, 2 * math.pi / 10
    tol = IntegrationTolerances(rtol=1e-11, atol=1e-13)
    spectra = []
    for d0, a in ((1.0, 1.5), (2.0, 3.0), (1.0, 0.01)):
        model = LatticeModel.hertz(1.5, delta0=d0)
        cont = AmplitudeFamily(model, q, ProfileGrid(200, COMM))
        try:
            p = list(cont.points([x * d0 for x in (0.01, 0.1, 0.5, 1.0, 1.5)] if a > 0.01 else [a]))[-1]
        finally:
            cont.destroy()
        orbit = wave_orbit(model, q, p.a, list(p.profiles), p.lam, N, cont.grid.h)
        dense = DenseFloquet(ChainSpec(model, N), COMM, tol)
        try:
            spectra.append(np.sort_complex(dense.spectrum(orbit).multipliers))
        finally:
            dense.destroy()
    assert np.allclose(spectra[0], spectra[1], atol=1e-7)
    assert np.max(np.abs(spectra[2])) < 1 + 1e-5


def test_bad_input():
    with pytest.raises(ParameterError, match="delta0"):
        LatticeModel.hertz(1.5, delta0=-0.1)
    with pytest.raises(ParameterError, match="masses"):
        LatticeModel.hertz(1.5, masses=(1.0, 0.0))
    with pytest.raises(ParameterError, match="multiple of the mass pattern"):
        ChainSpec(LatticeModel.hertz(1.5, masses=(1.0, 0.5), delta0=1.0), 5)
    with pytest.raises(ParameterError, match="amplitude"):
        check_amplitude(-1.0)
    with pytest.raises(ParameterError, match="delta0"):
        AmplitudeFamily(LatticeModel.hertz(1.5), Q, ProfileGrid(20, COMM))


@pytest.mark.serial
@pytest.mark.parametrize("args, name", [(("-delta0", "-1"), "-delta0"), (("-a_min", "-0.5"), "-a_min"),
                                        (("-precomp_snes_rtoll", "1"), "-precomp_snes_rtoll"),
                                        (("-branch", "optical"), "-branch"), (("-branch", "upper"), "-branch"),
                                        (("-masses", "1,0"), "-masses"), (("-a_min", "1e-300"), "-a_min"),
                                        (("-a_min", "1e-100", "-a_max", "1e-99"), "-a_min"),
                                        (("-a_min", "100"), "-a_min")])
def test_driver_bad_input_one_line(tmp_path, args, name):
    res = run_script("precompressed_branch.py", *args, "-output", tmp_path / "x.npz", "-table", tmp_path / "x.md")
    assert name in one_error_line(res)


@pytest.mark.serial
def test_driver_records_resume_and_ranks(tmp_path):
    """The driver writes its records and table, refuses to overwrite, resumes without recomputing, and gives the same
    numbers on 2 ranks (LU with MUMPS instead of PETSc's LU: round-off, bound 1e-10 relative)."""
    common = ["-q", "3*pi/10", "-cells_per_pi", "100", "-a_min", "0.01", "-a_max", "100", "-ds", "0.5", "-figures",
              str(tmp_path)]
    out = lambda k: ["-output", tmp_path / f"p{k}.npz", "-table", tmp_path / f"p{k}.md"]   # noqa: E731
    r1 = run_script("precompressed_branch.py", *common, *out(1), timeout=120)
    assert r1.returncode == 0, r1.stderr
    d1 = np.load(tmp_path / "p1.npz")
    assert str(d1["format"]) == "hertzpetsc-precompressed-1" and set(d1["kind"]) == {0, 1, 2}
    assert "schema: hertzpetsc-precompressed-1" in open(tmp_path / "p1.md").read()
    assert os.path.exists(tmp_path / "precompressed_omega.png")
    assert "-resume" in one_error_line(run_script("precompressed_branch.py", *common, *out(1)))
    r = run_script("precompressed_branch.py", *common, *out(1), "-resume")
    assert r.returncode == 0 and len(np.load(tmp_path / "p1.npz")["q"]) == len(d1["q"])
    r2 = run_script("precompressed_branch.py", *common, *out(2), ranks=2, timeout=120)
    assert r2.returncode == 0, r2.stderr
    d2 = np.load(tmp_path / "p2.npz")
    for k in ("A", "omega", "Omega"):
        fin = np.isfinite(d1[k])
        assert np.allclose(d1[k][fin], d2[k][fin], rtol=1e-10, atol=0)


def test_amplitudes_below_the_floor_are_refused_and_above_it_keep_their_amplitude():
    """alpha = 3, q = pi/3: below amplitude_floor (eps^(1/4) delta0 here) the amplitude is refused, naming the Python
    argument (the API's A, a family's a); a family started at twice the floor resolves its amplitude: omega /
    omega_lin - 1 = C a^2 (omega_lin the scheme's, from the linear wave) to 1 % of C a^2 = 5e-8 (the scheme's O(h^2)
    in C is 0.03 % at h = pi/200; a wave that lost its amplitude would give 0, the old predictor accepted as converged
    O(1))."""
    from hertzpetsc.families import amplitude_floor, wave_at
    model = LatticeModel.hertz(3.0, delta0=1.0)
    grid, q = ProfileGrid(200, COMM), math.pi / 3
    lo = amplitude_floor(model)
    assert lo == pytest.approx(np.finfo(float).eps ** 0.25)
    with pytest.raises(ParameterError, match="invalid A = "):
        wave_at(model, q, 1e-300, grid)
    fam = AmplitudeFamily(model, q, grid)
    try:
        with pytest.raises(ParameterError, match="invalid a = "):
            fam.step_to(lo / 2)
        a = 2 * lo
        point = fam.step_to(a)
        fam.problem.set_parameter("a", a)
        lam_lin = fam.problem.linear_guess()[1]
    finally:
        fam.destroy()
    omega_lin = a ** ((3.0 - 1) / 2) * math.sqrt(lam_lin)
    C = float(model.law.stokes_coefficient(q))
    assert abs((point.omega / omega_lin - 1) - C * a * a) < 1e-2 * C * a * a


def test_trimer_family_goes_around_the_folds_past_its_gap_opening():
    """The trimer 1, 1/2, 1/3 (alpha = 3/2, delta0 = 1, q = 2 pi/15) folds in a just past its gap opening (an S:
    natural steps stall, reason -6); the layer's pseudo-arclength detour carries the family on, to the wave that the
    A-imposed family (wave_at, no fold in A there) finds at the same A: omega to 1e-6 relative (the 'sup' border row,
    a parabola through the largest grid value, is only piecewise smooth in w, and its Newton stops above the a1
    row's round-off), where the branch beyond the family's next fold differs by more than 1e-3."""
    from hertzpetsc.families import wave_at
    model = LatticeModel.hertz(1.5, (1.0, 0.5, 0.333333333333), 1.0)
    grid, q = ProfileGrid(60, COMM), 2 * math.pi / 15
    amplitudes = [0.1 * math.exp(0.1 * k) for k in range(25)]          # 0.1 .. 1.1, then 2.0086, 2.2198
    fam = AmplitudeFamily(model, q, grid, around_folds=0)
    try:
        with pytest.raises(ConvergenceError):
            list(fam.points(amplitudes + [2.0086, 2.2198]))
    finally:
        fam.destroy()
    fam = AmplitudeFamily(model, q, grid)
    try:
        point = list(fam.points(amplitudes + [2.0086, 2.2198]))[-1]
        events = [e.event for e in fam.events()]
    finally:
        fam.destroy()
    assert events.count("fold") == 2 and "gap" in events
    assert point.gap > 0
    imposed = wave_at(model, q, point.A, grid)
    assert abs(imposed.omega - point.omega) < 1e-6 * point.omega


def test_a_family_starting_beyond_the_linear_regime_is_continued_to_its_first_amplitude():
    """The first amplitude of a family above START_MAX delta0 (a = 0.3, delta0 = 0.5, alpha = 2, q = pi/6: the map's
    -a 0.3 on N = 60, m = 5) was solved by Newton from the linear wave at a and failed; the family now starts from the
    linear wave at START_MAX delta0 and steps to a, giving the wave a family from 1e-3 on a fine grid of a reaches
    (the same discrete problem: omega equal to the Newton tolerance, 1e-9). A first amplitude at or below START_MAX
    delta0 is solved as before, from the linear wave at that amplitude (the first point's a is it)."""
    from hertzpetsc.families import START_MAX
    model, q, grid = LatticeModel.hertz(2.0, delta0=0.5), math.pi / 6, ProfileGrid(60, COMM)
    omega = {}
    for name, amplitudes in (("direct", [0.3]), ("fine", np.geomspace(1e-3, 0.3, 30)), ("small", [0.02, 0.3])):
        fam = AmplitudeFamily(model, q, grid)
        try:
            points = [fam.step_to(a) for a in amplitudes]
        finally:
            fam.destroy()
        omega[name] = points[-1].omega
        assert points[0].a == pytest.approx(amplitudes[0], rel=1e-14) and points[-1].a == pytest.approx(0.3, rel=1e-14)
    assert 0.02 <= START_MAX * 0.5 < 0.3
    assert abs(omega["direct"] - omega["fine"]) < 1e-9 * omega["fine"]
    assert abs(omega["small"] - omega["fine"]) < 1e-9 * omega["fine"]


@pytest.mark.serial
def test_amplitudes_beyond_the_ceiling_are_refused():
    """A = 1e308 made wave_at's step count an OverflowError (log(A / a0) = inf); such waves' energies overflow. The
    ceiling is where the square of the energy per bond, (2A + delta0)^(2(alpha+1)), leaves the floats (closed form:
    finite at the ceiling, inf at twice it); wave.py refuses -A beyond it with one line naming -A and the range."""
    from hertzpetsc.families import amplitude_ceiling, check_wave_amplitude, wave_at
    for alpha, d0 in ((1.5, 1.0), (3.0, 0.5)):
        model = LatticeModel.hertz(alpha, delta0=d0)
        top = amplitude_ceiling(model)
        with np.errstate(over="ignore"):
            assert np.isfinite(np.float64(2 * top + d0) ** (2 * (alpha + 1)))
            assert np.isinf(np.float64(4 * top + d0) ** (2 * (alpha + 1)))
        assert check_wave_amplitude(model, top, "A") == top
        with pytest.raises(ParameterError, match=r"A = 1e\+308: .*must lie in \["):
            wave_at(model, Q, 1e308, ProfileGrid(20, COMM))
    r = run_script("wave.py", "-A", "1e308", "-cells_per_pi", "20", "-N", "30", "-q", "2*pi/15", timeout=120)
    assert r.returncode == 2 and "-A = 1e+308" in one_error_line(r) and "must lie in [" in r.stderr


def test_a_step_across_the_gap_opening_onto_another_branch_is_not_silent():
    """masses 1, 0.01, alpha = 2, q = pi/4: steps of 0.1 in log a jumped across the gap opening onto another branch
    (no A_gap, Omega0 0.575 instead of 0.655) and the run passed; the gap indicator changes sign there with no root
    located, now a convergence error. Steps of 0.05 stay on the family and locate the opening: the gap indicator is 0
    there to the layer's tolerance (1e-9 of the step 0.05 in log a, times d gap / d log a of order 1: below 1e-8)."""
    from hertzpetsc.studies.precompression import amplitude_grid
    model = LatticeModel.hertz(2.0, masses=(1.0, 0.01), delta0=1.0)
    for ds in (0.1, 0.05):
        fam = AmplitudeFamily(model, math.pi / 4, ProfileGrid(200, COMM))
        try:
            gaps = []
            for a in amplitude_grid(1e-3, 3.0, ds):
                if ds == 0.1 and a > 1.5:
                    with pytest.raises(ConvergenceError, match="gap indicator changed sign"):
                        fam.step_to(a)
                    break
                fam.step_to(a)
                gaps += fam.events()
        finally:
            fam.destroy()
        if ds == 0.05:
            assert [p.event for p in gaps] == ["gap"] and abs(gaps[0].gap) < 1e-8 and 1.5 < gaps[0].A < 2.5
