"""The command line of the drivers: the PETSc options database, application options declared with their
defaults and valid ranges, ``-help``, unknown options, and one-line errors on every rank.

Scripts call ``petsc4py.init(sys.argv)`` first, so PETSc options are the command line. A driver declares each of
its application options through :class:`AppOptions` (which reads and validates it), then calls
:meth:`AppOptions.done` (``-help`` prints the declarations, the solver prefixes and PETSc's options for them,
and exits 0 before anything is read or computed), builds its study (which configures every solver from the
options database), and calls :meth:`AppOptions.check_unused`: an option that nothing read is then an error that
names it and the closest known option. :func:`guarded_main` turns every error into one ``error: ...`` line on
stderr and the exit status of :mod:`hertzpetsc.errors`, on every rank.
"""
import contextlib
import ctypes
import difflib
import gc
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping
from dataclasses import MISSING
from typing import Any, Iterator, Optional

import numpy as np
from petsc4py import PETSc

from . import kernels
from .console import print0
from .errors import (HertzPetscError, OptionError, ParameterError, PetscFailure, RecordFileError, Terminated, specs,
                     unwrapped)
from .records import check_stores, name_path, prepare_outputs, provenance

# seconds the other ranks give rank 0 to report an error they all hit before they report it themselves
ABORT_GRACE = 3.0


def _lib():
    """The PETSc shared library, as loaded by petsc4py (for the calls petsc4py does not wrap)."""
    import petsc4py.PETSc as module
    return ctypes.CDLL(module.__file__)


def unused_options():
    """[(name, value)] of the options nobody has queried so far (PetscOptionsLeftGet)."""
    lib = _lib()
    n = ctypes.c_int()
    names, values = ctypes.POINTER(ctypes.c_char_p)(), ctypes.POINTER(ctypes.c_char_p)()
    if lib.PetscOptionsLeftGet(None, ctypes.byref(n), ctypes.byref(names), ctypes.byref(values)):
        return []
    out = [(names[i].decode(), values[i].decode() if values[i] is not None else None) for i in range(n.value)]
    lib.PetscOptionsLeftRestore(None, ctypes.byref(n), ctypes.byref(names), ctypes.byref(values))
    return out


def petsc_message(err):
    """PETSc's own text for a PETSc.Error: the specific message of the failed call and the generic one."""
    text, specific = ctypes.c_char_p(), ctypes.c_char_p()
    try:
        _lib().PetscErrorMessage(ctypes.c_int(err.ierr), ctypes.byref(text), ctypes.byref(specific))
    except (AttributeError, OSError):
        return f"PETSc error {getattr(err, 'ierr', '?')}"
    generic = (text.value or b"").decode().split(":")[0].strip()
    detail = (specific.value or b"").decode().strip()
    culprit = [f"-{k} {v}" for k, v in PETSc.Options().getAll().items()
               if v and len(str(v)) > 1 and re.search(r"\b" + re.escape(str(v)) + r"\b", detail)]
    where = f" (from the option {culprit[0]})" if culprit else ""
    return (f"{detail}{where} (PETSc error {err.ierr}: {generic})" if detail
            else f"PETSc error {err.ierr}: {generic}")


def make_solver_object(kind, prefix, comm=PETSc.COMM_SELF):
    """A bare solver of ``kind`` (snes, ts, eps, pep) under ``prefix``."""
    if kind in ("eps", "pep"):
        from slepc4py import SLEPc
    obj = getattr(SLEPc if kind in ("eps", "pep") else PETSc, kind.upper())().create(comm=comm)
    obj.setOptionsPrefix(prefix)
    return obj


def print_solver_help(roles):
    """PETSc's own -help text for the objects of each role (only meaningful while -help is in the database)."""
    for prefix, kinds in roles.items():
        for kind in kinds:
            obj = make_solver_object(kind, prefix)
            try:
                obj.setFromOptions()
            except PETSc.Error:
                pass
            obj.destroy()


