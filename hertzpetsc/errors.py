"""Exceptions raised by hertzpetsc, and the exit status each one gives a driver.

Every error names the offending parameter (and its valid range), option, file, or the continuation parameter at
which a solver failed, in one line, so that drivers print ``error: <message>`` and exit with ``exit_status``:

=======  ==================================================================================================
status   class
=======  ==================================================================================================
2        :class:`ParameterError` (a value out of range, an unknown option, a malformed list)
3        :class:`ConvergenceError` (a solver did not converge; the message names the parameter value)
4        :class:`RecordFileError` (an input file missing, corrupt or of another kind; an output that cannot
         be written or would overwrite a record file without -resume/-force, ``mode`` in the API)
5        :class:`PetscFailure` (PETSc refused an operation; the message is PETSc's own)
=======  ==================================================================================================

Errors are raised on every rank at once: parameters and input files are checked on all ranks (or on rank 0 and
the verdict broadcast), and solver verdicts are collective, so a driver can print on rank 0 and exit on all.
"""
from __future__ import annotations

import ctypes
import math
import numbers
import signal
from collections.abc import Mapping
from contextlib import contextmanager
from dataclasses import MISSING, dataclass, field, fields
from typing import Any, Collection, Optional, Union


class HertzPetscError(Exception):
    """Base class of the package's errors."""

    exit_status = 2

    def as_option(self, options: Collection[str]) -> HertzPetscError:
        """The same error as a driver reports it, naming its command-line ``options`` (the names it declares)
        where the message names an argument of the API; this one says it the same way in both."""
        return self


class ParameterError(HertzPetscError, ValueError):
    """A parameter is outside its valid range."""

    def __init__(self, name: Optional[str], value: Any, valid: str) -> None:
        self.name, self.value, self.valid = name, value, valid
        super().__init__(f"invalid {name} = {value!r}: {valid}")

    def as_option(self, options: Collection[str]) -> ParameterError:
        """The same error naming the command-line option ``-name`` when ``name`` (a Python argument of the API)
        is one of the driver's ``options`` (a mapping: {argument: its option}); else itself."""
        name = self.name
        if isinstance(name, str) and not name.startswith("-") and name in options:
            return ParameterError(f"-{options[name] if isinstance(options, Mapping) else name}", self.value,
                                  self.valid)
        return self


def check_real(name, value, what, lo=None, hi=None, lo_open=True, hi_open=True):
    """``value`` as a float if it is a finite real number in the interval from ``lo`` to ``hi`` (open ends by
    default; no bound where None), else a :class:`ParameterError` naming the parameter ``name`` (``what`` it is)
    and its valid range: the one check of a real parameter."""
    try:
        v = math.nan if isinstance(value, (bool, str, bytes)) or is_numpy_bool(value) else float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and (lo is None or (v > lo if lo_open else v >= lo))
            and (hi is None or (v < hi if hi_open else v <= hi))):
        rng = " and ".join(f"{op} {b:g}" for op, b in ((">" if lo_open else ">=", lo), ("<" if hi_open else "<=", hi))
                           if b is not None)
        kind = "" if isinstance(value, numbers.Real) and not isinstance(value, bool) else \
            f", not {type(value).__name__}"
        raise ParameterError(name, value, f"{what} must be a finite number" + (f" {rng}" if rng else "") + kind)
    return v


def is_numpy_bool(value) -> bool:
    """numpy's bool (np.True_): float() takes it, but it is a flag, not a number (check_flag's other spelling); its
    type is numpy.bool_, named numpy.bool from numpy 2."""
    return type(value).__module__ == "numpy" and type(value).__name__ in ("bool_", "bool")


