#!/usr/bin/env python3
"""The performance report (results/performance.md): every large workload on 1 and 2 ranks against the plain
SciPy route, in one run, with parallel efficiency, memory per unknown and a -log_view scaling section.

    python scripts/bench_report.py [-output runs/performance.md] [-repeats 2] [-scipy_timeout 600]
                                   [-workloads branch,newton,chain,floquet] [-records FILE [-resume]]

Workloads (each measurement in its own process, through the workers of the bench_*.py scripts):
  branch   full branch q = pi -> pi/50 at h = pi 1e-3 and pi 2e-5, -tw_solver nk (bench_branch.py)
  newton   one Newton solve at h = pi 1e-6, q = 0.9 pi, -tw_solver nk (bench_newton.py)
  chain    one script-T of the q = 3pi/10 wave on N = 1e6 beads, RK 8(7) (bench_chain.py)
  floquet  the 10 dominant multipliers at N = 1e4, q = 7pi/25 (bench_floquet.py)
Parallel efficiency = t1 / (2 t2); memory per unknown = sum over ranks of the peak resident set / unknowns
(it includes the interpreter and libraries, about 70 MB per process). The scaling section reruns the Newton
solve and the chain with -log_view (through PETSC_OPTIONS) and reports time, messages, bytes and reductions per
Newton step and per time step. Run on an otherwise idle machine: two ranks share its two cores.
"""
import math
import os
import re
import sys

from benchlib import BenchRecords, best_of, declare_common, machine, write_report

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPTS = os.path.join(ROOT, "scripts")
BRANCH = os.path.join(ROOT, "results", "branch_alpha1.5.npz")
REFINED = os.path.join(ROOT, "results", "refined_N100.npz")


def script(name):
    return os.path.join(SCRIPTS, name)


def workloads(rec, repeats, scipy_timeout, which):
    """Yield (workload, unknowns, {route: result}) with routes 'scipy', 1, 2."""
    q = 0.9 * math.pi
    nk = ["-tw_solver", "nk"]
    if "branch" in which:
        for K in (1000, 50000):
            req = dict(alpha=1.5, M=50, K=K)
            sci = rec.measure(f"branch {K} scipy", lambda: best_of(1 if K > 20000 else repeats, script(
                "bench_branch.py"), "scipy", req, None, scipy_timeout))
            runs = {r: rec.measure(f"branch {K} {r}", lambda: best_of(repeats, script("bench_branch.py"), "petsc", req,
                                                                      r, 3600, nk)) for r in (1, 2)}
            yield f"full branch, h = pi/{K}", K - 1, {"scipy": sci, **runs}
    if "newton" in which:
        K = 10 ** 6
        runs = {r: rec.measure(f"newton {r}", lambda: best_of(repeats, script("bench_newton.py"), "newton",
                                                              dict(K=K, q=q), r, 3600, nk)) for r in (1, 2)}
        yield "one Newton solve, h = pi 1e-6", K - 1, {"scipy": None, **runs}
    if "chain" in which:
        N = 10 ** 6
        req = dict(branch=BRANCH, N=N)
        sci = rec.measure("chain scipy", lambda: best_of(1, script("bench_chain.py"), "scipy", req, None,
                                                         scipy_timeout))
        runs = {r: rec.measure(f"chain {r}", lambda: best_of(repeats, script("bench_chain.py"), "petsc", req, r))
                for r in (1, 2)}
        yield "chain, N = 1e6, one script-T", 2 * N, {"scipy": sci, **runs}
    if "floquet" in which:
        N = 10 ** 4
        req = dict(branch=BRANCH, refined=REFINED, N=N)
        runs = {r: rec.measure(f"floquet {r}", lambda: best_of(1, script("bench_floquet.py"), "bloch", req, r))
                for r in (1, 2)}
        yield "Floquet, N = 1e4, 10 dominant multipliers", 2 * N, {"scipy": None, **runs}


EVENT = re.compile(r"^(\w+)\s+(\d+)\s+[\d.]+\s+([\d.e+-]+)\s+[\d.]+\s+[\d.e+-]+\s+[\d.]+\s+([\d.e+-]+)\s+"
                   r"([\d.e+-]+)\s+([\d.e+-]+)\s")


def log_events(path):
    """{event: (count, max time, total messages, average message bytes, reductions)} from a -log_view file."""
    out = {}
    with open(path) as f:
        for line in f:
            m = EVENT.match(line)
            if m:
                name, count, t, mess, length, red = m.groups()
                c0, t0, m0, l0, r0 = out.get(name, (0, 0.0, 0.0, 0.0, 0.0))
                out[name] = (c0 + int(count), t0 + float(t), m0 + float(mess), max(l0, float(length)), r0 + float(red))
    return out


def scaling_section(directory):
    """The -log_view rows; the logs are written into ``directory`` (the report's)."""
    q = 0.9 * math.pi
    rows = []
    for name, sname, worker, req, args, event, unit in (
            ("Newton solve, h = pi 1e-6", "bench_newton.py", "newton", dict(K=10 ** 6, q=q), ["-tw_solver", "nk"],
             "SNESSolve", "Newton step"),
            ("chain, N = 1e6", "bench_chain.py", "petsc", dict(branch=BRANCH, N=10 ** 6), [], "TSStep", "time step")):
        for ranks in (1, 2):
            path = os.path.join(directory, f"logview_{sname.split('_')[1].split('.')[0]}_np{ranks}.txt")
            res = best_of(1, script(sname), worker, req, ranks, 3600, [*args, "-log_view", f":{path}"])
            ev = log_events(path)
            if event not in ev:
                rows.append(f"| {name} | {ranks} | (no {event} in {os.path.relpath(path, ROOT)}) | | | | |")
                continue
            count, t, mess, length, red = ev[event]
            steps = res.get("newton", 0) if event == "SNESSolve" else count
            steps = max(int(steps), 1)
            rows.append(f"| {name} | {ranks} | {steps} {unit}s | {t / steps:.3g} | {mess / steps:.1f} | "
                        f"{mess * length / steps / 1e6:.3g} | {red / steps:.1f} | `{os.path.relpath(path, ROOT)}` |")
    return rows


