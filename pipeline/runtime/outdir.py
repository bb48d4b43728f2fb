"""The output folder: which folders a run may replace, the lock, and all-or-nothing writing.

A run writes into a hidden staging folder beside ``--out`` and renames it into place only
when complete, so a failed or interrupted run leaves the earlier result as it was. The
tool replaces a folder only when it is empty or carries the marker file that the tool
writes last into every results folder (its own JSON, listing the files the run wrote);
any other folder belongs to the user and is refused before any work is done
(docs/design.md §8).

Files a user adds to a results folder (notes, a ParaView state in a subfolder) are carried
over into the new result when a run replaces it, not refused: such files belong next to
the results they describe, and a refusal would make the user move them out and back on
every re-run. Only the names the earlier run's marker lists are the tool's; everything
else is moved (a rename, same file system) into the published folder. A user's file
with a name the tool writes (``results.json`` say) would be overwritten, so that folder is
refused up front, naming the file. A run killed between the renames leaves its earlier
folder beside ``--out`` with the user's files in it; the next run to the same folder
finishes the carry-over (or puts the earlier result back) instead of deleting it.

The names beside ``--out`` (lock, staging, replaced folder) start with ``.<name>`` and,
for a name longer than NAME_ROOM bytes, a shortened name and a hash of the whole one, so
that every folder name the file system accepts (255 bytes) can be an output folder.
"""
from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import json
import os
import re
import shutil
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from mpi4py import MPI

from pipeline.errors import InputError, OutputError
from pipeline.runtime.folders import (MARKER, RUN_FILES, STAGING_MARK, enclosing_study, is_field_part,
                                      marked_kind, marker_data, protected_reason, tool_names, user_names)
from pipeline.runtime.idle import wait_for_ranks
from pipeline.runtime.interrupts import on_stop, signals_wait, stop_outcome

NAME_ROOM = 200  # bytes of --out's name kept in the names beside it (see module doc)
HASH_CHARS = 12  # hex digits of the name's hash in a shortened name (48 bits)


# What the marker of each kind of results folder says it holds, for the refusal line.
KINDS = {"run": "a run's results", "sweep": "a design study's results", "summary": "a size summary"}


def _named(names: list[str], most: int = 3) -> str:
    """The first ``most`` names for a one-line message, "..." for the rest."""
    return ", ".join(names[:most]) + (", ..." if len(names) > most else "")


def ownership_reason(out: Path, kind: str = "run") -> str | None:
    """Why an existing ``out`` may not be written by a command of ``kind`` ("run": run and
    converge replace it; "sweep": a study resumes in it), or None when it is empty or holds
    that kind's results. Another kind's results folder is refused too: a run would replace a
    study's finished variants, and a study would write its report over a run's. A run's
    folder holding a user's file with a name the run writes is refused, naming it."""
    if not out.exists():
        return None
    if not out.is_dir():
        return "it exists and is not a folder"
    try:
        names = {p.name for p in out.iterdir()}
    except OSError as exc:
        return f"it cannot be read ({exc.strerror or exc})"
    if not names:
        return None
    found = None
    if MARKER in names:
        found = marked_kind(out)
        if found is None:
            return (f"its {MARKER} marker is not crosshead's (empty, unreadable, a folder or another "
                    "program's), so the files in it are not the tool's; choose a new or empty folder")
    else:
        field_parts = {n for n in names if is_field_part(n)}
        if "results.json" in names and names - field_parts <= RUN_FILES:
            found = "run"  # written by an earlier version of the tool (no marker yet)
    if found is None:
        return (f"it holds files crosshead did not write (no {MARKER} marker); "
                "choose a new or empty folder")
    if found != kind:
        return f"it holds {KINDS[found]}, not {KINDS[kind]}; choose another folder"
    if kind == "run":
        clash = [n for n in user_names(out) if n in RUN_FILES or is_field_part(n)]
        if clash:
            return (f"it holds {_named(clash)}, which crosshead did not write and a run would overwrite; "
                    "move or rename them, or choose another folder")
    return None


