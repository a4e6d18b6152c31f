"""Studies of driven, damped chains (issue 22; the question closing the paper's Discussion): frequency and amplitude
responses with their bifurcations, small-amplitude resonances against the linear chain's normal modes, the paper's
exact boundary driving by a travelling wave, and the generation of travelling waves by simple signals.

Each study follows the protocol of :mod:`hertzpetsc.studies.base`: ``Study(params, comm=None, output=None,
mode="new")`` with its frozen, validated parameters (:class:`ResponseParameters`, :class:`ResonanceParameters`,
:class:`WaveEndsParameters`, :class:`GenerationParameters`), its record kind, fields and solver roles (``drive_``,
``floquet_``), and an in-memory store without ``output``. Their identities are the protocol's: the constants of the
record kinds as before it, the options of ``drive_`` and ``floquet_`` that change numbers and the content hashes of
the input files (a resume from another input file or with other solver tolerances is refused, naming the option);
files written before the last two keys were added lack them and still resume. The call of before (loose
arguments) is still accepted (:meth:`DrivenStudy.legacy`).

Record files (npz, :class:`~hertzpetsc.records.NpzRecords`, written as they go, ``-resume`` continues), their columns
declared in :data:`RESPONSE_KIND` (:class:`ResponseCurve`), :data:`RESONANCE_KIND` (:class:`LinearResonances`),
:data:`WAVE_ENDS_KIND` (:class:`WaveEnds`) and :data:`GENERATION_KIND` (:class:`Generation`).
"""
from __future__ import annotations

import json
import math
from dataclasses import MISSING, dataclass, fields
from typing import TYPE_CHECKING, Any, Collection, Iterator, Optional, Sequence, overload

import numpy as np
from petsc4py import PETSc

from ..console import note
from ..continuation import (Continuation, ContinuationError, ContinuationPoint, Natural, PseudoArclength,
                             golden_maximum)
from ..dealing import dealt
from ..driven import (FLOQUET_METHODS, JACOBIANS, TOL_MU, BranchFamily, Drive, HalfSinePulses,
                      HarmonicWave, PeriodicShooting, SampledWave, _check_parameter, _one_of, check_dense_beads,
                      crossing, local_wave, neutral_saddle, refined_profile, switch_to_doubled,
                      verdict, wave_ends_drive)
from ..errors import Checked, ConvergenceError, ParameterError, check_real, param
from ..floquet import DenseFloquet
from ..model import Damping, LatticeModel, law_options
from ..records import Column, Kind, digest_column
from ..resources import (INTEGRATE_SECONDS, MAX_DENSE_BEADS, chain_seconds, check_chain_memory, check_chain_size,
                         check_work)
from ..roles import configure, uses
from ..units import bead_options, contact_options, parse_quantity
from .base import Study

if TYPE_CHECKING:
    from ..branch import Branch
    from ..waves import Orbit
    from .refinement import RefinedStates

GOLDEN = (math.sqrt(5) - 1) / 2     # the interval of a golden-section search shrinks by this per evaluation

RESPONSE_FORMAT = "hertzpetsc-driven-response-1"
_OPTIONS = Column("solver_options", "the options given under `-drive_` and `-floquet_` that change numbers "
                  "(`name=value ...`; absent from files before issue 37)", "", str, "s", constant=True, optional=True)
_STR, _INT = dict(unit="", dtype=str, format="s"), dict(unit="count", dtype=np.int64, format="d")
_CODE = dict(unit="", dtype=np.int64, format="d")
RESPONSE_KIND = Kind(RESPONSE_FORMAT, (
    Column("drive", "JSON: the chain and its driving (alpha, delta0, masses, gamma, eta, N, waveform, amplitude, "
           "omega, far end) at the start", constant=True, **_STR),
    Column("parameter", "the continuation parameter (`omega` or `amplitude`)", constant=True, **_STR),
    Column("p_end", "the continuation parameter's end value", constant=True),
    Column("base_periods", "period of the continued responses, in driving periods", constant=True, **_INT),
    Column("jacobian", "Newton's Jacobian (`dense`, `mf`)", constant=True, **_STR),
    Column("floquet", "the multipliers' route (`dense`, `slepc`, `none`)", constant=True, **_STR),
    Column("tol", "shooting tolerance (relative)", constant=True),
    Column("rtol", "flow tolerance (atol = rtol/100)", constant=True),
    Column("mode", "`arclength` or `grid`", constant=True, **_STR),
    Column("N", "beads", constant=True, **_INT),
    Column("nmult", "multipliers kept per record", constant=True, **_INT),
    _OPTIONS,
    Column("branch", "0: the continued branch; j >= 1: the branch switched onto at the j-th confirmed period "
           "doubling (period 2 k)", **_CODE),
    Column("periods", "the response's period in driving periods", **_INT),
    Column("p", "parameter value", format=".8f"),
    Column("omega", "driving frequency"),
    Column("amplitude", "driving amplitude"),
    Column("s", "arclength (grid: parameter distance)"),
    Column("dp_ds", "dp/ds (nan on a grid)"),
    Column("event", "0 regular, 1 fold, 2 period doubling, 3 Neimark-Sacker, located by the layer; on a regular "
           "point (dp_ds finite; on a grid always): a crossing bracketed between it and the previous one", **_CODE),
    Column("confirmed", "events: 1 if the multipliers of the regular points on both sides (or of two responses "
           "close to a located event) differ as the event says, else 0 (e.g. a neutral saddle); -1 regular points",
           **_CODE),
    Column("iterations", "Newton iterations", **_INT),
    Column("residual", "\\|\\|P^k(X) - X\\|\\|_inf / scale (from Newton's last evaluation, or measured again)",
           format=".1e"),
    Column("rho", "largest \\|multiplier\\| of the monodromy over the response period k 2 pi / omega", format=".6f"),
    Column("outside", "multipliers with \\|mu\\| > 1 + 1e-6", **_INT),
    Column("tau_pd", "the period-doubling test function"),
    Column("tau_ns", "the Neimark-Sacker test function"),
    Column("force_right", "largest compressive force of the last bond over the period: the force on the wall (nan "
           "without samples)",
           format=".4g"),
    Column("force_left", "largest compressive force of the first bond over the period (nan without samples)",
           format=".4g"),
    Column("amp_first", "amplitude (max - min)/2 of the first bead", format=".4g"),
    Column("amp_last", "amplitude (max - min)/2 of the last bead", format=".4g"),
    Column("amp_max", "largest bead amplitude (max - min)/2", format=".4g"),
    Column("power_in", "mean input power over the period"),
    Column("dissipation", "mean dissipation over the period"),
    Column("half_residual", "even periods k: \\|\\|P^(k/2)(X) - X\\|\\| / scale, large for a genuine period-k "
           "response (nan otherwise)"),
    Column("multipliers", "the largest multipliers (nan-padded)", "1", complex, shape="nmult"),
    Column("x", "the response's state at t = 0 (positions, velocities)", shape="N, 2"),
))
RESPONSE_FIELDS = RESPONSE_KIND.fields
EVENTS = {None: 0, "fold": 1, "period_doubling": 2, "neimark_sacker": 3}
# An event the neighbouring points do not confirm is checked on responses this fraction of its distance to the
# nearer neighbour away from it, on either side.
CONFIRM_DISTANCE = 0.05
EVENT_NAMES = {v: k for k, v in EVENTS.items()}
RESONANCE_FORMAT = "hertzpetsc-driven-resonances-1"
RESONANCE_KIND = Kind(RESONANCE_FORMAT, (
    Column("drive", "JSON: the chain and its driving", constant=True, **_STR),
    Column("modes", "the mode numbers asked for", shape="K", constant=True, **_INT),
    Column("tol", "shooting tolerance", constant=True),
    Column("rtol", "flow tolerance", constant=True),
    Column("golden", "golden-section steps per peak (absent from files before issue 37)", constant=True,
           optional=True, **_INT),
    _OPTIONS,
    Column("k", "mode number", **_INT),
    Column("omega_k", "normal-mode frequency of the undamped linear chain (closed form)", format=".8f"),
    Column("peak_linear", "frequency of the last bead's largest amplitude: damped linear chain (complex solve)",
           format=".8f"),
    Column("peak_shooting", "the same for the Hertz chain by shooting", format=".8f"),
    Column("amp_linear", "\\|X_N\\| / a at the linear peak: the first harmonic's amplitude of x_N(t) per unit "
           "actuator amplitude", format=".6g"),
    Column("amp_shooting", "the same at the shooting peak (the Fourier coefficient over the period from 64 samples; "
           "files before issue 37: hypot(x_N(0), x_N'(0)/omega))", format=".6g"),
    Column("mu_error", "largest distance of the response's sorted multipliers to exp(T lambda) of the linear "
           "damped chain",
           format=".1e"),
    Column("evaluations", "periodic responses computed for the peak", **_INT),
))
RESONANCE_FIELDS = RESONANCE_KIND.fields
WAVE_ENDS_FORMAT = "hertzpetsc-driven-wave-ends-1"
WAVE_ENDS_KIND = Kind(WAVE_ENDS_FORMAT, (
    Column("alpha", "Hertz exponent", constant=True),
    Column("P", "beads of the periodic chain of the refined waves", constant=True, **_INT),
    Column("branch", "the branch file read (a label)", constant=True, **_STR),
    Column("refined", "the refinement file read (a label)", constant=True, **_STR),
    Column("samples", "least number of points of the sampled wave profile", constant=True, **_INT),
    Column("rtols", "the flow tolerances", shape="R", constant=True),
    digest_column("branch", "branch file"), digest_column("refined", "refinement file"), _OPTIONS,
    Column("q", "wavenumber per bead (x_n = U(q n - omega t))"),
    Column("m", "wavelengths on the periodic chain", **_INT),
    Column("N", "beads of the driven chain", **_INT),
    Column("rtol", "flow tolerance", format=".0e"),
    Column("imposed", "\\|\\|P(X) - X\\|\\|_inf / \\|\\|X\\|\\|_inf of the refined wave", format=".1e"),
    Column("residual", "the same after Newton", format=".1e"),
    Column("moved", "how far Newton moved the state (relative)", format=".1e"),
    Column("iterations", "Newton iterations", **_INT),
    Column("rho", "largest \\|multiplier\\| of the driven chain over 2 pi / omega", format=".8f"),
    Column("outside", "multipliers outside the circle", **_INT),
    Column("rho_periodic", "rho(F_q)^(P/m) of the periodic chain over the same time", format=".8f"),
    Column("multipliers", "the largest multipliers", "1", complex, shape="nmult"),
))
WAVE_ENDS_FIELDS = WAVE_ENDS_KIND.fields
GENERATION_FORMAT = "hertzpetsc-driven-generation-1"
GENERATION_KIND = Kind(GENERATION_FORMAT, (
    Column("model", "JSON: alpha, masses (and delta0, eta when set)", constant=True, **_STR),
    Column("N", "beads", constant=True, **_INT),
    Column("branch", "the branch file of the travelling waves compared with (a label)", constant=True, **_STR),
    Column("bulk", "the bulk: fractions (lo, hi) of the chain", shape="2", constant=True),
    Column("run_in", "periods of run-in from rest", constant=True, **_INT),
    Column("width", "half-sine pulse width (periods)", constant=True),
    Column("tol", "shooting tolerance (absent from files before issue 37)", constant=True, optional=True),
    Column("rtol", "flow tolerance (atol = rtol a / 100; absent from files before issue 37)", constant=True,
           optional=True),
    Column("samples", "samples per period (absent from files before issue 37)", constant=True, optional=True,
           **_INT),
    digest_column("branch", "branch file"), _OPTIONS,
    Column("waveform", "0 harmonic, 1 half-sine pulses", **_CODE),
    Column("omega", "driving frequency", format="g"),
    Column("amplitude", "driving amplitude", format="g"),
    Column("gamma", "on-site damping", format="g"),
    Column("ok", "1: a periodic response was found", **_CODE),
    Column("runin_residual", "\\|\\|P(X) - X\\|\\| / scale after the run-in (large: not settled to a periodic "
           "motion)", format=".1e"),
    Column("residual", "residual after Newton"),
    Column("iterations", "Newton iterations", **_INT),
    Column("rho", "largest \\|multiplier\\| over the driving period 2 pi / omega", format=".4f"),
    Column("verdict", "1 stable, 0 neutral, -1 unstable, nan (stored as a float)", ""),
    Column("amp_first", "first bead's amplitude"),
    Column("decay", "-d ln A_n / dn over the bulk", format=".3f"),
    Column("q_bulk", "median local wavenumber over the bulk", format=".4f"),
    Column("q_spread", "interquartile range of the local wavenumbers over the bulk", format=".3f"),
    Column("amp_bulk", "median bulk amplitude", format=".3g"),
    Column("family_ratio", "median A_n / A(q_n, omega): 1 for the branch's wave at that frequency", format=".3g"),
    Column("distance", "median shape distance D_n to the branch's wave U_{q_n} over the bulk", format=".3f"),
    Column("distance_slope", "its slope along the chain", format=".1e"),
    Column("strain_static", "median mean strain x_{n+1} - x_n over the bulk (< 0 compressed)", format=".2e"),
    Column("strain_dynamic", "median (max - min)/2 of x_{n+1} - x_n", format=".2e"),
    Column("A_n", "per bead: amplitude", shape="N"),
    Column("q_n", "per bead: local wavenumber", shape="N"),
    Column("D_n", "per bead: distance to the branch profile", shape="N"),
))
GENERATION_FIELDS = GENERATION_KIND.fields
WAVEFORMS = ("harmonic", "half_sine")


