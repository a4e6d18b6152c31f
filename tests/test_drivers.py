"""Every driver in scripts/ run once as a subprocess on tiny inputs (the library's studies are tested in-process):
it reads its options, runs, writes its files, and the paper's numbers come out of the main command."""
import json
import math
import os

import numpy as np
import pytest

from conftest import DATA, SCRIPTS, run_script
from hertzpetsc.branch import BRANCH_KIND, Branch
from hertzpetsc.records import read_kind
from hertzpetsc.simulation import LONGRUN_KIND
from hertzpetsc.studies.floquet import BLOCH_KIND, FLOQUET_KIND
from hertzpetsc.studies.refinement import REFINED_KIND, RefinedStates

pytestmark = pytest.mark.serial


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """A coarse branch (h = pi/200, q = m pi/10 down to 0.3 pi) written by the continuation driver, and a
    refinement file of q = 0.4 pi on 20 beads written by the refinement driver."""
    d = tmp_path_factory.mktemp("drivers")
    r = run_script("continuation.py", "-M", 10, "-cells_per_pi", 200, "-q_stop", "0.3*pi", "-output", d / "b.npz")
    assert r.returncode == 0, r.stderr
    r = run_script("refine_branch.py", "-branch", d / "b.npz", "-N", 20, "-q", "0.4*pi", "-output", d / "r.npz",
                   "-table", d / "r.md", "-figures", d)
    assert r.returncode == 0, r.stderr
    return d


def test_main_command_reproduces_the_paper_table(tmp_path):
    """The default run (alpha = 3/2, h = pi 1e-3, M = 50) on 2 ranks: the figures and every number of the
    paper's table (paper_table.py exits 1 if one disagrees); the same branch as the committed one on 1 rank."""
    r = run_script("continuation.py", "-output", tmp_path / "b.npz", "-figures", tmp_path / "fig", ranks=2)
    assert r.returncode == 0, r.stderr
    assert len([line for line in r.stdout.splitlines() if line.startswith("  ")]) == 50
    r = run_script("paper_table.py", "-branch", tmp_path / "b.npz", "-output", tmp_path / "t.md")
    assert r.returncode == 0 and "NO" not in r.stdout, r.stdout + r.stderr
    assert sorted(p.name for p in (tmp_path / "fig").iterdir()) == sorted(
        f"{n}.png" for n in ("profiles", "normes", "pentes", "number", "lsq", "dispersplot"))
    two, one = Branch.load(str(tmp_path / "b.npz")), Branch.load(f"{DATA}/branch_alpha1.5.npz")
    assert two.meta["ranks"] == 2 and np.max(np.abs(two.u - one.u)) <= 1e-10 * np.max(np.abs(one.u))


def test_refinement_driver_resumes(work):
    r = run_script("refine_branch.py", "-branch", work / "b.npz", "-N", 20, "-q", "0.4*pi,0.6*pi", "-output",
                   work / "r2.npz", "-table", work / "r2.md")
    assert r.returncode == 0, r.stderr
    assert (work / "errors.png").exists() and "| 1.2566 | 4 |" in (work / "r.md").read_text()
    r = run_script("refine_branch.py", "-branch", work / "b.npz", "-N", 20, "-output", work / "r2.npz", "-table",
                   work / "r2.md", "-resume")
    assert r.returncode == 0, r.stderr
    assert len(RefinedStates.load(str(work / "r2.npz")).q) == 8            # the other 6 q = 2 pi m / 20 added
    assert REFINED_KIND.check(read_kind(str(work / "r2.npz"), REFINED_KIND, "x")) == ([], [])


def test_floquet_drivers(work):
    r = run_script("floquet_scan.py", "-branch", work / "b.npz", "-N", 20, "-refined", work / "r.npz", "-output",
                   work / "f.npz", "-table", work / "f.md", "-check_q", "0.4*pi", "-figures", work, ranks=2)
    assert r.returncode == 0, r.stderr
    text = (work / "f.md").read_text()
    assert "| 1.2566 |" in text and "consistency at q = 1.2566" in text and (work / "eigen.png").exists()
    r = run_script("floquet_long.py", "-branch", work / "b.npz", "-refined", work / "r.npz", "-sizes", 40,
                   "-q", "0.4*pi", "-nev", 4, "-output", work / "fl.md", "-npz", work / "fl.npz", "-reference",
                   work / "f.npz")
    assert r.returncode == 0, r.stderr
    assert "| 40 | 2pi/5 | 8 |" in (work / "fl.md").read_text()
    for name, kind in (("b", BRANCH_KIND), ("f", FLOQUET_KIND), ("fl", BLOCH_KIND)):   # the declared columns
        assert kind.check(read_kind(str(work / f"{name}.npz"), kind, "x")) == ([], []), name


