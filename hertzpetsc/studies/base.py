"""The study protocol: what every study of :mod:`hertzpetsc.studies` declares and does (defcon's
BifurcationProblem shape: one documented base class whose hooks have a default or raise NotImplementedError).

A study is a loop over parameters whose records are written as they are computed. It declares, once:

* ``Parameters``: a frozen dataclass validated when built, each parameter declared once in its field
  (:func:`hertzpetsc.errors.param`, :class:`~hertzpetsc.errors.Checked`), which drivers read as their options
  (:meth:`hertzpetsc.options.AppOptions.parameters`): errors name ``-option`` on the command line, ``field`` in the
  API;
* ``FORMAT``, ``FIELDS`` (and ``DTYPES``, ``SHAPES``): the record kind and the per-record fields, which the record
  store, the file schema and the identity checks read;
* ``ROLES``: the solver roles it configures, from the registry (:func:`hertzpetsc.roles.uses`);
  drivers hand them to :class:`~hertzpetsc.options.AppOptions` (``-help`` lists them; unknown options are
  matched against them).

It is built from its parameters, a communicator, and an output path: a record file (:class:`NpzRecords`,
``mode`` new/resume/force) or, with ``output=None``, an in-memory store (:class:`MemoryRecords`), so every study
runs from a notebook. :meth:`Study.run` yields each record after saving it; :meth:`Study.arrays` gives the records
as numpy arrays (the file's content) and :meth:`Study.table` the Markdown table. :class:`ContinuedScan`: the
studies whose points are continued per alpha, a round of steps at a time.
"""
from __future__ import annotations

import os
from dataclasses import fields, is_dataclass
from typing import TYPE_CHECKING, Any, Callable, Iterator, Optional

from petsc4py import PETSc

from ..dealing import dealt
from ..errors import HertzPetscError, ParameterError, check_choice, check_instance
from ..progress import Progress
from ..records import MODES, MemoryRecords, NpzRecords, given, input_digests, pending, provenance, write_text
from ..roles import configure

if TYPE_CHECKING:
    import numpy as np