def check_out(raw: str | os.PathLike, kind: str = "run", inside_study_ok: bool = False) -> Path:
    """The resolved output folder for a command of ``kind`` (see :func:`ownership_reason`),
    or InputError naming it and why it is refused.

    Runs before any work: a folder that will be refused costs the user nothing. A folder
    inside a design study's is refused unless ``inside_study_ok`` (the study's own
    variants): a run there would stand for a variant at the study's next resume. The
    study's folder itself is refused to a run by its kind, and resumed by a sweep.
    """
    text = os.fspath(raw)
    out = Path(text).expanduser().resolve()
    reason = protected_reason(out, text)
    if reason is None and not inside_study_ok:
        study = enclosing_study(out.parent)  # the study itself: refused below by its kind, or resumed
        if study is not None:
            reason = (f"it lies inside the design study {study}: only that study writes there (its variants "
                      "are its own runs); choose a folder outside it")
    reason = reason or ownership_reason(out, kind)
    if reason is not None:
        raise InputError(f"out: refusing {text or repr(text)} ({out}): {reason}")
    return out


def sidecar_stem(out: Path) -> str:
    """The start of every name the tool puts beside ``out``: ``.<name>``, or for a name
    longer than NAME_ROOM bytes its first bytes, ``~`` and a hash of the whole name (the
    file system allows 255 bytes, and the longest suffix takes 27)."""
    raw = os.fsencode(out.name)
    if len(raw) <= NAME_ROOM:
        return f".{out.name}"
    head = os.fsdecode(raw[:NAME_ROOM - HASH_CHARS - 1].decode("utf-8", errors="ignore").encode())
    return f".{head}~{hashlib.sha256(raw).hexdigest()[:HASH_CHARS]}"


@dataclass
class Lock:
    """An exclusive lock on ``.<name>.lock`` beside an output folder (rank 0 holds it)."""

    path: Path
    fd: int
    _guard: threading.Lock = field(default_factory=threading.Lock, repr=False, compare=False)

    def release(self) -> None:
        """Remove the lock file, then let go (unlink first: a waiter re-checks the inode).
        Releasing twice, from two threads too (a stop's clean-up and the main thread),
        closes the file once: a second close could close a file opened meanwhile."""
        with self._guard:
            if self.fd < 0:
                return
            with contextlib.suppress(OSError):
                self.path.unlink()
            os.close(self.fd)
            self.fd = -1


def lock_path(out: Path) -> Path:
    """The lock file beside ``out``."""
    return out.parent / f"{sidecar_stem(out)}.lock"


def acquire_lock(out: Path) -> Lock:
    """Lock ``out`` for this process, or InputError naming the process that holds it.

    flock is released by the kernel when its holder dies (even by SIGKILL), so a stale
    lock file never blocks a later run.
    """
    path = lock_path(out)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                os.close(fd)
                raise
            holder = os.pread(fd, 200, 0).decode(errors="replace").strip() or "another process"
            os.close(fd)
            raise InputError(f"out: {out} is being written by another run ({holder}); "
                             "wait for it to finish or choose another --out") from None
        try:
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:  # not a file the previous holder unlinked while we waited
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"pid {os.getpid()} on {os.uname().nodename}\n".encode(), 0)
            return Lock(path, fd)
        os.close(fd)


def _leftover_pattern(out: Path) -> re.Pattern:
    """The names of the staging and replaced folders of runs to ``out`` (and of no other
    folder: ``.res.x.abcd1234.partial`` is the staging folder of ``res.x``, not of ``res``)."""
    return re.compile(re.escape(sidecar_stem(out)) + r"\.(?:[a-z0-9_]{8}(?:\.discarded)?\.partial|old-\d+)")


def remove_leftovers(out: Path, notice=lambda s: None) -> list[Path]:
    """Deal with the staging and replaced folders of dead runs to ``out``; return those removed.

    Called with the lock held, so none of them belongs to a running process. Only folders
    the tool made are touched: a staging folder (staging mark or marker inside) is removed;
    a replaced folder (``.old-``, the tool's marker inside) goes back in place when ``out``
    is missing (the run died between its two renames), or else gives its user's files to
    ``out`` (see module doc) and is removed. ``notice`` receives a line for one kept.
    """
    removed = []
    pattern = _leftover_pattern(out)
    try:
        entries = [p for p in out.parent.iterdir() if pattern.fullmatch(p.name)]
    except OSError:
        return removed
    for p in entries:
        if not p.is_dir() or p.is_symlink():
            continue
        if p.name.endswith(".partial") and ((p / STAGING_MARK).exists() or marker_data(p) is not None):
            _remove_marked(p, STAGING_MARK if (p / STAGING_MARK).exists() else MARKER)
            removed.append(p)
        elif ".old-" in p.name and marker_data(p) is not None:
            if not os.path.lexists(out):
                p.rename(out)
                notice(f"put back {out.name}, the earlier result a killed run had set aside")
                continue
            left = _carry_over(p, out)
            if _remove_replaced(p):
                removed.append(p)
            else:
                notice(f"kept {p.name} beside the output folder: it holds {_named(left)}, not crosshead's, "
                       f"and {out.name} already holds that name")
    return removed


