"""Driven, damped chains (issue 22): the damped tangent flow, periodic responses by shooting against closed forms
(the linear damped chain, its normal modes and multipliers, Liouville's formula, the energy balance), the exact
travelling wave imposed at both ends, dense against SLEPc and Newton-Krylov against dense, period doubling with
branch switching, bad input, and the drivers."""
import math
import os

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import (DATA, ROOT, dense_and_slepc_agree, one_error_line, resolvent_differences, run_script,
                      script_env, shared_tmp)
from hertzpetsc.assembly import gathered
from hertzpetsc.chain import IntegrationTolerances
from hertzpetsc.continuation import ContinuationPoint, Natural, PseudoArclength
from hertzpetsc.driven import (CHORD_CONTRACTION, Drive, HalfSinePulses, HarmonicWave, PeriodicShooting, SampledWave,
                               crossing, damping_trace, neutral_saddle, refined_profile, wave_ends_drive)
from hertzpetsc.driven import test_functions as tau_functions        # not collected as a test
from hertzpetsc.errors import ParameterError
from hertzpetsc.floquet import DenseFloquet
from hertzpetsc.model import Actuator, ChainSpec, Harmonic, LatticeModel
from hertzpetsc.records import read_kind
from hertzpetsc.studies.driven import (EVENTS, GENERATION_KIND, RESONANCE_KIND, RESPONSE_KIND, WAVE_ENDS_KIND,
                                       Generation, GenerationParameters, LinearResonances, ResonanceParameters,
                                       ResponseCurve, ResponseParameters, WaveEnds, WaveEndsParameters, linear_chain,
                                       linear_multipliers, linear_response, normal_modes)
from hertzpetsc.tangent import TangentFlow

COMM = PETSc.COMM_WORLD
TIGHT = IntegrationTolerances(1e-12, 1e-14)


def small_drive(N=6, **kw):
    """A precompressed dimer chain with both dampings between a harmonic actuator of tiny amplitude and a wall."""
    model = LatticeModel.hertz(1.5, masses=(1.0, 0.7), delta0=1.0, gamma=kw.pop("gamma", 0.1), eta=kw.pop("eta", 0.05))
    return Drive(model, N, HarmonicWave(), kw.pop("amplitude", 1e-6), kw.pop("omega", 0.9), **kw)


def test_damped_tangent_flow_is_the_derivative_of_the_flow():
    """R(T; 0) from the tangent columns against central differences of the damped, driven flow: agreement to
    O(h^2) + tol/h ~ 1e-8 for h = 1e-5 (the damping terms act on the tangents' velocities too)."""
    model = LatticeModel.hertz(1.5, delta0=0.5, gamma=0.3, eta=0.2)
    spec = ChainSpec(model, 4, "fixed", left=Actuator(Harmonic(0.2, 1.3)))
    x0 = np.random.default_rng(3).normal(size=(4, 2)) * 0.05
    flow = TangentFlow(spec, 8, COMM, TIGHT, "floquet_")
    try:
        R, _ = flow.resolvent(x0, 2.0)
        fd = resolvent_differences(flow, x0, 2.0, 1e-5)
    finally:
        flow.destroy()
    assert np.max(np.abs(R - fd)) < 1e-7 * np.max(np.abs(R))
    # Liouville over a flow that is not periodic: det R = exp(-T tr(M^-1 C)) (an exact identity of the ODE)
    assert abs(np.linalg.slogdet(R)[1] + 2.0 * damping_trace(spec)) < 1e-9


def test_undamped_undriven_chain_gives_back_the_previous_numbers():
    """The refined wave of the record of the previous implementation (N = 20, q = 3 pi/10): the same Floquet
    multipliers modulo shift, on one rank as the record was made (the undamped code path is unchanged: the same
    numbers to round-off; across ranks see test_floquet). Another PETSc's flow differs by its steps' round-off: the
    multipliers away from 1 and the mean of the 8 at 1 (the symmetries' defective cluster, well conditioned as a whole)
    keep 1e-11 and 1e-12 (3.26 against the 3.18 record: 3.7e-12, 1e-13); the cluster's members, rho among them, move
    by the square root of those differences, so rho is held to 1e-7 (3.26: 8.6e-9; 3.18: the record's own numbers)."""
    prev = np.load(os.path.join(ROOT, "tests", "data", "previous_records.npz"))
    spec = ChainSpec(LatticeModel.hertz(1.5), 20)
    dense = DenseFloquet(spec, PETSc.COMM_SELF)
    try:
        from hertzpetsc.waves import Orbit
        orbit = Orbit(spec, 3 * math.pi / 10, 3, float(prev["refined_T"]), prev["refined_x"], 1.0)
        sp = dense.spectrum(orbit)
    finally:
        dense.destroy()
    mu, ref = sp.multipliers, prev["refined_multipliers"]
    at_one, ref_at_one = mu[np.abs(mu - 1) < 1e-4], ref[np.abs(ref - 1) < 1e-4]
    assert len(at_one) == len(ref_at_one) == 8 and abs(at_one.mean() - ref_at_one.mean()) < 1e-12
    far, ref_far = np.sort_complex(mu[np.abs(mu - 1) >= 1e-4]), np.sort_complex(ref[np.abs(ref - 1) >= 1e-4])
    assert np.max(np.abs(far - ref_far)) < 1e-11
    assert abs(sp.rho - float(prev["refined_rho"])) < 1e-7


def test_small_amplitude_response_is_the_linear_closed_form():
    """Newton shooting of the Hertz chain (masses 1, 0.7; gamma, eta; a = 1e-6 << delta0 = 1) against the damped
    linear chain's complex amplitudes X (x(0) = Re X, v(0) = -omega Im X): relative difference O(a / delta0) from
    the nonlinearity plus the shooting tolerance; the multipliers against exp(T lambda) of the linear chain."""
    drive = small_drive()
    prob = PeriodicShooting(drive, COMM, tolerances=IntegrationTolerances(1e-12, 1e-20))
    try:
        r = prob.solve_response(np.zeros((6, 2)))
        X = linear_response(drive)
        xc = np.stack([X.real, -drive.omega * X.imag], axis=1)
        assert np.max(np.abs(r.x - xc)) < 1e-6 * np.max(np.abs(xc))
        mu = prob.multipliers(x=r.x, p=drive.omega)
        ref = linear_multipliers(drive, prob.T)
        assert np.max(np.abs(np.sort_complex(mu) - np.sort_complex(ref))) < 1e-8
        # the energy balance over the period: mean input power = mean dissipation (the periodic trapezoid rule on
        # 64 samples of a smooth (linear-regime) response is spectrally accurate)
        d = prob.diagnostics(r.x, 64)
        assert d["dissipation"] > 0 and abs(d["power_in"] - d["dissipation"]) < 1e-6 * d["dissipation"]
    finally:
        prob.destroy()