def solver_help_text(roles):
    """PETSc's own -help text for the objects of each role, captured (PETSc prints an object's help once per
    process, and only while the database holds a bare ``-help``: ``-help solvers`` is one only for 3.18)."""
    opts = PETSc.Options()
    had_help = opts.getString("help", None) if opts.hasName("help") else False
    libc = ctypes.CDLL(None)
    with tempfile.TemporaryFile() as sink:
        libc.fflush(None)
        sys.stdout.flush()
        saved = os.dup(1)
        os.dup2(sink.fileno(), 1)
        try:
            opts.delValue("help")
            opts.setValue("help", None)
            print_solver_help(roles)
        finally:
            libc.fflush(None)
            os.dup2(saved, 1)
            os.close(saved)
            opts.delValue("help")
            if had_help is not False:
                opts.setValue("help", had_help)
        sink.seek(0)
        return sink.read().decode(errors="replace")


def known_solver_options(roles):
    """The option names PETSc reads for the objects of each role, from its own -help output (captured)."""
    text = solver_help_text(roles)
    names = set()
    for prefix in roles:
        names.update(re.findall(r"-(" + re.escape(prefix) + r"[A-Za-z0-9_]+)", text))
    return names


class AppOptions:
    """Typed, declared application options (no prefix) in the PETSc options database.

    ``doc``: the driver's description for -help; ``roles``: the solver roles the driver configures, as
    {prefix: (its line of -help, ("snes", ...))} (:func:`hertzpetsc.roles.uses`). Each reader declares the option (for -help and for the unknown-option
    check) and returns its validated value; under -help it returns the default without validating.
    """

    current = None      # the driver's AppOptions (guarded_main names its options in errors)

    def __init__(self, doc="", roles=None):
        AppOptions.current = self
        name_path(None, None)           # a new command line: the paths of another are forgotten
        self.db = PETSc.Options()
        self.doc = (doc or "").strip()
        self.roles = dict(roles or {})
        self.declared = []          # (name, default text, valid text, help)
        self.spelled = {}           # {parameter: its option} of the parameters read by parameters()
        self.help = self.db.hasName("help")

    # --- declaration helpers ---------------------------------------------------------------------------------
    def _raw(self, name, default, valid, help):
        """Declare the option; the value given for ``name``, None if absent or under -help."""
        self.declared.append((name, default, valid, help))
        if self.db.hasName(name):
            return None if self.help else self.db.getString(name, "")
        return None

    @staticmethod
    def _number(text, expr):
        """float of ``text``; with ``expr`` arithmetic with ``pi`` is allowed (``pi/50``, ``2*pi*1e-3``)."""
        if expr:
            if not re.fullmatch(r"[0-9eE.+\-*/() pi]*", text):
                raise ValueError(text)
            return float(eval(text, {"__builtins__": {}}, {"pi": math.pi}))
        return float(text)

    def real(self, name, default, help="", valid=None, expr=False):
        """A real option; ``valid`` = (predicate, text); with ``expr``, values like ``pi/50`` are accepted."""
        raw = self._raw(name, default, valid[1] if valid else ("real" + (", pi allowed" if expr else "")), help)
        if raw is None:
            return default
        try:
            value = self._number(raw, expr)
        except Exception:
            raise ParameterError(f"-{name}", raw, "must be a real number" + (" (pi allowed)" if expr else "")) from None
        if not math.isfinite(value):
            raise ParameterError(f"-{name}", raw, "must be a finite number")
        if valid is not None and not valid[0](value):
            raise ParameterError(f"-{name}", raw, valid[1])
        return value

    def integer(self, name, default, help="", minimum=None, maximum=None):
        rng = " and ".join(f"{op} {v}" for op, v in ((">=", minimum), ("<=", maximum)) if v is not None)
        raw = self._raw(name, default, f"integer {rng}".strip(), help)
        if raw is None:
            return default
        try:
            value = int(raw)
        except ValueError:
            value = None
        if value is None or (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
            raise ParameterError(f"-{name}", raw, f"must be an integer {rng}".strip())
        return value

    def string(self, name, default, help="", choices=None):
        raw = self._raw(name, default, "one of " + ", ".join(choices) if choices else "text", help)
        if raw is None:
            return default
        if choices is not None and raw not in choices:
            raise ParameterError(f"-{name}", raw, "must be one of " + ", ".join(choices))
        return raw

    def path(self, name, default, help=""):
        """A file or directory name; empty only where the default is empty (none: an empty value says so too). The
        errors about the file name the option (:func:`hertzpetsc.records.name_path`), its default included."""
        raw = self._raw(name, default, "a path" + (", or empty for none" if default == "" else ""), help)
        if raw is None:
            if default:
                name_path(f"-{name}", default)
            return default
        if not raw.strip():
            if default == "":
                return ""
            raise ParameterError(f"-{name}", raw, "must be a non-empty path")
        name_path(f"-{name}", raw)
        return raw

    def flag(self, name, help=""):
        raw = self._raw(name, "off", "flag", help)
        if raw is None:
            return False
        if raw.lower() in ("", "1", "true", "yes", "on"):
            return True
        if raw.lower() in ("0", "false", "no", "off"):
            return False
        raise ParameterError(f"-{name}", raw, "is a flag: give it alone, or with true/false")

    def numbers(self, name, default, help="", expr=True, kind=float, valid=None, distinct=False, minimum_count=1):
        """A comma-separated list (``default`` is the list's text). Empty lists, members out of ``valid`` =
        (predicate, text), and (with ``distinct``) repeated members are refused."""
        what = "integers" if kind is int else "numbers" + (" (pi allowed)" if expr else "")
        rule = (f"a comma-separated list of at least {minimum_count} {what}" if minimum_count else
                f"an optional comma-separated list of {what}") + \
               (f", each {valid[1]}" if valid else "") + (", all different" if distinct else "")
        raw = self._raw(name, default, rule, help)
        if self.help:
            return []
        text = default if raw is None else raw
        if raw is not None and not raw.strip():
            if minimum_count == 0:
                return []                             # an optional list given empty: none, as its help says
            raise ParameterError(f"-{name}", raw, f"is empty: give {rule}, or leave the option out")
        try:
            items = [v.strip() for v in text.split(",")] if text.strip() else []
            values = [self._number(v, expr) for v in items]
            if (kind is int and any(v != int(v) for v in values)) or len(values) < minimum_count:
                raise ValueError
            values = [kind(v) for v in values]
        except Exception:
            raise ParameterError(f"-{name}", text, f"must be {rule}") from None
        if valid is not None:
            bad = [v for v in values if not valid[0](v)]
            if bad:
                raise ParameterError(f"-{name}", text, f"member {bad[0]!r} is not {valid[1]}")
        if distinct:
            for i, v in enumerate(values):
                if any(math.isclose(v, s, rel_tol=1e-12) for s in values[:i]):
                    raise ParameterError(f"-{name}", text, f"lists {v!r} twice; the members must be different")
        return values

    def words(self, name, default, help="", choices=None):
        """A comma-separated list of names (``default`` is the list's text), each one of ``choices``."""
        rule = "a comma-separated list" + (" of " + ", ".join(choices) if choices else " of names")
        raw = self._raw(name, default, rule, help)
        text = default if raw is None else raw
        values = [v.strip() for v in text.split(",")] if text.strip() else []
        if not values or "" in values or (choices is not None and any(v not in choices for v in values)):
            raise ParameterError(f"-{name}", text, f"must be {rule}")
        return values

    def parameters(self, cls, skip=(), **defaults):
        """{field: value} of the declared parameters of the dataclass ``cls`` (:func:`hertzpetsc.errors.param`),
        each read as its option (``-field`` or the spec's ``option``) with its meaning and range, the errors naming
        the option; ``defaults`` replace the dataclass's (a list's as its text: ``q="2*pi/15"``); ``skip``: fields
        the driver reads otherwise. An error that the dataclass raises naming a field then names its option
        (:meth:`names`, :func:`guarded_main`)."""
        out = {}
        for f, spec in specs(cls):
            if f.name in skip:
                continue
            option, default = spec.option or f.name, defaults.get(f.name, f.default)
            default = "" if default is MISSING else default         # a required field: the option must be given
            self.spelled[f.name] = option
            valid = (spec.holds, spec.rule()) if spec.rule() else None
            if spec.kind == "real":
                value = self.real(option, default, spec.what, valid=valid, expr=spec.expr)
            elif spec.kind == "integer":
                value = self.integer(option, default, spec.what, minimum=spec.lo, maximum=spec.hi)
            elif spec.kind in ("reals", "integers"):
                text = default if isinstance(default, str) else ",".join(f"{v:g}" for v in default or ())
                value = self.numbers(option, text, spec.what, expr=spec.expr,
                                     kind=int if spec.kind == "integers" else float, valid=valid,
                                     distinct=spec.distinct, minimum_count=0 if default is None else spec.count)
                value = default if self.help else tuple(value) if value or default is not None else None
            elif spec.kind == "choice":
                value = self.string(option, default, spec.what, choices=spec.choices)
            elif spec.kind == "words":
                value = tuple(self.words(option, default if isinstance(default, str) else ",".join(default),
                                         spec.what, choices=spec.choices))
            elif spec.kind == "flag":          # a flag on by default: its option turns it off
                value = self.flag(option, spec.help or spec.what) != bool(default)
            else:
                value = self.string(option, default, spec.what)
            out[f.name] = value
        return out

    def names(self):
        """{name: option} of every declared option and of each parameter read by :meth:`parameters` (an error
        naming the parameter then names its option)."""
        return dict({name: name for name in self.known()}, **self.spelled)

    def table_and_figures(self, table, figures):
        """The -output table (default ``table``) and the -figures directory (its figures named by ``figures``;
        none if empty), as most drivers have them."""
        return (self.path("output", table, "table"),
                self.path("figures", "", f"directory for {figures} (none if empty)"))

    def record_table_figures(self, record, what, table, figures):
        """-output (a record file, default ``record``), -resume/-force, -table and -figures, for the drivers whose
        -output is their record store: (record path, mode, table path, figures directory)."""
        return (self.path("output", record, f"{what} (record store)"), self.mode(), self.path("table", table, "table"),
                self.path("figures", "", f"directory for {figures} (none if empty)"))

    def render_flag(self, also=""):
        """-render, a flag: compute nothing, rewrite -table and the figure from the record file -output
        (:meth:`render`); ``also`` ends its help text."""
        return self.flag("render", "compute nothing: rewrite -table and the figure from the file -output" + also)

    def render(self, mode, read, write, table, figures, computation=()):
        """-render, after :meth:`done` (the one place of the drivers' -render): refused with -resume or -force (the
        record file is read, not written) and with any of the options ``computation`` (they define what the file
        holds); then ``records = read()`` (the file -output, every rank), the outputs prepared, the options
        checked (:meth:`check_unused`: -check stops there) and ``write(records)`` (the table and the figure)."""
        if mode != "new":
            raise RecordFileError("-render reads -output and writes only -table and the figure: give it without "
                                  "-resume or -force")
        given = [name for name in computation if self.db.hasName(name)]
        if given:
            raise ParameterError(f"-{given[0]}", self.db.getString(given[0], ""), "-render takes the computation "
                                 "from the file -output: give no option that defines it (-"
                                 + ", -".join(computation) + ")")
        records = read()
        prepare_outputs(PETSc.COMM_WORLD, table, figures=figures)
        self.check_unused()
        write(records)

    def mode(self):
        """The record mode from -resume / -force: 'resume', 'force' or 'new' (both at once is an error)."""
        resume = self.flag("resume", "continue the record file (or run directory) of an interrupted run")
        force = self.flag("force", "overwrite an existing record file (or run directory)")
        if resume and force:
            raise ParameterError("-resume", "with -force", "give one of -resume (continue) and -force (overwrite)")
        return "resume" if resume else "force" if force else "new"

    # --- after the declarations ---------------------------------------------------------------------------------
    def help_text(self):
        lines = [self.doc, "", "Application options (default; valid values):"]
        for name, default, valid, text in self.declared:
            lines.append(f"  -{name} {default if default not in (None, '') else '(none)'}"
                         f"    [{valid}]" + (f"  {text}" if text else ""))
        if self.roles:
            lines += ["", "Solver prefixes (every PETSc option of these objects, e.g. -tw_snes_monitor):"]
            lines += [f"  -{prefix}*   {description}" for prefix, (description, _) in self.roles.items()]
        return "\n".join(lines)

    def done(self):
        """End of the declarations: under -help, print them and PETSc's options of the roles, and exit 0.
        Otherwise check that every rank was given the same options (ranks that disagree would compute different
        things and deadlock in the first collective call that depends on them). Declares ``-check``
        (:meth:`check_unused`)."""
        self.check = self.flag("check", "check the options and the input files, and that the outputs can be written, "
                               "then exit 0: nothing is computed or written (output directories may be created)")
        self.work_limit()
        if not self.help:
            check_ranks_agree(PETSc.COMM_WORLD)
            return
        if PETSc.COMM_WORLD.getRank() == 0:
            print(self.help_text(), flush=True)
        if self.roles and self.db.getString("help", "") == "solvers":
            print0("\nPETSc's options of these solvers (their defaults before the code's own):")
            if PETSc.COMM_WORLD.getRank() == 0:          # the objects are made on COMM_SELF: one rank prints
                roles = {p: kinds for p, (_, kinds) in self.roles.items()}
                print(solver_help_text(roles), end="", flush=True)
        elif self.roles:
            print0("\nPETSc's own options of each solver role: -help solvers")
        sys.stdout.flush()
        self.db.delValue("help")              # PETSc would print its viewer options again at its finalize
        raise SystemExit(0)

    def work_limit(self):
        """-max_hours, every driver's: the limit of the up-front estimates of computing time
        (:func:`hertzpetsc.resources.check_work`); a run estimated to take longer is refused before it computes."""
        from . import resources
        hours = self.real("max_hours", resources.DEFAULT_MAX_HOURS, "refuse a run estimated to compute longer than "
                          "this many hours (0: no limit)", valid=(lambda h: h >= 0, ">= 0 (0: no limit)"))
        return resources.set_work_limit(hours)

    def known(self):
        return {name for name, *_ in self.declared}

    def check_unused(self, passed_on=()):
        """Refuse options that nothing has read (after every solver of the driver was configured); options under
        the prefixes ``passed_on`` are handed to other processes (the benchmark workers) and not checked here.

        With ``-check`` this is where the driver stops: it has read and validated its options, loaded its inputs and
        built its studies (which configured their solvers); the record files those studies would open are then
        checked as a run would open them (an existing file without -resume or -force, a resume of another
        computation: :func:`hertzpetsc.records.check_stores`), one line says so, and every rank exits 0."""
        self._refuse_unused(passed_on)
        if getattr(self, "check", False):
            check_stores()
            for name in self.db.getAll():           # what PETSc would write when it finalizes (-log_view :file)
                if name.startswith(("log_", "memory_view", "malloc_dump", "malloc_view")):
                    self.db.delValue(name)
            print0("check: options, inputs and outputs valid (nothing computed or written)")
            raise SystemExit(0)

    def _refuse_unused(self, passed_on):
        left = [(n, v) for n, v in unused_options() if n not in self.known() and not n.startswith(tuple(passed_on))]
        if not left:
            return
        role_options = known_solver_options({p: kinds for p, (_, kinds) in self.roles.items()}) if self.roles else set()
        idle = [(n, v) for n, v in left if n in role_options]
        left = [(n, v) for n, v in left if n not in role_options]
        if not left:
            if idle:
                # a documented option of one of the driver's solver roles, for a solver this run does not create
                # (e.g. -floquet_eps_* with -method symmetric): accepted, and said
                print0("note: " + ", ".join("-" + n + (f" {v}" if v else "") for n, v in idle)
                       + " not used: this run creates no solver that reads " + ("them" if len(idle) > 1 else "it")
                       + " (its solvers depend on the other options; -help lists the roles)", file=sys.stderr)
            return
        name, value = left[0]
        candidates = self.known() | role_options
        close = difflib.get_close_matches(name, sorted(candidates), n=1, cutoff=0.6)
        hint = f"; did you mean -{close[0]}?" if close else "; see -help for the options of this driver"
        more = f" (and {len(left) - 1} more: " + ", ".join("-" + n for n, _ in left[1:4]) + ")" if len(left) > 1 else ""
        raise OptionError(f"unknown option -{name}" + (f" {value}" if value else "") + more + hint)


def user_set(prefix, names):
    """The ``names`` (without ``prefix``) the user set under ``prefix``: where one is, the code's default (one
    computed per solve: a tolerance from the residual's round-off floor, a step limit from the interval) does not
    apply. The one check of the kind (:func:`inserted_options` inserts defaults that do not vary)."""
    return {name for name in names if PETSc.Options().hasName(prefix + name)}


@contextlib.contextmanager
def inserted_options(prefix, defaults, override=False):
    """Insert ``defaults`` ({name: value}, names without ``prefix``) into the options database for the duration of
    the block, only where the user set none, and delete afterwards only the keys inserted here (petsctools'
    inserted_options): the one way a solver role gets code defaults that PETSc's own set-up would not accept
    otherwise (e.g. before setFromOptions). ``override``: set every key, also those the database holds, and put
    their values back afterwards (the per-call options of the API, :func:`call_options`). Yields the names
    inserted (those the database did not hold)."""
    opts = PETSc.Options()
    inserted, previous = [], {}
    if override:
        held = opts.getAll()
    for key, value in defaults.items():
        name = prefix + key
        if opts.hasName(name):
            if not override:
                continue
            previous[name] = held.get(name, held.get(name.lower()))
        else:
            inserted.append(name)
        opts.setValue(name, value)
    try:
        yield inserted
    finally:
        for key in inserted:
            opts.delValue(key)
        for key, value in previous.items():
            opts.setValue(key, value)


@contextlib.contextmanager
def call_options(options: Optional[Mapping[str, Any]]) -> Iterator[None]:
    """The per-call solver options of an API call (``options={"tw_snes_rtol": 1e-12}``, as DOLFINx's
    ``petsc_options``): in the options database for the duration of the block, over what it held, which is put
    back afterwards, also when the block raises. Names are full option names (prefix included, a leading '-'
    allowed); values a string, number, bool or None (a flag). An option the block's solvers did not read (a
    misspelt name, a solver the call does not create) is a ParameterError naming ``options`` after the block."""
    if options is None:
        yield
        return
    if not isinstance(options, Mapping):
        raise ParameterError("options", options, "a dict of solver options {name: value}, e.g. "
                             "{'tw_snes_rtol': 1e-12} (None: the options database as it is)")
    values = {}
    for key, value in options.items():
        name = key.lstrip("-") if isinstance(key, str) else ""
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", name):
            raise ParameterError("options", key, "an option name such as 'tw_snes_rtol' (prefix included)")
        if not (value is None or isinstance(value, (str, bool, int, float, np.integer, np.floating))):
            raise ParameterError("options", f"{{{key!r}: {value!r}}}", "a value is a string, a number, a bool or "
                                 "None (an option without value)")
        if name.lower() in {n.lower() for n in values}:
            raise ParameterError("options", key, "given twice (names are case-insensitive, the '-' optional)")
        values[name] = value
    with inserted_options("", values, override=True) as inserted:
        yield
        left = {n.lower() for n, _ in unused_options()}
        unread = [n for n in inserted if n.lower() in left]
    if unread:
        raise ParameterError("options", ", ".join(unread), "not read by any solver of this call (a misspelt name, "
                             "or a solver prefix this call does not use: docs/api.md lists each call's prefixes)")


def check_ranks_agree(comm):
    """ParameterError on every rank, naming the first option whose value differs between ranks (collective)."""
    if comm.getSize() == 1:
        return
    mine = sorted((k, "" if v is None else str(v)) for k, v in PETSc.Options().getAll().items())
    everyone = comm.tompi4py().allgather(mine)
    for name in sorted({k for other in everyone for k, _ in other}):
        values = [dict(other).get(name) for other in everyone]
        if any(v != values[0] for v in values):
            shown = ", ".join(f"rank {r}: {'(absent)' if v is None else v or '(no value)'}" for r, v in
                              enumerate(values))
            raise ParameterError(f"-{name}", values[0], f"the ranks were given different values ({shown}): give "
                                 "every rank the same options")


def run_metadata(**extra):
    """The run's provenance (:func:`hertzpetsc.records.provenance`, the one builder) and ``extra``: a branch file's
    ``meta``, a small-q summary's."""
    return dict(provenance(comm=PETSc.COMM_WORLD), **extra)


def _exit(code, message, collective):
    """Print the error line and end every rank with ``code``.

    One rank: print and exit. Several: when the error is the same on every rank, rank 0 prints and aborts the job;
    the other ranks wait a moment for that, and only if it does not come (the error was theirs alone) print their
    own line and abort. Aborting, rather than exiting, means that no rank ever waits in MPI_Finalize or in a
    collective for a rank that has stopped: an MPI run never hangs on an error.
    """
    comm = PETSc.COMM_WORLD
    size, rank = comm.getSize(), comm.getRank()
    message = " / ".join(line.strip() for line in str(message).splitlines() if line.strip())   # one line
    if size == 1:
        print(f"error: {message}", file=sys.stderr, flush=True)
        sys.exit(code)
    if rank != 0 or not collective:
        if collective:
            time.sleep(ABORT_GRACE)
        message += f" (rank {rank})"
    print(f"error: {message}", file=sys.stderr, flush=True)
    comm.tompi4py().Abort(code)


def _raise_terminated(signum, frame):
    raise Terminated(signum)


def run_child(cmd, cwd=None, out=None, grace=5.0, err=subprocess.STDOUT, env=None, timeout=None):
    """Run ``cmd`` in a process group of its own (stdout to ``out``, stderr to ``err``) and return its exit status,
    124 if it ran longer than ``timeout`` seconds. If it times out, or this process is interrupted or terminated
    meanwhile (KeyboardInterrupt, :class:`Terminated`), the whole group (an mpiexec and its ranks) is ended --
    SIGTERM, then SIGKILL after ``grace`` seconds -- before the interruption is passed on: no child outlives its
    parent (the paper pipeline's steps, the benchmarks' workers)."""
    child = subprocess.Popen(cmd, cwd=cwd, stdout=out, stderr=err, env=dict(os.environ) if env is None else env,
                             start_new_session=True)
    try:
        return _wait(child, timeout)
    except subprocess.TimeoutExpired:
        _end_group(child, grace)
        return 124
    except BaseException:
        _end_group(child, grace)
        raise


def _wait(child, timeout):
    """The exit status of ``child`` (TimeoutExpired after ``timeout`` seconds, None: no limit), by :func:`_reaped`."""
    if not _reaped(child, math.inf if timeout is None else timeout):
        raise subprocess.TimeoutExpired(child.args, timeout)
    return child.returncode


def _end_group(child, grace):
    for sig, wait in ((signal.SIGTERM, grace), (signal.SIGKILL, 60.0)):
        try:
            os.killpg(child.pid, sig)
        except ProcessLookupError:
            return
        if _reaped(child, wait):
            return


def _reaped(child, wait):
    """Whether ``child`` ended within ``wait`` seconds (reaped here), polling os.waitpid from the interpreter: a
    signal that the kernel gave another thread of this process (an MPI progress thread) is seen by Python's handler
    only there, and a handler that raises inside Popen.wait can leave that wait's lock held, so that the next wait
    blocks for ever (a held pipeline that SIGTERM did not end, its mpiexec a zombie)."""
    end = time.monotonic() + wait
    while True:
        try:
            pid, status = os.waitpid(child.pid, os.WNOHANG)
        except ChildProcessError:           # reaped already
            return True
        if pid:
            child.returncode = os.waitstatus_to_exitcode(status)
            return True
        if time.monotonic() >= end:
            return False
        time.sleep(0.02)


def guarded_main(main):
    """Run ``main()``; turn every error into one ``error:`` line on stderr and the documented exit status.

    Package errors are raised on every rank at once (see :mod:`hertzpetsc.errors`): rank 0 prints and every rank
    exits. SIGINT, SIGTERM and SIGHUP end the run with status 130, 143 and 129 after the ``finally`` blocks ran
    (child processes ended, record files left as after their last complete record). PETSc errors are collective
    as well (configuration and solver calls are) and are reported with PETSc's own message. Anything else is a
    failure of one rank: that rank prints it and aborts the others, so an MPI run never hangs.
    """
    try:
        # inside the try: a signal that arrives as soon as its handler is in place (mpiexec ending the ranks of a
        # job another rank aborted at start-up) is reported as any other, not a traceback
        for sig in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, _raise_terminated)
        main()
        return
    except SystemExit as exit_:                 # -help, -check: every rank at once
        code, collective = exit_.code, True
    except BaseException as err:
        # from here on a signal (mpiexec ending the ranks of a job another rank aborted) ends this rank quietly
        for sig in (signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, signal.SIG_DFL)
        try:
            _report(err)                        # one rank: sys.exit; several: the job aborted
        except SystemExit as exit_:
            code, collective = exit_.code, PETSc.COMM_WORLD.getSize() == 1
    # main's frames (held by the exception's traceback until here) and the solver objects they hold are freed while
    # Python runs: left to PETSc's finalize at the interpreter's exit, a shell matrix whose destroy calls Python
    # (a Floquet operator) crashed it (SEGV, status 139, after -check's line)
    gc.collect()
    if collective:
        PETSc.garbage_cleanup()
    raise SystemExit(code)


