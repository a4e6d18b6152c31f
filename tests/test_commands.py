"""Every documented command runs as written: each command line that README.md and docs/*.md quote (code blocks,
indented blocks and inline code) and every command that `bash scripts/hz.sh main` and `bash scripts/hz.sh paper` run
is run with ``-check`` appended: its driver reads and validates every option, loads its input files, checks that its
outputs can be written and that its record files can be opened as asked (an existing file without -resume or
-force is refused), then exits 0 without computing or writing anything. So a default that the parser refuses, an
option a driver no longer knows, an input of another kind or a committed output overwritten without -force fails
here, naming the page and the command.

Each command runs in a directory of its own laid out as a checkout: ``results/`` holds the committed results files
(links: they are only read), ``runs/`` the files the command reads that an earlier documented command writes there
(made once per session by that command, run for real with the small sizes of ``SMALL``), nothing else. Commands run
serially, the first ``PARALLEL`` commands that the pages run under mpiexec also under ``mpiexec -n 2``.
"""
import concurrent.futures
import glob
import os
import re
import shlex
import shutil
import subprocess
import sys
import time

import pytest

from conftest import DATA, ROOT, script_env

pytestmark = pytest.mark.serial

PAGES = [os.path.join(ROOT, "README.md")] + sorted(glob.glob(os.path.join(ROOT, "docs", "*.md")))
RESULTS = os.path.join(ROOT, "results")
BRANCH = os.path.join(DATA, "branch_alpha1.5.npz")
# options whose values a driver writes (the others' paths are read); -output is read by -render
OUTPUTS = ("output", "table", "npz", "progress", "pairs_output", "pairs_table", "figures", "logs", "log_view")
# tokens that mark a template, not a command (the text around it says what to put there)
PLACEHOLDERS = re.compile(r"^(CMD|DIR|FILE|\.\.\.)$|<\w+>")
# sizes of the commands run for real to make another command's input: the kind of file, quickly
SMALL = {"continuation.py": {"cells_per_pi": "200"}, "long_run.py": {"t_final": "2"}}
PARALLEL = 2
FENCE = re.compile(r"^(```|~~~)([^\n]*)\n(.*?)^\1[ \t]*$", re.M | re.S)
START = re.compile(r"^(bash scripts/hz\.sh|mpiexec|\.venv/bin/python|python3?\b)")  # inline code: a script's name
                                                                                 # alone names it


class Command:
    """A driver's command line: ``script`` (scripts/NAME.py), its arguments, the ranks of its mpiexec, and where it
    is quoted."""

    def __init__(self, where, script, args, ranks=1):
        self.where, self.script, self.args, self.ranks = where, script, list(args), ranks

    def __repr__(self):
        return f"{self.where}: " + ("" if self.ranks == 1 else f"mpiexec -n {self.ranks} ") + \
            " ".join(shlex.quote(a) for a in [f"scripts/{self.script}"] + self.args)

    def key(self):
        return self.script, tuple(self.args)

    def options(self):
        """[(name, value)] of the options (a value None for a flag)."""
        out, args = [], self.args
        for i, a in enumerate(args):
            if re.match(r"^-[A-Za-z_]", a):
                value = args[i + 1] if i + 1 < len(args) and not re.match(r"^-[A-Za-z_]", args[i + 1]) else None
                out.append((a[1:], value))
        return out

    def paths(self, written):
        """The relative paths of the values of its output options (``written``) or of the others."""
        render = any(n == "render" for n, _ in self.options())
        out = []
        for name, value in self.options():
            if value is None or (name in OUTPUTS and not (render and name == "output")) != written:
                continue
            if name == "log_view":              # PETSc's viewer, :file[:format]
                out += [value.split(":")[1]] if value.startswith(":") else []
                continue
            out += [v.split(":")[0] for v in value.split(",") if v]
        return out

    def with_sizes(self, sizes):
        """The command with the options of ``sizes`` ({name: value}) set (replaced or added)."""
        args = list(self.args)
        for name, value in sizes.items():
            if f"-{name}" in args:
                args[args.index(f"-{name}") + 1] = value
            else:
                args += [f"-{name}", value]
        return Command(self.where + " (small sizes)", self.script, args, 1)


