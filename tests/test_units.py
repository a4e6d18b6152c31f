"""Physical units (issue 38 item 4): quantities with units, materials, the Hertz constant of two spheres, the scales
of the dimensionless chain, the closed forms of a steel chain in SI (sound speed, cut-off) against the package's
linear lattice converted back, the solitary wave's speed in m/s, and bad input from the API and the command line."""
import math
import os
import re

import numpy as np
import pytest

import hertzpetsc as hz
from conftest import ROOT, one_error_line, run_script
from hertzpetsc.errors import ParameterError
from hertzpetsc.materials import MATERIALS, Material, material
from hertzpetsc.model import LatticeModel
from hertzpetsc.units import Bead, BeadChain, contact_constant, parse_quantity

# a steel chain as a datasheet gives it: stainless steel 316 beads of 4.76 mm radius pressed by 10 N
E, NU, RHO, R, F0 = 193e9, 0.30, 8000.0, 4.76e-3, 10.0
STEEL = BeadChain((Bead("steel", "4.76 mm"),), "10 N")


def datasheet_constants(E=E, nu=NU, rho=RHO, R=R, F0=F0):
    """K, m and K_lin of the steel chain written out from the datasheet (the formulas of the docs, not the code's)."""
    K = 4 / 3 * (E / (2 * (1 - nu ** 2))) * math.sqrt(R / 2)
    m = 4 / 3 * math.pi * R ** 3 * rho
    return K, m, 1.5 * K ** (2 / 3) * F0 ** (1 / 3)


@pytest.mark.parametrize("text, quantity, value", [
    ("4.76 mm", "length", 4.76e-3), ("4.76mm", "length", 4.76e-3), ("3 um", "length", 3e-6),
    ("3 \u00b5m", "length", 3e-6), ("0.5", "length", 0.5), ("193 GPa", "pressure", 193e9), ("10 N", "force", 10.0),
    ("2.5 mN", "force", 2.5e-3), ("2 kHz", "frequency", 2000.0), ("1 ms", "time", 1e-3),
    ("8000 kg/m^3", "density", 8000.0), ("8 g/cm^3", "density", 8000.0), ("0.1 m/s", "velocity", 0.1),
    ("3.6 g", "mass", 3.6e-3), ("6.9e9 N/m^1.5", "contact_constant", 6.9e9), ("0.3", "dimensionless", 0.3)])
def test_quantities_parse_to_si(text, quantity, value):
    assert parse_quantity("x", text, quantity) == pytest.approx(value, rel=1e-14)


@pytest.mark.parametrize("text, quantity", [("5 furlongs", "length"), ("5 N", "length"), ("", "force"),
                                            ("ten N", "force"), ("1e400 m", "length"), ("2 kHz/", "frequency"),
                                            ("3 Hz", "time"), ("0.3 m", "dimensionless")])
def test_a_quantity_that_does_not_parse_is_refused_naming_it(text, quantity):
    with pytest.raises(ParameterError) as err:
        parse_quantity("radius", text, quantity)
    assert err.value.name == "radius" and "e.g." in err.value.valid


def test_materials_have_sources_and_bad_values_name_their_argument():
    assert {"steel", "brass", "aluminium", "glass", "ptfe"} <= set(MATERIALS)
    assert all(m.source and 0 < m.youngs and -1 < m.poisson <= 0.5 and m.density > 0 for m in MATERIALS.values())
    assert material("Aluminum") is MATERIALS["aluminium"] and material("teflon") is MATERIALS["ptfe"]
    for kw, name in ((dict(youngs=-1e9), "youngs"), (dict(poisson=0.6), "poisson"), (dict(poisson=-1.0), "poisson"),
                     (dict(density=0.0), "density")):
        with pytest.raises(ParameterError) as err:
            Material("x", **{**dict(youngs=1e9, poisson=0.3, density=1e3), **kw})
        assert err.value.name == name
    Material("incompressible", 1e6, 0.5, 1e3)                 # nu = 1/2 is in (-1, 1/2]
    with pytest.raises(ParameterError) as err:
        Bead("unobtainium", 1e-3)
    assert err.value.name == "material" and "steel" in err.value.valid
    with pytest.raises(ParameterError) as err:
        Bead.of("steel", "5 mm", youngs="-193 GPa")
    assert err.value.name == "youngs"
    with pytest.raises(ParameterError) as err:
        Bead("steel", "-1 mm")
    assert err.value.name == "radius"


def test_the_hertz_constant_of_two_spheres_and_of_a_sphere_on_a_wall():
    steel, ptfe = Bead("steel", R), Bead("ptfe", 2 * R)
    K, m, _ = datasheet_constants()
    assert contact_constant(steel, steel) == pytest.approx(K, rel=1e-14)
    assert steel.mass == pytest.approx(m, rel=1e-14)
    # two materials: 1/E* sums the two, 1/R* too
    e_star = 1 / ((1 - NU ** 2) / E + (1 - 0.46 ** 2) / 1.46e9)
    assert contact_constant(steel, ptfe) == pytest.approx(4 / 3 * e_star * math.sqrt(1 / (1 / R + 1 / (2 * R))),
                                                          rel=1e-14)
    # a flat wall of the same steel: R* = R
    assert contact_constant(steel, wall=steel.material) == pytest.approx(4 / 3 * E / (2 * (1 - NU ** 2)) *
                                                                         math.sqrt(R), rel=1e-14)


