"""The one advance-delay problem (hertzpetsc.advdelay) for mass patterns, with borders and a free continuation
parameter: exact Jacobians, the direct and Newton-Krylov solvers on every layout, the amplitude measures, the linear
waves at the zone edge and tiny amplitudes, and a chain the code has never seen (a precompressed trimer)."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from hertzpetsc.advdelay import AdvanceDelayProblem
from hertzpetsc.continuation import Continuation, Natural
from hertzpetsc.diagnostics import sup_norm
from hertzpetsc.errors import ParameterError
from hertzpetsc.families import AmplitudeFamily, FamilyProblem, wave_at
from hertzpetsc.grid import ProfileGrid
from hertzpetsc.model import LatticeModel

COMM = PETSc.COMM_WORLD
TRIMER = LatticeModel.hertz(1.5, masses=(1.0, 0.5, 1 / 3), delta0=1.0)


def dense_jacobian_check(prob, Z):
    """(max |J_aij - J_fd| / max |J|, max |J_shell v - J_aij v| / max |J v|) on COMM_SELF."""
    J = prob.create_jacobian(Z, "aij")
    Jd = J.convert("dense").getDenseArray().copy()
    F0 = Z.duplicate()
    prob.formFunction(None, Z, F0)
    f0 = F0.getArray().copy()
    n = Z.getSize()
    fd = np.zeros((n, n))
    eps = 1e-7                  # forward differences: O(eps |J''|) ~ 1e-7 of the entries' scale
    for k in range(n):
        Zk = Z.copy()
        Zk.getArray()[k] += eps
        F = Z.duplicate()
        prob.formFunction(None, Zk, F)
        fd[:, k] = (F.getArray() - f0) / eps
        Zk.destroy()
        F.destroy()
    S = prob.create_jacobian(Z, "shell")
    v, y = Z.duplicate(), Z.duplicate()
    v.setArray(np.random.default_rng(0).standard_normal(n))
    S.mult(v, y)
    shell = np.max(np.abs(y.getArray() - Jd @ v.getArray())) / np.max(np.abs(y.getArray()))
    for obj in (J, S, v, y, F0):
        obj.destroy()
    return np.max(np.abs(Jd - fd)) / np.max(np.abs(Jd)), shell


@pytest.mark.parametrize("parameter", ["q", "log_a", "delta0", "alpha", "m1", "m2"])
@pytest.mark.parametrize("measure", ["a1", "sup"])
def test_bordered_jacobian_of_a_trimer_against_finite_differences(parameter, measure):
    grid = ProfileGrid(20, PETSc.COMM_SELF)
    prob = FamilyProblem(TRIMER, grid, 0.7, amplitude=0.4, measure=measure, parameter=parameter)
    try:
        prof, lam = prob.linear_guess()
        bumpy = [w * (1 + 0.2 * np.cos(np.arange(len(w)))) for w in prof]
        Z = prob.pack(bumpy, lam * 1.1, prob.get_parameter(parameter))
        row = Z.duplicate()
        row.setArray(np.random.default_rng(1).standard_normal(Z.getSize()))
        prob.arclength = (row.getArray().copy(), 0.1)
        fd, shell = dense_jacobian_check(prob, Z)
        assert fd < 1e-6
        assert shell < 1e-13
    finally:
        prob.destroy()


def test_fixed_frequency_pattern_jacobian():
    """The fixed-frequency form (eq. ad with omega given) for a dimer, continued in omega: no border but the
    parameter's."""
    grid = ProfileGrid(16, PETSc.COMM_SELF)
    prob = AdvanceDelayProblem(LatticeModel.hertz(2.0, masses=(1.0, 0.6), delta0=0.5), grid, 1.1, omega=0.8,
                               parameter="omega")
    try:
        xi = grid.xi_half()
        Z = prob.pack([0.3 * np.sin(xi), 0.2 * np.sin(xi) + 0.05 * np.sin(3 * xi)], parameter=0.8)
        prob.arclength = (np.random.default_rng(2).standard_normal(Z.getSize()), 0.0)
        fd, shell = dense_jacobian_check(prob, Z)
        assert fd < 1e-6 and shell < 1e-13
    finally:
        prob.destroy()