def _carry_over(old: Path, new: Path) -> list[str]:
    """Move the user's entries of ``old`` (a replaced results folder) into ``new``; return
    those that stay in ``old`` because ``new`` holds that name."""
    left = []
    for name in user_names(old):
        if os.path.lexists(new / name):
            left.append(name)
            continue
        try:
            (old / name).rename(new / name)
        except OSError:
            left.append(name)
    return left


def _remove_replaced(old: Path) -> bool:
    """Delete the tool's files of a replaced results folder, its marker last, and the
    folder when nothing else is left; True when it is gone. The user's files (those the
    carry-over could not move) stay, with the marker that names them for the next run."""
    try:
        names = {p.name for p in old.iterdir()}
    except OSError:
        return False
    if names - tool_names(old, names):
        for name in tool_names(old, names) - {MARKER}:
            _remove_entry(old / name)
        return False
    _remove_marked(old, MARKER)
    return not os.path.lexists(old)


def _remove_entry(p: Path) -> None:
    """Delete a file or a folder tree (a symlink itself, never its target)."""
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            p.unlink()


def _umask() -> int:
    """The process's file-mode creation mask, read without changing it (Linux's
    /proc/self/status; elsewhere by setting it and putting it back)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _created_parents(folder: Path) -> list[Path]:
    """Create ``folder``'s missing parents; return those created, deepest first."""
    missing = [p for p in folder.parents if not p.exists()][::-1]
    created = []
    for p in missing:
        p.mkdir()
        created.append(p)
    return created[::-1]


def _prepare(raw: str, notice=lambda s: None) -> tuple[Path, Lock, list[Path], list[Path]]:
    """Rank 0's checks and set-up: (staging, lock, parents created, leftovers removed).
    The study check is the caller's (the command line's; a study's own variants are
    written inside it)."""
    out = check_out(raw, inside_study_ok=True)
    try:
        created = _created_parents(out)
    except OSError as exc:
        raise InputError(f"out: cannot write to {out.parent} (creating it failed: {exc.strerror or exc})") from None
    try:
        lock = acquire_lock(out)
    except OSError as exc:
        _remove_empty(created)
        raise InputError(f"out: cannot write to {out.parent}: {exc.strerror or exc}") from None
    try:
        leftovers = remove_leftovers(out, notice)
        check_out(raw, inside_study_ok=True)  # again under the lock: another run may have changed it meanwhile
        staging = Path(tempfile.mkdtemp(prefix=f"{sidecar_stem(out)}.", suffix=".partial", dir=out.parent))
        # mkdtemp makes the folder private (0700); a results folder is made like any other
        # folder, 0777 under the user's umask (0755 with the usual 022), for others to read.
        staging.chmod(0o777 & ~_umask())
        (staging / STAGING_MARK).write_text(f"pid {os.getpid()}\n", encoding="utf-8")
    except BaseException as exc:
        lock.release()
        _remove_empty(created)
        if isinstance(exc, OSError):
            raise InputError(f"out: cannot write to {out.parent}: {exc.strerror or exc}") from None
        raise
    return staging, lock, created, leftovers


def _remove_empty(folders: list[Path]) -> None:
    """Remove the given folders (deepest first) where they are still empty."""
    for p in folders:
        with contextlib.suppress(OSError):
            p.rmdir()


def _remove_marked(folder: Path, mark: str) -> None:
    """Delete ``folder``, its ``mark`` file last: killed half-way, it still carries the mark
    by which :func:`remove_leftovers` knows it for the tool's own."""
    try:
        entries = list(folder.iterdir())
    except OSError:
        return
    for p in entries:
        if p.name != mark:
            _remove_entry(p)
    _remove_entry(folder / mark)
    with contextlib.suppress(OSError):
        folder.rmdir()


def _discard(staging: Path) -> None:
    """Remove a staging folder that will not be published. It is renamed first, so that a
    file written to it from now on (the main thread writes on while a stop's clean-up runs)
    fails instead of reviving it; the new name is still one :func:`remove_leftovers` knows."""
    trash = staging.with_name(staging.name.removesuffix(".partial") + ".discarded.partial")
    try:
        staging.rename(trash)
    except OSError:
        trash = staging  # already gone, or renamed by a stop's clean-up
    _remove_marked(trash, STAGING_MARK)


