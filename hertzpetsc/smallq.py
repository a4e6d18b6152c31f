"""The branch at small q with the grid refined as q decreases, and Richardson extrapolation in h (section 3.2).

As q -> 0 the compression region of u(.; q) shrinks like q (its width is about N(q) q, N -> 4.8 at alpha = 3/2),
so a fixed h resolves it less and less: at h = pi/1000 and q = pi/400 it spans a dozen cells. Here the number of
cells per unit of q is kept at least ``cells_per_q``: the continuation runs on the grid K = K0 2^k while
q > q_0 / 2^k, and when q crosses q_0 / 2^k the last two profiles are interpolated (degree-5 Lagrange, below the
scheme's O(h^2)) onto the grid twice as fine and the continuation goes on there, with the same secant predictor.
Running the whole path at ``levels`` resolutions h, h/2, h/4 gives, at every target q, the observed order and the
Richardson-extrapolated ||u||_inf, p(q), N(q) and ||u||_inf q^(2/(alpha-1)) (which tends to k_alpha, eq.
normscaling).
"""
import math
from dataclasses import dataclass

import numpy as np
from .continuation import BranchContinuation, ContinuationParameters
from .errors import ParameterError
from .stencil import full_period, lagrange_periodic

FIELDS = ("norm_inf", "slope", "N", "F", "rescaled_norm")


@dataclass(frozen=True)
class SmallQParameters:
    """q from pi down to q_stop through the targets; the grid at q has at least ``cells_per_q`` cells per q,
    doubled at every level (level l uses cells_per_q 2^l)."""

    alpha: float = 1.5
    q_stop: float = math.pi / 400
    q_first: float = math.pi / 50          # targets: q_first 2^(-i / per_halving) down to q_stop
    per_halving: int = 4
    cells_per_q: int = 20                  # q / h at q_first on level 0: h = pi/1000 at pi/50 (the paper's grid)

    def __post_init__(self):
        if not (0 < self.q_stop <= self.q_first <= math.pi):
            raise ParameterError("q_stop", self.q_stop, f"must satisfy 0 < q_stop <= q_first = {self.q_first:.6g} <= pi")
        if not (isinstance(self.per_halving, (int, np.integer)) and self.per_halving >= 1):
            raise ParameterError("per_halving", self.per_halving, "must be an integer >= 1")
        if not (isinstance(self.cells_per_q, (int, np.integer)) and self.cells_per_q >= 4):
            raise ParameterError("cells_per_q", self.cells_per_q, "must be an integer >= 4")

    def targets(self):
        """q_first 2^(-i/per_halving), i = 0, 1, ..., with q_stop appended if it falls between."""
        qs, i = [], 0
        while True:
            q = self.q_first * 2.0 ** (-i / self.per_halving)
            if q < self.q_stop * (1 - 1e-12):
                break
            qs.append(q)
            i += 1
        if abs(qs[-1] - self.q_stop) > 1e-12 * self.q_stop:
            qs.append(self.q_stop)
        return qs

    def cells_per_pi(self, q, level):
        """K for wavenumber q on ``level``: K0 2^(k + level), k = the number of halvings of q_first that q is below."""
        K0 = int(round(self.cells_per_q * math.pi / self.q_first))
        k = max(0, math.ceil(math.log2(self.q_first / q) - 1e-9))
        return K0 * 2 ** (k + level)


def regrid_half_profile(u_half, K_new):
    """An odd profile on [0, pi] (K+1 values) interpolated onto the grid of K_new cells per pi."""
    K = len(u_half) - 1
    xi = np.arange(K_new + 1) * math.pi / K_new
    out = lagrange_periodic(full_period(u_half), math.pi / K, xi)
    out[0] = out[-1] = 0.0
    return out


def continue_refining(params, level, comm=None, done=None, on_point=None):
    """Continue from pi to q_stop on ``level``, refining the grid at q_first / 2^k; yields (q, K, diagnostics).

    ``done``: a list of (q, K, u_half) already computed on this level (a resumed run); the last two seed the
    predictor. ``on_point(q, K, u_half, diagnostics)`` is called for every new target point, so the caller can
    save it before the next one is attempted.
    """
    targets = params.targets()
    history = list(done or [])[-2:]
    cont, K_cur = None, None
    try:
        if not history:
            K0 = params.cells_per_pi(params.q_first, level)
            # pi -> q_first through the targets m pi / M (M = pi / q_first, the paper's 50) on the first grid
            first = ContinuationParameters(params.alpha, max(1, round(math.pi / params.q_first)), K0,
                                           q_stop=params.q_first)
            cont, K_cur = BranchContinuation(first, comm), K0
            for point in cont.points():
                history = (history + [(point.q, K0, point.u_half)])[-2:]
                if abs(point.q - params.q_first) <= 1e-12 * params.q_first:
                    if on_point:
                        on_point(point.q, K0, point.u_half, point.diagnostics)
                    yield point.q, K0, point.diagnostics
        q_done = history[-1][0]
        for q in targets:
            if q >= q_done * (1 - 1e-12):
                continue
            K = params.cells_per_pi(q, level)
            if K != K_cur:
                if cont is not None:
                    cont.destroy()
                cont = BranchContinuation(ContinuationParameters(params.alpha, 1, K, q_stop=params.q_stop), comm)
                cont.resume_from([h[0] for h in history], [regrid_half_profile(h[2], K) for h in history])
                K_cur = K
            point = cont.step_to(q)
            history = (history + [(q, K, point.u_half)])[-2:]
            if on_point:
                on_point(q, K, point.u_half, point.diagnostics)
            yield q, K, point.diagnostics
    finally:
        if cont is not None:
            cont.destroy()


def richardson(values, ratio=2.0):
    """Observed order and extrapolated value from three values at h, h/ratio, h/ratio^2 (order 2 assumed when
    the differences do not define an order)."""
    f0, f1, f2 = values
    d1, d2 = f0 - f1, f1 - f2
    order = math.log(d1 / d2) / math.log(ratio) if d1 * d2 > 0 and d2 != 0 else math.nan
    p = order if order == order and 1.0 < order < 4.0 else 2.0
    return order, f2 - d2 / (ratio ** p - 1)

