"""Travelling waves of precompressed chains and of chains with a mass pattern (dimers), continued in amplitude
and in the mass ratio (issue 16, beyond the paper's sonic vacuum).

The chain m_n x_n'' = V'(x_{n+1} - x_n) - V'(x_n - x_{n-1}) with the precompressed Hertz law
V'(r) = delta0^alpha - (delta0 - r)_+^alpha (:class:`~hertzpetsc.hertz.HertzLaw`, eq. vhertz shifted by the static
overlap) and masses repeating a pattern m_0 .. m_{p-1}. A travelling wave with per-bead wavenumber q has one odd
2 pi-periodic profile per bead of the cell, x_{pj+c}(t) = u_c(q (pj + c) - omega t), and eq. ad becomes

    m_c omega^2 u_c'' = V'(u_{c+1}(xi + q) - u_c(xi)) - V'(u_c(xi) - u_{c-1}(xi - q)),   c = 0 .. p-1 (cyclic),

(p = 1: eq. ad itself). Scaling (exact, since V'_delta0(a r) = a^alpha V'_{delta0/a}(r)): u_c = a w_c,
omega^2 = a^(alpha-1) lam, and the rescaled profiles solve the same system with the law V'_eta, eta = delta0 / a,
and the normalisation a1(w_0) = (1/pi) int w_0 sin xi = 1 (a is the first sine coefficient of u_0). w and lam stay
O(1) from the linear wave (a -> 0, eta -> infinity) to the paper's wave (eta = 0), so s = log a is a well-scaled
continuation parameter. omega A^(-(alpha-1)/2) = sqrt(lam) ||w||^(-(alpha-1)/2) tends, as A -> infinity, to the
uncompressed branch value ||u(.;q)||^((1-alpha)/2) of eq. dispers.

:class:`BorderedWaveSystem` is that system (the profiles plus lam, and optionally the mass m_1 with a
pseudo-arclength row) as one SNES problem with an assembled Jacobian bordered by dense rows/columns; it reuses
the shift stencils of :class:`~hertzpetsc.advdelay.AdvanceDelayProblem`. :class:`AmplitudeContinuation` continues
in s at fixed q (secant predictor, step halving), :class:`MassContinuation` continues a dimer in its mass ratio
(pseudo-arclength). Closed forms: :func:`linear_frequency` (acoustic dispersion), :func:`dimer_frequencies`
(2x2 Bloch matrix), :func:`weakly_nonlinear_coefficient` (the Stokes coefficient of omega(A)).
"""
import math
from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

from .advdelay import AdvanceDelayProblem, check_wavenumber
from .assembly import merged_csr
from .diagnostics import sup_norm
from .errors import ConvergenceError, ParameterError
from .hertz import HertzLaw, check_alpha, check_delta0
from .model import LatticeModel
from .stencil import full_period, lagrange_periodic

PRECOMP_PREFIX = "precomp_"
DIMER_PREFIX = "dimer_"


# --- closed forms -------------------------------------------------------------------------------------------------
def linear_frequency(q, alpha=1.5, delta0=1.0):
    """omega_lin(q) = 2 sqrt(K) sin(q/2), K = alpha delta0^(alpha-1): the acoustic dispersion relation of the
    precompressed monatomic chain (the A -> 0 limit of its travelling waves)."""
    K = check_alpha(alpha) * check_delta0(delta0) ** (alpha - 1)
    return 2.0 * math.sqrt(K) * np.sin(np.asarray(q, dtype=float) / 2)


def weakly_nonlinear_coefficient(q, alpha=1.5, delta0=1.0):
    """C(q) in omega / omega_lin - 1 = C(q) a^2 + O(a^4) (a: first sine coefficient, or ||u||_inf, of the wave):
    C = (alpha-1)(alpha-1-sin^2(q/2)) / (4 delta0^2), from the cubic Taylor term of V' directly and the quadratic
    one through the second harmonic (Lindstedt-Poincare at fixed mean overlap)."""
    s2 = np.sin(np.asarray(q, dtype=float) / 2) ** 2
    return (alpha - 1) * (alpha - 1 - s2) / (4 * delta0 ** 2)


