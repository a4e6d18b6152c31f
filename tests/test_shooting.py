"""E(q) and the Gauss-Newton refinement (section 3.4)."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import chain, refine, small_branch
from hertzpetsc.errors import ParameterError, RecordFileError
from hertzpetsc.chain import CHAIN_PREFIX
from hertzpetsc.shooting import PAPER_TOLERANCES, ShiftMap
from hertzpetsc.waves import orbit_on_chain

N = 20   # q = 2 pi m / 20 = m pi / 10: on the M = 10 branch


@pytest.mark.parametrize("m", [4, 7])
def test_residual_decreases_like_h_squared(m):
    """E(q) of the discrete wave is its O(h^2) error: the interpolation onto q n keeps that order."""
    q = m * math.pi / 10
    Es = []
    for K in (100, 200, 400):
        w = orbit_on_chain(small_branch(K=K, q_stop=q).point(q), chain(N))
        smap = ShiftMap(w.spec, PETSc.COMM_WORLD, PAPER_TOLERANCES, CHAIN_PREFIX)
        Es.append(smap.residual(w))
        smap.destroy()
    orders = np.log2(np.array(Es[:-1]) / Es[1:])
    assert np.all(np.abs(orders - 2) < 0.35), orders


def test_refinement_reaches_target_and_is_rank_independent():
    w = orbit_on_chain(small_branch().point(0.4 * math.pi), chain(N))
    serial = refine(w, PETSc.COMM_SELF, tol=1e-10)
    assert serial.E <= 1e-10 < serial.E_initial
    # with the two symmetry directions removed the Gauss-Newton system is well posed
    assert serial.sigma_min > 1e-10
    parallel = refine(w, PETSc.COMM_WORLD, tol=1e-10)
    assert np.max(np.abs(serial.x - parallel.x)) <= 1e-9 * np.max(np.abs(serial.x))
    # the refined state is close to the discrete wave: it corrects an O(h^2) error
    assert np.max(np.abs(serial.x - w.x)) < 1e-2 * np.max(np.abs(w.x))
    assert serial.orbit.source == "refined" and w.source == "branch"


def test_travelling_waves_need_a_periodic_chain():
    with pytest.raises(ParameterError, match="periodic"):
        orbit_on_chain(small_branch().point(0.4 * math.pi), chain(N, boundary="free"))


def test_branch_without_requested_q_is_a_clear_error():
    with pytest.raises(RecordFileError, match="no point at q"):
        small_branch(K=100, q_stop=0.6 * math.pi).point(0.2 * math.pi)
