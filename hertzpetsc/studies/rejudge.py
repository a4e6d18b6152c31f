"""The weak infinite-chain verdicts of a published map file judged again on the refined cell orbit (issue 37).

A stability map (:class:`~hertzpetsc.studies.maps.StabilityMap`, also the boundary near pi/2) or a boundary in q
(:class:`~hertzpetsc.studies.maps.QBoundary`) written before the weak verdicts were refined holds infinite-chain
records with tol_rho < rho_inf - 1 < :data:`~hertzpetsc.studies.maps.NEAR_ONE` judged on the Richardson cell orbit,
whose error splits the zones' translations off the unit circle. Each such record (``E_cell`` absent or nan) is
judged again with the file's own parameters by the maps' one route (:meth:`MapProbe.infinite
<hertzpetsc.studies.maps.MapProbe.infinite>` with ``refine_all``): the wave at the record's q and amplitude (a map's
a, the first sine coefficient, reached by the amplitude family; a boundary's A = ||u||_inf, by
:func:`~hertzpetsc.families.wave_at`), its Richardson combination, the twist scan of its cell orbit (the old
record's twist among the hints), then the cell orbit refined by Gauss-Newton to E <= REFINE_TOL and scanned again
with the flow at FINE_FLOW times the file's tolerances. A boundary's edge record (kind 2) is judged at its unstable
end q_unstable. The uncompressed limit's records (A = inf) are not re-judged: they are counted in the table.

Record file (npz, kind ``hertzpetsc-map-rejudging-1``, docs/schemas.md): one record per re-judged record of the
source file (``index``), computed per q on one rank (the q are dealt to the ranks); the source's content hash is in
the identity and the provenance.
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass
from typing import Iterator, Optional

import numpy as np
from petsc4py import PETSc

from ..chain import IntegrationTolerances
from ..errors import ParameterError, RecordFileError, check_instance
from ..families import AmplitudeFamily, wave_at
from ..grid import ProfileGrid
from ..model import LatticeModel
from ..records import given, load_npz, on_rank0
from ..resources import check_memory
from ..twsolver import tw_solver
from ..verdicts import KIND_EDGE, KIND_EDGE_INF, KIND_LIMIT, KIND_POINT
from .base import Study
from .floquet import q_label
from .maps import (CERT_NONE, CERT_STABLE, CERT_UNRESOLVED, MAP_FORMAT, MAP_FORMAT_V2, NEAR_ONE, PRECOMP_PREFIX,
                   QMAP_FORMAT, QMAP_FORMAT_V1, REFINE_TOL, MapProbe, StabilityMap, saved_as_dealt, wave_cell)

REJUDGE_FORMAT = "hertzpetsc-map-rejudging-1"
REJUDGE_FIELDS = ("index", "side", "kind", "q", "a", "A", "omega", "rho_old", "theta_old", "rho_unrefined", "rho_new",
                  "theta_new", "cert_new", "bound_new", "modulation_new", "E_cell", "M", "seconds")
# the source kinds whose records carry an infinite-chain verdict at their own (q, a): a map's points and edges; a
# boundary in q's evaluations and edges (judged at q_unstable)
MAPS = (MAP_FORMAT, MAP_FORMAT_V2)
BOUNDARIES = (QMAP_FORMAT, QMAP_FORMAT_V1)
JUDGED_KINDS = (KIND_POINT, KIND_EDGE, KIND_EDGE_INF)


@dataclass(frozen=True)
class RejudgeParameters:
    """The file whose weak infinite-chain records are judged again: ``source``, a stability-map file (kind -3 or
    -2) or a boundary-in-q file (-2 or -1)."""

    source: str

    def __post_init__(self):
        check_instance("source", self.source, (str, os.PathLike), "the path of a stability-map or boundary-in-q file")
        object.__setattr__(self, "source", os.fspath(self.source))


def weak_records(z):
    """([(index, side)] of the verdicts of the arrays ``z`` to judge again, indices of the weak limit records left):
    the infinite-chain verdicts with tol_rho < rho - 1 < NEAR_ONE judged without the refinement: a record's own
    (side 0: ``rho_inf``, no ``E_cell`` or nan) and, in a map written before ``E_cell`` (whose every weak evaluation
    was unrefined), the unstable end of an infinite-chain edge whose record is its stable end (side 1:
    ``rho_unstable`` at ``a_unstable``)."""
    tol = float(z["tol_rho"])
    excess = np.asarray(z["rho_inf"], float) - 1
    refined = np.isfinite(np.asarray(z["E_cell"], float)) if "E_cell" in z else np.zeros(len(excess), bool)
    kind = np.asarray(z["kind"])
    weak = (excess > tol) & (excess < NEAR_ONE) & ~refined & np.isin(kind, JUDGED_KINDS + (KIND_LIMIT,))
    level = np.asarray(z["A"] if "grid" in z else z["a"], float)
    limit = (kind == KIND_LIMIT) | ~np.isfinite(level)
    out = [(int(i), 0) for i in np.nonzero(weak & ~limit)[0]]
    if "grid" not in z and "E_cell" not in z:
        ru, au, a = (np.asarray(z[k], float) for k in ("rho_unstable", "a_unstable", "a"))
        side = (kind == KIND_EDGE_INF) & (ru > tol) & (ru < NEAR_ONE) & (np.abs(au - a) > 1e-12 * a)
        out += [(int(i), 1) for i in np.nonzero(side)[0]]
    return sorted(out), np.nonzero(weak & limit)[0]


class MapRejudging(Study):
    """The weak infinite-chain verdicts of a map or boundary file judged again on the refined cell orbit (module
    docstring). Prefixes as the map's: ``precomp_``, ``floquet_``, ``shoot_``, ``shoot_jac_``."""

    Parameters = RejudgeParameters
    FORMAT, FIELDS = REJUDGE_FORMAT, REJUDGE_FIELDS
    DTYPES = {"index": np.int64, "side": np.int64, "kind": np.int64, "cert_new": np.int64, "M": np.int64}
    ROLES = StabilityMap.ROLES
    WHAT = "re-judging file"
    LABELS = ("source",)
    NAMES = dict(source_sha256="the content of the source file (-source)")
    locate = ("infinite",)
    route, destroy = StabilityMap.route, StabilityMap.destroy

    def __init__(self, params: RejudgeParameters, comm: Optional[PETSc.Comm] = None, output: Optional[str] = None,
                 mode: str = "new") -> None:
        super().__init__(params, comm, output, mode)
        z = on_rank0(self.comm, lambda: load_npz(params.source, "source file"), what="source file")
        kind = str(z.get("format", ""))
        if kind not in MAPS + BOUNDARIES:
            found = f"a {kind!r} file" if kind else "not a hertzpetsc record file"
            raise RecordFileError(f"source file {given(params.source)} is {found}, but a stability map "
                                  f"({', '.join(MAPS)}) or a boundary in q ({', '.join(BOUNDARIES)}) is expected here")
        if int(z["twists"]) <= 0:
            raise ParameterError("source", params.source, "a map with an infinite chain (twists > 0)")
        self.z, self.kind, self.boundary = z, kind, kind in BOUNDARIES
        self.model = LatticeModel.hertz(float(z["alpha"]), tuple(float(m) for m in np.atleast_1d(z["masses"])),
                                        float(z["delta0"]))
        rtol = float(z["rtol"])
        self.K, self.tolerances = int(z["cells_per_pi"]), IntegrationTolerances(rtol=rtol, atol=rtol / 100)
        self.tol_rho, self.twists = float(z["tol_rho"]), int(z["twists"])
        self.N = 0 if self.boundary else int(z["N"])
        self.todo, self.limits = weak_records(z)
        check_memory(2 * self.K, PETSc.COMM_SELF, tw_solver(PRECOMP_PREFIX), profiles=self.model.cell)
        self._routes = {}

    def constants(self) -> dict:
        return dict(source=self.params.source, source_format=self.kind, alpha=self.model.alpha,
                    delta0=self.model.delta0, masses=list(self.model.masses), N=self.N, cells_per_pi=self.K,
                    rtol=self.tolerances.rtol, tol_rho=self.tol_rho, twists=self.twists, near_one=NEAR_ONE,
                    refine_tol=REFINE_TOL, weak=len(self.todo), limits_left=len(self.limits))

    def inputs(self) -> dict:
        return {"source": self.params.source}

    def point(self, item: tuple) -> tuple[float, float]:
        """(q, amplitude) where the verdict ``item`` = (index, side) of the source is judged: a map's (q, a) (side 1:
        a_unstable), a boundary's (q, A) (an edge's unstable end)."""
        z, (i, side) = self.z, item
        if self.boundary:
            q = float(z["q_unstable"][i]) if int(z["kind"][i]) == KIND_EDGE_INF else float(z["q"][i])
            return q, float(z["A"][i])
        return float(z["q"][i]), float(z["a_unstable" if side else "a"][i])

    def old(self, item: tuple) -> tuple[float, float]:
        """(rho, twist) of the verdict ``item`` in the source."""
        z, (i, side) = self.z, item
        if side:
            return 1 + float(z["rho_unstable"][i]), float(z["theta_unstable"][i])
        return float(z["rho_inf"][i]), float(z["theta_inf"][i])

    def jobs(self) -> list[float]:
        """The wavenumbers of the records to judge, each once (to 1e-12)."""
        out = []
        for item in self.todo:
            q = self.point(item)[0]
            if not any(abs(q - x) <= 1e-12 * q for x in out):
                out.append(q)
        return sorted(out)

    def compute(self, q: float) -> list[dict]:
        """The records of the source at q judged again (on this rank), by increasing amplitude."""
        z = self.z
        mine = sorted((item for item in self.todo if abs(self.point(item)[0] - q) <= 1e-12 * q),
                      key=lambda item: self.point(item)[1])
        grid = ProfileGrid(self.K, PETSc.COMM_SELF)
        probe = MapProbe(self, q, measure="sup" if self.boundary else "a1", refine_all=True)
        family = None if self.boundary else AmplitudeFamily(self.model, q, grid)
        judged, rows = {}, []
        try:
            for item in mine:
                t0 = time.perf_counter()
                (i, side), amplitude = item, self.point(item)[1]
                rho_old, theta_old = self.old(item)
                key = round(amplitude, 12)
                if key not in judged:
                    point = wave_at(self.model, q, amplitude, grid) if self.boundary else family.step_to(amplitude)
                    entry = probe.entry(point)
                    probe.hints = [theta_old]                       # the twist of the old verdict
                    judged[key] = (probe.wave(entry), probe.infinite(entry))
                e, scan = judged[key]
                rows.append(dict(index=i, side=side, kind=int(z["kind"][i]), q=q,
                                 a=math.nan if self.boundary else e["point"].a, A=e["A"],
                                 omega=e.get("omega", math.nan), rho_old=rho_old, theta_old=theta_old,
                                 rho_unrefined=scan["unrefined"],
                                 rho_new=scan["rho"], theta_new=scan["theta"], cert_new=scan["cert"],
                                 bound_new=scan["bound"], modulation_new=scan["modulation"], E_cell=scan["E"],
                                 M=scan["M"], seconds=time.perf_counter() - t0))
        finally:
            if family is not None:
                family.destroy()
            probe.destroy()
        return rows

    def cost(self, q: float) -> float:
        M = wave_cell(q, self.model.cell).M
        return 1.0 + math.ceil(self.twists / M) * (M / 20) ** 3

    def _left(self):
        done = {(int(r["index"]), int(r["side"])) for r in self.store.records}
        return [item for item in self.todo if item not in done]

    def planned(self) -> Optional[int]:
        return len(self._left()) if self.store is not None else len(self.todo)

    def run(self) -> Iterator[dict]:
        """Judge every record of the source not in the file yet (a q in progress is judged again: its records are
        the same); yields each new record after saving it."""
        self.open()
        left = {self.point(i)[0] for i in self._left()}
        todo = [q for q in self.jobs() if any(abs(q - x) <= 1e-12 * q for x in left)]
        yield from saved_as_dealt(self, todo, [self.cost(q) for q in todo],
                                  lambda r: (int(r["index"]), int(r["side"])),
                                  lambda r, q: abs(float(r["q"]) - q) <= 1e-12 * q)

    def table(self) -> str:
        return rejudging_table(self.arrays())