def test_normal_modes_closed_form_and_resonance_peaks():
    """omega_k = 2 sqrt(K) sin(k pi / (2 (N + 1))) for unit masses between an actuator and a wall; the peak of the
    shooting response near omega_1 equals the damped linear chain's to the golden-section resolution (0.618^30 of
    the window, ~2e-7) and lies O(gamma^2) from omega_1."""
    model = LatticeModel.hertz(1.5, delta0=1.0, gamma=0.02)
    drive = Drive(model, 3, HarmonicWave(), 1e-6, 1.0)
    K = model.law.linear_stiffness
    closed = [2 * math.sqrt(K) * math.sin(k * math.pi / 8) for k in (1, 2, 3)]
    assert np.allclose(normal_modes(drive), closed, rtol=1e-13)
    study = LinearResonances(ResonanceParameters(drive, modes=(1,), golden=30), COMM)
    try:
        rec = next(study.run())
    finally:
        study.destroy()
    width = np.diff(study.window(1))[0]
    assert abs(rec["peak_shooting"] - rec["peak_linear"]) < 2 * 0.618 ** 30 * width
    assert abs(rec["peak_linear"] - closed[0]) < 0.02 ** 2 * 10 and rec["mu_error"] < 1e-8
    assert abs(rec["amp_shooting"] / rec["amp_linear"] - 1) < 1e-5


@pytest.mark.parametrize("masses,right", [((1.0,), "wall"), ((1.0, 0.6), "free")])
def test_liouville_product_of_the_multipliers(masses, right):
    """prod mu = exp(-T tr(M^-1 C)) (= exp(-N gamma T) for unit masses and on-site damping) for a nonlinear
    response (sonic vacuum, a = 0.3), to the flow's tolerance (log det error ~ 2N x rtol x growth)."""
    model = LatticeModel.hertz(1.5, masses=masses, delta0=0.0 if right == "wall" else 1.0, gamma=0.05,
                               eta=0.0 if right == "wall" else 0.02)
    drive = Drive(model, 4, HarmonicWave(), 0.3, 1.1, right=right)
    prob = PeriodicShooting(drive, COMM)
    try:
        r = prob.solve_response(prob.run_in(np.zeros((4, 2)), 30))
        mu = prob.multipliers(x=r.x, p=drive.omega)
    finally:
        prob.destroy()
    logdet = float(np.sum(np.log(np.abs(mu))))
    expected = -prob.T * damping_trace(drive.spec())
    if masses == (1.0,) and right == "wall":
        assert expected == pytest.approx(-4 * 0.05 * prob.T, rel=1e-14)
    assert abs(logdet - expected) < 1e-8 * abs(expected)
    assert r.residual < 1e-10


def wave_ends_pi10(N=10, samples=1024):
    """The refined wave q = pi/10 of the 100-bead chain (tests/data/wave_ends_pi10.npz, tests/data/make_wave_ends.py)
    imposed at both ends of N beads: (the orbit, its profile, the drive)."""
    from hertzpetsc.waves import Orbit
    with np.load(os.path.join(ROOT, "tests", "data", "wave_ends_pi10.npz")) as z:
        orbit = Orbit(ChainSpec.hertz(1.5, 100), float(z["q"]), int(z["m"]), float(z["T"]), z["x"], float(z["omega"]))
    profile = refined_profile(orbit, COMM, samples)
    return orbit, profile, wave_ends_drive(orbit.spec.model, N, profile, orbit.omega, orbit.q)


def test_the_drive_is_never_jumped():
    """The wave q = pi/10 imposed at both ends of 10 beads (issue 37): for part of the period every bead of the window
    flies freely, which the flow integrates exactly, so an adaptive step grows until it crosses the actuator's push
    (2.1 time units, a fifth of the profile) whole. Before the steps were limited by the push's duration
    (ChainSpec.time_scale / STEPS_PER_PUSH), the multipliers' flow took steps of 4 to 17 time units across it: det R
    came out 0 or e^-104 instead of 1, and rho 27.31 at rtol 1e-10 against 22.64 at 1e-12. Now no step exceeds a
    quarter of the push, det R = 1 (Liouville, undamped) to the flows' resolution and R is symplectic, and rho agrees
    between rtol 1e-10 and 1e-12 to 1e-6 relative (1e-8 measured)."""
    from hertzpetsc.chain import STEPS_PER_PUSH
    from hertzpetsc.studies.driven import tolerances_of
    orbit, profile, drive = wave_ends_pi10()
    push = profile.push / orbit.omega
    assert 1.5 < push < 3.0 and drive.spec().time_scale == pytest.approx(push, rel=1e-14)
    x0 = orbit.x[1:11]
    rhos = []
    for rtol in (1e-10, 1e-12):
        prob = PeriodicShooting(drive, COMM, tol=1e4 * rtol, tolerances=tolerances_of(rtol))
        try:
            steps = []
            ts = prob.dense.flow.integrator.ts
            ts.setMonitor(lambda ts, i, t, X: steps.append(ts.getTimeStep()))
            r = prob.solve_response(x0)
            mu = prob.multipliers(x=r.x, p=orbit.omega)
            ts.monitorCancel()
            assert prob.dense.flow.integrator.max_step == pytest.approx(push / STEPS_PER_PUSH, rel=1e-14)
            assert 0 < max(steps) <= push / STEPS_PER_PUSH * (1 + 1e-12)
        finally:
            prob.destroy()
        assert abs(np.sum(np.log(np.abs(mu)))) < 1e-6
        rhos.append(float(np.max(np.abs(mu))))
    assert abs(rhos[0] / rhos[1] - 1) < 1e-6 and 22 < rhos[1] < 23


@pytest.mark.serial
def test_the_driven_multipliers_do_not_depend_on_the_number_of_blas_threads():
    """The response and rho of the wave q = pi/10 on 10 beads (rtol 1e-10) in processes with one and with two BLAS
    threads (set explicitly; the drivers' default is one): the same to 1e-6 relative (1.5e-8 measured) -- the dense
    solves' round-off differs, the steps of the flows do not jump the push either way."""
    import subprocess
    import sys
    code = ("import sys; sys.path.insert(0, 'tests'); import numpy as np; import test_driven as t; "
            "from hertzpetsc.driven import PeriodicShooting; from hertzpetsc.studies.driven import tolerances_of; "
            "orbit, _, drive = t.wave_ends_pi10(); "
            "p = PeriodicShooting(drive, t.COMM, tol=1e-6, tolerances=tolerances_of(1e-10)); "
            "r = p.solve_response(orbit.x[1:11]); print(repr(float(np.max(np.abs(p.multipliers(x=r.x, p=orbit.omega))))))")
    rhos = []
    for threads in ("1", "2"):
        env = dict(script_env(), OPENBLAS_NUM_THREADS=threads, OMP_NUM_THREADS=threads)
        r = subprocess.run(["timeout", "300", sys.executable, "-c", code], capture_output=True, text=True, env=env,
                           cwd=ROOT)
        assert r.returncode == 0, r.stderr
        rhos.append(float(r.stdout.strip().splitlines()[-1]))
    assert abs(rhos[1] / rhos[0] - 1) < 1e-6 and 22 < rhos[0] < 23


