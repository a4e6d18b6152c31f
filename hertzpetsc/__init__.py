"""hertzpetsc: travelling waves of Hertzian granular chains on PETSc/SLEPc.

Reference: G. James, *Periodic travelling waves and compactons in granular chains*, J. Nonlinear Sci. (2012).
Equation labels in docstrings are the paper's (eq. ad, eq. vhertz, ...).

The public surface, for notebooks and scripts (``import hertzpetsc as hz``; the names are imported on first use, so
``import hertzpetsc`` itself does not start PETSc)::

    model = hz.LatticeModel.hertz(alpha=1.5)                       # the lattice: law, masses, damping
    branch = hz.compute_branch(model, M=10, cells_per_pi=400)      # eq. ad continued in q (section 3.1)
    orbit = hz.orbit(branch.point(3 * math.pi / 10), N=100)        # the wave on a chain (eq. twper)
    refined = hz.refine(orbit)                                     # Gauss-Newton, E(q) (section 3.4)
    spectrum = hz.multipliers(refined.orbit)                       # Floquet multipliers modulo shift (3.5)
    trimer = hz.wave(hz.LatticeModel.hertz(1.5, (1, 0.5, 0.5), delta0=1), q=2 * math.pi / 15, A=0.5, N=60)

Calls that take a communicator (``comm``, default PETSc.COMM_WORLD) are collective over it: every rank calls them
with the same arguments and gets the same result. docs/api.md lists the names and what each returns.
"""
import importlib

__version__ = "0.2.0"

# name -> module (relative to the package) that defines it
_EXPORTS = {
    # the lattice model (numpy only)
    "InteractionLaw": "law", "HertzLaw": "hertz", "LatticeModel": "model", "ChainSpec": "model",
    "Damping": "model", "Actuator": "model", "Harmonic": "model", "SampledSignal": "model",
    "FunctionSignal": "model",
    # travelling waves: the advance-delay problem, branches, families
    "ProfileGrid": "grid", "AdvanceDelayProblem": "advdelay", "Branch": "branch", "BranchPoint": "branch",
    "BranchContinuation": "qbranch", "ContinuationParameters": "qbranch", "AmplitudeFamily": "families",
    "MassFamily": "families", "AmplitudePoint": "families", "uncompressed_limit": "families",
    # the continuation layer
    "Continuation": "continuation", "ContinuationProblem": "continuation", "Natural": "continuation",
    "PseudoArclength": "continuation", "ContinuationPoint": "continuation",
    # the chain, its flows and orbits
    "Chain": "chain", "ChainIntegrator": "chain", "IntegrationTolerances": "chain", "Orbit": "waves",
    "orbit_on_chain": "waves", "TangentFlow": "tangent",
    # studies (records in memory when no output path is given)
    "Study": "studies.base", "BranchStudy": "studies.branch", "SmallQStudy": "studies.branch",
    "SmallQParameters": "studies.branch", "AmplitudeFamilies": "studies.precompression",
    "AmplitudeParameters": "studies.precompression", "DimerFamilies": "studies.precompression",
    "DimerParameters": "studies.precompression", "StabilityMap": "studies.maps",
    "MapParameters": "studies.maps", "QBoundary": "studies.maps", "QBoundaryParameters": "studies.maps",
    # errors
    "ParameterError": "errors", "ConvergenceError": "errors", "RecordFileError": "errors",
    # refinement and Floquet spectra
    "Refiner": "shooting", "Refinement": "shooting", "Spectrum": "floquet", "DenseFloquet": "floquet",
    "DominantFloquet": "floquet", "SymmetricFloquet": "bloch", "wave_of_amplitude": "families",
    "WaveStudy": "studies.wave", "WaveParameters": "studies.wave",
    "RefinementScan": "studies.refinement", "RefinedStates": "studies.refinement", "FloquetScan": "studies.floquet",
    "BlochScan": "studies.floquet", "SlowInstabilityScan": "studies.slow", "LongRun": "studies.longrun",
    "CompactonStabilityScan": "studies.compacton_stability", "CompactonDynamics": "studies.compacton_dynamics",
    "CompactonPairs": "studies.compacton_pairs",
    # driven, damped chains (issue 22)
    "Drive": "driven", "HarmonicWave": "driven", "HalfSinePulses": "driven", "SampledWave": "driven",
    "ProfileWave": "driven", "PeriodicShooting": "driven", "Response": "driven", "switch_to_doubled": "driven",
    "ResponseCurve": "studies.driven", "LinearResonances": "studies.driven", "WaveEnds": "studies.driven",
    "Generation": "studies.driven", "ResponseParameters": "studies.driven", "ResonanceParameters": "studies.driven",
    "WaveEndsParameters": "studies.driven", "GenerationParameters": "studies.driven",
    # conveniences (this package's api module)
    "compute_branch": "api", "wave_at": "api", "wave": "api", "orbit": "api", "refine": "api",
    "multipliers": "api", "plot_spectrum": "api",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'hertzpetsc' has no attribute {name!r}")


def __dir__():
    return __all__ + ["__version__"]
