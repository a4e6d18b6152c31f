"""Bonds of different beads (issue 38 item 3): a lattice model with one law per bond of its pattern, the chain's
right-hand side, Jacobian, tangents and energy with it (numpy; the compiled kernel evaluates one Hertz law), the
travelling waves of the pattern against the linear lattice's closed form, and on the chain."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import chain_arrays
from hertzpetsc.chain import Chain, ChainIntegrator, IntegrationTolerances
from hertzpetsc.dissipation import HuntCrossley
from hertzpetsc.errors import ParameterError
from hertzpetsc.families import AmplitudeFamily
from hertzpetsc.floquet import DenseFloquet
from hertzpetsc.fpu import FPULaw
from hertzpetsc.grid import ProfileGrid
from hertzpetsc.hertz import HertzLaw
from hertzpetsc.law import ScaledLaw
from hertzpetsc.model import ChainSpec, Damping, LatticeModel
from hertzpetsc.shooting import MEASURE_TOLERANCES, ShiftMap
from hertzpetsc.studies.precompression import wave_orbit

COMM = PETSc.COMM_WORLD
K_SOFT = 0.1                     # a soft contact (steel-PTFE-like: its constant 0.1 of the steel-steel one)
SOFT = ScaledLaw(HertzLaw(1.5, K_SOFT ** (-2 / 3)), K_SOFT)     # the same static force: overlap (F0 / K_c)^(2/3)
PATTERN = LatticeModel(HertzLaw(1.5, 1.0), (1.0, 1.0, 0.3)).with_bonds([HertzLaw(1.5, 1.0), SOFT, SOFT])


def test_a_bond_pattern_is_validated_described_and_rebuilt():
    m = PATTERN
    assert m.bonds == (HertzLaw(1.5, 1.0), SOFT, SOFT) and m.bond_law(4) is SOFT and m.bond_law(-1) is SOFT
    d = m.describe()
    assert d["bonds"][1] == dict(law="scaled", k=K_SOFT, base=dict(alpha=1.5, delta0=K_SOFT ** (-2 / 3)))
    assert LatticeModel.from_description(d) == m
    # one law in every bond is the model without a pattern: its identity is the uniform chain's, to the byte
    same = LatticeModel.hertz(1.5, (1.0, 1.0, 0.3), 1.0)
    assert same.with_bonds([HertzLaw(1.5, 1.0)] * 3) == same and "bonds" not in same.with_bonds([same.law] * 3)\
        .describe()
    # the bond pattern follows the model's lenses
    assert m.with_parameter("alpha", 1.6).bonds[1] == ScaledLaw(HertzLaw(1.6, K_SOFT ** (-2 / 3)), K_SOFT)
    assert m.rescaled(2.0).bonds[2] == ScaledLaw(HertzLaw(1.5, K_SOFT ** (-2 / 3) / 2), K_SOFT)
    assert m.with_damping(0.1).bonds == m.bonds
    with pytest.raises(ParameterError, match="bonds"):
        m.with_bonds([HertzLaw(1.5, 1.0), SOFT])
    with pytest.raises(ParameterError, match="bonds"):
        m.with_bonds([HertzLaw(1.5, 1.0), SOFT, FPULaw()])             # another degree: not rescaled alike
    with pytest.raises(ParameterError, match="law"):
        LatticeModel(HertzLaw(1.5, 2.0), (1.0, 1.0, 0.3), bonds=m.bonds)
    with pytest.raises(ParameterError, match="contact"):
        LatticeModel(m.law, m.masses, Damping(contact=HuntCrossley(0.1)), m.bonds)


def test_linear_lattice_of_a_bond_pattern():
    """B_cc = K_{c-1} + K_c, B_{c,c+1} = -K_c e^{iq}: at q = 0 the acoustic frequency is 0 and the pattern's sound
    speed omega / q -> sqrt(K_s / mean(m)), K_s the bonds in series (1 / K_s = mean(1 / K_c)); at the 2-bead pattern
    with bonds K_0, K_1 and unit masses omega^2 = K_0 + K_1 -+ |K_0 + K_1 e^{2iq}| (per-bead q)."""
    K = [b.linear_stiffness for b in PATTERN.bonds]
    assert K[1] == pytest.approx(1.5 * K_SOFT ** (2 / 3), rel=1e-14)
    assert PATTERN.linear_frequencies(0.0)[0] < 1e-7
    q = 1e-3
    c = PATTERN.linear_frequencies(q)[0] / q
    assert c == pytest.approx(math.sqrt(1 / np.mean(1 / np.array(K)) / np.mean(PATTERN.masses)), rel=1e-6)
    two = LatticeModel(HertzLaw(1.5, 1.0), (1.0, 1.0)).with_bonds([HertzLaw(1.5, 1.0), SOFT])
    K0, K1 = (b.linear_stiffness for b in two.bonds)
    for q in (0.3, 1.1):
        r = abs(K0 + K1 * np.exp(2j * q))
        assert np.allclose(two.linear_frequencies(q), np.sqrt([K0 + K1 - r, K0 + K1 + r]), rtol=1e-13)


@pytest.mark.parametrize("boundary", ["periodic", "fixed"])
def test_chain_of_a_bond_pattern_right_hand_side_and_jacobian(boundary):
    """Bond n has the law of bond n mod 3 (the wall bonds -1 and N - 1: bond 2's); the compiled kernel is not used; the
    exact Jacobian against forward differences of step 1e-7 (error ~1e-7 V''' ~ 1e-7)."""
    N = 6
    spec = ChainSpec(PATTERN, N, boundary)
    x = np.random.default_rng(3).normal(size=(N, 2)) * 0.3
    f, J, fd, kernel = chain_arrays(spec, x)
    assert kernel is None
    xe = np.concatenate([[x[-1, 0]], x[:, 0], [x[0, 0]]]) if boundary == "periodic" else \
        np.concatenate([[0.0], x[:, 0], [0.0]])
    r = np.diff(xe)                                            # bonds -1 .. N - 1
    force = np.array([PATTERN.bond_law(n).dV(r[n + 1]) for n in range(-1, N)])
    m = np.array([PATTERN.masses[n % 3] for n in range(N)])
    assert np.allclose(f[1::2], (force[1:] - force[:-1]) / m, rtol=1e-14, atol=1e-15)
    assert np.max(np.abs(J - fd)) < 1e-6
    uniform = chain_arrays(ChainSpec(PATTERN.with_law(HertzLaw(1.5, 1.0)), N, boundary), x)
    assert np.max(np.abs(uniform[0] - f)) > 1e-2                # the soft bonds change the forces


def test_energy_and_tangents_of_a_bond_pattern():
    """The Hamiltonian chain of the pattern conserves its energy (flow rtol 1e-12 over t = 20: drift ~1e-11 of E),
    and its tangent columns are the flow's linearisation (forward differences of step 1e-6: ~1e-6 of the entries)."""
    from hertzpetsc.tangent import TangentFlow
    N = 6
    spec = ChainSpec(PATTERN, N)
    x0 = np.random.default_rng(5).normal(size=(N, 2)) * 0.2
    ch = Chain(spec, COMM)
    X = ch.create_state()
    ch.set_from_array(X, x0)
    integ = ChainIntegrator(ch, IntegrationTolerances(1e-12, 1e-14))
    try:
        E0 = ch.energy(X)
        integ.integrate(X, 0.0, 20.0)
        moved = np.max(np.abs(ch.gather(X) - x0))
        E1 = ch.energy(X)
    finally:
        X.destroy()
        integ.destroy()
        ch.destroy()
    assert moved > 0.1 and abs(E1 - E0) < 1e-9 * E0
    flow = TangentFlow(spec, 2 * N, COMM, IntegrationTolerances(1e-12, 1e-14), "chain_")
    try:
        R, xT = flow.resolvent(x0, 2.0)
        fd = np.zeros_like(R)
        for k in range(2 * N):
            e = x0.ravel().copy()
            e[k] += 1e-6
            fd[:, k] = (flow.run(e.reshape(N, 2), 2.0, np.zeros((N, 2, 2 * N)))[0].ravel() - xT.ravel()) / 1e-6
    finally:
        flow.destroy()
    assert np.max(np.abs(R - fd)) < 1e-5 * np.max(np.abs(R))


@pytest.mark.parametrize("branch", ["acoustic", "optical"])
def test_small_amplitude_waves_of_a_bond_pattern(branch):
    """At a = 1e-5 the pattern's wave has the Bloch frequency of the scheme (the closed form with D2's symbol on
    e^{i xi}, 4 sin^2(h/2)/h^2; q = 60 h an exact shift): measured 2.4e-13 (acoustic) and 2.4e-11 (optical), the
    O(a^2) nonlinear shift; bound 1e-9."""
    Q = 0.3 * math.pi
    grid = ProfileGrid(200, COMM)
    cont = AmplitudeFamily(PATTERN, Q, grid, branch=branch)
    try:
        p = cont.solve_at(1e-5)
    finally:
        cont.destroy()
    symbol = 4 * math.sin(grid.h / 2) ** 2 / grid.h ** 2
    exact = PATTERN.linear_frequencies(Q)[0 if branch == "acoustic" else -1]
    assert abs(p.omega * math.sqrt(symbol) / exact - 1) < 1e-9


def test_a_wave_of_a_bond_pattern_on_the_chain():
    """The pattern's wave at a = 0.3, q = 2 pi / 9, put on 9 beads: S X(script-T) - X(0) is the profiles' O(h^2)
    error (E = 1.43e-4 at h = pi/90, 3.58e-5 at pi/180: ratio 4.000, measured; the flow's floor ~3e-15), and its
    dense Floquet spectrum has rho = 1 (the wave is stable at this amplitude: measured 1 - 2e-16) with the trivial
    multipliers split by the square root of that error."""
    N, q = 9, 2 * math.pi / 9
    E, orbits = [], []
    for K in (90, 180):
        cont = AmplitudeFamily(PATTERN, q, ProfileGrid(K, COMM))
        try:
            p = list(cont.points([1e-3, 0.3]))[-1]
        finally:
            cont.destroy()
        orbit = wave_orbit(PATTERN, q, p.a, list(p.profiles), p.lam, N, cont.grid.h)
        shift = ShiftMap(ChainSpec(PATTERN, N), COMM, MEASURE_TOLERANCES, "bonds_")
        try:
            E.append(shift.residual(orbit))
        finally:
            shift.destroy()
        orbits.append(orbit)
    assert E[1] < 1e-4 and E[0] / E[1] == pytest.approx(4.0, rel=1e-2)
    dense = DenseFloquet(ChainSpec(PATTERN, N), COMM, IntegrationTolerances(rtol=1e-11, atol=1e-13))
    try:
        spec = dense.spectrum(orbits[1])
    finally:
        dense.destroy()
    assert spec.trivial_spread < 1e-3 and abs(spec.rho - 1) < 1e-4


@pytest.mark.parametrize("right", ["wall", "free"])
def test_linear_driven_chain_of_a_bond_pattern_is_the_chains_linearisation(right):
    """studies.driven.linear_chain's stiffness matrix with each bond's V''(0) (the actuator's bond -1 and the wall's
    N - 1 have bond 2's law) is the chain's exact Jacobian at rest, -M^-1 Kmat, to rounding (V''(0) in closed form
    against V'' evaluated)."""
    from hertzpetsc.driven import Drive, HarmonicWave
    from hertzpetsc.studies.driven import linear_chain
    drive = Drive(PATTERN, 6, HarmonicWave(), 1e-6, 0.8, right=right)
    M, _, Kmat, K = linear_chain(drive)
    _, J, _, _ = chain_arrays(drive.spec(), np.zeros((6, 2)), t=math.pi / 2 / 0.8)     # the actuator at x = 0
    assert K == PATTERN.bond_law(-1).linear_stiffness
    assert np.allclose(J[1::2, 0::2], -np.linalg.solve(M, Kmat), rtol=1e-13, atol=1e-14)