def _padded(mu, n):
    out = np.full(n, np.nan, dtype=complex)
    mu = np.asarray(mu, dtype=complex)[:n]
    out[:len(mu)] = mu
    return out


def tolerances_of(rtol, scale=1.0):
    """Flow tolerances rtol and atol = rtol scale / 100, scale the size of the motion (the drive's amplitude when
    it is below 1: an absolute tolerance must not swamp a small-amplitude response)."""
    from ..chain import IntegrationTolerances
    scale = min(1.0, scale) if scale > 0 else 1.0
    return IntegrationTolerances(rtol=rtol, atol=rtol * scale / 100)


# --- the protocol of the driven studies --------------------------------------------------------------------------
def _several(name, values, what, lo=None, hi=None, lo_open=True, hi_open=True, check=None):
    """A non-empty tuple of reals, each checked as by :func:`~hertzpetsc.errors.check_real` (or by ``check``)."""
    check = check or (lambda v: check_real(name, v, what, lo, hi, lo_open, hi_open))
    out = tuple(check(v) for v in np.atleast_1d(values).tolist())
    if not out:
        raise ParameterError(name, values, f"give at least one {what}")
    return out


def _distinct(name, values, what):
    """``values`` unless one is repeated (a ParameterError naming ``name``), as AppOptions.numbers(distinct=True)."""
    if len(set(values)) < len(values):
        raise ParameterError(name, list(values), f"the {what}s must be distinct")
    return values


# Generous caps on counts whose cost per unit depends on the responses (a continuation step takes 0.1 s to several
# seconds): beyond them a run takes days. Golden-section steps beyond GOLDEN_MAX shrink the bracket below round-off.
MAX_POINTS = 10 ** 5
MAX_PERIODS = 1000
GOLDEN_MAX = 100
# The sampled wave profile of the exact boundary driving: a few arrays of this many points per (q, N) (128 MiB each)
MAX_PROFILE_SAMPLES = 2 ** 24


def _check_run_in(run_in, beads_periods):
    """The run-ins' state flows, estimated (:func:`~hertzpetsc.resources.check_work`): ``beads_periods`` the
    (beads, driving period) of each run-in of ``run_in`` periods."""
    seconds = sum(chain_seconds(N, run_in * T) for N, T in beads_periods)
    check_work("run_in", run_in, seconds, f"{len(beads_periods)} run-in(s) of {run_in} driving periods")


def _check_samples(name, samples, N, records, comm):
    """``records`` trajectories of ``samples`` stops each (one integration per stop; (samples + 1) states of N beads
    kept): their time (:func:`~hertzpetsc.resources.check_work`) and memory (one chain column per 24 states)."""
    check_work(name, samples, records * samples * INTEGRATE_SECONDS, f"{records} trajectories of {samples} stops")
    check_chain_memory(N, comm, columns=1 + math.ceil((samples + 1) / 24), name=name)


def _drive(drive):
    if not isinstance(drive, Drive):
        raise ParameterError("drive", drive, "must be a hertzpetsc.driven.Drive")
    return drive


# The tables' sentence on units (every driven table's header).
UNITS = ("Units: those of eq. nc (the masses as given, 1 by default, and the contact force (delta0 - r)_+^alpha with "
         "coefficient 1): omega in radians per time unit, the driving period 2 pi / omega")


class ResponseNotFound(ContinuationError):
    """No periodic response where a study needs one (a :class:`~hertzpetsc.continuation.ContinuationError`, exit
    status 3): the failure ``err`` with what was tried and what may help, in one line (``last``: the last response
    found, nan if none)."""

    def __init__(self, message: str, err: ConvergenceError) -> None:
        self.what, self.reason, self.where = err.what, err.reason, err.where
        self.last, self.failed = getattr(err, "last", math.nan), getattr(err, "failed", math.nan)
        RuntimeError.__init__(self, message)

    def as_option(self, options: Collection[str]) -> ResponseNotFound:
        """The same error naming the driver's options: ``(run_in)`` as ``(-run_in)`` where it has that option."""
        message = str(self)
        for name in ("run_in", "periods"):
            if name in options:
                message = message.replace(f"({name})", f"(-{name})")
        return ResponseNotFound(message, self)