def dimer_frequencies(q, epsilon, alpha=1.5, delta0=1.0):
    """(omega_acoustic, omega_optical) of the precompressed dimer (masses 1, epsilon) at per-bead wavenumber q:
    omega^2 = K [(1 + eps) -+ sqrt((1 + eps)^2 - 4 eps sin^2 q)] / eps (2x2 Bloch matrix, per-cell 2q)."""
    K = alpha * delta0 ** (alpha - 1)
    e = float(epsilon)
    root = math.sqrt((1 + e) ** 2 - 4 * e * math.sin(q) ** 2)
    return math.sqrt(K * ((1 + e) - root) / e), math.sqrt(K * ((1 + e) + root) / e)


def check_amplitude(a, name="amplitude"):
    try:
        x = float(a)
    except (TypeError, ValueError):
        raise ParameterError(name, a, "must be a real number > 0") from None
    if not (x > 0 and math.isfinite(x)):
        raise ParameterError(name, a, "the wave amplitude must be a finite number > 0")
    return x


# --- the bordered system ------------------------------------------------------------------------------------------
class BorderedWaveSystem:
    """Rescaled profiles w_0 .. w_{p-1} (p = the model's mass pattern), lam = omega^2 / a^(alpha-1) and, with
    ``free_mass``, the mass m_1 of a dimer, as one distributed Vec; residual and assembled Jacobian for SNES.

    Rows: the p advance-delay equations (module docstring), a1(w_0) = 1, and with ``free_mass`` the
    pseudo-arclength row t . (X - X_pred) = 0 (:meth:`set_arclength`). Layout: each rank holds its grid rows of
    w_0 .. w_{p-1} one after the other; the scalars are the last entries of the last rank. ``eta`` =
    delta0 / a is set by :meth:`set_eta`. The Jacobian is exact: the V''-weighted shift blocks of eq. ad, the
    dense column d R / d lam = m_c D2 w_c (and lam D2 w_1 for m_1), the dense row of a1.
    """

    def __init__(self, model, grid, q, free_mass=False):
        if not isinstance(model, LatticeModel):
            raise ParameterError("model", model, "must be a LatticeModel")
        if free_mass and model.cell != 2:
            raise ParameterError("masses", list(model.masses), "continuation in the mass ratio needs a dimer "
                                 "(a pattern of two masses)")
        self.model, self.grid = model, grid
        self.q = check_wavenumber(q, grid.h)
        self.p = model.cell
        self.masses = np.array(model.masses, dtype=float)
        self.free_mass = free_mass
        self.nsc = 2 if free_mass else 1
        self.shifts = AdvanceDelayProblem(LatticeModel.hertz(model.alpha), grid, q)   # the stencils only
        self.law = HertzLaw(model.alpha, model.delta0)
        comm = grid.comm
        self.comm = comm
        self.mpi = comm.tompi4py()
        self.last = comm.getRank() == comm.getSize() - 1
        self.nloc = grid.rend - grid.rstart
        p, n = self.p, grid.size
        self.size = p * n + self.nsc
        self.local_size = p * self.nloc + (self.nsc if self.last else 0)
        ranges = np.array(grid._template.getOwnershipRanges(), dtype=np.int64)
        self._starts, self._counts = ranges[:-1], np.diff(ranges)
        xi = grid.owned_points() * grid.h
        self.sin_local = (2.0 / grid.K) * np.sin(xi)             # a1(w) = sum_j (2/K) sin(xi_j) w_j
        self.work = [grid.create_vec() for _ in range(p)]
        self._pattern = None
        self.tangent = None
        self.tangent_full = None
        self.predicted = None
        self.set_eta(model.delta0)

    # layout
    def global_index(self, c, i):
        """Index in the bordered Vec of unknown i (grid numbering) of profile c."""
        i = np.asarray(i, dtype=np.int64)
        owner = np.searchsorted(self._starts, i, side="right") - 1
        return p_offset(self.p, self._starts[owner], self._counts[owner], c, i)

    def scalar_index(self, k):
        return self.p * self.grid.size + k

    def create_vec(self):
        v = PETSc.Vec().createMPI((self.local_size, self.size), comm=self.comm)
        return v

    def set_eta(self, eta):
        """The rescaled precompression eta = delta0 / a of the law the residual uses."""
        self.eta = float(eta)
        self.law = HertzLaw(self.model.alpha, self.eta)

    # packing
    def pack(self, profiles_half, lam, m1=None):
        """A bordered Vec from p half profiles (K+1 values on [0, pi]) and the scalars."""
        X = self.create_vec()
        a = X.getArray()
        g = self.grid
        for c in range(self.p):
            a[c * self.nloc:(c + 1) * self.nloc] = np.asarray(profiles_half[c])[g.rstart + 1:g.rend + 1]
        if self.last:
            a[self.p * self.nloc] = lam
            if self.free_mass:
                a[self.p * self.nloc + 1] = self.masses[1] if m1 is None else m1
        return X

    def scalars(self, X):
        """(lam, m1 or None) on every rank."""
        out = np.zeros(2)
        if self.last:
            a = X.getArray(readonly=True)
            out[:self.nsc] = a[self.p * self.nloc:self.p * self.nloc + self.nsc]
        out = self.mpi.allreduce(out) if self.comm.getSize() > 1 else out
        return float(out[0]), (float(out[1]) if self.free_mass else None)

    def half_profiles(self, X):
        """The p half profiles (K+1 values each, on every rank)."""
        self._unpack(X)
        return [self.grid.half_profile(w) for w in self.work]

    def _unpack(self, X):
        a = X.getArray(readonly=True)
        for c, w in enumerate(self.work):
            w.getArray()[:] = a[c * self.nloc:(c + 1) * self.nloc]

    def _differences(self, X):
        """Per profile: D2 w_c, d+_c = tau_q w_{c+1} - w_c, d-_c = w_c - tau_{-q} w_{c-1}, w_c (owned rows)."""
        self._unpack(X)
        n = self.nloc
        stacked = []
        for w in self.work:
            s = self.shifts.stacked(w).getArray(readonly=True)
            stacked.append((s[:n].copy(), s[n:2 * n].copy(), s[2 * n:].copy(), w.getArray(readonly=True).copy()))
        out = []
        for c in range(self.p):
            d2, _, _, w = stacked[c]
            plus = stacked[(c + 1) % self.p][1]
            minus = stacked[(c - 1) % self.p][2]
            out.append((d2, plus - w, w - minus, w))
        return out

    def _dot_all(self, local):
        return self.mpi.allreduce(float(local)) if self.comm.getSize() > 1 else float(local)

    def formFunction(self, snes, X, F):
        lam, m1 = self.scalars(X)
        masses = self.masses.copy()
        if self.free_mass:
            masses[1] = m1
        diffs = self._differences(X)
        out = F.getArray()
        n = self.nloc
        dV = self.law.dV
        for c, (d2, dp, dm, _) in enumerate(diffs):
            out[c * n:(c + 1) * n] = masses[c] * lam * d2 - dV(dp) + dV(dm)
        a1 = self._dot_all(np.dot(self.sin_local, diffs[0][3]))
        arc = 0.0
        if self.free_mass:
            arc = self._arclength_residual(X)
        if self.last:
            out[self.p * n] = a1 - 1.0
            if self.free_mass:
                out[self.p * n + 1] = arc

    # pseudo-arclength
    def set_arclength(self, tangent, predicted):
        """Row t . (X - X_pred) = 0 with the unit tangent t and the predicted point X_pred (bordered Vecs)."""
        self.tangent, self.predicted = tangent, predicted
        scatter, full = PETSc.Scatter.toAll(tangent)
        scatter.scatter(tangent, full, PETSc.InsertMode.INSERT_VALUES, PETSc.ScatterMode.FORWARD)
        self.tangent_full = full.getArray(readonly=True).copy()
        scatter.destroy()
        full.destroy()

    def _arclength_residual(self, X):
        d = X.copy()
        d.axpy(-1.0, self.predicted)
        r = d.dot(self.tangent)
        d.destroy()
        return r

    # Jacobian
    def _rows(self, X):
        lam, m1 = self.scalars(X)
        masses = self.masses.copy()
        if self.free_mass:
            masses[1] = m1
        diffs = self._differences(X)
        st = self.shifts.stencils
        rows_i = np.arange(self.grid.rstart, self.grid.rend, dtype=np.int64)
        d2c, pc, mc = st.cols["d2"], st.cols["plus"], st.cols["minus"]
        cols, vals = [], []
        for c, (d2, dp, dm, _) in enumerate(diffs):
            a, b = self.law.d2V(dp)[:, None], self.law.d2V(dm)[:, None]
            cp, cm = (c + 1) % self.p, (c - 1) % self.p
            blocks_c = [self.global_index(c, d2c), self.global_index(c, rows_i[:, None]),
                        self.global_index(cp, pc), self.global_index(cm, mc),
                        np.full((self.nloc, 1), self.scalar_index(0))]
            blocks_v = [masses[c] * lam * st.coef["d2"], a + b, -a * st.coef["plus"], -b * st.coef["minus"],
                        (masses[c] * d2)[:, None]]
            if self.free_mass:
                blocks_c.append(np.full((self.nloc, 1), self.scalar_index(1)))
                blocks_v.append((lam * d2 if c == 1 else 0.0 * d2)[:, None])
            cols.append(np.concatenate(blocks_c, axis=1))
            vals.append(np.concatenate([np.broadcast_to(v, blk.shape) for v, blk in zip(blocks_v, blocks_c)], axis=1))
        indptr, indices, values = merged_csr(np.concatenate(cols), np.concatenate(vals))
        if self.last:
            # a1 row: columns of w_0 (all of them), then the arclength row: every column
            n = self.grid.size
            j = np.arange(n)
            a1_cols = self.global_index(0, j)
            a1_vals = (2.0 / self.grid.K) * np.sin((j + 1) * self.grid.h)
            extra = [(a1_cols, a1_vals, [self.scalar_index(k) for k in range(self.nsc)], [0.0] * self.nsc)]
            if self.free_mass:
                extra.append((np.arange(self.size - self.nsc), self.tangent_full[:self.size - self.nsc],
                              [self.scalar_index(0), self.scalar_index(1)], list(self.tangent_full[-2:])))
            for ccols, cvals, scols, svals in extra:
                rc = np.concatenate([ccols, scols]).astype(np.int64)
                rv = np.concatenate([cvals, svals])
                order = np.argsort(rc)
                indices = np.concatenate([indices, rc[order].astype(PETSc.IntType)])
                values = np.concatenate([values, rv[order]])
                indptr = np.concatenate([indptr, [indptr[-1] + len(rc)]]).astype(PETSc.IntType)
        return indptr, indices, values

    def create_jacobian(self, X):
        indptr, indices, values = self._rows(X)
        J = PETSc.Mat().create(comm=self.comm)
        J.setSizes(((self.local_size, self.size), (self.local_size, self.size)))
        J.setType(PETSc.Mat.Type.AIJ)
        J.setPreallocationCSR((indptr, indices, values))
        J.assemble()
        return J

    def formJacobian(self, snes, X, J, P):
        indptr, indices, values = self._rows(X)
        P.zeroEntries()
        P.setValuesCSR(indptr, indices, values)
        P.assemble()
        if J.handle != P.handle:
            J.assemble()

    # the linear wave
    def linear_guess(self, branch="acoustic"):
        """Half profiles and lam of the discrete linear wave (eta = self.eta > 0) with a1(w_0) = 1: the
        eigenvector of the p x p Bloch matrix of the scheme (exact symbol of D2 and of the shift stencils)."""
        if not self.eta > 0:
            raise ParameterError("delta0", self.eta, "the linear wave needs a precompression > 0")
        g = self.grid
        xi = g.xi_half()
        s = np.sin(xi)
        v = g.vec_from_half_profile(s)
        st = self.shifts.stacked(v).getArray(readonly=True)
        n = self.nloc
        sl = v.getArray(readonly=True)
        dots = np.array([np.dot(sl, sl), np.dot(sl, st[:n]), np.dot(sl, st[n:2 * n]), np.dot(sl, st[2 * n:])])
        dots = self.mpi.allreduce(dots) if self.comm.getSize() > 1 else dots
        v.destroy()
        sigma_h, mu_plus, mu_minus = -dots[1] / dots[0], dots[2] / dots[0], dots[3] / dots[0]
        K = self.law.linear_stiffness
        L = np.zeros((self.p, self.p))
        for c in range(self.p):
            L[c, c] += 2 * K
            L[c, (c + 1) % self.p] -= K * mu_plus
            L[c, (c - 1) % self.p] -= K * mu_minus
        M = np.diag(self.masses) * sigma_h
        import scipy.linalg
        lams, vecs = scipy.linalg.eigh(L, M)
        k = 0 if branch == "acoustic" else self.p - 1
        vec = vecs[:, k] / vecs[0, k]
        return [vec[c] * s for c in range(self.p)], float(lams[k])

    def residual_floor(self, X):
        """Round-off floor of ||R||_2: 4 eps lam max(m) ||w|| / h^2 per row."""
        lam, m1 = self.scalars(X)
        mmax = max(np.max(self.masses), m1 or 0.0)
        wmax = X.norm(PETSc.NormType.NORM_INFINITY)
        return 4 * np.finfo(float).eps * max(abs(lam) * mmax, 1e-300) * wmax / self.grid.h ** 2 \
            * math.sqrt(self.size)

    def destroy(self):
        self.shifts.destroy()
        for w in self.work:
            w.destroy()


