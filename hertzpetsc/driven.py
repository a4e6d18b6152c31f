"""Driven, damped chains: periodic responses by shooting, their Floquet multipliers and bifurcations (issue 22: the
question that closes the paper's Discussion -- how to generate periodic travelling waves from simple driving
signals in dissipative granular chains).

Beads n = 1..N of a :class:`~hertzpetsc.model.LatticeModel` (Hertz law with precompression delta0 >= 0, masses,
damping gamma, eta) between an actuator x_0(t) and a wall, a free end or a second actuator:

    m_n x_n'' = f_n - f_{n-1} - gamma x_n',    f_n = V'(x_{n+1} - x_n) + eta (x_{n+1}' - x_n')     (eq. nc + drive)

A :class:`Drive` holds the chain and its driving: a :class:`Waveform` (a shape of period 2 pi: :class:`HarmonicWave`
cos, :class:`HalfSinePulses`, :class:`SampledWave`, :class:`ProfileWave` = a travelling-wave profile of the branch,
eq. twper), an amplitude a >= 0 and a frequency omega > 0; changing a parameter gives a new Drive whose
:meth:`Drive.spec` is put on the existing chains by :meth:`~hertzpetsc.chain.Chain.set_spec` (no new DMDA).

A periodic response of period k 2 pi / omega is a fixed point of the map P = flow over [0, kT]:

    G(X; p) = P(X; p) - X = 0,

solved by :class:`PeriodicShooting`, a :class:`~hertzpetsc.continuation.ContinuationProblem` on the extended vector Z =
(X, p) (p = omega, amplitude or gamma, last entry on the last rank): Newton on SNES (prefix ``drive_``, the state flow
is the TS of the same prefix) with the bordered Jacobian [R(kT; 0) - I, dG/dp; row], R the monodromy from the tangent
flow (prefix ``floquet_``): dense from 2N tangent columns (``jacobian='dense'``, small N; LU, MUMPS on several ranks;
the state resolved to JACOBIAN_RTOL, reused as a chord while Newton contracts, CHORD_CONTRACTION) or matrix-free, one
tangent column per product (``jacobian='mf'``: GMRES, Newton-Krylov for long chains); the residuals of far iterates from
a looser state flow (INEXACT_FRACTION); dG/dp a forward difference with one state flow. So the continuation layer's
natural and pseudo-arclength algorithms (:mod:`hertzpetsc.continuation`) continue responses in omega or a through folds.

Floquet multipliers mu of a response are the eigenvalues of R(kT; 0): all 2N by LAPACK on the dense monodromy
(:class:`~hertzpetsc.floquet.DenseFloquet`, the tangents resolved too, the Newton Jacobian's where it is one), the
dominant ones by SLEPc Krylov-Schur on the matrix-free monodromy (:class:`~hertzpetsc.floquet.DominantFloquet`), or
every multiplier outside a radius r (``floquet='radius'``, long chains: the same solver with its region and stopping
test; r from ``-floquet_radius``, else :func:`default_radius`, halfway in log between the circle of a damped chain's
phonons (:func:`phonon_radius`) and the unit circle; a spectrum not closed outside r is a ConvergenceError,
'unresolved'). A
driven chain has no symmetry multipliers (the actuator breaks translation and time shift). Liouville: prod mu = det R =
exp(-kT tr(M^-1 C)), C the damping matrix (:func:`damping_trace`), and without dashpots R^T J R = e^{-c kT} J
(:func:`conformal_rate`); with contact dissipation (a damping that depends on the state) log det R = int tr Df dt
along the orbit (:func:`~hertzpetsc.tangent.liouville_integral`) and no symplecticity: checked on every monodromy before its multipliers are used (:func:`check_monodromy`; the
dominant pairs against an independent flow, :func:`check_eigenpairs`), a failure a ConvergenceError. Every flow's
steps are at most a quarter of the drive's shortest push (:attr:`Waveform` signals' ``time_scale``,
:attr:`~hertzpetsc.chain.ChainIntegrator.max_step`): a push that no bead feels yet is invisible to a step's error
estimate. The test functions of the layer are

    period doubling:   tau_PD = prod (1 + mu_i)              (a real multiplier through -1)
    Neimark-Sacker:    tau_NS = prod_{i<j} (mu_i mu_j - 1)   (a complex pair through the unit circle; also
                                                             neutral saddles mu_i mu_j = 1, told apart by
                                                             :func:`crossing`)

each reported as sign(tau) times its smallest factor's modulus (same zeros, linear near them, no overflow). Folds
are the layer's (dp/ds changes sign). :func:`crossing` compares the multipliers on both sides of an event (what
crossed where).
"""
from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Iterator, Optional

import numpy as np
from mpi4py import MPI
from numpy.typing import ArrayLike
from petsc4py import PETSc

from .assembly import gathered
from .chain import Chain, ChainIntegrator, IntegrationTolerances
from .continuation import ContinuationProblem, _parameter, golden_maximum, set_parameter
from .errors import ConvergenceError, ParameterError, callbacks_raise, check_integer, check_real
from .floquet import FLOQUET_PREFIX, DenseFloquet, DominantFloquet, dense_multipliers
from .resources import MAX_DENSE_BEADS, check_chain_memory
from .model import Actuator, ChainSpec, Harmonic, LatticeModel, SampledSignal, Signal
from .options import user_set
from .tangent import MonodromyModShift, TangentFlow, liouville_integral

DRIVE_PREFIX = "drive_"
# The flows of the responses: the paper's tolerances (state, residual of the shooting).
RESPONSE_TOLERANCES = IntegrationTolerances(rtol=1e-12, atol=1e-14)
PARAMETERS = ("omega", "amplitude", "gamma")
# A chord step (the Jacobian of an earlier point) is kept while it reduces the residual at least this much: a fresh
# Jacobian costs a flow with 2N tangent columns, a chord iteration one state flow.
CHORD_CONTRACTION = 0.25
# The Newton Jacobian's flow resolves the state to this rtol (or the flows' own, if looser): a Jacobian of relative
# error e makes a Newton step contract by about e cond(R - I) besides its own convergence, far below the chord's.
JACOBIAN_RTOL = 1e-8
# Inexact Newton: the residual of an iterate is evaluated with the state flow at rtol INEXACT_FRACTION f^2 / (2 n)
# (f: the corrector's last relative residual, f^2 a quadratic prediction of this one's; n: the last flow's steps),
# within [the flow's rtol, JACOBIAN_RTOL], and again at the flow's own rtol when rtol n (the global error if every
# step errs by rtol) exceeds INEXACT_FRACTION times the residual it measured: every accepted evaluation is resolved
# to a fraction of its size, the converged one to the flow's tolerance.
INEXACT_FRACTION = 1e-1
# Steps a state flow over one driving period may take before it counts as failed (-drive_ts_max_steps overrides).
MAX_STEPS_PER_FLOW = 200000
JACOBIANS = ("dense", "mf")
FLOQUET_METHODS = ("dense", "slepc", "radius", "none")
# Multipliers within this distance of the unit circle are 'neutral' (the default resolution of the verdicts; the
# measured one, from a looser flow, is ResponseFloquet.resolution).
TOL_MU = 1e-6


def _one_of(name, value, choices, what="must be one of"):
    if value not in choices:
        raise ParameterError(name, value, f"{what} " + ", ".join(choices))


def singular_factor(err):
    """Whether a PETSc.Error is the LU factorisation of a singular matrix: a zero pivot (PETSC_ERR_MAT_LU_ZRPVT,
    LAPACK on one rank) or MUMPS failing on it (several ranks)."""
    from .options import petsc_message
    code = getattr(err, "ierr", None)
    return code == 71 or (code == 76 and "MUMPS" in petsc_message(err))


# --- waveforms: the actuator's motion as a shape of period 2 pi ---------------------------------------------------

class Waveform:
    """A 2 pi-periodic shape w(theta); :meth:`signal` gives the actuator's motion x(t) = a w(omega t + phase)."""

    name = "waveform"

    def signal(self, amplitude: float, omega: float, phase: float = 0.0) -> Signal:
        raise NotImplementedError

    def describe(self) -> dict:
        return dict(waveform=self.name)


@dataclass(frozen=True)
class HarmonicWave(Waveform):
    """w = cos: the actuator x(t) = a cos(omega t + phase) (Pozharskiy et al., Phys. Rev. E 92, 063203 (2015))."""

    name = "harmonic"

    def signal(self, amplitude: float, omega: float, phase: float = 0.0) -> Harmonic:
        return Harmonic(amplitude, omega, phase)


class HalfSineSignal(Signal):
    """A periodic train of half-sine pulses: x = a sin(pi s / w) for s = (t mod P) < w, else 0 (w = width P)."""

    def __init__(self, amplitude, omega, width, phase=0.0):
        self.amplitude, self.omega, self.width, self.phase = amplitude, omega, width, phase
        self.period = 2 * math.pi / omega
        self._w = 2 * math.pi * width          # the pulse's duration in phase

    @property
    def time_scale(self):
        """The pulse's duration."""
        return self.width * self.period

    def _pulse(self, t):
        """(whether the times t fall in a pulse, the pulse's phase pi s / w there)."""
        th = np.mod(self.omega * np.asarray(t, float) + self.phase, 2 * math.pi)
        return th < self._w, math.pi * np.minimum(th, self._w) / self._w

    def position(self, t):
        on, s = self._pulse(t)
        return np.where(on, self.amplitude * np.sin(s), 0.0)

    def velocity(self, t):
        on, s = self._pulse(t)
        return np.where(on, self.amplitude * self.omega * math.pi / self._w * np.cos(s), 0.0)

    def describe(self):
        return dict(signal="half_sine", amplitude=self.amplitude, omega=self.omega, width=self.width,
                    phase=self.phase)


