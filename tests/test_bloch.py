"""Bloch sectors of F_q on long chains (section 3.5): union of sector spectra = dense spectrum of the tiled chain,
theta = 0 = the cell's own F_q, full-chain residuals, seeded SLEPc, ranks, bad input."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from hertzpetsc.bloch import (BlochSectors, SymmetricFloquet, bloch_residuals, real_pairs, seeded_dominant_multipliers,
                              tile_mode)
from conftest import chain, dense_monodromy, refine, small_branch
from hertzpetsc.errors import ParameterError
from hertzpetsc.floquet import dense_multipliers, trivial_multipliers
from hertzpetsc.shooting import MEASURE_TOLERANCES
from hertzpetsc.waves import orbit_on_chain

M = 20          # the cell: q = pi/5 = 2 pi 2 / 20 (unstable, rho(F_q) = 1.2356 as at N = 100)
CELL = chain(M)


@pytest.fixture(scope="module")
def cell_wave():
    """The refined wave q = pi/5 on 20 beads (E <= 1e-10), the cell of the longer chains."""
    return refine(orbit_on_chain(small_branch().point(math.pi / 5), CELL), PETSc.COMM_SELF).orbit


def bloch_multipliers(cell, N, comm, tolerances, split="sectors", n_modes=0):
    """All 2N multipliers of the cell wave tiled onto N beads by the Bloch route."""
    fast = SymmetricFloquet(cell.spec.model, comm, tolerances, split=split, n_modes=n_modes)
    try:
        return fast.spectrum(cell.tiled(N // cell.N))
    finally:
        fast.destroy()


def nearest(a, b):
    """max over a of the distance to the nearest element of b."""
    return max(float(np.min(np.abs(b - v))) for v in a)


@pytest.mark.parametrize("L", [3, 4])
def test_union_of_sectors_is_the_dense_spectrum(cell_wave, L):
    """N = 60 (odd L: conjugate pairs only) and N = 80 (L = 4: also theta = pi): every multiplier of the dense
    2N x 2N F_q of the tiled chain is a sector multiplier and conversely, with the same count 2N."""
    cell = cell_wave
    N = L * M
    b = bloch_multipliers(cell, N, PETSc.COMM_SELF, MEASURE_TOLERANCES)
    lam = dense_multipliers(dense_monodromy(cell.tiled(L), PETSc.COMM_SELF, MEASURE_TOLERANCES))
    assert len(b.multipliers) == len(lam) == 2 * N
    # the wave repeats every 10 beads (m = 2 wavelengths on the 20-bead cell): 2L sectors of the 10-bead cell
    assert b.M == 10 and b.L == 2 * L and b.work["runs"] == b.L // 2 + 1
    assert np.bincount(b.sector, minlength=b.L).tolist() == [2 * b.M] * b.L
    # Without the 4 trivial multipliers (split by O(sqrt(eps)) differently in the two runs): the two flows take
    # different adaptive steps at rtol 1e-14; measured <= 5e-8 (double multipliers on the unit circle split as
    # the square root of the flow difference); 1e-6 leaves a factor 20.
    bt, lt = (np.delete(v, trivial_multipliers(v)) for v in (b.multipliers, lam))
    assert nearest(lt, bt) < 1e-6 and nearest(bt, lt) < 1e-6
    # simple dominant multipliers agree to the flow accuracy (measured 1e-13)
    assert abs(abs(b.multipliers[0]) - abs(lam[0])) < 1e-9


def test_theta_zero_is_the_cell_itself(cell_wave):
    """Sector 0 (untwisted, 2M complex columns) against the dense F_q of the M-bead periodic chain."""
    cell = cell_wave
    x, T = cell.x, cell.T
    sec = BlochSectors(CELL.model, PETSc.COMM_SELF, MEASURE_TOLERANCES)
    try:
        F0 = sec.monodromy(x, T, 0.0)
    finally:
        sec.destroy()
    F = dense_monodromy(cell, PETSc.COMM_SELF, MEASURE_TOLERANCES)
    assert np.max(np.abs(F0.imag)) == 0.0          # w = 0 stays 0 without a twist
    # same equations, different number of tangents in the TS error norm: entries agree to ~rtol * ||F||
    assert np.max(np.abs(F0.real - F)) < 1e-9 * np.max(np.abs(F))
    b = bloch_multipliers(cell, M, PETSc.COMM_SELF, MEASURE_TOLERANCES)
    assert (b.M, b.L) == (10, 2) and abs(abs(b.multipliers[0]) - abs(dense_multipliers(F)[0])) < 1e-9


def test_tiled_modes_are_eigenvectors_of_the_full_chain(cell_wave):
    """||F Y - lambda Y|| / (|lambda| ||Y||) on N = 100 beads (matrix-free, on all ranks) for the tiled Bloch
    modes of the 6 dominant multipliers: measured ~1e-12, the flow's accuracy."""
    cell = cell_wave
    L = 5
    b = bloch_multipliers(cell, L * M, PETSc.COMM_WORLD, MEASURE_TOLERANCES, n_modes=6)
    pairs = real_pairs(b.modes, b.L)
    assert 3 <= len(pairs) <= 6
    c = b.M                                            # the wave's cell: 10 beads
    for lam, Y in pairs:
        assert Y.shape == (L * M, 2)
        # Bloch form y_{n+c} = e^{i theta_j} y_n for one of the sectors theta_j = 2 pi j / (N / c)
        assert any(np.allclose(Y[c:2 * c], np.exp(2j * math.pi * j / b.L) * Y[:c]) for j in range(b.L))
    res, products = bloch_residuals(cell.tiled(L), pairs, PETSc.COMM_WORLD, MEASURE_TOLERANCES)
    assert products <= 2 * len(pairs) and np.max(res) < 1e-9


