"""The package as people adopt it (issue 40): one version, reported by the package and agreed by the citation file
and the changelog; a licence; a citation file that parses as CFF 1.2.0; every public name typed."""
import dataclasses
import importlib
import inspect
import os
import pkgutil
import re
import subprocess
import sys
import typing

import numpy as np
import numpy.typing
import pytest
from petsc4py import PETSc

import hertzpetsc
from conftest import ROOT, script_env

try:
    import yaml
except ImportError:                                     # the check below reads the file's few keys line by line
    yaml = None


def read(name):
    with open(os.path.join(ROOT, name)) as f:
        return f.read()


def test_the_version_is_written_once_and_reported():
    """pyproject.toml takes the version from hertzpetsc.__version__ (no second copy to drift), and a fresh
    interpreter reports it without starting PETSc."""
    text = read("pyproject.toml")
    assert 'dynamic = ["version"]' in text and 'version = {attr = "hertzpetsc.__version__"}' in text
    assert not re.search(r'^version\s*=\s*"', text, re.M)                  # no literal version
    assert re.fullmatch(r"\d+\.\d+\.\d+", hertzpetsc.__version__)
    r = subprocess.run([sys.executable, "-c", "import sys, hertzpetsc as hz; print(hz.__version__); "
                        "print('petsc4py.PETSc' in sys.modules)"], capture_output=True, text=True, cwd=ROOT,
                       env=script_env())
    assert r.returncode == 0 and r.stdout.split() == [hertzpetsc.__version__, "False"], r.stderr


def cff_fields(text):
    """The CFF file's top-level scalars and its references' titles: by yaml when installed, else line by line (the
    file's own layout: 'key: value' at column 0, '- type:' items under 'references:')."""
    if yaml is not None:
        data = yaml.safe_load(text)
        top = {k: v for k, v in data.items() if not isinstance(v, (list, dict))}
        return ({k: str(v) for k, v in top.items()}, [r["title"] for r in data.get("references", [])],
                [a.get("name", a.get("family-names")) for a in data["authors"]])
    top, titles, authors, section = {}, [], [], None
    for line in text.splitlines():
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        m = re.match(r"^([a-z-]+):\s*(.*)$", line)
        if m:
            section = m.group(1)
            if m.group(2) and m.group(2) != ">-":
                top[section] = m.group(2).strip('"')
            continue
        m = re.match(r"^\s+(?:- )?(title|name|family-names):\s*(.*)$", line)
        if m and section == "references" and m.group(1) == "title":
            titles.append(m.group(2).strip('"'))
        elif m and section == "authors":
            authors.append(m.group(2).strip('"'))
    for key in ("message", "abstract"):                    # folded blocks: present, their text not needed here
        if re.search(rf"^{key}:", text, re.M):
            top.setdefault(key, "(folded)")
    return top, titles, authors


def test_citation_file_names_this_version_and_the_paper():
    """CITATION.cff: the keys CFF 1.2.0 requires, this version, the licence of LICENSE, and the reference paper with
    the title the README's BibTeX gives (the paper's LaTeX source's); the README cites this version too."""
    top, titles, authors = cff_fields(read("CITATION.cff"))
    assert top["cff-version"] == "1.2.0" and top["message"] and top["title"] and authors == ["hertzpetsc developers"]
    assert top["version"] == hertzpetsc.__version__
    assert top["license"] == "BSD-2-Clause" and read("LICENSE").startswith("BSD 2-Clause License")
    readme = read("README.md")
    paper = re.search(r"@article\{James2012granular,.*?title\s*=\s*\{(.*?)\}", readme, re.S).group(1)
    assert titles == [paper] == ["Periodic travelling waves and compactons in granular chains"]
    software = re.search(r"@software\{hertzpetsc,.*?version\s*=\s*\{(.*?)\}", readme, re.S).group(1)
    assert software == hertzpetsc.__version__                  # the README's "How to cite"


def test_changelog_has_a_section_for_this_version():
    assert re.search(rf"^## {re.escape(hertzpetsc.__version__)}\b", read("CHANGELOG.md"), re.M)


