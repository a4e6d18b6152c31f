"""Helpers for the driver scripts: typed application options from the PETSc options database, one-line errors.

Scripts call ``petsc4py.init(sys.argv)`` first, so PETSc options are the command line; application knobs are
read here with a validated type, and any :class:`~hertzpetsc.errors.HertzPetscError` or ``PETSc.Error`` becomes
one line on stderr (rank 0) and a non-zero exit status on every rank.
"""
import json
import math
import platform
import sys
import time

import numpy as np
from petsc4py import PETSc

from . import __version__
from .errors import BranchFileError, ConvergenceError, HertzPetscError, ParameterError

EXIT_PARAMETER, EXIT_CONVERGENCE, EXIT_FILE, EXIT_PETSC = 2, 3, 4, 5


class AppOptions:
    """Typed access to application options (no prefix) in the PETSc options database."""

    def __init__(self):
        self.db = PETSc.Options()

    def _raw(self, name):
        return self.db.getString(name, None) if self.db.hasName(name) else None

    @staticmethod
    def _number(text, expr):
        """float of ``text``; with ``expr`` arithmetic with ``pi`` is allowed (``pi/50``, ``2*pi*1e-3``)."""
        return float(eval(text, {"__builtins__": {}}, {"pi": math.pi}) if expr else float(text))

    def real(self, name, default, valid=None, expr=False):
        """A real option; with ``expr``, values like ``pi/50`` or ``2*pi*1e-3`` are accepted."""
        raw = self._raw(name)
        if raw is None:
            return default
        try:
            value = self._number(raw, expr)
        except Exception:
            raise ParameterError(f"-{name}", raw, "must be a real number" + (" (pi allowed)" if expr else "")) from None
        if valid is not None and not valid[0](value):
            raise ParameterError(f"-{name}", raw, valid[1])
        return value

    def numbers(self, name, default, expr=True, kind=float):
        """A comma-separated list option (``default`` is the list's text), each item converted by ``kind``."""
        raw = self._raw(name)
        text = default if raw is None else raw
        if not text:
            return []
        try:
            values = [self._number(v, expr) for v in text.split(",")]
            if kind is int and any(v != int(v) for v in values):
                raise ValueError
        except Exception:
            raise ParameterError(f"-{name}", text, "must be a comma-separated list of "
                                 + ("integers" if kind is int else "numbers")) from None
        return [kind(v) for v in values]

    def integer(self, name, default, minimum=None):
        raw = self._raw(name)
        if raw is None:
            return default
        try:
            value = int(raw)
        except ValueError:
            raise ParameterError(f"-{name}", raw, "must be an integer"
                                 + (f" >= {minimum}" if minimum is not None else "")) from None
        if minimum is not None and value < minimum:
            raise ParameterError(f"-{name}", raw, f"must be an integer >= {minimum}")
        return value

    def string(self, name, default):
        raw = self._raw(name)
        return default if raw is None else raw

    def flag(self, name):
        return self.db.getBool(name, False) if self.db.hasName(name) else False


def print0(*args, file=sys.stdout):
    """Print on rank 0 of COMM_WORLD only."""
    if PETSc.COMM_WORLD.getRank() == 0:
        print(*args, file=file, flush=True)


def run_metadata(**extra):
    """Software versions and run context recorded in output files."""
    import petsc4py
    meta = dict(hertzpetsc=__version__, petsc=".".join(map(str, PETSc.Sys.getVersion())),
                petsc4py=petsc4py.__version__, numpy=np.__version__, python=platform.python_version(),
                ranks=PETSc.COMM_WORLD.getSize(), argv=sys.argv, created=time.strftime("%Y-%m-%dT%H:%M:%S%z"))
    try:
        import slepc4py
        meta["slepc4py"] = slepc4py.__version__
    except ImportError:  # pragma: no cover - slepc4py is part of the stack, but not needed here
        pass
    meta.update(extra)
    return meta


# Exit status per error class; the first matching class wins (ConvergenceError before its base classes).
EXIT_CODES = ((ParameterError, EXIT_PARAMETER), (ConvergenceError, EXIT_CONVERGENCE), (BranchFileError, EXIT_FILE),
              (HertzPetscError, EXIT_PARAMETER))


def guarded_main(main):
    """Run ``main()``; turn the package's and PETSc's errors into one line on stderr and a non-zero exit."""
    try:
        main()
    except HertzPetscError as err:
        print0(f"error: {err}", file=sys.stderr)
        sys.exit(next(code for cls, code in EXIT_CODES if isinstance(err, cls)))
    except PETSc.Error as err:
        print0(f"error: PETSc error {err.ierr}: see the PETSc message above (check the -tw_* / -chain_* options)",
               file=sys.stderr)
        sys.exit(EXIT_PETSC)


def dumps(obj):
    return json.dumps(obj, indent=1, default=float)
