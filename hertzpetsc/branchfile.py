"""The branch file: a travelling-wave branch u(.; q) with its diagnostics, readable with numpy alone.

Format: a numpy ``.npz`` archive (``numpy.load(path)``), rewritten atomically (temporary file + rename) after
every converged point, so a killed run leaves the last complete file. Schema (P = number of points, K =
cells_per_pi):

=================  ===========  ==================================================================
name               shape        meaning
=================  ===========  ==================================================================
format             ()           the string ``hertzpetsc-branch-1``
alpha              ()           Hertz exponent (eq. vhertz)
cells_per_pi       ()           K; grid step h = pi / K
h                  ()           grid step
M                  ()           target wavenumbers are q = m pi / M (and q_stop)
q                  (P,)         wavenumber, decreasing from pi
xi                 (K+1,)       grid points j h on the half period [0, pi]
u                  (P, K+1)     profile u(xi; q) on [0, pi]; u is odd and 2 pi-periodic (u(2 pi - xi) = -u(xi))
norm_inf           (P,)         ||u||_inf (parabolic refinement of the grid maximum)
slope              (P,)         p(q) = u'(0), the free-flight slope
ell                (P,)         free-flight half-length ell(q)
N                  (P,)         N(q) = 2 (pi - ell) / q (eq. defnq)
F                  (P,)         F(q) = 2 ell / q
T                  (P,)         inverse velocity script-T(q) = q ||u||_inf^((alpha-1)/2) (eq. invv)
omega_A0           (P,)         omega(q, A0), A0 = ||u0||_inf (eq. dispers)
rescaled_norm      (P,)         ||u||_inf q^(2/(alpha-1)) (-> k_alpha, eq. normscaling)
snes_iterations    (P,)         Newton iterations at this q (last sub-step)
ksp_iterations     (P,)         linear iterations at this q (last sub-step)
residual_norm      (P,)         final ||R(u)||_2 of the discrete eq. ad
snes_reason        (P,)         PETSc converged reason
substeps           (P,)         continuation sub-steps used to reach q from the previous point (1 = no reduction)
wall_time          (P,)         seconds spent on this point
meta               ()           JSON string: software versions, ranks, options, creation time
=================  ===========  ==================================================================
"""
import json
import os
import zipfile

import numpy as np

from .errors import BranchFileError

FORMAT = "hertzpetsc-branch-1"
SCALARS = ("alpha", "cells_per_pi", "h", "M")
POINT_FIELDS = ("q", "norm_inf", "slope", "ell", "N", "F", "T", "omega_A0", "rescaled_norm",
                "snes_iterations", "ksp_iterations", "residual_norm", "snes_reason", "substeps", "wall_time")
INT_FIELDS = ("snes_iterations", "ksp_iterations", "snes_reason", "substeps")


def atomic_savez(path, **arrays):
    """Write an npz archive to ``path`` through a temporary file and a rename (never a half-written file)."""
    tmp = f"{path}.tmp-{os.getpid()}"
    with open(tmp, "wb") as f:
        np.savez(f, **arrays)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def load_npz(path, what, error):
    """All arrays of an npz archive as a dict; ``error`` (naming ``what``) if it is missing or unreadable."""
    if not os.path.exists(path):
        raise error(f"{what} {path!r} does not exist")
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as err:
        raise error(f"{what} {path!r} is corrupt or not an npz archive ({err})") from None


class BranchWriter:
    """Accumulates branch points and rewrites the file after each one. Call from one rank only."""

    def __init__(self, path, scalars, xi, meta, existing=None):
        self.path = path
        self.scalars = dict(scalars)
        self.xi = np.asarray(xi, dtype=float)
        self.meta = meta
        self.points = {k: list(existing[k]) for k in POINT_FIELDS} if existing else {k: [] for k in POINT_FIELDS}
        self.profiles = list(existing["u"]) if existing else []

    def append(self, profile, **fields):
        missing = set(POINT_FIELDS) - set(fields)
        if missing:
            raise KeyError(f"branch point lacks {sorted(missing)}")
        for k in POINT_FIELDS:
            self.points[k].append(fields[k])
        self.profiles.append(np.asarray(profile, dtype=float))
        self.write()

    def write(self):
        arrays = {k: np.asarray(v, dtype=np.int64 if k in INT_FIELDS else float) for k, v in self.points.items()}
        atomic_savez(self.path, format=np.array(FORMAT), xi=self.xi,
                     u=np.array(self.profiles).reshape(len(self.profiles), len(self.xi)),
                     meta=np.array(json.dumps(self.meta)), **{k: np.asarray(v) for k, v in self.scalars.items()},
                     **arrays)