@pytest.mark.parametrize("measure", ["a1", "sup"])
def test_direct_and_newton_krylov_give_the_same_trimer_waves(measure, clean_options):
    """The amplitude family of the trimer with LU and with Newton-Krylov (GMRES + exact D2 blocks) on every rank
    count: the same waves to the Newton tolerance (bound 1e-10 relative)."""
    grid = ProfileGrid(120, COMM)
    out = {}
    for solver in ("direct", "nk"):
        fam = AmplitudeFamily(TRIMER, 0.6, grid, measure=measure, solver=solver)
        try:
            out[solver] = list(fam.points([1e-3, 0.05, 0.3, 0.8]))
        finally:
            fam.destroy()
    for a, b in zip(out["direct"], out["nk"]):
        assert abs(a.omega / b.omega - 1) < 1e-10
        assert max(np.max(np.abs(x - y)) for x, y in zip(a.profiles, b.profiles)) < 1e-10
    if measure == "sup":
        last = out["nk"][-1]
        assert max(sup_norm(w) for w in last.profiles) == pytest.approx(1.0, abs=1e-12)
        assert last.A == pytest.approx(0.8, rel=1e-12)


def test_omega_at_a_given_amplitude_is_solved_for():
    """wave_at imposes A = max |u| as the border row: the wave it returns has that amplitude, and the 'a1'
    family's wave with the same A has the same omega (two normalisations of one solution: solver tolerance)."""
    grid = ProfileGrid(100, COMM)
    model = LatticeModel.hertz(1.5, delta0=1.0)
    fam = AmplitudeFamily(model, 0.9, grid)
    try:
        ref = list(fam.points([1e-3, 0.3, 1.2]))[-1]
    finally:
        fam.destroy()
    w = wave_at(model, 0.9, ref.A, grid)
    assert w.A == pytest.approx(ref.A, rel=1e-12)
    assert w.omega == pytest.approx(ref.omega, rel=1e-10)


def test_tiny_amplitudes_and_the_optical_wave_at_the_zone_edge():
    """a = 1e-4 delta0 is the linear wave (omega to the scheme's linear frequency to O(a^2)); the dimer's optical
    wave at per-bead q = pi/2 leaves the heavy bead at rest (normalised on the light one) and has the closed-form
    frequency omega^2 = 2K/eps up to D2's symbol."""
    grid = ProfileGrid(200, COMM)
    model = LatticeModel.hertz(1.5, delta0=1.0)
    fam = AmplitudeFamily(model, 0.9, grid)
    try:
        p = fam.solve_at(1e-4)
    finally:
        fam.destroy()
    symbol = 4 * math.sin(grid.h / 2) ** 2 / grid.h ** 2
    assert p.omega * math.sqrt(symbol) == pytest.approx(model.linear_frequencies(0.9)[0], rel=1e-8)
    eps = 0.5
    dimer = LatticeModel.hertz(1.5, masses=(1.0, eps), delta0=1.0)
    fam = AmplitudeFamily(dimer, math.pi / 2, grid, branch="optical")
    try:
        pts = list(fam.points([1e-4, 0.01, 0.1]))
        assert fam.problem.normalised == 1
    finally:
        fam.destroy()
    assert all(np.all(np.isfinite(w)) for p in pts for w in p.profiles)
    assert np.max(np.abs(pts[0].profiles[0])) < 1e-6 * np.max(np.abs(pts[0].profiles[1]))
    assert pts[0].omega * math.sqrt(symbol) == pytest.approx(dimer.linear_frequencies(math.pi / 2)[1], rel=1e-8)


