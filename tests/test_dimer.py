"""Dimer chains (masses 1, epsilon) with precompression (issue 16): the (u, v) advance-delay system, its linear
limit against the 2x2 Bloch matrix, epsilon = 1 against the monatomic wave, the pseudo-arclength continuation in
epsilon, the chain with a mass pattern and the driver."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import one_error_line, run_script
from hertzpetsc.chain import Chain, IntegrationTolerances
from hertzpetsc.errors import ParameterError
from hertzpetsc.floquet import DenseFloquet
from hertzpetsc.grid import ProfileGrid
from hertzpetsc.model import ChainSpec, LatticeModel
from hertzpetsc.families import AmplitudeFamily, MassFamily
from hertzpetsc.records import read_kind
from hertzpetsc.studies.precompression import DIMER_KIND, wave_orbit

COMM = PETSc.COMM_WORLD
Q = 0.3 * math.pi


def dimer(eps, delta0=1.0):
    return LatticeModel.hertz(1.5, masses=(1.0, eps), delta0=delta0)


@pytest.mark.parametrize("eps", [0.5, 2.0, 0.2])
@pytest.mark.parametrize("branch", ["acoustic", "optical"])
def test_small_amplitude_frequencies(eps, branch):
    """At a = 1e-5 the nonlinear dimer wave has the Bloch frequency of the scheme: the closed form with D2's exact
    symbol on sin xi (4 sin^2(h/2)/h^2 instead of 1; the shift q = 60 h is an integer shift, exact). Measured
    relative differences 1e-12 .. 1e-10: the O(a^2) nonlinear shift."""
    grid = ProfileGrid(200, COMM)
    cont = AmplitudeFamily(dimer(eps), Q, grid, branch=branch)
    try:
        p = cont.solve_at(1e-5)
    finally:
        cont.destroy()
    symbol = 4 * math.sin(grid.h / 2) ** 2 / grid.h ** 2
    exact = dimer(eps).linear_frequencies(Q)[0 if branch == "acoustic" else 1]
    assert abs(p.omega * math.sqrt(symbol) / exact - 1) < 1e-9
    # the profiles' ratio is the Bloch eigenvector's: v/u = (2K - m_0 omega^2) / (2K cos q), K = V''(0) = 1.5; at
    # xi = pi/2, where the O(a) second harmonic vanishes (it is large near the resonance eps ~ 0.517 at this q)
    ratio = p.profiles[1][100] / p.profiles[0][100]
    assert max(abs(p.profiles[c][100]) for c in (0, 1)) > 0.5        # normalised on the larger profile
    lam_h = (p.omega * math.sqrt(symbol)) ** 2
    assert ratio == pytest.approx((3.0 - lam_h) / (3.0 * math.cos(Q)), rel=1e-6)


def test_epsilon_one_is_the_monatomic_wave():
    """At epsilon = 1 the dimer's acoustic wave is the monatomic wave (u = v), to solver tolerance."""
    grid = ProfileGrid(100, COMM)
    out = []
    for model in (LatticeModel.hertz(1.5, delta0=1.0), dimer(1.0)):
        cont = AmplitudeFamily(model, Q, grid)
        try:
            out.append(list(cont.points([1e-3, 0.1, 0.5, 2.0]))[-1])
        finally:
            cont.destroy()
    mono, di = out
    assert di.omega == pytest.approx(mono.omega, rel=1e-12)
    assert np.allclose(di.profiles[0], mono.profiles[0], atol=1e-12)
    assert np.allclose(di.profiles[1], mono.profiles[0], atol=1e-12)


def test_mass_continuation_gives_dimer_waves():
    """Each pseudo-arclength point (u, v, lam, epsilon) is the dimer wave at its epsilon: a natural solve at that
    epsilon from the linear wave gives the same omega (solver tolerance)."""
    grid = ProfileGrid(100, COMM)
    mc = MassFamily(dimer(1.0), Q, grid, 0.3, ds=0.05)
    try:
        mc.start()
        pts = [mc.step() for _ in range(4)]
    finally:
        mc.destroy()
    eps = [p.epsilon for p in pts]
    assert np.all(np.diff(eps) < 0) and eps[-1] < 0.9
    for p in (pts[0], pts[-1]):
        cont = AmplitudeFamily(dimer(p.epsilon), Q, grid)
        try:
            ref = list(cont.points([1e-3, 0.03, 0.3]))[-1]
        finally:
            cont.destroy()
        assert p.wave.omega == pytest.approx(ref.omega, rel=1e-10)


