"""Exceptions raised by hertzpetsc.

Every error names the offending parameter (and its valid range) or the continuation parameter at which a solver
failed, in one line, so that drivers can print ``str(err)`` and exit non-zero.
"""


class HertzPetscError(Exception):
    """Base class of the package's errors."""


class ParameterError(HertzPetscError, ValueError):
    """A parameter is outside its valid range."""

    def __init__(self, name, value, valid):
        self.name, self.value, self.valid = name, value, valid
        super().__init__(f"invalid {name} = {value!r}: {valid}")


class ConvergenceError(HertzPetscError, RuntimeError):
    """A PETSc solver did not converge; carries the converged reason and the parameter value."""

    def __init__(self, what, reason, **where):
        self.what, self.reason, self.where = what, reason, where
        at = ", ".join(f"{k} = {v:.12g}" if isinstance(v, float) else f"{k} = {v}" for k, v in where.items())
        super().__init__(f"{what} did not converge (reason {reason}) at {at}")


class BranchFileError(HertzPetscError, IOError):
    """A branch file is missing, corrupt, or belongs to another computation."""


class RunFileError(BranchFileError):
    """A snapshot directory or refinement file is missing, corrupt, or belongs to another run."""
