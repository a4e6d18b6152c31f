"""The compiled right-hand side of the chain (eq. nc) and of its variational equations (``_chain_kernel.c``).

PETSc's TS spends its time in the right-hand side: thousands of evaluations per orbit, each on a small state (the
wave's cell) or on a block of up to 4N tangent columns. In Python every evaluation pays a few microseconds of
interpreter and numpy overhead per operation; the compiled kernel does the whole evaluation -- ghost exchange through
the chain's DMDA, ends, Bloch twist, gap offset, the law, the tridiagonal stiffness on the whole tangent block,
damping and masses -- in one C function that the TS calls directly (:func:`install`), or that
:meth:`hertzpetsc.chain.Chain.rhs` calls when the chain's ends need Python (actuators).

The library is built once per machine against Debian's libpetsc by ``python -m hertzpetsc.kernels`` (run by
``scripts/hz.sh setup``; it needs gcc, which hz.sh installs; it is rebuilt when its source changes). Without it the
chain uses :meth:`~hertzpetsc.chain.Chain.rhs_reference` (numpy, the same arithmetic): :func:`status` says which,
and ``tests/test_kernels.py`` fails when the library is missing.
"""
import ctypes
import hashlib
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

from .console import note, print0
from .errors import check_signals
from .hertz import power_recipe

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.join(HERE, "_chain_kernel.c")
LIBRARY = os.path.join(HERE, "_chain_kernel.so")
# the same source built with HZ_CONTACT: the right-hand side with a contact dissipation, a library of its own so
# that the chains without one run the very code (and code layout) they ran before it existed
CONTACT_LIBRARY = os.path.join(HERE, "_chain_kernel_contact.so")
# IEEE arithmetic as numpy does it: no fast-math, no fused multiply-adds (the kernel matches the reference to the bit)
CFLAGS = ["-O3", "-fPIC", "-shared", "-std=c99", "-ffp-contract=off", "-fno-fast-math"]

END_INSIDE, END_FREE, END_WALL, END_ACTUATOR = 0, 1, 2, 3
# PETSc's error code "Signal received": what the compiled right-hand side returns once a watched signal arrived
SIGNAL_ERROR = 59


class KernelContext(ctypes.Structure):
    """The C struct ``ChainKernel`` of ``_chain_kernel.c``, field by field."""

    _fields_ = [("serial", ctypes.c_int), ("ghost_scatter", ctypes.c_void_p), ("ghost_vec", ctypes.c_void_p),
                ("ghost", ctypes.c_void_p),
                ("nloc", ctypes.c_int), ("dof", ctypes.c_int), ("ntan", ctypes.c_int),
                ("left", ctypes.c_int), ("right", ctypes.c_int),
                ("left_x", ctypes.c_double), ("left_v", ctypes.c_double),
                ("right_x", ctypes.c_double), ("right_v", ctypes.c_double),
                ("alpha", ctypes.c_double), ("delta0", ctypes.c_double), ("delta0_alpha", ctypes.c_double),
                ("delta0_base", ctypes.c_double),
                ("force_k", ctypes.c_int), ("force_half", ctypes.c_int),
                ("stiff_k", ctypes.c_int), ("stiff_half", ctypes.c_int),
                ("gamma", ctypes.c_double), ("eta", ctypes.c_double),
                ("inv_mass", ctypes.c_void_p),
                ("twist_left", ctypes.c_int), ("twist_right", ctypes.c_int),
                ("complex_modes", ctypes.c_int),
                ("cos_theta", ctypes.c_double), ("sin_theta", ctypes.c_double),
                ("gap", ctypes.c_double), ("step_bond", ctypes.c_int), ("step", ctypes.c_double),
                ("bond", ctypes.c_void_p), ("stiff", ctypes.c_void_p), ("dv", ctypes.c_void_p),
                ("harmonic_left", ctypes.c_int), ("harmonic_right", ctypes.c_int),
                ("harmonic", (ctypes.c_double * 4) * 2),
                ("contact_clipped", ctypes.c_int),
                ("contact_g", ctypes.c_double), ("contact_g_exp", ctypes.c_double),
                ("contact_dg", ctypes.c_double), ("contact_dg_exp", ctypes.c_double),
                ("contact_dfv", ctypes.c_void_p)]