def test_dimer_chain_and_floquet_shift_by_one_cell():
    """The dimer wave put on the chain of N = 10 beads (masses 1, eps alternating) is periodic modulo the shift by one
    cell: its dense monodromy F = S R(2q/omega) has the trivial multipliers at 1 (split by the profile's O(h^2)
    error: sqrt of it) and, at this small amplitude, every multiplier on the unit circle."""
    N, q, eps = 10, 2 * math.pi / 10, 0.5
    model = dimer(eps)
    cont = AmplitudeFamily(model, q, ProfileGrid(400, COMM))
    try:
        p = list(cont.points([1e-3, 0.05]))[-1]
    finally:
        cont.destroy()
    orbit = wave_orbit(model, q, p.a, list(p.profiles), p.lam, N, cont.grid.h)
    dense = DenseFloquet(ChainSpec(model, N), COMM, IntegrationTolerances(rtol=1e-11, atol=1e-13))
    try:
        spec = dense.spectrum(orbit)
    finally:
        dense.destroy()
    assert spec.trivial_spread < 1e-3
    assert abs(spec.rho - 1) < 1e-4


def test_bad_dimer_input():
    with pytest.raises(ParameterError, match="masses"):
        MassFamily(LatticeModel.hertz(1.5, delta0=1.0), Q, ProfileGrid(20, COMM), 0.5)
    with pytest.raises(ParameterError, match="amplitude"):
        MassFamily(dimer(1.0), Q, ProfileGrid(20, COMM), -0.5)
    with pytest.raises(ParameterError, match="multiple"):
        Chain(ChainSpec(dimer(0.5), 7), PETSc.COMM_SELF)


@pytest.mark.serial
def test_dimer_driver(tmp_path):
    """The driver writes the family; a run stopped after 2 steps and resumed with -max_steps 4 continues from its
    saved state and equals the uninterrupted run bit for bit (one rank: the same arithmetic)."""
    common = ["-cells_per_pi", "60", "-a", "0.3", "-figures", str(tmp_path)]
    out = lambda k: ["-output", tmp_path / f"d{k}.npz", "-table", tmp_path / f"d{k}.md"]   # noqa: E731
    r = run_script("dimer_branch.py", *common, "-max_steps", "4", *out(1), timeout=120)
    assert r.returncode == 0, r.stderr
    d = np.load(tmp_path / "d1.npz")
    regular = d["event"] == 0
    assert str(d["format"]) == "hertzpetsc-dimer-2" and regular.sum() == 6 and d["epsilon"][0] == 1.0
    assert DIMER_KIND.check(read_kind(str(tmp_path / "d1.npz"), DIMER_KIND, "x")) == ([], [])   # as declared
    assert "-max_steps = 4 reached at epsilon" in (tmp_path / "d1.md").read_text()     # the table says it stopped early
    assert run_script("dimer_branch.py", *common, "-max_steps", "2", *out(2), timeout=120).returncode == 0
    assert (np.load(tmp_path / "d2.npz")["event"] == 0).sum() == 4
    r = run_script("dimer_branch.py", *common, "-max_steps", "4", *out(2), "-resume", timeout=120)
    assert r.returncode == 0, r.stderr
    d2 = np.load(tmp_path / "d2.npz")
    for k in ("epsilon", "omega", "norm_v", "arclength", "event"):
        assert np.array_equal(d[k], d2[k]), k
    assert "-epsilon_end" in one_error_line(run_script("dimer_branch.py", "-epsilon_end", "1.5", *common, *out(3)))


