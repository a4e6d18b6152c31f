"""The advance-delay problem of periodic travelling waves (eqs. ad, pbc) for any lattice model: residual, Jacobian,
borders, and its continuation parameters.

For a mass pattern m_0 .. m_{p-1} (the paper's chain: p = 1, m = 1) a travelling wave with per-bead wavenumber q is
x_n(t) = u_c(q n - omega t), c = n mod p, with p odd 2 pi-periodic profiles, and eq. ad becomes

    m_c omega^2 u_c'' = V_c'(tau_q u_{c+1} - u_c) - V_{c-1}'(u_c - tau_{-q} u_{c-1}),      c = 0 .. p-1 (cyclic),

V_c the law of bond c (one law for all: the model's; a bond pattern, :attr:`~hertzpetsc.model.LatticeModel.bonds`),
discretised on the grid of :mod:`hertzpetsc.grid` (second differences D2, shift stencils tau_{+-q} of
:class:`ShiftStencils`). For p <= 2 with one law the reflection n -> -n keeps every bead's type and the profiles are
odd (unknowns on (0, pi)); for p >= 3 (or bonds that differ) it exchanges types, the profiles have no symmetry and
are unknown on the whole period, with the chain's two invariances (a constant added to every bead, a translation of
xi) removed by two gauge rows, mean(u_0) = 0 and b1(u_0) = (1/pi) int u_0 cos = 0, bordered by two unknowns
multiplying the constants and the reference translation u' (zero at an exact solution). Two forms of the unknowns:

* **fixed frequency** (``amplitude=None``): the profiles u_c at a given omega (eq. ad: omega = 1); no border. For
  p = 1 this is the paper's problem, on the grid's own Vec layout, with its own assembled/matrix-free Jacobian.
* **fixed amplitude** (``amplitude=a``): u_c = a w_c with the rescaled lattice of the law (u = a w turns V' into
  r -> a^(-d) V'(a r), :meth:`hertzpetsc.model.LatticeModel.rescaled`; Hertz: delta0 / a) and the frequency
  variable lam = omega^2 a^(1-d) as an unknown, bordered by one row: a1(w_c*) = 1 (``measure='a1'``: a is the first
  sine coefficient of the normalised profile c*) or ||w_c*||_inf = 1 (``measure='sup'``: a is the amplitude
  A = max |u|, the quantity the tables print). w and lam stay O(1) from the linear wave to the uncompressed one.

The problem is a :class:`~hertzpetsc.continuation.ContinuationProblem`: ``parameter`` names the continuation
parameter (q, omega, a, log_a, any parameter of the law by name (Hertz: delta0, alpha), or a mass m0, m1, ... ;
``epsilon`` is m1), the last entry of the
extended vector Z = (X, p). With the parameter fixed the SNES works on X alone (the fast path of the q-branch);
otherwise on Z with the continuation layer's row appended (pseudo-arclength). The parameter's column dF/dp is exact
for omega and the masses, a finite difference otherwise. Solvers: :mod:`hertzpetsc.twsolver` (SNES prefix ``tw_``,
direct LU or Newton-Krylov for every p and every border).
"""
from __future__ import annotations

import math
import weakref
from typing import TYPE_CHECKING, Optional, Sequence

import numpy as np
from petsc4py import PETSc

from .assembly import RowAssembler, StencilGather, gathered, merged_csr
from .continuation import ContinuationProblem
from .diagnostics import sup_norm
from .errors import ConvergenceError, ParameterError, is_numpy_bool, check_integer, check_real
from .model import LatticeModel
from .stencil import shift_stencil

if TYPE_CHECKING:
    from .branch import SolveStats
    from .grid import ProfileGrid
    from .twsolver import TravellingWaveSolver

MEASURES = ("a1", "sup")


def check_wavenumber(q, h=None, name="q"):
    """q must lie in (0, pi] (and span at least one grid step h if h is given); ``name`` is used in errors."""
    try:
        if isinstance(q, (str, bytes, bool)) or is_numpy_bool(q):
            raise TypeError(q)                  # float() would take '0.5' and True
        qf = float(q)
    except (TypeError, ValueError):
        raise ParameterError(name, q, f"must be a real number in (0, pi], not {type(q).__name__}") from None
    if not (0.0 < qf <= math.pi * (1 + 1e-14)):
        raise ParameterError(name, q, "the wavenumber must lie in (0, pi]")
    if h is not None and qf < h * (1 - 1e-12):
        raise ParameterError(name, q, f"must be at least one grid step h = {h:.6g} (refine the grid for smaller q)")
    return min(qf, math.pi)


def check_branch(model, q, branch):
    """The linear wave ``branch`` ('acoustic' or 'optical') of ``model`` at per-bead wavenumber q must exist: a
    monatomic chain has the acoustic one only, and the acoustic wave of a pattern of p beads has zero frequency at
    q = 2 pi k / p (its cells move as one)."""
    if branch not in ("acoustic", "optical"):
        raise ParameterError("branch", branch, "must be 'acoustic' or 'optical'")
    p = model.cell
    if branch == "optical" and p == 1:
        raise ParameterError("branch", branch, "a monatomic chain has the acoustic branch only")
    cells = p * q / (2 * math.pi)
    if branch == "acoustic" and abs(cells - round(cells)) < 1e-12 * p:
        raise ParameterError("q", q, f"the acoustic wave of a pattern of {p} beads has zero frequency at "
                             f"q = 2 pi k / {p} (its cells move as one): choose another q, or the optical branch")