def test_trimer_family_continued_in_q_at_fixed_amplitude():
    """A chain the code has never seen: the precompressed trimer (masses 1, 1/2, 1/3; whole-period profiles: the
    reflection n -> -n exchanges bead types). From the linear wave to a = 0.5 at q = 0.9, then continued in q at
    that amplitude (the layer's natural steps, parameter q): at q = 1.0 and 1.1 the waves are the amplitude
    family's there (one solution, two paths: solver tolerance). The window [0.9, 1.1] is free of the internal resonances
    k omega_ac(q) = omega_j(k q), k = 2, 3, 4 (the nearest is 0.09 away in frequency): near q = 0.75 and 1.35 the
    second harmonic resonates with an optical branch and the family at fixed a turns."""
    grid = ProfileGrid(120, COMM)
    fam = AmplitudeFamily(TRIMER, 0.9, grid)
    try:
        start = list(fam.points([1e-3, 0.1, 0.5]))[-1]
        normalised = fam.problem.normalised
    finally:
        fam.destroy()
    prob = FamilyProblem(TRIMER, grid, 0.9, amplitude=0.5, parameter="q", normalised=normalised)
    cont = Continuation(prob, Natural())
    try:
        Z = prob.pack(start.profiles, start.lam, 0.9)
        cont.start(Z)
        Z.destroy()
        omegas = []
        for q in (0.95, 1.0, 1.1):
            cont.step_to(q)
            omegas.append(prob.point(cont.history[-1][0], 1).omega)
    finally:
        cont.destroy()
        prob.destroy()
    for q, omega in ((1.0, omegas[1]), (1.1, omegas[2])):
        fam = AmplitudeFamily(TRIMER, q, grid)
        try:
            direct = list(fam.points([1e-3, 0.1, 0.5]))[-1]
        finally:
            fam.destroy()
        assert omega == pytest.approx(direct.omega, rel=1e-10)


def test_bad_wave_input():
    grid = ProfileGrid(20, PETSc.COMM_SELF)
    with pytest.raises(ParameterError, match="parameter"):
        FamilyProblem(TRIMER, grid, 0.6, amplitude=0.5, parameter="epsilon3")
    with pytest.raises(ParameterError, match="measure"):
        FamilyProblem(TRIMER, grid, 0.6, amplitude=0.5, measure="L2")
    with pytest.raises(ParameterError, match="amplitude"):
        FamilyProblem(TRIMER, grid, 0.6, amplitude=-1.0)
    with pytest.raises(ParameterError, match="delta0"):
        AmplitudeFamily(LatticeModel.hertz(1.5, masses=(1.0, 0.5)), 0.6, grid)


@pytest.mark.parametrize("masses,q", [((1.0, 0.7), math.pi), ((1.0, 0.5, 0.25), 2 * math.pi / 3),
                                      ((1.0, 0.5, 0.25, 0.5), math.pi / 2)])
def test_a_wavenumber_where_the_acoustic_wave_has_zero_frequency_is_refused(masses, q):
    """At q = 2 pi k / p the acoustic linear wave of a pattern of p beads moves every cell as one (zero frequency):
    no acoustic wave starts there, and the family refuses q before any Newton step (it stopped with a solver
    failure); the optical wave exists there."""
    model = LatticeModel.hertz(1.5, masses=masses, delta0=1.0)
    grid = ProfileGrid(40, COMM)
    with pytest.raises(ParameterError, match="q = .*zero frequency"):
        wave_at(model, q, 0.1, grid)
    assert wave_at(model, q, 0.1, grid, branch="optical").omega > 0


def test_the_optical_branch_of_a_monatomic_chain_and_its_q_branch_with_a_pattern_are_refused():
    """A monatomic chain has one branch (the optical request returned the acoustic wave); the q-branch at omega = 1
    (section 3.1) is the uncompressed monatomic chain's (a pattern raised an IndexError, a precompressed chain a
    continuation failure at q = pi)."""
    from hertzpetsc.qbranch import ContinuationParameters
    with pytest.raises(ParameterError, match="branch.*acoustic branch only"):
        wave_at(LatticeModel.hertz(1.5, delta0=1.0), math.pi / 4, 0.5, ProfileGrid(40, COMM), branch="optical")
    for model in (LatticeModel.hertz(1.5, masses=(1.0, 0.5)), LatticeModel.hertz(1.5, delta0=1.0)):
        with pytest.raises(ParameterError, match="model.*monatomic"):
            ContinuationParameters(model=model)


