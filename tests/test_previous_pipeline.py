"""The merged pipeline against the previous implementation's records (tests/data/previous_records.npz, made by
tests/data/make_previous.py at commit f463cb8): a refined wave and its Floquet multipliers (one orbit builder, one
Gauss-Newton engine, one Floquet signature), an exact compacton and its window multipliers (the same engine on the
window map), and a precompressed stability-map point (the orbit builder with the law's exact scaling)."""
import math
import os

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import small_branch
from hertzpetsc.branch import BranchPoint
from hertzpetsc.compacton_spectrum import sorted_eig, split_jordan_pair
from hertzpetsc.compacton_window import CompactonRefiner, CompactonWindow, guess_from_branch
from hertzpetsc.floquet import DenseFloquet, trivial_multipliers
from hertzpetsc.model import ChainSpec, LatticeModel
from hertzpetsc.shooting import Refiner
from hertzpetsc.studies.precompression import richardson_wave
from hertzpetsc.waves import orbit_on_chain

COMM = PETSc.COMM_SELF
PREVIOUS = np.load(os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "previous_records.npz"))


def nontrivial_distance(a, b):
    """max over a (trivial four excluded) of the distance to the nearest of b (trivial four excluded)."""
    va, vb = (np.delete(v, trivial_multipliers(v)) for v in (np.asarray(a), np.asarray(b)))
    return max(float(np.min(np.abs(vb - v))) for v in va)


def test_refined_wave_and_its_multipliers():
    """q = 3 pi/10 on 20 beads from the h = pi/200 branch, refined on its cell to E <= 1e-10, then dense F_q. The
    refined state is a fixed point pinned only up to the phase directions: it agrees with the previous one to the
    refinement's own size of a step (E <= 1e-10 with sigma_min ~ 1e-2 bounds it by ~1e-8; measured 0, the same
    arithmetic); script-T is the same formula (measured 0); rho to the flow's accuracy (rtol 1e-14) and the
    other multipliers within the square root of E (double multipliers on the unit circle)."""
    spec = ChainSpec(LatticeModel.hertz(1.5), 20)
    orbit = orbit_on_chain(small_branch().point(3 * math.pi / 10), spec)
    refiner = Refiner(spec, COMM)
    dense = DenseFloquet(spec, COMM)
    try:
        ref = refiner.refine(orbit)
        sp = dense.spectrum(ref.orbit)
    finally:
        refiner.destroy()
        dense.destroy()
    assert ref.orbit.T == pytest.approx(float(PREVIOUS["refined_T"]), rel=1e-14)
    assert ref.E <= 1e-10 and float(PREVIOUS["refined_E"]) <= 1e-10
    assert np.max(np.abs(ref.x - PREVIOUS["refined_x"])) < 1e-8
    # the wave is stable: rho - 1 ~ 1e-6 is the splitting of double multipliers on the unit circle, sqrt(E) for
    # an orbit off by E (the branch it starts from now differs from the previous one by ~1e-13, so the refined
    # fixed point moves within the refinement's tolerance): the same bound as the other multipliers
    assert abs(sp.rho - float(PREVIOUS["refined_rho"])) < 1e-5
    assert nontrivial_distance(sp.multipliers, PREVIOUS["refined_multipliers"]) < 1e-5
    assert nontrivial_distance(PREVIOUS["refined_multipliers"], sp.multipliers) < 1e-5


def test_exact_compacton_and_its_window_multipliers():
    """q = pi/5 on an 18-bead window from the branch guess: the engine's fixed point is pinned by the same phase
    condition, so the state agrees with the previous one to the refinement's residual scale (measured 2e-14 on
    positions of order D = 3.5); the residuals are both at the flow's floor (~1e-14); the gap and the dominant
    nontrivial multipliers to 1e-10 (measured 1e-15 and 8e-14)."""
    branch = small_branch()
    pt = branch.point(math.pi / 5)
    Y, gap0 = guess_from_branch(pt, 18, 6, branch.q_k())
    win = CompactonWindow(branch.model, 18, COMM)
    try:
        ex = CompactonRefiner(win).refine(Y, gap0, pt.q)
        lam, _ = sorted_eig(win.jacobian(ex.Y, ex.gap)[1])
    finally:
        win.destroy()
    _, _, rest = split_jordan_pair(lam)
    assert abs(ex.gap - float(PREVIOUS["compacton_gap"])) < 1e-10
    assert np.max(np.abs(ex.Y - PREVIOUS["compacton_Y"])) < 1e-10
    assert ex.residual < 1e-12 and float(PREVIOUS["compacton_residual"]) < 1e-12
    assert np.max(np.abs(rest[:3] - PREVIOUS["compacton_dominant"])) < 1e-10


def test_precompressed_map_point():
    """The stability map's wave (alpha = 3/2, delta0 = 1, q = 2 pi/5, a = 2, Richardson profiles of h = pi/64 and
    pi/128) put on 10 beads by the one orbit builder: the rescaled profiles w with frequency sqrt(lam) on the law
    with delta0 / a, scaled by a (x = a w, omega = a^((alpha-1)/2) sqrt(lam)): the same arithmetic as before
    (state and script-T measured equal); the dense multipliers to the flow's accuracy."""
    model = LatticeModel.hertz(1.5, delta0=1.0)
    q = 2 * math.pi / 5
    a, w, lam = richardson_wave(model, q, [2.0], 64, COMM)[0]
    point = BranchPoint(q, w[0], math.pi / 64, model.rescaled(a), profiles=tuple(w), omega=math.sqrt(lam))
    spec = ChainSpec(model, 10)
    orbit = orbit_on_chain(point, spec, scale=a)
    dense = DenseFloquet(spec, COMM)
    try:
        sp = dense.spectrum(orbit)
    finally:
        dense.destroy()
    assert orbit.T == pytest.approx(float(PREVIOUS["map_T"]), rel=1e-12)
    assert np.max(np.abs(orbit.x - PREVIOUS["map_x"])) < 1e-12 * np.max(np.abs(orbit.x))
    assert abs(sp.rho - float(PREVIOUS["map_rho"])) < 1e-9
    assert nontrivial_distance(sp.multipliers, PREVIOUS["map_multipliers"]) < 1e-6
