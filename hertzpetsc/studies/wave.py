"""A wave of a chain of one's own choosing and its stability: for a lattice model (Hertz exponent, precompression,
mass pattern), wavenumbers q and an amplitude A = max |u|, the travelling wave (eq. ad for the pattern, A a border
row), put on a periodic chain of N beads, refined by Gauss-Newton on its cell (section 3.4) and its Floquet
multipliers modulo shift from the Bloch sectors of its cell (section 3.5), on N beads and on longer chains L N.

Record file ``hertzpetsc-wave-1`` (npz, one record per q, -resume continues), its columns declared once in
:data:`WAVE_KIND`: the model's description (the file's model is ``LatticeModel.from_description`` of it), the
rows' numbers and the objects they are about (the wave's profiles, the refined state, the dominant multipliers; NaN
in files written before those).
"""
from __future__ import annotations

import math
import time
from dataclasses import MISSING, dataclass
from typing import TYPE_CHECKING, Iterator, Optional

import numpy as np

from ..advdelay import check_branch
from ..bloch import SymmetricFloquet
from ..errors import Checked, ConvergenceError, ParameterError, check_instance, param
from ..families import FamilyFold, check_amplitude, check_family_amplitude, wave_of_amplitude
from ..floquet import TOL_RHO
from ..grid import ProfileGrid, cells_per_pi_param
from ..model import ChainSpec, LatticeModel
from ..records import Column, Kind
from ..resources import check_memory
from ..roles import uses
from ..shooting import Refiner
from ..stencil import full_period
from ..twsolver import tw_solver
from ..waves import check_chain_wavenumber, orbit_on_chain
from .base import Study
from .precompression import _check_qs

if TYPE_CHECKING:
    from petsc4py import PETSc

WAVE_FORMAT = "hertzpetsc-wave-1"
DOMINANT = 8                 # the nontrivial multipliers of largest modulus kept per wave
# moduli equal to this relative resolution rank as equal (a stable wave's are all 1 to round-off), ordered then by
# their argument: the kept set does not follow the run's round-off (ranks, a resumed run)
DOMINANT_RESOLUTION = 1e-8


def dominant_multipliers(mu):
    """The :data:`DOMINANT` multipliers of largest modulus among ``mu``, moduli ranked to
    :data:`DOMINANT_RESOLUTION` and equal ones ordered by argument (rounded likewise)."""
    mu = np.asarray(mu, dtype=complex)
    key = np.lexsort((np.round(np.angle(mu) / DOMINANT_RESOLUTION), -np.round(np.abs(mu) / DOMINANT_RESOLUTION)))
    return mu[key][:DOMINANT]