def test_trimer_wave_is_a_travelling_wave_of_the_chain():
    """The trimer's wave (whole-period profiles, gauge rows) put on 90 beads is periodic modulo the shift by one
    cell up to its O(h^2) discretisation error: E of the second-order scheme at h = pi/200 and pi/400 falls by the
    factor 4 (measured 2.8e-5 at h = pi/200)."""
    from hertzpetsc.model import ChainSpec
    from hertzpetsc.shooting import MEASURE_TOLERANCES, ShiftMap
    from hertzpetsc.waves import orbit_on_chain
    q, N = 2 * math.pi * 3 / 90, 90
    E = []
    for K in (200, 400):
        fam = AmplitudeFamily(TRIMER, q, ProfileGrid(K, PETSc.COMM_SELF))
        try:
            w = list(fam.points([1e-3, 0.1, 0.5]))[-1]
        finally:
            fam.destroy()
        orbit = orbit_on_chain(w.branch_point(TRIMER, math.pi / K), ChainSpec(TRIMER, N))
        shift_map = ShiftMap(orbit.spec, PETSc.COMM_SELF, MEASURE_TOLERANCES, "chain_")
        try:
            E.append(shift_map.residual(orbit))
        finally:
            shift_map.destroy()
    assert E[0] < 1e-4 and 3.0 < E[0] / E[1] < 5.0


def test_wave_study_of_a_trimer_in_memory():
    """The trimer's wave through the whole pipeline, as a study without a file: refined on its cell (E below the
    target), multipliers on N = 30 beads from the Bloch sectors, and on 4 N beads, where the sectors of the longer
    chain contain those of the shorter one (its rho is at least as large)."""
    from hertzpetsc.studies.wave import WaveParameters, WaveStudy
    params = WaveParameters(TRIMER, (2 * math.pi / 15,), 0.5, 100, 30, (120,), 1e-10)
    study = WaveStudy(params, COMM)
    (row,) = list(study.run())
    assert row["E_profile"] < 1e-3 and row["E_refined"] <= 1e-10 and row["m"] == 2
    assert row["spread"] < 1e-4
    assert row["rho_sizes"][0] >= row["rho"] - 1e-9
    assert str(study.arrays()["format"]) == "hertzpetsc-wave-1"
    with pytest.raises(ParameterError, match="sizes"):
        WaveParameters(TRIMER, (2 * math.pi / 15,), 0.5, 100, 30, (100,))
    with pytest.raises(ParameterError, match="delta0"):
        WaveParameters(LatticeModel.hertz(1.5, masses=(1.0, 0.5)), (2 * math.pi / 15,), N=30)


