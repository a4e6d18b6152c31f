"""The house (issue 39; DESIGN.md, "Layers" and "Invariants"), read from the code: the ast of every module of
hertzpetsc/, imports inside functions included. No import circle; no import from a lower layer into a higher one;
the compatibility aliases only in hertzpetsc/compat.py, each old path still importable; and the invariants that a
reading of the code can check: no print outside the reporting modules, no law constructed outside the model, no
plot outside plotting, sys.argv and the options database read only where DESIGN.md says, every study on the base.

The checkers take sources, not files, so that the self-checks at the end feed them a bad package and see it flagged.
"""
import ast
import importlib
import os
import re
import subprocess
import sys
from dataclasses import dataclass

import pytest

from conftest import ROOT, script_env

# the code is the same on every rank, and a fresh interpreter is started below: serially only
pytestmark = pytest.mark.serial

PACKAGE = "hertzpetsc"

# The layers, lowest first (DESIGN.md, "Layers"): a module imports only from its own layer or a lower one.
LAYERS = ("numpy", "core", "studies", "surface")
SURFACE = {"hertzpetsc", "hertzpetsc.api", "hertzpetsc.compat"}

# where print() may be called: the library's console lines, the drivers' -help / check: / error: lines
REPORTING = {"hertzpetsc.console", "hertzpetsc.options"}
# where matplotlib may be imported: the figures, and api.plot_spectrum (a Figure, or the caller's axes)
PLOTTING = {"hertzpetsc.plotting", "hertzpetsc.api"}
# where sys.argv may be read, and why
ARGV = {"hertzpetsc.start": "the drivers' first call: PETSc started with the command line",
        "hertzpetsc.records": "provenance records the command line in every output file",
        "hertzpetsc.kernels": "python -m hertzpetsc.kernels, the kernel's build command"}
# where the options database is read besides setFromOptions (PETSc.Options()), and why (DESIGN.md, "Invariants")
OPTIONS_READERS = {
    "hertzpetsc.options": "the drivers' declared options, -help, unused and inconsistent options; user_set (the "
                          "one check of which options the user set: the code's defaults only where none is)",
    "hertzpetsc.start": "-h and --help kept for AppOptions",
    "hertzpetsc.twsolver": "-<prefix>solver and -<prefix>jacobian (the code's own role options); snes_type",
    "hertzpetsc.chain": "-<prefix>rhs_compiled",
    "hertzpetsc.shooting": "-shoot_gn_max_it, the Gauss-Newton's iteration limit",
    "hertzpetsc.floquet": "-<prefix>radius, the radius route's r (every multiplier outside it), and "
                          "-<prefix>slow_modes (its slow modes' stage)",
    "hertzpetsc.studies.base": "the roles' number-changing options, part of a record file's identity",
}
# where files are written: the record store and its atomic writers; the paper pipeline's step logs (a child's output)
WRITERS = {"hertzpetsc.records": "the record store, write_text, write_json, save_figure",
           "hertzpetsc.studies.paper": "each step's log: the child process's output streamed to it"}
# where COMM_WORLD may be used other than as the default of a ``comm`` argument (DESIGN.md: communicators are
# passed explicitly)
WORLD = {"hertzpetsc.options": "the drivers' process: options, errors, metadata",
         "hertzpetsc.start": "the drivers' first call", "hertzpetsc.console": "print0: rank 0 of the run"}
# where a module-level __getattr__ may be defined: the aliases, and the package's lazy exports (each name is
# defined in the module _MODULES lists: not an alias)
GETATTR = {"hertzpetsc.compat", "hertzpetsc"}
# where importlib.import_module may be called (an import the ast of imports does not see)
DYNAMIC = {"hertzpetsc.compat", "hertzpetsc"}
# the modules that define the laws (DESIGN.md: "nothing else constructs a law")
LAW_MODULES = {"hertzpetsc.law", "hertzpetsc.hertz", "hertzpetsc.toda", "hertzpetsc.fpu", "hertzpetsc.model"}
# classes of hertzpetsc/studies with run() or table() that are not studies.base.Study, and why (DESIGN.md,
# "Studies and records": not on the protocol)
NOT_ON_BASE = {
    "SolitaryStudy": "a table-only computation (k_alpha on grids), no records",
    "LongWaveStudy": "a table-only computation (eq. solapprox against a branch), no records",
    "CompactonStudy": "a table-only computation (compactons on the lattice), no records",
    "PaperPipeline": "runs the drivers as child processes; its progress file is its own, not a study's records",
}