def test_the_steel_chain_sound_speed_and_cutoff_match_their_closed_forms_in_si():
    """The package's dimensionless lattice (delta0 = 1 at the static overlap), its linear frequencies converted to
    SI, against c0 = 2R sqrt(K_lin / m), f_c = sqrt(K_lin / m) / pi written from the datasheet. omega(q) / q at
    q = 1e-3 differs from c0 by q^2 / 24 = 4.2e-8 relative (and by the round-off of 1 - cos q, eps / q^2 ~ 2e-10)."""
    K, m, k_lin = datasheet_constants()
    model = STEEL.model()
    assert model.delta0 == pytest.approx(1.0, rel=1e-14) and model.masses == (1.0,) and model.alpha == 1.5
    f_c = STEEL.to_si("frequency", model.linear_frequencies(math.pi)[0])
    assert f_c == pytest.approx(math.sqrt(k_lin / m) / math.pi, rel=1e-13)
    assert STEEL.cutoff_frequency() == pytest.approx(f_c, rel=1e-13)
    q = 1e-3
    c0 = STEEL.to_si("speed", model.linear_frequencies(q)[0] / q)
    assert c0 == pytest.approx(2 * R * math.sqrt(k_lin / m), rel=5e-8)
    assert STEEL.sound_speed() == pytest.approx(c0, rel=5e-8)
    # the physics does not depend on the length scale: another L gives another delta0, the same SI values
    other = BeadChain(STEEL.beads, F0, "0.1 um")
    assert other.model().delta0 == pytest.approx(STEEL.static_overlap / 1e-7, rel=1e-14)
    assert other.to_si("frequency", other.model().linear_frequencies(math.pi)[0]) == pytest.approx(f_c, rel=1e-13)
    # and the force scale at the default L is the static force
    assert STEEL.to_si("force", 1.0) == pytest.approx(F0, rel=1e-13)


def test_a_chain_by_value_and_a_dimer_of_two_materials():
    K, m, k_lin = datasheet_constants()
    by_value = BeadChain.by_value([f"{m * 1e3} g"], f"{K} N/m^1.5", f"{2 * R * 1e3} mm", "10 N")
    assert by_value.cutoff_frequency() == pytest.approx(STEEL.cutoff_frequency(), rel=1e-12)
    steel, ptfe = Bead("steel", R), Bead("ptfe", R)
    dimer = BeadChain((steel, ptfe), "5 N")
    model = dimer.model()
    assert model.masses == pytest.approx((1.0, ptfe.mass / steel.mass), rel=1e-14)
    # the top of the optical band (q = 0 per cell) against sqrt(2 K_lin (1/m1 + 1/m2)) / (2 pi)
    top = max(model.linear_frequencies(q)[-1] for q in np.linspace(1e-6, math.pi, 41))
    assert dimer.to_si("frequency", top) == pytest.approx(dimer.cutoff_frequency(), rel=1e-10)
    assert dimer.equal_bonds and "bonds" not in model.describe()


def test_bonds_of_different_beads():
    """Steel, steel, PTFE (issue 38 item 3): bond c has the constant of beads c and c + 1, K is bond 0's; in the
    chain's units bond c is k_c V'_(delta_c) with k_c = K_c / K and delta_c = (F0 / K_c)^(2/3) / L, so its static force
    k_c delta_c^(3/2) is F0 / (K L^(3/2)) in every bond (the chain is at rest); the long-wave speed of the model's
    linear lattice is the closed form with the bonds in series (dispersion O(q^2): 2.3e-7 at q = 1e-3, measured)."""
    steel, ptfe = Bead("steel", R), Bead("ptfe", R)
    chain = BeadChain((steel, steel, ptfe), "5 N")
    Ks = chain.bond_constants
    assert Ks == (contact_constant(steel, steel), contact_constant(steel, ptfe), contact_constant(ptfe, steel))
    assert chain.K == Ks[0] and not chain.equal_bonds and chain.describe()["bond_constants"] == list(Ks)
    model = chain.model()
    assert model.law == model.bonds[0] and model.delta0 == pytest.approx(1.0, rel=1e-14)
    static = [b.k * b.base.delta0 ** 1.5 if hasattr(b, "k") else b.delta0 ** 1.5 for b in model.bonds]
    assert np.allclose(static, chain.from_si("force", 5.0), rtol=1e-13)
    q = 1e-3
    speed = chain.spacing * model.linear_frequencies(q)[0] / q / chain.tau
    assert speed == pytest.approx(chain.sound_speed(), rel=1e-6)
    assert LatticeModel.from_description(model.describe()) == model