class Study:
    """Base class of the studies (module docstring)."""

    Parameters = None
    FORMAT = None
    FIELDS = ()
    DTYPES = {}
    SHAPES = {}
    ROLES = {}
    WHAT = "record file"
    LABELS = ()                # constants that are not part of the identity (file names, notes)
    ADDED = {}                 # {field: value} of fields added after files were written (NpzRecords ``added``)
    NAMES = {}                 # {identity key: "parameter (-option)"} where the key is not the parameter's name
    COLUMNS = None             # the record kind's columns (records.Kind): units and meanings in the file
    store = None

    def __init__(self, params: Any, comm: Optional[PETSc.Comm] = None, output: Optional[str] = None,
                 mode: str = "new") -> None:
        if self.Parameters is not None and not isinstance(params, self.Parameters):
            raise ParameterError("params", type(params).__name__, f"must be {self.Parameters.__name__}(...)")
        check_choice("mode", mode, MODES)
        if output is not None:
            check_instance("output", output, (str, os.PathLike), "a path (None: the records in memory)")
        self.params = params
        self.comm = comm if comm is not None else PETSc.COMM_WORLD
        self.output, self.mode = output, mode
        if output is not None:
            pending(self)

    # --- what identifies the records -------------------------------------------------------------------------
    def constants(self) -> dict:
        """Arrays written once per file; by default the parameters (plain data)."""
        return plain(self.params)

    def inputs(self) -> dict[str, str]:
        """{name: path} of the files the records are computed from (none by default): their content hashes
        (``<name>_sha256``) are part of the identity."""
        return {}

    def identity(self) -> dict:
        """What a resumed file must agree with (a difference is named): by default the constants but the
        ``LABELS``, the options given under the study's solver roles that change numbers, and the content hashes of
        the input files."""
        out = {k: v for k, v in self.constants().items() if k not in self.LABELS}
        # an input path that names no file (e.g. the label of a branch computed in memory) has no hash
        out.update({f"{name}_sha256": d["sha256"] for name, d in self.digests().items()},
                   solver_options=solver_options(self.ROLES))
        return out

    def digests(self) -> dict:
        """:func:`~hertzpetsc.records.input_digests` of :meth:`inputs`, read once (collective)."""
        if getattr(self, "_digests", None) is None:
            self._digests = input_digests(self.inputs(), self.comm)
        return self._digests

    def call(self) -> str:
        """The call that built the study, as the file's provenance records it."""
        return f"{type(self).__module__}.{type(self).__name__}({self.params!r}, output={self.output!r}, " \
               f"mode={self.mode!r})"

    def open(self) -> Study:
        """Open the record store once (collective)."""
        if self.store is None:
            self.store = self._open()
        return self

    def check_open(self) -> None:
        """Open the record file as a run would, unless it is open: within :func:`hertzpetsc.records.checking` (a
        driver's ``-check``, :func:`hertzpetsc.records.check_stores`) only to check it."""
        if self.store is None and self.output is not None:
            self._open()

    def _open(self):
        """The record store: the file of ``output`` in ``mode`` (constants and identity), or memory."""
        if self.output is None:
            return MemoryRecords(self.FORMAT, self.constants(), self.FIELDS, self.comm, self.DTYPES, self.SHAPES,
                                 self.COLUMNS)
        identity = self.identity()
        about = provenance(call=self.call(), comm=self.comm, digests=self.digests())
        return NpzRecords(self.output, self.FORMAT, dict(self.constants(), **identity), identity, self.FIELDS,
                          self.comm, self.mode, self.DTYPES, self.SHAPES, self.WHAT, self.ADDED, self.names(),
                          about, self.COLUMNS)

    def names(self) -> dict:
        """How the user sets each identity key whose name is not a parameter's (:func:`check_identity`): ``NAMES``,
        the input files (by the option each was given as) and the solver options of the roles."""
        out = {f"{name}_sha256": f"the content of the input file {given(path)}" for name, path in self.inputs().items()
               if path}
        if self.ROLES:
            out["solver_options"] = "the options " + ", ".join(f"-{p}*" for p in self.ROLES)
        return dict(out, **self.NAMES)

    def _todo(self, qs):
        """The wavenumbers of ``qs`` that the store holds no record of yet (to 12 decimals)."""
        done = {round(float(r["q"]), 12) for r in self.store.records}
        return [q for q in qs if round(q, 12) not in done]

    @property
    def records(self) -> list[dict]:
        """The records computed so far (a list of dicts, one per record)."""
        return self.open().store.records

    def arrays(self) -> dict[str, np.ndarray]:
        """The records as numpy arrays, as the file holds them (``format``, constants, one array per field)."""
        return self.open().store.arrays()

    # --- the hooks ---------------------------------------------------------------------------------------------
    def run(self) -> Iterator[dict]:
        """Compute what the store does not hold yet; yield each new record after saving it."""
        raise NotImplementedError

    def table(self) -> str:
        """The Markdown table of the records."""
        raise NotImplementedError

    def run_to_table(self, path: str, show: Optional[Callable[[Any], None]] = None,
                     text: Optional[Callable[[], str]] = None) -> str:
        """:func:`run_to_table` of this study."""
        return run_to_table(self, path, show, text)

    def configure(self) -> None:
        """Read and check the options of every solver role now, so that a bad value fails before any computation
        (:func:`hertzpetsc.roles.configure`)."""
        configure(self.ROLES, self.comm)

    def destroy(self) -> None:
        """Free the PETSc objects the study holds (none by default)."""

    def planned(self) -> Optional[int]:
        """How many records :meth:`run` will yield from now, where that is known in advance (None: not known); the
        drivers' progress line (:func:`run_to_table`) estimates the time left from it."""
        return None


