"""The record store: what a study computes, written as it goes, by rank 0, atomically, and resumable.

Every study that writes as it goes (the branch, the refinement and Floquet scans, the small-q levels, the Bloch
tables, the long runs' snapshots, the benchmarks) keeps its results in one :class:`RecordStore`:

* an **identity**: which computation the file holds (its kind and the parameters that define it). Resuming a
  file whose identity differs is refused, naming the first parameter that differs;
* **records**, appended one at a time. :meth:`RecordStore.append` is collective: rank 0 writes, and every rank
  learns whether that worked, so a failed write ends every rank with the same error;
* a **mode**: ``new`` refuses to overwrite an existing file (the user asks for ``resume`` or ``force``),
  ``resume`` returns the finished records, ``force`` starts afresh.

Two layouts: :class:`NpzRecords` (one numpy archive rewritten through a temporary file and a rename after each
record: the branch file of the README and the other per-point files) and :class:`AppendRecords` (a JSON header
and a file of fixed-length float64 records appended and flushed one by one: long runs, whose snapshots would make
a rewrite quadratic). A killed run leaves the last complete file (npz) or a partial trailing record that the next
resume drops (append); stale temporary files of a killed write are removed when the store is opened. Within
:func:`checking` (a driver's ``-check``) a store is opened only to check it: the mode against the file, its kind and
identity on a resume; nothing is created, removed or written.

Tables, figures and summaries are written by :func:`write_text` / :func:`save_figure` / :func:`write_json`
(temporary file and rename, rank 0, the verdict shared). Reading needs numpy only; a communicator, when given, is a
petsc4py or mpi4py communicator.
"""
import contextlib
import glob
import itertools
import json
import os
import weakref
import zipfile
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import HertzPetscError, ParameterError, RecordFileError

MODES = ("new", "resume", "force")
_CHECKING = []          # non-empty within checking(): stores are opened to be checked, never written
_GIVEN = {}             # {path: "-option"}: the paths given on the command line (name_path, given)
_PENDING = weakref.WeakKeyDictionary()    # {owner: order}: what would open a record file when run (check_stores)
_ORDER = itertools.count()


def name_path(option, value):
    """Remember that ``value`` (a path, or a comma-separated list of paths, each maybe followed by ``:...``) was
    given as ``option``: the errors about those files then name it (AppOptions.path calls this; ``option`` None:
    forget every path, for a new command line)."""
    if option is None:
        _GIVEN.clear()
        return
    for part in str(value).split(","):
        for path in {part.strip(), part.split(":")[0].strip()}:
            if path:
                _GIVEN.setdefault(path, option)


def given(path):
    """``path`` quoted, and the option it was given as, if it was given on the command line."""
    option = _GIVEN.get(str(path))
    return f"{str(path)!r}" + (f" ({option})" if option else "")


def is_checking():
    """True within :func:`checking`."""
    return bool(_CHECKING)


@contextlib.contextmanager
def checking():
    """Open record stores within this block only to check them (-check): nothing is created or written."""
    _CHECKING.append(True)
    try:
        yield
    finally:
        _CHECKING.pop()


def pending(owner) -> None:
    """Note that ``owner`` (a study: ``check_open()`` opens its record file unless it is open) opens a record file
    when it runs, for :func:`check_stores`."""
    _PENDING[owner] = next(_ORDER)


def check_stores() -> None:
    """Open the record file of every owner noted by :func:`pending` (the studies built so far), in the order they
    were built, as a run would, but only to check it (within :func:`checking`): an existing file without resume or
    force, a missing one to resume, one of another kind or computation is refused here (a driver's ``-check``);
    nothing is written. Collective."""
    with checking():
        for owner in sorted(list(_PENDING.keys()), key=_PENDING.get):
            owner.check_open()


# --- collective helpers -------------------------------------------------------------------------------------------
def mpi_comm(comm):
    """An mpi4py communicator for ``comm`` (petsc4py or mpi4py), or None for a serial run."""
    if comm is None:
        return None
    if hasattr(comm, "tompi4py"):
        comm = comm.tompi4py()
    return comm if comm.Get_size() > 1 else None


def _sent(err):
    """A package error as (class, message, attributes), to be sent to the other ranks and raised there by
    :func:`_rebuild` (a ParameterError keeps the name an error line turns into the option)."""
    return type(err), str(err), dict(vars(err))


def _rebuild(kind, message, attributes=None):
    err = kind.__new__(kind)
    err.args = (message,)
    err.__dict__.update(attributes or {})
    return err