def petsc_library():
    """The path of the libpetsc this process has loaded (through petsc4py)."""
    from petsc4py import PETSc  # noqa: F401  (loads libpetsc)
    try:
        with open("/proc/self/maps") as maps:
            for line in maps:
                path = line.split()[-1]
                if "/libpetsc" in path and ".so" in path:
                    return path
    except OSError as err:
        raise RuntimeError(f"cannot read the libraries of this process: {err}") from None
    raise RuntimeError("libpetsc is not loaded in this process")


def source_digest():
    """SHA-256 of the kernel's source and of the path of the libpetsc this process uses (compiled into the library:
    a library built from another source, or against another PETSc, is not used)."""
    with open(SOURCE, "rb") as f:
        digest = hashlib.sha256(f.read())
    digest.update(petsc_library().encode())
    return digest.hexdigest()[:16]


def built_digest(path=LIBRARY):
    """The source digest the library ``path`` was built from, or None if there is no library."""
    if not os.path.exists(path):
        return None
    petsc_library()                               # libpetsc first: the kernel resolves its symbols there
    try:
        lib = ctypes.CDLL(path)
        lib.hz_kernel_source.restype = ctypes.c_char_p
        return lib.hz_kernel_source().decode()
    except (OSError, AttributeError):               # not a library of this module (or from before the digest)
        return "unknown"


def build(compiler=None, force=False):
    """Compile ``_chain_kernel.c`` into ``_chain_kernel.so`` and, with HZ_CONTACT, ``_chain_kernel_contact.so``
    (atomically) unless a library was built from this source; returns the first library's path. ``compiler``:
    default $CC, else gcc."""
    compiler = compiler or os.environ.get("CC", "gcc")
    digest = source_digest()
    for path, defines in ((LIBRARY, []), (CONTACT_LIBRARY, ["-DHZ_CONTACT"])):
        if not force and os.path.exists(path) and built_digest(path) == digest:
            continue
        fd, tmp = tempfile.mkstemp(suffix=".so", dir=HERE)
        os.close(fd)
        try:
            subprocess.run([compiler, *CFLAGS, *defines, f'-DHZ_KERNEL_SOURCE="{digest}"', "-o", tmp, SOURCE,
                            petsc_library(), "-lm"], check=True)
            os.chmod(tmp, 0o755)
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    return LIBRARY


_lib = None
_status = None
_contact_lib = None


def _load(path):
    lib = ctypes.CDLL(path)
    ptr, vp = ctypes.POINTER(KernelContext), ctypes.c_void_p
    lib.hz_chain_rhs.argtypes = [vp, ctypes.c_double, vp, vp, ptr]
    lib.hz_chain_rhs.restype = ctypes.c_int
    lib.hz_install_rhs.argtypes = [vp, vp, ptr]
    lib.hz_install_rhs.restype = ctypes.c_int
    lib.hz_watch_signals.restype = lib.hz_release_signals.restype = ctypes.c_int
    return lib


def contact_library():
    """The library of the chains with a contact dissipation (built beside :func:`library`, from the same source),
    or None (their chains then evaluate in numpy; said once when the library is stale or missing)."""
    global _contact_lib
    if _contact_lib is None and library() is not None:
        if built_digest(CONTACT_LIBRARY) == source_digest():
            _contact_lib = _load(CONTACT_LIBRARY)
        else:
            _contact_lib = False
            note(f"the compiled chain kernel {CONTACT_LIBRARY} is not built from this source (run: python -m "
                 "hertzpetsc.kernels); chains with contact dissipation use the numpy right-hand side")
    return _contact_lib or None


def library():
    """The loaded kernel library, or None when it is not built (or built from another source)."""
    global _lib, _status
    if _status is None:
        from petsc4py import PETSc
        why = None
        try:
            built = built_digest()
        except RuntimeError as err:                   # libpetsc not located (no /proc/self/maps: not Linux)
            built, why = None, f"not usable here ({err})"
        if why is not None:
            _status = why
        elif np.dtype(PETSc.ScalarType) != np.float64 or np.dtype(PETSc.RealType) != np.float64:
            _status = "PETSc is not a real double-precision build (the kernel's PetscScalar is double)"
        elif built is None:
            _status = "not built (run: python -m hertzpetsc.kernels, or bash scripts/hz.sh setup)"
        elif built != source_digest():
            _status = "built from another source or against another PETSc (run: python -m hertzpetsc.kernels)"
            # same numbers, much slower: say so once
            note(f"the compiled chain kernel {LIBRARY} is {_status}; using the numpy right-hand side")
        else:
            _lib, _status = _load(LIBRARY), "compiled"
    return _lib


