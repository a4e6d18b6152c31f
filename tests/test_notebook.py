"""The notebook workflow (issue 40, item 3): plotting functions return Figures and write only when asked; hz.response
gives the driven chain's periodic responses at given frequencies with their multipliers, as the response curve
computes them; per-call solver options leave the options database as it was; the tutorial notebook
(docs/tutorial_notebook.py, jupytext percent format) runs as a script, serially and on 2 ranks."""
import math
import os
import re

import numpy as np
import pytest
from petsc4py import PETSc

import hertzpetsc as hz
from conftest import DATA, ROOT
from hertzpetsc import plotting
from hertzpetsc.branch import Branch
from hertzpetsc.driven import (Drive, HarmonicWave, PeriodicShooting, check_monodromy, conformal_rate,
                               damping_trace)
from hertzpetsc.errors import ConvergenceError, ParameterError
from hertzpetsc.studies.driven import ResponseCurve, ResponseParameters, tolerances_of

COMM = PETSc.COMM_WORLD
NOTEBOOK = os.path.join(ROOT, "docs", "tutorial_notebook.py")


def listing(path):
    return sorted(os.path.relpath(os.path.join(d, f), path) for d, _, files in os.walk(path) for f in files)


# --- 1. figures as objects ----------------------------------------------------------------------------------------
def test_plotting_functions_return_figures_and_write_only_when_asked(tmp_path, monkeypatch):
    """A few plotting functions of each kind (branch figures from the test's branch file, Floquet radius and
    multipliers, a driven response from records): each returns a matplotlib Figure with its axes drawn and writes
    nothing without a directory (fig.path None, the working directory left empty); with one, it writes exactly its
    file name there and says so in fig.path (the drivers' call)."""
    from matplotlib.figure import Figure
    monkeypatch.chdir(tmp_path)
    branch = Branch.load(os.path.join(DATA, "branch_alpha1.5.npz"))
    q = np.array([0.6, 0.9, 1.2])
    records = [dict(branch=0, periods=1, p=w, force_right=0.1 * w, rho=0.5 + 0.1 * w, amp_max=w, event=0,
                    confirmed=-1) for w in (0.5, 0.6, 0.7)]
    made = {"profiles.png": plotting.plot_branch_figures(branch)[0],
            "floquet.png": plotting.plot_floquet_radius(q, np.array([1.2, 1.0, 1.0]), 1e-4),
            "eigen.png": plotting.plot_multipliers([("1", np.exp(1j * q)), ("2", 1.1 * np.exp(1j * q))]),
            "driven_response.png": plotting.plot_driven_response(records, "omega")}
    for fig in made.values():
        assert isinstance(fig, Figure) and fig.path is None and fig.axes and fig.axes[0].has_data()
    assert listing(tmp_path) == []
    out = tmp_path / "figures"
    written = [plotting.plot_branch_figures(branch, str(out))[0],
               plotting.plot_floquet_radius(q, np.array([1.2, 1.0, 1.0]), 1e-4, str(out)),
               plotting.plot_multipliers([("1", np.exp(1j * q))], str(out)),
               plotting.plot_driven_response(records, "omega", str(out))]
    names = ["dispersplot.png", "driven_response.png", "eigen.png", "floquet.png", "lsq.png", "normes.png",
             "number.png", "pentes.png", "profiles.png"]          # the branch figures come as one call's six
    assert listing(out) == names
    for fig, name in zip(written, ("profiles.png", "floquet.png", "eigen.png", "driven_response.png")):
        assert isinstance(fig, Figure) and fig.path == str(out / name)


# --- 2. hz.response ---------------------------------------------------------------------------------------------
DRIVE = dict(N=12, amplitude=0.05, omega=0.5)


def damped_drive(**kw):
    """A precompressed chain with on-site damping (conformally symplectic flow: both closed forms apply)."""
    d = dict(DRIVE, **kw)
    return Drive(hz.LatticeModel.hertz(1.5, delta0=1.0, gamma=0.05), d["N"], HarmonicWave(), d["amplitude"], d["omega"])


