"""The long-wave limit (section 3.2): composite approximation and the rescaled norm against k_alpha."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import DATA
from hertzpetsc.branch import Branch
from hertzpetsc.longwave import compare_with_branch, composite_profile
from hertzpetsc.solitary import SolitaryParameters, solve_solitary_wave
from hertzpetsc.studies.longwave import LongWaveStudy


@pytest.fixture(scope="module")
def comparisons():
    """The committed paper branch (h = pi/1000; its reproduction is tested by the driver's smoke test)."""
    wave = solve_solitary_wave(SolitaryParameters(1.5, 80, 8.0), PETSc.COMM_SELF)
    branch = Branch.load(f"{DATA}/branch_alpha1.5.npz")
    pts = sorted([p for p in branch.points if p.q < 4 * math.pi / 50 + 1e-9], key=lambda p: -p.q)
    return wave, [compare_with_branch(wave, p) for p in pts]


def test_errors_vanish_as_q_decreases(comparisons):
    wave, rows = comparisons                      # q = 4pi/50 .. pi/50
    for key in ("max_error", "window_error", "inner_window_error"):
        errs = [getattr(r, key) for r in rows]
        assert all(a > b for a, b in zip(errs, errs[1:])), key
    # first-order matching: the composite's error is O(q) (measured 0.059 at pi/50, 0.119 at 2pi/50)
    assert 1.7 < rows[-2].max_error / rows[-1].max_error < 2.3


def test_rescaled_norm_tends_to_k_alpha_like_q_squared(comparisons):
    wave, rows = comparisons
    d = [r.rescaled_norm - wave.k_alpha for r in rows]
    assert all(v > 0 for v in d)
    assert 3.5 < d[-2] / d[-1] < 4.5                                   # q halved: difference / 4
    assert abs(d[-1] - 8e-3) < 1e-3                                     # paper: "differs ... by 8e-3"


def test_composite_matches_outer_solution_away_from_pi(comparisons):
    wave, _ = comparisons
    q = math.pi / 50
    xi = np.array([0.5, 1.0, 2.0])
    assert np.allclose(composite_profile(wave, q, xi), wave.k_alpha / math.pi * xi, atol=1e-12)


def test_study_table_lists_the_smallest_q_first():
    study = LongWaveStudy(Branch.load(f"{DATA}/branch_alpha1.5.npz"), cells_per_unit=20, count=3)
    rows = [line for line in study.table().splitlines() if line.startswith("| 0.")]
    assert [line.split("|")[1].strip() for line in rows] == ["0.0628", "0.1257", "0.1885"]
    assert study.smallest.q == pytest.approx(math.pi / 50)