@dataclass(frozen=True)
class HalfSinePulses(Waveform):
    """A train of half-sine pushes of duration ``width`` periods (0 < width <= 1; 1/2: the positive half of a sine,
    the actuator at rest the other half): the simplest impulsive driving of a chain."""

    width: float = 0.5
    name = "half_sine"

    def __post_init__(self):
        object.__setattr__(self, "width", check_real("width", self.width, "the pulse width (a fraction of the period)",
                                                0.0, 1.0, hi_open=False))

    def signal(self, amplitude: float, omega: float, phase: float = 0.0) -> HalfSineSignal:
        return HalfSineSignal(amplitude, omega, self.width, phase)

    def describe(self) -> dict:
        return dict(waveform=self.name, width=self.width)


@dataclass(frozen=True)
class SampledWave(Waveform):
    """A shape given by samples over one closed period, w(2 pi j / n) for j = 0..n (the last sample closes the
    period and must equal the first: a signal that is not periodic with its period is refused); evaluated by the
    trigonometric interpolant of the first n (:class:`~hertzpetsc.model.SampledSignal`)."""

    samples: tuple
    name = "samples"

    def __post_init__(self):
        try:
            s = np.asarray(self.samples, dtype=float).ravel()
        except (TypeError, ValueError):
            raise ParameterError("samples", self.samples, "must be a list of real numbers") from None
        if len(s) < 3 or not np.all(np.isfinite(s)):
            raise ParameterError("samples", len(s), "at least 3 finite samples over one closed period")
        scale = max(1.0, float(np.max(np.abs(s))))
        if abs(s[-1] - s[0]) > 1e-12 * scale:
            raise ParameterError("samples", f"first {s[0]:g}, last {s[-1]:g}", "the signal is not periodic with its "
                                 "period: the last sample closes the period and must equal the first")
        object.__setattr__(self, "samples", tuple(float(v) for v in s))

    def signal(self, amplitude: float, omega: float, phase: float = 0.0) -> SampledSignal:
        if phase != 0.0:
            raise ParameterError("phase", phase, "a sampled waveform starts at its first sample (phase 0)")
        return SampledSignal(tuple(amplitude * v for v in self.samples[:-1]), 2 * math.pi / omega)

    def describe(self) -> dict:
        return dict(waveform=self.name, samples=list(self.samples))


class ProfileSignal(Signal):
    """x(t) = a U(phase - omega t) for a 2 pi-periodic profile U tabulated on a uniform grid, by the degree-5
    piecewise Lagrange interpolant of :func:`~hertzpetsc.stencil.lagrange_periodic` held as per-cell polynomial
    coefficients (one cell lookup and Horner's rule per call: the right-hand side evaluates it at every stage);
    ``push``: the phase interval of the profile's shortest push (:func:`push_width`)."""

    def __init__(self, coefficients, h, amplitude, omega, phase=0.0, push=2 * math.pi):
        self.c, self.h = coefficients, h
        self.amplitude, self.omega, self.phase = amplitude, omega, phase
        self.period = 2 * math.pi / omega
        self.n = len(coefficients)
        self.push = push

    @property
    def time_scale(self):
        """The duration of the profile's shortest push."""
        return self.push / self.omega

    def _cell(self, t):
        xi = np.mod(self.phase - self.omega * np.asarray(t, float), 2 * math.pi) / self.h
        j = np.minimum(np.floor(xi).astype(np.int64), self.n - 1)
        return self.c[j], xi - j

    def position(self, t):
        c, s = self._cell(t)
        c = np.moveaxis(c, -1, 0)
        out = c[5]
        for k in range(4, -1, -1):
            out = out * s + c[k]
        return self.amplitude * out

    def velocity(self, t):
        c, s = self._cell(t)
        c = np.moveaxis(c, -1, 0)
        out = 5 * c[5]
        for k in range(4, 0, -1):
            out = out * s + k * c[k]
        return -self.amplitude * self.omega * out / self.h

    def describe(self):
        return dict(signal="profile", amplitude=self.amplitude, omega=self.omega, phase=self.phase, cells=self.n)


# Coefficients of the degree-5 interpolant through the nodes s = -2..3 of a cell (s in [0, 1)): c = V^-1 values.
_NODES = np.arange(-2, 4)
_VINV = np.linalg.inv(np.vander(_NODES, 6, increasing=True))
# A profile pushes where its acceleration |U''| exceeds this fraction of its largest (a wave of the uncompressed
# chain: zero in free flight, the bonds' forces in contact; the profile's own noise is some 1e-6 of it).
PUSH_THRESHOLD = 1e-3


def push_width(values):
    """The phase length of the shortest interval where the 2 pi-periodic profile ``values`` (uniform grid) pushes:
    |U''| > PUSH_THRESHOLD max |U''| (second differences); a half period for a profile whose acceleration changes
    sign as a sinusoid's, 2 pi if it never falls below the threshold."""
    u = np.asarray(values, float)
    n = len(u)
    d2 = np.abs(np.roll(u, -1) - 2 * u + np.roll(u, 1))
    on = d2 > PUSH_THRESHOLD * np.max(d2)
    if on.all() or not on.any():
        return 2 * math.pi
    on = np.roll(on, -int(np.argmin(on)))          # start outside a push: no run wraps around
    edges = np.flatnonzero(np.diff(np.concatenate(([0], on.astype(np.int8), [0]))))
    return 2 * math.pi / n * float(np.min(edges[1::2] - edges[::2]))


class ProfileWave(Waveform):
    """A travelling-wave profile U of period 2 pi as a waveform: x(t) = a U(phase - omega t), the motion of bead n
    of the wave x_n(t) = a U(q n - omega t) (eq. twper) at phase = q n. ``values``: U on the uniform grid
    j 2 pi / n, j = 0..n-1."""

    name = "profile"

    def __init__(self, values: ArrayLike, label: str = "profile") -> None:
        u = np.asarray(values, dtype=float).ravel()
        if len(u) < 6 or not np.all(np.isfinite(u)):
            raise ParameterError("profile", len(u), "at least 6 finite values over one period")
        self.values, self.label = u, label
        self.h = 2 * math.pi / len(u)
        idx = (np.arange(len(u))[:, None] + _NODES[None, :]) % len(u)
        self.coefficients = u[idx] @ _VINV.T
        self.push = push_width(u)

    def signal(self, amplitude: float, omega: float, phase: float = 0.0) -> ProfileSignal:
        return ProfileSignal(self.coefficients, self.h, amplitude, omega, float(phase), self.push)

    def describe(self) -> dict:
        return dict(waveform=self.name, label=self.label, cells=len(self.values))


# --- the driven chain -------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Drive:
    """N beads of ``model`` driven at the left by ``waveform`` with ``amplitude`` and frequency ``omega``; the
    right end is 'wall', 'free' or a second :class:`Waveform` (same amplitude and frequency, ``right_phase``)."""

    model: LatticeModel
    N: int
    waveform: Waveform
    amplitude: float
    omega: float
    right: object = "wall"
    left_phase: float = 0.0
    right_phase: float = 0.0

    def __post_init__(self):
        if not isinstance(self.model, LatticeModel):
            raise ParameterError("model", self.model, "must be a LatticeModel")
        object.__setattr__(self, "N", check_integer("N", self.N, 1, "the number of beads"))
        if not isinstance(self.waveform, Waveform):
            raise ParameterError("waveform", self.waveform, "must be a Waveform (harmonic, half_sine, samples, "
                                 "profile)")
        object.__setattr__(self, "amplitude", check_real("amplitude", self.amplitude, "the actuator amplitude", 0.0,
                                                    lo_open=False))
        object.__setattr__(self, "omega", check_real("omega", self.omega, "the driving frequency", 0.0))
        if not (self.right in ("wall", "free") or isinstance(self.right, Waveform)):
            raise ParameterError("right", self.right, "the far end is 'wall', 'free' or a Waveform (second actuator)")
        for name in ("left_phase", "right_phase"):
            object.__setattr__(self, name, check_real(name, getattr(self, name), "the actuator's phase"))

    @property
    def period(self) -> float:
        return 2 * math.pi / self.omega

    @property
    def gamma(self) -> float:
        return self.model.damping.gamma

    def spec(self) -> ChainSpec:
        """The :class:`~hertzpetsc.model.ChainSpec` of this drive (actuators with their signals)."""
        left = Actuator(self.waveform.signal(self.amplitude, self.omega, self.left_phase))
        right = self.right if isinstance(self.right, str) else \
            Actuator(self.right.signal(self.amplitude, self.omega, self.right_phase))
        return ChainSpec(self.model, int(self.N), "fixed", left=left, right=right)

    def value(self, name: str) -> float:
        """The parameter ``name`` (omega, amplitude, gamma)."""
        _check_parameter(name)
        return self.gamma if name == "gamma" else getattr(self, name)

    def with_parameter(self, name: str, value: float) -> Drive:
        """The same drive with parameter ``name`` (omega, amplitude or gamma) set to ``value``."""
        _check_parameter(name)
        if name == "gamma":
            return replace(self, model=self.model.with_damping(value, self.model.damping.eta))
        return replace(self, **{name: value})

    def describe(self) -> dict:
        out = dict(self.model.describe(), N=int(self.N), amplitude=self.amplitude, omega=self.omega,
                   **self.waveform.describe())
        out["right"] = self.right if isinstance(self.right, str) else dict(self.right.describe(),
                                                                            phase=self.right_phase)
        return out


def check_dense_beads(N, jacobian, floquet):
    """Whether the dense routes are used (``jacobian`` or ``floquet`` 'dense'); ParameterError naming N when the chain
    is longer than they allow (LAPACK on 2N x 2N matrices cannot be interrupted: its size is bounded instead)."""
    dense = "dense" in (jacobian, floquet)
    if dense and N > MAX_DENSE_BEADS:
        raise ParameterError("N", N, f"at most {MAX_DENSE_BEADS} beads with the dense Jacobian or dense "
                             "multipliers (2N x 2N matrices); longer chains: jacobian 'mf', floquet 'slepc' or 'none'")
    return dense