WAVE_KIND = Kind(WAVE_FORMAT, (
    Column("alpha", "Hertz exponent (absent for another law)", constant=True, optional=True),
    Column("delta0", "precompression (absent when 0)", constant=True, optional=True),
    Column("law", "a chain of another law than Hertz's (API only): its name (`toda`, `fpu`, ...), its parameters "
           "(`k`, `b`, ...) beside it instead of `alpha`, `delta0`; `LatticeModel.from_description` of the constants "
           "is the file's model (a file without `law` is Hertz's)", "", str, "s", constant=True, optional=True),
    Column("masses", "the mass pattern", shape="p", constant=True),
    Column("branch", "`optical` for the waves of a pattern's optical family (`-branch optical`); absent for the "
           "acoustic ones", "", str, "s", constant=True, optional=True),
    Column("A", "amplitude max \\|u\\|", constant=True),
    Column("cells_per_pi", "grid h = pi / cells_per_pi", "count", np.int64, "d", constant=True),
    Column("N", "beads of the refinement's chain", "count", np.int64, "d", constant=True),
    Column("sizes", "the longer chains of the Bloch spectra", "count", np.int64, "d", "s", constant=True),
    Column("tol", "the refinement's target E", constant=True),
    Column("tol_rho", "unstable when rho - 1 > tol_rho", constant=True),
    Column("solver_options", "number-changing options under the study's prefixes", "", str, "s", constant=True),
    Column("xi", "the grid of the profiles `u`: j h on [0, 2 pi) (absent from files written before `u`)",
           shape="2K", constant=True, optional=True),
    Column("q", "per-bead wavenumber", format=".6f"),
    Column("m", "wavelengths on N beads", "count", np.int64, "d"),
    Column("omega", "frequency of the refined wave", format=".8f"),
    Column("E_profile", "E(q) of the wave interpolated from the grid", format=".1e"),
    Column("E_refined", "E(q) of the refined wave", format=".1e"),
    Column("iterations", "Gauss-Newton iterations", "count", np.int64, "d"),
    Column("rho", "largest nontrivial multiplier modulus", format=".8f"),
    Column("outside", "multipliers with \\|mu\\| > 1 + tol_rho", "count", np.int64, "d"),
    Column("spread", "the trivial multipliers' spread from 1", format=".1e"),
    Column("unstable", "the verdict: 1 if rho - 1 > tol_rho", "", np.int64, "d"),
    Column("rho_sizes", "rho on each longer chain, in the order of `sizes`", shape="s", format=".8f"),
    Column("seconds", "wall time", "s", format=".1f"),
    Column("E_floor", "where `E_refined` > `tol`: the refinement flow's own error at the refined state, within which "
           "the refinement was accepted at that flow's floor; NaN elsewhere (and in files written before this field)",
           format=".0e", optional=True),
    Column("u", "the wave's profiles u_c(xi), bead n on profile n mod p (xi = q n - omega t), on the whole period: "
           "the solution of eq. ad the row is about (NaN in files written before it)", shape="p, 2K", optional=True),
    Column("state", "the refined initial state (x_n, x_n') of the N beads (eq. twper; NaN in files written before "
           "it)", shape="N, 2", optional=True),
    Column("dominant", f"the {DOMINANT} nontrivial multipliers modulo shift of largest modulus (Bloch sectors; "
           "\\|dominant[0]\\| = rho to 1e-8, moduli equal to 1e-8 ordered by argument; NaN past the spectrum's end and in "
           "files written before it)", "1", complex,
           shape=str(DOMINANT), optional=True),
))
WAVE_FIELDS = WAVE_KIND.fields
MAX_BEADS = 2000             # the refinement's dense Jacobian has (2 M)^2 entries on the wave's cell
MAX_SIZE = 10 ** 6           # beads of the longer chains (Bloch sectors: the cell's cost times the sectors)


