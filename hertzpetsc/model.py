"""The lattice model: the chain's physics in one frozen, validated object (eq. nc and its extensions).

    m_n x_n'' = f_n - f_{n-1} - gamma x_n',     f_n = V'(x_{n+1} - x_n) + eta (x_{n+1}' - x_n'),

:class:`LatticeModel` holds the interaction law between neighbours (any :class:`~hertzpetsc.law.InteractionLaw`;
the paper's is :class:`~hertzpetsc.hertz.HertzLaw`, eq. vhertz), or one law per bond of the pattern (``bonds``:
beads of different materials, bond n joining beads n and n + 1 with the law of bond n mod p), the masses m_n, which
repeat a pattern (the paper's chain: all masses 1), and the damping (:class:`Damping`: on-site gamma, between
neighbours eta, and a dissipation in the contacts, :mod:`hertzpetsc.dissipation`; none in the paper).
:class:`ChainSpec` is a finite chain of that lattice: N beads and its two ends -- periodic (eq. pbcl), free, a wall at rest, or an actuator whose motion is a given periodic function of time (:class:`Actuator`
with a :class:`Harmonic`, :class:`SampledSignal` or :class:`FunctionSignal`).

Every consumer (the advance-delay problem, the solitary wave, the chain's right-hand side, Jacobian, tangent flow
and energy balance, the waves) takes one of these and asks it for forces, stiffnesses, energies, damping and
masses. Adding a law is a file of its own (:mod:`hertzpetsc.law`: the protocol; the law's parameters are the
model's continuation parameters, :meth:`LatticeModel.with_parameter`); adding a term is a change in this module and
nowhere else. The model also knows the closed forms of its linear waves (:meth:`LatticeModel.linear_frequencies`)
and rebuilds itself from its description (:meth:`LatticeModel.from_description`: record files reopen with their
model).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, fields
from typing import Callable, Optional, Sequence, Union

import numpy as np
from numpy.typing import ArrayLike

from .dissipation import ContactDissipation
from .dissipation import from_description as contact_from_description
from .errors import ParameterError, check_integer, check_real, check_reals
from . import fpu, toda  # noqa: F401  (the package's laws, registered by name for from_description)
from .hertz import HertzLaw
from .law import LAWS, InteractionLaw, ScaledLaw
from .law import from_description as law_from_description

BOUNDARIES = ("periodic", "free", "fixed")
END_KINDS = ("free", "wall")


@dataclass(frozen=True)
class Damping:
    """Damping of the chain: linear on-site ``gamma`` (force -gamma x_n') and between neighbours ``eta`` (a
    dashpot in every bond: force eta (x_{n+1}' - 2 x_n' + x_{n-1}') on bead n), and ``contact``, a dissipation in
    the contacts that depends on the overlap and its rate (:class:`~hertzpetsc.dissipation.HuntCrossley`,
    :class:`~hertzpetsc.dissipation.KuwabaraKono`; None: none). All absent: the paper's Hamiltonian chain."""

    gamma: float = 0.0
    eta: float = 0.0
    contact: Optional[ContactDissipation] = None

    def __post_init__(self):
        for name, what in (("gamma", "the on-site damping"), ("eta", "the damping between neighbours")):
            object.__setattr__(self, name, check_real(name, getattr(self, name), what, 0.0, lo_open=False))
        if self.contact is not None and not isinstance(self.contact, ContactDissipation):
            raise ParameterError("contact", self.contact, "must be None or a contact dissipation (HuntCrossley(c), "
                                 "KuwabaraKono(eta))")

    @property
    def active(self) -> bool:
        """True when any term dissipates."""
        return self.gamma > 0.0 or self.eta > 0.0 or self.contact is not None


@dataclass(frozen=True)
class LatticeModel:
    """Interaction law, mass pattern and damping of the infinite chain; the default is the paper's (Hertz law
    with alpha = 3/2, m_n = 1, no damping)."""

    law: InteractionLaw = field(default_factory=HertzLaw)
    masses: tuple = (1.0,)
    damping: Damping = field(default_factory=Damping)
    #: the bonds' laws (issue 38 item 3): None, every bond has ``law``; or p laws, bond c joining beads c and c + 1
    #: of the p-bead mass pattern (bond n of a chain: law n mod p), ``law`` then bond 0's (:meth:`with_bonds`)
    bonds: Optional[tuple] = None

    def __post_init__(self):
        if not isinstance(self.law, InteractionLaw):
            raise ParameterError("law", self.law, "must be an InteractionLaw (V, V', V'' of a bond), e.g. HertzLaw()")
        self.law.check_consistency()
        masses = check_reals("masses", self.masses, "masses of the pattern", 0.0)    # b"1" is not (49.0,)
        object.__setattr__(self, "masses", masses)
        if not isinstance(self.damping, Damping):
            raise ParameterError("damping", self.damping, "must be a Damping(gamma, eta)")
        if self.bonds is not None:
            object.__setattr__(self, "bonds", self._check_bonds(self.bonds))
        if self.bonds is not None and self.damping.contact is not None:
            raise ParameterError("contact", self.damping.contact.describe(), "a dissipation in the contacts needs one "
                                 "law in every bond (bonds of different beads with contact dissipation: not yet)")

    def _check_bonds(self, bonds):
        """The bond pattern validated: p laws of one homogeneity degree (the wave problems rescale them alike), bond
        0's the model's ``law``; None when every bond has ``law`` (the identities of uniform chains unchanged)."""
        try:
            bonds = tuple(bonds)
        except TypeError:
            raise ParameterError("bonds", bonds, "must be None or a list of one law per bond of the pattern") \
                from None
        if len(bonds) != self.cell:
            raise ParameterError("bonds", len(bonds), f"must give one law per bond of the {self.cell}-bead pattern "
                                 f"(bond c joins beads c and c + 1): {self.cell} laws")
        for c, b in enumerate(bonds):
            if not isinstance(b, InteractionLaw):
                raise ParameterError("bonds", b, f"bond {c}: must be an InteractionLaw")
            b.check_consistency()
            if b.degree != self.law.degree or (b.separation is None) != (self.law.separation is None):
                raise ParameterError("bonds", b.describe(), f"bond {c}: must have the homogeneity degree of bond 0 "
                                     f"({self.law.degree}; the wave problems rescale every bond alike) and lose "
                                     "contact as it does (a separation, or none)")
        if bonds[0] != self.law:
            raise ParameterError("law", self.law.describe(), "must be bond 0's law when bonds are given "
                                 "(LatticeModel.with_bonds)")
        return None if all(b == self.law for b in bonds) else bonds

    @classmethod
    def hertz(cls, alpha: float = 1.5, masses: tuple = (1.0,), delta0: float = 0.0, gamma: float = 0.0,
              eta: float = 0.0) -> "LatticeModel":
        """The Hertzian chain with exponent alpha (eq. vhertz), the given mass pattern, precompression delta0 >= 0
        (static overlap of neighbours; 0 is the paper's uncompressed chain) and damping gamma, eta >= 0."""
        return cls(HertzLaw(alpha, delta0), masses, Damping(gamma, eta))

    def with_hertz_bonds(self, overlaps: Sequence[float], constants: Sequence[float]) -> "LatticeModel":
        """The same masses and damping with a pattern of Hertz bonds of this model's exponent (issue 38 item 3): bond
        c has the precompression ``overlaps[c]`` and the contact constant ``constants[c]`` relative to the force
        scale (1: the Hertz law itself; else :class:`~hertzpetsc.law.ScaledLaw`)."""
        if len(overlaps) != len(constants):
            raise ParameterError("constants", constants, f"one per bond ({len(overlaps)} overlaps)")
        laws = [HertzLaw(self.alpha, d) if k == 1.0 else ScaledLaw(HertzLaw(self.alpha, d), k)
                for d, k in zip(overlaps, constants)]
        return self.with_bonds(laws)

    # --- the parameters the studies continue in (one place each) ----------------------------------------------
    @property
    def alpha(self) -> float:
        """The law's parameter ``alpha`` if it has one (Hertz: its exponent), else its homogeneity degree."""
        return getattr(self.law, "alpha", self.law.scale_degree)

    @property
    def delta0(self) -> float:
        """The law's precompression ``delta0`` if it has one, else 0 (the paper's chain: 0)."""
        return getattr(self.law, "delta0", 0.0)

    @property
    def reference_amplitude(self) -> float:
        """The bond length at which the law's nonlinearity is of order one (Hertz: delta0; Toda: 1/b)."""
        return self.law.reference_amplitude

    @property
    def parameters(self) -> tuple:
        """The law's parameters by name (each a continuation parameter)."""
        return self.law.parameters

    def parameter(self, name: str) -> float:
        """The value of the law's parameter ``name``."""
        return self.law.parameter(name)

    def with_parameter(self, name: str, value: float) -> LatticeModel:
        """The same lattice with the law's parameter ``name`` replaced by value (the law's own class; a law without
        that parameter: ParameterError naming it); with a bond pattern, in every bond's law."""
        if self.bonds is not None:
            return self.with_bonds([b.with_parameter(name, value) for b in self.bonds])
        return self.with_law(self.law.with_parameter(name, value))

    def require_linear_stiffness(self, why: str) -> None:
        """ParameterError unless V''(0) > 0, naming the precompression delta0 for a law that has one (Hertz), else
        the law; ``why`` ends the message."""
        if not self.law.linear_stiffness > 0:
            if "delta0" in self.parameters:
                raise ParameterError("delta0", self.delta0, why)
            raise ParameterError("law", self.law.describe(), why.replace("a precompression > 0", "V''(0) > 0"))

    def with_law(self, law: InteractionLaw) -> LatticeModel:
        """The same masses and damping with another law in every bond."""
        return LatticeModel(law, self.masses, self.damping)

    def with_bonds(self, bonds: Sequence[InteractionLaw]) -> LatticeModel:
        """The same masses and damping with bond c's law bonds[c] (one per bead of the pattern)."""
        bonds = tuple(bonds)
        return LatticeModel(bonds[0] if bonds else self.law, self.masses, self.damping, bonds)

    def bond_law(self, c: int) -> InteractionLaw:
        """The law of bond c (joining beads c and c + 1; any integer: the pattern repeats)."""
        return self.law if self.bonds is None else self.bonds[c % self.cell]

    def with_masses(self, masses: Sequence[float]) -> LatticeModel:
        """The same laws with another mass pattern (of the same length when the bonds differ)."""
        return LatticeModel(self.law, masses, self.damping, self.bonds)

    def with_delta0(self, delta0: float) -> LatticeModel:
        """The same lattice with the law's precompression delta0 replaced (Hertz's; ParameterError for a law
        without one)."""
        return self.with_parameter("delta0", delta0)

    def with_alpha(self, alpha: float) -> LatticeModel:
        """The same lattice with the law's parameter alpha replaced (Hertz's exponent; ParameterError for a law
        without one)."""
        return self.with_parameter("alpha", alpha)

    def with_damping(self, gamma: float = 0.0, eta: float = 0.0) -> LatticeModel:
        """The same lattice with the linear damping gamma, eta (the contact dissipation kept)."""
        return LatticeModel(self.law, self.masses, Damping(gamma, eta, self.damping.contact), self.bonds)

    def rescaled(self, a: float) -> LatticeModel:
        """The model whose law is r -> a^(-d) V'(a r) (:meth:`~hertzpetsc.law.InteractionLaw.rescaled`): the
        lattice seen by the rescaled profiles w = u / a of the wave problems."""
        if self.bonds is not None:
            return self.with_bonds([b.rescaled(a) for b in self.bonds])
        return self.with_law(self.law.rescaled(a))

    @property
    def scale_invariant(self) -> bool:
        """True when x -> a x, t -> a^(-(d-1)/2) t maps the chain's motions to motions (eq. twper): a law
        homogeneous of degree d (no precompression) and no damping."""
        return not self.damped and self.rescaled(2.0) == self

    @property
    def cell(self) -> int:
        """Beads in the repeating mass pattern."""
        return len(self.masses)

    @property
    def uniform_masses(self) -> bool:
        """True when every bead has mass 1 (the paper's chain)."""
        return all(m == 1.0 for m in self.masses)

    @property
    def damped(self) -> bool:
        return self.damping.active

    # --- the forces, as every solver evaluates them ------------------------------------------------------------
    def force(self, r: ArrayLike, first: Optional[int] = None) -> np.ndarray:
        """V'(r), the force a bond of length r exerts (eq. vhertz); with a bond pattern, r[i] (along the first
        axis) is bond first + i's (``first`` None: one law in every bond, a ParameterError for a bond pattern)."""
        return self._bondwise("dV", r, first)

    def stiffness(self, r: ArrayLike, first: Optional[int] = None) -> np.ndarray:
        """V''(r), the bond's linearised stiffness (``first``: as :meth:`force`)."""
        return self._bondwise("d2V", r, first)

    def potential(self, r: ArrayLike, first: Optional[int] = None) -> np.ndarray:
        """V(r), the bond's energy (eq. ham; ``first``: as :meth:`force`)."""
        return self._bondwise("V", r, first)

    def _bondwise(self, what, r, first):
        if self.bonds is None:
            return getattr(self.law, what)(r)
        if first is None:
            raise ParameterError("bonds", [b.describe() for b in self.bonds], "this computation evaluates one law in "
                                 "every bond: bonds of different beads are not yet taken by it")
        r = np.asarray(r, dtype=float)
        out = np.empty_like(r)
        p = self.cell
        for c in range(p):
            out[c::p] = getattr(self.bonds[(first + c) % p], what)(r[c::p])
        return out

    def contact(self, r: ArrayLike) -> np.ndarray:
        """Bonds whose force or stiffness may be nonzero (the law's :meth:`contact`)."""
        return self.law.contact(r)

    def mass(self, n: ArrayLike) -> np.ndarray:
        """m_n for bead indices n (any integers: the pattern repeats)."""
        return np.asarray(self.masses)[np.mod(np.asarray(n), self.cell)]

    def require_conservative(self, what: str) -> None:
        """ParameterError if the model is damped (for computations of the Hamiltonian chain: travelling waves)."""
        if self.damped:
            raise ParameterError("damping", (self.damping.gamma, self.damping.eta),
                                 f"{what} needs the undamped chain (gamma = eta = 0, no contact dissipation)")

    # --- closed forms of the linear lattice ----------------------------------------------------------------
    def linear_frequencies(self, q: float) -> np.ndarray:
        """The p frequencies omega_1 <= ... <= omega_p of the linearised lattice (bond stiffnesses
        K_c = V_c''(0), no damping) at the per-bead wavenumber q: the eigenvalues of M^-1 B (:meth:`bloch_matrix` with
        mu+- = e^{+-iq}). p = 1: omega = 2 sqrt(K) sin(q/2) (the acoustic dispersion relation); p = 2:
        omega^2 = K [(1 + eps) -+ sqrt((1 + eps)^2 - 4 eps sin^2 q)] / eps for masses (1, eps)."""
        B = self.bloch_matrix(np.exp(1j * q), np.exp(-1j * q))
        w2 = np.sort(np.linalg.eigvals(B / np.asarray(self.masses)[:, None]).real)
        return np.sqrt(np.maximum(w2, 0.0))

    def bloch_matrix(self, mu_plus: complex, mu_minus: complex) -> np.ndarray:
        """The p x p stiffness matrix of the linearised lattice on a wave with shift symbols mu+- (the lattice's:
        e^{+-iq}; a scheme's: its stencils' symbols): B_cc = K_{c-1} + K_c, B_{c,c+1} = -K_c mu+, B_{c,c-1} =
        -K_{c-1} mu- (K_c = V_c''(0) of bond c, indices of the mass pattern, cyclic); real when both symbols are."""
        p = self.cell
        K = [self.bond_law(c).linear_stiffness for c in range(p)]
        B = np.zeros((p, p), dtype=np.result_type(mu_plus, mu_minus))
        for c in range(p):
            B[c, c] += K[c] + K[c - 1]
            B[c, (c + 1) % p] -= K[c] * mu_plus
            B[c, (c - 1) % p] -= K[c - 1] * mu_minus
        return B

    @classmethod
    def from_description(cls, description: dict) -> LatticeModel:
        """The model a :meth:`describe` dictionary describes (the law from the registry by name,
        :func:`~hertzpetsc.law.from_description`; a description without ``law`` is the Hertz chain's; the damping
        with its contact term, :func:`~hertzpetsc.dissipation.from_description`; ``bonds`` a list, or its JSON as
        :meth:`law_identity` writes it); keys of other objects (a chain's N, ends) are ignored."""
        bonds = description.get("bonds")
        bonds = json.loads(bonds) if isinstance(bonds, str) else bonds
        bonds = None if bonds is None else tuple(law_from_description(b) for b in bonds)
        return cls(law_from_description(description) if bonds is None else bonds[0],
                   tuple(description.get("masses", (1.0,))),
                   Damping(description.get("gamma", 0.0), description.get("eta", 0.0),
                           contact_from_description(description)), bonds)

    def law_identity(self) -> dict:
        """The law's keys in the identity of a record file that names alpha and delta0 (the precompressed families'):
        those two, as Hertz files always had them, and for any other law its description too (name, parameters), so
        that its file reopens as that law (:meth:`from_description`); bonds of laws of their own (a pattern of beads of
        different contact constants) add ``bonds``, their descriptions (a file without it has none:
        :data:`hertzpetsc.records.ABSENT`)."""
        out = dict(alpha=self.alpha, delta0=self.delta0)
        law = self.law.describe()
        out = out if "law" not in law else dict(out, **law)
        return out if self.bonds is None else dict(out, bonds=json.dumps([b.describe() for b in self.bonds],
                                                                          sort_keys=True))

    def describe(self) -> dict:
        """The model as plain data (for record identities and file metadata); delta0 and damping only when
        nonzero, so that the identities of the uncompressed chain's records are unchanged; the bonds' laws only when
        they differ (bond 0's law is also the model's)."""
        out = dict(self.law.describe())
        out["masses"] = list(self.masses)
        for name in ("gamma", "eta"):
            if getattr(self.damping, name) > 0.0:
                out[name] = getattr(self.damping, name)
        if self.damping.contact is not None:
            out.update(self.damping.contact.describe())
        if self.bonds is not None:
            out["bonds"] = [b.describe() for b in self.bonds]
        return out


# --- the ends of a finite chain ------------------------------------------------------------------------------------
class Signal:
    """A periodic motion x(t) of period ``period`` with its velocity; subclasses implement :meth:`position`
    and :meth:`velocity` (vectorised in t), and :attr:`time_scale`, the duration of the signal's shortest push (half
    a period of its fastest component: a pulse, a sample spacing), which limits the steps of every flow of a chain
    it drives (:attr:`ChainSpec.time_scale`): a push the chain's beads do not yet feel is invisible to the error
    estimate of a step that jumps it."""

    period = None

    @property
    def time_scale(self) -> float:
        raise NotImplementedError

    def position(self, t: ArrayLike) -> np.ndarray:
        raise NotImplementedError

    def velocity(self, t: ArrayLike) -> np.ndarray:
        raise NotImplementedError

    def describe(self) -> dict:
        raise NotImplementedError


# libm's cosine and sine, those of the compiled kernel, which moves harmonic actuators itself (numpy's own differ in
# the last bit): the numpy reference and the kernel stay equal to the bit
_cos = np.vectorize(math.cos, otypes=[float])
_sin = np.vectorize(math.sin, otypes=[float])


@dataclass(frozen=True)
class Harmonic(Signal):
    """x(t) = offset + amplitude cos(omega t + phase)."""

    amplitude: float
    omega: float
    phase: float = 0.0
    offset: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "amplitude", check_real("amplitude", self.amplitude, "the actuator amplitude", 0.0,
                                                         lo_open=False))
        object.__setattr__(self, "omega", check_real("omega", self.omega, "the driving frequency", 0.0))
        for name in ("phase", "offset"):
            object.__setattr__(self, name, check_real(name, getattr(self, name), f"the actuator's {name}"))

    @property
    def period(self) -> float:
        return 2 * math.pi / self.omega

    @property
    def time_scale(self) -> float:
        """Half a period: the actuator advances for half of it."""
        return 0.5 * self.period

    def position(self, t: ArrayLike) -> np.ndarray:
        return self.offset + self.amplitude * _cos(self.omega * np.asarray(t, float) + self.phase)

    def velocity(self, t: ArrayLike) -> np.ndarray:
        return -self.amplitude * self.omega * _sin(self.omega * np.asarray(t, float) + self.phase)

    def describe(self) -> dict:
        return dict(signal="harmonic", amplitude=self.amplitude, omega=self.omega, phase=self.phase,
                    offset=self.offset)


@dataclass(frozen=True)
class SampledSignal(Signal):
    """A periodic signal given by n equally spaced samples x(k period / n), k = 0..n-1, evaluated by its
    trigonometric interpolant (exact for band-limited signals; its derivative is the velocity)."""

    samples: tuple
    period: float

    def __post_init__(self):
        try:
            s = np.asarray(self.samples, dtype=float).ravel()
        except (TypeError, ValueError):
            raise ParameterError("samples", self.samples, "must be a list of real numbers") from None
        if len(s) < 2 or not np.all(np.isfinite(s)):
            raise ParameterError("samples", len(s), "at least 2 finite samples of one period")
        object.__setattr__(self, "samples", tuple(float(v) for v in s))
        object.__setattr__(self, "period", check_real("period", self.period, "the signal's period", 0.0))

    @property
    def time_scale(self) -> float:
        """The sample spacing (half the period of the interpolant's fastest component)."""
        return self.period / len(self.samples)

    def _series(self, t):
        """The interpolant's terms at t: the phases exp(2 pi i k t / period) (t, k), the coefficients c_k, and k."""
        n = len(self.samples)
        c = np.fft.rfft(np.asarray(self.samples)) / n
        k = np.arange(len(c))
        c = c * np.where((k == 0) | ((n % 2 == 0) & (k == n // 2)), 1.0, 2.0)
        return np.exp(2j * math.pi * np.multiply.outer(np.asarray(t, float) / self.period, k)), c, k

    def position(self, t: ArrayLike) -> np.ndarray:
        ph, c, _ = self._series(t)
        return (ph @ c).real

    def velocity(self, t: ArrayLike) -> np.ndarray:
        ph, c, k = self._series(t)
        return (ph @ (c * 2j * math.pi * k / self.period)).real

    def describe(self) -> dict:
        return dict(signal="samples", period=self.period, samples=list(self.samples))


class FunctionSignal(Signal):
    """x(t) = f(t) with velocity df(t), both periodic of ``period``; checked periodic at 64 points on creation.
    ``time_scale``: the duration of its shortest push (default: period / 64, the resolution of that check)."""

    def __init__(self, f: Callable[[np.ndarray], ArrayLike], df: Callable[[np.ndarray], ArrayLike], period: float,
                 name: str = "function", time_scale: Optional[float] = None) -> None:
        self.f, self.df, self.name = f, df, name
        self.period = check_real("period", period, "the signal's period", 0.0)
        self._time_scale = self.period / 64 if time_scale is None else \
            check_real("time_scale", time_scale, "the duration of the signal's shortest push", 0.0, self.period,
                       hi_open=False)
        t = np.linspace(0.0, self.period, 64, endpoint=False)
        for what, g in (("position", f), ("velocity", df)):
            a, b = np.asarray(g(t), float), np.asarray(g(t + self.period), float)
            scale = max(1.0, float(np.max(np.abs(a))))
            if a.shape != t.shape or not np.all(np.isfinite(a)) or np.max(np.abs(a - b)) > 1e-9 * scale:
                raise ParameterError("signal", name, f"its {what} is not periodic with the stated period "
                                     f"{self.period:g} (or not a finite vectorised function of t)")

    @property
    def time_scale(self) -> float:
        return self._time_scale

    def position(self, t: ArrayLike) -> np.ndarray:
        return np.asarray(self.f(np.asarray(t, float)), float)

    def velocity(self, t: ArrayLike) -> np.ndarray:
        return np.asarray(self.df(np.asarray(t, float)), float)

    def describe(self) -> dict:
        return dict(signal=self.name, period=self.period)


@dataclass(frozen=True)
class Actuator:
    """An end bead whose motion is the given :class:`Signal` (it is not an unknown of the chain)."""

    signal: Signal

    def __post_init__(self):
        if not isinstance(self.signal, Signal):
            raise ParameterError("signal", self.signal, "must be a Signal (Harmonic, SampledSignal, FunctionSignal)")

    def describe(self) -> dict:
        return dict(actuator=self.signal.describe())


@dataclass(frozen=True)
class ChainSpec:
    """A finite chain of ``model``: N beads and its ends. ``boundary`` 'periodic' (eq. pbcl), 'free' or 'fixed'
    (walls at rest, x_0 = x_{N+1} = 0) sets both ends; ``left`` / ``right`` override one end of a non-periodic
    chain with 'free', 'wall' or an :class:`Actuator` (e.g. the driven chain: left = Actuator(Harmonic(a, w)),
    right = 'wall')."""

    model: LatticeModel
    N: int
    boundary: str = "periodic"
    left: object = None
    right: object = None

    def __post_init__(self):
        if not isinstance(self.model, LatticeModel):
            raise ParameterError("model", self.model, "must be a LatticeModel")
        object.__setattr__(self, "N", check_integer("N", self.N, 1, "the number of beads"))
        if self.boundary not in BOUNDARIES:
            raise ParameterError("boundary", self.boundary, f"must be one of {', '.join(BOUNDARIES)}")
        if self.boundary == "periodic":
            if self.left is not None or self.right is not None:
                raise ParameterError("left" if self.left is not None else "right", self.left or self.right,
                                     "a periodic chain has no ends: give boundary 'free' or 'fixed' with left/right")
            if self.N < 2:
                raise ParameterError("N", self.N, "a periodic chain needs at least 2 beads")
        else:
            for side in ("left", "right"):
                end = getattr(self, side)
                end = ("free" if self.boundary == "free" else "wall") if end is None else end
                if not (isinstance(end, Actuator) or end in END_KINDS):
                    raise ParameterError(side, end, "an end is 'free', 'wall' or an Actuator(signal)")
                object.__setattr__(self, side, end)
        if self.N % self.model.cell:
            raise ParameterError("N", self.N, f"must be a multiple of the mass pattern's length {self.model.cell}")

    @classmethod
    def hertz(cls, alpha: float = 1.5, N: int = 100, boundary: str = "periodic", masses: Sequence[float] = (1.0,),
              delta0: float = 0.0, left: Union[str, Actuator, None] = None,
              right: Union[str, Actuator, None] = None) -> ChainSpec:
        """N beads of the Hertzian chain with exponent alpha (the paper's, with unit masses and no
        precompression, by default)."""
        return cls(LatticeModel.hertz(alpha, masses, delta0), N, boundary, left, right)

    @property
    def driven(self) -> bool:
        """True when an end is an actuator (the chain's equations depend on time)."""
        return isinstance(self.left, Actuator) or isinstance(self.right, Actuator)

    @property
    def time_scale(self) -> float:
        """The shortest :attr:`Signal.time_scale` of the actuators (inf without any): the steps of the chain's flows
        are limited by it (:class:`~hertzpetsc.chain.ChainIntegrator`)."""
        return min((end.signal.time_scale for end in (self.left, self.right) if isinstance(end, Actuator)),
                   default=math.inf)

    def with_length(self, N: int) -> ChainSpec:
        """The same lattice and ends on N beads."""
        return ChainSpec(self.model, N, self.boundary, self.left, self.right)

    def describe(self) -> dict:
        out = dict(self.model.describe(), N=self.N, boundary=self.boundary)
        for side in ("left", "right"):
            end = getattr(self, side)
            if isinstance(end, Actuator):
                out[side] = end.describe()
            elif end is not None and end != ("free" if self.boundary == "free" else "wall"):
                out[side] = end
        return out


# --- the drivers' options --------------------------------------------------------------------------------------------
def _command_line_laws() -> dict:
    """The registered laws a command line can build (:data:`hertzpetsc.law.LAWS`; the package's own are imported
    by this module): those whose parameters are all numbers with defaults (not the wrappers of another law)."""
    out = {}
    for name, cls in sorted(LAWS.items()):
        fs = fields(cls)
        if all(isinstance(f.default, (int, float)) and not isinstance(f.default, bool) for f in fs):
            out[name] = tuple(f.name for f in fs)
    return out


def law_options(opts, supported: bool = True, hertz_options: tuple = ("alpha", "delta0")) -> Optional[InteractionLaw]:
    """Declare and read the options of an interaction law (``opts`` an AppOptions): -law NAME (a registered law,
    :data:`hertzpetsc.law.LAWS`; hertz by default) and -law_<parameter> value for each parameter of the command
    line's laws by name (e.g. -law toda -law_k 1 -law_b 2; a parameter not given keeps the law's default). Returns
    the law, or None for Hertz (the driver's own -alpha, -delta0 as before; -law_<parameter> is not taken then). A
    driver whose computation is Hertz's alone (``supported`` False) declares -law only and refuses any other law;
    -beads (a Hertz chain) and the driver's Hertz options ``hertz_options`` (-alpha, -delta0) are refused beside
    another law, a -law_<parameter> the law has not, and a value the law refuses: one ParameterError naming the
    option."""
    if not supported:
        name = opts.string("law", "hertz", "the interaction law: hertz only in this driver (-alpha, -delta0)")
        if not opts.help and name.strip() != "hertz":
            raise ParameterError("-law", name, "this driver computes the Hertz chain only (-alpha, -delta0): other "
                                 "laws go through scripts/wave.py, driven_response.py and driven_resonances.py, or "
                                 "the API")
        return None
    laws = _command_line_laws()
    params = sorted({p for n, ps in laws.items() if n != "hertz" for p in ps})
    name = opts.string("law", "hertz", "the interaction law: " + "; ".join(
        f"{n} ({', '.join(ps)})" for n, ps in laws.items()) + " (hertz: by -alpha, -delta0)")
    given = {p: opts.string(f"law_{p}", "", f"-law: the law's parameter {p} (default: the law's)") for p in params}
    if opts.help:
        return None
    name = name.strip()
    given = {p: v for p, v in given.items() if opts.db.hasName(f"law_{p}")}
    if name not in laws:
        raise ParameterError("-law", name, "must be one of " + ", ".join(laws))
    if name == "hertz":
        if given:
            p = next(iter(given))
            raise ParameterError(f"-law_{p}", given[p], "the Hertz law is given by -alpha, -delta0 (-law_<parameter> "
                                 "goes with another -law)")
        return None
    for other in hertz_options + ("beads",):
        if opts.db.hasName(other):
            raise ParameterError(f"-{other}", opts.db.getString(other, ""), f"is the Hertz law's: with -law {name} "
                                 "give its parameters " + ", ".join(f"-law_{p}" for p in laws[name]))
    values = {}
    for p, text in given.items():
        if p not in laws[name]:
            raise ParameterError(f"-law_{p}", text, f"is not a parameter of the {name} law (its parameters: "
                                 + ", ".join(laws[name]) + ")")
        try:
            values[p] = float(text)
        except ValueError:
            raise ParameterError(f"-law_{p}", text, "must be a number") from None
    try:
        law = LAWS[name](**values)
        law.check_consistency()
    except ParameterError as err:
        raise ParameterError(f"-law_{err.name}" if err.name in laws[name] else "-law", err.value, err.valid) \
            from None
    return law
