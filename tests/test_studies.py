"""The studies in-process on tiny parameters (serial and under mpiexec -n 2): records written as they go, exact
resume, identities, tables, and the restrictions of the stability verdicts."""
import json
import math
import os

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import chain, refine, small_branch
from hertzpetsc.bloch import SymmetricFloquet
from hertzpetsc.branch import Branch
from hertzpetsc.qbranch import ContinuationError, ContinuationParameters
from hertzpetsc.errors import ParameterError, RecordFileError
from hertzpetsc.model import LatticeModel
from hertzpetsc.simulation import read_snapshots
from hertzpetsc.studies.branch import BranchStudy, ConvergenceStudy
from hertzpetsc.studies.compactons import CompactonStudy
from hertzpetsc.studies.floquet import BLOCH_DETAIL, BlochScan, FloquetScan, critical_wavenumbers
from hertzpetsc.studies.longrun import LongRun
from hertzpetsc.studies.refinement import RefinedStates, RefinementScan
from hertzpetsc.studies.solitary import SolitaryStudy
from hertzpetsc.waves import orbit_on_chain

COMM = PETSc.COMM_WORLD


def shared(tmp_path):
    """One directory for every rank (rank 0's pytest tmp_path)."""
    return COMM.tompi4py().bcast(str(tmp_path), root=0)


def run_branch(path, mode="new", **kw):
    params = ContinuationParameters(**{**dict(M=10, cells_per_pi=200), **kw})
    study = BranchStudy(params, path, COMM, mode)
    new = list(study.run())
    return study, new


def test_branch_study_writes_as_it_goes_and_resumes_identically(tmp_path):
    d = shared(tmp_path)
    run_branch(f"{d}/b.npz", q_stop=0.6 * math.pi)
    study, new = run_branch(f"{d}/b.npz", "resume")
    assert study.resumed == 5 and len(new) == 5 and len(Branch.load(f"{d}/b.npz")) == 10
    _, fresh = run_branch(f"{d}/c.npz")
    resumed = Branch.load(f"{d}/b.npz")
    assert np.max(np.abs(resumed.u - np.array([p.u_half for p in fresh]))) <= 1e-10 * np.max(np.abs(resumed.u))
    with pytest.raises(RecordFileError, match="exists"):
        run_branch(f"{d}/c.npz")
    with pytest.raises(RecordFileError, match="alpha = 1.5 there, 2.0 requested"):
        run_branch(f"{d}/c.npz", "resume", alpha=2.0)


def test_quasi_newton_gives_the_same_branch(tmp_path, clean_options):
    """-tw_snes_type qn reaches the solver (the paper's quasi-Newton, L-BFGS defaults) and the same branch."""
    d = shared(tmp_path)
    _, newton = run_branch(f"{d}/n.npz", q_stop=math.pi / 2)
    clean_options.setValue("tw_snes_type", "qn")
    study = BranchStudy(ContinuationParameters(M=10, cells_per_pi=200, q_stop=math.pi / 2), f"{d}/q.npz", COMM)
    snes = study.continuation.solver.snes
    assert snes.getType() == "qn"
    assert "tw_snes_linesearch_type" not in PETSc.Options().getAll()   # the L-BFGS defaults were for the call only
    qn = list(study.run())
    for a, b in zip(newton, qn):
        assert np.max(np.abs(a.u_half - b.u_half)) <= 1e-8 * np.max(np.abs(a.u_half))


def test_divergence_is_reported_not_accepted(tmp_path, clean_options):
    """SNES stopping on a small step far from a solution must not pass as converged."""
    for k, v in dict(tw_snes_type="qn", tw_snes_qn_type="broyden", tw_snes_linesearch_type="basic",
                     tw_snes_divergence_tolerance="-1", tw_snes_max_it="200").items():
        clean_options.setValue(k, v)
    with pytest.raises(ContinuationError, match="continuation stopped"):
        run_branch(f"{shared(tmp_path)}/b.npz", M=5, cells_per_pi=100, q_stop=0.6 * math.pi)


