"""Which cores a process or thread may run on (Linux; elsewhere these do nothing).

Why: mpirun binds each rank to one core, and a child process or a new thread inherits its
creator's binding. Work a rank hands to a helper process (the drawing, the PDF browser) or
to threads (compression) would then share the rank's one core while another core idles.
"""
from __future__ import annotations

import contextlib
import os
from typing import Iterator


def unbind(pid: int) -> None:
    """Let process ``pid`` (0: this thread) run on every core of the machine."""
    with contextlib.suppress(AttributeError, OSError):  # no affinity outside Linux
        os.sched_setaffinity(pid, range(os.cpu_count() or 1))


@contextlib.contextmanager
def unbound() -> Iterator[None]:
    """This thread runs on every core for the block, and threads it starts there inherit
    that; its binding is put back after."""
    bound = None
    with contextlib.suppress(AttributeError, OSError):
        bound = os.sched_getaffinity(0)
    unbind(0)
    try:
        yield
    finally:
        if bound is not None:
            with contextlib.suppress(OSError):
                os.sched_setaffinity(0, bound)