def _blocks(text):
    """The command lines of a page: its fenced blocks (but Python's), indented blocks and inline code spans, with
    continuation lines joined and comments removed."""
    lines = []
    for m in FENCE.finditer(text):
        if m.group(2).strip() != "python":
            lines += m.group(3).replace("\\\n", " ").splitlines()
    prose = FENCE.sub("", text)
    indented = re.findall(r"(?:^(?: {4}|\t)[^\n]*\n)+", prose, re.M)
    for block in indented:
        lines += "\n".join(line[4:] for line in block.splitlines()).replace("\\\n", " ").splitlines()
    out = []
    for line in lines:
        line = re.split(r"\s#", line.strip())[0].strip()
        if (START.match(line) or re.match(r"scripts/\w+\.py\b", line)) and "scripts/" in line:
            out.append(line)
    return out + [s for s in re.findall(r"`([^`]+)`", re.sub(r"\s*\n\s*", " ", prose))
                  if START.match(s) and "scripts/" in s]


def _hz_commands(job, where):
    """The driver commands of ``bash scripts/hz.sh <job>``: main's lines, read from hz.sh; paper: scripts/paper.py
    and every step of the pipeline as a fresh pipeline runs it; setup and test run no driver."""
    if job == "paper":
        from hertzpetsc.studies.paper import paper_steps
        return [Command(where, "paper.py", ["-ranks", "2"])] + \
            [Command(f"{where}, step {s.name}", s.script, s.arguments(), 2 if s.parallel else 1) for s in paper_steps()]
    if job != "main":
        return []
    with open(os.path.join(ROOT, "scripts", "hz.sh")) as f:
        arm = re.search(r"^\s*main\)\n(.*?);;", f.read(), re.M | re.S).group(1)
    out = []
    for line in arm.splitlines():
        line = line.replace('"$NRANKS"', "2").replace('"$PY"', "python").replace('"$@"', "").strip()
        if "scripts/" in line:
            out += _parse(line, where)
    return out


def _parse(line, where):
    """The commands a documented line runs ([] for a template or a job that runs no driver)."""
    tokens = shlex.split(line)
    if any(PLACEHOLDERS.search(t) for t in tokens):
        return []
    if tokens[:2] == ["bash", "scripts/hz.sh"]:
        if len(tokens) == 2:                    # the script named in prose, without a job: runs no driver
            return []
        if tokens[2] != "run":
            return _hz_commands(tokens[2], f"{where} (hz.sh {tokens[2]})")
        tokens = tokens[3:]
    ranks = 1
    if tokens[:2] == ["mpiexec", "-n"]:
        ranks, tokens = int(tokens[2]), tokens[3:]
    if re.match(r"^(\.venv/bin/)?python3?$", tokens[0]):
        tokens = tokens[1:]
    else:                                   # the script itself: it must be executable
        assert os.access(os.path.join(ROOT, tokens[0]), os.X_OK), f"{where}: {tokens[0]} is not executable: {line}"
    script = re.fullmatch(r"scripts/(\w+\.py)", tokens[0])
    assert script, f"{where}: not a driver command: {line}"
    args, depth = [], 0
    for t in tokens[1:]:                    # optional parts [-resume | -force] are left out
        depth += t.count("[")
        if depth == 0:
            args.append(t)
        depth -= t.count("]")
    return [Command(where, script.group(1), args, ranks)]


def documented_commands():
    """Every command of README.md, docs/*.md, and of hz.sh main and paper, each once, in the pages' order."""
    seen, out = set(), []
    for page in PAGES:
        with open(page) as f:
            text = f.read()
        for line in _blocks(text):
            for cmd in _parse(line, os.path.relpath(page, ROOT)):
                if cmd.key() not in seen:
                    seen.add(cmd.key())
                    out.append(cmd)
    return out


