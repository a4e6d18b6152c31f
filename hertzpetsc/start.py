"""The drivers' first call: PETSc started from the command line, with ``-help`` left to the package.

``-help`` shows a driver's own options and solver roles first and stops (PETSc's banner and its options for every
object it creates are not printed: they are hundreds of lines); ``-help solvers`` adds PETSc's own options of each
of the driver's solver roles. PETSc's other uses of -help (``-help intro``) pass through. ``-h`` and ``--help`` are
the same as ``-help`` (:data:`HELP_ALIASES`). Imports nothing of PETSc before it is started.

Importing this module sets one BLAS thread per process unless the user set OPENBLAS_NUM_THREADS / OMP_NUM_THREADS
(it runs before numpy loads its BLAS): the ranks of a run share the cores, and the small dense solves on rank 0
(the Gauss-Newton steps' least squares, the dense multipliers) are then the same arithmetic on every machine -- a
refinement that sits at the flow's floor of E(q) must not pass or fail with the machine's core count.
"""
import os
import sys

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
    os.environ.setdefault(_name, "1")


# spellings of -help that people type first; PETSc knows only -help (and would refuse these as unknown options)
HELP_ALIASES = ("-h", "--help")


def init_petsc(argv=None):
    """``petsc4py.init(argv)`` with ``-help [solvers]`` (or ``-h``, ``--help``) kept out of PETSc's start and put
    back into the options database (read by :class:`hertzpetsc.options.AppOptions`)."""
    import petsc4py
    args = list(sys.argv if argv is None else argv)
    args[1:] = ["-help" if a in HELP_ALIASES else a for a in args[1:]]
    value = None
    if "-help" in args[1:]:
        i = args.index("-help", 1)
        nxt = args[i + 1] if i + 1 < len(args) else None
        if nxt == "intro":
            petsc4py.init(args)
            return
        value = "solvers" if nxt == "solvers" else ""
        del args[i:i + (2 if nxt == "solvers" else 1)]
    petsc4py.init(args)
    if value is not None:
        from petsc4py import PETSc
        PETSc.Options().setValue("help", value or None)
