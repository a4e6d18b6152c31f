"""One-call conveniences of the public surface (``import hertzpetsc as hz``), for notebooks and scripts: each builds
the package's objects with the paper's defaults (solver options still read from the options database, e.g.
``-shoot_ts_rtol``), runs them, frees the PETSc objects and returns plain results. Every call here is collective over
``comm`` (default PETSc.COMM_WORLD): all ranks call it with the same arguments and get the same result, except
:func:`plot_spectrum` (local: call it on one rank). The package's docstring (:mod:`hertzpetsc`) shows the paper's
pipeline in these calls.

Per-call solver options: ``options={"tw_snes_rtol": 1e-12}`` (full names, prefix included, as DOLFINx's
``petsc_options``) are in the options database for that call only, over what it holds, which is put back afterwards
(also when the call raises; :func:`hertzpetsc.options.call_options`); an option none of the call's solvers read is a
ParameterError naming ``options``.
"""
from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING, Any, Mapping, Optional, Sequence, Union

import numpy as np
from petsc4py import PETSc

from .branch import Branch, BranchPoint
from .driven import Drive, Response
from .errors import ParameterError, check_flag, check_instance, check_integer, check_integers, check_real
from .families import AmplitudePoint
from .families import wave_at as _wave_at
from .families import wave_of_amplitude
from .floquet import Spectrum
from .grid import ProfileGrid
from .model import ChainSpec, LatticeModel
from .options import call_options
from .qbranch import ContinuationParameters
from .resources import check_chain_size
from .roles import FLOQUET_ROUTES, floquet_route
from .shooting import Refinement
from .shooting import refine as _refine
from .units import BeadChain
from .studies.branch import BranchStudy
from .waves import Orbit, orbit_on_chain

if TYPE_CHECKING:
    import matplotlib.axes
    import matplotlib.figure


def _comm(comm):
    return comm if comm is not None else PETSc.COMM_WORLD


def compute_branch(model: Optional[LatticeModel] = None, M: int = 50, cells_per_pi: int = 1000,
                   q_stop: Optional[float] = None, output: Optional[str] = None, mode: str = "new",
                   comm: Optional[PETSc.Comm] = None, options: Optional[Mapping[str, Any]] = None) -> Branch:
    """The branch of eq. ad from the binary oscillation at q = pi down to q_stop through q = m pi / M (section
    3.1), on the grid h = pi / cells_per_pi, for the uncompressed ``model`` (default: the paper's, alpha = 3/2).
    Written to ``output`` as it goes when given (a branch file; ``mode`` new/resume/force), else kept in memory.
    ``options``: per-call solver options (prefix ``tw_``). Collective."""
    model = model if model is not None else LatticeModel.hertz()
    if not isinstance(model, LatticeModel):
        raise ParameterError("model", type(model).__name__, "must be a LatticeModel (e.g. LatticeModel.hertz(1.5))")
    if output is not None:
        check_instance("output", output, (str, os.PathLike), "a path (None: in memory)")
    params = ContinuationParameters(M=M, cells_per_pi=cells_per_pi, q_stop=q_stop, model=model)
    with call_options(options):
        study = BranchStudy(params, output, _comm(comm), mode)
        for _ in study.run():
            pass
    return study.branch


def wave_at(model: LatticeModel, q: float, A: float, cells_per_pi: int = 400, branch: str = "acoustic",
            comm: Optional[PETSc.Comm] = None, options: Optional[Mapping[str, Any]] = None) -> AmplitudePoint:
    """The travelling wave of a precompressed ``model`` (any mass pattern) with per-bead wavenumber q and amplitude
    A = max |u| (A is a border row of eq. ad; reached from the linear wave by natural steps), on the grid h = pi /
    cells_per_pi: an :class:`~hertzpetsc.families.AmplitudePoint` (omega, the rescaled profiles, the gap
    indicator). ``branch``: the linear wave the family starts from, 'acoustic' (the lowest frequency at q) or, for a
    mass pattern, 'optical' (the highest); a family that folds below A raises
    :class:`~hertzpetsc.families.FamilyFold` (the largest A it reaches, the other branch to try). :func:`wave` puts
    such a wave on a chain. ``options``: per-call solver options (prefix ``precomp_``). Collective."""
    grid = ProfileGrid(cells_per_pi, _comm(comm))
    with call_options(options):
        return _wave_at(model, q, A, grid, branch=branch)


