"""Reference records of the implementation before the one-model merge (commit f463cb8), for tests/test_previous.py.

Run once, against that commit's package:  PYTHONPATH=<checkout of f463cb8> python tests/data/make_previous.py
Small cases of every family whose machinery was merged: the q-branch, the precompressed amplitude family (with the
gap opening and the uncompressed limit), the dimer's mass-ratio continuation, an exact compacton and its window
multipliers, a refined wave with its Floquet multipliers, a precompressed stability-map point.
"""
import math
import os

import numpy as np
from petsc4py import PETSc

import hertzpetsc
from hertzpetsc.branch import Branch
from hertzpetsc.continuation import BranchContinuation, ContinuationParameters
from hertzpetsc.grid import ProfileGrid
from hertzpetsc.model import ChainSpec, LatticeModel

COMM = PETSc.COMM_SELF
OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "previous_records.npz")
data = {"source": np.array(os.path.dirname(hertzpetsc.__file__))}

# 1. q-branch, alpha = 3/2, h = pi/200, q = m pi/10 down to pi/5
params = ContinuationParameters(alpha=1.5, M=10, cells_per_pi=200, q_stop=math.pi / 5)
cont = BranchContinuation(params, COMM)
points = list(cont.points())
cont.destroy()
branch = Branch(params.model, 200, 10, points)
data["branch_q"] = np.array([p.q for p in points])
data["branch_u"] = np.array([p.u_half for p in points])
data["branch_norm"] = np.array([p.diagnostics.norm_inf for p in points])

# 2. precompressed amplitude family at q = 3 pi/10 (alpha = 3/2, delta0 = 1, h = pi/100)
from hertzpetsc.precompression import AmplitudeContinuation, MassContinuation, uncompressed_limit
model = LatticeModel.hertz(1.5, delta0=1.0)
grid = ProfileGrid(100, COMM)
q = 3 * math.pi / 10
amps = [1e-3 * math.exp(0.5 * k) for k in range(0, 19)]
ac = AmplitudeContinuation(model, q, grid)
pts, gap = [], None
prev = None
for a in amps:
    p = ac.step_to(a)
    if prev is not None and prev.gap < 0 <= p.gap and gap is None:
        gap = ac.locate_gap(prev, p)
    pts.append(p)
    prev = p
limit = uncompressed_limit(model, q, grid, pts[-1])
ac.destroy()
data["amp_a"] = np.array([p.a for p in pts])
data["amp_lam"] = np.array([p.lam for p in pts])
data["amp_omega"] = np.array([p.omega for p in pts])
data["amp_A"] = np.array([p.A for p in pts])
data["amp_gap"] = np.array([p.gap for p in pts])
data["amp_w0"] = np.array(pts[-1].profiles[0])
data["amp_gap_point"] = np.array([gap.a, gap.A, gap.omega, gap.lam])
data["amp_limit"] = np.array([limit["Omega0"], limit["lam"], limit["norm"]])

# 3. dimer (masses 1, epsilon) at q = 3 pi/10, a = 0.5, h = pi/64: pseudo-arclength in epsilon from 1
dimer = LatticeModel.hertz(1.5, masses=(1.0, 1.0), delta0=1.0)
g64 = ProfileGrid(64, COMM)
mc = MassContinuation(dimer, q, g64, 0.5, ds=0.02, ds_max=0.1)
mpts = mc.start()
for k, p in enumerate(mc.run(0.4, 60)):
    mpts.append(p)
mc.destroy()
data["dimer_epsilon"] = np.array([p.epsilon for p in mpts])
data["dimer_omega"] = np.array([p.wave.omega for p in mpts])
data["dimer_lam"] = np.array([p.wave.lam for p in mpts])
data["dimer_norm_v"] = np.array([0.5 * max(abs(np.asarray(p.wave.profiles[1]))) for p in mpts])

# 4. exact compacton at q = pi/5 on an 18-bead window, its multipliers
from hertzpetsc.compacton_window import (CompactonRefiner, CompactonWindow, guess_from_branch, sorted_eig,
                                         split_jordan_pair)
pt = branch.point(math.pi / 5)
Y, gap0 = guess_from_branch(pt, 18, 6, branch.q_k())
win = CompactonWindow(branch.model, 18, COMM)
ex = CompactonRefiner(win).refine(Y, gap0, pt.q)
lam, _ = sorted_eig(win.jacobian(ex.Y, ex.gap)[1])
mean, split, rest = split_jordan_pair(lam)
win.destroy()
data["compacton_gap"] = np.array(ex.gap)
data["compacton_Y"] = ex.Y
data["compacton_residual"] = np.array(ex.residual)
data["compacton_dominant"] = rest[:3]

# 5. a refined wave (N = 20, q = 3 pi/10 is m = 3 wavelengths) and its multipliers
from hertzpetsc.floquet import DenseFloquet
from hertzpetsc.shooting import Refiner
from hertzpetsc.waves import orbit_on_chain
spec = ChainSpec(branch.model, 20)
orbit = orbit_on_chain(branch.point(3 * math.pi / 10), spec)
ref = Refiner(spec, COMM).refine(orbit)
df = DenseFloquet(spec, COMM)
sp = df.spectrum(ref.orbit)
df.destroy()
data["refined_x"] = ref.orbit.x
data["refined_E"] = np.array(ref.E)
data["refined_T"] = np.array(ref.orbit.T)
data["refined_rho"] = np.array(sp.rho)
data["refined_multipliers"] = sp.multipliers

# 6. stability-map point: precompressed wave at q = 2 pi/5 (N = 10), a = 2, Richardson (K, 2K) profiles
from hertzpetsc.studies.precompression import richardson_wave, wave_orbit
waves = richardson_wave(model, 2 * math.pi / 5, [2.0], 64, COMM)
a, w, lam_ = waves[0]
orb = wave_orbit(model, 2 * math.pi / 5, a, w, lam_, 10)
df = DenseFloquet(ChainSpec(model, 10), COMM)
sp = df.spectrum(orb)
df.destroy()
data["map_x"] = orb.x
data["map_T"] = np.array(orb.T)
data["map_rho"] = np.array(sp.rho)
data["map_multipliers"] = sp.multipliers
np.savez(OUT, **data)
print("wrote", OUT, sorted(data))