@dataclass(frozen=True)
class Import:
    source: str
    target: str
    line: int
    level: str           # "module" (run when the module is imported) or "function" (run when the function is)


def module_name(relpath):
    """hertzpetsc/studies/base.py -> hertzpetsc.studies.base; hertzpetsc/__init__.py -> hertzpetsc."""
    parts = relpath[:-3].split(os.sep)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def package_sources(root=ROOT):
    """{module: source} of every module of hertzpetsc/."""
    out = {}
    for folder, _, files in os.walk(os.path.join(root, PACKAGE)):
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                with open(path) as f:
                    out[module_name(os.path.relpath(path, root))] = f.read()
    return out


def is_package(name, sources):
    return any(m.startswith(name + ".") for m in sources)


def _targets(node, source, sources):
    """The package's modules an import statement in ``source`` loads (a name imported from a module, not a
    submodule, is that module; the package's ``__version__`` is not an import of the surface)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names if a.name.split(".")[0] == PACKAGE]
    if node.level:
        base = source.split(".") if is_package(source, sources) else source.split(".")[:-1]
        base = base[:len(base) - node.level + 1]
        module = ".".join(base + ([node.module] if node.module else []))
    else:
        module = node.module or ""
    if module.split(".")[0] != PACKAGE:
        return []
    out = []
    for alias in node.names:
        if f"{module}.{alias.name}" in sources:
            out.append(f"{module}.{alias.name}")
        elif not (module == PACKAGE and alias.name == "__version__"):
            out.append(module)
    return out


def imports(sources):
    """Every import of a package module by another, at module level or inside a function."""
    out = []
    for source, text in sources.items():
        def walk(node, level):
            for child in ast.iter_child_nodes(node):
                if isinstance(child, (ast.Import, ast.ImportFrom)):
                    out.extend(Import(source, t, child.lineno, level) for t in _targets(child, source, sources)
                               if t != source)
                inner = "function" if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)) \
                    else level
                walk(child, inner)
        walk(ast.parse(text), "module")
    return out


def cycles(edges):
    """The strongly connected components of more than one module (or a module importing itself) of the graph
    {module: {imported}}: every import circle is inside one (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]
    nodes = set(edges) | {t for ts in edges.values() for t in ts}

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in edges.get(v, ()):
                out.append(sorted(comp))

    for v in sorted(nodes):
        if v not in index:
            visit(v)
    return out


def graph(edge_list, levels=("module", "function")):
    out = {}
    for e in edge_list:
        if e.level in levels:
            out.setdefault(e.source, set()).add(e.target)
    return out


def numpy_modules(design):
    """The modules DESIGN.md's module map marks ``(numpy``: nothing of PETSc imported when they are."""
    section = design.split("## Module map", 1)[1].split("\n## ", 1)[0]
    entries = re.split(r"\n(?=  \w+\.py |\S)", section)             # an entry and its continuation lines
    return {f"{PACKAGE}.{m.group(1)}" for m in (re.match(r"  (\w+)\.py (.*)", e, re.S) for e in entries)
            if m and "(numpy" in m.group(2)}


def layer(module, numpy_set):
    if module in SURFACE:
        return "surface"
    if module.startswith(f"{PACKAGE}.studies"):
        return "studies"
    return "numpy" if module in numpy_set else "core"


def upward(edge_list, numpy_set):
    """The imports from a lower layer into a higher one."""
    rank = {name: i for i, name in enumerate(LAYERS)}
    return [e for e in edge_list if rank[layer(e.target, numpy_set)] > rank[layer(e.source, numpy_set)]]


def _calls(tree):
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            yield node, f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else None


def prints(sources):
    """(module, line) of every print() and sys.stdout/sys.stderr .write() outside REPORTING."""
    out = []
    for module, text in sources.items():
        if module in REPORTING:
            continue
        for node, name in _calls(ast.parse(text)):
            f = node.func
            if name == "print" and isinstance(f, ast.Name) or name == "write" and ast.unparse(f) in (
                    "sys.stdout.write", "sys.stderr.write"):
                out.append((module, node.lineno))
    return out