def test_signals_declare_the_time_scale_that_limits_every_flow():
    """A signal's time scale is its shortest push: half a period of a harmonic, a half-sine pulse's width, a sampled
    signal's spacing, a travelling-wave profile's contact (|U''| above 1e-3 of its largest); the chain's is its
    actuators' shortest (inf without any), and no step of a driven chain's flows exceeds a quarter of it."""
    from hertzpetsc.chain import STEPS_PER_PUSH
    from hertzpetsc.driven import push_width
    from hertzpetsc.model import FunctionSignal, SampledSignal
    assert Harmonic(0.1, 2.0).time_scale == pytest.approx(math.pi / 2, rel=1e-15)
    assert HalfSinePulses(0.3).signal(0.1, 2.0).time_scale == pytest.approx(0.3 * math.pi, rel=1e-15)
    assert SampledSignal((0.0, 1.0, 0.0, -1.0), 2.0).time_scale == 0.5
    assert FunctionSignal(np.sin, np.cos, 2 * math.pi).time_scale == pytest.approx(2 * math.pi / 64, rel=1e-15)
    th = np.linspace(0.0, 2 * math.pi, 512, endpoint=False)
    assert push_width(np.cos(th)) == pytest.approx(math.pi, abs=0.02)           # where |cos| > 1e-3
    pulse = np.where((th > 1.0) & (th < 1.5), np.sin(2 * math.pi * (th - 1.0)) ** 2, 0.0)
    assert push_width(pulse) == pytest.approx(0.5, abs=3 * 2 * math.pi / 512)     # the stencil adds a point a side
    spec = small_drive(N=6, right=HalfSinePulses(0.1), omega=2.0).spec()
    assert spec.time_scale == pytest.approx(0.1 * math.pi, rel=1e-15)
    assert ChainSpec.hertz(1.5, 8).time_scale == math.inf
    prob = PeriodicShooting(small_drive(N=6, right=HalfSinePulses(0.1), omega=2.0, amplitude=0.05), COMM)
    try:
        for integ in (prob.integrator, prob.dense.flow.integrator, prob.jacobian_flow.integrator):
            steps, last = [], {}

            def taken(ts, i, t, X):         # the steps taken: t between consecutive monitor calls of one solve
                if i > 0 and last.get("i") == i - 1:
                    steps.append(t - last["t"])
                last.update(i=i, t=t)

            integ.ts.setMonitor(taken)
            prob.monodromy(np.zeros((6, 2)), 2.0, accurate=integ is not prob.jacobian_flow.integrator)
            prob.map(np.zeros((6, 2)))
            integ.ts.monitorCancel()
            assert 0 < max(steps) <= 0.1 * math.pi / STEPS_PER_PUSH * (1 + 1e-12)
            prob._mono = None
    finally:
        prob.destroy()


def test_multipliers_that_break_liouville_or_symplecticity_are_refused():
    """check_monodromy: the monodromy of a response passes (det R = exp(-T tr(M^-1 C)), and R^T J R = e^(-gamma T) J
    with on-site damping and unit masses); one column off by 1e-6 fails Liouville, x_1 and x_2 rescaled by 2 and
    1/2 (det unchanged) fails symplecticity, each a ConvergenceError naming the check and the parameter. The
    SLEPc route's pairs against an independent flow: a multiplier off by 1e-4 fails its eigen-residual."""
    from hertzpetsc.driven import check_eigenpairs, check_monodromy
    from hertzpetsc.errors import ConvergenceError
    drive = Drive(LatticeModel.hertz(1.5, delta0=0.5, gamma=0.05), 4, HarmonicWave(), 0.05, 1.2)
    prob = PeriodicShooting(drive, COMM)
    try:
        r = prob.solve_response(prob.run_in(np.zeros((4, 2)), 10))
        prob.multipliers(x=r.x, p=1.2)                   # checked on the way
        R, steps = prob.monodromy(r.x, 1.2).copy(), prob._mono[5]
    finally:
        prob.destroy()
    where = {"omega": 1.2}
    check_monodromy(R, drive.spec(), prob.T, 1e-12, steps, where)
    bad = R.copy()
    bad[:, 3] *= 1 + 1e-6
    with pytest.raises(ConvergenceError, match=r"Liouville: det R = .* at omega = 1\.2"):
        check_monodromy(bad, drive.spec(), prob.T, 1e-12, steps, where)
    bad = R.copy()
    bad[0] *= 2.0                                        # x_1 doubled, x_2 halved: det R kept, the form is not
    bad[2] *= 0.5
    with pytest.raises(ConvergenceError, match="symplecticity"):
        check_monodromy(bad, drive.spec(), prob.T, 1e-12, steps, where)
    mf = PeriodicShooting(drive, COMM, jacobian="mf", floquet="slepc", nev=2)
    try:
        mu = mf.multipliers(x=r.x, p=1.2)                # checked on the way
        with pytest.raises(ConvergenceError, match="eigen-residual"):
            check_eigenpairs(mf.dominant.op, mu * (1 + 1e-4), mf.dominant.vectors, drive.spec(), mf.T, where)
    finally:
        mf.destroy()


def test_newton_jacobians_resolve_the_state_and_the_multipliers_the_tangents():
    """The Newton Jacobian's monodromy comes from steps controlled by the state's error alone, at JACOBIAN_RTOL: fewer
    steps, and a chord step with it contracts a Newton step's error by far less than CHORD_CONTRACTION (the bound
    1e-2 CHORD_CONTRACTION leaves its tangents, which no step controls, errors up to ~1e5 JACOBIAN_RTOL). Only the
    multipliers' monodromy resolves the tangents, and satisfies Liouville to the flow's tolerance. A Jacobian's
    monodromy is never served as the multipliers' (the cache knows which it holds); the accurate one serves both."""
    drive = Drive(LatticeModel.hertz(1.5, gamma=0.05), 4, HarmonicWave(), 0.3, 1.1)
    prob = PeriodicShooting(drive, COMM)
    try:
        r = prob.solve_response(prob.run_in(np.zeros((4, 2)), 30))
        steps_j, steps_a = prob.jacobian_flow.integrator.steps, prob.dense.flow.integrator.steps
        flows = prob.counters["tangent_flows"]
        R_j = prob.monodromy(r.x, 1.1, accurate=False).copy()
        steps_j = prob.jacobian_flow.integrator.steps - steps_j
        R_a = prob.monodromy(r.x, 1.1).copy()
        steps_a = prob.dense.flow.integrator.steps - steps_a
        assert prob.counters["tangent_flows"] == flows + 2 and 0 < steps_j < steps_a
        assert np.array_equal(prob.monodromy(r.x, 1.1, accurate=False), R_a)        # served from the cache
        assert prob.counters["tangent_flows"] == flows + 2
        eye = np.eye(8)
        chord = eye - np.linalg.solve(R_a - eye, R_j - eye)           # a chord step's error map
        assert 0 < np.linalg.norm(chord, 2) < 1e-2 * CHORD_CONTRACTION
        expected = -prob.T * damping_trace(drive.spec())
        assert abs(np.sum(np.log(np.abs(np.linalg.eigvals(R_a)))) - expected) < 1e-8 * abs(expected)
    finally:
        prob.destroy()


