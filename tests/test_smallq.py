"""Continuation to small q with the grid refined as q decreases, and Richardson extrapolation (hertzpetsc.smallq)."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

from conftest import shared_tmp
from hertzpetsc.qbranch import BranchContinuation, ContinuationParameters, regrid_half_profile
from hertzpetsc.errors import ParameterError
from hertzpetsc.richardson import richardson
from hertzpetsc.records import read_kind
from hertzpetsc.studies.branch import SMALLQ_KIND, SmallQParameters, SmallQStudy

COMM = PETSc.COMM_WORLD


def test_targets_and_grids():
    p = SmallQParameters(q_first=math.pi / 50, q_stop=math.pi / 400, per_halving=4, cells_per_q=20)
    qs = p.targets()
    assert len(qs) == 13 and qs[0] == math.pi / 50 and abs(qs[-1] - math.pi / 400) < 1e-15
    assert np.allclose(np.array(qs[:-1]) / np.array(qs[1:]), 2 ** 0.25)
    K = [p.cells_per_pi(q, 0) for q in qs]
    assert K[0] == 1000 and K[-1] == 8000
    assert all(20 <= q * k / math.pi < 40 + 1e-9 for q, k in zip(qs, K))    # q/h stays in [20, 40)
    assert p.cells_per_pi(math.pi / 400, 2) == 32000


def test_bad_parameters():
    with pytest.raises(ParameterError, match="q_stop"):
        SmallQParameters(q_stop=0.1, q_first=0.05)
    with pytest.raises(ParameterError, match="cells_per_q"):
        SmallQParameters(cells_per_q=2)
    with pytest.raises(ParameterError, match="levels"):
        SmallQParameters(levels=2)
    with pytest.raises(ParameterError, match="grids"):
        richardson([1.0, 2.0])


def test_regrid_is_exact_to_interpolation_order():
    K = 64
    xi = np.arange(K + 1) * math.pi / K
    u = np.sin(xi) + 0.3 * np.sin(3 * xi)
    fine = regrid_half_profile(u, 4 * K)
    xf = np.arange(4 * K + 1) * math.pi / (4 * K)
    # 6-point Lagrange: |error| <= h^6 / 6! max|u^(6)| max|prod (t - k)| = h^6 / 720 * 219.7 * 3.5 ~ 1.5e-8
    bound = (math.pi / K) ** 6 / 720 * (1 + 0.3 * 3 ** 6) * 3.6
    assert np.max(np.abs(fine - (np.sin(xf) + 0.3 * np.sin(3 * xf)))) < bound


def test_richardson_recovers_limit_and_order():
    c, a = 1.3, 0.7
    order, limit = richardson([c + a * h ** 2 for h in (0.1, 0.05, 0.025)])
    assert abs(order - 2) < 1e-9 and abs(limit - c) < 1e-12
    order, limit = richardson([c + a * h ** 2 + 0.1 * h ** 4 for h in (0.1, 0.05, 0.025)])
    assert abs(order - 2) < 0.01 and abs(limit - c) < 1e-6          # the h^4 term left: 0.1 * 0.05^4 ~ 6e-7


def test_refined_continuation_matches_a_direct_one_on_the_finer_grid(tmp_path):
    """The profile at q = pi/20 does not depend on how it was reached: continued on K = 80 and regridded to
    K = 160 when q fell below pi/10, or continued on K = 160 from pi (same discrete problem, unique solution:
    they agree to the Newton tolerance, bound 1e-8 relative)."""
    p = SmallQParameters(q_first=math.pi / 10, q_stop=math.pi / 20, per_halving=2, cells_per_q=8)
    study = SmallQStudy(p, f"{shared_tmp(tmp_path)}/progress.npz", COMM)
    rows = [row for row in study.run() if row[0] == 0]
    level, q, K, d = rows[-1]
    u = study.store.state["L0_seed1_u"]
    assert K == 160 and len(u) == 161 and q == pytest.approx(math.pi / 20)
    cont = BranchContinuation(ContinuationParameters(M=20, cells_per_pi=160, q_stop=math.pi / 20), COMM)
    direct = [pt for pt in cont.points()][-1]
    cont.destroy()
    assert abs(direct.q - q) < 1e-14
    assert np.max(np.abs(direct.u_half - u)) < 1e-8 * np.max(np.abs(u))


def test_a_killed_small_q_run_resumes_to_the_same_table(tmp_path):
    """Run two of the three levels, 'kill' (stop iterating), resume from the progress file: the table equals that
    of an uninterrupted run (the resumed levels restart from the last two profiles, which are saved exactly)."""
    d = shared_tmp(tmp_path)
    p = SmallQParameters(q_first=math.pi / 10, q_stop=math.pi / 20, per_halving=2, cells_per_q=8)
    full = SmallQStudy(p, f"{d}/full.npz", COMM)
    list(full.run())
    part = SmallQStudy(p, f"{d}/part.npz", COMM)
    for level, *_ in part.run():
        if level == 1:
            break                                   # killed during level 1
    resumed = SmallQStudy(p, f"{d}/part.npz", COMM, "resume")
    list(resumed.run())
    assert resumed.table(1.3568) == full.table(1.3568)
    assert SMALLQ_KIND.check(read_kind(f"{d}/part.npz", SMALLQ_KIND, "x")) == ([], [])      # as declared
    with pytest.raises(Exception, match="another computation"):
        SmallQStudy(SmallQParameters(q_first=math.pi / 10, q_stop=math.pi / 20, per_halving=2, cells_per_q=10),
                    f"{d}/part.npz", COMM, "resume").open()


def test_a_q_stop_too_small_for_the_machine_names_q_stop_and_the_smallest_that_fits():
    """The memory check of the finest grid is reported as q_stop's value and bound (it showed the grid K and K's
    bound under the name q_stop): the bound q_first / 2^k fits, half of it does not (K doubles per halving)."""
    import re
    from hertzpetsc.resources import check_memory
    p = SmallQParameters(q_stop=1e-9)
    with pytest.raises(ParameterError, match=r"q_stop = 1e-09: must be >= q_first / 2\^") as e:
        SmallQStudy(p, None, COMM)
    k = int(re.search(r"2\^(\d+) = ", str(e.value)).group(1))
    bound, finest = p.q_first / 2 ** k, p.levels - 1
    check_memory(p.cells_per_pi(bound, finest), COMM)
    with pytest.raises(ParameterError):
        check_memory(p.cells_per_pi(bound / 2, finest), COMM)
    assert f"= {bound:.6g} on this machine" in str(e.value)