def writes(sources):
    """(module, line) of every file opened to write (open() with a mode of w, a, x or +) or array or figure saved
    (np.save*, savefig, h5py.File with a writing mode) outside WRITERS."""
    out = []
    for module, text in sources.items():
        if module in WRITERS:
            continue
        for node, name in _calls(ast.parse(text)):
            mode = node.args[1] if len(node.args) > 1 else next((k.value for k in node.keywords if k.arg == "mode"),
                                                                  None)
            mode = mode.value if isinstance(mode, ast.Constant) and isinstance(mode.value, str) else ""
            if name in ("open", "File") and set(mode) & set("wax+") or name in ("save", "savez", "savez_compressed",
                                                                                "savetxt", "savefig"):
                out.append((module, node.lineno))
    return out


def world_uses(sources):
    """(module, line) of every PETSc.COMM_WORLD outside WORLD that is not ``comm if comm is not None else
    PETSc.COMM_WORLD`` (the default of an argument)."""
    out = []
    for module, text in sources.items():
        if module in WORLD:
            continue
        tree = ast.parse(text)
        defaults = {id(n.orelse) for n in ast.walk(tree) if isinstance(n, ast.IfExp)
                    and re.fullmatch(r"(\w+) is not None", ast.unparse(n.test)) and ast.unparse(n.body) ==
                    ast.unparse(n.test).split()[0]}
        out += [(module, n.lineno) for n in ast.walk(tree) if isinstance(n, ast.Attribute)
                and ast.unparse(n) == "PETSc.COMM_WORLD" and id(n) not in defaults]
    return out


def law_classes(sources):
    """The classes of the package that derive from law.InteractionLaw (by their bases' names)."""
    bases = {}
    for text in sources.values():
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ClassDef):
                bases[node.name] = {ast.unparse(b).split(".")[-1] for b in node.bases}
    found, grew = {"InteractionLaw"}, True
    while grew:
        new = {c for c, bs in bases.items() if bs & found} - found
        found |= new
        grew = bool(new)
    return found


def laws_constructed(sources):
    """(module, line, class) of every law constructed outside LAW_MODULES."""
    classes = law_classes(sources)
    return [(module, node.lineno, name) for module, text in sources.items() if module not in LAW_MODULES
            for node, name in _calls(ast.parse(text)) if name in classes]


def attribute_uses(sources, dotted, allowed):
    """(module, line) of every use of the attribute chain ``dotted`` (e.g. "sys.argv") outside ``allowed``."""
    return [(module, node.lineno) for module, text in sources.items() if module not in allowed
            for node in ast.walk(ast.parse(text)) if isinstance(node, ast.Attribute) and ast.unparse(node) == dotted]


def external_imports(sources, top, allowed):
    """(module, line) of every import of the top-level package ``top`` (e.g. matplotlib) outside ``allowed``."""
    out = []
    for module, text in sources.items():
        if module in allowed:
            continue
        for node in ast.walk(ast.parse(text)):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else []
            out += [(module, node.lineno) for n in names if n.split(".")[0] == top]
    return out


def module_level_petsc(sources, modules):
    """(module, line) of the imports of petsc4py, slepc4py or mpi4py at module level in ``modules`` (typing-only
    imports aside)."""
    out = []
    for module in modules:
        for node in ast.parse(sources[module]).body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                out += [(module, node.lineno) for n in names if n.split(".")[0] in ("petsc4py", "slepc4py", "mpi4py")]
    return out


def aliases(sources):
    """(module, line, what) of every compatibility alias outside GETATTR / compat: a module-level __getattr__, a
    module-level ``Name = OtherName`` of a class or function (a second name for it), importlib.import_module."""
    out = []
    for module, text in sources.items():
        tree = ast.parse(text)
        defined = {n.name for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef))}
        imported = {(a.asname or a.name).split(".")[0] for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))
                    for a in n.names}
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and node.name == "__getattr__" and module not in GETATTR:
                out.append((module, node.lineno, "module-level __getattr__"))
            if (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)
                    and isinstance(node.value, ast.Name) and node.value.id in defined | imported
                    and not node.targets[0].id.startswith("_")):
                out.append((module, node.lineno, f"{node.targets[0].id} = {node.value.id}"))
        if module not in DYNAMIC:
            out += [(module, node.lineno, "importlib.import_module") for node, name in _calls(tree)
                    if name == "import_module"]
    return out