def test_convergence_study_reports_second_order():
    study = ConvergenceStudy(LatticeModel.hertz(1.5), 10, [100, 200, 400], COMM)
    assert list(study.run()) == [100, 200, 400]
    rows = [line for line in study.table().splitlines() if line.startswith("| 3pi/10 | ")]
    assert len(rows) == 4 and all(abs(float(r.split("|")[-3]) - 2) < 0.3 for r in rows)   # observed order
    with pytest.raises(ParameterError, match="three different grids"):
        ConvergenceStudy(LatticeModel.hertz(1.5), 10, [100, 200, 200], COMM)
    # a grid coarser than the smallest target q = pi/M is refused as cells (it was q_stop, an internal parameter)
    with pytest.raises(ParameterError, match=r"cells = \[5, 100, 200\]: every grid K must be >= M = 10"):
        ConvergenceStudy(LatticeModel.hertz(1.5), 10, [100, 200, 5], COMM)


@pytest.fixture(scope="module")
def refined(tmp_path_factory):
    """q = 0.4 pi and 0.6 pi refined on 20 beads (branch h = pi/200), in a refinement file."""
    d = shared(tmp_path_factory.mktemp("refined"))
    branch = small_branch(q_stop=0.3 * math.pi)
    scan = RefinementScan(branch, "coarse", 20, COMM, f"{d}/r.npz", qs=[0.4 * math.pi])
    first = list(scan.run())
    again = RefinementScan(branch, "coarse", 20, COMM, f"{d}/r.npz", "resume", qs=[0.4 * math.pi, 0.6 * math.pi])
    rows = list(again.run())
    return d, branch, first, rows, again


def test_refinement_scan_reaches_the_target_and_resumes(refined):
    d, branch, first, rows, scan = refined
    assert len(first) == 1 and [r["q"] for r in rows] == [pytest.approx(0.6 * math.pi)]     # 0.4 pi not redone
    states = RefinedStates.load(f"{d}/r.npz")
    assert sorted(np.round(states.q / math.pi, 6)) == [0.4, 0.6]
    assert np.all(states.column("E_after") <= 1e-10) and np.all(states.column("E_before") > 1e-7)
    assert "| 1.2566 | 4 |" in scan.table()
    orbit = states.orbit(branch.point(0.4 * math.pi))
    assert orbit.source == "refined" and orbit.x.shape == (20, 2)
    # each q is refined on one rank (the q dealt to the ranks): bit-for-bit the serial refinement on any rank count
    serial = refine(orbit_on_chain(branch.point(0.6 * math.pi), chain(20)), PETSc.COMM_SELF, tol=1e-10)
    assert np.array_equal(states.state(0.6 * math.pi), serial.x)
    with pytest.raises(RecordFileError, match="no refined state at q"):
        states.orbit(branch.point(0.3 * math.pi))


def test_floquet_verdicts_only_from_the_waves_they_claim(refined, tmp_path):
    d, branch, *_ = refined
    out = shared(tmp_path)
    states = RefinedStates.load(f"{d}/r.npz")
    with pytest.raises(RecordFileError, match="no refined state at q = 0.942"):        # a listed q not refined
        FloquetScan(branch, 20, COMM, f"{out}/f1.npz", refined=states, qs=[0.3 * math.pi])
    scan = FloquetScan(branch, 20, COMM, f"{out}/f2.npz", refined=states)             # restricted, and says so
    rows = list(scan.run())
    scan.destroy()
    assert len(rows) == 2 and all(r["refined"] == 1 for r in rows)
    table = scan.table()
    assert "restricted to the 2 refined q" in table and "within the scanned q in [1.2566, 1.8850]" in table
    assert all(r["rho"] - 1 < 1e-4 for r in rows)
    unrefined = FloquetScan(branch, 20, COMM, f"{out}/f3.npz", refined=None, qs=[0.4 * math.pi])
    row = next(unrefined.run())
    unrefined.destroy()
    assert row["refined"] == 0 and "unrefined branch waves" in unrefined.table()
    # a wave whose trivial multipliers spread by more than tol_rho is not judged at that threshold
    spread = float(row["trivial_spread"])
    assert spread > 1e-12
    for tol_rho, judged in ((0.5 * spread, False), (2.0 * spread, True)):
        unrefined.tol_rho = tol_rho
        table = unrefined.table()
        assert ("not judged: q = 1.2566" in table) != judged and ("within the scanned q" in table) == judged
    # symmetric route, each q on one rank: the multipliers are bit-for-bit the serial ones on any rank count
    fast = SymmetricFloquet(branch.model, PETSc.COMM_SELF)
    try:
        for r in rows:
            assert np.array_equal(r["multipliers"], fast.spectrum(scan.orbit(r["q"])).multipliers)
    finally:
        fast.destroy()