def check_integer(name, value, lo, what="", hi=None, note=""):
    """``value`` as an int if it is a whole number in [lo, hi] (no upper bound where None; an integral float is
    taken), else a :class:`ParameterError` naming the parameter ``name`` (``what`` it is) and its valid range, then
    ``note``: the one check of an integer parameter."""
    if not (isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)
            and value == int(value) and lo <= value and (hi is None or value <= hi)):
        rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        kind = "" if isinstance(value, numbers.Real) and not isinstance(value, bool) else \
            f"(not {type(value).__name__})"
        raise ParameterError(name, value, " ".join(x for x in (what, f"must be an integer {rng}", kind, note) if x))
    return int(value)


def members(name, values, what):
    """``values`` (one number, or a sequence of them: a list, tuple, range or numpy array, 0-d included; not a
    string) as a list."""
    if getattr(values, "ndim", None) == 0 and hasattr(values, "item"):      # a 0-d numpy array: its one number
        values = values.item()
    if isinstance(values, numbers.Number):
        return [values]
    if isinstance(values, (str, bytes)) or not hasattr(values, "__iter__") or isinstance(values, dict):
        raise ParameterError(name, values, f"must be a sequence of {what} (a list or tuple), not "
                             f"{type(values).__name__}")
    return list(values.tolist() if hasattr(values, "tolist") else values)


def _distinct(name, values, what):
    """Refuse a repeated member (equal to 1e-12 relative, as AppOptions.numbers(distinct=True) does)."""
    for i, v in enumerate(values):
        if any(math.isclose(v, s, rel_tol=1e-12) for s in values[:i]):
            raise ParameterError(name, values, f"lists {v!r} twice; the {what} must be different")


def check_reals(name, values, what, lo=None, hi=None, lo_open=True, hi_open=True, distinct=False, empty=False):
    """``values`` (one number or a sequence) as a tuple of floats, each checked by :func:`check_real` under the
    name ``name``; at least one unless ``empty``; with ``distinct``, no member twice: the one check of a list of
    real parameters (``what``: the members, plural)."""
    out = tuple(check_real(name, v, f"each of the {what}", lo, hi, lo_open, hi_open)
                for v in members(name, values, "numbers"))
    if not out and not empty:
        raise ParameterError(name, values, f"give at least one of the {what}")
    if distinct:
        _distinct(name, out, what)
    return out


def check_integers(name, values, lo, what="", hi=None, distinct=False, empty=False):
    """``values`` (one number or a sequence) as a tuple of ints, each checked by :func:`check_integer` under the
    name ``name``; at least one unless ``empty``; with ``distinct``, no member twice."""
    out = tuple(check_integer(name, v, lo, f"each of the {what}" if what else "", hi)
                for v in members(name, values, "integers"))
    if not out and not empty:
        raise ParameterError(name, values, f"give at least one of the {what or 'integers'}")
    if distinct:
        _distinct(name, out, what or "integers")
    return out


def check_choice(name, value, choices, what="must be one of"):
    """``value`` if it is one of ``choices`` (names), else a :class:`ParameterError` naming ``name``."""
    if not (isinstance(value, str) and value in choices):
        raise ParameterError(name, value, f"{what} " + ", ".join(choices))
    return value


def check_instance(name, value, kind, what):
    """``value`` if it is an instance of ``kind``, else a :class:`ParameterError` naming ``name`` (``what`` it must
    be, e.g. "a LatticeModel (LatticeModel.hertz(1.5))") and the type it was given."""
    if not isinstance(value, kind):
        raise ParameterError(name, value, f"must be {what}, not {type(value).__name__}")
    return value


def check_prefix(name, value):
    """``value`` if it is an options prefix (text such as 'floquet_'), else a :class:`ParameterError` naming
    ``name``."""
    if not (isinstance(value, str) and all(c.isalnum() or c == "_" for c in value)):
        raise ParameterError(name, value, "must be an options prefix: letters, digits and '_' (e.g. 'floquet_')")
    return value


def check_flag(name, value):
    """``value`` as a bool if it is one (Python's or numpy's), else a :class:`ParameterError` naming ``name``."""
    if isinstance(value, bool) or is_numpy_bool(value):
        return bool(value)
    raise ParameterError(name, value, f"must be True or False, not {type(value).__name__}")