def wave(model: Optional[LatticeModel], q: float, A: float, N: int, cells_per_pi: int = 400,
         comm: Optional[PETSc.Comm] = None, branch: str = "acoustic",
         options: Optional[Mapping[str, Any]] = None, beads: Optional[BeadChain] = None) -> Orbit:
    """The travelling wave of any ``model`` (Hertz exponent, precompression, mass pattern) with per-bead wavenumber
    q and amplitude A = max |u|, on a periodic chain of N beads (N q / 2 pi wavelengths, whole pattern cells): an
    :class:`~hertzpetsc.waves.Orbit` (state, script-T) ready for :func:`refine` and :func:`multipliers`.
    ``branch``: the linear wave a precompressed pattern's family starts from ('acoustic' or 'optical', as in
    :func:`wave_at`). ``options``: per-call solver options (prefix ``precomp_`` with precompression, else ``tw_``).
    ``beads``: a :class:`~hertzpetsc.units.BeadChain` whose chain this is (``model`` None: ``beads.model()``; else
    refused unless it is the beads' chain); A in its length scale; the wave in SI (Hz, s, m/s, m, N):
    ``beads.wave_si(orbit)``, also of the refined orbit. Collective."""
    if beads is not None:
        check_instance("beads", beads, BeadChain, "a BeadChain (hertzpetsc.units.BeadChain)")
        model = beads.model() if model is None else model
        beads.check_chain(model, "the model")
    elif model is None:
        raise ParameterError("model", None, "give the LatticeModel (or the beads: beads=BeadChain(...))")
    spec = ChainSpec(model, N)                     # the chain checked before the wave is computed, as in orbit()
    check_chain_size(spec.N, 1)
    with call_options(options):
        point, scale = wave_of_amplitude(model, q, A, ProfileGrid(cells_per_pi, _comm(comm)), branch=branch)
    return orbit_on_chain(point, spec, scale=scale)


def orbit(point: BranchPoint, N: int, A: Optional[float] = None) -> Orbit:
    """A point of a branch (eq. ad) as a travelling wave on a periodic chain of N beads (eq. twper): the profile
    scaled to max |u| = 1 (the paper's normalisation, section 3.4) or to max |u| = ``A`` for a scale-invariant law
    (the beads at t = 0 sample u at q n, so max_n |x_n(0)| can be below it). Local (numpy only)."""
    check_instance("point", point, BranchPoint, "a BranchPoint (branch.point(q))")
    check_chain_size(check_integer("N", N, 2, "the number of beads"), 1)
    scale = None
    if A is not None:
        A = check_real("A", A, "the amplitude max |u|", lo=0.0)
        scale = A / point.diagnostics.norm_inf
    orbit = orbit_on_chain(point, ChainSpec(point.model, N), scale=scale)
    if not (np.all(np.isfinite(orbit.x)) and math.isfinite(orbit.T) and orbit.T > 0):
        raise ParameterError("A", A, "the wave's state at this amplitude is not finite in double precision "
                                     "(displacements or velocities overflow)")
    return orbit


def refine(orbit: Orbit, tol: float = 1e-10, symmetric: bool = True,
           comm: Optional[PETSc.Comm] = None, options: Optional[Mapping[str, Any]] = None) -> Refinement:
    """Gauss-Newton refinement of ``orbit`` until E(q) <= ``tol`` (section 3.4; prefix ``shoot_``): a
    :class:`~hertzpetsc.shooting.Refinement` (``.orbit`` the refined wave, ``.E_initial``, ``.E``, ``.iterations``);
    ``symmetric``: on the wave's cell over its shortest time symmetry. ConvergenceError if E stays above tol.
    ``options``: per-call solver options (prefixes ``shoot_``, ``shoot_jac_``; ``shoot_gn_max_it``). Collective."""
    check_instance("orbit", orbit, Orbit, "an Orbit (hz.orbit, hz.wave)")
    tol = check_real("tol", tol, "the target E(q) of the refinement", lo=0.0, hi=1.0)
    symmetric = check_flag("symmetric", symmetric)
    with call_options(options):
        return _refine(orbit, _comm(comm), tol, symmetric=symmetric)


