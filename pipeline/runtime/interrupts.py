"""Ctrl-C and SIGTERM end a run cleanly: the staging folder is removed, the lock released,
the picture process stopped, and the earlier result left as it was (exit 130 / 143).

The stop is done by a watcher thread, not by an exception in the main thread: a signal's
Python handler runs only between bytecodes, and a run spends seconds inside C calls
(gmsh meshing, PETSc solves) or, under MPI, waiting in a collective for a rank that has
already left; an exception would then come late or never. The C-level signal handler
writes the signal number to a wake-up pipe even while the main thread is blocked; the
watcher reads it, runs the clean-ups registered with :func:`on_stop` (newest first),
writes one line (rank 0) and ends the process with ``os._exit``. The watcher needs the
interpreter lock, which gmsh gives up while it meshes; PETSc's Krylov solves hold it, so
their monitor gives it up at every iteration (pipeline/fe/solve.py).

The main thread runs on while the watcher works. So the clean-ups run under the same
lock as the blocks that must not be cut in two (:func:`signals_wait`: putting the
finished folder in place), and the line is chosen after them, from what the output
folder's code last declared (:func:`stop_outcome`). A failure that the stop causes in the
main thread (a file of the removed staging folder, say) must not speak for the run: once
a stop has begun, :func:`yield_to_stop` keeps the main thread from writing a line or
exiting on its own.

Under mpirun every rank gets the signal, and mpirun kills the remaining ranks as soon as
one of them ends. A rank other than 0 has nothing to say and little to clean up, so it
would end first and rank 0 could be killed before its clean-up and its line. So the
silent ranks wait (at most QUIET_RANK_WAIT_S) after their clean-ups: rank 0 ends first,
and mpirun then ends them.

While the program is still loading, before the watcher is set up, the entry points
(``python -m pipeline``, ``pipeline.runtime.launch``) let :func:`stop_before_start` end the process
with the same line: nothing has been written yet.

gmsh's Python module resets SIGINT to the default action when imported, and PETSc
installs handlers that abort the MPI job on SIGTERM and on a closed pipe (SIGPIPE, exit
59). So PETSc is started without its handlers (pipeline/runtime/environment.py), and gmsh is
imported before ours are set.
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
from typing import Callable, Iterator

from pipeline.runtime.streams import ASCII_HANDLER

EXIT_FOR = {signal.SIGINT: 130, signal.SIGTERM: 143}
QUIET_RANK_WAIT_S = 10.0  # how long a silent rank lets rank 0 finish its stop (see module doc)
STOPPED = {signal.SIGINT: "interrupted (Ctrl-C)", signal.SIGTERM: "terminated (SIGTERM)"}
NOTHING_WRITTEN = "nothing written, the output folder is as it was"


class _Watcher:
    """The process's signal watcher and its clean-up stack (one per process, like atexit)."""

    def __init__(self) -> None:
        self.cleanups: list[Callable[[], None]] = []
        self.lock = threading.RLock()  # re-entrant: a guarded block may declare its outcome
        self.speak = True
        self.outcome: str | None = None  # what a stop says became of the output (stop_outcome)
        self.stopping = threading.Event()  # set when a signal's stop has begun


_WATCHER = _Watcher()  # process-wide by nature: signals and their handlers are per process
_ENDING = threading.Lock()  # held by the thread that ends the process (end_process)


def stop_line(signum: int) -> str:
    """The line a stop by ``signum`` writes now: how it stopped, and what became of the output."""
    return f"{STOPPED[signal.Signals(signum)]}: {_WATCHER.outcome or NOTHING_WRITTEN}"


def stop_outcome(text: str) -> None:
    """Declare what a stop from now on says became of the output (after "interrupted
    (Ctrl-C): "; until then NOTHING_WRITTEN). The first declaration of a command stands:
    a study declares at its start, and its variants' runs, which publish their folders
    inside it, do not replace it."""
    with _WATCHER.lock:
        if _WATCHER.outcome is None:
            _WATCHER.outcome = text


def declared_outcome() -> str:
    """What became of the output so far, as the command last declared it
    (:func:`stop_outcome`), or NOTHING_WRITTEN: the end of a failure line as of a stop's."""
    with _WATCHER.lock:
        return _WATCHER.outcome or NOTHING_WRITTEN


def new_command() -> None:
    """Forget the outcome a previous command in this process declared (tests call the
    command line several times in one process)."""
    with _WATCHER.lock:
        _WATCHER.outcome = None


def yield_to_stop() -> None:
    """Return at once unless a signal's stop has begun; then wait for it to end the
    process. Called before this thread writes a failure line or lets the process exit:
    the stop owns the exit status and the line."""
    if not _WATCHER.stopping.is_set():
        return
    while True:
        time.sleep(1.0)