@pytest.mark.serial
def test_a_dimer_file_resumes_on_another_number_of_ranks(tmp_path):
    """The saved state does not depend on the ranks: a run of 2 steps on 2 ranks resumed on 1 (and one of 1 resumed on
    2) equals the uninterrupted run to round-off (MUMPS on 2 ranks). A file of the earlier code holds its state in
    its writer's rank layout, without ``state_layout``: it resumes too, and a state matching none of the layouts is
    a file error naming the file."""
    common = ["-cells_per_pi", "60", "-a", "0.3"]
    out = lambda k: ["-output", tmp_path / f"d{k}.npz", "-table", tmp_path / f"d{k}.md"]   # noqa: E731
    assert run_script("dimer_branch.py", *common, "-max_steps", "4", *out(0), timeout=120).returncode == 0
    full = np.load(tmp_path / "d0.npz")
    for k, (first, then) in enumerate([(2, 1), (1, 2)], 1):
        r = run_script("dimer_branch.py", *common, "-max_steps", "2", *out(k), ranks=first, timeout=120)
        assert r.returncode == 0, r.stderr
        r = run_script("dimer_branch.py", *common, "-max_steps", "4", *out(k), "-resume", ranks=then, timeout=120)
        assert r.returncode == 0, r.stderr
        d = np.load(tmp_path / f"d{k}.npz")
        assert str(d["state_layout"]) == "natural" and np.array_equal(d["event"], full["event"])
        for f in ("epsilon", "omega", "norm_v", "arclength"):
            assert np.allclose(d[f], full[f], rtol=1e-10, atol=0), f
    # the earlier layout on 2 ranks: each rank's rows of u_0, then of u_1 (K - 1 = 59 unknowns: 30 and 29 rows)
    assert run_script("dimer_branch.py", *common, "-max_steps", "2", *out(3), timeout=120).returncode == 0
    data = dict(np.load(tmp_path / "d3.npz"))
    for k in ("q", "s", "ds", "normalised"):                # that code kept one state, of the last q
        data["state_" + k] = data["state_" + k][-1]
    Z = data.pop("state_Z")[-1]
    assert str(data.pop("state_layout")) == "natural"
    u, v, rest = Z[:, :59], Z[:, 59:118], Z[:, 118:]
    data["state_Z"] = np.hstack([u[:, :30], v[:, :30], u[:, 30:], v[:, 30:], rest])
    np.savez(tmp_path / "d3.npz", **data)
    r = run_script("dimer_branch.py", *common, "-max_steps", "4", *out(3), "-resume", timeout=120)
    assert r.returncode == 0, r.stderr
    d = np.load(tmp_path / "d3.npz")
    for f in ("epsilon", "omega", "norm_v", "arclength", "event"):
        assert np.array_equal(d[f], full[f]), f
    data["state_Z"] = Z[:, ::-1]
    np.savez(tmp_path / "d4.npz", **data)
    r = run_script("dimer_branch.py", *common, "-max_steps", "4", *out(4), "-resume", timeout=120)
    assert r.returncode == 4 and "d4.npz" in one_error_line(r) and "state_Z" in r.stderr


def test_a_mass_patterns_amplitude_family_does_not_jump_branches():
    """The six-amplitude dimer maps' steps (a = 0.1, 0.3, 1, 3; epsilon = 0.4, q = 7pi/25) landed on another branch
    when every converged step as long as the grid's was taken (omega 0.79 at a = 3); with the pattern's guards
    (PATTERN_MAX_STEP, PATTERN_MAX_CORRECTOR) the family reaches the wave a fine grid (40 steps of ln(30)/40)
    reaches: the same discrete problem, so the same omega to the Newton tolerance (1e-9)."""
    model = dimer(0.4)
    q = 2 * math.pi * 14 / 100
    omega = {}
    for name, max_step, grid in (("guarded", None, (0.1, 0.3, 1, 3)), ("unguarded", math.inf, (0.1, 0.3, 1, 3)),
                                 ("fine", math.inf, np.exp(np.linspace(math.log(0.1), math.log(3), 41)))):
        fam = AmplitudeFamily(model, q, ProfileGrid(50, COMM), max_step=max_step,
                              max_corrector=None if max_step is None else math.inf)
        try:
            for a in grid:
                point = fam.step_to(a)
            omega[name] = point.omega
        finally:
            fam.destroy()
    assert abs(omega["guarded"] - omega["fine"]) < 1e-9 * omega["fine"]
    assert abs(omega["unguarded"] - omega["fine"]) > 0.1 * omega["fine"]