def test_inexact_newton_evaluates_far_iterates_loosely_and_converges_to_the_same_response():
    """The residuals of Newton iterates far from the response come from the state flow at INEXACT_FRACTION f^2 / (2 n)
    (up to JACOBIAN_RTOL), f the last relative residual, n the last flow's steps: fewer steps in all. The converged evaluation is at the flow's
    own tolerance: the response's residual re-measured with it is below the shooting tolerance, and the response is
    the exact-evaluation corrector's to within twice that tolerance times ||(R - I)^-1|| (both satisfy it)."""
    N, omega = 8, 1.1
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.05), N, HarmonicWave(), 0.05, omega)
    out = {}
    for inexact in (False, True):
        prob = PeriodicShooting(drive, COMM, inexact=inexact)
        try:
            x0 = prob.run_in(np.zeros((N, 2)), 5)
            steps = prob.integrator.steps
            r = prob.solve_response(x0)
            out[inexact] = (r, prob.integrator.steps - steps, prob.monodromy(r.x, omega), prob.scale(r.x), prob.tol)
        finally:
            prob.destroy()
    (exact, steps_exact, R, scale, tol), (loose, steps_loose, _, _, _) = out[False], out[True]
    assert exact.residual <= tol and loose.residual <= tol
    assert steps_loose < 0.8 * steps_exact
    bound = 2 * tol * scale * np.linalg.norm(np.linalg.inv(R - np.eye(2 * N)), np.inf)
    assert 0 < np.max(np.abs(loose.x - exact.x)) <= bound


@pytest.mark.parametrize("right,eta", [("wall", 0.0), ("free", 0.03)])
def test_linear_chain_preconditioner_is_the_inverse_of_the_linear_monodromy_minus_one(right, eta):
    """The preconditioner of Newton-Krylov shooting applies (R_lin - I)^-1 (sine modes, closed-form 2 x 2 monodromies)
    equal to the dense one, R_lin = V exp(T Lambda) V^-1 from the eigen-decomposition of the linear chain's first-order
    matrix (studies.driven.linear_chain), to rounding amplified by the condition number; and with it GMRES on a
    small-amplitude response converges in a few iterations."""
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.05, eta=eta), 9, HarmonicWave(), 1e-6, 0.8, right=right)
    prob = PeriodicShooting(drive, COMM, jacobian="mf", floquet="none")
    try:
        pc = prob._snes.getKSP().getPC()
        assert pc.getType() == "python"
        M, C, Kmat, _ = linear_chain(drive)
        N = drive.N
        A = np.block([[np.zeros((N, N)), np.eye(N)], [-np.linalg.solve(M, Kmat), -np.linalg.solve(M, C)]])
        lam, V = np.linalg.eig(A)
        R = (V @ np.diag(np.exp(prob.T * lam)) @ np.linalg.inv(V)).real
        perm = np.arange(2 * N).reshape(2, N).T.ravel()          # (x_1..x_N, v_1..v_N) -> bead-major (x_n, v_n)
        B = (R - np.eye(2 * N))[np.ix_(perm, perm)]
        rng = np.random.default_rng(5)
        b = rng.normal(size=2 * N + 1)
        X, Y = prob.create_vec(), prob.create_vec()
        lo, hi = X.getOwnershipRange()
        X.getArray()[:] = b[lo:hi]
        pc.apply(X, Y)
        y = gathered(Y)
        expected = np.linalg.solve(B, b[:2 * N])
        assert np.max(np.abs(y[:2 * N] - expected)) < 1e-11 * np.linalg.cond(B) * np.max(np.abs(expected))
        assert y[-1] == b[-1]
        r = prob.solve_response(prob.run_in(np.zeros((N, 2)), 5))
        assert r.residual < 1e-10
        assert prob.counters["products"] <= 4 * prob.counters["jacobians"]     # a few GMRES iterations per step
        X.destroy()
        Y.destroy()
    finally:
        prob.destroy()


def test_dense_and_slepc_multipliers_agree_and_newton_krylov_agrees_with_dense():
    """The same response by the dense bordered Newton and by Newton-Krylov (tangent-flow products); its dominant
    multipliers by LAPACK on the dense monodromy and by SLEPc Krylov-Schur on the matrix-free one (dashpots between
    neighbours damp the modes unequally, so the dominant ones are well separated in modulus)."""
    model = LatticeModel.hertz(1.5, delta0=0.5, gamma=0.01, eta=0.1)
    drive = Drive(model, 6, HarmonicWave(), 0.05, 1.2)

    def counters(dense, mf, mu_dense):
        assert mf.counters["products"] > 0 and mf.counters["tangent_flows"] == 0
    dense_and_slepc_agree(drive, 1.2, counters)


def test_a_response_does_not_depend_on_the_number_of_ranks():
    """The same response on this communicator and on one rank: both are responses to the shooting tolerance
    (1e-10 relative), and they agree to it (the reductions' order changes the round-off, not the steps' size)."""
    drive = Drive(LatticeModel.hertz(1.5, delta0=0.5, gamma=0.08), 6, HalfSinePulses(0.4), 0.05, 1.2)
    out = []
    for comm in (COMM, PETSc.COMM_SELF):
        prob = PeriodicShooting(drive, comm)
        try:
            out.append(prob.solve_response(np.zeros((6, 2))).x)
        finally:
            prob.destroy()
    assert np.max(np.abs(out[0] - out[1])) < 1e-10 * np.max(np.abs(out[1]))


def test_travelling_wave_imposed_at_both_ends_is_a_periodic_response():
    """The refined wave q = 2 pi/5 (m = 20 on the 100-bead chain) with beads 0 and N + 1 of a 10-bead window as
    actuators: its residual in the driven chain is at the level of the refined wave's E(q) (1e-11 .. 1e-10, plus
    the profile's interpolation ~1e-11), Newton barely moves it, and the multipliers agree between the flow
    tolerances 1e-12 and 1e-14 (undamped: det R = 1)."""
    from hertzpetsc.branch import Branch
    from hertzpetsc.studies.refinement import RefinedStates
    branch = Branch.load(f"{DATA}/branch_alpha1.5.npz")
    ref = RefinedStates.load(f"{DATA}/refined_N100.npz")
    q = 2 * math.pi / 5
    orbit = ref.orbit(branch.point(q))
    profile = refined_profile(orbit, COMM, 4096)
    drive = wave_ends_drive(orbit.spec.model, 10, profile, orbit.omega, q)
    x0 = orbit.x[1:11]
    rhos = []
    for rtol in (1e-12, 1e-14):
        prob = PeriodicShooting(drive, COMM, tol=1e4 * rtol, tolerances=IntegrationTolerances(rtol, rtol / 100))
        try:
            imposed = prob.residual(x0)
            r = prob.solve_response(x0)
            mu = prob.multipliers(x=r.x, p=orbit.omega)
        finally:
            prob.destroy()
        assert imposed < 1e-9 if rtol == 1e-12 else imposed < 2e-10
        assert np.max(np.abs(r.x - x0)) < 1e-8
        assert abs(np.sum(np.log(np.abs(mu)))) < 1e-8
        rhos.append(float(np.max(np.abs(mu))))
    assert abs(rhos[0] - rhos[1]) < 1e-8