MODEL = """Model of the growth with the number of ranks P (n unknowns, k Krylov iterations per Newton step):

- Newton-Krylov step. Each Jacobian product (k + 3 per step, the residuals included) gathers the values shifted
  by +-q with one scatter. A rank's window of n/P shifted values lies on at most two other ranks, so there are
  at most 4 messages per rank per product, whatever P. Every rank sends about (1 - 1/P) of its 2 n/P shifted
  values: bytes per product ~ 16 n (1 - 1/P), about 8 MB at n = 1e6, P = 2 (measured: 75 MB per step of 9
  products). Per rank that is O(n/P), the same order as the local work, so the step's parallel efficiency is set
  by the ratio of copy bandwidth to compute, not by P. On one node it stays flat; across nodes the network
  bandwidth would set it. The preconditioner adds one allgather of 2 numbers per rank per application (a P x 2
  interface system). GMRES adds about one reduction per iteration (measured 17 per step), O(log P) latency each.
- Chain time step. Each right-hand side exchanges one ghost bead with each neighbour: 2 messages of 16 bytes per
  rank. That is 21 evaluations per RK 8(7) step, about 42 messages and 1.4 kB in all at P = 2 (measured 43), plus
  1.7 reductions for the error norm. Communication is O(1) per rank and work O(N/P), so the efficiency stays near
  ideal until N/P is a few thousand beads, where the per-step latency (about 21 x 2 messages + 2 reductions)
  dominates.
"""


def main():
    from hertzpetsc.options import AppOptions
    opts = AppOptions(__doc__)
    scipy_timeout = opts.integer("scipy_timeout", 600, "seconds before a SciPy run is given up", minimum=1)
    which = set(opts.words("workloads", "branch,newton,chain,floquet", "workloads to run",
                           choices=("branch", "newton", "chain", "floquet")))
    output, repeats, records_path, mode = declare_common(opts, "runs/performance.md", repeats=2)
    opts.done()
    opts.check_unused()
    rec = BenchRecords(records_path, "hertzpetsc-bench-report-1", dict(which=sorted(which)), mode)
    lines = [f"Performance report; {machine(repeats)}. hertzpetsc best of {repeats}, one OpenBLAS thread per rank; "
             "SciPy one run, one BLAS thread unless OPENBLAS_NUM_THREADS is set. "
             "Efficiency = t1 / (2 t2). Memory per unknown = peak resident set "
             "summed over ranks / unknowns (includes about 70 MB of interpreter and libraries per process).\n",
             "| workload | unknowns | SciPy (s) | SciPy MB | hertzpetsc 1 rank (s) | MB | 2 ranks (s) | MB/rank | "
             "SciPy / 1 rank | SciPy / 2 ranks | 1 -> 2 efficiency | MB/rank 2 vs 1 | bytes/unknown (1 rank) |",
             "|---" * 13 + "|"]
    for name, n, r in workloads(rec, repeats, scipy_timeout, which):
        sci, one, two = r["scipy"], r[1], r[2]

        def fmt(x, key="wall"):
            return f"{x[key]:.3g}" if x else "n/a"

        mb = lambda x: f"{max(x['rss_mb']):.0f}" if x else "n/a"
        ratio = lambda a, b: f"{a['wall'] / b['wall']:.2f}" if a and b else "n/a"
        eff = f"{one['wall'] / (2 * two['wall']):.0%}" if one and two else "n/a"
        mem = f"{max(two['rss_mb']) / max(one['rss_mb']):.0%}" if one and two else "n/a"
        per = f"{sum(one['rss_mb']) * 2 ** 20 / n:.0f}" if one else "n/a"
        lines.append(f"| {name} | {n} | {fmt(sci)} | {mb(sci)} | {fmt(one)} | {mb(one)} | {fmt(two)} | {mb(two)} | "
                     f"{ratio(sci, one)} | {ratio(sci, two)} | {eff} | {mem} | {per} |")
        print(lines[-1], flush=True)
    lines += ["", f"load average after the workloads {os.getloadavg()[0]:.2f}", "",
              "## Scaling from -log_view", "",
              "Per Newton step (SNESSolve / Newton iterations) and per time step (TSStep): time of the event (max "
              "over ranks), messages (total over ranks), megabytes sent (messages x average length), global "
              "reductions.", "",
              "| run | ranks | steps | s / step | messages / step | MB / step | reductions / step | log |",
              "|---|---|---|---|---|---|---|---|"]
    lines += scaling_section(os.path.dirname(os.path.abspath(output)))
    lines += ["", MODEL]
    write_report(output if os.path.isabs(output) else os.path.join(ROOT, output), lines)


if __name__ == "__main__":
    from hertzpetsc.start import init_petsc
    init_petsc(sys.argv)
    from hertzpetsc.options import guarded_main
    guarded_main(main)