def multipliers(orbit: Orbit, method: str = "symmetric", nev: Optional[int] = None,
                tol_rho: Optional[float] = None, comm: Optional[PETSc.Comm] = None,
                options: Optional[Mapping[str, Any]] = None) -> Spectrum:
    """The Floquet multipliers of F_q = S R(script-T; 0) around ``orbit`` (section 3.5; prefix ``floquet_``): a
    :class:`~hertzpetsc.floquet.Spectrum` (``.multipliers`` sorted by modulus, ``.rho`` without the trivial ones,
    ``.outside``, ``.trivial_spread``). ``method``: ``symmetric`` (all 2N, from the Bloch sectors of the wave's
    cell; any N = L M), ``dense`` (all 2N on the whole chain, the paper's route) or ``slepc`` (the ``nev`` largest,
    Krylov-Schur, default 10). ``nev`` given with ``symmetric`` or ``dense``: all 2N are computed and the ``nev``
    largest kept (``.complete`` False). ``tol_rho`` in (0, 1): unstable when rho - 1 > tol_rho (default 1e-4).
    ``options``: per-call solver options (prefix ``floquet_``: ``floquet_ts_*``, with ``slepc`` ``floquet_eps_*``).
    Collective."""
    check_instance("orbit", orbit, Orbit, "an Orbit (hz.orbit, hz.wave, hz.refine(...).orbit)")
    if method not in FLOQUET_ROUTES:
        raise ParameterError("method", method, f"must be one of {', '.join(FLOQUET_ROUTES)}")
    if tol_rho is not None:
        tol_rho = check_real("tol_rho", tol_rho, "the verdict's threshold on rho - 1", lo=0.0, hi=1.0)
    if nev is not None:
        nev = check_integer("nev", nev, 1, "the multipliers kept", hi=2 * orbit.N)
    comm = _comm(comm)
    with call_options(options):
        with floquet_route(method, orbit.spec, comm, nev if nev is not None else 10) as solver:
            return solver.spectrum(orbit, tol_rho, nev)


def response(drive: Drive, omega: Union[float, Sequence[float]], periods: int = 1, run_in: int = 50,
             tol: float = 1e-10, rtol: float = 1e-12, jacobian: str = "dense", floquet: str = "dense", nev: int = 8,
             samples: int = 64, comm: Optional[PETSc.Comm] = None,
             options: Optional[Mapping[str, Any]] = None, beads: Optional[BeadChain] = None) -> list[Response]:
    """The periodic responses of the driven chain ``drive`` (:class:`~hertzpetsc.driven.Drive`) at the driving
    frequencies ``omega`` (one or several, distinct), with their Floquet multipliers: the grid mode of
    :class:`~hertzpetsc.studies.driven.ResponseCurve` (records in memory): the first response Newton's from the state
    after ``run_in`` driving periods from rest at omega[0], each next one a natural continuation step from the one
    before, in the order given (so the responses are one branch; give the frequencies in order along it).
    ``periods`` k: responses of period k 2 pi / omega; ``tol`` on ||P(X) - X||_inf / scale and the flows' ``rtol``
    (atol rtol / 100, scaled by an amplitude below 1), ``jacobian`` ('dense', 'mf') and ``floquet`` ('dense': all 2N,
    checked against Liouville's determinant and, where the flow is conformally symplectic, symplecticity; 'slepc':
    the ``nev`` largest, eigen-residuals checked on an independent flow; 'none') as in
    :class:`~hertzpetsc.studies.driven.ResponseParameters`; ``samples`` per period for the record's forces,
    amplitudes and power balance (0: none). One :class:`~hertzpetsc.driven.Response` per frequency, in order, with
    ``.multipliers``, ``.rho`` and ``.record``; a ConvergenceError (a ContinuationError: the last response found)
    if a frequency's response is not found. ``options``: per-call solver options (prefixes ``drive_``,
    ``floquet_``). ``beads``: the :class:`~hertzpetsc.units.BeadChain` of the drive's chain (refused unless it is
    its model): each record then also has ``si``, the response in SI units (:meth:`BeadChain.response_si
    <hertzpetsc.units.BeadChain.response_si>`: Hz, s, m, m/s, N, W). Collective."""
    from .studies.driven import ResponseCurve, ResponseParameters
    check_instance("drive", drive, Drive, "a Drive (hertzpetsc.driven.Drive)")
    if beads is not None:
        check_instance("beads", beads, BeadChain, "a BeadChain (hertzpetsc.units.BeadChain)")
        beads.check_chain(drive.model, "the drive")
    omegas = [check_real("omega", w, "the driving frequency", lo=0.0) for w in np.atleast_1d(omega).tolist()]
    if not omegas or len(set(omegas)) < len(omegas):
        raise ParameterError("omega", omega, "one or more distinct driving frequencies")
    params = ResponseParameters(drive.with_parameter("omega", omegas[0]), "omega", omegas[-1], periods=periods,
                                jacobian=jacobian, floquet=floquet, nev=nev, tol=tol, rtol=rtol, grid=tuple(omegas),
                                run_in=run_in, samples=samples, nmult=2 * drive.N)
    with call_options(options):
        study = ResponseCurve(params, _comm(comm))
        try:
            records = list(study.run())
        finally:
            study.destroy()
    if study.stop is not None:
        raise study.stop
    out = []
    for rec in records:
        mu = np.asarray(rec["multipliers"])
        mu = mu[np.isfinite(mu)] if floquet != "none" else None
        out.append(Response(drive.with_parameter("omega", float(rec["omega"])), int(rec["periods"]),
                            np.asarray(rec["x"]), float(rec["residual"]), int(rec["iterations"]), mu, rec))
        if beads is not None:
            rec["si"] = beads.response_si(out[-1])
    return out