def test_long_run_and_dynamics_figures(work):
    run = work / "run"
    r = run_script("long_run.py", "-branch", work / "b.npz", "-q", "0.4*pi", "-N", 20, "-t_final", 6, "-refined",
                   work / "r.npz", "-output", run)
    assert r.returncode == 0, r.stderr
    r = run_script("dynamics_figures.py", "-runs", f"{run}:0:6", "-figures", work / "dyn", "-table", work / "lr.md")
    assert r.returncode == 0, r.stderr
    assert {p.name for p in (work / "dyn").iterdir()} == {"run_snapshot.png", "run_forces.png", "deviation.png"}
    assert "| run | 1.2566 | 1.2627 | refined |" in (work / "lr.md").read_text()
    with open(run / "run.json") as f:
        header = json.load(f)                       # the keys and the records' parts, declared once
    assert set(header["columns"]) == {c.name for c in LONGRUN_KIND.columns}
    assert {c.name for c in LONGRUN_KIND.columns if c.constant} <= set(header)


def test_every_file_a_driver_writes_names_its_provenance(work, tmp_path):
    """The results files of the drivers (npz and HDF5 record files, a run directory's header), reread with numpy,
    h5py or json alone, name what made them: the version and commit, the driver's command line, the stack's
    versions, the ranks, the date, and the digests of the files the run read."""
    import json
    import h5py
    from test_records import check_provenance
    r = run_script("refine_branch.py", "-branch", work / "b.npz", "-N", 20, "-q", "0.4*pi", "-output",
                   tmp_path / "r.h5", "-table", tmp_path / "r.md", ranks=2)
    assert r.returncode == 0, r.stderr
    r = run_script("restitution.py", "-velocities", "0.01", "-output", tmp_path / "e.npz", "-table", tmp_path / "e.md")
    assert r.returncode == 0, r.stderr
    run = work / "run"
    if not (run / "run.json").exists():
        assert run_script("long_run.py", "-branch", work / "b.npz", "-q", "0.4*pi", "-N", 20, "-t_final", 6,
                          "-refined", work / "r.npz", "-output", run).returncode == 0
    files = {work / "b.npz": ("continuation.py", {}, 1), work / "r.npz": ("refine_branch.py", {"branch"}, 1),
             tmp_path / "r.h5": ("refine_branch.py", {"branch"}, 2), tmp_path / "e.npz": ("restitution.py", {}, 1)}
    for path, (script, inputs, ranks) in files.items():
        if path.suffix == ".h5":
            with h5py.File(path, "r") as f:
                about = json.loads(f["__provenance__"][()].decode())
        else:
            with np.load(path) as z:
                about = json.loads(str(z["__provenance__"]))
        check_provenance(about, {name: about["inputs"][name]["path"] for name in inputs})
        assert os.path.basename(about["argv"][0]) == script and about["ranks"] == ranks, (path, about)
        assert set(about["inputs"]) == set(inputs), (path, about["inputs"])
    with h5py.File(tmp_path / "r.h5", "r") as f:          # a kind declared with its columns: units and meanings
        assert f["wall_time"].attrs["units"] == "s" and f["x"].attrs["description"].startswith("refined state")
        assert set(json.loads(f["__columns__"][()].decode())) >= set(f) - {"format", "__provenance__", "__columns__"}
    with open(run / "run.json") as f:
        about = json.load(f)["provenance"]
    check_provenance(about)
    assert os.path.basename(about["argv"][0]) == "long_run.py"


def test_section_3_1_3_3_and_appendix_drivers(work, tmp_path):
    r = run_script("convergence_h.py", "-M", 10, "-cells", "100,200,400", "-output", tmp_path / "c.md")
    assert r.returncode == 0, r.stderr
    row = [line for line in (tmp_path / "c.md").read_text().splitlines() if line.startswith("| 3pi/10 | norm_inf")]
    assert len(row) == 1 and abs(float(row[0].split("|")[-3]) - 2) < 0.3
    r = run_script("solitary_wave.py", "-alphas", "1.5", "-cells", "10,20,40", "-lengths", "5,6", "-output",
                   tmp_path / "s.md", "-figures", tmp_path)
    assert r.returncode == 0 and (tmp_path / "ondesol.png").exists(), r.stderr
    r = run_script("long_wave.py", "-branch", f"{DATA}/branch_alpha1.5.npz", "-cells_per_unit", 20, "-output",
                   tmp_path / "lw.md", "-figures", tmp_path)
    assert r.returncode == 0 and "| 0.0628 |" in (tmp_path / "lw.md").read_text(), r.stderr
    r = run_script("compactons.py", "-branches", work / "b.npz", "-q", "0.3*pi", "-margin", 4, "-travel", 20,
                   "-dt_snapshot", 0.1, "-output", tmp_path / "cp.md", "-figures", tmp_path, ranks=2)
    assert r.returncode == 0, r.stderr
    rows = [line for line in (tmp_path / "cp.md").read_text().splitlines() if line.startswith("| pi/200 ")]
    assert len(rows) == 2 and all(line.split("|")[7].strip() == "0.0e+00" for line in rows)
    assert (tmp_path / "graphulin.png").exists() and (tmp_path / "compacton2_spacetime.png").exists()


