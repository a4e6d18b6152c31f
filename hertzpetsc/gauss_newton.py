"""The one Gauss-Newton engine with phase conditions, for fixed points of flow maps: travelling waves on the periodic
chain (section 3.4, :class:`hertzpetsc.shooting.Refiner`) and exact compactons on the travelling window (section
3.3, :class:`hertzpetsc.compacton_window.CompactonRefiner`).

A problem gives its rows R(z) (the map's defect, condition rows: a phase, the gap) with a measure E(z), and their
Jacobian A with an orthonormal basis Q of the admissible steps (phase conditions by projection; None: all). A step
d = Q c minimises ||A Q c + R|| by the SVD of A Q truncated at the relative levels ``truncations`` (0: plain least
squares), on rank 0 and broadcast: the first level that reduces E tenfold, else the best. A step that does not reduce
E is refused: a stale Jacobian (``reuse_jacobian``, as in the paper; re-evaluated when a step falls short of a tenfold
reduction) is then re-evaluated, a fresh one ends the iteration (the flow's floor).
"""
import math
from dataclasses import dataclass, field

import numpy as np

# Relative singular-value cut-offs tried at each iteration (0: plain least squares on A Q).
TRUNCATIONS = (0.0, 1e-9, 1e-7, 1e-5, 1e-3)


@dataclass
class GaussNewtonResult:
    """The last iterate z, its rows and E, accepted steps, Jacobians, the last step's max|dz| / max|z| (the paper's
    r), the smallest singular value of A Q at the last fresh Jacobian, and E after each step (the start first)."""

    z: np.ndarray
    rows: np.ndarray
    E: float
    iterations: int
    jacobians: int
    r: float = math.nan
    sigma_min: float = None
    history: list = field(default_factory=list)


class GaussNewton:
    """Gauss-Newton on a problem with ``residual(z) -> (R, E)`` and ``jacobian(z) -> (A, Q)`` (module docstring);
    collective over ``comm`` (every rank evaluates the problem, rank 0 solves)."""

    def __init__(self, comm, truncations=TRUNCATIONS, reuse_jacobian=True):
        self.mpi = comm.tompi4py()
        self.truncations, self.reuse_jacobian = tuple(truncations), reuse_jacobian

    def steps(self, A, R, Q=None):
        """The candidate steps (one per truncation level) and the smallest singular value of A Q, on every rank."""
        out = None
        if self.mpi.rank == 0:
            U, sv, Vt = np.linalg.svd(A if Q is None else A @ Q, full_matrices=False)
            coef = U.T @ -R
            steps = []
            for cut in self.truncations:
                keep = sv > cut * sv[0]
                c = Vt[keep].T @ (coef[keep] / sv[keep])
                steps.append(c if Q is None else Q @ c)
            out = (steps, float(sv[-1]))
        return self.mpi.bcast(out, root=0)

    def solve(self, problem, z, target, max_iterations):
        """Iterate from ``z`` until E <= ``target``, the iteration limit, or no decrease with a fresh Jacobian."""
        z = np.array(z, dtype=float)
        R, E = problem.residual(z)
        history, it, jacobians, A, Q, fresh, r, sigma_min = [E], 0, 0, None, None, False, math.nan, None
        while E > target and it < max_iterations:
            if A is None:
                A, Q = problem.jacobian(z)
                jacobians, fresh = jacobians + 1, True
            steps, sig = self.steps(A, R, Q)
            sigma_min = sig if fresh else sigma_min
            best = None
            for d in steps:               # the first step that reduces E tenfold, else the best one
                cand = (z + d,) + tuple(problem.residual(z + d))
                if best is None or cand[2] < best[2]:
                    best = cand
                if best[2] <= 0.1 * E:
                    break
            if best[2] < E:
                r = float(np.max(np.abs(best[0] - z)) / np.max(np.abs(best[0])))
                previous, (z, R, E) = E, best
                it += 1
                history.append(E)
                if not self.reuse_jacobian or (E > 0.1 * previous and not fresh):
                    A = None              # a fresh Jacobian at every iterate, or slow progress with a stale one
                fresh = False
            elif not fresh:
                A = None                  # the stale Jacobian gives no decrease: re-evaluate and retry
            else:
                break                     # no decrease even with a fresh Jacobian
        return GaussNewtonResult(z, R, E, it, jacobians, r, sigma_min, history)