@pytest.mark.parametrize("branch", ["acoustic", "optical"])
def test_amplitude_families_of_a_mass_pattern(branch):
    """AmplitudeFamilies takes a mass pattern and either linear branch: its first wave (a = 1e-5) has the branch's
    Bloch frequency of the scheme (as test_small_amplitude_frequencies: O(a^2) = 1e-10 nonlinear shift, bound 1e-9),
    omega_lin is the closed form of that branch, the file's identity names the pattern and the branch (a monatomic
    file's does not), the table has no C(q) closed form for it, and the family tends to its uncompressed limit:
    Omega - Omega0 ~ c1 delta0 / A with c1 the same at the two largest A (measured to 5e-5 relative: the O(delta0/A)
    correction at A ~ 270 and 1200; an Omega0 normalised by the heavy bead's profile alone, where the light bead's
    is larger, leaves Omega - Omega0 constant, c1 growing with A)."""
    from hertzpetsc.studies.precompression import AmplitudeFamilies, AmplitudeParameters
    model = dimer(0.4)
    study = AmplitudeFamilies(AmplitudeParameters(model, (Q,), 100, 1e-5, 1000.0, 1.5, branch), COMM)
    rows = list(study.run())
    exact = model.linear_frequencies(Q)[0 if branch == "acoustic" else 1]
    first = rows[0]
    symbol = 4 * math.sin(math.pi / 200) ** 2 / (math.pi / 100) ** 2
    assert first["omega_lin"] == exact
    assert abs(first["omega"] * math.sqrt(symbol) / exact - 1) < 1e-9
    assert [int(r["kind"]) for r in rows].count(2) == 1
    summary = study.summary(Q)
    assert abs(summary["c1"] / summary["c1_previous"] - 1) < 1e-3
    assert study.constants()["masses"] == [1.0, 0.4] and study.constants()["branch"] == branch
    assert "masses 1, 0.4 (repeated), " + branch in study.table() and "| n/a |" in study.table()
    mono = AmplitudeFamilies(AmplitudeParameters(LatticeModel.hertz(1.5, delta0=1.0), (Q,), 100, 1e-3, 1.0, 1.0))
    assert "masses" not in mono.constants() and "branch" not in mono.constants()
    with pytest.raises(ParameterError, match="branch"):
        AmplitudeParameters(LatticeModel.hertz(1.5, delta0=1.0), (Q,), 100, branch="optical")
    with pytest.raises(ParameterError, match="branch"):
        AmplitudeParameters(model, (Q,), 100, branch="upper")


@pytest.mark.serial
def test_every_q_resumes_from_its_own_end(tmp_path):
    """A file of three q's run to -max_steps 3 and resumed with -max_steps 6 continues every q from its saved end state:
    the records equal the uninterrupted -max_steps 6 run bit for bit (one rank: the same arithmetic). The earlier
    code kept the last q's state alone and restarted the others from epsilon = 1, appending a second path. A file of
    that code (one state, of the last q) resumes that q, and is refused (file error naming the q) for another."""
    common = ["-cells_per_pi", "40", "-a", "0.3", "-q", "pi/4,3*pi/10,pi/5", "-ds", "0.05"]
    out = lambda k: ["-output", tmp_path / f"d{k}.npz", "-table", tmp_path / f"d{k}.md"]   # noqa: E731
    assert run_script("dimer_branch.py", *common, "-max_steps", "6", *out(0), timeout=300).returncode == 0
    full = np.load(tmp_path / "d0.npz")
    assert run_script("dimer_branch.py", *common, "-max_steps", "3", *out(1), timeout=300).returncode == 0
    short = dict(np.load(tmp_path / "d1.npz"))
    r = run_script("dimer_branch.py", *common, "-max_steps", "6", *out(1), "-resume", timeout=300)
    assert r.returncode == 0, r.stderr
    d = np.load(tmp_path / "d1.npz")
    assert np.array_equal(np.unique(d["q"]), np.unique(full["q"]))
    for q in np.unique(full["q"]):                 # the resumed file holds them in the order of computation
        mine, ref = d["q"] == q, full["q"] == q
        for f in ("epsilon", "omega", "norm_v", "v1", "arclength", "tangent_epsilon", "event"):
            assert np.array_equal(d[f][mine], full[f][ref], equal_nan=True), (q, f)
    # a file of the earlier code: one state (2, n), that of the last q computed (pi/5)
    assert short["state_Z"].shape[0] == 3 and short["state_q"][-1] == math.pi / 5
    for k in ("q", "Z", "s", "ds", "normalised"):
        short["state_" + k] = short["state_" + k][-1]
    np.savez(tmp_path / "d2.npz", **short)
    r = run_script("dimer_branch.py", *common, "-max_steps", "6", *out(2), "-resume", timeout=300)
    assert r.returncode == 4 and "q = pi/4" in one_error_line(r) and "d2.npz" in r.stderr
    assert np.array_equal(np.load(tmp_path / "d2.npz")["epsilon"], short["epsilon"])     # nothing appended
    r = run_script("dimer_branch.py", *common[:4], "-q", "pi/5", "-ds", "0.05", "-max_steps", "6", *out(2), "-resume",
                   timeout=300)
    assert r.returncode == 0, r.stderr
    d = np.load(tmp_path / "d2.npz")
    for q in np.unique(full["q"]):
        mine, ref = d["q"] == q, full["q"] == q
        want = full["epsilon"][ref] if q == math.pi / 5 else short["epsilon"][short["q"] == q]
        assert np.array_equal(d["epsilon"][mine], want), q


