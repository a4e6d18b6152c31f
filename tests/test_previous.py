"""The merged pipeline against the records of the implementation before the merge (tests/data/previous_records.npz,
written by tests/data/make_previous.py at commit f463cb8): the q-branch, the precompressed amplitude family with
its gap opening and uncompressed limit, and the dimer's mass-ratio continuation. The same discrete equations are
solved by the same Newton to the round-off floor, so the values agree to solver tolerance (bounds below)."""
import math
import os

import numpy as np
import pytest
from petsc4py import PETSc

from hertzpetsc.families import AmplitudeFamily, MassFamily, uncompressed_limit
from hertzpetsc.grid import ProfileGrid
from hertzpetsc.model import LatticeModel
from hertzpetsc.qbranch import BranchContinuation, ContinuationParameters

COMM = PETSc.COMM_WORLD
REF = np.load(os.path.join(os.path.dirname(__file__), "data", "previous_records.npz"))


def rel(x, y):
    x, y = np.asarray(x, float), np.asarray(y, float)
    return float(np.max(np.abs(x - y) / np.abs(y)))


def test_q_branch_is_the_previous_one():
    params = ContinuationParameters(alpha=1.5, M=10, cells_per_pi=200, q_stop=math.pi / 5)
    cont = BranchContinuation(params, COMM)
    try:
        points = list(cont.points())
    finally:
        cont.destroy()
    assert np.allclose([p.q for p in points], REF["branch_q"], rtol=0, atol=1e-15)
    u = np.array([p.u_half for p in points])
    # Newton stops at the round-off floor (atol ~ 4e2 eps |u| / h^2 sqrt(K)): profiles agree to ~1e-12 relative
    assert np.max(np.abs(u - REF["branch_u"])) < 1e-11 * np.max(np.abs(REF["branch_u"]))
    assert rel([p.diagnostics.norm_inf for p in points], REF["branch_norm"]) < 1e-12


def test_amplitude_family_gap_and_limit_are_the_previous_ones():
    model = LatticeModel.hertz(1.5, delta0=1.0)
    grid = ProfileGrid(100, COMM)
    q = 3 * math.pi / 10
    fam = AmplitudeFamily(model, q, grid)
    try:
        pts, gaps = [], []
        for a in REF["amp_a"]:
            pts.append(fam.step_to(a))
            gaps += fam.events()
        limit = uncompressed_limit(model, q, grid, pts[-1])
    finally:
        fam.destroy()
    assert rel([p.lam for p in pts], REF["amp_lam"]) < 1e-12
    assert rel([p.A for p in pts], REF["amp_A"]) < 1e-12
    assert rel([p.omega for p in pts], REF["amp_omega"]) < 1e-12
    assert len(gaps) == 1
    # the gap is located by regula falsi to |gap| < 1e-10 delta0 (previous) and by the layer to 1e-9 of the step:
    # the located amplitudes agree to that tolerance
    g = gaps[0]
    assert rel([g.a, g.A, g.omega, g.lam], REF["amp_gap_point"]) < 1e-9
    assert rel([limit["Omega0"], limit["lam"], limit["norm"]], REF["amp_limit"]) < 1e-12


def test_mass_family_is_the_previous_one():
    dimer = LatticeModel.hertz(1.5, masses=(1.0, 1.0), delta0=1.0)
    fam = MassFamily(dimer, 3 * math.pi / 10, ProfileGrid(64, COMM), 0.5, ds=0.02, ds_max=0.1)
    try:
        pts = fam.start() + [p for p in fam.run(0.4, 60)]
    finally:
        fam.destroy()
    regular = [p for p in pts if p.event is None]
    assert len(regular) == len(REF["dimer_epsilon"])
    # the same pseudo-arclength steps (same ds sequence): each point agrees to the Newton tolerance
    assert np.max(np.abs([p.epsilon for p in regular] - REF["dimer_epsilon"])) < 1e-11
    assert rel([p.wave.omega for p in regular], REF["dimer_omega"]) < 1e-11
    assert rel([p.wave.lam for p in regular], REF["dimer_lam"]) < 1e-11
    # new: the gap opening on the path is located between the two points that bracket it
    gaps = [p for p in pts if p.event == "gap"]
    assert len(gaps) == 1 and abs(gaps[0].wave.gap) < 1e-8