def study_classes_off_base(sources):
    """The classes of hertzpetsc/studies with run() or table() that do not derive from studies.base.Study."""
    bases, studies = {}, set()
    for module, text in sources.items():
        if not module.startswith(f"{PACKAGE}.studies"):
            continue
        for node in ast.parse(text).body:
            if isinstance(node, ast.ClassDef):
                bases[node.name] = [ast.unparse(b).split(".")[-1] for b in node.bases]
                if {f.name for f in node.body if isinstance(f, ast.FunctionDef)} & {"run", "table"}:
                    studies.add(node.name)

    def derives(name):
        return name == "Study" or any(derives(b) for b in bases.get(name, ()))
    return sorted(c for c in studies if not derives(c))


# --- the package as it is -----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def sources():
    return package_sources()


@pytest.fixture(scope="module")
def design():
    with open(os.path.join(ROOT, "DESIGN.md")) as f:
        return f.read()


def test_no_import_circle(sources):
    edges = imports(sources)
    assert not cycles(graph(edges, ("module",))), "import circles at module level"
    found = cycles(graph(edges))
    assert not found, "import circles (imports inside functions included): " + "; ".join(
        " -> ".join(c) + ": " + ", ".join(f"{e.source}:{e.line} -> {e.target}" for e in edges
                                          if e.source in c and e.target in c) for c in found)


def test_no_import_from_a_lower_layer_into_a_higher_one(sources, design):
    numpy_set = numpy_modules(design)
    assert {"hertzpetsc.law", "hertzpetsc.model", "hertzpetsc.records"} <= numpy_set <= set(sources)
    up = upward(imports(sources), numpy_set)
    assert not up, [f"{e.source} ({layer(e.source, numpy_set)}) line {e.line} -> {e.target} "
                    f"({layer(e.target, numpy_set)})" for e in up]
    assert not module_level_petsc(sources, numpy_set), "a (numpy) module of DESIGN.md's map imports PETSc"
    scripts = {f[:-3] for f in os.listdir(os.path.join(ROOT, "scripts")) if f.endswith(".py")} | {"scripts"}
    for top in sorted(scripts - {PACKAGE}):                      # drivers are above the package
        assert not external_imports(sources, top, set()), f"the package imports the driver {top}"


def test_the_layers_and_every_module_are_in_design(sources, design):
    """DESIGN.md states the layer order the test checks, and its module map names every module."""
    layers = design.split("## Layers", 1)[1].split("\n## ", 1)[0]
    assert re.search(r"numpy.*<.*core.*<.*studies.*<.*surface.*<.*scripts", layers.replace("\n", " ")), \
        "DESIGN.md's Layers section states the order numpy < core < studies < surface < scripts"
    section = design.split("## Module map", 1)[1].split("\n## ", 1)[0]
    mapped = set(re.findall(r"^  (\w+)\.py ", section, re.M))
    top = {m.split(".")[1] for m in sources if m.count(".") == 1 and not m.startswith(f"{PACKAGE}.studies")}
    assert top <= mapped, f"modules missing from DESIGN.md's module map: {sorted(top - mapped)}"


def test_compatibility_aliases_live_in_compat_only(sources):
    assert not aliases(sources), aliases(sources)


def test_every_old_import_path_still_works(sources):
    """Each alias of hertzpetsc.compat, imported the way users' scripts import it, is the object at its new place;
    the old modules define none of them themselves (the table would be dead)."""
    from hertzpetsc import compat
    for old, names in compat.NAMES.items():
        own = set()
        for node in ast.parse(sources[old]).body:
            if isinstance(node, (ast.ClassDef, ast.FunctionDef)):
                own.add(node.name)
            elif isinstance(node, (ast.Import, ast.ImportFrom)):
                own |= {(a.asname or a.name).split(".")[0] for a in node.names}
            elif isinstance(node, ast.Assign):
                own |= {t.id for target in node.targets for t in ast.walk(target) if isinstance(t, ast.Name)}
        for name, (module, new) in names.items():
            assert name not in own, f"{old}.{name} is defined or imported there: no alias needed"
            namespace = {}
            exec(f"from {old} import {name}", namespace)
            assert namespace[name] is getattr(importlib.import_module(module), new)
            assert getattr(importlib.import_module(old), name) is namespace[name]
        with pytest.raises(ImportError):
            exec(f"from {old} import no_such_name", {})
    for old, new in compat.MODULES.items():
        namespace = {}
        exec(f"import {old} as moved", namespace)
        assert namespace["moved"] is importlib.import_module(new) is sys.modules[old]
        assert namespace["moved"].__spec__.name == new                   # reload and pickling see the real one
        package, _, name = old.rpartition(".")
        exec(f"from {package} import {name} as moved_too", namespace)
        assert namespace["moved_too"] is namespace["moved"]
    from hertzpetsc.errors import BranchFileError, RecordFileError, RunFileError
    from hertzpetsc.studies.dealing import dealt
    from hertzpetsc.studies.precompression import StabilityMap
    from hertzpetsc.continuation import BranchContinuation
    from hertzpetsc.dealing import dealt as dealt_now
    from hertzpetsc.qbranch import BranchContinuation as now
    from hertzpetsc.studies.maps import StabilityMap as map_now
    assert BranchFileError is RunFileError is RecordFileError and dealt is dealt_now
    assert BranchContinuation is now and StabilityMap is map_now


