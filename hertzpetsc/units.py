"""Physical units: beads in SI, the Hertz contact constant, and the scales of the dimensionless chain (issue 38).

Two elastic spheres i, j pressed by a force F overlap by d with F = K_ij d^(3/2) (Hertz), where

    K_ij = (4/3) E* sqrt(R*),   1/E* = (1 - nu_i^2)/E_i + (1 - nu_j^2)/E_j,   1/R* = 1/R_i + 1/R_j

(a flat wall: R_j = inf), and a bead of radius R and density rho has the mass m = (4/3) pi R^3 rho. A chain of beads
whose bonds all have the same K, beads of masses m_n, pressed by a static force F0, is

    m_n x_n'' = K [(delta_s - (x_n - x_{n-1}))_+^(3/2) - (delta_s - (x_{n+1} - x_n))_+^(3/2)],
    delta_s = (F0 / K)^(2/3)  (the static overlap),

and with the length scale L, the mass scale m = m_0 (the first bead of the pattern) and the time scale
tau = sqrt(m / (K L^(1/2))), X = x / L, T = t / tau, it is the package's lattice (eq. nc with the Hertz law, eq.
vhertz, alpha = 3/2): masses m_n / m_0 and precompression delta0 = delta_s / L. :class:`BeadChain` chooses
L = delta_s (so delta0 = 1) unless a length scale is given; the sonic vacuum (F0 = 0) has no intrinsic length and
needs one. Forces scale by K L^(3/2), velocities by L / tau, angular frequencies by 1 / tau, and the wavenumber q
(per bead) by the spacing of the beads' centres (R_n + R_{n+1}: touching beads; the static overlap, a few
micrometres, is neglected in the spacing). Bonds of different beads (a pattern such as steel, steel, PTFE) have
constants K_c of their own: K is bond 0's and bond c is the Hertz law of overlap (F0 / K_c)^(2/3) / L scaled by
K_c / K (:meth:`BeadChain.model`, one law per bond: :attr:`hertzpetsc.model.LatticeModel.bonds`).

Closed forms (:meth:`BeadChain.sound_speed`, :meth:`BeadChain.cutoff_frequency`): the linearised bond stiffness
K_lin = (3/2) K^(2/3) F0^(1/3), the long-wave sound speed c0 = a sqrt(K_lin / m_mean) (a the spacing) and the
cut-off of the monatomic chain f_c = (1/pi) sqrt(K_lin / m) (omega_c = 2 sqrt(K_lin / m)). The solitary wave of the
uncompressed chain (paper appendix, eq. adr, computed at unit speed by :mod:`hertzpetsc.solitary`) scales as
x -> a x, t -> a^(-1/4) t: its speed at the maximal bead velocity v is c = (v / v1)^(1/5) (Nesterenko's law), v1
that of the unit-speed wave (:meth:`BeadChain.solitary_speed`).

Strings with units (:func:`parse_quantity`): a number and an SI unit with an optional prefix (p n u m c k M G T),
e.g. '4.76 mm', '193GPa', '10 N', '2 kHz', '1um', '8000 kg/m^3'; a bare number is in the SI unit.
Dissipation in the contacts (:mod:`hertzpetsc.dissipation`, :meth:`BeadChain.contact_damping`) by its coefficient in
SI or by a restitution e measured at an impact velocity v: Hunt-Crossley's c [s/m] is c* = c L / tau in the chain's
units, and e gives c = (1 - e) / v; Kuwabara-Kono's eta [N s / m^(3/2)] is eta* = eta / (K tau), and e gives eta*
from 1 - e = C eta* v*^(1/5) for the pattern's first two beads (the small-dissipation laws of
:mod:`hertzpetsc.dissipation`, first order in 1 - e: a restitution below :data:`MIN_RESTITUTION` is refused).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Callable, Optional, Sequence, Union

from numpy.typing import ArrayLike

import numpy as np

from .errors import ParameterError, check_real, members
from .dissipation import KINDS as CONTACT_KINDS, ContactDissipation, hunt_crossley_restitution, \
    kuwabara_kono_restitution
from .materials import MATERIALS, Material, material
from .model import Damping, LatticeModel

ALPHA = 1.5             # the Hertz exponent of elastic spheres
#: the smallest restitution converted to a contact damping by the small-dissipation laws (first order in 1 - e: the
#: coefficient's relative error is of order 1 - e, and the impact it gives has a restitution higher by about (1 - e)^2)
MIN_RESTITUTION = 0.9

# --- quantities with units -----------------------------------------------------------------------------------------
_PREFIXES = {"p": 1e-12, "n": 1e-9, "u": 1e-6, "\u00b5": 1e-6, "\u03bc": 1e-6, "m": 1e-3, "c": 1e-2, "k": 1e3,
             "M": 1e6, "G": 1e9, "T": 1e12}
# symbol: (factor to SI, dimension in (kg, m, s))
_UNITS = {"m": (1.0, (0, 1, 0)), "g": (1e-3, (1, 0, 0)), "s": (1.0, (0, 0, 1)), "N": (1.0, (1, 1, -2)),
          "Pa": (1.0, (1, -1, -2)), "Hz": (1.0, (0, 0, -1))}
# quantity: (dimension, SI unit as written)
QUANTITIES = {
    "length": ((0, 1, 0), "m"), "mass": ((1, 0, 0), "kg"), "time": ((0, 0, 1), "s"),
    "force": ((1, 1, -2), "N"), "pressure": ((1, -1, -2), "Pa"), "frequency": ((0, 0, -1), "Hz"),
    "density": ((1, -3, 0), "kg/m^3"), "velocity": ((0, 1, -1), "m/s"),
    "contact_constant": ((1, -0.5, -2), "N/m^1.5"), "dimensionless": ((0, 0, 0), ""),
    "slowness": ((0, -1, 1), "s/m"), "contact_damping": ((1, -0.5, -1), "N s/m^1.5"),
}
_NUMBER = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")
_ATOM = re.compile(r"^([A-Za-z\u00b5\u03bc]+)(?:\^([-+]?\d+(?:\.\d+)?))?$")


def _atom(text):
    """(factor, dimension) of one unit symbol with its prefix and power, e.g. 'mm', 'kPa', 'm^3'; None if unknown."""
    m = _ATOM.match(text)
    if not m:
        return None
    sym, power = m.group(1), float(m.group(2)) if m.group(2) else 1.0
    if sym in _UNITS:
        f, d = _UNITS[sym]
    elif sym[0] in _PREFIXES and sym[1:] in _UNITS:
        f, d = _UNITS[sym[1:]]
        f = f * _PREFIXES[sym[0]]
    else:
        return None
    return f ** power, tuple(x * power for x in d)


def _unit(text):
    """(factor, dimension) of a unit 'a*b/c^2' (parts separated by '*', '.' or spaces; '/' divides the rest)."""
    factor, dim = 1.0, (0.0, 0.0, 0.0)
    parts = text.split("/")
    for k, part in enumerate(parts):
        atoms = [a for a in re.split(r"[*\u00b7 ]+|(?<=[A-Za-z0-9])\.(?=[A-Za-z])", part) if a]
        if not atoms:
            return None
        for a in atoms:
            got = _atom(a)
            if got is None:
                return None
            sign = 1.0 if k == 0 else -1.0
            factor *= got[0] ** sign
            dim = tuple(x + sign * y for x, y in zip(dim, got[1]))
    return factor, dim


# a value in SI units: a number, or a string with its unit ('4.76 mm')
Quantity = Union[float, str]


def parse_quantity(name: str, value: Quantity, quantity: str, what: str = "") -> float:
    """``value`` (a number in SI units, or a string: a number and a unit, e.g. '4.76 mm', '193 GPa', '2 kHz') as a
    float in the SI unit of ``quantity`` (a key of QUANTITIES); a ParameterError naming ``name`` for a string that
    does not parse or a unit of another quantity."""
    dim, si = QUANTITIES[quantity]
    what = what or quantity.replace("_", " ")
    example = {"length": "'4.76 mm'", "force": "'10 N'", "pressure": "'193 GPa'", "frequency": "'2 kHz'",
               "density": "'8000 kg/m^3'", "velocity": "'0.1 m/s'", "mass": "'3.6 g'", "time": "'1 ms'",
               "contact_constant": "'8.5e9 N/m^1.5'"}.get(quantity, "'1'")
    rule = (f"{what} must be a number with a unit of {quantity.replace('_', ' ')}, e.g. {example} (SI prefixes "
            f"p n u m c k M G T; a bare number is in {si or 'no unit'})")
    if isinstance(value, str):
        m = _NUMBER.match(value)
        unit = _unit(m.group(2)) if m and m.group(2) else (1.0, dim) if m else None       # bare: in SI
        if unit is None or any(abs(a - b) > 1e-12 for a, b in zip(unit[1], dim)):
            raise ParameterError(name, value, rule)
        number = float(m.group(1)) * unit[0]
    elif isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool):
        number = float(value)
    else:
        raise ParameterError(name, value, rule)
    if not math.isfinite(number):
        raise ParameterError(name, value, rule)
    return number


# --- beads and their contacts --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Bead:
    """A sphere of ``radius`` [m] of an elastic ``material`` (a :class:`~hertzpetsc.materials.Material` or the
    name of one in :data:`~hertzpetsc.materials.MATERIALS`)."""

    material: Material
    radius: float

    def __post_init__(self):
        mat = material(self.material) if isinstance(self.material, str) else self.material
        if not isinstance(mat, Material):
            raise ParameterError("material", self.material, "must be a Material or one of " + ", ".join(MATERIALS))
        object.__setattr__(self, "material", mat)
        object.__setattr__(self, "radius", check_real("radius", parse_quantity("radius", self.radius, "length"),
                                                      "the bead's radius [m]", 0.0))

    @classmethod
    def of(cls, material_name: str = "steel", radius: Quantity = "4.76 mm", youngs: Optional[Quantity] = None,
           poisson: Optional[Quantity] = None, density: Optional[Quantity] = None) -> Bead:
        """A bead of the table's material, its values replaced by those given (numbers in SI or strings with
        units: youngs '200 GPa', density '7800 kg/m^3'); material_name 'custom' takes all three as given."""
        if material_name == "custom":
            if youngs is None or poisson is None or density is None:
                raise ParameterError("material", material_name, "a custom material needs youngs, poisson and "
                                     "density")
            base = Material("custom", 1.0, 0.0, 1.0)
        else:
            base = material(material_name)
        given = not (youngs is None and poisson is None and density is None)
        mat = Material(base.name + (" (values given)" if given and base.name != "custom" else ""),
                       base.youngs if youngs is None else parse_quantity("youngs", youngs, "pressure",
                                                                         "Young's modulus"),
                       base.poisson if poisson is None else parse_quantity("poisson", poisson, "dimensionless",
                                                                           "the Poisson ratio"),
                       base.density if density is None else parse_quantity("density", density, "density"),
                       "given by value" if given else base.source)
        return cls(mat, radius)

    @property
    def mass(self) -> float:
        """(4/3) pi R^3 rho [kg]."""
        return 4.0 / 3.0 * math.pi * self.radius ** 3 * self.material.density


def contact_constant(a: Bead, b: Optional[Bead] = None, wall: Optional[Material] = None) -> float:
    """K = (4/3) E* sqrt(R*) [N/m^(3/2)] of the contact of beads a and b, or of a and a flat ``wall`` (R = inf) when
    b is None."""
    other = b.material if b is not None else wall
    if other is None:
        raise ParameterError("b", b, "give the second bead or the wall's material")
    e_star = 1.0 / (1.0 / a.material.plane_modulus + 1.0 / other.plane_modulus)
    r_star = a.radius if b is None else 1.0 / (1.0 / a.radius + 1.0 / b.radius)
    return 4.0 / 3.0 * e_star * math.sqrt(r_star)


# --- the chain and its scales --------------------------------------------------------------------------------------
# quantity: (SI unit, the power of (L, tau, m, spacing) in it, the display unit and its factor)
_SCALES = {
    "length": ("m", (1, 0, 0, 0)), "time": ("s", (0, 1, 0, 0)), "mass": ("kg", (0, 0, 1, 0)),
    "velocity": ("m/s", (1, -1, 0, 0)), "force": ("N", (1, -2, 1, 0)), "energy": ("J", (2, -2, 1, 0)),
    "angular_frequency": ("rad/s", (0, -1, 0, 0)), "damping": ("kg/s", (0, -1, 1, 0)),
    "speed": ("m/s", (0, -1, 0, 1)), "wavenumber": ("rad/m", (0, 0, 0, -1)), "power": ("W", (2, -3, 1, 0)),
}
# how drivers show them: displacements in um, frequencies in Hz, speeds in m/s, forces in N
DISPLAY = {"length": ("um", 1e6), "frequency": ("Hz", 1.0), "velocity": ("m/s", 1.0), "speed": ("m/s", 1.0),
           "force": ("N", 1.0), "time": ("ms", 1e3)}


@dataclass(frozen=True)
class BeadChain:
    """A chain of beads (a pattern of :class:`Bead`, repeated) pressed by ``static_force`` F0 >= 0 [N], in the
    package's dimensionless units with the length scale ``length_scale`` [m] (default: the static overlap
    delta_s = (F0/K)^(2/3); needed when F0 = 0). Or, by value: ``masses`` [kg] of the pattern, the contact
    constant ``K`` [N/m^1.5] of every bond and the ``spacing`` of the beads' centres [m] (:meth:`by_value`).
    Bonds of different beads (e.g. steel, steel, PTFE) have their own constants K_c (:attr:`bond_constants`, bond c
    joining beads c and c + 1); K is then bond 0's, the scale of the chain's units, and bond c's law in them is the
    Hertz law with precompression (F0 / K_c)^(2/3) / L scaled by K_c / K (:meth:`model`). A pattern of one bead, or
    of two alternating, has equal bonds."""

    beads: tuple = ()
    static_force: float = 0.0
    length_scale: Optional[float] = None
    masses: tuple = ()
    K: float = 0.0
    spacing: float = 0.0

    def __post_init__(self):
        F0 = check_real("static_force", parse_quantity("static_force", self.static_force, "force"),
                        "the static force [N]", 0.0, lo_open=False)
        object.__setattr__(self, "static_force", F0)
        if self.beads:
            beads = tuple(members("beads", self.beads, "Beads"))
            for b in beads:
                if not isinstance(b, Bead):
                    raise ParameterError("beads", b, "must be a list of Bead(material, radius)")
            p = len(beads)
            bonds = [contact_constant(beads[c], beads[(c + 1) % p]) for c in range(p)]
            object.__setattr__(self, "beads", beads)
            object.__setattr__(self, "masses", tuple(b.mass for b in beads))
            object.__setattr__(self, "K", float(np.mean(bonds) if _equal(bonds) else bonds[0]))
            object.__setattr__(self, "spacing", float(np.mean([beads[c].radius + beads[(c + 1) % p].radius
                                                               for c in range(p)])))
        else:
            masses = tuple(parse_quantity("masses", m, "mass") for m in members("masses", self.masses, "masses"))
            if not masses or not all(m > 0 for m in masses):
                raise ParameterError("masses", self.masses, "give the beads, or the masses [kg] of the pattern, "
                                     "each > 0")
            object.__setattr__(self, "masses", masses)
            object.__setattr__(self, "K", check_real("K", parse_quantity("K", self.K, "contact_constant"),
                                                     "the contact constant [N/m^1.5]", 0.0))
            object.__setattr__(self, "spacing", check_real("spacing", parse_quantity("spacing", self.spacing,
                                                                                     "length"),
                                                           "the spacing of the beads' centres [m]", 0.0))
        if self.length_scale is None:
            if F0 == 0.0:
                raise ParameterError("length_scale", None, "the uncompressed chain (static_force = 0) has no "
                                     "intrinsic length: give a length scale [m], e.g. '1 um'")
        else:
            object.__setattr__(self, "length_scale", check_real(
                "length_scale", parse_quantity("length_scale", self.length_scale, "length"), "the length scale [m]",
                0.0))

    @classmethod
    def by_value(cls, masses: Sequence[Quantity], K: Quantity, spacing: Quantity, static_force: Quantity = 0.0,
                 length_scale: Optional[Quantity] = None) -> BeadChain:
        """A chain given by the masses [kg] of its pattern, the contact constant K [N/m^1.5] of its bonds and the
        spacing of its beads' centres [m] (numbers in SI or strings with units)."""
        return cls((), static_force, length_scale, tuple(members("masses", masses, "masses")), K, spacing)

    # --- the scales --------------------------------------------------------------------------------------------
    @property
    def static_overlap(self) -> float:
        """delta_s = (F0 / K)^(2/3) [m]."""
        return (self.static_force / self.K) ** (2.0 / 3.0)

    @property
    def L(self) -> float:
        """The length scale [m]."""
        return self.static_overlap if self.length_scale is None else self.length_scale

    @property
    def mass(self) -> float:
        """The mass scale: the first bead's mass [kg]."""
        return self.masses[0]

    @property
    def tau(self) -> float:
        """The time scale sqrt(m / (K L^(alpha-1))) [s]."""
        return math.sqrt(self.mass / (self.K * self.L ** (ALPHA - 1.0)))

    @property
    def bond_constants(self) -> tuple:
        """The contact constants K_c [N/m^1.5] of the pattern's bonds (bond c: beads c and c + 1); all K when the
        chain is given by value or its bonds are equal."""
        p = len(self.masses)
        if not self.beads:
            return (self.K,) * p
        bonds = [contact_constant(self.beads[c], self.beads[(c + 1) % p]) for c in range(p)]
        return (self.K,) * p if _equal(bonds) else tuple(bonds)

    @property
    def equal_bonds(self) -> bool:
        """True when every bond of the pattern has the constant K."""
        return all(k == self.K for k in self.bond_constants)

    def model(self, gamma: float = 0.0, eta: float = 0.0,
              contact: Optional[ContactDissipation] = None) -> LatticeModel:
        """The dimensionless lattice: the Hertz law (alpha = 3/2) with delta0 = delta_s / L, masses m_n / m_0,
        damping gamma, eta (dimensionless: gamma m / tau [kg/s] in SI) and the contact damping ``contact``
        (:meth:`contact_damping`, or None); bonds of different constants K_c: bond c's law
        k_c V'(r) with k_c = K_c / K and V the Hertz law of precompression (F0 / K_c)^(2/3) / L
        (:class:`~hertzpetsc.law.ScaledLaw`), since K_c [(d_c - x)^(3/2) - d_c^(3/2)] = K L^(3/2) k_c
        [(d_c / L - X)^(3/2) - (d_c / L)^(3/2)], d_c = (F0 / K_c)^(2/3)."""
        model = LatticeModel.hertz(ALPHA, tuple(m / self.mass for m in self.masses), self.static_overlap / self.L)
        model = LatticeModel(model.law, model.masses, Damping(gamma, eta, contact))
        if self.equal_bonds:
            return model
        constants = self.bond_constants
        return model.with_hertz_bonds([(self.static_force / Kc) ** (2.0 / 3.0) / self.L for Kc in constants],
                                      [1.0 if Kc == self.K else Kc / self.K for Kc in constants])

    def contact_damping(self, kind: str, coefficient: Optional[Quantity] = None,
                        restitution: Optional[float] = None, velocity: Optional[Quantity] = None,
                        clipped: bool = True) -> ContactDissipation:
        """The dissipation in the contacts in the chain's units (module docstring): ``kind`` 'hunt-crossley' (c
        [s/m]) or 'kuwabara-kono' (eta [N s/m^1.5]), given by its ``coefficient`` in SI, or by a ``restitution`` e
        in [MIN_RESTITUTION, 1) measured at the impact ``velocity`` v [m/s] of the pattern's first two beads."""
        if kind not in CONTACT_KINDS:
            raise ParameterError("kind", kind, f"must be one of {', '.join(CONTACT_KINDS)}")
        if (coefficient is None) == (restitution is None):
            raise ParameterError("coefficient" if coefficient is not None else "restitution", None,
                                 "give the contact damping's coefficient or a measured restitution, one of them")
        hunt = kind == "hunt-crossley"
        if coefficient is not None:
            value = parse_quantity("coefficient", coefficient, "slowness" if hunt else "contact_damping")
            value = check_real("coefficient", value, "the contact damping's coefficient", 0.0, lo_open=False)
            scaled = value * self.L / self.tau if hunt else value / (self.K * self.tau)
            return CONTACT_KINDS[kind](scaled, clipped)
        e = check_real("restitution", restitution, "a measured coefficient of restitution (the small-dissipation "
                       f"laws are first order in 1 - e)", MIN_RESTITUTION, 1.0, lo_open=False)
        if velocity is None:
            raise ParameterError("velocity", None, "the impact velocity [m/s] at which the restitution was measured")
        v = check_real("velocity", parse_quantity("velocity", velocity, "velocity"), "the impact velocity [m/s]", 0.0)
        v_star = v * self.tau / self.L
        if hunt:
            return CONTACT_KINDS[kind]((1.0 - e) / hunt_crossley_restitution(1.0, v_star), clipped)
        m0, m1 = self.masses[0], self.masses[1 % len(self.masses)]
        reduced = m0 * m1 / (m0 + m1) / self.mass
        return CONTACT_KINDS[kind]((1.0 - e) / kuwabara_kono_restitution(1.0, v_star, reduced, ALPHA), clipped)

    def _factor(self, quantity):
        if quantity == "frequency":
            return 1.0 / (2.0 * math.pi * self.tau)
        if quantity not in _SCALES:
            raise ParameterError("quantity", quantity, "must be one of " + ", ".join(list(_SCALES) + ["frequency"]))
        e = _SCALES[quantity][1]       # force m L / tau^2 = K L^(3/2), energy K L^(5/2): tau^2 = m / (K L^(1/2))
        return self.L ** e[0] * self.tau ** e[1] * self.mass ** e[2] * self.spacing ** e[3]

    def to_si(self, quantity: str, value: ArrayLike) -> Union[float, np.ndarray]:
        """A dimensionless value in SI: length [m], time [s], mass [kg], velocity [m/s], force [N], energy [J],
        angular_frequency [rad/s], frequency (from a dimensionless angular frequency omega: omega / (2 pi tau), in
        Hz), damping [kg/s], speed (beads per unit time, in m/s), wavenumber (q per bead, in rad/m)."""
        return np.asarray(value, dtype=float) * self._factor(quantity) if np.ndim(value) else \
            float(value) * self._factor(quantity)

    def from_si(self, quantity: str, value: Union[ArrayLike, str]) -> Union[float, np.ndarray]:
        """The inverse of :meth:`to_si` (value a number in SI, or a string with a unit where it has one)."""
        if isinstance(value, str):
            parsed = {"angular_frequency": "frequency", "speed": "velocity", "damping": None, "wavenumber": None,
                      "energy": None}.get(quantity, quantity)
            if parsed is None:
                raise ParameterError(quantity, value, "give a number in SI units")
            value = parse_quantity(quantity, value, parsed)
            if quantity == "angular_frequency":
                value = 2 * math.pi * value
        return np.asarray(value, dtype=float) / self._factor(quantity) if np.ndim(value) else \
            float(value) / self._factor(quantity)

    def show(self, quantity: str, value: float) -> str:
        """A dimensionless value as the drivers report it in SI ('12.3 um', '1523 Hz', '0.81 m/s')."""
        unit, f = DISPLAY.get(quantity, (_SCALES.get(quantity, ("",))[0], 1.0))
        return f"{self.to_si(quantity, value) * f:.6g} {unit}"

    # --- closed forms ------------------------------------------------------------------------------------------
    @property
    def linear_stiffness(self) -> float:
        """K_lin = (3/2) K^(2/3) F0^(1/3) [N/m], the stiffness of a precompressed bond."""
        return ALPHA * self.K ** (1.0 / ALPHA) * self.static_force ** (1.0 - 1.0 / ALPHA)

    def sound_speed(self) -> float:
        """c0 = a sqrt(K_lin / m_mean) [m/s], the long-wave speed of the precompressed chain (a the spacing); bonds
        that differ: K_lin the stiffness of the pattern's bonds in series, 1 / K_lin = mean(1 / K_lin,c)."""
        self._require_force("the sound speed")
        k = self.linear_stiffness if self.equal_bonds else 1.0 / float(np.mean(
            [1.0 / (ALPHA * Kc ** (1.0 / ALPHA) * self.static_force ** (1.0 - 1.0 / ALPHA))
             for Kc in self.bond_constants]))
        return self.spacing * math.sqrt(k / float(np.mean(self.masses)))

    def cutoff_frequency(self) -> float:
        """The highest frequency of linear waves [Hz]: f_c = (1/pi) sqrt(K_lin / m) for one bead, the top of the
        optical band sqrt(2 K_lin (1/m_1 + 1/m_2)) / (2 pi) for two."""
        self._require_force("the cut-off frequency")
        k, m = self.linear_stiffness, self.masses
        if len(m) == 1:
            return math.sqrt(k / m[0]) / math.pi
        if len(m) == 2:
            return math.sqrt(2 * k * (1 / m[0] + 1 / m[1])) / (2 * math.pi)
        raise ParameterError("beads", len(m), "the cut-off's closed form is for patterns of one or two beads (the "
                             "model's linear_frequencies computes any)")

    def _require_force(self, what):
        if not self.static_force > 0:
            raise ParameterError("static_force", self.static_force, f"{what} needs a precompression (> 0): the "
                                 "uncompressed chain has no linear waves")

    def solitary_speed(self, max_velocity: Quantity, unit_velocity: float) -> float:
        """The speed [m/s] of the uncompressed chain's solitary wave whose beads reach ``max_velocity`` [m/s]
        (a number or a string with a unit): c = (v / v1)^((alpha-1)/(alpha+1)) beads per unit time (x -> a x,
        t -> a^(-(alpha-1)/2) t), v1 = ``unit_velocity``, the dimensionless maximal bead velocity of the
        unit-speed wave (:func:`hertzpetsc.solitary.max_bead_velocity`)."""
        if self.static_force > 0 or len(self.masses) != 1:
            raise ParameterError("static_force" if self.static_force > 0 else "beads", self.static_force
                                 if self.static_force > 0 else len(self.masses), "the solitary wave's scaling "
                                 "v^(1/5) is that of the uncompressed chain of one bead (static_force = 0)")
        v = check_real("max_velocity", parse_quantity("max_velocity", max_velocity, "velocity"),
                       "the maximal bead velocity [m/s]", 0.0)
        V = self.from_si("velocity", v)
        c = (V / check_real("unit_velocity", unit_velocity, "the unit wave's maximal velocity", 0.0)) ** \
            ((ALPHA - 1.0) / (ALPHA + 1.0))
        return self.to_si("speed", c)

    def columns(self, record: Any, columns: Sequence[tuple[str, str, Callable[[Any], float]]]) -> list[str]:
        """The SI values of one record as the drivers show them: ``columns`` is [(label, quantity, value(record))];
        each value is converted by :meth:`to_si` and shown in :data:`DISPLAY`'s unit."""
        out = []
        for _, quantity, value in columns:
            unit, f = DISPLAY.get(quantity, (_SCALES.get(quantity, ("",))[0], 1.0))
            out.append(f"{self.to_si(quantity, float(value(record))) * f:.6g}")
        return out

    def table(self, records: Sequence[Any], columns: Sequence[tuple[str, str, Callable[[Any], float]]],
              lead: Sequence[tuple[str, Callable[[Any], float]]] = ()) -> str:
        """A Markdown section of the records in SI units: the chain and its scales, then one row per record with
        the dimensionless ``lead`` columns [(label, value(record)): a number, or text as it is] and the SI
        ``columns`` (:meth:`columns`)."""
        heads = [label for label, _ in lead] + \
            [f"{label} [{DISPLAY.get(q, (_SCALES.get(q, ('',))[0],))[0]}]" for label, q, _ in columns]
        lines = ["", "## In SI units", "", "\n\n".join(x[2:] for x in self.summary().splitlines()), "",
                 "| " + " | ".join(heads) + " |", "|" + "---|" * len(heads)]
        for r in records:
            lines.append("| " + " | ".join([v(r) if isinstance(v(r), str) else f"{float(v(r)):.6g}" for _, v in lead]
                                           + self.columns(r, columns))
                         + " |")
        return "\n".join(lines) + "\n"

    def describe(self) -> dict:
        """The chain and its scales as plain data (SI)."""
        out = dict(K=self.K, static_force=self.static_force, static_overlap=self.static_overlap,
                   masses=list(self.masses), spacing=self.spacing, L=self.L, tau=self.tau)
        if not self.equal_bonds:
            out["bond_constants"] = list(self.bond_constants)
        if self.beads:
            out["beads"] = [dict(material=b.material.name, radius=b.radius, youngs=b.material.youngs,
                                 poisson=b.material.poisson, density=b.material.density) for b in self.beads]
        return out

    # --- the API's results in SI ---------------------------------------------------------------------------
    def check_chain(self, model: LatticeModel, what: str = "the chain") -> None:
        """ParameterError unless ``model`` is these beads' chain (law, bonds and masses; the damping may be any)."""
        mine = self.model()
        if (model.law, model.bonds, model.masses) != (mine.law, mine.bonds, mine.masses):
            raise ParameterError("beads", self.describe().get("beads", self.masses), f"{what} is not on these beads' "
                                 f"chain (its model {model.describe()}, the beads' {mine.describe()})")

    def wave_si(self, orbit: Any) -> dict:
        """A travelling wave (:class:`~hertzpetsc.waves.Orbit`: ``hz.wave(model, ..., beads=chain)``,
        ``hz.refine(...).orbit``) on these beads in SI units: frequency [Hz], angular_frequency [rad/s], period
        [s] (2 pi / omega), phase_speed [m/s] (omega / q beads per unit time), wavenumber [rad/m] (q per bead
        spacing), amplitude [m] (the wave's size max |u|), and at t = 0 the beads' displacement [m] and velocity
        [m/s] from rest (N each) and the contact forces [N] of the N bonds of the periodic chain (static force
        included: F0 - K L^(3/2) V'(r), bond n joining beads n, n + 1)."""
        self.check_chain(orbit.spec.model, "the wave")
        model, x = orbit.spec.model, np.asarray(orbit.x, float)
        r = np.roll(x[:, 0], -1) - x[:, 0]            # periodic: bond N - 1 joins beads N - 1 and 0
        force = self.static_force - self.to_si("force", np.asarray(model.force(r, 0), float))
        omega = float(orbit.omega)
        return dict(frequency=self.to_si("frequency", omega), angular_frequency=self.to_si("angular_frequency", omega),
                    period=self.to_si("time", 2 * math.pi / omega), phase_speed=self.to_si("speed", omega / orbit.q),
                    wavenumber=self.to_si("wavenumber", orbit.q), amplitude=self.to_si("length", orbit.amplitude),
                    displacement=self.to_si("length", x[:, 0]), velocity=self.to_si("velocity", x[:, 1]),
                    force=force)

    def response_si(self, response: Any) -> dict:
        """A periodic response of a driven chain of these beads (:class:`~hertzpetsc.driven.Response`, from
        ``hz.response(drive, ..., beads=chain)``) in SI units: frequency [Hz] and period [s] of the drive and of the
        response (k periods), drive_amplitude [m], the state at t = 0 (displacement [m], velocity [m/s]); from its
        record when it has one: force_right, force_left [N] (the largest force on the wall and on the actuator beyond
        the static force F0), amp_first, amp_last, amp_max [m] (bead amplitudes), power_in, dissipation [W] (means
        over the period), as ``scripts/driven_response.py -beads`` shows them."""
        self.check_chain(response.drive.model, "the response")
        x = np.asarray(response.x, float)
        out = dict(frequency=self.to_si("frequency", response.omega), period=self.to_si("time", response.T),
                   drive_amplitude=self.to_si("length", response.drive.amplitude),
                   displacement=self.to_si("length", x[:, 0]), velocity=self.to_si("velocity", x[:, 1]))
        rec = response.record or {}
        for name, quantity in (("force_right", "force"), ("force_left", "force"), ("amp_first", "length"),
                               ("amp_last", "length"), ("amp_max", "length"), ("power_in", "power"),
                               ("dissipation", "power")):
            if name in rec:
                out[name] = self.to_si(quantity, float(rec[name]))
        return out

    def summary(self) -> str:
        """Lines stating the chain, its constants and scales (the drivers print them)."""
        what = " / ".join(f"{b.material.name} R = {b.radius * 1e3:g} mm" for b in self.beads) if self.beads \
            else "masses " + ", ".join(f"{m:.4g} kg" for m in self.masses)
        lines = [f"# beads: {what}; K = {self.K:.6g} N/m^1.5, m = {self.mass:.6g} kg, spacing {self.spacing:.6g} m",
                 f"# static force F0 = {self.static_force:g} N, static overlap {self.static_overlap * 1e6:.6g} um; "
                 f"scales L = {self.L * 1e6:.6g} um, tau = {self.tau * 1e6:.6g} us, velocity L/tau = "
                 f"{self.L / self.tau:.6g} m/s, force K L^1.5 = {self._factor('force'):.6g} N"]
        if self.static_force > 0 and len(self.masses) <= 2:
            lines.append(f"# sound speed c0 = {self.sound_speed():.6g} m/s, cut-off f_c = "
                         f"{self.cutoff_frequency():.6g} Hz (closed forms)")
        return "\n".join(lines)


