"""The output folder: which folders a run may replace, the lock, and all-or-nothing writing.

A run writes into a hidden staging folder beside ``--out`` and renames it into place only
when complete, so a failed or interrupted run leaves the earlier result as it was. The
tool replaces a folder only when it is empty or carries the marker file that the tool
writes last into every results folder; any other folder belongs to the user and is
refused before any work is done (docs/design.md §8).
"""
from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import shutil
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from mpi4py import MPI

from pipeline.errors import InputError
from pipeline.runtime.folders import MARKER, REPOSITORY, STAGING_MARK, marked_kind, protected_reason
from pipeline.runtime.idle import wait_for_ranks
from pipeline.runtime.interrupts import on_stop, signals_wait, stop_outcome

# Files a run writes; a folder holding nothing else (and a results.json) is a results folder
# of a version of the tool that wrote no marker yet.
RUN_FILES = frozenset({"results.json", "report.md", "report.html", "mesh.msh", "displacement.pvd",
                       "displacement.vtu", "von_mises.vtu", "fields.vtu", "von_mises.png", "convergence.png",
                       "sections.png", "peaks.png", MARKER})


class OutputError(InputError):
    """The output could not be written (disk full, permission); nothing was written."""


def default_out(name: str) -> Path:
    """The default output folder of a case: ``results/<name>`` in the repository, wherever
    the command is started from (a run from ``/`` must not write ``/results``)."""
    return REPOSITORY / "results" / name


# What the marker of each kind of results folder says it holds, for the refusal line.
KINDS = {"run": "a run's results", "sweep": "a design study's results", "summary": "a size summary"}


def ownership_reason(out: Path, kind: str = "run") -> str | None:
    """Why an existing ``out`` may not be written by a command of ``kind`` ("run": run and
    converge replace it; "sweep": a study resumes in it), or None when it is empty or holds
    that kind's results. Another kind's results folder is refused too: a run would replace a
    study's finished variants, and a study would write its report over a run's."""
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
    else:
        field_parts = {n for n in names if n.startswith("displacement") and n.endswith((".vtu", ".pvtu"))}
        if "results.json" in names and names - field_parts <= RUN_FILES:
            found = "run"  # written by an earlier version of the tool (no marker yet)
    if found is None:
        return (f"it holds files crosshead did not write (no {MARKER} marker); "
                "choose a new or empty folder")
    if found != kind:
        return f"it holds {KINDS[found]}, not {KINDS[kind]}; choose another folder"
    return None


def check_out(raw: str | os.PathLike, kind: str = "run") -> Path:
    """The resolved output folder for a command of ``kind`` (see :func:`ownership_reason`),
    or InputError naming it and why it is refused.

    Runs before any work: a folder that will be refused costs the user nothing.
    """
    text = os.fspath(raw)
    out = Path(text).expanduser().resolve()
    reason = protected_reason(out, text) or ownership_reason(out, kind)
    if reason is not None:
        raise InputError(f"out: refusing {text or repr(text)} ({out}): {reason}")
    return out


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
    return out.parent / f".{out.name}.lock"


def acquire_lock(out: Path) -> Lock:
    """Lock ``out`` for this process, or InputError naming the process that holds it.

    flock is released by the kernel when its holder dies (even by SIGKILL), so a stale
    lock file never blocks a later run.
    """
    path = lock_path(out)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
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


def remove_leftovers(out: Path) -> list[Path]:
    """Delete staging folders and replaced results of dead runs to ``out``; return them.

    Called with the lock held, so none of them belongs to a running process. Only folders
    the tool made (staging mark inside, or the ``.old-`` name of a replaced results
    folder with its marker) are touched.
    """
    removed = []
    for p in out.parent.glob(f".{out.name}.*"):
        ours = (p.name.endswith(".partial") and ((p / STAGING_MARK).exists() or (p / MARKER).exists())) or (
            ".old-" in p.name and (p / MARKER).exists())
        if p.is_dir() and not p.is_symlink() and ours:
            _remove_marked(p, STAGING_MARK if (p / STAGING_MARK).exists() else MARKER)
            removed.append(p)
    return removed


def _created_parents(folder: Path) -> list[Path]:
    """Create ``folder``'s missing parents; return those created, deepest first."""
    missing = [p for p in folder.parents if not p.exists()][::-1]
    created = []
    for p in missing:
        p.mkdir()
        created.append(p)
    return created[::-1]


def _prepare(raw: str) -> tuple[Path, Lock, list[Path], list[Path]]:
    """Rank 0's checks and set-up: (staging, lock, parents created, leftovers removed)."""
    out = check_out(raw)
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
        leftovers = remove_leftovers(out)
        check_out(raw)  # again under the lock: another run may have changed it meanwhile
        staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
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
        if p.name == mark:
            continue
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                p.unlink()
    with contextlib.suppress(OSError):
        (folder / mark).unlink()
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


def _publish(staging: Path, out: Path) -> None:
    """Mark ``staging`` as a finished results folder and put it in place of ``out``. The
    results marker comes before the staging mark goes, so the folder always carries one."""
    (staging / MARKER).write_text(json.dumps({"tool": "crosshead", "written": time.strftime(
        "%Y-%m-%dT%H:%M:%S%z"), "pid": os.getpid()}) + "\n", encoding="utf-8")
    (staging / STAGING_MARK).unlink()
    old = None
    if out.exists():
        old = out.with_name(f".{out.name}.old-{os.getpid()}")
        out.rename(old)
    try:
        staging.rename(out)
    except OSError:
        if old is not None:  # the earlier result back in its place, not left to be removed
            old.rename(out)
        raise
    stop_outcome(f"the results were already written to {out}")
    if old is not None:
        _remove_marked(old, MARKER)


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
            prepared = _prepare(raw)
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
            yield staging
            wait_for_ranks(comm)  # rank 0 may still be waiting for the picture
            if comm.rank == 0:
                try:
                    with signals_wait():  # a stop between the two renames would lose both
                        _publish(staging, out)
                except OSError as exc:
                    raise OutputError(f"out: cannot write {out}: {exc.strerror or exc}; nothing written, "
                                      "the output folder is as it was") from None
            ok = True
        finally:
            if comm.rank == 0 and not ok:
                with signals_wait():  # a stop's clean-up waits, and must not end the process half-way
                    _discard(staging)
                    lock.release()  # before the parents: its file is in the innermost one
                    _remove_empty(created)
