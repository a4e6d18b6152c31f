"""The law protocol (issue 38, item 1): parameters by name, scaling where a law has one, the reference amplitude, the
kernel form, the consistency check and the registry by name; the Toda lattice's cnoidal waves against the whole wave
pipeline; the linear limit of every law."""
import math
import os
from dataclasses import dataclass

import numpy as np
import pytest
from petsc4py import PETSc

from hertzpetsc.branch import BranchPoint
from hertzpetsc.chain import Chain
from hertzpetsc.errors import ParameterError
from hertzpetsc.families import AmplitudeFamily, amplitude_floor, check_family_amplitude
from hertzpetsc.fpu import FPULaw
from hertzpetsc.grid import ProfileGrid
from hertzpetsc.hertz import HertzLaw
from hertzpetsc.dissipation import HuntCrossley, KuwabaraKono
from hertzpetsc.law import LAWS, InteractionLaw, RescaledLaw, from_description
from hertzpetsc.model import ChainSpec, Damping, LatticeModel
from hertzpetsc.richardson import richardson
from hertzpetsc.toda import TodaLaw
from hertzpetsc.waves import orbit_on_chain

COMM = PETSc.COMM_WORLD
EPS = float(np.finfo(float).eps)


@dataclass(frozen=True)
class StiffHertz(HertzLaw):
    """A Hertz law with a stiffer contact: redefines the derivatives (and must not use Hertz's compiled kernel)."""

    name = "stiff-hertz"
    c: float = 2.0

    def V(self, x):
        return self.c * HertzLaw.V(self, x)

    def dV(self, x):
        return self.c * HertzLaw.dV(self, x)

    def d2V(self, x):
        return self.c * HertzLaw.d2V(self, x)


@dataclass(frozen=True)
class PlainHertz(HertzLaw):
    """A Hertz subclass that changes nothing of the law (its kernel is still Hertz's)."""


@dataclass(frozen=True)
class WrongForce(InteractionLaw):
    """A law whose force is not the derivative of its potential (V'(r) off by a factor 2)."""

    name = "wrong-force"
    k: float = 1.0

    def V(self, r):
        return 0.5 * self.k * np.asarray(r, float) ** 2

    def dV(self, r):
        return 2 * self.k * np.asarray(r, float)

    def d2V(self, r):
        return 2 * self.k + 0 * np.asarray(r, float)


def test_parameters_by_name_and_the_lenses():
    """with_alpha / with_delta0 continue the law's own parameter (any law); a law without it: ParameterError
    naming it (before: a non-Hertz model silently became a Hertz chain)."""
    toda, fpu = LatticeModel(TodaLaw(1.3, 0.7), (1.0, 2.0)), LatticeModel(FPULaw(1.0, 0.2, 0.5))
    assert toda.parameters == ("k", "b") and fpu.parameters == ("k", "alpha", "beta")
    for name in ("alpha", "delta0"):
        with pytest.raises(ParameterError, match=name):
            getattr(toda, f"with_{name}")(2.0)
    assert fpu.with_alpha(0.3).law == FPULaw(1.0, 0.3, 0.5)
    assert toda.with_parameter("b", 0.2) == LatticeModel(TodaLaw(1.3, 0.2), (1.0, 2.0))
    assert LatticeModel.hertz(1.5, delta0=0.4).with_alpha(2.5) == LatticeModel.hertz(2.5, delta0=0.4)
    with pytest.raises(ParameterError, match="b"):
        toda.with_parameter("b", -1.0)


def test_a_hertz_subclass_stays_itself_under_rescaling_and_off_hertz_kernel():
    law = StiffHertz(1.5, 0.6, c=3.0)
    assert law.rescaled(2.0) == StiffHertz(1.5, 0.3, c=3.0)
    assert law.rescaled(math.inf) == StiffHertz(1.5, 0.0, c=3.0)
    assert LatticeModel(law).with_delta0(0.2).law == StiffHertz(1.5, 0.2, c=3.0)
    assert HertzLaw().kernel_form == "hertz" and PlainHertz().kernel_form == "hertz"
    assert law.kernel_form is None and TodaLaw().kernel_form is None
    chain = Chain(ChainSpec(LatticeModel(law), 8), COMM)
    try:
        assert chain.kernel is None            # its own V' in numpy, never Hertz's compiled one
    finally:
        chain.destroy()


