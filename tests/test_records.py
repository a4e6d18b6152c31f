"""The record store and the branch file: schema, atomic rewrite, modes, identities, resume, readable with numpy
alone, clear errors (serial and under mpiexec -n 2: rank 0 writes, every rank sees the same records)."""
import json
import math
import os

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import DATA, shared_tmp
from hertzpetsc.branch import POINT_FIELDS, Branch, BranchPoint, SolveStats, branch_store
from hertzpetsc.diagnostics import WaveDiagnostics
from hertzpetsc.errors import ParameterError, RecordFileError
from hertzpetsc.model import LatticeModel
from hertzpetsc.records import (AppendRecords, NpzRecords, file_provenance, load_npz, prepare_output, provenance,
                                write_text)

COMM = PETSc.COMM_WORLD


def small_branch(npts=3, K=8):
    model = LatticeModel.hertz(1.5)
    b = Branch(model, K, 10, [], dict(note="test"))
    for i in range(npts):
        d = WaveDiagnostics(*[float(i)] * len(WaveDiagnostics.names()))
        b.points.append(BranchPoint(q=math.pi * (10 - i) / 10, u_half=np.sin(np.arange(K + 1) * math.pi / K) * (i + 1),
                                    h=b.h, model=model, diagnostics=d, solve=SolveStats(2, 3, 4, 1e-9, 0.1), substeps=1,
                                    wall_time=0.5))
    return b


def write(path, branch, mode="new"):
    store = branch_store(path, Branch(branch.model, branch.cells_per_pi, branch.M, [], branch.meta), COMM, mode)
    for p in branch.points:
        store.append(p.record())
    return store


def test_roundtrip_and_plain_numpy_access(tmp_path):
    path = os.path.join(shared_tmp(tmp_path), "b.npz")
    write(path, small_branch())
    b = Branch.load(path)
    assert b.u.shape == (3, 9) and b.alpha == 1.5 and b.meta["note"] == "test"
    assert b.point(0.9 * math.pi).q == pytest.approx(0.9 * math.pi) and b.point(0.9 * math.pi).solve.linear_iterations == 4
    with np.load(path) as z:                       # no hertzpetsc needed to read it: the README's schema
        assert set(POINT_FIELDS) <= set(z.files) and str(z["format"]) == "hertzpetsc-branch-1"
        assert z["snes_iterations"].dtype == np.int64 and z["u"].shape == (3, 9)
    COMM.tompi4py().Barrier()
    assert not [f for f in os.listdir(os.path.dirname(path)) if ".tmp" in f]     # no temporary file left


def test_a_file_written_before_the_record_store_still_loads():
    b = Branch.load(os.path.join(DATA, "branch_alpha1.5.npz"))
    assert len(b) == 50 and abs(b.point(math.pi / 50).diagnostics.N - 4.8442) < 1e-4


def test_modes_new_resume_force(tmp_path):
    path = os.path.join(shared_tmp(tmp_path), "b.npz")
    write(path, small_branch(2))
    with pytest.raises(RecordFileError, match="exists: continue it with -resume or overwrite it with -force "
                       r"\(mode 'resume' or 'force' in the API\)"):
        write(path, small_branch(1))
    empty = Branch(LatticeModel.hertz(1.5), 8, 10, [])
    resumed = branch_store(path, empty, COMM, "resume")
    assert len(resumed.records) == 2                             # every rank gets the finished records
    resumed.append(small_branch(3).points[2].record())
    assert len(Branch.load(path)) == 3
    write(path, small_branch(1), "force")
    assert len(Branch.load(path)) == 1
    with pytest.raises(RecordFileError, match="does not exist: nothing to resume"):
        branch_store(path + ".missing", empty, COMM, "resume")


def test_resume_with_another_identity_names_the_parameter(tmp_path):
    path = os.path.join(shared_tmp(tmp_path), "b.npz")
    write(path, small_branch(1))
    other = Branch(LatticeModel.hertz(2.0), 8, 10, [])
    with pytest.raises(RecordFileError, match=r"another computation: alpha = 1.5 there, 2.0 requested"):
        branch_store(path, other, COMM, "resume")


