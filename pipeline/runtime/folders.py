"""Folders the tool must never write into, and the marks by which it knows its own.

No MPI here (pipeline/runtime/outdir.py, which imports this, does the writing under MPI): the
bench tools check their output folders with it without starting MPI in their parent
process, whose children would inherit MPI's environment.
"""
from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Callable

MARKER = ".crosshead-results"  # written last into every results folder: "this folder is ours"
STAGING_MARK = ".crosshead-staging"  # written first into every staging folder
REPOSITORY = Path(__file__).resolve().parents[2]


def marker_data(folder: Path) -> dict | None:
    """What ``folder``'s marker says, or None when it is not the tool's: the tool writes a
    regular file holding a JSON object with ``"tool": "crosshead"``. An empty, unreadable
    or foreign marker, or one that is a folder, does not make a folder the tool's: a user
    can make such a file, and only the tool's own JSON says the tool wrote the rest."""
    mark = folder / MARKER
    try:
        if mark.is_symlink() or not mark.is_file():
            return None
        data = json.loads(mark.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("tool") != "crosshead":
        return None
    return data


def marked_kind(out: Path) -> str | None:
    """The kind of results folder ``out``'s marker names ("sweep" and "summary" say so in
    it; the tool's other markers are a run's), or None when it carries no marker of the
    tool's (:func:`marker_data`)."""
    data = marker_data(out)
    if data is None:
        return None
    for kind in ("sweep", "summary"):
        if data.get(kind) is True:
            return kind
    return "run"


def enclosing_study(out: Path) -> Path | None:
    """The design study's folder that ``out`` (resolved) is, or lies inside, or None.

    A run written into a study's ``variants/<key>`` carries a run marker there, and the
    study's next resume would report that run's numbers as the variant's: only the study
    itself writes inside its folder."""
    for folder in (out, *out.parents):
        if marked_kind(folder) == "sweep":
            return folder
    return None


MOUNTINFO = Path("/proc/self/mountinfo")


def _unescape_mount(text: str) -> str:
    """A mount point as /proc/self/mountinfo writes it: space, tab, newline and backslash
    as octal escapes (\\040 ...)."""
    return re.sub(r"\\([0-7]{3})", lambda m: chr(int(m.group(1), 8)), text)


def mount_points(mountinfo: Path = MOUNTINFO) -> set[Path]:
    """Every mount point of this process's mount namespace (empty when the kernel does not
    say). A bind mount of a folder of the same file system has the same device number as
    its parent, so ``os.path.ismount`` misses it; the kernel's table does not."""
    try:
        lines = mountinfo.read_text(encoding="utf-8", errors="surrogateescape").splitlines()
    except OSError:
        return set()
    found = set()
    for line in lines:
        fields = line.split(" ")
        if len(fields) > 4:
            found.add(Path(_unescape_mount(fields[4])))
    return found


def is_mount_point(folder: Path, mountinfo: Path = MOUNTINFO) -> bool:
    """True when ``folder`` (resolved) is a mount point: a different device from its
    parent (``os.path.ismount``) or listed in the kernel's mount table (a bind mount)."""
    return os.path.ismount(folder) or folder in mount_points(mountinfo)


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
    if out.exists() and is_mount_point(out):
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