@dataclass(frozen=True)
class WaveParameters(Checked):
    """The chain (``model``), wavenumbers ``q`` (per bead; one number or a sequence), amplitude A = max |u| (with
    delta0 = 0 and one mass: any A, the waves scale), grid h = pi / cells_per_pi, N beads of the periodic chain (a
    whole number of wavelengths and of pattern cells), longer chains ``sizes`` (multiples of N), the refinement's
    target E ``tol``, the verdict's threshold ``tol_rho`` and the ``branch`` of a mass pattern (the linear wave
    its family starts from: 'acoustic', the lowest frequency, or 'optical', the highest)."""

    model: LatticeModel
    q: tuple = param(MISSING, "per-bead wavenumbers (q N / (2 pi) whole)", "reals", lo=0.0, hi=math.pi,
                     hi_open=False, distinct=True, expr=True)
    A: float = param(1.0, "the amplitude max |u| (delta0 > 0: at least delta0 max(sqrt(eps), eps^(1/(2(alpha-1)))))",
                     lo=0.0)
    cells_per_pi: int = cells_per_pi_param(400)
    N: int = param(100, "beads of the periodic chain of the refinement", lo=2, hi=MAX_BEADS)
    sizes: tuple = param((), "longer chains for the Bloch spectra (multiples of N; none if empty)", "integers", lo=3,
                         hi=MAX_SIZE, distinct=True, count=0)
    tol: float = param(1e-10, "the refinement's target E (at least the flow's -shoot_ts_rtol, 1e-14)", lo=0.0, hi=1.0)
    tol_rho: float = param(TOL_RHO, "the verdict's threshold: unstable when rho - 1 > tol_rho", lo=0.0, hi=1.0)
    branch: str = param("acoustic", "the linear wave the family starts from (a mass pattern: the lowest frequency "
                        "at q, or the highest)", choices=("acoustic", "optical"))

    def __post_init__(self):
        m = check_instance("model", self.model, LatticeModel, "a LatticeModel (LatticeModel.hertz(1.5, delta0=1))")
        super().__post_init__()
        m.require_conservative("a travelling wave")
        linear = m.law.linear_stiffness > 0              # the waves start from the linear wave (else: scale-invariant)
        if not linear and m.cell > 1:
            raise ParameterError("delta0", 0.0, "a mass pattern's waves start from the linear wave: give a "
                                 "precompression > 0 (the sonic-vacuum dimer: dimer_branch.py from epsilon = 1)")
        object.__setattr__(self, "A", check_family_amplitude(m, self.A, "A") if linear else
                           check_amplitude(self.A, "A"))
        if self.N % m.cell:
            raise ParameterError("N", self.N, f"must be a multiple of the mass pattern's length {m.cell} in "
                                 f"[2, {MAX_BEADS}]")
        for q in _check_qs(self.q, math.pi / self.cells_per_pi):
            check_chain_wavenumber(q, self.N)
            check_branch(m, q, self.branch)
        for L in self.sizes:
            if not (L > self.N and L % self.N == 0):
                raise ParameterError("sizes", L, f"each longer chain must be a multiple of N = {self.N} beads, at "
                                     f"most {MAX_SIZE}")


