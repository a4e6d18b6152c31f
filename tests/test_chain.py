"""The chain (eq. nc) on TS: Jacobian, tangent-linear flow, energy, boundaries, rank independence, interpolation."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import chain, small_branch
from hertzpetsc.chain import Chain, ChainIntegrator, IntegrationTolerances
from hertzpetsc.errors import ParameterError
from hertzpetsc.model import ChainSpec
from hertzpetsc.stencil import lagrange_periodic
from hertzpetsc.tangent import TangentFlow
from hertzpetsc.waves import check_chain_wavenumber, orbit_on_chain

COMM = PETSc.COMM_WORLD


def wave(N, m, alpha=1.5):
    """The coarse branch's wave with m wavelengths on N beads."""
    return orbit_on_chain(small_branch(alpha).point(2 * math.pi * m / N), chain(N, alpha))


def random_state(N, seed=0):
    rng = np.random.default_rng(seed)
    return np.stack([rng.normal(0, 0.3, N), rng.normal(0, 0.3, N)], axis=1)


@pytest.mark.parametrize("boundary", ["periodic", "free", "fixed"])
def test_jacobian_matches_finite_differences(boundary):
    ch = Chain(chain(12, 1.5, boundary), COMM)
    X = ch.create_state()
    ch.set_from_array(X, random_state(12))
    J = ch.create_jacobian()
    ch.rhs_jacobian(None, 0.0, X, J, J)
    v = ch.create_state()
    ch.set_from_array(v, random_state(12, seed=1))
    Jv = v.duplicate()
    J.mult(v, Jv)
    eps = 1e-6
    Fp, Fm, Xp, Xm = (ch.create_state() for _ in range(4))
    X.copy(Xp); Xp.axpy(eps, v)
    X.copy(Xm); Xm.axpy(-eps, v)
    ch.rhs(None, 0, Xp, Fp)
    ch.rhs(None, 0, Xm, Fm)
    Fp.axpy(-1, Fm)
    Fp.scale(0.5 / eps)
    Fp.axpy(-1, Jv)
    # central differences, O(eps^2) except at bonds with |r| < eps (V'' is C^{0,1/2}): none in this state
    assert Fp.norm() <= 1e-7 * Jv.norm()
    ch.destroy()


# Central differences with eps = 1e-4 through fixed RK4 steps (dt = 1e-3, the same steps for every run, so the
# discrete flow itself is differentiated). alpha = 5/2: V'' is C^1, the error is O(eps^2) ~ 1e-9 (measured
# 2e-9). alpha = 3/2: V'' is only C^{0,1/2} where contacts open and close, and the difference quotient has an
# O(eps^{1/2}) error on the steps that straddle such an event (measured ~1e-6). An error in the tangent
# equations would show at O(1).
@pytest.mark.parametrize("alpha,bound", [(2.5, 1e-8), (1.5, 1e-5)])
def test_tangent_flow_matches_finite_differences_of_the_flow(alpha, bound):
    N = 20
    w = wave(N, 2, alpha)
    opts = PETSc.Options()
    fixed = {"chain_ts_adapt_type": "none", "chain_ts_rk_type": "4"}
    for k, val in fixed.items():
        opts.setValue(k, val)
    try:
        flow = TangentFlow(chain(N, alpha), 1, COMM, None, "chain_")
    finally:
        for k in fixed:
            opts.delValue(k)
    v = random_state(N, seed=3)[:, :, None]
    _, Rv = flow.run(w.x, w.T, v)
    zero = np.zeros((N, 2, 1))
    eps = 1e-4
    xp, _ = flow.run(w.x + eps * v[:, :, 0], w.T, zero)
    xm, _ = flow.run(w.x - eps * v[:, :, 0], w.T, zero)
    flow.destroy()
    fd = (xp - xm) / (2 * eps)
    assert np.max(np.abs(fd - Rv[:, :, 0])) <= bound * np.max(np.abs(Rv))