def p_offset(p, start, count, c, i):
    """Bordered index of unknown i of profile c, on the rank owning rows [start, start + count)."""
    return p * start + c * count + (i - start)


class BorderedSolver:
    """One SNES (Newton with line search, LU; MUMPS on several ranks) for a :class:`BorderedWaveSystem`, options
    prefix ``prefix`` (e.g. -precomp_snes_rtol, -precomp_pc_factor_mat_solver_type)."""

    def __init__(self, system, prefix=PRECOMP_PREFIX):
        self.system, self.prefix = system, prefix
        comm = system.comm
        snes = PETSc.SNES().create(comm=comm)
        snes.setOptionsPrefix(prefix)
        snes.setType(PETSc.SNES.Type.NEWTONLS)
        self.F = system.create_vec()
        snes.setFunction(system.formFunction, self.F)
        ksp = snes.getKSP()
        ksp.setType(PETSc.KSP.Type.PREONLY)
        pc = ksp.getPC()
        pc.setType(PETSc.PC.Type.LU)
        if comm.getSize() > 1:
            pc.setFactorSolverType("mumps")
        opts = PETSc.Options()
        self._user_set = {k for k in ("rtol", "atol", "stol", "max_it")
                          if opts.hasName(prefix + "snes_" + k)}
        snes.setFromOptions()
        self.snes = snes

    def solve(self, X):
        """Newton from X (overwritten). Raises ConvergenceError unless ||R|| reaches 1e3 x the round-off floor."""
        sysm = self.system
        floor = sysm.residual_floor(X)
        tol = dict(rtol=1e-12, atol=10 * floor, stol=1e-12, max_it=50)
        self.snes.setTolerances(**{k: v for k, v in tol.items() if k not in self._user_set})
        J = sysm.create_jacobian(X)
        self.snes.setJacobian(sysm.formJacobian, J, J)
        try:
            self.snes.solve(None, X)
            reason = int(self.snes.getConvergedReason())
            its = self.snes.getIterationNumber()
            F = X.duplicate()
            sysm.formFunction(None, X, F)
            res = F.norm()
            F.destroy()
        finally:
            J.destroy()
        what = f"bordered travelling-wave SNES (prefix -{self.prefix})"
        if reason <= 0:
            raise ConvergenceError(what, reason, q=sysm.q)
        if not res <= 1e3 * sysm.residual_floor(X):
            raise ConvergenceError(what, f"{reason}, but residual {res:.3g} above the round-off floor", q=sysm.q)
        return its

    def destroy(self):
        self.snes.destroy()
        self.F.destroy()


