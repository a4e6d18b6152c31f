"""Verdicts read back from records (numpy): q_c and q_m of a scan in q (section 3.5), and the intervals of A where a
stability map's chain is unstable, between its located edges (issue 23). Read by the studies' tables and by
:mod:`hertzpetsc.plotting`'s figures alike.
"""
import math

import numpy as np

# the kinds of a stability map's records (``hertzpetsc-precompression-map-*``, :mod:`hertzpetsc.studies.maps`): a
# point of the map, a located boundary point on N beads, on the infinite chain, the uncompressed limit, the gap
# opening, a Krein crossing
KIND_POINT, KIND_EDGE, KIND_EDGE_INF, KIND_LIMIT, KIND_GAP, KIND_CROSSING = 0, 1, 2, 3, 4, 5


def critical_wavenumbers(q, rho, tol_rho):
    """(q_c, next stable q above it or None, q_m): q_c the largest q with rho - 1 > tol_rho (nan if none is
    unstable), q_m the q of the largest rho."""
    q, rho = np.asarray(q, dtype=float), np.asarray(rho, dtype=float)
    unstable = rho - 1 > tol_rho
    if not unstable.any():
        return math.nan, None, float(q[int(np.argmax(rho))])
    qc = float(q[unstable].max())
    above = ~unstable & (q > qc)
    return qc, float(q[above].min()) if above.any() else None, float(q[int(np.argmax(rho))])


def unstable_intervals(z, key="rho"):
    """{q: [(A_from, A_to), ...]} the intervals of A where the chain of ``key`` (``rho``: N beads, ``rho_inf``: the
    infinite chain) is unstable, between its located edges (the located points' A, the midpoints of their
    brackets), read together with the verdicts at the map's amplitudes and at the uncompressed limit (A = inf, the
    last verdict of the walk when the map has it): from 0 when the smallest map amplitude is unstable before the
    first edge, to inf when the verdict stays unstable up to the limit (without a limit record: up to the largest
    map amplitude); nan where an edge was not located (an onset after an onset, an offset after an offset, a map
    amplitude or the limit whose verdict contradicts the last located edge: the family stepped into a window the
    edges do not show, or the verdict changes beyond the largest map amplitude) and at an edge whose location
    failed (``located`` 0: bracketed only)."""
    tol = float(z["tol_rho"])
    kind, q, A = np.asarray(z["kind"]), np.asarray(z["q"], float), np.asarray(z["A"], float)
    rho = np.asarray(z[key], float)
    edge = KIND_EDGE if key == "rho" else KIND_EDGE_INF
    onset_of = np.asarray(z["A_unstable"], float) > np.asarray(z["A_stable"], float)
    # an edge's end of an interval: its A, nan where its location failed (files before the field: all located)
    end = np.where(np.asarray(z["located"]) == 0, math.nan, A) if "located" in z else A
    out = {}
    for qq in sorted(set(q[(kind == KIND_POINT) & np.isfinite(rho)].tolist())):
        pts = np.nonzero(((kind == KIND_POINT) | (kind == KIND_LIMIT)) & (q == qq) & np.isfinite(rho))[0]
        mine = np.nonzero((kind == edge) & (q == qq))[0]
        # the walk in A: points (their verdicts, the limit's at A = inf last) and edges; at equal A the point first
        walk = sorted([(float(A[i]) if kind[i] == KIND_POINT else math.inf, 0, i) for i in pts]
                      + [(float(A[i]), 1, i) for i in mine])
        start, spans, seen = None, [], False
        for a, is_edge, i in walk:
            if not is_edge:
                unstable = rho[i] - 1 > tol
                if unstable and start is None:
                    start = 0.0 if not seen else math.nan      # an onset before it was not located
                elif not unstable and start is not None:
                    spans.append((start, math.nan))             # an offset before it was not located
                    start = None
                seen = True
            elif onset_of[i]:
                if start is not None:                           # unstable already: an offset between was not located
                    spans.append((start, math.nan))
                start, seen = float(end[i]), True
            else:                                               # stable before: nan, an onset between was not located
                spans.append((math.nan if start is None else start, float(end[i])))
                start, seen = None, True
        if start is not None:                  # up to the uncompressed limit only if the last verdict is unstable
            last = next(i for a, is_edge, i in reversed(walk) if not is_edge)
            spans.append((start, math.inf if rho[last] - 1 > tol or A[last] < start else math.nan))
        out[qq] = spans
    return out