def test_floquet_scan_resumes_and_its_file_is_the_documented_one(refined, tmp_path):
    d, branch, *_ = refined
    out = shared(tmp_path)
    states = RefinedStates.load(f"{d}/r.npz")
    first = FloquetScan(branch, 20, COMM, f"{out}/f.npz", refined=states, qs=[0.4 * math.pi])
    a = list(first.run())
    first.destroy()
    second = FloquetScan(branch, 20, COMM, f"{out}/f.npz", "resume", refined=states, qs=[0.4 * math.pi, 0.6 * math.pi])
    b = list(second.run())
    second.destroy()
    assert len(a) == 1 and len(b) == 1
    with np.load(f"{out}/f.npz") as z:
        assert str(z["format"]) == "hertzpetsc-floquet-1" and z["multipliers"].shape == (2, 40)


def test_section_3_scans_run_in_memory_with_the_records_and_identity_of_their_files(refined, tmp_path):
    """The scans that take their arguments directly are studies too: without an output path their records stay in
    memory, equal to those of the file; the file's identity (constants but the labels, solver options) is what a
    resume compares."""
    d, branch, *_ = refined
    states = RefinedStates.load(f"{d}/r.npz")
    memory = FloquetScan(branch, 20, refined=states, qs=[0.4 * math.pi])
    on_file = FloquetScan(branch, 20, COMM, f"{shared(tmp_path)}/f.npz", refined=states, qs=[0.4 * math.pi])
    rows = [list(s.run()) for s in (memory, on_file)]
    assert memory.store.path is None and len(memory.records) == 1
    assert np.array_equal(rows[0][0]["multipliers"], rows[1][0]["multipliers"])
    with np.load(f"{shared(tmp_path)}/f.npz") as z:
        for key, value in memory.arrays().items():
            if key != "seconds":
                assert np.array_equal(z[key], value, equal_nan=value.dtype.kind in "fc"), key
        assert "note" in z.files and "note" not in memory.identity() and "solver_options" in memory.identity()
    memory.destroy()
    on_file.destroy()
    refinement = RefinementScan(branch, "coarse", 20, qs=[0.4 * math.pi])
    assert np.array_equal(next(refinement.run())["x"], states.state(0.4 * math.pi))


def test_critical_wavenumbers():
    q = np.array([1.0, 0.9, 0.8, 0.7])
    assert critical_wavenumbers(q, [1.0, 1.0, 1.1, 1.2], 1e-4) == (0.8, 0.9, 0.7)
    qc, above, qm = critical_wavenumbers(q, [1.0] * 4, 1e-4)
    assert math.isnan(qc) and above is None
    assert critical_wavenumbers(q, [1.1, 1.2, 1.0, 1.0], 1e-4) == (1.0, None, 0.9)   # no stable q above


def test_bloch_scan_records_and_table(refined, tmp_path):
    d, branch, *_ = refined
    scan = BlochScan(branch, RefinedStates.load(f"{d}/r.npz"), [40], [0.4 * math.pi], COMM, f"{shared(tmp_path)}/b.npz",
                     nev=4)
    rows = list(scan.run())
    scan.destroy()
    (row, extra), = rows
    assert row["N"] == 40 and extra["runs"] == 5 and row["residual"] < 1e-8 and len(row["dominant"]) == 4
    assert "| 40 | 2pi/5 | 8 |" in scan.table(COMM.getSize())


