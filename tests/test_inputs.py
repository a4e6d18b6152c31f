"""Records never mix their inputs, and a table never says more than its rows: every file input of every driver
refuses a file of another kind in one error line naming the option; a resume from another input file or with solver
options that change numbers is refused naming them (by the run and by -check); a table of the paper's numbers, a
reference rho, a map drawn beside a boundary or a table of long runs refuses a file of another Hertz exponent; a
table's header states the brackets its rows show. Serially and on 2 ranks (each case ends within seconds)."""
import concurrent.futures
import math
import os
import shutil

import numpy as np
import pytest

from conftest import DATA, one_error_line, run_script

pytestmark = pytest.mark.serial

BRANCH = os.path.join(DATA, "branch_alpha1.5.npz")
REFINED = os.path.join(DATA, "refined_N100.npz")
FLOQUET = os.path.join(DATA, "floquet_N100.npz")
MAP = os.path.join(DATA, "stability_boundary_alpha2_N100.npz")

# (driver, the option of a file input, arguments that make the rest of the command valid); the files of the other
# inputs are the driver's defaults, results/..., which the tests' checkout holds (conftest.checkout)
INPUTS = [
    ("refine_branch.py", "branch", ()),
    ("floquet_scan.py", "branch", ()), ("floquet_scan.py", "refined", ()),
    ("floquet_long.py", "branch", ()), ("floquet_long.py", "refined", ()), ("floquet_long.py", "reference", ()),
    ("long_run.py", "branch", ()), ("long_run.py", "refined", ()),
    ("long_wave.py", "branch", ()), ("compactons.py", "branches", ()), ("paper_table.py", "branch", ()),
    ("slow_instabilities.py", "branch", ()), ("slow_instabilities.py", "refined", ()),
    ("slow_instabilities.py", "reference", ()),
    ("compacton_stability.py", "branches", ()), ("compacton_dynamics.py", "stability", ()),
    ("compacton_dynamics.py", "pairs_branch", ()),
    ("driven_wave_ends.py", "branch", ("-rtols", "1e-12")), ("driven_wave_ends.py", "refined", ("-rtols", "1e-12")),
    ("driven_generation.py", "branch", ()),
    ("precompression_map.py", "compare", ()), ("precompression_map.py", "output", ("-render",)),
    ("boundary_in_q.py", "map", ()), ("boundary_in_q.py", "output", ("-render",)),
    ("dynamics_figures.py", "runs", ()),
    ("bench_chain.py", "branch", ()), ("bench_floquet.py", "branch", ()), ("bench_floquet.py", "refined", ()),
    ("bench_stability.py", "branch", ()),
]


def _other_kind(option, tmp_path):
    """A file of another kind than the option reads: a Floquet file, or a branch file where a Floquet file is
    read; a directory that holds no run where a run directory is."""
    return str(tmp_path) if option == "runs" else BRANCH if option == "reference" else FLOQUET


@pytest.mark.parametrize("ranks", [1, 2])
def test_every_file_input_refuses_a_file_of_another_kind_naming_the_option(tmp_path, ranks):
    """Each driver's each file input, given a file of another kind: status 4 and one error line that names the
    option, with -check (the run refuses it at the same place, before any computation: -check stops after it)."""
    def one(case):
        script, option, extra = case
        r = run_script(script, *extra, f"-{option}", _other_kind(option, tmp_path), "-check", ranks=ranks,
                       timeout=120)
        try:
            line = one_error_line(r)
        except AssertionError:
            return f"{script} -{option}: status {r.returncode}, {r.stderr.strip()[-300:] or r.stdout[-300:]}"
        if r.returncode != 4 or f"-{option}" not in line:
            return f"{script} -{option}: status {r.returncode}, {line}"
        return None

    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        bad = [b for b in pool.map(one, INPUTS) if b]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("ranks", [1, 2])
