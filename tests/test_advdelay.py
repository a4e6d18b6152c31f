"""The discretised advance-delay problem (eqs. ad, pbc): Jacobian, consistency, shifts, rank independence."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from hertzpetsc.advdelay import AdvanceDelayProblem, check_wavenumber
from hertzpetsc.binary import binary_oscillation
from hertzpetsc.diagnostics import sup_norm
from hertzpetsc.errors import ParameterError
from hertzpetsc.grid import ProfileGrid
from hertzpetsc.model import LatticeModel
from hertzpetsc.twsolver import solve_travelling_wave


def residual(problem, u):
    F = u.duplicate()
    problem.formFunction(None, u, F)
    return F


def test_fold_implements_oddness_and_periodicity():
    g = ProfileGrid(8, PETSc.COMM_SELF)
    idx, sign = g.fold(np.array([0, 3, 8, 11, 16, -3, 19]))
    assert list(sign) == [0, 1, 0, -1, 0, -1, 1]          # u_0 = u_K = 0, u_{2K-j} = -u_j, period 2K
    assert list(idx[sign != 0]) == [2, 4, 2, 2]           # unknown index of u_3, u_5, u_3, u_3


@pytest.mark.parametrize("q, mass", [(0.7 * math.pi, 1.0), (0.7, 1.0), (math.pi, 1.0), (0.7, 2.0)])
def test_jacobian_matches_finite_differences(q, mass):    # integer, interpolated, half-period shifts; a heavy chain
    pot = LatticeModel.hertz(1.5, masses=(mass,))
    g = ProfileGrid(120, PETSc.COMM_WORLD)
    xi = g.xi_half()
    rng = np.random.default_rng(7)
    # a generic odd state: u0 plus a smooth odd perturbation (not a solution, shift differences of both signs)
    u = g.vec_from_half_profile(binary_oscillation(pot.law, xi) + 0.05 * np.sin(3 * xi) * rng.uniform(0.5, 1))
    v = g.vec_from_half_profile(np.sin(xi) + 0.3 * np.sin(5 * xi + 0.2) * np.sin(xi))
    prob = AdvanceDelayProblem(pot, g, q)
    J = prob.create_jacobian(u)
    Jv = v.duplicate()
    J.mult(v, Jv)
    eps = 1e-6
    up, um = u.copy(), u.copy()
    up.axpy(eps, v)
    um.axpy(-eps, v)
    fd = residual(prob, up)
    fd.axpy(-1.0, residual(prob, um))
    fd.scale(0.5 / eps)
    fd.axpy(-1.0, Jv)
    # central differences: O(eps^2) except where a shift difference crosses 0, where V'' is only
    # C^{0,1/2}: there the error is O(eps^{1/2}) times eps-sized terms, far below 1e-6 relative
    assert fd.norm() <= 1e-6 * Jv.norm()
    prob.destroy()


@pytest.mark.parametrize("alpha", [1.5, 2.5])
def test_binary_oscillation_residual_is_the_truncation_error(alpha):
    """R(u0) at q = pi is the scheme's truncation error h^2 u0^(4) / 12: O(h^2) where u0 is smooth, but
    u0^(4) ~ |u0|^(alpha-2) at the zeros of u0, so the sup norm is O(h^min(2, alpha))."""
    pot = LatticeModel.hertz(alpha)
    errs = []
    for K in (100, 200, 400):
        g = ProfileGrid(K, PETSc.COMM_WORLD)
        u = g.vec_from_half_profile(binary_oscillation(pot.law, g.xi_half()))
        prob = AdvanceDelayProblem(pot, g, math.pi)
        errs.append(residual(prob, u).norm(PETSc.NormType.NORM_INFINITY))
        prob.destroy()
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(orders - min(2.0, alpha)) < 0.15), orders


def solve(K, q, alpha=1.5, comm=PETSc.COMM_WORLD, guess_q=math.pi):
    """Solve at q by a short continuation from u0 (in steps of at most pi/10)."""
    pot = LatticeModel.hertz(alpha)
    g = ProfileGrid(K, comm)
    u = g.vec_from_half_profile(binary_oscillation(pot.law, g.xi_half()))
    qs = list(np.arange(math.pi, q, -math.pi / 10)) + [q]
    for qq in qs:
        u.scale((guess_q / qq) ** (2 / (alpha - 1)))
        guess_q = qq
        prob = AdvanceDelayProblem(pot, g, qq)
        solve_travelling_wave(prob, u)
        prob.destroy()
    return g.half_profile(u)


def test_interpolated_shift_agrees_with_exact_shift():
    """A q on the grid, and the same q moved off it by delta: solutions differ by O(delta)."""
    K, q = 200, 0.6 * math.pi       # sigma = 120 grid steps
    exact = solve(K, q)
    delta = 1e-6                     # > INTEGER_SHIFT_TOLERANCE: takes the interpolation path
    moved = solve(K, q * (1 + delta))
    assert np.max(np.abs(exact - moved)) <= 50 * delta * np.max(np.abs(exact))


def test_interpolated_shift_keeps_second_order():
    q = 2.0                          # 2/h is never a whole number of steps
    sup = [sup_norm(solve(K, q)) for K in (100, 200, 400)]
    order = math.log2((sup[0] - sup[1]) / (sup[1] - sup[2]))
    assert abs(order - 2) < 0.3, order


def test_one_rank_equals_all_ranks():
    """Under mpiexec -n 2: the distributed solve equals the serial one to solver tolerance."""
    q = 0.5
    serial = solve(160, q, comm=PETSc.COMM_SELF)
    parallel = solve(160, q, comm=PETSc.COMM_WORLD)
    assert np.max(np.abs(serial - parallel)) <= 1e-10 * np.max(np.abs(serial))


@pytest.mark.parametrize("q", [0.0, -1.0, 3.2, float("nan"), "x"])
def test_wavenumber_outside_range_is_rejected(q):
    with pytest.raises(ParameterError, match=r"q.*\(0, pi\]"):
        check_wavenumber(q)


def test_wavenumber_below_grid_step_is_rejected():
    g = ProfileGrid(10, PETSc.COMM_SELF)
    with pytest.raises(ParameterError, match="grid step"):
        AdvanceDelayProblem(LatticeModel.hertz(1.5), g, 0.1)


def test_damped_models_and_unknown_parameters_are_refused():
    g = ProfileGrid(10, PETSc.COMM_SELF)
    with pytest.raises(ParameterError, match="damping"):
        AdvanceDelayProblem(LatticeModel.hertz(1.5, gamma=0.1), g, 1.0)
    with pytest.raises(ParameterError, match="parameter"):
        AdvanceDelayProblem(LatticeModel.hertz(1.5), g, 1.0, parameter="epsilon")
    with pytest.raises(ParameterError, match="parameter"):
        AdvanceDelayProblem(LatticeModel.hertz(1.5), g, 1.0, parameter="a")


@pytest.mark.parametrize("K", [3, 10.5, "many"])
def test_bad_grid_is_rejected(K):
    with pytest.raises(ParameterError, match="cells_per_pi"):
        ProfileGrid(K, PETSc.COMM_SELF)


def test_a_monatomic_chain_of_mass_m_at_omega_is_the_unit_chain_at_omega_sqrt_m():
    """Eq. ad with masses m: m omega^2 u'' = V'(tau_q u - u) - V'(u - tau_-q u), so the residual depends on m omega^2
    only (the single-profile path included)."""
    g = ProfileGrid(200, PETSc.COMM_WORLD)
    u = g.vec_from_half_profile(np.sin(g.xi_half()) + 0.2 * np.sin(3 * g.xi_half()))
    heavy = AdvanceDelayProblem(LatticeModel.hertz(1.5, masses=(2.0,)), g, 2.0, omega=0.8)
    unit = AdvanceDelayProblem(LatticeModel.hertz(1.5), g, 2.0, omega=0.8 * math.sqrt(2.0))
    r_heavy, r_unit = residual(heavy, u), residual(unit, u)
    r_heavy.axpy(-1.0, r_unit)
    assert r_heavy.norm(PETSc.NormType.INFINITY) <= 1e-13 * r_unit.norm(PETSc.NormType.INFINITY)
    heavy.destroy()
    unit.destroy()