@pytest.mark.parametrize("kind", ["hunt-crossley", "kuwabara-kono"])
def test_a_contact_damping_from_a_measured_restitution_gives_it_back(kind):
    """Dissipation in the contacts given as a restitution e measured at an impact velocity v in m/s: the two beads'
    impact computed in the chain's units with the damping derived gives e back. The small-dissipation laws are first
    order in 1 - e: their next term makes e come back high by about (1 - e)^2 (0.97 (1 - e)^2 for Hunt-Crossley, 0.6
    for Kuwabara-Kono at e = 0.97, 0.9), so within 1.5 (1 - e)^2; the coefficient given in SI gives the same damping."""
    from hertzpetsc.model import Damping, LatticeModel
    from hertzpetsc.studies.contacts import restitution
    dimer = BeadChain((Bead("steel", R), Bead("brass", R)), "5 N")
    e, v = 0.97, "0.1 m/s"
    contact = dimer.contact_damping(kind, restitution=e, velocity=v)
    model = dimer.model()
    impact = LatticeModel(model.law.with_parameter("delta0", 0.0), model.masses, Damping(contact=contact))
    e_back, _ = restitution(impact, dimer.from_si("velocity", v), 1e-10)
    assert 0 < e_back - e < 1.5 * (1 - e) ** 2, e_back
    field = "c" if kind == "hunt-crossley" else "eta"
    # the coefficient in SI from the module docstring's scales: c* = c L / tau, eta* = eta / (K tau)
    value = contact.c * dimer.tau / dimer.L if kind == "hunt-crossley" else contact.eta * dimer.K * dimer.tau
    again = dimer.contact_damping(kind, coefficient=f"{value} {'s/m' if field == 'c' else 'N s/m^1.5'}")
    assert getattr(again, field) == pytest.approx(getattr(contact, field), rel=1e-12)
    for call, name in [(lambda: dimer.contact_damping(kind, restitution=0.5, velocity=v), "restitution"),
                       (lambda: dimer.contact_damping(kind, restitution=e), "velocity"),
                       (lambda: dimer.contact_damping(kind), "restitution"),
                       (lambda: dimer.contact_damping(kind, coefficient="1 m"), "coefficient"),
                       (lambda: dimer.contact_damping("dashpot", coefficient=1.0), "kind")]:
        with pytest.raises(ParameterError) as err:
            call()
        assert err.value.name == name, (name, err.value)


@pytest.mark.parametrize("quantity", ["length", "time", "mass", "velocity", "force", "energy", "angular_frequency",
                                      "frequency", "damping", "speed", "wavenumber"])
def test_to_si_and_from_si_are_inverse(quantity):
    x = np.array([0.3, 1.0, 7.5])
    assert np.allclose(STEEL.from_si(quantity, STEEL.to_si(quantity, x)), x, rtol=1e-14, atol=0)
    assert STEEL.from_si(quantity, STEEL.to_si(quantity, 2.5)) == pytest.approx(2.5, rel=1e-14)


def test_strings_with_units_convert_and_the_scales_are_consistent():
    assert STEEL.from_si("length", "1.28093 um") == pytest.approx(1e-6 * 1.28093 / STEEL.L, rel=1e-14)
    assert STEEL.from_si("angular_frequency", "1 kHz") == pytest.approx(2 * math.pi * 1e3 * STEEL.tau, rel=1e-14)
    # tau^2 K L^(1/2) / m = 1: the dimensionless equation has no coefficient
    assert STEEL.tau ** 2 * STEEL.K * STEEL.L ** 0.5 / STEEL.mass == pytest.approx(1.0, rel=1e-14)
    assert STEEL.to_si("velocity", 1.0) == pytest.approx(STEEL.L / STEEL.tau, rel=1e-14)


def test_bad_chains_name_their_argument():
    cases = [(lambda: BeadChain(STEEL.beads, "-1 N"), "static_force"),
             (lambda: BeadChain(STEEL.beads, "10 m"), "static_force"),
             (lambda: BeadChain(STEEL.beads, 0.0), "length_scale"),
             (lambda: BeadChain(("steel",), 1.0), "beads"),
             (lambda: BeadChain.by_value([-1.0], 1e9, 0.01, 1.0), "masses"),
             (lambda: BeadChain.by_value([1.0], "1e9 Pa", 0.01, 1.0), "K"),
             (lambda: STEEL.to_si("colour", 1.0), "quantity"),
             (lambda: STEEL.solitary_speed(0.1, 1.6), "static_force"),
             (lambda: BeadChain(STEEL.beads, 0, "1 um").sound_speed(), "static_force"),
             (lambda: BeadChain(STEEL.beads, 0, "1 um").solitary_speed("-1 m/s", 1.6), "max_velocity"),
             (lambda: hz.solitary_speed(STEEL, 0.1), "static_force"),
             (lambda: hz.solitary_speed("steel", 0.1), "chain")]
    for call, name in cases:
        with pytest.raises(ParameterError) as err:
            call()
        assert err.value.name == name, (name, err.value)