def _run(cmd, cwd, check=True, ranks=1, timeout=180):
    argv = [sys.executable, os.path.join(ROOT, "scripts", cmd.script), *cmd.args] + (["-check"] if check else [])
    if ranks > 1:
        argv = ["mpiexec", "-n", str(ranks), *argv]
    try:
        return subprocess.run(argv, cwd=cwd, capture_output=True, text=True, env=script_env(), timeout=timeout)
    except subprocess.TimeoutExpired as err:
        return subprocess.CompletedProcess(argv, 124, err.stdout or "", f"timed out after {timeout} s")


class Inputs:
    """The files under runs/ that documented commands read, each made once by the documented command that writes
    it, run for real at the small sizes of SMALL (with its own inputs made first)."""

    def __init__(self, directory, commands):
        self.directory, self.commands, self.made = directory, commands, {}

    def producer(self, path):
        return next((c for c in self.commands if path in c.paths(written=True)), None)

    def get(self, path):
        if path not in self.made:
            cmd = self.producer(path)
            assert cmd is not None, f"no documented command writes {path}"
            small = cmd.with_sizes(SMALL.get(cmd.script, {}))
            sandbox = self.layout(small, os.path.join(self.directory, f"make{len(self.made)}"))
            r = _run(small, sandbox, check=False, timeout=600)
            assert r.returncode == 0, f"making {path} by {small!r} failed: {r.stderr[-2000:]}"
            self.made[path] = os.path.join(sandbox, path)
        return self.made[path]

    def layout(self, cmd, sandbox):
        """A checkout for ``cmd``: the committed results (linked; copied where the command writes them, so that a
        write, which -check must not make, lands in the copy), and the runs/ files it reads."""
        os.makedirs(os.path.join(sandbox, "results"))
        written = {os.path.normpath(p) for p in cmd.paths(written=True)}
        for f in os.listdir(RESULTS):
            (shutil.copy if os.path.join("results", f) in written else os.symlink)(
                os.path.join(RESULTS, f), os.path.join(sandbox, "results", f))
        for path in cmd.paths(written=False):
            if path.startswith("runs/"):
                os.makedirs(os.path.dirname(os.path.join(sandbox, path)), exist_ok=True)
                os.symlink(os.path.abspath(self.get(path)), os.path.join(sandbox, path))
        return sandbox


def _files(directory, since=None):
    """The regular files under ``directory`` (links not followed), those modified after ``since`` if given."""
    paths = (os.path.join(d, f) for d, _, fs in os.walk(directory) for f in fs)
    return {os.path.relpath(p, directory) for p in paths
            if not os.path.islink(p) and (since is None or os.stat(p).st_mtime_ns > since)}


def _stamp():
    return {f: os.stat(os.path.join(RESULTS, f)).st_mtime_ns for f in os.listdir(RESULTS)}


def test_the_pages_quote_the_commands_this_test_runs():
    """The extraction sees what the pages show: the README's tour, a driven-chain command from an indented block, an
    inline command, hz.sh main's two drivers and every step of hz.sh paper; templates and set-up jobs are left out."""
    cmds = documented_commands()
    text = "\n".join(map(repr, cmds))
    assert "README.md: mpiexec -n 2 scripts/continuation.py -alpha 2 -output runs/branch_alpha2.npz" in text
    with open(os.path.join(ROOT, "docs", "driven.md")) as f:          # an indented block, continuation joined
        assert any(line.startswith("python scripts/driven_wave_ends.py -branch results/branch_alpha1.5.npz ")
                   and line.endswith("-force") for line in _blocks(f.read()))
    assert "docs/floquet.md: mpiexec -n 2 scripts/floquet_long.py" in text
    assert "(hz.sh main): mpiexec -n 2 scripts/continuation.py -output results/branch_alpha1.5.npz -force" in text
    assert ("(hz.sh main): scripts/paper_table.py -branch results/branch_alpha1.5.npz -output "
            "results/paper_table.md") in text
    from hertzpetsc.studies.paper import paper_steps
    keys = {c.key() for c in cmds}
    assert all((s.script, tuple(s.arguments())) in keys for s in paper_steps())
    assert "<driver>" not in text and "CMD" not in text and len(cmds) > 100
    # optional parts are left out; a bare script must be executable
    only = _parse("mpiexec -n 2 .venv/bin/python scripts/long_run.py -q 7*pi/25 -output runs/q [-resume | -force] "
                  "[-chain_ts_rtol 1e-14 -chain_ts_atol 1e-16]", "x")
    assert only[0].args == ["-q", "7*pi/25", "-output", "runs/q"] and only[0].ranks == 2
    assert only[0].paths(written=True) == ["runs/q"]
    assert Command("x", "dynamics_figures.py", ["-runs", "runs/a:1:2,runs/b", "-table", "t.md"]).paths(False) == \
        ["runs/a", "runs/b"]
    with pytest.raises(AssertionError, match="not executable"):
        _parse("scripts/wave.py -help", "x")