class DrivenStudy(Study):
    """Common part of the driven studies (:class:`~hertzpetsc.studies.base.Study`; the call of before and the
    identity: module docstring)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        if not ((args and isinstance(args[0], self.Parameters)) or "params" in kwargs):
            args, kwargs = self.legacy(*args, **kwargs), {}
        super().__init__(*args, **kwargs)

    @classmethod
    def legacy(cls, *args: Any, **kwargs: Any) -> tuple[Any, Optional[PETSc.Comm], Optional[str], str]:
        """(params, comm, output, mode) from the call of before the protocol: the parameters without a default,
        comm, output, mode ("new"), then the others, by position or by name (the names of before in ``RENAMED``)."""
        fs = fields(cls.Parameters)
        k = sum(f.default is MISSING for f in fs)
        names = [f.name for f in fs[:k]] + ["comm", "output", "mode"] + [f.name for f in fs[k:]]
        kw = dict(zip(names, args), **{cls.RENAMED.get(n, n): v for n, v in kwargs.items()})
        params = cls.Parameters(**{f.name: kw[f.name] for f in fs if f.name in kw})
        return params, kw.get("comm"), kw.get("output"), kw.get("mode", "new")

    RENAMED = {}
    NAMES = dict(branch_sha256="the branch file's content (-branch)",
                 refined_sha256="the refinement file's content (-refined)",
                 solver_options="the solver options (-drive_*, -floquet_*)")

    def configure(self) -> None:
        """Nothing left to check: the options of ``drive_`` and ``floquet_`` are read when the study is built (its
        shooting problem, or their probe, :func:`hertzpetsc.roles.configure`)."""


# --- frequency and amplitude responses --------------------------------------------------------------------------
def corner_arclength(ds=0.02, ds_max=0.05, max_corrector=1.5):
    """The pseudo-arclength algorithm for response curves of Hertz chains: their contacts open and close, so the
    curves are only piecewise smooth (grazing points are corners, where the secant is not the tangent and Newton
    converges linearly): a corrector may land up to ``max_corrector`` ds from the prediction and take up to 20
    Newton iterations (the chord iterations of :class:`~hertzpetsc.driven.PeriodicShooting` are cheap), and the step
    grows after steps of at most 5; ``ds_max`` >= ``ds``."""
    ds = check_real("ds", ds, "the first arclength step", 0.0)
    ds_max = check_real("ds_max", ds_max, "the largest arclength step", ds, lo_open=False)
    return PseudoArclength(ds=ds, ds_max=ds_max, easy=5, max_iterations=20, max_corrector=max_corrector,
                           max_halvings=10)


@dataclass(frozen=True)
class ResponseParameters(Checked):
    """A response curve: the ``drive`` continued in ``parameter`` (omega, amplitude or gamma) from its value to
    ``p_end``; the response's period in driving ``periods``; Newton's ``jacobian`` (dense, mf) and the multipliers'
    route ``floquet`` (dense, slepc with ``nev``, none); the shooting tolerance ``tol`` and the flows' ``rtol``
    (:func:`tolerances_of`); ``algorithm`` the pseudo-arclength (None: :func:`corner_arclength`), or ``grid`` the
    parameter values of the grid mode (natural steps from the drive's value through them in their order: ``algorithm``
    if it is a continuation.Natural; a value equal to the drive's is its first record, not solved twice; ``p_end`` may
    then equal the start, :func:`hertzpetsc.api.response`); ``run_in`` driving
    periods from rest before the first Newton; ``samples`` per period for the diagnostics (0: none); ``switch`` steps on
    each period-doubled branch; ``max_steps``; the ``nmult`` largest multipliers recorded (at most 2N)."""

    drive: Drive
    parameter: str
    p_end: float = param(MISSING, "the end value of the parameter", expr=True, kind="real")
    periods: int = param(1, "the response period in driving periods", lo=1, hi=MAX_PERIODS)
    jacobian: str = param("dense", "Newton's Jacobian", choices=JACOBIANS)
    floquet: str = param("dense", "the multipliers (radius: every one outside -floquet_radius, long chains)",
                         choices=FLOQUET_METHODS)
    nev: int = param(8, "the number of dominant multipliers (SLEPc; radius: at most this many outside)", lo=1)
    tol: float = param(1e-10, "the shooting tolerance (relative)", lo=0.0, hi=1.0)
    rtol: float = param(1e-12, "the flow tolerance (atol = rtol/100)", lo=0.0, hi=1.0)
    algorithm: object = None
    grid: tuple = None
    run_in: int = param(50, "the run-in: driving periods of transient from rest before the first Newton", lo=0)
    samples: int = param(64, "the samples per period for forces and energy balance (0: none, else at least 2)", lo=0,
                         option="samples_per_period")
    switch: int = param(0, "the steps on each period-doubled branch (branch switching)", lo=0, hi=MAX_POINTS)
    max_steps: int = param(400, "the number of continuation steps", lo=1, hi=MAX_POINTS)
    nmult: int = param(64, "the number of recorded multipliers", lo=1)

    def __post_init__(self):
        drive = _drive(self.drive)
        _check_parameter(self.parameter)
        super().__post_init__()
        if not self.p_end != drive.value(self.parameter) and self.grid is None:
            raise ParameterError("p_end", self.p_end, f"must differ from the start {self.parameter} = "
                                 f"{drive.value(self.parameter):g}")
        _check_end("p_end", self.p_end, drive, self.parameter)
        if self.algorithm is not None and not isinstance(self.algorithm, (PseudoArclength, Natural)):
            raise ParameterError("algorithm", self.algorithm, "a continuation.PseudoArclength (None: "
                                 "corner_arclength()) or, with a grid, a continuation.Natural")
        if self.grid is not None:
            object.__setattr__(self, "grid", _distinct("grid", _several("grid", self.grid, "parameter value of the "
                                                                        "grid"), "grid value"))
            if len(self.grid) > MAX_POINTS:
                raise ParameterError("grid", len(self.grid), f"at most {MAX_POINTS} values (a run of days)")
            for value in self.grid:
                _check_end("grid", value, drive, self.parameter)
        dense = check_dense_beads(drive.N, self.jacobian, self.floquet)
        check_chain_size(drive.N, 2 + 2 * drive.N if dense else 3)
        _check_run_in(self.run_in, [(drive.N, drive.period)])
        if self.samples == 1:
            raise ParameterError("samples", 1, "the samples per period must be 0 (no diagnostics) or at least 2")


def _check_end(name, value, drive, parameter):
    """A ParameterError naming ``name`` unless the drive with ``parameter`` set to ``value`` is valid (the drive's
    own check: omega > 0, amplitude >= 0, gamma >= 0), so a continuation does not run into it; an amplitude > 0
    (at 0 the response is the chain at rest, which the steps' relative corrector cannot measure)."""
    try:
        drive.with_parameter(parameter, value)
    except ParameterError as err:
        raise ParameterError(name, value, f"a value of the continuation parameter {parameter}: {err.valid}") from None
    if parameter == "amplitude" and value == 0:
        raise ParameterError(name, value, "a value of the continuation parameter amplitude must be > 0 (at 0 the "
                             "response is the chain at rest)")


class ResponseCurve(DrivenStudy):
    """Responses of one :class:`~hertzpetsc.driven.Drive` continued in ``parameter`` from its value to ``p_end``
    (:class:`ResponseParameters`).

    Arclength (no ``grid``): the layer's pseudo-arclength (``algorithm``), through folds, with folds, period
    doublings and Neimark-Sacker points located and each confirmed by the multipliers on both sides; grid: natural
    steps to each value of ``grid`` (every target recorded; events bracketed between grid points; a value not
    reached ends the run with a :class:`ResponseNotFound` naming the values not computed, the records before it
    kept). The first response: Newton from rest after ``run_in`` driving periods (0: from rest; not found: a
    :class:`ResponseNotFound` with the run-in's residual). ``switch``: steps taken on the
    period-doubled branch from each confirmed period doubling (branch switching). Records: module docstring."""

    Parameters = ResponseParameters
    FORMAT, FIELDS, DTYPES, COLUMNS = RESPONSE_FORMAT, RESPONSE_FIELDS, RESPONSE_KIND.dtypes, RESPONSE_KIND
    ended = None                   # why the continuation stopped before p_end, when it did (arclength: also said in
    stop = None                    # a note; grid: the error raised) and the ContinuationError that stopped it
    ROLES = uses("drive_", "floquet_")
    WHAT = "driven-response file"

    @overload
    def __init__(self, params: ResponseParameters, comm: Optional[PETSc.Comm] = None, output: Optional[str] = None,
                 mode: str = "new") -> None: ...

    @overload
    def __init__(self, drive: Drive, parameter: str, p_end: float, comm: Optional[PETSc.Comm] = None,
                 output: Optional[str] = None, mode: str = "new", **others: Any) -> None: ...

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        p = self.params
        self.drive, self.parameter, self.p_end = p.drive, p.parameter, p.p_end
        self.grid = None if p.grid is None else list(p.grid)
        self.algorithm = p.algorithm or corner_arclength()
        self.run_in, self.samples, self.switch, self.max_steps = p.run_in, p.samples, p.switch, p.max_steps
        self.nmult = min(p.nmult, 2 * p.drive.N)
        self.SHAPES = {"multipliers": (self.nmult,), "x": (p.drive.N, 2)}
        self.kw = dict(parameter=p.parameter, periods=p.periods, jacobian=p.jacobian, floquet=p.floquet, nev=p.nev,
                       tol=p.tol, tolerances=tolerances_of(p.rtol, p.drive.amplitude))
        if p.samples:                # a trajectory per record: the grid's values or the steps (and the switches')
            records = len(p.grid) if p.grid is not None else p.max_steps + p.switch
            _check_samples("samples", p.samples, p.drive.N, records, self.comm)
        self.problem = PeriodicShooting(p.drive, self.comm, **self.kw)       # configures drive_ and floquet_ now

    def constants(self) -> dict:
        """The constants (all part of the identity)."""
        p = self.params
        return dict(drive=json.dumps(p.drive.describe(), sort_keys=True, default=str), parameter=p.parameter,
                    p_end=p.p_end, base_periods=p.periods, jacobian=p.jacobian, floquet=p.floquet, tol=p.tol,
                    rtol=p.rtol, mode="grid" if p.grid is not None else "arclength", N=p.drive.N, nmult=self.nmult)

    # records
    def _record(self, problem, point, branch, event=None, confirmed=-1):
        rep = point.report
        mu = rep.get("multipliers", np.zeros(0))
        x = rep["x"]
        drive = problem.drive.with_parameter(problem.parameter, point.parameter)
        problem.set_drive(drive)
        res = problem.known_residual(x, point.parameter)
        if res is None:
            res = problem.residual(x)
        half = math.nan
        if problem.periods % 2 == 0:                # not a response of half the period: ||P^(k/2) X - X|| / scale
            k = problem.periods
            problem.periods = k // 2
            try:
                half = problem.residual(x)
            finally:
                problem.periods = k
        diag = problem.diagnostics(x, self.samples) if self.samples else {}
        amp = diag.get("amplitude", np.full(drive.N, np.nan))
        tests = point.tests or {}
        return dict(branch=branch, periods=problem.periods, p=point.parameter, omega=drive.omega,
                    amplitude=drive.amplitude, s=point.s, dp_ds=point.dp_ds, event=EVENTS[event],
                    confirmed=confirmed, iterations=point.iterations, residual=res,
                    rho=rep.get("rho", math.nan), outside=int(np.sum(np.abs(mu) > 1 + TOL_MU)),
                    tau_pd=tests.get("period_doubling", math.nan), tau_ns=tests.get("neimark_sacker", math.nan),
                    force_right=diag.get("force_right", math.nan), force_left=diag.get("force_left", math.nan),
                    amp_first=float(amp[0]), amp_last=float(amp[-1]), amp_max=float(np.max(amp)),
                    power_in=diag.get("power_in", math.nan), dissipation=diag.get("dissipation", math.nan),
                    half_residual=half, multipliers=_padded(mu, self.nmult), x=x)

    def branch_records(self, branch: int = 0) -> list[dict]:
        return [r for r in self.store.records if int(r["branch"]) == branch]

    def _regular(self, r):
        """A point the continuation stepped to (not an event it located between two such points): on a grid every
        record; else a record without event, or one whose event is bracketed on it (finite dp/ds), or a branch's
        first point."""
        if self.grid is not None and int(r["branch"]) == 0:
            return True
        dp = float(r["dp_ds"])
        return int(r["event"]) == 0 or int(r["confirmed"]) == -1 or (math.isfinite(dp) and dp != 0.0)

    def _seed_from(self, cont, problem, records, branch=0):
        """Seed ``cont`` from the last two regular ``records`` and the step size the run had reached (resume);
        the located events after the last regular record (a run stopped between them and the next point): they
        are computed again and must not be recorded twice."""
        last = max(i for i, r in enumerate(records) if self._regular(r))
        regular = [r for r in records[:last + 1] if self._regular(r)][-2:]
        Zs = [problem.pack(np.asarray(r["x"]), float(r["p"])) for r in regular]
        cont.seed(Zs, [float(r["s"]) for r in regular])
        for Z in Zs:
            Z.destroy()
        ds = self.store.state.get(f"ds_{branch}")
        if ds is not None:
            cont.ds = float(ds)
        return records[last], list(records[last + 1:])

    def _append(self, rec, cont):
        """Append a record with the continuation's next step size (the state a resume starts from)."""
        state = {f"ds_{int(rec['branch'])}": np.float64(cont.ds)} if cont.ds is not None else None
        self.store.append(rec, state)

    @staticmethod
    def _same_event(rec, point, code):
        return int(rec["event"]) == code and abs(float(rec["s"]) - point.s) <= 1e-12 * max(1.0, abs(point.s))

    def planned(self) -> Optional[int]:
        """Grid mode without switching: the grid's values (and the start) not yet in the file; else None (a
        continuation's steps are not known in advance)."""
        if self.grid is None or self.switch:
            return None
        done = [self.drive.value(self.parameter)] + [float(r["p"]) for r in self.open().branch_records(0)]
        todo = [p for p in self.grid if not any(abs(q - p) <= 1e-12 * max(1, abs(p)) for q in done)]
        return len(todo) + (0 if self.branch_records(0) else 1)

    def run(self) -> Iterator[dict]:
        """Compute what the file lacks: the main branch, then the period-doubled branches. Yields each record."""
        self.open()
        yield from self._main()
        if self.switch:
            yield from self._switched()

    def _main(self):
        prob = self.problem
        done = self.branch_records(0)
        p_start = self.drive.value(self.parameter)
        if self.grid is not None:        # the start's value is the first record (a grid may hold it: hz.response)
            targets = [p for p in self.grid if not any(abs(q - p) <= 1e-12 * max(1, abs(p))
                                                       for q in [p_start] + [float(r["p"]) for r in done])]
            if done and not targets:
                return
        elif done and (len(done) >= self.max_steps
                       or (float(done[-1]["p"]) - self.p_end) * (p_start - self.p_end) <= 0):
            return
        # grid: natural steps, the algorithm given if natural, else the default
        cont = Continuation(prob, self.algorithm if self.grid is None or isinstance(self.algorithm, Natural)
                            else Natural())
        trailing = []
        try:
            if done:
                previous, trailing = self._seed_from(cont, prob, done)
            else:
                x = np.zeros((self.drive.N, 2))
                if self.run_in:
                    x = prob.run_in(x, self.run_in)
                Z = prob.pack(x)
                try:
                    point = cont.start(Z)
                except ConvergenceError as err:
                    raise self._no_first_response(err, prob, x, p_start) from None
                finally:
                    Z.destroy()
                previous = self._record(prob, point, 0)
                self._append(previous, cont)
                yield previous
            if self.grid is not None:
                yield from self._grid(cont, previous, targets)
            else:
                yield from self._arclength(cont, previous, p_start, len(done) - len(trailing) + (0 if done else 1),
                                           trailing)
        finally:
            cont.destroy()

    def _grid(self, cont, previous, targets):
        prob = self.problem
        mu_prev = previous["multipliers"]
        for i, p in enumerate(targets):
            try:
                point = cont.step_to(p)
            except ContinuationError as err:
                self._grid_stopped(err, targets[i:])
            rec = self._record(prob, point, 0)
            mu = point.report.get("multipliers", rec["multipliers"])
            kind = crossing(mu_prev, mu)
            if kind in EVENTS and kind is not None:
                rec["event"], rec["confirmed"] = EVENTS[kind], 1
            yield self.store.append(rec)
            mu_prev = mu

    def _arclength(self, cont, previous, p_start, count, trailing=()):
        prob = self.problem
        if len(cont.history) < 2:
            direction = math.copysign(1.0, self.p_end - p_start)
            step = getattr(self.algorithm, "ds", 0.02) * direction
            p_first = float(previous["p"]) + step
            point = cont.step_to(self.p_end if (p_first - self.p_end) * direction > 0 else p_first)  # not past it
            previous = self._record(prob, point, 0)
            self._append(previous, cont)
            yield previous
            count += 1
            if point.parameter == self.p_end:
                return
        try:
            yield from self._steps(cont, prob, 0, previous, trailing, self.max_steps - count, self.p_end)
        except ContinuationError as err:
            self._stopped(err)

    def _steps(self, cont, prob, branch, previous, trailing, steps, until=None):
        """The records of up to ``steps`` steps of ``cont`` on ``branch`` after the record ``previous``: each located
        event (confirmed; those of ``trailing`` were recorded before a resume) before the point that follows it; on
        branch 0 a sign change (or a fold) the layer could not locate (its corrector failed on the chord: a corner of
        the curve; the layer's unresolved event, with its note) is recorded on this point, bracketed between it and the
        previous one."""
        trailing, pending = list(trailing), []
        mu_prev = previous["multipliers"]          # the full spectra confirm the events (records keep nmult)
        tests_prev = dict(period_doubling=float(previous["tau_pd"]), neimark_sacker=float(previous["tau_ns"]))
        dp_prev = float(previous["dp_ds"])
        for point in cont.run(until=until, max_steps=steps):
            if point.event is not None:
                # an event the layer could not locate (unresolved, said in its note) is left to the bracket below
                if point.unresolved is None:
                    pending.append(point)
                continue
            rec = self._record(prob, point, branch)
            mu = point.report.get("multipliers", rec["multipliers"])
            for ev in pending:
                if trailing and self._same_event(trailing[0], ev, EVENTS[ev.event]):
                    trailing.pop(0)            # recorded before the run was stopped
                    continue
                # confirmed by the spectra on both sides, else by two responses close to it
                confirmed = crossing(mu_prev, mu) == ev.event or self._confirmed_nearby(ev, previous, rec, prob)
                er = self._record(prob, ev, branch, ev.event, int(confirmed))
                self._append(er, cont)
                yield er
            if branch == 0:
                located = {ev.event for ev in pending}
                changed = [name for name, v in (point.tests or {}).items()
                           if name in tests_prev and v * tests_prev[name] < 0]
                if math.isfinite(point.dp_ds) and math.isfinite(dp_prev) and point.dp_ds * dp_prev < 0:
                    changed.append("fold")
                missed = [name for name in changed if name not in located]
                if missed:
                    rec["event"], rec["confirmed"] = EVENTS[missed[0]], int(crossing(mu_prev, mu) == missed[0])
            pending = []
            self._append(rec, cont)
            yield rec
            mu_prev, tests_prev, dp_prev, previous = mu, point.tests or {}, point.dp_ds, rec

    def _confirmed_nearby(self, ev, before, after, problem=None):
        """Whether two responses close to a located event, on either side of it, have multipliers that differ by
        the crossing it names (the curve's neighbouring points ``before``, ``after`` may differ by several). The two
        responses lie CONFIRM_DISTANCE of the event's distance to the nearer neighbour away from it: for a period
        doubling or Neimark-Sacker point at parameters on either side (Newton at fixed parameter from the event's
        state), for a fold on either side along the neighbours' chord (Newton on the hyperplane normal to it: both
        at about the fold's parameter, one on each side of the turning point)."""
        prob, p = problem or self.problem, ev.parameter
        p_before, p_after = float(before["p"]), float(after["p"])
        spectra = []
        try:
            with prob.detour():      # the continuation goes on as if these solves had not been made
                if ev.event == "fold":
                    spectra = self._fold_sides(prob, ev, before, after)
                else:
                    direction = ev.dp_ds if math.isfinite(ev.dp_ds) and ev.dp_ds != 0.0 else p_after - p_before
                    delta = CONFIRM_DISTANCE * min(abs(p - p_before), abs(p_after - p))
                    if not (delta > 0 and direction != 0.0):
                        return False
                    for side in (-1.0, 1.0):
                        q = p + side * math.copysign(delta, direction)
                        r = prob.solve_response(ev.report["x"], q)
                        spectra.append(prob.multipliers(x=r.x, p=q))
        except (ConvergenceError, ParameterError):
            return False
        return len(spectra) == 2 and crossing(*spectra) == ev.event

    @staticmethod
    def _fold_sides(prob, ev, before, after):
        """The multipliers of two responses on either side of a located fold, along the chord of its neighbouring
        records (Newton on the hyperplane normal to the chord), CONFIRM_DISTANCE of the nearer neighbour's
        distance away; [] if the neighbours coincide."""
        z = [np.append(np.ravel(x), float(p)) for x, p in ((before["x"], before["p"]), (ev.report["x"], ev.parameter),
                                                           (after["x"], after["p"]))]
        d = z[2] - z[0]
        length = np.linalg.norm(d)
        if not length > 0:
            return []
        d /= length
        near = CONFIRM_DISTANCE * min(np.linalg.norm(z[1] - z[0]), np.linalg.norm(z[2] - z[1]))
        chord, spectra = prob.pack(d[:-1], d[-1]), []
        try:
            for side in (-1.0, 1.0):
                w = z[1] + side * near * d
                W = prob.pack(w[:-1], w[-1])
                try:
                    prob.solve(W, row=chord, value=chord.dot(W))
                    x, q = prob.state(W)
                    spectra.append(prob.multipliers(x=x, p=q))
                finally:
                    W.destroy()
        finally:
            chord.destroy()
        return spectra

    def _no_first_response(self, err, prob, x, p):
        """The error of a first response not found (exit status 3), in one line: the failure ``err`` at the start
        ``p``, the run-in's residual at its state ``x`` (large: the motion has not settled to a periodic one) and
        what may find a response."""
        try:
            residual = f"{prob.residual(x):.1e}"
        except ConvergenceError:
            residual = "not measured (its flow failed)"
        k = prob.periods
        return ResponseNotFound(
            f"no periodic response of {k} driving period{'s' if k > 1 else ''} found at {self.parameter} = {p:g}: "
            f"{err} (Newton from the state after {self.run_in} driving periods from rest, where ||P(X) - X|| / "
            f"scale = {residual}; a motion that has not settled to a periodic one keeps it large: more run-in "
            "periods (run_in), a response of several driving periods (periods), or another start may find one)", err)

    def _grid_stopped(self, err, missing):
        """A grid that could not reach its values ``missing`` (the records before them are kept): the error that
        ends the run (exit status 3), naming them; also :attr:`ended` and :attr:`stop`."""
        shown = [f"{v:g}" for v in missing]
        if len(shown) > 4:                              # one line, also for a long grid
            shown = shown[:2] + ["..."] + shown[-1:]
        values = ", ".join(shown)
        self.ended = (f"grid mode: the responses at {self.parameter} = {values} ({len(missing)} of the "
                      f"{len(self.grid)} grid values) not computed: {err}")
        self.stop = ResponseNotFound(self.ended, err)
        raise self.stop from None

    def _stopped(self, err):
        """Everything up to the last point was recorded; the curve ends there (e.g. the response is lost): say so
        once (:attr:`ended`, and a note on rank 0)."""
        self.ended = f"the continuation stopped before {self.parameter} = {self.p_end:g}: {err}"
        self.stop = err
        note(self.ended, self.comm)

    def _switched(self):
        """From each confirmed period doubling of branch 0 (in order), switch onto the doubled branch and take
        ``switch`` steps on it (branch j, periods 2 k)."""
        pds = [r for r in self.branch_records(0) if int(r["event"]) == EVENTS["period_doubling"]
               and int(r["confirmed"]) == 1]
        for j, ev in enumerate(pds, start=1):
            done = self.branch_records(j)
            if len(done) > self.switch:                 # the first point and ``switch`` steps
                continue
            double = PeriodicShooting(self.problem.drive.with_parameter(self.parameter, float(ev["p"])), self.comm,
                                      **dict(self.kw, periods=2 * self.problem.periods))
            cont = Continuation(double, self.algorithm)
            trailing = []
            try:
                if len(done) >= 2:                       # resume: the branch's last points and step size
                    _, trailing = self._seed_from(cont, double, done, j)
                else:
                    try:
                        Zs = switch_to_doubled(self.problem, double, np.asarray(ev["x"]), float(ev["p"]))
                    except ConvergenceError:
                        continue        # no doubled response found from this doubling (table: no branch j)
                    cont.seed(Zs, [0.0, 0.0])
                    for Z in Zs:
                        Z.destroy()
                    if not done:
                        Z, _, tests = cont.history[-1]
                        first = ContinuationPoint(cont.parameter, 0.0, math.nan, 1, report=double.report(Z),
                                                  tests=tests)
                        rec = self._record(double, first, j)
                        self._append(rec, cont)
                        yield rec
                try:
                    yield from self._steps(cont, double, j, self.branch_records(j)[-1], trailing,
                                           self.switch - max(len(done) - len(trailing) - 1, 0))
                except ContinuationError:
                    pass
            finally:
                cont.destroy()
                double.destroy()

    def destroy(self) -> None:
        self.problem.destroy()

    # --- tables ---------------------------------------------------------------------------------------------
    def table(self) -> str:
        recs = self.store.records
        d = json.loads(str(self.store.constants["drive"]))
        lines = [f"schema: {RESPONSE_FORMAT}; drive {d}; continuation in {self.parameter} towards {self.p_end:g}; "
                 f"{len(recs)} records.\n",
                 "Events (fold, period doubling, Neimark-Sacker) located by the continuation layer, or 'bracketed' "
                 "between the listed point and the previous one where the layer's location failed (a corner of the "
                 "curve) or on a grid; 'confirmed': the multipliers of the regular points on both sides, or of two "
                 "responses close to a located event on either side of it, differ by the crossing the event names (1), "
                 "or not (0: e.g. a neutral saddle, marked where the stored multipliers show it: the factor of tau_NS "
                 "nearest zero is that of a real pair mu, 1/mu).\n",
                 f"{UNITS}. Columns: branch (0 the continued one, j the j-th period-doubled); periods k (the "
                 f"response's period k 2 pi / omega); {self.parameter} (the continuation parameter); rho: the largest "
                 "|mu| of the monodromy over one response period k 2 pi / omega (Liouville and, where it holds, "
                 "symplecticity checked on every dense monodromy); residual: ||P^k(X) - X||_inf / max(||X||_inf, a); "
                 "force_right: largest compressive force of the last bond over the period (the force on the wall, in "
                 "the law's unit); amp_max: largest bead amplitude (max - min)/2 of x_n over the period.\n",
                 "| branch | periods | event | " + self.parameter + " | confirmed | rho | residual | force_right | "
                 "amp_max |", "|---|---|---|---|---|---|---|---|---|"]
        arclength = str(self.store.constants.get("mode", "arclength")) == "arclength"
        for r in recs:
            if int(r["event"]) == 0 and (int(r["branch"]) == 0 or r is not self.branch_records(int(r["branch"]))[0]):
                continue                           # regular points but the first of a switched branch
            name = EVENT_NAMES[int(r["event"])] or "first point"
            if int(r["event"]) == EVENTS["neimark_sacker"] and int(r["confirmed"]) == 0 and \
                    neutral_saddle(r["multipliers"]):
                name += " (neutral saddle)"
            dp = float(r["dp_ds"])
            if int(r["event"]) and (not arclength or (math.isfinite(dp) and dp != 0.0)):
                name += " (bracketed)"
            lines.append(RESPONSE_KIND.row(r, "{branch}", "{periods}", name, "{p}", "{confirmed}", "{rho}",
                                           "{residual}", "{force_right}", "{amp_max}"))
        for j in sorted({int(r["branch"]) for r in recs}):
            br = self.branch_records(j)
            span = f"{len(br)} points, {self.parameter} from {float(br[0]['p']):.6g} to {float(br[-1]['p']):.6g}"
            worst = f"max residual {max(float(r['residual']) for r in br):.1e}"
            if j:
                lines.append(f"Branch {j} (period {int(br[0]['periods'])} T): {span}, {worst}.")
                continue
            stable = sum(1 for r in br if float(r["rho"]) < 1 - TOL_MU)
            verdicts = f"stable (rho < 1 - {TOL_MU:g}) at {stable}" \
                if any(math.isfinite(float(r["rho"])) for r in br) else "multipliers not computed (floquet none)"
            if str(self.store.constants.get("floquet", "")) == "radius" and verdicts[0] == "s":
                verdicts += (" (floquet radius: every multiplier outside a radius r < 1, -floquet_radius or the "
                             "default e^(-gamma T / 4); rho = r where none lies outside)")
            forces = [float(r["force_right"]) for r in br if math.isfinite(float(r["force_right"]))]
            force = f"max force_right {max(forces):.4g}" if forces else "force_right not computed (samples 0)"
            lines += ["", f"Branch 0: {span}; {verdicts}; {worst}; {force}."]
        return "\n".join(lines) + "\n"


# --- small-amplitude resonances of the precompressed chain ---------------------------------------------------------
def bond_dashpot(model):
    """The dashpot of every bond of the chain linearised at rest: eta and, with a contact dissipation, its
    linearisation at the overlap delta0 (:meth:`~hertzpetsc.dissipation.ContactDissipation.linear_dashpot`:
    Hunt-Crossley (3/2) c delta0^alpha, Kuwabara-Kono eta_c delta0^(alpha - 1))."""
    contact = model.damping.contact
    return model.damping.eta + (0.0 if contact is None else contact.linear_dashpot(model.law))


def linear_chain(drive):
    """(M, C, Kmat, f) of the linearised chain of a drive with a harmonic actuator at the left and a wall (or free
    end) at the right: M x'' + C x' + Kmat x = Re(f e^{i omega t}) with f = (K + i omega eta) a e_1, K = V''(0) (of the
    actuator's bond, -1, when the bonds differ; Kmat then with each bond's V''(0)) and eta the bonds' dashpot, the
    contacts' linearised damping included (:func:`bond_dashpot`)."""
    model, N = drive.model, drive.N
    K = model.law.linear_stiffness
    L = 2 * np.eye(N) - np.eye(N, k=1) - np.eye(N, k=-1)
    if drive.right == "free":
        L[-1, -1] = 1.0
    M = np.diag(model.mass(np.arange(N)))
    C = model.damping.gamma * np.eye(N) + bond_dashpot(model) * L
    if model.bonds is None:
        return M, C, K * L, K
    # bonds of different laws: bond n (beads n, n + 1; -1 the actuator's, N - 1 the wall's) of stiffness K_n
    Kb = np.array([model.bond_law(n).linear_stiffness for n in range(-1, N)])
    if drive.right == "free":
        Kb[-1] = 0.0
    Kmat = np.diag(Kb[:-1] + Kb[1:]) - np.diag(Kb[1:-1], 1) - np.diag(Kb[1:-1], -1)
    return M, C, Kmat, float(Kb[0])


def linear_response(drive, omega=None):
    """Complex amplitudes X (x_n = Re X_n e^{i omega t}) of the damped linear chain driven by a cos(omega t)."""
    M, C, Kmat, K = linear_chain(drive)
    w = drive.omega if omega is None else omega
    f = np.zeros(drive.N, complex)
    f[0] = (K + 1j * w * bond_dashpot(drive.model)) * drive.amplitude
    return np.linalg.solve(-w * w * M + 1j * w * C + Kmat, f)


def normal_modes(drive):
    """The undamped linear chain's frequencies: sqrt of the eigenvalues of M^-1 Kmat (unit masses and a wall:
    2 sqrt(K) sin(k pi / (2 (N + 1))))."""
    M, _, Kmat, _ = linear_chain(drive)
    return np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, Kmat)).real))


