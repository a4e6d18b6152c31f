"""The chain (eq. nc) on PETSc: state, right-hand side, exact Jacobian, energy balance, variational equations.

    m_n x_n'' = f_n - f_{n-1} - gamma x_n',    f_n = V'(x_{n+1} - x_n) + eta (x_{n+1}' - x_n'),

for the N beads of a :class:`~hertzpetsc.model.ChainSpec` (the law V', the masses m_n and the damping gamma, eta
are its lattice model's; gamma = eta = 0 is the paper's eq. nc; a contact dissipation adds its tension f_d(r, dv) to
f_n, :mod:`hertzpetsc.dissipation`) with periodic boundary conditions x_{n+N} = x_n
(eq. pbcl), or two ends: free (no bond beyond), a wall at rest (x = 0) or an actuator whose prescribed motion
x(t), x'(t) enters the bond to the first (last) bead -- the right-hand side, and through that bond's stiffness
the Jacobian, but it is not an unknown. The state X = (x_n, xdot_n)_n is a PETSc Vec on a 1-D DMDA (bead-major,
2 dof per bead, stencil width 1: nearest neighbours are a genuine stencil here).

With ``n_tangent = k`` the DMDA carries k tangent vectors Y_i = (y_n, ydot_n) next to X, and the right-hand
side is that of the variational equations Y' = Df(X) Y as well: one TS then integrates the flow and its
tangent-linear map together (the resolvent R(t; 0) of the paper's sections 3.4-3.5). The energy balance of
:meth:`Chain.power`: dE/dt = (input power of the actuators) - (dissipation).

Two chains reuse this one with other ghost rows: the Bloch cell, whose tangents satisfy y_{n+M} = e^{i theta} y_n
(:attr:`Chain.theta`, :attr:`Chain.complex_modes`; :class:`hertzpetsc.bloch.TwistedChain`), and the chain in
gap-lattice coordinates, whose bonds are r = gap + y_{n+1} - y_n (:attr:`Chain.gap`;
:func:`hertzpetsc.compacton_window.WindowChain`), where one bond may carry an extra length (:attr:`Chain.step`:
the beads behind it stored relative to their rest position, so that bonds closed by less than the positions'
round-off are computed without cancellation).

The right-hand side a TS calls is compiled (:mod:`hertzpetsc.kernels`) for the Hertz law, with or without the
contact dissipations of :mod:`hertzpetsc.dissipation`; :meth:`Chain.rhs_reference` is the same arithmetic in numpy
(any law, any damping; the reference the kernel is tested against).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np
from petsc4py import PETSc

from . import kernels
from .assembly import gathered
from .errors import (ConvergenceError, ParameterError, PetscFailure, callbacks_raise, check_instance, check_integer,
                     check_prefix, check_real)
from .dissipation import contact_exponent
from .model import Actuator, ChainSpec
from .options import user_set
from .resources import check_chain_size

# The options prefix of the TS of simulations (long runs, compactons on the chain); the refinement's and the
# Floquet analysis' flows have their own (shoot_, floquet_).
CHAIN_PREFIX = "chain_"
# The steps of a driven chain's flows are at most its actuators' time scale (ChainSpec.time_scale: a push's
# duration) over this: every push is sampled by several steps of 13 stages, so the error estimate sees it even
# when no bead touches the actuator before it starts (free flight is integrated exactly, and a step may otherwise
# grow across the whole push).
STEPS_PER_PUSH = 4
# The steps one integration over (t0, t1) may take unless -<prefix>ts_max_steps is given: MIN_STEPS plus
# STEP_LIMIT_FACTOR times the steps of the integrator's first step size, (t1 - t0) / dt0 (dt0 = -<prefix>ts_dt,
# 1e-3 by default; fixed-step runs take exactly (t1 - t0) / dt0). The flows of the test suite took at most 6.5 times
# that count (short Floquet intervals from dt0), most of them 20 to 70 times fewer steps; a flow whose step collapses
# (a state blowing up: max_t |x| to 1e10) fails with ConvergenceError instead of crawling for hours.
MIN_STEPS = 1000
STEP_LIMIT_FACTOR = 100
# PETSc's error code of an infinity or NaN met by a norm (PETSC_ERR_FP): a state that overflowed
OVERFLOW_ERROR = 72


@dataclass(frozen=True)
class IntegrationTolerances:
    """Adaptive time-stepping tolerances; the defaults are the paper's (rtol 1e-12, atol 1e-14)."""

    rtol: float = 1e-12
    atol: float = 1e-14

    def __post_init__(self):
        for name in ("rtol", "atol"):
            object.__setattr__(self, name, check_real(name, getattr(self, name), "the integration tolerance", 0.0))