def test_old_import_paths_work_in_a_fresh_interpreter():
    """A user's script that imports old paths first thing (nothing of the package imported before)."""
    code = ("from hertzpetsc.continuation import BranchContinuation, ContinuationParameters\n"
            "from hertzpetsc.errors import BranchFileError\n"
            "from hertzpetsc.studies.dealing import dealt\n"
            "import hertzpetsc.studies.precompression as p\n"
            "from hertzpetsc.qbranch import BranchContinuation as B\n"
            "from hertzpetsc.records import RecordFileError, check_stores\n"
            "from hertzpetsc.studies.base import check_stores as c\n"
            "assert B is BranchContinuation and BranchFileError is RecordFileError and c is check_stores\n"
            "print(p.StabilityMap.__module__, dealt.__module__)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=script_env())
    assert r.returncode == 0 and r.stdout.split() == ["hertzpetsc.studies.maps", "hertzpetsc.dealing"], r.stderr


def test_the_library_prints_only_through_its_reporting_modules(sources):
    assert not prints(sources), f"print outside {sorted(REPORTING)}: {prints(sources)}"


def test_files_are_written_only_through_the_record_store(sources):
    assert not writes(sources), f"files written outside {sorted(WRITERS)}: {writes(sources)}"


def test_communicators_are_passed_explicitly(sources):
    assert not world_uses(sources), f"COMM_WORLD used but as a comm argument's default: {world_uses(sources)}"


def test_nothing_else_constructs_a_law(sources):
    assert {"HertzLaw", "RescaledLaw"} <= law_classes(sources)
    assert not laws_constructed(sources), laws_constructed(sources)


def test_plots_argv_and_options_only_where_design_says(sources):
    assert not external_imports(sources, "matplotlib", PLOTTING)
    assert not [e for e in imports(sources) if e.target == "hertzpetsc.plotting" and e.source not in SURFACE], \
        "plotting is called by drivers and the API, never by solvers or studies"
    assert not attribute_uses(sources, "sys.argv", ARGV), attribute_uses(sources, "sys.argv", ARGV)
    readers = attribute_uses(sources, "PETSc.Options", OPTIONS_READERS)
    assert not readers, f"the options database read outside {sorted(OPTIONS_READERS)}: {readers}"
    unused = [m for m in OPTIONS_READERS if not attribute_uses({m: sources[m]}, "PETSc.Options", set())]
    assert not unused, f"OPTIONS_READERS lists modules that read no option: {unused}"


def test_every_solver_prefix_is_a_declared_role(sources):
    """A solver role is declared once, in hertzpetsc.roles.REGISTRY: every ``*_PREFIX = "..."`` of the package is one
    of its prefixes."""
    from hertzpetsc.roles import REGISTRY
    constants = {node.value.value for text in sources.values() for node in ast.walk(ast.parse(text))
                 if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)
                 and node.targets[0].id.endswith("_PREFIX") and isinstance(node.value, ast.Constant)}
    assert len(constants) >= 13 and constants <= set(REGISTRY), sorted(constants - set(REGISTRY))


def test_every_study_is_on_the_base(sources):
    off = study_classes_off_base(sources)
    assert set(off) == set(NOT_ON_BASE), f"not on studies.base.Study: {off}; listed: {sorted(NOT_ON_BASE)}"