def run_to_table(study, path, show=None, text=None):
    """Run ``study`` (anything with ``run()``, ``comm`` and ``table()``; ``show(item)`` for each item it yields),
    then write ``text()`` (default ``study.table()``) to ``path`` and return it; a study that knows the records it
    will yield (``planned()``) shows the time left on a terminal (:class:`~hertzpetsc.progress.Progress`). If an error stops it (a solver that
    did not converge, PETSc refusing), the table of what was done with the error below it is written first (a
    table that needs the whole run says why there is none) and the error re-raised: the table on disk never
    describes another run than the record file's (one that could not be opened is left alone). Collective."""
    text = text or study.table
    planned = getattr(study, "planned", lambda: None)()
    progress = Progress(planned, "records", type(study).__name__, comm=study.comm) if planned else None
    try:
        for done, item in enumerate(study.run(), 1):
            if show is not None:
                show(item)
            if progress is not None:
                progress.update(done)          # on a terminal: the time left, now and then
    except HertzPetscError as err:
        if getattr(study, "output", None) is None or study.store is not None:
            try:
                done = text()
            except HertzPetscError as why:
                done = f"No table: {why}\n"
            write_text(path, done + f"\nStopped before the end: {err}\n", study.comm)
        raise
    out = text()
    write_text(path, out, study.comm)
    return out


def plain(params):
    """A parameters dataclass as plain data (numbers, strings, lists; nested models by their describe())."""
    if not is_dataclass(params):
        return dict(params)
    out = {}
    for f in fields(params):
        v = getattr(params, f.name)
        if hasattr(v, "describe"):
            out.update(v.describe())
        elif isinstance(v, (tuple, list)):
            out[f.name] = list(v)
        elif v is not None:
            out[f.name] = v
    return out


# options that do not change numbers (what is printed or logged, not what is computed)
_NON_NUMERIC = ("monitor", "view", "converged_reason", "log", "help", "draw")


def solver_options(prefixes):
    """The options given under the solver prefixes that can change a result (tolerances, types, sizes; monitors
    and views left out), as one sorted ``name=value`` string: part of a record file's identity, so that a resume
    with other solver settings is refused, naming them."""
    items = sorted((k, v) for k, v in PETSc.Options().getAll().items()
                   if k.startswith(tuple(prefixes)) and not any(w in k for w in _NON_NUMERIC))
    return " ".join(f"{k}={v}" for k, v in items)


def point_key(alpha, value):
    """(alpha, value) rounded: the key of a point of a :class:`ContinuedScan` in its records."""
    return (round(float(alpha), 10), round(float(value), 12))


class ContinuedScan(Study):
    """Points continued per alpha through ``self.sequences`` ({alpha: the values of :attr:`PARAMETER` in computing
    order}): round i computes the i-th point of every alpha not in the file from the records of the preceding ones,
    each point on one rank and the alphas of a round dealt to the ranks, so the records do not depend on their
    number."""

    PARAMETER = "q"

    def cost(self, value: float) -> float:
        """The relative cost of the point at ``value`` (for dealing)."""
        return 1.0

    def run(self) -> Iterator[dict]:
        """Compute every (alpha, value) not in the file, by continuation steps; yields each record after saving it."""
        self.open()
        done = {point_key(r["alpha"], r[self.PARAMETER]) for r in self.store.records}
        for i in range(max(len(s) for s in self.sequences.values())):
            items = [(a, i) for a, s in self.sequences.items() if i < len(s) and point_key(a, s[i]) not in done]
            for _, row in dealt(items, [self.cost(self.sequences[a][i]) for a, _ in items], self.comm, self.compute):
                yield self.store.append(row)

    def preceding(self, alpha: float, i: int) -> list[dict]:
        """The records of the (up to two) points of ``alpha`` before its i-th."""
        known = {point_key(r["alpha"], r[self.PARAMETER]): r for r in self.store.records}
        return [known[point_key(alpha, v)] for v in self.sequences[alpha][max(0, i - 2):i]]

    def by_alpha(self) -> Iterator[tuple[float, list[dict]]]:
        """(alpha, its rows in table order) for every alpha of the file, by increasing alpha."""
        for a in sorted({float(r["alpha"]) for r in self.records}):
            yield a, [r for r in self.rows() if float(r["alpha"]) == a]
