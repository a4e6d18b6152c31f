"""Verdicts that state what they rest on (issue 21): the slow-instability verdict's three outcomes and its grid
check, Richardson from the grids' actual ratios, q labels that are fractions of pi only when q is one, a missing
reference file refused before any computation, and no record from a failed flow."""
import math
import os
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import DATA, one_error_line, run_script
from hertzpetsc.errors import ParameterError
from hertzpetsc.richardson import observed_order, richardson
from hertzpetsc.studies.floquet import q_label
from hertzpetsc.studies.slow import CELLS_PER_Q, SlowInstabilityScan


def verdict(gamma_cm, gamma_mono=math.nan, target=1e-3):
    return SlowInstabilityScan.verdict(SimpleNamespace(target=target), dict(gamma_cm=gamma_cm, gamma_mono=gamma_mono))


def test_slow_verdict_is_unstable_stable_or_unresolved():
    # above the target on every grid, the last two within 10 %: slowly unstable, bound |g1 - g2| / 3
    res, v = verdict([2.2e-3, 2.05e-3, 2.0e-3])
    assert v == 1 and res == pytest.approx(0.05e-3 / 3)
    # every gamma below the target: stable within the largest one measured (the monodromy's included)
    res, v = verdict([1e-5, 3e-6, 1e-6], gamma_mono=4e-5)
    assert v == 0 and res == pytest.approx(4e-5)
    # a gamma above the target on grids that disagree: no bound claimed
    res, v = verdict([5e-3, 2e-3, 1e-4])
    assert v == 2 and res == pytest.approx(5e-3)
    # below the target on the co-moving grids but the monodromy route above it: not 'stable'
    assert verdict([1e-5, 1e-5, 1e-5], gamma_mono=2e-3)[1] == 2


@pytest.mark.serial
def test_slow_grids_too_coarse_for_the_wavenumber_are_refused_before_computing():
    # q = pi/10 needs K >= CELLS_PER_Q pi / q = 200 cells per pi on the coarsest grid
    r = run_script("slow_instabilities.py", "-q", "pi/10", "-grids", "100,200,400", "-reference", "none",
                   "-output", "/nonexistent/x.npz", timeout=60)
    line = one_error_line(r)
    assert r.returncode == 2 and "-grids" in line and f"at least {CELLS_PER_Q}" in line, r.stderr


def test_richardson_uses_the_actual_grid_ratios():
    # f(h) = 1 + 3 h^2 exactly: on grids that are not halvings the order is 2 and the limit 1 (closed form); the
    # constant-ratio formula with ratio 2 would give neither
    h = [0.1, 0.07, 0.04]
    f = [1 + 3 * x * x for x in h]
    p, lim = richardson(f, steps=h)
    assert p == pytest.approx(2, abs=1e-9) and lim == pytest.approx(1, abs=1e-12)
    assert abs(observed_order(f) - 2) > 0.1
    with pytest.raises(ParameterError):
        richardson(f, steps=[0.1, 0.1, 0.04])          # a grid list that is not refined


def test_q_is_labelled_a_fraction_of_pi_only_when_it_is_one():
    assert q_label(7 * math.pi / 25) == "7pi/25" and q_label(math.pi / 50) == "pi/50" and q_label(math.pi) == "pi"
    assert q_label(2 * math.pi) == "2pi"
    assert q_label(1.0) == "1" and q_label(0.3) == "0.3"
    assert q_label(7 * math.pi / 22 * (1 + 1e-9)) != "7pi/22"


@pytest.mark.serial
def test_a_missing_reference_file_is_an_error_before_any_computation(tmp_path):
    r = run_script("floquet_long.py", "-refined", os.path.join(DATA, "refined_N100.npz"), "-reference",
                   str(tmp_path / "missing.npz"), "-sizes", "200", "-q", "7*pi/25", "-output", str(tmp_path / "l.md"),
                   "-npz", str(tmp_path / "l.npz"), timeout=60)
    line = one_error_line(r)
    assert r.returncode != 0 and "reference" in line and "missing.npz" in line, r.stderr
    assert not os.path.exists(tmp_path / "l.npz") and not os.path.exists(tmp_path / "l.md")


@pytest.mark.serial
def test_a_flow_that_fails_leaves_no_record(tmp_path):
    out = tmp_path / "f.npz"
    r = run_script("floquet_scan.py", "-q", "3*pi/10", "-output", str(out), "-table", str(tmp_path / "f.md"),
                   "-floquet_ts_max_steps", "3", timeout=120)
    assert r.returncode != 0 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    if os.path.exists(out):                            # the record store, if created, holds no row
        with np.load(out) as f:
            assert all(f[k].shape[:1] in ((0,), ()) for k in f.files if k == "rho"), dict(f)