def test_bloch_scan_resumed_table_is_the_uninterrupted_one(refined, tmp_path):
    """The table of a resumed Bloch file prints what the run that computed each row printed (work, residual detail,
    SLEPc), read from the records; a file written before those were recorded falls back, marked; -slepc_sizes
    outside -sizes is refused before any computation."""
    d, branch, *_ = refined
    path = f"{shared(tmp_path)}/b.npz"
    kw = dict(nev=4)                          # SLEPc: test_failures.py (it does not converge on this tiny chain)
    scan = BlochScan(branch, RefinedStates.load(f"{d}/r.npz"), [40], [0.4 * math.pi], COMM, path, **kw)
    (row, extra), = list(scan.run())
    table = scan.table(COMM.getSize())
    scan.destroy()
    assert extra["propagated"] and f"({extra['res_products']}, " in table
    assert f"| {extra['runs']} from 1 x {extra['columns'] // extra['runs']} on 3 cells |" in table
    again = BlochScan(branch, RefinedStates.load(f"{d}/r.npz"), [40], [0.4 * math.pi], COMM, path, "resume", **kw)
    assert list(again.run()) == [] and again.table(COMM.getSize()) == table
    again.destroy()
    old = f"{shared(tmp_path)}/old.npz"
    if COMM.getRank() == 0:                    # the file as written before BLOCH_DETAIL was recorded
        data = dict(np.load(path))
        np.savez(old, **{k: v for k, v in data.items() if k not in BLOCH_DETAIL})
    COMM.barrier()
    older = BlochScan(branch, RefinedStates.load(f"{d}/r.npz"), [40], [0.4 * math.pi], COMM, old, "resume", **kw)
    text = older.open().table(COMM.getSize())
    older.destroy()
    L = 40 // 20
    assert f"| {L // 2 + 1} x 40* |" in text and f"{row['residual']:.1e} * |" in text
    assert "* not recorded in this file" in text
    with pytest.raises(ParameterError, match="-slepc_sizes.*one of -sizes"):
        BlochScan(branch, RefinedStates.load(f"{d}/r.npz"), [40], [0.4 * math.pi], COMM, slepc_sizes=[60])


def test_long_run_resumes_bit_for_bit(tmp_path):
    """A run interrupted after some snapshots and resumed (the integrator's step is stored with each snapshot)
    repeats the uninterrupted trajectory exactly, record for record."""
    d = shared(tmp_path)
    orbit = orbit_on_chain(small_branch().point(0.4 * math.pi), chain(20))
    full = LongRun(orbit, 10.0, 2, f"{d}/a", COMM)
    full.run()
    summary = full.write_summary()
    full.destroy()
    part = LongRun(orbit, 5.0, 2, f"{d}/b", COMM)
    part.run()
    part.destroy()
    rest = LongRun(orbit, 10.0, 2, f"{d}/b", COMM, "resume")
    rest.run()
    rest.destroy()
    a, b = read_snapshots(f"{d}/a"), read_snapshots(f"{d}/b")
    assert np.array_equal(a.times, b.times) and np.array_equal(a.states, b.states)
    assert np.array_equal(a.steps, b.steps)
    # energy: 1e-11 between contact events; a step that straddles a contact opening or closing (V'' is only
    # C^(1/2) there) loses RK 8(7)'s order and leaves a jump of 1e-10 .. 3e-9 depending on where the adaptive steps
    # fall (measured on 1 and 2 ranks): the bound is 1e-8
    assert summary.energy_drift < 1e-8 and summary.max_deviation < 1e-3 and math.isnan(summary.destruction_time)
    other = orbit_on_chain(small_branch().point(0.6 * math.pi), chain(20))
    with pytest.raises(RecordFileError, match="another computation"):
        LongRun(other, 10.0, 2, f"{d}/a", COMM, "resume").open()
    with pytest.raises(RecordFileError, match="exists"):
        LongRun(orbit, 10.0, 2, f"{d}/a", COMM).open()
    with pytest.raises(ParameterError, match="t_final"):
        LongRun(orbit, -1.0, 2, f"{d}/c", COMM)
    # shorter than one snapshot interval: named as t_final with the bound T / snapshots_per_T (was snapshot_dt)
    with pytest.raises(ParameterError, match=f"t_final = 1e-09: must be >= script-T / snapshots_per_T = "
                       f"{orbit.T / 2:.6g} "):
        LongRun(orbit, 1e-9, 2, f"{d}/c", COMM)


def test_long_run_directories_of_the_first_format_are_read_but_not_resumed(tmp_path):
    d = shared(tmp_path)
    if COMM.getRank() == 0:
        os.makedirs(f"{d}/old")
        header = dict(alpha=1.5, N=3, boundary="periodic", q=2.0, T=1.0, initial_state="refined",
                      initial_state_sha256="x", snapshot_dt=0.5, rtol=1e-12, atol=1e-14, ts="rk 8vr")
        json.dump(header, open(f"{d}/old/run.json", "w"))
        np.arange(2 * (2 + 6), dtype=np.float64).tofile(f"{d}/old/snapshots.f64")
    COMM.tompi4py().Barrier()
    snaps = read_snapshots(f"{d}/old")
    assert snaps.states.shape == (2, 3, 2) and np.isnan(snaps.steps).all() and snaps.times[1] == 8.0
    orbit = orbit_on_chain(small_branch().point(0.4 * math.pi), chain(20))
    with pytest.raises(RecordFileError, match="older hertzpetsc"):
        LongRun(orbit, 10.0, 2, f"{d}/old", COMM, "resume").open()