# --- continuation in amplitude ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class AmplitudePoint:
    """One wave of the amplitude family at fixed q: a = first sine coefficient of u_0, A = ||u_0||_inf, omega,
    Omega = omega A^(-(alpha-1)/2), lam, the gap indicator 2 u_0(q/2) - delta0 (> 0: a gap opens somewhere in the
    wave, monatomic chain), the rescaled half profiles w_c (u_c = a w_c), Newton iterations."""

    q: float
    a: float
    A: float
    omega: float
    Omega: float
    lam: float
    gap: float
    profiles: tuple
    iterations: int
    m1: float = float("nan")

    @property
    def s(self):
        return math.log(self.a)


def amplitude_point(system, X, a, iterations):
    alpha, delta0 = system.model.alpha, system.model.delta0
    lam, m1 = system.scalars(X)
    prof = system.half_profiles(X)
    w0 = prof[0]
    norm = sup_norm(w0)
    omega = a ** ((alpha - 1) / 2) * math.sqrt(lam)
    h = system.grid.h
    w_half_q = float(lagrange_periodic(full_period(w0), h, np.array([system.q / 2]))[0])
    return AmplitudePoint(q=system.q, a=a, A=a * norm, omega=omega, Omega=math.sqrt(lam) * norm ** (-(alpha - 1) / 2),
                          lam=lam, gap=2 * a * w_half_q - delta0, profiles=tuple(prof), iterations=iterations,
                          m1=m1 if m1 is not None else float(system.masses[1] if system.p > 1 else 1.0))


