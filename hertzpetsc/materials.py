"""A small table of bead materials (Young's modulus, Poisson ratio, density) with their sources.

Pure numpy-layer data, no PETSc. Values are nominal: a supplier's datasheet for the beads at hand is better, and
:class:`hertzpetsc.units.Bead` takes any values. The granular-crystal literature's usual values are used where it
has them (stainless steel 316 and PTFE beads of a few millimetres: C. Daraio, V. F. Nesterenko, E. B. Herbold and
S. Jin, Phys. Rev. E 73, 026610 (2006)); the others are handbook values (N. E. Dowling, *Mechanical Behavior of
Materials*, Table 5.2, for the moduli and Poisson ratios of brass and soda-lime glass; ASM's datasheet of 6061-T6;
densities from the same handbooks).
"""
from __future__ import annotations

from dataclasses import dataclass

from .errors import ParameterError, check_real


@dataclass(frozen=True)
class Material:
    """An isotropic elastic material: Young's modulus E [Pa], Poisson ratio nu in (-1, 1/2], density rho [kg/m^3],
    and where the values come from."""

    name: str
    youngs: float
    poisson: float
    density: float
    source: str = "given by value"

    def __post_init__(self):
        object.__setattr__(self, "youngs", check_real("youngs", self.youngs, "Young's modulus [Pa]", 0.0))
        object.__setattr__(self, "poisson", check_real("poisson", self.poisson, "the Poisson ratio", -1.0, 0.5,
                                                       hi_open=False))
        object.__setattr__(self, "density", check_real("density", self.density, "the density [kg/m^3]", 0.0))

    @property
    def plane_modulus(self) -> float:
        """E / (1 - nu^2), the modulus a Hertz contact sees [Pa]."""
        return self.youngs / (1.0 - self.poisson ** 2)


_DARAIO = "Daraio, Nesterenko, Herbold & Jin, Phys. Rev. E 73, 026610 (2006)"
MATERIALS = {m.name: m for m in (
    Material("steel", 193e9, 0.30, 8000.0, "stainless steel 316, as in " + _DARAIO),
    Material("chrome_steel", 200e9, 0.30, 7830.0, "AISI 52100 bearing steel, handbook values (E 200-210 GPa, "
             "nu 0.27-0.30, rho 7810-7830 kg/m^3)"),
    Material("brass", 101e9, 0.35, 8530.0, "brass 70Cu-30Zn: E, nu from Dowling, Mechanical Behavior of Materials, "
             "Table 5.2; rho handbook"),
    Material("aluminium", 68.9e9, 0.33, 2700.0, "aluminium 6061-T6, ASM datasheet"),
    Material("glass", 69e9, 0.20, 2500.0, "soda-lime glass: E, nu from Dowling, Mechanical Behavior of Materials, "
             "Table 5.2; rho handbook"),
    Material("ptfe", 1.46e9, 0.46, 2200.0, "PTFE (Teflon) beads, as in " + _DARAIO),
)}


def material(name: str) -> Material:
    """The table's material ``name`` (case-insensitive; 'aluminum' and 'teflon' are taken); ParameterError naming
    ``material`` for an unknown one."""
    key = name.strip().lower() if isinstance(name, str) else name
    key = {"aluminum": "aluminium", "teflon": "ptfe", "316": "steel"}.get(key, key)
    if key not in MATERIALS:
        raise ParameterError("material", name, "must be one of " + ", ".join(MATERIALS)
                             + " (or give youngs, poisson, density by value)")
    return MATERIALS[key]