def test_the_wave_file_holds_the_wave_its_state_and_its_multipliers(tmp_path):
    """A wave file holds what its rows are about, read back with numpy (h = pi/100) or h5py (h = pi/200) alone: the
    profiles u_c on the whole period (max |u| is the amplitude A asked for, within the grid maximum's error
    h^2/8 max |u''|), the refined state on the chain (x_n(0) = u_{n mod p}(q n) at the beads where q n is a grid
    point, up to the refinement's correction of the profile's O(h^2) error: a quarter at h/2), the dominant
    nontrivial multipliers (|the first| is rho, the same numbers, by decreasing modulus); and the units and meanings
    of every entry (``__columns__``, HDF5 attributes ``units`` and ``description``)."""
    import json
    from conftest import shared_tmp
    from hertzpetsc.studies.wave import DOMINANT, DOMINANT_RESOLUTION, WAVE_KIND, WaveParameters, WaveStudy
    N, q, A = 30, 2 * math.pi / 15, 0.5
    corrections = []
    for K, suffix in ((100, ".npz"), (200, ".h5")):
        path = f"{shared_tmp(tmp_path)}/w{suffix}"
        (row,) = list(WaveStudy(WaveParameters(TRIMER, (q,), A, K, N, (), 1e-10), COMM, path).run())
        COMM.tompi4py().Barrier()
        if suffix == ".npz":
            with np.load(path) as z:
                data, about = {k: z[k] for k in z.files}, json.loads(str(z["__columns__"]))
        else:
            h5py = pytest.importorskip("h5py")
            with h5py.File(path, "r") as f:
                data, about = {k: f[k][()] for k in f}, json.loads(f["__columns__"][()].decode())
                attrs = {k: dict(f[k].attrs) for k in f}
            assert attrs["omega"] == dict(units="1", description=WAVE_KIND.by_name["omega"].description)
            assert attrs["seconds"]["units"] == "s" and attrs["u"]["description"].startswith("the wave's profiles")
        entries = set(data) - {"format", "__provenance__", "__columns__"}
        assert entries <= set(about), entries - set(about)
        assert all(about[k]["description"] and about[k]["unit"] in ("1", "s", "count", "") for k in entries)
        u, x, dominant = data["u"][0], data["state"][0], data["dominant"][0]
        assert u.shape == (3, 2 * K) and x.shape == (N, 2) and dominant.shape == (DOMINANT,)
        assert np.array_equal(data["xi"], np.arange(2 * K) * math.pi / K)
        d2 = np.abs(np.roll(u, -1, axis=1) - 2 * u + np.roll(u, 1, axis=1)).max()
        assert abs(np.abs(u).max() - A) <= d2 / 8
        on_grid = [n for n in range(N) if abs(q * n * K / math.pi - round(q * n * K / math.pi)) < 1e-9]
        assert len(on_grid) == 10
        corrections.append(max(abs(x[n, 0] - u[n % 3, round(q * n * K / math.pi) % (2 * K)]) for n in on_grid))
        assert abs(dominant[0]) == pytest.approx(float(data["rho"][0]), rel=DOMINANT_RESOLUTION)
        assert float(data["rho"][0]) == pytest.approx(row["rho"], rel=1e-14)
        assert np.all(np.diff(np.abs(dominant)) <= DOMINANT_RESOLUTION)
    assert 3.0 < corrections[0] / corrections[1] < 5.0, corrections


def test_a_wave_file_written_before_the_objects_resumes_with_nan_there(tmp_path):
    """The committed fixture (written before u, state and dominant) opens, resumes with nothing to compute, keeps
    its numbers, and is rewritten with NaN in the new fields."""
    import shutil
    from conftest import DATA, shared_tmp
    from hertzpetsc.records import load_npz
    from hertzpetsc.studies.wave import WaveParameters, WaveStudy
    old = load_npz(f"{DATA}/wave.npz", "x")
    path = f"{shared_tmp(tmp_path)}/w.npz"
    if COMM.getRank() == 0:
        shutil.copy(f"{DATA}/wave.npz", path)
    COMM.tompi4py().Barrier()
    params = WaveParameters(LatticeModel.hertz(1.5, tuple(old["masses"]), delta0=1.0), tuple(old["q"]), 0.5, 400, 60,
                            (30000,), 1e-10, 1e-4)
    study = WaveStudy(params, COMM, path, "resume")
    assert list(study.run()) == []
    new = load_npz(path, "x")
    for k in old:
        assert np.array_equal(old[k], new[k]), k
    assert np.isnan(new["u"]).all() and np.isnan(new["state"]).all() and np.isnan(new["dominant"]).all()
    assert new["u"].shape == (2, 3, 800) and new["dominant"].dtype == complex


