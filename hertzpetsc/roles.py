"""The solver roles, each declared once (:data:`REGISTRY`): prefix, what it solves, PETSc objects, the code's
defaults (the paper's: set on the objects before ``setFromOptions``, or by :func:`~hertzpetsc.options.inserted_options`,
or per solve where :func:`~hertzpetsc.options.user_set` finds none given) and probe. Studies and drivers name theirs
(:func:`uses`), which ``-help`` and the unknown-option check read; :func:`configure` probes them before computing;
:func:`floquet_route` makes a Floquet route; :func:`markdown_table` is README's table.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Optional

from .errors import ParameterError

if TYPE_CHECKING:           # PETSc is imported by the probes: the registry itself reads without it (the README test)
    from petsc4py import PETSc

# the objects of each kind of solver, as the README's table names them
KIND_OBJECTS = {"snes": "SNES, KSP, PC", "ts": "TS", "eps": "EPS", "pep": "PEP, ST, KSP, PC"}
# the Floquet routes by name (prefix floquet_): floquet_route
FLOQUET_ROUTES = ("symmetric", "dense", "slepc")


@dataclass(frozen=True)
class Role:
    """A solver role: ``prefix``, what it solves (``role``), the kinds of solver it is made of (``kinds``: snes, ts,
    eps, pep), its own options beyond PETSc's (``own``), the code's defaults (``defaults``, as documented) and its
    probe (``probe(comm, prefix, spec)``; None: one of :data:`PROBES` per kind)."""
    prefix: str
    role: str
    kinds: tuple
    defaults: str
    own: tuple = ()
    probe: Optional[Callable] = None

    def objects(self, kinds=None) -> str:
        """The PETSc objects of ``kinds`` (default: all the role's) and the role's own options, in Markdown."""
        return ", ".join(KIND_OBJECTS[k] for k in kinds or self.kinds) + \
            "".join(f"; `-{self.prefix}{o.replace('|', chr(92) + '|')}`" for o in self.own)


def _probe_snes(comm, prefix, spec, kind=None):
    """The travelling-wave SNES (``-<prefix>solver direct|nk`` included) on a small grid."""
    from .grid import ProfileGrid
    from .twsolver import TravellingWaveSolver
    TravellingWaveSolver(ProfileGrid(max(8, 2 * comm.getSize() + 2), comm), prefix).destroy()


def _probe_ts(comm, prefix, spec, kind=None):
    """The chain's integrator on a small chain of ``spec``'s lattice (default: the Hertz chain)."""
    from .chain import Chain, ChainIntegrator
    from .model import ChainSpec, LatticeModel
    spec = spec or ChainSpec(LatticeModel(), 3, "free")
    n = max(3, comm.getSize(), spec.model.cell)
    chain = Chain(spec.with_length(n + (-n) % spec.model.cell), comm)
    try:
        ChainIntegrator(chain, None, prefix).destroy()
    finally:
        chain.destroy()


def _probe_slepc(comm, prefix, spec, kind):
    """A bare SLEPc solver (eps, pep) under ``prefix``."""
    from .options import make_solver_object
    obj = make_solver_object(kind, prefix, comm)
    try:
        obj.setFromOptions()
    finally:
        obj.destroy()


# the probe of each kind of solver: probe(comm, prefix, spec, kind)
PROBES = {"snes": _probe_snes, "ts": _probe_ts, "eps": _probe_slepc, "pep": _probe_slepc}


def _probe_solitary(comm, prefix, spec):
    """The SNES of a small solitary-wave problem (eq. adr)."""
    from .solitary import SolitaryParameters, _compacton_start
    from .twsolver import create_snes
    with _compacton_start(SolitaryParameters(1.5, 2, 3.0), comm) as (prob, X, J):
        create_snes(prob, J, prefix).destroy()


def _probe_drive(comm, prefix, spec):
    """Both shooting routes (dense and matrix-free with SLEPc) on a tiny driven chain: SNES and TS ``drive_``,
    TS and EPS ``floquet_``."""
    from .driven import Drive, HarmonicWave, PeriodicShooting
    from .model import LatticeModel
    drive = Drive(LatticeModel.hertz(1.5, delta0=1.0, gamma=0.1), max(2, comm.getSize()), HarmonicWave(), 0.1, 1.0)
    for kw in (dict(jacobian="dense", floquet="dense"), dict(jacobian="mf", floquet="slepc", nev=1)):
        PeriodicShooting(drive, comm, prefix=prefix, **kw).destroy()


_LU = "Newton + LU (MUMPS on several ranks)"
_RK8 = "RK 8(7), rtol 1e-14, atol 1e-16"
REGISTRY = {r.prefix: r for r in (
    Role("tw_", "the travelling waves of eq. ad (continuation, small q, convergence)", ("snes",), _LU,
         ("solver direct|nk", "jacobian aij|shell")),
    Role("sol_", "the solitary wave of eq. adr (k_alpha)", ("snes",), "Newton + LU", probe=_probe_solitary),
    Role("chain_", "simulations: long runs, compactons on the chain; E(q) with the paper's flow", ("ts",),
         "RK 8(7), rtol 1e-12, atol 1e-14"),
    Role("shoot_", "the Gauss-Newton refinement: its flows and `-shoot_gn_max_it`", ("ts",), _RK8 + "; 20 iterations"),
    Role("shoot_jac_", "the flow of the refinement's Jacobian (the residual keeps `-shoot_`)", ("ts",),
         "RK 8(7), rtol 1e-10, atol 1e-12"),
    Role("floquet_", "Floquet spectra: the variational flow (`-floquet_ts_*`), the eigensolver (`-floquet_eps_*`)",
         ("ts", "eps"), "RK 8(7) rtol 1e-14 (scan) or 1e-12 (Bloch table); Krylov-Schur, largest magnitude, ncv = "
         "max(2 nev + 20, 60)", ("radius R", "slow_modes 0|1")),
    Role("drive_", "driven chains: Newton on P(X) - X (bordered) and the state flow", ("snes", "ts"),
         "Newton, LU of the dense R - I (MUMPS on several ranks) or GMRES (restart 200, rtol 1e-8) on tangent-flow "
         "products; max_it 20, atol tol max(\\|X\\|_inf, a); RK 8(7), rtol 1e-12, atol 1e-14", probe=_probe_drive),
    Role("cm_", "the co-moving QEP (slow instabilities)", ("pep",), "TOAR, sinvert, preonly + LU (MUMPS, ICNTL(14) = "
         "100 inserted only for the solve), tol 1e-13, nev 12 (doubled until the window is covered)"),
    Role("cwin_", "the compacton window map's flows (state + tangents)", ("ts",), _RK8),
    Role("ccheck_", "the independent flow of the compacton residual check", ("ts",), "RK 7(6), rtol 1e-13, atol 1e-16"),
    Role("cstab_", "the compacton window's dominant multipliers (`-cstab_eps_*`)", ("eps",), "Krylov-Schur, largest "
         "magnitude, nev <= 3 above 2 exp(-eta), tol 1e-12, weight eta = 2.5"),
    Role("cdyn_", "perturbed compactons and pairs on long free chains", ("ts",),
         "RK 8(7), rtol 1e-13, atol 1e-16, `-cdyn_ts_adapt_wnormtype infinity`"),
    Role("precomp_", "the precompressed waves (amplitude continuation, gap, uncompressed limit)", ("snes",),
         _LU + ", rtol 1e-12, atol 10 x the round-off floor of the residual", ("solver direct|nk",)),
    Role("dimer_", "dimer waves: pseudo-arclength in epsilon", ("snes",), "as `-precomp_`", ("solver direct|nk",)),
    Role("dimer_natural_", "dimer waves: the natural continuation in a to the first points", ("snes",),
         "as `-precomp_`", ("solver direct|nk",)),
)}


def uses(*prefixes: str, **kinds: tuple) -> dict:
    """``{prefix: (its line of -help, kinds)}`` of the registry's roles ``prefixes`` (and of ``kinds``' keys, with
    only those kinds of solver: e.g. ``floquet_=("ts",)`` where no eigensolver is made): a study's ``ROLES``."""
    out = {}
    for r in [REGISTRY[prefix] for prefix in prefixes + tuple(kinds)]:
        used = tuple(kinds.get(r.prefix, r.kinds))
        text = f"{r.role} ({r.objects(used)}); defaults: {r.defaults}"
        out[r.prefix] = (text.replace("`", "").replace(chr(92), ""), used)
    return out