def test_response_agrees_with_the_response_curve_and_its_multipliers_pass_the_closed_forms():
    """hz.response at the frequencies a pseudo-arclength response curve stepped to (ResponseCurve's records, another
    corrector: the arclength row, not the frequency, fixed) gives those responses: each satisfies
    ||P(X) - X||_inf <= tol scale, so two of them differ by at most 2 tol scale ||(R - I)^-1||_inf (R the
    monodromy); their multipliers, from the same resolved tangent flow at states that close, agree to 1e-8 (the
    flow's rtol 1e-12 times its ~1e3 steps and the eigenvalues' condition). The multipliers pass the closed forms:
    the monodromy at the response passes check_monodromy (Liouville, symplecticity) and its eigenvalues are the
    multipliers returned; their product is det R = exp(-T tr(M^-1 C)) and they pair as mu mu' = exp(-gamma T)."""
    drive = damped_drive()
    tol = 1e-10
    curve = ResponseCurve(ResponseParameters(drive, "omega", 0.8, tol=tol, run_in=20, samples=0, max_steps=4,
                                             nmult=2 * drive.N), COMM)
    try:
        records = [r for r in curve.run() if int(r["event"]) == 0]
    finally:
        curve.destroy()
    assert len(records) >= 4 and curve.ended is None
    omegas = [float(r["p"]) for r in records]
    responses = hz.response(drive, omegas, run_in=20, tol=tol, samples=0)
    assert [r.omega for r in responses] == omegas and len(responses) == len(records)
    for rec, r in zip(records, responses):
        assert r.residual <= tol and r.record["omega"] == r.omega
        prob = PeriodicShooting(r.drive, COMM, tol=tol, tolerances=tolerances_of(1e-12, drive.amplitude))
        try:
            R = prob.monodromy(r.x, r.omega)
            steps = prob.dense.flow.integrator.ts.getStepNumber()
            check_monodromy(R, r.drive.spec(), r.T, prob.tangent_rtol, steps, {"omega": r.omega})
            scale = prob.scale(r.x)
        finally:
            prob.destroy()
        bound = 2 * tol * scale * np.linalg.norm(np.linalg.inv(R - np.eye(2 * drive.N)), np.inf)
        assert np.max(np.abs(r.x - np.asarray(rec["x"]))) <= bound
        mu = r.multipliers
        assert len(mu) == 2 * drive.N and np.all(np.diff(np.abs(mu)) <= 0)
        assert np.max(np.abs(np.sort_complex(mu) - np.sort_complex(np.asarray(rec["multipliers"])))) < 1e-8
        assert np.max(np.abs(np.sort_complex(mu) - np.sort_complex(np.linalg.eigvals(R)))) < 1e-8
        assert r.rho == pytest.approx(float(rec["rho"]), abs=1e-8) and r.rho < 1
        spec = r.drive.spec()
        assert abs(np.sum(np.log(np.abs(mu))) + r.T * damping_trace(spec)) < 1e-8 * r.T * damping_trace(spec)
        pair = math.exp(-conformal_rate(spec) * r.T)
        assert max(np.min(np.abs(m * mu - pair)) for m in mu) < 1e-8


def test_response_errors_name_the_argument():
    drive = damped_drive()
    with pytest.raises(ParameterError, match="omega"):
        hz.response(drive, [0.5, 0.6, 0.5])
    with pytest.raises(ParameterError, match="omega"):
        hz.response(drive, -1.0)
    with pytest.raises(ParameterError, match="drive"):
        hz.response(drive.model, 0.5)


# --- 3. per-call solver options ---------------------------------------------------------------------------------
def test_per_call_options_change_the_solver_and_leave_the_database_as_it_was():
    """options= of an hz call is in the database for that call only: here Newton-Krylov instead of LU for the
    branch's SNES (tw_solver nk: GMRES iterations, one LU solve per Newton step without) and a tighter rtol than the
    one set globally, which is put back; the branch is the same to the solvers' tolerances (residuals <= 1e-8 on
    the h = pi/100 grid, where the profiles are O(1)); after a call that raises, and after a misspelt option (a
    ParameterError naming it), the database is exactly as before."""
    opts = PETSc.Options()
    opts.setValue("tw_snes_rtol", 1e-9)
    try:
        before = opts.getAll()
        lu = hz.compute_branch(M=4, cells_per_pi=100)
        nk = hz.compute_branch(M=4, cells_per_pi=100, options={"tw_solver": "nk", "-tw_snes_rtol": 1e-11})
        assert opts.getAll() == before
        assert all(p.solve.linear_iterations == p.solve.iterations for p in lu.points)
        assert all(p.solve.linear_iterations > p.solve.iterations for p in nk.points)
        assert np.max(np.abs(lu.column("norm_inf") - nk.column("norm_inf"))) < 1e-7
        with pytest.raises(ConvergenceError):
            hz.compute_branch(M=4, cells_per_pi=100, options={"tw_snes_max_it": 0})
        assert opts.getAll() == before
        with pytest.raises(ParameterError, match="options = 'tw_snes_rtl': not read"):
            hz.compute_branch(M=2, cells_per_pi=100, options={"tw_snes_rtl": 1e-3})
        assert opts.getAll() == before
        for bad in ({"tw snes": 1}, {"tw_snes_rtol": [1]}, ["tw_snes_rtol"], {"tw_snes_rtol": 1, "-TW_snes_rtol": 2}):
            with pytest.raises(ParameterError, match="options"):
                hz.compute_branch(M=2, cells_per_pi=100, options=bad)
        assert opts.getAll() == before
    finally:
        opts.delValue("tw_snes_rtol")


