"""Driver scripts as subprocesses: the paper's branch, 2 ranks vs 1, resume, and one-line errors on bad input."""

import numpy as np
import pytest

from conftest import run_script
from hertzpetsc.branchfile import read_branch

pytestmark = pytest.mark.serial


@pytest.fixture(scope="module")
def paper_branch(tmp_path_factory):
    """The default run (alpha = 3/2, h = pi 1e-3, M = 50): about a second."""
    d = tmp_path_factory.mktemp("paper")
    r = run_script("continuation.py", "-output", d / "b.npz", "-figures", d / "fig")
    assert r.returncode == 0, r.stderr
    return d, r


def test_default_run_reproduces_the_paper_table(paper_branch):
    d, run = paper_branch
    assert len([l for l in run.stdout.splitlines() if l.startswith("  ")]) == 50   # one line per point
    r = run_script("paper_table.py", "-branch", d / "b.npz", "-output", d / "t.md")
    assert r.returncode == 0, r.stdout + r.stderr        # exit 1 if any number disagrees with the paper
    assert "NO" not in r.stdout
    assert sorted(p.name for p in (d / "fig").iterdir()) == sorted(
        f"{n}.png" for n in ("profiles", "normes", "pentes", "number", "lsq", "dispersplot"))


def test_two_ranks_give_the_one_rank_branch(paper_branch, tmp_path):
    d, _ = paper_branch
    r = run_script("continuation.py", "-output", tmp_path / "b2.npz", "-q_stop", "pi/5", ranks=2, timeout=300)
    assert r.returncode == 0, r.stderr
    one, two = read_branch(str(d / "b.npz")), read_branch(str(tmp_path / "b2.npz"))
    n = len(two["q"])
    assert n == 41 and two["meta"]["ranks"] == 2
    assert np.array_equal(one["q"][:n], two["q"])
    assert np.max(np.abs(one["u"][:n] - two["u"])) <= 1e-10 * np.max(np.abs(one["u"][:n]))


def test_killed_run_resumes(tmp_path):
    out = tmp_path / "b.npz"
    args = ("-M", 10, "-cells_per_pi", 200, "-output", out)
    assert run_script("continuation.py", *args, "-q_stop", "0.6*pi").returncode == 0
    first = read_branch(str(out))
    r = run_script("continuation.py", *args, "-resume")
    assert r.returncode == 0, r.stderr
    assert "resuming" in r.stdout
    resumed = read_branch(str(out))
    assert len(resumed["q"]) == 10 and np.array_equal(resumed["u"][:5], first["u"])
    assert run_script("continuation.py", *args, "-output", tmp_path / "c.npz").returncode == 0
    fresh = read_branch(str(tmp_path / "c.npz"))
    assert np.max(np.abs(fresh["u"] - resumed["u"])) <= 1e-10 * np.max(np.abs(fresh["u"]))


@pytest.mark.parametrize("args,needle", [
    (("-alpha", 1), "alpha"),
    (("-alpha", "x"), "alpha"),
    (("-M", 0), "-M"),
    (("-cells_per_pi", 3), "cells_per_pi"),
    (("-q_stop", 0), "q_stop"),
    (("-q_stop", "4"), "q_stop"),
    (("-q_stop", "1e-5"), "q_stop"),
    (("-resume", "-output", "missing.npz"), "does not exist"),
])
def test_bad_input_gives_one_line_and_nonzero_exit(tmp_path, args, needle):
    r = run_script("continuation.py", *args, cwd=tmp_path)
    assert r.returncode != 0
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and needle in lines[0], r.stderr


def test_resume_from_corrupt_or_foreign_file(tmp_path):
    (tmp_path / "bad.npz").write_bytes(b"garbage")
    r = run_script("continuation.py", "-resume", "-output", tmp_path / "bad.npz")
    assert r.returncode != 0 and r.stderr.strip().count("\n") == 0 and "corrupt" in r.stderr
    out = tmp_path / "b.npz"
    assert run_script("continuation.py", "-M", 5, "-cells_per_pi", 100, "-q_stop", "0.6*pi",
                      "-output", out).returncode == 0
    r = run_script("continuation.py", "-M", 5, "-cells_per_pi", 100, "-alpha", 2, "-resume", "-output", out)
    assert r.returncode != 0 and "alpha" in r.stderr and "stored" in r.stderr


def test_quasi_newton_reaches_the_solver_and_the_same_branch(paper_branch, tmp_path):
    r = run_script("continuation.py", "-q_stop", "pi/5", "-output", tmp_path / "b.npz",
                   "-tw_snes_monitor", "-tw_snes_type", "qn", "-tw_snes_view")
    assert r.returncode == 0, r.stderr
    assert "SNES Function norm" in r.stdout and "type: qn" in r.stdout
    newton, qn = read_branch(str(paper_branch[0] / "b.npz")), read_branch(str(tmp_path / "b.npz"))
    n = len(qn["q"])
    assert np.max(np.abs(newton["u"][:n] - qn["u"])) <= 1e-8 * np.max(np.abs(qn["u"]))


def test_divergence_is_reported_not_accepted(tmp_path):
    """SNES stopping on a small step far from a solution must not pass as converged."""
    r = run_script("continuation.py", "-M", 5, "-cells_per_pi", 100, "-q_stop", "0.6*pi", "-output",
                   tmp_path / "b.npz", "-tw_snes_type", "qn", "-tw_snes_qn_type", "broyden",
                   "-tw_snes_linesearch_type", "basic", "-tw_snes_divergence_tolerance", -1, "-tw_snes_max_it", 200)
    assert r.returncode == 3 and "continuation stopped" in r.stderr, r.stderr


def test_convergence_study_script(tmp_path):
    out = tmp_path / "conv.md"
    r = run_script("convergence_h.py", "-M", 10, "-cells", "100,200,400", "-output", out)
    assert r.returncode == 0, r.stderr
    rows = [l for l in out.read_text().splitlines() if l.startswith("| 3pi/10 | norm_inf")]
    assert len(rows) == 1 and abs(float(rows[0].split("|")[-3]) - 2) < 0.3   # observed order column
    assert run_script("convergence_h.py", "-cells", "100,200").returncode == 2


def test_benchmark_script(tmp_path):
    out = tmp_path / "bench.md"
    r = run_script("bench_branch.py", "-cells", 100, "-repeats", 1, "-M", 10, "-output", out, timeout=600)
    assert r.returncode == 0, r.stderr
    text = out.read_text()
    assert text.count("| pi/100 |") == 5 and "SciPy spsolve" in text and "hertzpetsc nk" in text
    # both routes solve the same discretisation: the last column (relative difference) is at round-off level
    assert all(float(l.split("|")[-2]) < 1e-10 for l in text.splitlines() if l.startswith("| pi/100 |"))
