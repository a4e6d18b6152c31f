"""The wave's space and time symmetries (hertzpetsc.symmetry) and the fast routes built on them: the symmetric
refinement and the symmetric Floquet spectrum against the paper's full map and dense F_q, on every rank count."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import chain, small_branch
from hertzpetsc.bloch import SymmetricFloquet
from hertzpetsc.errors import ParameterError
from hertzpetsc.floquet import DenseFloquet, trivial_multipliers
from hertzpetsc.shooting import MEASURE_TOLERANCES, Refiner, ShiftMap, relative_residual
from hertzpetsc.symmetry import WaveSymmetry
from hertzpetsc.waves import orbit_on_chain

SELF = PETSc.COMM_SELF
Q = 6 * math.pi / 25        # unstable (q < q_c); on N = 25 beads m = 3 (m' = 3, k = 17), on N = 50 m = 6 (g = 2)


def branch():
    return small_branch(M=25, q_stop=Q)


@pytest.mark.parametrize("N, m", [(25, 3), (50, 6), (20, 4), (100, 14), (100, 1), (7, 7), (2, 1)])
def test_cell_shift_and_time_fraction(N, m):
    s = WaveSymmetry(N, m)
    assert s.g * s.M == N and s.g * s.m_cell == m and math.gcd(s.m_cell, s.M) == 1
    assert 0 < s.k <= s.M and s.k * s.m_cell == 1 + s.j * s.M
    # omega script-T = q: the phase q k - omega delta = q (k - 1 / m') of the short map is 2 pi j
    assert math.isclose(m / N * (s.k - 1 / s.m_cell), s.j, abs_tol=1e-12)
    assert s.sectors()[0] == 0.0 and len(s.sectors()) == s.g // 2 + 1
    assert 0 < s.cost() <= 1 and (s.cost() == 1) == (m == 1)


def test_wavenumbers_off_the_chain_are_refused():
    with pytest.raises(ParameterError, match=r"invalid m = 0: .*\[1, N\] = \[1, 25\]"):
        WaveSymmetry(25, 0)


@pytest.fixture(scope="module")
def refined():
    """The branch wave at q = 6 pi / 25 on 25 beads, refined by the symmetric and by the full map (E <= 1e-10)."""
    spec = chain(25)
    wave = orbit_on_chain(branch().point(Q), spec)
    out = {}
    for symmetric in (True, False):
        refiner = Refiner(spec, SELF, 1e-10, symmetric=symmetric)
        try:
            out[symmetric] = refiner.refine(wave)
        finally:
            refiner.destroy()
    return wave, out[True], out[False]


def test_symmetric_refinement_is_a_travelling_wave_of_the_paper_map(refined):
    """Both refinements reach E <= 1e-10 on the paper's map over script-T; the symmetric one is in addition a fixed
    point of the short map S^k R(T / m') (to its own target 1e-10 / m'). The full one is not: with three compression
    zones on the chain the Gauss-Newton system over script-T is nearly singular (sigma_min ~ 1e-4 against ~ 0.1 on
    the short map) and its fixed point drifts along the directions that move the zones apart (measured short-map
    residual 4.5e-5, states 4e-5 apart). The drift does not touch the dominant multiplier (measured 3e-12)."""
    wave, sym, full = refined
    assert sym.E <= 1e-10 and full.E <= 1e-10 < sym.E_initial
    assert sym.sigma_min > 100 * full.sigma_min
    s = WaveSymmetry(25, 3)
    short = ShiftMap(chain(25), SELF, MEASURE_TOLERANCES, "shoot_")
    dense = DenseFloquet(chain(25), SELF, MEASURE_TOLERANCES)
    try:
        r_sym, r_full = (relative_residual(r.x, short(r.x, s.delta(r.orbit.T), s.k)) for r in (sym, full))
        rho_sym, rho_full = (dense.spectrum(r.orbit).rho for r in (sym, full))
    finally:
        short.destroy()
        dense.destroy()
    assert r_sym <= 1e-10 / s.m_cell and r_full > 1e-8
    assert rho_sym > 1.1 and abs(rho_sym - rho_full) < 1e-9


@pytest.mark.parametrize("L", [1, 2])
def test_symmetric_spectrum_is_the_dense_spectrum(refined, L):
    """N = 25 (one sector, m' = 3) and N = 50 (sectors theta = 0, pi; m' = 3): every multiplier of the dense F_q is a
    multiplier of the symmetric route and conversely. Simple dominant multipliers agree to the flow's accuracy
    (rtol 1e-14: measured ~1e-12); the others without the trivial four within 1e-6, the square root of the flows'
    difference that splits double multipliers on the unit circle (measured <= 1e-7)."""
    _, sym, _ = refined
    orbit = sym.orbit.tiled(L)
    fast = SymmetricFloquet(orbit.spec.model, SELF, MEASURE_TOLERANCES)
    dense = DenseFloquet(orbit.spec, SELF, MEASURE_TOLERANCES)
    try:
        a, b = fast.spectrum(orbit), dense.spectrum(orbit)
    finally:
        fast.destroy()
        dense.destroy()
    assert len(a.multipliers) == len(b.multipliers) == 50 * L
    assert a.rho > 1.01 and abs(a.rho - b.rho) < 1e-9 * b.rho and a.outside == b.outside
    va, vb = (np.delete(v, trivial_multipliers(v)) for v in (a.multipliers, b.multipliers))
    assert max(np.min(np.abs(vb - v)) for v in va) < 1e-6 and max(np.min(np.abs(va - v)) for v in vb) < 1e-6