def test_period_doubling_is_located_confirmed_and_switched():
    """Two beads of the sonic vacuum between an actuator (a = 1) and a wall, gamma = 0.1: continuing down from
    omega = 1.69 the period-1 response loses stability through a multiplier -1 near omega = 1.675; the event is
    located (|mu + 1| small), confirmed by the multipliers on both sides, and the branch switched onto has period
    2 T: P^2 X = X to the shooting tolerance while P X != X."""
    drive = Drive(LatticeModel.hertz(1.5, gamma=0.1), 2, HarmonicWave(), 1.0, 1.69)
    study = ResponseCurve(ResponseParameters(drive, "omega", 1.665, algorithm=PseudoArclength(ds=0.01, ds_max=0.02,
                                                                                            easy=5),
                                             run_in=100, samples=0, switch=2, max_steps=12), COMM)
    try:
        records = list(study.run())
        pd = [r for r in records if r["event"] == EVENTS["period_doubling"] and r["branch"] == 0]
        assert len(pd) == 1 and pd[0]["confirmed"] == 1
        assert abs(pd[0]["p"] - 1.6752) < 1e-3
        assert np.min(np.abs(pd[0]["multipliers"] + 1)) < 1e-6
        regular = [r for r in records if r["branch"] == 0 and r["event"] == 0]
        before = [r for r in regular if r["p"] > pd[0]["p"]][-1]
        after = [r for r in regular if r["p"] < pd[0]["p"]][0]
        assert crossing(before["multipliers"], after["multipliers"]) == "period_doubling"
        # the check on two responses close to the event (for neighbours that differ by several crossings) says
        # the same, and does not confirm a crossing of another kind there
        for kind, expected in (("period_doubling", True), ("neimark_sacker", False)):
            event = ContinuationPoint(pd[0]["p"], pd[0]["s"], math.nan, 1, kind, dict(x=pd[0]["x"]))
            assert study._confirmed_nearby(event, before, after) is expected
    finally:
        study.destroy()
    doubled = [r for r in records if r["branch"] == 1]
    assert len(doubled) >= 2 and all(r["periods"] == 2 for r in doubled)
    for r in doubled:
        assert r["residual"] < 1e-9 and r["half_residual"] > 1e-4


def test_a_neutral_saddle_is_told_from_a_neimark_sacker_point():
    """tau_NS = prod (mu_i mu_j - 1) vanishes for a real pair mu, 1/mu (a neutral saddle: nothing on the unit circle)
    and for a complex pair on the circle (Neimark-Sacker): neutral_saddle names the first, also with the zero
    padding of stored spectra; crossing sees nothing cross in the first."""
    e = np.exp(0.7j) * (1 + 1e-9)
    saddle = np.array([-2.5, -0.4 * (1 + 1e-9), 0.3 + 0.2j, 0.3 - 0.2j, 0.0, 0.0])
    ns = np.array([e, np.conj(e), -0.5, 0.2, 0.0])
    assert neutral_saddle(saddle) and not neutral_saddle(ns)
    for mu in (saddle[:4], ns[:4]):
        assert abs(tau_functions(mu)["neimark_sacker"]) < 1e-8
    assert crossing(saddle[:4], saddle[:4] * np.array([1.01, 1 / 1.01, 1, 1])) is None


def test_folds_of_a_driven_chain_are_located_and_confirmed_on_both_sides_of_the_turning_point():
    """Two precompressed beads between an actuator (a = 0.4) and a wall, gamma = 0.05: the softening resonance near
    omega = 1.01 folds twice (hysteresis), both folds confirmed. A located fold has a multiplier at +1 (R - I
    singular), and the check on two responses along the neighbours' chord, one on each side of the turning point,
    finds a real multiplier through +1 there too, and no multiplier through -1. (The second fold is located on one
    rank and bracketed on two, where the corrector takes other steps: the checks run on the located ones.)"""
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.05), 2, HarmonicWave(), 0.4, 0.8)
    study = ResponseCurve(ResponseParameters(drive, "omega", 1.1, algorithm=PseudoArclength(ds=0.02, ds_max=0.05),
                                             run_in=50, samples=0, max_steps=100), COMM)
    try:
        records = list(study.run())
        folds = [i for i, r in enumerate(records) if r["event"] == EVENTS["fold"]]
        assert len(folds) == 2 and all(records[i]["confirmed"] == 1 for i in folds)
        assert all(1.0 < records[i]["p"] < 1.03 for i in folds)
        located = [i for i in folds if records[i]["dp_ds"] == 0.0]
        assert located
        for i in located:
            assert np.min(np.abs(records[i]["multipliers"] - 1)) < 1e-5
            before = [r for r in records[:i] if r["event"] == 0][-1]
            after = [r for r in records[i:] if r["event"] == 0][0]
            for kind, expected in (("fold", True), ("period_doubling", False)):
                event = ContinuationPoint(records[i]["p"], records[i]["s"], math.nan, 1, kind, dict(x=records[i]["x"]))
                assert study._confirmed_nearby(event, before, after) is expected
    finally:
        study.destroy()


@pytest.mark.parametrize("make,name", [
    (lambda: LatticeModel.hertz(1.5, gamma=-0.1), "gamma"),
    (lambda: Drive(LatticeModel.hertz(), 4, HarmonicWave(), -0.1, 1.0), "amplitude"),
    (lambda: Drive(LatticeModel.hertz(), 4, HarmonicWave(), 0.1, 0.0), "omega"),
    (lambda: Drive(LatticeModel.hertz(), 0, HarmonicWave(), 0.1, 1.0), "N"),
    (lambda: SampledWave((0.0, 1.0, 0.5)), "not periodic"),
    (lambda: HalfSinePulses(1.5), "width"),
])
def test_bad_input_is_refused_naming_the_parameter(make, name):
    with pytest.raises(ParameterError, match=name):
        make()


# --- the study protocol ----------------------------------------------------------------------------------------------
def test_a_response_curve_that_stops_early_says_where_and_keeps_its_points(monkeypatch, capfd):
    """A continuation that cannot take a step ends the curve at the last converged response: the records up to it
    are kept, and the study says so in one note naming the parameter and the end it did not reach (never a
    silently shorter curve)."""
    from hertzpetsc import continuation
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.1), 3, HarmonicWave(), 0.05, 0.5)
    run = continuation.Continuation.run

    def stopping(self, until, max_steps=None):
        for k, point in enumerate(run(self, until, max_steps)):
            if k == 2:
                raise continuation.ContinuationError("omega", point.parameter, point.parameter + 0.01, "test")
            yield point
    monkeypatch.setattr(continuation.Continuation, "run", stopping)
    study = ResponseCurve(ResponseParameters(drive, "omega", 0.9, run_in=5, max_steps=20, samples=0), COMM)
    try:
        recs = list(study.run())
    finally:
        study.destroy()
    assert len(recs) == 4 and float(recs[-1]["p"]) < 0.9            # the first two, and the two steps taken
    assert "omega = 0.9" in study.ended and "last converged omega" in study.ended
    if COMM.getRank() == 0:
        err = capfd.readouterr().err
        assert err.count("note: the continuation stopped before omega = 0.9") == 1