def status():
    """'compiled', or why the chain falls back to its numpy right-hand side."""
    library()
    return _status


def watch_signals():
    """Before a solve on the compiled right-hand side (no Python runs its signal handlers until the solve returns):
    from now on SIGINT, SIGTERM or SIGHUP (where the process handles them) make the right-hand side fail with
    :data:`SIGNAL_ERROR` at its next evaluation, so that the solve ends within a step. No-op without the library."""
    if _lib is not None:
        _lib.hz_watch_signals()


def release_signals():
    """After the solve (also when it failed): a watched signal that arrived meanwhile goes to the process's handler
    now, and Python's handler runs at once (guarded_main's raises :class:`~hertzpetsc.errors.Terminated`, Python's
    default one KeyboardInterrupt)."""
    global last_signal
    if _lib is not None:
        signum = _lib.hz_release_signals()
        if signum:
            last_signal = signum
            check_signals()                            # raises what the handler raises


last_signal = 0          # the last signal that ended a solve (release_signals), for an error that hides it


class ChainKernel:
    """The compiled right-hand side of one :class:`~hertzpetsc.chain.Chain` (its context and work arrays), kept in
    step with the chain's parameters by the chain (:meth:`sync`)."""

    def __init__(self, chain, lib):
        self.lib = lib
        n = chain.nloc
        self.work = np.zeros((4, n + 1))
        self.ghost = np.zeros(2 * chain.dof)
        ctx = KernelContext()
        ctx.nloc, ctx.dof, ctx.ntan = n, chain.dof, chain.n_tangent
        ctx.serial = int(chain.comm.getSize() == 1)
        ctx.ghost = self.ghost.ctypes.data
        self.scatter = self.ghost_vec = None
        if not ctx.serial:
            self.scatter, self.ghost_vec = ghost_scatter(chain)
            ctx.ghost_scatter, ctx.ghost_vec = self.scatter.handle, self.ghost_vec.handle
        ctx.bond, ctx.stiff, ctx.dv, ctx.contact_dfv = (self.work[i].ctypes.data for i in range(4))
        self.ctx = ctx
        self.ref = ctypes.byref(ctx)
        self.set_physics(chain)

    def set_physics(self, chain):
        """Copy the chain's law, damping, masses and kinds of ends into the context (at construction and after
        :meth:`~hertzpetsc.chain.Chain.set_spec`; the context stays the same object)."""
        ctx, law = self.ctx, chain.model.law
        ctx.left, ctx.right = end_kind(chain.left_end), end_kind(chain.right_end)
        ctx.alpha, ctx.delta0 = law.alpha, law.delta0
        ctx.delta0_alpha = law.delta0 ** law.alpha
        ctx.force_k, ctx.force_half = power_recipe(law.alpha)
        ctx.delta0_base = math.sqrt(law.delta0) if ctx.force_half else law.delta0
        ctx.stiff_k, ctx.stiff_half = power_recipe(law.alpha - 1.0)
        damping = chain.model.damping
        ctx.gamma, ctx.eta = damping.gamma, damping.eta
        if damping.contact is not None:          # this chain's library is contact_library() (Chain.__init__)
            ctx.contact_clipped = int(damping.contact.clipped)
            (ctx.contact_g, ctx.contact_g_exp), (ctx.contact_dg, ctx.contact_dg_exp) = \
                damping.contact.kernel_form(law)
        self.inverse_mass = None if chain.inverse_mass is None else np.ascontiguousarray(chain.inverse_mass, float)
        ctx.inv_mass = None if self.inverse_mass is None else self.inverse_mass.ctypes.data
        # harmonic actuators move in C; any other signal is evaluated in Python at each right-hand side (set_time)
        from .model import Harmonic
        self.python_signals = []
        for i, (end, side) in enumerate(((chain.left_end, "left"), (chain.right_end, "right"))):
            harmonic = end_kind(end) == END_ACTUATOR and type(end.signal) is Harmonic
            setattr(ctx, "harmonic_" + side, int(harmonic))
            if harmonic:
                s = end.signal
                ctx.harmonic[i][:] = (s.offset, s.amplitude, s.omega, s.phase)
            elif end_kind(end) == END_ACTUATOR:
                self.python_signals.append((side, end.signal))

    def sync(self, chain):
        """Copy the chain's twist, gap and step (attributes that may change between integrations) into the context."""
        ctx = self.ctx
        seam = chain.spec.boundary == "periodic" and chain.theta != 0.0
        ctx.twist_left = int(seam and chain.xs == 0)
        ctx.twist_right = int(seam and chain.xe == chain.spec.N)
        ctx.complex_modes = int(bool(chain.complex_modes))
        ctx.cos_theta, ctx.sin_theta = math.cos(chain.theta), math.sin(chain.theta)
        ctx.gap = chain.gap
        ctx.step_bond, ctx.step = chain._step_row(), chain.step[1]

    def set_time(self, t):
        """The position and velocity at time t of the actuators whose signal is not harmonic (the only time
        dependence of eq. nc that the kernel does not compute itself)."""
        ctx = self.ctx
        for side, signal in self.python_signals:
            setattr(ctx, side + "_x", float(signal.position(t)))
            setattr(ctx, side + "_v", float(signal.velocity(t)))

    def __call__(self, X, F, t=0.0):
        """F = f(t, X) through PETSc objects (the chain's DMDA does the ghost exchange)."""
        err = self.lib.hz_chain_rhs(None, t, X.handle, F.handle, self.ref)
        if err:
            raise RuntimeError(f"the compiled chain right-hand side failed with PETSc error {err}")

    @property
    def needs_python(self) -> bool:
        """The TS calls :meth:`hertzpetsc.chain.Chain.rhs`, not this function itself: an actuator's signal is
        evaluated in Python, or the library is the contact one, which leaves signals to Python's handlers (they run
        between the evaluations; only :func:`library`'s are armed by :func:`watch_signals`)."""
        return bool(self.python_signals) or self.lib is not _lib

    def install(self, ts, F):
        """Make the compiled function the right-hand side of the TS ``ts`` (residual vector F)."""
        err = self.lib.hz_install_rhs(ts.handle, F.handle, self.ref)
        if err:
            raise RuntimeError(f"TSSetRHSFunction failed with PETSc error {err}")

    def destroy(self):
        if self.scatter is not None:
            self.scatter.destroy()
            self.ghost_vec.destroy()
            self.scatter = self.ghost_vec = None