def test_a_resume_of_the_wave_ends_from_another_refinement_or_other_tolerances_is_refused(tmp_path, ranks):
    """driven_wave_ends.py: the file records the content hashes of its branch and refinement files and the options
    of -drive_ and -floquet_ that change numbers; a resume from another -refined file (another content under a new
    name), or with another -drive_ts_rtol, is refused in one line naming the option, by the run and by -check, and
    the file is left as it was; a resume with the same inputs continues it."""
    other = tmp_path / "refined_copy.npz"
    shutil.copy(REFINED, other)
    with open(other, "ab") as f:                    # another file: a zip archive with one byte more still loads
        f.write(b"\0")
    args = ["-branch", BRANCH, "-q", "2*pi/5", "-sizes", 4, "-rtols", "1e-12", "-samples", 256,
            "-output", tmp_path / "w.npz", "-table", tmp_path / "w.md"]
    r = run_script("driven_wave_ends.py", "-refined", REFINED, *args, ranks=ranks, timeout=300)
    assert r.returncode == 0, r.stderr
    before = (tmp_path / "w.npz").read_bytes()
    with np.load(tmp_path / "w.npz") as z:
        assert len(str(z["refined_sha256"])) == 64 and str(z["solver_options"]) == ""
    for check in ((), ("-check",)):
        r = run_script("driven_wave_ends.py", "-refined", other, *args, "-resume", *check, ranks=ranks)
        line = one_error_line(r)
        assert r.returncode == 4 and "refined_sha256" in line and "(-refined)" in line, line
        r = run_script("driven_wave_ends.py", "-refined", REFINED, *args, "-resume", "-drive_ts_rtol", "1e-9", *check,
                       ranks=ranks)
        line = one_error_line(r)
        assert r.returncode == 4 and "solver_options" in line and "drive_ts_rtol=1e-9" in line, line
    assert (tmp_path / "w.npz").read_bytes() == before
    r = run_script("driven_wave_ends.py", "-refined", REFINED, *args, "-resume", ranks=ranks)
    assert r.returncode == 0, r.stderr


def test_a_driven_response_resumed_with_other_tolerances_is_refused(tmp_path):
    """driven_response.py (no input file): a resume with another -floquet_ts_rtol is refused naming it; a monitor
    changes no number and is accepted."""
    args = ["-N", 2, "-omega", 1.69, "-p_end", 1.68, "-run_in", 2, "-max_steps", 2, "-output", tmp_path / "r.npz",
            "-table", tmp_path / "r.md"]
    r = run_script("driven_response.py", *args)
    assert r.returncode == 0, r.stderr
    r = run_script("driven_response.py", *args, "-resume", "-floquet_ts_rtol", "1e-10")
    line = one_error_line(r)
    assert r.returncode == 4 and "floquet_ts_rtol=1e-10" in line and "-floquet_*" in line, line
    r = run_script("driven_response.py", *args, "-resume", "-drive_snes_monitor", "-check")
    assert r.returncode == 0 and r.stdout.startswith("check: "), r.stderr


def _branch(tmp_path, alpha):
    """A coarse branch file of another alpha (h = pi/100, q = m pi/10 down to pi/5), made by the driver."""
    path = tmp_path / f"branch_alpha{alpha:g}.npz"
    r = run_script("continuation.py", "-alpha", alpha, "-M", 10, "-cells_per_pi", 100, "-q_stop", "pi/5", "-output",
                   path, timeout=120)
    assert r.returncode == 0, r.stderr
    return path