def test_the_solitary_wave_speed_in_si():
    """The unit-speed solitary wave's maximal bead velocity converges at second order in the grid step; the speed in
    m/s scales as v^(1/5) and equals 2R (K/m)^(2/5) (v / v1)^(1/5) for any length scale; it lies within a few per
    cent below Nesterenko's long-wave formula 0.9314 (4 E^2 / (pi^2 rho^2 (1 - nu^2)^2))^(1/5) v^(1/5) (the
    continuum limit, whose maximal velocity at unit speed is (6/5)^2 = 1.44: below the lattice's, so the lattice's wave
    is slower at the same v)."""
    from hertzpetsc.studies.solitary import unit_wave_velocity
    v1, order, _ = unit_wave_velocity(1.5, (40, 80, 160))
    assert abs(order - 2) < 0.05 and 1.44 < v1 < 1.7
    K, m, _ = datasheet_constants()
    chain = BeadChain(STEEL.beads, 0.0, "1 um")
    speeds = [chain.solitary_speed(v, v1) for v in (0.01, 0.1, 1.0)]
    assert speeds == pytest.approx([2 * R * (K / m) ** 0.4 * (v / v1) ** 0.2 for v in (0.01, 0.1, 1.0)], rel=1e-13)
    assert BeadChain(STEEL.beads, 0.0, "1 mm").solitary_speed("10 cm/s", v1) == pytest.approx(speeds[1], rel=1e-13)
    nesterenko = 0.9314 * (4 * E ** 2 / (math.pi ** 2 * RHO ** 2 * (1 - NU ** 2) ** 2)) ** 0.2 * 0.1 ** 0.2
    assert 0.0 < 1 - speeds[1] / nesterenko < 0.05
    api = hz.solitary_speed(chain, [0.01, 0.1, 1.0], cells=(40, 80, 160))
    assert api == pytest.approx(speeds, rel=1e-12)


# --- the command line (drivers run as processes of their own: serial) ---------------------------------------------------------------------------------------------
@pytest.mark.serial
@pytest.mark.parametrize("script, args, option", [
    ("wave.py", ["-beads", "unobtainium"], "-beads"),
    ("wave.py", ["-beads", "steel", "-poisson", "0.7", "-static_force", "1N"], "-poisson"),
    ("wave.py", ["-beads", "steel", "-youngs", "-1GPa", "-static_force", "1N"], "-youngs"),
    ("wave.py", ["-beads", "steel", "-radius", "5 furlongs", "-static_force", "1N"], "-radius"),
    ("wave.py", ["-beads", "steel", "-static_force", "10 m"], "-static_force"),
    ("wave.py", ["-beads", "steel", "-static_force", "10N", "-delta0", "1"], "-delta0"),
    ("precompressed_branch.py", ["-beads", "steel"], "-length_scale"),
    ("precompressed_branch.py", ["-static_force", "10N"], "-static_force"),
    ("driven_response.py", ["-drive_frequency", "2kHz"], "-drive_frequency"),
    ("driven_response.py", ["-beads", "steel", "-static_force", "1N", "-drive_frequency", "2 kHz/s"],
     "-drive_frequency"),
    ("driven_response.py", ["-beads", "steel", "-static_force", "1N", "-omega", "1", "-drive_frequency", "2kHz"],
     "-omega"),
    ("restitution.py", ["-impact_velocities", "1m/s"], "-impact_velocities"),
    ("restitution.py", ["-contact_coefficient", "0.1s/m"], "-contact_coefficient"),
    ("restitution.py", ["-beads", "steel", "-velocities", "1", "-impact_velocities", "1m/s"], "-velocities"),
    ("restitution.py", ["-beads", "steel", "-contact_coefficient", "0.1 N"], "-contact_coefficient"),
    ("restitution.py", ["-beads", "steel", "-damping", "0.1", "-contact_coefficient", "0.1s/m"], "-damping"),
    ("pulse_decay.py", ["-beads", "steel", "-striker_velocities", "1 kHz"], "-striker_velocities"),
    ("restitution.py", ["-beads", "steel", "-impact_velocities", "1m/s,-1m/s"], "-impact_velocities"),
    ("precompression_map.py", ["-beads", "steel", "-static_force", "1N", "-epsilon", "0.5"], "-epsilon"),
    ("boundary_in_q.py", ["-beads", "steel", "-static_force", "1N", "-A", "1", "-A_si", "1um"], "-A"),
    ("boundary_in_q.py", ["-A_si", "1um"], "-A_si"),
])
def test_bad_si_options_are_one_error_line_naming_them(script, args, option):
    r = run_script(script, *args, "-check")
    line = one_error_line(r)
    assert r.returncode == 2 and line.startswith(f"error: invalid {option} = "), line


# the drivers whose computation cannot take a given chain of beads refuse it, saying why and which command gives it
REFUSED = [
    ("dimer_branch.py", ["-beads", "steel"], "-beads", "scripts/wave.py -beads"),
    ("pulse_decay.py", ["-beads", "steel,ptfe"], "-beads", "scripts/wave.py -beads"),
    ("pulse_decay.py", ["-beads", "steel", "-static_force", "1N"], "-static_force", "free"),
    ("restitution.py", ["-beads", "steel,brass,ptfe"], "-beads", "two beads"),
    ("restitution.py", ["-beads", "steel", "-static_force", "1N"], "-static_force", "free"),
    ("driven_generation.py", ["-beads", "steel,ptfe", "-static_force", "1N"], "-beads",
     "scripts/driven_response.py -beads"),
    ("precompression_map.py", ["-beads", "steel,steel,ptfe", "-static_force", "1N"], "-beads",
     "scripts/wave.py -beads"),
    ("precompression_map.py", ["-render", "-beads", "steel", "-static_force", "1N"], "-beads", "-render"),
    ("boundary_in_q.py", ["-beads", "steel,brass", "-static_force", "1N"], "-beads",
     "scripts/precompression_map.py -beads"),
]


