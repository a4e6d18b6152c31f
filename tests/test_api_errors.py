"""API errors name the Python argument (issue 37): a value of the wrong type (a string where a number is needed, a
tuple of strings for sizes, an object of another kind), a repeated member of a list that must hold distinct values,
a count that would run for hours: a ParameterError naming the argument, never a bare TypeError, ValueError or
AttributeError from inside. The sweep passes every kind of wrong value to every argument of the cheap constructors
of the public surface."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

import hertzpetsc as hz
from conftest import small_branch
from hertzpetsc import resources
from hertzpetsc.chain import Chain, ChainIntegrator, IntegrationTolerances
from hertzpetsc.continuation import Natural, PseudoArclength
from hertzpetsc.driven import Drive, HarmonicWave
from hertzpetsc.errors import HertzPetscError, ParameterError
from hertzpetsc.solitary import SolitaryParameters
from hertzpetsc.studies.solitary_stability import SolitaryStabilityParameters

PRE = hz.LatticeModel.hertz(1.5, delta0=1.0)
DAMPED = hz.LatticeModel.hertz(1.5, delta0=1.0, gamma=0.05)
DRIVE = Drive(DAMPED, 10, HarmonicWave(), 0.1, 1.0)

# values of another kind than any argument takes
WRONG = {"text": "x", "number as text": "1e-10", "tuple of text": ("a",), "object": object(), "dict": {"a": 1}}

# constructor: the arguments of a valid call
CONSTRUCTORS = [
    (IntegrationTolerances, dict(rtol=1e-12, atol=1e-14)),
    (Natural, dict(max_halvings=8, max_corrector=0.25, max_step=1.0)),
    (PseudoArclength, dict(ds=0.02, ds_min=1e-8, ds_max=0.1, growth=1.5, easy=3)),
    (hz.Damping, dict(gamma=0.1, eta=0.0)),
    (hz.HertzLaw, dict(alpha=1.5, delta0=0.0)),
    (hz.LatticeModel.hertz, dict(alpha=1.5, masses=(1.0,), delta0=0.0, gamma=0.0, eta=0.0)),
    (hz.ChainSpec, dict(model=hz.LatticeModel.hertz(), N=10)),
    (hz.ContinuationParameters, dict(alpha=1.5, M=10, cells_per_pi=200)),
    (SolitaryParameters, dict(alpha=1.5, cells_per_unit=40, half_length=8.0, tail_tolerance=1e-13)),
    (hz.SmallQParameters, dict(alpha=1.5, q_stop=math.pi / 400, q_first=math.pi / 50, per_halving=4)),
    (hz.WaveParameters, dict(model=PRE, q=(2 * math.pi / 15,), A=0.5, N=30, sizes=(60,), tol=1e-10, tol_rho=1e-4)),
    (hz.MapParameters, dict(model=PRE, q=(2 * math.pi / 10,), a=(0.5,), N=20, tol_rho=1e-4, locate=("chain",),
                            locate_tol=1e-3, limit=True, twists=0)),
    (hz.QBoundaryParameters, dict(model=PRE, A=(0.5,), q=(2 * math.pi / 10, 2 * math.pi / 8), twists=16)),
    (hz.AmplitudeParameters, dict(model=PRE, q=(0.5,), a_min=1e-3, a_max=1.0, ds=0.1)),
    (hz.DimerParameters, dict(model=PRE, q=(0.5,), a=0.5, epsilon_end=0.3, ds=0.02, ds_max=0.1)),
    (SolitaryStabilityParameters, dict(alphas=(1.5,), c0=(0.0, 0.5), M=0, tail=1e-12, tol_unstable=1e-6)),
    (Drive, dict(model=DAMPED, N=10, waveform=HarmonicWave(), amplitude=0.1, omega=1.0, left_phase=0.0)),
    (hz.ResponseParameters, dict(drive=DRIVE, parameter="omega", p_end=1.2, run_in=5, samples=16, max_steps=10)),
    (hz.ResonanceParameters, dict(drive=DRIVE, modes=(1, 2), golden=20)),
]


def _cases():
    for fn, base in CONSTRUCTORS:
        for arg in base:
            for kind, value in WRONG.items():
                yield pytest.param(fn, base, arg, value, id=f"{getattr(fn, '__qualname__', fn)}-{arg}-{kind}")


@pytest.mark.parametrize("fn, base, arg, value", list(_cases()))
def test_a_value_of_another_kind_is_a_parameter_error_naming_the_argument(fn, base, arg, value):
    fn(**base)                                          # the valid call is valid
    with pytest.raises(ParameterError) as err:
        fn(**dict(base, **{arg: value}))
    assert err.value.name == arg, str(err.value)


@pytest.mark.parametrize("call, name, words", [
    (lambda: hz.WaveParameters(PRE, (2 * math.pi / 15,), 0.5, N=30, tol="1e-10"), "tol", "not str"),
    (lambda: hz.WaveParameters(PRE, (2 * math.pi / 15,), 0.5, N=30, sizes=("a",)), "sizes", "not str"),
    (lambda: hz.WaveParameters(PRE, (2 * math.pi / 15, 2 * math.pi / 15), 0.5, N=30), "q", "twice"),
    (lambda: hz.ResponseParameters(DRIVE, "omega", 1.2, grid=(1.1, 1.2, 1.1)), "grid", "distinct"),
    (lambda: hz.MapParameters(PRE, (2 * math.pi / 10,), (0.5, 1.0), N=20, locate="everything"), "locate",
     "subset"),
    (lambda: SolitaryStabilityParameters(alphas=(1.5, 1.5)), "alphas", "twice"),
    (lambda: hz.ResonanceParameters(DRIVE, golden=1000), "golden", "round-off"),
    (lambda: Chain(hz.ChainSpec(hz.LatticeModel.hertz(), 10), PETSc.COMM_SELF, n_tangent="2"), "n_tangent",
     "not str"),
    (lambda: ChainIntegrator("a chain"), "chain", "not str"),
    (lambda: hz.DenseFloquet(hz.LatticeModel.hertz(), PETSc.COMM_SELF), "spec", "not LatticeModel"),
    (lambda: hz.refine(hz.ChainSpec(hz.LatticeModel.hertz(), 10)), "orbit", "not ChainSpec"),
    (lambda: hz.multipliers("orbit"), "orbit", "not str"),
])
def test_wrong_types_and_repeated_members_name_the_argument(call, name, words):
    with pytest.raises(ParameterError, match=words) as err:
        call()
    assert err.value.name == name


def test_the_loose_arguments_of_the_scans_are_checked_by_name():
    """The studies that predate the Parameters protocol check their arguments the same way."""
    from hertzpetsc.studies.floquet import FloquetScan
    from hertzpetsc.studies.longrun import LongRun
    from hertzpetsc.studies.refinement import RefinementScan
    branch = small_branch()
    orbit = hz.orbit(branch.point(3 * math.pi / 10), 20)
    for call, name in [(lambda: RefinementScan("branch.npz", "", 20, PETSc.COMM_SELF), "branch"),
                       (lambda: RefinementScan(branch, "", 20, PETSc.COMM_SELF, qs=("a",)), "qs"),
                       (lambda: RefinementScan(branch, "", 20, PETSc.COMM_SELF, tol="1e-10"), "tol"),
                       (lambda: FloquetScan(branch, 20, PETSc.COMM_SELF, nev="10"), "nev"),
                       (lambda: FloquetScan(branch, 20, PETSc.COMM_SELF, tolerances=1e-12), "tolerances"),
                       (lambda: RefinementScan(branch, "", 20, PETSc.COMM_SELF, mode="append"), "mode"),
                       (lambda: LongRun(orbit, "100", 4, None, PETSc.COMM_SELF), "t_final"),
                       (lambda: LongRun(orbit, 100.0, 4.5, None, PETSc.COMM_SELF), "snapshots_per_T")]:
        with pytest.raises(ParameterError) as err:
            call()
        assert err.value.name == name


def test_a_count_that_would_run_for_hours_is_refused_with_the_estimate():
    """run_in = 10^8 driving periods of 10 beads: about 10 beads x 6.3e8 time units x CHAIN_SECONDS, refused with
    that estimate in hours and the option that raises the limit; without a limit the same parameters are taken."""
    seconds = resources.chain_seconds(10, 10 ** 8 * DRIVE.period)
    assert seconds > resources.DEFAULT_MAX_HOURS * 3600
    with pytest.raises(ParameterError, match=r"about %.3g hours.*-max_hours" % (seconds / 3600)) as err:
        hz.ResponseParameters(DRIVE, "omega", 1.2, run_in=10 ** 8)
    assert err.value.name == "run_in"
    try:
        resources.set_work_limit(0)
        assert hz.ResponseParameters(DRIVE, "omega", 1.2, run_in=10 ** 8).run_in == 10 ** 8
    finally:
        resources.set_work_limit(resources.DEFAULT_MAX_HOURS)
    assert hz.ResponseParameters(DRIVE, "omega", 1.2, run_in=50).run_in == 50


def test_no_package_error_escapes_as_another_type():
    """ParameterError is a ValueError (callers that catch ValueError keep working) and a package error."""
    assert issubclass(ParameterError, ValueError) and issubclass(ParameterError, HertzPetscError)


# --- a parameter declared once (issue 39 item 1) ------------------------------------------------------------------
DECLARED = [hz.WaveParameters, hz.DimerParameters, hz.ResonanceParameters, hz.ResponseParameters,
            SolitaryStabilityParameters, hz.SmallQParameters]


@pytest.mark.parametrize("cls", DECLARED, ids=lambda c: c.__name__)
def test_a_declared_parameter_is_checked_by_its_field_and_read_as_its_option(cls):
    """Each declared field (errors.param) is one source: the dataclass refuses a value out of its range naming the
    Python argument, and AppOptions.parameters declares it as its option with the same range, refuses the same
    value naming -option, and maps an error the dataclass raises about the field to the option."""
    from dataclasses import MISSING
    from hertzpetsc.errors import specs
    from hertzpetsc.options import AppOptions
    db, kept = PETSc.Options(), AppOptions.current
    required = [f.name for f, _ in specs(cls) if f.default is MISSING]         # a driver gives their defaults
    for f, spec in specs(cls):
        if spec.kind not in ("real", "integer") or spec.lo is None:
            continue
        bad = spec.lo - 1 if spec.kind == "integer" else spec.lo - 1.0
        with pytest.raises(ParameterError, match=rf"invalid {f.name} = "):
            spec.check(f.name, bad)
        option = spec.option or f.name
        db.setValue(option, str(bad))
        try:
            opts = AppOptions()
            with pytest.raises(ParameterError, match=rf"invalid -{option} = '{bad}'"):
                opts.parameters(cls, skip=required)
            shown = {name: valid for name, _, valid, _ in opts.declared}[option]      # -help shows its range
            assert spec.rule() in shown if spec.kind == "real" else \
                f">= {spec.lo}" in shown and (spec.hi is None or f"<= {spec.hi}" in shown)
            assert ParameterError(f.name, bad, "x").as_option(opts.names()).name == f"-{option}"
        finally:
            db.delValue(option)
            AppOptions.current = kept


def test_an_option_of_another_name_names_the_option_in_errors_between_fields():
    """ResponseParameters.samples is read as -samples_per_period: the dataclass's own rule (0 or >= 2) reported by a
    driver names that option."""
    from hertzpetsc.options import AppOptions
    kept = AppOptions.current
    try:
        opts = AppOptions()
        values = opts.parameters(hz.ResponseParameters, p_end=0.3)
        assert values["samples"] == 64 and "samples_per_period" in opts.known() and "samples" not in opts.known()
        with pytest.raises(ParameterError) as err:
            hz.ResponseParameters(DRIVE, **dict(values, samples=1, parameter="omega"))
        assert str(err.value.as_option(opts.names())).startswith("invalid -samples_per_period = 1:")
    finally:
        AppOptions.current = kept


# values numpy hands a user that float() or iteration takes silently (the sweep of issue 37): a flag where a number
# is needed, a 0-d array where a list is, a 1-d array where one number is
NUMPY_WRONG = {"np.bool_": np.True_, "1-d array": np.array([0.1, 0.2])}


def _numpy_cases():
    for fn, base in CONSTRUCTORS:
        for arg, good in base.items():
            if isinstance(good, float) and not isinstance(good, bool):
                for kind, value in NUMPY_WRONG.items():
                    yield pytest.param(fn, base, arg, value, id=f"{getattr(fn, '__qualname__', fn)}-{arg}-{kind}")


@pytest.mark.parametrize("fn, base, arg, value", list(_numpy_cases()))
def test_a_numpy_flag_or_array_for_a_real_argument_is_a_parameter_error_naming_it(fn, base, arg, value):
    """np.True_ for a real (float() takes it as 1.0) and an array for one number (its truth value raised a bare
    ValueError in the continuation algorithms' inf test) are refused naming the argument."""
    with pytest.raises(ParameterError) as err:
        fn(**dict(base, **{arg: value}))
    assert err.value.name == arg, str(err.value)


@pytest.mark.parametrize("fn, base, arg", [(fn, base, arg) for fn, base in CONSTRUCTORS for arg, good in base.items()
                                           if isinstance(good, tuple) and good and isinstance(good[0], float)])
def test_a_0d_array_is_one_member_of_a_list_argument(fn, base, arg):
    """np.array(x) (what np.float64 arithmetic or a reduction gives) for a list argument is the list [x], as the
    number x is (it raised a bare TypeError: 'float' object is not iterable)."""
    assert fn(**dict(base, **{arg: np.array(base[arg][0])})) == fn(**dict(base, **{arg: base[arg][0]}))


def test_an_exponent_or_precompression_that_overflows_is_refused_naming_it():
    """alpha = 1e300 overflowed 2^alpha in the starting wave (OverflowError, an internal error of continuation.py)
    and delta0 = 1e300 overflowed delta0^alpha in the chain's kernel (driven_resonances.py): both are refused, with
    the bound: alpha <= ALPHA_MAX, delta0 below sqrt(max float)^(1/(alpha+1)) (the amplitudes' ceiling)."""
    from hertzpetsc.hertz import ALPHA_MAX
    with pytest.raises(ParameterError, match=r"<= 1000") as err:
        hz.LatticeModel.hertz(1e300)
    assert err.value.name == "alpha"
    assert 2.0 ** ALPHA_MAX < math.inf
    with pytest.raises(ParameterError, match=r"< 4.4\d*e\+61") as err:
        hz.LatticeModel.hertz(1.5, delta0=1e300)
    assert err.value.name == "delta0"
    bound = math.sqrt(np.finfo(float).max) ** (1 / 2.5)
    assert hz.LatticeModel.hertz(1.5, delta0=0.5 * bound).law.delta0 ** 2.5 < math.inf


def test_a_dimer_amplitude_beyond_the_ceiling_is_refused_before_computing():
    """a = 1e300 in DimerParameters ran the amplitude family for minutes (dimer_branch.py, killed after 90 s);
    refused now by the amplitudes' one ceiling (families.amplitude_ceiling)."""
    from hertzpetsc.families import amplitude_ceiling
    with pytest.raises(ParameterError, match="overflow") as err:
        hz.DimerParameters(PRE, q=(0.5,), a=1e300)
    assert err.value.name == "a"
    assert hz.DimerParameters(PRE, q=(0.5,), a=amplitude_ceiling(PRE)).a == amplitude_ceiling(PRE)


def test_a_grid_or_chain_beyond_memory_is_refused_before_the_wave_is_computed(monkeypatch):
    """hz.wave_at on cells_per_pi = 10^8 built the stencils of 10^8 points for minutes before the solver's memory
    check; hz.wave computed the wave before it checked N (N = 10^9, N = None). Both refuse up front now: the wave
    is never computed (families.wave_of_amplitude is replaced by a function that fails the test)."""
    import hertzpetsc.api as api

    def never(*args, **kwargs):
        raise AssertionError("the wave was computed before its arguments were checked")
    with pytest.raises(ParameterError, match="GiB") as err:
        hz.wave_at(PRE, 0.5, 0.5, cells_per_pi=10 ** 8, comm=PETSc.COMM_SELF)
    assert err.value.name == "cells_per_pi"
    monkeypatch.setattr(api, "wave_of_amplitude", never)
    for N, words in ((10 ** 9, "GiB"), (None, "not NoneType")):
        with pytest.raises(ParameterError, match=words) as err:
            hz.wave(PRE, 2 * math.pi / 10, 0.5, N=N, comm=PETSc.COMM_SELF)
        assert err.value.name == "N"


def test_a_wavenumber_given_as_text_is_refused():
    """float('0.5') made q = '0.5' a wavenumber; the error named N instead (its wavelengths did not fit)."""
    with pytest.raises(ParameterError, match="not str") as err:
        hz.wave(PRE, "0.5", 0.5, N=10, comm=PETSc.COMM_SELF)
    assert err.value.name == "q"


def test_masses_of_another_kind_are_refused_not_converted():
    """masses = b'1' iterated as the byte 49 (a pattern of one bead of mass 49); ['1'] as text: both refused by the
    one check of a list of reals (errors.check_reals), naming masses."""
    for value in (b"1", ["1"], "1", (1.0, None)):
        with pytest.raises(ParameterError) as err:
            hz.LatticeModel.hertz(1.5, masses=value)
        assert err.value.name == "masses", value
    assert hz.LatticeModel.hertz(1.5, masses=np.array([1.0, 0.5])).masses == (1.0, 0.5)


def test_a_maps_threshold_beyond_one_is_refused_as_the_other_verdicts():
    """tol_rho = 1e300 made every map point and boundary stable (boundary_in_q.py, precompression_map.py took it);
    the threshold on rho - 1 lies in (0, 1) as for the wave and the Floquet scans."""
    base = dict(CONSTRUCTORS)
    for fn in (hz.MapParameters, hz.QBoundaryParameters):
        assert fn(**dict(base[fn], tol_rho=0.5)).tol_rho == 0.5
        for value in (1.0, 1e300):
            with pytest.raises(ParameterError, match="< 1") as err:
                fn(**dict(base[fn], tol_rho=value))
            assert err.value.name == "tol_rho"