def test_a_rescaled_generic_law_equals_itself_and_goes_on_a_chain():
    """RescaledLaw is a value (before: never equal to itself, so orbit_on_chain refused the wave)."""
    model = LatticeModel(TodaLaw(1.0, 0.5)).rescaled(2.0)
    assert model == LatticeModel(TodaLaw(1.0, 0.5)).rescaled(2.0)
    assert model.law == RescaledLaw(TodaLaw(1.0, 0.5), 2.0, 1.0) and hash(model.law) == hash(model.law)
    assert model.rescaled(2.0) != model and not model.scale_invariant
    h = math.pi / 8
    xi = np.arange(9) * h
    point = BranchPoint(q=math.pi / 2, u_half=0.1 * np.sin(xi), h=h, model=model, omega=1.0)
    orbit = orbit_on_chain(point, ChainSpec(LatticeModel(TodaLaw(1.0, 0.5)).rescaled(2.0), 8))
    assert orbit.amplitude == pytest.approx(0.1) and orbit.T == pytest.approx(math.pi / 2)
    # a homogeneous law is its own rescaling
    assert HertzLaw(2.0).rescaled(3.0) == HertzLaw(2.0)


def test_amplitude_floor_of_laws_without_precompression():
    """The floor is the law's reference amplitude times sqrt(eps) (before: a division by zero for d = 1)."""
    for law in (TodaLaw(1.0, 2.0), FPULaw(2.0, 0.0, 8.0)):
        model = LatticeModel(law)
        assert amplitude_floor(model) == pytest.approx(0.5 * math.sqrt(EPS), rel=1e-15)
        assert check_family_amplitude(model, 0.01, start=True) == 0.01
        with pytest.raises(ParameterError, match="amplitude"):
            check_family_amplitude(model, 0.2, start=True)           # above START_MAX r0 = 0.05
    hertz = LatticeModel.hertz(1.5, delta0=2.0)
    assert amplitude_floor(hertz) == pytest.approx(2.0 * EPS ** 0.5, rel=1e-15)   # unchanged: delta0 sqrt(eps)


def test_a_law_whose_force_and_potential_disagree_is_refused():
    with pytest.raises(ParameterError, match="law.*force V' disagrees with the derivative of its potential"):
        LatticeModel(WrongForce())
    for law in (HertzLaw(1.5), HertzLaw(2.5, 0.3), HertzLaw(1.01, 1e-3), TodaLaw(2.0, 5.0), FPULaw(1.0, -0.7, 0.2),
                StiffHertz()):
        law.check_consistency()


def test_descriptions_round_trip_through_the_registry():
    """Every law reopens from its description as what it was; the uncompressed Hertz chain's is unchanged."""
    assert LatticeModel.hertz(1.5).describe() == {"alpha": 1.5, "masses": [1.0]}
    assert LatticeModel.hertz(2.5, delta0=0.5).describe() == {"alpha": 2.5, "delta0": 0.5, "masses": [1.0]}
    for model in (LatticeModel.hertz(1.5), LatticeModel.hertz(2.0, (1.0, 0.5), 0.3, gamma=0.1),
                  LatticeModel(TodaLaw(1.3, 0.7), (1.0, 3.0)), LatticeModel(FPULaw(1.0, 0.25, -0.5)),
                  LatticeModel(StiffHertz(1.5, 0.2, c=4.0)),
                  LatticeModel(HertzLaw(1.5), (1.0,), Damping(0.0, 0.02, HuntCrossley(0.3, clipped=False))),
                  LatticeModel(HertzLaw(2.0, 0.1), (1.0, 2.0), Damping(contact=KuwabaraKono(0.05)))):
        assert LatticeModel.from_description(model.describe()) == model
    assert {"hertz", "toda", "fpu", "stiff-hertz"} <= set(LAWS)
    assert from_description({"alpha": 2.0}) == HertzLaw(2.0)
    with pytest.raises(ParameterError, match="law"):
        from_description({"law": "no-such-law"})