def _bound(b):
    return {math.pi: "pi", math.pi / 2: "pi/2"}.get(b, f"{b:g}" if isinstance(b, float) else str(b))


@dataclass(frozen=True)
class Spec:
    """A parameter declared once (:func:`param`): one line of meaning ``what``, its ``kind`` (real, integer, reals,
    integers, choice, words: a list of choices, flag, text) and range (``lo``, ``hi``, open ends by default for
    reals; ``choices``; lists: ``distinct``, at least ``count`` members), its command-line ``option`` where the name
    differs (a flag whose default is True: the option that turns it off, meaning ``help``); ``expr``: the option
    takes ``pi/50``. :meth:`check` validates a value (errors name the Python argument);
    :meth:`hertzpetsc.options.AppOptions.parameters` reads it as its option (errors name ``-option``)."""

    what: str
    kind: str
    lo: Any = None
    hi: Any = None
    lo_open: bool = True
    hi_open: bool = True
    choices: tuple = ()
    distinct: bool = False
    count: int = 1
    option: Optional[str] = None
    help: str = ""
    expr: bool = False

    def check(self, name: str, value: Any) -> Any:
        """``value`` normalised (a float, an int, a tuple ...) if valid, else a ParameterError naming ``name``."""
        k, what = self.kind, self.what
        if k == "real":
            return check_real(name, value, what, self.lo, self.hi, self.lo_open, self.hi_open)
        if k == "integer":
            return check_integer(name, value, self.lo, what, self.hi)
        if k == "choice":
            return check_choice(name, value, self.choices)
        if k == "flag":
            return check_flag(name, value)
        if k == "text":
            return check_instance(name, value, str, "text")
        if k == "words":
            out = tuple(check_choice(name, v, self.choices, "each must be one of")
                        for v in members(name, [value] if isinstance(value, str) else value, "names"))
        elif k == "reals":
            out = check_reals(name, value, what, self.lo, self.hi, self.lo_open, self.hi_open, self.distinct,
                              not self.count)
        else:
            out = check_integers(name, value, self.lo, what, self.hi, self.distinct, not self.count)
        if len(out) < self.count:
            raise ParameterError(name, value, f"give at least {self.count} {what}")
        return out

    def holds(self, value: Any) -> bool:
        """Whether one value (a member, for a list) is in the range."""
        try:
            Spec(self.what, self.kind.rstrip("s"), self.lo, self.hi, self.lo_open, self.hi_open).check("", value)
        except ParameterError:
            return False
        return True

    def rule(self) -> str:
        """The range as -help shows it (of a member, for a list)."""
        lo, hi = self.lo, self.hi
        if self.kind.startswith("integer"):
            return f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        if lo is not None and hi is not None:
            return f"in {'(' if self.lo_open else '['}{_bound(lo)}, {_bound(hi)}{')' if self.hi_open else ']'}"
        if lo is not None:
            return f"{'>' if self.lo_open else '>='} {_bound(lo)}"
        return f"{'<' if self.hi_open else '<='} {_bound(hi)}" if hi is not None else ""


_KINDS = {float: "real", int: "integer", bool: "flag", str: "text"}


def param(default: Any = MISSING, what: str = "", kind: Optional[str] = None, **spec: Any) -> Any:
    """A field of a study's parameters dataclass declared once (:class:`Spec`: ``kind`` from the default where
    not given: a float real, an int integer, a bool flag, a str text, or with ``choices`` a choice, a tuple of
    floats reals): validated by :class:`Checked`, read as an option by
    :meth:`hertzpetsc.options.AppOptions.parameters`."""
    if kind is None:
        kind = "choice" if spec.get("choices") else "reals" if isinstance(default, tuple) else \
            _KINDS[type(default)]
    return field(default=default, metadata={"param": Spec(what, kind, **spec)})


