"""Mass patterns through the wave's symmetry (hertzpetsc.symmetry, bloch, shooting): the cell is the pattern times the
wave's cell. A precompressed dimer (masses 1, 1/2, delta0 = 1, alpha = 3/2; its wave from the amplitude
continuation, put on the chain by orbit_on_chain) and a three-bead pattern: the symmetric refinement, the symmetric
spectrum against the dense one, the Bloch spectrum of the tiled chain and the residuals of its tiled modes."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import small_branch
from hertzpetsc.bloch import SymmetricFloquet, bloch_residuals, real_pairs
from hertzpetsc.branch import BranchPoint
from hertzpetsc.errors import ParameterError
from hertzpetsc.floquet import DenseFloquet, trivial_multipliers
from hertzpetsc.grid import ProfileGrid
from hertzpetsc.model import ChainSpec, LatticeModel
from hertzpetsc.families import AmplitudeFamily
from hertzpetsc.shooting import MEASURE_TOLERANCES, Refiner
from hertzpetsc.symmetry import WaveSymmetry
from hertzpetsc.waves import orbit_on_chain

SELF = PETSc.COMM_SELF
DIMER = LatticeModel.hertz(1.5, masses=(1.0, 0.5), delta0=1.0)


def refined(orbit):
    refiner = Refiner(orbit.spec, SELF, 1e-10)
    try:
        return refiner.refine(orbit)
    finally:
        refiner.destroy()


@pytest.fixture(scope="module")
def dimer_wave():
    """The dimer's acoustic wave at a = 1 (A = 1.007), q = 2 pi 4 / 20 per bead on 20 beads (10 cells; the wave's
    cell is 5 pattern cells, m' = 2, k = 3 cells), h = pi/100, refined on its cell (E <= 1e-10)."""
    q = 2 * math.pi * 4 / 20
    cont = AmplitudeFamily(DIMER, q, ProfileGrid(100, SELF))
    try:
        p = list(cont.points([1e-3, 1.0]))[-1]
    finally:
        cont.destroy()
    point = BranchPoint(q, p.a * p.profiles[0], math.pi / 100, DIMER, profiles=tuple(p.a * w for w in p.profiles),
                        omega=p.omega)
    orbit = orbit_on_chain(point, ChainSpec(DIMER, 20))
    return orbit, refined(orbit)


def compare(a, b, tol):
    """max over each spectrum without its trivial four of the distance to the other."""
    va, vb = (np.delete(v, trivial_multipliers(v)) for v in (a.multipliers, b.multipliers))
    return max(max(np.min(np.abs(vb - v)) for v in va), max(np.min(np.abs(va - v)) for v in vb)) < tol


def spectra(orbit, n_modes=0):
    dense = DenseFloquet(orbit.spec, SELF, MEASURE_TOLERANCES)
    fast = SymmetricFloquet(orbit.spec.model, SELF, MEASURE_TOLERANCES, n_modes=n_modes)
    try:
        return dense.spectrum(orbit), fast.spectrum(orbit)
    finally:
        dense.destroy()
        fast.destroy()


def test_pattern_symmetry_counts_cells():
    """m = 4 wavelengths on 10 cells of 2 beads: cell of 5 pattern cells (10 beads), m' = 2, k = 3 (3 x 2 = 1 + 5)."""
    s = WaveSymmetry(20, 4, 2)
    assert (s.g, s.M, s.m_cell, s.k, s.j) == (2, 10, 2, 3, 1)
    with pytest.raises(ParameterError, match="multiple of the mass pattern"):
        WaveSymmetry(15, 2, 2)


def test_dimer_wave_is_refined_on_its_cell(dimer_wave):
    """The wave from the h = pi/100 profiles is off by O(h^2) (measured E = 4e-4); the symmetric refinement (the
    short map: 3 cells in script-T / 2, script-T = 2 q / omega) makes it a travelling wave to 1e-10 on the 20 beads
    over script-T."""
    orbit, ref = dimer_wave
    assert orbit.T == pytest.approx(2 * orbit.q / orbit.omega, rel=1e-15)
    assert 1e-5 < ref.E_initial and ref.E <= 1e-10