def test_a_study_stopped_by_an_error_writes_the_table_of_its_records(monkeypatch, tmp_path):
    """Study.run_to_table (the drivers' loop): an error after records were written leaves the table of those
    records with the error below it, then is raised; the table of another run does not stay next to the file."""
    from hertzpetsc import continuation
    from hertzpetsc.errors import ConvergenceError
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.1), 3, HarmonicWave(), 0.05, 0.5)
    run = continuation.Continuation.run

    def failing(self, until, max_steps=None):
        for k, point in enumerate(run(self, until, max_steps)):
            if k == 1:
                raise ConvergenceError("test solver", -3, omega=point.parameter)
            yield point
    monkeypatch.setattr(continuation.Continuation, "run", failing)
    path = os.path.join(shared_tmp(tmp_path), "r.md")
    if COMM.getRank() == 0:
        with open(path, "w") as f:
            f.write("the table of another run\n")
    COMM.barrier()
    study = ResponseCurve(ResponseParameters(drive, "omega", 0.9, run_in=5, max_steps=20, samples=0), COMM)
    try:
        with pytest.raises(ConvergenceError, match="test solver"):
            study.run_to_table(path)
        done = len(study.records)
        expected = study.table()
    finally:
        study.destroy()
    COMM.barrier()
    with open(path) as f:
        table = f.read()
    assert done >= 1 and f"{done} records" in table and table.startswith(expected)
    assert "Stopped before the end: test solver did not converge (reason -3)" in table


def test_grid_mode_takes_the_natural_algorithm_it_is_given():
    """In grid mode a continuation.Natural given as the algorithm is the one stepping (here a corrector limit no
    step can meet: no grid value is reached after the first response, an error naming the values not computed),
    the default Natural otherwise."""
    from hertzpetsc.continuation import ContinuationError
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.1), 3, HarmonicWave(), 0.05, 0.5)
    out = []
    for algorithm in (Natural(max_corrector=1e-14, max_halvings=1), None):
        study = ResponseCurve(ResponseParameters(drive, "omega", 0.6, grid=(0.55, 0.6), algorithm=algorithm,
                                                 run_in=5, samples=0), COMM)
        recs = []
        try:
            for rec in study.run():
                recs.append(rec)
        except ContinuationError as err:
            recs.append(err)
        finally:
            study.destroy()
        out.append((recs, study.ended))
    (first, err), ended = out[0]
    assert float(first["p"]) == 0.5 and isinstance(err, ContinuationError) and str(err) == ended
    assert "omega = 0.55, 0.6 (2 of the 2 grid values) not computed" in ended and "last converged omega = 0.5" in ended
    assert len(out[1][0]) == 3 and out[1][1] is None


def test_a_long_grid_not_reached_is_named_in_one_short_line():
    """The grid values not computed are named by the first two, '...' and the last (a grid may hold 10^5)."""
    from hertzpetsc.continuation import ContinuationError
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.1), 3, HarmonicWave(), 0.05, 0.5)
    grid = tuple(0.5 + 0.01 * k for k in range(1, 11))
    study = ResponseCurve(ResponseParameters(drive, "omega", grid[-1], grid=grid, run_in=5, samples=0,
                                             algorithm=Natural(max_corrector=1e-14, max_halvings=1)), COMM)
    try:
        with pytest.raises(ContinuationError, match=r"omega = 0\.51, 0\.52, \.\.\., 0\.6 \(10 of the 10 grid values\)"):
            list(study.run())
    finally:
        study.destroy()


@pytest.mark.serial
@pytest.mark.parametrize("ranks", [1, 2])
def test_a_grid_that_reaches_none_of_its_values_is_an_error_not_an_empty_table(tmp_path, ranks):
    """driven_response.py -mode grid whose steps reach no grid value (a corrector limit no step meets): exit 3 with
    one error line on every rank naming the values not computed, the table of the records done (the first response)
    with the failure below it; it exited 0 with a table of no rows."""
    r = run_script("driven_response.py", "-N", 3, "-delta0", 1, "-gamma", 0.1, "-amplitude", 0.05, "-omega", 0.5,
                   "-mode", "grid", "-points", 3, "-p_end", 0.6, "-grid_max_corrector", 1e-14, "-run_in", 5,
                   "-samples_per_period", 0, "-output", tmp_path / "g.npz", "-table", tmp_path / "g.md",
                   ranks=ranks, timeout=120, cwd=tmp_path)
    line = one_error_line(r)
    assert r.returncode == 3 and "grid mode" in line and "omega = 0.55, 0.6 (2 of the 2 grid values) not computed" \
        in line and "last converged omega = 0.5" in line
    table = (tmp_path / "g.md").read_text()
    assert "; 1 records." in table and "Stopped before the end: grid mode" in table


def test_a_first_response_not_found_says_what_was_tried_and_what_may_help():
    """The sonic vacuum of 10 beads at omega = 0.1, a = 0.5 has no periodic response that the run-in reaches (its
    motion after the run-in is not periodic: ||P(X) - X|| / scale stays about 3e-2): Newton stalls (reason -8). The
    error (exit status 3) names the frequency, the run-in and its residual, and what may find a response; it said
    only 'did not converge (reason -8)'."""
    from hertzpetsc.errors import ConvergenceError
    drive = Drive(LatticeModel.hertz(1.5, gamma=0.05), 10, HarmonicWave(), 0.5, 0.1)
    study = ResponseCurve(ResponseParameters(drive, "omega", 0.6, run_in=50, samples=0), COMM)
    try:
        with pytest.raises(ConvergenceError) as caught:
            list(study.run())
    finally:
        study.destroy()
    msg = str(caught.value)
    assert caught.value.exit_status == 3 and "\n" not in msg
    assert msg.startswith("no periodic response of 1 driving period found at omega = 0.1:")
    assert "after 50 driving periods from rest" in msg and "run_in" in msg and "periods" in msg
    residual = float(msg.split("||P(X) - X|| / scale = ")[1].split(";")[0])
    assert residual > 1e-3                  # far above the shooting tolerance: the run-in did not settle


def test_driven_studies_follow_the_study_protocol():
    """Each driven study is a studies.base.Study: its record kind, fields and roles declared on the class, an
    in-memory store without output, and the call of before the protocol (loose arguments) building the same
    parameters and the same record file (constants and identity as the files written before hold them)."""
    from hertzpetsc.studies.base import Study
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.1), 3, HarmonicWave(), 0.05, 0.5)
    for cls, kind in ((ResponseCurve, "response"), (LinearResonances, "resonances"), (WaveEnds, "wave-ends"),
                      (Generation, "generation")):
        assert issubclass(cls, Study) and cls.FORMAT == f"hertzpetsc-driven-{kind}-1"
        assert set(cls.ROLES) == {"drive_", "floquet_"} and set(cls.DTYPES) <= set(cls.FIELDS)
    new = ResponseCurve(ResponseParameters(drive, "omega", 0.75, run_in=5, max_steps=6, samples=16, nmult=100), COMM)
    old = ResponseCurve(drive, "omega", 0.75, COMM, None, run_in=5, max_steps=6, samples=16, nmult=100)
    try:
        assert new.params == old.params and new.output is None and new.comm is COMM
        # the identity: the constants of the files of before, and the solver options that change numbers (none here)
        assert new.identity() == dict(new.constants(), solver_options="") and new.constants()["nmult"] == 6
        assert new.open().arrays()["multipliers"].shape == (0, 6) and new.records == []
        assert sorted(new.constants()) == ["N", "base_periods", "drive", "floquet", "jacobian", "mode", "nmult",
                                           "p_end", "parameter", "rtol", "tol"]
    finally:
        new.destroy()
        old.destroy()
    res = LinearResonances(drive, COMM, None, "new", [2], golden=20)          # the call of before
    try:
        assert res.params == ResonanceParameters(drive, (2,), golden=20) and res.modes == [2]
        assert res.identity() == dict(drive=res.constants()["drive"], modes=[2], tol=1e-10, rtol=1e-12, golden=20,
                                      solver_options="")
    finally:
        res.destroy()