def _interruption(err):
    """The signal number behind ``err``: a KeyboardInterrupt or :class:`Terminated`, also one that an error in a
    ``finally`` block replaced (a solver object destroyed in the state the interruption left it in: PETSc error 58)
    or a PETSc call wrapped (:func:`~hertzpetsc.errors.unwrapped`),
    or a solve that the compiled kernel ended for a signal whose handler did not raise; else None."""
    seen, todo = set(), [err]
    while todo:
        err = todo.pop()
        if err is None or id(err) in seen:
            continue
        if isinstance(err, KeyboardInterrupt):
            return signal.SIGINT
        if isinstance(err, Terminated):
            return err.signum
        if isinstance(err, PETSc.Error) and err.ierr == kernels.SIGNAL_ERROR and kernels.last_signal:
            return kernels.last_signal
        seen.add(id(err))
        todo += [err.__context__, err.__cause__]      # __cause__: a callback's exception, as petsc4py 3.26 wraps it
    return None


def _report(err):
    """The one error line and exit status of an exception that ended ``main`` (:func:`guarded_main`)."""
    signum = _interruption(err)
    err = unwrapped(err)
    if signum is not None:
        # under mpiexec the signal is either the user's, forwarded to every rank, or mpiexec ending the ranks of a
        # job that another rank aborted after printing its error: end quietly. The finally blocks ran; the exit
        # skips PETSc's finalization, which would meet solver objects the interruption left mid-operation.
        sys.stdout.flush()
        if PETSc.COMM_WORLD.getSize() == 1:
            text = "interrupted" if signum == signal.SIGINT else f"terminated by {signal.Signals(signum).name}"
            print(f"error: {text}", file=sys.stderr, flush=True)
        os._exit(128 + signum)
    elif not isinstance(err, Exception):
        raise err
    elif os.environ.get("HZ_TRACEBACK"):          # for developers: the full traceback instead of one line
        raise err
    elif isinstance(err, HertzPetscError):
        if AppOptions.current is not None:
            err = err.as_option(AppOptions.current.names())
        _exit(err.exit_status, str(err), True)
    elif isinstance(err, PETSc.Error):
        _exit(PetscFailure.exit_status, petsc_message(err), True)
    else:                                         # a bug or a rank-local failure: never a hang
        _exit(1, f"internal error: {type(err).__name__}: {err}", False)