def verdict(excess, cert, tol):
    """The infinite chain's verdict of rho - 1 = ``excess`` and its certification code."""
    if not math.isfinite(excess):
        return "no verdict"
    if excess > tol:
        return "unstable"
    return {CERT_STABLE: "stable (certified)", CERT_UNRESOLVED: "unresolved", CERT_NONE: "stable (samples)"}.get(
        int(cert), "stable (samples)")


SOURCE_KINDS = {KIND_POINT: "point", KIND_EDGE: "edge (N)", KIND_EDGE_INF: "edge (inf)"}


def rejudging_table(z) -> str:
    """The Markdown table of a re-judging file's arrays: per re-judged record of the source, the old and new rho - 1
    and verdicts, and a summary line."""
    tol = float(z["tol_rho"])
    n = len(np.asarray(z["index"]))
    old, new = np.asarray(z["rho_old"], float) - 1, np.asarray(z["rho_new"], float) - 1
    changed = [i for i in range(n) if not new[i] > tol]          # every source record here was unstable
    kept = [i for i in range(n) if new[i] > tol]
    diff = np.abs(new - old)
    source = str(z["source"])
    lines = [f"schema: {REJUDGE_FORMAT}; the weak infinite-chain verdicts (tol_rho = {tol:g} < rho - 1 < NEAR_ONE = "
             f"{float(z['near_one']):g}, judged on the Richardson cell orbit) of `{os.path.basename(source)}` "
             f"({str(z['source_format'])}; alpha = {float(z['alpha']):g}, delta0 = {float(z['delta0']):g}, masses "
             f"{', '.join(f'{m:g}' for m in np.atleast_1d(z['masses']))}) judged again with its parameters (waves: "
             f"Richardson of h = pi/{int(z['cells_per_pi'])} and pi/{2 * int(z['cells_per_pi'])}; twists "
             f"{int(z['twists'])} per pi) on the cell orbit refined by Gauss-Newton to E <= "
             f"{float(z['refine_tol']):g} (column E_cell) and scanned again with the flow at rtol "
             f"{float(z['rtol']) / 100:g} (the file's {float(z['rtol']):g} / 100).\n",
             f"{n} verdicts judged again; {len(changed)} changed (unstable before, stable or unresolved now)"
             + (": " + ", ".join(f"{q_label(float(z['q'][i]))} at A = {float(z['A'][i]):.6g}" for i in changed)
                if changed else "")
             + (f"; max |new - old| of rho - 1: {float(np.max(diff)):.2e}" if n else "; none to judge" if not int(z["weak"]) else "")
             + (f"; the {len(kept)} unchanged: rho - 1 within {float(np.max(diff[kept] / old[kept])):.1e} relative of "
                f"the source's (the old twist among the hints, the scan's maxima refined again)" if kept else "")
             + (f"; {int(z['limits_left'])} weak records of the uncompressed limit not judged again"
                if int(z["limits_left"]) else "")
             + (f"; {int(z['weak']) - n} of the source's {int(z['weak'])} weak verdicts not judged yet (the run "
                f"stopped before them: -resume continues it)" if n < int(z["weak"]) else "") + ".\n",
             "Columns: the source's record (index; 'unstable end': the unstable end of an infinite-chain edge whose "
             "record is its stable end, rho_unstable at a_unstable; kind), q, A = ||u||_inf, a (first sine "
             "coefficient), rho - 1 in the source, rho - 1 of the Richardson cell orbit recomputed now (unrefined: "
             "the source's number reproduced), rho - 1 on the refined cell orbit, the cell twist Theta of its "
             "largest multiplier, E_cell, the verdicts (unstable when rho - 1 > tol_rho; a stable verdict certified "
             "between the twist samples or unresolved) and the longest modulation (beads) the new scan covers.\n",
             "| index | kind | q | A | a | old rho - 1 | unrefined rho - 1 | new rho - 1 | Theta | E_cell "
             "| old verdict | new verdict | modulations (beads) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for i in np.lexsort((np.asarray(z["a"], float), np.asarray(z["q"], float))):
        end = " (unstable end)" if int(z["side"][i]) else ""
        lines.append(f"| {int(z['index'][i])}{end} | {SOURCE_KINDS.get(int(z['kind'][i]), str(int(z['kind'][i])))} | "
                     f"{q_label(float(z['q'][i]))} ({float(z['q'][i]):.6f}) | {float(z['A'][i]):.6g} | "
                     f"{float(z['a'][i]):.6g} | {old[i]:.2e} | {float(z['rho_unrefined'][i]) - 1:.2e} | "
                     f"{new[i]:.2e} | {float(z['theta_new'][i]):.4f} | {float(z['E_cell'][i]):.1e} | unstable | "
                     f"{verdict(new[i], z['cert_new'][i], tol)} | {float(z['modulation_new'][i]):.4g} |")
    return "\n".join(lines) + "\n"
