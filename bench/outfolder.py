"""The output folder of a bench tool: it writes only where it may (mm, N, MPa, s aside).

A bench tool writes its own few files into ``--out`` (and reads them back to resume), so
it may use a folder that is new, empty, or holds nothing but those files; any other
folder belongs to someone else and is refused before any work, as the pipeline refuses
a folder it did not write (pipeline/outdir.py, docs/design.md §8).
"""
from __future__ import annotations

from pathlib import Path

from pipeline.folders import protected_reason


def refusal(out: Path, own: frozenset[str]) -> str | None:
    """The one line (exit 2) that refuses ``out`` for a tool whose files are ``own``, or
    None when the tool may write there."""
    reason = protected_reason(out.expanduser().resolve(), str(out))
    if reason is None and out.exists():
        if not out.is_dir():
            reason = "it exists and is not a folder"
        else:
            foreign = sorted(p.name for p in out.iterdir() if p.name not in own)
            if foreign:
                reason = (f"it holds files this tool did not write ({', '.join(foreign[:3])}"
                          f"{', ...' if len(foreign) > 3 else ''}); choose a new or empty folder")
    return None if reason is None else f"error: out: refusing {out}: {reason}"
