"""Studies: the loops over parameters that the paper's sections are made of, with their records and tables.

Each study takes validated parameters and a communicator, configures its solvers when it is built (so that a
driver can check the options database before computing), computes when run, writes its records as it goes
through :mod:`hertzpetsc.records` (resumable, rank 0, atomic), and renders its table as Markdown. Drivers in
``scripts/`` only read options, build a study, run it and write its table and figures.

=====================  ===================================================================================
module                 studies
=====================  ===================================================================================
``branch``             :class:`BranchStudy` (sec. 3.1), :class:`ConvergenceStudy` (order in h),
                       :class:`SmallQStudy` (sec. 3.2, grids refined as q decreases, Richardson)
``refinement``         :class:`RefinementScan` (sec. 3.4: E(q), Gauss-Newton), :class:`RefinedStates`
``floquet``            :class:`FloquetScan` (sec. 3.5: rho(F_q), q_c, q_m), :class:`BlochScan` (long chains)
``longrun``            :class:`LongRun` (sec. 3.4: long simulations, exact resume)
``solitary``           :class:`SolitaryStudy` (appendix: k_alpha in the grid step and the domain)
``longwave``           :class:`LongWaveStudy` (sec. 3.2: eq. solapprox against the branch)
``compactons``         :class:`CompactonStudy` (sec. 3.3: compactons on the lattice)
``paper``              :class:`PaperPipeline` (every study of sections 3.1-3.5 and the appendix, in order)
=====================  ===================================================================================
"""
