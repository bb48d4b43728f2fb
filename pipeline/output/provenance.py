"""Where a results.json comes from: its schema version, the tool and software versions, when
and by which command line it was made (docs/design.md §7), and the keys every run carries.

results.json keeps the same keys in every run: a value that does not apply is null, so
that files of several runs concatenate into one table without gaps
(docs/results.schema.json is the schema the tests hold every written file to).
"""
from __future__ import annotations

import datetime
import platform
import sys

from pipeline import __version__

SCHEMA_VERSION = 1
# Top-level keys a run may not fill (null then): a load sweep and its verdict sentence, the
# sensitivity section, a convergence study's block.
OPTIONAL_KEYS = ("load_sweep", "load_sweep_verdict", "sensitivity", "sensitivity_summary", "convergence")
# The order of the top-level keys in every results.json.
KEY_ORDER = ("about", "units", "case", "analytic", "fe", "comparison_pct", "timings_s", "files", "notes", *OPTIONAL_KEYS,
             "summary")


def _versions() -> dict[str, str]:
    """The versions of the software that made the numbers (DOLFINx, PETSc, gmsh, numpy,
    Python), read from the modules the run has loaded."""
    import dolfinx
    import gmsh
    import numpy
    from petsc4py import PETSc
    return {"python": platform.python_version(), "dolfinx": dolfinx.__version__,
            "petsc": ".".join(str(v) for v in PETSc.Sys.getVersion()), "gmsh": gmsh.__version__,
            "numpy": numpy.__version__}


def about(document: dict[str, str | None], argv: list[str] | None = None) -> dict:
    """results.json's ``about`` block: schema version, tool and version, UTC time of
    writing, the command line (``crosshead`` and its arguments), software versions and the
    report's title block ``document`` (pipeline.inputs.case.Document: part, number,
    revision, author, checker; None where the case file does not give one)."""
    args = sys.argv[1:] if argv is None else argv
    return {"schema_version": SCHEMA_VERSION, "tool": "crosshead", "tool_version": __version__,
            "created_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "command_line": ["crosshead", *args], "software": _versions(), "document": dict(document)}


def complete(res: dict, summary_row: dict) -> dict:
    """``res`` with every optional top-level key present (null where it does not apply) and
    its flat ``summary`` block: the row at the case's own load, one tidy row for
    pandas.json_normalize."""
    for key in OPTIONAL_KEYS:
        res.setdefault(key, None)
    res["summary"] = summary_row
    ordered = {k: res[k] for k in KEY_ORDER if k in res} | {k: v for k, v in res.items() if k not in KEY_ORDER}
    res.clear()
    res.update(ordered)
    return res