def _equal(constants):
    """True when the contact constants agree to round-off (a pattern of two beads alternating: K_01 = K_10)."""
    return max(constants) - min(constants) <= 1e-12 * max(constants)


# --- the drivers' options ----------------------------------------------------------------------------------------
BEAD_OPTIONS = ("beads", "radius", "youngs", "poisson", "density", "static_force", "length_scale")


def bead_options(opts, replaces=("alpha", "delta0", "masses"), beads="", static_force="0N", length_scale="",
                 refused="", one_bead="", equal_bonds="", free="") -> Optional[BeadChain]:
    """Declare and read the options of a chain in SI units (``opts`` an AppOptions): -beads (materials of the
    pattern, e.g. steel or steel,ptfe; 'custom' with -youngs, -poisson, -density), -radius (one, or one per bead),
    -youngs, -poisson, -density (replace the table's values), -static_force, -length_scale. Returns the
    :class:`BeadChain`, or None without -beads (the dimensionless options alone, as before). With -beads the
    dimensionless options ``replaces`` (the exponent, -delta0, -masses) may not be given: the beads define them.
    ``beads``, ``static_force``, ``length_scale``: the defaults (a driver whose chain is always one of beads; a free
    chain's scale). What a driver cannot compute is refused with the reason given (a ParameterError naming the
    option; each reason says which command computes it): ``refused`` any chain of beads, ``one_bead`` a pattern of
    several beads, ``equal_bonds`` bonds of different contact constants, ``free`` a static force (a free chain)."""
    names = opts.string("beads", beads, f"refused by this driver: {refused}" if refused else "bead materials of the "
                        "pattern, comma-separated, from " + ", ".join(MATERIALS) + " or custom (none: the "
                        "dimensionless chain of -delta0, -masses)")
    radius = opts.string("radius", "4.76mm", "-beads: radius, or one per bead (e.g. 4.76mm)")
    youngs = opts.string("youngs", "", "-beads: Young's modulus (e.g. 193GPa), replacing the table's")
    poisson = opts.string("poisson", "", "-beads: Poisson ratio in (-1, 0.5], replacing the table's")
    density = opts.string("density", "", "-beads: density (e.g. 8000kg/m^3), replacing the table's")
    force = opts.string("static_force", static_force, "-beads: the static force pressing the chain (precompression)")
    length = opts.string("length_scale", length_scale, "-beads: the length scale (default: " + (
        length_scale if length_scale else "the static overlap, so that delta0 = 1; needed when -static_force is 0")
        + ")")
    if opts.help:
        return None
    if refused:
        given = [name for name in BEAD_OPTIONS if opts.db.hasName(name)]
        if given:
            raise ParameterError(f"-{given[0]}", opts.db.getString(given[0], ""), refused)
        return None
    if not names.strip():
        given = [name for name in BEAD_OPTIONS[1:] if opts.db.hasName(name)]
        if given:
            raise ParameterError(f"-{given[0]}", opts.db.getString(given[0], ""), "describes beads: give -beads "
                                 "(e.g. steel) too")
        return None
    if free and opts.db.hasName("static_force"):
        raise ParameterError("-static_force", force, free)
    for name in replaces:
        if opts.db.hasName(name):
            raise ParameterError(f"-{name}", opts.db.getString(name, ""), "is defined by -beads (the Hertz exponent "
                                 "3/2, the precompression by -static_force, the masses by the beads): give one or "
                                 "the other")
    kinds = [v.strip() for v in names.split(",")]
    if one_bead and len(kinds) > 1:
        raise ParameterError("-beads", names, one_bead)
    radii = [v.strip() for v in radius.split(",")]
    if len(radii) not in (1, len(kinds)) or "" in radii:
        raise ParameterError("-radius", radius, f"give one radius or one per bead ({len(kinds)})")
    radii = radii * len(kinds) if len(radii) == 1 else radii
    beads = []
    for kind, r in zip(kinds, radii):
        try:
            beads.append(Bead.of(kind, r, youngs or None, poisson or None, density or None))
        except ParameterError as err:
            raise ParameterError(f"-{'beads' if err.name == 'material' else err.name}", err.value, err.valid) \
                from None
    try:
        chain = BeadChain(tuple(beads), force, length or None)
    except ParameterError as err:
        raise ParameterError(f"-{err.name}", err.value, err.valid) from None
    if equal_bonds and not chain.equal_bonds:
        raise ParameterError("-beads", names, f"its bonds have different contact constants ("
                             + ", ".join(f"{k:.4g}" for k in chain.bond_constants) + " N/m^1.5): " + equal_bonds)
    return chain