def test_solitary_study_table():
    study = SolitaryStudy([1.5], [10, 20, 40], [5, 6], COMM)
    assert list(study.run()) == [1.5]
    assert "| k_alpha (L = 8) | 1.350" in study.table() and study.finest[1.5].params.cells_per_unit == 40
    with pytest.raises(ParameterError, match="three different grids"):
        SolitaryStudy([1.5], [10, 20], [5], COMM)


def test_compacton_study_keeps_beads_ahead_at_rest():
    branch = small_branch(K=200)
    study = CompactonStudy([branch], [0.3 * math.pi], COMM, margin=4, travel=10, dt_snapshot=0.1)
    cases = list(study.run())
    assert len(cases) == 2 and [c.train.count for c in cases] == [1, 2]
    assert all(c.checks.max_velocity_ahead == 0.0 for c in cases)
    assert study.table().count("| pi/200 |") == 2
    with pytest.raises(ParameterError, match="q_k"):
        CompactonStudy([branch], [0.7 * math.pi], COMM)
    # a snapshot interval longer than the single compacton's run (travel + its length, over c: the times of the
    # cases above) is refused before any run, naming dt_snapshot with that bound and saying where it comes from
    t_final = min(c.times[-1] for c in cases)
    with pytest.raises(ParameterError, match=rf"dt_snapshot = 1000.0: must lie in \(0, {t_final:g}\], the shortest "
                       r"run's duration t_final = \(travel \+ "):
        CompactonStudy([branch], [0.3 * math.pi], COMM, margin=4, travel=10, dt_snapshot=1e3)


def test_studies_run_in_memory_without_an_output_file():
    """A study built without an output path keeps its records in memory (a notebook): the same records and arrays
    as the file would hold."""
    params = ContinuationParameters(M=10, cells_per_pi=200, q_stop=math.pi / 2)
    study = BranchStudy(params)
    points = list(study.run())
    arrays = study.arrays()
    assert str(arrays["format"]) == "hertzpetsc-branch-1" and len(arrays["q"]) == len(points) == 6
    assert np.array_equal(arrays["u"][-1], points[-1].u_half)
    from hertzpetsc.studies.precompression import AmplitudeFamilies, AmplitudeParameters
    fam = AmplitudeFamilies(AmplitudeParameters(LatticeModel.hertz(1.5, delta0=1.0), (0.9,), 60, 0.01, 1.0, 1.0))
    rows = list(fam.run())
    assert [int(r["kind"]) for r in rows].count(2) == 1 and len(fam.records) == len(rows)


def test_a_resume_with_other_solver_options_is_refused(tmp_path, clean_options):
    """The options of the study's solver roles that change numbers are part of the record file's identity."""
    from hertzpetsc.studies.precompression import AmplitudeFamilies, AmplitudeParameters
    d = shared(tmp_path)
    params = AmplitudeParameters(LatticeModel.hertz(1.5, delta0=1.0), (0.9,), 60, 0.01, 1.0, 1.0)
    list(AmplitudeFamilies(params, COMM, f"{d}/a.npz").run())
    clean_options.setValue("precomp_snes_monitor", None)              # not a number-changing option
    list(AmplitudeFamilies(params, COMM, f"{d}/a.npz", "resume").run())
    clean_options.setValue("precomp_snes_rtol", "1e-6")
    with pytest.raises(RecordFileError, match="solver_options"):
        AmplitudeFamilies(params, COMM, f"{d}/a.npz", "resume").open()


def test_parameter_errors_name_the_argument_or_the_option():
    from hertzpetsc.studies.precompression import DimerParameters
    with pytest.raises(ParameterError, match=r"invalid max_steps = 0"):
        DimerParameters(LatticeModel.hertz(1.5, delta0=1.0), (0.9,), max_steps=0)
    err = ParameterError("max_steps", 0, "must be >= 1")
    assert str(err.as_option({"max_steps"})).startswith("invalid -max_steps = 0")
    assert err.as_option({"q"}) is err


