"""The one-call API (hertzpetsc.api) and the public parameters objects: bad arguments are ParameterErrors naming the
Python argument and its range (the same ranges the drivers' options have), never a raw Python or PETSc error, and
what the calls document (the orbit's normalisation, nev with every method) is what they do."""
import math

import numpy as np
import pytest
from petsc4py import PETSc

import hertzpetsc as hz
from conftest import small_branch
from hertzpetsc.branch import POINT_FIELDS
from hertzpetsc.errors import ParameterError
from hertzpetsc.waves import orbit_on_chain

COMM = PETSc.COMM_WORLD


@pytest.fixture(scope="module")
def point():
    return small_branch().point(math.pi / 5)


@pytest.mark.parametrize("A", [np.float32(2.0), np.int64(2), 2])
def test_orbit_takes_any_real_amplitude(point, A):
    """numpy scalars are amplitudes like Python floats (the check is errors.check_real's)."""
    assert np.array_equal(hz.orbit(point, 10, A=A).x, hz.orbit(point, 10, A=2.0).x)


def test_orbit_amplitude_scales_the_displacements(point):
    """A scale-invariant law: the displacements scale with A (eq. twper), the same shape at every amplitude."""
    o2, o4 = hz.orbit(point, 10, A=2.0), hz.orbit(point, 10, A=4.0)
    np.testing.assert_allclose(o4.x[:, 0], 2 * o2.x[:, 0], rtol=1e-14, atol=0)


@pytest.mark.parametrize("A,why", [(math.inf, "must be a finite number > 0"), (math.nan, "finite number > 0"),
                                   (-1.0, "> 0"), (0, "> 0"), (True, "> 0"),
                                   ("2", "> 0"), (1e300, "not finite in double precision")])
def test_orbit_refuses_amplitudes_naming_A(point, A, why):
    """An amplitude out of range, or one whose state overflows (1e300: velocities ~ A^((alpha+1)/2)), is refused
    naming A, not a later PETSc error of refine."""
    with pytest.raises(ParameterError, match=f"invalid A = .*{why}") as e:
        hz.orbit(point, 10, A=A)
    assert e.value.name == "A"


def test_orbit_normalises_the_profile_not_the_beads_at_time_zero():
    """max |u| = 1 (section 3.4): over the phases of the wave the beads reach 1 (to the phase grid's resolution,
    spacing d: the crest is missed by at most max|u''| d^2 / 8, below 1e-5 here), at t = 0 they sample u at q n only."""
    p = small_branch().point(math.pi / 2)
    o = hz.orbit(p, 4)
    d = p.q / 400
    crest = max(np.max(np.abs(orbit_on_chain(p, o.spec, phase=k * d).x[:, 0])) for k in range(400))
    assert abs(crest - 1) < 1e-4
    assert np.max(np.abs(o.x[:, 0])) <= crest


@pytest.mark.parametrize("tol", [2, 1, 0, -1e-10, math.nan])
def test_refine_tolerance_is_checked(point, tol):
    with pytest.raises(ParameterError, match=r"invalid tol = .*: .* in|invalid tol = .*> 0 and < 1"):
        hz.refine(hz.orbit(point, 10), tol=tol, comm=COMM)


@pytest.mark.parametrize("kw,name", [(dict(tol_rho=-1), "tol_rho"), (dict(tol_rho=0), "tol_rho"),
                                     (dict(tol_rho=math.nan), "tol_rho"), (dict(tol_rho=1), "tol_rho"),
                                     (dict(nev=0), "nev"), (dict(nev=21), "nev"), (dict(nev=2.5), "nev"),
                                     (dict(method="bogus"), "method")])
def test_multipliers_arguments_are_checked_before_any_solve(point, kw, name):
    """The ranges of floquet_scan.py's options: tol_rho in (0, 1), nev in [1, 2N]."""
    with pytest.raises(ParameterError, match=f"invalid {name} = ") as e:
        hz.multipliers(hz.orbit(point, 10), comm=COMM, **kw)
    assert e.value.name == name


