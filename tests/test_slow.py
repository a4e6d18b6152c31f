"""Slow instabilities on the infinite chain: the co-moving QEP (hertzpetsc.comoving) against the chain's monodromy and
against dense LAPACK, the deflation of the symmetry multipliers (hertzpetsc.slow), rank independence, the study and
its driver (bad input, resume)."""
import math

import numpy as np
import pytest
import scipy.sparse as sp
from petsc4py import PETSc

from conftest import DATA, chain, one_error_line, run_script, small_branch
from hertzpetsc.bloch import SymmetricFloquet
from hertzpetsc.comoving import ComovingWave
from hertzpetsc.comoving_pep import ComovingPEP
from hertzpetsc.comoving_window import sector_window, tracked_exponent
from hertzpetsc.errors import ParameterError
from hertzpetsc.records import load_npz
from hertzpetsc.richardson import richardson
from hertzpetsc.shooting import Refiner
from hertzpetsc.slow import DeflatedSectors
from hertzpetsc.studies.slow import SLOW_KIND, SLOW_TOLERANCES
from hertzpetsc.waves import orbit_on_chain


def dense_pencil_eigenvalues(mats):
    """All eigenvalues of A0 + z A1 + z^2 A2 (A2 invertible) by the companion linearisation and LAPACK: the
    independent check of the SLEPc route on small grids."""
    A0, A1, A2 = [np.asarray(A.todense()) if sp.issparse(A) else np.asarray(A) for A in mats]
    n = A0.shape[0]
    inv = np.linalg.inv(A2)
    C = np.zeros((2 * n, 2 * n), dtype=np.result_type(A0, A1, complex))
    C[:n, n:] = np.eye(n)
    C[n:, :n] = -inv @ A0
    C[n:, n:] = -inv @ A1
    return np.linalg.eigvals(C)


@pytest.fixture(scope="module")
def pep():
    return ComovingPEP(PETSc.COMM_SELF)


def refined(q, N):
    """The small branch's wave at q on N beads, refined on its cell with the tight flow (E ~ 1e-12)."""
    spec = chain(N)
    rf = Refiner(spec, PETSc.COMM_SELF, 1e-11, tolerances=SLOW_TOLERANCES)
    try:
        return rf.refine(orbit_on_chain(small_branch().point(q), spec)).orbit
    finally:
        rf.destroy()


def test_slepc_pencil_against_dense_lapack(pep):
    """The SLEPc shift-and-invert eigenvalues of the z-pencil (realified, theta = 1) are the companion-LAPACK ones."""
    wave = ComovingWave.from_point(small_branch(K=40, M=5, q_stop=0.4 * math.pi).point(0.4 * math.pi))
    win = sector_window(wave, 1.0, pep)
    ref = np.log(dense_pencil_eigenvalues(wave.pencil(1.0)).astype(complex)) / wave.h
    ref = np.concatenate([ref, np.conj(ref)])                  # the -theta problem of the realified pencil
    # both are double-precision eigenvalues of the same 160 x 160 pencil: rounding, amplified by 1/h ~ 13
    assert len(win.lam) >= 4
    assert max(np.min(np.abs(ref - lam)) for lam in win.lam) < 1e-9


