"""The binary oscillation u0 (lemma binary)."""
import math

import numpy as np
import pytest

from hertzpetsc.binary import binary_oscillation
from hertzpetsc.hertz import HertzLaw


def full_period_rk4(pot, steps):
    """u0 on [0, 2 pi] by RK4 over the whole period, without any symmetry: the oracle for the symmetries."""
    dt = 2 * math.pi / steps
    u, v = 0.0, pot.p0
    out = [u]
    f = lambda y: -float(pot.dW(y))
    for _ in range(steps):
        k1u, k1v = v, f(u)
        k2u, k2v = v + 0.5 * dt * k1v, f(u + 0.5 * dt * k1u)
        k3u, k3v = v + 0.5 * dt * k2v, f(u + 0.5 * dt * k2u)
        k4u, k4v = v + dt * k3v, f(u + dt * k3u)
        u, v = u + dt / 6 * (k1u + 2 * k2u + 2 * k3u + k4u), v + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        out.append(u)
    return np.linspace(0, 2 * math.pi, steps + 1), np.array(out)


@pytest.mark.parametrize("alpha", [1.5, 2.0, 2.5])
def test_closed_forms_at_quarter_period(alpha):
    pot = HertzLaw(alpha)
    u, du = binary_oscillation(pot, np.array([0.5 * math.pi]), derivative=True)
    assert abs(u[0] - pot.amplitude(pot.p0)) < 1e-12
    assert abs(du[0]) < 1e-11
    u, du = binary_oscillation(pot, np.array([0.0]), derivative=True)
    assert u[0] == 0 and abs(du[0] - pot.p0) < 1e-12


@pytest.mark.parametrize("alpha", [1.5, 2.5])
def test_sampled_profile_is_accurate_to_1e10(alpha):
    xi = np.linspace(-7, 7, 2001)
    fine = binary_oscillation(alpha, xi, steps=1 << 17)
    assert np.max(np.abs(binary_oscillation(alpha, xi) - fine)) < 1e-10


@pytest.mark.parametrize("alpha", [1.5, 2.0])
def test_period_oddness_antiperiodicity_against_unsymmetrised_integration(alpha):
    pot = HertzLaw(alpha)
    xi, u = full_period_rk4(pot, 1 << 16)
    # RK4 over a whole period with step 1e-4: global error ~1e-13 (measured); the sampler is checked against it
    assert np.max(np.abs(binary_oscillation(pot, xi) - u)) < 1e-10
    assert abs(u[-1]) < 1e-10                                      # period 2 pi: u(2 pi) = u(0) = 0
    half = len(u) // 2
    assert np.max(np.abs(u[half:] + u[:half + 1])) < 1e-10          # u(xi + pi) = -u(xi)  (eq. sym)
    assert np.max(np.abs(u[::-1] + u)) < 1e-10                      # odd and 2 pi periodic: u(2 pi - xi) = -u(xi)
