"""Solitary waves on the travelling window (hertzpetsc.solitary_family, studies.solitary_stability, the q = 0 row of
studies.compacton_stability).

Closed forms: the scaling family of the uncompressed chain (H ~ c^(2(alpha+1)/(alpha-1)), dX/dc = (2/(alpha-1) y,
(alpha+1)/(alpha-1) v)), the tail rate and the weighted essential spectrum of the linear chain; computed references:
k_alpha of eq. adr (Richardson in the grid step), the energy slope by finite differences along the family. Windows of
20-30 beads: the refinement reaches max|G(Y) - Y| ~ 1e-15 and the flows' errors (rtol 1e-14) set the tolerances.
"""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import DATA, one_error_line, run_script
from hertzpetsc.compacton_spectrum import jordan_check, split_jordan_pair
from hertzpetsc.compacton_window import CompactonWindow, embed
from hertzpetsc.continuation import Continuation, Natural
from hertzpetsc.errors import ParameterError
from hertzpetsc.model import LatticeModel
from hertzpetsc.solitary import SolitaryParameters, solve_solitary_wave
from hertzpetsc.solitary_family import (PrecompressionContinuation, _radius, essential_radius, guess_from_solitary,
                                        precompression_at_unit_speed, sound_speed, symplectic_product, tail_rate,
                                        unit_lattice, weighted_multipliers, window_beads, window_energy)
from hertzpetsc.studies.solitary import k_alpha_extrapolated
from hertzpetsc.records import read_kind
from hertzpetsc.studies.solitary_stability import SOLITARY_KIND, SolitaryStabilityParameters, SolitaryStabilityScan

SELF = PETSc.COMM_SELF


def test_tail_rate_and_essential_radius_of_the_linear_chain():
    """kappa solves the dispersion relation at an imaginary wavenumber; the weighted essential radius is below 1 for
    0 < eta < kappa and 1 at eta = kappa (the tails' own rate); the window map of the chain at rest (the linear
    chain itself) has its weighted multipliers at that radius, below it by at most 1e-2 for M = 40 (finite
    sections approach the limit set from inside)."""
    for c0 in (0.3, 0.6, 0.9):
        k = tail_rate(c0)
        assert math.isclose(math.sinh(k / 2) / (k / 2), 1 / c0, rel_tol=1e-14)
        grid = np.linspace(-math.pi, math.pi, 4097)
        assert abs(_radius(c0, k, grid) - 1.0) < 1e-12
        r, eta = essential_radius(c0)
        assert 0 < eta < k and r < 1
        assert r <= min(_radius(c0, e, grid) for e in np.linspace(0.05, 0.95, 19) * k) + 1e-9
    assert tail_rate(0.0) == math.inf and essential_radius(0.0) == (0.0, math.inf)
    alpha, c0, M = 2.0, 0.6, 40
    d = precompression_at_unit_speed(alpha, c0)
    assert math.isclose(sound_speed(alpha, d), c0, rel_tol=1e-14)
    w = CompactonWindow(LatticeModel.hertz(alpha, delta0=d), M, SELF)
    try:
        J = w.jacobian(np.zeros((M, 2)), 0.0)[1]
    finally:
        w.destroy()
    r, eta = essential_radius(c0)
    mu = np.abs(weighted_multipliers(J, eta))
    assert r - 1e-2 < mu.max() <= r + 1e-6


