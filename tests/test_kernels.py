"""The compiled right-hand side (hertzpetsc.kernels) against the numpy reference Chain.rhs_reference: random states
with damping, mass patterns, precompression, twists, the gap lattice, walls, free ends and actuators, on any number of
ranks; the TS calling it gives the same flows; damped tangent flows against finite differences of the flow."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from hertzpetsc import kernels
from hertzpetsc.bloch import TwistedChain
from hertzpetsc.chain import Chain
from hertzpetsc.compacton_window import WindowChain
from hertzpetsc.errors import ParameterError
from hertzpetsc.model import Actuator, ChainSpec, Harmonic, LatticeModel, SampledSignal
from hertzpetsc.tangent import TangentFlow

COMM = PETSc.COMM_WORLD
EPS = np.finfo(float).eps
H = LatticeModel.hertz
SAMPLED = SampledSignal((0.1, 0.3, -0.2, 0.05, 0.0), 2.5)

def stepped(chain, step):
    chain.step = step
    return chain


# (label, chain factory): every kind of ghost row and every term of eq. nc
CHAINS = [
    ("paper chain", lambda: Chain(ChainSpec(H(1.5), 12), COMM)),
    ("tangents", lambda: Chain(ChainSpec(H(1.5), 12), COMM, 3)),
    ("masses, damping, precompression", lambda: Chain(ChainSpec(H(1.5, (1.0, 0.6), 0.5, 0.05, 0.03), 12), COMM, 3)),
    ("walls, actuator, alpha 5/2", lambda: Chain(ChainSpec(H(2.5, (1.0, 0.6), gamma=0.05, eta=0.03), 12, "fixed",
                                                          left=Actuator(Harmonic(0.2, 1.3))), COMM, 2)),
    ("precompression, alpha 2", lambda: Chain(ChainSpec(H(2.0, delta0=0.4), 12), COMM, 1)),
    ("precompression, alpha 5/2, fixed ends", lambda: Chain(ChainSpec(H(2.5, delta0=0.4, gamma=0.05), 12, "fixed"),
                                                           COMM, 1)),
    ("precompression, alpha 1.7", lambda: Chain(ChainSpec(H(1.7, delta0=0.4), 12), COMM, 1)),
    ("free end, sampled actuator, alpha 1.7", lambda: Chain(ChainSpec(H(1.7, (1.0, 0.6), eta=0.03), 12, "free",
                                                                      right=Actuator(SAMPLED)), COMM, 2)),
    ("gap lattice", lambda: WindowChain(ChainSpec(H(1.5), 12, "free"), COMM, gap=0.37, n_tangent=2)),
    ("gap lattice, precompression", lambda: WindowChain(ChainSpec(H(1.5, delta0=0.2), 12, "free"), COMM, 0.37, 2)),
    ("gap lattice, step", lambda: stepped(WindowChain(ChainSpec(H(1.5), 12, "free"), COMM, gap=0.37, n_tangent=2),
                                          (5, -1.3))),
    ("real twist theta = pi", lambda: TwistedChain(ChainSpec(H(1.5), 12), 4, COMM, complex_modes=False,
                                                   theta=math.pi)),
    ("complex twist, damping", lambda: TwistedChain(ChainSpec(H(1.5, gamma=0.1, eta=0.2), 12), 4, COMM,
                                                    complex_modes=True, theta=0.7)),
]


def test_the_kernel_is_built():
    """hz.sh setup builds the library; without it every flow falls back to numpy (correct but several times slower)."""
    assert kernels.status() == "compiled"


@pytest.mark.parametrize("label,make", CHAINS, ids=[c[0] for c in CHAINS])
def test_kernel_equals_the_numpy_reference(label, make):
    """The same operations in the same order: equal to the bit for whole and half-whole alpha (products, sqrt and
    division are correctly rounded in both), to an ulp or two where libm's pow / expm1 / log1p round differently
    from numpy's (alpha = 1.7, with and without precompression); bound 8 eps of the largest
    value. Several states and times (the actuators move), and the twist changed between evaluations."""
    ch = make()
    assert ch.kernel is not None
    X, F, G = ch.create_state(), ch.create_state(), ch.create_state()
    rng = np.random.default_rng(7)
    try:
        for t, theta in ((0.0, None), (0.7, 2.1), (3.1, None)):
            if theta is not None and isinstance(ch, TwistedChain) and ch.complex_modes:
                ch.theta = theta
            ch.set_from_array(X, rng.normal(size=(ch.spec.N, ch.dof)) * 0.3)
            ch.rhs(None, t, X, F)
            ch.rhs_reference(None, t, X, G)
            f, g = ch.gather(F), ch.gather(G)
            assert np.max(np.abs(f - g)) <= 8 * EPS * np.max(np.abs(g)), label
    finally:
        for v in (X, F, G):
            v.destroy()
        ch.destroy()


def test_a_step_is_the_same_chain_with_the_beads_behind_it_moved():
    """Chain.step = (b, s): beads 0..b stored as x - s give the right-hand side of the chain without a step, to the
    round-off of the positions (|x| <= 3: 1e-15), compiled and in numpy; also Chain.bonds on the gathered state."""
    spec = ChainSpec(H(1.5), 12, "free")
    plain, step = WindowChain(spec, COMM, gap=0.05, n_tangent=2), WindowChain(spec, COMM, gap=0.05, n_tangent=2)
    b, s = 6, 2.7
    step.step = (b, -s)
    rng = np.random.default_rng(3)
    x = rng.normal(size=(12, plain.dof)) * 0.3
    x[:b + 1, 0] += s
    xs = x.copy()
    xs[:b + 1, 0] -= s
    vecs = [plain.create_state() for _ in range(3)] + [step.create_state() for _ in range(3)]
    X, F, G, Xs, Fs, Gs = vecs
    try:
        plain.set_from_array(X, x)
        step.set_from_array(Xs, xs)
        plain.rhs(None, 0.0, X, F)
        plain.rhs_reference(None, 0.0, X, G)
        step.rhs(None, 0.0, Xs, Fs)
        step.rhs_reference(None, 0.0, Xs, Gs)
        f = plain.gather(F)
        for other in (G, Fs, Gs):
            assert np.max(np.abs(plain.gather(other) - f)) <= 1e-14 * np.max(np.abs(f))
        assert np.max(np.abs(step.bonds(xs) - plain.bonds(x))) <= 1e-15
        with pytest.raises(ParameterError):
            step.step = (11, 1.0)
    finally:
        for v in vecs:
            v.destroy()
        plain.destroy()
        step.destroy()


@pytest.mark.parametrize("spec", [ChainSpec(H(1.5), 16),
                                  ChainSpec(H(1.5, gamma=0.05, eta=0.02), 16, "fixed",
                                            left=Actuator(Harmonic(0.2, 1.3, phase=0.4, offset=0.01)))],
                         ids=["periodic", "harmonic actuator"])
def test_the_ts_calls_the_kernel_and_the_flow_is_unchanged(clean_options, spec):
    """A tangent flow with the compiled right-hand side and with -chain_rhs_compiled 0 (numpy): the same
    operations give the same adaptive steps and the same numbers, to the bit (the harmonic actuator's motion too,
    computed by the kernel at each stage's time: no Python between the TS and the kernel)."""
    rng = np.random.default_rng(3)
    x0 = np.stack([np.sin(2 * math.pi * 2 * np.arange(16) / 16) - 0.1, 0.2 * rng.normal(size=16)], axis=1)
    Y0 = rng.normal(size=(16, 2, 3))
    out = []
    for compiled in ("1", "0"):
        clean_options.setValue("chain_rhs_compiled", compiled)
        flow = TangentFlow(spec, 3, COMM, None, "chain_")
        if compiled == "1":
            assert flow.aug.kernel.python_signals == []       # the kernel moves the harmonic actuator itself
        out.append(flow.run(x0, 2.0, Y0) + (flow.integrator.steps,))
        flow.destroy()
    (x1, R1, n1), (x2, R2, n2) = out
    assert n1 == n2 and np.array_equal(x1, x2) and np.array_equal(R1, R2)


@pytest.mark.parametrize("ends", [dict(boundary="periodic"),
                                  dict(boundary="fixed", left=Actuator(Harmonic(0.05, 1.3)))])
def test_damped_tangent_flow_matches_finite_differences_of_the_flow(clean_options, ends):
    """The variational equations carry the damping (-gamma y' + eta (y'_{n+1} - 2 y'_n + y'_{n-1})) and the masses.
    Central differences with eps = 1e-4 through fixed RK4 steps (dt = 1e-3, the same steps in every run, so the
    discrete flow is differentiated): a precompressed chain (delta0 = 0.5) with amplitudes 0.1 stays in contact, V''
    is smooth there and the error is O(eps^2) (measured 2.7e-8 relative; bound 1e-7). Without the damping of the
    tangents (the right-hand side before 2026-11: the tangents' damping terms were overwritten) the error is 9%."""
    model = H(2.5, (1.0, 0.7), 0.5, gamma=0.05, eta=0.03)
    spec = ChainSpec(model, 10, **ends)
    for k, v in (("chain_ts_adapt_type", "none"), ("chain_ts_rk_type", "4")):
        clean_options.setValue(k, v)
    flow = TangentFlow(spec, 1, COMM, None, "chain_")
    rng = np.random.default_rng(5)
    x0 = 0.1 * rng.normal(size=(10, 2))
    v = rng.normal(size=(10, 2))
    try:
        _, Rv = flow.run(x0, 1.0, v[:, :, None])
        zero = np.zeros((10, 2, 1))
        eps = 1e-4
        xp, _ = flow.run(x0 + eps * v, 1.0, zero)
        xm, _ = flow.run(x0 - eps * v, 1.0, zero)
    finally:
        flow.destroy()
    fd = (xp - xm) / (2 * eps)
    assert np.max(np.abs(fd - Rv[:, :, 0])) <= 1e-7 * np.max(np.abs(Rv))


def test_block_product_equals_the_dense_monodromy():
    """MonodromyModShift.apply: k vectors through one integration of the orbit, against the dense S R(T; 0) (other
    adaptive steps: agreement to the flow's tolerance budget, as the single product in test_chain)."""
    from hertzpetsc.tangent import MonodromyModShift
    spec = ChainSpec(H(1.5), 10)
    rng = np.random.default_rng(4)
    x0 = np.stack([np.sin(2 * math.pi * 2 * np.arange(10) / 10) - 0.1, 0.2 * rng.normal(size=10)], axis=1)
    dense = TangentFlow(spec, 20, COMM, None, "chain_")
    F, _ = dense.monodromy_mod_shift(x0, 1.5)
    dense.destroy()
    op = MonodromyModShift(spec, x0, 1.5, COMM, None, "chain_")
    Y = rng.normal(size=(10, 2, 3))
    try:
        FY = op.apply(Y)
    finally:
        op.destroy()
    expected = (F @ Y.reshape(20, 3)).reshape(10, 2, 3)
    assert np.max(np.abs(FY - expected)) <= 1e-9 * np.max(np.abs(expected))
    assert op.products == 3 and op.integrations == 1


def test_set_spec_keeps_the_kernel_in_step():
    """Chain.set_spec (a driven chain at another frequency, amplitude, damping, law or masses) rewrites the compiled
    context in place (a TS that calls it directly keeps the same context): the moved chain's right-hand side equals
    that of a chain built for the new spec to the bit (same operations on the same numbers), and its numpy reference
    to 8 eps (libm's pow against numpy's at alpha = 5/2). Another kind of end is refused."""
    a = ChainSpec(H(1.5, (1.0, 0.6), 0.5, gamma=0.05, eta=0.03), 12, "fixed", left=Actuator(Harmonic(0.2, 1.3)))
    b = ChainSpec(H(2.5, (1.0, 0.8), 0.2, gamma=0.2), 12, "fixed", left=Actuator(Harmonic(0.1, 0.7)))
    moved, fresh = Chain(a, COMM, 2), Chain(b, COMM, 2)
    ctx = moved.kernel.ctx
    moved.set_spec(b)
    assert moved.kernel.ctx is ctx
    X, F, G, R = moved.create_state(), moved.create_state(), moved.create_state(), moved.create_state()
    rng = np.random.default_rng(3)
    try:
        for t in (0.0, 0.9, 2.3):
            moved.set_from_array(X, rng.normal(size=(12, moved.dof)) * 0.3)
            moved.rhs(None, t, X, F)
            fresh.rhs(None, t, X, G)
            moved.rhs_reference(None, t, X, R)
            f, g, r = moved.gather(F), fresh.gather(G), moved.gather(R)
            assert np.array_equal(f, g)
            assert np.max(np.abs(f - r)) <= 8 * EPS * np.max(np.abs(r))
        with pytest.raises(ParameterError, match="kinds of the ends"):
            moved.set_spec(ChainSpec(H(1.5), 12, "fixed"))
    finally:
        for v in (X, F, G, R):
            v.destroy()
        moved.destroy()
        fresh.destroy()


def test_a_stale_kernel_is_said_once_and_the_numpy_route_taken(monkeypatch, capsys):
    """A library built from another C source is not loaded (its context layout may differ): the chain falls back
    to the numpy right-hand side and rank 0 says so in one note line, once."""
    monkeypatch.setattr(kernels, "_lib", None)
    monkeypatch.setattr(kernels, "_status", None)
    monkeypatch.setattr(kernels, "source_digest", lambda: "another source")
    chain = Chain(ChainSpec(H(1.5), 6), COMM)
    try:
        assert chain.kernel is None and kernels.library() is None
    finally:
        chain.destroy()
    notes = [line for line in capsys.readouterr().err.splitlines() if line.startswith("note:")]
    if COMM.getRank() == 0:
        assert len(notes) == 1 and "built from another source" in notes[0], notes
    else:
        assert not notes, notes



def test_a_kernel_built_against_another_petsc_is_not_used(monkeypatch):
    """The library's digest covers the libpetsc it was linked against: seen from a process whose PETSc is another
    (an environment's own PETSc, the clone's library built against Debian's), it is not called and the chain takes
    the numpy right-hand side."""
    built = kernels.built_digest()
    assert built == kernels.source_digest()                    # this process's PETSc: the library is used
    monkeypatch.setattr(kernels, "_lib", None)
    monkeypatch.setattr(kernels, "_status", None)
    monkeypatch.setattr(kernels, "petsc_library", lambda: "/another/prefix/lib/libpetsc.so.3.22")
    assert kernels.source_digest() != built
    chain = Chain(ChainSpec(H(1.5), 6), COMM)
    try:
        assert chain.kernel is None and kernels.library() is None and "another PETSc" in kernels.status()
    finally:
        chain.destroy()