def specs(cls: Any) -> list:
    """[(field, Spec)] of the declared parameters of a dataclass (or of an instance), in field order."""
    return [(f, f.metadata["param"]) for f in fields(cls) if "param" in f.metadata]


class Checked:
    """A parameters dataclass whose :func:`param` fields are validated (and normalised) when it is built, errors
    naming the Python argument; a subclass adds the rules between fields in its own ``__post_init__`` after
    ``super().__post_init__()``."""

    def __post_init__(self) -> None:
        for f, spec in specs(self):
            value = getattr(self, f.name)
            if not (value is None and f.default is None):          # None where it is the default: not given
                object.__setattr__(self, f.name, spec.check(f.name, value))


class OptionError(ParameterError):
    """An option on the command line that no part of the driver reads (a typo), or a malformed option."""

    def __init__(self, message):
        self.name, self.value, self.valid = None, None, message
        Exception.__init__(self, message)


class ConvergenceError(HertzPetscError, RuntimeError):
    """A PETSc solver did not converge; carries the converged reason and the parameter value."""

    exit_status = 3

    def __init__(self, what: str, reason: Union[int, str], **where: float) -> None:
        if isinstance(reason, str) and reason.startswith("reason "):       # a nested failure's own reason
            reason = reason[len("reason "):]
        self.what, self.reason, self.where = what, reason, where
        at = ", ".join(f"{k} = {v:.12g}" if isinstance(v, float) else f"{k} = {v}" for k, v in where.items())
        super().__init__(f"{what} did not converge (reason {reason}) at {at}")


class RecordFileError(HertzPetscError, IOError):
    """A record file is missing, corrupt, of another kind, belongs to another computation, or cannot be written."""

    exit_status = 4


class Terminated(BaseException):
    """SIGTERM or SIGHUP (what ``timeout``, ``kill`` and batch schedulers send), raised like KeyboardInterrupt so
    that ``finally`` blocks end child processes and leave record files consistent (status 128 + the signal)."""

    def __init__(self, signum):
        self.signum = signum
        super().__init__(signal.Signals(signum).name)


def check_signals(*args):
    """Run Python's pending signal handlers now (a KeyboardInterrupt or :class:`Terminated` is raised here): the
    monitor of a solver that calls no Python otherwise (SLEPc's PEP on assembled matrices), so that a signal ends it
    within an iteration. Takes and ignores the monitor's arguments."""
    ctypes.pythonapi.PyErr_CheckSignals()


def unwrapped(err: BaseException) -> BaseException:
    """The error behind ``err`` as petsc4py 3.18 raises it. Newer petsc4py/slepc4py (3.26) report an exception raised
    in a Python callback as a PETSc.Error of code 101 or -1, and some calls' errors as a SystemError, each chained to
    what it wraps by ``__cause__``; 3.18 raises the callback's exception or the PETSc.Error itself."""
    seen, e = set(), err
    while e.__cause__ is not None and id(e) not in seen:
        seen.add(id(e))
        wrapper = isinstance(e, SystemError) or (type(e).__name__ == "Error" and getattr(e, "ierr", 0) in (101, -1))
        if not wrapper:
            break
        e = e.__cause__
    return e


@contextmanager
def callbacks_raise():
    """Around a PETSc call whose callbacks are Python (right-hand sides, residuals, shell products, monitors): an
    exception raised in a callback leaves it as itself (a ParameterError, KeyboardInterrupt, :class:`Terminated`
    ...), and PETSc's own errors as PETSc.Error, whatever the petsc4py version (:func:`unwrapped`)."""
    try:
        yield
    except Exception as err:
        inner = unwrapped(err)
        if inner is err:
            raise
        raise inner from None


class PetscFailure(HertzPetscError, RuntimeError):
    """PETSc refused an operation (an unknown solver type, a bad option value ...): PETSc's own message."""

    exit_status = 5