def test_nev_keeps_the_largest_multipliers_with_every_method(point):
    """nev with the symmetric (and dense) route keeps the nev largest of all 2N, as documented (not ignored)."""
    o = hz.orbit(point, 10)
    full = hz.multipliers(o, comm=COMM)
    for method in ("symmetric", "dense"):
        part = hz.multipliers(o, method=method, nev=5, tol_rho=1e-4, comm=COMM)
        assert len(part.multipliers) == 5 and not part.complete
        np.testing.assert_allclose(np.abs(part.multipliers), np.abs(full.multipliers[:5]), rtol=1e-6)


def test_scalar_wavenumber_is_a_list_of_one():
    m = hz.LatticeModel.hertz(2, delta0=0.5)
    one = hz.WaveParameters(m, q=math.pi / 3, A=0.5, N=6)
    assert one == hz.WaveParameters(m, q=(math.pi / 3,), A=0.5, N=6) and one.q == (math.pi / 3,)
    assert hz.AmplitudeParameters(m, q=math.pi / 3).q == (math.pi / 3,)
    assert hz.DimerParameters(m, q=math.pi / 4).q == (math.pi / 4,)


def test_branch_column_names_the_fields():
    b = small_branch()
    for name in POINT_FIELDS:
        assert len(b.column(name)) == len(b)
    with pytest.raises(ParameterError, match="invalid name = 'bogus': must be a field of the branch: .*norm_inf"):
        b.column("bogus")


def test_compute_branch_wants_a_model():
    with pytest.raises(ParameterError, match="invalid model = 'str': must be a LatticeModel"):
        hz.compute_branch("x", M=2, cells_per_pi=100, comm=COMM)


def test_a_study_checks_its_mode_when_built(tmp_path):
    """mode is checked by Study.__init__ (records.MODES), not first in run(); no file is made."""
    params = hz.WaveParameters(hz.LatticeModel.hertz(2, delta0=0.5), q=(math.pi / 3,), A=0.5, N=6)
    with pytest.raises(ParameterError, match="invalid mode = 'bogus': must be one of new, resume, force"):
        hz.WaveStudy(params, comm=COMM, output=str(tmp_path / "w.npz"), mode="bogus")
    assert not (tmp_path / "w.npz").exists()


def test_plot_spectrum_leaves_pyplot_alone_and_returns_the_figure():
    """hz.plot_spectrum makes its figure without pyplot: a notebook's current figure and figure list stay as they
    were (it opened a pyplot figure, which became the current one); it returns the Figure (shown as a notebook
    cell's value), whose axes hold the multipliers and the unit circle; with ``ax`` it draws on the caller's axes
    and returns their figure. ``.figure.savefig`` (the tutorial's call) works on what it returns."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure
    mine = plt.figure()
    before = plt.get_fignums()
    mu = np.array([1.1, 1 / 1.1, np.exp(0.3j), np.exp(-0.3j)])
    try:
        fig = hz.plot_spectrum(mu, title="test")
        assert isinstance(fig, Figure) and fig.figure is fig and len(fig.axes) == 1
        assert plt.get_fignums() == before and plt.gcf() is mine and not mine.axes
        ax = fig.axes[0]
        assert ax.get_title() == "test"
        circle, points = ax.lines
        assert np.allclose(np.hypot(circle.get_xdata(), circle.get_ydata()), 1.0)
        assert np.array_equal(points.get_xdata(), mu.real) and np.array_equal(points.get_ydata(), mu.imag)
        theirs = Figure().subplots()
        assert hz.plot_spectrum(mu, ax=theirs) is theirs.figure and len(theirs.lines) == 2
        assert plt.get_fignums() == before and plt.gcf() is mine
    finally:
        plt.close(mine)
