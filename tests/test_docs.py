"""The documentation's promises: every link of README.md and docs/*.md resolves (files, images, anchors), no number
the README quoted before its results moved to docs/ is lost, every results file kind is documented in
docs/schemas.md, and the schemas' numpy-only examples run on the committed results.

File checks only, no PETSc: run in the serial pass (repeating them on 2 ranks checks nothing more).
"""
import ast
import glob
import importlib.util
import io
import os
import re
import subprocess
from contextlib import redirect_stdout

import pytest

pytestmark = pytest.mark.serial

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOCS = os.path.join(ROOT, "docs")
PAGES = [os.path.join(ROOT, "README.md")] + sorted(glob.glob(os.path.join(DOCS, "*.md")))
SCHEMAS = os.path.join(DOCS, "schemas.md")


def _numbers_module():
    """tests/data/make_readme_numbers.py: the one number extraction (the list was made with it)."""
    path = os.path.join(ROOT, "tests", "data", "make_readme_numbers.py")
    spec = importlib.util.spec_from_file_location("make_readme_numbers", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


NUMBERS = _numbers_module()


# --- Markdown, as GitHub reads it -----------------------------------------------------------------------------
FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", re.M | re.S)
CODE_SPAN = re.compile(r"`[^`\n]*`")
LINK = re.compile(r"!?\[[^\]\n]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
HEADING = re.compile(r"^(#{1,6})[ \t]+(.+?)[ \t#]*$", re.M)


def prose(text):
    """The text without fenced code blocks (their content is code, not Markdown)."""
    return FENCE.sub("", text)


def slug(heading):
    """GitHub's anchor of a heading: lower case, punctuation other than '-' and '_' dropped, spaces to '-'."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(text):
    """The anchors of a page's headings, duplicates numbered as GitHub does (-1, -2, ...)."""
    seen, out = {}, set()
    for _, title in HEADING.findall(prose(text)):
        base = slug(title)
        n = seen.get(base, 0)
        seen[base] = n + 1
        out.add(base if n == 0 else f"{base}-{n}")
    return out


def links(text):
    """Every link and image target of a page, outside code."""
    return LINK.findall(CODE_SPAN.sub("", prose(text)))


def broken_links(path, root=ROOT):
    """(target, why) for every relative link of ``path`` that does not resolve to a file inside ``root``, or whose
    '#anchor' is not a heading of the page it points to."""
    with open(path) as f:
        text = f.read()
    here = os.path.dirname(path)
    bad = []
    for target in links(text):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):          # http:, https:, mailto: ...
            continue
        file_part, _, anchor = target.partition("#")
        resolved = os.path.normpath(os.path.join(here, file_part)) if file_part else path
        if os.path.commonpath([os.path.abspath(root), os.path.abspath(resolved)]) != os.path.abspath(root):
            bad.append((target, "outside the repository"))
            continue
        if not os.path.exists(resolved):
            bad.append((target, "no such file"))
            continue
        if anchor:
            if not resolved.endswith(".md"):
                bad.append((target, "an anchor into a file that is not a Markdown page"))
                continue
            with open(resolved) as f:
                if anchor not in anchors(f.read()):
                    bad.append((target, f"no heading with anchor #{anchor} in {os.path.relpath(resolved, root)}"))
    return bad


def test_every_link_and_image_resolves():
    assert len(PAGES) >= 10, PAGES                         # the README and the docs pages are there
    bad = {os.path.relpath(p, ROOT): broken_links(p) for p in PAGES}
    bad = {p: b for p, b in bad.items() if b}
    assert not bad, bad
    # the check saw the links it should: the README links to every page of docs/
    with open(PAGES[0]) as f:
        readme_targets = {t.partition("#")[0] for t in links(f.read())}
    missing = [os.path.relpath(p, ROOT) for p in PAGES[1:] if os.path.relpath(p, ROOT) not in readme_targets]
    assert not missing, f"docs pages the README does not link to: {missing}"


def test_link_checker_finds_broken_links(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "other.md").write_text("# Other page\n\n## A `code` heading (3.2)\n\n## Twice\n\n## Twice\n")
    page = tmp_path / "docs" / "page.md"
    page.write_text("# Page\n\n[ok](other.md#a-code-heading-32) [ok](other.md#twice-1) [ok](#page) "
                    "[web](https://example.org/x)\n[gone](missing.md) ![img](../figures/none.png) "
                    "[anchor](other.md#nope) [self](#absent) [out](../../elsewhere.md)\n\n"
                    "```sh\n[not a link](nowhere.md)\n```\n`[code](nowhere.md)`\n")
    bad = dict(broken_links(str(page), str(tmp_path)))
    assert set(bad) == {"missing.md", "../figures/none.png", "other.md#nope", "#absent", "../../elsewhere.md"}, bad


# --- numbers ---------------------------------------------------------------------------------------------------
def old_numbers():
    with open(NUMBERS.LIST) as f:
        return [line.strip() for line in f if line.strip() and not line.startswith("#")]


def lost_numbers(wanted, text):
    """The numbers of ``wanted`` that are not a whole number token of ``text``."""
    present = set(NUMBERS.numbers(text, minimum=0))
    return [n for n in wanted if n not in present]


def test_no_number_of_the_old_readme_is_lost():
    wanted = old_numbers()
    assert len(wanted) > 300, len(wanted)                  # the list of commit b3184da's README (368 numbers)
    corpus = ""
    for p in PAGES:
        with open(p) as f:
            corpus += f.read() + "\n"
    lost = lost_numbers(wanted, corpus)
    assert not lost, f"numbers of the old README quoted nowhere in README.md or docs/: {lost}"


def test_number_check_finds_a_lost_number():
    text = "k_3/2 = 1.35678 (n = 160); rho = 1.0837, E = 9.73e-07 in x86_64 with branch_alpha1.5.npz and v3.18.5"
    assert lost_numbers(["1.35678", "9.73e-07"], text) == []
    assert lost_numbers(["1.3567", "1.083", "9.73e-7", "3.18", "1.5"], text) == ["1.3567", "1.083", "9.73e-7",
                                                                                 "3.18", "1.5"]
    assert NUMBERS.numbers("2.00 1e-10 0.066 87684.0 0.0628 5.2e-06 1.3e-05 12.8x") == ["2.00", "87684.0", "0.0628",
                                                                                     "12.8"]


def test_number_list_is_the_old_readme_s():
    """tests/data/readme_numbers.txt is what make_readme_numbers.py extracts from commit b3184da's README."""
    have = subprocess.run(["git", "cat-file", "-e", f"{NUMBERS.COMMIT}:README.md"], cwd=ROOT, capture_output=True)
    if have.returncode != 0:
        pytest.skip(f"commit {NUMBERS.COMMIT} is not in this clone's history")
    assert NUMBERS.numbers(NUMBERS.old_readme(ROOT)) == old_numbers()


# --- schemas ---------------------------------------------------------------------------------------------------
from hertzpetsc.records import ABOUT, schema_page  # noqa: E402  (numpy only)


def schema_sections():
    """{heading: body} of docs/schemas.md's '## ' sections."""
    with open(SCHEMAS) as f:
        parts = re.split(r"^## +(.+)$", prose(f.read()), flags=re.M)
    return dict(zip(parts[1::2], parts[2::2]))


def code_kinds():
    """Every record kind ``hertzpetsc-<kind>-<n>`` named in the package and the scripts."""
    kinds = set()
    for path in glob.glob(os.path.join(ROOT, "hertzpetsc", "**", "*.py"), recursive=True) + \
            glob.glob(os.path.join(ROOT, "scripts", "*.py")):
        with open(path) as f:
            kinds |= set(re.findall(r"hertzpetsc-[a-z][a-z0-9-]*-\d+\b", f.read()))
    return kinds


def test_every_record_kind_has_a_schema():
    with open(SCHEMAS) as f:
        text = f.read()
    patterns = [re.escape(h).replace(re.escape("<name>"), "[a-z]+") for h in re.findall(r"hertzpetsc-[\w<>-]+-\d+", text)]
    kinds = code_kinds()
    assert len(kinds) >= 16, sorted(kinds)
    undocumented = [k for k in sorted(kinds) if not any(re.fullmatch(p, k) for p in patterns)]
    assert not undocumented, f"record kinds without a schema in docs/schemas.md: {undocumented}"


def test_schemas_name_every_entry_of_the_committed_files():
    np = pytest.importorskip("numpy")
    sections = schema_sections()
    files = sorted(glob.glob(os.path.join(ROOT, "results", "*.npz")))
    assert len(files) >= 10
    missing = {}
    for path in files:
        with np.load(path, allow_pickle=False) as z:
            kind, keys = str(z["format"]), list(z.files)
        body = next((b for h, b in sections.items() if kind in h), None) or \
            next((b for b in sections.values() if kind in b), None)
        assert body is not None, f"{path}: no schema section for {kind}"
        absent = [k for k in keys if f"`{k}`" not in body and k not in ABOUT]      # those: the common layout
        if absent:
            missing[os.path.relpath(path, ROOT)] = absent
    assert not missing, f"entries of the committed files that their schema does not name: {missing}"


def test_the_schema_tables_are_generated_from_the_declared_columns():
    """The tables of the kinds declared with their columns are what the declarations write (not written beside
    them): the page as committed equals the page regenerated; every declared kind has its table there; and a
    change to a declaration is seen (the check can fail)."""
    from dataclasses import replace
    from hertzpetsc.records import Kind
    from hertzpetsc.studies.schemas import kinds, page
    text, generated = page(SCHEMAS)
    assert text == generated, "docs/schemas.md differs from the declared columns: python -m hertzpetsc.studies.schemas"
    declared = kinds()
    assert "hertzpetsc-wave-1" in declared
    assert all(f"<!-- columns {k} -->" in text for k in declared), [k for k in declared if k not in text]
    wave = declared["hertzpetsc-wave-1"]
    changed = Kind.__new__(Kind)
    changed.name, changed.columns = wave.name, tuple(replace(c, description=c.description + " (changed)")
                                                     if c.name == "omega" else c for c in wave.columns)
    assert schema_page(text, dict(declared, **{wave.name: changed})) != text


def test_schema_examples_run_with_numpy_alone(monkeypatch):
    pytest.importorskip("numpy")
    with open(SCHEMAS) as f:
        blocks = re.findall(r"^```python\n(.*?)^```", f.read(), re.M | re.S)
    assert len(blocks) >= 14, len(blocks)
    monkeypatch.chdir(ROOT)
    ran = 0
    for i, block in enumerate(blocks):
        imports = set()
        for node in ast.walk(ast.parse(block)):
            if isinstance(node, ast.Import):
                imports |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                imports.add(node.module.split(".")[0])
        assert imports <= {"numpy", "json", "os"}, f"example {i} imports {imports - {'numpy', 'json', 'os'}}"
        out = io.StringIO()
        with redirect_stdout(out):
            exec(compile(block, f"docs/schemas.md example {i}", "exec"), {})
        ran += bool(out.getvalue())                          # the examples on files of runs/ print nothing without them
    assert ran >= 10, ran                                    # every example on a committed file printed its result


def test_the_solver_prefix_table_is_the_registry():
    """README's table of solver prefixes is hertzpetsc.roles.markdown_table(), row for row (no PETSc imported)."""
    from hertzpetsc.roles import markdown_table
    with open(PAGES[0]) as f:
        section = f.read().split("## Solver prefixes", 1)[1]
    table = next(block for block in section.split("\n\n") if block.startswith("| prefix"))
    assert table == markdown_table(), "README's solver prefixes differ from hertzpetsc.roles.REGISTRY: paste " \
        "markdown_table() into README.md"


def test_scripts_named_in_the_docs_exist():
    named = set()
    for p in PAGES:
        with open(p) as f:
            named |= set(re.findall(r"scripts/([\w*]+\.(?:py|sh))", f.read()))
    assert len(named) >= 25, sorted(named)
    missing = [n for n in sorted(named) if "*" not in n and not os.path.exists(os.path.join(ROOT, "scripts", n))]
    assert not missing, f"scripts the docs name that do not exist: {missing}"
