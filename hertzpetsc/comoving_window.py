"""The eigenvalues of the co-moving pencils (:mod:`hertzpetsc.comoving`) that represent the chain's modes, the
compacton band among them, and the scans over the Bloch parameter theta.

Window. (theta, lambda) and (theta + q, lambda - i) describe the same chain mode, and (-theta, conj lambda) its
conjugate: every mode of the infinite chain has a representative with theta in [0, pi] (counting the eigenvalues
of the -theta problem) and |Im lambda| <= 1/2, the least oscillatory w, i.e. the best resolved one.

The near-1 band. Each compression zone's translation mode W_0 = u' - p (zero in free flight, C^2) solves the
theta = 0 problem on its own, because no contact link joins two zones; its Bloch sums therefore give, at every
theta, the eigenvalue lambda_b = -i theta / q (mu = 1) with a Jordan partner: m translations per m wavelengths,
as if the wave were m compactons. The scheme splits that block at O(h) (the coefficients are not smooth), which
would read as a spurious |mu| - 1 = O(h); it is identified by its known location and excluded (:class:`SectorWindow`),
and reported separately.
"""
import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .comoving_pep import realified
from .errors import ParameterError
from .symmetry import real_sector

WINDOW_IM = 0.5            # |Im lambda| <= 1/2 covers every chain mode (module docstring)
TARGET_OFFSET = 0.0123     # added to every target, so that none falls on an exact eigenvalue (lambda = 0, theta = 0)
DEFAULT_BOX = (-0.3, 0.9)  # Re lambda searched: contains the exponents of the most unstable branch waves


def real_pencil(wave, theta):
    """The theta pencil of ``wave`` as real CSR matrices (realified unless theta is 0 or pi), its size n (the complex
    problem's) and whether it is real."""
    real, mats = real_sector(theta), wave.pencil(theta)
    return ([sp.csr_matrix(A.real) if np.iscomplexobj(A.data) else A for A in mats] if real else
            [realified(A) for A in mats]), mats[0].shape[0], real


def sector_side(vectors, n):
    """For eigenvectors (x1, x2) of a realified pencil: +1 when x1 + i x2 carries most of the norm (an eigenvector
    of the theta problem), -1 when x1 - i x2 does (the -theta problem)."""
    out = []
    for v in vectors:
        x1, x2 = v[:n], v[n:]
        p, m = np.linalg.norm(x1 + 1j * x2), np.linalg.norm(x1 - 1j * x2)
        out.append(1.0 if p >= m else -1.0)
    return np.array(out)


def nearest_exponents(wave, pencil, solver, target, count):
    """The ``count`` eigenvalues lambda = ln z / h of a :func:`real_pencil` nearest the real ``target`` (in Re lambda),
    each with its side (:func:`sector_side`; a real pencil's: +1)."""
    mats, n, real = pencil
    z, vectors = solver.solve(mats, math.exp(target * wave.h), count, want_vectors=not real)
    lam = np.log(z.astype(complex)) / wave.h
    return lam, (np.ones(len(lam)) if real else sector_side(vectors, n))


@dataclass
class SectorWindow:
    """The eigenvalues lambda with Re lambda in the box and |Im lambda| <= 1/2 at Bloch parameter theta (each with
    its side: +1 the theta problem, -1 the -theta problem; real theta: +1), which of them are the compacton band
    (``band``), the band's spread max |lambda - lambda_b| and the distance from lambda_b to the nearest other
    eigenvalue (``separation``), the radius around the target within which every eigenvalue was found, and nev."""

    theta: float
    K: int
    lam: np.ndarray
    side: np.ndarray
    band: np.ndarray
    band_spread: float
    separation: float
    radius: float
    nev: int

    def dominant(self):
        """(lambda, theta of its problem) of the largest Re lambda outside the band, or (nan, theta)."""
        keep = ~self.band
        if not keep.any():
            return complex(math.nan), self.theta
        i = int(np.argmax(np.where(keep, self.lam.real, -np.inf)))
        return complex(self.lam[i]), float(self.side[i] * self.theta)


