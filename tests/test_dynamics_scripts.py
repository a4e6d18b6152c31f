"""Section 3.4 drivers as subprocesses: refinement table, long runs with snapshots, resume, bad input."""
import json
import math

import numpy as np
import pytest

from conftest import ROOT, run_script
from hertzpetsc.branchfile import read_refined
from hertzpetsc.simulation import SnapshotFile

pytestmark = pytest.mark.serial


@pytest.fixture(scope="module")
def coarse_branch(tmp_path_factory):
    d = tmp_path_factory.mktemp("branch")
    r = run_script("continuation.py", "-M", 10, "-cells_per_pi", 200, "-q_stop", "0.3*pi", "-output", d / "b.npz")
    assert r.returncode == 0, r.stderr
    return d / "b.npz"


def test_refinement_script(coarse_branch, tmp_path):
    out = tmp_path / "ref.npz"
    args = ("-branch", coarse_branch, "-N", 20, "-output", out, "-table", tmp_path / "t.md", "-figures", tmp_path)
    r = run_script("refine_branch.py", *args, "-q", "0.4*pi")
    assert r.returncode == 0, r.stderr
    r = run_script("refine_branch.py", *args, "-resume")          # adds the missing q, keeps the first
    assert r.returncode == 0, r.stderr
    data = read_refined(str(out))
    assert sorted(np.round(data["q"] / math.pi * 10).astype(int)) == list(range(3, 11))   # q = 2 pi m / 20
    assert np.all(data["E_after"] <= 1e-10) and np.all(data["E_before"] > 1e-7)
    assert (tmp_path / "errors.png").exists() and "| 1.2566 |" in (tmp_path / "t.md").read_text()


def test_long_run_resumes_to_the_same_trajectory(coarse_branch, tmp_path):
    common = ("-branch", coarse_branch, "-q", "0.4*pi", "-N", 20, "-snapshots_per_T", 2)
    r = run_script("long_run.py", *common, "-t_final", 10, "-output", tmp_path / "a")
    assert r.returncode == 0, r.stderr
    run_script("long_run.py", *common, "-t_final", 5, "-output", tmp_path / "b")
    with open(tmp_path / "b" / "snapshots.f64", "ab") as f:          # a killed run: half a record in flight
        f.write(b"\0" * 100)
    r = run_script("long_run.py", *common, "-t_final", 10, "-output", tmp_path / "b", "-resume")
    assert r.returncode == 0 and "resuming" in r.stdout, r.stderr
    hdr = json.loads((tmp_path / "a" / "run.json").read_text())
    ta, Ea, Xa = SnapshotFile(str(tmp_path / "a"), hdr).read()
    tb, Eb, Xb = SnapshotFile(str(tmp_path / "b"), hdr).read()
    assert np.array_equal(ta, tb)
    # the resumed run restarts its step-size controller at the snapshot: same trajectory to rtol x steps
    assert np.max(np.abs(Xa - Xb)) < 1e-9
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary["energy_drift"] < 1e-9 and summary["max_deviation"] < 1e-3
    assert math.isnan(summary["destruction_time"])