def test_a_resume_from_other_inputs_or_other_solver_tolerances_is_refused(tmp_path, clean_options):
    """A wave-ends file names the branch and refinement files it was computed from with their contents' hashes: a
    resume from another -refined file (same name or not) is refused naming -refined, one with another
    -floquet_ts_rtol naming the solver options; the same inputs resume."""
    from types import SimpleNamespace
    from hertzpetsc.errors import RecordFileError
    from hertzpetsc.records import file_digest
    branch, refined = SimpleNamespace(alpha=1.5), SimpleNamespace(N=100, has=lambda q: True,
                                                                      check_alpha=lambda alpha, of=None: None)
    tmp = shared_tmp(tmp_path)
    files = {name: os.path.join(tmp, f"{name}.npz") for name in ("branch", "refined", "other")}
    out = os.path.join(tmp, "w.npz")

    def write(name, content):
        if COMM.getRank() == 0:
            with open(files[name], "wb") as f:
                f.write(content)
        COMM.barrier()

    def study(mode, refined_path=files["refined"]):
        return WaveEnds(WaveEndsParameters(branch, refined, [0.5], [4], [1e-12], branch_path=files["branch"],
                                           refined_path=refined_path), COMM, out, mode).open()
    for name in files:
        write(name, name.encode())
    study("new")
    with np.load(out) as z:
        assert str(z["refined_sha256"]) == file_digest(files["refined"], COMM) and str(z["solver_options"]) == ""
    study("resume")
    with pytest.raises(RecordFileError, match=r"refined_sha256 = .* set by the refinement file's content \(-refined\)"):
        study("resume", files["other"])
    write("refined", b"changed")
    with pytest.raises(RecordFileError, match="-refined"):
        study("resume")
    write("refined", b"refined")
    clean_options.setValue("floquet_ts_rtol", "1e-10")
    with pytest.raises(RecordFileError, match=r"solver_options = .* set by the solver options"):
        study("resume")


@pytest.mark.parametrize("make,name", [
    (lambda d: ResponseParameters(d, "eta", 1.0), "invalid parameter = 'eta'"),
    (lambda d: ResponseParameters(d, "omega", 0.5), "invalid p_end = 0.5: must differ"),
    (lambda d: ResponseParameters(d, "omega", 1.0, jacobian="full"), "invalid jacobian"),
    (lambda d: ResponseParameters(d, "omega", 1.0, tol=2.0), "invalid tol = 2.0"),
    (lambda d: ResponseParameters(d, "omega", 1.0, run_in=-1), "invalid run_in = -1: .* integer >= 0"),
    (lambda d: ResponseParameters(d, "omega", 1.0, grid=()), "invalid grid"),
    (lambda d: ResponseParameters("drive", "omega", 1.0), "invalid drive"),
    (lambda d: ResonanceParameters(d, modes=(4,)), r"invalid modes = 4: a mode number in \[1, N\] = \[1, 3\]"),
    (lambda d: ResonanceParameters(Drive(LatticeModel.hertz(1.5, gamma=0.1), 3, HarmonicWave(), 0.1, 0.5)),
     "invalid delta0"),
    (lambda d: ResonanceParameters(d, golden=0), "invalid golden"),
    # an end or grid value the drive refuses fails up front, not after the continuation reached it
    (lambda d: ResponseParameters(d, "amplitude", -0.01), "invalid p_end = -0.01: .* amplitude must be .* >= 0"),
    (lambda d: ResponseParameters(d, "omega", -1.0), "invalid p_end = -1.0: .* frequency must be .* > 0"),
    (lambda d: ResponseParameters(d, "gamma", -0.1), "invalid p_end = -0.1: .* damping must be .* >= 0"),
    (lambda d: ResponseParameters(d, "amplitude", 0.0), "invalid p_end = 0.0: .* amplitude must be > 0"),
    (lambda d: ResponseParameters(d, "omega", 1.0, grid=(0.6, -0.2)), "invalid grid = -0.2: .* > 0"),
    # an undamped chain has no isolated response at a resonance
    (lambda d: ResonanceParameters(Drive(LatticeModel.hertz(1.5, delta0=1.0), 3, HarmonicWave(), 0.1, 0.5)),
     "invalid gamma = 0.0: the resonances need a damped chain, gamma > 0"),
])
def test_driven_parameters_name_the_field_and_its_range(make, name):
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.1), 3, HarmonicWave(), 0.05, 0.5)
    with pytest.raises(ParameterError, match=name):
        make(drive)


def test_arclength_steps_and_damping_by_bonds_are_checked_as_the_continuation_layer_does():
    """corner_arclength refuses ds_max < ds (as continuation.PseudoArclength does), not silently raising ds_max;
    a chain damped by its bonds only (eta > 0) has its resonances."""
    from hertzpetsc.studies.driven import corner_arclength
    with pytest.raises(ParameterError, match=r"invalid ds_max = 0.001: .* >= 0.02"):
        corner_arclength(0.02, 0.001)
    a = corner_arclength(0.02, 0.02)
    assert (a.ds, a.ds_max) == (0.02, 0.02)
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, eta=0.01), 3, HarmonicWave(), 0.1, 0.5)
    assert ResonanceParameters(drive).drive is drive


def test_wave_ends_and_generation_parameters_are_checked():
    """The file-based studies' parameters: sizes within the periodic chain, wavenumbers refined in the file, a
    model of the branch's exponent, known signals, a bulk inside the chain."""
    from hertzpetsc.branch import Branch
    from hertzpetsc.studies.refinement import RefinedStates
    branch = Branch.load(os.path.join(DATA, "branch_alpha1.5.npz"), COMM)
    refined = RefinedStates.load(os.path.join(DATA, "refined_N100.npz"), COMM)
    q = branch.point(2 * math.pi / 5).q
    p = WaveEndsParameters(branch, refined, [q], [4, 10], [1e-12])
    assert p.q == (q,) and p.sizes == (4, 10) and p.rtols == (1e-12,)
    for kw, name in ((dict(rtols=[1e-12, 1e-12]), "rtols"), (dict(sizes=[4, 4]), "sizes"), (dict(q=[q, q]), "q")):
        with pytest.raises(ParameterError, match=f"invalid {name} = .* twice; the .* must be different"):
            WaveEndsParameters(**dict(dict(branch=branch, refined=refined, q=[q], sizes=[4]), **kw))
    with pytest.raises(ParameterError, match=r"invalid sizes = 99: .* 1 <= N <= P - 2 = 98"):
        WaveEndsParameters(branch, refined, [q], [99])
    with pytest.raises(ParameterError, match="invalid q = 1.3: the refinement file has no refined wave"):
        WaveEndsParameters(branch, refined, [1.3], [4])
    model = LatticeModel.hertz(1.5)
    g = GenerationParameters(branch, model, 8, ["half_sine"], [0.5], [0.1], [0.1], bulk=[0.2, 0.8])
    assert g.signals == ("half_sine",) and g.bulk == (0.2, 0.8)
    for kw, name in ((dict(model=LatticeModel.hertz(2.0)), "invalid alpha = 2.0: must be the branch's exponent"),
                     (dict(signals=["square"]), "invalid signals = 'square'"),
                     (dict(bulk=(0.5,)), "invalid bulk"), (dict(omegas=[0.0]), "invalid omegas = 0.0"),
                     (dict(gammas=[-0.1]), "invalid gammas = -0.1")):
        args = dict(branch=branch, model=model, N=8, signals=["harmonic"], omegas=[0.5], amplitudes=[0.1],
                    gammas=[0.1])
        with pytest.raises(ParameterError, match=name):
            GenerationParameters(**dict(args, **kw))