class AmplitudeContinuation:
    """Travelling waves of the precompressed lattice ``model`` at fixed q, continued in s = log a (a = first sine
    coefficient of u_0) from the linear wave: secant predictor on the rescaled unknowns (w, lam), step halving
    on failure (up to ``max_halvings``). One SNES under ``prefix``. delta0 = 0 is allowed only through
    :meth:`limit` (the eta = 0 wave on the same grid, the paper's wave rescaled)."""

    def __init__(self, model, q, grid, prefix=PRECOMP_PREFIX, branch="acoustic", max_halvings=6):
        if model.delta0 <= 0:
            raise ParameterError("delta0", model.delta0, "the amplitude family needs a precompression > 0")
        self.model, self.grid = model, grid
        self.system = BorderedWaveSystem(model, grid, q)
        self.solver = BorderedSolver(self.system, prefix)
        self.q = self.system.q
        self.branch = branch
        self.max_halvings = max_halvings
        self.history = []          # (s, X) of the last two converged points

    def _remember(self, s, X):
        self.history.append((s, X.copy()))
        while len(self.history) > 2:
            self.history.pop(0)[1].destroy()

    def _predict(self, s):
        s1, X1 = self.history[-1]
        X = X1.copy()
        if len(self.history) == 2:
            s0, X0 = self.history[0]
            X.axpy((s - s1) / (s1 - s0), X1)
            X.axpy(-(s - s1) / (s1 - s0), X0)
        return X

    def solve_at(self, a):
        """The wave at amplitude a from the predictor (or, first, from the linear wave); returns AmplitudePoint."""
        a = check_amplitude(a)
        s = math.log(a)
        self.system.set_eta(self.model.delta0 / a)
        if self.history:
            X = self._predict(s)
        else:
            prof, lam = self.system.linear_guess(self.branch)
            X = self.system.pack(prof, lam)
        try:
            its = self.solver.solve(X)
        except ConvergenceError:
            X.destroy()
            raise
        self._remember(s, X)
        point = amplitude_point(self.system, X, a, its)
        X.destroy()
        return point

    def step_to(self, a_target):
        """Continue from the last point to a_target, halving the step in s on failure."""
        if not self.history:
            return self.solve_at(a_target)
        s_last = self.history[-1][0]
        s_target = math.log(check_amplitude(a_target))
        ds = s_target - s_last
        halvings = 0
        while True:
            s = s_last + ds
            try:
                point = self.solve_at(math.exp(s) if abs(s - s_target) > 1e-14 else a_target)
            except ConvergenceError as err:
                halvings += 1
                if halvings > self.max_halvings:
                    raise ConvergenceError("amplitude continuation", err.reason, q=self.q, a=math.exp(s)) from None
                ds *= 0.5
                continue
            if abs(s - s_target) <= 1e-14:
                return point
            s_last = s
            ds = s_target - s_last

    def points(self, amplitudes):
        """Yield the waves at the increasing amplitudes ``amplitudes`` (a, first sine coefficient)."""
        for a in amplitudes:
            yield self.step_to(a)

    def locate_gap(self, lo, hi, tol=1e-10, max_steps=60):
        """The wave where the gap indicator 2 u(q/2) - delta0 vanishes, between the points lo and hi (opposite
        signs), by the Illinois variant of regula falsi in s. Leaves the continuation's history at hi."""
        if not lo.gap * hi.gap < 0:
            raise ParameterError("gap bracket", (lo.a, hi.a), "the gap indicator must change sign")
        saved = [(s, X.copy()) for s, X in self.history]
        a_, b_ = (lo.s, lo.gap), (hi.s, hi.gap)
        side = 0
        point = hi
        try:
            for _ in range(max_steps):
                s = (a_[0] * b_[1] - b_[0] * a_[1]) / (b_[1] - a_[1])
                point = self.solve_at(math.exp(s))
                if abs(point.gap) <= tol * self.model.delta0 or abs(b_[0] - a_[0]) < 1e-14:
                    break
                if point.gap * b_[1] < 0:
                    a_ = b_
                    b_ = (s, point.gap)
                    side = 0
                else:
                    b_ = (s, point.gap)
                    if side == -1:
                        a_ = (a_[0], a_[1] / 2)
                    side = -1
        finally:
            for _, X in self.history:
                X.destroy()
            self.history = saved
        return point

    def destroy(self):
        for _, X in self.history:
            X.destroy()
        self.history = []
        self.solver.destroy()
        self.system.destroy()