def on_rank0(comm, fn, *args, what="file operation"):
    """Run ``fn(*args)`` on rank 0 only; return its result on every rank, or raise its error on every rank.

    OS errors become :class:`RecordFileError` naming ``what``; package errors keep their class and message.
    """
    mpi = mpi_comm(comm)
    result = error = None
    if mpi is None or mpi.Get_rank() == 0:
        try:
            result = fn(*args)
        except HertzPetscError as err:
            error = _sent(err)
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as err:
            error = (RecordFileError, f"{what}: {err}")
    if mpi is not None:
        result, error = mpi.bcast((result, error), root=0)
    if error is not None:
        raise _rebuild(*error) from None
    return result


def _replace_atomically(path, write):
    """Call ``write(file)`` on ``path.tmp`` (reused by the next write if this one is killed), fsync, rename. A path
    that exists and is not a regular file or a directory (a device such as /dev/null, a pipe) is written in place:
    a rename would replace the device with a file (as root, /dev/null itself)."""
    if os.path.exists(path) and not os.path.isfile(path) and not os.path.isdir(path):
        with open(path, "wb") as f:
            write(f)
        return
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        write(f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def make_directory(path, what):
    """Create the directory of ``path`` (and its parents); RecordFileError naming ``what`` if that fails."""
    directory = os.path.dirname(os.path.abspath(path))
    try:
        os.makedirs(directory, exist_ok=True)
    except OSError as err:
        blocker = directory
        while blocker and not os.path.exists(blocker):
            blocker = os.path.dirname(blocker)
        why = f"{blocker!r} is not a directory" if os.path.exists(blocker) and not os.path.isdir(blocker) \
            else (err.strerror or str(err))
        raise RecordFileError(f"cannot write {what} {path!r}: {why}") from None
    return directory


def prepare_output(path, comm=None, what="output"):
    """Check, before any computation, that ``path`` can be written: its directory is created if missing and a
    probe file is written and removed there. Collective; :class:`RecordFileError` on every rank otherwise."""
    def probe():
        directory = make_directory(path, what)
        try:
            if os.path.isdir(path):
                raise RecordFileError(f"cannot write {what} {path!r}: it is a directory")
            test = os.path.join(directory, f".hz-write-test-{os.getpid()}")
            with open(test, "wb"):
                pass
            os.remove(test)
        except OSError as err:
            raise RecordFileError(f"cannot write {what} {path!r}: {err.strerror or err}") from None
    on_rank0(comm, probe, what=what)


def prepare_outputs(comm, *tables, figures=""):
    """:func:`prepare_output` for each table and, if ``figures`` is not empty, for the figures' directory."""
    for path in tables:
        prepare_output(path, comm, "table")
    if figures:
        prepare_output(os.path.join(figures, "figure.png"), comm, "figure in directory")


def write_text(path, text, comm=None, what="table"):
    """Write ``text`` to ``path`` atomically on rank 0 (collective; the error, if any, on every rank)."""
    def write():
        make_directory(path, what)
        _replace_atomically(path, lambda f: f.write(text.encode()))
    on_rank0(comm, write, what=f"cannot write {what} {path!r}")
    return path


def write_json(path, obj, comm=None, what="summary"):
    return write_text(path, json.dumps(obj, indent=1, default=float) + "\n", comm, what)


def save_figure(fig, path):
    """Save a matplotlib figure atomically (the format from the file name). Call on one rank."""
    make_directory(path, "figure")
    ext = os.path.splitext(path)[1].lstrip(".") or "png"
    try:
        _replace_atomically(path, lambda f: fig.savefig(f, format=ext, dpi=120))
    except OSError as err:
        raise RecordFileError(f"cannot write figure {path!r}: {err.strerror or err}") from None
    return path


def remove_stale_temporaries(path):
    """Delete ``path.tmp`` and ``path.tmp-<pid>`` files left by killed writes (this and older versions)."""
    for tmp in glob.glob(glob.escape(path) + ".tmp*"):
        try:
            os.remove(tmp)
        except OSError:
            pass


def _sha256(path):
    import hashlib
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def file_digest(path, comm=None, what="input file"):
    """sha256 of a file's content (rank 0 reads it; every rank gets the digest): an input's identity in the
    records made from it, so that a resume from another input is refused, naming it."""
    return on_rank0(comm, _sha256, path, what=f"cannot read {what} {path!r}")


def input_digests(inputs, comm=None):
    """{name: {"path", "sha256"}} of the input files ``{name: path}`` that exist (a path naming no file, e.g. the
    label of a branch computed in memory, has none), as rank 0 sees them: the one record of what a run read, in a
    study's identity (``<name>_sha256``) and in every file's :func:`provenance`. Collective."""
    def digests():
        return {name: dict(path=str(path), sha256=_sha256(path)) for name, path in (inputs or {}).items()
                if path and os.path.isfile(path)}
    return on_rank0(comm, digests, what=f"cannot read the input files {sorted((inputs or {}).values())}")


PROVENANCE = "__provenance__"      # the entry of every record file that says what made it (JSON)
COLUMNS = "__columns__"            # the entry that names each entry's unit and meaning (JSON, from a kind's columns)
ABOUT = (PROVENANCE, COLUMNS)      # entries about the file, not records or constants


def _git_commit(directory):
    """The commit checked out where ``directory`` lies (read from .git, no subprocess: a fork under MPI is not
    safe everywhere), or None outside a git work tree."""
    directory = os.path.abspath(directory)
    while not os.path.exists(os.path.join(directory, ".git")):
        if os.path.dirname(directory) == directory:
            return None
        directory = os.path.dirname(directory)
    try:
        git = os.path.join(directory, ".git")
        if os.path.isfile(git):                         # a worktree or submodule: "gitdir: <path>"
            with open(git) as f:
                git = os.path.join(directory, f.read().split("gitdir:", 1)[1].strip())
        common = git
        if os.path.isfile(os.path.join(git, "commondir")):
            with open(os.path.join(git, "commondir")) as f:
                common = os.path.join(git, f.read().strip())
        with open(os.path.join(git, "HEAD")) as f:
            head = f.read().strip()
        if not head.startswith("ref:"):
            return head
        ref = head.split(None, 1)[1]
        for base in (git, common):
            if os.path.isfile(os.path.join(base, ref)):
                with open(os.path.join(base, ref)) as f:
                    return f.read().strip()
        with open(os.path.join(common, "packed-refs")) as f:
            for line in f:
                if line.rstrip().endswith(" " + ref):
                    return line.split()[0]
    except (OSError, IndexError):
        pass
    return None


def _software():
    """Versions of the package's stack: the bindings always, the libraries (PETSc, SLEPc, MPI) where the run has
    started PETSc (nothing is initialised for this)."""
    import platform
    import sys
    out = dict(python=platform.python_version(), numpy=np.__version__)
    for name in ("petsc4py", "slepc4py", "mpi4py"):
        try:
            out[name] = __import__(name).__version__
        except ImportError:
            out[name] = None
    if "petsc4py.PETSc" in sys.modules:
        from petsc4py import PETSc
        out["petsc"] = ".".join(map(str, PETSc.Sys.getVersion()))
        try:
            from slepc4py import SLEPc
            out["slepc"] = ".".join(map(str, SLEPc.Sys.getVersion()))
        except ImportError:
            pass
        try:
            from mpi4py import MPI
            out["mpi"] = MPI.Get_library_version().splitlines()[0].split(",")[0].strip()
        except ImportError:
            pass
    return out


def provenance(inputs=None, call=None, comm=None, digests=None):
    """What made a file, written by the record store into every file it writes (``__provenance__``, JSON): the
    package's version and git commit (None outside a work tree), the command line (``argv``) and, for a study,
    the call that built it (``call``), the software versions (Python, numpy, PETSc, SLEPc, MPI and their bindings),
    the number of ranks of ``comm``, the date the run opened the file (UTC, ISO 8601) and the input files read
    ({name: {path, sha256}}: the ``inputs`` {name: path}, or their ``digests`` already computed by
    :func:`input_digests`). Collective unless ``digests`` are given (rank 0 reads the inputs)."""
    import datetime
    import sys
    from . import __version__
    mpi = mpi_comm(comm)
    return dict(hertzpetsc=__version__, commit=_git_commit(os.path.dirname(__file__)), argv=list(sys.argv),
                call=call, ranks=1 if mpi is None else mpi.Get_size(), **_software(),
                created=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                inputs=digests if digests is not None else input_digests(inputs, comm))


def file_provenance(data):
    """The provenance of a loaded record file (a dict of its arrays, or an AppendRecords header) as a dict, or None
    for a file written before provenance was recorded."""
    value = data.get(PROVENANCE, data.get("provenance"))
    if value is None:
        return None
    return json.loads(str(value)) if not isinstance(value, dict) else value


def resumed_provenance(new, old):
    """``new`` with the provenance of the runs that wrote the resumed file before (``earlier``, oldest first)."""
    if not old:
        return new
    earlier = list(old.get("earlier", [])) + [{k: v for k, v in old.items() if k != "earlier"}]
    return dict(new, earlier=earlier)


# --- record kinds declared once -----------------------------------------------------------------------------------
UNITS = {"1": "dimensionless: the scaled chain's units (unit mass, the law's scale; time as in eq. ad)",
         "s": "seconds of wall-clock time", "count": "a whole number", "": "a label or code (no unit)"}


@dataclass(frozen=True)
class Column:
    """One entry of a record kind: its ``name`` in the file, a one-line ``description``, its ``unit`` (a key of
    :data:`UNITS`), numpy ``dtype``, ``format`` (how a table shows a value), ``shape`` (beyond the record axis, as
    the schema page writes it: "(s,)", "(K+1,)") and whether it is a ``constant`` (once per file) or a field (one
    value per record). ``optional``: absent from some files (a label only some files have, a field added later)."""

    name: str
    description: str
    unit: str = "1"
    dtype: Any = float
    format: str = ".6g"
    shape: str = ""
    constant: bool = False
    optional: bool = False

    def __post_init__(self):
        if self.unit not in UNITS:
            raise ValueError(f"column {self.name!r}: unit {self.unit!r} is not one of {sorted(UNITS)}")


def digest_column(name: str, what: str, when: str = "") -> Column:
    """The constant column ``<name>_sha256``: the sha256 of the input file ``what`` (:func:`input_digests`), absent
    from files written before digests were recorded; ``when``: e.g. "when there is one"."""
    return Column(f"{name}_sha256", f"sha256 of the {what}'s content{', ' + when if when else ''} (absent from files "
                  "written before it)", "", str, "s", constant=True, optional=True)


# the number-changing options given under a study's solver prefixes (its identity's solver_options)
OPTIONS_COLUMN = Column("solver_options", "number-changing options under the study's prefixes (absent from files "
                        "written before it)", "", str, "s", constant=True, optional=True)


class Kind:
    """A record kind (``hertzpetsc-<kind>-<n>``) declared once: its columns drive the record store's fields and
    dtypes, the units and meanings written into each file (``__columns__``; HDF5 attributes ``units`` and
    ``description``), the rows of a table (:meth:`cell`) and the schema page's table (:meth:`schema`)."""

    def __init__(self, name, columns):
        self.name, self.columns = name, tuple(columns)
        names = [c.name for c in self.columns]
        if len(set(names)) != len(names):
            raise ValueError(f"kind {name}: a column declared twice")
        self.by_name = {c.name: c for c in self.columns}
        KINDS[name] = self

    @property
    def fields(self):
        """The per-record fields, in declaration order."""
        return tuple(c.name for c in self.columns if not c.constant)

    @property
    def dtypes(self):
        """{field: dtype} of the per-record fields that are not float64 (the record store's ``dtypes``)."""
        return {c.name: c.dtype for c in self.columns if c.dtype is not float and not c.constant}

    def about(self):
        """{name: {unit, description, dtype}} of every column: the file's ``__columns__``."""
        return {c.name: dict(unit=c.unit, description=c.description, dtype=np.dtype(c.dtype).str,
                             constant=c.constant) for c in self.columns}

    def cell(self, name, value):
        """``value`` of column ``name`` as a table shows it (its ``format``)."""
        return format(self.by_name[name].dtype(value) if self.by_name[name].dtype is not str else str(value),
                      self.by_name[name].format)

    def row(self, record, *cells):
        """A Markdown table row of ``record``: in each of ``cells`` (a string, or anything ``str`` writes) every
        ``{name}`` of a column is replaced by the record's value in the column's format (:meth:`cell`)."""
        import re

        def fill(m):
            return self.cell(m.group(1), record[m.group(1)]) if m.group(1) in self.by_name else m.group(0)
        return "| " + " | ".join(re.sub(r"\{(\w+)\}", fill, str(c)) for c in cells) + " |"

    def check(self, arrays):
        """(missing, undeclared) of a record archive's ``arrays`` (a loaded file, :func:`npz_arrays`): the declared
        columns it lacks (but the ``optional`` ones) and its entries that no column declares (but ``format``, the
        provenance, the columns and the ``state_*`` arrays)."""
        import re
        patterns = {c.name: re.sub(r"<[^>]*>", ".+", re.escape(c.name)) for c in self.columns if "<" in c.name}

        def has(name):                  # a name <x> stands for one entry per x
            return name in arrays or name in patterns and any(re.fullmatch(patterns[name], k) for k in arrays)
        missing = [c.name for c in self.columns if not has(c.name) and not c.optional]
        undeclared = [k for k in arrays if k not in self.by_name and k != "format" and k not in ABOUT
                      and not k.startswith("state_") and not any(re.fullmatch(p, k) for p in patterns.values())]
        return missing, undeclared

    def schema(self):
        """The schema page's table of the kind (docs/schemas.md, generated from the columns)."""
        lines = ["| name | shape | unit | meaning |", "|---|---|---|---|", f"| `format` | () | - | `\"{self.name}\"` |"]
        for c in self.columns:
            dims = ([] if c.constant else ["P"]) + [d.strip() for d in c.shape.strip("()").split(",") if d.strip()]
            shape = "(" + ", ".join(dims) + ("," if len(dims) == 1 else "") + ")"
            kind = "" if np.dtype(c.dtype).kind == "f" else " " + {"i": "int", "U": "str", "c": "complex",
                                                                     "b": "bool"}.get(np.dtype(c.dtype).kind, "")
            absent = " (absent from some files)" if c.optional and "absent" not in c.description else ""
            lines.append(f"| `{c.name}` | {shape}{kind} | {c.unit or '-'} | {c.description}{absent} |")
        return "\n".join(lines)


KINDS = {}          # {kind name: Kind}: the kinds declared so far (each study module declares its own)


def schema_page(text, kinds=None):
    """``text`` (docs/schemas.md) with the table between ``<!-- columns KIND -->`` and ``<!-- end columns -->``
    replaced by that kind's :meth:`Kind.schema`: the page's tables are generated from the declarations."""
    import re
    kinds = KINDS if kinds is None else kinds

    def table(m):
        if m.group(1) not in kinds:
            raise ValueError(f"docs/schemas.md names the columns of {m.group(1)}, which no module declares")
        return f"<!-- columns {m.group(1)} -->\n{kinds[m.group(1)].schema()}\n<!-- end columns -->"
    return re.sub(r"<!-- columns (\S+) -->\n.*?<!-- end columns -->", table, text, flags=re.S)


HDF5_SUFFIXES = (".h5", ".hdf5")


def is_hdf5(path):
    """A record file named ``*.h5`` or ``*.hdf5`` is written as HDF5 (one dataset per array, the same names as the
    npz layout; strings as UTF-8 bytes), for readers outside Python (MATLAB, Julia); every other name is npz."""
    return str(path).lower().endswith(HDF5_SUFFIXES)


def load_npz(path, what, error=RecordFileError):
    """All arrays of a record archive (npz, or HDF5 by its name: :func:`is_hdf5`) as a dict; ``error`` (naming
    ``what``) if it is missing or unreadable."""
    if not os.path.exists(path):
        raise error(f"{what} {given(path)} does not exist")
    if is_hdf5(path):
        return _load_h5(path, what, error)
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as err:
        raise error(f"{what} {given(path)} is corrupt or not an npz archive ({err})") from None


def check_kind(data, path, kind, what):
    """The ``format`` entry of a loaded archive must be ``kind`` (a file of another kind names both)."""
    stored = str(data.get("format", ""))
    if stored != kind:
        found = f"a {stored!r} file" if stored else "not a hertzpetsc record file"
        raise RecordFileError(f"{given(path)} is {found}, but a {what} ({kind!r}) is expected here")


def read_kind(path, kind, what, error=RecordFileError):
    """The arrays of a record file of ``kind`` (a :class:`Kind`) as a dict: :func:`load_npz`, :func:`check_kind`,
    and every declared column there but the ``optional`` ones (files written before those), else ``error`` naming
    ``what``."""
    data = load_npz(path, what, error)
    check_kind(data, path, kind.name, what)
    missing = kind.check(data)[0]
    if missing:
        raise error(f"{what} {given(path)} is corrupt: missing {missing}")
    return data


def typed_records(data, kind):
    """The records of a loaded file ``data`` of ``kind`` (a :class:`Kind`) as a list of {field: value}, each value
    of its column's dtype (a number as a Python number, an array as an array); the fields the file lacks (optional
    ones) are left out."""
    fields = [kind.by_name[f] for f in kind.fields if f in data]
    if not fields:
        return []
    return [{c.name: _typed(np.asarray(data[c.name][i]), c.dtype) for c in fields}
            for i in range(len(data[fields[0].name]))]


def _typed(value, dtype):
    if value.ndim:
        return value.astype(dtype, copy=False)
    return str(value) if dtype is str else np.dtype(dtype).type(value).item()


def _same(a, b):
    if isinstance(a, (float, np.floating)) or isinstance(b, (float, np.floating)):
        try:
            a, b = float(a), float(b)
        except (TypeError, ValueError):
            return False
        return a == b or abs(a - b) <= 1e-12 * max(abs(a), abs(b))
    if isinstance(a, (list, tuple)) or isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b


# identity keys whose absence from a file has a meaning: the files of the Hertz chain name no law
ABSENT = {"law": "hertz", "bonds": None}
ABSENT_WHAT = {"law": "law is Hertz's", "bonds": "bonds all have the model's law"}


def check_identity(stored, wanted, path, names=None):
    """Every identity key in both must agree; keys the stored file lacks (older files) are not compared, but for
    those of :data:`ABSENT` (a file without ``law`` is of the Hertz law). A difference names the key and, where
    ``names`` has one, the parameter and option that set it."""
    for key, value in ABSENT.items():               # the file names one, the request none: the request is the default
        if key in stored and key not in wanted and not _same(stored[key], value):
            by = f", set by {names[key]}" if names and key in names else ""
            raise RecordFileError(f"{given(path)} holds another computation: {key} = {stored[key]!r} there, none "
                                  f"requested (its {ABSENT_WHAT[key]}){by} (rerun with the same model, or without "
                                  "-resume and with -force (mode 'force' in the API) to start afresh)")
    for key, value in wanted.items():
        if key not in stored and key in ABSENT and value != ABSENT[key]:
            raise RecordFileError(f"{given(path)} holds another computation: {key} = {value!r} requested, where the "
                                  f"file has none (its {ABSENT_WHAT[key]}; rerun with the same model, or without "
                                  "-resume and with -force (mode 'force' in the API) to start afresh)")
        if key in stored and not _same(stored[key], value):
            by = f", set by {names[key]}" if names and key in names else ""
            raise RecordFileError(f"{given(path)} holds another computation: {key} = {stored[key]!r} there, {value!r} "
                                  f"requested{by} (rerun with the same parameters, or without -resume and with "
                                  "-force (mode 'force' in the API) to start afresh)")


class RecordStore:
    """Common part of the layouts: the mode, the identity, the collective open and append."""

    what = "record file"

    def __init__(self, path, kind, identity, comm=None, mode="new", about=None):
        if mode not in MODES:
            raise ParameterError("mode", mode, f"must be one of {', '.join(MODES)}")
        self.path, self.kind, self.identity, self.comm, self.mode = path, kind, dict(identity), comm, mode
        self.state = {}            # arrays that are replaced, not stacked (e.g. the profiles a resume starts from)
        # what made the file (:func:`provenance`; ``about`` given: the caller's, {} for none), kept with the
        # provenance of the runs before on a resume
        self.provenance = provenance(comm=comm) if about is None else dict(about)
        self.records, self.state, self.provenance = on_rank0(comm, self._open, what=f"cannot open {self.what} {path!r}")

    def _open(self):
        """Load or start the store on rank 0: (records, state)."""
        exists = self._exists()
        if self.mode == "resume":
            if not exists:
                raise RecordFileError(f"{self.what} {given(self.path)} does not exist: nothing to resume (omit "
                                      "-resume, mode 'resume' in the API, to start it)")
            records = self._load()
        elif exists and self.mode == "new":
            raise RecordFileError(f"{self.what} {given(self.path)} exists: continue it with -resume or overwrite it "
                                  "with -force (mode 'resume' or 'force' in the API)")
        else:
            records = []
        if _CHECKING:
            return records, self.state, self.provenance
        self._prepare()
        self.records = records
        self._start(records)
        return records, self.state, self.provenance

    def append(self, record):
        """Add one record and write it (collective: rank 0 writes, every rank raises if that failed); returns it."""
        self.records.append(record)
        on_rank0(self.comm, self._write_last, what=f"cannot write {self.what} {self.path!r}")
        return record

    # layout hooks
    def _exists(self):
        return os.path.exists(self.path)

    def _prepare(self):
        make_directory(self.path, self.what)
        remove_stale_temporaries(self.path)

    def _start(self, records):
        """Write the file as it stands at the start (empty for a new store, so that it exists from now on)."""

    def _load(self):
        raise NotImplementedError

    def _write_last(self):
        raise NotImplementedError


class NpzRecords(RecordStore):
    """Records as the rows of one npz archive, rewritten atomically after each append.

    ``constants``: arrays written once per file (the identity's values among them, plus e.g. a grid or JSON
    metadata); ``fields``: the per-record entries, stacked along a first axis of length P; ``dtypes`` maps a
    field to its dtype (default float64) and ``shapes`` gives the per-record shape of array fields, so that an
    archive with P = 0 records still has the right shapes. ``added``: {field: value} of the fields added to the
    format after files were written; a file without one loads with that value in every record. ``names``: how
    the user sets an identity key whose name is not the parameter's (:func:`check_identity`).
    """

    def __init__(self, path, kind, constants, identity, fields, comm=None, mode="new", dtypes=None, shapes=None,
                 what="record file", added=None, names=None, about=None, columns=None):
        self.constants, self.fields, self.names = dict(constants), tuple(fields), names
        self.dtypes, self.shapes, self.added = dict(dtypes or {}), dict(shapes or {}), dict(added or {})
        self.what, self.columns = what, columns
        super().__init__(path, kind, identity, comm, mode, about)

    def append(self, record, state=None):
        """Add one record (and replace the given ``state`` arrays), then write (collective); returns it."""
        if state:
            self.state.update(state)
        return super().append(record)

    def _load(self):
        data = load_npz(self.path, self.what)
        check_kind(data, self.path, self.kind, self.what)
        check_identity({k: data[k].item() if data[k].ndim == 0 else data[k].tolist()
                        for k in list(self.identity) + [k for k in ABSENT if k not in self.identity
                                                         and k not in self.fields] if k in data},
                       self.identity, self.path, self.names)
        missing = [f for f in self.fields if f not in data and f not in self.added]
        if missing:
            raise RecordFileError(f"{self.what} {given(self.path)} is corrupt: missing {missing}")
        present = [f for f in self.fields if f in data]
        P = len(data[present[0]])
        if any(len(data[f]) != P for f in present):
            raise RecordFileError(f"{self.what} {given(self.path)} is corrupt: inconsistent array shapes")
        self.state = {k[len("state_"):]: data[k] for k in data if k.startswith("state_")}
        self.provenance = resumed_provenance(self.provenance, file_provenance(data))
        return [{f: data[f][i] if f in data else self.added[f] for f in self.fields} for i in range(P)]

    def _start(self, records):
        self._write_last()

    def arrays(self):
        """The archive's content as it is written: constants, ``format``, the stacked fields and the state."""
        return npz_arrays(self.kind, self.constants, self.fields, self.records, self.state, self.dtypes, self.shapes,
                          self.provenance, self.columns)

    def _write_last(self):
        write_npz(self.path, self.arrays())


def npz_arrays(kind, constants, fields, records, state=None, dtypes=None, shapes=None, about=None, columns=None):
    """The arrays of a record archive: ``format``, the constants, each field stacked over the records (with its
    dtype; P = 0 keeps the per-record ``shapes``), the state arrays under ``state_<name>``, the provenance
    ``about`` (:func:`provenance`) as JSON under ``__provenance__`` and, for a kind with declared ``columns``
    (a :class:`Kind`), their units and meanings as JSON under ``__columns__``."""
    dtypes, shapes = dtypes or {}, shapes or {}
    clash = set(constants) & set(fields)
    if clash or {"format", *ABOUT} & (set(constants) | set(fields)):
        raise ValueError(f"a record archive's constants and fields must have different names: {sorted(clash)}")
    out = {"format": np.array(kind)}
    if about:
        out[PROVENANCE] = np.array(json.dumps(about, default=str))
    if columns is not None:
        out[COLUMNS] = np.array(json.dumps(columns.about()))
    for k, v in constants.items():
        out[k] = np.asarray(v)
    for f in fields:
        dtype = dtypes.get(f, float)
        values = [np.asarray(r[f], dtype=dtype) for r in records]
        out[f] = np.stack(values) if values else np.zeros((0,) + tuple(shapes.get(f, ())), dtype=dtype)
    for k, v in (state or {}).items():
        out["state_" + k] = np.asarray(v)
    return out


class MemoryRecords(NpzRecords):
    """The record store of a study run without an output file (a notebook, a test): the same records, state and
    :meth:`arrays` as :class:`NpzRecords`, kept in memory; nothing is read or written."""

    what = "in-memory records"

    def __init__(self, kind, constants, fields, comm=None, dtypes=None, shapes=None, columns=None):
        super().__init__(None, kind, constants, constants, fields, comm, "new", dtypes, shapes, self.what, about={},
                         columns=columns)

    def _exists(self):
        return False

    def _prepare(self):
        pass

    def _write_last(self):
        pass


def write_npz(path, arrays):
    """Write a record archive atomically (temporary file, fsync, rename): npz, or HDF5 by its name."""
    if is_hdf5(path):
        _write_h5(path, arrays)
    else:
        _replace_atomically(path, lambda f: np.savez(f, **arrays))


def _h5py():
    try:
        import h5py
    except ImportError:
        raise RecordFileError("HDF5 record files need h5py (Debian's python3-h5py-mpi, installed by "
                              "`bash scripts/hz.sh setup`)") from None
    return h5py


def _write_h5(path, arrays):
    """The HDF5 layout: one dataset per array; each dataset that ``__columns__`` describes carries the attributes
    ``units`` and ``description``."""
    h5py = _h5py()
    about = json.loads(str(arrays[COLUMNS])) if COLUMNS in arrays else {}

    def write(f):
        with h5py.File(f, "w") as h5:
            for name, value in arrays.items():
                value = np.asarray(value)
                dataset = h5.create_dataset(name, data=np.char.encode(value, "utf-8") if value.dtype.kind == "U"
                                            else value)
                if name in about:
                    dataset.attrs["units"] = about[name]["unit"]
                    dataset.attrs["description"] = about[name]["description"]
    _replace_atomically(path, write)


def _load_h5(path, what, error):
    h5py = _h5py()
    try:
        with h5py.File(path, "r") as f:
            out = {}
            for name, dataset in f.items():
                value = np.asarray(dataset[()])
                if value.dtype.kind == "S":
                    value = np.char.decode(value, "utf-8")
                out[name] = value
            return out
    except (OSError, ValueError) as err:
        raise error(f"{what} {given(path)} is corrupt or not an HDF5 file ({err})") from None


class AppendRecords(RecordStore):
    """Fixed-length float64 records appended to ``directory/<data>``, with a JSON header ``directory/<header>``.

    The header holds the identity (and whatever else describes the records; ``columns``, a :class:`Kind`: the
    units and meanings of its keys and of the records' parts, under ``columns``). Each append is flushed and fsynced,
    so a killed run loses at most the record in flight; a partial trailing record is dropped on resume.
    """

    def __init__(self, directory, kind, header, identity, record_length, comm=None, mode="new",
                 header_name="run.json", data_name="records.f64", what="run directory", columns=None):
        self.directory = directory
        self.header = dict(header, format=kind, **({} if columns is None else {"columns": columns.about()}))
        self.record_length = int(record_length)
        self.header_path = os.path.join(directory, header_name)
        self.data_path = os.path.join(directory, data_name)
        self.what = what
        super().__init__(directory, kind, identity, comm, mode)

    def _exists(self):
        return os.path.exists(self.header_path)

    def _prepare(self):
        make_directory(self.header_path, self.what)
        remove_stale_temporaries(self.header_path)

    @staticmethod
    def read_header(directory, header_name="run.json", what="run directory"):
        path = os.path.join(directory, header_name)
        if not os.path.exists(path):
            raise RecordFileError(f"no run in {given(directory)} ({header_name} missing)")
        try:
            with open(path) as f:
                return json.load(f)
        except ValueError:
            raise RecordFileError(f"{path!r} is corrupt") from None

    def _load(self):
        header = self.read_header(self.directory, os.path.basename(self.header_path), self.what)
        if "format" in header and header["format"] != self.kind:
            raise RecordFileError(f"{given(self.directory)} holds a {header['format']!r} run, not a {self.kind!r} one")
        check_identity(header, self.identity, self.directory)
        size = os.path.getsize(self.data_path) if os.path.exists(self.data_path) else 0
        whole = size // (8 * self.record_length) * 8 * self.record_length
        if whole != size:                       # a record in flight when the run was killed
            with open(self.data_path, "r+b") as f:
                f.truncate(whole)
        raw = np.fromfile(self.data_path, dtype=np.float64) if whole else np.zeros(0)
        return list(raw.reshape(-1, self.record_length))

    def _start(self, records):
        if self.mode != "resume":
            header = dict(self.header, provenance=self.provenance)     # a resumed run's header is the first run's
            _replace_atomically(self.header_path, lambda f: f.write(json.dumps(header, indent=1,
                                                                               default=str).encode()))
            open(self.data_path, "wb").close()

    def append(self, record):
        record = np.asarray(record, dtype=np.float64).ravel()
        if record.size != self.record_length:
            raise ValueError(f"a record has {self.record_length} numbers, not {record.size}")
        return super().append(record)

    def _write_last(self):
        with open(self.data_path, "ab") as f:
            f.write(self.records[-1].tobytes())
            f.flush()
            os.fsync(f.fileno())

    def array(self):
        """The records as an (n, record_length) array."""
        return np.array(self.records).reshape(-1, self.record_length)
