"""What the command line says: progress lines on stderr, stamped with the seconds since the
program started, and the results on stdout, so that ``crosshead run ... > results.txt``
keeps them apart. A stream that cannot take a line loses the line, never the run."""
from __future__ import annotations

import contextlib
import sys
import textwrap
import threading
import time

from pipeline.runtime.streams import closed_at_start, silence_stdout

T_START = time.perf_counter()
WIDTH = 100  # the longest line the closing lines print (characters)


class StdoutError(Exception):
    """stdout could not take a line (a full disk, /dev/full); the message names stdout.
    Not an OSError: the line must not blame --out."""


def progress(msg: str) -> None:
    """A progress line on stderr, stamped with the seconds since the program started. A
    stderr that cannot take it loses the line, never the run (pipeline.runtime.streams)."""
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.write(f"[{time.perf_counter() - T_START:7.2f} s] {msg}\n")
        sys.stderr.flush()


def quiet(msg: str) -> None:
    """A progress sink for --quiet (and ranks other than 0)."""


CLOSED_STDOUT = ("stdout: closed when crosshead started, so its closing lines are not shown; the results are "
                 "in the output folder")
_said_closed: list[bool] = []  # whether CLOSED_STDOUT was said (once per process)


def show(line: str) -> None:
    """Print a line. A stdout closed when the program started (``>&-``) takes none: that is
    said once on stderr (CLOSED_STDOUT). A closed pipe (``| head``) silences the rest and
    the run goes on: the reader wanted no more. Any other failure (a full disk, /dev/full)
    is the command's: StdoutError, and the rest silenced so that the exit does not try
    again."""
    if closed_at_start(1):
        if not _said_closed:
            _said_closed.append(True)
            with contextlib.suppress(OSError, ValueError):
                sys.stderr.write(CLOSED_STDOUT + "\n")
                sys.stderr.flush()
        return
    try:
        print(line, flush=True)
    except (BrokenPipeError, ValueError):  # ValueError: a stream closed in this process
        silence_stdout()
    except OSError as exc:
        if threading.current_thread() is not threading.main_thread():
            return  # the meshing heartbeat's: the main thread's next line meets the failure and reports it
        silence_stdout()
        raise StdoutError(f"stdout: cannot write ({exc.strerror or exc})") from None


def wrapped(text: str) -> list[str]:
    """``text`` as lines of at most WIDTH characters, the continuations indented by two
    spaces; a word longer than a line (a long path) is kept whole on a line of its own."""
    return textwrap.wrap(text, WIDTH, subsequent_indent="  ", break_long_words=False, break_on_hyphens=False)


def say(text: str) -> None:
    """Print ``text`` (:func:`show`) wrapped to WIDTH: a closing line a person scans."""
    for line in wrapped(text):
        show(line)