def test_every_documented_command_passes_its_check(tmp_path):
    """Each command with -check exits 0 and writes no file; the committed results are left as they were. A failure
    lists every command that failed with its driver's error line."""
    cmds = documented_commands()
    inputs = Inputs(str(tmp_path / "inputs"), cmds)
    before = _stamp()
    jobs = []
    parallel = [c for c in cmds if c.ranks > 1][:PARALLEL]
    for i, cmd in enumerate(cmds):
        sandbox = inputs.layout(cmd, str(tmp_path / f"c{i}"))
        jobs.append((cmd, sandbox, 1))
        if cmd in parallel:
            sandbox2 = inputs.layout(cmd, str(tmp_path / f"c{i}np2"))
            jobs.append((cmd, sandbox2, 2))
    failed = []

    def one(job):
        cmd, sandbox, ranks = job
        time.sleep(0.01)
        start = time.time_ns()
        r = _run(cmd, sandbox, ranks=ranks)
        written = sorted(_files(sandbox, start))
        said = "Application options" if "-help" in cmd.args else "check: "
        if r.returncode != 0 or said not in r.stdout or written:
            lines = [line for line in r.stderr.splitlines() if line.strip()] or [r.stdout.strip()[-300:]]
            failed.append(f"{cmd!r}" + (f" [on {ranks} ranks]" if ranks > 1 else "") + f": exit {r.returncode}: "
                          + lines[-1] + (f"; wrote {written}" if written else ""))

    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        list(pool.map(one, jobs))
    assert _stamp() == before, "a -check changed the committed results"
    assert not failed, f"{len(failed)} of {len(jobs)} documented commands fail their check:\n" + "\n".join(failed)
    shutil.rmtree(tmp_path, ignore_errors=True)


def test_check_refuses_what_a_run_would_refuse(tmp_path):
    """-check is not a pass-through: an option out of range, an unknown option, a missing input and an existing
    record file without -resume or -force each fail with the run's own error line and status, before anything is
    written."""
    def check(*args):
        return _run(Command("t", "refine_branch.py", ["-branch", BRANCH, "-q", "7*pi/25", "-output", "r.npz",
                                                      *args]), str(tmp_path))
    ok = check()
    assert ok.returncode == 0 and ok.stdout.strip().endswith("(nothing computed or written)"), ok.stderr
    assert _files(str(tmp_path)) == set()
    for args, status, needle in ((("-tol", "-1"), 2, "invalid -tol"), (("-tolerance", "1"), 2, "unknown option"),
                                 (("-branch", "nowhere.npz"), 4, "does not exist"), (("-q", "0"), 2, "-q"),
                                 (("-q", "0.123"), 4, "no point at q = 0.123")):
        r = check(*args)
        assert r.returncode == status and needle in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    (tmp_path / "r.npz").write_bytes(b"")
    r = check()
    assert r.returncode == 4 and "exists: continue it with -resume" in r.stderr, r.stderr
    r = check("-resume")
    assert r.returncode == 4 and "corrupt" in r.stderr, r.stderr
    assert (tmp_path / "r.npz").read_bytes() == b""