@pytest.mark.serial
@pytest.mark.parametrize("script, args, option, says", REFUSED)
def test_a_chain_of_beads_a_driver_cannot_compute_is_refused_on_every_rank(script, args, option, says, tmp_path):
    r = run_script(script, *args, "-output", tmp_path / "x.npz", "-table", tmp_path / "x.md", ranks=2,
                   timeout=120, cwd=tmp_path)
    line = one_error_line(r)
    assert r.returncode == 2 and line.startswith(f"error: invalid {option} = ") and says in line, line
    assert not (tmp_path / "x.npz").exists()


@pytest.mark.serial
def test_bad_si_options_end_every_rank_with_one_line():
    r = run_script("wave.py", "-beads", "steel", "-poisson", "0.6", "-static_force", "1N", "-check", ranks=2)
    assert one_error_line(r).startswith("error: invalid -poisson = ")


@pytest.mark.serial
def test_the_wave_driver_reports_si_beside_the_dimensionless_values(tmp_path):
    table = tmp_path / "wave.md"
    r = run_script("wave.py", "-beads", "steel", "-radius", "4.76mm", "-static_force", "10N", "-q", "2*pi/15",
                   "-A", "0.5", "-cells_per_pi", "100", "-N", "30", "-output", tmp_path / "wave.npz", "-table", table)
    assert r.returncode == 0, r.stderr
    text = table.read_text()
    row = re.search(r"^\| 0\.418879 \| (\S+) \| (\S+) \| (\S+) \| (\S+) \|$", text.split("## In SI units")[1], re.M)
    omega, A_um, f, c = map(float, row.groups())
    assert A_um == pytest.approx(0.5 * STEEL.L * 1e6, rel=1e-5)
    assert f == pytest.approx(omega / (2 * math.pi * STEEL.tau), rel=1e-5)
    assert c == pytest.approx(omega / (2 * math.pi / 15) * 2 * R / STEEL.tau, rel=1e-5)
    assert "sound speed c0 = 541.9" in text          # c0 of the closed form, checked above to 1e-9


@pytest.mark.serial
def test_the_driven_response_takes_its_drive_in_si_and_reports_the_wall_force_in_newtons(tmp_path):
    table = tmp_path / "driven.md"
    r = run_script("driven_response.py", "-N", "4", "-beads", "steel", "-static_force", "10N", "-gamma", "0.05",
                   "-drive_amplitude", "0.1um", "-drive_frequency", "10kHz", "-p_end_si", "10.5kHz", "-run_in", "10",
                   "-max_steps", "3", "-output", tmp_path / "driven.npz", "-table", table)
    assert r.returncode == 0, r.stderr
    data = np.load(tmp_path / "driven.npz", allow_pickle=True)
    rows = [line.split("|")[1:-1] for line in table.read_text().split("## In SI units")[1].splitlines()
            if re.match(r"^\| 0 \|", line)]
    omega = np.asarray(data["omega"], float)
    assert len(rows) == len(omega) >= 2
    assert float(rows[0][3]) == pytest.approx(1e4, rel=1e-5)                   # the first response at -drive_frequency
    assert omega[0] == pytest.approx(2 * math.pi * 1e4 * STEEL.tau, rel=1e-12)
    assert data["amplitude"][0] == pytest.approx(1e-7 / STEEL.L, rel=1e-12)
    for row, w, f in zip(rows, omega, np.asarray(data["force_right"], float)):
        assert float(row[3]) == pytest.approx(w / (2 * math.pi * STEEL.tau), rel=1e-5)
        assert float(row[4]) == pytest.approx(f * F0, rel=1e-5)                   # K L^(3/2) = F0 at L = delta_s


@pytest.mark.serial
def test_the_page_quotes_what_beads_to_waves_prints(tmp_path):
    """docs/from-beads-to-waves.md's tables of closed forms and solitary speeds are the driver's output."""
    out = tmp_path / "b.md"
    r = run_script("beads_to_waves.py", "-beads", "steel", "-radius", "4.76mm", "-static_force", "10N", "-output", out)
    assert r.returncode == 0, r.stderr
    page = open(os.path.join(ROOT, "docs", "from-beads-to-waves.md")).read()
    rows = [line for line in out.read_text().splitlines() if re.match(r"^\| [0-9cs]", line)]
    assert len(rows) == 5 and all(row in page for row in rows), [row for row in rows if row not in page]
    assert "v1 = 1.6249441" in out.read_text() and "v1 = 1.6249441" in page


