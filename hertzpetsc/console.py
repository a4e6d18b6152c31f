"""The library's lines on the console: everything the package prints goes through here, except the drivers' own
lines (``-help``, ``check:``, ``error:``) printed by :mod:`hertzpetsc.options`. Solvers and studies return their
results; what they say besides is a note on stderr from one rank (tests/test_architecture.py keeps print here).
"""
from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Any, Optional, TextIO

if TYPE_CHECKING:
    from petsc4py import PETSc


def print0(*args: Any, file: TextIO = sys.stdout) -> None:
    """Print on rank 0 of COMM_WORLD only."""
    from petsc4py import PETSc                  # here: the drivers start PETSc before they import it
    if PETSc.COMM_WORLD.getRank() == 0:
        print(*args, file=file, flush=True)


def note(message: str, comm: Optional[PETSc.Comm] = None) -> None:
    """One line ``note: message`` on stderr from rank 0 of ``comm`` (default COMM_WORLD): what a computation says
    besides its result (a fallback taken, a point left without a verdict, a curve ended early)."""
    from petsc4py import PETSc
    if (comm if comm is not None else PETSc.COMM_WORLD).getRank() == 0:
        print(f"note: {message}", file=sys.stderr, flush=True)