# --- 4. the tutorial notebook -----------------------------------------------------------------------------------
def notebook_cells():
    """[(the cell's '# %%' line, its body)] of the notebook, in order."""
    with open(NOTEBOOK) as f:
        parts = re.split(r"^(# %%.*)$", f.read(), flags=re.M)[1:]
    return list(zip(parts[0::2], parts[1::2]))


def test_the_tutorial_notebook_runs_and_makes_its_figures_as_objects(tmp_path, monkeypatch, capsys):
    """docs/tutorial_notebook.py is in jupytext's percent format (its header, markdown cells all comments) and runs
    as a script, cell by cell in one namespace: its figures are Figures; the unstable wave at q = pi/5 and the stable
    ones at 3pi/10 and 2pi/5 on 20 beads (q_c ~ 0.9, the paper's fig. floquet; rho - 1 below the verdict's 1e-4
    where stable); its driven responses are stable and their multipliers complete; only rank 0 writes and prints."""
    from matplotlib.figure import Figure
    with open(NOTEBOOK) as f:
        head = f.read(400)
    assert "format_name: percent" in head
    cells = notebook_cells()
    markdown = [body for marker, body in cells if marker == "# %% [markdown]"]
    assert len(markdown) >= 4 and all(line.startswith("#") for body in markdown for line in body.strip().splitlines())
    monkeypatch.chdir(tmp_path)
    scope = {"__name__": "__main__"}
    for _, body in cells:
        exec(compile(body, NOTEBOOK, "exec"), scope)
    for name in ("eigen", "response_figure"):
        assert isinstance(scope[name], Figure)
    assert all(isinstance(f, Figure) for f in scope["figures"])
    spectra = scope["spectra"]
    assert spectra[0].outside > 0 and all(s.rho - 1 < s.tol_rho for s in spectra[1:])
    responses = scope["responses"]
    assert all(r.rho < 1 and len(r.multipliers) == 2 * r.N and r.residual <= 1e-10 for r in responses)
    out = capsys.readouterr().out
    if COMM.getRank() == 0:
        assert listing(tmp_path) == ["driven_response.png", os.path.join("figures", "floquet.png")]
        assert out.count("omega = ") == len(responses) and "wrote driven_response.png" in out
    else:
        assert out == "" and listing(tmp_path) == []


# --- 5. progress with the time left -----------------------------------------------------------------------------
class Terminal:
    """A stream that says it is a terminal (or not), keeping what is written."""

    def __init__(self, tty):
        self.tty, self.text = tty, ""

    def isatty(self):
        return self.tty

    def write(self, s):
        self.text += s

    def flush(self):
        pass


def test_progress_estimates_the_time_left_on_rank_0_of_a_terminal_only():
    """Progress at the pace so far: after 30 s for 3 of 10 records (2 done before this run started) the time left
    is 30 s x 7 / 1; a line at most every interval seconds, none when the stream is not a terminal, none on the
    other ranks."""
    from hertzpetsc.progress import Progress, duration
    now = [0.0]
    tty = Terminal(True)
    p = Progress(10, "records", "scan", start=2, stream=tty, interval=20.0, clock=lambda: now[0])
    now[0] = 10.0
    assert p.update(2.5) is None                           # within the interval: nothing
    now[0] = 30.0
    line = p.update(3)
    assert p.left(3) == 30.0 * 7 / 1
    assert (line == "scan: 3/10 records, 30 s elapsed, about 3 min 30 s left at the pace so far"
            if COMM.getRank() == 0 else line is None)
    assert tty.text == (line + "\n" if line else "")
    assert p.update(4) is None and p.update(4, force=True) == (p.line(4) if COMM.getRank() == 0 else None)
    assert duration(7384) == "2 h 3 min" and duration(59.6) == "1 min 0 s"
    # a start of nan (a new long run's resumed_at: Open MPI's ranks write to a terminal even into a log file): a
    # line without an estimate, not a ValueError (hz.sh paper's long run at t = 240, after its first 30 s)
    unknown = Progress(10, "time units", start=float("nan"), stream=Terminal(True), clock=lambda: now[0])
    assert unknown.left(3) is None and unknown.update(3, force=True) in (None, unknown.line(3))
    pipe = Terminal(False)
    quiet = Progress(10, stream=pipe, interval=0.0, clock=lambda: now[0])
    assert quiet.update(5, force=True) is None and pipe.text == ""
