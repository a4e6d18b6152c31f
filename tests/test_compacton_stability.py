"""Isolated compactons on the travelling window (hertzpetsc.compacton_window, studies.compacton_stability).

Small windows (M = 12, 3 resting beads behind the compression zone) around compactons of the committed branch
(h = pi/1000). The refinement converges to max|G(Y) - Y| ~ 1e-14 (measured 7e-15 at q = pi/5, M = 12);
tolerances below leave a factor >= 10 over the flows' errors (rtol 1e-13 to 1e-14 on positions of order D ~ 3-14).
"""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import DATA, one_error_line, run_script
from hertzpetsc.branch import Branch
from hertzpetsc.chain import Chain, ChainIntegrator, IntegrationTolerances
from hertzpetsc.compacton_spectrum import WindowStability, eigenvector, jordan_check, sorted_eig, split_jordan_pair
from hertzpetsc.compacton_window import CompactonRefiner, CompactonWindow, embed, guess_from_branch
from hertzpetsc.errors import ParameterError
from hertzpetsc.model import ChainSpec, LatticeModel
from hertzpetsc.studies.compacton_dynamics import CompactonDynamics
from hertzpetsc.records import read_kind
from hertzpetsc.studies.compacton_dynamics import DYNAMICS_KIND
from hertzpetsc.studies.compacton_stability import STABILITY_KIND, exact_compacton

BRANCH = f"{DATA}/branch_alpha1.5.npz"
M, REAR = 12, 3
Q = math.pi / 5                      # mu_3 = 0.211 lies above 2 exp(-eta) = 0.164: SLEPc can be asked for it


def bead_indices(beads):
    """Bead-major state indices (2 j, 2 j + 1) of the given beads."""
    beads = np.asarray(beads)
    return np.stack([2 * beads, 2 * beads + 1], axis=1).ravel()


@pytest.fixture(scope="module")
def branch():
    return Branch.load(BRANCH)


@pytest.fixture(scope="module")
def compacton(branch):
    """The exact compacton at q = pi/5 in an M = 12 window (COMM_SELF), its window and Jacobian."""
    w = CompactonWindow(branch.model, M, PETSc.COMM_SELF)
    Y, gap = guess_from_branch(branch.point(Q), M, REAR, branch.q_k())
    ex = CompactonRefiner(w).refine(Y, gap, Q)
    _, J, _ = w.jacobian(ex.Y, ex.gap)
    yield ex, w, J, w.residual(Y, gap)
    w.destroy()


def test_refinement_meets_its_conditions(compacton):
    ex, w, J, unrefined = compacton
    assert unrefined > 1e-6                          # the branch profile is not a fixed point (measured 2.8e-5)
    assert ex.residual <= 1e-12                      # Gauss-Newton to the flow's error (measured 7e-15)
    # q enters only through D / Delta = 2 pi / q (eqs. extens, defvit): the refined pair satisfies it
    assert math.isclose(2 * math.pi * ex.gap / ex.D, Q, rel_tol=1e-12)
    # beads ahead at rest on the lattice (y = 0), beads behind at rest, displaced by D
    assert np.max(np.abs(ex.Y[-2:])) < 1e-13 and np.max(np.abs(ex.Y[:2, 1])) < 1e-12
    assert abs(ex.Y[0, 0] - ex.Y[1, 0]) < 1e-12


def test_residual_checked_by_an_independent_integration(compacton, branch):
    """The refined window on a longer free chain in lab coordinates (chain.Chain, x_n = Delta n + y_n, a 7(6) pair
    at another tolerance): one unit of time moves every bead's state to the next bead's."""
    ex, *_ = compacton
    N = M + 10
    spec = ChainSpec(branch.model, N, "free")
    chain = Chain(spec, PETSc.COMM_WORLD)
    integ = ChainIntegrator(chain, IntegrationTolerances(rtol=1e-13, atol=1e-16), prefix="test_cwin_check_",
                            rk_type="7vr")
    n0 = 4
    y = np.zeros((N, 2))
    y[:n0, 0] = ex.D
    y[n0:n0 + M] = ex.Y
    x0 = y.copy()
    x0[:, 0] += ex.gap * np.arange(N)
    X = chain.create_state()
    chain.set_from_array(X, x0)
    integ.integrate(X, 0.0, 1.0, dt=integ.initial_step)
    x1 = chain.gather(X)
    X.destroy(), integ.destroy(), chain.destroy()
    y1 = x1.copy()
    y1[:, 0] -= ex.gap * np.arange(N)
    # bead n + 1 at t = 1 is bead n at t = 0 (c = 1), over the window and its rest
    err = np.max(np.abs(y1[1:] - y[:-1]))
    assert err < 1e-11 * max(1.0, ex.D), err          # measured 9e-14