# issue 40's dimer: alpha 1.8, delta0 0.3, masses 1, 0.6, q = pi/4 per cell (pi/8 per bead), A = 0.8
FOLD_DIMER, FOLD_Q, FOLD_A = LatticeModel.hertz(1.8, masses=(1.0, 0.6), delta0=0.3), math.pi / 8, 0.8


def test_a_family_that_folds_says_its_largest_amplitude_and_the_other_branch():
    """The acoustic family of the dimer turns back at a fold below A = 0.8: FamilyFold carries the farthest wave
    (the largest A of the family) and names the optical branch. That A is the family's largest at this grid: 1 %
    below it the acoustic wave exists, 1 % above it the family folds at the same A (to the fold location's
    tolerance, 1e-3 relative). h = pi/200: q = 25 h, an integer shift (at h = pi/100, q = 12.5 h, the natural steps
    land on another branch at A = 0.0028, a jump of omega by 2.4 % that nothing flags)."""
    from hertzpetsc.api import wave_at
    from hertzpetsc.families import FamilyFold
    with pytest.raises(FamilyFold) as err:
        wave_at(FOLD_DIMER, FOLD_Q, FOLD_A, cells_per_pi=200, comm=COMM)
    fold = err.value.fold
    assert err.value.branch == "acoustic" and err.value.other == "optical" and 0 < fold.A < FOLD_A
    message = str(err.value)
    assert len(message.splitlines()) == 1 and f"folds at A = max |u| = {fold.A:.6g}" in message
    assert 'branch="optical"' in message and "-branch optical" in message and "-resume" not in message
    assert err.value.as_option({"branch", "A"}).args[0].endswith("run again with -branch optical")
    below = wave_at(FOLD_DIMER, FOLD_Q, 0.99 * fold.A, cells_per_pi=200, comm=COMM)
    assert below.A == pytest.approx(0.99 * fold.A, rel=1e-9)
    with pytest.raises(FamilyFold) as again:
        wave_at(FOLD_DIMER, FOLD_Q, 1.01 * fold.A, cells_per_pi=200, comm=COMM)
    assert again.value.fold.A == pytest.approx(fold.A, rel=1e-3)


def test_the_optical_family_has_the_wave_the_acoustic_one_folds_before():
    """The optical wave of the same dimer at A = 0.8 (hz.wave_at with branch="optical"): omega on h = pi/100 and
    pi/200, Richardson-extrapolated (the scheme is O(h^2)), is the issue's 2.0675 to its four decimals; hz.wave puts
    it on a chain of 16 beads (one wavelength) with the same frequency and amplitude."""
    import hertzpetsc as hz
    omega = [hz.wave_at(FOLD_DIMER, FOLD_Q, FOLD_A, cells_per_pi=K, branch="optical", comm=COMM).omega
             for K in (100, 200)]
    extrapolated = omega[1] + (omega[1] - omega[0]) / 3
    assert abs(extrapolated - 2.0675) <= 5e-5
    orbit = hz.wave(FOLD_DIMER, FOLD_Q, FOLD_A, 16, cells_per_pi=200, comm=COMM, branch="optical")
    assert orbit.omega == pytest.approx(omega[1], rel=1e-12) and orbit.amplitude == pytest.approx(FOLD_A, rel=1e-9)


@pytest.mark.serial
def test_wave_driver_names_the_fold_and_the_branch_that_has_the_wave(tmp_path):
    """wave.py on the dimer from the README's options: the acoustic family's fold is one error line (status 3)
    with the largest A and the option that gives the wave; with -branch optical the wave is refined and tabled."""
    args = ("-alpha", 1.8, "-delta0", 0.3, "-masses", "1,0.6", "-q", "pi/8", "-A", 0.8, "-N", 16, "-cells_per_pi",
            200, "-output", tmp_path / "w.npz", "-table", tmp_path / "w.md")
    line = one_error_line(run_script("wave.py", *args))
    assert "acoustic family" in line and "folds at A = max |u| = " in line and line.endswith("-branch optical")
    assert "Not computed:" in (tmp_path / "w.md").read_text()
    r = run_script("wave.py", *args, "-branch", "optical", "-force")
    assert r.returncode == 0, r.stderr
    row = [x.strip() for x in (tmp_path / "w.md").read_text().splitlines()[-1].split("|")]
    assert float(row[1]) == pytest.approx(FOLD_Q, abs=1e-6) and abs(float(row[3]) - 2.0675) < 1e-4