@pytest.mark.parametrize("ranks", [1, 2])
def test_a_table_never_takes_a_file_of_another_alpha(tmp_path, ranks):
    """The paper's table refuses a branch of alpha = 2; a Floquet reference (floquet_long, slow_instabilities) of
    alpha = 3/2 is refused for a branch of alpha = 2, and so are refined waves of 3/2; a stability map of another
    chain is not drawn beside a boundary in q (computing or -render); long runs of two exponents make no table."""
    b2 = _branch(tmp_path, 2.0)
    out = ["-check"]
    cases = [("paper_table.py", ("-branch", b2), "-branch", "alpha = 2"),
             ("floquet_long.py", ("-branch", b2, "-refined", REFINED, "-q", "2*pi/5", "-sizes", 200), "-refined",
              "alpha = 1.5"),
             ("slow_instabilities.py", ("-branch", b2, "-q", "2*pi/5", "-validate", "2*pi/5"), "-reference",
              "alpha = 1.5"),
             ("floquet_scan.py", ("-branch", b2, "-refined", REFINED), "-refined", "alpha = 1.5"),
             ("driven_wave_ends.py", ("-branch", b2, "-refined", REFINED, "-q", "2*pi/5", "-rtols", "1e-12"),
              "-refined", "alpha = 1.5"),
             ("boundary_in_q.py", ("-alpha", 1.5, "-map", MAP), "-map", "alpha = 2.0 there"),
             ("boundary_in_q.py", ("-delta0", 0.5, "-alpha", 2, "-map", MAP), "-map", "delta0 = 1.0 there"),
             ("boundary_in_q.py", ("-render", "-output", os.path.join(DATA, "boundary_in_q_alpha1.5.npz"), "-map",
                                   MAP), "-map", "alpha = 2.0 there")]
    for script, args, option, needle in cases:
        r = run_script(script, *args, *out, ranks=ranks)
        line = one_error_line(r)
        assert r.returncode == 4 and f"({option})" in line and needle in line, (script, line)
    if ranks > 1:
        return
    # long runs of two exponents
    runs = []
    for alpha, branch in ((1.5, BRANCH), (2.0, b2)):
        runs.append(tmp_path / f"run{alpha:g}")
        r = run_script("long_run.py", "-branch", branch, "-q", "2*pi/5", "-N", 10, "-t_final", 2, "-output", runs[-1])
        assert r.returncode == 0, r.stderr
    r = run_script("dynamics_figures.py", "-runs", ",".join(map(str, runs)), "-figures", tmp_path, "-table",
                   tmp_path / "t.md")
    line = one_error_line(r)
    assert r.returncode == 2 and "-runs" in line and "alpha = 1.5, 2" in line, line
    assert not (tmp_path / "t.md").exists()


def test_a_table_claims_the_brackets_its_rows_show():
    """The headers of a stability map and of a boundary in q state the largest relative bracket of their located
    edges, computed from the rows (an edge left wide, e.g. by the cell limit of the bisection in q, is said), next to
    the bracket that was asked for."""
    from hertzpetsc.studies import maps
    z = {k: np.array(v) for k, v in maps.read_map(MAP).items()}
    edges = np.nonzero((z["kind"] == maps.KIND_EDGE) | (z["kind"] == maps.KIND_EDGE_INF))[0]
    widths = np.abs(z["A_unstable"][edges] - z["A_stable"][edges]) / np.minimum(z["A_stable"][edges],
                                                                               z["A_unstable"][edges])
    head = maps.map_table(z).splitlines()[0]
    assert f"the {len(edges)} located edges within brackets of at most {widths.max():.1e}" in head
    assert "asked to a bracket of 0.001" in head
    i = edges[0]                                   # one edge left ten times wider than asked
    z["A_unstable"][i] = z["A_stable"][i] * (1 + 0.01)
    assert "within brackets of at most 1.0e-02" in maps.map_table(z).splitlines()[0]
    zq = dict(kind=np.array([maps.KIND_EDGE_INF, maps.KIND_EDGE_INF, 0]), q_stable=np.array([1.0, 2.0, math.nan]),
              q_unstable=np.array([1.001, 2.0056, math.nan]))
    assert maps._brackets(zq["q_stable"], zq["q_unstable"], zq["kind"] == maps.KIND_EDGE_INF, "q") == \
        "the 2 located edges within brackets of at most 2.8e-03 (relative, in q)"
    assert maps._brackets(zq["q_stable"], zq["q_unstable"], zq["kind"] == 99, "q") == "no edge located"