def linear_multipliers(drive, T):
    """exp(T lambda) for the eigenvalues lambda of the linear damped chain's first-order matrix (sorted by
    decreasing modulus, then argument)."""
    M, C, Kmat, _ = linear_chain(drive)
    N = drive.N
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((N, N)), np.eye(N)], [-Mi @ Kmat, -Mi @ C]])
    return np.exp(T * np.linalg.eigvals(A))


# Samples per period of the first-harmonic quadrature of a resonance (the response at small amplitude: its
# harmonics beyond the first are O(a / delta0) smaller each order, those from J - 1 on below round-off).
HARMONIC_SAMPLES = 64


def _match(mu, ref):
    """max |mu_i - ref_j| after matching each multiplier to the nearest of the reference set (greedy)."""
    ref = list(np.asarray(ref, complex))
    worst = 0.0
    for m in np.asarray(mu, complex):
        j = int(np.argmin([abs(m - r) for r in ref]))
        worst = max(worst, abs(m - ref[j]))
        ref.pop(j)
    return worst


@dataclass(frozen=True)
class ResonanceParameters(Checked):
    """The linear resonances: the ``drive`` of a precompressed chain (delta0 > 0, at most
    :data:`~hertzpetsc.resources.MAX_DENSE_BEADS` beads), the mode numbers ``modes`` in [1, N] (None: all), the
    shooting tolerance ``tol`` and the flows' ``rtol``, ``golden`` golden-section steps per peak."""

    drive: Drive
    modes: tuple = param(None, "mode numbers k (None: all 1..N)", "integers", lo=1, distinct=True)
    tol: float = param(1e-10, "the shooting tolerance (relative)", lo=0.0, hi=1.0)
    rtol: float = param(1e-12, "the flow tolerance (atol = rtol/100)", lo=0.0, hi=1.0)
    golden: int = param(40, "the golden-section steps per peak (more shrink the bracket below round-off)", lo=1,
                        hi=GOLDEN_MAX)

    def __post_init__(self):
        drive = _drive(self.drive)
        super().__post_init__()
        if not drive.model.law.linear_stiffness > 0:
            raise ParameterError("delta0", drive.model.delta0, "the linear resonances need a precompressed chain "
                                 "(delta0 > 0; another law: V''(0) > 0)")
        if not drive.model.damped:
            raise ParameterError("gamma", drive.gamma, "the resonances need a damped chain, gamma > 0 (or eta > 0): "
                                 "undamped, the response at omega_k is unbounded and not isolated (the multiplier 1)")
        if drive.N > MAX_DENSE_BEADS:
            raise ParameterError("N", drive.N, f"at most {MAX_DENSE_BEADS} beads (dense linear chain and multipliers)")
        for k in self.modes or ():
            if not 1 <= k <= drive.N:
                raise ParameterError("modes", k, f"a mode number in [1, N] = [1, {drive.N}]")