def test_the_slepc_route_table_does_not_cap_the_count_or_print_an_unseen_spread():
    """The SLEPc route computes nev dominant multipliers: its rho is the dense route's (to the eigensolver's
    tolerance), but when all nev are outside the unit circle the count is a lower bound ('>= nev'; 13 and 3 are
    outside on the dense route here) and the trivial multipliers are not computed ('n/a', not 'nan')."""
    branch = small_branch(q_stop=0.2 * math.pi)
    tables, rhos = {}, {}
    for method in ("dense", "slepc"):
        scan = FloquetScan(branch, 20, COMM, refined=None, qs=[0.2 * math.pi, 0.3 * math.pi], method=method, nev=2)
        rhos[method] = [r["rho"] for r in scan.run()]
        scan.destroy()
        tables[method] = scan.table()
    assert np.allclose(rhos["slepc"], rhos["dense"], rtol=1e-9, atol=0)
    assert "| 0.6283 | 1.23542531 | 13 | 8.8e-03 |" in tables["dense"]
    assert "| 0.6283 | 1.23542531 | >= 2 | n/a |" in tables["slepc"] and "| >= 2 | n/a |" in tables["slepc"]


def _stale_table(tmp_path):
    """A table file as another run left it (on every rank's shared directory)."""
    from conftest import shared_tmp
    path = os.path.join(shared_tmp(tmp_path), "t.md")
    if COMM.getRank() == 0:
        with open(path, "w") as f:
            f.write("the table of another run\n")
    COMM.barrier()
    return path


def _read_after(path):
    COMM.barrier()
    with open(path) as f:
        return f.read()


def test_a_stopped_study_that_is_not_a_study_subclass_writes_the_table_of_what_it_did(monkeypatch, tmp_path):
    """run_to_table (solitary_wave.py, compactons.py): a ConvergenceError on the second alpha leaves the table of
    the first with the stop below it, not the table of another run; the error is raised."""
    from hertzpetsc.errors import ConvergenceError
    from hertzpetsc.studies import solitary
    from hertzpetsc.studies.base import run_to_table
    solve = solitary.solve_solitary_wave

    def failing(params, comm):
        if params.alpha == 2.0:
            raise ConvergenceError("test solver", -3, alpha=params.alpha)
        return solve(params, comm)
    monkeypatch.setattr(solitary, "solve_solitary_wave", failing)
    path = _stale_table(tmp_path)
    study = SolitaryStudy([1.5, 2.0], [10, 20, 40], [5], COMM)
    shown = []
    with pytest.raises(ConvergenceError, match="test solver"):
        run_to_table(study, path, shown.append)
    table = _read_after(path)
    assert shown == [1.5] and table == study.table() + ("\nStopped before the end: test solver did not converge "
                                                        "(reason -3) at alpha = 2\n")
    assert "### alpha = 1.5" in table and "alpha = 2\n" not in table.split("Stopped")[0]


def test_a_stopped_study_without_a_record_file_writes_the_table_of_what_it_did(monkeypatch, tmp_path):
    """Study.run_to_table (convergence_h.py: no record file, the table is the result; small_q.py: a table that
    needs the whole run): an error on the second grid leaves the table of the first grid, or the reason there is
    none, with the stop below it; the stale table is gone and the error is raised."""
    from hertzpetsc.errors import ConvergenceError
    from hertzpetsc.studies import branch
    points = branch.BranchContinuation.points

    def failing(self, targets=None):
        if self.params.cells_per_pi == 40:
            raise ConvergenceError("test solver", -3, q=1.0)
        yield from points(self, targets)
    monkeypatch.setattr(branch.BranchContinuation, "points", failing)
    stop = "\nStopped before the end: test solver did not converge (reason -3) at q = 1\n"
    for text, why in ((None, None), ("needs", "the progress file lacks q = 1 (run to the end first)")):
        path = _stale_table(tmp_path)
        study = ConvergenceStudy(LatticeModel.hertz(1.5), 5, [20, 40, 80], COMM)

        def lacking():
            raise RecordFileError(why)
        shown = []
        with pytest.raises(ConvergenceError, match="test solver"):
            study.run_to_table(path, shown.append, lacking if text else None)
        table = _read_after(path)
        assert shown == [20] and {K for K, _ in study.values} == {20}
        assert table == (f"No table: {why}\n" if text else study.table()) + stop