def test_comoving_route_reproduces_the_monodromy_route():
    """An unstable wave (q = pi/5 on 10 beads, h = pi/200): the Bloch parameters of the 10-bead chain are
    theta_j = 2 pi j / 10; Richardson over h = pi/200, pi/400, pi/800 of the co-moving |mu| gives the chain's
    (refined wave, tight flow) two largest multipliers."""
    pep = ComovingPEP(PETSc.COMM_SELF)
    q = 0.2 * math.pi
    orbit = refined(q, 10)
    fast = SymmetricFloquet(orbit.spec.model, PETSc.COMM_SELF)
    try:
        chain_mu = np.abs(fast.spectrum(orbit).multipliers)
    finally:
        fast.destroy()
    point = small_branch().point(q)
    got = {}
    for j in (4, 5):
        theta, lam, values = 2 * math.pi * j / 10, None, []
        for K in (200, 400, 800):
            wave = ComovingWave.from_point(point, K)
            lam = sector_window(wave, theta, pep).dominant()[0] if lam is None else \
                tracked_exponent(wave, theta, lam, pep)
            values.append(abs(wave.multiplier(lam, theta)))
        order, got[j] = richardson(values, 2.0, 2)
        assert abs(order - 2) < 0.1                             # measured 2.006 at both j
    # measured: |difference| 4e-8 at both; the K = 200 grid has 40 cells per q, the O(h^3) remainder ~ 1e-7
    assert abs(got[5] - chain_mu[0]) < 2e-7 and abs(got[4] - chain_mu[2]) < 2e-7


def test_deflation_leaves_the_nontrivial_multipliers_unchanged():
    """q = 3 pi/10 on 20 beads (3 compression zones on a cell of 20 beads): the zone translations are exact
    eigenvectors, the deflated spectrum is P's spectrum without the 2r symmetry multipliers, and the deflated
    multipliers lie on the unit circle while the undeflated cluster is split by sqrt(E)."""
    orbit = refined(0.3 * math.pi, 20)
    sectors = DeflatedSectors(orbit.spec.model, PETSc.COMM_SELF, SLOW_TOLERANCES)
    try:
        for theta, r in ((0.0, 8), (1.0, 6), (math.pi, 6)):
            s = sectors.sector(orbit, theta)
            assert s.r == r                                   # 2 m' (+ translation and boost at Theta = 0)
            # E ~ 1e-12 and the flow's rtol 1e-14: measured 3e-12
            assert s.eigenvector_residual < 1e-10
            rest = s.all_values[np.argsort(np.abs(s.all_values - 1))[s.r:]]
            # a deflation by an invariant subspace to 1e-12 moves simple multipliers by as much: measured 1.4e-11
            assert max(np.min(np.abs(s.values - mu)) for mu in rest) < 1e-9
            assert s.rho - 1 < 1e-11                          # measured 1.5e-13
            assert np.max(np.abs(s.raw_cluster)) - 1 > 1e2 * (s.rho - 1)   # the Jordan blocks split: ~9e-7
        x = orbit.x.copy()
        x[3, 0] += 1e-7                                       # not a travelling wave any more
        s = sectors.sector(orbit.with_state(x, "perturbed"), 1.0)
        assert s.eigenvector_residual > 1e-8                  # measured 6e-8: the deflation sees it
    finally:
        sectors.destroy()


def test_comoving_eigenvalues_do_not_depend_on_the_ranks(pep):
    """The same pencil solved with the matrices on COMM_WORLD (rows split over the ranks, MUMPS in parallel) and on
    one rank: the eigenvalues in the window agree to rounding (the LU pivots differ)."""
    wave = ComovingWave.from_point(small_branch().point(0.2 * math.pi), 400)
    one = sector_window(wave, 2 * math.pi / 5, pep)
    world = sector_window(wave, 2 * math.pi / 5, ComovingPEP(PETSc.COMM_WORLD))
    assert len(one.lam) == len(world.lam) and np.array_equal(one.band, world.band)
    # eigenvalues of a 1600 x 1600 pencil in z, lambda = log(z)/h: rounding times 1/h ~ 130
    assert max(np.min(np.abs(world.lam - lam)) for lam in one.lam) < 1e-10


def test_bad_parameters_name_themselves(pep):
    wave = ComovingWave.from_point(small_branch().point(0.4 * math.pi))
    with pytest.raises(ParameterError, match="theta"):
        DeflatedSectors(wave.model, PETSc.COMM_SELF).sector(refined(0.4 * math.pi, 20), 4.0)
    with pytest.raises(ParameterError, match="guess"):
        tracked_exponent(wave, 1.0, complex(math.nan), pep)