class LinearResonances(DrivenStudy):
    """Small-amplitude responses of a precompressed chain between an actuator a cos(omega t) and a wall
    (:class:`ResonanceParameters`): for each normal mode k, the peak of the last bead's amplitude from shooting
    responses of the Hertz chain against the damped linear chain's (closed form: complex solve) and against
    omega_k; the multipliers at the peak against exp(T lambda) of the linear chain. Records per mode (module
    docstring)."""

    Parameters = ResonanceParameters
    FORMAT, FIELDS, DTYPES, COLUMNS = RESONANCE_FORMAT, RESONANCE_FIELDS, RESONANCE_KIND.dtypes, RESONANCE_KIND
    ROLES = uses("drive_", floquet_=("ts",))
    WHAT = "driven-resonances file"

    @overload
    def __init__(self, params: ResonanceParameters, comm: Optional[PETSc.Comm] = None,
                 output: Optional[str] = None, mode: str = "new") -> None: ...

    @overload
    def __init__(self, drive: Drive, comm: Optional[PETSc.Comm] = None, output: Optional[str] = None,
                 mode: str = "new", **others: Any) -> None: ...

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        p = self.params
        self.drive = p.drive
        self.omega_k = normal_modes(p.drive)
        self.modes = list(range(1, p.drive.N + 1)) if p.modes is None else list(p.modes)
        self.golden = p.golden
        self.problem = PeriodicShooting(p.drive, self.comm, parameter="omega", tol=p.tol,
                                        tolerances=tolerances_of(p.rtol, p.drive.amplitude))
        self._x = None

    def constants(self) -> dict:
        """The constants (all part of the identity)."""
        p = self.params
        return dict(drive=json.dumps(p.drive.describe(), sort_keys=True, default=str), modes=self.modes, tol=p.tol,
                    rtol=p.rtol, golden=p.golden)

    def window(self, k: int) -> tuple[float, float]:
        w = self.omega_k
        lo = w[k - 2] if k >= 2 else 0.0
        hi = w[k] if k < len(w) else w[k - 1] + (w[k - 1] - lo)
        return w[k - 1] - 0.4 * (w[k - 1] - lo), w[k - 1] + 0.4 * (hi - w[k - 1])

    def shooting_amplitude(self, omega: float) -> float:
        """|X_N| / a of the response at omega: the modulus of the first Fourier coefficient of the last bead's
        x_N(t) over the period, X_N = (2 / J) sum_j x_N(t_j) e^{-i omega t_j} (J = HARMONIC_SAMPLES equal steps:
        the trapezoidal rule, exact for the harmonics below J - 1), as the linear chain's complex amplitude is."""
        prob = self.problem
        prob.set_drive(prob.drive.with_parameter("omega", omega))
        x0 = self._x if self._x is not None else np.zeros((self.drive.N, 2))
        r = prob.solve_response(x0)
        self._x = r.x
        self._evals += 1
        t, X = prob.trajectory(r.x, HARMONIC_SAMPLES)
        first = 2.0 / HARMONIC_SAMPLES * np.sum(X[:-1, -1, 0] * np.exp(-1j * omega * t[:-1]))
        return abs(first) / self.drive.amplitude

    def run(self) -> Iterator[dict]:
        self.open()
        done = {int(r["k"]) for r in self.store.records}
        for k in self.modes:
            if k in done:
                continue
            a, b = self.window(k)
            lin = lambda w: abs(linear_response(self.drive, w)[-1]) / self.drive.amplitude   # noqa: E731
            peak_lin = golden_maximum(lin, a, b, GOLDEN ** 60 * (b - a))[0]
            self._evals, self._x = 0, None
            peak = golden_maximum(self.shooting_amplitude, a, b, GOLDEN ** self.golden * (b - a))[0]
            amp = self.shooting_amplitude(peak)
            prob = self.problem
            mu = prob.multipliers(x=self._x, p=peak)
            ref = linear_multipliers(prob.drive, prob.T)
            rec = dict(k=k, omega_k=float(self.omega_k[k - 1]), peak_linear=peak_lin, peak_shooting=peak,
                       amp_linear=lin(peak_lin), amp_shooting=amp, mu_error=_match(mu, ref),
                       evaluations=self._evals)
            yield self.store.append(rec)

    def table(self) -> str:
        d = self.drive
        contact = d.model.damping.contact
        contact = "" if contact is None else ", contact dissipation " + ", ".join(
            f"{k} = {v}" for k, v in contact.describe().items()) + f" (linearised at rest: a dashpot " \
            f"{contact.linear_dashpot(d.model.law):.6g} in every bond, with eta in the linear chain)"
        law = f"alpha = {d.model.alpha:g}, delta0 = {d.model.delta0:g}" if d.model.law.name == "hertz" else \
            ", ".join(f"{k} = {v}" for k, v in d.model.law.describe().items())
        lines = [f"schema: {RESONANCE_FORMAT}; precompressed chain {law} (K = V''(0) = "
                 f"{d.model.law.linear_stiffness:.6g}), N = {d.N}, masses {list(d.model.masses)}, gamma = "
                 f"{d.model.damping.gamma:g}, eta = {d.model.damping.eta:g}{contact}; actuator a cos(omega t), a = "
                 f"{d.amplitude:g}; right end {d.right}.\n",
                 f"{UNITS}. k: mode number; omega_k: normal modes of the undamped linear chain (closed form); "
                 "peak (linear): maximum over omega of the last bead's |X_N| for the damped linear chain (complex "
                 "solve, golden section); peak (shooting): the same from periodic responses of the Hertz chain (Newton "
                 "shooting, golden section); |X_N|/a: the first harmonic's amplitude of x_N(t) per unit actuator "
                 "amplitude (shooting: the Fourier coefficient of the response over its period, "
                 f"{HARMONIC_SAMPLES} samples); mu error: max distance of the response's Floquet multipliers at its "
                 "peak (monodromy over one driving period 2 pi / omega) to exp(T lambda) of the linear damped chain; "
                 "solves: periodic responses computed for the peak.\n",
                 "| k | omega_k | peak (linear) | peak - omega_k | peak (shooting) | shooting - linear | "
                 "|X_N|/a linear | |X_N|/a shooting | mu error | solves |", "|---|---|---|---|---|---|---|---|---|---|"]
        for r in sorted(self.store.records, key=lambda r: int(r["k"])):
            lines.append(RESONANCE_KIND.row(r, "{k}", "{omega_k}", "{peak_linear}",
                                            f"{r['peak_linear'] - r['omega_k']:.2e}", "{peak_shooting}",
                                            f"{r['peak_shooting'] - r['peak_linear']:.1e}", "{amp_linear}",
                                            "{amp_shooting}", "{mu_error}", "{evaluations}"))
        return "\n".join(lines) + "\n"

    def destroy(self) -> None:
        self.problem.destroy()


