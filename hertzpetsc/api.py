"""One-call conveniences of the public surface (``hz.branch``, ``hz.wave_at``), for notebooks: each builds the
package's objects with the paper's defaults, runs them, frees the PETSc objects, and returns plain results. They
are collective over ``comm`` (default PETSc.COMM_WORLD)."""
from __future__ import annotations

from typing import Optional

from petsc4py import PETSc

from .branch import Branch
from .families import AmplitudePoint
from .families import wave_at as _wave_at
from .grid import ProfileGrid
from .model import LatticeModel
from .qbranch import ContinuationParameters
from .studies.branch import BranchStudy


def branch(model: Optional[LatticeModel] = None, M: int = 50, cells_per_pi: int = 1000,
           q_stop: Optional[float] = None, output: Optional[str] = None, mode: str = "new",
           comm=None) -> Branch:
    """The branch of eq. ad from the binary oscillation at q = pi down to q_stop through q = m pi / M (section
    3.1), on the grid h = pi / cells_per_pi, for the uncompressed monatomic ``model`` (default: the paper's, alpha
    = 3/2). Written to ``output`` as it goes when given (a branch file; ``mode`` new/resume/force), else kept in
    memory. Collective over ``comm``."""
    model = model if model is not None else LatticeModel.hertz()
    params = ContinuationParameters(M=M, cells_per_pi=cells_per_pi, q_stop=q_stop, model=model)
    study = BranchStudy(params, output, comm if comm is not None else PETSc.COMM_WORLD, mode)
    for _ in study.run():
        pass
    return study.branch


def wave_at(model: LatticeModel, q: float, A: float, cells_per_pi: int = 400, branch: str = "acoustic",
            comm=None) -> AmplitudePoint:
    """The travelling wave of a precompressed ``model`` (any mass pattern) with per-bead wavenumber q and amplitude
    A = max |u| (A is a border row of eq. ad; reached from the linear wave by natural steps), on the grid h = pi /
    cells_per_pi. Returns an :class:`~hertzpetsc.families.AmplitudePoint` (omega, profiles, ...); its
    ``branch_point(model, h)`` puts it on a chain. Collective over ``comm``."""
    grid = ProfileGrid(cells_per_pi, comm if comm is not None else PETSc.COMM_WORLD)
    return _wave_at(model, q, A, grid, branch=branch)