def test_small_q_driver(tmp_path):
    args = ("-q_stop", "pi/60", "-per_halving", 1, "-cells_per_q", 4, "-progress", tmp_path / "p.npz", "-output",
            tmp_path / "s.md")
    r = run_script("small_q.py", *args, "-figures", tmp_path)
    assert r.returncode == 0, r.stderr
    assert "| 0.052360 | 60.00 | 1600 |" in (tmp_path / "s.md").read_text() and (tmp_path / "smallq.png").exists()
    r = run_script("small_q.py", *args, "-resume")                       # nothing left to do: the same table
    assert r.returncode == 0 and (tmp_path / "s.md").read_text().count("| 0.0") == 2, r.stderr


@pytest.mark.parametrize("script,args,rows", [
    ("bench_branch.py", ("-cells", 100, "-M", 10), ("| pi/100 |", 5)),
    ("bench_chain.py", ("-sizes", 20, "-refine_N", 20), ("| 20 |", 3)),
    ("bench_newton.py", ("-cells", "100,200", "-logview_cells", 0), ("| pi*", 4)),
    ("bench_driven.py", ("-N", 2, "-points", 3, "-run_in", 2, "-workloads", "sweep"), ("| hertzpetsc", 2)),
    ("bench_long_driven.py", ("-sizes", 20, "-ranks", 1, "-run_in", 2, "-routes", "radius,dense"), ("| 20 |", 2)),
])
def test_benchmark_drivers(tmp_path, script, args, rows):
    out = tmp_path / "bench.md"
    r = run_script(script, *args, "-repeats", 1, "-output", out, timeout=600)
    assert r.returncode == 0, r.stderr
    needle, count = rows
    assert out.read_text().count(needle) == count


def test_bench_branch_labels_the_last_q_and_shows_a_disagreement(tmp_path):
    """The comparison column names q = pi/M, not pi/50; at M = 5 the SciPy route's large q steps reach another
    solution (max u differs by O(1)): each row beyond the stated tolerance is marked and a note says so."""
    out = tmp_path / "bench.md"
    r = run_script("bench_branch.py", "-cells", 100, "-M", 5, "-repeats", 1, "-scipy_timeout", 60, "-output", out,
                   timeout=600)
    assert r.returncode == 0, r.stderr
    text = out.read_text()
    assert "rel. diff of max u(pi/5) vs SciPy |" in text and "pi/50" not in text
    rows = [line.split("|")[-2].split() for line in text.splitlines() if line.startswith("| pi/100 |")]
    assert len(rows) == 5
    marked = [float(cell[0]) > 1e-8 for cell in rows]
    assert marked == [cell[-1] == "(!)" for cell in rows] and any(marked)
    assert "(!) max u(pi/5) differs from SciPy's by more than 1e-08" in text


def test_paper_pipeline_lists_its_steps():
    r = run_script("paper.py", "-help")
    assert r.returncode == 0 and "-steps branch,paper_table,convergence_h" in r.stdout
    assert "dynamics_figures" in r.stdout


def test_a_resume_continues_the_same_branch(tmp_path):
    out = tmp_path / "b.npz"
    args = ("-M", 10, "-cells_per_pi", 200, "-output", out)
    assert run_script("continuation.py", *args, "-q_stop", "0.6*pi").returncode == 0
    r = run_script("continuation.py", *args, "-resume")
    assert r.returncode == 0 and "resuming" in r.stdout, r.stderr
    assert len(Branch.load(str(out))) == 10 and math.isclose(Branch.load(str(out)).q[-1], math.pi / 10)


DRIVERS = sorted(f for f in os.listdir(SCRIPTS) if f.endswith(".py") and not f.startswith("bench"))


@pytest.mark.parametrize("script", DRIVERS)
def test_h_and_double_dash_help_are_help(script, tmp_path):
    """-h and --help, the spellings people try first, print the driver's -help (the same text), exit 0 and write
    nothing."""
    texts = []
    for flag in ("-h", "--help"):
        r = run_script(script, flag, cwd=tmp_path)
        assert r.returncode == 0 and not r.stderr and "Application options" in r.stdout, (flag, r.stderr)
        texts.append(r.stdout)
    assert texts[0] == texts[1] and list(tmp_path.iterdir()) == []
