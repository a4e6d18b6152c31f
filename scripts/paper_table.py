#!/usr/bin/env python3
"""Compare a computed branch with the numbers quoted in the paper (section 3.1), as a Markdown table.

    python scripts/paper_table.py -branch results/branch_alpha1.5.npz -output results/paper_table.md

A value "agrees" when it is within half a unit of the last digit the paper quotes (see ``_row``).
Needs numpy only (reads the branch file); prints the table and writes it to -output.
"""
import argparse
import math
import sys

from hertzpetsc.branchfile import point_index, read_branch
from hertzpetsc.diagnostics import crossing, q_k
from hertzpetsc.errors import HertzPetscError

def _row(label, paper_text, get, value=None, tol=None):
    """A paper number; by default its value is the quoted text and the tolerance half a unit of its last digit."""
    decimals = len(paper_text.split(".")[1]) if "." in paper_text else 0
    return (label, paper_text, float(paper_text) if value is None else value,
            0.5 * 10.0 ** (-decimals) if tol is None else tol, get)


PAPER = [
    _row("N(pi)", "2", lambda b: b["N"][point_index(b, math.pi)]),
    _row("N(pi/50)", "4.8", lambda b: b["N"][point_index(b, math.pi / 50)]),
    _row("q_k, F(q_k) = 1", "1.8", lambda b: q_k(b["q"], b["F"])),
    _row("T(3pi/10)", "1.20", lambda b: b["T"][point_index(b, 3 * math.pi / 10)]),
    _row("T(7pi/25)", "1.19", lambda b: b["T"][point_index(b, 7 * math.pi / 25)]),
    _row("T(9pi/50)", "1.14", lambda b: b["T"][point_index(b, 9 * math.pi / 50)]),
    _row("T(pi/50)", "1.08", lambda b: b["T"][point_index(b, math.pi / 50)]),
    # Sec. 3.2: the k_alpha read off fig. normes "differs from 1.3567 by 8e-3" (quoted as 1.36 in sec. 3.1),
    # i.e. 1.3647, known to one digit of the 8e-3: +- 5e-4.
    _row("\\|u\\|_inf q^4 at pi/50", "1.36 (1.3567 + 8e-3)",
         lambda b: b["rescaled_norm"][point_index(b, math.pi / 50)], value=1.3567 + 8e-3, tol=5e-4),
    _row("q where N(q) = 3 (paper: N(q_c) ~ 3 at q_c ~ 0.9)", "0.9", lambda b: crossing(b["q"], b["N"], 3.0)),
]


def table(branch):
    rows = ["| quantity | paper | hertzpetsc | agrees |", "|---|---|---|---|"]
    ok_all = True
    for label, paper_text, paper_value, tol, get in PAPER:
        value = float(get(branch))
        ok = abs(value - paper_value) <= tol * (1 + 1e-9)
        ok_all &= ok
        rows.append(f"| {label} | {paper_text} | {value:.4f} | {'yes' if ok else 'NO'} |")
    head = (f"alpha = {branch['alpha']}, h = pi/{branch['cells_per_pi']}, M = {branch['M']}, "
            f"{len(branch['q'])} points, computed on {branch['meta'].get('ranks', '?')} rank(s)\n\n")
    return head + "\n".join(rows) + "\n", ok_all


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-branch", default="results/branch_alpha1.5.npz")
    ap.add_argument("-output", default="results/paper_table.md")
    args = ap.parse_args(argv)
    try:
        text, ok = table(read_branch(args.branch))
    except HertzPetscError as err:
        print(f"error: {err}", file=sys.stderr)
        return 4
    with open(args.output, "w") as f:
        f.write(text)
    print(text)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