# --- the shift stencils -------------------------------------------------------------------------------------------
class ShiftStencils(StencilGather):
    """D2, tau_q and tau_{-q} on a :class:`~hertzpetsc.grid.ProfileGrid` at one wavenumber q.

    The three linear maps are stacked into one AIJ matrix T (3 rows per unknown, built once per q), so that one
    MatMult (one scatter, compiled code) gives D2 u, tau_q u and tau_{-q} u. One rank: T acts on the grid's Vec
    layout. Several ranks: T is a rank-local SeqAIJ block acting on the values gathered by one VecScatter (the
    stencils' ``needed`` set): one set of per-row arrays instead of MPIAIJ's diagonal and off-diagonal blocks,
    which doubled the memory per rank. ``cols``/``coef`` (global unknown columns and weights times folding
    signs, per stencil) serve the assembled Jacobians.
    """

    def __init__(self, grid, q):
        self.q = check_wavenumber(q, grid.h)
        self.sigma = self.q / grid.h
        self.parallel = grid.comm.getSize() > 1
        super().__init__(grid, {"d2": (np.array([-1, 0, 1]), np.array([1.0, -2.0, 1.0]) / grid.h ** 2),
                                "plus": shift_stencil(self.sigma), "minus": shift_stencil(-self.sigma)},
                         scatter=self.parallel)
        key = self.pos if self.parallel else self.cols
        parts = [_d2_csr(grid, self) if k == "d2" and not self.parallel else merged_csr(key[k], self.coef[k])
                 for k in ("d2", "plus", "minus")]
        self.pos = {}                     # positions are folded into T's columns
        self.nloc = nloc = grid.rend - grid.rstart
        offsets = np.cumsum([0] + [p[0][-1] for p in parts])
        indptr = np.concatenate([parts[0][0]] + [p[0][1:] + offsets[i] for i, p in enumerate(parts) if i > 0])
        csr = (indptr.astype(PETSc.IntType), np.concatenate([p[1] for p in parts]),
               np.concatenate([p[2] for p in parts]))
        del parts, indptr
        # the arrays are used in place (petsc4py keeps them alive)
        if self.parallel:
            self.T = PETSc.Mat().createAIJWithArrays((3 * nloc, len(self.needed)), csr, comm=PETSc.COMM_SELF)
        else:
            self.T = PETSc.Mat().createAIJWithArrays(((3 * nloc, 3 * grid.size), (nloc, grid.size)), csr,
                                                     comm=grid.comm)
        self.T.assemble()
        self.w = self.T.createVecLeft()

    def stacked(self, X):
        """w = T X = (D2 X, tau_q X, tau_{-q} X) on the owned rows (one scatter and one MatMult)."""
        if self.parallel:
            self.gather(X)
        self.T.mult(self.local if self.parallel else X, self.w)
        return self.w

    def destroy(self):
        super().destroy()
        self.T.destroy()
        self.w.destroy()


_D2_CACHE = weakref.WeakKeyDictionary()


def _d2_csr(grid, stencils):
    """CSR rows of the second difference on ``grid`` (independent of q: built once per grid)."""
    csr = _D2_CACHE.get(grid)
    if csr is None:
        csr = _D2_CACHE[grid] = merged_csr(stencils.cols["d2"], stencils.coef["d2"])
    return csr


def profile_sup(values, periodic=False):
    """max |u| of a profile's grid values, refined by the parabola through the largest and its neighbours
    (:func:`~hertzpetsc.diagnostics.sup_norm`; ``periodic``: the values are a whole period, neighbours wrap)."""
    if not periodic:
        return sup_norm(values)
    u = np.abs(np.asarray(values, dtype=float))
    j = int(np.argmax(u))
    return sup_norm(u[[(j - 1) % len(u), j, (j + 1) % len(u)]])


def _sup_gradient(u, periodic):
    """(indices j-1, j, j+1 of the maximiser of |u|, d max / d u there) of :func:`profile_sup`."""
    v = np.abs(u)
    j = int(np.argmax(v))
    idx = np.array([j - 1, j, j + 1]) % len(u) if periodic else np.array([j - 1, j, j + 1])
    a, b, c = v[idx]
    curv = a - 2 * b + c
    if not curv < 0:
        return idx[1:2], np.sign(u[idx[1:2]])
    # s = b - (a - c)^2 / (8 curv), curv = a - 2b + c: its partial derivatives in a, b, c
    da = -(2 * (a - c) * curv - (a - c) ** 2) / (8 * curv ** 2)
    db = 1.0 - (a - c) ** 2 / (4 * curv ** 2)
    dc = (2 * (a - c) * curv + (a - c) ** 2) / (8 * curv ** 2)
    return idx, np.sign(u[idx]) * np.array([da, db, dc])


def _on_contact(model, f, x):
    """f(x) on the bonds the law (or the model of one law) says may be in contact, 0 elsewhere (V' and V'' of the uncompressed law vanish
    off contact and few bonds are in contact)."""
    m = model.contact(x)
    if m.all():
        return f(x)
    out = np.zeros_like(x)
    out[m] = f(x[m])
    return out


