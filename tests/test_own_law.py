"""A law declared in this file alone (issue 38, item 1: "adding a law is a new file and its tests"): the Morse bond
goes through every route with no library file changed for it: waves in the amplitude from the linear limit and in
the wavenumber, refinement on a finite chain, Floquet (dense and Bloch), dynamics, a driven response, and the
registry by name."""
import math
from dataclasses import dataclass

import numpy as np
import pytest
from petsc4py import PETSc

import hertzpetsc as hz
from hertzpetsc.chain import Chain, ChainIntegrator, IntegrationTolerances
from hertzpetsc.driven import Drive, HarmonicWave
from hertzpetsc.families import AmplitudeFamily, WavenumberFamily
from hertzpetsc.grid import ProfileGrid
from hertzpetsc.law import InteractionLaw
from hertzpetsc.model import ChainSpec, LatticeModel

COMM = PETSc.COMM_WORLD


@dataclass(frozen=True)
class MorseLaw(InteractionLaw):
    """V(r) = (k / (2 c^2)) (1 - e^(-c r))^2: stiffness k = V''(0), range 1/c (a bond that breaks when stretched)."""

    name = "morse-test"
    k: float = 1.0
    c: float = 1.0

    @property
    def reference_amplitude(self):
        return 1.0 / self.c

    def V(self, r):
        return self.k / (2 * self.c ** 2) * np.expm1(-self.c * np.asarray(r, float)) ** 2

    def dV(self, r):
        e = np.exp(-self.c * np.asarray(r, float))
        return self.k / self.c * (1 - e) * e

    def d2V(self, r):
        e = np.exp(-self.c * np.asarray(r, float))
        return self.k * e * (2 * e - 1)


LAW = MorseLaw(1.2, 0.8)
MODEL = LatticeModel(LAW)
Q = 2 * math.pi / 5


def test_the_law_is_known_by_name_and_its_parameters_are_continuation_parameters():
    assert LatticeModel.from_description(MODEL.describe()) == MODEL
    assert MODEL.with_parameter("c", 0.5).law == MorseLaw(1.2, 0.5)
    with pytest.raises(hz.ParameterError, match="alpha"):
        MODEL.with_alpha(1.5)
    LAW.check_consistency()


def test_waves_in_the_amplitude_from_the_linear_limit_and_in_the_wavenumber():
    """omega(a) from the linear wave: at a = 1e-3 / c the linear frequency 2 sqrt(k) sin(q/2) (1 + C a^2) (C from
    the law's Taylor coefficients, by differences) to the scheme's h^2 error; continued in q at a = 0.3 / c, the
    wave at 2 pi / 8 is the amplitude family's there to the Newton tolerance (two routes, one problem)."""
    grid = ProfileGrid(128, COMM)
    a0 = 1e-3 / LAW.c
    fam = AmplitudeFamily(MODEL, Q, grid)
    try:
        small = fam.step_to(a0)
        big = fam.step_to(0.3 / LAW.c)
    finally:
        fam.destroy()
    lin = 2 * math.sqrt(LAW.k) * math.sin(Q / 2)
    h2 = (math.pi / 128) ** 2 * lin          # the scheme's O(h^2) dispersion error (test_laws: order 2 observed)
    assert abs(small.omega - lin * (1 + LAW.stokes_coefficient(Q) * a0 ** 2)) < h2
    assert abs(big.omega / lin - 1) > 1e-3                     # nonlinear: far from the linear frequency
    qfam = WavenumberFamily(MODEL, 0.3 / LAW.c, grid, Q)
    try:
        assert qfam.first.omega == pytest.approx(big.omega, rel=1e-10)
        at = qfam.step_to(2 * math.pi / 8)
    finally:
        qfam.destroy()
    fam = AmplitudeFamily(MODEL, 2 * math.pi / 8, grid)
    try:
        direct = fam.step_to(0.3 / LAW.c)
    finally:
        fam.destroy()
    assert at.q == pytest.approx(2 * math.pi / 8, rel=1e-15)
    assert at.omega == pytest.approx(direct.omega, rel=1e-8)
    assert np.max(np.abs(np.asarray(at.profiles[0]) - np.asarray(direct.profiles[0]))) < 1e-7


