"""Dissipation in the contacts (issue 38, item 2): Hunt-Crossley and Kuwabara-Kono bond forces, clipped or not,
in the chain's right-hand side, exact Jacobian, tangent flow, energy balance and driven responses."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import chain_arrays, dense_and_slepc_agree, one_error_line, resolvent_differences, run_script
from hertzpetsc import kernels
from hertzpetsc.chain import Chain, ChainIntegrator, IntegrationTolerances
from hertzpetsc.dissipation import HuntCrossley, KuwabaraKono, contact_dissipation
from hertzpetsc.driven import Drive, HarmonicWave, check_monodromy, conformal_rate
from hertzpetsc.errors import ConvergenceError, ParameterError
from hertzpetsc.hertz import HertzLaw
from hertzpetsc.law import RescaledLaw
from hertzpetsc.model import Actuator, ChainSpec, Damping, Harmonic, LatticeModel
from hertzpetsc.records import read_kind
from hertzpetsc.studies.contacts import (PULSE_KIND, RESTITUTION_KIND, PulseDecay, PulseParameters, Restitution,
                                        RestitutionParameters, line_misfit)
from hertzpetsc.tangent import TangentFlow, liouville_integral

COMM = PETSc.COMM_WORLD
TIGHT = IntegrationTolerances(1e-12, 1e-14)
CONTACTS = [HuntCrossley(0.8), HuntCrossley(0.8, clipped=False), KuwabaraKono(0.3), KuwabaraKono(0.3, clipped=False)]


def model_with(contact, delta0=0.2, masses=(1.0, 0.6), gamma=0.01, eta=0.02):
    return LatticeModel(HertzLaw(1.5, delta0), masses, Damping(gamma, eta, contact))


def test_bond_terms_closed_forms_clipping_and_derivatives():
    """f_d = g(d) dv in contact (HC: 1.5 c d^alpha, KK: eta d^(alpha - 1)), 0 out of contact, min(g dv, d^alpha) when
    clipped; df/dr and df/d(dv) against central differences (h = 1e-6: error O(h^2) ~ 1e-11, round-off 1e-10)."""
    law = HertzLaw(1.5, 0.3)
    rng = np.random.default_rng(0)
    r = rng.uniform(-1.0, 0.6, 200)
    dv = rng.uniform(-2.0, 2.0, 200)
    d = 0.3 - r
    for contact, g in ((HuntCrossley(0.7, False), 1.05 * np.maximum(d, 0) ** 1.5),
                       (KuwabaraKono(0.4, False), 0.4 * np.sqrt(np.maximum(d, 0)))):
        f, dfr, dfv = contact.bond_terms(law, r, dv)
        assert np.allclose(f, g * dv, rtol=1e-14, atol=0)
        clipped = type(contact)(contact.c if hasattr(contact, "c") else contact.eta, True)
        fc, _, _ = clipped.bond_terms(law, r, dv)
        P = np.maximum(d, 0) ** 1.5
        assert np.allclose(fc, np.minimum(g * dv, P), rtol=1e-14, atol=0)
        assert np.any(fc < f) and np.all(fc <= P + 1e-15)           # some contacts would pull, none does
        assert np.all(f[d <= 0] == 0) and np.all(fc[d <= 0] == 0)
    h = 1e-6
    away = np.abs(d) > 1e-3                                          # kinks: contact edge, clipping edge
    for contact in CONTACTS:
        f, dfr, dfv = contact.bond_terms(law, r, dv)
        edge = np.abs(contact.bond_terms(law, r, dv + 1e-3)[2] - dfv) > 0.1 * np.abs(dfv) + 1e-3
        ok = away & ~edge
        num_r = (contact.bond_terms(law, r + h, dv)[0] - contact.bond_terms(law, r - h, dv)[0]) / (2 * h)
        num_v = (contact.bond_terms(law, r, dv + h)[0] - contact.bond_terms(law, r, dv - h)[0]) / (2 * h)
        assert np.allclose(dfr[ok], num_r[ok], rtol=1e-6, atol=1e-6)
        assert np.allclose(dfv[ok], num_v[ok], rtol=1e-6, atol=1e-6)


def test_the_model_records_the_term_only_when_present_and_checks_it():
    assert LatticeModel.hertz(1.5, gamma=0.1).describe() == {"alpha": 1.5, "masses": [1.0], "gamma": 0.1}
    m = model_with(HuntCrossley(0.5))
    assert m.describe()["contact"] == "hunt-crossley" and m.describe()["contact_c"] == 0.5 and m.damped
    assert m.with_damping(0.2, 0.0).damping.contact == HuntCrossley(0.5)           # the lens keeps the term
    assert contact_dissipation("none", 1.0) is None
    assert contact_dissipation("kuwabara-kono", 0.2, False) == KuwabaraKono(0.2, False)
    for bad in (lambda: HuntCrossley(-1.0), lambda: KuwabaraKono(math.nan), lambda: HuntCrossley(1.0, "yes"),
                lambda: Damping(0.0, 0.0, "hunt-crossley"), lambda: contact_dissipation("hertz", 1.0)):
        with pytest.raises(ParameterError):
            bad()
    with pytest.raises(ParameterError, match="travelling"):
        m.require_conservative("travelling waves")


@pytest.mark.parametrize("contact", CONTACTS)
@pytest.mark.parametrize("boundary,ends", [("periodic", {}), ("free", {}),
                                           ("fixed", dict(left=Actuator(Harmonic(0.2, 1.3))))])
def test_exact_jacobian_with_velocity_derivatives(contact, boundary, ends):
    """The exact Jacobian (positions and velocities) against forward differences (h = 1e-7: error h |f''| ~ 1e-7
    of the largest entry, the states chosen away from the kinks), at states where bonds touch, clip and separate."""
    spec = ChainSpec(model_with(contact), 8, boundary, **ends)
    x = np.random.default_rng(3).normal(size=(8, 2)) * 0.3
    f, J, fd, kernel = chain_arrays(spec, x, t=0.7)
    r = np.diff(x[:, 0])
    assert np.any(0.2 - r > 0) and np.any(0.2 - r < 0)   # in and out of contact
    assert np.max(np.abs(J - fd)) < 1e-6 * max(1.0, np.max(np.abs(J)))
    # the velocity derivatives are there: the velocity columns differ from the dashpots' alone
    plain, _, _, _ = chain_arrays(ChainSpec(model_with(None), 8, boundary, **ends), x, t=0.7)
    assert np.max(np.abs(f - plain)) > 1e-3


class _OwnCoefficient(HuntCrossley):
    """A Hunt-Crossley whose g(d) is its own (not the power form the kernel evaluates)."""

    def coefficient(self, d, alpha):
        return 1.5 * self.c * d ** alpha * (1.0 + d)


def test_the_kernel_takes_the_contact_dissipations_it_evaluates_and_no_other():
    """The compiled kernel's guard looks at the damping's terms too: Hunt-Crossley and Kuwabara-Kono (their power
    form) take the contact build of the kernel (the TS calls Chain.rhs, whose signals Python handles), a subclass
    with its own g(d) evaluates in numpy, a chain without contact dissipation takes the plain build; set_spec keeps
    the kind of contact dissipation and moves its coefficient."""
    compiled = kernels.status() == "compiled"
    ch = Chain(ChainSpec(model_with(None), 6, "fixed"), COMM)
    try:
        assert (ch.kernel is not None) == compiled
        assert ch.kernel is None or (ch.kernel.lib is kernels.library() and not ch.kernel.needs_python)
        with pytest.raises(ParameterError, match="contact dissipation"):
            ch.set_spec(ChainSpec(model_with(HuntCrossley(0.5)), 6, "fixed"))
    finally:
        ch.destroy()
    for contact in (HuntCrossley(0.5), KuwabaraKono(0.5, False)):
        ch = Chain(ChainSpec(model_with(contact), 6, "fixed"), COMM)
        try:
            assert (ch.kernel is not None) == compiled
            assert ch.kernel is None or (ch.kernel.lib is kernels.contact_library() and ch.kernel.needs_python)
            ch.set_spec(ChainSpec(model_with(type(contact)(0.9)), 6, "fixed"))
            assert ch.model.damping.contact == type(contact)(0.9)
            if ch.kernel is not None:
                assert ch.kernel.ctx.contact_g == (1.5 * 0.9 if type(contact) is HuntCrossley else 0.9)
        finally:
            ch.destroy()
    ch = Chain(ChainSpec(model_with(_OwnCoefficient(0.5)), 6, "fixed"), COMM)
    try:
        assert ch.kernel is None
    finally:
        ch.destroy()
    no_contact = RescaledLaw(HertzLaw(), 2.0, 1.5)          # a law that names no exponent: contact unknown
    with pytest.raises(ParameterError, match="law"):
        Chain(ChainSpec(LatticeModel(no_contact, damping=Damping(contact=HuntCrossley(0.5))), 6, "fixed"), COMM)


@pytest.mark.parametrize("contact", CONTACTS)
@pytest.mark.parametrize("alpha,delta0,boundary,ends", [
    (1.5, 0.2, "periodic", {}), (2.0, 0.0, "free", {}), (1.7, 0.3, "fixed", dict(left=Actuator(Harmonic(0.2, 1.3))))])
def test_the_compiled_contact_terms_equal_the_numpy_reference(contact, alpha, delta0, boundary, ends):
    """The contact build of the kernel against Chain.rhs_reference, state and 3 tangent columns, at states where
    bonds touch, clip (where clipped) and separate: the same operations in the same order (numpy's d ** e: sqrt for
    e = 1/2, pow otherwise, as the kernel's scalar_power), within 8 eps of the largest value as the Hertz kernel's
    test (libm's pow may differ from numpy's by an ulp)."""
    model = LatticeModel(HertzLaw(alpha, delta0), (1.0, 0.6), Damping(0.01, 0.02, contact))
    ch = Chain(ChainSpec(model, 12, boundary, **ends), COMM, 3)
    if ch.kernel is None:
        ch.destroy()
        pytest.skip(f"the compiled kernel is {kernels.status()}")
    X, F, G = ch.create_state(), ch.create_state(), ch.create_state()
    rng = np.random.default_rng(11)
    try:
        for t in (0.0, 0.7):
            x = rng.normal(size=(12, ch.dof)) * 0.3
            x[:, 1] *= 4.0                                 # fast enough that clipped contacts clip
            ch.set_from_array(X, x)
            ch.rhs(None, t, X, F)
            ch.rhs_reference(None, t, X, G)
            f, g = ch.gather(F), ch.gather(G)
            assert np.max(np.abs(f - g)) <= 8 * np.finfo(float).eps * np.max(np.abs(g))
        r = np.diff(x[:, 0]) if boundary != "periodic" else np.diff(np.append(x[:, 0], x[0, 0]))
        dv = np.diff(x[:, 1]) if boundary != "periodic" else np.diff(np.append(x[:, 1], x[0, 1]))
        d = delta0 - r
        fd = contact.coefficient(np.where(d > 0, d, 1.0), alpha) * dv
        assert np.any(d > 0) and np.any(d < 0)
        if contact.clipped:
            assert np.any((d > 0) & (fd > np.where(d > 0, d, 1.0) ** alpha))
    finally:
        for v in (X, F, G):
            v.destroy()
        ch.destroy()


def test_a_flow_with_contact_dissipation_is_the_same_compiled_or_in_numpy(clean_options):
    """A driven tangent flow with Hunt-Crossley contacts, compiled (the contact build through Chain.rhs) and with
    -chain_rhs_compiled 0 (numpy). The right-hand sides differ by ulps (sqrt against pow), and where a contact clips
    or opens, an ulp can flip a step's acceptance, so the adaptive step sequences may part: the two flows then agree
    to the integration's global error at rtol 1e-12 through the contacts' kinks, bounded here by 1e-9 relative."""
    spec = ChainSpec(model_with(HuntCrossley(0.8)), 10, "fixed", left=Actuator(Harmonic(0.2, 1.3)))
    rng = np.random.default_rng(5)
    x0 = np.stack([0.05 * rng.normal(size=10), 0.2 * rng.normal(size=10)], axis=1)
    Y0 = rng.normal(size=(10, 2, 2))
    out = []
    for compiled in ("1", "0"):
        clean_options.setValue("chain_rhs_compiled", compiled)
        flow = TangentFlow(spec, 2, COMM, TIGHT, "chain_")
        assert (flow.aug.kernel is not None) == (kernels.status() == "compiled")
        out.append(flow.run(x0, 6.0, Y0))
        flow.destroy()
    (x1, R1), (x2, R2) = out
    assert np.max(np.abs(x1 - x2)) <= 1e-9 * np.max(np.abs(x2))
    assert np.max(np.abs(R1 - R2)) <= 1e-9 * np.max(np.abs(R2))


@pytest.mark.parametrize("contact", [HuntCrossley(3.0), HuntCrossley(0.8, clipped=False), KuwabaraKono(0.3)])
def test_energy_balance_with_contact_dissipation(contact):
    """E(T) - E(0) = int (input - dissipation) dt along a driven trajectory with collisions: Simpson on 2000
    intervals, its error estimated by Simpson on 1000 (the integrand has kinks where contacts open, close or clip:
    the quadrature, not the flow's rtol 1e-12, limits the check; 4 times the samples shrink the misfit 5 to 40 fold);
    the balance holds within three times that estimate."""
    model = model_with(contact, delta0=0.0, gamma=0.0, eta=0.0)
    spec = ChainSpec(model, 6, "fixed", left=Actuator(Harmonic(0.5, 2.0)))
    ch = Chain(spec, COMM)
    X = ch.create_state()
    x0 = np.zeros((6, 2))
    x0[:, 1] = np.random.default_rng(1).normal(size=6) * 0.5
    ch.set_from_array(X, x0)
    integ = ChainIntegrator(ch, TIGHT)
    try:
        ts = np.linspace(0.0, 6.0, 2001)
        E, W = [], []
        for i, t in enumerate(ts):
            if i:
                integ.integrate(X, ts[i - 1], t)
            E.append(ch.energy(X, t))
            p_in, diss = ch.power(X, t)
            W.append(p_in - diss)
            assert diss >= 0.0
        E, W = np.array(E), np.array(W)

        def simpson(f, h):
            return h / 3 * (f[0] + f[-1] + 4 * f[1:-1:2].sum() + 2 * f[2:-1:2].sum())
        h = ts[1] - ts[0]
        fine, coarse = simpson(W, h), simpson(W[::2], 2 * h)
        assert abs(E[-1] - E[0]) > 1e-2
        assert abs((E[-1] - E[0]) - fine) <= max(3 * abs(fine - coarse), 1e-9 * np.max(E))
        assert abs(fine - coarse) < 1e-4 * np.max(E)        # d^(1/2) (KK) and the clipping's jump: Simpson ~ h
    finally:
        X.destroy()
        integ.destroy()
        ch.destroy()


def test_tangent_flow_and_liouville_with_contact_dissipation():
    """R(T; 0) of a driven chain with Hunt-Crossley contacts against central differences of the flow (h = 1e-4: the
    contacts that open and close move the adaptive steps, so the differences carry noise ~ 1e-6 at this h, more at
    smaller h, the same without contact dissipation), and log det R against int tr Df dt along the orbit (liouville_integral, to its own
    error estimate); the symplectic form is not conserved (no conformal rate)."""
    spec = ChainSpec(model_with(HuntCrossley(0.8)), 4, "fixed", left=Actuator(Harmonic(0.2, 1.3)))
    x0 = np.random.default_rng(3).normal(size=(4, 2)) * 0.2
    flow = TangentFlow(spec, 8, COMM, TIGHT, "floquet_")
    try:
        R, _ = flow.resolvent(x0, 2.0)
        steps = flow.integrator.ts.getStepNumber()
        fd = resolvent_differences(flow, x0, 2.0, 1e-4)
    finally:
        flow.destroy()
    assert np.max(np.abs(R - fd)) < 1e-5 * np.max(np.abs(R))
    integral, err = liouville_integral(spec, x0, 2.0, COMM, TIGHT)
    assert err < 1e-6
    assert abs(np.linalg.slogdet(R)[1] - integral) < 3 * err + 1e-9
    assert conformal_rate(spec) is None
    where = {"omega": 1.3}
    check_monodromy(R, spec, 2.0, 1e-12, steps, where, (integral, err))
    with pytest.raises(ConvergenceError, match="Liouville"):
        check_monodromy(R, spec, 2.0, 1e-12, steps, where, (integral + 1e-3, err))
    with pytest.raises(ParameterError, match="trace"):
        check_monodromy(R, spec, 2.0, 1e-12, steps, where)


def test_driven_response_with_contact_dissipation_dense_and_slepc_multipliers_agree():
    """A periodic response of a precompressed chain with Hunt-Crossley contacts (and a weak on-site damping): the
    dense bordered Newton and Newton-Krylov find the same response; its dominant multipliers by LAPACK on the dense
    monodromy (Liouville checked by the integral of tr Df along the orbit) and by SLEPc on the matrix-free one agree
    to 1e-8 (the eigen-residuals' tolerance)."""
    model = model_with(HuntCrossley(0.5), delta0=0.5, masses=(1.0,), gamma=0.01, eta=0.0)
    drive = Drive(model, 5, HarmonicWave(), 0.05, 1.2)

    def damped_more(dense, mf, mu_dense):
        # the contacts damp more than the on-site term alone: prod |mu| < exp(-gamma N T)
        assert np.sum(np.log(np.abs(mu_dense))) < -0.01 * 5 * dense.T - 1e-3
    dense_and_slepc_agree(drive, 1.2, damped_more)


def test_restitution_converges_and_follows_the_small_dissipation_laws():
    """e of two-bead impacts at rtol 1e-11 and 1e-9 agree to 1e-8 (converged under refinement); Hunt-Crossley:
    (1 - e) / (c v) = 1 + O(c v) (within 2 c v); Kuwabara-Kono: (1 - e) / (C eta v^(1/5)) = 1 + O(1 - e) and the
    exponent fitted on v = 1e-4..1e-2 within 0.005 of 1/5."""
    hc = Restitution(RestitutionParameters("hunt-crossley", 0.1, velocities=(1e-3, 1e-2, 0.1)), COMM)
    kk = Restitution(RestitutionParameters("kuwabara-kono", 0.05, velocities=(1e-4, 1e-3, 1e-2)), COMM)
    for study in (hc, kk):
        for _ in study.run():
            pass
        for r in study.rows():
            assert abs(float(r["e"]) - float(r["e_coarse"])) < 1e-8
            assert 0.0 < float(r["e"]) < 1.0
    for r in hc.rows():
        cv = 0.1 * float(r["v"])
        assert abs((1 - float(r["e"])) / cv - 1.0) < 2 * cv
    for r in kk.rows():
        loss = 1 - float(r["e"])
        assert abs(loss / float(r["law"]) - 1.0) < loss
    slope, expected, _ = kk.fit()
    assert expected == pytest.approx(0.2) and abs(slope - 0.2) < 5e-3
    assert "fit on the three smallest v" in hc.table()


def test_pulse_decay_law_tells_the_two_dampings_apart():
    """A pulse on 60 beads (fit over beads 8..51): Hunt-Crossley's amplitudes make A^-1 linear in n (10 times closer
    to a line than A^-1/5), Kuwabara-Kono's A^-1/5 (5 times closer than A^-1); the slope per unit damping is the
    same for v0 = 1 and 0.5 to 5 % (the law's coefficient does not depend on the amplitude; the pulse's formation
    over the first beads and O(c v) corrections make the rest)."""
    for kind, damping, law, other in (("hunt-crossley", 0.05, -1.0, -0.2), ("kuwabara-kono", 0.02, -0.2, -1.0)):
        study = PulseDecay(PulseParameters(kind, damping, velocities=(1.0, 0.5), N=60, skip=8), COMM)
        rows = list(study.run())
        n = np.arange(8, 52)
        for r in rows:
            A = np.asarray(r["amplitude"])
            assert np.all(np.diff(A[8:52]) < 0)                          # decays bead after bead
            assert line_misfit(n, A[8:52], other)[1] > 5 * line_misfit(n, A[8:52], law)[1]
            assert float(r["misfit"]) < 2e-3
        assert abs(float(rows[0]["slope"]) / float(rows[1]["slope"]) - 1.0) < 0.05
        assert "decay law A^p linear in n" in study.table()


@pytest.mark.serial
def test_the_drivers_write_their_tables(tmp_path):
    r = run_script("restitution.py", "-contact", "kuwabara-kono", "-damping", 0.05, "-velocities", "1e-3,1e-2",
                   "-output", tmp_path / "r.npz", "-table", tmp_path / "r.md")
    assert r.returncode == 0, r.stderr
    assert "Kuwabara-Kono eta = 0.05" in (tmp_path / "r.md").read_text()
    r = run_script("pulse_decay.py", "-N", 16, "-skip", 3, "-velocities", 1, "-unclipped", "-output",
                   tmp_path / "p.npz", "-table", tmp_path / "p.md")
    assert r.returncode == 0, r.stderr
    with np.load(tmp_path / "p.npz") as z:
        assert z["amplitude"].shape == (1, 16) and str(z["format"]) == "hertzpetsc-pulse-1"
    for path, kind in ((tmp_path / "r.npz", RESTITUTION_KIND), (tmp_path / "p.npz", PULSE_KIND)):
        assert kind.check(read_kind(str(path), kind, "record file")) == ([], [])     # each entry declared, as written


@pytest.mark.parametrize("contact", [HuntCrossley(0.2), KuwabaraKono(0.3)])
def test_small_amplitude_driven_response_is_the_linear_chain_with_the_contacts_dashpot(contact):
    """At a precompressed chain (delta0 = 1) the contact dissipation linearises to a dashpot g(delta0) in every bond
    (Hunt-Crossley (3/2) c delta0^(3/2), Kuwabara-Kono eta delta0^(1/2): 0.3 here, 15 times gamma): the first
    harmonics of the Hertz chain's periodic responses (shooting) at actuator amplitudes a = 2e-4, 4e-4 against the
    damped linear chain's complex amplitudes (studies.driven.linear_response). The quadratic terms of the law and of
    g(d) dv make harmonics 0 and 2 at O(a^2), which return to the first at O(a^3): the relative difference is
    O((a / delta0)^2) (its ratio between the two amplitudes 4, within 10 %; below (a / delta0)^2 itself, while the
    linear chain without the contacts' dashpot is off by O(1)). The multipliers against exp(T lambda) of the linear
    chain (Liouville checked by the integral of tr Df) to O(a^2) too; the energy balance (mean input power = mean
    dissipation, contacts included) to the periodic trapezoid's spectral accuracy on 64 samples; the end forces."""
    from hertzpetsc.driven import PeriodicShooting
    from hertzpetsc.studies.driven import bond_dashpot, linear_multipliers, linear_response
    model = LatticeModel(HertzLaw(1.5, 1.0), (1.0, 0.7), Damping(0.02, 0.0, contact))
    assert bond_dashpot(model) == pytest.approx(0.3, rel=1e-15)
    errors = []
    for a in (2e-4, 4e-4):
        drive = Drive(model, 2, HarmonicWave(), a, 0.9)
        prob = PeriodicShooting(drive, COMM, tolerances=IntegrationTolerances(1e-12, 1e-20))
        try:
            r = prob.solve_response(np.zeros((2, 2)))
            t, x = prob.trajectory(r.x, 64)
            first = 2.0 / 64 * np.sum(x[:-1, :, 0] * np.exp(-1j * drive.omega * t[:-1])[:, None], axis=0)
            X = linear_response(drive)
            errors.append(np.max(np.abs(first - X)) / np.max(np.abs(X)))
            assert errors[-1] < a * a
            # the forces on the wall and the actuator (the contacts' tension included): the largest over the
            # period, |K + i omega g| |X_N| and |K + i omega g| |X_1 - a| to O(a / delta0) (the static offset of the
            # quadratic terms; without the contacts' term 1.6 % off)
            d = prob.diagnostics(r.x, 64)
            dashpot = (model.law.linear_stiffness + 1j * drive.omega * bond_dashpot(model))
            assert abs(d["force_right"] / abs(dashpot * X[-1]) - 1) < a
            assert abs(d["force_left"] / abs(dashpot * (X[0] - a)) - 1) < a
            without = linear_response(Drive(LatticeModel(model.law, model.masses, Damping(0.02)), 2,
                                            HarmonicWave(), a, 0.9))
            assert np.max(np.abs(without - X)) > 0.1 * np.max(np.abs(X))
            if a == 4e-4:
                mu = prob.multipliers(x=r.x, p=drive.omega)
                assert np.max(np.abs(np.sort_complex(mu) - np.sort_complex(linear_multipliers(drive, prob.T)))) \
                    < 10 * a * a
                assert abs(d["power_in"] - d["dissipation"]) < 1e-10 * d["dissipation"]
        finally:
            prob.destroy()
    assert 3.6 < errors[1] / errors[0] < 4.4


@pytest.mark.serial
def test_the_driven_drivers_take_contact_dissipation_from_the_command_line(tmp_path):
    """driven_resonances.py -contact (and the beads' route by a measured restitution): the drive recorded holds the
    contact damping the API builds (units.BeadChain.contact_damping), and the multipliers at the shooting peak match
    the linear chain with the contacts' dashpot (mu error ~ a^2 at the peak, at most 25 a^2 seen, + the flow's
    tolerance; without the dashpot the
    linear multipliers differ by O(T g(delta0))). Bad contact options: one error line naming the option."""
    import json
    from hertzpetsc.units import BeadChain, Bead
    r = run_script("driven_resonances.py", "-N", 2, "-modes", 1, "-golden", 6, "-contact", "hunt_crossley",
                   "-contact_damping", 0.1, "-output", tmp_path / "s.npz", "-table", tmp_path / "s.md",
                   "-figures", "")
    assert r.returncode == 0, r.stderr
    assert "contact = hunt-crossley, contact_c = 0.1" in (tmp_path / "s.md").read_text()
    with np.load(tmp_path / "s.npz") as z:
        assert json.loads(str(z["drive"]))["contact_c"] == 0.1 and float(z["mu_error"][0]) < 1e-8
    r = run_script("driven_resonances.py", "-beads", "steel", "-static_force", "10N", "-N", 2, "-modes", 1,
                   "-golden", 6, "-drive_amplitude", "0.01nm", "-contact", "kuwabara-kono", "-restitution", 0.95,
                   "-impact_velocity", "0.1m/s", "-output", tmp_path / "b.npz", "-table", tmp_path / "b.md",
                   "-figures", "")
    assert r.returncode == 0, r.stderr
    expected = BeadChain((Bead.of("steel", "4.76mm"),), "10N").contact_damping(
        "kuwabara-kono", restitution=0.95, velocity="0.1m/s")
    with np.load(tmp_path / "b.npz") as z:
        model = json.loads(str(z["drive"]))
        a = model["amplitude"]            # 0.01 nm / L, L the static overlap (~ 1 um): a ~ 1e-5
        assert model["contact_eta"] == pytest.approx(expected.eta, rel=1e-14)
        assert float(z["mu_error"][0]) < 100 * a * a + 1e-9
    for args, needle in ((("-contact_damping", 0.1), "invalid -contact_damping"),
                         (("-contact", "hunt-crossley"), "invalid -contact"),
                         (("-contact", "coulomb", "-contact_damping", 1), "invalid -contact = 'coulomb'"),
                         (("-contact", "hunt-crossley", "-contact_damping", 1, "-restitution", 0.95,
                           "-impact_velocity", 1), "invalid -contact"),
                         (("-contact", "hunt-crossley", "-restitution", 0.95, "-impact_velocity", 1),
                          "invalid -restitution"),
                         (("-beads", "steel", "-static_force", "1N", "-contact", "hunt-crossley", "-restitution", 0.5,
                           "-impact_velocity", "1m/s"), "invalid -restitution = 0.5")):
        r = run_script("driven_response.py", *args, "-output", tmp_path / "r.npz", "-table", tmp_path / "r.md",
                       ranks=2 if "coulomb" in args else 1, timeout=120, cwd=tmp_path)
        assert r.returncode == 2 and needle in one_error_line(r), (args, r.stderr)
    assert not (tmp_path / "r.npz").exists()