def test_a_wave_list_goes_on_past_a_q_that_does_not_converge():
    """A q whose refinement does not reach its target (tol 1e-14 in one Gauss-Newton iteration, which leaves E
    near 1e-11) is left out and named below the table; the study goes on to the next q, and the finished records
    are kept."""
    from hertzpetsc.studies.wave import WaveParameters, WaveStudy
    model = LatticeModel.hertz(1.5, delta0=1.0)
    qs = (2 * math.pi / 3, 2 * math.pi / 5)
    study = WaveStudy(WaveParameters(model, qs, 0.3, 100, 30, (), 1e-10), COMM)
    assert [r["q"] for r in study.run()] == list(qs) and not study.failed
    PETSc.Options().setValue("shoot_gn_max_it", 1)
    try:
        study = WaveStudy(WaveParameters(model, qs, 0.3, 100, 30, (), 1e-14), COMM)
        assert list(study.run()) == [] and sorted(study.failed) == sorted(qs)
    finally:
        PETSc.Options().delValue("shoot_gn_max_it")
    table = study.table()
    assert all(f"Not computed (-resume retries it): q = {q:.6f}: Gauss-Newton refinement" in table for q in qs)


def test_the_wave_table_gives_the_refined_waves_omega():
    """At C(q) = 0 the refinement corrects the period (the wave's profile error): the record's omega is the refined
    wave's, not the profile's."""
    import hertzpetsc as hz
    from hertzpetsc.studies.wave import WaveParameters, WaveStudy
    model = LatticeModel.hertz(1.5, delta0=1.0)
    (row,) = list(WaveStudy(WaveParameters(model, (math.pi / 2,), 0.3, 200, 8), COMM).run())
    w = hz.wave(model, math.pi / 2, 0.3, 8, cells_per_pi=200, comm=COMM)
    refined = hz.refine(w, comm=COMM).orbit
    assert row["omega"] == pytest.approx(refined.omega, rel=1e-12) and refined.omega != w.omega


@pytest.mark.serial
def test_wave_driver_reads_its_documented_gauss_newton_option(tmp_path):
    """-shoot_gn_max_it (in wave.py's -help) is read before the first wave: 0 is refused naming it, 5 is taken
    (it was refused as an unknown option)."""
    from conftest import one_error_line, run_script
    common = ["-q", "2*pi/3", "-N", 30, "-A", 0.3, "-cells_per_pi", 100, "-output", tmp_path / "w.npz",
              "-table", tmp_path / "w.md", "-force"]
    bad = run_script("wave.py", *common, "-shoot_gn_max_it", 0, timeout=120)
    assert bad.returncode == 2 and "invalid -shoot_gn_max_it = 0" in one_error_line(bad)
    assert not (tmp_path / "w.npz").exists()
    good = run_script("wave.py", *common, "-shoot_gn_max_it", 5, timeout=120)
    assert good.returncode == 0, good.stderr


def test_the_dominant_multipliers_do_not_follow_round_off():
    """A stable wave's multipliers all lie on the unit circle to round-off: the kept 'dominant' ones were the first
    by modulus, a set that two runs differing by round-off (ranks, a resumed run) chose differently (a resumed 2-rank
    wave study's file differed from the uninterrupted one by 1.9 in 'dominant'). Ranked to DOMINANT_RESOLUTION and
    ordered by argument, the kept set is the same under perturbations of 1e-11."""
    from hertzpetsc.studies.wave import DOMINANT, DOMINANT_RESOLUTION, dominant_multipliers
    rng = np.random.default_rng(7)
    theta = np.sort(rng.uniform(0.05, np.pi - 0.05, 29))
    circle = np.concatenate([np.exp(1j * theta), np.exp(-1j * theta), [1.3, 1 / 1.3]])
    picked = dominant_multipliers(circle)
    assert picked[0] == 1.3 and len(picked) == DOMINANT
    for _ in range(20):
        noisy = circle * (1 + 1e-11 * rng.standard_normal(circle.size))
        noisy = noisy * np.exp(1e-11j * rng.standard_normal(circle.size))
        np.testing.assert_allclose(dominant_multipliers(rng.permutation(noisy)), picked, rtol=0, atol=1e-10)
    assert np.all(np.diff(np.abs(picked)) <= DOMINANT_RESOLUTION)
