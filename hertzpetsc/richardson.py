"""Observed order and Richardson extrapolation from values on grids h, h/r, h/r^2 (one implementation for the
h-convergence of the branch, the solitary wave, the small-q levels, the slow-instability validation and the
precompressed waves of the stability map)."""
import math

from .errors import ParameterError


def observed_order(values, ratio=2.0, steps=None):
    """The order p with f_k = f + C h_k^p through the last three values: log_r(|f0 - f1| / |f1 - f2|) when the
    grids are refined by a constant ``ratio``; with the grid ``steps`` h0 > h1 > h2 (any ratios) the root of
    (f0 - f1) / (f1 - f2) = (h0^p - h1^p) / (h1^p - h2^p) in (0.05, 20) (nan when the differences do not define
    one)."""
    f0, f1, f2 = values[-3:]
    d1, d2 = f0 - f1, f1 - f2
    if d1 == 0 or d2 == 0:
        return math.nan
    if steps is None:
        return math.log(abs(d1) / abs(d2)) / math.log(ratio)
    h0, h1, h2 = steps[-3:]
    target = d1 / d2
    if target <= 0:
        return math.nan
    g = lambda p: math.log((h0 ** p - h1 ** p) / (h1 ** p - h2 ** p)) - math.log(target)   # noqa: E731
    lo, hi = 0.05, 20.0
    if g(lo) * g(hi) > 0:
        return math.nan
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if g(lo) * g(mid) <= 0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def extrapolate(coarse, fine, ratio=2.0, order=2.0):
    """The value without its h^order error term, from values (numbers or arrays) on the grids h and h/ratio."""
    return fine - (coarse - fine) / (ratio ** order - 1)


def richardson(values, ratio=2.0, order=None, steps=None):
    """(observed order, extrapolated value) from values on grids refined by ``ratio`` each time (at least 3), or
    on the grids of the given ``steps`` (decreasing h, any ratios: the order and the extrapolation use the actual
    ratios).

    The extrapolation eliminates the error term h^p from the two finest values: p = ``order`` if given (the
    scheme's order, 2 here), else the observed order when the differences are monotone and it lies in (1, 4),
    else 2.
    """
    if len(values) < 3:
        raise ParameterError("grids", len(values), "Richardson extrapolation needs values on at least 3 grids")
    if steps is not None:
        steps = [float(h) for h in steps]
        if len(steps) != len(values) or any(not b < a / 1.05 for a, b in zip(steps, steps[1:])):
            raise ParameterError("grids", steps, "the grid steps must decrease by at least 5 % from grid to grid")
        ratio = steps[-2] / steps[-1]
    if not ratio > 1:
        raise ParameterError("ratio", ratio, "the grids must be refined (ratio > 1)")
    f0, f1, f2 = values[-3:]
    d1, d2 = f0 - f1, f1 - f2
    seen = observed_order(values, ratio, steps)
    if order is None:
        order = seen if d1 * d2 > 0 and 1.0 < seen < 4.0 else 2.0
    return seen, extrapolate(f1, f2, ratio, order)