def solitary_speed(chain: BeadChain, max_velocity: Union[float, str, Sequence[float]],
                   cells: Sequence[int] = (80, 160, 320)) -> Union[float, np.ndarray]:
    """The speed [m/s] of the solitary wave of the uncompressed bead chain ``chain`` (a
    :class:`~hertzpetsc.units.BeadChain` of one bead, static force 0) whose beads reach ``max_velocity`` [m/s] (a
    number, a string with a unit such as '0.1 m/s', or several numbers): the unit-speed wave of eq. adr computed on
    the grids 1/n, n in ``cells`` (three), its maximal bead velocity extrapolated in the grid step
    (:func:`hertzpetsc.studies.solitary.unit_wave_velocity`), scaled as v^(1/5)
    (:meth:`~hertzpetsc.units.BeadChain.solitary_speed`). Local (each rank solves on its own)."""
    from .studies.solitary import unit_wave_velocity
    check_instance("chain", chain, BeadChain, "a BeadChain (hertzpetsc.units.BeadChain)")
    cells = check_integers("cells", cells, 2, "grids n (even)", distinct=True)
    if len(cells) != 3:
        raise ParameterError("cells", cells, "three grids for the extrapolation")
    many = not isinstance(max_velocity, str) and np.ndim(max_velocity) > 0
    values = list(max_velocity) if many else [max_velocity]
    chain.solitary_speed(values[0], 1.0)            # the chain and the velocities refused before solving
    for v in values[1:]:
        chain.solitary_speed(v, 1.0)
    v1 = unit_wave_velocity(1.5, tuple(sorted(cells)))[0]
    speeds = [chain.solitary_speed(v, v1) for v in values]
    return np.array(speeds) if many else speeds[0]


def plot_spectrum(spectrum: Union[Spectrum, np.ndarray], ax: Optional[matplotlib.axes.Axes] = None,
                  title: Optional[str] = None) -> matplotlib.figure.Figure:
    """The multipliers in the complex plane with the unit circle (fig. eigen of the paper), on the matplotlib axes
    ``ax`` (None: a new Figure, made without pyplot, so a notebook's current figure and figure list stay as they
    were); returns the figure (shown as a notebook cell's value; ``fig.axes[0]`` the axes, ``fig.savefig`` writes
    it). Local: call it on one rank."""
    from .plotting import draw_multipliers
    if ax is None:
        from matplotlib.figure import Figure
        ax = Figure(figsize=(4.5, 4.5)).subplots()
    lam = spectrum.multipliers if isinstance(spectrum, Spectrum) else np.asarray(spectrum)
    draw_multipliers(ax, lam, title)
    return ax.figure
