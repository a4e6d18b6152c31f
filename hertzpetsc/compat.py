"""The names users' code may still import from where they were before they moved or were renamed: each old path
resolves to the object at its place now. The one place of every compatibility alias (tests/test_architecture.py
keeps them here); the modules themselves hold none and import nothing for them.

:func:`install` (called by ``import hertzpetsc``, before any of its modules is imported) puts an import hook in
front of ``sys.meta_path``: a module of :data:`NAMES` gets a module-level ``__getattr__`` (PEP 562) that imports
the new place when an old name is first asked for, and a module path of :data:`MODULES` is the module now.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
from types import ModuleType
from typing import Any, Callable, Optional, Sequence

_QBRANCH = ("BranchContinuation", "ContinuationParameters", "FixedGrid", "RefiningGrid", "continue_branch",
            "paper_targets", "regrid_half_profile")
_MAP = ("StabilityMap", "MapParameters", "map_table", "MAP_FORMAT", "MAP_FIELDS")

# {old module: {old name: (module now, name now)}}
NAMES: dict[str, dict[str, tuple[str, str]]] = {
    # the q-branch moved out of the continuation layer (the one-model merge, commit 464f95d)
    "hertzpetsc.continuation": {name: ("hertzpetsc.qbranch", name) for name in _QBRANCH},
    # the stability map moved to its own study module (issue 23)
    "hertzpetsc.studies.precompression": {name: ("hertzpetsc.studies.maps", name) for name in _MAP},
    # the errors about files, before the record store had one
    "hertzpetsc.errors": {"BranchFileError": ("hertzpetsc.errors", "RecordFileError"),
                          "RunFileError": ("hertzpetsc.errors", "RecordFileError")},
    # the -check of record files moved down to the record store (issue 39: options no longer imports a study)
    "hertzpetsc.studies.base": {"check_stores": ("hertzpetsc.records", "check_stores"),
                                # the solver roles' probe and Floquet routes moved to their registry (issue 39)
                                "configure_roles": ("hertzpetsc.roles", "configure")},
    "hertzpetsc.studies.floquet": {"METHODS": ("hertzpetsc.roles", "FLOQUET_ROUTES")},
}

# {old module path: module now}: modules that moved down a layer (issue 39)
MODULES: dict[str, str] = {
    "hertzpetsc.studies.dealing": "hertzpetsc.dealing",
}


def resolve(module: str, name: str) -> Any:
    """The object the old ``module.name`` stands for (``AttributeError`` if it is not an alias)."""
    try:
        new_module, new_name = NAMES[module][name]
    except KeyError:
        raise AttributeError(f"module {module!r} has no attribute {name!r}") from None
    return getattr(importlib.import_module(new_module), new_name)


def _module_getattr(module: str) -> Callable[[str], Any]:
    def __getattr__(name: str) -> Any:
        return resolve(module, name)
    __getattr__.__doc__ = f"The old names of {module} (:data:`hertzpetsc.compat.NAMES`)."
    return __getattr__


def _add_aliases(module: ModuleType) -> None:
    if "__getattr__" not in vars(module):
        module.__getattr__ = _module_getattr(module.__name__)


class _AliasedLoader(importlib.abc.Loader):
    """The module's own loader, and the aliases added once the module has run."""

    def __init__(self, loader: importlib.abc.Loader) -> None:
        self.loader = loader

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> Optional[ModuleType]:
        return self.loader.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        self.loader.exec_module(module)
        _add_aliases(module)

    def __getattr__(self, name: str) -> Any:             # get_source, get_filename, ... of the file's loader
        return getattr(self.loader, name)


class _MovedModule(importlib.abc.Loader):
    """An old module path: the module at its place now."""

    def __init__(self, target: str) -> None:
        self.target = target

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        module = importlib.import_module(self.target)
        self.spec = module.__spec__
        return module

    def exec_module(self, module: ModuleType) -> None:
        module.__spec__ = self.spec                          # the import system set the old path's spec on it


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname: str, path: Optional[Sequence[str]],
                  target: Optional[ModuleType] = None) -> Optional[importlib.machinery.ModuleSpec]:
        if fullname in MODULES:
            return importlib.util.spec_from_loader(fullname, _MovedModule(MODULES[fullname]))
        if fullname in NAMES:
            spec = importlib.machinery.PathFinder.find_spec(fullname, path, target)
            if spec is not None and spec.loader is not None:
                spec.loader = _AliasedLoader(spec.loader)
            return spec
        return None


def install() -> None:
    """Put the hook in front of ``sys.meta_path`` (once), and the aliases into the modules already imported."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())
    for name in NAMES:
        if name in sys.modules:
            _add_aliases(sys.modules[name])