def test_translation_multiplier_is_a_jordan_block_at_one(compacton):
    ex, w, J, _ = compacton
    lam, _ = sorted_eig(J)
    mean, split, rest = split_jordan_pair(lam)
    # a defective pair splits by ~ sqrt(error) (measured 1e-7): only its mean is accurate to the residual's order
    assert abs(mean - 1) < 1e-11 and split < 1e-5
    jc = jordan_check(w, J, ex.Y, ex.gap)
    assert jc.translation < 1e-11 and jc.generalized < 1e-11        # J v1 = v1, (J - 1) v2 = v1 solvable
    # the left vectors reproduce the block: u_i . v_j = delta_ij
    V = np.array([[jc.u1 @ jc.v1, jc.u1 @ jc.v2], [jc.u2 @ jc.v1, jc.u2 @ jc.v2]])
    assert np.allclose(V, np.eye(2), atol=1e-10)
    # the geometric multiplicity is 1: a single small singular value of J - 1
    s = np.linalg.svd(J - np.eye(len(J)), compute_uv=False)
    assert s[-1] < 1e-11 < 1e-4 < s[-2]
    assert np.all(np.abs(rest) < 1)                                # the isolated compacton: no unstable multiplier


def test_block_structure_and_window_independence(compacton, branch):
    """spec(J) = {0} U spec(core block), and the nonzero multipliers do not change when the window grows."""
    ex, w, J, _ = compacton
    lam = sorted_eig(J)[0]
    core = bead_indices(w.core(ex.Y, ex.gap))
    lam_core = sorted_eig(J[np.ix_(core, core)])[0]
    k = len(lam_core)
    m, _, r = split_jordan_pair(lam)
    mc, _, rc = split_jordan_pair(lam_core)
    assert abs(m - mc) < 1e-11 and np.max(np.abs(r[:k - 2] - rc)) < 1e-10     # measured 0 (same block)
    assert np.max(np.abs(r[k - 2:])) < 1e-6                       # the transport part: nilpotent (LAPACK: ~0)
    # the front buffer is exactly a truncated shift composed with free flight (no coupling at all)
    front = bead_indices(np.arange(w.core(ex.Y, ex.gap)[-1] + 1, M))
    block = J[np.ix_(front, front)]
    expected = np.zeros_like(block)
    for j in range(len(front) // 2 - 1):
        expected[2 * j:2 * j + 2, 2 * j + 2:2 * j + 4] = [[1.0, 1.0], [0.0, 1.0]]
    assert np.max(np.abs(block - expected)) < 1e-13
    M2 = M + 6
    w2 = CompactonWindow(branch.model, M2, PETSc.COMM_SELF)
    try:
        ex2 = CompactonRefiner(w2).refine(embed(ex.Y, M2, 3), ex.gap, Q)
        lam2 = sorted_eig(w2.jacobian(ex2.Y, ex2.gap)[1])[0]
    finally:
        w2.destroy()
    m1, _, r1 = split_jordan_pair(lam)
    m2, _, r2 = split_jordan_pair(lam2)
    assert abs(m1 - m2) < 1e-11 and np.max(np.abs(r1[:3] - r2[:3])) < 1e-10      # measured 5e-14


def test_dense_and_slepc_multipliers_agree(compacton):
    ex, w, J, _ = compacton
    lam = sorted_eig(J)[0]
    core = w.core(ex.Y, ex.gap)
    stab = WindowStability(w, nev=3, eta=2.5)
    try:
        sl = stab.solve(ex.Y, ex.gap, 0.5 * (core[0] + core[-1]))
    finally:
        stab.destroy()
    mean_s, _, rest_s = split_jordan_pair(sl.multipliers[:3])
    mean_d, _, rest_d = split_jordan_pair(lam)
    assert abs(mean_s - mean_d) < 1e-9                  # the defective pair: means (SLEPc's split is ~1e-7)
    assert abs(rest_s[0] - rest_d[0]) < 1e-10          # mu_3 (measured agreement 2.5e-13)
    assert np.max(sl.work["errors"][:3]) < 1e-10 and sl.work["products"] < 200


def test_least_stable_mode_of_the_solitary_wave_at_alpha_2():
    """Behind the solitary wave (committed record, alpha = 2) the rear bonds are closed by doubly exponentially small
    amounts, so J's rear columns are tiny but nonzero; dgeev's vector of mu_3 (balancing) was then nearly a rear-bead
    unit vector, which leaves the window in one period (the dynamics' |rest| fell from 1e-8 to 1e-14 at k = 1).
    The eigenvector is J's, and on the chain the perturbation along it shrinks by |mu_3| per bead."""
    d = np.load(f"{DATA}/compacton_stability.npz")
    i = int(np.nonzero((d["alpha"] == 2.0) & (d["q"] == 0.0))[0][0])
    rec = {k: d[k][i] for k in ("alpha", "q", "gap", "residual", "iterations", "dominant", "state")}
    ex = exact_compacton(rec)
    model = LatticeModel.hertz(2.0)
    w = CompactonWindow(model, ex.M, PETSc.COMM_SELF)
    try:
        J = w.jacobian(ex.Y, ex.gap)[1]
    finally:
        w.destroy()
    mu3 = complex(rec["dominant"][0])
    v = eigenvector(J, mu3)
    assert np.linalg.norm(J @ v - mu3 * v) < 1e-12           # round-off of the SVD (|J| ~ 1; measured 1e-16)
    dyn = CompactonDynamics([rec], model, PETSc.COMM_WORLD, None, N=ex.M + 30, n0=5, travel=12, kinds=("mode",))
    try:
        rest = [r for r in dyn.run()][0]["rest"]
    finally:
        dyn.destroy()
    # |rest_k| ~ 1e-8 mu_3^k >= 2e-10 for k <= 3, the flow's floor of |rest| ~ 2e-14 (measured ratios: |mu_3| to 1e-5)
    assert np.max(np.abs(rest[1:4] / rest[:3] / abs(mu3) - 1)) < 1e-3


def test_results_do_not_depend_on_the_ranks(compacton, branch):
    """The window flow on COMM_WORLD (the DMDA split over the ranks) against COMM_SELF: same map and multipliers."""
    ex, w, J, _ = compacton
    ww = CompactonWindow(branch.model, M, PETSc.COMM_WORLD)
    try:
        Gw, Jw, _ = ww.jacobian(ex.Y, ex.gap)
    finally:
        ww.destroy()
    G, _, _ = w.jacobian(ex.Y, ex.gap)
    # same adaptive steps up to the round-off of the TS error norm's reduction
    assert np.max(np.abs(Gw - G)) < 1e-12 and np.max(np.abs(Jw - J)) < 1e-11
    assert np.max(np.abs(sorted_eig(Jw)[0][2:5] - sorted_eig(J)[0][2:5])) < 1e-10


def test_bad_input_is_refused(branch):
    q_high = max(branch.q)                                # pi: F(q) < 1, no compacton
    with pytest.raises(ParameterError, match="q_k"):
        guess_from_branch(branch.point(q_high), M, REAR, branch.q_k())
    with pytest.raises(ParameterError, match="too short for the compression zone"):
        guess_from_branch(branch.point(Q), 9, REAR, branch.q_k())
    w = CompactonWindow(branch.model, M, PETSc.COMM_SELF)
    try:
        with pytest.raises(ParameterError, match="nev"):
            WindowStability(w, nev=2 * M + 1)
    finally:
        w.destroy()


@pytest.mark.serial
def test_drivers_smoke_and_errors(tmp_path):
    """The scan (two q, the solitary wave and the ring skipped), then the dynamics on a short chain; errors."""
    out = tmp_path / "cs.npz"
    r = run_script("compacton_stability.py", "-branches", BRANCH, "-q", "pi/5", "-no_solitary", "-no_ring", "-M", M, "-rear",
                   REAR, "-output", out, "-table", tmp_path / "cs.md", "-figures", tmp_path, ranks=2, timeout=120)
    assert r.returncode == 0, r.stderr
    text = (tmp_path / "cs.md").read_text()
    assert "| 1.5 | 2: 0.62832 - 1.7593 |" in text and "none" in text
    assert (tmp_path / "compacton_stability_mu.png").exists()
    assert STABILITY_KIND.check(read_kind(str(out), STABILITY_KIND, "x")) == ([], [])     # exactly the declared columns
    d = run_script("compacton_dynamics.py", "-stability", out, "-q", "pi/5", "-N", 60, "-n0", 5, "-travel", 30,
                   "-kinds", "mode", "-output", tmp_path / "dyn.npz", "-table", tmp_path / "dyn.md",
                   "-figures", tmp_path, "-no_pairs", timeout=120)
    assert d.returncode == 0, d.stderr
    assert DYNAMICS_KIND.check(read_kind(str(tmp_path / "dyn.npz"), DYNAMICS_KIND, "x")) == ([], [])
    row = [line for line in (tmp_path / "dyn.md").read_text().splitlines() if "| mode |" in line][0]
    ratio = float(row.split("|")[6])
    assert abs(ratio - 1) < 0.1            # the decay of the mode follows ln|mu_3| (full runs: within 0.2%)
    e = run_script("compacton_stability.py", "-branches", BRANCH, "-q", "1.9", "-output", tmp_path / "x.npz",
                   "-table", tmp_path / "x.md", timeout=60)
    assert "invalid -q = 1.9" in one_error_line(e) and "q_k" in one_error_line(e)          # no compacton there
    for ring, why in (("pi/25", "must be one of the scanned q"), ("pi/5", "a whole number of beads >= M + 2")):
        e = run_script("compacton_stability.py", "-branches", BRANCH, "-q", "pi/5", "-no_solitary", "-ring_q", ring,
                       "-output", tmp_path / "r.npz", "-table", tmp_path / "r.md", timeout=60)
        assert "invalid -ring_q" in one_error_line(e) and why in one_error_line(e)   # before the scan
        assert not (tmp_path / "r.npz").exists()
    e = run_script("compacton_dynamics.py", "-stability", out, "-alpha", "1", "-output", tmp_path / "y.npz")
    assert "-alpha" in one_error_line(e)
