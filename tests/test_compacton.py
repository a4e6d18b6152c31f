"""Compactons (section 3.3): the extension solves eq. ad on the line, and the chain keeps the beads ahead at rest."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from hertzpetsc.compacton import (CompactonScales, CompactonTrain, chain_length, compacton_train,
                                  extension_residuals, lattice_checks, placement, simulate_on_chain)
from conftest import small_branch
from hertzpetsc.errors import ParameterError

K = 200                                       # h = pi/200: every q = m pi/10 is a whole number (20 m) of steps
Q = 3 * math.pi / 10                          # F(q) ~ 4 > 1


@pytest.fixture(scope="module")
def branch():
    """alpha = 3/2, q = m pi/10 from pi to pi/5."""
    return small_branch(K=K)


@pytest.mark.parametrize("spacings", [(), (2,), (2, 0)])
def test_extension_solves_eq_ad_on_the_extended_domain(branch, spacings):
    """U_q, U^(2) and a 3-compacton: the residual of the discrete eq. ad over the whole train and a period of
    line on each side is that of the periodic profile, plus at most what the switch from the computed u to the
    exact line adds (2 delta / h^2, delta = the computed u's deviation from a line on the free flight, ~1e-14)."""
    train = compacton_train(branch.point(Q), spacings)
    extended, period, switch = extension_residuals(train)
    U_max = abs(train(np.array([train.offsets[-1] + 4 * math.pi]))[0])
    roundoff = 64 * np.finfo(float).eps * U_max / train.h ** 2
    assert period < 1e-6                      # the SNES residual of the branch point
    assert extended <= period + switch + roundoff
    assert switch + roundoff < 1e-6


def test_overlapping_compactons_violate_eq_ad(branch):
    """The check above can fail: two bumps whose compression regions overlap by half do not solve eq. ad, while
    the smallest admitted spacing d = 2 - F (negative here: theta = 2 (q - ell)) still does."""
    good = compacton_train(branch.point(Q))
    edge = compacton_train(branch.point(Q), (math.ceil((2 - good.F) * Q / good.h) * good.h / Q,))
    extended, period, switch = extension_residuals(edge)
    assert extended <= period + switch + 64 * np.finfo(float).eps * 40 / good.h ** 2
    overlap = round((math.pi - good.ell) / good.h) * good.h
    bad = CompactonTrain(**{**good.__dict__, "offsets": (0.0, overlap)})
    extended, period, switch = extension_residuals(bad)
    assert extended > 1e3 * (period + switch)


def test_bad_input_is_refused(branch):
    with pytest.raises(ParameterError, match="q_k"):
        compacton_train(branch.point(7 * math.pi / 10))            # q > q_k ~ 1.8: F(q) < 1
    with pytest.raises(ParameterError, match="spacings"):
        compacton_train(branch.point(Q), (2, -3))                  # overlapping compactons: d < 2 - F ~ -2
    with pytest.raises(ParameterError, match="c"):
        CompactonScales.for_velocity(compacton_train(branch.point(Q)), 0.0)
    with pytest.raises(ParameterError, match="spacings"):
        compacton_train(branch.point(Q), (2 / Q,)).grid_values(np.arange(3))   # theta = 2 is not on the grid


@pytest.mark.parametrize("spacings", [(), (2.5,)])
def test_beads_ahead_stay_exactly_at_rest(branch, spacings):
    """A short run (30 beads of travel at c = 1): beads ahead of the train keep xdot = 0 and x = x(0) exactly,
    the front arrives on time (within one snapshot interval), and speed and shift match c and 2 pi a p to the
    profile's O(h^2) error (measured ~1e-6 and ~1e-5 at h = pi/200)."""
    train = compacton_train(branch.point(Q), spacings)
    scales = CompactonScales.for_velocity(train, 1.0)
    N = chain_length(train, 5, 30)
    phi = placement(train, 5)
    dt = 0.1
    times, states = simulate_on_chain(train, scales, N, phi, 30.0, dt, PETSc.COMM_WORLD)
    chk = lattice_checks(train, scales, phi, times, states)
    assert chk.max_velocity_ahead == 0.0
    assert chk.max_displacement_ahead == 0.0
    assert 0.0 <= chk.arrival_delay_min and chk.arrival_delay_max <= dt
    assert all(abs(c - 1.0) < 1e-4 for c in chk.measured_c)
    assert chk.beads_passed >= 5
    assert chk.shift_error < 1e-3 and chk.gap_error < 1e-2
    assert chk.max_velocity_behind < 1e-3 * chk.v_peak


def test_same_run_on_one_and_all_ranks(branch):
    """The distributed chain gives the single-rank snapshots to within the integrator's tolerance (the adaptive
    steps may differ by round-off in the reductions: bound 1e-9 of the shift over 10 time units)."""
    train = compacton_train(branch.point(Q))
    scales = CompactonScales.for_velocity(train, 1.0)
    N = chain_length(train, 4, 10)
    phi = placement(train, 4)
    _, self_states = simulate_on_chain(train, scales, N, phi, 10.0, 1.0, PETSc.COMM_SELF)
    _, world_states = simulate_on_chain(train, scales, N, phi, 10.0, 1.0, PETSc.COMM_WORLD)
    assert np.max(np.abs(self_states - world_states)) < 1e-9 * scales.shift