def _check_parameter(name):
    _one_of("parameter", name, PARAMETERS, "the continuation parameter is one of")


def damping_trace(spec):
    """tr(M^-1 C) of the chain's damping matrix: sum_n (gamma + eta d_n) / m_n, d_n the dashpots at bead n (2
    inside, 1 next to a free end): d/dt log det R = -tr(M^-1 C) (Liouville), so det R(T; 0) = exp(-T tr)."""
    m, deg = spec.model, np.full(spec.N, 2.0)
    if spec.boundary != "periodic":
        deg[0] -= spec.left == "free"
        deg[-1] -= spec.right == "free"
    return float(np.sum((m.damping.gamma + m.damping.eta * deg) / m.mass(np.arange(spec.N))))


def phonon_radius(spec, T):
    """exp(-gamma T / (2 m_max)): the largest modulus of the multipliers of the underdamped phonons of the chain
    linearised about rest with its on-site damping gamma (dashpots and contact dissipation damp them further; the
    overdamped long waves are real multipliers nearer 1), the circle the multipliers of a long driven chain crowd on
    (its part far from the actuator is at rest). 1 without on-site damping."""
    return math.exp(-0.5 * T * spec.model.damping.gamma / float(np.max(spec.model.mass(np.arange(spec.model.cell)))))


def default_radius(spec, T):
    """The radius r of the multipliers wanted outside (``floquet='radius'``): sqrt(:func:`phonon_radius`), halfway
    in log between the phonons' circle and the unit circle (e^{-gamma T / 4} with uniform masses). 1 for a chain
    without on-site damping: then every multiplier outside the unit circle, and -floquet_radius must exceed 1."""
    return math.sqrt(phonon_radius(spec, T))


def conformal_rate(spec):
    """c with R^T J_M R = e^{-c T} J_M for the monodromy of ``spec`` (J_M the symplectic form sum_n m_n dx_n ^ dv_n):
    0 undamped, gamma / m for on-site damping with uniform masses (y = e^{-c t / 2} z makes the variational
    equation Hamiltonian); None where the flow is not conformally symplectic (dashpots between beads, on-site damping
    with unequal masses, contact dissipation)."""
    model = spec.model
    if model.damping.eta != 0.0 or model.damping.contact is not None or \
            (model.damping.gamma != 0.0 and not model.uniform_masses):
        return None
    return model.damping.gamma / float(model.mass(np.arange(1))[0])


def check_monodromy(R, spec, T, rtol, steps, where, trace=None):
    """The closed forms of a dense monodromy R = R(T; 0) of ``spec``, resolved to ``steps`` rtol relative in
    Frobenius norm (2N columns started as unit vectors, each step erring by at most rtol): Liouville, log det R =
    -T tr(M^-1 C) (:func:`damping_trace`), to steps rtol ||R||_F ||R^-1||_F (|tr(R^-1 dR)| <= ||R^-1||_F ||dR||_F),
    with det R > 0; and where the flow is conformally symplectic (:func:`conformal_rate`), R^T J_M R = e^{-c T}
    J_M to 2 steps rtol ||J_M|| ||R||_F^2. With contact dissipation the damping depends on the state: no closed form
    and no symplecticity; ``trace`` = (int_0^T tr Df dt, its error) along the orbit
    (:func:`~hertzpetsc.tangent.liouville_integral`) replaces -T tr(M^-1 C), the bound widened by three times its
    error. A ConvergenceError naming the check, its value and its bound, at ``where`` (the parameter), otherwise: the
    multipliers of a flow that jumped a push of the drive, or did not resolve its contacts, are not the response's."""
    what = "the multipliers' tangent flow (prefix -floquet_)"
    sign, logdet = np.linalg.slogdet(R)
    norm = np.linalg.norm(R)
    bound = steps * rtol * norm * (np.linalg.norm(np.linalg.inv(R)) if sign != 0 else math.inf)
    if spec.model.damping.contact is None:
        exact, form = -T * damping_trace(spec), "closed form exp(-T tr(M^-1 C))"
    elif trace is None:
        raise ParameterError("trace", None, "the Liouville check of a chain with contact dissipation needs the "
                             "integral of tr Df along the orbit (tangent.liouville_integral)")
    else:
        exact, form = trace[0], "exp(int tr Df dt) along the orbit"
        bound += 3.0 * trace[1]
    if not (sign > 0 and abs(logdet - exact) <= bound):
        raise ConvergenceError(what, f"Liouville: det R = {sign * math.exp(logdet) if sign else 0.0:.6g}, {form} = "
                               f"{math.exp(exact):.6g} (log det off by "
                               f"{abs(logdet - exact):.2g} > {bound:.2g}, {steps} steps at rtol {rtol:.0e})", **where)
    c = conformal_rate(spec)
    if c is not None:
        m = spec.model.mass(np.arange(spec.N))
        JR = np.empty_like(R)                  # J_M R: rows (x_n, v_n) -> (m_n v_n, -m_n x_n)
        JR[0::2], JR[1::2] = m[:, None] * R[1::2], -m[:, None] * R[0::2]
        defect = R.T @ JR
        defect[0::2, 1::2] -= math.exp(-c * T) * np.diag(m)
        defect[1::2, 0::2] += math.exp(-c * T) * np.diag(m)
        size, bound = np.linalg.norm(defect), 2 * steps * rtol * float(np.max(m)) * norm ** 2
        if not size <= bound:
            raise ConvergenceError(what, f"symplecticity: ||R^T J R - e^(-cT) J|| = {size:.2g} > {bound:.2g} "
                                   f"(c = {c:g}, {steps} steps at rtol {rtol:.0e})", **where)


def check_eigenpairs(op, mu, vectors, spec, T, where, tol=TOL_MU):
    """The dominant multipliers mu (SLEPc on the matrix-free monodromy, no determinant to check) against an
    independent flow: R v for all the eigenvectors in one integration (:meth:`~hertzpetsc.tangent.MonodromyModShift.
    apply`, its steps controlled on all the columns at once, not on one as the Krylov products'), each relative
    residual ||R v - mu v|| / (|mu| ||v||) within ``tol`` (the verdicts' resolution); and where the flow is
    conformally symplectic (:func:`conformal_rate`, multipliers in pairs of product e^{-c T}) the largest at least
    e^{-c T / 2} (1 - tol). A ConvergenceError naming the check otherwise."""
    what = "the multipliers' tangent flow and eigensolver (prefix -floquet_)"
    mu = np.asarray(mu, complex)
    V = np.asarray(vectors, complex)
    N, k = spec.N, V.shape[1]
    if not k:                                  # the radius route found nothing outside its radius
        return
    RY = op.apply(np.concatenate([V.real, V.imag], axis=1).reshape(N, 2, 2 * k)).reshape(2 * N, 2 * k)
    res = np.linalg.norm(RY[:, :k] + 1j * RY[:, k:] - V * mu, axis=0) / (np.abs(mu) * np.linalg.norm(V, axis=0))
    worst = int(np.argmax(res))
    if not res[worst] <= tol:
        raise ConvergenceError(what, f"eigen-residual on an independent flow: ||R v - mu v|| / |mu| ||v|| = "
                               f"{res[worst]:.2g} > {tol:.0e} for mu = {mu[worst]:.8g}", **where)
    c = conformal_rate(spec)
    if c is not None and k and not np.max(np.abs(mu)) >= math.exp(-0.5 * c * T) * (1 - tol):
        raise ConvergenceError(what, f"symplecticity: rho = {np.max(np.abs(mu)):.8g} < e^(-cT/2) = "
                               f"{math.exp(-0.5 * c * T):.8g} (multipliers in pairs of product e^(-cT), c = {c:g})",
                               **where)


# --- the response and its multipliers ---------------------------------------------------------------------------
@dataclass
class Response:
    """A periodic response: the drive, k (period k 2 pi / omega), the state X(0) as (N, 2) on every rank, the
    relative residual ||P(X) - X||_inf / scale and Newton's iterations; from :func:`hertzpetsc.api.response` also
    its ``multipliers`` (sorted by decreasing modulus: all 2N, or the dominant ones; None: not computed) and its
    ``record`` (the fields of a ``hertzpetsc-driven-response-1`` record: forces, amplitudes, power balance, ...)."""

    drive: Drive
    periods: int
    x: np.ndarray
    residual: float
    iterations: int = 0
    multipliers: Optional[np.ndarray] = None
    record: Optional[dict] = None

    @property
    def omega(self) -> float:
        """The driving frequency."""
        return self.drive.omega

    @property
    def rho(self) -> float:
        """The largest multiplier modulus (nan without multipliers): stable below 1 (:func:`verdict`)."""
        return float(np.max(np.abs(self.multipliers))) if self.multipliers is not None and len(self.multipliers) \
            else math.nan

    @property
    def T(self) -> float:
        """The response's period k 2 pi / omega (the time of the monodromy)."""
        return self.periods * self.drive.period

    @property
    def N(self) -> int:
        """The chain's number of beads."""
        return self.drive.N


def _peak(f):
    """(position, value) of the maximum of periodic samples f, refined by the parabola through it and its two
    neighbours."""
    f = np.asarray(f, float)
    k = int(np.argmax(f))
    a, b, c = f[k - 1], f[k], f[(k + 1) % len(f)]
    den = a - 2 * b + c
    return (k + 0.5 * (a - c) / den, float(b - 0.125 * (a - c) ** 2 / den)) if den < 0 else (k, float(b))


def verdict(rho, tol=TOL_MU):
    """'unstable' (rho > 1 + tol), 'stable' (rho < 1 - tol) or 'neutral' (within the resolution of the circle)."""
    return "unstable" if rho > 1 + tol else "stable" if rho < 1 - tol else "neutral"


