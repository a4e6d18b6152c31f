"""The schema page's tables generated from the record kinds' declarations (:class:`hertzpetsc.records.Kind`):
``python -m hertzpetsc.studies.schemas`` rewrites the tables of docs/schemas.md between ``<!-- columns KIND -->``
and ``<!-- end columns -->``; tests/test_docs.py fails when the page differs from what this writes."""
import os

from ..records import KINDS, schema_page, write_text

PAGE = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "docs",
                    "schemas.md")


def kinds() -> dict:
    """{kind name: Kind} of every record kind declared with its columns."""
    # the modules that declare kinds with columns (importing one registers its kinds)
    from .. import simulation  # noqa: F401
    from . import (branch, compacton_dynamics, compacton_pairs, compacton_stability, contacts, driven,  # noqa: F401
                   floquet, paper, precompression, refinement, slow, solitary_stability, wave)
    return dict(KINDS)


def page(path: str = PAGE) -> tuple[str, str]:
    """(the schema page as it is, as the declarations write it)."""
    with open(path) as f:
        text = f.read()
    return text, schema_page(text, kinds())


if __name__ == "__main__":
    write_text(PAGE, page()[1], what="schema page")
