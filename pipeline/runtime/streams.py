"""The standard streams, made safe before the program writes anything.

- A closed descriptor 0, 1 or 2 (``P >&-``, ``P 2>&-``) is opened on /dev/null. Left
  closed, the next file the run opens would take its number, and anything written to
  "stdout" (by Python, PETSc or gmsh) would go into that file; Python also sets
  ``sys.stdout`` (or ``sys.stderr``) to None then, and a write to it is an
  AttributeError. The user closed the stream: what goes to it is not wanted.
- Characters the streams' encoding cannot show (``PYTHONIOENCODING=ascii``, a C locale)
  are written as ASCII text ("x" for "×", "+/-" for "±") instead of ending the output at
  the first one.
- stderr never raises: when it is full or gone, the failure line is lost but the exit
  status still says what happened (docs/design.md §8). stdout's failures are the
  command's to report (pipeline/cli.py).
- A stdout closed at the start is remembered (:func:`closed_at_start`): what the command
  would have shown there is said to be lost, once, on stderr (pipeline/cli/terminal.py).
  Like the signal watcher, this is the process's own state: its streams are the process's.
"""
from __future__ import annotations

import codecs
import contextlib
import io
import os
import sys

ASCII_HANDLER = "crosshead-ascii"
# The characters the tool's lines use, as ASCII text; any other becomes "?".
ASCII_TEXT = {"×": "x", "±": "+/-", "…": "...", "–": "-", "—": "-", "−": "-", "≤": "<=", "≥": ">=",
              "→": "->", "·": "*", "²": "^2", "³": "^3", "°": " deg", "σ": "sigma", "μ": "u", "≈": "~",
              "√": "sqrt", "Δ": "d", "∞": "inf", "‰": "o/oo", "\u2009": " ", "\u00a0": " ", "’": "'",
              "“": '"', "”": '"'}


def _as_ascii(exc: UnicodeError) -> tuple[str, int]:
    """The codec error handler: the unencodable characters as ASCII text (ASCII_TEXT)."""
    if not isinstance(exc, UnicodeEncodeError):
        raise exc
    text = exc.object[exc.start:exc.end]
    return "".join(ASCII_TEXT.get(ch, "?") for ch in text), exc.end


codecs.register_error(ASCII_HANDLER, _as_ascii)


class _QuietStderr(io.TextIOWrapper):
    """stderr that drops what it cannot write (full, closed) instead of raising."""

    def write(self, text: str) -> int:
        try:
            return super().write(text)
        except (OSError, ValueError):
            return len(text)

    def flush(self) -> None:
        with contextlib.suppress(OSError, ValueError):
            super().flush()


def _reopen_closed(fd: int) -> bool:
    """Open /dev/null on descriptor ``fd`` if it is closed; True when it was."""
    try:
        os.fstat(fd)
        return False
    except OSError:
        pass
    null = os.open(os.devnull, os.O_RDWR)
    if null != fd:
        os.dup2(null, fd)
        os.close(null)
    return True


def _text_stream(fd: int, cls: type[io.TextIOWrapper] = io.TextIOWrapper,
                 encoding: str | None = None) -> io.TextIOWrapper:
    """A line-buffered text stream on descriptor ``fd`` (not closed with the stream)."""
    return cls(open(fd, "wb", closefd=False), encoding=encoding or "utf-8", errors=ASCII_HANDLER,
               line_buffering=True)


_CLOSED: set[int] = set()  # the standard descriptors that were closed when the process started


def closed_at_start(fd: int) -> bool:
    """Whether standard descriptor ``fd`` was closed when :func:`make_safe` ran (and is
    /dev/null since)."""
    return fd in _CLOSED


def make_safe() -> None:
    """Apply the rules of the module doc to this process (the program's entry points call
    it first). Streams that are not the process's own (a test's capture) are left alone."""
    for fd in (0, 1, 2):
        if _reopen_closed(fd):
            _CLOSED.add(fd)
    if sys.stdout is None:
        sys.stdout = _text_stream(1)
    elif isinstance(sys.stdout, io.TextIOWrapper):
        with contextlib.suppress(ValueError, OSError):
            sys.stdout.reconfigure(errors=ASCII_HANDLER)
    err = sys.stderr
    if err is None or (isinstance(err, io.TextIOWrapper) and not isinstance(err, _QuietStderr)
                       and _fileno(err) == 2):
        encoding = getattr(err, "encoding", None)
        with contextlib.suppress(OSError, ValueError, AttributeError):
            err.flush()
        sys.stderr = _text_stream(2, _QuietStderr, encoding)


def _fileno(stream: io.TextIOWrapper) -> int | None:
    """The descriptor under ``stream``, or None (a stream of a test's capture has none)."""
    try:
        return stream.fileno()
    except (OSError, ValueError):
        return None


def silence_stdout() -> None:
    """Send the rest of stdout to /dev/null (what is still buffered too): after a closed pipe
    or a full disk, so that neither the next line nor the exit's flush tries again."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
