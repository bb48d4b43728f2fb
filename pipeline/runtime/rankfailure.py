"""A failure on one MPI rank ends the run on every rank: one line and its exit status.

Why: the ranks meet in collectives (the mesh's distribution, the solves, reductions, the
output folder's barrier). A rank that fails alone and returns normally enters
``MPI_Finalize``, which waits for the others, while they wait in a collective for it: the
run hangs with nothing said. Failures that every rank meets (bad input, a diverged solve)
end well either way; those met by one rank's own data (its cells, its part of the mesh) do
not. So under more than one rank a failing rank first waits up to SAME_FAILURE_WAIT_S for
the others to fail too (a barrier on a communicator of its own); if they do, every rank
returns its status as usual and rank 0 writes the line. If they do not:

- rank 0 writes its line and ends its process; mpirun then ends the others;
- another rank sends its line and status to rank 0 and waits. On rank 0 a listener thread
  runs the stop's clean-ups (the staging folder, the lock: pipeline.runtime.interrupts), writes
  the line and ends the process, so the line is written once, by the rank that speaks.
  If rank 0 has not ended after HAND_OVER_WAIT_S (its main thread can hold Python's lock
  inside a C call, and then the listener cannot run), the rank writes the line itself
  and ends; rank 0 is then stopped by mpirun and its next run removes the staging folder.

Processes end with ``os._exit``, not ``MPI_Finalize``: mpirun ends the remaining ranks as
soon as one ends without finalising (with ``--quiet``, which pipeline.runtime.launch passes,
without a banner) and exits with that rank's status.
"""
from __future__ import annotations

import sys
import threading
import time
from typing import Self

from mpi4py import MPI

from pipeline.runtime.interrupts import end_process, yield_to_stop

FAILURE_TAG = 4047  # on a communicator of its own: no other message can match it
SAME_FAILURE_WAIT_S = 1.0  # ranks that fail alike (bad input) do so within milliseconds
HAND_OVER_WAIT_S = 10.0  # how long a failing rank waits for rank 0 to end the run
POLL_S = 0.1  # the listener's interval (an Iprobe: microseconds of CPU)


class RankFailures:
    """The failure channel of one command on ``comm`` (collective to create: every rank
    creates it at the same point). Use as a context manager around the command."""

    def __init__(self, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
        self.rank = comm.rank
        self.comm = comm.Dup() if comm.size > 1 else None
        self._done = threading.Event()
        self._listener: threading.Thread | None = None
        if self.comm is not None and self.rank == 0 and MPI.Query_thread() >= MPI.THREAD_MULTIPLE:
            self._listener = threading.Thread(target=self._listen, name="rank-failures", daemon=True)
            self._listener.start()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self._done.set()
        if self._listener is not None:
            self._listener.join()

    def _listen(self) -> None:
        """Rank 0: end the run with the line of the first rank that reports a failure."""
        status = MPI.Status()
        while not self._done.wait(POLL_S):
            if self.comm.Iprobe(source=MPI.ANY_SOURCE, tag=FAILURE_TAG, status=status):
                code, line = self.comm.recv(source=status.Get_source(), tag=FAILURE_TAG)
                end_process(code, line, run_cleanups=True)

    def fail(self, code: int, line: str) -> int:
        """Report a failure of this rank with exit status ``code`` and its ``line`` (no
        newline). Returns ``code`` when every rank fails (one rank, or all within
        SAME_FAILURE_WAIT_S: bad input, say), rank 0 having written the line; otherwise the
        run ends here on every rank (see module doc) and this does not return. During a
        signal's stop it waits for the stop to end the process (the stop may have caused
        this failure: pipeline.runtime.interrupts.yield_to_stop)."""
        yield_to_stop()
        if self.comm is None:
            sys.stderr.write(line + "\n")
            return code
        self._done.set()  # from here this rank's own failure decides, not the listener
        everyone = self.comm.Ibarrier()
        if _wait(everyone, SAME_FAILURE_WAIT_S):
            if self.rank == 0:
                sys.stderr.write(line + "\n")
            return code
        if self.rank == 0:
            end_process(code, line, run_cleanups=True)
        self.comm.send((code, line), dest=0, tag=FAILURE_TAG)
        if _wait(everyone, HAND_OVER_WAIT_S):  # rank 0 failed too, later: it writes its line
            return code
        end_process(code, line, run_cleanups=True)
        return code  # not reached: end_process does not return


def _wait(request: MPI.Request, seconds: float) -> bool:
    """True when ``request`` completes within ``seconds`` (tested, not waited on: a blocking
    wait would spin a core)."""
    deadline = time.monotonic() + seconds
    while not request.Test():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.002)
    return True