@pytest.fixture(scope="module")
def uncompressed():
    """The alpha = 3/2 solitary wave on a window of 24 beads, from eq. adr (n = 40) refined on the window."""
    alpha, M = 1.5, 24
    wave = solve_solitary_wave(SolitaryParameters(alpha, 40, 8.0), SELF)
    family = PrecompressionContinuation(LatticeModel.hertz(alpha), M, SELF)
    ex = family.refine(guess_from_solitary(wave, M, M // 2), 0.0)
    w = family.window(0.0)
    J = w.jacobian(ex.Y, 0.0)[1]
    yield alpha, ex, w, J
    family.destroy()


def test_uncompressed_wave_is_eq_adr_and_the_scaling_family(uncompressed):
    alpha, ex, w, J = uncompressed
    assert ex.residual < 1e-13                                     # measured 2e-15
    # D = 2 k_alpha (eqs. kal2, depsol2): eq. adr extrapolated in the grid step (n = 80, 160, 320: an h^4 remainder
    # ~1e-9) against the window (measured 4e-10)
    assert abs(ex.D - 2 * k_alpha_extrapolated(alpha)[0]) < 1e-8
    # the Jordan vector at 1 is dX/dc of the scaling family x -> a x(b t), a = c^(2/(alpha-1)), b = c
    jc = jordan_check(w, J, ex.Y, 0.0)
    kappa = 2 / (alpha - 1)
    dXdc = np.stack([kappa * ex.Y[:, 0], (kappa + 1) * ex.Y[:, 1]], axis=1).ravel()
    beta = (jc.v2 - dXdc) @ jc.v1 / (jc.v1 @ jc.v1)
    assert np.linalg.norm(jc.v2 - dXdc - beta * jc.v1) < 1e-10 * np.linalg.norm(dXdc)   # measured 6e-15
    # the energy slope omega(v1, v2) = dH/dc, and H(c) = H(1) c^(2(alpha+1)/(alpha-1)): c dH/dc / H in closed form
    H = window_energy(w.model, ex.Y)
    assert abs(symplectic_product(jc.v1, jc.v2) / H - 2 * (alpha + 1) / (alpha - 1)) < 1e-9     # measured 1.5e-13
    # the q -> 0 end of the compacton table: the compacton study's solitary row (M = 18): the window's length does
    # not change the multipliers (the tails are doubly exponential)
    _, _, rest = split_jordan_pair(weighted_multipliers(J, math.inf))
    with np.load(f"{DATA}/compacton_stability.npz") as z:
        row = np.nonzero((z["alpha"] == alpha) & (z["q"] == 0))[0][0]
        assert np.max(np.abs(rest[:3] - z["dominant"][row][:3])) < 1e-10            # measured 8e-15
    assert np.max(np.abs(rest)) < 1


def test_uncompressed_window_flow_is_cheap(uncompressed):
    """The beads behind the wave are integrated relative to their rest position (Chain.step): a tangent perturbation
    there costs no more steps than one in the compression zone (it cost 14353 steps against 28 when the bonds behind
    were differences of positions ~ D: alpha = 3/2, whose stiffness alpha |r|^(1/2) switched on round-off)."""
    alpha, ex, w, J = uncompressed
    integrator = w._flow(1).integrator
    steps = []
    for bead in (2, w.M // 2):                                   # behind the compression zone, in it
        e = np.zeros(2 * w.M)
        e[2 * bead] = 1.0
        before = integrator.steps
        w.apply(ex.Y, 0.0, e)
        steps.append(integrator.steps - before)
    assert steps[0] <= 2 * steps[1], steps                       # measured 27 and 31


@pytest.fixture(scope="module")
def precompressed():
    """alpha = 2 continued from the uncompressed wave to c0 = 0.5 in a window with tails of 1e-10 at its ends."""
    alpha, c0 = 2.0, 0.5
    M = window_beads(c0, 1e-10)
    wave = solve_solitary_wave(SolitaryParameters(alpha, 40, 8.0), SELF)
    family = PrecompressionContinuation(LatticeModel.hertz(alpha), M, SELF)
    start = family.refine(guess_from_solitary(wave, M, M // 2), 0.0)
    d = precompression_at_unit_speed(alpha, c0)
    cont = Continuation(family, Natural(max_corrector=math.inf))
    seed = family.pack(start.Y, 0.0)
    try:
        cont.seed([seed])
        ex = cont.step_to(d).report["wave"]
    finally:
        seed.destroy()
        cont.destroy()
    w = family.window(d)
    yield alpha, c0, d, ex, w, w.jacobian(ex.Y, 0.0)[1], family
    family.destroy()


def test_precompressed_wave_has_the_predicted_tails(precompressed):
    alpha, c0, d, ex, w, J, _ = precompressed
    assert ex.residual < 1e-13
    r = np.abs(np.diff(ex.Y[:, 0]))
    peak = int(np.argmax(r))
    # ahead of the wave r decays as exp(-kappa n): the ratio of successive bonds 4 to 8 beads ahead (the nonlinear
    # correction is O(r), below 1e-4 there; measured 3e-6)
    ratios = r[peak + 5:peak + 9] / r[peak + 4:peak + 8]
    assert np.all(np.abs(np.log(ratios) / -tail_rate(c0) - 1) < 1e-4), np.log(ratios)
    assert r[-1] / r.max() < 1e-9 and r[0] / r.max() < 1e-9      # the window's ends see the tails below 1e-10 x 10


def test_energy_slope_two_ways_and_the_unit_lattice(precompressed):
    """omega(v1, v2) / H = d ln H / d ln c at fixed lattice equals the finite difference of H along the family in
    delta0 (step 1e-4 relative: error ~1e-8); dH/dc > 0 (the energy criterion: no change of stability here)."""
    alpha, c0, d, ex, w, J, family = precompressed
    jc = jordan_check(w, J, ex.Y, 0.0)
    H = window_energy(w.model, ex.Y)
    slope = symplectic_product(jc.v1, jc.v2) / H
    eps = 1e-4
    Hs = [window_energy(w.model.with_delta0(d * (1 + s)), family.refine(ex.Y, d * (1 + s)).Y) for s in (-eps, eps)]
    dlog = (math.log(Hs[1]) - math.log(Hs[0])) / (math.log1p(eps) - math.log1p(-eps))
    assert abs(slope - 2 / (alpha - 1) * (alpha + 1 - dlog)) < 1e-6 * slope          # measured 4e-10
    assert slope > 2 * (alpha + 1) / (alpha - 1)                   # above the uncompressed slope (6), > 0
    c, H1, dHdc = unit_lattice(alpha, d, H, slope * H)
    assert math.isclose(c, 1 / math.sqrt(d), rel_tol=1e-14) and math.isclose(c * dHdc / H1, slope, rel_tol=1e-12)


def test_precompressed_multipliers_point_and_transport(precompressed):
    """The weighted multipliers: the Jordan pair at 1, one point multiplier above the essential radius that a
    longer window does not move (1e-8), the rest at most at the essential radius; none outside the unit circle."""
    alpha, c0, d, ex, w, J, _ = precompressed
    r, eta = essential_radius(c0)
    mean, _, rest = split_jordan_pair(weighted_multipliers(J, eta))
    assert abs(mean - 1) < 1e-10
    assert abs(rest[0]) > 1.05 * r and np.all(np.abs(rest[1:]) < r + 1e-6) and np.all(np.abs(rest) < 1)
    M2 = w.M + 8
    longer = PrecompressionContinuation(w.model, M2, SELF)
    try:
        e2 = longer.refine(embed(ex.Y, M2, 4), d)
        rest2 = split_jordan_pair(weighted_multipliers(longer.window(d).jacobian(e2.Y, 0.0)[1], eta))[2]
    finally:
        longer.destroy()
    assert abs(rest2[0] - rest[0]) < 1e-8                          # measured 1.9e-9


def test_study_records_on_any_number_of_ranks_and_bad_input(precompressed):
    """The study in memory on COMM_WORLD (alpha = 2 and 5/2 dealt to the ranks, each on COMM_SELF): its alpha = 2,
    c0 = 0.5 record is the fixture's wave computed here on COMM_SELF (same window, same continuation step)."""
    alpha, c0, d, ex, w, J, _ = precompressed
    params = SolitaryStabilityParameters(alphas=(2.0, 2.5), c0=(0.5,), tail=1e-10)
    assert params.c0 == (0.0, 0.5) and params.M == w.M
    scan = SolitaryStabilityScan(params, PETSc.COMM_WORLD)
    try:
        rows = list(scan.run())
    finally:
        scan.destroy()
    assert len(rows) == 4
    for r in rows:
        # the 2M window: H and the slope move by the tails (1e-10); the point multiplier by 1.4e-7 (measured: its
        # eigenvector decays more slowly than the wave)
        assert r["unstable"] == 0 and r["residual"] < 1e-13 and r["doubling_change"] < 1e-6
        if r["c0"] > 0:
            assert abs(r["log_slope"] - r["log_slope_fd"]) < 1e-6 * r["log_slope"] and r["points"] == 1
        else:
            assert abs(r["log_slope"] - 2 * (r["alpha"] + 1) / (r["alpha"] - 1)) < 1e-9
    mine = next(r for r in rows if r["alpha"] == 2.0 and r["c0"] == 0.5)
    assert np.max(np.abs(mine["state"] - ex.Y)) < 1e-13
    assert abs(mine["H"] - window_energy(w.model, ex.Y)) < 1e-13
    assert "> 0 throughout" in scan.summary() and "| 2.5 | 0.5 | 2.0000 |" in scan.table()
    for bad, match in ((dict(c0=(1.0,)), "c0"), (dict(c0=(0.5, 0.5)), "c0"), (dict(alphas=(1.0,)), "alpha"),
                       (dict(M=10), "M"), (dict(tail=0.1), "tail")):
        with pytest.raises(ParameterError, match=match):
            SolitaryStabilityParameters(**bad)


@pytest.mark.serial
def test_driver_on_two_ranks_and_errors(tmp_path):
    r = run_script("solitary_stability.py", "-alphas", "2", "-c0", "0.5", "-tail", "1e-10", "-output",
                   tmp_path / "s.npz", "-table", tmp_path / "s.md", "-figures", tmp_path, ranks=2, timeout=120)
    assert r.returncode == 0, r.stderr
    text = (tmp_path / "s.md").read_text()
    assert "| 2 | 2: 0 ... 0.5 |" in text and "stable" in text
    assert (tmp_path / "solitary_stability.png").exists()
    assert SOLITARY_KIND.check(read_kind(str(tmp_path / "s.npz"), SOLITARY_KIND, "x")) == ([], [])   # as declared
    e = run_script("solitary_stability.py", "-c0", "1.2", "-output", tmp_path / "x.npz", timeout=60)
    assert "-c0" in one_error_line(e) and "[0, 1)" in one_error_line(e)
