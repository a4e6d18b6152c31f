"""Floquet multipliers modulo shifts (section 3.5): dense vs SLEPc, trivial multipliers, symplecticity, ranks."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import chain, dense_monodromy, refine, small_branch
from hertzpetsc.errors import ConvergenceError, ParameterError
from hertzpetsc.floquet import (FLOQUET_TOLERANCES, DominantFloquet, dense_multipliers, spectral_radius,
                                trivial_multipliers)
from hertzpetsc.shooting import MEASURE_TOLERANCES
from hertzpetsc.waves import orbit_on_chain

N = 20


def dominant_multipliers(orbit, nev, comm, tolerances=FLOQUET_TOLERANCES):
    with DominantFloquet(orbit.spec, comm, nev, tolerances) as solver:
        return solver.spectrum(orbit)


@pytest.fixture(scope="module")
def refined_wave():
    """The refined wave q = 2 pi 2 / 20 = pi/5 on 20 beads (E <= 1e-10)."""
    res = refine(orbit_on_chain(small_branch().point(math.pi / 5), chain(N)), PETSc.COMM_SELF)
    return res.orbit, res.E


def test_trivial_multipliers_and_symplectic_structure(refined_wave):
    orbit, E = refined_wave
    lam = dense_multipliers(dense_monodromy(orbit, PETSc.COMM_SELF, MEASURE_TOLERANCES))
    triv = lam[trivial_multipliers(lam)]
    # four multipliers at 1 (two Jordan blocks): an O(eps) orbit error splits them by O(sqrt(eps)), eps ~ 1e-10
    assert np.max(np.abs(triv - 1)) < 1e-3
    # symplectic: the spectrum is closed under lambda -> 1/conj(lambda) (up to the dgeev/flow accuracy)
    others = np.delete(lam, trivial_multipliers(lam))
    inv = 1 / np.conj(others)
    assert max(np.min(np.abs(others - v)) for v in inv) < 1e-6
    assert spectral_radius(lam) >= 1 - 1e-8


def test_dense_and_matrix_free_agree(refined_wave):
    """SLEPc Krylov-Schur on the shell operator finds the dominant multipliers of the dense matrix (under
    mpiexec -n 2 the shell runs distributed while the dense reference is serial: also the rank check)."""
    orbit, _ = refined_wave
    lam = dense_multipliers(dense_monodromy(orbit, PETSc.COMM_SELF, MEASURE_TOLERANCES))
    res = dominant_multipliers(orbit, nev=6, comm=PETSc.COMM_WORLD, tolerances=MEASURE_TOLERANCES)
    assert res.work["products"] > 0 and len(res.multipliers) == 6 and not res.complete
    # the two flows take different adaptive steps (1 vs 40 tangent vectors): eigenvalues agree to the flow
    # budget amplified by the conditioning of the dominant multipliers; Krylov-Schur tolerance is 1e-10
    for v in res.multipliers[:2]:
        assert np.min(np.abs(lam - v)) < 1e-6 * abs(v)
    assert abs(abs(res.multipliers[0]) - abs(lam[0])) < 1e-6


def test_nev_larger_than_dimension_is_refused(refined_wave):
    orbit, _ = refined_wave
    with pytest.raises(ParameterError, match=r"nev.*\[1, 2N\] = \[1, 40\]"):
        dominant_multipliers(orbit, nev=41, comm=PETSc.COMM_WORLD)


def test_unconverged_eigensolve_is_an_error(refined_wave, clean_options):
    orbit, _ = refined_wave
    clean_options.setValue("floquet_eps_max_it", 1)     # with a subspace smaller than the dimension 40
    clean_options.setValue("floquet_eps_ncv", 13)
    with pytest.raises(ConvergenceError, match="multipliers converged"):
        dominant_multipliers(orbit, nev=6, comm=PETSc.COMM_WORLD)