@contextlib.contextmanager
def on_stop(cleanup: Callable[[], None]) -> Iterator[None]:
    """Run ``cleanup`` if the process is stopped by a signal while inside this block."""
    with _WATCHER.lock:
        _WATCHER.cleanups.append(cleanup)
    try:
        yield
    finally:
        with _WATCHER.lock:
            if cleanup in _WATCHER.cleanups:
                _WATCHER.cleanups.remove(cleanup)


def signals_wait() -> contextlib.AbstractContextManager:
    """A block that a stop's clean-ups wait for, and never cut in two (as a context
    manager): keep it short."""
    return _WATCHER.lock


def _run_cleanups() -> None:
    """The clean-ups registered with :func:`on_stop`, newest first, each whatever the
    others do; under the lock of :func:`signals_wait`, so none runs inside such a block."""
    with _WATCHER.lock:
        for cleanup in list(reversed(_WATCHER.cleanups)):
            try:
                cleanup()
            except Exception:  # noqa: BLE001  (the others must still run)
                pass


def end_process(code: int, line: str | Callable[[], str] | None, run_cleanups: bool) -> None:
    """End the process with status ``code``: the clean-ups registered with :func:`on_stop`
    if ``run_cleanups``, then ``line`` on stderr (if any; a callable is asked after the
    clean-ups). Does not return.

    The first thread to call this ends the process; a second one (a signal while a failure
    is ending the run, say) waits here until it has, so one line is written, not two.
    Python's buffered streams are flushed from the main thread only: another thread could
    wait forever on a buffer's lock that the main thread holds.
    """
    _ENDING.acquire()
    if run_cleanups:
        _run_cleanups()
    if threading.current_thread() is threading.main_thread():
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError, AttributeError):  # a closed pipe, or no stream: the line below still goes out
                pass
    if callable(line):
        line = line()
    if line is not None:
        try:
            os.write(2, (line + "\n").encode(_stderr_encoding(), errors=ASCII_HANDLER))
        except (OSError, LookupError):
            pass
    os._exit(code)


def _stderr_encoding() -> str:
    """The encoding of stderr's text stream (UTF-8 when there is none): the line is written
    to the descriptor directly, in the encoding the reader chose (PYTHONIOENCODING)."""
    return getattr(sys.stderr, "encoding", None) or "utf-8"


def _stop(signum: int) -> None:
    """Run the clean-ups, say how the run stopped (rank 0), end the process."""
    _WATCHER.stopping.set()
    if _WATCHER.speak:
        end_process(EXIT_FOR[signum], lambda: stop_line(signum), run_cleanups=True)
    _run_cleanups()
    time.sleep(QUIET_RANK_WAIT_S)  # outside end_process: a failure may still end it first
    end_process(EXIT_FOR[signum], None, run_cleanups=False)


def _watch(read_fd: int) -> None:
    while True:
        data = os.read(read_fd, 1)
        if data and data[0] in EXIT_FOR:
            _stop(signal.Signals(data[0]))


def _noop(signum: int, frame) -> None:
    """The Python-level handler: the watcher thread does the work (see module doc)."""


def first_rank_by_environment() -> bool:
    """Is this process MPI rank 0 (or not under MPI at all), as its launcher's environment
    says? Readable before MPI starts, so a line can be written once under mpirun or srun."""
    return os.environ.get("OMPI_COMM_WORLD_RANK", os.environ.get("PMI_RANK", "0")) == "0"


def stop_before_start(signum: int, frame: object = None) -> None:
    """The handler of SIGINT and SIGTERM until :func:`install` sets the watcher's: the
    program is still loading and has written nothing, so it ends here with its line and
    status (without it, Ctrl-C printed Python's traceback)."""
    end_process(EXIT_FOR[signal.Signals(signum)], stop_line(signum) if first_rank_by_environment() else None,
                run_cleanups=False)


def install(speak: bool = True) -> None:
    """Import gmsh (its import resets SIGINT), then route SIGINT and SIGTERM to the watcher.

    ``speak``: write the one line when stopped (False on MPI ranks other than 0).
    Only the main thread of a program may call this; a second call changes ``speak`` only.
    """
    import gmsh  # imported for its side effect on SIGINT, before ours is set
    _WATCHER.speak = speak
    if signal.getsignal(signal.SIGTERM) is _noop:
        return
    read_fd, write_fd = os.pipe()
    os.set_blocking(write_fd, False)
    signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
    for s in EXIT_FOR:
        signal.signal(s, _noop)
    # gmsh.finalize() puts back the SIGINT handler gmsh found at its import (Python's, which
    # raises KeyboardInterrupt in the main thread beside the watcher's stop): make it ours.
    gmsh.oldsig = _noop
    threading.Thread(target=_watch, args=(read_fd,), name="stop-watcher", daemon=True).start()
    with contextlib.suppress(OSError, ValueError, AttributeError):  # no stdout, or a full or closed one
        sys.stdout.flush()
