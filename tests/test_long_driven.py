"""Every multiplier outside a radius (issue 41 item 1: the multipliers of long damped, driven chains): the radius
route of the driven chain's Floquet part (SLEPc Krylov-Schur on the matrix-free monodromy, a region |mu| > r and
a stopping test that closes the spectrum there) against LAPACK on the dense monodromy, against itself under another
eigensolver tolerance, its unresolved verdict, and the test functions on a partial spectrum."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from hertzpetsc.driven import (Drive, HarmonicWave, PeriodicShooting, default_radius, phonon_radius)
from hertzpetsc.driven import test_functions as tau_functions        # not collected as a test
from hertzpetsc.errors import ConvergenceError, ParameterError
from hertzpetsc.model import LatticeModel

COMM = PETSc.COMM_WORLD


@pytest.fixture
def options():
    """Set options of the database for one test, removed afterwards."""
    db, names = PETSc.Options(), []

    def put(**kw):
        for k, v in kw.items():
            db[k] = v
            names.append(k)
    yield put
    for k in names:
        db.delValue(k)


def _response(gamma, amplitude, N=40):
    """The response at omega = 1 of N beads (precompressed, on-site damping gamma) and its dense multipliers."""
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=gamma), N, HarmonicWave(), amplitude, 1.0)
    dense = PeriodicShooting(drive, COMM)
    try:
        r = dense.solve_response(dense.run_in(np.zeros((N, 2)), 10))
        assert r.residual < 1e-10
        return drive, r.x, dense.multipliers(x=r.x, p=1.0)
    finally:
        dense.destroy()


def _outside(drive, x, nev=8):
    prob = PeriodicShooting(drive, COMM, jacobian="mf", floquet="radius", nev=nev)
    try:
        mu = prob.multipliers(x=x, p=1.0)
        return mu, prob.radius, prob.report(prob.pack(x))
    finally:
        prob.destroy()


def _same(mu_dense, mu, r, tol):
    """Every dense multiplier outside r, and no other, within ``tol``; none within tol of the circle |mu| = r (the
    comparison would depend on round-off)."""
    ref = mu_dense[np.abs(mu_dense) > r]
    assert np.min(np.abs(np.abs(mu_dense) - r)) > 10 * tol
    assert len(ref) == len(mu)
    assert np.max(np.abs(np.sort_complex(ref) - np.sort_complex(mu))) < tol


def test_the_default_radius_and_overdamped_long_waves():
    """gamma = 0.5 on 50 beads: the longest waves are overdamped (real multipliers near 1 - omega_k^2 T / gamma),
    the phonons crowd on |mu| = e^{-gamma T / 2}; the default radius e^{-gamma T / 4} lies halfway (in log) between
    them and the unit circle, and the radius route finds every dense multiplier outside it. Tolerance 1e-8: the EPS
    resolves the pairs to relative residual 1e-10, the dense monodromy is resolved to 1e-12 in norm (an isolated
    simple multiplier moves by about its condition number times either)."""
    drive, x, mu_d = _response(0.5, 0.2, N=50)
    T = 2 * math.pi
    assert phonon_radius(drive.spec(), T) == pytest.approx(math.exp(-0.25 * T), rel=1e-14)
    # the phonons: most dense multipliers on the circle (the chain beyond the first beads barely moves)
    assert np.sum(np.abs(np.abs(mu_d) - math.exp(-0.25 * T)) < 1e-6) > 50
    mu, r, rep = _outside(drive, x)
    assert r == pytest.approx(default_radius(drive.spec(), T)) and r == pytest.approx(math.exp(-0.125 * T))
    assert len(mu) >= 2 and np.all(np.abs(mu.imag) < 1e-12)
    _same(mu_d, mu, r, 1e-8)
    assert rep["rho"] == pytest.approx(abs(mu_d[0]), abs=1e-8) and rep["verdict"] == "stable" and rep["radius"] == r


def test_a_stated_radius_near_the_phonons_and_another_tolerance(options):
    """gamma = 0.1, a = 0.8 on 40 beads: complex pairs just outside the phonons' circle (modes near the actuator,
    where the response stiffens the contacts); with -floquet_radius between them the route finds the pair
    outside, the same under -floquet_eps_tol 1e-8 (to 1e-6: that tolerance's) as under the default 1e-10."""
    drive, x, mu_d = _response(0.1, 0.8)
    r = 0.748
    options(floquet_radius=r)
    mu, r_used, _ = _outside(drive, x)
    assert r_used == r and len(mu) == 2 and np.all(np.abs(mu.imag) > 1e-3)
    _same(mu_d, mu, r, 1e-8)
    options(floquet_eps_tol=1e-8)
    loose, _, _ = _outside(drive, x)
    _same(mu_d, loose, r, 1e-6)


def test_unresolved_when_more_lie_outside_than_the_cap(options):
    """nev caps the multipliers outside r: with 1 allowed and 2 outside, the route says 'unresolved' (a
    ConvergenceError naming the radius), never a partial set as complete; a radius inside the phonons' circle is
    refused naming the option."""
    drive, x, _ = _response(0.5, 0.2, N=50)
    with pytest.raises(ConvergenceError, match="unresolved"):
        _outside(drive, x, nev=1)
    options(floquet_radius=0.2)
    with pytest.raises(ParameterError, match="floquet_radius"):           # when the problem is built
        PeriodicShooting(drive, COMM, jacobian="mf", floquet="radius")


def test_partial_test_functions_keep_their_sign_when_a_pair_enters():
    """tau_NS on the multipliers outside r < 1 (factors 1 - mu_i mu_j): a complex pair entering the set at |mu| = r
    leaves its sign, and both test functions vanish where the full ones do."""
    mu = np.array([0.95, 0.5 + 0.6j, 0.5 - 0.6j])
    pair = 0.8 * np.exp(1j * np.array([1.0, -1.0]))
    before, after = tau_functions(mu, partial=True), tau_functions(np.concatenate([mu, pair]), partial=True)
    for name in before:
        assert np.sign(before[name]) == np.sign(after[name])
    crossing = np.array([0.95, np.exp(0.3j), np.exp(-0.3j)])
    assert abs(tau_functions(crossing, partial=True)["neimark_sacker"]) < 1e-15
    assert abs(tau_functions(crossing)["neimark_sacker"]) < 1e-15


def _linear_monodromy(drive, T):
    """R_lin = exp(T A) of the chain linearised about rest (studies.driven.linear_chain, scipy's expm), in the
    bead-major layout 2n + c of the flows."""
    from scipy.linalg import expm

    from hertzpetsc.studies.driven import linear_chain
    M, C, K, _ = linear_chain(drive)
    N = drive.N
    Mi = np.linalg.inv(M)
    R = expm(T * np.block([[np.zeros((N, N)), np.eye(N)], [-Mi @ K, -Mi @ C]]))
    order = np.arange(2 * N).reshape(2, N).T.ravel()            # (x_0, v_0, x_1, v_1, ...)
    return R[np.ix_(order, order)]


def test_the_linear_chains_slow_modes_and_shifted_solves_in_closed_form():
    """The slow modes' start and preconditioner (driven.LinearChainPreconditioner: R_lin's 2 x 2 blocks in the sine
    modes) against R_lin = expm(T A) of the linearised chain: the eigenvalues outside r, their eigenvectors'
    residuals and (R_lin - theta I)^-1 for complex shifts, to 1e-10 (expm and the closed form agree to a few
    hundred ulps of ||R_lin|| ~ 1; the solves are conditioned by 1 / dist(theta, spectrum) <= 20 here); gamma = 0.5
    on 60 beads: the three longest waves are overdamped."""
    from hertzpetsc.driven import LinearChainPreconditioner
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.5), 60, HarmonicWave(), 0.2, 1.0)
    prob = PeriodicShooting(drive, COMM, jacobian="mf", floquet="radius", nev=8)
    try:
        lin = LinearChainPreconditioner(prob)
        R = _linear_monodromy(drive, prob.T)
        mu_all = np.linalg.eigvals(R)
        r = 0.3                                 # the overdamped long waves' slow multipliers (k = 1, 2, 3)
        mu, V = lin.slow_modes(r)
        assert len(mu) == np.sum(np.abs(mu_all) > r) >= 3
        assert np.max(np.abs(np.sort_complex(mu) - np.sort_complex(mu_all[np.abs(mu_all) > r]))) < 1e-10
        assert np.max(np.linalg.norm(R @ V - V * mu, axis=0) / np.linalg.norm(V, axis=0)) < 1e-10
        B = np.random.default_rng(1).standard_normal((120, 3)) + 0j
        theta = np.array([0.95 + 0.05j, 1.02, -0.3j])
        X = lin.shifted_solve(theta, B)
        for j in range(3):
            assert np.allclose((R - theta[j] * np.eye(120)) @ X[:, j], B[:, j], rtol=0, atol=1e-10)
    finally:
        prob.destroy()


