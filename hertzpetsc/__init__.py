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

from . import compat

__version__ = "0.3.0"

compat.install()           # the old import paths of moved and renamed names (hertzpetsc.compat)

# module (relative to the package) -> the names it defines that the package exports
_MODULES = {
    # the lattice model (numpy only)
    "law": "InteractionLaw ScaledLaw", "hertz": "HertzLaw", "toda": "TodaLaw", "fpu": "FPULaw",
    "model": "LatticeModel ChainSpec Damping Actuator Harmonic SampledSignal FunctionSignal",
    # beads in SI units (issue 38)
    "materials": "Material material", "units": "Bead BeadChain contact_constant parse_quantity",
    # travelling waves: the advance-delay problem, branches, families
    "grid": "ProfileGrid", "advdelay": "AdvanceDelayProblem", "branch": "Branch BranchPoint",
    "qbranch": "BranchContinuation ContinuationParameters",
    "families": "AmplitudeFamily WavenumberFamily MassFamily AmplitudePoint FamilyFold uncompressed_limit "
                "wave_of_amplitude",
    # the continuation layer
    "continuation": "Continuation ContinuationProblem Natural PseudoArclength ContinuationPoint",
    # the chain, its flows and orbits
    "chain": "Chain ChainIntegrator IntegrationTolerances", "waves": "Orbit orbit_on_chain", "tangent": "TangentFlow",
    # errors
    "errors": "ParameterError ConvergenceError RecordFileError",
    # refinement and Floquet spectra
    "shooting": "Refiner Refinement", "floquet": "Spectrum DenseFloquet DominantFloquet", "bloch": "SymmetricFloquet",
    # studies (records in memory when no output path is given)
    "studies.base": "Study", "studies.branch": "BranchStudy SmallQStudy SmallQParameters",
    "studies.precompression": "AmplitudeFamilies AmplitudeParameters DimerFamilies DimerParameters",
    "studies.maps": "StabilityMap MapParameters QBoundary QBoundaryParameters",
    "studies.wave": "WaveStudy WaveParameters", "studies.refinement": "RefinementScan RefinedStates",
    "studies.floquet": "FloquetScan BlochScan", "studies.slow": "SlowInstabilityScan", "studies.longrun": "LongRun",
    "studies.compacton_stability": "CompactonStabilityScan", "studies.compacton_dynamics": "CompactonDynamics",
    "studies.compacton_pairs": "CompactonPairs",
    # driven, damped chains (issue 22)
    "driven": "Drive HarmonicWave HalfSinePulses SampledWave ProfileWave PeriodicShooting Response switch_to_doubled",
    "studies.driven": "ResponseCurve LinearResonances WaveEnds Generation ResponseParameters ResonanceParameters "
                      "WaveEndsParameters GenerationParameters",
    # conveniences (this package's api module)
    "api": "compute_branch wave_at wave orbit refine multipliers response solitary_speed plot_spectrum",
}
# name -> module that defines it
_EXPORTS = {name: module for module, names in _MODULES.items() for name in names.split()}

__all__ = sorted(_EXPORTS)


def __getattr__(name):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(f".{_EXPORTS[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'hertzpetsc' has no attribute {name!r}")


def __dir__():
    return __all__ + ["__version__"]