def test_toda_cnoidal_wave_solves_the_lattice():
    """The closed form (module toda) satisfies m omega^2 s'' = V'(s(.+q)) - 2 V'(s) + V'(s(.-q)) (spectral
    derivatives of the closed form, residual at round-off times the stiffness), has zero mean strain and its
    frequency tends to the linear one with the weakly nonlinear coefficient b^2/4 of the Taylor coefficients.
    Tolerance: the spectral s'' amplifies round-off by (n/2)^2 ~ 4e6, i.e. ~1e-9 of max |s''|."""
    law = TodaLaw(1.3, 0.7)
    for q in (0.4, 2 * math.pi / 5, math.pi):
        for m in (0.3, 0.9, 0.999):
            w = law.cnoidal_wave(q, m, mass=1.5)
            n = len(w.xi)
            k = np.fft.fftfreq(n, 1.0 / n)
            S = np.fft.fft(w.strain)
            s2 = np.fft.ifft(-(k ** 2) * S).real
            shift = lambda d: np.fft.ifft(S * np.exp(1j * k * d)).real    # noqa: E731
            rhs = law.dV(shift(q)) - 2 * law.dV(w.strain) + law.dV(shift(-q))
            res = 1.5 * w.omega ** 2 * s2 - rhs
            assert np.max(np.abs(res)) <= 1e-7 * np.max(np.abs(rhs)), (q, m)
            assert abs(np.mean(w.strain)) < 1e-14
    lin = 2 * math.sqrt(1.3) * math.sin(0.7)
    for m in (1e-3, 1e-4):
        w = law.cnoidal_wave(1.4, m)
        assert (w.omega / lin - 1) / w.a1 ** 2 == pytest.approx(0.7 ** 2 / 4, rel=2e-4)     # O(a1^2) = O(m)
    assert law.stokes_coefficient(1.4) == pytest.approx(0.7 ** 2 / 4, rel=1e-14)


def family_omegas(model, q, a, grids):
    """omega of the wave of ``model`` at (q, a = first sine coefficient) from the linear wave, on each grid."""
    out = []
    for K in grids:
        fam = AmplitudeFamily(model, q, ProfileGrid(K, COMM))
        try:
            out.append(fam.step_to(a).omega)
        finally:
            fam.destroy()
    return out


@pytest.mark.parametrize("q,a1", [(2 * math.pi / 5, 0.3), (2 * math.pi / 5, 2.0), (math.pi, 1.0)])
def test_toda_waves_of_the_pipeline_match_the_closed_form(q, a1):
    """The amplitude family (linear wave -> a1, eq. ad on h = pi/K) converges to the cnoidal wave's frequency at
    the scheme's second order; the Richardson value agrees to the next term's size (from the three grids)."""
    law = TodaLaw(1.3, 0.7)
    exact = law.cnoidal_wave_of(q, a1).omega
    grids = (32, 64, 128)
    omegas = family_omegas(LatticeModel(law), q, a1, grids)
    errors = [abs(w - exact) for w in omegas]
    order, extrapolated = richardson(omegas, order=2.0)
    assert 1.9 < order < 2.1, (errors, order)
    assert errors[-1] < 2e-4 * exact
    h4 = abs(richardson(omegas[:2] + [omegas[1]], order=2.0)[1] - extrapolated)  # the (32, 64) value's distance
    assert abs(extrapolated - exact) <= max(h4, 1e-12)


@pytest.mark.parametrize("model", [LatticeModel.hertz(1.5, delta0=0.8), LatticeModel(TodaLaw(1.3, 0.7)),
                                   LatticeModel(FPULaw(1.0, 0.3, 0.5)), LatticeModel(FPULaw(1.0, 0.6, 0.0)),
                                   LatticeModel(StiffHertz(2.5, 0.5, c=2.0))],
                         ids=lambda m: "-".join(str(v) for v in m.law.describe().values()))
