"""E(q) and the Gauss-Newton refinement (section 3.4)."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from hertzpetsc.chain import ChainParameters
from hertzpetsc.errors import ParameterError
from hertzpetsc.shooting import refine, residual_E
from hertzpetsc.waves import wave_on_chain
from test_chain import branch_dict

N = 20   # q = 2 pi m / 20 = m pi / 10: on the M = 10 branch


@pytest.mark.parametrize("m", [4, 7])
def test_residual_decreases_like_h_squared(m):
    """E(q) of the discrete wave is its O(h^2) error: the interpolation onto q n keeps that order."""
    q = m * math.pi / 10
    Es = []
    for K in (100, 200, 400):
        w = wave_on_chain(branch_dict(1.5, K=K, q_stop=q), q, N)
        Es.append(residual_E(ChainParameters(1.5, N), w.as_array(), w.T))
    orders = np.log2(np.array(Es[:-1]) / Es[1:])
    assert np.all(np.abs(orders - 2) < 0.35), orders


def test_refinement_reaches_target_and_is_rank_independent():
    b = branch_dict(1.5, K=200, q_stop=0.4 * math.pi)
    w = wave_on_chain(b, 0.4 * math.pi, N)
    params = ChainParameters(1.5, N)
    serial = refine(params, w.as_array(), w.T, comm=PETSc.COMM_SELF, tol=1e-10)
    assert serial.E <= 1e-10 < serial.E_initial
    # with the two symmetry directions removed the Gauss-Newton system is well posed
    assert serial.sigma_min > 1e-10
    parallel = refine(params, w.as_array(), w.T, comm=PETSc.COMM_WORLD, tol=1e-10)
    assert np.max(np.abs(serial.x - parallel.x)) <= 1e-9 * np.max(np.abs(serial.x))
    # the refined state is close to the discrete wave: it corrects an O(h^2) error
    assert np.max(np.abs(serial.x - w.as_array())) < 1e-2 * np.max(np.abs(w.as_array()))


def test_refinement_needs_a_periodic_chain():
    with pytest.raises(ParameterError, match="periodic"):
        refine(ChainParameters(1.5, N, "free"), np.zeros((N, 2)), 1.0)


def test_branch_without_requested_q_is_a_clear_error():
    from hertzpetsc.errors import BranchFileError
    with pytest.raises(BranchFileError, match="no point at q"):
        wave_on_chain(branch_dict(1.5, K=100, q_stop=0.6 * math.pi), 0.2 * math.pi, N)