def uncompressed_limit(model, q, grid, start, prefix=PRECOMP_PREFIX):
    """The eta = 0 wave (delta0 / A -> 0) on ``grid`` from the AmplitudePoint ``start`` (a large-amplitude wave
    of the family): Omega(q, 0) = ||u(.;q)||^((1-alpha)/2) of eq. dispers on the same grid."""
    system = BorderedWaveSystem(model, grid, q)
    solver = BorderedSolver(system, prefix)
    try:
        system.set_eta(0.0)
        X = system.pack(start.profiles, start.lam)
        its = solver.solve(X)
        lam, _ = system.scalars(X)
        profiles = system.half_profiles(X)
        w0 = profiles[0]
        X.destroy()
    finally:
        solver.destroy()
        system.destroy()
    norm = sup_norm(w0)
    return dict(Omega0=math.sqrt(lam) * norm ** (-(model.alpha - 1) / 2), lam=lam, norm=norm, iterations=its,
                profile=w0, profiles=profiles)


# --- continuation of a dimer in its mass ratio ----------------------------------------------------------------
@dataclass(frozen=True)
class MassPoint:
    """One dimer wave of the mass-ratio family at fixed q and a: the mass m_1 = epsilon, the wave (an
    :class:`AmplitudePoint`), the arclength parameter and the m_1 component of the unit tangent (its sign
    change marks a fold)."""

    epsilon: float
    wave: AmplitudePoint
    arclength: float
    tangent_epsilon: float