def test_seeded_slepc_on_the_full_chain(cell_wave):
    """Krylov-Schur on the N = 80 shell (distributed under mpiexec -n 2), started from the Bloch modes, converges
    to the Bloch multipliers (eigensolver tolerance 1e-8 on relative residuals, the seeded default; measured
    agreement 4e-12 since the flows at rtol 1e-14 make the residuals ~1e-13 after a few restarts)."""
    cell = cell_wave
    L = 4
    b = bloch_multipliers(cell, L * M, PETSc.COMM_WORLD, MEASURE_TOLERANCES, n_modes=10)
    res = seeded_dominant_multipliers(cell.tiled(L), b, nev=10, comm=PETSc.COMM_WORLD, tolerances=MEASURE_TOLERANCES)
    assert nearest(res.multipliers, b.multipliers[:12]) < 1e-7
    assert res.work["products"] <= 2 * 30         # measured 45 with ncv = 30 (plain Krylov-Schur needs more, see README)


def test_ranks_and_splits_agree(cell_wave):
    """Sectors dealt to ranks (each on one rank) vs every sector distributed over COMM_WORLD (the twisted ghost
    exchange across ranks under mpiexec -n 2) vs one rank: the same multipliers to the flow tolerance."""
    cell = cell_wave
    N = 3 * M
    ref = bloch_multipliers(cell, N, PETSc.COMM_SELF, MEASURE_TOLERANCES)
    for split in ("sectors", "beads"):
        b = bloch_multipliers(cell, N, PETSc.COMM_WORLD, MEASURE_TOLERANCES, split=split)
        assert np.array_equal(np.sort(b.sector), np.sort(ref.sector))
        # the same TS on 1 or 2 ranks: only the reduction order of the error norm differs, which can change an
        # adaptive step; simple dominant multipliers move by ~rtol (measured 1e-13), double ones on the unit
        # circle and the trivial ones by its square root (measured 3e-9 under mpiexec -n 2)
        assert abs(abs(b.multipliers[0]) - abs(ref.multipliers[0])) < 1e-10
        assert nearest(b.multipliers, ref.multipliers) < 1e-6 and nearest(ref.multipliers, b.multipliers) < 1e-6
        if split == "sectors":      # each sector on one rank, every run from the same first step: same arithmetic
            assert np.array_equal(b.multipliers, ref.multipliers)


def test_tiling():
    Y = tile_mode(np.arange(4, dtype=complex), 1, 4)          # M = 2 beads, theta = pi/2
    assert np.allclose(Y[2:4], 1j * Y[:2]) and np.allclose(Y[6:8], -1j * Y[:2])


def test_bad_input_is_refused(cell_wave):
    cell = cell_wave
    x = cell.x
    comm = PETSc.COMM_WORLD
    with pytest.raises(ParameterError, match=r"invalid state = \(10, 2\): .*\(N, 2\) = \(20, 2\)"):
        cell.with_state(x[:10], "truncated")
    with pytest.raises(ParameterError, match=r"n_modes.*\[0, 2N\] = \[0, 80\]"):
        bloch_multipliers(cell, 40, comm, MEASURE_TOLERANCES, n_modes=81)
    with pytest.raises(ParameterError, match="split"):
        bloch_multipliers(cell, 40, comm, MEASURE_TOLERANCES, split="rows")