# --- the checkers flag a bad package (self-checks) ----------------------------------------------------------------
BAD = {
    "hertzpetsc": "from . import compat\n",
    "hertzpetsc.law": "class InteractionLaw:\n    pass\n",
    "hertzpetsc.hertz": "from .law import InteractionLaw\nclass HertzLaw(InteractionLaw):\n    pass\n",
    "hertzpetsc.model": "from .hertz import HertzLaw\n",
    "hertzpetsc.compat": "",
    "hertzpetsc.tangent": "def f():\n    from .studies.dealing import dealt\n    print('x')\n",
    "hertzpetsc.continuation": "def __getattr__(name):\n    from . import qbranch\n    return getattr(qbranch, name)\n",
    "hertzpetsc.qbranch": "from .advdelay import P\n",
    "hertzpetsc.advdelay": "from .continuation import C\nfrom .errors import RecordFileError\n"
                           "BranchFileError = RecordFileError\n",
    "hertzpetsc.errors": "class RecordFileError(Exception):\n    pass\n",
    "hertzpetsc.diagnostics": "from .hertz import HertzLaw\nlaw = HertzLaw(1.5)\nimport sys\nsys.stderr.write('x')\n"
                              "open('t.md', 'w').write('x')\nopen('t.md').read()\n",
    "hertzpetsc.studies": "",
    "hertzpetsc.studies.dealing": "def dealt():\n    pass\n",
    "hertzpetsc.studies.maps": "from .precompression import wave_orbit\nclass Map:\n    def run(self):\n"
                               "        pass\n",
    "hertzpetsc.studies.precompression": "def __getattr__(name):\n    from . import maps\n"
                                         "    return getattr(maps, name)\n",
}


def test_the_checkers_flag_a_bad_package():
    """A synthetic package with the faults issue 39 found (the advdelay -> continuation -> qbranch circle through a
    __getattr__, the maps <-> precompression circle, tangent -> studies.dealing, an alias, a print, a law built in
    diagnostics, a study off the base): every checker flags its fault, and only it."""
    edges = imports(BAD)
    assert sorted(map(sorted, cycles(graph(edges)))) == [
        ["hertzpetsc.advdelay", "hertzpetsc.continuation", "hertzpetsc.qbranch"],
        ["hertzpetsc.studies.maps", "hertzpetsc.studies.precompression"]]
    assert cycles(graph(edges, ("module",))) == []                    # both close through a function's import
    assert cycles({"a": {"a"}}) == [["a"]] and cycles({"a": {"b"}, "b": {"c"}}) == []
    up = upward(edges, {"hertzpetsc.law", "hertzpetsc.hertz"})
    assert [(e.source, e.target, e.level) for e in up] == [
        ("hertzpetsc.tangent", "hertzpetsc.studies.dealing", "function")]
    assert upward([Import("hertzpetsc.law", "hertzpetsc.model", 1, "module")], {"hertzpetsc.law"}) != []
    assert sorted(aliases(BAD)) == [("hertzpetsc.advdelay", 3, "BranchFileError = RecordFileError"),
                                    ("hertzpetsc.continuation", 1, "module-level __getattr__"),
                                    ("hertzpetsc.studies.precompression", 1, "module-level __getattr__")]
    assert sorted(prints(BAD)) == [("hertzpetsc.diagnostics", 4), ("hertzpetsc.tangent", 3)]
    assert laws_constructed(BAD) == [("hertzpetsc.diagnostics", 2, "HertzLaw")]
    assert writes(BAD) == [("hertzpetsc.diagnostics", 5)]
    assert writes({"m": "import numpy as np\nnp.savez('x.npz', a=1)\nf = open('x', mode='ab')\n"}) == [("m", 2), ("m", 3)]
    assert study_classes_off_base(BAD) == ["Map"]
    assert module_level_petsc({"m": "from petsc4py import PETSc\ndef f():\n    import slepc4py\n"}, ["m"]) == [("m", 1)]
    assert attribute_uses({"m": "import sys\nx = sys.argv\n"}, "sys.argv", set()) == [("m", 2)]
    assert world_uses({"m": "def f(comm=None):\n    comm = comm if comm is not None else PETSc.COMM_WORLD\n"
                            "    return PETSc.COMM_WORLD.getSize()\n"}) == [("m", 3)]
    assert external_imports({"m": "import matplotlib.pyplot as plt\n"}, "matplotlib", set()) == [("m", 1)]