def test_the_api_reports_waves_and_responses_in_si():
    """hz.wave(None, ..., beads=chain) on a steel chain pressed by 10 N and chain.wave_si: at A = 1e-3 (of the
    static overlap) the frequency at q = pi is the cut-off f_c and the phase speed at q = pi/10 is
    c0 sin(q/2) / (q/2) (units' closed forms) up to the grid's O(h^2) (relative 4.1e-5 at h = pi/100, 1.0e-5 at
    pi/200: observed order 2) and the amplitude's O(A^2) = 1e-6: Richardson's extrapolation of the two within 1e-6;
    the bonds' forces at t = 0 are F0 - K_lin (x_{n+1} - x_n) to O(A^2 F0). hz.response(..., beads=chain): the
    drive's frequency in Hz given back, and the wall's force beyond F0 is K_lin |X_N| in N (the linear chain's
    amplitude in metres) to O(a). A model that is not the beads' dimensionless chain is refused, naming ``beads``."""
    from hertzpetsc.driven import Drive, HarmonicWave
    from hertzpetsc.studies.driven import linear_response
    chain = BeadChain((Bead.of("steel", "4.76mm"),), "10N")
    A = 1e-3
    for q, N, closed in ((math.pi, 2, lambda si: si["frequency"] / chain.cutoff_frequency()),
                         (math.pi / 10, 20, lambda si: si["phase_speed"] / (chain.sound_speed() * math.sin(q / 2)
                                                                            / (q / 2)))):
        ratio = []
        for cells in (100, 200):
            orbit = hz.wave(None, q, A, N, cells_per_pi=cells, beads=chain)
            si = chain.wave_si(orbit)
            ratio.append(closed(si) - 1)
            assert si["period"] == pytest.approx(1 / si["frequency"], rel=1e-14)
            assert si["amplitude"] == pytest.approx(A * chain.L, rel=1e-14)
            assert si["wavenumber"] == pytest.approx(q / chain.spacing, rel=1e-14)
            strain = np.roll(si["displacement"], -1) - si["displacement"]
            assert np.max(np.abs(si["force"] - (10.0 - chain.linear_stiffness * strain))) < 10 * A * A * 10.0
        assert 3.6 < ratio[0] / ratio[1] < 4.4 and abs((4 * ratio[1] - ratio[0]) / 3) < 1e-6
    with pytest.raises(ParameterError, match="invalid beads"):
        hz.wave(LatticeModel.hertz(1.5, delta0=0.5), math.pi, A, 2, beads=chain)   # not delta0 = 1 of the beads
    a, f = chain.from_si("length", "1nm"), 10e3
    drive = Drive(chain.model(gamma=0.05), 3, HarmonicWave(), a, chain.from_si("angular_frequency", 2 * math.pi * f))
    (response,) = hz.response(drive, drive.omega, run_in=5, floquet="none", beads=chain)
    si = response.record["si"]
    assert si["frequency"] == pytest.approx(f, rel=1e-12) and si["drive_amplitude"] == pytest.approx(1e-9, rel=1e-12)
    X = linear_response(drive)
    wall = chain.linear_stiffness * chain.to_si("length", abs(X[-1]))
    assert abs(si["force_right"] / wall - 1) < 10 * a
    assert si["dissipation"] == pytest.approx(si["power_in"], rel=1e-9) and si["power_in"] > 0


def si_rows(text):
    """The rows of the section "In SI units" of a driver's table (cells as strings)."""
    lines = [line for line in text.split("## In SI units")[1].splitlines() if line.startswith("|")]
    return [line.split("|")[1:-1] for line in lines[2:]]            # below the header and its rule


@pytest.mark.serial
def test_restitution_and_pulse_take_beads_and_report_si(tmp_path):
    """A steel-brass impact with Hunt-Crossley c = 0.2 s/m at 1 and 3 mm/s: the masses are the beads', the
    velocities and the damping converted (v* = v tau / L, c* = c L / tau), and 1 - e = c v (dimensionless in any
    units) to first order in c v; a pulse into a steel chain at 0.1 m/s: its amplitudes (bead velocities) in m/s are
    the records' times L / tau."""
    steel, brass = Bead("steel", R), Bead("brass", R)
    chain = BeadChain((steel, brass), 0.0, "1 um")
    r = run_script("restitution.py", "-beads", "steel,brass", "-contact_coefficient", "0.2s/m", "-impact_velocities",
                   "1mm/s,3mm/s", "-output", tmp_path / "r.npz", "-table", tmp_path / "r.md")
    assert r.returncode == 0, r.stderr
    with np.load(tmp_path / "r.npz") as z:
        assert list(z["masses"]) == pytest.approx([1.0, brass.mass / steel.mass], rel=1e-14)
        assert float(z["damping"]) == pytest.approx(0.2 * chain.L / chain.tau, rel=1e-14)
        v, e = np.asarray(z["v"], float), np.asarray(z["e"], float)
    assert v == pytest.approx(np.array([1e-3, 3e-3]) * chain.tau / chain.L, rel=1e-14)
    rows = si_rows((tmp_path / "r.md").read_text())
    assert [float(row[4]) for row in rows] == pytest.approx([1e-3, 3e-3], rel=1e-5)
    for v_si, ei in zip((1e-3, 3e-3), e):
        cv = 0.2 * v_si                                     # the law's error is of order (c v)^2: relative c v
        assert abs((1 - ei) / cv - 1) < 2 * cv
    # resumed (the record field 'law' is not the identity's absent key 'law', records.ABSENT)
    r = run_script("restitution.py", "-beads", "steel,brass", "-contact_coefficient", "0.2s/m", "-impact_velocities",
                   "1mm/s,3mm/s", "-output", tmp_path / "r.npz", "-table", tmp_path / "r.md", "-resume")
    assert r.returncode == 0, r.stderr
    assert len(si_rows((tmp_path / "r.md").read_text())) == 2
    r = run_script("pulse_decay.py", "-beads", "steel", "-contact_coefficient", "0.05s/m", "-striker_velocities",
                   "0.1m/s", "-N", 12, "-skip", 2, "-output", tmp_path / "p.npz", "-table", tmp_path / "p.md")
    assert r.returncode == 0, r.stderr
    chain = BeadChain((steel,), 0.0, "1 um")
    with np.load(tmp_path / "p.npz") as z:
        assert float(z["v0"][0]) == pytest.approx(0.1 * chain.tau / chain.L, rel=1e-14)
        A = np.asarray(z["amplitude"][0], float)
    (row,) = si_rows((tmp_path / "p.md").read_text())
    assert [float(x) for x in row[2:]] == pytest.approx([0.1, A[2] * chain.L / chain.tau,
                                                         A[9] * chain.L / chain.tau], rel=1e-5)


