# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # hertzpetsc in a notebook
#
# A notebook in jupytext's percent format: each `# %%` line starts a cell. Jupyter with the jupytext extension
# opens this file as a notebook; `jupytext --to notebook tutorial_notebook.py` makes an `.ipynb` of it; plain
# Python runs it as a script (`python docs/tutorial_notebook.py`, or on 2 ranks under `mpiexec -n 2`), and so does
# the test suite (`tests/test_notebook.py`). [docs/notebook.md](notebook.md) explains the workflow.
#
# Every `hz.` call is collective: under MPI all ranks make it and get the same result. The figures are
# matplotlib `Figure` objects: the last expression of a cell shows inline; nothing is written to a file unless a
# directory is given. The sizes are small so that the whole notebook runs in well under a minute; the paper's are
# in the comments.

# %%
import math

import numpy as np
from petsc4py import PETSc

import hertzpetsc as hz
from hertzpetsc import plotting

rank0 = PETSc.COMM_WORLD.getRank() == 0                         # print and write files on rank 0 only

# %% [markdown]
# ## 1. The branch of travelling waves and its figures (section 3.1)

# %%
model = hz.LatticeModel.hertz(alpha=1.5)                      # the paper's chain
branch = hz.compute_branch(model, M=10, cells_per_pi=200)       # q = pi, 9pi/10, ..., pi/10 (paper: M = 50, pi/1000)
figures = plotting.plot_branch_figures(branch)                  # six Figures, nothing written
figures[1]                                                      # fig. normes: ||u||_inf against q

# %% [markdown]
# ## 2. Stability against q, with per-call solver options (sections 3.4, 3.5)
#
# `options=` sets solver options for one call only (full names, prefix included); the options database is
# exactly as it was afterwards. Here the refinement may take up to 30 Gauss-Newton iterations (`shoot_gn_max_it`,
# default 20), and the multipliers' flow runs at rtol 1e-12 instead of its default 1e-14 (`floquet_ts_rtol`:
# faster, and still far below the verdict's threshold rho - 1 > 1e-4).

# %%
qs = [math.pi / 5, 3 * math.pi / 10, 2 * math.pi / 5]
spectra = []
for q in qs:
    orbit = hz.orbit(branch.point(q), N=20)                     # 2, 3, 4 wavelengths on 20 beads
    refined = hz.refine(orbit, options={"shoot_gn_max_it": 30})
    spectra.append(hz.multipliers(refined.orbit, options={"floquet_ts_rtol": 1e-12}))
rho = np.array([s.rho for s in spectra])
if rank0:
    for q, s in zip(qs, spectra):
        print(f"q = {q:.4f}: rho - 1 = {s.rho - 1:.2e}, {s.outside} multipliers outside the unit circle")
plotting.plot_floquet_radius(np.array(qs), rho, spectra[0].tol_rho)

# %%
eigen = plotting.plot_multipliers([(f"{q / math.pi:.2g} pi", s.multipliers) for q, s in zip(qs, spectra)])
eigen

# %% [markdown]
# ## 3. A driven, damped chain: responses at given frequencies (issue 22)
#
# `hz.response` gives the periodic responses of a driven chain at the frequencies asked for, with their Floquet
# multipliers (all 2N here, checked against Liouville's determinant and the damped flow's symplecticity): the
# first from the state after 20 driving periods from rest, each next one continued from the one before.

# %%
drive = hz.Drive(hz.LatticeModel.hertz(1.5, delta0=1.0, gamma=0.05), 10, hz.HarmonicWave(), amplitude=0.05, omega=0.5)
responses = hz.response(drive, np.linspace(0.5, 0.8, 13), run_in=20)
if rank0:
    for r in responses:
        print(f"omega = {r.omega:.3f}: max |mu| = {r.rho:.6f}, force on the wall {r.record['force_right']:.4g}")
response_figure = plotting.plot_driven_response([r.record for r in responses], "omega")
response_figure

# %% [markdown]
# ## 4. Writing figures
#
# A figure is written where you ask, on one rank: `fig.savefig(path)`, or `directory=` of a plotting function,
# which writes its usual file name there atomically (the drivers in `scripts/` call them so) and keeps the path
# in `fig.path`.

# %%
if rank0:
    response_figure.savefig("driven_response.png", dpi=120)
    written = plotting.plot_floquet_radius(np.array(qs), rho, spectra[0].tol_rho, directory="figures")
    print("wrote driven_response.png and", written.path)
