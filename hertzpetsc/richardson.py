"""Observed order and Richardson extrapolation from values on grids h, h/r, h/r^2 (one implementation for the
h-convergence of the branch, the solitary wave, the small-q levels, the slow-instability validation and the
precompressed waves of the stability map)."""
import math

from .errors import ParameterError


def observed_order(values, ratio=2.0):
    """log_r(|f0 - f1| / |f1 - f2|) from the last three values (nan when the differences do not define one)."""
    f0, f1, f2 = values[-3:]
    d1, d2 = f0 - f1, f1 - f2
    return math.log(abs(d1) / abs(d2)) / math.log(ratio) if d1 != 0 and d2 != 0 else math.nan


def extrapolate(coarse, fine, ratio=2.0, order=2.0):
    """The value without its h^order error term, from values (numbers or arrays) on the grids h and h/ratio."""
    return fine - (coarse - fine) / (ratio ** order - 1)


def richardson(values, ratio=2.0, order=None):
    """(observed order, extrapolated value) from values on grids refined by ``ratio`` each time (at least 3).

    The extrapolation eliminates the error term h^p from the two finest values: p = ``order`` if given (the
    scheme's order, 2 here), else the observed order when the differences are monotone and it lies in (1, 4),
    else 2.
    """
    if len(values) < 3:
        raise ParameterError("grids", len(values), "Richardson extrapolation needs values on at least 3 grids")
    if not ratio > 1:
        raise ParameterError("ratio", ratio, "the grids must be refined (ratio > 1)")
    f0, f1, f2 = values[-3:]
    d1, d2 = f0 - f1, f1 - f2
    seen = observed_order(values, ratio)
    if order is None:
        order = seen if d1 * d2 > 0 and 1.0 < seen < 4.0 else 2.0
    return seen, extrapolate(f1, f2, ratio, order)