def _signed_min(values):
    """sign(prod v) min |v|: the product's sign and zeros (a product over a conjugation-closed set is real), but
    linear near a simple zero (the factor that vanishes is the smallest) and free of overflow."""
    v = np.asarray(values, dtype=complex)
    if not len(v):
        return 1.0
    mag = np.abs(v)
    if not np.all(mag > 0):
        return 0.0
    return float(np.sign(np.prod(v / mag).real) * np.min(mag))


def test_functions(mu, partial=False):
    """{'period_doubling': tau_PD, 'neimark_sacker': tau_NS} of the multipliers ``mu`` (module docstring).
    ``partial``: ``mu`` are the multipliers outside a radius r < 1, a set that changes along a curve; tau_NS then has
    the factors 1 - mu_i mu_j (the same zeros), so that a multiplier entering the set (|mu| = r: a complex pair's
    own factor 1 - r^2 > 0, its others |1 - mu mu_j|^2 > 0) does not change its sign."""
    mu = np.asarray(mu, dtype=complex)
    i, j = np.triu_indices(len(mu), 1)
    ns = 1.0 - mu[i] * mu[j] if partial else mu[i] * mu[j] - 1.0
    return {"period_doubling": _signed_min(1.0 + mu), "neimark_sacker": _signed_min(ns)}


def neutral_saddle(mu):
    """Whether the factor of tau_NS nearest zero, mu_i mu_j - 1, is that of two real multipliers (a neutral saddle:
    mu and 1/mu, nothing on the unit circle) rather than of a complex pair (|mu|^2 = 1: Neimark-Sacker)."""
    mu = np.asarray(mu, dtype=complex)
    mu = mu[mu != 0]                       # zero padding of stored spectra
    if len(mu) < 2:
        return False
    i, j = np.triu_indices(len(mu), 1)
    k = int(np.argmin(np.abs(mu[i] * mu[j] - 1.0)))
    real = np.abs(mu.imag) <= 1e-9 * np.maximum(1.0, np.abs(mu))
    return bool(real[i[k]] and real[j[k]])


def counts(mu, tol=TOL_MU):
    """Multipliers outside the unit circle by kind: real > 1, real < -1, complex (counted singly)."""
    mu = np.asarray(mu, dtype=complex)
    out = np.abs(mu) > 1 + tol
    real = np.abs(mu.imag) <= 1e-9 * np.maximum(1.0, np.abs(mu))
    return dict(real_plus=int(np.sum(out & real & (mu.real > 0))), real_minus=int(np.sum(out & real & (mu.real < 0))),
                complex=int(np.sum(out & ~real)))


def crossing(mu_before, mu_after, tol=TOL_MU):
    """What crossed the unit circle between two spectra: 'fold' (a real multiplier through +1), 'period_doubling'
    (through -1), 'neimark_sacker' (a complex pair), None if nothing, 'several' if more than one kind."""
    a, b = counts(mu_before, tol), counts(mu_after, tol)
    kinds = [name for k, name in (("real_plus", "fold"), ("real_minus", "period_doubling"),
                                  ("complex", "neimark_sacker")) if a[k] != b[k]]
    if not kinds:
        return None
    return kinds[0] if len(kinds) == 1 else "several"


