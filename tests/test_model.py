"""The lattice model as the one place a chain is described: the law protocol, damping, ends and actuators, and the
chain's right-hand side, Jacobian and energy balance honouring them."""
import math
from dataclasses import dataclass

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import chain_arrays
from hertzpetsc.chain import Chain, ChainIntegrator, IntegrationTolerances
from hertzpetsc.errors import ParameterError
from hertzpetsc.hertz import HertzLaw
from hertzpetsc.law import InteractionLaw, RescaledLaw
from hertzpetsc.model import (Actuator, ChainSpec, Damping, FunctionSignal, Harmonic, LatticeModel, SampledSignal)

COMM = PETSc.COMM_WORLD


@dataclass(frozen=True)
class CubicLaw(InteractionLaw):
    """An FPU-type law V'(r) = k r + b r^3 declared in a few lines: the chain needs nothing else."""

    k: float = 1.0
    b: float = 0.5

    def V(self, r):
        r = np.asarray(r, float)
        return 0.5 * self.k * r ** 2 + 0.25 * self.b * r ** 4

    def dV(self, r):
        r = np.asarray(r, float)
        return self.k * r + self.b * r ** 3

    def d2V(self, r):
        return self.k + 3 * self.b * np.asarray(r, float) ** 2

    def describe(self):
        return dict(law="cubic", k=self.k, b=self.b)


def test_a_new_law_is_declared_in_the_model_only():
    model = LatticeModel(CubicLaw())
    spec = ChainSpec(model, 6, "fixed")
    x = np.random.default_rng(0).normal(size=(6, 2)) * 0.3
    f, J, fd, _ = chain_arrays(spec, x)
    # m x_n'' = V'(x_{n+1} - x_n) - V'(x_n - x_{n-1}) with walls at 0
    xe = np.concatenate([[0.0], x[:, 0], [0.0]])
    r = np.diff(xe)
    assert np.allclose(f[1::2], CubicLaw().dV(r[1:]) - CubicLaw().dV(r[:-1]), rtol=1e-14, atol=1e-14)
    assert np.max(np.abs(J - fd)) < 1e-6
    assert model.describe()["law"] == "cubic"
    with pytest.raises(ParameterError, match="law"):
        LatticeModel(law="hertz")


def test_the_rescaled_law_is_the_closed_form_of_hertz():
    law = HertzLaw(1.5, 0.8)
    r = np.linspace(-2.0, 1.5, 41)
    for a in (0.01, 3.0):
        closed, generic = law.rescaled(a), RescaledLaw(law, a, law.degree)
        assert closed == HertzLaw(1.5, 0.8 / a)
        for f in ("dV", "d2V"):
            assert np.allclose(getattr(closed, f)(r), getattr(generic, f)(r), rtol=1e-14, atol=1e-14)
        # V's closed form subtracts delta0^(1+alpha) / (1+alpha): its round-off is eps delta0^(1+alpha)
        atol = 8 * np.finfo(float).eps * max(1.0, closed.delta0) ** 2.5
        assert np.allclose(closed.V(r), generic.V(r), rtol=1e-14, atol=atol)


@pytest.mark.parametrize("boundary,ends", [("periodic", {}), ("free", {}), ("fixed", {}),
                                           ("fixed", dict(left=Actuator(Harmonic(0.2, 1.3)))),
                                           ("free", dict(right=Actuator(Harmonic(0.1, 0.7, 0.4))))])
def test_damped_chain_jacobian_against_finite_differences(boundary, ends):
    model = LatticeModel.hertz(1.5, masses=(1.0, 0.6), delta0=0.5, gamma=0.05, eta=0.03)
    spec = ChainSpec(model, 8, boundary, **ends)
    x = np.random.default_rng(1).normal(size=(8, 2)) * 0.1
    _, J, fd, _ = chain_arrays(spec, x, t=0.7)
    assert np.max(np.abs(J - fd)) < 1e-6 * max(1.0, np.max(np.abs(J)))


def test_energy_balance_of_the_damped_driven_chain():
    """dE/dt = input power - dissipation, integrated along a trajectory (Simpson on 501 points; the flow's rtol is
    1e-12, Simpson's error with dt = 0.01 is O(dt^4) ~ 1e-9 of E)."""
    model = LatticeModel.hertz(1.5, masses=(1.0, 0.7), delta0=0.5, gamma=0.05, eta=0.03)
    spec = ChainSpec(model, 8, "fixed", left=Actuator(Harmonic(0.2, 1.3)))
    ch = Chain(spec, COMM)
    X = ch.create_state()
    ch.set_from_array(X, np.random.default_rng(1).normal(size=(8, 2)) * 0.1)
    integ = ChainIntegrator(ch, IntegrationTolerances(1e-12, 1e-14))
    try:
        ts = np.linspace(0.0, 5.0, 501)
        E, P, D = [], [], []
        for i, t in enumerate(ts):
            if i:
                integ.integrate(X, ts[i - 1], t)
            E.append(ch.energy(X, t))
            p_in, diss = ch.power(X, t)
            P.append(p_in)
            D.append(diss)
        E, P, D = map(np.array, (E, P, D))
        h = ts[1] - ts[0]
        simpson = h / 3 * ((P - D)[0] + (P - D)[-1] + 4 * (P - D)[1:-1:2].sum() + 2 * (P - D)[2:-1:2].sum())
        assert abs(E[-1] - E[0]) > 1e-2                       # a non-trivial exchange
        assert np.all(D >= 0)
        assert abs((E[-1] - E[0]) - simpson) < 1e-8
    finally:
        X.destroy()
        integ.destroy()
        ch.destroy()