@pytest.mark.serial
def test_driven_generation_takes_beads_and_reports_si(tmp_path):
    """The generation study on a steel chain pressed by 10 N is the dimensionless one of delta0 = 1 (the record's
    model), its table's SI section the records converted: f = omega / (2 pi tau), a and A bulk times L (in um),
    gamma times m / tau."""
    from conftest import DATA
    r = run_script("driven_generation.py", "-branch", f"{DATA}/branch_alpha1.5.npz", "-beads", "steel",
                   "-static_force", "10N", "-N", 8, "-signals", "half_sine", "-omegas", 0.5, "-amplitudes", 0.1,
                   "-gammas", 0.1, "-run_in", 10, "-output", tmp_path / "g.npz", "-table", tmp_path / "g.md",
                   "-figures", "")
    assert r.returncode == 0, r.stderr
    with np.load(tmp_path / "g.npz") as z:
        assert str(z["model"]) == '{"alpha": 1.5, "delta0": 1.0, "masses": [1.0]}'
        amp_bulk, ok = float(z["amp_bulk"][0]), int(z["ok"][0])
    (row,) = si_rows((tmp_path / "g.md").read_text())
    assert row[0].strip() == "half_sine" and ok == 1
    f, a_um, gamma, A_um = (float(x) for x in row[5:9])
    assert f == pytest.approx(0.5 / (2 * math.pi * STEEL.tau), rel=1e-5)
    assert a_um == pytest.approx(0.1 * STEEL.L * 1e6, rel=1e-5)
    assert gamma == pytest.approx(0.1 * STEEL.mass / STEEL.tau, rel=1e-5)
    assert A_um == pytest.approx(amp_bulk * STEEL.L * 1e6, rel=1e-5)


@pytest.mark.serial
def test_the_map_of_a_steel_chain_is_the_hertz_map_of_its_model_and_reports_si(tmp_path):
    """-beads steel -static_force 10N is the chain delta0 = 1: the map's file names the model as the Hertz maps
    always did (alpha, delta0, masses: no law, no bonds), so that -resume with -delta0 1 continues it and a file made
    before the model's identity was extended reads as this one; the same beads at another length scale (delta0 =
    delta_s / 1 um) are another model, refused naming delta0 and the options that set it. The SI section: A in um,
    f in Hz of the records."""
    args = ["-N", 20, "-a", 0.5, "-cells_per_pi", 100, "-rtol", "1e-10", "-output", tmp_path / "m.npz", "-table",
            tmp_path / "m.md", "-figures", ""]
    r = run_script("precompression_map.py", "-beads", "steel", "-static_force", "10N", "-m", 3, *args)
    assert r.returncode == 0, r.stderr
    with np.load(tmp_path / "m.npz") as z:
        assert "law" not in z and "bonds" not in z
        assert (float(z["alpha"]), float(z["delta0"]), list(z["masses"])) == (1.5, 1.0, [1.0])
        A, omega, kind = (np.asarray(z[k], float) for k in ("A", "omega", "kind"))
    rows = si_rows((tmp_path / "m.md").read_text())
    finite = np.isfinite(A)
    assert len(rows) == int(np.sum(finite)) >= 1
    for row, Ai, wi in zip(rows, A[finite], omega[finite]):
        assert float(row[4]) == pytest.approx(Ai * STEEL.L * 1e6, rel=1e-5)
        assert float(row[5]) == pytest.approx(wi / (2 * math.pi * STEEL.tau), rel=1e-5)
    r = run_script("precompression_map.py", "-delta0", 1, "-m", "3,4", *args, "-resume")
    assert r.returncode == 0, r.stderr
    r = run_script("precompression_map.py", "-beads", "steel", "-static_force", "10N", "-length_scale", "1um",
                   "-m", "3,4", *args, "-resume")
    line = one_error_line(r)
    assert "delta0 = 1.0 there" in line and "-static_force and -length_scale with -beads" in line, line
    # two materials alternating (one contact constant in every bond): the dimer map of their mass ratio
    r = run_script("precompression_map.py", "-beads", "steel,brass", "-static_force", "10N", "-m", 3, *args[:-6],
                   "-output", tmp_path / "d.npz", "-table", tmp_path / "d.md", "-figures", "")
    assert r.returncode == 0, r.stderr
    with np.load(tmp_path / "d.npz") as z:
        ratio = Bead("brass", R).mass / Bead("steel", R).mass
        assert list(z["masses"]) == pytest.approx([1.0, ratio], rel=1e-14) and float(z["delta0"]) == 1.0