# --- the paper's exact boundary driving ------------------------------------------------------------------------------
@dataclass(frozen=True)
class WaveEndsParameters(Checked):
    """The exact boundary driving: the ``branch`` and the ``refined`` waves of its periodic chain of P beads
    (:class:`~hertzpetsc.studies.refinement.RefinedStates`), the wavenumbers ``q`` (refined in it), the driven
    chains' ``sizes`` N in [1, P - 2], the flow tolerances ``rtols``, at least ``samples`` points of the sampled
    wave profile, the ``nmult`` largest multipliers recorded; ``branch_path`` and ``refined_path`` name the files
    (recorded; their contents' hashes are part of the identity)."""

    branch: object
    refined: object
    q: tuple = param(MISSING, "wavenumbers (refined in the file)", "reals", lo=0.0, hi=math.pi, hi_open=False,
                     distinct=True, expr=True)
    sizes: tuple = param(MISSING, "beads of the driven chains (dense multipliers)", "integers", lo=1,
                         hi=MAX_DENSE_BEADS, distinct=True)
    rtols: tuple = param((1e-12, 1e-14), "flow tolerances (atol = rtol/100)", lo=0.0, hi=1.0, distinct=True)
    samples: int = param(8192, "the least number of points of the sampled wave profile", lo=64,
                         hi=MAX_PROFILE_SAMPLES)
    nmult: int = param(12, "the number of recorded multipliers", lo=1)
    branch_path: str = ""
    refined_path: str = ""

    def __post_init__(self):
        super().__post_init__()
        P = self.refined.N
        self.refined.check_alpha(self.branch.alpha)
        for N in self.sizes:
            if not 1 <= N <= P - 2:
                raise ParameterError("sizes", N, f"the driven chain must be a window of the periodic chain: "
                                     f"1 <= N <= P - 2 = {P - 2}")
        for q in self.q:
            if not self.refined.has(q):
                raise ParameterError("q", q, f"the refinement file has no refined wave at q = {q:.12g}")