def read_branch(path):
    """Load a branch file into a dict of numpy arrays (``meta`` decoded); :class:`BranchFileError` if unusable."""
    data = load_npz(path, "branch file", BranchFileError)
    if str(data.get("format", "")) != FORMAT:
        raise BranchFileError(f"{path!r} is not a hertzpetsc branch file (format {FORMAT!r} expected)")
    required = set(SCALARS) | set(POINT_FIELDS) | {"u", "xi", "meta"}
    missing = required - set(data)
    if missing:
        raise BranchFileError(f"branch file {path!r} is corrupt: missing {sorted(missing)}")
    P = len(data["q"])
    if data["u"].shape != (P, len(data["xi"])) or any(len(data[k]) != P for k in POINT_FIELDS):
        raise BranchFileError(f"branch file {path!r} is corrupt: inconsistent array shapes")
    for k in SCALARS:
        data[k] = data[k].item()
    try:
        data["meta"] = json.loads(str(data["meta"]))
    except ValueError:
        raise BranchFileError(f"branch file {path!r} is corrupt: unreadable meta") from None
    return data


def point_index(branch, q, tol=1e-12):
    """Index of the point at wavenumber ``q`` in a loaded branch, or :class:`BranchFileError`."""
    i = int(np.argmin(np.abs(branch["q"] - q))) if len(branch["q"]) else -1
    if i < 0 or abs(branch["q"][i] - q) > tol * max(1.0, abs(q)):
        raise BranchFileError(f"the branch has no point at q = {q:.12g} "
                              f"(it has q in [{branch['q'].min():.6g}, {branch['q'].max():.6g}])")
    return i


# --- refined travelling-wave states (section 3.4), one file per chain length -----------------------------------
REFINED_FORMAT = "hertzpetsc-refined-1"
REFINED_FIELDS = ("q", "E_before_paper_flow", "E_before", "E_after", "E_after_paper_flow", "r", "iterations",
                  "jacobians", "wall_time", "sigma_min")


class RefinedWriter:
    """Refined states X^(q) (N, 2) with their residuals, rewritten atomically after each q. One rank only.

    Fields (P = number of q): ``q`` (P,); ``x`` (P, N, 2) refined (x_n, xdot_n); ``E_before`` / ``E_after``
    E(q) of the interpolated branch wave / of the refined state, measured with the tight flow (rtol 1e-14);
    ``E_before_paper_flow`` / ``E_after_paper_flow`` the same with the paper's rtol 1e-12; ``r`` relative
    difference of the last two Gauss-Newton iterates; ``iterations``, ``jacobians``, ``wall_time``;
    ``sigma_min`` the smallest singular value of the Jacobian restricted by the phase conditions;
    scalars ``alpha``, ``N``, ``branch`` (path), ``format``.
    """

    def __init__(self, path, alpha, N, branch_path, existing=None):
        self.path, self.alpha, self.N, self.branch_path = path, alpha, N, branch_path
        self.rows = {k: list(existing[k]) for k in REFINED_FIELDS} if existing else {k: [] for k in REFINED_FIELDS}
        self.x = list(existing["x"]) if existing else []

    def append(self, x, **fields):
        for k in REFINED_FIELDS:
            self.rows[k].append(fields[k])
        self.x.append(np.asarray(x, dtype=float))
        atomic_savez(self.path, format=np.array(REFINED_FORMAT), alpha=np.asarray(self.alpha),
                     N=np.asarray(self.N), branch=np.array(self.branch_path),
                     x=np.array(self.x).reshape(len(self.x), self.N, 2),
                     **{k: np.asarray(v, dtype=float) for k, v in self.rows.items()})


def read_refined(path):
    """Load a refinement file (dict of arrays); :class:`RunFileError` if unusable."""
    from .errors import RunFileError
    data = load_npz(path, "refinement file", RunFileError)
    if str(data.get("format", "")) != REFINED_FORMAT or set(REFINED_FIELDS) - set(data):
        raise RunFileError(f"{path!r} is not a hertzpetsc refinement file")
    data["N"], data["alpha"] = int(data["N"]), float(data["alpha"])
    return data


def refined_state(path, q, N):
    """The refined (N, 2) state at wavenumber q from a refinement file, or None if the file lacks that q."""
    from .errors import RunFileError
    data = read_refined(path)
    if data["N"] != N:
        raise RunFileError(f"refinement file {path!r} is for N = {data['N']} beads, not {N}")
    return refined_lookup(data, q)


def refined_lookup(data, q):
    """The refined (N, 2) state at wavenumber q in loaded refinement data, or None if it lacks that q."""
    i = np.nonzero(np.abs(data["q"] - q) <= 1e-12 * max(1.0, q))[0]
    return data["x"][i[0]] if len(i) else None
