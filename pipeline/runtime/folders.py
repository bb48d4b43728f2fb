"""Folders the tool must never write into, the marks by which it knows its own, and
``make clean`` (``python -m pipeline.runtime.folders results``).

A folder is the tool's only when its marker is the tool's JSON (``"tool": "crosshead"``); a
run's marker lists the files the run wrote, and everything else in the folder is the
user's. No MPI here (pipeline/runtime/outdir.py, which imports this, does the writing under MPI): the
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
# Files a run writes. A folder holding nothing else (and a results.json) is a run's results
# folder in the format without a marker, and a marker without a list of files names these
# as the tool's.
RUN_FILES = frozenset({"results.json", "report.md", "report.html", "mesh.msh", "displacement.pvd",
                       "displacement.vtu", "von_mises.vtu", "fields.vtu", "von_mises.png", "convergence.png",
                       "sections.png", "peaks.png", "report.pdf", "meshes.csv", "sensitivity.csv"})



def default_out(name: str) -> Path:
    """The default output folder of a case: ``results/<name>`` in the repository, wherever
    the command is started from (a run from ``/`` must not write ``/results``)."""
    return REPOSITORY / "results" / name

def is_field_part(name: str) -> bool:
    """A piece of the displacement field a run wrote (one .vtu per rank under MPI)."""
    return name.startswith("displacement") and name.endswith((".vtu", ".pvtu"))


def tool_names(folder: Path, names: set[str]) -> set[str]:
    """Of ``names`` (the entries of ``folder``, which carries the tool's marker), those the
    tool wrote: what its marker lists, or for a marker without the list a run's files."""
    listed = (marker_data(folder) or {}).get("files")
    if isinstance(listed, list) and all(isinstance(n, str) for n in listed):
        return (names & set(listed)) | ({MARKER} & names)
    return {n for n in names if n in RUN_FILES or n == MARKER or is_field_part(n)}


def user_names(folder: Path) -> list[str]:
    """The entries of ``folder`` (the tool's results folder) that the tool did not write,
    sorted: the user's, which a re-run carries over."""
    names = {p.name for p in folder.iterdir()}
    return sorted(names - tool_names(folder, names))


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



# What a design study and a size summary write besides their marker (pipeline/study/):
# the names `make clean` may remove from such a folder; a variant's folder is a run's.
STUDY_FILES = frozenset({"sweep.csv", "sweep.json", "report.md", "report.html", "variants", ".claims"})
SUMMARY_FILES = frozenset({"summary.md", "summary.csv", "summary.png"})  # as pipeline/study/summary.py's


def _is_study_plot(name: str) -> bool:
    """A plot a study draws: peak_vs_rf.png, critical_peak_vs_dj.png (pipeline/study/table.py)."""
    return name.endswith(".png") and "_vs_" in name


def _remove_tree(p: Path) -> None:
    """Delete a file, a symlink (not its target) or a folder tree."""
    import shutil
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p, ignore_errors=True)
    else:
        try:
            p.unlink()
        except OSError:
            pass


def _clean_results_folder(folder: Path) -> list[str]:
    """Remove what the tool wrote in ``folder`` (it carries the tool's marker): a run's
    files as its marker lists them, a study's files and its variants' folders and failure
    notes, a summary's files; the marker goes last, then the folder if nothing is left.
    Returns the paths kept (relative to ``folder``): files the tool did not write."""
    kind = marked_kind(folder)
    names = {p.name for p in folder.iterdir()}
    if kind == "run":
        ours = tool_names(folder, names)
    elif kind == "summary":
        ours = names & (SUMMARY_FILES | {MARKER})
    else:
        ours = {n for n in names if n in STUDY_FILES or n == MARKER or _is_study_plot(n)}
    kept = sorted(names - ours)
    for name in sorted(ours - {MARKER, "variants"}):
        _remove_tree(folder / name)
    variants = folder / "variants"
    if "variants" in ours and variants.is_dir() and not variants.is_symlink():
        for v in sorted(variants.iterdir()):
            if v.is_dir() and not v.is_symlink() and marked_kind(v) == "run":
                kept += [f"variants/{v.name}/{n}" for n in _clean_results_folder(v)]
            elif v.is_file() and v.name.endswith(".failed.json"):
                _remove_tree(v)
            else:
                kept.append(f"variants/{v.name}")
        try:
            variants.rmdir()
        except OSError:
            pass
    if not kept:
        _remove_tree(folder / MARKER)
        try:
            folder.rmdir()
        except OSError:
            pass
    return kept


def _lock_is_free(path: Path) -> bool:
    """True when no running process holds the lock file ``path`` (flock, as
    pipeline/runtime/outdir.py takes it)."""
    import fcntl
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except OSError:
        return False
    finally:
        os.close(fd)


def clean(results: Path, say: Callable[[str], None] = print) -> None:
    """`make clean`: remove from ``results`` what crosshead wrote and name what it keeps.

    Results folders carrying the tool's marker lose the tool's files (a folder is removed
    when nothing else is left in it); staging folders and lock files of runs that are not
    running are removed; anything else (a folder without the tool's marker, a user's file
    in a results folder, the bench tools' outputs) is kept and named. ``results`` itself
    goes when it is left empty.
    """
    if not results.is_dir():
        return
    for p in sorted(results.iterdir()):
        where = f"{results.name}/{p.name}"
        if p.is_dir() and not p.is_symlink() and p.name.endswith(".partial") and (
                (p / STAGING_MARK).is_file() or marker_data(p) is not None):
            _remove_tree(p)  # a staging folder holds only what the tool wrote
        elif p.is_dir() and not p.is_symlink() and marker_data(p) is not None:
            kept = _clean_results_folder(p)
            if kept:
                say(f"make clean: kept {where}/ with {', '.join(kept[:5])}{', ...' if len(kept) > 5 else ''} "
                    "(not written by crosshead); its results were removed")
        elif p.is_file() and not p.is_symlink() and p.name.startswith(".") and p.name.endswith(".lock"):
            if _lock_is_free(p):
                _remove_tree(p)
            else:
                say(f"make clean: kept {where} (a run is writing beside it)")
        else:
            say(f"make clean: kept {where} (no {MARKER} marker of crosshead's: not a run's folder; the outputs "
                "of make bench and make reference are kept on purpose, remove them by hand)")
    try:
        results.rmdir()
    except OSError:
        pass


if __name__ == "__main__":
    import sys
    clean(Path(sys.argv[1] if len(sys.argv) > 1 else "results"))