@pytest.mark.serial
def test_the_boundary_in_q_takes_beads_and_amplitudes_in_si(tmp_path):
    """The boundary in q of a steel chain at A = 3.8 um (-A_si): the level is 3.8 um / L, the grid's SI rows the
    records' f = omega / (2 pi tau) and c = omega / q beads per unit time in m/s, a located edge's wavenumbers per
    metre its q over the beads' spacing."""
    r = run_script("boundary_in_q.py", "-beads", "steel", "-static_force", "10N", "-A_si", "3.8um", "-N", 20, "-m",
                   "3,4", "-cells_per_pi", 100, "-twists", 16, "-locate_tol", 0.1, "-max_cell", 20, "-output",
                   tmp_path / "q.npz", "-table", tmp_path / "q.md", "-figures", "")
    assert r.returncode == 0, r.stderr
    with np.load(tmp_path / "q.npz") as z:
        kind, A, q, omega = (np.asarray(z[k], float) for k in ("kind", "A", "q", "omega"))
        q_stable = np.asarray(z["q_stable"], float)
    assert A == pytest.approx(np.full(len(A), 3.8e-6 / STEEL.L), rel=1e-14)
    rows = si_rows((tmp_path / "q.md").read_text())
    assert len(rows) == len(A) and 2 in kind                 # the edge between q = 3pi/10 and 2pi/5 located
    spacing = 2 * R
    for row, k, qi, wi, qs in zip(rows, kind, q, omega, q_stable):
        assert float(row[4]) == pytest.approx(3.8, rel=1e-5)
        if k == 2:
            assert float(row[7]) == pytest.approx(qs / spacing, rel=1e-5) and row[5].strip() == "nan"
        else:
            assert float(row[5]) == pytest.approx(wi / (2 * math.pi * STEEL.tau), rel=1e-5)
            assert float(row[6]) == pytest.approx(wi / qi * spacing / STEEL.tau, rel=1e-5)


def test_the_map_refuses_what_it_cannot_compute_and_files_name_the_bonds():
    """The map and the boundary in q are of the Hertz law in every bond (their uncompressed limit is that law's): a
    law of its own (here a stiffer Hertz contact, precompressed) and a steel-steel-PTFE pattern (bonds of their own
    constants) are refused naming the model; a Hertz model's identity is the keys the map files always had. A record
    file of the pattern names its bonds (law_identity): resumed as the plain Hertz chain of the same masses it is
    refused, and the other way round."""
    import tempfile

    from hertzpetsc.chain import IntegrationTolerances
    from hertzpetsc.errors import RecordFileError
    from hertzpetsc.studies.maps import MapParameters, QBoundaryParameters, StabilityMap
    from hertzpetsc.studies.precompression import AmplitudeFamilies, AmplitudeParameters
    from petsc4py import PETSc
    from test_laws import StiffHertz

    patterned = BeadChain((Bead("steel", R), Bead("steel", R), Bead("ptfe", R)), "10 N").model()
    assert patterned.bonds is not None
    # the identity's keys reopen as the model (the bonds' JSON as a file holds it)
    assert LatticeModel.from_description(dict(patterned.law_identity(), masses=list(patterned.masses))) == patterned
    q = 2 * math.pi * 3 / 20
    tolerances = IntegrationTolerances(rtol=1e-10, atol=1e-12)
    for model in (LatticeModel(StiffHertz(1.5, 1.0, c=3.0)), patterned):
        with pytest.raises(ParameterError, match="invalid model = .*Hertz chain, one law in every bond"):
            MapParameters(model, (q,), (0.5,), N=60 if model is patterned else 20, cells_per_pi=100)
        with pytest.raises(ParameterError, match="invalid model = "):
            QBoundaryParameters(model, (1.0,), (q,), cells_per_pi=100, tolerances=tolerances)
    plain = LatticeModel.hertz(1.5, patterned.masses, patterned.delta0)
    study = StabilityMap(MapParameters(LatticeModel.hertz(1.5, (1.0,), 1.0), (q,), (0.5,), N=20, cells_per_pi=100))
    assert list(study.constants())[:3] == ["alpha", "delta0", "masses"] and "law" not in study.constants()
    with tempfile.TemporaryDirectory() as tmp:
        for first, second in ((plain, patterned), (patterned, plain)):
            path = os.path.join(tmp, "a.npz")
            params = [AmplitudeParameters(m, (math.pi / 5,), 100, 1e-3, 2e-3, 0.5) for m in (first, second)]
            AmplitudeFamilies(params[0], PETSc.COMM_SELF, path, "force").open()
            with pytest.raises(RecordFileError, match="bonds"):
                AmplitudeFamilies(params[1], PETSc.COMM_SELF, path, "resume").open()