class WaveStudy(Study):
    """The wave, its refinement and its multipliers at each q (module docstring). Collective over ``comm``."""

    Parameters = WaveParameters
    FORMAT, FIELDS, DTYPES, COLUMNS = WAVE_FORMAT, WAVE_FIELDS, WAVE_KIND.dtypes, WAVE_KIND
    LABELS = ("xi",)           # the profiles' grid: set by cells_per_pi
    ROLES = uses("precomp_", "tw_", "shoot_", "shoot_jac_", floquet_=("ts",))
    WHAT, ADDED = "wave file", {"E_floor": math.nan}

    def __init__(self, params: WaveParameters, comm: Optional[PETSc.Comm] = None, output: Optional[str] = None,
                 mode: str = "new") -> None:
        super().__init__(params, comm, output, mode)
        # before the file's arrays of the profiles' size are made (10^9 cells: 16 GB of NaN before the refusal)
        check_memory(params.cells_per_pi, self.comm, tw_solver("precomp_"), profiles=params.model.cell)
        K2, p = 2 * params.cells_per_pi, params.model.cell
        self.SHAPES = {"rho_sizes": (len(params.sizes),), "u": (p, K2), "state": (params.N, 2),
                       "dominant": (DOMINANT,)}
        # a file written before the profiles, states and multipliers resumes with NaN in their place
        self.ADDED = dict(self.ADDED, **{k: np.full(self.SHAPES[k], math.nan, dtype=complex if k == "dominant" else
                                                    float) for k in ("u", "state", "dominant")})

    def configure(self) -> None:
        """The solver roles' options, and the refiner's (-shoot_gn_max_it, tol against the flow's rtol), now."""
        super().configure()
        with Refiner(ChainSpec(self.params.model, self.params.N), self.comm, self.params.tol):
            pass

    def constants(self) -> dict:
        p = self.params
        return dict(p.model.describe(), A=p.A, cells_per_pi=p.cells_per_pi, N=p.N, sizes=list(p.sizes), tol=p.tol,
                    tol_rho=p.tol_rho, **({} if p.branch == "acoustic" else dict(branch=p.branch)),
                    xi=np.arange(2 * p.cells_per_pi) * math.pi / p.cells_per_pi)

    def compute(self, q: float) -> dict:
        """The wave at q (:func:`~hertzpetsc.families.wave_of_amplitude`) refined on N beads, its spectra."""
        p = self.params
        t0 = time.perf_counter()
        point, scale = wave_of_amplitude(p.model, q, p.A, ProfileGrid(p.cells_per_pi, self.comm), branch=p.branch)
        spec = ChainSpec(p.model, p.N)
        orbit = orbit_on_chain(point, spec, scale=scale)
        with Refiner(spec, self.comm, p.tol) as refiner:
            E0 = refiner.residual(orbit)
            refined = refiner.refine(orbit)
        with SymmetricFloquet(p.model, self.comm) as floquet:
            s = floquet.spectrum(refined.orbit, p.tol_rho)
            longer = [floquet.spectrum(refined.orbit.tiled(L // p.N), p.tol_rho).rho for L in p.sizes]
        K2 = 2 * p.cells_per_pi
        u = np.array([scale * (np.asarray(w) if len(w) == K2 else full_period(w)) for w in point.profiles])
        nontrivial = dominant_multipliers(np.delete(s.multipliers, s.trivial))
        dominant = np.full(DOMINANT, math.nan, dtype=complex)
        dominant[:len(nontrivial)] = nontrivial
        return dict(q=q, m=orbit.m, omega=refined.orbit.omega, E_profile=E0, E_refined=refined.E,
                    E_floor=refined.E_floor, iterations=refined.iterations, rho=s.rho, outside=s.outside,
                    spread=s.trivial_spread, unstable=int(s.rho - 1 > p.tol_rho),
                    rho_sizes=np.array(longer, dtype=float),
                    seconds=time.perf_counter() - t0, u=u, state=refined.orbit.x, dominant=dominant)

    def run(self) -> Iterator[dict]:
        """The records of the q not yet in the file; a q whose wave or refinement does not converge is left out
        (its error kept in ``failed``, by q, for the table and the driver's exit status) and the next q goes on."""
        self.failed = {}
        for q in self.open()._todo(self.params.q):
            try:
                record = self.compute(q)
            except ConvergenceError as err:
                self.failed[q] = err
                continue
            yield self.store.append(record)

    def table(self) -> str:
        p = self.params
        optical = ", the optical branch" if p.branch == "optical" else ""
        lines = [f"schema: {WAVE_FORMAT}; chain {p.model.describe()}{optical}, amplitude A = max |u| = {p.A:g}, h = pi/"
                 f"{p.cells_per_pi}; refined on N = {p.N} beads (target E {p.tol:g}); multipliers modulo shift from "
                 f"the Bloch sectors of the wave's cell; unstable when rho - 1 > {p.tol_rho:g}.\n",
                 "| " + " | ".join(["q", "m", "omega", "E (profile)", "E (refined)", "rho - 1", "outside",
                                    "trivial spread", "verdict"] + [f"rho - 1 on {L}" for L in p.sizes]) + " |",
                 "|---" * (9 + len(p.sizes)) + "|"]
        for r in self.store.records:
            extra = "".join(f" {float(v) - 1:.2e} |" for v in np.atleast_1d(r["rho_sizes"]))
            # above the target: accepted within the refinement flow's own error (hertzpetsc.shooting)
            floor = "" if math.isnan(float(r["E_floor"])) else f" (flow's floor {float(r['E_floor']):.0e})"
            lines.append(WAVE_KIND.row(r, "{q}", "{m}", "{omega}", "{E_profile}", "{E_refined}" + floor,
                                       f"{r['rho'] - 1:.2e}", "{outside}", "{spread}",
                                       "unstable" if int(r["unstable"]) else f"stable within {p.tol_rho:g}") + extra)
        lines += [f"\nNot computed{'' if isinstance(err, FamilyFold) else ' (-resume retries it)'}: q = {q:.6f}: "
                  f"{err}" for q, err in sorted(getattr(self, "failed", {}).items())]
        return "\n".join(lines) + "\n"