class MassContinuation:
    """Dimer waves (masses 1, epsilon) at fixed q and amplitude a (first sine coefficient of u_0), continued in
    epsilon from ``epsilon_start`` by pseudo-arclength: unknowns (w_0, w_1, lam, epsilon), secant tangent in the
    norm ||X||^2 = (h/pi) sum w^2 + lam^2 + epsilon^2 (profile part as the integral over a period), arclength
    row t . (X - X_pred) = 0, step ds halved on failure (up to ``max_halvings``) and grown by 1.5 after easy
    steps up to ``ds_max``. Passes folds in epsilon (where d epsilon / d s changes sign). One SNES (prefix
    ``dimer_``) for the natural first steps and one for the bordered system."""

    def __init__(self, model, q, grid, a, prefix=DIMER_PREFIX, ds=0.02, ds_max=0.1, max_halvings=8):
        if model.cell != 2:
            raise ParameterError("masses", list(model.masses), "must be a pattern of two masses (a dimer)")
        if model.delta0 <= 0:
            raise ParameterError("delta0", model.delta0, "the dimer family is computed for a precompression > 0")
        self.model, self.grid, self.q, self.a = model, grid, q, check_amplitude(a)
        self.prefix, self.ds, self.ds_max, self.max_halvings = prefix, ds, ds_max, max_halvings
        self.system = BorderedWaveSystem(model, grid, q, free_mass=True)
        self.system.set_eta(model.delta0 / self.a)
        self.solver = BorderedSolver(self.system, prefix)
        self.weights = None
        self.points_X = []      # last two converged bordered Vecs
        self.s = 0.0

    def _weight_vec(self):
        if self.weights is None:
            W = self.system.create_vec()
            W.set(self.grid.h / math.pi)
            if self.system.last:
                arr = W.getArray()
                arr[-2:] = 1.0
            self.weights = W
        return self.weights

    def _wnorm(self, X):
        Y = X.copy()
        Y.pointwiseMult(Y, self._weight_vec())
        val = math.sqrt(Y.dot(X))
        Y.destroy()
        return val

    def _natural(self, epsilon):
        """The dimer wave at mass epsilon by a solve with the m_1 row pinned (first points only)."""
        model = self.model.with_masses((self.model.masses[0], epsilon))
        cont = AmplitudeContinuation(model, self.q, self.grid, self.prefix + "natural_")
        try:
            pts = list(cont.points(np.geomspace(min(1e-3, self.a), self.a, 12)))
        finally:
            cont.destroy()
        return pts[-1]

    def start(self, epsilon_start=1.0, first_step=-0.01):
        """Two natural points, at epsilon_start and epsilon_start + first_step (sets the direction)."""
        out = []
        for e in (epsilon_start, epsilon_start + first_step):
            p = self._natural(e)
            X = self.system.pack(p.profiles, p.lam, e)
            self.points_X.append(X)
            out.append(MassPoint(e, p, 0.0, float("nan")))
        self.s = self._wnorm(self._diff(self.points_X[1], self.points_X[0]))
        return out

    @staticmethod
    def _diff(X1, X0):
        D = X1.copy()
        D.axpy(-1.0, X0)
        return D

    def step(self):
        """One pseudo-arclength step; returns the new MassPoint."""
        X0, X1 = self.points_X[-2], self.points_X[-1]
        t = self._diff(X1, X0)
        t.scale(1.0 / self._wnorm(t))
        row = t.copy()
        row.pointwiseMult(row, self._weight_vec())
        ds = self.ds
        halvings = 0
        while True:
            Xp = X1.copy()
            Xp.axpy(ds, t)
            self.system.set_arclength(row, Xp)
            X = Xp.copy()
            try:
                its = self.solver.solve(X)
                ok = True
            except ConvergenceError as err:
                ok, reason = False, err.reason
            if ok:
                break
            X.destroy()
            Xp.destroy()
            halvings += 1
            if halvings > self.max_halvings:
                t.destroy()
                row.destroy()
                raise ConvergenceError("mass-ratio continuation", reason, q=self.q, ds=ds)
            ds *= 0.5
        Xp.destroy()
        self.s += ds
        if its <= 3 and halvings == 0:
            self.ds = min(self.ds_max, 1.5 * self.ds)
        elif halvings:
            self.ds = ds
        t_eps = self.system.scalars(t)[1]
        t.destroy()
        row.destroy()
        self.points_X.pop(0).destroy()
        self.points_X.append(X)
        lam, eps = self.system.scalars(X)
        wave = amplitude_point(self.system, X, self.a, its)
        return MassPoint(eps, wave, self.s, t_eps)

    def run(self, epsilon_end, max_steps=400):
        """Yield MassPoints until epsilon passes epsilon_end (or max_steps)."""
        for _ in range(max_steps):
            p = self.step()
            yield p
            if (p.epsilon - epsilon_end) * (self.model.masses[1] - epsilon_end) < 0 or p.epsilon <= 0:
                return

    def destroy(self):
        for X in self.points_X:
            X.destroy()
        if self.weights is not None:
            self.weights.destroy()
        self.solver.destroy()
        self.system.destroy()


def configure_options(comm, prefix=PRECOMP_PREFIX):
    """Read and check the options under ``prefix`` by configuring a bordered SNES on a small grid, for studies
    that build their solvers later (a bad value fails here, before any computation)."""
    from .grid import ProfileGrid
    system = BorderedWaveSystem(LatticeModel.hertz(1.5, delta0=1.0), ProfileGrid(max(8, 2 * comm.getSize() + 2), comm),
                                math.pi / 2)
    try:
        BorderedSolver(system, prefix).destroy()
    finally:
        system.destroy()
