"""The solitary wave of unit velocity and k_alpha (appendix): convergence in the grid step and the domain."""
from petsc4py import PETSc

from ..errors import ParameterError, check_integers, check_real, check_reals
from ..richardson import richardson
from ..roles import configure, uses
from ..solitary import SolitaryParameters, max_bead_velocity, solve_solitary_wave


def k_alpha_extrapolated(alpha, cells=(80, 160, 320), half_length=None):
    """(k_alpha extrapolated in the grid step (Richardson with the observed order) from three solves on one rank,
    the L used: ``half_length``, or chosen on the first grid when None)."""
    first = solve_solitary_wave(SolitaryParameters(alpha, cells[0], half_length), PETSc.COMM_SELF)
    L = first.params.half_length
    ks = [first.k_alpha] + [solve_solitary_wave(SolitaryParameters(alpha, n, L), PETSc.COMM_SELF).k_alpha
                            for n in cells[1:]]
    return richardson(ks)[1], L


def unit_wave_velocity(alpha=1.5, cells=(80, 160, 320), half_length=None):
    """(v1, observed order, L): the maximal bead velocity of the unit-speed solitary wave
    (:func:`~hertzpetsc.solitary.max_bead_velocity`) extrapolated in the grid step (Richardson with the observed
    order) from three solves on one rank; the SI speed of a solitary wave (:meth:`hertzpetsc.units.BeadChain.
    solitary_speed`) scales from it."""
    first = solve_solitary_wave(SolitaryParameters(alpha, cells[0], half_length), PETSc.COMM_SELF)
    L = first.params.half_length
    vs = [max_bead_velocity(first)] + [max_bead_velocity(solve_solitary_wave(SolitaryParameters(alpha, n, L),
                                                                             PETSc.COMM_SELF)) for n in cells[1:]]
    order, v1 = richardson(vs)
    return v1, order, L


class SolitaryStudy:
    """For each alpha: k_alpha (eq. kal2) on grids 1/n, n in ``cells`` (at least 3, all different), on [-L, L],
    L = ``half_length``, the observed order and the Richardson value (delta^2); and k_alpha for L in ``lengths`` at
    the finest n."""

    ROLES = uses("sol_")

    def __init__(self, alphas, cells, lengths, comm, half_length=8.0):
        alphas = check_reals("alphas", alphas, "Hertz exponents", 1.0, distinct=True)
        cells = sorted(check_integers("cells", cells, 2, "grids n (delta = 1/n, even)"))
        lengths = check_reals("lengths", lengths, "half-lengths L", 3.0, lo_open=False, distinct=True, empty=True)
        half_length = check_real("half_length", half_length, "the half-length L", 3.0, lo_open=False)
        if len(cells) < 3 or len(set(cells)) != len(cells):
            raise ParameterError("-cells", cells, "needs at least three different grids for an observed order")
        for n in cells:
            SolitaryParameters(1.5, n)                 # validates n before any solve
        SolitaryParameters(1.5, cells[0], half_length)          # validates L
        self.alphas, self.cells, self.lengths, self.comm = list(alphas), cells, sorted(lengths), comm
        self.half_length = float(half_length)
        self.results = {}
        self.finest = {}
        configure(self.ROLES, comm)

    def run(self):
        """Solve for every alpha; yields alpha after each."""
        for alpha in self.alphas:
            waves = [solve_solitary_wave(SolitaryParameters(alpha, n, self.half_length), self.comm) for n in self.cells]
            # the domain study accepts any tail (tail_tolerance 1) and reports it
            lengths = [solve_solitary_wave(SolitaryParameters(alpha, self.cells[-1], L, tail_tolerance=1.0),
                                           self.comm) for L in self.lengths]
            self.results[alpha] = ([w.k_alpha for w in waves], lengths)
            self.finest[alpha] = waves[-1]
            yield alpha

    def section(self, alpha):
        ks, wl = self.results[alpha]
        order, extrap = richardson(ks, order=2, steps=[1.0 / n for n in self.cells])      # any ratios of the grids
        cells, lengths = self.cells, self.lengths
        return [f"\n### alpha = {alpha}\n", "| n (delta = 1/n) | " + " | ".join(str(n) for n in cells)
                + " | observed order | extrapolated |", "|---|" + "---|" * (len(cells) + 2),
                f"| k_alpha (L = {self.half_length:g}) | " + " | ".join(f"{k:.8f}" for k in ks) + f" | {order:.2f} | {extrap:.7f} |",
                "", "| L | " + " | ".join(f"{L:g}" for L in lengths) + " |", "|---|" + "---|" * len(lengths),
                f"| k_alpha (n = {cells[-1]}) | " + " | ".join(f"{w.k_alpha:.10f}" for w in wl) + " |",
                "| max \\|r\\| at \\|s\\| >= L-1, relative | " + " | ".join(f"{w.tail:.1e}" for w in wl) + " |"]

    def table(self):
        lines = ["k_alpha = -sum_k r(k + 1/2) (eq. kal2) of the unit-velocity solitary wave of eq. adr, grid step "
                 "delta = 1/n on [-L, L]; order from the three finest grids; extrapolated = Richardson (delta^2).\n"]
        for alpha in self.results:                   # those done, in the order of alphas
            lines += self.section(alpha)
        return "\n".join(lines) + "\n"