# --- the drivers -----------------------------------------------------------------------------------------------------
BAD = [(("-gamma", "-0.1"), "gamma"), (("-amplitude", "-1"), "amplitude"), (("-omega", "0"), "omega"),
       (("-N", "0"), "-N"), (("-signal", "samples", "-signal_samples", "0,1,0.5"), "not periodic"),
       (("-samples_per_period", "1"), "-samples_per_period"),
       (("-parameter", "amplitude", "-amplitude", "0.01", "-p_end", "-0.01"), "invalid -p_end = -0.01"),
       (("-ds_max", "0.001"), "invalid -ds_max = 0.001")]


def test_distinct_numbers_are_told_apart_relative_to_their_size():
    """-rtols 1e-12,1e-14 (the wave-ends driver's default) lists two tolerances, 1e-14,1e-14 one twice: members are
    the same when they agree to 1e-12 relative (an absolute floor made every pair below 1e-12 the same)."""
    from hertzpetsc.options import AppOptions
    kept = AppOptions.current
    try:
        opts = AppOptions()
        assert opts.numbers("hz_test_rtols", "1e-12,1e-14", expr=False, distinct=True) == [1e-12, 1e-14]
        assert opts.numbers("hz_test_q", "pi/10,pi/10+1e-9", distinct=True)[1] > math.pi / 10
        assert opts.numbers("hz_test_levels", "100,inf", expr=False, distinct=True) == [100.0, math.inf]
        for text in ("1e-14,1e-14", "1e-14,1.0000000000001e-14", "0,0", "inf,inf"):
            with pytest.raises(ParameterError, match="twice"):
                opts.numbers("hz_test_same", text, expr=False, distinct=True)
    finally:
        AppOptions.current = kept


@pytest.mark.serial
def test_drivers_refuse_bad_input_in_one_line_on_every_rank(tmp_path):
    for args, needle in BAD:
        r = run_script("driven_response.py", *args, "-output", tmp_path / "r.npz", "-table", tmp_path / "r.md",
                       ranks=2, timeout=120, cwd=tmp_path)
        line = one_error_line(r)
        assert r.returncode == 2 and needle in line, (args, r.stderr)
    assert not (tmp_path / "r.npz").exists()
    for name, args, needle in (("driven_resonances.py", ("-N", "4", "-gamma", "0"), "invalid -gamma = 0.0"),
                               ("driven_wave_ends.py", ("-rtols", "1e-12,1e-12"), "-rtols")):
        r = run_script(name, *args, "-output", tmp_path / "r.npz", "-table", tmp_path / "r.md", ranks=2, timeout=120,
                       cwd=tmp_path)
        assert r.returncode == 2 and needle in one_error_line(r), (name, r.stderr)
    assert not (tmp_path / "r.npz").exists()


@pytest.mark.serial
def test_driven_drivers_run(tmp_path):
    r = run_script("driven_response.py", "-N", 2, "-gamma", 0.1, "-amplitude", 1, "-omega", 1.69, "-p_end", 1.68,
                   "-mode", "grid", "-points", 3, "-run_in", 20, "-samples_per_period", 16, "-output",
                   tmp_path / "r.npz", "-table", tmp_path / "r.md", "-figures", tmp_path, ranks=2)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "driven_response.png").exists() and "Branch 0: 3 points" in (tmp_path / "r.md").read_text()
    r = run_script("driven_resonances.py", "-N", 2, "-modes", 1, "-golden", 6, "-output", tmp_path / "s.npz",
                   "-table", tmp_path / "s.md", "-figures", tmp_path)
    assert r.returncode == 0 and "| 1 | 1.22474487 |" in (tmp_path / "s.md").read_text(), r.stderr
    r = run_script("driven_wave_ends.py", "-q", "2*pi/5", "-sizes", 4, "-rtols", "1e-12", "-samples", 1024,
                   "-output", tmp_path / "w.npz", "-table", tmp_path / "w.md", "-figures", tmp_path)
    assert r.returncode == 0 and "| 2pi/5 (1.2566) | 20 | 4 |" in (tmp_path / "w.md").read_text(), r.stderr
    r = run_script("driven_generation.py", "-N", 8, "-signals", "half_sine", "-omegas", 0.5, "-amplitudes", 0.1,
                   "-gammas", 0.1, "-run_in", 10, "-output", tmp_path / "g.npz", "-table", tmp_path / "g.md",
                   "-figures", tmp_path, ranks=2)
    assert r.returncode == 0 and "| half_sine | 0.5 | 0.1 | 0.1 | yes |" in (tmp_path / "g.md").read_text(), r.stderr
    for name, kind in (("r", RESPONSE_KIND), ("s", RESONANCE_KIND), ("w", WAVE_ENDS_KIND), ("g", GENERATION_KIND)):
        assert kind.check(read_kind(str(tmp_path / f"{name}.npz"), kind, "x")) == ([], []), name   # as declared


@pytest.mark.serial
@pytest.mark.parametrize("ranks", [1, 2])
def test_a_singular_newton_matrix_is_a_convergence_failure_at_its_frequency(tmp_path, ranks):
    """A 4-bead sonic vacuum with a free end: beads out of contact over a whole period give R - I a multiplier at 1;
    its LU (LAPACK on one rank, MUMPS on two) fails. That is a convergence failure at the frequency (exit 3, one line),
    not PETSc's raw 'Zero pivot' or MUMPS error (exit 5)."""
    (tmp_path / "r.md").write_text("the table of another run\n")
    r = run_script("driven_response.py", "-N", 4, "-omega", 0.5, "-p_end", 0.52, "-max_steps", 3, "-run_in", 5,
                   "-right", "free", "-output", tmp_path / "r.npz", "-table", tmp_path / "r.md", "-force",
                   ranks=ranks, timeout=120, cwd=tmp_path)
    assert r.returncode == 3 and "zero pivot in R - I" in one_error_line(r) and "omega = 0.5" in r.stderr
    # the table on disk is the record file's (no record), the failure below it, not the previous run's
    table = (tmp_path / "r.md").read_text()
    assert "0 records" in table and "Stopped before the end:" in table and "zero pivot in R - I" in table


def test_a_continuation_whose_end_is_nearer_than_its_first_step_ends_there():
    """-p_end within the first arclength step (ds): the first step lands on p_end and the curve ends there (it
    overshot to a negative amplitude, and -p_end 0.001 gave a point at 4.5e-4)."""
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.05), 4, HarmonicWave(), 0.01, 1.0)
    study = ResponseCurve(ResponseParameters(drive, "amplitude", 0.001, run_in=5, samples=0), COMM)
    try:
        recs = list(study.run())
    finally:
        study.destroy()
    assert [float(r["p"]) for r in recs] == [0.01, 0.001] and study.ended is None
