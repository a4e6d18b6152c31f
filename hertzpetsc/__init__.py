"""hertzpetsc: travelling waves of Hertzian granular chains on PETSc/SLEPc.

Reference: G. James, *Periodic travelling waves and compactons in granular chains*, J. Nonlinear Sci. (2012).
Equation labels in docstrings are the paper's (eq. ad, eq. vhertz, ...).

Importing the package does not import PETSc: :mod:`hertzpetsc.branchfile`, :mod:`hertzpetsc.diagnostics`,
:mod:`hertzpetsc.hertz` and :mod:`hertzpetsc.binary` need only numpy.
"""

__version__ = "0.1.0"