class WaveEnds(DrivenStudy):
    """The refined travelling waves of a periodic chain of P beads (refinement file) imposed at both ends of finite
    undamped chains of N beads (:class:`WaveEndsParameters`; :func:`~hertzpetsc.driven.wave_ends_drive`, the end
    signals from the refined wave's profile :func:`~hertzpetsc.driven.refined_profile`): the wave's residual in the
    driven chain, the periodic response Newton finds from it, its multipliers over tau = 2 pi / omega, at each flow
    tolerance of ``rtols``, against the periodic chain's rho(F_q)^(P/m) (dense Floquet modulo shift, same
    tolerance)."""

    Parameters = WaveEndsParameters
    FORMAT, FIELDS, DTYPES, COLUMNS = WAVE_ENDS_FORMAT, WAVE_ENDS_FIELDS, WAVE_ENDS_KIND.dtypes, WAVE_ENDS_KIND
    ROLES = uses("drive_", floquet_=("ts",))
    WHAT, RENAMED = "driven wave-ends file", {"qs": "q"}
    LABELS = ("branch", "refined", "rtols")         # not the file names, nor rtols: a resume may add tolerances

    @overload
    def __init__(self, params: WaveEndsParameters, comm: Optional[PETSc.Comm] = None, output: Optional[str] = None,
                 mode: str = "new") -> None: ...

    @overload
    def __init__(self, branch: Branch, refined: RefinedStates, qs: Sequence[float], sizes: Sequence[int],
                 comm: Optional[PETSc.Comm] = None, output: Optional[str] = None, mode: str = "new",
                 **others: Any) -> None: ...

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        p = self.params
        self.branch, self.refined = p.branch, p.refined
        self.qs, self.sizes, self.rtols = list(p.q), list(p.sizes), list(p.rtols)
        self.samples, self.nmult = p.samples, p.nmult
        self.SHAPES = {"multipliers": (self.nmult,)}
        configure(uses("drive_"), self.comm)
        self._rho_periodic = {}

    def constants(self) -> dict:
        p = self.params
        return dict(alpha=p.branch.alpha, P=p.refined.N, branch=p.branch_path, refined=p.refined_path,
                    samples=p.samples, rtols=list(p.rtols))

    def inputs(self) -> dict:
        return dict(branch=self.params.branch_path, refined=self.params.refined_path)

    def periodic_rho(self, orbit: Orbit, rtol: float) -> float:
        key = (round(orbit.q, 12), rtol)
        if key not in self._rho_periodic:
            with DenseFloquet(orbit.spec, self.comm, tolerances_of(rtol)) as dense:
                self._rho_periodic[key] = dense.spectrum(orbit).rho ** (orbit.N / orbit.m)
        return self._rho_periodic[key]

    def run(self) -> Iterator[dict]:
        self.open()
        done = {(round(float(r["q"]), 12), int(r["N"]), float(r["rtol"])) for r in self.store.records}
        for q in self.qs:
            orbit = self.refined.orbit(self.branch.point(q))
            profile = None
            for N in self.sizes:
                for rtol in self.rtols:
                    if (round(q, 12), N, rtol) in done:
                        continue
                    if profile is None:
                        profile = refined_profile(orbit, self.comm, self.samples)
                    drive = wave_ends_drive(orbit.spec.model, N, profile, orbit.omega, q)
                    prob = PeriodicShooting(drive, self.comm, tol=1e4 * rtol, tolerances=tolerances_of(rtol))
                    try:
                        x0 = orbit.x[1:N + 1]
                        imposed = prob.residual(x0)
                        r = prob.solve_response(x0)
                        mu = prob.multipliers(x=r.x, p=orbit.omega)
                    finally:
                        prob.destroy()
                    rec = dict(q=q, m=orbit.m, N=N, rtol=rtol, imposed=imposed, residual=r.residual,
                               moved=float(np.max(np.abs(r.x - x0)) / np.max(np.abs(x0))), iterations=r.iterations,
                               rho=float(np.max(np.abs(mu))), outside=int(np.sum(np.abs(mu) > 1 + TOL_MU)),
                               rho_periodic=self.periodic_rho(orbit, rtol), multipliers=_padded(mu, self.nmult))
                    yield self.store.append(rec)

    def table(self) -> str:
        from .floquet import q_label
        recs = sorted(self.store.records, key=lambda r: (-float(r["q"]), int(r["N"]), -float(r["rtol"])))
        P = self.refined.N
        lines = [f"schema: {WAVE_ENDS_FORMAT}; refined waves of the periodic chain of P = {P} beads (alpha = "
                 f"{self.branch.alpha:g}) imposed at both ends of N beads (beads 0 and N + 1 move as the wave's, from "
                 f"its profile sampled on >= {self.samples} points), undamped.\n",
                 f"{UNITS}. q: the wave's wavenumber per bead (x_n(t) = U(q n - omega t)), q = 2 pi m / P; m: its "
                 "wavelengths on the P beads; N: beads of the driven chain; rtol: the flows' tolerance (atol = rtol / "
                 "100; every step at most a quarter of the profile's push, ChainSpec.time_scale); omega (not listed): "
                 "the wave's frequency. 'imposed': residual ||P(X) - X||_inf / ||X||_inf of the refined wave itself "
                 "in the driven chain; 'residual': after Newton; 'moved': ||X - X_wave||_inf / ||X_wave||_inf. rho: "
                 "largest |multiplier| of the driven chain's monodromy over one period tau = 2 pi / omega of the wave "
                 "(det = 1 and symplecticity checked); outside: multipliers with |mu| > 1 + 1e-6; rho periodic: "
                 "rho(F_q)^(P/m), F_q = S R(q / omega; 0) the periodic chain's map over the shift by one bead, i.e. "
                 "the periodic chain over the same tau. Driving the ends stabilises the wave where rho < rho "
                 "periodic.\n",
                 "| q | m | N | rtol | imposed | residual | moved | rho | outside | rho periodic | driven / periodic |",
                 "|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in recs:
            lines.append(WAVE_ENDS_KIND.row(r, f"{q_label(float(r['q']))} ({r['q']:.4f})", "{m}", "{N}", "{rtol}",
                                            "{imposed}", "{residual}", "{moved}", "{rho}", "{outside}",
                                            "{rho_periodic}", f"{r['rho'] / r['rho_periodic']:.4f}"))
        return "\n".join(lines) + "\n"


# --- generation of travelling waves by simple signals -----------------------------------------------------------------
def make_waveform(name, width=0.5):
    _one_of("waveform", name, WAVEFORMS, "one of")
    return HarmonicWave() if name == "harmonic" else HalfSinePulses(width)


@dataclass(frozen=True)
class GenerationParameters(Checked):
    """Simple signals at one end: the ``branch`` (its travelling-wave family; ``branch_path`` names its file,
    recorded; its content's hash is part of the identity) and a ``model`` of the same exponent (its damping is replaced by each
    gamma), N beads, the actuator's ``signals`` (of :data:`WAVEFORMS`; half_sine pulses of ``width`` periods), the
    driving frequencies ``omegas`` > 0, ``amplitudes`` >= 0 and on-site damping ``gammas`` >= 0 (every
    combination), ``run_in`` driving periods from rest, the shooting tolerance ``tol`` and the flows' ``rtol``, the
    ``bulk`` fractions (lo, hi) of the chain, ``samples`` per period."""

    branch: object
    model: LatticeModel
    N: int = param(MISSING, "the number of beads", kind="integer", lo=1)
    signals: tuple = param(MISSING, "actuator waveforms, of " + ", ".join(WAVEFORMS), "words", choices=WAVEFORMS)
    omegas: tuple = param(MISSING, "driving frequencies", "reals", lo=0.0, distinct=True, expr=True)
    amplitudes: tuple = param(MISSING, "actuator amplitudes", "reals", lo=0.0, lo_open=False, distinct=True,
                              expr=True)
    gammas: tuple = param(MISSING, "on-site dampings", "reals", lo=0.0, lo_open=False, distinct=True, expr=True)
    run_in: int = param(60, "the run-in: driving periods of transient from rest", lo=0)
    tol: float = param(1e-9, "the shooting tolerance (relative)", lo=0.0, hi=1.0)
    rtol: float = param(1e-12, "the flow tolerance (atol = rtol/100)", lo=0.0, hi=1.0)
    bulk: tuple = param((0.25, 0.75), "the bulk: fractions (lo, hi) of the chain", count=2)
    samples: int = param(128, "the samples per period", lo=8)
    width: float = param(0.5, "half_sine: the pulse duration in periods", kind="real")
    branch_path: str = ""

    def __post_init__(self):
        if not isinstance(self.model, LatticeModel):
            raise ParameterError("model", self.model, "must be a LatticeModel")
        if abs(self.model.alpha - self.branch.alpha) > 1e-12:
            raise ParameterError("alpha", self.model.alpha, f"must be the branch's exponent {self.branch.alpha:g}")
        super().__post_init__()
        for w in self.signals:
            make_waveform(w, self.width)                # a half_sine train checks the width
        if not (len(self.bulk) == 2 and 0 <= self.bulk[0] < self.bulk[1] <= 1):
            raise ParameterError("bulk", self.bulk, "two fractions lo, hi of the chain with 0 <= lo < hi <= 1")
        check_chain_size(self.N, 2 + 2 * self.N if self.N <= 200 else 3)
        per_omega = len(self.signals) * len(self.amplitudes) * len(self.gammas)
        _check_run_in(self.run_in, [(self.N, 2 * math.pi / om) for om in self.omegas] * per_omega)


class Generation(DrivenStudy):
    """A long damped chain driven at one end (wall at the other) by simple signals (:class:`GenerationParameters`):
    for each waveform, omega, amplitude and gamma, the periodic response (run-in transient from rest, then Newton:
    dense for N <= 200, Newton-Krylov above), its multipliers, and its bulk (beads in the fraction ``bulk`` of the
    chain) against the branch's travelling-wave family (:class:`~hertzpetsc.driven.BranchFamily`): local wavenumber
    and amplitude, the amplitude the family has at that (q, omega), the shape distance, their trends along the
    chain, and the static and dynamic strains. The cases are dealt to the ranks (each on one rank)."""

    Parameters = GenerationParameters
    FORMAT, FIELDS, DTYPES, COLUMNS = GENERATION_FORMAT, GENERATION_FIELDS, GENERATION_KIND.dtypes, GENERATION_KIND
    ROLES = uses("drive_", "floquet_")
    WHAT, RENAMED = "driven-generation file", {"waveforms": "signals"}
    LABELS = ("branch",)

    @overload
    def __init__(self, params: GenerationParameters, comm: Optional[PETSc.Comm] = None,
                 output: Optional[str] = None, mode: str = "new") -> None: ...

    @overload
    def __init__(self, branch: Branch, model: LatticeModel, N: int, waveforms: Sequence[str], omegas: Sequence[float],
                 amplitudes: Sequence[float], gammas: Sequence[float], comm: Optional[PETSc.Comm] = None,
                 output: Optional[str] = None, mode: str = "new", **others: Any) -> None: ...

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        p = self.params
        self.branch, self.model, self.N = p.branch, p.model, p.N
        # each case on one rank: the state flow and the Jacobian's tangent flow (2N columns up to 200 beads, else one)
        check_chain_memory(self.N, PETSc.COMM_SELF, columns=2 + 2 * self.N if self.N <= 200 else 3, name="N")
        self.family = BranchFamily(p.branch)
        self.cases = [(w, om, a, g) for w in p.signals for om in p.omegas for a in p.amplitudes for g in p.gammas]
        _check_samples("samples", p.samples, self.N, len(self.cases), self.comm)
        self.width, self.bulk = p.width, p.bulk
        self.run_in, self.tol, self.rtol, self.samples = p.run_in, p.tol, p.rtol, p.samples
        self.SHAPES = {"A_n": (self.N,), "q_n": (self.N,), "D_n": (self.N,)}
        configure(uses("drive_"), PETSc.COMM_SELF)

    def constants(self) -> dict:
        p = self.params
        return dict(model=json.dumps(p.model.describe(), sort_keys=True), N=p.N, branch=p.branch_path,
                    bulk=list(p.bulk), run_in=p.run_in, width=p.width, tol=p.tol, rtol=p.rtol, samples=p.samples)

    def inputs(self) -> dict:
        return dict(branch=self.params.branch_path)

    def inputs(self) -> dict:
        return dict(branch=self.params.branch_path)

    def _key(self, w, om, a, g):
        return (WAVEFORMS.index(w), round(om, 12), round(a, 12), round(g, 12))

    def case(self, w: str, om: float, a: float, g: float) -> dict:
        """One case on this rank (COMM_SELF): the record."""
        drive = Drive(self.model.with_damping(g, self.model.damping.eta), self.N, make_waveform(w, self.width), a, om)
        rec = dict(waveform=WAVEFORMS.index(w), omega=om, amplitude=a, gamma=g)
        nan = dict(dict.fromkeys(GENERATION_FIELDS[5:-3], math.nan), ok=0, iterations=0,
                   **{k: np.full(self.N, np.nan) for k in GENERATION_FIELDS[-3:]})
        jac = "dense" if self.N <= 200 else "mf"
        prob = PeriodicShooting(drive, PETSc.COMM_SELF, jacobian=jac, floquet="dense" if jac == "dense" else "slepc",
                                tol=self.tol, tolerances=tolerances_of(self.rtol, a))
        try:
            x = prob.run_in(np.zeros((self.N, 2)), self.run_in)
            runin = prob.residual(x)
            try:
                r = prob.solve_response(x)
            except ConvergenceError:
                rec.update(nan, runin_residual=runin)
                return rec
            mu = prob.multipliers(x=r.x, p=om)
            rho = float(np.max(np.abs(mu)))
            t, X = prob.trajectory(r.x, self.samples)
        finally:
            prob.destroy()
        pos = X[:, :, 0]
        A, c, q = local_wave(t, pos, om)
        D = np.full(self.N, np.nan)
        lo = int(self.bulk[0] * self.N)
        bulk = np.arange(lo, min(max(lo + 2, int(self.bulk[1] * self.N)), self.N - 1))
        for n in bulk:
            if np.isfinite(q[n]) and A[n] > 0:
                D[n] = self.family.distance(t, pos[:, n], om, abs(q[n]))
        strain = np.diff(pos, axis=1)[:-1]
        static = strain.mean(axis=0)
        dynamic = 0.5 * (strain.max(axis=0) - strain.min(axis=0))
        fam = np.array([self.family.amplitude(abs(q[n]), om) if np.isfinite(q[n]) else np.nan for n in bulk])
        good = A[bulk] > 0
        decay = -np.polyfit(bulk[good], np.log(A[bulk][good]), 1)[0] if np.sum(good) >= 2 else math.nan
        dfin = np.isfinite(D[bulk])
        slope = np.polyfit(bulk[dfin], D[bulk][dfin], 1)[0] if np.sum(dfin) >= 2 else math.nan
        qb = q[bulk]
        rec.update(ok=1, runin_residual=runin, residual=r.residual, iterations=r.iterations, rho=rho,
                   verdict={"stable": 1, "neutral": 0, "unstable": -1}[verdict(rho)], amp_first=float(A[0]),
                   decay=float(decay), q_bulk=float(np.nanmedian(qb)),
                   q_spread=float(np.nanpercentile(qb, 75) - np.nanpercentile(qb, 25)),
                   amp_bulk=float(np.median(A[bulk])), family_ratio=float(np.nanmedian(A[bulk] / fam)),
                   distance=float(np.nanmedian(D[bulk])), distance_slope=float(slope),
                   strain_static=float(np.median(static[bulk])), strain_dynamic=float(np.median(dynamic[bulk])),
                   A_n=A, q_n=q, D_n=D)
        return rec

    def run(self) -> Iterator[dict]:
        self.open()
        done = {self._key(WAVEFORMS[int(r["waveform"])], float(r["omega"]), float(r["amplitude"]), float(r["gamma"]))
                for r in self.store.records}
        todo = [c for c in self.cases if self._key(*c) not in done]
        costs = [self.run_in / c[1] for c in todo]
        for _, rec in dealt(todo, costs, self.comm, lambda c: self.case(*c)):
            yield self.store.append(rec)

    def linear_wavenumber(self, omega: float, strain: float) -> float:
        """q of the linear wave at omega of the chain compressed by the static strain (nan above the band edge)."""
        K = float(self.model.law.d2V(strain))           # V'' at the static strain (alpha |s|^(alpha-1), delta0 = 0)
        if not K > 0:
            return math.nan
        edge = 2 * math.sqrt(K)
        return 2 * math.asin(omega / edge) if omega < edge else math.nan

    def table(self) -> str:
        lines = [f"schema: {GENERATION_FORMAT}; chain {json.loads(str(self.store.constants['model']))}, N = {self.N}, "
                 f"actuator at bead 0, wall at bead N + 1; periodic response after {self.run_in} periods of run-in "
                 f"from rest and Newton; bulk = beads {self.bulk[0]:g} N .. {self.bulk[1]:g} N.\n",
                 f"{UNITS}. periodic: whether Newton found a periodic response (of the driving period); rho: the "
                 "largest |mu| of its monodromy over one driving period 2 pi / omega (Liouville and conformal "
                 "symplecticity checked); a: the actuator's amplitude; gamma: on-site damping; A bulk: median bead "
                 "amplitude (max - min)/2 over the bulk; q IQR: interquartile range of the local wavenumbers.\n",
                 "q: median local wavenumber per bead over the bulk (bead-to-bead time lag x omega); A/A_fam: median "
                 "ratio of the bead amplitude to the amplitude of the branch's wave with that q at the driving "
                 "frequency (1: on the family); D: median RMS distance of the normalised bead motion to the branch's "
                 "profile U_q (0: the wave's shape); decay: -d ln A_n/dn; strains: static (mean x_{n+1} - x_n, < 0 "
                 "compressed) and dynamic ((max - min)/2); q lin: the wavenumber of the linear wave at omega in the "
                 "chain statically compressed by the bulk's static strain s: omega = 2 sqrt(K) sin(q/2), K = V''(s) = "
                 "alpha |s|^(alpha-1) (the actuator's mean push compresses the chain against the wall).\n",
                 "| signal | omega | a | gamma | periodic | rho | q | q lin | q IQR | A bulk | A/A_fam | D | dD/dn | "
                 "decay | static strain | dynamic strain |", "|---" * 16 + "|"]
        for r in sorted(self.store.records, key=lambda r: (int(r["waveform"]), float(r["gamma"]), float(r["amplitude"]),
                                                           float(r["omega"]))):
            case = (WAVEFORMS[int(r["waveform"])], "{omega}", "{amplitude}", "{gamma}")
            if not int(r["ok"]):
                no = f"no (run-in residual {r['runin_residual']:.1e})"
                lines.append(GENERATION_KIND.row(r, *case, no) + " |" * 11)
                continue
            q_lin = f"{self.linear_wavenumber(r['omega'], r['strain_static']):.4f}"
            lines.append(GENERATION_KIND.row(r, *case, "yes", "{rho}", "{q_bulk}", q_lin, "{q_spread}", "{amp_bulk}",
                                             "{family_ratio}", "{distance}", "{distance_slope}", "{decay}",
                                             "{strain_static}", "{strain_dynamic}"))
        return "\n".join(lines) + "\n"


# --- the drivers' shared options -------------------------------------------------------------------------------------
def drive_options(opts, N=20, delta0=0.0, gamma=0.05, amplitude=0.5, omega=1.0, signal="harmonic", beads=False):
    """Declare and read the options that define a driven chain (for the drivers; ``opts`` an
    :class:`~hertzpetsc.options.AppOptions`): the Hertz law (-alpha, -delta0), -N, -masses, -gamma, -eta, the
    actuator's -signal (harmonic, half_sine with -width, samples with -signal_samples over one closed period),
    -amplitude, -omega, the far end -right (wall, free) and a dissipation in the contacts
    (:func:`hertzpetsc.units.contact_options`: -contact, -contact_damping, -unclipped; with beads also
    -contact_coefficient, -restitution, -impact_velocity); -law with -law_<parameter> for another law than Hertz
    (:func:`hertzpetsc.model.law_options`). Returns the :class:`~hertzpetsc.driven.Drive`
    (ParameterError naming the parameter for a value out of range: negative damping, amplitude < 0, omega <= 0,
    a sampled signal that is not periodic). With ``beads``: also the chain in SI units
    (:func:`hertzpetsc.units.bead_options`: -beads, -radius, -static_force, ...) and the actuator's -drive_amplitude
    (a length) and -drive_frequency (in Hz) in their stead; returns (drive, the BeadChain or None)."""
    alpha = opts.real("alpha", 1.5, "Hertz exponent", valid=(lambda x: x > 1, "> 1"))
    d0 = opts.real("delta0", delta0, "precompression (static overlap; 0: the sonic vacuum)")
    n = opts.integer("N", N, "beads between the actuator and the far end", minimum=1)
    masses = opts.numbers("masses", "1", "mass pattern (repeated along the chain)", expr=False)
    gamma = opts.real("gamma", gamma, "on-site damping (force -gamma x_n')")
    eta = opts.real("eta", 0.0, "damping between neighbours (a dashpot in every bond)")
    kind = opts.string("signal", signal, "the actuator's waveform", choices=("harmonic", "half_sine", "samples"))
    width = opts.real("width", 0.5, "half_sine: pulse duration in periods")
    samples = opts.numbers("signal_samples", "0,1,0,-1,0", "samples: the waveform over one closed period (the last "
                           "sample closes the period)")
    a = opts.real("amplitude", amplitude, "actuator amplitude a >= 0")
    om = opts.real("omega", omega, "driving frequency omega > 0", expr=True)
    right = opts.string("right", "wall", "the far end", choices=("wall", "free"))
    chain = None
    if beads:
        chain = bead_options(opts)
        a_si = opts.string("drive_amplitude", "", "-beads: the actuator's amplitude (e.g. 1um), instead of -amplitude")
        f_si = opts.string("drive_frequency", "", "-beads: the driving frequency (e.g. 2kHz), instead of -omega")
        for name, given in (("drive_amplitude", a_si), ("drive_frequency", f_si)):
            if given and chain is None:
                raise ParameterError(f"-{name}", given, "is in SI units: give the beads (-beads) too")
        if chain is not None:
            for name, si in (("amplitude", "drive_amplitude"), ("omega", "drive_frequency")):
                if opts.db.hasName(name) and opts.db.hasName(si):
                    raise ParameterError(f"-{name}", opts.db.getString(name, ""), f"give one of -{name} "
                                         f"(dimensionless) and -{si} (SI)")
            if a_si:
                a = chain.from_si("length", check_real("-drive_amplitude", parse_quantity(
                    "-drive_amplitude", a_si, "length"), "the actuator's amplitude", 0.0, lo_open=False))
            if f_si:
                om = chain.from_si("angular_frequency", 2 * math.pi * check_real("-drive_frequency", parse_quantity(
                    "-drive_frequency", f_si, "frequency"), "the driving frequency", 0.0))
    contact = contact_options(opts, chain, si=beads)
    law = law_options(opts)
    if opts.help:
        return (None, None) if beads else None
    model = LatticeModel.hertz(alpha, tuple(masses), d0, gamma, eta) if chain is None else chain.model(gamma, eta)
    if law is not None:
        model = LatticeModel(law, tuple(masses), Damping(gamma, eta))
    if contact is not None:
        model = LatticeModel(model.law, model.masses, Damping(gamma, eta, contact), model.bonds)
    waveform = {"harmonic": HarmonicWave, "half_sine": lambda: HalfSinePulses(width),
                "samples": lambda: SampledWave(tuple(samples))}[kind]()
    drive = Drive(model, n, waveform, a, om, right)
    return (drive, chain) if beads else drive