# --- the problem --------------------------------------------------------------------------------------------------
class AdvanceDelayProblem(ContinuationProblem):
    """eq. ad for the lattice ``model`` at wavenumber ``q`` on ``grid`` (module docstring); methods are the SNES
    callbacks and the continuation layer's hooks.

    ``omega``: the frequency of the fixed-frequency form (1: eq. ad); ``amplitude``: the fixed-amplitude form's a
    (inf: the uncompressed limit delta0 / a = 0 of the Hertz law); ``measure``: 'a1' or 'sup' (what a is);
    ``normalised``: the profile c* that carries the normalisation (default 0); ``parameter``: the continuation
    parameter (default q).
    """

    def __init__(self, model: LatticeModel, grid: ProfileGrid, q: float, omega: float = 1.0,
                 amplitude: Optional[float] = None, measure: str = "a1", normalised: int = 0,
                 parameter: str = "q") -> None:
        if not isinstance(model, LatticeModel):
            raise ParameterError("model", model, "must be a LatticeModel")
        model.require_conservative("the travelling-wave problem (eq. ad)")
        if measure not in MEASURES:
            raise ParameterError("measure", measure, "must be 'a1' (first sine coefficient) or 'sup' (max |u|)")
        self.p = model.cell
        # no reflection symmetry (p >= 3, or bonds that differ: n -> -n maps bond c to bond -c-1): the whole period
        self.full = self.p >= 3 or model.bonds is not None
        if self.full and grid.parity != 0:
            from .grid import ProfileGrid
            grid = ProfileGrid(grid.K, grid.comm, parity=0)
        self.model, self.grid = model, grid
        from .resources import check_memory
        check_memory(grid.K, grid.comm, "nk", profiles=self.p)    # the least a solver needs, before the stencils
        self.masses = np.array(model.masses, dtype=float)
        self.normalised = check_integer("normalised", normalised, 0, "the normalised profile's index", self.p - 1)
        self.measure = measure
        self.bordered = amplitude is not None
        self.amplitude = self.lam = None
        if self.bordered:
            self._set_amplitude(amplitude)
        else:
            self._set_omega(omega)
        self.comm = grid.comm
        self.mpi = self.comm.tompi4py() if self.comm.getSize() > 1 else None
        self.last = self.comm.getRank() == self.comm.getSize() - 1
        self.nloc = grid.rend - grid.rstart
        # scalars of X: lam (fixed amplitude), then the gauge unknowns (whole-period profiles)
        self.i_gauge = 1 if self.bordered else 0
        self.nsc = self.i_gauge + (2 if self.full else 0)
        self.gauge = None                 # reference translation u_c' of the gauge column (owned rows)
        self.simple = self.p == 1 and not self.bordered        # X is the grid's own Vec (the paper's problem)
        ranges = np.array(grid._template.getOwnershipRanges(), dtype=np.int64)
        self._starts, self._counts = ranges[:-1], np.diff(ranges)
        self.stencils = None
        self._assembler = None
        self._set_q(q)
        have = ["q"] + list(model.parameters) + (["a", "log_a"] if self.bordered else ["omega"]) + \
            [f"m{c}" for c in range(self.p)] + (["epsilon"] if self.p > 1 else [])
        if parameter not in have:
            raise ParameterError("parameter", parameter, "this travelling-wave problem continues in one of "
                                 + ", ".join(have))
        self.parameter = parameter
        self._work = [PETSc.Vec().createMPI((self.nloc, grid.size), comm=self.comm) for _ in range(2)]
        self.a = self.b = None            # V''(d+), V''(d-) at the last Jacobian evaluation
        self.arclength = None             # (row as a full array, value) while solving on Z
        self.dparam = None                # dF/dp at the last Jacobian evaluation (Z solves)
        self.solvers = {}
        self.stats = None
        self._state = None                # X of the natural solves (:meth:`solve` with row None)

    # --- parameters (the lenses of the continuation layer) ----------------------------------------------------
    def _set_omega(self, omega):
        self.omega = w = check_real("omega", omega, "the frequency", 0.0)
        self.lam = w * w
        self.lattice = self.model

    def _set_amplitude(self, a):
        self.amplitude = math.inf if a == math.inf else check_real("amplitude", a, "the wave amplitude", 0.0)
        self.lattice = self.model.rescaled(self.amplitude)          # the law seen by w = u / a

    def _set_q(self, q):
        if self.stencils is not None:
            if check_wavenumber(q, self.grid.h) == self.q:
                return
            self.stencils.destroy()
        self.stencils = ShiftStencils(self.grid, q)        # checks q (ParameterError naming q)
        self.q, self.sigma = self.stencils.q, self.stencils.sigma
        self._assembler = None

    def set_parameter(self, name: str, value: float) -> None:
        """Set one parameter of the problem (any of those it continues in)."""
        value = float(value)
        if name == "q":
            self._set_q(value)
        elif name == "omega":
            self._set_omega(value)
        elif name == "a":
            self._set_amplitude(value)
        elif name == "log_a":
            self._set_amplitude(math.exp(value))
        else:                                       # the model: a parameter of the law, or a mass
            if name in self.model.parameters:
                self.model = self.model.with_parameter(name, value)
            else:
                masses = list(self.masses)
                masses[1 if name == "epsilon" else int(name[1:])] = value
                self.model = self.model.with_masses(masses)
                self.masses = np.array(self.model.masses)
            self.lattice = self.model.rescaled(self.amplitude) if self.bordered else self.model

    def get_parameter(self, name: str) -> float:
        if name in ("q", "omega"):
            return getattr(self, name)
        if name == "a":
            return self.amplitude
        if name == "log_a":
            return math.log(self.amplitude)
        if name in self.model.parameters:
            return float(self.model.parameter(name))
        return float(self.masses[1 if name == "epsilon" else int(name[1:])])

    # --- layout: X = (profiles, [lam]), Z = (X, parameter) ------------------------------------------------------
    def sizes(self, extended: bool = False) -> tuple[int, int]:
        """(local, global) size of X (or of Z)."""
        extra = self.nsc + (1 if extended else 0)
        return (self.p * self.nloc + (extra if self.last else 0), self.p * self.grid.size + extra)

    def create_state(self) -> PETSc.Vec:
        """A new X Vec."""
        if self.simple:
            return self.grid.create_vec()
        return PETSc.Vec().createMPI(self.sizes(), comm=self.comm)

    def create_vec(self) -> PETSc.Vec:
        """A new extended Vec Z = (X, parameter)."""
        return PETSc.Vec().createMPI(self.sizes(True), comm=self.comm)

    def global_index(self, c: int, i: np.ndarray, extended: bool = False,
                     counts: Optional[Sequence[int]] = None) -> np.ndarray:
        """Index in X (or Z) of grid unknown i of profile c (``counts``: the grid rows per rank of another split
        than this run's, e.g. the one a saved vector was written with)."""
        starts, counts = (self._starts, self._counts) if counts is None else (np.cumsum(counts) - counts, counts)
        i = np.asarray(i, dtype=np.int64)
        owner = np.searchsorted(starts, i, side="right") - 1
        start, count = starts[owner], counts[owner]
        # each rank holds its rows of u_0 .. u_{p-1} one after the other; the scalars sit after them on the last
        return self.p * start + c * count + (i - start)

    def natural_order(self, size: int, counts: Optional[Sequence[int]] = None) -> np.ndarray:
        """The positions in an X or Z Vec of ``size`` entries of its values in an order that does not depend on the
        ranks (u_0 whole, ..., u_{p-1} whole, then the scalars): ``V_natural = gathered(V)[order]``."""
        i = np.arange(self.grid.size)
        return np.concatenate([self.global_index(c, i, counts=counts) for c in range(self.p)]
                              + [np.arange(self.p * self.grid.size, size)])

    def scalar_index(self, k: int, extended: bool = False) -> int:
        """Index of scalar k (0: lam; with ``extended``, the parameter after the scalars of X)."""
        return self.p * self.grid.size + k

    def pack(self, profiles_half: Sequence[np.ndarray], lam: Optional[float] = None,
             parameter: Optional[float] = None) -> PETSc.Vec:
        """An X Vec (or a Z Vec if ``parameter`` is given) from p half profiles (K+1 values on [0, pi]) and, in the
        fixed-amplitude form, lam."""
        extended = parameter is not None
        V = self.create_vec() if extended else self.create_state()
        a = V.getArray()
        g = self.grid
        for c in range(self.p):
            a[c * self.nloc:(c + 1) * self.nloc] = \
                np.asarray(profiles_half[c], float)[g.rstart + g.offset:g.rend + g.offset]
        if self.last:                     # lam (fixed amplitude), the gauge unknowns (0), the parameter (Z)
            scalars = [self.lam if lam is None else lam] if self.bordered else []
            a[self.p * self.nloc:] = scalars + [0.0] * (self.nsc - self.i_gauge) + ([parameter] if extended else [])
        return V

    def _scalars(self, V):
        """The scalars after the profiles (on every rank): lam (bordered form) then the parameter (Z)."""
        n = V.getSize() - self.p * self.grid.size
        out = np.zeros(max(n, 1))
        if self.last and n:
            out[:n] = V.getArray(readonly=True)[self.p * self.nloc:]
        if n:
            out = self._sum(out)
        return out[:n]

    def _sum(self, local):
        """The sum of ``local`` (a number or an array) over the ranks (collective)."""
        return self.mpi.allreduce(local) if self.mpi is not None else local

    def half_profiles(self, V: PETSc.Vec) -> list[np.ndarray]:
        """The p half profiles (K+1 values each, on every rank) of an X or Z Vec."""
        a, n = V.getArray(readonly=True), self.nloc
        return [self._gathered_profile(a[c * n:(c + 1) * n]) for c in range(self.p)]

    def frequency(self, V: PETSc.Vec) -> float:
        """omega of the wave held by V (fixed frequency: self.omega; fixed amplitude: a^((d-1)/2) sqrt(lam))."""
        if not self.bordered:
            return self.omega
        return self._omega_from(self._scalars(V)[0])

    def _omega_from(self, lam):
        d = self.model.law.scale_degree
        a = self.amplitude if math.isfinite(self.amplitude) else 1.0
        return a ** ((d - 1) / 2) * math.sqrt(max(lam, 0.0))

    # --- the residual ---------------------------------------------------------------------------------------
    def _profile_parts(self, V):
        """Per profile: (D2 u_c, tau_q u_c, tau_{-q} u_c, u_c) on the owned rows (copies)."""
        a = V.getArray(readonly=True)
        n = self.nloc
        out = []
        w = self._work[0]
        for c in range(self.p):
            w.placeArray(a[c * n:(c + 1) * n])
            try:
                s = self.stencils.stacked(w).getArray(readonly=True)
                out.append((s[:n].copy(), s[n:2 * n].copy(), s[2 * n:].copy(), a[c * n:(c + 1) * n].copy()))
            finally:
                w.resetArray()
        return out

    def _differences(self, parts):
        """Per profile c: (D2 u_c, d+_c = tau_q u_{c+1} - u_c, d-_c = u_c - tau_{-q} u_{c-1}, u_c)."""
        p = self.p
        return [(parts[c][0], parts[(c + 1) % p][1] - parts[c][3], parts[c][3] - parts[(c - 1) % p][2], parts[c][3])
                for c in range(p)]

    def _field_rows(self, diffs, lam):
        """Per profile c: m_c lam D2 u_c - V_c'(d+_c) + V_{c-1}'(d-_c) (bond c joins profiles c and c + 1)."""
        bond = self.lattice.bond_law
        rows = []
        for c, (d2, dp, dm, _) in enumerate(diffs):
            coef = self.masses[c] * lam
            first = d2 if coef == 1.0 else coef * d2
            right, left = bond(c), bond(c - 1)
            rows.append(first - _on_contact(right, right.dV, dp) + _on_contact(left, left.dV, dm))
        return rows

    def _measure(self, profiles_local):
        """The normalisation functional of profile c* (collective): a1(w) = (1/pi) int w sin, or ||w||_inf."""
        w = profiles_local[self.normalised]
        if self.measure == "a1":
            xi = self.grid.owned_points() * self.grid.h
            return self._sum(float(np.dot((1.0 if self.full else 2.0) / self.grid.K * np.sin(xi), w)))
        return profile_sup(self._gathered_profile(w), self.full)

    def _gauge_rows(self, profiles_local):
        """(mean(u_0), b1(u_0)) over the whole period (collective): the two gauge rows."""
        xi = self.grid.owned_points() * self.grid.h
        u0 = profiles_local[0]
        return self._sum(np.array([np.sum(u0) / (2 * self.grid.K), np.dot(np.cos(xi), u0) / self.grid.K]))

    def set_gauge(self, V: PETSc.Vec) -> None:
        """The translation column of the gauge border: u_c' of V's profiles (centred differences), fixed for a
        solve (a whole-period problem only)."""
        if not self.full:
            return
        g, out = self.grid, []
        for prof in self.half_profiles(V):
            d = (np.roll(prof, -1) - np.roll(prof, 1)) / (2 * g.h)
            out.append(d[g.rstart:g.rend])
        self.gauge = np.concatenate(out)

    def _gathered_profile(self, w_local):
        w = self._work[1]
        w.placeArray(w_local)
        try:
            return self.grid.half_profile(w)
        finally:
            w.resetArray()

    def formFunction(self, snes: PETSc.SNES, X: PETSc.Vec, F: PETSc.Vec) -> None:
        if self.simple and X.getSize() == self.grid.size:
            dplus, dminus, d2u = self.shift_differences(X)
            force, lat = self.lattice.force, self.lattice
            lam = self.masses[0] * self.lam               # m_0 omega^2 (eq. ad)
            first = d2u if lam == 1.0 else lam * d2u
            F.getArray()[:] = first - _on_contact(lat, force, dplus) + _on_contact(lat, force, dminus)
            return
        extended, sc, lam, diffs = self._evaluate(X)
        out = F.getArray()
        n = self.nloc
        for c, r in enumerate(self._field_rows(diffs, lam)):
            out[c * n:(c + 1) * n] = r
        profiles = [d[3] for d in diffs]
        border = []                       # the border rows (collective), written on the last rank
        if self.bordered:
            border.append(self._measure(profiles) - 1.0)
        if self.full:
            i = self.i_gauge
            out[:self.p * n] += sc[i] + sc[i + 1] * self.gauge
            border.extend(self._gauge_rows(profiles))
        if extended:
            border.append(self._arclength_dot(X) - self.arclength[1])
        if self.last:
            out[self.p * n:] = border

    def _evaluate(self, X):
        """(extended, scalars, lam, :meth:`_differences`) of an X or Z Vec in the general layout, with the free
        parameter set from Z and the gauge column from X if none is set."""
        extended = X.getSize() > self.p * self.grid.size + self.nsc
        sc = self._scalars(X)
        if extended:
            self.set_parameter(self.parameter, sc[-1])
        if self.full and self.gauge is None:
            self.set_gauge(X)
        return extended, sc, (sc[0] if self.bordered else self.lam), self._differences(self._profile_parts(X))

    def _arclength_dot(self, V):
        """row . V with the arclength row of the Z solve (collective)."""
        lo, hi = V.getOwnershipRange()
        return self._sum(float(np.dot(self.arclength[0][lo:hi], V.getArray(readonly=True))))

    def shift_differences(self, X: PETSc.Vec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """d+ = tau_q u - u, d- = u - tau_{-q} u and D2 u on the owned rows (p = 1, X the grid Vec)."""
        w = self.stencils.stacked(X).getArray(readonly=True)
        u = X.getArray(readonly=True)
        n = self.nloc
        return w[n:2 * n] - u, u - w[2 * n:], w[:n]

    # --- the Jacobian -----------------------------------------------------------------------------------------
    @property
    def assembler(self) -> RowAssembler:
        """The CSR pattern of the paper problem's assembled Jacobian (built on first use)."""
        if self._assembler is None:
            st = self.stencils
            self_cols = np.arange(self.grid.rstart, self.grid.rend, dtype=np.int64)[:, None]
            self._assembler = RowAssembler(self.grid, [st.cols["d2"], self_cols, st.cols["plus"], st.cols["minus"]])
        return self._assembler

    def _coefficients(self, X):
        if self.simple and X.getSize() == self.grid.size:
            lat = self.lattice
            dplus, dminus, _ = self.shift_differences(X)
            self.a = _on_contact(lat, lat.stiffness, dplus)
            self.b = _on_contact(lat, lat.stiffness, dminus)
            return
        _, _, self._lam_lin, diffs = self._evaluate(X)
        bond = self.lattice.bond_law
        self.a = [_on_contact(bond(c), bond(c).d2V, d[1]) for c, d in enumerate(diffs)]
        self.b = [_on_contact(bond(c - 1), bond(c - 1).d2V, d[2]) for c, d in enumerate(diffs)]
        self._diffs = diffs

    def _jacobian_blocks(self):
        a, b = self.a[:, None], self.b[:, None]
        c = self.stencils.coef
        lam = self.masses[0] * self.lam
        d2 = c["d2"] if lam == 1.0 else lam * c["d2"]
        return [d2, a + b, -a * c["plus"], -b * c["minus"]]

    def create_jacobian(self, X: PETSc.Vec, kind: str = "aij") -> PETSc.Mat:
        """J(X) as a new parallel AIJ matrix with this q's pattern (``kind='aij'``), or as a matrix-free operator
        (``kind='shell'``); X is an X Vec or, while continuing in a free parameter, a Z Vec."""
        if kind not in ("aij", "shell"):
            raise ParameterError("kind", kind, "must be 'aij' or 'shell'")
        self._coefficients(X)
        simple = self.simple and X.getSize() == self.grid.size
        if kind == "aij" and simple:
            return self.assembler.create(self._jacobian_blocks())
        sizes = (X.getLocalSize(), X.getSize())
        if kind == "aij":
            J = PETSc.Mat().createAIJ((sizes, sizes), csr=self._bordered_csr(X), comm=self.comm)
            J.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
            J.assemble()
            return J
        J = PETSc.Mat().createPython((sizes, sizes), _JacobianProduct(self, X.getSize()), comm=self.comm)
        J.setUp()
        if not simple:
            self._border_columns(X)
        return J

    def formJacobian(self, snes: PETSc.SNES, X: PETSc.Vec, J: PETSc.Mat, P: PETSc.Mat) -> None:
        self._coefficients(X)
        simple = self.simple and X.getSize() == self.grid.size
        if P.getType() != PETSc.Mat.Type.PYTHON:
            if simple:
                self.assembler.update(P, self._jacobian_blocks())
            else:
                indptr, indices, values = self._bordered_csr(X)
                P.zeroEntries()
                P.setValuesCSR(indptr, indices, values)
                P.assemble()
        elif not simple:
            self._border_columns(X)
        if J.handle != P.handle:
            J.assemble()
        pc = getattr(self, "preconditioner", None)
        if pc is not None:                # a layout's block preconditioner (never the simple path)
            pc.scales = [self.masses[c] * self._lam_lin for c in range(self.p)]

    def _parameter_column(self, X):
        """dF/dp on the field rows (owned; the border rows do not depend on p): exact for omega and the masses, a
        finite difference otherwise."""
        name, diffs, lam = self.parameter, self._diffs, self._lam_lin
        if name == "omega":
            return np.concatenate([2 * self.omega * self.masses[c] * diffs[c][0] for c in range(self.p)])
        if name == "epsilon" or (name.startswith("m") and name[1:].isdigit()):
            c0 = 1 if name == "epsilon" else int(name[1:])
            return np.concatenate([lam * diffs[c][0] if c == c0 else np.zeros(self.nloc) for c in range(self.p)])
        value = self.get_parameter(name)
        step = 1e-7 * max(abs(value), 1e-3)
        if name == "q" and value + step > math.pi:
            step = -step
        base = np.concatenate(self._field_rows(diffs, lam))
        self.set_parameter(name, value + step)
        try:
            parts = self._profile_parts(X) if name == "q" else None
            shifted = np.concatenate(self._field_rows(self._differences(parts) if parts else diffs, lam))
        finally:
            self.set_parameter(name, value)
        return (shifted - base) / step

    def _border_columns(self, X):
        """The dense columns of the current Jacobian: d/dlam (bordered form) and d/dp (Z)."""
        diffs = self._diffs
        self.dlam = np.concatenate([self.masses[c] * diffs[c][0] for c in range(self.p)]) if self.bordered else None
        extended = X.getSize() > self.p * self.grid.size + self.nsc
        self.dparam = self._parameter_column(X) if extended else None
        self.measure_row = self._measure_gradient([d[3] for d in diffs])

    def _measure_gradient(self, profiles_local):
        """The normalisation row restricted to profile c*: (global unknown indices, values) on every rank."""
        if not self.bordered:
            return None
        g = self.grid
        if self.measure == "a1":
            j = np.arange(g.size)
            return j, (1.0 if self.full else 2.0) / g.K * np.sin((j + g.offset) * g.h)
        u = self._gathered_profile(profiles_local[self.normalised])
        idx, vals = _sup_gradient(u, self.full)
        idx = idx - g.offset                    # grid points -> unknowns (odd profiles: u_1 is unknown 0)
        keep = (idx >= 0) & (idx < g.size)
        return idx[keep], vals[keep]

    def _bordered_csr(self, X):
        """CSR rows (owned) of the Jacobian on X (or Z) with the border columns and rows."""
        self._border_columns(X)
        extended = X.getSize() > self.p * self.grid.size + self.nsc
        st, lam = self.stencils, self._lam_lin
        rows_i = np.arange(self.grid.rstart, self.grid.rend, dtype=np.int64)
        n = self.nloc
        cols, vals = [], []
        j_lam = self.scalar_index(0)
        j_gauge = self.scalar_index(self.i_gauge)
        j_par = self.scalar_index(self.nsc)
        for c in range(self.p):
            a, b = self.a[c][:, None], self.b[c][:, None]
            cp, cm = (c + 1) % self.p, (c - 1) % self.p
            bc = [self.global_index(c, st.cols["d2"]), self.global_index(c, rows_i[:, None]),
                  self.global_index(cp, st.cols["plus"]), self.global_index(cm, st.cols["minus"])]
            bv = [self.masses[c] * lam * st.coef["d2"], a + b, -a * st.coef["plus"], -b * st.coef["minus"]]
            if self.bordered:
                bc.append(np.full((n, 1), j_lam))
                bv.append(self.dlam[c * n:(c + 1) * n, None])
            if self.full:
                bc += [np.full((n, 1), j_gauge), np.full((n, 1), j_gauge + 1)]
                bv += [np.ones((n, 1)), self.gauge[c * n:(c + 1) * n, None]]
            if extended:
                bc.append(np.full((n, 1), j_par))
                bv.append(self.dparam[c * n:(c + 1) * n, None])
            cols.append(np.concatenate(bc, axis=1))
            vals.append(np.concatenate([np.broadcast_to(v, blk.shape) for v, blk in zip(bv, bc)], axis=1))
        indptr, indices, values = merged_csr(np.concatenate(cols), np.concatenate(vals))
        if self.last:
            extra = []
            if self.bordered:             # the measure row, with an explicit (zero) diagonal entry for LU
                idx, v = self.measure_row
                extra.append((np.append(self.global_index(self.normalised, idx), j_lam), np.append(v, 0.0)))
            if self.full:                 # the gauge rows: mean(u_0), b1(u_0)
                j = np.arange(self.grid.size)
                cols0 = self.global_index(0, j)
                extra.append((np.append(cols0, j_gauge), np.append(np.full(len(j), 0.5 / self.grid.K), 0.0)))
                extra.append((np.append(cols0, j_gauge + 1), np.append(np.cos(j * self.grid.h) / self.grid.K, 0.0)))
            if extended:
                row = self.arclength[0]
                nz = np.union1d(np.flatnonzero(row), [j_par])
                extra.append((nz, row[nz]))
            for rc, rv in extra:
                rc = np.asarray(rc, dtype=np.int64)
                order = np.argsort(rc)
                indices = np.concatenate([indices, rc[order].astype(PETSc.IntType)])
                values = np.concatenate([values, np.asarray(rv, float)[order]])
                indptr = np.concatenate([indptr, [indptr[-1] + len(rc)]]).astype(PETSc.IntType)
        return indptr, indices, values

    # --- the linear wave (start of the amplitude families) -------------------------------------------------
    def linear_guess(self, branch: str = "acoustic") -> tuple[list[np.ndarray], float]:
        """Half profiles and lam of the discrete linear wave of the fixed-amplitude form (the law's linear
        stiffness K = V''(0) > 0): the eigenvector of the scheme's p x p Bloch matrix L_cc = 2K, L_{c,c+1} = -K mu+,
        L_{c,c-1} = -K mu- (:meth:`~hertzpetsc.model.LatticeModel.bloch_matrix`) against diag(m) sigma_h, mu+- and
        sigma_h the symbols of tau_{+-q} and of -D2, normalised so that the measure of profile c* is 1, where c*
        (:attr:`normalised`) is set to the profile of largest amplitude (the optical wave at the zone edge leaves a
        bead at rest). Odd profiles: the symbols on the sine (exact, from the stencils). Whole-period profiles: on
        e^{i xi} (mu- = conj(mu+), sigma_h = 4 sin^2(h/2)/h^2; L Hermitian), the profiles Im(Y_c e^{i xi}) (the
        bead types' phases differ when the pattern has no reflection symmetry)."""
        if not self.bordered:
            raise ParameterError("amplitude", None, "the linear wave starts the fixed-amplitude form")
        K = self.lattice.law.linear_stiffness
        self.lattice.require_linear_stiffness("the linear wave needs a linear stiffness V''(0) > 0 (a precompression "
                                              "> 0)")
        check_branch(self.model, self.q, branch)
        import scipy.linalg
        g, p = self.grid, self.p
        xi = g.xi_half()
        s = np.sin(xi)
        if self.full:
            offsets, weights = shift_stencil(self.sigma)
            mu_plus = complex(np.sum(weights * np.exp(1j * offsets * g.h)))
            mu_minus = np.conj(mu_plus)
            sigma_h = 4 * math.sin(g.h / 2) ** 2 / g.h ** 2
        else:
            v = g.vec_from_half_profile(s)
            st = self.stencils.stacked(v).getArray(readonly=True)
            n = self.nloc
            sl = v.getArray(readonly=True)
            dots = self._sum(np.array([np.dot(sl, sl), np.dot(sl, st[:n]), np.dot(sl, st[n:2 * n]),
                                       np.dot(sl, st[2 * n:])]))
            v.destroy()
            sigma_h, mu_plus, mu_minus = -dots[1] / dots[0], dots[2] / dots[0], dots[3] / dots[0]
        lams, vecs = scipy.linalg.eigh(self.lattice.bloch_matrix(mu_plus, mu_minus), np.diag(self.masses) * sigma_h)
        k = 0 if branch == "acoustic" else p - 1
        vec = vecs[:, k]
        self.normalised = int(np.argmax(np.abs(vec)))
        unit = 1.0 if self.measure == "a1" else profile_sup(s, self.full)
        if self.full:
            Y = vec * np.conj(vec[self.normalised]) / abs(vec[self.normalised]) ** 2
            return [np.imag(Y[c] * np.exp(1j * xi)) / unit for c in range(p)], float(lams[k])
        vec = vec / (vec[self.normalised] * unit)
        return [vec[c] * s for c in range(p)], float(lams[k])

    # --- solving --------------------------------------------------------------------------------------------
    def tolerance_scale(self, V: PETSc.Vec) -> float:
        """max(m lam) ||u||_inf: the scale of the field rows' round-off (4 eps scale / h^2 per row)."""
        lam = abs(self._scalars(V)[0]) if self.bordered else self.lam
        return max(float(np.max(self.masses)) * lam, 1e-300) * max(V.norm(PETSc.NormType.NORM_INFINITY), 1e-300)

    def solver(self, extended: bool, prefix: Optional[str] = None,
               solver: Optional[str] = None) -> TravellingWaveSolver:
        """The SNES of this problem's X (or Z) layout under ``prefix`` (built once)."""
        from .resources import check_memory
        from .twsolver import TW_PREFIX, TravellingWaveSolver, tw_solver
        if extended not in self.solvers:
            prefix = prefix or getattr(self, "prefix", TW_PREFIX)
            check_memory(self.grid.K, self.comm, tw_solver(prefix, solver), profiles=self.p)
            self.solvers[extended] = TravellingWaveSolver(self.grid, prefix, solver, layout=self, extended=extended)
        return self.solvers[extended]

    def solve_state(self, X: PETSc.Vec, tolerances: Optional[dict] = None) -> SolveStats:
        """Solve for X at the current parameters (SolveStats); ConvergenceError when SNES fails. With the 'sup'
        measure, the normalised profile is the largest one (max_c ||u_c||_inf = A): solved again on the
        largest profile if the solution's largest is another."""
        return self._solve(X, False, tolerances)

    def _solve(self, V, extended, tolerances=None):
        """:meth:`solve_state` on an X Vec, or on a Z Vec (``extended``) with the arclength row set."""
        self.set_gauge(V)
        self.stats = self.solver(extended).solve(self, V, tolerances)
        if self.bordered and self.measure == "sup" and self.p > 1:
            for _ in range(self.p):
                largest = int(np.argmax([profile_sup(w, self.full) for w in self.half_profiles(V)]))
                if largest == self.normalised:
                    break
                self.normalised = largest
                self.stats = self.solver(extended).solve(self, V, tolerances)
        return self.stats

    def solve(self, Z: PETSc.Vec, row: Optional[PETSc.Vec] = None, value: Optional[float] = None) -> int:
        """The continuation layer's corrector (:meth:`ContinuationProblem.solve`)."""
        if row is None:
            self.set_parameter(self.parameter, self._scalars(Z)[-1] if value is None else value)
            if self._state is None:               # the X of the natural solves, kept (one per problem)
                self._state = self.create_state()
            X = self._state
            n = X.getLocalSize()
            X.getArray()[:] = Z.getArray(readonly=True)[:n]
            stats = self.solve_state(X)
            Z.getArray()[:n] = X.getArray(readonly=True)
            return stats.iterations
        self.arclength = (gathered(row), float(value))
        try:
            self._solve(Z, True)
        except (ParameterError, OverflowError) as err:     # a Newton iterate's parameter out of its range (a -> 0, ...)
            raise ConvergenceError(f"travelling-wave SNES (prefix -{getattr(self, 'prefix', 'tw_')})",
                                   f"an iterate left the parameter's range: {err}", q=self.q) from None
        finally:
            self.arclength = None
        self.set_parameter(self.parameter, self._scalars(Z)[-1])
        return self.stats.iterations

    def predictor_ratio(self, p_from: float, p_to: float) -> float:
        """(q_from / q_to)^(2/(d-1)) for the paper's continuation in q: the rescaled profile q^(2/(d-1)) u stays
        O(1) (eq. normscaling); a ratio, so that exponents 2/(d-1) in the hundreds (alpha near 1) neither
        overflow nor underflow."""
        if self.parameter == "q" and not self.bordered and self.model.delta0 == 0.0:
            d = self.model.law.scale_degree
            return (p_from / p_to) ** (2.0 / (d - 1.0)) if d > 1 else 1.0
        return 1.0

    def weights(self) -> PETSc.Vec:
        """The arclength inner product: (h/pi) sum over the profiles' grid values (the integral over a period)
        plus the scalars' squares."""
        W = self.create_vec()
        W.set(self.grid.h / math.pi)
        if self.last:
            W.getArray()[self.p * self.nloc:] = 1.0
        return W

    def report(self, Z: PETSc.Vec) -> dict:
        profiles = self.half_profiles(Z)
        lam = float(self._scalars(Z)[0]) if self.bordered else self.lam
        return dict(profiles=profiles, lam=lam, omega=self.frequency(Z))

    def destroy(self) -> None:
        for s in self.solvers.values():
            s.destroy()
        self.solvers = {}
        self.stencils.destroy()
        for w in self._work:
            w.destroy()
        if self._state is not None:
            self._state.destroy()
            self._state = None


class _JacobianProduct:
    """Matrix-free Jacobian of eq. ad (the ``shell`` kind of :meth:`AdvanceDelayProblem.create_jacobian`), with
    the border columns and rows of the fixed-amplitude form and of a free parameter."""

    def __init__(self, problem, size):
        self.problem, self.size = problem, size

    @PETSc.Log.EventDecorator("hz_tw_jacobian_mult")
    def mult(self, mat, x, y):
        p = self.problem
        if p.simple and self.size == p.grid.size:
            w = p.stencils.stacked(x).getArray(readonly=True)
            v = x.getArray(readonly=True)
            n = p.nloc
            lam = p.masses[0] * p.lam
            d2 = w[:n] if lam == 1.0 else lam * w[:n]
            y.getArray()[:] = d2 + (p.a + p.b) * v - p.a * w[n:2 * n] - p.b * w[2 * n:]
            return
        extended = self.size > p.p * p.grid.size + p.nsc
        sc = p._scalars(x)                    # the direction's components along lam and the parameter
        lam = p._lam_lin
        parts = p._profile_parts(x)
        n = p.nloc
        out = y.getArray()
        for c in range(p.p):
            d2 = parts[c][0]
            plus = parts[(c + 1) % p.p][1]
            minus = parts[(c - 1) % p.p][2]
            v = parts[c][3]
            r = p.masses[c] * lam * d2 + (p.a[c] + p.b[c]) * v - p.a[c] * plus - p.b[c] * minus
            if p.bordered:
                r = r + sc[0] * p.dlam[c * n:(c + 1) * n]
            if p.full:
                r = r + sc[p.i_gauge] + sc[p.i_gauge + 1] * p.gauge[c * n:(c + 1) * n]
            if extended:
                r = r + sc[-1] * p.dparam[c * n:(c + 1) * n]
            out[c * n:(c + 1) * n] = r
        border = []                       # the border rows (collective), written on the last rank
        if p.bordered:
            idx, vals = p.measure_row
            own = (idx >= p.grid.rstart) & (idx < p.grid.rend)
            local = float(np.dot(vals[own], x.getArray(readonly=True)[p.normalised * n + idx[own] - p.grid.rstart]))
            border.append(p.mpi.allreduce(local) if p.mpi is not None else local)
        if p.full:
            border.extend(p._gauge_rows([parts[c][3] for c in range(p.p)]))
        if extended:
            border.append(p._arclength_dot(x))
        if p.last:
            out[p.p * n:] = border