def _radius_work(drive, x, **opts):
    """The radius route's multipliers and work with the options ``opts`` (then removed)."""
    db = PETSc.Options()
    for k, v in opts.items():
        db[k] = v
    try:
        prob = PeriodicShooting(drive, COMM, jacobian="mf", floquet="radius", nev=16)
        try:
            return prob.multipliers(x=x, p=drive.omega), dict(prob.floquet_work)
        finally:
            prob.destroy()
    finally:
        for k in opts:
            db.delValue(k)


def test_the_slow_modes_stage_against_krylov_alone_on_a_long_weakly_damped_chain():
    """gamma = 0.1 on 300 beads: the overdamped long waves crowd at 1 (gaps O(1 / N^2)). The slow modes' stage
    (block Davidson from R_lin's modes) finds every one of them outside the default radius and the Krylov stage,
    deflated, nothing more; Krylov-Schur alone (-floquet_slow_modes 0, the route before) finds the same
    multipliers to 1e-8 (both resolve the pairs to relative residual 1e-10; the multipliers are real, simple and
    separated by >= 1e-3, condition ~1), with more products; under -floquet_eps_tol 1e-8 the same to 1e-6."""
    N = 300
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.1), N, HarmonicWave(), 0.2, 1.0)
    prob = PeriodicShooting(drive, COMM, jacobian="mf", floquet="none")
    try:
        r = prob.solve_response(prob.run_in(np.zeros((N, 2)), 10))
        assert r.residual < 1e-10
    finally:
        prob.destroy()
    mu, work = _radius_work(drive, r.x)
    ref, ref_work = _radius_work(drive, r.x, floquet_slow_modes=0)
    assert work["resolved"] and ref_work["resolved"] and ref_work["slow"] == 0
    assert len(mu) == len(ref) == work["slow"] >= 3 and np.all(np.abs(mu.imag) < 1e-12)
    assert np.min(np.abs(np.diff(np.abs(ref)))) > 1e-3
    assert np.max(np.abs(mu - ref)) < 1e-8
    assert work["products"] < ref_work["products"]
    loose, _ = _radius_work(drive, r.x, floquet_eps_tol=1e-8)
    assert len(loose) == len(mu) and np.max(np.abs(loose - mu)) < 1e-6


def test_both_stages_find_their_part_and_the_deflated_eigenvectors_are_the_operators(options):
    """gamma = 0.3, a = 1.5 on 60 beads: two overdamped long waves (0.918, 0.654) and, with -floquet_radius 0.402
    just outside the phonons' circle (0.390), a complex pair 0.405 near the actuator. The slow modes' stage finds
    the two waves, the deflated Krylov stage the pair; its eigenvectors, which SLEPc computes in the deflated
    complement, are completed by the deflated span (DominantFloquet._undeflated): without that the independent
    flow's check refuses them (residual 2.5e-4 at N = 200). All four equal the dense route's to 1e-8 (pairs to
    relative residual 1e-10, condition ~1)."""
    drive, x, mu_d = _response(0.3, 1.5, N=60)
    r = 0.402
    options(floquet_radius=r)
    prob = PeriodicShooting(drive, COMM, jacobian="mf", floquet="radius", nev=8)
    try:
        mu = prob.multipliers(x=x, p=1.0)
        work = prob.floquet_work
    finally:
        prob.destroy()
    assert work["slow"] == 2 and len(mu) == 4 and np.sum(np.abs(mu.imag) > 0.1) == 2
    _same(mu_d, mu, r, 1e-8)