def _publish(staging: Path, out: Path) -> list[str]:
    """Mark ``staging`` as a finished results folder and put it in place of ``out``, with
    the user's files of ``out`` carried over (module doc). The results marker, listing the
    files the run wrote, comes before the staging mark goes, so the folder always carries
    one. Returns the user's entries that stay beside it (the new folder holds their name)."""
    files = sorted(p.name for p in staging.iterdir() if p.name != STAGING_MARK)
    (staging / MARKER).write_text(json.dumps({"tool": "crosshead", "written": time.strftime(
        "%Y-%m-%dT%H:%M:%S%z"), "pid": os.getpid(), "files": files}) + "\n", encoding="utf-8")
    (staging / STAGING_MARK).unlink()
    old = None
    if out.exists():
        old = out.with_name(f"{sidecar_stem(out)}.old-{os.getpid()}")
        out.rename(old)
    try:
        staging.rename(out)
    except OSError as exc:
        if old is not None:  # the earlier result back in its place, not left to be removed
            try:
                old.rename(out)
            except OSError:
                raise OutputError(f"out: cannot write {out}: {exc.strerror or exc}", outcome=(
                    f"the earlier result is in {old} (putting it back failed); the next run to {out.name} "
                    "puts it back")) from None
        raise
    stop_outcome(f"the results were already written to {out}")
    if old is None:
        return []
    left = _carry_over(old, out)
    _remove_replaced(old)
    return left


def _within(filename: object, folder: Path) -> bool:
    """True when ``filename`` (an OSError's, maybe None or bytes) names ``folder`` or a path in it."""
    if filename is None:
        return False
    path = Path(os.fsdecode(filename))
    return path == folder or folder in path.parents


@contextlib.contextmanager
def staged_dir(out_dir: str | os.PathLike, comm: MPI.Comm = MPI.COMM_WORLD,
               notice=lambda s: None) -> Iterator[Path]:
    """Yield a fresh staging folder; on success it replaces ``out_dir``, on any error or
    interrupt it is removed and ``out_dir`` stays as it was.

    Raises InputError before any work when ``out_dir`` may not be used (see module doc) or
    another run holds its lock. ``notice`` receives one line per leftover it removes.
    """
    raw = os.fspath(out_dir)
    prepared: object = None
    if comm.rank == 0:
        try:
            prepared = _prepare(raw, notice)
        except InputError as exc:
            prepared = exc
    shared = comm.bcast(prepared[0] if isinstance(prepared, tuple) else prepared, root=0)
    if isinstance(shared, Exception):
        raise shared
    staging = Path(shared)
    out = Path(raw).expanduser().resolve()
    ok = False
    with contextlib.ExitStack() as stack:
        if comm.rank == 0:  # rank 0 alone holds the lock and touches the file system
            _, lock, created, leftovers = prepared  # type: ignore[misc]
            for p in leftovers:
                notice(f"removed {p.name} beside the output folder (left by a run that was killed)")

            def discard() -> None:
                _discard(staging)
                lock.release()
                _remove_empty(created)
            stack.callback(lock.release)
            stack.enter_context(on_stop(discard))
        try:
            try:
                yield staging
            except OSError as exc:
                if not isinstance(exc, OutputError) and _within(exc.filename, staging):
                    raise OutputError(f"out: cannot write {out}: {exc.strerror or exc}") from None
                raise
            wait_for_ranks(comm)  # rank 0 may still be waiting for the picture
            if comm.rank == 0:
                try:
                    with signals_wait():  # a stop between the two renames would lose both
                        left = _publish(staging, out)
                except OutputError:
                    raise
                except OSError as exc:
                    raise OutputError(f"out: cannot write {out}: {exc.strerror or exc}") from None
                if left:
                    notice(f"kept {_named(left)} beside {out} in {sidecar_stem(out)}.old-{os.getpid()}: "
                           "not crosshead's, and the new result holds that name")
            ok = True
        finally:
            if comm.rank == 0 and not ok:
                with signals_wait():  # a stop's clean-up waits, and must not end the process half-way
                    _discard(staging)
                    lock.release()  # before the parents: its file is in the innermost one
                    _remove_empty(created)
