"""docs/tutorial.md runs as written: its Python blocks, in order, as one script (serially and, in the suite's second
pass, on 2 ranks), in a temporary directory; its results are checked against closed forms and the results files
that the drivers wrote (the copies in tests/data; other routes and grids: tolerances below)."""
import math
import os
import re

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TUTORIAL = os.path.join(ROOT, "docs", "tutorial.md")


def tutorial_blocks():
    with open(TUTORIAL) as f:
        return re.findall(r"^```python\n(.*?)^```", f.read(), re.M | re.S)


def committed(name, q):
    with np.load(os.path.join(ROOT, "tests", "data", name)) as z:
        i = int(np.argmin(np.abs(z["q"] - q)))
        assert abs(z["q"][i] - q) < 1e-12
        return {k: z[k][i] for k in z.files if z[k].ndim and len(z[k]) == len(z["q"])}


def test_the_tutorial_runs_and_reproduces_the_committed_results(tmp_path, monkeypatch, capsys):
    from petsc4py import PETSc
    from hertzpetsc.binary import binary_oscillation

    blocks = tutorial_blocks()
    assert len(blocks) >= 6
    monkeypatch.chdir(tmp_path)
    scope, first = {}, {}
    for block in blocks:                                     # one namespace, as one script; keep each name's first value
        exec(compile(block, TUTORIAL, "exec"), scope)
        first.update({k: v for k, v in scope.items() if k not in first})
    branch, spectrum, row = first["branch"], first["spectrum"], scope["row"]
    # 1. the branch starts on the binary oscillation (lemma binary): ||u0||_inf = u0(pi/2), to the scheme's O(h^2)
    #    at h = pi/400 (h^2 = 6e-5; the error constant is below 1)
    assert len(branch) == 10 and branch.q[0] == math.pi
    assert abs(branch.column("norm_inf")[0] - binary_oscillation(1.5, np.array([math.pi / 2]))[0]) < 1e-4
    # 3. q = pi/5 on 100 beads: the refined orbit is the one of results/floquet_N100.npz (made from the h = pi/1000
    #    branch) up to its scale and phase, to which the multipliers are blind; they agree to the flows' accuracy
    #    (rtol 1e-12 over script-T: 1e-8 relative on rho, an unstable multiplier well separated)
    ref = committed("floquet_N100.npz", math.pi / 5)
    assert abs(spectrum.rho - ref["rho"]) < 1e-8 * ref["rho"] and spectrum.outside == ref["outside"]
    # 5. the trimer's record on 60 beads is results/wave.npz's (same grid, A, tolerances; refined there on 60 beads,
    #    here on 30 and tiled): the flows' accuracy again
    wave = committed("wave.npz", 2 * math.pi / 15)
    assert abs(row["rho_sizes"][0] - wave["rho"]) < 1e-8
    assert scope["spectrum"].rho - 1 < 1e-10                 # 30 beads: no unstable sector (the last block's rho)
    out = capsys.readouterr().out
    if PETSc.COMM_WORLD.getRank() == 0:
        assert os.path.getsize(tmp_path / "tutorial_multipliers.png") > 10_000
        assert out.count("q = ") == 11 and "trimer: omega = " in out
    else:
        assert out == ""                                     # only rank 0 prints


def test_the_api_page_lists_the_public_surface():
    """docs/api.md names every name of hertzpetsc.__all__ in its tables, and nothing the package does not export; no
    exported name is shadowed by a submodule of the same name (``import hertzpetsc.<name>`` would replace it)."""
    import hertzpetsc as hz

    with open(os.path.join(ROOT, "docs", "api.md")) as f:
        text = f.read()
    rows = [line for line in text.splitlines() if line.startswith("| `")]
    listed = set()
    for line in rows:
        first = line.split(" | ")[0]
        listed |= {re.match(r"(?:hz\.)?(\w+)", name).group(1) for name in re.findall(r"`([^`]+)`", first)}
    assert listed == set(hz.__all__), (sorted(listed - set(hz.__all__)), sorted(set(hz.__all__) - listed))
    package = os.path.join(ROOT, "hertzpetsc")
    modules = {os.path.splitext(n)[0] for n in os.listdir(package)} - {"__init__"}
    assert not set(hz.__all__) & modules
    for name in hz.__all__:
        assert getattr(hz, name) is not None


def test_the_release_0_1_snippet_still_runs(tmp_path, monkeypatch, capsys):
    """The module-level Python of release 0.1 (docs/running.md, "From Python") runs as written: a branch at alpha = 2,
    one refined wave at 7pi/25 on 100 beads and its rho, which is the committed Floquet table's (the same refined
    orbit up to scale and phase, to which multipliers are blind: the flows' accuracy, 1e-8)."""
    with open(os.path.join(ROOT, "docs", "running.md")) as f:
        text = f.read()
    block = re.findall(r"^```python\n(.*?)^```", text[text.index("## From Python"):], re.M | re.S)[0]
    (tmp_path / "results").mkdir()                            # it reads results/branch_alpha1.5.npz: the test's copy
    os.symlink(os.path.join(ROOT, "tests", "data", "branch_alpha1.5.npz"), tmp_path / "results" / "branch_alpha1.5.npz")
    monkeypatch.chdir(tmp_path)
    exec(compile(block, "docs/running.md", "exec"), {})
    out = capsys.readouterr().out.split()
    rho = float(out[-1])
    assert abs(rho - committed("floquet_N100.npz", 7 * math.pi / 25)["rho"]) < 1e-8


def test_the_readme_python_block_prints_what_it_says(tmp_path, monkeypatch, capsys):
    """The README's Python block runs, and the numbers its comments quote are the ones it prints (to the digits
    quoted)."""
    with open(os.path.join(ROOT, "README.md")) as f:
        block = re.findall(r"^```python\n(.*?)^```", f.read(), re.M | re.S)[0]
    monkeypatch.chdir(tmp_path)
    exec(compile(block, "README.md", "exec"), {})
    printed = [float(x) for x in capsys.readouterr().out.split()]
    quoted = [re.search(r"# [^#]*?(\d+\.\d+) \(", line).group(1) for line in block.splitlines() if "print(" in line]
    assert len(printed) == len(quoted) == 2
    for value, text in zip(printed, quoted):
        decimals = len(text.split(".")[1])
        assert round(value, decimals) == float(text), (value, text)