def si_numbers(opts, chain: Optional[BeadChain], name: str, quantity: str, help: str, instead: str) -> Optional[list]:
    """Declare and read -``name``, a comma-separated list of positive values in SI units of ``quantity`` (a key of
    both :data:`_SCALES` and :data:`QUANTITIES`: length, velocity) for a driver with -beads, e.g. -impact_velocities
    1mm/s,1cm/s: the dimensionless values (:meth:`BeadChain.from_si`), or None when not given. Refused without
    -beads (``chain`` None) and beside the dimensionless option -``instead``."""
    text = opts.string(name, "", f"-beads: {help} in SI units, comma-separated, instead of -{instead}")
    if opts.help or not text.strip():
        return None
    if chain is None:
        raise ParameterError(f"-{name}", text, f"is in SI units: give the beads (-beads) too, or -{instead}")
    if opts.db.hasName(instead):
        raise ParameterError(f"-{instead}", opts.db.getString(instead, ""), f"give one of -{instead} (dimensionless) "
                             f"and -{name} (SI)")
    values = [check_real(f"-{name}", parse_quantity(f"-{name}", v.strip(), quantity), f"every value of -{name}", 0.0)
              for v in text.split(",")]
    return [float(chain.from_si(quantity, v)) for v in values]


def impact_damping(opts, chain: Optional[BeadChain], contact: str, damping: float, coefficient: str) -> float:
    """The contact damping of the free-chain studies (restitution, pulse decay): ``damping`` (-damping, the chain's
    units), or with -beads (``chain``) the SI ``coefficient`` (-contact_coefficient: Hunt-Crossley c in s/m,
    Kuwabara-Kono eta in N s/m^1.5) in the chain's units; one of them."""
    if not coefficient:
        return damping
    if chain is None:
        raise ParameterError("-contact_coefficient", coefficient, "is in SI units: give the beads (-beads) too, or "
                             "-damping")
    if opts.db.hasName("damping"):
        raise ParameterError("-damping", opts.db.getString("damping", ""), "give one of -damping "
                             "(dimensionless) and -contact_coefficient (SI)")
    try:
        law = chain.contact_damping(contact, coefficient=coefficient)
    except ParameterError as err:
        raise ParameterError("-contact_coefficient", err.value, err.valid) from None
    return law.c if contact == "hunt-crossley" else law.eta