class Chain:
    """eq. nc on a DMDA; the methods ``rhs`` and ``rhs_jacobian`` are TS callbacks."""

    def __init__(self, spec: ChainSpec, comm: PETSc.Comm, n_tangent: int = 0) -> None:
        if not isinstance(spec, ChainSpec):
            raise ParameterError("spec", spec, "must be a ChainSpec")
        self.comm = comm
        self.n_tangent = check_integer("n_tangent", n_tangent, 0, "the number of tangent vectors")
        check_chain_size(spec.N, 1 + self.n_tangent, "n_tangent" if self.n_tangent else "N")
        self.dof = 2 * (1 + self.n_tangent)
        periodic = spec.boundary == "periodic"
        bt = PETSc.DM.BoundaryType.PERIODIC if periodic else PETSc.DM.BoundaryType.GHOSTED
        if self.comm.getSize() > spec.N:
            raise ParameterError("N", spec.N, f"must be at least the number of ranks ({self.comm.getSize()})")
        self.da = PETSc.DMDA().create(dim=1, sizes=(spec.N,), dof=self.dof, stencil_width=1, boundary_type=(bt,),
                                      stencil_type=PETSc.DMDA.StencilType.STAR, comm=self.comm)
        self.da.setUp()
        (self.xs, self.xe), = self.da.getRanges()
        self.nloc = self.xe - self.xs
        self.local = self.da.createLocalVec()
        self.first = self.xs == 0 and not periodic
        self.last = self.xe == spec.N and not periodic
        self._take(spec)
        self._shift = None
        self._theta, self._complex_modes, self._gap, self._step = 0.0, False, 0.0, (-1, 0.0)
        # the compiled right-hand side: one law in every bond, which it evaluates exactly (the law says so: Hertz's
        # form), a contact dissipation it evaluates exactly (the dissipation says so: its power form) or none, and
        # this class's ghost rows (any other law, a bond pattern or another term, or a subclass that redefines the
        # ghost rows or the right-hand side, evaluates in numpy)
        contact = self.model.damping.contact
        compiled = self.model.law.kernel_form == "hertz" and self.model.bonds is None \
            and (contact is None or contact.kernel_form(self.model.law) is not None) \
            and type(self)._ghosted is Chain._ghosted and type(self).rhs_reference is Chain.rhs_reference
        lib = None if not compiled else kernels.library() if contact is None else kernels.contact_library()
        self.kernel = kernels.ChainKernel(self, lib) if lib is not None else None
        self._sync()

    def _take(self, spec):
        """The physics of ``spec`` on this layout: model, masses and the ends this rank touches."""
        self.spec = spec
        self.model = spec.model
        if spec.model.damping.contact is not None:
            contact_exponent(spec.model.law)          # a law with contacts, else a ParameterError
        # the ends this rank touches: ('free' | 'wall' | Actuator) or None inside the chain / periodic
        self.left_end = spec.left if self.first else None
        self.right_end = spec.right if self.last else None
        # 1/m_n of the owned beads, or None for unit masses (the paper's chain: no extra arithmetic)
        self.inverse_mass = None if self.model.uniform_masses else \
            1.0 / self.model.mass(np.arange(self.xs, self.xe))

    def set_spec(self, spec: ChainSpec) -> None:
        """Take another chain of the same layout (same N, boundary and kinds of ends; the Hertz parameters, masses,
        damping and the actuators' signals may differ): a continuation in a driving frequency, amplitude or damping
        changes the chain this way, without a new DMDA; the compiled kernel's context is updated in place (a TS
        that calls it directly keeps working)."""
        if not isinstance(spec, ChainSpec):
            raise ParameterError("spec", spec, "must be a ChainSpec")
        if spec.N != self.spec.N or spec.boundary != self.spec.boundary:
            raise ParameterError("spec", (spec.N, spec.boundary), f"must keep N = {self.spec.N} and boundary "
                                 f"{self.spec.boundary!r} (the layout of this chain)")
        kind = kernels.end_kind
        if (kind(spec.left), kind(spec.right)) != (kind(self.spec.left), kind(self.spec.right)) \
                or type(spec.model.law) is not type(self.model.law) \
                or (spec.model.bonds is None) != (self.model.bonds is None) \
                or type(spec.model.damping.contact) is not type(self.model.damping.contact):
            raise ParameterError("spec", spec, "must keep the kinds of the ends (free, wall, actuator), of the "
                                 f"law ({type(self.model.law).__name__}; one in every bond or a bond pattern) and of "
                                 "the contact dissipation of this chain")
        self._take(spec)
        if self.kernel is not None:
            self.kernel.set_physics(self)
        self._sync()

    # --- the ghost rows of the Bloch cell and of the gap lattice ------------------------------------------------
    @property
    def theta(self) -> float:
        """Bloch twist of the tangents across the seam of a periodic chain: y_{n+N} = e^{i theta} y_n (0: none)."""
        return self._theta

    @theta.setter
    def theta(self, value):
        self._theta = float(value)
        self._sync()

    @property
    def complex_modes(self) -> bool:
        """True: tangent 2p is the real part u, tangent 2p + 1 the imaginary part w of complex mode p (any theta);
        False: real tangents, twisted by cos theta (theta = 0 or pi)."""
        return self._complex_modes

    @complex_modes.setter
    def complex_modes(self, value):
        if value and self.n_tangent % 2:
            raise ParameterError("n_tangent", self.n_tangent, "complex modes need an even number of tangents")
        self._complex_modes = bool(value)
        self._sync()

    @property
    def gap(self) -> float:
        """Gap-lattice offset: bond n is r = gap + x_{n+1} - x_n (0: the lab frame)."""
        return self._gap

    @gap.setter
    def gap(self, value):
        self._gap = float(value)
        self._sync()

    @property
    def step(self) -> tuple[int, float]:
        """(bond b, length s): bond b (joining beads b, b + 1) is r = s + gap + x_{b+1} - x_b, i.e. beads 0..b are
        stored relative to a position s further back (b = -1: no step)."""
        return self._step

    @step.setter
    def step(self, value):
        b, s = value
        if not (isinstance(b, (int, np.integer)) and -1 <= b < self.spec.N - 1):
            raise ParameterError("step", b, f"the bond index must be in -1..{self.spec.N - 2}")
        self._step = (int(b), float(s) if b >= 0 else 0.0)
        self._sync()

    def _step_row(self):
        """The local index (ghosted numbering: bond i joins rows i, i + 1) of the step bond, or -1 off this rank."""
        i = self._step[0] - self.xs + 1
        return i if self._step[0] >= 0 and 0 <= i <= self.nloc else -1

    def _bonds(self, a):
        """Bond lengths r_i (nloc + 1) of the ghosted local rows ``a`` (gap included there), the step added."""
        r = a[1:, 0] - a[:-1, 0]
        i = self._step_row()
        if i >= 0:
            r[i] = r[i] + self._step[1]
        return r

    def bonds(self, values: np.ndarray) -> np.ndarray:
        """Bond lengths (N - 1) of a gathered state ``values`` (N, dof): gap + x_{n+1} - x_n, the step added."""
        r = self.gap + np.diff(np.asarray(values)[:, 0])
        if self._step[0] >= 0:
            r[self._step[0]] += self._step[1]
        return r

    def _sync(self):
        if self.kernel is not None:
            self.kernel.sync(self)

    # --- layout helpers ---------------------------------------------------------------------------------------
    def create_state(self) -> PETSc.Vec:
        return self.da.createGlobalVec()

    def _ghosted(self, X, t=None):
        """Local values with one ghost bead on each side, shape (nloc + 2, dof): the neighbours' values, or at an
        end the wall at rest (all zero) or the actuator's position and velocity at time t (zero tangents); the
        tangents of the ghost rows across a twisted seam multiplied by e^{-+i theta} (left, right); positions
        offset by gap * (local row index) in the gap lattice."""
        self.da.globalToLocal(X, self.local)
        a = self.local.getArray(readonly=True).reshape(self.nloc + 2, self.dof)
        if self.left_end in (None, "free") and self.right_end in (None, "free") and self.theta == 0.0 \
                and self.gap == 0.0:
            return a
        a = a.copy()
        for row, end in ((0, self.left_end), (-1, self.right_end)):
            if end == "wall":
                a[row] = 0.0
            elif isinstance(end, Actuator):
                tt = 0.0 if t is None else t
                a[row] = 0.0
                a[row, 0] = end.signal.position(tt)
                a[row, 1] = end.signal.velocity(tt)
        if self.theta != 0.0 and self.spec.boundary == "periodic":
            c, s = math.cos(self.theta), math.sin(self.theta)
            for row, sign, wraps in ((0, -1.0, self.xs == 0), (-1, 1.0, self.xe == self.spec.N)):
                if not wraps:
                    continue
                if not self.complex_modes:
                    a[row, 2:] *= c                                          # e^{+-i pi} = -1
                    continue
                modes = a[:, 2:].reshape(self.nloc + 2, self.n_tangent // 2, 2, 2)  # bead, mode, (u, w), (y, y')
                u, w = modes[row, :, 0, :].copy(), modes[row, :, 1, :].copy()
                modes[row, :, 0, :] = c * u - sign * s * w
                modes[row, :, 1, :] = sign * s * u + c * w
        if self.gap != 0.0:
            a[:, 0] += self.gap * np.arange(self.nloc + 2, dtype=float)
        return a

    def _bond_mask(self):
        """1 for bonds that carry a force, 0 for the missing bonds beyond free ends (bond i joins ghosted i, i+1)."""
        m = np.ones(self.nloc + 1)
        if self.left_end == "free":
            m[0] = 0.0
        if self.right_end == "free":
            m[-1] = 0.0
        return m

    # --- eq. nc and its variational equations -------------------------------------------------------------
    def rhs(self, ts: Optional[PETSc.TS], t: float, X: PETSc.Vec, F: PETSc.Vec) -> None:
        """F = f(t, X): eq. nc and, with tangents, its variational equations (a TS callback); compiled when the
        kernel is available (:mod:`hertzpetsc.kernels`), else :meth:`rhs_reference`."""
        if self.kernel is None:
            self.rhs_reference(ts, t, X, F)
            return
        self.kernel.set_time(t)                       # the actuators whose signals are evaluated in Python
        self.kernel(X, F, t)

    def rhs_reference(self, ts: Optional[PETSc.TS], t: float, X: PETSc.Vec, F: PETSc.Vec) -> None:
        """:meth:`rhs` in numpy, for any law: the reference of the compiled kernel (the same operations in the same
        order)."""
        a = self._ghosted(X, t)
        model = self.model
        r = self._bonds(a)                          # bond lengths x_{n+1} - x_n
        mask = self._bond_mask()
        bond = model.force(r, self.xs - 1) * mask     # r[i]: bond xs - 1 + i (its law: that bond's)
        contact = self._contact_terms(a, r, mask)
        if contact is not None:
            bond = bond + contact[0]
        out = F.getArray().reshape(self.nloc, self.dof)
        out[:, 0] = a[1:-1, 1]
        out[:, 1] = bond[1:] - bond[:-1]
        if self.n_tangent:
            stiff = (model.stiffness(r, self.xs - 1) * mask)[:, None]
            y = a[:, 2::2]                           # (nloc + 2, k) tangent displacements
            dy = y[1:] - y[:-1]
            out[:, 2::2] = a[1:-1, 3::2]
            if contact is not None:                  # the contacts' df/dr and df/d(dv) on the tangents
                stiff = stiff + contact[1][:, None]
                w = contact[2][:, None] * (a[1:, 3::2] - a[:-1, 3::2])
                out[:, 3::2] = stiff[1:] * dy[1:] - stiff[:-1] * dy[:-1] + (w[1:] - w[:-1])
            else:
                out[:, 3::2] = stiff[1:] * dy[1:] - stiff[:-1] * dy[:-1]
        if self.model.damped:                        # the state's and the tangents' velocities alike
            out[:, 1::2] += self._damping_forces(a[:, 1::2], mask)
        if self.inverse_mass is not None:
            out[:, 1::2] *= self.inverse_mass[:, None]

    def _contact_terms(self, a, r, mask):
        """(f_d, df_d/dr, df_d/d(dv)) of the bonds (nloc + 1) from the contact dissipation
        (:meth:`~hertzpetsc.dissipation.ContactDissipation.bond_terms`), or None without one; a: ghosted rows."""
        contact = self.model.damping.contact
        if contact is None:
            return None
        f, dfr, dfv = contact.bond_terms(self.model.law, r, a[1:, 1] - a[:-1, 1])
        return f * mask, dfr * mask, dfv * mask

    def _damping_forces(self, v, mask):
        """-gamma v_n + eta (dv_n - dv_{n-1}), dv the bonds' velocity differences (v: (nloc + 2, columns) ghosted
        velocities of the state and of the tangents, which obey the same linear terms)."""
        gamma, eta = self.model.damping.gamma, self.model.damping.eta
        out = -gamma * v[1:-1]
        if eta > 0.0:
            dv = (v[1:] - v[:-1]) * mask[:, None]
            out = out + eta * (dv[1:] - dv[:-1])
        return out

    def rhs_jacobian(self, ts: Optional[PETSc.TS], t: float, X: PETSc.Vec, J: PETSc.Mat, P: PETSc.Mat) -> None:
        """Exact Jacobian Df(X) of the chain (for implicit integrators); only for the chain without tangents.
        Assembled entry by entry: adequate for the chain lengths where implicit integration is used."""
        a = self._ghosted(X, t)
        r = self._bonds(a)
        mask = self._bond_mask()
        s = self.model.stiffness(r, self.xs - 1) * mask   # bond stiffness V''(x_{n+1} - x_n)
        inv = self.inverse_mass if self.inverse_mass is not None else np.ones(self.nloc)
        gamma, eta = self.model.damping.gamma, self.model.damping.eta
        e = eta * mask                                    # the bonds' df/d(dv): dashpots and contacts
        contact = self._contact_terms(a, r, mask)
        if contact is not None:
            s, e = s + contact[1], e + contact[2]
        N = self.spec.N
        n = np.arange(self.xs, self.xe)
        rows_v = 2 * n + 1
        left, right = (n - 1) % N, (n + 1) % N
        P.zeroEntries()
        for i in range(self.nloc):
            P.setValue(2 * n[i], rows_v[i], 1.0, addv=True)
            sl, sr = s[i] * inv[i], s[i + 1] * inv[i]
            el, er = e[i] * inv[i], e[i + 1] * inv[i]
            P.setValue(rows_v[i], 2 * n[i], -(sl + sr), addv=True)
            if gamma or eta or contact is not None:
                P.setValue(rows_v[i], 2 * n[i] + 1, -(gamma * inv[i] + el + er), addv=True)
            if not (self.first and i == 0):
                P.setValue(rows_v[i], 2 * left[i], sl, addv=True)
                if el:
                    P.setValue(rows_v[i], 2 * left[i] + 1, el, addv=True)
            if not (self.last and i == self.nloc - 1):
                P.setValue(rows_v[i], 2 * right[i], sr, addv=True)
                if er:
                    P.setValue(rows_v[i], 2 * right[i] + 1, er, addv=True)
        P.assemble()
        if J.handle != P.handle:
            J.assemble()

    def create_jacobian(self) -> PETSc.Mat:
        J = self.da.createMat()
        J.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        return J

    # --- diagnostics --------------------------------------------------------------------------------------
    def energy(self, X: PETSc.Vec, t: Optional[float] = None) -> float:
        """Total energy (eq. ham): sum of m v^2/2 and of V over the bonds, the bonds to walls and actuators
        included (their positions at time t)."""
        a = self._ghosted(X, t)
        r = self._bonds(a)
        Vb = self.model.potential(r, self.xs - 1) * self._bond_mask()
        # each rank counts the bonds to the right of its beads, plus the bond at the left end
        kinetic = a[1:-1, 1] ** 2 if self.inverse_mass is None else a[1:-1, 1] ** 2 / self.inverse_mass
        local = 0.5 * np.sum(kinetic) + np.sum(Vb[1:])
        if self.first:
            local += Vb[0]
        return self.comm.tompi4py().allreduce(float(local))

    def power(self, X: PETSc.Vec, t: Optional[float] = None) -> tuple[float, float]:
        """(input power of the actuators, dissipation rate) at the state X and time t, so that
        dE/dt = input - dissipation: input = -f_0 x_0' + f_N x_{N+1}' (f the bond forces V' + eta dv + f_d of the
        bonds to the actuators; f < 0 in compression), dissipation = gamma sum v^2 + sum over bonds (eta dv^2 +
        f_d dv), f_d the contact dissipation's tension (>= 0 power in every bond, clipped or not)."""
        a = self._ghosted(X, t)
        r = self._bonds(a)
        mask = self._bond_mask()
        v = a[:, 1]
        dv = (v[1:] - v[:-1]) * mask
        gamma, eta = self.model.damping.gamma, self.model.damping.eta
        f = self.model.force(r, self.xs - 1) * mask + eta * dv
        dissipation = gamma * np.sum(v[1:-1] ** 2) + eta * np.sum(dv[1:] ** 2)
        if self.first:
            dissipation += eta * dv[0] ** 2
        contact = self._contact_terms(a, r, mask)
        if contact is not None:                       # the contacts' tension f_d: power f_d dv >= 0 per bond
            f = f + contact[0]
            lost = contact[0] * dv
            dissipation += np.sum(lost[1:]) + (lost[0] if self.first else 0.0)
        power_in = 0.0
        if isinstance(self.left_end, Actuator):
            power_in -= f[0] * v[0]
        if isinstance(self.right_end, Actuator):
            power_in += f[-1] * v[-1]
        mpi = self.comm.tompi4py()
        return mpi.allreduce(float(power_in)), mpi.allreduce(float(dissipation))

    def velocity_trace(self, X: PETSc.Vec, t: Optional[float] = None) -> float:
        """tr of the velocity block d(x'')/d(x') of the Jacobian at X: -sum_n (gamma + e_{n-1} + e_n) / m_n, e the
        bonds' df/d(dv) (dashpots eta, contacts); d/dt log det R = this trace (Liouville), constant but for the
        contact dissipation."""
        a = self._ghosted(X, t)
        r = self._bonds(a)
        mask = self._bond_mask()
        e = self.model.damping.eta * mask
        contact = self._contact_terms(a, r, mask)
        if contact is not None:
            e = e + contact[2]
        inv = self.inverse_mass if self.inverse_mass is not None else np.ones(self.nloc)
        local = -float(np.sum((self.model.damping.gamma + e[:-1] + e[1:]) * inv))
        return self.comm.tompi4py().allreduce(local)

    # --- the spatial shift S X = (X_2, ..., X_N, X_1) of section 3.5 -------------------------------------------
    def shift(self, X: PETSc.Vec, out: PETSc.Vec) -> None:
        """out = S X (periodic chains): bead n of ``out`` holds bead n+c of ``X``, all dof, c the mass pattern's
        length (one bead for the paper's chain: S moves bead n+1 to bead n)."""
        if self.spec.boundary != "periodic":
            raise ParameterError("boundary", self.spec.boundary, "the shift S needs a periodic chain")
        if self._shift is None:
            N, d, c = self.spec.N, self.dof, self.model.cell
            src = ((np.arange(self.xs, self.xe)[:, None] + c) % N * d + np.arange(d)[None, :]).ravel()
            dst = (np.arange(self.xs, self.xe)[:, None] * d + np.arange(d)[None, :]).ravel()
            isf = PETSc.IS().createGeneral(src.astype(PETSc.IntType), comm=self.comm)
            ist = PETSc.IS().createGeneral(dst.astype(PETSc.IntType), comm=self.comm)
            self._shift = PETSc.Scatter().create(X, isf, out, ist)
            isf.destroy()
            ist.destroy()
        self._shift.scatter(X, out, PETSc.InsertMode.INSERT_VALUES, PETSc.ScatterMode.FORWARD)

    def gather(self, X: PETSc.Vec) -> np.ndarray:
        """The whole state as a numpy array of shape (N, dof) on every rank."""
        return gathered(X).reshape(self.spec.N, self.dof)

    def set_from_array(self, X: PETSc.Vec, values: np.ndarray) -> None:
        """Set X from a (N, dof) array given on every rank."""
        values = np.asarray(values, dtype=float).reshape(self.spec.N, self.dof)
        X.getArray()[:] = values[self.xs:self.xe].ravel()

    def destroy(self) -> None:
        if self._shift is not None:
            self._shift.destroy()
        if self.kernel is not None:
            self.kernel.destroy()
        self.local.destroy()
        self.da.destroy()


class ChainIntegrator:
    """PETSc TS for a chain, under the options prefix ``chain_`` (e.g. -chain_ts_type, -chain_ts_rk_type,
    -chain_ts_rtol). Default: adaptive explicit Runge-Kutta 8(7) (Verner), rtol 1e-12, atol 1e-14 as in the
    paper, steps matched to the final time. The right-hand side is the chain's compiled one; ``-chain_rhs_compiled
    0`` makes the TS call :meth:`Chain.rhs_reference` (numpy, the same numbers) instead."""

    def __init__(self, chain: Chain, tolerances: Optional[IntegrationTolerances] = None, prefix: str = CHAIN_PREFIX,
                 rk_type: str = "8vr") -> None:
        self.chain = check_instance("chain", chain, Chain, "a Chain")
        tol = IntegrationTolerances() if tolerances is None else \
            check_instance("tolerances", tolerances, IntegrationTolerances, "an IntegrationTolerances(rtol, atol)")
        check_prefix("prefix", prefix)
        check_instance("rk_type", rk_type, str, "a PETSc Runge-Kutta type such as '8vr'")
        ts = PETSc.TS().create(comm=chain.comm)
        ts.setOptionsPrefix(prefix)
        ts.setProblemType(PETSc.TS.ProblemType.NONLINEAR)
        ts.setType(PETSc.TS.Type.RK)
        try:
            ts.setRKType(rk_type)
        except PETSc.Error:
            ts.destroy()
            raise ParameterError("rk_type", rk_type, "is not a Runge-Kutta type of PETSc's TSRK (e.g. '8vr', "
                                 "'5dp', '4')") from None
        self._F = chain.create_state()
        # the compiled function, called by the TS itself unless an actuator's signal (any but Harmonic) needs Python:
        # then Chain.rhs; no kernel or -<prefix>rhs_compiled 0: Chain.rhs_reference
        self.compiled = False                 # the TS calls the compiled function itself (no Python per stage)
        if not PETSc.Options(prefix).getBool("rhs_compiled", True) or chain.kernel is None:
            ts.setRHSFunction(chain.rhs_reference, self._F)
        elif chain.kernel.needs_python:
            ts.setRHSFunction(chain.rhs, self._F)
        else:
            chain.kernel.install(ts, self._F)
            self.compiled = True
        if chain.n_tangent == 0:
            self._J = chain.create_jacobian()
            ts.setRHSJacobian(chain.rhs_jacobian, self._J, self._J)
        else:
            self._J = None
        ts.setTolerances(rtol=tol.rtol, atol=tol.atol)
        ts.setExactFinalTime(PETSc.TS.ExactFinalTime.MATCHSTEP)
        ts.setTimeStep(1e-3)
        ts.setFromOptions()
        self.initial_step = ts.getTimeStep()     # flows that measure something start from it every time
        # the step limit of each integration: -<prefix>ts_max_steps if given, else max_steps if set, else the budget
        # of MIN_STEPS and STEP_LIMIT_FACTOR
        self.user_max_steps = ts.getMaxSteps() if user_set(prefix, ("ts_max_steps",)) else None
        self.max_steps = None
        rtol, atol = ts.getTolerances()
        for name, value, what in (("rtol", rtol, "the integration tolerance"), ("atol", atol, "the integration "
                                  "tolerance"), ("dt", self.initial_step, "the first time step")):
            if not (value > 0 and math.isfinite(value)):
                ts.destroy()
                raise ParameterError(f"-{prefix}ts_{name}", value, f"{what} must be positive")
        self.ts = ts
        self.steps = 0
        # the largest step: -<prefix>ts_adapt_dt_max, or less on a driven chain (max_step)
        self._adapt = _TSAdapt(ts)
        self._dt_max = self._given_dt_max = self._adapt.dt_max()

    @property
    def max_step(self) -> float:
        """The largest step of the next integration: the chain's time scale (its actuators' shortest push,
        :attr:`~hertzpetsc.model.ChainSpec.time_scale`) over STEPS_PER_PUSH, or -<prefix>ts_adapt_dt_max if
        smaller; read at each integration (the chain's spec may have changed, :meth:`Chain.set_spec`)."""
        return min(self._given_dt_max, self.chain.spec.time_scale / STEPS_PER_PUSH)

    def control_components(self, state: Optional[tuple[float, float]] = None,
                           tangents: tuple[float, float] = (0.0, 0.0)) -> None:
        """Per-component tolerances (rtol, atol): ``state`` on x, x' (None: the TS's own), ``tangents`` on the tangent
        columns. Zeros leave the columns out of PETSc's weighted error norm: they are still the exact derivative of
        the steps taken (they move with the same Runge-Kutta formula), resolved as far as the state's steps resolve
        them: a Newton Jacobian's accuracy, never the multipliers'. Columns that start as unit vectors, given
        atol = rtol, are resolved to rtol in norm, which bounds the multipliers' error (times their condition)."""
        ts = self.ts
        rtol, atol = ts.getTolerances() if state is None else state
        vr, va = self.chain.create_state(), self.chain.create_state()
        r = vr.getArray().reshape(self.chain.nloc, self.chain.dof)
        a = va.getArray().reshape(self.chain.nloc, self.chain.dof)
        r[:], a[:] = tangents
        r[:, :2], a[:, :2] = rtol, atol
        ts.setTolerances(rtol=vr, atol=va)
        vr.destroy()
        va.destroy()

    @PETSc.Log.EventDecorator("hz_chain_integrate")
    def integrate(self, X: PETSc.Vec, t0: float, t1: float, dt: Optional[float] = None) -> int:
        """Advance X (in place) from t0 to t1; returns the number of steps. Raises ConvergenceError on failure.

        ``dt``: the first step (the integrator's :attr:`initial_step` for a measurement that must not depend on what
        ran before); None carries on with the step the last integration ended with (a simulation in intervals)."""
        if not t1 > t0:
            raise ParameterError("time", t1, f"the final time must exceed the initial time {t0}")
        hmax = self.max_step
        if hmax != self._dt_max:
            self._adapt.set_dt_max(hmax)
            self._dt_max = hmax
        if (self.ts.getTimeStep() if dt is None else dt) > hmax:     # the first step too
            dt = hmax
        ts = self.ts
        ts.setTime(t0)
        ts.setMaxTime(t1)
        ts.setStepNumber(0)
        limit = self.step_limit(t1 - t0)
        ts.setMaxSteps(limit)
        if dt is not None:
            ts.setTimeStep(dt)
        if self.compiled:                     # no Python during the solve: a signal ends it through the kernel
            kernels.watch_signals()
        try:
            with callbacks_raise():
                ts.solve(X)
        except PETSc.Error as err:
            if err.ierr != OVERFLOW_ERROR:
                raise
            # PETSc's norms of the steps saw an infinity or NaN (on every rank: the norm is collective)
            raise ConvergenceError("chain TS (prefix -%s)" % ts.getOptionsPrefix(), "the state overflowed: a force "
                                   "became infinite or NaN (an initial state or perturbation far too large?)",
                                   t=ts.getTime()) from None
        finally:
            if self.compiled:
                kernels.release_signals()
        reason = ts.getConvergedReason()
        prefix = ts.getOptionsPrefix()
        if reason < 0 or abs(ts.getTime() - t1) > 1e-12 * max(1.0, abs(t1)):
            if reason >= 0 and ts.getStepNumber() >= limit:
                reason = (f"the step limit of {limit} steps from t = {t0:.12g} to {t1:.12g}, last step "
                          f"{ts.getTimeStep():.3g}: the flow is too stiff or blows up; -{prefix}ts_max_steps raises it")
            raise ConvergenceError("chain TS (prefix -%s)" % prefix, reason if isinstance(reason, str) else int(reason),
                                   t=ts.getTime())
        n = ts.getStepNumber()
        self.steps += n
        return n

    def step_limit(self, interval: float) -> int:
        """The steps an integration over ``interval`` may take: -<prefix>ts_max_steps if given, else
        :attr:`max_steps` if set, else MIN_STEPS + STEP_LIMIT_FACTOR interval / dt0."""
        if self.user_max_steps is not None:
            return self.user_max_steps
        if self.max_steps is not None:
            return int(self.max_steps)
        return int(min(MIN_STEPS + STEP_LIMIT_FACTOR * interval / self.initial_step, 2 ** 31 - 1))

    def destroy(self) -> None:
        self.ts.destroy()
        self._F.destroy()
        if self._J is not None:
            self._J.destroy()


class _TSAdapt:
    """The step limits of a TS's TSAdapt (TSAdaptGet/SetStepLimits of libpetsc by ctypes: petsc4py 3.18 does not
    wrap TSAdapt). Adaptive steps are clipped to dt_max after every step, accepted or rejected."""

    _lib = None

    def __init__(self, ts):
        import ctypes
        if _TSAdapt._lib is None:
            lib = ctypes.CDLL(kernels.petsc_library())
            vp, dp = ctypes.c_void_p, ctypes.POINTER(ctypes.c_double)
            lib.TSGetAdapt.argtypes = [vp, ctypes.POINTER(vp)]
            lib.TSAdaptGetStepLimits.argtypes = [vp, dp, dp]
            lib.TSAdaptSetStepLimits.argtypes = [vp, ctypes.c_double, ctypes.c_double]
            _TSAdapt._lib = lib
        self._ctypes = ctypes
        self.handle = ctypes.c_void_p()
        self._call("TSGetAdapt", ctypes.c_void_p(ts.handle), ctypes.byref(self.handle))

    def _call(self, name, *args):
        ierr = getattr(self._lib, name)(*args)
        if ierr:
            raise PetscFailure(f"{name} failed (PETSc error code {ierr})")

    def dt_max(self):
        lo, hi = self._ctypes.c_double(), self._ctypes.c_double()
        self._call("TSAdaptGetStepLimits", self.handle, self._ctypes.byref(lo), self._ctypes.byref(hi))
        return hi.value

    def set_dt_max(self, hmax):
        self._call("TSAdaptSetStepLimits", self.handle, float(PETSc.DEFAULT), float(hmax))