def ghost_scatter(chain):
    """(scatter, vector): the rows next to this rank's first and last beads (left, right; none beyond an end of a
    non-periodic chain) from the chain's state into a sequential vector of 2 x dof values."""
    from petsc4py import PETSc
    N, d = chain.spec.N, chain.dof
    periodic = chain.spec.boundary == "periodic"
    src, dst = [], []
    for slot, bead, exists in ((0, chain.xs - 1, periodic or chain.xs > 0), (1, chain.xe, periodic or chain.xe < N)):
        if exists:
            src += list((bead % N) * d + np.arange(d))
            dst += list(slot * d + np.arange(d))
    vec = PETSc.Vec().createSeq(2 * d, comm=PETSc.COMM_SELF)
    vec.set(0.0)
    template = chain.da.createGlobalVec()
    isf = PETSc.IS().createGeneral(np.asarray(src, dtype=PETSc.IntType), comm=PETSc.COMM_SELF)
    ist = PETSc.IS().createGeneral(np.asarray(dst, dtype=PETSc.IntType), comm=PETSc.COMM_SELF)
    scatter = PETSc.Scatter().create(template, isf, vec, ist)
    for obj in (isf, ist, template):
        obj.destroy()
    return scatter, vec


def end_kind(end):
    """END_* of a chain end as the chain stores it (None inside the chain or periodic)."""
    from .model import Actuator
    if end is None:
        return END_INSIDE
    if isinstance(end, Actuator):
        return END_ACTUATOR
    return {"free": END_FREE, "wall": END_WALL}[end]


def main(argv):
    """python -m hertzpetsc.kernels [--force]: build the library if it is missing or older than its source; without
    a compiler (or where the library cannot be built) one line says so and the status is 1: the chains then use
    the numpy right-hand side."""
    import petsc4py
    petsc4py.init([argv[0]])
    try:
        path = build(force="--force" in argv[1:])
    except (OSError, RuntimeError, subprocess.CalledProcessError) as err:
        print0(f"hertzpetsc kernel: not built ({err}); the chains use the numpy right-hand side (same arithmetic, "
               "slower)", file=sys.stderr)
        sys.exit(1)
    print0(f"hertzpetsc kernel: {path}")


if __name__ == "__main__":
    main(sys.argv)
