"""The numbers the README quoted before its results moved to docs/ (commit b3184da), for tests/test_docs.py.

Run once from the repository:  python tests/data/make_readme_numbers.py  (writes tests/data/readme_numbers.txt)
A number is a decimal (``1.3567``, ``87684.0``) or a number in scientific notation (``9.73e-07``) with at least
three significant digits (``2.00`` counts, ``1e-10`` and ``0.066`` do not: such short numbers recur everywhere,
so finding them proves nothing). Signs are not part of the token. Digits glued to a name (``alpha1.5`` in a file
name, ``x86_64``) are not numbers. :func:`numbers` is the one extraction: the test reads the new pages with it.
"""
import os
import re
import subprocess

COMMIT = "b3184da"
HERE = os.path.dirname(os.path.abspath(__file__))
LIST = os.path.join(HERE, "readme_numbers.txt")
NUMBER = re.compile(r"(?<![\w.])(\d+\.\d+(?:[eE][+-]?\d+)?|\d+[eE][+-]?\d+)(?![\w.]?\d)")


def significant_digits(token):
    """Significant digits of a decimal or scientific token: leading zeros dropped, trailing zeros kept."""
    mantissa = token.lower().split("e")[0].replace(".", "")
    return len(mantissa.lstrip("0"))


def numbers(text, minimum=3):
    """The distinct number tokens of ``text`` with at least ``minimum`` significant digits, in order of appearance."""
    out = []
    for token in NUMBER.findall(text):
        if significant_digits(token) >= minimum and token not in out:
            out.append(token)
    return out


def old_readme(root):
    """The README at :data:`COMMIT`, from git."""
    return subprocess.run(["git", "show", f"{COMMIT}:README.md"], cwd=root, capture_output=True, text=True,
                          check=True).stdout


if __name__ == "__main__":
    found = numbers(old_readme(os.path.dirname(os.path.dirname(HERE))))
    with open(LIST, "w") as f:
        f.write(f"# numbers quoted in README.md at commit {COMMIT} (tests/data/make_readme_numbers.py), one a line\n")
        f.write("\n".join(found) + "\n")
    print(f"{len(found)} numbers written to {LIST}")