def test_small_amplitude_limit_of_every_law(model):
    """omega -> 2 sqrt(V''(0)/m) sin(q/2) (1 + C a^2), C the law's weakly nonlinear coefficient, at a = 1e-3 r0:
    the Richardson value of three grids to its estimated error (the scheme's h^4 term) and the term C a^2."""
    q, a = 2 * math.pi / 5, 1e-3 * model.reference_amplitude
    K0 = model.law.linear_stiffness
    lin = 2 * math.sqrt(K0) * math.sin(q / 2)
    C = float(InteractionLaw.stokes_coefficient(model.law, q))
    omegas = family_omegas(model, q, a, (32, 64, 128))
    order, extrapolated = richardson(omegas, order=2.0)
    h4 = abs(richardson(omegas[:2] + [omegas[1]], order=2.0)[1] - extrapolated)
    assert 1.9 < order < 2.1
    assert abs(extrapolated - lin) <= 2 * abs(C) * a ** 2 * lin + h4 + 1e-13
    assert abs(extrapolated - lin * (1 + C * a ** 2)) <= h4 + 1e-3 * abs(C) * a ** 2 * lin + 1e-13
    # the weakly nonlinear term itself at a = 0.02 r0, where C a^2 is well above the Richardson value's error: the
    # O(a^4) term is (a / r0)^2 = 4e-4 times a coefficient of order one to ten (0.3 % at most at 0.04 r0 for these
    # laws), hence 1 %; the quadratic FPU (beta = 0) checks the second-harmonic part of C alone
    a = 0.02 * model.reference_amplitude
    order, extrapolated = richardson(family_omegas(model, q, a, (32, 64, 128)), order=2.0)
    assert (extrapolated / lin - 1) / a ** 2 == pytest.approx(C, rel=1e-2)


def test_a_wave_file_of_any_law_reopens_as_that_law(tmp_path):
    """The wave study's file holds the model's description: LatticeModel.from_description of its constants is the
    Toda chain it was computed for; a resume with another b is refused naming b, one with the Hertz law naming
    the law."""
    from hertzpetsc.records import load_npz
    from hertzpetsc.errors import RecordFileError
    from hertzpetsc.studies.wave import WaveParameters, WaveStudy
    from conftest import shared_tmp
    model = LatticeModel(TodaLaw(1.3, 0.7))
    path = os.path.join(shared_tmp(tmp_path), "toda.npz")
    params = WaveParameters(model, (2 * math.pi / 5,), 0.3, 64, 10, tol=1e-9)
    (row,) = list(WaveStudy(params, COMM, path).run())
    assert row["E_refined"] <= 1e-9 and row["rho"] == pytest.approx(1.0, abs=1e-6)
    data = load_npz(path, "wave file")
    constants = {k: data[k].item() if data[k].ndim == 0 else data[k].tolist() for k in data}
    assert LatticeModel.from_description(constants) == model
    assert constants["law"] == "toda"
    WaveStudy(params, COMM, path, mode="resume").open()
    with pytest.raises(RecordFileError, match="b = 0.7 there, 0.5 requested"):
        WaveStudy(WaveParameters(model.with_parameter("b", 0.5), (2 * math.pi / 5,), 0.3, 64, 10, tol=1e-9), COMM,
                  path, mode="resume").open()


def test_a_hertz_file_is_not_resumed_as_another_law(tmp_path):
    from hertzpetsc.errors import RecordFileError
    from hertzpetsc.studies.wave import WaveParameters, WaveStudy
    from conftest import shared_tmp
    path = os.path.join(shared_tmp(tmp_path), "hertz.npz")
    hertz = LatticeModel.hertz(1.5, delta0=1.0)
    list(WaveStudy(WaveParameters(hertz, (2 * math.pi / 5,), 0.3, 64, 10), COMM, path).run())
    toda = LatticeModel(TodaLaw(1.5, 1.0))
    with pytest.raises(RecordFileError, match="law = 'toda' requested, where the file has none"):
        WaveStudy(WaveParameters(toda, (2 * math.pi / 5,), 0.3, 64, 10), COMM, path, mode="resume").open()


def test_a_branch_file_holds_its_model(tmp_path):
    """A branch of another model than the uncompressed monatomic Hertz chain stores its description and reopens as
    it; the paper's chain's branch file has no such entry (its identity unchanged)."""
    from hertzpetsc.branch import Branch
    plain = Branch(LatticeModel.hertz(2.0), 16, 4)
    assert "model" not in plain.constants()
    other = Branch(LatticeModel(TodaLaw(1.3, 0.7)), 16, 4)
    assert LatticeModel.from_description(__import__("json").loads(other.constants()["model"])) == other.model


WRONG_LAW_SCRIPT = '''
import sys
from hertzpetsc.start import init_petsc
init_petsc(sys.argv)
from dataclasses import dataclass
import numpy as np
import hertzpetsc as hz
from hertzpetsc.law import InteractionLaw
from hertzpetsc.options import guarded_main


@dataclass(frozen=True)
class Halved(InteractionLaw):
    name = "halved"
    k: float = 2.0

    def V(self, r):
        return 0.5 * self.k * np.asarray(r, float) ** 2

    def dV(self, r):
        return 0.5 * self.k * np.asarray(r, float)

    def d2V(self, r):
        return 0.5 * self.k + 0 * np.asarray(r, float)


guarded_main(lambda: hz.wave(hz.LatticeModel(Halved()), 2 * np.pi / 5, 0.1, 10, cells_per_pi=32))
'''