def test_energy_is_conserved_and_momentum_too():
    ch = Chain(chain(30), COMM)
    X = ch.create_state()
    s = random_state(30, seed=5)
    ch.set_from_array(X, s)
    E0 = ch.energy(X)
    integ = ChainIntegrator(ch)
    steps = integ.integrate(X, 0.0, 20.0)
    a = ch.gather(X)
    # each step's local error is controlled at rtol = 1e-12 of the state: the drift is bounded by the sum over the
    # ~1500 steps (measured 3e-11 on 1 rank, 1.6e-10 on 2, where round-off changes the step sequence)
    assert abs(ch.energy(X) - E0) <= steps * 1e-12 * E0
    assert abs(a[:, 1].sum() - s[:, 1].sum()) <= 1e-10
    integ.destroy()
    ch.destroy()


def test_fixed_walls_and_free_ends():
    """A compressed bead next to a wall is pushed back; a free end bead feels nothing beyond the chain."""
    for boundary, expect_sign in (("fixed", 1.0), ("free", 0.0)):
        ch = Chain(chain(5, 1.5, boundary), COMM)
        X, F = ch.create_state(), ch.create_state()
        s = np.zeros((5, 2))
        s[0, 0] = -0.1                                      # bead 1 moved towards the left wall
        ch.set_from_array(X, s)
        ch.rhs(None, 0, X, F)
        f = ch.gather(F)
        assert np.sign(f[0, 1]) == expect_sign and abs(f[0, 1]) == pytest.approx(expect_sign * 0.1 ** 1.5)
        ch.destroy()


def _run_on(comm, w, N, t, tol=None):
    ch = Chain(chain(N), comm)
    X = ch.create_state()
    ch.set_from_array(X, w.x)
    integ = ChainIntegrator(ch, tol)
    integ.integrate(X, 0.0, t, dt=1e-2)
    out = ch.gather(X)
    integ.destroy()
    ch.destroy()
    return out


def test_one_rank_equals_all_ranks(clean_options):
    """Under mpiexec -n 2: the same trajectory on COMM_WORLD and COMM_SELF.

    With fixed steps every bead's update is the same arithmetic on any partition: identical to round-off. With the
    adaptive controller, reductions sum in another order on 2 ranks and the step sequences may part; each run is
    then within the integrator's global error of the exact flow, checked against a rtol 1e-14 run (measured
    1e-10 to 4e-10 relative over 5 script-T of this unstable wave; bound 1e-8)."""
    N = 40
    w = wave(N, 4)
    for key, value in (("chain_ts_adapt_type", "none"), ("chain_ts_rk_type", "4")):
        clean_options.setValue(key, value)
    fixed = [_run_on(comm, w, N, 2 * w.T) for comm in (PETSc.COMM_SELF, PETSc.COMM_WORLD)]
    for key in ("chain_ts_adapt_type", "chain_ts_rk_type"):
        clean_options.delValue(key)
    scale = np.max(np.abs(fixed[0]))
    assert np.max(np.abs(fixed[0] - fixed[1])) <= 1e-13 * scale
    ref = _run_on(PETSc.COMM_SELF, w, N, 5 * w.T, IntegrationTolerances(1e-14, 1e-16))
    for comm in (PETSc.COMM_SELF, PETSc.COMM_WORLD):
        assert np.max(np.abs(_run_on(comm, w, N, 5 * w.T) - ref)) <= 1e-8 * scale