def test_long_run_refuses_snapshots_of_another_run(coarse_branch, tmp_path):
    common = ("-branch", coarse_branch, "-N", 20, "-t_final", 3, "-output", tmp_path / "a")
    assert run_script("long_run.py", *common, "-q", "0.4*pi").returncode == 0
    r = run_script("long_run.py", *common, "-q", "0.6*pi", "-resume")
    assert r.returncode == 4 and "another run" in r.stderr and len(r.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("args,needle", [
    (("-N", 21, "-q", "0.4*pi"), "N q / (2 pi)"),
    (("-q", "0.45*pi", "-N", 20), "no point at q"),
    (("-t_final", -1), "t_final"),
    (("-t_final", 0), "t_final"),
    (("-chain_ts_rtol", "0"), "rtol"),
    (("-chain_ts_atol", "-1e-3"), "atol"),
])
def test_long_run_bad_input(coarse_branch, tmp_path, args, needle):
    base = {"-N": 20, "-q": "0.4*pi", "-t_final": 2}
    base.update(dict(zip(args[::2], args[1::2])))
    flat = [str(a) for kv in base.items() for a in kv]
    r = run_script("long_run.py", "-branch", coarse_branch, "-output", tmp_path / "x", *flat)
    assert r.returncode != 0
    assert needle in r.stderr and r.stderr.strip().splitlines()[-1].startswith("error:"), r.stderr


def test_dynamics_figures_script(coarse_branch, tmp_path):
    run = tmp_path / "r"
    assert run_script("long_run.py", "-branch", coarse_branch, "-q", "0.4*pi", "-N", 20, "-t_final", 6,
                      "-output", run).returncode == 0
    r = run_script("dynamics_figures.py", "-runs", f"{run}:0:6", "-figures", tmp_path / "f", "-table",
                   tmp_path / "t.md")
    assert r.returncode == 0, r.stderr
    assert {p.name for p in (tmp_path / "f").iterdir()} == {"r_snapshot.png", "r_forces.png", "deviation.png"}
    assert "| r | 1.2566 |" in (tmp_path / "t.md").read_text()
    assert run_script("dynamics_figures.py", "-runs", tmp_path / "missing").returncode == 4


def test_chain_benchmark_script(tmp_path):
    out = tmp_path / "b.md"
    r = run_script("bench_chain.py", "-branch", f"{ROOT}/results/branch_alpha1.5.npz", "-sizes", 20,
                   "-repeats", 1, "-output", out, timeout=600)
    assert r.returncode == 0, r.stderr
    text = out.read_text()
    assert text.count("| 20 |") == 3 and "| 2 |" in text
    assert run_script("bench_chain.py", "-sizes", 30).returncode == 2


def test_solitary_wave_script(tmp_path):
    out = tmp_path / "s.md"
    r = run_script("solitary_wave.py", "-alphas", "1.5", "-cells", "10,20,40", "-lengths", "5,6", "-output", out,
                   "-figures", tmp_path)
    assert r.returncode == 0, r.stderr
    text = out.read_text()
    assert "| k_alpha (L = 8) | 1.350" in text and (tmp_path / "ondesol.png").exists()
    assert run_script("solitary_wave.py", "-cells", "10,20").returncode == 2


def test_long_wave_script(tmp_path):
    out = tmp_path / "lw.md"
    r = run_script("long_wave.py", "-branch", f"{ROOT}/results/branch_alpha1.5.npz", "-cells_per_unit", 20,
                   "-output", out, "-figures", tmp_path)
    assert r.returncode == 0, r.stderr
    assert "| 0.0628 |" in out.read_text() and (tmp_path / "approxz.png").exists()
    assert run_script("long_wave.py", "-window", 4).returncode == 2


def test_compacton_script_table_and_bad_input(coarse_branch, tmp_path):
    """Section 3.3 driver under mpiexec -n 2: the table has both cases with beads ahead exactly at rest; a q above
    q_k and a negative theta are refused in one line with exit status 2."""
    common = ("-branches", coarse_branch, "-margin", 4, "-travel", 20, "-dt_snapshot", 0.1)
    out = tmp_path / "c.md"
    r = run_script("compactons.py", *common, "-q", "0.3*pi", "-output", out, "-figures", tmp_path, ranks=2)
    assert r.returncode == 0, r.stderr
    rows = [l for l in out.read_text().splitlines() if l.startswith("| pi/200 ")]
    assert len(rows) == 2 and all(l.split("|")[7].strip() == "0.0e+00" for l in rows)
    assert (tmp_path / "graphulin.png").exists() and (tmp_path / "compacton2_spacetime.png").exists()
    for bad, what in ((("-q", "0.7*pi"), "q_k"), (("-q", "0.3*pi", "-theta", "-3"), "spacings")):
        r = run_script("compactons.py", *common, *bad, "-output", tmp_path / "x.md")
        assert r.returncode == 2 and what in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