def contact_options(opts, chain: Optional[BeadChain] = None, si: bool = False) -> Optional[ContactDissipation]:
    """Declare and read the options of a dissipation in the contacts (:mod:`hertzpetsc.dissipation`; the driven
    drivers): -contact none|hunt-crossley|kuwabara-kono (also spelt with '_'), -contact_damping (Hunt-Crossley's c
    or Kuwabara-Kono's eta in the chain's units), -unclipped (a contact may pull); with ``si`` (a driver that takes
    -beads) also -contact_coefficient (the coefficient in SI: c in s/m, eta in N s/m^1.5) or -restitution e with
    -impact_velocity v (a restitution measured at that impact velocity), converted by
    :meth:`BeadChain.contact_damping` for ``chain`` (refused without -beads). Returns the contact damping, or None
    (-contact none, the default: no option of a contact may then be given)."""
    kind = opts.string("contact", "none", "dissipation in the contacts: none, " + ", ".join(CONTACT_KINDS)
                       + " (or with '_')")
    value = opts.real("contact_damping", 0.0, "-contact: Hunt-Crossley c or Kuwabara-Kono eta (the chain's units)",
                      valid=(lambda x: x >= 0, ">= 0"))
    unclipped = opts.flag("unclipped", "-contact: let a contact pull (no clipping of the contact force at 0)")
    named = ["contact_damping", "unclipped"]
    if si:
        coefficient = opts.string("contact_coefficient", "", "-contact with -beads: the coefficient in SI units "
                                  "(Hunt-Crossley c, e.g. 0.05s/m; Kuwabara-Kono eta in N s/m^1.5)")
        restitution = opts.string("restitution", "", "-contact with -beads: a coefficient of restitution in "
                                  f"[{MIN_RESTITUTION:g}, 1), measured at -impact_velocity, instead of a coefficient")
        velocity = opts.string("impact_velocity", "", "-restitution: the impact velocity it was measured at "
                               "(e.g. 0.1m/s)")
        named += ["contact_coefficient", "restitution", "impact_velocity"]
    if opts.help:
        return None
    kind = kind.strip().replace("_", "-")
    if kind == "none":
        given = [name for name in named if opts.db.hasName(name)]
        if given:
            raise ParameterError(f"-{given[0]}", opts.db.getString(given[0], ""), "describes a dissipation in the "
                                 "contacts: give -contact (" + ", ".join(CONTACT_KINDS) + ") too")
        return None
    if kind not in CONTACT_KINDS:
        raise ParameterError("-contact", kind, "must be one of none, " + ", ".join(CONTACT_KINDS))
    clipped = not unclipped
    given = [name for name in ("contact_damping", "contact_coefficient", "restitution")[:3 if si else 1]
             if opts.db.hasName(name)]
    if len(given) != 1:
        raise ParameterError("-contact", kind, "give its damping by one of -contact_damping (the chain's units)"
                             + (", -contact_coefficient (SI) or -restitution with -impact_velocity (with -beads)"
                                if si else "") + (f"; not both -{given[0]} and -{given[1]}" if given else ""))
    if given[0] == "contact_damping":
        return CONTACT_KINDS[kind](value, clipped)
    if chain is None:
        raise ParameterError(f"-{given[0]}", opts.db.getString(given[0], ""), "is in SI units: give the beads "
                             "(-beads) too, or -contact_damping in the chain's units")
    if given[0] == "restitution":
        try:
            e = float(restitution)
        except ValueError:
            raise ParameterError("-restitution", restitution, "must be a number in "
                                 f"[{MIN_RESTITUTION:g}, 1)") from None
        if not velocity:
            raise ParameterError("-impact_velocity", None, "-restitution needs the impact velocity it was measured "
                                 "at (e.g. 0.1m/s)")
        args = dict(restitution=e, velocity=velocity)
    else:
        if velocity:
            raise ParameterError("-impact_velocity", velocity, "goes with -restitution, not -contact_coefficient")
        args = dict(coefficient=coefficient)
    try:
        return chain.contact_damping(kind, clipped=clipped, **args)
    except ParameterError as err:
        name = {"coefficient": "contact_coefficient", "velocity": "impact_velocity"}.get(err.name, err.name)
        raise ParameterError(f"-{name}", err.value, err.valid) from None
