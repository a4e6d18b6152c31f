"""The Hertz potential (eq. vhertz) and the closed forms of lemma binary (eqs. ci, period)."""
import math

import numpy as np
import pytest

from hertzpetsc.errors import ParameterError
from hertzpetsc.hertz import HertzLaw


@pytest.mark.parametrize("alpha", [1.0, 0.5, -2, float("nan"), float("inf"), "abc"])
def test_alpha_at_most_one_is_rejected(alpha):
    with pytest.raises(ParameterError, match=r"alpha.*> 1"):
        HertzLaw(alpha)


@pytest.mark.parametrize("alpha", [1.5, 2.0, 2.5, 1.2])
def test_derivatives_are_consistent(alpha):
    V = HertzLaw(alpha)
    x = np.linspace(-2, 2, 41)
    x = x[np.abs(x) > 0.05]
    eps = 1e-6
    # central differences: error O(eps^2 V''') away from the kink at 0
    assert np.allclose((V.V(x + eps) - V.V(x - eps)) / (2 * eps), V.dV(x), atol=1e-8)
    assert np.allclose((V.dV(x + eps) - V.dV(x - eps)) / (2 * eps), V.d2V(x), atol=1e-7)
    # no force without contact, repulsion under compression
    assert np.all(V.dV(x[x > 0]) == 0) and np.all(V.dV(x[x < 0]) < 0)
    # W(x) = V(-2|x|)/2 (proof of lemma binary)
    assert np.allclose(V.W(x), 0.5 * V.V(-2 * np.abs(x)), rtol=1e-14)


def measured_period(pot, p, steps=200000):
    """Period of u'' + W'(u) = 0, u(0) = 0, u'(0) = p, from a plain RK4 integration to the return of u' to p:
    an oracle independent of the closed form (time to the first maximum of u is T/4)."""
    u, v, t = 0.0, p, 0.0
    dt = float(pot.period(p)) / steps
    f = lambda y: -float(pot.dW(y))
    while True:
        k1u, k1v = v, f(u)
        k2u, k2v = v + 0.5 * dt * k1v, f(u + 0.5 * dt * k1u)
        k3u, k3v = v + 0.5 * dt * k2v, f(u + 0.5 * dt * k2u)
        k4u, k4v = v + dt * k3v, f(u + dt * k3u)
        un, vn = u + dt / 6 * (k1u + 2 * k2u + 2 * k3u + k4u), v + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        if vn <= 0 < v:  # u' changes sign at the maximum: locate it by linear interpolation of u'
            return 4 * (t + dt * v / (v - vn))
        u, v, t = un, vn, t + dt


@pytest.mark.parametrize("alpha,p", [(1.5, 0.3), (1.5, 2.0), (2.0, 1.0), (3.0, 0.7)])
def test_period_law_matches_integration(alpha, p):
    pot = HertzLaw(alpha)
    # the linear interpolation of u' at the maximum has error O(dt^2 u'''') ~ 1e-9 with these steps
    assert abs(measured_period(pot, p, steps=40000) - pot.period(p)) < 1e-6


@pytest.mark.parametrize("alpha", [1.1, 1.5, 2.0, 2.5, 4.0])
def test_p0_gives_period_two_pi(alpha):
    pot = HertzLaw(alpha)
    assert abs(pot.period(pot.p0) - 2 * math.pi) < 1e-12
    # p0 of eq. ci for alpha = 2: (3)^(-2) [sqrt(pi) Gamma(5/6)/Gamma(1/3)]^(-3), evaluated independently
    if alpha == 2.0:
        g = math.sqrt(math.pi) * math.gamma(1 / 3 + 0.5) / math.gamma(1 / 3)
        assert abs(pot.p0 - 3.0 ** -2 * g ** -3) < 1e-14


@pytest.mark.parametrize("e", [0.5, 1.0, 1.5, 2.0, 2.5, 3.5, 1.3, 4.5])
def test_abs_power_matches_the_general_power(e):
    from hertzpetsc.hertz import abs_power
    a = np.concatenate([[0.0], np.logspace(-12, 3, 200)])
    assert np.allclose(abs_power(a, e), a ** e, rtol=8 * np.finfo(float).eps, atol=0)
