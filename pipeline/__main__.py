"""The command line, as ``crosshead`` or ``python -m pipeline`` (pipeline.cli)."""
import signal
import sys

from pipeline.runtime.interrupts import stop_before_start
from pipeline.runtime.streams import make_safe


def console() -> None:
    """Run the command line and exit with its status (the ``crosshead`` command)."""
    # Closed or unencodable standard streams made safe before anything is written or
    # opened (pipeline/runtime/streams.py).
    make_safe()
    # Until the run's own stop is set up (pipeline.cli.main), Ctrl-C or SIGTERM ends the
    # loading program with its one line: nothing has been written yet.
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, stop_before_start)
    from pipeline.cli import main
    code = main(handle_signals=True)
    # The command has ended and said so. A signal from here on would only cut the exit
    # short: Python's shutdown puts back the default action, which ends the process with
    # no line and no exit status of its own. Ignored, the exit goes on with its status.
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, signal.SIG_IGN)
    sys.exit(code)


if __name__ == "__main__":
    console()