def band_members(lam, side, theta, q, spread_limit):
    """Mask of the compacton band: at theta = 0 the 4 eigenvalues nearest 0 (band pair and Galilean pair), else on
    each side s the 2 nearest lambda_b = -i s theta / q when that lies in the window. Returns (mask, spread,
    separation): members farther than ``spread_limit`` from lambda_b are not taken."""
    mask = np.zeros(len(lam), dtype=bool)
    spread, separation = 0.0, math.inf
    groups = [(0.0, np.ones(len(lam), dtype=bool), 4)] if abs(math.sin(theta / 2)) < 1e-14 else \
        [(s, side == s, 2) for s in ((1.0,) if real_sector(theta) else (1.0, -1.0))]
    for s, on_side, count in groups:
        lam_b = -1j * s * theta / q
        if abs(lam_b.imag) > WINDOW_IM:
            continue
        idx = np.nonzero(on_side)[0]
        order = idx[np.argsort(np.abs(lam[idx] - lam_b))]
        near = [i for i in order[:count] if abs(lam[i] - lam_b) <= spread_limit]
        mask[near] = True
        if near:
            spread = max(spread, float(np.max(np.abs(lam[near] - lam_b))))
        rest = [i for i in order if i not in near]
        if rest:
            separation = min(separation, float(abs(lam[rest[0]] - lam_b)))
    return mask, spread, separation


def sector_window(wave, theta, solver, box=DEFAULT_BOX, max_nev=192):
    """All eigenvalues of the theta problem (and of -theta) in the window, by shift-and-invert at the box centre;
    nev doubles until the converged eigenvalues cover the box. The band is identified within 0.1 of lambda_b (its
    discrete splitting is O(h); the other eigenvalues near it are the acoustic ones, lambda ~ -i c theta)."""
    if not box[0] < box[1]:
        raise ParameterError("box", box, "must be an interval (low, high) of Re lambda")
    centre = 0.5 * (box[0] + box[1]) + TARGET_OFFSET
    need = 1.05 * math.hypot(0.5 * (box[1] - box[0]) + TARGET_OFFSET, WINDOW_IM)
    pencil = real_pencil(wave, theta)
    nev = solver.nev * (1 if pencil[2] else 2)
    while True:
        lam, side = nearest_exponents(wave, pencil, solver, centre, nev)
        dist = np.sort(np.abs(lam - centre))
        radius = float(dist[min(nev, len(dist)) - 1]) if len(dist) else 0.0
        if radius >= need or nev >= max_nev:
            break
        nev *= 2
    keep = (np.abs(lam.imag) <= WINDOW_IM) & (lam.real >= box[0]) & (lam.real <= box[1]) & \
           (np.abs(lam - centre) <= radius)
    lam, side = lam[keep], side[keep]
    band, spread, separation = band_members(lam, side, theta, wave.q, 0.1)
    return SectorWindow(theta, wave.K, lam, side, band, spread, separation, radius, nev)


@dataclass
class ThetaScan:
    """The worst non-band mode over a theta grid on one profile grid: gamma = q Re lambda / script-T, its theta and
    lambda, the largest band spread (as |mu| - 1 = q spread, the O(h) artefact) and the smallest separation."""

    lam: complex
    theta: float
    gamma: float
    band_mu: float
    min_separation: float


def theta_scan(wave, thetas, solver, box=DEFAULT_BOX):
    """:func:`sector_window` at every theta of ``thetas`` (in [0, pi])."""
    best, band_mu, sep = None, 0.0, math.inf
    for th in thetas:
        if not (-1e-14 <= th <= math.pi + 1e-14):
            raise ParameterError("theta", th, "the Bloch parameters must lie in [0, pi]")
        w = sector_window(wave, th, solver, box)
        lam, th_eff = w.dominant()
        g = float(wave.growth(lam)) if lam == lam else -math.inf
        if best is None or g > best[0]:
            best = (g, lam, abs(th_eff))
        band_mu = max(band_mu, wave.q * w.band_spread)
        sep = min(sep, w.separation)
    return ThetaScan(best[1], best[2], best[0], band_mu, sep)


def tracked_exponent(wave, theta, guess, solver, nev=12):
    """The eigenvalue of the theta problem nearest ``guess`` (shift-and-invert at Re guess + TARGET_OFFSET; the
    nev nearest cover |Im lambda| <= 1.5, about two eigenvalues per unit of Im lambda): Richardson sequences."""
    if not np.isfinite(guess):
        raise ParameterError("guess", guess, "the eigenvalue to track must be a finite complex number")
    pencil = real_pencil(wave, theta)
    lam, side = nearest_exponents(wave, pencil, solver, guess.real + TARGET_OFFSET, nev if pencil[2] else 2 * nev)
    lam = np.where(side < 0, np.conj(lam), lam)          # the theta problem's representatives
    return complex(lam[int(np.argmin(np.abs(lam - guess)))])
