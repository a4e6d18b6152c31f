"""The long-wave limit (section 3.2): the branch at its smallest q against the inner solution (the solitary wave,
eq. inner) and the composite approximation (eq. solapprox)."""
import functools
import math

from petsc4py import PETSc

from ..branch import Branch
from ..errors import check_instance, check_integer, check_real
from ..longwave import compare_with_branch
from ..roles import configure, uses
from ..solitary import SolitaryParameters, solve_solitary_wave

Q_REPORT = 10     # the branch points with the 10 smallest q


class LongWaveStudy:
    """Errors of eq. solapprox and of the inner solution, relative to k_alpha, at the ``count`` smallest q (computed
    when first asked for: building the study checks its arguments and the options of ``sol_``)."""

    ROLES = uses("sol_")

    def __init__(self, branch, cells_per_unit=160, window=0.1, count=Q_REPORT):
        check_instance("branch", branch, Branch, "a Branch (Branch.load(path), hz.compute_branch)")
        window = check_real("window", window, "the half-width of the window around xi = pi", 0.0, math.pi,
                            hi_open=False)
        count = check_integer("count", count, 1, "the smallest q reported")
        self.branch, self.n, self.window = branch, cells_per_unit, window
        self.params = SolitaryParameters(branch.alpha, cells_per_unit)
        self.order = sorted(branch.points, key=lambda p: p.q)[:count]
        self.smallest = self.order[0]
        configure(self.ROLES, PETSc.COMM_SELF)

    @functools.cached_property
    def wave(self):
        return solve_solitary_wave(self.params, PETSc.COMM_SELF)

    @functools.cached_property
    def rows(self):
        return [compare_with_branch(self.wave, p, self.window) for p in self.order]

    def table(self):
        b, w = self.branch, self.wave
        lines = [f"alpha = {b.alpha}, branch h = pi/{b.cells_per_pi}; k_alpha = {w.k_alpha:.7f} (solitary wave, "
                 f"delta = 1/{self.n}, L = {w.params.half_length:g}). Errors relative to k_alpha; window "
                 f"|xi - pi| <= {self.window}.\n",
                 "| q | composite, max over the period | composite, max in the window | inner solution, max in the "
                 "window | \\|u\\|_inf q^(2/(alpha-1)) | minus k_alpha |", "|---|---|---|---|---|---|"]
        for r in self.rows:
            lines.append(f"| {r.q:.4f} | {r.max_error:.4f} | {r.window_error:.4f} | {r.inner_window_error:.4f} "
                         f"| {r.rescaled_norm:.5f} | {r.rescaled_norm - w.k_alpha:+.5f} |")
        return "\n".join(lines) + "\n"