# --- every public name typed ------------------------------------------------------------------------------------
def public_functions():
    """(qualified name, function) of every name of hertzpetsc.__all__ that is a function, and of every public method
    (and __init__, and property getters) of its classes, the package's base classes included."""
    seen = set()
    for name in hertzpetsc.__all__:
        obj = getattr(hertzpetsc, name)
        if not inspect.isclass(obj):
            seen.add(obj)
            yield name, obj
            continue
        for klass in obj.__mro__:
            if not klass.__module__.startswith("hertzpetsc"):
                continue
            for attr, value in vars(klass).items():
                if attr.startswith("_") and attr != "__init__":
                    continue
                f = value.fget if isinstance(value, property) else getattr(value, "__func__", value)
                f = inspect.unwrap(f) if hasattr(f, "__wrapped__") else f      # PETSc's log-event decorator
                if inspect.isfunction(f) and f not in seen:
                    seen.add(f)
                    yield f"{klass.__name__}.{attr}", f


def namespace():
    """The names an annotation may use besides its module's own (those imported for type checking only among
    them): typing's, PETSc, SLEPc, numpy, ArrayLike, matplotlib and every class of the package's modules."""
    import matplotlib.axes
    import matplotlib.figure
    from slepc4py import SLEPc
    names = dict(vars(typing), PETSc=PETSc, SLEPc=SLEPc, np=np, ArrayLike=numpy.typing.ArrayLike, matplotlib=matplotlib)
    for info in pkgutil.walk_packages(hertzpetsc.__path__, "hertzpetsc."):
        if info.name.rsplit(".", 1)[-1].startswith("_"):             # the compiled kernel's library
            continue
        module = importlib.import_module(info.name)
        names.update({k: v for k, v in vars(module).items() if inspect.isclass(v)
                      and v.__module__.startswith("hertzpetsc")})
    return names


# the public calls that take *args / **kwargs, and why; each annotated. The driven studies' constructors (called
# ResponseCurve.__init__ and so on) declare their two calls as typing overloads instead.
VARIADIC = {
    "DrivenStudy.__init__": "the protocol's (params, comm, output, mode) or the call of before the protocol, "
                            "declared by each driven study's overloads",
    "DrivenStudy.legacy": "the call of before the protocol, whose positions depend on each study's parameters",
    "ConvergenceError.__init__": "where the solver failed: the parameters by name (q=..., a=...), as many as it has",
}


def unannotated(qualname, f):
    """The parameters (self and cls aside) and the return of f that have no annotation."""
    sig = inspect.signature(f)
    out = [f"{qualname}({p.name})" for p in sig.parameters.values()
           if p.name not in ("self", "cls") and p.annotation is p.empty]
    if sig.return_annotation is sig.empty and f.__name__ != "__init__":
        out.append(f"{qualname} -> ?")
    return out


def test_every_public_name_has_type_hints():
    """Each parameter (self and cls aside) and each return of the public surface is annotated, every annotation
    names something that exists, and a public call takes *args or **kwargs only where VARIADIC says why or where
    its overloads (typing.overload) declare its calls, each of them annotated."""
    missing, unresolved, variadic, names = [], [], [], namespace()
    for qualname, f in public_functions():
        missing += unannotated(qualname, f)
        if any(p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD) for p in inspect.signature(f).parameters.values()):
            overloads = typing.get_overloads(f)
            if qualname not in VARIADIC and len(overloads) < 2:
                variadic.append(qualname)
            for g in overloads:
                missing += unannotated(f"{qualname} (overload)", g)
        try:
            typing.get_type_hints(f, globalns=dict(names, **vars(sys.modules[f.__module__])))
        except Exception as err:                               # an annotation that names nothing
            unresolved.append(f"{qualname}: {err}")
    assert not missing, f"{len(missing)} without type hints: {missing}"
    assert not unresolved, unresolved
    assert not variadic, f"(*args, **kwargs) without a reason or overloads: {variadic}"


@pytest.mark.parametrize("name", ["ResponseCurve", "LinearResonances", "WaveEnds", "Generation"])
def test_the_driven_studies_declare_both_their_calls(name):
    """The driven studies take the protocol's call and the call of before it (docs/api.md): both are declared as
    overloads whose first parameter is the study's parameters, respectively the first parameter those require."""
    study = getattr(hertzpetsc, name)
    first = [list(inspect.signature(g).parameters)[1] for g in typing.get_overloads(study.__init__)]
    required = [f.name for f in dataclasses.fields(study.Parameters)][0]
    assert first == ["params", required], first