def test_interpolation_orders():
    n = 64
    errs, derrs = [], []
    for n in (32, 64, 128):
        h = 2 * math.pi / n
        f = np.sin(np.arange(n) * h) + 0.3 * np.cos(2 * np.arange(n) * h)
        pts = np.linspace(0, 2 * math.pi, 101)[:-1] + 0.0123
        exact = np.sin(pts) + 0.3 * np.cos(2 * pts)
        dexact = np.cos(pts) - 0.6 * np.sin(2 * pts)
        errs.append(np.max(np.abs(lagrange_periodic(f, h, pts) - exact)))
        derrs.append(np.max(np.abs(lagrange_periodic(f, h, pts, derivative=True) - dexact)))
    assert np.all(np.log2(np.array(errs[:-1]) / errs[1:]) > 5.7)     # degree 5: O(h^6)
    assert np.all(np.log2(np.array(derrs[:-1]) / derrs[1:]) > 4.7)   # derivative: O(h^5)
    f = np.arange(10.0) ** 2
    assert np.array_equal(lagrange_periodic(f, 1.0, np.array([3.0, 4.0])), [9.0, 16.0])


@pytest.mark.parametrize("N,q", [(100, math.pi / 3), (7, math.pi)])
def test_chain_must_hold_whole_wavelengths(N, q):
    with pytest.raises(ParameterError, match="N q / \\(2 pi\\)"):
        check_chain_wavenumber(q, N)


@pytest.mark.parametrize("kw,name", [(dict(N=1), "N"), (dict(boundary="loose"), "boundary"), (dict(alpha=0.9), "alpha"),
                                     (dict(N=7, masses=(1.0, 0.5)), "N"), (dict(masses=()), "masses")])
def test_bad_chain_parameters(kw, name):
    with pytest.raises(ParameterError, match=name):
        ChainSpec.hertz(**kw)


@pytest.mark.parametrize("rtol,atol", [(0, 1e-14), (1e-12, -1), (float("nan"), 1e-14)])
def test_bad_tolerances(rtol, atol):
    with pytest.raises(ParameterError, match="tol"):
        IntegrationTolerances(rtol, atol)


def test_nonpositive_time_is_rejected():
    ch = Chain(chain(10), COMM)
    integ = ChainIntegrator(ch)
    with pytest.raises(ParameterError, match="final time"):
        integ.integrate(ch.create_state(), 0.0, 0.0)
    integ.destroy()
    ch.destroy()


def test_matrix_free_monodromy_equals_dense():
    """The shell operator's product equals the dense S R(T; 0) applied to the same vector (same flow)."""
    from hertzpetsc.tangent import MonodromyModShift
    N = 10
    w = wave(N, 2)
    dense_flow = TangentFlow(w.spec, 2 * N, COMM, None, "chain_")
    F, _ = dense_flow.monodromy_mod_shift(w.x, w.T)
    dense_flow.destroy()
    op = MonodromyModShift(w.spec, w.x, w.T, COMM, None, "chain_")
    A = op.create_mat()
    x, y = A.createVecs()
    v = random_state(N, seed=11).ravel()
    base = op.base
    x.getArray()[:] = v[2 * base.xs:2 * base.xe]
    A.mult(x, y)
    got = base.gather(y).ravel()
    # different tangent counts change the adaptive steps: agreement to the flow's tolerance budget
    assert np.max(np.abs(got - F @ v)) <= 1e-9 * np.max(np.abs(F @ v)) and op.products == 1
    A.destroy()
    op.destroy()


def test_implicit_integrator_uses_the_exact_jacobian(clean_options):
    """Crank-Nicolson (needs the Jacobian) with small fixed steps agrees with the explicit default to O(dt^2)."""
    params = chain(16, 1.5, "fixed")
    s = random_state(16, seed=9)
    out = []
    for opts in ({}, {"chain_ts_type": "cn", "chain_ts_adapt_type": "none", "chain_snes_rtol": "1e-12"}):
        for k, v in opts.items():
            clean_options.setValue(k, v)
        ch = Chain(params, COMM)
        X = ch.create_state()
        ch.set_from_array(X, s)
        integ = ChainIntegrator(ch)
        integ.integrate(X, 0.0, 1.0, dt=1e-3)
        out.append(ch.gather(X))
        integ.destroy()
        ch.destroy()
    # CN error ~ dt^2 |x'''| T / 12 ~ 1e-7 for these O(1) data
    assert np.max(np.abs(out[0] - out[1])) < 1e-5