def test_undamped_undriven_chain_is_unchanged():
    """gamma = eta = 0 takes the paper's code path: the same right-hand side as the model without damping."""
    x = np.random.default_rng(2).normal(size=(10, 2)) * 0.2
    f0, _, _, _ = chain_arrays(ChainSpec(LatticeModel.hertz(1.5), 10), x)
    f1, _, _, _ = chain_arrays(ChainSpec(LatticeModel.hertz(1.5, gamma=0.0, eta=0.0), 10), x)
    assert np.array_equal(f0, f1)


def test_signals():
    t = np.linspace(0, 3, 17)
    h = Harmonic(0.3, 2.0, 0.5)
    assert np.allclose(h.position(t), 0.3 * np.cos(2 * t + 0.5)) and h.period == pytest.approx(math.pi)
    s = SampledSignal(tuple(np.cos(2 * math.pi * np.arange(8) / 8) + 0.5 * np.sin(4 * math.pi * np.arange(8) / 8)),
                      2.0)
    exact = np.cos(math.pi * t) + 0.5 * np.sin(2 * math.pi * t)
    assert np.allclose(s.position(t), exact, atol=1e-13)
    assert np.allclose(s.velocity(t), -math.pi * np.sin(math.pi * t) + math.pi * np.cos(2 * math.pi * t), atol=1e-12)
    FunctionSignal(np.sin, np.cos, 2 * math.pi)
    with pytest.raises(ParameterError, match="not periodic"):
        FunctionSignal(np.sin, np.cos, 3.0)
    for bad in (dict(amplitude=-1.0, omega=1.0), dict(amplitude=1.0, omega=0.0), dict(amplitude=1.0, omega=-2.0)):
        with pytest.raises(ParameterError):
            Harmonic(**bad)


def test_model_and_ends_validation():
    with pytest.raises(ParameterError, match="gamma"):
        Damping(gamma=-0.1)
    with pytest.raises(ParameterError, match="eta"):
        LatticeModel.hertz(1.5, eta=float("nan"))
    with pytest.raises(ParameterError, match="N"):
        ChainSpec(LatticeModel.hertz(), 0, "fixed")
    with pytest.raises(ParameterError, match="periodic"):
        ChainSpec(LatticeModel.hertz(), 4, "periodic", left="wall")
    with pytest.raises(ParameterError, match="left"):
        ChainSpec(LatticeModel.hertz(), 4, "fixed", left="glue")
    with pytest.raises(ParameterError, match="N"):
        ChainSpec(LatticeModel.hertz(masses=(1, 2, 3)), 4, "free")
    spec = ChainSpec(LatticeModel.hertz(), 3, "fixed", left=Actuator(Harmonic(0.1, 1.0)))
    assert spec.driven and spec.right == "wall" and spec.with_length(6).driven


def test_linear_frequencies_closed_forms():
    K = 1.5 * 0.8 ** 0.5
    q = 0.9
    mono = LatticeModel.hertz(1.5, delta0=0.8)
    assert mono.linear_frequencies(q)[0] == pytest.approx(2 * math.sqrt(K) * math.sin(q / 2), rel=1e-14)
    eps = 0.4
    dimer = LatticeModel.hertz(1.5, masses=(1.0, eps), delta0=0.8)
    root = math.sqrt((1 + eps) ** 2 - 4 * eps * math.sin(q) ** 2)
    expected = [math.sqrt(K * ((1 + eps) - root) / eps), math.sqrt(K * ((1 + eps) + root) / eps)]
    assert np.allclose(dimer.linear_frequencies(q), expected, rtol=1e-13)


def test_tangent_flow_of_the_damped_chain_is_its_linearisation():
    """The tangent columns obey the damped variational equations: R(T) e_k against finite differences of the
    damped, driven flow (flow rtol 1e-12; differences of step 1e-6: error ~1e-6 of the entries)."""
    from hertzpetsc.tangent import TangentFlow
    model = LatticeModel.hertz(1.5, masses=(1.0, 0.7), delta0=0.5, gamma=0.2, eta=0.1)
    spec = ChainSpec(model, 4, "fixed", left=Actuator(Harmonic(0.05, 1.3)))
    x0 = np.random.default_rng(4).normal(size=(4, 2)) * 0.05
    tol = IntegrationTolerances(1e-12, 1e-14)
    flow = TangentFlow(spec, 8, COMM, tol, "chain_")
    try:
        R, xT = flow.resolvent(x0, 2.0)
        fd = np.zeros_like(R)
        for k in range(8):
            e = x0.ravel().copy()
            e[k] += 1e-6
            fd[:, k] = (flow.run(e.reshape(4, 2), 2.0, np.zeros((4, 2, 8)))[0].ravel() - xT.ravel()) / 1e-6
    finally:
        flow.destroy()
    assert np.max(np.abs(R - fd)) < 1e-5 * np.max(np.abs(R))