def test_dimer_symmetric_spectrum_is_the_dense_spectrum(dimer_wave):
    """All 40 multipliers: the dense F_q (40 tangents over script-T) and the cell's two sectors over script-T / 2.
    The wave is unstable (rho = 1.111); simple multipliers agree to the flow's accuracy (measured 2e-13 for rho and
    for every nontrivial one); 1e-9 and 1e-6 (double multipliers on the unit circle split as the square root of
    the flows' difference) leave margins."""
    _, ref = dimer_wave
    dense, fast = spectra(ref.orbit)
    assert len(fast.multipliers) == 40 and (fast.M, fast.L) == (10, 2)
    assert dense.rho > 1.05 and abs(dense.rho - fast.rho) < 1e-9 and compare(dense, fast, 1e-6)


def test_dimer_bloch_sectors_on_the_tiled_chain(dimer_wave):
    """The refined wave tiled on 40 beads (4 sectors of the 10-bead cell): Bloch = dense (measured 2e-13), and the
    tiled modes of the 6 dominant multipliers are eigenvectors of the full chain's F_q (matrix-free residuals,
    measured 5e-13)."""
    _, ref = dimer_wave
    full = ref.orbit.tiled(2)
    dense, fast = spectra(full, n_modes=6)
    assert fast.L == 4 and dense.rho > 1.05 and abs(fast.rho - dense.rho) < 1e-9 and compare(dense, fast, 1e-6)
    res, products = bloch_residuals(full, real_pairs(fast.modes, fast.L), PETSc.COMM_WORLD, MEASURE_TOLERANCES)
    assert products <= 12 and np.max(res) < 1e-9


def test_three_bead_pattern_against_the_monatomic_chain():
    """The paper's unstable wave q = pi/5 read with a pattern of three unit masses on 30 beads: script-T = 3 q / omega
    and S the shift by three beads, so F_q(p = 3) = F_q(p = 1)^3 around a travelling wave; 10 cells, m' = 3,
    k = 7 cells. The refinement on the pattern's cell reaches E <= 1e-10; the dense and symmetric p = 3 spectra are
    the cubes of the monatomic one: rho to the flow's accuracy, and the multipliers that are double on the unit
    circle within 2e-5, since they split as the square root of the orbit's residual E <= 1e-10 (measured 2.8e-6,
    the trivial ones excluded); the tiled modes on 60 beads are eigenvectors of the chain."""
    point = small_branch().point(math.pi / 5)
    triple = LatticeModel.hertz(1.5, masses=(1.0, 1.0, 1.0))
    three = orbit_on_chain(BranchPoint(point.q, point.u_half, point.h, triple, profiles=(point.u_half,) * 3),
                           ChainSpec(triple, 30))
    one = orbit_on_chain(point, ChainSpec(point.model, 30))
    assert np.array_equal(one.x, three.x) and three.T == pytest.approx(3 * one.T, rel=1e-15)
    assert (three.symmetry.M, three.symmetry.m_cell, three.symmetry.k) == (30, 3, 7)
    ref = refined(three)
    assert ref.E <= 1e-10
    mono = DenseFloquet(one.spec, SELF, MEASURE_TOLERANCES)
    try:
        cubes = mono.spectrum(one.with_state(ref.x, "refined"))
    finally:
        mono.destroy()
    cubes.multipliers = cubes.multipliers ** 3
    dense, fast = spectra(ref.orbit)
    assert dense.rho > 1.5 and abs(cubes.rho - dense.rho) < 1e-9 * dense.rho and abs(fast.rho - dense.rho) < 1e-9
    assert compare(cubes, dense, 2e-5) and compare(fast, dense, 2e-5)
    full = ref.orbit.tiled(2)
    fast = SymmetricFloquet(triple, SELF, MEASURE_TOLERANCES, n_modes=4)
    try:
        b = fast.spectrum(full)
    finally:
        fast.destroy()
    res, _ = bloch_residuals(full, real_pairs(b.modes, b.L), SELF, MEASURE_TOLERANCES)
    assert b.L == 2 and np.max(res) < 1e-9


def test_pattern_orbit_refuses_a_chain_of_another_lattice(dimer_wave):
    orbit, _ = dimer_wave
    point = BranchPoint(orbit.q, np.zeros(101), math.pi / 100, DIMER, profiles=(np.zeros(101),) * 2)
    with pytest.raises(ParameterError, match="model"):
        orbit_on_chain(point, ChainSpec(LatticeModel.hertz(1.5, masses=(1.0, 0.4), delta0=1.0), 20))
    with pytest.raises(ParameterError, match="multiple of the mass pattern"):
        ChainSpec(DIMER, 15)