@pytest.mark.serial
def test_a_script_with_a_law_whose_force_and_potential_disagree_ends_in_one_error_line(tmp_path):
    """Under mpiexec -n 2: one `error:` line naming the law, status 2 (a ParameterError), no traceback."""
    import subprocess
    import sys
    from conftest import one_error_line, script_env
    path = tmp_path / "wrong_law.py"
    path.write_text(WRONG_LAW_SCRIPT)
    result = subprocess.run(["timeout", "120", "mpiexec", "-n", "2", sys.executable, str(path)], capture_output=True,
                            text=True, env=script_env(), cwd=tmp_path)
    line = one_error_line(result)
    assert result.returncode == 2
    assert "invalid law = {'law': 'halved', 'k': 2.0}" in line and "force V' disagrees" in line, line


@pytest.mark.serial
def test_a_law_from_the_command_line(tmp_path):
    """scripts/wave.py -law toda -law_b 2: the wave the driver computes is the API's (hz.wave_at on the model
    LatticeModel(TodaLaw(b=2)): the same computation, omega to 1e-10 under the different order of a run), and its
    file names the law and its parameters; driven_resonances.py -law toda: the normal mode 2 sqrt(V''(0)) sin(pi/6)
    = 1 of two beads (Toda's V''(0) = k = 1). Other drivers refuse the law, and bad -law options are one error line
    naming the option."""
    import hertzpetsc as hz
    from conftest import one_error_line, run_script
    q, A = 2 * math.pi / 10, 0.3
    r = run_script("wave.py", "-law", "toda", "-law_b", 2, "-q", "2*pi/10", "-A", A, "-N", 10, "-cells_per_pi", 100,
                   "-output", tmp_path / "w.npz", "-table", tmp_path / "w.md")
    assert r.returncode == 0, r.stderr
    point = hz.wave_at(LatticeModel(TodaLaw(1.0, 2.0)), q, A, cells_per_pi=100, comm=PETSc.COMM_SELF)
    with np.load(tmp_path / "w.npz") as z:
        assert str(z["law"]) == "toda" and float(z["b"]) == 2.0 and float(z["k"]) == 1.0
        assert abs(float(z["omega"][0]) - point.omega) < 1e-10 and float(z["E_refined"][0]) < 1e-10
    r = run_script("driven_resonances.py", "-law", "toda", "-N", 2, "-modes", 1, "-golden", 6, "-output",
                   tmp_path / "s.npz", "-table", tmp_path / "s.md", "-figures", "")
    assert r.returncode == 0 and "precompressed chain law = toda, k = 1.0, b = 1.0" in (tmp_path / "s.md").read_text()
    with np.load(tmp_path / "s.npz") as z:
        assert abs(float(z["omega_k"][0]) - 1.0) < 1e-13
    for script, args, needle in (
            ("wave.py", ("-law", "morse"), "invalid -law = 'morse'"),
            ("wave.py", ("-law", "toda", "-alpha", 2), "invalid -alpha"),
            ("wave.py", ("-law", "toda", "-law_beta", 1), "invalid -law_beta"),
            ("wave.py", ("-law", "toda", "-law_b", -1), "invalid -law_b"),
            ("wave.py", ("-law", "fpu", "-law_alpha", "x"), "invalid -law_alpha"),
            ("wave.py", ("-law_k", 2), "invalid -law_k"),
            ("wave.py", ("-law", "toda", "-beads", "steel"), "invalid -beads"),
            ("driven_response.py", ("-law", "toda", "-delta0", 1), "invalid -delta0"),
            ("precompression_map.py", ("-law", "toda"), "invalid -law = 'toda'"),
            ("continuation.py", ("-law", "fpu"), "invalid -law = 'fpu'")):
        r = run_script(script, *args, "-output", tmp_path / "x.npz", "-table", tmp_path / "x.md", timeout=120,
                       cwd=tmp_path)
        assert r.returncode == 2 and needle in one_error_line(r), (script, args, r.stderr)
    assert not (tmp_path / "x.npz").exists()