def test_stale_temporaries_are_removed(tmp_path):
    d = shared_tmp(tmp_path)
    path = os.path.join(d, "b.npz")
    if COMM.getRank() == 0:
        for tmp in (path + ".tmp", path + ".tmp-12345"):
            open(tmp, "wb").write(b"half a write")
    COMM.tompi4py().Barrier()
    write(path, small_branch(1))
    assert sorted(os.listdir(d)) == ["b.npz"]


def test_missing_point_and_missing_file(tmp_path):
    path = os.path.join(shared_tmp(tmp_path), "b.npz")
    write(path, small_branch())
    with pytest.raises(RecordFileError, match="no point at q = 0.5"):
        Branch.load(path).point(0.5)
    with pytest.raises(RecordFileError, match="does not exist"):
        Branch.load(path + ".nothing")


@pytest.mark.parametrize("content", [b"", b"not a zip at all", b"PK\x03\x04garbage"])
def test_corrupt_file(tmp_path, content):
    path = tmp_path / "b.npz"
    path.write_bytes(content)
    with pytest.raises(RecordFileError, match="corrupt"):
        Branch.load(str(path))


def test_truncated_file(tmp_path):
    path = os.path.join(shared_tmp(tmp_path), "b.npz")
    write(path, small_branch())
    COMM.tompi4py().Barrier()
    if COMM.getRank() == 0:
        data = open(path, "rb").read()
        open(path, "wb").write(data[: len(data) // 2])
    COMM.tompi4py().Barrier()
    with pytest.raises(RecordFileError, match="corrupt"):
        Branch.load(path)


def test_a_file_of_another_kind_is_named(tmp_path):
    path = os.path.join(shared_tmp(tmp_path), "f.npz")
    NpzRecords(path, "hertzpetsc-floquet-1", {}, {}, ("q",), COMM)
    with pytest.raises(RecordFileError, match="is a 'hertzpetsc-floquet-1' file, but a branch file"):
        Branch.load(path)
    if COMM.getRank() == 0:
        np.savez(os.path.join(os.path.dirname(path), "x.npz"), x=np.zeros(3))
    COMM.tompi4py().Barrier()
    with pytest.raises(RecordFileError, match="not a hertzpetsc record file"):
        Branch.load(os.path.join(os.path.dirname(path), "x.npz"))


def test_state_arrays_are_replaced_and_resumed(tmp_path):
    path = os.path.join(shared_tmp(tmp_path), "s.npz")
    store = NpzRecords(path, "test-1", dict(a=1), dict(a=1), ("q",), COMM)
    store.append(dict(q=1.0), state=dict(u=np.arange(3.0)))
    store.append(dict(q=0.5), state=dict(u=np.arange(5.0)))
    again = NpzRecords(path, "test-1", dict(a=1), dict(a=1), ("q",), COMM, "resume")
    assert [float(r["q"]) for r in again.records] == [1.0, 0.5] and np.array_equal(again.state["u"], np.arange(5.0))


def git_head():
    """The commit of this checkout by git itself (None outside a work tree or without git)."""
    import subprocess
    try:
        r = subprocess.run(["git", "rev-parse", "HEAD"], cwd=os.path.dirname(__file__), capture_output=True,
                           text=True, timeout=30)
    except OSError:
        return None
    return r.stdout.strip() if r.returncode == 0 else None


def check_provenance(about, inputs=None):
    """A file's provenance names the package's version and commit, the command line, the stack's versions, the
    ranks, a date (UTC, within the last hour) and the digests of ``inputs`` ({name: path})."""
    import datetime
    import hashlib
    import hertzpetsc
    from mpi4py import MPI
    assert about["hertzpetsc"] == hertzpetsc.__version__ and about["commit"] == git_head()
    assert about["argv"] and about["petsc"] == ".".join(map(str, PETSc.Sys.getVersion()))
    assert about["slepc"].startswith("3.") and about["mpi4py"] and about["mpi"] == \
        MPI.Get_library_version().splitlines()[0].split(",")[0].strip()
    created = datetime.datetime.fromisoformat(about["created"])
    age = datetime.datetime.now(datetime.timezone.utc) - created
    assert created.utcoffset() == datetime.timedelta(0) and datetime.timedelta(0) <= age < datetime.timedelta(hours=1)
    for name, path in (inputs or {}).items():
        with open(path, "rb") as f:
            assert about["inputs"][name] == dict(path=str(path), sha256=hashlib.sha256(f.read()).hexdigest())


@pytest.mark.parametrize("suffix", [".npz", ".h5"])
def test_every_record_file_names_its_provenance_and_keeps_it_on_resume(tmp_path, suffix):
    """A record file says what made it (``__provenance__``, JSON, read with numpy or h5py alone); a resume adds
    its own and keeps the first run's under ``earlier``; a file written before has none and still resumes."""
    d = shared_tmp(tmp_path)
    source = os.path.join(d, "input.txt")
    if COMM.getRank() == 0:
        with open(source, "w") as f:
            f.write("an input file")
    COMM.tompi4py().Barrier()
    path = os.path.join(d, "p" + suffix)
    NpzRecords(path, "test-1", dict(a=1), dict(a=1), ("q",), COMM,
               about=provenance(dict(source=source), "test()", COMM)).append(dict(q=1.0))
    if suffix == ".npz":
        with np.load(path) as z:                       # numpy alone
            about = json.loads(str(z["__provenance__"]))
    else:
        h5py = pytest.importorskip("h5py")
        with h5py.File(path, "r") as f:                # h5py alone
            about = json.loads(f["__provenance__"][()].decode())
    COMM.tompi4py().Barrier()                          # every rank has read it before the resume rewrites it
    check_provenance(about, dict(source=source))
    assert about["ranks"] == COMM.getSize() and about["call"] == "test()"
    NpzRecords(path, "test-1", dict(a=1), dict(a=1), ("q",), COMM, "resume").append(dict(q=0.5))
    again = file_provenance(load_npz(path, "x"))
    check_provenance(again)
    assert again["earlier"] == [about] and again["call"] is None and again["inputs"] == {}
    if suffix == ".npz":                               # a file of before: no provenance, resumed, given one
        old = os.path.join(d, "old.npz")
        if COMM.getRank() == 0:
            np.savez(old, format=np.array("test-1"), a=np.array(1), q=np.array([1.0]))
        COMM.tompi4py().Barrier()
        assert file_provenance(load_npz(old, "x")) is None
        NpzRecords(old, "test-1", dict(a=1), dict(a=1), ("q",), COMM, "resume").append(dict(q=0.5))
        assert "earlier" not in file_provenance(load_npz(old, "x"))


def test_a_run_directory_names_its_provenance(tmp_path):
    d = os.path.join(shared_tmp(tmp_path), "run")
    AppendRecords(d, "test-log-1", dict(N=2), dict(N=2), 3, COMM).append([1.0, 2.0, 3.0])
    with open(os.path.join(d, "run.json")) as f:
        check_provenance(json.load(f)["provenance"])


def test_identity_difference_names_the_parameter_that_sets_the_key(tmp_path):
    """A key that is not the parameter's name (the solitary scan stores c0 as sound_speeds) is named with the
    parameter and option that set it; other keys as they are."""
    path = os.path.join(shared_tmp(tmp_path), "n.npz")
    names = dict(sound_speeds="c0 (-c0)")
    NpzRecords(path, "test-1", dict(sound_speeds=[0.0, 0.5], M=40), dict(sound_speeds=[0.0, 0.5], M=40), ("q",),
               COMM, names=names).append(dict(q=1.0))
    other_c0 = dict(sound_speeds=[0.0, 0.7], M=40)
    other_M = dict(sound_speeds=[0.0, 0.5], M=42)
    c0_said = r"sound_speeds = \[0\.0, 0\.5\] there, \[0\.0, 0\.7\] requested, set by c0 \(-c0\) \(rerun"
    for identity, said in ((other_c0, c0_said), (other_M, r"M = 40 there, 42 requested \(rerun")):
        with pytest.raises(RecordFileError, match=said):
            NpzRecords(path, "test-1", identity, identity, ("q",), COMM, "resume", names=names)


def test_append_records_survive_a_record_in_flight(tmp_path):
    d = os.path.join(shared_tmp(tmp_path), "run")
    store = AppendRecords(d, "test-log-1", dict(N=2), dict(N=2), 3, COMM)
    for i in range(4):
        store.append([i, 2.0 * i, 3.0 * i])
    COMM.tompi4py().Barrier()
    if COMM.getRank() == 0:
        with open(os.path.join(d, "records.f64"), "ab") as f:
            f.write(b"\0" * 12)                               # killed in the middle of a record
    COMM.tompi4py().Barrier()
    again = AppendRecords(d, "test-log-1", dict(N=2), dict(N=2), 3, COMM, "resume")
    assert again.array().shape == (4, 3) and again.array()[3, 2] == 9.0
    with pytest.raises(RecordFileError, match="N = 2 there, 3 requested"):
        AppendRecords(d, "test-log-1", dict(N=3), dict(N=3), 3, COMM, "resume")


def test_unwritable_outputs_fail_on_every_rank_before_anything_is_computed(tmp_path):
    d = shared_tmp(tmp_path)
    blocker = os.path.join(d, "afile")
    if COMM.getRank() == 0:
        open(blocker, "w").write("x")
    COMM.tompi4py().Barrier()
    with pytest.raises(RecordFileError, match="cannot write table"):
        prepare_output(os.path.join(blocker, "t.md"), COMM, "table")
    with pytest.raises(RecordFileError, match="cannot"):
        write_text(os.path.join(blocker, "t.md"), "x", COMM)
    with pytest.raises(RecordFileError):
        write(os.path.join(blocker, "b.npz"), small_branch(1))


@pytest.mark.serial
def test_a_device_or_pipe_is_written_in_place_not_replaced(tmp_path):
    """A table written to a path that is not a regular file (a FIFO here; /dev/null for a user who wants no table)
    is written into it: the atomic rename of a regular file would replace the device by a file (as root, the
    machine's /dev/null)."""
    import stat
    import threading
    fifo = str(tmp_path / "pipe")
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(open(fifo, "rb").read()), daemon=True)
    reader.start()
    write_text(fifo, "| a | table |\n")
    reader.join(timeout=10)
    assert got == [b"| a | table |\n"] and stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert sorted(os.listdir(tmp_path)) == ["pipe"]                      # no temporary file beside it


def test_bad_mode_and_model_are_refused():
    with pytest.raises(ParameterError, match="invalid mode = 'sometimes': must be one of new, resume, force"):
        NpzRecords("x.npz", "k", {}, {}, ("q",), None, "sometimes")
    with pytest.raises(ParameterError, match="masses"):
        LatticeModel.hertz(1.5, masses=(1.0, -2.0))


def test_hdf5_record_files_have_the_same_fields_and_identity_checks(tmp_path):
    """A record file named *.h5 is HDF5 (for MATLAB and Julia): the same arrays as the npz layout, read back
    equal, resumed with the same identity checks."""
    import h5py
    from petsc4py import PETSc
    from hertzpetsc.qbranch import ContinuationParameters
    from hertzpetsc.studies.branch import BranchStudy
    d = str(tmp_path) if PETSc.COMM_WORLD.getSize() == 1 else None
    if d is None:
        pytest.skip("one rank: a file per process")
    params = ContinuationParameters(M=10, cells_per_pi=100, q_stop=0.6 * math.pi)
    for name in ("b.npz", "b.h5"):
        list(BranchStudy(params, f"{d}/{name}", PETSc.COMM_SELF).run())
    a, b = load_npz(f"{d}/b.npz", "x"), load_npz(f"{d}/b.h5", "x")
    assert set(a) == set(b)
    for k in a:
        if a[k].dtype.kind in "fi":
            assert np.array_equal(a[k], b[k]) or k in ("wall_time",), k
        else:
            assert str(a[k]) == str(b[k]) or k in ("meta", "__provenance__"), k
    with h5py.File(f"{d}/b.h5", "r") as f:                 # plain HDF5: datasets by name
        assert f["u"].shape == a["u"].shape and f["format"][()] == b"hertzpetsc-branch-1"
    with pytest.raises(RecordFileError, match="alpha"):
        BranchStudy(ContinuationParameters(alpha=2.0, M=10, cells_per_pi=100, q_stop=0.6 * math.pi), f"{d}/b.h5",
                    PETSc.COMM_SELF, "resume").open()
    resumed = BranchStudy(params, f"{d}/b.h5", PETSc.COMM_SELF, "resume").open()
    assert resumed.resumed == len(a["q"])


def test_a_missing_branch_point_names_its_nearest_neighbours():
    branch = Branch(LatticeModel.hertz(1.5), 8, 10, small_branch(3).points)
    q = branch.q
    with pytest.raises(RecordFileError, match=rf"no point at q = .* \(it has 3 points, .* the nearest "
                                              rf"{min(q[:2]):.12g} and {max(q[:2]):.12g}\)"):
        branch.point(0.5 * (q[0] + q[1]))


def test_an_error_raised_on_every_rank_keeps_its_fields():
    """A package error passed from the rank that raised it to the others (rank 0's file operations, the dealt
    computations) keeps its fields, so that the driver's one error line names the option on every rank (on two
    ranks a ParameterError arrived without ``name``: an AttributeError traceback, exit 1)."""
    from hertzpetsc.errors import ConvergenceError
    from hertzpetsc.records import on_rank0
    from hertzpetsc.studies.dealing import dealt

    def refuse(x=None):
        raise ParameterError("a", 1e-12, "too small")

    with pytest.raises(ParameterError) as err:
        on_rank0(COMM, refuse)
    assert (err.value.name, err.value.value, err.value.as_option({"a"}).name) == ("a", 1e-12, "-a")
    with pytest.raises(ParameterError) as err:
        list(dealt([1, 2], [1.0, 1.0], COMM, refuse))
    assert err.value.as_option({"a"}).name == "-a"

    def diverge():
        raise ConvergenceError("Newton", -5, q=0.5)

    with pytest.raises(ConvergenceError) as err:
        on_rank0(COMM, diverge)
    assert err.value.reason == -5 and err.value.where == {"q": 0.5}


# --- record kinds declared once ---------------------------------------------------------------------------------
def test_a_kinds_rows_check_and_typed_reader(tmp_path):
    """Kind.row writes each {column} of its cells in the column's format, the rest as given; Kind.check names the declared
    columns a file lacks and the entries it has that no column declares (a name <x> standing for one per x);
    read_kind refuses a file of another kind or without a declared column, naming it; typed_records gives each value
    its column's dtype."""
    from hertzpetsc.records import Column, Kind, KINDS, npz_arrays, read_kind, typed_records, write_npz
    kind = Kind("hertzpetsc-test-kind-1", (
        Column("alpha", "exponent", constant=True), Column("input_<x>_sha256", "hashes", "", str, "s", constant=True),
        Column("note", "a label", "", str, "s", constant=True, optional=True),
        Column("q", "wavenumber", format=".4f"), Column("m", "wavelengths", "count", np.int64, "d"),
        Column("mu", "multiplier", "1", complex), Column("tag", "a label", "", str, "s"),
        Column("x", "state", shape="2")))
    KINDS.pop(kind.name)                                        # not a kind of the package
    records = [dict(q=0.5, m=3, mu=1 + 2j, tag="a", x=[1.0, 2.0]), dict(q=1.25, m=4, mu=0.5j, tag="bc", x=[3.0, 4.0])]
    arrays = npz_arrays(kind.name, dict(alpha=1.5, input_branch_sha256="0" * 64), kind.fields, records,
                        dtypes=kind.dtypes, columns=kind)
    assert kind.row(records[1], "{q}", "{m} ({tag})", "tag", f"{abs(records[1]['mu']):.1f}", 7, "{other}") == \
        "| 1.2500 | 4 (bc) | tag | 0.5 | 7 | {other} |"          # a literal that names a column stays a literal
    assert kind.check(arrays) == ([], [])
    assert kind.check(dict(arrays, extra=np.zeros(2))) == ([], ["extra"])
    assert kind.check({k: v for k, v in arrays.items() if k != "m"}) == (["m"], [])
    path = str(tmp_path / "k.npz")
    write_npz(path, arrays)
    rows = typed_records(read_kind(path, kind, "test file"), kind)
    assert rows[1]["q"] == 1.25 and type(rows[1]["m"]) is int and rows[1]["mu"] == 0.5j and rows[1]["tag"] == "bc"
    assert type(rows[0]["mu"]) is complex and type(rows[0]["tag"]) is str and rows[0]["x"].tolist() == [1.0, 2.0]
    write_npz(path, {k: v for k, v in arrays.items() if k != "m"})
    with pytest.raises(RecordFileError, match=r"is corrupt: missing \['m'\]"):
        read_kind(path, kind, "test file")
    write_npz(path, dict(arrays, format=np.array("hertzpetsc-other-1")))
    with pytest.raises(RecordFileError, match="hertzpetsc-other-1"):
        read_kind(path, kind, "test file")


def test_the_committed_fixtures_of_every_declared_kind_open_as_declared():
    """Files written by earlier versions (tests/data, frozen copies of results files: some before __columns__,
    provenance or fields added since) open through the typed reader of their kind, every entry declared."""
    from hertzpetsc.records import read_kind, typed_records
    from hertzpetsc.studies.schemas import kinds
    declared, seen = kinds(), set()
    for name in sorted(os.listdir(DATA)):
        if not name.endswith(".npz"):
            continue
        data = load_npz(os.path.join(DATA, name), "fixture")
        kind = declared.get(str(data.get("format", "")))
        if kind is None:
            continue
        data = read_kind(os.path.join(DATA, name), kind, "fixture")
        assert kind.check(data) == ([], []), name
        assert len(typed_records(data, kind)) == len(data[kind.fields[0]]), name
        seen.add(kind.name)
    assert {"hertzpetsc-refined-1", "hertzpetsc-floquet-1", "hertzpetsc-wave-1",
            "hertzpetsc-compacton-stability-1"} <= seen


def test_a_file_written_before_its_columns_were_declared_resumes(tmp_path):
    """A restitution file as written before its kind was declared (no __columns__, no provenance), its run stopped
    after the first velocity, resumes: that record kept as it was, the other added, the file then naming its
    columns."""
    from hertzpetsc.records import write_npz
    from hertzpetsc.studies.contacts import RESTITUTION_KIND, Restitution, RestitutionParameters
    path, params = f"{shared_tmp(tmp_path)}/e.npz", RestitutionParameters(velocities=(0.1, 0.3))
    first = Restitution(params, COMM, path)
    list(first.run())
    old = {k: v[:1] if k in RESTITUTION_KIND.fields else v for k, v in first.arrays().items()
           if k not in ("__columns__", "__provenance__")}
    if COMM.getRank() == 0:
        write_npz(path, old)
    COMM.barrier()
    resumed = Restitution(params, COMM, path, "resume")
    assert len(list(resumed.run())) == 1
    data = load_npz(path, "x")
    assert data["e"][0] == old["e"][0] and data["e"].tolist() == first.arrays()["e"].tolist()
    assert set(json.loads(str(data["__columns__"]))) == {c.name for c in RESTITUTION_KIND.columns}
