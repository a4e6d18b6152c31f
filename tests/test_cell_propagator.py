"""The cell propagator (hertzpetsc.tangent.CellPropagator): every Bloch sector's twisted resolvent from one run on three
cells, R_theta = P_0 + e^{-i theta} P_1 + e^{i theta} P_{-1}, against the twisted-cell runs of hertzpetsc.bloch; the
fall-back when the response reaches beyond a cell; the sectors of a long chain through either route."""
import math

import numpy as np
from petsc4py import PETSc

from conftest import small_branch
from hertzpetsc.bloch import BlochSectors, SymmetricFloquet
from hertzpetsc.chain import IntegrationTolerances
from hertzpetsc.model import ChainSpec, LatticeModel
from hertzpetsc.tangent import CellPropagator, twisted_resolvent
from hertzpetsc.waves import orbit_on_chain

COMM = PETSc.COMM_WORLD
TIGHT = IntegrationTolerances(1e-14, 1e-16)


def cell_state(M, seed=0):
    """An M-periodic state of a precompressed chain (every bond couples: the response to data in one cell decays
    through the neighbouring cells but never vanishes), small enough to stay in contact."""
    rng = np.random.default_rng(seed)
    return 0.05 * rng.normal(size=(M, 2))


def test_twisted_resolvent_from_three_cells():
    """Precompressed (delta0 = 0.5, K = V''(0) = 1.06), M = 16, T = 0.2: the response crosses half a cell (8 beads)
    only at O((K T^2)^8 / 16!) ~ 1e-25, so the three blocks are the whole story and R_theta agrees with the twisted
    run at theta = 0.9 (complex), pi and 0 (real) to the flows' accuracy (two flows at rtol 1e-14 with other steps;
    measured 7e-16; bound 1e-12). The seam blocks are not zero here (the test would not see a sign error otherwise)."""
    model = LatticeModel.hertz(1.5, delta0=0.5)
    M, T = 16, 0.2
    x0 = cell_state(M)
    prop = CellPropagator(model, M, COMM, TIGHT, "chain_")
    sectors = BlochSectors(model, COMM, TIGHT, "chain_")
    try:
        assert prop.reaches(x0, T) < 1e-15 and prop.run(x0, T).local
        Pm, P0, P1 = prop.blocks
        assert min(np.max(np.abs(Pm)), np.max(np.abs(P1))) > 1e-3
        for theta in (0.9, math.pi, 0.0):
            R = sectors.monodromy(x0, T, theta, 0)                  # shift 0: the twisted resolvent itself
            L = twisted_resolvent(prop.blocks, theta)
            assert np.iscomplexobj(L) == np.iscomplexobj(R)
            assert np.max(np.abs(L - R)) <= 1e-12 * np.max(np.abs(R))
    finally:
        prop.destroy()
        sectors.destroy()


def test_response_beyond_a_cell_falls_back_to_twisted_runs():
    """M = 8 beads over T = 3: the response fills the neighbouring cells, the probe says so, and the sectors come
    from one twisted run each (the same numbers as monodromy, to the bit)."""
    model = LatticeModel.hertz(1.5, delta0=0.5)
    M, T = 8, 3.0
    x0 = cell_state(M, 1)
    sectors = BlochSectors(model, COMM, TIGHT, "chain_")
    thetas = [0.0, 2 * math.pi / 5, 4 * math.pi / 5]
    try:
        G = list(sectors.monodromies(x0, T, thetas, 3))
        assert sectors.propagated == 0
        for theta, g in zip(thetas, G):
            assert np.array_equal(g, sectors.monodromy(x0, T, theta, 3))
    finally:
        sectors.destroy()


class TwistedRuns(BlochSectors):
    """The sectors by one twisted run each, whatever the cell (the route before the propagator)."""

    def monodromies(self, x0, T, thetas, shift=1, among=None):
        return (self.monodromy(x0, T, theta, shift) for theta in thetas)


def test_long_chain_sectors_through_the_propagator():
    """The wave q = 2 pi/5 (2 wavelengths on 10 beads: a 5-bead cell) tiled to 60 beads: 7 sectors of the cell over
    script-T, 5 of them complex. Uncompressed, the bonds between compression zones carry no force, so the response
    stays within a few beads (the probe measures exactly 0) and the propagator is used; its spectrum equals the
    twisted runs' (the dominant multiplier to 1e-9, the flows' accuracy at rtol 1e-14 over script-T, measured 2e-12;
    the spectra as sets to 1e-6, measured 3e-9: double multipliers on the unit circle split as the square root of
    the flow error)."""
    cell = orbit_on_chain(small_branch().point(2 * math.pi / 5), ChainSpec(LatticeModel.hertz(1.5), 10))
    chain = cell.tiled(6)
    with SymmetricFloquet(cell.spec.model, COMM, TIGHT, prefix="chain_") as solver:
        fast = solver.spectrum(chain)
    with SymmetricFloquet(cell.spec.model, COMM, TIGHT, prefix="chain_", split="beads") as solver:
        solver.sectors.destroy()
        solver.sectors = TwistedRuns(cell.spec.model, COMM, TIGHT, "chain_")
        slow = solver.spectrum(chain)
    assert fast.work["propagated"] and not slow.work["propagated"]
    assert abs(abs(fast.multipliers[0]) - abs(slow.multipliers[0])) <= 1e-9 * abs(slow.multipliers[0])
    assert max(float(np.min(np.abs(slow.multipliers - v))) for v in fast.multipliers) < 1e-6