# --- the shooting problem -------------------------------------------------------------------------------------------
class PeriodicShooting(ContinuationProblem):
    """G(X; p) = P(X; p) - X for the responses of period k 2 pi / omega of one driven chain, as a continuation
    problem in ``parameter`` (omega, amplitude or gamma) with one corrector :meth:`solve` (SNES, prefix ``drive_``).

    ``jacobian``: 'dense' (R from 2N tangent columns, LU) or 'mf' (tangent-flow products, GMRES); ``floquet``:
    multipliers for the test functions and reports, 'dense' (all 2N, the Jacobian's monodromy), 'slepc' (``nev``
    dominant ones), 'radius' (every one outside a radius: :func:`default_radius` or ``-floquet_radius``, at most
    ``nev``) or 'none'. ``tol``: the shooting tolerance on ||G||_inf / max(||X||_inf, amplitude).
    ``inexact``: the residuals of iterates far from the response from a looser state flow (:meth:`_evaluation_rtol`).
    """

    def __init__(self, drive: Drive, comm: PETSc.Comm, parameter: str = "omega", periods: int = 1,
                 jacobian: str = "dense", floquet: str = "dense", nev: int = 8, tol: float = 1e-10,
                 tolerances: IntegrationTolerances = RESPONSE_TOLERANCES,
                 floquet_tolerances: Optional[IntegrationTolerances] = None, prefix: str = DRIVE_PREFIX,
                 floquet_prefix: str = FLOQUET_PREFIX, inexact: bool = True) -> None:
        if not isinstance(drive, Drive):
            raise ParameterError("drive", drive, "must be a Drive")
        _check_parameter(parameter)
        _one_of("jacobian", jacobian, JACOBIANS)
        _one_of("floquet", floquet, FLOQUET_METHODS)
        self.tol = check_real("tol", tol, "the shooting tolerance", 0.0)
        self.periods = check_integer("periods", periods, 1, "the response period in driving periods")
        self.parameter, self.comm = parameter, comm
        self.jacobian_kind, self.floquet_kind = jacobian, floquet
        self.drive = drive
        spec = drive.spec()
        self.N = spec.N
        dense = check_dense_beads(spec.N, jacobian, floquet)
        # the state flow, and the tangent flows with 2N columns (dense: the multipliers' and the Jacobian's) or one
        # (matrix-free), before any allocation
        check_chain_memory(spec.N, comm, columns=(2 + 2 * spec.N) * (2 if jacobian == "dense" else 1) if dense else 3,
                           name="N")
        self.chain = Chain(spec, comm)
        self.integrator = ChainIntegrator(self.chain, tolerances, prefix)
        # a Newton iterate far from any response (huge overlaps: stiff contacts) must fail, not crawl
        self.integrator.max_steps = MAX_STEPS_PER_FLOW * self.periods
        self.X = self.chain.create_state()
        ftol = self.floquet_tolerances = floquet_tolerances or tolerances
        self.dense = DenseFloquet(spec, comm, ftol, floquet_prefix) if dense else None
        if self.dense is not None:             # R's columns start as unit vectors: R to rtol in norm
            rtol = self.tangent_rtol = self.dense.flow.integrator.ts.getTolerances()[0]
            self.dense.flow.integrator.control_components(tangents=(rtol, rtol))
        # the Newton Jacobian's monodromy: the same 2N columns, steps controlled by the state's error alone
        self.jacobian_flow = TangentFlow(spec, 2 * spec.N, comm, tolerances, floquet_prefix) \
            if jacobian == "dense" else None
        if self.jacobian_flow is not None:
            rtol, atol = self.jacobian_flow.integrator.ts.getTolerances()
            loose = max(rtol, JACOBIAN_RTOL)
            self.jacobian_flow.integrator.control_components(state=(loose, atol * loose / rtol))
        self.product = MonodromyModShift(spec, np.zeros((spec.N, 2)), 1.0, comm, ftol, floquet_prefix, shift=0) \
            if jacobian == "mf" else None
        self.dominant = DominantFloquet(spec, comm, min(nev, 2 * spec.N), ftol, floquet_prefix, shift=0,
                                        vectors=True, radius=default_radius(spec, self.T_of(drive))
                                        if floquet == "radius" else None) if floquet in ("slepc", "radius") else None
        self.mpi = comm.tompi4py()
        self.last_rank = comm.getRank() == comm.getSize() - 1
        self.nloc = 2 * self.chain.nloc
        self.size = 2 * spec.N + 1
        self._mono = None              # (x, p, R, version, accurate, steps of its flow) of the last dense monodromy
        self._checked = None           # the version of the last monodromy whose closed forms were checked
        self._spectra = {}             # key of (x, p) -> multipliers
        self.radius = None             # the radius of the last spectrum outside one (floquet 'radius')
        self.floquet_work = {}         # and its work (products; 'slow': multipliers from the slow modes, ...)
        self.counters = dict(state_flows=0, tangent_flows=0, products=0, jacobians=0)
        self._tight = False            # the corrector's retry: Jacobians from the fully resolved flow
        self._solves, self._assembled, self._mono_version = 0, None, 0
        self._residuals = {}
        self._flow_tolerances = self.integrator.ts.getTolerances()
        self._f_last = None            # the relative residual of the corrector's last evaluation (inexact Newton)
        self._steps_last = 0           # and the steps of its flow
        self.inexact = inexact
        self._snes = self._make_snes(prefix)
        if floquet == "radius" and self.dominant.fixed_radius is not None:     # refused before any flow
            self._radius_check(spec, self.T_of(drive))

    # --- layout ---------------------------------------------------------------------------------------------------
    def create_vec(self) -> PETSc.Vec:
        return PETSc.Vec().createMPI((self.nloc + (1 if self.last_rank else 0), self.size), comm=self.comm)

    def pack(self, x: ArrayLike, p: Optional[float] = None) -> PETSc.Vec:
        """A new Z from the state ``x`` ((N, 2), on every rank) and the parameter (default: the drive's)."""
        Z = self.create_vec()
        a = Z.getArray()
        xs = self.chain.xs
        a[:self.nloc] = np.asarray(x, float).reshape(self.N, 2)[xs:xs + self.nloc // 2].ravel()
        set_parameter(Z, self.drive.value(self.parameter) if p is None else p)
        return Z

    def state(self, Z: PETSc.Vec) -> tuple[np.ndarray, float]:
        """(x as (N, 2) on every rank, p) of an extended vector."""
        self.X.getArray()[:] = Z.getArray(readonly=True)[:self.nloc]
        return self.chain.gather(self.X), _parameter(Z)

    def weights(self) -> PETSc.Vec:
        """RMS over the 2N state entries, the parameter as it is."""
        W = self.create_vec()
        W.set(1.0 / (2 * self.N))
        set_parameter(W, 1.0)
        return W

    # --- the drive's parameter --------------------------------------------------------------------------------
    def set_drive(self, drive: Drive) -> None:
        """Move every chain of the problem to ``drive`` (same N and ends' kinds)."""
        if drive == self.drive:
            return
        spec = drive.spec()
        self.chain.set_spec(spec)
        for engine in self._engines():
            engine.set_spec(spec)
        self.drive = drive

    def _engines(self):
        return [e for e in (self.dense, self.dominant, self.jacobian_flow, self.product) if e is not None]

    def _at(self, p):
        if p != self.drive.value(self.parameter):
            self.set_drive(self.drive.with_parameter(self.parameter, p))

    def scale(self, x: Optional[np.ndarray] = None) -> float:
        """The size the residual is measured against: max(||X||_inf, amplitude), 1 if both vanish."""
        return self._scale(float(np.max(np.abs(x))) if x is not None else 0.0)

    def _scale(self, norm):
        """:meth:`scale` of a state whose sup norm is ``norm``."""
        s = max(self.drive.amplitude, norm)
        return s if s > 0 else 1.0

    @property
    def T(self) -> float:
        return self.periods * self.drive.period

    def _radius_check(self, spec, T):
        """ParameterError naming -floquet_radius when it does not exceed the phonons' circle at the period T."""
        rho_c = phonon_radius(spec, T)
        if not self.dominant.fixed_radius > rho_c:
            self.destroy()
            raise ParameterError("-%sradius" % self.dominant.prefix, self.dominant.fixed_radius,
                                 f"the radius must exceed the phonons' modulus e^(-gamma T / 2) = {rho_c:.6g}")

    def T_of(self, drive: Drive) -> float:
        """The response's period for ``drive``."""
        return self.periods * drive.period

    # --- the map ----------------------------------------------------------------------------------------------
    def flow(self, X: PETSc.Vec) -> int:
        """X <- P(X) (in place, the chain's layout) at the current drive; returns the steps taken."""
        steps = self.integrator.integrate(X, 0.0, self.T, dt=self.integrator.initial_step)
        self.counters["state_flows"] += 1
        return steps

    def map(self, x: ArrayLike) -> np.ndarray:
        """P(x) as (N, 2) on every rank."""
        self.chain.set_from_array(self.X, x)
        self.flow(self.X)
        return self.chain.gather(self.X)

    def residual(self, x: np.ndarray) -> float:
        """||P(x) - x||_inf / scale at the current drive."""
        return float(np.max(np.abs(self.map(x) - x))) / self.scale(x)

    def run_in(self, x: ArrayLike, periods: int) -> np.ndarray:
        """The state after ``periods`` driving periods from ``x`` (a transient, e.g. from rest)."""
        self.chain.set_from_array(self.X, x)
        T = self.drive.period
        for k in range(int(periods)):
            self.integrator.integrate(self.X, k * T, (k + 1) * T, dt=self.integrator.initial_step if k == 0 else None)
        self.counters["state_flows"] += int(periods)
        return self.chain.gather(self.X)

    def trajectory(self, x: ArrayLike, samples: int = 64) -> tuple[np.ndarray, np.ndarray]:
        """(times (J+1,), states (J+1, N, 2)) at J = ``samples`` equal steps over one response period from x, on
        every rank (one state flow stopped J times)."""
        J = int(samples)
        if J < 2:
            raise ParameterError("samples", samples, "at least 2 samples per period")
        self.chain.set_from_array(self.X, x)
        t = np.linspace(0.0, self.T, J + 1)
        out = [np.asarray(x, float).reshape(self.N, 2)]
        for j in range(J):
            self.integrator.integrate(self.X, t[j], t[j + 1], dt=self.integrator.initial_step if j == 0 else None)
            out.append(self.chain.gather(self.X))
        self.counters["state_flows"] += 1
        return t, np.array(out)

    def diagnostics(self, x: ArrayLike, samples: int = 64) -> dict:
        """What a response does over its period (plain data): per bead the amplitude (max - min)/2 and mean of
        x_n; the largest compressive force of the bond to the right end (the force transmitted to the wall, the
        observable of Pozharskiy et al. 2015) and to the left end (the actuator), each from the samples with a
        parabola through the largest three; the mean input power and mean dissipation (periodic trapezoid rule:
        equal for an exact response, the energy balance dE/dt = input - dissipation over a period)."""
        t, X = self.trajectory(x, samples)
        pos = X[:, :, 0]
        spec = self.drive.spec()
        law = self.drive.model
        eta = law.damping.eta
        # the ends' positions and velocities (an actuator's motion, a wall at rest)
        (x0, v0), (xr, vr) = [(end.signal.position(t), end.signal.velocity(t)) if isinstance(end, Actuator)
                              else (0.0, 0.0) for end in (spec.left, spec.right)]
        f_left = -(law.bond_law(-1).dV(pos[:, 0] - x0) + eta * (X[:, 0, 1] - v0))   # bonds -1, N - 1: law p - 1
        f_right = np.zeros_like(t) if spec.right == "free" else \
            -(law.bond_law(-1).dV(xr - pos[:, -1]) + eta * (vr - X[:, -1, 1]))             # a free end has no bond
        if law.damping.contact is not None:            # the contacts' tension f_d(r, dv) in the end bonds too
            f_left = f_left - law.damping.contact.bond_terms(law.law, pos[:, 0] - x0, X[:, 0, 1] - v0)[0]
            if spec.right != "free":
                f_right = f_right - law.damping.contact.bond_terms(law.law, xr - pos[:, -1], vr - X[:, -1, 1])[0]
        p_in, diss = [], []
        for j in range(len(t) - 1):
            self.chain.set_from_array(self.X, X[j])
            a, b = self.chain.power(self.X, t[j])
            p_in.append(a)
            diss.append(b)
        return dict(amplitude=0.5 * (pos.max(axis=0) - pos.min(axis=0)), mean=pos[:-1].mean(axis=0),
                    force_right=_peak(f_right[:-1])[1], force_left=_peak(f_left[:-1])[1], power_in=float(np.mean(p_in)),
                    dissipation=float(np.mean(diss)))

    # --- SNES callbacks ------------------------------------------------------------------------------------------
    def _make_snes(self, prefix):
        snes = PETSc.SNES().create(comm=self.comm)
        snes.setOptionsPrefix(prefix)
        snes.setType(PETSc.SNES.Type.NEWTONLS)
        self.F = self.create_vec()
        snes.setFunction(self.formFunction, self.F)
        ksp = snes.getKSP()
        pc = ksp.getPC()
        local = self.nloc + (1 if self.last_rank else 0)
        sizes = ((local, self.size), (local, self.size))
        if self.jacobian_kind == "dense":
            # LU with pivoting: the bordered row's diagonal vanishes at a fold in the parameter. One rank: LAPACK on
            # a dense matrix; several: MUMPS on AIJ.
            if self.comm.getSize() == 1:
                self.J = PETSc.Mat().createDense(sizes, comm=self.comm)
            else:
                self.J = PETSc.Mat().createAIJ(sizes, nnz=(local, self.size - local), comm=self.comm)
                self.J.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
            ksp.setType(PETSc.KSP.Type.PREONLY)
            pc.setType(PETSc.PC.Type.LU)
            if self.comm.getSize() > 1:
                pc.setFactorSolverType("mumps")
        else:
            self._shell = _BorderedProduct(self)
            self.J = PETSc.Mat().createPython(sizes, context=self._shell, comm=self.comm)
            ksp.setType(PETSc.KSP.Type.GMRES)
            ksp.setGMRESRestart(200)
            if LinearChainPreconditioner.applies(self.drive):
                # right preconditioning: GMRES measures the true residual of the Newton step
                pc.setType(PETSc.PC.Type.PYTHON)
                pc.setPythonContext(LinearChainPreconditioner(self))
                ksp.setPCSide(PETSc.PC.Side.RIGHT)
            else:
                pc.setType(PETSc.PC.Type.NONE)
            ksp.setTolerances(rtol=1e-8, max_it=2000)
        self.J.setUp()
        snes.setJacobian(self.formJacobian, self.J, self.J)
        snes.setTolerances(rtol=1e-30, stol=1e-30, max_it=20)
        snes.setConvergenceTest(self._converged)
        self._user_set = user_set(prefix + "snes_", ("atol", "rtol", "stol", "max_it"))
        snes.setFromOptions()
        return snes

    def _converged(self, snes, it, norms):
        """SNES's tests on ||F|| (atol, rtol, max_it from -drive_snes_*) and one more: a corrector that has not
        halved the residual in three iterations is not converging (it would only spend flows): DIVERGED_LOCAL_MIN."""
        R = PETSc.SNES.ConvergedReason
        fnorm = norms[2]
        rtol, atol, _, max_it = snes.getTolerances()
        if it == 0:
            self._fhist = []
        self._fhist.append(fnorm)
        if not math.isfinite(fnorm):
            return R.DIVERGED_FNORM_NAN
        if fnorm <= atol:
            return R.CONVERGED_FNORM_ABS
        if fnorm <= rtol * self._fhist[0]:
            return R.CONVERGED_FNORM_RELATIVE
        if it >= 3 and fnorm > 0.5 * self._fhist[-4]:
            return R.DIVERGED_LOCAL_MIN
        if it >= max_it:
            return R.DIVERGED_MAX_IT
        return R.ITERATING

    def _evaluation_rtol(self):
        """The state flow's rtol for the next residual evaluation of the corrector (inexact Newton): the flow's
        own at the first evaluation of a bordered solve (dG/dp is differenced from it) and once the residual is
        small, else INEXACT_FRACTION f^2 / (2 n) up to JACOBIAN_RTOL."""
        rtol = self._flow_tolerances[0]
        if not self.inexact or self._tight:
            return rtol
        if self._f_last is None:
            return rtol if self._row is not None else max(rtol, JACOBIAN_RTOL)
        wanted = INEXACT_FRACTION * self._f_last ** 2 / (2 * self._steps_last)
        return min(max(rtol, wanted), max(rtol, JACOBIAN_RTOL))

    def _flow_at(self, X, z, rtol):
        """X <- P(z) with the state flow at ``rtol`` (atol in the same ratio), the flow's tolerances restored;
        returns the steps taken."""
        rtol0, atol0 = self._flow_tolerances
        X.getArray()[:] = z[:self.nloc]
        if rtol == rtol0:
            return self.flow(X)
        ts = self.integrator.ts
        ts.setTolerances(rtol=rtol, atol=atol0 * rtol / rtol0)
        try:
            return self.flow(X)
        finally:
            ts.setTolerances(rtol=rtol0, atol=atol0)

    def _relative(self, g, z):
        """||g||_inf / max(||z||_inf, amplitude) over the state rows of every rank."""
        local = np.array([np.max(np.abs(g), initial=0.0), np.max(np.abs(z), initial=0.0)])
        self.mpi.Allreduce(MPI.IN_PLACE, local, op=MPI.MAX)
        return local[0] / self._scale(local[1])

    def formFunction(self, snes: PETSc.SNES, Z: PETSc.Vec, F: PETSc.Vec) -> None:
        z = Z.getArray(readonly=True)
        p = _parameter(Z)
        try:
            self._at(p)
            for rtol in (self._evaluation_rtol(), self._flow_tolerances[0]):
                steps = self._flow_at(self.X, z, rtol)
                g = self.X.getArray(readonly=True) - z[:self.nloc]
                rel = self._relative(g, z[:self.nloc])
                # an evaluation not resolved to a small fraction of itself (the global error: up to rtol per step)
                # is made again at the flow's tolerance
                if not (rtol > self._flow_tolerances[0] and rtol * steps > INEXACT_FRACTION * rel):
                    break
        except (ParameterError, ConvergenceError):
            # outside the parameter's range (omega <= 0, a < 0) or a failed flow: NaN makes the line search
            # shorten the step, or SNES stop with a negative reason
            F.set(math.nan)
            return
        self._f_last, self._steps_last = rel, steps
        f = F.getArray()
        f[:self.nloc] = g
        g = self._row.dot(Z) - self._value if self._row is not None else z[-1] - self._p_fixed
        if self.last_rank:
            f[-1] = g

    def _dG_dp(self, x, p, G):
        """dG/dp (local rows) by a forward difference from G = G(x; p) with one state flow (the drive changes with
        p, and with omega the period): step h = 1e-6 max(|p|, 1e-3), truncation O(h) and noise (flow tolerance) / h
        both ~1e-6 relative: the bordered column of a Newton step, which then converges linearly at that rate."""
        h = 1e-6 * max(abs(p), 1e-3)
        self._at(p + h)
        xh = self.map(x)
        self._at(p)
        xs = self.chain.xs
        return ((xh - x).ravel()[2 * xs:2 * xs + self.nloc] - G) / h

    def monodromy(self, x: np.ndarray, p: float, accurate: bool = True) -> np.ndarray:
        """Dense R(kT; 0) at (x, p), on every rank (cached for the last point): ``accurate``, the tangents resolved
        to the Floquet flow's tolerance (multipliers, branch switching), else the Newton Jacobian's (the steps of
        the state's error to JACOBIAN_RTOL, :meth:`~hertzpetsc.chain.ChainIntegrator.control_components`)."""
        m = self._mono
        if m is not None and m[1] == p and (m[4] or not accurate) and np.array_equal(m[0], x):
            return m[2]
        self._at(p)
        flow = self.dense.flow if accurate or self.jacobian_flow is None else self.jacobian_flow
        R = flow.resolvent(x, self.T)[0]
        self.counters["tangent_flows"] += 1
        self._mono_version += 1
        self._mono = (np.array(x, copy=True), p, R, self._mono_version, accurate, flow.integrator.ts.getStepNumber())
        return R

    def formJacobian(self, snes: PETSc.SNES, Z: PETSc.Vec, J: PETSc.Mat, P: PETSc.Mat) -> None:
        """The bordered Jacobian at Z. dG/dp is computed once per corrector solve. Dense route: the monodromy of
        the last point where one was computed (e.g. the previous response's multipliers) is reused while Newton
        contracts the residual by CHORD_CONTRACTION per iteration (a chord step), and recomputed otherwise."""
        x, p = self.state(Z)
        if self._row is not None and self._dGdp is None:
            G = snes.getFunction()[0].getArray(readonly=True)[:self.nloc].copy()
            self._dGdp = self._dG_dp(x, p, G)
        dGdp = self._dGdp if self._row is not None else np.zeros(self.nloc)
        if self.jacobian_kind == "mf":
            self.counters["jacobians"] += 1
            self._shell.set_point(x, dGdp)
            return
        fnorm = snes.getFunctionNorm()
        first = snes.getIterationNumber() == 0
        contracting = (first and self._near(x, p)) or (not first and fnorm <= CHORD_CONTRACTION * self._last_fnorm)
        self._last_fnorm = fnorm
        if self._tight or not contracting or self._mono is None:
            self.monodromy(x, p, accurate=self._tight)
            self.counters["jacobians"] += 1
        key = (self._mono[3], self._solves)
        if key == self._assembled:
            return                                 # the matrix (and its factorisation) is the chord's
        self._assembled = key
        R = self._mono[2]
        lo, hi = P.getOwnershipRange()
        P.zeroEntries()
        n2 = 2 * self.N
        rows = np.arange(lo, min(hi, n2), dtype=PETSc.IntType)
        if len(rows):
            block = np.zeros((len(rows), self.size))
            block[:, :n2] = R[rows]
            block[np.arange(len(rows)), rows] -= 1.0
            block[:, n2] = dGdp
            P.setValues(rows, np.arange(self.size, dtype=PETSc.IntType), block.ravel())
        if hi == self.size:
            last = self._row_full if self._row is not None else np.eye(1, self.size, self.size - 1)[0]
            P.setValues([self.size - 1], np.arange(self.size, dtype=PETSc.IntType), last)
        P.assemble()

    def _near(self, x, p):
        """Whether the cached monodromy was computed within 5% (parameter and state) of (x, p)."""
        if self._mono is None:
            return False
        xm, pm = self._mono[0], self._mono[1]
        return abs(p - pm) <= 0.05 * max(abs(p), 1e-12) and \
            np.max(np.abs(x - xm)) <= 0.05 * max(float(np.max(np.abs(x))), 1e-300)

    # --- the corrector -------------------------------------------------------------------------------------------
    def solve(self, Z: PETSc.Vec, row: Optional[PETSc.Vec] = None, value: Optional[float] = None) -> int:
        """Newton (SNES ``drive_``) on G(X; p) = 0 with row . Z = value (row None: p fixed at Z's). Returns the
        iterations (at least 1: a Z that is already a response counts as one); ConvergenceError naming p."""
        self._row, self._value, self._dGdp = row, value, None
        self._row_full = gathered(row) if row is not None and self.jacobian_kind == "dense" else None
        x0, p0 = self.state(Z)
        self._p_fixed = p0
        try:
            self._at(p0)
        except ParameterError as err:            # a predictor beyond the parameter's range: no response there
            raise ConvergenceError("periodic-response Newton", f"parameter out of range ({err.valid})",
                                   **{self.parameter: p0}) from None
        if "atol" not in self._user_set:
            self._snes.setTolerances(atol=self.tol * self.scale(x0))
        Z0, its = Z.copy(), 0
        try:
            # a chord step that led nowhere, or a Jacobian too loose for R - I (multipliers near 1: an undamped
            # chain amplifies JACOBIAN_RTOL by cond(R - I)): again from Z with fresh, fully resolved Jacobians
            for self._tight in (False, True):
                Z0.copy(Z)
                self._last_fnorm, self._solves, self._f_last = math.inf, self._solves + 1, None
                try:
                    with callbacks_raise():
                        self._snes.solve(None, Z)
                except PETSc.Error as err:
                    if not singular_factor(err):
                        raise
                    raise ConvergenceError(f"periodic-response Newton (prefix -{self._snes.getOptionsPrefix()})",
                                           "zero pivot in R - I: a multiplier at 1 (e.g. beads out of contact "
                                           "over a whole period, as in the sonic vacuum)", **{self.parameter: p0}) \
                        from None
                reason = int(self._snes.getConvergedReason())
                its += int(self._snes.getIterationNumber())
                if reason > 0:
                    break
        finally:
            self._tight = False
            Z0.destroy()
        p = _parameter(Z)
        if reason <= 0:
            raise ConvergenceError(f"periodic-response Newton (prefix -{self._snes.getOptionsPrefix()})", reason,
                                   **{self.parameter: p})
        self._at(p)
        # the relative residual of the converged point, from the last function evaluation (the flow from this very
        # state, at the flow's own tolerance)
        x, _ = self.state(Z)
        self._residuals = {(float(p), hash(x.tobytes())): self._f_last}
        return max(its, 1)

    @contextmanager
    def detour(self) -> Iterator[PeriodicShooting]:
        """Solves made inside (e.g. checking an event on nearby responses) leave the problem as it was: the drive, the
        cached monodromy a chord step may reuse and the last converged residual are restored on exit."""
        kept = self.drive, self._mono, self._residuals
        try:
            yield self
        finally:
            self.set_drive(kept[0])
            self._mono, self._residuals = kept[1], kept[2]

    def known_residual(self, x: np.ndarray, p: float) -> Optional[float]:
        """The relative residual of the last converged point if (x, p) is it, else None."""
        return self._residuals.get((float(p), hash(np.asarray(x).tobytes())))

    def solve_response(self, x: ArrayLike, p: Optional[float] = None) -> Response:
        """Newton at fixed parameter from the state ``x``: the converged :class:`Response` (its residual measured
        again with one state flow)."""
        Z = self.pack(x, p)
        try:
            its = self.solve(Z)
            x, _ = self.state(Z)
        finally:
            Z.destroy()
        return Response(self.drive, self.periods, x, self.residual(x), its)

    # --- multipliers, test functions, report -----------------------------------------------------------------------
    def multipliers(self, Z: Optional[PETSc.Vec] = None, x: Optional[np.ndarray] = None,
                    p: Optional[float] = None) -> np.ndarray:
        """The Floquet multipliers at Z (or at the state x and parameter p): all 2N ('dense') or the dominant
        ('slepc'), sorted by decreasing modulus; cached per point."""
        if Z is not None:
            x, p = self.state(Z)
        key = (float(p), hash(np.asarray(x).tobytes()))
        if key in self._spectra:
            return self._spectra[key]
        self._at(p)
        if self.floquet_kind == "dense":
            R = self.monodromy(x, p)
            if self._checked != self._mono[3]:          # once per monodromy
                spec = self.drive.spec()
                trace = None if spec.model.damping.contact is None else \
                    liouville_integral(spec, x, self.T, self.comm, self.floquet_tolerances,
                                       self.dense.flow.integrator.ts.getOptionsPrefix())
                check_monodromy(R, spec, self.T, self.tangent_rtol, self._mono[5], {self.parameter: float(p)}, trace)
                self._checked = self._mono[3]
            mu = dense_multipliers(R)
        elif self.floquet_kind in ("slepc", "radius"):
            if self.floquet_kind == "radius":
                spec = self.drive.spec()
                self.dominant.cluster = phonon_radius(spec, self.T)
                if self.dominant.fixed_radius is None:
                    self.dominant.radius = default_radius(spec, self.T)
                self.dominant.slow = LinearChainPreconditioner(self) if self.dominant.use_slow and \
                    LinearChainPreconditioner.applies(self.drive) else None
            res = self.dominant.spectrum(Response(self.drive, self.periods, x, math.nan))
            self.counters["products"] += res.work["products"] + 2 * len(res.multipliers)
            mu = res.multipliers
            if self.floquet_kind == "radius" and not res.work["resolved"]:
                raise ConvergenceError("the multipliers outside a radius (prefix -%s)" % self.dominant.prefix,
                                       f"unresolved: {len(mu)} outside r = {res.work['radius']:.6g} converged, the "
                                       f"spectrum not closed there (EPS reason {res.work['reason']}; more than "
                                       f"-{self.dominant.prefix}eps_nev = {self.dominant.nev} outside, or the "
                                       "restarts ran out)", **{self.parameter: float(p)})
            self.radius = res.work.get("radius")
            self.floquet_work = res.work
            check_eigenpairs(self.dominant.op, mu, self.dominant.vectors, self.drive.spec(), self.T,
                             {self.parameter: float(p)})
        else:
            raise ParameterError("floquet", "none", "this problem computes no multipliers")
        self._spectra = {key: mu}
        return mu

    def test_functions(self, Z: PETSc.Vec) -> dict[str, float]:
        if self.floquet_kind == "none":
            return {}
        return test_functions(self.multipliers(Z), partial=self.floquet_kind == "radius")

    def report(self, Z: PETSc.Vec) -> dict:
        x, p = self.state(Z)
        out = dict(x=x, periods=self.periods)
        if self.floquet_kind != "none":
            mu = self.multipliers(x=x, p=p)
            # the radius route: rho <= r when no multiplier lies outside r (r itself reported: an upper bound)
            rho = float(np.max(np.abs(mu))) if len(mu) else self.radius
            out.update(multipliers=mu, rho=rho, verdict=verdict(rho), **counts(mu))
            if self.floquet_kind == "radius":
                out["radius"] = self.radius
        return out

    def destroy(self) -> None:
        for obj in (self._snes, self.J, self.F, self.X, self.integrator, self.chain, *self._engines()):
            obj.destroy()


class LinearChainPreconditioner:
    """(R_lin - I)^-1, the preconditioner of Newton-Krylov shooting (a PETSc ``PC`` python context, prefix
    ``drive_``: -drive_pc_type none turns it off). R_lin is the monodromy over the response's period of the chain
    linearised about rest, m x'' + (gamma + eta L) x' + K L x = 0 with K = V''(0) (eta with the contacts' df/d(dv) at
    rest, if the chain has contact dissipation) and L the second difference with the
    actuator's end fixed and the far end fixed (wall, actuator) or free: uniform masses make it diagonal in the sine
    modes of L (a sine transform by numpy's FFT), each mode a damped oscillator with its 2 x 2 monodromy in closed
    form. Without it GMRES on R - I stalls for about N / (c T) iterations on a long damped chain: the overdamped long
    waves have multipliers 1 - O(omega_k^2 T / gamma). The border row (the parameter's) is left as it is."""

    def __init__(self, problem):
        self.problem = problem
        self._key = None

    @staticmethod
    def applies(drive):
        """Uniform masses, one law in every bond and a precompressed law (V''(0) > 0: in a sonic vacuum R_lin - I is
        singular)."""
        return len(set(drive.model.masses)) == 1 and drive.model.bonds is None and \
            drive.model.law.linear_stiffness > 0.0

    def _modes(self):
        """The transform's length and frequencies and the 2 x 2 inverses per mode, for the current drive and T."""
        prob = self.problem
        drive, T = prob.drive, prob.T
        if self._key == (drive, T):
            return
        N, model = drive.N, drive.model
        k = np.arange(1, N + 1)
        if drive.right == "free":                  # sin(pi (2k - 1) n / (2N + 1)), n = 1..N
            self.ext, self.freq, self.norm = 2 * (2 * N + 1), 2 * k - 1, (2 * N + 1) / 4.0
        else:                                      # sin(pi k n / (N + 1))
            self.ext, self.freq, self.norm = 2 * (N + 1), k, (N + 1) / 2.0
        lam = 4.0 * np.sin(np.pi * self.freq / self.ext) ** 2
        m = model.masses[0]
        w2 = model.law.linear_stiffness * lam / m
        eta = model.damping.eta
        if model.damping.contact is not None:     # the contacts at rest (overlap delta0): a dashpot df_d/d(dv)
            eta = eta + model.damping.contact.linear_dashpot(model.law)
        half = 0.5 * (model.damping.gamma + eta * lam) / m
        s = np.sqrt(half * half - w2 + 0j)
        decay, cosh = np.exp(-half * T), np.cosh(s * T)
        sinc = np.where(np.abs(s * T) > 1e-8, np.sinh(s * T) / np.where(s == 0, 1.0, s), T)   # sinh(s T) / s
        phi = np.empty((N, 2, 2))
        phi[:, 0, 0] = (decay * (cosh + half * sinc)).real
        phi[:, 0, 1] = (decay * sinc).real
        phi[:, 1, 0] = (-decay * w2 * sinc).real
        phi[:, 1, 1] = (decay * (cosh - half * sinc)).real
        self.phi = phi
        self.inverse = np.linalg.inv(phi - np.eye(2))
        self._key = (drive, T)

    def _sine(self, x, into, out):
        """The sine transform of x (rows ``into`` of the length-ext sequence) at the rows ``out``: the modes
        sum_n x_n sin(2 pi j n / ext) (into the beads 1..N, out the frequencies j) and, divided by norm, back."""
        z = np.zeros((self.ext, x.shape[1]))
        z[into] = x
        return -np.fft.rfft(z, axis=0).imag[out]

    def _real_sine(self, x, into, out):
        """:meth:`_sine` of complex columns (the transform is real-linear)."""
        if not np.iscomplexobj(x):
            return self._sine(x, into, out)
        return self._sine(x.real, into, out) + 1j * self._sine(x.imag, into, out)

    def slow_modes(self, radius):
        """The eigenpairs of R_lin with |mu| > ``radius`` (every mode's 2 x 2 block in closed form): multipliers
        (m,) and eigenvectors (2N, m), complex, index 2n + c; the start of the slow modes' refinement
        (:func:`hertzpetsc.floquet.slow_eigenpairs`)."""
        self._modes()
        N = self.problem.N
        lam, vec = np.linalg.eig(self.phi)                    # (N, 2), (N, 2, 2)
        modes, values = [], []
        for j, i in zip(*np.nonzero(np.abs(lam) > radius)):
            z = np.zeros((N, 2), complex)
            z[j] = vec[j, :, i]
            modes.append(self._real_sine(z, self.freq, slice(1, N + 1)).reshape(2 * N) / self.norm)
            values.append(lam[j, i])
        return np.array(values, complex), np.array(modes, complex).T.reshape(2 * N, len(modes))

    def shifted_solve(self, theta, B):
        """(R_lin - theta_j I)^-1 B[:, j] for complex shifts ``theta`` (k,) and columns B (2N, k), index 2n + c."""
        self._modes()
        N, k = self.problem.N, B.shape[1]
        beads = slice(1, N + 1)
        modes = self._real_sine(B.reshape(N, 2 * k), beads, self.freq).reshape(N, 2, k)
        M = self.phi[:, None, :, :] - np.asarray(theta)[None, :, None, None] * np.eye(2)     # (N, k, 2, 2)
        solved = np.linalg.solve(M, modes.transpose(0, 2, 1)[..., None])[..., 0]            # (N, k, 2)
        return self._real_sine(solved.transpose(0, 2, 1).reshape(N, 2 * k), self.freq, beads).reshape(2 * N, k) \
            / self.norm

    def apply(self, pc, x, y):
        prob = self.problem
        self._modes()
        full = gathered(x)
        beads = slice(1, prob.N + 1)
        modes = self._sine(full[:2 * prob.N].reshape(prob.N, 2), beads, self.freq)
        solved = self._sine(np.einsum("kij,kj->ki", self.inverse, modes), self.freq, beads) / self.norm
        out = y.getArray()
        xs = prob.chain.xs
        out[:prob.nloc] = solved[xs:xs + prob.nloc // 2].ravel()
        if prob.last_rank:
            out[-1] = x.getArray(readonly=True)[-1]


class _BorderedProduct:
    """The bordered Jacobian [R - I, dG/dp; row] as a ``Mat.createPython`` context: R v by one tangent-flow
    product (:class:`~hertzpetsc.tangent.MonodromyModShift` without shift)."""

    def __init__(self, problem):
        self.problem = problem
        chain = problem.chain
        self.vX, self.RvX = chain.create_state(), chain.create_state()
        self.dGdp = None

    def set_point(self, x, dGdp):
        self.problem.product.set_orbit(x, self.problem.T)
        self.dGdp = dGdp

    def mult(self, mat, v, y):
        prob = self.problem
        a = v.getArray(readonly=True)
        n = prob.nloc
        self.vX.getArray()[:] = a[:n]
        vp = prob.mpi.bcast(float(a[-1]) if prob.last_rank else None, root=prob.comm.getSize() - 1)
        prob.product.mult(None, self.vX, self.RvX)
        prob.counters["products"] += 1
        out = y.getArray()
        out[:n] = self.RvX.getArray(readonly=True) - a[:n] + vp * self.dGdp
        g = prob._row.dot(v) if prob._row is not None else vp
        if prob.last_rank:
            out[-1] = g

    def destroy(self, mat=None):
        if self.vX is not None:
            self.vX.destroy()
            self.RvX.destroy()
            self.vX = None


# --- branch switching at a period doubling ---------------------------------------------------------------------
def switch_to_doubled(single: PeriodicShooting, double: PeriodicShooting, x: np.ndarray, p: float,
                      step: Optional[float] = None) -> tuple[PETSc.Vec, PETSc.Vec]:
    """(Z0, Z1) to start the period-doubled branch at the period doubling (x, p) of ``single`` (period k T), on
    ``double`` (period 2 k T, the same drive and parameter): Z0 is the doubling point itself (a fixed point of P^2
    on both branches), Z1 the first point of the new branch, from the pseudo-arclength corrector of ``double`` along
    the eigenvector v of the multiplier -1, (v, 0), at W-distance ``step`` (default 5% of ||x||_inf) -- the
    period-1 branch crosses that hyperplane only at a distance O(step) from the prediction, the doubled one at
    O(step^2). The layer continues from the two (:meth:`~hertzpetsc.continuation.Continuation.seed`)."""
    if double.periods != 2 * single.periods:
        raise ParameterError("periods", double.periods, f"the doubled problem's period must be 2 x {single.periods}")
    if single.dense is None:
        raise ParameterError("floquet", single.floquet_kind, "branch switching needs the dense monodromy")
    single._at(p)
    lam, V = np.linalg.eig(single.monodromy(x, p))
    v = V[:, int(np.argmin(np.abs(lam + 1.0)))].real
    v = v / np.max(np.abs(v))
    Z0 = double.pack(x, p)
    t = double.pack(v, 0.0)
    W = double.weights()
    w = t.copy()
    w.pointwiseMult(w, W)
    t.scale(1.0 / math.sqrt(w.dot(t)))
    step = 0.05 * float(np.max(np.abs(x))) if step is None else step
    Z1 = Z0.copy()
    Z1.axpy(step, t)
    row = t.copy()
    row.pointwiseMult(row, W)
    try:
        double.solve(Z1, row, row.dot(Z1))
    except ConvergenceError:
        Z0.destroy()
        Z1.destroy()
        raise
    finally:
        for vec in (t, w, row, W):
            vec.destroy()
    return Z0, Z1


# --- a refined travelling wave's profile, for the exact boundary driving (paper's Discussion) ---------------------
def refined_profile(orbit, comm, samples=8192, tolerances=None):
    """The travelling-wave profile U (x_n(t) = U(q n - omega t)) of a refined periodic-chain wave ``orbit``
    (:class:`~hertzpetsc.waves.Orbit`: P beads, q = 2 pi m / P) on a uniform grid of at least ``samples`` points of
    [0, 2 pi): the chain integrated over script-T with J stops gives U(q (n - j / J)) for every bead n and stop j,
    i.e. the grid 2 pi k / L, L = P J / gcd(m, P J), k = (m / gcd) (n J - j) mod L. Returns a :class:`ProfileWave`
    (U includes the wave's amplitude: drive it with amplitude 1 and the orbit's omega)."""
    from .shooting import MEASURE_TOLERANCES
    P, m = orbit.N, orbit.m
    J = 1
    while P * J // math.gcd(m, P * J) < samples:
        J *= 2
    g = math.gcd(m, P * J)
    L = P * J // g
    chain = Chain(orbit.spec, comm)
    integ = ChainIntegrator(chain, tolerances or MEASURE_TOLERANCES, "floquet_")
    X = chain.create_state()
    try:
        chain.set_from_array(X, orbit.x)
        U = np.full(L, np.nan)
        n = np.arange(P)
        dt = orbit.T / J
        for j in range(J):
            if j:
                integ.integrate(X, (j - 1) * dt, j * dt, dt=integ.initial_step if j == 1 else None)
            k = ((m // g) * (n * J - j)) % L
            U[k] = chain.gather(X)[:, 0]
    finally:
        X.destroy()
        integ.destroy()
        chain.destroy()
    if not np.all(np.isfinite(U)):
        raise ParameterError("samples", samples, "the stops did not cover the profile's grid")
    return ProfileWave(U, label=f"refined wave q = {orbit.q:.12g} on {P} beads")


def wave_ends_drive(model, N, profile, omega, q, amplitude=1.0):
    """The finite chain of N beads whose ends move as beads 0 and N + 1 of the travelling wave x_n(t) =
    a U(q n - omega t): both ends actuators with the wave's profile at phases 0 and q (N + 1) (the paper's
    Discussion: 'the motions of the first and last beads are imposed, following an exact travelling wave
    profile'). Undamped unless the model is."""
    return Drive(model, N, profile, amplitude, omega, right=profile, left_phase=0.0, right_phase=q * (N + 1))


# --- the bulk of a driven response against the travelling-wave family -------------------------------------------
def local_wave(t, positions, omega):
    """Per bead of a sampled response (times t over one period, positions (J+1, N)): the amplitude A_n =
    (max - min)/2, the offset c_n = (max + min)/2 and the local wavenumber q_n = omega tau_n in (-pi, pi], tau_n
    the time by which bead n+1 lags bead n (the peak of their periodic cross-correlation, refined by a parabola;
    nan for the last bead; q_n < 0: the wave runs towards the actuator). For a travelling wave
    x_n = c + A U(q n - omega t): q_n = q, A_n = A."""
    x = np.asarray(positions, float)[:-1]              # one period of samples
    J = len(x)
    A = 0.5 * (x.max(axis=0) - x.min(axis=0))
    c = 0.5 * (x.max(axis=0) + x.min(axis=0))
    F = np.fft.rfft(x - x.mean(axis=0), axis=0)
    q = np.full(x.shape[1], np.nan)
    dt = (t[-1] - t[0]) / J
    for n in range(x.shape[1] - 1):
        cc = np.fft.irfft(F[:, n + 1] * np.conj(F[:, n]), n=J)   # cc[s] = sum_j x_{n+1}(t_j + s) x_n(t_j)
        lag = _peak(cc)[0] * dt                        # x_{n+1}(t) = x_n(t - lag)
        q[n] = (omega * lag + math.pi) % (2 * math.pi) - math.pi
    return A, c, q


class BranchFamily:
    """The travelling waves of a branch (eq. ad, uncompressed chain) as a family in (q, amplitude) at a given
    frequency: the normalised profiles U_q = u_q / ||u_q||_inf (interpolated linearly in q between branch points)
    and the amplitude of the wave of wavenumber q at frequency omega, A(q, omega) = ||u_q|| omega^(2/(alpha-1))
    (x = a u(q n - omega t) with omega = a^((alpha-1)/2))."""

    def __init__(self, branch):
        self.branch = branch
        order = np.argsort(branch.q)
        self.q = np.asarray(branch.q, float)[order]
        self.norm = np.array([branch.points[i].diagnostics.norm_inf for i in order])
        self.shapes = np.array([branch.points[i].u_full / branch.points[i].diagnostics.norm_inf for i in order])
        self.h = branch.points[0].h
        self.alpha = branch.model.alpha

    def _weights(self, q):
        q = float(np.clip(q, self.q[0], self.q[-1]))
        i = int(np.clip(np.searchsorted(self.q, q) - 1, 0, len(self.q) - 2))
        s = (q - self.q[i]) / (self.q[i + 1] - self.q[i])
        return i, s

    def amplitude(self, q, omega):
        i, s = self._weights(q)
        return ((1 - s) * self.norm[i] + s * self.norm[i + 1]) * omega ** (2 / (self.alpha - 1))

    def shape(self, q, xi):
        """U_q at the phases xi (degree-5 Lagrange in xi, linear in q)."""
        from .stencil import lagrange_periodic
        i, s = self._weights(q)
        return (1 - s) * lagrange_periodic(self.shapes[i], self.h, np.mod(xi, 2 * math.pi)) + \
            s * lagrange_periodic(self.shapes[i + 1], self.h, np.mod(xi, 2 * math.pi))

    def distance(self, t, x, omega, q):
        """min over the phase of the RMS distance between the normalised motion (x - c)/A of one bead over a period
        (samples x at times t, the last closing the period) and U_q(phi - omega t): 0 for a wave of the family."""
        xs = np.asarray(x, float)[:-1]
        tt = np.asarray(t, float)[:-1]
        A = 0.5 * (xs.max() - xs.min())
        if not A > 0:
            return math.nan
        y = (xs - 0.5 * (xs.max() + xs.min())) / A
        phis = np.linspace(0, 2 * math.pi, 256, endpoint=False)
        f = lambda ph: np.sqrt(np.mean((y - self.shape(q, ph - omega * tt)) ** 2))   # noqa: E731
        k = int(np.argmin([f(ph) for ph in phis]))
        # refine the phase by golden section around the best grid phase
        a, b = phis[k] - 2 * math.pi / 256, phis[k] + 2 * math.pi / 256
        return -golden_maximum(lambda ph: -f(ph), a, b, 1e-9)[1]

