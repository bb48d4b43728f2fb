"""Folders the tool must never write into, and the marks by which it knows its own.

No MPI here (pipeline/runtime/outdir.py, which imports this, does the writing under MPI): the
bench tools check their output folders with it without starting MPI in their parent
process, whose children would inherit MPI's environment.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Callable

MARKER = ".crosshead-results"  # written last into every results folder: "this folder is ours"
STAGING_MARK = ".crosshead-staging"  # written first into every staging folder
REPOSITORY = Path(__file__).resolve().parents[2]


def marked_kind(out: Path) -> str:
    """The kind of results folder ``out``'s marker names: "sweep" and "summary" say so in
    it; any other marker (a run's, an earlier version's) is a run's."""
    try:
        data = json.loads((out / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return "run"
    if isinstance(data, dict):
        for kind in ("sweep", "summary"):
            if data.get(kind) is True:
                return kind
    return "run"


def _is_same_or_above(folder: Path, other: Path) -> bool:
    """True when ``folder`` is ``other`` or one of its ancestors."""
    return other == folder or folder in other.parents


def protected_reason(out: Path, raw: str) -> str | None:
    """Why ``out`` (resolved, symlinks followed) must never be a results folder, or None.

    Refused whatever they hold: the working folder and every folder above it, the
    repository, its source folders and everything above it, ``/``, the home folder and
    above, and mount points. ``raw`` is the text the user gave (``''`` and ``.`` refused).
    """
    if raw.strip() in ("", "."):
        return "the current folder cannot be an output folder"
    if out == Path(out.anchor):
        return "the file-system root cannot be an output folder"
    if _is_same_or_above(out, Path.cwd().resolve()):
        return "it is the working folder or above it"
    home = Path.home().resolve()
    if _is_same_or_above(out, home):
        return "it is the home folder or above it"
    if _is_same_or_above(out, REPOSITORY):
        return "it is the crosshead repository or above it"
    if REPOSITORY in out.parents:
        top = out.relative_to(REPOSITORY).parts[0]
        if top != "results" and (REPOSITORY / top).exists():
            return f"it is inside the crosshead source tree ({top}/); use a folder under results/"
    if out.exists() and os.path.ismount(out):
        return "it is a mount point"
    return None


def refusal(out: Path, own: frozenset[str], not_mine: Callable[[Path], str | None] | None = None) -> str | None:
    """The one line (exit 2) that refuses ``out`` to a tool that writes the files named
    ``own`` into it, or None: a protected folder, something that is not a folder, or a
    folder holding any other file is refused; ``not_mine`` (the folder -> why, or None)
    refuses one holding only those names that the tool still knows is not its own."""
    reason = protected_reason(out.expanduser().resolve(), str(out))
    if reason is None and out.exists():
        if not out.is_dir():
            reason = "it exists and is not a folder"
        else:
            foreign = sorted(p.name for p in out.iterdir() if p.name not in own)
            if foreign:
                reason = (f"it holds files this tool did not write ({', '.join(foreign[:3])}"
                          f"{', ...' if len(foreign) > 3 else ''}); choose a new or empty folder")
            elif not_mine is not None and any(out.iterdir()):
                reason = not_mine(out)
    return None if reason is None else f"error: out: refusing {out}: {reason}"

