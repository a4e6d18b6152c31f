"""Continuation in q (section 3.1): predictor, step reduction, convergence in h, rank independence."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from hertzpetsc.qbranch import BranchContinuation, ContinuationError, ContinuationParameters
from hertzpetsc.errors import ParameterError


def branch(comm=PETSc.COMM_WORLD, **kw):
    cont = BranchContinuation(ContinuationParameters(**kw), comm)
    try:
        return list(cont.points())
    finally:
        cont.destroy()


@pytest.mark.parametrize("kw,name", [
    (dict(alpha=1.0), "alpha"), (dict(M=0), "M"), (dict(M=2.5), "M"), (dict(cells_per_pi=2), "cells_per_pi"),
    (dict(q_stop=0.0), "q_stop"), (dict(q_stop=4.0), "q_stop"), (dict(q_stop=1e-4), "q_stop"),
    (dict(max_halvings=-1), "max_halvings"), (dict(max_corrector=0), "max_corrector"),
])
def test_bad_parameters_are_rejected(kw, name):
    with pytest.raises(ParameterError, match=name):
        ContinuationParameters(**kw)


def test_targets_reach_any_q_stop():
    p = ContinuationParameters(M=10, q_stop=0.5)
    t = p.targets()
    assert t[0] == math.pi and t[-1] == 0.5 and all(a > b for a, b in zip(t, t[1:]))
    assert np.allclose(t[:-1], np.arange(10, 1, -1) * math.pi / 10)


def test_branch_starts_at_binary_oscillation_with_two_interacting_beads():
    pts = branch(M=10, cells_per_pi=100, q_stop=0.8 * math.pi)
    assert pts[0].q == math.pi
    assert pts[0].diagnostics["ell"] == 0.0 and pts[0].diagnostics["N"] == 2.0   # N(pi) = 2 exactly
    assert [round(p.q / math.pi * 10) for p in pts] == [10, 9, 8]
    for p in pts:
        assert p.solve.reason > 0 and p.u_half[0] == 0 and p.u_half[-1] == 0
        assert np.all(p.u_half[1:-1] > 0)                                   # u > 0 on (0, pi) (lemma mono)


@pytest.mark.parametrize("alpha", [2.0, 2.5])
def test_other_exponents_run_unchanged(alpha):
    pts = branch(alpha=alpha, M=10, cells_per_pi=200, q_stop=math.pi / 5)
    assert len(pts) == 9
    N = [p.diagnostics["N"] for p in pts]
    assert N[0] == 2.0 and all(b > a for a, b in zip(N, N[1:]))        # packets widen as q decreases


def test_second_order_convergence_in_h():
    """||u||_inf, p(q) and N(q) converge like h^2 (observed on three grids) at a few q."""
    q_check = [0.8 * math.pi, 0.5 * math.pi, 0.3 * math.pi]
    vals = {}
    for K in (100, 200, 400):
        pts = branch(M=10, cells_per_pi=K, q_stop=0.3 * math.pi)
        vals[K] = {round(p.q, 9): tuple(p.diagnostics[k] for k in ("norm_inf", "slope", "N")) for p in pts}
    for q in q_check:
        for i in (0, 1, 2):
            a, b, c = (vals[K][round(q, 9)][i] for K in (100, 200, 400))
            order = math.log2(abs(a - b) / abs(b - c))
            # three-grid estimate; the C^{3,1/2} regularity of u adds O(h^2.5) terms: +- 0.3 on these grids
            assert abs(order - 2) < 0.3, (q, i, order)


def test_step_reduction_recovers_a_too_large_step():
    """With a demanding corrector bound the big step pi -> pi/2 must be split, and gives the same point."""
    direct = branch(M=10, cells_per_pi=100, q_stop=0.5 * math.pi)[-1]
    halved = branch(M=2, cells_per_pi=100, max_corrector=0.02)[-1]
    assert halved.substeps > 1 and halved.q == 0.5 * math.pi
    assert np.max(np.abs(halved.u_half - direct.u_half)) < 1e-9 * np.max(direct.u_half)


def test_failure_names_last_converged_q():
    cont = BranchContinuation(ContinuationParameters(M=4, cells_per_pi=100, max_corrector=1e-9, max_halvings=2),
                              PETSc.COMM_WORLD)
    got = []
    with pytest.raises(ContinuationError, match=r"last converged q = 3\.14159"):
        for p in cont.points():
            got.append(p.q)
    assert got == [math.pi]
    cont.destroy()


def test_resume_continues_identically():
    full = branch(M=10, cells_per_pi=100, q_stop=0.5 * math.pi)
    cont = BranchContinuation(ContinuationParameters(M=10, cells_per_pi=100, q_stop=0.5 * math.pi), PETSc.COMM_WORLD)
    cont.resume_from([p.q for p in full[:3]], [p.u_half for p in full[:3]])
    rest = list(cont.points())
    cont.destroy()
    assert [p.q for p in rest] == [p.q for p in full[3:]]
    for a, b in zip(rest, full[3:]):
        assert np.max(np.abs(a.u_half - b.u_half)) < 1e-10 * np.max(b.u_half)


def test_branch_is_rank_independent():
    """Under mpiexec -n 2: a branch on COMM_WORLD equals the branch on COMM_SELF to solver tolerance."""
    kw = dict(M=10, cells_per_pi=200, q_stop=math.pi / 5)
    serial = branch(PETSc.COMM_SELF, **kw)
    parallel = branch(PETSc.COMM_WORLD, **kw)
    for a, b in zip(serial, parallel):
        assert a.q == b.q
        assert np.max(np.abs(a.u_half - b.u_half)) <= 1e-10 * np.max(a.u_half)
        for key in ("N", "T", "slope"):
            assert abs(a.diagnostics[key] - b.diagnostics[key]) <= 1e-9 * abs(a.diagnostics[key])