@pytest.fixture(scope="module")
def refined():
    """The wave at q = 2 pi / 5, A = 0.3 / c on 10 beads, refined to E <= 1e-10 (tol of the flows 1e-12)."""
    orbit = hz.wave(MODEL, Q, 0.3 / LAW.c, 10, cells_per_pi=128, comm=COMM)
    return orbit, hz.refine(orbit, tol=1e-10, comm=COMM)


def test_refinement_on_a_finite_chain(refined):
    """Gauss-Newton reaches E <= tol from the grid's wave, whose own E is the profile's O(h^2) error."""
    orbit, r = refined
    assert r.E <= 1e-10 < r.E_initial < 1e-3
    assert np.max(np.abs(r.orbit.x - orbit.x)) < 1e-3 * np.max(np.abs(orbit.x))


def test_floquet_dense_and_bloch_agree_with_the_trivial_multipliers(refined):
    """All 2N multipliers by the dense route and from the Bloch sectors of the wave's cell agree; the Hamiltonian
    flow's multipliers come in pairs mu, 1/conj(mu) and include the trivial ones at 1."""
    orbit = refined[1].orbit
    dense = hz.multipliers(orbit, method="dense", comm=COMM)
    bloch = hz.multipliers(orbit, method="symmetric", comm=COMM)
    md, mb = np.sort_complex(dense.multipliers), np.sort_complex(bloch.multipliers)
    assert len(md) == len(mb) == 2 * orbit.N
    assert np.max(np.abs(md - mb)) < 1e-6
    assert np.min(np.abs(md - 1)) < 1e-4
    assert max(np.min(np.abs(md - 1 / np.conj(m))) for m in md) < 1e-5
    assert dense.rho == pytest.approx(bloch.rho, abs=1e-6)


def test_dynamics_conserve_the_energy_and_carry_the_wave(refined):
    """Ten periods of the refined wave in the chain's TS (rtol 1e-12): the energy is conserved to the flow's
    tolerance and the state after script-T is the state shifted by one bead."""
    orbit = refined[1].orbit
    ch = Chain(orbit.spec, COMM)
    X = ch.create_state()
    integ = ChainIntegrator(ch, IntegrationTolerances(1e-12, 1e-14))
    try:
        ch.set_from_array(X, orbit.x)
        E0 = ch.energy(X)
        integ.integrate(X, 0.0, orbit.T)
        x1 = ch.gather(X)
        shifted = np.roll(orbit.x, -1, axis=0)   # x_n(T) = x_{n-1}(0) or x_{n+1}(0): the wave moves one bead
        other = np.roll(orbit.x, 1, axis=0)
        assert min(np.max(np.abs(x1 - shifted)), np.max(np.abs(x1 - other))) < 1e-8
        integ.integrate(X, orbit.T, 10 * orbit.T)
        assert ch.energy(X) == pytest.approx(E0, rel=1e-9)
    finally:
        X.destroy()
        integ.destroy()
        ch.destroy()


def test_a_driven_damped_response_and_its_multipliers():
    """The chain of 8 beads driven at one end (wall at the other, on-site damping gamma) has a periodic response
    to tol; its multipliers' product is Liouville's exp(-gamma N T) and they pair as mu mu' = exp(-gamma T)."""
    gamma, N = 0.05, 8
    drive = Drive(MODEL.with_damping(gamma), N, HarmonicWave(), 0.05 / LAW.c, 0.7)
    (r,) = hz.response(drive, 0.7, run_in=20, tol=1e-10, samples=0, comm=COMM)
    assert r.residual <= 1e-10 and np.max(np.abs(r.x[:, 0])) > 1e-3
    mu = r.multipliers
    assert len(mu) == 2 * N and r.rho < 1
    assert np.sum(np.log(np.abs(mu))) == pytest.approx(-gamma * N * r.T, rel=1e-8)
    assert max(np.min(np.abs(m * mu - math.exp(-gamma * r.T))) for m in mu) < 1e-8