@pytest.mark.serial
def test_driver_runs_resumes_and_refuses_bad_input(tmp_path):
    """The driver on the committed branch on 30 beads at one chain q (2 pi/5, m = 6) and one co-moving-only q
    (3 pi/10), on 2 ranks and on 1: the same records; -resume adds a q; bad input is one error line."""
    args = ["-branch", f"{DATA}/branch_alpha1.5.npz", "-N", 30, "-grids", "250,500,1000", "-n_theta", 5,
            "-n_twist", 2, "-refine_tol", "1e-11", "-reference", "none", "-convergence_q", "2*pi/5"]
    r = run_script("slow_instabilities.py", *args, "-q", "2*pi/5,3*pi/10", "-output", tmp_path / "two.npz",
                   "-table", tmp_path / "two.md", "-figures", tmp_path, ranks=2)
    assert r.returncode == 0, r.stderr
    r = run_script("slow_instabilities.py", *args, "-q", "2*pi/5", "-output", tmp_path / "one.npz", "-table",
                   tmp_path / "one.md")
    assert r.returncode == 0, r.stderr
    two, one = load_npz(str(tmp_path / "two.npz"), "x"), load_npz(str(tmp_path / "one.npz"), "x")
    assert SLOW_KIND.check(two) == ([], [])                    # the file holds exactly the declared columns
    assert sorted(two["m"].tolist()) == [-1, 6] and np.isnan(two["gamma_mono"][two["m"] < 0]).all()
    i = int(np.nonzero(two["m"] == 6)[0][0])
    # each q is computed on one rank: the same arithmetic on any number of ranks, up to the threads of the dense
    # LAPACK calls (one rank per core under mpiexec, two threads serially): the co-moving growth rates here are
    # round-off (|gamma| ~ 3e-14, measured to differ by 1e-18), compared to 1e-12, far below the verdict's 1e-9
    assert np.allclose(two["gamma_cm"][i], one["gamma_cm"][0], rtol=0, atol=1e-12)
    assert two["gamma_mono"][i] == one["gamma_mono"][0]
    assert (tmp_path / "slow_instabilities.png").exists()
    assert "stable within resolution" in (tmp_path / "two.md").read_text()
    r = run_script("slow_instabilities.py", *args, "-q", "2*pi/5", "-output", tmp_path / "one.npz", "-table",
                   tmp_path / "one.md")
    assert "-resume" in one_error_line(r)
    r = run_script("slow_instabilities.py", *args, "-q", "2*pi/5,7*pi/25", "-output", tmp_path / "one.npz",
                   "-table", tmp_path / "one.md", "-resume")
    assert r.returncode == 0, r.stderr
    rows = load_npz(str(tmp_path / "one.npz"), "x")
    assert len(rows["q"]) == 2 and rows["verdict"].tolist() == [0, 1]      # 7 pi/25 is unstable (rho = 1.084)
    r = run_script("slow_instabilities.py", *args[:-8], "-n_twist", 0, "-reference", "none", "-refine_tol", "1e-11",
                   "-q", "2*pi/5", "-output", tmp_path / "one.npz", "-table", tmp_path / "one.md", "-resume")
    assert "n_twist" in one_error_line(r)                      # the file's identity names the parameter
    for bad, name in ((("-grids", "250,500"), "-grids"), (("-n_theta", 1), "-n_theta"), (("-rtol", 1e-3), "-rtol"),
                      (("-q_min", 4), "-q_min"), (("-convergence_q", "3*pi/10", "-N", 30), "-convergence_q"),
                      (("-figure_name", "x.txt"), "-figure_name")):
        r = run_script("slow_instabilities.py", "-branch", f"{DATA}/branch_alpha1.5.npz", *bad, "-output",
                       tmp_path / "bad.npz", "-table", tmp_path / "bad.md")
        assert name in one_error_line(r)