def configure(roles: dict, comm: PETSc.Comm, spec=None) -> None:
    """Probe each role of ``roles`` (``{prefix: (role, kinds)}``): its solvers built on a tiny problem (TS roles on
    a chain of ``spec``'s lattice) read and check the options database, then are freed -- the one early options
    check of the studies. A prefix outside the registry (a study given another prefix) is probed by its kinds."""
    for prefix, (_, kinds) in roles.items():
        role = REGISTRY.get(prefix)
        if role is not None and role.probe is not None:
            role.probe(comm, prefix, spec)
        else:
            for kind in kinds:
                PROBES[kind](comm, prefix, spec, kind)


def floquet_route(method: str, spec, comm: PETSc.Comm, nev: int = 10, tolerances=None, **slepc):
    """The Floquet solver of the route ``method`` (prefix ``floquet_``) for orbits on ``spec``'s chain: 'symmetric'
    (all 2N from the Bloch sectors of the wave's cell), 'dense' (all 2N from the whole chain's monodromy, the
    paper's) or 'slepc' (the ``nev`` dominant, Krylov-Schur; ``slepc`` passed on)."""
    from .bloch import SymmetricFloquet
    from .floquet import FLOQUET_TOLERANCES, DenseFloquet, DominantFloquet
    tolerances = tolerances or FLOQUET_TOLERANCES
    if method == "symmetric":
        return SymmetricFloquet(spec.model, comm, tolerances)
    if method == "dense":
        return DenseFloquet(spec, comm, tolerances)
    if method == "slepc":
        return DominantFloquet(spec, comm, nev, tolerances, **slepc)
    raise ParameterError("method", method, "must be one of " + ", ".join(FLOQUET_ROUTES))


def markdown_table() -> str:
    """The README's table of solver prefixes."""
    rows = [f"| `-{r.prefix}` | {r.role} | {r.objects()} | {r.defaults} |" for r in REGISTRY.values()]
    return "\n".join(["| prefix | role | PETSc objects | code defaults (the paper's) |", "|---|---|---|---|"] + rows)
