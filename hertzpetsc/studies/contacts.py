"""Studies of dissipation in the contacts (issue 38, item 2; :mod:`hertzpetsc.dissipation`): the coefficient of
restitution of a two-bead impact against the impact velocity, and a pulse launched into a long chain.

:class:`Restitution` (record kind ``hertzpetsc-restitution-1``, one record per impact velocity v): two free beads of
masses m1, m2 touching at rest overlap 0, bead 1 at velocity v towards bead 2; the flow (prefix ``chain_``) until
the contact opens (free flight after it); e = (v2 - v1)_after / v (columns: :data:`RESTITUTION_KIND`). The table
fits the law over the smallest velocities: Hunt-Crossley's coefficient (1 - e)/v -> c, Kuwabara-Kono's exponent of
1 - e ~ v^p -> (alpha - 1)/(alpha + 1) (1/5 for Hertz) and its constant.

:class:`PulseDecay` (record kind ``hertzpetsc-pulse-1``, one record per striker velocity v0): an uncompressed chain of
N beads at rest, free ends, bead 0 launched at v0; ``amplitude`` (N values) is the largest velocity of each bead
(the leading pulse; sampled every ``sample`` time units, the peak interpolated by a parabola through the three
samples around it). The adiabatic decay of a solitary wave of speed amplitude A whose energy (~ A^2) is lost bond
by bond (loss per bond from the wave's scaling x -> a x, t -> a^(-(alpha-1)/2) t) is A^p linear in n:
p = -1 for Hunt-Crossley, (1 - alpha)/(alpha + 1) (-1/5) for Kuwabara-Kono (columns: :data:`PULSE_KIND`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Iterator

import numpy as np
from petsc4py import PETSc

from ..chain import Chain, ChainIntegrator, IntegrationTolerances
from ..continuation import golden_maximum
from ..dealing import dealt
from ..dissipation import KINDS, contact_dissipation, hunt_crossley_restitution, kuwabara_kono_restitution
from ..errors import Checked, ConvergenceError, ParameterError, check_integer, check_real, param
from ..model import ChainSpec, Damping, LatticeModel
from ..records import Column, Kind
from ..resources import check_chain_size
from ..roles import uses
from .base import Study

RESTITUTION_FORMAT = "hertzpetsc-restitution-1"
PULSE_FORMAT = "hertzpetsc-pulse-1"
_DISSIPATION = (
    Column("contact", '`"hunt-crossley"` or `"kuwabara-kono"`', "", str, "s", constant=True),
    Column("damping", "Hunt-Crossley's c or Kuwabara-Kono's eta", constant=True),
    Column("clipped", "True: a contact never pulls", "", bool, constant=True),
    Column("alpha", "Hertz exponent", constant=True))
_OPTIONS = Column("solver_options", "the options given under `-chain_` that change numbers", "", str, "s",
                  constant=True)
RESTITUTION_KIND = Kind(RESTITUTION_FORMAT, _DISSIPATION + (
    Column("velocities", "the impact velocities asked for", shape="K", constant=True),
    Column("masses", "the two beads' masses", shape="2", constant=True),
    Column("rtol", "flow tolerance (the refinement at 100 rtol)", constant=True),
    _OPTIONS,
    Column("v", "impact velocity (relative)", format=".4g"),
    Column("e", "coefficient of restitution at rtol", format=".12f"),
    Column("e_coarse", "coefficient of restitution at 100 rtol", format=".12f"),
    Column("law", "1 - e of the small-dissipation law (c v; C eta v^((alpha-1)/(alpha+1)))", format=".6e"),
    Column("steps", "the flow's steps (at rtol and 100 rtol together)", "count", np.int64, "d")))
PULSE_KIND = Kind(PULSE_FORMAT, _DISSIPATION + (
    Column("velocities", "the striker velocities asked for", shape="K", constant=True),
    Column("N", "beads", "count", np.int64, "d", constant=True),
    Column("skip", "beads left out of the fit at each end", "count", np.int64, "d", constant=True),
    Column("sample", "sampling interval of the velocities", constant=True),
    Column("rtol", "flow tolerance", constant=True),
    _OPTIONS,
    Column("v0", "striker velocity (bead 0)", format="g"),
    Column("amplitude", "largest velocity of each bead (parabolic peak of the samples)", shape="N", format=".6f"),
    Column("p_fit", "the exponent p whose A^p is most nearly linear in n over the fitted beads", format=".4f"),
    Column("slope", "d(A^p)/dn per unit damping at the law's p (-1 Hunt-Crossley, (1-alpha)/(1+alpha) "
           "Kuwabara-Kono)", format=".6g"),
    Column("misfit", "RMS deviation of A^p from its line over its range, at the law's p", format=".1e"),
    Column("steps", "the flow's steps", "count", np.int64, "d")))
ROLES = uses("chain_")
# an impact is followed in steps of its undamped duration over this, until the contact opens
IMPACT_CHUNKS = 64
MAX_IMPACT_DURATIONS = 1000


UNCLIPPED = "let a contact pull (no clipping of the contact force at 0)"


def _contact(kind, damping, clipped):
    if kind not in KINDS:
        raise ParameterError("contact", kind, "must be one of " + ", ".join(KINDS))
    return contact_dissipation(kind, check_real("damping", damping, "the contact damping (c or eta)", 0.0), clipped)


def impact_duration(v, alpha=1.5, mass=0.5):
    """The undamped Hertz impact's duration at relative velocity v (reduced mass ``mass``, K = 1):
    2 d_max / v B(1/(alpha + 1), 1/2) / (alpha + 1), d_max = ((alpha + 1) m v^2 / 2)^(1/(alpha + 1))."""
    a = alpha + 1.0
    dmax = (a * mass * v * v / 2.0) ** (1.0 / a)
    beta = math.gamma(1.0 / a) * math.gamma(0.5) / math.gamma(1.0 / a + 0.5)
    return 2.0 * dmax / v * beta / a


def restitution(model, v, rtol, comm=PETSc.COMM_SELF, prefix="chain_"):
    """(e, steps) of the impact of two free beads of ``model`` (bead 1 at v towards bead 2 at rest, in contact at
    overlap 0): the flow until the contact opens, e = (v2 - v1) / v after it."""
    m = model.mass(np.arange(2))
    spec = ChainSpec(model, 2, "free")
    chain = Chain(spec, comm)
    integ = ChainIntegrator(chain, IntegrationTolerances(rtol, rtol * 1e-2 * v), prefix)
    X = chain.create_state()
    try:
        chain.set_from_array(X, np.array([[0.0, v], [0.0, 0.0]]))
        dt = impact_duration(v, model.alpha, m[0] * m[1] / (m[0] + m[1])) / IMPACT_CHUNKS
        t = 0.0
        for _ in range(IMPACT_CHUNKS * MAX_IMPACT_DURATIONS):
            integ.integrate(X, t, t + dt, dt=integ.initial_step if t == 0.0 else None)
            t += dt
            s = chain.gather(X)
            if s[1, 0] - s[0, 0] > 0.0:                  # the contact opened: free flight from here on
                return float((s[1, 1] - s[0, 1]) / v), integ.steps
        raise ConvergenceError("restitution", f"the contact did not open within {MAX_IMPACT_DURATIONS} impact "
                               "durations", v=v)
    finally:
        X.destroy()
        integ.destroy()
        chain.destroy()


@dataclass(frozen=True)
class RestitutionParameters(Checked):
    """Impacts of two beads (masses ``masses``) with contact dissipation ``contact`` ('hunt-crossley': c =
    ``damping``; 'kuwabara-kono': eta = ``damping``), ``clipped`` or not, Hertz exponent ``alpha``, at the impact
    velocities ``velocities``; flows at ``rtol`` and 100 rtol."""

    contact: str = param("hunt-crossley", "the contact dissipation", choices=tuple(KINDS))
    damping: float = param(0.1, "the contact damping (Hunt-Crossley c or Kuwabara-Kono eta)", lo=0.0)
    velocities: tuple = param((1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0), "impact velocities", lo=0.0, distinct=True)
    clipped: bool = param(True, "clip the contact force at 0", option="unclipped", help=UNCLIPPED)
    alpha: float = param(1.5, "the Hertz exponent", lo=1.0)
    masses: tuple = param((1.0, 1.0), "two bead masses", lo=0.0, count=2)
    rtol: float = param(1e-11, "the flow tolerance (also 100 rtol: the refinement)", lo=0.0, hi=1e-4)

    def __post_init__(self):
        super().__post_init__()
        if len(self.masses) != 2:
            raise ParameterError("masses", self.masses, "must be the two beads' masses")

    @property
    def model(self) -> LatticeModel:
        return replace(LatticeModel.hertz(self.alpha, self.masses),
                       damping=Damping(contact=_contact(self.contact, self.damping, self.clipped)))

    def law(self, v):
        """1 - e of the small-dissipation law at v."""
        if self.contact == "hunt-crossley":
            return hunt_crossley_restitution(self.damping, v)
        m1, m2 = self.masses
        return kuwabara_kono_restitution(self.damping, v, m1 * m2 / (m1 + m2), self.alpha)


class Restitution(Study):
    """The coefficient of restitution against the impact velocity (module docstring)."""

    Parameters = RestitutionParameters
    FORMAT, FIELDS, DTYPES, COLUMNS = RESTITUTION_FORMAT, RESTITUTION_KIND.fields, RESTITUTION_KIND.dtypes, \
        RESTITUTION_KIND
    ROLES = ROLES
    WHAT = "restitution file"

    def __init__(self, params, comm=None, output=None, mode="new"):
        super().__init__(params, comm, output, mode)
        self.configure()

    def planned(self):
        return len(self._todo_v())

    def _todo_v(self):
        done = {round(float(r["v"]), 14) for r in (self.store.records if self.store else [])}
        return [v for v in self.params.velocities if round(v, 14) not in done]

    def compute(self, v):
        p = self.params
        model = p.model
        e, steps = restitution(model, v, p.rtol)
        e_coarse, _ = restitution(model, v, 100 * p.rtol)
        return dict(v=v, e=e, e_coarse=e_coarse, law=p.law(v), steps=steps)

    def run(self) -> Iterator[dict]:
        self.open()
        todo = self._todo_v()
        for _, row in dealt(todo, [1.0 / v ** 0.2 for v in todo], self.comm, self.compute):
            yield self.store.append(row)

    def rows(self):
        return sorted(self.records, key=lambda r: float(r["v"]))

    def fit(self, count=3):
        """The small-dissipation law fitted on the ``count`` smallest velocities: (exponent p of 1 - e ~ v^p by least
        squares in logs, the law's p, ratio of the measured 1 - e to the law's at the smallest v)."""
        rows = self.rows()[:count]
        v = np.array([float(r["v"]) for r in rows])
        loss = np.array([1.0 - float(r["e"]) for r in rows])
        p = self.params
        expected = 1.0 if p.contact == "hunt-crossley" else (p.alpha - 1.0) / (p.alpha + 1.0)
        slope = float(np.polyfit(np.log(v), np.log(loss), 1)[0]) if len(v) > 1 else math.nan
        return slope, expected, float(loss[0] / float(rows[0]["law"]))

    def table(self) -> str:
        p = self.params
        name = {"hunt-crossley": f"Hunt-Crossley c = {p.damping:g}", "kuwabara-kono": f"Kuwabara-Kono eta = "
                f"{p.damping:g}"}[p.contact]
        law = "c v" if p.contact == "hunt-crossley" else \
            "C eta v^((alpha-1)/(alpha+1)), C = 2 d_max^alpha B(alpha/(alpha+1), 3/2) / ((alpha+1) m v)"
        lines = [f"schema: {RESTITUTION_FORMAT}; two beads of masses {list(p.masses)}, Hertz alpha = {p.alpha:g}, "
                 f"{name}, {'clipped (a contact never pulls)' if p.clipped else 'unclipped'}; flows at rtol "
                 f"{p.rtol:.0e} and {100 * p.rtol:.0e} (|de|: the refinement); small-dissipation law 1 - e = {law}",
                 "", "| v | e | abs de | 1 - e | law 1 - e | (1 - e) / law |", "|---|---|---|---|---|---|"]
        for r in self.rows():
            e = float(r["e"])
            lines.append(RESTITUTION_KIND.row(r, "{v}", "{e}", f"{abs(e - r['e_coarse']):.1e}", f"{1 - e:.6e}",
                                              "{law}", f"{(1 - e) / r['law']:.6f}"))
        if len(self.records) >= 2:
            slope, expected, ratio = self.fit()
            lines += ["", f"fit on the three smallest v: 1 - e ~ v^{slope:.4f} (law: v^{expected:.4f}); (1 - e) / law "
                          f"= {ratio:.6f} at v = {float(self.rows()[0]['v']):g}"]
        return "\n".join(lines) + "\n"


# --- the pulse in a long chain ---------------------------------------------------------------------------------------
def decay_exponent(kind, alpha):
    """p of the adiabatic decay law A^p linear in the bead index (module docstring)."""
    return {"hunt-crossley": -1.0, "kuwabara-kono": (1.0 - alpha) / (alpha + 1.0)}[kind]


def line_misfit(n, A, p):
    """(slope, RMS deviation over the range) of the least-squares line of A^p against n (invariant under y -> a y +
    b, so that exponents near 0 are not favoured)."""
    y = A ** p
    coef = np.polyfit(n, y, 1)
    return float(coef[0]), float(np.sqrt(np.mean((np.polyval(coef, n) - y) ** 2)) / np.ptp(y))


def pulse_amplitudes(model, N, v0, rtol, sample, comm, prefix="chain_", last=None):
    """The largest velocity of each bead (the leading pulse) of a free chain of N beads at rest, bead 0 launched at
    v0; sampled every ``sample``, each peak interpolated by the parabola through its three samples; the flow stops
    once bead ``last`` (default N - 1) has peaked."""
    last = N - 1 if last is None else last
    spec = ChainSpec(model, N, "free")
    chain = Chain(spec, comm)
    integ = ChainIntegrator(chain, IntegrationTolerances(rtol, rtol * 1e-2 * v0), prefix)
    X = chain.create_state()
    try:
        x0 = np.zeros((N, 2))
        x0[0, 1] = v0
        chain.set_from_array(X, x0)
        best = np.zeros(N)
        prev2 = prev = None
        t, limit = 0.0, 50.0 * N / v0 ** 0.2 + 100.0
        while t < limit:
            integ.integrate(X, t, t + sample, dt=integ.initial_step if t == 0.0 else None)
            t += sample
            now = chain.gather(X)[:, 1]
            if prev2 is not None:
                peak = (prev >= prev2) & (prev >= now)
                curv = prev2 - 2.0 * prev + now
                safe = np.where(curv < 0.0, curv, -1.0)
                value = np.where(curv < 0.0, prev - (prev2 - now) ** 2 / (8.0 * safe), prev)
                best = np.where(peak & (value > best), value, best)
                if best[last] > 1e-2 * np.max(best) and now[last] < 0.5 * best[last]:
                    return best, integ.steps
            prev2, prev = prev, now
        raise ConvergenceError("pulse", f"bead {last} saw no pulse before t = {limit:g}", v0=v0)
    finally:
        X.destroy()
        integ.destroy()
        chain.destroy()


@dataclass(frozen=True)
class PulseParameters(Checked):
    """A pulse launched at ``velocities`` (one run each) into a free Hertz chain (exponent ``alpha``) of N beads
    with contact dissipation ``contact`` ('hunt-crossley' c, 'kuwabara-kono' eta = ``damping``), ``clipped`` or not;
    the decay fitted over beads ``skip``..N - 1 - ``skip``; peaks sampled every ``sample``; flows at ``rtol``."""

    contact: str = param("hunt-crossley", "the contact dissipation", choices=tuple(KINDS))
    damping: float = param(0.01, "the contact damping (Hunt-Crossley c or Kuwabara-Kono eta)", lo=0.0)
    velocities: tuple = param((1.0, 0.5), "striker velocities v0", lo=0.0, distinct=True)
    N: int = param(200, "the number of beads", lo=10)
    clipped: bool = param(True, "clip the contact force at 0", option="unclipped", help=UNCLIPPED)
    alpha: float = param(1.5, "the Hertz exponent", lo=1.0)
    skip: int = param(20, "the beads left out at each end of the fit", lo=0)
    sample: float = param(0.02, "the sampling interval of the velocities", lo=0.0, hi=1.0)
    rtol: float = param(1e-10, "the flow tolerance", lo=0.0, hi=1e-4)

    def __post_init__(self):
        super().__post_init__()
        check_integer("skip", self.skip, 0, "the beads left out at each end of the fit", (self.N - 6) // 2)

    @property
    def model(self) -> LatticeModel:
        return replace(LatticeModel.hertz(self.alpha),
                       damping=Damping(contact=_contact(self.contact, self.damping, self.clipped)))


class PulseDecay(Study):
    """A pulse's amplitude along a long chain with contact dissipation, and its decay law (module docstring)."""

    Parameters = PulseParameters
    FORMAT, FIELDS, DTYPES, COLUMNS = PULSE_FORMAT, PULSE_KIND.fields, PULSE_KIND.dtypes, PULSE_KIND
    ROLES = ROLES
    WHAT = "pulse file"

    def __init__(self, params, comm=None, output=None, mode="new"):
        super().__init__(params, comm, output, mode)
        check_chain_size(params.N, 1, "N")                 # before any file is opened
        self.SHAPES = {"amplitude": (params.N,)}
        self.configure()

    def planned(self):
        done = {round(float(r["v0"]), 14) for r in (self.store.records if self.store else [])}
        return len([v for v in self.params.velocities if round(v, 14) not in done])

    def fitted(self, A):
        """(p_fit, slope per unit damping at the law's p, misfit at the law's p) of the amplitudes A."""
        p = self.params
        n = np.arange(p.skip, p.N - p.skip)
        a = np.asarray(A)[p.skip:p.N - p.skip]
        law = decay_exponent(p.contact, p.alpha)
        sign = -1.0 if law < 0 else 1.0
        # the exponent whose A^p is most nearly linear: |p| in [0.01, 3], the law's sign
        best = golden_maximum(lambda q: -line_misfit(n, a, sign * q)[1], 0.01, 3.0, 1e-6)[0]
        slope, misfit = line_misfit(n, a, law)
        return sign * best, slope / p.damping, misfit

    def run(self) -> Iterator[dict]:
        self.open()
        p = self.params
        done = {round(float(r["v0"]), 14) for r in self.store.records}
        for v0 in p.velocities:
            if round(v0, 14) in done:
                continue
            A, steps = pulse_amplitudes(p.model, p.N, v0, p.rtol, p.sample, self.comm, last=p.N - 1 - p.skip)
            p_fit, slope, misfit = self.fitted(A)
            yield self.store.append(dict(v0=v0, amplitude=A, p_fit=p_fit, slope=slope, misfit=misfit, steps=steps))

    def table(self) -> str:
        p = self.params
        law = decay_exponent(p.contact, p.alpha)
        what = {"hunt-crossley": "Hunt-Crossley c", "kuwabara-kono": "Kuwabara-Kono eta"}[p.contact]
        marks = [n for n in (p.skip, p.N // 4, p.N // 2, 3 * p.N // 4, p.N - 1 - p.skip)]
        lines = [f"schema: {PULSE_FORMAT}; free Hertz chain alpha = {p.alpha:g}, N = {p.N}, {what} = {p.damping:g}"
                 f"{', clipped' if p.clipped else ', unclipped'}; bead 0 "
                 f"launched at v0; amplitude A_n = largest velocity of bead n (sampled every {p.sample:g}, parabolic "
                 f"peak); flows at rtol {p.rtol:.0e}; decay law A^p linear in n with p = {law:.4f}, fitted over "
                 f"beads {p.skip}..{p.N - 1 - p.skip}", "",
                 "| v0 | " + " | ".join(f"A_{n}" for n in marks) + " | p fitted | d(A^p)/dn / damping | misfit |",
                 "|---|" + "---|" * (len(marks) + 3)]
        for r in sorted(self.records, key=lambda r: -float(r["v0"])):
            lines.append(PULSE_KIND.row(r, "{v0}", *(f"{r['amplitude'][n]:.6f}" for n in marks), "{p_fit}", "{slope}",
                                        "{misfit}"))
        return "\n".join(lines) + "\n"
