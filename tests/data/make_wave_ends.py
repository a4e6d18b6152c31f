"""The refined travelling wave q = pi/10 of the 100-bead periodic chain (alpha = 3/2), for tests/test_driven.py
(the exact boundary driving of a 10-bead window, whose beads are all in free flight for part of the period).

Run once from the repository:  python tests/data/make_wave_ends.py  (reads results/branch_alpha1.5.npz and
results/refined_N100.npz as committed at 217f6ff; writes tests/data/wave_ends_pi10.npz: q, m, T, omega, x (100, 2)).
"""
import math
import os

import numpy as np
from petsc4py import PETSc

from hertzpetsc.branch import Branch
from hertzpetsc.studies.refinement import RefinedStates

HERE = os.path.dirname(os.path.abspath(__file__))
RESULTS = os.path.join(os.path.dirname(os.path.dirname(HERE)), "results")

if __name__ == "__main__":
    comm = PETSc.COMM_SELF
    branch = Branch.load(os.path.join(RESULTS, "branch_alpha1.5.npz"), comm)
    refined = RefinedStates.load(os.path.join(RESULTS, "refined_N100.npz"), comm)
    orbit = refined.orbit(branch.point(math.pi / 10))
    assert orbit.N == 100 and orbit.spec.model.alpha == 1.5 and orbit.spec.boundary == "periodic"
    np.savez(os.path.join(HERE, "wave_ends_pi10.npz"), q=orbit.q, m=orbit.m, T=orbit.T, omega=orbit.omega, x=orbit.x)
